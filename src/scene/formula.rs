//! `[formula]` of a scene: `model = "mechanical"` (potential, kinetic,
//! damping, dof) or `model = "lienard"` with formulas f and g, compiled into
//! a formula model (`models/formula.rs`). Errors name `formula.<key>` at its
//! line and show the formula with a caret under the column.

use std::ops::Range;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::models::formula::{FormulaModel, Kind, ModelError, Source};
use crate::models::Model;

use super::values::Parser;
use super::SceneError;

/// Keys of `[formula]` per family.
const MECHANICAL_KEYS: &[&str] = &[
    "dof",
    "potential",
    "kinetic",
    "damping",
    "forcing_frequency",
];
const LIENARD_KEYS: &[&str] = &["f", "g", "forcing_frequency"];

/// The formula model of `[formula]` (`table`, at `span`), for the family
/// `name`, over the parameters the scene's `[params]` names.
pub fn formula_model(
    p: &mut Parser,
    name: &str,
    table: Option<(&DeTable, Range<usize>)>,
    params: Vec<String>,
) -> Result<Model, SceneError> {
    let mechanical = name == "mechanical";
    let keys = if mechanical {
        MECHANICAL_KEYS
    } else {
        LIENARD_KEYS
    };
    let mut source = Source {
        kind: Kind::Lienard,
        texts: vec![],
        params,
        forcing_frequency: None,
    };
    let mut dof = 1;
    let mut spans: Vec<(String, Range<usize>)> = vec![];
    if let Some((t, _)) = &table {
        for (k, v) in p.entries(t, "formula", Some(keys))? {
            let key = k.get_ref().to_string();
            let field = format!("formula.{key}");
            spans.push((key.clone(), v.span()));
            match key.as_str() {
                "dof" => dof = p.integer(&field, v)? as usize,
                "forcing_frequency" => {
                    source.forcing_frequency = Some(parameter(p, &field, v, &source.params)?)
                }
                _ => source.texts.push((key, p.string(&field, v)?)),
            }
        }
    }
    if mechanical {
        source.kind = Kind::Mechanical { dof };
    } else if !source.texts.iter().any(|(k, _)| k == "g") {
        return Err(p.err(
            "formula.g",
            table.as_ref().map(|(_, s)| s),
            "a Liénard system needs g (e.g. g = \"q - A*cos(omega*t)\")",
        ));
    }
    FormulaModel::get(&source)
        .map(Model::Formula)
        .map_err(|e| located(p, &source, &spans, e))
}

/// `forcing_frequency = "omega"`: one of the parameters.
fn parameter(
    p: &Parser,
    field: &str,
    v: &Spanned<DeValue>,
    params: &[String],
) -> Result<String, SceneError> {
    let name = p.string(field, v)?;
    if params.contains(&name) {
        return Ok(name);
    }
    let known: Vec<&str> = params.iter().map(|s| s.as_str()).collect();
    Err(p.err(
        field,
        Some(&v.span()),
        format!(
            "`{name}` is not a parameter{}; [params] gives: {}",
            crate::num::names::suggest(&name, &known),
            if known.is_empty() {
                "(none)".to_string()
            } else {
                known.join(", ")
            }
        ),
    ))
}

/// A model error at the line of its field, with a caret under the column.
fn located(
    p: &Parser,
    source: &Source,
    spans: &[(String, Range<usize>)],
    e: ModelError,
) -> SceneError {
    let key = e.field.strip_prefix("formula.").unwrap_or(&e.field);
    let span = spans.iter().find(|(k, _)| k == key).map(|(_, s)| s);
    let text = source
        .texts
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, t)| t.as_str());
    let message = match (text, e.column) {
        (Some(text), Some(col)) => {
            let col = text.char_indices().take_while(|(i, _)| *i < col).count();
            with_caret(text, col, &e.message)
        }
        _ => e.message,
    };
    p.err(&e.field, span, message)
}

/// `column N: message`, then the formula (around the column) with a caret
/// under character `col`.
pub fn with_caret(text: &str, col: usize, message: &str) -> String {
    let (shown, caret) = around(text, col);
    format!(
        "column {}: {message}\n    {shown}\n    {}^",
        col + 1,
        " ".repeat(caret)
    )
}

/// Characters of a formula shown around an error's column.
const SHOWN: usize = 72;

/// The part of `text` shown under an error at character `col` (all of it
/// when short, else [`SHOWN`] characters around the column, cut ends marked
/// `…`), and the caret's position in it.
fn around(text: &str, col: usize) -> (String, usize) {
    let n = text.chars().count();
    if n <= SHOWN {
        return (text.to_string(), col);
    }
    let start = col.saturating_sub(SHOWN / 2).min(n - SHOWN);
    let mut shown: String = text.chars().skip(start).take(SHOWN).collect();
    if start + SHOWN < n {
        shown.push('…');
    }
    if start > 0 {
        return (format!("…{shown}"), col - start + 1);
    }
    (shown, col)
}

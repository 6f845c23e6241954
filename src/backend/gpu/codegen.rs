//! WGSL for a plan: `shaders/prelude_*.wgsl`, the shared functions (translated
//! from their single Rust source by [`crate::num::dsl::to_wgsl`]) and
//! `shaders/driver.wgsl`, with the plan's code spliced in.
//!
//! The kernel is specialised: it declares only the variables the plan's ops
//! name, loads and stores only the integrated ones, bakes constant inputs in as
//! literals, reads time only when the plan has time, and contains observer code
//! only for the observers asked for.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

use crate::models::COMMON_WGSL;
use crate::num::dsl::to_wgsl;
use crate::num::math::{MATH_F32_WGSL, MATH_F64_WGSL};
use crate::num::precision::Precision;
use crate::plan::observers::{Direction, Section};
use crate::plan::{ObsVar, Op, Plan, Source};

const PRELUDE_F32: &str = include_str!("../../../shaders/prelude_f32.wgsl");
const PRELUDE_F64: &str = include_str!("../../../shaders/prelude_f64.wgsl");
const DRIVER: &str = include_str!("../../../shaders/driver.wgsl");

/// Per-trajectory observer slots in `aux_r` (R) and `aux_u` (u32).
pub const AUX_R: [&str; 5] = ["cyc_max", "cyc_min", "cyc_first", "cyc_mean", "cyc_com"];
pub const AUX_U: [&str; 3] = ["strobe_k", "npoints", "cyc_count"];

/// A generated kernel and what the host needs to drive it.
#[derive(Debug, Clone)]
pub struct Kernel {
    pub source: String,
    /// Values of the axis-dependent inputs, concatenated (uploaded as `table`).
    pub table: Vec<f64>,
    /// Whether the stroboscopic section samples exactly (no interpolation).
    pub strobe_exact: bool,
}

/// Why no kernel could be generated.
#[derive(Debug, thiserror::Error)]
pub enum CodegenError {
    #[error(transparent)]
    Dsl(#[from] crate::num::dsl::DslError),
    #[error("{0}")]
    Plan(String),
}

/// Arguments of every shared function in `wgsl`: name → [(argument, by pointer)].
pub fn signatures(wgsl: &str) -> BTreeMap<String, Vec<(String, bool)>> {
    let mut out = BTreeMap::new();
    let mut rest = wgsl;
    while let Some(pos) = rest.find("fn ") {
        let after = &rest[pos + 3..];
        let name: String = after
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let Some(open) = after.find('(') else { break };
        // Arguments end at the parenthesis that closes the list.
        let mut depth = 0;
        let mut end = open;
        for (k, c) in after[open..].char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + k;
                        break;
                    }
                }
                _ => {}
            }
        }
        let args = &after[open + 1..end];
        let mut list = vec![];
        let mut depth = 0;
        let mut cur = String::new();
        for c in args.chars().chain(std::iter::once(',')) {
            match c {
                '<' => {
                    depth += 1;
                    cur.push(c)
                }
                '>' => {
                    depth -= 1;
                    cur.push(c)
                }
                ',' if depth == 0 => {
                    if let Some((n, ty)) = cur.split_once(':') {
                        list.push((n.trim().to_string(), ty.trim().starts_with("ptr")));
                    }
                    cur.clear();
                }
                _ => cur.push(c),
            }
        }
        out.insert(name, list);
        rest = &after[end..];
    }
    out
}

/// A WGSL literal for `v` (abstract float: full f64 precision, converted by
/// the compiler to the working precision exactly as `as f32` does).
fn lit(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') {
        s
    } else {
        format!("{s}.0")
    }
}

/// All shared-function text a plan's kernel includes, translated.
fn shared_text(plan: &Plan, precision: Precision) -> Result<String, CodegenError> {
    let mut text = String::new();
    text.push_str(&to_wgsl(match precision {
        Precision::F32 => MATH_F32_WGSL,
        Precision::F64 => MATH_F64_WGSL,
    })?);
    for t in COMMON_WGSL.iter().chain(plan.model.spec().wgsl) {
        text.push_str(&to_wgsl(t)?);
    }
    Ok(text)
}

/// Generates the kernel of `plan` in `precision`.
pub fn generate(plan: &Plan, precision: Precision) -> Result<Kernel, CodegenError> {
    let shared = shared_text(plan, precision)?;
    let sigs = signatures(&shared);
    let needs_field = plan.needs_field();
    let calls = plan.called_ops();
    let mut names: BTreeSet<String> = BTreeSet::new();
    for c in &calls {
        let sig = sigs
            .get(*c)
            .ok_or_else(|| CodegenError::Plan(format!("no shared function `{c}`")))?;
        names.extend(sig.iter().map(|(a, _)| a.clone()));
    }
    names.insert("dt".into());
    names.insert("t0".into());
    if plan.observers.stroboscopic() {
        names.insert("strobe_period".into());
        names.insert("strobe_phase".into());
    }

    // Inputs: constants as literals, axis-dependent values from the table.
    let mut table: Vec<f64> = vec![];
    let mut inputs = String::new();
    let mut declared: BTreeSet<String> = BTreeSet::new();
    let input_expr = |src: &Source, table: &mut Vec<f64>| -> Result<String, CodegenError> {
        Ok(match src {
            Source::Const(v) => {
                if precision == Precision::F32 && v.abs() > f32::MAX as f64 {
                    return Err(CodegenError::Plan(format!("{v} does not fit in f32")));
                }
                lit(*v)
            }
            Source::Axis { axis, values } => {
                let off = table.len();
                table.extend(values);
                format!(
                    "table[{off}u + (g / {}u) % {}u]",
                    plan.strides[*axis],
                    values.len()
                )
            }
        })
    };
    for (name, src) in &plan.bindings {
        if plan.vars.contains(name) || !names.contains(*name) {
            continue;
        }
        // The step and the start time come from the table even when constant,
        // so that the plans of a scene's sub-runs (one per dt) share a kernel.
        let e = match (src, *name) {
            (Source::Const(v), "dt" | "t0") => {
                table.push(*v);
                format!("table[{}u]", table.len() - 1)
            }
            _ => input_expr(src, &mut table)?,
        };
        writeln!(inputs, "    let {name}: R = {e};").unwrap();
        declared.insert(name.to_string());
    }

    // State: the integrated variables (initial values at step 0).
    let mut load = String::new();
    let mut store = String::new();
    for (k, v) in plan.vars.iter().enumerate() {
        let init = input_expr(plan.binding(v), &mut table)?;
        writeln!(load, "    var {v}: R;\n    if u.step0 == 0u {{\n        {v} = {init};\n    }} else {{\n        {v} = state[{k}u * u.cap + i];\n    }}").unwrap();
        writeln!(store, "    state[{k}u * u.cap + i] = {v};").unwrap();
        declared.insert(v.to_string());
    }
    // Everything else an op names: step, time, time terms, derivatives,
    // variables this plan does not integrate.
    for n in &names {
        if !declared.contains(n) {
            writeln!(load, "    var {n}: R = 0.0;").unwrap();
        }
    }

    let call = |name: &str| -> String {
        let args: Vec<String> = sigs[name]
            .iter()
            .map(|(a, p)| if *p { format!("&{a}") } else { a.clone() })
            .collect();
        format!("        {name}({});\n", args.join(", "))
    };
    let mut step = String::new();
    if needs_field {
        for v in &plan.vars {
            writeln!(step, "        prev_{v} = {v};\n        dprev_{v} = d{v};").unwrap();
        }
    }
    for op in &plan.ops {
        match op {
            Op::Tau(c) => writeln!(step, "        tau = {} * dt;", lit(*c)).unwrap(),
            Op::Time(c) => writeln!(step, "        t = t0 + nf * dt + {} * dt;", lit(*c)).unwrap(),
            Op::Call(name) => step.push_str(&call(name)),
        }
    }
    let finite = plan
        .vars
        .iter()
        .map(|v| format!("finite({v})"))
        .collect::<Vec<_>>()
        .join(" && ");

    let field = |n1: &str| -> String {
        let mut s = if names.contains("t") {
            format!("        t = t0 + R({n1}) * dt;\n")
        } else {
            String::new()
        };
        for f in &plan.field_ops {
            s.push_str(&call(f));
        }
        s
    };

    // Observers.
    let strobe_exact = plan.observers.stroboscopic() && !plan.strobe_interpolated();
    let mut begin = String::new();
    let mut observe = String::new();
    let uses_aux = plan.observers.poincare.is_some() || plan.cycle_var.is_some();
    if uses_aux {
        for (k, a) in AUX_R.iter().enumerate() {
            let init = match *a {
                "cyc_max" => "-inf()",
                "cyc_min" => "inf()",
                _ => "0.0",
            };
            writeln!(load, "    var {a}: R = {init};\n    if u.step0 != 0u {{\n        {a} = aux_r[{k}u * u.cap + i];\n    }}").unwrap();
            writeln!(store, "    aux_r[{k}u * u.cap + i] = {a};").unwrap();
        }
        for (k, a) in AUX_U.iter().enumerate() {
            writeln!(load, "    var {a}: u32 = 0u;\n    if u.step0 != 0u {{\n        {a} = aux_u[{k}u * u.cap + i];\n    }}").unwrap();
            writeln!(store, "    aux_u[{k}u * u.cap + i] = {a};").unwrap();
        }
    }
    if needs_field {
        for v in &plan.vars {
            writeln!(
                load,
                "    var prev_{v}: R = 0.0;\n    var dprev_{v}: R = 0.0;"
            )
            .unwrap();
        }
        begin.push_str(&field("u.step0"));
    }
    let value = |v: &ObsVar, th: &str, n1: &str| -> String {
        match v {
            ObsVar::Time => format!("(t0 + R({n1}) * dt) - (1.0 - {th}) * dt"),
            ObsVar::State(k) => {
                let x = plan.vars[*k];
                if th == "1.0" {
                    x.to_string()
                } else {
                    format!("select(hermite(prev_{x}, {x}, dprev_{x}, d{x}, dt, {th}), {x}, {th} == 1.0)")
                }
            }
        }
    };
    let observe_at = |n1: &str, initial: bool| -> String {
        let mut s = String::new();
        if let Some(tr) = &plan.observers.trajectory {
            let nv = plan.trajectory_vars.len();
            writeln!(
                s,
                "        if ({n1}) % {}u == 0u {{\n            let fr = ({n1}) / {}u - u.frame0;",
                tr.every, tr.every
            )
            .unwrap();
            for (j, v) in plan.trajectory_vars.iter().enumerate() {
                writeln!(
                    s,
                    "            traj_out[(fr * {nv}u + {j}u) * u.cap + i] = {};",
                    value(v, "1.0", n1)
                )
                .unwrap();
            }
            s.push_str("        }\n");
        }
        if let Some(pc) = &plan.observers.poincare {
            let npv = plan.poincare_vars.len();
            let record = |th: &str, crossing: Option<(usize, f64)>| -> String {
                let mut r = format!("            if npoints < {}u {{\n", pc.max_points);
                for (j, v) in plan.poincare_vars.iter().enumerate() {
                    let x = match (crossing, v) {
                        (Some((cv, level)), ObsVar::State(k)) if *k == cv => lit(level),
                        _ => value(v, th, n1),
                    };
                    writeln!(
                        r,
                        "                points_out[(npoints * {npv}u + {j}u) * u.cap + i] = {x};"
                    )
                    .unwrap();
                }
                r.push_str("            }\n            npoints = npoints + 1u;\n");
                r
            };
            match &pc.section {
                Section::Stroboscopic { .. } | Section::Forced { .. } => {
                    if strobe_exact {
                        writeln!(s, "        {{\n            let every = u32(floor(strobe_period / dt + 0.5));\n            let first = u32(floor(strobe_phase / dt + 0.5));\n            if ({n1}) >= first && (({n1}) - first) % every == 0u {{").unwrap();
                        s.push_str(
                            &record("1.0", None).replace("\n            ", "\n                "),
                        );
                        s.push_str("            }\n        }\n");
                    } else {
                        // Every sample time in (t_{n1−1}, t_{n1}] (t_0 itself at step 0).
                        writeln!(s, "        loop {{\n            let x = strobe_position(R(strobe_k), strobe_period, strobe_phase, dt);\n            if x > R({n1}) + 1e-4 {{\n                break;\n            }}\n            let th: R = {};", if initial { "1.0".to_string() } else { format!("clamp(x - R({n1}) + 1.0, 0.0, 1.0)") }).unwrap();
                        s.push_str(&record("th", None));
                        s.push_str("            strobe_k = strobe_k + 1u;\n        }\n");
                    }
                }
                Section::Crossing {
                    value: level,
                    direction,
                    ..
                } => {
                    if !initial {
                        let cv = plan.crossing_var.expect("planned");
                        let x = plan.vars[cv];
                        let cond = match direction {
                            Direction::Up => "y0 < 0.0 && y1 >= 0.0",
                            Direction::Down => "y0 > 0.0 && y1 <= 0.0",
                            Direction::Both => "(y0 < 0.0 && y1 >= 0.0) || (y0 > 0.0 && y1 <= 0.0)",
                        };
                        writeln!(s, "        {{\n            let y0 = prev_{x} - {l};\n            let y1 = {x} - {l};\n            if {cond} {{\n            let th: R = crossing_theta(y0, y1, dprev_{x}, d{x}, dt);", l = lit(*level)).unwrap();
                        s.push_str(&record("th", Some((cv, *level))));
                        s.push_str("            }\n        }\n");
                    }
                }
            }
        }
        s
    };
    if plan.observers.trajectory.is_some() || plan.observers.poincare.is_some() {
        writeln!(
            begin,
            "    if u.step0 == 0u {{\n{}    }}",
            observe_at("0u", true)
        )
        .unwrap();
    }
    if needs_field {
        observe.push_str(&field("n + 1u"));
    }
    observe.push_str(&observe_at("n + 1u", false));
    if let (Some(k), Some(cy)) = (plan.cycle_var, &plan.observers.cycle) {
        let x = plan.vars[k];
        let start = (cy.skip * plan.steps as f64).floor() as u64;
        writeln!(
            observe,
            "        if n + 1u >= {start}u {{\n            cyc_max = max(cyc_max, {x});\n            cyc_min = min(cyc_min, {x});\n            let y0 = prev_{x} - {l};\n            let y1 = {x} - {l};\n            if y0 < 0.0 && y1 >= 0.0 {{\n                let th = crossing_theta(y0, y1, dprev_{x}, d{x}, dt);\n                let tc = t0 + nf * dt + th * dt;\n                if cyc_count == 0u {{\n                    cyc_first = tc;\n                }}\n                cycle_crossing(R(cyc_count), tc - cyc_first, &cyc_mean, &cyc_com);\n                cyc_count = cyc_count + 1u;\n            }}\n        }}",
            l = lit(cy.level)
        )
        .unwrap();
    }

    let prelude = match precision {
        Precision::F32 => PRELUDE_F32,
        Precision::F64 => PRELUDE_F64,
    };
    let driver = DRIVER
        .replace("{{INPUTS}}", inputs.trim_end())
        .replace("{{LOAD}}", load.trim_end())
        .replace("{{BEGIN}}", begin.trim_end())
        .replace("{{STEP}}", step.trim_end())
        .replace("{{FINITE}}", &finite)
        .replace("{{OBSERVE}}", observe.trim_end())
        .replace("{{STORE}}", store.trim_end());
    let source = format!("{prelude}\n// ---- shared functions (generated from src/**/*.rs) ----\n{shared}\n// ---- driver ----\n{driver}");
    Ok(Kernel {
        source,
        table,
        strobe_exact,
    })
}

//! A scene given as JSON (the Python package's dicts): its TOML text, which
//! the scene reader then reads as it reads a file, so a dict is checked by
//! exactly the rules of a file and its errors name the same fields.

use serde_json::Value;

/// The TOML text of the scene `v` (a JSON object), or the field that has no
/// TOML form and why: `(field, message)`.
pub fn toml_text_of_json(v: &Value) -> Result<String, (String, String)> {
    match to_toml(v, "")? {
        toml::Value::Table(t) => toml::to_string(&t).map_err(|e| (String::new(), e.to_string())),
        _ => Err((
            String::new(),
            "a scene is a table of keys (a dict), as a scene file is".into(),
        )),
    }
}

fn to_toml(v: &Value, field: &str) -> Result<toml::Value, (String, String)> {
    let key = |k: &str| {
        if field.is_empty() {
            k.to_string()
        } else {
            format!("{field}.{k}")
        }
    };
    Ok(match v {
        Value::Null => {
            return Err((
                field.into(),
                "None has no TOML form: leave the key out".into(),
            ))
        }
        Value::Bool(b) => toml::Value::Boolean(*b),
        Value::Number(n) => match n.as_i64() {
            Some(i) => toml::Value::Integer(i),
            None => toml::Value::Float(n.as_f64().unwrap_or(f64::NAN)),
        },
        Value::String(s) => toml::Value::String(s.clone()),
        Value::Array(a) => toml::Value::Array(
            a.iter()
                .enumerate()
                .map(|(k, x)| to_toml(x, &format!("{field}[{k}]")))
                .collect::<Result<_, _>>()?,
        ),
        Value::Object(o) => toml::Value::Table(
            o.iter()
                .map(|(k, x)| Ok::<_, (String, String)>((k.clone(), to_toml(x, &key(k))?)))
                .collect::<Result<_, _>>()?,
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_dict_reads_as_the_file_it_spells() {
        let v = serde_json::json!({
            "model": "van_der_pol",
            "params": {"epsilon": {"linspace": [0.0, 10.0, 4]}, "forcing_amplitude": 0.5},
            "initial": {"q": [1.0, 2.0]},
            "integrator": {"scheme": "s2", "dt": 0.01, "steps": 100},
            "output": {"final": ["q"], "trajectory": {"every": 10, "vars": ["q"]}},
        });
        let text = toml_text_of_json(&v).unwrap();
        let s = crate::scene::Scene::parse(Path::new("<dict>"), &text).unwrap();
        assert_eq!(s.ensemble_size(), 8);
        assert_eq!(s.axes[0].name, "epsilon");
    }

    #[test]
    fn none_is_refused_naming_its_field() {
        let v = serde_json::json!({"params": {"epsilon": null}});
        let (field, message) = toml_text_of_json(&v).unwrap_err();
        assert_eq!(field, "params.epsilon");
        assert!(message.contains("None"), "{message}");
        assert!(toml_text_of_json(&serde_json::json!([1, 2])).is_err());
    }
}

//! JSON as probecal writes it (`summary.json`, `study.json`): pretty, keys
//! sorted, a final newline, and never a `null` standing for a number that is not
//! finite.

use serde::Serialize;

/// A summary as written: pretty JSON, keys sorted, a final newline. A number
/// that is not finite is an error naming its field: JSON has no NaN and would
/// write `null`, which a reader takes for "not measured".
pub fn to_text<T: Serialize>(summary: &T) -> Result<String, JsonError> {
    // YAML keeps NaN and infinity as numbers (JSON turns them into null, as it
    // does a `None`), so the search runs on the YAML tree.
    let tree = serde_yaml::to_value(summary).map_err(|e| JsonError::Serialize(e.to_string()))?;
    if let Some(field) = non_finite_field(&tree, "") {
        return Err(JsonError::NonFinite { field });
    }
    let value = serde_json::to_value(summary).map_err(|e| JsonError::Serialize(e.to_string()))?;
    serde_json::to_string_pretty(&value)
        .map(|text| text + "\n")
        .map_err(|e| JsonError::Serialize(e.to_string()))
}

/// Why a summary could not be written as JSON.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JsonError {
    #[error("field `{field}` is not a finite number")]
    NonFinite { field: String },
    #[error("{0}")]
    Serialize(String),
}

/// The path of the first number in `tree` that is NaN or infinite.
fn non_finite_field(tree: &serde_yaml::Value, at: &str) -> Option<String> {
    use serde_yaml::Value;
    match tree {
        Value::Number(n) => n.as_f64().filter(|v| !v.is_finite()).map(|_| at.to_string()),
        Value::Sequence(items) => items
            .iter()
            .enumerate()
            .find_map(|(i, item)| non_finite_field(item, &format!("{at}[{i}]"))),
        Value::Mapping(fields) => fields.iter().find_map(|(key, item)| {
            let key = key.as_str().map(str::to_string).unwrap_or_else(|| format!("{key:?}"));
            let path = if at.is_empty() { key } else { format!("{at}.{key}") };
            non_finite_field(item, &path)
        }),
        Value::Tagged(tagged) => non_finite_field(&tagged.value, at),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Stats {
        mean_mm: f64,
        sd_mm: Option<f64>,
        per_axis_mm: Vec<f64>,
    }

    #[derive(Serialize)]
    struct Summary {
        experiment: String,
        bre: Stats,
    }

    fn summary(mean_mm: f64, sd_mm: Option<f64>, z_mm: f64) -> Summary {
        Summary {
            experiment: "lab".into(),
            bre: Stats {
                mean_mm,
                sd_mm,
                per_axis_mm: vec![0.1, 0.2, z_mm],
            },
        }
    }

    #[test]
    fn a_missing_value_is_null_and_keys_are_sorted() {
        let text = to_text(&summary(0.5, None, 0.3)).unwrap();
        assert!(text.contains("\"sd_mm\": null"), "{text}");
        assert!(text.find("\"bre\"").unwrap() < text.find("\"experiment\"").unwrap());
        assert!(text.ends_with("}\n"));
    }

    #[test]
    fn a_number_that_is_not_finite_is_an_error_naming_its_field() {
        assert_eq!(
            to_text(&summary(f64::NAN, Some(0.1), 0.3)).unwrap_err().to_string(),
            "field `bre.mean_mm` is not a finite number"
        );
        assert_eq!(
            to_text(&summary(0.5, Some(f64::INFINITY), 0.3))
                .unwrap_err()
                .to_string(),
            "field `bre.sd_mm` is not a finite number"
        );
        assert_eq!(
            to_text(&summary(0.5, None, -f64::INFINITY)).unwrap_err().to_string(),
            "field `bre.per_axis_mm[2]` is not a finite number"
        );
    }
}

//! The forms a station serves — the `ground` catalogue: per user task type, the goal it
//! receives and the answer fields with their types — and answers typed by an operator as
//! `field=value` text, checked against the form before anything is sent.

use std::path::Path;

use connector_api::catalogue::Type;
use connector_api::{ActionSpec, Catalogue, Fields};
use serde_json::Value;

/// The forms file could not be used.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {reason}")]
pub struct FormsError {
    /// The file.
    pub path: String,
    /// What is wrong.
    pub reason: String,
}

/// Reads the forms (a catalogue in JSON, `deploy/ground/forms.json`).
pub fn load(path: &Path) -> Result<Catalogue, FormsError> {
    let bad = |reason: String| FormsError {
        path: path.display().to_string(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let catalogue: Catalogue = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    if catalogue.actions.is_empty() {
        return Err(bad("no forms: `actions` is empty".to_owned()));
    }
    Ok(catalogue)
}

/// The answer fields of a form, one line each (`approve: bool`, `comment: string (optional)`).
pub fn describe(spec: &ActionSpec) -> Vec<String> {
    spec.result
        .iter()
        .map(|(k, t)| match t {
            Type::Optional(inner) => format!("{k}: {inner} (optional)"),
            t => format!("{k}: {t}"),
        })
        .collect()
}

/// Reads an answer typed as `field=value …` (values as JSON; text may be bare or quoted) and
/// checks it against the form: unknown fields, values that do not parse or have the wrong
/// type, and missing required fields are refused with the field named.
pub fn parse_answer(spec: &ActionSpec, text: &str) -> Result<Fields, String> {
    let mut fields = Fields::new();
    for token in split(text)? {
        let Some((name, raw)) = token.split_once('=') else {
            return Err(format!("`{token}` is not `field=value`"));
        };
        let Some(ty) = spec.result.get(name) else {
            let known: Vec<&str> = spec.result.keys().map(String::as_str).collect();
            return Err(format!(
                "`{name}` is not a field of this form (fields: {})",
                known.join(", ")
            ));
        };
        let value = match ty.required() {
            Type::String | Type::Timestamp if !raw.starts_with('"') => {
                Value::String(raw.to_owned())
            }
            _ => serde_json::from_str(raw)
                .map_err(|_| format!("`{name}` must be {}: `{raw}` is not one", ty.required()))?,
        };
        ty.check(name, &value)?;
        if fields.insert(name.to_owned(), value).is_some() {
            return Err(format!("`{name}` is given twice"));
        }
    }
    spec.check_result(&fields)?;
    Ok(fields)
}

/// Splits on white space outside double quotes (quotes are kept; `\` escapes inside them).
fn split(text: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let (mut quoted, mut escaped) = (false, false);
    for c in text.chars() {
        if escaped {
            cur.push(c);
            escaped = false;
        } else if quoted && c == '\\' {
            cur.push(c);
            escaped = true;
        } else if c == '"' {
            cur.push(c);
            quoted = !quoted;
        } else if c.is_whitespace() && !quoted {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
        } else {
            cur.push(c);
        }
    }
    if quoted {
        return Err("a quote is not closed".to_owned());
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn form() -> ActionSpec {
        serde_json::from_value(json!({
            "name": "ground.approve_site",
            "result": {"approve": "bool", "site_id": "int?", "comment": "string?"}
        }))
        .unwrap()
    }

    #[test]
    fn typed_answers_are_read_and_bad_ones_named() {
        let f = form();
        let ok = parse_answer(
            &f,
            r#"approve=true comment="dig here, not there" site_id=3"#,
        );
        assert_eq!(
            Value::Object(ok.unwrap()),
            json!({"approve": true, "comment": "dig here, not there", "site_id": 3})
        );
        assert_eq!(
            parse_answer(&f, "approve=false comment=fine").unwrap()["comment"],
            "fine"
        );
        let err = |t: &str| parse_answer(&f, t).unwrap_err();
        assert_eq!(
            err("approve=maybe"),
            "`approve` must be bool: `maybe` is not one"
        );
        assert_eq!(err("approve=1"), "`approve` must be bool, got an int");
        assert_eq!(err("comment=x"), "`approve` is missing");
        assert_eq!(
            err("approve=true site_id=2.5"),
            "`site_id` must be int, got an f64"
        );
        assert!(err("approve=true colour=red").starts_with("`colour` is not a field"));
        assert_eq!(
            err("approve=true approve=false"),
            "`approve` is given twice"
        );
        assert_eq!(err("approve"), "`approve` is not `field=value`");
        assert_eq!(
            err(r#"approve=true comment="open"#),
            "a quote is not closed"
        );
    }

    #[test]
    fn forms_are_described_for_people() {
        assert_eq!(
            describe(&form()),
            [
                "approve: bool",
                "comment: string (optional)",
                "site_id: int (optional)"
            ]
        );
    }
}

//! The start variables of `trace run`: `--var name=value`, `--vars FILE`, and their check
//! against what the process declares (a collection given a single value is refused; names it
//! does not declare are returned, to be said).

use super::*;

/// One `--var name=value`: the value is JSON if it parses as JSON, else the text itself.
pub fn parse_var(arg: &str) -> Result<(String, Value), String> {
    let (name, value) = arg
        .split_once('=')
        .ok_or_else(|| format!("`{arg}` is not name=value"))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(format!("`{arg}` has no variable name"));
    }
    let value =
        serde_json::from_str::<Value>(value).unwrap_or_else(|_| Value::String(value.to_owned()));
    Ok((name.to_owned(), value))
}

/// A `--vars` file: one JSON object, its fields the variables.
pub fn read_vars(path: &Path) -> Result<Vars, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str::<Vars>(&text)
        .map_err(|e| format!("{}: not a JSON object of variables: {e}", path.display()))
}

/// Checks start variables against the data a process declares (its properties and data
/// objects carry no type in BPMN as TRACE reads it, only `isCollection`): a collection must
/// be given a list. Names the process does not declare are returned (a warning: models
/// often use undeclared variables).
pub(super) fn check_vars(
    g: &ProcessGraph,
    p: executive_model::ProcessId,
    vars: &Vars,
) -> Result<Vec<String>, String> {
    let process = g.process(p);
    let declared: Vec<_> = process
        .properties
        .iter()
        .chain(&process.data_objects)
        .collect();
    let mut undeclared = Vec::new();
    for (name, value) in vars {
        match declared
            .iter()
            .find(|d| d.name.as_deref().unwrap_or(&d.id) == name)
        {
            Some(d) if d.collection && !matches!(value, Value::List(_)) => {
                return Err(format!(
                    "`{name}` is a collection in process `{}` (isCollection), but was given {} `{value}`",
                    process.id,
                    value.type_name()
                ));
            }
            Some(_) => {}
            None if !declared.is_empty() => undeclared.push(name.clone()),
            None => {}
        }
    }
    Ok(undeclared)
}

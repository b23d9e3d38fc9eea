//! Functions that Camunda 8 models call but that come from Zeebe and the Connectors runtime
//! rather than from feel-scala's library: `fromAi` (Zeebe, Camunda 8.8, docs.camunda.io
//! *Miscellaneous functions*) and the connector error-expression functions `bpmnError` and
//! `jobError` (docs.camunda.io *Using Connectors*, section *BPMN errors and failing jobs*).
//!
//! They are built-ins here so that such models load and run: outside an AI agent `fromAi` is
//! its value, and the error functions build the context the Connectors runtime reads from an
//! `errorExpression` header.

use chrono::TimeDelta;

use super::{Out, context, number, take, text, wrong};
use crate::host::Host;
use crate::value::{Context, Value};

/// `fromAi(value)`, `fromAi(value, description)`, `fromAi(value, description, type)`,
/// `fromAi(value, description, type, schema)`,
/// `fromAi(value, description, type, schema, options)`: `value`, unchanged. The function only
/// tags the value as one an AI agent supplies; the agent's connector reads the description,
/// type, JSON schema and options from the expression text, not from the evaluation. As in
/// Zeebe's `FromAiFunction`, the other arguments are not checked when evaluating (Camunda's
/// modeler lints them: the description and type must be string literals or null).
pub(super) fn from_ai(_: &mut dyn Host, args: Vec<Value>) -> Out {
    Ok(args.into_iter().next().unwrap_or(Value::Null))
}

/// `bpmnError(code, message)`, `bpmnError(code, message, variables)`: the BPMN error a
/// connector's error expression asks for, as the context the Connectors runtime reads:
/// `{errorType: "bpmnError", code, message}`, with `variables` (a context) when given. The code
/// and message must be strings (the runtime fails the expression otherwise).
pub(super) fn bpmn_error(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [code, message, variables] = take(args);
    let mut entries = vec![
        (
            "errorType".to_owned(),
            Value::String("bpmnError".to_owned()),
        ),
        (
            "code".to_owned(),
            Value::String(text(&code, "code")?.to_owned()),
        ),
        (
            "message".to_owned(),
            Value::String(text(&message, "message")?.to_owned()),
        ),
    ];
    if n > 2 {
        let variables = context(variables, "variables")?;
        entries.push(("variables".to_owned(), Value::Context(variables)));
    }
    Ok(Value::Context(Context(entries)))
}

/// `jobError(message)`, `jobError(message, variables)`, `jobError(message, variables, retries)`,
/// `jobError(message, variables, retries, retryBackoff)`: a failed job a connector's error
/// expression asks for, as the context the Connectors runtime reads:
/// `{errorType: "jobError", message, variables, retries, retryBackoff}`, the missing ones
/// `{}`, `0` and `PT0S`. The names are the runtime's (`FeelConnectorFunctionProvider`, read
/// back as its `JobError` record); docs.camunda.io calls the last one `timeout`.
pub(super) fn job_error(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [message, variables, retries, backoff] = take(args);
    let message = text(&message, "message")?.to_owned();
    let variables = if n > 1 {
        context(variables, "variables")?
    } else {
        Context::default()
    };
    let retries = if n > 2 {
        number(&retries, "retries")?
    } else {
        0.into()
    };
    let backoff = match (n > 3, backoff) {
        (false, _) => TimeDelta::zero(),
        (true, Value::DayTime(d)) => d,
        (true, other) => {
            return Err(wrong("retryBackoff", "a days and time duration", &other));
        }
    };
    Ok(Value::Context(Context(vec![
        ("errorType".to_owned(), Value::String("jobError".to_owned())),
        ("message".to_owned(), Value::String(message)),
        ("variables".to_owned(), Value::Context(variables)),
        ("retries".to_owned(), Value::Number(retries)),
        ("retryBackoff".to_owned(), Value::DayTime(backoff)),
    ])))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{check, nulls};

    #[test]
    fn from_ai_is_its_value() {
        check(&[
            ("fromAi(\"A\")", "\"A\""),
            ("fromAi(1, \"The user's ID\")", "1"),
            ("fromAi(1, null)", "1"),
            ("fromAi([1, 2], \"Tags\", \"array\")", "[1, 2]"),
            ("fromAi(\"x\", null, \"number\")", "\"x\""),
            (
                "fromAi(\"invoice\", \"The document type\", \"string\", {enum: [\"invoice\"]})",
                "\"invoice\"",
            ),
            (
                "fromAi(\"invoice\", \"The document type\", \"string\", null, {strict: true})",
                "\"invoice\"",
            ),
            ("fromAi({a: 1}, 5, 6, 7, 8)", "{a: 1}"),
            ("fromAi(null)", "null"),
        ]);
    }

    #[test]
    fn bpmn_error_builds_the_error_context() {
        check(&[
            (
                "bpmnError(\"123\", \"error received\")",
                "{errorType: \"bpmnError\", code: \"123\", message: \"error received\"}",
            ),
            (
                "bpmnError(\"123\", \"error received\", {myVar: 1})",
                "{errorType: \"bpmnError\", code: \"123\", message: \"error received\", variables: {myVar: 1}}",
            ),
            (
                "bpmnError(\"\", \"\", {})",
                "{errorType: \"bpmnError\", code: \"\", message: \"\", variables: {}}",
            ),
        ]);
        nulls(&[
            ("bpmnError(null, \"m\")", "bpmnError: `code` is null"),
            (
                "bpmnError(404, \"m\")",
                "`code` must be a string, not a number",
            ),
            ("bpmnError(\"1\", null)", "`message` is null"),
            ("bpmnError(\"1\", \"m\", null)", "`variables` is null"),
            (
                "bpmnError(\"1\", \"m\", [1])",
                "`variables` must be a context, not a list",
            ),
        ]);
    }

    #[test]
    fn job_error_builds_the_error_context_with_defaults() {
        use crate::value::{Context, Value};
        let message = || Value::String("job failed".to_owned());
        let vars = || Value::Context(Context(vec![("myVar".to_owned(), Value::int(1))]));
        let all = |vars: &str, retries: &str, backoff: &str| {
            format!(
                "{{errorType:\"jobError\", message:\"job failed\", variables:{vars}, retries:{retries}, retryBackoff:{backoff}}}"
            )
        };
        // Called directly: the test literals have no durations.
        for (args, want) in [
            (vec![message()], all("{}", "0", "PT0S")),
            (vec![message(), vars()], all("{myVar:1}", "0", "PT0S")),
            (
                vec![message(), vars(), Value::int(2)],
                all("{myVar:1}", "2", "PT0S"),
            ),
            (
                vec![
                    message(),
                    Value::Context(Context::default()),
                    Value::int(2),
                    Value::DayTime(chrono::TimeDelta::seconds(30)),
                ],
                all("{}", "2", "PT30S"),
            ),
        ] {
            let mut host = super::super::testing::Mock::new(100);
            let out = super::job_error(&mut host, args);
            assert!(
                matches!(out, Ok(ref v) if v.to_string() == want),
                "{out:?}, want {want}"
            );
        }
        nulls(&[
            ("jobError(null)", "jobError: `message` is null"),
            ("jobError(1)", "`message` must be a string, not a number"),
            ("jobError(\"m\", null)", "`variables` is null"),
            (
                "jobError(\"m\", {}, \"2\")",
                "`retries` must be a number, not a string",
            ),
            ("jobError(\"m\", {}, 2, null)", "`retryBackoff` is null"),
            (
                "jobError(\"m\", {}, 2, 30)",
                "`retryBackoff` must be a days and time duration, not a number",
            ),
        ]);
    }

    /// The value of `text` evaluated with `vars`, as text (`null: reason` for a null).
    fn feel(text: &str, vars: &[(&str, crate::value::Value)]) -> String {
        let expression = crate::parse(text).unwrap_or_else(|p| panic!("{p}"));
        let lookup = |name: &str| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.clone())
        };
        let env = crate::Env {
            lookup: &lookup,
            now: crate::DateTime {
                local: chrono::NaiveDateTime::default(),
                zone: None,
            },
            budget: 10_000,
        };
        match expression.evaluate(&env) {
            Ok(e) if e.value.is_null() => format!("null: {}", e.note.unwrap_or_default()),
            Ok(e) => e.value.to_string(),
            Err(stop) => format!("stop: {stop}"),
        }
    }

    #[test]
    fn documented_calls_evaluate() {
        use crate::value::{Context, Value};
        let tool_call = Value::Context(Context(vec![
            ("userId".to_owned(), Value::int(7)),
            (
                "documentType".to_owned(),
                Value::String("invoice".to_owned()),
            ),
        ]));
        let vars = [("toolCall", tool_call)];
        for (text, want) in [
            // docs.camunda.io Miscellaneous functions: named calls may skip parameters.
            ("fromAi(toolCall.userId)", "7"),
            (
                "fromAi(toolCall.userId, \"The user's ID\", \"number\")",
                "7",
            ),
            ("fromAi(value: toolCall.userId, type: \"number\")", "7"),
            (
                "fromAi(value: toolCall.documentType, description: \"The document type to provide\", schema: {type: \"string\", enum: [\"invoice\", \"receipt\"]})",
                "\"invoice\"",
            ),
            (
                "fromAi(value: toolCall.documentType, options: {strict: true, required: false})",
                "\"invoice\"",
            ),
            (
                "fromAi(toolCall.documentType, \"The document type\", \"string\", null, {strict: true})",
                "\"invoice\"",
            ),
            ("fromAi(toolCall.missing)", "null: "),
            // docs.camunda.io Using Connectors, error expressions.
            (
                "bpmnError(\"123\", \"error received\", {myVar: toolCall.userId})",
                "{errorType:\"bpmnError\", code:\"123\", message:\"error received\", variables:{myVar:7}}",
            ),
            (
                "jobError(\"Gateway timeout\", {}, 3 - 1, @\"PT30S\")",
                "{errorType:\"jobError\", message:\"Gateway timeout\", variables:{}, retries:2, retryBackoff:PT30S}",
            ),
            (
                "bpmnError(code: \"1\", message: \"m\")",
                "{errorType:\"bpmnError\", code:\"1\", message:\"m\"}",
            ),
        ] {
            let got = feel(text, &vars);
            assert!(got.starts_with(want), "{text}\n  got  {got}\n  want {want}");
        }
    }
}

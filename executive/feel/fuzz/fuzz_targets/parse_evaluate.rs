//! Coverage-guided fuzzing of the FEEL lexer, parser, checker and evaluator: any text is parsed,
//! checked, and evaluated with a few variables and a small budget; nothing may panic, overflow
//! the stack or run unbounded. Run: `cargo fuzz run parse_evaluate` in `executive/feel`.
#![no_main]

use executive_feel::{Context, DateTime, Env, Value, parse};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(expression) = parse(text) else {
        return;
    };
    let _ = expression.problems();
    let vars = |name: &str| match name {
        "n" => Some(Value::int(3)),
        "s" => Some(Value::String("abc".into())),
        "l" => Some(Value::List(vec![Value::int(1), Value::int(2), Value::Null])),
        "c" => Some(Value::Context(Context(vec![("a".into(), Value::int(1))]))),
        "z" => Some(Value::Null),
        _ => None,
    };
    let env = Env {
        lookup: &vars,
        now: DateTime {
            local: chrono::NaiveDate::from_ymd_opt(2026, 11, 23)
                .and_then(|d| d.and_hms_opt(10, 0, 0))
                .unwrap_or_default(),
            zone: None,
        },
        budget: 20_000,
    };
    if let Ok(v) = expression.evaluate(&env) {
        let _ = v.value.to_string();
    }
});

//! Context built-ins: `get value` (by key or by a path of keys), `get entries`, `context put`
//! (by key or path), `context merge`, and feel-scala's deprecated `put` and `put all`.
//! Paths are walked without recursion.

use super::{Entries, Fail, Out, context, list, null, take, varargs};
use crate::host::Host;
use crate::value::{Context, Value};

/// A `key` (string) or `keys` (list of strings) argument as a path.
fn path(v: Value) -> Result<Vec<String>, Fail> {
    match v {
        Value::String(k) => Ok(vec![k]),
        Value::List(keys) => keys
            .into_iter()
            .enumerate()
            .map(|(i, k)| match k {
                Value::String(k) => Ok(k),
                other => null(format!(
                    "key {} of the path must be a string, not a {}",
                    i + 1,
                    other.type_name()
                )),
            })
            .collect(),
        other => Err(super::wrong("key", "a string or a list of strings", &other)),
    }
}

/// `get value(context, key)` and `get value(context, keys)`: the value of the entry `key`, or
/// of the nested entry the path `keys` names; null if there is no such entry or `keys` is
/// empty.
pub(super) fn get_value(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [c, key] = take(args);
    let c = context(c, "context")?;
    let keys = path(key)?;
    host.spend(keys.len())?;
    if keys.is_empty() {
        return null("the path of keys is empty");
    }
    let mut current = Value::Context(c);
    for k in &keys {
        current = match current {
            Value::Context(mut c) => match c.0.iter().position(|(name, _)| name == k) {
                Some(i) => c.0.swap_remove(i).1,
                None => return null(format!("no entry {k:?}")),
            },
            other => {
                return null(format!(
                    "no entry {k:?}: the value on the way is a {}",
                    other.type_name()
                ));
            }
        };
    }
    Ok(current)
}

/// `get entries(context)`: the entries as a list of `{key, value}` contexts, in order.
pub(super) fn get_entries(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [c] = take(args);
    let c = context(c, "context")?;
    host.spend(c.0.len())?;
    Ok(Value::List(
        c.0.into_iter()
            .map(|(k, v)| {
                Value::Context(Context(vec![
                    ("key".to_owned(), Value::String(k)),
                    ("value".to_owned(), v),
                ]))
            })
            .collect(),
    ))
}

/// `context put(context, key, value)` and `context put(context, keys, value)` (also the
/// deprecated `put`): the context with the entry `key`, or the nested entry the path `keys`
/// names, set to `value` (replacing an entry in place, creating missing or non-context levels
/// as contexts); null for an empty path.
pub(super) fn put(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [c, key, value] = take(args);
    let c = context(c, "context")?;
    let keys = path(key)?;
    host.spend(keys.len())?;
    let Some((last, outer)) = keys.split_last() else {
        return null("the path of keys is empty");
    };
    // Walk down, taking each level out of its parent; then put the levels back bottom-up.
    let mut levels: Vec<Context> = Vec::with_capacity(keys.len());
    let mut current = c;
    for k in outer {
        let inner = match current.0.iter().position(|(name, _)| name == k) {
            Some(i) => match current
                .0
                .get_mut(i)
                .map(|e| std::mem::replace(&mut e.1, Value::Null))
            {
                Some(Value::Context(inner)) => inner,
                _ => Context::default(),
            },
            None => Context::default(),
        };
        levels.push(current);
        current = inner;
    }
    current.put(last.clone(), value);
    for k in outer.iter().rev() {
        let Some(mut parent) = levels.pop() else {
            break;
        };
        parent.put(k.clone(), Value::Context(current));
        current = parent;
    }
    Ok(Value::Context(current))
}

/// `context merge(contexts)` / `context merge(c1, c2, …)` (also the deprecated `put all`): one
/// context with the entries of all, later ones replacing earlier ones of the same key.
pub(super) fn merge(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let contexts = list(Value::List(varargs(args)), "contexts")?;
    let mut out = Entries::default();
    for (i, c) in contexts.into_iter().enumerate() {
        match c {
            Value::Context(c) => {
                host.spend(c.0.len())?;
                for (k, v) in c.0 {
                    out.put(k, v);
                }
            }
            Value::Null => return null(format!("item {} is null, not a context", i + 1)),
            other => {
                return null(format!(
                    "item {} must be a context, not a {}",
                    i + 1,
                    other.type_name()
                ));
            }
        }
    }
    Ok(Value::Context(out.done()))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, check, nulls};
    use crate::value::{Context, Value};

    #[test]
    fn get_value_by_key_and_path() {
        check(&[
            ("get value({foo: 123}, \"foo\")", "123"),
            ("get value({a: 1}, \"b\")", "null"),
            ("get value({a: null}, \"a\")", "null"),
            ("get value({x: 1, y: {z: 0}}, [\"y\", \"z\"])", "0"),
            ("get value({x: {y: {z: 0}}}, [\"x\", \"y\"])", "{z: 0}"),
            ("get value({a: {b: 3}}, [\"b\"])", "null"),
            ("get value({a: 1}, [\"a\"])", "1"),
        ]);
        nulls(&[
            ("get value({a: 1}, \"b\")", "no entry \"b\""),
            ("get value({a: {b: 3}}, [\"a\", \"c\"])", "no entry \"c\""),
            (
                "get value({a: 1}, [\"a\", \"b\"])",
                "the value on the way is a number",
            ),
            ("get value({a: 1}, [])", "the path of keys is empty"),
            (
                "get value({a: 1}, [\"a\", 1])",
                "key 2 of the path must be a string, not a number",
            ),
            ("get value(null, \"a\")", "`context` is null"),
            (
                "get value([1], \"a\")",
                "`context` must be a context, not a list",
            ),
            ("get value({a: 1}, null)", "`key` is null"),
            (
                "get value({a: 1}, 1)",
                "must be a string or a list of strings",
            ),
        ]);
    }

    #[test]
    fn get_entries_lists_pairs() {
        check(&[
            ("get entries({foo: 123})", "[{key: \"foo\", value: 123}]"),
            (
                "get entries({b: 1, a: [2]})",
                "[{key: \"b\", value: 1}, {key: \"a\", value: [2]}]",
            ),
            ("get entries({})", "[]"),
        ]);
        nulls(&[
            ("get entries(null)", "`context` is null"),
            ("get entries([])", "must be a context"),
        ]);
    }

    #[test]
    fn context_put_by_key_and_path() {
        check(&[
            ("context put({x: 1}, \"y\", 2)", "{x: 1, y: 2}"),
            ("context put({x: 1, y: 0}, \"x\", 2)", "{x: 2, y: 0}"),
            ("context put({x: 1}, \"y\", null)", "{x: 1, y: null}"),
            ("context put({}, \"a\", 1)", "{a: 1}"),
            ("context put({x: 1}, [\"y\"], 2)", "{x: 1, y: 2}"),
            (
                "context put({x: 1, y: {z: 0}}, [\"y\", \"z\"], 2)",
                "{x: 1, y: {z: 2}}",
            ),
            (
                "context put({x: 1}, [\"y\", \"z\"], 2)",
                "{x: 1, y: {z: 2}}",
            ),
            (
                "context put({x: 1, y: 5}, [\"y\", \"z\"], 2)",
                "{x: 1, y: {z: 2}}",
            ),
            (
                "context put({a: {b: {c: 1, d: 2}, e: 3}}, [\"a\", \"b\", \"c\"], 9)",
                "{a: {b: {c: 9, d: 2}, e: 3}}",
            ),
            ("put({x: 1}, \"y\", 2)", "{x: 1, y: 2}"),
        ]);
        nulls(&[
            ("context put({x: 1}, [], 2)", "the path of keys is empty"),
            ("context put(null, \"a\", 1)", "`context` is null"),
            ("context put({}, null, 1)", "`key` is null"),
            (
                "context put({}, [\"a\", null], 1)",
                "key 2 of the path must be a string",
            ),
            ("put(1, \"a\", 1)", "must be a context"),
        ]);
    }

    #[test]
    fn context_put_deep_path_without_recursion() {
        let keys: Vec<Value> = (0..50_000)
            .map(|i| Value::String(format!("k{i}")))
            .collect();
        let mut host = Mock::new(10_000_000);
        let out = super::put(
            &mut host,
            vec![
                Value::Context(Context::default()),
                Value::List(keys.clone()),
                Value::int(1),
            ],
        );
        let Ok(out) = out else { panic!("a context") };
        let got = super::get_value(&mut host, vec![out, Value::List(keys)]);
        assert!(matches!(got, Ok(Value::Number(n)) if n == 1.into()));
    }

    #[test]
    fn context_merge_in_order() {
        check(&[
            ("context merge([{x: 1}, {y: 2}])", "{x: 1, y: 2}"),
            ("context merge([{x: 1, y: 0}, {y: 2}])", "{x: 1, y: 2}"),
            ("context merge({x: 1}, {y: 2})", "{x: 1, y: 2}"),
            ("context merge([{a: 1}])", "{a: 1}"),
            ("context merge([{}])", "{}"),
            ("context merge([])", "{}"),
            ("context merge({a: 1})", "{a: 1}"),
            ("put all({x: 1}, {y: 2})", "{x: 1, y: 2}"),
            ("put all([{x: 1}, {x: 2}])", "{x: 2}"),
        ]);
        nulls(&[
            (
                "context merge([{a: 1}, 1])",
                "item 2 must be a context, not a number",
            ),
            ("context merge(null)", "item 1 is null, not a context"),
            ("context merge({a: 1}, null)", "item 2 is null"),
            ("put all([1])", "item 1 must be a context"),
        ]);
    }
}

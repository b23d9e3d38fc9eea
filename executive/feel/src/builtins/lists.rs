//! List built-ins: membership and counting, the aggregates (`min`, `max`, `sum`, `product`,
//! `mean`, `median`, `stddev`, `mode`, `all`/`and`, `any`/`or`), building and cutting lists
//! (`sublist`, `append`, `concatenate`, `insert before`, `remove`, `reverse`, `union`,
//! `partition`, `flatten`), searching (`index of`, `distinct values`, `duplicate values`),
//! `sort` and `string join`.
//!
//! Equality is FEEL's (`Value::feel_eq`), order FEEL's (`Value::compare`). Every function
//! spends budget in proportion to the elements it walks or makes; nothing recurses on the
//! depth of nested lists.
//!
//! One file over 1,000 lines, on purpose: these are one family of DMN's built-ins (the list
//! functions, with the aggregates that read lists), sharing their argument readers; the other
//! families have files of their own.

use std::cmp::Ordering;
use std::collections::BTreeMap;

use rust_decimal::Decimal;

use super::{Fail, Out, list, list_ref, null, take, text, varargs, whole, wrong};
use crate::host::{Host, Stop};
use crate::value::{Function, Value};

/// `list contains(list, element)`: whether an item equals `element`.
pub(super) fn contains(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, element] = take(args);
    let items = list_ref(&items, "list")?;
    host.spend(items.len())?;
    Ok(Value::Bool(
        items.iter().any(|i| i.feel_eq(&element) == Some(true)),
    ))
}

/// `count(list)`.
pub(super) fn count(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    Ok(Value::Number(list_ref(&items, "list")?.len().into()))
}

/// `is empty(list)`.
pub(super) fn is_empty(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    Ok(Value::Bool(list_ref(&items, "list")?.is_empty()))
}

/// The smallest (`want` Less) or greatest (Greater) item; null for an empty list or items that
/// cannot be compared.
fn extreme(host: &mut dyn Host, args: Vec<Value>, want: Ordering) -> Out {
    let items = varargs(args);
    host.spend(items.len())?;
    let mut it = items.into_iter();
    let Some(mut best) = it.next() else {
        return null("the list is empty");
    };
    for v in it {
        match v.compare(&best) {
            Some(o) if o == want => best = v,
            Some(_) => {}
            None => {
                return null(format!(
                    "cannot compare {} with {}",
                    describe(&v),
                    describe(&best)
                ));
            }
        }
    }
    if best.compare(&best).is_none() {
        return null(format!("cannot order {}", describe(&best)));
    }
    Ok(best)
}

/// A value's type for messages (`null` rather than "a null").
fn describe(v: &Value) -> String {
    if v.is_null() {
        "null".to_owned()
    } else {
        format!("a {}", v.type_name())
    }
}

/// `min(list)` / `min(c1, c2, …)`.
pub(super) fn min(host: &mut dyn Host, args: Vec<Value>) -> Out {
    extreme(host, args, Ordering::Less)
}

/// `max(list)` / `max(c1, c2, …)`.
pub(super) fn max(host: &mut dyn Host, args: Vec<Value>) -> Out {
    extreme(host, args, Ordering::Greater)
}

/// The numbers of a variadic aggregate; null if one is not a number or there are none.
fn numbers(host: &mut dyn Host, args: Vec<Value>) -> Result<Vec<Decimal>, Fail> {
    let items = varargs(args);
    host.spend(items.len())?;
    if items.is_empty() {
        return null("the list is empty");
    }
    items
        .iter()
        .enumerate()
        .map(|(i, v)| match v {
            Value::Number(n) => Ok(*n),
            other => null(format!(
                "item {} must be a number, not {}",
                i + 1,
                describe(other)
            )),
        })
        .collect()
}

/// The sum of numbers; `None` on overflow.
fn total(ns: &[Decimal]) -> Option<Decimal> {
    ns.iter()
        .try_fold(Decimal::ZERO, |acc, n| acc.checked_add(*n))
}

/// `sum(list)` / `sum(n1, n2, …)`: null for an empty list.
pub(super) fn sum(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let ns = numbers(host, args)?;
    match total(&ns) {
        Some(s) => Ok(Value::Number(s)),
        None => null("the sum is out of range"),
    }
}

/// `product(list)` / `product(n1, n2, …)`: null for an empty list.
pub(super) fn product(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let ns = numbers(host, args)?;
    match ns
        .iter()
        .try_fold(Decimal::ONE, |acc, n| acc.checked_mul(*n))
    {
        Some(p) => Ok(Value::Number(p)),
        None => null("the product is out of range"),
    }
}

/// The arithmetic mean; `None` on overflow.
fn average(ns: &[Decimal]) -> Option<Decimal> {
    total(ns)?.checked_div(Decimal::from(ns.len()))
}

/// `mean(list)` / `mean(n1, n2, …)`.
pub(super) fn mean(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let ns = numbers(host, args)?;
    match average(&ns) {
        Some(m) => Ok(Value::Number(m)),
        None => null("the sum is out of range"),
    }
}

/// `median(list)` / `median(n1, n2, …)`: the middle number, or the mean of the two middle
/// ones.
pub(super) fn median(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let mut ns = numbers(host, args)?;
    ns.sort();
    let mid = ns.len() / 2;
    let m = if ns.len() % 2 == 1 {
        ns.get(mid).copied()
    } else {
        match (ns.get(mid.wrapping_sub(1)), ns.get(mid)) {
            // a ≤ b: when a + b overflows both have the same sign and b − a cannot.
            (Some(a), Some(b)) => a
                .checked_add(*b)
                .and_then(|s| s.checked_div(Decimal::TWO))
                .or_else(|| a.checked_add(b.checked_sub(*a)?.checked_div(Decimal::TWO)?)),
            _ => None,
        }
    };
    match m {
        Some(m) => Ok(Value::Number(m)),
        None => null("the median is out of range"),
    }
}

/// `stddev(list)` / `stddev(n1, n2, …)`: the sample standard deviation (n − 1); null for fewer
/// than two numbers.
pub(super) fn stddev(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let ns = numbers(host, args)?;
    if ns.len() < 2 {
        return null("needs at least two numbers");
    }
    let Some(mean) = average(&ns) else {
        return null("the sum is out of range");
    };
    let squares = ns.iter().try_fold(Decimal::ZERO, |acc, n| {
        let d = n.checked_sub(mean)?;
        acc.checked_add(d.checked_mul(d)?)
    });
    let variance = squares.and_then(|s| s.checked_div(Decimal::from(ns.len() - 1)));
    match variance.and_then(super::numbers::square_root) {
        Some(s) => Ok(Value::Number(s)),
        None => null("the result is out of range"),
    }
}

/// `mode(list)` / `mode(n1, n2, …)`: the most frequent numbers, ascending; `[]` for an empty
/// list.
pub(super) fn mode(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let items = varargs(args);
    if items.is_empty() {
        return Ok(Value::List(Vec::new()));
    }
    let ns = numbers(host, items)?;
    let mut counts: BTreeMap<Decimal, usize> = BTreeMap::new();
    for n in ns {
        *counts.entry(n).or_default() += 1;
    }
    let top = counts.values().copied().max().unwrap_or(0);
    Ok(Value::List(
        counts
            .into_iter()
            .filter(|&(_, c)| c == top)
            .map(|(n, _)| Value::Number(n))
            .collect(),
    ))
}

/// `all(list)` / `and(list)` and their variadic forms: false if an item is false, else null if
/// an item is not a boolean, else true (`all([])` is true).
pub(super) fn all(host: &mut dyn Host, args: Vec<Value>) -> Out {
    decide(host, args, false)
}

/// `any(list)` / `or(list)` and their variadic forms: true if an item is true, else null if an
/// item is not a boolean, else false (`any([])` is false).
pub(super) fn any(host: &mut dyn Host, args: Vec<Value>) -> Out {
    decide(host, args, true)
}

/// Three-valued `all` (`decisive` false) or `any` (`decisive` true).
fn decide(host: &mut dyn Host, args: Vec<Value>, decisive: bool) -> Out {
    let items = varargs(args);
    host.spend(items.len())?;
    if items
        .iter()
        .any(|v| matches!(v, Value::Bool(b) if *b == decisive))
    {
        return Ok(Value::Bool(decisive));
    }
    if let Some((i, v)) = items
        .iter()
        .enumerate()
        .find(|(_, v)| !matches!(v, Value::Bool(_)))
    {
        return null(format!(
            "item {} must be a boolean, not {}",
            i + 1,
            describe(v)
        ));
    }
    Ok(Value::Bool(!decisive))
}

/// `sublist(list, start position)` and `sublist(list, start position, length)`: the items from
/// `start position` (1-based; negative counts from the end), `length` of them or to the end;
/// a slice beyond the list's ends is cut to it (feel-scala), position 0 is null.
pub(super) fn sublist(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [items, start, length] = take(args);
    let items = list(items, "list")?;
    let start = whole(&start, "start position")?;
    let len = i64::try_from(items.len()).unwrap_or(i64::MAX);
    let from = match start {
        0 => return null("positions start at 1 (or -1 from the end), not 0"),
        s if s > 0 => s - 1,
        s => len.saturating_add(s),
    };
    let to = if n < 3 {
        len
    } else {
        from.saturating_add(whole(&length, "length")?)
    };
    let (from, to) = (from.clamp(0, len), to.clamp(0, len));
    if from >= to {
        return Ok(Value::List(Vec::new()));
    }
    let (from, to) = (
        usize::try_from(from).unwrap_or(0),
        usize::try_from(to).unwrap_or(0),
    );
    host.spend(to - from)?;
    Ok(Value::List(
        items.into_iter().skip(from).take(to - from).collect(),
    ))
}

/// `append(list, item…)`: the list with the items added at the end.
pub(super) fn append(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let mut args = args.into_iter();
    let mut items = list(args.next().unwrap_or(Value::Null), "list")?;
    let more: Vec<Value> = args.collect();
    host.spend(items.len() + more.len())?;
    items.extend(more);
    Ok(Value::List(items))
}

/// The items of several lists in order; an argument that is not a list counts as a list of
/// itself (feel-scala).
fn joined(host: &mut dyn Host, args: Vec<Value>) -> Result<Vec<Value>, Fail> {
    let parts = varargs(args);
    let mut out = Vec::new();
    for p in parts {
        match p {
            Value::List(items) => {
                host.spend(items.len())?;
                out.extend(items);
            }
            other => {
                host.spend(1)?;
                out.push(other);
            }
        }
    }
    Ok(out)
}

/// `concatenate(list…)`: the lists' items in order.
pub(super) fn concatenate(host: &mut dyn Host, args: Vec<Value>) -> Out {
    Ok(Value::List(joined(host, args)?))
}

/// `union(list…)`: the lists' items in order, without duplicates.
pub(super) fn union(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let items = joined(host, args)?;
    let class = classes(host, &items)?;
    Ok(Value::List(
        items
            .into_iter()
            .zip(class)
            .enumerate()
            .filter(|(i, (_, c))| c == i)
            .map(|(_, (v, _))| v)
            .collect(),
    ))
}

/// The 0-based index for `position` (1-based, negative from the end) in a list of `len`;
/// one past the end is allowed only when `past_end`.
fn index(position: i64, len: usize, past_end: bool) -> Result<usize, Fail> {
    match super::strings::position(position, len).filter(|&i| past_end || i < len) {
        Some(i) => Ok(i),
        None => null(format!(
            "position {position} is outside the list (length {len})"
        )),
    }
}

/// `insert before(list, position, newItem)`: the list with `newItem` inserted before the item
/// at `position` (1-based, negative from the end; one past the end appends).
pub(super) fn insert_before(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, position, new_item] = take(args);
    let mut items = list(items, "list")?;
    let at = index(whole(&position, "position")?, items.len(), true)?;
    host.spend(items.len() + 1)?;
    items.insert(at, new_item);
    Ok(Value::List(items))
}

/// `remove(list, position)`: the list without the item at `position` (1-based, negative from
/// the end).
pub(super) fn remove(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, position] = take(args);
    let mut items = list(items, "list")?;
    let at = index(whole(&position, "position")?, items.len(), false)?;
    host.spend(items.len())?;
    items.remove(at);
    Ok(Value::List(items))
}

/// `reverse(list)`.
pub(super) fn reverse(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    let mut items = list(items, "list")?;
    host.spend(items.len())?;
    items.reverse();
    Ok(Value::List(items))
}

/// `index of(list, match)`: the positions (1-based) of the items equal to `match`.
pub(super) fn index_of(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, m] = take(args);
    let items = list_ref(&items, "list")?;
    host.spend(items.len())?;
    Ok(Value::List(
        items
            .iter()
            .enumerate()
            .filter(|(_, v)| v.feel_eq(&m) == Some(true))
            .map(|(i, _)| Value::Number((i + 1).into()))
            .collect(),
    ))
}

/// A value that can be ordered for duplicate detection, equal exactly when FEEL equality says
/// so (numbers by value: `1 = 1.0`).
#[derive(PartialEq, Eq, PartialOrd, Ord)]
enum Key<'a> {
    Null,
    Bool(bool),
    Number(Decimal),
    String(&'a str),
}

/// The key of a simple value; `None` for lists, contexts, ranges, temporal values and
/// functions (compared one by one).
fn key(v: &Value) -> Option<Key<'_>> {
    match v {
        Value::Null => Some(Key::Null),
        Value::Bool(b) => Some(Key::Bool(*b)),
        Value::Number(n) => Some(Key::Number(*n)),
        Value::String(s) => Some(Key::String(s)),
        _ => None,
    }
}

/// For each item, the index of the first item equal to it (FEEL equality). Simple values are
/// found through an ordered map; the others are compared with each earlier distinct one,
/// spending a step per comparison.
fn classes(host: &mut dyn Host, items: &[Value]) -> Result<Vec<usize>, Stop> {
    host.spend(items.len())?;
    let mut simple: BTreeMap<Key<'_>, usize> = BTreeMap::new();
    let mut complex: Vec<usize> = Vec::new();
    let mut out = Vec::with_capacity(items.len());
    for (i, v) in items.iter().enumerate() {
        let class = match key(v) {
            Some(k) => *simple.entry(k).or_insert(i),
            None => {
                host.spend(complex.len())?;
                match complex
                    .iter()
                    .copied()
                    .find(|&j| items.get(j).and_then(|w| w.feel_eq(v)) == Some(true))
                {
                    Some(j) => j,
                    None => {
                        complex.push(i);
                        i
                    }
                }
            }
        };
        out.push(class);
    }
    Ok(out)
}

/// `distinct values(list)`: the items without repeats, in first-seen order.
pub(super) fn distinct_values(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    let items = list(items, "list")?;
    let class = classes(host, &items)?;
    Ok(Value::List(
        items
            .into_iter()
            .zip(class)
            .enumerate()
            .filter(|(i, (_, c))| c == i)
            .map(|(_, (v, _))| v)
            .collect(),
    ))
}

/// `duplicate values(list)`: the items that occur more than once, each once, in first-seen
/// order.
pub(super) fn duplicate_values(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    let items = list(items, "list")?;
    let class = classes(host, &items)?;
    let mut seen = vec![0usize; items.len()];
    for &c in &class {
        if let Some(s) = seen.get_mut(c) {
            *s += 1;
        }
    }
    Ok(Value::List(
        items
            .into_iter()
            .enumerate()
            .filter(|(i, _)| class.get(*i) == Some(i) && seen.get(*i).is_some_and(|&n| n > 1))
            .map(|(_, v)| v)
            .collect(),
    ))
}

/// `flatten(list)`: the items of nested lists, at any depth, in order (walked with an explicit
/// stack).
pub(super) fn flatten(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items] = take(args);
    let items = list(items, "list")?;
    host.spend(items.len())?;
    let mut out = Vec::new();
    let mut stack = vec![items.into_iter()];
    while let Some(top) = stack.last_mut() {
        match top.next() {
            Some(Value::List(inner)) => {
                host.spend(inner.len())?;
                stack.push(inner.into_iter());
            }
            Some(v) => out.push(v),
            None => {
                stack.pop();
            }
        }
    }
    Ok(Value::List(out))
}

/// `sort(list)` (ascending, the items must be comparable) and `sort(list, precedes)` (ordered
/// by a function of two items that is true when the first comes before the second). Stable.
pub(super) fn sort(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [items, precedes] = take(args);
    let items = list(items, "list")?;
    host.spend(items.len())?;
    let order = if n < 2 {
        merge_sort(items.len(), &mut |a, b| {
            let (Some(x), Some(y)) = (items.get(a), items.get(b)) else {
                return Ok(false);
            };
            match x.compare(y) {
                Some(o) => Ok(o == Ordering::Less),
                None => null(format!(
                    "cannot compare {} with {}",
                    describe(x),
                    describe(y)
                )),
            }
        })?
    } else {
        match &precedes {
            Value::Function(Function::Lambda(l)) if l.params.len() != 2 => {
                return null(format!(
                    "`precedes` must be a function of two parameters, not {}",
                    l.params.len()
                ));
            }
            Value::Function(_) => {}
            other => return Err(wrong("precedes", "a function", other)),
        }
        merge_sort(items.len(), &mut |a, b| {
            let (Some(x), Some(y)) = (items.get(a), items.get(b)) else {
                return Ok(false);
            };
            match host.apply(&precedes, vec![x.clone(), y.clone()])? {
                Value::Bool(b) => Ok(b),
                other => null(format!(
                    "`precedes` must return a boolean, not {}",
                    describe(&other)
                )),
            }
        })?
    };
    let mut slots: Vec<Option<Value>> = items.into_iter().map(Some).collect();
    Ok(Value::List(
        order
            .into_iter()
            .filter_map(|i| slots.get_mut(i).and_then(Option::take))
            .collect(),
    ))
}

/// A stable bottom-up merge sort of the indices `0..n`; `less(a, b)` tells whether item `a`
/// must come before item `b`. Total for any `less` (an inconsistent one gives some order).
fn merge_sort(
    n: usize,
    less: &mut dyn FnMut(usize, usize) -> Result<bool, Fail>,
) -> Result<Vec<usize>, Fail> {
    let mut src: Vec<usize> = (0..n).collect();
    let mut dst: Vec<usize> = Vec::with_capacity(n);
    let mut width = 1usize;
    while width < n {
        dst.clear();
        let mut lo = 0;
        while lo < n {
            let mid = lo.saturating_add(width).min(n);
            let hi = lo.saturating_add(width.saturating_mul(2)).min(n);
            let (left, right) = (
                src.get(lo..mid).unwrap_or(&[]),
                src.get(mid..hi).unwrap_or(&[]),
            );
            let (mut i, mut j) = (0, 0);
            while let (Some(&a), Some(&b)) = (left.get(i), right.get(j)) {
                if less(b, a)? {
                    dst.push(b);
                    j += 1;
                } else {
                    dst.push(a);
                    i += 1;
                }
            }
            dst.extend_from_slice(left.get(i..).unwrap_or(&[]));
            dst.extend_from_slice(right.get(j..).unwrap_or(&[]));
            lo = hi;
        }
        std::mem::swap(&mut src, &mut dst);
        width = width.saturating_mul(2);
    }
    Ok(src)
}

/// `string join(list)`, `string join(list, delimiter)`,
/// `string join(list, delimiter, prefix, suffix)`: the strings joined; null items are skipped,
/// a null delimiter, prefix or suffix is empty.
pub(super) fn string_join(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, delimiter, prefix, suffix] = take(args);
    let items = list_ref(&items, "list")?;
    let opt = |v: &Value, p: &str| -> Result<String, Fail> {
        match v {
            Value::Null => Ok(String::new()),
            other => Ok(text(other, p)?.to_owned()),
        }
    };
    let (delimiter, prefix, suffix) = (
        opt(&delimiter, "delimiter")?,
        opt(&prefix, "prefix")?,
        opt(&suffix, "suffix")?,
    );
    host.spend(items.len())?;
    let mut parts = Vec::with_capacity(items.len());
    for (i, v) in items.iter().enumerate() {
        match v {
            Value::String(s) => parts.push(s.as_str()),
            Value::Null => {}
            other => {
                return null(format!(
                    "item {} must be a string, not a {}",
                    i + 1,
                    other.type_name()
                ));
            }
        }
    }
    let out = format!("{prefix}{}{suffix}", parts.join(&delimiter));
    host.spend(out.len() / 64)?;
    Ok(Value::String(out))
}

/// `partition(list, size)`: the list cut into lists of `size` items (the last may be shorter).
pub(super) fn partition(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [items, size] = take(args);
    let items = list(items, "list")?;
    let n = super::number(&size, "size")?;
    let size = match usize::try_from(whole(&size, "size")?) {
        Ok(s) if s > 0 && n.fract().is_zero() => s,
        _ => return null(format!("the size must be a whole number above 0, not {n}")),
    };
    host.spend(items.len())?;
    let mut out = Vec::with_capacity(items.len().div_ceil(size));
    let mut it = items.into_iter().peekable();
    while it.peek().is_some() {
        out.push(Value::List(it.by_ref().take(size).collect()));
    }
    Ok(Value::List(out))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, call_with, check, nulls};
    use super::merge_sort;
    use crate::host::Stop;

    #[test]
    fn contains_count_is_empty() {
        check(&[
            ("list contains([1, 2, 3], 2)", "true"),
            ("list contains([1, 2, 3], 4)", "false"),
            ("list contains([1, 2.0, 3], 2)", "true"),
            ("list contains([1, null], null)", "true"),
            ("list contains([1], null)", "false"),
            ("list contains([[1, 2], {a: 1}], {a: 1})", "true"),
            ("list contains([\"a\"], 1)", "false"),
            ("count([1, 2, 3])", "3"),
            ("count([])", "0"),
            ("count([1, [2, 3]])", "2"),
            ("is empty([])", "true"),
            ("is empty([1, 2, 3])", "false"),
            ("is empty([null])", "false"),
        ]);
        nulls(&[
            ("list contains(null, 1)", "`list` is null"),
            (
                "list contains(\"a\", \"a\")",
                "`list` must be a list, not a string",
            ),
            ("count(null)", "`list` is null"),
            ("count(1)", "must be a list"),
            ("is empty(null)", "`list` is null"),
            ("is empty(\"\")", "must be a list"),
        ]);
    }

    #[test]
    fn min_max() {
        check(&[
            ("min([1, 2, 3])", "1"),
            ("min(1, 2, 3)", "1"),
            ("min(1)", "1"),
            ("min([\"b\", \"a\", \"c\"])", "\"a\""),
            ("max([1, 2, 3])", "3"),
            ("max(1, 2, 3)", "3"),
            ("max([2.5, -1])", "2.5"),
            ("max(\"a\", \"b\")", "\"b\""),
            ("min([[1]])", "null"),
        ]);
        nulls(&[
            ("min([])", "the list is empty"),
            ("min()", "the list is empty"),
            ("max([])", "the list is empty"),
            ("min([1, \"a\"])", "cannot compare a string with a number"),
            ("max([1, null])", "cannot compare null with a number"),
            ("min(null)", "cannot order null"),
            (
                "max([true, false])",
                "cannot compare a boolean with a boolean",
            ),
            ("max([{a: 1}])", "cannot order a context"),
        ]);
    }

    #[test]
    fn sums_and_statistics() {
        check(&[
            ("sum([1, 2, 3])", "6"),
            ("sum(1, 2, 3)", "6"),
            ("sum(1)", "1"),
            ("sum([0.1, 0.2])", "0.3"),
            ("product([2, 3, 4])", "24"),
            ("product(2, 3, 4)", "24"),
            ("mean([1, 2, 3])", "2"),
            ("mean(1, 2, 3)", "2"),
            ("mean([1, 2])", "1.5"),
            ("median(8, 2, 5, 3, 4)", "4"),
            ("median([6, 1, 2, 3])", "2.5"),
            ("median([3])", "3"),
            ("stddev(2, 4, 7, 5)", "2.0816659994661327352822977070"),
            ("stddev([47])", "null"),
            ("stddev([1, 1])", "0"),
            ("mode(6, 3, 9, 6, 6)", "[6]"),
            ("mode([6, 1, 9, 6, 1])", "[1, 6]"),
            ("mode([])", "[]"),
            ("mode([1.0, 1, 2])", "[1]"),
        ]);
        nulls(&[
            ("sum([])", "the list is empty"),
            ("sum(null)", "item 1 must be a number, not null"),
            ("sum([1, \"a\"])", "item 2 must be a number, not a string"),
            (
                "sum([79228162514264337593543950335, 1])",
                "the sum is out of range",
            ),
            ("product([])", "the list is empty"),
            (
                "product([79228162514264337593543950335, 2])",
                "the product is out of range",
            ),
            ("product([1, null])", "item 2 must be a number"),
            ("mean([])", "the list is empty"),
            ("mean([\"a\"])", "must be a number"),
            ("median([])", "the list is empty"),
            (
                "median([1, true])",
                "item 2 must be a number, not a boolean",
            ),
            ("stddev([])", "the list is empty"),
            ("stddev([47])", "needs at least two numbers"),
            ("stddev([1, \"a\"])", "item 2 must be a number"),
            ("mode([1, \"a\"])", "item 2 must be a number"),
        ]);
    }

    #[test]
    fn median_of_huge_numbers_does_not_overflow() {
        check(&[(
            "median([79228162514264337593543950335, 79228162514264337593543950335])",
            "79228162514264337593543950335",
        )]);
    }

    #[test]
    fn all_and_any_are_three_valued() {
        check(&[
            ("all([false, null, true])", "false"),
            ("all([true, true])", "true"),
            ("all(true)", "true"),
            ("all([])", "true"),
            ("all()", "true"),
            ("all(false, null, true)", "false"),
            ("and([false, null, true])", "false"),
            ("and([])", "true"),
            ("any([false, null, true])", "true"),
            ("any([false, false])", "false"),
            ("any(false)", "false"),
            ("any([])", "false"),
            ("any(false, null, true)", "true"),
            ("or([false, null, true])", "true"),
            ("or([])", "false"),
        ]);
        nulls(&[
            ("all([true, null])", "item 2 must be a boolean, not null"),
            ("all(0)", "item 1 must be a boolean, not a number"),
            ("any([false, \"x\"])", "item 2 must be a boolean"),
            ("any(null)", "item 1 must be a boolean, not null"),
            ("or([null])", "not null"),
        ]);
    }

    #[test]
    fn sublist_cuts() {
        check(&[
            ("sublist([4, 5, 6], 1, 2)", "[4, 5]"),
            ("sublist([1, 2, 3], 2)", "[2, 3]"),
            ("sublist([1, 2, 3], 1, 2)", "[1, 2]"),
            ("sublist([1, 2, 3], -2)", "[2, 3]"),
            ("sublist([1, 2, 3], -2, 1)", "[2]"),
            ("sublist([1, 2, 3], 3, 5)", "[3]"),
            ("sublist([1, 2, 3], 4)", "[]"),
            ("sublist([1, 2, 3], 2, 0)", "[]"),
            ("sublist([1, 2, 3], 2, -1)", "[]"),
            ("sublist([1, 2, 3], -5, 3)", "[1]"),
            ("sublist([], 1)", "[]"),
            ("sublist([1, 2, 3], 99999999999999999999999, 1)", "[]"),
        ]);
        nulls(&[
            ("sublist([1, 2, 3], 0)", "positions start at 1"),
            ("sublist(null, 1)", "`list` is null"),
            ("sublist([1], null)", "`start position` is null"),
            ("sublist([1], 1, \"2\")", "`length` must be a number"),
        ]);
    }

    #[test]
    fn building_lists() {
        check(&[
            ("append([1], 2, 3)", "[1, 2, 3]"),
            ("append([], 1)", "[1]"),
            ("append([1])", "[1]"),
            ("append([1], [2])", "[1, [2]]"),
            ("append([1], null)", "[1, null]"),
            ("concatenate([1, 2], [3])", "[1, 2, 3]"),
            ("concatenate([1], [2], [3])", "[1, 2, 3]"),
            ("concatenate([], [])", "[]"),
            ("concatenate([[1]], [])", "[[1]]"),
            ("concatenate([1, 2], 3)", "[1, 2, 3]"),
            ("concatenate()", "[]"),
            ("insert before([1, 3], 1, 2)", "[2, 1, 3]"),
            ("insert before([1, 3], 2, 2)", "[1, 2, 3]"),
            ("insert before([1, 3], 3, 2)", "[1, 3, 2]"),
            ("insert before([1, 3], -1, 2)", "[1, 2, 3]"),
            ("insert before([1, 3], -2, 2)", "[2, 1, 3]"),
            ("insert before([], 1, \"a\")", "[\"a\"]"),
            ("insert before([1], 1, null)", "[null, 1]"),
            ("remove([1, 2, 3], 2)", "[1, 3]"),
            ("remove([1, 2, 3], -1)", "[1, 2]"),
            ("remove([1, 2, 3], -3)", "[2, 3]"),
            ("remove([[1]], 1)", "[]"),
            ("reverse([1, 2, 3])", "[3, 2, 1]"),
            ("reverse([])", "[]"),
            ("index of([1, 2, 3, 2], 2)", "[2, 4]"),
            ("index of([1, 2, 3], 4)", "[]"),
            ("index of([[1], {a: null}, null], {a: null})", "[2]"),
            ("union([1, 2], [2, 3])", "[1, 2, 3]"),
            ("union([1, 2.0], [2, [1], [1]])", "[1, 2.0, [1]]"),
            ("union([], [])", "[]"),
            ("union([1, 1])", "[1]"),
        ]);
        nulls(&[
            ("append(null, 1)", "`list` is null"),
            ("append(1, 2)", "`list` must be a list"),
            (
                "insert before([1, 3], 0, 2)",
                "position 0 is outside the list (length 2)",
            ),
            ("insert before([1, 3], 4, 2)", "outside the list"),
            ("insert before([1, 3], -3, 2)", "outside the list"),
            ("insert before([], -1, 2)", "outside the list"),
            ("insert before(null, 1, 2)", "`list` is null"),
            (
                "remove([1, 2, 3], 4)",
                "position 4 is outside the list (length 3)",
            ),
            ("remove([1, 2, 3], 0)", "outside the list"),
            ("remove([], 1)", "outside the list"),
            ("remove([1], null)", "`position` is null"),
            ("reverse(null)", "`list` is null"),
            ("index of(null, 1)", "`list` is null"),
        ]);
    }

    #[test]
    fn distinct_and_duplicates() {
        check(&[
            ("distinct values([1, 2, 3, 2, 1])", "[1, 2, 3]"),
            ("distinct values([1, 1.0, \"1\"])", "[1, \"1\"]"),
            (
                "distinct values([[1], [1], [2], {a: 1}, {a: 1}])",
                "[[1], [2], {a: 1}]",
            ),
            (
                "distinct values([null, null, true, false, true])",
                "[null, true, false]",
            ),
            ("distinct values([@not, @not])", "[@not, @not]"),
            ("distinct values([])", "[]"),
            ("duplicate values([1, 2, 3, 2, 1])", "[1, 2]"),
            ("duplicate values([1, 2, 3])", "[]"),
            ("duplicate values([[1], 2, [1], [1]])", "[[1]]"),
            (
                "duplicate values([\"a\", \"b\", \"a\", null, null])",
                "[\"a\", null]",
            ),
        ]);
        nulls(&[
            ("distinct values(null)", "`list` is null"),
            ("duplicate values(1)", "must be a list"),
        ]);
    }

    #[test]
    fn flatten_any_depth() {
        check(&[
            ("flatten([[1, 2], [[3]], 4])", "[1, 2, 3, 4]"),
            ("flatten([[], [[]], 1])", "[1]"),
            ("flatten([])", "[]"),
            ("flatten([{a: [1]}])", "[{a: [1]}]"),
        ]);
        nulls(&[("flatten(null)", "`list` is null")]);
    }

    #[test]
    fn flatten_deep_nesting_without_recursion() {
        let mut v = crate::value::Value::List(vec![crate::value::Value::int(1)]);
        for _ in 0..100_000 {
            v = crate::value::Value::List(vec![v]);
        }
        let mut host = Mock::new(10_000_000);
        let out = super::flatten(&mut host, vec![v]);
        match out {
            Ok(crate::value::Value::List(items)) => assert_eq!(items.len(), 1),
            _ => panic!("want [1]"),
        }
    }

    #[test]
    fn sorting() {
        check(&[
            ("sort([3, 1, 4, 5, 2])", "[1, 2, 3, 4, 5]"),
            ("sort([\"b\", \"a\"])", "[\"a\", \"b\"]"),
            ("sort([])", "[]"),
            ("sort([3, 1, 4, 5, 2], @before)", "[1, 2, 3, 4, 5]"),
            ("sort([3, 1, 4, 5, 2], @after)", "[5, 4, 3, 2, 1]"),
            ("sort([1], @sum)", "[1]"),
        ]);
        nulls(&[
            ("sort([1, \"a\"])", "cannot compare"),
            ("sort([null, 1])", "cannot compare"),
            (
                "sort([3, 1], @sum)",
                "`precedes` must return a boolean, not a number",
            ),
            (
                "sort([3, 1], 1)",
                "`precedes` must be a function, not a number",
            ),
            ("sort([3, 1], null)", "`precedes` is null"),
            ("sort(null)", "`list` is null"),
        ]);
    }

    #[test]
    fn sorting_is_stable() {
        // 1.0, 1 and 1.00 are equal; their scales tell them apart.
        for c in [
            "sort([2, 1.0, 3, 1, 1.00])",
            "sort([2, 1.0, 3, 1, 1.00], @before)",
        ] {
            let (out, _) = super::super::testing::call(c);
            let scales: Vec<u32> = match out {
                Ok(crate::value::Value::List(items)) => items
                    .iter()
                    .filter_map(|v| v.as_number().map(|n| n.scale()))
                    .collect(),
                other => panic!("{c}: {other:?}"),
            };
            assert_eq!(scales, [1, 0, 2, 0, 0], "{c}");
        }
    }

    #[test]
    fn merge_sort_is_total_for_inconsistent_orders() {
        let mut flip = false;
        let order = merge_sort(37, &mut |_, _| {
            flip = !flip;
            Ok(flip)
        });
        let mut order = order.unwrap_or_default();
        order.sort_unstable();
        assert_eq!(order, (0..37).collect::<Vec<_>>());
    }

    #[test]
    fn joining_strings() {
        check(&[
            ("string join([\"a\", \"b\", \"c\"])", "\"abc\""),
            ("string join([\"a\", \"b\", \"c\"], \", \")", "\"a, b, c\""),
            (
                "string join([\"a\", \"b\", \"c\"], \", \", \"[\", \"]\")",
                "\"[a, b, c]\"",
            ),
            ("string join([\"a\", null, \"c\"])", "\"ac\""),
            ("string join([\"a\", null, \"c\"], \"-\")", "\"a-c\""),
            ("string join([])", "\"\""),
            ("string join([], \"x\", \"<\", \">\")", "\"<>\""),
            ("string join([\"a\", \"b\"], null)", "\"ab\""),
            ("string join([\"a\"], null, \"(\", \")\")", "\"(a)\""),
            ("string join([\"a\", \"b\"], \"+\", null, null)", "\"a+b\""),
        ]);
        nulls(&[
            (
                "string join([1, \"a\"])",
                "item 1 must be a string, not a number",
            ),
            ("string join(null)", "`list` is null"),
            ("string join([\"a\"], 1)", "`delimiter` must be a string"),
            (
                "string join([\"a\"], \"\", 1, \"\")",
                "`prefix` must be a string",
            ),
        ]);
    }

    #[test]
    fn partitions() {
        check(&[
            ("partition([1, 2, 3, 4, 5], 2)", "[[1, 2], [3, 4], [5]]"),
            ("partition([1, 2, 3], 3)", "[[1, 2, 3]]"),
            ("partition([1, 2], 5)", "[[1, 2]]"),
            ("partition([], 2)", "[]"),
        ]);
        nulls(&[
            (
                "partition([1, 2], 0)",
                "the size must be a whole number above 0, not 0",
            ),
            ("partition([1, 2], -1)", "above 0"),
            ("partition([1, 2], 1.5)", "above 0"),
            ("partition([1, 2], null)", "`size` is null"),
            ("partition(null, 2)", "`list` is null"),
        ]);
    }

    #[test]
    fn list_functions_spend_budget() {
        let rows = [
            "sublist([1, 2, 3, 4, 5, 6], 1)",
            "append([1, 2, 3, 4], 5, 6)",
            "concatenate([1, 2, 3], [4, 5, 6])",
            "flatten([[1, 2, 3], [4, 5, 6]])",
            "sort([6, 5, 4, 3, 2, 1])",
            "distinct values([1, 2, 3, 4, 5, 6])",
            "string join([\"a\", \"b\", \"c\", \"d\", \"e\", \"f\"])",
            "reverse([1, 2, 3, 4, 5, 6])",
            "partition([1, 2, 3, 4, 5, 6], 2)",
            "sum([1, 2, 3, 4, 5, 6])",
            "list contains([1, 2, 3, 4, 5, 6], 7)",
        ];
        for row in rows {
            let mut host = Mock::new(5);
            assert_eq!(
                call_with(&mut host, row).err(),
                Some(Stop::Budget(5)),
                "{row}"
            );
        }
    }
}

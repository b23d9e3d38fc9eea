//! Range built-ins (DMN 1.3 §10.3.4.9, Table 78): `before`, `after`, `meets`, `met by`,
//! `overlaps`, `overlaps before`, `overlaps after`, `finishes`, `finished by`, `includes`,
//! `during`, `starts`, `started by`, `coincides`, for points (any ordered value) and ranges.
//!
//! Each function looks at its argument types to pick the point/point, point/range,
//! range/point or range/range definition, so positional calls work whichever overload the
//! evaluator chose. An open end (`[1..]`, `< 5`) is infinite. Values that cannot be ordered
//! against each other give null.

use std::cmp::Ordering;

use super::{Fail, Out, null, take};
use crate::host::Host;
use crate::value::{Bound, Range, Value};

/// An end point: a value, or minus/plus infinity for an open end.
#[derive(Clone, Copy)]
enum End<'a> {
    /// Minus infinity: an open start.
    Below,
    /// A value.
    At(&'a Value),
    /// Plus infinity: an open end.
    Above,
}

/// A range, or a point as the degenerate closed range.
#[derive(Clone, Copy)]
struct Interval<'a> {
    start: End<'a>,
    start_in: bool,
    end: End<'a>,
    end_in: bool,
}

/// An argument: a point or a range.
enum Arg<'a> {
    Point(&'a Value),
    Range(Interval<'a>),
}

/// Reads an argument: a range, or any other non-null value as a point.
fn arg<'a>(v: &'a Value, param: &str) -> Result<Arg<'a>, Fail> {
    let end = |b: &'a Bound, open: End<'a>| match &b.value {
        Some(v) => End::At(v),
        None => open,
    };
    match v {
        Value::Null => null(format!("the {param} argument is null")),
        Value::Range(r) => {
            let Range { start, end: stop } = &**r;
            Ok(Arg::Range(Interval {
                start: end(start, End::Below),
                start_in: start.closed && start.value.is_some(),
                end: end(stop, End::Above),
                end_in: stop.closed && stop.value.is_some(),
            }))
        }
        point => Ok(Arg::Point(point)),
    }
}

/// Orders two end points.
fn cmp(a: End<'_>, b: End<'_>) -> Result<Ordering, Fail> {
    Ok(match (a, b) {
        (End::Below, End::Below) | (End::Above, End::Above) => Ordering::Equal,
        (End::Below, _) | (_, End::Above) => Ordering::Less,
        (End::Above, _) | (_, End::Below) => Ordering::Greater,
        (End::At(x), End::At(y)) => match x.compare(y) {
            Some(o) => o,
            None => {
                return null(format!("cannot compare {} with {}", name(x), name(y)));
            }
        },
    })
}

/// A value's type for messages.
fn name(v: &Value) -> String {
    if v.is_null() {
        "null".to_owned()
    } else {
        format!("a {}", v.type_name())
    }
}

/// `a < b`.
fn lt(a: End<'_>, b: End<'_>) -> Result<bool, Fail> {
    Ok(cmp(a, b)? == Ordering::Less)
}

/// `a > b`.
fn gt(a: End<'_>, b: End<'_>) -> Result<bool, Fail> {
    Ok(cmp(a, b)? == Ordering::Greater)
}

/// `a = b` (by order).
fn eq(a: End<'_>, b: End<'_>) -> Result<bool, Fail> {
    Ok(cmp(a, b)? == Ordering::Equal)
}

/// Runs a range relation on the two arguments.
fn relation(args: Vec<Value>, f: fn(Arg<'_>, Arg<'_>) -> Result<bool, Fail>) -> Out {
    let [a, b] = take(args);
    Ok(Value::Bool(f(arg(&a, "first")?, arg(&b, "second")?)?))
}

/// The reason for a combination of points and ranges a relation does not define.
fn undefined<T>(what: &str) -> Result<T, Fail> {
    null(format!("defined only for {what}"))
}

/// `before(point1, point2)`, `before(point, range)`, `before(range, point)`,
/// `before(range1, range2)`.
pub(super) fn before(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Point(q)) => lt(End::At(p), End::At(q)),
        (Arg::Point(p), Arg::Range(r)) => {
            Ok(lt(End::At(p), r.start)? || (eq(End::At(p), r.start)? && !r.start_in))
        }
        (Arg::Range(r), Arg::Point(p)) => {
            Ok(lt(r.end, End::At(p))? || (eq(r.end, End::At(p))? && !r.end_in))
        }
        (Arg::Range(r1), Arg::Range(r2)) => {
            Ok(lt(r1.end, r2.start)? || ((!r1.end_in || !r2.start_in) && eq(r1.end, r2.start)?))
        }
    })
}

/// `after(point1, point2)`, `after(point, range)`, `after(range, point)`,
/// `after(range1, range2)`.
pub(super) fn after(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Point(q)) => gt(End::At(p), End::At(q)),
        (Arg::Point(p), Arg::Range(r)) => {
            Ok(gt(End::At(p), r.end)? || (eq(End::At(p), r.end)? && !r.end_in))
        }
        (Arg::Range(r), Arg::Point(p)) => {
            Ok(gt(r.start, End::At(p))? || (eq(r.start, End::At(p))? && !r.start_in))
        }
        (Arg::Range(r1), Arg::Range(r2)) => {
            Ok(gt(r1.start, r2.end)? || ((!r1.start_in || !r2.end_in) && eq(r1.start, r2.end)?))
        }
    })
}

/// `meets(range1, range2)`: the first ends where the second starts, both including it.
pub(super) fn meets(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.end_in && r2.start_in && eq(r1.end, r2.start)?),
        _ => undefined("two ranges"),
    })
}

/// `met by(range1, range2)`: the first starts where the second ends, both including it.
pub(super) fn met_by(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.start_in && r2.end_in && eq(r1.start, r2.end)?),
        _ => undefined("two ranges"),
    })
}

/// `overlaps(range1, range2)`: the ranges share a point.
pub(super) fn overlaps(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r1), Arg::Range(r2)) => Ok((gt(r1.end, r2.start)?
            || (eq(r1.end, r2.start)? && r1.end_in && r2.start_in))
            && (lt(r1.start, r2.end)? || (eq(r1.start, r2.end)? && r1.start_in && r2.end_in))),
        _ => undefined("two ranges"),
    })
}

/// Whether `r1` starts before `r2`, overlaps it and ends within it.
fn overlapping_before(r1: Interval<'_>, r2: Interval<'_>) -> Result<bool, Fail> {
    Ok(
        (lt(r1.start, r2.start)? || (eq(r1.start, r2.start)? && r1.start_in && !r2.start_in))
            && (gt(r1.end, r2.start)? || (eq(r1.end, r2.start)? && r1.end_in && r2.start_in))
            && (lt(r1.end, r2.end)? || (eq(r1.end, r2.end)? && (!r1.end_in || r2.end_in))),
    )
}

/// `overlaps before(range1, range2)`: the first starts before the second and ends inside it.
pub(super) fn overlaps_before(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r1), Arg::Range(r2)) => overlapping_before(r1, r2),
        _ => undefined("two ranges"),
    })
}

/// `overlaps after(range1, range2)`: the second starts before the first and ends inside it.
pub(super) fn overlaps_after(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r1), Arg::Range(r2)) => overlapping_before(r2, r1),
        _ => undefined("two ranges"),
    })
}

/// `finishes(point, range)`, `finishes(range1, range2)`: ends where the range ends (and, for
/// a range, starts within it).
pub(super) fn finishes(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Range(r)) => Ok(r.end_in && eq(r.end, End::At(p))?),
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.end_in == r2.end_in
            && eq(r1.end, r2.end)?
            && (gt(r1.start, r2.start)?
                || (eq(r1.start, r2.start)? && (!r1.start_in || r2.start_in)))),
        _ => undefined("a point or range and a range"),
    })
}

/// `finished by(range, point)`, `finished by(range1, range2)`.
pub(super) fn finished_by(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r), Arg::Point(p)) => Ok(r.end_in && eq(r.end, End::At(p))?),
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.end_in == r2.end_in
            && eq(r1.end, r2.end)?
            && (lt(r1.start, r2.start)?
                || (eq(r1.start, r2.start)? && (r1.start_in || !r2.start_in)))),
        _ => undefined("a range and a point or range"),
    })
}

/// Whether range `r` includes point `p`.
fn contains_point(r: Interval<'_>, p: &Value) -> Result<bool, Fail> {
    let p = End::At(p);
    Ok((lt(r.start, p)? && gt(r.end, p)?)
        || (eq(r.start, p)? && r.start_in)
        || (eq(r.end, p)? && r.end_in))
}

/// Whether range `r1` includes range `r2`.
fn contains_range(r1: Interval<'_>, r2: Interval<'_>) -> Result<bool, Fail> {
    Ok(
        (lt(r1.start, r2.start)? || (eq(r1.start, r2.start)? && (r1.start_in || !r2.start_in)))
            && (gt(r1.end, r2.end)? || (eq(r1.end, r2.end)? && (r1.end_in || !r2.end_in))),
    )
}

/// `includes(range, point)`, `includes(range1, range2)`.
pub(super) fn includes(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r), Arg::Point(p)) => contains_point(r, p),
        (Arg::Range(r1), Arg::Range(r2)) => contains_range(r1, r2),
        _ => undefined("a range and a point or range"),
    })
}

/// `during(point, range)`, `during(range1, range2)`.
pub(super) fn during(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Range(r)) => contains_point(r, p),
        (Arg::Range(r1), Arg::Range(r2)) => contains_range(r2, r1),
        _ => undefined("a point or range and a range"),
    })
}

/// `starts(point, range)`, `starts(range1, range2)`.
pub(super) fn starts(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Range(r)) => Ok(r.start_in && eq(r.start, End::At(p))?),
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.start_in == r2.start_in
            && eq(r1.start, r2.start)?
            && (lt(r1.end, r2.end)? || (eq(r1.end, r2.end)? && (!r1.end_in || r2.end_in)))),
        _ => undefined("a point or range and a range"),
    })
}

/// `started by(range, point)`, `started by(range1, range2)`.
pub(super) fn started_by(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Range(r), Arg::Point(p)) => Ok(r.start_in && eq(r.start, End::At(p))?),
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.start_in == r2.start_in
            && eq(r1.start, r2.start)?
            && (gt(r1.end, r2.end)? || (eq(r1.end, r2.end)? && (!r2.end_in || r1.end_in)))),
        _ => undefined("a range and a point or range"),
    })
}

/// `coincides(point1, point2)`, `coincides(range1, range2)`: the same point, or the same
/// ends with the same inclusion.
pub(super) fn coincides(_: &mut dyn Host, args: Vec<Value>) -> Out {
    relation(args, |x, y| match (x, y) {
        (Arg::Point(p), Arg::Point(q)) => eq(End::At(p), End::At(q)),
        (Arg::Range(r1), Arg::Range(r2)) => Ok(r1.start_in == r2.start_in
            && r1.end_in == r2.end_in
            && eq(r1.start, r2.start)?
            && eq(r1.end, r2.end)?),
        _ => undefined("two points or two ranges"),
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{check, nulls};

    #[test]
    fn before_and_after() {
        check(&[
            ("before(1, 10)", "true"),
            ("before(10, 1)", "false"),
            ("before(1, [2..5])", "true"),
            ("before(2, [2..5])", "false"),
            ("before(2, (2..5])", "true"),
            ("before([1..5], 10)", "true"),
            ("before([1..5], 5)", "false"),
            ("before([1..5), 5)", "true"),
            ("before([1..5], [6..10])", "true"),
            ("before([1..5), [5..10])", "true"),
            ("before([1..5], (5..10])", "true"),
            ("before([1..5], [5..10])", "false"),
            ("before([1..5], [2..10])", "false"),
            ("before(\"a\", \"b\")", "true"),
            ("after(10, 1)", "true"),
            ("after(1, 10)", "false"),
            ("after(12, [2..5])", "true"),
            ("after(5, [2..5])", "false"),
            ("after(5, [2..5))", "true"),
            ("after([6..10], 5)", "true"),
            ("after((5..10], 5)", "true"),
            ("after([5..10], 5)", "false"),
            ("after([6..10], [1..5])", "true"),
            ("after((5..10], [1..5])", "true"),
            ("after([5..10], [1..5])", "false"),
            ("after([5..10], [1..5))", "true"),
        ]);
    }

    #[test]
    fn meets_and_overlaps() {
        check(&[
            ("meets([1..5], [5..10])", "true"),
            ("meets([1..3], [4..6])", "false"),
            ("meets([1..3], [3..5])", "true"),
            ("meets([1..5], (5..8])", "false"),
            ("meets([1..5), [5..8])", "false"),
            ("met by([5..10], [1..5])", "true"),
            ("met by([3..4], [1..2])", "false"),
            ("met by([3..5], [1..3])", "true"),
            ("met by((5..8], [1..5))", "false"),
            ("met by([5..10], [1..5))", "false"),
            ("overlaps([5..10], [1..6])", "true"),
            ("overlaps((5..8], [1..5])", "false"),
            ("overlaps([5..8], [1..5))", "false"),
            ("overlaps([5..8], [1..5])", "true"),
            ("overlaps([1..5], [5..8])", "true"),
            ("overlaps([1..5], (5..8])", "false"),
            ("overlaps([1..2], [3..4])", "false"),
            ("overlaps([1..10], [3..4])", "true"),
            ("overlaps([3..4], [1..10])", "true"),
            ("overlaps before([1..5], [4..10])", "true"),
            ("overlaps before([3..4], [1..2])", "false"),
            ("overlaps before([1..3], (3..5])", "false"),
            ("overlaps before([1..5), (3..8])", "true"),
            ("overlaps before([1..5), [5..10])", "false"),
            ("overlaps after([4..10], [1..5])", "true"),
            ("overlaps after([3..4], [1..2])", "false"),
            ("overlaps after((5..8], [1..5))", "false"),
            ("overlaps after([4..10], [1..5))", "true"),
            ("overlaps after((3..5], [1..3])", "false"),
        ]);
    }

    #[test]
    fn finishes_includes_during() {
        check(&[
            ("finishes(5, [1..5])", "true"),
            ("finishes(10, [1..7])", "false"),
            ("finishes(5, [1..5))", "false"),
            ("finishes([3..5], [1..5])", "true"),
            ("finishes((1..5], [1..5))", "false"),
            ("finishes([5..10], [1..10))", "false"),
            ("finishes([1..5], [1..5])", "true"),
            ("finished by([5..10], 10)", "true"),
            ("finished by([3..4], 2)", "false"),
            ("finished by([1..5], [3..5])", "true"),
            ("finished by((5..8], [1..5))", "false"),
            ("finished by([5..10], (1..10))", "false"),
            ("includes([5..10], 6)", "true"),
            ("includes([3..4], 5)", "false"),
            ("includes([5..10], 5)", "true"),
            ("includes((5..10], 5)", "false"),
            ("includes([1..10], [4..6])", "true"),
            ("includes((5..8], [1..5))", "false"),
            ("includes([1..10], [1..5))", "true"),
            ("includes((1..10], [1..5))", "false"),
            ("during(5, [1..10])", "true"),
            ("during(12, [1..10])", "false"),
            ("during(1, (1..10])", "false"),
            ("during([4..6], [1..10))", "true"),
            ("during((1..5], (1..10])", "true"),
            ("during([1..5], (1..10])", "false"),
        ]);
    }

    #[test]
    fn starts_started_by_coincides() {
        check(&[
            ("starts(1, [1..5])", "true"),
            ("starts(1, (1..8])", "false"),
            ("starts((1..5], [1..5])", "false"),
            ("starts([1..10], [1..10])", "true"),
            ("starts((1..10), (1..10))", "true"),
            ("starts([1..5], [1..10])", "true"),
            ("starts([1..10], [1..5])", "false"),
            ("started by([1..10], 1)", "true"),
            ("started by((1..10], 1)", "false"),
            ("started by([1..10], [1..5])", "true"),
            ("started by((1..10], [1..5))", "false"),
            ("started by([1..10], [1..10))", "true"),
            ("coincides(5, 5)", "true"),
            ("coincides(3, 4)", "false"),
            ("coincides([1..5], [1..5])", "true"),
            ("coincides((1..5], [1..5))", "false"),
            ("coincides([1..5], [2..6])", "false"),
        ]);
    }

    #[test]
    fn open_ends_are_infinite() {
        check(&[
            ("before(1, (2..])", "true"),
            ("before([..5], 7)", "true"),
            ("before([..5], [6..])", "true"),
            ("after(1, [..0])", "true"),
            ("after([1..], 0)", "true"),
            ("includes([1..], 1000000)", "true"),
            ("includes([..], 5)", "true"),
            ("includes([1..], [2..])", "true"),
            ("during([2..], [1..])", "true"),
            ("during([1..], [2..])", "false"),
            ("overlaps([..5], [3..])", "true"),
            ("coincides([1..], [1..])", "true"),
            ("finishes([2..], [1..])", "true"),
            ("finishes([1..], [2..])", "false"),
        ]);
    }

    #[test]
    fn wrong_arguments() {
        nulls(&[
            ("before(null, 1)", "the first argument is null"),
            ("after(1, null)", "the second argument is null"),
            ("before(1, \"a\")", "cannot compare a number with a string"),
            ("before(1, [\"a\"..\"b\"])", "cannot compare"),
            (
                "before(true, false)",
                "cannot compare a boolean with a boolean",
            ),
            ("meets(1, [1..2])", "defined only for two ranges"),
            ("met by([1..2], 1)", "two ranges"),
            ("overlaps(1, 2)", "two ranges"),
            ("overlaps before(1, [1..2])", "two ranges"),
            ("overlaps after([1..2], 1)", "two ranges"),
            ("finishes([1..2], 2)", "a point or range and a range"),
            ("finished by(2, [1..2])", "a range and a point or range"),
            ("includes(1, [1..2])", "a range and a point or range"),
            ("during([1..2], 1)", "a point or range and a range"),
            ("starts([1..2], 1)", "a point or range and a range"),
            ("started by(1, [1..2])", "a range and a point or range"),
            ("coincides(1, [1..2])", "two points or two ranges"),
        ]);
    }
}

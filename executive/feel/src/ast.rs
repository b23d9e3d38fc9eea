//! The syntax tree of a FEEL expression. Every node keeps the byte span it was read from.

use rust_decimal::Decimal;

/// A byte range in the expression text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
}

/// A node and where it was written.
#[derive(Clone, Debug)]
pub struct Node {
    /// What the node is.
    pub kind: Kind,
    /// Where it was written.
    pub span: Span,
}

/// Binary operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `**`
    Pow,
    /// `=`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
}

/// The quantifier of a `some`/`every` expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantifier {
    /// `some … satisfies`
    Some,
    /// `every … satisfies`
    Every,
}

/// Arguments of an invocation.
#[derive(Clone, Debug)]
pub enum Args {
    /// `f(a, b)`
    Positional(Vec<Node>),
    /// `f(x: a, y: b)`
    Named(Vec<(String, Node)>),
}

/// One `name in source` of a `for`, `some` or `every`; a `for` source may be a range `a..b`.
#[derive(Clone, Debug)]
pub struct Iteration {
    /// The variable.
    pub name: String,
    /// The list (or the start of an integer range).
    pub source: Node,
    /// The end of an integer range `source..end`.
    pub end: Option<Node>,
}

/// What a node is.
#[derive(Clone, Debug)]
pub enum Kind {
    /// `null`
    Null,
    /// `true`, `false`
    Bool(bool),
    /// A number literal.
    Number(Decimal),
    /// A string literal (escapes resolved).
    String(String),
    /// `@"2026-01-01"`: the text of a temporal literal.
    At(String),
    /// A name: a variable, a name bound inside the expression, or a function defined in it.
    Name(String),
    /// `?`: the value a test after `in` is testing (`x in contains(?, "a")`).
    Input,
    /// `a.b`
    Path(Box<Node>, String),
    /// `l[f]`: a filter, or an index when `f` is a number.
    Filter(Box<Node>, Box<Node>),
    /// `f(args)`
    Call(Box<Node>, Args),
    /// `-a`
    Neg(Box<Node>),
    /// `a op b`
    Binary(Op, Box<Node>, Box<Node>),
    /// `a and b`
    And(Box<Node>, Box<Node>),
    /// `a or b`
    Or(Box<Node>, Box<Node>),
    /// `a between b and c`
    Between(Box<Node>, Box<Node>, Box<Node>),
    /// `a in tests`: each test is a value, a range or a unary comparison (`< 5`).
    In(Box<Node>, Vec<Node>),
    /// A unary test inside `in`: `< 5`, `>= x`, `!= 3`.
    UnaryTest(Op, Box<Node>),
    /// `not(tests)` after `in`: true when none of the tests holds (`x in not(2, 3)`).
    NotTests(Vec<Node>),
    /// A test after `in` that mentions `?`: evaluated with `?` bound to the tested value; an
    /// expression test must then give a boolean, which is the test's result.
    InputTest(Box<Node>),
    /// `a instance of type`
    InstanceOf(Box<Node>, String),
    /// `[a, b]`
    List(Vec<Node>),
    /// `{a: 1, "b c": 2}`; later entries see earlier ones.
    Context(Vec<(String, Node)>),
    /// `[a..b]`, `(a..b)`, `]a..b[`: ends closed or open.
    Range {
        /// Lower end.
        start: Box<Node>,
        /// Whether the lower end belongs to the range.
        start_closed: bool,
        /// Upper end.
        end: Box<Node>,
        /// Whether the upper end belongs to the range.
        end_closed: bool,
    },
    /// `if c then a else b`
    If(Box<Node>, Box<Node>, Box<Node>),
    /// `for x in l, y in m return e`
    For(Vec<Iteration>, Box<Node>),
    /// `some x in l satisfies c`, `every …`
    Quantified(Quantifier, Vec<Iteration>, Box<Node>),
    /// `function(a, b) body`
    Function(Vec<String>, std::sync::Arc<Node>),
}

//! A small expression language for regressors of the Δ model (thesis
//! Section 3.3.2 and Eq. 3.14, 3.21, 3.22).
//!
//! A regressor is an expression over named data columns, e.g.
//! `beta_rad`, `phat`, `alphadot_rps * ds_deg`, `ct_left - ct_right`,
//! `deadband(da_deg, 2)` or `1` (the constant of the bias term). It is parsed
//! once and evaluated over whole columns.
//!
//! Grammar (usual precedence; `^` binds tightest and is right-associative):
//! ```text
//! expr    := term (('+' | '-') term)*
//! term    := unary (('*' | '/') unary)*
//! unary   := '-' unary | power
//! power   := atom ('^' unary)?
//! atom    := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
//! ```
//! Functions:
//! - `pos(x)` $= (x)_+ = \max(x, 0)$ and `neg(x)` $= (x)_- = \min(x, 0)$;
//! - `deadband(x, k)` $= (x - k)_+ + (x + k)_-$, the aileron dead-band spline
//!   of thesis Eq. 3.15-3.16 (zero for $|x| \le k$, slope one outside);
//! - `step(x)` (1 for $x > 0$, else 0), `abs`, `sqrt`, `sin`, `cos`, `exp`,
//!   `min(a, b)`, `max(a, b)`.
//!
//! `a ^ b` with a whole `b` of at most 16 in magnitude is computed by
//! multiplication (`x^2` is `x*x` exactly), otherwise as `powf`.
//!
//! Names are column names; they may contain letters, digits and `_`, and may
//! not start with a digit.
//!
//! Limits (far above any aerodynamic regressor, which nests a handful of
//! levels; they keep a malformed or hostile expression from overflowing the
//! stack of the parser or of the tree walks that follow it):
//! - [`MAX_NESTING`]: parentheses, function arguments, unary minus and `^`
//!   exponents each open one level while parsing; at most 64 may be open;
//! - [`MAX_DEPTH`]: the parsed tree is at most 256 nodes deep, counting every
//!   operator and function call on the way down, so a flat chain
//!   `a + b + c + ...` may have at most 256 terms;
//! - [`MAX_NODES`]: the tree has at most 2048 nodes (numbers, names,
//!   operators and calls), so a parse never takes more than a few hundred
//!   kilobytes, whatever the input.

use crate::error::{AeroError, Result};
use crate::text::shown;
use std::fmt;

/// Most levels of parentheses, function arguments, unary minus and `^`
/// exponents open at once while parsing (see the module documentation).
pub const MAX_NESTING: usize = 64;

/// Deepest expression tree [`Expr::parse`] returns, in nodes (a leaf is 1,
/// `a + b` is 2, `a + b + c` is 3).
pub const MAX_DEPTH: usize = 256;

/// Most nodes (numbers, names, operators, function calls) of a tree
/// [`Expr::parse`] returns: it bounds the memory of a parse whatever the
/// shape of the expression (a tree node takes some 32 bytes, more than the
/// two characters of `*a`).
pub const MAX_NODES: usize = 2048;

/// A parsed regressor expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A number.
    Const(f64),
    /// A data column by name.
    Column(String),
    /// Negation.
    Neg(Box<Expr>),
    /// A binary operation.
    Bin(BinOp, Box<Expr>, Box<Expr>),
    /// A function call.
    Call(Func, Vec<Expr>),
}

/// Binary operators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `^`
    Pow,
}

/// Built-in functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    /// `pos(x) = max(x, 0)`
    Pos,
    /// `neg(x) = min(x, 0)`
    Neg,
    /// `deadband(x, k) = (x-k)+ + (x+k)-` (thesis Eq. 3.15-3.16)
    Deadband,
    /// `step(x)`: 1 if x > 0 else 0
    Step,
    /// `abs(x)`
    Abs,
    /// `sqrt(x)`
    Sqrt,
    /// `sin(x)` (x in radians)
    Sin,
    /// `cos(x)` (x in radians)
    Cos,
    /// `exp(x)`
    Exp,
    /// `min(a, b)`
    Min,
    /// `max(a, b)`
    Max,
}

impl Func {
    fn from_name(name: &str) -> Option<(Func, usize)> {
        Some(match name {
            "pos" => (Func::Pos, 1),
            "neg" => (Func::Neg, 1),
            "deadband" => (Func::Deadband, 2),
            "step" => (Func::Step, 1),
            "abs" => (Func::Abs, 1),
            "sqrt" => (Func::Sqrt, 1),
            "sin" => (Func::Sin, 1),
            "cos" => (Func::Cos, 1),
            "exp" => (Func::Exp, 1),
            "min" => (Func::Min, 2),
            "max" => (Func::Max, 2),
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Func::Pos => "pos",
            Func::Neg => "neg",
            Func::Deadband => "deadband",
            Func::Step => "step",
            Func::Abs => "abs",
            Func::Sqrt => "sqrt",
            Func::Sin => "sin",
            Func::Cos => "cos",
            Func::Exp => "exp",
            Func::Min => "min",
            Func::Max => "max",
        }
    }

    #[inline]
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Func::Pos => a.max(0.0),
            Func::Neg => a.min(0.0),
            Func::Deadband => {
                if a.is_nan() || b.is_nan() {
                    f64::NAN
                } else {
                    (a - b).max(0.0) + (a + b).min(0.0)
                }
            }
            Func::Step => {
                if a.is_nan() {
                    f64::NAN
                } else if a > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Func::Abs => a.abs(),
            Func::Sqrt => a.sqrt(),
            Func::Sin => a.sin(),
            Func::Cos => a.cos(),
            Func::Exp => a.exp(),
            Func::Min => {
                if a.is_nan() || b.is_nan() {
                    f64::NAN
                } else {
                    a.min(b)
                }
            }
            Func::Max => {
                if a.is_nan() || b.is_nan() {
                    f64::NAN
                } else {
                    a.max(b)
                }
            }
        }
    }
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Expr::Const(c) => write!(f, "{c}"),
            Expr::Column(n) => f.write_str(n),
            Expr::Neg(e) => write!(f, "-({e})"),
            Expr::Bin(op, a, b) => {
                let s = match op {
                    BinOp::Add => "+",
                    BinOp::Sub => "-",
                    BinOp::Mul => "*",
                    BinOp::Div => "/",
                    BinOp::Pow => "^",
                };
                write!(f, "({a} {s} {b})")
            }
            Expr::Call(func, args) => {
                write!(f, "{}(", func.name())?;
                for (i, a) in args.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{a}")?;
                }
                f.write_str(")")
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Tok<'a> {
    Num(f64),
    Name(&'a str),
    Op(char),
}

impl Tok<'_> {
    /// Whether the token ends an operand (so a following `-` is binary).
    fn ends_operand(self) -> bool {
        matches!(self, Tok::Num(_) | Tok::Name(_) | Tok::Op(')'))
    }
}

/// The tokens of a regressor, one at a time (nothing is stored: memory stays
/// independent of the expression's length), each with its 0-based column in
/// characters.
struct Lexer<'a> {
    src: &'a str,
    /// Byte offset of the next character.
    at: usize,
    /// Its column, in characters.
    col: usize,
}

impl<'a> Lexer<'a> {
    fn new(src: &'a str) -> Self {
        Lexer { src, at: 0, col: 0 }
    }

    fn error(&self, col: usize, msg: impl Into<String>) -> AeroError {
        AeroError::invalid(
            format!("regressor '{}', column {}", shown(self.src), col + 1),
            msg,
        )
    }

    /// The next token and its column; `None` at the end.
    fn next_tok(&mut self) -> Result<Option<(usize, Tok<'a>)>> {
        let src = self.src;
        let mut chars = src[self.at..].chars();
        let c = loop {
            match chars.next() {
                None => return Ok(None),
                Some(c) if c.is_whitespace() => {
                    self.at += c.len_utf8();
                    self.col += 1;
                }
                Some(c) => break c,
            }
        };
        let (start, col) = (self.at, self.col);
        let b = src.as_bytes();
        let digit = |i: usize| b.get(i).is_some_and(u8::is_ascii_digit);
        let tok = if c.is_ascii_digit() || (c == '.' && digit(start + 1)) {
            // ASCII only: digits and points, then an optional exponent.
            let mut i = start;
            while b.get(i).is_some_and(|&d| d.is_ascii_digit() || d == b'.') {
                i += 1;
            }
            if matches!(b.get(i), Some(b'e' | b'E')) {
                let mut j = i + 1;
                if matches!(b.get(j), Some(b'+' | b'-')) {
                    j += 1;
                }
                if digit(j) {
                    while digit(j) {
                        j += 1;
                    }
                    i = j;
                }
            }
            let text = &src[start..i];
            let v: f64 = text
                .parse()
                .map_err(|_| self.error(col, format!("'{}' is not a number", shown(text))))?;
            self.at = i;
            self.col += i - start;
            Tok::Num(v)
        } else if c.is_alphabetic() || c == '_' {
            let mut end = start;
            for ch in src[start..].chars() {
                if !(ch.is_alphanumeric() || ch == '_') {
                    break;
                }
                end += ch.len_utf8();
                self.col += 1;
            }
            self.at = end;
            Tok::Name(&src[start..end])
        } else if "+-*/^(),".contains(c) {
            self.at += 1;
            self.col += 1;
            Tok::Op(c)
        } else {
            return Err(self.error(
                col,
                format!(
                    "unexpected character '{}'; use names, numbers, + - * / ^, ( ) and functions",
                    c.escape_debug()
                ),
            ));
        };
        Ok(Some((col, tok)))
    }
}

/// What a first pass over the tokens finds: their count, the nesting the
/// [`Parser`] reaches (the deepest level, and the column where it first passes
/// [`MAX_NESTING`], if it does), computed without recursion. Mirrors the
/// parser: `(` (a group or an argument list) opens a level that its `)`
/// closes; a unary `-` or a `^` opens a level that lasts until its operand
/// ends, i.e. up to the next `+ - * / ,` or `)` of the same parenthesis level.
///
/// # Errors
/// The first token that is not one of the language (as [`Lexer::next_tok`]).
fn scan(src: &str) -> Result<(usize, usize, Option<usize>)> {
    let mut lx = Lexer::new(src);
    // Open unary/^ levels per parenthesis level, kept only for the levels
    // that have some: (parenthesis level, count); 32 bits each (the input is
    // shorter than 4 GiB), so the stack stays within 4 bytes per character.
    let mut pending: Vec<(u32, u32)> = Vec::new();
    if u32::try_from(src.len()).is_err() {
        return Err(AeroError::invalid(
            format!("regressor '{}'", shown(src)),
            "is longer than 4 GiB; write a short expression",
        ));
    }
    let (mut level, mut depth, mut max, mut first_over) = (0u32, 0usize, 0usize, None);
    let (mut count, mut prev): (usize, Option<Tok>) = (0, None);
    fn take_pending(pending: &mut Vec<(u32, u32)>, level: u32) -> usize {
        match pending.last() {
            Some(&(l, n)) if l == level => {
                pending.pop();
                n as usize
            }
            _ => 0,
        }
    }
    while let Some((col, t)) = lx.next_tok()? {
        count += 1;
        match t {
            Tok::Num(_) | Tok::Name(_) => {}
            Tok::Op('(') => {
                depth += 1;
                level += 1;
            }
            Tok::Op(')') => {
                if level > 0 {
                    depth -= take_pending(&mut pending, level) + 1;
                    level -= 1;
                }
            }
            Tok::Op(c) if c == '^' || (c == '-' && !prev.is_some_and(Tok::ends_operand)) => {
                match pending.last_mut() {
                    Some((l, n)) if *l == level => *n += 1,
                    _ => pending.push((level, 1)),
                }
                depth += 1;
            }
            Tok::Op(_) => depth -= take_pending(&mut pending, level),
        }
        prev = Some(t);
        max = max.max(depth);
        if depth > MAX_NESTING && first_over.is_none() {
            first_over = Some(col);
        }
    }
    Ok((count, max, first_over))
}

struct Parser<'a> {
    src: &'a str,
    lexer: Lexer<'a>,
    /// The next token and its column (`None` at the end).
    next: Option<(usize, Tok<'a>)>,
    /// Column of the last token consumed.
    last_col: usize,
    /// Levels of nesting open now (bounded by [`MAX_NESTING`]).
    nesting: usize,
    /// Deepest tree seen, when deeper than [`MAX_DEPTH`], and the column
    /// where that first happened.
    too_deep: Option<(usize, usize)>,
    /// Nodes of the tree (every number, name, operator and call).
    nodes: usize,
    /// Column where the tree first passed [`MAX_NODES`].
    too_big: Option<usize>,
}

/// A parsed subexpression and the true depth of its tree. Subtrees deeper than
/// [`MAX_DEPTH`], and every node past the [`MAX_NODES`]th, are replaced by a
/// placeholder leaf (the parse then fails), so the tree built stays small
/// while the true depth and size are still counted.
type Node = (Expr, usize);

impl<'a> Parser<'a> {
    fn err(&self, msg: impl Into<String>) -> AeroError {
        let col = self.next.map_or_else(|| self.src.chars().count(), |t| t.0);
        self.err_at(col, msg)
    }

    fn err_at(&self, col: usize, msg: impl Into<String>) -> AeroError {
        self.lexer.error(col, msg)
    }

    /// Consume the next token.
    fn bump(&mut self) -> Result<()> {
        if let Some((col, _)) = self.next {
            self.last_col = col;
        }
        self.next = self.lexer.next_tok()?;
        Ok(())
    }

    fn nesting_err(&self, depth: usize, col: usize) -> AeroError {
        self.err_at(
            col,
            format!(
                "nests {depth} levels deep (parentheses, function arguments, unary minus and ^ \
                 exponents); at most {MAX_NESTING} are supported; simplify the expression"
            ),
        )
    }

    /// Open one level of nesting; an error past [`MAX_NESTING`]. [`scan`]
    /// refuses such input before parsing, so this only backs it up.
    fn enter(&mut self) -> Result<()> {
        self.nesting += 1;
        if self.nesting > MAX_NESTING {
            let col = self.next.map_or(self.last_col, |t| t.0);
            return Err(self.nesting_err(self.nesting, col));
        }
        Ok(())
    }

    fn leave(&mut self) {
        self.nesting -= 1;
    }

    /// Count one more node; whether the tree is still within [`MAX_NODES`].
    fn count(&mut self) -> bool {
        self.nodes += 1;
        if self.nodes > MAX_NODES {
            self.too_big.get_or_insert(self.last_col);
            return false;
        }
        true
    }

    /// A node of true depth `depth`: `e` itself, or a placeholder leaf when
    /// `depth` passes [`MAX_DEPTH`] (noted for the error at the end) or the
    /// tree has passed [`MAX_NODES`].
    fn node(&mut self, e: Expr, depth: usize) -> Node {
        let small = self.count();
        if depth <= MAX_DEPTH && small {
            return (e, depth);
        }
        if depth > MAX_DEPTH {
            match self.too_deep {
                Some((d, _)) if d >= depth => {}
                Some((_, at)) => self.too_deep = Some((depth, at)),
                None => self.too_deep = Some((depth, self.last_col)),
            }
        }
        (Expr::Const(0.0), depth)
    }

    fn peek(&self) -> Option<Tok<'a>> {
        self.next.map(|t| t.1)
    }

    fn eat_op(&mut self, c: char) -> Result<bool> {
        if self.peek() == Some(Tok::Op(c)) {
            self.bump()?;
            Ok(true)
        } else {
            Ok(false)
        }
    }

    fn expr(&mut self) -> Result<Node> {
        let (mut lhs, mut depth) = self.term()?;
        loop {
            let op = if self.eat_op('+')? {
                BinOp::Add
            } else if self.eat_op('-')? {
                BinOp::Sub
            } else {
                return Ok((lhs, depth));
            };
            let (rhs, rd) = self.term()?;
            (lhs, depth) = self.node(
                Expr::Bin(op, Box::new(lhs), Box::new(rhs)),
                depth.max(rd) + 1,
            );
        }
    }

    fn term(&mut self) -> Result<Node> {
        let (mut lhs, mut depth) = self.unary()?;
        loop {
            let op = if self.eat_op('*')? {
                BinOp::Mul
            } else if self.eat_op('/')? {
                BinOp::Div
            } else {
                return Ok((lhs, depth));
            };
            let (rhs, rd) = self.unary()?;
            (lhs, depth) = self.node(
                Expr::Bin(op, Box::new(lhs), Box::new(rhs)),
                depth.max(rd) + 1,
            );
        }
    }

    fn unary(&mut self) -> Result<Node> {
        if self.eat_op('-')? {
            self.enter()?;
            let (e, depth) = self.unary()?;
            self.leave();
            return Ok(match e {
                Expr::Const(c) => (Expr::Const(-c), depth),
                e => self.node(Expr::Neg(Box::new(e)), depth + 1),
            });
        }
        self.power()
    }

    fn power(&mut self) -> Result<Node> {
        let (base, bd) = self.atom()?;
        if self.eat_op('^')? {
            self.enter()?;
            let (exp, ed) = self.unary()?;
            self.leave();
            return Ok(self.node(
                Expr::Bin(BinOp::Pow, Box::new(base), Box::new(exp)),
                bd.max(ed) + 1,
            ));
        }
        Ok((base, bd))
    }

    fn atom(&mut self) -> Result<Node> {
        match self.next {
            Some((_, Tok::Num(v))) => {
                self.bump()?;
                self.count();
                Ok((Expr::Const(v), 1))
            }
            Some((name_col, Tok::Name(name))) => {
                self.bump()?;
                if self.eat_op('(')? {
                    let Some((func, arity)) = Func::from_name(name) else {
                        return Err(self.err_at(
                            name_col,
                            format!(
                                "unknown function '{}'; known: pos, neg, deadband, step, abs, sqrt, sin, cos, exp, min, max",
                                shown(name)
                            ),
                        ));
                    };
                    self.enter()?;
                    let (first, mut depth) = self.expr()?;
                    let mut args = vec![first];
                    let mut given = 1;
                    while self.eat_op(',')? {
                        let (a, d) = self.expr()?;
                        // Arguments past the arity are counted, not kept.
                        given += 1;
                        if given <= arity {
                            args.push(a);
                        }
                        depth = depth.max(d);
                    }
                    if !self.eat_op(')')? {
                        return Err(self.err("expected ')' to close the argument list"));
                    }
                    self.leave();
                    if given != arity {
                        return Err(
                            self.err(format!("{name}() takes {arity} argument(s), got {given}"))
                        );
                    }
                    Ok(self.node(Expr::Call(func, args), depth + 1))
                } else if self.count() {
                    Ok((Expr::Column(name.to_string()), 1))
                } else {
                    Ok((Expr::Const(0.0), 1))
                }
            }
            Some((_, Tok::Op('('))) => {
                self.bump()?;
                self.enter()?;
                let e = self.expr()?;
                if !self.eat_op(')')? {
                    return Err(self.err("expected ')'"));
                }
                self.leave();
                Ok(e)
            }
            Some((_, Tok::Op(c))) => Err(self.err(format!("unexpected '{c}'"))),
            None => Err(self.err("unexpected end of expression")),
        }
    }
}

impl Expr {
    /// Parse a regressor expression.
    ///
    /// Memory is bounded by the tree returned (at most [`MAX_NODES`] nodes)
    /// and the nesting: tokens are read one at a time, twice (a first pass
    /// checks every token and the nesting before the tree is built).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the expression and the 1-based
    /// column of the first problem, including nesting deeper than
    /// [`MAX_NESTING`], a tree deeper than [`MAX_DEPTH`] or larger than
    /// [`MAX_NODES`].
    ///
    /// ```
    /// use aero_core::regressor::Expr;
    /// let e = Expr::parse("deadband(da_deg, 2)").unwrap();
    /// let da = [-5.0, -1.0, 0.0, 1.5, 4.0];
    /// let out = e.eval_columns(&|n: &str| (n == "da_deg").then_some(&da[..]), da.len()).unwrap();
    /// assert_eq!(out, vec![-3.0, 0.0, 0.0, 0.0, 2.0]);
    /// ```
    pub fn parse(src: &str) -> Result<Expr> {
        let (count, depth, over) = scan(src)?;
        let mut p = Parser {
            src,
            lexer: Lexer::new(src),
            next: None,
            last_col: 0,
            nesting: 0,
            too_deep: None,
            nodes: 0,
            too_big: None,
        };
        if count == 0 {
            return Err(AeroError::invalid(
                "regressor ''",
                "is empty; write an expression such as 'beta_rad' or '1'",
            ));
        }
        if let Some(col) = over {
            return Err(p.nesting_err(depth, col));
        }
        p.bump()?;
        let (e, _) = p.expr()?;
        if p.next.is_some() {
            return Err(p.err("unexpected text after the end of the expression"));
        }
        if let Some((depth, col)) = p.too_deep {
            return Err(p.err_at(
                col,
                format!(
                    "is {depth} operations deep (each operator and function call on the way \
                     down counts, so a chain a + b + c is 3); at most {MAX_DEPTH} are supported; \
                     split it into several regressors"
                ),
            ));
        }
        if let Some(col) = p.too_big {
            return Err(p.err_at(
                col,
                format!(
                    "has {} numbers, names, operators and function calls; at most {MAX_NODES} \
                     are supported; split it into several regressors",
                    p.nodes
                ),
            ));
        }
        Ok(e)
    }

    /// The column names this expression reads, each once, in order of appearance.
    pub fn columns(&self) -> Vec<String> {
        let mut out = Vec::new();
        self.collect_columns(&mut out);
        out
    }

    fn collect_columns(&self, out: &mut Vec<String>) {
        match self {
            Expr::Const(_) => {}
            Expr::Column(n) => {
                if !out.iter().any(|o| o == n) {
                    out.push(n.clone());
                }
            }
            Expr::Neg(e) => e.collect_columns(out),
            Expr::Bin(_, a, b) => {
                a.collect_columns(out);
                b.collect_columns(out);
            }
            Expr::Call(_, args) => args.iter().for_each(|a| a.collect_columns(out)),
        }
    }

    /// True when the expression reads no column (e.g. the bias term `1`).
    pub fn is_constant(&self) -> bool {
        self.columns().is_empty()
    }

    /// Evaluate at one point, looking columns up by name.
    ///
    /// Returns NaN when a column is missing (the batch path reports it).
    pub fn eval_point(&self, lookup: &dyn Fn(&str) -> Option<f64>) -> f64 {
        match self {
            Expr::Const(c) => *c,
            Expr::Column(n) => lookup(n).unwrap_or(f64::NAN),
            Expr::Neg(e) => -e.eval_point(lookup),
            Expr::Bin(op, a, b) => binop(*op, a.eval_point(lookup), b.eval_point(lookup)),
            Expr::Call(func, args) => {
                let a = args.first().map_or(f64::NAN, |e| e.eval_point(lookup));
                let b = args.get(1).map_or(0.0, |e| e.eval_point(lookup));
                func.apply(a, b)
            }
        }
    }

    /// Evaluate over whole columns of `n` rows.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the expression and the missing
    /// column, or a column whose length differs from `n`.
    pub fn eval_columns<'a>(
        &self,
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
    ) -> Result<Vec<f64>> {
        let mut out = Vec::new();
        self.eval_columns_into(lookup, n, &mut out)?;
        Ok(out)
    }

    /// [`Expr::eval_columns`] written into `out` (cleared first; its capacity is reused, so a
    /// caller evaluating expression after expression into one vector allocates once). The
    /// same values: the right operand of an operation is read in place when it is a data
    /// column or a number, evaluated into a vector of its own otherwise.
    ///
    /// # Errors
    /// Those of [`Expr::eval_columns`]; `out` is then left in an unspecified state.
    pub fn eval_columns_into<'a>(
        &self,
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
        out: &mut Vec<f64>,
    ) -> Result<()> {
        out.clear();
        match self {
            Expr::Const(c) => out.resize(n, *c),
            Expr::Column(name) => out.extend_from_slice(data_column(name, lookup, n)?),
            Expr::Neg(e) => {
                e.eval_columns_into(lookup, n, out)?;
                out.iter_mut().for_each(|x| *x = -*x);
            }
            Expr::Bin(op, a, b) => {
                a.eval_columns_into(lookup, n, out)?;
                let op = *op;
                combine_with(out, b, lookup, n, |x, y| binop(op, x, y))?;
            }
            Expr::Call(func, args) => {
                match args.first() {
                    Some(e) => e.eval_columns_into(lookup, n, out)?,
                    None => out.resize(n, f64::NAN),
                }
                let func = *func;
                match args.get(1) {
                    Some(e) => combine_with(out, e, lookup, n, |x, y| func.apply(x, y))?,
                    None => out.iter_mut().for_each(|x| *x = func.apply(*x, 0.0)),
                }
            }
        }
        Ok(())
    }

    /// The data column of a plain column expression (`None` for any other expression),
    /// checked as [`Expr::eval_columns`] checks it: read in place, not copied.
    ///
    /// # Errors
    /// Those of [`Expr::eval_columns`] for the column.
    pub fn as_data_column<'a>(
        &self,
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
    ) -> Result<Option<&'a [f64]>> {
        match self {
            Expr::Column(name) => data_column(name, lookup, n).map(Some),
            _ => Ok(None),
        }
    }
}

/// Column `name` of `n` rows from `lookup`, or the error of [`Expr::eval_columns`].
fn data_column<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
    n: usize,
) -> Result<&'a [f64]> {
    let col = lookup(name).ok_or_else(|| {
        AeroError::invalid(
            format!("regressor column '{name}'"),
            "is not in the data; add the channel or derive it before fitting",
        )
    })?;
    if col.len() != n {
        return Err(AeroError::invalid(
            format!("regressor column '{name}'"),
            format!("has {} rows, expected {n}", col.len()),
        ));
    }
    Ok(col)
}

/// `out[i] = f(out[i], b[i])` for the values `b` of expression `b` over `n` rows: a number
/// or a data column read in place, any other expression evaluated first.
fn combine_with<'a>(
    out: &mut [f64],
    b: &Expr,
    lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
    n: usize,
    f: impl Fn(f64, f64) -> f64,
) -> Result<()> {
    match b {
        Expr::Const(c) => out.iter_mut().for_each(|x| *x = f(*x, *c)),
        Expr::Column(name) => {
            let vb = data_column(name, lookup, n)?;
            for (x, y) in out.iter_mut().zip(vb) {
                *x = f(*x, *y);
            }
        }
        _ => {
            let vb = b.eval_columns(lookup, n)?;
            for (x, y) in out.iter_mut().zip(&vb) {
                *x = f(*x, *y);
            }
        }
    }
    Ok(())
}

/// A regressor whose column names are resolved to positions in a state
/// vector, for allocation-free evaluation in a simulator's real-time loop.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundExpr {
    code: Vec<Op>,
    stack_depth: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Const(f64),
    Load(usize),
    Neg,
    Bin(BinOp),
    Call1(Func),
    Call2(Func),
}

/// Deepest stack a bound expression may use (no allocation at evaluation).
const MAX_STACK: usize = 32;

impl Expr {
    /// Resolve column names against `layout` (the names of the state vector's
    /// entries, in order).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming a column absent from the layout, or
    /// an expression nested too deeply for the fixed evaluation stack.
    pub fn bind(&self, layout: &[&str]) -> Result<BoundExpr> {
        let mut code = Vec::new();
        self.compile(layout, &mut code)?;
        let mut depth = 0usize;
        let mut max_depth = 0usize;
        for op in &code {
            match op {
                Op::Const(_) | Op::Load(_) => depth += 1,
                Op::Bin(_) | Op::Call2(_) => depth -= 1,
                Op::Neg | Op::Call1(_) => {}
            }
            max_depth = max_depth.max(depth);
        }
        if max_depth > MAX_STACK {
            return Err(AeroError::invalid(
                format!("regressor '{}'", shown(&self.to_string())),
                format!("needs an evaluation stack {max_depth} deep; at most {MAX_STACK} are supported; simplify the expression"),
            ));
        }
        Ok(BoundExpr {
            code,
            stack_depth: max_depth,
        })
    }

    fn compile(&self, layout: &[&str], code: &mut Vec<Op>) -> Result<()> {
        match self {
            Expr::Const(c) => code.push(Op::Const(*c)),
            Expr::Column(n) => {
                let i = layout.iter().position(|l| l == n).ok_or_else(|| {
                    AeroError::invalid(
                        format!("regressor column '{n}'"),
                        format!("is not among the model inputs ({})", layout.join(", ")),
                    )
                })?;
                code.push(Op::Load(i));
            }
            Expr::Neg(e) => {
                e.compile(layout, code)?;
                code.push(Op::Neg);
            }
            Expr::Bin(op, a, b) => {
                a.compile(layout, code)?;
                b.compile(layout, code)?;
                code.push(Op::Bin(*op));
            }
            Expr::Call(f, args) => {
                for a in args {
                    a.compile(layout, code)?;
                }
                code.push(if args.len() == 2 {
                    Op::Call2(*f)
                } else {
                    Op::Call1(*f)
                });
            }
        }
        Ok(())
    }
}

impl BoundExpr {
    /// Evaluate on a state vector laid out as given to [`Expr::bind`].
    /// Never allocates; an index past the state's end reads NaN.
    #[inline]
    pub fn eval(&self, state: &[f64]) -> f64 {
        let mut stack = [0.0f64; MAX_STACK];
        let mut sp = 0usize;
        for op in &self.code {
            match *op {
                Op::Const(c) => {
                    stack[sp] = c;
                    sp += 1;
                }
                Op::Load(i) => {
                    stack[sp] = state.get(i).copied().unwrap_or(f64::NAN);
                    sp += 1;
                }
                Op::Neg => stack[sp - 1] = -stack[sp - 1],
                Op::Bin(b) => {
                    sp -= 1;
                    stack[sp - 1] = binop(b, stack[sp - 1], stack[sp]);
                }
                Op::Call1(f) => stack[sp - 1] = f.apply(stack[sp - 1], 0.0),
                Op::Call2(f) => {
                    sp -= 1;
                    stack[sp - 1] = f.apply(stack[sp - 1], stack[sp]);
                }
            }
        }
        debug_assert!(self.stack_depth <= MAX_STACK);
        stack[0]
    }
}

#[inline]
fn binop(op: BinOp, a: f64, b: f64) -> f64 {
    match op {
        BinOp::Add => a + b,
        BinOp::Sub => a - b,
        BinOp::Mul => a * b,
        BinOp::Div => a / b,
        BinOp::Pow => {
            if b.fract() == 0.0 && b.abs() <= 16.0 {
                a.powi(b as i32)
            } else {
                a.powf(b)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(src: &str, cols: &[(&str, &[f64])]) -> Vec<f64> {
        let n = cols.first().map_or(1, |c| c.1.len());
        let lookup = |name: &str| cols.iter().find(|c| c.0 == name).map(|c| c.1);
        Expr::parse(src)
            .expect("parses")
            .eval_columns(&lookup, n)
            .expect("evaluates")
    }

    #[test]
    fn precedence_and_associativity() {
        let x = [2.0];
        assert_eq!(eval("1 + 2 * x ^ 2", &[("x", &x)]), vec![9.0]);
        assert_eq!(eval("2 ^ 3 ^ 2", &[("x", &x)]), vec![512.0]);
        assert_eq!(eval("-x ^ 2", &[("x", &x)]), vec![-4.0]);
        assert_eq!(eval("(1 + x) * 3 - 8 / x", &[("x", &x)]), vec![5.0]);
        assert_eq!(eval("1.5e1 - x", &[("x", &x)]), vec![13.0]);
    }

    #[test]
    fn deadband_is_thesis_eq_3_15_3_16() {
        // (da - 2)+ + (da + 2)-: zero in [-2, 2], unit slope outside.
        let da = [-6.0, -2.0, -1.9, 0.0, 2.0, 2.5, 10.0];
        let got = eval("deadband(da, 2)", &[("da", &da)]);
        let want: Vec<f64> = da
            .iter()
            .map(|&d| {
                let plus = if d - 2.0 > 0.0 { d - 2.0 } else { 0.0 };
                let minus = if d + 2.0 < 0.0 { d + 2.0 } else { 0.0 };
                plus + minus
            })
            .collect();
        assert_eq!(got, want);
        assert_eq!(eval("pos(da - 2) + neg(da + 2)", &[("da", &da)]), want);
    }

    #[test]
    fn products_and_functions() {
        let a = [1.0, -2.0];
        let b = [3.0, 4.0];
        assert_eq!(eval("a * b", &[("a", &a), ("b", &b)]), vec![3.0, -8.0]);
        assert_eq!(
            eval("abs(a) + max(a, b) - min(a, 0)", &[("a", &a), ("b", &b)]),
            vec![4.0, 8.0]
        );
        assert_eq!(eval("step(a)", &[("a", &a)]), vec![1.0, 0.0]);
        let e = Expr::parse("alphadot * ds + beta * phat - 1").expect("parses");
        assert_eq!(e.columns(), vec!["alphadot", "ds", "beta", "phat"]);
        assert!(Expr::parse("2 * 3").expect("parses").is_constant());
    }

    #[test]
    fn nan_propagates() {
        let a = [f64::NAN];
        assert!(eval("deadband(a, 2)", &[("a", &a)])[0].is_nan());
        assert!(eval("step(a)", &[("a", &a)])[0].is_nan());
        assert!(eval("max(a, 1)", &[("a", &a)])[0].is_nan());
    }

    #[test]
    fn errors_name_expression_and_column() {
        let e = Expr::parse("beta * ").unwrap_err().to_string();
        assert!(e.contains("regressor 'beta * ', column 8"), "{e}");
        let e = Expr::parse("foo(beta)").unwrap_err().to_string();
        assert!(e.contains("unknown function 'foo'"), "{e}");
        let e = Expr::parse("deadband(da)").unwrap_err().to_string();
        assert!(e.contains("takes 2 argument(s), got 1"), "{e}");
        let e = Expr::parse("beta $ 2").unwrap_err().to_string();
        assert!(e.contains("column 6") && e.contains("'$'"), "{e}");
        let e = Expr::parse("(beta").unwrap_err().to_string();
        assert!(e.contains("expected ')'"), "{e}");
        let lookup = |_: &str| -> Option<&[f64]> { None };
        let e = Expr::parse("phat")
            .expect("parses")
            .eval_columns(&lookup, 3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("regressor column 'phat'"), "{e}");
    }

    #[test]
    fn bound_path_matches_columns() {
        let a = [0.3, -1.7, 2.5];
        let b = [1.0, 2.0, -3.0];
        let src = "deadband(a, 0.5) * b ^ 2 - sin(a) / (1 + abs(b)) + -max(a, b)";
        let cols = eval(src, &[("a", &a), ("b", &b)]);
        let bound = Expr::parse(src)
            .expect("parses")
            .bind(&["x", "b", "a"])
            .expect("binds");
        for i in 0..3 {
            assert_eq!(bound.eval(&[99.0, b[i], a[i]]).to_bits(), cols[i].to_bits());
        }
        let e = Expr::parse("c + a")
            .expect("parses")
            .bind(&["a", "b"])
            .unwrap_err();
        assert!(e.to_string().contains("regressor column 'c'"), "{e}");
    }

    #[test]
    fn point_and_column_paths_agree() {
        let a = [0.3, -1.7, 2.5];
        let b = [1.0, 2.0, -3.0];
        let src = "deadband(a, 0.5) * b ^ 2 - sin(a) / (1 + abs(b))";
        let cols = eval(src, &[("a", &a), ("b", &b)]);
        let e = Expr::parse(src).expect("parses");
        for i in 0..3 {
            let lookup = |n: &str| match n {
                "a" => Some(a[i]),
                "b" => Some(b[i]),
                _ => None,
            };
            assert_eq!(e.eval_point(&lookup).to_bits(), cols[i].to_bits());
        }
    }

    /// Parse `src` on a thread with Rust's default 2 MiB test stack, so a
    /// recursion that is not bounded fails the test (by overflowing) instead
    /// of passing on a larger main-thread stack.
    fn parse_on_small_stack(src: String) -> Result<Expr> {
        std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(move || Expr::parse(&src))
            .expect("spawn")
            .join()
            .expect("no panic")
    }

    fn too_deep(src: String) -> String {
        let n = src.chars().count();
        let e = parse_on_small_stack(src).expect_err("must be refused");
        assert_eq!(e.kind(), crate::error::ErrorKind::InvalidInput);
        let msg = e.to_string();
        assert!(!msg.contains('\n'), "one line: {msg}");
        assert!(msg.len() < 600, "short: {msg}");
        assert!(msg.contains(&format!("({n} characters)")), "{msg}");
        msg
    }

    #[test]
    fn deep_parentheses_are_refused_not_overflowing() {
        let src = format!("{}x{}", "(".repeat(20_000), ")".repeat(20_000));
        let msg = too_deep(src);
        assert!(
            msg.contains("nests 20000 levels deep") && msg.contains("at most 64 are supported"),
            "{msg}"
        );
        assert!(msg.contains("column 65"), "{msg}");
        // Unbalanced: still refused on depth, not by recursing.
        let msg = too_deep("(".repeat(20_000));
        assert!(msg.contains("nests 20000 levels deep"), "{msg}");
    }

    #[test]
    fn long_unary_minus_and_power_chains_are_refused() {
        let msg = too_deep(format!("{}x", "-".repeat(20_000)));
        assert!(msg.contains("nests 20000 levels deep"), "{msg}");
        let msg = too_deep(vec!["x"; 20_001].join(" ^ "));
        assert!(msg.contains("nests 20000 levels deep"), "{msg}");
        let msg = too_deep(format!("{}1", "-".repeat(20_000)));
        assert!(msg.contains("at most 64"), "{msg}");
        let msg = too_deep(vec!["f(x)"; 300].join("^").replace('f', "abs"));
        assert!(msg.contains("nests 300 levels deep"), "{msg}");
        let calls = format!("{}x{}", "abs(".repeat(20_000), ")".repeat(20_000));
        assert!(too_deep(calls).contains("nests 20000 levels deep"));
    }

    #[test]
    fn long_flat_chains_are_refused_by_tree_depth() {
        for op in ["+", "-", "*", "/"] {
            let msg = too_deep(vec!["a"; 20_000].join(&format!(" {op} ")));
            assert!(
                msg.contains("is 20000 operations deep")
                    && msg.contains("at most 256 are supported")
                    && msg.contains("split it"),
                "{msg}"
            );
        }
        // Mixed: nesting within the limit around a long chain.
        let src = format!(
            "{}{}{}",
            "(".repeat(60),
            vec!["b"; 5_000].join("*"),
            ")".repeat(60)
        );
        assert!(too_deep(src).contains("is 5000 operations deep"));
    }

    #[test]
    fn trees_past_max_nodes_are_refused_and_extra_arguments_counted() {
        // A sum of 16 products of 64 factors: 16 * (64 + 63) + 15 = 2047
        // nodes, 81 deep; one more factor passes MAX_NODES.
        let row = vec!["a"; 64].join("*");
        let src = vec![row.as_str(); 16].join("+");
        let e = parse_on_small_stack(src.clone()).expect("2047 nodes parse");
        let a = [1.5];
        let lookup = |n: &str| (n == "a").then_some(&a[..]);
        let want = 16.0 * 1.5f64.powi(64);
        let got = e.eval_columns(&lookup, 1).expect("evaluates")[0];
        assert!((got - want).abs() <= 1e-12 * want, "{got} {want}");
        let msg = too_deep(format!("{src}*a*a"));
        assert!(
            msg.contains("has 2051 numbers, names, operators and function calls; at most 2048"),
            "{msg}"
        );
        // Arguments past a function's arity are counted, not kept.
        let msg = Expr::parse(&format!("min({})", vec!["a"; 5000].join(",")))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("min() takes 2 argument(s), got 5000"), "{msg}");
        // Messages quote the expression on one line.
        let msg = Expr::parse("a +\n* b").unwrap_err().to_string();
        assert!(
            msg.starts_with("regressor 'a +\\n* b', column 5: unexpected '*'"),
            "{msg}"
        );
    }

    #[test]
    fn expressions_at_the_limits_parse_and_evaluate() {
        // 64 levels of each kind of nesting parse.
        let x = [2.0];
        let src = format!("{}x{}", "(".repeat(MAX_NESTING), ")".repeat(MAX_NESTING));
        assert_eq!(eval(&src, &[("x", &x)]), vec![2.0]);
        let src = format!("{}x", "-".repeat(MAX_NESTING));
        assert_eq!(eval(&src, &[("x", &x)]), vec![2.0]);
        let src = format!("{}x{}", "abs(".repeat(MAX_NESTING), ")".repeat(MAX_NESTING));
        assert_eq!(eval(&src, &[("x", &x)]), vec![2.0]);
        let src = format!("{}x", "-".repeat(MAX_NESTING + 1));
        assert!(Expr::parse(&src).is_err());
        // A chain of MAX_DEPTH terms is MAX_DEPTH deep and parses; one more does not.
        let src = vec!["x"; MAX_DEPTH].join(" + ");
        let e = parse_on_small_stack(src).expect("parses");
        let lookup = |n: &str| (n == "x").then_some(&x[..]);
        assert_eq!(e.eval_columns(&lookup, 1).expect("evaluates"), vec![512.0]);
        assert_eq!(e.columns(), vec!["x"]);
        assert!(e.to_string().len() > 1000);
        let src = vec!["x"; MAX_DEPTH + 1].join(" + ");
        let msg = parse_on_small_stack(src).unwrap_err().to_string();
        assert!(msg.contains("is 257 operations deep"), "{msg}");
        // Short expressions keep their whole text in messages.
        let msg = Expr::parse("((beta)").unwrap_err().to_string();
        assert!(msg.starts_with("regressor '((beta)', column 8"), "{msg}");
    }
}

//! The MathML-2 content-markup subset DAVE-ML models use, compiled once into an
//! expression tree ([`Expr`]) whose variables are indices into the model's
//! value vector.
//!
//! Supported: `cn` (also `type="e-notation"`/`"rational"` with `<sep/>`), `ci`,
//! constants `pi`, `exponentiale`, `true`, `false`, `notanumber`, `infinity`;
//! `apply` with `plus`, `minus` (unary and binary), `times`, `divide`, `power`,
//! `root` (optional `degree`), `abs`, `sqrt` (a `csymbol`), `exp`, `ln`, `log`
//! (optional `logbase`, default 10), `floor`, `ceiling`, `rem`, `quotient`,
//! `min`, `max`, `sin`, `cos`, `tan`, `sec`, `csc`, `cot`, `arcsin`, `arccos`,
//! `arctan`, `sinh`, `cosh`, `tanh`, `eq`, `neq`, `gt`, `lt`, `geq`, `leq`,
//! `and`, `or`, `xor`, `not`; `csymbol` named `atan2` (two arguments, y then x,
//! as DAVE-ML's extension), `sqrt`, `sign`; and `piecewise` with `piece` and
//! `otherwise`. Angles of trigonometric functions are in radians (MathML).
//! Booleans are 1.0 (true) and 0.0 (false); a `piecewise` with no true piece
//! and no `otherwise` is NaN.
//!
//! A calculation may nest at most [`MAX_DEPTH`] elements below its `<math>`
//! (real models nest a few dozen at most; long sums and products are one n-ary
//! `<apply>`); deeper ones are refused before compiling, so neither the
//! compiler nor the evaluation recurses without bound.

use super::{elements, text_of, Node, Source};
use crate::error::Result;
use crate::text::shown;

/// Most elements a calculation may nest below its `<math>` (a `<ci>` directly
/// in `<math>` is 1 deep; `<apply><plus/><ci>a</ci><ci>b</ci></apply>` is 2).
/// Regressors written by [`super::write`] (at most
/// [`crate::regressor::MAX_DEPTH`] deep) stay well within it.
pub const MAX_DEPTH: usize = 512;

/// The depth of the deepest element below `math`, and the first element (in
/// document order) deeper than [`MAX_DEPTH`], if any; without recursion: a
/// walk in document order keeping the chain of open elements (siblings are
/// not kept).
fn element_depth(math: Node<'_>) -> (usize, Option<Node<'_>>) {
    let (mut max, mut first_over) = (0usize, None);
    let mut chain: Vec<Node<'_>> = vec![math];
    for n in math.descendants().skip(1).filter(|n| n.is_element()) {
        while chain.len() > 1 && !chain.last().is_some_and(|p| p.contains(n)) {
            chain.pop();
        }
        chain.push(n);
        let depth = chain.len() - 1;
        max = max.max(depth);
        if depth > MAX_DEPTH && first_over.is_none() {
            first_over = Some(n);
        }
    }
    (max, first_over)
}

/// A function of one argument.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unary {
    Neg,
    Abs,
    Sqrt,
    Exp,
    Ln,
    Log10,
    Floor,
    Ceil,
    Sin,
    Cos,
    Tan,
    Sec,
    Csc,
    Cot,
    Asin,
    Acos,
    Atan,
    Sinh,
    Cosh,
    Tanh,
    Not,
    Sign,
}

impl Unary {
    fn apply(self, x: f64) -> f64 {
        match self {
            Unary::Neg => -x,
            Unary::Abs => x.abs(),
            Unary::Sqrt => x.sqrt(),
            Unary::Exp => x.exp(),
            Unary::Ln => x.ln(),
            Unary::Log10 => x.log10(),
            Unary::Floor => x.floor(),
            Unary::Ceil => x.ceil(),
            Unary::Sin => x.sin(),
            Unary::Cos => x.cos(),
            Unary::Tan => x.tan(),
            Unary::Sec => 1.0 / x.cos(),
            Unary::Csc => 1.0 / x.sin(),
            Unary::Cot => 1.0 / x.tan(),
            Unary::Asin => x.asin(),
            Unary::Acos => x.acos(),
            Unary::Atan => x.atan(),
            Unary::Sinh => x.sinh(),
            Unary::Cosh => x.cosh(),
            Unary::Tanh => x.tanh(),
            Unary::Not => truth(!is_true(x)),
            Unary::Sign => {
                if x > 0.0 {
                    1.0
                } else if x < 0.0 {
                    -1.0
                } else {
                    x
                }
            }
        }
    }
}

/// A function of two arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binary {
    Sub,
    Div,
    Pow,
    Rem,
    Quotient,
    Atan2,
    /// `root` with a degree: `a^(1/degree)`, degree first.
    Root,
    /// `log` with a base: `ln(a)/ln(base)`, base first.
    Log,
}

impl Binary {
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Binary::Sub => a - b,
            Binary::Div => a / b,
            Binary::Pow => a.powf(b),
            Binary::Rem => a % b,
            Binary::Quotient => (a / b).trunc(),
            Binary::Atan2 => a.atan2(b),
            Binary::Root => b.powf(1.0 / a),
            Binary::Log => b.ln() / a.ln(),
        }
    }
}

/// An n-ary function or relation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Nary {
    Plus,
    Times,
    Min,
    Max,
    And,
    Or,
    Xor,
    Eq,
    Neq,
    Gt,
    Lt,
    Geq,
    Leq,
}

/// A compiled MathML expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A number.
    Const(f64),
    /// The value of variable `i` of the model.
    Var(usize),
    /// `f(a)`.
    Unary(Unary, Box<Expr>),
    /// `f(a, b)`.
    Binary(Binary, Box<Expr>, Box<Expr>),
    /// `f(a, b, ...)`; relations hold pairwise along the chain.
    Nary(Nary, Vec<Expr>),
    /// The value of the first piece whose condition holds, else `otherwise`, else NaN.
    Piecewise {
        pieces: Vec<(Expr, Expr)>,
        otherwise: Option<Box<Expr>>,
    },
}

#[inline]
fn truth(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

#[inline]
fn is_true(x: f64) -> bool {
    x != 0.0 && !x.is_nan()
}

impl Expr {
    /// Evaluate with the model's current values (`values[i]` is variable `i`).
    ///
    /// ```
    /// use aero_core::daveml::mathml::{Expr, Binary};
    /// let e = Expr::Binary(Binary::Pow, Box::new(Expr::Var(0)), Box::new(Expr::Const(2.0)));
    /// assert_eq!(e.eval(&[3.0]), 9.0);
    /// ```
    pub fn eval(&self, values: &[f64]) -> f64 {
        match self {
            Expr::Const(c) => *c,
            Expr::Var(i) => values.get(*i).copied().unwrap_or(f64::NAN),
            Expr::Unary(op, a) => op.apply(a.eval(values)),
            Expr::Binary(op, a, b) => op.apply(a.eval(values), b.eval(values)),
            Expr::Nary(op, args) => eval_nary(*op, args, values),
            Expr::Piecewise { pieces, otherwise } => {
                for (value, cond) in pieces {
                    if is_true(cond.eval(values)) {
                        return value.eval(values);
                    }
                }
                otherwise.as_ref().map_or(f64::NAN, |o| o.eval(values))
            }
        }
    }

    /// Indices of the variables this expression reads, in order of appearance.
    pub fn variables(&self, out: &mut Vec<usize>) {
        match self {
            Expr::Const(_) => {}
            Expr::Var(i) => out.push(*i),
            Expr::Unary(_, a) => a.variables(out),
            Expr::Binary(_, a, b) => {
                a.variables(out);
                b.variables(out);
            }
            Expr::Nary(_, args) => args.iter().for_each(|a| a.variables(out)),
            Expr::Piecewise { pieces, otherwise } => {
                for (v, c) in pieces {
                    v.variables(out);
                    c.variables(out);
                }
                if let Some(o) = otherwise {
                    o.variables(out);
                }
            }
        }
    }
}

fn eval_nary(op: Nary, args: &[Expr], v: &[f64]) -> f64 {
    match op {
        Nary::Plus => args.iter().map(|a| a.eval(v)).sum(),
        Nary::Times => args.iter().fold(1.0, |acc, a| acc * a.eval(v)),
        Nary::Min => args.iter().map(|a| a.eval(v)).fold(f64::INFINITY, |m, x| {
            if x < m || x.is_nan() {
                x
            } else {
                m
            }
        }),
        Nary::Max => args
            .iter()
            .map(|a| a.eval(v))
            .fold(
                f64::NEG_INFINITY,
                |m, x| if x > m || x.is_nan() { x } else { m },
            ),
        Nary::And => truth(args.iter().all(|a| is_true(a.eval(v)))),
        Nary::Or => truth(args.iter().any(|a| is_true(a.eval(v)))),
        Nary::Xor => truth(args.iter().filter(|a| is_true(a.eval(v))).count() % 2 == 1),
        Nary::Eq | Nary::Neq | Nary::Gt | Nary::Lt | Nary::Geq | Nary::Leq => {
            let xs: Vec<f64> = args.iter().map(|a| a.eval(v)).collect();
            truth(xs.windows(2).all(|w| {
                let (a, b) = (w[0], w[1]);
                match op {
                    Nary::Eq => a == b,
                    Nary::Neq => a != b,
                    Nary::Gt => a > b,
                    Nary::Lt => a < b,
                    Nary::Geq => a >= b,
                    _ => a <= b,
                }
            }))
        }
    }
}

/// Compile the `<math>` of the calculation of variable `var` (its
/// `<variableDef>`); `resolve` maps a `ci` name to a variable index.
///
/// # Errors
/// As [`compile`]; a calculation nested deeper than [`MAX_DEPTH`] is an error
/// naming the variable, its line and the line of the first element too deep.
pub(crate) fn calculation(
    src: &Source,
    math: Node<'_>,
    resolve: &dyn Fn(&str) -> Option<usize>,
    var: Node<'_>,
) -> Result<Expr> {
    if let (depth, Some(deep)) = element_depth(math) {
        return Err(src.err(
            var,
            format!(
                "its calculation nests {depth} MathML elements deep (past {MAX_DEPTH} on line {}); \
                 at most {MAX_DEPTH} are supported; write long sums and products as one n-ary \
                 <apply><plus/> or <apply><times/>, or split the calculation into intermediate \
                 variables",
                src.line(deep)
            ),
        ));
    }
    compile_checked(src, math, resolve)
}

/// Compile the content of a `<math>` (or `<calculation>`) element; `resolve`
/// maps a `ci` name to a variable index.
///
/// # Errors
/// A parse error naming the element and line for an unknown `ci`, an
/// unsupported element, a wrong number of arguments or nesting deeper than
/// [`MAX_DEPTH`].
#[cfg(test)]
pub(crate) fn compile(
    src: &Source,
    math: Node<'_>,
    resolve: &dyn Fn(&str) -> Option<usize>,
) -> Result<Expr> {
    if let (depth, Some(deep)) = element_depth(math) {
        return Err(src.err(
            deep,
            format!("is nested {depth} MathML elements deep; at most {MAX_DEPTH} are supported"),
        ));
    }
    compile_checked(src, math, resolve)
}

/// [`compile`] once the depth is known to be within [`MAX_DEPTH`].
fn compile_checked(
    src: &Source,
    math: Node<'_>,
    resolve: &dyn Fn(&str) -> Option<usize>,
) -> Result<Expr> {
    let mut kids = elements(math);
    match (kids.next(), kids.next()) {
        (Some(one), None) => expr(src, one, resolve),
        (None, _) => Err(src.err(math, "holds no expression")),
        (Some(_), Some(_)) => Err(src.err(
            math,
            format!(
                "holds {} expressions; give exactly one",
                elements(math).count()
            ),
        )),
    }
}

fn expr(src: &Source, node: Node<'_>, resolve: &dyn Fn(&str) -> Option<usize>) -> Result<Expr> {
    let tag = node.tag_name();
    match tag {
        "cn" => cn(src, node).map(Expr::Const),
        "ci" => {
            let name = text_of(node);
            resolve(&name).map(Expr::Var).ok_or_else(|| {
                let name = shown(&name);
                src.err(
                    node,
                    format!(
                        "unknown varID '{name}'; declare it with a <variableDef varID=\"{name}\">"
                    ),
                )
            })
        }
        "pi" => Ok(Expr::Const(std::f64::consts::PI)),
        "exponentiale" => Ok(Expr::Const(std::f64::consts::E)),
        "true" => Ok(Expr::Const(1.0)),
        "false" => Ok(Expr::Const(0.0)),
        "notanumber" => Ok(Expr::Const(f64::NAN)),
        "infinity" => Ok(Expr::Const(f64::INFINITY)),
        "semantics" | "math" => compile_checked(src, node, resolve),
        "piecewise" => piecewise(src, node, resolve),
        "apply" => apply(src, node, resolve),
        _ => Err(src.err(node, "is not a supported MathML element here")),
    }
}

fn cn(src: &Source, node: Node<'_>) -> Result<f64> {
    let parts: Vec<String> = {
        // Split the text on <sep/> for e-notation and rational numbers.
        let mut parts = vec![String::new()];
        for c in node.children() {
            if c.is_text() {
                if let Some(last) = parts.last_mut() {
                    last.push_str(c.text().unwrap_or(""));
                }
            } else if c.is_element() && c.tag_name() == "sep" {
                parts.push(String::new());
            }
        }
        parts.into_iter().map(|p| p.trim().to_string()).collect()
    };
    let num = |s: &str| -> Result<f64> {
        s.parse::<f64>()
            .map_err(|_| src.err(node, format!("'{}' is not a number", shown(s))))
    };
    match (node.attribute("type"), parts.as_slice()) {
        (_, [one]) => num(one),
        (Some("e-notation"), [m, e]) => Ok(num(m)? * 10f64.powf(num(e)?)),
        (Some("rational"), [n, d]) => Ok(num(n)? / num(d)?),
        _ => Err(src.err(node, "has an unsupported form; use a plain number")),
    }
}

fn piecewise(
    src: &Source,
    node: Node<'_>,
    resolve: &dyn Fn(&str) -> Option<usize>,
) -> Result<Expr> {
    let mut pieces = Vec::new();
    let mut otherwise = None;
    for k in elements(node) {
        match k.tag_name() {
            "piece" => {
                let mut parts = elements(k);
                let (Some(v), Some(c), None) = (parts.next(), parts.next(), parts.next()) else {
                    return Err(src.err(
                        k,
                        format!(
                            "has {} children; a piece holds a value then a condition",
                            elements(k).count()
                        ),
                    ));
                };
                pieces.push((expr(src, v, resolve)?, expr(src, c, resolve)?));
            }
            "otherwise" => otherwise = Some(Box::new(compile_checked(src, k, resolve)?)),
            _ => {
                return Err(src.err(
                    k,
                    "is not allowed in <piecewise>; use <piece> or <otherwise>",
                ))
            }
        }
    }
    Ok(Expr::Piecewise { pieces, otherwise })
}

fn op_name(node: Node<'_>) -> String {
    if node.tag_name() == "csymbol" {
        text_of(node)
    } else {
        node.tag_name().to_string()
    }
}

fn apply(src: &Source, node: Node<'_>, resolve: &dyn Fn(&str) -> Option<usize>) -> Result<Expr> {
    // The children are walked, not collected: an <apply> may have many.
    let mut kids = elements(node);
    let Some(op_node) = kids.next() else {
        return Err(src.err(node, "is empty; give an operator and its arguments"));
    };
    let n_rest = elements(node).count() - 1;
    let op = shown(&op_name(op_node));
    // `<apply><piecewise>...</piecewise></apply>` (F16_aero.dml) is the piecewise itself.
    if n_rest == 0 && matches!(op.as_str(), "piecewise" | "ci" | "cn" | "apply") {
        return expr(src, op_node, resolve);
    }
    // Qualifiers (degree, logbase) come first among the arguments.
    let mut qualifier = None;
    let mut args = Vec::with_capacity(n_rest);
    for a in kids {
        match a.tag_name() {
            "degree" | "logbase" => qualifier = Some(compile_checked(src, a, resolve)?),
            _ => args.push(expr(src, a, resolve)?),
        }
    }
    build(src, op_node, &op, args, qualifier)
}

/// The expression of operator `op` applied to compiled `args`: apart from
/// [`apply`] so the recursion through `apply` keeps a small stack frame.
#[inline(never)]
fn build(
    src: &Source,
    op_node: Node<'_>,
    op: &str,
    args: Vec<Expr>,
    qualifier: Option<Expr>,
) -> Result<Expr> {
    let n = args.len();
    let arity_err = |want: &str| {
        src.err(
            op_node,
            format!("'{op}' takes {want} argument(s) but the <apply> gives {n}"),
        )
    };
    let unary = |u: Unary, mut args: Vec<Expr>| -> Result<Expr> {
        match args.pop() {
            Some(a) if n == 1 => Ok(Expr::Unary(u, Box::new(a))),
            _ => Err(arity_err("1")),
        }
    };
    let binary = |b: Binary, args: Vec<Expr>| -> Result<Expr> {
        let mut it = args.into_iter();
        match (it.next(), it.next(), it.next()) {
            (Some(a), Some(c), None) => Ok(Expr::Binary(b, Box::new(a), Box::new(c))),
            _ => Err(arity_err("2")),
        }
    };
    let nary = |m: Nary, min: usize, args: Vec<Expr>| -> Result<Expr> {
        if args.len() < min {
            return Err(arity_err(&format!("at least {min}")));
        }
        Ok(Expr::Nary(m, args))
    };
    match op {
        "plus" => {
            if n == 1 {
                Ok(args.into_iter().next().unwrap_or(Expr::Const(0.0)))
            } else {
                nary(Nary::Plus, 1, args)
            }
        }
        "minus" => match n {
            1 => unary(Unary::Neg, args),
            _ => binary(Binary::Sub, args),
        },
        "times" => nary(Nary::Times, 1, args),
        "divide" => binary(Binary::Div, args),
        "power" => binary(Binary::Pow, args),
        "rem" => binary(Binary::Rem, args),
        "quotient" => binary(Binary::Quotient, args),
        "atan2" | "arctan2" => binary(Binary::Atan2, args),
        "root" => match qualifier {
            Some(d) => {
                let a = args.into_iter().next().ok_or_else(|| arity_err("1"))?;
                Ok(Expr::Binary(Binary::Root, Box::new(d), Box::new(a)))
            }
            None => unary(Unary::Sqrt, args),
        },
        "log" => match qualifier {
            Some(b) => {
                let a = args.into_iter().next().ok_or_else(|| arity_err("1"))?;
                Ok(Expr::Binary(Binary::Log, Box::new(b), Box::new(a)))
            }
            None => unary(Unary::Log10, args),
        },
        "sqrt" => unary(Unary::Sqrt, args),
        "abs" => unary(Unary::Abs, args),
        "exp" => unary(Unary::Exp, args),
        "ln" => unary(Unary::Ln, args),
        "floor" => unary(Unary::Floor, args),
        "ceiling" => unary(Unary::Ceil, args),
        "sin" => unary(Unary::Sin, args),
        "cos" => unary(Unary::Cos, args),
        "tan" => unary(Unary::Tan, args),
        "sec" => unary(Unary::Sec, args),
        "csc" => unary(Unary::Csc, args),
        "cot" => unary(Unary::Cot, args),
        "arcsin" => unary(Unary::Asin, args),
        "arccos" => unary(Unary::Acos, args),
        "arctan" => unary(Unary::Atan, args),
        "sinh" => unary(Unary::Sinh, args),
        "cosh" => unary(Unary::Cosh, args),
        "tanh" => unary(Unary::Tanh, args),
        "not" => unary(Unary::Not, args),
        "sign" => unary(Unary::Sign, args),
        "min" => nary(Nary::Min, 1, args),
        "max" => nary(Nary::Max, 1, args),
        "and" => nary(Nary::And, 1, args),
        "or" => nary(Nary::Or, 1, args),
        "xor" => nary(Nary::Xor, 1, args),
        "eq" => nary(Nary::Eq, 2, args),
        "neq" => nary(Nary::Neq, 2, args),
        "gt" => nary(Nary::Gt, 2, args),
        "lt" => nary(Nary::Lt, 2, args),
        "geq" => nary(Nary::Geq, 2, args),
        "leq" => nary(Nary::Leq, 2, args),
        _ => Err(src.err(
            op_node,
            format!("operator '{op}' is not supported (supported: plus, minus, times, divide, power, root, sqrt, abs, exp, ln, log, floor, ceiling, rem, quotient, min, max, trigonometric and hyperbolic functions, relations, and, or, xor, not, piecewise, csymbol atan2)"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn compile_str(body: &str, vars: &[&str]) -> Result<Expr> {
        let text = format!("<math xmlns=\"http://www.w3.org/1998/Math/MathML\">{body}</math>");
        let doc = super::super::parse_document(&text, "t.xml").expect("xml");
        let src = Source::new("t.xml", &text);
        let names: Vec<String> = vars.iter().map(|s| s.to_string()).collect();
        compile(&src, doc.root_element(), &|n| {
            names.iter().position(|v| v == n)
        })
    }

    fn eval(body: &str, vals: &[f64]) -> f64 {
        let names = ["x", "y", "z"];
        compile_str(body, &names[..vals.len()])
            .expect("compiles")
            .eval(vals)
    }

    #[test]
    fn arithmetic_against_closed_forms() {
        let (x, y) = (1.7, -0.4);
        let v = [x, y];
        assert_eq!(
            eval("<apply><plus/><ci>x</ci><ci>y</ci><cn>3</cn></apply>", &v),
            x + y + 3.0
        );
        assert_eq!(
            eval("<apply><minus/><ci>x</ci><ci>y</ci></apply>", &v),
            x - y
        );
        assert_eq!(eval("<apply><minus/><ci>x</ci></apply>", &v), -x);
        assert_eq!(
            eval("<apply><times/><ci>x</ci><ci>y</ci><cn>2.</cn></apply>", &v),
            x * y * 2.0
        );
        assert_eq!(
            eval("<apply><divide/><ci>x</ci><ci>y</ci></apply>", &v),
            x / y
        );
        assert_eq!(
            eval("<apply><power/><ci>x</ci><cn>0.5</cn></apply>", &v),
            x.powf(0.5)
        );
        assert_eq!(eval("<apply><abs/><ci>y</ci></apply>", &v), 0.4);
        assert_eq!(
            eval("<apply><csymbol>sqrt</csymbol><ci>x</ci></apply>", &v),
            x.sqrt()
        );
        assert_eq!(eval("<apply><root/><ci>x</ci></apply>", &v), x.sqrt());
        assert!(
            (eval(
                "<apply><root/><degree><cn>3</cn></degree><cn>27</cn></apply>",
                &v
            ) - 3.0)
                .abs()
                < 1e-15
        );
        assert!(
            (eval(
                "<apply><log/><logbase><cn>2</cn></logbase><cn>8</cn></apply>",
                &v
            ) - 3.0)
                .abs()
                < 1e-15
        );
        assert_eq!(
            eval("<apply><min/><ci>x</ci><ci>y</ci><cn>5</cn></apply>", &v),
            y
        );
        assert_eq!(eval("<apply><max/><ci>x</ci><ci>y</ci></apply>", &v), x);
        assert_eq!(eval("<cn type=\"e-notation\">1.5<sep/>-3</cn>", &v), 1.5e-3);
        assert_eq!(eval("<pi/>", &v), std::f64::consts::PI);
    }

    #[test]
    fn trigonometry_and_atan2() {
        let v = [0.3, -0.8];
        assert_eq!(eval("<apply><sin/><ci>x</ci></apply>", &v), 0.3f64.sin());
        assert_eq!(eval("<apply><cos/><ci>x</ci></apply>", &v), 0.3f64.cos());
        assert_eq!(eval("<apply><tan/><ci>x</ci></apply>", &v), 0.3f64.tan());
        assert_eq!(
            eval("<apply><arctan/><ci>y</ci></apply>", &v),
            (-0.8f64).atan()
        );
        assert_eq!(
            eval("<apply><arcsin/><ci>x</ci></apply>", &v),
            0.3f64.asin()
        );
        assert_eq!(
            eval("<apply><csymbol definitionURL=\"http://daveml.org/function_spaces.html#atan2\">atan2</csymbol><ci>y</ci><ci>x</ci></apply>", &v),
            (-0.8f64).atan2(0.3)
        );
    }

    #[test]
    fn piecewise_with_comparisons() {
        // F16_aero.dml's form: sign(beta) * |Cl0|, wrapped in an operator-less <apply>.
        let body = "<apply><piecewise>\
            <piece><apply><minus/><ci>x</ci></apply><apply><lt/><ci>y</ci><cn>0</cn></apply></piece>\
            <otherwise><ci>x</ci></otherwise></piecewise></apply>";
        assert_eq!(eval(body, &[2.0, -1.0]), -2.0);
        assert_eq!(eval(body, &[2.0, 1.0]), 2.0);
        assert_eq!(eval(body, &[2.0, 0.0]), 2.0);
        let no_otherwise = "<piecewise><piece><cn>1</cn><apply><gt/><ci>x</ci><cn>0</cn></apply></piece></piecewise>";
        assert_eq!(eval(no_otherwise, &[1.0]), 1.0);
        assert!(eval(no_otherwise, &[-1.0]).is_nan());
        let both = "<apply><and/><apply><geq/><ci>x</ci><cn>0</cn></apply><apply><leq/><ci>x</ci><cn>1</cn></apply></apply>";
        assert_eq!(eval(both, &[0.5]), 1.0);
        assert_eq!(eval(both, &[1.5]), 0.0);
        assert_eq!(
            eval("<apply><lt/><cn>1</cn><cn>2</cn><cn>3</cn></apply>", &[]),
            1.0
        );
        assert_eq!(eval("<apply><neq/><cn>1</cn><cn>1</cn></apply>", &[]), 0.0);
    }

    #[test]
    fn errors_name_element_and_line() {
        let e =
            compile_str("\n<apply><plus/>\n<ci>nope</ci><cn>1</cn></apply>", &["x"]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.xml:3: <ci>: unknown varID 'nope'; declare it with a <variableDef varID=\"nope\">"
        );
        let e = compile_str("<apply><divide/><cn>1</cn></apply>", &[]).unwrap_err();
        assert!(
            e.to_string().contains("'divide' takes 2 argument(s)"),
            "{e}"
        );
        let e = compile_str("<apply><gamma/><cn>1</cn></apply>", &[]).unwrap_err();
        assert!(
            e.to_string()
                .contains("<gamma>: operator 'gamma' is not supported"),
            "{e}"
        );
    }
}

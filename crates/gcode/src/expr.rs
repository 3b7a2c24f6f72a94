//! Parameters and expressions as LinuxCNC's RS274NGC interpreter reads them.
//!
//! A word's value may be an expression (`X[#1+2]`), a parameter (`X#100`, `X#<depth>`,
//! `X##1`), a unary function (`XSIN[30]`, `XATAN[1]/[2]`) or a signed one of those (`X-#1`).
//! A line may set parameters (`#1=2`, `#<depth> = [#1*2]`). Semantics (LinuxCNC 2.9 manual,
//! "Parameters" and "Expressions"):
//!
//! - Binary operators by precedence, highest first: `**`; `*` `/` `MOD`; `+` `-`;
//!   `EQ NE GT GE LT LE`; `AND OR XOR`. Operators of equal precedence apply left to right.
//! - Functions: `ABS ACOS ASIN ATAN[y]/[x] COS EXP FIX FUP LN ROUND SIN SQRT TAN EXISTS`, angles
//!   in degrees, `FIX` rounds down, `FUP` up, `ROUND` half away from zero; `MOD` of a negative
//!   value is made non-negative (`fmod` plus `|divisor|`, as the interpreter does).
//! - Every parameter setting on a line takes effect after all values on that line have been read.
//! - Numbers have no exponent (`1e3` is not G-code); case and spaces inside brackets do not matter.
//!
//! What truepos cannot know is refused, never guessed: a parameter not set earlier in the program
//! (its value lives in the controller), a domain error (`SQRT[-1]`, division by zero), a result
//! that is not finite. Entry points: [`parse_value`], [`parse_assignment`], [`Params`].

use std::collections::HashMap;

/// A parsed expression.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Expr {
    Num(f64),
    Param(Box<ParamRef>),
    Neg(Box<Expr>),
    Bin(Op, Box<Expr>, Box<Expr>),
    Func(Func, Box<Expr>),
    Atan(Box<Expr>, Box<Expr>),
    Exists(String),
}

/// A parameter reference: numbered (by the value of an expression) or named.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum ParamRef {
    Num(Expr),
    Name(String),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Op {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl Op {
    fn precedence(self) -> u8 {
        match self {
            Op::Pow => 5,
            Op::Mul | Op::Div | Op::Mod => 4,
            Op::Add | Op::Sub => 3,
            Op::Eq | Op::Ne | Op::Gt | Op::Ge | Op::Lt | Op::Le => 2,
            Op::And | Op::Or | Op::Xor => 1,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Func {
    Abs,
    Acos,
    Asin,
    Cos,
    Exp,
    Fix,
    Fup,
    Ln,
    Round,
    Sin,
    Sqrt,
    Tan,
}

/// Highest numbered parameter LinuxCNC has (`RS274NGC_MAX_PARAMETERS - 1`).
pub(crate) const MAX_PARAMETER: u32 = 5601;

/// A syntax error at byte offset `at` (relative to the start of the parsed slice).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SyntaxError {
    pub at: usize,
    pub message: String,
}

struct Parser<'a> {
    b: &'a [u8],
    i: usize,
    /// Values and operators read so far (see [`MAX_EXPR_NODES`]).
    nodes: usize,
}

/// Most values and operators one word's expression (or one parameter setting) may hold. It
/// bounds the parser's recursion and the depth of the tree that evaluating, copying and
/// dropping walk recursively: 10,000 terms or nested brackets overflowed the reader thread's
/// stack. Real programs use a handful.
pub(crate) const MAX_EXPR_NODES: usize = 1000;

fn err<T>(at: usize, message: impl Into<String>) -> Result<T, SyntaxError> {
    Err(SyntaxError { at, message: message.into() })
}

impl Parser<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.b.len() && matches!(self.b[self.i], b' ' | b'\t') {
            self.i += 1;
        }
    }

    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    /// `[ expr ]`
    fn bracketed(&mut self) -> Result<Expr, SyntaxError> {
        if self.peek() != Some(b'[') {
            return err(self.i, "expected '['");
        }
        self.i += 1;
        let e = self.expr(0)?;
        self.skip_ws();
        if self.peek() != Some(b']') {
            return err(self.i, "expected ']' (unbalanced brackets)");
        }
        self.i += 1;
        Ok(e)
    }

    /// Binary expression with precedence climbing; all operators are left-associative.
    fn expr(&mut self, min_prec: u8) -> Result<Expr, SyntaxError> {
        let mut lhs = self.operand()?;
        loop {
            let save = self.i;
            self.skip_ws();
            let Some((op, len)) = self.binary_op() else {
                self.i = save;
                return Ok(lhs);
            };
            if op.precedence() < min_prec.max(1) {
                self.i = save;
                return Ok(lhs);
            }
            self.i += len;
            self.node()?;
            let rhs = self.expr(op.precedence() + 1)?;
            lhs = Expr::Bin(op, Box::new(lhs), Box::new(rhs));
        }
    }

    fn binary_op(&self) -> Option<(Op, usize)> {
        let rest = &self.b[self.i..];
        let up = |n: usize| -> Option<String> {
            rest.get(..n).map(|s| String::from_utf8_lossy(s).to_ascii_uppercase())
        };
        if rest.starts_with(b"**") {
            return Some((Op::Pow, 2));
        }
        match rest.first()? {
            b'*' => return Some((Op::Mul, 1)),
            b'/' => return Some((Op::Div, 1)),
            b'+' => return Some((Op::Add, 1)),
            b'-' => return Some((Op::Sub, 1)),
            _ => {}
        }
        if let Some(w) = up(3) {
            match w.as_str() {
                "MOD" => return Some((Op::Mod, 3)),
                "AND" => return Some((Op::And, 3)),
                "XOR" => return Some((Op::Xor, 3)),
                _ => {}
            }
        }
        let w = up(2)?;
        Some(match w.as_str() {
            "EQ" => (Op::Eq, 2),
            "NE" => (Op::Ne, 2),
            "GT" => (Op::Gt, 2),
            "GE" => (Op::Ge, 2),
            "LT" => (Op::Lt, 2),
            "LE" => (Op::Le, 2),
            "OR" => (Op::Or, 2),
            _ => return None,
        })
    }

    /// Count one value or operator against [`MAX_EXPR_NODES`].
    fn node(&mut self) -> Result<(), SyntaxError> {
        self.nodes += 1;
        if self.nodes > MAX_EXPR_NODES {
            return err(
                self.i,
                format!("expression of more than {MAX_EXPR_NODES} values and operators (nested or chained; the limit truepos reads)"),
            );
        }
        Ok(())
    }

    /// A value: number, `[expr]`, parameter, function, or a signed value.
    fn operand(&mut self) -> Result<Expr, SyntaxError> {
        self.node()?;
        self.skip_ws();
        let Some(c) = self.peek() else { return err(self.i, "expected a value") };
        match c {
            b'[' => self.bracketed(),
            b'#' => {
                self.i += 1;
                Ok(Expr::Param(Box::new(self.param()?)))
            }
            b'-' => {
                self.i += 1;
                Ok(Expr::Neg(Box::new(self.operand()?)))
            }
            b'+' => {
                self.i += 1;
                self.operand()
            }
            b'0'..=b'9' | b'.' => self.number(),
            c if c.is_ascii_alphabetic() => self.function(),
            _ => err(self.i, format!("unexpected '{}'", c as char)),
        }
    }

    fn number(&mut self) -> Result<Expr, SyntaxError> {
        let s = self.i;
        let mut digits = 0;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.i += 1;
            digits += 1;
        }
        if self.peek() == Some(b'.') {
            self.i += 1;
            while self.peek().is_some_and(|c| c.is_ascii_digit()) {
                self.i += 1;
                digits += 1;
            }
        }
        if digits == 0 {
            return err(s, "a number needs at least one digit");
        }
        if self.peek().is_some_and(|c| c == b'.' || c.is_ascii_digit()) {
            return err(self.i, "malformed number");
        }
        if self.peek().is_some_and(|c| c == b'e' || c == b'E')
            && self.b.get(self.i + 1).is_some_and(|c| c.is_ascii_digit() || *c == b'+' || *c == b'-')
        {
            return err(self.i, "exponents (1e3) are not G-code numbers");
        }
        let text = std::str::from_utf8(&self.b[s..self.i]).unwrap_or("");
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Expr::Num(v)),
            _ => err(s, "number out of range"),
        }
    }

    /// After `#`: digits, `<name>`, `[expr]` or another parameter.
    fn param(&mut self) -> Result<ParamRef, SyntaxError> {
        match self.peek() {
            Some(b'<') => {
                let s = self.i + 1;
                let Some(e) = self.b[s..].iter().position(|&c| c == b'>') else {
                    return err(self.i, "parameter name without closing '>'");
                };
                let raw = std::str::from_utf8(&self.b[s..s + e]).unwrap_or("");
                let name: String =
                    raw.chars().filter(|c| !c.is_whitespace()).collect::<String>().to_ascii_lowercase();
                if name.is_empty() {
                    return err(self.i, "empty parameter name");
                }
                self.i = s + e + 1;
                Ok(ParamRef::Name(name))
            }
            Some(b'[') => Ok(ParamRef::Num(self.bracketed()?)),
            Some(b'#') => {
                self.i += 1;
                Ok(ParamRef::Num(Expr::Param(Box::new(self.param()?))))
            }
            Some(c) if c.is_ascii_digit() => {
                let Expr::Num(v) = self.number()? else { unreachable!("number() returns Num") };
                Ok(ParamRef::Num(Expr::Num(v)))
            }
            _ => err(self.i, "'#' must be followed by a parameter number, <name> or [expression]"),
        }
    }

    fn function(&mut self) -> Result<Expr, SyntaxError> {
        let s = self.i;
        while self.peek().is_some_and(|c| c.is_ascii_alphabetic()) {
            self.i += 1;
        }
        let name = String::from_utf8_lossy(&self.b[s..self.i]).to_ascii_uppercase();
        self.skip_ws();
        let f = match name.as_str() {
            "ABS" => Func::Abs,
            "ACOS" => Func::Acos,
            "ASIN" => Func::Asin,
            "COS" => Func::Cos,
            "EXP" => Func::Exp,
            "FIX" => Func::Fix,
            "FUP" => Func::Fup,
            "LN" => Func::Ln,
            "ROUND" => Func::Round,
            "SIN" => Func::Sin,
            "SQRT" => Func::Sqrt,
            "TAN" => Func::Tan,
            "ATAN" => {
                let y = self.bracketed()?;
                self.skip_ws();
                if self.peek() != Some(b'/') {
                    return err(self.i, "ATAN needs the form ATAN[y]/[x]");
                }
                self.i += 1;
                self.skip_ws();
                let x = self.bracketed()?;
                return Ok(Expr::Atan(Box::new(y), Box::new(x)));
            }
            "EXISTS" => {
                if self.peek() != Some(b'[') {
                    return err(self.i, "expected '['");
                }
                self.i += 1;
                self.skip_ws();
                if self.peek() != Some(b'#') {
                    return err(self.i, "EXISTS takes a named parameter: EXISTS[#<name>]");
                }
                self.i += 1;
                let ParamRef::Name(n) = self.param()? else {
                    return err(self.i, "EXISTS takes a named parameter: EXISTS[#<name>]");
                };
                self.skip_ws();
                if self.peek() != Some(b']') {
                    return err(self.i, "expected ']'");
                }
                self.i += 1;
                return Ok(Expr::Exists(n));
            }
            _ => return err(s, format!("unknown function or operator '{name}'")),
        };
        Ok(Expr::Func(f, Box::new(self.bracketed()?)))
    }
}

/// Parse a word's value (after the letter) at the start of `b`: returns the expression and the
/// number of bytes it takes.
pub(crate) fn parse_value(b: &[u8]) -> Result<(Expr, usize), SyntaxError> {
    let mut p = Parser { b, i: 0, nodes: 0 };
    if p.peek().is_some_and(|c| c == b' ' || c == b'\t') {
        return err(0, "a word's value must follow its letter");
    }
    let e = p.operand()?;
    Ok((e, p.i))
}

/// Parse a parameter setting `#ref = value` at the start of `b` (which starts with `#`).
pub(crate) fn parse_assignment(b: &[u8]) -> Result<(ParamRef, Expr, usize), SyntaxError> {
    let mut p = Parser { b, i: 0, nodes: 0 };
    if p.peek() != Some(b'#') {
        return err(0, "expected '#'");
    }
    p.i += 1;
    let r = p.param()?;
    p.skip_ws();
    if p.peek() != Some(b'=') {
        return err(p.i, "a parameter on its own is not a G-code word (expected '=' to set it)");
    }
    p.i += 1;
    let e = p.operand()?;
    Ok((r, e, p.i))
}

/// A parameter key: number or lower-case name without spaces.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) enum Key {
    Num(u32),
    Name(String),
}

impl std::fmt::Display for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Key::Num(n) => write!(f, "#{n}"),
            Key::Name(n) => write!(f, "#<{n}>"),
        }
    }
}

/// Parameter values set by the program so far.
#[derive(Debug, Default, Clone)]
pub(crate) struct Params {
    values: HashMap<Key, f64>,
}

impl Params {
    pub fn set(&mut self, k: Key, v: f64) {
        self.values.insert(k, v);
    }

    pub fn key(&self, r: &ParamRef) -> Result<Key, String> {
        match r {
            ParamRef::Name(n) => Ok(Key::Name(n.clone())),
            ParamRef::Num(e) => {
                let v = self.eval(e)?;
                let n = v.round();
                if (v - n).abs() > 1e-6 {
                    return Err(format!("parameter number {v} is not an integer"));
                }
                if !(1.0..=MAX_PARAMETER as f64).contains(&n) {
                    return Err(format!("parameter number {n} is outside 1..{MAX_PARAMETER}"));
                }
                Ok(Key::Num(n as u32))
            }
        }
    }

    fn get(&self, r: &ParamRef) -> Result<f64, String> {
        let k = self.key(r)?;
        match self.values.get(&k) {
            Some(v) => Ok(*v),
            None => match &k {
                // A local named parameter never set reads as an error in LinuxCNC too.
                Key::Name(n) if !n.starts_with('_') => Err(format!("parameter {k} is used before it is set")),
                _ => Err(format!(
                    "parameter {k} is not set earlier in the program; its value lives in the controller and \
                     truepos cannot know it (set it in the program, or write the number)"
                )),
            },
        }
    }

    /// Evaluate `e` with the current values.
    pub fn eval(&self, e: &Expr) -> Result<f64, String> {
        let v = match e {
            Expr::Num(v) => *v,
            Expr::Param(r) => self.get(r)?,
            Expr::Neg(a) => -self.eval(a)?,
            Expr::Exists(n) => {
                if n.starts_with('_') && !self.values.contains_key(&Key::Name(n.clone())) {
                    return Err(format!(
                        "EXISTS[#<{n}>]: a global parameter may be set by the controller; truepos cannot know"
                    ));
                }
                if self.values.contains_key(&Key::Name(n.clone())) {
                    1.0
                } else {
                    0.0
                }
            }
            Expr::Atan(y, x) => self.eval(y)?.atan2(self.eval(x)?).to_degrees(),
            Expr::Func(f, a) => {
                let x = self.eval(a)?;
                let dom =
                    |ok: bool, what: &str| if ok { Ok(()) } else { Err(format!("{what} (argument {x})")) };
                match f {
                    Func::Abs => x.abs(),
                    Func::Acos => {
                        dom((-1.0..=1.0).contains(&x), "ACOS of a value outside [-1, 1]")?;
                        x.acos().to_degrees()
                    }
                    Func::Asin => {
                        dom((-1.0..=1.0).contains(&x), "ASIN of a value outside [-1, 1]")?;
                        x.asin().to_degrees()
                    }
                    Func::Cos => x.to_radians().cos(),
                    Func::Exp => x.exp(),
                    Func::Fix => x.floor(),
                    Func::Fup => x.ceil(),
                    Func::Ln => {
                        dom(x > 0.0, "LN of a value that is not positive")?;
                        x.ln()
                    }
                    Func::Round => x.round(),
                    Func::Sin => x.to_radians().sin(),
                    Func::Sqrt => {
                        dom(x >= 0.0, "SQRT of a negative value")?;
                        x.sqrt()
                    }
                    Func::Tan => x.to_radians().tan(),
                }
            }
            Expr::Bin(op, a, b) => {
                let x = self.eval(a)?;
                let y = self.eval(b)?;
                let t = |c: bool| if c { 1.0 } else { 0.0 };
                match op {
                    Op::Pow => {
                        if x < 0.0 && y.fract() != 0.0 {
                            return Err(format!("{x} ** {y}: a negative base needs an integer exponent"));
                        }
                        x.powf(y)
                    }
                    Op::Mul => x * y,
                    Op::Div => {
                        if y == 0.0 {
                            return Err("division by zero".into());
                        }
                        x / y
                    }
                    Op::Mod => {
                        if y == 0.0 {
                            return Err("MOD by zero".into());
                        }
                        let m = x % y;
                        if m < 0.0 {
                            m + y.abs()
                        } else {
                            m
                        }
                    }
                    Op::Add => x + y,
                    Op::Sub => x - y,
                    Op::Eq => t(x == y),
                    Op::Ne => t(x != y),
                    Op::Gt => t(x > y),
                    Op::Ge => t(x >= y),
                    Op::Lt => t(x < y),
                    Op::Le => t(x <= y),
                    Op::And => t(x != 0.0 && y != 0.0),
                    Op::Or => t(x != 0.0 || y != 0.0),
                    Op::Xor => t((x != 0.0) != (y != 0.0)),
                }
            }
        };
        if v.is_finite() {
            Ok(v)
        } else {
            Err("the expression's value is not a finite number".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(s: &str, p: &Params) -> Result<f64, String> {
        let (e, n) = parse_value(s.as_bytes()).map_err(|e| e.message)?;
        assert_eq!(n, s.len(), "{s}");
        p.eval(&e)
    }

    fn set(p: &mut Params, s: &str) {
        let (r, e, n) = parse_assignment(s.as_bytes()).unwrap();
        assert_eq!(n, s.len());
        let v = p.eval(&e).unwrap();
        let k = p.key(&r).unwrap();
        p.set(k, v);
    }

    /// Values worked by hand from the LinuxCNC manual's rules.
    #[test]
    fn precedence_functions_and_parameters() {
        let mut p = Params::default();
        set(&mut p, "#1=2");
        set(&mut p, "#<Depth> = [#1 * 3]");
        set(&mut p, "#2=1");
        let cases = [
            ("[#1+2]", 4.0),
            ("#1", 2.0),
            ("##2", 2.0),
            ("#[1]", 2.0),
            ("#<depth>", 6.0),
            ("#<D e p t h>", 6.0),
            ("-#1", -2.0),
            ("[2+3*4]", 14.0),
            ("[2*3**2]", 18.0),
            ("[2**3**2]", 64.0), // left to right: (2**3)**2
            ("[10-4-3]", 3.0),
            ("[12/3/2]", 2.0),
            ("[-7 MOD 3]", 2.0),
            ("[7 mod 3]", 1.0),
            ("[1+1 EQ 2]", 1.0),
            ("[1 LT 2 AND 3 GT 4]", 0.0),
            ("[1 XOR 0]", 1.0),
            ("SIN[30]", 0.5),
            ("[COS[60]]", 0.5),
            ("ATAN[1]/[1]", 45.0),
            ("ATAN[1]/[-1]", 135.0),
            ("SQRT[16]", 4.0),
            ("FIX[-1.5]", -2.0),
            ("FUP[1.2]", 2.0),
            ("ROUND[2.5]", 3.0),
            ("ROUND[-2.5]", -3.0),
            ("ABS[-3]", 3.0),
            ("[EXISTS[#<depth>] + EXISTS[#<nope>]]", 1.0),
            ("[.5+1.]", 1.5),
        ];
        for (s, want) in cases {
            let v = ev(s, &p).unwrap_or_else(|e| panic!("{s}: {e}"));
            assert!((v - want).abs() < 1e-12, "{s} = {v}, want {want}");
        }
    }

    #[test]
    fn refusals() {
        let p = Params::default();
        for s in ["#100", "[SQRT[-1]]", "[1/0]", "#<_x>", "#<local>", "ASIN[2]", "[LN[0]]", "#0", "#[1.5]"] {
            assert!(ev(s, &p).is_err(), "{s}");
        }
        for s in ["[1", "[1e3]", "[1+]", "FOO[1]", "ATAN[1]", "#", "[1.2.3]", " 1"] {
            assert!(parse_value(s.as_bytes()).is_err(), "{s}");
        }
        assert!(parse_assignment(b"#1").is_err());
    }

    /// Long chains, deep brackets and long runs of signs are refused at the node limit with
    /// their place, before the tree grows deep enough to overflow a stack (10,000 terms did, in
    /// the reader thread, before the limit); expressions under the limit still evaluate.
    #[test]
    fn huge_expressions_are_refused_not_crashed() {
        let p = Params::default();
        let chain = |n: usize| format!("[{}1]", "1+".repeat(n - 1));
        assert_eq!(ev(&chain(500), &p), Ok(500.0)); // 1 + 500 + 499 = 1000 nodes
        assert_eq!(ev(&format!("{}1{}", "[".repeat(400), "]".repeat(400)), &p), Ok(1.0));
        for s in [
            chain(501),
            chain(10_000),
            chain(200_001),
            format!("{}1{}", "[".repeat(7000), "]".repeat(7000)),
            format!("[{}1]", "-".repeat(20_000)),
            format!("[{}]", "SIN[".repeat(5000) + "1" + &"]".repeat(5000)),
        ] {
            let e = parse_value(s.as_bytes()).unwrap_err();
            assert!(e.message.contains("more than 1000 values and operators"), "{}", e.message);
            assert!(e.at <= s.len());
        }
        let long = format!("#1=[{}1]", "1+".repeat(10_000));
        assert!(parse_assignment(long.as_bytes()).unwrap_err().message.contains("1000"));
    }
}

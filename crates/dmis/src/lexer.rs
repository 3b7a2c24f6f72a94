//! The lexical layer: DMIS text → statements of tokens ([`RawStatement`]), each token with its
//! line and column.
//!
//! Rules (DMIS 3.0–5.x, ISO 22093 clause 5):
//! - A statement ends at the end of its line unless the line ends with `$` (blanks may follow),
//!   which continues it on the next line. `$$` starts a comment running to the end of the line
//!   (anywhere outside text). A `$` elsewhere is an error.
//! - Blanks (spaces, tabs, carriage returns, form feeds) separate nothing and are ignored.
//! - Words are case-insensitive (`units/mm` is `UNITS/MM`); they are kept upper-case.
//! - Numbers: `50`, `50.`, `.5`, `-1.0`, `+1`, `1.5E-3`, `1e3`; a number must be finite.
//!   A number directly followed by letters is a word (`2D`, `3D`).
//! - Text is between apostrophes on one line; `''` is one apostrophe inside text.
//! - A word directly followed by `(` is a label: `F(A_CIRCLE)`, `DID(OUT1)`; the name runs to the
//!   next `)` on the line and may hold letters, digits, `_`, `-` and `.`.
//!
//! Entry point: [`statements`] (an iterator; the whole file is never tokenised at once).

use crate::error::{DmisError, ErrorKind, Pos};

/// One token's value.
#[derive(Debug, Clone, PartialEq)]
pub enum Tok {
    /// A word, upper-cased.
    Word(String),
    /// A number.
    Num(f64),
    /// A quoted text, without the quotes.
    Text(String),
    /// `PREFIX(name)`: prefix upper-cased, name as written.
    Label(String, String),
    /// `,`.
    Comma,
    /// `/`.
    Slash,
    /// `=`.
    Eq,
}

impl Tok {
    /// How the token is named in messages.
    pub fn describe(&self) -> String {
        match self {
            Tok::Word(w) => format!("the word {w}"),
            Tok::Num(v) => format!("the number {v}"),
            Tok::Text(_) => "a text".to_string(),
            Tok::Label(p, n) => format!("the label {p}({n})"),
            Tok::Comma => "','".to_string(),
            Tok::Slash => "'/'".to_string(),
            Tok::Eq => "'='".to_string(),
        }
    }
}

/// One statement's tokens, with where it starts and where it ends.
#[derive(Debug, Clone, PartialEq)]
pub struct RawStatement {
    /// The tokens with their positions.
    pub toks: Vec<(Tok, Pos)>,
    /// Position just after the statement's last token (for "expected … at the end").
    pub end: Pos,
}

/// The statements of `text`, in order; the first lexical error ends the iteration.
pub fn statements<'a>(file: &'a str, text: &'a str) -> Statements<'a> {
    Statements { file, text, offset: 0, line: 1, done: false }
}

/// Iterator over the statements of a text (see [`statements`]).
pub struct Statements<'a> {
    file: &'a str,
    text: &'a str,
    offset: usize,
    line: u32,
    done: bool,
}

impl Iterator for Statements<'_> {
    type Item = Result<RawStatement, DmisError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let mut toks: Vec<(Tok, Pos)> = Vec::new();
        let mut end = Pos::new(self.line, 1);
        loop {
            if self.offset >= self.text.len() {
                self.done = true;
                if toks.is_empty() {
                    return None;
                }
                return Some(Ok(RawStatement { toks, end }));
            }
            let rest = &self.text[self.offset..];
            let (line_text, advance) = match rest.find('\n') {
                Some(k) => (&rest[..k], k + 1),
                None => (rest, rest.len()),
            };
            let line_no = self.line;
            self.offset += advance;
            self.line = self.line.saturating_add(1);
            match lex_line(self.file, line_text, line_no, &mut toks) {
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
                Ok(LineEnd { continued, end: e }) => {
                    if let Some(e) = e {
                        end = e;
                    }
                    if continued {
                        continue;
                    }
                    if !toks.is_empty() {
                        return Some(Ok(RawStatement { toks, end }));
                    }
                }
            }
        }
    }
}

struct LineEnd {
    continued: bool,
    end: Option<Pos>,
}

fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.'
}

/// Lex one physical line, appending its tokens.
fn lex_line(file: &str, line: &str, line_no: u32, toks: &mut Vec<(Tok, Pos)>) -> Result<LineEnd, DmisError> {
    // Characters; a character's column is its index + 1.
    let mut lx = LineLexer { file, line_no, chars: line.chars().collect(), toks, end: None };
    let n = lx.chars.len();
    let mut i = 0;
    while i < n {
        i = match lx.chars[i] {
            ' ' | '\t' | '\r' | '\x0c' => i + 1,
            '$' => {
                if i + 1 < n && lx.chars[i + 1] == '$' {
                    break; // comment to the end of the line
                }
                if lx.chars[i + 1..].iter().all(|c| matches!(c, ' ' | '\t' | '\r' | '\x0c')) {
                    return Ok(LineEnd { continued: true, end: lx.end });
                }
                return Err(lx.err(
                    i + 1,
                    "a single '$' continues a statement only at the end of a line ('$$' starts a comment)"
                        .into(),
                ));
            }
            ',' => lx.push(Tok::Comma, i, i + 1),
            '/' => lx.push(Tok::Slash, i, i + 1),
            '=' => lx.push(Tok::Eq, i, i + 1),
            '\'' => lx.text(i)?,
            _ if lx.starts_number(i) => lx.number(i)?,
            c if c.is_ascii_alphabetic() => lx.word_or_label(i)?,
            other => return Err(lx.unexpected(i, other)),
        };
    }
    Ok(LineEnd { continued: false, end: lx.end })
}

/// One physical line being lexed: its characters, the statement's tokens so far and where the
/// line's last token ends.
struct LineLexer<'a> {
    file: &'a str,
    line_no: u32,
    chars: Vec<char>,
    toks: &'a mut Vec<(Tok, Pos)>,
    end: Option<Pos>,
}

impl LineLexer<'_> {
    /// The error for a character no DMIS token starts with, at index `i`: in a statement whose
    /// major word is outside the subset (`IF/(…)`), that is said instead, as the parser says it
    /// for the statement's other forms.
    fn unexpected(&self, i: usize, c: char) -> DmisError {
        let major = match self.toks.as_slice() {
            [(Tok::Label(..), _), (Tok::Eq, _), (Tok::Word(w), p), ..] | [(Tok::Word(w), p), ..] => {
                Some((w, *p))
            }
            _ => None,
        };
        match major {
            Some((w, p)) if crate::parse::OTHER_MAJORS.contains(&w.as_str()) => DmisError::new(
                self.file,
                p,
                ErrorKind::Unsupported,
                format!("{w} is outside the DMIS subset truepos runs (see docs/dmis.md)"),
            ),
            _ => self.err(i + 1, format!("unexpected character {c:?}")),
        }
    }

    /// A syntax error at 1-based column `col` of this line.
    fn err(&self, col: usize, msg: String) -> DmisError {
        DmisError::new(self.file, Pos::new(self.line_no, col as u32), ErrorKind::Syntax, msg)
    }

    /// Appends `t`, which starts at index `i` and ends before index `next`; returns `next`.
    fn push(&mut self, t: Tok, i: usize, next: usize) -> usize {
        self.toks.push((t, Pos::new(self.line_no, (i + 1) as u32)));
        self.end = Some(Pos::new(self.line_no, (next + 1) as u32));
        next
    }

    /// Text between apostrophes starting at index `i` (`''` is one apostrophe).
    fn text(&mut self, i: usize) -> Result<usize, DmisError> {
        let (chars, n) = (&self.chars, self.chars.len());
        let mut s = String::new();
        let mut j = i + 1;
        loop {
            if j >= n {
                return Err(self.err(i + 1, "text without its closing apostrophe on this line".into()));
            }
            if chars[j] == '\'' {
                if j + 1 < n && chars[j + 1] == '\'' {
                    s.push('\'');
                    j += 2;
                    continue;
                }
                break;
            }
            s.push(chars[j]);
            j += 1;
        }
        Ok(self.push(Tok::Text(s), i, j + 1))
    }

    /// Whether a number starts at index `i`: a digit, a `.`, or a sign before a digit or `.digit`.
    fn starts_number(&self, i: usize) -> bool {
        let (chars, n, c) = (&self.chars, self.chars.len(), self.chars[i]);
        c.is_ascii_digit()
            || c == '.'
            || ((c == '+' || c == '-')
                && i + 1 < n
                && (chars[i + 1].is_ascii_digit()
                    || (chars[i + 1] == '.' && i + 2 < n && chars[i + 2].is_ascii_digit())))
    }

    /// The number starting at index `i`, or the word when letters follow its digits (`2D`).
    fn number(&mut self, i: usize) -> Result<usize, DmisError> {
        let (chars, n, col) = (&self.chars, self.chars.len(), i + 1);
        let mut j = i;
        if chars[j] == '+' || chars[j] == '-' {
            j += 1;
        }
        let mut digits = 0;
        while j < n && chars[j].is_ascii_digit() {
            j += 1;
            digits += 1;
        }
        if j < n && chars[j] == '.' {
            j += 1;
            while j < n && chars[j].is_ascii_digit() {
                j += 1;
                digits += 1;
            }
        }
        if digits == 0 {
            return Err(self.err(col, format!("'{}' is not a number", chars[i])));
        }
        if j < n && (chars[j] == 'e' || chars[j] == 'E') {
            let mut k = j + 1;
            if k < n && (chars[k] == '+' || chars[k] == '-') {
                k += 1;
            }
            if k < n && chars[k].is_ascii_digit() {
                while k < n && chars[k].is_ascii_digit() {
                    k += 1;
                }
                j = k;
            }
        }
        if j < n && (chars[j].is_ascii_alphabetic() || chars[j] == '_') {
            // `2D`, `3D`: a word that starts with digits.
            if chars[i] == '+' || chars[i] == '-' {
                return Err(self.err(col, "a sign before a word".into()));
            }
            let mut k = j;
            while k < n && (chars[k].is_ascii_alphanumeric() || chars[k] == '_') {
                k += 1;
            }
            let w: String = chars[i..k].iter().collect::<String>().to_ascii_uppercase();
            Ok(self.push(Tok::Word(w), i, k))
        } else {
            let s: String = chars[i..j].iter().collect();
            let v: f64 = s.parse().map_err(|_| self.err(col, format!("{s:?} is not a number")))?;
            if !v.is_finite() {
                return Err(self.err(col, format!("the number {s} is out of range")));
            }
            Ok(self.push(Tok::Num(v), i, j))
        }
    }

    /// The word starting at index `i`, or the label `WORD(name)` when `(` follows it.
    fn word_or_label(&mut self, i: usize) -> Result<usize, DmisError> {
        let (chars, n) = (&self.chars, self.chars.len());
        let mut j = i;
        while j < n && (chars[j].is_ascii_alphanumeric() || chars[j] == '_') {
            j += 1;
        }
        let w: String = chars[i..j].iter().collect::<String>().to_ascii_uppercase();
        if !(j < n && chars[j] == '(') {
            return Ok(self.push(Tok::Word(w), i, j));
        }
        let mut k = j + 1;
        while k < n && chars[k] != ')' {
            if !is_name_char(chars[k]) {
                return Err(self.err(
                    k + 1,
                    format!("{:?} cannot be part of a label name (letters, digits, '_', '-', '.')", chars[k]),
                ));
            }
            k += 1;
        }
        if k >= n {
            return Err(self.err(j + 1, format!("the label {w}( has no closing ')' on this line")));
        }
        if k == j + 1 {
            return Err(self.err(j + 2, format!("the label {w}() has no name")));
        }
        let name: String = chars[j + 1..k].iter().collect();
        Ok(self.push(Tok::Label(w, name), i, k + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lex(t: &str) -> Vec<Vec<Tok>> {
        statements("t.dms", t).map(|s| s.unwrap().toks.into_iter().map(|(t, _)| t).collect()).collect()
    }

    #[test]
    fn numbers_in_every_form() {
        let s = lex("GOTO/50, 50., .5, -1.0, +1, 1.5E-3, 1e3, -.25, 2D\n");
        assert_eq!(
            s[0],
            vec![
                Tok::Word("GOTO".into()),
                Tok::Slash,
                Tok::Num(50.0),
                Tok::Comma,
                Tok::Num(50.0),
                Tok::Comma,
                Tok::Num(0.5),
                Tok::Comma,
                Tok::Num(-1.0),
                Tok::Comma,
                Tok::Num(1.0),
                Tok::Comma,
                Tok::Num(1.5e-3),
                Tok::Comma,
                Tok::Num(1e3),
                Tok::Comma,
                Tok::Num(-0.25),
                Tok::Comma,
                Tok::Word("2D".into()),
            ]
        );
    }

    #[test]
    fn continuations_comments_and_case() {
        let s = lex("$$ comment\n\nf(c1) = feat/circle, $  \n  inner $$ not a continuation? no: comment\n");
        // The `$` continues; the comment line after `inner` ends the statement.
        assert_eq!(s.len(), 1);
        assert_eq!(s[0][0], Tok::Label("F".into(), "c1".into()));
        assert_eq!(s[0].last().unwrap(), &Tok::Word("INNER".into()));
    }

    #[test]
    fn text_with_apostrophes() {
        let s = lex("TEXT/OPER,'it''s $$ here'\n");
        assert_eq!(s[0][4], Tok::Text("it's $$ here".into()));
    }

    #[test]
    fn errors_are_located() {
        let e = statements("p.dms", "UNITS/MM\nTEXT/OPER,'open\n").nth(1).unwrap().unwrap_err();
        assert_eq!((e.pos.line, e.pos.col), (2, 11));
        let e = statements("p.dms", "GOTO/1,2 $ 3\n").next().unwrap().unwrap_err();
        assert_eq!((e.pos.line, e.pos.col), (1, 10));
        let e = statements("p.dms", "GOTO/1,2,3#\n").next().unwrap().unwrap_err();
        assert_eq!((e.pos.line, e.pos.col), (1, 11));
        let e = statements("p.dms", "GOTO/1e999,2,3\n").next().unwrap().unwrap_err();
        assert_eq!((e.pos.line, e.pos.col), (1, 6));
        let e = statements("p.dms", "F(A B)=FEAT/POINT\n").next().unwrap().unwrap_err();
        assert_eq!((e.pos.line, e.pos.col), (1, 4));
    }
}

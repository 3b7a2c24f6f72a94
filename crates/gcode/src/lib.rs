//! # truepos-gcode — lossless RS-274 / ISO 6983 G-code
//!
//! Parses a program into tokens that keep their original text (words, both comment styles,
//! line numbers, `%` and `O` lines, blank lines, spacing, line endings), so that printing a
//! parsed program gives back the input byte for byte: `parse(s).to_string() == s` for any input.
//! Interprets the modal state (G90/G91, G20/G21, G17/G18/G19, G90.1/G91.1, motion mode, current
//! position) and rewrites coordinates through a similarity transform, touching only the words
//! that change.
//!
//! Entry points:
//! - [`Program::parse`], `Program::to_string` (lossless, through `Display`), [`Program::check`] (malformed numbers
//!   with line and column).
//! - [`Program::blocks`]: the interpreted blocks (line, commanded position in mm, comments), as a
//!   controller would execute them — used for trickle feeding.
//! - [`Program::transform`]: rewrite the program through `new_from_old` (mm).
//! - [`transform_stream`] / [`StreamTransform`]: the same rewrite of a program of any size in
//!   constant memory, chunk by chunk (modal state and parameters carried across chunks), read
//!   from a `BufRead` and written to a `Write`, byte-identical to [`Program::transform`].

#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]

mod expr;
mod interp;
mod lex;
mod rewrite;
mod stream;

pub use interp::{Block, Modal, MotionMode, Plane, Units};
pub use lex::{Token, TokenKind};
pub use rewrite::{ArcPolicy, TransformOptions};
pub use stream::{transform_stream, StreamError, StreamSummary, StreamTransform, PIECE_BYTES};

use thiserror::Error;

/// Errors with the 1-based line and column of the offending token.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GcodeError {
    /// A word's number is malformed (1-based line and column, and the text).
    #[error("line {line}, column {column}: malformed number '{text}' (a word needs a finite decimal number or a [expression])")]
    MalformedNumber {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The malformed text.
        text: String,
    },
    /// Valid G-code this crate does not handle (1-based line and column, and why).
    #[error("line {line}, column {column}: {message}")]
    Unsupported {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is not supported.
        message: String,
    },
}

impl GcodeError {
    /// 1-based line of the offending token.
    pub fn line(&self) -> usize {
        match self {
            GcodeError::MalformedNumber { line, .. } | GcodeError::Unsupported { line, .. } => *line,
        }
    }
    /// The message without the location (for callers that add file, line and column).
    pub fn detail(&self) -> String {
        match self {
            GcodeError::MalformedNumber { text, .. } => {
                format!("malformed number '{text}' (a word needs a finite decimal number or a [expression])")
            }
            GcodeError::Unsupported { message, .. } => message.clone(),
        }
    }
    /// 1-based column (character) of the offending token.
    pub fn column(&self) -> usize {
        match self {
            GcodeError::MalformedNumber { column, .. } | GcodeError::Unsupported { column, .. } => *column,
        }
    }
    /// The same error `lines` further down (for a piece of a program that follows `lines` lines).
    pub(crate) fn shifted(mut self, lines: usize) -> Self {
        match &mut self {
            GcodeError::MalformedNumber { line, .. } | GcodeError::Unsupported { line, .. } => *line += lines,
        }
        self
    }
}

/// One source line: its tokens and its line ending.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Byte offset of the line's first byte in the source.
    pub start: usize,
    /// Byte offset just past the line's content (before the line ending) in the source.
    pub end: usize,
    /// Byte offset just past the line ending (`\n`, `\r\n`, or nothing on the last line).
    pub next: usize,
    /// Range into [`Program::tokens`].
    pub tokens: std::ops::Range<usize>,
}

/// A parsed program: the source text plus token and line indices into it.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// The program's text, as read.
    pub source: String,
    /// Every token of the program, in order.
    pub tokens: Vec<Token>,
    /// Every line of the program, in order, with its range of tokens.
    pub lines: Vec<Line>,
}

/// At most the first 40 characters of a token's text, for a message (a token may be a whole
/// line of a megabyte).
fn clip(text: &str) -> &str {
    text.char_indices().nth(40).map_or(text, |(i, _)| &text[..i])
}

impl Program {
    /// Tokenise `source`. Never fails: unknown or malformed text becomes tokens that are kept
    /// verbatim (see [`Program::check`] for malformed numbers).
    pub fn parse(source: &str) -> Program {
        let mut p = lex::parse(source.to_string());
        if p.tokens.iter().any(|t| matches!(t.kind, TokenKind::Expr { .. })) {
            let (values, _) = p.evaluate(&mut expr::Params::default(), true);
            p.set_values(values);
        }
        p
    }

    /// Tokenise the next piece of a program (complete lines) and evaluate it with the
    /// parameters set by the pieces before it (`params`, updated). `first` says whether this is
    /// the program's first piece (where a byte-order mark may stand). The check's result has
    /// line numbers relative to the piece.
    pub(crate) fn parse_piece(
        source: String,
        params: &mut expr::Params,
        first: bool,
        reuse: Option<Program>,
    ) -> (Program, Result<(), GcodeError>) {
        let (old_tokens, old_lines) = reuse.map(|old| (old.tokens, old.lines)).unwrap_or_default();
        let (mut p, plain) = lex::parse_reusing(source, old_tokens, old_lines);
        if plain {
            // Nothing to evaluate, nothing that can fail the check (see `lex::is_plain`).
            return (p, Ok(()));
        }
        let (values, checked) = p.evaluate(params, first);
        p.set_values(values);
        (p, checked)
    }

    fn set_values(&mut self, values: Vec<(usize, f64)>) {
        for (ti, v) in values {
            if let TokenKind::Expr { letter, .. } = self.tokens[ti].kind {
                self.tokens[ti].kind = TokenKind::Expr { letter, value: Some(v) };
            }
        }
    }

    /// The text of a token.
    pub fn text(&self, t: &Token) -> &str {
        &self.source[t.start..t.end]
    }

    /// The tokens of line `i` (0-based).
    pub fn line_tokens(&self, i: usize) -> &[Token] {
        &self.tokens[self.lines[i].tokens.clone()]
    }

    /// The content of line `i` without its line ending.
    pub fn line_text(&self, i: usize) -> &str {
        let l = &self.lines[i];
        &self.source[l.start..l.end]
    }

    /// The first thing in the program that truepos cannot execute exactly, with its line and
    /// column: a malformed number (`X`, `Xabc`, `XNaN`, `X1,5`, `X1e999`), an expression that
    /// cannot be evaluated (a parameter not set earlier in the program, a domain error), O-word
    /// control flow, an unclosed comment, or text that is not G-code. Passing this check means
    /// every word's value is known.
    pub fn check(&self) -> Result<(), GcodeError> {
        self.evaluate(&mut expr::Params::default(), true).1
    }

    /// The first carriage return followed by more text on its line: the lines end in a
    /// carriage return alone (classic Mac OS), so the whole program would read as one block
    /// (its words repeated, the last of each taken). A CR before the line's LF (CRLF, or
    /// `\r\r\n`) is only a line end.
    fn bare_carriage_return(&self) -> Option<GcodeError> {
        let (line, column) = truepos_math::text::bare_carriage_return(&self.source)?;
        Some(GcodeError::Unsupported {
            line,
            column,
            message: "CR-only line ends: the lines end in a carriage return alone (classic Mac OS), so the program reads as one line; convert them to LF or CRLF line ends (e.g. tr '\\r' '\\n' < in.nc > out.nc)".into(),
        })
    }

    /// Evaluate parameters and expressions in program order (see the `expr` module), starting
    /// from `params` (the settings of earlier pieces; updated): the values of expression words
    /// (token index, value) up to the first error, and that error. `first`: this text starts
    /// the program (a byte-order mark may open it).
    fn evaluate(
        &self,
        params: &mut expr::Params,
        first: bool,
    ) -> (Vec<(usize, f64)>, Result<(), GcodeError>) {
        const FLOW: [&str; 15] = [
            "sub",
            "endsub",
            "call",
            "do",
            "while",
            "endwhile",
            "if",
            "elseif",
            "else",
            "endif",
            "break",
            "continue",
            "repeat",
            "endrepeat",
            "return",
        ];
        // Reported at its line, in program order (a streamed piece and the whole program then
        // stop at the same first error).
        let mut bare_cr = self.bare_carriage_return();
        let mut values = Vec::new();
        for (i, l) in self.lines.iter().enumerate() {
            if bare_cr.as_ref().is_some_and(|e| e.line() == i + 1) {
                let e = bare_cr.take().map_or(Ok(()), Err);
                return (values, e);
            }
            let mut pending: Vec<(expr::Key, f64)> = Vec::new();
            let mut has_o = false;
            for ti in l.tokens.clone() {
                let t = &self.tokens[ti];
                // The common tokens need nothing (not even their text).
                match t.kind {
                    TokenKind::Word { letter, .. } if letter != b'O' => continue,
                    TokenKind::Whitespace
                    | TokenKind::ParenComment { closed: true }
                    | TokenKind::SemicolonComment
                    | TokenKind::Percent => continue,
                    _ => {}
                }
                let text = self.text(t);
                // Only computed for an error: counting characters on every token is slow.
                let column = || self.source[l.start..t.start].chars().count() + 1;
                let unsupported = |message: String| -> GcodeError {
                    GcodeError::Unsupported { line: i + 1, column: column(), message }
                };
                let res: Result<(), GcodeError> = match t.kind {
                    TokenKind::Word { letter: b'O', .. } => {
                        has_o = true;
                        Ok(())
                    }
                    TokenKind::Malformed { letter } => {
                        let lower = text.to_ascii_lowercase();
                        if (letter == b'O' && text[1..].starts_with('<'))
                            || (has_o && FLOW.contains(&lower.as_str()))
                        {
                            Err(unsupported(format!(
                                "O-word subroutines and control flow ('{text}') are not supported: truepos \
                                 follows a program line by line and cannot know which lines run how often"
                            )))
                        } else if let Some(e) = text
                            .get(1..)
                            .filter(|v| v.starts_with('['))
                            .and_then(|v| expr::parse_value(v.as_bytes()).err())
                            .filter(|e| e.message.contains("values and operators"))
                        {
                            // An expression beyond the size truepos reads: say so (and do not
                            // quote all of it).
                            Err(unsupported(format!("'{}…': {}", clip(text), e.message)))
                        } else {
                            Err(GcodeError::MalformedNumber {
                                line: i + 1,
                                column: column(),
                                text: text.to_string(),
                            })
                        }
                    }
                    TokenKind::ParenComment { closed: false } => {
                        Err(unsupported("comment '(' is not closed on this line".into()))
                    }
                    TokenKind::Other => {
                        let block_delete = text == "/"
                            && self.tokens[l.tokens.start..ti]
                                .iter()
                                .all(|x| x.kind == TokenKind::Whitespace);
                        let bom = first && t.start == 0 && text == "\u{feff}";
                        if block_delete || bom {
                            Ok(())
                        } else if let Some(e) = Some(text)
                            .filter(|t| t.starts_with('#'))
                            .and_then(|t| expr::parse_assignment(t.as_bytes()).err())
                            .filter(|e| e.message.contains("values and operators"))
                        {
                            Err(unsupported(format!("'{}…': {}", clip(text), e.message)))
                        } else {
                            Err(unsupported(format!(
                                "'{}' is not G-code (expected words such as G1 or X10.5)",
                                clip(text)
                            )))
                        }
                    }
                    TokenKind::Expr { .. } => match expr::parse_value(&text.as_bytes()[1..]) {
                        Ok((e, _)) => match params.eval(&e) {
                            Ok(v) => {
                                values.push((ti, v));
                                Ok(())
                            }
                            Err(m) => Err(unsupported(format!("cannot evaluate '{text}': {m}"))),
                        },
                        Err(e) => Err(unsupported(format!("'{text}': {}", e.message))),
                    },
                    TokenKind::Assign => match expr::parse_assignment(text.as_bytes()) {
                        Ok((r, e, _)) => match params.key(&r).and_then(|k| params.eval(&e).map(|v| (k, v))) {
                            Ok(kv) => {
                                pending.push(kv);
                                Ok(())
                            }
                            Err(m) => Err(unsupported(format!("cannot evaluate '{text}': {m}"))),
                        },
                        Err(e) => Err(unsupported(format!("'{text}': {}", e.message))),
                    },
                    _ => Ok(()),
                };
                if let Err(e) = res {
                    return (values, Err(e));
                }
            }
            // Settings take effect after every value on the line has been read.
            for (k, v) in pending {
                params.set(k, v);
            }
        }
        (values, Ok(()))
    }

    /// 1-based column of a token on line `i`.
    pub fn column_of(&self, i: usize, t: &Token) -> usize {
        self.source[self.lines[i].start..t.start].chars().count() + 1
    }
}

impl std::fmt::Display for Program {
    /// Prints the program from its tokens and line endings (which tile the source exactly).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for l in &self.lines {
            for t in &self.tokens[l.tokens.clone()] {
                f.write_str(&self.source[t.start..t.end])?;
            }
            f.write_str(&self.source[l.end..l.next])?;
        }
        Ok(())
    }
}

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
//! - [`Program::parse`], [`Program::to_string`] (lossless), [`Program::check`] (malformed numbers
//!   with line and column).
//! - [`Program::blocks`]: the interpreted blocks (line, commanded position in mm, comments), as a
//!   controller would execute them — used for trickle feeding.
//! - [`Program::transform`]: rewrite the program through `new_from_old` (mm).

mod interp;
mod lex;
mod rewrite;

pub use interp::{Block, Modal, MotionMode, Plane, Units};
pub use lex::{Token, TokenKind};
pub use rewrite::{ArcPolicy, TransformOptions};

use thiserror::Error;

/// Errors with the 1-based line and column of the offending token.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GcodeError {
    #[error("line {line}, column {column}: malformed number '{text}'")]
    MalformedNumber { line: usize, column: usize, text: String },
    #[error("line {line}, column {column}: {message}")]
    Unsupported { line: usize, column: usize, message: String },
}

impl GcodeError {
    pub fn line(&self) -> usize {
        match self {
            GcodeError::MalformedNumber { line, .. } | GcodeError::Unsupported { line, .. } => *line,
        }
    }
    /// The message without the location (for callers that add file, line and column).
    pub fn detail(&self) -> String {
        match self {
            GcodeError::MalformedNumber { text, .. } => format!("malformed number '{text}'"),
            GcodeError::Unsupported { message, .. } => message.clone(),
        }
    }
    pub fn column(&self) -> usize {
        match self {
            GcodeError::MalformedNumber { column, .. } | GcodeError::Unsupported { column, .. } => *column,
        }
    }
}

/// One source line: its tokens and its line ending.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Byte range of the line's content (without the line ending) in the source.
    pub start: usize,
    pub end: usize,
    /// Byte offset just past the line ending (`\n`, `\r\n`, or nothing on the last line).
    pub next: usize,
    /// Range into [`Program::tokens`].
    pub tokens: std::ops::Range<usize>,
}

/// A parsed program: the source text plus token and line indices into it.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    pub source: String,
    pub tokens: Vec<Token>,
    pub lines: Vec<Line>,
}

impl Program {
    /// Tokenise `source`. Never fails: unknown or malformed text becomes tokens that are kept
    /// verbatim (see [`Program::check`] for malformed numbers).
    pub fn parse(source: &str) -> Program {
        lex::parse(source)
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

    /// First malformed number, with its line and column.
    pub fn check(&self) -> Result<(), GcodeError> {
        for (i, l) in self.lines.iter().enumerate() {
            for t in &self.tokens[l.tokens.clone()] {
                if let TokenKind::Malformed { .. } = t.kind {
                    return Err(GcodeError::MalformedNumber {
                        line: i + 1,
                        column: self.source[l.start..t.start].chars().count() + 1,
                        text: self.text(t).to_string(),
                    });
                }
            }
        }
        Ok(())
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

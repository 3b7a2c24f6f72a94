//! The one error type of the crate: every problem in a program names its file, line and column.

use thiserror::Error;

/// A position in a program: 1-based line and column (columns count characters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub struct Pos {
    /// 1-based line.
    pub line: u32,
    /// 1-based column, in characters.
    pub col: u32,
}

impl Pos {
    /// The position at 1-based `line` and `col`.
    pub fn new(line: u32, col: u32) -> Pos {
        Pos { line, col }
    }
}

impl std::fmt::Display for Pos {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

/// What kind of problem a [`DmisError`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Not DMIS: bad characters, unterminated text, a statement that does not follow the grammar.
    Syntax,
    /// Valid DMIS, but outside the subset truepos runs (named in `docs/dmis.md`).
    Unsupported,
    /// A well-formed statement that makes no sense where it stands (undefined label, feature not
    /// measured, PTMEAS outside MEAS, …).
    Semantic,
}

/// A located problem in a DMIS program (exit code 2 in the binary).
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{file}:{line}:{col}: {message}", line = pos.line, col = pos.col)]
pub struct DmisError {
    /// The program's file name, as reported.
    pub file: String,
    /// Where the problem is.
    pub pos: Pos,
    /// What kind of problem it is.
    pub kind: ErrorKind,
    /// What is wrong, as a sentence.
    pub message: String,
}

impl DmisError {
    /// An error of `kind` at `pos` in `file`.
    pub fn new(file: &str, pos: Pos, kind: ErrorKind, message: impl Into<String>) -> DmisError {
        DmisError { file: file.to_string(), pos, kind, message: message.into() }
    }
}

impl truepos_math::exit::HasExitClass for DmisError {
    /// A program that does not parse or check (exit 2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Input
    }
}

//! [`InputError`]: bad user input, located as precisely as possible.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with user input: a file that cannot be read, a malformed value, data that cannot
/// support the requested computation. Displayed as `file:line:column: message` (line and column
/// when known). The binary exits with code 2 on it.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    /// The file the problem is in, when there is one.
    pub file: Option<PathBuf>,
    /// 1-based line number in the file.
    pub line: Option<usize>,
    /// 1-based column number (field index for CSV).
    pub column: Option<usize>,
    /// Column name for CSV files.
    pub column_name: Option<String>,
    /// What is wrong, as a sentence for the user.
    pub message: String,
}

impl InputError {
    /// An error not tied to a file (e.g. about a command-line value).
    pub fn new(message: impl Into<String>) -> Self {
        Self { file: None, line: None, column: None, column_name: None, message: message.into() }
    }
    /// An error about a whole file (no line or column).
    pub fn in_file(file: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Self { file: Some(file.as_ref().to_path_buf()), ..Self::new(message) }
    }
    /// An error at a 1-based `line` (and optional 1-based `column`) of a file.
    pub fn at(
        file: impl AsRef<Path>,
        line: usize,
        column: Option<usize>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            file: Some(file.as_ref().to_path_buf()),
            line: Some(line),
            column,
            column_name: None,
            message: message.into(),
        }
    }
    /// The same error naming the CSV column it is in.
    pub fn with_column_name(mut self, name: impl Into<String>) -> Self {
        self.column_name = Some(name.into());
        self
    }
    /// The same error in `file`, unless it already names a file.
    pub fn with_file(mut self, file: impl AsRef<Path>) -> Self {
        if self.file.is_none() {
            self.file = Some(file.as_ref().to_path_buf());
        }
        self
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}", file.display())?;
            if let Some(line) = self.line {
                write!(f, ":{line}")?;
                if let Some(col) = self.column {
                    write!(f, ":{col}")?;
                }
            }
            write!(f, ": ")?;
        }
        if let Some(name) = &self.column_name {
            write!(f, "column '{name}': ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for InputError {}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn display_names_file_line_column() {
        let e = InputError::at("a.csv", 7, Some(3), "not a number: 'x'").with_column_name("z_mm");
        assert_eq!(e.to_string(), "a.csv:7:3: column 'z_mm': not a number: 'x'");
        assert_eq!(InputError::in_file("b.ds", "empty file").to_string(), "b.ds: empty file");
    }
}

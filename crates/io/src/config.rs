//! TOML configuration files into serde types, with line and column in errors.

use crate::InputError;
use serde::de::DeserializeOwned;
use std::path::Path;

/// Read and deserialize a TOML file. Syntax and type errors name the line and column.
pub fn read_toml<T: DeserializeOwned>(path: impl AsRef<Path>) -> Result<T, InputError> {
    let path = path.as_ref();
    let text = crate::limits::read_string(path, "TOML")?;
    parse_toml(path, &text)
}

/// Deserialize TOML text that came from `path` (used for error messages only).
pub fn parse_toml<T: DeserializeOwned>(path: impl AsRef<Path>, text: &str) -> Result<T, InputError> {
    let path = path.as_ref();
    toml::from_str(text).map_err(|e| {
        let msg = e.message().to_string();
        match e.span() {
            Some(span) => {
                let (line, col) = line_col(text, span.start);
                InputError::at(path, line, Some(col), msg)
            }
            None => InputError::in_file(path, msg),
        }
    })
}

/// 1-based line and column of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let col = offset - before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1) + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[derive(serde::Deserialize, Debug)]
    #[allow(dead_code)]
    struct C {
        a: f64,
    }
    #[test]
    fn type_error_has_line_and_column() {
        let e = parse_toml::<C>("c.toml", "# x\na = \"text\"\n").unwrap_err();
        assert_eq!(e.line, Some(2));
        assert_eq!(e.column, Some(5));
        assert!(e.to_string().starts_with("c.toml:2:5:"), "{e}");
    }
}

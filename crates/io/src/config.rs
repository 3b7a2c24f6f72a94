//! TOML configuration files into serde types, with line and column in errors.
//!
//! Entry points: [`read_toml`] / [`parse_toml`] (syntax and type errors located), and
//! [`read_toml_doc`] which also returns a [`TomlDoc`]: the file's text, so that a value found
//! wrong after deserialization (a negative thickness, a point off the bed) is reported at the line
//! and column of that value ([`TomlDoc::error_at`]).

use crate::InputError;
use serde::de::DeserializeOwned;
use std::path::Path;

/// Read and deserialize a TOML file. Syntax and type errors name the line and column.
pub fn read_toml<T: DeserializeOwned>(path: impl AsRef<Path>) -> Result<T, InputError> {
    let path = path.as_ref();
    let text = crate::limits::read_config_string(path, "TOML")?;
    parse_toml(path, &text)
}

/// Deserialize TOML text that came from `path` (used for error messages only).
pub fn parse_toml<T: DeserializeOwned>(path: impl AsRef<Path>, text: &str) -> Result<T, InputError> {
    let path = path.as_ref();
    toml::from_str(text).map_err(|e| {
        // CR-only line ends make the file one line, whatever the parser then says about it.
        if let Some((line, col)) = crate::limits::bare_carriage_return(text) {
            return InputError::at(path, line, Some(col), crate::limits::CR_ONLY);
        }
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

/// Read a TOML file and keep its text for located errors on values ([`TomlDoc::error_at`]).
pub fn read_toml_doc<T: DeserializeOwned>(path: impl AsRef<Path>) -> Result<(T, TomlDoc), InputError> {
    let path = path.as_ref();
    let text = crate::limits::read_config_string(path, "TOML")?;
    let value = parse_toml(path, &text)?;
    Ok((value, TomlDoc { path: path.to_path_buf(), text }))
}

/// A TOML file's path and text: locates a value by its key path for error messages.
#[derive(Clone, Debug)]
pub struct TomlDoc {
    /// The file's path, as given (named in error messages).
    pub path: std::path::PathBuf,
    /// The file's whole text.
    pub text: String,
}

impl TomlDoc {
    /// Line and column of the value at `keys` (table names, then the key; a number indexes an
    /// array, `[[rest]]` entries included: `["rest", "2", "force_n"]`). When the value is not
    /// there, the deepest table or array on the path that is; `None` when not even the first
    /// key is.
    pub fn locate(&self, keys: &[&str]) -> Option<(usize, usize)> {
        use toml::de::{DeTable, DeValue};
        let doc = DeTable::parse(&self.text).ok()?;
        let mut table: &DeTable = doc.get_ref();
        let mut found: Option<std::ops::Range<usize>> = None;
        let mut value: Option<&toml::Spanned<DeValue>> = None;
        for k in keys {
            let next = match value.map(|v| v.get_ref()) {
                None => table.get(*k),
                Some(DeValue::Table(t)) => {
                    table = t;
                    table.get(*k)
                }
                Some(DeValue::Array(a)) => k.parse::<usize>().ok().and_then(|i| a.get(i)),
                Some(_) => None,
            };
            match next {
                Some(v) => {
                    found = Some(v.span());
                    value = Some(v);
                }
                None => break,
            }
        }
        found.map(|span| line_col(&self.text, span.start))
    }

    /// An input error at the value of `keys` (see [`locate`](Self::locate)), else naming only
    /// the file. The message should name the key: `"[bed] thickness_mm = -5: must be positive"`.
    pub fn error_at(&self, keys: &[&str], message: impl Into<String>) -> InputError {
        match self.locate(keys) {
            Some((line, col)) => InputError::at(&self.path, line, Some(col), message),
            None => InputError::in_file(&self.path, message),
        }
    }

    /// Give `e` (an error of this file without a line) the line and column of the key its
    /// message starts with: `[air] pressure_pa …`, `[[tracker]] 1 yaw_deg …` (0-based entry),
    /// `error_scale …`; errors already located, or naming no key of the file, are returned as
    /// they are.
    pub fn locate_error(&self, mut e: InputError) -> InputError {
        if e.line.is_some() {
            return e;
        }
        let keys = message_keys(&e.message);
        let keys: Vec<&str> = keys.iter().map(String::as_str).collect();
        if keys.is_empty() {
            return e;
        }
        if let Some((line, col)) = self.locate(&keys) {
            e.line = Some(line);
            e.column = Some(col);
            e.file.get_or_insert_with(|| self.path.clone());
        }
        e
    }

    /// `Ok` when `value` (the one at `keys`) is finite and > 0, else the located error
    /// `"<name> = <value>: must be positive"`.
    pub fn positive(&self, keys: &[&str], value: f64) -> Result<(), InputError> {
        if value.is_finite() && value > 0.0 {
            return Ok(());
        }
        Err(self.error_at(keys, format!("{} = {value}: must be positive", key_name(keys))))
    }

    /// `Ok` when `value` is finite and ≥ 0, else the located error.
    pub fn non_negative(&self, keys: &[&str], value: f64) -> Result<(), InputError> {
        if value.is_finite() && value >= 0.0 {
            return Ok(());
        }
        Err(self.error_at(keys, format!("{} = {value}: must be zero or positive", key_name(keys))))
    }
}

/// The key path a message starts with (see [`TomlDoc::locate_error`]).
fn message_keys(message: &str) -> Vec<String> {
    let is_key = |w: &str| !w.is_empty() && w.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
    let mut words = message.split_whitespace();
    let Some(first) = words.next() else {
        return Vec::new();
    };
    let mut keys: Vec<String> = Vec::new();
    if let Some(t) = first.strip_prefix("[[").and_then(|t| t.strip_suffix("]]")) {
        keys.extend(t.split('.').map(String::from));
        if let Some(i) = words.next().filter(|w| w.parse::<usize>().is_ok()) {
            keys.push(i.to_string());
            if let Some(k) = words.next().filter(|w| is_key(w)) {
                keys.push(k.to_string());
            }
        }
    } else if let Some(t) = first.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
        keys.extend(t.split('.').map(String::from));
        if let Some(k) = words.next().map(|w| w.trim_end_matches([':', ','])).filter(|w| is_key(w)) {
            keys.push(k.to_string());
        }
    } else {
        // `error_scale …` or a dotted `servo.bandwidth_hz …` (a plain word is prose, not a key).
        let k = first.trim_end_matches([':', ',']);
        if k.split('.').all(is_key) && k.contains(['_', '.']) {
            keys.extend(k.split('.').map(String::from));
        }
    }
    keys
}

/// `[bed] thickness_mm` for `["bed", "thickness_mm"]`, `[[rest]] 3 force_n` for an array entry
/// (1-based), `mass_kg` for a top-level key.
pub fn key_name(keys: &[&str]) -> String {
    match keys {
        [] => String::new(),
        [k] => (*k).to_string(),
        [t, i, k] if i.parse::<usize>().is_ok() => {
            format!("[[{t}]] #{} {k}", i.parse::<usize>().unwrap_or(0) + 1)
        }
        [tables @ .., k] => format!("[{}] {k}", tables.join(".")),
    }
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

    /// CR-only line ends are named at the first one, not as what the TOML parser makes of a
    /// one-line file ("key with no value"; hostile audit 2 of issue 31, F21); CRLF is fine.
    #[test]
    fn cr_only_toml_is_named() {
        #[derive(serde::Deserialize, Debug)]
        #[allow(dead_code)]
        struct T {
            a: i64,
            b: i64,
        }
        let e = parse_toml::<T>("part.toml", "a = 1\rb = 2\r").unwrap_err();
        assert_eq!((e.line, e.column), (Some(1), Some(6)), "{e}");
        assert!(e.to_string().contains("CR-only line ends"), "{e}");
        parse_toml::<T>("part.toml", "a = 1\r\nb = 2\r\n").unwrap();
    }

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

    #[test]
    fn values_are_located_by_key_path() {
        let doc = TomlDoc {
            path: "b.toml".into(),
            text: "# bed\n[bed]\nsize_x_mm = 2000\nthickness_mm = -5\n\n[[rest]]\nx_mm = 1\n[[rest]]\nx_mm = 2\nforce_n = 3\n".into(),
        };
        assert_eq!(doc.locate(&["bed", "thickness_mm"]), Some((4, 16)));
        assert_eq!(doc.locate(&["rest", "1", "force_n"]), Some((10, 11)));
        // A key that is not there: the table that is.
        assert_eq!(doc.locate(&["bed", "poisson"]).map(|l| l.0), Some(2));
        assert_eq!(doc.locate(&["portal", "y_step_mm"]), None);
        let e = doc.positive(&["bed", "thickness_mm"], -5.0).unwrap_err();
        assert_eq!(e.to_string(), "b.toml:4:16: [bed] thickness_mm = -5: must be positive");
        assert_eq!(key_name(&["rest", "1", "force_n"]), "[[rest]] #2 force_n");
        assert!(doc.positive(&["bed", "size_x_mm"], 2000.0).is_ok());
        // Errors found elsewhere, placed by the key their message names.
        let e = doc.locate_error(InputError::in_file("b.toml", "[bed] thickness_mm must be positive"));
        assert_eq!((e.line, e.column), (Some(4), Some(16)));
        let e = doc.locate_error(InputError::in_file("b.toml", "[[rest]] 1 force_n is not finite"));
        assert_eq!(e.line, Some(10));
        let e = doc.locate_error(InputError::in_file("b.toml", "something else entirely"));
        assert_eq!(e.line, None);
    }
}

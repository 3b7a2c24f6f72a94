//! Bounds on XML inputs (QIF plans and models): the XML side of the bounded-read rule of
//! [`crate::limits`].
//!
//! An XML reader builds the whole document in memory and the programs that walk it recurse
//! into it, so three bounds apply before any XML parser sees the text:
//! - size: at most [`MAX_XML_BYTES`] (64 MiB; a QIF plan of a large part is a few MB, and the
//!   parsed tree takes several times the text), and never more than
//!   [`crate::limits::max_input_bytes`]; pipes and devices are read only up to the limit;
//! - no NUL byte (binary data), valid UTF-8;
//! - nesting at most [`MAX_XML_DEPTH`] elements deep (the QIF 3 schemas nest about 15 levels;
//!   tens of thousands of nested elements overflowed the stack), checked by [`check_depth`], a
//!   single pass over the text that needs no stack of its own;
//! - at most [`MAX_XML_ATTRIBUTES`] attributes on one element (the parser checks each new
//!   attribute against the element's others, so 150 000 attributes on one element took 17 s;
//!   QIF elements have a handful), counted in the same pass;
//! - at most [`MAX_XML_NODES`] nodes for the parser (`roxmltree`'s `nodes_limit`).
//!
//! Entry points: [`read_xml`] (a file, all bounds) and [`check_depth`] (text already in memory;
//! what a reader of XML text calls first). Lines are not limited in length: XML written by
//! programs is often one line.

use crate::limits::{human, max_input_bytes, other_format};
use crate::InputError;
use std::io::Read;
use std::path::Path;

/// Largest XML input, bytes (64 MiB).
pub const MAX_XML_BYTES: u64 = 64 << 20;

/// Deepest accepted nesting of elements.
pub const MAX_XML_DEPTH: usize = 256;

/// Most attributes (namespace declarations included) accepted on one element.
pub const MAX_XML_ATTRIBUTES: usize = 1024;

/// Most nodes (elements, text, attributes) a parsed XML document may have.
pub const MAX_XML_NODES: u32 = 4_000_000;

/// Which bound of [`check_depth`] an XML text broke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XmlBound {
    /// Elements nested deeper than [`MAX_XML_DEPTH`].
    Depth,
    /// An element with more than [`MAX_XML_ATTRIBUTES`] attributes.
    Attributes,
}

/// Nesting deeper than [`MAX_XML_DEPTH`], or more than [`MAX_XML_ATTRIBUTES`] attributes on
/// one element ([`TooDeep::bound`]): where the element starts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TooDeep {
    /// 1-based line of the element's `<`.
    pub line: usize,
    /// 1-based column (characters) of the element's `<`.
    pub column: usize,
    /// The bound broken.
    pub bound: XmlBound,
}

impl TooDeep {
    /// What is wrong and the limit, without the place.
    pub fn what(&self) -> String {
        match self.bound {
            XmlBound::Depth => format!("elements nested more than {MAX_XML_DEPTH} deep: truepos reads XML nested at most {MAX_XML_DEPTH} levels (QIF documents nest about 15)"),
            XmlBound::Attributes => format!("an element with more than {MAX_XML_ATTRIBUTES} attributes: truepos reads XML elements of at most {MAX_XML_ATTRIBUTES} attributes (QIF elements have a few)"),
        }
    }
}

impl std::fmt::Display for TooDeep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {}, column {}: {}", self.line, self.column, self.what())
    }
}

impl std::error::Error for TooDeep {}

/// Check that no element of `text` is nested deeper than [`MAX_XML_DEPTH`] or has more than
/// [`MAX_XML_ATTRIBUTES`] attributes (each `=` outside quotes in a start tag). Comments, CDATA,
/// processing instructions and declarations are skipped; quoted attribute values may hold `>`.
/// Malformed text is left to the XML parser (this only counts).
pub fn check_depth(text: &str) -> Result<(), TooDeep> {
    let b = text.as_bytes();
    let mut depth = 0usize;
    let mut i = 0;
    let find = |from: usize, pat: &[u8]| -> usize {
        memchr::memmem::find(&b[from.min(b.len())..], pat).map_or(b.len(), |p| from + p + pat.len())
    };
    while let Some(p) = memchr::memchr(b'<', &b[i..]) {
        let start = i + p;
        let rest = &b[start..];
        if rest.starts_with(b"<!--") {
            i = find(start + 4, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = find(start + 9, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = find(start + 2, b"?>");
        } else if rest.starts_with(b"<!") {
            // A declaration (DOCTYPE): an internal subset in brackets may hold '>'.
            let mut j = start + 2;
            let mut bracket = 0i32;
            while j < b.len() {
                match b[j] {
                    b'[' => bracket += 1,
                    b']' => bracket -= 1,
                    b'>' if bracket <= 0 => break,
                    _ => {}
                }
                j += 1;
            }
            i = j + 1;
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = find(start + 2, b">");
        } else {
            // A start tag: to its '>' outside quotes; "/>" closes it at once.
            let mut j = start + 1;
            let mut quote = 0u8;
            let mut attributes = 0usize;
            while j < b.len() {
                let c = b[j];
                if quote != 0 {
                    if c == quote {
                        quote = 0;
                    }
                } else if c == b'"' || c == b'\'' {
                    quote = c;
                } else if c == b'=' {
                    attributes += 1;
                } else if c == b'>' {
                    break;
                }
                j += 1;
            }
            let here = |bound| {
                let before = &text[..start];
                let line = memchr::memchr_iter(b'\n', before.as_bytes()).count() + 1;
                let line_start = before.rfind('\n').map_or(0, |n| n + 1);
                let column = before[line_start..].chars().count() + 1;
                TooDeep { line, column, bound }
            };
            if attributes > MAX_XML_ATTRIBUTES {
                return Err(here(XmlBound::Attributes));
            }
            let empty = j < b.len() && j > start + 1 && b[j - 1] == b'/';
            if !empty {
                depth += 1;
                if depth > MAX_XML_DEPTH {
                    return Err(here(XmlBound::Depth));
                }
            }
            i = j + 1;
        }
        if i >= b.len() {
            break;
        }
    }
    Ok(())
}

/// Read an XML file (`what` names it in messages: "QIF plan") with every bound above: size,
/// binary data, UTF-8 and nesting depth. Errors name the file (and the line where known).
pub fn read_xml(path: &Path, what: &str) -> Result<String, InputError> {
    let cannot = |e: std::io::Error| InputError::in_file(path, format!("cannot read the {what}: {e}"));
    let file = std::fs::File::open(path).map_err(cannot)?;
    crate::atomic::note_input(path);
    let meta = file.metadata().map_err(cannot)?;
    if meta.is_dir() {
        return Err(InputError::in_file(path, "is a directory, not a file"));
    }
    let limit = MAX_XML_BYTES.min(max_input_bytes());
    let over = || {
        InputError::in_file(
            path,
            format!(
                "the {what} is larger than {}: truepos reads XML inputs of at most {} (the parsed tree takes several times the text)",
                human(limit),
                human(limit)
            ),
        )
    };
    if meta.is_file() && meta.len() > limit {
        return Err(over());
    }
    let binary = |bytes: &[u8], p: usize| {
        let line = memchr::memchr_iter(b'\n', &bytes[..p]).count() + 1;
        let mut msg = format!("binary data (NUL byte): not a {what} (XML text)");
        if let Some(kind) = other_format(path) {
            msg = format!("this is {kind}, not a {what} (XML text)");
        }
        InputError::at(path, line, None, msg)
    };
    // In blocks, each checked as it arrives: /dev/zero stops at the first block.
    let mut bytes = Vec::new();
    let mut reader = file.take(limit + 1);
    let mut block = vec![0u8; 1 << 20];
    loop {
        let n = match reader.read(&mut block) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(cannot(e)),
        };
        let at = bytes.len();
        bytes.extend_from_slice(&block[..n]);
        if let Some(p) = memchr::memchr(0, &block[..n]) {
            return Err(binary(&bytes, at + p));
        }
        if bytes.len() as u64 > limit {
            return Err(over());
        }
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let ok = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = memchr::memchr_iter(b'\n', ok).count() + 1;
        InputError::at(path, line, None, format!("not valid UTF-8 text: not a {what} (XML text)"))
    })?;
    check_depth(&text).map_err(|d| InputError::at(path, d.line, Some(d.column), d.what()))?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nested(n: usize) -> String {
        format!("<r>{}{}</r>", "<a x='>'>".repeat(n), "</a>".repeat(n))
    }

    #[test]
    fn depth_is_counted_and_located() {
        assert!(check_depth(&nested(MAX_XML_DEPTH - 1)).is_ok());
        let e = check_depth(&nested(MAX_XML_DEPTH)).unwrap_err();
        assert_eq!(e.line, 1);
        assert_eq!(e.column, 1 + 3 + 9 * (MAX_XML_DEPTH - 1));
        // Empty elements, comments, CDATA, PIs and DOCTYPE do not nest.
        let flat = format!(
            "<?xml version='1.0'?>\n<!DOCTYPE r [<!ENTITY e 'x'>]>\n<r>{}<!-- <a> --><![CDATA[<a><a>]]><?pi <a>?></r>",
            "<a/><b k=\"/>\"/>".repeat(10_000)
        );
        assert!(check_depth(&flat).is_ok());
        let deep = format!("<r>\n  {}", "<a>".repeat(100_000));
        let e = check_depth(&deep).unwrap_err();
        assert_eq!((e.line, e.column), (2, 3 + 3 * (MAX_XML_DEPTH - 1)));
        assert!(e.to_string().contains("256"), "{e}");
    }

    #[test]
    fn attributes_per_element_are_bounded_in_linear_time() {
        let attrs = |n: usize| (0..n).map(|i| format!(" a{i}=\"x=>\"")).collect::<String>();
        let ok = format!("<r{}><b{}/></r>", attrs(MAX_XML_ATTRIBUTES), attrs(MAX_XML_ATTRIBUTES));
        assert!(check_depth(&ok).is_ok());
        let bad = format!("<r>\n <b{}/></r>", attrs(MAX_XML_ATTRIBUTES + 1));
        let e = check_depth(&bad).unwrap_err();
        assert_eq!((e.line, e.column, e.bound), (2, 2, XmlBound::Attributes));
        assert!(e.to_string().contains("more than 1024 attributes"), "{e}");
        // 500 000 attributes (the audit's 17 s at 150 000): refused in well under a second.
        let huge = format!("<r{}/>", attrs(500_000));
        let t = std::time::Instant::now();
        assert_eq!(check_depth(&huge).unwrap_err().bound, XmlBound::Attributes);
        assert!(t.elapsed().as_secs_f64() < 2.0);
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("many.qif");
        std::fs::write(&p, &bad).unwrap();
        let e = read_xml(&p, "QIF plan").unwrap_err();
        assert_eq!((e.line, e.column), (Some(2), Some(2)));
        assert!(e.to_string().contains("1024 attributes"), "{e}");
    }

    #[test]
    fn files_are_bounded() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("deep.qif");
        std::fs::write(&p, nested(50_000)).unwrap();
        let e = read_xml(&p, "QIF plan").unwrap_err();
        assert_eq!(e.line, Some(1));
        assert!(e.to_string().contains("nested more than 256"), "{e}");
        std::fs::write(&p, b"<a>\n\0</a>").unwrap();
        let e = read_xml(&p, "QIF plan").unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("binary"), "{e}");
        assert!(read_xml(d.path(), "QIF plan").unwrap_err().to_string().contains("directory"));
        if Path::new("/dev/zero").exists() {
            let t = std::time::Instant::now();
            let e = read_xml(Path::new("/dev/zero"), "QIF plan").unwrap_err();
            assert!(e.to_string().contains("binary") || e.to_string().contains("larger"), "{e}");
            assert!(t.elapsed().as_secs_f64() < 5.0);
        } else {
            eprintln!("SKIPPED: no /dev/zero on this system");
        }
        std::fs::write(&p, "<r>é</r>").unwrap();
        assert_eq!(read_xml(&p, "QIF plan").unwrap(), "<r>é</r>");
    }
}

//! Bounds on what truepos reads: every input is text of bounded size with bounded lines.
//!
//! - A text line longer than [`MAX_LINE_BYTES`] (1 MiB; a CSV row or a G-code block is at most a
//!   few hundred bytes) is an input error naming the line.
//! - A file larger than [`max_input_bytes`] (2 GiB by default, `TRUEPOS_MAX_INPUT_MB` to change)
//!   is refused before it is read (regular files: from their size; pipes and devices: when that
//!   many bytes have arrived).
//! - A NUL byte means binary data, not text: refused at the first block that contains one, so
//!   `/dev/zero` or a binary file given by mistake fails at once instead of being read forever.
//!
//! - A configuration file (TOML, JSON: a part, a machine, a map, a scenario) larger than
//!   [`max_config_bytes`] (64 MiB by default, `TRUEPOS_MAX_CONFIG_MB` to change) is refused the
//!   same way ([`read_config_string`]): such files are kilobytes, and their parsers hold
//!   several times the text in memory.
//!
//! [`read_text`] reads a whole (bounded) file for the readers that need all of it;
//! [`crate::stream`] reads in blocks with the same checks and constant memory; [`open_text`]
//! gives a `BufRead` with the same checks for readers that stream text themselves (G-code).

use crate::InputError;
use std::io::Read;
use std::path::Path;

/// Longest accepted line, bytes.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Default largest input file, bytes (2 GiB).
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 2 << 30;

/// Largest input file in bytes: `TRUEPOS_MAX_INPUT_MB` (mebibytes) if set to a positive number,
/// else [`DEFAULT_MAX_INPUT_BYTES`].
pub fn max_input_bytes() -> u64 {
    std::env::var("TRUEPOS_MAX_INPUT_MB")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok())
        .filter(|&m| m > 0)
        .map_or(DEFAULT_MAX_INPUT_BYTES, |m| m.saturating_mul(1 << 20))
}

/// Default largest configuration file (TOML, JSON), bytes (64 MiB): the project's part,
/// machine, bed, squareness, cell and scenario files are kilobytes (a part of the virtual CMM
/// takes about 200 bytes per solid: 64 MiB is some 300 000 solids).
pub const DEFAULT_MAX_CONFIG_BYTES: u64 = 64 << 20;

/// Largest configuration file in bytes: `TRUEPOS_MAX_CONFIG_MB` (mebibytes) if set to a positive
/// number, else [`DEFAULT_MAX_CONFIG_BYTES`].
pub fn max_config_bytes() -> u64 {
    std::env::var("TRUEPOS_MAX_CONFIG_MB")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok())
        .filter(|&m| m > 0)
        .map_or(DEFAULT_MAX_CONFIG_BYTES, |m| m.saturating_mul(1 << 20))
}

/// A size limit and how it is named in messages.
#[derive(Clone, Copy)]
struct Limit {
    bytes: u64,
    /// "inputs", "configuration files".
    of: &'static str,
    /// The variable that changes it.
    env: &'static str,
}

impl Limit {
    fn input() -> Limit {
        Limit { bytes: max_input_bytes(), of: "inputs", env: "TRUEPOS_MAX_INPUT_MB" }
    }
    fn config() -> Limit {
        Limit { bytes: max_config_bytes(), of: "configuration files", env: "TRUEPOS_MAX_CONFIG_MB" }
    }
    fn too_large(self, path: &Path, size: u64) -> InputError {
        InputError::in_file(
            path,
            format!(
                "the file is {}; truepos reads {} of at most {} (set {} to change the limit)",
                human(size),
                self.of,
                human(self.bytes),
                self.env
            ),
        )
    }
    fn stream_too_large(self, path: &Path) -> InputError {
        InputError::in_file(
            path,
            format!(
                "more than {} arrived (read up to the limit); truepos reads {} of at most {} (set {} to change the limit)",
                human(self.bytes),
                self.of,
                human(self.bytes),
                self.env
            ),
        )
    }
}

/// Human size.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{bytes} bytes")
    }
}

/// The error for a file over the size limit, its size known (a regular file).
pub fn too_large(path: &Path, size: u64, limit: u64) -> InputError {
    InputError::in_file(
        path,
        format!(
            "the file is {}; truepos reads inputs of at most {} (set TRUEPOS_MAX_INPUT_MB to change the limit)",
            human(size),
            human(limit)
        ),
    )
}

/// The error for a pipe or device that delivered more than the size limit (its size is not
/// known beforehand; reading stopped at the limit).
pub fn stream_too_large(path: &Path, limit: u64) -> InputError {
    InputError::in_file(
        path,
        format!(
            "more than {} arrived (read up to the limit); truepos reads inputs of at most {} (set TRUEPOS_MAX_INPUT_MB to change the limit)",
            human(limit),
            human(limit)
        ),
    )
}

/// The message for a text whose lines end in a carriage return alone (classic Mac OS), where a
/// reader that splits at LF saw one line: said as such, not as what follows from it (a missing
/// column, a line too long).
pub const CR_ONLY: &str = "CR-only line ends: the lines end in a carriage return alone (classic Mac OS), so the file reads as one line; convert them to LF or CRLF line ends (e.g. tr '\\r' '\\n' < in.csv > out.csv)";

pub use truepos_math::text::bare_carriage_return;

/// The error for a line over [`MAX_LINE_BYTES`].
pub fn line_too_long(path: &Path, line: usize) -> InputError {
    InputError::at(
        path,
        line,
        Some(1),
        format!("line longer than {} MB: not a text file of this kind", MAX_LINE_BYTES >> 20),
    )
}

/// The error for a NUL byte (binary data); a file of a known other kind (a spreadsheet, a ZIP
/// archive) is named as such ([`other_format`]).
pub fn binary(path: &Path, line: usize, what: &str) -> InputError {
    let mut msg = format!("binary data (NUL byte): not a {what} text file");
    if let Some(kind) = other_format(path) {
        msg = format!("this is {kind}, not a {what} text file{}", export_hint(kind, what));
        if kind == UTF16 {
            msg = format!(
                "this is UTF-16 text; truepos reads {what} as UTF-8: convert it (e.g. iconv -f UTF-16 -t UTF-8 in > out)"
            );
        }
    }
    InputError::at(path, line, None, msg)
}

/// [`other_format`]'s name for UTF-16 text (a byte-order mark, or zero bytes between ASCII).
const UTF16: &str = "UTF-16 text";

/// What to do with a file of another kind given where text of kind `what` was expected.
pub fn export_hint(kind: &str, what: &str) -> &'static str {
    if what != "CSV" {
        return "";
    }
    if kind.contains("spreadsheet") || kind.contains("workbook") || kind.contains("ZIP") {
        "; save the sheet as CSV (comma-separated, decimal point; points need the columns x_mm,y_mm,z_mm)"
    } else {
        "; points are CSV with the columns x_mm,y_mm,z_mm (or .ds, .parquet, .e57)"
    }
}

/// A file of a known kind other than text, or a text format that is not CSV, from its
/// extension or its first bytes: "an Excel workbook (.xlsx)", "a TOML file", … `None` when it
/// is none of these (or cannot be read).
pub fn other_format(path: &Path) -> Option<&'static str> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let by_ext = match ext.as_str() {
        "xlsx" | "xlsm" | "xlsb" => Some("an Excel workbook (.xlsx)"),
        "xls" => Some("an Excel 97-2003 workbook (.xls)"),
        "ods" => Some("an OpenDocument spreadsheet (.ods)"),
        "numbers" => Some("a Numbers spreadsheet"),
        "toml" => Some("a TOML file"),
        "json" => Some("a JSON file"),
        "zip" => Some("a ZIP archive"),
        _ => None,
    };
    if by_ext.is_some() {
        return by_ext;
    }
    let mut head = [0u8; 8];
    let n = std::fs::File::open(path).and_then(|mut f| f.read(&mut head)).ok()?;
    match &head[..n] {
        [b'P', b'K', 3, 4, ..] => Some("a ZIP archive (an .xlsx or .ods spreadsheet?)"),
        [0xD0, 0xCF, 0x11, 0xE0, 0xA1, 0xB1, 0x1A, 0xE1] => Some("an Excel 97-2003 workbook (.xls)"),
        [b'P', b'A', b'R', b'1', ..] => Some("a Parquet file without the .parquet extension"),
        // A byte-order mark, or text characters with a zero byte after (before) each.
        [0xFF, 0xFE, ..] | [0xFE, 0xFF, ..] => Some(UTF16),
        [a, 0, b, 0, ..] | [0, a, 0, b, ..]
            if [a, b].iter().all(|c| matches!(c, b'\t' | b'\n' | b'\r' | 0x20..=0x7e)) =>
        {
            Some(UTF16)
        }
        _ => None,
    }
}

/// Refuse `path` unless it is a regular file (checked before opening it, so a FIFO without a
/// writer does not block): for the binary formats read by seeking (`what`: "Parquet", "E57").
pub fn require_regular(path: &Path, what: &str) -> Result<(), InputError> {
    let Ok(meta) = std::fs::metadata(path) else { return Ok(()) };
    if meta.is_dir() {
        return Err(InputError::in_file(path, "is a directory, not a file"));
    }
    if !meta.is_file() {
        return Err(InputError::in_file(
            path,
            format!(
                "cannot read: it is {}; a {what} file is read by seeking, so it must be a regular file (copy it to one first)",
                crate::atomic::kind_of(&meta.file_type())
            ),
        ));
    }
    Ok(())
}

/// Refuse a regular file over the limit from its metadata (cheap, before any read).
pub fn check_file_size(path: &Path, meta: &std::fs::Metadata) -> Result<(), InputError> {
    let limit = max_input_bytes();
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(path, meta.len(), limit));
    }
    Ok(())
}

/// Scans blocks of text as they arrive: NUL bytes, line lengths and line count.
#[derive(Debug, Default, Clone)]
pub struct LineGuard {
    /// Completed lines so far.
    pub lines: usize,
    /// Bytes of the current (unfinished) line.
    current: usize,
}

impl LineGuard {
    /// Check `block`, the next bytes of the file.
    pub fn scan(&mut self, path: &Path, block: &[u8], what: &str) -> Result<(), InputError> {
        if let Some(p) = memchr::memchr(0, block) {
            let line = self.lines + memchr::memchr_iter(b'\n', &block[..p]).count() + 1;
            return Err(binary(path, line, what));
        }
        let mut start = 0;
        for nl in memchr::memchr_iter(b'\n', block) {
            if self.current + (nl - start) > MAX_LINE_BYTES {
                return Err(line_too_long(path, self.lines + 1));
            }
            self.lines += 1;
            self.current = 0;
            start = nl + 1;
        }
        self.current += block.len() - start;
        if self.current > MAX_LINE_BYTES {
            // No LF in the first megabyte but carriage returns: CR-only line ends, not a long line.
            if self.lines == 0 && memchr::memchr(b'\r', &block[start..]).is_some() {
                return Err(InputError::at(path, 1, Some(1), CR_ONLY));
            }
            return Err(line_too_long(path, self.lines + 1));
        }
        Ok(())
    }
}

/// Read a whole text file with the bounds above (size, line length, no NUL bytes). `what` names
/// the kind of file in messages ("CSV", "G-code", …). Regular files are read in one go after a
/// size check; pipes and devices in blocks, each checked as it arrives.
pub fn read_text(path: &Path, what: &str) -> Result<Vec<u8>, InputError> {
    read_limited(path, what, Limit::input())
}

/// [`read_text`] with the limit `limit`.
fn read_limited(path: &Path, what: &str, limit: Limit) -> Result<Vec<u8>, InputError> {
    let cannot = |e: std::io::Error| InputError::in_file(path, format!("cannot read: {e}"));
    let mut file = std::fs::File::open(path).map_err(cannot)?;
    crate::atomic::note_input(path);
    let meta = file.metadata().map_err(cannot)?;
    if meta.is_dir() {
        return Err(InputError::in_file(path, "is a directory, not a file"));
    }
    if meta.is_file() && meta.len() > limit.bytes {
        return Err(limit.too_large(path, meta.len()));
    }
    let mut guard = LineGuard::default();
    let mut buf = Vec::with_capacity(if meta.is_file() { meta.len() as usize + 1 } else { 1 << 16 });
    let mut block = vec![0u8; 1 << 20];
    loop {
        let n = match file.read(&mut block) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(cannot(e)),
        };
        guard.scan(path, &block[..n], what)?;
        if (buf.len() + n) as u64 > limit.bytes {
            return Err(limit.stream_too_large(path));
        }
        buf.extend_from_slice(&block[..n]);
    }
    Ok(buf)
}

/// [`read_text`] as a `String` (invalid UTF-8 is an error naming the line).
pub fn read_string(path: &Path, what: &str) -> Result<String, InputError> {
    utf8(path, what, read_text(path, what)?)
}

/// A configuration file (TOML, JSON; `what` names the kind) as a `String`, read like
/// [`read_string`] but within [`max_config_bytes`] (64 MiB by default), far below the limit
/// of the data inputs.
pub fn read_config_string(path: &Path, what: &str) -> Result<String, InputError> {
    utf8(path, what, read_limited(path, what, Limit::config())?)
}

/// `bytes` of `path` as text (invalid UTF-8 is an error naming the line).
fn utf8(path: &Path, what: &str, bytes: Vec<u8>) -> Result<String, InputError> {
    String::from_utf8(bytes).map_err(|e| {
        let ok = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = memchr::memchr_iter(b'\n', ok).count() + 1;
        InputError::at(path, line, None, format!("not valid UTF-8 text: not a {what} file"))
    })
}

/// A file read through the bounds above (size limit, line length, no NUL bytes), checked block
/// by block as it is read. A violation is an `io::Error` carrying the located [`InputError`]
/// (get it back with [`read_error`]).
pub struct BoundedReader {
    path: std::path::PathBuf,
    what: String,
    file: std::fs::File,
    guard: LineGuard,
    total: u64,
    limit: u64,
}

impl Read for BoundedReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        self.total += n as u64;
        let bad = |e: InputError| std::io::Error::new(std::io::ErrorKind::InvalidData, e);
        if self.total > self.limit {
            return Err(bad(stream_too_large(&self.path, self.limit)));
        }
        self.guard.scan(&self.path, &buf[..n], &self.what).map_err(bad)?;
        Ok(n)
    }
}

/// Open a text file for streaming with the bounds above; `what` names the kind of file in
/// messages. A directory, a missing file or a file over the size limit is refused here.
pub fn open_text(path: &Path, what: &str) -> Result<std::io::BufReader<BoundedReader>, InputError> {
    let cannot = |e: std::io::Error| InputError::in_file(path, format!("cannot read: {e}"));
    let file = std::fs::File::open(path).map_err(cannot)?;
    crate::atomic::note_input(path);
    let meta = file.metadata().map_err(cannot)?;
    if meta.is_dir() {
        return Err(InputError::in_file(path, "is a directory, not a file"));
    }
    check_file_size(path, &meta)?;
    let r = BoundedReader {
        path: path.to_path_buf(),
        what: what.to_string(),
        file,
        guard: LineGuard::default(),
        total: 0,
        limit: max_input_bytes(),
    };
    Ok(std::io::BufReader::with_capacity(1 << 20, r))
}

/// The input error of a failed read of `path` through a [`BoundedReader`]: the located error it
/// carries, or "cannot read" with the system's message.
pub fn read_error(path: &Path, e: std::io::Error) -> InputError {
    match e.get_ref().and_then(|i| i.downcast_ref::<InputError>()) {
        Some(i) => i.clone(),
        None => InputError::in_file(path, format!("cannot read: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// UTF-16 text (with or without a byte-order mark) is named as such with the conversion,
    /// not as "binary data" (hostile audit 2 of issue 31, F22); zeros stay binary data.
    #[test]
    fn utf16_is_named() {
        let d = tempfile::tempdir().unwrap();
        let utf16 = |bom: &[u8], be: bool| {
            let mut b = bom.to_vec();
            for c in "x_mm,y_mm,z_mm\n1,2,3\n".bytes() {
                b.extend(if be { [0, c] } else { [c, 0] });
            }
            b
        };
        for (name, bytes) in [
            ("le.csv", utf16(&[0xFF, 0xFE], false)),
            ("be.csv", utf16(&[0xFE, 0xFF], true)),
            ("nobom.qif", utf16(&[], false)),
        ] {
            let p = d.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            let e = read_string(&p, "CSV").unwrap_err().to_string();
            assert!(e.contains("UTF-16 text") && e.contains("iconv"), "{e}");
        }
        let z = d.path().join("z.csv");
        std::fs::write(&z, [0u8; 64]).unwrap();
        assert!(read_string(&z, "CSV").unwrap_err().to_string().contains("binary data"));
    }

    #[test]
    fn guard_finds_nul_and_long_lines_across_blocks() {
        let p = Path::new("f.csv");
        let mut g = LineGuard::default();
        g.scan(p, b"a,b\n1,2\n", "CSV").unwrap();
        let e = g.scan(p, b"3,\x004\n", "CSV").unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("binary"));
        let mut g = LineGuard::default();
        let half = vec![b'x'; MAX_LINE_BYTES / 2 + 1];
        g.scan(p, b"ok\n", "CSV").unwrap();
        g.scan(p, &half, "CSV").unwrap();
        let e = g.scan(p, &half, "CSV").unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("longer than 1 MB"), "{e}");
    }

    #[test]
    fn dev_zero_is_refused_at_once() {
        let p = Path::new("/dev/zero");
        if !p.exists() {
            eprintln!("SKIPPED: no /dev/zero on this system");
            return;
        }
        let t = std::time::Instant::now();
        let e = read_text(p, "CSV").unwrap_err();
        assert!(e.to_string().contains("binary"), "{e}");
        assert!(t.elapsed().as_secs_f64() < 1.0);
    }

    #[test]
    fn directories_and_missing_files_are_input_errors() {
        let d = tempfile::tempdir().unwrap();
        assert!(read_text(d.path(), "CSV").unwrap_err().to_string().contains("directory"));
        assert!(read_text(&d.path().join("nope"), "CSV").unwrap_err().to_string().contains("cannot read"));
    }

    #[test]
    fn bounded_reader_locates_nul_bytes_and_long_lines() {
        use std::io::BufRead;
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("p.nc");
        std::fs::write(&p, b"G0 X1\nG1 X2\nG1 \x00X3\n").unwrap();
        let mut r = open_text(&p, "G-code").unwrap();
        let mut line = String::new();
        let e = loop {
            line.clear();
            match r.read_line(&mut line) {
                Ok(0) => panic!("no error"),
                Ok(_) => {}
                Err(e) => break read_error(&p, e),
            }
        };
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("binary") && e.to_string().contains("G-code"), "{e}");
        let mut long = b"G0 X1\n".to_vec();
        long.extend(std::iter::repeat_n(b'(', MAX_LINE_BYTES + 1));
        std::fs::write(&p, &long).unwrap();
        let mut all = Vec::new();
        let e = read_error(
            &p,
            std::io::Read::read_to_end(&mut open_text(&p, "G-code").unwrap(), &mut all).unwrap_err(),
        );
        assert_eq!(e.line, Some(2));
        assert!(open_text(d.path(), "G-code").err().unwrap().to_string().contains("directory"));
        let e = read_error(&p, std::io::Error::other("gone"));
        assert!(e.to_string().contains("cannot read: gone"), "{e}");
    }
}

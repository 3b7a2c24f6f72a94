//! CSV files as the interface contract defines them.
//!
//! Comma separated, UTF-8, one header row; lines starting with `#` before the header are
//! comments (kept in [`Table::comments`]); blank lines and later `#` lines are skipped. Columns may
//! come in any order and unknown columns are kept so commands can pass them through. Fields may
//! be double-quoted (no embedded newlines).
//!
//! [`Table::read`] loads the file and indexes its rows (one `memchr` pass); typed access
//! ([`Table::f64_columns`]) parses the requested columns of all rows in parallel and reports
//! the first bad value with file, line, column number and column name. Ragged rows are errors.
//! [`CsvWriter`] writes rows with shortest round-trip float formatting.
//!
//! The direct readers ([`Table::read_rows_direct`] for points, [`Table::read_stream_direct`] for
//! time streams) parse the wanted columns straight from the text in parallel segments, without a
//! row index, and hand anything unusual back as a [`Table`] (the general path, which also words
//! the errors). Their common row, short decimals separated by commas, is read by delimiter
//! blocks and SSSE3 number conversion where the CPU has it (`plain_rows_ssse3`), else by the
//! SWAR reader (`short_decimal_prefix`); both give `str::parse`'s value bit for bit. A mapped
//! file is checked for NUL bytes and UTF-8 only where the parser did not see plain ASCII rows.
//!
//! Layout: this file holds the table API, the general row path and the writer; `direct` the
//! direct readers' segment loop; `swar` the portable number conversion; `x86` every kernel that
//! needs an instruction set beyond the x86-64 baseline. `cpu_has_ssse3` is the one run-time
//! choice between them.

use crate::num::NumFormat;
use crate::InputError;
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};

mod direct;
mod swar;
#[cfg(target_arch = "x86_64")]
mod x86;

use direct::*;
use swar::*;
#[cfg(target_arch = "x86_64")]
use x86::*;

/// The one run-time choice of instruction set for the readers: whether this CPU has SSSE3
/// (every x86-64 since 2006–2011). The standard library caches the CPUID answer, so asking per
/// segment or per range costs a load. `false` on other architectures: the portable path.
#[inline]
pub(crate) fn cpu_has_ssse3() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("ssse3")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The file's text: owned, or a read-only memory map of a large regular file (no copy). Either
/// way it has been checked to be UTF-8 without NUL bytes.
enum Text {
    Owned(String),
    Mapped(memmap2::Mmap),
}

impl std::ops::Deref for Text {
    type Target = str;
    fn deref(&self) -> &str {
        match self {
            Text::Owned(s) => s,
            // SAFETY: validated as UTF-8 in `Table::from_mapped` before construction; the map is
            // read-only and private to this process.
            Text::Mapped(m) => unsafe { std::str::from_utf8_unchecked(&m[..]) },
        }
    }
}

impl Text {
    /// A file whose lines end in a carriage return alone (classic Mac OS) as LF lines: the same
    /// lines, numbered the same. Other text is returned as it is (a file with any LF is not
    /// looked at further; `memchr` finds the first LF within the first line).
    fn with_lf_lines(self) -> Text {
        let b = self.as_bytes();
        if memchr::memchr(b'\n', b).is_none() && memchr::memchr(b'\r', b).is_some() {
            return Text::Owned(self.replace('\r', "\n"));
        }
        self
    }

    /// Let go of the text. A memory map is unmapped on a short-lived thread of its own: tearing
    /// down the page tables of a large map takes milliseconds (about 2 ms for 30 MB) that the
    /// caller, about to compute on what it parsed, need not wait for. (If no thread can be
    /// started, the map is unmapped here.)
    fn release(self) {
        if let Text::Mapped(map) = self {
            let _ = std::thread::Builder::new().name("truepos-unmap".into()).spawn(move || drop(map));
        }
    }
}

/// A parsed CSV file: the text, the header and the byte offset of each data row.
pub struct Table {
    /// The file's path, as given (named in error messages).
    pub path: PathBuf,
    text: Text,
    /// The column names of the header row, trimmed.
    pub header: Vec<String>,
    /// Comment lines before the header, without the leading `#` and surrounding spaces.
    pub comments: Vec<String>,
    /// Byte offset of the start of each data row.
    rows: Vec<usize>,
    /// Points of an E57 file left out because the file marks them invalid
    /// (`cartesianInvalidState`); 0 for every other format. Commands that read points through
    /// a table can report it as `truepos fit` does.
    pub skipped_invalid: usize,
    /// Points of an E57 file left out because a coordinate is NaN or infinite; 0 otherwise.
    pub skipped_nonfinite: usize,
}

/// The message for a column the header lacks, with what the header says about the file when it
/// tells why: separated by `;` or tabs (spreadsheet exports with a decimal comma), or not CSV at
/// all (TOML, JSON, a spreadsheet by its extension).
pub(crate) fn missing_column_message(path: &Path, name: &str, header: &[String]) -> String {
    // A carriage return inside the header: the file's lines end in CR alone and were read as
    // one line. Said first and as such (column `name` is only missing because of it).
    if crate::limits::other_format(path).is_none() && header.iter().any(|h| h.contains('\r')) {
        return format!("{} (column '{name}' not found in the one line read)", crate::limits::CR_ONLY);
    }
    let mut msg = format!("missing required column '{name}' (columns: {})", header.join(","));
    if let Some(hint) = header_hint(path, header) {
        msg.push_str(": ");
        msg.push_str(&hint);
    }
    msg
}

/// See [`missing_column_message`].
fn header_hint(path: &Path, header: &[String]) -> Option<String> {
    if let Some(kind) = crate::limits::other_format(path) {
        return Some(format!("this is {kind}, not a CSV file{}", crate::limits::export_hint(kind, "CSV")));
    }
    let first = header.first().map(String::as_str).unwrap_or("");
    let whole = header.join(",");
    if whole.contains('\r') {
        return Some(
            "the lines end in a carriage return alone (classic Mac OS): convert them to LF or CRLF \
             line ends (e.g. tr '\\r' '\\n' < in.csv > out.csv)"
                .into(),
        );
    }
    let toml_like = (first.starts_with('[') && first.trim_end().ends_with(']'))
        || (header.len() == 1 && first.contains(" = "));
    if first.starts_with('{')
        || (first.starts_with('[') && whole.trim_start_matches('[').trim_start().starts_with(['{', '"']))
    {
        return Some("this looks like JSON, not a CSV file (points: x_mm,y_mm,z_mm columns)".into());
    }
    if toml_like {
        return Some("this looks like a TOML file, not a CSV file (points: x_mm,y_mm,z_mm columns)".into());
    }
    if header.len() == 1 && first.contains(';') {
        return Some(
            "the fields are separated by ';': truepos reads comma-separated files with a decimal point \
             (export as CSV with ',' between fields and '.' in numbers, e.g. x_mm,y_mm,z_mm / 102.99606)"
                .into(),
        );
    }
    if header.len() == 1 && first.contains('\t') {
        return Some(
            "the fields are separated by tabs: truepos reads comma-separated files (x_mm,y_mm,z_mm)".into(),
        );
    }
    None
}

/// The number format that keeps the precision an input CSV carries in `columns`: `Fixed(d)`
/// with `d` the most decimals among the first 1000 data rows (at least
/// [`MIN_OUTPUT_DECIMALS`]), when that is at most
/// [`FULL_PRECISION_DECIMALS`]; the shortest round-trip text when it is more (a machine-written
/// full-precision double), when a value has an exponent, or when the file is not a CSV that can
/// be read (Parquet, E57: binary doubles). Reads at most the first 256 KiB.
pub fn input_precision(path: &Path, columns: &[&str]) -> NumFormat {
    use std::io::Read;
    if crate::parquet_file::is_parquet(path) || crate::e57_file::is_e57(path) {
        return NumFormat::Shortest;
    }
    let mut head = Vec::new();
    let Ok(f) = std::fs::File::open(path) else {
        return NumFormat::Shortest;
    };
    if f.take(256 << 10).read_to_end(&mut head).is_err() {
        return NumFormat::Shortest;
    }
    let text = String::from_utf8_lossy(&head);
    let mut lines =
        text.lines().map(trim_line).filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some(header) = lines.next() else {
        return NumFormat::Shortest;
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let idx: Vec<usize> = columns.iter().filter_map(|c| names.iter().position(|n| n == c)).collect();
    if idx.is_empty() {
        return NumFormat::Shortest;
    }
    let mut most = 0usize;
    let mut rows = 0;
    // The last line may be cut by the 256 KiB window: it is not looked at.
    let complete = text.rfind('\n').map_or("", |e| &text[..e]);
    let mut lines =
        complete.lines().map(trim_line).filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    lines.next();
    for line in lines.take(1000) {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        for &i in &idx {
            let Some(f) = fields.get(i) else { continue };
            if f.contains(['e', 'E']) {
                return NumFormat::Shortest;
            }
            most = most.max(f.split_once('.').map_or(0, |(_, d)| d.len()));
        }
        rows += 1;
    }
    if rows == 0 || most > FULL_PRECISION_DECIMALS {
        NumFormat::Shortest
    } else {
        NumFormat::Fixed(most.max(MIN_OUTPUT_DECIMALS) as u8)
    }
}

/// At least this many decimals (1 nm in mm) whatever the input shows: a correction of a few
/// micrometres to `250` or `10.5` must not be rounded away.
pub const MIN_OUTPUT_DECIMALS: usize = 6;

/// More decimals than this (in mm: below a picometre) is a full-precision double written by a
/// program, not a measured precision: [`input_precision`] then keeps the shortest round-trip text.
pub const FULL_PRECISION_DECIMALS: usize = 9;

/// What a field that is not a number probably is, when it looks like a known mistake.
fn value_hint(s: &str) -> Option<&'static str> {
    let t = s.trim().trim_start_matches(['+', '-']);
    let decimal_comma = t.split_once(',').is_some_and(|(a, b)| {
        !a.is_empty()
            && !b.is_empty()
            && a.bytes().all(|c| c.is_ascii_digit())
            && b.bytes().all(|c| c.is_ascii_digit())
    });
    if decimal_comma {
        Some("a decimal comma: truepos reads a decimal point (102.99606, not 102,99606)")
    } else if s.contains(';') {
        Some("fields separated by ';': truepos reads comma-separated files")
    } else {
        None
    }
}

/// Split one CSV line into field byte ranges (relative to the line), honouring double quotes.
#[inline]
pub(crate) fn split_fields(line: &str, out: &mut Vec<(usize, usize)>) {
    out.clear();
    let b = line.as_bytes();
    let mut i = 0;
    loop {
        // Leading spaces.
        let mut s = i;
        while s < b.len() && (b[s] == b' ' || b[s] == b'\t') {
            s += 1;
        }
        if s < b.len() && b[s] == b'"' {
            let start = s + 1;
            let mut j = start;
            while j < b.len() {
                if b[j] == b'"' {
                    if j + 1 < b.len() && b[j + 1] == b'"' {
                        j += 2;
                        continue;
                    }
                    break;
                }
                j += 1;
            }
            out.push((start, j.min(b.len())));
            let next = memchr::memchr(b',', &b[j.min(b.len())..]).map(|p| j + p);
            match next {
                Some(c) => i = c + 1,
                None => return,
            }
        } else {
            let end = memchr::memchr(b',', &b[i..]).map_or(b.len(), |p| i + p);
            let mut e = end;
            while e > s && (b[e - 1] == b' ' || b[e - 1] == b'\t') {
                e -= 1;
            }
            out.push((s, e));
            if end == b.len() {
                return;
            }
            i = end + 1;
        }
    }
}

/// [`split_fields`] for the common case without quotes: one byte loop, no `memchr` call per
/// short field. Returns `false` (and leaves `out` unspecified) when the line has a quote.
#[inline]
fn split_fields_fast(line: &[u8], out: &mut Vec<(usize, usize)>) -> bool {
    out.clear();
    let mut start = 0;
    let mut i = 0;
    loop {
        while i < line.len() && line[i] != b',' {
            if line[i] == b'"' {
                return false;
            }
            i += 1;
        }
        let (mut a, mut e) = (start, i);
        while a < e && (line[a] == b' ' || line[a] == b'\t') {
            a += 1;
        }
        while e > a && (line[e - 1] == b' ' || line[e - 1] == b'\t') {
            e -= 1;
        }
        out.push((a, e));
        if i >= line.len() {
            return true;
        }
        i += 1;
        start = i;
    }
}

/// A read-only map of a regular file of at least 8 MiB (`None` for smaller files, pipes, or
/// when mapping fails: the caller then reads it). Mapping saves the kernel copy of the whole
/// file; the pages come straight from the page cache. Files over the size limit are refused.
fn map_large_file(path: &Path) -> Result<Option<memmap2::Mmap>, InputError> {
    map_large_file_with(path, true)
}

/// [`map_large_file`]; `populate`: the page tables are filled in one go (the file is about to
/// be read whole), instead of one page fault per few pages. (Without it the caller populates
/// when it is ready to, e.g. after starting other work.)
fn map_large_file_with(path: &Path, populate: bool) -> Result<Option<memmap2::Mmap>, InputError> {
    let Ok(file) = std::fs::File::open(path) else { return Ok(None) };
    crate::atomic::note_input(path);
    let Ok(meta) = file.metadata() else { return Ok(None) };
    crate::limits::check_file_size(path, &meta)?;
    if !meta.is_file() || meta.len() < 8 << 20 {
        return Ok(None);
    }
    let mut options = memmap2::MmapOptions::new();
    if populate {
        options.populate();
    }
    // SAFETY: a private read-only map; the input file is not expected to change while truepos
    // reads it (as with any reader, a file truncated meanwhile is an error the OS reports).
    Ok(unsafe { options.map(&file).ok() })
}

/// Read a whole file with the bounds of [`crate::limits`] (size, line length, no NUL bytes).
pub fn read_file(path: &Path) -> Result<Vec<u8>, InputError> {
    crate::limits::read_text(path, "CSV")
}

/// Bytes per segment of [`line_segments`]: small enough that the segments of a large file
/// outnumber the threads many times over (a thread held up, e.g. by the kernel clearing a fresh
/// page of the output, leaves its remaining segments to the others), large enough that the
/// per-segment bookkeeping stays negligible.
const SEGMENT_BYTES: usize = 512 << 10;

/// Boundaries `[0, …, len]` of segments of `bytes` cut just after line ends, about
/// [`SEGMENT_BYTES`] each (at least 4 × the worker threads of them) when `bytes` is at least
/// `min_len` long (else one segment).
fn line_segments(bytes: &[u8], min_len: usize) -> Vec<usize> {
    let len = bytes.len();
    let mut bounds = vec![0];
    if len >= min_len {
        let parts = (len / SEGMENT_BYTES).clamp(4 * rayon::current_num_threads(), 1 << 12);
        for k in 1..parts {
            let b = len * k / parts;
            let b = memchr::memchr(b'\n', &bytes[b..]).map_or(len, |p| b + p + 1);
            if b > *bounds.last().unwrap_or(&0) && b < len {
                bounds.push(b);
            }
        }
    }
    bounds.push(len);
    bounds
}

/// Start offsets of the data rows in `text[from..to]` (`from` at a line start): lines that are
/// blank or start with `#` (after leading whitespace) are skipped.
/// Returns the offset of the first line longer than [`crate::limits::MAX_LINE_BYTES`], if any.
pub(crate) fn index_rows(text: &str, from: usize, to: usize, out: &mut Vec<usize>) -> Option<usize> {
    let bytes = text.as_bytes();
    let mut pos = from;
    // One search over the whole range (rows are short: a call per row would cost more than it finds).
    let mut ends = memchr::memchr_iter(b'\n', &bytes[from..to]).map(|p| from + p);
    while pos < to {
        let end = ends.next().unwrap_or(to);
        if end - pos > crate::limits::MAX_LINE_BYTES {
            return Some(pos);
        }
        let mut i = pos;
        while i < end && matches!(bytes[i], b' ' | b'\t' | b'\r' | 0x0b | 0x0c) {
            i += 1;
        }
        if i < end {
            if bytes[i] >= 0x80 {
                // Non-ASCII: let `str` decide what is whitespace.
                let t = trim_line(&text[pos..end]).trim_start();
                if !t.is_empty() && !t.starts_with('#') {
                    out.push(pos);
                }
            } else if bytes[i] != b'#' {
                out.push(pos);
            }
        }
        pos = end + 1;
    }
    None
}

/// [`index_rows`] over `text[from..]`, in parallel segments for large inputs. `Err(offset)`: a
/// line over the length limit starts at `offset`.
fn index_rows_parallel(text: &str, from: usize) -> Result<Vec<usize>, usize> {
    let bytes = text.as_bytes();
    let len = bytes.len();
    if len.saturating_sub(from) < (1 << 20) {
        let mut rows = Vec::new();
        return match index_rows(text, from, len, &mut rows) {
            Some(bad) => Err(bad),
            None => Ok(rows),
        };
    }
    let parts = 4 * rayon::current_num_threads();
    let mut bounds = vec![from];
    for k in 1..parts {
        let b = from + (len - from) * k / parts;
        let b = memchr::memchr(b'\n', &bytes[b..]).map_or(len, |p| b + p + 1);
        if b > *bounds.last().unwrap_or(&from) && b < len {
            bounds.push(b);
        }
    }
    bounds.push(len);
    let segs: Vec<Result<Vec<usize>, usize>> = bounds
        .par_windows(2)
        .map(|w| {
            // ~33 bytes per row is typical for x,y,z: reserve accordingly.
            let mut v = Vec::with_capacity((w[1] - w[0]) / 24 + 1);
            match index_rows(text, w[0], w[1], &mut v) {
                Some(bad) => Err(bad),
                None => Ok(v),
            }
        })
        .collect();
    let mut rows = Vec::with_capacity(segs.iter().map(|s| s.as_ref().map_or(0, Vec::len)).sum());
    for s in segs {
        rows.extend_from_slice(&s?);
    }
    Ok(rows)
}

fn line_of(text: &str, offset: usize) -> usize {
    memchr::memchr_iter(b'\n', &text.as_bytes()[..offset]).count() + 1
}

fn trim_line(line: &str) -> &str {
    line.strip_suffix('\r').unwrap_or(line)
}

impl std::fmt::Debug for Table {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Table")
            .field("path", &self.path)
            .field("header", &self.header)
            .field("rows", &self.rows.len())
            .finish()
    }
}

impl Table {
    /// Read and index a CSV file.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, InputError> {
        let path = path.as_ref();
        if crate::parquet_file::is_parquet(path) {
            return Self::from_columns(path, crate::parquet_file::read_columns(path)?);
        }
        if crate::e57_file::is_e57(path) {
            // The points of every scan as x_mm,y_mm,z_mm (see `crate::e57_file`).
            let e = crate::e57_file::read_e57(path)?;
            let col =
                |k: usize| crate::parquet_file::ColumnData::F64(e.points.iter().map(|p| p[k]).collect());
            let names = ["x_mm", "y_mm", "z_mm"].map(String::from).to_vec();
            let mut t = Self::from_columns(
                path,
                crate::parquet_file::Columns { names, data: vec![col(0), col(1), col(2)] },
            )?;
            t.skipped_invalid = e.skipped_invalid;
            t.skipped_nonfinite = e.skipped_nonfinite;
            return Ok(t);
        }
        if let Some(map) = map_large_file(path)? {
            return Self::from_text(path, Self::check_bytes(path, &map[..]).map(|_| Text::Mapped(map))?);
        }
        Self::from_bytes(path, read_file(path)?)
    }

    /// A Parquet file as a table: its columns written as CSV text in memory (numbers in shortest
    /// round-trip form, so they read back bit for bit). Line `r + 2` of such a table is row `r + 1`
    /// of the Parquet file.
    /// (E57 files come the same way, as their `x_mm,y_mm,z_mm` columns.)
    fn from_columns(path: &Path, c: crate::parquet_file::Columns) -> Result<Self, InputError> {
        use crate::parquet_file::ColumnData;
        // Parquet column names are free text, the header here is a CSV line: a name must read
        // back as itself (a comma in a name split the header in two, found by the
        // `parquet_points` fuzz target; a leading '#' would make it a comment line).
        for (i, n) in c.names.iter().enumerate() {
            if n.is_empty()
                || n.contains([',', '"', '\n', '\r'])
                || n.trim() != n
                || n.starts_with(['#', '\u{feff}'])
                || c.names[..i].contains(n)
            {
                return Err(InputError::in_file(
                    path,
                    format!(
                        "column {}: the name '{}' is empty, repeated, or has a comma, quote, line break, leading '#' or surrounding spaces",
                        i + 1,
                        n.escape_debug()
                    ),
                ));
            }
        }
        let mut w = CsvWriter::new(Vec::with_capacity(c.n_rows() * 40));
        let names: Vec<&str> = c.names.iter().map(String::as_str).collect();
        let io = |e: std::io::Error| InputError::in_file(path, e.to_string());
        w.header(&names).map_err(io)?;
        for r in 0..c.n_rows() {
            for (name, d) in c.names.iter().zip(&c.data) {
                match d {
                    ColumnData::F64(v) => w.field_f64(v[r]).map_err(io)?,
                    ColumnData::Str(v) => {
                        if v[r].contains(['\n', '\r']) {
                            return Err(InputError::in_file(
                                path,
                                format!("row {}: a line break in the text", r + 1),
                            )
                            .with_column_name(name.clone()));
                        }
                        w.field_str(&v[r]).map_err(io)?
                    }
                }
            }
            w.end_row().map_err(io)?;
        }
        let t = Self::from_bytes(path, w.into_inner())?;
        if t.header != c.names {
            return Err(InputError::in_file(
                path,
                format!("column names that do not read back as a header: {:?}", c.names),
            ));
        }
        Ok(t)
    }

    /// NUL bytes and invalid UTF-8 are input errors (a binary file is not a CSV file): the first
    /// NUL byte if there is one, else the first invalid UTF-8. Large inputs are checked in
    /// parallel segments cut after line ends (a line end is never inside a UTF-8 character, so
    /// each segment validates on its own and finds the same first bad byte).
    fn check_bytes(path: &Path, bytes: &[u8]) -> Result<(), InputError> {
        Self::check_counted(path, bytes, false).map(|_| ())
    }

    /// [`check_bytes`](Self::check_bytes) that also counts the lines of each segment when
    /// `count` (in the same visit of the segment, while it is in cache): the segments
    /// [`direct_rows`] parses.
    fn check_counted(path: &Path, bytes: &[u8], count: bool) -> Result<Segments, InputError> {
        let bounds = line_segments(bytes, if count { 1 << 20 } else { 1 << 22 });
        let per: Vec<(Option<usize>, Option<usize>, usize)> = bounds
            .par_windows(2)
            .map(|w| {
                let seg = &bytes[w[0]..w[1]];
                let nul = memchr::memchr(0, seg).map(|p| w[0] + p);
                let utf8 = std::str::from_utf8(seg).err().map(|e| w[0] + e.valid_up_to());
                (nul, utf8, if count { segment_lines(seg) } else { 0 })
            })
            .collect();
        if let Some(p) = per.iter().find_map(|s| s.0) {
            let line = memchr::memchr_iter(b'\n', &bytes[..p]).count() + 1;
            return Err(crate::limits::binary(path, line, "CSV"));
        }
        if let Some(p) = per.iter().find_map(|s| s.1) {
            let line = memchr::memchr_iter(b'\n', &bytes[..p]).count() + 1;
            return Err(InputError::at(path, line, None, "not valid UTF-8 text: not a CSV file"));
        }
        Ok(Segments { lines: per.iter().map(|s| s.2).collect(), bounds })
    }

    /// Index CSV data that came from `path` (used in messages).
    pub fn from_bytes(path: impl AsRef<Path>, bytes: Vec<u8>) -> Result<Self, InputError> {
        let path = path.as_ref();
        Self::check_bytes(path, &bytes)?;
        let text = String::from_utf8(bytes).map_err(|_| InputError::in_file(path, "not valid UTF-8 text"))?;
        Self::from_text(path, Text::Owned(text))
    }

    fn from_text(path: &Path, text: Text) -> Result<Self, InputError> {
        let text = text.with_lf_lines();
        let (header, comments, data) = Self::head(path, &text)?;
        // The data rows are indexed in parallel (segments split at line ends).
        let rows = index_rows_parallel(&text, data)
            .map_err(|bad| crate::limits::line_too_long(path, line_of(&text, bad)))?;
        Ok(Self {
            path: path.to_path_buf(),
            text,
            header,
            comments,
            rows,
            skipped_invalid: 0,
            skipped_nonfinite: 0,
        })
    }

    /// The header (checked), the comments before it and the byte offset just after its line.
    fn head(path: &Path, text: &str) -> Result<(Vec<String>, Vec<String>, usize), InputError> {
        let start = if text.starts_with('\u{feff}') { 3 } else { 0 };
        let mut comments = Vec::new();
        let mut pos = start;
        let bytes = text.as_bytes();
        let mut fields = Vec::new();
        while pos < bytes.len() {
            let end = memchr::memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |p| pos + p);
            if end - pos > crate::limits::MAX_LINE_BYTES {
                return Err(crate::limits::line_too_long(path, line_of(text, pos)));
            }
            let line = trim_line(&text[pos..end]);
            let trimmed = line.trim_start();
            if trimmed.is_empty() {
            } else if let Some(comment) = trimmed.strip_prefix('#') {
                comments.push(comment.trim().to_string());
            } else {
                split_fields(line, &mut fields);
                let names: Vec<String> = fields.iter().map(|&(a, b)| line[a..b].to_string()).collect();
                let lineno = line_of(text, pos);
                for (i, n) in names.iter().enumerate() {
                    if n.is_empty() {
                        return Err(InputError::at(
                            path,
                            lineno,
                            Some(i + 1),
                            "empty column name in the header",
                        ));
                    }
                    if names[..i].contains(n) {
                        return Err(InputError::at(
                            path,
                            lineno,
                            Some(i + 1),
                            format!("duplicate column '{n}' in the header"),
                        ));
                    }
                }
                // A header on the last line without a line end: no data after it (not past the end).
                return Ok((names, comments, (end + 1).min(bytes.len())));
            }
            pos = end + 1;
        }
        Err(InputError::in_file(path, "empty file: no header row"))
    }

    /// Read a CSV file and parse columns `names` of every data row straight from the text, in
    /// parallel segments cut after line ends, without a row index. `Ok(Err(table))` when the
    /// file is not the plain case (an `id` column, a missing column, quotes, a non-ASCII or
    /// too long line, a bad value): the caller then takes the general path on the returned
    /// table (built from the same text, no second read), which also produces the exact error
    /// (file:line:col) of today. Parquet and E57 files always come back as a table.
    pub fn read_rows_direct<const K: usize>(
        path: &Path,
        names: &[&str; K],
    ) -> Result<Result<Vec<[f64; K]>, Table>, InputError> {
        if crate::parquet_file::is_parquet(path) || crate::e57_file::is_e57(path) {
            return Self::read(path).map(Err);
        }
        let Some(map) = map_large_file_with(path, false)? else {
            return Self::rows_direct(path, Self::checked_text(path)?, names);
        };
        // The input's page tables are not filled beforehand (on one thread, ≈ 6 ms for 30 MB):
        // the threads that check it fault its pages in as they go, in parallel. (A thread that
        // backed the output with memory meanwhile, `MADV_POPULATE_WRITE`, helped while the
        // input was populated serially; now it competes with the checking threads and gains
        // nothing measurable: medians of 21 alternated runs of `fit sphere` on 1M points, with /
        // without, 31.5 / 30.8 ms and 32.4 / 32.2 ms. One thread and an `unsafe` call fewer.)
        if let Some(rows) = Self::mapped_rows_direct(path, &map[..], names)? {
            Text::Mapped(map).release();
            return Ok(Ok(rows));
        }
        let segments = Self::check_counted(path, &map[..], true)?;
        Self::rows_direct_into(path, Text::Mapped(map), names, Some(segments))
    }

    /// The plain case of [`read_rows_direct`](Self::read_rows_direct) on a mapped file, with
    /// the text checks only where they can find something: the segment holding the header is
    /// checked (NUL bytes, UTF-8) before the header is read; every other segment whose lines
    /// the row parser passed as plain ASCII ([`parse_segment`]'s `clean`) needs no check, and
    /// the rest are checked after the parse. On a plain file this is one visit of the text
    /// (counting its lines) before the parse, instead of three (NUL bytes, UTF-8, lines).
    /// `None` when the file is not the plain case (or its header is not in the first segment):
    /// the caller then takes the general path, which checks the whole text first and reports
    /// exactly what [`Table::read`] reports.
    fn mapped_rows_direct<const K: usize>(
        path: &Path,
        bytes: &[u8],
        names: &[&str; K],
    ) -> Result<Option<Vec<[f64; K]>>, InputError> {
        let bounds = line_segments(bytes, 1 << 20);
        let first = &bytes[..bounds[1]];
        if memchr::memchr(0, first).is_some() {
            return Ok(None);
        }
        let Ok(first) = std::str::from_utf8(first) else {
            return Ok(None);
        };
        let Ok((header, _, data)) = Self::head(path, first) else {
            return Ok(None);
        };
        let idx: Option<Vec<usize>> = names.iter().map(|n| header.iter().position(|h| h == n)).collect();
        let Some(idx) = idx.filter(|_| !header.iter().any(|h| h == "id")) else {
            return Ok(None);
        };
        let lines: Vec<usize> = bounds.par_windows(2).map(|w| segment_lines(&bytes[w[0]..w[1]])).collect();
        let segments = Segments { bounds, lines }.after(bytes, data);
        let data_bounds = segments.0.clone();
        let Some((rows, clean)) = direct_rows_clean::<K>(&bytes[data..], header.len(), &idx, Some(segments))
        else {
            return Ok(None);
        };
        // Segments with a line that was not plain ASCII: checked as `check_bytes` would have;
        // on a finding the whole text is checked, which reports its first bad byte.
        let suspect = data_bounds.windows(2).zip(&clean).any(|(w, &c)| {
            let seg = &bytes[data + w[0]..data + w[1]];
            !c && (memchr::memchr(0, seg).is_some() || std::str::from_utf8(seg).is_err())
        });
        if suspect {
            Self::check_bytes(path, bytes)?;
        }
        Ok(Some(rows))
    }

    /// The text of a CSV file, mapped when large, with the checks of [`Table::read`] (size, NUL
    /// bytes, UTF-8).
    fn checked_text(path: &Path) -> Result<Text, InputError> {
        Ok(match map_large_file(path)? {
            Some(map) => {
                Self::check_bytes(path, &map[..])?;
                Text::Mapped(map)
            }
            None => {
                let bytes = read_file(path)?;
                Self::check_bytes(path, &bytes)?;
                let s = String::from_utf8(bytes)
                    .map_err(|_| InputError::in_file(path, "not valid UTF-8 text"))?;
                Text::Owned(s)
            }
        })
    }

    /// A time stream straight from the text, as [`read_rows_direct`](Self::read_rows_direct)
    /// reads points: column `names[0]` (the time) into one vector and `names[1..4]` into
    /// another, one pass, in parallel segments, no row index. `Ok(Err(table))` when the file is
    /// not the plain case (a missing column, quotes, a non-ASCII or too long line, a bad value;
    /// Parquet and E57 files): the caller then takes the general path on the returned table
    /// (built from the same text), which also produces the exact error (file:line:col).
    #[allow(clippy::type_complexity)]
    pub fn read_stream_direct(
        path: &Path,
        names: &[&str; 4],
    ) -> Result<Result<(Vec<f64>, Vec<[f64; 3]>), Table>, InputError> {
        if crate::parquet_file::is_parquet(path) || crate::e57_file::is_e57(path) {
            return Self::read(path).map(Err);
        }
        Self::stream_direct(path, Self::checked_text(path)?, names)
    }

    /// [`read_stream_direct`](Self::read_stream_direct) on text already read and checked.
    #[allow(clippy::type_complexity)]
    fn stream_direct(
        path: &Path,
        text: Text,
        names: &[&str; 4],
    ) -> Result<Result<(Vec<f64>, Vec<[f64; 3]>), Table>, InputError> {
        let text = text.with_lf_lines();
        let (header, _, data) = Self::head(path, &text)?;
        let idx: Option<Vec<usize>> = names.iter().map(|n| header.iter().position(|h| h == n)).collect();
        let rows = match idx {
            Some(idx) => direct_streams(&text.as_bytes()[data..], header.len(), &idx),
            None => None,
        };
        match rows {
            Some(r) => Ok(Ok(r)),
            None => Self::from_text(path, text).map(Err),
        }
    }

    /// [`read_rows_direct`](Self::read_rows_direct) on text already read and checked.
    fn rows_direct<const K: usize>(
        path: &Path,
        text: Text,
        names: &[&str; K],
    ) -> Result<Result<Vec<[f64; K]>, Table>, InputError> {
        Self::rows_direct_into(path, text, names, None)
    }

    /// [`rows_direct`](Self::rows_direct) into `out` when its capacity suffices, with the
    /// text's `segments` (from [`check_counted`](Self::check_counted)) when known.
    fn rows_direct_into<const K: usize>(
        path: &Path,
        text: Text,
        names: &[&str; K],
        segments: Option<Segments>,
    ) -> Result<Result<Vec<[f64; K]>, Table>, InputError> {
        let text = text.with_lf_lines();
        let (header, _, data) = Self::head(path, &text)?;
        let idx: Option<Vec<usize>> = names.iter().map(|n| header.iter().position(|h| h == n)).collect();
        let plain = !header.iter().any(|h| h == "id");
        let rows = match idx {
            Some(idx) if plain => {
                let bytes = text.as_bytes();
                let segments = segments.map(|s| s.after(bytes, data));
                direct_rows::<K>(&bytes[data..], header.len(), &idx, segments)
            }
            _ => None,
        };
        match rows {
            Some(r) => {
                text.release();
                Ok(Ok(r))
            }
            None => Self::from_text(path, text).map(Err),
        }
    }

    /// Number of data rows.
    pub fn n_rows(&self) -> usize {
        self.rows.len()
    }

    /// Index of a column by name.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Index of a required column, or an error naming it.
    pub fn require(&self, name: &str) -> Result<usize, InputError> {
        self.column(name).ok_or_else(|| {
            InputError::at(
                &self.path,
                self.header_line(),
                None,
                missing_column_message(&self.path, name, &self.header),
            )
        })
    }

    /// 1-based line number of the header.
    pub fn header_line(&self) -> usize {
        // The header is the line before the first data row, or found by scanning.
        for (line, l) in (1..).zip(self.text.lines()) {
            let t = l.trim_start().trim_start_matches('\u{feff}');
            if !t.is_empty() && !t.starts_with('#') {
                return line;
            }
        }
        1
    }

    /// 1-based line number of data row `row`.
    pub fn line_number(&self, row: usize) -> usize {
        line_of(&self.text, self.rows[row])
    }

    /// The raw text of data row `row` (without line ending).
    pub fn row_text(&self, row: usize) -> &str {
        let s = self.rows[row];
        let b = self.text.as_bytes();
        let e = memchr::memchr(b'\n', &b[s..]).map_or(b.len(), |p| s + p);
        trim_line(&self.text[s..e])
    }

    /// The fields of data row `row`, checked against the header width.
    pub fn fields<'a>(
        &'a self,
        row: usize,
        buf: &mut Vec<(usize, usize)>,
    ) -> Result<Vec<&'a str>, InputError> {
        let line = self.row_text(row);
        split_fields(line, buf);
        if buf.len() != self.header.len() {
            return Err(self.ragged(row, buf.len()));
        }
        Ok(buf.iter().map(|&(a, b)| &line[a..b]).collect())
    }

    fn ragged(&self, row: usize, got: usize) -> InputError {
        InputError::at(
            &self.path,
            self.line_number(row),
            Some(got.min(self.header.len()) + 1),
            format!("ragged row: {got} fields, the header has {}", self.header.len()),
        )
    }

    /// Parse the named columns of every row as finite `f64`, row-major (`k` values per row).
    /// Rows are parsed in parallel; the first bad row (in file order) is reported.
    pub fn f64_columns(&self, names: &[&str]) -> Result<Vec<f64>, InputError> {
        let idx: Vec<usize> = names.iter().map(|n| self.require(n)).collect::<Result<_, _>>()?;
        self.f64_columns_at(&idx)
    }

    /// As [`f64_columns`](Self::f64_columns) with column indices.
    pub fn f64_columns_at(&self, idx: &[usize]) -> Result<Vec<f64>, InputError> {
        let mut out = vec![0.0; self.rows.len() * idx.len()];
        self.parse_into(idx, &mut out)?;
        Ok(out)
    }

    /// Parse columns `idx` of every row into `out` (row-major, `idx.len()` values per row).
    fn parse_into(&self, idx: &[usize], out: &mut [f64]) -> Result<(), InputError> {
        let rows = Rows { text: self.text.as_bytes(), rows: &self.rows, width: self.header.len() };
        rows.parse_into(idx, out)
            .map_err(|e| e.into_input_error(&self.path, &self.header, |r| self.line_number(r)))
    }

    /// As [`f64_columns`](Self::f64_columns), one `[f64; K]` per row, parsed in place (no
    /// copy: `Vec<[f64; 3]>` maps to `Vec<Point3>` in place).
    pub fn f64_rows<const K: usize>(&self, names: &[&str; K]) -> Result<Vec<[f64; K]>, InputError> {
        let idx: Vec<usize> = names.iter().map(|n| self.require(n)).collect::<Result<_, _>>()?;
        let mut out = vec![[0.0; K]; self.rows.len()];
        self.parse_into(&idx, out.as_flattened_mut())?;
        Ok(out)
    }

    /// One numeric column.
    pub fn f64_column(&self, name: &str) -> Result<Vec<f64>, InputError> {
        self.f64_columns(&[name])
    }

    /// One text column (fields as written, quotes removed).
    pub fn str_column(&self, name: &str) -> Result<Vec<String>, InputError> {
        let col = self.require(name)?;
        let mut buf = Vec::new();
        (0..self.rows.len()).map(|r| self.fields(r, &mut buf).map(|f| f[col].to_string())).collect()
    }

    /// Check that every row has as many fields as the header.
    pub fn check_rectangular(&self) -> Result<(), InputError> {
        self.f64_columns_at(&[]).map(|_| ())
    }
}

/// A bad row found by [`Rows::parse_into`]: row index, column (`usize::MAX`: ragged, with the
/// field count in `text`) and the offending text.
#[derive(Debug)]
pub(crate) struct RowError {
    pub row: usize,
    pub col: usize,
    pub text: String,
}

impl RowError {
    /// The located input error (`line_of` gives the 1-based line of a row).
    pub(crate) fn into_input_error(
        self,
        path: &Path,
        header: &[String],
        line_of: impl Fn(usize) -> usize,
    ) -> InputError {
        let line = line_of(self.row);
        if self.col == usize::MAX {
            let got: usize = self.text.parse().unwrap_or(0);
            return InputError::at(
                path,
                line,
                Some(got.min(header.len()) + 1),
                format!("ragged row: {got} fields, the header has {}", header.len()),
            );
        }
        let s = self.text;
        let what = if s.is_empty() {
            "empty value where a number is required".to_string()
        } else if s.parse::<f64>().is_ok() {
            format!("not a finite number: '{s}'")
        } else {
            let mut m = format!("not a number: '{}'", s.chars().take(40).collect::<String>());
            if let Some(h) = value_hint(&s) {
                m.push_str(&format!(" ({h})"));
            }
            m
        };
        InputError::at(path, line, Some(self.col + 1), what).with_column_name(header[self.col].clone())
    }
}

/// Data rows of CSV text: the text, the start offset of each row, the header width.
pub(crate) struct Rows<'a> {
    pub text: &'a [u8],
    pub rows: &'a [usize],
    pub width: usize,
}

impl Rows<'_> {
    /// Bytes of row `r` without the line ending.
    #[inline]
    fn line(&self, r: usize) -> &[u8] {
        let s0 = self.rows[r];
        let e0 = memchr::memchr(b'\n', &self.text[s0..]).map_or(self.text.len(), |p| s0 + p);
        match &self.text[s0..e0] {
            [l @ .., b'\r'] => l,
            l => l,
        }
    }

    /// Parse columns `idx` of every row into `out` (row-major), rows in parallel chunks; the
    /// first bad row in file order is reported.
    pub(crate) fn parse_into(&self, idx: &[usize], out: &mut [f64]) -> Result<(), RowError> {
        let k = idx.len();
        let n = self.rows.len();
        debug_assert_eq!(out.len(), n * k);
        const CHUNK: usize = 8 * 1024;
        let slots = self.slots(idx);
        let work = |c: usize, dst: &mut [f64]| -> Option<RowError> {
            let mut buf = Vec::with_capacity(self.width);
            let first = c * CHUNK;
            self.parse_range(first..(first + CHUNK).min(n), idx, &slots, dst, &mut buf).err()
        };
        let first_error = if k == 0 {
            (0..n.div_ceil(CHUNK)).into_par_iter().filter_map(|c| work(c, &mut [])).min_by_key(|e| e.row)
        } else {
            out.par_chunks_mut(CHUNK * k)
                .enumerate()
                .filter_map(|(c, dst)| work(c, dst))
                .min_by_key(|e| e.row)
        };
        match first_error {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Column → output slot (`usize::MAX`: not wanted) of the fused fast path, for columns `idx`.
    pub(crate) fn slots(&self, idx: &[usize]) -> Vec<usize> {
        let mut slots = vec![usize::MAX; self.width];
        for (j, &c) in idx.iter().enumerate() {
            if c < self.width {
                slots[c] = j;
            }
        }
        slots
    }

    /// Rows `range` split into fields and columns `idx` parsed, in one walk over each row: the
    /// fields' byte ranges in the text (trimmed of spaces and tabs, quotes removed, as
    /// [`split_fields`] gives them) are appended to `fields`, `width` per row, and the values go
    /// to `dst` (row-major). For callers that write the rows back out with some fields replaced:
    /// the passed-through fields need no second split. The first bad row of the range is
    /// reported.
    ///
    /// Where the CPU has SSSE3 (checked at run time), rows of plain fields are split by
    /// delimiter masks and their numbers converted by vector instructions
    /// ([`split_parse_row_ssse3`]); any other row takes the portable walk.
    pub(crate) fn split_and_parse_range(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize],
        dst: &mut [f64],
        fields: &mut Vec<(usize, usize)>,
    ) -> Result<(), RowError> {
        #[cfg(target_arch = "x86_64")]
        if cpu_has_ssse3() {
            // SAFETY: the CPU has SSSE3 (checked just above).
            return unsafe { self.split_and_parse_range_ssse3(range, idx, dst, fields) };
        }
        self.split_and_parse_range_impl::<false>(range, idx, dst, fields)
    }

    /// [`split_and_parse_range`](Self::split_and_parse_range) compiled with SSSE3.
    ///
    /// # Safety
    /// The CPU must have SSSE3.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "ssse3")]
    unsafe fn split_and_parse_range_ssse3(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize],
        dst: &mut [f64],
        fields: &mut Vec<(usize, usize)>,
    ) -> Result<(), RowError> {
        self.split_and_parse_range_impl::<true>(range, idx, dst, fields)
    }

    /// The loop of [`split_and_parse_range`](Self::split_and_parse_range); `SSSE3`: rows tried
    /// by [`split_parse_row_ssse3`] first (only inside a function compiled with SSSE3).
    #[inline(always)]
    fn split_and_parse_range_impl<const SSSE3: bool>(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize],
        dst: &mut [f64],
        fields: &mut Vec<(usize, usize)>,
    ) -> Result<(), RowError> {
        let k = idx.len();
        let first = range.start;
        let mut quoted = Vec::new();
        let slots = self.slots(idx);
        for row in range {
            let s0 = self.rows[row];
            let t = &self.text[s0..];
            let base = fields.len();
            let d = &mut dst[(row - first) * k..(row - first + 1) * k];
            #[cfg(target_arch = "x86_64")]
            if SSSE3 {
                // SAFETY: with `SSSE3` this runs on a CPU with SSSE3 (see the dispatch above).
                if unsafe { split_parse_row_ssse3(self.text, s0, &slots, d, fields) } {
                    continue;
                }
                fields.truncate(base);
            }
            if split_parse_row_fast(t, s0, &slots, d, fields) {
                continue;
            }
            // Anything unusual (quotes, a bad or missing value, a ragged row): split the row
            // as the general reader does and report exactly what it would.
            fields.truncate(base);
            let n = t.len();
            let (mut start, mut i) = (0, 0);
            let mut has_quote = false;
            loop {
                while i < n {
                    let b = t[i];
                    if b == b',' || b == b'\n' {
                        break;
                    }
                    if b == b'"' {
                        has_quote = true;
                        break;
                    }
                    i += 1;
                }
                if has_quote {
                    break;
                }
                let last = i >= n || t[i] == b'\n';
                let mut e = i;
                if last && e > start && t[e - 1] == b'\r' {
                    e -= 1;
                }
                let mut a = start;
                while a < e && (t[a] == b' ' || t[a] == b'\t') {
                    a += 1;
                }
                while e > a && (t[e - 1] == b' ' || t[e - 1] == b'\t') {
                    e -= 1;
                }
                fields.push((s0 + a, s0 + e));
                if last {
                    break;
                }
                i += 1;
                start = i;
            }
            if has_quote {
                fields.truncate(base);
                let line = self.line(row);
                split_fields(std::str::from_utf8(line).unwrap_or(""), &mut quoted);
                fields.extend(quoted.iter().map(|&(a, b)| (s0 + a, s0 + b)));
            }
            let got = fields.len() - base;
            if got != self.width {
                return Err(RowError { row, col: usize::MAX, text: got.to_string() });
            }
            for (j, &col) in idx.iter().enumerate() {
                let (a, b) = fields[base + col];
                let f = &self.text[a..b];
                match crate::num::parse_f64_bytes(f) {
                    Some(v) => d[j] = v,
                    None => return Err(RowError { row, col, text: String::from_utf8_lossy(f).into_owned() }),
                }
            }
        }
        Ok(())
    }

    /// Parse columns `idx` of rows `range` into `dst` (row-major, `range.len() × idx.len()`), on
    /// the calling thread; `slots` from [`slots`](Self::slots), `buf` a scratch field list. The
    /// first bad row of the range is reported.
    pub(crate) fn parse_range(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize],
        slots: &[usize],
        dst: &mut [f64],
        buf: &mut Vec<(usize, usize)>,
    ) -> Result<(), RowError> {
        let k = idx.len();
        let first = range.start;
        for row in range {
            let d = &mut dst[(row - first) * k..(row - first + 1) * k];
            // The fast path finds the row's end itself (no search for it first).
            if parse_row_fast(&self.text[self.rows[row]..], slots, d) {
                continue;
            }
            let line = self.line(row);
            let text = std::str::from_utf8(line).unwrap_or("");
            if !split_fields_fast(line, buf) {
                split_fields(text, buf);
            }
            if buf.len() != self.width {
                return Err(RowError { row, col: usize::MAX, text: buf.len().to_string() });
            }
            for (j, &col) in idx.iter().enumerate() {
                let (a, b) = buf[col];
                let f = &line[a..b];
                match crate::num::parse_f64_bytes(f) {
                    Some(v) => d[j] = v,
                    None => return Err(RowError { row, col, text: String::from_utf8_lossy(f).into_owned() }),
                }
            }
        }
        Ok(())
    }
}

pub use crate::num::parse_f64;

/// Write CSV rows with a header; floats in shortest round-trip form (or a fixed number of
/// decimals, [`CsvWriter::with_format`]). The fields of a row are gathered in memory and written
/// with one call at [`end_row`](CsvWriter::end_row) (an unfinished row at
/// [`into_inner`](CsvWriter::into_inner)).
pub struct CsvWriter<W: Write> {
    w: W,
    first: bool,
    fmt: NumFormat,
    row: Vec<u8>,
}

impl<W: Write> CsvWriter<W> {
    /// A writer on `w` that formats numbers in the shortest round-trip form.
    pub fn new(w: W) -> Self {
        Self { w, first: true, fmt: NumFormat::Shortest, row: Vec::with_capacity(256) }
    }
    /// How numbers are written.
    pub fn with_format(mut self, fmt: NumFormat) -> Self {
        self.fmt = fmt;
        self
    }
    /// The number format in use (set by [`CsvWriter::with_format`]).
    pub fn format(&self) -> NumFormat {
        self.fmt
    }
    /// Write `# text` comment lines (before the header).
    pub fn comment(&mut self, text: &str) -> std::io::Result<()> {
        writeln!(self.w, "# {text}")
    }
    /// Write the header row (column names joined by commas).
    pub fn header(&mut self, names: &[&str]) -> std::io::Result<()> {
        writeln!(self.w, "{}", names.join(","))
    }
    #[inline]
    fn sep(&mut self) {
        if !self.first {
            self.row.push(b',');
        }
        self.first = false;
    }
    /// Append one field to the current row.
    pub fn field_str(&mut self, s: &str) -> std::io::Result<()> {
        self.sep();
        push_field(&mut self.row, s);
        Ok(())
    }
    /// Append one number to the current row, formatted by the writer's [`NumFormat`].
    #[inline]
    pub fn field_f64(&mut self, v: f64) -> std::io::Result<()> {
        self.sep();
        self.fmt.write(v, &mut self.row);
        Ok(())
    }
    /// Append a raw, already formatted CSV fragment (e.g. a passed-through row).
    pub fn raw(&mut self, s: &str) -> std::io::Result<()> {
        self.sep();
        self.row.extend_from_slice(s.as_bytes());
        Ok(())
    }
    /// Finish the current row (newline) and write it.
    pub fn end_row(&mut self) -> std::io::Result<()> {
        self.first = true;
        self.row.push(b'\n');
        let r = self.w.write_all(&self.row);
        self.row.clear();
        r
    }
    /// Write a whole row of numbers.
    pub fn row_f64(&mut self, v: &[f64]) -> std::io::Result<()> {
        for x in v {
            self.field_f64(*x)?;
        }
        self.end_row()
    }
    /// The inner writer (after writing the fields of an unfinished row, if any; a failure of
    /// that last write shows when the caller flushes or writes next).
    pub fn into_inner(mut self) -> W {
        if !self.row.is_empty() {
            let _ = self.w.write_all(&self.row);
        }
        self.w
    }
}

/// Append `s` to `out` as one CSV field: quoted (inner quotes doubled) when it holds a comma or
/// a quote, as is otherwise.
#[inline]
pub fn push_field(out: &mut Vec<u8>, s: &str) {
    if s.as_bytes().iter().any(|&b| b == b',' || b == b'"') {
        out.push(b'"');
        for &b in s.as_bytes() {
            if b == b'"' {
                out.push(b'"');
            }
            out.push(b);
        }
        out.push(b'"');
    } else {
        out.extend_from_slice(s.as_bytes());
    }
}

/// Format `n` rows in parallel: `row(r, w)` writes row `r` (fields and `end_row`) into an
/// in-memory writer; the pieces come back in row order, ready to be written one after another.
/// This is how large outputs are written at the speed of the cores rather than of one.
pub fn format_rows_parallel<F, E>(n: usize, fmt: NumFormat, row: F) -> Result<Vec<Vec<u8>>, E>
where
    F: Fn(usize, &mut CsvWriter<Vec<u8>>) -> Result<(), E> + Sync,
    E: Send,
{
    const ROWS: usize = 8 * 1024;
    (0..n.div_ceil(ROWS))
        .into_par_iter()
        .map(|c| {
            let mut w = CsvWriter::new(Vec::with_capacity(ROWS * 48)).with_format(fmt);
            for r in c * ROWS..((c + 1) * ROWS).min(n) {
                row(r, &mut w)?;
            }
            Ok(w.into_inner())
        })
        .collect()
}

/// The readers' kernels one by one, for the criterion bench `crates/io/benches/readers.rs`
/// (the decision whether each hand-written kernel is worth keeping is measured there). Not part
/// of the API: hidden from the docs, may change with any commit.
#[doc(hidden)]
pub mod kernels {
    /// Bytes a short-decimal kernel may read from the start of a number.
    pub const READ: usize = super::SHORT_DECIMAL_READ;

    /// The portable SWAR short decimal (`super::swar`); `None` if `b` is shorter than [`READ`].
    pub fn short_decimal_swar(b: &[u8]) -> Option<(f64, usize)> {
        (b.len() >= READ).then(|| super::short_decimal_prefix(b)).flatten()
    }

    /// The SSSE3 short decimal; `None` without SSSE3 or if `b` is shorter than [`READ`].
    pub fn short_decimal_ssse3(b: &[u8]) -> Option<(f64, usize)> {
        #[cfg(target_arch = "x86_64")]
        if super::cpu_has_ssse3() && b.len() >= READ {
            // SAFETY: the CPU has SSSE3 (checked) and `b` holds the bytes the kernel reads.
            return unsafe { super::short_decimal_ssse3(b) };
        }
        let _ = b;
        None
    }

    /// Plain rows of three numbers (`x,y,z\n`, short decimals) of one segment into `out` by the
    /// SSSE3 plain-row loop (delimiter masks of 64-byte blocks), its numbers converted by the
    /// SSSE3 kernel (`swar_numbers` false, what the readers run) or by the portable SWAR one;
    /// the rows read. `None` without SSSE3. A bench hook: the loop stops at the first row that
    /// is not plain, and near the end of the segment (the readers go on with their general loop).
    pub fn plain_rows3(seg: &[u8], swar_numbers: bool, out: &mut Vec<[f64; 3]>) -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if super::cpu_has_ssse3() {
            let put = |_: usize, d: [f64; 3]| out.push(d);
            // SAFETY: the CPU has SSSE3 (checked).
            let (n, _) = unsafe {
                if swar_numbers {
                    super::x86::plain_rows_masks_swar::<3>(seg, 0, usize::MAX, put)
                } else {
                    super::x86::plain_rows_ssse3::<3>(seg, 0, usize::MAX, put)
                }
            };
            return Some(n);
        }
        let _ = (seg, swar_numbers, out);
        None
    }

    /// Rows of three numbers of one segment (text of whole lines) into `out`, by the readers'
    /// own loop: `simd` the SSSE3 copy where the CPU has it, else the portable one. The rows
    /// read, or `None` at a row the fast path leaves to the general one.
    pub fn rows3(seg: &[u8], simd: bool, out: &mut Vec<[f64; 3]>) -> Option<usize> {
        let slots = [0usize, 1, 2];
        let put = |_: usize, d: [f64; 3]| out.push(d);
        let r = if simd && super::cpu_has_ssse3() {
            super::parse_segment_best::<3>(seg, &slots, usize::MAX, put)
        } else {
            super::parse_segment::<3, false>(seg, &slots, usize::MAX, put)
        };
        r.map(|(n, _)| n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(s: &str) -> Result<Table, InputError> {
        Table::from_bytes("t.csv", s.as_bytes().to_vec())
    }

    #[test]
    fn comments_any_order_unknown_columns() {
        let t = table("# unit_load_n = 1000\n# second\nz_mm, id ,x_mm,y_mm,extra\n3,\"a,b\",1,2,keep\r\n\n6,b,4,5,keep2\n").unwrap();
        assert_eq!(t.comments, vec!["unit_load_n = 1000", "second"]);
        assert_eq!(t.header, vec!["z_mm", "id", "x_mm", "y_mm", "extra"]);
        assert_eq!(t.f64_columns(&["x_mm", "y_mm", "z_mm"]).unwrap(), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(t.str_column("id").unwrap(), vec!["a,b", "b"]);
        assert_eq!(t.row_text(1), "6,b,4,5,keep2");
        assert_eq!(t.line_number(1), 6);
    }

    #[test]
    fn errors_name_line_and_column() {
        let t = table("x_mm,y_mm,z_mm\n1,2,3\n1,abc,3\n").unwrap();
        let e = t.f64_columns(&["x_mm", "y_mm", "z_mm"]).unwrap_err();
        assert_eq!((e.line, e.column), (Some(3), Some(2)));
        assert!(e.to_string().contains("y_mm") && e.to_string().contains("abc"), "{e}");

        let t = table("x_mm,y_mm,z_mm\n1,2,NaN\n").unwrap();
        let e = t.f64_columns(&["x_mm", "y_mm", "z_mm"]).unwrap_err();
        assert_eq!((e.line, e.column), (Some(2), Some(3)));
        assert!(e.to_string().contains("finite"));

        let t = table("x_mm,y_mm,z_mm\n1,2,3\n1,2\n").unwrap();
        let e = t.f64_columns(&["x_mm"]).unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("ragged"));

        let t = table("# c\nx_mm,y_mm\n1,2\n").unwrap();
        let e = t.f64_columns(&["x_mm", "y_mm", "z_mm"]).unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("z_mm"));

        assert!(table("").is_err());
        assert!(table("# only comments\n\n").is_err());
        assert!(Table::from_bytes("b.bin", vec![0x7f, 0x45, 0x4c, 0x46, 0, 1, 2])
            .unwrap_err()
            .to_string()
            .contains("binary"));
        assert!(Table::from_bytes("b.bin", vec![b'a', 0xff, 0xfe, b'\n'])
            .unwrap_err()
            .to_string()
            .contains("UTF-8"));
    }

    #[test]
    fn large_files_are_mapped_and_checked_like_small_ones() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.csv");
        let mut text = String::from("# big\nx_mm,y_mm,z_mm\n");
        let n = 400_000;
        for i in 0..n {
            text.push_str(&format!("{i}.125,{}.5,-{i}.0625\n", i % 7));
        }
        assert!(text.len() > 8 << 20);
        std::fs::write(&p, &text).unwrap();
        let t = Table::read(&p).unwrap();
        let v = t.f64_columns(&["x_mm", "y_mm", "z_mm"]).unwrap();
        assert_eq!(v.len(), 3 * n);
        assert_eq!(
            &v[3 * (n - 1)..],
            &[(n - 1) as f64 + 0.125, ((n - 1) % 7) as f64 + 0.5, -((n - 1) as f64) - 0.0625]
        );
        // A bad value deep in the mapped file: located by line.
        let bad = text.replacen("123456.125", "123456.1x5", 1);
        std::fs::write(&p, &bad).unwrap();
        let e = Table::read(&p).unwrap().f64_columns(&["x_mm"]).unwrap_err();
        assert_eq!(e.line, Some(123456 + 3));
        // A NUL byte: not a text file, named at its line (segments are checked in parallel).
        let mut bin = text.into_bytes();
        let line_at = |b: &[u8], at: usize| b[..at].iter().filter(|&&c| c == b'\n').count() + 1;
        let mut bad_utf8 = bin.clone();
        bad_utf8[7_000_000] = 0xff;
        bad_utf8[9_000_000] = 0xff;
        std::fs::write(&p, &bad_utf8).unwrap();
        let e = Table::read(&p).unwrap_err();
        assert!(e.to_string().contains("UTF-8"), "{e}");
        assert_eq!(e.line, Some(line_at(&bad_utf8, 7_000_000)));
        bin[9_500_000] = 0;
        bin[5_000_000] = 0;
        bin[6_000_000] = 0xff;
        std::fs::write(&p, &bin).unwrap();
        let e = Table::read(&p).unwrap_err();
        assert!(e.to_string().contains("binary"), "{e}");
        assert_eq!(e.line, Some(line_at(&bin, 5_000_000)));
    }

    /// The direct read of a mapped file checks the text only where its row parser did not see
    /// plain ASCII rows, and reports exactly what `Table::read` reports: a NUL byte or invalid
    /// UTF-8 in a comment deep in the file (the rows themselves parse) is an error at its line;
    /// valid non-ASCII text in a comment is fine; bad bytes in a row, and a header after more
    /// than a segment of comments, take the general path with the same result.
    #[test]
    fn mapped_direct_rows_check_the_text_where_the_parse_did_not() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.csv");
        let names = ["x_mm", "y_mm", "z_mm"];
        let mut text = String::from("# big\nx_mm,y_mm,z_mm\n");
        let mut i = 0u64;
        while text.len() < 9 << 20 {
            if i == 200_000 {
                text.push_str("# a comment: COMMENT_HERE\n");
            }
            text.push_str(&format!("{}.{:03},-{}.5,{}\n", i % 997, i % 1000, i % 13, i));
            i += 1;
        }
        let at = text.find("COMMENT_HERE").unwrap();
        let line_at = |b: &[u8], at: usize| b[..at].iter().filter(|&&c| c == b'\n').count() + 1;
        let direct = |bytes: &[u8]| {
            std::fs::write(&p, bytes).unwrap();
            Table::read_rows_direct(&p, &names)
        };
        let general = |bytes: &[u8]| {
            std::fs::write(&p, bytes).unwrap();
            Table::read(&p).and_then(|t| t.f64_rows(&names))
        };
        // Plain, and with valid UTF-8 in the comment: the direct rows, as the general path's.
        let good = text.replace("COMMENT_HERE", "été µm");
        let d = direct(good.as_bytes()).unwrap().expect("direct");
        assert_eq!(d, general(good.as_bytes()).unwrap());
        assert_eq!(d.len() as u64, i);
        // A NUL byte or an invalid byte in the comment: the text error of `Table::read`.
        for (byte, what) in [(0u8, "binary"), (0xff, "UTF-8")] {
            let mut b = text.clone().into_bytes();
            b[at] = byte;
            let e = direct(&b).unwrap_err();
            assert!(e.to_string().contains(what), "{e}");
            assert_eq!(e.line, Some(line_at(&b, at)));
            assert_eq!(e.to_string(), general(&b).unwrap_err().to_string());
        }
        // The same bytes in a row: the general path, the same error.
        let row = text.find("\n5.005,").unwrap() + 2;
        for byte in [0u8, 0xff] {
            let mut b = text.clone().into_bytes();
            b[row] = byte;
            let e = direct(&b).unwrap_err();
            assert_eq!(e.to_string(), general(&b).unwrap_err().to_string());
        }
        // The header after 2 MiB of comments (not in the first segment): still read.
        let late = format!("{}{}", "# padding\n".repeat(200_000), text);
        let d = direct(late.as_bytes()).unwrap().expect("direct or general rows");
        assert_eq!(d, general(late.as_bytes()).unwrap());
    }

    #[test]
    fn writer_round_trips_floats() {
        let mut w = CsvWriter::new(Vec::new());
        w.header(&["a", "b"]).unwrap();
        w.row_f64(&[0.1 + 0.2, -1e-300]).unwrap();
        let s = String::from_utf8(w.into_inner()).unwrap();
        let t = table(&s).unwrap();
        assert_eq!(t.f64_columns(&["a", "b"]).unwrap(), vec![0.1 + 0.2, -1e-300]);
    }

    #[test]
    fn parallel_row_index_matches_serial() {
        // > 1 MiB so the parallel path runs; blank, comment, CRLF and non-ASCII lines mixed in.
        let mut s = String::from("# c\nx_mm,y_mm,z_mm\n");
        for i in 0..80_000 {
            match i % 97 {
                0 => s.push('\n'),
                1 => s.push_str("  # later comment\n"),
                2 => s.push_str("\u{a0}\r\n"),
                _ => s.push_str(&format!("{i}.25,{},-{i}\r\n", i * 2)),
            }
        }
        let t = table(&s).unwrap();
        let start = s.find("x_mm").unwrap();
        let from = start + s[start..].find('\n').unwrap() + 1;
        let mut serial = Vec::new();
        assert_eq!(index_rows(&s, from, s.len(), &mut serial), None);
        assert_eq!(t.rows, serial);
        // i % 97 ∈ {0, 1, 2} for 825 values of i each.
        assert_eq!(t.n_rows(), 80_000 - 3 * 825);
        let v = t.f64_rows(&["x_mm", "y_mm", "z_mm"]).unwrap();
        assert!(s.len() > 1 << 20);
        assert_eq!(v[0], [3.25, 6.0, -3.0]);
    }

    /// The direct reader gives the general path's rows bit for bit (several parallel segments,
    /// comments, blank and CRLF lines, extra columns in any order), and on anything it does not
    /// take it hands back the table, whose error is today's (line and column).
    /// Regression (found by the `csv_rewrite` fuzz target): a header on the last line without a
    /// line end panicked (slice past the end) in every reader; it is a table without rows.
    #[test]
    fn header_without_line_end_is_an_empty_table() {
        for text in ["x_mm,y_mm,z_mm", "# c\n\nx_mm,y_id,x_,mmmm,zy", "\u{feff}x_mm,y_mm,z_mm\r"] {
            let t = table(text).unwrap();
            assert_eq!(t.n_rows(), 0, "{text:?}");
            let direct = Table::rows_direct(
                Path::new("t.csv"),
                Text::Owned(text.to_string()),
                &["x_mm", "y_mm", "z_mm"],
            );
            match direct {
                Ok(Ok(rows)) => assert!(rows.is_empty()),
                Ok(Err(t)) => assert_eq!(t.n_rows(), 0),
                Err(e) => assert!(e.to_string().contains("t.csv"), "{e}"),
            }
        }
    }

    #[test]
    fn split_and_parse_matches_the_general_reader_row_by_row() {
        // Rows the fast path takes and rows it hands to the general one: the values, every
        // field's text and the first error (row, column) agree with `Table`'s general reader.
        let rows = [
            "P1,1.5,2,3,ok",
            "  P2 , 1.25 ,\t-2\t,3e2,  spaced  ",
            "P3,1,2,3,crlf\r",
            "\"P,4\",1,2,3,\"q\"\"x\"",
            "P5,\"7.5\",2,3,",
            "P6,1,2,3,a\rb",
            "P7,.5,-0.,+4,ab\"c",
            "P8,1,2,3,x,extra",
            "P9,1,2",
            "P10,1,abc,3,x",
            "P11,1,2 3,3,x",
            "P12,,2,3,x",
            "P13,12345678.5,2.123456789,3,x",
            "P14,1.5,2,3,x,",
            "P15,1.5,2,3",
            "P16,-7.25,+8.,.5,nöte",
            "P17,1.5,2,3,x,y,z,w,v,u,t,s,r,q,p,o,n,m,l,k,j,i,h,g,f,e,d,c,b,a,0123456789",
        ];
        for (k, row) in rows.iter().enumerate() {
            // A comment line after the row (skipped by every reader) leaves the text long
            // enough for the SSSE3 row reader's block reads, so that it is tested too.
            let text = format!("id,x_mm,y_mm,z_mm,note\n{row}\n# {}\n", "pad ".repeat(30));
            let t = table(&text).unwrap();
            let general = t.f64_rows(&["x_mm", "y_mm", "z_mm"]);
            let view = Rows { text: t.text.as_bytes(), rows: &t.rows, width: t.header.len() };
            let (mut d, mut f) = (vec![0.0; 3], Vec::new());
            let fast = view.split_and_parse_range(0..1, &[1, 2, 3], &mut d, &mut f);
            match (general, fast) {
                (Ok(g), Ok(())) => {
                    assert_eq!(g[0].to_vec(), d, "row {k}");
                    let mut buf = Vec::new();
                    let want = t.fields(0, &mut buf).unwrap();
                    let got: Vec<&str> = f.iter().map(|&(a, b)| &t.text[a..b]).collect();
                    assert_eq!(want, got, "row {k}");
                }
                (Err(g), Err(e)) => {
                    let e = e.into_input_error(Path::new("t.csv"), &t.header, |r| t.line_number(r));
                    assert_eq!((g.line, g.column), (e.line, e.column), "row {k}: {g} / {e}");
                }
                (g, e) => panic!("row {k}: general {g:?}, fast {e:?}"),
            }
        }
    }

    #[test]
    fn direct_rows_match_the_general_path() {
        let names = ["x_mm", "y_mm", "z_mm"];
        let direct = |s: &str| Table::rows_direct(Path::new("t.csv"), Text::Owned(s.to_string()), &names);
        let general = |s: &str| table(s).and_then(|t| t.f64_rows(&names));
        let mut s = String::from("\u{feff}# c\nnote,z_mm,y_mm,x_mm\n");
        for i in 0..120_000u64 {
            let v = i as f64 * 0.123_456_789;
            match i % 997 {
                0 => s.push_str("\n   \n# later comment\n"),
                1 => s.push_str(&format!("n{i},{v:e},{},-{}.5\r\n", i, i % 13)),
                _ => s.push_str(&format!("n{i}, {v} ,{:.6},{}\n", v / 7.0, i)),
            }
        }
        s.push_str("last,1,2,3");
        assert!(s.len() > 2 << 20, "needs several segments: {}", s.len());
        let d = direct(&s).unwrap().expect("plain file takes the direct path");
        let g = general(&s).unwrap();
        assert_eq!(d.len(), g.len());
        assert!(d.iter().flatten().zip(g.iter().flatten()).all(|(a, b)| a.to_bits() == b.to_bits()));
        // Not plain: a quoted field, an id column, a bad value late in the file, a ragged row,
        // a missing column. The table comes back and reports as before.
        let bad = format!("{s}\n1,2,x,4\n");
        let e = direct(&bad).unwrap().expect_err("general path").f64_rows(&names).unwrap_err();
        let e0 = general(&bad).unwrap_err();
        assert_eq!((e.line, e.column), (e0.line, e0.column));
        assert_eq!(e.line, Some(s.lines().count() + 1));
        assert_eq!(e.column, Some(3));
        for other in [
            "x_mm,y_mm,z_mm\n1,2,3\n\"4\",5,6\n",
            "id,x_mm,y_mm,z_mm\na,1,2,3\n",
            "x_mm,y_mm,z_mm\n1,2,3\n1,2\n",
            "x_mm,y_mm\n1,2\n",
            "x_mm,y_mm,z_mm\n1,2,3\n\u{e9}1,2,3\n",
        ] {
            let t = direct(other).unwrap().expect_err("general path");
            let g = general(other);
            match (t.f64_rows(&names), g) {
                (Ok(a), Ok(b)) => assert_eq!(a, b),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                (a, b) => panic!("{other:?}: {a:?} vs {b:?}"),
            }
        }
        assert!(direct("x_mm,y_mm,z_mm\n").unwrap().unwrap().is_empty());
    }

    /// A large (mapped) file read directly, into the output prepared while it was mapped or,
    /// when its first 64 KiB have longer lines than the rest (more rows than estimated), into
    /// a new one: the general path's rows either way; a bad value still comes back as the table.
    #[test]
    fn mapped_direct_rows_match_the_general_path() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.csv");
        let names = ["x_mm", "y_mm", "z_mm"];
        for long_start in [false, true] {
            let mut s = String::from("x_mm,note,y_mm,z_mm\n");
            let mut i = 0u64;
            while s.len() < (9 << 20) {
                let note = if long_start && s.len() < (80 << 10) { "n".repeat(200) } else { String::new() };
                s.push_str(&format!("{}.{:03},{note},-{}.5,{}\n", i % 997, i % 1000, i % 13, i));
                i += 1;
            }
            std::fs::write(&p, &s).unwrap();
            let d = Table::read_rows_direct(&p, &names).unwrap().expect("plain file takes the direct path");
            let g = Table::read(&p).unwrap().f64_rows(&names).unwrap();
            assert_eq!(d.len(), i as usize);
            assert!(d.iter().flatten().zip(g.iter().flatten()).all(|(a, b)| a.to_bits() == b.to_bits()));
            let bad = s.replacen("\n5.005,", "\n5.0x5,", 1);
            std::fs::write(&p, &bad).unwrap();
            let e = Table::read_rows_direct(&p, &names)
                .unwrap()
                .expect_err("table")
                .f64_rows(&names)
                .unwrap_err();
            assert_eq!((e.line, e.column), (Some(7), Some(1)));
        }
        // An `id` column: the table comes back.
        let mut s = String::from("id,x_mm,y_mm,z_mm\n");
        let mut i = 0u64;
        while s.len() < (9 << 20) {
            s.push_str(&format!("p{i},{}.25,{},-{}\n", i % 101, i % 7, i));
            i += 1;
        }
        std::fs::write(&p, &s).unwrap();
        let t = Table::read_rows_direct(&p, &names).unwrap().expect_err("id column: the table");
        assert_eq!(t.f64_rows(&names).unwrap()[5], [5.25, 5.0, -5.0]);
    }

    /// The segments counted while checking, cut down to the data after the header (which may
    /// start beyond the first segment), hold the lines `direct_segments` finds there, and
    /// parse to the same rows.
    #[test]
    fn counted_segments_match_direct_segments() {
        let names = ["x_mm", "y_mm", "z_mm"];
        for comment_bytes in [10, 700 << 10] {
            let mut s = String::new();
            while s.len() < comment_bytes {
                s.push_str("# a comment line before the header\n");
            }
            s.push_str("x_mm,y_mm,z_mm\n");
            for i in 0..120_000u64 {
                s.push_str(&format!("{i}.5,{},-{}.25\n", i % 11, i % 7));
            }
            s.push_str("1,2,3");
            let bytes = s.as_bytes();
            let segments = Table::check_counted(Path::new("t.csv"), bytes, true).unwrap();
            // At least four per thread (`line_segments`): four on a one-core machine.
            assert!(segments.lines.len() >= 4, "several segments");
            let (_, _, data) = Table::head(Path::new("t.csv"), &s).unwrap();
            let (bounds, lines, total) = segments.after(bytes, data);
            let (b0, _, t0) = direct_segments(&bytes[data..]);
            assert_eq!(total, t0);
            assert_eq!(total, 120_001);
            assert_eq!(
                (bounds[0], bounds.last(), b0.last()),
                (0, Some(&(s.len() - data)), Some(&(s.len() - data)))
            );
            assert_eq!(lines.len() + 1, bounds.len());
            let idx = [0, 1, 2];
            let a = direct_rows::<3>(&bytes[data..], 3, &idx, Some((bounds, lines, total))).unwrap();
            let b = direct_rows::<3>(&bytes[data..], 3, &idx, None).unwrap();
            let g = table(&s).unwrap().f64_rows(&names).unwrap();
            assert_eq!(a, b);
            assert_eq!(a, g);
        }
    }

    /// The direct stream reader gives the general path's columns bit for bit, and hands back
    /// the table (with today's error) on anything it does not take.
    #[test]
    fn direct_streams_match_the_general_path() {
        let names = ["t_s", "x_mm", "y_mm", "z_mm"];
        let direct = |s: &str| Table::stream_direct(Path::new("m.csv"), Text::Owned(s.to_string()), &names);
        let mut s = String::from("# machine\nz_mm,t_s,other,x_mm,y_mm\n");
        for i in 0..150_000u64 {
            let t = i as f64 * 0.001;
            match i % 1009 {
                0 => s.push_str("\n# gap\n"),
                1 => s.push_str(&format!("{},{t:.8},a,{}.25,{:e}\r\n", i % 7, i, t * 3.0)),
                _ => s.push_str(&format!("{:.8},{t:.8},b,{:.8},{}\n", t / 3.0, t * 250.0, 0.1 * t)),
            }
        }
        assert!(s.len() > 2 << 20, "needs several segments: {}", s.len());
        let (t, v) = direct(&s).unwrap().expect("plain file takes the direct path");
        let g = Table::from_bytes("m.csv", s.clone().into_bytes()).unwrap().f64_rows(&names).unwrap();
        assert_eq!(t.len(), g.len());
        assert_eq!(v.len(), g.len());
        for (k, row) in g.iter().enumerate() {
            assert_eq!(t[k].to_bits(), row[0].to_bits());
            assert_eq!(v[k].map(f64::to_bits), [row[1], row[2], row[3]].map(f64::to_bits));
        }
        let bad = format!("{s}1,2,b,x,5\n");
        let e = direct(&bad).unwrap().expect_err("general path").f64_rows(&names).unwrap_err();
        assert_eq!(e.line, Some(s.lines().count() + 1));
        assert_eq!(e.column, Some(4));
        let t = direct("t_s,x_mm,y_mm\n1,2,3\n").unwrap().expect_err("missing column");
        assert!(t.f64_rows(&names).is_err());
        let (t, v) = direct("t_s,x_mm,y_mm,z_mm\n").unwrap().unwrap();
        assert!(t.is_empty() && v.is_empty());
    }

    #[test]
    fn check_rectangular_finds_ragged_rows() {
        let t = table("a,b\n1,2\n3\n").unwrap();
        assert_eq!(t.check_rectangular().unwrap_err().line, Some(3));
        assert!(table("a,b\n1,2\n3,4\n").unwrap().check_rectangular().is_ok());
    }

    #[test]
    fn rows_match_columns() {
        let t = table("x_mm,y_mm,z_mm\n1,2,3\n# later comment\n\n4,5,6\n").unwrap();
        assert_eq!(t.f64_rows(&["z_mm", "x_mm"]).unwrap(), vec![[3.0, 1.0], [6.0, 4.0]]);
        let e = table("x_mm\n1\nq\n").unwrap().f64_rows(&["x_mm"]).unwrap_err();
        assert_eq!((e.line, e.column), (Some(3), Some(1)));
    }

    #[test]
    fn fast_float_path_edge_cases_match_std() {
        for s in [
            "0",
            "-0",
            "-0.0",
            "+1.5",
            "123456789012345",
            "0.000000000000001",
            "9999999999999.99",
            "1.",
            ".5",
            "-.5",
            "00012.500",
            "0.1",
            "1.7976931348623157",
            "12.7000015",
        ] {
            let want: f64 = s.parse().unwrap();
            assert_eq!(parse_f64(s).map(f64::to_bits), Some(want.to_bits()), "{s}");
        }
        for s in ["", "-", ".", "+", "1.2.3", "1e5x", "--1", "1,5", "nan", "inf", "-inf", "1e400", "0x10"] {
            let want = s.parse::<f64>().ok().filter(|v| v.is_finite());
            assert_eq!(parse_f64(s).map(f64::to_bits), want.map(f64::to_bits), "{s}");
        }
    }

    /// Whether `b` starts with `[+-]?d{0,7}(.d{0,7})?` with at least one digit, not followed by
    /// a digit, `.` after the fraction, or an exponent: what [`short_decimal_prefix`] must read.
    fn regex_like_short(b: &[u8]) -> bool {
        let mut i = usize::from(matches!(b[0], b'-' | b'+'));
        let run = |i: usize| b[i..].iter().take_while(|c| c.is_ascii_digit()).count();
        let int = run(i);
        i += int;
        let mut frac = 0;
        if b[i] == b'.' {
            frac = run(i + 1);
            i += 1 + frac;
        }
        int <= 7 && frac <= 7 && int + frac > 0 && !matches!(b[i] | 0x20, b'e')
    }

    #[test]
    fn short_decimal_cases() {
        let pad = |s: &str| format!("{s},0000000000000000000000000");
        for (s, want) in [
            ("0", Some((0.0, 1))),
            ("-0.0", Some((-0.0, 4))),
            ("+1.5", Some((1.5, 4))),
            ("1.", Some((1.0, 2))),
            (".5", Some((0.5, 2))),
            ("-.5", Some((-0.5, 3))),
            ("00012.500", Some((12.5, 9))),
            ("1234567.1234567", Some((1234567.1234567, 15))),
            ("-12.345678", Some((-12.345678, 10))),
            ("12345678.1", None),
            ("1.12345678", Some((1.12345678, 10))),
            ("250.00023792", Some((250.00023792, 12))),
            ("-1234567.12345678", Some((-1234567.12345678, 17))),
            ("1.123456789", None),
            ("0.000000001", None),
            ("1e5", None),
            ("1.5E3", None),
            (".", None),
            ("-", None),
            ("", None),
        ] {
            let b = pad(s);
            let got = short_decimal_prefix(b.as_bytes());
            assert_eq!(
                got.map(|(v, n)| (v.to_bits(), n)),
                want.map(|(v, n): (f64, usize)| (v.to_bits(), n)),
                "{s}"
            );
        }
        // Rows: plain ones are taken, anything else is left to the general row parser.
        let row = |s: &str| parse_row_plain::<3, false>(format!("{s}000000000000000000000000").as_bytes());
        assert_eq!(row("1.5,-2.25,3\n"), Some(([1.5, -2.25, 3.0], 11)));
        for other in ["1.5,-2.25,3\r\n", "1.5, -2.25,3\n", "1.5,-2.25\n", "1.5,-2.25,3,4\n", "#1,2,3\n", "\n"]
        {
            assert_eq!(row(other), None, "{other:?}");
        }
        // Non-ASCII bytes (0xFA..=0xFF carry when 6 is added) after the digits.
        let b = [
            b'1', b'2', 0xff, 0xfa, b'3', b'4', b'5', b'6', b'7', b'8', b'9', b'0', b'1', b'2', b'3', b'4',
            b'5', b'6', b'7', b'8', b'9', b'0', b'1', b'2',
        ];
        assert_eq!(short_decimal_prefix(&b), Some((12.0, 2)));
    }

    proptest::proptest! {
        /// The rewrite's split-and-parse agrees with the general reader on any row: the same
        /// values and fields, or an error at the same line and column.
        #[test]
        fn split_and_parse_matches_the_general_reader(fields in proptest::collection::vec("( |-|\\+)?[0-9]{0,6}(\\.[0-9]{0,6})?(e[0-9])? ?|[a-z\" \t]{0,3}|\"[a-z,\"]{0,3}\"", 1..7), cr in proptest::bool::ANY) {
            let row = fields.join(",");
            let text = format!("a,x_mm,y_mm,z_mm,b\n{row}{}\n# {}\n", if cr { "\r" } else { "" }, "pad ".repeat(30));
            let t = table(&text).unwrap();
            proptest::prop_assume!(t.n_rows() == 1);
            let general = t.f64_rows(&["x_mm", "y_mm", "z_mm"]);
            let view = Rows { text: t.text.as_bytes(), rows: &t.rows, width: t.header.len() };
            let (mut d, mut f) = (vec![0.0; 3], Vec::new());
            let fast = view.split_and_parse_range(0..1, &[1, 2, 3], &mut d, &mut f);
            match (general, fast) {
                (Ok(g), Ok(())) => {
                    proptest::prop_assert_eq!(g[0].iter().map(|v| v.to_bits()).collect::<Vec<_>>(), d.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
                    let mut buf = Vec::new();
                    let want = t.fields(0, &mut buf).unwrap();
                    let got: Vec<&str> = f.iter().map(|&(a, b)| &t.text[a..b]).collect();
                    proptest::prop_assert_eq!(want, got);
                }
                (Err(g), Err(e)) => {
                    let e = e.into_input_error(Path::new("t.csv"), &t.header, |r| t.line_number(r));
                    proptest::prop_assert_eq!((g.line, g.column), (e.line, e.column));
                }
                (g, e) => proptest::prop_assert!(false, "general {:?}, fast {:?}", g, e),
            }
        }

        /// The fast path is bit-identical to `str::parse` on every decimal it accepts.
        #[test]
        fn fast_float_path_is_exact(int in 0u64..10_000_000_000, frac in 0u64..1_000_000_000, fd in 0usize..10, neg in proptest::bool::ANY) {
            let s = format!("{}{}.{:0width$}", if neg { "-" } else { "" }, int, frac % 10u64.pow(fd as u32), width = fd);
            let want: f64 = s.parse().unwrap();
            proptest::prop_assert_eq!(parse_f64(&s).unwrap().to_bits(), want.to_bits(), "{}", s);
        }

        /// The SWAR short-decimal path reads what the general parser reads (value bit for bit,
        /// length), or declines; numbers of up to 7 + 7 digits are never declined.
        #[test]
        fn short_decimal_matches_general(text in "[-+]?[0-9]{0,9}(\\.[0-9]{0,9})?[eE,\n .x0-9]?[0-9]?", tail in "[,\n0-9a-z.]{24}") {
            let b = format!("{text}{tail}");
            let b = b.as_bytes();
            let general = crate::num::parse_f64_prefix(b);
            match short_decimal_prefix(b) {
                Some((v, n)) => {
                    let (g, gn) = general.expect("the general parser reads it too");
                    proptest::prop_assert_eq!((v.to_bits(), n), (g.to_bits(), gn), "{}", text);
                }
                None => {
                    let num = regex_like_short(b);
                    proptest::prop_assert!(!num, "declined a short decimal: {}", text);
                }
            }
            proptest::prop_assert_eq!(number_prefix(b).map(|(v, n)| (v.to_bits(), n)), general.map(|(v, n)| (v.to_bits(), n)));
        }

        /// The plain-row path gives what the general row parser gives, or declines.
        #[test]
        fn plain_rows_match_the_row_parser(fields in proptest::collection::vec("-?[0-9]{0,8}(\\.[0-9]{0,8})?|[ a-z\r\"]{1,2}[0-9]?", 3), end in "(\r?\n|,|\r| )", tail in "[0-9,\n]{24}") {
            let line = format!("{}{end}{tail}", fields.join(","));
            let b = line.as_bytes();
            let mut d = [0.0; 3];
            let general = parse_row_fast_len(b, &[0, 1, 2], &mut d).map(|n| (d.map(f64::to_bits), n));
            if let Some((p, n)) = parse_row_plain::<3, false>(b) {
                proptest::prop_assert_eq!(Some((p.map(f64::to_bits), n)), general, "{:?}", line);
            }
        }

        /// The vector short-decimal readers read what the SWAR one reads (value bit for bit,
        /// end), declining only the 7 + 8 digit numbers whose end lies past their 16 bytes.
        #[test]
        fn ssse3_short_decimal_matches_swar(text in "[-+]?[0-9]{0,9}(\\.[0-9]{0,9})?[eE,\n .x0-9]?[0-9]?", tail in "[,\n0-9a-z.]{24}") {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("ssse3") {
                let b = format!("{text}{tail}");
                let b = b.as_bytes();
                let swar = short_decimal_prefix(b);
                // SAFETY: the CPU has SSSE3.
                let simd = unsafe { short_decimal_ssse3(b) };
                match (simd, swar) {
                    (Some((v, n)), Some((w, m))) => proptest::prop_assert_eq!((v.to_bits(), n), (w.to_bits(), m), "{}", text),
                    (None, Some((_, m))) => {
                        let digits = b[..m].iter().filter(|c| c.is_ascii_digit()).count();
                        proptest::prop_assert!(digits == 15, "declined {:?}", text);
                    }
                    (Some(_), None) => proptest::prop_assert!(false, "took what SWAR declines: {:?}", text),
                    (None, None) => {}
                }
                // A field ended by a delimiter: what the SWAR reader gives when it ends there.
                if let Some(e) = b.iter().position(|&c| c == b',' || c == b'\n') {
                    let padded = [b, &[b'0'; 32][..]].concat();
                    // SAFETY: the CPU has SSSE3.
                    let field = unsafe { plain_field_ssse3(&padded, 0, e) };
                    let want = swar.filter(|&(_, m)| m == e).map(|(v, _)| v.to_bits());
                    match (field.map(f64::to_bits), want) {
                        (Some(f), w) => proptest::prop_assert_eq!(Some(f), w, "{:?}", text),
                        (None, Some(_)) => proptest::prop_assert!(b[..e].iter().filter(|c| c.is_ascii_digit()).count() > 15 || b[..e].len() > 17, "declined {:?}", text),
                        (None, None) => {}
                    }
                }
            }
        }

        /// A segment read by the SSSE3 loop (delimiter blocks, vector numbers) gives the rows,
        /// count and cleanliness of the portable loop, whatever its lines hold.
        #[test]
        fn ssse3_segment_matches_portable(rows in proptest::collection::vec(
            "-?[0-9]{1,3}\\.[0-9]{1,6},-?[0-9]{1,3}\\.[0-9]{1,6},[0-9]{1,7}(\\.[0-9]{0,8})?\n|[0-9.,]{0,12}\n|-?[0-9]\\.[0-9]{1,9}, 1,2\r\n|# \u{e9}\n|\n|1e3,2,3\n|\u{0}1,2,3\n", 1..80)) {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("ssse3") {
                let text = rows.concat();
                let seg = text.as_bytes();
                let slots = [0, 1, 2];
                let mut a = Vec::new();
                let pa = parse_segment::<3, false>(seg, &slots, usize::MAX, |r, d| { assert_eq!(r, a.len()); a.push(d.map(f64::to_bits)) });
                let mut b = Vec::new();
                // SAFETY: the CPU has SSSE3.
                let pb = unsafe { parse_segment_ssse3::<3>(seg, &slots, usize::MAX, |r, d| { assert_eq!(r, b.len()); b.push(d.map(f64::to_bits)) }) };
                proptest::prop_assert_eq!(pa, pb);
                if pa.is_some() {
                    proptest::prop_assert_eq!(a, b);
                }
                // A cap stops both at the same row.
                let cap = rows.len() / 2;
                let ca = parse_segment::<3, false>(seg, &slots, cap, |_, _| {});
                // SAFETY: the CPU has SSSE3.
                let cb = unsafe { parse_segment_ssse3::<3>(seg, &slots, cap, |_, _| {}) };
                proptest::prop_assert_eq!(ca, cb);
            }
        }

        /// The quote-free splitter agrees with the general one.
        #[test]
        fn fast_split_matches(line in "[ a-z0-9.,\t-]{0,40}") {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            split_fields(&line, &mut a);
            proptest::prop_assert!(split_fields_fast(line.as_bytes(), &mut b));
            proptest::prop_assert_eq!(a, b);
        }

        /// The fused row parser agrees with the general path (split, then `str::parse`) on any
        /// row it accepts, and declines rows it cannot handle.
        #[test]
        fn fused_row_parser_matches(fields in proptest::collection::vec("( |-|\\+)?[0-9]{0,9}(\\.[0-9]{0,9})? ?|[a-z\"e]{1,3}", 1..6), want in proptest::collection::vec(0usize..6, 1..4)) {
            let line = fields.join(",");
            let width = fields.len();
            let want: Vec<usize> = want.into_iter().filter(|&c| c < width).collect();
            let mut slots = vec![usize::MAX; width];
            for (j, &c) in want.iter().enumerate() {
                slots[c] = j;
            }
            let mut d = vec![f64::NAN; want.len()];
            if parse_row_fast(line.as_bytes(), &slots, &mut d) {
                let mut buf = Vec::new();
                split_fields(&line, &mut buf);
                for (j, &c) in want.iter().enumerate() {
                    let (a, b) = buf[c];
                    let v: f64 = line[a..b].parse().unwrap();
                    proptest::prop_assert_eq!(v.to_bits(), d[j].to_bits(), "{}", line);
                }
            }
        }
    }

    /// The usual mistakes get a message that says what the file is: separated by ';' or tabs,
    /// decimal commas, TOML or JSON given as points, a spreadsheet, CR-only line ends (read).
    #[test]
    fn usual_mistakes_are_named() {
        let need = ["x_mm", "y_mm", "z_mm"];
        let err = |text: &str| table(text).and_then(|t| t.f64_rows(&need)).unwrap_err().to_string();
        let e = err("x_mm;y_mm;z_mm\n102,99606;1,5;2\n");
        assert!(e.contains("separated by ';'") && e.contains("decimal point"), "{e}");
        let e = err("x_mm\ty_mm\tz_mm\n1\t2\t3\n");
        assert!(e.contains("separated by tabs"), "{e}");
        let e = err("x_mm,y_mm,z_mm\n\"102,996060\",1,2\n");
        assert!(e.contains("not a number: '102,996060'") && e.contains("decimal comma"), "{e}");
        assert!(e.starts_with("t.csv:2:1:"), "{e}");
        let e = err("[bed]\nsize_x_mm = 2000\n");
        assert!(e.contains("TOML"), "{e}");
        let e = err("{\"points\": [1, 2, 3]}\n");
        assert!(e.contains("JSON"), "{e}");
        // By extension, whatever the text.
        let e = Table::from_bytes("p.toml", b"a = 1\n".to_vec()).unwrap().f64_rows(&need).unwrap_err();
        assert!(e.to_string().contains("this is a TOML file"), "{e}");
        // CR-only line ends are lines.
        let t = table("# c\rx_mm,y_mm,z_mm\r1,2,3\r4,5,6\r").unwrap();
        assert_eq!(t.f64_rows(&need).unwrap(), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(t.line_number(1), 4);
        match Table::rows_direct(Path::new("t.csv"), Text::Owned("x_mm,y_mm,z_mm\r1,2,3\r".into()), &need) {
            Ok(Ok(rows)) => assert_eq!(rows, vec![[1.0, 2.0, 3.0]]),
            Ok(Err(t)) => assert_eq!(t.f64_rows(&need).unwrap(), vec![[1.0, 2.0, 3.0]]),
            Err(e) => panic!("{e}"),
        }
    }

    /// A spreadsheet given as CSV is named by its first bytes (an .xlsx is a ZIP archive).
    #[test]
    fn a_spreadsheet_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("points.csv");
        std::fs::write(&f, b"PK\x03\x04\x14\x00\x06\x00\x08\x00\x00\x00!\x00").unwrap();
        let e = Table::read(&f).unwrap_err().to_string();
        assert!(e.contains("ZIP archive") && e.contains("save the sheet as CSV"), "{e}");
        let f = dir.path().join("points.xlsx");
        std::fs::write(&f, b"PK\x03\x04\x14\x00\x06\x00\x08\x00\x00\x00!\x00").unwrap();
        let e = crate::points::read_points(&f).err().expect("an error").to_string();
        assert!(e.contains("Excel workbook"), "{e}");
    }

    /// Outputs keep the input's precision: decimals as written, full doubles round-trip.
    #[test]
    fn input_precision_follows_the_input() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.csv");
        let cols = ["x_mm", "y_mm", "z_mm"];
        std::fs::write(&f, "# c\nid,x_mm,y_mm,z_mm\nP1,1.5,2.1234567,3\nP2,1,2,3.25\n").unwrap();
        assert_eq!(input_precision(&f, &cols), NumFormat::Fixed(7));
        std::fs::write(&f, "x_mm,y_mm,z_mm\n250,10.5,3\n").unwrap();
        assert_eq!(input_precision(&f, &cols), NumFormat::Fixed(6));
        std::fs::write(&f, "x_mm,y_mm,z_mm\n379.1898194711725,1,2\n").unwrap();
        assert_eq!(input_precision(&f, &cols), NumFormat::Shortest);
        std::fs::write(&f, "x_mm,y_mm,z_mm\n1e-3,1,2\n").unwrap();
        assert_eq!(input_precision(&f, &cols), NumFormat::Shortest);
        assert_eq!(input_precision(&dir.path().join("none.csv"), &cols), NumFormat::Shortest);
    }
}

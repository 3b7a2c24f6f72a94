//! Streaming CSV: constant memory whatever the file size, reading overlapped with work.
//!
//! [`CsvStream::open`] starts a reader thread that reads the file in blocks of
//! [`BLOCK_BYTES`], checks each block as it arrives (size limit, line length, NUL bytes, UTF-8;
//! see [`crate::limits`]), cuts it at the last line end and indexes its data rows, then hands
//! the [`Chunk`] over a channel two deep. So at most a few blocks are in memory at any time,
//! and the next block is read and indexed while the caller parses (in parallel, with rayon) and
//! processes the current one. Errors keep the file, line and column of the whole file.
//!
//! ```no_run
//! # fn main() -> Result<(), truepos_io::InputError> {
//! let mut s = truepos_io::stream::CsvStream::open("points.csv")?;
//! let idx = [s.require("x_mm")?, s.require("y_mm")?, s.require("z_mm")?];
//! while let Some(chunk) = s.next_chunk()? {
//!     let xyz: Vec<[f64; 3]> = chunk.f64_rows(&idx)?;
//!     // … process, write …
//! }
//! # Ok(()) }
//! ```
//!
//! [`BackgroundWriter`] is the output side: formatted pieces go to a thread that writes them to
//! an [`AtomicFile`], so writing overlaps the next chunk's work too.

use crate::atomic::{AtomicFile, OutputError};
use crate::csv::{index_rows, split_fields, Rows};
use crate::limits::{self, LineGuard};
use crate::InputError;
use rayon::prelude::*;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// Bytes read per block (a chunk holds the complete lines of about one block).
pub const BLOCK_BYTES: usize = 4 << 20;

/// Bytes of the first block read (the blocks after it grow to [`BLOCK_BYTES`]).
const FIRST_BLOCK_BYTES: usize = 64 << 10;

/// A block of complete lines with its data rows indexed.
pub struct Chunk {
    path: Arc<PathBuf>,
    header: Arc<Vec<String>>,
    text: String,
    rows: Vec<usize>,
    /// 1-based line number of the first byte of `text`.
    first_line: usize,
    /// Index (in the whole file) of the first data row.
    first_row: usize,
}

impl Chunk {
    /// Number of data rows in this chunk.
    pub fn n_rows(&self) -> usize {
        self.rows.len()
    }
    /// Index in the whole file of this chunk's first data row.
    pub fn first_row(&self) -> usize {
        self.first_row
    }
    /// 1-based line number (in the whole file) of data row `r` of this chunk.
    pub fn line_number(&self, r: usize) -> usize {
        self.first_line + memchr::memchr_iter(b'\n', &self.text.as_bytes()[..self.rows[r]]).count()
    }
    /// The text of data row `r` without its line ending.
    pub fn row_text(&self, r: usize) -> &str {
        let s = self.rows[r];
        let b = self.text.as_bytes();
        let e = memchr::memchr(b'\n', &b[s..]).map_or(b.len(), |p| s + p);
        let l = &self.text[s..e];
        l.strip_suffix('\r').unwrap_or(l)
    }
    /// The fields of data row `r`, checked against the header width.
    pub fn fields<'a>(&'a self, r: usize, buf: &mut Vec<(usize, usize)>) -> Result<Vec<&'a str>, InputError> {
        let line = self.split_row(r, buf)?;
        Ok(buf.iter().map(|&(a, b)| &line[a..b]).collect())
    }
    /// The text of data row `r` and its field ranges in `buf` (no allocation), checked against
    /// the header width.
    pub fn split_row<'a>(&'a self, r: usize, buf: &mut Vec<(usize, usize)>) -> Result<&'a str, InputError> {
        let line = self.row_text(r);
        split_fields(line, buf);
        if buf.len() != self.header.len() {
            return Err(InputError::at(
                self.path.as_path(),
                self.line_number(r),
                Some(buf.len().min(self.header.len()) + 1),
                format!("ragged row: {} fields, the header has {}", buf.len(), self.header.len()),
            ));
        }
        Ok(line)
    }
    /// Parse columns `idx` of every row (row-major), in parallel.
    pub fn f64_columns_at(&self, idx: &[usize]) -> Result<Vec<f64>, InputError> {
        let mut out = vec![0.0; self.rows.len() * idx.len()];
        self.parse_into(idx, &mut out)?;
        Ok(out)
    }
    /// One `[f64; K]` per row.
    pub fn f64_rows<const K: usize>(&self, idx: &[usize; K]) -> Result<Vec<[f64; K]>, InputError> {
        let mut out = vec![[0.0; K]; self.rows.len()];
        self.parse_into(idx, out.as_flattened_mut())?;
        Ok(out)
    }
    fn parse_into(&self, idx: &[usize], out: &mut [f64]) -> Result<(), InputError> {
        self.rows_view()
            .parse_into(idx, out)
            .map_err(|e| e.into_input_error(self.path.as_path(), &self.header, |r| self.line_number(r)))
    }
    /// Parse columns `idx` of rows `range` (of this chunk) into `out`, one `[f64; K]` per row,
    /// on the calling thread (for callers that split the chunk across threads themselves).
    /// `scratch` is reused between calls.
    pub fn parse_rows_into<const K: usize>(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize; K],
        out: &mut [[f64; K]],
        scratch: &mut RowScratch,
    ) -> Result<(), InputError> {
        let rows = self.rows_view();
        if scratch.slots.len() != self.header.len() || scratch.idx != idx[..] {
            scratch.slots = rows.slots(idx);
            scratch.idx = idx.to_vec();
        }
        rows.parse_range(range, idx, &scratch.slots, out.as_flattened_mut(), &mut scratch.fields)
            .map_err(|e| e.into_input_error(self.path.as_path(), &self.header, |r| self.line_number(r)))
    }
    /// As [`parse_rows_into`](Self::parse_rows_into), and every field's byte range in the
    /// chunk's text appended to `fields` (the header's width per row; spaces trimmed, quotes
    /// removed): for writing the rows back with some fields replaced ([`field`](Self::field)).
    pub fn split_parse_rows_into<const K: usize>(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize; K],
        out: &mut [[f64; K]],
        fields: &mut Vec<(usize, usize)>,
    ) -> Result<(), InputError> {
        self.rows_view()
            .split_and_parse_range(range, idx, out.as_flattened_mut(), fields)
            .map_err(|e| e.into_input_error(self.path.as_path(), &self.header, |r| self.line_number(r)))
    }
    /// As [`split_parse_rows_into`](Self::split_parse_rows_into) with any number of columns:
    /// `out` holds `idx.len()` values per row (row-major).
    pub fn split_parse_rows_flat(
        &self,
        range: std::ops::Range<usize>,
        idx: &[usize],
        out: &mut [f64],
        fields: &mut Vec<(usize, usize)>,
    ) -> Result<(), InputError> {
        self.rows_view()
            .split_and_parse_range(range, idx, out, fields)
            .map_err(|e| e.into_input_error(self.path.as_path(), &self.header, |r| self.line_number(r)))
    }
    /// The value of a field range from [`split_parse_rows_into`](Self::split_parse_rows_into):
    /// its text, a quoted field's doubled quotes made single (what the field means, for an
    /// output that is not CSV).
    pub fn field_value(&self, range: (usize, usize)) -> std::borrow::Cow<'_, str> {
        let raw = self.field(range);
        let quoted = range.0 > 0 && self.text.as_bytes().get(range.0 - 1) == Some(&b'"');
        if quoted && raw.contains("\"\"") {
            std::borrow::Cow::Owned(raw.replace("\"\"", "\""))
        } else {
            std::borrow::Cow::Borrowed(raw)
        }
    }
    /// The text of a field range from [`split_parse_rows_into`](Self::split_parse_rows_into)
    /// (for a quoted field: as written between the quotes, inner quotes still doubled).
    pub fn field(&self, range: (usize, usize)) -> &str {
        self.text.get(range.0..range.1).unwrap_or("")
    }
    /// Append the field at `range` (from [`split_parse_rows_into`](Self::split_parse_rows_into))
    /// to a CSV row being written as it was written in the input (without the spaces around
    /// it): a quoted field with its quotes (its inner quotes are already doubled), any other
    /// one as is (it holds no comma). So a passed-through field keeps its text byte for byte.
    pub fn push_field(&self, out: &mut Vec<u8>, range: (usize, usize)) {
        let raw = self.field(range);
        let quoted = range.0 > 0 && self.text.as_bytes().get(range.0 - 1) == Some(&b'"');
        if quoted {
            out.push(b'"');
            out.extend_from_slice(raw.as_bytes());
            out.push(b'"');
        } else {
            out.extend_from_slice(raw.as_bytes());
        }
    }
    fn rows_view(&self) -> Rows<'_> {
        Rows { text: self.text.as_bytes(), rows: &self.rows, width: self.header.len() }
    }
}

/// Scratch space of [`Chunk::parse_rows_into`]: the column slots and a field list, kept
/// between calls.
#[derive(Default)]
pub struct RowScratch {
    idx: Vec<usize>,
    slots: Vec<usize>,
    fields: Vec<(usize, usize)>,
}

/// A CSV file read in chunks (see the module docs).
pub struct CsvStream {
    path: Arc<PathBuf>,
    header: Arc<Vec<String>>,
    /// Comment lines before the header (without `#`).
    pub comments: Vec<String>,
    header_line: usize,
    rx: Receiver<Result<Block, InputError>>,
    /// Consumed chunks' buffers back to the reader ([`recycle`](Self::recycle)).
    spare: SyncSender<Spare>,
    /// Unconsumed remainder of the block that held the header.
    pending: Option<Block>,
    next_row: usize,
    reader: Option<JoinHandle<()>>,
}

/// Complete lines from the reader thread: text, the start offsets of its data rows (indexed by
/// the reader, so the consumer's thread does not walk the text once more) and the line number
/// of its first byte.
struct Block {
    text: String,
    rows: Vec<usize>,
    first_line: usize,
}

/// Buffers of consumed chunks, handed back to the reader for its next blocks (no fresh memory,
/// hence no page faults, per block).
type Spare = (String, Vec<usize>);

fn reader_thread(
    path: PathBuf,
    mut file: std::fs::File,
    tx: SyncSender<Result<Block, InputError>>,
    spare: Receiver<Spare>,
) {
    let limit = limits::max_input_bytes();
    let mut guard = LineGuard::default();
    let mut carry: Vec<u8> = Vec::new();
    let mut total: u64 = 0;
    let mut line = 1usize;
    // The first blocks are small and grow to `BLOCK_BYTES` (64 KiB, 256 KiB, 1 MiB, 4 MiB): the
    // header, and the first rows to work on, arrive after a short read instead of a whole
    // block's read, check and index (≈ 7 ms for 4 MiB, on the caller's critical path before).
    let mut block_bytes = FIRST_BLOCK_BYTES;
    loop {
        let (mut buf, mut rows) = match spare.try_recv() {
            Ok((text, rows)) => (text.into_bytes(), rows),
            Err(_) => (Vec::with_capacity(block_bytes + carry.len()), Vec::new()),
        };
        // A returned buffer is about as long as needed already: only the difference is
        // zero-filled, not the whole block again.
        let start = carry.len();
        buf.resize(start + block_bytes, 0);
        block_bytes = (block_bytes * 4).min(BLOCK_BYTES);
        buf[..start].copy_from_slice(&carry);
        carry.clear();
        let mut filled = start;
        let mut eof = false;
        while filled < buf.len() {
            match file.read(&mut buf[filled..]) {
                Ok(0) => {
                    eof = true;
                    break;
                }
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    let _ = tx.send(Err(InputError::in_file(&path, format!("cannot read: {e}"))));
                    return;
                }
            }
        }
        buf.truncate(filled);
        total += (filled - start) as u64;
        if total > limit {
            let _ = tx.send(Err(limits::stream_too_large(&path, limit)));
            return;
        }
        if let Err(e) = guard.scan(&path, &buf[start..], "CSV") {
            let _ = tx.send(Err(e));
            return;
        }
        // Cut after the last line end (everything at end of file).
        let cut = if eof { buf.len() } else { memchr::memrchr(b'\n', &buf).map_or(0, |p| p + 1) };
        carry.extend_from_slice(&buf[cut..]);
        buf.truncate(cut);
        if !buf.is_empty() {
            let lines_here = memchr::memchr_iter(b'\n', &buf).count();
            let text = match String::from_utf8(buf) {
                Ok(t) => t,
                Err(e) => {
                    let ok = &e.as_bytes()[..e.utf8_error().valid_up_to()];
                    let l = line + memchr::memchr_iter(b'\n', ok).count();
                    let _ =
                        tx.send(Err(InputError::at(&path, l, None, "not valid UTF-8 text: not a CSV file")));
                    return;
                }
            };
            rows.clear();
            // Lines over the limit were refused by the guard above (a line never spans blocks).
            if let Some(bad) = index_rows(&text, 0, text.len(), &mut rows) {
                let l = line + memchr::memchr_iter(b'\n', &text.as_bytes()[..bad]).count();
                let _ = tx.send(Err(limits::line_too_long(&path, l)));
                return;
            }
            if tx.send(Ok(Block { text, rows, first_line: line })).is_err() {
                return; // the consumer stopped (an error, or it had enough)
            }
            line += lines_here;
        }
        if eof {
            return;
        }
    }
}

impl CsvStream {
    /// Open `path`, start the reader and read up to the header row.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, InputError> {
        let path = path.as_ref().to_path_buf();
        let cannot = |e: std::io::Error| InputError::in_file(&path, format!("cannot read: {e}"));
        let file = std::fs::File::open(&path).map_err(cannot)?;
        crate::atomic::note_input(&path);
        let meta = file.metadata().map_err(cannot)?;
        if meta.is_dir() {
            return Err(InputError::in_file(&path, "is a directory, not a file"));
        }
        limits::check_file_size(&path, &meta)?;
        let (tx, rx) = sync_channel(2);
        let (spare, spare_rx) = sync_channel(4);
        let p2 = path.clone();
        let reader = std::thread::Builder::new()
            .name("truepos-csv-reader".into())
            .spawn(move || reader_thread(p2, file, tx, spare_rx))
            .map_err(|e| InputError::in_file(&path, format!("cannot start the reader: {e}")))?;
        let mut comments = Vec::new();
        let mut bom_checked = false;
        // Blocks until the header line.
        loop {
            let mut block = match rx.recv() {
                Ok(b) => b?,
                Err(_) => return Err(InputError::in_file(&path, "empty file: no header row")),
            };
            if !bom_checked {
                bom_checked = true;
                if let Some(rest) = block.text.strip_prefix('\u{feff}') {
                    block.text = rest.to_string();
                }
            }
            let mut pos = 0;
            let mut line = block.first_line;
            let bytes = block.text.as_bytes();
            while pos < bytes.len() {
                let end = memchr::memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |p| pos + p);
                let raw = &block.text[pos..end];
                let l = raw.strip_suffix('\r').unwrap_or(raw);
                let trimmed = l.trim_start();
                if trimmed.is_empty() {
                } else if let Some(c) = trimmed.strip_prefix('#') {
                    comments.push(c.trim().to_string());
                } else {
                    let mut f = Vec::new();
                    split_fields(l, &mut f);
                    let names: Vec<String> = f.iter().map(|&(a, b)| l[a..b].to_string()).collect();
                    for (i, n) in names.iter().enumerate() {
                        if n.is_empty() {
                            return Err(InputError::at(
                                &path,
                                line,
                                Some(i + 1),
                                "empty column name in the header",
                            ));
                        }
                        if names[..i].contains(n) {
                            return Err(InputError::at(
                                &path,
                                line,
                                Some(i + 1),
                                format!("duplicate column '{n}' in the header"),
                            ));
                        }
                    }
                    let rest = block.text[(end + 1).min(bytes.len())..].to_string();
                    let mut rows = Vec::new();
                    if let Some(bad) = index_rows(&rest, 0, rest.len(), &mut rows) {
                        let l = line + 1 + memchr::memchr_iter(b'\n', &rest.as_bytes()[..bad]).count();
                        return Err(limits::line_too_long(&path, l));
                    }
                    let pending =
                        (!rest.is_empty()).then_some(Block { text: rest, rows, first_line: line + 1 });
                    return Ok(Self {
                        path: Arc::new(path),
                        header: Arc::new(names),
                        comments,
                        header_line: line,
                        rx,
                        spare,
                        pending,
                        next_row: 0,
                        reader: Some(reader),
                    });
                }
                pos = end + 1;
                line += 1;
            }
        }
    }

    /// The path of the file being read.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// The column names of the header row.
    pub fn header(&self) -> &[String] {
        &self.header
    }
    /// 1-based line of the header row.
    pub fn header_line(&self) -> usize {
        self.header_line
    }
    /// Index of a column by name.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }
    /// Index of a required column, or an error naming it.
    pub fn require(&self, name: &str) -> Result<usize, InputError> {
        self.column(name).ok_or_else(|| {
            InputError::at(
                self.path.as_path(),
                self.header_line,
                None,
                crate::csv::missing_column_message(&self.path, name, &self.header),
            )
        })
    }

    /// The next chunk of data rows (`None` at the end of the file). Chunks without data rows
    /// (only comments or blank lines) are skipped.
    pub fn next_chunk(&mut self) -> Result<Option<Chunk>, InputError> {
        loop {
            let block = match self.pending.take() {
                Some(b) => b,
                None => match self.rx.recv() {
                    Ok(b) => b?,
                    Err(_) => return Ok(None),
                },
            };
            let rows = block.rows;
            if rows.is_empty() {
                continue;
            }
            let first_row = self.next_row;
            self.next_row += rows.len();
            return Ok(Some(Chunk {
                path: self.path.clone(),
                header: self.header.clone(),
                text: block.text,
                rows,
                first_line: block.first_line,
                first_row,
            }));
        }
    }
}

impl CsvStream {
    /// Hand a consumed chunk's buffers back to the reader, which fills them with a later block
    /// instead of asking the system for fresh memory. Optional: a dropped chunk is just freed.
    pub fn recycle(&self, chunk: Chunk) {
        let _ = self.spare.try_send((chunk.text, chunk.rows));
    }
}

impl Drop for CsvStream {
    fn drop(&mut self) {
        // The reader ends at its next send (the receiver is gone). It is not waited for: on a
        // pipe it may be blocked in a read that only the writer's end can finish.
        drop(self.reader.take());
    }
}

/// Writes byte pieces to an [`AtomicFile`] on a thread of its own, two batches deep, so the
/// caller computes the next pieces while the last ones are written. Written pieces go back to a
/// pool ([`buffer`](Self::buffer)), so a long stream of output reuses the same few buffers.
/// [`finish`](Self::finish) returns the file for [`AtomicFile::commit`]; dropping the writer
/// unfinished removes the temporary file.
pub struct BackgroundWriter {
    tx: Option<SyncSender<Vec<Vec<u8>>>>,
    handle: Option<JoinHandle<(AtomicFile, std::io::Result<()>)>>,
    path: PathBuf,
    pool: Arc<Mutex<Vec<Vec<u8>>>>,
}

/// Most buffers the pool keeps (the rest are freed).
const POOL_MAX: usize = 256;

impl BackgroundWriter {
    /// Start the writer thread for `file`; buffers sent to it are written in order.
    pub fn new(mut file: AtomicFile) -> Self {
        let path = file.path().to_path_buf();
        let (tx, rx) = sync_channel::<Vec<Vec<u8>>>(2);
        let pool: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
        let back = pool.clone();
        let handle = std::thread::spawn(move || {
            let mut r = Ok(());
            for batch in rx {
                for mut piece in batch {
                    if r.is_ok() {
                        r = file.write_piece(&piece);
                    }
                    piece.clear();
                    if let Ok(mut p) = back.lock() {
                        if p.len() < POOL_MAX {
                            p.push(piece);
                        }
                    }
                }
            }
            (file, r)
        });
        Self { tx: Some(tx), handle: Some(handle), path, pool }
    }

    /// An empty buffer for a piece: a written one from the pool, or a new one. Callable from
    /// any thread (the pool is shared).
    pub fn buffer(&self) -> Vec<u8> {
        self.pool.lock().ok().and_then(|mut p| p.pop()).unwrap_or_default()
    }

    /// Queue `piece` for writing. A failed earlier write is reported here (or at `finish`).
    pub fn send(&mut self, piece: Vec<u8>) -> Result<(), OutputError> {
        self.send_all(vec![piece])
    }

    /// Queue `pieces` for writing, in order, as one batch.
    pub fn send_all(&mut self, pieces: Vec<Vec<u8>>) -> Result<(), OutputError> {
        let sent = self.tx.as_ref().map(|tx| tx.send(pieces).is_ok()).unwrap_or(false);
        if sent {
            return Ok(());
        }
        self.finish_inner().map(|_| ())
    }

    /// Wait for every queued piece to be written; the file, ready to commit.
    pub fn finish(mut self) -> Result<AtomicFile, OutputError> {
        self.finish_inner()
    }

    fn finish_inner(&mut self) -> Result<AtomicFile, OutputError> {
        self.tx = None;
        let h = self.handle.take().ok_or_else(|| OutputError::Io {
            path: self.path.clone(),
            source: std::io::Error::other("writer already finished"),
        })?;
        match h.join() {
            Ok((file, Ok(()))) => Ok(file),
            Ok((_file, Err(source))) => Err(OutputError::Io { path: self.path.clone(), source }),
            Err(_) => Err(OutputError::Io {
                path: self.path.clone(),
                source: std::io::Error::other("the writer thread panicked"),
            }),
        }
    }
}

impl Drop for BackgroundWriter {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.handle.take() {
            // The file is dropped with the thread's result: the temporary is removed.
            let _ = h.join();
        }
    }
}

/// Rows per piece of [`rewrite_points`]: parsed, transformed and formatted by one task.
pub(crate) const PIECE_ROWS: usize = 4096;

/// Rows per batch of a Parquet or E57 input: a whole number of pieces, so pieces start at the
/// same rows as if the whole file were cut into pieces.
pub(crate) const BATCH_ROWS: usize = 8 * PIECE_ROWS;

/// Rows per row group of a Parquet output.
const ROW_GROUP: usize = crate::parquet_file::ROW_GROUP;

/// Per-thread scratch of [`rewrite_points`]: the piece's points, its extra values, the
/// parser's and the formatter's field lists. Taken out of the thread-local while a piece is
/// worked on (so a nested task on the same thread gets its own) and put back after.
#[derive(Default)]
struct PieceScratch {
    xyz: Vec<[f64; 3]>,
    pts: Vec<truepos_math::Point3>,
    /// The extra values, `N` per point, flat (one scratch type for every `N`).
    ex: Vec<f64>,
    parse: RowScratch,
    fields: Vec<(usize, usize)>,
}

thread_local! {
    static SCRATCH: std::cell::Cell<Option<Box<PieceScratch>>> = const { std::cell::Cell::new(None) };
}

/// What [`rewrite_points`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RewriteSummary {
    /// Number of points (data rows) rewritten.
    pub n_points: usize,
    /// Number of chunks the file was processed in.
    pub n_chunks: usize,
    /// Points of an E57 input left out because the file marks them invalid
    /// ([`crate::e57_file::E57Counts`]); 0 for other inputs.
    pub skipped_invalid: usize,
    /// Points of an E57 input left out because a coordinate is NaN or infinite; 0 for other
    /// inputs.
    pub skipped_nonfinite: usize,
}

/// Failure of [`rewrite_points`]: bad input (located), an unwritable output, or the caller's
/// own error for a point (turned into an input error on that point's line).
#[derive(Debug, thiserror::Error)]
pub enum RewriteError {
    /// The input file is bad (located error).
    #[error(transparent)]
    Input(#[from] InputError),
    /// The output file could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Stream a point file through `f` into `output`: the input with `x_mm,y_mm,z_mm` replaced by the
/// points as `f` leaves them and the columns `extra` (`N` values per point from `f`, e.g.
/// `dx_um,dy_um,dz_um`) replaced where the input has them or appended; every other column is
/// passed through unchanged. Constant memory: one chunk of about [`BLOCK_BYTES`] at a time (its
/// buffers handed back to the reader for a later block), the next one read and indexed by the
/// reader thread while this one is worked on, the previous one written by the writer thread.
///
/// A chunk is cut into pieces of `PIECE_ROWS` rows, worked on in parallel: each piece is
/// parsed, passed to `f` and formatted by one task, while its rows are still in the cache.
/// `f(first_row, points, extra)` gets the piece's points (`first_row`: index in the whole file
/// of the first) and returns a partial result, or `Err((row_in_piece, message))` to refuse a
/// point, which becomes an input error on that point's line (the first such row in file
/// order). `merge` receives the partial results in file order, on the calling thread, so sums
/// come out the same on every run. The output is atomic: nothing is left at `output` unless
/// every row was written.
///
/// Binary files, by extension, are streamed too (`rewrite_binary`): a Parquet or E57 input is
/// read in batches of `BATCH_ROWS` rows (pieces at the same rows as if the whole file were
/// cut; a refused point is an input error naming its 1-based row), and a `.parquet` output is
/// written a row group at a time by a writer thread (numbers as doubles; a Parquet input keeps
/// its column types; a CSV input's passed-through column is a number column when every value
/// of it in the file is a number — decided by a first pass over the file, or text for an input
/// that cannot be read twice, a pipe — else text). Memory holds a batch or chunk and one row
/// group, whatever the file's size.
pub fn rewrite_points<const N: usize, F, T, M>(
    input: &Path,
    output: &Path,
    extra: [&str; N],
    fmt: crate::num::NumFormat,
    f: F,
    mut merge: M,
) -> Result<RewriteSummary, RewriteError>
where
    F: Fn(usize, &mut [truepos_math::Point3], &mut [[f64; N]]) -> Result<T, (usize, String)> + Sync,
    T: Send,
    M: FnMut(T),
{
    use crate::parquet_file::is_parquet;
    if is_parquet(input) || crate::e57_file::is_e57(input) {
        return crate::rewrite_binary::rewrite_batches(
            input, output, extra, fmt, f, merge, BATCH_ROWS, ROW_GROUP,
        );
    }
    if is_parquet(output) {
        return crate::rewrite_binary::rewrite_csv_to_parquet(input, output, extra, f, merge, ROW_GROUP);
    }
    let mut s = CsvStream::open(input)?;
    if let Some((i, n)) = unwritable_name(s.header()) {
        return Err(InputError::at(input, s.header_line(), Some(i + 1), unwritable_message(n)).into());
    }
    let xyz = [s.require("x_mm")?, s.require("y_mm")?, s.require("z_mm")?];
    let width = s.header().len();
    let (plan, names) = output_plan(s.header(), xyz, extra);
    let passes = plan.iter().any(|p| matches!(p, Src::Pass(_)));
    let file = AtomicFile::create(output)?;
    let mut head = crate::csv::CsvWriter::new(Vec::new()).with_format(fmt);
    head.header(&names).map_err(|e| OutputError::Io { path: output.to_path_buf(), source: e })?;
    let mut w = BackgroundWriter::new(file);
    w.send(head.into_inner())?;
    let mut n_points = 0;
    let mut n_chunks = 0;
    while let Some(chunk) = s.next_chunk()? {
        let n = chunk.n_rows();
        let first = chunk.first_row();
        let piece = |range: std::ops::Range<usize>,
                     sc: &mut PieceScratch|
         -> Result<(Vec<u8>, T), InputError> {
            let m = range.len();
            sc.xyz.clear();
            sc.xyz.resize(m, [0.0; 3]);
            sc.fields.clear();
            if passes {
                chunk.split_parse_rows_into(range.clone(), &xyz, &mut sc.xyz, &mut sc.fields)?;
            } else {
                chunk.parse_rows_into(range.clone(), &xyz, &mut sc.xyz, &mut sc.parse)?;
            }
            sc.pts.clear();
            sc.pts.extend(sc.xyz.iter().map(|&p| truepos_math::Point3::from(p)));
            sc.ex.clear();
            sc.ex.resize(m * N, 0.0);
            let (ex, _) = sc.ex.as_chunks_mut::<N>();
            let t = f(first + range.start, &mut sc.pts, ex)
                .map_err(|(r, msg)| InputError::at(input, chunk.line_number(range.start + r), None, msg))?;
            let mut out = w.buffer();
            out.reserve(m * 128);
            for i in 0..m {
                let fields = sc.fields.get(i * width..).unwrap_or(&[]);
                for (j, src) in plan.iter().enumerate() {
                    if j > 0 {
                        out.push(b',');
                    }
                    match *src {
                        Src::Point(k) => fmt.write(sc.pts[i][k], &mut out),
                        Src::Extra(k) => fmt.write(sc.ex[i * N + k], &mut out),
                        Src::Pass(c) => chunk.push_field(&mut out, fields[c]),
                    }
                }
                out.push(b'\n');
            }
            Ok((out, t))
        };
        let results: Vec<Result<(Vec<u8>, T), InputError>> = (0..n.div_ceil(PIECE_ROWS))
            .into_par_iter()
            .map(|c| {
                let mut sc = SCRATCH.take().unwrap_or_default();
                let r = piece(c * PIECE_ROWS..((c + 1) * PIECE_ROWS).min(n), &mut sc);
                SCRATCH.set(Some(sc));
                r
            })
            .collect();
        let mut pieces = Vec::with_capacity(results.len());
        for r in results {
            let (p, t) = r?;
            merge(t);
            pieces.push(p);
        }
        w.send_all(pieces)?;
        n_points += n;
        n_chunks += 1;
        s.recycle(chunk);
    }
    w.finish()?.commit()?;
    Ok(RewriteSummary { n_points, n_chunks, skipped_invalid: 0, skipped_nonfinite: 0 })
}

/// The first column name that could not be written back unchanged, with its index: it holds a
/// comma or a quote (the header is written plain), or a byte-order mark (which would open the
/// output and be taken for the file's own).
pub(crate) fn unwritable_name(header: &[String]) -> Option<(usize, &str)> {
    header.iter().enumerate().find(|(_, n)| n.contains([',', '"', '\u{feff}'])).map(|(i, n)| (i, n.as_str()))
}

pub(crate) fn unwritable_message(name: &str) -> String {
    format!(
        "column name '{}' holds a comma, a quote or a byte-order mark: the output could not carry it unchanged (rename the column)",
        name.replace('\u{feff}', "<BOM>")
    )
}

/// Output column `c`: what to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Src {
    /// Coordinate `k` of the point as `f` leaves it.
    Point(usize),
    /// Value `k` of the extra columns.
    Extra(usize),
    /// Input column `c`, passed through.
    Pass(usize),
}

/// The output's columns for an input with columns `header` (`x_mm,y_mm,z_mm` at `xyz`): every
/// input column in place (the point's coordinates and the `extra` columns replaced), then the
/// `extra` columns the input does not have; with their names.
pub(crate) fn output_plan<'a, const N: usize>(
    header: &'a [String],
    xyz: [usize; 3],
    extra: [&'a str; N],
) -> (Vec<Src>, Vec<&'a str>) {
    let existing: Vec<Option<usize>> = extra.iter().map(|n| header.iter().position(|h| h == n)).collect();
    let mut plan: Vec<Src> = (0..header.len())
        .map(|c| {
            if let Some(k) = xyz.iter().position(|&x| x == c) {
                Src::Point(k)
            } else if let Some(k) = existing.iter().position(|&e| e == Some(c)) {
                Src::Extra(k)
            } else {
                Src::Pass(c)
            }
        })
        .collect();
    let mut names: Vec<&str> = header.iter().map(String::as_str).collect();
    for (k, e) in existing.iter().enumerate() {
        if e.is_none() {
            plan.push(Src::Extra(k));
            names.push(extra[k]);
        }
    }
    (plan, names)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn chunks_cover_every_row_with_file_line_numbers() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("\u{feff}# made by a test\n\nx_mm,y_mm,z_mm,id\n");
        let n = 300_000; // several blocks
        for i in 0..n {
            if i % 1000 == 0 {
                text.push_str("# a comment inside\n");
            }
            text.push_str(&format!("{i}.5,{},{},P{i}\r\n", i * 2, -(i as f64) * 0.25));
        }
        assert!(text.len() > 2 * BLOCK_BYTES);
        let p = write(dir.path(), "big.csv", &text);
        let mut s = CsvStream::open(&p).unwrap();
        assert_eq!(s.comments, vec!["made by a test"]);
        assert_eq!(s.header_line(), 3);
        let idx = [s.require("x_mm").unwrap(), s.require("y_mm").unwrap(), s.require("z_mm").unwrap()];
        let mut seen = 0;
        let mut chunks = 0;
        while let Some(c) = s.next_chunk().unwrap() {
            assert_eq!(c.first_row(), seen);
            let v = c.f64_rows(&idx).unwrap();
            for (r, row) in v.iter().enumerate() {
                let i = seen + r;
                assert_eq!(*row, [i as f64 + 0.5, (i * 2) as f64, -(i as f64) * 0.25]);
            }
            // Line of row r: header line 3, one comment line per 1000 rows before it.
            let r = c.n_rows() - 1;
            let i = seen + r;
            assert_eq!(c.line_number(r), 3 + i + 1 + i / 1000 + 1);
            let mut buf = Vec::new();
            assert_eq!(c.fields(r, &mut buf).unwrap()[3], format!("P{i}"));
            seen += c.n_rows();
            chunks += 1;
        }
        assert_eq!(seen, n);
        assert!(chunks >= 3);
    }

    #[test]
    fn errors_are_located_in_the_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("x_mm,y_mm\n");
        for i in 0..400_000 {
            text.push_str(&format!("{i},{i}.25\n"));
        }
        text.push_str("1,abc\n");
        let p = write(dir.path(), "bad.csv", &text);
        let mut s = CsvStream::open(&p).unwrap();
        let idx = [0, 1];
        let e = loop {
            match s.next_chunk().unwrap() {
                Some(c) => {
                    if let Err(e) = c.f64_rows(&idx) {
                        break e;
                    }
                }
                None => panic!("no error"),
            }
        };
        assert_eq!((e.line, e.column), (Some(400_002), Some(2)));
        assert!(e.to_string().contains("y_mm") && e.to_string().contains("abc"), "{e}");

        let p = write(dir.path(), "empty.csv", "# nothing\n\n");
        assert!(CsvStream::open(&p).err().unwrap().to_string().contains("no header"));
        let p = write(dir.path(), "dup.csv", "a,a\n1,2\n");
        assert!(CsvStream::open(&p).err().unwrap().to_string().contains("duplicate"));
        let p = write(dir.path(), "m.csv", "a,b\n1,2\n");
        assert!(CsvStream::open(&p).unwrap().require("z").unwrap_err().to_string().contains("missing"));
    }

    #[test]
    fn dev_zero_and_long_lines_end_at_once() {
        if Path::new("/dev/zero").exists() {
            let t = std::time::Instant::now();
            let e = CsvStream::open("/dev/zero").err().unwrap();
            assert!(e.to_string().contains("binary"), "{e}");
            assert!(t.elapsed().as_secs_f64() < 1.0);
        } else {
            eprintln!("SKIPPED: no /dev/zero");
        }
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("a,b\n1,2\n");
        text.push_str(&"9".repeat(limits::MAX_LINE_BYTES + 10));
        text.push_str("\n3,4\n");
        let p = write(dir.path(), "long.csv", &text);
        // Found by the reader as the block arrives: at open (here) or at a later chunk.
        let e = match CsvStream::open(&p) {
            Err(e) => e,
            Ok(mut s) => loop {
                match s.next_chunk() {
                    Err(e) => break e,
                    Ok(Some(_)) => {}
                    Ok(None) => panic!("no error"),
                }
            },
        };
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("longer than"), "{e}");
    }

    #[test]
    fn rewrite_points_replaces_adds_and_passes_through() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("# c\nid,z_mm,x_mm,y_mm,dy_um,note\n");
        let n = 250_000;
        for i in 0..n {
            text.push_str(&format!("P{i},{}.5,{i},0.1,9,\"a,{i}\"\n", i % 10));
        }
        let inp = write(dir.path(), "in.csv", &text);
        let out = dir.path().join("out.csv");
        let mut merged = Vec::new();
        let sum = rewrite_points(
            &inp,
            &out,
            ["dx_um", "dy_um", "dz_um"],
            Default::default(),
            |first, p, e| {
                for (k, (q, d)) in p.iter_mut().zip(e.iter_mut()).enumerate() {
                    q.x += 1.0;
                    *d = [(first + k) as f64, 0.25, -1.0];
                }
                Ok((first, p.len()))
            },
            |t| merged.push(t),
        )
        .unwrap();
        assert_eq!(sum.n_points, n);
        // Every piece's result, in file order, covering every row once.
        let mut next = 0;
        for &(first, len) in &merged {
            assert_eq!(first, next);
            next += len;
        }
        assert_eq!(next, n);
        assert!(sum.n_chunks >= 2);
        let t = crate::csv::Table::read(&out).unwrap();
        assert_eq!(t.header, vec!["id", "z_mm", "x_mm", "y_mm", "dy_um", "note", "dx_um", "dz_um"]);
        assert_eq!(t.n_rows(), n);
        let r = n - 7;
        assert_eq!(t.row_text(r), format!("P{r},{}.5,{},0.1,0.25,\"a,{r}\",{r},-1", r % 10, r + 1));
        // A refused point: an input error on its line; no output left behind.
        std::fs::remove_file(&out).unwrap();
        let e = rewrite_points(
            &inp,
            &out,
            ["dx_um", "dy_um", "dz_um"],
            Default::default(),
            |first, _, _| if first > 0 { Err((3, "outside the map".into())) } else { Ok(()) },
            |_| {},
        )
        .unwrap_err();
        let RewriteError::Input(e) = e else { panic!("{e}") };
        // The first refused point in file order: row 3 of the second piece (a comment line and
        // the header come before row 0). The second piece starts where the first run's second
        // partial result did (the first chunk is a short read, so it may hold fewer rows than a
        // piece).
        assert_eq!(e.line, Some(merged[1].0 + 3 + 3), "{e}");
        assert!(e.to_string().contains("outside the map"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn rewrite_points_keeps_passed_through_fields_as_they_were() {
        // Quoted fields with doubled quotes and commas, spaces around numbers, CRLF endings,
        // comments and blank lines between rows, and a quoted number: every passed-through
        // field keeps its value (read back through the general reader), nothing is escaped twice.
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("id,x_mm,y_mm,z_mm,note\r\n");
        let n = 20_000;
        for i in 0..n {
            match i % 5 {
                0 => text.push_str(&format!("\"P\"\"{i}\"\"\",{i}, 2 ,\"3.5\",\"a,b\"\"c\"\r\n")),
                1 => text.push_str(&format!("Q{i},{i}.25,-2,3,plain\n\n# comment\n")),
                2 => text.push_str(&format!("R{i},{i},2,3,ab\"c\n")),
                3 => text.push_str(&format!("  S{i} ,{i},2,3,  \"\"  \n")),
                _ => text.push_str(&format!("T{i},{i},2,3,\n")),
            }
        }
        let inp = write(dir.path(), "in.csv", &text);
        let out = dir.path().join("out.csv");
        rewrite_points(&inp, &out, ["dx_um", "dy_um", "dz_um"], Default::default(), |_, _, _| Ok(()), |_| {})
            .unwrap();
        let a = crate::csv::Table::read(&inp).unwrap();
        let b = crate::csv::Table::read(&out).unwrap();
        assert_eq!(b.n_rows(), n);
        for name in ["id", "note"] {
            assert!(a.str_column(name).unwrap() == b.str_column(name).unwrap(), "{name} differs");
        }
        for name in ["x_mm", "y_mm", "z_mm"] {
            assert!(a.f64_column(name).unwrap() == b.f64_column(name).unwrap(), "{name} differs");
        }
        assert_eq!(b.row_text(0), "\"P\"\"0\"\"\",0,2,3.5,\"a,b\"\"c\",0,0,0");
        assert_eq!(b.row_text(2), "R2,2,2,3,ab\"c,0,0,0");
        assert_eq!(b.row_text(3), "S3,3,2,3,\"\",0,0,0");
    }

    #[test]
    fn rewrite_points_reads_and_writes_parquet_by_extension() {
        use crate::parquet_file::{read_columns, ColumnData};
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("id,x_mm,y_mm,z_mm,t_s\n");
        let n = 9_000;
        for i in 0..n {
            text.push_str(&format!("P{i},{}.125,{},-{}.5,{}\n", i, i % 97, i % 13, i as f64 * 0.001));
        }
        let inp = write(dir.path(), "in.csv", &text);
        let shift = |first: usize, p: &mut [truepos_math::Point3], e: &mut [[f64; 3]]| {
            for (k, (q, d)) in p.iter_mut().zip(e.iter_mut()).enumerate() {
                q.x += 0.1;
                *d = [(first + k) as f64, 0.5, q.z];
            }
            Ok::<(), (usize, String)>(())
        };
        let run = |i: &Path, o: &Path| {
            rewrite_points(i, o, ["dx_um", "dy_um", "dz_um"], Default::default(), shift, |_| {}).unwrap()
        };
        let csv_out = dir.path().join("out.csv");
        let pq_out = dir.path().join("out.parquet");
        assert_eq!(run(&inp, &csv_out).n_points, n);
        assert_eq!(run(&inp, &pq_out).n_points, n);
        // The Parquet output holds the same numbers as the CSV output, bit for bit, with the
        // text column as text and the numeric pass-through column as numbers.
        let want = crate::csv::Table::read(&csv_out).unwrap();
        let got = read_columns(&pq_out).unwrap();
        assert_eq!(got.names, want.header);
        for name in ["x_mm", "y_mm", "z_mm", "t_s", "dx_um", "dy_um", "dz_um"] {
            let a = want.f64_column(name).unwrap();
            let b = got.f64(&pq_out, name).unwrap();
            assert!(a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}");
        }
        assert!(matches!(&got.data[0], ColumnData::Str(v) if v[7] == "P7"));
        // Parquet in, CSV out: byte for byte the CSV route's output, shifted once more.
        let again = dir.path().join("again.csv");
        run(&pq_out, &again);
        let csv_twice = dir.path().join("twice.csv");
        run(&csv_out, &csv_twice);
        assert_eq!(std::fs::read(&again).unwrap(), std::fs::read(&csv_twice).unwrap());
        // A refused point of a Parquet input is named by its row; nothing is written.
        let gone = dir.path().join("gone.csv");
        let e = rewrite_points(
            &pq_out,
            &gone,
            ["dx_um", "dy_um", "dz_um"],
            Default::default(),
            |first, _, _| if first > 0 { Err((5, "outside the map".to_string())) } else { Ok(()) },
            |_| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains(&format!("row {}", PIECE_ROWS + 6)), "{e}");
        assert!(!gone.exists());
    }

    /// Regression (found by the `csv_rewrite` fuzz target): a column name holding a comma was
    /// written back plain, so the output's header split it in two (an unreadable output). Such
    /// a name is refused at its place, and nothing is written.
    #[test]
    fn rewrite_points_refuses_column_names_it_cannot_write_back() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.csv");
        let inp = write(dir.path(), "in.csv", "# c\nid,x_mm,y_mm,z_mm,\"P,x_mm\"\n1,2,3,4,5\n");
        let e = rewrite_points(
            &inp,
            &out,
            ["dx_um", "dy_um", "dz_um"],
            Default::default(),
            |_, _, _| Ok(()),
            |_| {},
        )
        .unwrap_err();
        let RewriteError::Input(e) = e else { panic!("{e}") };
        assert_eq!((e.line, e.column), (Some(2), Some(5)), "{e}");
        assert!(e.to_string().contains("P,x_mm") && e.to_string().contains("comma"), "{e}");
        assert!(!out.exists());
    }

    #[test]
    fn background_writer_writes_in_order_and_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.txt");
        let mut w = BackgroundWriter::new(AtomicFile::create(&p).unwrap());
        for i in 0..100 {
            w.send(format!("{i}\n").into_bytes()).unwrap();
        }
        w.finish().unwrap().commit().unwrap();
        let want: String = (0..100).map(|i| format!("{i}\n")).collect();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), want);
        {
            let mut w = BackgroundWriter::new(AtomicFile::create(dir.path().join("gone.txt")).unwrap());
            w.send(b"partial".to_vec()).unwrap();
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}

//! The binary routes of [`crate::stream::rewrite_points`], streamed in constant memory like the
//! CSV → CSV route: a Parquet or E57 input, or a Parquet output (by extension).
//!
//! - [`rewrite_batches`] (Parquet or E57 in; CSV or Parquet out): a reader thread decodes the
//!   input in batches of `stream::BATCH_ROWS` (32 768) rows ([`ParquetReader`]: one row group's column readers
//!   open at a time, pages decoded as needed; [`E57Source`]: the scans packet by packet); the
//!   calling thread cuts each batch into pieces of [`PIECE_ROWS`] rows for `f` (in parallel, at
//!   the same rows as if the whole file were cut, so `merge` sees the same partial results as
//!   before streaming), and hands the rows to the output: CSV pieces formatted in parallel for a
//!   [`BackgroundWriter`], or columns for a [`ParquetWriter`] (its own thread, one row group in
//!   memory). A Parquet input keeps its column types; E57 gives `x_mm,y_mm,z_mm`. A refused
//!   point is an input error naming its 1-based row.
//! - [`rewrite_csv_to_parquet`] (CSV in, Parquet out): [`CsvStream`] chunks, split and parsed
//!   in pieces in parallel as in the CSV route, written as Parquet columns. A passed-through
//!   column is a number column when **every** value of it in the file is a number, else text —
//!   the rule of the in-memory route before it, kept: since a streamed file cannot be seen whole
//!   before its first row group is written, a first pass reads the file once to decide
//!   (parsing only the passed-through columns, and stopping as soon as each of them has shown
//!   text); a file that cannot be read twice (a pipe) gets every passed-through column as
//!   text. So no value is ever changed: a number column holds exactly the `f64` the text
//!   reads as, a text column the text (a quoted field's doubled quotes made single). A
//!   replaced column (`dx_um,dy_um,dz_um` already in the input) is not read.
//!
//! Every output is atomic: nothing is left at the output path unless every row was written.

use crate::atomic::{AtomicFile, OutputError};
use crate::csv::CsvWriter;
use crate::e57_file::{E57Counts, E57Source};
use crate::parquet_file::{is_parquet, BatchColumn, ParquetReader, ParquetWriter, TextColumn};
use crate::stream::{
    output_plan, unwritable_message, unwritable_name, BackgroundWriter, CsvStream, RewriteError,
    RewriteSummary, Src, PIECE_ROWS,
};
use crate::InputError;
use rayon::prelude::*;
use std::path::Path;
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::{Arc, OnceLock};
use std::thread::JoinHandle;
use truepos_math::Point3;

/// A binary input decoded by a reader thread, batch by batch.
struct Source {
    names: Vec<String>,
    text: Vec<bool>,
    rx: Receiver<Result<Vec<BatchColumn>, InputError>>,
    handle: Option<JoinHandle<()>>,
    /// What an E57 reader skipped: set by the reader thread when it has read every scan.
    e57_counts: Arc<OnceLock<E57Counts>>,
}

impl Source {
    /// Open `input` (Parquet or E57 by extension), check what can be checked before reading
    /// points, and start the reader thread on batches of `batch` rows.
    fn open(input: &Path, batch: usize) -> Result<Self, InputError> {
        let (tx, rx) = sync_channel(2);
        let spawn = |name: &str, work: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(work)
                .map_err(|e| InputError::in_file(input, format!("cannot start the reader: {e}")))
        };
        if is_parquet(input) {
            let mut r = ParquetReader::open(input)?;
            let (names, text) = (r.names().to_vec(), r.is_text().to_vec());
            let handle = spawn(
                "truepos-parquet-reader",
                Box::new(move || loop {
                    match r.next_batch(batch) {
                        Ok(Some(b)) => {
                            if tx.send(Ok(b)).is_err() {
                                return; // the consumer stopped
                            }
                        }
                        Ok(None) => return,
                        Err(e) => {
                            let _ = tx.send(Err(e));
                            return;
                        }
                    }
                }),
            )?;
            Ok(Self { names, text, rx, handle: Some(handle), e57_counts: Arc::default() })
        } else {
            let s = E57Source::open(input)?;
            let e57_counts: Arc<OnceLock<E57Counts>> = Arc::default();
            let counts = Arc::clone(&e57_counts);
            let handle = spawn(
                "truepos-e57-reader",
                Box::new(move || {
                    let r = s.for_each_batch(batch, |pts| {
                        let col = |k: usize| BatchColumn::F64(pts.iter().map(|p| p[k]).collect());
                        tx.send(Ok(vec![col(0), col(1), col(2)])).is_ok()
                    });
                    match r {
                        Ok(c) => {
                            let _ = counts.set(c);
                        }
                        Err(e) => {
                            let _ = tx.send(Err(e));
                        }
                    }
                }),
            )?;
            let names = ["x_mm", "y_mm", "z_mm"].map(String::from).to_vec();
            Ok(Self { names, text: vec![false; 3], rx, handle: Some(handle), e57_counts })
        }
    }

    /// The next batch, `None` after the last. A reader that ended without finishing (a panic of
    /// the decoder) is an input error, never a short file taken for the whole.
    fn next(&mut self, input: &Path) -> Result<Option<Vec<BatchColumn>>, InputError> {
        match self.rx.recv() {
            Ok(b) => b.map(Some),
            Err(_) => match self.handle.take().map(JoinHandle::join) {
                Some(Err(_)) => Err(InputError::in_file(input, "the reader failed on malformed data")),
                _ => Ok(None),
            },
        }
    }

    /// Index of the numeric column `name`, or an error naming it.
    fn number_column(&self, input: &Path, name: &str) -> Result<usize, InputError> {
        match self.names.iter().position(|n| n == name) {
            Some(i) if !self.text[i] => Ok(i),
            Some(_) => Err(InputError::in_file(
                input,
                format!("column '{name}' holds text, a number column is needed"),
            )),
            None => {
                Err(InputError::in_file(input, crate::csv::missing_column_message(input, name, &self.names)))
            }
        }
    }
}

impl Drop for Source {
    /// The reader is stopped and waited for (not left running past the rewrite): with the
    /// channel gone, its next send fails and it returns, after at most the batch it decodes.
    fn drop(&mut self) {
        let (_, closed) = sync_channel(0);
        drop(std::mem::replace(&mut self.rx, closed));
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// The values of a number column (a text column has none: checked before this is asked).
fn numbers(c: &BatchColumn) -> &[f64] {
    match c {
        BatchColumn::F64(v) => v,
        BatchColumn::Text(_) => &[],
    }
}

/// A column name of a binary input that a CSV header cannot carry unchanged, with the reason:
/// a comma, quote or byte-order mark, a line break, surrounding spaces, a leading `#`, empty or
/// repeated (the names `csv::Table` refuses for a Parquet file).
fn csv_unwritable(names: &[String]) -> Option<(usize, String)> {
    if let Some((i, n)) = unwritable_name(names) {
        return Some((i, unwritable_message(n)));
    }
    names.iter().enumerate().find_map(|(i, n)| {
        let why = if n.is_empty() {
            "is empty"
        } else if n.contains(['\n', '\r']) {
            "holds a line break"
        } else if n.trim() != n.as_str() {
            "has spaces around it"
        } else if n.starts_with('#') {
            "starts with '#'"
        } else if names[..i].contains(n) {
            "is repeated"
        } else {
            return None;
        };
        Some((
            i,
            format!(
                "column name '{}' {why}: a CSV header could not carry it unchanged (write Parquet, or rename the column)",
                n.escape_debug()
            ),
        ))
    })
}

/// Where the rows of [`rewrite_batches`] go.
enum Sink {
    Csv(BackgroundWriter),
    Parquet(ParquetWriter),
}

/// [`crate::stream::rewrite_points`] for a Parquet or E57 input (see the module docs), read in
/// batches of `batch` rows (a multiple of [`PIECE_ROWS`]); a Parquet output gets row groups of
/// `group` rows.
#[allow(clippy::too_many_arguments)]
pub(crate) fn rewrite_batches<const N: usize, F, T, M>(
    input: &Path,
    output: &Path,
    extra: [&str; N],
    fmt: crate::num::NumFormat,
    f: F,
    mut merge: M,
    batch: usize,
    group: usize,
) -> Result<RewriteSummary, RewriteError>
where
    F: Fn(usize, &mut [Point3], &mut [[f64; N]]) -> Result<T, (usize, String)> + Sync,
    T: Send,
    M: FnMut(T),
{
    debug_assert!(batch > 0 && batch.is_multiple_of(PIECE_ROWS));
    // Check the output before the work (a bad path is named at once).
    crate::atomic::check_output_path(output)?;
    let mut src = Source::open(input, batch)?;
    let xyz = [
        src.number_column(input, "x_mm")?,
        src.number_column(input, "y_mm")?,
        src.number_column(input, "z_mm")?,
    ];
    let (plan, names) = output_plan(&src.names, xyz, extra);
    let col_names: Vec<String> = src.names.clone();
    let mut sink = if is_parquet(output) {
        let text: Vec<bool> = plan.iter().map(|s| matches!(*s, Src::Pass(c) if src.text[c])).collect();
        Sink::Parquet(ParquetWriter::create_grouped(output, &names, &text, group)?)
    } else {
        if let Some((i, msg)) = csv_unwritable(&src.names) {
            return Err(InputError { column: Some(i + 1), ..InputError::in_file(input, msg) }.into());
        }
        let mut w = BackgroundWriter::new(AtomicFile::create(output)?);
        w.send(format!("{}\n", names.join(",")).into_bytes())?;
        Sink::Csv(w)
    };
    let (mut n_points, mut n_batches) = (0, 0);
    let (mut pts, mut ex): (Vec<Point3>, Vec<[f64; N]>) = (Vec::new(), Vec::new());
    while let Some(mut cols) = src.next(input)? {
        let n = cols.first().map_or(0, BatchColumn::len);
        let first = n_points;
        let [x, y, z] = xyz.map(|i| numbers(&cols[i]));
        pts.clear();
        pts.extend((0..n).map(|i| Point3::new(x[i], y[i], z[i])));
        ex.clear();
        ex.resize(n, [0.0; N]);
        let results: Vec<Result<T, (usize, String)>> = pts
            .par_chunks_mut(PIECE_ROWS)
            .zip(ex.par_chunks_mut(PIECE_ROWS))
            .enumerate()
            .map(|(c, (p, e))| f(first + c * PIECE_ROWS, p, e).map_err(|(r, msg)| (c * PIECE_ROWS + r, msg)))
            .collect();
        for r in results {
            match r {
                Ok(t) => merge(t),
                Err((row, msg)) => {
                    return Err(InputError::in_file(input, format!("row {}: {msg}", first + row + 1)).into())
                }
            }
        }
        match &mut sink {
            Sink::Csv(w) => {
                let wr = &*w;
                let pieces = (0..n.div_ceil(PIECE_ROWS))
                    .into_par_iter()
                    .map(|c| {
                        let mut cw = CsvWriter::new(wr.buffer()).with_format(fmt);
                        for r in c * PIECE_ROWS..((c + 1) * PIECE_ROWS).min(n) {
                            csv_row(&mut cw, &plan, &pts[r], &ex[r], &cols, r).map_err(|e| match e {
                                RowFail::Text(c) => RewriteError::from(
                                    InputError::in_file(
                                        input,
                                        format!(
                                            "row {}: a line break or NUL byte in the text (a CSV cannot carry it; write Parquet)",
                                            first + r + 1
                                        ),
                                    )
                                    .with_column_name(col_names[c].clone()),
                                ),
                                RowFail::Io(e) => {
                                    OutputError::Io { path: output.to_path_buf(), source: e }.into()
                                }
                            })?;
                        }
                        Ok(cw.into_inner())
                    })
                    .collect::<Result<Vec<Vec<u8>>, RewriteError>>()?;
                w.send_all(pieces)?;
            }
            Sink::Parquet(w) => {
                let out = plan
                    .iter()
                    .map(|s| match *s {
                        Src::Point(k) => BatchColumn::F64(pts.iter().map(|p| p[k]).collect()),
                        Src::Extra(k) => BatchColumn::F64(ex.iter().map(|e| e[k]).collect()),
                        Src::Pass(c) => std::mem::replace(&mut cols[c], BatchColumn::F64(Vec::new())),
                    })
                    .collect();
                w.send(out)?;
            }
        }
        n_points += n;
        n_batches += 1;
    }
    match sink {
        Sink::Csv(w) => w.finish()?.commit()?,
        Sink::Parquet(w) => w.finish()?,
    }
    let e57 = src.e57_counts.get().copied().unwrap_or_default();
    Ok(RewriteSummary {
        n_points,
        n_chunks: n_batches,
        skipped_invalid: e57.skipped_invalid,
        skipped_nonfinite: e57.skipped_nonfinite,
    })
}

/// Why a CSV row of [`rewrite_batches`] could not be written: a text value with a line break
/// (in input column `.0`), or the writer.
enum RowFail {
    Text(usize),
    Io(std::io::Error),
}

/// Row `r` of a batch as CSV: the point, the extra values and the passed-through values.
fn csv_row(
    cw: &mut CsvWriter<Vec<u8>>,
    plan: &[Src],
    p: &Point3,
    e: &[f64],
    cols: &[BatchColumn],
    r: usize,
) -> Result<(), RowFail> {
    for s in plan {
        match *s {
            Src::Point(k) => cw.field_f64(p[k]),
            Src::Extra(k) => cw.field_f64(e[k]),
            Src::Pass(c) => match &cols[c] {
                BatchColumn::F64(v) => cw.field_f64(v[r]),
                BatchColumn::Text(t) => {
                    let s = t.get(r);
                    // A CSV field cannot hold a line break (the readers take it for a row's end),
                    // nor a NUL byte (they take it for a binary file).
                    if s.contains(['\n', '\r', '\0']) {
                        return Err(RowFail::Text(c));
                    }
                    cw.field_str(s)
                }
            },
        }
        .map_err(RowFail::Io)?;
    }
    cw.end_row().map_err(RowFail::Io)
}

/// Which passed-through columns (`pass`, input column indices) hold a number in every row of
/// the file (`numeric[c]`): a first pass over the file, parsing only those columns and ending
/// as soon as each has shown text. A file that cannot be read twice (not a regular file: a
/// pipe) is not read here, and every passed-through column is text.
fn numeric_columns(input: &Path, pass: &[usize], width: usize) -> Result<Vec<bool>, InputError> {
    let mut numeric = vec![false; width];
    let regular = std::fs::metadata(input).is_ok_and(|m| m.is_file());
    if pass.is_empty() || !regular {
        return Ok(numeric);
    }
    let mut open: Vec<usize> = pass.to_vec();
    let mut s = CsvStream::open(input)?;
    while !open.is_empty() {
        let Some(chunk) = s.next_chunk()? else { break };
        // All at once (the common case: they all are numbers), else one by one.
        if chunk.f64_columns_at(&open).is_err() {
            open.retain(|&c| chunk.f64_columns_at(&[c]).is_ok());
        }
        s.recycle(chunk);
    }
    for c in open {
        numeric[c] = true;
    }
    Ok(numeric)
}

/// [`crate::stream::rewrite_points`] for a CSV input and a Parquet output (see the module docs),
/// in row groups of `group` rows.
pub(crate) fn rewrite_csv_to_parquet<const N: usize, F, T, M>(
    input: &Path,
    output: &Path,
    extra: [&str; N],
    f: F,
    mut merge: M,
    group: usize,
) -> Result<RewriteSummary, RewriteError>
where
    F: Fn(usize, &mut [Point3], &mut [[f64; N]]) -> Result<T, (usize, String)> + Sync,
    T: Send,
    M: FnMut(T),
{
    crate::atomic::check_output_path(output)?;
    let mut s = CsvStream::open(input)?;
    if let Some((i, n)) = unwritable_name(s.header()) {
        return Err(InputError::at(input, s.header_line(), Some(i + 1), unwritable_message(n)).into());
    }
    let xyz = [s.require("x_mm")?, s.require("y_mm")?, s.require("z_mm")?];
    let header = s.header().to_vec();
    let width = header.len();
    let (plan, names) = output_plan(&header, xyz, extra);
    let pass: Vec<usize> =
        plan.iter().filter_map(|s| if let Src::Pass(c) = *s { Some(c) } else { None }).collect();
    let numeric = numeric_columns(input, &pass, width)?;
    // Parsed per row: the point, then the numeric passed-through columns (`slot[c]`: where).
    let mut idx: Vec<usize> = xyz.to_vec();
    let mut slot: Vec<Option<usize>> = vec![None; width];
    for &c in &pass {
        if numeric[c] {
            slot[c] = Some(idx.len());
            idx.push(c);
        }
    }
    let text: Vec<bool> = plan.iter().map(|s| matches!(*s, Src::Pass(c) if !numeric[c])).collect();
    let mut w = ParquetWriter::create_grouped(output, &names, &text, group)?;
    let (mut n_points, mut n_chunks) = (0, 0);
    while let Some(chunk) = s.next_chunk()? {
        let n = chunk.n_rows();
        let first = chunk.first_row();
        let k = idx.len();
        let piece = |range: std::ops::Range<usize>| -> Result<(Vec<BatchColumn>, T), InputError> {
            let m = range.len();
            let mut vals = vec![0.0; m * k];
            let mut fields = Vec::with_capacity(m * width);
            chunk.split_parse_rows_flat(range.clone(), &idx, &mut vals, &mut fields)?;
            let mut pts: Vec<Point3> =
                (0..m).map(|i| Point3::new(vals[i * k], vals[i * k + 1], vals[i * k + 2])).collect();
            let mut ex = vec![[0.0; N]; m];
            let t = f(first + range.start, &mut pts, &mut ex)
                .map_err(|(r, msg)| InputError::at(input, chunk.line_number(range.start + r), None, msg))?;
            let cols = plan
                .iter()
                .map(|s| match *s {
                    Src::Point(q) => BatchColumn::F64(pts.iter().map(|p| p[q]).collect()),
                    Src::Extra(q) => BatchColumn::F64(ex.iter().map(|e| e[q]).collect()),
                    Src::Pass(c) => match slot[c] {
                        Some(j) => BatchColumn::F64((0..m).map(|i| vals[i * k + j]).collect()),
                        None => BatchColumn::Text(
                            (0..m).map(|i| chunk.field_value(fields[i * width + c])).collect::<TextColumn>(),
                        ),
                    },
                })
                .collect();
            Ok((cols, t))
        };
        let results: Vec<Result<(Vec<BatchColumn>, T), InputError>> = (0..n.div_ceil(PIECE_ROWS))
            .into_par_iter()
            .map(|c| piece(c * PIECE_ROWS..((c + 1) * PIECE_ROWS).min(n)))
            .collect();
        // Piece by piece to the writer (which gathers them into row groups): no copy of the
        // whole chunk's columns, and little in flight.
        for r in results {
            let (cols, t) = r?;
            merge(t);
            w.send(cols)?;
        }
        n_points += n;
        n_chunks += 1;
        s.recycle(chunk);
    }
    w.finish()?;
    Ok(RewriteSummary { n_points, n_chunks, skipped_invalid: 0, skipped_nonfinite: 0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::NumFormat;
    use crate::parquet_file::{read_columns, write_columns_grouped, ColumnData, Columns};
    use crate::stream::rewrite_points;

    const EXTRA: [&str; 3] = ["dx_um", "dy_um", "dz_um"];

    /// The transform of these tests: x moved, the extra values from the row and the point.
    fn shift(first: usize, p: &mut [Point3], e: &mut [[f64; 3]]) -> Result<(usize, usize), (usize, String)> {
        for (k, (q, d)) in p.iter_mut().zip(e.iter_mut()).enumerate() {
            q.x += 0.1;
            *d = [(first + k) as f64, 0.5, q.z * 3.0];
        }
        Ok((first, p.len()))
    }

    fn row_groups(path: &Path) -> usize {
        use ::parquet::file::reader::{FileReader, SerializedFileReader};
        SerializedFileReader::new(std::fs::File::open(path).unwrap()).unwrap().num_row_groups()
    }

    /// A Parquet input of `n` rows in row groups of `group`: text `id`, the point, a number
    /// column `t_s` and an old `dy_um` column (replaced).
    fn parquet_input(path: &Path, n: usize, group: usize) -> Columns {
        let f = |g: &dyn Fn(usize) -> f64| ColumnData::F64((0..n).map(g).collect());
        let c = Columns {
            names: ["id", "x_mm", "y_mm", "z_mm", "t_s", "dy_um"].map(String::from).to_vec(),
            data: vec![
                ColumnData::Str((0..n).map(|i| format!("P{i}")).collect()),
                f(&|i| (i as f64).sqrt() * 0.37),
                f(&|i| -(i as f64) / 3.0),
                f(&|i| 1e-3 * i as f64 + 0.1),
                f(&|i| i as f64 * 0.001),
                f(&|_| 99.0),
            ],
        };
        // A file this process read is an input: an output onto it is refused, so it goes first.
        let _ = std::fs::remove_file(path);
        write_columns_grouped(path, &c, group).unwrap();
        c
    }

    /// What the rewrite of `input` must give, computed on the whole columns at once (the
    /// in-memory route this streaming replaced): x moved, `dy_um` replaced, `dx_um,dz_um`
    /// appended.
    fn expected(input: &Columns) -> Columns {
        let n = input.n_rows();
        let mut out = input.clone();
        let mut pts: Vec<Point3> = (0..n)
            .map(|i| {
                let v = |name: &str| match &input.data[input.index(name).unwrap()] {
                    ColumnData::F64(v) => v[i],
                    ColumnData::Str(_) => panic!("{name} is text"),
                };
                Point3::new(v("x_mm"), v("y_mm"), v("z_mm"))
            })
            .collect();
        let mut ex = vec![[0.0; 3]; n];
        for (c, (p, e)) in pts.chunks_mut(PIECE_ROWS).zip(ex.chunks_mut(PIECE_ROWS)).enumerate() {
            shift(c * PIECE_ROWS, p, e).unwrap();
        }
        for (k, name) in ["x_mm", "y_mm", "z_mm"].iter().enumerate() {
            let i = out.index(name).unwrap();
            out.data[i] = ColumnData::F64(pts.iter().map(|p| p[k]).collect());
        }
        for (k, name) in EXTRA.iter().enumerate() {
            let v = ColumnData::F64(ex.iter().map(|e| e[k]).collect());
            match out.index(name) {
                Some(i) => out.data[i] = v,
                None => {
                    out.names.push(name.to_string());
                    out.data.push(v);
                }
            }
        }
        out
    }

    /// The columns as CSV, the way the in-memory route wrote them.
    fn as_csv(c: &Columns, fmt: NumFormat) -> Vec<u8> {
        let mut w = CsvWriter::new(Vec::new()).with_format(fmt);
        w.header(&c.names.iter().map(String::as_str).collect::<Vec<_>>()).unwrap();
        for r in 0..c.n_rows() {
            for d in &c.data {
                match d {
                    ColumnData::F64(v) => w.field_f64(v[r]).unwrap(),
                    ColumnData::Str(v) => w.field_str(&v[r]).unwrap(),
                }
            }
            w.end_row().unwrap();
        }
        w.into_inner()
    }

    /// Regression for the streamed Parquet route: an input of several row groups read in
    /// batches that cross them, into outputs of several row groups. Pieces start where they
    /// would on the whole file; the outputs are the in-memory route's, byte for byte.
    #[test]
    fn parquet_input_streams_across_row_groups_with_the_whole_file_results() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.parquet");
        let n: usize = 30_000;
        let cols = parquet_input(&inp, n, 7_000);
        assert_eq!(row_groups(&inp), 5);
        let want = expected(&cols);
        let batch = 2 * PIECE_ROWS; // batches end inside row groups and cross them
        let mut merged = Vec::new();
        let pq_out = dir.path().join("out.parquet");
        let sum = rewrite_batches(
            &inp,
            &pq_out,
            EXTRA,
            NumFormat::Shortest,
            shift,
            |t| merged.push(t),
            batch,
            5_000,
        )
        .unwrap();
        assert_eq!((sum.n_points, sum.n_chunks), (n, n.div_ceil(batch)));
        let starts: Vec<usize> = merged.iter().map(|t| t.0).collect();
        assert_eq!(starts, (0..n).step_by(PIECE_ROWS).collect::<Vec<_>>());
        assert_eq!(merged.iter().map(|t| t.1).sum::<usize>(), n);
        // Column types kept (text stays text), values bit for bit: the same file as writing the
        // whole columns at once.
        assert_eq!(row_groups(&pq_out), 6);
        assert_eq!(read_columns(&pq_out).unwrap(), want);
        let whole = dir.path().join("whole.parquet");
        write_columns_grouped(&whole, &want, 5_000).unwrap();
        assert_eq!(std::fs::read(&pq_out).unwrap(), std::fs::read(&whole).unwrap());
        // Through `rewrite_points` (batches of BATCH_ROWS, row groups of ROW_GROUP).
        let pq_default = dir.path().join("default.parquet");
        rewrite_points(&inp, &pq_default, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        write_columns_grouped(&whole, &want, crate::parquet_file::ROW_GROUP).unwrap();
        assert_eq!(std::fs::read(&pq_default).unwrap(), std::fs::read(&whole).unwrap());
        // CSV out: the in-memory route's text, whatever the batch size.
        for fmt in [NumFormat::Shortest, NumFormat::Fixed(4)] {
            let csv_out = dir.path().join("out.csv");
            rewrite_batches(&inp, &csv_out, EXTRA, fmt, shift, |_| {}, batch, 5_000).unwrap();
            assert_eq!(std::fs::read(&csv_out).unwrap(), as_csv(&want, fmt));
            rewrite_points(&inp, &csv_out, EXTRA, fmt, shift, |_| {}).unwrap();
            assert_eq!(std::fs::read(&csv_out).unwrap(), as_csv(&want, fmt));
        }
    }

    /// A point refused in a later row group (and a later batch) is named by its 1-based row;
    /// nothing is left at the output, Parquet or CSV.
    #[test]
    fn a_refused_point_in_a_later_row_group_names_its_row_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.parquet");
        parquet_input(&inp, 30_000, 7_000);
        let bad = 19_999; // row 20 000, in the third row group and the third batch
        let refuse = |first: usize, p: &mut [Point3], _: &mut [[f64; 3]]| {
            if (first..first + p.len()).contains(&bad) {
                Err((bad - first, "outside the map".to_string()))
            } else {
                Ok(())
            }
        };
        for name in ["out.parquet", "out.csv"] {
            let out = dir.path().join(name);
            let e = rewrite_batches(
                &inp,
                &out,
                EXTRA,
                NumFormat::Shortest,
                refuse,
                |_| {},
                2 * PIECE_ROWS,
                5_000,
            )
            .unwrap_err();
            let RewriteError::Input(e) = e else { panic!("{e}") };
            assert_eq!(e.to_string(), format!("{}: row 20000: outside the map", inp.display()));
            assert!(!out.exists(), "{name}");
            assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "a temporary file is left");
        }
        // A non-finite value in a later row group: named by row and column, nothing written.
        let mut c = parquet_input(&inp, 30_000, 7_000);
        if let ColumnData::F64(v) = &mut c.data[2] {
            v[25_000] = f64::INFINITY;
        }
        write_columns_grouped(&inp, &c, 7_000).unwrap();
        let out = dir.path().join("out.parquet");
        let e = rewrite_batches(&inp, &out, EXTRA, NumFormat::Shortest, shift, |_| {}, 2 * PIECE_ROWS, 5_000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 25001") && e.contains("y_mm") && e.contains("not a finite number"), "{e}");
        assert!(!out.exists());
    }

    /// CSV in, Parquet out, over several chunks and row groups: numbers bit for bit as the CSV
    /// reads them; a passed-through column is a number column only when every value in the file
    /// is a number (one text value in the last row keeps the whole column text, as written); a
    /// quoted field's doubled quotes are one quote in the value.
    #[test]
    fn csv_to_parquet_streams_and_decides_column_types_on_the_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("# c\nid,x_mm,y_mm,z_mm,t_s,late,q,dy_um\n");
        let n = 150_000;
        for i in 0..n {
            let late = if i == n - 1 { "n/a".to_string() } else { format!("{i}.50") };
            text.push_str(&format!(
                "P{i},{}.125,{},-{}.5,{},{late},\"a\"\"{i}\",7\n",
                i,
                i % 97,
                i % 13,
                i as f64 * 0.001
            ));
        }
        assert!(text.len() > 2 * crate::stream::BLOCK_BYTES);
        let inp = dir.path().join("in.csv");
        std::fs::write(&inp, &text).unwrap();
        let out = dir.path().join("out.parquet");
        let mut merged = Vec::new();
        let sum = rewrite_csv_to_parquet(&inp, &out, EXTRA, shift, |t| merged.push(t), 40_000).unwrap();
        assert_eq!(sum.n_points, n);
        assert!(sum.n_chunks >= 2, "{sum:?}");
        assert_eq!(merged.iter().map(|t| t.1).sum::<usize>(), n);
        assert_eq!(row_groups(&out), 4);
        let got = read_columns(&out).unwrap();
        assert_eq!(got.names, ["id", "x_mm", "y_mm", "z_mm", "t_s", "late", "q", "dy_um", "dx_um", "dz_um"]);
        // The CSV route's output holds the same numbers.
        let csv_out = dir.path().join("out.csv");
        rewrite_points(&inp, &csv_out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        let want = crate::csv::Table::read(&csv_out).unwrap();
        for name in ["x_mm", "y_mm", "z_mm", "t_s", "dx_um", "dy_um", "dz_um"] {
            let a = want.f64_column(name).unwrap();
            let b = got.f64(&out, name).unwrap();
            assert!(a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}");
        }
        let text_of = |name: &str| match &got.data[got.index(name).unwrap()] {
            ColumnData::Str(v) => v.clone(),
            ColumnData::F64(_) => panic!("{name} is a number column"),
        };
        let late = text_of("late");
        assert_eq!((late[0].as_str(), late[n - 1].as_str()), ("0.50", "n/a"));
        assert_eq!(text_of("q")[12], "a\"12");
        assert_eq!(text_of("id")[n - 1], format!("P{}", n - 1));
        // A refused point: an input error on its line, nothing written.
        std::fs::remove_file(&out).unwrap();
        let e = rewrite_csv_to_parquet(
            &inp,
            &out,
            EXTRA,
            |first, _, _| if first > 100_000 { Err((2, "outside the map".to_string())) } else { Ok(()) },
            |_| {},
            40_000,
        )
        .unwrap_err();
        let RewriteError::Input(e) = e else { panic!("{e}") };
        let line = e.line.unwrap();
        assert!(line > 100_000 + 3 && e.to_string().contains("outside the map"), "{e}");
        assert!(!out.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2, "only in.csv and out.csv");
    }

    /// A CSV read from a pipe cannot be read twice: its passed-through columns are text, their
    /// values as written.
    #[cfg(unix)]
    #[test]
    fn csv_from_a_pipe_keeps_passed_through_columns_as_text() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("in.csv");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("SKIPPED: no mkfifo");
            return;
        }
        let f2 = fifo.clone();
        let writer = std::thread::spawn(move || {
            let mut text = String::from("x_mm,y_mm,z_mm,t_s\n");
            for i in 0..1000 {
                text.push_str(&format!("{i},1,2,{i}.0\n"));
            }
            std::fs::write(f2, text).unwrap();
        });
        let out = dir.path().join("out.parquet");
        rewrite_points(&fifo, &out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        writer.join().unwrap();
        let got = read_columns(&out).unwrap();
        match &got.data[3] {
            ColumnData::Str(v) => assert_eq!((v.len(), v[7].as_str()), (1000, "7.0")),
            ColumnData::F64(_) => panic!("t_s is a number column"),
        }
        assert!(matches!(&got.data[0], ColumnData::F64(v) if v[7] == 7.0 + 0.1));
    }

    /// E57 in, streamed scan by scan in batches: the points as `read_e57` gives them, pieces at
    /// the whole file's rows, a refused point named by its row.
    #[test]
    fn e57_input_streams_in_batches() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.e57");
        let n: usize = 10_000;
        let pts: Vec<Point3> = (0..n).map(|i| Point3::new(i as f64 * 0.25, -(i as f64), 12.5)).collect();
        crate::e57_file::write_e57(&inp, &pts).unwrap();
        let read = crate::e57_file::read_e57(&inp).unwrap().points;
        let cols = Columns {
            names: ["x_mm", "y_mm", "z_mm"].map(String::from).to_vec(),
            data: (0..3).map(|k| ColumnData::F64(read.iter().map(|p| p[k]).collect())).collect(),
        };
        let want = expected(&cols);
        let mut merged = Vec::new();
        let csv_out = dir.path().join("out.csv");
        let sum = rewrite_batches(
            &inp,
            &csv_out,
            EXTRA,
            NumFormat::Shortest,
            shift,
            |t| merged.push(t),
            PIECE_ROWS,
            4,
        )
        .unwrap();
        assert_eq!((sum.n_points, sum.n_chunks), (n, n.div_ceil(PIECE_ROWS)));
        assert_eq!(merged.iter().map(|t| t.0).collect::<Vec<_>>(), vec![0, PIECE_ROWS, 2 * PIECE_ROWS]);
        assert_eq!(std::fs::read(&csv_out).unwrap(), as_csv(&want, NumFormat::Shortest));
        let pq_out = dir.path().join("out.parquet");
        rewrite_points(&inp, &pq_out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        assert_eq!(read_columns(&pq_out).unwrap(), want);
        let gone = dir.path().join("gone.csv");
        let e = rewrite_batches(
            &inp,
            &gone,
            EXTRA,
            NumFormat::Shortest,
            |first, _, _| if first > 0 { Err((9, "outside the map".to_string())) } else { Ok(()) },
            |_| {},
            PIECE_ROWS,
            4,
        )
        .unwrap_err();
        assert_eq!(e.to_string(), format!("{}: row {}: outside the map", inp.display(), PIECE_ROWS + 10));
        assert!(!gone.exists());
    }

    /// Column names a CSV header cannot carry (here a line break, from a Parquet input) are
    /// refused before anything is written.
    #[test]
    fn binary_column_names_a_csv_cannot_carry_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.parquet");
        // The writer takes only plain names: the file is made with the `parquet` crate directly.
        {
            use ::parquet::data_type::DoubleType;
            use ::parquet::file::writer::SerializedFileWriter;
            let schema = ::parquet::schema::types::Type::group_type_builder("t")
                .with_fields(
                    ["x_mm", "y_mm", "z_mm", "a\nb"]
                        .iter()
                        .map(|n| {
                            std::sync::Arc::new(
                                ::parquet::schema::types::Type::primitive_type_builder(
                                    n,
                                    ::parquet::basic::Type::DOUBLE,
                                )
                                .with_repetition(::parquet::basic::Repetition::REQUIRED)
                                .build()
                                .unwrap(),
                            )
                        })
                        .collect(),
                )
                .build()
                .unwrap();
            let file = std::fs::File::create(&inp).unwrap();
            let mut w =
                SerializedFileWriter::new(file, std::sync::Arc::new(schema), Default::default()).unwrap();
            let mut rg = w.next_row_group().unwrap();
            while let Some(mut c) = rg.next_column().unwrap() {
                c.typed::<DoubleType>().write_batch(&[1.0, 2.0], None, None).unwrap();
                c.close().unwrap();
            }
            rg.close().unwrap();
            w.close().unwrap();
        }
        let out = dir.path().join("out.csv");
        let e = rewrite_points(&inp, &out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap_err();
        let RewriteError::Input(e) = e else { panic!("{e}") };
        assert_eq!(e.column, Some(4), "{e}");
        assert!(!out.exists());
    }

    /// Inputs without rows: a CSV output of just the header, a Parquet output of no rows with
    /// every column (one empty row group, as `write_columns` writes it).
    #[test]
    fn inputs_without_rows_give_outputs_without_rows() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("empty.parquet");
        let none = Columns {
            names: ["id", "x_mm", "y_mm", "z_mm"].map(String::from).to_vec(),
            data: vec![
                ColumnData::Str(vec![]),
                ColumnData::F64(vec![]),
                ColumnData::F64(vec![]),
                ColumnData::F64(vec![]),
            ],
        };
        crate::parquet_file::write_columns(&inp, &none).unwrap();
        let csv_out = dir.path().join("out.csv");
        let sum = rewrite_points(&inp, &csv_out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        assert_eq!(sum.n_points, 0);
        assert_eq!(std::fs::read_to_string(&csv_out).unwrap(), "id,x_mm,y_mm,z_mm,dx_um,dy_um,dz_um\n");
        let pq_out = dir.path().join("out.parquet");
        rewrite_points(&inp, &pq_out, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        let got = read_columns(&pq_out).unwrap();
        assert_eq!((got.names.len(), got.n_rows(), row_groups(&pq_out)), (7, 0, 1));
        let csv_in = dir.path().join("empty.csv");
        std::fs::write(&csv_in, "# nothing yet\nid,x_mm,y_mm,z_mm\n").unwrap();
        // A file read once is an input of this process: the next output gets its own name.
        let pq_out2 = dir.path().join("out2.parquet");
        rewrite_points(&csv_in, &pq_out2, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
        assert_eq!(read_columns(&pq_out2).unwrap().n_rows(), 0);
    }

    /// Text a CSV field cannot carry (a line break, a NUL byte) is refused on the way to CSV,
    /// named by row and column, nothing written; Parquet carries it unchanged.
    #[test]
    fn text_a_csv_cannot_carry_is_refused_for_csv_only() {
        let dir = tempfile::tempdir().unwrap();
        let inp = dir.path().join("in.parquet");
        for bad in ["a\nb", "a\0b"] {
            let mut ids: Vec<String> = (0..10).map(|i| format!("P{i}")).collect();
            ids[3] = bad.to_string();
            let c = Columns {
                names: ["id", "x_mm", "y_mm", "z_mm"].map(String::from).to_vec(),
                data: vec![
                    ColumnData::Str(ids),
                    ColumnData::F64(vec![1.0; 10]),
                    ColumnData::F64(vec![2.0; 10]),
                    ColumnData::F64(vec![3.0; 10]),
                ],
            };
            let _ = std::fs::remove_file(&inp);
            crate::parquet_file::write_columns(&inp, &c).unwrap();
            let out = dir.path().join("out.csv");
            let e = rewrite_points(&inp, &out, EXTRA, NumFormat::Shortest, shift, |_| {})
                .unwrap_err()
                .to_string();
            assert!(e.contains("row 4") && e.contains("id") && e.contains("line break or NUL"), "{e}");
            assert!(!out.exists());
            // A name of its own per case: the first case's output was read back (an input of
            // this process since), and an output onto an input is refused.
            let pq = dir.path().join(format!("out{}.parquet", bad.len() + usize::from(bad.contains('\0'))));
            rewrite_points(&inp, &pq, EXTRA, NumFormat::Shortest, shift, |_| {}).unwrap();
            assert!(matches!(&read_columns(&pq).unwrap().data[0], ColumnData::Str(v) if v[3] == bad));
        }
    }

    /// A writer dropped before `finish` leaves nothing behind.
    #[test]
    fn an_unfinished_parquet_writer_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.parquet");
        {
            let mut w = ParquetWriter::create_grouped(&out, &["x_mm", "id"], &[false, true], 3).unwrap();
            let ids: TextColumn = ["a", "b", "c", "d"].into_iter().collect();
            w.send(vec![BatchColumn::F64(vec![1.0, 2.0, 3.0, 4.0]), BatchColumn::Text(ids)]).unwrap();
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        // A batch of the wrong kinds is refused, and nothing is left either.
        let mut w = ParquetWriter::create(&out, &["x_mm"], &[false]).unwrap();
        assert!(w.send(vec![BatchColumn::Text(TextColumn::default())]).is_err());
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}

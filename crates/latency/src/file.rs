//! The stream files of delay calibration, defined once: [`read_stream`] reads `t_s` and three
//! value columns of a CSV ([`read_streams`]: the machine and probe files at once; plain CSV is
//! parsed straight from the text, without a row index, unless the table is needed later);
//! [`input_error`] turns a [`LatencyError`] about a stream into an input error naming the file
//! and line; [`write_centres`] writes the stylus centres of `truepos latency apply`.

use crate::{LatencyError, Which};
use std::io::Write;
use std::path::{Path, PathBuf};
use truepos_io::atomic::AtomicFile;
use truepos_io::csv::Table;
use truepos_io::InputError;

/// A stream read from a CSV file.
pub struct StreamFile {
    /// The file's path, as given.
    pub path: PathBuf,
    /// The indexed table, when the file was read through one (`keep_table`, or a file that is
    /// not plain CSV); `None` when the columns were parsed straight from the text (an error
    /// about a row then reads the table to name its line).
    pub table: Option<Table>,
    /// Time stamps, s (master clock), increasing.
    pub t: Vec<f64>,
    /// The three values per sample (machine x, y, z or probe a, b, c), mm.
    pub v: Vec<[f64; 3]>,
}

/// Read `t_s` and three value columns. `keep_table`: go through the indexed table and keep it
/// (to copy other columns row by row); otherwise plain CSV is parsed straight from the text and
/// anything else (or any bad value) takes the table's path, whose errors name file:line:col.
pub fn read_stream(path: &Path, cols: [&str; 3], keep_table: bool) -> Result<StreamFile, InputError> {
    let names = ["t_s", cols[0], cols[1], cols[2]];
    let table = if keep_table {
        Table::read(path)?
    } else {
        match Table::read_stream_direct(path, &names)? {
            Ok((t, v)) => return Ok(StreamFile { path: path.to_path_buf(), table: None, t, v }),
            Err(table) => table,
        }
    };
    let all = table.f64_columns(&names)?;
    let mut t = Vec::with_capacity(all.len() / 4);
    let mut v = Vec::with_capacity(all.len() / 4);
    for c in all.chunks_exact(4) {
        t.push(c[0]);
        v.push([c[1], c[2], c[3]]);
    }
    Ok(StreamFile { path: path.to_path_buf(), table: Some(table), t, v })
}

/// Read the machine stream (`t_s,x_mm,y_mm,z_mm`) and the probe stream (`t_s,a_mm,b_mm,c_mm`)
/// at the same time (each read is itself parallel; reading both at once overlaps their serial
/// parts: mapping, header, allocation). A bad machine file is reported before a bad probe file.
/// `keep_probe_table`: keep the probe file's table (see [`read_stream`]).
pub fn read_streams(
    machine: &Path,
    probe: &Path,
    keep_probe_table: bool,
) -> Result<(StreamFile, StreamFile), InputError> {
    let (m, p) = rayon::join(
        || read_stream(machine, crate::task::MACHINE_COLUMNS, false),
        || read_stream(probe, crate::task::PROBE_COLUMNS, keep_probe_table),
    );
    Ok((m?, p?))
}

/// Turn a library error into an input error naming the file and line where there is one.
pub fn input_error(e: LatencyError, machine: &StreamFile, probe: &StreamFile) -> InputError {
    let pick = |w: Which| if w == Which::Machine { machine } else { probe };
    let at = |w: Which, index: usize, msg: String| {
        let f = pick(w);
        // Parsed without a table: read it now to name the row's line (an error path only).
        let read;
        let table = match &f.table {
            Some(t) => Some(t),
            None => {
                read = Table::read(&f.path).ok();
                read.as_ref()
            }
        };
        let line = table.filter(|t| index < t.n_rows()).map_or(0, |t| t.line_number(index));
        let col = table.and_then(|t| t.column("t_s")).map(|c| c + 1);
        InputError::at(&f.path, line, col, msg).with_column_name("t_s")
    };
    match &e {
        LatencyError::DuplicateStamp { which, index, t } => {
            at(*which, *index, format!("duplicate time stamp {t} s (same as the previous row)"))
        }
        LatencyError::NotIncreasing { which, index, t, previous } => at(
            *which,
            *index,
            format!("time stamps must increase: {t} s follows {previous} s (sort the file by t_s)"),
        ),
        LatencyError::NotFinite { which, index } => at(*which, *index, "value is not finite".into()),
        LatencyError::TooShort { which, n } => {
            InputError::in_file(&pick(*which).path, format!("{n} data row(s); at least two are needed"))
        }
        LatencyError::NoOverlap { .. } => {
            InputError::in_file(&probe.path, format!("{e} (with {})", machine.path.display()))
        }
        LatencyError::NoContact(_) => InputError::in_file(&probe.path, e.to_string()),
        _ => InputError::new(e.to_string()),
    }
}

/// Write stylus-centre positions at the probe stamps (`t_s,x_mm,y_mm,z_mm`, then the probe file's
/// other columns unchanged), atomically, as Parquet for a `.parquet` path (the comment line has
/// no place there) else CSV; rows whose centre is NaN (machine data not covering
/// `t + delay`) are left out. The probe stream must have been read with its table
/// ([`read_stream`]'s `keep_table`).
pub fn write_centres(path: &Path, delay_s: f64, probe: &StreamFile, out: &[[f64; 3]]) -> std::io::Result<()> {
    let Some(table) = &probe.table else {
        return Err(std::io::Error::other("the probe stream was read without its table"));
    };
    // Pass through the probe file's other columns.
    let used = ["t_s", "a_mm", "b_mm", "c_mm", "x_mm", "y_mm", "z_mm"];
    let extra: Vec<usize> =
        (0..table.header.len()).filter(|&i| !used.contains(&table.header[i].as_str())).collect();
    if truepos_io::parquet_file::is_parquet(path) {
        use truepos_io::parquet_file::{write_columns, ColumnData, Columns};
        let keep: Vec<usize> = (0..out.len()).filter(|&i| !out[i][0].is_nan()).collect();
        let mut names: Vec<String> = ["t_s", "x_mm", "y_mm", "z_mm"].map(String::from).to_vec();
        let mut data = vec![ColumnData::F64(keep.iter().map(|&i| probe.t[i]).collect())];
        for k in 0..3 {
            data.push(ColumnData::F64(keep.iter().map(|&i| out[i][k]).collect()));
        }
        for &c in &extra {
            let name = &table.header[c];
            // A passed-through column stays a number column when every kept value is a number.
            let all = table.f64_column(name).ok();
            data.push(match all {
                Some(v) => ColumnData::F64(keep.iter().map(|&i| v[i]).collect()),
                None => {
                    let s = table.str_column(name).map_err(std::io::Error::other)?;
                    ColumnData::Str(keep.iter().map(|&i| s[i].clone()).collect())
                }
            });
            names.push(name.clone());
        }
        return Ok(write_columns(path, &Columns { names, data })?);
    }
    let mut f = AtomicFile::create(path)?;
    {
        let mut w = truepos_io::csv::CsvWriter::new(std::io::BufWriter::new(&mut f));
        w.comment(&format!("stylus centre = machine(t + {} s) + deflection(t)", delay_s))?;
        let mut names: Vec<&str> = vec!["t_s", "x_mm", "y_mm", "z_mm"];
        names.extend(extra.iter().map(|&i| table.header[i].as_str()));
        w.header(&names)?;
        let mut buf = Vec::new();
        for (i, p) in out.iter().enumerate() {
            if p[0].is_nan() {
                continue;
            }
            w.field_f64(probe.t[i])?;
            for x in p {
                w.field_f64(*x)?;
            }
            if !extra.is_empty() {
                let fields = table.fields(i, &mut buf).map_err(std::io::Error::other)?;
                for &c in &extra {
                    w.field_str(fields[c])?;
                }
            }
            w.end_row()?;
        }
        w.into_inner().flush()?;
    }
    Ok(f.commit()?)
}

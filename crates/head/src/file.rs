//! The points file of head-offset calibration, defined once: [`read_input`] reads it into
//! [`Reading`]s (degrees → radians, `face`/`group` ids interned); [`head_error`] names the file
//! and line of a solver error that concerns one reading.

use crate::{HeadError, Reading};
use std::io::Write;
use std::path::Path;
use truepos_io::atomic::AtomicFile;
use truepos_io::csv::CsvWriter;
use truepos_io::csv::Table;
use truepos_io::InputError;
use truepos_math::{Point3, Vector3};

/// The readings of a points file.
pub struct Input {
    /// The readings, in file order.
    pub readings: Vec<Reading>,
    /// The parsed file (for line numbers in messages).
    pub table: Table,
    /// The `face` ids as written, indexed by `Reading::face`.
    pub face_names: Vec<String>,
    /// The `group` ids as written, indexed by `Reading::group`.
    pub group_names: Vec<String>,
}

fn missing_angles(table: &Table, name: &str) -> InputError {
    InputError::in_file(
        &table.path,
        format!(
            "missing column '{name}': head-offset needs the head swivel angle B and the table angle C of every \
             reading (columns b_deg,c_deg in degrees; write 0 for an axis the machine does not have) \
             (columns: {})",
            table.header.join(",")
        ),
    )
}

/// Row ids (index into the names) and the distinct names in order of appearance.
type IdColumn = (Vec<Option<i64>>, Vec<String>);

/// An id column (`face`, `group`) if present: any text, interned; empty fields have no id.
/// Returns the index of each row's id and the distinct ids in order of appearance.
fn id_column(table: &Table, name: &str) -> Result<Option<IdColumn>, InputError> {
    if table.column(name).is_none() {
        return Ok(None);
    }
    let values = table.str_column(name)?;
    let mut names: Vec<String> = Vec::new();
    let mut index = std::collections::HashMap::new();
    let ids = values
        .iter()
        .map(|v| {
            let v = v.trim();
            if v.is_empty() {
                return None;
            }
            let k = *index.entry(v.to_string()).or_insert_with(|| {
                names.push(v.to_string());
                names.len() - 1
            });
            Some(k as i64)
        })
        .collect();
    Ok(Some((ids, names)))
}

/// Read a points file (`x_mm,y_mm,z_mm,b_deg[,c_deg][,dist_mm][,face][,group]`); `c_deg` is
/// required when `need_c`.
pub fn read_input(path: &Path, need_c: bool) -> Result<Input, InputError> {
    let table = Table::read(path)?;
    for name in ["b_deg", "c_deg"] {
        if table.column(name).is_none() && (name == "b_deg" || need_c) {
            return Err(missing_angles(&table, name));
        }
    }
    let xyz = table.f64_columns(&["x_mm", "y_mm", "z_mm"])?;
    let b = table.f64_column("b_deg")?;
    let c =
        if table.column("c_deg").is_some() { table.f64_column("c_deg")? } else { vec![0.0; table.n_rows()] };
    let dist = if table.column("dist_mm").is_some() { Some(table.f64_column("dist_mm")?) } else { None };
    let face = id_column(&table, "face")?;
    let group = id_column(&table, "group")?;
    let readings = (0..table.n_rows())
        .map(|i| Reading {
            b: b[i].to_radians(),
            c: c[i].to_radians(),
            p: Point3::new(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]),
            dist: dist.as_ref().map(|d| d[i]),
            face: face.as_ref().and_then(|f| f.0[i]),
            group: group.as_ref().and_then(|g| g.0[i]),
        })
        .collect();
    Ok(Input {
        readings,
        table,
        face_names: face.map(|f| f.1).unwrap_or_default(),
        group_names: group.map(|g| g.1).unwrap_or_default(),
    })
}

/// A solver error as an input error naming the file and, where it concerns one reading, its line.
pub fn head_error(table: &Table, e: HeadError) -> InputError {
    match e {
        HeadError::MissingFace { index } | HeadError::NotFinite { index } | HeadError::BadTilt { index }
            if index < table.n_rows() =>
        {
            InputError::at(&table.path, table.line_number(index), None, e.to_string())
        }
        _ => InputError::in_file(&table.path, e.to_string()),
    }
}

/// Write `input`'s rows as measured points (`truepos head-offset apply`), atomically: x_mm, y_mm,
/// z_mm become the measured point Q = P + Ry(b)·R (or the laser surface point
/// Q + dist·Ry(b)·u with the beam of `tilt_deg`), expressed on the table at c = 0 when
/// `table_center` is given; every other column and the comments pass through. Returns the number
/// of rows. A bad output path rides inside the `io::Error` as a `truepos_io::atomic::OutputError`.
pub fn write_applied(
    path: &Path,
    input: &Input,
    offset: &Vector3,
    tilt_deg: [f64; 2],
    table_center: Option<Point3>,
) -> std::io::Result<usize> {
    let table = &input.table;
    let beam = crate::beam_direction([tilt_deg[0].to_radians(), tilt_deg[1].to_radians()]);
    let col = |name: &str| table.require(name).map_err(std::io::Error::other);
    let (ix, iy, iz) = (col("x_mm")?, col("y_mm")?, col("z_mm")?);
    let mut file = AtomicFile::create(path)?;
    {
        let mut w = CsvWriter::new(&mut file);
        for c in &table.comments {
            w.comment(c)?;
        }
        w.comment(&format!(
            "truepos head-offset apply: offset_mm = {},{},{}; tilt_deg = {},{}; {}",
            offset.x,
            offset.y,
            offset.z,
            tilt_deg[0],
            tilt_deg[1],
            if table_center.is_some() { "table coordinates at c = 0" } else { "machine coordinates" }
        ))?;
        let header: Vec<&str> = table.header.iter().map(|s| s.as_str()).collect();
        w.header(&header)?;
        let mut buf = Vec::new();
        for (i, r) in input.readings.iter().enumerate() {
            let fields = table.fields(i, &mut buf).map_err(|e| std::io::Error::other(e.to_string()))?;
            let mut q = crate::surface_point(&r.p, r.b, offset, r.dist, &beam);
            if let Some(o) = table_center {
                q = crate::machine_to_table(&q, r.c, &o);
            }
            for (k, f) in fields.iter().enumerate() {
                if k == ix {
                    w.field_f64(q.x)?;
                } else if k == iy {
                    w.field_f64(q.y)?;
                } else if k == iz {
                    w.field_f64(q.z)?;
                } else {
                    w.field_str(f)?;
                }
            }
            w.end_row()?;
        }
    }
    file.flush()?;
    file.commit()?;
    Ok(input.readings.len())
}

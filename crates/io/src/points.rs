//! Point files: CSV with `x_mm,y_mm,z_mm` (optional `id`), NIST `.ds` (a count, then
//! `x y z` per line, whitespace separated), Parquet (same column names) or E57 point clouds; points with required unique ids
//! ([`read_id_points`]) and their matching by id ([`match_by_id`]).

use crate::csv::Table;
use crate::InputError;
use std::collections::HashMap;
use std::path::Path;
use truepos_math::Point3;

/// Points with optional ids (one per point, `None` when the file has no `id` column).
pub struct PointSet {
    /// The points, in file order, in the file's frame, mm.
    pub points: Vec<Point3>,
    /// The point ids, in the order of `points`, when the file has an `id` column.
    pub ids: Option<Vec<String>>,
    /// Points of the file left out because the file marks them invalid (E57
    /// `cartesianInvalidState`); 0 for the other formats.
    pub skipped_invalid: usize,
    /// Points of an E57 file left out because a coordinate is NaN or infinite; 0 for the other
    /// formats (where such a value is an error on its line or row).
    pub skipped_nonfinite: usize,
}

/// Read a point file by extension: `.ds` as NIST data set, `.parquet` as Parquet (same column
/// names), `.e57` as E57 point cloud (every scan, in mm; see [`crate::e57_file`]), anything
/// else as CSV.
pub fn read_points(path: impl AsRef<Path>) -> Result<PointSet, InputError> {
    let path = path.as_ref();
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("ds")) {
        return Ok(PointSet { points: read_ds(path)?, ids: None, skipped_invalid: 0, skipped_nonfinite: 0 });
    }
    if crate::e57_file::is_e57(path) {
        let e = crate::e57_file::read_e57(path)?;
        return Ok(PointSet {
            points: e.points,
            ids: None,
            skipped_invalid: e.skipped_invalid,
            skipped_nonfinite: e.skipped_nonfinite,
        });
    }
    if crate::parquet_file::is_parquet(path) {
        let c = crate::parquet_file::read_columns(path)?;
        let (x, y, z) = (c.f64(path, "x_mm")?, c.f64(path, "y_mm")?, c.f64(path, "z_mm")?);
        let points = x.iter().zip(y).zip(z).map(|((&x, &y), &z)| Point3::new(x, y, z)).collect();
        return Ok(PointSet { points, ids: c.strings("id"), skipped_invalid: 0, skipped_nonfinite: 0 });
    }
    // The plain case (no `id`, no quotes, all values good) is parsed straight from the text;
    // anything else comes back as a table and takes the general path (exact errors).
    let t = match Table::read_rows_direct(path, &["x_mm", "y_mm", "z_mm"])? {
        Ok(rows) => {
            // `[f64; 3]` and `Point3` have the same layout: this collect reuses the allocation.
            let points = rows.into_iter().map(Point3::from).collect();
            return Ok(PointSet { points, ids: None, skipped_invalid: 0, skipped_nonfinite: 0 });
        }
        Err(t) => t,
    };
    let points = t.f64_rows(&["x_mm", "y_mm", "z_mm"])?.into_iter().map(Point3::from).collect();
    let ids = match t.column("id") {
        Some(_) => Some(t.str_column("id")?),
        None => None,
    };
    Ok(PointSet { points, ids, skipped_invalid: 0, skipped_nonfinite: 0 })
}

/// Read a NIST `.ds` file.
pub fn read_ds(path: impl AsRef<Path>) -> Result<Vec<Point3>, InputError> {
    let path = path.as_ref();
    let bytes = crate::limits::read_text(path, ".ds")?;
    parse_ds(path, &bytes)
}

/// Parse `.ds` content that came from `path`.
pub fn parse_ds(path: &Path, bytes: &[u8]) -> Result<Vec<Point3>, InputError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        InputError::at(path, line, None, "not valid UTF-8 text: not a .ds file")
    })?;
    if text.contains('\0') {
        return Err(InputError::in_file(path, "binary data (NUL byte): not a .ds file"));
    }
    // Lines ending in a carriage return alone (classic Mac OS) read as lines.
    let owned;
    let text = if !text.contains('\n') && text.contains('\r') {
        owned = text.replace('\r', "\n");
        owned.as_str()
    } else {
        text
    };
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let Some((l0, first)) = lines.next() else {
        return Err(InputError::in_file(path, "empty file: expected a point count on the first line"));
    };
    let count: usize = first.trim().parse().map_err(|_| {
        InputError::at(path, l0 + 1, Some(1), format!("expected the point count, found '{}'", first.trim()))
    })?;
    let mut pts = Vec::with_capacity(count.min(1 << 24));
    for (ln, line) in lines {
        let mut v = [0.0; 3];
        let mut k = 0;
        for (j, tok) in line.split_whitespace().enumerate() {
            if j >= 3 {
                return Err(InputError::at(path, ln + 1, Some(j + 1), "more than three values on a line"));
            }
            v[j] = crate::csv::parse_f64(tok).ok_or_else(|| {
                InputError::at(path, ln + 1, Some(j + 1), format!("not a finite number: '{tok}'"))
            })?;
            k += 1;
        }
        if k != 3 {
            return Err(InputError::at(
                path,
                ln + 1,
                Some(k + 1),
                format!("expected x y z, found {k} values"),
            ));
        }
        pts.push(Point3::new(v[0], v[1], v[2]));
    }
    if pts.len() != count {
        return Err(InputError::in_file(
            path,
            format!("the header says {count} points, the file has {}", pts.len()),
        ));
    }
    Ok(pts)
}

/// Points of a file with their ids (ids required, unique).
pub struct IdPoints {
    /// The point ids (non-empty and unique), in file order.
    pub ids: Vec<String>,
    /// The points, in the order of `ids`, in the file's frame, mm.
    pub points: Vec<Point3>,
    /// The parsed file (for further columns and line numbers).
    pub table: Table,
}

/// Read a CSV of points with ids (`id,x_mm,y_mm,z_mm`); an empty id, or a duplicate id (naming
/// both lines), is an error.
pub fn read_id_points(path: &Path) -> Result<IdPoints, InputError> {
    let table = Table::read(path)?;
    let xyz = table.f64_columns(&["x_mm", "y_mm", "z_mm"])?;
    let ids = table.str_column("id")?;
    let mut seen = HashMap::new();
    for (i, id) in ids.iter().enumerate() {
        if id.trim().is_empty() {
            return Err(InputError::at(
                path,
                table.line_number(i),
                table.column("id").map(|c| c + 1),
                "empty id: every point needs an id to be matched",
            ));
        }
        if let Some(prev) = seen.insert(id.clone(), i) {
            return Err(InputError::at(
                path,
                table.line_number(i),
                table.column("id").map(|c| c + 1),
                format!("duplicate id '{id}' (also on line {})", table.line_number(prev)),
            ));
        }
    }
    let points = xyz.chunks_exact(3).map(|c| Point3::new(c[0], c[1], c[2])).collect();
    Ok(IdPoints { ids, points, table })
}

/// Pairs of points matched by id, in the order of `from`.
pub struct Matched {
    /// The ids present in both files, in the order of `from`.
    pub ids: Vec<String>,
    /// The matched points of the `from` file, mm.
    pub from: Vec<Point3>,
    /// The matched points of the `to` file (same ids, same order), mm.
    pub to: Vec<Point3>,
    /// Row index in the `from` file of each matched point.
    pub from_rows: Vec<usize>,
    /// Row index in the `to` file of each matched point.
    pub to_rows: Vec<usize>,
}

/// The points of `from` whose id is also in `to`, paired.
pub fn match_by_id(from: &IdPoints, to: &IdPoints) -> Matched {
    let index: HashMap<&str, usize> = to.ids.iter().enumerate().map(|(i, s)| (s.as_str(), i)).collect();
    let mut m = Matched { ids: vec![], from: vec![], to: vec![], from_rows: vec![], to_rows: vec![] };
    for (i, id) in from.ids.iter().enumerate() {
        if let Some(&j) = index.get(id.as_str()) {
            m.ids.push(id.clone());
            m.from.push(from.points[i]);
            m.to.push(to.points[j]);
            m.from_rows.push(i);
            m.to_rows.push(j);
        }
    }
    m
}

/// Read two id-point files and pair their points by id (`from` → `to`); fewer than `min` common
/// ids is an input error on `to` that says what needs them (`what`, e.g. "orientation").
pub fn read_matched(
    from: &Path,
    to: &Path,
    min: usize,
    what: &str,
) -> Result<(IdPoints, IdPoints, Matched), InputError> {
    let a = read_id_points(from)?;
    let b = read_id_points(to)?;
    let m = match_by_id(&a, &b);
    if m.ids.len() < min {
        return Err(InputError::in_file(
            to,
            format!(
                "only {} ids are common to {} and {}; {what} needs at least {min}",
                m.ids.len(),
                from.display(),
                to.display()
            ),
        ));
    }
    Ok((a, b, m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ds_parses_and_checks_count() {
        let p = Path::new("x.ds");
        let pts = parse_ds(p, b"2\n1\t2\t3\n4 5 6\n").unwrap();
        assert_eq!(pts[1], Point3::new(4.0, 5.0, 6.0));
        assert!(parse_ds(p, b"3\n1 2 3\n").unwrap_err().to_string().contains("3 points"));
        let e = parse_ds(p, b"1\n1 x 3\n").unwrap_err();
        assert_eq!((e.line, e.column), (Some(2), Some(2)));
        assert!(parse_ds(p, b"").is_err());
    }
}

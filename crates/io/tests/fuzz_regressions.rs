//! Files found by the fuzz targets (`fuzz/`, see its README) that once panicked or gave a wrong
//! answer, kept as they were found (`tests/fuzz/`): each is now an input error that names the
//! file, through the entry points the CLI uses (`points::read_points`, `csv::Table::read`, and
//! for the Parquet cases the streamed point rewrite, `stream::rewrite_points`).

use std::path::{Path, PathBuf};
use truepos_io::csv::Table;
use truepos_io::points::read_points;

fn case(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz").join(name)
}

/// Both entry points refuse the file with an error that starts with its path and contains `what`.
fn refused(name: &str, what: &str) {
    let path = case(name);
    let prefix = format!("{}:", path.display());
    let errors = [read_points(&path).err(), Table::read(&path).err()];
    for e in errors {
        let e = e.expect("refused").to_string();
        assert!(e.starts_with(&prefix) && e.contains(what), "{name}: {e}");
    }
}

/// `parquet_points`: a column chunk at a negative offset made `parquet` panic (`byte_range`).
#[test]
fn parquet_negative_chunk_offset() {
    refused("negative_chunk_offset.parquet", "row group 1, column 't_s': chunk at offset -33");
}

/// `parquet_points`: a dictionary page whose text lengths run past its end made `parquet`'s
/// decoder assert (`bit_util::read_num_bytes`). It was contained at the reader (catch_unwind);
/// since the page headers are walked first (below), the same file is refused before decoding,
/// at an invalid header of its `x_mm` column.
#[test]
fn parquet_dictionary_text_past_page_end() {
    refused("dictionary_text_past_page_end.parquet", "not a readable Parquet file");
}

/// `parquet_points`: a column named `z_,m` was written into the table's CSV header as is and
/// split in two (a header of five names over rows of four fields).
#[test]
fn parquet_comma_in_column_name() {
    let path = case("comma_in_column_name.parquet");
    let e = Table::read(&path).expect_err("refused").to_string();
    assert!(e.starts_with(&format!("{}: column 4: the name 'z_,m'", path.display())), "{e}");
}

/// `parquet_points` (a timeout): a page header announcing a huge list of doubles made
/// `parquet`'s Thrift skipping read the end of the file again and again; now refused at once.
#[test]
fn parquet_page_header_list_past_end() {
    let t = std::time::Instant::now();
    refused("page_header_list_past_end.parquet", "not a readable Parquet file");
    // It took over 15 s in the fuzz build; a refusal takes milliseconds. 2 s leaves room for a
    // loaded machine and a debug build.
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

/// Found by reading `parquet`'s Thrift skipping after the case above (not by the fuzzer yet):
/// the first page header of `points.parquet` (the fuzz seed) overwritten with an unknown field
/// holding a list of 2³¹ − 1 bools, which `parquet` skipped one by one without reading (4 s
/// per header). The page headers are now walked first; the list cannot fit in the chunk.
#[test]
fn parquet_page_header_bool_list() {
    let t = std::time::Instant::now();
    refused("page_header_bool_list.parquet", "2147483647 elements announced in");
    // Milliseconds when refused up front; 2 s leaves room for a loaded machine.
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

/// `parquet_points` (a timeout, after the page headers were checked): the same kind of list in
/// the file metadata (footer), which `parquet` parses before anything else.
#[test]
fn parquet_footer_bool_list() {
    let t = std::time::Instant::now();
    refused("footer_bool_list.parquet", "file metadata: ");
    // Milliseconds when refused up front; 2 s leaves room for a loaded machine.
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

/// The map of the file (for the footer and header walks) copes with an empty file: refused by
/// `parquet`, naming the file.
#[test]
fn parquet_empty_file() {
    let d = tempfile::tempdir().unwrap();
    let path = d.path().join("empty.parquet");
    std::fs::write(&path, b"").unwrap();
    let e = truepos_io::parquet_file::read_columns(&path).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: not a readable Parquet file", path.display())), "{e}");
}

/// `parquet_points` (out of memory): a dictionary page header announcing 671 million doubles
/// in a 1 kB file made `parquet` reserve 5 GB before decoding; a page holds no more values than
/// its column chunk.
#[test]
fn parquet_dictionary_of_671m_values() {
    refused("dictionary_of_671m_values.parquet", "a page of 671088639 values in a column chunk of 4");
}

/// Every Parquet file above through the streamed point rewrite (`comp correct` of a `.parquet`
/// input, `stream::rewrite_points`), into CSV and into Parquet: refused with an error naming
/// the file, never a panic, and nothing left at the output.
#[test]
fn parquet_cases_through_the_streamed_rewrite() {
    use truepos_io::stream::rewrite_points;
    let dir = tempfile::tempdir().unwrap();
    let mut n = 0;
    for entry in std::fs::read_dir(case("")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "parquet") {
            continue;
        }
        n += 1;
        for out in [dir.path().join("out.csv"), dir.path().join("out.parquet")] {
            let r = rewrite_points(
                &path,
                &out,
                ["dx_um", "dy_um", "dz_um"],
                Default::default(),
                |_, p, e| {
                    for (q, d) in p.iter_mut().zip(e.iter_mut()) {
                        q.x += 1.0;
                        *d = [1.0, 2.0, 3.0];
                    }
                    Ok::<(), (usize, String)>(())
                },
                |_| {},
            );
            let e = r.expect_err("refused").to_string();
            assert!(e.starts_with(&format!("{}:", path.display())), "{}: {e}", path.display());
            assert!(!out.exists(), "{}", path.display());
        }
    }
    assert!(n >= 6, "{n} Parquet cases");
}

/// `parquet_points` (out of memory): a footer whose schema element announces 562 million
/// children made `parquet` reserve 4.5 GB for them before reading any; now refused while the
/// footer is walked.
#[test]
fn parquet_schema_children_past_elements() {
    refused("schema_children_past_elements.parquet", "children in a schema of");
}

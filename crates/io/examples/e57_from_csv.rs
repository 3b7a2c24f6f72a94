//! Write the points of a CSV or Parquet point file (`x_mm,y_mm,z_mm`) as an E57 point cloud
//! (one Cartesian scan of doubles), to make E57 inputs for benchmarks, e.g. the E57 rows of the
//! peak-memory table in `docs/performance-io.md`:
//!
//! ```text
//! cargo run --release -p truepos-io --example e57_from_csv -- points_1M.csv points_1M.e57
//! ```
//!
//! Everything is held in memory (about 50 bytes a point): a tool for making inputs, not a
//! command.

use truepos_math::Point3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output] = args.as_slice() else {
        return Err("usage: e57_from_csv INPUT.csv OUTPUT.e57".into());
    };
    let t = truepos_io::csv::Table::read(input)?;
    let xyz = t.f64_rows(&["x_mm", "y_mm", "z_mm"])?;
    drop(t);
    let pts: Vec<Point3> = xyz.into_iter().map(Point3::from).collect();
    truepos_io::e57_file::write_e57(std::path::Path::new(output), &pts)?;
    eprintln!("{} points → {output}", pts.len());
    Ok(())
}

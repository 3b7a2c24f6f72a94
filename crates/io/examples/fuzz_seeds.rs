//! Writes the small valid files that seed the E57 and Parquet fuzz targets (`fuzz/seeds/`):
//! E57 with Cartesian doubles, singles with intensity, colour and invalid states (two scans, one
//! with a pose), spherical coordinates, and scaled integers; Parquet as `write_columns` writes it
//! (required doubles and text, Snappy), and optional FLOAT / INT32 / INT64 / DOUBLE columns with
//! nulls-free definition levels over two row groups, uncompressed.
//!
//! `cargo run -p truepos-io --example fuzz_seeds -- fuzz/seeds`

use e57::{E57Writer, Quaternion, Record, RecordDataType, RecordName, RecordValue, Transform, Translation};
use parquet::data_type::{DoubleType, FloatType, Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use std::path::Path;
use std::sync::Arc;
use truepos_io::parquet_file::{write_columns, ColumnData, Columns};
use truepos_math::Point3;

type Res = Result<(), Box<dyn std::error::Error>>;

fn rec(name: RecordName, data_type: RecordDataType) -> Record {
    Record { name, data_type }
}

fn e57_seeds(dir: &Path) -> Res {
    std::fs::create_dir_all(dir)?;
    // 1. What truepos writes: one Cartesian scan of doubles.
    let pts: Vec<Point3> = (0..6).map(|i| Point3::new(i as f64 * 1.5, -(i as f64), 12.5)).collect();
    truepos_io::e57_file::write_e57(&dir.join("doubles.e57"), &pts)?;
    // 2. Two scans: singles with intensity, colour and invalid state (one posed), then spherical.
    {
        let mut w = E57Writer::from_file(dir.join("mixed.e57"), "seed-mixed")?;
        let mut proto = vec![Record::CARTESIAN_X_F32, Record::CARTESIAN_Y_F32, Record::CARTESIAN_Z_F32];
        proto.push(Record::CARTESIAN_INVALID_STATE);
        proto.push(rec(RecordName::Intensity, RecordDataType::UNIT_F32));
        for c in [RecordName::ColorRed, RecordName::ColorGreen, RecordName::ColorBlue] {
            proto.push(rec(c, RecordDataType::U8));
        }
        let mut pc = w.add_pointcloud("posed", proto)?;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        pc.set_transform(Some(Transform {
            rotation: Quaternion { w: h, x: 0.0, y: 0.0, z: h },
            translation: Translation { x: 1.0, y: 2.0, z: 3.0 },
        }));
        for (i, state) in [0, 1, 2, 0].into_iter().enumerate() {
            let f = i as f32 * 0.25;
            pc.add_point(vec![
                RecordValue::Single(f),
                RecordValue::Single(-f),
                RecordValue::Single(0.5),
                RecordValue::Integer(state),
                RecordValue::Single(0.75),
                RecordValue::Integer(10 * i as i64),
                RecordValue::Integer(200),
                RecordValue::Integer(255),
            ])?;
        }
        pc.finalize()?;
        let sph = vec![
            Record::SPHERICAL_RANGE_F64,
            Record::SPHERICAL_AZIMUTH_F64,
            Record::SPHERICAL_ELEVATION_F64,
            Record::SPHERICAL_INVALID_STATE,
        ];
        let mut pc = w.add_pointcloud("spherical", sph)?;
        for (r, a, e, s) in [(2.0, 0.5, 0.1, 0), (1.0, -1.0, 1.2, 0), (3.0, 0.0, 0.0, 2)] {
            pc.add_point(vec![
                RecordValue::Double(r),
                RecordValue::Double(a),
                RecordValue::Double(e),
                RecordValue::Integer(s),
            ])?;
        }
        pc.finalize()?;
        w.finalize()?;
    }
    // 3. Scaled integers (the bit-packed path): 0.1 mm steps over ±10 m.
    {
        let mut w = E57Writer::from_file(dir.join("scaled.e57"), "seed-scaled")?;
        let t = RecordDataType::ScaledInteger { min: -100_000, max: 100_000, scale: 1e-4, offset: 0.0 };
        let proto = [RecordName::CartesianX, RecordName::CartesianY, RecordName::CartesianZ]
            .map(|n| rec(n, t.clone()))
            .to_vec();
        let mut pc = w.add_pointcloud("scaled", proto)?;
        for i in 0..8_i64 {
            pc.add_point(vec![
                RecordValue::ScaledInteger(i * 1234 - 5000),
                RecordValue::ScaledInteger(-i * 77),
                RecordValue::ScaledInteger(99_999 - i),
            ])?;
        }
        pc.finalize()?;
        w.finalize()?;
    }
    Ok(())
}

fn parquet_seeds(dir: &Path) -> Res {
    std::fs::create_dir_all(dir)?;
    // 1. What truepos writes: id text and x, y, z doubles, Snappy.
    let c = Columns {
        names: ["id", "x_mm", "y_mm", "z_mm"].map(String::from).to_vec(),
        data: vec![
            ColumnData::Str((0..4).map(|i| format!("P{i}")).collect()),
            ColumnData::F64(vec![1.0, 2.5, -3.25, 1e-3]),
            ColumnData::F64(vec![0.0, 10.0, 20.0, 30.0]),
            ColumnData::F64(vec![5.0, 5.0, 5.0, 5.5]),
        ],
    };
    write_columns(&dir.join("points.parquet"), &c)?;
    // 2. A stream: optional columns of every numeric type, two row groups, uncompressed.
    let schema = parquet::schema::parser::parse_message_type(
        "message s { optional double t_s; optional float x_mm; optional int32 y_mm; optional int64 z_mm; }",
    )?;
    let props = WriterProperties::builder().build();
    let file = std::fs::File::create(dir.join("stream.parquet"))?;
    let mut w = SerializedFileWriter::new(file, Arc::new(schema), Arc::new(props))?;
    for g in 0..2 {
        let mut rg = w.next_row_group()?;
        let defs = [1_i16; 3];
        let mut k = 0;
        while let Some(mut col) = rg.next_column()? {
            let base: i32 = g * 3;
            match k {
                0 => {
                    let v: Vec<f64> = (0..3).map(|i| (base + i) as f64 * 0.001).collect();
                    col.typed::<DoubleType>().write_batch(&v, Some(&defs), None)?;
                }
                1 => {
                    let v: Vec<f32> = (0..3).map(|i| (base + i) as f32 * 0.5).collect();
                    col.typed::<FloatType>().write_batch(&v, Some(&defs), None)?;
                }
                2 => {
                    let v: Vec<i32> = (0..3).map(|i| base - i).collect();
                    col.typed::<Int32Type>().write_batch(&v, Some(&defs), None)?;
                }
                _ => {
                    let v: Vec<i64> = (0..3).map(|i| 7 * (base as i64 + i)).collect();
                    col.typed::<Int64Type>().write_batch(&v, Some(&defs), None)?;
                }
            }
            col.close()?;
            k += 1;
        }
        rg.close()?;
    }
    w.close()?;
    Ok(())
}

fn main() -> Res {
    let out = std::env::args().nth(1).unwrap_or_else(|| "fuzz/seeds".into());
    let out = Path::new(&out);
    e57_seeds(&out.join("e57_points"))?;
    parquet_seeds(&out.join("parquet_points"))?;
    Ok(())
}

//! What the head-offset tests and the figures example share: the simulator's data set as the
//! solver's readings and parameters.

use truepos_head::{Params, Reading, Reference};
use truepos_math::{Point3, Vector3};
use truepos_sim::scenario::head_offset::{Head, HeadOffsetConfig, HeadOffsetData};

pub fn readings(d: &HeadOffsetData) -> Vec<Reading> {
    d.rows
        .iter()
        .map(|r| Reading {
            b: r.b_deg.to_radians(),
            c: r.c_deg.to_radians(),
            p: Point3::new(r.x_mm, r.y_mm, r.z_mm),
            dist: r.dist_mm,
            face: r.face.map(|f| f as i64),
            group: Some(r.group as i64),
        })
        .collect()
}

pub fn setup(cfg: &HeadOffsetConfig, d: &HeadOffsetData, fixed_radius: bool) -> Params {
    let t = &d.truth;
    let tip = match cfg.head {
        Head::TouchProbe { tip_radius } => tip_radius,
        Head::Laser { .. } => 0.0,
    };
    let reference = if t.variant_reference == "sphere" {
        Reference::Sphere { radius: if fixed_radius { t.fitted_radius_mm } else { None } }
    } else {
        Reference::Vertex { tip_radius: tip }
    };
    let tilt = t.tilt_deg.map_or([0.0, 0.0], |a| [a[0].to_radians(), a[1].to_radians()]);
    Params {
        reference,
        table_center: Point3::from(t.table_center_mm),
        tilt,
        prior: Vector3::zeros(),
        beam_through_reference: false,
    }
}

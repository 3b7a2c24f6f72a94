//! Influence maps from the plate FE model: superposition reproduces a direct FE solve of the
//! combined load (linearity, read-out of the right rails and bearings), the physical sign, and
//! singular models are refused.

use truepos_comp::fe_map::{influence_map, BedModel, FeMapError, LoadGrid};
use truepos_comp::load::portal_rotation;
use truepos_comp::Portal;
use truepos_fe::{Bed, MeshOptions, PlateModel, Supports};

fn model() -> BedModel {
    BedModel {
        bed: Bed {
            size_x: 1200.0,
            size_y: 1000.0,
            thickness: 150.0,
            youngs_modulus: 50_000.0,
            poisson: 0.2,
            supports: Supports::Points {
                xy: vec![[200.0, 150.0], [1000.0, 150.0], [1000.0, 850.0], [200.0, 850.0]],
                stiffness_n_per_mm: None,
            },
        },
        portal: Portal {
            rail_x: [50.0, 1150.0],
            rail_height: 0.0,
            bearing_span: 300.0,
            y_range: [150.0, 850.0],
            y_step: 100.0,
        },
        grid: LoadGrid { spacing: 200.0, unit_load_n: 1000.0 },
    }
}

#[test]
fn superposed_map_equals_direct_solve_at_grid_nodes() {
    let m = model();
    let mesh = MeshOptions::with_element_size(25.0);
    let map = influence_map(&m, &mesh, &|_| {}).unwrap();
    assert_eq!(map.load_x(), &[0.0, 200.0, 400.0, 600.0, 800.0, 1000.0, 1200.0]);
    assert_eq!(map.portal_y(), &[150.0, 250.0, 350.0, 450.0, 550.0, 650.0, 750.0, 850.0]);
    // Loads on grid nodes: bilinear interpolation is exact there, so superposition must equal the
    // direct solve of the combined load to solver rounding (linear elasticity).
    let loads = [(400.0, 600.0, 7000.0), (800.0, 200.0, 3000.0), (600.0, 800.0, 4500.0)];
    let curves = map.superpose(&loads).unwrap();
    let plate = PlateModel::new(&m.bed, &mesh).unwrap();
    let d = plate.solve(&loads).unwrap();
    let mut peak = 0.0f64;
    for (k, &y) in map.portal_y().iter().enumerate() {
        let (p, r) = portal_rotation(|x, y| d.uz(x, y), &m.portal, y);
        peak = peak.max(p.abs()).max(r.abs());
        // Rounding of the sparse solve and of the sums: 1e-9 of the peak value.
        assert!(
            (curves.pitch[k] - p).abs() < 1e-9 * 1e-5 + 1e-9 * p.abs(),
            "pitch at {y}: {} vs {p}",
            curves.pitch[k]
        );
        assert!(
            (curves.roll[k] - r).abs() < 1e-9 * 1e-5 + 1e-9 * r.abs(),
            "roll at {y}: {} vs {r}",
            curves.roll[k]
        );
    }
    assert!(peak > 1e-7, "the case must tilt the portal visibly ({peak} rad)");
    // Physics of the sign: a load ahead of the portal (larger y) sinks its front bearings; the
    // portal tips forward, a negative rotation about +X: pitch negative. Load at y = 800, portal
    // at y = 250; and a load near rail 2 (x = 1000) lowers rail 2, turning +Z towards +X: a
    // positive rotation about +Y, roll positive.
    let ahead = map.superpose(&[(600.0, 800.0, 1000.0)]).unwrap();
    assert!(ahead.at(250.0).unwrap().0 < 0.0);
    let right = map.superpose(&[(1000.0, 500.0, 1000.0)]).unwrap();
    assert!(right.at(500.0).unwrap().1 > 0.0);
}

#[test]
fn singular_supports_and_portals_off_the_bed_are_refused() {
    let mut m = model();
    m.bed.supports = Supports::Points { xy: vec![[200.0, 150.0], [1000.0, 850.0]], stiffness_n_per_mm: None };
    assert!(matches!(influence_map(&m, &MeshOptions::default(), &|_| {}), Err(FeMapError::Fe(_))));
    let mut m = model();
    m.portal.y_range = [100.0, 850.0]; // rear bearing at y = −50: off the bed
    assert!(matches!(influence_map(&m, &MeshOptions::default(), &|_| {}), Err(FeMapError::PortalOffBed(_))));
}

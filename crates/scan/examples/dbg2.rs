use truepos_scan::execute::{execute, Machine};
use truepos_scan::{plan, Geometry, Style};
fn main() {
    let (mut nom, _, p) = truepos_scan::scenario::program(&truepos_sim::scenario::scan::scenario(11, 4));
    if let Geometry::Circle { radius, .. } = &mut nom[0].geometry {
        *radius = 12.0;
    }
    let mut truth = nom.clone();
    if let Geometry::Circle { radius, .. } = &mut truth[0].geometry {
        *radius = 14.0;
    }
    let pl = plan(&nom[..1], &p, Style::Blended);
    let r = execute(&pl, &truth[..1], &Machine::default(), 3).unwrap();
    for q in r.points.iter().step_by(10).take(60) {
        println!(
            "{:.3} {:?} tgt {:.4} defl {:.4} v {:.1} d_true {:.3}",
            q.t,
            q.segment,
            q.target,
            q.deflection,
            q.speed,
            truth[0].signed_distance(&q.commanded).0 - p.tip_radius
        );
    }
    println!("{:?}", r.features[0]);
}

use truepos_scan::execute::{execute, Machine};
use truepos_scan::{plan, Style};
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(8);
    let s = truepos_sim::scenario::scan::scenario(11, n);
    let (nom, truth, p) = truepos_scan::scenario::program(&s);
    let m = Machine::default();
    for style in [Style::Blended, Style::Classic] {
        let pl = plan(&nom, &p, style);
        let t0 = std::time::Instant::now();
        let r = execute(&pl, &truth, &m, 1);
        let el = t0.elapsed();
        match r {
            Err(e) => println!("{style:?}: error {e}"),
            Ok(r) => {
                println!(
                    "{style:?}: plan {:.3}s cycle {:.3}s stops {} points {} wall {:?}",
                    pl.duration(),
                    r.cycle_time,
                    r.stops,
                    r.points.len(),
                    el
                );
                if std::env::var("TRACE").is_ok() {
                    let fk: usize = std::env::var("TRACE").unwrap().parse().unwrap_or(1);
                    let f1 = &r.features[fk];
                    for q in r
                        .points
                        .iter()
                        .filter(|q| {
                            q.feature == fk && q.t > f1.contact_t - 0.02 && q.t < f1.scan_start_t + 0.06
                        })
                        .step_by(5)
                    {
                        println!(
                            "    {:.3} {:?} tgt {:.4} defl {:.4} v {:.1}",
                            q.t, q.segment, q.target, q.deflection, q.speed
                        );
                    }
                }
                for f in &r.features {
                    println!("  {:8} time {:.3} form {:.4}um shift {:+.3} vib_rms {:.2}um vib_pk {:.2}um settle {:.3}s ready {:.3} q0 {:.3} maxdefl {:.3}", f.id, f.time, f.form_error*1e3, f.contact_shift, f.vibration_rms*1e3, f.vibration_peak*1e3, f.settle_time, f.ready_time, f.quality0_share,
                        r.points.iter().filter(|q| q.feature == r.features.iter().position(|g| g.id == f.id).unwrap()).map(|q| q.deflection).fold(0.0, f64::max));
                }
            }
        }
    }
}
#[allow(dead_code)]
fn unused() {}

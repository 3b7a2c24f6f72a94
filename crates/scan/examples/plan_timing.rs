//! Planning time, program duration and its share per segment kind for the test programs
//! (`scenario(11, n)`), both styles:
//! `cargo run --release -p truepos-scan --example plan_timing [n ...]`.

use std::time::Instant;
use truepos_scan::{plan, SegmentKind, Style};

fn main() {
    let ns: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4, 8, 16] } else { ns };
    let kinds = [
        SegmentKind::Transfer,
        SegmentKind::Approach,
        SegmentKind::Settle,
        SegmentKind::Scan,
        SegmentKind::Release,
    ];
    for n in ns {
        let seed = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(11);
        let s = truepos_plant::scan_scenario::scenario(seed, n);
        let (fs, _, p) = truepos_plant::scan_scenario::program(&s);
        for style in [Style::Blended, Style::Classic] {
            let t0 = Instant::now();
            let pl = plan(&fs, &p, style);
            let dt = t0.elapsed();
            let by: Vec<String> = kinds
                .iter()
                .map(|k| {
                    let t: f64 = pl.segments.iter().filter(|s| s.kind == *k).map(|s| s.duration()).sum();
                    format!("{} {:.3}", k.as_str(), t)
                })
                .collect();
            println!(
                "{n:3} features {:8}: planned in {:8.2} ms, program {:.3} s ({})",
                style.name(),
                dt.as_secs_f64() * 1e3,
                pl.duration(),
                by.join(", ")
            );
            let curve_first = pl
                .segments
                .iter()
                .filter(|s| {
                    s.kind == SegmentKind::Transfer
                        && matches!(s.geom, truepos_scan::plan::Geom::Quintic { .. })
                })
                .count();
            println!("    curve-first (fallback) transfer segments: {curve_first}");
            if std::env::var_os("TRANSFERS").is_some() {
                groups(&pl);
            }
        }
    }
}

/// Per transfer group (consecutive transfer segments): chord, turn angles, time, and the
/// rest-to-rest straight time over the chord.
#[allow(dead_code)]
pub fn groups(pl: &truepos_scan::Plan) {
    let p = &pl.params;
    let mut i = 0;
    let segs = &pl.segments;
    while i < segs.len() {
        if segs[i].kind != SegmentKind::Transfer {
            i += 1;
            continue;
        }
        let j0 = i;
        while i < segs.len() && segs[i].kind == SegmentKind::Transfer {
            i += 1;
        }
        let f = |k: usize| &pl.features[segs[k].feature];
        let tip = p.tip_radius;
        let a = segs[j0].eval(0.0, f(j0), tip).position;
        let a2 = segs[j0].eval(1e-3, f(j0), tip).position;
        let last = i - 1;
        let d = segs[last].duration();
        let b = segs[last].eval(d, f(last), tip).position;
        let b2 = segs[last].eval(d - 1e-3, f(last), tip).position;
        let t: f64 = segs[j0..i].iter().map(|s| s.duration()).sum();
        let ch = b - a;
        let ang = |u: truepos_math::Vector3, w: truepos_math::Vector3| {
            if u.norm() < 1e-12 || w.norm() < 1e-12 {
                0.0
            } else {
                u.normalize().dot(&w.normalize()).clamp(-1.0, 1.0).acos().to_degrees()
            }
        };
        let prof = truepos_scan::plan::Profile::s_curve(ch.norm(), 0.0, p.move_speed, 0.0, p.accel, p.jerk);
        println!(
            "  group {} segs {}: chord {:7.2} mm, turn out {:5.1}°, turn in {:5.1}°, time {:.3} s, rest-to-rest {:.3} s",
            j0,
            i - j0,
            ch.norm(),
            ang(a2 - a, ch),
            ang(ch, b - b2),
            t,
            prof.duration()
        );
    }
}

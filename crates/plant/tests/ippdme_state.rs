//! The I++ DME server's machine state under hostile commands (issue 31, round 3), on the virtual
//! CMM over a loopback port: multi-turn circle scans end where the analytic circle says, scans
//! beyond the limits are refused before anything moves, and part moves that would take the part
//! out of the machine volume are refused with the part, the table and the probe left as they were.

mod common;

use common::Raw;
use truepos_ippdme::part::Part;
use truepos_ippdme::protocol::{parse_data_items, Body, Response};
use truepos_ippdme::{MachineConfig, Server, ServerHandle};
use truepos_plant::cmm::IppdmeCmm;

/// The ideal machine (every error model off) with `part`.
fn start(part: &str) -> ServerHandle<IppdmeCmm> {
    let config = MachineConfig::ideal();
    let part = Part::from_toml("test-part.toml", part).unwrap();
    Server::bind("127.0.0.1:0", IppdmeCmm::new(&config, Some(part)), &config, None).unwrap().spawn().unwrap()
}

fn scan_points(lines: &[String]) -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    for l in lines {
        if let Ok(Response { body: Body::Data(d), .. }) = Response::parse(l) {
            let v: Vec<f64> = d.split(',').map(|s| s.trim().parse().unwrap()).collect();
            assert_eq!(v.len() % 3, 0, "{d}");
            pts.extend(v.chunks(3).map(|c| [c[0], c[1], c[2]]));
        }
    }
    pts
}

/// A table plane Z = 0 with a Ø30 bore about (−100, 0) along Z.
const BORE_PART: &str = "[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n\n[[cylinder]]\nid = \"bore\"\npoint_mm = [-100, 0, 0]\naxis = [0, 0, 1]\ndiameter_mm = 30\nside = \"inside\"\n";

/// Multi-turn scans in the bore on the ideal machine: every point, the last included, lies where
/// the analytic circle of tip centres (radius 15 − 1.5 = 13.5 mm about the bore's axis, at the
/// scan height) puts the k-th step, to < 1 µm; two turns end on the start point (before the fix:
/// 66 µm short), and no point repeats.
#[test]
fn multi_turn_circle_scans_end_on_the_analytic_circle() {
    let h = start(BORE_PART);
    let mut c = Raw::connect(&h);
    for l in ["00001 StartSession()", "00002 Home()", "00003 ChangeTool(\"Probe1\")"] {
        c.ok(l);
    }
    c.ok("00004 OnScanReport(X(), Y(), Z())");
    c.ok("00005 GoTo(X(-100), Y(0), Z(50))");
    c.ok("00006 GoTo(Z(-10))");
    for (tag, delta, step) in [(7, 720.0, 1.0), (8, 450.0, 2.5), (9, -720.0, 4.0)] {
        let out = c.ok(&format!(
            "{tag:05} ScanOnCircle(-100, 0, -10, -85.4, 0, -10, 0, 0, 1, {delta}, 180, {step})"
        ));
        let pts = scan_points(&out);
        let n = (f64::abs(delta) / step) as usize + 1;
        assert_eq!(pts.len(), n, "delta {delta}");
        let mut worst: f64 = 0.0;
        for (k, p) in pts.iter().enumerate() {
            let a = (k as f64 * step * delta.signum()).to_radians();
            let truth = [-100.0 + 13.5 * a.cos(), 13.5 * a.sin(), -10.0];
            let e =
                ((p[0] - truth[0]).powi(2) + (p[1] - truth[1]).powi(2) + (p[2] - truth[2]).powi(2)).sqrt();
            worst = worst.max(e);
        }
        let last = pts[n - 1];
        let a_end = delta.to_radians();
        let end_err = ((last[0] - (-100.0 + 13.5 * a_end.cos())).powi(2)
            + (last[1] - 13.5 * a_end.sin()).powi(2))
        .sqrt();
        eprintln!(
            "ScanOnCircle {delta}° in {step}° steps: {n} points, end point {:.4} µm from the analytic end, worst point {:.4} µm",
            end_err * 1e3,
            worst * 1e3
        );
        assert!(end_err < 1e-3, "delta {delta}: end {last:?} is {:.3} µm off", end_err * 1e3);
        assert!(worst < 1e-3, "delta {delta}: a point is {:.3} µm off", worst * 1e3);
        // No duplicated points: consecutive points one step's chord apart (to 2 µm).
        let chord = 2.0 * 13.5 * (f64::to_radians(step) / 2.0).sin();
        for w in pts.windows(2) {
            let d = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
            assert!((d - chord).abs() < 2e-3, "{w:?}");
        }
        c.ok(&format!("{:05} GoTo(X(-100), Y(0), Z(-10))", tag + 10));
    }
}

/// Scans refused for their size (beyond 720°, too many points, too much machine time) are
/// refused before anything moves: the position is unchanged to the last digit, and the error's
/// text names the limit.
#[test]
fn scans_refused_for_their_size_leave_the_machine_where_it_was() {
    let h = start(BORE_PART);
    let mut c = Raw::connect(&h);
    for l in ["00001 StartSession()", "00002 Home()", "00003 ChangeTool(\"Probe1\")"] {
        c.ok(l);
    }
    c.ok("00004 GoTo(X(-100), Y(0), Z(50))");
    c.ok("00005 GoTo(Z(-10))");
    let before = c.where_();
    // Beyond two turns: before the fix 1080° returned the 720° points and then repeated the last.
    let e = c.refused(
        "00006 ScanOnCircle(-100, 0, -10, -85.4, 0, -10, 0, 0, 1, 1080, 180, 1)",
        "1011",
        &["1080.000 deg", "limit of 720 deg"],
    );
    eprintln!("{e}");
    assert_eq!(c.where_(), before);
    c.refused(
        "00007 ScanOnCircle(-100, 0, -10, -85.4, 0, -10, 0, 0, 1, 720.01, 180, 1)",
        "1011",
        &["720 deg"],
    );
    assert_eq!(c.where_(), before);
    // 3.6e9 points.
    let e = c.refused(
        "00008 ScanOnCircle(-100, 0, -10, -85.4, 0, -10, 0, 0, 1, 360, 180, 0.0000001)",
        "1011",
        &["at most 1000000 points per scan"],
    );
    eprintln!("{e}");
    assert_eq!(c.where_(), before);
    // A line of 1800 mm in 1 µm steps: 1.8e6 points.
    c.refused("00009 ScanOnLine(-900, 0, 0, 900, 0, 0, 0, 0, 1, 0.001)", "1011", &["points per scan"]);
    assert_eq!(c.where_(), before);
    // Two turns of a 1.6 m circle on the table: 10 km of path, 500 s at 20 mm/s.
    c.ok("00010 GoTo(Z(50))");
    c.ok("00011 GoTo(X(800), Y(0))");
    let before = c.where_();
    let e = c.refused(
        "00012 ScanOnCircle(0, 0, 0, 800, 0, 0, 0, 0, 1, 720, 90, 1)",
        "1011",
        &["machine time", "the limit is 300 s per scan"],
    );
    eprintln!("{e}");
    assert_eq!(c.where_(), before);
    // Within the limits the same start works (the session was not harmed).
    let out = c.ok("00013 ScanOnLine(800, 0, 0, 810, 0, 0, 0, 0, 1, 1)");
    assert_eq!(out.iter().filter(|l| l.contains(" # ")).count(), 1);
}

/// A scan that passes the check on its nominal start but is refused at the start it measured
/// (the bore is 5 mm wider than the program says, so two turns at the real radius are over the
/// 300 s limit while two at the nominal one are not): the machine probes the start, and then,
/// refused, goes back the way it came, to the approach point and to where the command found it.
/// Before: it was left at the start contact, the probe on the wall.
#[test]
fn a_scan_refused_at_its_measured_start_leaves_the_machine_where_it_was() {
    // Ø964 bore about the Z axis through a table at Z = 0.
    let h = start("[[plane]]\nid = \"table\"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n\n[[cylinder]]\nid = \"bore\"\npoint_mm = [0, 0, 0]\naxis = [0, 0, 1]\ndiameter_mm = 964\nside = \"inside\"\n");
    let mut c = Raw::connect(&h);
    for l in [
        "00001 StartSession()",
        "00002 Home()",
        "00003 ChangeTool(\"Probe1\")",
        "00004 SetProp(Tool.PtMeasPar.Search(12))",
    ] {
        c.ok(l);
    }
    c.ok("00005 GoTo(X(0), Y(0), Z(50))");
    c.ok("00006 GoTo(Z(-10))");
    c.ok("00007 GoTo(X(400), Y(0), Z(-10))");
    let before = c.where_();
    // Nominal: a Ø954 bore (tip centre at 475.5 mm: 5975 mm for two turns, 299 s at 20 mm/s).
    let e = c.refused(
        "00008 ScanOnCircle(0, 0, -10, 477, 0, -10, 0, 0, 1, 720, 180, 1)",
        "1011",
        &["machine time", "the limit is 300 s per scan"],
    );
    eprintln!("{e}");
    assert_eq!(c.where_(), before, "the refused scan left the machine elsewhere");
    // The same scan on the nominal radius of the real bore, one turn: runs (the session was not
    // harmed).
    let out = c.ok("00009 ScanOnCircle(0, 0, -10, 482, 0, -10, 0, 0, 1, 360, 180, 1)");
    // One turn in 1° steps: 361 points (X, Y, Z and R each).
    let values: usize = out.iter().filter(|l| l.contains(" # ")).map(|l| l.split(',').count()).sum();
    assert!(values >= 4 * 360, "{out:?}");
}

/// A Ø20 sphere at (800, 800, 20): 1131 mm from the table axis, so a quarter turn of the table
/// or a steep tilt would carry it beyond the ±1000 mm volume.
const FAR_PART: &str = "[[sphere]]\nid = \"far\"\ncenter_mm = [800, 800, 20]\ndiameter_mm = 20\n";

/// PtMeas straight down onto the top of the sphere at (x, y): the tip-centre height.
fn top_at(c: &mut Raw, x: f64, y: f64) -> Option<f64> {
    c.ok("00020 GoTo(Z(80))");
    c.ok(&format!("00021 GoTo(X({x}), Y({y}))"));
    let out = c.cmd(&format!("00022 PtMeas(X({x}), Y({y}), Z(30), IJK(0, 0, 1))"));
    if out.iter().any(|l| l.contains(" ! ")) {
        c.ok("00023 ClearAllErrors()");
        return None;
    }
    let items = out
        .iter()
        .filter_map(|l| match Response::parse(l).ok()?.body {
            Body::Data(d) => parse_data_items(&d).ok(),
            _ => None,
        })
        .flatten()
        .collect::<Vec<_>>();
    items.iter().find(|(k, _)| k == "Z").map(|(_, v)| v[0])
}

/// `AlignPart`, `CenterPart`, `TiltPart`, `TiltCenterPart` with numbers that would take the part
/// out of the volume (or are out of it) are refused with 1008 naming the solid, and the table
/// angle, the part and the probe position are unchanged; a sound move afterwards works.
#[test]
fn part_moves_that_would_leave_the_volume_are_refused_and_change_nothing() {
    let h = start(FAR_PART);
    let mut c = Raw::connect(&h);
    for l in ["00001 StartSession()", "00002 Home()", "00003 ChangeTool(\"Probe1\")"] {
        c.ok(l);
    }
    // The ideal machine: the sphere's top under the tip centre at 20 + 10 + 1.5.
    assert_eq!(top_at(&mut c, 800.0, 800.0), Some(31.5));
    let before = c.where_();
    let cases: [(&str, &[&str]); 7] = [
        // Turn the part's (1, 1, 0) onto machine X: the sphere to (1131, 0).
        ("00030 AlignPart(1, 1, 0, 1, 0, 0, 0)", &["solid 'far'", "out of the machine volume"]),
        // The same with extreme components (a direction all the same).
        ("00031 AlignPart(1e300, 1e300, 0, 1, 0, 0, 0)", &["solid 'far'"]),
        // Centre on a point far off: the shift carries the sphere to (1600, 1600).
        ("00032 CenterPart(-800, -800, 20, 0.01)", &["solid 'far'", "part left where it is"]),
        // A centre outside the volume at all.
        ("00033 CenterPart(1e300, 0, 20, 0)", &["CenterPart", "outside the machine volume"]),
        // Tilt the nearly horizontal (1, 1, 0.001) onto the axis: the sphere to z ≈ 1131.
        ("00034 TiltPart(1, 1, 0.001, 0.01)", &["solid 'far'"]),
        ("00035 TiltPart(1e300, 1e300, 1e297, 0.01)", &["solid 'far'"]),
        (
            "00036 TiltCenterPart(1e300, 0, 0, 1e300, 0, 10, 0.01)",
            &["TiltCenterPart", "outside the machine volume"],
        ),
    ];
    for (line, needles) in cases {
        let e = c.refused(line, "1008", needles);
        eprintln!("{e}");
        assert_eq!(c.where_(), before, "{line}");
    }
    // The part and the table are where they were: R() 0 (in `before`) and the sphere's top.
    assert_eq!(top_at(&mut c, 800.0, 800.0), Some(31.5));
    // A sound move still works: centre the sphere on the table axis.
    assert!(c.ok("00040 CenterPart(800, 800, 20, 0.01)").iter().any(|l| l.contains("# CenterPart(0)")));
    assert_eq!(top_at(&mut c, 0.0, 0.0), Some(31.5));
    assert_eq!(top_at(&mut c, 800.0, 800.0), None);
}

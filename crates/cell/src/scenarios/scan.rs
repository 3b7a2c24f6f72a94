//! The scanning section of the demo: the same features scanned the blended and the classic way
//! on the virtual CMM, side by side, with the path shift at missed surfaces against the true
//! offsets. (The `scan` data set itself is [`truepos_plant::scan_scenario`].)

use crate::error::{Context, Result};
use truepos_plant::scan_scenario::{self, ScanFeature, ScanScenario};
use truepos_plant::scanning_cmm::{run_scan, CmmConfig};
use truepos_report::{self as report, Report, Series};
use truepos_scan::execute::{ControlParams, FeatureRun, Run as ScanRun};
use truepos_scan::{plan, validate, Plan, SegmentKind, Style};

/// Noise seeds of the form-error comparison's uncertainty.
const SCAN_MC_RUNS: usize = 40;

/// This capability's section of the demo report: the same features scanned the blended and the
/// classic way on the virtual CMM, side by side.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let s = scan_scenario::scenario(1, 12);
    let (nominal, truth, params) = scan_scenario::program(&s);
    validate(&nominal, &params).context("demo features")?;
    let (machine, control) = (CmmConfig::default(), ControlParams::default());
    let pb = plan(&nominal, &params, Style::Blended);
    let pc = plan(&nominal, &params, Style::Classic);
    let rb = run_scan(&pb, &truth, &machine, &control, 1).context("blended run")?;
    let rc = run_scan(&pc, &truth, &machine, &control, 1).context("classic run")?;

    let plot_b = path_plot(&pb, "Blended path around boss1 (XY), by segment")?;
    let plot_c = path_plot(&pc, "Classic path around boss1 (XY), by segment")?;
    // deflection against time around the first contact on feature 1 (a boss), both styles
    let plot_d = report::xy_plot(
        "Deflection from first contact into the scan (boss1)",
        "time from contact (s)",
        "deflection (mm)",
        &[deflection_series(&rb, "blended"), deflection_series(&rc, "classic")],
    )?;
    let table = report::table(
        &[
            "style",
            "cycle time (s)",
            "stops",
            "scan-start vibration, rms (µm)",
            "scan-start vibration, peak (µm)",
            "contact → scan (s)",
            "form error, mean (µm)",
            "form error, max (µm)",
        ],
        &[style_row("blended", &rb), style_row("classic", &rc)],
    );
    let shifts: Vec<Vec<String>> = missed_surfaces(&rb, &s)
        .map(|(f, t)| {
            vec![
                f.id.clone(),
                format!("{:+.3}", t.normal_offset_mm),
                format!("{:+.3}", f.contact_shift),
                format!("{:.2}", f.form_error * 1e3),
            ]
        })
        .collect();
    let shift_table = report::table(
        &["feature", "true offset (mm)", "path shift at contact (mm)", "form error (µm)"],
        &shifts,
    );
    let runs = StyleRuns { pb: &pb, pc: &pc, truth: &truth, machine: &machine, control: &control };
    report.verdict(demo_verdict(&s, nominal.len(), &rb, &rc, &runs)?);
    let html = format!(
        "<p>{} features (bores, bosses, circles on the top plane, lines) of a part whose every fifth feature is 1.2–1.8 mm off nominal, scanned at {} mm/s with {} mm deflection on the virtual CMM (15 Hz servo; 150 Hz stylus with restitution and Coulomb friction), the blended and the classic way. Cycle time saving of the blended style: <b>{:.1} %</b>. Vibration at scan start: deviation of the deflection from its target over the first 50 ms of the scan. Form error: peak-to-valley of the residuals of the least-squares element fitted to the scan segment (the true features are perfect, so this is what noise and dynamics leave).</p>\n{}\n{}\n{}\n{}\n<p>Missed surfaces (blended): the path shift where contact was made against the true offset.</p>\n{}",
        nominal.len(),
        params.scan_speed,
        params.deflection,
        100.0 * (1.0 - rb.cycle_time / rc.cycle_time),
        table,
        plot_b,
        plot_c,
        plot_d,
        shift_table
    );
    report.add("scan", "Scanning without stops: blended vs classic", html);
    Ok(())
}

/// Path plot (XY of the boss `boss1` with its incoming transfer), coloured by segment kind.
fn path_plot(pl: &Plan, title: &str) -> Result<String> {
    let kinds = [
        SegmentKind::Transfer,
        SegmentKind::Approach,
        SegmentKind::Settle,
        SegmentKind::Scan,
        SegmentKind::Release,
    ];
    let samples = pl.sample(0.002);
    let series: Vec<Series> = kinds
        .iter()
        .map(|k| {
            let pts = samples
                .iter()
                .filter(|q| pl.segments[q.segment].kind == *k && pl.segments[q.segment].feature == 1)
                .map(|q| (q.position.x, q.position.y))
                .collect();
            Series::points(k.as_str(), pts)
        })
        .collect();
    Ok(report::xy_plot_equal(title, "x (mm)", "y (mm)", &series)?)
}

/// Deflection against time from 20 ms before the first contact on feature 1 to 150 ms into
/// its scan.
fn deflection_series(r: &ScanRun, label: &str) -> Series {
    let f = &r.features[1];
    let pts = r
        .points
        .iter()
        .filter(|q| q.feature == 1 && q.t >= f.contact_t - 0.02 && q.t <= f.scan_start_t + 0.15)
        .map(|q| (q.t - f.contact_t, q.deflection))
        .collect();
    Series::line(label, pts)
}

fn mean_of(r: &ScanRun, g: fn(&FeatureRun) -> f64) -> f64 {
    r.features.iter().map(g).sum::<f64>() / r.features.len() as f64
}

/// The largest form error of a run (mm).
fn max_form(r: &ScanRun) -> f64 {
    r.features.iter().map(|f| f.form_error).fold(0.0, f64::max)
}

/// One style's row of the comparison table.
fn style_row(name: &str, r: &ScanRun) -> Vec<String> {
    vec![
        name.to_string(),
        format!("{:.2}", r.cycle_time),
        r.stops.to_string(),
        format!("{:.2}", mean_of(r, |f| f.vibration_rms) * 1e3),
        format!("{:.2}", mean_of(r, |f| f.vibration_peak) * 1e3),
        format!("{:.3}", mean_of(r, |f| f.ready_time)),
        format!("{:.2}", mean_of(r, |f| f.form_error) * 1e3),
        format!("{:.2}", max_form(r) * 1e3),
    ]
}

/// The features of the scenario displaced by more than 1 mm (missed surfaces), with their run.
fn missed_surfaces<'a>(
    r: &'a ScanRun,
    s: &'a ScanScenario,
) -> impl Iterator<Item = (&'a FeatureRun, &'a ScanFeature)> + 'a {
    r.features.iter().zip(&s.features).filter(|(_, t)| t.normal_offset_mm.abs() > 1.0)
}

/// Both styles' plans and what they run on, for further runs with other noise seeds.
struct StyleRuns<'a> {
    pb: &'a Plan,
    pc: &'a Plan,
    truth: &'a [truepos_scan::Feature],
    machine: &'a CmmConfig,
    control: &'a ControlParams,
}

/// The verdict: the blended largest form error against the classic one (≤ + 0.5 µm) and a
/// shorter cycle. The uncertainty of the compared quantity (blended − classic largest form
/// error) from the noise models (encoder, deflection, stylus): the same two runs on other noise
/// seeds.
fn demo_verdict(
    s: &ScanScenario,
    n_features: usize,
    rb: &ScanRun,
    rc: &ScanRun,
    runs: &StyleRuns,
) -> Result<report::Verdict> {
    let (fb, fc) = (max_form(rb) * 1e3, max_form(rc) * 1e3);
    let diffs: Vec<f64> = {
        use rayon::prelude::*;
        (2..2 + SCAN_MC_RUNS as u64)
            .into_par_iter()
            .map(|seed| -> Result<f64> {
                let b =
                    run_scan(runs.pb, runs.truth, runs.machine, runs.control, seed).context("blended run")?;
                let c =
                    run_scan(runs.pc, runs.truth, runs.machine, runs.control, seed).context("classic run")?;
                Ok((max_form(&b) - max_form(&c)) * 1e3)
            })
            .collect::<Result<Vec<f64>>>()?
    };
    let n = diffs.len() as f64;
    let mean_d = diffs.iter().sum::<f64>() / n;
    let sd_d = (diffs.iter().map(|d| (d - mean_d).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let u_d = truepos_math::stats::COVERAGE_FACTOR * sd_d;
    let worst_shift = missed_surfaces(rb, s)
        .map(|(f, t)| (f.contact_shift - t.normal_offset_mm).abs())
        .fold(0.0_f64, f64::max);
    Ok(report::Verdict {
        section: "scan".into(),
        capability: "Scanning without stops".into(),
        measured: format!("{n_features} features scanned blended and classic; form error and cycle time"),
        truth: "perfect features at the simulator's true positions (form error 0)".into(),
        result: format!(
            "cycle time −{:.1} %; form error max {fb:.2} µm blended, {fc:.2} µm classic; missed-surface shift within {:.0} µm of the true offset",
            100.0 * (1.0 - rb.cycle_time / rc.cycle_time),
            worst_shift * 1e3
        ),
        uncertainty: format!(
            "U = {u_d:.2} µm (k = 2) on blended − classic largest form error: its spread over {SCAN_MC_RUNS} further runs of both styles with other noise seeds (encoder, deflection, stylus; mean {mean_d:+.2} µm)"
        ),
        tolerance_text: "blended form error max ≤ classic + 0.5 µm, and a shorter cycle".into(),
        ..report::Verdict::judged(
            report::Judgement::new((fb - fc).max(0.0), u_d, 0.5, "µm", report::DecisionRule::Simple)
                .require(rb.cycle_time < rc.cycle_time, "the blended cycle is not shorter")
                .require(fb <= fc + 0.5, "blended form error more than 0.5 µm above classic"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_section_compares_both_styles() {
        let dir = std::env::temp_dir().join(format!("truepos-cell-scan-demo-{}", std::process::id()));
        let mut r = Report::new(&dir);
        demo_section(&mut r).unwrap();
        let html = std::fs::read_to_string(r.write().unwrap()).unwrap();
        let _ = std::fs::remove_dir_all(&dir);

        assert!(html.contains("Scanning without stops"));
        assert!(html.contains("blended") && html.contains("classic"));
        assert!(html.matches("<svg").count() >= 3, "path plots and deflection plot");
    }
}

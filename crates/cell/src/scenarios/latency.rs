//! The `latency` scenario: the simulator's probe and machine streams written as the contract's
//! files with their `truth.json`, and the demo section (every method against the true delay).
//!
//! Entry points: [`write_dataset`], [`OwnedStreams`] (a data set as the library's streams),
//! [`demo_section`].

use crate::error::{CellError, Result};
use std::io::Write;
use std::path::Path;
use truepos_io::atomic::AtomicFile;
use truepos_latency::{self as lat, KnownSize, Method, Options, Streams};
use truepos_report::{self as report, Report, Series};
use truepos_sim::scenario::latency as scen;

/// Write a data set as the contract's files: `machine.csv` (t_s,x_mm,y_mm,z_mm), `probe.csv`
/// (t_s,a_mm,b_mm,c_mm) and `truth.json`.
pub fn write_dataset(dir: &Path, d: &scen::Dataset) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| CellError::io(dir, e))?;
    let facts = key_facts(&d.truth);
    let next = suggested_command(dir, &d.truth);
    let write = |name: &str, header: [&str; 4], rows: &mut dyn Iterator<Item = [f64; 4]>| -> Result<()> {
        let path = dir.join(name);
        let mut f = AtomicFile::create(&path)?;
        {
            // 10 ns and 0.01 nm: far below the clocks' and sensors' resolution, and files a third
            // smaller than the shortest round-trip text of noisy numbers.
            let mut w = truepos_io::csv::CsvWriter::new(std::io::BufWriter::new(&mut f))
                .with_format(truepos_io::num::NumFormat::Fixed(8));
            w.comment(&format!("truepos simulate latency: {facts}"))?;
            if name == "machine.csv" {
                w.comment("t_s: time stamp on the master clock (s); x_mm,y_mm,z_mm: encoder position of the probe body (mm), stamped with the machine's capture latency")?;
            } else {
                w.comment("t_s: time stamp on the master clock (s); a_mm,b_mm,c_mm: stylus deflection along the machine X, Y, Z axes (mm), pointing along the surface's outward normal")?;
            }
            w.comment(&format!("estimate the delay with: {next}"))?;
            w.comment("the true delay is delay_s in truth.json")?;
            w.header(&header)?;
            for r in rows {
                w.row_f64(&r)?;
            }
            w.into_inner().flush()?;
        }
        f.commit()?;
        Ok(())
    };
    write(
        "machine.csv",
        ["t_s", "x_mm", "y_mm", "z_mm"],
        &mut d.machine.iter().map(|(t, p)| [*t, p.x, p.y, p.z]),
    )?;
    write(
        "probe.csv",
        ["t_s", "a_mm", "b_mm", "c_mm"],
        &mut d.probe.iter().map(|(t, p)| [*t, p.x, p.y, p.z]),
    )?;
    truepos_io::atomic::write_atomic(
        dir.join("truth.json"),
        serde_json::to_string_pretty(&d.truth)?.as_bytes(),
    )?;
    Ok(())
}

/// A `truepos simulate latency` request: a preset variant and the values that override it.
#[derive(Clone, Debug, Default)]
pub struct SimRequest {
    /// One of [`scen::Variant::ALL`] by name (sphere, plates, speeds, …).
    pub variant: String,
    /// Seed of the noise.
    pub seed: u64,
    /// System delay (s): machine capture latency minus probe capture latency.
    pub delay_s: Option<f64>,
    /// Contact speed, mm/s (`None`: the variant's).
    pub speed_mm_s: Option<f64>,
    /// Repeats of the contact pattern; `None`: [`default_repeats`] (enough for the 10 µs goal).
    pub repeats: Option<usize>,
    /// Machine sampling rate, Hz (`None`: the variant's).
    pub machine_rate_hz: Option<f64>,
    /// Probe sampling rate, Hz (`None`: the variant's).
    pub probe_rate_hz: Option<f64>,
}

/// A request the scenario cannot honour.
#[derive(Debug, thiserror::Error)]
pub enum SimRequestError {
    /// The variant is not one of the scenario's.
    #[error("unknown variant '{given}': one of {known}")]
    UnknownVariant {
        /// The name given.
        given: String,
        /// The names there are.
        known: String,
    },
    /// The delay is not finite.
    #[error("--delay-s must be finite")]
    DelayNotFinite,
    /// The scenario refused the settings.
    #[error(transparent)]
    Scenario(#[from] scen::LatencyError),
}

/// The scenario configuration of a request: the variant's preset with the overrides applied.
pub fn config(r: &SimRequest) -> Result<scen::Config, SimRequestError> {
    let v = scen::Variant::parse(&r.variant).ok_or_else(|| SimRequestError::UnknownVariant {
        given: r.variant.clone(),
        known: scen::Variant::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", "),
    })?;
    let mut c = scen::Config::preset(v);
    c.seed = r.seed;
    if let Some(d) = r.delay_s {
        if !d.is_finite() {
            return Err(SimRequestError::DelayNotFinite);
        }
        // Keep the probe latency; the machine latencies follow the requested delay (per axis:
        // shifted so that their mean delay is d).
        let mean = c.machine_latencies().iter().sum::<f64>() / 3.0 - c.probe_latency_s;
        if let Some(ax) = &mut c.axis_latency_s {
            for l in ax.iter_mut() {
                *l += d - mean;
            }
        }
        c.machine_latency_s = c.probe_latency_s + d;
    }
    if let Some(s) = r.speed_mm_s {
        c.speed_mm_s = s;
    }
    // Without repeats, enough contacts to meet the 10 µs goal (not the simulator's single
    // pattern): see [`default_repeats`].
    c.repeats = r.repeats.unwrap_or_else(|| default_repeats(v));
    if let Some(h) = r.machine_rate_hz {
        c.machine_rate_hz = h;
    }
    if let Some(h) = r.probe_rate_hz {
        c.probe_rate_hz = h;
    }
    Ok(c)
}

/// The data set of a request (the simulator run on [`config`]).
pub fn simulate(r: &SimRequest) -> Result<scen::Dataset, SimRequestError> {
    Ok(scen::simulate(&config(r)?)?)
}

/// Streams of a data set, as the library takes them.
pub struct OwnedStreams {
    /// Machine time stamps, s.
    pub mt: Vec<f64>,
    /// Machine positions, mm.
    pub m: Vec<[f64; 3]>,
    /// Probe time stamps, s.
    pub pt: Vec<f64>,
    /// Probe deflections, mm.
    pub p: Vec<[f64; 3]>,
}

impl OwnedStreams {
    /// Copy the streams of a simulated data set.
    pub fn of(d: &scen::Dataset) -> Self {
        OwnedStreams {
            mt: d.machine.iter().map(|x| x.0).collect(),
            m: d.machine.iter().map(|x| [x.1.x, x.1.y, x.1.z]).collect(),
            pt: d.probe.iter().map(|x| x.0).collect(),
            p: d.probe.iter().map(|x| [x.1.x, x.1.y, x.1.z]).collect(),
        }
    }
    /// The streams as the latency library takes them.
    pub fn streams(&self) -> Streams<'_> {
        Streams { machine_t: &self.mt, machine: &self.m, probe_t: &self.pt, probe: &self.p }
    }
}

/// The demo's data sets: the preset variant, the method it is estimated with, and its repeats.
const DEMO_RUNS: [(scen::Variant, Method, usize); 8] = [
    (scen::Variant::Sphere, Method::Artefact, 48),
    (scen::Variant::Plates, Method::Artefact, 48),
    (scen::Variant::Speeds, Method::Speeds, 16),
    (scen::Variant::Scan, Method::Scan, 24),
    (scen::Variant::InOut, Method::Inout, 48),
    (scen::Variant::PerAxis, Method::Artefact, 48),
    (scen::Variant::MultiRate, Method::Artefact, 48),
    (scen::Variant::Oblique, Method::Artefact, 48),
];

/// What the demo's data sets gave: the table rows, the plots, and for the verdict the worst
/// |error| and largest standard uncertainty over the whole-delay estimates (per-axis rows are
/// judged in their own table), and the data sets whose method failed.
#[derive(Default)]
struct Tally {
    rows: Vec<Vec<String>>,
    html: String,
    worst_err: f64,
    worst_u: f64,
    n_ok: usize,
    failed: Vec<String>,
}

/// Demo: every method on the virtual cell against the truth; size against speed; the scan's
/// radial error before and after the shift.
pub fn demo_section(report: &mut Report) -> Result<()> {
    let mut tally = Tally::default();
    for (variant, method, repeats) in DEMO_RUNS {
        run_demo_dataset(variant, method, repeats, &mut tally)?;
    }
    report.verdict(demo_verdict(&tally));
    let table = report::table(
        &["data set", "method", "true delay (µs)", "recovered (µs)", "u (µs)", "error (µs)", "|error|/u"],
        &tally.rows,
    );
    let html = &tally.html;
    report.add(
        "latency",
        "System delay between probe and machine data",
        format!("<p>Virtual cell: encoders 1 µm, probe 0.3 µm, 1 kHz streams (probe 4 kHz for multi-rate), stylus dynamics and servo following error on. The delay is recovered from the raw streams by every method. The per-axis data set has a different delay on each machine axis: its single-delay row is a compromise over the axes and is not judged; the rows “per-axis X/Y” are each axis's own delay (from the contacts on opposite sides along that axis) against that axis's true delay, and Z, touched from one side only, is not determined.</p>{table}{html}"),
    );
    Ok(())
}

/// One data set of the demo: simulate it (seed 7), estimate the delay with `method`, and add
/// its rows and plots (or its failure) to `tally`.
fn run_demo_dataset(variant: scen::Variant, method: Method, repeats: usize, tally: &mut Tally) -> Result<()> {
    let mut c = scen::Config::preset(variant);
    c.repeats = repeats;
    c.seed = 7;
    let per_axis = variant == scen::Variant::PerAxis;
    let d = scen::simulate(&c)?;
    let st = OwnedStreams::of(&d);
    let known = match (method, d.truth.artefact) {
        (Method::Artefact, scen::ArtefactTruth::Sphere { diameter_mm, .. }) => {
            Some(KnownSize::SphereDiameter(diameter_mm))
        }
        (Method::Artefact, scen::ArtefactTruth::Plates { gap_mm, .. }) => Some(KnownSize::Gap(gap_mm)),
        _ => None,
    };
    let opt = Options {
        method,
        known_size: known,
        tip_radius: d.truth.tip_radius_mm,
        per_axis,
        ..Options::default()
    };
    let name = variant.name();
    let e = match lat::estimate(&st.streams(), &opt) {
        Ok(e) => e,
        Err(err) => {
            tally.failed.push(name.to_string());
            tally.rows.push(vec![
                name.to_string(),
                method.name().to_string(),
                format!("{:.2}", d.truth.delay_s * 1e6),
                format!("failed: {err}"),
                String::new(),
                String::new(),
                String::new(),
            ]);
            return Ok(());
        }
    };
    let err = e.delay - d.truth.delay_s;
    if !per_axis {
        tally.worst_err = tally.worst_err.max(err.abs());
        tally.worst_u = tally.worst_u.max(e.u_delay);
        tally.n_ok += 1;
    }
    tally.rows.push(vec![
        name.to_string(),
        if per_axis {
            format!("{} (one delay for axes that differ: not meaningful)", e.method().name())
        } else {
            e.method().name().to_string()
        },
        format!("{:.2}", d.truth.delay_s * 1e6),
        format!("{:.2}", e.delay * 1e6),
        format!("{:.2}", e.u_delay * 1e6),
        if per_axis {
            format!("{:+.2} (not judged: the axes differ, see the rows below)", err * 1e6)
        } else {
            format!("{:+.2}", err * 1e6)
        },
        if per_axis { "—".into() } else { format!("{:.2}", err.abs() / e.u_delay) },
    ]);
    if let Some(pa) = e.per_axis() {
        tally.rows.extend(per_axis_rows(name, &e, pa, &d.truth));
    }
    if variant == scen::Variant::Speeds {
        tally.html.push_str(&speeds_plot(&e, &d.truth)?);
    }
    if let Some(sc) = e.scan() {
        tally.html.push_str(&scan_plot(&st, sc)?);
    }
    Ok(())
}

/// The rows of each axis's own delay (per-axis method) against that axis's true delay.
fn per_axis_rows(name: &str, e: &lat::Estimate, pa: &lat::PerAxis, truth: &scen::Truth) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for k in 0..3 {
        if pa.delay[k].is_none() {
            rows.push(vec![
                format!("{name} {}", ["X", "Y", "Z"][k]),
                format!("{} (per axis)", e.method().name()),
                format!("{:.2}", truth.per_axis_delay_s[k] * 1e6),
                "not determined (no opposite contacts along this axis)".into(),
                String::new(),
                String::new(),
                String::new(),
            ]);
        }
        if let (Some(dk), Some(uk)) = (pa.delay[k], pa.u_delay[k]) {
            let ek = dk - truth.per_axis_delay_s[k];
            rows.push(vec![
                format!("{name} {}", ["X", "Y", "Z"][k]),
                format!("{} (per axis)", e.method().name()),
                format!("{:.2}", truth.per_axis_delay_s[k] * 1e6),
                format!("{:.2}", dk * 1e6),
                format!("{:.2}", uk * 1e6),
                format!("{:+.2}", ek * 1e6),
                format!("{:.2}", ek.abs() / uk),
            ]);
        }
    }
    rows
}

/// The speeds method's plot: measured size against speed with the fitted line.
fn speeds_plot(e: &lat::Estimate, truth: &scen::Truth) -> Result<String> {
    let pts: Vec<(f64, f64)> = e.per_speed().to_vec();
    let s0 = e.static_size().unwrap_or(f64::NAN);
    let vmax = pts.iter().map(|p| p.0).fold(0.0, f64::max);
    // Retract on an outer feature: size = static − 2·v·D.
    let line: Vec<(f64, f64)> = (0..=20)
        .map(|i| {
            let v = vmax * 1.05 * i as f64 / 20.0;
            (v, s0 - 2.0 * v * e.delay)
        })
        .collect();
    let svg = report::xy_plot(
        "Measured sphere size against speed (speeds method)",
        "speed (mm/s)",
        "size (mm)",
        &[Series::points("measured", pts), Series::line("fit: static − 2·v·delay", line)],
    )?;
    Ok(format!(
        "<p>Speeds method: static size {:.5} mm (true {:.5} mm); the gradient of size against speed gives the delay.</p>{svg}",
        s0, truth.static_size_mm
    ))
}

/// The scan method's plot: the radial error of the combined points without and with the shift.
fn scan_plot(st: &OwnedStreams, sc: &lat::scan::ScanResult) -> Result<String> {
    let before = lat::scan::radial_errors(&st.streams(), sc, 0.0);
    let after = lat::scan::radial_errors(&st.streams(), sc, sc.delay);
    let t0 = before.first().map_or(0.0, |p| p.0);
    let step = (before.len() / 3000).max(1);
    let to_um = |v: &[(f64, f64)]| v.iter().step_by(step).map(|p| (p.0 - t0, p.1 * 1e3)).collect::<Vec<_>>();
    let svg = report::xy_plot(
        "Scan: radial error of the combined points",
        "time (s)",
        "radial error (µm)",
        &[
            Series::line("without shift", to_um(&before)),
            Series::line(&format!("shifted by {:.1} µs", sc.delay * 1e6), to_um(&after)),
        ],
    )?;
    Ok(format!(
        "<p>Scan method: RMS radial error {:.3} µm without the shift, {:.3} µm with it ({} deflection steps).</p>{svg}",
        sc.rms_before * 1e3,
        sc.rms_after * 1e3,
        sc.n_steps
    ))
}

/// The section's verdict: the worst |error| of the whole-delay estimates against 10 µs.
fn demo_verdict(t: &Tally) -> report::Verdict {
    let tol_s = 10e-6;
    report::Verdict {
        section: "latency".into(),
        capability: "System delay (latency)".into(),
        measured: format!("delay between probe and machine streams, {} data sets × method", t.n_ok),
        truth: "the simulator's delay per data set (column “true delay”)".into(),
        result: format!("worst |error| {:.2} µs", t.worst_err * 1e6),
        uncertainty: format!("largest U = {:.2} µs (k = 2)", 2.0 * t.worst_u * 1e6),
        tolerance_text: "|error| ≤ 10 µs for every method (the product goal)".into(),
        ..report::Verdict::judged(
            report::Judgement::new(
                t.worst_err * 1e6,
                2.0 * t.worst_u * 1e6,
                tol_s * 1e6,
                "µs",
                report::DecisionRule::Simple,
            )
            .require(t.n_ok > 0, "no data set was evaluated")
            .require(t.failed.is_empty(), format!("failed: {}", t.failed.join(", "))),
        )
    }
}

/// Repeats of the contact pattern (or scan revolutions) that `truepos simulate latency` uses
/// when `--repeats` is not given: enough contacts that the default data set meets the 10 µs
/// goal (the simulator's preset of one pattern, 5 contacts, gives about ±20 µs standard
/// uncertainty; 24 patterns, 120 contacts, about ±4 µs).
pub fn default_repeats(variant: scen::Variant) -> usize {
    match variant {
        scen::Variant::Speeds => 8,
        scen::Variant::Scan => 12,
        _ => 24,
    }
}

/// The `truepos latency` command line that estimates the delay of a data set written to `dir`.
pub fn suggested_command(dir: &Path, t: &scen::Truth) -> String {
    let files = format!(
        "truepos latency --machine {} --probe {}",
        dir.join("machine.csv").display(),
        dir.join("probe.csv").display()
    );
    let artefact = match t.artefact {
        scen::ArtefactTruth::Sphere { diameter_mm, .. } => format!("--sphere-diameter-mm {diameter_mm}"),
        scen::ArtefactTruth::Plates { gap_mm, .. } => format!("--gap-mm {gap_mm}"),
    };
    match t.variant {
        scen::Variant::Speeds => format!("{files} --method speeds"),
        scen::Variant::Scan => format!("{files} --method scan"),
        scen::Variant::InOut => format!("{files} --method inout"),
        scen::Variant::PerAxis => {
            format!("{files} {artefact} --tip-radius-mm {} --per-axis", t.tip_radius_mm)
        }
        _ => format!("{files} {artefact} --tip-radius-mm {}", t.tip_radius_mm),
    }
}

/// What `truepos simulate latency` prints: the key facts, the command and what to compare.
pub fn written_text(dir: &Path, d: &scen::Dataset) -> String {
    format!(
        "latency scenario {}; {} machine and {} probe samples → {}\nnext: {}\nthen compare delay_s with the true delay_s in {}\n",
        key_facts(&d.truth),
        d.machine.len(),
        d.probe.len(),
        dir.display(),
        suggested_command(dir, &d.truth),
        dir.join("truth.json").display()
    )
}

/// The scenario's key facts in one line: artefact and its size, tip, contacts and speeds,
/// stream rates and noise.
pub fn key_facts(t: &scen::Truth) -> String {
    let artefact = match t.artefact {
        scen::ArtefactTruth::Sphere { diameter_mm, centre_mm } => {
            format!("sphere Ø {diameter_mm} mm at ({}, {}, {}) mm", centre_mm[0], centre_mm[1], centre_mm[2])
        }
        scen::ArtefactTruth::Plates { gap_mm, .. } => format!("parallel plates {gap_mm} mm apart"),
    };
    let speeds = t.speeds_mm_s.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(", ");
    let contacts = if t.variant == scen::Variant::Scan {
        "a continuous scan".to_string()
    } else {
        format!("{} contacts", t.contacts.len())
    };
    format!(
        "variant {}: {artefact}, stylus tip radius {} mm, {contacts} at {speeds} mm/s, machine {} Hz (encoder noise {} µm), probe {} Hz (noise {} µm), {:.1} s of data",
        t.variant.name(),
        t.tip_radius_mm,
        t.machine_rate_hz,
        t.encoder_noise_mm * 1e3,
        t.probe_rate_hz,
        t.probe_noise_mm * 1e3,
        t.duration_s
    )
}

impl truepos_math::exit::HasExitClass for SimRequestError {
    /// A scenario request that cannot be simulated is bad usage (exit 2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Usage
    }
}

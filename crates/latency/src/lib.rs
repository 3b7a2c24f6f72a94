//! # truepos-latency — probe/machine system-delay calibration
//!
//! A scanning probe reports stylus deflection, the machine its encoder position; both are
//! stamped on one master clock but captured with different latencies. The *system delay*
//! `D` is how much later the machine data is stamped than the probe data for the same instant:
//! the stylus centre at probe stamp `t` is `machine(t + D) + deflection(t)` (interface contract).
//!
//! The estimation functions take time-stamped streams as slices and do no I/O; [`crate::file`] reads
//! the stream CSVs.
//!
//! Entry points:
//! - [`estimate`] with [`Options`] → [`Estimate`] (its [`Evidence`] has one variant per method):
//!   checks the streams, segments the contacts,
//!   extrapolates each to zero deflection and runs one of the four methods
//!   ([`Method::Artefact`], [`Method::Speeds`], [`Method::Scan`], [`Method::Inout`]), or picks
//!   one ([`Method::Auto`]).
//! - [`probing::delay_by_feeds`]: the delay through a controller, a sphere probed at several
//!   feeds (radius against feed).
//! - [`task`]: `truepos latency` and `latency apply` as library calls (files in, a `Report` back).
//! - [`file::read_stream`]: a stream CSV; [`file::input_error`]: stream errors with file and line.
//! - [`apply`]: stylus-centre positions at the probe stamps for a known delay.
//! - modules: [`stream`] (checks, interpolation), [`contact`] (segmentation, extrapolation),
//!   [`geom`] (feature fits with the delay), [`touch`] (touch methods), [`scan`] (scan method).

#![forbid(unsafe_code)]
// `!(x > 0.0)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod contact;
pub mod file;
pub mod geom;
pub mod json;
pub mod probing;
pub mod scan;
pub mod stream;
pub mod task;
pub mod text;
pub mod touch;

pub use contact::{Contact, Phase};
pub use stream::{Streams, Which};
pub use touch::PerAxis;

use thiserror::Error;

/// Why a delay cannot be computed. Every variant is caused by the input data or options.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LatencyError {
    /// A stream has a different number of time stamps and values.
    #[error("{which} stream: {times} time stamps but {values} values")]
    LengthMismatch {
        /// Which stream.
        which: Which,
        /// Number of time stamps.
        times: usize,
        /// Number of values.
        values: usize,
    },
    /// A stream has fewer than two samples.
    #[error("{which} stream: {n} sample(s); at least two are needed")]
    TooShort {
        /// Which stream.
        which: Which,
        /// Number of samples.
        n: usize,
    },
    /// A stream sample (0-based index) is NaN or infinite.
    #[error("{which} stream: sample {index} is not finite")]
    NotFinite {
        /// Which stream.
        which: Which,
        /// 0-based sample index.
        index: usize,
    },
    /// Two samples of a stream have the same time stamp, s.
    #[error("{which} stream: duplicate time stamp {t} s (sample {index})")]
    DuplicateStamp {
        /// Which stream.
        which: Which,
        /// 0-based sample index.
        index: usize,
        /// The stamp, s.
        t: f64,
    },
    /// A stream's time stamps decrease at a sample (stamp and previous stamp, s).
    #[error("{which} stream: time stamps not increasing: {t} s after {previous} s (sample {index})")]
    NotIncreasing {
        /// Which stream.
        which: Which,
        /// 0-based sample index.
        index: usize,
        /// The stamp, s.
        t: f64,
        /// The stamp before it, s.
        previous: f64,
    },
    /// The machine and probe streams cover disjoint time spans (start, end of each, s).
    #[error(
        "the streams do not overlap in time: machine {:.6}–{:.6} s, probe {:.6}–{:.6} s",
        machine.0,
        machine.1,
        probe.0,
        probe.1
    )]
    NoOverlap {
        /// The machine stream's span (start, end), s.
        machine: (f64, f64),
        /// The probe stream's span (start, end), s.
        probe: (f64, f64),
    },
    /// No contact was found in the probe stream (why).
    #[error("no contact found: {0}")]
    NoContact(String),
    /// The speeds method with contacts at one speed only (that speed, mm/s).
    #[error(
        "all contacts are at one speed ({0:.3} mm/s): the speeds method needs at least two speeds (or give the artefact size for the artefact method)"
    )]
    SingleSpeed(f64),
    /// The data cannot determine the delay (why).
    #[error("the data cannot determine the delay: {0}")]
    Underdetermined(String),
    /// Degenerate data: a fit has no solution (why).
    #[error("degenerate data: {0}")]
    Degenerate(String),
    /// The options contradict each other or the data (the message).
    #[error("{0}")]
    Options(String),
}

/// Calibration method (`truepos latency --method`; the variants' documentation is the command
/// line's help for each value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Method {
    /// Chosen from the data and options: scan when the data is a scan; artefact when a size is
    /// given; speeds when the contacts have several speeds; in-out otherwise.
    Auto,
    /// Known artefact size (--sphere-diameter-mm or --gap-mm) at one or more speeds.
    Artefact,
    /// Several speeds, size unknown: size linear in speed (gradient → delay).
    Speeds,
    /// Continuous scan switching between two radii: the shift minimising the form error.
    Scan,
    /// Single point in and out: time between the extrema of machine position and deflection.
    Inout,
}

impl Method {
    /// The method's name on the command line and in the JSON output.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Artefact => "artefact",
            Method::Speeds => "speeds",
            Method::Scan => "scan",
            Method::Inout => "inout",
        }
    }
}

/// Known artefact size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KnownSize {
    /// Sphere (or ring) diameter, mm.
    SphereDiameter(f64),
    /// Distance between two parallel faces, mm.
    Gap(f64),
}

/// Options of [`estimate`].
#[derive(Clone, Debug)]
pub struct Options {
    /// The calibration method (`Auto` chooses from the data).
    pub method: Method,
    /// The artefact's known size, for the artefact method.
    pub known_size: Option<KnownSize>,
    /// Stylus tip radius (mm); sizes are of the artefact, points of the stylus centre.
    pub tip_radius: f64,
    /// Contact detection threshold on |deflection| (mm).
    pub threshold: f64,
    /// Separate delays for X, Y, Z.
    pub per_axis: bool,
    /// Search range of the scan method (s).
    pub max_delay: f64,
    /// Delay already applied to the data (s): the estimate is then a residual.
    pub already_corrected: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            method: Method::Auto,
            known_size: None,
            tip_radius: 0.0,
            threshold: 0.005,
            per_axis: false,
            max_delay: 0.05,
            already_corrected: 0.0,
        }
    }
}

/// The calibrated delay and what supports it.
#[derive(Clone, Debug)]
pub struct Estimate {
    /// Total delay (s): `already_corrected + residual_delay`.
    pub delay: f64,
    /// Delay measured in the data as given (s).
    pub residual_delay: f64,
    /// Standard uncertainty of the delay (s).
    pub u_delay: f64,
    /// Number of contacts in the final fit.
    pub n_contacts: usize,
    /// RMS residual of the fit (mm).
    pub rms: f64,
    /// Notes for people about the data or the result (e.g. a poorly determined axis).
    pub warnings: Vec<String>,
    /// The contacts of the final fit. For the artefact and speeds methods the machine stamps
    /// were moved by a first estimate of the delay before they were extracted, so their points
    /// hold the data corrected by that estimate (see [`estimate`]).
    pub contacts: Vec<Contact>,
    /// What the method found besides the delay; its variant is the method used.
    pub evidence: Evidence,
}

/// What each method found besides the delay (one variant per method).
#[derive(Clone, Debug)]
pub enum Evidence {
    /// A known artefact: the feature the contacts describe and its known size (mm).
    Artefact {
        /// The feature the contact normals describe.
        feature: &'static str,
        /// Its known size, mm.
        size_mm: f64,
        /// Separate delays per axis, when fitted.
        per_axis: Option<PerAxis>,
    },
    /// Several speeds: the artefact size at zero speed with its standard uncertainty (mm), and
    /// (speed mm/s, size mm) per speed group.
    Speeds {
        /// The feature the contact normals describe.
        feature: &'static str,
        /// The size at zero speed, mm.
        static_size_mm: f64,
        /// Its standard uncertainty, mm.
        u_static_size_mm: f64,
        /// (mean speed mm/s, size mm) per speed group.
        per_speed: Vec<(f64, f64)>,
        /// Separate delays per axis, when fitted.
        per_axis: Option<PerAxis>,
    },
    /// A scan with direction changes.
    Scan(scan::ScanResult),
    /// In-out touches: the delay of every contact (s) with its uncertainty.
    Inout {
        /// (delay s, standard uncertainty s) per contact.
        per_contact: Vec<(f64, f64)>,
        /// Separate delays per axis, when fitted.
        per_axis: Option<PerAxis>,
    },
}

impl Estimate {
    /// The method used (never `Auto`).
    pub fn method(&self) -> Method {
        match self.evidence {
            Evidence::Artefact { .. } => Method::Artefact,
            Evidence::Speeds { .. } => Method::Speeds,
            Evidence::Scan(_) => Method::Scan,
            Evidence::Inout { .. } => Method::Inout,
        }
    }
    /// The feature the contacts describe (touch methods with a feature fit).
    pub fn feature(&self) -> Option<&'static str> {
        match self.evidence {
            Evidence::Artefact { feature, .. } | Evidence::Speeds { feature, .. } => Some(feature),
            _ => None,
        }
    }
    /// Artefact size (mm): the known size (artefact), at zero speed (speeds), the scanned
    /// circle's diameter (scan).
    pub fn static_size(&self) -> Option<f64> {
        match &self.evidence {
            Evidence::Artefact { size_mm, .. } => Some(*size_mm),
            Evidence::Speeds { static_size_mm, .. } => Some(*static_size_mm),
            Evidence::Scan(r) => Some(2.0 * r.radius),
            Evidence::Inout { .. } => None,
        }
    }
    /// Standard uncertainty of the size at zero speed (speeds).
    pub fn u_static_size(&self) -> Option<f64> {
        match &self.evidence {
            Evidence::Speeds { u_static_size_mm, .. } => Some(*u_static_size_mm),
            _ => None,
        }
    }
    /// (speed mm/s, size mm) per speed group (speeds; empty otherwise).
    pub fn per_speed(&self) -> &[(f64, f64)] {
        match &self.evidence {
            Evidence::Speeds { per_speed, .. } => per_speed,
            _ => &[],
        }
    }
    /// Separate delays for X, Y, Z when asked for (touch methods).
    pub fn per_axis(&self) -> Option<&PerAxis> {
        match &self.evidence {
            Evidence::Artefact { per_axis, .. }
            | Evidence::Speeds { per_axis, .. }
            | Evidence::Inout { per_axis, .. } => per_axis.as_ref(),
            Evidence::Scan(_) => None,
        }
    }
    fn per_axis_mut(&mut self) -> Option<&mut PerAxis> {
        match &mut self.evidence {
            Evidence::Artefact { per_axis, .. }
            | Evidence::Speeds { per_axis, .. }
            | Evidence::Inout { per_axis, .. } => per_axis.as_mut(),
            Evidence::Scan(_) => None,
        }
    }
    /// The scan method's result.
    pub fn scan(&self) -> Option<&scan::ScanResult> {
        match &self.evidence {
            Evidence::Scan(r) => Some(r),
            _ => None,
        }
    }
    /// Per-contact delays of the in-out method (s, u; empty otherwise).
    pub fn inout_each(&self) -> &[(f64, f64)] {
        match &self.evidence {
            Evidence::Inout { per_contact, .. } => per_contact,
            _ => &[],
        }
    }
}

/// Artefact size from a signed stylus-centre size (+ outer, − inner).
pub fn artefact_size(signed: f64, tip_radius: f64) -> f64 {
    if signed >= 0.0 {
        signed - 2.0 * tip_radius
    } else {
        -signed + 2.0 * tip_radius
    }
}

/// Signed stylus-centre size of a known artefact for a feature that is outer or inner.
fn stylus_centre_size(k: KnownSize, outer: bool, tip_radius: f64) -> f64 {
    let s = match k {
        KnownSize::SphereDiameter(d) | KnownSize::Gap(d) => d,
    };
    if outer {
        s + 2.0 * tip_radius
    } else {
        -(s - 2.0 * tip_radius)
    }
}

/// Run the calibration: check the options, find the contacts, choose the method (when
/// [`Method::Auto`]), measure the delay with it, and check the result's plausibility.
pub fn estimate(s: &Streams, opt: &Options) -> Result<Estimate, LatencyError> {
    s.check()?;
    check_options(opt)?;
    let mut mi = Vec::new();
    stream::machine_at(s.machine_t, s.machine, s.probe_t, 0.0, &mut mi);
    let copt = contact::ContactOptions { threshold: opt.threshold, ..Default::default() };
    let contacts = contact::extract_contacts(s, &mi, &copt, 0.5);
    let method = choose_method(s, opt, &contacts)?;
    let mut warnings = Vec::new();
    let m = if method == Method::Scan {
        let r = scan::scan_delay(s, opt.threshold, opt.max_delay)?;
        if opt.per_axis {
            warnings
                .push("--per-axis is not available with the scan method; use touches along each axis".into());
        }
        Measured {
            delay: r.delay,
            u_delay: r.u_delay,
            rms: r.rms_after,
            n_contacts: 1,
            contacts,
            evidence: Evidence::Scan(r),
        }
    } else {
        touch_delay(s, opt, method, contacts, &copt, &mut mi, &mut warnings)?
    };
    finish(opt, m, warnings)
}

/// Option values the methods cannot work with.
fn check_options(opt: &Options) -> Result<(), LatencyError> {
    if !(opt.threshold > 0.0) {
        return Err(LatencyError::Options("the contact threshold must be positive".into()));
    }
    if let Some(KnownSize::SphereDiameter(d) | KnownSize::Gap(d)) = opt.known_size {
        if !(d > 0.0) {
            return Err(LatencyError::Options("the known artefact size must be positive".into()));
        }
    }
    Ok(())
}

/// The method asked for, or for [`Method::Auto`] the one the data allow: scan when there are no
/// contacts but a long deflected run, the artefact with a known size, speeds with two or more
/// speed groups, in-out when every contact approaches and retracts at the same speed.
fn choose_method(s: &Streams, opt: &Options, contacts: &[Contact]) -> Result<Method, LatencyError> {
    if opt.method != Method::Auto {
        return Ok(opt.method);
    }
    if contacts.is_empty() && scan::scan_samples(s, opt.threshold, 0.5).len() >= 50 {
        Ok(Method::Scan)
    } else if contacts.is_empty() {
        Err(no_contact(s, opt.threshold))
    } else if opt.known_size.is_some() {
        Ok(Method::Artefact)
    } else if touch::speed_groups(contacts).len() >= 2 {
        Ok(Method::Speeds)
    } else if contacts.iter().all(in_out_symmetric) {
        Ok(Method::Inout)
    } else {
        Err(LatencyError::Underdetermined(
            "all contacts are at one speed and no artefact size is given (--sphere-diameter-mm or --gap-mm), and their approach and retract speeds differ so in-out does not apply".into(),
        ))
    }
}

/// What one method measured, before the already-applied delay is added back.
struct Measured {
    /// Residual delay (s) and its standard uncertainty.
    delay: f64,
    u_delay: f64,
    rms: f64,
    n_contacts: usize,
    contacts: Vec<Contact>,
    evidence: Evidence,
}

/// The delay from touches (artefact, speeds or in-out), with warnings about deflection runs
/// that gave no point and contacts extrapolated on approach data.
fn touch_delay(
    s: &Streams,
    opt: &Options,
    method: Method,
    contacts: Vec<Contact>,
    copt: &contact::ContactOptions,
    mi: &mut Vec<[f64; 3]>,
    warnings: &mut Vec<String>,
) -> Result<Measured, LatencyError> {
    if contacts.is_empty() {
        return Err(no_contact(s, opt.threshold));
    }
    let runs = contact::find_runs(s.probe, opt.threshold, copt.min_band).len();
    if runs > contacts.len() {
        warnings.push(format!(
            "{} of {runs} deflection runs gave no surface point (stylus ringing after a contact, too few samples at constant speed, or a scan)",
            runs - contacts.len()
        ));
    }
    let approach = contacts.iter().filter(|c| c.phase == Phase::Approach).count();
    if approach > 0 {
        warnings.push(format!(
            "{approach} contact(s) without usable retract data: extrapolated on approach data"
        ));
    }
    let (r, contacts, feature, per_contact) = match method {
        Method::Inout => {
            let (r, each) = touch::inout(s, &contacts, opt.per_axis)?;
            (r, contacts, "", each)
        }
        Method::Artefact | Method::Speeds => {
            let (r, contacts, feature) = feature_fit_refined(s, opt, method, contacts, copt, mi)?;
            (r, contacts, feature, Vec::new())
        }
        Method::Scan | Method::Auto => (unreachable_method(), contacts, "", Vec::new()),
    };
    warnings.extend(r.warnings);
    let evidence = match method {
        Method::Artefact => {
            Evidence::Artefact { feature, size_mm: r.static_size.unwrap_or(f64::NAN), per_axis: r.per_axis }
        }
        Method::Speeds => Evidence::Speeds {
            feature,
            static_size_mm: r.static_size.unwrap_or(f64::NAN),
            u_static_size_mm: r.u_static_size.unwrap_or(f64::NAN),
            per_speed: r.per_speed,
            per_axis: r.per_axis,
        },
        _ => Evidence::Inout { per_contact, per_axis: r.per_axis },
    };
    Ok(Measured {
        delay: r.delay,
        u_delay: r.u_delay,
        rms: r.rms,
        n_contacts: contacts.len(),
        contacts,
        evidence,
    })
}

/// The artefact or speeds fit, then a second pass on the delay-corrected data.
///
/// The fits correct each point with its velocity at the zero-deflection instant, a
/// linearisation: where the servo is still settling as the tip leaves (fast retracts), the
/// velocity a whole delay away differs and the size-speed line bends (at 40 mm/s and +2.5 ms,
/// −1 µm on the size). So the machine stamps are moved by the delay found and the contacts
/// extracted and fitted again; what remains is a residual delay of microseconds, where the
/// linearisation is exact to nanometres. The first pass stands (with a warning) when the second
/// cannot be fitted.
fn feature_fit_refined(
    s: &Streams,
    opt: &Options,
    method: Method,
    contacts: Vec<Contact>,
    copt: &contact::ContactOptions,
    mi: &mut Vec<[f64; 3]>,
) -> Result<(touch::TouchResult, Vec<Contact>, &'static str), LatencyError> {
    let (r0, f0) = feature_fit(method, &contacts, opt)?;
    let shift = r0.delay;
    if !(shift.is_finite() && shift.abs() <= opt.max_delay) {
        return Ok((r0, contacts, f0));
    }
    let mt: Vec<f64> = s.machine_t.iter().map(|t| t - shift).collect();
    let s2 = Streams { machine_t: &mt, machine: s.machine, probe_t: s.probe_t, probe: s.probe };
    stream::machine_at(s2.machine_t, s2.machine, s2.probe_t, 0.0, mi);
    let contacts2 = contact::extract_contacts(&s2, mi, copt, 0.5);
    match feature_fit(method, &contacts2, opt) {
        Ok((mut r, f)) => {
            r.delay += shift;
            // The sizes as measured (no correction), as the size-speed plot shows.
            r.per_speed = r0.per_speed;
            if let Some(pa) = &mut r.per_axis {
                for d in pa.delay.iter_mut().flatten() {
                    *d += shift;
                }
            }
            Ok((r, contacts2, f))
        }
        Err(e) => {
            let mut r0 = r0;
            r0.warnings.push(format!(
                "the refit on the delay-corrected data failed ({e}); the delay is from the first pass, whose velocity correction is linearised"
            ));
            Ok((r0, contacts, f0))
        }
    }
}

/// The estimate: the already-applied delay added back, a finite result required, and a warning
/// when the delay is beyond the plausible range.
fn finish(opt: &Options, m: Measured, warnings: Vec<String>) -> Result<Estimate, LatencyError> {
    if !(m.u_delay.is_finite()) || !(m.delay.is_finite()) {
        return Err(LatencyError::Underdetermined("the fit gives no finite delay".into()));
    }
    let mut est = Estimate {
        delay: opt.already_corrected + m.delay,
        residual_delay: m.delay,
        u_delay: m.u_delay,
        n_contacts: m.n_contacts,
        rms: m.rms,
        warnings,
        contacts: m.contacts,
        evidence: m.evidence,
    };
    if let Some(pa) = est.per_axis_mut() {
        for d in pa.delay.iter_mut().flatten() {
            *d += opt.already_corrected;
        }
    }
    if est.residual_delay.abs() > opt.max_delay {
        // A capture delay is milliseconds; a result this large means the inputs disagree (most
        // often a size given for the artefact rather than for the stylus-centre surface).
        est.warnings.push(format!(
            "the delay {:.1} ms is beyond ±{:.0} ms, implausible for a capture delay: check the artefact size and --tip-radius-mm (sizes are of the stylus-centre surface unless a tip radius is given)",
            est.residual_delay * 1e3,
            opt.max_delay * 1e3
        ));
    }
    Ok(est)
}

/// The artefact or speeds method on a set of contacts: classify the feature, fit.
fn feature_fit(
    method: Method,
    contacts: &[Contact],
    opt: &Options,
) -> Result<(touch::TouchResult, &'static str), LatencyError> {
    let normals: Vec<_> = contacts.iter().map(|c| c.normal).collect();
    let feature = geom::Feature::classify(&normals)?;
    if method == Method::Artefact {
        let k = opt.known_size.ok_or_else(|| {
            LatencyError::Options("the artefact method needs --sphere-diameter-mm or --gap-mm".into())
        })?;
        let outer = geom::is_outer(feature, contacts)?;
        let size = stylus_centre_size(k, outer, opt.tip_radius);
        if !(size.abs() > 0.0) || size * if outer { 1.0 } else { -1.0 } <= 0.0 {
            return Err(LatencyError::Options("the tip radius is larger than the gap".into()));
        }
        let mut r = touch::artefact(feature, contacts, size, opt.per_axis)?;
        r.static_size = Some(artefact_size(size, opt.tip_radius));
        Ok((r, feature.name()))
    } else {
        // The deflection-domain points (see `Contact::point_defl`): the servo still settling as
        // the tip leaves biases the time-domain points by an amount that changes with the speed
        // (+3.7 µs on the virtual cell's gradient), which the deflection domain does not see.
        // A 2-u Hausman switch between the two still let it through in some seeds; the
        // time-domain points remain the fallback.
        let dd: Vec<Contact> = contacts
            .iter()
            .map(|c| Contact { point: c.point_defl, u_point: c.u_point_defl, ..c.clone() })
            .collect();
        let mut r = match touch::speeds(feature, &dd, opt.per_axis) {
            Ok(r) => r,
            Err(_) => touch::speeds(feature, contacts, opt.per_axis)?,
        };
        r.static_size = r.static_size.map(|v| artefact_size(v, opt.tip_radius));
        for p in &mut r.per_speed {
            p.1 = artefact_size(p.1, opt.tip_radius);
        }
        Ok((r, feature.name()))
    }
}

fn unreachable_method() -> touch::TouchResult {
    // Scan and Auto are resolved before the touch branch; keep a harmless value.
    touch::TouchResult { delay: f64::NAN, u_delay: f64::NAN, ..Default::default() }
}

fn no_contact(s: &Streams, threshold: f64) -> LatencyError {
    let max = s.probe.iter().map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()).fold(0.0f64, f64::max);
    LatencyError::NoContact(format!(
        "the largest deflection is {max:.6} mm, the threshold {threshold} mm (or no contact run has enough samples to extrapolate)"
    ))
}

/// Approach and retract along the normal at the same speed (within 5 %)?
fn in_out_symmetric(c: &Contact) -> bool {
    match (c.phase, c.approach_velocity) {
        (Phase::Retract, Some(va)) => {
            let (a, r) = (-va.dot(&c.normal), c.normal_speed());
            a > 0.0 && r > 0.0 && (a - r).abs() <= 0.05 * a.max(r)
        }
        _ => false,
    }
}

/// Stylus-centre positions `machine(t + delay) + deflection(t)` at every probe stamp; NaN where
/// the machine data does not cover `t + delay`. `out` is cleared and refilled.
pub fn apply(s: &Streams, delay: f64, out: &mut Vec<[f64; 3]>) {
    stream::machine_at(s.machine_t, s.machine, s.probe_t, delay, out);
    for (p, d) in out.iter_mut().zip(s.probe) {
        for k in 0..3 {
            p[k] += d[k];
        }
    }
}

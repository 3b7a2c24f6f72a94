//! The system delay through a controller, by the speeds method on a reference sphere: the same
//! sphere probed at several feeds through any [`ProbingMachine`] (the virtual machine tool,
//! LinuxCNC with G38.2, a CMM through I++ DME).
//!
//! A delay τ between the probe's trigger and the position the controller latches puts every
//! latched tip centre v·τ beyond the contact along the approach; the sphere probed from outside
//! then fits a radius smaller by v·τ: `R(v) = R₀ − v·τ`. The weighted straight-line fit of the
//! fitted radii against the feed gives τ (minus the slope) and R₀ (the static radius), with
//! standard uncertainties from the radii's own fit uncertainties (each sphere fit's covariance)
//! scaled by the line's residual scatter when that is larger (Birge ratio). A controller that
//! samples its probe input on a servo period T latches 0…T late, so τ ≈ T/2 there.
//!
//! What this measures is the delay of the latched positions the controller reports, i.e. what a
//! touch-trigger measurement through it suffers; the stream methods of this crate measure the
//! delay between two separately time-stamped streams.
//!
//! Entry point: [`delay_by_feeds`], returning a [`FeedDelay`] (a `Report`).

use serde_json::{json, Value};
use std::fmt::Write;
use truepos_device::ProbingMachine;
use truepos_head::acquire::{probe_sphere, AcquireError, ProbedSphere, SphereProbing};
use truepos_io::report::Report;

/// The sphere at one feed.
#[derive(Clone, Debug)]
pub struct AtFeed {
    /// Probing feed, mm/s.
    pub feed_mm_s: f64,
    /// The sphere fitted to the points probed at this feed.
    pub sphere: ProbedSphere,
}

/// The delay from the radius-feed line.
#[derive(Clone, Debug)]
pub struct FeedDelay {
    /// τ (s) and its standard uncertainty.
    pub delay_s: f64,
    /// Standard uncertainty of `delay_s`, s.
    pub u_delay_s: f64,
    /// R₀, the radius at zero feed (mm), and its standard uncertainty.
    pub static_radius_mm: f64,
    /// Standard uncertainty of `static_radius_mm`, mm.
    pub u_static_radius_mm: f64,
    /// The sphere fitted at each feed, in feed order.
    pub per_feed: Vec<AtFeed>,
    /// For the virtual machine: the delay it was built with (s).
    pub virtual_truth_s: Option<f64>,
}

impl Report for FeedDelay {
    fn to_json(&self) -> Value {
        json!({
            "method": "feeds",
            "delay_s": self.delay_s,
            "uncertainty_s": self.u_delay_s,
            "static_radius_mm": self.static_radius_mm,
            "static_radius_uncertainty_mm": self.u_static_radius_mm,
            "n_points": self.per_feed.iter().map(|f| f.sphere.points.len()).sum::<usize>(),
            "per_feed": self.per_feed.iter().map(|f| json!({
                "feed_mm_min": f.feed_mm_s * 60.0,
                "radius_mm": f.sphere.radius_mm,
                "radius_uncertainty_mm": f.sphere.radius_uncertainty_mm,
                "center_mm": <[f64; 3]>::from(f.sphere.center_mm.coords),
                "rms_mm": f.sphere.rms_mm,
            })).collect::<Vec<_>>(),
            "device": self.per_feed.first().map(|f| f.sphere.device.address.clone()),
            "virtual_truth_delay_s": self.virtual_truth_s,
        })
    }

    fn text(&self) -> String {
        let mut out = format!(
            "delay (feeds)  {:+.1} µs ± {:.1} µs (standard uncertainty)\nstatic radius  {:.6} mm ± {:.6} mm\n",
            self.delay_s * 1e6,
            self.u_delay_s * 1e6,
            self.static_radius_mm,
            self.u_static_radius_mm
        );
        let _ = writeln!(out, "{:>14} {:>12} {:>10}", "feed_mm_min", "radius_mm", "u_um");
        for f in &self.per_feed {
            let s = &f.sphere;
            let _ = writeln!(
                out,
                "{:14.1} {:12.6} {:10.3}",
                f.feed_mm_s * 60.0,
                s.radius_mm,
                s.radius_uncertainty_mm * 1e3
            );
        }
        if let Some(t) = self.virtual_truth_s {
            let _ = writeln!(out, "virtual machine: true latch delay {:+.1} µs", t * 1e6);
        }
        out
    }
}

/// Probe the sphere of `plan` once at each feed of `feeds_mm_s` (its own feed is ignored) and
/// fit the radius against the feed. At least two distinct feeds; the feeds and the plan are
/// checked before any motion.
pub fn delay_by_feeds<M: ProbingMachine + ?Sized>(
    m: &mut M,
    plan: &SphereProbing,
    feeds_mm_s: &[f64],
) -> Result<FeedDelay, AcquireError> {
    plan.check()?;
    if feeds_mm_s.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
        return Err(AcquireError::Plan("every feed must be a positive number".into()));
    }
    let lo = feeds_mm_s.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = feeds_mm_s.iter().copied().fold(0.0, f64::max);
    if feeds_mm_s.len() < 2 || !(hi > lo * 1.5) {
        return Err(AcquireError::Plan(
            "give at least two feeds, the highest at least 1.5 times the lowest (the delay is the slope of radius against feed)".into(),
        ));
    }
    let mut per_feed = Vec::with_capacity(feeds_mm_s.len());
    for &feed in feeds_mm_s {
        let sphere = probe_sphere(m, &SphereProbing { feed_mm_s: feed, ..*plan })?;
        per_feed.push(AtFeed { feed_mm_s: feed, sphere });
    }
    let (r0, slope, u_r0, u_slope) = weighted_line(&per_feed);
    Ok(FeedDelay {
        delay_s: -slope,
        u_delay_s: u_slope,
        static_radius_mm: r0,
        u_static_radius_mm: u_r0,
        per_feed,
        virtual_truth_s: None,
    })
}

/// Weighted least-squares line `R = a + b·v` through the radii (weights 1/u², a floor of 1 nm on
/// u so that a perfect fit does not get infinite weight): (a, b, u(a), u(b)), the uncertainties
/// scaled by the Birge ratio when the scatter exceeds the radii's own uncertainties.
fn weighted_line(per_feed: &[AtFeed]) -> (f64, f64, f64, f64) {
    let (mut sw, mut sv, mut sr, mut svv, mut svr) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for f in per_feed {
        let u = f.sphere.radius_uncertainty_mm.max(1e-6);
        let w = 1.0 / (u * u);
        let (v, r) = (f.feed_mm_s, f.sphere.radius_mm);
        sw += w;
        sv += w * v;
        sr += w * r;
        svv += w * v * v;
        svr += w * v * r;
    }
    let det = sw * svv - sv * sv;
    let b = (sw * svr - sv * sr) / det;
    let a = (sr - b * sv) / sw;
    let n = per_feed.len();
    let chi2: f64 = per_feed
        .iter()
        .map(|f| {
            let u = f.sphere.radius_uncertainty_mm.max(1e-6);
            ((f.sphere.radius_mm - a - b * f.feed_mm_s) / u).powi(2)
        })
        .sum();
    let birge = if n > 2 { (chi2 / (n - 2) as f64).sqrt().max(1.0) } else { 1.0 };
    (a, b, birge * (svv / det).sqrt(), birge * (sw / det).sqrt())
}

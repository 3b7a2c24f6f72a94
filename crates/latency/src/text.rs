//! The human-readable summary of an estimate, as `truepos latency` prints it (the JSON is
//! [`crate::json`]).
//!
//! Entry point: [`estimate`].

use crate::{Estimate, Options};
use std::fmt::Write;

/// One line into the text (writing to a `String` cannot fail).
macro_rules! w {
    ($($t:tt)*) => {{
        let _ = writeln!($($t)*);
    }};
}

/// The estimate for people: method, delay with its standard uncertainty, contacts, sizes,
/// per-axis delays with whether the axes differ, residual.
pub fn estimate(e: &Estimate, opt: &Options) -> String {
    let mut out = String::new();
    w!(out, "method        {}", e.method().name());
    w!(out, "delay         {:+.3} µs ± {:.3} µs (standard uncertainty)", e.delay * 1e6, e.u_delay * 1e6);
    if opt.already_corrected != 0.0 {
        w!(
            out,
            "residual      {:+.3} µs (data already corrected by {:+.3} µs)",
            e.residual_delay * 1e6,
            opt.already_corrected * 1e6
        );
    }
    w!(out, "contacts      {}", e.n_contacts);
    if let Some(s) = e.static_size() {
        w!(out, "static size   {s:.6} mm");
    }
    for (sp, sz) in e.per_speed() {
        w!(out, "  {sp:8.3} mm/s  size {sz:.6} mm");
    }
    if let Some(pa) = e.per_axis() {
        w!(out, "per axis      each axis's own delay, from its contacts on opposite sides (or at several speeds) along it:");
        for (k, name) in ["X", "Y", "Z"].iter().enumerate() {
            match (pa.delay[k], pa.u_delay[k]) {
                (Some(d), Some(u)) => {
                    w!(out, "delay {name}       {:+.3} µs ± {:.3} µs", d * 1e6, u * 1e6)
                }
                _ => w!(out,
                    "delay {name}       not determined: no opposite contacts (or speeds) along {name} in this data"
                ),
            }
        }
        match pa.largest_difference() {
            Some((diff, u)) if diff > crate::touch::AXES_DIFFER_K * u => w!(out,
                "note          the axes differ by up to {:.1} µs ({:.0} u): this machine's axes have different delays, so\n              correct each axis with its own delay. The single delay above is a compromise over the axes\n              and its distance from any one axis's delay is not an error of the method.",
                diff * 1e6,
                diff / u
            ),
            Some((diff, u)) => w!(out,
                "note          the axes agree within their uncertainties (largest difference {:.1} µs = {:.1} u,\n              below 3 u): one delay for all axes is enough.",
                diff * 1e6,
                diff / u
            ),
            None => w!(out, "note          fewer than two axes determined: the axes cannot be compared."),
        }
    }
    w!(out, "rms           {:.3} µm", e.rms * 1e3);
    out
}

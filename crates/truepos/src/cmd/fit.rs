//! `truepos fit <line|plane|circle|sphere|cylinder|cone> <points> [--json]`: geometric elements
//! by least squares (ISO 10360-6 / ASME B89.4.10) with standard and expanded uncertainties, or
//! by the Chebyshev criteria of ISO form (minimum zone, maximum inscribed, minimum
//! circumscribed); form; verdicts against size and form tolerances (simple or ISO 14253-1
//! guarded rule); QIF 3.0 export and tolerances read from a QIF plan.
//!
//! Points come from a CSV (`x_mm,y_mm,z_mm`, any other columns ignored) or a NIST `.ds` file.
//! Degenerate data (too few points, coincident, collinear, coplanar, a cone that is a cylinder,
//! flat data for a cylinder, an open arc for an inscribed element) is an input error naming the
//! file (exit 2). The work is `truepos_fit::evaluate::evaluate`; this module parses options,
//! prints, and writes the QIF file (`truepos_qif`).
//!
//! Entry point: [`run`]. The demo's NIST section (every NIST reference data set against its
//! certified fit) and its table are `demo_section` and `nist_table` of the cell's `nist`
//! scenario.

use crate::output::print_json;
use crate::{ClassExt, Classed, Outcome, UsageError};
use anyhow::Result;
use std::path::PathBuf;
use truepos_fit::evaluate::{self, Kind, Method, Spec};
use truepos_fit::verdict::{self, DecisionRule, SizeTolerance, Verdict};
use truepos_io::InputError;
use truepos_math::exit::ExitClass;

#[derive(clap::Args, Debug)]
#[command(after_help = "\
Points: CSV with columns x_mm,y_mm,z_mm (any order, other columns ignored) or a NIST .ds file.\n\
Least-squares fits are Gaussian (orthogonal distance). A 3D circle is the least-squares plane,\n\
then the circle of the points projected into it (for every method). form_mm is the largest minus\n\
the smallest orthogonal residual about the reported feature (a line: the diameter of the\n\
cylinder about it holding every point). Uncertainties (ls only) are standard uncertainties from\n\
σ̂²(JᵀJ)⁻¹, σ̂² = SSR/(n − p) (noise only, no systematic effects); expanded with k = 2.\n\
Verdicts: size deviation = measured diameter − nominal; guard band (guarded rule) = the\n\
least-squares expanded uncertainty of the diameter, for every method (where it is not\n\
determined, as many points as parameters, a guarded decision is undecided); form uses the\n\
simple rule. Exit code 1 when the verdict is not pass.\n\
--qif-plan reads the nominal diameter with its tolerance (deviations or limits) and the kind's\n\
form tolerance (straightness, flatness, circularity, sphericity, cylindricity, conicity) from a\n\
QIF 3 plan or model; it does not read feature nominals, datums, position or profile\n\
tolerances, limits-and-fits codes, or files with several diameter characteristics.")]
pub struct Args {
    /// Geometric element to fit.
    #[arg(value_enum)]
    pub kind: Kind,
    /// Point file (.csv or .ds).
    pub points: PathBuf,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Association criterion.
    #[arg(long, value_enum, default_value = "ls")]
    pub method: Method,
    /// Nominal diameter, mm (circle, sphere, cylinder; needs --tolerance-mm).
    #[arg(long, value_parser = crate::output::positive, value_name = "D", allow_hyphen_values = true)]
    pub nominal_diameter_mm: Option<f64>,
    /// Size tolerance, mm: T for ±T, or LOWER,UPPER signed deviations from the nominal
    /// (e.g. --tolerance-mm=-0.001,0.006).
    #[arg(long, value_name = "T|LOWER,UPPER", allow_hyphen_values = true)]
    pub tolerance_mm: Option<String>,
    /// Form tolerance (zone width), mm.
    #[arg(long, value_parser = crate::output::positive, value_name = "F", allow_hyphen_values = true)]
    pub form_tolerance_mm: Option<f64>,
    /// Decision rule for the size verdict.
    #[arg(long, value_enum, default_value = "simple")]
    pub decision_rule: DecisionRule,
    /// Write the result as a QIF 3.0 document.
    #[arg(long, value_name = "OUT.qif")]
    pub qif: Option<PathBuf>,
    /// Read the nominal diameter, its tolerance and the form tolerance from a QIF plan/model.
    #[arg(long, value_name = "PLAN.qif", conflicts_with_all = ["nominal_diameter_mm", "tolerance_mm", "form_tolerance_mm"])]
    pub qif_plan: Option<PathBuf>,
}

/// The tolerance specification from the options (or the QIF plan).
fn spec(a: &Args) -> Result<Spec> {
    let rule = a.decision_rule;
    if let Some(plan_path) = &a.qif_plan {
        let text = truepos_io::xml::read_xml(plan_path, "QIF plan")?;
        let in_plan = |e: String| InputError::in_file(plan_path, e);
        let plan = truepos_qif::read_plan(&text, a.kind).map_err(|e| in_plan(e.to_string()))?;
        let (spec, notes) = truepos_qif::plan_spec(&plan, a.kind, rule).map_err(in_plan)?;
        for n in notes {
            eprintln!("note: {}: {n}", plan_path.display());
        }
        return Ok(spec);
    }
    let size = match (a.nominal_diameter_mm, &a.tolerance_mm) {
        (Some(n), Some(t)) => Some(SizeTolerance::parse(t, n).map_err(|e| match e {
            verdict::ToleranceError::BadNominal(_) => {
                Classed::new(ExitClass::Usage, Some("--nominal-diameter-mm".into()), e)
            }
            e => Classed::new(ExitClass::Usage, Some(format!("--tolerance-mm {t}")), e),
        })?),
        (Some(_), None) => return Err(UsageError("--nominal-diameter-mm needs --tolerance-mm".into()).into()),
        (None, Some(_)) => return Err(UsageError("--tolerance-mm needs --nominal-diameter-mm".into()).into()),
        (None, None) => None,
    };
    let form_tolerance =
        a.form_tolerance_mm.map(verdict::check_form_tolerance).transpose().usage_in("--form-tolerance-mm")?;
    Ok(Spec { size, form_tolerance, rule })
}

pub fn run(a: Args) -> Result<Outcome> {
    // Everything that can be refused is refused before any work or output.
    let spec = spec(&a)?;
    let m = a.method;
    evaluate::check(a.kind, m, &spec).usage()?;
    if let Some(q) = &a.qif {
        truepos_io::atomic::check_output_path(q).map_err(|e| anyhow::Error::from(e).context("--qif"))?;
    }
    let set = truepos_io::points::read_points(&a.points)?;
    if set.skipped_invalid > 0 {
        eprintln!(
            "note: {}: {} points marked invalid in the file were skipped",
            a.points.display(),
            set.skipped_invalid
        );
    }
    if set.skipped_nonfinite > 0 {
        eprintln!(
            "note: {}: {} points with a NaN or infinite coordinate were skipped",
            a.points.display(),
            set.skipped_nonfinite
        );
    }
    let e = evaluate::evaluate(a.kind, m, &set.points, &spec).map_err(|e| match e {
        evaluate::EvaluateError::Spec(s) => anyhow::Error::from(Classed::new(ExitClass::Usage, None, s)),
        evaluate::EvaluateError::Fit(f) => {
            InputError::in_file(&a.points, format!("cannot fit a {}: {f}", a.kind.name())).into()
        }
    })?;
    let v = truepos_fit::json::evaluation(&e);
    if let Some(q) = &a.qif {
        let name = a.points.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let r =
            truepos_qif::results_from_evaluation(&e, &name, concat!("truepos ", env!("CARGO_PKG_VERSION")));
        let xml = truepos_qif::write_results(&r).map_err(|e| InputError::in_file(q, e.to_string()))?;
        truepos_io::atomic::write_atomic(q, xml.as_bytes())
            .map_err(|err| InputError::in_file(q, format!("cannot write the QIF file: {err}")))?;
    }
    let outcome = match e.verdict {
        None | Some(Verdict::Pass) => Outcome::Done,
        Some(_) => Outcome::OutOfTolerance,
    };
    if a.json {
        print_json(&v)?;
        return Ok(outcome);
    }
    println!(
        "{} fit ({}) of {} points from {}",
        a.kind.name(),
        m.name(),
        set.points.len(),
        a.points.display()
    );
    print!("{}", truepos_fit::json::text(&v));
    if let Some(q) = &a.qif {
        eprintln!("QIF written to {}", q.display());
    }
    Ok(outcome)
}

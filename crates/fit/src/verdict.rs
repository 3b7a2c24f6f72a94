//! Conformance decisions for a fitted feature: size (diameter against a nominal with a
//! symmetric or asymmetric tolerance) and form (zone width against a form tolerance), under the
//! simple rule or the guarded rule of ISO 14253-1.
//!
//! - `simple`: conformance when the value lies in the tolerance zone, limits included.
//! - `guarded` (ISO 14253-1): conformance only when the value lies in the zone shrunk by the
//!   expanded uncertainty `U` on both sides; non-conformance only when it lies outside the zone
//!   widened by `U`; otherwise undecided. A zone narrower than `2U` cannot prove conformance.
//!
//! Form verdicts use the simple rule (the form value is a zone width whose uncertainty is not
//! a symmetric quantity about it). Several characteristics combine as: fail if any fails, else
//! undecided if any is, else pass.
//!
//! Entry points: [`SizeTolerance`], [`size_verdict`], [`form_verdict`], [`combine`].

use thiserror::Error;

/// Decision rule for conformance (`truepos fit --decision-rule`; the variants' documentation is
/// the command line's help for each value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DecisionRule {
    /// Conformance inside the tolerance zone, limits included.
    Simple,
    /// ISO 14253-1: conformance only inside the zone shrunk by U, non-conformance only outside
    /// the zone widened by U, else undecided.
    Guarded,
}

impl DecisionRule {
    /// The CLI's and JSON's name of the rule (`simple`, `guarded`).
    pub fn name(self) -> &'static str {
        match self {
            DecisionRule::Simple => "simple",
            DecisionRule::Guarded => "guarded",
        }
    }
}

/// The outcome of a conformance decision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    /// Conforms (inside the zone, shrunk by the guard band under the guarded rule).
    Pass,
    /// Neither conformance nor non-conformance is proven (inside the guard band).
    Undecided,
    /// Does not conform (outside the zone, widened by the guard band under the guarded rule).
    Fail,
}

impl Verdict {
    /// The lower-case name the CLI, JSON and reports use (`pass`, `fail`, `undecided`).
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Undecided => "undecided",
        }
    }
}

/// Why a tolerance specification is not usable.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ToleranceError {
    /// The lower deviation is above the upper one (both mm).
    #[error("the lower deviation {lower} mm is above the upper deviation {upper} mm")]
    LowerAboveUpper {
        /// The lower deviation, mm.
        lower: f64,
        /// The upper deviation, mm.
        upper: f64,
    },
    /// A negative symmetric tolerance ±T (T in mm).
    #[error("a symmetric tolerance must not be negative (±{0} mm given)")]
    NegativeSymmetric(f64),
    /// A nominal diameter that is not finite and positive (mm).
    #[error("the nominal diameter must be finite and positive ({0} mm given)")]
    BadNominal(f64),
    /// A form tolerance that is negative or not finite (mm).
    #[error("the form tolerance must be finite and not negative ({0} mm given)")]
    NegativeForm(f64),
    /// A tolerance value is NaN or infinite.
    #[error("a tolerance value is not a finite number")]
    NotFinite,
    /// The text is not a number (the text given).
    #[error("'{0}' is not a finite number")]
    NotANumber(String),
    /// The text is neither `T` nor `LOWER,UPPER`.
    #[error("expected T or LOWER,UPPER")]
    Syntax,
}

/// A size tolerance: nominal diameter and the signed limit deviations from it, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizeTolerance {
    /// Nominal diameter, mm.
    pub nominal: f64,
    /// Lower limit deviation from the nominal (signed), mm.
    pub lower: f64,
    /// Upper limit deviation from the nominal (signed), mm.
    pub upper: f64,
}

impl SizeTolerance {
    /// A tolerance as written on a command line or in a plan: `T` (±T) or `LOWER,UPPER` (signed
    /// deviations from `nominal`, mm).
    pub fn parse(text: &str, nominal: f64) -> Result<Self, ToleranceError> {
        let num = |t: &str| -> Result<f64, ToleranceError> {
            match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(ToleranceError::NotANumber(t.trim().to_string())),
            }
        };
        match text.split(',').collect::<Vec<_>>().as_slice() {
            [t] => Self::symmetric(nominal, num(t)?),
            [lo, hi] => Self::new(nominal, num(lo)?, num(hi)?),
            _ => Err(ToleranceError::Syntax),
        }
    }

    /// Nominal with asymmetric limit deviations (`lower ≤ upper`, either may be negative).
    pub fn new(nominal: f64, lower: f64, upper: f64) -> Result<Self, ToleranceError> {
        if !(nominal.is_finite() && nominal > 0.0) {
            return Err(ToleranceError::BadNominal(nominal));
        }
        if !(lower.is_finite() && upper.is_finite()) {
            return Err(ToleranceError::NotFinite);
        }
        if lower > upper {
            return Err(ToleranceError::LowerAboveUpper { lower, upper });
        }
        Ok(SizeTolerance { nominal, lower, upper })
    }
    /// Nominal ± `t`.
    pub fn symmetric(nominal: f64, t: f64) -> Result<Self, ToleranceError> {
        if !t.is_finite() {
            return Err(ToleranceError::NotFinite);
        }
        if t < 0.0 {
            return Err(ToleranceError::NegativeSymmetric(t));
        }
        Self::new(nominal, -t, t)
    }
    /// Lower and upper limit of size, mm.
    pub fn limits(&self) -> (f64, f64) {
        (self.nominal + self.lower, self.nominal + self.upper)
    }
}

/// Check a form tolerance value (finite, ≥ 0).
pub fn check_form_tolerance(f: f64) -> Result<f64, ToleranceError> {
    if !f.is_finite() || f < 0.0 {
        return Err(ToleranceError::NegativeForm(f));
    }
    Ok(f)
}

/// A size decision with what it was based on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizeDecision {
    /// The tolerance decided against.
    pub tolerance: SizeTolerance,
    /// Measured diameter minus nominal, mm.
    pub deviation: f64,
    /// Guard band (the expanded uncertainty of the diameter) applied, mm; 0 under `simple`;
    /// NaN under `guarded` when the uncertainty is not determined (the verdict is then
    /// undecided).
    pub guard_band: f64,
    /// The decision rule applied.
    pub rule: DecisionRule,
    /// The outcome.
    pub verdict: Verdict,
}

/// Decide on a measured diameter with expanded uncertainty `u_expanded` (of the diameter).
pub fn size_verdict(tol: &SizeTolerance, diameter: f64, u_expanded: f64, rule: DecisionRule) -> SizeDecision {
    let dev = diameter - tol.nominal;
    // "On a limit" allows for the rounding of `diameter − nominal` (a few ulps of the
    // diameter: 1e-12 relative is 2e-11 mm at 20 mm, far below any measurement).
    let eps = 1e-12 * diameter.abs().max(1.0);
    let (verdict, guard_band) = match rule {
        DecisionRule::Simple => (
            if dev >= tol.lower - eps && dev <= tol.upper + eps { Verdict::Pass } else { Verdict::Fail },
            0.0,
        ),
        DecisionRule::Guarded => {
            let u = u_expanded.abs();
            let v = if !dev.is_finite() || !u.is_finite() {
                Verdict::Undecided
            } else if dev >= tol.lower + u - eps && dev <= tol.upper - u + eps {
                Verdict::Pass
            } else if dev < tol.lower - u - eps || dev > tol.upper + u + eps {
                Verdict::Fail
            } else {
                Verdict::Undecided
            };
            (v, u)
        }
    };
    SizeDecision { tolerance: *tol, deviation: dev, guard_band, rule, verdict }
}

/// Form verdict (simple rule): conformance when `form ≤ tolerance`.
pub fn form_verdict(form: f64, tolerance: f64) -> Verdict {
    if form <= tolerance {
        Verdict::Pass
    } else {
        Verdict::Fail
    }
}

/// Several characteristics: fail if any fails, else undecided if any is, else pass. `None`
/// for no characteristic.
pub fn combine(v: &[Verdict]) -> Option<Verdict> {
    v.iter().copied().max()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simple_and_guarded_rules() {
        let t = SizeTolerance::new(20.0, -0.001, 0.006).unwrap();
        let d = |dia: f64, u: f64, r| size_verdict(&t, dia, u, r).verdict;
        // On a limit: conforms under the simple rule.
        assert_eq!(d(20.006, 0.0, DecisionRule::Simple), Verdict::Pass);
        assert_eq!(d(19.999, 0.0, DecisionRule::Simple), Verdict::Pass);
        assert_eq!(d(20.0061, 0.0, DecisionRule::Simple), Verdict::Fail);
        // Guarded with U = 0.001: pass in [19.9990+0.001, 20.006−0.001].
        assert_eq!(d(20.003, 0.001, DecisionRule::Guarded), Verdict::Pass);
        assert_eq!(d(20.0055, 0.001, DecisionRule::Guarded), Verdict::Undecided);
        assert_eq!(d(20.0065, 0.001, DecisionRule::Guarded), Verdict::Undecided);
        assert_eq!(d(20.0075, 0.001, DecisionRule::Guarded), Verdict::Fail);
        assert_eq!(d(19.9975, 0.001, DecisionRule::Guarded), Verdict::Fail);
        // A zone narrower than 2U never proves conformance.
        assert_eq!(d(20.0025, 0.004, DecisionRule::Guarded), Verdict::Undecided);
        assert_eq!(combine(&[Verdict::Pass, Verdict::Undecided]), Some(Verdict::Undecided));
        assert_eq!(combine(&[Verdict::Undecided, Verdict::Fail, Verdict::Pass]), Some(Verdict::Fail));
        assert_eq!(combine(&[]), None);
        assert_eq!(form_verdict(0.01, 0.01), Verdict::Pass);
    }

    #[test]
    fn bad_tolerances_are_refused() {
        assert!(matches!(SizeTolerance::new(20.0, 0.01, -0.01), Err(ToleranceError::LowerAboveUpper { .. })));
        assert!(SizeTolerance::symmetric(20.0, -0.01).is_err());
        assert!(SizeTolerance::symmetric(-20.0, 0.01).is_err());
        assert!(check_form_tolerance(-0.001).is_err());
        assert!(check_form_tolerance(f64::NAN).is_err());
    }

    #[test]
    fn tolerance_text_parses_symmetric_and_asymmetric_and_refuses_junk() {
        let t = SizeTolerance::parse("0.01", 20.0).unwrap();
        assert_eq!((t.nominal, t.lower, t.upper), (20.0, -0.01, 0.01));
        let t = SizeTolerance::parse("-0.001, 0.006", 20.0).unwrap();
        assert_eq!((t.lower, t.upper), (-0.001, 0.006));
        assert!(matches!(SizeTolerance::parse("a", 20.0), Err(ToleranceError::NotANumber(s)) if s == "a"));
        assert!(matches!(SizeTolerance::parse("1,2,3", 20.0), Err(ToleranceError::Syntax)));
        assert!(matches!(SizeTolerance::parse("inf", 20.0), Err(ToleranceError::NotANumber(_))));
        assert!(matches!(SizeTolerance::parse("0.01", -1.0), Err(ToleranceError::BadNominal(_))));
    }
}

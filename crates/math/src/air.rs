//! Refractive index of air, by the Ciddor equation and the modified Edlén equation, exactly as
//! NIST's "Refractive Index of Air Calculator" (J. A. Stone and J. H. Zimmerman, Engineering
//! Metrology Toolbox) documents them in its Appendix A: saturation vapour pressure over water
//! (IAPWS 1997) or ice (IAPWS 2008), the enhancement factor, the mole fraction of water vapour,
//! the BIPM compressibility, Ciddor's dispersion and density terms with the gas constant
//! R = 8.314472 J/(mol·K), and the Birch & Downs Edlén equation with NIST's modified water-vapour
//! term. A laser tracker or interferometer measures `distance = optical path / n`.
//!
//! Entry points: [`refractive_index`], [`AirConditions`], [`Formula`], [`validity_range`],
//! [`saturation_vapour_pressure_pa`].
//!
//! Outside the range where NIST states the equations' uncertainty (section VI of the calculator's
//! documentation) the result is refused, naming the quantity and the range: an index computed
//! there is a number nobody can vouch for.

use thiserror::Error;

/// Ambient conditions: °C, Pa, % relative humidity, CO2 mole fraction in ppm (µmol/mol), vacuum
/// wavelength in nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirConditions {
    /// Air temperature, °C.
    pub temperature_c: f64,
    /// Total air pressure, Pa.
    pub pressure_pa: f64,
    /// Relative humidity, % (0 to 100).
    pub humidity_pct: f64,
    /// CO2 mole fraction, ppm (µmol/mol).
    pub co2_ppm: f64,
    /// Vacuum wavelength of the light, nm.
    pub wavelength_nm: f64,
}

impl Default for AirConditions {
    /// 20 °C, 101 325 Pa, 50 % RH, 450 ppm CO2, 633 nm (HeNe).
    fn default() -> Self {
        Self {
            temperature_c: 20.0,
            pressure_pa: 101_325.0,
            humidity_pct: 50.0,
            co2_ppm: 450.0,
            wavelength_nm: 633.0,
        }
    }
}

/// Which equation [`refractive_index`] evaluates (`truepos somac air --formula`, whose help
/// describes the values in the option's own text, so their `clap` help is empty).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Formula {
    /// Ciddor (1996), valid for any CO2 content in its range.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Ciddor,
    /// Modified Edlén (Birch & Downs with NIST's water-vapour term). CO2 fixed at 450 ppm.
    #[cfg_attr(feature = "clap", value(help = None::<&str>))]
    Edlen,
}

/// Why [`refractive_index`] refuses a set of conditions.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum AirError {
    /// The named input is NaN or infinite.
    #[error("{0} must be a finite number")]
    NotFinite(&'static str),
    /// Relative humidity outside 0 to 100 % (the value given).
    #[error("relative humidity must be between 0 and 100 %, got {0}")]
    Humidity(f64),
    /// Pressure not positive (the value given, Pa), with the chosen equation's range.
    #[error(
        "pressure {value} Pa is not positive, and outside the range of the {formula} equation ({lo} to {hi} Pa, \
         as NIST states it)"
    )]
    Pressure {
        /// The pressure given (Pa).
        value: f64,
        /// Lower end of the equation's range (Pa).
        lo: f64,
        /// Upper end of the equation's range (Pa).
        hi: f64,
        /// The equation's name.
        formula: &'static str,
    },
    /// Wavelength not positive (the value given, nm).
    #[error("wavelength must be positive, got {0} nm")]
    Wavelength(f64),
    /// CO2 mole fraction outside 0 to 1e6 ppm (the value given).
    #[error("CO2 mole fraction must be between 0 and 1e6 ppm, got {0}")]
    Co2(f64),
    /// Temperature at or below absolute zero (the value given, °C), with the equation's range.
    #[error(
        "temperature {value} °C is below absolute zero (-273.15 °C), and outside the range of the {formula} \
         equation ({lo} to {hi} °C, as NIST states it)"
    )]
    Temperature {
        /// The temperature given (°C).
        value: f64,
        /// Lower end of the equation's range (°C).
        lo: f64,
        /// Upper end of the equation's range (°C).
        hi: f64,
        /// The equation's name.
        formula: &'static str,
    },
    /// An input outside the range where NIST states the chosen equation valid.
    #[error(
        "{quantity} {value} {unit} is outside the range of the {formula} equation ({lo} to {hi} {unit}, \
         as NIST states it)"
    )]
    OutOfRange {
        /// The input (`temperature`, `pressure`, ...).
        quantity: &'static str,
        /// Its value, in `unit`.
        value: f64,
        /// Its unit (`°C`, `Pa`, `%`, `ppm`, `nm`).
        unit: &'static str,
        /// The low end of the valid range, in `unit`.
        lo: f64,
        /// The high end of the valid range, in `unit`.
        hi: f64,
        /// The equation's name.
        formula: &'static str,
    },
    /// The modified Edlén equation asked for with a CO2 content other than 450 ppm (the value given).
    #[error("the modified Edlén equation is for 450 ppm CO2 only (got {0} ppm); use the Ciddor equation")]
    EdlenCo2(f64),
}

/// The range of one input where an equation is valid: (quantity, unit, low, high).
pub type Range = (&'static str, &'static str, f64, f64);

/// Where NIST states each equation valid (Stone & Zimmerman, section VI): Ciddor 300–1700 nm,
/// −40–100 °C, 10–140 kPa, 0–100 % RH, 0–2000 µmol/mol CO2; modified Edlén 300–1700 nm,
/// 0–40 °C, 60–140 kPa, 0–100 % RH, CO2 fixed at 450 µmol/mol.
pub fn validity_range(formula: Formula) -> [Range; 5] {
    let (lo_t, hi_t, lo_p, hi_co2) = match formula {
        Formula::Ciddor => (-40.0, 100.0, 10_000.0, 2000.0),
        Formula::Edlen => (0.0, 40.0, 60_000.0, 450.0),
    };
    [
        ("wavelength", "nm", 300.0, 1700.0),
        ("temperature", "°C", lo_t, hi_t),
        ("pressure", "Pa", lo_p, 140_000.0),
        ("humidity", "%", 0.0, 100.0),
        ("CO2", "ppm", if formula == Formula::Edlen { 450.0 } else { 0.0 }, hi_co2),
    ]
}

/// Saturation vapour pressure (Pa): over water for t ≥ 0 °C (IAPWS 1997), over ice below.
pub fn saturation_vapour_pressure_pa(t_c: f64) -> f64 {
    if t_c >= 0.0 {
        const K: [f64; 10] = [
            1.16705214528e3,
            -7.24213167032e5,
            -1.70738469401e1,
            1.20208247025e4,
            -3.23255503223e6,
            1.49151086135e1,
            -4.82326573616e3,
            4.05113405421e5,
            -2.38555575678e-1,
            6.50175348448e2,
        ];
        let t = t_c + 273.15;
        let om = t + K[8] / (t - K[9]);
        let a = om * om + K[0] * om + K[1];
        let b = K[2] * om * om + K[3] * om + K[4];
        let c = K[5] * om * om + K[6] * om + K[7];
        let x = -b + (b * b - 4.0 * a * c).sqrt();
        1e6 * (2.0 * c / x).powi(4)
    } else {
        let theta = (t_c + 273.15) / 273.16;
        let y = -13.928169 * (1.0 - theta.powf(-1.5)) + 34.7078238 * (1.0 - theta.powf(-1.25));
        611.657 * y.exp()
    }
}

/// Partial pressure of water vapour (Pa) from relative humidity.
pub fn vapour_pressure_pa(humidity_pct: f64, t_c: f64) -> f64 {
    humidity_pct / 100.0 * saturation_vapour_pressure_pa(t_c)
}

/// Mole fraction of water vapour, with the enhancement factor f = α + β·p + γ·t².
pub fn vapour_mole_fraction(humidity_pct: f64, p_pa: f64, t_c: f64) -> f64 {
    let f = 1.00062 + 3.14e-8 * p_pa + 5.6e-7 * t_c * t_c;
    f * vapour_pressure_pa(humidity_pct, t_c) / p_pa
}

/// The name of an equation in messages.
fn formula_name(formula: Formula) -> &'static str {
    match formula {
        Formula::Ciddor => "Ciddor",
        Formula::Edlen => "modified Edlén",
    }
}

/// Physically impossible inputs; the temperature and pressure messages state the equation's
/// validity range too (the range a user has to stay in, not only the physical bound).
fn check(c: &AirConditions, formula: Formula) -> Result<(), AirError> {
    let range = |q: &str| {
        let (_, _, lo, hi) =
            validity_range(formula).into_iter().find(|r| r.0 == q).unwrap_or(("", "", 0.0, 0.0));
        (lo, hi)
    };
    for (v, name) in [
        (c.temperature_c, "temperature"),
        (c.pressure_pa, "pressure"),
        (c.humidity_pct, "humidity"),
        (c.co2_ppm, "CO2"),
        (c.wavelength_nm, "wavelength"),
    ] {
        if !v.is_finite() {
            return Err(AirError::NotFinite(name));
        }
    }
    if !(0.0..=100.0).contains(&c.humidity_pct) {
        return Err(AirError::Humidity(c.humidity_pct));
    }
    if c.pressure_pa <= 0.0 {
        let (lo, hi) = range("pressure");
        return Err(AirError::Pressure { value: c.pressure_pa, lo, hi, formula: formula_name(formula) });
    }
    if c.wavelength_nm <= 0.0 {
        return Err(AirError::Wavelength(c.wavelength_nm));
    }
    if !(0.0..=1e6).contains(&c.co2_ppm) {
        return Err(AirError::Co2(c.co2_ppm));
    }
    if c.temperature_c <= -273.15 {
        let (lo, hi) = range("temperature");
        return Err(AirError::Temperature { value: c.temperature_c, lo, hi, formula: formula_name(formula) });
    }
    Ok(())
}

/// The refractive index of air (phase index) for the given conditions; conditions outside the
/// equation's validity range ([`validity_range`]) are an error naming the quantity and the range.
pub fn refractive_index(c: &AirConditions, formula: Formula) -> Result<f64, AirError> {
    check(c, formula)?;
    let name = formula_name(formula);
    let values = [c.wavelength_nm, c.temperature_c, c.pressure_pa, c.humidity_pct, c.co2_ppm];
    for ((quantity, unit, lo, hi), value) in validity_range(formula).into_iter().zip(values) {
        if formula == Formula::Edlen && quantity == "CO2" {
            if (value - 450.0).abs() > 1e-9 {
                return Err(AirError::EdlenCo2(value));
            }
            continue;
        }
        if !(lo..=hi).contains(&value) {
            return Err(AirError::OutOfRange { quantity, value, unit, lo, hi, formula: name });
        }
    }
    Ok(match formula {
        Formula::Ciddor => ciddor(c),
        Formula::Edlen => edlen(c),
    })
}

fn ciddor(c: &AirConditions) -> f64 {
    let (t, p, xc) = (c.temperature_c, c.pressure_pa, c.co2_ppm);
    let xv = vapour_mole_fraction(c.humidity_pct, p, t);
    let s = 1.0 / (c.wavelength_nm * 1e-3).powi(2);
    let ras = 1e-8 * (5_792_105.0 / (238.0185 - s) + 167_917.0 / (57.362 - s));
    let rvs = 1.022e-8 * (295.235 + 2.6422 * s - 0.032380 * s * s + 0.004028 * s * s * s);
    let ma = 0.0289635 + 1.2011e-8 * (xc - 400.0);
    let raxs = ras * (1.0 + 5.34e-7 * (xc - 450.0));
    let tk = t + 273.15;
    let pt = p / tk;
    let zm = 1.0
        - pt * (1.58123e-6 - 2.9331e-8 * t
            + 1.1043e-10 * t * t
            + (5.707e-6 - 2.051e-8 * t) * xv
            + (1.9898e-4 - 2.376e-6 * t) * xv * xv)
        + pt * pt * (1.83e-11 - 0.765e-8 * xv * xv);
    const R: f64 = 8.314472;
    const MV: f64 = 0.018015;
    let rho_axs = 101_325.0 * ma / (0.9995922115 * R * 288.15);
    let rho_v = xv * p * MV / (zm * R * tk);
    let rho_a = (1.0 - xv) * p * ma / (zm * R * tk);
    const RHO_VS: f64 = 0.00985938;
    1.0 + (rho_a / rho_axs) * raxs + (rho_v / RHO_VS) * rvs
}

fn edlen(c: &AirConditions) -> f64 {
    let (t, p) = (c.temperature_c, c.pressure_pa);
    let pv = vapour_pressure_pa(c.humidity_pct, t);
    let s = 1.0 / (c.wavelength_nm * 1e-3).powi(2);
    let ns = 1.0 + 1e-8 * (8342.54 + 2_406_147.0 / (130.0 - s) + 15998.0 / (38.9 - s));
    let x = (1.0 + 1e-8 * (0.601 - 0.00972 * t) * p) / (1.0 + 0.003661 * t);
    let ntp = 1.0 + p * (ns - 1.0) * x / 96095.43;
    ntp - 1e-10 * (292.75 / (t + 273.15)) * (3.7345 - 0.0401 * s) * pv
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64, p: f64, rh: f64, wl: f64) -> AirConditions {
        AirConditions {
            temperature_c: t,
            pressure_pa: p,
            humidity_pct: rh,
            co2_ppm: 450.0,
            wavelength_nm: wl,
        }
    }

    /// Values printed by NIST's online calculator (Ciddor, 20 °C, 101 325 Pa, 50 % RH,
    /// 450 ppm), as quoted to 9 decimals in the test suite of the `ref_index` package
    /// (P. H. Nair). Printed to 1e-9, so agreement is checked to half a unit of the last digit.
    #[test]
    fn ciddor_matches_nist_calculator_output() {
        let wl = [321.456, 500.0, 600.1234, 633.0, 700.0, 1000.987, 1500.8, 1700.0];
        let nist = [
            1.000283543,
            1.000273781,
            1.000271818,
            1.000271373,
            1.000270657,
            1.000269038,
            1.00026819,
            1.000268041,
        ];
        for (w, n) in wl.iter().zip(nist) {
            let v = refractive_index(&at(20.0, 101_325.0, 50.0, *w), Formula::Ciddor).unwrap();
            assert!((v - n).abs() <= 5e-10, "λ {w}: {v} vs NIST {n}");
        }
    }

    /// Published values of the NIST equations (the `ref_index` documentation, 16 digits),
    /// reproduced to 1e-11.
    #[test]
    #[allow(clippy::excessive_precision)] // the published values, as printed
    fn reproduces_published_values_of_the_nist_equations() {
        let cases = [
            (Formula::Ciddor, 20.0, 20.0, 1.0002716285340578),
            (Formula::Edlen, 20.0, 20.0, 1.0002716291691649),
            (Formula::Edlen, 20.0, 80.0, 1.0002711197635226),
            (Formula::Ciddor, 20.0, 80.0, 1.0002711183472626),
            (Formula::Edlen, 60.0, 80.0, 1.0002339748542823),
            (Formula::Ciddor, 60.0, 80.0, 1.0002340241754055),
        ];
        for (f, t, rh, n) in cases {
            // 60 °C is outside the range NIST states for the Edlén equation, which the public
            // function refuses; the equation itself is checked here.
            let c = at(t, 101_325.0, rh, 633.0);
            let v = match f {
                Formula::Ciddor => refractive_index(&c, f).unwrap(),
                Formula::Edlen => edlen(&c),
            };
            assert!((v - n).abs() < 1e-11, "{f:?} t {t} rh {rh}: {v} vs {n} (Δ {:e})", v - n);
        }
    }

    #[test]
    fn physical_trends_and_bad_input() {
        let base = refractive_index(&AirConditions::default(), Formula::Ciddor).unwrap();
        // About −0.93 ppm/°C, +2.7 ppm/kPa, −0.009 ppm/%RH near standard conditions.
        let warm =
            refractive_index(&AirConditions { temperature_c: 21.0, ..Default::default() }, Formula::Ciddor)
                .unwrap();
        assert!(((warm - base) * 1e6 + 0.93).abs() < 0.05, "{}", (warm - base) * 1e6);
        let p = refractive_index(
            &AirConditions { pressure_pa: 102_325.0, ..Default::default() },
            Formula::Ciddor,
        )
        .unwrap();
        assert!(((p - base) * 1e6 - 2.68).abs() < 0.05);
        assert!(refractive_index(
            &AirConditions { humidity_pct: 120.0, ..Default::default() },
            Formula::Ciddor
        )
        .is_err());
        assert!(refractive_index(
            &AirConditions { pressure_pa: f64::NAN, ..Default::default() },
            Formula::Edlen
        )
        .is_err());
        // Outside the validity range: refused, naming the quantity and the range.
        for (c, f, what) in [
            (AirConditions { wavelength_nm: 0.633, ..Default::default() }, Formula::Ciddor, "wavelength"),
            (AirConditions { pressure_pa: 1e12, ..Default::default() }, Formula::Ciddor, "pressure"),
            (AirConditions { pressure_pa: 9_999.0, ..Default::default() }, Formula::Ciddor, "pressure"),
            (AirConditions { humidity_pct: 150.0, ..Default::default() }, Formula::Ciddor, "humidity"),
            (AirConditions { temperature_c: -300.0, ..Default::default() }, Formula::Ciddor, "temperature"),
            (AirConditions { temperature_c: -41.0, ..Default::default() }, Formula::Ciddor, "temperature"),
            (AirConditions { temperature_c: 41.0, ..Default::default() }, Formula::Edlen, "temperature"),
            (AirConditions { co2_ppm: 2500.0, ..Default::default() }, Formula::Ciddor, "CO2"),
            (AirConditions { co2_ppm: 400.0, ..Default::default() }, Formula::Edlen, "CO2"),
            (AirConditions { wavelength_nm: 1701.0, ..Default::default() }, Formula::Edlen, "wavelength"),
        ] {
            let e = refractive_index(&c, f).expect_err(what).to_string();
            assert!(e.contains(what), "{e}");
        }
        // Below absolute zero, or a pressure that is not positive: the physical bound and the
        // equation's range are both named.
        let e =
            refractive_index(&AirConditions { temperature_c: -300.0, ..Default::default() }, Formula::Ciddor)
                .unwrap_err()
                .to_string();
        assert!(e.contains("absolute zero") && e.contains("Ciddor equation (-40 to 100 °C"), "{e}");
        let e = refractive_index(&AirConditions { pressure_pa: -1.0, ..Default::default() }, Formula::Edlen)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("not positive") && e.contains("modified Edlén equation (60000 to 140000 Pa"),
            "{e}"
        );
        // The edges of the ranges are inside.
        for c in [
            AirConditions { temperature_c: -40.0, pressure_pa: 10_000.0, ..Default::default() },
            AirConditions {
                temperature_c: 100.0,
                pressure_pa: 140_000.0,
                humidity_pct: 0.0,
                ..Default::default()
            },
            AirConditions { wavelength_nm: 300.0, co2_ppm: 2000.0, ..Default::default() },
        ] {
            refractive_index(&c, Formula::Ciddor).unwrap();
        }
        // Frost point branch is continuous at 0 °C to within the difference of the two curves (~0.1 %).
        assert!(
            (saturation_vapour_pressure_pa(-1e-9) / saturation_vapour_pressure_pa(0.0) - 1.0).abs() < 2e-3
        );
    }
}

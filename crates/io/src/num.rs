//! Numbers in text: exact fast parsing and shortest round-trip (or fixed-decimal) formatting.
//!
//! - [`parse_f64`] / [`parse_f64_prefix`]: correctly rounded decimal → `f64` (every input gives
//!   the nearest double, as `str::parse` does). Plain decimals of at most 19 significant digits
//!   take the exact fast path of [`truepos_math::decimal`] (Clinger's division up to 15 digits,
//!   a 64-bit reciprocal of 5^f beyond; digits eight at a time; the same code the G-code reader
//!   uses); everything else (exponents, longer mantissas, the rare values the reciprocal leaves
//!   undecided) goes to the `fast-float2` crate (Eisel–Lemire with an exact big-decimal
//!   fallback), which parses straight from bytes.
//! - [`NumFormat`]: how written numbers look. `Shortest` (the default) writes the shortest text
//!   that parses back to the same `f64` (the `zmij` crate: Schubfach/yy, already in the tree
//!   through serde_json), so every written number round-trips bit for bit; `Fixed(n)` writes `n`
//!   decimals (what `--decimals N` asks for), by integer arithmetic when exact.

/// Parse a finite float (surrounding spaces already trimmed): the whole text must be a number.
/// `None` for malformed text and for values that are not finite (`inf`, `nan`, `1e999`).
#[inline]
pub fn parse_f64(s: &str) -> Option<f64> {
    parse_f64_bytes(s.as_bytes())
}

/// [`parse_f64`] on bytes.
#[inline]
pub fn parse_f64_bytes(b: &[u8]) -> Option<f64> {
    match parse_f64_prefix(b) {
        Some((v, n)) if n == b.len() => Some(v),
        _ => None,
    }
}

/// Parse the longest number at the start of `b`: `(value, bytes used)`. `None` when `b` does not
/// start with a number, or the number is not finite. Only decimal syntax is accepted
/// (`[+-]digits[.digits][e[+-]digits]`, `.5`, `1.`); `inf`/`nan` words are refused.
#[inline(always)]
pub fn parse_f64_prefix(b: &[u8]) -> Option<(f64, usize)> {
    // The exact fast path (shared with the G-code reader) for `[+-]digits[.digits]` with ≤ 19
    // significant digits, not followed by an exponent.
    match truepos_math::decimal::decimal_prefix(b) {
        Ok(r) => Some(r),
        // No digits: not a number in our syntax (this also refuses `inf`, `nan`, `infinity`).
        Err(0) => None,
        Err(_) => parse_f64_prefix_slow(b),
    }
}

/// Longer mantissas and exponents: Eisel–Lemire with its exact fallback (`fast-float2`). Kept
/// out of line so the fast path above stays small where it is inlined.
#[cold]
#[inline(never)]
fn parse_f64_prefix_slow(b: &[u8]) -> Option<(f64, usize)> {
    let (v, n) = fast_float2::parse_partial::<f64, _>(b).ok()?;
    v.is_finite().then_some((v, n))
}

/// How numbers are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NumFormat {
    /// The shortest text that parses back to the same `f64`.
    #[default]
    Shortest,
    /// A fixed number of decimals (no `-0.000`: a value that rounds to zero is written unsigned).
    Fixed(u8),
}

/// Largest number of decimals [`NumFormat::Fixed`] accepts (beyond 17 significant digits an
/// f64 has no more information to show).
pub const MAX_DECIMALS: u8 = 17;

impl NumFormat {
    /// `Fixed(n)` for `Some(n)`, `Shortest` for `None`; more than [`MAX_DECIMALS`] is an error.
    pub fn from_decimals(decimals: Option<u8>) -> Result<Self, String> {
        match decimals {
            None => Ok(NumFormat::Shortest),
            Some(n) if n <= MAX_DECIMALS => Ok(NumFormat::Fixed(n)),
            Some(n) => Err(format!("--decimals {n}: at most {MAX_DECIMALS} decimals")),
        }
    }

    /// Append `v` to `out`. Non-finite values are written `NaN`, `inf`, `-inf`.
    #[inline]
    pub fn write(self, v: f64, out: &mut Vec<u8>) {
        match self {
            NumFormat::Shortest => write_shortest(v, out),
            NumFormat::Fixed(d) => write_fixed(v, d, out),
        }
    }

    /// `v` as a `String`.
    pub fn to_string(self, v: f64) -> String {
        let mut out = Vec::with_capacity(24);
        self.write(v, &mut out);
        String::from_utf8(out).unwrap_or_default()
    }
}

/// Shortest round-trip text of `v`.
#[inline]
pub fn write_shortest(v: f64, out: &mut Vec<u8>) {
    let mut b = zmij::Buffer::new();
    let s = b.format(v);
    // zmij writes integers as `1.0`; the short form `1` is what the files always had. Only an
    // integer value can end so: the text just written is not read back for any other (a load
    // of its last two bytes right after zmij's wide stores stalls on store forwarding).
    let s = if v.fract() == 0.0 { s.strip_suffix(".0").unwrap_or(s) } else { s };
    out.extend_from_slice(s.as_bytes());
}

/// `v` with `dec` decimals.
///
/// The integer route (digits of `round(v·10^dec)` by [`truepos_math::fixed`], one copy into
/// `out`) is taken while |v|·10^dec < 9·10^15 and the scaled value is far from a .5 tie: the
/// product v·10^dec is one rounding away from exact, so near a tie std's exact decimal
/// formatting decides.
#[inline]
pub fn write_fixed(v: f64, dec: u8, out: &mut Vec<u8>) {
    use truepos_math::fixed;
    let p = v * truepos_math::decimal::POW10[dec.min(MAX_DECIMALS) as usize];
    let scaled = fixed::round(p);
    // |p|'s fractional part, exact (the difference from the truncation, below 2^52).
    let frac_part = (p - (p as i64) as f64).abs();
    // NaN, infinities and huge values take the exact route, as do values near a tie.
    if scaled.is_nan() || scaled.abs() >= 9.0e15 || (frac_part - 0.5).abs() < 1e-6 + scaled.abs() * 1e-15 {
        return write_fixed_exact(v, dec, out);
    }
    let n = scaled as i64;
    let a = n.unsigned_abs();
    let neg = usize::from(n < 0);
    // The digits go straight to their place in `out` (a constant-size zeroed tail, then cut to
    // the text's length): no stack buffer copied out after byte stores, whose reload stalls.
    let start = out.len();
    let end = start + neg + fixed::len(a, dec);
    out.resize(start + fixed::BUF + 1, 0);
    fixed::digits(a, dec, &mut out[start + neg..end]);
    if neg == 1 {
        out[start] = b'-';
    }
    out.truncate(end);
}

/// [`write_fixed`] by std's exact decimal formatting (non-finite values, huge values, ties); no
/// `-0.000`.
#[cold]
#[inline(never)]
fn write_fixed_exact(v: f64, dec: u8, out: &mut Vec<u8>) {
    let s = format!("{:.*}", dec as usize, v);
    let negzero = s.starts_with('-') && s[1..].bytes().all(|c| c == b'0' || c == b'.');
    out.extend_from_slice(if negzero { &s.as_bytes()[1..] } else { s.as_bytes() });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_edge_cases_match_std() {
        for s in [
            "0",
            "-0",
            "-0.0",
            "+1.5",
            "123456789012345",
            "1234567890123456789012",
            "0.000000000000001",
            "9999999999999.99",
            "1.",
            ".5",
            "-.5",
            "00012.500",
            "0.1",
            "1.7976931348623157",
            "1.7976931348623157e308",
            "2.2250738585072014e-308",
            "4.9e-324",
            "12.7000015",
            "1e5",
            "1E-5",
            "-3.14159265358979323846264338327950288",
            "0.30000000000000004",
            "123.456e-7",
            // Halfway and near-halfway cases, 17+ digits, subnormals, exponents.
            "9007199254740993",
            "9007199254740993.0",
            "9007199254740993.00000001",
            "9007199254740992.99999999",
            "900719925474099.25",
            "4503599627370496.5",
            "1.00000000000000011102230246251565404236316680908203125",
            "1.0000000000000001110223024625156540423631668090820312",
            "1.00000000000000011102230246251565404236316680908203126",
            "0.1000000000000000055511151231257827",
            "123456789.01234567890123",
            "2.2250738585072011e-308",
            "2.2250738585072012e-308",
            "4.9406564584124654e-324",
            "2.4703282292062328e-324",
            "2.4703282292062327e-324",
            "1e-320",
            "8.98846567431158e307",
            "1.7976931348623158e308",
            "179769313486231570814527423731704356798070567525844996598917476803157260780028538760589558632766878171540458953514382464234321326889464182768467546703537516986049910576551282076245490090389328944075868508455133942304583236903222948165808559332123348274797826204144723168738177180919299881250404026184124858368.0",
            "1e22",
            "1e23",
            "-0.000000000000000000",
        ] {
            let want: f64 = s.parse().unwrap();
            assert_eq!(parse_f64(s).map(f64::to_bits), Some(want.to_bits()), "{s}");
        }
        for s in [
            "", "-", ".", "+", "1.2.3", "1e5x", "--1", "1,5", "nan", "NaN", "inf", "-inf", "infinity",
            "1e400", "0x10", "e5", " 1", "1 ",
        ] {
            assert_eq!(parse_f64(s), None, "{s}");
        }
        assert_eq!(parse_f64_prefix(b"1.5,2"), Some((1.5, 3)));
        assert_eq!(parse_f64_prefix(b"-2.5e3 x"), Some((-2500.0, 6)));
        assert_eq!(parse_f64_prefix(b"12345678901234567,"), Some((12345678901234567.0, 17)));
    }

    #[test]
    fn shortest_is_short_and_exact() {
        let f = |v: f64| NumFormat::Shortest.to_string(v);
        assert_eq!(f(1.0), "1");
        assert_eq!(f(-0.5), "-0.5");
        assert_eq!(f(0.1 + 0.2), "0.30000000000000004");
        assert_eq!(f(100.0), "100");
        assert_eq!(f(f64::NAN), "NaN");
        assert_eq!(parse_f64(&f(1e-300)), Some(1e-300));
        assert_eq!(parse_f64(&f(f64::MAX)), Some(f64::MAX));
    }

    #[test]
    fn fixed_decimals() {
        let f = |v: f64, d: u8| NumFormat::Fixed(d).to_string(v);
        assert_eq!(f(1.23456, 3), "1.235");
        assert_eq!(f(-1.23456, 3), "-1.235");
        assert_eq!(f(-0.00001, 3), "0.000");
        assert_eq!(f(12.0, 0), "12");
        assert_eq!(f(0.05, 4), "0.0500");
        assert_eq!(f(2.5, 0), format!("{:.0}", 2.5));
        assert_eq!(f(1e20, 2), "100000000000000000000.00");
        assert!(NumFormat::from_decimals(Some(18)).is_err());
    }

    proptest::proptest! {
        /// Shortest output parses back to the same bits, for any finite f64.
        #[test]
        fn shortest_round_trips_bit_exactly(bits in proptest::num::u64::ANY) {
            let v = f64::from_bits(bits);
            proptest::prop_assume!(v.is_finite());
            let s = NumFormat::Shortest.to_string(v);
            let back = parse_f64(&s).unwrap();
            proptest::prop_assert_eq!(back.to_bits(), v.to_bits(), "{}", s);
        }

        /// The parser agrees with `str::parse` bit for bit on decimal text of every shape.
        #[test]
        fn parse_matches_std(int in "[0-9]{0,20}", frac in "[0-9]{0,20}", exp in proptest::option::of(-330i32..330), neg in proptest::bool::ANY) {
            proptest::prop_assume!(!(int.is_empty() && frac.is_empty()));
            let mut s = format!("{}{}", if neg { "-" } else { "" }, int);
            if !frac.is_empty() { s = format!("{s}.{frac}"); }
            if let Some(e) = exp { s = format!("{s}e{e}"); }
            let want = s.parse::<f64>().ok().filter(|v| v.is_finite());
            proptest::prop_assert_eq!(parse_f64(&s).map(f64::to_bits), want.map(f64::to_bits), "{}", s);
        }

        /// Fixed decimals agree with std's exact `{:.n}` formatting (up to the sign of zero).
        #[test]
        fn fixed_matches_std(v in -1e9f64..1e9, d in 0u8..10) {
            let want = format!("{:.*}", d as usize, v);
            let want = if want.starts_with('-') && want[1..].bytes().all(|c| c == b'0' || c == b'.') { want[1..].to_string() } else { want };
            proptest::prop_assert_eq!(NumFormat::Fixed(d).to_string(v), want);
        }
    }
}

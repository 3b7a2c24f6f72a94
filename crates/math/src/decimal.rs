//! Exact decimal text → `f64` for the common case, shared by every reader of numbers (CSV in
//! `truepos-io`, G-code words in `truepos-gcode`): one implementation, one set of tests.
//!
//! [`decimal_prefix`] reads `[+-]digits[.digits]` with at most 19 significant digits (leading
//! zeros counted) and no exponent, and returns the nearest `f64`, bit for bit what `str::parse`
//! gives. Anything else (longer mantissas, exponents) is left to the caller's general parser,
//! with the count of digits seen so it can tell "not a number" from "not this path".
//!
//! How:
//! - Digits are taken eight, then four, at a time with SWAR arithmetic on one 64-bit load where
//!   the text allows.
//! - Up to 15 digits: Clinger's fast path, the digits as one exact integer (< 10^15 < 2^53)
//!   divided by an exact power of ten, a single correctly rounded operation. (A division-free
//!   route, below, was measured slower for these: the division is not on the critical path of
//!   reading a row, which is the position in the text, so it overlaps with the next number.)
//! - 16 to 19 digits (what shortest round-trip output writes), without a division:
//!   `m / 10^f = (m / 5^f) · 2^-f`, and `m / 5^f` is `m` (shifted to 64 significant bits) times
//!   a 64-bit reciprocal of `5^f` (`⌊2^(63+b)/5^f⌋`, `b` the bit length of `5^f`, computed at
//!   compile time), one 64 × 64 → 128-bit product. The truncations of the reciprocal and of the
//!   product leave the 64 leading bits at most 3 units of their last place low, so the rounding
//!   to 53 bits is decided exactly unless the 11 bits dropped lie within 3 units below the
//!   halfway point (about 0.15 % of random inputs). Those, and only those, take the exact
//!   route: Clinger's division when `m < 2^53`, else the caller's general parser. A halfway
//!   case (a tie) always lands in the undecided band, so ties are never decided by the
//!   reciprocal. `f = 0` is an integer, whose `as f64` cast is correctly rounded. (The
//!   reciprocal-and-ambiguity idea is the one of Eisel–Lemire's algorithm, restricted to
//!   `10^-f` with `f ≤ 19`, where a 64-bit reciprocal suffices.)

/// Exact powers of ten representable in an `f64` (10^0 … 10^22).
pub const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

/// Most significant digits the fast path takes (10^19 < 2^64: the mantissa is one `u64`).
pub const MAX_DIGITS: usize = 19;

/// `(R, b)` per `f` = 0..=19: `b` the bit length of `5^f` and `R = ⌊2^(63+b) / 5^f⌋`, which lies
/// in `(2^63, 2^64)` for `f ≥ 1` (5^f is not a power of two). Row 0 is unused (`f = 0` is an
/// integer).
const RECIP5: [(u64, u32); MAX_DIGITS + 1] = {
    let mut t = [(0u64, 0u32); MAX_DIGITS + 1];
    let mut f = 1;
    let mut p: u128 = 5;
    while f <= MAX_DIGITS {
        let b = 128 - p.leading_zeros();
        // 63 + b ≤ 63 + 45 < 128: no overflow.
        t[f] = (((1u128 << (63 + b)) / p) as u64, b);
        p *= 5;
        f += 1;
    }
    t
};

/// Powers of ten as integers (10^0 … 10^8).
const POW10_U64: [u64; 9] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000];

/// The run of ASCII digits at the start of the eight bytes `v` (the first byte lowest): its
/// length `n` (0 to 8) and its value. One load, no branch per digit: a byte is a digit when
/// `x ^ 0x30` is below 10, found for all eight bytes at once (the first byte that is not has
/// its high bit set in `flags`; a carry out of a byte only reaches bytes after one that is
/// already flagged). The `n` digits are then shifted to the top, so the bytes below them are
/// zeros (leading zeros of an eight-digit number), and combined pairwise, then by fours.
#[inline(always)]
fn digit_run(v: u64) -> (usize, u64) {
    let t = v ^ 0x3030_3030_3030_3030;
    let flags = (t.wrapping_add(0x7676_7676_7676_7676) | t) & 0x8080_8080_8080_8080;
    let n = (flags.trailing_zeros() / 8) as usize;
    if n == 0 {
        return (0, 0);
    }
    let d = t << (64 - 8 * n as u32);
    let d = d.wrapping_mul(10).wrapping_add(d >> 8);
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    let v1 = (d & MASK).wrapping_mul(100 + (1_000_000 << 32));
    let v2 = ((d >> 16) & MASK).wrapping_mul(1 + (10_000 << 32));
    (n, (v1.wrapping_add(v2) >> 32) as u32 as u64)
}

/// Digits from `b[i..]`: `(mantissa (wrapping), end)`. Eight bytes at a time where the text
/// allows (a number's digits end inside the first load, mostly), one at a time in the last
/// seven bytes.
#[inline(always)]
fn digits(b: &[u8], mut i: usize, mut mant: u64) -> (u64, usize) {
    while let Some(chunk) = b.get(i..i + 8) {
        let mut w = [0u8; 8];
        w.copy_from_slice(chunk);
        let (n, d) = digit_run(u64::from_le_bytes(w));
        mant = mant.wrapping_mul(POW10_U64[n]).wrapping_add(d);
        i += n;
        if n < 8 {
            return (mant, i);
        }
    }
    while i < b.len() && b[i].is_ascii_digit() {
        mant = mant.wrapping_mul(10).wrapping_add((b[i] - b'0') as u64);
        i += 1;
    }
    (mant, i)
}

/// `m / 10^f` correctly rounded, for `0 < m < 10^19` and `1 ≤ f ≤ 19`, by the reciprocal of `5^f`
/// (see the module docs); `None` in the undecided band (the caller takes an exact route).
#[inline(always)]
fn div_pow10(m: u64, f: usize) -> Option<f64> {
    // (m = 0 has no leading bit: the caller's division gives the zero.)
    if m == 0 {
        return None;
    }
    let (r, b) = RECIP5[f];
    let lz = m.leading_zeros();
    let prod = ((m << lz) as u128) * (r as u128);
    // prod ∈ [2^126, 2^128): its 64 leading bits.
    let hi_bit = (prod >> 127) as u32;
    let top = (prod >> (63 + hi_bit)) as u64;
    let dropped = top & 0x7FF;
    if (1022..=1024).contains(&dropped) {
        return None;
    }
    let mut mant = (top >> 11) + u64::from(dropped > 1024);
    // value = 1.xxx · 2^(63 + hi_bit − b − lz − f)
    let mut e = (1023 + 63 + hi_bit) as i64 - (b + lz) as i64 - f as i64;
    if mant == 1 << 53 {
        mant >>= 1;
        e += 1;
    }
    Some(f64::from_bits(((e as u64) << 52) | (mant & ((1 << 52) - 1))))
}

/// The number at the start of `b` on the exact fast path: `Ok((value, bytes used))` for
/// `[+-]digits[.digits]` (`1.`, `.5` included) with 1 to [`MAX_DIGITS`] digits in all, not
/// followed by an exponent (`e`/`E`). Otherwise `Err(n)`, `n` the count of mantissa digits
/// seen: 0 means `b` does not start with a number of this syntax; more means the caller's
/// general parser decides (also for the rare values this path leaves undecided).
#[inline]
pub fn decimal_prefix(b: &[u8]) -> Result<(f64, usize), usize> {
    decimal_prefix_decimals(b).map(|(v, n, _)| (v, n))
}

/// [`decimal_prefix`] that also gives the count of decimals (digits after the point; `None`
/// without a point): `Ok((value, bytes used, decimals))`.
#[inline(always)]
pub fn decimal_prefix_decimals(b: &[u8]) -> Result<(f64, usize, Option<usize>), usize> {
    let (neg, s0) = match b.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let (mut mant, mut i) = digits(b, s0, 0);
    let mut n = i - s0;
    let mut frac = 0usize;
    let mut point = false;
    if i < b.len() && b[i] == b'.' {
        let f0 = i + 1;
        (mant, i) = digits(b, f0, mant);
        frac = i - f0;
        n += frac;
        point = true;
    }
    if n == 0 || n > MAX_DIGITS || (i < b.len() && (b[i] | 0x20) == b'e') {
        return Err(n);
    }
    let v = if frac == 0 {
        // An integer below 10^19: the cast rounds correctly (to nearest, ties to even).
        mant as f64
    } else {
        if n <= 15 {
            // Clinger: mant < 10^15 < 2^53 and frac ≤ 15, both operands exact, one rounding.
            // (Measured faster than the reciprocal here: the division is off the critical path
            // of the reading, which is the position in the text.)
            (mant as i64) as f64 / POW10[frac]
        } else {
            match div_pow10(mant, frac) {
                Some(v) => v,
                // Undecided by the reciprocal: Clinger's exact division when both operands are
                // exact (m < 2^53, f ≤ 19 ≤ 22), else the caller's general parser.
                None if mant < 1 << 53 => (mant as i64) as f64 / POW10[frac],
                None => return Err(n),
            }
        }
    };
    Ok((if neg { -v } else { v }, i, point.then_some(frac)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn swar_digits() {
        let run = |b: &[u8; 8]| digit_run(u64::from_le_bytes(*b));
        assert_eq!(run(b"12345678"), (8, 12_345_678));
        assert_eq!(run(b"00000009"), (8, 9));
        assert_eq!(run(b"1234567/"), (7, 1_234_567));
        assert_eq!(run(b"1234567:"), (7, 1_234_567));
        assert_eq!(run(b"123 5678"), (3, 123));
        assert_eq!(run(b"1234.678"), (4, 1234));
        assert_eq!(run(b"\xb11234567"), (0, 0));
        assert_eq!(run(b"9\xff\xff\xff\xff\xff\xff\xff"), (1, 9));
        assert_eq!(run(b"0907,1.5"), (4, 907));
        // Every byte value after a digit ends the run exactly when it is not a digit.
        for x in 0..=255u8 {
            let mut b = *b"57000000";
            b[2] = x;
            let want =
                if x.is_ascii_digit() { (8, 57_000_000 + (x - b'0') as u64 * 100_000) } else { (2, 57) };
            assert_eq!(run(&b), want, "{x}");
        }
        assert_eq!(digits(b"0907,1.5", 0, 0), (907, 4));
        assert_eq!(digits(b"123456789012,", 0, 7), (7_123_456_789_012, 12));
        assert_eq!(digits(b"12", 0, 0), (12, 2));
        assert_eq!(digits(b"x1234567", 0, 5), (5, 0));
    }

    #[test]
    fn reciprocals_are_in_range() {
        for (f, &(r, b)) in RECIP5.iter().enumerate().skip(1) {
            let p = 5u128.pow(f as u32);
            assert_eq!(b, 128 - p.leading_zeros());
            assert!(r > 1 << 63, "{f}");
            // R·5^f ≤ 2^(63+b) < (R+1)·5^f
            assert!((r as u128) * p <= 1u128 << (63 + b) && (r as u128 + 1) * p > 1u128 << (63 + b));
        }
    }

    #[test]
    fn fast_path_cases() {
        assert_eq!(decimal_prefix(b"-12.345678,1"), Ok((-12.345678, 10)));
        assert_eq!(decimal_prefix(b"250.00023792\n"), Ok((250.00023792, 12)));
        assert_eq!(decimal_prefix(b".5"), Ok((0.5, 2)));
        assert_eq!(decimal_prefix(b"1."), Ok((1.0, 2)));
        assert_eq!(decimal_prefix(b"+0.00000000000001"), Ok((1e-14, 17)));
        assert_eq!(decimal_prefix(b"+0.000000000000001"), Ok((1e-15, 18)));
        assert_eq!(decimal_prefix(b"1234567890123456"), Ok((1234567890123456.0, 16)));
        assert_eq!(decimal_prefix(b"0.30000000000000004"), Ok((0.30000000000000004, 19)));
        assert_eq!(decimal_prefix(b"0.3000000000000000444"), Err(20));
        assert_eq!(decimal_prefix(b"1e5"), Err(1));
        assert_eq!(decimal_prefix(b"-"), Err(0));
        assert_eq!(decimal_prefix(b"."), Err(0));
        assert_eq!(decimal_prefix(b"inf"), Err(0));
        assert_eq!(decimal_prefix(b""), Err(0));
        assert_eq!(decimal_prefix_decimals(b"12,"), Ok((12.0, 2, None)));
        assert_eq!(decimal_prefix_decimals(b"12.,"), Ok((12.0, 3, Some(0))));
        assert_eq!(decimal_prefix_decimals(b"-0.250 "), Ok((-0.25, 6, Some(3))));
    }

    /// `s` (a whole number of the fast path's syntax) agrees with `str::parse`, or is left to
    /// the general parser (`Err`) only for too many digits or an undecided value.
    fn check(s: &str) {
        let want: f64 = s.parse().unwrap();
        let digits = s.bytes().filter(u8::is_ascii_digit).count();
        match decimal_prefix(s.as_bytes()) {
            Ok((v, n)) => {
                assert_eq!(n, s.len(), "{s}");
                assert_eq!(v.to_bits(), want.to_bits(), "{s}");
            }
            Err(n) => {
                assert_eq!(n, digits, "{s}");
                assert!(digits > MAX_DIGITS || digits > 15, "{s}: left to the general parser");
            }
        }
    }

    #[test]
    fn halfway_and_near_halfway_cases() {
        // Ties between two doubles (2^53 + 1 and neighbours) and values a hair either side,
        // written with decimals so that the reciprocal path sees them.
        for s in [
            "9007199254740993.0",
            "9007199254740993.5",
            "9007199254740994.5",
            "900719925474099.25",
            "4503599627370496.5",
            "4503599627370497.5",
            "0.500000000000000055",
            "1.00000000000000011",
            "1.00000000000000012",
            "2.22044604925031308",
            "0.1",
            "0.2",
            "0.3",
            "123456789012345.678",
            "9999999999999999999",
            "999999999999999999.9",
            "0.9999999999999999999",
            "1.7976931348623157",
            "0.0000000000000000001",
        ] {
            check(s);
        }
        // Every halfway point between consecutive doubles in [1, 2) with few enough digits: the
        // midpoint (2k + 1)·2^-53 of the binade ..  written exactly needs 53 decimals, so take
        // the doubles of 1 + j·2^-10, whose midpoints 1 + (2j + 1)·2^-11 have 11 decimals.
        for j in 0..1024u64 {
            let mid = 1.0 + (2 * j + 1) as f64 / 2048.0;
            check(&format!("{mid:.11}"));
        }
    }

    proptest::proptest! {
        /// Bit for bit what `str::parse` gives, for every shape the fast path accepts.
        #[test]
        fn matches_std(int in "[0-9]{0,20}", frac in proptest::option::of("[0-9]{0,20}"), sign in "[-+]?", tail in "[,x e]?") {
            let mut s = format!("{sign}{int}");
            if let Some(f) = &frac { s = format!("{s}.{f}"); }
            let body = s.clone();
            s.push_str(&tail);
            let digits = int.len() + frac.as_ref().map_or(0, String::len);
            match decimal_prefix(s.as_bytes()) {
                Ok((v, n)) => {
                    proptest::prop_assert_eq!(n, body.len());
                    let want: f64 = body.parse().unwrap();
                    proptest::prop_assert_eq!(v.to_bits(), want.to_bits(), "{}", s);
                }
                Err(n) => {
                    proptest::prop_assert_eq!(n, digits);
                    // Refused: no digits, too many, an exponent, or (rarely) a long undecided value.
                    proptest::prop_assert!(digits == 0 || digits > 15 || tail == "e", "{}", s);
                }
            }
        }

        /// Halfway points between consecutive doubles (`(2j + 1)·2^-k`, written exactly) and
        /// their neighbours cut to 15–19 significant digits, one unit either side.
        #[test]
        fn near_halfway_matches_std(j in (1u64 << 52)..(1u64 << 53), k in 0u32..=20, cut in 15usize..=19, delta in -1i64..=1) {
            let m = 2 * j + 1;
            let full = (m as u128 * 5u128.pow(k)).to_string();
            let full = format!("{}{}", "0".repeat((k as usize + 1).saturating_sub(full.len())), full);
            let (int, frac) = full.split_at(full.len() - k as usize);
            let s = format!("{int}.{frac}");
            if int.len() + frac.len() <= MAX_DIGITS {
                check(&s);
            }
            let keep = cut.saturating_sub(int.len()).min(frac.len());
            let mut cutd: u128 = format!("{int}{}", &frac[..keep]).parse().unwrap();
            cutd = cutd.saturating_add_signed(delta as i128);
            let t = format!("{:0>w$}", cutd, w = keep + 1);
            let (ti, tf) = t.split_at(t.len() - keep);
            check(&format!("{ti}.{tf}"));
        }
    }
}

//! Exact decimal text → `f64` for the common case, shared by every reader of numbers (CSV in
//! `truepos-io`, G-code words in `truepos-gcode`): one implementation, one set of tests.
//!
//! [`decimal_prefix`] reads `[+-]digits[.digits]` and, when the number has at most 15
//! significant digits and no exponent, returns its value by Clinger's fast path: the digits as
//! one exact integer (< 10^15 < 2^53) divided by an exact power of ten, a single correctly
//! rounded operation, so the result is the nearest `f64`, bit for bit what `str::parse` gives.
//! Digits are taken eight (then four) at a time with SWAR arithmetic on one 64-bit load where
//! the text allows. Anything else (longer mantissas, exponents) is left to the caller's general
//! parser, with the count of digits seen so it can tell "not a number" from "not this path".

/// Exact powers of ten representable in an `f64` (10^0 … 10^22).
pub const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

/// Eight ASCII digits at `b[i..i + 8]` as their value, if all eight are digits.
#[inline(always)]
fn eight_digits(b: &[u8], i: usize) -> Option<u64> {
    let chunk: [u8; 8] = b.get(i..i + 8)?.try_into().ok()?;
    let v = u64::from_le_bytes(chunk);
    // Every byte in 0x30..=0x39: its high nibble is 3 and adding 6 does not carry out of it.
    if (v & 0xF0F0_F0F0_F0F0_F0F0) | (((v.wrapping_add(0x0606_0606_0606_0606)) & 0xF0F0_F0F0_F0F0_F0F0) >> 4)
        != 0x3333_3333_3333_3333
    {
        return None;
    }
    // Pairs, then quads, then the eight (the first digit is the lowest byte).
    let v = v - 0x3030_3030_3030_3030;
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    let v1 = (v & MASK).wrapping_mul(100 + (1_000_000 << 32));
    let v2 = ((v >> 16) & MASK).wrapping_mul(1 + (10_000 << 32));
    Some((v1.wrapping_add(v2) >> 32) as u32 as u64)
}

/// Four ASCII digits at `b[i..i + 4]` as their value, if all four are digits.
#[inline(always)]
fn four_digits(b: &[u8], i: usize) -> Option<u64> {
    let chunk: [u8; 4] = b.get(i..i + 4)?.try_into().ok()?;
    let v = u32::from_le_bytes(chunk);
    if (v & 0xF0F0_F0F0) | (((v.wrapping_add(0x0606_0606)) & 0xF0F0_F0F0) >> 4) != 0x3333_3333 {
        return None;
    }
    let v = v - 0x3030_3030;
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    Some(((v & 0x00FF_00FF).wrapping_mul(1 + (100 << 16)) >> 16) as u64 & 0xFFFF)
}

/// Digits from `b[i..]`: `(mantissa (wrapping), end)`.
#[inline(always)]
fn digits(b: &[u8], mut i: usize, mut mant: u64) -> (u64, usize) {
    while let Some(d) = eight_digits(b, i) {
        mant = mant.wrapping_mul(100_000_000).wrapping_add(d);
        i += 8;
    }
    if let Some(d) = four_digits(b, i) {
        mant = mant.wrapping_mul(10_000).wrapping_add(d);
        i += 4;
    }
    while i < b.len() && b[i].is_ascii_digit() {
        mant = mant.wrapping_mul(10).wrapping_add((b[i] - b'0') as u64);
        i += 1;
    }
    (mant, i)
}

/// The number at the start of `b` on the exact fast path: `Ok((value, bytes used))` for
/// `[+-]digits[.digits]` (`1.`, `.5` included) with 1 to 15 digits in all, not followed by an
/// exponent (`e`/`E`). Otherwise `Err(n)`, `n` the count of mantissa digits seen: 0 means `b`
/// does not start with a number of this syntax; more means the caller's general parser decides.
#[inline]
pub fn decimal_prefix(b: &[u8]) -> Result<(f64, usize), usize> {
    let (neg, s0) = match b.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let (mut mant, mut i) = digits(b, s0, 0);
    let mut n = i - s0;
    let mut frac = 0usize;
    if i < b.len() && b[i] == b'.' {
        let f0 = i + 1;
        (mant, i) = digits(b, f0, mant);
        frac = i - f0;
        n += frac;
    }
    if n == 0 || n > 15 || (i < b.len() && (b[i] | 0x20) == b'e') {
        return Err(n);
    }
    // n ≤ 15 so frac ≤ 15 and mant < 10^15: both operands exact, one rounding.
    // (`mant` < 2^53: the signed conversion is exact and one instruction.)
    let v = (mant as i64) as f64 / POW10[frac];
    Ok((if neg { -v } else { v }, i))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn swar_digits() {
        assert_eq!(eight_digits(b"12345678", 0), Some(12_345_678));
        assert_eq!(eight_digits(b"x00000009", 1), Some(9));
        assert_eq!(eight_digits(b"1234567", 0), None);
        for bad in [b"1234567/", b"1234567:", b"123 5678", b"1234.678", b"\xb11234567"] {
            assert_eq!(eight_digits(bad, 0), None, "{:?}", bad);
        }
        assert_eq!(four_digits(b"0907", 0), Some(907));
        assert_eq!(four_digits(b"9999", 0), Some(9999));
        assert_eq!(four_digits(b"99,9", 0), None);
    }

    #[test]
    fn fast_path_cases() {
        assert_eq!(decimal_prefix(b"-12.345678,1"), Ok((-12.345678, 10)));
        assert_eq!(decimal_prefix(b"250.00023792\n"), Ok((250.00023792, 12)));
        assert_eq!(decimal_prefix(b".5"), Ok((0.5, 2)));
        assert_eq!(decimal_prefix(b"1."), Ok((1.0, 2)));
        assert_eq!(decimal_prefix(b"+0.00000000000001"), Ok((1e-14, 17)));
        assert_eq!(decimal_prefix(b"+0.000000000000001"), Err(16));
        assert_eq!(decimal_prefix(b"1234567890123456"), Err(16));
        assert_eq!(decimal_prefix(b"1e5"), Err(1));
        assert_eq!(decimal_prefix(b"-"), Err(0));
        assert_eq!(decimal_prefix(b"."), Err(0));
        assert_eq!(decimal_prefix(b"inf"), Err(0));
        assert_eq!(decimal_prefix(b""), Err(0));
    }

    proptest::proptest! {
        /// Bit for bit what `str::parse` gives, for every shape the fast path accepts.
        #[test]
        fn matches_std(int in "[0-9]{0,17}", frac in proptest::option::of("[0-9]{0,17}"), sign in "[-+]?", tail in "[,x ]?") {
            let mut s = format!("{sign}{int}");
            if let Some(f) = &frac { s = format!("{s}.{f}"); }
            let body = s.clone();
            s.push_str(&tail);
            match decimal_prefix(s.as_bytes()) {
                Ok((v, n)) => {
                    proptest::prop_assert_eq!(n, body.len());
                    let want: f64 = body.parse().unwrap();
                    proptest::prop_assert_eq!(v.to_bits(), want.to_bits(), "{}", s);
                }
                Err(n) => {
                    let digits = int.len() + frac.as_ref().map_or(0, String::len);
                    proptest::prop_assert_eq!(n, digits);
                    proptest::prop_assert!(digits == 0 || digits > 15);
                }
            }
        }
    }
}

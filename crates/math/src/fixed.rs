//! Fixed-point decimal text: the digits of a scaled integer with a decimal point, and a rounding
//! that needs no libm call. Shared by every writer of fixed-decimal numbers (the CSV and stream
//! writers of `truepos-io` for `--decimals N`, the G-code rewriter of `truepos-gcode`): one
//! implementation, one set of tests.
//!
//! Entry points:
//! - [`digits`]: `a` written with a point `dec` digits from the right, right-aligned in a small
//!   stack buffer (two digits at a time from a pair table; the usual 3 to 6 decimals with
//!   constant divisors, which compile to multiplications).
//! - [`round`]: `f64::round` bit for bit, without the call into libm that `f64::round` is on the
//!   x86-64 baseline (no rounding instruction before SSE4.1).
//!
//! How a caller scales and rounds (and what it does near a tie) is its own rule; this module
//! only turns the resulting integer into text.

/// Length of the buffer [`digits`] writes into: room for 16 digits, a point, up to 18 decimals'
/// leading zeros and a sign.
pub const BUF: usize = 31;

/// Digit pairs "00" to "99".
const PAIRS: &[u8; 200] = b"00010203040506070809101112131415161718192021222324252627282930313233343536373839\
404142434445464748495051525354555657585960616263646566676869707172737475767778798081828384858687888990919293949596979899";

/// `a` (below 10^16) written with a point `dec` (0 to 18) digits from the right, ending at the
/// end of `buf` (`0.5` for `a = 5, dec = 1`; no point when `dec` is 0; at least one integer
/// digit). Returns where the text starts: the text is `buf[start..]`, ASCII digits and the
/// point only, so a caller that wants a sign writes it at `start - 1`. `buf` must hold
/// [`len`]`(a, dec)` bytes (a [`BUF`]-byte buffer always does); the digits are written where
/// they stay, so a caller can pass the very bytes of its output.
#[inline(always)]
pub fn digits(a: u64, dec: u8, buf: &mut [u8]) -> usize {
    debug_assert!(a < 10_000_000_000_000_000 && dec <= 18);
    match dec {
        4 => digits_const::<4>(a, buf),
        5 => digits_const::<5>(a, buf),
        3 => digits_const::<3>(a, buf),
        6 => digits_const::<6>(a, buf),
        _ => digits_any(a, dec as usize, buf),
    }
}

/// Length of the text [`digits`] writes for `a` and `dec`: the digits of `a`, at least `dec + 1`
/// of them, and the point when `dec > 0`.
#[inline(always)]
pub fn len(a: u64, dec: u8) -> usize {
    let n = a.checked_ilog10().map_or(1, |d| d as usize + 1);
    n.max(dec as usize + 1) + usize::from(dec > 0)
}

/// `v.round()` (half away from zero, the sign of zero kept) without a libm call: truncation by
/// the integer conversion, and the difference `v − trunc(v)`, exact below 2^52. (The sign is
/// restored last: `t + 0 − 0` of a negative zero `t` is a positive zero.)
#[inline(always)]
pub fn round(v: f64) -> f64 {
    if v.is_nan() || v.abs() >= 4.0e15 {
        return v.round();
    }
    let t = (v as i64) as f64;
    let d = v - t;
    // Without branches: which way a value rounds is as good as random (a mispredicted branch
    // on every written number). t ± 1 is exact below 2^52.
    let up = f64::from(u8::from(d >= 0.5));
    let down = f64::from(u8::from(d <= -0.5));
    (t + up - down).copysign(v)
}

/// The integer part `q` written two digits at a time, ending before `buf[i]`; at least one
/// digit. Returns where the text starts.
#[inline(always)]
fn integer_digits(mut q: u64, mut i: usize, buf: &mut [u8]) -> usize {
    while q >= 10 {
        let r = (q % 100) as usize * 2;
        q /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[r..r + 2]);
    }
    // The leading digit, unless the pairs ended on one ("10" of 1000).
    if q > 0 || i == buf.len() || buf[i] == b'.' {
        i -= 1;
        buf[i] = b'0' + q as u8;
    }
    i
}

/// [`digits`] for a constant `D` (1 to 9) decimals: the fraction and the integer part come from
/// `a % 10^D` and `a / 10^D`, two short chains of divisions (by constants) instead of one long
/// one.
#[inline(always)]
fn digits_const<const D: usize>(a: u64, buf: &mut [u8]) -> usize {
    const P: [u64; 10] =
        [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000, 1_000_000_000];
    let p = P[D];
    let mut f = (a % p) as u32;
    let mut i = buf.len();
    let mut left = D;
    while left >= 2 {
        let r = (f % 100) as usize * 2;
        f /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[r..r + 2]);
        left -= 2;
    }
    if left == 1 {
        i -= 1;
        buf[i] = b'0' + f as u8;
    }
    i -= 1;
    buf[i] = b'.';
    integer_digits(a / p, i, buf)
}

/// [`digits`] for any count of decimals `dec` (0 to 18): one chain of divisions.
fn digits_any(mut a: u64, dec: usize, buf: &mut [u8]) -> usize {
    let mut i = buf.len();
    let mut left = dec;
    while left >= 2 {
        let r = (a % 100) as usize * 2;
        a /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[r..r + 2]);
        left -= 2;
    }
    if left == 1 {
        i -= 1;
        buf[i] = b'0' + (a % 10) as u8;
        a /= 10;
    }
    if dec > 0 {
        i -= 1;
        buf[i] = b'.';
    }
    integer_digits(a, i, buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(a: u64, dec: u8) -> String {
        let mut buf = [0u8; BUF];
        let i = digits(a, dec, &mut buf);
        // Written in place into a slice of exactly its length: the same text, from 0.
        let mut exact = vec![0u8; len(a, dec)];
        assert_eq!(digits(a, dec, &mut exact), 0);
        assert_eq!(exact, &buf[i..]);
        String::from_utf8(buf[i..].to_vec()).unwrap()
    }

    /// The plain reference: the integer's digits, zero-padded to `dec + 1`, point inserted.
    fn reference(a: u64, dec: u8) -> String {
        let s = format!("{:0width$}", a, width = dec as usize + 1);
        let (int, frac) = s.split_at(s.len() - dec as usize);
        if dec == 0 {
            int.to_string()
        } else {
            format!("{int}.{frac}")
        }
    }

    #[test]
    fn edge_cases() {
        for (a, dec, want) in [
            (0, 0, "0"),
            (0, 3, "0.000"),
            (5, 1, "0.5"),
            (10, 0, "10"),
            (1000, 0, "1000"),
            (1000, 3, "1.000"),
            (123456789123456, 6, "123456789.123456"),
            (9_999_999_999_999_999, 0, "9999999999999999"),
            (9_999_999_999_999_999, 18, "0.009999999999999999"),
            (1, 17, "0.00000000000000001"),
        ] {
            assert_eq!(text(a, dec), want, "{a} {dec}");
        }
    }

    proptest::proptest! {
        /// Every count of decimals the writers use gives the reference text.
        #[test]
        fn digits_match_the_reference(a in 0u64..10_000_000_000_000_000, dec in 0u8..=18) {
            proptest::prop_assert_eq!(text(a, dec), reference(a, dec));
        }

        /// Small values too (the leading-zero and "10 of 1000" cases).
        #[test]
        fn small_values_match_the_reference(a in 0u64..100_000, dec in 0u8..=8) {
            proptest::prop_assert_eq!(text(a, dec), reference(a, dec));
        }

        /// The inline rounding is `f64::round`, bit for bit (sign of zero included).
        #[test]
        fn round_matches_std(v in proptest::num::f64::ANY, k in 0i32..8) {
            let v = v / 10f64.powi(k);
            proptest::prop_assert_eq!(round(v).to_bits(), v.round().to_bits(), "{}", v);
            let h = (v * 2.0).trunc() / 2.0;
            proptest::prop_assert_eq!(round(h).to_bits(), h.round().to_bits(), "{}", h);
        }
    }
}

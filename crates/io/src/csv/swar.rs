//! Portable number conversion by SWAR (SIMD within a register): a short decimal's digit runs
//! found and converted eight bytes at a time in one `u64` ([`short_decimal_prefix`]). The same
//! values as `str::parse`, bit for bit, on every CPU; the SSSE3 kernels of [`super::x86`] are
//! tested against it.

/// Bytes [`short_decimal_prefix`] may read: sign, 8 bytes of integer digits, the point, 8 bytes
/// of fraction digits, the byte after them (18 at most; 24 keeps a margin).
pub(super) const SHORT_DECIMAL_READ: usize = 24;

/// The common short decimal (`[+-]digits[.digits]`, at most 7 digits before and 8 after the
/// point, at least one digit, no exponent after it) without a loop over its digits: each digit
/// run is found and converted in one 8-byte word (SWAR), so the cost does not depend on how many
/// digits there are and no branch follows the digit count (which varies from number to number
/// and defeated the branch predictor). `None` for anything else, which the general parser then
/// reads. With at most 15 digits the value is Clinger's one exact division, the very operation
/// (and result, bit for bit) of `truepos_math::decimal::decimal_prefix` and of `str::parse`.
/// Needs `b.len() >= SHORT_DECIMAL_READ`.
#[inline(always)]
pub(super) fn short_decimal_prefix(b: &[u8]) -> Option<(f64, usize)> {
    const POW10: [u64; 9] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000, 100_000_000];
    // Signs without branches: in real data they change from number to number unpredictably,
    // and a mispredicted branch per number cost more than all of the digit arithmetic.
    let neg = b[0] == b'-';
    let s = usize::from(neg) | usize::from(b[0] == b'+');
    let w = word(b, s);
    let int_len = digit_run(w);
    if int_len == 8 {
        return None;
    }
    let mut end = s + int_len;
    let mut mant = digits_value(w, int_len);
    let mut frac_len = 0;
    if b[end] == b'.' {
        let f = word(b, end + 1);
        frac_len = digit_run(f);
        // Eight fraction digits fill the word: taken when the byte after them ends the run
        // (the 8-decimal files of the latency streams), else the general parser reads on.
        if frac_len == 8 && b[end + 9].is_ascii_digit() {
            return None;
        }
        mant = mant * POW10[frac_len] + digits_value(f, frac_len);
        end += 1 + frac_len;
    }
    if int_len + frac_len == 0 || (b[end] | 0x20) == b'e' {
        return None;
    }
    // mant < 10^15 < 2^53 and 10^frac_len are exact: one correctly rounded division.
    // (`as i64` first: one conversion instruction; the unsigned one takes several.)
    let v = (mant as i64) as f64 / truepos_math::decimal::POW10[frac_len];
    // `v ≥ 0`: setting the sign bit is `-v` (also for zero: `-0.0`).
    Some((f64::from_bits(v.to_bits() | (u64::from(neg) << 63)), end))
}

/// The 8 bytes at `b[i..]` as a little-endian word (the first byte lowest).
#[inline(always)]
pub(super) fn word(b: &[u8], i: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(a)
}

/// How many of the bytes of `w` (first byte lowest) are ASCII digits before the first that is
/// not (8 when all are).
#[inline(always)]
pub(super) fn digit_run(w: u64) -> usize {
    const HIGH: u64 = 0xF0F0_F0F0_F0F0_F0F0;
    const THREES: u64 = 0x3030_3030_3030_3030;
    // A digit 0x30..=0x39 has high nibble 3, and still has after adding 6 (0x3A..=0x3F do not).
    // A carry out of a byte (0xFA..=0xFF + 6) only disturbs the bytes after a non-digit.
    let bad = ((w & HIGH) ^ THREES) | ((w.wrapping_add(0x0606_0606_0606_0606) & HIGH) ^ THREES);
    (bad.trailing_zeros() / 8) as usize
}

/// The value of the first `len` (≤ 8) bytes of `w`, all ASCII digits, the first byte the most
/// significant digit.
#[inline(always)]
pub(super) fn digits_value(w: u64, len: usize) -> u64 {
    // The digits move to the top bytes, zeros (leading zero digits) come in below; a borrow of
    // the subtraction only starts at a non-digit byte, which is shifted out.
    let d = w.wrapping_sub(0x3030_3030_3030_3030);
    let d = ((d as u128) << (64 - 8 * len)) as u64;
    // Pairs, then quads, then all eight.
    let d = d.wrapping_mul(10).wrapping_add(d >> 8);
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    let lo = (d & MASK).wrapping_mul(100 + (1_000_000 << 32));
    let hi = ((d >> 16) & MASK).wrapping_mul(1 + (10_000 << 32));
    (lo.wrapping_add(hi) >> 32) as u32 as u64
}

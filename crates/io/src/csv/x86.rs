//! The x86-64 kernels (SSSE3, SSE2), compiled with `#[target_feature]` and called only after
//! the run-time check of [`super::cpu_has_ssse3`]: delimiter masks of 64-byte blocks, short
//! decimals converted with byte shuffles and multiply-adds, the plain-row reader, and the SSSE3
//! copy of the segment loop. Each gives the portable path's values bit for bit (proptests in
//! `super::tests`). Every `unsafe` block states why its target feature is present.

use super::*;

/// [`parse_segment`] compiled with SSSE3, its plain rows read by [`short_decimal_ssse3`].
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
pub(super) unsafe fn parse_segment_ssse3<const K: usize>(
    seg: &[u8],
    slots: &[usize],
    cap: usize,
    put: impl FnMut(usize, [f64; K]),
) -> Option<(usize, bool)> {
    parse_segment::<K, true>(seg, slots, cap, put)
}

/// [`short_decimal_prefix`] with SSE2/SSSE3 vector instructions: the 16 bytes after the sign
/// are classified at once (digit or not: the integer and fraction lengths are the positions of
/// the first two non-digits) and the digits converted by [`digits_value_ssse3`].
/// Takes what [`short_decimal_prefix`] takes (except 7 integer digits followed by 8 fraction
/// digits, which it leaves to the general parser), with the same value, bit for bit (the same
/// integer mantissa and the same one division), and the same end.
///
/// # Safety
/// The CPU must have SSSE3. Needs `b.len() >= SHORT_DECIMAL_READ` (else `None`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
pub(super) unsafe fn short_decimal_ssse3(b: &[u8]) -> Option<(f64, usize)> {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_min_epu8, _mm_movemask_epi8, _mm_set1_epi8,
        _mm_sub_epi8,
    };
    if b.len() < SHORT_DECIMAL_READ {
        return None;
    }
    let neg = b[0] == b'-';
    let s = usize::from(neg) | usize::from(b[0] == b'+');
    let bytes: &[u8; 16] = b[s..s + 16].try_into().ok()?;
    // SAFETY: an unaligned load of the 16 bytes of `bytes`.
    let v = unsafe { _mm_loadu_si128(bytes.as_ptr().cast::<__m128i>()) };
    let d = _mm_sub_epi8(v, _mm_set1_epi8(b'0' as i8));
    // A byte is a digit when `byte − '0'` (unsigned) is at most 9; bits 16.. are set (not digits).
    let digit = _mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8(9)), d);
    let non_digit = !(_mm_movemask_epi8(digit) as u32);
    let int_len = non_digit.trailing_zeros() as usize;
    if int_len >= 8 {
        return None;
    }
    let mut end = s + int_len;
    let mut frac_len = 0;
    if bytes[int_len] == b'.' {
        frac_len = (non_digit >> (int_len + 1)).trailing_zeros() as usize;
        // The run must end inside the 16 bytes (else its end is not seen) and fit in 8 digits.
        if frac_len > 8 || int_len + 1 + frac_len >= 16 {
            return None;
        }
        end += 1 + frac_len;
    }
    if int_len + frac_len == 0 || (b[end] | 0x20) == b'e' {
        return None;
    }
    // SAFETY: the CPU has SSSE3 (this function's contract).
    Some((unsafe { digits_value_ssse3(d, int_len, frac_len, neg) }, end))
}

/// The value of a short decimal whose bytes minus `'0'` are `d` (after the sign): `int_len`
/// (≤ 7) digits, the point, `frac_len` (≤ 8) digits, all checked by the caller. The digits are
/// moved by one byte shuffle to the right end of the register, the point dropped and zeros in
/// front ([`DIGIT_SHUFFLE`]), and combined by three multiply-adds of neighbours (×10, ×100,
/// ×10⁴) into two 8-digit halves: the integer mantissa, then the one correctly rounded division
/// of [`short_decimal_prefix`] (the same value, bit for bit).
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
pub(super) unsafe fn digits_value_ssse3(
    d: std::arch::x86_64::__m128i,
    int_len: usize,
    frac_len: usize,
    neg: bool,
) -> f64 {
    use std::arch::x86_64::{
        __m128i, _mm_cvtsi128_si64, _mm_loadu_si128, _mm_madd_epi16, _mm_maddubs_epi16, _mm_packs_epi32,
        _mm_set1_epi16, _mm_set1_epi32, _mm_shuffle_epi8,
    };
    let table = &DIGIT_SHUFFLE[int_len][frac_len];
    // SAFETY: an unaligned load of the 16 bytes of `table`.
    let ctl = unsafe { _mm_loadu_si128(table.as_ptr().cast::<__m128i>()) };
    let digits = _mm_shuffle_epi8(d, ctl);
    // Bytes (d0 … d15) → 16-bit d0·10 + d1, … → 32-bit ·100 + … → 16-bit (≤ 9999) → 32-bit
    // ·10⁴ + …: lane 0 the first 8 digits, lane 1 the last 8.
    let pairs = _mm_maddubs_epi16(digits, _mm_set1_epi16(0x010A));
    let quads = _mm_madd_epi16(pairs, _mm_set1_epi32(0x0001_0064));
    let quads = _mm_packs_epi32(quads, quads);
    let eights = _mm_madd_epi16(quads, _mm_set1_epi32(0x0001_2710));
    let lanes = _mm_cvtsi128_si64(eights) as u64;
    let mant = (lanes & 0xFFFF_FFFF) * 100_000_000 + (lanes >> 32);
    // mant < 10^15 < 2^53: one correctly rounded division, as in `short_decimal_prefix`.
    let v = (mant as i64) as f64 / truepos_math::decimal::POW10[frac_len];
    // `v ≥ 0`: setting the sign bit is `-v` (also for zero).
    f64::from_bits(v.to_bits() | (u64::from(neg) << 63))
}

/// Bytes after a block start [`plain_rows_ssse3`] may read: the 64-byte block, then up to 16
/// bytes of a field's number that starts inside it.
pub(super) const PLAIN_BLOCK: usize = 64;

/// Consecutive plain rows (as [`parse_row_plain`] takes them: `K` short decimals separated by
/// single commas, ended by `\n`) from `seg[pos..]`, at most `cap`, each handed to `put(i, row)`
/// (`i` = 0, 1, …); returns how many and where the next row starts. Stops at the first row that
/// is not plain (the caller reads it by the general path) or where the rest of the segment is
/// shorter than a block and a number.
///
/// The delimiters (`,` and `\n`) of each 64-byte block are found at once, as a bit mask
/// ([`delimiter_mask`]), so every field's end is known before its digits are looked at and the
/// fields are converted independently of each other ([`plain_field_ssse3`]). (Finding each
/// number's end by classifying its bytes, and the next number's start from it, made a chain
/// of dependent steps of about 20 cycles a number that bounded the row rate, whatever the
/// conversion cost.) Values are bit for bit those of [`short_decimal_prefix`].
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
pub(super) unsafe fn plain_rows_ssse3<const K: usize>(
    seg: &[u8],
    pos: usize,
    cap: usize,
    put: impl FnMut(usize, [f64; K]),
) -> (usize, usize) {
    // SAFETY: the CPU has SSSE3 (this function's contract).
    unsafe { plain_rows::<K, false>(seg, pos, cap, put) }
}

/// [`plain_rows_ssse3`] with the numbers converted by the portable SWAR kernel
/// ([`super::swar::short_decimal_prefix`]) instead of [`plain_field_ssse3`]: the measurement
/// of whether the SSSE3 number conversion earns its place inside the row loop (criterion
/// bench `rows/*` of `crates/io/benches/readers.rs`; not used by the readers).
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
pub(super) unsafe fn plain_rows_masks_swar<const K: usize>(
    seg: &[u8],
    pos: usize,
    cap: usize,
    put: impl FnMut(usize, [f64; K]),
) -> (usize, usize) {
    // SAFETY: the CPU has SSSE3 (this function's contract).
    unsafe { plain_rows::<K, true>(seg, pos, cap, put) }
}

/// The plain-row loop of [`plain_rows_ssse3`]; `SWAR`: numbers by the portable kernel.
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
unsafe fn plain_rows<const K: usize, const SWAR: bool>(
    seg: &[u8],
    mut pos: usize,
    cap: usize,
    mut put: impl FnMut(usize, [f64; K]),
) -> (usize, usize) {
    // A block at `base` is taken only when `base + PLAIN_BLOCK + 16 <= len`: a field that ends
    // at a delimiter inside it starts inside it or the block before (a field is at most 17
    // bytes) and its 16-byte read stays inside the segment.
    let Some(last_base) = seg.len().checked_sub(PLAIN_BLOCK + 16) else {
        return (0, pos);
    };
    if pos > last_base {
        return (0, pos);
    }
    let mut base = pos;
    // SAFETY: the CPU has SSSE3 (so SSE2).
    let mut mask = unsafe { delimiter_mask(seg, base) };
    let mut n = 0;
    while n < cap {
        let start = pos;
        let mut d = [0.0; K];
        let mut a = pos;
        for (k, v) in d.iter_mut().enumerate() {
            while mask == 0 {
                base += PLAIN_BLOCK;
                if base > last_base {
                    return (n, start);
                }
                // SAFETY: as above.
                mask = unsafe { delimiter_mask(seg, base) };
            }
            let e = base + mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let want = if k + 1 < K { b',' } else { b'\n' };
            let x = if SWAR {
                match seg.get(a..).filter(|b| b.len() >= SHORT_DECIMAL_READ).map(short_decimal_prefix) {
                    Some(Some((x, used))) if a + used == e => Some(x),
                    _ => None,
                }
            } else {
                // SAFETY: as above.
                unsafe { plain_field_ssse3(seg, a, e) }
            };
            match x {
                Some(x) if seg[e] == want => *v = x,
                _ => return (n, start),
            }
            a = e + 1;
        }
        put(n, d);
        n += 1;
        pos = a;
    }
    (n, pos)
}

/// The field `b[a..e]` (ended by a delimiter at `e`, 16 bytes readable from `a + 1`) as a
/// short decimal: [`short_decimal_ssse3`] where the field's end is already known, so that
/// nothing of the next field waits for this one. The same numbers are taken, with the same
/// values; `None` for anything else.
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
pub(super) unsafe fn plain_field_ssse3(b: &[u8], a: usize, e: usize) -> Option<f64> {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_min_epu8, _mm_movemask_epi8, _mm_set1_epi8,
        _mm_sub_epi8,
    };
    if e <= a || e - a > 17 {
        return None;
    }
    let neg = b[a] == b'-';
    let s = a + (usize::from(neg) | usize::from(b[a] == b'+'));
    let bytes: &[u8; 16] = b.get(s..s + 16)?.try_into().ok()?;
    // SAFETY: an unaligned load of the 16 bytes of `bytes`.
    let v = unsafe { _mm_loadu_si128(bytes.as_ptr().cast::<__m128i>()) };
    let d = _mm_sub_epi8(v, _mm_set1_epi8(b'0' as i8));
    let digit = _mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8(9)), d);
    let non_digit = !(_mm_movemask_epi8(digit) as u32);
    let int_len = non_digit.trailing_zeros() as usize;
    let len = e - s;
    if int_len >= 8 || int_len > len {
        return None;
    }
    let mut frac_len = 0;
    if int_len < len {
        // A point, then digits up to the delimiter, at most 8.
        frac_len = len - int_len - 1;
        if bytes[int_len] != b'.'
            || frac_len > 8
            || (non_digit >> (int_len + 1)).trailing_zeros() < frac_len as u32
        {
            return None;
        }
    }
    if int_len + frac_len == 0 {
        return None;
    }
    // SAFETY: the CPU has SSSE3 (this function's contract).
    Some(unsafe { digits_value_ssse3(d, int_len, frac_len, neg) })
}

/// Bit `j` set where `b[i + j]` is `,` or `\n` (`j` < 64).
///
/// # Safety
/// The CPU must have SSE2 (every x86-64 CPU).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
pub(super) unsafe fn delimiter_mask(b: &[u8], i: usize) -> u64 {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_movemask_epi8, _mm_or_si128, _mm_set1_epi8,
    };
    let block: &[u8; PLAIN_BLOCK] = match b[i..i + PLAIN_BLOCK].try_into() {
        Ok(x) => x,
        Err(_) => return 0,
    };
    let mut m = 0u64;
    for q in 0..4 {
        // SAFETY: an unaligned load of 16 bytes inside `block`.
        let v = unsafe { _mm_loadu_si128(block.as_ptr().add(16 * q).cast::<__m128i>()) };
        let hit = _mm_or_si128(
            _mm_cmpeq_epi8(v, _mm_set1_epi8(b',' as i8)),
            _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\n' as i8)),
        );
        m |= (_mm_movemask_epi8(hit) as u32 as u64) << (16 * q);
    }
    m
}

/// One row of [`Rows::split_and_parse_range`] by delimiter masks: the row starting at
/// `text[s0]`, whole within the 64 bytes from `s0` and holding no quote, space, tab or `\r`
/// (so no field needs trimming or unquoting), has its fields' ranges appended to `fields` and
/// its wanted columns (`slots`, as for [`row_fast`]) converted by [`plain_field_ssse3`] — every
/// field's end is known from the masks, so nothing waits for the previous field's digits.
/// `true` when it did; `false` (with `fields` and `d` unspecified) for any other row, which
/// the portable walk then reads: the same fields and values for every row this one takes.
///
/// # Safety
/// The CPU must have SSSE3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
#[inline]
pub(super) unsafe fn split_parse_row_ssse3(
    text: &[u8],
    s0: usize,
    slots: &[usize],
    d: &mut [f64],
    fields: &mut Vec<(usize, usize)>,
) -> bool {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_movemask_epi8, _mm_or_si128, _mm_set1_epi8,
    };
    // The block and a number's 16-byte read after the last field start must lie in the text.
    let Some(block) = text.get(s0..s0 + PLAIN_BLOCK + 16) else {
        return false;
    };
    let (mut delims, mut newline, mut special) = (0u64, 0u64, 0u64);
    for q in 0..4 {
        // SAFETY: an unaligned load of 16 bytes inside `block`.
        let v = unsafe { _mm_loadu_si128(block.as_ptr().add(16 * q).cast::<__m128i>()) };
        let eq = |c: u8| _mm_cmpeq_epi8(v, _mm_set1_epi8(c as i8));
        let nl = eq(b'\n');
        let del = _mm_or_si128(eq(b','), nl);
        let sp = _mm_or_si128(_mm_or_si128(eq(b'"'), eq(b' ')), _mm_or_si128(eq(b'\t'), eq(b'\r')));
        delims |= (_mm_movemask_epi8(del) as u32 as u64) << (16 * q);
        newline |= (_mm_movemask_epi8(nl) as u32 as u64) << (16 * q);
        special |= (_mm_movemask_epi8(sp) as u32 as u64) << (16 * q);
    }
    if newline == 0 {
        return false;
    }
    // Bits up to and including the row's `\n`.
    let end = newline.trailing_zeros();
    let row = u64::MAX >> (63 - end);
    if special & row != 0 || (delims & row).count_ones() as usize != slots.len() {
        return false;
    }
    let mut m = delims & row;
    let mut a = 0usize;
    let mut filled = 0;
    for &slot in slots {
        let e = m.trailing_zeros() as usize;
        m &= m - 1;
        if slot != usize::MAX {
            // SAFETY: the CPU has SSSE3; `s0 + e` is a delimiter with 16 readable bytes after.
            match unsafe { plain_field_ssse3(text, s0 + a, s0 + e) } {
                Some(x) => d[slot] = x,
                None => return false,
            }
            filled += 1;
        }
        fields.push((s0 + a, s0 + e));
        a = e + 1;
    }
    filled == d.len()
}

/// Byte shuffles of [`short_decimal_ssse3`], by integer length (0–7) and fraction length
/// (0–8): the `i + f` digits right-aligned in 16 bytes, the point (at byte `i`) skipped,
/// zeros (index with the high bit set) in front.
#[cfg(target_arch = "x86_64")]
pub(super) static DIGIT_SHUFFLE: [[[u8; 16]; 9]; 8] = {
    let mut t = [[[0x80u8; 16]; 9]; 8];
    let mut i = 0;
    while i < 8 {
        let mut f = 0;
        while f < 9 {
            let total = i + f;
            if total <= 15 {
                let mut j = 16 - total;
                while j < 16 {
                    let idx = j - (16 - total);
                    t[i][f][j] = if idx < i { idx as u8 } else { (idx + 1) as u8 };
                    j += 1;
                }
            }
            f += 1;
        }
        i += 1;
    }
    t
};

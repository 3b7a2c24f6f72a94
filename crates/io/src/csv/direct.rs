//! The direct readers' row loop: [`direct_rows`] and [`direct_streams`] cut the text into
//! segments after line ends and parse them in parallel; [`parse_segment_best`] is the one place
//! that picks the instruction set for a segment (the SSSE3 copy of the loop in [`super::x86`],
//! else the portable one), and [`row_fast`] the one fast walk of a general row. Numbers go
//! through [`number_prefix`] (the SWAR short decimal of [`super::swar`], else the general
//! parser).

use super::*;

/// Parse columns `idx` of the data rows in `data` (the text after the header line) into one
/// `[f64; K]` per row, in parallel segments cut after line ends. Blank lines and `#` lines are
/// skipped as [`index_rows`] skips them. `None` at the first row the fused fast path does not
/// take (or a non-ASCII or too long line): the caller then takes the general path.
/// The output is sized once by the line count (a line gives at most one row); segments that
/// skipped lines are moved down afterwards.
pub(super) fn direct_rows<const K: usize>(
    data: &[u8],
    width: usize,
    idx: &[usize],
    segments: Option<(Vec<usize>, Vec<usize>, usize)>,
) -> Option<Vec<[f64; K]>> {
    direct_rows_clean::<K>(data, width, idx, segments).map(|(rows, _)| rows)
}

/// [`direct_rows`] that also tells, per segment, whether its text is known clean (see
/// [`parse_segment`]).
#[allow(clippy::type_complexity)]
pub(super) fn direct_rows_clean<const K: usize>(
    data: &[u8],
    width: usize,
    idx: &[usize],
    segments: Option<(Vec<usize>, Vec<usize>, usize)>,
) -> Option<(Vec<[f64; K]>, Vec<bool>)> {
    let slots = direct_slots(width, idx)?;
    let (bounds, lines, total) = segments.unwrap_or_else(|| direct_segments(data));
    let mut vec: Vec<[f64; K]> = Vec::with_capacity(total);
    advise_huge_pages(vec.spare_capacity_mut());
    let out = &mut vec;
    let parts = split_parts(&mut out.spare_capacity_mut()[..total], &lines);
    let filled: Option<Vec<(usize, bool)>> = parts
        .into_par_iter()
        .zip(bounds.par_windows(2))
        .map(|(dst, w)| {
            parse_segment_best::<K>(&data[w[0]..w[1]], &slots, dst.len(), |r, d| {
                dst[r].write(d);
            })
        })
        .collect();
    let (filled, clean): (Vec<usize>, Vec<bool>) = filled?.into_iter().unzip();
    // SAFETY: each segment wrote rows `0..f` of its part (`parse_segment` calls `put` for
    // consecutive rows from 0 and returns their count).
    unsafe { compact(out, &lines, &filled) };
    Some((vec, clean))
}

/// [`direct_rows`] for a time stream: column `idx[0]` into one vector, `idx[1..4]` into another
/// (the layout `truepos_latency` works on), without an intermediate row buffer.
pub(super) fn direct_streams(data: &[u8], width: usize, idx: &[usize]) -> Option<(Vec<f64>, Vec<[f64; 3]>)> {
    if idx.len() != 4 {
        return None;
    }
    let slots = direct_slots(width, idx)?;
    let (bounds, lines, total) = direct_segments(data);
    let mut t: Vec<f64> = Vec::with_capacity(total);
    let mut v: Vec<[f64; 3]> = Vec::with_capacity(total);
    advise_huge_pages(t.spare_capacity_mut());
    advise_huge_pages(v.spare_capacity_mut());
    let parts_t = split_parts(&mut t.spare_capacity_mut()[..total], &lines);
    let parts_v = split_parts(&mut v.spare_capacity_mut()[..total], &lines);
    let filled: Option<Vec<(usize, bool)>> = parts_t
        .into_par_iter()
        .zip(parts_v)
        .zip(bounds.par_windows(2))
        .map(|((dt, dv), w)| {
            parse_segment_best::<4>(&data[w[0]..w[1]], &slots, dt.len().min(dv.len()), |r, d| {
                dt[r].write(d[0]);
                dv[r].write([d[1], d[2], d[3]]);
            })
        })
        .collect();
    let filled: Vec<usize> = filled?.into_iter().map(|(n, _)| n).collect();
    // SAFETY: as in `direct_rows`, for both vectors (the same rows of each segment).
    unsafe {
        compact(&mut t, &lines, &filled);
        compact(&mut v, &lines, &filled);
    }
    Some((t, v))
}

/// Column → output slot (`usize::MAX`: not wanted) for the fused row parser; `None` when a
/// column is outside the header or wanted twice.
pub(super) fn direct_slots(width: usize, idx: &[usize]) -> Option<Vec<usize>> {
    let mut slots = vec![usize::MAX; width];
    for (j, &c) in idx.iter().enumerate() {
        if c >= width || slots[c] != usize::MAX {
            return None;
        }
        slots[c] = j;
    }
    Some(slots)
}

/// Segment bounds of `data` (cut after line ends), the line count of each segment (a last line
/// without `\n` counts too: an upper bound of its rows) and their total.
pub(super) fn direct_segments(data: &[u8]) -> (Vec<usize>, Vec<usize>, usize) {
    let bounds = line_segments(data, 1 << 20);
    let lines: Vec<usize> = bounds.par_windows(2).map(|w| segment_lines(&data[w[0]..w[1]])).collect();
    let total = lines.iter().sum();
    (bounds, lines, total)
}

/// Lines of a segment: its `\n`s, and a last line without one.
pub(super) fn segment_lines(seg: &[u8]) -> usize {
    memchr::memchr_iter(b'\n', seg).count() + usize::from(seg.last().is_some_and(|&b| b != b'\n'))
}

/// Segments of a whole text cut after line ends ([`line_segments`]) with the line count of
/// each ([`segment_lines`]).
pub(super) struct Segments {
    pub(super) bounds: Vec<usize>,
    pub(super) lines: Vec<usize>,
}

impl Segments {
    /// The segments of `bytes[from..]` (`from` at a line start), as [`direct_segments`] gives
    /// them: bounds relative to `from`, line counts, total. The segment holding `from` loses the
    /// lines before it; segments before it are left out.
    pub(super) fn after(&self, bytes: &[u8], from: usize) -> (Vec<usize>, Vec<usize>, usize) {
        let mut bounds = vec![0];
        let mut lines = Vec::with_capacity(self.lines.len());
        for (w, &n) in self.bounds.windows(2).zip(&self.lines) {
            if w[1] <= from {
                continue;
            }
            let before = if w[0] < from { memchr::memchr_iter(b'\n', &bytes[w[0]..from]).count() } else { 0 };
            bounds.push(w[1] - from);
            lines.push(n - before);
        }
        let total = lines.iter().sum();
        (bounds, lines, total)
    }
}

/// `buf` cut into consecutive parts of `lines[k]` slots each.
pub(super) fn split_parts<'a, T>(mut buf: &'a mut [T], lines: &[usize]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(lines.len());
    for &n in lines {
        let (a, b) = buf.split_at_mut(n);
        parts.push(a);
        buf = b;
    }
    parts
}

/// Move the rows of each segment down to follow the previous segment's and set the length:
/// segment `k` owns slots `Σ lines[..k] ..` of `out`'s capacity and wrote `filled[k]` of them.
///
/// # Safety
/// `out` has capacity `Σ lines`, its length is 0, and segment `k` initialised the first
/// `filled[k] ≤ lines[k]` slots of its part.
pub(super) unsafe fn compact<T>(out: &mut Vec<T>, lines: &[usize], filled: &[usize]) {
    let mut at = 0;
    let mut from = 0;
    let base = out.as_mut_ptr();
    for (&n, &f) in lines.iter().zip(filled) {
        if at != from {
            // SAFETY: `from..from + f` (written by its segment) and `at..at + f` (`at <= from`)
            // are within the capacity; `ptr::copy` allows overlap.
            unsafe { std::ptr::copy(base.add(from), base.add(at), f) };
        }
        at += f;
        from += n;
    }
    // SAFETY: the first `at` slots were written and moved to follow each other.
    unsafe { out.set_len(at) };
}

/// Ask the kernel for transparent huge pages for a large output buffer about to be written
/// whole (Linux; THP in `madvise` mode): a few faults of 2 MiB instead of one per 4 KiB page.
/// Only a hint: nothing changes if it is refused.
pub(super) fn advise_huge_pages<T>(buf: &mut [std::mem::MaybeUninit<T>]) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let start = buf.as_mut_ptr() as usize;
        let end = start + std::mem::size_of_val(buf);
        let a = start.next_multiple_of(HUGE);
        if end > a + HUGE {
            let len = (end - a) / HUGE * HUGE;
            // SAFETY: `a..a + len` lies inside `buf`'s allocation; MADV_HUGEPAGE changes no
            // contents, only how the (not yet touched) pages are backed.
            unsafe { libc::madvise(a as *mut libc::c_void, len, libc::MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = buf;
}

/// Parse the rows of one segment (whole lines), handing row `r` (0, 1, …, below `cap`) to
/// `put`; the number of rows, or `None` at a line the fast path does not take (or a row `cap`).
/// With it, whether every byte of the segment is known to be ASCII other than NUL (`clean`): the
/// plain rows are (they hold only digits, signs, points, commas and line ends), and the other
/// lines are looked at as they are passed; a clean segment needs no text check.
///
/// Where the CPU has SSSE3 (every x86-64 since 2006-2011; checked at run time) the segment is
/// parsed by a copy of this loop compiled for it ([`parse_segment_ssse3`]), whose plain rows
/// convert each number with a few vector instructions ([`short_decimal_ssse3`]).
#[inline(always)]
pub(super) fn parse_segment_best<const K: usize>(
    seg: &[u8],
    slots: &[usize],
    cap: usize,
    put: impl FnMut(usize, [f64; K]),
) -> Option<(usize, bool)> {
    #[cfg(target_arch = "x86_64")]
    if cpu_has_ssse3() {
        // SAFETY: the CPU has SSSE3 (checked just above).
        return unsafe { parse_segment_ssse3::<K>(seg, slots, cap, put) };
    }
    parse_segment::<K, false>(seg, slots, cap, put)
}

/// The row loop behind [`parse_segment_best`]; `SSSE3`: plain rows by [`short_decimal_ssse3`]
/// (only inside a function compiled with SSSE3).
#[inline(always)]
pub(super) fn parse_segment<const K: usize, const SSSE3: bool>(
    seg: &[u8],
    slots: &[usize],
    cap: usize,
    mut put: impl FnMut(usize, [f64; K]),
) -> Option<(usize, bool)> {
    let mut pos = 0;
    let mut r = 0;
    let mut clean = true;
    // The wanted columns are the row's columns in order (`x_mm,y_mm,z_mm` for points): rows
    // of plain numbers take the short path first.
    let in_order = slots.len() == K && slots.iter().enumerate().all(|(c, &s)| s == c);
    // Rows before the indexed run ([`plain_rows_ssse3`]) is tried again after it stopped at
    // its first row (a file whose rows are never plain, e.g. with `\r\n` line ends, pays the
    // attempt only once in a while).
    #[cfg(target_arch = "x86_64")]
    let mut indexed_after = 0;
    while pos < seg.len() {
        #[cfg(target_arch = "x86_64")]
        if SSSE3 && in_order && r < cap && r >= indexed_after {
            // SAFETY: with `SSSE3` the caller runs on a CPU with SSSE3 (see `parse_segment_best`).
            let (n, p) = unsafe { plain_rows_ssse3::<K>(seg, pos, cap - r, |i, d| put(r + i, d)) };
            r += n;
            pos = p;
            if n == 0 {
                indexed_after = r + 64;
            }
            if pos >= seg.len() || r >= cap {
                continue;
            }
        }
        if in_order && r < cap {
            if let Some((d, used)) = parse_row_plain::<K, SSSE3>(&seg[pos..]) {
                put(r, d);
                r += 1;
                pos += used + 1;
                continue;
            }
        }
        let mut i = pos;
        while i < seg.len() && matches!(seg[i], b' ' | b'\t' | b'\r' | 0x0b | 0x0c) {
            i += 1;
        }
        if i == seg.len() || seg[i] == b'\n' || seg[i] == b'#' || seg[i] >= 0x80 {
            // Blank, comment or non-ASCII start: find the end and check the limit.
            if i < seg.len() && seg[i] >= 0x80 {
                return None;
            }
            let end = memchr::memchr(b'\n', &seg[i..]).map_or(seg.len(), |p| i + p);
            if end - pos > crate::limits::MAX_LINE_BYTES {
                return None;
            }
            clean &= ascii_text(&seg[pos..end]);
            pos = end + 1;
            continue;
        }
        let mut d = [0.0; K];
        let used = parse_row_fast_len(&seg[pos..], slots, &mut d)?;
        if r >= cap {
            return None;
        }
        put(r, d);
        if used > crate::limits::MAX_LINE_BYTES {
            return None;
        }
        clean &= ascii_text(&seg[pos..pos + used]);
        r += 1;
        pos += used + 1;
    }
    Some((r, clean))
}

/// Every byte ASCII and none NUL: text that needs no UTF-8 or binary check.
pub(super) fn ascii_text(b: &[u8]) -> bool {
    b.iter().all(|&c| c != 0 && c < 0x80)
}

/// The most common row, `K` short decimals (see [`short_decimal_prefix`]) separated by single
/// commas and ended by `\n`, nothing else (no spaces, no `\r`, no other column): its values
/// and the offset of its `\n`, exactly what [`parse_row_fast_len`] gives for it when the `K`
/// columns are all wanted in order, with none of its per-field generality. `None` for any
/// other row (the caller then takes the general row parser).
/// `SSSE3`: the numbers by [`short_decimal_ssse3`] (the caller is compiled with SSSE3 and runs
/// on a CPU that has it).
#[inline(always)]
pub(super) fn parse_row_plain<const K: usize, const SSSE3: bool>(text: &[u8]) -> Option<([f64; K], usize)> {
    let mut d = [0.0; K];
    let mut i = 0;
    for (k, v) in d.iter_mut().enumerate() {
        if text.len() - i < SHORT_DECIMAL_READ {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        let (x, used) = if SSSE3 {
            // SAFETY: with `SSSE3` the caller runs on a CPU with SSSE3 (see `parse_segment_best`).
            unsafe { short_decimal_ssse3(&text[i..]) }?
        } else {
            short_decimal_prefix(&text[i..])?
        };
        #[cfg(not(target_arch = "x86_64"))]
        let (x, used) = short_decimal_prefix(&text[i..])?;
        *v = x;
        i += used;
        if text[i] != if k + 1 < K { b',' } else { b'\n' } {
            return None;
        }
        i += 1;
    }
    Some((d, i - 1))
}

/// One pass over a quote-free row: wanted columns are parsed while the row is split. `text`
/// starts at the row and may go on past it: the row ends at `\n`, `\r\n` or the end of `text`.
/// Returns `false` on anything else (quotes, bad text, a wrong field count, a column wanted
/// twice), and the caller then takes the general path, which also produces the error message.
#[inline]
pub(super) fn parse_row_fast(text: &[u8], slots: &[usize], d: &mut [f64]) -> bool {
    parse_row_fast_len(text, slots, d).is_some()
}

/// [`parse_row_fast`] that also tells where the row ends: the offset of its `\n` (or the end
/// of `text`), i.e. the length of the line with its `\r` if any. Inlined into every row loop
/// (the points' and the streams' readers each get their own copy, with the number parser in it).
#[inline(always)]
pub(super) fn parse_row_fast_len(text: &[u8], slots: &[usize], d: &mut [f64]) -> Option<usize> {
    row_fast(text, slots, d, |_, _| {})
}

/// The one fast row walk behind [`parse_row_fast_len`] and [`split_parse_row_fast`]: wanted
/// columns (`slots`) are parsed where they start, without a scan for their end first; only the
/// other fields are walked byte by byte. `field(start, end)` receives every field's range in
/// `text` (spaces and tabs trimmed, a row-ending `\r` left out); a no-op closure costs nothing.
/// Returns the offset of the row's `\n` (or the end of `text`), or `None` at anything the
/// general path must decide: a quote, a value that is not a plain number, a ragged row.
#[inline(always)]
pub(super) fn row_fast(
    text: &[u8],
    slots: &[usize],
    d: &mut [f64],
    mut field: impl FnMut(usize, usize),
) -> Option<usize> {
    let n = text.len();
    let line_end =
        |i: usize| i >= n || text[i] == b'\n' || (text[i] == b'\r' && (i + 1 >= n || text[i + 1] == b'\n'));
    let mut i = 0;
    let mut filled = 0;
    for (col, &slot) in slots.iter().enumerate() {
        if col > 0 {
            // The previous field ended at a comma.
            if i >= n || text[i] != b',' {
                return None;
            }
            i += 1;
        }
        while i < n && (text[i] == b' ' || text[i] == b'\t') {
            i += 1;
        }
        let a = i;
        let e;
        if slot == usize::MAX {
            while i < n && text[i] != b',' && text[i] != b'\n' {
                if text[i] == b'"' {
                    return None;
                }
                i += 1;
            }
            let mut end = i;
            if end > a && text[end - 1] == b'\r' && (i >= n || text[i] == b'\n') {
                end -= 1;
            }
            while end > a && (text[end - 1] == b' ' || text[end - 1] == b'\t') {
                end -= 1;
            }
            e = end;
        } else {
            let (v, used) = number_prefix(&text[i..])?;
            i += used;
            e = i;
            while i < n && (text[i] == b' ' || text[i] == b'\t') {
                i += 1;
            }
            if !line_end(i) && text[i] != b',' {
                return None;
            }
            d[slot] = v;
            filled += 1;
        }
        field(a, e);
    }
    if !line_end(i) || filled != d.len() {
        return None;
    }
    Some(if i < n && text[i] == b'\r' { i + 1 } else { i })
}

/// The number at the start of `b`: [`crate::num::parse_f64_prefix`], through
/// [`short_decimal_prefix`] first where the text is long enough for its 8-byte reads.
#[inline(always)]
pub(super) fn number_prefix(b: &[u8]) -> Option<(f64, usize)> {
    if b.len() >= SHORT_DECIMAL_READ {
        if let Some(r) = short_decimal_prefix(b) {
            return Some(r);
        }
    }
    crate::num::parse_f64_prefix(b)
}

/// The fast path of [`Rows::split_and_parse_range`] for one row (`text` from the row's start,
/// `s0` its offset in the whole text): [`row_fast`] with every field's range (absolute, spaces
/// trimmed) appended to `fields`. `false` (with `fields` and `d` unspecified) at anything the
/// general path must decide.
#[inline(always)]
pub(super) fn split_parse_row_fast(
    text: &[u8],
    s0: usize,
    slots: &[usize],
    d: &mut [f64],
    fields: &mut Vec<(usize, usize)>,
) -> bool {
    row_fast(text, slots, d, |a, e| fields.push((s0 + a, s0 + e))).is_some()
}

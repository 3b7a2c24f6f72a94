//! Coordinate rewriting through a similarity transform.
//!
//! [`Program::transform`] maps every programmed position `p_old` to `new_from_old · p_old`
//! (mm; program units are converted), following the modal state. Only words whose value changes
//! at the output resolution are rewritten; a move whose new position differs on an axis the line
//! did not program gets that axis word inserted (so a transform that mixes axes makes a move carry
//! all three). Everything else — comments, line numbers, other words, spacing, blank lines, line
//! endings — is copied byte for byte.
//!
//! - Absolute moves transform as points, incremental moves as vectors (`s·R·d`), with the new
//!   increments taken as differences of rounded absolute values so no rounding drift accumulates.
//! - Arcs: I/J/K (incremental) rotate as vectors and R scales when the transform keeps the arc
//!   plane (a plane turned over swaps G2/G3, which must then be on the line); a transform that
//!   tilts the arc plane is refused with the line and column, or, with
//!   [`ArcPolicy::Linearize`], the arc is replaced by G1 chords of the exactly transformed arc
//!   whose chord error (sagitta) stays within the tolerance, output rounding included.
//! - Canned cycles (G81–G89) are transformed when the rotation keeps the Z axis; G92 is refused;
//!   G53 (machine coordinates) and G10 lines are copied unchanged.

use crate::interp::{LineScan, Modal, MotionMode, Special, NONE};
use crate::{GcodeError, Program};
use truepos_math::Transform3;

/// What to do with an arc whose plane the transform tilts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ArcPolicy {
    /// Refuse the program (an error naming the line), the default.
    #[default]
    Refuse,
    /// Replace an arc whose plane the transform tilts by straight G1 moves whose largest
    /// distance from the exact (transformed) arc is at most `tolerance_mm`.
    Linearize {
        /// Largest distance of the chords from the exact arc, mm.
        tolerance_mm: f64,
    },
}

/// How [`Program::transform`](crate::Program::transform) and [`crate::StreamTransform`] rewrite a
/// program.
#[derive(Debug, Clone)]
pub struct TransformOptions {
    /// Decimals written for rewritten values (default: 4 in mm programs, 5 in inch programs).
    pub decimals: Option<u8>,
    /// What to do with an arc whose plane the transform tilts.
    pub arc_policy: ArcPolicy,
    /// Position (mm, old frame) before the first block, if known.
    pub start_mm: Option<[f64; 3]>,
}

impl Default for TransformOptions {
    fn default() -> Self {
        Self { decimals: None, arc_policy: ArcPolicy::Refuse, start_mm: None }
    }
}

const MIX_EPS: f64 = 1e-12;
const AXES: [u8; 3] = [b'X', b'Y', b'Z'];
const CENTRE: [u8; 3] = [b'I', b'J', b'K'];

/// Replacement text of a word: inline (no allocation) up to 31 bytes, which every fixed-point
/// number below 10^15 is; longer text on the heap. Inline text is kept at the end of its
/// buffer (`buf[start..]`), where [`fmt_num`] writes its digits: no copy to build one.
#[derive(Clone)]
enum Txt {
    Inline { start: u8, buf: [u8; 31] },
    Heap(String),
}

impl Txt {
    /// Inline text from bytes that are a whole UTF-8 string (a `&str`'s bytes, or ASCII) of at
    /// most 31 bytes; the invariant [`Deref`](std::ops::Deref) relies on.
    fn inline(b: &[u8]) -> Self {
        debug_assert!(b.len() <= 31 && std::str::from_utf8(b).is_ok());
        let mut buf = [0u8; 31];
        let start = 31 - b.len();
        buf[start..].copy_from_slice(b);
        Txt::Inline { start: start as u8, buf }
    }
}

impl From<&str> for Txt {
    fn from(s: &str) -> Self {
        if s.len() <= 31 {
            Txt::inline(s.as_bytes())
        } else {
            Txt::Heap(s.to_string())
        }
    }
}

impl From<String> for Txt {
    fn from(s: String) -> Self {
        if s.len() <= 31 {
            Txt::from(s.as_str())
        } else {
            Txt::Heap(s)
        }
    }
}

impl std::ops::Deref for Txt {
    type Target = str;
    fn deref(&self) -> &str {
        match self {
            // SAFETY: `Inline` is built by `Txt::inline`, from the bytes of a whole `&str` or
            // from ASCII, and by `fmt_num`, from ASCII digits, point and sign only, so
            // `buf[start..]` is valid UTF-8 (checked in debug builds).
            Txt::Inline { start, buf } => unsafe { std::str::from_utf8_unchecked(&buf[*start as usize..]) },
            Txt::Heap(s) => s,
        }
    }
}

impl std::fmt::Display for Txt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self)
    }
}

/// Fixed-point text of `v` with `dec` decimals (no "-0.000"). Integer arithmetic: much faster
/// than float formatting, exact for |v|·10^dec below 2^53.
fn fmt_num(v: f64, dec: u8) -> Txt {
    let mut t = Txt::Inline { start: 31, buf: [0; 31] };
    fmt_num_into(v, dec, &mut t);
    t
}

/// [`fmt_num`] written into `t` where it lies (e.g. in the edit list): the digits are stored
/// once, in place, and not copied out of a buffer just written (a reload that stalls).
fn fmt_num_into(v: f64, dec: u8, t: &mut Txt) {
    const SCALE: [i64; 19] = {
        let mut t = [1i64; 19];
        let mut k = 1;
        while k < 19 {
            t[k] = t[k - 1] * 10;
            k += 1;
        }
        t
    };
    let Some(&scale) = SCALE.get(dec as usize) else {
        *t = Txt::from(format!("{:.*}", dec as usize, v));
        return;
    };
    let scaled = round(v * scale as f64);
    if !scaled.is_finite() || scaled.abs() >= 9.0e15 {
        *t = Txt::from(format!("{:.*}", dec as usize, v));
        return;
    }
    let n = scaled as i64;
    if !matches!(t, Txt::Inline { .. }) {
        *t = Txt::Inline { start: 31, buf: [0; 31] };
    }
    let Txt::Inline { start, buf } = t else { return };
    let mut i = truepos_math::fixed::digits(n.unsigned_abs(), dec, buf);
    if n < 0 {
        i -= 1;
        buf[i] = b'-';
    }
    // ASCII digits, point and sign only, at the end of the buffer (at most 18 bytes).
    debug_assert!(std::str::from_utf8(&buf[i..]).is_ok());
    *start = i as u8;
}

/// 10^dec (a table for the usual decimals: this is on every rewritten word).
#[inline]
fn pow10(dec: u8) -> f64 {
    const T: [f64; 16] =
        [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15];
    // Not inlined: `powi` may be computed ahead of the test (it has no side effects), which
    // costs a call on every line.
    #[cold]
    #[inline(never)]
    fn big(dec: u8) -> f64 {
        10f64.powi(dec as i32)
    }
    match T.get(dec as usize) {
        Some(&p) => p,
        None => big(dec),
    }
}

fn round_to(v: f64, dec: u8) -> f64 {
    let f = pow10(dec);
    round(v * f) / f
}

pub(crate) use truepos_math::fixed::round;

/// One edit of a line, at token `ti`: text inserted before it, its number replaced, or text
/// inserted after it.
struct Edit {
    /// `ti · 4 + slot` (slot 0: insert before, 1: replace, 2: insert after): sorted by it, the
    /// edits come in the order they are written.
    key: u32,
    /// Inserted word's letter (0: none; a replacement keeps the letter as written).
    letter: u8,
    /// An inserted word is set off by a space (after the token, or before the token it precedes).
    space: bool,
    /// The replacement number (empty: the word is removed) or the inserted word's value.
    text: Txt,
}

const BEFORE: u32 = 0;
const REPLACE: u32 = 1;
const AFTER: u32 = 2;

/// Edits of one line, in the order they were planned (kept from line to line: no allocation
/// per line).
#[derive(Default)]
struct Edits(Vec<Edit>);

impl Edits {
    fn push(&mut self, ti: usize, slot: u32, letter: u8, space: bool, text: Txt) {
        self.0.push(Edit { key: ti as u32 * 4 + slot, letter, space, text });
    }

    /// Replace token `ti`'s number by `v` with `dec` decimals, formatted in place in the list.
    #[inline]
    fn replace_num(&mut self, ti: usize, v: f64, dec: u8) {
        self.push(ti, REPLACE, 0, false, Txt::Inline { start: 31, buf: [0; 31] });
        if let Some(e) = self.0.last_mut() {
            fmt_num_into(v, dec, &mut e.text);
        }
    }

    /// Insert word `letter` with value `v` (`dec` decimals) at token `ti` (`slot` BEFORE or AFTER).
    #[inline]
    fn insert_num(&mut self, ti: usize, slot: u32, letter: u8, space: bool, v: f64, dec: u8) {
        self.push(ti, slot, letter, space, Txt::Inline { start: 31, buf: [0; 31] });
        if let Some(e) = self.0.last_mut() {
            fmt_num_into(v, dec, &mut e.text);
        }
    }
}

impl Program {
    /// Rewrite the program through `new_from_old` (mm). See the module docs.
    ///
    /// The first thing that cannot be executed or re-oriented, in program order, is the error
    /// (a malformed word on line 9 is reported before a refused arc on line 12, and after one on
    /// line 5). The same `Rewriter` does the work of [`crate::transform_stream`], chunk by chunk.
    pub fn transform(
        &self,
        new_from_old: &Transform3,
        opts: &TransformOptions,
    ) -> Result<String, GcodeError> {
        // Every word's value must be known (no malformed numbers, expressions evaluated): lines
        // up to the first one that fails the check are rewritten, then that check fails.
        let checked = self.check();
        let upto = match &checked {
            Ok(()) => self.lines.len(),
            Err(e) => e.line() - 1,
        };
        let mut out = String::with_capacity(self.source.len() + self.source.len() / 8);
        let mut rw = Rewriter::new(new_from_old, opts);
        rw.rewrite_lines(self, upto, &mut out)?;
        checked.map(|()| out)
    }
}

/// The rewriting state carried from line to line (and from chunk to chunk of a streamed
/// program): the modal state of the old program, the last written new-frame values and the
/// exact incremental accumulators, and how many lines came before.
pub(crate) struct Rewriter {
    new_from_old: Transform3,
    opts: TransformOptions,
    old: Modal,
    /// Last written new-frame absolute values (program units).
    written: [Option<f64>; 3],
    /// Exact new-frame increments accumulated in incremental mode.
    exact_inc: [f64; 3],
    /// An axis whose new value depends on other old axes (the transform mixes them) is written
    /// on every transformed move.
    mixes: [bool; 3],
    /// `s·R` (new from old, by axis) and which of its terms count (above [`MIX_EPS`]).
    coef: [[f64; 3]; 3],
    coef_used: [[bool; 3]; 3],
    /// Lines rewritten so far (in earlier chunks): added to the line numbers of errors.
    base: usize,
    /// The edits of the current line (kept from line to line: no allocation per line).
    edits: Edits,
}

impl Rewriter {
    pub(crate) fn new(new_from_old: &Transform3, opts: &TransformOptions) -> Self {
        let s = new_from_old.scale;
        let r = new_from_old.rotation;
        let t = new_from_old.translation;
        let mut old = Modal::default();
        let mut written: [Option<f64>; 3] = [None; 3];
        if let Some(p) = opts.start_mm {
            old.pos = [Some(p[0]), Some(p[1]), Some(p[2])];
            for (k, w) in written.iter_mut().enumerate() {
                *w = Some(s * (r.row(k) * truepos_math::Vector3::new(p[0], p[1], p[2]))[0] + t[k]);
            }
        }
        let mixes = std::array::from_fn(|k| (0..3).any(|j| j != k && (s * r[(k, j)]).abs() > MIX_EPS));
        let coef: [[f64; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|j| s * r[(k, j)]));
        let coef_used = coef.map(|row| row.map(|c| c.abs() > MIX_EPS));
        Self {
            new_from_old: *new_from_old,
            opts: opts.clone(),
            old,
            written,
            exact_inc: [0.0; 3],
            mixes,
            coef,
            coef_used,
            base: 0,
            edits: Edits::default(),
        }
    }

    /// Lines of the program done so far (rewritten, or passed over in an erroneous piece).
    pub(crate) fn lines_done(&self) -> usize {
        self.base
    }

    /// Rewrite lines `0..upto` of `p` (the next piece of the program) into `out`, then count all
    /// of `p`'s lines as done. Errors carry line numbers in the whole program.
    pub(crate) fn rewrite_lines(
        &mut self,
        p: &Program,
        upto: usize,
        out: &mut String,
    ) -> Result<(), GcodeError> {
        for i in 0..upto {
            self.line(p, i, out).map_err(|e| e.shifted(self.base))?;
        }
        self.base += p.lines.len();
        Ok(())
    }

    /// Rewrite line `i` of `p` (line numbers of errors relative to `p`).
    fn line(&mut self, p: &Program, i: usize, out: &mut String) -> Result<(), GcodeError> {
        let line = &p.lines[i];
        let toks = &p.tokens[line.tokens.clone()];
        // One pass over the tokens: the block and where its words are; `self.old` becomes the
        // state after the line (`cx.after`). The state before it is kept only where an arc may
        // be linearised (which starts from it).
        let before_units = self.old.units;
        let before = matches!(self.opts.arc_policy, ArcPolicy::Linearize { .. }).then_some(self.old);
        let sc = p.scan_tokens(toks, &mut self.old, |_| {});
        let after = self.old;
        let units_mm = after.units.mm();
        if after.units != before_units {
            let f = before_units.mm() / units_mm;
            for w in self.written.iter_mut() {
                *w = w.map(|v| v * f);
            }
        }
        let dec = self.opts.decimals.unwrap_or(if after.units == crate::Units::Inch { 5 } else { 4 });
        let cx = LineCx { p, i, toks, sc: &sc, after, dec, half: 0.5 / pow10(dec), units_mm };
        let has_axes = sc.axes.iter().any(|a| a.is_some());
        let has_centre = sc.ijk.iter().any(|a| a.is_some()) || sc.r.is_some();
        if self.special_line(&cx, has_axes, out)? {
            return Ok(());
        }
        let moving = has_axes && (after.motion != MotionMode::None || sc.special == Some(Special::Home));
        if !moving && !has_centre {
            cx.copy(out);
            return Ok(());
        }
        if moving && after.pos.iter().any(|p| p.is_none()) {
            return Err(cx.unknown_start());
        }
        let is_arc = matches!(after.motion, MotionMode::ArcCw | MotionMode::ArcCcw);
        if let (true, true, ArcPolicy::Linearize { tolerance_mm }, Some(before)) =
            (is_arc && moving, has_centre, self.opts.arc_policy, before)
        {
            let r = self.new_from_old.rotation;
            let n = after.plane.normal_axis();
            if (r[(n, n)].abs() - 1.0).abs() > MIX_EPS {
                let blk = p.interpret_line(i, &before);
                p.linearize_arc(
                    i,
                    &blk,
                    &before,
                    &self.new_from_old,
                    tolerance_mm,
                    dec,
                    &mut self.written,
                    out,
                )?;
                return Ok(());
            }
        }
        // The edits live in `self` from line to line (no allocation per line).
        let mut edits = std::mem::take(&mut self.edits);
        edits.0.clear();
        let planned = self.plan_edits(&cx, moving, has_centre && is_arc, &mut edits);
        if planned.is_ok() {
            if edits.0.is_empty() {
                cx.copy(out);
            } else {
                p.emit_line(i, &mut edits.0, out);
            }
        }
        self.edits = edits;
        planned
    }

    /// Lines that are copied as they are or refused whatever the transform: G92 (refused),
    /// machine-coordinate moves (copied; the last written values are then unknown) and data
    /// setting. `Ok(true)` when the line was handled.
    fn special_line(
        &mut self,
        cx: &LineCx<'_>,
        has_axes: bool,
        out: &mut String,
    ) -> Result<bool, GcodeError> {
        match cx.sc.special {
            Some(Special::SetPosition) => Err(cx.err(
                cx.toks.iter().find(|tk| tk.word().is_some_and(|w| w.0 == b'G' && (w.1 - 92.0).abs() < 1e-6)),
                "G92 shifts the coordinate system; a program that uses it cannot be re-oriented".into(),
            )),
            Some(Special::Machine) => {
                if has_axes {
                    self.written = [None; 3];
                }
                cx.copy(out);
                Ok(true)
            }
            Some(Special::DataSetting) => {
                cx.copy(out);
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    /// The edits of a moving line and/or an arc's centre words, in `edits`.
    fn plan_edits(
        &mut self,
        cx: &LineCx<'_>,
        moving: bool,
        arc_centre: bool,
        edits: &mut Edits,
    ) -> Result<(), GcodeError> {
        let r = self.new_from_old.rotation;
        if let MotionMode::Cycle(_) = cx.after.motion {
            if (r[(2, 2)] - 1.0).abs() > MIX_EPS || r[(0, 2)].abs() > MIX_EPS || r[(1, 2)].abs() > MIX_EPS {
                return Err(cx.err(
                    cx.word_tok(2),
                    "a canned drilling cycle cannot be re-oriented by a rotation that tilts the Z axis"
                        .into(),
                ));
            }
        }
        let ins = InsertAt::of(cx.sc);
        if moving {
            if cx.after.absolute {
                self.move_absolute(cx, &ins, edits)?;
            } else {
                self.move_incremental(cx, &ins, edits);
            }
            self.cycle_r_plane(cx, edits);
        }
        if arc_centre {
            self.arc_centre(cx, &ins, edits)?;
        }
        Ok(())
    }

    /// The axis words of an absolute move: the new values from the whole old position,
    /// written where they change (or where the transform mixes axes).
    fn move_absolute(
        &mut self,
        cx: &LineCx<'_>,
        ins: &InsertAt,
        edits: &mut Edits,
    ) -> Result<(), GcodeError> {
        let t = self.new_from_old.translation;
        let sc = cx.sc;
        // New values per axis (program units) for the axis words.
        let mut new_vals: [Option<f64>; 3] = [None; 3];
        let pos = cx.after.pos;
        for k in 0..3 {
            let mut acc = t[k] / cx.units_mm;
            let mut known = true;
            for j in 0..3 {
                if self.coef_used[k][j] {
                    match pos[j] {
                        Some(v) => acc += self.coef[k][j] * v,
                        None => known = false,
                    }
                }
            }
            if known {
                // Exact: compared with the written value before any rounding, so a
                // value the transform leaves alone is never rewritten, however large.
                new_vals[k] = Some(acc);
            } else if sc.axes[k].is_some() {
                let missing = (0..3).find(|&j| pos[j].is_none() && self.coef_used[k][j]).unwrap_or(k);
                return Err(cx.err(cx.word_tok(k), format!("the {} position is not known before this move (give it earlier in the program, or a start position)", AXES[missing] as char)));
            }
        }
        let (dec, half) = (cx.dec, cx.half);
        for k in 0..3 {
            let Some(v) = new_vals[k] else { continue };
            match (sc.axes[k], cx.word_at(k)) {
                (Some(orig), Some(ti)) => {
                    if (v - orig).abs() >= half {
                        edits.replace_num(ti, v, dec);
                        self.written[k] = Some(round_to(v, dec));
                    } else {
                        self.written[k] = Some(orig);
                    }
                }
                _ => {
                    if self.mixes[k] || self.written[k].is_none_or(|w| (w - v).abs() >= half) {
                        ins.plan(edits, k, &AXES, v, dec);
                        self.written[k] = Some(round_to(v, dec));
                    }
                }
            }
        }
        Ok(())
    }

    /// The axis words of an incremental move: exact new-frame increments accumulated, each
    /// written increment the difference of the rounded accumulators (no drift).
    fn move_incremental(&mut self, cx: &LineCx<'_>, ins: &InsertAt, edits: &mut Edits) {
        let s = self.new_from_old.scale;
        let r = self.new_from_old.rotation;
        let (dec, half) = (cx.dec, cx.half);
        let d = cx.sc.axes.map(|a| a.unwrap_or(0.0));
        for k in 0..3 {
            let dn = s * (r[(k, 0)] * d[0] + r[(k, 1)] * d[1] + r[(k, 2)] * d[2]);
            let before = self.exact_inc[k];
            self.exact_inc[k] += dn;
            let inc = round_to(self.exact_inc[k], dec) - round_to(before, dec);
            let inc = round_to(inc, dec);
            match (cx.sc.axes[k], cx.word_at(k)) {
                (Some(orig), Some(ti)) => {
                    // Unchanged by the transform (to the resolution, before rounding):
                    // keep the text.
                    if (dn - orig).abs() >= half && (inc - orig).abs() >= half {
                        edits.replace_num(ti, inc, dec);
                    }
                }
                _ => {
                    if self.mixes[k] || inc.abs() >= half {
                        ins.plan(edits, k, &AXES, inc, dec);
                    }
                }
            }
            self.written[k] = self.written[k].map(|w| w + inc);
        }
    }

    /// A canned cycle's R plane: a Z level, scaled and (in absolute mode) shifted.
    fn cycle_r_plane(&self, cx: &LineCx<'_>, edits: &mut Edits) {
        let s = self.new_from_old.scale;
        let t = self.new_from_old.translation;
        if let (MotionMode::Cycle(_), Some(rv)) = (cx.after.motion, cx.sc.r) {
            if let Some(ti) = cx.word_at(6) {
                let nv = if cx.after.absolute { s * rv + t[2] / cx.units_mm } else { s * rv };
                if (nv - rv).abs() >= cx.half {
                    edits.replace_num(ti, nv, cx.dec);
                }
            }
        }
    }

    /// An arc's centre words (I, J, K or R) and its direction (G2/G3 swap when the transform
    /// turns the arc plane over); refused when the transform tilts the plane.
    fn arc_centre(&self, cx: &LineCx<'_>, ins: &InsertAt, edits: &mut Edits) -> Result<(), GcodeError> {
        let s = self.new_from_old.scale;
        let r = self.new_from_old.rotation;
        let t = self.new_from_old.translation;
        let (sc, after, toks) = (cx.sc, &cx.after, cx.toks);
        let (dec, half) = (cx.dec, cx.half);
        let n = after.plane.normal_axis();
        let rn = r[(n, n)];
        if (rn.abs() - 1.0).abs() > MIX_EPS {
            let tok = cx.word_at(3 + (n + 1) % 3).or_else(|| cx.word_at(6)).map(|x| &toks[x]);
            return Err(cx.err(tok, format!("this arc lies in the {:?} plane and the transform tilts that plane; arcs can only be re-oriented by rotations that keep their plane", after.plane)));
        }
        if rn < 0.0 {
            // The plane is turned over: clockwise becomes counter-clockwise.
            if sc.arc_g == NONE {
                return Err(cx.err(None, "the transform turns the arc plane over, which swaps G2 and G3, but the arc's G2/G3 word is modal (not on this line)".into()));
            }
            let gi = sc.arc_g as usize;
            let txt = cx.p.text(&toks[gi]);
            let swapped: String = txt
                .chars()
                .map(|c| match c {
                    '2' => '3',
                    '3' => '2',
                    c => c,
                })
                .collect();
            edits.push(gi, REPLACE, 0, false, Txt::from(&swapped[1..]));
        }
        let v = sc.ijk.map(|a| a.unwrap_or(0.0));
        if sc.ijk.iter().any(|x| x.is_some()) {
            for k in 0..3 {
                if k == n {
                    continue;
                }
                let mut nv = s * (r[(k, 0)] * v[0] + r[(k, 1)] * v[1] + r[(k, 2)] * v[2]);
                if after.arc_absolute {
                    nv += t[k] / cx.units_mm;
                }
                match (sc.ijk[k], cx.word_at(3 + k)) {
                    (Some(orig), Some(ti)) => {
                        if (nv - orig).abs() >= half {
                            edits.replace_num(ti, nv, dec);
                        }
                    }
                    _ => {
                        if nv.abs() >= half {
                            ins.plan(edits, k, &CENTRE, nv, dec);
                        }
                    }
                }
            }
        }
        if let (Some(rv), Some(ti)) = (sc.r, cx.word_at(6)) {
            let nv = s * rv;
            if (nv - rv).abs() >= half {
                edits.replace_num(ti, nv, dec);
            }
        }
        Ok(())
    }
}

/// What the steps of [`Rewriter::line`] share about the line being rewritten.
struct LineCx<'a> {
    p: &'a Program,
    /// Line index in `p`.
    i: usize,
    toks: &'a [crate::Token],
    sc: &'a LineScan,
    /// The modal state after the line.
    after: Modal,
    /// Decimals written, and half their resolution (a change below it is no change).
    dec: u8,
    half: f64,
    /// Millimetres per program unit.
    units_mm: f64,
}

impl<'a> LineCx<'a> {
    /// Copy the line as it is.
    fn copy(&self, out: &mut String) {
        let line = &self.p.lines[self.i];
        out.push_str(&self.p.source[line.start..line.next]);
    }

    /// An "unsupported" error at `tok` (column 1 without one).
    fn err(&self, tok: Option<&crate::Token>, message: String) -> GcodeError {
        GcodeError::Unsupported {
            line: self.i + 1,
            column: tok.map_or(1, |tk| self.p.column_of(self.i, tk)),
            message,
        }
    }

    /// The first token of word X, Y, Z, I, J, K, R (k = 0..7), if on the line.
    fn word_at(&self, k: usize) -> Option<usize> {
        (self.sc.first[k] != NONE).then_some(self.sc.first[k] as usize)
    }

    /// The token of [`Self::word_at`].
    fn word_tok(&self, k: usize) -> Option<&'a crate::Token> {
        self.word_at(k).map(|x| &self.toks[x])
    }

    /// The error for a move whose start position is not known on an axis it does not give.
    fn unknown_start(&self) -> GcodeError {
        // The machine's position on an axis the move does not give is unknown: the
        // transformed move could not say where it goes (contract: a start position).
        let (sc, after) = (self.sc, &self.after);
        let given: String = (0..3).filter(|&k| sc.axes[k].is_some()).map(|k| AXES[k] as char).collect();
        let missing: Vec<String> =
            (0..3).filter(|&k| after.pos[k].is_none()).map(|k| (AXES[k] as char).to_string()).collect();
        let first = (0..3).find_map(|k| self.word_at(k)).map(|x| &self.toks[x]);
        self.err(
            first,
            format!(
                "this motion gives only {given} and the {} position before it is not known (give it \
                 earlier in the program, or the start position: orient --start-mm X,Y,Z in the \
                 program's coordinates)",
                missing.join(", ")
            ),
        )
    }
}

/// Where an inserted word goes on a line: next to the other words of its group (see
/// [`InsertAt::plan`]), from the positions of the line's words.
struct InsertAt {
    /// First token of X, Y, Z, I, J, K ([`NONE`]: absent).
    first: [u32; 6],
    spaced: bool,
    /// Last word of the line, or token 0.
    last_word: usize,
}

impl InsertAt {
    fn of(sc: &LineScan) -> Self {
        let mut first = [NONE; 6];
        first.copy_from_slice(&sc.first[..6]);
        let last_word = if sc.last_word == NONE { 0 } else { sc.last_word as usize };
        Self { first, spaced: sc.spaced, last_word }
    }

    fn find(&self, letters: &[u8; 3], j: usize) -> Option<usize> {
        let base = if letters[0] == b'X' { 0 } else { 3 };
        let f = self.first[base + j];
        (f != NONE).then_some(f as usize)
    }

    /// Plan the insertion of word `letters[k]` with value `v` (`dec` decimals) next to the
    /// other words of its group: after the nearest one before it in X, Y, Z (I, J, K) order,
    /// else before the nearest one after it; centre words with no other centre word go after
    /// the last axis word (by letter), and otherwise after the last word of the line.
    fn plan(&self, edits: &mut Edits, k: usize, letters: &[u8; 3], v: f64, dec: u8) {
        let (letter, sp) = (letters[k], self.spaced);
        if let Some(ti) = (0..k).rev().find_map(|j| self.find(letters, j)) {
            edits.insert_num(ti, AFTER, letter, sp, v, dec);
        } else if let Some(ti) = (k + 1..3).find_map(|j| self.find(letters, j)) {
            edits.insert_num(ti, BEFORE, letter, sp, v, dec);
        } else if let Some(ti) = (0..3).find_map(|j| self.find(&AXES, j)) {
            // Centre words with no other centre word: after the last axis word.
            let last = (0..3).rev().find_map(|j| self.find(&AXES, j)).unwrap_or(ti);
            edits.insert_num(last, AFTER, letter, sp, v, dec);
        } else {
            edits.insert_num(self.last_word, AFTER, letter, sp, v, dec);
        }
    }
}

/// An arc block in its plane (mm): axes (a, b) with a × b = +normal (G17 X, Y; G18 Z, X; G19
/// Y, Z), the centre (a, b), the start and end radii, the start angle and the signed sweep (rad,
/// > 0 counter-clockwise).
struct PlaneArc {
    n: usize,
    ia: usize,
    ib: usize,
    ca: f64,
    cb: f64,
    r0: f64,
    r1: f64,
    th0: f64,
    sweep: f64,
}

impl PlaneArc {
    /// The arc of `blk` from `start` to `end` (mm; `u` mm per program unit); an arc that does
    /// not exist is the letter to blame and why.
    fn of(
        blk: &crate::Block<'_>,
        u: f64,
        start: &[f64],
        end: &[f64],
    ) -> Result<PlaneArc, (Option<u8>, String)> {
        // Plane axes (a, b) with a × b = +normal: G17 (X, Y), G18 (Z, X), G19 (Y, Z).
        let n = blk.after.plane.normal_axis();
        let (ia, ib) = ((n + 1) % 3, (n + 2) % 3);
        let ccw = blk.after.motion == MotionMode::ArcCcw;
        let (sa, sb, ea, eb) = (start[ia], start[ib], end[ia], end[ib]);
        let (ca, cb) = if blk.ijk.iter().any(|v| v.is_some()) {
            let off = |k: usize| blk.ijk[k].unwrap_or(0.0) * u;
            if blk.after.arc_absolute {
                (off(ia), off(ib))
            } else {
                (sa + off(ia), sb + off(ib))
            }
        } else if let Some(rr) = blk.r {
            // Radius form: the centre on the perpendicular bisector; R < 0 takes the long way.
            let rr = rr * u;
            let (dx, dy) = (ea - sa, eb - sb);
            let d = dx.hypot(dy);
            if d <= 0.0 || d > 2.0 * rr.abs() * (1.0 + 1e-9) {
                return Err((Some(b'R'), format!("no arc of radius {} joins the start and the end", rr / u)));
            }
            let h = (rr * rr - 0.25 * d * d).max(0.0).sqrt();
            // Left of the chord for a counter-clockwise short arc.
            let side = if ccw == (rr > 0.0) { 1.0 } else { -1.0 };
            (0.5 * (sa + ea) - side * h * dy / d, 0.5 * (sb + eb) + side * h * dx / d)
        } else {
            return Err((None, "an arc needs I/J/K or R".into()));
        };
        let r0 = (sa - ca).hypot(sb - cb);
        let r1 = (ea - ca).hypot(eb - cb);
        if r0 <= 0.0 || r1 <= 0.0 {
            return Err((None, "the arc has zero radius".into()));
        }
        let th0 = (sb - cb).atan2(sa - ca);
        let mut sweep = (eb - cb).atan2(ea - ca) - th0;
        let tau = std::f64::consts::TAU;
        if ccw {
            while sweep <= 1e-12 {
                sweep += tau;
            }
        } else {
            while sweep >= -1e-12 {
                sweep -= tau;
            }
        }
        Ok(PlaneArc { n, ia, ib, ca, cb, r0, r1, th0, sweep })
    }
}

impl Program {
    /// Replace arc block `blk` (line `i`) by G1 chords of the transformed arc (see
    /// [`ArcPolicy::Linearize`]): the intermediate points on lines of their own before the
    /// block, the end point on the block's own line (G2/G3 becomes G1, I/J/K/R are removed, a
    /// feed word moves to the first chord so the whole arc runs at it).
    #[allow(clippy::too_many_arguments)]
    fn linearize_arc(
        &self,
        i: usize,
        blk: &crate::Block<'_>,
        old: &Modal,
        new_from_old: &Transform3,
        tolerance_mm: f64,
        dec: u8,
        written: &mut [Option<f64>; 3],
        out: &mut String,
    ) -> Result<(), GcodeError> {
        let line = &self.lines[i];
        let toks = &self.tokens[line.tokens.clone()];
        let find = |letter: u8| toks.iter().position(|tk| tk.word().is_some_and(|w| w.0 == letter));
        let err = |letter: Option<u8>, message: String| GcodeError::Unsupported {
            line: i + 1,
            column: letter.and_then(&find).map_or(1, |k| self.column_of(i, &toks[k])),
            message,
        };
        if !(tolerance_mm.is_finite() && tolerance_mm > 0.0) {
            return Err(err(
                None,
                format!("arc tolerance must be a positive number of mm, got {tolerance_mm}"),
            ));
        }
        if !blk.after.absolute {
            return Err(err(
                Some(b'G'),
                "linearising an arc in incremental mode (G91) is not supported".into(),
            ));
        }
        let u = blk.after.units.mm();
        let (Some(start), Some(end)) = (
            old.pos.iter().map(|v| v.map(|x| x * u)).collect::<Option<Vec<f64>>>(),
            blk.after.pos.iter().map(|v| v.map(|x| x * u)).collect::<Option<Vec<f64>>>(),
        ) else {
            return Err(err(
                None,
                "the arc's start position is not known (give it earlier, or a start position)".into(),
            ));
        };
        let arc = PlaneArc::of(blk, u, &start, &end).map_err(|(letter, m)| err(letter, m))?;
        let PlaneArc { n, ia, ib, ca, cb, r0, r1, th0, sweep } = arc;
        // Chord error of a step φ on radius ρ: ρ(1 − cos(φ/2)). Output rounding moves each point
        // by at most half a unit of the last decimal per axis (√3/2 of it in space).
        let round_err = 0.5 * 3f64.sqrt() * 10f64.powi(-(dec as i32)) * u;
        let budget = tolerance_mm - round_err;
        if budget <= 0.0 {
            return Err(err(None, format!("an arc tolerance of {tolerance_mm} mm is below the output resolution; write more decimals")));
        }
        let rho = r0.max(r1);
        let phi = if budget >= rho { std::f64::consts::PI } else { 2.0 * (1.0 - budget / rho).acos() };
        let steps = ((sweep.abs() / phi).ceil() as usize).max(1);
        if steps > 1_000_000 {
            return Err(err(
                None,
                format!("linearising this arc within {tolerance_mm} mm would take {steps} moves"),
            ));
        }
        let point = |k: usize| -> truepos_math::Point3 {
            let f = k as f64 / steps as f64;
            let th = th0 + sweep * f;
            let rad = r0 + (r1 - r0) * f;
            let mut p = [0.0; 3];
            p[ia] = ca + rad * th.cos();
            p[ib] = cb + rad * th.sin();
            p[n] = start[n] + (end[n] - start[n]) * f;
            new_from_old.apply(&truepos_math::Point3::new(p[0], p[1], p[2]))
        };
        let eol = &self.source[line.end..line.next];
        let eol = if eol.is_empty() { "\n" } else { eol };
        let feed = find(b'F').map(|k| self.text(&toks[k]).to_string());
        let fmt_point = |q: &truepos_math::Point3| {
            format!("X{} Y{} Z{}", fmt_num(q.x / u, dec), fmt_num(q.y / u, dec), fmt_num(q.z / u, dec))
        };
        for k in 1..steps {
            let q = point(k);
            out.push_str("G1 ");
            out.push_str(&fmt_point(&q));
            if k == 1 {
                if let Some(fw) = &feed {
                    out.push(' ');
                    out.push_str(fw);
                }
            }
            out.push_str(eol);
        }
        self.rewrite_arc_block(i, old, &point(steps), u, dec, written, out);
        Ok(())
    }

    /// The arc block's own line: G2/G3 → G1, centre words removed, the end point `q` (mm)
    /// written in the block's units.
    #[allow(clippy::too_many_arguments)]
    fn rewrite_arc_block(
        &self,
        i: usize,
        old: &Modal,
        q: &truepos_math::Point3,
        u: f64,
        dec: u8,
        written: &mut [Option<f64>; 3],
        out: &mut String,
    ) {
        let toks = &self.tokens[self.lines[i].tokens.clone()];
        let find = |letter: u8| toks.iter().position(|tk| tk.word().is_some_and(|w| w.0 == letter));
        let mut edits = Edits::default();
        let g = toks.iter().position(|tk| {
            tk.word().is_some_and(|w| w.0 == b'G' && ((w.1 - 2.0).abs() < 1e-6 || (w.1 - 3.0).abs() < 1e-6))
        });
        for letter in [b'I', b'J', b'K', b'R'] {
            if let Some(k) = find(letter) {
                edits.push(k, REPLACE, 0, false, Txt::from(""));
            }
        }
        let mut state = *old;
        let ins = InsertAt::of(&self.scan_tokens(toks, &mut state, |_| {}));
        let axis_pos: Vec<usize> = (0..3).filter_map(|k| find(AXES[k])).collect();
        for (k, letter) in AXES.iter().enumerate() {
            let v = [q.x, q.y, q.z][k] / u;
            match find(*letter) {
                Some(ti) => edits.replace_num(ti, v, dec),
                None => ins.plan(&mut edits, k, &AXES, v, dec),
            }
            written[k] = Some(round_to(v, dec));
        }
        match g {
            Some(gi) => edits.push(gi, REPLACE, 0, false, Txt::from("1")),
            None => {
                let first = axis_pos.first().copied().unwrap_or(0);
                edits.push(first, BEFORE, 0, false, Txt::from("G1 "));
            }
        }
        self.emit_line(i, &mut edits.0, out);
    }

    /// Write line `i` with `edits` applied (sorted here into the order of the line); the text
    /// between edited tokens is copied as it is.
    fn emit_line(&self, i: usize, edits: &mut [Edit], out: &mut String) {
        // A handful of edits: a stable insertion sort (inserts at one place keep their order).
        for a in 1..edits.len() {
            let mut b = a;
            while b > 0 && edits[b - 1].key > edits[b].key {
                edits.swap(b - 1, b);
                b -= 1;
            }
        }
        let line = &self.lines[i];
        let toks = &self.tokens[line.tokens.clone()];
        let src = &self.source;
        // `from`: the first source byte not yet written.
        let mut from = line.start;
        let mut replaced = u32::MAX;
        for e in edits.iter() {
            let ti = e.key / 4;
            let tk = &toks[ti as usize];
            match e.key % 4 {
                BEFORE => {
                    out.push_str(&src[from..tk.start]);
                    from = tk.start;
                    if e.letter != 0 {
                        out.push(e.letter as char);
                    }
                    out.push_str(&e.text);
                    if e.space {
                        out.push(' ');
                    }
                }
                REPLACE => {
                    // The first replacement of a token counts.
                    if replaced == ti {
                        continue;
                    }
                    replaced = ti;
                    // Keep the letter as written (its case), replace the number; empty text
                    // removes the word.
                    if e.text.is_empty() {
                        out.push_str(&src[from..tk.start]);
                    } else {
                        out.push_str(&src[from..tk.start + 1]);
                        out.push_str(&e.text);
                    }
                    from = tk.end;
                }
                _ => {
                    out.push_str(&src[from..tk.end]);
                    from = tk.end;
                    if e.space {
                        out.push(' ');
                    }
                    if e.letter != 0 {
                        out.push(e.letter as char);
                    }
                    out.push_str(&e.text);
                }
            }
        }
        out.push_str(&src[from..line.next]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_math::types::{rx, rz};
    use truepos_math::Vector3;

    fn tr(prog: &str, t: Transform3) -> Result<String, GcodeError> {
        Program::parse(prog).transform(&t, &TransformOptions::default())
    }

    proptest::proptest! {
        /// The pairwise digit writer gives the text of the plain one: the scaled, rounded
        /// integer's digits with the point `dec` places from the right (no `-0`); below the
        /// 9e15 bound where `fmt_num` hands over to `format!`.
        #[test]
        fn fixed_point_digits_match_the_integer(v in -1e8f64..1e8, dec in 0u8..8) {
            let n = (v * 10f64.powi(dec as i32)).round() as i64;
            let digits = format!("{:0width$}", n.unsigned_abs(), width = dec as usize + 1);
            let (int, frac) = digits.split_at(digits.len() - dec as usize);
            let mut want = if n < 0 { format!("-{int}") } else { int.to_string() };
            if dec > 0 {
                want = format!("{want}.{frac}");
            }
            proptest::prop_assert_eq!(&*fmt_num(v, dec), want);
        }
    }

    #[test]
    fn fixed_point_text() {
        for (v, dec, want) in [
            (1.5, 4, "1.5000"),
            (-0.00001, 4, "0.0000"),
            (-12.34567, 3, "-12.346"),
            (0.0, 0, "0"),
            (-7.5, 0, "-8"),
            (123456789.123456, 6, "123456789.123456"),
            (0.05, 1, "0.1"),
            (1e300, 2, &format!("{:.2}", 1e300)),
        ] {
            assert_eq!(&*fmt_num(v, dec), want, "{v} {dec}");
        }
    }

    #[test]
    fn identity_keeps_every_byte() {
        let p = "%\nO1000 (WING SPAR)\r\nN10 G21 G90 G17\n\nN20 G0 X100. Y50 Z10 ; rapid\nN30 G1 X150.25 F500\nN40 G2 X160 Y60 I10 J0\nG91 X1 Y1\n#1=2\nM30\n%";
        assert_eq!(tr(p, Transform3::identity()).unwrap(), p);
    }

    #[test]
    fn translation_touches_only_changed_words() {
        let p = "G90 G0 X10 Y20 Z5 (keep)\nG1 X15 F100\nG1 Y25\n";
        let out =
            tr(p, Transform3::rigid(truepos_math::Matrix3::identity(), Vector3::new(1.0, 0.0, 0.0))).unwrap();
        assert_eq!(out, "G90 G0 X11.0000 Y20 Z5 (keep)\nG1 X16.0000 F100\nG1 Y25\n");
    }

    #[test]
    fn mixing_rotation_writes_all_three_axes() {
        let p = "G0 X10 Y10 Z0\nG1 X20 F100\n";
        let out = tr(p, Transform3::rigid(rx(0.1), Vector3::zeros())).unwrap();
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines[0], "G0 X10 Y9.9500 Z0.9983");
        // Rotation about X leaves X20 as it is, but the move carries all three axes.
        assert_eq!(lines[1], "G1 X20 Y9.9500 Z0.9983 F100");
    }

    #[test]
    fn arcs_rotate_in_plane_and_refuse_tilt() {
        let p = "G17 G0 X10 Y0 Z0\nG2 X0 Y-10 I-10 J0\n";
        let out = tr(p, Transform3::rigid(rz(std::f64::consts::FRAC_PI_2), Vector3::zeros())).unwrap();
        assert_eq!(out.lines().nth(1).unwrap(), "G2 X10.0000 Y0.0000 I0.0000 J-10.0000");
        let e = tr(p, Transform3::rigid(rx(0.2), Vector3::zeros())).unwrap_err();
        assert_eq!(e.line(), 2);
        assert!(e.to_string().contains("tilts"));
    }

    /// Found by the fuzzer: a value beyond 2^53·10^-4 was rewritten by the identity transform
    /// (rounding to 4 decimals is not representable there). Unchanged values keep their text.
    #[test]
    fn huge_values_are_not_rewritten_by_the_identity() {
        for p in [
            "G3 X0 Y0 Z0 r22222222222222222222222222222222222222222222222222g3g3\n",
            "G90 G0 X100000000000000000000000000000000000000000000000000000000000 Y2 Z3\nG1 X123456789012345678.25\n",
        ] {
            assert_eq!(tr(p, Transform3::identity()).unwrap(), p);
        }
    }

    #[test]
    fn incremental_moves_do_not_drift() {
        let p: String = std::iter::once("G0 X0 Y0 Z0\nG91\n".to_string())
            .chain((0..1000).map(|_| "G1 X0.1\n".to_string()))
            .collect();
        let t = Transform3::rigid(rz(0.3), Vector3::zeros());
        let out = tr(&p, t).unwrap();
        let parsed = Program::parse(&out);
        let b = parsed.blocks();
        let end = b.last().unwrap().after.pos;
        let expect = t.apply(&truepos_math::Point3::new(100.0, 0.0, 0.0));
        assert!((end[0].unwrap() - expect.x).abs() < 1e-4 && (end[1].unwrap() - expect.y).abs() < 1e-4);
    }

    /// A first motion that gives only Z is refused without a start position, whatever the
    /// transform (even a pure translation), and transformed with one.
    #[test]
    fn partial_first_motion_needs_a_start_position() {
        let p = "N10 G21 G90\nN20 G0 Z50.\nN30 G1 X10 Y20 F100\n";
        let shift = Transform3::rigid(truepos_math::Matrix3::identity(), Vector3::new(1.0, 2.0, 3.0));
        let e = tr(p, shift).unwrap_err();
        assert_eq!((e.line(), e.column()), (2, 8), "{e}");
        assert!(e.to_string().contains("start-mm"), "{e}");
        let opts = TransformOptions { start_mm: Some([5.0, 6.0, 100.0]), ..Default::default() };
        let out = Program::parse(p).transform(&shift, &opts).unwrap();
        // The machine starts at (5, 6, 100) of the program's frame = (6, 8, 103) of the new one;
        // a translation keeps X and Y where they are, so the Z move stays a Z move.
        assert_eq!(out.lines().nth(1).unwrap(), "N20 G0 Z53.0000");
        assert_eq!(out.lines().nth(2).unwrap(), "N30 G1 X11.0000 Y22.0000 F100");
    }

    #[test]
    fn g92_and_unknown_positions_are_refused_with_location() {
        assert_eq!(tr("G0 X1 Y1 Z1\nG92 X0\n", Transform3::identity()).unwrap_err().line(), 2);
        let e = tr("G1 X10\n", Transform3::rigid(rz(0.1), Vector3::zeros())).unwrap_err();
        assert_eq!((e.line(), e.column()), (1, 4));
    }
}

//! The modal interpreter: what each block commands, as a controller would execute it.
//!
//! Tracks G90/G91 (distance mode), G90.1/G91.1 (arc centre mode), G20/G21 (units), G17/G18/G19
//! (plane), the motion mode (G0–G3, canned cycles G81–G89, G80) and the current position. Entry
//! point: [`crate::Program::blocks`].

use crate::lex::{Token, TokenKind};
use crate::Program;
use truepos_math::Point3;

/// The program's length unit (G21 or G20).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// Millimetres (G21).
    Mm,
    /// Inches (G20).
    Inch,
}

impl Units {
    /// Millimetres per program unit.
    pub fn mm(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
        }
    }
}

/// The arc plane selected by G17, G18 or G19.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    /// G17
    XY,
    /// G18
    ZX,
    /// G19
    YZ,
}

impl Plane {
    /// Index of the axis normal to the plane (0 = X, 1 = Y, 2 = Z).
    pub fn normal_axis(self) -> usize {
        match self {
            Plane::XY => 2,
            Plane::ZX => 1,
            Plane::YZ => 0,
        }
    }
}

/// The modal motion command (group 1) in force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionMode {
    /// No motion mode yet (or G80 cancelled it).
    None,
    /// G0: rapid positioning.
    Rapid,
    /// G1: linear feed.
    Linear,
    /// G2: clockwise arc.
    ArcCw,
    /// G3: counter-clockwise arc.
    ArcCcw,
    /// Canned cycle G81–G89.
    Cycle(u8),
}

/// The modal state between blocks. Positions are in program units; `None` until known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Modal {
    /// Absolute (G90) rather than incremental (G91) axis words.
    pub absolute: bool,
    /// Absolute (G90.1) rather than incremental (G91.1) arc centre words I, J, K.
    pub arc_absolute: bool,
    /// The length unit of the program's words.
    pub units: Units,
    /// The arc plane.
    pub plane: Plane,
    /// The motion command in force.
    pub motion: MotionMode,
    /// Current X, Y, Z in program units (`None` until the program sets it).
    pub pos: [Option<f64>; 3],
}

impl Default for Modal {
    fn default() -> Self {
        Self {
            absolute: true,
            arc_absolute: false,
            units: Units::Mm,
            plane: Plane::XY,
            motion: MotionMode::None,
            pos: [None; 3],
        }
    }
}

/// Non-modal codes that change how coordinates on their line are meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Special {
    /// G53: machine coordinates.
    Machine,
    /// G28 / G30: reference return through an intermediate point.
    Home,
    /// G92: sets the current position (a coordinate-system shift).
    SetPosition,
    /// G10: data setting (offsets), not a motion.
    DataSetting,
}

/// One interpreted block (source line).
#[derive(Debug, Clone, PartialEq)]
pub struct Block<'a> {
    /// 0-based line index.
    pub line: usize,
    /// The modal state before this block.
    pub before: Modal,
    /// The modal state after this block.
    pub after: Modal,
    /// Axis words on this line: value per axis (program units, as written).
    pub axes: [Option<f64>; 3],
    /// Arc centre words I, J, K and radius R.
    pub ijk: [Option<f64>; 3],
    /// Arc radius word R (program units, as written).
    pub r: Option<f64>,
    /// A non-modal code on this line that changes what its coordinates mean.
    pub special: Option<Special>,
    /// The commanded end position in mm, when the block moves and all three axes are known.
    pub target_mm: Option<Point3>,
    /// Comment texts on the line (with their delimiters).
    pub comments: Vec<&'a str>,
}

impl<'a> Block<'a> {
    /// Whether the block commands a motion (axis words with an active motion mode).
    pub fn is_motion(&self) -> bool {
        self.axes.iter().any(|a| a.is_some())
            && (self.after.motion != MotionMode::None || self.special == Some(Special::Home))
    }

    /// Whether any comment on the line contains `keyword` (case-insensitive).
    pub fn has_keyword(&self, keyword: &str) -> bool {
        let k = keyword.to_ascii_lowercase();
        self.comments.iter().any(|c| c.to_ascii_lowercase().contains(&k))
    }
}

fn is_code(v: f64, code: f64) -> bool {
    (v - code).abs() < 1e-6
}

impl Program {
    /// Interpret every line in order.
    pub fn blocks(&self) -> Vec<Block<'_>> {
        let mut modal = Modal::default();
        let mut out = Vec::with_capacity(self.lines.len());
        for i in 0..self.lines.len() {
            let b = self.interpret_line(i, &modal);
            modal = b.after;
            out.push(b);
        }
        out
    }

    /// Interpret line `i` given the modal state before it.
    pub fn interpret_line(&self, i: usize, before: &Modal) -> Block<'_> {
        let mut comments = Vec::new();
        let mut m = *before;
        let s = self.scan_tokens(self.line_tokens(i), &mut m, |t| comments.push(self.text(t)));
        let moves = s.axes.iter().any(|a| a.is_some());
        let target_mm = if moves && m.motion != MotionMode::None && s.special.is_none() {
            match m.pos {
                [Some(x), Some(y), Some(z)] => {
                    let u = m.units.mm();
                    Some(Point3::new(x * u, y * u, z * u))
                }
                _ => None,
            }
        } else {
            None
        };
        Block {
            line: i,
            before: *before,
            after: m,
            axes: s.axes,
            ijk: s.ijk,
            r: s.r,
            special: s.special,
            target_mm,
            comments,
        }
    }

    /// The interpretation of one line's tokens: `m`, the modal state before the line, becomes the
    /// state after it (what [`Program::interpret_line`] gives, without the comments' texts and
    /// the target), and the words and where they are come back: one pass over the tokens, for
    /// the rewriter. `comment` is called with each comment token in order. (The state is updated
    /// where it lies: a copy of it built field by field and read back whole stalls the load.)
    #[inline]
    pub(crate) fn scan_tokens(
        &self,
        toks: &[Token],
        m: &mut Modal,
        mut comment: impl FnMut(&Token),
    ) -> LineScan {
        let before_units = m.units;
        let mut s = LineScan {
            axes: [None; 3],
            ijk: [None; 3],
            r: None,
            special: None,
            first: [NONE; 7],
            arc_g: NONE,
            spaced: false,
            last_word: NONE,
        };
        for (ti, t) in toks.iter().enumerate() {
            let (letter, value) = match t.kind {
                TokenKind::Word { letter, value, .. } => (letter, value),
                TokenKind::Expr { letter, value: Some(value) } => (letter, value),
                TokenKind::Whitespace => {
                    s.spaced = true;
                    continue;
                }
                TokenKind::ParenComment { .. } | TokenKind::SemicolonComment => {
                    comment(t);
                    continue;
                }
                _ => continue,
            };
            let ti = ti as u32;
            s.last_word = ti;
            match letter {
                b'G' => {
                    let g = value;
                    // At most one integer code lies within 1e-6 of `g`: the nearest integer.
                    let n = crate::rewrite::round(g);
                    if (g - n).abs() < 1e-6 {
                        match n as i64 {
                            0 => m.motion = MotionMode::Rapid,
                            1 => m.motion = MotionMode::Linear,
                            c @ (2 | 3) => {
                                m.motion = if c == 2 { MotionMode::ArcCw } else { MotionMode::ArcCcw };
                                if s.arc_g == NONE {
                                    s.arc_g = ti;
                                }
                            }
                            17 => m.plane = Plane::XY,
                            18 => m.plane = Plane::ZX,
                            19 => m.plane = Plane::YZ,
                            20 => m.units = Units::Inch,
                            21 => m.units = Units::Mm,
                            90 => m.absolute = true,
                            91 => m.absolute = false,
                            80 => m.motion = MotionMode::None,
                            // Cycles only at exact integers.
                            81..=89 if g.fract() == 0.0 => m.motion = MotionMode::Cycle(g as u8),
                            53 => s.special = Some(Special::Machine),
                            28 | 30 => s.special = Some(Special::Home),
                            92 => s.special = Some(Special::SetPosition),
                            10 => s.special = Some(Special::DataSetting),
                            _ => {}
                        }
                    } else if is_code(g, 90.1) {
                        m.arc_absolute = true
                    } else if is_code(g, 91.1) {
                        m.arc_absolute = false
                    }
                }
                b'X' | b'Y' | b'Z' | b'I' | b'J' | b'K' | b'R' => {
                    let k = match letter {
                        b'X' => 0,
                        b'Y' => 1,
                        b'Z' => 2,
                        b'I' => 3,
                        b'J' => 4,
                        b'K' => 5,
                        _ => 6,
                    };
                    if s.first[k] == NONE {
                        s.first[k] = ti;
                    }
                    match k {
                        0..=2 => s.axes[k] = Some(value),
                        3..=5 => s.ijk[k - 3] = Some(value),
                        _ => s.r = Some(value),
                    }
                }
                _ => {}
            }
        }
        if m.units != before_units {
            // The position is kept in program units: convert it when the units change.
            let f = before_units.mm() / m.units.mm();
            for p in m.pos.iter_mut() {
                *p = p.map(|v| v * f);
            }
        }
        let axes = s.axes;
        let moves = axes.iter().any(|a| a.is_some());
        match s.special {
            Some(Special::Machine) if moves => m.pos = [None; 3],
            Some(Special::SetPosition) => {
                for k in 0..3 {
                    if let Some(v) = axes[k] {
                        m.pos[k] = Some(v);
                    }
                }
            }
            Some(Special::DataSetting) => {}
            _ => {
                if moves && (m.motion != MotionMode::None || s.special == Some(Special::Home)) {
                    for k in 0..3 {
                        if let Some(v) = axes[k] {
                            m.pos[k] = if m.absolute { Some(v) } else { m.pos[k].map(|p| p + v) };
                        }
                    }
                }
            }
        }
        s
    }
}

/// "No such token" in [`LineScan`]'s token indices.
pub(crate) const NONE: u32 = u32::MAX;

/// One line interpreted for the rewriter: the block's values and the positions (indices into
/// the line's tokens, [`NONE`] when absent) of the words it edits.
pub(crate) struct LineScan {
    pub axes: [Option<f64>; 3],
    pub ijk: [Option<f64>; 3],
    pub r: Option<f64>,
    pub special: Option<Special>,
    /// The first word of each letter X, Y, Z, I, J, K, R (the one a rewrite edits).
    pub first: [u32; 7],
    /// The first G2/G3 word.
    pub arc_g: u32,
    /// Whether the line has any whitespace token.
    pub spaced: bool,
    /// The last word of the line.
    pub last_word: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modal_positions_units_and_keyword() {
        let p = Program::parse("G21 G90\nG0 X10 Y20 Z5\nG1 X15 (MSG,Measure SOMaC)\nG91 Y-5\nG20 G90 X1\n");
        let b = p.blocks();
        assert_eq!(b[1].target_mm, Some(Point3::new(10.0, 20.0, 5.0)));
        assert_eq!(b[2].target_mm, Some(Point3::new(15.0, 20.0, 5.0)));
        assert!(b[2].has_keyword("measure somac"));
        assert_eq!(b[3].target_mm, Some(Point3::new(15.0, 15.0, 5.0)));
        let t = b[4].target_mm.unwrap();
        assert!((t - Point3::new(25.4, 15.0, 5.0)).norm() < 1e-12, "{t}");
    }
}

//! The `somac` scenario: a wing-spar drilling program for the virtual large gantry.
//!
//! A spar of `length_mm` along X with two rows of holes at a fixed pitch, reflector nests on the
//! part for real-time orientation, and an RS-274 program in part (nominal) coordinates: for each
//! hole a rapid above it, a feed down to the drilling height marked with the measurement keyword
//! comment, the drilling call, and a retract. The physics (gantry, trackers, thermal drift,
//! misalignment) lives in `truepos-somac`'s virtual cell; this module writes the program and the
//! nominal geometry that are the truth.
//!
//! Entry point: [`spar`].

use truepos_math::Point3;

/// Options of the spar program.
#[derive(Debug, Clone, PartialEq)]
pub struct SparConfig {
    /// Number of holes in each row.
    pub holes_per_row: usize,
    /// Distance between holes in a row, mm.
    pub pitch_mm: f64,
    /// X of the first hole, mm.
    pub start_x_mm: f64,
    /// Y of the two rows.
    pub rows_y_mm: [f64; 2],
    /// Height of the drilling position (reflector at the drill point) above the part surface z = 0.
    pub drill_z_mm: f64,
    /// Height of the moves between holes, mm.
    pub clearance_z_mm: f64,
    /// The comment that marks a measurement block.
    pub keyword: String,
}

impl Default for SparConfig {
    fn default() -> Self {
        Self {
            holes_per_row: 150,
            pitch_mm: 65.0,
            start_x_mm: 1000.0,
            rows_y_mm: [1900.0, 2100.0],
            drill_z_mm: 5.0,
            clearance_z_mm: 60.0,
            keyword: "(MSG,Measure SOMaC)".into(),
        }
    }
}

/// The generated scenario: program text, holes by 1-based program line (the measurement
/// block), and the part's target nests (nominal).
#[derive(Debug, Clone, PartialEq)]
pub struct Spar {
    /// The G-code program.
    pub program: String,
    /// The holes (index, nominal position mm), in program order.
    pub holes: Vec<(usize, Point3)>,
    /// The part's target nests (name, nominal position mm).
    pub targets: Vec<(String, Point3)>,
}

/// Build the spar program.
pub fn spar(c: &SparConfig) -> Spar {
    let mut s = String::new();
    let mut line = 0usize;
    let mut push = |s: &mut String, text: &str| {
        s.push_str(text);
        s.push('\n');
        line += 1;
        line
    };
    push(&mut s, "%");
    push(&mut s, "O2001 (WING SPAR - TRUEPOS VIRTUAL CELL)");
    push(&mut s, "N10 G21 G90 G17 (MM, ABSOLUTE, XY PLANE)");
    push(
        &mut s,
        &format!("N20 G0 X{:.3} Y{:.3} Z{:.3}", c.start_x_mm - 200.0, c.rows_y_mm[0], c.clearance_z_mm),
    );
    let mut holes = vec![];
    let mut n = 30;
    for (r, &y) in c.rows_y_mm.iter().enumerate() {
        for i in 0..c.holes_per_row {
            // Alternate direction per row to keep moves short.
            let k = if r % 2 == 0 { i } else { c.holes_per_row - 1 - i };
            let x = c.start_x_mm + k as f64 * c.pitch_mm;
            push(&mut s, &format!("N{n} G0 X{x:.3} Y{y:.3} Z{:.3}", c.clearance_z_mm));
            let l = push(&mut s, &format!("N{} G1 Z{:.3} F1500 {}", n + 1, c.drill_z_mm, c.keyword));
            holes.push((l, Point3::new(x, y, c.drill_z_mm)));
            push(&mut s, &format!("N{} M98 P9001 (DRILL CYCLE)", n + 2));
            push(&mut s, &format!("N{} G0 Z{:.3}", n + 3, c.clearance_z_mm));
            n += 4;
        }
    }
    push(&mut s, &format!("N{n} M30"));
    push(&mut s, "%");
    let x_end = c.start_x_mm + (c.holes_per_row as f64 - 1.0) * c.pitch_mm;
    let targets = [c.start_x_mm - 100.0, 0.5 * (c.start_x_mm + x_end), x_end + 100.0]
        .iter()
        .enumerate()
        .flat_map(|(i, &x)| {
            [
                (format!("T{}", 2 * i + 1), Point3::new(x, c.rows_y_mm[0] - 150.0, 0.0)),
                (format!("T{}", 2 * i + 2), Point3::new(x, c.rows_y_mm[1] + 150.0, 20.0)),
            ]
        })
        .collect();
    Spar { program: s, holes, targets }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holes_are_on_keyword_lines() {
        let sp = spar(&SparConfig::default());
        assert_eq!(sp.holes.len(), 300);
        let lines: Vec<&str> = sp.program.lines().collect();
        for (l, p) in &sp.holes {
            assert!(lines[l - 1].contains("(MSG,Measure SOMaC)"), "{}", lines[l - 1]);
            assert!(lines[l - 1].contains(&format!("Z{:.3}", p.z)));
        }
        assert_eq!(sp.targets.len(), 6);
    }
}

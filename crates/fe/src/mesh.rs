//! Structured rectangular mesh of the bed: grid lines in x and y, nodes at their intersections,
//! one rectangular element per grid cell.
//!
//! Entry points: [`Mesh::build`] (used by the model), [`Mesh::locate`] (which element holds a
//! point and where in it), [`Mesh::node_index`]. Node `(i, j)` (x line i, y line j) has index
//! `j * nx + i`; element `(i, j)` spans `xs[i]..xs[i+1]` × `ys[j]..ys[j+1]`.

use crate::FeError;

/// Upper limit on the number of nodes (3 DOFs each); beyond this the factorisation would need
/// more memory than a workstation should spend on a bed model.
pub const MAX_NODES: usize = 400_000;

/// A structured mesh of rectangles.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// x coordinates of the grid lines, ascending, from 0 to size_x.
    pub xs: Vec<f64>,
    /// y coordinates of the grid lines, ascending, from 0 to size_y.
    pub ys: Vec<f64>,
}

/// Where a point lies in the mesh: element cell `(i, j)` and local coordinates ξ, η ∈ [−1, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// Element column index (along x), 0-based.
    pub i: usize,
    /// Element row index (along y), 0-based.
    pub j: usize,
    /// Local coordinate ξ across the element along x, −1 to 1.
    pub xi: f64,
    /// Local coordinate η across the element along y, −1 to 1.
    pub eta: f64,
}

/// Grid lines over `[0, len]`: multiples of `h`, the end, and the `breaks`; a multiple closer
/// than 0.3·h to a break is dropped so no element is thinner than 0.3·h (aspect ratio ≤ ~4).
fn lines(len: f64, h: f64, breaks: &[f64]) -> Vec<f64> {
    let tol = 1e-9 * len.max(1.0);
    let mut brk: Vec<f64> = breaks.iter().map(|b| b.clamp(0.0, len)).collect();
    brk.push(0.0);
    brk.push(len);
    brk.sort_by(|a, b| a.total_cmp(b));
    brk.dedup_by(|a, b| (*a - *b).abs() <= tol);
    let n = (len / h).floor() as usize;
    let mut out = brk.clone();
    for k in 1..=n {
        let x = k as f64 * h;
        if x >= len - tol {
            break;
        }
        if brk.iter().all(|b| (b - x).abs() >= 0.3 * h) {
            out.push(x);
        }
    }
    out.sort_by(|a, b| a.total_cmp(b));
    out.dedup_by(|a, b| (*a - *b).abs() <= tol);
    out
}

/// Automatic element size: the largest 1, 2, 2.5, 5 × 10^k not above `max_len / 64`.
pub fn automatic_element_size(max_len: f64) -> f64 {
    let target = max_len / 64.0;
    let decade = 10f64.powf(target.log10().floor());
    let mut best = decade;
    for m in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if m * decade <= target * (1.0 + 1e-12) {
            best = m * decade;
        }
    }
    best
}

impl Mesh {
    /// Build the mesh of a `size_x` × `size_y` bed with target element size `h` and grid lines
    /// through every point of `through` (support pads).
    pub fn build(size_x: f64, size_y: f64, h: f64, through: &[[f64; 2]]) -> Result<Mesh, FeError> {
        // Guard before building the lines (an absurdly small h would allocate without bound);
        // the exact count, including the lines through the pads, is checked afterwards.
        let nodes_estimate = ((size_x / h).ceil() + 2.0) * ((size_y / h).ceil() + 2.0);
        if !nodes_estimate.is_finite() || nodes_estimate > MAX_NODES as f64 {
            let est = if nodes_estimate.is_finite() { nodes_estimate as usize } else { usize::MAX };
            return Err(FeError::MeshTooLarge { nodes: est, limit: MAX_NODES });
        }
        let bx: Vec<f64> = through.iter().map(|p| p[0]).collect();
        let by: Vec<f64> = through.iter().map(|p| p[1]).collect();
        let mesh = Mesh { xs: lines(size_x, h, &bx), ys: lines(size_y, h, &by) };
        if mesh.n_nodes() > MAX_NODES {
            return Err(FeError::MeshTooLarge { nodes: mesh.n_nodes(), limit: MAX_NODES });
        }
        Ok(mesh)
    }

    /// Number of grid lines in x (nodes per row).
    pub fn nx(&self) -> usize {
        self.xs.len()
    }

    /// Number of grid lines in y (nodes per column).
    pub fn ny(&self) -> usize {
        self.ys.len()
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nx() * self.ny()
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        (self.nx() - 1) * (self.ny() - 1)
    }

    /// Index of node (i, j).
    pub fn node_index(&self, i: usize, j: usize) -> usize {
        j * self.nx() + i
    }

    /// Coordinates of node `n`.
    pub fn node_xy(&self, n: usize) -> [f64; 2] {
        [self.xs[n % self.nx()], self.ys[n / self.nx()]]
    }

    /// The four nodes of element (i, j) in the element's local order
    /// (−1,−1), (1,−1), (1,1), (−1,1).
    pub fn element_nodes(&self, i: usize, j: usize) -> [usize; 4] {
        [
            self.node_index(i, j),
            self.node_index(i + 1, j),
            self.node_index(i + 1, j + 1),
            self.node_index(i, j + 1),
        ]
    }

    /// The node nearest to (x, y) on a grid line intersection, if one lies within `tol`.
    pub fn node_at(&self, x: f64, y: f64, tol: f64) -> Option<usize> {
        let i = nearest(&self.xs, x)?;
        let j = nearest(&self.ys, y)?;
        if (self.xs[i] - x).abs() <= tol && (self.ys[j] - y).abs() <= tol {
            Some(self.node_index(i, j))
        } else {
            None
        }
    }

    /// Locate (x, y): the element and local coordinates. `None` if outside the bed (a
    /// relative tolerance of 1e-9 of the bed size is allowed on the edges) or not finite.
    pub fn locate(&self, x: f64, y: f64) -> Option<Location> {
        let (i, xi) = locate_1d(&self.xs, x)?;
        let (j, eta) = locate_1d(&self.ys, y)?;
        Some(Location { i, j, xi, eta })
    }
}

fn nearest(lines: &[f64], x: f64) -> Option<usize> {
    if !x.is_finite() || lines.is_empty() {
        return None;
    }
    let k = lines.partition_point(|&v| v < x);
    let mut best = k.min(lines.len() - 1);
    if k > 0 && (lines[k - 1] - x).abs() < (lines[best] - x).abs() {
        best = k - 1;
    }
    Some(best)
}

fn locate_1d(lines: &[f64], x: f64) -> Option<(usize, f64)> {
    let n = lines.len();
    if n < 2 || !x.is_finite() {
        return None;
    }
    let (lo, hi) = (lines[0], lines[n - 1]);
    let tol = 1e-9 * (hi - lo).abs().max(1.0);
    if x < lo - tol || x > hi + tol {
        return None;
    }
    let x = x.clamp(lo, hi);
    // Cell k with lines[k] <= x <= lines[k+1].
    let k = lines.partition_point(|&v| v <= x).saturating_sub(1).min(n - 2);
    let (a, b) = (lines[k], lines[k + 1]);
    let xi = (2.0 * (x - a) / (b - a) - 1.0).clamp(-1.0, 1.0);
    Some((k, xi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_include_breaks_and_multiples() {
        let l = lines(2000.0, 25.0, &[130.0, 1870.0]);
        assert_eq!(l[0], 0.0);
        assert_eq!(*l.last().unwrap(), 2000.0);
        assert!(l.contains(&130.0) && l.contains(&1870.0) && l.contains(&100.0));
        // 125 is within 0.3 h of 130 and dropped.
        assert!(!l.contains(&125.0));
        for w in l.windows(2) {
            assert!(w[1] - w[0] >= 0.3 * 25.0 - 1e-9 && w[1] - w[0] <= 1.3 * 25.0 + 1e-9);
        }
    }

    #[test]
    fn automatic_size() {
        assert_eq!(automatic_element_size(2000.0), 25.0);
        assert_eq!(automatic_element_size(1000.0), 10.0);
        assert_eq!(automatic_element_size(3200.0), 50.0);
    }

    #[test]
    fn locate_points() {
        let m = Mesh::build(100.0, 50.0, 10.0, &[]).unwrap();
        let loc = m.locate(15.0, 50.0).unwrap();
        assert_eq!((loc.i, loc.j), (1, 4));
        assert!((loc.xi - 0.0).abs() < 1e-12 && (loc.eta - 1.0).abs() < 1e-12);
        assert!(m.locate(-1.0, 0.0).is_none());
        assert!(m.locate(f64::NAN, 0.0).is_none());
        assert_eq!(m.node_at(20.0, 10.0, 1e-9), Some(m.node_index(2, 1)));
    }
}

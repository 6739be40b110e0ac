//! Recker's two-level plane, "l'hémicube modifié" (radiosity thesis §2.3.2, Fig. 2.8): one
//! projection plane at height 1, its central square `[−a, a]²` cut uniformly at R1 × R1 and the
//! outer square `[−D, D]²` at R2 × R2; the facets are depth-buffered on both grids, the
//! outer grid's form factors ignoring the central square.
//!
//! The thesis gives only R1 / R2; its Tables 2.1 and 2.2 follow from `a = 1.8` (R1 = 1.8 R: the
//! inner proxels as large as the hemicube's) and `D = 5` (R2 = 5 R / 7.48: the outer FFE at the
//! inner square's corner, `(1 + 2a²)²` times smaller for the same area, equal to the hemicube's
//! largest; used proxels R1² + R2²(1 − (a/D)²)), which are [`INNER_HALF_SIDE`] and
//! [`OUTER_HALF_SIDE`].
//!
//! Outer cells: an outer proxel's FFE is the exact form factor of its part outside the central
//! square (so the FFEs sum to the outer square's form factor exactly), and it is sampled along
//! the centroid of that part; outer proxels wholly inside the central square are not sampled.
//! FFEs stored on 1/8 of each grid ([`octant_index`]). The four small side planes Recker uses
//! "occasionnellement" are not part of this surface (nor of §2.5's comparison).

use std::sync::OnceLock;

use anyhow::{bail, Result};

use super::{check_resolution, octant_index, octant_len, ProjectionSurface, Resolution};
use crate::truth::closed_form::point_to_parallel_rectangle;

/// The central square's half-side a (height 1).
pub const INNER_HALF_SIDE: f64 = 1.8;
/// The outer square's half-side D (height 1).
pub const OUTER_HALF_SIDE: f64 = 5.0;

/// Recker's plane at R1 / R2.
#[derive(Debug)]
pub struct ReckerPlane {
    r1: u32,
    r2: u32,
    /// The stored FFEs and the sampled outer cells, computed on first use.
    tables: OnceLock<Tables>,
}

/// The stored FFEs (one octant of each grid) and the sampled outer cells.
#[derive(Debug)]
struct Tables {
    inner: Vec<f64>,
    outer: Vec<f64>,
    /// Sampled outer cells: (i, j, centroid x, centroid y).
    outer_cells: Vec<(u32, u32, f64, f64)>,
}

/// `[x0, x1] × [y0, y1]`.
type Rect = [f64; 4];

fn ff(r: Rect) -> f64 {
    point_to_parallel_rectangle(r[0], r[1], r[2], r[3], 1.0)
}

fn area(r: Rect) -> f64 {
    (r[1] - r[0]).max(0.0) * (r[3] - r[2]).max(0.0)
}

fn clip_inner(r: Rect) -> Rect {
    let a = INNER_HALF_SIDE;
    [r[0].max(-a), r[1].min(a).max(r[0].max(-a)), r[2].max(-a), r[3].min(a).max(r[2].max(-a))]
}

/// Cell (i, j) of the grid of cell size `w` on `[−h, h]²`.
fn cell(w: f64, h: f64, i: u32, j: u32) -> Rect {
    let (x, y) = (-h + i as f64 * w, -h + j as f64 * w);
    [x, x + w, y, y + w]
}

/// Whether an outer cell has a part outside the central square (it is sampled).
fn sampled(c: Rect) -> bool {
    let (ca, ia) = (area(c), area(clip_inner(c)));
    ca - ia > 1e-12 * ca
}

impl ReckerPlane {
    /// Recker's plane with `r1` inner and `r2` outer proxels per side.
    pub fn new(r1: u32, r2: u32) -> Result<ReckerPlane> {
        check_resolution("recker R1", r1, false)?;
        check_resolution("recker R2", r2, false)?;
        if r2 as f64 * INNER_HALF_SIDE >= r1 as f64 * OUTER_HALF_SIDE {
            bail!("recker {r1}/{r2}: the outer proxels must be larger than the inner ones (R2 < R1 · {OUTER_HALF_SIDE}/{INNER_HALF_SIDE})");
        }
        Ok(ReckerPlane { r1, r2, tables: OnceLock::new() })
    }

    fn tables(&self) -> &Tables {
        self.tables.get_or_init(|| {
            let ((r1, r2), (wi, wo)) = ((self.r1, self.r2), self.proxel_sizes());
            let mut inner = vec![0.0; octant_len(r1)];
            for j in 0..r1.div_ceil(2) {
                for i in 0..=j {
                    inner[octant_index(r1, i, j)] = ff(cell(wi, INNER_HALF_SIDE, i, j));
                }
            }
            let mut outer = vec![0.0; octant_len(r2)];
            for j in 0..r2.div_ceil(2) {
                for i in 0..=j {
                    let c = cell(wo, OUTER_HALF_SIDE, i, j);
                    outer[octant_index(r2, i, j)] = ff(c) - ff(clip_inner(c));
                }
            }
            let outer_cells = (0..r2 * r2).filter_map(|k| outer_sample(wo, k % r2, k / r2)).collect();
            Tables { inner, outer, outer_cells }
        })
    }

    /// Outer proxels not sampled: wholly inside the central square.
    fn hidden_outer(&self) -> u64 {
        let (_, wo) = self.proxel_sizes();
        // Cell (i, j) is wholly inside iff both its intervals are: count them on the diagonal.
        let n = (0..self.r2).filter(|&i| !sampled(cell(wo, OUTER_HALF_SIDE, i, i))).count() as u64;
        n * n
    }

    /// The outer square's form factor: what the FFEs sum to.
    pub fn coverage(&self) -> f64 {
        ff([-OUTER_HALF_SIDE, OUTER_HALF_SIDE, -OUTER_HALF_SIDE, OUTER_HALF_SIDE])
    }

    /// The inner proxels' size and the outer proxels' size.
    pub fn proxel_sizes(&self) -> (f64, f64) {
        (2.0 * INNER_HALF_SIDE / self.r1 as f64, 2.0 * OUTER_HALF_SIDE / self.r2 as f64)
    }

    /// The outer grid's FFE of a proxel of its size at the inner square's corner, by the
    /// §2.3.1 formula `ΔS / (π (x² + y² + 1)²)`: the one §2.5.2 equates with the hemicube's.
    pub fn outer_corner_delta(&self) -> f64 {
        let (_, wo) = self.proxel_sizes();
        let a2 = INNER_HALF_SIDE * INNER_HALF_SIDE;
        wo * wo / (std::f64::consts::PI * (1.0 + 2.0 * a2).powi(2))
    }

    /// The largest inner FFE (a central proxel).
    pub fn inner_largest(&self) -> f64 {
        let c = self.r1 / 2;
        ff(cell(self.proxel_sizes().0, INNER_HALF_SIDE, c, c))
    }

    /// The largest outer FFE (on the central square's edges, near their middles).
    pub fn outer_largest(&self) -> f64 {
        self.tables().outer.iter().copied().fold(0.0, f64::max)
    }
}

/// The sample of outer cell (i, j): its part outside the central square, along that part's
/// centroid; `None` when it is wholly inside.
fn outer_sample(wo: f64, i: u32, j: u32) -> Option<(u32, u32, f64, f64)> {
    let c = cell(wo, OUTER_HALF_SIDE, i, j);
    if !sampled(c) {
        return None;
    }
    let (k, ca) = (clip_inner(c), area(c));
    let ia = area(k);
    let cx = (ca * (c[0] + c[1]) / 2.0 - ia * (k[0] + k[1]) / 2.0) / (ca - ia);
    let cy = (ca * (c[2] + c[3]) / 2.0 - ia * (k[2] + k[3]) / 2.0) / (ca - ia);
    Some((i, j, cx, cy))
}

impl ProjectionSurface for ReckerPlane {
    fn name(&self) -> &'static str {
        "recker"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Two(self.r1, self.r2)
    }
    /// R1² plus the outer proxels not wholly inside the central square (Table 2.2).
    fn proxels(&self) -> u64 {
        (self.r1 as u64).pow(2) + (self.r2 as u64).pow(2) - self.hidden_outer()
    }
    fn largest_delta_ff(&self) -> f64 {
        self.inner_largest().max(self.outer_largest())
    }
    /// §2.5.3: both grids stored whole, 8 bytes a proxel, 4 per FFE on 1/8 of each:
    /// `Q_r = 17/2 (R1² + R2²)`.
    fn memory_bytes(&self) -> u64 {
        let s = (self.r1 as u64).pow(2) + (self.r2 as u64).pow(2);
        8 * s + s / 2
    }
    fn samples(&self) -> usize {
        (self.r1 as usize).pow(2) + self.tables().outer_cells.len()
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let r1 = self.r1 as usize;
        if k < r1 * r1 {
            let (wi, _) = self.proxel_sizes();
            let c = |i: usize| -INNER_HALF_SIDE + (i as f64 + 0.5) * wi;
            return [c(k % r1), c(k / r1), 1.0];
        }
        let (_, _, x, y) = self.tables().outer_cells[k - r1 * r1];
        [x, y, 1.0]
    }
    fn delta(&self, k: usize) -> f64 {
        let r1 = self.r1 as usize;
        if k < r1 * r1 {
            return self.tables().inner[octant_index(self.r1, (k % r1) as u32, (k / r1) as u32)];
        }
        let (i, j, _, _) = self.tables().outer_cells[k - r1 * r1];
        self.tables().outer[octant_index(self.r2, i, j)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::testkit;

    #[test]
    fn deltas_sum_to_the_outer_square() {
        let s = ReckerPlane::new(36, 14).unwrap();
        testkit::deltas_sum_to(&s, s.coverage());
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        // δ: a proxel's half-diagonal over the height (every proxel is at distance ≥ 1); the
        // outer grid's proxels are at distance ≥ √(1 + a²) from the centre.
        let make: testkit::Make = |r| {
            let s = ReckerPlane::new(r * 9 / 5, r * 2 / 3).unwrap();
            let (wi, wo) = s.proxel_sizes();
            let d = (wi / std::f64::consts::SQRT_2)
                .max(wo / std::f64::consts::SQRT_2 / (1.0 + INNER_HALF_SIDE.powi(2)).sqrt());
            (Box::new(s), d)
        };
        let cover = ReckerPlane::new(18, 6).unwrap().coverage();
        testkit::all_checks(make, 20, 80, cover);
    }

    #[test]
    fn bad_input_is_refused() {
        assert!(ReckerPlane::new(0, 5).is_err());
        assert!(ReckerPlane::new(10, 0).is_err());
        assert!(ReckerPlane::new(10, 100).is_err());
    }
}

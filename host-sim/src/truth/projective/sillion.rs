//! Sillion's single projection plane (radiosity thesis §2.3.2, Fig. 2.6–2.7): the square
//! `[−D, D]²` at height H = 1 above the differential area, cut non-uniformly so that the
//! proxels along each axis carry equal delta form factors:
//! `x_i = (i/N) ξ_N / √(1 − i²ξ_N²/N²)`, `ξ_N = √(D² / (1 + D²))` (here written for the R + 1
//! cuts from −D to D, `t_k = (2k/R − 1) ξ`, `x_k = t_k / √(1 − t_k²)`).
//!
//! FFEs are not stored per proxel but cumulated (Fig. 2.7.a): `C[i][j]` is the form factor of
//! the window `[x_0, x_i] × [y_0, y_j]`, here exactly by the closed form of a rectangle
//! ([`point_to_parallel_rectangle`]); any window of proxels then costs one addition and two
//! subtractions (Fig. 2.7.b, the four-corner sum [`SillionPlane::window`]). Form factors are
//! gathered by windows: each row's maximal runs of proxels keeping the same facet.
//!
//! Invariants: the FFEs sum to the square's form factor (`C[R][R]`), less than 1 by the grazing
//! directions the plane misses (§2.3.2, `D/H ≈ √(2/E)`); the largest FFEs are at the corners,
//! and §2.5.2 compares resolutions on the central ones ([`ProjectionSurface::equivalence_delta_ff`]).
//!
//! The half-side: the thesis's Table 2.1 follows from `ξ² = 28/29`, i.e. `D = √28`
//! ([`THESIS_HALF_SIDE`]); its example of the 1 % rule is a square of side 28 (D = 14), which
//! would give the resolutions 100, 200, 399, 599, 798, 998 (docs/FORM-FACTORS.md).

use std::sync::OnceLock;

use anyhow::{bail, Result};

use super::{check_resolution, ProjectionSurface, Resolution, NONE};
use crate::truth::closed_form::point_to_parallel_rectangle;

/// The half-side D (height 1) that reproduces the thesis's Table 2.1: `ξ_N² = 28/29`.
pub const THESIS_HALF_SIDE: f64 = 5.291_502_622_129_181; // √28

/// Sillion's plane at resolution R (R × R proxels).
#[derive(Debug)]
pub struct SillionPlane {
    r: u32,
    d: f64,
    /// The R + 1 cuts (same on both axes).
    cuts: Vec<f64>,
    /// Cumulative FFEs, `(R + 1)²`, row-major in j; computed on first use.
    c: OnceLock<Vec<f64>>,
}

impl SillionPlane {
    /// Sillion's plane at resolution `r` with the thesis's half-side.
    pub fn new(r: u32) -> Result<SillionPlane> {
        Self::with_half_side(r, THESIS_HALF_SIDE)
    }

    /// Sillion's plane at resolution `r`, half-side `d` (> 0, finite) at height 1.
    pub fn with_half_side(r: u32, d: f64) -> Result<SillionPlane> {
        check_resolution("sillion", r, false)?;
        if !(d.is_finite() && d > 0.0) {
            bail!("sillion: half-side {d} must be positive and finite");
        }
        Ok(SillionPlane { r, d, cuts: cuts(r, d), c: OnceLock::new() })
    }

    /// The cumulative table (Fig. 2.7.a): `C[i][j]`, the window `[x_0, x_i] × [y_0, y_j]`.
    fn table(&self) -> &[f64] {
        self.c.get_or_init(|| {
            let (n, x) = (self.r as usize + 1, &self.cuts);
            let mut c = vec![0.0; n * n];
            for j in 0..n {
                for i in 0..n {
                    c[j * n + i] = point_to_parallel_rectangle(x[0], x[i], x[0], x[j], 1.0);
                }
            }
            c
        })
    }

    /// The form factor of the window of proxels `[i0, i1) × [j0, j1)`: four corners of the
    /// cumulative table (Fig. 2.7.b).
    pub fn window(&self, i0: usize, i1: usize, j0: usize, j1: usize) -> f64 {
        let (n, t) = (self.r as usize + 1, self.table());
        let c = |i: usize, j: usize| t[j * n + i];
        c(i1, j1) - c(i0, j1) - c(i1, j0) + c(i0, j0)
    }

    /// One proxel's FFE by the closed form, without the table.
    pub fn cell(&self, i: usize, j: usize) -> f64 {
        let x = &self.cuts;
        point_to_parallel_rectangle(x[i], x[i + 1], x[j], x[j + 1], 1.0)
    }

    /// The square's form factor: what all the FFEs sum to.
    pub fn coverage(&self) -> f64 {
        let n = self.r as usize;
        self.window(0, n, 0, n)
    }

    /// The cuts `x_0 … x_R` from −D to D.
    pub fn cuts(&self) -> &[f64] {
        &self.cuts
    }

    /// The half-side D.
    pub fn half_side(&self) -> f64 {
        self.d
    }
}

/// §2.3.2's cuts: equal steps in `t = sin(atan x)`, from −ξ to ξ.
fn cuts(r: u32, d: f64) -> Vec<f64> {
    let xi = (d * d / (1.0 + d * d)).sqrt();
    (0..=r)
        .map(|k| {
            let t = (2.0 * k as f64 / r as f64 - 1.0) * xi;
            t / (1.0 - t * t).sqrt()
        })
        .collect()
}

impl ProjectionSurface for SillionPlane {
    fn name(&self) -> &'static str {
        "sillion"
    }
    fn resolution(&self) -> Resolution {
        Resolution::Single(self.r)
    }
    /// R² (Table 2.2).
    fn proxels(&self) -> u64 {
        (self.r as u64).pow(2)
    }
    /// A corner proxel's (§2.5.2: "beaucoup plus importante que partout ailleurs").
    fn largest_delta_ff(&self) -> f64 {
        self.cell(0, 0)
    }
    /// The central proxel's, which §2.5.2 chose to compare on.
    fn equivalence_delta_ff(&self) -> f64 {
        let m = (self.r / 2) as usize;
        self.cell(m, m)
    }
    /// §2.5.3: only the (cumulative) FFEs, 4 bytes each: `Q_Sillion = 4 R²`.
    fn memory_bytes(&self) -> u64 {
        4 * (self.r as u64).pow(2)
    }
    fn samples(&self) -> usize {
        (self.r as usize).pow(2)
    }
    fn direction(&self, k: usize) -> [f64; 3] {
        let r = self.r as usize;
        let mid = |i: usize| 0.5 * (self.cuts[i] + self.cuts[i + 1]);
        [mid(k % r), mid(k / r), 1.0]
    }
    fn delta(&self, k: usize) -> f64 {
        let r = self.r as usize;
        let (i, j) = (k % r, k / r);
        self.window(i, i + 1, j, j + 1)
    }
    /// Row by row, each maximal run of one facet summed as one window (Fig. 2.7.b).
    fn gather(&self, ids: &[u32], out: &mut [f64]) {
        let r = self.r as usize;
        for (j, row) in ids.chunks(r).enumerate() {
            let mut i0 = 0;
            while i0 < r {
                let id = row[i0];
                let i1 = i0 + row[i0..].iter().take_while(|&&x| x == id).count();
                if id != NONE {
                    out[id as usize] += self.window(i0, i1, j, j + 1);
                }
                i0 = i1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::testkit;

    /// δ: the largest half-diagonal of a proxel over its least distance from the centre (≥ the
    /// angle between its centre direction and a corner's).
    fn delta(s: &SillionPlane) -> f64 {
        let c = s.cuts();
        let cell = |i: usize| ((c[i + 1] - c[i]) / 2.0, c[i].abs().min(c[i + 1].abs()));
        let mut worst = 0.0f64;
        for i in 0..c.len() - 1 {
            for j in 0..c.len() - 1 {
                let ((hx, nx), (hy, ny)) = (cell(i), cell(j));
                worst = worst.max(hx.hypot(hy) / (1.0 + nx * nx + ny * ny).sqrt());
            }
        }
        worst
    }

    #[test]
    fn deltas_sum_to_the_square_and_windows_add_up() {
        let s = SillionPlane::new(30).unwrap();
        let exact = point_to_parallel_rectangle(-s.half_side(), s.half_side(), -s.half_side(), s.half_side(), 1.0);
        testkit::deltas_sum_to(&s, exact);
        // §2.3.2's purpose: equal FFEs along an axis. Each column strip of an infinite plane
        // would carry exactly dt/2; on the square the outer strips lose the part beyond ±D
        // (about 19 % at D = √28), where a uniform cut would differ by (1 + D²)^(3/2) ≈ 156.
        let strips: Vec<f64> = (0..30).map(|i| s.window(i, i + 1, 0, 30)).collect();
        let (lo, hi) = strips.iter().fold((f64::MAX, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(hi / lo < 1.3, "{lo} {hi}");
        // The corners' FFEs are the largest (§2.5.2): (1 + D²)³ / (1 + 2D²)² ≈ 7.5 times the
        // centre's for small proxels.
        let fine = SillionPlane::new(400).unwrap();
        let ratio = fine.largest_delta_ff() / fine.equivalence_delta_ff();
        assert!((6.0..7.5).contains(&ratio), "{ratio}");
    }

    #[test]
    fn enclosure_parallel_perpendicular_occlusion() {
        let make: testkit::Make = |r| {
            let s = SillionPlane::new(r).unwrap();
            let d = delta(&s);
            (Box::new(s), d)
        };
        let cover = SillionPlane::new(40).unwrap().coverage();
        testkit::all_checks(make, 40, 160, cover);
    }

    #[test]
    fn bad_input_is_refused() {
        assert!(SillionPlane::new(0).is_err());
        assert!(SillionPlane::with_half_side(10, 0.0).is_err());
        assert!(SillionPlane::with_half_side(10, f64::NAN).is_err());
    }
}

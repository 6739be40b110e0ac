//! §2.5.4, Fig. 2.17–2.18: how each surface's form factor to a small facet converges with the
//! resolution. Four equal squares side by side in a plane parallel to the projection surface,
//! their block slightly off the axis so that no projection is symmetric about one (the thesis's
//! geometry; its drawing is not in the text, so the sizes are ours: squares of side 0.5, the
//! block's corner at (−0.43, −0.46)), at two distances; the form factor of facets 1 and 4 (the
//! diagonal pair) from a point at the origin with normal +z, for each method at the resolution
//! equivalent to a hemicube of R (Table 2.1's criterion), against the exact value (the contour
//! integral, Eq. 2.2).

use anyhow::Result;
use parry3d_f64::math::Vector;

use super::{tables, SurfaceSpec};
use crate::truth::closed_form::point_to_polygon;

/// The methods, in Table 2.1's column order (the names of [`SurfaceSpec::parse`]).
pub use super::tables::METHODS;

/// The distances of the squares' plane from the point (near: each square ≈ 6 % of the view's
/// form factor; far: ≈ 0.5 %).
pub const DISTANCES: [f64; 2] = [1.0, 4.0];

/// The facets plotted (1-based, row-major in the block: 1 and 4 are the diagonal pair).
pub const FACETS: [usize; 2] = [1, 4];

/// One computed form factor.
#[derive(Clone, Debug, PartialEq)]
pub struct FigurePoint {
    /// The plane's distance.
    pub distance: f64,
    /// The facet, 1..=4.
    pub facet: usize,
    /// The method ([`METHODS`]).
    pub method: &'static str,
    /// The hemicube resolution this method's resolution is equivalent to.
    pub hemicube_r: u32,
    /// The method's resolution, as the CLI writes it (`R`, or `R1/R2` for Recker).
    pub resolution: String,
    /// The sampled form factor.
    pub computed: f64,
    /// The exact one.
    pub exact: f64,
}

/// The point the form factors are taken from, its normal, and the normal the squares face it
/// with.
const FROM: (Vector, Vector, Vector) = (Vector::ZERO, Vector::Z, Vector::NEG_Z);

/// The four squares at `distance`, facet k (0-based) as its corners.
pub fn squares(distance: f64) -> [[Vector; 4]; 4] {
    let (x0, y0, s) = (-0.43, -0.46, 0.5);
    std::array::from_fn(|k| {
        let (x, y) = (x0 + s * (k % 2) as f64, y0 + s * (k / 2) as f64);
        [
            Vector::new(x, y, distance),
            Vector::new(x + s, y, distance),
            Vector::new(x + s, y + s, distance),
            Vector::new(x, y + s, distance),
        ]
    })
}

/// Every point of the figure for the hemicube resolutions `rs` (even, ≥ 2).
pub fn compute(rs: &[u32]) -> Result<Vec<FigurePoint>> {
    let (x, n, facing) = FROM;
    let mut out = Vec::new();
    for &r in rs {
        let (_, resolutions) = tables::equivalent_resolutions(r)?;
        for (method, res) in METHODS.iter().zip(&resolutions) {
            let surface = SurfaceSpec::parse(&format!("{method}:{res}"))?.build()?;
            for distance in DISTANCES {
                let sq = squares(distance);
                let tris: Vec<[Vector; 3]> = sq.iter().flat_map(|c| [[c[0], c[1], c[2]], [c[0], c[2], c[3]]]).collect();
                let ff = surface.form_factors(x, n, &tris);
                for facet in FACETS {
                    let k = facet - 1;
                    out.push(FigurePoint {
                        distance,
                        facet,
                        method,
                        hemicube_r: r,
                        resolution: res.clone(),
                        computed: ff[2 * k] + ff[2 * k + 1],
                        exact: point_to_polygon(x, n, &sq[k], facing),
                    });
                }
            }
        }
    }
    Ok(out)
}

/// The points as CSV: distance, facet, method, hemicube_r, resolution, computed, exact,
/// relative_error.
pub fn csv(points: &[FigurePoint]) -> String {
    let mut s = String::from("distance,facet,method,hemicube_r,resolution,computed,exact,relative_error\n");
    for p in points {
        s += &format!(
            "{},{},{},{},{},{:.9e},{:.9e},{:.6e}\n",
            p.distance,
            p.facet,
            p.method,
            p.hemicube_r,
            p.resolution,
            p.computed,
            p.exact,
            p.computed / p.exact - 1.0
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The four squares tile one 1 × 1 square: their exact form factors (the contour integral)
    /// add up to the block's by the rectangle formula, an independent closed form. Every
    /// method converges: its mean relative error over both distances and both facets falls
    /// from the resolution equivalent to a hemicube of 16 to that of 64.
    #[test]
    fn the_squares_tile_the_block_and_the_methods_converge() {
        for d in DISTANCES {
            let sq = squares(d);
            let (x, n, facing) = FROM;
            let sum: f64 = sq.iter().map(|c| point_to_polygon(x, n, c, facing)).sum();
            let block = crate::truth::closed_form::point_to_parallel_rectangle(-0.43, 0.57, -0.46, 0.54, d);
            assert!((sum - block).abs() < 1e-12, "d = {d}: {sum} against {block}");
        }
        let points = compute(&[16, 64]).unwrap();
        assert_eq!(points.len(), 2 * METHODS.len() * DISTANCES.len() * FACETS.len());
        for method in METHODS {
            let err = |r: u32| -> f64 {
                let ps: Vec<&FigurePoint> = points.iter().filter(|p| p.method == method && p.hemicube_r == r).collect();
                ps.iter().map(|p| (p.computed / p.exact - 1.0).abs()).sum::<f64>() / ps.len() as f64
            };
            assert!(err(64) < err(16), "{method}: mean relative error {} at 64 against {} at 16", err(64), err(16));
        }
    }
}

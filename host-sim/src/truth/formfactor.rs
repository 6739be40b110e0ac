//! Form factors between radiosity patches, in `f64`, with exact visibility (radiosity thesis,
//! ch. 2 and §3.1): the independent reference the machine's form factors are measured against.
//!
//! The form factor from patch i to patch j is (thesis Eq. 2.3)
//! `F_ij = 1/A_i ∬ cosθ_i cosθ_j / (π r²) · V dA_i dA_j`,
//! the fraction of the power leaving i (diffusely, from its front side) that reaches j directly.
//! Invariants: `0 ≤ F_ij`, `F_ii = 0` (patches are planar), and up to the estimators' errors
//! `Σ_j F_ij ≤ 1` (= 1 in a closed scene) and `A_i F_ij = A_j F_ji` (§2.1).
//!
//! Estimation ([`FormFactors`]): each patch carries fixed sample points, one per stratum (each of
//! its triangles cut into k² equal triangles by [`split_triangle`], one uniform point in each,
//! from a seeded [`Rng`]), each standing for its stratum's area. Visibility between a shooter
//! point and a receiver point is one exact ray cast ([`Reference::surfaces_see`]) against the
//! triangles of the scene's planar pieces, always from the lower-numbered patch's point to the
//! higher one's (so the answer is the same for `F_ij` and `F_ji`), ignoring the two pieces the
//! segment starts and ends on; a point under an overlapping coplanar piece that wins it (the
//! Cornell light in its ceiling) sees nothing, as the reference renderer never sees it. Two
//! estimators ([`Estimator`]):
//! * [`Estimator::Contour`] (the default): for each shooter point `x`, the *unoccluded* point-to-
//!   polygon form factor of the receiver clipped to `x`'s hemisphere, exactly, by the contour
//!   integral (thesis Eq. 2.2, [`point_to_polygon`]), times the kernel-weighted fraction of the
//!   receiver's points that `x` sees. Exact when the receiver is wholly visible or wholly hidden,
//!   including adjacent patches, where the point-to-point kernel is singular (r → 0): this is
//!   how the near field is handled. Partial occlusion: a ratio estimate (slightly biased, O(1/n)).
//! * [`Estimator::PointToPoint`]: every shooter point with every receiver point,
//!   `cosθ_i cosθ_j / max(π r², a_k + a_l) · a_l` (a = the two points' stratum areas). The cap
//!   replaces the kernel only where the two strata are closer than about their own size: there a
//!   pair carries at most `min(a_k, a_l)` of area, as a disc-to-disc exchange would (Wallace's
//!   disc kernel of §3.1.3, `a/(π r² + a)`, behaves alike near contact but would bias every
//!   far pair by `a/(π r²)` with jittered points; the cap leaves them unbiased). Its near-field
//!   bias is known: along a right-angle edge of length L it removes `4 ρ₀ L / (9 π A_i)` from
//!   `F_ij` (ρ₀ = √(ε/π), ε = a_k + a_l), the tests check it. Reciprocity is exact by construction.
//!
//! * [`Estimator::Projective`]: a projective surface of ch. 2 ([`crate::truth::projective`]) at
//!   each shooter point, applied on its normal, depth-buffering every patch's triangles (a
//!   triangle seen from behind occludes but receives nothing): one projection gives the whole row, `F_ij = Σ_x a_x F_proj(x → j) / A_i`. Its errors are the
//!   surface's aliasing (docs/FORM-FACTORS.md) and, for the single planes, the grazing
//!   directions they miss.
//!
//! Closed forms for the tests: two directly opposed parallel rectangles, two perpendicular
//! rectangles sharing an edge, a differential area facing a parallel rectangle.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;
use rayon::prelude::*;

use super::closed_form::{clip_front, point_to_polygon};
use super::projective::{ProjectionSurface, SurfaceSpec};
use super::visibility::Reference;
use crate::rng::Rng;
use crate::scene::patches::{area_vector, split_triangle, Patch, Patches};

use std::f64::consts::PI;

/// Every patch's triangles and the patch each belongs to, with the surface of `spec`.
fn projective(patches: &Patches, spec: SurfaceSpec) -> Result<Projective> {
    let mut triangles = Vec::new();
    let mut owner = Vec::new();
    for (k, p) in patches.patches.iter().enumerate() {
        triangles.extend(p.triangles.iter().copied());
        owner.extend(std::iter::repeat_n(k, p.triangles.len()));
    }
    Ok(Projective { surface: spec.build()?, triangles, owner })
}

/// How [`FormFactors`] estimates `F_ij` (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// Exact unoccluded point-to-polygon factor × sampled visible fraction.
    #[default]
    Contour,
    /// Point-to-point kernel over all pairs of sample points, capped in the near field.
    PointToPoint,
    /// A projective surface of the thesis's ch. 2 at every shooter point.
    Projective(SurfaceSpec),
}

impl std::fmt::Display for Estimator {
    /// What a run's summary calls it: `contour`, `point-to-point`, or the surface's `METHOD:R`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Estimator::Contour => f.write_str("contour"),
            Estimator::PointToPoint => f.write_str("point-to-point"),
            Estimator::Projective(s) => write!(f, "{s}"),
        }
    }
}

impl serde::Serialize for Estimator {
    /// As its name ([`Estimator`]'s `Display`): `"contour"`, `"hemicube:16"` …
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Most form factors [`FormFactors::row`] keeps (2²⁴ numbers, 128 MiB).
pub const ROW_CACHE: usize = 1 << 24;

/// Sampling of the form factors.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Sampling {
    /// Each triangle of a patch is cut into `strata²` strata, one sample point each (a quad
    /// patch, two triangles, has 2·strata² points). 1..=64.
    pub strata: usize,
    /// Seed of the sample points.
    pub seed: u64,
    /// The estimator.
    pub estimator: Estimator,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling { strata: 3, seed: 1, estimator: Estimator::Contour }
    }
}

/// A sample point of a patch and the area of the stratum it stands for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// World position (on the patch).
    pub point: Vector,
    /// Stratum area: the samples' weights sum to the patch's area.
    pub weight: f64,
}

/// The geometry of a patch the estimators need.
#[derive(Clone, Debug)]
struct Geom {
    polygon: Vec<Vector>,
    normal: Vector,
    area: f64,
    piece: u32,
}

/// Form factors of a set of patches: their sample points and the exact-visibility reference.
#[derive(Debug)]
pub struct FormFactors {
    geoms: Vec<Geom>,
    samples: Vec<Vec<Sample>>,
    reference: Reference,
    sampling: Sampling,
    rays: AtomicU64,
    /// Proxels projected so far (all rows; [`Estimator::Projective`] only).
    proxels: AtomicU64,
    /// Rows computed so far, kept while they hold under [`ROW_CACHE`] numbers: a solver that
    /// shoots a patch again, the direct-light solve and the indirect irradiance after it ask for
    /// the same rows.
    rows: Mutex<HashMap<usize, Vec<f64>>>,
    /// With [`Estimator::Projective`]: the surface, every patch's triangles and their patch.
    projective: Option<Projective>,
}

/// What [`Estimator::Projective`] projects.
#[derive(Debug)]
struct Projective {
    surface: Box<dyn ProjectionSurface>,
    triangles: Vec<[Vector; 3]>,
    owner: Vec<usize>,
}

impl FormFactors {
    /// Sample the patches and build the visibility reference over their pieces' triangles.
    ///
    /// Errors: `strata` outside 1..=64, no patch, a patch with a non-positive or non-finite
    /// area or normal, a piece index outside `patches.pieces`, or no piece triangle with an area.
    pub fn new(patches: &Patches, sampling: Sampling) -> Result<FormFactors> {
        if !(1..=64).contains(&sampling.strata) {
            bail!("form factors: strata must be 1..=64, got {}", sampling.strata);
        }
        if patches.patches.is_empty() {
            bail!("form factors: no patches");
        }
        let geoms = patches.patches.iter().enumerate().map(|(i, p)| geom(i, p, patches)).collect::<Result<_>>()?;
        let samples = (0..patches.patches.len())
            .map(|i| sample_patch(&patches.patches[i], sampling.strata, sampling.seed, i as u64))
            .collect();
        let mut tris = Vec::new();
        let mut ids = Vec::new();
        for (k, piece) in patches.pieces.iter().enumerate() {
            tris.extend(piece.triangles.iter().map(|t| t.map(<[f64; 3]>::from)));
            ids.extend(std::iter::repeat_n(k as u32, piece.triangles.len()));
        }
        let reference = Reference::new(tris, ids)?;
        let projective = match sampling.estimator {
            Estimator::Projective(spec) => Some(projective(patches, spec)?),
            _ => None,
        };
        Ok(FormFactors {
            geoms,
            samples,
            reference,
            sampling,
            rays: AtomicU64::new(0),
            proxels: AtomicU64::new(0),
            rows: Mutex::default(),
            projective,
        })
    }

    /// Number of patches.
    pub fn len(&self) -> usize {
        self.geoms.len()
    }

    /// Whether there is no patch (never, once built).
    pub fn is_empty(&self) -> bool {
        self.geoms.is_empty()
    }

    /// The sampling used.
    pub fn sampling(&self) -> Sampling {
        self.sampling
    }

    /// The sample points of patch `i` (empty if there is no such patch).
    pub fn samples(&self, i: usize) -> &[Sample] {
        self.samples.get(i).map_or(&[], Vec::as_slice)
    }

    /// Rays cast so far (all rows).
    pub fn rays_cast(&self) -> u64 {
        self.rays.load(Ordering::Relaxed)
    }

    /// Proxels sampled so far (all rows): the surface's proxels for every shooter point a
    /// projective row projected from; 0 for the ray-cast estimators.
    pub fn proxels_sampled(&self) -> u64 {
        self.proxels.load(Ordering::Relaxed)
    }

    /// Row i: `F_ij` for every patch j (receivers in parallel), computed once while the kept
    /// rows hold under [`ROW_CACHE`] numbers (the rows are deterministic: the same numbers
    /// either way; a row read back casts no ray). Error if `i` is out of range.
    pub fn row(&self, i: usize) -> Result<Vec<f64>> {
        if i >= self.len() {
            bail!("form factors: patch {i} out of range ({} patches)", self.len());
        }
        let kept = || self.rows.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(r) = kept().get(&i) {
            return Ok(r.clone());
        }
        let r = match &self.projective {
            Some(p) => self.projective_row(p, i),
            None => (0..self.len()).into_par_iter().map(|j| self.pair(i, j)).collect(),
        };
        let mut rows = kept();
        if rows.len() < ROW_CACHE / self.len() {
            rows.insert(i, r.clone());
        }
        Ok(r)
    }

    /// The whole matrix, row by row (rows in parallel).
    pub fn matrix(&self) -> Vec<Vec<f64>> {
        if let Some(p) = &self.projective {
            return (0..self.len()).into_par_iter().map(|i| self.projective_row(p, i)).collect();
        }
        (0..self.len()).into_par_iter().map(|i| (0..self.len()).map(|j| self.pair(i, j)).collect()).collect()
    }

    /// Row i by [`Estimator::Projective`]: one projection per shooter point (in parallel),
    /// each triangle's form factor credited to its patch, weighted by the point's stratum.
    fn projective_row(&self, p: &Projective, i: usize) -> Vec<f64> {
        let g = &self.geoms[i];
        let per_point = |x: &Sample| {
            let ff = p.surface.form_factors(x.point, g.normal, &p.triangles);
            let mut row = vec![0.0; self.len()];
            for (t, f) in ff.iter().enumerate() {
                // A triangle seen from behind hides what is beyond it but receives nothing
                // (as the other estimators' `faces_toward`): a point inside a closed block.
                let j = p.owner[t];
                if (x.point - p.triangles[t][0]).dot(self.geoms[j].normal) > 0.0 {
                    row[j] += x.weight * f / g.area;
                }
            }
            row
        };
        // Points in parallel, summed in their order: the same row whatever the threads.
        let rows: Vec<Vec<f64>> = self.samples[i].par_iter().map(per_point).collect();
        self.proxels.fetch_add(p.surface.proxels() * rows.len() as u64, Ordering::Relaxed);
        let mut row = vec![0.0; self.len()];
        for r in &rows {
            row.iter_mut().zip(r).for_each(|(a, b)| *a += b);
        }
        row[i] = 0.0;
        row
    }

    /// `F_ij` by the chosen estimator.
    fn pair(&self, i: usize, j: usize) -> f64 {
        let (gi, gj) = (&self.geoms[i], &self.geoms[j]);
        if i == j || gi.piece == gj.piece || !faces_toward(gi, gj) {
            return 0.0;
        }
        let sum: f64 = match self.sampling.estimator {
            Estimator::Contour => self.samples[i].iter().map(|x| x.weight * self.contour_term(i, x, j)).sum(),
            Estimator::PointToPoint => self.samples[i].iter().map(|x| x.weight * self.kernel_sum(i, x, j)).sum(),
            // `row` and `matrix` project whole rows; a single pair is the same row's entry.
            Estimator::Projective(_) => return self.projective.as_ref().map_or(0.0, |p| self.projective_row(p, i)[j]),
        };
        sum / gi.area
    }

    /// Contour estimator at one shooter point: exact unoccluded factor × visible fraction.
    fn contour_term(&self, i: usize, xs: &Sample, j: usize) -> f64 {
        let (gi, gj) = (&self.geoms[i], &self.geoms[j]);
        let x = xs.point;
        let f = point_to_polygon(x, gi.normal, &gj.polygon, gj.normal);
        if f <= 0.0 {
            return 0.0;
        }
        let (mut seen, mut all) = (0.0, 0.0);
        for y in &self.samples[j] {
            let k = y.weight * capped_kernel(x, gi.normal, y.point, gj.normal, xs.weight + y.weight);
            if k > 0.0 {
                all += k;
                if self.visible(i, x, j, y.point) {
                    seen += k;
                }
            }
        }
        if all > 0.0 {
            return f * seen / all;
        }
        // No sample point of j is in front of x (a sliver of j is): one ray to that sliver.
        let span = x.distance(gj.polygon[0]).max(f64::MIN_POSITIVE);
        let part = clip_front(&gj.polygon, x, gi.normal, 1e-12 * span);
        let c = part.iter().sum::<Vector>() / part.len().max(1) as f64;
        if self.visible(i, x, j, c) {
            f
        } else {
            0.0
        }
    }

    /// Point-to-point estimator at one shooter point: `Σ_l a_l K V`.
    fn kernel_sum(&self, i: usize, x: &Sample, j: usize) -> f64 {
        let (gi, gj) = (&self.geoms[i], &self.geoms[j]);
        let mut sum = 0.0;
        for y in &self.samples[j] {
            let k = capped_kernel(x.point, gi.normal, y.point, gj.normal, x.weight + y.weight);
            if k > 0.0 && self.visible(i, x.point, j, y.point) {
                sum += y.weight * k;
            }
        }
        sum
    }

    /// Exact visibility between a point of patch i and a point of patch j, cast from the
    /// lower-numbered patch: nothing but their own pieces between them, and neither point under
    /// a coplanar piece that wins it ([`Reference::surfaces_see`]).
    fn visible(&self, i: usize, x: Vector, j: usize, y: Vector) -> bool {
        self.rays.fetch_add(1, Ordering::Relaxed);
        let (pi, pj) = (self.geoms[i].piece, self.geoms[j].piece);
        let ((from, fp), (to, tp)) = if i < j { ((x, pi), (y, pj)) } else { ((y, pj), (x, pi)) };
        self.reference.surfaces_see(from.into(), fp, to.into(), tp)
    }
}

/// `cosθ_x cosθ_y / max(π r², eps)`, 0 unless each point is in front of the other's plane.
fn capped_kernel(x: Vector, nx: Vector, y: Vector, ny: Vector, eps: f64) -> f64 {
    let d = y - x;
    let (cx, cy) = (d.dot(nx), -d.dot(ny));
    if cx <= 0.0 || cy <= 0.0 {
        return 0.0;
    }
    let r2 = d.length_squared();
    cx * cy / (r2 * (PI * r2).max(eps))
}

/// Whether some point of j is in front of i's plane and some point of i in front of j's.
fn faces_toward(gi: &Geom, gj: &Geom) -> bool {
    let front = |poly: &[Vector], p0: Vector, n: Vector| poly.iter().any(|p| (*p - p0).dot(n) > 0.0);
    front(&gj.polygon, gi.polygon[0], gi.normal) && front(&gi.polygon, gj.polygon[0], gj.normal)
}

fn geom(i: usize, p: &Patch, patches: &Patches) -> Result<Geom> {
    if !(p.area.is_finite() && p.area > 0.0) {
        bail!("form factors: patch {i} (face {}) has area {}", p.face, p.area);
    }
    let off = (p.normal.length() - 1.0).abs();
    if off.is_nan() || off >= 1e-9 || p.polygon.len() < 3 {
        bail!("form factors: patch {i} (face {}) has no unit normal or fewer than 3 vertices", p.face);
    }
    if p.piece >= patches.pieces.len() || p.piece > u32::MAX as usize {
        bail!("form factors: patch {i} lies on piece {} of {}", p.piece, patches.pieces.len());
    }
    Ok(Geom { polygon: p.polygon.clone(), normal: p.normal, area: p.area, piece: p.piece as u32 })
}

/// One uniform point in each of the `strata²` strata of each triangle of the patch.
fn sample_patch(p: &Patch, strata: usize, seed: u64, index: u64) -> Vec<Sample> {
    let mut rng = Rng(seed ^ index.wrapping_add(1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    rng.next_u64();
    let mut out = Vec::with_capacity(p.triangles.len() * strata * strata);
    for t in &p.triangles {
        let w = area_vector(t).dot(p.normal) / (strata * strata) as f64;
        for s in split_triangle(*t, strata) {
            let (r1, r2) = (rng.f().sqrt(), rng.f());
            let point = s[0] + ((s[1] - s[0]) * (r1 * (1.0 - r2)) + (s[2] - s[0]) * (r1 * r2));
            out.push(Sample { point, weight: w });
        }
    }
    out
}

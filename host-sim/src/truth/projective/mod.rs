//! Projective form factors (radiosity thesis, ch. 2, §2.2–2.5): the form factors from a
//! differential area (a point with a unit normal) to the scene's facets, sampled on a
//! projection surface cut into proxels, each proxel carrying its delta form factor (FFE).
//!
//! Principle (§2.2): by Nusselt's analogue a facet's form factor is the area its radial
//! projection covers on the unit hemisphere, projected again onto the base plane; a surface
//! cut into proxels with precomputed delta form factors samples it. Occlusion is a depth buffer
//! (§2.2, Fig. 2.3.b): each proxel keeps the nearest facet seen through it, and a facet's form
//! factor is the sum of the delta form factors of the proxels it keeps.
//!
//! The methods, one file each:
//! * [`hemicube`] — Cohen's hemicube (§2.3.1): five faces, FFEs stored on 1/8 of the top face
//!   and 1/4 of one side face.
//! * [`sillion`] — Sillion's single plane (§2.3.2): non-uniform cuts, a cumulative table and the
//!   four-corner window sum.
//! * [`recker`] — Recker's two-level plane (§2.3.2): an inner square at R1, an outer one at R2.
//! * [`hemisphere_uniform`] — Spencer's hemisphere cut at constant Δθ, Δφ (§2.4.1).
//! * [`hemisphere`] — the hemisphere cut into rings of equal delta form factor (§2.4.1).
//! * [`disk`] — the projection disk (§2.4.2): the (u, v, ρ) frame and half-ellipse tests.
//! * [`tables`] — §2.5: equivalent resolutions, proxels, memory (Tables 2.1–2.3).
//!
//! Invariants every surface keeps: its delta form factors are positive and sum to the form
//! factor of the part of the hemisphere it covers (1 for the hemicube, the hemispheres and the
//! disk; the closed form of the square for the single planes, §2.3.2's loss through grazing
//! directions); a proxel is given to at most one facet, the nearest along its centre ray.
//!
//! The depth-buffer pass here is Spencer's ray test (§2.4.1), applied on every surface: a
//! proxel's centre direction `d` is inside a facet's projection iff it is on the inner side of
//! the three planes through the centre and each edge (the disk's half-ellipses, Eq. 2.5, are
//! exactly these planes seen in (u, v)); its depth is the distance along `d` to the facet's
//! plane. Facets are the slice's triangles; a facet's id is its index in the slice.

pub mod disk;
pub mod figure;
pub mod hemicube;
pub mod hemisphere;
pub mod hemisphere_uniform;
pub mod recker;
pub mod sillion;
pub mod tables;

use std::fmt;

use anyhow::{bail, Result};
use parry3d_f64::math::Vector;

/// The largest resolution a surface accepts (per axis; 4 000² proxels is 16 M depth-buffer
/// slots, far past the thesis's 1 000).
pub const MAX_RESOLUTION: u32 = 4000;

/// A surface's resolution: one number, or Recker's two (inner R1 / outer R2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resolution {
    /// One resolution R.
    Single(u32),
    /// Recker's inner and outer resolutions.
    Two(u32, u32),
}

impl fmt::Display for Resolution {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Resolution::Single(r) => write!(f, "{r}"),
            Resolution::Two(a, b) => write!(f, "{a}/{b}"),
        }
    }
}

/// Check a resolution: 1..=[`MAX_RESOLUTION`], and even where `even` (a surface split in half).
pub fn check_resolution(what: &str, r: u32, even: bool) -> Result<()> {
    if r == 0 || r > MAX_RESOLUTION {
        bail!("{what}: resolution {r} is out of range (1..={MAX_RESOLUTION})");
    }
    if even && r % 2 == 1 {
        bail!("{what}: resolution {r} must be even (its side faces are R × R/2)");
    }
    Ok(())
}

/// A projection surface cut into proxels (§2.2), in its local frame: the differential area at
/// the origin, its normal along +z.
pub trait ProjectionSurface: Sync + Send + fmt::Debug {
    /// The method's name in the tables (`hemicube`, `sillion`, …).
    fn name(&self) -> &'static str;
    /// Its resolution.
    fn resolution(&self) -> Resolution;
    /// Proxels as §2.5 counts them (Table 2.2).
    fn proxels(&self) -> u64;
    /// The largest delta form factor of any proxel.
    fn largest_delta_ff(&self) -> f64;
    /// The delta form factor §2.5.2 compares resolutions on (the largest, unless the thesis
    /// chose another proxel; see each method).
    fn equivalence_delta_ff(&self) -> f64 {
        self.largest_delta_ff()
    }
    /// Bytes to store the proxels and the FFEs, by the thesis's byte model (§2.5.3, Table 2.3).
    fn memory_bytes(&self) -> u64;
    /// Depth-buffer slots: the proxels actually sampled.
    fn samples(&self) -> usize;
    /// The centre direction of sample `k` (not necessarily unit length; z > 0).
    fn direction(&self, k: usize) -> [f64; 3];
    /// The delta form factor of sample `k`, from the surface's stored table.
    fn delta(&self, k: usize) -> f64;
    /// Sum the delta form factors of each facet's samples into `out` (`ids[k]` is the facet
    /// sample `k` keeps, [`NONE`] for none). The default adds [`Self::delta`] per sample.
    fn gather(&self, ids: &[u32], out: &mut [f64]) {
        for (k, &id) in ids.iter().enumerate() {
            if id != NONE {
                out[id as usize] += self.delta(k);
            }
        }
    }
    /// Form factors from the point `x` with unit normal `n` to each facet (§2.2): depth buffer,
    /// then the sum of the kept proxels' delta form factors. `out[i]` is facet `i`'s.
    fn form_factors(&self, x: Vector, n: Vector, facets: &[[Vector; 3]]) -> Vec<f64> {
        let cones = local_cones(x, n, facets);
        let ids = depth_buffer(self, &cones);
        let mut out = vec![0.0; facets.len()];
        self.gather(&ids, &mut out);
        out
    }
}

/// No facet in a proxel.
pub const NONE: u32 = u32::MAX;

/// The proxels a facet's projection may cover on one plane of a surface: the bounding rectangle
/// `[i0, i1] × [j0, j1]` of proxel indices on plane `plane` (§6.2.4: a conservative rectangle,
/// every proxel whose centre the projection covers is inside).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneRect {
    /// The plane ([`Planar::planes`]).
    pub plane: usize,
    /// First and last column.
    pub i0: u32,
    /// Last column.
    pub i1: u32,
    /// First row.
    pub j0: u32,
    /// Last row.
    pub j1: u32,
}

/// A surface made of planes of proxels on a square lattice (the hemicube's five faces, the
/// disk's bounding square): what a grid of cells distributes zone by zone (radiosity thesis
/// §6.2.3) and restricts per facet to bounding rectangles (§6.2.4).
pub trait Planar: ProjectionSurface {
    /// Each plane's columns × rows.
    fn planes(&self) -> Vec<(u32, u32)>;
    /// The sample of proxel (i, j) of plane `plane`, if that proxel exists (the disk's square
    /// has none outside the disk).
    fn sample_at(&self, plane: usize, i: u32, j: u32) -> Option<usize>;
    /// The bounding rectangles of the facet with vertices `local` (in the surface's frame)
    /// on each plane its projection reaches: the rectangles the surface's own depth buffer
    /// scans.
    fn rects(&self, local: &[[f64; 3]; 3]) -> Vec<PlaneRect>;
}

/// A facet seen from the centre: the three edge planes through the origin, oriented so that the
/// facet's projection is where all three are ≥ 0, and its own plane `p · d = h`.
#[derive(Clone, Copy, Debug)]
pub struct Cone {
    edges: [[f64; 3]; 3],
    plane: [f64; 3],
    h: f64,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// An orthonormal frame (t, b, n) around the unit normal `n`.
pub fn frame(n: Vector) -> (Vector, Vector, Vector) {
    let n = n.normalize();
    let a = if n.x.abs() < 0.9 { Vector::X } else { Vector::Y };
    let t = a.cross(n).normalize();
    (t, n.cross(t), n)
}

impl Cone {
    /// The cone of the triangle `v` (vertices relative to the centre, local frame); `None` when
    /// its plane passes through the centre (seen edge-on: it covers no direction).
    pub fn new(v: [[f64; 3]; 3]) -> Option<Cone> {
        let plane = cross(sub(v[1], v[0]), sub(v[2], v[0]));
        let h = dot(plane, v[0]);
        let scale = dot(plane, plane).sqrt() * dot(v[0], v[0]).sqrt();
        if h.is_nan() || h.abs() <= 1e-12 * scale {
            return None;
        }
        let s = h.signum();
        let e = |a: [f64; 3], b: [f64; 3]| cross(a, b).map(|c| c * s);
        Some(Cone { edges: [e(v[0], v[1]), e(v[1], v[2]), e(v[2], v[0])], plane, h })
    }

    /// Distance parameter along `d` to the facet (`t` with `t·d` on it), when `d` is inside.
    pub fn hit(&self, d: [f64; 3]) -> Option<f64> {
        if self.edges.iter().all(|e| dot(*e, d) >= 0.0) {
            let t = self.h / dot(self.plane, d);
            (t > 0.0).then_some(t)
        } else {
            None
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The facets' cones in the local frame of the point `x` with normal `n`.
pub fn local_cones(x: Vector, n: Vector, facets: &[[Vector; 3]]) -> Vec<Option<Cone>> {
    let (t, b, n) = frame(n);
    let local = |p: Vector| {
        let d = p - x;
        [d.dot(t), d.dot(b), d.dot(n)]
    };
    facets.iter().map(|f| Cone::new(f.map(local))).collect()
}

/// The depth buffer (§2.2, Fig. 2.3.b): for each sample, the nearest facet along its centre ray.
pub fn depth_buffer<S: ProjectionSurface + ?Sized>(s: &S, cones: &[Option<Cone>]) -> Vec<u32> {
    (0..s.samples())
        .map(|k| {
            let d = s.direction(k);
            let mut best = (f64::INFINITY, NONE);
            for (i, c) in cones.iter().enumerate() {
                if let Some(t) = c.as_ref().and_then(|c| c.hit(d)) {
                    if t < best.0 {
                        best = (t, i as u32);
                    }
                }
            }
            best.1
        })
        .collect()
}

/// The depth buffer facet by facet, for surfaces that scan only the proxels a facet may cover:
/// `project(facet, cone, local_vertices, zbuf)` fills the (depth, facet) slots of the samples
/// it covers (vertices in the frame of `n` about `x`, [`frame`]); then the kept proxels' delta
/// form factors are summed per facet ([`ProjectionSurface::gather`]).
pub fn by_facet<S: ProjectionSurface + ?Sized>(
    s: &S,
    x: Vector,
    n: Vector,
    facets: &[[Vector; 3]],
    mut project: impl FnMut(u32, &Cone, &[[f64; 3]; 3], &mut [(f64, u32)]),
) -> Vec<f64> {
    let cones = local_cones(x, n, facets);
    let (t, b, nn) = frame(n);
    let mut zbuf = vec![(f64::INFINITY, NONE); s.samples()];
    for (f, (cone, tri)) in cones.iter().zip(facets).enumerate() {
        let Some(cone) = cone else { continue };
        let local = tri.map(|p| {
            let d = p - x;
            [d.dot(t), d.dot(b), d.dot(nn)]
        });
        project(f as u32, cone, &local, &mut zbuf);
    }
    let ids: Vec<u32> = zbuf.iter().map(|z| z.1).collect();
    let mut out = vec![0.0; facets.len()];
    s.gather(&ids, &mut out);
    out
}

/// Index of an octant-folded cell of an `r × r` grid symmetric in x, y and the diagonal
/// (§2.3.1: 1/8 of the FFEs are stored): `(i, j)` → index into the stored triangle.
pub fn octant_index(r: u32, i: u32, j: u32) -> usize {
    let fold = |k: u32| k.min(r - 1 - k);
    let (a, b) = (fold(i), fold(j));
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    (b * (b + 1) / 2 + a) as usize
}

/// Cells stored by [`octant_index`] for an `r × r` grid.
pub fn octant_len(r: u32) -> usize {
    let h = r.div_ceil(2);
    (h * (h + 1) / 2) as usize
}

/// A method and its resolution, as `--form-factors` names it: `hemicube:R`, `sillion:R`,
/// `recker:R1/R2`, `hemisphere-uniform:R`, `hemisphere:R`, `disk:R`. Parsed specs are valid:
/// [`SurfaceSpec::build`] succeeds on them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SurfaceSpec {
    /// [`hemicube::Hemicube`].
    Hemicube(u32),
    /// [`sillion::SillionPlane`].
    Sillion(u32),
    /// [`recker::ReckerPlane`].
    Recker(u32, u32),
    /// [`hemisphere_uniform::UniformHemisphere`].
    HemisphereUniform(u32),
    /// [`hemisphere::Hemisphere`].
    Hemisphere(u32),
    /// [`disk::Disk`].
    Disk(u32),
}

impl SurfaceSpec {
    /// Parse and validate `METHOD:R` (see the type).
    pub fn parse(spec: &str) -> Result<SurfaceSpec> {
        let Some((name, res)) = spec.split_once(':') else {
            bail!("'{spec}': expected METHOD:R (hemicube:R, sillion:R, recker:R1/R2, hemisphere-uniform:R, hemisphere:R, disk:R)");
        };
        let num = |s: &str| -> Result<u32> {
            s.parse::<u32>().map_err(|_| anyhow::anyhow!("'{spec}': '{s}' is not a resolution (a positive integer)"))
        };
        let parsed = match name {
            "hemicube" => SurfaceSpec::Hemicube(num(res)?),
            "sillion" => SurfaceSpec::Sillion(num(res)?),
            "recker" => {
                let Some((a, b)) = res.split_once('/') else {
                    bail!("'{spec}': Recker's plane takes two resolutions, recker:R1/R2");
                };
                SurfaceSpec::Recker(num(a)?, num(b)?)
            }
            "hemisphere-uniform" => SurfaceSpec::HemisphereUniform(num(res)?),
            "hemisphere" => SurfaceSpec::Hemisphere(num(res)?),
            "disk" => SurfaceSpec::Disk(num(res)?),
            _ => bail!(
                "'{spec}': unknown method '{name}' (hemicube, sillion, recker, hemisphere-uniform, hemisphere, disk)"
            ),
        };
        parsed.build()?;
        Ok(parsed)
    }

    /// The surface.
    pub fn build(&self) -> Result<Box<dyn ProjectionSurface>> {
        Ok(match *self {
            SurfaceSpec::Hemicube(r) => Box::new(hemicube::Hemicube::new(r)?),
            SurfaceSpec::Sillion(r) => Box::new(sillion::SillionPlane::new(r)?),
            SurfaceSpec::Recker(a, b) => Box::new(recker::ReckerPlane::new(a, b)?),
            SurfaceSpec::HemisphereUniform(r) => Box::new(hemisphere_uniform::UniformHemisphere::new(r)?),
            SurfaceSpec::Hemisphere(r) => Box::new(hemisphere::Hemisphere::new(r)?),
            SurfaceSpec::Disk(r) => Box::new(disk::Disk::new(r)?),
        })
    }
}

/// [`SurfaceSpec::parse`], then [`SurfaceSpec::build`].
impl fmt::Display for SurfaceSpec {
    /// The CLI spelling, `METHOD:R` ([`SurfaceSpec::parse`] reads it back).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SurfaceSpec::Hemicube(r) => write!(f, "hemicube:{r}"),
            SurfaceSpec::Sillion(r) => write!(f, "sillion:{r}"),
            SurfaceSpec::Recker(r1, r2) => write!(f, "recker:{r1}/{r2}"),
            SurfaceSpec::HemisphereUniform(r) => write!(f, "hemisphere-uniform:{r}"),
            SurfaceSpec::Hemisphere(r) => write!(f, "hemisphere:{r}"),
            SurfaceSpec::Disk(r) => write!(f, "disk:{r}"),
        }
    }
}

/// Build the surface `METHOD:R` names.
pub fn parse_surface(spec: &str) -> Result<Box<dyn ProjectionSurface>> {
    SurfaceSpec::parse(spec)?.build()
}

#[cfg(test)]
pub(crate) mod testkit;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surfaces_parse_from_their_names() {
        for (spec, name, res) in [
            ("hemicube:64", "hemicube", "64"),
            ("sillion:31", "sillion", "31"),
            ("recker:36/13", "recker", "36/13"),
            ("hemisphere-uniform:20", "hemisphere-uniform", "20"),
            ("hemisphere:20", "hemisphere", "20"),
            ("disk:50", "disk", "50"),
        ] {
            let s = parse_surface(spec).unwrap();
            assert_eq!((s.name(), s.resolution().to_string()), (name, res.to_string()));
            assert_eq!(SurfaceSpec::parse(spec).unwrap().to_string(), spec);
        }
        for bad in [
            "hemicube",
            "hemicube:0",
            "hemicube:7",
            "disk:-3",
            "disk:1e9",
            "recker:40",
            "recker:10/x",
            "cube:8",
            "disk:99999",
        ] {
            let e = parse_surface(bad).err().unwrap_or_else(|| panic!("{bad} accepted"));
            assert!(e.to_string().contains(bad.split(':').next().unwrap()), "{bad}: {e}");
        }
    }

    /// `--form-factors` against an independent closed form: the Cornell box is closed but for
    /// its front opening (z = 0), and nothing stands above the tall block's top (y = 330), so a
    /// point on that top sees the box everywhere except through the opening's part above its
    /// plane, which it sees unoccluded. Each top patch's row sum must be 1 minus the
    /// sample-weighted form factor to that rectangle (the contour integral, Eq. 2.2), within
    /// the hemicube's aliasing along the rectangle's contour, sample-weighted too:
    /// `(2 δ L + 3 π δ²) / π` with δ = √2 / R (see `testkit`) and L the angles the rectangle's
    /// four edges subtend at the point. Every row is non-negative and sums to at most 1.
    ///
    /// (This test found the contour estimator counting the ceiling behind the coplanar light as
    /// well as the light — top-patch rows of 0.997 — fixed by `Reference::surfaces_see`.)
    #[test]
    fn projective_rows_of_the_block_top_match_the_opening() {
        use crate::truth::closed_form::point_to_polygon;
        use crate::truth::formfactor::{Estimator, FormFactors, Sampling};
        use std::f64::consts::PI;
        let mesh = crate::scene::load("cornell").unwrap();
        let patches = crate::scene::patches::subdivide(&mesh, 300.0, 200).unwrap();
        let top = |p: &crate::scene::patches::Patch| p.normal.y > 0.999 && (p.centroid.y - 330.0).abs() < 1.0;
        let tops: Vec<usize> = (0..patches.patches.len()).filter(|&i| top(&patches.patches[i])).collect();
        assert!(!tops.is_empty());
        let v = |x: f64, y: f64| Vector::new(x, y, 0.0);
        let opening = [v(0.0, 330.0), v(556.0, 330.0), v(556.0, 548.8), v(0.0, 548.8)];
        let into_box = Vector::new(0.0, 0.0, 1.0);
        // The angles the opening's edges subtend at x.
        let contour =
            |x: Vector| -> f64 { (0..4).map(|k| (opening[k] - x).angle_between(opening[(k + 1) % 4] - x)).sum() };
        for r in [32, 128] {
            let ff = FormFactors::new(
                &patches,
                Sampling { strata: 3, seed: 1, estimator: Estimator::Projective(SurfaceSpec::Hemicube(r)) },
            )
            .unwrap();
            let delta = std::f64::consts::SQRT_2 / r as f64;
            let bound = |x: Vector| (2.0 * delta * contour(x) + 3.0 * PI * delta * delta) / PI;
            for (i, row) in ff.matrix().iter().enumerate() {
                let sum: f64 = row.iter().sum();
                assert!(sum <= 1.0 + 1e-9 && row.iter().all(|&f| f >= 0.0), "R = {r}, row {i}: sum {sum}");
                if tops.contains(&i) {
                    let (n, samples) = (patches.patches[i].normal, ff.samples(i));
                    let area: f64 = samples.iter().map(|s| s.weight).sum();
                    let mean =
                        |f: &dyn Fn(Vector) -> f64| samples.iter().map(|s| s.weight * f(s.point)).sum::<f64>() / area;
                    let out = mean(&|x| point_to_polygon(x, n, &opening, into_box));
                    let (err, bound) = ((sum - (1.0 - out)).abs(), mean(&bound));
                    eprintln!(
                        "R = {r}, top patch {i}: row sum {sum:.4}, 1 − opening {:.4}, bound {bound:.4}",
                        1.0 - out
                    );
                    assert!(
                        err <= bound,
                        "R = {r}, top patch {i}: row sum {sum}, 1 − opening {}, bound {bound}",
                        1.0 - out
                    );
                }
            }
        }
    }

    #[test]
    fn octant_folding_covers_the_grid() {
        for r in [1, 2, 7, 8] {
            let mut seen = vec![false; octant_len(r)];
            for j in 0..r {
                for i in 0..r {
                    assert_eq!(octant_index(r, i, j), octant_index(r, j, i));
                    assert_eq!(octant_index(r, i, j), octant_index(r, r - 1 - i, j));
                    seen[octant_index(r, i, j)] = true;
                }
            }
            assert!(seen.iter().all(|&s| s), "r = {r}");
        }
    }
}

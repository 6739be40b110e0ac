//! Where the plane rule's shadow error comes from (thesis §5.5.6; docs/LIGHTING.md, "What it
//! does not fix"): the per-ray oracle's walk with one part of the rule replaced at a time by
//! exact geometry, each image shaded as the render shades and compared with the f64 reference.
//!
//! ```text
//! cargo run --release -p rc2-tests --example lit_bounds -- teapot-floor 128 [VARIANT ...]
//! cargo run --release -p rc2-tests --example lit_bounds -- ../shared/scenes/fandisk.obj 256 --light 0.8,0.3,0.7
//! ```
//!
//! A variant is `rule` (the plane rule as the machine runs it: the image equals
//! `render --view fitted`) or parts joined by `+`; without variants, those of BENCHMARKS
//! ([`DEFAULT_VARIANTS`]). Occluders:
//! * `empty-crossings` — a plane crossed (rule 4's crossing, the terminal step, "behind after
//!   empty space") stops a ray only where the crossing point lies in an occupied voxel;
//! * `exact` (also `exact-occluders`) — wherever the rule would stop a ray, it is stopped only
//!   if its segment meets a triangle of the mesh (f64);
//! * `complete` — `exact`, and a ray also stops wherever its segment meets a triangle that the
//!   rule lets it through (a voxel keeps one plane): occluders exactly the mesh;
//! * `own` — `exact` with only what a voxel's dexel knows: the triangles of its own plane near
//!   it (a ray crossing a neighbouring facet in that voxel is let through: light leaks);
//! * `local` — `complete` with what the two cells of a step know: segment [k − 1, k] is
//!   tested against the triangles through the columns of the ray's voxels at layers k − 1 and k
//!   (triangles sampled every tenth of a voxel);
//! * `cell`, `cellC` — `local` as a cell runs it: the loaded facets' lattice triangles, kept by
//!   every column they cross (`cell_core::occluder::Triangle::crosses_column`; at most C per
//!   column, in stream order, with `cellC`), tested by `cell_core::occluder::Occluder` in exact
//!   integers;
//! * `creases`, `rims` — `exact` only in the voxels two planes of the mesh pass through, or in
//!   the occupied voxels no triangle passes through (the conservative contour and the standard
//!   band around edges; triangles sampled every tenth of a voxel);
//! * `wedges` — creases and rims with what cells hold: a voxel next to another plane (within a
//!   voxel of its centre, in one of its 26 neighbours) takes the two planes as a solid's convex
//!   or concave wedge, or as a sheet bent along their line;
//! * `free` — no column rule (a ±z ray that stays in its column stops at the column's next
//!   dexel, for the machine's no-deadlock argument).
//!
//! The source: `source` (also `exact-source`) — the lattice rays leave from the light itself:
//! the machine's ray at layer k of a face is `S + (u, v)·k/D` with S the light across the
//! face's axis (sixteenths) but its voxel's centre along it (§4.3's layers are whole voxels from
//! the source voxel), up to half a voxel from the light; here the ray's distance along the axis
//! is counted from the light, `k − δ`, so every ray is a true ray from the light.
//!
//! The receivers. The machine lights a pixel by any lattice ray through its two bracketing
//! voxels on the light's side of its plane; at f = 0 about one or two rays cross a pixel's
//! footprint, a region around the point the reference samples. Instead:
//! * `point` — lit iff the ray to the pixel's own point (the visible plane on the column's
//!   centre line; a lattice ray at f = 8) gets there: with `complete+source`, the reference's
//!   own test but for the lattice rays;
//! * `truth` — no lattice: lit iff the machine's visible point faces the light and the f64 mesh
//!   lets it see it (the reference's own test at the machine's point, started 0.05 voxel
//!   toward the light): what is left is the error of the surfaces the machine sees;
//! * `reference` — no light at all: each covered pixel takes the reference's own lit flags
//!   (what shading and coverage alone cost);
//! * `nearest0`, `nearest1` — a receiver a cell can evaluate: one lattice ray at f = 0 or 1,
//!   the one nearest the pixel's point among those whose path crosses its bracketing voxels on
//!   the plane's outer side, must reach it.
//!
//! Each variant's line ends with its wrong pixels (light 1) sorted by what the machine shows
//! there ([`Why`]): the reference's facet (`light`), a coincident surface (`coincident`), a
//! surface past a silhouette edge the vertex lattice moved (`edge`), or `other`.
//!
//! `--refine` re-tests each variant's pixels on a shadow's edge (a covered 8-neighbour lit
//! otherwise) with `truth` and prints how many.
//!
//! `--cuts` (window receivers) also counts, per variant, the (face, voxel) groups the rays visit
//! and those where some rays stop and others go on: where a cell must cut its beams.
//!
//! f = 0, standard + conservative surfaces, the scene's own lights (or `--light`), the fitted view. f64
//! arithmetic where the variants need it: an experiment, not a cell.

use cell_core::beam::{frac, Direction, FarDistance, FracBits, Origin, Source, SourceCoord, SourceId};
use cell_core::occluder::{Occluder, Triangle};
use cell_core::receiver::target;
use cell_core::shade::NormalMode;
use cell_core::visible::VisibleSurface;
use host_sim::jobs::render::{reference_image, RenderConfig};
use host_sim::machine::loading::loaded_scene::LoadedScene;
use host_sim::machine::shading::pixels::Seen;
use host_sim::precompute::{Contour, LoadConfig, Thickness};
use host_sim::truth::visibility::Reference;
use rayon::prelude::*;
use rc2_tests::oracle::lit::{plane_value, Surface, Visible};
use rc2_tests::oracle::rays::{dir_axes, ray_voxel, source_voxel};
use std::collections::BTreeMap;

#[path = "../tests/integration/common/mod.rs"]
mod common;

/// How a pixel's visible surface is tested.
#[derive(Clone, Copy, PartialEq)]
enum Receiver {
    /// The machine's: lit by any lattice ray through its two bracketing voxels.
    Window,
    /// Lit iff the ray from the source to the surface's point on the column's centre line
    /// reaches it (a lattice ray at f = [`POINT_F`]: the exact ray to within 2⁻⁸ voxel).
    Point,
    /// Lit iff one lattice ray at f fraction bits reaches it: of the rays whose path crosses
    /// the two bracketing voxels on the plane's outer side (without obstacles), the one
    /// nearest the exact ray to the surface's point — a sample the cell can name from its own
    /// geometry.
    Nearest(u32),
    /// `Nearest` as a cell computes it (`cell_core::receiver::target`, exact integers, from the
    /// machine's visible surface): the target ray must reach its voxel, and no triangle of the
    /// column or its 8 neighbours may cross the contact segment (`Target::shadowed_by`, and the
    /// neighbours' answers, `cell_core::receiver::crosses_any`).
    Target(u32),
    /// No lattice: lit iff the machine's visible point (the column's centre line on its
    /// visible facet's plane, z\*) faces the light and sees it through the mesh itself (f64,
    /// its own facet ignored) — the reference's test at the machine's point. What is left is
    /// the error of the surface the machine sees, not of its light.
    Truth,
    /// No light at all: each covered pixel takes the reference's own lit flags. What is left is
    /// the error of the shading and the coverage, the PSNR no lit rule can pass.
    Reference,
}

/// Which parts of the rule are replaced by exact geometry.
#[derive(Clone, Copy)]
struct Variant {
    empty_crossings: bool,
    exact_occluders: bool,
    exact_source: bool,
    receiver: Receiver,
    /// Exact occluders in the voxels that two planes of the mesh pass through.
    exact_creases: bool,
    /// Exact occluders in the occupied voxels that no triangle passes through (the rims that
    /// conservative contours and the standard band add around facets).
    exact_rims: bool,
    /// Exact occluders also stop a ray where the rule lets it through a triangle.
    complete: bool,
    /// Exact occluders from what the voxel's own dexel knows: the triangles of its own plane
    /// (near it) instead of the whole mesh.
    own_plane: bool,
    /// Exact occluders from what the two cells a step joins know: segment [k − 1, k] is tested
    /// against the triangles through the columns of the ray's voxels at layers k − 1 and k.
    local: bool,
    /// `local` with what a cell runs: the lattice triangles of the loaded facets, kept by the
    /// columns they cross (`Triangle::crosses_column`, at most this many per column, in stream
    /// order) and tested by `cell_core::occluder::Occluder` in exact integers.
    cell: Option<usize>,
    /// No column rule (a ±z ray staying in its column is not stopped by its column's next
    /// dexel: the rule's other stops, or triangles, stop it).
    free_columns: bool,
    /// Two planes in a voxel next to an edge: its own and the nearest other plane of a
    /// neighbouring voxel, as a convex (both) or concave (either) wedge of inside.
    wedges: bool,
}

const RULE: Variant = Variant {
    empty_crossings: false,
    exact_occluders: false,
    exact_source: false,
    receiver: Receiver::Window,
    exact_creases: false,
    exact_rims: false,
    complete: false,
    own_plane: false,
    local: false,
    cell: None,
    free_columns: false,
    wedges: false,
};

/// The variants BENCHMARKS quotes, run when none is named.
const DEFAULT_VARIANTS: [&str; 33] = [
    "rule",
    "empty-crossings",
    "exact-occluders",
    "exact-source",
    "point",
    "point+exact",
    "point+creases",
    "point+rims",
    "point+creases+rims",
    "creases+rims",
    "nearest0+creases+rims",
    "nearest1+creases+rims",
    "complete+source",
    "nearest0+source",
    "point+complete",
    "point+complete+source",
    "nearest0+complete+source",
    "nearest1+complete+source",
    "free",
    "point+complete+source+free",
    "wedges",
    "nearest0+wedges",
    "own",
    "local",
    "nearest0+local",
    "cell64",
    "target0+cell64",
    "target0+cell64+source",
    "target1+cell64+source",
    "target0+cell32+source",
    "target0+cell16+source",
    "truth",
    "reference",
];

/// A variant from its name: `rule`, or parts joined by `+` (see the file's doc).
fn parse_variant(name: &str) -> Option<Variant> {
    if name == "rule" {
        return Some(RULE);
    }
    let mut v = RULE;
    for part in name.split('+') {
        match part {
            "point" => v.receiver = Receiver::Point,
            "nearest0" => v.receiver = Receiver::Nearest(0),
            "nearest1" => v.receiver = Receiver::Nearest(1),
            "target0" => v.receiver = Receiver::Target(0),
            "target1" => v.receiver = Receiver::Target(1),
            "truth" => v.receiver = Receiver::Truth,
            "reference" => v.receiver = Receiver::Reference,
            "exact" | "exact-occluders" => v.exact_occluders = true,
            "complete" => (v.exact_occluders, v.complete) = (true, true),
            "own" => (v.exact_occluders, v.own_plane) = (true, true),
            "local" => (v.exact_occluders, v.complete, v.local) = (true, true, true),
            "cell" => (v.exact_occluders, v.complete, v.cell) = (true, true, Some(usize::MAX)),
            p if p.starts_with("cell") => {
                (v.exact_occluders, v.complete, v.cell) = (true, true, Some(p[4..].parse().ok()?));
            }
            "creases" => v.exact_creases = true,
            "rims" => v.exact_rims = true,
            "empty-crossings" => v.empty_crossings = true,
            "source" | "exact-source" => v.exact_source = true,
            "free" => v.free_columns = true,
            "wedges" => v.wedges = true,
            _ => return None,
        }
    }
    Some(v)
}

/// How far (voxels) toward the light the `truth` receiver starts its segment.
const TRUTH_OFFSET: f64 = 0.05;

/// Fraction bits of the one ray a point receiver walks.
const POINT_F: u32 = 8;

type Surfaces<'a> = &'a (dyn Fn(i64, i64, i64) -> Option<Surface> + Sync);
type Columns<'a> = &'a (dyn Fn(i64, i64) -> Option<Visible> + Sync);

/// One source seen by the walk: the oracle's lattice (D = n − 1, f = 0).
struct Walk<'a> {
    n: i64,
    d: i64,
    src: [i64; 3],
    sv: [i64; 3],
    surfaces: Surfaces<'a>,
    columns: Columns<'a>,
    mesh: &'a Reference,
    /// The mesh face of each facet id the machine loaded (the reference numbers faces).
    source_face: &'a [u32],
    origin: [f64; 3],
    voxel: f64,
    /// Rays from the light itself (the `exact-source` variant).
    exact_source: bool,
    /// Fraction bits of the rays walked (0 but for point receivers).
    f: u32,
    /// Voxels two planes of the mesh pass through, and voxels a triangle passes through.
    sampled: &'a Sampled,
    /// Each column's visible surface as the machine keeps it.
    visible: &'a (dyn Fn(i64, i64) -> Option<VisibleSurface> + Sync),
    /// The cells' triangle stores and this light's occluders (`cell` variants).
    cells: &'a CellStores,
    /// `cells`' occluders of each triangle for this light, by direction.
    occluders: &'a [[Option<Occluder>; 6]],
}

impl Walk<'_> {
    /// 16 × the distance along the face's axis from the ray's origin to layer t: 16·t for the
    /// machine's rays, 16·t − sign·(S_w − 16·V_w) from the light itself.
    fn t16(&self, dir: usize, t: i64) -> i128 {
        let (w, sign, _, _) = dir_axes(dir);
        let lead = if self.exact_source { self.src[w] - 16 * self.sv[w] } else { 0 };
        16 * t as i128 - (sign * lead) as i128
    }

    /// How many layers cell_core's numbering of this face's layers is ahead of the walk's:
    /// from the light, a face whose light lies behind the source voxel's centre plane numbers
    /// its layers from the slab behind ([`Source::slab`]); the walk's layer k is its k + 1.
    fn shift(&self, dir: usize) -> i64 {
        let (w, sign, _, _) = dir_axes(dir);
        (self.exact_source && sign * (self.src[w] - 16 * self.sv[w]) < 0) as i64
    }

    /// The voxel of ray (dir, a, b) at layer k: the oracle's [`ray_voxel`], or the same
    /// rounding (`⌊x + ½⌋`, exact) of the true ray from the light.
    fn voxel(&self, dir: usize, a: i64, b: i64, k: i64) -> [i64; 3] {
        if !self.exact_source {
            return ray_voxel(self.n, self.src, dir, a, b, self.d, self.f, k);
        }
        let (w, sign, ua, va) = dir_axes(dir);
        let scale = (self.d as i128) << self.f;
        let across = |c: i64, o: i64| ((c as i128 + 8) * scale + o as i128 * self.t16(dir, k)).div_euclid(16 * scale);
        let mut p = [0; 3];
        p[w] = self.sv[w] + sign * k;
        p[ua] = across(self.src[ua], a) as i64;
        p[va] = across(self.src[va], b) as i64;
        p
    }

    /// Whether `var` takes the occluder in voxel p as exact.
    fn exact_at(&self, var: Variant, p: [i64; 3]) -> bool {
        var.exact_occluders
            || (var.exact_creases && self.sampled.creases.contains(&p))
            || (var.exact_rims && !self.sampled.touched.contains(&p))
    }

    /// `plane_value` of the oracle, or the same scaled plane value at the true ray's point.
    fn value(&self, s: &Surface, p: [i64; 3], dir: usize, a: i64, b: i64, t: i64) -> i128 {
        if !self.exact_source {
            return plane_value(s, p[0], p[1], self.src, dir, a, b, self.d, self.f, t);
        }
        let (w, sign, ua, va) = dir_axes(dir);
        let (df, tt) = ((self.d as i128) << self.f, self.t16(dir, t));
        let reference = [p[0] as i128, p[1] as i128, s.lo as i128];
        let mut lp = [0i128; 3];
        lp[w] = 16 * df * (self.sv[w] as i128 + sign as i128 * t as i128 - reference[w]);
        lp[ua] = df * self.src[ua] as i128 + a as i128 * tt - 16 * df * reference[ua];
        lp[va] = df * self.src[va] as i128 + b as i128 * tt - 16 * df * reference[va];
        Self::scaled(s, lp, 16 * df)
    }

    /// `2¹⁶·L·g` from `L·(point − reference)`, as the oracle's `plane_value` combines it.
    fn scaled(s: &Surface, lp: [i128; 3], l: i128) -> i128 {
        (s.nx as i128 * lp[0] + s.ny as i128 * lp[1]) * 65536 + s.nz as i128 * lp[2] + 65536 * l * s.e as i128
    }

    /// Whether the source is on the front side of `s` (voxel p): the layer-0 point of the
    /// machine's rays, or the light itself.
    fn source_in_front(&self, s: &Surface, p: [i64; 3], dir: usize) -> bool {
        if !self.exact_source {
            return self.value(s, p, dir, 0, 0, 0) > 0;
        }
        let l = 16 * self.d as i128;
        let reference = [p[0] as i128, p[1] as i128, s.lo as i128];
        Self::scaled(s, [0, 1, 2].map(|i| self.d as i128 * self.src[i] as i128 - l * reference[i]), l) > 0
    }

    /// The ray's point of parameter t, in voxel-centre coordinates.
    fn point(&self, dir: usize, a: i64, b: i64, t: f64) -> [f64; 3] {
        let (w, sg, ua, va) = dir_axes(dir);
        let dist = t + self.t16(dir, 0) as f64 / 16.0;
        let mut p = [0.0; 3];
        p[w] = self.sv[w] as f64 + sg as f64 * t;
        let df = self.d as f64 * (1u64 << self.f) as f64;
        p[ua] = self.src[ua] as f64 / 16.0 + a as f64 * dist / df;
        p[va] = self.src[va] as f64 / 16.0 + b as f64 * dist / df;
        p
    }

    /// Whether the ray's segment between parameters t0 and t1 meets a triangle.
    fn meets_mesh(&self, dir: usize, a: i64, b: i64, t0: f64, t1: f64) -> bool {
        let world = |p: [f64; 3]| [0, 1, 2].map(|i| self.origin[i] + (p[i] + 0.5) * self.voxel);
        !self.mesh.visible(world(self.point(dir, a, b, t0)), world(self.point(dir, a, b, t1)), &[])
    }

    /// Whether segment [k − 1, k] of the ray meets a triangle through the column of its voxel
    /// at layer k − 1 or k: what the two cells of the step know.
    fn meets_local(&self, dir: usize, a: i64, b: i64, k: i64) -> bool {
        let (q0, q1) = (self.point(dir, a, b, (k - 1) as f64), self.point(dir, a, b, k as f64));
        self.step_columns(dir, a, b, k).iter().any(|c| {
            self.sampled
                .by_column
                .get(c)
                .is_some_and(|ts| ts.iter().any(|&t| segment_meets_triangle(q0, q1, &self.sampled.tris[t])))
        })
    }

    /// `meets_local` as a cell runs it: the first `cap` triangles of each column's store, by
    /// the exact occluder test.
    fn meets_cell(&self, dir: usize, a: i64, b: i64, k: i64, cap: usize) -> bool {
        self.step_columns(dir, a, b, k).iter().any(|c| {
            self.cells.by_column.get(c).is_some_and(|ts| {
                let k = k + self.shift(dir);
                ts.iter().take(cap).any(|&t| self.occluders[t][dir].is_some_and(|o| o.meets(a, b, k)))
            })
        })
    }

    /// The columns of the ray's voxels at layers k − 1 and k (one when they are the same).
    fn step_columns(&self, dir: usize, a: i64, b: i64, k: i64) -> Vec<[i64; 2]> {
        let (p, q) = (self.voxel(dir, a, b, k - 1), self.voxel(dir, a, b, k));
        if (p[0], p[1]) == (q[0], q[1]) {
            vec![[q[0], q[1]]]
        } else {
            vec![[p[0], p[1]], [q[0], q[1]]]
        }
    }

    /// Whether the ray's segment between parameters t0 and t1 (= k) meets an occluder as the
    /// variant holds them: a cell's store (`cell`), the two columns' sampled triangles
    /// (`local`, both on [k − 1, k]), or the whole mesh.
    fn meets_segment(&self, var: Variant, dir: usize, a: i64, b: i64, t0: f64, t1: f64) -> bool {
        if let Some(cap) = var.cell {
            self.meets_cell(dir, a, b, t1.round() as i64, cap)
        } else if var.local {
            self.meets_local(dir, a, b, t1.round() as i64)
        } else {
            self.meets_mesh(dir, a, b, t0, t1)
        }
    }

    /// `meets_segment`, or with `own` only the triangles of the plane of `s` (voxel p) that pass
    /// through p or its 26 neighbours.
    #[allow(clippy::too_many_arguments)]
    fn meets(&self, var: Variant, s: &Surface, p: [i64; 3], dir: usize, a: i64, b: i64, t0: f64, t1: f64) -> bool {
        if var.cell.is_some() || var.local || !var.own_plane {
            return self.meets_segment(var, dir, a, b, t0, t1);
        }
        let placed = Placed { s: *s, col: [p[0], p[1]] };
        let (nrm, len) = placed.normal();
        let (q0, q1) = (self.point(dir, a, b, t0), self.point(dir, a, b, t1));
        // The triangles near p, with how parallel to the stored plane each is (vertices are
        // snapped to the loading lattice, so coplanar ones agree only to about 10⁻³).
        let mut cands: Vec<(f64, usize)> = Vec::new();
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(ids) = self.sampled.near.get(&[p[0] + dx, p[1] + dy, p[2] + dz]) else { continue };
                    for &t in ids {
                        let tri = &self.sampled.tris[t];
                        let tn = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
                        let tl = dot(tn, tn).sqrt();
                        if tl > 0.0
                            && tri.iter().all(|v| placed.distance(*v).abs() < 0.15)
                            && !cands.iter().any(|c| c.1 == t)
                        {
                            cands.push(((dot(tn, nrm) / (tl * len)).abs(), t));
                        }
                    }
                }
            }
        }
        let best = cands.iter().map(|c| c.0).fold(0.0, f64::max);
        cands.iter().any(|&(c, t)| c >= best - 1e-5 && segment_meets_triangle(q0, q1, &self.sampled.tris[t]))
    }

    /// Where the ray crosses the plane of `s` (voxel p) between layers t0 and t1: in voxel
    /// coordinates, if it does.
    fn crossing(&self, s: &Surface, p: [i64; 3], (dir, a, b): (usize, i64, i64), t0: i64, t1: i64) -> Option<[f64; 3]> {
        let (v0, v1) = (self.value(s, p, dir, a, b, t0) as f64, self.value(s, p, dir, a, b, t1) as f64);
        (v0 != v1 && (v0 > 0.0) != (v1 > 0.0))
            .then(|| self.point(dir, a, b, t0 as f64 + (t1 - t0) as f64 * v0 / (v0 - v1)))
    }

    /// Whether the ray crossed the plane of `s` between layers t0 and t1 in an occupied voxel
    /// (or did not cross it there at all: then nothing is known, and it counts as occupied).
    fn crossed_in_occupied(&self, s: &Surface, p: [i64; 3], ray: (usize, i64, i64), t0: i64, t1: i64) -> bool {
        let Some(q) = self.crossing(s, p, ray, t0, t1) else { return true };
        let v = q.map(|c| c.round() as i64);
        v.iter().all(|&c| (0..self.n).contains(&c)) && (self.surfaces)(v[0], v[1], v[2]).is_some()
    }

    /// One ray by the plane rule (`rc2_tests::oracle::lit`'s walk, restated) with `var`'s
    /// replacements; pushes the columns whose visible surface it lights.
    /// Returns the layer where the ray stops (`None`: it left the grid).
    fn ray(&self, dir: usize, a: i64, b: i64, var: Variant, out: &mut Vec<[i64; 2]>) -> Option<i64> {
        let (n, d, z_ray) = (self.n, self.d, dir >= 4);
        let mut terminal: Option<(Surface, [i64; 3], i64)> = None;
        let (mut column, mut outside, mut from_empty) = (None, false, false);
        for k in 0..=d {
            let p = self.voxel(dir, a, b, k);
            if p.iter().any(|&c| !(0..n).contains(&c)) {
                return None;
            }
            let next = self.voxel(dir, a, b, k + 1);
            let stays = z_ray && k < d && p[0] == next[0] && p[1] == next[1];
            let own = (self.surfaces)(p[0], p[1], p[2]);
            let prev = (k - 1).max(0);
            let sigma = |s: &Surface, t: i64| self.value(s, p, dir, a, b, t) > 0;
            // Rule 1: the visible surface.
            if let Some(v) = (self.columns)(p[0], p[1]) {
                if (p[2] == v.z_v || p[2] == v.z_v + 1)
                    && self.source_in_front(&v.plane, p, dir)
                    && (sigma(&v.plane, k) || sigma(&v.plane, prev))
                {
                    out.push([p[0], p[1]]);
                }
            }
            if var.complete && k > 0 && self.meets_segment(var, dir, a, b, (k - 1) as f64, k as f64) {
                return Some(k);
            }
            let from_outside = std::mem::take(&mut outside);
            // Rule 2: a terminal ray dies.
            if let Some((s, q, tk)) = terminal.take() {
                let dies = if self.exact_at(var, q) {
                    self.meets(var, &s, q, dir, a, b, tk as f64, k as f64)
                } else {
                    !var.empty_crossings || own.is_some() || self.crossed_in_occupied(&s, q, (dir, a, b), tk, k)
                };
                if dies {
                    return Some(k);
                }
            }
            if let Some(w) = var.wedges.then(|| self.wedge(p)).flatten() {
                let at = |i: i64| self.point(dir, a, b, (k - 1) as f64 + i as f64 / 16.0);
                let in_cube = |q: [f64; 3]| (0..3).all(|j| (q[j] - p[j] as f64).abs() <= 0.5);
                if let Some(i) = (0..=32).find(|&i| {
                    let q = at(i);
                    in_cube(q) && if i == 0 { w.inside(q) } else { w.enters(at(i - 1), q) }
                }) {
                    return Some(k - 1 + (i + 15) / 16);
                }
                column = (z_ray && stays).then_some(w.a.s.lo);
                outside = !stays;
                from_empty = false;
                continue;
            }
            // Rule 3: empty space.
            let Some(s) = own else {
                if z_ray && !stays {
                    column = None;
                }
                from_empty = true;
                continue;
            };
            // Rule 4.
            let (was, now, then, faces) =
                (sigma(&s, prev), sigma(&s, k), sigma(&s, k + 1), self.source_in_front(&s, p, dir));
            let stop = |t0: i64| {
                if self.exact_at(var, p) {
                    self.meets(var, &s, p, dir, a, b, t0 as f64, k as f64)
                } else {
                    !var.empty_crossings || self.crossed_in_occupied(&s, p, (dir, a, b), t0, k)
                }
            };
            if was != now && stop(prev) {
                return Some(k);
            }
            let behind = ((from_empty && (faces || !s.two_sided)) || (from_outside && faces)) && !was && !now;
            if behind && stop(0) {
                return Some(k);
            }
            if z_ray && stays && column.is_some_and(|c| c != s.lo) && !var.free_columns {
                return Some(k);
            }
            if now != then {
                terminal = Some((s, p, k));
            }
            column = (z_ray && stays).then_some(s.lo);
            outside = now && !stays;
            from_empty = false;
        }
        None
    }

    /// Voxel p's wedge: its own plane and, of its 26 neighbours' planes of another normal
    /// passing within a voxel of its centre, the nearest, if the two say which side is inside.
    fn wedge(&self, p: [i64; 3]) -> Option<Wedge> {
        let own = (self.surfaces)(p[0], p[1], p[2])?;
        let a = Placed { s: own, col: [p[0], p[1]] };
        let centre = p.map(|c| c as f64);
        let mut best: Option<(f64, Placed, [i64; 3])> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let q = [p[0] + dx, p[1] + dy, p[2] + dz];
                    if q.iter().any(|&c| !(0..self.n).contains(&c)) {
                        continue;
                    }
                    let Some(s) = (self.surfaces)(q[0], q[1], q[2]) else { continue };
                    if s.two_sided != own.two_sided || (s.nx, s.ny, s.nz) == (own.nx, own.ny, own.nz) {
                        continue;
                    }
                    let b = Placed { s, col: [q[0], q[1]] };
                    let dist = b.distance(centre).abs();
                    if dist < 1.0 && best.as_ref().is_none_or(|(d, _, _)| dist < *d) {
                        best = Some((dist, b, q));
                    }
                }
            }
        }
        let (_, b, q) = best?;
        // Each plane's point nearest its own voxel's centre: on the other's inner side at a
        // convex edge, on its outer side at a concave one.
        let (ca, cb) = (a.foot(centre), b.foot(q.map(|c| c as f64)));
        let (ga, gb) = (b.distance(ca), a.distance(cb));
        let convex = match (own.two_sided, ga < 0.0, gb < 0.0) {
            (true, _, _) => None,
            (false, true, true) => Some(true),
            (false, false, false) => Some(false),
            _ => return None,
        };
        Some(Wedge { a, b, convex, sides: (ga > 0.0, gb > 0.0) })
    }

    /// A point or nearest-ray receiver: whether column c's visible surface is lit.
    fn receiver_lit(&self, c: [i64; 2], v: &Visible, var: Variant) -> bool {
        match var.receiver {
            Receiver::Target(f) => return self.target_lit(c, f, var),
            Receiver::Truth => return self.truth_lit(c),
            _ => {}
        }
        let s = &v.plane;
        // The plane at the column's centre: g = nz/2¹⁶·dz + e = 0.
        let z = v.z_v as f64 - 65536.0 * s.e as f64 / s.nz as f64;
        let p = [c[0] as f64, c[1] as f64, z];
        let scale = self.d as f64 * (1u64 << self.f) as f64;
        let Some((dir, k, a, b)) = (0..6).find_map(|dir| {
            let (w, sign, ua, va) = dir_axes(dir);
            let k = sign as f64 * (p[w] - self.sv[w] as f64);
            // The ray's distance along the axis from its origin (the layer-0 point, or the light).
            let dist = k + self.t16(dir, 0) as f64 / 16.0;
            let a = (p[ua] - self.src[ua] as f64 / 16.0) * scale / dist;
            let b = (p[va] - self.src[va] as f64 / 16.0) * scale / dist;
            (k > 0.0 && dist > 0.0 && a.abs() <= scale && b.abs() <= scale).then_some((dir, k, a, b))
        }) else {
            return false;
        };
        if !self.source_in_front(s, [c[0], c[1], v.z_v], dir) {
            return false;
        }
        if var.receiver == Receiver::Point {
            let stop = self.ray(dir, a.round() as i64, b.round() as i64, var, &mut Vec::new());
            return stop.is_none_or(|t| t as f64 >= k.ceil());
        }
        let Some((ra, rb)) = self.nearest_through(dir, [c[0], c[1]], s, v.z_v, a, b) else {
            return false;
        };
        let mut out = Vec::new();
        self.ray(dir, ra, rb, var, &mut out);
        out.contains(&c)
    }

    /// [`Receiver::Truth`]: the reference's test at the machine's visible point.
    fn truth_lit(&self, c: [i64; 2]) -> bool {
        let Some(vis) = (self.visible)(c[0], c[1]) else { return false };
        let z = vis.num as f64 / vis.den as f64;
        let world = |p: [f64; 3]| [0, 1, 2].map(|i| self.origin[i] + (p[i] + 0.5) * self.voxel);
        let light = self.src.map(|s| s as f64 / 16.0);
        let p = [c[0] as f64, c[1] as f64, z];
        // The visible plane (oriented toward the viewer) at p: the light must be on its side.
        let s = &vis.plane;
        let g = |q: [f64; 3]| {
            s.nx as f64 * (q[0] - p[0]) + s.ny as f64 * (q[1] - p[1]) + s.nz as f64 / 65536.0 * (q[2] - p[2])
        };
        // Start a hair toward the light: at z* exactly, the neighbouring facets of the same
        // surface (their own lattice planes) shadow the point by rounding.
        let len = (0..3).map(|i| (light[i] - p[i]).powi(2)).sum::<f64>().sqrt();
        let p = [0, 1, 2].map(|i| p[i] + TRUTH_OFFSET * (light[i] - p[i]) / len);
        let face = self.source_face.get(vis.facet as usize).copied().unwrap_or(u32::MAX);
        g(light) > 0.0 && self.mesh.visible(world(p), world(light), &[face])
    }

    /// The cell's receiver: whether column c's target ray reaches its voxel.
    fn target_lit(&self, c: [i64; 2], f: u32, var: Variant) -> bool {
        let Some(vis) = (self.visible)(c[0], c[1]) else { return false };
        let origin = if self.exact_source { Origin::Light } else { Origin::SourceVoxel };
        let source = Source::new(SourceId(0), self.src.map(|x| SourceCoord::from_bits(x as i32))).with_origin(origin);
        let (x, y, n) = (c[0] as i32, c[1] as i32, self.n as u32);
        let t = match f {
            0 => target(x, y, &vis, &source, FarDistance::<frac::U0>::new(n - 1).expect("far")),
            _ => target(x, y, &vis, &source, FarDistance::<frac::U1>::new(n - 1).expect("far")),
        };
        let Some(t) = t else { return false };
        let dir = (0..6).find(|&d| oracle_direction(d) == t.dir).expect("six directions");
        let stop = self.ray(dir, t.a, t.b, var, &mut Vec::new());
        // The cell's contact test: its own triangles and its 8 neighbours' (each store's first
        // `cap`) against the segment from the light to just in front of the pixel.
        let cap = var.cell.unwrap_or(usize::MAX);
        let kept = |q: [i64; 2]| self.cells.by_column.get(&q).map_or(&[][..], |ts| &ts[..ts.len().min(cap)]);
        let around = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| [c[0] + dx, c[1] + dy]));
        let tris: Vec<Triangle> = around.flat_map(kept).map(|&i| self.cells.tris[i]).collect();
        stop.is_none_or(|k| k >= t.layer as i64 - self.shift(dir)) && !t.shadowed_by(&tris)
    }

    /// Of the lattice rays (f = `self.f`) whose path crosses voxel (c, z_v) or (c, z_v + 1) on
    /// the outer side of the column's visible plane, the one nearest (a, b).
    fn nearest_through(
        &self,
        dir: usize,
        c: [i64; 2],
        plane: &Surface,
        z_v: i64,
        a: f64,
        b: f64,
    ) -> Option<(i64, i64)> {
        let (w, sign, ua, va) = dir_axes(dir);
        let scale = (self.d as i128) << self.f;
        // The offsets t whose voxel across the axis is q at layer k (`voxel`'s rounding):
        // 16·scale·q ≤ (src + 8)·scale + t·t16(k) < 16·scale·(q + 1).
        let range = |src: i64, q: i64, den: i128| {
            let lo = 16 * scale * q as i128 - (src as i128 + 8) * scale;
            let hi = lo + 16 * scale - 1;
            (lo.div_euclid(den) + i128::from(lo.rem_euclid(den) != 0), hi.div_euclid(den))
        };
        let mut best: Option<(f64, i64, i64)> = None;
        for z in [z_v, z_v + 1] {
            let q = [c[0], c[1], z];
            let k = sign * (q[w] - self.sv[w]);
            let den = self.t16(dir, k);
            if k <= 0 || den <= 0 {
                continue;
            }
            let (a0, a1) = range(self.src[ua], q[ua], den);
            let (b0, b1) = range(self.src[va], q[va], den);
            let (a0, a1, b0, b1) = (a0.max(-scale), a1.min(scale), b0.max(-scale), b1.min(scale));
            if a0 > a1 || b0 > b1 {
                continue;
            }
            // Only rays on the plane's outer side there (rule 1's test), searched near (a, b).
            let (ca, cb) = ((a.round() as i128).clamp(a0, a1), (b.round() as i128).clamp(b0, b1));
            let outer = |ta: i64, tb: i64| {
                self.value(plane, q, dir, ta, tb, k) > 0 || self.value(plane, q, dir, ta, tb, (k - 1).max(0)) > 0
            };
            for ta in (ca - 24).max(a0)..=(ca + 24).min(a1) {
                for tb in (cb - 24).max(b0)..=(cb + 24).min(b1) {
                    let dist = (ta as f64 - a).powi(2) + (tb as f64 - b).powi(2);
                    if best.is_none_or(|(d, _, _)| dist < d) && outer(ta as i64, tb as i64) {
                        best = Some((dist, ta as i64, tb as i64));
                    }
                }
            }
        }
        best.map(|(_, ta, tb)| (ta, tb))
    }
}

/// A stored plane with the column it is referenced to.
#[derive(Clone, Copy)]
struct Placed {
    s: Surface,
    col: [i64; 2],
}

impl Placed {
    /// The stored normal (z with its 16 extra fraction bits removed) and its length.
    fn normal(&self) -> ([f64; 3], f64) {
        let n = [self.s.nx as f64, self.s.ny as f64, self.s.nz as f64 / 65536.0];
        (n, (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt())
    }

    /// Signed distance (voxels) of point q from the plane, positive outside.
    fn distance(&self, q: [f64; 3]) -> f64 {
        let (n, len) = self.normal();
        let g = n[0] * (q[0] - self.col[0] as f64)
            + n[1] * (q[1] - self.col[1] as f64)
            + n[2] * (q[2] - self.s.lo as f64)
            + self.s.e as f64;
        g / len
    }

    /// The point of the plane nearest q.
    fn foot(&self, q: [f64; 3]) -> [f64; 3] {
        let (n, len) = self.normal();
        let d = self.distance(q);
        [0, 1, 2].map(|i| q[i] - d * n[i] / len)
    }
}

/// Two planes near an edge: a solid's convex (both) or concave (either) wedge of inside, or
/// a sheet bent along the edge (each plane on its own side of the other).
struct Wedge {
    a: Placed,
    b: Placed,
    /// For a solid: whether the edge is convex.
    convex: Option<bool>,
    /// The side of the other plane each plane's real part lies on.
    sides: (bool, bool),
}

impl Wedge {
    fn inside(&self, q: [f64; 3]) -> bool {
        let (ia, ib) = (self.a.distance(q) < 0.0, self.b.distance(q) < 0.0);
        match self.convex {
            Some(true) => ia && ib,
            Some(false) => ia || ib,
            None => false,
        }
    }

    /// Whether the step q0 → q1 enters the inside, or crosses a real part of the sheet.
    fn enters(&self, q0: [f64; 3], q1: [f64; 3]) -> bool {
        if self.convex.is_some() {
            return !self.inside(q0) && self.inside(q1);
        }
        let crosses = |p: &Placed, o: &Placed, side: bool| {
            let (g0, g1) = (p.distance(q0), p.distance(q1));
            if (g0 > 0.0) == (g1 > 0.0) {
                return false;
            }
            let t = g0 / (g0 - g1);
            let x = [0, 1, 2].map(|i| q0[i] + t * (q1[i] - q0[i]));
            (o.distance(x) > 0.0) == side
        };
        crosses(&self.a, &self.b, self.sides.0) || crosses(&self.b, &self.a, self.sides.1)
    }
}

/// The loaded facets' lattice triangles (sixteenths, voxel centres at multiples of 16) and the
/// triangles each column keeps, in stream order.
struct CellStores {
    tris: Vec<Triangle>,
    by_column: std::collections::HashMap<[i64; 2], Vec<usize>>,
}

impl CellStores {
    fn new(polygons: &[Vec<[i64; 3]>], n: i64) -> Self {
        let mut tris = Vec::new();
        for poly in polygons {
            // The precompute's lattice is X = 16·x + 8.
            let v: Vec<[i32; 3]> = poly.iter().map(|p| p.map(|c| (c - 8) as i32)).collect();
            for k in 1..v.len().saturating_sub(1) {
                tris.extend(Triangle::new([v[0], v[k], v[k + 1]]));
            }
        }
        let mut by_column: std::collections::HashMap<[i64; 2], Vec<usize>> = Default::default();
        for (i, t) in tris.iter().enumerate() {
            let range = |c: usize| {
                let lo = t.vertices().iter().map(|v| v[c] as i64).min().unwrap_or(0);
                let hi = t.vertices().iter().map(|v| v[c] as i64).max().unwrap_or(0);
                ((lo - 8).div_euclid(16).max(0), (hi + 8 + 15).div_euclid(16).min(n - 1))
            };
            let ((x0, x1), (y0, y1)) = (range(0), range(1));
            for x in x0..=x1 {
                for y in y0..=y1 {
                    if t.crosses_column(x as i32, y as i32) {
                        by_column.entry([x, y]).or_default().push(i);
                    }
                }
            }
        }
        let mut sizes: Vec<usize> = by_column.values().map(Vec::len).collect();
        sizes.sort_unstable();
        let over = |cap: usize| sizes.iter().filter(|&&s| s > cap).count();
        println!(
            "cell stores: {} triangles, {} columns keep one or more: mean {:.1}, median {}, max {}; over 16 / 32 / 64: {} / {} / {} columns",
            tris.len(),
            sizes.len(),
            sizes.iter().sum::<usize>() as f64 / sizes.len().max(1) as f64,
            sizes.get(sizes.len() / 2).unwrap_or(&0),
            sizes.last().unwrap_or(&0),
            over(16),
            over(32),
            over(64)
        );
        CellStores { tris, by_column }
    }

    /// Each triangle's occluder for the rays of one light (source position in sixteenths) in
    /// each direction, at f fraction bits.
    fn occluders(&self, src: [i64; 3], n: u32, f: u32, exact_source: bool) -> Vec<[Option<Occluder>; 6]> {
        let origin = if exact_source { Origin::Light } else { Origin::SourceVoxel };
        let source = Source::new(SourceId(0), src.map(|c| SourceCoord::from_bits(c as i32))).with_origin(origin);
        fn build<F: FracBits>(t: &Triangle, s: &Source, n: u32) -> [Option<Occluder>; 6] {
            let far = FarDistance::<F>::new(n - 1).expect("far distance");
            [0, 1, 2, 3, 4, 5].map(|dir| Occluder::new(t, s, oracle_direction(dir), far))
        }
        self.tris
            .par_iter()
            .map(|t| match f {
                0 => build::<frac::U0>(t, &source, n),
                1 => build::<frac::U1>(t, &source, n),
                _ => build::<frac::U8>(t, &source, n),
            })
            .collect()
    }
}

/// How often the rays one cell holds at a layer (one face's rays in one voxel: what its beams
/// there carry) meet different fates: some stop, some go on. Each such group needs its beams
/// cut; the count of groups visited is what the machine's beam steps grow with.
struct Cuts {
    n: usize,
    /// Per (face, voxel): bit 0 a ray went on, bit 1 a ray stopped.
    fate: Vec<std::sync::atomic::AtomicU8>,
}

impl Cuts {
    fn new(n: usize) -> Self {
        Cuts { n, fate: (0..6 * n * n * n).map(|_| std::sync::atomic::AtomicU8::new(0)).collect() }
    }

    fn record(&self, walk: &Walk, dir: usize, a: i64, b: i64, stop: Option<i64>) {
        let last = stop.unwrap_or(walk.d);
        for k in 0..=last {
            let p = walk.voxel(dir, a, b, k);
            if p.iter().any(|&c| !(0..self.n as i64).contains(&c)) {
                break;
            }
            let i = ((dir * self.n + p[0] as usize) * self.n + p[1] as usize) * self.n + p[2] as usize;
            let bit = if stop == Some(k) { 2 } else { 1 };
            self.fate[i].fetch_or(bit, std::sync::atomic::Ordering::Relaxed);
        }
    }

    fn report(&self, name: &str, light: usize) {
        let (mut visited, mut mixed) = (0u64, 0u64);
        for f in &self.fate {
            let v = f.load(std::sync::atomic::Ordering::Relaxed);
            visited += (v != 0) as u64;
            mixed += (v == 3) as u64;
        }
        println!(
            "{name} light {}: {visited} (face, voxel) groups visited, {mixed} with rays that stop and rays that go on ({:.2} %)",
            light + 1,
            100.0 * mixed as f64 / visited.max(1) as f64
        );
    }
}

/// The cell's direction of the oracle's direction index (`dir_axes`).
fn oracle_direction(dir: usize) -> Direction {
    let (w, sign, _, _) = dir_axes(dir);
    Direction::ALL.into_iter().find(|d| d.principal().index() == w && d.sign() as i64 == sign).expect("six directions")
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[i] - b[i])
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether segment q0–q1 meets triangle `t` (Möller–Trumbore, closed).
fn segment_meets_triangle(q0: [f64; 3], q1: [f64; 3], t: &[[f64; 3]; 3]) -> bool {
    let d = [0, 1, 2].map(|i| q1[i] - q0[i]);
    let e1 = [0, 1, 2].map(|i| t[1][i] - t[0][i]);
    let e2 = [0, 1, 2].map(|i| t[2][i] - t[0][i]);
    let h = cross(d, e2);
    let det = dot(e1, h);
    if det.abs() < 1e-12 {
        return false;
    }
    let s = [0, 1, 2].map(|i| q0[i] - t[0][i]);
    let u = dot(s, h) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    let w = dot(e2, q) / det;
    (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && (0.0..=1.0).contains(&w)
}

/// Voxels of the mesh found by sampling every triangle at a tenth of a voxel.
struct Sampled {
    /// The triangles in voxel-centre coordinates.
    tris: Vec<[[f64; 3]; 3]>,
    /// The triangles passing through each column.
    by_column: std::collections::HashMap<[i64; 2], Vec<usize>>,
    /// The triangles passing through each voxel.
    near: std::collections::HashMap<[i64; 3], Vec<usize>>,
    /// Voxels that triangles of two different planes pass through.
    creases: std::collections::HashSet<[i64; 3]>,
    /// Voxels a triangle passes through.
    touched: std::collections::HashSet<[i64; 3]>,
}

/// The voxels (centre coordinates rounded) the mesh's triangles pass through, and those that
/// triangles of two different planes pass through, found by sampling every triangle at a tenth
/// of a voxel; prints how many triangles pass through an occupied column.
fn sample_mesh(tris: &[[[f64; 3]; 3]], origin: [f64; 3], voxel: f64) -> Sampled {
    let mut planes: std::collections::HashMap<[i64; 3], Vec<[i64; 4]>> = Default::default();
    let mut per_column: std::collections::HashMap<[i64; 2], std::collections::HashSet<usize>> = Default::default();
    let mut near: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    let mut in_voxels = Vec::new();
    for (ti, t) in tris.iter().enumerate() {
        let q = t.map(|p| [0, 1, 2].map(|i| (p[i] - origin[i]) / voxel - 0.5));
        in_voxels.push(q);
        let e1 = [0, 1, 2].map(|i| q[1][i] - q[0][i]);
        let e2 = [0, 1, 2].map(|i| q[2][i] - q[0][i]);
        let nrm = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        let len = nrm.iter().map(|c| c * c).sum::<f64>().sqrt();
        if len == 0.0 {
            continue;
        }
        let u = nrm.map(|c| c / len);
        let off = u[0] * q[0][0] + u[1] * q[0][1] + u[2] * q[0][2];
        let key = [
            (u[0] * 1e3).round() as i64,
            (u[1] * 1e3).round() as i64,
            (u[2] * 1e3).round() as i64,
            (off * 100.0).round() as i64,
        ];
        let steps = (e1.iter().chain(e2.iter()).map(|c| c.abs()).fold(0.0, f64::max) * 10.0).ceil() as usize + 1;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (s, r) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let v = [0, 1, 2].map(|c| (q[0][c] + s * e1[c] + r * e2[c]).round() as i64);
                per_column.entry([v[0], v[1]]).or_default().insert(ti);
                let at = near.entry(v).or_default();
                if at.last() != Some(&ti) {
                    at.push(ti);
                }
                let e = planes.entry(v).or_default();
                if !e.contains(&key) {
                    e.push(key);
                }
            }
        }
    }
    let counts: Vec<usize> = per_column.values().map(|t| t.len()).collect();
    let mean = counts.iter().sum::<usize>() as f64 / counts.len().max(1) as f64;
    println!(
        "triangles through a column: mean {mean:.1}, max {} over {} columns",
        counts.iter().max().unwrap_or(&0),
        counts.len()
    );
    Sampled {
        by_column: per_column.iter().map(|(c, ts)| (*c, ts.iter().copied().collect())).collect(),
        tris: in_voxels,
        near,
        creases: planes.iter().filter(|(_, k)| k.len() > 1).map(|(v, _)| *v).collect(),
        touched: planes.into_keys().collect(),
    }
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--light X,Y,Z` (grid-normalised, repeatable), as `render` takes it.
    // `--cuts`: count the (face, voxel) groups of rays whose fates differ there (see `Cuts`).
    let cuts_flag = args.iter().position(|a| a == "--cuts").map(|i| args.remove(i)).is_some();
    let refine_flag = args.iter().position(|a| a == "--refine").map(|i| args.remove(i)).is_some();
    let mut cli_lights = Vec::new();
    while let Some(i) = args.iter().position(|a| a == "--light") {
        let parsed = args.get(i + 1).and_then(|v| {
            let c: Vec<f64> = v.split(',').filter_map(|c| c.parse().ok()).collect();
            <[f64; 3]>::try_from(c).ok()
        });
        let Some(l) = parsed else {
            eprintln!("lit_bounds: --light takes X,Y,Z");
            std::process::exit(2);
        };
        cli_lights.push(l);
        args.drain(i..i + 2);
    }
    let (Some(scene), Some(n)) = (args.first(), args.get(1).and_then(|s| s.parse::<u32>().ok())) else {
        eprintln!("usage: lit_bounds SCENE N [VARIANT ...] [--light X,Y,Z ...]  (variants: see the file's doc)");
        std::process::exit(2);
    };
    let names: Vec<&str> =
        if args.len() > 2 { args[2..].iter().map(String::as_str).collect() } else { DEFAULT_VARIANTS.to_vec() };
    let mut chosen = Vec::new();
    for name in names {
        let Some(var) = parse_variant(name) else {
            eprintln!("lit_bounds: unknown variant {name} (parts: see the file's doc)");
            std::process::exit(2);
        };
        chosen.push((name, var));
    }
    let mesh = host_sim::scene::load(scene).unwrap_or_else(|e| {
        eprintln!("{scene}: {e:#}");
        std::process::exit(1)
    });
    let cfg = LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative };
    let loaded = host_sim::machine::loading::loaded_scene::load_scene(&mesh, &cfg).expect("load");
    let lights =
        host_sim::machine::loading::loaded_scene::resolve_lights(&mesh, &loaded, &cli_lights).unwrap_or_else(|e| {
            eprintln!("{e:#}");
            std::process::exit(2)
        });
    let reference = reference_image(
        &mesh,
        &loaded,
        &lights,
        &RenderConfig::diffusion(host_sim::config::plane_rule(), NormalMode::Facet),
    )
    .expect("reference");
    let (triangles, facets) = host_sim::truth::refrender::mesh_triangles(&mesh).expect("triangles");
    let sampled = sample_mesh(&triangles, loaded.fit.origin, loaded.fit.voxel);
    let exact = Reference::new(triangles, facets).expect("reference mesh");
    let stores = if chosen.iter().any(|(_, v)| v.cell.is_some()) {
        let prepared = host_sim::precompute::prepare(&mesh, &cfg).expect("precompute");
        CellStores::new(&prepared.polygons, n as i64)
    } else {
        CellStores { tris: Vec::new(), by_column: Default::default() }
    };
    let (surfaces, columns) = (common::surfaces_of(&loaded.grid), common::columns_of(&loaded.grid));
    let visible_of = |x: i64, y: i64| loaded.grid.cell(x as u32, y as u32).visible;
    println!("{} voxels with two planes or more, {} with a triangle", sampled.creases.len(), sampled.touched.len());
    let cell_lights = host_sim::machine::shading::pixels::point_lights(&lights);
    println!(
        "{scene} n = {n}: variant, shadow disagreement, PSNR, pixels darker / brighter than the reference (light 1)"
    );
    for (i, light) in lights.iter().enumerate() {
        let src = host_sim::machine::lighting::diffuse::source_at(i, *light, n)
            .expect("source")
            .pos
            .map(|c| c.to_bits() as i64);
        let lead = [0, 1, 2].map(|w| (src[w] - 16 * source_voxel(src)[w]) as f64 / 16.0);
        println!("light {}: voxel {:?}, the light {lead:+?} voxel from its centre", i + 1, source_voxel(src));
    }
    for (name, var) in &chosen {
        let mut lit: BTreeMap<[i64; 2], u32> = BTreeMap::new();
        if var.receiver == Receiver::Reference {
            for (i, c) in loaded.grid.cells.iter().enumerate().filter(|&(i, _)| reference.covered[i]) {
                lit.insert([c.x as i64, c.y as i64], reference.lit[i]);
            }
        }
        for (i, light) in lights.iter().enumerate().filter(|_| var.receiver != Receiver::Reference) {
            let src = host_sim::machine::lighting::diffuse::source_at(i, *light, n)
                .expect("source")
                .pos
                .map(|c| c.to_bits() as i64);
            let f = match var.receiver {
                Receiver::Window | Receiver::Truth | Receiver::Reference => 0,
                Receiver::Point => POINT_F,
                Receiver::Nearest(f) | Receiver::Target(f) => f,
            };
            let occluders = if var.cell.is_some() { stores.occluders(src, n, f, var.exact_source) } else { Vec::new() };
            let walk = Walk {
                n: n as i64,
                d: n as i64 - 1,
                src,
                sv: source_voxel(src),
                surfaces: &surfaces,
                columns: &columns,
                mesh: &exact,
                source_face: &loaded.source_face,
                origin: loaded.fit.origin,
                voxel: loaded.fit.voxel,
                exact_source: var.exact_source,
                f,
                sampled: &sampled,
                cells: &stores,
                visible: &visible_of,
                occluders: &occluders,
            };
            let m = walk.d;
            let cols: Vec<[i64; 2]> = if var.receiver != Receiver::Window {
                let all: Vec<[i64; 2]> = (0..n as i64).flat_map(|x| (0..n as i64).map(move |y| [x, y])).collect();
                all.into_par_iter()
                    .filter(|&c| columns(c[0], c[1]).is_some_and(|v| walk.receiver_lit(c, &v, *var)))
                    .collect()
            } else {
                let cuts = cuts_flag.then(|| Cuts::new(n as usize));
                let cols = (0..6usize)
                    .into_par_iter()
                    .flat_map_iter(|dir| (-m..=m).map(move |a| (dir, a)))
                    .flat_map_iter(|(dir, a)| {
                        let mut out = Vec::new();
                        for b in -m..=m {
                            let stop = walk.ray(dir, a, b, *var, &mut out);
                            if let Some(c) = &cuts {
                                c.record(&walk, dir, a, b, stop);
                            }
                        }
                        out
                    })
                    .collect();
                if let Some(c) = cuts {
                    c.report(name, i);
                }
                cols
            };
            let cols = if refine_flag { refine(&walk, cols, n as i64) } else { cols };
            for c in cols {
                *lit.entry(c).or_insert(0) |= 1 << i;
            }
        }
        let seen = Seen::Surface(Box::new(move |x, y| lit.get(&[x as i64, y as i64]).copied().unwrap_or(0)));
        let img =
            host_sim::machine::shading::pixels::shade_grid_with(&mesh, &loaded, &cell_lights, &seen, NormalMode::Facet);
        let c = host_sim::truth::compare::compare(&img.rgb, &img.covered, &img.lit, &reference);
        let (mut darker, mut brighter) = (0, 0);
        for i in (0..img.lit.len()).filter(|&i| img.covered[i] && reference.covered[i]) {
            match (img.lit[i] & 1).cmp(&(reference.lit[i] & 1)) {
                std::cmp::Ordering::Less => darker += 1,
                std::cmp::Ordering::Greater => brighter += 1,
                std::cmp::Ordering::Equal => {}
            }
        }
        let why = Why::of(&img.lit, &reference, &loaded, &exact);
        println!(
            "{name:>16}  {:5.2} %  {:5.2} dB  {darker} / {brighter}  (light {}, coincident {}, edge {}, other {})",
            c.shadow_disagreement_pct, c.psnr_db, why.light, why.coincident, why.edge, why.other
        );
    }
}

/// `--refine`: each covered pixel with a covered 8-neighbour lit otherwise (a pixel on a
/// shadow's edge) takes the [`Receiver::Truth`] answer, as one exact shadow ray from it would
/// give: what re-testing only the edges of the diffused shadows could gain.
fn refine(walk: &Walk, cols: Vec<[i64; 2]>, n: i64) -> Vec<[i64; 2]> {
    let set: std::collections::HashSet<[i64; 2]> = cols.into_iter().collect();
    let covered = |c: [i64; 2]| (walk.visible)(c[0], c[1]).is_some();
    let mut out = Vec::new();
    let mut refined = 0;
    for x in 0..n {
        for y in 0..n {
            let c = [x, y];
            if !covered(c) {
                continue;
            }
            let me = set.contains(&c);
            let edge = (-1..=1)
                .flat_map(|dx| (-1..=1).map(move |dy| [x + dx, y + dy]))
                .any(|q| q[0] >= 0 && q[1] >= 0 && q[0] < n && q[1] < n && covered(q) && set.contains(&q) != me);
            let lit = if edge {
                refined += 1;
                walk.truth_lit(c)
            } else {
                me
            };
            if lit {
                out.push(c);
            }
        }
    }
    eprintln!("refined {refined} pixels");
    out
}

/// The pixels whose lit flags differ from the reference's (light 1), by what the machine sees
/// there:
/// * `light` — the reference's own facet: the light's error;
/// * `coincident` — a facet parallel to the reference's within 1/16 voxel of its point: of two
///   nearly coincident surfaces (a drawer's front and its frame, the two sides of a sheet) the
///   1/16-voxel vertex lattice put the other in front;
/// * `edge` — another surface, which the reference's own ray meets once moved 1/32 voxel or less
///   across the view: a silhouette edge the lattice moved onto the pixel's centre line;
/// * `other` — anything else (a neighbouring facet across a crease, ...).
#[derive(Default)]
struct Why {
    light: usize,
    coincident: usize,
    edge: usize,
    other: usize,
}

impl Why {
    fn of(
        lit: &[u32],
        reference: &host_sim::truth::refrender::RefImage,
        loaded: &LoadedScene,
        mesh: &Reference,
    ) -> Why {
        let (o, vx) = (loaded.fit.origin, loaded.fit.voxel);
        // Where the reference's view ray through (x, y) meets the mesh: depth (voxels), normal.
        let hit = |x: f64, y: f64| {
            let from = [o[0] + (x + 0.5) * vx, o[1] + (y + 0.5) * vx, o[2] - vx];
            mesh.first_hit(from, [0.0, 0.0, 1.0], f64::MAX, &[]).map(|(t, _, nrm)| (t / vx - 1.5, nrm))
        };
        let mut why = Why::default();
        for (i, cell) in loaded.grid.cells.iter().enumerate() {
            let Some(vis) = cell.visible else { continue };
            if !reference.covered[i] || (lit[i] ^ reference.lit[i]) & 1 == 0 {
                continue;
            }
            let (x, y, z) = (cell.x as f64, cell.y as f64, vis.num as f64 / vis.den as f64);
            let p = &vis.plane;
            let m = [p.nx as f64, p.ny as f64, p.nz as f64 / 65536.0];
            let parallel = |r: [f64; 3]| dot(m, r).abs() >= 0.999 * dot(m, m).sqrt() * dot(r, r).sqrt();
            let moved = || {
                (1..=16).map(|k| k as f64 / 512.0).any(|d| {
                    [(d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)]
                        .iter()
                        .any(|&(dx, dy)| hit(x + dx, y + dy).is_some_and(|(r, _)| (r - z).abs() <= 0.5))
                })
            };
            match hit(x, y) {
                _ if loaded.source_face.get(vis.facet as usize) == Some(&reference.facet[i]) => why.light += 1,
                Some((r, nrm)) if (r - z).abs() <= 1.0 / 16.0 && parallel(nrm) => why.coincident += 1,
                Some((r, _)) if (r - z).abs() > 0.5 && moved() => why.edge += 1,
                _ => why.other += 1,
            }
        }
        why
    }
}

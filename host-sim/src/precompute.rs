//! Host precompute ("géométrie/précalcul", §3.9): fit the mesh into the grid, quantise its
//! vertices to a lattice, and compute each facet's exact integer packet.
//!
//! * **Fit**: uniform scale; the mesh's bounding box (of the vertices faces use) is centred in
//!   the grid and its largest side spans `n − 2·MARGIN_VOXELS` voxels, so a one-voxel shell of
//!   empty space surrounds the mesh on its longest axis.
//! * **Lattice**: vertex coordinates are rounded to `1/Q` voxel (`Q = 16`); lattice coordinate
//!   `X = Q·x_vox + Q/2` where `x_vox` is the voxel-centre coordinate, so `0 ..= Q·n` spans the
//!   grid from its low faces to its high faces. A contour edge whose unrounded counterpart lies
//!   inside it is marked to exclude its own points ([`cell_core::facet::EdgeOff`]): a pixel
//!   centre the rounding put exactly on an edge meets the facet iff it meets the mesh's own.
//! * **Coefficients**: plane normal from an exact `i128` cross product, band half-width `Kσ`
//!   per thickness mode, contour edges in the base plane most orthogonal to the normal (§3.6
//!   "Simplification"), optionally pushed out by the voxel's half-extent (`conservative`).
//!   Everything is checked to fit the cell's `i64`/`i32` fields.
//!
//! Polygons are kept when planar (exactly, after quantisation) and convex; otherwise a convex
//! polygon is split into a triangle fan, a non-convex one is ear-clipped (both counted), and a
//! self-intersecting one is rejected with a message naming the face. A small polygon that is
//! simple in the mesh but that the lattice folds onto itself is split before quantisation
//! (ear clipping of the mesh's own polygon, [`triangulate_f64`]), not refused.

use anyhow::{bail, Result};
use cell_core::dexel::FacetTag;
use cell_core::facet::{EdgeOff, FacetBox, PipeEdge, PipelinePacket, MAX_EDGES};
use cell_core::normal::NormalCode;
use cell_core::plane::FacetPlane;
use cell_core::units::MAX_N;

use crate::scene::Mesh;

/// Lattice steps per voxel.
pub const Q: i64 = 16;
/// Empty voxels kept between the mesh's bounding box and the grid faces on its longest axis.
pub const MARGIN_VOXELS: f64 = 1.0;

/// Plane thickness (§3.5, §3.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Thickness {
    /// σ = ½: the thinnest hole-free plane; stops 6-connected rays only.
    Naive,
    /// The thesis's σ = max σ_ij, σ_ij = ½(1 + min/max) (§3.8): chosen from experiments.
    Thesis,
    /// Kσ = (|a|+|b|+|c|)/2: the standard arithmetic plane, provably free of 26-tunnels.
    Standard,
}

/// Contour of a facet (§3.6, §3.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Contour {
    /// The thesis's projected contour: the voxel centre's projection lies in the facet's.
    Projected,
    /// Edges pushed out by the voxel's half-extent: every voxel whose square touches the
    /// projected facet is kept; closes gaps between facets and holes in thin facets.
    Conservative,
}

/// Loading-phase configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadConfig {
    /// Grid side (n × n cells, depth n).
    pub n: u32,
    /// Plane thickness mode.
    pub thickness: Thickness,
    /// Contour mode.
    pub contour: Contour,
}

impl LoadConfig {
    /// The watertight surfaces every job loads unless told otherwise, at grid side `n`: standard
    /// thickness (free of 26-tunnels) and conservative contours (no gaps between facets).
    pub const fn watertight(n: u32) -> LoadConfig {
        LoadConfig { n, thickness: Thickness::Standard, contour: Contour::Conservative }
    }

    /// The thin surfaces at grid side `n`: naive thickness (σ = ½) and projected contours, the
    /// fewest voxels per facet; 26-connected beam steps can pass through them.
    pub const fn thin(n: u32) -> LoadConfig {
        LoadConfig { n, thickness: Thickness::Naive, contour: Contour::Projected }
    }

    /// Validate the grid size against the cell's bit budget.
    pub fn validate(&self) -> Result<()> {
        if self.n < 4 {
            bail!("--n {} is too small: the grid needs at least 4 cells per side", self.n);
        }
        if self.n > MAX_N {
            bail!("--n {} exceeds the largest grid a cell supports ({MAX_N}, bounded by the i64 bit budget and u16 depths)", self.n);
        }
        Ok(())
    }
}

/// World ↔ grid mapping chosen by the fit.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Fit {
    /// World position of the grid's low corner (lattice coordinate 0).
    pub origin: [f64; 3],
    /// World size of one voxel.
    pub voxel: f64,
}

impl Fit {
    /// Lattice coordinates of a world point (rounded to nearest).
    pub fn to_lattice(&self, p: [f64; 3]) -> [i64; 3] {
        self.to_lattice_f64(p).map(|c| c.round() as i64)
    }

    /// Lattice coordinates of a world point, unrounded.
    pub fn to_lattice_f64(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|i| (p[i] - self.origin[i]) / self.voxel * Q as f64)
    }

    /// World coordinates of a lattice point.
    pub fn to_world(&self, l: [i64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|i| self.origin[i] + l[i] as f64 / Q as f64 * self.voxel)
    }
}

/// Why a face produced no packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skip {
    /// Zero area after quantisation.
    Degenerate,
    /// No column of the grid can hold a voxel of it.
    OutsideGrid,
}

/// The result of the precompute.
#[derive(Clone, Debug, Default)]
pub struct Prepared {
    /// Packets in stream order; packet i has facet id i.
    pub packets: Vec<PipelinePacket>,
    /// The lattice polygon of each packet (for oracles and reports).
    pub polygons: Vec<Vec<[i64; 3]>>,
    /// Source face index of each packet.
    pub source_face: Vec<u32>,
    /// World ↔ grid mapping.
    pub fit: Option<Fit>,
    /// Faces in the input.
    pub faces_in: usize,
    /// Faces skipped as degenerate (zero area after quantisation).
    pub skipped_degenerate: usize,
    /// Faces skipped as outside the grid.
    pub skipped_outside: usize,
    /// Pieces skipped as exact duplicates of an earlier piece (same lattice vertices, normal
    /// and material: it could claim no voxel, first come first kept).
    pub skipped_duplicate: usize,
    /// Polygons split into triangles (non-planar after quantisation, or too many edges).
    pub polygons_split: usize,
}

/// Fit the mesh's used vertices into an n-grid. A mesh in screen space
/// ([`crate::scene::camera`]) is not fitted: its unit cube is the grid.
pub fn fit(mesh: &Mesh, n: u32) -> Result<Fit> {
    if mesh.screen.is_some() {
        return Ok(Fit { origin: [0.0; 3], voxel: 1.0 / n as f64 });
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut used = 0usize;
    for (fi, f) in mesh.faces.iter().enumerate() {
        for &v in &f.verts {
            let p = mesh.positions[v as usize];
            if !p.iter().all(|c| c.is_finite()) {
                bail!("{}: face {} uses vertex {} with a non-finite coordinate {:?}", mesh.name, fi + 1, v + 1, p);
            }
            for i in 0..3 {
                lo[i] = lo[i].min(p[i]);
                hi[i] = hi[i].max(p[i]);
            }
            used += 1;
        }
    }
    if used == 0 {
        bail!("{}: the mesh has no faces: nothing to voxelize", mesh.name);
    }
    let extent = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
    if extent.is_nan() || extent <= 0.0 || !extent.is_finite() {
        bail!("{}: all vertices coincide (or the extent overflows): nothing to voxelize", mesh.name);
    }
    let voxel = extent / (n as f64 - 2.0 * MARGIN_VOXELS);
    if voxel.is_nan() || voxel <= 0.0 || !voxel.is_finite() {
        bail!("{}: cannot fit the mesh (extent {extent:e}) into the grid", mesh.name);
    }
    let origin = [0, 1, 2].map(|i| (lo[i] + hi[i]) / 2.0 - n as f64 / 2.0 * voxel);
    Ok(Fit { origin, voxel })
}

fn cross(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: [i64; 3], b: [i64; 3]) -> [i128; 3] {
    [0, 1, 2].map(|i| a[i] as i128 - b[i] as i128)
}

fn dot(a: [i128; 3], b: [i128; 3]) -> i128 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Normal of a lattice polygon from its first non-collinear vertex triple (zero if none).
pub fn polygon_normal(p: &[[i64; 3]]) -> [i128; 3] {
    for k in 2..p.len() {
        let n = cross(sub(p[1], p[0]), sub(p[k], p[0]));
        if n != [0; 3] {
            return n;
        }
    }
    [0; 3]
}

/// Dominant axis of a normal (largest |component|, ties prefer z, then y, then x), and the two
/// projection axes in increasing order.
pub fn projection_axes(n: [i128; 3]) -> (usize, usize, usize) {
    let m = [n[0].abs(), n[1].abs(), n[2].abs()];
    if m[2] >= m[0] && m[2] >= m[1] {
        (2, 0, 1)
    } else if m[1] >= m[0] {
        (1, 0, 2)
    } else {
        (0, 1, 2)
    }
}

/// Band half-width `⌊Kσ⌋` (in the units of `E = a·x + b·y + c·z + d`) for voxel-unit
/// coefficients `abc = q·(A, B, C)`. `E` is an integer, so `|E| ≤ Kσ ⇔ |E| ≤ ⌊Kσ⌋` exactly.
pub fn band_half_width(abc: [i128; 3], th: Thickness) -> i128 {
    let m = abc.map(|v| v.abs());
    let k = m[0].max(m[1]).max(m[2]);
    match th {
        Thickness::Naive => k / 2,
        Thickness::Standard => (m[0] + m[1] + m[2]) / 2,
        Thickness::Thesis => [(0, 1), (0, 2), (1, 2)]
            .iter()
            .map(|&(i, j)| {
                let (mx, mn) = (m[i].max(m[j]), m[i].min(m[j]));
                if mx == 0 {
                    k / 2
                } else {
                    (k * (mx + mn)) / (2 * mx)
                }
            })
            .max()
            .unwrap_or(0),
    }
}

fn fits_i64(v: i128, what: &str) -> Result<i64> {
    i64::try_from(v).map_err(|_| anyhow::anyhow!("{what} = {v} exceeds the cell's i64 bit budget"))
}

fn fits_i32(v: i128, what: &str) -> Result<i32> {
    i32::try_from(v).map_err(|_| anyhow::anyhow!("{what} = {v} exceeds the cell's i32 bit budget"))
}

/// Whether a polygon is convex in its projection (collinear runs allowed), given its normal.
fn convex_in_projection(p: &[[i64; 3]], axes: (usize, usize, usize)) -> bool {
    let (_, u, v) = axes;
    let k = p.len();
    let mut sign = 0i128;
    for i in 0..k {
        let (a, b, c) = (p[i], p[(i + 1) % k], p[(i + 2) % k]);
        let cr = (b[u] - a[u]) as i128 * (c[v] - b[v]) as i128 - (b[v] - a[v]) as i128 * (c[u] - b[u]) as i128;
        if cr != 0 {
            if sign != 0 && cr.signum() != sign {
                return false;
            }
            sign = cr.signum();
        }
    }
    true
}

/// A facet's packet, or why it has none.
pub type PacketOrSkip = std::result::Result<PipelinePacket, Skip>;

/// Largest |lattice coordinate| [`facet_packet`] accepts.
pub const MAX_LATTICE_COORD: u64 = 1 << 32;

/// Build the packet of one planar convex lattice polygon (`Ok(Err(skip))`: skipped, with the reason).
/// Its edges hold their points ([`facet_packet_of`] with the unrounded polygon decides).
pub fn facet_packet(poly: &[[i64; 3]], tag: FacetTag, cfg: &LoadConfig) -> Result<PacketOrSkip> {
    facet_packet_of(poly, None, tag, cfg)
}

/// [`facet_packet`] of a lattice polygon whose vertices were `world` before rounding (lattice
/// units, [`Fit::to_lattice_f64`]): an edge whose unrounded counterpart lies inside it, by
/// the sign of its edge function at the unrounded edge's midpoint, excludes its own points
/// ([`cell_core::facet::EdgeOff`]), so a pixel centre the rounding put exactly on an edge
/// meets the facet iff it meets the mesh's own.
pub fn facet_packet_of(
    poly: &[[i64; 3]],
    world: Option<&[[f64; 3]]>,
    tag: FacetTag,
    cfg: &LoadConfig,
) -> Result<PacketOrSkip> {
    // The i128 products below (normal · vertex) stay exact for |coordinate| ≤ 2^32 lattice
    // steps (normal components < 2^67, products < 2^101); a fitted mesh uses 0 ..= 16·n.
    if let Some(c) = poly.iter().flatten().find(|c| c.unsigned_abs() > MAX_LATTICE_COORD) {
        bail!("vertex coordinate {c} exceeds the precompute's bit budget (|coordinate| ≤ 2^32 lattice steps)");
    }
    let n = polygon_normal(poly);
    if n == [0; 3] || poly.len() > MAX_EDGES {
        return Ok(Err(Skip::Degenerate));
    }
    let q = Q as i128;
    let h = q / 2;
    let abc = n.map(|v| v * q);
    let ks = band_half_width(abc, cfg.thickness);
    // E at voxel (0,0,0): N · (centre − P0) with centre = (h, h, h).
    let p0 = poly[0];
    let d = n[0] * (h - p0[0] as i128) + n[1] * (h - p0[1] as i128) + n[2] * (h - p0[2] as i128);
    let axes = projection_axes(n);
    let (dom, ua, va) = axes;
    // Orientation: sign of the projected (shoelace) area, so that the interior is ≥ 0.
    let area2: i128 = (0..poly.len())
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            a[ua] as i128 * b[va] as i128 - b[ua] as i128 * a[va] as i128
        })
        .sum();
    let s = area2.signum();
    if s == 0 {
        return Ok(Err(Skip::Degenerate));
    }
    let conservative = cfg.contour == Contour::Conservative;
    let mut edges = heapless::Vec::<PipeEdge, MAX_EDGES>::new();
    for i in 0..poly.len() {
        let (pi, pj) = (poly[i], poly[(i + 1) % poly.len()]);
        let du = (pj[ua] - pi[ua]) as i128;
        let dv = (pj[va] - pi[va]) as i128;
        if du == 0 && dv == 0 {
            continue; // repeated vertex in projection: no constraint
        }
        // F(M) = du·(Mv − Vi) − dv·(Mu − Ui), M = q·idx + h.
        let mut coef = [0i128; 3];
        coef[ua] = -s * dv * q;
        coef[va] = s * du * q;
        let mut g0 = s * (du * (h - pi[va] as i128) - dv * (h - pi[ua] as i128));
        let push = if conservative { h * (du.abs() + dv.abs()) } else { 0 };
        g0 += push;
        // F at the unrounded edge's midpoint (lattice units): > 0, the mesh's edge lies inside.
        let strict = world.is_some_and(|w| {
            let mid = |k: usize| (w[i][k] + w[(i + 1) % w.len()][k]) / 2.0;
            let f = du as f64 * (mid(va) - pi[va] as f64) - dv as f64 * (mid(ua) - pi[ua] as f64);
            s as f64 * f > 0.0
        });
        let off = push | if strict { EdgeOff::STRICT as i128 } else { 0 };
        let e = PipeEdge {
            a: fits_i32(coef[0], "edge coefficient a_i")?,
            b: fits_i32(coef[1], "edge coefficient b_i")?,
            c: fits_i32(coef[2], "edge coefficient c_i")?,
            g: fits_i64(g0, "edge value g_i")?,
            off: fits_i32(off, "edge push")?,
        };
        // Cannot fail: at most poly.len() <= MAX_EDGES edges.
        let _ = edges.push(e);
    }
    // Box: on the projected axes, the vertex range (pushed out by ½ voxel in conservative mode:
    // with the pushed-out edges this is conservative rasterisation, edges ∩ box, which trims
    // the spikes at acute corners); on the dominant axis, the vertex range pushed out by the
    // farthest a kept centre can be (≤ 1.5 voxel for the band, + 1 for the conservative spill),
    // so it never cuts a voxel (the brute-force tests check it).
    let reach = |axis: usize| -> i128 {
        match (axis == dom, conservative) {
            (true, true) => 5 * h,
            (true, false) => 3 * h,
            (false, true) => h,
            (false, false) => 0,
        }
    };
    let nn = cfg.n as i128;
    let range = |axis: usize| -> Option<(u16, u16)> {
        let lo = poly.iter().map(|p| p[axis]).min()? as i128 - reach(axis);
        let hi = poly.iter().map(|p| p[axis]).max()? as i128 + reach(axis);
        // Voxel i has centre q·i + h: q·i + h ∈ [lo, hi].
        let i_lo = (lo - h + q - 1).div_euclid(q).max(0);
        let i_hi = (hi - h).div_euclid(q).min(nn - 1);
        (i_lo <= i_hi).then_some((i_lo as u16, i_hi as u16))
    };
    let (Some((x_min, x_max)), Some((y_min, y_max)), Some((z_min, z_max))) = (range(0), range(1), range(2)) else {
        return Ok(Err(Skip::OutsideGrid));
    };
    Ok(Ok(PipelinePacket {
        tag,
        bbox: FacetBox { x_min, x_max, y_min, y_max, z_min, z_max },
        a: fits_i64(abc[0], "plane coefficient a")?,
        b: fits_i64(abc[1], "plane coefficient b")?,
        c: fits_i64(abc[2], "plane coefficient c")?,
        t: fits_i64(ks - d, "plane value T")?,
        u: fits_i64(-ks - d, "plane value U")?,
        edges,
    }))
}

fn dedup_cyclic(mut p: Vec<[i64; 3]>) -> Vec<[i64; 3]> {
    p.dedup();
    while p.len() > 1 && p.first() == p.last() {
        p.pop();
    }
    p
}

/// Planar convex pieces of a polygon, and whether it was split.
pub type Pieces = (Vec<Vec<[i64; 3]>>, bool);

/// Split a lattice polygon into what the cells accept: planar convex polygons of at most
/// `MAX_EDGES` vertices. A planar convex polygon is kept whole; a convex one that quantisation
/// made non-planar (or that has too many vertices) becomes a triangle fan; a non-convex simple
/// polygon is ear-clipped in its projection. Returns the pieces and whether it was split.
pub fn planar_pieces(p: Vec<[i64; 3]>) -> std::result::Result<Pieces, &'static str> {
    let p = dedup_cyclic(p);
    if p.len() <= 3 {
        return Ok((vec![p], false));
    }
    let n = polygon_normal(&p);
    if n == [0; 3] {
        return Ok((vec![p], false)); // degenerate: skipped by the caller
    }
    let planar = p.iter().all(|&v| dot(n, sub(v, p[0])) == 0);
    let axes = projection_axes(n);
    if convex_in_projection(&p, axes) {
        if planar && p.len() <= MAX_EDGES {
            return Ok((vec![p], false));
        }
        return Ok(((1..p.len() - 1).map(|k| vec![p[0], p[k], p[k + 1]]).collect(), true));
    }
    ear_clip(&p, axes).map(|t| (t, true))
}

/// Ear clipping in the projection on the dominant plane (exact integer orientation tests).
fn ear_clip(p: &[[i64; 3]], (_, u, v): (usize, usize, usize)) -> std::result::Result<Vec<Vec<[i64; 3]>>, &'static str> {
    let orient = |a: [i64; 3], b: [i64; 3], c: [i64; 3]| -> i128 {
        (b[u] - a[u]) as i128 * (c[v] - a[v]) as i128 - (b[v] - a[v]) as i128 * (c[u] - a[u]) as i128
    };
    let area2: i128 = (0..p.len()).map(|i| orient([0; 3], p[i], p[(i + 1) % p.len()])).sum();
    let sign = |i: usize, j: usize, k: usize| orient(p[i], p[j], p[k]).signum() as i8;
    let tris = ear_clip_indices(p.len(), area2.signum() as i8, sign, |i, j| p[i] == p[j])?;
    Ok(tris.into_iter().map(|t| t.map(|i| p[i]).to_vec()).collect())
}

/// Ear clipping of a simple polygon of `k` vertices, given the sign of its (projected) area and
/// of each triangle's (`orient`), and which vertices coincide (`same`): index triples in the
/// polygon's winding.
fn ear_clip_indices(
    k: usize,
    area_sign: i8,
    orient: impl Fn(usize, usize, usize) -> i8,
    same: impl Fn(usize, usize) -> bool,
) -> std::result::Result<Vec<[usize; 3]>, &'static str> {
    if area_sign == 0 {
        return Err("self-overlapping polygon (zero projected area)");
    }
    let mut idx: Vec<usize> = (0..k).collect();
    let mut tris = Vec::new();
    while idx.len() > 3 {
        let k = idx.len();
        let ear = (0..k).find(|&i| {
            let (a, b, c) = (idx[(i + k - 1) % k], idx[i], idx[(i + 1) % k]);
            if orient(a, b, c) * area_sign <= 0 {
                return false; // reflex or flat corner
            }
            // No other vertex inside or on the candidate ear.
            idx.iter().all(|&q| {
                same(q, a)
                    || same(q, b)
                    || same(q, c)
                    || !(orient(a, b, q) * area_sign >= 0
                        && orient(b, c, q) * area_sign >= 0
                        && orient(c, a, q) * area_sign >= 0)
            })
        });
        let Some(i) = ear else {
            return Err("self-intersecting polygon: cannot be triangulated");
        };
        tris.push([idx[(i + k - 1) % k], idx[i], idx[(i + 1) % k]]);
        idx.remove(i);
    }
    tris.push([idx[0], idx[1], idx[2]]);
    Ok(tris)
}

/// Triangles (vertex index triples) of a polygon given by its mesh positions (f64): ear
/// clipping in the projection on the plane its Newell normal is most orthogonal to. For the
/// polygons quantisation folds (a small quad whose lattice vertices overlap in projection): the
/// mesh's own polygon is simple, so its triangles are, before quantisation.
pub fn triangulate_f64(p: &[[f64; 3]]) -> std::result::Result<Vec<[usize; 3]>, &'static str> {
    let points: Vec<parry3d_f64::math::Vector> = p.iter().map(|&q| q.into()).collect();
    let n = crate::scene::patches::area_vector(&points).to_array();
    if n.iter().any(|c| !c.is_finite()) {
        return Err("non-finite polygon");
    }
    let axis = (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(2);
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let sign = |x: f64| {
        if x > 0.0 {
            1
        } else if x < 0.0 {
            -1
        } else {
            0
        }
    };
    let orient = |a: usize, b: usize, c: usize| {
        let (a, b, c) = (p[a], p[b], p[c]);
        sign((b[u] - a[u]) * (c[v] - a[v]) - (b[v] - a[v]) * (c[u] - a[u]))
    };
    ear_clip_indices(p.len(), sign(n[axis]), orient, |i, j| p[i] == p[j])
}

/// Plane ids by exact oriented plane (primitive normal, offset): the first facet's id.
pub type PlaneIds = std::collections::HashMap<([i128; 3], i128), u32>;

fn gcd(a: i128, b: i128) -> i128 {
    let (mut a, mut b) = (a.abs(), b.abs());
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The plane a facet's packet carries ([`cell_core::plane`]): its normal scaled to a largest
/// component of 2¹⁴, and an id shared by every facet in the same exact oriented plane (`ids`
/// maps the primitive normal and offset to the first such facet). A zero normal (a degenerate
/// piece, which the packet builder skips) gets the default. `two_sided`: the facet belongs to
/// an open surface ([`cell_core::plane::TWO_SIDED`], [`crate::scene::meshops::open_faces`]).
pub fn facet_plane(poly: &[[i64; 3]], facet: u32, two_sided: bool, ids: &mut PlaneIds) -> FacetPlane {
    let n = polygon_normal(poly);
    let Some((nx, ny, nz, m)) = cell_core::plane::scale_normal(n) else {
        return FacetPlane::default();
    };
    let g = gcd(gcd(n[0], n[1]), n[2]);
    let p = n.map(|v| v / g);
    let d = dot(p, poly[0].map(|c| c as i128));
    let id = *ids.entry((p, d)).or_insert(facet) | if two_sided { cell_core::plane::TWO_SIDED } else { 0 };
    FacetPlane { id, nx, ny, nz, m }
}

/// The normal a facet is shaded with: its lattice normal, or for a mesh in screen space the
/// normal of the same polygon mapped back to view space (where the cells shade).
fn shading_normal(mesh: &Mesh, fit: &Fit, piece: &[[i64; 3]], lattice_normal: [i128; 3]) -> NormalCode {
    let Some(screen) = &mesh.screen else {
        return NormalCode::encode(lattice_normal.map(|v| v as f32));
    };
    let view: Vec<[f64; 3]> = piece.iter().map(|&l| screen.view.screen_to_view(fit.to_world(l))).collect();
    // Newell's normal: exact for a planar polygon, an average for a slightly bent one.
    NormalCode::encode(crate::scene::normals::newell(&view).map(|v| v as f32))
}

/// Run the precompute for a whole mesh.
pub fn prepare(mesh: &Mesh, cfg: &LoadConfig) -> Result<Prepared> {
    cfg.validate()?;
    let fit = fit(mesh, cfg.n)?;
    let mut out = Prepared { fit: Some(fit), faces_in: mesh.faces.len(), ..Default::default() };
    let mut seen: std::collections::HashSet<(u16, [i8; 3], Vec<[i64; 3]>)> = Default::default();
    let mut planes = PlaneIds::default();
    let open = crate::scene::meshops::open_faces(mesh);
    for (fi, face) in mesh.faces.iter().enumerate() {
        let exact: Vec<[f64; 3]> = face.verts.iter().map(|&v| fit.to_lattice_f64(mesh.positions[v as usize])).collect();
        let lat: Vec<[i64; 3]> = exact.iter().map(|c| c.map(|c| c.round() as i64)).collect();
        let (pieces, split) = match planar_pieces(lat.clone()) {
            Ok(pieces) => pieces,
            // Quantisation can fold a small polygon that is simple in the mesh: split the mesh's
            // own polygon and quantise its triangles (those it flattens are skipped, counted).
            Err(why) => {
                let world: Vec<[f64; 3]> = face.verts.iter().map(|&v| mesh.positions[v as usize]).collect();
                let tris = triangulate_f64(&world).map_err(|_| {
                    anyhow::anyhow!("{}: face {} ({} vertices): {why}", mesh.name, fi + 1, face.verts.len())
                })?;
                (tris.into_iter().map(|t| dedup_cyclic(t.map(|i| lat[i]).to_vec())).collect(), true)
            }
        };
        out.polygons_split += split as usize;
        for piece in pieces {
            let nrm = polygon_normal(&piece);
            let mut key = piece.clone();
            key.sort_unstable();
            if !seen.insert((face.material, nrm.map(|v| v.signum() as i8), key)) {
                out.skipped_duplicate += 1;
                continue;
            }
            let facet = out.packets.len() as u32;
            let tag = FacetTag {
                facet,
                material: face.material,
                normal: shading_normal(mesh, &fit, &piece, nrm),
                plane: facet_plane(&piece, facet, open[fi], &mut planes),
            };
            // The piece's vertices before rounding (a lattice point two vertices share: the first).
            let world: Vec<[f64; 3]> = piece
                .iter()
                .map(|p| lat.iter().position(|l| l == p).map_or(p.map(|c| c as f64), |k| exact[k]))
                .collect();
            match facet_packet_of(&piece, Some(&world), tag, cfg)? {
                Ok(pkt) => {
                    out.packets.push(pkt);
                    out.polygons.push(piece);
                    out.source_face.push(fi as u32);
                }
                Err(Skip::Degenerate) => out.skipped_degenerate += 1,
                Err(Skip::OutsideGrid) => out.skipped_outside += 1,
            }
        }
    }
    if out.packets.len() >= cell_core::plane::TWO_SIDED as usize {
        bail!("too many facets: {} (plane ids have 31 bits)", out.packets.len());
    }
    let total = out.packets.len() + out.skipped_degenerate;
    if total > 8 && out.skipped_degenerate * 2 > total {
        eprintln!(
            "warning: {}: {} of {} facets collapsed to zero area after fitting to the grid; \
             a few far-away vertices may dominate the mesh's bounding box",
            mesh.name, out.skipped_degenerate, total
        );
    }
    if out.packets.is_empty() {
        bail!("{}: every facet is degenerate after quantisation: nothing to voxelize", mesh.name);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Face, Material};

    /// Twice the signed area of a polygon's projection on axes (u, v), in f64.
    fn area2(p: &[[f64; 3]], u: usize, v: usize) -> f64 {
        (0..p.len()).map(|i| p[i][u] * p[(i + 1) % p.len()][v] - p[(i + 1) % p.len()][u] * p[i][v]).sum()
    }

    /// A small quad of a rotated Suzanne, simple in the mesh, that the 1/16-voxel lattice
    /// folds at n = 64: its lattice polygon overlaps itself (zero projected area), which the
    /// precompute refused for the whole mesh. Now the mesh's own quad is split into triangles
    /// before quantisation: the mesh loads, the quad's pieces are triangles of its own vertices
    /// (or skipped as degenerate, counted), and the triangles cover the quad: their projected
    /// areas sum to its own in f64.
    #[test]
    fn a_quad_that_quantisation_folds_is_split_not_refused() {
        let quad = [
            [-1.988194, 0.373821, 5.111843],
            [-1.956551, 0.384146, 5.065068],
            [-2.099595, 0.450383, 5.14733],
            [-2.068451, 0.384179, 5.098982],
        ];
        // A triangle spanning the rotated mesh's bounding box sets the same fit.
        let (lo, hi) = ([-3.280888, -1.187599, 3.404089], [-1.255502, 1.189965, 5.273136]);
        let mut positions = vec![lo, [hi[0], hi[1], lo[2]], [lo[0], hi[1], hi[2]]];
        positions.extend(quad);
        let mesh = Mesh {
            name: "folded-quad".into(),
            positions,
            faces: vec![Face { verts: vec![0, 1, 2], material: 0 }, Face { verts: vec![3, 4, 5, 6], material: 0 }],
            materials: vec![Material::default()],
            ..Default::default()
        };
        let cfg = LoadConfig::watertight(64);
        let fit = fit(&mesh, 64).unwrap();
        let lat: Vec<[i64; 3]> = quad.iter().map(|&p| fit.to_lattice(p)).collect();
        assert!(planar_pieces(lat.clone()).is_err(), "the premise: the lattice folds this quad");

        let out = prepare(&mesh, &cfg).expect("the mesh loads");
        assert_eq!(out.polygons_split, 1);
        let pieces: Vec<&Vec<[i64; 3]>> =
            out.polygons.iter().zip(&out.source_face).filter(|(_, &f)| f == 1).map(|(p, _)| p).collect();
        assert_eq!(pieces.len() + out.skipped_degenerate, 2, "two triangles, kept or skipped as degenerate");
        assert!(pieces.iter().all(|p| p.len() == 3 && p.iter().all(|v| lat.contains(v))));
        let tris = triangulate_f64(&quad).unwrap();
        assert_eq!(tris.len(), 2);
        for (u, v) in [(0, 1), (1, 2), (2, 0)] {
            let whole = area2(&quad, u, v);
            let parts: f64 = tris.iter().map(|t| area2(&t.map(|i| quad[i]), u, v)).sum();
            assert!((whole - parts).abs() <= 1e-12 * whole.abs().max(1e-9), "axes ({u}, {v}): {whole} vs {parts}");
        }
    }

    /// `mesh` turned by `angles` (radians) about x, then y, then z.
    fn rotated(mut mesh: Mesh, angles: [f64; 3]) -> Mesh {
        for p in &mut mesh.positions {
            for (axis, t) in angles.into_iter().enumerate() {
                let (c, s) = (t.cos(), t.sin());
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                (p[u], p[v]) = (c * p[u] - s * p[v], s * p[u] + c * p[v]);
            }
        }
        mesh
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]

        /// Every polygon of the built-in meshes is simple, so the meshes load whatever their
        /// orientation and grid: nothing refused, every face voxelized or counted as skipped
        /// (degenerate after quantisation, or split into pieces that are).
        #[test]
        fn the_meshes_load_turned_any_way(
            name in proptest::sample::select(vec!["suzanne", "fandisk", "cow", "teapot"]),
            angles in [-3.2f64..3.2, -3.2f64..3.2, -3.2f64..3.2],
            n in 8u32..=96,
        ) {
            let mesh = rotated(crate::scene::load(name).unwrap(), angles);
            let out = prepare(&mesh, &LoadConfig::watertight(n));
            proptest::prop_assert!(out.is_ok(), "{name} turned {angles:?} at n = {n}: {:#}", out.err().unwrap());
            let out = out.unwrap();
            proptest::prop_assert!(!out.packets.is_empty());
            proptest::prop_assert!(out.source_face.iter().all(|&f| (f as usize) < mesh.faces.len()));
        }
    }

    /// The rotation of Suzanne that the lattice folded at n = 64 (the quad above in its mesh).
    #[test]
    fn suzanne_turned_loads_at_n_64() {
        let mesh = rotated(rotated(crate::scene::load("suzanne").unwrap(), [0.0, 0.0, 1.1]), [-0.4, 0.0, 0.0]);
        prepare(&mesh, &LoadConfig::watertight(64)).expect("loads");
    }

    /// A polygon that overlaps itself in the mesh (a bowtie) is still refused: there is no
    /// simple polygon to split.
    #[test]
    fn a_bowtie_in_the_mesh_is_still_refused() {
        let bowtie = [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(triangulate_f64(&bowtie).is_err());
        let l_shape =
            [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [2.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 2.0, 1.0], [0.0, 2.0, 1.0]];
        let tris = triangulate_f64(&l_shape).unwrap();
        assert_eq!(tris.len(), 4);
        let parts: f64 = tris.iter().map(|t| area2(&t.map(|i| l_shape[i]), 0, 1)).sum();
        assert!((parts - 6.0).abs() < 1e-12, "the L's area twice: {parts}");
    }
}

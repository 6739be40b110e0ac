//! §5.5.5 — the receiver: which one lattice ray decides whether a pixel is lit.
//!
//! **Invariant: a cell's target ray for a light is the lattice ray nearest the exact ray from
//! the rays' origin to the pixel's point, among the rays that occupy one of the two voxels
//! bracketing the visible surface or the voxel in front of them at their layer and lie on the
//! surface's outer side there (rule 1 of [`crate::lit`]), searched within [`SEARCH`] lattice
//! steps of the exact ray; it is found in exact integer arithmetic, the same on every machine,
//! once per light. The pixel is lit iff that ray arrives at its voxel and no triangle kept by
//! the column or one of its 8 neighbours crosses its contact segment (the exact segment from
//! the light to [`CONTACT_GAP`] in front of the pixel; the neighbours answer the cell's query,
//! [`crosses_any`]).**
//!
//! # Why
//!
//! The machine lights a column's visible surface when *any* lattice ray reaches one of its two
//! bracketing voxels on the outer side of its plane ([`crate::lit`], rule 1): at f = 0 one or
//! two rays per pixel, sampling a region around the point the f64 reference samples, so a shadow
//! edge comes out up to half a voxel too bright. Naming one ray, the nearest to the ray to the
//! pixel's own point, and lighting the pixel iff that ray arrives, is the receiver half of the
//! fix described in docs/LIGHTING.md ("Shadow edges at the pixel"): with exact occluders
//! ([`crate::occluder`]) and rays from the light it takes the shadow edges of the meshes to
//! within the lattice's rounding (figures: BENCHMARKS.md, "How the default lit rule was
//! chosen").
//!
//! # Definition
//!
//! The pixel's point is P = (x, y, z\*) with z\* = num/den the visible surface's exact depth
//! ([`VisibleSurface`]), rounded to [`POINT_UNITS`]⁻¹ voxel along z (a ray's choice, not a
//! test: the rounding moves the point by 2⁻¹³ voxel at most). With the rays' origin O and lead
//! ([`Source::ray_origin`], [`Source::lead`]):
//!
//! 1. the face: the first direction of [`Direction::ALL`] along which P lies at a positive
//!    distance from O with the exact ray's offsets `a = (P_u − O_u)·N/dist`,
//!    `b = (P_v − O_v)·N/dist` within ±N (N = D·2^f; the pyramids share their boundaries);
//! 2. the candidates: for each voxel q = (x, y, z) of the column with z_v − 1 ≤ z ≤ z_v + 1
//!    ([`VisibleSurface::receives`]) and 0 ≤ z ≤ D, at layer k with 1 ≤ k ≤ D
//!    ([`Source::layer_at`]), the lattice rays whose voxel at layer k is q (the
//!    rounding of [`crate::beam`] from O: `⌊(O_u + T·a/N)/16 + ½⌋ = q_u`, T = 16k − lead) and
//!    on the visible plane's outer side at layer k or k − 1 ([`RayPlane::new`]),
//!    a plane that faces the origin (rule 1: a back face is lit by no ray);
//! 3. the nearest to (a, b) in the lattice's (u, v) metric, within [`SEARCH`] steps of the exact
//!    ray's rounding clamped to each voxel's rectangle of rays; ties go to the first found
//!    (z_v, then z_v + 1, then z_v − 1: a ray through two of them counts at the one nearer the
//!    surface; then increasing a, then b).
//!
//! No candidate: no target, and the pixel is unlit for that light (P outside every face's
//! pyramid, or behind the plane's outer side for every ray near it).
//!
//! **Why the voxel in front.** At f = 0 a voxel far from the source holds about one lattice
//! ray. Where the light grazes the surface, the plane cuts the bracketing voxel z_v so that its
//! one ray may lie on the inner side, and z_v + 1 lies behind the surface: the two bracketing
//! voxels alone then offer no candidate and a lit pixel stays dark, in moiré arcs over the
//! grazed face (the Cornell box's tall block seen in the fitted view, growing with n). Voxel
//! z_v − 1, in front of the surface, holds rays on its outer side next to the point; with it
//! the nearest-ray receiver's moiré is gone (`tests/examples/lit_bounds.rs`, docs/LIGHTING.md).
//!
//! # Contact shadows
//!
//! The target ray decides whether light reaches the pixel's *voxel*: a ray stopped in the
//! segment that ends there still arrives. So a shadow cast from closer than a voxel — a
//! shelf's underside over a desk, a drawer's front, a poster on a wall at n = 128 — is lost:
//! on bureau1 at n = 128 most of its wrong pixels were such, too bright. The cell therefore also
//! tests the exact segment from the light S to the point X₁ of the ray to P where the visible
//! plane's value falls to [`CONTACT_GAP`] (¼ voxel in front of the surface, along its normal's
//! largest axis; X₁ rounded to the 1/[`POINT_UNITS`] grid) against the triangles its own column
//! keeps ([`Target::shadowed_by`]): one crossing and the pixel is in shadow. The gap keeps the
//! surface's own triangles (and its neighbours', within lattice rounding of its plane) from
//! shadowing it; only the column's triangles are known, so the test is the near end of the
//! exact ray, which is where the lattice ray's arrival is blind. It pays on bureau1 at n = 128
//! and changes little elsewhere (`bench/lit_rules.sh`; BENCHMARKS.md, "How the default lit rule
//! was chosen").
//!
//! # The neighbours' triangles
//!
//! A shadow cast from within a voxel or two is often cast by a triangle the pixel's own column
//! does not keep: the edge of a panel one column over. The contact segment passes through the
//! neighbouring column there, the lattice target ray (up to half a voxel off the exact ray)
//! misses the edge, and whole lines of pixels along such edges come out lit (bureau1 at
//! n = 128, along its bookcase). So once per
//! light, after computing its target, a cell sends its contact segment's near end to its 8
//! neighbours (the light is known to all); each tests the segment from the light to it against
//! its own triangles ([`crosses_any`], the same exact test) and answers one bit; the OR is
//! [`Target::neighbour_shadow`]
//! ([`Target::with_neighbour_answers`]), and the pixel is lit only if it is clear too
//! ([`Target::in_contact_shadow`]). Any crossing is a true one up to the vertex lattice (the
//! segment is exact and ends [`CONTACT_GAP`] in front of the surface), so a neighbour darkens
//! pixels the mesh shadows: on bureau1 at n = 128 the f64 reference lights only a pixel or so
//! of those a neighbour's triangle shadows, its segment within rounding of that triangle's edge
//! (`tests/tests/integration/render.rs` checks it). The exchange costs one query and one answer
//! per link and a test of 8 queries per cell; beams do not change. Its effect: BENCHMARKS.md,
//! "How the default lit rule was chosen"; testing two rings of neighbours instead of one was
//! tried and gained too little to keep.
//!
//! # Bit budget
//!
//! Coordinates within [`COORD_LIMIT`] sixteenths, in units of 1/[`POINT_UNITS`] voxel: below
//! 2³¹; `dist` ≤ 2³², `a·dist` ≤ 2⁶³ (N < 2³¹). Two candidates compare by the sign of
//! `dist·Σ(Δt·(t₁ + t₂)) − 2·Σ(num·Δt)`, each term below 2⁹⁷: `i128`, exact.
//!
//! The contact segment: the plane's value `2¹⁶·POINT_UNITS·g` at a point within 2³² units of
//! the column is below 3·2³⁰·2³² + 2¹⁵·2²⁸ < 2⁶⁴; X₁'s rounding multiplies a value difference
//! (< 2⁶⁵) by a coordinate difference (< 2³²): < 2⁹⁸. The crossing test ([`Target::shadowed_by`],
//! vertices scaled to the same unit, below 2³¹): the triangle's normal (sixteenths) below
//! 2⁴⁹ per component, its plane's value `n·(X − V₀)` below 3·2⁴⁹·2³² < 2⁸³; the Plücker signs
//! `d·((V_i − X₀) × (V_j − X₀))` below 3·2³²·(2·2⁶⁴) < 2⁹⁹: `i128`, exact. The tests evaluate
//! them at these limits with overflow checks on.
//!
//! # Example
//!
//! ```
//! use cell_core::beam::{frac, Direction, FarDistance, Source, SourceId};
//! use cell_core::normal::NormalCode;
//! use cell_core::occluder::Triangle;
//! use cell_core::plane::DexelPlane;
//! use cell_core::receiver::target;
//! use cell_core::visible::VisibleSurface;
//!
//! // A light at voxel (6, 6, 0) over a floor at z* = 9.5 (its plane faces −z, the light).
//! let source = Source::at_voxel(SourceId(0), [6, 6, 0]).unwrap();
//! let far = FarDistance::<frac::U0>::new(12).unwrap();
//! let plane = DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 };
//! let floor = VisibleSurface { num: 19, den: 2, facet: 0, material: 0, normal: NormalCode::default(), plane, z_v: 9 };
//! // Column (8, 5): the exact ray has offsets (2.53, −1.26); the nearest lattice ray that
//! // reaches voxel (8, 5, 9) at layer 9 on the floor's light side is (3, −1).
//! let t = target(8, 5, &floor, &source, far).unwrap();
//! assert_eq!((t.dir, t.layer, t.z, t.a, t.b), (Direction::PosZ, 9, 9, 3, -1));
//! // Contact shadows: a shelf ½ voxel above the floor (z = 9, in sixteenths) over the pixel
//! // shadows it; one ⅛ voxel above, within the gap, does not.
//! let shelf = |z| Triangle::new([[100, 60, z], [160, 60, z], [130, 110, z]]).unwrap();
//! assert!(t.shadowed_by(&[shelf(144)]) && !t.shadowed_by(&[shelf(150)]));
//! // A neighbour's shelf: it answers the cell's query, and the pixel is in its shadow.
//! let answer = cell_core::receiver::crosses_any(&[shelf(144)], t.contact.unwrap());
//! assert!(!t.in_contact_shadow(&[]) && t.with_neighbour_answers(answer).in_contact_shadow(&[]));
//! ```

use crate::beam::{Beam, Direction, FarDistance, FracBits, Source};
use crate::lit::RayPlane;
use crate::plane::DexelPlane;
use crate::triangle::{cross, dot, sub, Triangle, COORD_LIMIT};
use crate::visible::VisibleSurface;

/// Units per voxel of the pixel's point.
pub const POINT_UNITS: i64 = 4096;

/// How far (lattice steps) from the exact ray's rounding the search for the nearest candidate
/// looks.
pub const SEARCH: i64 = 8;

/// The ray that decides whether a pixel is lit by one light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Target {
    /// The face whose rays reach the pixel.
    pub dir: Direction,
    /// The layer of the voxel the ray must reach.
    pub layer: u32,
    /// That voxel's z (z_v or z_v + 1 of the column).
    pub z: i64,
    /// The ray's u offset (lattice steps of 2^−f).
    pub a: i64,
    /// The ray's v offset.
    pub b: i64,
    /// The contact segment, ends in 1/[`POINT_UNITS`] voxel: from the light to the last point
    /// of the exact ray to the pixel's point at least [`CONTACT_GAP`] in front of the visible
    /// plane (module doc, "Contact shadows"); `None` when the light itself is not.
    pub contact: Option<[[i64; 3]; 2]>,
    /// Whether a triangle kept by one of the 8 neighbouring columns crosses the contact
    /// segment: the OR of their answers to the cell's query (module doc, "The neighbours'
    /// triangles", [`crosses_any`]); `false` until they answer.
    pub neighbour_shadow: bool,
}

impl Target {
    /// Whether `beam`, arriving at the target's voxel, carries the target ray.
    pub fn in_beam<F: FracBits>(&self, beam: &Beam<F>) -> bool {
        let within = |lo: i64, hi: i64, x: i64| lo <= x && x <= hi;
        beam.direction() == self.dir
            && beam.layer().0 == self.layer
            && within(beam.u().lo().to_bits() as i64, beam.u().hi().to_bits() as i64, self.a)
            && within(beam.v().lo().to_bits() as i64, beam.v().hi().to_bits() as i64, self.b)
    }

    /// Whether one of `triangles` (the column's own) crosses the contact segment: a shadow cast
    /// onto the pixel from closer than its voxel, which the lattice ray's arrival does not see
    /// (module doc, "Contact shadows").
    pub fn shadowed_by(&self, triangles: &[Triangle]) -> bool {
        self.contact.is_some_and(|c| crosses_any(triangles, c))
    }

    /// Whether the pixel is in a contact shadow: a triangle of `triangles` (the column's own)
    /// or of a neighbouring column ([`Target::neighbour_shadow`]) crosses the contact segment.
    pub fn in_contact_shadow(&self, triangles: &[Triangle]) -> bool {
        self.neighbour_shadow || self.shadowed_by(triangles)
    }

    /// The same target once its neighbours have answered its contact query: `shadowed` is the
    /// OR of their [`crosses_any`] answers.
    pub fn with_neighbour_answers(self, shadowed: bool) -> Target {
        Target { neighbour_shadow: shadowed, ..self }
    }
}

/// A neighbour's answer to a cell's contact query: whether one of `triangles` (the answering
/// column's own) crosses the contact segment `[x0, x1]` (1/[`POINT_UNITS`] voxel,
/// [`Target::contact`]). Exact, the arithmetic of [`Target::shadowed_by`].
pub fn crosses_any(triangles: &[Triangle], [x0, x1]: [[i64; 3]; 2]) -> bool {
    triangles.iter().any(|t| crosses_segment(t, x0, x1))
}

/// How far in front of the visible plane the contact segment ends: ¼ voxel, in the plane's
/// normal units ([`crate::plane`]: 2⁻¹⁴ voxel along the normal's largest axis).
pub const CONTACT_GAP: i128 = 1 << 12;

/// Whether segment [x0, x1] (1/[`POINT_UNITS`] voxel) crosses the closed triangle `tri`: the
/// triangle's plane value `h = n·(X − V₀)` is positive at exactly one end, and with
/// d = x1 − x0 the three `E_ij = d·((V_i − x0) × (V_j − x0))` (whose sum is n·d) all have
/// the sign of n·d or are zero.
pub(crate) fn crosses_segment(tri: &Triangle, x0: [i64; 3], x1: [i64; 3]) -> bool {
    let scale = POINT_UNITS / 16;
    let v = tri.vertices().map(|c| c.map(|x| x as i64 * scale));
    let n = tri.normal();
    let side = |x: [i64; 3]| dot(n, sub(x, v[0])) > 0;
    if side(x0) == side(x1) {
        return false;
    }
    let d = sub(x1, x0);
    let nd = dot(n, d).signum();
    let rel = v.map(|p| sub(p, x0));
    [(0, 1), (1, 2), (2, 0)].iter().all(|&(i, j)| dot(d, cross(rel[i], rel[j])).signum() * nd >= 0)
}

/// The contact segment ([`Target::contact`]) from the light `s` to the pixel's point `p` (both
/// in 1/[`POINT_UNITS`] voxel) of column (x, y) with visible surface `vis`: `[s, x1]` with x1
/// the point of [s, p] where the plane's value is [`CONTACT_GAP`], rounded to the unit grid.
fn contact_segment(vis: &VisibleSurface, (x, y): (i32, i32), s: [i64; 3], p: [i64; 3]) -> Option<[[i64; 3]; 2]> {
    contact_point(&vis.plane, (x, y), vis.z_v, s, p).map(|x1| [s, x1])
}

/// The near end of the contact segment from the light `s` to point `p` (both in
/// 1/[`POINT_UNITS`] voxel) of a surface of plane `pl` (column (x, y), reference voxel `z_ref`):
/// the point of [s, p] where the plane's value is [`CONTACT_GAP`], rounded to the unit grid;
/// `None` when the light is not farther than the gap in front of the plane, or `p` not nearer.
pub(crate) fn contact_point(
    pl: &DexelPlane,
    (x, y): (i32, i32),
    z_ref: i32,
    s: [i64; 3],
    p: [i64; 3],
) -> Option<[i64; 3]> {
    let g = POINT_UNITS as i128;
    // 2¹⁶·POINT_UNITS·g at q (module doc's bit budget: below 2⁶⁵).
    let value = |q: [i64; 3]| {
        ((pl.nx as i128) << 16) * (q[0] as i128 - g * x as i128)
            + ((pl.ny as i128) << 16) * (q[1] as i128 - g * y as i128)
            + pl.nz as i128 * (q[2] as i128 - g * z_ref as i128)
            + ((pl.e as i128) << 16) * g
    };
    let gap = (CONTACT_GAP * g) << 16;
    let (vs, vp) = (value(s), value(p));
    if vs <= gap || vs <= vp {
        return None;
    }
    // x1 = s + σ·(p − s), σ = (vs − gap)/(vs − vp) ∈ (0, 1].
    let (num, den) = (vs - gap, vs - vp);
    Some([0, 1, 2].map(|i| s[i] + ((2 * num * (p[i] - s[i]) as i128 + den).div_euclid(2 * den)) as i64))
}

/// The face whose rays reach point `p` (in 1/[`POINT_UNITS`] voxel): its rays' origin, the exact ray's distance to `p` along the axis (`dist`) and its transverse offsets
/// scaled by it (a = an/dist, b = bn/dist, in lattice steps of the far square).
struct Face {
    dir: Direction,
    o: [i64; 3],
    dist: i128,
    an: i128,
    bn: i128,
}

impl Face {
    /// The first face (in [`Direction::ALL`] order) whose pyramid holds `p`; `None` if none
    /// does or the rays' origin lies outside [`COORD_LIMIT`].
    fn towards(p: [i128; 3], source: &Source, nn: i128) -> Option<Face> {
        let face = Direction::ALL.into_iter().find_map(|dir| {
            let o = source.ray_origin(dir);
            let (w, (u, v)) = (dir.principal().index(), dir.transverse());
            let dist = dir.sign() as i128 * (p[w] - 256 * o[w] as i128);
            let off = |i: usize| (p[i] - 256 * o[i] as i128) * nn;
            let (an, bn) = (off(u.index()), off(v.index()));
            (dist > 0 && an.abs() <= nn * dist && bn.abs() <= nn * dist).then_some(Face { dir, o, dist, an, bn })
        })?;
        (face.o.iter().all(|c| c.abs() <= COORD_LIMIT)).then_some(face)
    }
}

/// The offsets of the rays whose voxel at layer k (reach `tk` = T_k) is `q` along one
/// transverse axis whose origin coordinate is `o`: N·(16q − 8 − O) ≤ T·t < N·(16q + 8 − O),
/// cut to ±N.
fn rays_in_voxel(q: i64, o: i64, nn: i128, tk: i128) -> (i128, i128) {
    let lo = ceil_div(nn * (16 * q as i128 - 8 - o as i128), tk).max(-nn);
    let hi = (ceil_div(nn * (16 * q as i128 + 8 - o as i128), tk) - 1).min(nn);
    (lo, hi)
}

/// The lattice rectangle (inclusive) of `dir`'s rays whose voxel at layer `k` is `q`:
/// `rays_in_voxel` along each transverse axis; `None` when it is empty or the layer lies at or
/// behind the rays' origin.
pub fn voxel_rays<F: FracBits>(
    q: [i64; 3],
    dir: Direction,
    k: i64,
    source: &Source,
    far: FarDistance<F>,
) -> Option<((i64, i64), (i64, i64))> {
    let (o, lead) = (source.ray_origin(dir), source.lead(dir));
    let tk = (16 * k - lead) as i128;
    if tk <= 0 {
        return None;
    }
    let nn = far.scaled() as i128;
    let (ua, va) = dir.transverse();
    let range = |i: usize| rays_in_voxel(q[i], o[i], nn, tk);
    let ((a0, a1), (b0, b1)) = (range(ua.index()), range(va.index()));
    // Within ±N < 2³¹ (`rays_in_voxel` clamps).
    (a0 <= a1 && b0 <= b1).then_some(((a0 as i64, a1 as i64), (b0 as i64, b1 as i64)))
}

/// The ray that decides whether occupied voxel (x, y, z) is lit in the full lit store under
/// exact occluders (what `light` reports and reflected rays read): of the rays whose voxel at
/// that voxel's layer is (x, y, z), the one nearest the exact ray from the light to its
/// centre, in the far square's (u, v) metric. The voxel is lit iff that ray arrives there (as
/// a pixel is lit iff its target ray arrives: module doc). `None` if no face's rays reach the
/// voxel, or a coordinate lies outside [`COORD_LIMIT`].
pub fn voxel_ray<F: FracBits>(x: i32, y: i32, z: i64, source: &Source, far: FarDistance<F>) -> Option<Target> {
    let g = POINT_UNITS as i128;
    let q = [x as i64, y as i64, z];
    if q.iter().any(|c| c.abs() > COORD_LIMIT / 16) {
        return None;
    }
    let nn = far.scaled() as i128;
    let Face { dir, dist, an, bn, .. } = Face::towards(q.map(|c| g * c as i128), source, nn)?;
    let w = dir.principal().index();
    let k = source.layer_at(dir, q[w]);
    if k < 1 || k > far.get() as i64 {
        return None;
    }
    let ((a0, a1), (b0, b1)) = voxel_rays(q, dir, k, source, far)?;
    let (a0, a1, b0, b1) = (a0 as i128, a1 as i128, b0 as i128, b1 as i128);
    let round = |n: i128| (2 * n + dist).div_euclid(2 * dist);
    // The nearest lattice point of the box to (a, b): each coordinate rounded, then clamped.
    let (a, b) = (round(an).clamp(a0, a1) as i64, round(bn).clamp(b0, b1) as i64);
    Some(Target { dir, layer: k as u32, z, a, b, contact: None, neighbour_shadow: false })
}

/// ⌈n/d⌉ for d > 0.
fn ceil_div(n: i128, d: i128) -> i128 {
    -crate::lit::floor_div(-n, d)
}

/// The pixel's point P = (x, y, z\*) of column (x, y) with visible surface `vis`, in
/// 1/[`POINT_UNITS`] voxel (z\* rounded half up: module doc, "Definition"); `None` beyond
/// [`COORD_LIMIT`] or for a surface without a positive denominator.
pub(crate) fn pixel_point(x: i32, y: i32, vis: &VisibleSurface) -> Option<[i64; 3]> {
    let g = POINT_UNITS as i128;
    let (num, den) = (vis.num as i128, vis.den as i128);
    if den <= 0 {
        return None;
    }
    let p = [g * x as i128, g * y as i128, (2 * g * num + den).div_euclid(2 * den)];
    if p.iter().any(|c| c.abs() > (COORD_LIMIT as i128) * g / 16) {
        return None;
    }
    Some(p.map(|c| c as i64))
}

/// The target ray of column (x, y), whose visible surface is `vis`, for `source`'s rays from
/// `origin` (see the module doc); `None` if no ray qualifies or a coordinate lies outside
/// [`COORD_LIMIT`].
pub fn target<F: FracBits>(
    x: i32,
    y: i32,
    vis: &VisibleSurface,
    source: &Source,
    far: FarDistance<F>,
) -> Option<Target> {
    let p = pixel_point(x, y, vis)?.map(i128::from);
    let nn = far.scaled() as i128;
    let Face { dir, dist, an, bn, .. } = Face::towards(p, source, nn)?;
    let w = dir.principal().index();
    // The visible plane along this face's rays (its reference voxel is the same for every
    // candidate voxel); a back face is lit by no ray.
    let plane = RayPlane::new(&vis.plane, [x as i64, y as i64, vis.z_v as i64], source, dir, far);
    if !plane.faces_source() {
        return None;
    }
    // (ta, tb) nearer (a, b) than (sa, sb): the sign of dist²·(D₁ − D₂) / dist.
    let nearer = |(ta, tb): (i64, i64), (sa, sb): (i64, i64)| {
        let (ta, tb, sa, sb) = (ta as i128, tb as i128, sa as i128, sb as i128);
        dist * ((ta - sa) * (ta + sa) + (tb - sb) * (tb + sb)) - 2 * (an * (ta - sa) + bn * (tb - sb)) < 0
    };
    let round = |n: i128| (2 * n + dist).div_euclid(2 * dist);
    let mut best: Option<Target> = None;
    let depth = far.get() as i64;
    let z_v = vis.z_v as i64;
    for zq in [z_v, z_v + 1, z_v - 1].into_iter().filter(|z| (0..=depth).contains(z)) {
        let q = [x as i64, y as i64, zq];
        let k = source.layer_at(dir, q[w]);
        if k < 1 || k > depth {
            continue;
        }
        let Some(((a0, a1), (b0, b1))) = voxel_rays(q, dir, k, source, far) else { continue };
        let (a0, a1, b0, b1) = (a0 as i128, a1 as i128, b0 as i128, b1 as i128);
        let (ca, cb) = (round(an).clamp(a0, a1), round(bn).clamp(b0, b1));
        for ta in (ca - SEARCH as i128).max(a0)..=(ca + SEARCH as i128).min(a1) {
            for tb in (cb - SEARCH as i128).max(b0)..=(cb + SEARCH as i128).min(b1) {
                let (ta, tb) = (ta as i64, tb as i64);
                let outer = plane.value(ta, tb, k) > 0 || plane.value(ta, tb, k - 1) > 0;
                if outer && best.is_none_or(|t| nearer((ta, tb), (t.a, t.b))) {
                    best = Some(Target {
                        dir,
                        layer: k as u32,
                        z: zq,
                        a: ta,
                        b: tb,
                        contact: None,
                        neighbour_shadow: false,
                    });
                }
            }
        }
    }
    let light = source.pos.map(|c| (POINT_UNITS / 16) * c.to_bits() as i64);
    let point = p.map(|c| c as i64);
    best.map(|t| Target { contact: contact_segment(vis, (x, y), light, point), ..t })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::{frac, FarOffset, Layer, Origin, RayRange, SourceCoord, SourceId};
    use crate::normal::NormalCode;
    use crate::plane::DexelPlane;

    fn lcg(s: &mut u64) -> u64 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *s >> 33
    }

    fn r(s: &mut u64, lo: i64, hi: i64) -> i64 {
        lo + (lcg(s) % (hi - lo + 1) as u64) as i64
    }

    fn surface(num: i64, den: i64, plane: DexelPlane) -> VisibleSurface {
        VisibleSurface {
            num,
            den,
            facet: 0,
            material: 0,
            normal: NormalCode::default(),
            plane,
            z_v: num.div_euclid(den) as i32,
        }
    }

    /// The oracle: every lattice ray of the face, its voxel at the layer and its side of the
    /// plane from the definitions (the ray's point as an exact fraction, the plane function of
    /// [`crate::plane`]), the exact squared distance; no search window.
    fn brute<F: FracBits>(x: i64, y: i64, vis: &VisibleSurface, src: &Source, far: FarDistance<F>) -> Option<Target> {
        brute_in(x, y, vis, src, far, &[0, 1, -1])
    }

    /// [`brute`] with the candidate voxels `z_v + dz` for the `dz` given, in that order.
    fn brute_in<F: FracBits>(
        x: i64,
        y: i64,
        vis: &VisibleSurface,
        src: &Source,
        far: FarDistance<F>,
        dzs: &[i64],
    ) -> Option<Target> {
        let g = POINT_UNITS as i128;
        let p =
            [g * x as i128, g * y as i128, (2 * g * vis.num as i128 + vis.den as i128).div_euclid(2 * vis.den as i128)];
        let nn = far.scaled() as i128;
        let mut found = None;
        for dir in Direction::ALL {
            let o = src.ray_origin(dir);
            let (w, (ua, va)) = (dir.principal().index(), dir.transverse());
            let (u, v) = (ua.index(), va.index());
            let s = dir.sign() as i128;
            let dist = s * (p[w] - 256 * o[w] as i128);
            let (an, bn) = ((p[u] - 256 * o[u] as i128) * nn, (p[v] - 256 * o[v] as i128) * nn);
            if dist <= 0 || an.abs() > nn * dist || bn.abs() > nn * dist {
                continue;
            }
            let mut best: Option<(i128, Target)> = None;
            for zq in dzs.iter().map(|dz| vis.z_v as i64 + dz) {
                let q = [x, y, zq];
                if !(0..=far.get() as i64).contains(&zq) {
                    continue;
                }
                // The voxel's centre plane lies `tq` sixteenths from the origin along the
                // axis: a layer whose T is tq, the layer before it 16 sixteenths (or the
                // origin) back; the layers are numbered from the slab whose centre plane is
                // the last one at or behind the origin (T ≡ −lead mod 16).
                let tq = s as i64 * (16 * q[w] - o[w]);
                let k = (tq + (-tq).rem_euclid(16)) / 16;
                if tq <= 0 || k > far.get() as i64 {
                    continue;
                }
                for a in -nn..=nn {
                    for b in -nn..=nn {
                        // 16·N·p at distance tt: N·O + tt·(s·N, a, b) on (w, u, v).
                        let at = |tt: i64| {
                            let tt = tt.max(0) as i128;
                            let mut m = o.map(|c| nn * c as i128);
                            m[w] += tt * s * nn;
                            m[u] += tt * a;
                            m[v] += tt * b;
                            m
                        };
                        let m = at(tq);
                        let voxel = m.map(|c| (c + 8 * nn).div_euclid(16 * nn));
                        if voxel != [q[0] as i128, q[1] as i128, q[2] as i128] {
                            continue;
                        }
                        let pl = &vis.plane;
                        let side = |m: [i128; 3]| {
                            ((pl.nx as i128) << 16) * (m[0] - 16 * nn * x as i128)
                                + ((pl.ny as i128) << 16) * (m[1] - 16 * nn * y as i128)
                                + pl.nz as i128 * (m[2] - 16 * nn * vis.z_v as i128)
                                + ((pl.e as i128) << 16) * 16 * nn
                                > 0
                        };
                        if !side(at(0)) {
                            return None;
                        }
                        if !(side(m) || side(at(tq - 16))) {
                            continue;
                        }
                        let d2 = (a * dist - an).pow(2) + (b * dist - bn).pow(2);
                        if best.is_none_or(|(bd, _)| d2 < bd) {
                            let (a, b) = (a as i64, b as i64);
                            best = Some((
                                d2,
                                Target { dir, layer: k as u32, z: zq, a, b, contact: None, neighbour_shadow: false },
                            ));
                        }
                    }
                }
            }
            found = best.map(|(_, t)| t);
            break;
        }
        found
    }

    fn like_brute_force<F: FracBits>(seed: u64) {
        let mut s = seed;
        let (mut some, mut none) = (0, 0);
        for _ in 0..400 {
            let d = r(&mut s, 6, 14);
            let far = FarDistance::<F>::new(d as u32).unwrap();
            let src = Source::new(SourceId(0), [0; 3].map(|_| SourceCoord::from_bits(r(&mut s, 0, 16 * d) as i32)));
            let origin = if lcg(&mut s) % 2 == 0 { Origin::SourceVoxel } else { Origin::Light };
            let src = src.with_origin(origin);
            let (x, y) = (r(&mut s, 0, d), r(&mut s, 0, d));
            let den = r(&mut s, 1, 999);
            let num = r(&mut s, 0, d * den);
            let m = r(&mut s, -16384, 16384);
            let frac_z = (num.rem_euclid(den) as f64) / den as f64;
            let plane = DexelPlane {
                id: 0,
                nx: r(&mut s, -16384, 16384) as i16,
                ny: r(&mut s, -16384, 16384) as i16,
                nz: (m << 16) as i32,
                e: (-(m as f64) * frac_z).round() as i32 + r(&mut s, -40, 40) as i32,
            };
            let vis = surface(num, den, plane);
            let want = brute(x, y, &vis, &src, far);
            let got = target(x as i32, y as i32, &vis, &src, far);
            assert_eq!(
                got.map(|t| Target { contact: None, ..t }),
                want,
                "column ({x}, {y}) z* = {num}/{den} {plane:?} {src:?} D = {d}"
            );
            if want.is_some() {
                some += 1
            } else {
                none += 1
            }
        }
        assert!(some > 150 && none > 5, "targets found and not found ({some} / {none})");
    }

    #[test]
    fn target_equals_the_brute_force_nearest() {
        like_brute_force::<frac::U0>(1);
        like_brute_force::<frac::U1>(2);
    }

    /// [`voxel_ray`] against every lattice ray of the face whose pyramid holds the voxel's
    /// centre: among those whose voxel at the voxel's layer is the voxel (from the definitions,
    /// as in [`brute_in`]), none is nearer the exact ray to the centre; and a voxel such rays
    /// reach always has one.
    #[test]
    fn voxel_ray_is_the_nearest_ray_through_the_voxel() {
        fn check<F: FracBits>(seed: u64) {
            let mut s = seed;
            let mut found = 0;
            for _ in 0..300 {
                let d = r(&mut s, 6, 14);
                let far = FarDistance::<F>::new(d as u32).unwrap();
                let src = Source::new(SourceId(0), [0; 3].map(|_| SourceCoord::from_bits(r(&mut s, 0, 16 * d) as i32)));
                let src = src.with_origin(if lcg(&mut s) % 2 == 0 { Origin::SourceVoxel } else { Origin::Light });
                let q = [r(&mut s, 0, d), r(&mut s, 0, d), r(&mut s, 0, d)];
                let g = POINT_UNITS as i128;
                let p = q.map(|c| g * c as i128);
                let nn = far.scaled() as i128;
                let got = voxel_ray(q[0] as i32, q[1] as i32, q[2], &src, far);
                // The face, as `target`'s module doc defines it (first in `Direction::ALL`).
                let face = Direction::ALL.into_iter().find(|&dir| {
                    let o = src.ray_origin(dir);
                    let (w, (ua, va)) = (dir.principal().index(), dir.transverse());
                    let dist = dir.sign() as i128 * (p[w] - 256 * o[w] as i128);
                    let off = |i: usize| (p[i] - 256 * o[i] as i128) * nn;
                    dist > 0 && off(ua.index()).abs() <= nn * dist && off(va.index()).abs() <= nn * dist
                });
                let Some(dir) = face else {
                    assert_eq!(got, None, "{q:?} {src:?}: no face");
                    continue;
                };
                let o = src.ray_origin(dir);
                let (w, (ua, va)) = (dir.principal().index(), dir.transverse());
                let (u, v) = (ua.index(), va.index());
                let sg = dir.sign() as i128;
                let dist = sg * (p[w] - 256 * o[w] as i128);
                let (an, bn) = ((p[u] - 256 * o[u] as i128) * nn, (p[v] - 256 * o[v] as i128) * nn);
                let tq = sg as i64 * (16 * q[w] - o[w]);
                let k = (tq + (-tq).rem_euclid(16)) / 16;
                let mut best: Option<i128> = None;
                if tq > 0 && k <= far.get() as i64 {
                    for a in -nn..=nn {
                        for b in -nn..=nn {
                            let mut m = o.map(|c| nn * c as i128);
                            m[w] += tq as i128 * sg * nn;
                            m[u] += tq as i128 * a;
                            m[v] += tq as i128 * b;
                            if m.map(|c| (c + 8 * nn).div_euclid(16 * nn)) == q.map(i128::from) {
                                let d2 = (a * dist - an).pow(2) + (b * dist - bn).pow(2);
                                best = Some(best.map_or(d2, |x: i128| x.min(d2)));
                            }
                        }
                    }
                }
                match (got, best) {
                    (Some(t), Some(d2)) => {
                        assert_eq!((t.dir, t.layer as i64, t.z), (dir, k, q[2]), "{q:?} {src:?}");
                        let (a, b) = (t.a as i128, t.b as i128);
                        assert_eq!((a * dist - an).pow(2) + (b * dist - bn).pow(2), d2, "{q:?} {src:?}: nearest");
                        found += 1;
                    }
                    (None, None) => {}
                    (g, b) => panic!("{q:?} {src:?} D = {d}: got {g:?}, the nearest at {b:?}"),
                }
            }
            assert!(found > 150, "voxels with a ray: {found}");
        }
        check::<frac::U0>(3);
        check::<frac::U1>(4);
    }

    /// A face the light grazes: the plane cuts the bracketing voxels so that every ray through
    /// them at its layer lies behind it; the target is the nearest ray in front (z_v − 1).
    #[test]
    fn a_grazed_face_takes_its_target_in_front() {
        let far = FarDistance::<frac::U0>::new(12).unwrap();
        let src = Source::at_voxel(SourceId(0), [11, 12, 0]).unwrap();
        // z* = 4 at column (1, 3), the plane tilted along x (its normal 19° from −z).
        let vis = surface(40, 10, DexelPlane { id: 0, nx: -5517, ny: 0, nz: -(16384 << 16), e: 0 });
        let want = brute(1, 3, &vis, &src, far);
        assert_eq!(brute_in(1, 3, &vis, &src, far, &[0, 1]), None, "no ray through z_v or z_v + 1 on the outer side");
        let t = target(1, 3, &vis, &src, far).unwrap();
        assert_eq!(Some(Target { contact: None, ..t }), want);
        assert_eq!((t.dir, t.layer, t.z, t.a, t.b), (Direction::NegX, 10, 3, -11, 4));
    }

    /// A light at voxel (6, 6, 0) over a floor at z* = 9.5: shelves between them over the pixel
    /// shadow it from ½ voxel, not from ⅛ (within the gap), nor beside the ray, nor the floor's
    /// own triangle.
    #[test]
    fn contact_shadows_by_hand() {
        let far = FarDistance::<frac::U0>::new(12).unwrap();
        let src = Source::at_voxel(SourceId(0), [6, 6, 0]).unwrap();
        let vis = surface(19, 2, DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 });
        let t = target(8, 5, &vis, &src, far).unwrap();
        let [x0, x1] = t.contact.expect("the light is far in front of the floor");
        let u = POINT_UNITS;
        assert_eq!(x0, [6 * u, 6 * u, 0], "from the light");
        // ¼ voxel in front of the floor, on the ray to P = (8, 5, 9.5): 9.25/9.5 of the way.
        assert_eq!(x1[2], 37 * u / 4);
        for (c, p) in [(0, 8 * u), (1, 5 * u)] {
            let exact = 6.0 * u as f64 + (p - 6 * u) as f64 * 9.25 / 9.5;
            assert!((x1[c] as f64 - exact).abs() <= 0.5, "x1 {x1:?} on the ray");
        }
        // Shelves in sixteenths: the ray crosses z = 9 near (126.3, 80.8).
        let shelf =
            |z: i32, dx: i32| Triangle::new([[100 + dx, 60, z], [160 + dx, 60, z], [130 + dx, 110, z]]).unwrap();
        assert!(t.shadowed_by(&[shelf(144, 0)]), "½ voxel in front: a contact shadow");
        assert!(!t.shadowed_by(&[shelf(150, 0)]), "⅛ voxel in front: within the gap");
        assert!(!t.shadowed_by(&[shelf(152, 0)]), "the floor's own plane");
        assert!(!t.shadowed_by(&[shelf(144, 80)]), "beside the ray");
        assert!(t.shadowed_by(&[shelf(144, 80), shelf(144, 0)]), "any of the column's triangles");
        // A light within the gap of the floor's plane (3/16 voxel above z* = 1.5) tests nothing;
        // 5/16 above, it does.
        let low = surface(3, 2, DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 });
        let light = |z: i32| Source::new(SourceId(0), [96, 96, z].map(SourceCoord::from_bits));
        let contact = |z: i32| target(7, 6, &low, &light(z), far).map(|t| t.contact.is_some());
        assert_eq!((contact(21), contact(19)), (Some(false), Some(true)));
    }

    /// Every term of the contact test at the bit budget's limits (overflow checks on in the
    /// test profile): vertices and segment ends at ±[`COORD_LIMIT`] sixteenths.
    #[test]
    fn contact_arithmetic_at_the_limits() {
        let l = COORD_LIMIT as i32;
        let u = POINT_UNITS / 16 * COORD_LIMIT;
        let tris = [
            Triangle::new([[-l, -l, -l], [l, -l, l], [-l, l, l]]).unwrap(),
            Triangle::new([[l, l, -l], [-l, l, l], [l, -l, -l]]).unwrap(),
            Triangle::new([[-l, -l, l], [l, l, -l], [l, -l, l]]).unwrap(),
        ];
        let mut crossed = 0;
        for x0 in [[-u, -u, -u], [u, u, u], [-u, u, -u]] {
            for x1 in [[u, u, u], [-u, -u, u], [u, -u, -u], [0, 0, 0]] {
                crossed += tris.iter().filter(|tri| crosses_any(core::slice::from_ref(tri), [x0, x1])).count();
            }
        }
        assert!(crossed > 0);
        // The contact segment's plane values and rounding, from a light at the limit to a
        // column at the other end, with the steepest plane.
        let far = FarDistance::<frac::U0>::new(crate::beam::MAX_FAR).unwrap();
        let src = Source::new(SourceId(0), [SourceCoord::from_bits(-l); 3]);
        let plane = DexelPlane { id: 0, nx: -16384, ny: -16384, nz: -(1 << 30), e: -(1 << 14) };
        let far_col = (COORD_LIMIT / 16 - 1) as i32;
        let vis = surface((far_col as i64) * 2 + 1, 2, plane);
        let got = contact_segment(&vis, (far_col, far_col), src.pos.map(|c| 256 * c.to_bits() as i64), [u - 4096; 3]);
        assert!(got.is_some(), "{got:?}");
        let _ = target(far_col, far_col, &vis, &src, far);
    }

    #[test]
    fn a_beam_holds_its_target() {
        let far = FarDistance::<frac::U0>::new(12).unwrap();
        let src = Source::at_voxel(SourceId(0), [6, 6, 0]).unwrap();
        // A floor at z* = 9.5, normal up (toward the viewer at −z), under the light.
        let vis = surface(19, 2, DexelPlane { id: 0, nx: 0, ny: 0, nz: -(16384 << 16), e: 8192 });
        let t = target(8, 5, &vis, &src, far).unwrap();
        assert_eq!((t.dir, t.layer, t.z), (Direction::PosZ, 9, 9), "a +z ray, into the voxel above the floor");
        let beam = |dir, layer, u: (i32, i32), v: (i32, i32)| {
            let range = |(lo, hi): (i32, i32)| RayRange::new(FarOffset::from_num(lo), FarOffset::from_num(hi)).unwrap();
            Beam::new(SourceId(0), dir, Layer(layer), range(u), range(v), far).unwrap()
        };
        assert!(t.in_beam(&beam(Direction::PosZ, 9, (2, 3), (-2, -1))));
        assert!(!t.in_beam(&beam(Direction::PosZ, 9, (0, 2), (-2, -1))), "another ray");
        assert!(!t.in_beam(&beam(Direction::PosZ, 10, (2, 3), (-2, -1))), "another layer");
        assert!(!t.in_beam(&beam(Direction::PosX, 9, (2, 3), (-2, -1))), "another face");
        assert_eq!((t.a, t.b), (3, -1), "nearest to (2/9.5·12, −1/9.5·12) = (2.53, −1.26) on the outer side");
    }
}

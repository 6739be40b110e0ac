//! §1.1, §1.3.2, ch. 5 — reflected rays of the distributed ray tree: what one cell computes.
//!
//! A cell whose visible voxel is reflective (material `Kr > 0`) emits a [`ReflectRay`] in the
//! view direction mirrored about its normal. The ray walks the grid voxel by voxel on an
//! incremental [`Line`] (§2.3), like a shadow ray; the cell owning the first occupied voxel it
//! meets (of another facet, unless [`ReflectRay::advance`] is told otherwise) shades that voxel
//! for the ray's direction and, if the voxel is itself reflective and the tree may grow (depth
//! and Hall's intensity threshold, §1.2.5.1), emits its own reflected ray and waits for that
//! answer before answering its parent (§1.3.2). The answer is the linear intensity (thesis
//! §5.5.5: `I = local + Kr·I_R`) as [`Answer`], routed back; a ray leaving the grid answers the
//! background (0).
//!
//! **Normals** (§5.2): [`ReflectNormal::Facet`] mirrors about the dexel's stored facet normal
//! (§5.2.1), in exact integers: the 16-bit octahedral code decodes to an integer vector
//! N = 255 × the decoded normal ([`normal_int`], |N_i| ≤ 255) and the mirrored direction of an
//! integer direction I is `R = |N|²·I − 2(N·I)·N`, a positive multiple of the exact mirror image.
//! [`ReflectNormal::Face`] stores no normal: the ray is mirrored about the voxel face(s) it
//! entered through — the sign of the component(s) of the last step flips (§5.2.2, the "face
//! flip" of §5.5.4). The primary ray (along +z) always enters through the −z face, so a face
//! flip sends it straight back to the eye: the defect the thesis describes ("renvoyés vers la
//! source").
//!
//! **Bit budget.** Directions are lattice vectors (1/[`Q`] voxel) with |I_i| ≤ 2²⁰ ([`MAX_SPAN`]);
//! |N|² ≤ 3·255² < 2¹⁸, so |N|²·|I_i| < 2³⁸, |N·I| < 2³⁰ and |R_i| < 2⁴⁰. [`scaled`] brings R back
//! to a span of 2·Q·n lattice units (the ray must be able to cross the whole grid): products
//! |R_i|·span < 2⁶¹ for n ≤ [`MAX_GRID`] = 2¹⁵ — i64 throughout.

use crate::dexel::{Dexel, DexelStore};
use crate::light::Port;
use crate::normal::NormalCode;
use crate::plane::DexelPlane;
use crate::ray::{cell_step, Connectivity, Line, LineError, MAX_SPAN, Q};
use crate::shade::{dot, normalise};
use crate::units::{FacetId, MaterialId};

/// Largest grid side reflected rays support (spans of 2·Q·n ≤ [`MAX_SPAN`]).
pub const MAX_GRID: u32 = (MAX_SPAN / (2 * Q)) as u32;

/// Fixed-point scale of answers: intensity 1.0 = 4096 (Q12).
pub const ANSWER_ONE: f32 = 4096.0;

/// A routed answer: linear RGB intensity in Q12, saturated at 65535 (16.0).
pub type Answer = [u16; 3];

/// Which normal mirrors a ray (§5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ReflectNormal {
    /// The facet normal stored in the dexel (§5.2.1).
    #[default]
    Facet,
    /// The face of the voxel the ray entered through: flip the sign of that component (§5.2.2,
    /// §5.5.4).
    Face,
}

/// Where a reflected ray leaves the voxel its parent ray hit (§5.3: "le choix du calcul de
/// l'intersection entre le rayon et la surface"). Each is a lattice point (1/[`Q`] voxel)
/// inside the hit voxel, so the reflected ray starts in the cell that holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum HitPoint {
    /// §5.3.2: at the centre of the hit voxel — the incident ray replaced by the parallel ray
    /// through the centre ("calculs plus simples", "une légère erreur").
    #[default]
    Centre,
    /// §5.3.1: where the incident ray entered the hit voxel, on the face (the last face, for a
    /// step through an edge or a corner) it crossed, from the ray's integer state.
    Edge,
    /// §5.3.3: where the incident ray meets the plane the hit voxel's dexel stores
    /// ([`crate::plane`]), moved into the voxel when it lies outside ("l'intersection réelle
    /// peut ne pas se trouver dans le pixel coupé") or when the ray runs parallel to the plane.
    Exact,
}

impl HitPoint {
    /// Every hit rule.
    pub const ALL: [HitPoint; 3] = [HitPoint::Centre, HitPoint::Edge, HitPoint::Exact];

    /// The rule's name, as hosts spell it (`--hit`).
    pub const fn name(self) -> &'static str {
        match self {
            HitPoint::Centre => "centre",
            HitPoint::Edge => "edge",
            HitPoint::Exact => "exact",
        }
    }

    /// The rule's code in a reflection setup record (2 bits).
    pub const fn code(self) -> u8 {
        match self {
            HitPoint::Centre => 0,
            HitPoint::Edge => 1,
            HitPoint::Exact => 2,
        }
    }

    /// The rule of code `code`, if any.
    pub const fn from_code(code: u8) -> Option<HitPoint> {
        match code {
            0 => Some(HitPoint::Centre),
            1 => Some(HitPoint::Edge),
            2 => Some(HitPoint::Exact),
            _ => None,
        }
    }
}

/// The ray that hit a voxel, as the hit voxel's cell knows it: a point of its continuous line
/// (`num / den` lattice units, [`Line::point`]), its direction and the faces its last step
/// crossed (bit k: axis k).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Incident {
    /// A point of the line: numerators, lattice units × `den`.
    pub num: [i64; 3],
    /// Its denominator, > 0.
    pub den: i64,
    /// Direction (lattice units).
    pub dir: [i32; 3],
    /// Faces entered by the last step (bit k: axis k).
    pub entry: u8,
}

impl Incident {
    /// The primary ray of column (x, y): the column's centre line along +z (the view), entering
    /// its voxels by their −z face.
    pub const fn primary(x: u16, y: u16) -> Incident {
        Incident { num: [x as i64 * Q as i64, y as i64 * Q as i64, 0], den: 1, dir: [0, 0, 1], entry: 0b100 }
    }

    /// A reflected ray at its current voxel.
    pub fn of(ray: &ReflectRay) -> Incident {
        let (num, den) = ray.line.point();
        Incident { num, den, dir: ray.dir, entry: ray.entry }
    }
}

/// `n / d` rounded half up (d ≠ 0).
fn round_div(n: i128, d: i128) -> i128 {
    let (n, d) = if d < 0 { (-n, -d) } else { (n, d) };
    (2 * n + d).div_euclid(2 * d)
}

/// The lattice point a reflected ray leaves voxel `at` from under `rule`, for the incident ray
/// `inc` that hit it; `plane` is the plane of the hit voxel's dexel, `lo` its first voxel
/// (the plane's reference, [`crate::plane`]). The point is clamped into the voxel
/// (`at·Q − Q/2 ..= at·Q + Q/2 − 1` on each axis).
///
/// Bit budget: with the incident's point below 2⁴² × den (den ≤ 2²⁰) and |dir| ≤ 2²⁰, the plane
/// value at it, `2¹⁶·nx·(X − Q·x) + … + Q·2¹⁶·e`, times den, is below 2⁷⁹; its slope along dir
/// below 2⁵²; the products that place the point below 2¹⁰⁰: `i128`.
pub fn hit_point(at: [u16; 3], inc: &Incident, plane: &DexelPlane, lo: u16, rule: HitPoint) -> [i32; 3] {
    let centre = at.map(|c| c as i32 * Q);
    let (d, den) = (inc.dir.map(i128::from), inc.den as i128);
    let p = inc.num.map(i128::from);
    // t, as (tn, td) with td > 0, such that the point is p/den + (tn/td)·dir.
    let t = match rule {
        HitPoint::Centre => None,
        HitPoint::Edge => (0..3)
            .filter(|&k| inc.entry & (1 << k) != 0 && d[k] != 0)
            .map(|k| {
                // The face entered along axis k: the low one when moving up, the high one down.
                let face = (centre[k] - d[k].signum() as i32 * (Q / 2)) as i128;
                let (tn, td) = (face * den - p[k], den * d[k]);
                if td < 0 {
                    (-tn, -td)
                } else {
                    (tn, td)
                }
            })
            // The last face crossed: the largest t (cross-multiplied, both denominators > 0).
            .reduce(|a, b| if b.0 * a.1 > a.0 * b.1 { b } else { a }),
        HitPoint::Exact => {
            let s = 1i128 << 16;
            let (x, y, q) = (at[0] as i128, at[1] as i128, Q as i128);
            let g = s * plane.nx as i128 * (p[0] - q * x * den)
                + s * plane.ny as i128 * (p[1] - q * y * den)
                + plane.nz as i128 * (p[2] - q * lo as i128 * den)
                + q * s * plane.e as i128 * den;
            let slope = s * plane.nx as i128 * d[0] + s * plane.ny as i128 * d[1] + plane.nz as i128 * d[2];
            // g/den + t·slope = 0.
            (slope != 0).then(|| if slope < 0 { (g, -slope * den) } else { (-g, slope * den) })
        }
    };
    let Some((tn, td)) = t else { return centre };
    core::array::from_fn(|k| {
        let v = round_div(p[k] * td + tn * d[k] * den, den * td);
        v.clamp((centre[k] - Q / 2) as i128, (centre[k] + Q / 2 - 1) as i128) as i32
    })
}

/// Where a reflected ray of direction `dir` leaving lattice point `from` of voxel `at` starts its
/// walk. The 6-connected walk starts at `from`. The 26/18 walks read a line only where it
/// crosses the centre planes of its major axis (largest |dir|, lowest index on ties,
/// [`crate::ray`]), and their first voxel is the line's at the first centre plane, which for a
/// point off that plane can lie in a neighbouring column — a column the emitting cell does not
/// own. So for them the start is the same line's point on the centre plane of `at` (the same
/// walk from there on), its other coordinates kept inside the voxel. A point on the centre plane
/// (the voxel's centre, [`HitPoint::Centre`]) is returned unchanged.
pub fn walk_start(from: [i32; 3], dir: [i32; 3], at: [u16; 3], conn: Connectivity) -> [i32; 3] {
    if conn == Connectivity::Six {
        return from;
    }
    let m = (1..3).fold(0, |m, i| if dir[i].abs() > dir[m].abs() { i } else { m });
    let centre = at.map(|c| c as i32 * Q);
    if dir[m] == 0 || from[m] == centre[m] {
        return from;
    }
    // from + s·dir with s = (centre_m − from_m) / dir_m; |products| < 2²²·2²⁰.
    let (sn, sd) = ((centre[m] - from[m]) as i128, dir[m] as i128);
    core::array::from_fn(|i| {
        if i == m {
            centre[m]
        } else {
            let v = round_div(from[i] as i128 * sd + sn * dir[i] as i128, sd);
            v.clamp((centre[i] - Q / 2) as i128, (centre[i] + Q / 2 - 1) as i128) as i32
        }
    })
}

/// The octahedral normal code as an exact integer vector: 255 × [`NormalCode::decode`].
pub fn normal_int(c: NormalCode) -> [i32; 3] {
    let (qx, qy) = ((c.0 >> 8) as i32, (c.0 & 0xff) as i32);
    let (mut x, mut y) = (2 * qx - 255, 2 * qy - 255);
    let z = 255 - x.abs() - y.abs();
    if z < 0 {
        let (ox, oy) = (x, y);
        let sign = |v: i32| if v < 0 { -1 } else { 1 };
        x = (255 - oy.abs()) * sign(ox);
        y = (255 - ox.abs()) * sign(oy);
    }
    [x, y, z]
}

/// `|N|²·I − 2(N·I)·N`: the mirror image of `i` about the plane of normal `n`, times |N|².
pub fn mirror(i: [i64; 3], n: [i32; 3]) -> [i64; 3] {
    let n = n.map(i64::from);
    let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    let ni = n[0] * i[0] + n[1] * i[1] + n[2] * i[2];
    [0, 1, 2].map(|k| nn * i[k] - 2 * ni * n[k])
}

/// `i` with the components of the axes in `axes` (bit k = axis k) negated (the face flip).
pub fn face_flip(i: [i64; 3], axes: u8) -> [i64; 3] {
    [0, 1, 2].map(|k| if axes >> k & 1 == 1 { -i[k] } else { i[k] })
}

/// `r` scaled so that its largest component is `span` (truncated toward zero); `None` for a
/// zero vector.
pub fn scaled(r: [i64; 3], span: i32) -> Option<[i32; 3]> {
    let m = r.iter().map(|c| c.abs()).max()?;
    (m > 0).then(|| r.map(|c| (c * span as i64 / m) as i32))
}

/// A reflected ray in flight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectRay {
    /// The walk; its current voxel is in the column of the cell holding the ray.
    pub line: Line,
    /// Direction of the walk (B − A, lattice units).
    pub dir: [i32; 3],
    /// The cell waiting for the answer.
    pub parent: [u16; 2],
    /// The parent's wait-table slot the answer is for.
    pub slot: u16,
    /// Facet of the voxel the ray left.
    pub facet: FacetId,
    /// Tree level: 1 for a ray from a visible voxel.
    pub level: u8,
    /// Product of the Kr of the voxels the ray's ancestors left, its own included (Hall's
    /// contribution weight, §1.2.5.1).
    pub weight: f32,
    /// Axes (bit k) changed by the last step: the face(s) the current voxel was entered by.
    pub entry: u8,
    /// Whether the current voxel is still the emitting one (not tested).
    pub fresh: bool,
    /// The transparent material the ray travels inside, once a refraction took it in (`None`:
    /// outside every solid). Only measured (the leaks of §5.5.2: a ray inside that meets another
    /// material, or leaves the grid, went through its solid's surface); the ray's wire form does
    /// not carry it (traces hold no transparent material).
    pub inside: Option<MaterialId>,
}

/// What the cell holding a [`ReflectRay`] does with it this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReflectStep {
    /// The current voxel (depth `z`) is occupied by `dexel`: shade it (and maybe reflect again).
    Hit(Dexel, u16),
    /// The ray left the grid: answer the background.
    Exit,
    /// The next voxel is in this column.
    Stay,
    /// The next voxel is in the neighbour column through this port.
    Forward(Port),
}

/// The direction a voxel hit by a ray of direction `incident` (entered by the faces `entry`)
/// reflects toward, as a lattice vector of largest component `span`; `None` if degenerate.
pub fn reflected_dir(
    incident: [i32; 3],
    entry: u8,
    normal: NormalCode,
    mode: ReflectNormal,
    span: i32,
) -> Option<[i32; 3]> {
    let i = incident.map(i64::from);
    let r = match mode {
        ReflectNormal::Facet => mirror(i, normal_int(normal)),
        ReflectNormal::Face => face_flip(i, entry),
    };
    scaled(r, span)
}

impl ReflectRay {
    /// A ray leaving lattice point `a` (in the voxel of the cell that emits it: its centre
    /// `Q·v`, or a [`hit_point`] through [`walk_start`]) along lattice direction `dir`,
    /// answering to `parent`'s slot `slot`.
    #[allow(clippy::too_many_arguments)]
    pub fn leaving(
        a: [i32; 3],
        dir: [i32; 3],
        conn: Connectivity,
        parent: [u16; 2],
        slot: u16,
        facet: FacetId,
        level: u8,
        weight: f32,
    ) -> Result<Self, LineError> {
        let b = [a[0] + dir[0], a[1] + dir[1], a[2] + dir[2]];
        Ok(ReflectRay {
            line: Line::new(a, b, conn)?,
            dir,
            parent,
            slot,
            facet,
            level,
            weight,
            entry: 0,
            fresh: true,
            inside: None,
        })
    }

    /// The 4 classes of rays by the signs of their x and y steps (bit 0: x decreasing, bit 1: y
    /// decreasing). A ray's cell steps never go against its class, so within a class every move
    /// strictly increases ±x ± y: the basis of the no-deadlock argument (host `reflect`).
    pub fn class(&self) -> usize {
        (self.dir[0] < 0) as usize | ((self.dir[1] < 0) as usize) << 1
    }

    /// One voxel of work in the cell owning the current voxel of a grid of side `n` and depth
    /// `depth`: test it against the column's dexels (not the emitting voxel; not the emitting
    /// facet's voxels when `skip_own_facet`, §5.5.2), then take one step.
    pub fn advance<const D: usize>(
        &mut self,
        store: &DexelStore<D>,
        n: u32,
        depth: u32,
        skip_own_facet: bool,
    ) -> ReflectStep {
        let here = self.line.voxel();
        if !self.fresh {
            if let Ok(z) = u16::try_from(here[2]) {
                if let Some(d) = store.occupied(z) {
                    if !(skip_own_facet && d.facet == self.facet) {
                        return ReflectStep::Hit(*d, z);
                    }
                }
            }
        }
        self.fresh = false;
        let Some(next) = self.line.step() else { return ReflectStep::Exit };
        let inside = |c: i32, lim: u32| c >= 0 && (c as u32) < lim;
        if !(inside(next[0], n) && inside(next[1], n) && inside(next[2], depth)) {
            return ReflectStep::Exit;
        }
        self.entry = (0..3).fold(0, |m, k| m | ((next[k] != here[k]) as u8) << k);
        match cell_step(here, next).and_then(|(dx, dy)| Port::from_delta(dx, dy)) {
            Some(p) => ReflectStep::Forward(p),
            None => ReflectStep::Stay,
        }
    }
}

/// The unit normal a hit voxel is shaded with, facing the ray's origin (`v` = −direction,
/// normalised): the facet's (§5.2.1) or the entered face's (§5.2.2).
pub fn hit_normal(d: &Dexel, mode: ReflectNormal, v: [f32; 3], entry: u8, dir: [i32; 3]) -> [f32; 3] {
    let n = match mode {
        ReflectNormal::Facet => normalise(d.normal.decode()),
        ReflectNormal::Face => {
            normalise([0, 1, 2].map(|k| if entry >> k & 1 == 1 { -(dir[k].signum() as f32) } else { 0.0 }))
        }
    };
    if dot(n, v) < 0.0 {
        n.map(|c| -c)
    } else {
        n
    }
}

/// The unit vector from a hit point back along a ray of direction `dir`.
pub fn toward_origin(dir: [i32; 3]) -> [f32; 3] {
    normalise(dir.map(|c| -(c as f32)))
}

/// An intensity as an answer (Q12, rounded, saturated).
pub fn to_answer(c: [f32; 3]) -> Answer {
    c.map(|v| (v * ANSWER_ONE + 0.5).clamp(0.0, u16::MAX as f32) as u16)
}

/// §5.5.5: `local + Kr · answer`.
pub fn combine(local: [f32; 3], kr: f32, answer: Answer) -> [f32; 3] {
    [0, 1, 2].map(|k| local[k] + kr * (answer[k] as f32 / ANSWER_ONE))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_normal_is_the_decoded_one() {
        for code in (0..=u16::MAX).step_by(97) {
            let c = NormalCode(code);
            let (a, b) = (normal_int(c), c.decode());
            for k in 0..3 {
                assert!((a[k] as f32 / 255.0 - b[k]).abs() < 1e-5, "code {code}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn mirror_is_a_reflection() {
        // About the plane y = z (normal (0, 1, −1)): the view ray (0, 0, 1) goes along +y.
        assert_eq!(mirror([0, 0, 1], [0, 1, -1]), [0, 2, 0]);
        // A reflection keeps the length and reverses the normal component.
        let (i, n) = ([3i64, -7, 11], [2i32, 5, -1]);
        let r = mirror(i, n);
        let nn = 30i64;
        assert_eq!(r.iter().map(|c| c * c).sum::<i64>(), nn * nn * i.iter().map(|c| c * c).sum::<i64>());
        let dn = |v: [i64; 3]| v[0] * 2 + v[1] * 5 - v[2];
        assert_eq!(dn(r), -nn * dn(i));
        assert_eq!(face_flip([1, -2, 3], 0b101), [-1, -2, -3]);
        assert_eq!(scaled([0, 0, 0], 8), None);
        assert_eq!(scaled([4, -2, 1], 8), Some([8, -4, 2]));
    }

    #[test]
    fn answers_round_trip() {
        let a = to_answer([0.25, 1.0, 20.0]);
        assert_eq!(a, [1024, 4096, u16::MAX]);
        assert_eq!(combine([0.1, 0.0, 0.0], 0.5, a)[0], 0.1 + 0.125);
    }

    /// A plane through voxel `at` in the dexel's terms (reference column (x, y), first voxel `lo`).
    fn plane_through(nx: i16, ny: i16, nz: i32, e: i32) -> DexelPlane {
        DexelPlane { id: 0, nx, ny, nz, e }
    }

    /// The continuous truth: the line `num/den + t·dir` (lattice units) meets
    /// g(p) = nx·(p_x − x) + ny·(p_y − y) + (nz/2¹⁶)·(p_z − lo) + e (p in voxels) at t.
    fn f64_hit(inc: &Incident, pl: &DexelPlane, col: [f64; 2], lo: f64) -> Option<[f64; 3]> {
        let q = Q as f64;
        let p = inc.num.map(|c| c as f64 / inc.den as f64 / q);
        let d = inc.dir.map(|c| c as f64 / q);
        let n = [pl.nx as f64, pl.ny as f64, pl.nz as f64 / 65536.0];
        let g = n[0] * (p[0] - col[0]) + n[1] * (p[1] - col[1]) + n[2] * (p[2] - lo) + pl.e as f64;
        let slope = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
        (slope != 0.0).then(|| {
            let t = -g / slope;
            [0, 1, 2].map(|k| (p[k] + t * d[k]) * q)
        })
    }

    proptest::proptest! {
        /// The three hit points against continuous geometry: the exact one is the f64
        /// intersection of the incident line with the dexel's plane, rounded to the lattice,
        /// wherever that lies in the voxel; the edge one lies on the incident line (to within
        /// the lattice's rounding) on the face it entered by; the centre one is the centre; every
        /// one is in the hit voxel.
        #[test]
        fn hit_points_agree_with_continuous_geometry(
            at in proptest::array::uniform3(1u16..60),
            off in proptest::array::uniform3(-7i32..8),
            dir in proptest::array::uniform3(-600i32..600),
            back in 1i64..400,
            normal in (-16384i16..=16384, -16384i16..=16384, -(1i32 << 30)..=(1 << 30)),
            lo_below in 0u16..3,
        ) {
            proptest::prop_assume!(dir != [0, 0, 0]);
            let q = Q as i64;
            // The incident line passes through a point of the voxel; the cell knows a point
            // `back`/den of the way back along it (a rational point, den = 7).
            let inside = [0, 1, 2].map(|k| at[k] as i64 * q + off[k] as i64);
            let den = 7;
            let num = [0, 1, 2].map(|k| inside[k] * den - back * dir[k] as i64);
            // The faces a walk entering here would have crossed: the axes whose coordinate the
            // line changes; the exact rule ignores them.
            let entry = (0..3).fold(0u8, |m, k| m | ((dir[k] != 0) as u8) << k);
            let inc = Incident { num, den, dir, entry };
            // A plane through `inside` (e chosen so that g(inside) is about 0).
            let lo = at[2].saturating_sub(lo_below);
            let (nx, ny, nz) = normal;
            let p = inside.map(|c| c as f64 / q as f64);
            let g0 = nx as f64 * (p[0] - at[0] as f64) + ny as f64 * (p[1] - at[1] as f64) + nz as f64 / 65536.0 * (p[2] - lo as f64);
            let plane = plane_through(nx, ny, nz, (-g0).round() as i32);
            let centre = at.map(|c| c as i32 * Q);
            let in_voxel = |h: [i32; 3]| (0..3).all(|k| (centre[k] - Q / 2..=centre[k] + Q / 2 - 1).contains(&h[k]));
            proptest::prop_assert_eq!(hit_point(at, &inc, &plane, lo, HitPoint::Centre), centre);
            let exact = hit_point(at, &inc, &plane, lo, HitPoint::Exact);
            proptest::prop_assert!(in_voxel(exact));
            if let Some(truth) = f64_hit(&inc, &plane, [at[0] as f64, at[1] as f64], lo as f64) {
                let inside_voxel = (0..3).all(|k| truth[k] >= (centre[k] - Q / 2) as f64 && truth[k] <= (centre[k] + Q / 2 - 1) as f64);
                if inside_voxel {
                    for k in 0..3 {
                        proptest::prop_assert!((exact[k] as f64 - truth[k]).abs() <= 0.5 + 1e-6, "axis {} {:?} vs {:?}", k, exact, truth);
                    }
                }
            }
            let edge = hit_point(at, &inc, &plane, lo, HitPoint::Edge);
            proptest::prop_assert!(in_voxel(edge));
            // On the line: the distance from the edge point to the f64 line is at most the
            // lattice rounding (√3/2) — unless the clamp moved it (the entry face beyond the
            // voxel's high side is the neighbour's first lattice point).
            let pt = num.map(|c| c as f64 / den as f64);
            let d = dir.map(f64::from);
            let w = [0, 1, 2].map(|k| edge[k] as f64 - pt[k]);
            let dd = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let c = [w[1] * d[2] - w[2] * d[1], w[2] * d[0] - w[0] * d[2], w[0] * d[1] - w[1] * d[0]];
            let dist = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / dd;
            proptest::prop_assert!(dist <= 1.8, "edge {:?} is {} from the line", edge, dist);
            // On the face it entered by, the last one crossed: the axis of the largest t.
            let last = (0..3).filter(|&k| dir[k] != 0).max_by(|&i, &j| {
                let t = |k: usize| ((centre[k] - dir[k].signum() * Q / 2) as f64 - pt[k]) / d[k];
                t(i).partial_cmp(&t(j)).unwrap()
            });
            if let Some(k) = last {
                let face = if dir[k] > 0 { centre[k] - Q / 2 } else { centre[k] + Q / 2 - 1 };
                proptest::prop_assert_eq!(edge[k], face, "axis {}", k);
            }
            // Every walk of the reflected ray starts in the hit voxel, the emitting cell's.
            for h in [centre, edge, exact] {
                for conn in Connectivity::ALL {
                    let start = walk_start(h, dir, at, conn);
                    let line = Line::new(start, [0, 1, 2].map(|k| start[k] + dir[k]), conn).unwrap();
                    proptest::prop_assert_eq!(line.voxel(), at.map(i32::from), "{:?} from {:?}", conn, h);
                    if conn != Connectivity::Six {
                        // The same line: start − h is parallel to dir (up to the rounding and
                        // the clamp, at most a voxel).
                        proptest::prop_assert!((0..3).all(|k| (start[k] - h[k]).abs() <= Q || dir[k] == 0));
                    }
                }
            }
            proptest::prop_assert_eq!(walk_start(centre, dir, at, Connectivity::TwentySix), centre);
        }
    }

    /// The primary ray of a column meets a horizontal floor at its exact depth, enters the voxel
    /// by its −z face, and reflects from the centre under the centre rule.
    #[test]
    fn the_primary_rays_hit_points() {
        // A floor at z = 9.25 voxels facing −z: g = −2¹⁴·(p_z − 9.25) with lo = 9.
        let floor = plane_through(0, 0, -(16384 << 16), 4096);
        let inc = Incident::primary(5, 6);
        let at = [5, 6, 9];
        assert_eq!(hit_point(at, &inc, &floor, 9, HitPoint::Centre), [5 * Q, 6 * Q, 9 * Q]);
        assert_eq!(hit_point(at, &inc, &floor, 9, HitPoint::Edge), [5 * Q, 6 * Q, 9 * Q - Q / 2]);
        assert_eq!(hit_point(at, &inc, &floor, 9, HitPoint::Exact), [5 * Q, 6 * Q, 9 * Q + Q / 4]);
        // The same floor met in the voxel above: the true point (9.25) is clamped into voxel 8.
        assert_eq!(hit_point([5, 6, 8], &inc, &floor, 9, HitPoint::Exact), [5 * Q, 6 * Q, 8 * Q + Q / 2 - 1]);
        // A wall parallel to the ray: no crossing, the centre.
        let wall = plane_through(16384, 0, 0, 0);
        assert_eq!(hit_point(at, &inc, &wall, 9, HitPoint::Exact), [5 * Q, 6 * Q, 9 * Q]);
        for h in HitPoint::ALL {
            assert_eq!(HitPoint::from_code(h.code()), Some(h));
        }
        assert_eq!(HitPoint::from_code(3), None);
    }
}

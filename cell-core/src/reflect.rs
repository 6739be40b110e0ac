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
use crate::ray::{cell_step, Connectivity, Line, LineError, MAX_SPAN, Q};
use crate::shade::{dot, normalise};
use crate::units::FacetId;

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
    /// A ray leaving the centre of voxel `from` along lattice direction `dir`, answering to
    /// `parent`'s slot `slot`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        from: [u16; 3],
        dir: [i32; 3],
        conn: Connectivity,
        parent: [u16; 2],
        slot: u16,
        facet: FacetId,
        level: u8,
        weight: f32,
    ) -> Result<Self, LineError> {
        let a = from.map(|c| c as i32 * Q);
        let b = [a[0] + dir[0], a[1] + dir[1], a[2] + dir[2]];
        Ok(ReflectRay { line: Line::new(a, b, conn)?, dir, parent, slot, facet, level, weight, entry: 0, fresh: true })
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
}

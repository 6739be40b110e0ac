//! §5.5.5 — the lit-ray ratio: a pixel's visibility of a light as the share of its rays that
//! arrive.
//!
//! **Invariant: a column's weight for a light is `⌊255·r/R + ½⌋` with R the number of lattice
//! rays of its target voxel ([`TargetVoxel`]: the voxel of its target ray, [`crate::receiver`],
//! at that ray's layer and face) that lie on the visible surface's outer side there, and r the
//! number of those that arrive at the voxel; both exact integers, r counted beam by beam as the
//! cell processes them ([`TargetVoxel::count`]: every ray once, whatever pieces its beam is cut
//! into); 0 in a contact shadow.**
//!
//! # Why
//!
//! A pixel is reached by several discrete rays of the same light (§5.5.5: through two voxels
//! pass several Bresenham lines), and an occluder may stop some of them: "contradictory
//! information". The thesis weighs three answers: the one exact ray from the source's centre to
//! the pixel's (rc2's default: the target ray, [`crate::receiver`]), "lit if more than 50 % of
//! its surface is lit", and "the ratio of the lit rays received to all the rays received,
//! lit if it exceeds 0.5"; it keeps "lit if any ray arrives" for simplicity. Beams carry exact
//! ray counts, so the ratio costs the cell no approximation: [`Visibility::Ratio`] shades with
//! it as a weight of the light (a shadow edge falls off over the pixel instead of jumping),
//! [`Visibility::Majority`] is the thesis's binary "> 0.5".
//!
//! # Definition
//!
//! Let t be the column's target ray for the light: its face, layer k and voxel q (z_v − 1,
//! z_v or z_v + 1 of the column). The candidates are the lattice rays of that face whose voxel
//! at layer k is q (`rays_in_voxel` per transverse axis: a rectangle) and that lie on the
//! visible plane's outer side at layer k or k − 1 (the receiver's rule 1, the same rays the
//! target is chosen from). R counts them; r counts those a beam brings to q at layer k whose
//! verdict there is not *absent* (a ray stopped in the segment that ends in q still arrives, as
//! the target ray does). Without a target there is no weight (0: the pixel is unlit, as under
//! the target rule). With f fraction bits a voxel at layer k holds about `(D·2^f/k)²` lattice
//! rays, so at f = 0 far from the light a ratio has few values; `--frac-bits` refines it.
//!
//! # Counting once
//!
//! The cell may take a beam in several steps (it peels pieces of uniform verdict, the rest
//! staying in its FIFO slot, [`crate::light`]). A step counts the arriving candidates of the
//! whole rectangle it was given and takes back those of the rectangle it keeps: over the
//! beam's steps each ray counts once. Counting reads the visit's lines ([`Rule::line`]) and
//! the two outer tests' intervals on them: one line per lattice column of the beam.
//!
//! # Bit budget
//!
//! A voxel holds at most (2N + 1)² rays (N = D·2^f < 2³¹): R < 2⁶⁴, a `u64`; the weight's
//! `255·r` is formed in `u128`.
//!
//! # Example
//!
//! ```
//! use cell_core::visibility::Visibility;
//! // 3 of 4 candidate rays arrived: a weight of 191/255 under the ratio, lit by the majority.
//! assert_eq!(Visibility::Ratio.weight(3, 4, false), 191);
//! assert_eq!(Visibility::Majority.weight(3, 4, false), 255);
//! assert_eq!(Visibility::Majority.weight(2, 4, false), 0, "exactly half is not more than half");
//! // A contact shadow (a triangle within a voxel of the pixel) darkens it whatever arrives.
//! assert_eq!(Visibility::Ratio.weight(4, 4, true), 0);
//! assert_eq!(Visibility::from_name("ratio"), Some(Visibility::Ratio));
//! ```

use crate::beam::{Beam, Direction, FarDistance, FracBits, Source};
use crate::lit::{spans, Along, RayPlane, Rule, Segments, Test};
use crate::receiver::Target;
use crate::visible::VisibleSurface;

/// How a cell decides its pixel's visibility of one light (§5.5.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Visibility {
    /// Lit iff its target ray arrives and no contact shadow ([`crate::receiver`]).
    #[default]
    Target,
    /// The share of its target voxel's candidate rays that arrive, as the light's weight.
    Ratio,
    /// Lit iff more than half of them arrive (the thesis's "> 0.5").
    Majority,
}

impl Visibility {
    /// Every rule, in the order options list them.
    pub const ALL: [Visibility; 3] = [Visibility::Target, Visibility::Ratio, Visibility::Majority];

    /// The name options and outputs use.
    pub const fn name(self) -> &'static str {
        match self {
            Visibility::Target => "target",
            Visibility::Ratio => "ratio",
            Visibility::Majority => "majority",
        }
    }

    /// The rule named `name`.
    pub fn from_name(name: &str) -> Option<Visibility> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }

    /// Whether the cells count their target voxel's rays ([`TargetVoxel`]).
    pub const fn counts_rays(self) -> bool {
        !matches!(self, Visibility::Target)
    }

    /// The weight (0 ..= 255) of a light whose target voxel received `arrived` of its `total`
    /// candidate rays; 0 in a contact shadow or without candidates. Under
    /// [`Visibility::Target`] the target ray decides, not the counts: use the lit mask.
    pub fn weight(self, arrived: u64, total: u64, contact_shadow: bool) -> u8 {
        if contact_shadow || total == 0 {
            return 0;
        }
        let arrived = arrived.min(total);
        match self {
            Visibility::Majority => {
                if 2 * arrived as u128 > total as u128 {
                    255
                } else {
                    0
                }
            }
            _ => ((510 * arrived as u128 + total as u128) / (2 * total as u128)) as u8,
        }
    }
}

/// A column's target voxel for one light: where its candidate rays are counted (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TargetVoxel {
    /// The face whose rays reach it.
    pub dir: Direction,
    /// Its layer.
    pub layer: u32,
    /// Its z in the column.
    pub z: i64,
    /// The lattice rectangle of the face's rays whose voxel at the layer it is (inclusive).
    pub rays: ((i64, i64), (i64, i64)),
    /// The visible plane's σ at the layer and the layer before: a candidate holds either.
    outer: [Test; 2],
    /// R: the candidates.
    pub total: u64,
    /// A triangle of the column or a neighbour crosses the contact segment
    /// ([`Target::in_contact_shadow`]): the weight is 0.
    pub contact_shadow: bool,
}

impl TargetVoxel {
    /// The target voxel of target ray `t` of column (x, y) (visible surface `vis`, light
    /// `source`); `contact_shadow` as the target's own test found it. `None` when `t` is not a
    /// target of this surface (no candidate in its voxel).
    pub fn new<F: FracBits>(
        t: &Target,
        (x, y): (i32, i32),
        vis: &VisibleSurface,
        source: &Source,
        far: FarDistance<F>,
        contact_shadow: bool,
    ) -> Option<TargetVoxel> {
        let plane = RayPlane::new(&vis.plane, [x as i64, y as i64, vis.z_v as i64], source, t.dir, far);
        let k = t.layer as i64;
        let outer = [Test { plane, t: k }, Test { plane, t: k - 1 }];
        let rays = crate::receiver::voxel_rays([x as i64, y as i64, t.z], t.dir, k, source, far)?;
        let mut v = TargetVoxel { dir: t.dir, layer: t.layer, z: t.z, rays, outer, total: 0, contact_shadow };
        let ((a0, a1), (b0, b1)) = rays;
        v.total = (a0..=a1).map(|a| v.candidates(a, b0, b1)).sum();
        (v.total > 0).then_some(v)
    }

    /// Whether `beam` (at this voxel's depth of the column) is one of its face and layer.
    pub fn receives<F: FracBits>(&self, beam: &Beam<F>) -> bool {
        beam.direction() == self.dir && beam.layer().0 == self.layer
    }

    /// The candidates on line `a` (the u offset) with `lo ≤ b ≤ hi`: the union of the two outer
    /// tests' intervals there.
    fn candidates(&self, a: i64, lo: i64, hi: i64) -> u64 {
        let len = |(f, l): (i64, i64)| if f > l { 0 } else { (l - f + 1) as u64 };
        let (i0, i1) = (self.outer[0].interval(Along::V, a, lo, hi), self.outer[1].interval(Along::V, a, lo, hi));
        len(i0) + len(i1) - len((i0.0.max(i1.0), i0.1.min(i1.1)))
    }

    /// The candidates of rectangle `a × b` (lattice offsets, inclusive: a beam at this voxel)
    /// whose verdict under `rule` is not absent: what the beam brings (module doc, "Counting
    /// once"). `C`: the segment capacity `rule`'s lines need.
    pub fn count<R: Rule, const C: usize>(&self, rule: &R, a: (i64, i64), b: (i64, i64)) -> u64 {
        let (a0, a1) = (a.0.max(self.rays.0 .0), a.1.min(self.rays.0 .1));
        let (b0, b1) = (b.0.max(self.rays.1 .0), b.1.min(self.rays.1 .1));
        if b0 > b1 {
            return 0;
        }
        let mut seg = Segments::<C>::new();
        let mut n = 0;
        for line in a0..=a1 {
            rule.line(Along::V, line, b0, b1, &mut seg);
            for (s, e, bits) in spans(&seg, b1) {
                if rule.verdict(bits, false).out.present() {
                    n += self.candidates(line, s, e);
                }
            }
        }
        n
    }
}

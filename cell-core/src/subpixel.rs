//! §1.2.5.2 — s × s samples per pixel: the visible surface at sub-pixel points of the cell's
//! column, each shaded, and the pixel their mean (anti-aliasing by supersampling).
//!
//! **Invariant: sample (i, j) of cell (x, y) is the point `(x + m_i/(2s), y + m_j/(2s))` with
//! `m_k = 2k + 1 − s` (a regular s × s grid over the pixel's square, its centre the column's
//! centre line when s is odd); its record is the facet whose own polygon that line meets, at
//! the exact depth z\* = num/den, chosen among the packets by [`crate::visible::depth_test`]'s
//! rule; the pixel is the mean of the samples' linear colours, each clamped to [0, 1] (a sample
//! that meets nothing is black), gamma-encoded once.**
//!
//! # The hit test off the centre line
//!
//! A row packet holds the facet's plane `E = P + c·z` and edges `g_i + c_i·z` at the column's
//! centre ([`crate::facet::RowPacket`]), with the plane's and the edges' x coefficients (`a`,
//! `a_i`) for the step east. Their y coefficients (`b`, `b_i`) stay in the pipeline: a row
//! never needs them ([`crate::facet`]). A sampling cell needs both, so each row packet carries
//! them too ([`RowSlopes`]: 8 bytes and 4 per edge). At the sample, with q = 2s,
//!
//! ```text
//! q·E = q·P + a·m_x + b·m_y + q·c·z     q·G_i = q·(g_i − push_i) + a_i·m_x + b_i·m_y + q·c_i·z
//! ```
//!
//! so the line meets the plane at z\* = −(q·P + a·m_x + b·m_y)/(q·c), kept as num/den with
//! den = q·|c| > 0, and the point lies on the facet iff every edge holds at it:
//! `(q·(g_i − push_i) + a_i·m_x + b_i·m_y)·den + q·c_i·num ≥ 0` (`> 0` for a strict edge,
//! [`crate::facet::EdgeOff`]), the test of [`crate::visible::hit`] at another point. With
//! s = 1 the one sample is the centre line, and the answer is `hit`'s (z\* the same fraction).
//!
//! # Bit budget
//!
//! [`crate::voxelize`]'s bounds with M = q_l·n (q_l ≤ 16 lattice steps per voxel, n ≤
//! [`crate::units::MAX_N`]): `|P| < 2⁶³`, `|a|, |b|, |c| ≤ 2q_l·M² ≤ 2⁴⁵`, `|g_i| < 2⁴³`,
//! `|a_i|, |b_i|, |c_i| ≤ q_l·M ≤ 2²⁴`. With s ≤ [`MAX_SAMPLES`] (q ≤ 8, |m| ≤ 7):
//! `q·P + a·m_x + b·m_y` below 2⁶⁷, den ≤ 2⁴⁸, each edge value below 2⁴⁶·2⁴⁸ + 2³·2²⁴·2⁶⁷ <
//! 2⁹⁵: `i128`, exact. A kept hit has |z\*| < n, so `|num| < n·q·|c| ≤ 2q·M³`: below 2⁵⁸ for
//! n ≤ [`MAX_SAMPLED_N`] (M ≤ 2¹⁸), and the record's `i64` holds it. Beyond that grid (or from
//! a forged packet) a numerator that does not fit is reported, not kept
//! ([`SampleHit::Overflow`]). Records compare by [`crate::visible`]'s cross products, below
//! 2¹¹⁵.
//!
//! # The samples' lights
//!
//! Lighting does not change: each cell still lights its one visible surface, the centre line's
//! ([`crate::receiver`]). A sample on that facet takes the cell's lights. A sample on another
//! facet (the pixel straddles a silhouette or a crease) takes those of the neighbour that shows
//! that facet nearest the sample: after lighting, each cell tells its 8 neighbours what its
//! centre shows and which lights reached it (its lit mask, or its lights' weights under the
//! lit-ray ratio: [`Shown`], one message per link); a sample looks
//! for its own facet, then for a facet of its normal code (the same plane cut into several
//! facets), then takes the nearest cell's (a facet no centre line meets: a thin wire).
//! Distances are squared, in units of 1/(2s) voxel; ties go to the cell itself, then to the
//! neighbours in [`NEIGHBOURS`] order. That is [`SampleLights::Nearest`]. By default
//! ([`SampleLights::Bilinear`]) a sample weighs the lit states of the four cells whose centres
//! surround it, bilinearly by its position among them, over those that show its facet or a
//! facet of its normal code: a shadow edge that the centres place between two pixels then
//! falls off across them, as the supersampled reference's does, instead of staying a step.
//!
//! # Example
//!
//! ```
//! use cell_core::subpixel::{offsets, Sample};
//!
//! // 2 × 2 samples: a quarter voxel from the centre along each axis.
//! assert_eq!(offsets(2).collect::<Vec<_>>(), [-1, 1]);
//! let s = Sample::new(0, 1, 2).unwrap();
//! assert_eq!((s.mx, s.my), (-1, 1));
//! assert_eq!(s.point(10, 20), [9.75, 20.25]);
//! // 3 × 3: the middle sample is the centre line.
//! assert_eq!(Sample::new(1, 1, 3).unwrap().point(10, 20), [10.0, 20.0]);
//! ```

use heapless::Vec;

use crate::facet::{PipelinePacket, RowPacket, MAX_EDGES};
use crate::light::SourceMask;
use crate::normal::NormalCode;
use crate::shade::{facing_mask, shade_linear_toward, shading_normal_toward, Material, PointLight, ShadeParams};
use crate::units::FacetId;
use crate::visible::VisibleSurface;

/// Most samples per pixel side: s ≤ 4, 16 samples.
pub const MAX_SAMPLES: u32 = 4;

/// Largest grid the samples' bit budget allows (see the module doc).
pub const MAX_SAMPLED_N: u32 = 1 << 14;

/// The 8 neighbours a cell tells what it shows, as (dx, dy).
pub const NEIGHBOURS: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// The offsets `m_k = 2k + 1 − s`, k = 0 .. s, of the samples along one axis (units of 1/(2s)
/// voxel from the column's centre).
pub fn offsets(s: u32) -> impl Iterator<Item = i32> {
    (0..s as i32).map(move |k| 2 * k + 1 - s as i32)
}

/// One sample of a pixel: the point `(x + mx/(2s), y + my/(2s))` of column (x, y).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sample {
    /// x offset, in units of 1/(2s) voxel.
    pub mx: i32,
    /// y offset, in units of 1/(2s) voxel.
    pub my: i32,
    /// Samples per side.
    pub s: u32,
}

impl Sample {
    /// Sample (i, j) of an s × s grid; `None` unless `i, j < s ≤ MAX_SAMPLES`.
    pub fn new(i: u32, j: u32, s: u32) -> Option<Sample> {
        let ok = (1..=MAX_SAMPLES).contains(&s) && i < s && j < s;
        ok.then(|| Sample { mx: 2 * i as i32 + 1 - s as i32, my: 2 * j as i32 + 1 - s as i32, s })
    }

    /// The s × s samples of a pixel, row by row (j, then i); none unless `1 ≤ s ≤ MAX_SAMPLES`.
    pub fn all(s: u32) -> impl Iterator<Item = Sample> {
        let s = if (1..=MAX_SAMPLES).contains(&s) { s } else { 0 };
        (0..s * s).filter_map(move |k| Sample::new(k % s, k / s, s))
    }

    /// The sample's point in grid units (column (x, y)'s centre line at (x, y)).
    pub fn point(&self, x: u32, y: u32) -> [f32; 2] {
        let q = 2.0 * self.s as f32;
        [x as f32 + self.mx as f32 / q, y as f32 + self.my as f32 / q]
    }

    /// The squared distance from the sample to the centre of the cell (dx, dy) away, in units
    /// of 1/(2s) voxel.
    pub fn distance2_to(&self, (dx, dy): (i32, i32)) -> i64 {
        let q = 2 * self.s as i64;
        let (ex, ey) = (dx as i64 * q - self.mx as i64, dy as i64 * q - self.my as i64);
        ex * ex + ey * ey
    }
}

/// The columns a sampling grid feeds a packet to: its box ([`crate::facet::FacetBox`], the
/// columns whose voxels the facet can touch, judged at their centres) grown by one column and
/// one row on each side within the grid (`0 .. n`), so that every column whose square the facet
/// overlaps meets it; the cells outside the packet's own box test their samples only (they
/// voxelize nothing: [`crate::voxelize`] clips to the box).
pub fn sampled_box(b: crate::facet::FacetBox, n: u32) -> crate::facet::FacetBox {
    let last = (n.max(1) - 1) as crate::units::Coord;
    crate::facet::FacetBox {
        x_min: b.x_min.saturating_sub(1),
        x_max: b.x_max.saturating_add(1).min(last),
        y_min: b.y_min.saturating_sub(1),
        y_max: b.y_max.saturating_add(1).min(last),
        ..b
    }
}

/// The y coefficients of a facet's plane and edges, which a sampling cell's row packet carries
/// besides the thesis's ([`crate::facet::RowPacket`] drops them: a row never needs them).
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct RowSlopes {
    /// Plane y coefficient `b`.
    pub b: i64,
    /// Each contour edge's `b_i`, in the packet's edge order.
    pub edges: Vec<i32, MAX_EDGES>,
}

impl RowSlopes {
    /// The slopes of a pipeline packet (constant along the pipeline).
    pub fn of(p: &PipelinePacket) -> RowSlopes {
        RowSlopes { b: p.b, edges: p.edges.iter().map(|e| e.b).collect() }
    }

    /// What they add to a row packet on a link: 8 bytes and 4 per edge.
    pub fn bytes(&self) -> usize {
        8 + 4 * self.edges.len()
    }
}

/// What the hit test of a sample found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleHit {
    /// The sample's line meets the facet at z\* = num/den (den > 0) in the column.
    Hit(i64, i64),
    /// It does not (or the facet contains the view direction).
    Miss,
    /// It meets it, but the numerator does not fit `i64` (beyond the bit budget: a grid larger
    /// than [`MAX_SAMPLED_N`] or a forged packet): a counted event, the hit not kept.
    Overflow,
}

/// The exact depth at which sample `at`'s line meets the packet's facet (see the module doc),
/// if it does within `[−½, depth − ½)`.
pub fn hit_at(p: &RowPacket, slopes: &RowSlopes, at: Sample, depth: u32) -> SampleHit {
    if p.c == 0 || slopes.edges.len() != p.edges.len() {
        return SampleHit::Miss;
    }
    let q = 2 * at.s as i128;
    let (mx, my) = (at.mx as i128, at.my as i128);
    let value = q * p.column_plane().p as i128 + p.a as i128 * mx + slopes.b as i128 * my;
    let (n, d) = if p.c > 0 { (-value, q * p.c as i128) } else { (value, -q * p.c as i128) };
    if 2 * n < -d || 2 * n >= (2 * depth as i128 - 1) * d {
        return SampleHit::Miss;
    }
    let inside = p.edges.iter().zip(&slopes.edges).all(|(e, &b)| {
        let at_point = q * (e.g as i128 - e.off().push() as i128) + e.a as i128 * mx + b as i128 * my;
        let v = at_point * d + q * e.c as i128 * n;
        if e.off().strict() {
            v > 0
        } else {
            v >= 0
        }
    });
    if !inside {
        return SampleHit::Miss;
    }
    match (i64::try_from(n), i64::try_from(d)) {
        (Ok(n), Ok(d)) => SampleHit::Hit(n, d),
        _ => SampleHit::Overflow,
    }
}

/// A sample's hit whose depth does not fit the record ([`SampleHit::Overflow`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DepthOverflow;

/// The record of the packet's facet at sample `at`, if its line meets it ([`hit_at`]); its
/// plane as [`crate::visible::surface_of`] keeps it (oriented toward the viewer, the offset at
/// the centre of the column's voxel `z_v = ⌊z*⌋`).
pub fn surface_at(
    p: &RowPacket,
    slopes: &RowSlopes,
    at: Sample,
    depth: u32,
) -> Result<Option<VisibleSurface>, DepthOverflow> {
    let (num, den) = match hit_at(p, slopes, at, depth) {
        SampleHit::Hit(n, d) => (n, d),
        SampleHit::Miss => return Ok(None),
        SampleHit::Overflow => return Err(DepthOverflow),
    };
    Ok(Some(crate::visible::record_at(p, num, den)))
}

/// What a cell tells its neighbours after lighting: the facet its centre line shows, its normal
/// code, and its lights `L`: the lit mask of the lights that reached it (before the facing
/// test), or under the lit-ray ratio each light's weight ([`crate::visibility`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shown<L = SourceMask> {
    /// The facet.
    pub facet: FacetId,
    /// Its normal code.
    pub normal: NormalCode,
    /// Its lights.
    pub reached: L,
}

impl Shown {
    /// Bytes of the message with a lit mask: the facet (4), the normal code (2) and the mask (4);
    /// with weights, 6 and one byte per light.
    pub const BYTES: usize = 10;
    /// Bytes of the facet and normal code.
    pub const HEADER_BYTES: usize = 6;
}

/// The lights that reach sample `at`, showing `surface`, of a cell that shows `own` and whose
/// neighbours (in [`NEIGHBOURS`] order) show `around` (see the module doc).
pub fn sample_reached<L: Copy + Default>(
    own: Option<Shown<L>>,
    around: &[Option<Shown<L>>; 8],
    surface: &VisibleSurface,
    at: Sample,
) -> L {
    let cells = core::iter::once(((0, 0), own)).chain(NEIGHBOURS.iter().copied().zip(around.iter().copied()));
    // Rank: same facet 0, same normal code 1, any other 2; then the distance; first wins ties.
    let mut best: Option<((u8, i64), L)> = None;
    for (d, shown) in cells {
        let Some(s) = shown else { continue };
        let rank = if s.facet == surface.facet {
            0
        } else if s.normal == surface.normal {
            1
        } else {
            2
        };
        let key = (rank, at.distance2_to(d));
        if best.is_none_or(|(k, _)| key < k) {
            best = Some((key, s.reached));
        }
    }
    best.map_or(L::default(), |(_, m)| m)
}

/// The linear colour of sample `at` of column (x, y) showing `surface`, lit by the lights of
/// `reached` that it faces ([`crate::shade::surface_pixel`]'s formula at the sample's point),
/// and those lights.
#[allow(clippy::too_many_arguments)]
pub fn sample_colour(
    (x, y): (u32, u32),
    at: Sample,
    surface: &VisibleSurface,
    reached: SourceMask,
    materials: &[Material],
    lights: &[PointLight],
    params: &ShadeParams,
) -> ([f32; 3], SourceMask) {
    let [px, py] = at.point(x, y);
    let (p, v) = params.eye.shading_point([px, py, surface.depth()]);
    let m = materials.get(surface.material as usize).copied().unwrap_or_default();
    let nrm = shading_normal_toward(surface.normal, params.normal_mode, v);
    let lit = facing_mask(p, nrm, lights, reached);
    (shade_linear_toward(p, nrm, v, &m, lights, lit, params), lit)
}

/// How a sample takes its lights from the cells around it (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum SampleLights {
    /// The lights of the nearest cell that shows the sample's facet (its own cell's, on the
    /// centre's facet): a shadow edge stays where the centres put it.
    Nearest,
    /// The lit states of the four cells whose centres surround the sample, bilinearly weighed
    /// by its position among them, over those that show its facet or a facet of its normal
    /// code (the others' weights shared out; none: [`SampleLights::Nearest`]): a shadow edge
    /// between two lit states falls off across the pixels at its sides.
    #[default]
    Bilinear,
}

/// The lights of sample `at` (showing `surface`, of a cell showing `own` among neighbours
/// `around`) as up to four cells' lights with weights summing to 1 (see [`SampleLights`]).
pub fn sample_lights<L: Copy + Default>(
    own: Option<Shown<L>>,
    around: &[Option<Shown<L>>; 8],
    surface: &VisibleSurface,
    at: Sample,
    how: SampleLights,
) -> Vec<(L, f32), 4> {
    let mut out = Vec::new();
    let nearest = |out: &mut Vec<(L, f32), 4>| {
        let _ = out.push((sample_reached(own, around, surface, at), 1.0));
    };
    if how == SampleLights::Nearest {
        nearest(&mut out);
        return out;
    }
    let cell = |d: (i32, i32)| match d {
        (0, 0) => own,
        d => NEIGHBOURS.iter().position(|&e| e == d).and_then(|k| around[k]),
    };
    // In units of 1/(2s) voxel: the sample at m from its cell's centre, between the centres at
    // c0 = 0 or −1 and c0 + 1 along each axis, at f = m − 2s·c0 from c0.
    let q = 2 * at.s as i32;
    let split = |m: i32| if m < 0 { (-1, m + q) } else { (0, m) };
    let ((x0, fx), (y0, fy)) = (split(at.mx), split(at.my));
    let mut total = 0i32;
    for (dx, wx) in [(x0, q - fx), (x0 + 1, fx)] {
        for (dy, wy) in [(y0, q - fy), (y0 + 1, fy)] {
            let w = wx * wy;
            let Some(c) = cell((dx, dy)).filter(|c| c.facet == surface.facet || c.normal == surface.normal) else {
                continue;
            };
            if w > 0 {
                total += w;
                let _ = out.push((c.reached, w as f32));
            }
        }
    }
    if total == 0 {
        nearest(&mut out);
        return out;
    }
    for (_, w) in out.iter_mut() {
        *w /= total as f32;
    }
    out
}

/// The pixel of s × s samples: the mean of their linear colours (`None`: a sample that meets
/// nothing, black), each clamped to [0, 1], gamma-encoded ([`crate::shade::encode`]).
pub fn mean_pixel(colours: impl IntoIterator<Item = Option<[f32; 3]>>) -> [u8; 3] {
    let (mut sum, mut count) = ([0.0f32; 3], 0u32);
    for c in colours {
        count += 1;
        if let Some(c) = c {
            for k in 0..3 {
                sum[k] += c[k].clamp(0.0, 1.0);
            }
        }
    }
    let count = count.max(1) as f32;
    sum.map(|c| crate::shade::encode(c / count))
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn samples_tile_the_pixel() {
        for s in 1..=MAX_SAMPLES {
            let all: std::vec::Vec<Sample> = Sample::all(s).collect();
            assert_eq!(all.len(), (s * s) as usize);
            // Each sample is the centre of its cell of the s × s grid over [x − ½, x + ½).
            for (k, smp) in all.iter().enumerate() {
                let (i, j) = (k as u32 % s, k as u32 / s);
                let want = |i: u32| -0.5 + (i as f64 + 0.5) / s as f64;
                let p = smp.point(0, 0);
                assert!((p[0] as f64 - want(i)).abs() < 1e-7 && (p[1] as f64 - want(j)).abs() < 1e-7);
            }
        }
        assert_eq!(Sample::all(0).count() + Sample::all(MAX_SAMPLES + 1).count(), 0);
        assert!(Sample::new(2, 0, 2).is_none());
    }

    #[test]
    fn the_nearest_cell_of_the_samples_facet_lends_its_lights() {
        let code = |z: f32| NormalCode::encode([0.0, 0.0, z]);
        let shown = |facet, z, reached| Some(Shown { facet, normal: code(z), reached });
        let surface = |facet, z| VisibleSurface {
            num: 0,
            den: 1,
            facet,
            material: 0,
            normal: code(z),
            plane: crate::plane::DexelPlane::default(),
            z_v: 0,
        };
        // The cell shows facet 1; its east neighbour (index 4) facet 2, its west (3) facet 2 too.
        let mut around = [None; 8];
        around[4] = shown(2, -1.0, 0b10);
        around[3] = shown(2, -1.0, 0b100);
        let own = shown(1, 1.0, 0b1);
        let east = Sample::new(1, 0, 2).unwrap();
        let west = Sample::new(0, 0, 2).unwrap();
        // Its own facet: its own lights; facet 2 east of the centre: the east neighbour's.
        assert_eq!(sample_reached(own, &around, &surface(1, 1.0), east), 0b1);
        assert_eq!(sample_reached(own, &around, &surface(2, -1.0), east), 0b10);
        assert_eq!(sample_reached(own, &around, &surface(2, -1.0), west), 0b100);
        // Facet 3 of facet 2's normal: a coplanar facet's lights; of no one's: the nearest cell's.
        assert_eq!(sample_reached(own, &around, &surface(3, -1.0), east), 0b10);
        assert_eq!(sample_reached(own, &around, &surface(3, 0.5), east), 0b1);
        assert_eq!(sample_reached::<SourceMask>(None, &[None; 8], &surface(3, 0.5), east), 0);
    }

    #[test]
    fn bilinear_lights_weigh_the_four_cells_around_the_sample() {
        let code = |z: f32| NormalCode::encode([0.0, 0.0, z]);
        let shown = |facet, z, reached| Some(Shown { facet, normal: code(z), reached });
        let surface = VisibleSurface {
            num: 0,
            den: 1,
            facet: 1,
            material: 0,
            normal: code(1.0),
            plane: crate::plane::DexelPlane::default(),
            z_v: 0,
        };
        // Sample (1, 0) of 2 × 2, at (+¼, −¼) from the centre: among the centres (0, −1),
        // (1, −1), (0, 0), (1, 0) with weights 3, 1, 9, 3 (sixteenths).
        let at = Sample::new(1, 0, 2).unwrap();
        let mut around = [None; 8];
        let index = |d| NEIGHBOURS.iter().position(|&e| e == d).unwrap();
        around[index((0, -1))] = shown(1, 1.0, 1);
        around[index((1, -1))] = shown(1, 1.0, 0);
        around[index((1, 0))] = shown(2, 1.0, 0); // another facet of the same plane: counts
        let lit = |w: &Vec<(SourceMask, f32), 4>| w.iter().filter(|(m, _)| *m == 1).map(|(_, w)| w).sum::<f32>();
        let w = sample_lights(shown(1, 1.0, 1), &around, &surface, at, SampleLights::Bilinear);
        assert!((lit(&w) - 12.0 / 16.0).abs() < 1e-6, "{w:?}");
        assert!((w.iter().map(|(_, w)| w).sum::<f32>() - 1.0).abs() < 1e-6);
        // A corner showing another plane is left out and the others' weights shared out.
        around[index((1, 0))] = shown(3, -1.0, 0);
        let w = sample_lights(shown(1, 1.0, 1), &around, &surface, at, SampleLights::Bilinear);
        assert!((lit(&w) - 12.0 / 13.0).abs() < 1e-6, "{w:?}");
        // No corner shows its plane: the nearest rule.
        let w = sample_lights::<SourceMask>(None, &[None; 8], &surface, at, SampleLights::Bilinear);
        assert_eq!(&w[..], &[(0, 1.0)]);
        assert_eq!(&sample_lights(shown(1, 1.0, 1), &around, &surface, at, SampleLights::Nearest)[..], &[(1, 1.0)]);
    }

    #[test]
    fn the_mean_is_taken_before_the_gamma() {
        // Half white, half black: 255·0.5^(1/2.2) ≈ 186, not 128.
        assert_eq!(mean_pixel([Some([1.0; 3]), None]), [186; 3]);
        assert_eq!(mean_pixel([Some([3.0; 3]), Some([-1.0; 3])]), [186; 3], "each sample clamped");
        assert_eq!(mean_pixel([Some([0.25; 3])]), [crate::shade::encode(0.25); 3]);
    }
}

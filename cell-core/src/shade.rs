//! §1.1, §5.2 — shading the voxel a cell shows.
//!
//! The view is orthographic along +z and the near end is z = 0: cell (x, y) shows the first
//! occupied voxel of its column (the dexel with the smallest z), the pixel (x, y) of the image
//! (y up). The model is Phong/Blinn with point lights and no distance attenuation:
//!
//! ```text
//! emitter (max Ke > 0):  c = Ke / max(Ke)
//! otherwise:             c = Ka ⊙ Ia + Σ_{s lit the voxel, N·L_s > 0} E_s ⊙ (Kd (N·L_s) + Ks (N·H_s)^Ns)
//! pixel = round(255 · clamp(c, 0, 1)^(1/2.2))
//! ```
//!
//! with L_s the unit vector from the voxel centre to light s, V = (0, 0, −1) toward the viewer,
//! H_s = normalise(L_s + V), and N the unit normal turned toward the viewer.
//!
//! A cell is a small CPU without `libm`. Raw `micromath` is too coarse for 8-bit output (measured:
//! `powf(x, 1/2.2)` is off by up to 11.7 levels, `powf(x, Ns)` by 0.24 absolute, `invsqrt` by
//! 3.4 %), so the cell keeps the cheap operations and removes their error: `micromath::invsqrt`
//! refined by three Newton steps (normalisation), `Ns` rounded to an integer and raised by repeated
//! squaring (specular), and gamma encoding by binary search in a 255-entry threshold table
//! ([`GAMMA_THRESHOLDS`], in flash). The host measures what remains against f64 on every
//! rendered pixel (`render --stats`: `shading_max_err_levels`, `shading_mean_err_levels`).
//!
//! Normals (§5.2): [`NormalMode::Facet`] decodes the dexel's 16-bit octahedral normal (the facet's
//! real normal, §5.2.1); [`NormalMode::Face`] stores no normal and uses the voxel face the view
//! ray crossed (§5.2.2) — for this orthographic view always the −z face.

use micromath::F32Ext;

use crate::dexel::Dexel;
use crate::light::SourceMask;

/// A surface material (values in 0..1, `ns` the specular exponent).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Material {
    /// Ambient reflectance.
    pub ka: [f32; 3],
    /// Diffuse reflectance.
    pub kd: [f32; 3],
    /// Specular reflectance.
    pub ks: [f32; 3],
    /// Specular exponent.
    pub ns: f32,
    /// Emitted colour (light fixtures); shown as is when non-zero.
    pub ke: [f32; 3],
}

/// A point light: position in voxel units and RGB intensity.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PointLight {
    /// Position (voxel centres at integers).
    pub pos: [f32; 3],
    /// RGB intensity.
    pub color: [f32; 3],
}

/// Which normal a cell shades with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum NormalMode {
    /// The stored facet normal (§5.2.1).
    #[default]
    Facet,
    /// The face of the voxel the view ray crossed (§5.2.2); no normal stored.
    Face,
}

/// Scene-wide shading parameters every cell receives once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeParams {
    /// Ambient intensity Ia.
    pub ambient: [f32; 3],
    /// Normal choice.
    pub normal_mode: NormalMode,
    /// Where the eye is: the space a cell shades in.
    pub eye: Eye,
}

/// Where the eye is, and so the space a cell shades in (§1.3: the geometry stage delivers the
/// scene in screen space, where the grid looks along its own +z).
///
/// Screen space keeps planes and straight lines, so voxelization and beams are right there; a
/// perspective transform does not keep angles, so a cell under a [`Eye::Camera`] maps its
/// visible point back to view space and shades there, with the normal and lights the host
/// gives in view space.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Eye {
    /// The grid's own view (the scene fitted into the grid, seen along +z from z = −∞): voxel
    /// units are the shading space, the direction to the eye is [`VIEW`].
    #[default]
    Grid,
    /// A camera: voxel units are screen space, shading is in view space (eye at the origin,
    /// looking along +z, x right, y up; the host's units).
    Camera(CameraView),
}

/// The inverse of the host's screen transform, as a cell needs it: voxel (x, y, z) of an
/// `n`-grid has screen coordinates s = (v + ½)/n in 0 ..= 1 on each axis, and view space is
///
/// * orthographic: `x = (s_x − ½)·width`, `y = (s_y − ½)·width`, `z = near + s_z·(far − near)`;
/// * perspective: `z = near·far / (far − s_z·(far − near))` (s_z = 0 at `near`, 1 at `far`:
///   depth resolution is finest near the eye), `x = (s_x − ½)·width·z`, `y = (s_y − ½)·width·z`
///   with `width = 2·tan(fov/2)`.
///
/// f32 throughout: a shading point, not a voxel address (its relative error, ~1e−7 per
/// operation, is far below the half voxel the point's depth is known to).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CameraView {
    /// Grid side.
    pub n: f32,
    /// Perspective (else orthographic).
    pub perspective: bool,
    /// View width: at unit depth (perspective, 2·tan(fov/2)), or the window's (orthographic).
    pub width: f32,
    /// Depth of the near plane (s_z = 0).
    pub near: f32,
    /// Depth of the far plane (s_z = 1).
    pub far: f32,
}

impl CameraView {
    /// The view-space point of voxel-unit point `g`.
    pub fn point(&self, g: [f32; 3]) -> [f32; 3] {
        let s = g.map(|c| (c + 0.5) / self.n);
        let z = if self.perspective {
            self.near * self.far / (self.far - s[2] * (self.far - self.near))
        } else {
            self.near + s[2] * (self.far - self.near)
        };
        let k = if self.perspective { self.width * z } else { self.width };
        [(s[0] - 0.5) * k, (s[1] - 0.5) * k, z]
    }

    /// The unit direction from view-space point `p` toward the eye.
    pub fn toward_eye(&self, p: [f32; 3]) -> [f32; 3] {
        if self.perspective {
            normalise([-p[0], -p[1], -p[2]])
        } else {
            VIEW
        }
    }
}

impl Eye {
    /// The shading point of voxel-unit point `g` and the unit direction toward the eye there.
    #[inline]
    pub fn shading_point(&self, g: [f32; 3]) -> ([f32; 3], [f32; 3]) {
        match self {
            Eye::Grid => (g, VIEW),
            Eye::Camera(c) => {
                let p = c.point(g);
                (p, c.toward_eye(p))
            }
        }
    }
}

/// `((L + ½)/255)^2.2` for L = 0..=254: a linear intensity c encodes to the number of
/// thresholds ≤ c (exact rounding of `255·c^(1/2.2)`), found by binary search. Generated in f64;
/// the tests check every entry against `powf`.
pub const GAMMA_THRESHOLDS: [f32; 255] = [
    1.1049576e-06,
    1.2388319e-05,
    3.811357e-05,
    7.9902675e-05,
    0.0001388926,
    0.000215978,
    0.00031190403,
    0.00042731327,
    0.00056277297,
    0.0007187925,
    0.00089583505,
    0.0010943264,
    0.0013146605,
    0.0015572053,
    0.0018223056,
    0.0021102862,
    0.0024214543,
    0.0027561022,
    0.0031145078,
    0.0034969365,
    0.003903643,
    0.004334871,
    0.0047908565,
    0.005271824,
    0.005777993,
    0.0063095735,
    0.0068667703,
    0.0074497815,
    0.0080587985,
    0.008694008,
    0.009355592,
    0.010043725,
    0.010758581,
    0.011500327,
    0.012269125,
    0.013065137,
    0.013888518,
    0.01473942,
    0.015617993,
    0.016524382,
    0.01745873,
    0.018421179,
    0.019411864,
    0.020430923,
    0.021478483,
    0.02255468,
    0.023659639,
    0.024793483,
    0.025956338,
    0.027148325,
    0.028369563,
    0.029620167,
    0.030900255,
    0.03220994,
    0.033549335,
    0.034918547,
    0.036317687,
    0.03774686,
    0.039206177,
    0.040695738,
    0.042215645,
    0.043766,
    0.045346905,
    0.046958454,
    0.048600752,
    0.050273888,
    0.05197796,
    0.05371306,
    0.055479284,
    0.057276726,
    0.059105467,
    0.060965605,
    0.062857226,
    0.06478042,
    0.06673527,
    0.06872186,
    0.070740275,
    0.07279061,
    0.07487293,
    0.07698733,
    0.0791339,
    0.08131269,
    0.08352381,
    0.08576732,
    0.08804331,
    0.09035185,
    0.09269302,
    0.0950669,
    0.097473554,
    0.09991307,
    0.102385506,
    0.10489095,
    0.10742947,
    0.11000113,
    0.11260601,
    0.11524419,
    0.11791571,
    0.120620675,
    0.12335914,
    0.12613116,
    0.12893681,
    0.13177617,
    0.1346493,
    0.13755627,
    0.14049713,
    0.14347196,
    0.14648081,
    0.14952376,
    0.15260087,
    0.1557122,
    0.15885782,
    0.16203779,
    0.16525216,
    0.168501,
    0.17178439,
    0.17510235,
    0.17845497,
    0.1818423,
    0.1852644,
    0.18872133,
    0.19221315,
    0.19573992,
    0.1993017,
    0.20289853,
    0.2065305,
    0.21019763,
    0.21389998,
    0.21763764,
    0.22141063,
    0.22521904,
    0.22906289,
    0.23294225,
    0.23685718,
    0.24080771,
    0.24479392,
    0.24881585,
    0.25287357,
    0.2569671,
    0.26109654,
    0.2652619,
    0.26946324,
    0.27370062,
    0.27797407,
    0.2822837,
    0.2866295,
    0.2910115,
    0.29542986,
    0.29988453,
    0.3043756,
    0.30890307,
    0.31346706,
    0.31806758,
    0.32270467,
    0.32737842,
    0.33208883,
    0.33683598,
    0.3416199,
    0.34644064,
    0.35129824,
    0.3561928,
    0.36112428,
    0.36609277,
    0.37109834,
    0.37614098,
    0.3812208,
    0.3863378,
    0.39149204,
    0.39668354,
    0.4019124,
    0.4071786,
    0.41248223,
    0.4178233,
    0.42320192,
    0.42861804,
    0.43407178,
    0.43956316,
    0.44509217,
    0.45065895,
    0.45626345,
    0.46190578,
    0.46758595,
    0.473304,
    0.47906,
    0.48485395,
    0.49068594,
    0.49655598,
    0.5024641,
    0.5084104,
    0.5143948,
    0.52041745,
    0.5264784,
    0.53257763,
    0.5387152,
    0.5448911,
    0.5511055,
    0.5573583,
    0.56364965,
    0.5699795,
    0.5763479,
    0.58275497,
    0.5892007,
    0.59568506,
    0.6022082,
    0.6087701,
    0.6153708,
    0.62201035,
    0.6286888,
    0.6354062,
    0.6421625,
    0.6489578,
    0.6557922,
    0.6626656,
    0.66957814,
    0.6765298,
    0.6835207,
    0.69055074,
    0.6976201,
    0.7047287,
    0.7118767,
    0.719064,
    0.72629076,
    0.7335569,
    0.74086255,
    0.7482077,
    0.75559235,
    0.76301664,
    0.7704805,
    0.777984,
    0.7855272,
    0.7931102,
    0.80073285,
    0.8083953,
    0.8160976,
    0.8238398,
    0.8316218,
    0.83944374,
    0.8473057,
    0.8552076,
    0.8631495,
    0.87113154,
    0.87915367,
    0.88721585,
    0.89531827,
    0.9034608,
    0.9116436,
    0.9198667,
    0.92813003,
    0.93643373,
    0.9447778,
    0.9531622,
    0.9615871,
    0.97005236,
    0.9785582,
    0.9871045,
    0.99569136,
];

/// Direction toward the viewer.
pub const VIEW: [f32; 3] = [0.0, 0.0, -1.0];

pub(crate) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// 1/√x: micromath's estimate (≤ 3.4 % off) refined by three Newton steps (≤ 1e-6 relative:
/// 3.4e-2 → 1.7e-3 → 4.5e-6 → f32 round-off).
pub fn inv_sqrt(x: f32) -> f32 {
    let mut r = x.invsqrt();
    for _ in 0..3 {
        r *= 1.5 - 0.5 * x * r * r;
    }
    r
}

/// `x^k` by repeated squaring.
pub fn powi(mut x: f32, mut k: u32) -> f32 {
    let mut acc = 1.0f32;
    while k > 0 {
        if k & 1 == 1 {
            acc *= x;
        }
        x *= x;
        k >>= 1;
    }
    acc
}

/// Normalise (a zero vector stays zero).
pub(crate) fn normalise(v: [f32; 3]) -> [f32; 3] {
    let l2 = dot(v, v);
    if l2 <= 0.0 {
        return [0.0; 3];
    }
    let r = inv_sqrt(l2);
    [v[0] * r, v[1] * r, v[2] * r]
}

/// The unit normal a cell shades `d` with, turned toward the viewer.
pub fn shading_normal(d: &Dexel, mode: NormalMode) -> [f32; 3] {
    shading_normal_of(d.normal, mode)
}

/// [`shading_normal`] of a normal code.
pub fn shading_normal_of(code: crate::normal::NormalCode, mode: NormalMode) -> [f32; 3] {
    shading_normal_toward(code, mode, VIEW)
}

/// The unit normal of a normal code turned toward `v` (the unit direction to the eye); the
/// voxel face the view ray crossed faces `v` itself.
pub fn shading_normal_toward(code: crate::normal::NormalCode, mode: NormalMode, v: [f32; 3]) -> [f32; 3] {
    match mode {
        NormalMode::Face => v,
        NormalMode::Facet => {
            let n = normalise(code.decode());
            if dot(n, v) < 0.0 {
                [-n[0], -n[1], -n[2]]
            } else {
                n
            }
        }
    }
}

/// Encode a linear intensity as an 8-bit gamma-2.2 level: `round(255 · clamp(c)^(1/2.2))`.
pub fn encode(c: f32) -> u8 {
    GAMMA_THRESHOLDS.partition_point(|&t| t <= c) as u8
}

/// Shade a point `p` (voxel units) with unit normal `n` facing the viewer, lit by the sources in
/// `lit` (bit s = `lights[s]`).
pub fn shade(
    p: [f32; 3],
    n: [f32; 3],
    m: &Material,
    lights: &[PointLight],
    lit: SourceMask,
    params: &ShadeParams,
) -> [u8; 3] {
    shade_linear_toward(p, n, VIEW, m, lights, lit, params).map(encode)
}

/// The linear (unclamped, not encoded) colour of [`shade`] seen from direction `v` (unit vector
/// from the point toward the eye, [`VIEW`] for the camera; the reversed direction of a
/// reflected ray for a point it hits, §1.1), `n` the unit normal facing `v`.
pub fn shade_linear_toward(
    p: [f32; 3],
    n: [f32; 3],
    v: [f32; 3],
    m: &Material,
    lights: &[PointLight],
    lit: SourceMask,
    params: &ShadeParams,
) -> [f32; 3] {
    let kmax = m.ke[0].max(m.ke[1]).max(m.ke[2]);
    let mut c: [f32; 3];
    if kmax > 0.0 {
        c = m.ke.map(|k| k / kmax);
    } else {
        c = core::array::from_fn(|i| m.ka[i] * params.ambient[i]);
        for (s, l) in lights.iter().enumerate().take(32) {
            if lit >> s & 1 == 0 {
                continue;
            }
            let ld = normalise([l.pos[0] - p[0], l.pos[1] - p[1], l.pos[2] - p[2]]);
            let ndl = dot(n, ld);
            if ndl <= 0.0 {
                continue;
            }
            let h = normalise([ld[0] + v[0], ld[1] + v[1], ld[2] + v[2]]);
            let nh = dot(n, h).max(0.0);
            let spec =
                if nh > 0.0 && m.ks.iter().any(|&k| k > 0.0) { powi(nh, (m.ns.max(0.0) + 0.5) as u32) } else { 0.0 };
            for (i, ci) in c.iter_mut().enumerate() {
                *ci += l.color[i] * (m.kd[i] * ndl + m.ks[i] * spec);
            }
        }
    }
    c
}

/// The lights of `reached` (bit s: a beam or ray of light s reached the voxel) that the surface
/// at `p` with normal `nrm` faces (N·(L − p) > 0).
pub fn facing_mask(p: [f32; 3], nrm: [f32; 3], lights: &[PointLight], reached: SourceMask) -> SourceMask {
    lights.iter().take(32).enumerate().fold(0u32, |acc, (s, l)| {
        let l = l.pos;
        let faces = nrm[0] * (l[0] - p[0]) + nrm[1] * (l[1] - p[1]) + nrm[2] * (l[2] - p[2]) > 0.0;
        acc | (((reached >> s & 1 == 1) && faces) as u32) << s
    })
}

/// What a cell shows: the colour of its visible voxel and the lights that lit it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pixel {
    /// Gamma-encoded colour.
    pub rgb: [u8; 3],
    /// Lights that lit the voxel: a beam of the light reached it and the surface faces it.
    pub lit: SourceMask,
    /// Depth of the visible voxel.
    pub z: crate::units::Depth,
}

/// The pixel of column (x, y): the first occupied voxel of `store` seen from the camera (near
/// end z = 0, looking along +z), shaded with its material (`materials[id]`, default when
/// missing) under the lights whose bit is set in `reached(z)` and that the surface faces.
/// `None` when the column is empty.
pub fn pixel<const D: usize>(
    x: crate::units::Coord,
    y: crate::units::Coord,
    store: &crate::dexel::DexelStore<D>,
    reached: impl Fn(crate::units::Depth) -> SourceMask,
    materials: &[Material],
    lights: &[PointLight],
    params: &ShadeParams,
) -> Option<Pixel> {
    let d = store.dexels().first()?;
    let z = d.span.lo;
    let (p, v) = params.eye.shading_point([x as f32, y as f32, z as f32]);
    let nrm = shading_normal_toward(d.normal, params.normal_mode, v);
    let m = materials.get(d.material as usize).copied().unwrap_or_default();
    let lit = facing_mask(p, nrm, lights, reached(z));
    Some(Pixel { rgb: shade_linear_toward(p, nrm, v, &m, lights, lit, params).map(encode), lit, z })
}

/// Where column (x, y) shades its visible surface: the point (x, y, z\*) in the shading space,
/// the unit direction to the eye there, and the surface's material (default when missing).
pub fn surface_point(
    x: crate::units::Coord,
    y: crate::units::Coord,
    surface: &crate::visible::VisibleSurface,
    materials: &[Material],
    params: &ShadeParams,
) -> ([f32; 3], [f32; 3], Material) {
    let (p, v) = params.eye.shading_point([x as f32, y as f32, surface.depth()]);
    (p, v, materials.get(surface.material as usize).copied().unwrap_or_default())
}

/// The pixel of column (x, y) under the plane rule: the facet its centre line meets first
/// ([`crate::visible`]), shaded at that exact point (x, y, z*) with its material under the lights
/// in `reached` (those that lit the surface, [`crate::lit`]) that it faces.
pub fn surface_pixel(
    x: crate::units::Coord,
    y: crate::units::Coord,
    surface: &crate::visible::VisibleSurface,
    reached: SourceMask,
    materials: &[Material],
    lights: &[PointLight],
    params: &ShadeParams,
) -> Pixel {
    let (p, v, m) = surface_point(x, y, surface, materials, params);
    let nrm = shading_normal_toward(surface.normal, params.normal_mode, v);
    let lit = facing_mask(p, nrm, lights, reached);
    Pixel {
        rgb: shade_linear_toward(p, nrm, v, &m, lights, lit, params).map(encode),
        lit,
        z: surface.z_v.clamp(0, u16::MAX as i32) as u16,
    }
}

/// The pixel a cell shows under `rule`: its first occupied voxel lit by `reached(z)` (the
/// thesis's rule, [`pixel`]), or its visible surface lit by `visible_lit` (the plane rule,
/// [`surface_pixel`]). `None` when the column shows nothing.
#[allow(clippy::too_many_arguments)]
pub fn cell_pixel<const D: usize>(
    rule: crate::lit::LitRule,
    cell: &crate::cell::Cell<D>,
    reached: impl Fn(crate::units::Depth) -> SourceMask,
    visible_lit: SourceMask,
    materials: &[Material],
    lights: &[PointLight],
    params: &ShadeParams,
) -> Option<Pixel> {
    if rule.shades_visible_surface() {
        cell.visible.as_ref().map(|v| surface_pixel(cell.x, cell.y, v, visible_lit, materials, lights, params))
    } else {
        pixel(cell.x, cell.y, &cell.store, reached, materials, lights, params)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn emitter_and_unlit() {
        let params = ShadeParams { ambient: [0.0; 3], normal_mode: NormalMode::Facet, eye: Eye::Grid };
        let lamp = Material { ke: [17.0, 12.0, 4.0], ..Default::default() };
        let c = shade([0.0; 3], VIEW, &lamp, &[], 0, &params);
        assert_eq!(c[0], 255);
        assert!(c[1] < c[0] && c[2] < c[1]);
        let wall = Material { kd: [0.8; 3], ..Default::default() };
        let light = PointLight { pos: [0.0, 0.0, -10.0], color: [1.0; 3] };
        assert_eq!(shade([0.0; 3], VIEW, &wall, &[light], 0, &params), [0, 0, 0], "not lit: dark");
        // Head-on, fully lit: 0.8 → 255·0.8^(1/2.2) ≈ 230.
        assert_eq!(shade([0.0; 3], VIEW, &wall, &[light], 1, &params)[0], 230);
    }

    #[test]
    fn gamma_table_is_exact_rounding() {
        for (l, &t) in GAMMA_THRESHOLDS.iter().enumerate() {
            let want = ((l as f64 + 0.5) / 255.0).powf(2.2);
            assert!(((t as f64) - want).abs() <= want * 1e-6, "entry {l}");
        }
        for i in 0..=100_000 {
            let c = i as f32 / 100_000.0;
            let exact = 255.0 * (c as f64).powf(1.0 / 2.2);
            let got = encode(c) as f64;
            // Exact rounding, except within float noise of a half level.
            assert!((got - exact).abs() <= 0.5 + 1e-3, "c = {c}: {got} vs {exact}");
        }
        assert_eq!((encode(-1.0), encode(0.0), encode(1.0), encode(7.0)), (0, 0, 255, 255));
    }

    #[test]
    fn refined_math_is_accurate() {
        for i in 1..10_000 {
            let x = i as f32 / 97.0;
            let r = inv_sqrt(x) as f64;
            assert!((r * (x as f64).sqrt() - 1.0).abs() < 1e-6, "1/sqrt({x})");
        }
        for k in [0u32, 1, 2, 7, 20, 64, 1000] {
            for x in [0.0f32, 0.3, 0.9, 0.999] {
                let want = (x as f64).powi(k as i32);
                assert!(((powi(x, k) as f64) - want).abs() <= 1e-5 * want.max(1e-30) + 1e-12, "{x}^{k}");
            }
        }
    }
}

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
}

/// `((L + ½)/255)^2.2` for L = 0..=254: a linear intensity c encodes to the number of
/// thresholds ≤ c (exact rounding of `255·c^(1/2.2)`), found by binary search. Generated in f64;
/// the tests check every entry against `powf`.
pub const GAMMA_THRESHOLDS: [f32; 255] = [
    1.104957598e-06, 1.23883188e-05, 3.811356932e-05, 7.990267162e-05, 0.0001388926082, 0.0002159780024,
    0.0003119040311, 0.0004273132726, 0.0005627729823, 0.0007187924962, 0.0008958350718, 0.001094326338,
    0.001314660552, 0.001557205374, 0.001822305592, 0.002110286103, 0.002421454318, 0.002756102152,
    0.003114507676, 0.003496936515, 0.003903643037, 0.004334871368, 0.004790856282, 0.005271823965,
    0.005777992698, 0.006309573445, 0.006866770389, 0.007449781402, 0.008058798465, 0.008694008054,
    0.009355591478, 0.01004372519, 0.01075858108, 0.01150032672, 0.01226912559, 0.01306513735,
    0.01388851796, 0.01473941992, 0.01561799243, 0.01652438152, 0.01745873022, 0.01842117871,
    0.01941186441, 0.02043092212, 0.02147848413, 0.0225546803, 0.02365963821, 0.02479348319,
    0.02595633843, 0.02714832507, 0.02836956227, 0.02962016728, 0.03090025551, 0.03220994057,
    0.03354933437, 0.03491854716, 0.03631768757, 0.03774686269, 0.0392061781, 0.04069573791,
    0.04221564482, 0.04376600017, 0.04534690397, 0.0469584549, 0.04860075044, 0.05027388681,
    0.05197795906, 0.05371306108, 0.05547928563, 0.0572767244, 0.059105468, 0.06096560599,
    0.06285722695, 0.06478041845, 0.06673526711, 0.06872185861, 0.0707402777, 0.07279060827,
    0.07487293331, 0.07698733496, 0.07913389454, 0.08131269254, 0.08352380867, 0.08576732185,
    0.08804331024, 0.09035185126, 0.0926930216, 0.09506689722, 0.0974735534, 0.09991306474,
    0.1023855051, 0.1048909479, 0.1074294655, 0.1100011301, 0.112606013, 0.1152441849,
    0.117915716, 0.1206206759, 0.1233591335, 0.1261311573, 0.1289368153, 0.1317761746,
    0.1346493021, 0.1375562642, 0.1404971265, 0.1434719544, 0.1464808125, 0.1495237651,
    0.1526008761, 0.1557122088, 0.1588578259, 0.16203779, 0.1652521629, 0.1685010061,
    0.1717843808, 0.1751023475, 0.1784549664, 0.1818422974, 0.1852643998, 0.1887213327,
    0.1922131545, 0.1957399236, 0.1993016977, 0.2028985343, 0.2065304904, 0.2101976227,
    0.2138999875, 0.2176376408, 0.2214106383, 0.2252190351, 0.2290628863, 0.2329422464,
    0.2368571696, 0.2408077099, 0.2447939209, 0.2488158559, 0.2528735678, 0.2569671093,
    0.2610965327, 0.2652618901, 0.2694632332, 0.2737006134, 0.277974082, 0.2822836897,
    0.2866294872, 0.2910115247, 0.2954298523, 0.2998845197, 0.3043755765, 0.3089030717,
    0.3134670544, 0.3180675732, 0.3227046766, 0.3273784127, 0.3320888294, 0.3368359745,
    0.3416198953, 0.346440639, 0.3512982525, 0.3561927826, 0.3611242758, 0.3660927782,
    0.3710983358, 0.3761409945, 0.3812207997, 0.3863377969, 0.3914920311, 0.3966835472,
    0.4019123899, 0.4071786036, 0.4124822326, 0.417823321, 0.4232019126, 0.428618051,
    0.4340717796, 0.4395631417, 0.4450921804, 0.4506589384, 0.4562634584, 0.4619057829,
    0.467585954, 0.473304014, 0.4790600047, 0.4848539677, 0.4906859447, 0.4965559769,
    0.5024641055, 0.5084103716, 0.5143948158, 0.5204174789, 0.5264784014, 0.5325776234,
    0.5387151852, 0.5448911266, 0.5511054876, 0.5573583077, 0.5636496263, 0.5699794829,
    0.5763479164, 0.582754966, 0.5892006704, 0.5956850684, 0.6022081984, 0.6087700988,
    0.6153708078, 0.6220103636, 0.6286888039, 0.6354061666, 0.6421624894, 0.6489578096,
    0.6557921646, 0.6626655917, 0.6695781278, 0.6765298099, 0.6835206747, 0.690550759,
    0.6976200991, 0.7047287315, 0.7118766924, 0.7190640179, 0.7262907439, 0.7335569063,
    0.7408625409, 0.748207683, 0.7555923683, 0.7630166321, 0.7704805095, 0.7779840355,
    0.7855272453, 0.7931101735, 0.8007328549, 0.8083953241, 0.8160976155, 0.8238397635,
    0.8316218023, 0.8394437661, 0.8473056887, 0.8552076041, 0.8631495461, 0.8711315482,
    0.8791536441, 0.8872158672, 0.8953182507, 0.9034608279, 0.9116436319, 0.9198666957,
    0.9281300521, 0.9364337339, 0.9447777738, 0.9531622043, 0.9615870579, 0.970052367,
    0.9785581637, 0.9871044803, 0.9956913488,
];

/// Direction toward the viewer.
pub const VIEW: [f32; 3] = [0.0, 0.0, -1.0];

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
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
fn normalise(v: [f32; 3]) -> [f32; 3] {
    let l2 = dot(v, v);
    if l2 <= 0.0 {
        return [0.0; 3];
    }
    let r = inv_sqrt(l2);
    [v[0] * r, v[1] * r, v[2] * r]
}

/// The unit normal a cell shades `d` with, turned toward the viewer.
pub fn shading_normal(d: &Dexel, mode: NormalMode) -> [f32; 3] {
    match mode {
        NormalMode::Face => VIEW,
        NormalMode::Facet => {
            let n = normalise(d.normal.decode());
            if dot(n, VIEW) < 0.0 {
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
pub fn shade(p: [f32; 3], n: [f32; 3], m: &Material, lights: &[PointLight], lit: SourceMask, params: &ShadeParams) -> [u8; 3] {
    let kmax = m.ke[0].max(m.ke[1]).max(m.ke[2]);
    let mut c = [0.0f32; 3];
    if kmax > 0.0 {
        for i in 0..3 {
            c[i] = m.ke[i] / kmax;
        }
    } else {
        for i in 0..3 {
            c[i] = m.ka[i] * params.ambient[i];
        }
        for (s, l) in lights.iter().enumerate().take(32) {
            if lit >> s & 1 == 0 {
                continue;
            }
            let ld = normalise([l.pos[0] - p[0], l.pos[1] - p[1], l.pos[2] - p[2]]);
            let ndl = dot(n, ld);
            if ndl <= 0.0 {
                continue;
            }
            let h = normalise([ld[0] + VIEW[0], ld[1] + VIEW[1], ld[2] + VIEW[2]]);
            let nh = dot(n, h).max(0.0);
            let spec = if nh > 0.0 && m.ks.iter().any(|&k| k > 0.0) {
                powi(nh, (m.ns.max(0.0) + 0.5) as u32)
            } else {
                0.0
            };
            for i in 0..3 {
                c[i] += l.color[i] * (m.kd[i] * ndl + m.ks[i] * spec);
            }
        }
    }
    c.map(encode)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn emitter_and_unlit() {
        let params = ShadeParams { ambient: [0.0; 3], normal_mode: NormalMode::Facet };
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

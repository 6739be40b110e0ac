//! Shading: every cell shades its pixel with `cell_core::shade` (thesis §1.1, §5.2).
//!
//! The pixel shows the column's visible voxel or surface (by lit rule, [`Seen`]): orthographic
//! view along +z, image y up, +x to the left as a camera looking along +z sees it. Lights are
//! white, each of intensity 1/√(number of lights), ambient 0.2. The image also carries the
//! cells' shading error against the same formula in f64 with the same inputs.

use cell_core::light::SourceMask;
use cell_core::shade::{
    pixel, shading_normal_toward, surface_pixel, Eye, Material as CellMaterial, NormalMode, PointLight, ShadeParams,
};

use cell_core::smooth::{smooth_pixel, Smooth, SmoothSurface};

use crate::machine::loading::loaded_scene::LoadedScene;
use crate::machine::shading::smooth_surface::SmoothGrid;
use crate::scene::{Material, Mesh};

/// Ambient intensity Ia.
pub const AMBIENT: f32 = 0.2;

/// The discrete image: what the cells show.
pub struct Image {
    /// Side.
    pub n: u32,
    /// Pixels, index y·n + x, y up.
    pub rgb: Vec<[u8; 3]>,
    /// Whether the column holds a voxel.
    pub covered: Vec<bool>,
    /// Lights that lit the shown voxel (a beam reached it and the surface faces the light).
    pub lit: Vec<u32>,
    /// Largest |cell − f64| over channels and covered pixels, in 8-bit levels.
    pub shading_max_err_levels: u8,
    /// Mean of that over channels and covered pixels.
    pub shading_mean_err_levels: f64,
}

/// The cell's view of a scene material.
pub fn cell_material(m: &Material) -> CellMaterial {
    CellMaterial { ka: m.ka, kd: m.kd, ks: m.ks, ns: m.ns, ke: m.ke }
}

/// Lights as the cells see them (voxel units, white, 1/√L each).
pub fn point_lights(positions: &[[f64; 3]]) -> Vec<PointLight> {
    let e = 1.0 / (positions.len().max(1) as f32).sqrt();
    weighted_lights(positions, &vec![e; positions.len()])
}

/// Lights as the cells see them, white, with the intensity each carries (an area light's
/// samples share its intensity: [`crate::machine::loading::loaded_scene::Sources`]).
pub fn weighted_lights(positions: &[[f64; 3]], intensity: &[f32]) -> Vec<PointLight> {
    assert_eq!(positions.len(), intensity.len(), "one intensity per light");
    positions.iter().zip(intensity).map(|(p, &e)| PointLight { pos: p.map(|c| c as f32), color: [e; 3] }).collect()
}

/// Lights (voxel units) as the cells under `eye` shade with them: in view space under a
/// camera ([`Eye::Camera`]), unchanged in the grid's own view.
pub fn eye_lights(eye: &Eye, lights: &[PointLight]) -> Vec<PointLight> {
    match eye {
        Eye::Grid => lights.to_vec(),
        Eye::Camera(c) => lights.iter().map(|l| PointLight { pos: c.point(l.pos), ..*l }).collect(),
    }
}

/// What the image reads for each cell.
pub enum Seen<'a> {
    /// The thesis's: the first occupied voxel of the column, lit by the sources
    /// `mask(x, y, z)` gives for voxel (x, y, z) (diffusion or classic shadow rays).
    FirstVoxel(Box<dyn Fn(u32, u32, u16) -> SourceMask + 'a>),
    /// The plane rule's: the surface the column's centre line meets ([`cell_core::visible`]),
    /// lit by the sources `mask(x, y)` gives for column (x, y).
    Surface(Box<dyn Fn(u32, u32) -> SourceMask + 'a>),
    /// The visible surface under the lit-ray ratio ([`cell_core::visibility`]): each light
    /// weighed by the weight (0 ..= 255) `weights(x, y)` gives it for column (x, y).
    Weighted(Box<dyn Fn(u32, u32) -> Vec<u8> + 'a>),
}

/// The lights of a pixel each weighed by its weight (0 ..= 255; a cell scales the light's
/// intensity by `w/255`), and the mask of those with a weight.
pub fn weigh_lights(lights: &[PointLight], weights: &[u8]) -> (SourceMask, Vec<PointLight>) {
    let mask = weights.iter().take(32).enumerate().fold(0, |m, (s, &w)| m | ((w > 0) as SourceMask) << s);
    let scaled = lights
        .iter()
        .enumerate()
        .map(|(s, l)| {
            let w = weights.get(s).copied().unwrap_or(0) as f32 / 255.0;
            PointLight { color: l.color.map(|c| c * w), ..*l }
        })
        .collect();
    (mask, scaled)
}

/// What the image of a diffusion reads, by its lit rule (and, when the cells counted rays,
/// their weights).
pub fn seen(lighting: &crate::machine::lighting::diffuse::Lighting) -> Seen<'_> {
    if lighting.weights.is_some() {
        Seen::Weighted(Box::new(|x, y| lighting.pixel_weights(x, y).unwrap_or_default()))
    } else if lighting.rule.shades_visible_surface() {
        Seen::Surface(Box::new(|x, y| lighting.visible_mask(x, y)))
    } else {
        Seen::FirstVoxel(Box::new(|x, y, z| lighting.mask(x, y, z)))
    }
}

/// The lights as the reference renderer takes them.
pub fn ref_lights(lights: &[PointLight]) -> Vec<crate::truth::refrender::RefLight> {
    lights
        .iter()
        .map(|l| crate::truth::refrender::RefLight { pos: l.pos.map(|c| c as f64), color: l.color.map(|c| c as f64) })
        .collect()
}

/// Shade every cell's visible voxel.
pub fn shade_grid(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    lighting: &crate::machine::lighting::diffuse::Lighting,
    mode: NormalMode,
) -> Image {
    shade_grid_with(mesh, scene, lights, &seen(lighting), mode)
}

/// The ambient term `Ka ⊙ Ia` a cell shades with.
#[derive(Clone, Copy, Debug)]
pub enum Ambient<'a> {
    /// The empirical ambient source of the local model (radiosity thesis §1.1.1): `Ia` the same
    /// everywhere, reflected with the material's `Ka`.
    Constant([f32; 3]),
    /// Radiosity (`crate::machine::shooting::indirect`): per cell (row-major) the indirect irradiance of
    /// its visible point, reflected with the material's `Kd` like any diffuse light: `Ka := Kd`.
    Indirect(&'a [[f32; 3]]),
}

impl Ambient<'_> {
    /// `Ia` at cell `i`.
    fn at(&self, i: usize) -> [f32; 3] {
        match self {
            Ambient::Constant(a) => *a,
            Ambient::Indirect(cells) => cells[i],
        }
    }

    /// A material as the cells shade it under this ambient term.
    fn material(&self, m: &Material) -> Material {
        match self {
            Ambient::Constant(_) => m.clone(),
            Ambient::Indirect(_) => Material { ka: m.kd, ..m.clone() },
        }
    }
}

/// The normal(s) a pixel was shaded with.
enum Normals<'a> {
    /// One unit normal facing the eye.
    One([f32; 3]),
    /// A smooth record, its mode and the facet's normal code.
    Smooth(Smooth, &'a SmoothSurface, cell_core::normal::NormalCode),
}

/// The colour of [`cell_core::smooth::smooth_pixel`] in f64 from the same record: its weights
/// and decoded vertex normals, the Phong normal or the Gouraud sum, `shade(n)` the formula at
/// the pixel's point.
pub fn smooth_f64(
    mode: Smooth,
    r: &SmoothSurface,
    facet: cell_core::normal::NormalCode,
    v: [f32; 3],
    shade: impl Fn([f64; 3]) -> [f64; 3],
) -> [f64; 3] {
    let unit = |a: [f32; 3]| crate::scene::normals::unit(a.map(f64::from));
    let (fc, v) = (facet.decode().map(f64::from), v.map(f64::from));
    let s = if fc[0] * v[0] + fc[1] * v[1] + fc[2] * v[2] < 0.0 { -1.0 } else { 1.0 };
    let n: Vec<[f64; 3]> = r.normals.iter().map(|c| unit(c.decode()).unwrap_or([0.0; 3]).map(|x| s * x)).collect();
    let sum: f64 = r.weights.iter().map(|&w| w as f64).sum::<f64>().max(1.0);
    let l: Vec<f64> = r.weights.iter().map(|&w| w as f64 / sum).collect();
    match mode {
        Smooth::Phong => {
            let mix: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| l[k] * n[k][i]).sum());
            let fallback = || {
                let f = unit(facet.decode()).unwrap_or([0.0, 0.0, 1.0]);
                let d = f[0] * v[0] + f[1] * v[1] + f[2] * v[2];
                if d < 0.0 {
                    f.map(|x| -x)
                } else {
                    f
                }
            };
            shade(crate::scene::normals::unit(mix).unwrap_or_else(fallback))
        }
        Smooth::Gouraud => {
            let mut c = [0.0; 3];
            for k in 0..3 {
                let ck = shade(n[k]);
                for i in 0..3 {
                    c[i] += l[k] * ck[i];
                }
            }
            c
        }
    }
}

/// Shade every cell's visible voxel or surface (see [`Seen`]) with the constant ambient
/// [`AMBIENT`].
pub fn shade_grid_with(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    seen: &Seen<'_>,
    mode: NormalMode,
) -> Image {
    shade_grid_ambient(mesh, scene, lights, seen, mode, &Ambient::Constant([AMBIENT; 3]), None)
}

/// [`shade_grid_with`] under the given ambient term; with `smooth`, the visible surfaces
/// ([`Seen::Surface`]) are shaded from the cells' smooth records ([`cell_core::smooth`]).
pub fn shade_grid_ambient(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    seen: &Seen<'_>,
    mode: NormalMode,
    ambient: &Ambient<'_>,
    smooth: Option<&SmoothGrid>,
) -> Image {
    let n = scene.grid.n;
    let mut params = ShadeParams { ambient: [AMBIENT; 3], normal_mode: mode, eye: scene.eye };
    let materials: Vec<Material> = mesh.materials.iter().map(|m| ambient.material(m)).collect();
    let mats: Vec<CellMaterial> = materials.iter().map(cell_material).collect();
    let lights = &eye_lights(&scene.eye, lights)[..];
    let ref_lights = ref_lights(lights);
    let mut img = Image {
        n,
        rgb: vec![[0; 3]; (n * n) as usize],
        covered: vec![false; (n * n) as usize],
        lit: vec![0; (n * n) as usize],
        shading_max_err_levels: 0,
        shading_mean_err_levels: 0.0,
    };
    let (mut err_sum, mut err_count) = (0u64, 0u64);
    for (i, c) in scene.grid.cells.iter().enumerate() {
        let (x, y) = (c.x as u32, c.y as u32);
        params.ambient = ambient.at(i);
        // The pixel's lights: weighed by its cell's weights, or as they are.
        let weighed = match seen {
            Seen::Weighted(w) => Some(weigh_lights(lights, &w(x, y))),
            _ => None,
        };
        let (lights, ref_lights) = match &weighed {
            Some((_, l)) => (&l[..], std::borrow::Cow::Owned(self::ref_lights(l))),
            None => (lights, std::borrow::Cow::Borrowed(&ref_lights[..])),
        };
        // The lights that reached the visible surface (its cell's mask, or those it weighs).
        let reached = || match (seen, &weighed) {
            (Seen::Surface(mask), _) => mask(x, y),
            (_, Some((m, _))) => *m,
            _ => 0,
        };
        // The pixel, the point and normal it was shaded at, and its material.
        let shaded = match seen {
            Seen::FirstVoxel(mask) => pixel(c.x, c.y, &c.store, |z| mask(x, y, z), &mats, lights, &params).map(|px| {
                let d = c.store.dexels()[0];
                let (p, v) = scene.eye.shading_point([c.x as f32, c.y as f32, px.z as f32]);
                (px, p, v, Normals::One(shading_normal_toward(d.normal, mode, v)), d.material)
            }),
            Seen::Surface(_) | Seen::Weighted(_) => c.visible.as_ref().map(|s| {
                let (p, v) = scene.eye.shading_point([c.x as f32, c.y as f32, s.depth()]);
                match smooth.and_then(|g| Some((g.mode, g.records[i].as_ref()?))) {
                    Some((m, r)) => {
                        let px = smooth_pixel(c.x, c.y, s, r, m, reached(), &mats, lights, &params);
                        (px, p, v, Normals::Smooth(m, r, s.normal), s.material)
                    }
                    None => {
                        let px = surface_pixel(c.x, c.y, s, reached(), &mats, lights, &params);
                        (px, p, v, Normals::One(shading_normal_toward(s.normal, mode, v)), s.material)
                    }
                }
            }),
        };
        let Some((px, p, v, nrm, material)) = shaded else {
            continue;
        };
        let (rgb, lit) = (px.rgb, px.lit);
        // The same inputs through the f64 formula: the error of the cell's arithmetic alone.
        let m = &materials[(material as usize).min(materials.len() - 1)];
        let f64_shade = |n: [f64; 3]| {
            crate::truth::refrender::shade_linear_view_f64(
                p.map(f64::from),
                n,
                v.map(f64::from),
                m,
                &ref_lights,
                lit,
                params.ambient.map(f64::from),
            )
        };
        let exact = match nrm {
            Normals::One(n) => f64_shade(n.map(f64::from)),
            Normals::Smooth(m, r, facet) => smooth_f64(m, r, facet, v, f64_shade),
        }
        .map(crate::truth::refrender::encode_gamma);
        for k in 0..3 {
            let e = rgb[k].abs_diff(exact[k]);
            img.shading_max_err_levels = img.shading_max_err_levels.max(e);
            err_sum += e as u64;
            err_count += 1;
        }
        img.rgb[i] = rgb;
        img.covered[i] = true;
        img.lit[i] = lit;
    }
    img.shading_mean_err_levels = err_sum as f64 / err_count.max(1) as f64;
    img
}

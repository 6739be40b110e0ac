//! Continuous ground-truth renderer: the image the discrete machine's images are compared with.
//!
//! Every ray query goes to [`Reference`] (exact `f64` ray–triangle tests); shading is the
//! machine's Phong/Blinn formula evaluated in `f64` with `std` math ([`shade_f64`]).
//!
//! Camera and image (fixed): orthographic along +z. The image is `n × n`; pixel `(x, y)`
//! (`x` right, `y` **up**, stored at index `y·n + x`) is the world ray with origin
//! `fit.origin + ((x + 0.5)·voxel, (y + 0.5)·voxel, −voxel)`, direction `(0, 0, +1)` and
//! `max_t = (n + 2)·voxel`. A pixel is *covered* when that ray hits a triangle.
//!
//! Units: a world point `P` is `p_vox = (P − origin)/voxel − 0.5` in voxel units (voxel
//! `(i, j, k)` has its centre at `p_vox = (i, j, k)`); light positions are given in voxel units.
//!
//! Shadows: light `s` lights a covered pixel iff the surface faces it (N·L > 0: no attached
//! shadow) and `reference.visible(P, L_s, ignore = [hit facet])`
//! (the open segment from the hit point to the light crosses no other facet). This is pure
//! visibility: a light behind the hit surface can count as lit (its shading contribution is
//! zero through `N·L ≤ 0`). Emitters (`max(ke) > 0`) get their lit mask the same way.

use anyhow::{bail, Context, Result};
use parry3d_f64::math::Vector;

use crate::precompute::Fit;
use crate::scene::camera::View;
use crate::scene::{Material, Mesh};
use crate::truth::visibility::Reference;

/// A point light for the reference renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefLight {
    /// Position in voxel units (voxel `(i, j, k)`'s centre is `(i, j, k)`).
    pub pos: [f64; 3],
    /// Colour (linear; 1.0 = full).
    pub color: [f64; 3],
}

/// A reference image (index `y·n + x`, `y` up).
#[derive(Clone, Debug, PartialEq)]
pub struct RefImage {
    /// Side of the image.
    pub n: u32,
    /// Gamma-encoded colour (2.2); `(0, 0, 0)` where uncovered.
    pub rgb: Vec<[u8; 3]>,
    /// Whether the pixel's ray hits a triangle.
    pub covered: Vec<bool>,
    /// Bit `s` set iff the hit surface faces light `s` and sees it (0 where uncovered).
    pub lit: Vec<u32>,
    /// Number of lights.
    pub lights: u32,
    /// Face index of the hit, `u32::MAX` where uncovered.
    pub facet: Vec<u32>,
}

impl RefImage {
    /// An image of side `n` with nothing covered.
    fn empty(n: u32, lights: u32) -> RefImage {
        let npix = n as usize * n as usize;
        RefImage {
            n,
            rgb: vec![[0; 3]; npix],
            covered: vec![false; npix],
            lit: vec![0; npix],
            lights,
            facet: vec![u32::MAX; npix],
        }
    }

    /// Index of pixel `(x, y)` (`y` up).
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.n as usize + x as usize
    }

    /// The colour rows top to bottom (image row `r` is `y = n − 1 − r`), e.g. for a PNG writer.
    pub fn rows_top_down(&self) -> Vec<[u8; 3]> {
        let n = self.n as usize;
        (0..n).rev().flat_map(|y| self.rgb[y * n..(y + 1) * n].iter().copied()).collect()
    }
}

/// `None` for a zero (or non-finite-length) vector. Divides by the length (glam's `normalize`
/// multiplies by its reciprocal, which rounds differently).
fn normalize(a: Vector) -> Option<Vector> {
    let l = a.length();
    (l > 0.0 && l.is_finite()).then(|| a / l)
}

/// Gamma 2.2 encoding of a linear value: `round(255 · clamp(c, 0, 1)^(1/2.2))`.
pub fn encode_gamma(c: f64) -> u8 {
    // NaN → 0 (clamp keeps NaN; map it explicitly).
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (255.0 * c.powf(1.0 / 2.2)).round() as u8
}

/// The linear (unclamped, un-encoded) colour of the shading formula; see [`shade_f64`].
pub fn shade_linear_f64(
    p_vox: [f64; 3],
    n: [f64; 3],
    m: &Material,
    lights: &[RefLight],
    lit_mask: u32,
    ambient: [f64; 3],
) -> [f64; 3] {
    shade_linear_view_f64(p_vox, n, [0.0, 0.0, -1.0], m, lights, lit_mask, ambient)
}

/// [`shade_linear_f64`] seen from direction `v` (unit, from the point toward the eye; the
/// reversed direction of a reflected ray at the point it hits).
pub fn shade_linear_view_f64(
    p_vox: [f64; 3],
    n: [f64; 3],
    v: [f64; 3],
    m: &Material,
    lights: &[RefLight],
    lit_mask: u32,
    ambient: [f64; 3],
) -> [f64; 3] {
    let (p_vox, n, v) = (Vector::from(p_vox), Vector::from(n), Vector::from(v));
    let ke = m.ke.map(f64::from);
    let kmax = ke[0].max(ke[1]).max(ke[2]);
    if kmax > 0.0 {
        return ke.map(|x| x / kmax);
    }
    let ka = m.ka.map(f64::from);
    let kd = m.kd.map(f64::from);
    let ks = m.ks.map(f64::from);
    let ns = f64::from(m.ns);
    let mut c = [0, 1, 2].map(|i| ka[i] * ambient[i]);
    for (s, light) in lights.iter().enumerate() {
        if s >= 32 || lit_mask & (1u32 << s) == 0 {
            continue;
        }
        let Some(ld) = normalize(Vector::from(light.pos) - p_vox) else {
            continue;
        };
        let ndl = n.dot(ld);
        if ndl > 0.0 {
            for i in 0..3 {
                c[i] += kd[i] * light.color[i] * ndl;
            }
            let nh = match normalize(ld + v) {
                Some(h) => n.dot(h).max(0.0),
                None => 0.0,
            };
            let spec = nh.powf(ns);
            for i in 0..3 {
                c[i] += ks[i] * light.color[i] * spec;
            }
        }
    }
    c
}

/// The shading formula for one point (`f64`), shared with the tests of the discrete shader.
///
/// `p_vox`: the point in voxel units; `n`: unit normal facing the viewer; `lit_mask`: bit `s`
/// set iff light `s` is visible from the point (lights beyond 32 are never lit).
/// ```text
/// V = (0, 0, −1)
/// if max(ke) > 0: c = ke / max(ke)
/// else: c = ka ⊙ ambient
///       for each lit light s: Ld = normalize(L_s − p); ndl = N·Ld
///           if ndl > 0: c += kd ⊙ color_s · ndl
///                       H = normalize(Ld + V); c += ks ⊙ color_s · max(0, N·H)^ns
/// out = round(255 · clamp(c, 0, 1)^(1/2.2))
/// ```
/// A light exactly at the point contributes nothing; `Ld + V = 0` gives `N·H = 0`.
pub fn shade_f64(
    p_vox: [f64; 3],
    n: [f64; 3],
    m: &Material,
    lights: &[RefLight],
    lit_mask: u32,
    ambient: [f64; 3],
) -> [u8; 3] {
    shade_linear_f64(p_vox, n, m, lights, lit_mask, ambient).map(encode_gamma)
}

/// A triangle's three vertices in world units.
pub type WorldTriangle = [[f64; 3]; 3];

/// Fan-triangulate the mesh's faces: world triangles and their face index (the facet id).
/// Faces with fewer than 3 vertices give no triangle. Errors on a vertex or material index out
/// of range.
pub fn mesh_triangles(mesh: &Mesh) -> Result<(Vec<WorldTriangle>, Vec<u32>)> {
    let mut tris = Vec::new();
    let mut facets = Vec::new();
    for (fi, f) in mesh.faces.iter().enumerate() {
        if f.material as usize >= mesh.materials.len() {
            bail!(
                "{}: face {} uses material {} but the mesh has {} materials",
                mesh.name,
                fi,
                f.material,
                mesh.materials.len()
            );
        }
        let mut pts = Vec::with_capacity(f.verts.len());
        for &v in &f.verts {
            let Some(p) = mesh.positions.get(v as usize) else {
                bail!(
                    "{}: face {} uses vertex {} but the mesh has {} vertices",
                    mesh.name,
                    fi,
                    v,
                    mesh.positions.len()
                );
            };
            pts.push(*p);
        }
        for k in 1..pts.len().saturating_sub(1) {
            tris.push([pts[0], pts[k], pts[k + 1]]);
            facets.push(fi as u32);
        }
    }
    Ok((tris, facets))
}

/// Render the reference image of `mesh` (see the module doc for camera and shading).
///
/// Errors: `n = 0`, more than 32 lights, a non-finite or non-positive voxel size, a face with a
/// vertex or material index out of range, or no non-degenerate triangle at all.
pub fn render_reference(mesh: &Mesh, fit: &Fit, n: u32, lights: &[RefLight], ambient: [f64; 3]) -> Result<RefImage> {
    render_reference_reflect(mesh, fit, n, lights, ambient, &RefReflect::NONE)
}

/// Mirror reflections of the reference (the grid's rule, `crate::machine::rays::mirror`): a surface with
/// `Kr > 0` adds `Kr` × the colour its exactly reflected ray brings back (§5.5.5); the tree
/// stops at `depth` reflections or when the product of the Kr along the path falls below
/// `threshold` (Hall, §1.2.5.1); a ray that hits nothing brings back black.
///
/// With `refract`, a surface with transparency `Kt > 0` also adds `Kt·Tf` ⊙ the colour its
/// refracted ray brings back (§1.1's `I_T`): Snell's direction ([`refracted`]) between air
/// (index 1) and the material's `Ni`, entering where the ray meets the face's outer side (its
/// winding, closed meshes outward) and leaving on the inner side; beyond the critical angle the
/// transmitted share is reflected instead (total internal reflection). Each refraction is a
/// level of the tree like a reflection (`depth`, `threshold` with the product of `Kr` and `Kt`
/// weights). Shadow rays still stop at transparent surfaces, as in the machine. `render
/// --reflections D --reference` turns it on (the machine's refracted rays: docs/REFLECTIONS.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefReflect {
    /// Largest number of reflections (0: none).
    pub depth: u32,
    /// Smallest contribution weight that still reflects.
    pub threshold: f64,
    /// Whether transparent surfaces refract too.
    pub refract: bool,
}

impl RefReflect {
    /// No reflected or refracted rays.
    pub const NONE: RefReflect = RefReflect { depth: 0, threshold: 0.0, refract: false };
}

/// Snell's refracted direction of unit incident direction `i` at a surface of unit normal `n`
/// (either orientation) with `eta` = n₁ / n₂ (the incident side's index over the other's); `None`
/// beyond the critical angle. The result is a unit vector on the far side of the surface.
pub fn refracted(i: Vector, n: Vector, eta: f64) -> Option<Vector> {
    let (n, c1) = if n.dot(i) > 0.0 { (-n, n.dot(i)) } else { (n, -n.dot(i)) };
    let k = 1.0 - eta * eta * (1.0 - c1 * c1);
    (k >= 0.0).then(|| eta * i + (eta * c1 - k.sqrt()) * n)
}

/// The ambient term `Ka ⊙ Ia` of the reference's shading.
#[derive(Clone, Copy)]
pub enum RefAmbient<'a> {
    /// The local model's constant ambient source, reflected with `Ka`.
    Constant([f64; 3]),
    /// Radiosity: `Ia` of a point given by its face and world position (the indirect irradiance
    /// there), reflected with `Kd` like any diffuse light (`Ka := Kd`).
    Indirect(&'a dyn Fn(u32, [f64; 3]) -> [f64; 3]),
}

/// Smooth shading in the reference (the cells': `cell_core::smooth`): at the hit point, the
/// barycentric coordinates of the pixel's centre in the projection along the view (z) of the
/// face's triangle that holds it (the face fanned from its first vertex; its positions as the
/// grid has them: world, or screen under a camera, where the view is along z too), the corner
/// normals (world) turned to the side of the face the eye sees, then Phong (the interpolated
/// normal, normalised) or Gouraud (the colours of each corner normal, interpolated). The lights
/// counted as lighting the point are those that light it ([`render_reference`]) and that the
/// interpolated normal faces.
#[derive(Clone, Copy)]
pub struct RefSmooth<'a> {
    /// Phong or Gouraud.
    pub mode: cell_core::smooth::Smooth,
    /// Per face, per corner: unit world normals ([`crate::scene::normals::corner_normals`]).
    pub corners: &'a [Vec<[f64; 3]>],
}

/// The barycentric coordinates of `q` in the xy projection of the triangle `t`, `None` when the
/// projection is degenerate.
pub fn barycentric_xy(q: [f64; 2], t: [[f64; 3]; 3]) -> Option<[f64; 3]> {
    let area = |a: [f64; 3], b: [f64; 3], c: [f64; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let total = area(t[0], t[1], [t[2][0], t[2][1]]);
    if total == 0.0 || !total.is_finite() {
        return None;
    }
    Some([area(t[1], t[2], q) / total, area(t[2], t[0], q) / total, area(t[0], t[1], q) / total])
}

struct RefScene<'a> {
    mesh: &'a Mesh,
    smooth: Option<RefSmooth<'a>>,
    reference: Reference,
    /// The lights in the space the formula is evaluated in: voxel units, or world units under
    /// a camera.
    lights: Vec<RefLight>,
    lights_world: Vec<Vector>,
    /// The camera of a scene in screen space: primary rays and shading in world space.
    view: Option<View>,
    ambient: RefAmbient<'a>,
    origin: Vector,
    voxel: f64,
    /// Length of a primary ray (world units).
    primary_t: f64,
    /// Length of a reflected ray.
    max_t: f64,
    reflect: RefReflect,
    /// Weigh each light by the share of the pixel's footprint that sees it
    /// ([`render_reference_footprint`]); `None`: the pixel's point decides.
    footprint: Option<RefFootprint>,
    /// Points per pixel side whose colours are averaged (1: the centre's alone;
    /// [`render_reference_samples`]).
    samples: u32,
}

/// How the reference weighs a light by a pixel's footprint (the machine's lit-ray ratio,
/// `cell_core::visibility`): `samples` × `samples` points of the pixel's square, each carried
/// along the primary ray through it; those that meet the facet the pixel's centre sees count
/// (`RefScene::footprint_weights`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefFootprint {
    /// Points per side of the pixel.
    pub samples: u32,
    /// Lit iff more than half the points see the light (the machine's `majority`), instead of
    /// weighed by their share (`ratio`).
    pub majority: bool,
}

/// [`render_reference_reflect`] with each light weighed by the share of each pixel's footprint
/// that sees it ([`RefFootprint`]) at the visible point (reflected rays' hits keep their point's
/// own visibility).
pub fn render_reference_footprint(
    mesh: &Mesh,
    fit: &Fit,
    n: u32,
    lights: &[RefLight],
    ambient: [f64; 3],
    reflect: &RefReflect,
    footprint: RefFootprint,
) -> Result<RefImage> {
    if footprint.samples == 0 {
        bail!("refrender: a footprint needs at least one sample per side");
    }
    let mut scene = RefScene::new(mesh, fit, n, lights, RefAmbient::Constant(ambient), reflect)?;
    scene.footprint = Some(footprint);
    Ok(scene.image(n, lights.len() as u32))
}

impl RefScene<'_> {
    /// The `n` × `n` image of the scene, lit by its `lights` lights.
    fn image(&self, n: u32, lights: u32) -> RefImage {
        let mut img = RefImage::empty(n, lights);
        for y in 0..n {
            for x in 0..n {
                self.pixel(x, y, &mut img);
            }
        }
        img
    }

    /// The primary ray through point (sx, sy) of the image (pixel units, the pixel's centre at
    /// x + ½): from one voxel in front of the grid along +z, or the camera's.
    fn primary(&self, sx: f64, sy: f64, n: u32) -> (Vector, Vector) {
        let (o, vx) = (self.origin, self.voxel);
        match &self.view {
            Some(v) => v.ray(sx / n as f64, sy / n as f64),
            None => (Vector::new(o.x + sx * vx, o.y + sy * vx, o.z - vx), Vector::Z),
        }
    }

    /// Each light's weight at pixel (x, y), whose centre sees `facet` at point `p` (unit normal
    /// `normal` facing the eye): the share of `f`'s points of the pixel whose primary ray meets
    /// that facet at a point that faces the light and sees it (points whose ray meets another
    /// surface or none do not count: the weight is the visibility of the surface the pixel
    /// shows, not its coverage; without any such point, `p` alone); under `majority`, 1 above
    /// half, else 0.
    fn footprint_weights(
        &self,
        f: RefFootprint,
        (x, y, n): (u32, u32, u32),
        (p, normal, facet): (Vector, Vector, u32),
    ) -> Vec<f64> {
        let s = f.samples;
        let mut hits: Vec<(Vector, Vector, u32)> = (0..s * s)
            .filter_map(|k| {
                let (i, j) = ((k % s) as f64, (k / s) as f64);
                let (o, d) = self.primary(x as f64 + (i + 0.5) / s as f64, y as f64 + (j + 0.5) / s as f64, n);
                let (t, hit, nq) = self.reference.first_hit(o.to_array(), d.to_array(), self.primary_t, &[])?;
                (hit == facet).then(|| (o + t * d, Vector::from(nq), hit))
            })
            .collect();
        if hits.is_empty() {
            hits.push((p, normal, facet));
        }
        self.lights_world
            .iter()
            .map(|lw| {
                let sees = |(q, nq, facet): &&(Vector, Vector, u32)| {
                    nq.dot(*lw - *q) > 0.0 && self.reference.visible(q.to_array(), lw.to_array(), &[*facet])
                };
                let share = hits.iter().filter(sees).count() as f64 / hits.len() as f64;
                match f.majority {
                    true => (share > 0.5) as u8 as f64,
                    false => share,
                }
            })
            .collect()
    }

    /// Lit: the surface faces the light (no attached shadow) and sees it.
    fn lit_mask(&self, p: Vector, normal: Vector, facet: u32) -> u32 {
        let mut mask = 0u32;
        for (s, lw) in self.lights_world.iter().enumerate() {
            let to_light = *lw - p;
            if normal.dot(to_light) > 0.0 && self.reference.visible(p.to_array(), lw.to_array(), &[facet]) {
                mask |= 1 << s;
            }
        }
        mask
    }

    /// The linear colour at world point `p` of `facet` (unit normal facing the eye, `v` toward
    /// the eye), reflections included from tree level `level` (1 for a visible point) with
    /// contribution weight `weight` of the ray that reached it. Also the lit mask.
    fn colour(&self, p: Vector, normal: Vector, facet: u32, v: Vector, level: u32, weight: f64) -> ([f64; 3], u32) {
        self.colour_weighed(p, normal, facet, v, level, weight, None)
    }

    /// [`RefScene::colour`] with each light's intensity weighed by `lights` (its weight per
    /// light, [`RefScene::footprint_weights`]; the lit mask: those with a weight) instead of
    /// the point's own visibility.
    #[allow(clippy::too_many_arguments)]
    fn colour_weighed(
        &self,
        p: Vector,
        normal: Vector,
        facet: u32,
        v: Vector,
        level: u32,
        weight: f64,
        lights: Option<&[f64]>,
    ) -> ([f64; 3], u32) {
        let (o, vx) = (self.origin, self.voxel);
        let (mask, weighed) = match lights {
            Some(w) => {
                let mask = w.iter().enumerate().fold(0u32, |m, (s, &w)| m | ((w > 0.0) as u32) << s);
                let scaled = self.lights.iter().zip(w).map(|(l, &w)| RefLight { color: l.color.map(|c| c * w), ..*l });
                (mask, std::borrow::Cow::Owned(scaled.collect::<Vec<_>>()))
            }
            None => (self.lit_mask(p, normal, facet), std::borrow::Cow::Borrowed(&self.lights[..])),
        };
        let p_vox = if self.view.is_some() { p } else { (p - o) / vx - Vector::splat(0.5) };
        let m = &self.mesh.materials[self.mesh.faces[facet as usize].material as usize];
        let (p_vox, n, v_arr) = (p_vox.to_array(), normal.to_array(), v.to_array());
        let mut c = match self.ambient {
            RefAmbient::Constant(a) => shade_linear_view_f64(p_vox, n, v_arr, m, &weighed, mask, a),
            RefAmbient::Indirect(at) => {
                let m = Material { ka: m.kd, ..m.clone() };
                shade_linear_view_f64(p_vox, n, v_arr, &m, &weighed, mask, at(facet, p.to_array()))
            }
        };
        // R = I − 2(I·N)N with I = −v: the reflected ray, and the transmitted share's way
        // beyond the critical angle.
        let mirrored = || 2.0 * v.dot(normal) * normal - v;
        let kr = f64::from(m.kr);
        let w = weight * kr;
        if kr > 0.0 && level <= self.reflect.depth && w >= self.reflect.threshold {
            let c2 = self.trace(p, mirrored(), facet, level, w);
            for k in 0..3 {
                c[k] += kr * c2[k];
            }
        }
        let kt = f64::from(m.kt);
        let w = weight * kt;
        if self.reflect.refract && kt > 0.0 && level <= self.reflect.depth && w >= self.reflect.threshold {
            let i = -v;
            let outward = self.outward(facet);
            let ni = f64::from(m.ni);
            let eta = if outward.dot(i) < 0.0 { 1.0 / ni } else { ni };
            let t = refracted(i, normal, eta).unwrap_or_else(mirrored);
            let c2 = self.trace(p, t, facet, level, w);
            for k in 0..3 {
                c[k] += kt * f64::from(m.tf[k]) * c2[k];
            }
        }
        (c, mask)
    }

    /// The colour a secondary ray from `p` (on `facet`) along `dir` brings back: the colour of
    /// the first surface it meets at tree level `level + 1`, black if it meets none.
    fn trace(&self, p: Vector, dir: Vector, facet: u32, level: u32, weight: f64) -> [f64; 3] {
        let Some((t, f2, n2)) = self.reference.first_hit(p.to_array(), dir.to_array(), self.max_t, &[facet]) else {
            return [0.0; 3];
        };
        let back = normalize(-dir).unwrap_or(Vector::new(0.0, 0.0, -1.0));
        self.colour(p + t * dir, Vector::from(n2), f2, back, level + 1, weight).0
    }

    /// The unit normal of `facet` on its outer side (its winding), in the space rays are traced in.
    fn outward(&self, facet: u32) -> Vector {
        let f = &self.mesh.faces[facet as usize];
        let pts: Vec<[f64; 3]> = f.verts.iter().map(|&k| self.mesh.positions[k as usize]).collect();
        normalize(Vector::from(crate::scene::normals::newell(&pts))).unwrap_or(Vector::Z)
    }
}

/// The reference with `s` × `s` points per pixel (the machine's `--samples`): each point's
/// primary ray shaded at its own hit with its own shadow rays, the pixel the mean of their
/// colours (clamped to [0, 1]; a ray that meets nothing is black), gamma-encoded once. The
/// coverage, lit masks and facets stay the centre ray's.
pub fn render_reference_samples(
    mesh: &Mesh,
    fit: &Fit,
    n: u32,
    lights: &[RefLight],
    ambient: [f64; 3],
    s: u32,
) -> Result<RefImage> {
    if s == 0 {
        bail!("refrender: at least one sample per pixel side");
    }
    let mut scene = RefScene::new(mesh, fit, n, lights, RefAmbient::Constant(ambient), &RefReflect::NONE)?;
    scene.samples = s;
    Ok(scene.image(n, lights.len() as u32))
}

impl RefScene<'_> {
    /// The mean colour of pixel (x, y)'s `s` × `s` points (see [`render_reference_samples`]).
    fn mean_of_samples(&self, x: u32, y: u32, n: u32, s: u32) -> [u8; 3] {
        let colours: Vec<Option<[f64; 3]>> = (0..s * s)
            .map(|k| {
                let (i, j) = ((k % s) as f64, (k / s) as f64);
                let (o, d) = self.primary(x as f64 + (i + 0.5) / s as f64, y as f64 + (j + 0.5) / s as f64, n);
                let (t, facet, normal) = self.reference.first_hit(o.to_array(), d.to_array(), self.primary_t, &[])?;
                Some(self.colour(o + t * d, Vector::from(normal), facet, -d, 1, 1.0).0)
            })
            .collect();
        mean_colour(&colours)
    }
}

/// The pixel of several samples' linear colours (`None`: a sample that meets nothing, black):
/// each clamped to [0, 1], their mean gamma-encoded once ([`encode_gamma`]).
pub fn mean_colour(colours: &[Option<[f64; 3]>]) -> [u8; 3] {
    let mut sum = [0.0; 3];
    for c in colours.iter().flatten() {
        for k in 0..3 {
            sum[k] += c[k].clamp(0.0, 1.0);
        }
    }
    sum.map(|c| encode_gamma(c / colours.len().max(1) as f64))
}

/// [`render_reference`] with mirror reflections (see [`RefReflect`]).
pub fn render_reference_reflect(
    mesh: &Mesh,
    fit: &Fit,
    n: u32,
    lights: &[RefLight],
    ambient: [f64; 3],
    reflect: &RefReflect,
) -> Result<RefImage> {
    render_reference_ambient(mesh, fit, n, lights, RefAmbient::Constant(ambient), reflect)
}

/// [`render_reference`] shaded smoothly ([`RefSmooth`]).
pub fn render_reference_smooth(
    mesh: &Mesh,
    fit: &Fit,
    n: u32,
    lights: &[RefLight],
    ambient: [f64; 3],
    smooth: &RefSmooth<'_>,
) -> Result<RefImage> {
    if smooth.corners.len() != mesh.faces.len() {
        bail!("refrender: {} faces but corner normals for {}", mesh.faces.len(), smooth.corners.len());
    }
    let mut scene = RefScene::new(mesh, fit, n, lights, RefAmbient::Constant(ambient), &RefReflect::NONE)?;
    scene.smooth = Some(*smooth);
    Ok(scene.image(n, lights.len() as u32))
}

/// [`render_reference_reflect`] with any ambient term ([`RefAmbient`]).
pub fn render_reference_ambient(
    mesh: &Mesh,
    fit: &Fit,
    n: u32,
    lights: &[RefLight],
    ambient: RefAmbient<'_>,
    reflect: &RefReflect,
) -> Result<RefImage> {
    let scene = RefScene::new(mesh, fit, n, lights, ambient, reflect)?;
    Ok(scene.image(n, lights.len() as u32))
}

impl<'a> RefScene<'a> {
    /// Check the inputs and build the exact visibility structure.
    fn new(
        mesh: &'a Mesh,
        fit: &Fit,
        n: u32,
        lights: &[RefLight],
        ambient: RefAmbient<'a>,
        reflect: &RefReflect,
    ) -> Result<Self> {
        if n == 0 {
            bail!("refrender: n must be positive");
        }
        if lights.len() > 32 {
            bail!("refrender: at most 32 lights (lit masks are u32), got {}", lights.len());
        }
        let fit_ok = fit.voxel > 0.0 && fit.voxel.is_finite() && fit.origin.iter().all(|x| x.is_finite());
        if !fit_ok {
            bail!("refrender: invalid fit {fit:?}");
        }
        if mesh.screen.is_some() && reflect.depth > 0 {
            bail!("refrender: reflections under a camera are not supported");
        }
        // Under a camera the triangles are the world ones the screen-space mesh came from.
        let world_mesh =
            mesh.screen.as_ref().map(|s| Mesh { positions: s.world.clone(), screen: None, ..mesh.clone() });
        let (tris, facets) = mesh_triangles(world_mesh.as_ref().unwrap_or(mesh))?;
        let reference = Reference::new(tris, facets).with_context(|| format!("refrender: scene {}", mesh.name))?;
        let (o, vx) = (Vector::from(fit.origin), fit.voxel);
        let view = mesh.screen.as_ref().map(|s| s.view);
        let to_world = |p: Vector| match &view {
            // Voxel units are screen space: s = (v + ½)/n, then back through the camera.
            Some(v) => {
                Vector::from(v.from_view(v.screen_to_view((p + Vector::splat(0.5)).to_array().map(|c| c / n as f64))))
            }
            None => o + (p + Vector::splat(0.5)) * vx,
        };
        let lights_world: Vec<Vector> = lights.iter().map(|l| to_world(Vector::from(l.pos))).collect();
        let lights = match view {
            Some(_) => lights.iter().zip(&lights_world).map(|(l, w)| RefLight { pos: w.to_array(), ..*l }).collect(),
            None => lights.to_vec(),
        };
        // A primary ray crosses the grid: n voxels and the one in front (under a camera: any
        // length, the frustum bounds the scene).
        let primary_t = if view.is_some() { f64::MAX / 4.0 } else { (n as f64 + 2.0) * vx };
        Ok(RefScene {
            mesh,
            smooth: None,
            reference,
            lights,
            lights_world,
            view,
            ambient,
            origin: o,
            voxel: vx,
            primary_t,
            // Reflected rays are unit vectors: far enough to leave the fitted cube from anywhere.
            max_t: 2.0 * primary_t,
            reflect: *reflect,
            footprint: None,
            samples: 1,
        })
    }

    /// The corner normals of `face` turned to the side `v` sees, and the barycentric coordinates
    /// of `q` in its triangle that holds it (the largest smallest coordinate: [`RefSmooth`]).
    fn interpolate(&self, s: &RefSmooth<'_>, face: u32, q: [f64; 2], v: Vector) -> Option<([Vector; 3], [f64; 3])> {
        let f = self.mesh.faces.get(face as usize)?;
        let pos = |k: usize| self.mesh.positions[f.verts[k] as usize];
        let corners = s.corners.get(face as usize)?;
        let world = crate::scene::normals::world_positions(self.mesh);
        let fnrm = Vector::from(crate::scene::normals::newell(
            &f.verts.iter().map(|&i| world[i as usize]).collect::<Vec<_>>(),
        ));
        let side = if fnrm.dot(v) < 0.0 { -1.0 } else { 1.0 };
        let mut best: Option<([Vector; 3], [f64; 3])> = None;
        for k in 1..f.verts.len().saturating_sub(1) {
            let Some(l) = barycentric_xy(q, [pos(0), pos(k), pos(k + 1)]) else { continue };
            let min = |l: &[f64; 3]| l[0].min(l[1]).min(l[2]);
            if best.as_ref().is_none_or(|b| min(&l) > min(&b.1)) {
                let n = [0, k, k + 1].map(|c| Vector::from(corners[c]) * side);
                best = Some((n, l));
            }
        }
        best
    }

    /// The linear colour and lit mask of point `p` of `facet` (geometric unit normal `normal`,
    /// `v` toward the eye) shaded smoothly from its corner normals `n` and weights `l`.
    #[allow(clippy::too_many_arguments)]
    fn smooth_colour(
        &self,
        p: Vector,
        normal: Vector,
        facet: u32,
        v: Vector,
        mode: cell_core::smooth::Smooth,
        n: &[Vector; 3],
        l: &[f64; 3],
    ) -> ([f64; 3], u32) {
        let mix = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
        let phong = normalize(mix).unwrap_or(if normal.dot(v) < 0.0 { -normal } else { normal });
        let mut mask = self.lit_mask(p, normal, facet);
        for (s, lw) in self.lights_world.iter().enumerate() {
            if phong.dot(*lw - p) <= 0.0 {
                mask &= !(1 << s);
            }
        }
        let p_vox = if self.view.is_some() { p } else { (p - self.origin) / self.voxel - Vector::splat(0.5) };
        let m = &self.mesh.materials[self.mesh.faces[facet as usize].material as usize];
        let a = match self.ambient {
            RefAmbient::Constant(a) => a,
            RefAmbient::Indirect(_) => [0.0; 3],
        };
        let shade =
            |n: Vector| shade_linear_view_f64(p_vox.to_array(), n.to_array(), v.to_array(), m, &self.lights, mask, a);
        let c = match mode {
            cell_core::smooth::Smooth::Phong => shade(phong),
            cell_core::smooth::Smooth::Gouraud => {
                let mut c = [0.0; 3];
                for k in 0..3 {
                    let ck = shade(n[k]);
                    for i in 0..3 {
                        c[i] += l[k] * ck[i];
                    }
                }
                c
            }
        };
        (c, mask)
    }

    /// Pixel (x, y): the primary ray along +z from one voxel in front of the grid, or the
    /// camera's ray through the pixel's centre.
    fn pixel(&self, x: u32, y: u32, img: &mut RefImage) {
        let (origin, dir) = self.primary(x as f64 + 0.5, y as f64 + 0.5, img.n);
        let Some((t, facet, normal)) = self.reference.first_hit(origin.to_array(), dir.to_array(), self.primary_t, &[])
        else {
            // Uncovered at its centre; its other points may meet a surface.
            if self.samples > 1 {
                let i = img.index(x, y);
                img.rgb[i] = self.mean_of_samples(x, y, img.n, self.samples);
            }
            return;
        };
        let p = origin + t * dir;
        let q = match &self.view {
            Some(_) => [(x as f64 + 0.5) / img.n as f64, (y as f64 + 0.5) / img.n as f64],
            None => [origin.x, origin.y],
        };
        let smooth = self.smooth.and_then(|s| Some((s, self.interpolate(&s, facet, q, -dir)?)));
        let (c, mask) = match smooth {
            Some((s, (n, l))) => self.smooth_colour(p, Vector::from(normal), facet, -dir, s.mode, &n, &l),
            None => {
                let normal = Vector::from(normal);
                let weights = self.footprint.map(|f| self.footprint_weights(f, (x, y, img.n), (p, normal, facet)));
                self.colour_weighed(p, normal, facet, -dir, 1, 1.0, weights.as_deref())
            }
        };
        let i = y as usize * img.n as usize + x as usize;
        img.rgb[i] = match self.samples {
            1 => c.map(encode_gamma),
            s => self.mean_of_samples(x, y, img.n, s),
        };
        img.covered[i] = true;
        img.lit[i] = mask;
        img.facet[i] = facet;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Face;
    use crate::truth::compare::{compare, difference_image};

    type V3 = [f64; 3];

    fn mat(ka: [f32; 3], kd: [f32; 3], ks: [f32; 3], ns: f32, ke: [f32; 3]) -> Material {
        Material { name: "m".into(), ka, kd, ks, ns, ke, ..Material::default() }
    }

    /// Test fit: a non-trivial origin and voxel size.
    const FIT: Fit = Fit { origin: [10.0, -20.0, 5.0], voxel: 2.5 };

    /// World point of a voxel-unit point under `FIT`.
    fn w(p: V3) -> V3 {
        [0, 1, 2].map(|i| FIT.origin[i] + (p[i] + 0.5) * FIT.voxel)
    }

    /// Independent gamma encoding for the tests.
    fn gamma(c: f64) -> u8 {
        let c = c.clamp(0.0, 1.0);
        (c.powf(1.0 / 2.2) * 255.0 + 0.5).floor() as u8
    }

    /// 2-D point-in-triangle, strict (sign of the three edge functions; either winding).
    fn in_tri(p: [f64; 2], t: &[[f64; 2]; 3]) -> bool {
        let e = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let (d0, d1, d2) = (e(t[0], t[1]), e(t[1], t[2]), e(t[2], t[0]));
        (d0 > 0.0 && d1 > 0.0 && d2 > 0.0) || (d0 < 0.0 && d1 < 0.0 && d2 < 0.0)
    }

    const PLANE_Z: f64 = 40.0; // voxel units
    const PLANE_LO: f64 = 4.3;
    const PLANE_HI: f64 = 59.7;
    const OCC_Z: f64 = 22.5;
    const OCC: [[f64; 2]; 3] = [[34.0, 30.0], [44.0, 33.0], [38.0, 44.0]];
    const LIGHT: RefLight = RefLight { pos: [32.0, 32.0, 5.0], color: [0.9, 0.8, 0.7] };
    const AMB: [f64; 3] = [0.2, 0.3, 0.25];
    const N: u32 = 64;

    fn plane_mesh(with_occluder: bool) -> Mesh {
        let (lo, hi, z) = (PLANE_LO, PLANE_HI, PLANE_Z);
        let mut positions = vec![w([lo, lo, z]), w([hi, lo, z]), w([hi, hi, z]), w([lo, hi, z])];
        let mut faces = vec![Face { verts: vec![0, 1, 2, 3], material: 0 }];
        if with_occluder {
            for v in OCC {
                positions.push(w([v[0], v[1], OCC_Z]));
            }
            faces.push(Face { verts: vec![4, 5, 6], material: 1 });
        }
        Mesh {
            name: "plane".into(),
            positions,
            faces,
            materials: vec![
                mat([0.3, 0.2, 0.1], [0.6, 0.7, 0.4], [0.0; 3], 1.0, [0.0; 3]),
                mat([0.1; 3], [0.5; 3], [0.0; 3], 1.0, [0.0; 3]),
            ],
            lights: vec![],
            rewound: 0,
            screen: None,
            normals: Vec::new(),
            face_normals: Vec::new(),
        }
    }

    /// Closed-form Lambert value on the plane at pixel (x, y): N = (0, 0, −1).
    fn lambert(x: f64, y: f64, m: &Material, light: &RefLight) -> [u8; 3] {
        let d = [light.pos[0] - x, light.pos[1] - y, light.pos[2] - PLANE_Z];
        let cos = (PLANE_Z - light.pos[2]) / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        assert!(cos > 0.0);
        [0, 1, 2].map(|i| gamma(m.ka[i] as f64 * AMB[i] + m.kd[i] as f64 * light.color[i] * cos))
    }

    #[test]
    fn plane_under_point_light_is_lambert() {
        let mesh = plane_mesh(false);
        // A far light, and one only 2.5 voxels in front of the plane (there the colour varies
        // steeply, so a half-voxel error in the light's or the point's position shows).
        let near = RefLight { pos: [20.3, 40.7, PLANE_Z - 2.5], color: [0.8, 0.9, 1.0] };
        for light in [LIGHT, near] {
            let img = render_reference(&mesh, &FIT, N, &[light], AMB).unwrap();
            let mut covered = 0;
            for y in 0..N {
                for x in 0..N {
                    let i = img.index(x, y);
                    let (xf, yf) = (x as f64, y as f64);
                    let inside = xf > PLANE_LO && xf < PLANE_HI && yf > PLANE_LO && yf < PLANE_HI;
                    assert_eq!(img.covered[i], inside, "pixel ({x}, {y})");
                    if !inside {
                        assert_eq!((img.rgb[i], img.lit[i], img.facet[i]), ([0; 3], 0, u32::MAX));
                        continue;
                    }
                    covered += 1;
                    assert_eq!(img.facet[i], 0);
                    assert_eq!(img.lit[i], 1, "pixel ({x}, {y}) must be lit");
                    let want = lambert(xf, yf, &mesh.materials[0], &light);
                    for c in 0..3 {
                        assert!(img.rgb[i][c].abs_diff(want[c]) <= 1, "pixel ({x}, {y}): {:?} vs {want:?}", img.rgb[i]);
                    }
                }
            }
            assert_eq!(covered, 55 * 55);
            // Not a constant image: right under the light is brighter than a far corner.
            let c = img.rgb[img.index(light.pos[0].round() as u32, light.pos[1].round() as u32)];
            let k = img.rgb[img.index(58, 5)];
            assert!(c[0] > k[0] + 10, "{c:?} {k:?}");
        }
    }

    #[test]
    fn occluder_casts_the_predicted_shadow() {
        let mesh = plane_mesh(true);
        // Light 0: the general case. Light 1: a quarter voxel *behind* the occluder's plane (it
        // lights the whole plane). Light 2: a quarter voxel in front of the occluder, above its
        // interior (the occluder hides it from the whole plane). Lights 1 and 2 make a position
        // error of half a voxel (light or hit point) flip whole regions.
        let (cx, cy) = (38.5, 35.5);
        assert!(in_tri([cx, cy], &OCC));
        let lights = [
            LIGHT,
            RefLight { pos: [cx, cy, OCC_Z + 0.25], color: [0.3, 0.2, 0.1] },
            RefLight { pos: [cx, cy, OCC_Z - 0.25], color: [0.5; 3] },
        ];
        let img = render_reference(&mesh, &FIT, N, &lights, AMB).unwrap();
        // Analytic prediction for a plane point (x, y): does the segment to light l cross the
        // occluder (plane z = OCC_Z)? And does the camera ray at (x, y) hit the occluder first?
        let shadowed = |l: V3, x: f64, y: f64| {
            let t = (OCC_Z - PLANE_Z) / (l[2] - PLANE_Z);
            t > 0.0 && t < 1.0 && in_tri([x + t * (l[0] - x), y + t * (l[1] - y)], &OCC)
        };
        let on_occ = |x: f64, y: f64| in_tri([x, y], &OCC);
        let stable = |f: &dyn Fn(f64, f64) -> bool, x: f64, y: f64| {
            let v = f(x, y);
            (-1..=1).all(|dx| (-1..=1).all(|dy| f(x + dx as f64, y + dy as f64) == v))
        };
        let m = &mesh.materials[0];
        let (mut checked_shadow, mut checked_lit, mut checked_occ, mut band) = (0, 0, 0, 0);
        for y in 0..N {
            for x in 0..N {
                let (xf, yf) = (x as f64, y as f64);
                let i = img.index(x, y);
                if !(xf > PLANE_LO && xf < PLANE_HI && yf > PLANE_LO && yf < PLANE_HI) {
                    continue;
                }
                if !stable(&on_occ, xf, yf) {
                    band += 1;
                    continue;
                }
                if on_occ(xf, yf) {
                    assert_eq!(img.facet[i], 1, "pixel ({x}, {y}) sees the occluder");
                    // Nothing lies between the occluder and any light, but light 1 sits behind
                    // the occluder's plane: the occluder faces away from it (attached shadow).
                    assert_eq!(img.lit[i], 0b101, "occluder pixel ({x}, {y})");
                    checked_occ += 1;
                    continue;
                }
                assert_eq!(img.facet[i], 0, "pixel ({x}, {y}) sees the plane");
                let mut want_mask = 0u32;
                let mut in_band = false;
                for (s, l) in lights.iter().enumerate() {
                    let f = |x: f64, y: f64| shadowed(l.pos, x, y);
                    in_band |= !stable(&f, xf, yf);
                    if !f(xf, yf) {
                        want_mask |= 1 << s;
                    }
                }
                if in_band {
                    band += 1;
                    continue;
                }
                assert_eq!(img.lit[i], want_mask, "pixel ({x}, {y})");
                if want_mask & 1 == 0 {
                    checked_shadow += 1;
                } else {
                    checked_lit += 1;
                }
                // Colour: ambient plus Lambert from the lit lights (closed form).
                let want = [0, 1, 2].map(|c| {
                    let mut v = m.ka[c] as f64 * AMB[c];
                    for (s, l) in lights.iter().enumerate() {
                        if want_mask & (1 << s) != 0 {
                            let d = [l.pos[0] - xf, l.pos[1] - yf, l.pos[2] - PLANE_Z];
                            let cos = (PLANE_Z - l.pos[2]) / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                            v += m.kd[c] as f64 * l.color[c] * cos;
                        }
                    }
                    gamma(v)
                });
                for c in 0..3 {
                    assert!(img.rgb[i][c].abs_diff(want[c]) <= 1, "pixel ({x}, {y}): {:?} vs {want:?}", img.rgb[i]);
                }
            }
        }
        // The checks had something to check.
        assert!(checked_shadow > 100, "{checked_shadow} shadow pixels");
        assert!(checked_occ > 15, "{checked_occ} occluder pixels");
        assert!(checked_lit > 2500, "{checked_lit} lit pixels");
        assert!(band < 400, "{band} boundary pixels");
    }

    /// An icosphere of radius `r` about `c` (world), subdivided `levels` times.
    fn icosphere(c: V3, r: f64, levels: u32) -> Mesh {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        #[rustfmt::skip]
        let mut v: Vec<V3> = vec![
            [-1.0, t, 0.0], [1.0, t, 0.0], [-1.0, -t, 0.0], [1.0, -t, 0.0],
            [0.0, -1.0, t], [0.0, 1.0, t], [0.0, -1.0, -t], [0.0, 1.0, -t],
            [t, 0.0, -1.0], [t, 0.0, 1.0], [-t, 0.0, -1.0], [-t, 0.0, 1.0],
        ];
        #[rustfmt::skip]
        let mut f: Vec<[usize; 3]> = vec![
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ];
        let unit = |p: V3| {
            let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            p.map(|x| x / l)
        };
        for p in v.iter_mut() {
            *p = unit(*p);
        }
        for _ in 0..levels {
            let mut cache = std::collections::HashMap::new();
            let mut mid = |a: usize, b: usize, v: &mut Vec<V3>| {
                *cache.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push(unit([0, 1, 2].map(|i| (v[a][i] + v[b][i]) / 2.0)));
                    v.len() - 1
                })
            };
            let mut nf = Vec::new();
            for [a, b, cc] in f {
                let ab = mid(a, b, &mut v);
                let bc = mid(b, cc, &mut v);
                let ca = mid(cc, a, &mut v);
                nf.extend([[a, ab, ca], [b, bc, ab], [cc, ca, bc], [ab, bc, ca]]);
            }
            f = nf;
        }
        Mesh {
            name: "icosphere".into(),
            positions: v.iter().map(|p| [0, 1, 2].map(|i| c[i] + r * p[i])).collect(),
            faces: f.iter().map(|t| Face { verts: t.iter().map(|&k| k as u32).collect(), material: 0 }).collect(),
            materials: vec![Material::default()],
            lights: vec![],
            rewound: 0,
            screen: None,
            normals: Vec::new(),
            face_normals: Vec::new(),
        }
    }

    #[test]
    fn icosphere_covers_its_disc() {
        let (cx, cy, cz, r) = (32.0, 31.0, 30.0, 20.0); // voxel units
        let mesh = icosphere(w([cx, cy, cz]), r * FIT.voxel, 3);
        assert_eq!(mesh.faces.len(), 1280);
        let light = RefLight { pos: [cx - 10.0, cy + 20.0, cz - 40.0], color: [1.0; 3] };
        let img = render_reference(&mesh, &FIT, N, &[light], [0.1; 3]).unwrap();
        let mut count = 0usize;
        for y in 0..N {
            for x in 0..N {
                let i = img.index(x, y);
                let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                if d < r - 1.0 {
                    assert!(img.covered[i], "({x}, {y}) at {d} must be covered");
                    // The front hemisphere faces the camera: the hit is on its near half.
                    assert!(img.facet[i] < 1280);
                } else if d > r + 1.0 {
                    assert!(!img.covered[i], "({x}, {y}) at {d} must not be covered");
                }
                count += img.covered[i] as usize;
            }
        }
        let disc = std::f64::consts::PI * r * r;
        assert!((count as f64 - disc).abs() < 0.02 * disc, "{count} covered vs disc {disc:.1}");
        // Shading varies across the sphere (normals follow the facets) and the lit side is
        // brighter than the far side.
        let toward = img.rgb[img.index(26, 41)];
        let away = img.rgb[img.index(40, 22)];
        assert!(toward[1] > away[1] + 20, "{toward:?} vs {away:?}");
    }

    #[test]
    fn rendering_is_deterministic() {
        let mesh = crate::scene::load("cornell").unwrap();
        let n = 48;
        let fit = crate::precompute::fit(&mesh, n).unwrap();
        let lights = [cornell_light(&fit), RefLight { pos: [10.0, 10.0, 5.0], color: [0.3, 0.2, 0.1] }];
        let a = render_reference(&mesh, &fit, n, &lights, [0.2; 3]).unwrap();
        let b = render_reference(&mesh, &fit, n, &lights, [0.2; 3]).unwrap();
        assert_eq!(a, b);
        let c = compare(&b.rgb, &b.covered, &b.lit, &a);
        assert_eq!(
            (c.shadow_disagreement_pct, c.coverage_disagreement_pct, c.psnr_db, c.max_abs_diff),
            (0.0, 0.0, f64::INFINITY, 0)
        );
        // The box's back wall fills the view except the one-voxel margin.
        let covered = a.covered.iter().filter(|&&c| c).count();
        assert!(covered >= ((n - 2) * (n - 2)) as usize * 95 / 100, "{covered}");
        // Both lit and shadowed pixels (the blocks shadow the floor).
        assert!(a.lit.iter().zip(&a.covered).any(|(&l, &c)| c && l & 1 == 0));
        assert!(a.lit.iter().any(|&l| l & 1 == 1));
    }

    fn cornell_light(fit: &Fit) -> RefLight {
        let wpos = [278.0, 548.8, 279.5];
        let mut pos = [0, 1, 2].map(|i| (wpos[i] - fit.origin[i]) / fit.voxel - 0.5);
        pos[1] -= 2.0;
        RefLight { pos, color: [1.0; 3] }
    }

    #[test]
    fn compare_hand_made_pair() {
        let reference = RefImage {
            n: 2,
            rgb: vec![[10, 10, 10], [20, 20, 20], [30, 30, 30], [0, 0, 0]],
            covered: vec![true, true, true, false],
            lit: vec![1, 1, 0, 0],
            lights: 2,
            facet: vec![0, 0, 1, u32::MAX],
        };
        let rgb = [[10, 10, 10], [20, 20, 26], [0, 0, 0], [4, 0, 0]];
        let covered = [true, true, false, true];
        let lit = [1, 3, 0, 1];
        let c = compare(&rgb, &covered, &lit, &reference);
        // covered in both: pixels 0, 1, two lights: 4 (pixel, light) pairs; one bit differs
        // (pixel 1, light 1) → 25 %.
        assert_eq!(c.shadow_disagreement_pct, 25.0);
        // covered in exactly one: 2, 3; in either: all 4 → 50 %.
        assert_eq!(c.coverage_disagreement_pct, 50.0);
        // squared error 6² + 3·30² + 4² = 2752 over 12 samples; PSNR = 10·log10(65025·12/2752).
        assert!((c.psnr_db - 24.525_8).abs() < 1e-3, "{}", c.psnr_db);
        assert_eq!(c.max_abs_diff, 30);
        // identical inputs
        let c = compare(&reference.rgb, &reference.covered, &reference.lit, &reference);
        assert_eq!(
            (c.shadow_disagreement_pct, c.coverage_disagreement_pct, c.psnr_db, c.max_abs_diff),
            (0.0, 0.0, f64::INFINITY, 0)
        );
        // nothing covered anywhere: 0 %, not NaN
        let empty =
            RefImage { n: 1, rgb: vec![[0; 3]], covered: vec![false], lit: vec![0], lights: 1, facet: vec![u32::MAX] };
        let c = compare(&[[1, 0, 0]], &[false], &[0], &empty);
        assert_eq!((c.shadow_disagreement_pct, c.coverage_disagreement_pct, c.max_abs_diff), (0.0, 0.0, 1));
        assert!((c.psnr_db - 10.0 * (65025.0f64 * 3.0).log10()).abs() < 1e-9);
        // difference image
        let d = difference_image(&rgb, &covered, &reference);
        assert_eq!(d, vec![[0, 0, 0], [0, 0, 24], [255, 0, 255], [255, 0, 255]]);
        let d = difference_image(&[[200, 0, 70], [0; 3], [30, 30, 30], [0; 3]], &[true, true, true, false], &reference);
        assert_eq!(d, vec![[255, 40, 240], [80, 80, 80], [0, 0, 0], [0, 0, 0]]);
    }

    /// A quad of material `material` at z = 20 in front of the plane, over pixels x 11..=20,
    /// y 11..=30.
    fn add_front_quad(mesh: &mut Mesh, material: u16) {
        let base = mesh.positions.len() as u32;
        for p in [[10.5, 10.5, 20.0], [20.5, 10.5, 20.0], [20.5, 30.5, 20.0], [10.5, 30.5, 20.0]] {
            mesh.positions.push(w(p));
        }
        mesh.faces.push(Face { verts: (base..base + 4).collect(), material });
    }

    #[test]
    fn emitters_show_their_own_colour() {
        // An emitter quad in front of a diffuse plane, no lights and zero ambient.
        let mut mesh = plane_mesh(false);
        add_front_quad(&mut mesh, 2);
        mesh.materials.push(mat([1.0; 3], [0.8; 3], [0.5; 3], 8.0, [17.0, 8.5, 0.0]));
        let want = [255, gamma(0.5), 0];
        assert_eq!(want, [255, 186, 0]);
        for (lights, amb) in [(&[][..], [0.0; 3]), (&[LIGHT][..], AMB)] {
            let img = render_reference(&mesh, &FIT, N, lights, amb).unwrap();
            let mut seen = 0;
            for y in 0..N {
                for x in 0..N {
                    let i = img.index(x, y);
                    let inside = (11..=20).contains(&x) && (11..=30).contains(&y);
                    assert_eq!(img.facet[i] == 1, inside, "({x}, {y})");
                    if inside {
                        assert_eq!(img.rgb[i], want);
                        seen += 1;
                    } else if img.covered[i] && lights.is_empty() {
                        assert_eq!(img.rgb[i], [0; 3], "unlit diffuse plane is black");
                    }
                }
            }
            assert_eq!(seen, 200);
        }
    }

    /// Snell's law from angles: sin θ₂ = η·sin θ₁ in the plane of incidence, on the far side,
    /// a unit vector; nothing beyond the critical angle; through a parallel slab (air → glass →
    /// air) the ray leaves along the direction it came in.
    #[test]
    fn refracted_obeys_snell() {
        let n = Vector::new(0.3, -0.4, 0.866_025_403_784_438_6).normalize();
        let (u, w) = (n.any_orthonormal_vector(), n.cross(n.any_orthonormal_vector()));
        for eta in [1.0 / 1.5, 1.5, 1.0 / 1.33, 1.33, 1.0] {
            for deg in (0..90).step_by(7) {
                for phi in [0.0f64, 1.0, 2.5] {
                    let th = (deg as f64).to_radians();
                    let tangent = phi.cos() * u + phi.sin() * w;
                    let i = th.sin() * tangent - th.cos() * n;
                    let want_sin = eta * th.sin();
                    let Some(t) = refracted(i, n, eta) else {
                        assert!(want_sin > 1.0, "eta {eta}, {deg}°: reflected below the critical angle");
                        continue;
                    };
                    assert!(want_sin <= 1.0 + 1e-12, "eta {eta}, {deg}°: passes beyond the critical angle");
                    assert!((t.length() - 1.0).abs() < 1e-12);
                    assert!((t.dot(tangent) - want_sin).abs() < 1e-12, "eta {eta}, {deg}°: {t:?}");
                    assert!(t.dot(n) < 0.0 && t.dot(i.cross(n)).abs() < 1e-12);
                    // The same with the normal the other way round.
                    assert!((refracted(i, -n, eta).unwrap() - t).length() < 1e-12);
                    if eta < 1.0 {
                        let out = refracted(t, n, 1.0 / eta).expect("leaves the slab: the reverse path");
                        assert!((out - i).length() < 1e-12, "{out:?} vs {i:?}");
                    }
                }
            }
        }
    }

    /// A transparent pane (no colour of its own, `Kt` = 1, filter `Tf`) in front of the plane,
    /// under ambient light only: with refraction each pixel of the pane shows the plane behind
    /// it through the filter (`Tf` ⊙ `Ka` ⊙ ambient, the view at normal incidence going
    /// straight on); without, the pane is black. The plane around it is the same either way.
    #[test]
    fn a_glass_pane_shows_what_is_behind_through_its_filter() {
        let mut mesh = plane_mesh(false);
        add_front_quad(&mut mesh, 1);
        let tf = [0.5, 1.0, 0.25];
        mesh.materials[1] = Material { kt: 1.0, tf, ni: 1.5, ..mat([0.0; 3], [0.0; 3], [0.0; 3], 1.0, [0.0; 3]) };
        let plane = &mesh.materials[0];
        let through = [0, 1, 2].map(|c| gamma(f64::from(tf[c]) * f64::from(plane.ka[c]) * AMB[c]));
        let around = [0, 1, 2].map(|c| gamma(f64::from(plane.ka[c]) * AMB[c]));
        assert!(through != around && through != [0; 3]);
        for refract in [true, false] {
            let r = RefReflect { depth: 2, threshold: 0.0, refract };
            let img = render_reference_reflect(&mesh, &FIT, N, &[], AMB, &r).unwrap();
            let mut seen = 0;
            for y in 11..=30 {
                for x in 11..=20 {
                    let i = img.index(x, y);
                    assert_eq!(img.facet[i], 1, "({x}, {y})");
                    let want = if refract { through } else { [0; 3] };
                    assert!(
                        (0..3).all(|c| img.rgb[i][c].abs_diff(want[c]) <= 1),
                        "({x}, {y}): {:?} vs {want:?}",
                        img.rgb[i]
                    );
                    seen += 1;
                }
            }
            assert_eq!(seen, 200);
            let i = img.index(40, 40);
            assert_eq!((img.facet[i], img.rgb[i]), (0, around));
        }
    }

    #[test]
    fn shade_f64_closed_forms() {
        let m = mat([0.2, 0.4, 0.6], [0.5, 0.3, 0.1], [0.25, 0.5, 0.125], 10.0, [0.0; 3]);
        let nrm = [0.0, 0.0, -1.0];
        let amb = [0.1, 0.2, 0.3];
        // Light straight in front: N·L = 1, N·H = 1.
        let l = [RefLight { pos: [0.0, 0.0, -10.0], color: [1.0, 0.5, 0.25] }];
        let lin = shade_linear_f64([0.0; 3], nrm, &m, &l, 1, amb);
        let want = [0, 1, 2].map(|i| m.ka[i] as f64 * amb[i] + (m.kd[i] as f64 + m.ks[i] as f64) * l[0].color[i]);
        for i in 0..3 {
            assert!((lin[i] - want[i]).abs() < 1e-12);
        }
        // Light at 45°: N·L = cos 45°, H halfway between L and V: N·H = cos 22.5°.
        let l = [RefLight { pos: [5.0, 3.0, -7.0], color: [1.0, 0.5, 0.25] }];
        let p = [1.0, 3.0, -3.0];
        let lin = shade_linear_f64(p, nrm, &m, &l, 1, amb);
        let (c45, c22) = (std::f64::consts::FRAC_1_SQRT_2, (std::f64::consts::PI / 8.0).cos());
        let want = [0, 1, 2]
            .map(|i| m.ka[i] as f64 * amb[i] + l[0].color[i] * (m.kd[i] as f64 * c45 + m.ks[i] as f64 * c22.powi(10)));
        for i in 0..3 {
            assert!((lin[i] - want[i]).abs() < 1e-12, "{lin:?} vs {want:?}");
        }
        assert_eq!(shade_f64(p, nrm, &m, &l, 1, amb), want.map(gamma));
        // Not lit / behind the surface: ambient only.
        let ambient_only = [0, 1, 2].map(|i| gamma(m.ka[i] as f64 * amb[i]));
        assert_eq!(shade_f64(p, nrm, &m, &l, 0, amb), ambient_only);
        let behind = [RefLight { pos: [1.0, 3.0, 2.0], color: [1.0; 3] }];
        assert_eq!(shade_f64(p, nrm, &m, &behind, 1, amb), ambient_only);
        // Light at the point itself: no contribution, no NaN.
        let at = [RefLight { pos: p, color: [1.0; 3] }];
        assert_eq!(shade_f64(p, nrm, &m, &at, 1, amb), ambient_only);
        // Clamping and gamma.
        let bright = [RefLight { pos: [0.0, 0.0, -10.0], color: [9.0; 3] }];
        assert_eq!(shade_f64([0.0; 3], nrm, &m, &bright, 1, amb), [255; 3]);
        assert_eq!(encode_gamma(0.0), 0);
        assert_eq!(encode_gamma(-1.0), 0);
        assert_eq!(encode_gamma(f64::NAN), 0);
        assert_eq!(encode_gamma(0.5), 186);
        // Emitter: ke / max(ke), lights ignored.
        let e = mat([1.0; 3], [1.0; 3], [1.0; 3], 1.0, [4.0, 2.0, 1.0]);
        assert_eq!(shade_f64([0.0; 3], nrm, &e, &bright, 1, amb), [255, gamma(0.5), gamma(0.25)]);
    }

    #[test]
    fn bad_input_is_an_error() {
        let mesh = plane_mesh(false);
        assert!(render_reference(&mesh, &FIT, 0, &[], AMB).is_err());
        assert!(render_reference(&mesh, &FIT, 8, &[LIGHT; 33], AMB).is_err());
        assert!(render_reference(&mesh, &Fit { origin: [0.0; 3], voxel: 0.0 }, 8, &[], AMB).is_err());
        let mut bad = mesh.clone();
        bad.faces[0].material = 5;
        assert!(render_reference(&bad, &FIT, 8, &[], AMB).is_err());
        let mut bad = mesh.clone();
        bad.faces[0].verts[1] = 99;
        assert!(render_reference(&bad, &FIT, 8, &[], AMB).is_err());
        assert!(render_reference(&Mesh::default(), &FIT, 8, &[], AMB).is_err());
    }

    #[test]
    fn rows_top_down_flips_y() {
        let img = RefImage {
            n: 2,
            rgb: vec![[1; 3], [2; 3], [3; 3], [4; 3]],
            covered: vec![true; 4],
            lit: vec![0; 4],
            lights: 1,
            facet: vec![0; 4],
        };
        assert_eq!(img.rows_top_down(), vec![[3; 3], [4; 3], [1; 3], [2; 3]]);
    }

    /// The footprint weights against the shadow's area: a light 70 voxels below the occluder
    /// and 87.5 below the plane (off to one side, so that the shadow falls clear of the
    /// occluder's own image) casts a shadow 1.25 times its size (area 1.25² × 64 = 100 square
    /// voxels, a pixel being one); the pixels' shadowed shares (1 − weight) add up to it within
    /// the sampling's error along the shadow's 46-voxel edge, weights are multiples of 1/64,
    /// and the edge's pixels are fractional. Majority weights are 0 or 1, and 1 exactly where
    /// the share is above ½.
    #[test]
    fn footprint_weights_add_up_to_the_shadow_area() {
        let mesh = plane_mesh(true);
        let light = RefLight { pos: [32.0, 110.0, -47.5], ..LIGHT };
        let scene = RefScene::new(&mesh, &FIT, N, &[light], RefAmbient::Constant(AMB), &RefReflect::NONE).unwrap();
        let ratio = RefFootprint { samples: 8, majority: false };
        let majority = RefFootprint { majority: true, ..ratio };
        let (mut shadow, mut fractional) = (0.0, 0);
        for y in 0..N {
            for x in 0..N {
                let (o, d) = scene.primary(x as f64 + 0.5, y as f64 + 0.5, N);
                let Some((t, facet, nrm)) = scene.reference.first_hit(o.to_array(), d.to_array(), scene.primary_t, &[])
                else {
                    continue;
                };
                if facet != 0 {
                    continue;
                }
                let centre = (o + t * d, Vector::from(nrm), facet);
                let w = scene.footprint_weights(ratio, (x, y, N), centre)[0];
                assert_eq!((w * 64.0).round(), w * 64.0, "({x}, {y}): {w}");
                shadow += 1.0 - w;
                fractional += (w > 0.0 && w < 1.0) as u32;
                let m = scene.footprint_weights(majority, (x, y, N), centre)[0];
                assert_eq!(m, (w > 0.5) as u8 as f64, "({x}, {y})");
            }
        }
        assert!((shadow - 100.0).abs() < 2.0, "shadowed area {shadow}, 100 expected");
        assert!(fractional > 30, "{fractional} fractional pixels along a 46-voxel edge");
    }
}

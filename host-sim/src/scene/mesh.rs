//! Meshes: the polygons, materials and lights of a scene, and the OBJ/MTL reader (through `tobj`).
//!
//! A [`Mesh`] keeps the polygons as the file gives them (no triangulation here: the host
//! precompute keeps planar convex polygons and splits the rest) with world coordinates in
//! `f64` and one material per face — wound consistently, closed surfaces outward
//! ([`crate::scene::meshops::orient`]: the lit rule reads the winding).

use anyhow::{bail, Result};
use std::io::BufReader;
use std::path::Path;

/// A surface material (Phong/Blinn parameters, from the MTL file or defaults).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Material {
    /// Name in the MTL file.
    pub name: String,
    /// Ambient reflectance `Ka`.
    pub ka: [f32; 3],
    /// Diffuse reflectance `Kd`.
    pub kd: [f32; 3],
    /// Specular reflectance `Ks`.
    pub ks: [f32; 3],
    /// Specular exponent `Ns`.
    pub ns: f32,
    /// Emitted radiance `Ke` (light sources).
    pub ke: [f32; 3],
    /// Mirror reflectance `Kr` in 0..1 (MTL keyword `Kr`, one value; 0: not reflective). A
    /// reflective surface adds `Kr` × the intensity its reflected ray brings back (§5.5.5).
    pub kr: f32,
    /// Index of refraction `Ni`, in (0, 4] (1: vacuum, the default; glass 1.5). The refracted
    /// branch's direction is `cell_core::refract`'s; `render --reflections D` traces refracted
    /// rays through every material with `Kt > 0` (docs/REFLECTIONS.md).
    pub ni: f32,
    /// Transparency `Kt` in 0..1: `1 − d` (MTL `d`, dissolve), or `Tr` where a file gives that
    /// instead; 0, opaque, by default.
    pub kt: f32,
    /// Transmission filter `Tf` (the colour a transparent surface lets through); white by
    /// default.
    pub tf: [f32; 3],
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            ka: [0.1; 3],
            kd: [0.7; 3],
            ks: [0.0; 3],
            ns: 1.0,
            ke: [0.0; 3],
            kr: 0.0,
            ni: 1.0,
            kt: 0.0,
            tf: [1.0; 3],
        }
    }
}

/// One polygon: vertex indices into [`Mesh::positions`] and a material index.
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// Indices of the polygon's vertices, in order.
    pub verts: Vec<u32>,
    /// Index into [`Mesh::materials`].
    pub material: u16,
}

/// Where a light (or one of its samples) is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightAt {
    /// At a world position; moved along −y to the first empty voxel if it falls in an occupied
    /// one (a ceiling light sits on the ceiling's voxels).
    World([f64; 3]),
    /// At grid-normalised coordinates (0..1 on each axis).
    Grid([f64; 3]),
}

impl LightAt {
    /// The position, in the light's own units (world or grid-normalised).
    pub const fn point(self) -> [f64; 3] {
        match self {
            LightAt::World(p) | LightAt::Grid(p) => p,
        }
    }

    /// The same kind of position at `p`.
    const fn with_point(self, p: [f64; 3]) -> LightAt {
        match self {
            LightAt::World(_) => LightAt::World(p),
            LightAt::Grid(_) => LightAt::Grid(p),
        }
    }
}

/// A light a scene carries: a point, or a horizontal rectangle facing down (−y, a ceiling
/// lamp) centred on its point, which `--area-light S` samples by S × S point sources
/// ([`SceneLight::samples`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneLight {
    /// Its centre.
    pub at: LightAt,
    /// The rectangle's width along x and depth along z, in the units of `at`; `None`: a point.
    pub size: Option<[f64; 2]>,
}

impl SceneLight {
    /// A point light at a world position.
    pub const fn world(p: [f64; 3]) -> SceneLight {
        SceneLight { at: LightAt::World(p), size: None }
    }

    /// A point light at grid-normalised coordinates.
    pub const fn grid(t: [f64; 3]) -> SceneLight {
        SceneLight { at: LightAt::Grid(t), size: None }
    }

    /// The same light as a rectangle `size` = [along x, along z] wide, facing −y.
    pub const fn sized(self, size: [f64; 2]) -> SceneLight {
        SceneLight { size: Some(size), ..self }
    }

    /// The point sources that sample it `s` × `s`: the centres of the cells of a regular
    /// `s` × `s` grid over its rectangle (row-major: z outer, x inner), each of which carries
    /// 1/(number of samples) of its intensity. A point light, or `s` = 1, is its own one
    /// sample, at exactly its position.
    pub fn samples(&self, s: u32) -> Vec<LightAt> {
        let (Some([w, d]), true) = (self.size, s > 1) else {
            return vec![self.at];
        };
        let c = self.at.point();
        let offset = |i: u32, side: f64| ((f64::from(i) + 0.5) / f64::from(s) - 0.5) * side;
        (0..s)
            .flat_map(|k| (0..s).map(move |i| (i, k)))
            .map(|(i, k)| self.at.with_point([c[0] + offset(i, w), c[1], c[2] + offset(k, d)]))
            .collect()
    }
}

/// A polygon mesh in world coordinates.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Scene name (built-in name or file stem).
    pub name: String,
    /// Vertex positions (world units).
    pub positions: Vec<[f64; 3]>,
    /// Polygons.
    pub faces: Vec<Face>,
    /// Materials; index 0 exists always (the default material when the file has none).
    pub materials: Vec<Material>,
    /// The scene's own lights (built-ins); `--light` replaces them.
    pub lights: Vec<SceneLight>,
    /// Faces whose winding the loader reversed to make each surface consistent, closed ones
    /// outward ([`crate::scene::meshops::orient`]).
    pub rewound: usize,
    /// Set when the positions are in screen space ([`crate::scene::camera::to_screen`]): the
    /// camera, and the world positions they came from. `None`: world space, fitted into the grid.
    pub screen: Option<std::sync::Arc<super::view::Screen>>,
    /// The file's vertex normals (`vn`, world units, as written: checked where smooth shading
    /// uses them, [`crate::scene::normals`]).
    pub normals: Vec<[f64; 3]>,
    /// Per face, the index into [`Mesh::normals`] of each corner's normal (`f v//vn`), in the
    /// face's vertex order; empty (or missing: faces added after loading) for a face without.
    pub face_normals: Vec<Vec<u32>>,
}

/// The numbers of MTL keyword `key` (an unknown one to tobj), if the material has it.
fn mtl_numbers(m: &tobj::Material, key: &str) -> Option<Result<Vec<f32>>> {
    let text = m.unknown_param.get(key)?;
    Some(
        text.split_whitespace()
            .map(|t| t.parse::<f32>().map_err(|_| anyhow::anyhow!("material {}: {key} {text}: not a number", m.name)))
            .collect(),
    )
}

/// What a material lets through: `Ni`, `Kt` (from `d` or `Tr`) and `Tf`, each checked: an
/// index outside (0, 4] (the refraction's bit budget, `cell_core::refract`; `Ni 0`, which
/// exporters write for none, is the default 1), a transparency outside 0..1 or a filter that
/// is not three numbers in 0..1 is refused, naming the material.
fn transmission(m: &tobj::Material) -> Result<(f32, f32, [f32; 3])> {
    let d = Material::default();
    let ni = match m.optical_density {
        // Exporters write `Ni 0` for a material that sets none.
        None | Some(0.0) => d.ni,
        Some(n) if n.is_finite() && n > 0.0 && n <= 4.0 => n as f32,
        Some(n) => bail!("material {}: Ni {n}: an index of refraction is in (0, 4]", m.name),
    };
    let unit = |what: &str, v: f32| -> Result<f32> {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            bail!("material {}: {what} {v}: outside 0..1", m.name)
        }
    };
    let kt = match (m.dissolve, mtl_numbers(m, "Tr")) {
        (Some(dissolve), _) => 1.0 - unit("d", dissolve as f32)?,
        (None, Some(tr)) => match tr?[..] {
            [t] => unit("Tr", t)?,
            _ => bail!("material {}: Tr takes one number", m.name),
        },
        (None, None) => d.kt,
    };
    let tf = match mtl_numbers(m, "Tf") {
        None => d.tf,
        Some(v) => match v?[..] {
            [r, g, b] => [unit("Tf", r)?, unit("Tf", g)?, unit("Tf", b)?],
            _ => bail!("material {}: Tf takes three numbers (spectral and CIE XYZ forms are not read)", m.name),
        },
    };
    Ok((ni, kt, tf))
}

fn convert_material(m: &tobj::Material) -> Result<Material> {
    let d = Material::default();
    let (ni, kt, tf) = transmission(m)?;
    let f = |v: Option<[f64; 3]>, dv: [f32; 3]| v.map(|c| c.map(|x| x as f32)).unwrap_or(dv);
    let ke = m
        .unknown_param
        .get("Ke")
        .and_then(|s| {
            let v: Vec<f32> = s.split_whitespace().filter_map(|t| t.parse().ok()).collect();
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        })
        .or(m.emissive.map(|c| c.map(|x| x as f32)))
        .unwrap_or(d.ke);
    Ok(Material {
        name: m.name.clone(),
        ka: f(m.ambient, d.ka),
        kd: f(m.diffuse, d.kd),
        ks: f(m.specular, d.ks),
        ns: m.shininess.map(|s| s as f32).unwrap_or(d.ns),
        ke,
        kr: m
            .unknown_param
            .get("Kr")
            .and_then(|s| s.split_whitespace().next()?.parse::<f32>().ok())
            .filter(|k| k.is_finite())
            .map_or(d.kr, |k| k.clamp(0.0, 1.0)),
        ni,
        kt,
        tf,
    })
}

/// Put a floor under a mesh as the camera sees it: the view looks along +z, so the floor is the
/// plane z = max z of the mesh (the camera looks down at it and the mesh rests on it), a square
/// twice the mesh's footprint, grey, facing the camera; the light hangs in front of it, up and
/// to the left (grid-normalised (0.25, 0.8, 0.1)), so the mesh casts a visible shadow.
pub fn add_floor(mesh: &mut Mesh) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    if !lo[0].is_finite() {
        return;
    }
    let c = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let r = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let z = hi[2];
    let base = mesh.positions.len() as u32;
    // Wound so that its normal points toward the camera (−z).
    for (dx, dy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)] {
        mesh.positions.push([c[0] + dx * r, c[1] + dy * r, z]);
    }
    mesh.materials.push(Material { name: "floor".into(), kd: [0.6, 0.6, 0.55], ..Material::default() });
    let material = (mesh.materials.len() - 1) as u16;
    mesh.faces.push(Face { verts: vec![base, base + 1, base + 2, base + 3], material });
    mesh.lights = vec![SceneLight::grid([0.25, 0.8, 0.1])];
}

/// OBJ bytes as text: invalid UTF-8 is refused (binary junk, wrong format).
pub(super) fn obj_text<'a>(what: &str, bytes: &'a [u8]) -> Result<&'a str> {
    std::str::from_utf8(bytes)
        .map_err(|e| anyhow::anyhow!("{what}: not a text OBJ file (invalid UTF-8 at byte {})", e.valid_up_to()))
}

/// Load a scene from OBJ bytes and optional MTL bytes (every `mtllib` resolves to them): the
/// file-free entry point of [`crate::scene::load`], used by the fuzzer.
pub fn load_obj_bytes(name: &str, obj: &[u8], mtl: Option<&[u8]>) -> Result<Mesh> {
    let text = obj_text(name, obj)?;
    parse_obj(name, text, |_| match mtl {
        Some(m) => load_mtl_bytes(&format!("{name} (MTL)"), m),
        None => Err(tobj::LoadError::OpenFileFailed),
    })
}

/// Parse MTL bytes with tobj, refusing first what tobj 4.0.5 would panic on: a colour
/// statement (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three numbers (found by the `obj_load`
/// fuzz target; regression input `fuzz/regressions/obj_load/crash-short-ke`). The refusal is a
/// warning naming the line; the scene then uses the default material, like any unreadable MTL.
pub(super) fn load_mtl_bytes(what: &str, bytes: &[u8]) -> tobj::MTLLoadResult {
    if let Some((line, key, k)) = short_colour(bytes) {
        eprintln!("warning: {what}: line {line}: '{key}' needs 3 numbers, found {k}");
        return Err(tobj::LoadError::MaterialParseError);
    }
    tobj::load_mtl_buf(&mut BufReader::new(bytes))
}

/// The first colour statement with fewer than three values: (line, keyword, values). tobj reads
/// lines as UTF-8 (lossily, as we do here) and splits on whitespace.
fn short_colour(bytes: &[u8]) -> Option<(usize, String, usize)> {
    String::from_utf8_lossy(bytes).lines().enumerate().find_map(|(i, l)| {
        let mut t = l.split_whitespace();
        let key = t.next()?;
        let k = t.take(3).count();
        (matches!(key, "Ka" | "Kd" | "Ks" | "Ke") && k < 3).then(|| (i + 1, key.to_string(), k))
    })
}

/// A face statement with fewer than three vertices (tobj would take it for a line and drop
/// it silently): its line number and vertex count.
fn short_face(text: &str) -> Option<(usize, usize)> {
    text.lines().enumerate().find_map(|(i, l)| {
        let mut t = l.split_whitespace();
        (t.next() == Some("f")).then(|| t.count()).filter(|&k| k < 3).map(|k| (i + 1, k))
    })
}

/// Parse OBJ text. `mtl_loader` resolves `mtllib` references.
pub fn parse_obj<ML>(name: &str, text: &str, mtl_loader: ML) -> Result<Mesh>
where
    ML: Fn(&Path) -> tobj::MTLLoadResult,
{
    if let Some((line, k)) = short_face(text) {
        bail!("{name}: line {line}: a face needs at least 3 vertices, this one has {k}");
    }
    let opts = tobj::LoadOptions { triangulate: false, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, mats) = tobj::load_obj_buf(&mut BufReader::new(text.as_bytes()), &opts, mtl_loader)
        .map_err(|e| anyhow::anyhow!("{name}: malformed OBJ ({e})"))?;
    let mut materials = vec![Material::default()];
    match mats {
        Ok(ms) => {
            for m in &ms {
                materials.push(convert_material(m).map_err(|e| anyhow::anyhow!("{name}: {e}"))?);
            }
        }
        Err(e) => {
            if text.lines().any(|l| l.trim_start().starts_with("mtllib")) {
                eprintln!("warning: {name}: material library not loaded ({e}); using the default material");
            }
        }
    }
    if materials.len() > u16::MAX as usize {
        bail!("{name}: {} materials, at most {} supported", materials.len(), u16::MAX);
    }
    let mut mesh = Mesh { name: name.to_string(), materials, ..Default::default() };
    for model in &models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 {
            bail!("{name}: malformed vertex data in object '{}'", model.name);
        }
        let base = mesh.positions.len();
        if base + m.positions.len() / 3 > u32::MAX as usize {
            bail!("{name}: too many vertices");
        }
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        let nbase = mesh.normals.len() as u32;
        mesh.normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        // tobj gives a normal index per corner (parallel to the vertex indices) or none.
        let has_normals = m.normal_indices.len() == m.indices.len();
        let material = m.material_id.map(|i| i + 1).unwrap_or(0);
        let material = if material < mesh.materials.len() { material as u16 } else { 0 };
        let nverts = m.positions.len() / 3;
        let mut push = |at: usize, idx: &[u32]| -> Result<()> {
            if let Some(&bad) = idx.iter().find(|&&i| i as usize >= nverts) {
                bail!("{name}: face refers to vertex {} but object '{}' has {} vertices", bad + 1, model.name, nverts);
            }
            mesh.faces.push(Face { verts: idx.iter().map(|&i| (i as usize + base) as u32).collect(), material });
            let corners = if has_normals { &m.normal_indices[at..at + idx.len()] } else { &[] };
            mesh.face_normals.push(corners.iter().map(|&i| nbase.saturating_add(i)).collect());
            Ok(())
        };
        if m.face_arities.is_empty() {
            if m.indices.len() % 3 != 0 {
                bail!("{name}: malformed face data in object '{}'", model.name);
            }
            for (t, tri) in m.indices.chunks_exact(3).enumerate() {
                push(3 * t, tri)?;
            }
        } else {
            let mut at = 0usize;
            for &k in &m.face_arities {
                let k = k as usize;
                let Some(idx) = m.indices.get(at..at + k) else {
                    bail!("{name}: malformed face data in object '{}'", model.name);
                };
                push(at, idx)?;
                at += k;
            }
        }
    }
    let o = crate::scene::meshops::orient(&mut mesh);
    if o.rewound > 0 {
        // The plane lit rule reads a facet's winding as its outer side (docs/LIGHTING.md).
        eprintln!(
            "note: {name}: {} of {} faces rewound to agree with their neighbours ({} of {} surfaces closed, turned outward)",
            o.rewound,
            mesh.faces.len(),
            o.closed,
            o.components
        );
    }
    mesh.rewound = o.rewound;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::{load, BUILTINS};

    #[test]
    fn short_colour_lines_in_mtl_are_refused_not_panicked_on() {
        // tobj 4.0.5 unwraps a short colour statement; each keyword, 0..=2 values.
        for key in ["Ka", "Kd", "Ks", "Ke"] {
            for vals in ["", " 0.5", " 0.5 0.5"] {
                let mtl = format!("newmtl red\nKd 1 0 0\n{key}{vals}\n");
                let obj = b"mtllib x.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
                let m = load_obj_bytes("t", obj, Some(mtl.as_bytes())).expect("the OBJ itself is fine");
                assert_eq!(m.materials.len(), 1, "{key}{vals}: the MTL is refused, default material");
            }
        }
        assert_eq!(short_colour(b"Kd 1 2 3\n  Ks 1\n"), Some((2, "Ks".into(), 1)));
        assert_eq!(short_colour(b"Kd 1 2 3\nKsx 1\n"), None);
    }

    /// MTL's transmission keywords: `Ni`, `d` (or `Tr`) and `Tf` read into the material;
    /// values outside their ranges refused with the material's name, never clamped.
    #[test]
    fn transmission_keywords_are_read_and_checked() {
        let obj = b"mtllib x.mtl\nusemtl glass\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let load = |mtl: &str| load_obj_bytes("t", obj, Some(format!("newmtl glass\nKd 1 1 1\n{mtl}").as_bytes()));
        let glass = |mtl: &str| load(mtl).unwrap().materials.pop().unwrap();
        let m = glass("Ni 1.5\nd 0.25\nTf 0.9 0.8 0.7\n");
        assert_eq!((m.ni, m.kt, m.tf), (1.5, 0.75, [0.9, 0.8, 0.7]));
        let m = glass("Tr 0.4\n");
        assert_eq!((m.ni, m.kt, m.tf), (1.0, 0.4, [1.0; 3]));
        // d wins over Tr (files that carry both mean the same by them).
        assert_eq!(glass("d 1\nTr 0.3\n").kt, 0.0);
        let plain = glass("");
        assert_eq!((plain.ni, plain.kt, plain.tf), (1.0, 0.0, [1.0; 3]));
        assert_eq!(glass("Ni 0\n").ni, 1.0, "exporters' Ni 0: none set");
        for (bad, why) in [
            ("Ni -1\n", "Ni -1"),
            ("Ni 5\n", "Ni 5"),
            ("Ni nan\n", "Ni NaN"),
            ("d 1.5\n", "d 1.5"),
            ("Tr -0.1\n", "Tr -0.1"),
            ("Tr 0.1 0.2\n", "Tr takes one number"),
            ("Tf 0.9 0.8\n", "Tf takes three numbers"),
            ("Tf 0.9 x 0.7\n", "not a number"),
            ("Tf 0.9 2 0.7\n", "Tf 2"),
        ] {
            let err = load(bad).expect_err(bad).to_string();
            assert!(err.contains("material glass") && err.contains(why), "{bad}: {err}");
        }
    }

    #[test]
    fn builtins_load() {
        for (name, _) in BUILTINS {
            let m = load(name).unwrap();
            assert_eq!(m.faces.is_empty(), *name == "empty", "{name}");
            assert!(!m.lights.is_empty(), "{name} carries a light");
        }
        let c = load("cornell").unwrap();
        // 5 walls + light + 2 blocks × 5 faces.
        assert_eq!(c.faces.len(), 16);
        assert!(c.materials.iter().any(|m| m.name == "red" && m.kd[0] > m.kd[1]));
    }

    #[test]
    fn bad_index_is_an_error_not_a_panic() {
        let r = parse_obj("t", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", |_| Err(tobj::LoadError::OpenFileFailed));
        assert!(r.is_err());
        let r = parse_obj("t", "v 0 0 0\nf 1 2 x\n", |_| Err(tobj::LoadError::OpenFileFailed));
        assert!(r.is_err());
    }
}

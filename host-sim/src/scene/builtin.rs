//! The built-in scenes and the one entry point that loads a scene by name or path.

use anyhow::{bail, Context, Result};
use std::path::Path;

use super::mesh::{add_floor, load_mtl_bytes, obj_text, parse_obj, Material, Mesh, SceneLight};

/// Built-in scenes: name, one-line description.
pub const BUILTINS: &[(&str, &str)] = &[
    ("cornell", "the Cornell box (published geometry: 5 walls, ceiling light, two blocks)"),
    ("cornell-mirror", "the Cornell box with the tall block a mirror (Kr 0.85): for --reflections"),
    ("cornell-glass", "the Cornell box with the short block and a sphere of glass (Ni 1.5, Kt 0.9): for --reflections"),
    ("empty", "nothing: an empty grid with one light at the centre (the thesis's diffusion experiment)"),
    ("facet", "a single triangle in general position"),
    ("teapot", "Utah teapot, 6 320 triangles (open surface)"),
    ("cow", "cow, 5 804 triangles (closed)"),
    ("fandisk", "fandisk CAD part, 12 946 triangles (closed)"),
    ("suzanne", "Blender's Suzanne, 500 polygons (open)"),
    ("teapot-floor", "the teapot on a floor (the plane behind it, facing the camera), lit from the front"),
    ("cow-floor", "the cow on a floor (the plane behind it, facing the camera), lit from the front"),
    ("bureau1", "procedural office (thesis's Bureau1): desk, CRT, chair, bookshelf; 8 038 facets, 1 light"),
    (
        "bureau2",
        "procedural office for three (thesis's Bureau2): desks, meeting table, shelves; 17 289 facets, 2 lights",
    ),
    ("classe", "procedural classroom (thesis's Classe): 20 desks, 40 chairs, blackboard; 38 603 facets, 26 lights"),
];

/// The Cornell box's ceiling lamp as published: the quad x 213..343, z 227..332 at y = 548.8
/// (world units), facing down; its centre is the point light the box is lit by.
pub const CORNELL_LAMP: SceneLight = SceneLight::world([278.0, 548.8, 279.5]).sized([130.0, 105.0]);

const CORNELL_OBJ: &str = include_str!("../../scenes/cornell.obj");
const CORNELL_MTL: &str = include_str!("../../scenes/cornell.mtl");
const CORNELL_MIRROR_OBJ: &str = include_str!("../../scenes/cornell-mirror.obj");
const CORNELL_MIRROR_MTL: &str = include_str!("../../scenes/cornell-mirror.mtl");
const CORNELL_GLASS_OBJ: &str = include_str!("../../scenes/cornell-glass.obj");
const CORNELL_GLASS_MTL: &str = include_str!("../../scenes/cornell-glass.mtl");
const FACET_OBJ: &str = "# rc2 built-in: one triangle in general position\n\
v 0.10 0.20 0.30\nv 0.90 0.35 0.60\nv 0.40 0.85 0.15\nf 1 2 3\n";

fn builtin_source(name: &str) -> Option<(&'static str, Option<&'static str>)> {
    Some(match name {
        "cornell" => (CORNELL_OBJ, Some(CORNELL_MTL)),
        "cornell-mirror" => (CORNELL_MIRROR_OBJ, Some(CORNELL_MIRROR_MTL)),
        "cornell-glass" => (CORNELL_GLASS_OBJ, Some(CORNELL_GLASS_MTL)),
        "facet" => (FACET_OBJ, None),
        "teapot" => (include_str!("../../scenes/teapot.obj"), None),
        "cow" => (include_str!("../../scenes/cow.obj"), None),
        "fandisk" => (include_str!("../../scenes/fandisk.obj"), None),
        "suzanne" => (include_str!("../../scenes/suzanne.obj"), None),
        _ => return None,
    })
}

/// Load a scene: a built-in name (see [`BUILTINS`]) or a path to an `.obj` file.
pub fn load(scene: &str) -> Result<Mesh> {
    if scene == "empty" {
        return Ok(Mesh {
            name: "empty".into(),
            materials: vec![Material::default()],
            lights: vec![SceneLight::grid([0.5; 3])],
            ..Default::default()
        });
    }
    if matches!(scene, "bureau1" | "bureau2" | "classe") {
        return super::office::generate(scene);
    }
    if let Some(base) = scene.strip_suffix("-floor").filter(|b| matches!(*b, "teapot" | "cow")) {
        let mut mesh = load(base)?;
        add_floor(&mut mesh);
        mesh.name = scene.to_string();
        return Ok(mesh);
    }
    if let Some((obj, mtl)) = builtin_source(scene) {
        let mut mesh = parse_obj(scene, obj, |_| match mtl {
            Some(m) => load_mtl_bytes(scene, m.as_bytes()),
            None => Err(tobj::LoadError::OpenFileFailed),
        })?;
        mesh.lights = match scene {
            // The published light quad, 213..343 × 227..332 at y = 548.8: a point at its centre,
            // and its extent for --area-light.
            "cornell" | "cornell-mirror" | "cornell-glass" => vec![CORNELL_LAMP],
            "facet" => vec![SceneLight::grid([0.5, 0.5, 0.05])],
            _ => vec![SceneLight::grid([0.5, 0.95, 0.05])],
        };
        return Ok(mesh);
    }
    let path = Path::new(scene);
    if !path.exists() {
        let names: Vec<_> = BUILTINS.iter().map(|b| b.0).collect();
        bail!("scene '{scene}' is neither a file nor a built-in scene (built-ins: {})", names.join(", "));
    }
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let text = obj_text(&path.display().to_string(), &bytes)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mesh = parse_obj(&name, text, |mtl| {
        let path = dir.join(mtl);
        let bytes = std::fs::read(&path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        load_mtl_bytes(&path.display().to_string(), &bytes)
    })?;
    if mesh.faces.is_empty() {
        bail!("{name}: the mesh has no faces: nothing to load (only the built-in 'empty' scene may be empty)");
    }
    Ok(mesh)
}

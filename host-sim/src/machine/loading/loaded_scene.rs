//! A scene loaded into the grid: the voxelized cells, the world ↔ grid mapping, where its lights are.

use anyhow::{bail, Result};
use cell_core::cell::DEFAULT_DEXELS;
use cell_core::shade::Eye;

use crate::machine::grid::LightGrid;

use crate::machine::grid::Grid;
use crate::precompute::{Fit, LoadConfig};
use crate::scene::{LightAt, Mesh, SceneLight};

/// A loaded scene: its grid and the world ↔ grid mapping.
pub struct LoadedScene {
    /// The voxelized grid.
    pub grid: LightGrid,
    /// World ↔ grid mapping (unit cube for the empty scene).
    pub fit: Fit,
    /// Facets loaded.
    pub facets: usize,
    /// Loading cycles.
    pub load_cycles: u64,
    /// Source face of each facet id (packet order).
    pub source_face: Vec<u32>,
    /// Where the eye is: the grid's own view, or the camera the scene was seen through.
    pub eye: Eye,
}

/// Voxelize a scene with the wave (an empty scene gives an empty grid).
pub fn load_scene(mesh: &Mesh, cfg: &LoadConfig) -> Result<LoadedScene> {
    load_scene_tapped(mesh, cfg, None)
}

/// [`load_scene`], recording the cells watched by `tap`.
pub fn load_scene_tapped(
    mesh: &Mesh,
    cfg: &LoadConfig,
    tap: Option<&mut crate::machine::links::tap::Tap>,
) -> Result<LoadedScene> {
    cfg.validate()?;
    if mesh.faces.is_empty() {
        crate::machine::grid::limits::check_grid_memory(
            "grid of loading cells",
            cfg.n,
            std::mem::size_of::<cell_core::cell::Cell<DEFAULT_DEXELS>>(),
        )?;
        let fit = Fit { origin: [0.0; 3], voxel: 1.0 / cfg.n as f64 };
        return Ok(LoadedScene {
            grid: Grid::new(cfg.n, cfg.n),
            fit,
            facets: 0,
            load_cycles: 0,
            source_face: Vec::new(),
            eye: Eye::Grid,
        });
    }
    let v = crate::machine::loading::engines::voxelize_tapped::<DEFAULT_DEXELS>(
        mesh,
        cfg,
        crate::machine::loading::engines::Engine::Wave,
        tap,
        |_, _| {},
    )?;
    v.check_overflow()?;
    Ok(LoadedScene {
        facets: v.stats.facets,
        load_cycles: v.stats.load_cycles,
        fit: v.prepared.fit.expect("fitted"),
        source_face: v.prepared.source_face,
        grid: v.grid,
        eye: mesh.screen.as_ref().map_or(Eye::Grid, |s| Eye::Camera(s.view.cell_view(cfg.n))),
    })
}

/// World position of a voxel-unit point.
pub fn voxel_to_world(fit: &Fit, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| fit.origin[i] + (v[i] + 0.5) * fit.voxel)
}

/// World position of a voxel-unit point of a loaded scene: through [`voxel_to_world`] in the
/// fitted view, back through the camera (screen space, s = (v + ½)/n) when `mesh` is in screen
/// space.
pub fn grid_to_world(mesh: &Mesh, scene: &LoadedScene, v: [f64; 3]) -> [f64; 3] {
    match &mesh.screen {
        Some(s) => {
            let n = scene.grid.n as f64;
            s.view.from_view(s.view.screen_to_view(v.map(|c| (c + 0.5) / n)))
        }
        None => voxel_to_world(&scene.fit, v),
    }
}

/// Voxel-unit position of a world point (voxel centres at integers).
pub fn world_to_voxel(fit: &Fit, p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (p[i] - fit.origin[i]) / fit.voxel - 0.5)
}

/// Voxel-unit position of a grid-normalised point (0..1 spans the grid's faces).
pub fn normalised_to_voxel(t: [f64; 3], n: u32) -> [f64; 3] {
    t.map(|c| (c * n as f64 - 0.5).clamp(0.0, n as f64 - 1.0))
}

/// Where a scene without lights (an OBJ file) gets its light: above, in front, a little left.
pub const DEFAULT_LIGHT: [f64; 3] = [0.3, 0.95, 0.1];

/// The point sources a run diffuses from and shades with: every light's samples
/// ([`SceneLight::samples`]) in order, in voxel units, with the intensity (white) each carries.
#[derive(Clone, Debug, PartialEq)]
pub struct Sources {
    /// Positions in voxel units.
    pub positions: Vec<[f64; 3]>,
    /// Intensity of each: its light's 1/√(number of lights), divided among the light's samples.
    pub intensity: Vec<f32>,
    /// Index of the light each samples.
    pub light: Vec<usize>,
}

/// How a run's lights become point sources: `--light` (grid-normalised; empty: the scene's own),
/// their `--light-size`, and `--area-light` S.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSampling<'a> {
    /// `--light` positions, grid-normalised (empty: the scene's own lights).
    pub cli: &'a [[f64; 3]],
    /// `--light-size`: the `--light` lights' square side, grid-normalised.
    pub cli_size: Option<f64>,
    /// S: each light with an extent is sampled by S × S point sources.
    pub area: u32,
}

/// Light positions in voxel units: `--light` values (normalised, validated) if any, else the
/// scene's own lights; each light one source at its centre.
pub fn resolve_lights(mesh: &Mesh, scene: &LoadedScene, cli: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
    let sampling = LightSampling { cli, cli_size: None, area: 1 };
    Ok(resolve_sources(mesh, scene, &sampling)?.positions)
}

/// The lights of a run ([`LightSampling`]): the `--light` ones (validated, with their size) if
/// any, else the scene's own (a default light if it has none).
pub fn run_lights(mesh: &Mesh, sampling: &LightSampling<'_>) -> Result<Vec<SceneLight>> {
    if sampling.area == 0 {
        bail!("--area-light 0: S is the number of samples along each side of a light, at least 1");
    }
    if let Some(w) = sampling.cli_size {
        if sampling.cli.is_empty() {
            bail!("--light-size gives the --light lights an extent: add --light X,Y,Z");
        }
        if !w.is_finite() || w <= 0.0 || w > 1.0 {
            bail!("--light-size {w}: the lamp's side is grid-normalised, 0 < W <= 1");
        }
    }
    if !sampling.cli.is_empty() {
        return sampling
            .cli
            .iter()
            .enumerate()
            .map(|(i, t)| {
                if t.iter().any(|c| !c.is_finite() || *c < 0.0 || *c > 1.0) {
                    bail!("--light {} = {:?} is outside the grid: coordinates are grid-normalised, 0 ..= 1", i + 1, t);
                }
                let light = SceneLight::grid(*t);
                let Some(w) = sampling.cli_size else { return Ok(light) };
                let light = light.sized([w, w]);
                let outside = |c: f64| c - w / 2.0 < 0.0 || c + w / 2.0 > 1.0;
                if outside(t[0]) || outside(t[2]) {
                    bail!(
                        "--light {} = {:?} with --light-size {w}: the lamp reaches outside the grid (0 ..= 1 along x and z)",
                        i + 1,
                        t
                    );
                }
                Ok(light)
            })
            .collect();
    }
    if mesh.lights.is_empty() {
        eprintln!(
            "note: scene '{}' has no lights; using one at grid-normalised {:?} (give your own with --light X,Y,Z)",
            mesh.name, DEFAULT_LIGHT
        );
        return Ok(vec![SceneLight::grid(DEFAULT_LIGHT)]);
    }
    Ok(mesh.lights.clone())
}

/// The point sources of a run: each light of [`run_lights`] sampled `sampling.area` squared
/// times if it has an extent, in voxel units, each sample with its share of the light's
/// intensity. More than the machine's [`cell_core::light::MAX_SOURCES`] sources under
/// `--area-light` is an error.
pub fn resolve_sources(mesh: &Mesh, scene: &LoadedScene, sampling: &LightSampling<'_>) -> Result<Sources> {
    let lights = run_lights(mesh, sampling)?;
    let samples: Vec<Vec<LightAt>> = lights.iter().map(|l| l.samples(sampling.area)).collect();
    let count: usize = samples.iter().map(Vec::len).sum();
    if sampling.area > 1 && count > cell_core::light::MAX_SOURCES {
        let s = sampling.area;
        bail!(
            "--area-light {s}: {} light(s) sampled by {s} × {s} points make {count} point sources; the machine \
             lights at most {} (one bit each in a cell's source mask): use a smaller S",
            lights.len(),
            cell_core::light::MAX_SOURCES
        );
    }
    let e = 1.0 / (lights.len().max(1) as f32).sqrt();
    let mut out = Sources { positions: Vec::new(), intensity: Vec::new(), light: Vec::new() };
    for (i, pts) in samples.iter().enumerate() {
        for &at in pts {
            out.positions.push(voxel_position(mesh, scene, at));
            out.intensity.push(e / pts.len() as f32);
            out.light.push(i);
        }
    }
    Ok(out)
}

/// A light's (or sample's) position in voxel units: a world one through the view, stepped
/// down (−y) out of the occupied voxels its lamp sits in.
fn voxel_position(mesh: &Mesh, scene: &LoadedScene, at: LightAt) -> [f64; 3] {
    let n = scene.grid.n;
    match at {
        LightAt::Grid(t) => normalised_to_voxel(t, n),
        LightAt::World(w) => {
            let w = mesh.screen.as_ref().map_or(w, |s| s.view.to_screen(w));
            let mut p = world_to_voxel(&scene.fit, w);
            // Step down (−y) out of the occupied voxels the light's own quad sits in.
            for _ in 0..n {
                let v = p.map(|c| (c + 0.5).floor());
                let inside = v.iter().all(|&c| c >= 0.0 && c < n as f64);
                if !inside || scene.grid.cell(v[0] as u32, v[1] as u32).store.occupied(v[2] as u16).is_none() {
                    break;
                }
                p[1] -= 1.0;
            }
            p
        }
    }
}

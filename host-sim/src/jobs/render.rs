//! The main job: load, light (beam diffusion or classic shadow rays), shade, reflect — the whole
//! RC² pipeline — and compare with the f64 reference.
//!
//! Every cell shades its pixel ([`crate::machine::shade`]): orthographic view along +z, image y
//! up, +x to the left as a camera looking along +z sees it. Lights are white, each of intensity
//! 1/√(number of lights), ambient 0.2. With `--reference` the same scene is ray-cast in f64
//! ([`crate::truth::refrender`]) with the same camera, resolution and shading formula, and
//! compared ([`crate::truth::compare`]).

use std::time::Instant;

use anyhow::Result;
use cell_core::beam::FracBits;
use cell_core::lit::LitRule;
use cell_core::shade::NormalMode;

use crate::machine::classic::{run_classic, ClassicConfig, ClassicCounts};
use crate::machine::diffuse::LightConfig;
use crate::machine::lighting::{run_diffusion, LightStats};
use crate::machine::loaded::LoadedScene;
use crate::machine::reflect::{reflect, ReflectConfig, ReflectCounts, ShadeEnv};
use crate::machine::shade::{point_lights, ref_lights, seen, shade_grid_with, Image, Seen, AMBIENT};
use crate::scene::Mesh;
use crate::truth::compare::psnr;

/// Everything `render --stats` reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderStats {
    /// The lighting run (load and light counters, bytes per cell).
    pub light: LightStats,
    /// Normal mode used for shading.
    pub normals: String,
    /// Shading step: one light per cell per cycle, all cells in parallel.
    pub shade_cycles: u64,
    /// Pixels showing a voxel.
    pub covered_pixels: u64,
    /// Covered pixels lit by at least one light.
    pub lit_pixels: u64,
    /// `size_of` a loading cell (dexel store with its compile-time capacity + inbound packet).
    pub bytes_per_cell_load: usize,
    /// Loading + lighting state of one cell.
    pub bytes_per_cell: usize,
    /// Cell shading against the same formula in f64, same inputs (8-bit levels).
    pub shading_max_err_levels: u8,
    /// Mean of that.
    pub shading_mean_err_levels: f64,
    /// Comparison with the continuous reference (with `--reference`).
    pub reference: Option<crate::truth::compare::Comparison>,
    /// Wall time: load, light, shade, reference.
    pub load_seconds: f64,
    /// Lighting wall time.
    pub light_seconds: f64,
    /// Shading wall time.
    pub shade_seconds: f64,
    /// Reference rendering wall time.
    pub reference_seconds: f64,
    /// All of it.
    pub wall_seconds: f64,
    /// Peak resident memory (MiB).
    pub peak_rss_mib: Option<f64>,
}

/// Render options.
#[derive(Clone, Copy, Debug)]
pub struct RenderConfig {
    /// Lighting.
    pub light: LightConfig,
    /// Normals.
    pub normals: NormalMode,
}

/// Ray-cast the f64 reference of a loaded scene with the same camera, resolution and lights.
pub fn reference_image(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
) -> Result<crate::truth::refrender::RefImage> {
    let rl = ref_lights(&point_lights(light_positions));
    crate::truth::refrender::render_reference(mesh, &scene.fit, scene.grid.n, &rl, [AMBIENT as f64; 3])
}

/// Outputs of a render.
pub struct Rendered {
    /// The machine's image.
    pub image: Image,
    /// Statistics.
    pub stats: RenderStats,
}

/// Light and shade a loaded scene; compare with `reference` when given (the time to make it is
/// `reference_seconds`).
#[allow(clippy::too_many_arguments)]
pub fn render<F: FracBits>(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
    cfg: &RenderConfig,
    reference: Option<&crate::truth::refrender::RefImage>,
    load_seconds: f64,
    reference_seconds: f64,
    progress: impl FnMut(usize, u64),
) -> Result<Rendered> {
    let t0 = Instant::now();
    let (lighting, lstats) = run_diffusion::<F>(mesh, scene, light_positions, &cfg.light, progress)?;
    let t1 = Instant::now();
    let times = [load_seconds, (t1 - t0).as_secs_f64(), reference_seconds];
    let rendered = finish_render(mesh, scene, light_positions, cfg, reference, &seen(&lighting), lstats, times);
    Ok(rendered)
}

/// Shade with the given lit state and assemble the statistics; `times` = load, light and
/// reference seconds.
#[allow(clippy::too_many_arguments)]
pub fn finish_render(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
    cfg: &RenderConfig,
    reference: Option<&crate::truth::refrender::RefImage>,
    seen: &Seen<'_>,
    lstats: LightStats,
    times: [f64; 3],
) -> Rendered {
    let [load_seconds, light_seconds, reference_seconds] = times;
    let t1 = Instant::now();
    let lights = point_lights(light_positions);
    let image = shade_grid_with(mesh, scene, &lights, seen, cfg.normals);
    let t2 = Instant::now();
    let cmp = reference.map(|r| crate::truth::compare::compare(&image.rgb, &image.covered, &image.lit, r));
    let load_cell = std::mem::size_of::<cell_core::cell::Cell<{ cell_core::cell::DEFAULT_DEXELS }>>()
        + std::mem::size_of::<cell_core::facet::RowPacket>();
    let stats = RenderStats {
        normals: match cfg.normals {
            NormalMode::Facet => "facet".into(),
            NormalMode::Face => "face".into(),
        },
        shade_cycles: light_positions.len().max(1) as u64,
        covered_pixels: image.covered.iter().filter(|&&c| c).count() as u64,
        lit_pixels: image.lit.iter().filter(|&&l| l != 0).count() as u64,
        bytes_per_cell_load: load_cell,
        bytes_per_cell: load_cell + lstats.bytes_light_cell,
        shading_max_err_levels: image.shading_max_err_levels,
        shading_mean_err_levels: image.shading_mean_err_levels,
        reference: cmp,
        load_seconds,
        light_seconds,
        shade_seconds: (t2 - t1).as_secs_f64(),
        reference_seconds,
        wall_seconds: load_seconds + light_seconds + (t2 - t1).as_secs_f64() + reference_seconds,
        peak_rss_mib: crate::machine::load::peak_rss_mib(),
        light: lstats,
    };
    Rendered { image, stats }
}

/// `render --lighting classic`: the classic phase, then the same shading and report as
/// diffusion ([`crate::jobs::render::finish_render`]).
#[allow(clippy::too_many_arguments)]
pub fn render_classic<F: FracBits>(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &crate::jobs::render::RenderConfig,
    classic_cfg: &ClassicConfig,
    reference: Option<&crate::truth::refrender::RefImage>,
    load_seconds: f64,
    reference_seconds: f64,
    progress: impl FnMut(usize, u64),
) -> Result<(crate::jobs::render::Rendered, ClassicCounts)> {
    let t0 = Instant::now();
    let (cl, stats) = run_classic::<F>(mesh, scene, lights, classic_cfg, progress)?;
    let times = [load_seconds, t0.elapsed().as_secs_f64(), reference_seconds];
    let r = crate::jobs::render::finish_render(
        mesh,
        scene,
        lights,
        cfg,
        reference,
        &match classic_cfg.rule {
            LitRule::Thesis => crate::machine::shade::Seen::FirstVoxel(Box::new(|x, y, _| cl.mask(x, y))),
            LitRule::Plane => crate::machine::shade::Seen::Surface(Box::new(|x, y| cl.mask(x, y))),
        },
        stats,
        times,
    );
    Ok((r, cl.totals))
}

/// `render --reflections D` (D ≥ 1): diffusion lighting, shading, then the reflection phase;
/// reflective visible voxels get `local + Kr · answer`, every other pixel is the plain render's.
/// Compared with `reference` when given (make it with [`reflect_reference_image`]).
#[allow(clippy::too_many_arguments)]
pub fn render_reflect<F: cell_core::beam::FracBits>(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
    cfg: &crate::jobs::render::RenderConfig,
    rcfg: &ReflectConfig,
    reference: Option<&crate::truth::refrender::RefImage>,
    times: [f64; 2],
    progress: impl FnMut(usize, u64),
) -> Result<(crate::jobs::render::Rendered, ReflectCounts)> {
    let t0 = std::time::Instant::now();
    let (lighting, lstats) =
        crate::machine::lighting::run_diffusion::<F>(mesh, scene, light_positions, &cfg.light, progress)?;
    let mask = |x, y, z| lighting.mask(x, y, z);
    let light_seconds = t0.elapsed().as_secs_f64();
    let mut r = crate::jobs::render::finish_render(
        mesh,
        scene,
        light_positions,
        cfg,
        None,
        &crate::machine::shade::seen(&lighting),
        lstats,
        [times[0], light_seconds, times[1]],
    );
    let t1 = std::time::Instant::now();
    let lights = crate::machine::shade::point_lights(light_positions);
    let env = ShadeEnv::new(mesh, &lights, cfg.normals, &mask);
    let refl = reflect(scene, &env, rcfg)?;
    let local_only = r.image.rgb.clone();
    for (px, v) in r.image.rgb.iter_mut().zip(&refl.rgb) {
        if let Some(v) = v {
            *px = *v;
        }
    }
    let mut counts = refl.counts;
    if let Some(rf) = reference {
        let mirror: Vec<bool> = rf
            .facet
            .iter()
            .map(|&f| mesh.faces.get(f as usize).is_some_and(|fc| mesh.materials[fc.material as usize].kr > 0.0))
            .collect();
        let all = vec![true; mirror.len()];
        counts.psnr_db = Some(psnr(&r.image.rgb, &rf.rgb, &all));
        counts.psnr_without_db = Some(psnr(&local_only, &rf.rgb, &all));
        counts.mirror_psnr_db = Some(psnr(&r.image.rgb, &rf.rgb, &mirror));
        counts.mirror_psnr_without_db = Some(psnr(&local_only, &rf.rgb, &mirror));
        counts.mirror_pixels = mirror.iter().filter(|&&m| m).count() as u64;
    }
    r.stats.shade_seconds += t1.elapsed().as_secs_f64();
    r.stats.wall_seconds += t1.elapsed().as_secs_f64();
    r.stats.reference =
        reference.map(|rf| crate::truth::compare::compare(&r.image.rgb, &r.image.covered, &r.image.lit, rf));
    Ok((r, counts))
}

/// The f64 reference with the same reflections (depth, threshold; exact normals and hits).
pub fn reflect_reference_image(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
    depth: u8,
    threshold: f32,
) -> Result<crate::truth::refrender::RefImage> {
    let rl = crate::jobs::render::ref_lights(&crate::machine::shade::point_lights(light_positions));
    let refl = crate::truth::refrender::RefReflect { depth: depth as u32, threshold: threshold as f64 };
    let ambient = [crate::machine::shade::AMBIENT as f64; 3];
    crate::truth::refrender::render_reference_reflect(mesh, &scene.fit, scene.grid.n, &rl, ambient, &refl)
}

/// The render statistics with the reflection counters added under `"reflections"`.
pub fn with_counts(stats: &crate::jobs::render::RenderStats, c: &ReflectCounts) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(stats)?;
    if let serde_json::Value::Object(m) = &mut v {
        m.insert("reflections".into(), serde_json::to_value(c)?);
    }
    Ok(v)
}

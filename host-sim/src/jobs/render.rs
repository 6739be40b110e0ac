//! The main job: load, light (beam diffusion or classic shadow rays), shade, reflect — the whole
//! RC² pipeline — and compare with the f64 reference.
//!
//! Every cell shades its pixel ([`crate::machine::shading::pixels`]): orthographic view along +z, image y
//! up, +x to the left as a camera looking along +z sees it. Lights are white, each of intensity
//! 1/√(number of lights) (shared by an area light's samples, `--area-light`), ambient 0.2. With a reference the same scene is ray-cast in f64
//! ([`crate::truth::refrender`]) with the same camera, resolution and shading formula, and
//! compared ([`crate::truth::compare`]).
//!
//! [`render`] is the one entry point of a render on a loaded scene ([`RenderConfig`] says how
//! it is lit); [`run`] is the `render` job around it: load, reference, render, write, summarise.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Result};
use cell_core::lit::LitRule;
use cell_core::shade::{NormalMode, PointLight};
use cell_core::smooth::Smooth;

use crate::config::RunSummary;
use crate::dist::run_diffusion;
use crate::jobs::light::{classic_description, print_link_faults, LightingOptions};
use crate::jobs::render_radiosity::{self, DisplayPsnr, F64Solution, RadiosityRenderStats, RenderRadiosity, TruthPsnr};
use crate::machine::lighting::diffuse::LightConfig;
use crate::machine::lighting::run::LightStats;
use crate::machine::loading::loaded_scene::{load_scene, resolve_sources, LoadedScene, Sources};
use crate::machine::rays::classic::{refine_edges, run_classic, ClassicConfig, ClassicCounts, RefineCounts};
use crate::machine::rays::mirror::{reflect, ReflectConfig, ReflectCounts, ShadeEnv};
use crate::machine::shading::pixels::{
    point_lights, ref_lights, seen, shade_grid_ambient, weighted_lights, Ambient, Image, Seen, AMBIENT,
};
use crate::machine::shading::samples::{sample_grid, shade_samples, CentreLights, SampleGrid, SampleStats};
use crate::machine::shading::smooth_surface::{smooth_grid, SmoothGrid, SmoothScene, SmoothStats};
use crate::machine::shooting::indirect::Display;
use crate::report::files::write_json;
use crate::report::png::write_png;
use crate::report::progress;
use crate::scene::{self, Mesh};
use crate::truth::compare::psnr;
use crate::truth::refrender::{RefFootprint, RefImage, RefReflect};
use cell_core::visibility::Visibility;

/// Everything `render --stats` reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderStats {
    /// What ran: the preset and its resolved settings (set by the `render` job).
    pub run: Option<RunSummary>,
    /// The view: "fitted" (the scene fitted into the grid, seen along +z) or the camera's.
    pub view: String,
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
    /// The stores a cell holds besides those for this run ([`crate::config::extra_cell_bytes`]):
    /// the column's triangle store under exact occluders, the occupancy summary under the
    /// frustum and hidden skips.
    pub bytes_per_cell_stores: usize,
    /// Loading + lighting state of one cell, with those stores.
    pub bytes_per_cell: usize,
    /// Cell shading against the same formula in f64, same inputs (8-bit levels).
    pub shading_max_err_levels: u8,
    /// Mean of that.
    pub shading_mean_err_levels: f64,
    /// Comparison with the continuous reference (with `--reference`; with `--radiosity`, the
    /// radiosity image against the reference shaded with the f64 solver's radiosity).
    pub reference: Option<crate::truth::compare::Comparison>,
    /// With `--radiosity`: the solution, its display and their costs.
    pub radiosity: Option<RadiosityRenderStats>,
    /// With `--lighting refined`: the shadow-edge refinement's counters (its cycles come after
    /// `light.cycles`).
    pub refine: Option<RefineCounts>,
    /// With `--normals gouraud|phong`: where the vertex normals came from and what they cost
    /// (absent otherwise, so that a facet render's statistics are unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smooth: Option<SmoothStats>,
    /// With `--samples S` (S > 1): what the samples cost and found (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<SampleStats>,
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

/// How a render computes the lit state.
#[derive(Clone, Copy, Debug)]
pub enum RenderLighting {
    /// Beam diffusion from each source (§4.3), with [`RenderConfig::light`].
    Diffusion,
    /// One classic shadow ray per visible voxel and source, answers routed back (§4.1.2).
    Classic(ClassicConfig),
    /// Beam diffusion, then shadow-edge refinement with these shadow rays
    /// ([`crate::machine::rays::classic::refine_edges`]).
    Refined(ClassicConfig),
    /// Beam diffusion, then the reflection phase (§5.2): reflective visible voxels get
    /// `local + Kr · answer`, every other pixel is the plain render's.
    Reflections(ReflectConfig),
}

/// How to render a loaded scene.
#[derive(Clone, Copy, Debug)]
pub struct RenderConfig {
    /// Diffusion settings (diffusion and reflections).
    pub light: LightConfig,
    /// Normals.
    pub normals: NormalMode,
    /// Smooth shading from the vertex normals (the input's [`RenderInput::smooth`] records);
    /// `None`: `normals` alone.
    pub smooth: Option<Smooth>,
    /// Samples per pixel side (1: the centre line alone; the input's [`RenderInput::samples`]
    /// records otherwise); the reference averages the same points.
    pub samples: u32,
    /// How the lit state is computed.
    pub lighting: RenderLighting,
}

impl RenderConfig {
    /// Diffusion lighting with `light`, shading with `normals`.
    pub fn diffusion(light: LightConfig, normals: NormalMode) -> RenderConfig {
        RenderConfig { light, normals, smooth: None, samples: 1, lighting: RenderLighting::Diffusion }
    }
}

/// What a render works on: a scene loaded on the grid, its lights, and optionally the reference
/// to compare with; the times spent making them go into the statistics.
#[derive(Clone, Copy)]
pub struct RenderInput<'a> {
    /// The scene.
    pub mesh: &'a Mesh,
    /// The scene loaded on the grid.
    pub scene: &'a LoadedScene,
    /// Light positions in voxel units ([`resolve_sources`]).
    pub lights: &'a [[f64; 3]],
    /// The intensity each light carries ([`Sources::intensity`]); `None`: 1/√(number of
    /// lights) each.
    pub intensity: Option<&'a [f32]>,
    /// The f64 reference to compare with ([`reference_image`]).
    pub reference: Option<&'a RefImage>,
    /// Wall time of the loading.
    pub load_seconds: f64,
    /// Wall time of the reference.
    pub reference_seconds: f64,
    /// Radiosity ([`crate::jobs::render_radiosity`]): per cell the indirect irradiance of its
    /// visible point, which the cells shade with in place of the constant ambient term.
    pub indirect: Option<&'a [[f32; 3]]>,
    /// Smooth shading: the cells' records ([`crate::machine::shading::smooth_surface`]).
    pub smooth: Option<&'a SmoothGrid>,
    /// Samples per pixel: the cells' sample records ([`crate::machine::shading::samples`]).
    pub samples: Option<&'a SampleGrid>,
}

impl<'a> RenderInput<'a> {
    /// The scene and its lights, with no reference and no time spent before.
    pub fn new(mesh: &'a Mesh, scene: &'a LoadedScene, lights: &'a [[f64; 3]]) -> RenderInput<'a> {
        RenderInput {
            mesh,
            scene,
            lights,
            intensity: None,
            reference: None,
            load_seconds: 0.0,
            reference_seconds: 0.0,
            indirect: None,
            smooth: None,
            samples: None,
        }
    }

    /// The same, compared with `reference`.
    pub fn compared_with(self, reference: &'a RefImage) -> RenderInput<'a> {
        RenderInput { reference: Some(reference), ..self }
    }

    /// The same lit by `sources` (positions and intensities).
    pub fn with_sources(self, sources: &'a Sources) -> RenderInput<'a> {
        RenderInput { lights: &sources.positions, intensity: Some(&sources.intensity), ..self }
    }

    /// The lights as the cells shade with them.
    pub fn point_lights(&self) -> Vec<PointLight> {
        match self.intensity {
            Some(e) => weighted_lights(self.lights, e),
            None => point_lights(self.lights),
        }
    }
}

/// Ray-cast the f64 reference of a loaded scene with the same camera, resolution and lights,
/// and the same reflections (depth, threshold; exact normals and hits) when `cfg` has them.
pub fn reference_image(
    mesh: &Mesh,
    scene: &LoadedScene,
    light_positions: &[[f64; 3]],
    cfg: &RenderConfig,
) -> Result<RefImage> {
    reference_image_lit(mesh, scene, &point_lights(light_positions), cfg)
}

/// [`reference_image`] with the lights' intensities given: the same lights as the cells'
/// ([`RenderInput::point_lights`]), an area light's samples with the same weights.
pub fn reference_image_lit(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    cfg: &RenderConfig,
) -> Result<RefImage> {
    let rl = ref_lights(lights);
    let refl = match &cfg.lighting {
        RenderLighting::Reflections(r) => {
            RefReflect { depth: r.depth as u32, threshold: r.threshold as f64, refract: true }
        }
        RenderLighting::Diffusion | RenderLighting::Classic(_) | RenderLighting::Refined(_) => RefReflect::NONE,
    };
    let (fit, n, ambient) = (&scene.fit, scene.grid.n, [AMBIENT as f64; 3]);
    if cfg.samples > 1 {
        return crate::truth::refrender::render_reference_samples(mesh, fit, n, &rl, ambient, cfg.samples);
    }
    match cfg.light.visibility {
        Visibility::Target => crate::truth::refrender::render_reference_reflect(mesh, fit, n, &rl, ambient, &refl),
        v => {
            let footprint = RefFootprint { samples: FOOTPRINT_SAMPLES, majority: v == Visibility::Majority };
            crate::truth::refrender::render_reference_footprint(mesh, fit, n, &rl, ambient, &refl, footprint)
        }
    }
}

/// Points per side of a pixel's footprint the reference samples under `--visibility ratio` and
/// `majority` ([`RefFootprint`]): 64 per pixel, a weight to 1/64.
pub const FOOTPRINT_SAMPLES: u32 = 8;

/// [`reference_image`] shaded smoothly as `smooth` says (the same corner normals and mode as the
/// cells; the f64 interpolation of [`crate::truth::refrender::RefSmooth`]).
pub fn smooth_reference_image(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[PointLight],
    smooth: &SmoothScene,
) -> Result<RefImage> {
    let rl = ref_lights(lights);
    let rs = crate::truth::refrender::RefSmooth { mode: smooth.mode, corners: &smooth.corners };
    crate::truth::refrender::render_reference_smooth(mesh, &scene.fit, scene.grid.n, &rl, [AMBIENT as f64; 3], &rs)
}

/// Outputs of a render.
pub struct Rendered {
    /// The machine's image.
    pub image: Image,
    /// Statistics.
    pub stats: RenderStats,
    /// Counters of the classic phase (classic lighting).
    pub classic: Option<ClassicCounts>,
    /// Counters of the reflection phase (with reflections), PSNRs against the reference included.
    pub reflections: Option<ReflectCounts>,
    /// With radiosity: the same render with the constant ambient term (direct light only).
    pub direct_only: Option<Image>,
}

/// Light and shade a loaded scene as `cfg` says; compare with the input's reference when given.
/// `progress` hears the lighting phase's source and cycle.
pub fn render(input: &RenderInput<'_>, cfg: &RenderConfig, progress: impl FnMut(usize, u64)) -> Result<Rendered> {
    match &cfg.lighting {
        RenderLighting::Diffusion => render_diffusion(input, cfg, progress),
        RenderLighting::Classic(c) => render_classic(input, cfg, c, progress),
        RenderLighting::Refined(c) => render_refined(input, cfg, c, progress),
        RenderLighting::Reflections(r) => render_reflect(input, cfg, r, progress),
    }
}

fn render_diffusion(input: &RenderInput<'_>, cfg: &RenderConfig, progress: impl FnMut(usize, u64)) -> Result<Rendered> {
    let t0 = Instant::now();
    let (lighting, lstats) = run_diffusion(input.mesh, input.scene, input.lights, &cfg.light, progress)?;
    let light_seconds = t0.elapsed().as_secs_f64();
    let rendered = shade(input, cfg, &seen(&lighting), lstats, light_seconds);
    Ok(rendered)
}

/// Diffusion, then shadow-edge refinement of the visible masks, then the same shading; the
/// refinement's counters go into the statistics (`refine`).
fn render_refined(
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
    classic_cfg: &ClassicConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<Rendered> {
    let t0 = Instant::now();
    let (lighting, lstats) = run_diffusion(input.mesh, input.scene, input.lights, &cfg.light, &mut progress)?;
    let n = input.scene.grid.n;
    let mut masks: Vec<cell_core::light::SourceMask> =
        (0..n * n).map(|i| lighting.visible_mask(i % n, i / n)).collect();
    let refine = refine_edges(input.scene, input.lights, &mut masks, classic_cfg, progress)?;
    let light_seconds = t0.elapsed().as_secs_f64();
    let seen = Seen::Surface(Box::new(|x, y| masks[(y * n + x) as usize]));
    let mut r = shade(input, cfg, &seen, lstats, light_seconds);
    r.stats.refine = Some(refine);
    Ok(r)
}

/// Classic shadow rays, then the same shading and report as diffusion.
fn render_classic(
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
    classic_cfg: &ClassicConfig,
    progress: impl FnMut(usize, u64),
) -> Result<Rendered> {
    let t0 = Instant::now();
    let (cl, stats) = run_classic(input.mesh, input.scene, input.lights, classic_cfg, progress)?;
    let light_seconds = t0.elapsed().as_secs_f64();
    let r = {
        let seen = if classic_cfg.rule.shades_visible_surface() {
            Seen::Surface(Box::new(|x, y| cl.mask(x, y)))
        } else {
            Seen::FirstVoxel(Box::new(|x, y, _| cl.mask(x, y)))
        };
        shade(input, cfg, &seen, stats, light_seconds)
    };
    Ok(Rendered { classic: Some(cl.totals), ..r })
}

/// Diffusion lighting, shading, then the reflection phase; compared with the input's reference
/// (make it with the same reflections: [`reference_image`]) after the reflections.
fn render_reflect(
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
    rcfg: &ReflectConfig,
    progress: impl FnMut(usize, u64),
) -> Result<Rendered> {
    let (mesh, light_positions) = (input.mesh, input.lights);
    let t0 = Instant::now();
    let (lighting, lstats) = run_diffusion(mesh, input.scene, light_positions, &cfg.light, progress)?;
    let mask = |x, y, z| lighting.mask(x, y, z);
    let light_seconds = t0.elapsed().as_secs_f64();
    let unreferenced = RenderInput { reference: None, ..*input };
    let mut r = shade(&unreferenced, cfg, &seen(&lighting), lstats, light_seconds);
    let t1 = Instant::now();
    let lights = input.point_lights();
    let env = ShadeEnv::new(mesh, &lights, cfg.normals, &mask);
    let refl = reflect(input.scene, &env, rcfg)?;
    let local_only = r.image.rgb.clone();
    for (px, v) in r.image.rgb.iter_mut().zip(&refl.rgb) {
        if let Some(v) = v {
            *px = *v;
        }
    }
    let mut counts = refl.counts;
    if let Some(rf) = input.reference {
        compare_reflections(mesh, &r.image.rgb, &local_only, rf, &mut counts);
    }
    r.stats.shade_seconds += t1.elapsed().as_secs_f64();
    r.stats.wall_seconds += t1.elapsed().as_secs_f64();
    r.stats.reference =
        input.reference.map(|rf| crate::truth::compare::compare(&r.image.rgb, &r.image.covered, &r.image.lit, rf));
    r.reflections = Some(counts);
    Ok(r)
}

/// PSNR of the image with and without its reflections against the reference, over the whole
/// image, over the pixels where the reference sees a mirror, and over those where it sees glass.
fn compare_reflections(mesh: &Mesh, rgb: &[[u8; 3]], local_only: &[[u8; 3]], rf: &RefImage, c: &mut ReflectCounts) {
    // The pixels where the reference sees a face whose material passes `test`.
    let sees = |test: fn(&crate::scene::Material) -> bool| -> Vec<bool> {
        let face = |f: u32| mesh.faces.get(f as usize).map(|fc| &mesh.materials[fc.material as usize]);
        rf.facet.iter().map(|&f| face(f).is_some_and(test)).collect()
    };
    let mirror = sees(|m| m.kr > 0.0);
    let all = vec![true; mirror.len()];
    c.psnr_db = Some(psnr(rgb, &rf.rgb, &all));
    c.psnr_without_db = Some(psnr(local_only, &rf.rgb, &all));
    c.mirror_psnr_db = Some(psnr(rgb, &rf.rgb, &mirror));
    c.mirror_psnr_without_db = Some(psnr(local_only, &rf.rgb, &mirror));
    c.mirror_pixels = mirror.iter().filter(|&&m| m).count() as u64;
    let glass = sees(|m| m.kt > 0.0);
    c.glass_pixels = glass.iter().filter(|&&g| g).count() as u64;
    if c.glass_pixels > 0 {
        c.glass_psnr_db = Some(psnr(rgb, &rf.rgb, &glass));
        c.glass_psnr_without_db = Some(psnr(local_only, &rf.rgb, &glass));
    }
}

/// Shade with the given lit state, compare with the input's reference and assemble the
/// statistics.
fn shade(
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
    seen: &Seen<'_>,
    lstats: LightStats,
    light_seconds: f64,
) -> Rendered {
    let (load_seconds, reference_seconds) = (input.load_seconds, input.reference_seconds);
    let t1 = Instant::now();
    let lights = input.point_lights();
    let constant = Ambient::Constant([AMBIENT; 3]);
    let ambient = input.indirect.map_or(constant, Ambient::Indirect);
    let centre = match seen {
        Seen::Surface(mask) => Some(CentreLights::Masks(mask)),
        Seen::Weighted(w) => Some(CentreLights::Weights(w)),
        Seen::FirstVoxel(_) => None,
    };
    let (image, sample_stats) = match (input.samples, centre) {
        (Some(g), Some(centre)) => {
            let (img, st) = shade_samples(input.mesh, input.scene, &lights, &centre, cfg.normals, g);
            (img, Some(st))
        }
        _ => (shade_grid_ambient(input.mesh, input.scene, &lights, seen, cfg.normals, &ambient, input.smooth), None),
    };
    let direct_only = input
        .indirect
        .map(|_| shade_grid_ambient(input.mesh, input.scene, &lights, seen, cfg.normals, &constant, input.smooth));
    let t2 = Instant::now();
    let cmp = input.reference.map(|r| crate::truth::compare::compare(&image.rgb, &image.covered, &image.lit, r));
    // With smooth shading a loading cell also holds the packet's vertex normals and its record.
    let smooth_bytes = input.smooth.map_or(0, |g| g.stats.bytes_per_packet + g.stats.bytes_per_cell);
    // With samples, the packet's y slopes, the sample records and the neighbours' messages.
    let sample_bytes = sample_stats.as_ref().map_or(0, |g| g.bytes_per_packet + g.bytes_per_cell);
    let load_cell = crate::config::loading_cell_bytes() + smooth_bytes + sample_bytes;
    let stores = crate::config::extra_cell_bytes(&cfg.light);
    let stats = RenderStats {
        run: None,
        view: input.mesh.screen.as_ref().map_or_else(|| "fitted".into(), |s| s.view.describe()),
        normals: match (input.smooth.map(|g| g.mode), cfg.normals) {
            (Some(Smooth::Phong), _) => "phong".into(),
            (Some(Smooth::Gouraud), _) => "gouraud".into(),
            (None, NormalMode::Facet) => "facet".into(),
            (None, NormalMode::Face) => "face".into(),
        },
        smooth: input.smooth.map(|g| g.stats.clone()),
        shade_cycles: input.lights.len().max(1) as u64 + sample_stats.as_ref().map_or(0, |g| g.exchange_cycles),
        samples: sample_stats,
        covered_pixels: image.covered.iter().filter(|&&c| c).count() as u64,
        lit_pixels: image.lit.iter().filter(|&&l| l != 0).count() as u64,
        bytes_per_cell_load: load_cell,
        bytes_per_cell_stores: stores,
        bytes_per_cell: load_cell + lstats.bytes_light_cell + stores,
        shading_max_err_levels: image.shading_max_err_levels,
        shading_mean_err_levels: image.shading_mean_err_levels,
        reference: cmp,
        load_seconds,
        light_seconds,
        shade_seconds: (t2 - t1).as_secs_f64(),
        reference_seconds,
        wall_seconds: load_seconds + light_seconds + (t2 - t1).as_secs_f64() + reference_seconds,
        peak_rss_mib: crate::machine::grid::limits::peak_rss_mib(),
        light: lstats,
        radiosity: None,
        refine: None,
    };
    Rendered { image, stats, classic: None, reflections: None, direct_only }
}

/// The render statistics with the reflection counters added under `"reflections"`.
pub fn with_counts(stats: &RenderStats, c: &ReflectCounts) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(stats)?;
    if let serde_json::Value::Object(m) = &mut v {
        m.insert("reflections".into(), serde_json::to_value(c)?);
    }
    Ok(v)
}

/// What the `render` job runs and writes.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// The view: fitted, the scene's camera, or a camera of the user's.
    pub view: crate::scene::camera::ViewChoice,
    /// Lights, the run (preset and overrides, resolved) and the lighting method.
    pub light: LightingOptions,
    /// Normal used for shading.
    pub normals: NormalMode,
    /// Smooth shading from vertex normals (with `normals` = facet).
    pub smooth: Option<Smooth>,
    /// Samples per pixel side (`--samples`; 1: the centre line alone).
    pub samples: u32,
    /// How a sample takes its lights (`--sample-lights`).
    pub sample_lights: cell_core::subpixel::SampleLights,
    /// The reflection phase (needs diffusion lighting); `None`: no reflections.
    pub reflections: Option<ReflectConfig>,
    /// Indirect light by radiosity on the grid; `None`: direct light only.
    pub radiosity: Option<RenderRadiosity>,
    /// Output PNG.
    pub out: PathBuf,
    /// Also ray-cast the f64 reference and compare: `F.reference.png` and `F.diff.png` beside
    /// the image `F`.
    pub reference: bool,
    /// Write the statistics as JSON here.
    pub stats: Option<PathBuf>,
    /// No progress bars.
    pub quiet: bool,
}

impl RenderOptions {
    /// Check the options before any work and say how to render.
    pub fn config(&self) -> Result<RenderConfig> {
        let lighting = match (&self.reflections, &self.light.classic) {
            (Some(_), Some(_)) => bail!(
                "--reflections needs --lighting diffusion (the lit state of every voxel, not only the visible ones)"
            ),
            (Some(r), None) => {
                r.validate(self.light.load().n)?;
                RenderLighting::Reflections(*r)
            }
            (None, Some(c)) => RenderLighting::Classic(*c),
            (None, None) => match &self.light.refine {
                Some(c) => RenderLighting::Refined(*c),
                None => RenderLighting::Diffusion,
            },
        };
        if self.light.refine.is_some() && (self.reflections.is_some() || self.radiosity.is_some()) {
            bail!("--lighting refined refines the direct light's image: run it without --reflections and --radiosity");
        }
        let reflecting = self.reflections.is_some();
        if reflecting && self.radiosity.is_some() {
            bail!(
                "--radiosity cannot be combined with --reflections: reflected rays shade what they hit \
                 without its indirect light (run one or the other)"
            );
        }
        // The run was resolved for reflections (the full lit store): `crate::config::Needs`.
        let light = self.light.config();
        if reflecting && light.lit_visible_only {
            bail!("--reflections needs the full lit store: resolve the run with `Needs::reflections`");
        }
        if self.light.run.area_light > 1 && self.radiosity.is_some() {
            bail!("--area-light with --radiosity: the radiosity phase shoots from point lights only (run one or the other)");
        }
        if light.visibility.counts_rays() {
            let other = [
                (self.light.classic.is_some(), "--lighting classic|refined"),
                (reflecting, "--reflections"),
                (self.radiosity.is_some(), "--radiosity"),
                (self.smooth.is_some(), "--normals gouraud|phong"),
            ];
            if let Some((_, what)) = other.iter().find(|o| o.0) {
                bail!(
                    "--visibility {} weighs each pixel's lights by the diffusion's ray counts: not done with {what} yet \
                     (run one or the other)",
                    light.visibility.name()
                );
            }
        }
        if self.smooth.is_some() {
            let rule = self.light.classic.as_ref().map_or(light.rule, |c| c.rule);
            if !rule.shades_visible_surface() {
                bail!(
                    "--normals gouraud|phong shade the surface a column's centre line meets: they need \
                     --lit-rule plane or exact (the thesis's rule shows the first voxel, whose point on its facet is not known)"
                );
            }
            if reflecting || self.radiosity.is_some() {
                bail!("--normals gouraud|phong: smooth shading is not done with --reflections or --radiosity yet");
            }
        }
        self.check_samples(&light)?;
        Ok(RenderConfig { light, normals: self.normals, smooth: self.smooth, samples: self.samples, lighting })
    }

    /// `--samples`: S in range, and only where a sample's surface and lights are known: the
    /// visible surface (plane or exact rule), flat normals, no reflections or radiosity.
    fn check_samples(&self, light: &LightConfig) -> Result<()> {
        crate::machine::shading::samples::check_samples(self.samples, self.light.load().n)?;
        if self.samples == 1 {
            return Ok(());
        }
        let rule = self.light.classic.as_ref().map_or(light.rule, |c| c.rule);
        let other = [
            (!rule.shades_visible_surface(), "--lit-rule thesis (it shows a voxel, not a point of a facet)"),
            (self.smooth.is_some(), "--normals gouraud|phong"),
            (self.reflections.is_some(), "--reflections"),
            (self.radiosity.is_some(), "--radiosity"),
        ];
        if let Some((_, what)) = other.iter().find(|o| o.0) {
            bail!("--samples {}: not done with {what} yet (run one or the other)", self.samples);
        }
        Ok(())
    }
}

/// Run the `render` job.
pub fn run(o: &RenderOptions) -> Result<()> {
    let cfg = o.config()?;
    let (mesh, loaded, load_seconds, smooth, samples) = load_phase(o)?;
    let sources = resolve_sources(&mesh, &loaded, &o.light.sampling())?;
    let lights = &sources.positions;
    let radiosity = radiosity_phase(o, &mesh, &loaded, lights, cfg.light.rule)?;
    let lit = RenderInput::new(&mesh, &loaded, lights).with_sources(&sources);
    let t1 = Instant::now();
    let reference = match &smooth {
        Some((s, _)) if o.reference => Some(smooth_reference_image(&mesh, &loaded, &lit.point_lights(), s)?),
        _ => reference_phase(o, &lit, &cfg, radiosity.as_ref())?,
    };
    let input = RenderInput {
        reference: reference.as_ref(),
        load_seconds,
        reference_seconds: t1.elapsed().as_secs_f64(),
        indirect: radiosity.as_ref().map(|r| &r.shown.cells[..]),
        smooth: smooth.as_ref().map(|(_, g)| g),
        samples: samples.as_ref(),
        ..lit
    };
    let pb = progress::bar(o.quiet, "light 1");
    let mut r = render(&input, &cfg, progress::light(&pb))?;
    pb.finish_and_clear();
    if let Some(rad) = &radiosity {
        let t2 = Instant::now();
        let mut stats = radiosity_stats(rad, &r, &input, &cfg)?;
        stats.seconds = rad.seconds + t2.elapsed().as_secs_f64();
        r.stats.wall_seconds += stats.seconds;
        r.stats.radiosity = Some(stats);
    }
    r.stats.run = Some(o.light.run.summary());
    let written = write_outputs(o, &r, reference.as_ref())?;
    print_summary(o, &r, &written);
    Ok(())
}

/// What a smooth render loads besides the scene: the corner normals and the cells' records.
type SmoothPhase = Option<(SmoothScene, SmoothGrid)>;

/// Load phase: the scene through the chosen view (with smooth shading, its polygons of unequal
/// corner normals cut into triangles), loaded on the grid; the load's wall time; the smooth
/// records; with samples, the sample records.
fn load_phase(o: &RenderOptions) -> Result<(Mesh, LoadedScene, f64, SmoothPhase, Option<SampleGrid>)> {
    // Reflected rays are traced in the grid's own view: with reflections the default view is
    // the fitted one.
    let view = match o.view {
        crate::scene::camera::ViewChoice::Auto if o.reflections.is_some() => crate::scene::camera::ViewChoice::Fitted,
        v => v,
    };
    let mesh = crate::scene::camera::apply(scene::load(&o.scene)?, &view, o.light.load().n)?;
    if mesh.screen.is_some() && o.reflections.is_some() {
        bail!("--reflections needs the fitted view: reflected rays are not traced through a camera yet");
    }
    let (mesh, smooth) = match o.smooth {
        Some(mode) => {
            let (mesh, s) = SmoothScene::new(mesh, mode)?;
            (mesh, Some(s))
        }
        None => (mesh, None),
    };
    let t0 = Instant::now();
    let pb = progress::bar(o.quiet, "load");
    pb.set_length(1);
    let loaded = load_scene(&mesh, o.light.load())?;
    let smooth = match smooth {
        Some(s) => {
            let g = smooth_grid(&mesh, &s, &loaded, o.light.load())?;
            Some((s, g))
        }
        None => None,
    };
    let samples = match o.samples {
        1 => None,
        s => Some(sample_grid(&mesh, &loaded, o.light.load(), s, o.sample_lights)?),
    };
    pb.finish_and_clear();
    Ok((mesh, loaded, t0.elapsed().as_secs_f64(), smooth, samples))
}

/// The radiosity phase's results ([`render_radiosity`]): the solutions and what the cells show.
struct RadiosityPhase {
    solved: render_radiosity::Solved,
    shown: render_radiosity::Prepared,
    /// Wall time of the shots, the reference solver and the display.
    seconds: f64,
}

/// Radiosity phase (with `--radiosity`): shoot, solve the reference (with `--reference`), show
/// the solution on the render's grid, pixels showing by `rule`.
fn radiosity_phase(
    o: &RenderOptions,
    mesh: &Mesh,
    loaded: &LoadedScene,
    lights: &[[f64; 3]],
    rule: LitRule,
) -> Result<Option<RadiosityPhase>> {
    let Some(r) = &o.radiosity else {
        return Ok(None);
    };
    let t0 = Instant::now();
    let solved = render_radiosity::solve(mesh, loaded, o.light.load(), &r.solve, o.reference, r.truth, o.quiet)?;
    let shown = solved.show(mesh, loaded, lights, r.display, rule)?;
    Ok(Some(RadiosityPhase { solved, shown, seconds: t0.elapsed().as_secs_f64() }))
}

/// Reference phase (with `--reference`): the f64 image, shaded with the f64 solver's radiosity
/// when the render has radiosity.
fn reference_phase(
    o: &RenderOptions,
    lit: &RenderInput<'_>,
    cfg: &RenderConfig,
    radiosity: Option<&RadiosityPhase>,
) -> Result<Option<RefImage>> {
    let (mesh, loaded, lights) = (lit.mesh, lit.scene, lit.lights);
    if !o.reference {
        return Ok(None);
    }
    if mesh.faces.is_empty() {
        bail!("--reference needs a scene with geometry ('{}' has none)", mesh.name);
    }
    match radiosity {
        Some(rad) => rad.solved.f64_image(F64Solution::Reference, &rad.shown, mesh, loaded, lights),
        None => reference_image_lit(mesh, loaded, &lit.point_lights(), cfg).map(Some),
    }
}

/// The radiosity statistics of a radiosity render `r`: with a reference, the direct-only
/// image's PSNR against it and the other display's render.
fn radiosity_stats(
    rad: &RadiosityPhase,
    r: &Rendered,
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
) -> Result<RadiosityRenderStats> {
    let mut stats = rad.shown.stats.clone();
    stats.direct_only_psnr_db = r.direct_only.as_ref().zip(input.reference).map(|(d, rf)| direct_psnr(d, rf));
    if let Some(reference) = input.reference {
        stats.other_display = Some(other_display(&rad.solved, stats.display, input, cfg)?);
        let truth = rad.solved.f64_image(F64Solution::Truth, &rad.shown, input.mesh, input.scene, input.lights)?;
        stats.truth_image = truth.map(|t| TruthPsnr {
            reference_psnr_db: crate::truth::compare::psnr(&reference.rgb, &t.rgb, &t.covered),
            machine_psnr_db: crate::truth::compare::compare(&r.image.rgb, &r.image.covered, &r.image.lit, &t).psnr_db,
        });
    }
    Ok(stats)
}

/// PSNR of a direct-light-only image against a (radiosity) reference.
fn direct_psnr(direct: &Image, reference: &RefImage) -> f64 {
    crate::truth::compare::compare(&direct.rgb, &direct.covered, &direct.lit, reference).psnr_db
}

/// The radiosity render of `input`'s scene with the display other than `shown`, against the
/// reference shown the same way: its PSNR and the direct-only image's.
fn other_display(
    solved: &render_radiosity::Solved,
    shown: Display,
    input: &RenderInput<'_>,
    cfg: &RenderConfig,
) -> Result<DisplayPsnr> {
    let display = match shown {
        Display::Flat => Display::Smooth,
        Display::Smooth => Display::Flat,
    };
    let (mesh, loaded, lights) = (input.mesh, input.scene, input.lights);
    let other = solved.show(mesh, loaded, lights, display, cfg.light.rule)?;
    let reference =
        solved.f64_image(F64Solution::Reference, &other, mesh, loaded, lights)?.expect("solved with the reference");
    let input = RenderInput { indirect: Some(&other.cells), reference: Some(&reference), ..*input };
    let r = render(&input, cfg, |_, _| {})?;
    let direct = r.direct_only.as_ref().expect("a radiosity render");
    let psnr_db = r.stats.reference.map_or(f64::NAN, |c| c.psnr_db);
    Ok(DisplayPsnr { display, psnr_db, direct_only_psnr_db: direct_psnr(direct, &reference) })
}

/// `F.EXT` beside the image `F.png`: its extension replaced, dots in the stem kept
/// (`shot-0.5.png` gives `shot-0.5.diff.png`).
fn beside(out: &Path, ext: &str) -> PathBuf {
    let stem = out.file_stem().unwrap_or_default().to_string_lossy();
    out.with_file_name(format!("{stem}.{ext}"))
}

/// The image, the reference and difference images, the statistics; the files written.
fn write_outputs(o: &RenderOptions, r: &Rendered, reference: Option<&RefImage>) -> Result<Vec<String>> {
    write_png(&o.out, r.image.n, &r.image.rgb)?;
    let mut written = vec![o.out.display().to_string()];
    if let Some(direct) = &r.direct_only {
        let p = beside(&o.out, "direct.png");
        write_png(&p, direct.n, &direct.rgb)?;
        written.push(p.display().to_string());
    }
    if let Some(reference) = reference {
        let (rp, dp) = (beside(&o.out, "reference.png"), beside(&o.out, "diff.png"));
        write_png(&rp, reference.n, &reference.rgb)?;
        let diff = crate::truth::compare::difference_image(&r.image.rgb, &r.image.covered, reference);
        write_png(&dp, reference.n, &diff)?;
        written.push(rp.display().to_string());
        written.push(dp.display().to_string());
    }
    match (&o.stats, &r.reflections) {
        (Some(p), Some(c)) => write_json(p, &with_counts(&r.stats, c)?)?,
        (Some(p), None) => write_json(p, &r.stats)?,
        _ => {}
    }
    Ok(written)
}

fn print_summary(o: &RenderOptions, r: &Rendered, written: &[String]) {
    let s = &r.stats;
    let t = &s.light.totals;
    let method = match (&o.light.classic, &o.light.refine) {
        (Some(c), _) => classic_description(&o.light.run, c.fa),
        (None, Some(_)) => format!("{}; shadow edges refined by classic rays", o.light.run.describe()),
        (None, None) => o.light.run.describe(),
    };
    eprintln!("{method}");
    eprintln!(
        "{}: {} facets, {} light(s), {} normals",
        s.light.scene,
        s.light.facets,
        s.light.sources.len(),
        s.normals
    );
    eprintln!("  view: {}", s.view);
    if let Some(sm) = &s.smooth {
        eprintln!(
            "  smooth shading ({}): vertex normals {}, {} polygons cut into triangles, +{} bytes/packet, +{} bytes/cell",
            sm.mode, sm.normals_from, sm.polygons_cut, sm.bytes_per_packet, sm.bytes_per_cell
        );
    }
    if let Some(g) = &s.samples {
        eprintln!(
            "  samples: {}×{} per pixel, lights {}, {} pixels mixed ({} samples on another surface than the centre's); +{} bytes/packet, +{} bytes/cell, +{} row steps in loading, {} messages and {} cycle to the neighbours",
            g.samples_per_side, g.samples_per_side, g.lights, g.mixed_pixels, g.foreign_samples, g.bytes_per_packet, g.bytes_per_cell,
            g.load_extra_row_steps, g.exchange_messages, g.exchange_cycles
        );
    }
    eprintln!(
        "  cycles: load {}  light {} (T/LB {:.2}, {} beams)  shade {}",
        s.light.load_cycles, t.cycles, s.light.t_over_lb, t.beams_processed, s.shade_cycles
    );
    print_link_faults(&s.light);
    eprintln!(
        "  pixels: {} covered, {} lit   bytes/cell {} (dexels {} + light {} + triangles and summary {})   shading vs f64: max {} mean {:.3} levels",
        s.covered_pixels, s.lit_pixels, s.bytes_per_cell, s.bytes_per_cell_load, s.light.bytes_light_cell, s.bytes_per_cell_stores,
        s.shading_max_err_levels, s.shading_mean_err_levels
    );
    if let Some(c) = &r.classic {
        eprintln!("  {}", crate::machine::rays::classic::summary(c));
    }
    if let Some(k) = &s.refine {
        eprintln!(
            "  shadow edges: {} (pixel, light) pairs re-tested by shadow rays, {} changed, {} more cycles",
            k.edge_pixels, k.changed, k.cycles
        );
    }
    if let Some(c) = &r.reflections {
        eprintln!("  {}", crate::machine::rays::mirror::summary(c));
    }
    if let Some(rad) = &s.radiosity {
        render_radiosity::print_summary(rad);
    }
    if let Some(c) = &s.reference {
        eprintln!(
            "  reference: shadow disagreement {:.2} %, coverage disagreement {:.2} %, PSNR {:.2} dB",
            c.shadow_disagreement_pct, c.coverage_disagreement_pct, c.psnr_db
        );
    }
    if let Some(d) = s.radiosity.as_ref().and_then(|r| r.direct_only_psnr_db) {
        eprintln!("  direct light only against the radiosity reference: PSNR {d:.2} dB");
    }
    eprintln!(
        "  wall {:.2} s (load {:.2}, light {:.2}, shade {:.2}, reference {:.2})   wrote {}",
        s.wall_seconds,
        s.load_seconds,
        s.light_seconds,
        s.shade_seconds,
        s.reference_seconds,
        written.join(", ")
    );
}

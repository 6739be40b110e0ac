//! Recording cell traces from a grid run (the `trace` job's machine): for chosen cells, every
//! message they receive, every compute cycle, every message a neighbour takes from them, in
//! order, as `cell_core::trace` records; and the digest of what they output and end up holding,
//! computed from the grid itself. A firmware (or [`cell_core::trace::replay`]) drives a fresh
//! cell through the records and must reach the same digest.
//!
//! The run is the one `render` makes with the same options: loading, then beam diffusion or
//! (with classic lighting) the classic shadow-ray phase of each source, shading, then (with
//! reflections) the reflection phase; every phase it runs is in the trace. A trace is recorded
//! under the run's f (`light.frac_bits`): the cells' build for that f is chosen here, once.

use anyhow::{bail, Result};
use cell_core::beam::{FracBits, Source};
use cell_core::cell::DEFAULT_DEXELS;
use cell_core::lit::LitRule;
use cell_core::shade::{cell_pixel, Eye, NormalMode, ShadeParams};
use cell_core::trace::{Event, ShadeSetup, MAX_LIGHTS, MAX_MATERIALS};

use crate::machine::grid::capacity::{HostLightCell, FA_CAP, LIT_CAP, OB_CAP};
use crate::machine::lighting::diffuse::{diffuse_cells, with_f, LightConfig, Lighting, Share};
use crate::machine::links::tap::{CellRecorder, Tap};
use crate::machine::loading::loaded_scene::LoadedScene;
use crate::machine::rays::classic::{classic_tapped, ClassicConfig, ClassicLighting};
use crate::machine::rays::mirror::{reflect_tapped, ReflectConfig, ShadeEnv};
use crate::machine::shading::pixels::{cell_material, eye_lights, point_lights, AMBIENT};
use crate::precompute::LoadConfig;
use crate::scene::Mesh;

/// A recorded trace and the digest the grid run gives.
#[derive(Clone, Debug)]
pub struct CellTrace {
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
    /// The records.
    pub bytes: Vec<u8>,
    /// Records written.
    pub records: u64,
    /// Digest of the outputs and final state, from the grid.
    pub digest: u64,
}

/// What `record` needs to know.
pub struct TraceJob<'a> {
    /// Scene.
    pub mesh: &'a Mesh,
    /// Loading settings.
    pub load: LoadConfig,
    /// Lighting settings.
    pub light: LightConfig,
    /// Lights at grid-normalised positions (empty: the scene's own, as `render` does).
    pub lights: Vec<[f64; 3]>,
    /// Cells to record; `busiest` adds the cell that processed the most beams.
    pub cells: Vec<[u32; 2]>,
    /// Also record the busiest cell (found by a first, untraced run).
    pub busiest: bool,
    /// Classic shadow rays instead of beam diffusion (`light` is then unused).
    pub classic: Option<ClassicConfig>,
    /// The reflection phase after shading (needs beam diffusion and the grid's own view).
    pub reflections: Option<ReflectConfig>,
}

/// The lit state the lighting phase left.
enum Lit<F: FracBits> {
    /// Beam diffusion's: every cell's lit store, and the cells (what the digest reads).
    Beams(Lighting, Vec<HostLightCell<F>>),
    /// Classic shadow rays': the sources that lit each visible surface.
    Rays(ClassicLighting, LitRule),
}

/// Run the phases on the grid (see the module doc), recording the chosen cells.
pub fn record(job: &TraceJob<'_>) -> Result<Vec<CellTrace>> {
    with_f!(job.light.frac_bits, F => record_f::<F>(job))
}

/// [`record`] under f = `F`.
fn record_f<F: FracBits>(job: &TraceJob<'_>) -> Result<Vec<CellTrace>> {
    let n = job.load.n;
    if job.mesh.materials.len() > MAX_MATERIALS {
        bail!("{} materials: a trace carries at most {MAX_MATERIALS}", job.mesh.materials.len());
    }
    if job.reflections.is_some() && job.classic.is_some() {
        bail!("--reflections needs --lighting diffusion (the lit state of every voxel, not only the visible ones)");
    }
    let cells = cells_to_record(job)?;
    let mut tap = Tap::new::<F>(n, n, &cells)?;
    let scene: LoadedScene =
        crate::machine::loading::loaded_scene::load_scene_tapped(job.mesh, &job.load, Some(&mut tap))?;
    let (lights, sources) = lights_of(job, &scene)?;
    if lights.len() > MAX_LIGHTS {
        bail!("{} lights: a trace carries at most {MAX_LIGHTS}", lights.len());
    }
    let lit = match &job.classic {
        None => {
            let (lighting, cells) = diffuse_cells::<F, DEFAULT_DEXELS>(
                &scene.grid,
                &sources,
                &job.light,
                Share::ALL,
                Some(&mut tap),
                None,
                &mut |_, _| {},
            )?;
            Lit::Beams(lighting, cells)
        }
        Some(c) => Lit::Rays(classic_tapped(&scene, &lights, c, Some(&mut tap), &mut |_, _| {})?, c.rule),
    };
    let shade = ShadeSetup {
        params: ShadeParams { ambient: [AMBIENT; 3], normal_mode: NormalMode::Facet, eye: scene.eye },
        lights: eye_lights(&scene.eye, &point_lights(&lights)).into_iter().collect(),
        materials: job.mesh.materials.iter().map(cell_material).collect(),
    };
    tap.shade(&shade);
    if let (Some(cfg), Lit::Beams(lighting, _)) = (&job.reflections, &lit) {
        reflections(job, &scene, lighting, &shade, cfg, &mut tap)?;
    }
    Ok(tap.into_recorders().into_iter().map(|r| finish_trace::<F>(r, job, &scene, &lit, &shade)).collect())
}

/// The reflection phase over the lit grid, shading with the trace's shading inputs (what the
/// replaying cell shades with).
fn reflections(
    job: &TraceJob<'_>,
    scene: &LoadedScene,
    lighting: &Lighting,
    shade: &ShadeSetup,
    cfg: &ReflectConfig,
    tap: &mut Tap,
) -> Result<()> {
    if shade.params.eye != Eye::Grid {
        bail!("--reflections needs the fitted view: reflected rays are not traced through a camera yet");
    }
    cfg.validate(job.load.n)?;
    let mask = |x, y, z| lighting.mask(x, y, z);
    let env = ShadeEnv {
        mats: shade.materials.to_vec(),
        kr: job.mesh.materials.iter().map(|m| m.kr).collect(),
        transmit: job.mesh.materials.iter().map(crate::machine::rays::mirror::transmit).collect(),
        lights: &shade.lights,
        params: shade.params,
        mask: &mask,
    };
    reflect_tapped(scene, &env, cfg, Some(tap))?;
    Ok(())
}

/// The job's lights (grid-normalised positions) and the cell sources at them.
fn lights_of(job: &TraceJob<'_>, scene: &LoadedScene) -> Result<(Vec<[f64; 3]>, Vec<Source>)> {
    let lights = crate::machine::loading::loaded_scene::resolve_lights(job.mesh, scene, &job.lights)?;
    let sources = lights.iter().enumerate().map(|(i, p)| job.light.source(i, *p, job.load.n)).collect::<Result<_>>()?;
    Ok((lights, sources))
}

/// The cells asked for, and the busiest one (found by a first, untraced run) if asked.
fn cells_to_record(job: &TraceJob<'_>) -> Result<Vec<[u32; 2]>> {
    let mut cells = job.cells.clone();
    if job.busiest {
        let scene = crate::machine::loading::loaded_scene::load_scene(job.mesh, &job.load)?;
        let (lights, sources) = lights_of(job, &scene)?;
        match &job.classic {
            None => {
                let l = crate::machine::lighting::diffuse::diffuse(&scene.grid, &sources, &job.light, |_, _| {})?;
                cells.extend(l.reports.iter().max_by_key(|r| r.counts.lb_cell_load).map(|r| r.busiest_cell));
            }
            Some(c) => {
                cells.push(crate::machine::rays::classic::classic(&scene, &lights, c, |_, _| {})?.totals.busiest_cell)
            }
        }
    }
    if cells.is_empty() {
        bail!("no cell to record: give --cell X,Y or --busiest");
    }
    Ok(cells)
}

/// Close one cell's recording: its end record, and the digest of what the grid left in the
/// cell (state, lit store, pixel; a classic run leaves the lighting cell as it was built).
fn finish_trace<F: FracBits>(
    mut r: CellRecorder,
    job: &TraceJob<'_>,
    scene: &LoadedScene,
    lit: &Lit<F>,
    shade: &ShadeSetup,
) -> CellTrace {
    let idx = (r.y * job.load.n + r.x) as usize;
    let cell = &scene.grid.cells[idx];
    let (mats, lights) = (&shade.materials, &shade.lights);
    let unlit = HostLightCell::<F>::new(cell.x, cell.y);
    let (light, px) = match lit {
        Lit::Beams(_, cells) => {
            let light = &cells[idx];
            let (lit, visible) = (&light.lit, light.visible_lit);
            (light, cell_pixel(job.light.rule, cell, |z| lit.mask_at(z), visible, mats, lights, &shade.params))
        }
        Lit::Rays(cl, rule) => {
            let m = cl.mask(r.x, r.y);
            (&unlit, cell_pixel(*rule, cell, |_| m, m, mats, lights, &shade.params))
        }
    };
    r.push::<F>(&Event::End);
    let (x, y) = (r.x, r.y);
    let (bytes, records, mut digest) = r.into_parts();
    digest.state(cell, light, px);
    CellTrace { x, y, records, digest: digest.finish(), bytes }
}

/// Replay a trace recorded under f = `frac_bits` with the host's build of `cell_core` (the same
/// code the firmware runs).
pub fn replay(frac_bits: u32, bytes: &[u8]) -> Result<(u64, cell_core::trace::ReplayStats)> {
    with_f!(frac_bits, F => cell_core::trace::replay::<F, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>(bytes)
        .map_err(|e| anyhow::anyhow!("trace replay failed: {e:?}")))
}

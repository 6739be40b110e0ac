//! `render --radiosity`: the radiosity phase of a render (radiosity thesis §1.3.1–1.3.2;
//! docs/RADIOSITY.md, "Rendering"). The cells shade their direct light as every render does, plus
//! the indirect light of their visible point in place of the empirical ambient term
//! ([`crate::machine::shooting::indirect`]).
//!
//! Phases, after the render's loading:
//! 1. **patches and shots** — the world scene's patches and the machine's progressive solution,
//!    exactly as the `radiosity` job makes them ([`RadiositySettings`]), on a grid loaded in the
//!    fitted view: the render's own grid when it has no camera, else a second load of the world
//!    scene (radiosity is view-independent, and a perspective grid would not keep the beams'
//!    solid angles, so shots never run in screen space);
//! 2. **display** — the exposure ([`exposure`]), the supervisor's values, the costed broadcast,
//!    every cell's `Ia` ([`show`]) on the render's grid;
//! 3. **reference** (with `--reference`) — the f64 solver on the same patches with the same
//!    stopping rule, its indirect irradiance ([`indirect_irradiance`]) shown the same way
//!    (display, exposure) at each exact hit point of the reference image ([`RefAmbient`]).
//!
//! Invariant: the machine's and the reference's images differ only by what they compute (lit
//! state, visible point, per-patch solution), never by how a solution is shown.

use std::time::Instant;

use anyhow::Result;
use cell_core::lit::LitRule;
use parry3d_f64::math::Vector;

use crate::jobs::radiosity::{compare, solve_with_bar, summarise, RadiositySettings, RadiosityStats};
use crate::machine::loading::loaded_scene::{grid_to_world, load_scene, LoadedScene};
use crate::machine::shading::pixels::{point_lights, ref_lights};
use crate::machine::shooting::indirect::{patch_values, show, visible_points, Display, DisplayCost, Surfaces};
use crate::precompute::LoadConfig;
use crate::scene::patch_display::exposure;
use crate::scene::patches::Patches;
use crate::scene::Mesh;
use crate::truth::formfactor::FormFactors;
use crate::truth::radiosity::{indirect_irradiance, Solution};
use crate::truth::refrender::{render_reference_ambient, RefAmbient, RefImage, RefReflect};

/// The display `render --radiosity` uses unless told (docs/RADIOSITY.md: smooth is closer to
/// the reference at every n measured).
pub const DEFAULT_DISPLAY: Display = Display::Smooth;

/// What `render --radiosity` adds to a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderRadiosity {
    /// Patches and stopping rule (as the `radiosity` job).
    pub solve: RadiositySettings,
    /// How a cell shows its patch's radiosity.
    pub display: Display,
    /// With `--reference`: also a converged truth (`--truth-error`), its image, and the PSNR of
    /// the reference's and the machine's images against it.
    pub truth: bool,
}

/// The radiosity part of `render --stats` (key `radiosity`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct RadiosityRenderStats {
    /// The solution on the grid, as the `radiosity` job reports it (its `reference`: the
    /// per-patch comparison with the f64 solver).
    pub solution: RadiosityStats,
    /// How cells show it.
    pub display: Display,
    /// Vertices shared by the patches (the smooth display's records).
    pub vertices: usize,
    /// The exposure of indirect irradiance, per channel.
    pub exposure: [f64; 3],
    /// Loading cycles of the grid the shots ran on, when it is not the render's (a camera).
    pub shot_grid_load_cycles: Option<u64>,
    /// The broadcast of the display values and what a cell holds for it.
    pub display_cost: DisplayCost,
    /// Covered pixels whose visible face has no patch (no indirect light there).
    pub pixels_without_patch: u64,
    /// With `--reference`: PSNR of the direct-light-only image (the render without radiosity)
    /// against the radiosity reference, beside the `reference` PSNR of the radiosity image.
    pub direct_only_psnr_db: Option<f64>,
    /// With `--reference`: the same solution shown by the other display, against the reference
    /// shown by it (one more lighting and shading of the grid).
    pub other_display: Option<DisplayPsnr>,
    /// With `--truth-error`: the images against the converged truth's, shown the same way.
    pub truth_image: Option<TruthPsnr>,
    /// Wall time of the radiosity phase: shots, reference solver, display (and the other
    /// display's render), seconds.
    pub seconds: f64,
}

/// The rendered images against the image of the converged truth ([`crate::jobs::radiosity::
/// TruthError`]'s solution, shown by the same display with the same exposure and direct light):
/// what a method's form-factor error leaves in the picture.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct TruthPsnr {
    /// PSNR of the f64 reference's image (its `--form-factors`) against the truth's, dB.
    pub reference_psnr_db: f64,
    /// PSNR of the machine's image against the truth's, dB.
    pub machine_psnr_db: f64,
}

/// A display's image against the reference shown the same way.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct DisplayPsnr {
    /// The display.
    pub display: Display,
    /// PSNR of the radiosity image.
    pub psnr_db: f64,
    /// PSNR of the direct-light-only image against the same reference.
    pub direct_only_psnr_db: f64,
}

/// The radiosity phase's results on the render's grid.
pub struct Prepared {
    /// Per cell of the render's grid, its indirect irradiance `Ia`.
    pub cells: Vec<[f32; 3]>,
    /// Statistics (`direct_only_psnr_db` is filled once the images exist).
    pub stats: RadiosityRenderStats,
    /// The reference's broadcast records (its display values), with `--reference`.
    reference_records: Option<Vec<[f64; 3]>>,
    /// The converged truth's records, with `--truth-error`.
    truth_records: Option<Vec<[f64; 3]>>,
}

/// Which f64 solution an image shows ([`Solved::f64_image`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum F64Solution {
    /// The reference (`--reference`, with its `--form-factors`).
    Reference,
    /// The converged truth (`--truth-error`).
    Truth,
}

/// An RGB value per patch.
type PerPatch = Vec<[f64; 3]>;

/// Phases 1 and 3's solutions, before any display: the machine's and (with `--reference`) the
/// f64 solver's indirect irradiance per patch.
pub struct Solved {
    patches: Patches,
    faces: usize,
    machine: crate::machine::shooting::shots::GridSolution,
    /// The f64 solver's indirect irradiance and unshot radiosity per patch.
    reference: Option<(PerPatch, PerPatch)>,
    /// The converged truth's, the same way.
    truth: Option<(PerPatch, PerPatch)>,
    stats: RadiosityStats,
    shot_grid_load_cycles: Option<u64>,
}

/// The world-space mesh of a (possibly screen-space) mesh.
fn world_mesh(mesh: &Mesh) -> Option<Mesh> {
    mesh.screen.as_ref().map(|s| Mesh { positions: s.world.clone(), screen: None, ..mesh.clone() })
}

/// Phases 1 and 3: the patches of the world scene, shot on the fitted grid (`loaded` when it
/// has no camera), and with `reference` the f64 solver's solution on the same patches (with
/// `truth`, a converged truth's too).
pub fn solve(
    mesh: &Mesh,
    loaded: &LoadedScene,
    load: &LoadConfig,
    settings: &RadiositySettings,
    reference: bool,
    truth: bool,
    quiet: bool,
) -> Result<Solved> {
    let world = world_mesh(mesh);
    let own = world.as_ref().map(|w| load_scene(w, load)).transpose()?;
    let (world, shot_grid) = (world.as_ref().unwrap_or(mesh), own.as_ref().unwrap_or(loaded));
    let p = settings.patches(world, shot_grid.fit.voxel)?;
    let t0 = Instant::now();
    let s = solve_with_bar(shot_grid, &p, settings, quiet)?;
    let wall = t0.elapsed().as_secs_f64();
    let irradiance = |ff: &FormFactors, sol: Solution| -> Result<(PerPatch, PerPatch)> {
        Ok((indirect_irradiance(&p.patches, &sol, |i| ff.row(i))?, sol.unshot))
    };
    let (compared, reference, truth) = if reference {
        let c = compare(&p, &s, settings, false, truth.then_some(None))?;
        let t = c.truth.map(|(ff, sol)| irradiance(&ff, sol)).transpose()?;
        (Some(c.stats), Some(irradiance(&c.ff, c.solution)?), t)
    } else {
        (None, None, None)
    };
    Ok(Solved {
        stats: summarise(&mesh.name, shot_grid, &p, &s, settings, wall, compared),
        faces: world.faces.len(),
        patches: p,
        machine: s,
        reference,
        truth,
        shot_grid_load_cycles: own.as_ref().map(|g| g.load_cycles),
    })
}

impl Solved {
    /// Phase 2: show the solutions on the render's grid (`lights` in its voxel units, pixels
    /// showing by `rule`) with `display`.
    pub fn show(
        &self,
        mesh: &Mesh,
        loaded: &LoadedScene,
        lights: &[[f64; 3]],
        display: Display,
        rule: LitRule,
    ) -> Result<Prepared> {
        let lights_world: Vec<[f64; 3]> = lights.iter().map(|l| grid_to_world(mesh, loaded, *l)).collect();
        let k = exposure(&self.patches.patches, &lights_world, 1.0 / (lights.len().max(1) as f64).sqrt())?;
        let surfaces = Surfaces::new(&self.patches, self.faces, display)?;
        let records = |h: &[[f64; 3]], unshot: &[[f64; 3]]| {
            surfaces.record_values(&patch_values(&self.patches.patches, h, unshot, k))
        };
        let machine = records(&self.machine.indirect, &self.machine.unshot);
        let shown = show(&surfaces, &machine, &visible_points(mesh, loaded, rule), loaded.grid.n)?;
        let stats = RadiosityRenderStats {
            solution: self.stats.clone(),
            display,
            vertices: surfaces.vertex_count(),
            exposure: k,
            shot_grid_load_cycles: self.shot_grid_load_cycles,
            display_cost: shown.cost,
            pixels_without_patch: shown.missing,
            direct_only_psnr_db: None,
            other_display: None,
            truth_image: None,
            seconds: 0.0,
        };
        let reference_records = self.reference.as_ref().map(|(h, u)| records(h, u));
        let truth_records = self.truth.as_ref().map(|(h, u)| records(h, u));
        Ok(Prepared { cells: shown.cells, stats, reference_records, truth_records })
    }

    /// The f64 image of a radiosity render shown by `p` (the f64 solution `of` at each exact
    /// hit point); `None` when that solution was not asked for (`--reference`,
    /// `--truth-error`).
    pub fn f64_image(
        &self,
        of: F64Solution,
        p: &Prepared,
        mesh: &Mesh,
        loaded: &LoadedScene,
        lights: &[[f64; 3]],
    ) -> Result<Option<RefImage>> {
        let records = match of {
            F64Solution::Reference => &p.reference_records,
            F64Solution::Truth => &p.truth_records,
        };
        records.as_ref().map(|r| self.image(r, p, mesh, loaded, lights)).transpose()
    }

    /// The f64 image of per-record display values `records` shown by `p`'s display.
    fn image(
        &self,
        records: &[[f64; 3]],
        p: &Prepared,
        mesh: &Mesh,
        loaded: &LoadedScene,
        lights: &[[f64; 3]],
    ) -> Result<RefImage> {
        let surfaces = Surfaces::new(&self.patches, self.faces, p.stats.display)?;
        let at = |face: u32, x: [f64; 3]| surfaces.value_at(records, face as usize, Vector::from(x));
        let rl = ref_lights(&point_lights(lights));
        let refl = RefReflect::NONE;
        render_reference_ambient(mesh, &loaded.fit, loaded.grid.n, &rl, RefAmbient::Indirect(&at), &refl)
    }
}

/// The radiosity lines of a render's summary: the solution as the `radiosity` job prints it,
/// then its display.
pub fn print_summary(r: &RadiosityRenderStats) {
    eprintln!("  radiosity phase ({:.1} s):", r.seconds);
    crate::jobs::radiosity::print_summary(&r.solution);
    let d = &r.display_cost;
    eprintln!(
        "  display {:?}: {} records broadcast in {} cycles, {} messages, {} supervisor operations; \
         bytes/cell added {}; exposure [{:.3}, {:.3}, {:.3}]; covered pixels without a patch {}",
        r.display,
        d.records,
        d.broadcast_cycles,
        d.broadcast_messages,
        d.supervisor_ops,
        d.bytes_per_cell,
        r.exposure[0],
        r.exposure[1],
        r.exposure[2],
        r.pixels_without_patch
    );
    if let Some(t) = &r.truth_image {
        eprintln!(
            "  against the converged truth's image: reference PSNR {:.2} dB, machine {:.2} dB",
            t.reference_psnr_db, t.machine_psnr_db
        );
    }
    if let Some(o) = &r.other_display {
        eprintln!(
            "  {:?} display against its reference: PSNR {:.2} dB (direct light only {:.2} dB)",
            o.display, o.psnr_db, o.direct_only_psnr_db
        );
    }
}

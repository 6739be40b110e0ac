//! The `light` and `diffusion-table` jobs: load a scene, place its lights, diffuse, report.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Result};
use cell_core::beam::FracBits;
use cell_core::cell::DEFAULT_DEXELS;
use cell_core::light::{BeamMsg, Policy};

use crate::diffuse::{diffuse, source_at, DiffusionCounts, HostLightCell, LightConfig, Lighting, SourceReport};
use crate::grid::Grid;
use crate::precompute::{Fit, LoadConfig};
use crate::scene::{Mesh, SceneLight};

/// Fraction bits the lighting jobs use unless told otherwise: under the plane rule f = 0 meets
/// the accuracy goals at a quarter to four fifths of the former default's cycles; f = 1 is the
/// accuracy knob for faces lit at extreme grazing angles (BENCHMARKS.md, "Is the light right?").
pub const DEFAULT_FRAC_BITS: u32 = 0;

/// The grid type the lighting jobs load into.
pub type LightGrid = Grid<DEFAULT_DEXELS>;

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
}

/// Voxelize a scene with the wave (an empty scene gives an empty grid).
pub fn load_scene(mesh: &Mesh, cfg: &LoadConfig) -> Result<LoadedScene> {
    load_scene_tapped(mesh, cfg, None)
}

/// [`load_scene`], recording the cells watched by `tap`.
pub fn load_scene_tapped(mesh: &Mesh, cfg: &LoadConfig, tap: Option<&mut crate::trace::Tap>) -> Result<LoadedScene> {
    cfg.validate()?;
    if mesh.faces.is_empty() {
        crate::limits::check_grid_memory(
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
        });
    }
    let v = crate::load::voxelize_tapped::<DEFAULT_DEXELS>(mesh, cfg, crate::load::Engine::Wave, tap, |_, _| {})?;
    v.check_overflow()?;
    Ok(LoadedScene {
        facets: v.stats.facets,
        load_cycles: v.stats.load_cycles,
        fit: v.prepared.fit.expect("fitted"),
        source_face: v.prepared.source_face,
        grid: v.grid,
    })
}

/// World position of a voxel-unit point.
pub fn voxel_to_world(fit: &Fit, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| fit.origin[i] + (v[i] + 0.5) * fit.voxel)
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

/// Light positions in voxel units: `--light` values (normalised, validated) if any, else the
/// scene's own lights.
pub fn resolve_lights(mesh: &Mesh, scene: &LoadedScene, cli: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
    let n = scene.grid.n;
    if !cli.is_empty() {
        return cli
            .iter()
            .enumerate()
            .map(|(i, t)| {
                if t.iter().any(|c| !c.is_finite() || *c < 0.0 || *c > 1.0) {
                    bail!("--light {} = {:?} is outside the grid: coordinates are grid-normalised, 0 ..= 1", i + 1, t);
                }
                Ok(normalised_to_voxel(*t, n))
            })
            .collect();
    }
    let default_light = [SceneLight::Grid(DEFAULT_LIGHT)];
    let scene_lights: &[SceneLight] = if mesh.lights.is_empty() {
        eprintln!(
            "note: scene '{}' has no lights; using one at grid-normalised {:?} (give your own with --light X,Y,Z)",
            mesh.name, DEFAULT_LIGHT
        );
        &default_light
    } else {
        &mesh.lights
    };
    let mut out = Vec::new();
    for l in scene_lights {
        let p = match *l {
            SceneLight::Grid(t) => normalised_to_voxel(t, n),
            SceneLight::World(w) => {
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
        };
        out.push(p);
    }
    Ok(out)
}

/// Everything `light --stats` reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LightStats {
    /// Scene name.
    pub scene: String,
    /// Grid side.
    pub n: u32,
    /// FIFO limit.
    pub fa: usize,
    /// Fraction bits of the far-plane offsets.
    pub frac_bits: u32,
    /// Scheduling policy.
    pub policy: String,
    /// Beam merging on arrival.
    pub merge: bool,
    /// Facets loaded.
    pub facets: usize,
    /// Loading cycles.
    pub load_cycles: u64,
    /// Counters summed over sources (cycles and lower bounds add up: sources run one after
    /// another).
    #[serde(flatten)]
    pub totals: DiffusionCounts,
    /// totals.cycles / totals.lower_bound.
    pub t_over_lb: f64,
    /// Voxels lit by at least one source.
    pub lit_voxels: u64,
    /// Lit marks lost to a full lit store (non-zero is an error).
    pub lit_overflows: u64,
    /// `size_of` a beam message.
    pub bytes_beam_message: usize,
    /// `size_of` a cell's lighting state (FIFO, output buffers, lit runs, counters).
    pub bytes_light_cell: usize,
    /// Per-source reports.
    pub sources: Vec<SourceReport>,
    /// Wall time of the diffusion.
    pub wall_seconds: f64,
    /// Peak resident memory (MiB).
    pub peak_rss_mib: Option<f64>,
    /// What the faulty links did (`--link-faults`).
    pub link_faults: Option<crate::faults::FaultCounts>,
}

/// Fail, naming the first cell and the capacity to raise, when a lit store overflowed (a lit
/// mark lost is a wrong image, never a silent loss).
pub fn check_lit_overflow<F: FracBits>(lighting: &Lighting<F>) -> Result<()> {
    let full: Vec<_> = lighting.cells.iter().filter(|c| c.counters.lit_overflows > 0).collect();
    if let Some(c) = full.first() {
        bail!(
            "lit store overflow in {} cell(s), first at cell ({}, {}): more than {} lit runs per column needed, \
             {} lit marks lost; raise LIT_CAP in host-sim/src/diffuse.rs, or pass --lit-visible-only \
             (keeps only the marks shading needs: same image)",
            full.len(),
            c.x,
            c.y,
            crate::diffuse::LIT_CAP,
            lighting.lit_overflows()
        );
    }
    Ok(())
}

/// Diffuse and summarise.
pub fn run_diffusion<F: FracBits>(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    progress: impl FnMut(usize, u64),
) -> Result<(Lighting<F>, LightStats)> {
    let n = scene.grid.n;
    let sources = lights.iter().enumerate().map(|(i, p)| source_at(i, *p, n)).collect::<Result<Vec<_>>>()?;
    let t0 = Instant::now();
    let lighting = diffuse::<F, DEFAULT_DEXELS>(&scene.grid, &sources, cfg, progress)?;
    check_lit_overflow(&lighting)?;
    let wall = t0.elapsed().as_secs_f64();
    let r = &lighting.reports;
    let mut totals = DiffusionCounts::default();
    for s in r {
        totals.add(&s.counts);
    }
    let stats = LightStats {
        scene: mesh.name.clone(),
        n,
        fa: cfg.fa,
        frac_bits: F::U32,
        policy: policy_name(cfg.policy).into(),
        merge: cfg.merge,
        facets: scene.facets,
        load_cycles: scene.load_cycles,
        t_over_lb: totals.t_over_lb(),
        totals,
        lit_voxels: lighting.lit_voxels().count() as u64,
        lit_overflows: lighting.lit_overflows(),
        bytes_beam_message: std::mem::size_of::<BeamMsg<F>>(),
        bytes_light_cell: std::mem::size_of::<HostLightCell<F>>(),
        sources: r.clone(),
        wall_seconds: wall,
        peak_rss_mib: crate::load::peak_rss_mib(),
        link_faults: lighting.link_faults,
    };
    Ok((lighting, stats))
}

/// The CLI name of a policy.
pub fn policy_name(p: Policy) -> &'static str {
    match p {
        Policy::Thesis => "thesis",
        Policy::Wavefront => "wavefront",
        Policy::Radial => "radial",
    }
}

/// Write `x,y,z,source_mask` for every lit voxel.
pub fn write_lit_csv<F: FracBits>(l: &Lighting<F>, mut w: impl Write) -> Result<()> {
    writeln!(w, "x,y,z,source_mask")?;
    for ([x, y, z], m) in l.lit_voxels() {
        writeln!(w, "{x},{y},{z},{m}")?;
    }
    Ok(())
}

/// Lit state of surface voxels against exact continuous visibility (SPEC §7).
///
/// A *surface voxel* for a light is an occupied voxel with an empty 6-neighbour whose centre
/// lies on the light's side of the voxel's own face (the face's plane separates them): the
/// voxels a beam from that light can enter first. Voxels of a thick wall's back layer are not
/// surface voxels for a light in front of it (their centres see the light only through their
/// own face, which the measure ignores).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Accuracy {
    /// Surface voxels, summed over lights.
    pub surface_voxels: u64,
    /// Of those, lit by beam diffusion.
    pub lit_discrete: u64,
    /// Of those, whose centre sees the light in the continuous scene (ignoring its own face).
    pub lit_continuous: u64,
    /// Lit by diffusion, dark in the continuous scene.
    pub false_lit: u64,
    /// Dark by diffusion, lit in the continuous scene.
    pub false_dark: u64,
    /// (false_lit + false_dark) / surface_voxels, in percent.
    pub disagreement_pct: f64,
}

/// Compare the discrete lit state of every surface voxel with f64 visibility of its centre
/// from each light, ignoring the voxel's own face (SPEC §7, issue 3).
pub fn accuracy<F: FracBits>(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    lighting: &Lighting<F>,
) -> Result<Accuracy> {
    let mut tris = Vec::new();
    let mut ids = Vec::new();
    for (fi, f) in mesh.faces.iter().enumerate() {
        for k in 1..f.verts.len().saturating_sub(1) {
            let p = |i: usize| mesh.positions[f.verts[i] as usize];
            tris.push([p(0), p(k), p(k + 1)]);
            ids.push(fi as u32);
        }
    }
    // Each face's plane (normal from its first non-degenerate corner, through its first vertex).
    let planes: Vec<([f64; 3], [f64; 3])> = mesh
        .faces
        .iter()
        .map(|f| {
            let p = |i: usize| mesh.positions[f.verts[i] as usize];
            let o = p(0);
            let mut nrm = [0.0; 3];
            for k in 2..f.verts.len() {
                let (a, b) = (sub3(p(k - 1), o), sub3(p(k), o));
                let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                if dot3(c, c) > 0.0 {
                    nrm = c;
                    break;
                }
            }
            (nrm, o)
        })
        .collect();
    let reference = crate::reference::Reference::new(tris, ids)?;
    let g = &scene.grid;
    let n = g.n;
    let occ = |x: i64, y: i64, z: i64| -> bool {
        x >= 0
            && y >= 0
            && z >= 0
            && x < n as i64
            && y < n as i64
            && z < n as i64
            && g.cell(x as u32, y as u32).store.occupied(z as u16).is_some()
    };
    let world_lights: Vec<[f64; 3]> = lights.iter().map(|l| voxel_to_world(&scene.fit, *l)).collect();
    let mut a = Accuracy::default();
    for c in &g.cells {
        for d in c.store.dexels() {
            let face = scene.source_face.get(d.facet as usize).copied().unwrap_or(u32::MAX);
            for z in d.span.lo..=d.span.hi {
                let (x, y, zz) = (c.x as i64, c.y as i64, z as i64);
                let empty: Vec<[f64; 3]> = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
                    .iter()
                    .filter(|&&(dx, dy, dz)| !occ(x + dx, y + dy, zz + dz))
                    .map(|&(dx, dy, dz)| {
                        voxel_to_world(&scene.fit, [(x + dx) as f64, (y + dy) as f64, (zz + dz) as f64])
                    })
                    .collect();
                if empty.is_empty() {
                    continue;
                }
                let (nrm, o) = planes.get(face as usize).copied().unwrap_or(([0.0; 3], [0.0; 3]));
                let centre = voxel_to_world(&scene.fit, [x as f64, y as f64, zz as f64]);
                let mask = lighting.mask(c.x as u32, c.y as u32, z);
                for (si, l) in world_lights.iter().enumerate() {
                    let side = dot3(nrm, sub3(*l, o)).signum();
                    if side == 0.0 || !empty.iter().any(|q| dot3(nrm, sub3(*q, o)).signum() == side) {
                        continue;
                    }
                    let disc = mask >> si & 1 == 1;
                    let cont = reference.visible(centre, *l, &[face]);
                    a.surface_voxels += 1;
                    a.lit_discrete += disc as u64;
                    a.lit_continuous += cont as u64;
                    a.false_lit += (disc && !cont) as u64;
                    a.false_dark += (!disc && cont) as u64;
                }
            }
        }
    }
    a.disagreement_pct = 100.0 * (a.false_lit + a.false_dark) as f64 / a.surface_voxels.max(1) as f64;
    Ok(a)
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

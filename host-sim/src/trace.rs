//! Recording cell traces from a grid run (issue 5): for chosen cells, every message they
//! receive, every compute cycle, every message a neighbour takes from them, in order, as
//! `cell_core::trace` records; and the digest of what they output and end up holding, computed
//! from the grid itself. A firmware (or [`cell_core::trace::replay`]) drives a fresh cell
//! through the records and must reach the same digest.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use cell_core::beam::FracBits;
use cell_core::cell::DEFAULT_DEXELS;
use cell_core::facet::RowPacket;
use cell_core::light::{BeamMsg, FrustumSummary, LightEnv, Port, Step};
use cell_core::link::{self, Message};
use cell_core::shade::{cell_pixel, NormalMode, ShadeParams};
use cell_core::trace::{
    write_event, Digester, Event, Header, LightSetup, Replayer, ShadeSetup, MAX_LIGHTS, MAX_MATERIALS,
};

use crate::diffuse::{diffuse_tapped, source_at, LightConfig, FA_CAP, LIT_CAP, OB_CAP};
use crate::lightjob::LoadedScene;
use crate::precompute::LoadConfig;
use crate::render::{cell_material, point_lights, AMBIENT};
use crate::scene::Mesh;

/// Records one cell.
pub struct CellRecorder {
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
    bytes: Vec<u8>,
    digest: Digester,
    steps: u32,
    records: u64,
}

impl CellRecorder {
    fn new(x: u32, y: u32) -> Self {
        CellRecorder { x, y, bytes: Vec::new(), digest: Digester::new(), steps: 0, records: 0 }
    }

    fn push<F: FracBits>(&mut self, ev: &Event<'_, F>) {
        if !matches!(ev, Event::Step(_)) {
            self.flush_steps::<F>();
        }
        let mut buf = [0u8; 2048];
        // Cannot fail: the largest record (shading with 8 lights and 16 materials) is < 1 KiB.
        let len = write_event(ev, &mut buf).expect("trace record fits its buffer");
        self.bytes.extend_from_slice(&buf[..len]);
        self.records += 1;
    }

    fn flush_steps<F: FracBits>(&mut self) {
        if self.steps > 0 {
            let n = std::mem::take(&mut self.steps);
            self.push::<F>(&Event::Step(n));
        }
    }

    /// A row packet arrives (before the cell processes it).
    pub fn row(&mut self, p: &RowPacket) {
        self.push::<cell_core::beam::frac::U0>(&Event::Row(p.clone()));
    }

    /// The cell forwarded the (stepped) packet east.
    pub fn forwarded(&mut self, p: &RowPacket) {
        self.digest.forwarded(p);
    }

    /// The source emitter hands the cell a beam.
    pub fn inject<F: FracBits>(&mut self, m: &BeamMsg<F>) {
        self.push(&Event::Inject(*m));
    }

    /// One compute cycle and its result.
    pub fn step(&mut self, r: Step) {
        self.steps += 1;
        self.digest.step(r);
    }

    fn frame<F: FracBits>(m: &BeamMsg<F>) -> ([u8; cell_core::trace::BEAM_FRAME], usize) {
        let mut buf = [0u8; cell_core::trace::BEAM_FRAME];
        // Cannot fail: a beam frame has a fixed size.
        let len = link::encode(0, &Message::Beam(*m), &mut buf).expect("beam frame fits");
        (buf, len)
    }

    fn recv<F: FracBits>(&mut self, port: Port, m: &BeamMsg<F>) {
        let (buf, len) = Self::frame(m);
        self.push::<F>(&Event::Recv { port, frame: &buf[..len] });
    }

    fn grant<F: FracBits>(&mut self, port: Port, m: &BeamMsg<F>) {
        self.push::<F>(&Event::Grant(port));
        let (buf, len) = Self::frame(m);
        self.digest.sent(port, &buf[..len]);
    }
}

/// The cells being recorded, by grid index.
pub struct Tap {
    recorders: Vec<CellRecorder>,
    by_index: HashMap<usize, usize>,
}

impl Tap {
    /// Watch cells `cells` of an n × n grid with `depth` voxels per column; writes each header.
    pub fn new<F: FracBits>(n: u32, depth: u32, cells: &[[u32; 2]]) -> Result<Self> {
        let mut t = Tap { recorders: Vec::new(), by_index: HashMap::new() };
        for &[x, y] in cells {
            if x >= n || y >= n {
                bail!("cell ({x}, {y}) is outside the {n} × {n} grid");
            }
            let idx = (y * n + x) as usize;
            if t.by_index.contains_key(&idx) {
                continue;
            }
            let mut r = CellRecorder::new(x, y);
            let h: Header = Replayer::<F, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>::header(x as u16, y as u16, depth);
            r.push::<F>(&Event::Header(h));
            t.by_index.insert(idx, t.recorders.len());
            t.recorders.push(r);
        }
        Ok(t)
    }

    /// The recorder of cell `idx`, if watched.
    pub fn get(&mut self, idx: usize) -> Option<&mut CellRecorder> {
        let i = *self.by_index.get(&idx)?;
        self.recorders.get_mut(i)
    }

    /// A source's diffusion starts.
    pub fn light<F: FracBits>(&mut self, env: &LightEnv<'_, F>, frustum: Option<&FrustumSummary>) {
        let s = LightSetup {
            source: *env.source,
            n: env.n,
            depth: env.depth,
            far: env.far.get(),
            policy: env.policy,
            fa: env.fa as u16,
            merge: env.merge,
            source_bit: env.source_bit,
            skip: env.skip,
            hold: env.hold,
            frustum: frustum.copied(),
            rule: env.rule,
        };
        for r in &mut self.recorders {
            r.push::<F>(&Event::Light(s));
        }
    }

    /// Cell `from` sent `m` through its port `port` to cell `to`.
    pub fn transfer<F: FracBits>(&mut self, from: usize, to: usize, port: Port, m: &BeamMsg<F>) {
        if let Some(r) = self.get(from) {
            r.grant(port, m);
        }
        if let Some(r) = self.get(to) {
            let (dx, dy) = port.delta();
            // Cannot fail: the opposite of a unit step is a unit step.
            r.recv(Port::from_delta(-dx, -dy).expect("opposite port"), m);
        }
    }
}

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
}

/// Run loading and lighting on the grid, recording the chosen cells.
pub fn record<F: FracBits>(job: &TraceJob<'_>) -> Result<Vec<CellTrace>> {
    let n = job.load.n;
    if job.mesh.materials.len() > MAX_MATERIALS {
        bail!("{} materials: a trace carries at most {MAX_MATERIALS}", job.mesh.materials.len());
    }
    let sources_of = |scene: &LoadedScene| -> Result<(Vec<[f64; 3]>, Vec<cell_core::beam::Source>)> {
        let lights = crate::lightjob::resolve_lights(job.mesh, scene, &job.lights)?;
        let sources = lights.iter().enumerate().map(|(i, p)| source_at(i, *p, n)).collect::<Result<Vec<_>>>()?;
        Ok((lights, sources))
    };
    let mut cells = job.cells.clone();
    if job.busiest {
        let scene = crate::lightjob::load_scene(job.mesh, &job.load)?;
        let (_, sources) = sources_of(&scene)?;
        let l = crate::diffuse::diffuse::<F, DEFAULT_DEXELS>(&scene.grid, &sources, &job.light, |_, _| {})?;
        let b = l.reports.iter().max_by_key(|r| r.counts.lb_cell_load).map(|r| r.busiest_cell);
        cells.extend(b);
    }
    if cells.is_empty() {
        bail!("no cell to record: give --cell X,Y or --busiest");
    }
    let mut tap = Tap::new::<F>(n, n, &cells)?;
    let scene: LoadedScene = crate::lightjob::load_scene_tapped(job.mesh, &job.load, Some(&mut tap))?;
    let (lights, sources) = sources_of(&scene)?;
    if lights.len() > MAX_LIGHTS {
        bail!("{} lights: a trace carries at most {MAX_LIGHTS}", lights.len());
    }
    let lighting = diffuse_tapped::<F, DEFAULT_DEXELS>(&scene.grid, &sources, &job.light, Some(&mut tap), |_, _| {})?;
    let shade = ShadeSetup {
        params: ShadeParams { ambient: [AMBIENT; 3], normal_mode: NormalMode::Facet },
        lights: point_lights(&lights).into_iter().collect(),
        materials: job.mesh.materials.iter().map(cell_material).collect(),
    };
    let mut out = Vec::new();
    for mut r in tap.recorders {
        let idx = (r.y * n + r.x) as usize;
        let (cell, light) = (&scene.grid.cells[idx], &lighting.cells[idx]);
        let (lit, visible) = (&light.lit, light.visible_lit);
        let (mats, lights) = (&shade.materials, &shade.lights);
        let px = cell_pixel(job.light.rule, cell, |z| lit.mask_at(z), visible, mats, lights, &shade.params);
        r.push::<F>(&Event::Shade(shade.clone()));
        r.push::<F>(&Event::End);
        r.digest.state(cell, light, px);
        out.push(CellTrace { x: r.x, y: r.y, records: r.records, digest: r.digest.finish(), bytes: r.bytes });
    }
    Ok(out)
}

/// Replay a trace with the host's build of `cell_core` (the same code the firmware runs).
pub fn replay<F: FracBits>(bytes: &[u8]) -> Result<(u64, cell_core::trace::ReplayStats)> {
    cell_core::trace::replay::<F, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>(bytes)
        .map_err(|e| anyhow::anyhow!("trace replay failed: {e:?}"))
}

/// Write each trace as `cell_X_Y.rc2t` and a `digests.json` listing them.
pub fn write_traces(dir: &Path, traces: &[CellTrace]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut list = Vec::new();
    for t in traces {
        let name = format!("cell_{}_{}.rc2t", t.x, t.y);
        std::fs::write(dir.join(&name), &t.bytes).with_context(|| format!("cannot write {name}"))?;
        list.push(serde_json::json!({
            "file": name, "x": t.x, "y": t.y, "bytes": t.bytes.len(), "records": t.records,
            "digest": format!("{:016x}", t.digest),
        }));
    }
    let json = serde_json::to_string_pretty(&serde_json::json!({ "traces": list }))?;
    std::fs::write(dir.join("digests.json"), json).context("cannot write digests.json")?;
    Ok(())
}

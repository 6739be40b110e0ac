//! The `trace` job: record cell traces of a grid run ([`crate::machine::record`]), write them
//! with their digests, and replay each with the host's build of `cell-core`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::jobs::light::LightingOptions;
use crate::machine::rays::mirror::ReflectConfig;
pub use crate::machine::record::{record, replay, CellTrace, TraceJob};

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

/// What the `trace` job records and where.
#[derive(Clone, Debug)]
pub struct TraceOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// The view: fitted, the scene's camera, or a camera of the user's.
    pub view: crate::scene::camera::ViewChoice,
    /// Lights and lighting settings: beam diffusion, or classic shadow rays.
    pub light: LightingOptions,
    /// The reflection phase after shading (`None`: none).
    pub reflections: Option<ReflectConfig>,
    /// Cells to record, `[x, y]`.
    pub cells: Vec<[u32; 2]>,
    /// Also record the cell that processes the most beams.
    pub busiest: bool,
    /// Directory for the traces and `digests.json`.
    pub out: PathBuf,
}

/// Run the `trace` job: record, write, and replay every trace with the host's build of
/// `cell-core` (the same digest, or the trace is wrong).
pub fn run(o: &TraceOptions) -> Result<()> {
    // Reflected rays are traced in the grid's own view: with reflections the default view is
    // the fitted one (as `render` has it).
    let view = match o.view {
        crate::scene::camera::ViewChoice::Auto if o.reflections.is_some() => crate::scene::camera::ViewChoice::Fitted,
        v => v,
    };
    if o.light.refine.is_some() {
        bail!("--lighting refined is not recorded by trace: record --lighting diffusion and --lighting classic");
    }
    let load = *o.light.load();
    let mesh = crate::scene::camera::apply(crate::scene::load(&o.scene)?, &view, load.n)?;
    eprintln!("{}", o.light.run.describe());
    let job = TraceJob {
        mesh: &mesh,
        load,
        light: o.light.config(),
        lights: o.light.lights.clone(),
        cells: o.cells.clone(),
        busiest: o.busiest,
        classic: o.light.classic,
        reflections: o.reflections,
    };
    let traces = record(&job)?;
    write_traces(&o.out, &traces)?;
    for t in &traces {
        let (d, st) = replay(job.light.frac_bits, &t.bytes)?;
        let ok = if d == t.digest { "replay ok" } else { "REPLAY MISMATCH" };
        println!(
            "cell ({:>3}, {:>3}): {:>6} bytes, {:>5} records ({} rows, {} beams/rays in, {} cycles, {} sent, {} answers), \
             digest {:016x}, {ok}",
            t.x,
            t.y,
            t.bytes.len(),
            t.records,
            st.rows,
            st.received,
            st.steps,
            st.sent,
            st.answers,
            t.digest
        );
        if d != t.digest {
            bail!("replaying the trace of cell ({}, {}) gave digest {d:016x}", t.x, t.y);
        }
    }
    println!("traces written to {}", o.out.display());
    Ok(())
}

//! The machine: an n × n grid of `cell_core` cells and the host code that steps them, cycle by
//! cycle, through every phase. Nothing here knows about jobs, reports or the command line.
//!
//! One folder per phase, each standing only on the ones listed before it (no import circle
//! between them: `host-sim/tests/integration/architecture.rs` checks it):
//!
//! * [`grid`] — what every phase stands on: the grid of cells, their capacities, each column's
//!   triangles, the host's memory limits, the pieces of the cell array.
//! * [`links`] — the links between cells behind `cell_core::link::Link`, the fault-injecting
//!   wrapper and the trace tap.
//! * [`loading`] — the loading wave (§3.9), its engines and its check; the loaded scene.
//! * [`lighting`] — beam diffusion (ch. 4), a whole lighting run, exact occluders, the timing
//!   rules, the ray-by-ray mode, the asynchronous boards.
//! * [`shading`] — the cells' shading of their pixels (§1.1, §5.2), smooth shading's records.
//! * [`rays`] — classic shadow rays (§4.1.2) and mirror reflections (§1.3.2, ch. 5), and the
//!   router network that carries their answers.
//! * [`shooting`] — progressive radiosity's shots and the indirect light they show.
//! * [`record`] — a whole traced run through every phase (the `trace` job's machine).

pub mod grid;
pub mod lighting;
pub mod links;
pub mod loading;
pub mod rays;
pub mod record;
pub mod shading;
pub mod shooting;

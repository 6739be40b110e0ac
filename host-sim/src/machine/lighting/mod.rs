//! The lighting phase (thesis ch. 4, §4.2–4.4): every source's light diffused over the loaded
//! grid as beams split layer by layer, cycle by cycle, until the grid is quiescent.
//!
//! * [`diffuse`] — the beam-diffusion scheduler: a run's settings, results and entry points,
//!   the cycle loop, the skips' occupancy summaries and the frustum shortcut.
//! * [`run`] — a whole lighting run over a loaded scene: its lit-store checks and statistics.
//! * [`occluders`] — exact occluders for one source (§5.5.6): each column's triangles and its
//!   target ray, and the contact exchange.
//! * [`timing`] — the timing rules of the cycle model that the thesis leaves open
//!   (§4.4.1–4.4.3); [`sequential`] — the ray-by-ray emission mode beams are weighed against
//!   (§4.2.4).
//! * [`boards`] — the grid as asynchronous boards whose phases end by distributed termination
//!   detection (§4.4.4), checked against the host's ground truth.
//!
//! Invariant: no beam is ever lost (the no-loss rule, §4.4.2) and no timing rule, link stack or
//! schedule changes which rays a beam carries or where they stop — only cycles, messages and
//! FIFO occupancy. Lighting stands on the grid, the links and the loaded scene; it imports
//! nothing of shading, rays or radiosity (a radiosity shot is a diffusion it runs for them,
//! `diffuse::diffuse_shot`).

pub mod boards;
pub mod diffuse;
pub mod occluders;
pub mod run;
pub mod sequential;
pub mod timing;

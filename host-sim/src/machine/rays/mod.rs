//! The ray phases (thesis §4.1.2–4.1.3, §1.3.2, §5.2, §5.5): rays that walk the grid voxel by
//! voxel and are answered through routers — the classic shadow rays beam diffusion replaces
//! (or refines at shadow edges), and the distributed ray tree of mirror reflections.
//!
//! * [`classic`] — classic shadow rays on the diffusion's cycle model, and the shadow-edge
//!   refinement after a diffusion.
//! * [`mirror`] — the reflection phase: reflected rays, the cells' wait tables, the answers
//!   sent back up the tree.
//! * [`network`] — the routers of the whole grid that carry their answers (§1.3, §4.1.3).
//!
//! Invariant: the same cycle model as diffusion — one voxel step per cell and cycle, FIFOs of
//! `fa` rays, one message per link, direction and cycle, no message lost (a ray that cannot
//! leave waits); a cycle with messages in flight and nothing moving is a deadlock, reported.
//! The ray phases stand on the loaded scene, lighting's counts and shading's materials.

pub mod classic;
pub mod mirror;
pub mod network;

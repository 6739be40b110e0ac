//! Progressive radiosity on the grid (radiosity thesis §1.3.2, §3.4, ch. 5): patches shoot their
//! unshot energy one after another, each shot one beam diffusion whose beams carry their rays'
//! energy; the solution is then shown as every cell's indirect light.
//!
//! * [`shots`] — one shot in machine phases (broadcast, diffusion, collection, the costed
//!   reduction to the supervisor) and the supervisor's progressive loop.
//! * [`proxels`] — shots by projection (radiosity thesis §6.2): the shooter's hemicube or disk
//!   distributed over the cells, its depth buffer z-tested there, the update's alternatives costed.
//! * [`reduce`] — the pipelined merge of the cells' (patch, quanta) lists to the supervisor,
//!   costed to the cycle; both kinds of shot use it.
//! * [`indirect`] — showing the solution (radiosity thesis §1.3.1): each cell's indirect light
//!   of its visible point, broadcast and costed, handed to shading as its ambient term.
//!
//! Invariant (tested): per shot, quanta received (lost ones included) + quanta that left the grid
//! = quanta emitted, exactly ([`shots::ShotLog::balanced`]); a shot's diffusion is the lighting
//! phase's own, not a copy.
//! Radiosity stands on the grid, the loaded scene and the lighting phase.

pub mod indirect;
pub mod proxels;
pub mod reduce;
pub mod shots;

//! Independent test oracles for the voxelizer (thesis ch. 3) and the lighting (ch. 4–5).
//!
//! Pure `std`, exact `i128` integer arithmetic, no dependency on `cell-core` or `host-sim`:
//! these modules restate the project's definitions directly so that the cell wave and the host
//! voxelizer can be judged against them.
//!
//! * [`brute`] — which voxels belong to a facet (thickness band + contour), by brute force.
//! * [`tunnels`] — k-tunnels: adjacent free voxel pairs on opposite sides of a surface.
//! * [`lines`] — reference walks of 6/18/26-connected discrete 3D lines (f64, exact here).
//! * [`inside`] — strict inside/outside of voxel centres for a closed mesh, by column parity.
//! * [`flood`] — flood fill from outside the grid and leaks into the mesh's interior.
//! * [`rays`] — per-ray lighting under the thesis's rule (§4.1.5, §5.5.5).
//! * [`lit`] — per-ray lighting under the plane-aware rule (§5.5.6).
//! * [`exact`] — per-ray fates under exact occluders: the triangles kept by the columns a ray
//!   passes through, each met in one segment of its walk (§5.5.6).
//! * [`shadow`] — classic shadow rays under the plane principle, by brute force (§4.1.2).

pub mod brute;
pub mod exact;
pub mod flood;
pub mod inside;
pub mod lines;
pub mod lit;
pub mod rays;
pub mod shadow;
pub mod tunnels;

//! Scenes: what the host loads before the machine runs.
//!
//! * [`mesh`] — polygons, materials, lights; the OBJ/MTL reader.
//! * [`builtin`] — the built-in scenes and [`load`], by name or path.
//! * [`camera`] — the geometry stage: a camera and the map to screen space (thesis §1.3).
//! * [`view`] — a camera's view transform (look-at basis, screen maps, depth range).
//! * [`office`] — the procedural offices of the radiosity thesis (bureau1, bureau2, classe).
//! * [`meshops`] — winding orientation, subdivision.
//! * [`normals`] — vertex normals for smooth shading: the file's `vn` or area-averaged.
//! * [`binvox`] — the `.binvox` voxel file format.
//! * [`patches`] — radiosity patches: a mesh cut into small planar convex polygons
//!   (Renaud 1993, §1.3.3).
//! * [`patch_display`] — showing a radiosity solution: a point's place on its patch, shared
//!   vertices, the exposure of indirect light (Renaud 1993, §1.3.1).
//!
//! Modules of this folder import each other by `super::…`, never through this file: the
//! re-exports below are for the rest of the crate.

pub mod binvox;
pub mod builtin;
pub mod camera;
pub mod mesh;
pub mod meshops;
pub mod normals;
pub mod office;
pub mod patch_display;
pub mod patches;
pub mod view;

pub use builtin::{load, BUILTINS};
pub use mesh::{add_floor, load_obj_bytes, parse_obj, Face, LightAt, Material, Mesh, SceneLight};

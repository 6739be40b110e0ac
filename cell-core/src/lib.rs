//! # cell-core — what one RC² cell runs
//!
//! RC² (Vidal, Lille 1992) is an n × n grid of small processors. Cell (x, y) owns the whole
//! voxel column {(x, y, z)} and stores it as **dexels**: short sorted z ranges (§3.4).
//! This crate is exactly the code one cell runs, with no `std` and no allocation: every store
//! has its capacity in its type (heapless), every overflow is a counted event, and every
//! integer in the loading phase is exact (see [`voxelize`] for the bit budget).
//!
//! * [`units`] — integer types named for their meaning (column index, depth, facet id …).
//! * [`facet`] — the facet packets the host injects and the cells pass on (§3.9).
//! * [`voxelize`] — the pipeline cell and the row cell of the loading wave (§3.5–3.9).
//! * [`dexel`] — the per-cell dexel store (§3.4).
//! * [`normal`] — the 16-bit octahedral normal code stored with each dexel.
//! * [`plane`] — the facet plane stored with each dexel (for the plane-aware lit rule).
//! * [`cell`] — one cell: its store and counters.
//! * [`beam`] — light beams and their split (§4.3).
//! * [`light`] — the lighting phase: FIFO, ports, back-pressure, lit voxels, quiescence (§4.4).
//! * [`lit`] — the lit rules: the thesis's (§5.5.5) and the plane rule for grazing light (§5.5.6).
//! * [`radiosity`] — a shooting patch's energy: the form factor of a beam's rays, exactly
//!   conserved by the split, and the per-column patch accumulators (radiosity thesis §1.3.2, §3.4).
//! * [`proxel`] — proxel-parallel form factors (radiosity thesis §6.2): a cell's share of a
//!   projection surface's proxels, their depth test, and the quanta of the facets it owns.
//! * [`occupancy`] — a coarse block summary of the scene and the sound empty-frustum beam skip.
//! * [`wire`] — the bytes a link carries: framed messages with a CRC (parse and emit).
//! * [`link`] — the link seam: one `Link` trait for the perfect link, the `embedded-hal` link
//!   and their wrappers.
//! * [`serial`] — a reliable frame link over a byte stream (a UART, through `embedded-io`):
//!   every frame exactly once and in order, whatever bytes the wire corrupts or drops.
//! * [`trace`] — cell traces (what a cell received, as frames) and their replay through the real cell.
//! * [`ray`] — incremental 6/18/26-connected 3D lines for shadow and reflected rays (§2.3).
//! * [`shadow`] — the classic shadow-ray cell: emission, ray walking, answers (§4.1.2–4.1.3).
//! * [`route`] — destination-addressed routers with virtual channels, deadlock-free (§1.3, §4.1.3).
//! * [`reflect`] — reflected rays: mirrored directions, the ray walk, answers (§5.2, §5.5).
//! * [`reflect_cell`] — the reflection cell: ray FIFOs, wait table, answers (§1.3.2, §5.5.5).
//! * [`refract`] — the refracted branch's direction: Snell's law in integers, total internal
//!   reflection (§1.1, §1.2.5).
//! * [`visible`] — the surface the pixel shows: a per-cell depth test of the exact facets during loading.
//! * [`shade`] — Phong/Blinn shading of the visible voxel with `micromath` (§1.1, §5.2).
//! * [`smooth`] — smooth shading (feature `smooth-normals`): vertex normals in the packets,
//!   interpolated at the visible point (Phong) or the colours they shade (Gouraud) (§1.3.2).
//! * [`subpixel`] — s × s samples per pixel: visible surfaces at sub-pixel points, their lights
//!   from the neighbours that show their facets, the pixel their mean (§1.2.5.2).
//! * [`termination`] — distributed termination detection: Safra's token ring with message
//!   counters over the boards' links (§4.4.4 without a central counter).
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod beam;
pub mod bytes;
pub mod cell;
pub mod dexel;
pub mod facet;
pub mod light;
pub mod link;
pub mod lit;
pub mod normal;
pub mod occluder;
pub mod occupancy;
pub mod plane;
pub mod proxel;
pub mod radiosity;
pub mod ray;
pub mod receiver;
pub mod reflect;
pub mod reflect_cell;
pub mod refract;
pub mod route;
pub mod serial;
pub mod shade;
pub mod shadow;
#[cfg(feature = "smooth-normals")]
pub mod smooth;
pub mod subpixel;
pub mod termination;
pub mod trace;
pub mod triangle;
pub mod units;
pub mod visibility;
pub mod visible;
pub mod voxelize;
pub mod wire;

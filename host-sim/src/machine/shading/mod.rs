//! The shading phase (thesis §1.1, §5.2, §1.3.2): every cell shades the surface its pixel shows,
//! one step per light, from its own lit state.
//!
//! * [`pixels`] — the cells' shading of their pixels (flat or smooth, what each pixel sees
//!   under the run's lit rule, the ambient term) and its f64 counterpart.
//! * [`samples`] — S × S samples per pixel: each sample's surface from the packets, its lights
//!   from the cell or the neighbour showing its facet, the pixel their mean.
//! * [`smooth_surface`] — smooth shading's records: the vertex normals each facet packet
//!   carries and each cell's record of its visible point (Gouraud / Phong interpolation).
//!
//! Invariant: a pixel is a function of its own cell's state and the lights alone (no messages),
//! except under samples, where it also reads one message from each of its 8 neighbours.
//! Shading stands on the loaded scene and a lighting run's result; the ray phases and radiosity
//! build on it, not it on them (radiosity's indirect light comes in as plain per-cell values).

pub mod pixels;
pub mod samples;
pub mod smooth_surface;

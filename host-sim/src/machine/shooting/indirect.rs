//! Showing a radiosity solution on the grid (radiosity thesis §1.3.1, "Visualisation de la
//! scène"; §1.1.1 and §1.3.2 for the ambient terms): after the shots ([`super::shots`]) every
//! cell's pixel shows its direct light — the point lights' diffusion and shading, as without
//! radiosity — plus the indirect light of its visible point, which takes the place of the local
//! model's empirical ambient source (§1.1.1: "l'ensemble de l'énergie lumineuse qui provient de
//! l'environnement par l'intermédiaire des diverses réflexions entre objets"): the cell shades
//! with `Ia` its indirect irradiance and `Ka := Kd` ([`crate::machine::shading::pixels::Ambient::Indirect`]).
//!
//! In machine phases:
//! 1. **host load** (once, with the patch runs): each cell gets the keys of its visible point —
//!    the patch holding it ([`Display::Flat`]), or that patch's vertices with the point's
//!    interpolation weights ([`Display::Smooth`], Gouraud's double linear interpolation of
//!    §1.1.2 on vertex values, §1.3.1) — in its [`cell_core::radiosity::IndirectPixel`]. Geometry:
//!    [`crate::scene::patch_display`].
//! 2. **supervisor**: patch j's display value is `k ⊙ (H_j + a)` ([`patch_values`]): its
//!    indirect irradiance, plus §1.3.2's ambient term of the power still unshot (display only),
//!    times the exposure `k` that puts it in the point lights' units. Smooth: each vertex's value
//!    is the area-weighted mean of its patches'. P operations (+ one per patch corner).
//! 3. **broadcast**: R records (P patches or V vertices), each a 16-bit key and three `f32`
//!    (14 bytes), pipelined from cell (0, 0) over the grid along the shot broadcast's tree
//!    (one record per link and cycle): the first reaches the far corner after n − 1 cycles, the
//!    last R − 1 cycles later; R (n² − 1) messages. Costed, not simulated message by message
//!    (as the shot broadcast): a cell keeps exactly the records its keys name, so the result
//!    is the direct lookup [`show`] makes.
//! 4. **cells**: `Ia = Σ w_k value(key_k)` ([`cell_core::radiosity::IndirectPixel::hear`]), then the shading step.
//!
//! **Invariant:** a cell's `Ia` is a convex combination of its keys' values (weights ≥ 0
//! summing to 1): flat, its patch's value rounded to `f32`.

use anyhow::{bail, Result};
use cell_core::lit::LitRule;
use parry3d_f64::math::Vector;

use crate::machine::grid::capacity::{CellIndirectFlat, CellIndirectSmooth};
use crate::machine::loading::loaded_scene::{grid_to_world, LoadedScene};
use crate::scene::patch_display::{by_face, locate, weights, Vertices};
use crate::scene::patches::{Patch, Patches};
use crate::scene::Mesh;

/// How a cell shows its patch's radiosity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Display {
    /// The value of the patch holding the visible point: constant over each patch.
    Flat,
    /// Bilinear (barycentric) interpolation of vertex values, each the area-weighted mean of
    /// the patches around the vertex on the same planar piece (§1.3.1).
    Smooth,
}

/// Bytes of one broadcast record: a 16-bit key and three `f32`.
pub const RECORD_BYTES: u64 = 2 + 12;

/// The patches as the display reads them: by face, their shared vertices, the display.
pub struct Surfaces<'a> {
    patches: &'a [Patch],
    by_face: Vec<Vec<usize>>,
    vertices: Vertices,
    display: Display,
}

impl<'a> Surfaces<'a> {
    /// The display of `p`'s patches on a mesh of `faces` faces. Errors: more records than a
    /// 16-bit key names.
    pub fn new(p: &'a Patches, faces: usize, display: Display) -> Result<Self> {
        let s =
            Surfaces { patches: &p.patches, by_face: by_face(&p.patches, faces), vertices: Vertices::new(p), display };
        if s.records() > u16::MAX as usize + 1 {
            bail!(
                "radiosity display: {} {} to broadcast, a cell names at most 65 536 (raise --patch-size)",
                s.records(),
                if display == Display::Flat { "patches" } else { "vertices" }
            );
        }
        Ok(s)
    }

    /// The display.
    pub fn display(&self) -> Display {
        self.display
    }

    /// Number of records broadcast: patches (flat) or vertices (smooth).
    pub fn records(&self) -> usize {
        match self.display {
            Display::Flat => self.patches.len(),
            Display::Smooth => self.vertices.count,
        }
    }

    /// Number of shared vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices.count
    }

    /// The records the supervisor broadcasts, from per-patch values.
    pub fn record_values(&self, patch_values: &[[f64; 3]]) -> Vec<[f64; 3]> {
        match self.display {
            Display::Flat => patch_values.to_vec(),
            Display::Smooth => self.vertices.average(self.patches, patch_values),
        }
    }

    /// The supervisor's operations: one per patch value, and one per patch corner to average.
    pub fn supervisor_ops(&self) -> u64 {
        let average = if self.display == Display::Smooth { self.vertices.incidences() } else { 0 };
        (self.patches.len() + average) as u64
    }

    /// The records a point `x` (world) of face `face` reads, with their weights; empty when the
    /// face has no patch.
    pub fn keys(&self, face: usize, x: Vector) -> Vec<(usize, f64)> {
        let cands = self.by_face.get(face).map(Vec::as_slice).unwrap_or(&[]);
        let Some(j) = locate(self.patches, cands, x) else {
            return Vec::new();
        };
        match self.display {
            Display::Flat => vec![(j, 1.0)],
            Display::Smooth => {
                let w = weights(&self.patches[j], x);
                self.vertices.of_patch[j].iter().zip(w).map(|(&v, w)| (v as usize, w)).collect()
            }
        }
    }

    /// The value at a point in `f64` (the reference image's): `Σ w · records[key]`.
    pub fn value_at(&self, records: &[[f64; 3]], face: usize, x: Vector) -> [f64; 3] {
        let mut v = [0.0; 3];
        for (k, w) in self.keys(face, x) {
            for c in 0..3 {
                v[c] += w * records[k][c];
            }
        }
        v
    }
}

/// The supervisor's display value of every patch: `k ⊙ (indirect + a)` with `a` the ambient
/// term of §1.3.2 for the power still `unshot` ([`crate::truth::radiosity::ambient`]).
pub fn patch_values(patches: &[Patch], indirect: &[[f64; 3]], unshot: &[[f64; 3]], k: [f64; 3]) -> Vec<[f64; 3]> {
    let a = crate::truth::radiosity::ambient(patches, unshot);
    indirect.iter().map(|h| [0, 1, 2].map(|c| k[c] * (h[c] + a[c]))).collect()
}

/// Per cell (row-major) the face and world point its pixel shows under `rule` — the first
/// occupied voxel (thesis's rule) or the exact visible surface (plane rule) — or `None`.
pub fn visible_points(mesh: &Mesh, scene: &LoadedScene, rule: LitRule) -> Vec<Option<(usize, Vector)>> {
    let face = |facet: u32| scene.source_face.get(facet as usize).map(|&f| f as usize);
    scene
        .grid
        .cells
        .iter()
        .map(|c| {
            let (x, y) = (c.x as f64, c.y as f64);
            let (facet, z) = if rule.shades_visible_surface() {
                c.visible.as_ref().map(|s| (s.facet, s.depth() as f64))?
            } else {
                c.store.dexels().first().map(|d| (d.facet, d.span.lo as f64))?
            };
            Some((face(facet)?, Vector::from(grid_to_world(mesh, scene, [x, y, z]))))
        })
        .collect()
}

/// What the display costs the grid.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DisplayCost {
    /// Records broadcast (patches or vertices).
    pub records: u64,
    /// Bytes of one record.
    pub record_bytes: u64,
    /// Cycles of the pipelined broadcast: n − 1 + R − 1.
    pub broadcast_cycles: u64,
    /// Its messages: R (n² − 1).
    pub broadcast_messages: u64,
    /// Supervisor operations.
    pub supervisor_ops: u64,
    /// Bytes a cell holds for it (its `IndirectPixel`).
    pub bytes_per_cell: u64,
}

/// What the cells show of a solution.
pub struct Shown {
    /// Per cell (row-major) its indirect irradiance `Ia`.
    pub cells: Vec<[f32; 3]>,
    /// Covered cells whose visible face has no patch (`Ia` = 0 there).
    pub missing: u64,
    /// The cost.
    pub cost: DisplayCost,
}

/// Load every cell's keys (phase 1), broadcast the supervisor's `records` (phases 2–3) and let
/// the cells sum what they hear (phase 4). `points` from [`visible_points`], grid side `n`.
///
/// Errors: a cell with more keys than its `IndirectPixel` holds (cannot happen: a patch has at
/// most 4 corners; reported, not silent).
pub fn show(s: &Surfaces<'_>, records: &[[f64; 3]], points: &[Option<(usize, Vector)>], n: u32) -> Result<Shown> {
    let mut missing = 0;
    let mut cells = Vec::with_capacity(points.len());
    for (i, pt) in points.iter().enumerate() {
        let mut px = CellIndirectSmooth::new();
        if let Some((face, x)) = pt {
            let keys = s.keys(*face, *x);
            missing += u64::from(keys.is_empty());
            for (k, w) in keys {
                if !px.listen(k as u16, w as f32) {
                    bail!("radiosity display: cell {i} reads more than 4 records");
                }
            }
        }
        // The broadcast, as the cell hears it: the records its keys name.
        let heard: Vec<u16> = px.keys().to_vec();
        for k in heard {
            px.hear(k, records[k as usize].map(|v| v as f32));
        }
        cells.push(px.rgb());
    }
    let r = records.len() as u64;
    let bytes_per_cell = match s.display {
        Display::Flat => std::mem::size_of::<CellIndirectFlat>(),
        Display::Smooth => std::mem::size_of::<CellIndirectSmooth>(),
    } as u64;
    let cost = DisplayCost {
        records: r,
        record_bytes: RECORD_BYTES,
        broadcast_cycles: if r == 0 { 0 } else { n as u64 - 1 + r - 1 },
        broadcast_messages: r * ((n as u64).pow(2) - 1),
        supervisor_ops: s.supervisor_ops(),
        bytes_per_cell,
    };
    Ok(Shown { cells, missing, cost })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Face, Material};

    /// A 2 × 1 strip cut into two unit patches.
    fn strip() -> Patches {
        let positions = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let faces = vec![Face { verts: vec![0, 1, 2, 3], material: 0 }];
        let m = Mesh { name: "s".into(), positions, faces, materials: vec![Material::default()], ..Default::default() };
        crate::scene::patches::subdivide(&m, 1.0, 10).unwrap()
    }

    #[test]
    fn flat_shows_the_patch_value_and_smooth_interpolates_between_neighbours() {
        let p = strip();
        assert_eq!(p.patches.len(), 2);
        let values = vec![[1.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let left = p.patches.iter().position(|q| q.centroid.x < 1.0).unwrap();
        let values = if left == 0 { values } else { vec![values[1], values[0]] };
        let at = |x: f64| Some((0usize, Vector::new(x, 0.5, 0.0)));
        let points = vec![at(0.0), at(0.5), at(0.999), at(1.5), None];
        let flat = Surfaces::new(&p, 1, Display::Flat).unwrap();
        let shown = show(&flat, &flat.record_values(&values), &points, 4).unwrap();
        let r: Vec<f32> = shown.cells.iter().map(|c| c[0]).collect();
        assert_eq!(r, vec![1.0, 1.0, 1.0, 3.0, 0.0]);
        // Smooth: the shared edge's vertices average the two patches (2), the outer ones keep
        // their patch's value; linear in between.
        let smooth = Surfaces::new(&p, 1, Display::Smooth).unwrap();
        assert_eq!(smooth.records(), 6);
        let shown = show(&smooth, &smooth.record_values(&values), &points, 4).unwrap();
        let want = [1.0, 1.5, 2.0, 2.5, 0.0];
        for (c, w) in shown.cells.iter().zip(want) {
            assert!((c[0] - w).abs() < 1e-3, "{} vs {w}", c[0]);
        }
        assert_eq!(shown.cost.records, 6);
        assert_eq!(shown.cost.broadcast_cycles, 3 + 5);
        assert_eq!(shown.cost.broadcast_messages, 6 * 15);
        assert_eq!(shown.cost.supervisor_ops, 2 + 8);
        assert_eq!(shown.missing, 0);
    }
}

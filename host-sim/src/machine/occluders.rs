//! Exact occluders on the grid for one source (thesis §5.5.6; `cell_core::occluder`): each
//! column's triangles ([`crate::machine::triangles`]) and its target ray.

use cell_core::beam::{FarDistance, FracBits, Source};
use cell_core::occluder::{ColumnOccluders, Triangle};
use cell_core::receiver::{target, Target};
use cell_core::units::Coord;
use rayon::prelude::*;

use crate::machine::grid::Grid;
use crate::machine::triangles::ColumnTriangles;

/// What the cells know for one source: their triangles and their target rays
/// (`cell_core::receiver::target` from each column's visible surface, computed in parallel).
#[derive(Debug)]
pub struct SourceOccluders<'a> {
    n: u32,
    triangles: &'a ColumnTriangles,
    targets: Vec<Option<Target>>,
}

impl<'a> SourceOccluders<'a> {
    /// The occluders of `grid` for `source` at far distance `far`.
    pub fn new<F: FracBits, const D: usize>(grid: &'a Grid<D>, source: &Source, far: FarDistance<F>) -> Self {
        let targets = grid
            .cells
            .par_iter()
            .map(|c| c.visible.as_ref().and_then(|v| target(c.x as i32, c.y as i32, v, source, far)))
            .collect();
        SourceOccluders { n: grid.n, triangles: &grid.triangles, targets }
    }
}

impl ColumnOccluders for SourceOccluders<'_> {
    fn triangles(&self, x: Coord, y: Coord) -> &[Triangle] {
        self.triangles.column(x as u32, y as u32)
    }

    fn target(&self, x: Coord, y: Coord) -> Option<Target> {
        self.targets.get(y as usize * self.n as usize + x as usize).copied().flatten()
    }
}

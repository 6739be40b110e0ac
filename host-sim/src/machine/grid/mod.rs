//! The grid every phase stands on (thesis §1.3, the machine; §3.4, a column as dexels): n × n
//! cells, cell (x, y) owning the voxel column {(x, y, z)} and talking only to its 8 neighbours
//! ([`neighbour`]).
//!
//! * [`Grid`] — the cells (their dexels and lit state) and, for exact occluders, the triangles
//!   each column keeps ([`triangles`], thesis §5.5.6); [`LightGrid`] the grid the lighting jobs
//!   load into.
//! * [`capacity`] — the cell capacities (from `cell_core::cell`, shared with the firmware) and
//!   the cell types built from them.
//! * [`limits`] — the host's memory: a grid that cannot fit is refused before it is allocated,
//!   and the peak a run reached.
//! * [`pieces`] — disjoint pieces of the cell array for the data-parallel phases.
//!
//! Invariant: this level steps no cell and imports no phase (nor the links): it is the data
//! every phase reads and writes, and a cell's state here is its own alone.

use cell_core::cell::Cell;
use cell_core::light::Port;

pub mod capacity;
pub mod limits;
pub mod pieces;
pub mod triangles;

/// The index (y·n + x) of the neighbour of cell `i` (same indexing) across port `p`, if it
/// lies inside the n × n grid.
pub fn neighbour(n: u32, i: usize, p: Port) -> Option<usize> {
    let (dx, dy) = p.delta();
    let (x, y) = ((i % n as usize) as i64 + dx as i64, (i / n as usize) as i64 + dy as i64);
    let inside = (0..n as i64).contains(&x) && (0..n as i64).contains(&y);
    inside.then(|| (y * n as i64 + x) as usize)
}

/// The grid type the lighting jobs load into.
pub type LightGrid = Grid<{ capacity::DEFAULT_DEXELS }>;

/// The grid: n × n cells, each with room for `D` dexels.
pub struct Grid<const D: usize> {
    /// Side.
    pub n: u32,
    /// Voxels per column.
    pub depth: u32,
    /// Cells, row-major (`y·n + x`).
    pub cells: Vec<Cell<D>>,
    /// The triangles each column keeps for exact occluders, loaded with the facets (empty
    /// until then).
    pub triangles: triangles::ColumnTriangles,
}

impl<const D: usize> Grid<D> {
    /// An empty grid.
    pub fn new(n: u32, depth: u32) -> Self {
        let mut cells = Vec::with_capacity(n as usize * n as usize);
        for y in 0..n {
            for x in 0..n {
                cells.push(Cell::new(x as u16, y as u16));
            }
        }
        Grid { n, depth, cells, triangles: Default::default() }
    }

    /// The cell at (x, y).
    pub fn cell(&self, x: u32, y: u32) -> &Cell<D> {
        &self.cells[(y * self.n + x) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_lie_inside_the_grid_and_rows_do_not_wrap() {
        let n = 3;
        for p in Port::ALL {
            let (dx, dy) = p.delta();
            assert_eq!(neighbour(n, 4, p), Some((4 + 3 * dy as i64 + dx as i64) as usize), "the centre, {p:?}");
        }
        let count = |i: usize| Port::ALL.iter().filter(|&&p| neighbour(n, i, p).is_some()).count();
        assert_eq!((count(0), count(8), count(5), count(1)), (3, 3, 5, 5), "corners three, edges five");
        assert_eq!((neighbour(n, 2, Port::E), neighbour(n, 3, Port::W)), (None, None), "a row's ends do not wrap");
    }
}

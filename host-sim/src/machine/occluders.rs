//! Exact occluders on the grid for one source (thesis §5.5.6; `cell_core::occluder`): each
//! column's triangles ([`crate::machine::triangles`]) and its target ray.

use cell_core::beam::{FarDistance, FracBits, Source};
use cell_core::light::Port;
use cell_core::occluder::{ColumnOccluders, Triangle};
use cell_core::receiver::{crosses_any, target, Target};
use cell_core::units::Coord;
use rayon::prelude::*;

use crate::machine::grid::{neighbour, Grid};
use crate::machine::triangles::ColumnTriangles;

/// Cycles of the contact exchange ([`cell_core::receiver`], "The neighbours' triangles"), once
/// per source before its beams leave: every cell sends its contact segment's near end to its 8
/// neighbours (one cycle), tests the 8 it receives against its triangles (one query a cycle)
/// and answers each with one bit (one cycle).
pub const CONTACT_EXCHANGE_CYCLES: u64 = 1 + 8 + 1;

/// What the cells know for one source: their triangles and their target rays
/// (`cell_core::receiver::target` from each column's visible surface, computed in parallel),
/// with their neighbours' answers to their contact queries.
#[derive(Debug)]
pub struct SourceOccluders<'a> {
    n: u32,
    triangles: &'a ColumnTriangles,
    targets: Vec<Option<Target>>,
    exchange_messages: u64,
}

impl<'a> SourceOccluders<'a> {
    /// The occluders of `grid` for `source` at far distance `far`.
    pub fn new<F: FracBits, const D: usize>(grid: &'a Grid<D>, source: &Source, far: FarDistance<F>) -> Self {
        let n = grid.n;
        let own: Vec<Option<Target>> = grid
            .cells
            .par_iter()
            .map(|c| c.visible.as_ref().and_then(|v| target(c.x as i32, c.y as i32, v, source, far)))
            .collect();
        let tris = &grid.triangles;
        // The contact exchange: each neighbour inside the grid gets the query and answers it.
        let answered: Vec<(Option<Target>, u64)> = own
            .par_iter()
            .enumerate()
            .map(|(i, t)| {
                let Some((t, contact)) = t.and_then(|t| t.contact.map(|c| (t, c))) else {
                    return (*t, 0);
                };
                let around: Vec<usize> = Port::ALL.iter().filter_map(|&p| neighbour(n, i, p)).collect();
                let column = |j: usize| tris.column(j as u32 % n, j as u32 / n);
                let shadowed = around.iter().any(|&j| crosses_any(column(j), contact));
                (Some(t.with_neighbour_answers(shadowed)), 2 * around.len() as u64)
            })
            .collect();
        let exchange_messages = answered.iter().map(|a| a.1).sum();
        let targets = answered.into_iter().map(|a| a.0).collect();
        SourceOccluders { n, triangles: tris, targets, exchange_messages }
    }

    /// Messages of the contact exchange (a query and an answer per link from each cell with a
    /// contact segment).
    pub fn exchange_messages(&self) -> u64 {
        self.exchange_messages
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

//! Exact occluders on the grid for one source (thesis §5.5.6; `cell_core::occluder`): each
//! column's triangles ([`crate::machine::grid::triangles`]) and its target ray.
//!
//! A host speed-up beside them: each distinct triangle's plane along the source's rays in each
//! of the six directions (`cell_core::occluder::SeenEntry`), computed once per source instead of by
//! every beam that visits a column keeping it (a cell computes it per beam; the verdicts are
//! the same).

use cell_core::beam::{Direction, FarDistance, FracBits, Source};
use cell_core::light::Port;
use cell_core::occluder::{Column, ColumnOccluders, SeenEntry, SeenTable, SourceViews, Triangle};
use cell_core::receiver::{crosses_any, target, Target};
use cell_core::units::{Coord, Depth};
use cell_core::visibility::TargetVoxel;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::machine::grid::pieces::{par_map, prefetch};
use crate::machine::grid::triangles::ColumnTriangles;
use crate::machine::grid::{neighbour, Grid};

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
    /// Per column, its target voxel's depth (−1: no target): 4 bytes a beam reads, where the
    /// target is ~100.
    target_z: Vec<i32>,
    /// Per direction, then per distinct triangle ([`ColumnTriangles::distinct`]), its plane
    /// (`cell_core::occluder::SeenTable`'s layout).
    seen: Vec<SeenEntry>,
    /// Per column, its target voxel, where it counts its candidate rays (empty: the cells do
    /// not count them, `cell_core::visibility::Visibility::Target`).
    voxels: Vec<Option<TargetVoxel>>,
    /// Per column, the candidate rays its target voxel received (the cells' counts; cells step
    /// in parallel, each adding only to its own).
    arrived: Vec<AtomicU64>,
}

impl<'a> SourceOccluders<'a> {
    /// The occluders of `grid` for `source` at far distance `far`.
    pub fn new<F: FracBits, const D: usize>(grid: &'a Grid<D>, source: &Source, far: FarDistance<F>) -> Self {
        let (n, tris) = (grid.n, &grid.triangles);
        let column = |j: usize| tris.column(j as u32 % n, j as u32 / n);
        let targets = par_map(grid.cells.len(), &|i| {
            let c = &grid.cells[i];
            let t = c.visible.as_ref().and_then(|v| target(c.x as i32, c.y as i32, v, source, far))?;
            // The contact exchange: each neighbour inside the grid answers the query.
            let Some(contact) = t.contact else { return Some(t) };
            let shadowed =
                Port::ALL.iter().filter_map(|&p| neighbour(n, i, p)).any(|j| crosses_any(column(j), contact));
            Some(t.with_neighbour_answers(shadowed))
        });
        let distinct = tris.distinct();
        let (views, m) = (SourceViews::new(source, far), distinct.len());
        let seen = par_map(6 * m, &|j| views.entry(&distinct[j % m], Direction::ALL[j / m]));
        let target_z = targets.iter().map(|t| t.as_ref().map_or(-1, |t| t.z as i32)).collect();
        SourceOccluders { n, triangles: tris, targets, target_z, seen, voxels: Vec::new(), arrived: Vec::new() }
    }

    /// The same occluders with every column's target voxel, for cells that count the
    /// candidate rays reaching it (`cell_core::visibility`): computed from the target ray and
    /// the visible surface, as a cell does once per source.
    pub fn counting_rays<F: FracBits, const D: usize>(
        mut self,
        grid: &Grid<D>,
        source: &Source,
        far: FarDistance<F>,
    ) -> Self {
        let (n, tris) = (grid.n, &grid.triangles);
        let voxels = par_map(grid.cells.len(), &|i| {
            let (c, t) = (&grid.cells[i], self.targets[i].as_ref()?);
            let shadowed = t.in_contact_shadow(tris.column(i as u32 % n, i as u32 / n));
            TargetVoxel::new(t, (c.x as i32, c.y as i32), c.visible.as_ref()?, source, far, shadowed)
        });
        self.arrived = voxels.iter().map(|_| AtomicU64::new(0)).collect();
        self.voxels = voxels;
        self
    }

    /// The candidate rays each column's target voxel received (row-major; empty unless
    /// [`SourceOccluders::counting_rays`]).
    pub fn arrived_rays(&self) -> Vec<u64> {
        self.arrived.iter().map(|a| a.load(Ordering::Relaxed)).collect()
    }

    /// Every column's target voxel (row-major; empty unless [`SourceOccluders::counting_rays`]).
    pub fn target_voxels(&self) -> &[Option<TargetVoxel>] {
        &self.voxels
    }

    /// The planes of the triangles `ids` (a column's).
    fn table<'s>(&'s self, ids: &'s [u32]) -> SeenTable<'s> {
        SeenTable { ids, seen: &self.seen, distinct: self.seen.len() / 6 }
    }

    /// Every column's target ray (row-major; `None`: no ray lights its pixel).
    pub fn targets(&self) -> &[Option<Target>] {
        &self.targets
    }

    /// Messages of the contact exchange: a query and an answer per link from each cell with a
    /// contact segment to a neighbour inside the grid.
    pub fn exchange_messages(&self) -> u64 {
        let links = |i: usize| Port::ALL.iter().filter(|&&p| neighbour(self.n, i, p).is_some()).count() as u64;
        let asking = self.targets.iter().enumerate().filter(|(_, t)| t.is_some_and(|t| t.contact.is_some()));
        asking.map(|(i, _)| 2 * links(i)).sum()
    }
}

impl ColumnOccluders for SourceOccluders<'_> {
    fn triangles(&self, x: Coord, y: Coord) -> &[Triangle] {
        self.triangles.column(x as u32, y as u32)
    }

    fn target(&self, x: Coord, y: Coord) -> Option<&Target> {
        self.targets.get(y as usize * self.n as usize + x as usize)?.as_ref()
    }

    fn seen(&self, x: Coord, y: Coord) -> Option<SeenTable<'_>> {
        Some(self.table(self.triangles.ids(x as u32, y as u32)))
    }

    fn target_voxel(&self, x: Coord, y: Coord) -> Option<&TargetVoxel> {
        self.voxels.get(y as usize * self.n as usize + x as usize)?.as_ref()
    }

    fn arrived(&self, x: Coord, y: Coord, rays: u64) {
        if let Some(a) = self.arrived.get(y as usize * self.n as usize + x as usize) {
            a.fetch_add(rays, Ordering::Relaxed);
        }
    }

    fn column(&self, x: Coord, y: Coord, z: Depth) -> Column<'_> {
        let (triangles, ids, near) = self.triangles.column_parts(x as u32, y as u32);
        let i = y as usize * self.n as usize + x as usize;
        // The depth alone first: most beams are not at their column's target voxel.
        let here = self.target_z.get(i) == Some(&(z as i32));
        Column {
            triangles,
            seen: Some(self.table(ids)),
            target: if here { self.targets.get(i).and_then(Option::as_ref) } else { None },
            voxel: if here { self.voxels.get(i).and_then(Option::as_ref) } else { None },
            near: Some(near),
        }
    }

    fn prefetch(&self, x: Coord, y: Coord) {
        let i = y as usize * self.n as usize + x as usize;
        if let Some(z) = self.target_z.get(i) {
            prefetch(z);
        }
        self.triangles.prefetch(x as u32, y as u32);
    }
}

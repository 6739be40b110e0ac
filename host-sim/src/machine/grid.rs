//! The n × n grid of cells plus the vertical loading pipeline, stepped cycle by cycle.
//!
//! Cycle model of the loading phase (thesis §3.9): the host injects at most one facet packet per
//! cycle into pipeline cell 0; a link carries one packet per cycle; a cell processes one packet
//! per cycle. A packet processed by a cell in cycle t is processed by the next cell in cycle
//! t + 1. In this phase every cell has exactly one upstream neighbour (north for the pipeline,
//! west for a row), so packets never contend and no buffer beyond one register per link is
//! needed: the wave is systolic. Only cells holding a packet are visited in a cycle, so idle
//! regions cost nothing on the host.

use cell_core::cell::Cell;
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::Port;
use cell_core::voxelize::{row_span, PipelineCell};

use crate::machine::tap::Tap;

/// The index (y·n + x) of the neighbour of cell `i` (same indexing) across port `p`, if it
/// lies inside the n × n grid.
pub fn neighbour(n: u32, i: usize, p: Port) -> Option<usize> {
    let (dx, dy) = p.delta();
    let (x, y) = ((i % n as usize) as i64 + dx as i64, (i / n as usize) as i64 + dy as i64);
    let inside = (0..n as i64).contains(&x) && (0..n as i64).contains(&y);
    inside.then(|| (y * n as i64 + x) as usize)
}

/// Counters of one loading run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct LoadReport {
    /// Cycles from the first injection to the last packet processed.
    pub cycles: u64,
    /// Packets the host injected into the pipeline.
    pub host_messages: u64,
    /// Pipeline → pipeline transfers.
    pub pipeline_messages: u64,
    /// Pipeline → row transfers.
    pub row_feed_messages: u64,
    /// Row cell → row cell transfers.
    pub row_messages: u64,
    /// Packets processed by row cells.
    pub row_steps: u64,
}

/// The grid type the lighting jobs load into.
pub type LightGrid = Grid<{ super::capacity::DEFAULT_DEXELS }>;

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
    pub triangles: crate::machine::triangles::ColumnTriangles,
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

    /// Run the loading wave (§3.9) over the packets, cycle by cycle. `progress` is called
    /// now and then with the cycle reached.
    pub fn load_wave(&mut self, packets: &[PipelinePacket], progress: impl FnMut(u64)) -> LoadReport {
        self.load_wave_tapped(packets, None, progress)
    }

    /// [`Grid::load_wave`], recording what the cells watched by `tap` receive and send.
    pub fn load_wave_tapped(
        &mut self,
        packets: &[PipelinePacket],
        mut tap: Option<&mut Tap>,
        mut progress: impl FnMut(u64),
    ) -> LoadReport {
        let n = self.n as usize;
        let mut rep = LoadReport::default();
        let mut pipes: Vec<PipelinePacket> = packets.to_vec();
        // Packets in flight: (pipeline row, packet index) and (x, y, row-packet slot).
        let (mut pipe_now, mut pipe_next) = (Vec::<(u32, u32)>::new(), Vec::<(u32, u32)>::new());
        let (mut row_now, mut row_next) = (Vec::<(u32, u32, u32)>::new(), Vec::<(u32, u32, u32)>::new());
        let mut slab: Vec<RowPacket> = Vec::new();
        let mut free: Vec<u32> = Vec::new();
        let mut injected = 0usize;
        loop {
            if injected < pipes.len() {
                pipe_now.push((0, injected as u32));
                injected += 1;
                rep.host_messages += 1;
            }
            if pipe_now.is_empty() && row_now.is_empty() {
                break;
            }
            for &(y, idx) in &pipe_now {
                let step = PipelineCell { y: y as u16 }.step(&mut pipes[idx as usize]);
                if let Some(rp) = step.east {
                    let slot = match free.pop() {
                        Some(s) => {
                            slab[s as usize] = rp;
                            s
                        }
                        None => {
                            slab.push(rp);
                            (slab.len() - 1) as u32
                        }
                    };
                    row_next.push((0, y, slot));
                    rep.row_feed_messages += 1;
                }
                if step.down {
                    pipe_next.push((y + 1, idx));
                    rep.pipeline_messages += 1;
                }
            }
            for &(x, y, slot) in &row_now {
                let idx = y as usize * n + x as usize;
                let cell = &mut self.cells[idx];
                rep.row_steps += 1;
                let mut rec = tap.as_deref_mut().and_then(|t| t.get(idx));
                if let Some(r) = rec.as_deref_mut() {
                    r.row(&slab[slot as usize]);
                }
                let forward = cell.load_step(&mut slab[slot as usize], self.depth);
                if let (true, Some(r)) = (forward, rec) {
                    r.forwarded(&slab[slot as usize]);
                }
                if forward {
                    row_next.push((x + 1, y, slot));
                    rep.row_messages += 1;
                } else {
                    free.push(slot);
                }
            }
            pipe_now.clear();
            row_now.clear();
            std::mem::swap(&mut pipe_now, &mut pipe_next);
            std::mem::swap(&mut row_now, &mut row_next);
            rep.cycles += 1;
            if rep.cycles % 4096 == 0 {
                progress(rep.cycles);
            }
        }
        progress(rep.cycles);
        rep
    }

    /// The direct host path: the same integer formulas evaluated by multiplication at every
    /// column of each facet's box, facets in stream order. No cycles, no messages.
    pub fn load_direct(&mut self, packets: &[PipelinePacket], mut progress: impl FnMut(u64)) {
        let n = self.n as usize;
        for (i, p) in packets.iter().enumerate() {
            let mut rp = p.to_row();
            let b = p.bbox;
            for y in b.y_min as i64..=b.y_max as i64 {
                for x in b.x_min as i64..=b.x_max as i64 {
                    let plane = p.a * x + p.b * y;
                    rp.t = p.t - plane;
                    rp.u = p.u - plane;
                    for (re, pe) in rp.edges.iter_mut().zip(p.edges.iter()) {
                        re.g = pe.g + pe.a as i64 * x + pe.b as i64 * y;
                    }
                    let cell = &mut self.cells[y as usize * n + x as usize];
                    if let Some(span) = row_span(&rp, self.depth) {
                        cell.store.insert_on(span, p.tag, &rp.column_plane());
                    }
                    cell_core::visible::depth_test(&mut cell.visible, cell_core::visible::surface_of(&rp, self.depth));
                }
            }
            if i % 1024 == 0 {
                progress(i as u64);
            }
        }
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

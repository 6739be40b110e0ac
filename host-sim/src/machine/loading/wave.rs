//! The loading wave: the vertical pipeline and the rows, stepped cycle by cycle, and the direct
//! host path that evaluates the same integer formulas column by column.
//!
//! Cycle model of the loading phase (thesis §3.9): the host injects at most one facet packet per
//! cycle into pipeline cell 0; a link carries one packet per cycle; a cell processes one packet
//! per cycle. A packet processed by a cell in cycle t is processed by the next cell in cycle
//! t + 1. In this phase every cell has exactly one upstream neighbour (north for the pipeline,
//! west for a row), so packets never contend and no buffer beyond one register per link is
//! needed: the wave is systolic. Only cells holding a packet are visited in a cycle, so idle
//! regions cost nothing on the host.

use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::voxelize::{row_span, PipelineCell};

use crate::machine::grid::Grid;
use crate::machine::links::tap::Tap;

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

impl<const D: usize> Grid<D> {
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
                    row_packet_at(p, &mut rp, x, y);
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

/// Set `rp` (`p.to_row()`) to the row packet column (x, y) holds, by multiplication: what the
/// wave's steps down and east give there (`T − B·y − A·x`, …).
pub fn row_packet_at(p: &PipelinePacket, rp: &mut RowPacket, x: i64, y: i64) {
    let plane = p.a * x + p.b * y;
    rp.t = p.t - plane;
    rp.u = p.u - plane;
    for (re, pe) in rp.edges.iter_mut().zip(p.edges.iter()) {
        re.g = pe.g + pe.a as i64 * x + pe.b as i64 * y;
    }
}

//! The loading wave stepped the straightforward way: every pipeline cell and every row cell is
//! visited in every cycle, each with its one inbound register. A reference for
//! [`Grid::load_wave`], which visits only the cells holding a packet; both must give the same
//! dexels and the same [`LoadReport`].

use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::voxelize::PipelineCell;

use crate::machine::grid::Grid;
use crate::machine::loading::wave::LoadReport;

impl<const D: usize> Grid<D> {
    /// [`Grid::load_wave`] visiting all n + n² cells every cycle (slow; for tests).
    pub fn load_wave_all_cells(&mut self, packets: &[PipelinePacket]) -> LoadReport {
        let n = self.n as usize;
        let mut rep = LoadReport::default();
        let mut pipes: Vec<PipelinePacket> = packets.to_vec();
        // Inbound registers: pipeline cell y holds a packet index; row cell (x, y) a row packet.
        let (mut pipe_reg, mut pipe_next) = (vec![None::<usize>; n], vec![None::<usize>; n]);
        let (mut row_reg, mut row_next) = (vec![None::<RowPacket>; n * n], vec![None::<RowPacket>; n * n]);
        let mut injected = 0usize;
        loop {
            if injected < pipes.len() {
                pipe_reg[0] = Some(injected);
                injected += 1;
                rep.host_messages += 1;
            }
            if pipe_reg.iter().all(Option::is_none) && row_reg.iter().all(Option::is_none) {
                break;
            }
            for y in 0..n {
                let Some(idx) = pipe_reg[y].take() else { continue };
                let step = PipelineCell { y: y as u16 }.step(&mut pipes[idx]);
                if let Some(rp) = step.east {
                    row_next[y * n] = Some(rp);
                    rep.row_feed_messages += 1;
                }
                if step.down {
                    pipe_next[y + 1] = Some(idx);
                    rep.pipeline_messages += 1;
                }
            }
            for i in 0..n * n {
                let Some(mut rp) = row_reg[i].take() else { continue };
                rep.row_steps += 1;
                if self.cells[i].load_step(&mut rp, self.depth) {
                    row_next[i + 1] = Some(rp);
                    rep.row_messages += 1;
                }
            }
            std::mem::swap(&mut pipe_reg, &mut pipe_next);
            std::mem::swap(&mut row_reg, &mut row_next);
            rep.cycles += 1;
        }
        rep
    }
}

//! The timing rules of the diffusion cycle model that the thesis leaves open (§4.4.1–4.4.3),
//! one knob each, gathered in [`Timing`] inside [`crate::machine::lighting::diffuse::LightConfig`].
//!
//! rc2's model ([`Timing::RC2`], the default) charges one cycle per processed beam, moves one
//! message per link and direction per cycle, counts the beam being processed inside the FIFO
//! limit FA, and hands the source cell its six initial beams one per cycle, x and y first.
//! The thesis states its algorithm (§4.4.1) and its no-loss rule (§4.4.2) but not these rules;
//! [`Timing::THESIS`] is the reading of its text and tables that docs/DIFFUSION-TIMING.md
//! argues for, rule by rule. No knob changes which rays a beam carries or where they stop: the
//! lit set is the same under every timing (tests/tests/integration/diffusion.rs checks it against the
//! per-ray oracle), only cycles, messages and FIFO occupancy change.

use anyhow::{bail, Result};
use cell_core::beam::Direction;

use crate::machine::grid::capacity::{FA_CAP, OB_CAP};

/// Which initial beams the source emits first (§4.4.3: "Il vaut mieux envoyer d'abord en x et
/// y … puis ensuite en z").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Emission {
    /// +x, −x, +y, −y, then +z, −z (the thesis's recommended order; rc2's default).
    #[default]
    XyFirst,
    /// +z, −z first, then +x, −x, +y, −y (the order the thesis found slower).
    ZFirst,
}

impl Emission {
    /// The six directions in emission order.
    pub const fn order(self) -> [Direction; 6] {
        use Direction::*;
        match self {
            Emission::XyFirst => Direction::ALL,
            Emission::ZFirst => [PosZ, NegZ, PosX, NegX, PosY, NegY],
        }
    }
}

/// The diffusion's timing rules. Every combination lights the same voxels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Timing {
    /// Messages one link carries per direction and cycle (1 ..= the output-buffer capacity,
    /// [`OB_CAP`]). A ±x or ±y split sends up to three sub-beams to one neighbour (its z − 1,
    /// z, z + 1 pieces); with 3 the output buffer the split filled is empty again next cycle,
    /// as if the thesis's "1 buffer de sortie pour chaque direction" (§4.4.1) held one message
    /// carrying all the pieces for that neighbour. rc2: 1.
    pub link_rate: u8,
    /// The FIFO limit FA counts only the beams waiting, not the one the cell is processing
    /// (an input register besides the FA): a FIFO of limit FA holds FA + 1 beams. The thesis's
    /// "large enough" table lists FA = 0 for N ≤ 3 (§4.4.3), which only a cell with room
    /// outside its FA can run. rc2: false.
    pub register: bool,
    /// A beam is processed only when the output buffer toward every neighbour it sends to is
    /// empty ("si dir propagation libre alors découper faisceau", §4.4.1), not merely has room
    /// ([`cell_core::light::LightEnv::free_ports`]). rc2: false.
    pub free_ports: bool,
    /// Order of the initial beams.
    pub emission: Emission,
    /// The source hands its cell every initial beam the FIFO has room for in one cycle ("Nous
    /// envoyons donc 6 cônes", §4.2.3), rather than one per cycle. rc2: false.
    pub burst: bool,
}

impl Default for Timing {
    fn default() -> Self {
        Timing::RC2
    }
}

impl Timing {
    /// rc2's cycle model (docs/ARCHITECTURE.md, "The life of a beam in one cycle").
    pub const RC2: Timing =
        Timing { link_rate: 1, register: false, free_ports: false, emission: Emission::XyFirst, burst: false };

    /// The thesis's timing as docs/DIFFUSION-TIMING.md reads it: rc2's, but a beam goes only
    /// when the output buffers it sends to are empty (§4.4.1: "Si l'un des buffers de sortie
    /// reste occupé … la cellule passe dans l'état bloqué"). With the source at the grid's
    /// origin it reproduces the published FA-sweep tables of §4.4.3 within ±20 % at 193 of
    /// their 202 points (the others at 0.76–0.80), and with the source at the centre the
    /// time-lapse's final times within 10 %.
    pub const THESIS: Timing = Timing { free_ports: true, ..Timing::RC2 };

    /// The FIFO limit a cell applies for a run's FA (`fa` waiting, plus the register).
    pub const fn fifo_limit(&self, fa: usize) -> usize {
        fa + self.register as usize
    }

    /// Refuse rules the machine cannot run: a link rate the output buffers cannot feed, a FIFO
    /// limit past the compiled capacity, and (`plain_links` false: link faults or a cell trace)
    /// several messages per link and cycle, which the link protocol and the trace format carry
    /// one at a time.
    pub fn check(&self, fa: usize, plain_links: bool) -> Result<()> {
        if self.link_rate == 0 || self.link_rate as usize > OB_CAP {
            bail!("link rate {} is out of range: 1 ..= {OB_CAP} (the output-buffer capacity)", self.link_rate);
        }
        if self.fifo_limit(fa) > FA_CAP {
            bail!(
                "--fa {fa} with an input register needs {} FIFO slots: at most {FA_CAP} are compiled into a cell",
                self.fifo_limit(fa)
            );
        }
        if (self.link_rate > 1 || self.free_ports) && !plain_links {
            bail!("a link rate above 1 and free ports need perfect, untraced links (no --link-faults, no cell trace)");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_are_permutations_of_all_six() {
        for e in [Emission::XyFirst, Emission::ZFirst] {
            let mut o = e.order();
            o.sort_by_key(|d| d.index());
            assert_eq!(o, Direction::ALL);
        }
    }

    #[test]
    fn checks_refuse_what_cannot_run() {
        assert!(Timing::RC2.check(FA_CAP, true).is_ok());
        assert!(Timing::THESIS.check(FA_CAP, true).is_ok());
        assert!(Timing::THESIS.check(1, false).is_err());
        let register = Timing { register: true, ..Timing::RC2 };
        assert!(register.check(FA_CAP - 1, true).is_ok());
        assert!(register.check(FA_CAP, true).is_err());
        assert!(Timing { link_rate: 0, ..Timing::RC2 }.check(1, true).is_err());
        assert!(Timing { link_rate: OB_CAP as u8 + 1, ..Timing::RC2 }.check(1, true).is_err());
    }
}

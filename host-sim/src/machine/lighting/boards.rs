//! The grid as asynchronous boards: B × B tiles of cells, each stepping on its own schedule,
//! inter-board messages delivered after random delays, and the end of every phase detected by
//! the boards themselves ([`cell_core::termination`], Safra's token ring), not by the host.
//!
//! The rest of the machine steps every cell in one global cycle and ends a phase when the
//! host's exact activity counter reads 0 (§4.4.4). Here there is no global cycle:
//!
//! * **Boards.** The n × n grid is cut into (n / B)² boards of B × B cells (the radiosity
//!   thesis's several cells per PE). The executor's clock counts *ticks*; a board steps again
//!   1 ..= `max_pause` ticks after its last step (seeded [`Rng`]), whatever the others do.
//! * **Inter-board messages** (beams, row and pipeline packets crossing a board edge) are
//!   delivered 1 ..= `max_delay` ticks after they are sent (plus `slow.extra_delay` for every
//!   message a slow board sends). Row and pipeline packets keep their order on a link (a serial
//!   line is FIFO: the loading wave relies on it); a beam link between two cells on either side
//!   of an edge holds one frame at a time, the receiving cell's register, and its sender sees
//!   the register's state as a ready line (the link seam, [`cell_core::link::Link`], with the
//!   far end [`Register`]). Inside a board the cells' links are [`PerfectLink`]s into the
//!   neighbour's FIFO ([`CellInbox`]), as in the synchronous grid.
//! * **One board step**: take the arrived messages off the wires (the token, loading packets;
//!   beams into their cell's FIFO when it has room), move every loading packet one cell, emit
//!   the next initial beam (the board holding the source), step every cell holding a beam
//!   ([`LightCell::step`]), move every output buffer's head over its link, and poll the
//!   board's termination [`Node`] with whether the board is passive (no packet, no beam to
//!   emit, no cell holding a beam).
//! * **Phases**: loading (0), then one lighting phase per source (1 ..= S), sources one after
//!   another as in [`crate::machine::lighting::diffuse`]. The host hands the facet packets to board 0
//!   (which holds pipeline cell 0) at the start. Board 0 declares the end of a phase and
//!   starts the next one's token round; the board holding the next source starts emitting when
//!   that token reaches it ([`cell_core::termination::Arrival`]). The host only reads the lit
//!   sets and the dexel stores after the last declaration.
//! * **The ring** ([`ring`]): a boustrophedon over the boards' 4-neighbour links closed back
//!   along the first column (the board grid must have an even side, or be 1 × 1). The token
//!   is encoded with the wire codec ([`TokenFrame`]) and decoded at the far end.
//!
//! **Ground truth.** The executor keeps what the boards cannot see — frames on wires, which
//! boards are passive — and checks every declaration against it: a declaration while a
//! message is in flight or a cell is busy is recorded as [`Early`] and ends the run (the
//! mutation check runs the ring without counters, [`AsyncConfig::counting`], and finds it).
//! It also records how many token hops each declaration came after true quiescence (the
//! liveness bound of [`cell_core::termination`]: at most 3N). Nothing the boards do reads it.
//!
//! The lighting environment is the synchronous run's (`AllSources::env`) without the skips
//! that need a reduction over the whole grid after loading (the receding-beam and
//! dead-direction skips, the frustum summaries): [`run`] refuses a configuration with them, or
//! with link faults, a sibling wait or a snapshot. Lit voxels and pixels do not depend on them
//! (`tests/tests/integration/async_boards.rs` compares with the synchronous grid).

use std::collections::VecDeque;
use std::convert::Infallible;

use anyhow::{bail, Result};
use cell_core::beam::{FracBits, Source, SplitOrder};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::{Activity, ActivityDelta, BeamMsg, LightCell, LightEnv, Port};
use cell_core::link::{Link, PerfectLink, Sent};
use cell_core::occluder::ColumnOccluders;
use cell_core::termination::{Action, Node, Token};
use cell_core::voxelize::PipelineCell;
use cell_core::wire::TokenFrame;

use crate::machine::grid::capacity::HostLightCell;
use crate::machine::grid::triangles::ColumnTriangles;
use crate::machine::grid::LightGrid;
use crate::machine::lighting::diffuse::{
    check_light_run, initial_beams, AllSources, LightConfig, Lighting, SourceReport,
};
use crate::machine::lighting::occluders::SourceOccluders;
use crate::machine::links::{sure, CellInbox, Took, BACK};
use crate::precompute::Prepared;
use crate::rng::Rng;

/// How the boards are cut and scheduled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AsyncConfig {
    /// Board side B in cells (divides n).
    pub tile: u32,
    /// Seed of the schedule and the delays.
    pub seed: u64,
    /// An inter-board message arrives 1 ..= this many ticks after it is sent.
    pub max_delay: u64,
    /// A board steps again 1 ..= this many ticks after its last step.
    pub max_pause: u64,
    /// One board whose every sent basic message takes longer (the adversarial schedule).
    pub slow: Option<SlowBoard>,
    /// Count basic messages in the termination nodes (Safra). `false` is the mutation check:
    /// the same ring without counters or colours, which declares when it finds every board
    /// passive.
    pub counting: bool,
    /// Give up (an error: the run hangs) after this many ticks.
    pub max_ticks: u64,
}

impl Default for AsyncConfig {
    fn default() -> Self {
        AsyncConfig { tile: 8, seed: 1, max_delay: 8, max_pause: 3, slow: None, counting: true, max_ticks: 10_000_000 }
    }
}

/// A board whose links are slow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlowBoard {
    /// The board (row-major board index).
    pub board: usize,
    /// Ticks added to the delay of every basic message it sends.
    pub extra_delay: u64,
}

/// A declaration made while the computation had not terminated (found by the ground truth).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Early {
    /// The phase declared.
    pub phase: u16,
    /// The tick.
    pub tick: u64,
    /// Basic messages on the wires then.
    pub in_flight: u64,
    /// Boards active then.
    pub active_boards: usize,
    /// Beams in the machine then (the host's activity counter, never read by the boards).
    pub beams: u64,
}

/// One phase's termination figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PhaseCost {
    /// 0: loading; p ≥ 1: lighting of source p − 1.
    pub phase: u16,
    /// Tick of the declaration.
    pub declared_at: u64,
    /// Tick from which nothing was active or in flight (ground truth).
    pub quiet_at: u64,
    /// Token hops between quiescence and the declaration (proved ≤ 3N).
    pub hops_after_quiescence: u64,
    /// Token hops during the phase (from the previous declaration to this one).
    pub token_hops: u64,
    /// Token rounds node 0 started in the phase.
    pub rounds: u64,
    /// Basic messages that crossed a board edge in the phase.
    pub basic_messages: u64,
    /// Beams that moved between cells in the phase (inside boards and across edges).
    pub beam_transfers: u64,
}

/// What an asynchronous run did.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct AsyncStats {
    /// Boards (N, the ring's length).
    pub boards: usize,
    /// The ring: board indices (row-major) in token order.
    pub ring: Vec<usize>,
    /// Ticks until the last declaration.
    pub ticks: u64,
    /// Per phase, in order.
    pub phases: Vec<PhaseCost>,
    /// Token frames sent, and their bytes on the wire.
    pub token_hops: u64,
    /// Bytes of those frames.
    pub token_bytes: u64,
    /// Board steps after which every board was passive with basic messages still on the wires
    /// (ground truth): the moments an "all passive" detector would declare too early.
    pub passive_in_flight: u64,
}

/// The result of [`run`].
pub struct AsyncRun {
    /// The loaded grid (the boards' dexel stores, row-major).
    pub grid: LightGrid,
    /// The boards' lighting cells, row-major (reports: one per source, position only).
    pub lighting: Lighting,
    /// Termination figures.
    pub stats: AsyncStats,
    /// The first declaration the ground truth refuted (the run stopped there).
    pub early: Option<Early>,
}

/// The receiving end of a beam link across a board edge: the receiving cell's one-frame
/// register, with the tick the frame arrives.
#[derive(Clone, Copy, Debug, Default)]
pub struct Register<F: FracBits> {
    frame: Option<(u64, BeamMsg<F>)>,
}

/// A beam link across a board edge: ready while the far register is free (its ready line);
/// a send puts the beam on the wire, to land in the register after a random delay. The wire
/// does not lose frames: the sender pops the beam at once.
#[derive(Clone, Debug)]
pub struct WireLink {
    rng: Rng,
    max_delay: u64,
    extra: u64,
}

impl<F: FracBits> Link<F, Register<F>> for WireLink {
    type Error = Infallible;
    const LOSSLESS: bool = false;

    fn ready(&mut self, rx: &Register<F>) -> Result<bool, Infallible> {
        Ok(rx.frame.is_none())
    }

    fn send(&mut self, now: u64, msg: &BeamMsg<F>, rx: &mut Register<F>) -> Result<Sent, Infallible> {
        rx.frame = Some((now + 1 + self.rng.below(self.max_delay) + self.extra, *msg));
        Ok(Sent::TAKEN)
    }
}

/// The token ring over a `tx` × `ty` board grid: a boustrophedon along the rows from board
/// (0, 0) over columns 1 … tx − 1, closed back down column 0 (ty even); the same transposed
/// (tx even, ty odd); one board. Consecutive boards (and the last and the first) are
/// 4-neighbours. Board index: `by · tx + bx`.
pub fn ring(tx: usize, ty: usize) -> Result<Vec<usize>> {
    if tx * ty == 1 {
        return Ok(vec![0]);
    }
    let snake = |cols: usize, rows: usize| -> Option<Vec<(usize, usize)>> {
        if rows % 2 != 0 || (cols < 2 && rows > 2) {
            return None;
        }
        let mut r: Vec<(usize, usize)> = (0..cols).map(|c| (c, 0)).collect();
        for row in 1..rows {
            let cs: Vec<usize> = if row % 2 == 1 { (1..cols).rev().collect() } else { (1..cols).collect() };
            r.extend(cs.into_iter().map(|c| (c, row)));
        }
        r.extend((1..rows).rev().map(|row| (0, row)));
        Some(r)
    };
    let cells = if let Some(r) = snake(tx, ty) {
        r
    } else if let Some(r) = snake(ty, tx) {
        r.into_iter().map(|(a, b)| (b, a)).collect()
    } else {
        bail!("no token ring over a {tx} × {ty} board grid: one side must be even (or both 1; a 1 × k line only for k ≤ 2)");
    };
    Ok(cells.into_iter().map(|(x, y)| y * tx + x).collect())
}

/// A loading packet on a board's work list: a pipeline packet at pipeline row y, or a row
/// packet at cell (x, y).
#[derive(Clone, Debug)]
enum Load {
    Pipe(u32, PipelinePacket),
    Row(u32, u32, RowPacket),
}

/// The board (row-major index, `tx` boards a side) holding cell (x, y).
fn board_index(x: u32, y: u32, tile: u32, tx: u32) -> usize {
    ((y / tile) * tx + x / tile) as usize
}

/// The row-major indices of the cells of the `tile` × `tile` board whose first cell is
/// (x0, y0), on a grid of side n.
fn board_cells(x0: u32, y0: u32, n: u32, tile: u32) -> impl Iterator<Item = usize> + Clone {
    (0..tile).flat_map(move |dy| (0..tile).map(move |dx| ((y0 + dy) * n + x0 + dx) as usize))
}

/// One board's own state (its cells live in the executor's row-major arrays).
struct Board<F: FracBits> {
    x0: u32,
    y0: u32,
    node: Node,
    /// Ring successor (board index).
    next: usize,
    /// The token on its way to this board: arrival tick and frame bytes.
    token_in: Option<(u64, Vec<u8>)>,
    /// Loading packets on the incoming west and north links: (arrival tick, packet), FIFO.
    load_in: VecDeque<(u64, Load)>,
    /// Loading packets being moved through the board's cells.
    work: VecDeque<Load>,
    /// The host's facets (board 0, phase 0).
    host: VecDeque<PipelinePacket>,
    /// Initial beams still to hand to the source cell (the board holding the source).
    emit: VecDeque<BeamMsg<F>>,
    next_step: u64,
}

/// Run the loading and lighting phases of a prepared scene's facets and `sources` on
/// asynchronous boards. Under exact occluders each column keeps its triangles as the
/// synchronous grid's do (loaded with the facets, [`crate::machine::grid::triangles`]).
pub fn run(
    prepared: &Prepared,
    n: u32,
    sources: &[Source],
    light: &LightConfig,
    cfg: &AsyncConfig,
) -> Result<AsyncRun> {
    crate::machine::lighting::diffuse::with_f!(light.frac_bits, F => run_f::<F>(prepared, n, sources, light, cfg))
}

/// [`run`] under f = `F`.
fn run_f<F: FracBits>(
    prepared: &Prepared,
    n: u32,
    sources: &[Source],
    light: &LightConfig,
    cfg: &AsyncConfig,
) -> Result<AsyncRun> {
    if cfg.tile == 0 || n % cfg.tile != 0 {
        bail!("board side {} must divide the grid side {n}", cfg.tile);
    }
    if light.skip_receding || light.skip_dead_directions || light.skip_frustum || light.skip_hidden {
        bail!("the asynchronous boards run without the skips that need a whole-grid reduction after loading");
    }
    if light.faults.is_some() || light.hold > 0 || light.stop_at.is_some() || light.record_visits {
        bail!("the asynchronous boards run on their own wires, without a sibling wait, snapshot or visit record");
    }
    if sources.len() >= u16::MAX as usize || cfg.max_delay == 0 || cfg.max_pause == 0 {
        bail!("too many sources, or a zero delay or pause bound");
    }
    let far = check_light_run::<F>(n, n as u64 * n as u64, sources, light)?;
    let mut ex = Executor::<F>::new(&prepared.packets, n, sources.len(), cfg)?;
    let mut grid = LightGrid::new(n, n);
    ex.schedule(0, |ex, b| ex.step_loading(b, &mut grid), |_, _, _| {})?;
    let exact = light.rule.needs_triangles();
    if exact {
        grid.triangles = ColumnTriangles::from_polygons(&prepared.polygons, n)?;
    }
    let order = SplitOrder::default();
    let all = AllSources::plain(&grid, sources, light, far);
    let occluders: Vec<Option<SourceOccluders<'_>>> =
        sources.iter().map(|s| exact.then(|| SourceOccluders::new(&grid, s, far))).collect();
    let envs: Vec<LightEnv<'_, F>> = sources
        .iter()
        .zip(&occluders)
        .enumerate()
        .map(|(i, (s, o))| all.env(s, i, &order, o.as_ref().map(|o| o as &dyn ColumnOccluders)))
        .collect();
    ex.light(&grid, sources, &envs, light)?;
    drop(envs);
    let reports = sources
        .iter()
        .enumerate()
        .map(|(i, s)| SourceReport { source: i, position: s.pos.map(|p| p.to_num::<f64>()), ..Default::default() })
        .collect();
    let lighting = Lighting {
        n,
        cells: crate::machine::lighting::diffuse::lit_columns(&ex.cells),
        reports,
        visited: None,
        link_faults: None,
        rule: light.rule,
        phases: Default::default(),
        weights: None,
    };
    Ok(AsyncRun { grid, lighting, stats: ex.stats, early: ex.early })
}

/// The boards, the wires and the ground truth.
struct Executor<F: FracBits> {
    n: u32,
    tile: u32,
    tx: u32,
    cfg: AsyncConfig,
    cells: Vec<HostLightCell<F>>,
    boards: Vec<Board<F>>,
    /// Beam registers and wire links of cell links across board edges, by receiving end
    /// ([`crate::machine::links::slot`]); `None` inside a board.
    regs: Vec<Register<F>>,
    wires: Vec<Option<WireLink>>,
    rng: Rng,
    now: u64,
    /// Ground truth: basic messages on wires and in registers, boards passive, beams.
    in_flight: u64,
    passive: Vec<bool>,
    activity: Activity,
    quiet_since: Option<(u64, u64)>,
    stats: AsyncStats,
    phase: PhaseCost,
    early: Option<Early>,
    done: bool,
    journal: Vec<Took<F>>,
}

impl<F: FracBits> Executor<F> {
    fn new(packets: &[PipelinePacket], n: u32, sources: usize, cfg: &AsyncConfig) -> Result<Self> {
        let tx = n / cfg.tile;
        let count = (tx * tx) as usize;
        let ring = ring(tx as usize, tx as usize)?;
        let mut rng = Rng(cfg.seed);
        let mut boards: Vec<Board<F>> = (0..count)
            .map(|b| Board {
                x0: (b as u32 % tx) * cfg.tile,
                y0: (b as u32 / tx) * cfg.tile,
                node: Node::new(0, sources as u16),
                next: 0,
                token_in: None,
                load_in: VecDeque::new(),
                work: VecDeque::new(),
                host: VecDeque::new(),
                emit: VecDeque::new(),
                next_step: rng.below(cfg.max_pause),
            })
            .collect();
        for (pos, &b) in ring.iter().enumerate() {
            boards[b].node = Node::new(pos as u16, sources as u16);
            boards[b].next = ring[(pos + 1) % ring.len()];
        }
        boards[0].host = packets.iter().cloned().collect();
        let cells = (0..n * n).map(|i| LightCell::new((i % n) as u16, (i / n) as u16)).collect();
        let wires = (0..(n * n) as usize * 8)
            .map(|s| {
                let (to, back) = ((s / 8) as u32, Port::ALL[s % 8]);
                let (dx, dy) = back.delta();
                let (fx, fy) = ((to % n) as i64 + dx as i64, (to / n) as i64 + dy as i64);
                let inside = (0..n as i64).contains(&fx) && (0..n as i64).contains(&fy);
                let from = (fy * n as i64 + fx) as u32;
                let board = |c: u32| board_index(c % n, c / n, cfg.tile, tx);
                (inside && board(from) != board(to)).then(|| WireLink {
                    rng: Rng(rng.next_u64()),
                    max_delay: cfg.max_delay,
                    extra: cfg.slow.filter(|s| s.board == board(from)).map_or(0, |s| s.extra_delay),
                })
            })
            .collect();
        Ok(Executor {
            n,
            tile: cfg.tile,
            tx,
            cfg: *cfg,
            cells,
            regs: vec![Register::default(); (n * n) as usize * 8],
            wires,
            passive: vec![false; count],
            boards,
            rng,
            now: 0,
            in_flight: 0,
            activity: Activity::new(),
            quiet_since: None,
            stats: AsyncStats { boards: count, ring, ..Default::default() },
            phase: PhaseCost::default(),
            early: None,
            done: false,
            journal: Vec::new(),
        })
    }

    fn board_of(&self, x: u32, y: u32) -> usize {
        board_index(x, y, self.tile, self.tx)
    }

    /// Delay of a basic message sent by board `b`.
    fn delay(&mut self, b: usize) -> u64 {
        let extra = self.cfg.slow.filter(|s| s.board == b).map_or(0, |s| s.extra_delay);
        1 + self.rng.below(self.cfg.max_delay) + extra
    }

    /// Phases 1 ..= S, on the loaded `grid`.
    fn light(
        &mut self,
        grid: &LightGrid,
        sources: &[Source],
        envs: &[LightEnv<'_, F>],
        light: &LightConfig,
    ) -> Result<()> {
        if self.done || self.early.is_some() {
            return Ok(());
        }
        let start = |ex: &mut Self, b: usize, phase: u16| {
            let si = phase as usize - 1;
            let sv = sources[si].voxel();
            if ex.board_of(sv[0] as u32, sv[1] as u32) != b {
                return;
            }
            let mut rep = SourceReport::default();
            let beams = initial_beams(&sources[si], envs[si].far, None, None, light.timing.emission.order(), &mut rep);
            ex.activity.add(beams.len() as u64);
            ex.boards[b].emit.extend(beams.into_iter().map(|bm| BeamMsg::new(bm, sv[2] as u16)));
        };
        // Phase 1 started at board 0 when it declared the loading.
        start(self, 0, 1);
        self.schedule(u16::MAX, |ex, b| ex.step_lighting(b, grid, sources, envs, light), start)
    }

    /// Step the boards on their own schedules until board 0 declares phase `last` (or its
    /// last phase, or early). `start(ex, b, p)`: board b entered phase p (board 0 when it
    /// declared p − 1, the others when p's token reached them).
    fn schedule(
        &mut self,
        last: u16,
        mut work: impl FnMut(&mut Self, usize) -> Result<()>,
        mut start: impl FnMut(&mut Self, usize, u16),
    ) -> Result<()> {
        let phase_end = last;
        while !self.done && self.early.is_none() && self.boards[0].node.phase() <= phase_end {
            let b = (0..self.boards.len()).min_by_key(|&b| (self.boards[b].next_step, b)).unwrap_or(0);
            self.now = self.now.max(self.boards[b].next_step);
            if self.now > self.cfg.max_ticks {
                bail!(
                    "the boards hang: no declaration of phase {phase_end} after {} ticks ({} messages in flight, {} boards active)",
                    self.now,
                    self.in_flight,
                    self.passive.iter().filter(|p| !**p).count()
                );
            }
            if let Some(p) = self.take_token(b) {
                start(self, b, p);
            }
            work(self, b)?;
            if let Some(p) = self.poll(b)? {
                start(self, 0, p);
            }
            self.boards[b].next_step = self.now + 1 + self.rng.below(self.cfg.max_pause);
        }
        Ok(())
    }

    /// The token, if it arrived: decoded from its frame and handed to the node; the phase it
    /// made the board enter.
    fn take_token(&mut self, b: usize) -> Option<u16> {
        let arrived = self.boards[b].token_in.as_ref().is_some_and(|(t, _)| *t <= self.now);
        if !arrived {
            return None;
        }
        let (_, bytes) = self.boards[b].token_in.take()?;
        let Ok((TokenFrame { token: t, .. }, _)) = TokenFrame::parse(&bytes) else {
            unreachable!("the token frame decodes");
        };
        self.stats.token_hops += 1;
        self.phase.token_hops += 1;
        self.boards[b].node.token(t).entered
    }

    /// Whether board `b` has nothing to do.
    fn board_passive(&self, b: usize) -> bool {
        let bd = &self.boards[b];
        if !(bd.host.is_empty() && bd.work.is_empty() && bd.emit.is_empty()) {
            return false;
        }
        board_cells(bd.x0, bd.y0, self.n, self.tile).all(|i| !self.cells[i].busy())
    }

    /// Poll board `b`'s node; send its token, or check its declaration against the ground
    /// truth. Returns the phase board 0 entered by declaring.
    fn poll(&mut self, b: usize) -> Result<Option<u16>> {
        let passive = self.board_passive(b);
        self.passive[b] = passive;
        self.track_quiet();
        let action = self.boards[b].node.poll(passive).map_err(|e| anyhow::anyhow!("board {b}: {e:?}"))?;
        match action {
            Action::Wait => {}
            Action::Forward(t) => {
                if self.boards[b].node.position() == 0 {
                    self.phase.rounds += 1;
                }
                self.send_token(b, t);
            }
            Action::Declare(p) => {
                self.declare(p);
                return Ok((!self.done && self.early.is_none()).then(|| self.boards[b].node.phase()));
            }
        }
        Ok(None)
    }

    fn send_token(&mut self, b: usize, t: Token) {
        let mut buf = [0u8; TokenFrame::LEN];
        let len = TokenFrame { seq: 0, token: t }.emit(&mut buf).expect("a token frame fits");
        self.stats.token_bytes += len as u64;
        let to = self.boards[b].next;
        let at = self.now + 1 + self.rng.below(self.cfg.max_delay);
        debug_assert!(self.boards[to].token_in.is_none(), "one token");
        self.boards[to].token_in = Some((at, buf[..len].to_vec()));
    }

    /// Ground truth: since when (tick, token hops) nothing was active or in flight.
    fn track_quiet(&mut self) {
        let all_passive = self.passive.iter().all(|p| *p);
        let quiet = self.in_flight == 0 && all_passive;
        self.stats.passive_in_flight += u64::from(all_passive && self.in_flight > 0);
        match (quiet, self.quiet_since) {
            (false, _) => self.quiet_since = None,
            (true, None) => self.quiet_since = Some((self.now, self.stats.token_hops)),
            (true, Some(_)) => {}
        }
    }

    /// Board 0 declared phase `p`: check it against the ground truth (every board's cells and
    /// work, every wire), record its cost, and move on.
    fn declare(&mut self, p: u16) {
        let active = (0..self.boards.len()).filter(|&b| !self.board_passive(b)).count();
        let on_wires = self.regs.iter().filter(|r| r.frame.is_some()).count() as u64
            + self.boards.iter().map(|b| b.load_in.len() as u64).sum::<u64>();
        debug_assert_eq!(on_wires, self.in_flight);
        if active > 0 || on_wires > 0 || self.activity.get() > 0 || self.quiet_since.is_none() {
            self.early = Some(Early {
                phase: p,
                tick: self.now,
                in_flight: on_wires,
                active_boards: active,
                beams: self.activity.get(),
            });
            return;
        }
        let (quiet_at, hops) = self.quiet_since.unwrap_or_default();
        self.phase.phase = p;
        self.phase.declared_at = self.now;
        self.phase.quiet_at = quiet_at;
        self.phase.hops_after_quiescence = self.stats.token_hops - hops;
        self.stats.phases.push(std::mem::take(&mut self.phase));
        self.stats.ticks = self.now;
        self.quiet_since = Some((self.now, self.stats.token_hops));
        self.done = self.boards[0].node.is_done();
    }

    /// A basic message leaves board `b` (counted by its node unless the mutation is on).
    fn sent(&mut self, b: usize) -> Result<()> {
        self.in_flight += 1;
        self.phase.basic_messages += 1;
        if self.cfg.counting {
            self.boards[b].node.sent().map_err(|e| anyhow::anyhow!("board {b}: {e:?}"))?;
        }
        Ok(())
    }

    /// A basic message reaches board `b`.
    fn received(&mut self, b: usize) -> Result<()> {
        self.in_flight -= 1;
        if self.cfg.counting {
            self.boards[b].node.received().map_err(|e| anyhow::anyhow!("board {b}: {e:?}"))?;
        }
        Ok(())
    }

    /// Send a loading packet from board `b` to the board holding its next cell, in order.
    fn send_load(&mut self, b: usize, to: usize, msg: Load) -> Result<()> {
        self.sent(b)?;
        let d = self.delay(b);
        let last = self.boards[to].load_in.back().map_or(0, |(t, _)| *t);
        let at = (self.now + d).max(last);
        self.boards[to].load_in.push_back((at, msg));
        Ok(())
    }

    /// One loading step of board `b`: take the arrived packets, inject one host facet, move
    /// every packet on the work list one cell.
    fn step_loading(&mut self, b: usize, grid: &mut LightGrid) -> Result<()> {
        while self.boards[b].load_in.front().is_some_and(|(t, _)| *t <= self.now) {
            if let Some((_, m)) = self.boards[b].load_in.pop_front() {
                self.received(b)?;
                self.boards[b].work.push_back(m);
            }
        }
        if let Some(p) = self.boards[b].host.pop_front() {
            self.boards[b].work.push_back(Load::Pipe(0, p));
        }
        let (n, depth) = (self.n, grid.depth);
        for _ in 0..self.boards[b].work.len() {
            let Some(item) = self.boards[b].work.pop_front() else { break };
            let next = match item {
                Load::Pipe(y, mut p) => {
                    let step = PipelineCell { y: y as u16 }.step(&mut p);
                    if let Some(rp) = step.east {
                        self.boards[b].work.push_back(Load::Row(0, y, rp));
                    }
                    (step.down && y + 1 < n).then(|| (Load::Pipe(y + 1, p), (0, y + 1)))
                }
                Load::Row(x, y, mut rp) => {
                    let forward = grid.cells[(y * n + x) as usize].load_step(&mut rp, depth);
                    (forward && x + 1 < n).then(|| (Load::Row(x + 1, y, rp), (x + 1, y)))
                }
            };
            if let Some((m, (x, y))) = next {
                let to = self.board_of(x, y);
                if to == b {
                    self.boards[b].work.push_back(m);
                } else {
                    self.send_load(b, to, m)?;
                }
            }
        }
        Ok(())
    }

    /// One lighting step of board `b`: take arrived beams into their cells' FIFOs, emit,
    /// step the cells, move the output buffers' heads over their links.
    fn step_lighting(
        &mut self,
        b: usize,
        grid: &LightGrid,
        sources: &[Source],
        envs: &[LightEnv<'_, F>],
        light: &LightConfig,
    ) -> Result<()> {
        let n = self.n;
        let own = board_cells(self.boards[b].x0, self.boards[b].y0, n, self.tile);
        let fa = envs.first().map_or(light.fa, |e| e.fa);
        let tally = ActivityDelta::new();
        // Arrived beams, into the FIFOs with room.
        for i in own.clone() {
            for back in 0..8 {
                let s = i * 8 + back;
                let arrived = self.regs[s].frame.is_some_and(|(at, _)| at <= self.now);
                if arrived && self.cells[i].can_accept(fa) {
                    if let Some((_, m)) = self.regs[s].frame.take() {
                        self.received(b)?;
                        let _ = self.cells[i].accept(m, light.merge, &tally);
                    }
                }
            }
        }
        // The source cell's next initial beam.
        if let Some(m) = self.boards[b].emit.front().copied() {
            let source = &sources[m.beam.source().0 as usize];
            let sv = source.voxel();
            let s = (sv[1] as u32 * n + sv[0] as u32) as usize;
            if self.cells[s].can_accept_initial(fa, source)
                && self.cells[s].accept(m, light.merge, &self.activity).is_ok()
            {
                self.boards[b].emit.pop_front();
            }
        }
        // Compute.
        for i in own.clone() {
            if let Some(m) = self.cells[i].fifo.first() {
                let env = &envs[m.beam.source().0 as usize];
                self.cells[i].step(&grid.cells[i], env, &tally);
            }
        }
        // Links.
        for i in own {
            for p in Port::ALL {
                let Some(&m) = self.cells[i].out.front(p) else { continue };
                let (dx, dy) = p.delta();
                let (x, y) = ((i as u32 % n) as i64 + dx as i64, (i as u32 / n) as i64 + dy as i64);
                let j = (y * n as i64 + x) as usize;
                let s = j * 8 + BACK[p.index()];
                let taken = match self.wires[s].as_mut() {
                    Some(w) => {
                        if !sure(w.ready(&self.regs[s])) {
                            continue;
                        }
                        let sent = sure(w.send(self.now, &m, &mut self.regs[s]));
                        if sent.acked {
                            self.sent(b)?;
                        }
                        sent.acked
                    }
                    None => {
                        let cell = &mut self.cells[j];
                        let mut rx =
                            CellInbox { cell, fa, merge: light.merge, tally: &tally, journal: &mut self.journal };
                        let mut link = PerfectLink;
                        if !sure(Link::<F, _>::ready(&mut link, &rx)) {
                            continue;
                        }
                        sure(link.send(self.now, &m, &mut rx)).acked
                    }
                };
                if taken {
                    self.cells[i].out.pop_front(p);
                    self.phase.beam_transfers += 1;
                }
            }
        }
        self.activity.apply(tally.get());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rings_are_cycles_over_neighbour_links() {
        for (tx, ty) in [(1, 1), (2, 1), (1, 2), (2, 2), (3, 2), (2, 3), (4, 4), (5, 4), (4, 5), (6, 3)] {
            let r = ring(tx, ty).unwrap();
            let mut seen = r.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..tx * ty).collect::<Vec<_>>(), "{tx} × {ty}: every board once");
            for k in 0..r.len() {
                let (a, b) = (r[k], r[(k + 1) % r.len()]);
                let d = (a % tx).abs_diff(b % tx) + (a / tx).abs_diff(b / tx);
                assert!(r.len() == 1 || d == 1, "{tx} × {ty}: {a} → {b} is not a link");
            }
        }
        for (tx, ty) in [(3, 3), (1, 3), (5, 1)] {
            assert!(ring(tx, ty).is_err(), "{tx} × {ty} has no Hamiltonian cycle over 4-neighbour links");
        }
    }
}

//! One grid cut into tiles (thesis §4.4's machine over several processes): each tile steps
//! its own cells, and the links that cross a tile edge carry their messages through a
//! [`Halo`] once per cycle. The result — every cell's lit store, counters and pixel, every
//! report's cycles, beams and messages — is the one-process run's.
//!
//! A tile is a band of whole rows ([`Tile`]): a cell's eight neighbours lie in its own band or
//! the bands just above and below, so a tile talks to two others each cycle. What crosses a
//! tile edge is what the link phase already passes between a sender and a receiver
//! (`cycle`'s model: a sender offers the front message of an output buffer, the receiver's
//! link takes it or not):
//!
//! 1. after the compute phase, the offers of this tile's senders to receivers in another tile
//!    go to that tile, and the other tiles' offers to this tile's receivers come in
//!    ([`Edge::offers`]); each receiver arbitrates its offers as in one process (by key,
//!    then sender), through its own link (perfect, or the fault injector: a link lives with
//!    its receiver);
//! 2. after the link phase, what the receivers took of another tile's senders (and, on links
//!    that acknowledge later, what went on the wire unacknowledged) goes back to the senders'
//!    tile before any sender pops ([`Edge::answers`]);
//! 3. at the end of the cycle, the machine-wide figures — beams in flight (the global activity
//!    counter: quiescence), busy cells, progress — are sums over the tiles ([`Halo::sum`]),
//!    so that every tile ends in the same cycle, or stops with the same stall report.
//!
//! Invariant: a tile holds and steps its band's lighting cells and the links into them, and
//! nothing else of the lighting state (the scene's grid of dexels, read only, is whole on every
//! tile), so a tile's counters and lit stores are exactly its cells' share of the one-process
//! run's, and a source's report is the tiles' reports put together ([`whole_report`]). The
//! per-cell flags of the cycle loop (a few bytes a cell) stay indexed by the whole grid.
//!
//! Here: the tile, the seam ([`Halo`]), a part's tile of cells ([`diffuse_tile`]), the parts
//! put together ([`merge_tiles`]), and tiles on threads of one process
//! ([`diffuse_in_tiles`]: the seam over in-memory channels, what the tests compare with one
//! process). The MPI seam is `crate::dist`'s; nothing here knows of ranks.

use std::ops::Range;
use std::sync::atomic::{AtomicU8, Ordering::Relaxed};
use std::sync::mpsc::{channel, Receiver, Sender};

use anyhow::{anyhow, bail, Context, Result};
use cell_core::beam::{FarDistance, FracBits, Source};
use cell_core::wire::{get_beam, put_beam};

use super::offer::{Offer, Taken};
use super::share::{report_from, report_to, Reader, Writer};
use super::{DiffusionCounts, LightConfig, Lighting, PhaseSeconds, SourceReport};
use crate::machine::grid::capacity::DEFAULT_DEXELS;
use crate::machine::grid::LightGrid;
use crate::machine::links::faults::FaultCounts;

/// A tile of an n × n grid: band `index` of `of` bands of whole rows, from the top (row 0).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tile {
    /// This band, 0 .. `of`.
    pub index: usize,
    /// How many bands.
    pub of: usize,
    /// Its rows.
    pub rows: Range<u32>,
}

impl Tile {
    /// The bands of an n × n grid cut above each row of `cuts` (increasing, within 1 .. n):
    /// `cuts.len() + 1` bands of at least one row each.
    pub fn bands(n: u32, cuts: &[u32]) -> Result<Vec<Tile>> {
        if cuts.windows(2).any(|w| w[0] >= w[1]) || cuts.iter().any(|&c| c == 0 || c >= n) {
            bail!(
                "tile cuts {cuts:?} must increase strictly within 1 ..= {} (bands of at least one row each)",
                n.saturating_sub(1)
            );
        }
        let ends: Vec<u32> = std::iter::once(0).chain(cuts.iter().copied()).chain([n]).collect();
        let of = ends.len() - 1;
        Ok(ends.windows(2).enumerate().map(|(index, w)| Tile { index, of, rows: w[0]..w[1] }).collect())
    }

    /// The cuts of `of` bands of equal height (but for one row): above rows ⌊i·n/of⌋.
    pub fn even_cuts(of: usize, n: u32) -> Result<Vec<u32>> {
        if of == 0 || of > n as usize {
            bail!("{of} tiles of whole rows do not fit an {n} × {n} grid (1 ..= {n})");
        }
        Ok((1..of as u64).map(|i| (i * n as u64 / of as u64) as u32).collect())
    }

    /// The cuts of `of` bands (one row at least each) whose largest share of `work` (per row, from
    /// the top) is the smallest any cut into `of` bands achieves: every cycle waits for the busiest
    /// band, so this balances a run whose work per row was measured (by beams processed). Among
    /// equal cuts, each band reaches as far down as that least largest band allows.
    pub fn balanced_cuts(work: &[u64], of: usize) -> Result<Vec<u32>> {
        let n = work.len();
        if of == 0 || of > n {
            bail!("{of} bands of whole rows do not fit {n} rows (1 ..= {n})");
        }
        // The least largest band: the smallest load L at which a greedy cut from the top (a band
        // grows while it stays within L) needs at most `of` bands.
        let bands_within = |limit: u64| {
            let (mut bands, mut load) = (1usize, 0u64);
            for &w in work {
                if load + w > limit {
                    bands += 1;
                    load = 0;
                }
                load += w;
            }
            bands
        };
        let (mut lo, mut hi) = (work.iter().copied().max().unwrap_or(0), work.iter().sum::<u64>());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if bands_within(mid) <= of {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        // The same greedy cut at that load, also cutting where the rows left are just enough for
        // the bands left (which only lightens bands).
        let mut cuts = Vec::with_capacity(of - 1);
        let mut load = 0u64;
        for (row, &w) in work.iter().enumerate() {
            let left = of - 1 - cuts.len();
            if row > 0 && left > 0 && (load + w > lo || n - row == left) {
                cuts.push(row as u32);
                load = 0;
            }
            load += w;
        }
        Ok(cuts)
    }

    /// Each band's sum of `work` (per row, from the top) under `cuts`.
    pub fn band_loads(work: &[u64], cuts: &[u32]) -> Vec<u64> {
        let ends: Vec<usize> = std::iter::once(0).chain(cuts.iter().map(|&c| c as usize)).chain([work.len()]).collect();
        ends.windows(2).map(|w| work[w[0]..w[1]].iter().sum()).collect()
    }

    /// Its cells (row-major indices) in an n × n grid.
    pub fn cells(&self, n: u32) -> Range<u32> {
        self.rows.start * n..self.rows.end * n
    }
}

/// What the tiles of one grid exchange (the link seam across a tile edge: MPI between
/// processes in `crate::dist`, channels between threads in [`diffuse_in_tiles`]). Every tile
/// calls the same methods in the same order; a tile that fails or vanishes makes the others'
/// calls fail (or, under MPI, ends the run), never wait for ever.
pub trait Halo {
    /// This tile.
    fn tile(&self) -> Tile;

    /// Send `up` to the tile above (index − 1) and `down` to the tile below (index + 1) —
    /// nothing where there is none — and return what they sent this tile: (from the tile
    /// above, from the tile below).
    fn swap(&mut self, up: &[u8], down: &[u8]) -> Result<(Vec<u8>, Vec<u8>)>;

    /// Every tile's `mine`, in tile order, on every tile.
    fn gather(&mut self, mine: &[u8]) -> Result<Vec<Vec<u8>>>;

    /// What this tile has sent so far: bytes to the tiles above and below ([`Halo::swap`]),
    /// and how many swaps (two a cycle).
    fn traffic(&self) -> Traffic;

    /// Each value summed over the tiles, on every tile.
    fn sum(&mut self, v: &mut [i64]) -> Result<()> {
        let mine: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let all = self.gather(&mine)?;
        v.iter_mut().for_each(|x| *x = 0);
        for bytes in &all {
            if bytes.len() != v.len() * 8 {
                bail!("a tile sent {} bytes of sums where {} were due", bytes.len(), v.len() * 8);
            }
            for (x, b) in v.iter_mut().zip(bytes.chunks_exact(8)) {
                *x += i64::from_le_bytes(b.try_into().expect("8 bytes"));
            }
        }
        Ok(())
    }
}

/// What a tile sent its neighbours, and how long it waited for the others ([`Halo::traffic`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Traffic {
    /// Bytes sent to the tiles above and below.
    pub bytes: u64,
    /// Swaps (two a cycle: offers, then answers).
    pub swaps: u64,
    /// Host seconds spent in the seam's calls (sending, and waiting for the other tiles).
    pub seconds: f64,
}

impl Traffic {
    /// One swap more by `tile`: `up` bytes to the tile above and `down` to the tile below,
    /// each counted where that tile exists.
    pub fn add(&mut self, tile: &Tile, up: usize, down: usize) {
        let up = if tile.index > 0 { up } else { 0 };
        let down = if tile.index + 1 < tile.of { down } else { 0 };
        self.bytes += (up + down) as u64;
        self.swaps += 1;
    }

    /// As bytes for another tile ([`Traffic::from_bytes`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        [self.bytes, self.swaps, self.seconds.to_bits()].iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// What [`Traffic::to_bytes`] wrote.
    pub fn from_bytes(b: &[u8]) -> Result<Traffic> {
        let mut r = Reader::new(b);
        let (bytes, swaps, seconds) = (r.u64()?, r.u64()?, f64::from_bits(r.u64()?));
        Ok(Traffic { bytes, swaps, seconds })
    }
}

/// Bytes of an offer between tiles: receiver, key, sender (u32 each), port (u8), then the
/// beam's fields (`cell_core::wire::put_beam`, 26 bytes).
const OFFER_BYTES: usize = 13 + 26;

/// Bytes of an answer between tiles: sender (u32), its [`Taken`] counts (u32), its
/// unacknowledged ports (u8).
const ANSWER_BYTES: usize = 9;

/// The edge of one tile during a source's diffusion: its seam, its cells, and the senders of
/// other tiles whose offers it received this cycle (above, below).
pub(super) struct Edge<'a> {
    halo: &'a mut dyn Halo,
    cells: Range<u32>,
    remote: [Vec<u32>; 2],
    out: [Writer; 2],
}

impl<'a> Edge<'a> {
    /// The edge of `halo`'s tile of an n × n grid.
    pub(super) fn new(halo: &'a mut dyn Halo, n: u32) -> Self {
        let cells = halo.tile().cells(n);
        Edge { halo, cells, remote: Default::default(), out: [Writer(Vec::new()), Writer(Vec::new())] }
    }

    /// This tile's cells.
    pub(super) fn cells(&self) -> Range<u32> {
        self.cells.clone()
    }

    /// Whether cell `i` is this tile's.
    pub(super) fn owns(&self, i: u32) -> bool {
        self.cells.contains(&i)
    }

    /// Hand the offers of `lists` (per port, by receiver) whose receiver lies in another tile
    /// to that tile, and put the other tiles' offers to this tile's receivers in their place:
    /// afterwards every list holds exactly the offers to this tile's receivers, by receiver.
    pub(super) fn offers<F: FracBits>(&mut self, lists: &mut [Vec<Offer<F>>; 8], far: FarDistance<F>) -> Result<()> {
        let (lo, hi) = (self.cells.start, self.cells.end);
        self.out.iter_mut().for_each(|w| w.0.clear());
        for l in lists.iter_mut() {
            let (a, b) = (l.partition_point(|o| o.to < lo), l.partition_point(|o| o.to < hi));
            for o in &l[b..] {
                put_offer(&mut self.out[1], o);
            }
            for o in &l[..a] {
                put_offer(&mut self.out[0], o);
            }
            l.truncate(b);
            l.drain(..a);
        }
        let (above, below) = self.halo.swap(&self.out[0].0, &self.out[1].0)?;
        let mut touched = 0u8;
        for (k, bytes) in [above, below].iter().enumerate() {
            self.remote[k].clear();
            let mut r = Reader::new(bytes);
            while r.left() > 0 {
                let o = get_offer(&mut r, far)?;
                if !self.cells.contains(&o.to) || self.cells.contains(&o.from) || o.port >= 8 {
                    bail!(
                        "a tile sent an offer from cell {} to cell {}, which is not across this tile's edge",
                        o.from,
                        o.to
                    );
                }
                self.remote[k].push(o.from);
                touched |= 1 << o.port;
                lists[o.port as usize].push(o);
            }
            self.remote[k].sort_unstable();
            self.remote[k].dedup();
        }
        // The offers that came in were appended: a stable sort by receiver (a merge of runs
        // already sorted) puts them in place and keeps each receiver's offers in their order
        // (a receiver's offers on one port come from one sender, here or in another tile).
        for (p, l) in lists.iter_mut().enumerate() {
            if touched & 1 << p != 0 {
                l.sort_by_key(|o| o.to);
            }
        }
        Ok(())
    }

    /// Send back what this tile's receivers took of the other tiles' senders (their
    /// [`Taken`] counts, then cleared here) and which of their offers went on the wire
    /// unacknowledged; add what the other tiles took of this tile's senders.
    pub(super) fn answers(&mut self, taken: &[Taken], unacked: &[AtomicU8], lossless: bool) -> Result<()> {
        for (w, senders) in self.out.iter_mut().zip(&self.remote) {
            w.0.clear();
            for &s in senders {
                let t = taken[s as usize].swap(0, Relaxed);
                let u = if lossless { 0 } else { unacked[s as usize].swap(0, Relaxed) };
                if t != 0 || u != 0 {
                    w.u32(s);
                    w.u32(t);
                    w.u8(u);
                }
            }
        }
        let (above, below) = self.halo.swap(&self.out[0].0, &self.out[1].0)?;
        for bytes in [above, below] {
            if bytes.len() % ANSWER_BYTES != 0 {
                bail!("a tile sent {} bytes of link answers, not a whole number of answers", bytes.len());
            }
            let mut r = Reader::new(&bytes);
            while r.left() > 0 {
                let (s, t, u) = (r.u32()?, r.u32()?, r.u8()?);
                if !self.cells.contains(&s) || (lossless && u != 0) {
                    bail!("a tile answered for cell {s}, which is not this tile's sender");
                }
                // Each port's count is its own 4 bits, and a port leads to one receiver.
                taken[s as usize].fetch_or(t, Relaxed);
                if u != 0 {
                    unacked[s as usize].fetch_or(u, Relaxed);
                }
            }
        }
        Ok(())
    }

    /// Sum `v` over the tiles.
    pub(super) fn sum(&mut self, v: &mut [i64]) -> Result<()> {
        self.halo.sum(v)
    }

    /// The busiest link of the whole grid from each tile's (link index, messages): the most
    /// messages, the first link in index order among equals, as in one process.
    pub(super) fn busiest(&mut self, mine: Option<(usize, u32)>) -> Result<Option<(usize, u32)>> {
        let mut w = Writer(Vec::new());
        if let Some((i, load)) = mine {
            w.u64(i as u64);
            w.u32(load);
        }
        let mut best: Option<(usize, u32)> = None;
        for bytes in self.halo.gather(&w.0)? {
            if bytes.is_empty() {
                continue;
            }
            let mut r = Reader::new(&bytes);
            let (i, load) = (r.u64()? as usize, r.u32()?);
            if best.is_none_or(|(bi, bl)| (load, std::cmp::Reverse(i)) > (bl, std::cmp::Reverse(bi))) {
                best = Some((i, load));
            }
        }
        Ok(best)
    }
}

fn put_offer<F: FracBits>(w: &mut Writer, o: &Offer<F>) {
    w.u32(o.to);
    w.u32(o.key);
    w.u32(o.from);
    w.u8(o.port);
    // A Vec never refuses bytes.
    let _ = put_beam(w, &o.msg);
}

fn get_offer<F: FracBits>(r: &mut Reader<'_>, far: FarDistance<F>) -> Result<Offer<F>> {
    let (to, key, from, port) = (r.u32()?, r.u32()?, r.u32()?, r.u8()?);
    let mut b = cell_core::bytes::Reader::new(r.take(OFFER_BYTES - 13)?);
    let msg = get_beam(&mut b, far).map_err(|e| anyhow!("a tile sent a beam that does not decode: {e:?}"))?;
    Ok(Offer { to, key, from, port, msg })
}

/// One source's report of the whole grid from each tile's (its cells' counts and its links'
/// messages, the machine-wide figures already summed): sums of what the cells and links
/// counted, maxima of their peaks, the busiest cell the first in row-major order among the
/// busiest, as in one process.
pub(super) fn whole_report(halo: &mut dyn Halo, mine: SourceReport) -> Result<SourceReport> {
    let mut w = Writer(Vec::new());
    report_to(&mut w, &mine);
    let mut parts = Vec::new();
    for bytes in halo.gather(&w.0)? {
        let mut r = Reader::new(&bytes);
        parts.push(report_from(&mut r).context("a tile's source report")?);
    }
    let mut whole = mine;
    // The figures every tile settled together, the same in every tile's report.
    let (cycles, peak_active) = (whole.counts.cycles, whole.counts.peak_active_cells);
    let mut c = DiffusionCounts::default();
    for p in &parts {
        let k = &p.counts;
        if p.source != whole.source || k.cycles != cycles || k.peak_active_cells != peak_active {
            bail!("the tiles disagree on source {}'s cycles or busy cells (a bug)", whole.source);
        }
        if k.lb_cell_load > c.lb_cell_load {
            whole.busiest_cell = p.busiest_cell;
        }
        // Sums of the tiles' counts, maxima of their peaks (the settled ones are equal).
        c.add(k);
    }
    if c.lb_cell_load == 0 {
        whole.busiest_cell = parts.first().map_or(whole.busiest_cell, |p| p.busiest_cell);
    }
    c.cycles = cycles;
    c.lower_bound = c.lb_distance.max(c.lb_cell_load);
    whole.counts = c;
    Ok(whole)
}

/// What a run cut into tiles cannot do (yet): the settings that make its tiles share more
/// than their edges' messages and the machine-wide sums. (A run that counts rays is cut: a
/// column's arrivals are counted by its own cell, so each tile's weights are its rows'.)
fn check_tiled(cfg: &LightConfig) -> Result<()> {
    if cfg.record_visits {
        bail!("a lighting run cut into tiles does not record visited voxels");
    }
    Ok(())
}

/// This tile's part of the diffusion of `sources` over `grid`: its cells' lighting and, in a
/// run that counts rays, its columns' pixel weights (the tile held no other cells), the whole
/// grid's reports (the same on every tile), what its links' fault injectors
/// did. [`merge_tiles`] puts the parts of every tile together.
pub fn diffuse_tile(
    grid: &LightGrid,
    sources: &[Source],
    cfg: &LightConfig,
    halo: &mut dyn Halo,
    progress: &mut dyn FnMut(usize, u64),
) -> Result<Lighting> {
    let tile = halo.tile();
    if tile.rows.is_empty() || tile.rows.end > grid.n {
        bail!("tile {} holds rows {:?}, not a band of the {} rows", tile.index, tile.rows, grid.n);
    }
    check_tiled(cfg)?;
    let edge: &mut dyn Halo = &mut *halo;
    // The tile holds its band's cells alone: its part is theirs (cells and weights).
    super::with_f!(cfg.frac_bits, F => {
        super::diffuse_cells::<F, DEFAULT_DEXELS>(grid, sources, cfg, super::Share::ALL, None, Some(edge), progress)
            .map(|(l, _)| l)
    })
}

/// The whole run from every tile's part ([`diffuse_tile`], in tile order): the cells of each
/// tile from its own part, the reports (every tile's are the whole grid's), the fault counts
/// added up, the host seconds added up.
pub fn merge_tiles(parts: Vec<Lighting>) -> Result<Lighting> {
    let Some(first) = parts.first() else { bail!("no lighting part to merge") };
    let (n, rule) = (first.n, first.rule);
    let of = parts.len();
    let mut phases = PhaseSeconds::default();
    let mut link_faults: Option<FaultCounts> = None;
    let mut cells: Vec<super::LitColumn> = Vec::with_capacity((n * n) as usize);
    let reports = first.reports.clone();
    // Each source's pixel weights, band after band (a run that counts rays).
    let mut weights: Option<Vec<Vec<u8>>> = first.weights.as_ref().map(|w| vec![Vec::new(); w.len()]);
    let row_major = |k: usize| (k / n as usize, k % n as usize);
    for (index, p) in parts.into_iter().enumerate() {
        if p.n != n || p.rule != rule || p.reports != reports {
            bail!("the tiles' lighting parts are of different runs (tile {index})");
        }
        match (weights.as_mut(), &p.weights) {
            (None, None) => {}
            (Some(all), Some(w)) if all.len() == w.len() && w.iter().all(|s| s.len() == p.cells.len()) => {
                all.iter_mut().zip(w).for_each(|(a, s)| a.extend_from_slice(s));
            }
            _ => bail!("tile {index}'s pixel weights are not its band's, one list per source"),
        }
        // Whole rows, row-major, from where the tile above ended.
        let at = cells.len();
        if p.cells.is_empty()
            || p.cells.len() % n as usize != 0
            || p.cells.iter().enumerate().any(|(k, c)| (c.y as usize, c.x as usize) != row_major(at + k))
        {
            bail!("tile {index}'s lighting part does not hold the whole rows below the tile above's");
        }
        cells.extend(p.cells);
        phases = super::share::add_phases(&phases, &p.phases);
        if let Some(f) = &p.link_faults {
            link_faults.get_or_insert_with(FaultCounts::default).add(f);
        }
    }
    if cells.len() != (n * n) as usize {
        bail!("{of} tiles' parts hold {} cells of an {n} × {n} grid", cells.len());
    }
    Ok(Lighting { n, cells, reports, visited: None, link_faults, rule, phases, weights })
}

/// The error of a tile whose neighbour ended first (with an error of its own).
#[derive(Debug)]
struct Ended(usize);

impl std::fmt::Display for Ended {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "tile {} ended before this tile's exchange with it", self.0)
    }
}

impl std::error::Error for Ended {}

/// A [`Halo`] between threads of one process: unbounded channels between every two tiles
/// (messages between two tiles arrive in the order sent; a tile that ends drops its senders,
/// and the others' receives fail instead of waiting).
pub struct ThreadHalo {
    tile: Tile,
    traffic: Traffic,
    to: Vec<Option<Sender<Vec<u8>>>>,
    from: Vec<Option<Receiver<Vec<u8>>>>,
}

impl ThreadHalo {
    /// The seams of `tiles` (every tile of a grid, in tile order), one per tile.
    pub fn tiles(tiles: Vec<Tile>) -> Vec<ThreadHalo> {
        let of = tiles.len();
        let mut halos: Vec<ThreadHalo> = tiles
            .into_iter()
            .map(|tile| ThreadHalo {
                tile,
                traffic: Traffic::default(),
                to: (0..of).map(|_| None).collect(),
                from: (0..of).map(|_| None).collect(),
            })
            .collect();
        for a in 0..of {
            for b in 0..of {
                if a != b {
                    let (tx, rx) = channel();
                    halos[a].to[b] = Some(tx);
                    halos[b].from[a] = Some(rx);
                }
            }
        }
        halos
    }

    fn send(&self, to: usize, bytes: &[u8]) -> Result<()> {
        let tx = self.to[to].as_ref().ok_or_else(|| anyhow!("tile {to} is not a neighbour"))?;
        tx.send(bytes.to_vec()).map_err(|_| Ended(to).into())
    }

    fn receive(&self, from: usize) -> Result<Vec<u8>> {
        let rx = self.from[from].as_ref().ok_or_else(|| anyhow!("tile {from} is not a neighbour"))?;
        rx.recv().map_err(|_| Ended(from).into())
    }
}

impl Halo for ThreadHalo {
    fn tile(&self) -> Tile {
        self.tile.clone()
    }

    fn traffic(&self) -> Traffic {
        self.traffic
    }

    fn swap(&mut self, up: &[u8], down: &[u8]) -> Result<(Vec<u8>, Vec<u8>)> {
        let (i, of) = (self.tile.index, self.tile.of);
        self.traffic.add(&self.tile, up.len(), down.len());
        if i > 0 {
            self.send(i - 1, up)?;
        }
        if i + 1 < of {
            self.send(i + 1, down)?;
        }
        let above = if i > 0 { self.receive(i - 1)? } else { Vec::new() };
        let below = if i + 1 < of { self.receive(i + 1)? } else { Vec::new() };
        Ok((above, below))
    }

    fn gather(&mut self, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
        let (i, of) = (self.tile.index, self.tile.of);
        for j in (0..of).filter(|&j| j != i) {
            self.send(j, mine)?;
        }
        (0..of).map(|j| if j == i { Ok(mine.to_vec()) } else { self.receive(j) }).collect()
    }
}

/// The diffusion of `sources` over `grid` cut into tiles above the rows `cuts`
/// ([`Tile::bands`]), each on a thread of its own (one cycle-loop thread each, whatever
/// `--threads`), through [`ThreadHalo`]s: the whole run, as [`super::diffuse`] gives it in one
/// piece.
pub fn diffuse_in_tiles(grid: &LightGrid, sources: &[Source], cfg: &LightConfig, cuts: &[u32]) -> Result<Lighting> {
    let tiles = Tile::bands(grid.n, cuts)?;
    let parts: Vec<Result<Lighting>> = std::thread::scope(|s| {
        let runs: Vec<_> = ThreadHalo::tiles(tiles)
            .into_iter()
            .map(|mut halo| {
                s.spawn(move || {
                    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("a tile's thread pool")?;
                    one.install(|| diffuse_tile(grid, sources, cfg, &mut halo, &mut |_, _| {}))
                })
            })
            .collect();
        runs.into_iter().map(|r| r.join().unwrap_or_else(|_| Err(anyhow!("a tile's thread panicked")))).collect()
    });
    // A tile's own error first, not the "tile ended" of the tiles it left waiting.
    if let Some(i) = parts.iter().position(|p| p.as_ref().is_err_and(|e| e.downcast_ref::<Ended>().is_none())) {
        return Err(parts.into_iter().nth(i).and_then(Result::err).expect("an error"));
    }
    merge_tiles(parts.into_iter().collect::<Result<Vec<_>>>()?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{plane_rule, Preset};
    use crate::machine::lighting::diffuse::share::tests::assert_same;
    use crate::machine::lighting::diffuse::{decode_part, diffuse, encode_part, Stepping};
    use crate::machine::lighting::timing::Timing;
    use crate::machine::links::faults::LinkFaults;
    use crate::machine::loading::loaded_scene::{load_scene, resolve_lights};
    use crate::precompute::LoadConfig;
    use cell_core::visibility::Visibility;

    /// Bands cover the rows once, in order, each at least one row high; cuts that are not
    /// increasing within the grid are refused.
    #[test]
    fn tiles_cut_the_rows_into_bands() {
        for n in [1u32, 2, 7, 24, 64] {
            for of in 1..=n as usize {
                let bands = Tile::bands(n, &Tile::even_cuts(of, n).unwrap()).unwrap();
                assert_eq!(bands.len(), of);
                let mut next = 0;
                for (index, t) in bands.iter().enumerate() {
                    assert_eq!((t.index, t.of, t.rows.start), (index, of, next), "n {n}, {of} tiles");
                    assert!(t.rows.end > t.rows.start);
                    assert!(t.rows.len().abs_diff(n as usize / of) <= 1, "even bands");
                    next = t.rows.end;
                }
                assert_eq!(next, n);
            }
            assert!(Tile::even_cuts(n as usize + 1, n).is_err());
            assert!(Tile::even_cuts(0, n).is_err());
            assert!(Tile::bands(n, &[n]).is_err());
            assert!(Tile::bands(n, &[0]).is_err());
        }
        assert!(Tile::bands(8, &[3, 3]).is_err());
        assert!(Tile::bands(8, &[5, 3]).is_err());
        let rows: Vec<_> = Tile::bands(8, &[1, 7]).unwrap().into_iter().map(|t| t.rows).collect();
        assert_eq!(rows, [0..1, 1..7, 7..8]);
    }

    /// The largest band's work under `cuts` (rows from the top), summed here.
    fn largest_band(work: &[u64], cuts: &[u32]) -> u64 {
        let mut bands = vec![0u64; cuts.len() + 1];
        for (row, &w) in work.iter().enumerate() {
            bands[cuts.iter().filter(|&&c| c as usize <= row).count()] += w;
        }
        assert_eq!(Tile::band_loads(work, cuts), bands);
        bands.into_iter().max().unwrap()
    }

    proptest::proptest! {
        /// Balanced cuts are cuts (`of` bands of one row at least) and their largest band is the
        /// least over every way of cutting the rows into `of` bands (all of them tried).
        #[test]
        fn balanced_cuts_give_the_least_largest_band(
            work in proptest::collection::vec(proptest::prop_oneof![proptest::strategy::Just(0u64), 0u64..50], 1..11),
            of in 1usize..11,
        ) {
            let n = work.len();
            if of > n {
                proptest::prop_assert!(Tile::balanced_cuts(&work, of).is_err());
                return Ok(());
            }
            let cuts = Tile::balanced_cuts(&work, of).unwrap();
            proptest::prop_assert!(Tile::bands(n as u32, &cuts).is_ok_and(|b| b.len() == of), "{cuts:?}");
            // Every choice of of − 1 cuts among rows 1 .. n.
            let best = (0u32..1 << (n - 1))
                .filter(|m| m.count_ones() as usize == of - 1)
                .map(|m| {
                    let c: Vec<u32> = (1..n as u32).filter(|r| m >> (r - 1) & 1 == 1).collect();
                    largest_band(&work, &c)
                })
                .min()
                .unwrap();
            proptest::prop_assert_eq!(largest_band(&work, &cuts), best, "cuts {:?}", cuts);
        }
    }

    /// The Cornell box lit by two sources, in one piece and cut into 2, 3, 5 and 24 even bands
    /// (one row each) and into uneven ones (a band of one row beside one of 23): every cell's lit store, visible mask and counters, every report and the
    /// link faults the same, under each preset and lit rule, the sibling wait (sleeping cells),
    /// every cell stepped, faulty links (acknowledged later), several messages per link and
    /// cycle, a snapshot stopped mid-run and the lit-ray ratio's counted rays (each column's
    /// pixel weights); the parts carried as bytes between tiles.
    #[test]
    fn tiles_give_the_one_piece_run() {
        let n = 24;
        let mesh = crate::scene::load("cornell").unwrap();
        let scene = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
        let lights = resolve_lights(&mesh, &scene, &[[0.5, 0.9, 0.5], [0.2, 0.45, 0.3]]).unwrap();
        let faults: LinkFaults = "corrupt=0.02,drop=0.02,delay=0.05,delay-cycles=3,seed=5".parse().unwrap();
        let configs = [
            ("render", Preset::Render.light()),
            ("light", Preset::Light.light()),
            ("thesis", Preset::Thesis.light()),
            ("plane", plane_rule()),
            ("hold", LightConfig { hold: 3, ..plane_rule() }),
            ("all cells", LightConfig { stepping: Stepping::AllCells, ..Preset::Render.light() }),
            ("faults", LightConfig { faults: Some(faults), ..Preset::Render.light() }),
            (
                "link rate",
                LightConfig {
                    timing: Timing { link_rate: 2, ..Preset::Render.light().timing },
                    ..Preset::Render.light()
                },
            ),
            ("snapshot", LightConfig { stop_at: Some(40), ..plane_rule() }),
            ("ratio", LightConfig { visibility: Visibility::Ratio, ..Preset::Render.light() }),
        ];
        for (name, cfg) in configs {
            let sources: Vec<_> = lights.iter().enumerate().map(|(i, p)| cfg.source(i, *p, n).unwrap()).collect();
            let whole = diffuse(&scene.grid, &sources, &cfg, |_, _| {}).unwrap();
            assert!(whole.lit_voxels().count() > 0 || cfg.lit_visible_only, "{name}: something is lit");
            assert!(whole.reports.iter().all(|r| r.counts.messages > 0), "{name}: beams crossed links");
            let even = [1, 2, 3, 5, 24].map(|of| Tile::even_cuts(of, n).unwrap());
            for cuts in even.iter().map(Vec::as_slice).chain([&[1][..], &[23], &[1, 2, 20]]) {
                let tiled = diffuse_in_tiles(&scene.grid, &sources, &cfg, cuts).unwrap();
                assert_same(&whole, &tiled, &format!("{name}, tiles cut at {cuts:?}"));
            }
        }
    }

    /// A part travels as bytes: decoded, it is the same part (its link faults, its band's
    /// pixel weights); tiles' parts that do not fit together are refused.
    #[test]
    fn tile_parts_travel_and_mismatches_are_refused() {
        let n = 16;
        let mesh = crate::scene::load("cornell").unwrap();
        let scene = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
        let lights = resolve_lights(&mesh, &scene, &[[0.5, 0.9, 0.5]]).unwrap();
        let tiled = |cfg: &LightConfig| -> Vec<Lighting> {
            let sources = [cfg.source(0, lights[0], n).unwrap()];
            let (grid, srcs) = (&scene.grid, &sources[..]);
            std::thread::scope(|s| {
                let runs: Vec<_> = ThreadHalo::tiles(Tile::bands(n, &[7]).unwrap())
                    .into_iter()
                    .map(|mut h| s.spawn(move || diffuse_tile(grid, srcs, cfg, &mut h, &mut |_, _| {}).unwrap()))
                    .collect();
                runs.into_iter().map(|r| r.join().unwrap()).collect()
            })
        };
        let ratio = LightConfig { visibility: Visibility::Ratio, ..Preset::Render.light() };
        let parts = tiled(&ratio);
        assert_eq!(
            parts.iter().map(|p| p.weights.as_ref().map(|w| w[0].len())).collect::<Vec<_>>(),
            [Some(7 * 16), Some(9 * 16)]
        );
        let carried: Vec<Lighting> = parts.iter().map(|p| decode_part(&encode_part(p).unwrap()).unwrap()).collect();
        let whole = diffuse(&scene.grid, &[ratio.source(0, lights[0], n).unwrap()], &ratio, |_, _| {}).unwrap();
        assert_same(&whole, &merge_tiles(carried).unwrap(), "carried parts, counted rays");
        let cfg = LightConfig { faults: Some("drop=0.05,seed=3".parse().unwrap()), ..Preset::Render.light() };
        let sources = [cfg.source(0, lights[0], n).unwrap()];
        let parts = tiled(&cfg);
        let carried: Vec<Lighting> = parts.iter().map(|p| decode_part(&encode_part(p).unwrap()).unwrap()).collect();
        assert!(carried[0].link_faults.is_some());
        let whole = diffuse(&scene.grid, &sources, &cfg, |_, _| {}).unwrap();
        assert_same(&whole, &merge_tiles(carried).unwrap(), "carried parts");
        let mut swapped: Vec<Lighting> = parts.iter().map(|p| decode_part(&encode_part(p).unwrap()).unwrap()).collect();
        swapped.reverse();
        assert!(merge_tiles(swapped).err().expect("refused").to_string().contains("whole rows"));
        let one: Vec<Lighting> = parts.iter().take(1).map(|p| decode_part(&encode_part(p).unwrap()).unwrap()).collect();
        assert!(merge_tiles(one).is_err(), "half a grid");
        assert!(merge_tiles(Vec::new()).is_err());
    }

    /// A run cut into bands that are not the grid's, or one that records visits, is refused; a stall is reported by every tile (the same error), never a hang.
    #[test]
    fn tiled_runs_refuse_what_they_cannot_do_and_stop_together() {
        let n = 8;
        let mesh = crate::scene::load("cornell").unwrap();
        let scene = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
        let cfg = plane_rule();
        let sources = [cfg.source(0, [3.0, 6.0, 3.0], n).unwrap()];
        let cut =
            |cuts: &[u32], c: &LightConfig| diffuse_in_tiles(&scene.grid, &sources, c, cuts).err().expect("refused");
        assert!(cut(&[4, 9], &cfg).to_string().contains("within"));
        assert!(cut(&[4], &LightConfig { record_visits: true, ..cfg }).to_string().contains("visited"));
        // Every link dead: nothing moves, and every tile stops with the stall report.
        let dead = LightConfig { faults: Some("drop=1".parse().unwrap()), stall_cycles: 5, ..cfg };
        let err = cut(&[2, 4, 6], &dead).to_string();
        assert!(err.contains("stall at cycle"), "{err}");
    }
}

//! A lighting run split by sources ([`Share`]): each share diffuses its sources on its own copy
//! of the grid, and the parts come back together as the whole run's [`Lighting`]
//! ([`merge_parts`]), identical to the run of every source in one go. Sources run one after
//! another on a quiescent grid, so what one source leaves to the next is only what adds up:
//! lit marks (an OR of source bits per voxel), the cells' counters (sums, and the per-source
//! peaks the last source leaves) and the reports.
//!
//! [`encode_part`] and [`decode_part`] carry a part as bytes between processes (the MPI
//! layer, `crate::dist`, moves them; nothing here knows how).

use anyhow::{anyhow, bail, Context, Result};
use cell_core::light::{LightCounters, LitRun, LitRuns, SourceMask};
use cell_core::lit::LitRule;
use cell_core::units::Depth;

use crate::machine::links::faults::FaultCounts;

use super::{DiffusionCounts, LightConfig, Lighting, LitColumn, PhaseSeconds, SourceReport};
use crate::machine::grid::capacity::LIT_CAP;

/// One share of a run's sources: source `s` is diffused by share `s % of`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Share {
    /// This share's index, 0 .. `of`.
    pub index: usize,
    /// How many shares the sources are split into (at least 1).
    pub of: usize,
}

impl Share {
    /// Every source.
    pub const ALL: Share = Share { index: 0, of: 1 };

    /// Whether source `s` is this share's.
    pub fn takes(&self, s: usize) -> bool {
        s % self.of.max(1) == self.index
    }

    /// Whether a run under `cfg` can be split by sources with the same result: not when its
    /// sources share more than the lit stores and counters — faulty links (each injector's
    /// random state runs on from source to source), a snapshot (`stop_at`: beams still in
    /// flight when the next source starts), the visited voxels or a cell trace (`tapped`). A
    /// run that counts rays spreads: each source's pixel weights come from the share that
    /// diffused it.
    pub fn spreads(cfg: &LightConfig, tapped: bool) -> bool {
        cfg.faults.is_none() && cfg.stop_at.is_none() && !cfg.record_visits && !tapped
    }
}

/// The lit runs of a column as sorted (voxel, mask) pairs, one per lit voxel.
fn lit_voxels(runs: &[LitRun], out: &mut Vec<(Depth, SourceMask)>) {
    for r in runs {
        out.extend((r.lo..=r.hi).map(|z| (z, r.mask)));
    }
}

/// A lit store holding `voxels` (sorted by depth, masks of equal depths OR-ed), marked in depth
/// order: each mark extends the last run or appends one, so the store never holds more runs
/// than its final state (the canonical runs of these masks: the same as any order of marks
/// that fits). Returns the store and the marks that did not fit.
fn lit_store(voxels: &mut [(Depth, SourceMask)]) -> (LitRuns<LIT_CAP>, u32) {
    voxels.sort_unstable_by_key(|v| v.0);
    let mut lit = LitRuns::new();
    let mut lost = 0;
    let mut i = 0;
    while i < voxels.len() {
        let z = voxels[i].0;
        let mut mask = 0;
        while i < voxels.len() && voxels[i].0 == z {
            mask |= voxels[i].1;
            i += 1;
        }
        if !lit.mark(z, mask) {
            lost += 1;
        }
    }
    (lit, lost)
}

/// The run of every source from the parts of its shares (each part from [`super::diffuse_share`]
/// on the same grid, sources and configuration; in any order, each source in one part only):
/// lit stores united, counters added, the reports in source order. The cells' per-source peaks
/// (`peak_fifo`, `max_layer`) and queued beams are those of the part that ran the last source,
/// as in one run; each source's pixel weights (a run that counts rays) those of its part.
pub fn merge_parts(parts: Vec<Lighting>) -> Result<Lighting> {
    let Some(first) = parts.first() else { bail!("no lighting part to merge") };
    let (n, rule, len) = (first.n, first.rule, first.cells.len());
    if let Some(p) = parts.iter().find(|p| p.n != n || p.rule != rule || p.cells.len() != len) {
        bail!(
            "lighting parts of different runs: n {} and {}, rule {:?} and {:?}, {} and {} cells",
            n,
            p.n,
            rule,
            p.rule,
            len,
            p.cells.len()
        );
    }
    if parts.iter().any(|p| p.visited.is_some() || p.link_faults.is_some()) {
        bail!("a lighting run with visited voxels or faulty links is not split by sources");
    }
    let mut reports: Vec<SourceReport> = parts.iter().flat_map(|p| p.reports.iter().cloned()).collect();
    reports.sort_by_key(|r| r.source);
    if reports.windows(2).any(|w| w[0].source == w[1].source) {
        bail!("a source was diffused in two lighting parts");
    }
    // The part whose last source is the run's last: its cells keep that source's peaks.
    let last = parts
        .iter()
        .enumerate()
        .filter_map(|(i, p)| p.reports.iter().map(|r| r.source).max().map(|s| (s, i)))
        .max()
        .map_or(0, |(_, i)| i);
    let mut phases = PhaseSeconds::default();
    for p in &parts {
        phases = add_phases(&phases, &p.phases);
    }
    let weights = merge_weights(&parts, &reports)?;
    let mut voxels = Vec::new();
    let cells = (0..len)
        .map(|i| {
            let mut counters = LightCounters::default();
            let mut visible_lit = 0;
            voxels.clear();
            for p in &parts {
                let c = &p.cells[i];
                lit_voxels(c.lit.runs(), &mut voxels);
                visible_lit |= c.visible_lit;
                counters = add_counters(&counters, &c.counters);
            }
            let (lit, lost) = lit_store(&mut voxels);
            let at = &parts[last].cells[i];
            counters.peak_fifo = at.counters.peak_fifo;
            counters.max_layer = at.counters.max_layer;
            counters.lit_overflows += lost;
            LitColumn { x: at.x, y: at.y, lit, visible_lit, counters, queued: at.queued }
        })
        .collect();
    Ok(Lighting { n, cells, reports, visited: None, link_faults: None, rule, phases, weights })
}

/// Each source's pixel weights from the one part that diffused it (a part holds a weight
/// vector for each of the run's sources, empty for those of other shares); `None` when no
/// part counted rays.
fn merge_weights(parts: &[Lighting], reports: &[SourceReport]) -> Result<Option<Vec<Vec<u8>>>> {
    if parts.iter().all(|p| p.weights.is_none()) {
        return Ok(None);
    }
    let Some(lists) = parts.iter().map(|p| p.weights.as_ref()).collect::<Option<Vec<_>>>() else {
        bail!("some lighting parts carry pixel weights and some do not");
    };
    let sources = lists.iter().map(|w| w.len()).max().unwrap_or(0);
    let mut out = vec![Vec::new(); sources];
    for (s, slot) in out.iter_mut().enumerate() {
        let mut given = lists.iter().filter_map(|w| w.get(s)).filter(|w| !w.is_empty());
        if let Some(w) = given.next() {
            *slot = w.clone();
        }
        if given.next().is_some() {
            bail!("source {s}'s pixel weights come from two lighting parts");
        }
        if slot.is_empty() && reports.iter().any(|r| r.source == s) {
            bail!("source {s} was diffused but no lighting part carries its pixel weights");
        }
    }
    Ok(Some(out))
}

/// Two cells' counters added (the peaks: the larger; [`merge_parts`] sets them).
fn add_counters(a: &LightCounters, b: &LightCounters) -> LightCounters {
    let LightCounters {
        processed,
        blocked_cycles,
        peak_fifo,
        max_layer,
        rays_absorbed,
        rays_exited,
        rays_skipped,
        sent,
        lit_overflows,
        merged,
        held_cycles,
        per_ray_visits,
    } = *b;
    LightCounters {
        processed: a.processed + processed,
        blocked_cycles: a.blocked_cycles + blocked_cycles,
        peak_fifo: a.peak_fifo.max(peak_fifo),
        max_layer: a.max_layer.max(max_layer),
        rays_absorbed: a.rays_absorbed + rays_absorbed,
        rays_exited: a.rays_exited + rays_exited,
        rays_skipped: a.rays_skipped + rays_skipped,
        sent: a.sent + sent,
        lit_overflows: a.lit_overflows + lit_overflows,
        merged: a.merged + merged,
        held_cycles: a.held_cycles + held_cycles,
        per_ray_visits: a.per_ray_visits + per_ray_visits,
    }
}

/// Host seconds of two parts, phase by phase.
pub(super) fn add_phases(a: &PhaseSeconds, b: &PhaseSeconds) -> PhaseSeconds {
    let PhaseSeconds { setup, emit, step, gather, links, pop, next, tally } = *b;
    PhaseSeconds {
        setup: a.setup + setup,
        emit: a.emit + emit,
        step: a.step + step,
        gather: a.gather + gather,
        links: a.links + links,
        pop: a.pop + pop,
        next: a.next + next,
        tally: a.tally + tally,
    }
}

/// The first bytes of an encoded part, with its format's version.
const MAGIC: &[u8; 8] = b"rc2part3";

/// A part as bytes for another process ([`decode_part`] reads them back): the lit stores,
/// visible masks, counters and queued beams of its cells (every cell, or a tile's), the
/// reports, what its faulty links did, the host seconds and the pixel weights of a run that
/// counts rays. Fails for a part with visited voxels (not carried).
pub fn encode_part(l: &Lighting) -> Result<Vec<u8>> {
    if l.visited.is_some() {
        bail!("a lighting part with visited voxels is not carried between processes");
    }
    let mut w = Writer(Vec::with_capacity(64 + l.cells.len() * 96));
    w.0.extend_from_slice(MAGIC);
    w.u32(l.n);
    w.u8(l.rule.code());
    w.u64(l.cells.len() as u64);
    for c in &l.cells {
        w.u16(c.x);
        w.u16(c.y);
        w.u32(c.visible_lit);
        w.u64(c.queued as u64);
        counters_to(&mut w, &c.counters);
        let runs = c.lit.runs();
        w.u32(runs.len() as u32);
        for r in runs {
            w.u16(r.lo);
            w.u16(r.hi);
            w.u32(r.mask);
        }
    }
    w.u64(l.reports.len() as u64);
    for r in &l.reports {
        report_to(&mut w, r);
    }
    for (_, s) in l.phases.named() {
        w.f64(s);
    }
    w.u8(u8::from(l.link_faults.is_some()));
    if let Some(f) = &l.link_faults {
        for v in fault_fields(f) {
            w.u64(v);
        }
    }
    w.u8(u8::from(l.weights.is_some()));
    if let Some(ws) = &l.weights {
        w.u64(ws.len() as u64);
        for s in ws {
            w.u64(s.len() as u64);
            w.0.extend_from_slice(s);
        }
    }
    Ok(w.0)
}

/// The fields of a fault count, in a fixed order.
fn fault_fields(f: &FaultCounts) -> [u64; 9] {
    [
        f.data_frames,
        f.retransmissions,
        f.data_corrupted,
        f.data_dropped,
        f.data_delayed,
        f.delay_cycles,
        f.acks_lost,
        f.crc_rejected,
        f.duplicates,
    ]
}

/// The part [`encode_part`] wrote, or an error naming what is wrong with the bytes.
pub fn decode_part(bytes: &[u8]) -> Result<Lighting> {
    let mut r = Reader { b: bytes, at: 0 };
    if r.take(MAGIC.len())? != MAGIC {
        bail!("not an encoded lighting part (or one of another version)");
    }
    let n = r.u32()?;
    let code = r.u8()?;
    let rule = LitRule::from_code(code)
        .ok_or_else(|| anyhow!("a lighting part names lit rule {code}, which does not exist"))?;
    let len = r.len(16)?;
    let mut cells = Vec::with_capacity(len);
    let mut voxels = Vec::new();
    for _ in 0..len {
        let (x, y, visible_lit, queued) = (r.u16()?, r.u16()?, r.u32()?, r.u64()? as usize);
        let counters = counters_from(&mut r)?;
        let runs = r.u32()? as usize;
        voxels.clear();
        let mut list = Vec::with_capacity(runs.min(LIT_CAP));
        for _ in 0..runs {
            let run = LitRun { lo: r.u16()?, hi: r.u16()?, mask: r.u32()? };
            if run.lo > run.hi || run.mask == 0 {
                bail!("a lighting part's lit run {run:?} of cell ({x}, {y}) is malformed");
            }
            list.push(run);
        }
        lit_voxels(&list, &mut voxels);
        let (lit, lost) = lit_store(&mut voxels);
        if lost > 0 || lit.runs() != &list[..] {
            bail!("a lighting part's lit runs of cell ({x}, {y}) are not a lit store's");
        }
        cells.push(LitColumn { x, y, lit, visible_lit, counters, queued });
    }
    let count = r.len(8)?;
    let reports = (0..count).map(|_| report_from(&mut r)).collect::<Result<Vec<_>>>()?;
    let mut s = [0.0; 8];
    for v in &mut s {
        *v = r.f64()?;
    }
    let [setup, emit, step, gather, links, pop, next, tally] = s;
    let phases = PhaseSeconds { setup, emit, step, gather, links, pop, next, tally };
    let link_faults = match r.u8()? {
        0 => None,
        1 => {
            let mut v = [0u64; 9];
            for x in &mut v {
                *x = r.u64()?;
            }
            let [data_frames, retransmissions, data_corrupted, data_dropped, data_delayed, delay_cycles, acks_lost, crc_rejected, duplicates] =
                v;
            Some(FaultCounts {
                data_frames,
                retransmissions,
                data_corrupted,
                data_dropped,
                data_delayed,
                delay_cycles,
                acks_lost,
                crc_rejected,
                duplicates,
            })
        }
        k => bail!("a lighting part's fault flag is {k}, not 0 or 1"),
    };
    let weights = match r.u8()? {
        0 => None,
        1 => {
            let sources = r.len(8)?;
            let mut ws = Vec::with_capacity(sources);
            for _ in 0..sources {
                let len = r.len(1)?;
                ws.push(r.take(len)?.to_vec());
            }
            Some(ws)
        }
        k => bail!("a lighting part's weights flag is {k}, not 0 or 1"),
    };
    if r.at != bytes.len() {
        bail!("{} bytes left over after a lighting part", bytes.len() - r.at);
    }
    Ok(Lighting { n, cells, reports, visited: None, link_faults, rule, phases, weights })
}

fn counters_to(w: &mut Writer, c: &LightCounters) {
    let LightCounters {
        processed,
        blocked_cycles,
        peak_fifo,
        max_layer,
        rays_absorbed,
        rays_exited,
        rays_skipped,
        sent,
        lit_overflows,
        merged,
        held_cycles,
        per_ray_visits,
    } = *c;
    for v in [processed, blocked_cycles, rays_absorbed, rays_exited, rays_skipped, sent, merged, held_cycles] {
        w.u64(v);
    }
    w.u16(peak_fifo);
    for v in [max_layer, lit_overflows, per_ray_visits] {
        w.u32(v);
    }
}

fn counters_from(r: &mut Reader) -> Result<LightCounters> {
    let [processed, blocked_cycles, rays_absorbed, rays_exited, rays_skipped, sent, merged, held_cycles] =
        [r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?];
    let peak_fifo = r.u16()?;
    let [max_layer, lit_overflows, per_ray_visits] = [r.u32()?, r.u32()?, r.u32()?];
    Ok(LightCounters {
        processed,
        blocked_cycles,
        peak_fifo,
        max_layer,
        rays_absorbed,
        rays_exited,
        rays_skipped,
        sent,
        lit_overflows,
        merged,
        held_cycles,
        per_ray_visits,
    })
}

pub(super) fn report_to(w: &mut Writer, s: &SourceReport) {
    let SourceReport { source, position, busiest_cell, counts } = s;
    let DiffusionCounts {
        cycles,
        lower_bound,
        lb_distance,
        lb_cell_load,
        beams_processed,
        beams_merged,
        messages,
        rays_emitted,
        rays_absorbed,
        rays_exited,
        rays_skipped,
        peak_fifo,
        blocked_cell_cycles,
        held_cell_cycles,
        peak_active_cells,
        peak_link_load,
        peak_link_distance,
        per_ray_visits,
    } = *counts;
    w.u64(*source as u64);
    for p in position {
        w.f64(*p);
    }
    for c in busiest_cell {
        w.u32(*c);
    }
    for v in [
        cycles,
        lower_bound,
        lb_distance,
        lb_cell_load,
        beams_processed,
        beams_merged,
        messages,
        blocked_cell_cycles,
        held_cell_cycles,
        peak_active_cells,
        peak_link_load,
        per_ray_visits,
    ] {
        w.u64(v);
    }
    for v in [rays_emitted, rays_absorbed, rays_exited, rays_skipped] {
        w.u128(v);
    }
    w.u16(peak_fifo);
    w.u32(peak_link_distance);
}

pub(super) fn report_from(r: &mut Reader) -> Result<SourceReport> {
    let source = r.u64()? as usize;
    let position = [r.f64()?, r.f64()?, r.f64()?];
    let busiest_cell = [r.u32()?, r.u32()?];
    let mut v = [0u64; 12];
    for x in &mut v {
        *x = r.u64()?;
    }
    let [cycles, lower_bound, lb_distance, lb_cell_load, beams_processed, beams_merged, messages, blocked_cell_cycles, held_cell_cycles, peak_active_cells, peak_link_load, per_ray_visits] =
        v;
    let [rays_emitted, rays_absorbed, rays_exited, rays_skipped] = [r.u128()?, r.u128()?, r.u128()?, r.u128()?];
    let peak_fifo = r.u16()?;
    let peak_link_distance = r.u32()?;
    let counts = DiffusionCounts {
        cycles,
        lower_bound,
        lb_distance,
        lb_cell_load,
        beams_processed,
        beams_merged,
        messages,
        rays_emitted,
        rays_absorbed,
        rays_exited,
        rays_skipped,
        peak_fifo,
        blocked_cell_cycles,
        held_cell_cycles,
        peak_active_cells,
        peak_link_load,
        peak_link_distance,
        per_ray_visits,
    };
    Ok(SourceReport { source, position, busiest_cell, counts })
}

/// A diffusion's counters as bytes for another process ([`counts_from_bytes`] reads them).
pub fn counts_to_bytes(c: &DiffusionCounts) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    report_to(&mut w, &SourceReport { counts: c.clone(), ..Default::default() });
    w.0
}

/// The counters [`counts_to_bytes`] wrote, and the bytes after them.
pub fn counts_from_bytes(b: &[u8]) -> Result<(DiffusionCounts, &[u8])> {
    let mut r = Reader::new(b);
    let counts = report_from(&mut r)?.counts;
    Ok((counts, &b[r.at..]))
}

/// Little-endian writer.
pub(super) struct Writer(pub(super) Vec<u8>);

impl cell_core::bytes::ByteSink for Writer {
    fn put(&mut self, bytes: &[u8]) -> Result<(), cell_core::bytes::EncodeError> {
        self.0.extend_from_slice(bytes);
        Ok(())
    }
}

impl Writer {
    pub(super) fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    pub(super) fn u16(&mut self, v: u16) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub(super) fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub(super) fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub(super) fn u128(&mut self, v: u128) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub(super) fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
}

/// Little-endian reader that fails on truncated input.
pub(super) struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub(super) fn new(b: &'a [u8]) -> Self {
        Reader { b, at: 0 }
    }
    /// Bytes not read yet.
    pub(super) fn left(&self) -> usize {
        self.b.len() - self.at
    }
    pub(super) fn take(&mut self, k: usize) -> Result<&'a [u8]> {
        let end = self.at.checked_add(k).filter(|&e| e <= self.b.len());
        let end = end.with_context(|| format!("a lighting part is truncated at byte {}", self.at))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const K: usize>(&mut self) -> Result<[u8; K]> {
        let mut a = [0; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }
    pub(super) fn u8(&mut self) -> Result<u8> {
        Ok(self.array::<1>()?[0])
    }
    pub(super) fn u16(&mut self) -> Result<u16> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    pub(super) fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    pub(super) fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    fn u128(&mut self) -> Result<u128> {
        Ok(u128::from_le_bytes(self.array()?))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_bits(self.u64()?))
    }
    /// A count of items at least `min_bytes` long each, checked against the bytes left.
    fn len(&mut self, min_bytes: usize) -> Result<usize> {
        let k = self.u64()?;
        let left = (self.b.len() - self.at) / min_bytes.max(1);
        if k > left as u64 {
            bail!("a lighting part announces {k} items where at most {left} fit");
        }
        Ok(k as usize)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::config::{plane_rule, Preset};
    use crate::machine::lighting::diffuse::{diffuse, diffuse_share};
    use crate::machine::loading::loaded_scene::{load_scene, resolve_lights};
    use crate::precompute::LoadConfig;
    use cell_core::visibility::Visibility;

    /// Two runs' lit stores, visible masks, counters, reports, link faults and pixel weights,
    /// cell by cell.
    pub(in crate::machine::lighting::diffuse) fn assert_same(a: &Lighting, b: &Lighting, what: &str) {
        assert_eq!(a.reports, b.reports, "{what}: reports");
        assert_eq!(a.link_faults, b.link_faults, "{what}: link faults");
        assert_eq!(a.weights, b.weights, "{what}: pixel weights");
        assert_eq!(a.cells.len(), b.cells.len());
        for (x, y) in a.cells.iter().zip(&b.cells) {
            assert_eq!((x.x, x.y), (y.x, y.y), "{what}");
            assert_eq!(x.lit.runs(), y.lit.runs(), "{what}: lit runs of ({}, {})", x.x, x.y);
            assert_eq!(x.visible_lit, y.visible_lit, "{what}: visible mask of ({}, {})", x.x, x.y);
            assert_eq!(x.counters, y.counters, "{what}: counters of ({}, {})", x.x, x.y);
            assert_eq!(x.queued, y.queued, "{what}");
        }
    }

    /// Cornell lit by five sources: the run of every source in one go and the parts of 2, 3
    /// and 5 shares (encoded, decoded, merged in reverse order) agree cell by cell, under each
    /// lit rule and preset, the sibling wait and the lit-ray ratio's counted rays included.
    #[test]
    fn shares_merge_into_the_whole_run() {
        let n = 24;
        let mesh = crate::scene::load("cornell").unwrap();
        let scene = load_scene(&mesh, &LoadConfig::watertight(n)).unwrap();
        let cli = [[0.5, 0.9, 0.5], [0.2, 0.5, 0.3], [0.8, 0.3, 0.7], [0.5, 0.5, 0.5], [0.3, 0.8, 0.8]];
        let lights = resolve_lights(&mesh, &scene, &cli).unwrap();
        let configs = [
            ("plane", plane_rule()),
            ("render", Preset::Render.light()),
            ("light", Preset::Light.light()),
            ("thesis", Preset::Thesis.light()),
            ("hold", LightConfig { hold: 3, ..plane_rule() }),
            ("ratio", LightConfig { visibility: Visibility::Ratio, ..Preset::Render.light() }),
        ];
        for (name, cfg) in configs {
            let sources: Vec<_> = lights.iter().enumerate().map(|(i, p)| cfg.source(i, *p, n).unwrap()).collect();
            let whole = diffuse(&scene.grid, &sources, &cfg, |_, _| {}).unwrap();
            assert!(whole.lit_voxels().count() > 0 || cfg.lit_visible_only, "{name}: something is lit");
            if let Some(w) = &whole.weights {
                let (full, part) = (w.iter().flatten().any(|&x| x == 255), w.iter().flatten().any(|&x| x % 255 != 0));
                assert!(full && part, "{name}: some pixels fully and some partly lit");
            }
            for of in [2, 3, 5] {
                let mut parts: Vec<Lighting> = (0..of)
                    .map(|index| {
                        let part = diffuse_share(&scene.grid, &sources, &cfg, Share { index, of }, &mut |_, _| {});
                        decode_part(&encode_part(&part.unwrap()).unwrap()).unwrap()
                    })
                    .collect();
                parts.reverse();
                let merged = merge_parts(parts).unwrap();
                assert_same(&whole, &merged, &format!("{name}, {of} shares"));
            }
        }
    }

    /// Runs whose sources share more than the lit stores are not split; bytes that are not a
    /// part are refused with an error, never a panic.
    #[test]
    fn what_cannot_be_split_or_decoded_is_refused() {
        let cfg = plane_rule();
        assert!(Share::spreads(&cfg, false));
        assert!(!Share::spreads(&cfg, true));
        assert!(!Share::spreads(&LightConfig { stop_at: Some(3), ..cfg }, false));
        assert!(!Share::spreads(&LightConfig { record_visits: true, ..cfg }, false));
        let mesh = crate::scene::load("cornell").unwrap();
        let scene = load_scene(&mesh, &LoadConfig::watertight(8)).unwrap();
        let src = [cfg.source(0, [3.0, 6.0, 3.0], 8).unwrap()];
        let snap = LightConfig { stop_at: Some(3), ..cfg };
        let err = diffuse_share(&scene.grid, &src, &snap, Share { index: 0, of: 2 }, &mut |_, _| {});
        assert!(err.err().expect("refused").to_string().contains("cannot be split"));
        let part = diffuse_share(&scene.grid, &src, &cfg, Share { index: 1, of: 2 }, &mut |_, _| {}).unwrap();
        assert!(part.reports.is_empty(), "source 0 is share 0's");
        let bytes = encode_part(&part).unwrap();
        for cut in [0, 5, 9, bytes.len() / 2, bytes.len() - 1] {
            assert!(decode_part(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(decode_part(&longer).err().expect("refused").to_string().contains("left over"));
        assert!(merge_parts(Vec::new()).is_err());
    }
}

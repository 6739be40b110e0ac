//! The trace tap: records, for chosen cells of a grid run, every message they receive, every
//! compute cycle and every message a neighbour takes from them (`cell_core::trace` records), as the
//! schedulers run: loading, beam diffusion, and the ray phases (the classic shadow rays of
//! [`crate::machine::rays::classic`] and the reflections of [`crate::machine::rays::mirror`], with the answers their routers
//! take and deliver). The `trace` job writes what it recorded; the firmware replays it.
//!
//! The link events come from [`Tracer`], a wrapper around any grid link (`cell_core::link::Link`):
//! it notes every beam its far end took in the link step's journal ([`Journal`]), and the
//! scheduler hands the journal to [`Tap::took`] in link order.

use std::collections::HashMap;

use anyhow::{bail, Result};
use cell_core::beam::{frac::U0, FracBits};
use cell_core::cell::DEFAULT_DEXELS;
use cell_core::facet::RowPacket;
use cell_core::light::{BeamMsg, FrustumSummary, LightEnv, Port, Step};
use cell_core::link::{Link, Sent};
use cell_core::occluder::Triangle;
use cell_core::reflect::Answer;
use cell_core::reflect_cell::{ReflectAnswer, ReflectCell};
use cell_core::shadow::{ShadowAnswer, ShadowCell, ShadowStep};
use cell_core::trace::{write_event, Digester, Event, Header, LightSetup, Replayer, ShadeSetup, ShadowSetup};
use cell_core::wire::{Message, RayMsg, MAX_RAY_FRAME};

use super::faults::{FaultCounts, FaultTally};
use super::{Journal, LinkId, Took, BACK};
use crate::machine::grid::capacity::{FA_CAP, LIT_CAP, OB_CAP};

/// Records one cell.
pub struct CellRecorder {
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
    bytes: Vec<u8>,
    digest: Digester,
    steps: u32,
    records: u64,
}

impl CellRecorder {
    /// The record bytes so far, the records written, and the digest of the cell's outputs so far
    /// (the job adds its final state with [`Digester::state`] before finishing it).
    pub fn into_parts(self) -> (Vec<u8>, u64, Digester) {
        (self.bytes, self.records, self.digest)
    }

    fn new(x: u32, y: u32) -> Self {
        CellRecorder { x, y, bytes: Vec::new(), digest: Digester::new(), steps: 0, records: 0 }
    }

    /// Append one record (the job adds the shading setup and the end record).
    pub fn push<F: FracBits>(&mut self, ev: &Event<'_, F>) {
        if !matches!(ev, Event::Step(_)) {
            self.flush_steps::<F>();
        }
        let mut buf = [0u8; 2048];
        // Cannot fail: the largest record (shading with 8 lights and 16 materials) is < 1 KiB.
        let len = write_event(ev, &mut buf).expect("trace record fits its buffer");
        self.bytes.extend_from_slice(&buf[..len]);
        self.records += 1;
    }

    fn flush_steps<F: FracBits>(&mut self) {
        if self.steps > 0 {
            let n = std::mem::take(&mut self.steps);
            self.push::<F>(&Event::Step(n));
        }
    }

    /// A row packet arrives (before the cell processes it).
    pub fn row(&mut self, p: &RowPacket) {
        self.push::<U0>(&Event::Row(p.clone()));
    }

    /// The cell forwarded the (stepped) packet east.
    pub fn forwarded(&mut self, p: &RowPacket) {
        self.digest.forwarded(p);
    }

    /// The source emitter hands the cell a beam.
    pub fn inject<F: FracBits>(&mut self, m: &BeamMsg<F>) {
        self.push(&Event::Inject(*m));
    }

    /// One compute cycle and its result.
    pub fn step(&mut self, r: Step) {
        self.steps += 1;
        self.digest.step(r);
    }

    fn frame<F: FracBits>(m: &BeamMsg<F>) -> ([u8; cell_core::trace::BEAM_FRAME], usize) {
        let mut buf = [0u8; cell_core::trace::BEAM_FRAME];
        // Cannot fail: a beam frame has a fixed size.
        let len = Message::Beam(*m).emit(0, &mut buf).expect("beam frame fits");
        (buf, len)
    }

    fn recv<F: FracBits>(&mut self, port: Port, m: &BeamMsg<F>) {
        let (buf, len) = Self::frame(m);
        self.push::<F>(&Event::Recv { port, frame: &buf[..len] });
    }

    fn grant<F: FracBits>(&mut self, port: Port, m: &BeamMsg<F>) {
        self.push::<F>(&Event::Grant(port));
        self.digest.sent_beam(port, m);
    }

    /// One cycle of a ray phase's cell: a `Refused` record when its router refused the answer
    /// it offered (`offered`: whether the router took it), else one more `Step`.
    fn ray_cycle(&mut self, offered: Option<bool>) {
        if offered == Some(false) {
            self.push::<U0>(&Event::Refused);
        } else {
            self.steps += 1;
        }
    }

    /// One cycle of the shadow-ray cell: its step, the rays it launched after it, and the
    /// answer it offered its router, if any, with whether the router took it.
    pub fn shadow_cycle(&mut self, step: ShadowStep, launched: u32, offered: Option<(ShadowAnswer, bool)>) {
        if let Some((a, true)) = &offered {
            self.digest.shadow_answer(a);
        }
        self.ray_cycle(offered.map(|(_, took)| took));
        self.digest.shadow_cycle(step, launched);
    }

    /// One cycle of the reflection cell: its moves, and the answer it offered its router, if
    /// any, with whether the router took it.
    pub fn reflect_cycle(&mut self, moved: u32, offered: Option<(ReflectAnswer, bool)>) {
        if let Some((a, true)) = &offered {
            self.digest.reflect_answer(a);
        }
        self.ray_cycle(offered.map(|(_, took)| took));
        self.digest.reflect_cycle(moved);
    }

    /// The router delivers a shadow-ray answer (its payload) to the cell.
    pub fn shadow_answer(&mut self, payload: u8) {
        self.push::<U0>(&Event::ShadowAnswer(payload));
    }

    /// The router delivers a reflection answer for wait-table slot `slot` to the cell.
    pub fn reflect_answer(&mut self, slot: u16, answer: Answer) {
        self.push::<U0>(&Event::ReflectAnswer { slot, answer });
    }

    /// The end of a source's shadow-ray phase: the record, and the cell's state in the digest.
    pub fn shadow_end<const FA: usize>(&mut self, cell: &ShadowCell<FA>) {
        self.push::<U0>(&Event::PhaseEnd);
        self.digest.shadow_state(cell);
    }

    /// The end of the reflection phase: the record, and the cell's state in the digest.
    pub fn reflect_end<const FA: usize, const W: usize, const S: usize>(&mut self, cell: &ReflectCell<FA, W, S>) {
        self.push::<U0>(&Event::PhaseEnd);
        self.digest.reflect_state(cell);
    }
}

/// The cells being recorded, by grid index.
pub struct Tap {
    recorders: Vec<CellRecorder>,
    by_index: HashMap<usize, usize>,
}

impl Tap {
    /// Watch cells `cells` of an n × n grid with `depth` voxels per column; writes each header.
    pub fn new<F: FracBits>(n: u32, depth: u32, cells: &[[u32; 2]]) -> Result<Self> {
        let mut t = Tap { recorders: Vec::new(), by_index: HashMap::new() };
        for &[x, y] in cells {
            if x >= n || y >= n {
                bail!("cell ({x}, {y}) is outside the {n} × {n} grid");
            }
            let idx = (y * n + x) as usize;
            if t.by_index.contains_key(&idx) {
                continue;
            }
            let mut r = CellRecorder::new(x, y);
            let h: Header = Replayer::<F, DEFAULT_DEXELS, FA_CAP, OB_CAP, LIT_CAP>::header(x as u16, y as u16, depth);
            r.push::<F>(&Event::Header(h));
            t.by_index.insert(idx, t.recorders.len());
            t.recorders.push(r);
        }
        Ok(t)
    }

    /// The recorders, in the order the cells were given.
    pub fn into_recorders(self) -> Vec<CellRecorder> {
        self.recorders
    }

    /// The recorder of cell `idx`, if watched.
    pub fn get(&mut self, idx: usize) -> Option<&mut CellRecorder> {
        let i = *self.by_index.get(&idx)?;
        self.recorders.get_mut(i)
    }

    /// A source's diffusion starts.
    pub fn light<F: FracBits>(&mut self, env: &LightEnv<'_, F>, frustum: Option<&FrustumSummary>) {
        let s = LightSetup {
            source: *env.source,
            n: env.n,
            depth: env.depth,
            far: env.far.get(),
            policy: env.policy,
            fa: env.fa as u16,
            merge: env.merge,
            source_bit: env.source_bit,
            skip: env.skip,
            hold: env.hold,
            frustum: frustum.copied(),
            rule: env.rule,
            lit_visible_only: env.lit_visible_only,
        };
        self.all::<F>(&Event::Light(s));
        // Exact occluders (the only rule given occluders): each cell's own triangles follow (its
        // target ray it computes itself), then its neighbours' contact answers.
        if let Some(occ) = env.occluders {
            self.triangles::<F>(|x, y| occ.triangles(x as u16, y as u16));
            // Then its neighbours' answers to its contact query, if it has a contact segment.
            for r in &mut self.recorders {
                if let Some(t) = occ.target(r.x as u16, r.y as u16).filter(|t| t.contact.is_some()) {
                    r.push::<F>(&Event::NeighbourContact(t.neighbour_shadow));
                }
            }
        }
    }

    /// After a setup record under exact occluders: each watched cell's own triangles,
    /// `column(x, y)`, in the column's order.
    fn triangles<'t, F: FracBits>(&mut self, column: impl Fn(u32, u32) -> &'t [Triangle]) {
        for r in &mut self.recorders {
            for t in column(r.x, r.y) {
                r.push::<F>(&Event::Triangle(*t));
            }
        }
    }

    /// A source's classic shadow-ray phase: its setup record, and under exact occluders each
    /// cell's own triangles after it.
    pub fn shadow_setup(&mut self, setup: ShadowSetup, triangles: &crate::machine::grid::triangles::ColumnTriangles) {
        let exact = setup.env.rule.needs_triangles();
        self.all::<U0>(&Event::Shadow(setup));
        if exact {
            self.triangles::<U0>(|x, y| triangles.column(x, y));
        }
    }

    /// Every recorder: `f(grid index, recorder)`.
    pub fn each(&mut self, mut f: impl FnMut(usize, &mut CellRecorder)) {
        for (&idx, &i) in &self.by_index {
            f(idx, &mut self.recorders[i]);
        }
    }

    /// A record for every watched cell (a phase's setup, the shading inputs).
    pub fn all<F: FracBits>(&mut self, ev: &Event<'_, F>) {
        for r in &mut self.recorders {
            r.push(ev);
        }
    }

    /// The shading inputs.
    pub fn shade(&mut self, s: &ShadeSetup) {
        self.all(&Event::<U0>::Shade(s.clone()));
    }

    /// A ray of class `class` left cell `from` through `port` into cell `to`: the sender's
    /// `Take`, the receiver's frame.
    pub fn ray_moved(&mut self, from: usize, port: Port, class: u8, ray: &RayMsg, to: usize) {
        if let Some(r) = self.get(from) {
            r.push::<U0>(&Event::Take { class, port });
            r.digest.sent_ray(port, ray);
        }
        if let Some(r) = self.get(to) {
            let mut buf = [0u8; MAX_RAY_FRAME];
            // Cannot fail: no ray frame is longer.
            let len = ray.emit(0, &mut buf).expect("ray frame fits");
            r.push::<U0>(&Event::Recv { port: Port::ALL[BACK[port.index()]], frame: &buf[..len] });
        }
    }

    /// A link's far end took a beam ([`Tracer`]): the sender's grant, the receiver's frame.
    pub fn took<F: FracBits>(&mut self, t: &Took<F>) {
        let LinkId { from, port, to } = t.link;
        if let Some(r) = self.get(from as usize) {
            r.grant(port, &t.msg);
        }
        if let Some(r) = self.get(to as usize) {
            r.recv(Port::ALL[BACK[port.index()]], &t.msg);
        }
    }
}

/// A link that records: every beam its far end took (the sender pops it) goes to the far end's
/// [`Journal`], after the wrapped link `L` answered.
pub struct Tracer<L> {
    inner: L,
    link: LinkId,
}

impl<L> Tracer<L> {
    /// Trace link `link`.
    pub fn new(inner: L, link: LinkId) -> Self {
        Tracer { inner, link }
    }
}

impl<F: FracBits, Rx: Journal<F> + ?Sized, L: Link<F, Rx>> Link<F, Rx> for Tracer<L> {
    type Error = L::Error;
    const LOSSLESS: bool = L::LOSSLESS;

    fn ready(&mut self, rx: &Rx) -> Result<bool, L::Error> {
        self.inner.ready(rx)
    }

    fn send(&mut self, now: u64, msg: &BeamMsg<F>, rx: &mut Rx) -> Result<Sent, L::Error> {
        let s = self.inner.send(now, msg, rx)?;
        if s.acked {
            rx.took(Took { link: self.link, msg: *msg });
        }
        Ok(s)
    }
}

impl<L: FaultTally> FaultTally for Tracer<L> {
    fn add_counts(&self, into: &mut Option<FaultCounts>) {
        self.inner.add_counts(into);
    }
}

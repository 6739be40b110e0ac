//! The ray phases in a cell trace: the classic shadow-ray phase (§4.1.2–4.1.3,
//! [`crate::shadow`]) and the reflection phase (§1.3.2, [`crate::reflect_cell`]).
//!
//! **What the records carry** (the format is in the [parent module](super)'s table). A phase
//! starts with its setup record ([`ShadowSetup`] for each source, [`ReflectSetup`] once):
//! its settings, the capacities it was recorded with, and the reflection's Kr table. Then,
//! in the order the host grid did them, the cell's inputs: compute cycles (`Step`, or
//! `Refused` for a cycle in which the cell's router did not take the answer the cell offered),
//! rays arriving from a link (`Recv` with a ray frame, [`crate::wire::RayMsg`]), a neighbour
//! taking the ray of an output slot (`Take`), and answers its router delivers
//! (`ShadowAnswer`, `ReflectAnswer`). The phase ends with `PhaseEnd` (for shadow rays, once per
//! source). The cell's **router** is outside the replayed cell: what crosses the boundary is
//! what the records carry (answers offered and taken or refused, answers delivered).
//!
//! **Invariant: the digest covers the phase's outputs and final state.** Each cycle's result
//! (the step and the rays launched, or the moves), each answer handed to the router, each ray
//! sent (its frame, as for beams) and, at `PhaseEnd`, the cell's phase state: counters, the
//! lit mask or the pixel and root answer, the open wait-table entries, what is left in its
//! FIFOs and queues. The host folds the same bytes from its own run ([`Digester`]'s methods
//! here are what both call), so a replay reaches the host's digest iff the cell did the same.
//!
//! ```
//! use cell_core::beam::frac::U0;
//! use cell_core::dexel::DexelStore;
//! use cell_core::light::Port;
//! use cell_core::lit::LitRule;
//! use cell_core::ray::{Connectivity, ShadowRay, Q};
//! use cell_core::shadow::ShadowEnv;
//! use cell_core::trace::{replay, write_event, Event, Replayer, ShadowSetup};
//! use cell_core::wire::RayMsg;
//!
//! // Cell (1, 0), an empty column: a shadow ray from voxel (0, 0, 2) toward a source at
//! // (5, 0, 2) comes in from the west, crosses the column and leaves east.
//! let env = ShadowEnv {
//!     source: [5 * Q, 0, 2 * Q],
//!     rule: LitRule::Thesis,
//!     connectivity: Connectivity::Six,
//!     all_voxels: false,
//!     bias: 0,
//!     fa: 4,
//! };
//! let mut ray = ShadowRay::new([0, 0, 2], env.source, Connectivity::Six, 7).unwrap();
//! let _ = ray.advance(&DexelStore::<4>::new()); // its emitter's step: now in column (1, 0)
//! let mut frame = [0u8; 128];
//! let len = RayMsg::Shadow(ray).emit(0, &mut frame).unwrap();
//!
//! let records = |take: bool| {
//!     let mut events = vec![
//!         Event::<U0>::Header(Replayer::<U0, 64, 64, 3, 64>::header(1, 0, 8)),
//!         Event::Shadow(ShadowSetup { env, source_bit: 1, fifo: 64 }),
//!         Event::Recv { port: Port::W, frame: &frame[..len] },
//!         Event::Step(1),
//!         Event::Take { class: 0, port: Port::E },
//!         Event::PhaseEnd,
//!         Event::End,
//!     ];
//!     if !take {
//!         events.remove(4);
//!     }
//!     let mut bytes = Vec::new();
//!     for ev in &events {
//!         let mut buf = [0u8; 256];
//!         let n = write_event(ev, &mut buf).unwrap();
//!         bytes.extend_from_slice(&buf[..n]);
//!     }
//!     bytes
//! };
//! let (digest, stats) = replay::<U0, 64, 64, 3, 64>(&records(true)).unwrap();
//! assert_eq!((stats.received, stats.steps, stats.sent), (1, 1, 1));
//! // Without the neighbour taking it, the ray is still in the east slot at the phase's end:
//! // another digest.
//! let (kept, _) = replay::<U0, 64, 64, 3, 64>(&records(false)).unwrap();
//! assert_ne!(digest, kept);
//! ```

use heapless::Vec;

use super::{port_of, Digester, Event, ReplayError, Replayer, MAX_MATERIALS};
use crate::beam::FracBits;
use crate::light::{Port, SourceMask};
use crate::lit::LitRule;
use crate::ray::{Connectivity, MAX_SPAN};
use crate::reflect::{Answer, HitPoint, ReflectNormal, MAX_GRID};
use crate::reflect_cell::{ReflectAnswer, ReflectCell, ReflectEnv, Surfaces};
use crate::shadow::{ShadowAnswer, ShadowCell, ShadowEnv, ShadowStep};
use crate::wire::{
    put_shadow_ray, read_frame, ByteSink, DecodeError, EncodeError, PutExt, RawFrame, RayMsg, Reader, SliceWriter,
    MAX_RAY_FRAME,
};

/// The classic shadow-ray phase of one source, as a cell receives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadowSetup {
    /// The phase's settings.
    pub env: ShadowEnv,
    /// The source's bit in the lit mask.
    pub source_bit: SourceMask,
    /// The ray FIFO capacity the trace was recorded with (a cell with another refuses it).
    pub fifo: u16,
}

/// The reflection phase, as a cell receives it. It shades with the materials, lights and
/// parameters of the trace's shading record, which comes first.
#[derive(Clone, Debug, PartialEq)]
pub struct ReflectSetup {
    /// The phase's settings.
    pub env: ReflectEnv,
    /// Kr by material id.
    pub kr: Vec<f32, MAX_MATERIALS>,
    /// Capacities the trace was recorded with: FIFO per class, wait table, send queue.
    pub caps: [u16; 3],
}

/// The ray phase a replay is in, with its cell: `SFA` shadow rays; `RFA` rays per class, `W`
/// wait entries and `S` answers for the reflection cell.
#[derive(Clone, Debug, Default)]
// One phase at a time: the cell's RAM is the larger of the two, not their sum.
#[allow(clippy::large_enum_variant)]
pub enum Rays<const SFA: usize, const RFA: usize, const W: usize, const S: usize> {
    /// No ray phase (loading and lighting).
    #[default]
    Idle,
    /// Classic shadow rays for one source.
    Shadow(ShadowCell<SFA>, ShadowSetup),
    /// The reflection phase.
    Reflect(ReflectCell<RFA, W, S>, ReflectSetup),
}

fn connectivity_code(c: Connectivity) -> u8 {
    c.k()
}

fn connectivity_of(k: u8) -> Result<Connectivity, DecodeError> {
    Connectivity::ALL.into_iter().find(|c| c.k() == k).ok_or(DecodeError::BadValue("ray connectivity"))
}

fn flag(r: &mut Reader<'_>, what: &'static str) -> Result<bool, DecodeError> {
    match r.u8()? {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(DecodeError::BadValue(what)),
    }
}

/// Write a shadow setup record's payload.
pub(super) fn put_shadow_setup(w: &mut SliceWriter<'_>, s: &ShadowSetup) -> Result<(), EncodeError> {
    let e = &s.env;
    e.source.iter().try_for_each(|&c| w.i32(c))?;
    w.u8(e.rule.code())?;
    w.u8(connectivity_code(e.connectivity))?;
    w.u8(e.all_voxels as u8)?;
    w.u8(e.bias)?;
    w.u16(e.fa as u16)?;
    w.u32(s.source_bit)?;
    w.u16(s.fifo)
}

/// The payload of a shadow setup record.
pub(super) fn get_shadow_setup(r: &mut Reader<'_>) -> Result<ShadowSetup, DecodeError> {
    let source = [r.i32()?, r.i32()?, r.i32()?];
    // Under exact occluders the column's triangles follow in their own records
    // ([`super::Event::Triangle`]).
    let rule = LitRule::from_code(r.u8()?).ok_or(DecodeError::BadValue("lit rule"))?;
    let connectivity = connectivity_of(r.u8()?)?;
    let all_voxels = flag(r, "emitters")?;
    let (bias, fa) = (r.u8()?, r.u16()? as usize);
    let env = ShadowEnv { source, rule, connectivity, all_voxels, bias, fa };
    Ok(ShadowSetup { env, source_bit: r.u32()?, fifo: r.u16()? })
}

/// Write a reflection setup record's payload.
pub(super) fn put_reflect_setup(w: &mut SliceWriter<'_>, s: &ReflectSetup) -> Result<(), EncodeError> {
    let e = &s.env;
    w.u8(e.depth)?;
    w.f32(e.threshold)?;
    // Bit 0: the face-flip normal; bits 1–2: the hit point rule (0, the centre, in older traces).
    w.u8(matches!(e.normal, ReflectNormal::Face) as u8 | e.hit.code() << 1)?;
    w.u8(e.skip_own_facet as u8)?;
    w.u8(connectivity_code(e.connectivity))?;
    w.u16(e.fa as u16)?;
    w.i32(e.span)?;
    w.u32(e.n)?;
    w.u32(e.grid_depth)?;
    s.caps.iter().try_for_each(|&c| w.u16(c))?;
    w.u8(s.kr.len() as u8)?;
    s.kr.iter().try_for_each(|&k| w.f32(k))
}

/// The payload of a reflection setup record. Refused ([`DecodeError::BadValue`]): a span
/// outside 1 ..= [`MAX_SPAN`] or a grid beyond [`MAX_GRID`] (the bit budget of the mirrored
/// directions, [`crate::reflect`]), a negative threshold or Kr (a float that is not finite is
/// refused by the reader).
pub(super) fn get_reflect_setup(r: &mut Reader<'_>) -> Result<ReflectSetup, DecodeError> {
    let (depth, threshold) = (r.u8()?, r.f32()?);
    let code = r.u8()?;
    let normal = if code & 1 != 0 { ReflectNormal::Face } else { ReflectNormal::Facet };
    let hit = HitPoint::from_code(code >> 1).ok_or(DecodeError::BadValue("reflection normal or hit point"))?;
    let skip_own_facet = flag(r, "own-facet skip")?;
    let connectivity = connectivity_of(r.u8()?)?;
    let fa = r.u16()? as usize;
    let (span, n, grid_depth) = (r.i32()?, r.u32()?, r.u32()?);
    if !(1..=MAX_SPAN).contains(&span) {
        return Err(DecodeError::BadValue("reflection span"));
    }
    if n > MAX_GRID || grid_depth > MAX_GRID {
        return Err(DecodeError::BadValue("reflection grid"));
    }
    let env = ReflectEnv { depth, threshold, normal, hit, skip_own_facet, connectivity, fa, span, n, grid_depth };
    let caps = [r.u16()?, r.u16()?, r.u16()?];
    let mut kr = Vec::new();
    for _ in 0..r.u8()? {
        kr.push(r.f32()?).map_err(|_| DecodeError::BadValue("too many materials"))?;
    }
    if !kr.iter().chain([&threshold]).all(|k| *k >= 0.0) {
        return Err(DecodeError::BadValue("reflection Kr or threshold"));
    }
    Ok(ReflectSetup { env, kr, caps })
}

/// Write a `Take` record's payload: class u8, port u8.
pub(super) fn put_take(w: &mut SliceWriter<'_>, class: u8, port: Port) -> Result<(), EncodeError> {
    w.u8(class)?;
    w.u8(port.index() as u8)
}

/// The payload of a `Take` record.
pub(super) fn get_take<'a, F: FracBits>(r: &mut Reader<'_>) -> Result<Event<'a, F>, DecodeError> {
    let class = r.u8()?;
    if class >= 4 {
        return Err(DecodeError::BadValue("ray class"));
    }
    Ok(Event::Take { class, port: port_of(r.u8()?)? })
}

/// Write a reflection answer record's payload: slot u16, the intensity 3×u16.
pub(super) fn put_reflect_answer(w: &mut SliceWriter<'_>, slot: u16, answer: &Answer) -> Result<(), EncodeError> {
    w.u16(slot)?;
    answer.iter().try_for_each(|&c| w.u16(c))
}

/// The payload of a reflection answer record.
pub(super) fn get_reflect_answer<'a, F: FracBits>(r: &mut Reader<'_>) -> Result<Event<'a, F>, DecodeError> {
    Ok(Event::ReflectAnswer { slot: r.u16()?, answer: [r.u16()?, r.u16()?, r.u16()?] })
}

impl Digester {
    fn answered(&mut self, dest: [u16; 2], payload: &[u8]) {
        let mut s = self.sink();
        let _ = (s.u8(b'A'), s.u16(dest[0]), s.u16(dest[1]), s.put(payload));
    }

    /// The shadow-ray cell handed an answer to its router (which took it).
    pub fn shadow_answer(&mut self, a: &ShadowAnswer) {
        self.answered(a.dest, &[a.payload]);
    }

    /// The reflection cell handed an answer to its router (which took it).
    pub fn reflect_answer(&mut self, a: &ReflectAnswer) {
        let (slot, v) = a.payload;
        let mut b = [0u8; 8];
        b[..2].copy_from_slice(&slot.to_le_bytes());
        for (k, c) in v.iter().enumerate() {
            b[2 + 2 * k..4 + 2 * k].copy_from_slice(&c.to_le_bytes());
        }
        self.answered(a.dest, &b);
    }

    /// One cycle of the shadow-ray cell: its step and the rays it launched after it.
    pub fn shadow_cycle(&mut self, step: ShadowStep, launched: u32) {
        let code = match step {
            ShadowStep::Idle => 0,
            ShadowStep::Answered(false) => 1,
            ShadowStep::Answered(true) => 2,
            ShadowStep::Moved => 3,
            ShadowStep::Blocked => 4,
        };
        let mut s = self.sink();
        let _ = (s.u8(b'R'), s.u8(code), s.u32(launched));
    }

    /// One cycle of the reflection cell: the moves it made (0 ..= 3).
    pub fn reflect_cycle(&mut self, moved: u32) {
        let _ = self.sink().put(&[b'M', moved as u8]);
    }

    /// The cell sent a ray on `port`: [`Digester::sent`] of its frame (sequence number 0).
    pub fn sent_ray(&mut self, port: Port, ray: &RayMsg) {
        let mut buf = [0u8; MAX_RAY_FRAME];
        // Cannot fail: no ray frame is longer.
        if let Ok(len) = ray.emit(0, &mut buf) {
            self.sent(port, &buf[..len]);
        }
    }

    /// The shadow-ray cell's state at the end of a source's phase: counters, lit mask, and what
    /// is left in its FIFO, output slots and emitter.
    pub fn shadow_state<const FA: usize>(&mut self, c: &ShadowCell<FA>) {
        let mut s = self.sink();
        let k = c.counters;
        let _ = (s.u8(b'H'), s.u32(k.rays), s.u32(k.back_facing), s.u32(k.steps), s.u32(k.blocked));
        let _ = (s.u32(k.lit), s.u32(k.overflows), s.u32(c.mask));
        let _ = (s.u16(c.fifo_len() as u16), s.u8(c.has_out() as u8), s.u8(c.emitting() as u8));
        for r in c.fifo() {
            let _ = put_shadow_ray(&mut s, r);
        }
    }

    /// The reflection cell's state at the end of the phase: counters, pixel, root answer, the
    /// open wait-table entries, and what is left in its FIFOs, slots and queues.
    pub fn reflect_state<const FA: usize, const W: usize, const S: usize>(&mut self, c: &ReflectCell<FA, W, S>) {
        let mut s = self.sink();
        let k = c.counters;
        let _ = (s.u8(b'X'), s.u32(k.roots), s.u32(k.rays), s.u32(k.ray_steps), s.u32(k.answers), s.u32(k.hits));
        let _ = (s.u32(k.exits), s.u32(k.waits), s.u8(k.max_level), s.u32(k.cut_depth), s.u32(k.cut_threshold));
        let _ = (s.u32(k.blocked), s.u16(k.peak_fifo), s.u16(k.peak_wait), s.u16(k.peak_send));
        let _ = (s.u32(k.wait_overflows), s.u32(k.send_overflows), s.u32(k.fifo_overflows), s.u32(k.stray_answers));
        match c.pixel {
            Some(p) => {
                let _ = (s.u8(1), s.put(&p));
            }
            None => {
                let _ = s.u8(0);
            }
        }
        match c.root_answer {
            Some(a) => {
                let _ = (s.u8(1), s.u16(a[0]), s.u16(a[1]), s.u16(a[2]));
            }
            None => {
                let _ = s.u8(0);
            }
        }
        for (slot, e) in c.wait_table() {
            let _ = s.u16(slot);
            if let Some((dest, ps)) = e.parent {
                let _ = (s.u16(dest[0]), s.u16(dest[1]), s.u16(ps));
            }
            let _ = (s.f32(e.local[0]), s.f32(e.local[1]), s.f32(e.local[2]), s.f32(e.kr));
        }
        for len in c.fifo_lens() {
            let _ = s.u16(len as u16);
        }
        let _ = (s.u32(c.outs()), s.u16(c.launching() as u16), s.u16(c.sending() as u16));
    }
}

impl<
        F: FracBits,
        const D: usize,
        const FA: usize,
        const OB: usize,
        const L: usize,
        const SFA: usize,
        const RFA: usize,
        const W: usize,
        const S: usize,
    > Replayer<F, D, FA, OB, L, SFA, RFA, W, S>
{
    /// A shadow setup record: a fresh shadow-ray cell for the source, started on the column
    /// (it launches its first rays).
    pub(super) fn start_shadow(&mut self, s: ShadowSetup) -> Result<(), ReplayError> {
        if s.fifo as usize != SFA {
            return Err(ReplayError::CapacityMismatch);
        }
        if !(1..=SFA).contains(&s.env.fa) {
            return Err(DecodeError::BadValue("shadow FIFO limit").into());
        }
        // Under exact occluders the column's triangles follow this record.
        #[cfg(feature = "exact-occluders")]
        self.column.clear();
        // Built in place: a cell-sized temporary would take the firmware's stack.
        self.rays = Rays::Shadow(ShadowCell::new(), s);
        let Rays::Shadow(cell, s) = &mut self.rays else { return Err(ReplayError::NoPhaseSetup) };
        cell.start(&self.cell, &s.env).map_err(|_| ReplayError::Ray)
    }

    /// A reflection setup record: a fresh reflection cell, its root planted (with a tree depth
    /// above 0) from the column's visible voxel lit as the light phase left it.
    pub(super) fn start_reflect(&mut self, s: ReflectSetup) -> Result<(), ReplayError> {
        if s.caps != [RFA, W, S].map(|c| c as u16) {
            return Err(ReplayError::CapacityMismatch);
        }
        if !(1..=RFA).contains(&s.env.fa) {
            return Err(DecodeError::BadValue("reflection FIFO limit").into());
        }
        let shade = self.shade.as_ref().ok_or(ReplayError::NoPhaseSetup)?;
        self.rays = Rays::Reflect(ReflectCell::new(), s);
        let Rays::Reflect(cell, s) = &mut self.rays else { return Err(ReplayError::NoPhaseSetup) };
        let surfaces =
            Surfaces { mats: &shade.materials, kr: &s.kr, transmit: &[], lights: &shade.lights, params: shade.params };
        let lit = &self.light.lit;
        if s.env.depth > 0 {
            cell.plant_root(&self.cell, &surfaces, &|z| lit.mask_at(z), &s.env).map_err(|_| ReplayError::Ray)?;
        }
        Ok(())
    }

    /// One cycle of the ray phase's cell; its router takes the answer the cell offers iff
    /// `takes`.
    pub(super) fn ray_cycle(&mut self, takes: bool) -> Result<(), ReplayError> {
        let digest = &mut self.digest;
        match &mut self.rays {
            Rays::Idle => return Err(ReplayError::NoPhaseSetup),
            Rays::Shadow(cell, s) => {
                #[cfg(feature = "exact-occluders")]
                let triangles = self.column.triangles.triangles();
                #[cfg(not(feature = "exact-occluders"))]
                let triangles = &[];
                let step = cell.step(&self.cell.store, triangles, |a| {
                    if takes {
                        digest.shadow_answer(&a);
                    }
                    takes
                });
                let launched = match cell.emitting() {
                    true => cell.launch(&self.cell, &s.env).map_err(|_| ReplayError::Ray)?,
                    false => 0,
                };
                digest.shadow_cycle(step, launched);
            }
            Rays::Reflect(cell, s) => {
                let shade = self.shade.as_ref().ok_or(ReplayError::NoPhaseSetup)?;
                let surfaces = Surfaces {
                    mats: &shade.materials,
                    kr: &s.kr,
                    transmit: &[],
                    lights: &shade.lights,
                    params: shade.params,
                };
                let lit = &self.light.lit;
                let send = |a: ReflectAnswer| {
                    if takes {
                        digest.reflect_answer(&a);
                    }
                    takes
                };
                let moved = cell.step(&self.cell, &surfaces, &|z| lit.mask_at(z), &s.env, send);
                digest.reflect_cycle(moved.map_err(|_| ReplayError::Ray)?);
            }
        }
        self.stats.steps += 1;
        Ok(())
    }

    /// The link receive path of a ray frame (CRC-checked by the caller): decode it and put the
    /// ray into the FIFO (of its class), after the credit check.
    pub(super) fn receive_ray(&mut self, raw: RawFrame<'_>) -> Result<(), ReplayError> {
        let (_, ray) = RayMsg::parse_payload(raw)?;
        let full = match (&mut self.rays, ray) {
            (Rays::Shadow(cell, s), RayMsg::Shadow(r)) => !cell.can_accept(s.env.fa) || cell.accept(r).is_err(),
            (Rays::Reflect(cell, s), RayMsg::Reflect(r)) => {
                let class = r.class();
                !cell.can_accept(class, s.env.fa) || cell.accept(class, r).is_err()
            }
            _ => return Err(ReplayError::NoPhaseSetup),
        };
        if full {
            return Err(ReplayError::FifoFull);
        }
        self.stats.received += 1;
        Ok(())
    }

    /// The neighbour on `port` took the ray of output slot (`class`, `port`): its frame goes
    /// into the digest and to `send` (the link's wire, on a firmware).
    pub fn take_ray(&mut self, class: u8, port: Port, send: impl FnOnce(&[u8])) -> Result<(), ReplayError> {
        let ray = match &mut self.rays {
            Rays::Shadow(cell, _) if class == 0 => cell.take_out(port).map(RayMsg::Shadow),
            Rays::Reflect(cell, _) if class < 4 => cell.take_out(class as usize, port).map(RayMsg::Reflect),
            _ => return Err(ReplayError::NoPhaseSetup),
        };
        let ray = ray.ok_or(ReplayError::NothingToSend)?;
        let mut buf = [0u8; MAX_RAY_FRAME];
        let len = ray.emit(0, &mut buf).map_err(|_| ReplayError::Link)?;
        self.digest.sent(port, &buf[..len]);
        send(&buf[..len]);
        self.stats.sent += 1;
        Ok(())
    }

    /// An answer the cell's router delivered.
    pub(super) fn deliver(&mut self, ev: Event<'_, F>) -> Result<(), ReplayError> {
        match (&mut self.rays, ev) {
            (Rays::Shadow(cell, s), Event::ShadowAnswer(p)) => cell.deliver(p, s.source_bit),
            (Rays::Reflect(cell, _), Event::ReflectAnswer { slot, answer }) => {
                cell.deliver(slot, answer);
            }
            _ => return Err(ReplayError::NoPhaseSetup),
        }
        self.stats.answers += 1;
        Ok(())
    }

    /// The end of the phase (of one source, for shadow rays): the cell's state goes into the
    /// digest; a shadow source's lit mask joins the column's.
    pub(super) fn end_phase(&mut self) -> Result<(), ReplayError> {
        match &self.rays {
            Rays::Idle => return Err(ReplayError::NoPhaseSetup),
            Rays::Shadow(cell, s) => {
                self.digest.shadow_state(cell);
                let before = self.shadow_lit.map_or(0, |(m, _)| m);
                self.shadow_lit = Some((before | cell.mask, s.env.rule));
            }
            Rays::Reflect(cell, _) => self.digest.reflect_state(cell),
        }
        Ok(())
    }
}

/// A single CRC-checked frame taking all of `frame`.
pub(super) fn single_frame(frame: &[u8]) -> Result<RawFrame<'_>, ReplayError> {
    let (raw, used) = read_frame(frame)?;
    if used != frame.len() {
        return Err(DecodeError::BadValue("not a single frame").into());
    }
    Ok(raw)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::frac::U0;
    use crate::trace::{replay, write_event};
    use std::vec::Vec;

    type R = Replayer<U0, 8, 4, 3, 4, 4, 2, 2, 2>;

    fn bytes(events: &[Event<'_, U0>]) -> Vec<u8> {
        let mut out = Vec::new();
        for ev in events {
            let mut buf = [0u8; 512];
            let n = write_event(ev, &mut buf).unwrap();
            out.extend_from_slice(&buf[..n]);
        }
        out
    }

    fn run(events: &[Event<'_, U0>]) -> Result<u64, ReplayError> {
        let mut r = R::new();
        for ev in events {
            r.apply(ev.clone())?;
        }
        r.take_digest()
    }

    fn shadow() -> ShadowSetup {
        let env = ShadowEnv {
            source: [0, 0, 0],
            rule: LitRule::Plane,
            connectivity: Connectivity::Six,
            all_voxels: true,
            bias: 2,
            fa: 3,
        };
        ShadowSetup { env, source_bit: 4, fifo: 4 }
    }

    fn shade() -> crate::trace::ShadeSetup {
        let params = crate::shade::ShadeParams {
            ambient: [0.1; 3],
            normal_mode: crate::shade::NormalMode::Facet,
            eye: crate::shade::Eye::Grid,
        };
        crate::trace::ShadeSetup { params, lights: heapless::Vec::new(), materials: heapless::Vec::new() }
    }

    fn reflect() -> ReflectSetup {
        let env = ReflectEnv {
            depth: 3,
            threshold: 0.25,
            normal: ReflectNormal::Face,
            hit: HitPoint::Exact,
            skip_own_facet: false,
            connectivity: Connectivity::Eighteen,
            fa: 2,
            span: 512,
            n: 16,
            grid_depth: 16,
        };
        ReflectSetup { env, kr: Vec::from([0.5, 0.0, 0.85]).into_iter().collect(), caps: [2, 2, 2] }
    }

    #[test]
    fn ray_records_round_trip() {
        let header = R::header(2, 3, 16);
        let events = [
            Event::Header(header),
            Event::Shadow(shadow()),
            Event::ShadowAnswer(3),
            Event::Refused,
            Event::Take { class: 3, port: Port::SW },
            Event::PhaseEnd,
            Event::Reflect(reflect()),
            Event::ReflectAnswer { slot: 1, answer: [1, 4096, 65535] },
            Event::End,
        ];
        let b = bytes(&events);
        let mut p = crate::trace::Parser::<U0>::new(&b);
        for ev in &events {
            assert_eq!(&p.next_event().unwrap().unwrap(), ev);
        }
        assert!(p.next_event().is_none());
    }

    #[test]
    fn ray_phases_refuse_other_capacities_and_records_out_of_phase() {
        let header = Event::Header(R::header(0, 0, 16));
        let other = ShadowSetup { fifo: 64, ..shadow() };
        assert_eq!(run(&[header.clone(), Event::Shadow(other)]), Err(ReplayError::CapacityMismatch));
        let caps = ReflectSetup { caps: [2, 2, 3], ..reflect() };
        assert_eq!(run(&[header.clone(), Event::Reflect(caps)]), Err(ReplayError::CapacityMismatch));
        // The reflection phase shades with the shading record's inputs: none yet.
        assert_eq!(run(&[header.clone(), Event::Reflect(reflect())]), Err(ReplayError::NoPhaseSetup));
        for ev in [Event::Refused, Event::PhaseEnd, Event::ShadowAnswer(1), Event::Take { class: 0, port: Port::E }] {
            assert_eq!(run(&[header.clone(), ev]), Err(ReplayError::NoPhaseSetup));
        }
        // A reflection answer in the shadow phase, a class beyond 0 for a shadow ray.
        let answer = Event::ReflectAnswer { slot: 0, answer: [0; 3] };
        assert_eq!(run(&[header.clone(), Event::Shadow(shadow()), answer]), Err(ReplayError::NoPhaseSetup));
        let take = Event::Take { class: 1, port: Port::E };
        assert_eq!(run(&[header.clone(), Event::Shadow(shadow()), take]), Err(ReplayError::NoPhaseSetup));
        // Nothing in the slot a neighbour takes from.
        let take = Event::Take { class: 0, port: Port::E };
        assert_eq!(run(&[header, Event::Shadow(shadow()), take]), Err(ReplayError::NothingToSend));
    }

    #[test]
    fn an_empty_column_answers_nothing_and_its_state_is_digested() {
        let header = Event::Header(R::header(0, 0, 16));
        let a = run(&[header.clone(), Event::Shadow(shadow()), Event::Step(3), Event::PhaseEnd, Event::End]).unwrap();
        let b = run(&[header.clone(), Event::Shadow(shadow()), Event::Step(2), Event::PhaseEnd, Event::End]).unwrap();
        let c = run(&[header.clone(), Event::Shadow(shadow()), Event::Step(3), Event::End]).unwrap();
        assert!(a != b && a != c && b != c, "cycles and the phase's end are in the digest");
        // The answers the router delivers change the cell's counters: in the digest too.
        let lit = run(&[header, Event::Shadow(shadow()), Event::ShadowAnswer(1), Event::PhaseEnd, Event::End]);
        assert_ne!(
            lit.unwrap(),
            run(&[Event::Header(R::header(0, 0, 16)), Event::Shadow(shadow()), Event::PhaseEnd, Event::End]).unwrap()
        );
        assert!(replay::<U0, 8, 4, 3, 4>(&bytes(&[Event::Header(R::header(0, 0, 16))])).is_err(), "no end");
    }

    #[test]
    fn reflection_setups_beyond_the_bit_budget_are_refused() {
        let refused = |edit: &dyn Fn(&mut ReflectSetup)| {
            let mut s = reflect();
            edit(&mut s);
            let b = bytes(&[Event::Reflect(s)]);
            crate::trace::Parser::<U0>::new(&b).next_event().unwrap().err()
        };
        assert_eq!(refused(&|_| {}), None);
        let bad = |what| Some(ReplayError::Decode(DecodeError::BadValue(what)));
        assert_eq!(refused(&|s| s.env.span = MAX_SPAN + 1), bad("reflection span"));
        assert_eq!(refused(&|s| s.env.span = 0), bad("reflection span"));
        assert_eq!(refused(&|s| s.env.n = MAX_GRID + 1), bad("reflection grid"));
        assert_eq!(refused(&|s| s.env.grid_depth = u32::MAX), bad("reflection grid"));
        assert_eq!(refused(&|s| s.env.threshold = -0.25), bad("reflection Kr or threshold"));
        assert_eq!(refused(&|s| s.kr[1] = -0.5), bad("reflection Kr or threshold"));
        assert_eq!(refused(&|s| s.kr[0] = f32::INFINITY), bad("non-finite float"));
    }

    /// One record of [`forged_ray_records_never_panic`]'s scripts, from its op code, a number
    /// and three more.
    fn forged<'a>(
        op: u8,
        x: u32,
        v: [u16; 3],
        shadow: ShadowSetup,
        reflect: &ReflectSetup,
        frame: &'a [u8],
    ) -> Event<'a, U0> {
        let port = Port::ALL[x as usize % 8];
        match op {
            0 => Event::Shadow(shadow),
            1 => Event::Reflect(reflect.clone()),
            2 => Event::ShadowAnswer(x as u8),
            3 => Event::ReflectAnswer { slot: x as u16, answer: v },
            4 => Event::Refused,
            5 => Event::Take { class: (x % 4) as u8, port },
            6 => Event::PhaseEnd,
            7 => Event::Step(x % 4),
            _ => Event::Recv { port, frame },
        }
    }

    proptest::proptest! {
        /// Ray-phase records with any values the decoders let through, in any order, after a
        /// header and a shading record (the cell's column empty): the replay goes through them
        /// or stops with an error, never a panic (debug builds check every operation), and a
        /// decoded setup record is within the bit budget. The rays arriving are built from any
        /// end points (refused beyond the budget) or are any bytes in a ray frame.
        #[test]
        fn forged_ray_records_never_panic(
            source in proptest::array::uniform3(proptest::prelude::any::<i32>()),
            (bias, fa, k, flags) in (0u8..4, 0usize..6, 0usize..3, 0u8..4),
            (depth, threshold, span, n, grid) in (0u8..6, -1.0f32..2.0, -5i32..MAX_SPAN + 5, 0u32..MAX_GRID + 3, 0u32..40),
            kr in proptest::collection::vec(-0.5f32..1.5, 0..4),
            ends in proptest::array::uniform2(proptest::array::uniform3(-3000i32..3000)),
            raw in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..100),
            script in proptest::collection::vec((0u8..10, proptest::prelude::any::<u32>(), proptest::array::uniform3(proptest::prelude::any::<u16>())), 0..40),
        ) {
            let env = ShadowEnv {
                source,
                rule: if flags & 1 != 0 { LitRule::Plane } else { LitRule::Thesis },
                connectivity: Connectivity::ALL[k],
                all_voxels: flags & 2 != 0,
                bias,
                fa,
            };
            let shadow = ShadowSetup { env, source_bit: 1 << k, fifo: 4 };
            let renv = ReflectEnv { depth, threshold, span, n, grid_depth: grid, fa, connectivity: Connectivity::ALL[k], hit: HitPoint::ALL[k], ..reflect().env };
            let reflect = ReflectSetup { env: renv, kr: kr.iter().copied().collect(), caps: [2, 2, 2] };
            let mut frames = std::vec::Vec::new();
            let mut buf = [0u8; MAX_RAY_FRAME];
            if let Ok(ray) = crate::ray::ShadowRay::new([1, 0, 3], ends[0], Connectivity::ALL[k], 5) {
                let len = RayMsg::Shadow(ray).emit(0, &mut buf).unwrap();
                frames.push(buf[..len].to_vec());
            }
            let dir = [ends[1][0] - 16, ends[1][1], ends[1][2] - 48];
            if let Ok(ray) = crate::reflect::ReflectRay::leaving([crate::ray::Q, 0, 3 * crate::ray::Q], dir, Connectivity::ALL[k], [0, 0], 1, 2, 1, 0.5) {
                let len = RayMsg::Reflect(ray).emit(0, &mut buf).unwrap();
                frames.push(buf[..len].to_vec());
            }
            for kind in [crate::wire::KIND_SHADOW_RAY, crate::wire::KIND_REFLECT_RAY] {
                let len = crate::wire::write_frame(&mut buf, kind, |w| w.put(&raw[..raw.len().min(90)])).unwrap();
                frames.push(buf[..len].to_vec());
            }
            let header = Event::Header(R::header(1, 0, 16));
            let mut events = std::vec![header, Event::Shade(shade())];
            for &(op, x, v) in &script {
                events.push(forged(op, x, v, shadow, &reflect, &frames[x as usize % frames.len()]));
            }
            events.push(Event::End);
            let b = bytes(&events);
            let mut p = crate::trace::Parser::<U0>::new(&b);
            let mut r = R::new();
            while let Some(ev) = p.next_event() {
                let Ok(ev) = ev else { continue };
                if let Event::Reflect(s) = &ev {
                    proptest::prop_assert!((1..=MAX_SPAN).contains(&s.env.span) && s.env.n <= MAX_GRID);
                }
                if r.apply(ev).is_err() {
                    break;
                }
            }
            let _ = r.take_digest();
        }
    }
}

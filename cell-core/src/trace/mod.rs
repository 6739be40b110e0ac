//! Cell traces: everything one cell received during a run, in order, and a replay of it through
//! the real cell.
//!
//! A trace is a sequence of [`crate::link`] frames (same framing and CRC as the links):
//!
//! | kind | record | payload |
//! |---|---|---|
//! | `0x40` | [`Event::Header`] | magic `RC2T` u32, version u8, x u16, y u16, depth u32, frac bits u8, dexel capacity u16, FIFO capacity u16, output buffer u8, lit runs u16 |
//! | `0x41` | [`Event::Row`] | a row packet arriving from the west (loading, §3.9) |
//! | `0x42` | [`Event::Light`] | a source's diffusion starts: source id u16, position 3×i32 (1/16 voxel), n u32, depth u32, D u32, policy u8, FIFO limit u16, merge u8, source bit u32, skip u8 (+ occupied box lo, hi 6×u16 when 1); from version 3: sibling wait u16, frustum u8 (+ the summary's 8 × 8 block rows, 64 × u8 bit masks over z, when 1), lit rule u8 (low nibble: 0 thesis, 1 plane, 2 exact occluders; from version 6 bits 4–6 are the rays' origin: 0 the source voxel, 1 the light; bit 7 the visible-only lit store, `render`'s: only the pixel's target voxel is marked — 0 in every trace written before it was carried) |
//! | `0x43` | [`Event::Inject`] | the source emitter hands this cell an initial beam |
//! | `0x44` | [`Event::Recv`] | link `port` delivers a beam (or, in a ray phase, a ray): port u8 + the link frame as on the wire (its own CRC) |
//! | `0x45` | [`Event::Step`] | `count` u32 compute cycles |
//! | `0x46` | [`Event::Grant`] | the neighbour on `port` took the head of that output buffer |
//! | `0x47` | [`Event::Shade`] | ambient 3×f32, normal mode u8, lights (count u8, pos+colour 6×f32), materials (count u8, 13×f32), then for a camera ([`crate::shade::Eye::Camera`]) perspective u8, n width near far 4×f32 |
//! | `0x48` | [`Event::End`] | end of the trace |
//! | `0x49` | [`Event::Shadow`] | a source's classic shadow-ray phase starts ([`ShadowSetup`]): source 3×i32 (1/16 voxel), lit rule u8 (0 thesis, 1 plane, 2 exact occluders: the column's triangles follow), ray connectivity u8 (6, 18, 26), every voxel emits u8, bias u8, FIFO limit u16, source bit u32, FIFO capacity u16 |
//! | `0x4a` | [`Event::Reflect`] | the reflection phase starts ([`ReflectSetup`]): depth u8, threshold f32, normal u8 (0 facet, 1 face), skip own facet u8, connectivity u8, FIFO limit u16, span i32, n u32, depth u32, capacities (FIFO per class, wait table, send queue) 3×u16, Kr (count u8, f32 each) |
//! | `0x4b` | [`Event::ShadowAnswer`] | the cell's router delivers a shadow-ray answer: payload u8 ([`crate::shadow::ANSWER_LIT`], [`crate::shadow::ANSWER_SURFACE`]) |
//! | `0x4c` | [`Event::ReflectAnswer`] | the cell's router delivers a reflection answer: wait-table slot u16, intensity 3×u16 (Q12) |
//! | `0x4d` | [`Event::Refused`] | one compute cycle of the ray phase in which the router refused the answer the cell offered |
//! | `0x4e` | [`Event::Take`] | the neighbour on `port` took the ray of output slot (class, port): class u8 (0 for shadow rays), port u8 |
//! | `0x4f` | [`Event::PhaseEnd`] | the ray phase ended (a source's, for shadow rays) |
//! | `0x50` | [`Event::Triangle`] | under exact occluders, after the light record or the shadow setup record: one triangle the column keeps for the source's diffusion or shadow rays ([`crate::occluder::Triangle`], its vertices 9×i32 in sixteenths of a voxel), in the column's order; the cell computes its target ray itself ([`crate::receiver::target`]) |
//! | `0x51` | [`Event::NeighbourContact`] | under exact occluders, after a light record's triangles, for a cell whose target ray has a contact segment: its 8 neighbours' answers to its contact query, OR-ed, u8 0/1, before any other record ([`crate::receiver`], "The neighbours' triangles"; a trace without it does not replay) |
//!
//! In the ray phases ([`rays`]) a `Step` record counts cycles of the phase's cell in which its
//! router took any answer offered, and `Recv` carries a ray frame ([`crate::wire::RayMsg`]). A
//! trace holds every phase the recorded run ran, in order: loading, then beam diffusion or
//! the classic shadow rays, shading, then reflections. The ray records were added without a
//! version change: a trace of loading and lighting reads and replays as before.
//!
//! **Invariant: a replay reaches the host's digest iff the cell behaved the same.** The cell's
//! *outputs* are what it sends (forwarded row packets, beam and ray frames on each port,
//! answers to its router) and the result of every compute cycle; its *final state* is its
//! dexels, lit runs, counters and pixel, and each ray phase's cell state at its end
//! ([`rays`]). [`Digester`] folds both into a CRC-64 digest. The host computes it from its own
//! grid run; [`Replayer`] recomputes it by driving a fresh cell through the trace. The two are
//! equal iff the cell behaves the same, which the QEMU test checks on a Cortex-M4F.
//!
//! **Thesis:** no section of its own: a trace records the cell of loading (§3.9), beam
//! diffusion (§4.4), classic shadow rays (§4.1.2–4.1.3), shading (§5) and reflections (§1.3.2)
//! at its links.

use heapless::Vec;

use crate::beam::{FarDistance, FracBits, Origin, Source, SourceCoord, SourceId, SplitOrder};
use crate::cell::{Cell, REFLECT_FA_CAP, SEND_CAP, SHADOW_FA_CAP, WAIT_CAP};
use crate::facet::RowPacket;
use crate::light::{
    Activity, BeamMsg, FrustumSummary, LightCell, LightEnv, OccupiedBox, Policy, Port, SourceMask, Step, SubBeamBounds,
};
use crate::link::{self, Link, Sent};
use crate::lit::LitRule;
use crate::occluder::Triangle;
use crate::reflect::Answer;
use crate::shade::{cell_pixel, CameraView, Eye, Material, NormalMode, Pixel, PointLight, ShadeParams};
use crate::units::{Coord, Depth};
use crate::wire::{
    self, get_beam, get_row, put_beam, put_row, read_frame, write_frame, ByteSink, DecodeError, EncodeError, Frame,
    PutExt, Reader, SliceWriter, HEADER, MAX_RAY_FRAME, TRAILER,
};

pub mod rays;
pub use rays::{Rays, ReflectSetup, ShadowSetup};

/// `RC2T`.
pub const MAGIC: u32 = u32::from_le_bytes(*b"RC2T");
/// Trace format version (5: row packets carry their facet's plane and contour pushes, beams
/// their terminal and after-empty flags, the light record the lit rule; the visible surface's
/// plane faces the viewer; 6: the light record carries the rays' origin, and exact occluders
/// their column's triangles). Earlier versions are refused: they were recorded under other
/// rules, and their replays would not reach their digests.
pub const VERSION: u8 = 6;
/// Record kinds.
pub mod kind {
    /// [`super::Event::Header`].
    pub const HEADER: u8 = 0x40;
    /// [`super::Event::Row`].
    pub const ROW: u8 = 0x41;
    /// [`super::Event::Light`].
    pub const LIGHT: u8 = 0x42;
    /// [`super::Event::Inject`].
    pub const INJECT: u8 = 0x43;
    /// [`super::Event::Recv`].
    pub const RECV: u8 = 0x44;
    /// [`super::Event::Step`].
    pub const STEP: u8 = 0x45;
    /// [`super::Event::Grant`].
    pub const GRANT: u8 = 0x46;
    /// [`super::Event::Shade`].
    pub const SHADE: u8 = 0x47;
    /// [`super::Event::End`].
    pub const END: u8 = 0x48;
    /// [`super::Event::Shadow`].
    pub const SHADOW: u8 = 0x49;
    /// [`super::Event::Reflect`].
    pub const REFLECT: u8 = 0x4a;
    /// [`super::Event::ShadowAnswer`].
    pub const SHADOW_ANSWER: u8 = 0x4b;
    /// [`super::Event::ReflectAnswer`].
    pub const REFLECT_ANSWER: u8 = 0x4c;
    /// [`super::Event::Refused`].
    pub const REFUSED: u8 = 0x4d;
    /// [`super::Event::Take`].
    pub const TAKE: u8 = 0x4e;
    /// [`super::Event::PhaseEnd`].
    pub const PHASE_END: u8 = 0x4f;
    /// [`super::Event::Triangle`].
    pub const TRIANGLE: u8 = 0x50;
    /// [`super::Event::NeighbourContact`].
    pub const NEIGHBOUR_CONTACT: u8 = 0x51;
}
/// Most lights a shading record carries.
pub const MAX_LIGHTS: usize = 8;
/// Most materials a shading record carries.
pub const MAX_MATERIALS: usize = 16;
/// Longest beam link frame.
pub const BEAM_FRAME: usize = HEADER + wire::BEAM_PAYLOAD + TRAILER;
/// Longest link frame a cell receives in a trace: a beam or a ray.
pub const LINK_FRAME: usize = if BEAM_FRAME > MAX_RAY_FRAME { BEAM_FRAME } else { MAX_RAY_FRAME };

/// The cell a trace is for and the capacities it was recorded with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// Column.
    pub x: Coord,
    /// Row.
    pub y: Coord,
    /// Voxels per column.
    pub depth: u32,
    /// Beam fraction bits.
    pub frac_bits: u8,
    /// Dexel capacity.
    pub dexels: u16,
    /// FIFO capacity.
    pub fifo: u16,
    /// Output buffer capacity.
    pub out: u8,
    /// Lit-run capacity.
    pub lit: u16,
}

/// The lighting environment of one source's diffusion, as a cell receives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightSetup {
    /// The source.
    pub source: Source,
    /// Grid side.
    pub n: u32,
    /// Voxels per column.
    pub depth: u32,
    /// Far distance D.
    pub far: u32,
    /// Scheduling policy.
    pub policy: Policy,
    /// FIFO limit in use.
    pub fa: u16,
    /// Exact beam merging.
    pub merge: bool,
    /// The source's bit.
    pub source_bit: SourceMask,
    /// The occupied box of the receding-beam skip (`None`: off).
    pub skip: Option<OccupiedBox>,
    /// The sibling wait ([`LightEnv::hold`]; 0: off).
    pub hold: u16,
    /// The empty-frustum skip's summary (`None`: off).
    pub frustum: Option<FrustumSummary>,
    /// The lit rule.
    pub rule: LitRule,
    /// The visible-only lit store ([`LightEnv::lit_visible_only`], `render`'s): only the
    /// pixel's target voxel is marked lit, not every occupied voxel its own ray reaches.
    pub lit_visible_only: bool,
}

impl LightSetup {
    /// The lighting environment this setup gives a cell, with sub-beam order `order` (what
    /// [`Replayer`] and a firmware main loop pass to [`LightCell::step`]). Fails with
    /// [`ReplayError::BadFar`] when the far distance is beyond the bit budget of `F`.
    pub fn env<'s, F: FracBits>(&'s self, order: &'s SplitOrder) -> Result<LightEnv<'s, F>, ReplayError> {
        let mut env = self.env_without_frustum(order)?;
        env.frustum = self.frustum.as_ref().map(|o| o as &dyn crate::occupancy::FrustumTest<F>);
        Ok(env)
    }

    /// [`LightSetup::env`] without the empty-frustum skip, whatever the setup says: for a
    /// cell built without the skip (a firmware image that refuses setups with a summary).
    /// Building the optional summary reference stores its vtable even when it is `None`, which
    /// would keep the skip's code, and through the `Debug` bound the formatting machinery, in
    /// the image. Always inlined: options a firmware fixes become constants through it.
    ///
    /// ```
    /// use cell_core::beam::{frac::U0, Source, SourceId, SplitOrder};
    /// use cell_core::light::{FrustumSummary, Policy};
    /// use cell_core::lit::LitRule;
    /// use cell_core::trace::LightSetup;
    ///
    /// let source = Source::at_voxel(SourceId(0), [4, 4, 4]).unwrap();
    /// let frustum = Some(FrustumSummary::new(16, 16));
    /// let (policy, rule) = (Policy::Thesis, LitRule::Thesis);
    /// let setup = LightSetup {
    ///     source, n: 16, depth: 16, far: 31, policy, fa: 16, merge: true, source_bit: 1,
    ///     skip: None, hold: 0, frustum, rule, lit_visible_only: false,
    /// };
    /// let order = SplitOrder::default();
    /// let with = setup.env::<U0>(&order).unwrap();
    /// let without = setup.env_without_frustum::<U0>(&order).unwrap();
    /// assert!(with.frustum.is_some() && without.frustum.is_none());
    /// assert_eq!((without.far, without.fa, without.bounds), (with.far, with.fa, with.bounds));
    /// ```
    #[inline(always)]
    pub fn env_without_frustum<'s, F: FracBits>(
        &'s self,
        order: &'s SplitOrder,
    ) -> Result<LightEnv<'s, F>, ReplayError> {
        Ok(LightEnv {
            source: &self.source,
            far: FarDistance::new(self.far).ok_or(ReplayError::BadFar)?,
            n: self.n,
            depth: self.depth,
            policy: self.policy,
            rule: self.rule,
            order,
            fa: self.fa as usize,
            // A trace records rc2's timing (the host refuses to trace other timings).
            free_ports: false,
            source_bit: self.source_bit,
            merge: self.merge,
            skip: self.skip,
            bounds: SubBeamBounds::new(self.n, self.depth, self.skip, &self.source),
            lit_visible_only: self.lit_visible_only,
            hold: self.hold,
            frustum: None,
            rays: None,
            // Under exact occluders the column's triangles come in their own records
            // ([`Event::Triangle`]): the replayer adds them (`Replayer::light_cycles`).
            occluders: None,
        })
    }
}

/// What a cell needs to shade its pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadeSetup {
    /// Ambient and normal mode.
    pub params: ShadeParams,
    /// The lights.
    pub lights: Vec<PointLight, MAX_LIGHTS>,
    /// The material table.
    pub materials: Vec<Material, MAX_MATERIALS>,
}

/// One trace record.
// One record lives on the stack at a time, and there is no heap to box the shading inputs into.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Event<'a, F: FracBits> {
    /// The cell and capacities.
    Header(Header),
    /// A row packet arrives.
    Row(RowPacket),
    /// A source's diffusion starts.
    Light(LightSetup),
    /// The source emitter hands over an initial beam.
    Inject(BeamMsg<F>),
    /// A link delivers a frame.
    Recv {
        /// The link it came in on (as the receiver names it).
        port: Port,
        /// The frame bytes.
        frame: &'a [u8],
    },
    /// Compute cycles.
    Step(u32),
    /// A neighbour took the head of an output buffer.
    Grant(Port),
    /// Shading inputs.
    Shade(ShadeSetup),
    /// End of trace.
    End,
    /// A source's classic shadow-ray phase starts.
    Shadow(ShadowSetup),
    /// The reflection phase starts.
    Reflect(ReflectSetup),
    /// The router delivers a shadow-ray answer (its payload bits).
    ShadowAnswer(u8),
    /// The router delivers a reflection answer.
    ReflectAnswer {
        /// The wait-table slot it is for.
        slot: u16,
        /// The intensity.
        answer: Answer,
    },
    /// One cycle of the ray phase in which the router refused the answer offered.
    Refused,
    /// A neighbour took the ray of an output slot.
    Take {
        /// The ray class (0 for shadow rays; 0 ..= 3 for reflected rays).
        class: u8,
        /// The link.
        port: Port,
    },
    /// The ray phase ended (a source's, for shadow rays).
    PhaseEnd,
    /// Under exact occluders: a triangle the column keeps for the current source.
    Triangle(Triangle),
    /// Under exact occluders, for a cell with a contact segment: its 8 neighbours' answers to
    /// its contact query, OR-ed ([`crate::receiver::Target::neighbour_shadow`]).
    NeighbourContact(bool),
}

/// Why a trace could not be replayed (a value, never a panic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// A record or frame did not decode.
    Decode(DecodeError),
    /// The first record is not a header, or its magic/version is wrong.
    BadHeader,
    /// The trace was recorded with other capacities or fraction bits than this build.
    CapacityMismatch,
    /// A lighting record came before the source's setup.
    NoLightSetup,
    /// The far distance of a setup is beyond the bit budget.
    BadFar,
    /// A beam arrived while the FIFO was full: the trace does not match the cell.
    FifoFull,
    /// A grant for an empty output buffer: the trace does not match the cell.
    NothingToSend,
    /// A link failed.
    Link,
    /// Records after the end, or no end.
    BadEnd,
    /// A ray-phase record without its phase's setup (or for another phase), or a reflection
    /// setup before the shading record.
    NoPhaseSetup,
    /// The cell could not build a ray (a coordinate or span beyond the ray's bit budget).
    Ray,
}

impl From<DecodeError> for ReplayError {
    fn from(e: DecodeError) -> Self {
        ReplayError::Decode(e)
    }
}

fn port_of(i: u8) -> Result<Port, DecodeError> {
    Port::ALL.get(i as usize).copied().ok_or(DecodeError::BadValue("port"))
}

fn policy_code(p: Policy) -> u8 {
    match p {
        Policy::Thesis => 0,
        Policy::Wavefront => 1,
        Policy::Radial => 2,
    }
}

/// Write one record into `buf`; returns its length.
pub fn write_event<F: FracBits>(ev: &Event<'_, F>, buf: &mut [u8]) -> Result<usize, EncodeError> {
    match ev {
        Event::Header(h) => write_frame(buf, kind::HEADER, |w| {
            w.u32(MAGIC)?;
            w.u8(VERSION)?;
            w.u16(h.x)?;
            w.u16(h.y)?;
            w.u32(h.depth)?;
            w.u8(h.frac_bits)?;
            w.u16(h.dexels)?;
            w.u16(h.fifo)?;
            w.u8(h.out)?;
            w.u16(h.lit)
        }),
        Event::Row(p) => write_frame(buf, kind::ROW, |w| put_row(w, p)),
        Event::Light(s) => write_frame(buf, kind::LIGHT, |w| put_light_setup(w, s)),
        Event::Inject(m) => write_frame(buf, kind::INJECT, |w| put_beam(w, m)),
        Event::Recv { port, frame } => write_frame(buf, kind::RECV, |w| {
            w.u8(port.index() as u8)?;
            w.put(frame)
        }),
        Event::Step(n) => write_frame(buf, kind::STEP, |w| w.u32(*n)),
        Event::Grant(p) => write_frame(buf, kind::GRANT, |w| w.u8(p.index() as u8)),
        Event::Shade(s) => write_frame(buf, kind::SHADE, |w| put_shade_setup(w, s)),
        Event::End => write_frame(buf, kind::END, |_| Ok(())),
        Event::Shadow(s) => write_frame(buf, kind::SHADOW, |w| rays::put_shadow_setup(w, s)),
        Event::Reflect(s) => write_frame(buf, kind::REFLECT, |w| rays::put_reflect_setup(w, s)),
        Event::ShadowAnswer(p) => write_frame(buf, kind::SHADOW_ANSWER, |w| w.u8(*p)),
        Event::ReflectAnswer { slot, answer } => {
            write_frame(buf, kind::REFLECT_ANSWER, |w| rays::put_reflect_answer(w, *slot, answer))
        }
        Event::Refused => write_frame(buf, kind::REFUSED, |_| Ok(())),
        Event::Take { class, port } => write_frame(buf, kind::TAKE, |w| rays::put_take(w, *class, *port)),
        Event::PhaseEnd => write_frame(buf, kind::PHASE_END, |_| Ok(())),
        Event::Triangle(t) => write_frame(buf, kind::TRIANGLE, |w| {
            for c in t.vertices().iter().flatten() {
                w.i32(*c)?;
            }
            Ok(())
        }),
        Event::NeighbourContact(b) => write_frame(buf, kind::NEIGHBOUR_CONTACT, |w| w.u8(*b as u8)),
    }
}

/// Write a light setup record's payload (the layout is in the module's table).
fn put_light_setup(w: &mut SliceWriter<'_>, s: &LightSetup) -> Result<(), EncodeError> {
    w.u16(s.source.id.0)?;
    for c in s.source.pos {
        w.i32(c.to_bits())?;
    }
    w.u32(s.n)?;
    w.u32(s.depth)?;
    w.u32(s.far)?;
    w.u8(policy_code(s.policy))?;
    w.u16(s.fa)?;
    w.u8(s.merge as u8)?;
    w.u32(s.source_bit)?;
    match &s.skip {
        None => w.u8(0)?,
        Some(b) => {
            w.u8(1)?;
            for v in b.lo.iter().chain(&b.hi) {
                w.u16(*v)?;
            }
        }
    }
    w.u16(s.hold)?;
    match &s.frustum {
        None => w.u8(0)?,
        Some(o) => {
            w.u8(1)?;
            for bx in 0..FRUSTUM_BLOCKS {
                for by in 0..FRUSTUM_BLOCKS {
                    let row = (0..FRUSTUM_BLOCKS).fold(0u8, |m, bz| m | (o.occupied_block([bx, by, bz]) as u8) << bz);
                    w.u8(row)?;
                }
            }
        }
    }
    let rule = s.rule.code();
    let origin: u8 = match s.source.origin {
        Origin::SourceVoxel => 0,
        #[cfg(feature = "rays-from-light")]
        Origin::Light => 1,
    };
    w.u8(rule | origin << 4 | (s.lit_visible_only as u8) << 7)
}

/// Write a shading record's payload (the layout is in the module's table).
fn put_shade_setup(w: &mut SliceWriter<'_>, s: &ShadeSetup) -> Result<(), EncodeError> {
    for a in s.params.ambient {
        w.f32(a)?;
    }
    w.u8(matches!(s.params.normal_mode, NormalMode::Face) as u8)?;
    w.u8(s.lights.len() as u8)?;
    for l in &s.lights {
        for v in l.pos.iter().chain(l.color.iter()) {
            w.f32(*v)?;
        }
    }
    w.u8(s.materials.len() as u8)?;
    for m in &s.materials {
        for v in m.ka.iter().chain(&m.kd).chain(&m.ks).chain(core::iter::once(&m.ns)).chain(&m.ke) {
            w.f32(*v)?;
        }
    }
    match s.params.eye {
        // The grid's own view writes nothing: traces recorded before cameras read the same.
        Eye::Grid => Ok(()),
        Eye::Camera(c) => {
            w.u8(c.perspective as u8)?;
            for v in [c.n, c.width, c.near, c.far] {
                w.f32(v)?;
            }
            Ok(())
        }
    }
}

fn f32x3(r: &mut Reader<'_>) -> Result<[f32; 3], DecodeError> {
    Ok([r.f32()?, r.f32()?, r.f32()?])
}

/// Reads the records of a trace one by one.
pub struct Parser<'a, F: FracBits> {
    bytes: &'a [u8],
    far: Option<FarDistance<F>>,
    /// The header's format version (0 before the header).
    version: u8,
}

/// Blocks per axis of the frustum summary a trace carries.
const FRUSTUM_BLOCKS: usize = 8;
const _: () = assert!(
    FrustumSummary::BYTES == crate::occupancy::Occupancy8::BYTES,
    "traces carry an 8 x 8 x 8 summary, one byte per block row"
);

/// The frustum summary of a light record after its flag (the summary's occupied blocks,
/// rebuilt by marking one voxel of each: the summary is a function of its blocks), for grid
/// `n` × `n` × `depth`. What [`get_light_setup`] calls on a cell that holds summaries.
pub fn read_frustum(r: &mut Reader<'_>, n: u32, depth: u32) -> Result<Option<FrustumSummary>, DecodeError> {
    match r.u8()? {
        0 => Ok(None),
        1 => {
            if !(1..=crate::units::MAX_N).contains(&n) || !(1..=crate::units::MAX_N).contains(&depth) {
                return Err(DecodeError::BadValue("frustum grid"));
            }
            let mut o = FrustumSummary::new(n, depth);
            let (side, used) = (o.side(), o.blocks());
            for bx in 0..FRUSTUM_BLOCKS {
                for by in 0..FRUSTUM_BLOCKS {
                    let row = r.u8()?;
                    for bz in (0..FRUSTUM_BLOCKS).filter(|&bz| row >> bz & 1 == 1) {
                        if bx >= used[0] || by >= used[1] || bz >= used[2] {
                            return Err(DecodeError::BadValue("frustum block outside the grid"));
                        }
                        let v = [bx as u32 * side[0], by as u32 * side[1], bz as u32 * side[2]];
                        o.mark_span(v[0], v[1], v[2], v[2]);
                    }
                }
            }
            Ok(Some(o))
        }
        _ => Err(DecodeError::BadValue("frustum flag")),
    }
}

/// The payload of a header record (magic and version checked).
pub fn get_header(r: &mut Reader<'_>) -> Result<Header, ReplayError> {
    if r.u32()? != MAGIC || r.u8()? != VERSION {
        return Err(ReplayError::BadHeader);
    }
    Ok(Header {
        x: r.u16()?,
        y: r.u16()?,
        depth: r.u32()?,
        frac_bits: r.u8()?,
        dexels: r.u16()?,
        fifo: r.u16()?,
        out: r.u8()?,
        lit: r.u16()?,
    })
}

/// The payload of a light record. `frustum(r, n, depth)` reads the frustum flag and summary:
/// [`read_frustum`], or, on a cell built without the empty-frustum skip, a reader that
/// refuses a summary (so that its code is not in the image).
pub fn get_light_setup(
    r: &mut Reader<'_>,
    frustum: impl FnOnce(&mut Reader<'_>, u32, u32) -> Result<Option<FrustumSummary>, DecodeError>,
) -> Result<LightSetup, ReplayError> {
    let id = SourceId(r.u16()?);
    let mut pos = [SourceCoord::ZERO; 3];
    for p in pos.iter_mut() {
        *p = SourceCoord::from_bits(r.i32()?);
    }
    let mut s = LightSetup {
        source: Source::new(id, pos),
        n: r.u32()?,
        depth: r.u32()?,
        far: r.u32()?,
        policy: match r.u8()? {
            0 => Policy::Thesis,
            1 => Policy::Wavefront,
            2 => Policy::Radial,
            _ => return Err(DecodeError::BadValue("policy").into()),
        },
        fa: r.u16()?,
        merge: r.u8()? != 0,
        source_bit: r.u32()?,
        skip: match r.u8()? {
            0 => None,
            1 => Some(OccupiedBox { lo: [r.u16()?, r.u16()?, r.u16()?], hi: [r.u16()?, r.u16()?, r.u16()?] }),
            _ => return Err(DecodeError::BadValue("skip flag").into()),
        },
        hold: r.u16()?,
        frustum: None,
        rule: LitRule::Thesis,
        lit_visible_only: false,
    };
    s.frustum = frustum(r, s.n, s.depth)?;
    let code = r.u8()?;
    s.rule = LitRule::from_code(code & 0x0f).ok_or(DecodeError::BadValue("lit rule"))?;
    s.lit_visible_only = code >> 7 != 0;
    s.source.origin = match code >> 4 & 0x7 {
        0 => Origin::SourceVoxel,
        #[cfg(feature = "rays-from-light")]
        1 => Origin::Light,
        _ => return Err(DecodeError::BadValue("lit rule").into()),
    };
    Ok(s)
}

/// The payload of a shading record.
pub fn get_shade_setup(r: &mut Reader<'_>) -> Result<ShadeSetup, DecodeError> {
    let ambient = f32x3(r)?;
    let normal_mode = if r.u8()? == 1 { NormalMode::Face } else { NormalMode::Facet };
    let mut lights = Vec::new();
    for _ in 0..r.u8()? {
        let l = PointLight { pos: f32x3(r)?, color: f32x3(r)? };
        lights.push(l).map_err(|_| DecodeError::BadValue("too many lights"))?;
    }
    let mut materials = Vec::new();
    for _ in 0..r.u8()? {
        let m = Material { ka: f32x3(r)?, kd: f32x3(r)?, ks: f32x3(r)?, ns: r.f32()?, ke: f32x3(r)? };
        materials.push(m).map_err(|_| DecodeError::BadValue("too many materials"))?;
    }
    // A camera's inverse follows for a scene seen through one; the grid's own view writes
    // nothing (traces recorded before cameras read the same).
    let eye = if r.remaining() == 0 {
        Eye::Grid
    } else {
        let perspective = r.u8()? == 1;
        let (n, width, near, far) = (r.f32()?, r.f32()?, r.f32()?, r.f32()?);
        Eye::Camera(CameraView { n, perspective, width, near, far })
    };
    Ok(ShadeSetup { params: ShadeParams { ambient, normal_mode, eye }, lights, materials })
}

impl<'a, F: FracBits> Parser<'a, F> {
    /// Parse `bytes` from the start.
    pub fn new(bytes: &'a [u8]) -> Self {
        Parser { bytes, far: None, version: 0 }
    }

    /// The next record; `None` at the end of the bytes.
    pub fn next_event(&mut self) -> Option<Result<Event<'a, F>, ReplayError>> {
        if self.bytes.is_empty() {
            return None;
        }
        let r = self.parse();
        if r.is_err() {
            // Stop after the first error: the rest of the bytes cannot be trusted.
            self.bytes = &[];
        }
        Some(r)
    }

    fn parse(&mut self) -> Result<Event<'a, F>, ReplayError> {
        let (raw, used) = read_frame(self.bytes)?;
        self.bytes = &self.bytes[used..];
        let mut r = Reader::new(raw.payload);
        let ev = match raw.kind {
            kind::HEADER => {
                let h = get_header(&mut r)?;
                self.version = VERSION;
                Event::Header(h)
            }
            kind::ROW => Event::Row(get_row(&mut r)?),
            kind::LIGHT => {
                let s = get_light_setup(&mut r, read_frustum)?;
                self.far = Some(FarDistance::new(s.far).ok_or(ReplayError::BadFar)?);
                Event::Light(s)
            }
            kind::INJECT => Event::Inject(get_beam(&mut r, self.far.ok_or(ReplayError::NoLightSetup)?)?),
            kind::RECV => {
                let port = port_of(r.u8()?)?;
                let frame = r.take(r.remaining())?;
                Event::Recv { port, frame }
            }
            kind::STEP => Event::Step(r.u32()?),
            kind::GRANT => Event::Grant(port_of(r.u8()?)?),
            kind::SHADE => Event::Shade(get_shade_setup(&mut r)?),
            kind::END => Event::End,
            kind::SHADOW => Event::Shadow(rays::get_shadow_setup(&mut r)?),
            kind::REFLECT => Event::Reflect(rays::get_reflect_setup(&mut r)?),
            kind::SHADOW_ANSWER => Event::ShadowAnswer(r.u8()?),
            kind::REFLECT_ANSWER => rays::get_reflect_answer(&mut r)?,
            kind::REFUSED => Event::Refused,
            kind::TAKE => rays::get_take(&mut r)?,
            kind::PHASE_END => Event::PhaseEnd,
            kind::TRIANGLE => Event::Triangle(get_triangle(&mut r)?),
            kind::NEIGHBOUR_CONTACT => Event::NeighbourContact(get_neighbour_contact(&mut r)?),
            k => return Err(DecodeError::UnknownKind(k).into()),
        };
        r.finish()?;
        Ok(ev)
    }
}

/// A triangle record's payload ([`kind::TRIANGLE`]): nine `i32` vertex coordinates, refused
/// beyond the bit budget of [`Triangle::new`].
pub fn get_triangle(r: &mut Reader<'_>) -> Result<Triangle, DecodeError> {
    let mut v = [[0i32; 3]; 3];
    for c in v.iter_mut().flatten() {
        *c = r.i32()?;
    }
    Triangle::new(v).ok_or(DecodeError::BadValue("triangle vertex beyond the bit budget"))
}

/// A neighbour-contact record's payload ([`kind::NEIGHBOUR_CONTACT`]): 0 or 1.
pub fn get_neighbour_contact(r: &mut Reader<'_>) -> Result<bool, DecodeError> {
    match r.u8()? {
        b @ (0 | 1) => Ok(b == 1),
        _ => Err(DecodeError::BadValue("a neighbour contact answer is 0 or 1")),
    }
}

/// The records one by one ([`Parser::next_event`]), ending after the first error.
impl<'a, F: FracBits> Iterator for Parser<'a, F> {
    type Item = Result<Event<'a, F>, ReplayError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_event()
    }
}

/// CRC-64/XZ, the digest of a cell's outputs and final state.
pub static CRC64: crc::Crc<u64> = crc::Crc::<u64>::new(&crc::CRC_64_XZ);

/// Folds a cell's outputs and final state into a digest (the same bytes on host and MCU).
pub struct Digester {
    digest: crc::Digest<'static, u64>,
}

impl Default for Digester {
    fn default() -> Self {
        Self::new()
    }
}

struct DigestSink<'d>(&'d mut crc::Digest<'static, u64>);

impl ByteSink for DigestSink<'_> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        self.0.update(bytes);
        Ok(())
    }
}

impl Digester {
    /// An empty digest.
    pub fn new() -> Self {
        Digester { digest: CRC64.digest() }
    }

    fn sink(&mut self) -> DigestSink<'_> {
        DigestSink(&mut self.digest)
    }

    /// The cell forwarded a row packet east (after stepping it).
    pub fn forwarded(&mut self, p: &RowPacket) {
        let mut s = self.sink();
        let _ = s.u8(b'F');
        let _ = put_row(&mut s, p);
    }

    /// The cell sent a frame on `port`.
    pub fn sent(&mut self, port: Port, frame: &[u8]) {
        let mut s = self.sink();
        let _ = s.u8(b'S');
        let _ = s.u8(port.index() as u8);
        let _ = s.put(frame);
    }

    /// The cell sent a beam on `port`: [`Digester::sent`] of its frame (sequence number 0).
    pub fn sent_beam<F: FracBits>(&mut self, port: Port, m: &BeamMsg<F>) {
        let mut buf = [0u8; BEAM_FRAME];
        // Cannot fail: a beam frame has a fixed size.
        if let Ok(len) = wire::Message::Beam(*m).emit(0, &mut buf) {
            self.sent(port, &buf[..len]);
        }
    }

    /// One compute cycle's result.
    pub fn step(&mut self, r: Step) {
        let code = match r {
            Step::Idle => 0,
            Step::Processed => 1,
            Step::Blocked => 2,
            Step::Held => 3,
        };
        let _ = self.sink().put(&[b'C', code]);
    }

    /// The cell's final state: dexels, lit runs, counters, pixel.
    pub fn state<F: FracBits, const D: usize, const FA: usize, const OB: usize, const L: usize>(
        &mut self,
        cell: &Cell<D>,
        light: &LightCell<F, FA, OB, L>,
        px: Option<Pixel>,
    ) {
        let mut s = self.sink();
        let _ = s.u8(b'E');
        for d in cell.store.dexels() {
            let _ = (s.u16(d.span.lo), s.u16(d.span.hi), s.u32(d.facet), s.u16(d.material), s.u16(d.normal.0));
            let _ = (s.u32(d.plane.id), s.u32(d.plane.e as u32));
        }
        let k = cell.counters;
        let _ = (s.u32(cell.store.overflows()), s.u32(cell.store.lost_voxels()));
        let _ = (s.u32(k.packets), s.u32(k.spans_computed), s.u32(k.voxels_shared));
        for r in light.lit.runs() {
            let _ = (s.u16(r.lo), s.u16(r.hi), s.u32(r.mask));
        }
        let c = light.counters;
        let _ = (s.u64(c.processed), s.u64(c.blocked_cycles), s.u16(c.peak_fifo), s.u32(c.max_layer));
        let _ = (s.u64(c.rays_absorbed), s.u64(c.rays_exited), s.u64(c.sent), s.u32(c.lit_overflows), s.u64(c.merged));
        let _ = (s.u16(light.fifo.len() as u16), s.u8(light.busy() as u8));
        if let Some(v) = &cell.visible {
            let _ = (s.u8(b'V'), s.u64(v.num as u64), s.u64(v.den as u64), s.u32(v.facet), s.u16(v.material));
            let _ = (s.u32(v.plane.id), s.u32(v.plane.e as u32), s.u32(v.z_v as u32));
        }
        let _ = s.u32(light.visible_lit);
        match px {
            Some(p) => {
                let _ = (s.u8(1), s.put(&p.rgb), s.u32(p.lit), s.u16(p.z));
            }
            None => {
                let _ = s.u8(0);
            }
        }
    }

    /// The digest.
    pub fn finish(self) -> u64 {
        self.digest.finalize()
    }
}

/// What a replay did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplayStats {
    /// Records read.
    pub records: u32,
    /// Row packets processed.
    pub rows: u32,
    /// Beams and rays received (links and emitter).
    pub received: u32,
    /// Compute cycles (of every phase).
    pub steps: u32,
    /// Frames sent (beams and rays).
    pub sent: u32,
    /// Answers the cell's router delivered (ray phases).
    pub answers: u32,
}

/// A [`Link`] whose neighbour is ready iff it is the granted one; a send is taken at once (its
/// frame goes to the digest through [`link::drain_outputs`]'s callback).
struct GrantLink(bool);

impl<F: FracBits> Link<F> for GrantLink {
    type Error = core::convert::Infallible;
    const LOSSLESS: bool = true;
    fn ready(&mut self, _: &()) -> Result<bool, Self::Error> {
        Ok(self.0)
    }
    fn send(&mut self, _: u64, _: &BeamMsg<F>, _: &mut ()) -> Result<Sent, Self::Error> {
        Ok(Sent::TAKEN)
    }
}

/// A fresh cell driven through a trace: `D` dexels, FIFO `FA`, output buffers `OB`, `L` lit
/// runs (they must equal the trace header's); for the ray phases ([`rays`]) `SFA` shadow rays,
/// and `RFA` rays per class, `W` wait entries and `S` queued answers in the reflection cell
/// (they must equal the phase's setup record; by default the capacities of [`crate::cell`]).
pub struct Replayer<
    F: FracBits,
    const D: usize,
    const FA: usize,
    const OB: usize,
    const L: usize,
    const SFA: usize = SHADOW_FA_CAP,
    const RFA: usize = REFLECT_FA_CAP,
    const W: usize = WAIT_CAP,
    const S: usize = SEND_CAP,
> {
    /// The loading state.
    pub cell: Cell<D>,
    /// The lighting state.
    pub light: LightCell<F, FA, OB, L>,
    /// The cell's activity counter (its share of the global detector).
    pub activity: Activity,
    /// What was replayed.
    pub stats: ReplayStats,
    /// The pixel, once shaded.
    pub pixel: Option<Pixel>,
    /// The ray phase running, with its cell.
    pub rays: Rays<SFA, RFA, W, S>,
    /// What the classic shadow-ray phases lit: the sources whose rays reached the visible
    /// surface, and the lit rule (`None`: no classic phase ran; the pixel reads the lit store).
    pub shadow_lit: Option<(SourceMask, LitRule)>,
    /// Under exact occluders, the column's triangles and target ray for the current source.
    #[cfg(feature = "exact-occluders")]
    column: TraceColumn,
    setup: Option<LightSetup>,
    shade: Option<ShadeSetup>,
    depth: u32,
    started: bool,
    ended: bool,
    order: SplitOrder,
    digest: Digester,
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
    > Default for Replayer<F, D, FA, OB, L, SFA, RFA, W, S>
{
    fn default() -> Self {
        Self::new()
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
    /// Before the header. A firmware builds its one replaying cell once and starts each trace
    /// over in place ([`Replayer::reset`]): the cell is a third of its RAM.
    pub fn new() -> Self {
        Replayer {
            cell: Cell::new(0, 0),
            light: LightCell::new(0, 0),
            activity: Activity::new(),
            stats: ReplayStats::default(),
            pixel: None,
            rays: Rays::Idle,
            shadow_lit: None,
            #[cfg(feature = "exact-occluders")]
            column: TraceColumn::new(),
            setup: None,
            shade: None,
            depth: 0,
            started: false,
            ended: false,
            order: SplitOrder::default(),
            digest: Digester::new(),
        }
    }

    /// Back to the state of [`Replayer::new`], in place, field by field (no cell-sized
    /// temporary: on a firmware the stack is what the static cell leaves of the RAM).
    pub fn reset(&mut self) {
        let Replayer {
            cell,
            light,
            activity,
            stats,
            pixel,
            rays,
            shadow_lit,
            #[cfg(feature = "exact-occluders")]
            column,
            setup,
            shade,
            depth,
            started,
            ended,
            order,
            digest,
        } = self;
        *cell = Cell::new(0, 0);
        *light = LightCell::new(0, 0);
        *activity = Activity::new();
        *stats = ReplayStats::default();
        *rays = Rays::Idle;
        (*pixel, *shadow_lit, *setup, *shade) = (None, None, None, None);
        #[cfg(feature = "exact-occluders")]
        column.clear();
        (*depth, *started, *ended, *order) = (0, false, false, SplitOrder::default());
        *digest = Digester::new();
    }

    /// The header this build expects for cell (x, y).
    pub fn header(x: Coord, y: Coord, depth: u32) -> Header {
        Header { x, y, depth, frac_bits: F::U32 as u8, dexels: D as u16, fifo: FA as u16, out: OB as u8, lit: L as u16 }
    }

    fn accept(&mut self, m: BeamMsg<F>) -> Result<(), ReplayError> {
        let merge = self.setup.ok_or(ReplayError::NoLightSetup)?.merge;
        let fa = self.setup.map_or(0, |s| s.fa as usize);
        if !self.light.can_accept(fa) {
            return Err(ReplayError::FifoFull);
        }
        self.stats.received += 1;
        self.light.accept(m, merge, &self.activity).map_err(|_| ReplayError::FifoFull)
    }

    /// The link receive path: decode a frame off link `port` and put its beam into the FIFO.
    /// On an MCU this runs in the link's receive interrupt.
    /// A ray frame goes into the ray phase's cell instead ([`rays`]).
    pub fn receive_frame(&mut self, _port: Port, frame: &[u8]) -> Result<(), ReplayError> {
        let raw = rays::single_frame(frame)?;
        if matches!(raw.kind, wire::KIND_SHADOW_RAY | wire::KIND_REFLECT_RAY) {
            return self.receive_ray(raw);
        }
        let far = FarDistance::new(self.setup.ok_or(ReplayError::NoLightSetup)?.far).ok_or(ReplayError::BadFar)?;
        match Frame::<F>::parse_payload(raw, far)?.msg {
            wire::Message::Beam(m) => self.accept(m),
            _ => Err(DecodeError::BadValue("not a beam frame").into()),
        }
    }

    /// A neighbour took the head of output buffer `port`: send it over `links` (only that
    /// link's neighbour is ready).
    pub fn grant<K: Link<F>>(&mut self, port: Port, links: &mut [K; 8]) -> Result<(), ReplayError> {
        if self.light.out.is_empty(port) {
            return Err(ReplayError::NothingToSend);
        }
        let digest = &mut self.digest;
        let mut sent = 0;
        // The link cycle: a trace carries no clock, the cell's step count stands in for it.
        link::drain_outputs(&mut self.light, links, self.stats.steps as u64, |p, m| {
            digest.sent_beam(p, m);
            sent += 1;
        })
        .map_err(|_| ReplayError::Link)?;
        self.stats.sent += sent;
        if sent == 1 {
            Ok(())
        } else {
            Err(ReplayError::Link)
        }
    }

    /// Apply one record. `Recv` goes through [`Replayer::receive_frame`], `Grant` through
    /// [`Replayer::grant`] with in-memory links and `Take` through [`Replayer::take_ray`]; a
    /// firmware routes them through its interrupt and its `embedded-hal` links instead.
    pub fn apply(&mut self, ev: Event<'_, F>) -> Result<(), ReplayError> {
        self.stats.records += 1;
        if self.ended {
            return Err(ReplayError::BadEnd);
        }
        // A target's contact segment needs its neighbours' answers before anything else happens.
        #[cfg(feature = "exact-occluders")]
        if self.column.awaiting && !matches!(ev, Event::Triangle(_) | Event::NeighbourContact(_)) {
            return Err(DecodeError::BadValue("a light record's target lacks its neighbours' contact answers").into());
        }
        match ev {
            Event::Header(h) => return self.start(h),
            _ if !self.started => return Err(ReplayError::BadHeader),
            Event::Row(mut p) => {
                self.stats.rows += 1;
                if self.cell.load_step(&mut p, self.depth) {
                    self.digest.forwarded(&p);
                }
            }
            Event::Light(s) => {
                // The host restarts the per-source peaks at each source.
                self.light.counters.max_layer = 0;
                self.light.counters.peak_fifo = 0;
                #[cfg(feature = "exact-occluders")]
                self.column.start::<F, D>(&self.cell, &s)?;
                self.setup = Some(s);
                self.rays = Rays::Idle;
            }
            Event::Triangle(t) => self.triangle(t)?,
            Event::NeighbourContact(b) => self.neighbour_contact(b)?,
            Event::Inject(m) => self.accept(m)?,
            Event::Recv { port, frame } => self.receive_frame(port, frame)?,
            Event::Step(n) if !matches!(self.rays, Rays::Idle) => {
                for _ in 0..n {
                    self.ray_cycle(true)?;
                }
            }
            Event::Step(n) => self.light_cycles(n)?,
            Event::Grant(p) => {
                let mut links: [GrantLink; 8] = core::array::from_fn(|i| GrantLink(i == p.index()));
                self.grant(p, &mut links)?;
            }
            Event::Shade(s) => self.shade(s),
            Event::End => self.ended = true,
            Event::Shadow(s) => self.start_shadow(s)?,
            Event::Reflect(s) => self.start_reflect(s)?,
            ev @ (Event::ShadowAnswer(_) | Event::ReflectAnswer { .. }) => self.deliver(ev)?,
            Event::Refused => self.ray_cycle(false)?,
            Event::Take { class, port } => self.take_ray(class, port, |_| {})?,
            Event::PhaseEnd => self.end_phase()?,
        }
        Ok(())
    }

    /// The header record: the cell it is for, after checking the capacities.
    fn start(&mut self, h: Header) -> Result<(), ReplayError> {
        if self.started {
            return Err(ReplayError::BadHeader);
        }
        if h != Self::header(h.x, h.y, h.depth) {
            return Err(ReplayError::CapacityMismatch);
        }
        self.cell = Cell::new(h.x, h.y);
        self.light = LightCell::new(h.x, h.y);
        self.depth = h.depth;
        self.started = true;
        Ok(())
    }

    /// The neighbours' answers to the column's contact query (exact occluders, a diffusion's
    /// target with a contact segment only, once, after the light record's triangles and before
    /// anything else: a trace without them does not replay).
    fn neighbour_contact(&mut self, shadowed: bool) -> Result<(), ReplayError> {
        let bad = DecodeError::BadValue("a neighbour contact answer without a target's contact segment");
        if !matches!(self.rays, Rays::Idle) || !self.setup.ok_or(ReplayError::NoLightSetup)?.rule.needs_triangles() {
            return Err(bad.into());
        }
        #[cfg(feature = "exact-occluders")]
        return self.column.answer(shadowed);
        #[cfg(not(feature = "exact-occluders"))]
        {
            let _ = shadowed;
            Err(bad.into())
        }
    }

    /// A triangle the column keeps for the current source (exact occluders only): its
    /// diffusion, or its classic shadow rays.
    fn triangle(&mut self, t: Triangle) -> Result<(), ReplayError> {
        let rule = match &self.rays {
            rays::Rays::Shadow(_, s) => s.env.rule,
            _ => self.setup.ok_or(ReplayError::NoLightSetup)?.rule,
        };
        if !rule.needs_triangles() {
            return Err(DecodeError::BadValue("a triangle outside exact occluders").into());
        }
        #[cfg(feature = "exact-occluders")]
        return self.column.push(t);
        #[cfg(not(feature = "exact-occluders"))]
        {
            let _ = t;
            Err(DecodeError::BadValue("a triangle outside exact occluders").into())
        }
    }

    /// `n` compute cycles of the light cell.
    fn light_cycles(&mut self, n: u32) -> Result<(), ReplayError> {
        let setup = self.setup.ok_or(ReplayError::NoLightSetup)?;
        let order = self.order;
        #[allow(unused_mut)]
        let mut env = setup.env(&order)?;
        #[cfg(feature = "exact-occluders")]
        if setup.rule.needs_triangles() {
            env.occluders = Some(&self.column);
        }
        for _ in 0..n {
            let r = self.light.step(&self.cell, &env, &self.activity);
            self.digest.step(r);
            self.stats.steps += 1;
        }
        Ok(())
    }

    /// The shading record: the pixel, from what the classic shadow rays lit (the visible
    /// surface only) or from the lit store; its inputs are kept for the reflection phase.
    fn shade(&mut self, s: ShadeSetup) {
        let (mats, lights) = (&s.materials, &s.lights);
        self.pixel = match self.shadow_lit {
            Some((m, rule)) => cell_pixel(rule, &self.cell, |_| m, m, mats, lights, &s.params),
            None => {
                let rule = self.setup.map_or(LitRule::Thesis, |l| l.rule);
                let (lit, visible) = (&self.light.lit, self.light.visible_lit);
                cell_pixel(rule, &self.cell, |z: Depth| lit.mask_at(z), visible, mats, lights, &s.params)
            }
        };
        self.shade = Some(s);
    }

    /// Whether the end record was applied.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// The digest of the outputs and the final state.
    pub fn finish(mut self) -> Result<u64, ReplayError> {
        self.take_digest()
    }

    /// [`Replayer::finish`] in place: the digest (the replayer's own starts over).
    pub fn take_digest(&mut self) -> Result<u64, ReplayError> {
        if !self.ended {
            return Err(ReplayError::BadEnd);
        }
        let mut digest = core::mem::take(&mut self.digest);
        digest.state(&self.cell, &self.light, self.pixel);
        Ok(digest.finish())
    }
}

/// The column's exact occluders as a cell driven by host records holds them
/// ([`crate::occluder`]): the triangles the host hands it after each light record
/// ([`Event::Triangle`]), the target ray it computes from its own visible surface when the
/// record arrives ([`crate::receiver::target`], as the host's cells do), and its neighbours'
/// contact answer ([`Event::NeighbourContact`]). The replayer keeps one; so does the
/// production cell image, which gets the same records over its host link.
///
/// **Invariant: while [`TraceColumn::awaiting`] is true (a target with a contact segment whose
/// neighbours have not answered) the cell must not step its light: its target ray is not
/// final.** The store holds at most [`crate::cell::TRIANGLE_CAP`] triangles; one more is
/// refused ([`ReplayError::CapacityMismatch`]), never dropped silently.
#[cfg(feature = "exact-occluders")]
#[derive(Debug)]
pub struct TraceColumn {
    triangles: crate::occluder::TriangleStore<{ crate::cell::TRIANGLE_CAP }>,
    target: Option<crate::receiver::Target>,
    /// The target has a contact segment and its neighbours have not answered yet.
    awaiting: bool,
}

#[cfg(feature = "exact-occluders")]
impl Default for TraceColumn {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(feature = "exact-occluders")]
impl TraceColumn {
    /// No triangles, no target.
    pub const fn new() -> Self {
        TraceColumn { triangles: crate::occluder::TriangleStore::new(), target: None, awaiting: false }
    }

    fn clear(&mut self) {
        self.triangles = crate::occluder::TriangleStore::new();
        self.target = None;
        self.awaiting = false;
    }

    /// A source's diffusion starts: no triangles yet, and the target ray of `cell`'s visible
    /// surface under exact occluders.
    pub fn start<F: FracBits, const D: usize>(&mut self, cell: &Cell<D>, s: &LightSetup) -> Result<(), ReplayError> {
        self.clear();
        if s.rule.needs_triangles() {
            let far = FarDistance::new(s.far).ok_or(ReplayError::BadFar)?;
            self.target = cell
                .visible
                .as_ref()
                .and_then(|v| crate::receiver::target::<F>(cell.x as i32, cell.y as i32, v, &s.source, far));
            self.awaiting = self.target.is_some_and(|t| t.contact.is_some());
        }
        Ok(())
    }

    /// Whether the target waits for its neighbours' contact answer (see the invariant).
    pub fn awaiting(&self) -> bool {
        self.awaiting
    }

    /// One more triangle for the current source, refused past the store's capacity.
    pub fn push(&mut self, t: Triangle) -> Result<(), ReplayError> {
        self.triangles.push(t).then_some(()).ok_or(ReplayError::CapacityMismatch)
    }

    /// The neighbours' answers to the column's contact query, OR-ed: once, while awaiting.
    pub fn answer(&mut self, shadowed: bool) -> Result<(), ReplayError> {
        let bad = DecodeError::BadValue("a neighbour contact answer without a target's contact segment");
        let t = self.target.filter(|_| self.awaiting).ok_or(bad)?;
        self.target = Some(t.with_neighbour_answers(shadowed));
        self.awaiting = false;
        Ok(())
    }
}

#[cfg(feature = "exact-occluders")]
impl crate::occluder::ColumnOccluders for TraceColumn {
    fn triangles(&self, _x: Coord, _y: Coord) -> &[Triangle] {
        self.triangles.triangles()
    }

    fn target(&self, _x: Coord, _y: Coord) -> Option<&crate::receiver::Target> {
        self.target.as_ref()
    }
}

/// Replay a whole trace with in-memory links: the host's reference replay.
pub fn replay<F: FracBits, const D: usize, const FA: usize, const OB: usize, const L: usize>(
    bytes: &[u8],
) -> Result<(u64, ReplayStats), ReplayError> {
    let mut r = Replayer::<F, D, FA, OB, L>::new();
    let mut p = Parser::<F>::new(bytes);
    while let Some(ev) = p.next_event() {
        r.apply(ev?)?;
    }
    let stats = r.stats;
    Ok((r.finish()?, stats))
}

//! §3.9, §4.4 — the bytes a link carries: framed inter-cell messages with a CRC.
//!
//! # Frame layout (all integers little-endian)
//!
//! ```text
//!   kind u8 | len u16 | payload (len bytes) | crc u32
//! ```
//!
//! `crc` is CRC-32/ISO-HDLC (the `crc` crate's `CRC_32_ISO_HDLC`, the Ethernet/zlib one) over
//! `kind`, `len` and the payload. A frame whose CRC does not match is never applied: decoding
//! returns [`DecodeError::BadCrc`]. The same framing carries the inter-cell messages
//! ([`Message`]) and the records of a cell trace ([`crate::trace`]).
//!
//! Message payloads:
//!
//! | kind | message | payload | bytes on the wire |
//! |---|---|---|---|
//! | `0x10` | [`Message::Row`] (a facet row packet, §3.9) | seq u8, facet u32, material u16, normal u16, plane (id u32, nx i16, ny i16, nz i32, m u64), box 6×u16, a c t u 4×i64, edge count u8, edges (a i32, c i32, g i64, off i32) | 81 + 20·edges |
//! | `0x20` | [`Message::Beam`] (§4.4) | seq u8, frac bits u8, source u16, direction u8 (bit 7: terminal, bit 6: after an empty voxel, bit 5: after the outside of a plane, [`crate::lit`]), layer u32, u_lo u_hi v_lo v_hi 4×i32, z u16 | 27 + 7 = 34 |
//! | `0x30` | [`Message::Ack`] | seq u8 | 1 + 7 = 8 |
//! | `0x21` | [`RayMsg::Shadow`] (a classic shadow ray, §4.1.2) | seq u8, the ray ([`put_shadow_ray`]) | 61 … 117 + 7 (117: the plane rule's segment) |
//! | `0x22` | [`RayMsg::Reflect`] (a reflected ray, §1.3.2) | seq u8, the ray ([`put_reflect_ray`]) | 76 … 88 + 7 |
//! | `0x40` | [`TokenFrame`] (the termination token between boards, [`crate::termination`]) | seq u8, phase u16, sum i32, colour u8 (0 white, 1 black) | 8 + 7 = 15 |
//!
//! Ray frames ([`RayMsg`]) are not [`Message`]s: the host grid moves rays between its cells as
//! values and the production cell does not run the ray phases yet; cell traces carry them
//! ([`crate::trace`]), and a cell replaying one decodes them off its links like beams.
//! A token is not a [`Message`]: cells never see one, a board's link driver dispatches on the
//! raw frame's kind ([`read_frame`]), and an image that runs no detector (the production cell,
//! whose flash budget is counted to the byte) carries no token decoder. The board exercises'
//! own frames, kinds `0x60`–`0x72`, are listed in [`board`].
//!
//! `seq` is the link-level sequence number (for acknowledgement and retransmission); a trace
//! leaves it 0.
//!
//! # Representation, parse and emit
//!
//! As in smoltcp, a message has a high-level representation, [`Message`] (with its sequence
//! number, [`Frame`]), that is parsed from bytes ([`Frame::parse`]: CRC, kind, length and
//! every field checked) and emitted into bytes ([`Message::emit`], [`Frame::emit`];
//! [`Message::buffer_len`] says how many). The field helpers ([`put_beam`], [`get_row`] …) and
//! the framing ([`write_frame`], [`read_frame`]) are shared with the cell trace format.
//! The [`crate::link`] seam decides who carries the bytes.
//!
//! ```
//! use cell_core::beam::{frac::U0, Beam, Direction, FarDistance, Source, SourceId};
//! use cell_core::light::BeamMsg;
//! use cell_core::wire::{DecodeError, Frame, Message, MAX_FRAME};
//!
//! let source = Source::at_voxel(SourceId(3), [1, 2, 3]).unwrap();
//! let far = FarDistance::<U0>::new(7).unwrap();
//! let msg = Message::Beam(BeamMsg::new(Beam::initial(&source, Direction::PosZ, far), 1));
//!
//! let mut buf = [0u8; MAX_FRAME];
//! let len = msg.emit(5, &mut buf).unwrap();
//! assert_eq!(len, msg.buffer_len());
//! assert_eq!(&buf[..3], &[0x20, 27, 0]); // kind, payload length (little-endian)
//!
//! let (frame, used) = Frame::parse(&buf[..len], far).unwrap();
//! assert_eq!((frame.seq, &frame.msg, used), (5, &msg, len));
//!
//! buf[4] ^= 0x01; // one bit flipped on the wire
//! assert_eq!(Frame::<U0>::parse(&buf[..len], far).unwrap_err(), DecodeError::BadCrc);
//! ```
//!
//! # No panic on malformed input
//!
//! Every decoder returns a [`DecodeError`] value for truncated, over-long, corrupted or
//! out-of-range input: a beam must satisfy [`Beam::new`] (ranges within the far square, layer
//! ≤ D) and carry this build's fraction bits; a row packet's coefficients must lie within the
//! bit budget of [`crate::voxelize`] (so that a cell's arithmetic on it stays in `i64`).

use heapless::Vec;

use crate::beam::{Beam, Direction, FarDistance, FarOffset, FracBits, Layer, RayRange, SourceId};
use crate::dexel::FacetTag;
use crate::facet::{EdgeOff, FacetBox, PipeEdge, PipelinePacket, RowEdge, RowPacket, MAX_EDGES};
use crate::light::BeamMsg;
use crate::normal::NormalCode;
use crate::occluder::COORD_LIMIT;
use crate::plane::FacetPlane;
use crate::ray::{ExactWalk, Line, PlaneWalk, RayWalk, ShadowRay, LINE_BYTES, MAX_COORD, MAX_SPAN};
use crate::receiver::POINT_UNITS;
use crate::reflect::ReflectRay;
use crate::termination::Token;
use crate::voxelize::{worst_case_g, worst_case_t, MAX_LATTICE_Q, MAX_LATTICE_SPAN};

/// CRC-32/ISO-HDLC (computed as [`Crc32Table`] says).
pub const CRC32: crc::Crc<u32, Crc32Table> = crc::Crc::<u32, Crc32Table>::new(&crc::CRC_32_ISO_HDLC);

/// How [`CRC32`] computes: with the `crc-table` feature (a default one) from a 256-entry table
/// (1 KiB of read-only data, one lookup per byte); without it bit by bit (no table, eight steps
/// per byte), for a cell whose flash budget cannot hold the table (docs/FIRMWARE.md, "Flash
/// budget"). The checksums are the same.
#[cfg(feature = "crc-table")]
pub type Crc32Table = crc::Table<1>;
/// See the other definition.
#[cfg(not(feature = "crc-table"))]
pub type Crc32Table = crc::NoTable;

/// Bytes before the payload: kind and length.
pub const HEADER: usize = 3;
/// Bytes after the payload: the CRC.
pub const TRAILER: usize = 4;
/// Frame kind of a row packet.
pub const KIND_ROW: u8 = 0x10;
/// Frame kind of a beam.
pub const KIND_BEAM: u8 = 0x20;
/// Frame kind of an acknowledgement.
pub const KIND_ACK: u8 = 0x30;
/// Frame kind of a classic shadow ray ([`RayMsg::Shadow`]).
pub const KIND_SHADOW_RAY: u8 = 0x21;
/// Frame kind of a reflected ray ([`RayMsg::Reflect`]).
pub const KIND_REFLECT_RAY: u8 = 0x22;
/// The longest ray frame: a shadow ray under the plane rule with an 18-connected line's
/// pending voxel (seq 1, line [`LINE_BYTES`], emitter to grace 14, plane state 52).
pub const MAX_RAY_FRAME: usize = HEADER + 1 + LINE_BYTES + 14 + 52 + TRAILER;
/// Frame kind of a termination token.
pub const KIND_TOKEN: u8 = 0x40;
/// Payload bytes of a termination token (with its `seq`).
pub const TOKEN_PAYLOAD: usize = 8;
/// Payload bytes of a beam message (with its `seq`).
pub const BEAM_PAYLOAD: usize = 27;
/// Payload bytes of a row packet without edges (with its `seq`).
pub const ROW_PAYLOAD_BASE: usize = 74;
/// Payload bytes per contour edge of a row packet.
pub const ROW_EDGE_BYTES: usize = 20;
/// The longest message frame (a row packet with [`MAX_EDGES`] edges).
pub const MAX_FRAME: usize = HEADER + ROW_PAYLOAD_BASE + MAX_EDGES * ROW_EDGE_BYTES + TRAILER;

pub use crate::bytes::{ByteSink, CountingSink, DecodeError, EncodeError, PutExt, Reader, SliceWriter};

/// Write one frame of `kind` whose payload `body` writes, into `buf`; returns the frame's
/// length. The payload is written in place, then the header and CRC around it.
pub fn write_frame(
    buf: &mut [u8],
    kind: u8,
    body: impl FnOnce(&mut SliceWriter<'_>) -> Result<(), EncodeError>,
) -> Result<usize, EncodeError> {
    if buf.len() < HEADER + TRAILER {
        return Err(EncodeError::BufferTooSmall);
    }
    let cap = buf.len() - TRAILER;
    let len = {
        let mut w = SliceWriter::new(&mut buf[HEADER..cap]);
        body(&mut w)?;
        w.len()
    };
    let len16 = u16::try_from(len).map_err(|_| EncodeError::PayloadTooLong)?;
    buf[0] = kind;
    buf[1..3].copy_from_slice(&len16.to_le_bytes());
    let end = HEADER + len;
    let crc = CRC32.checksum(&buf[..end]);
    buf[end..end + TRAILER].copy_from_slice(&crc.to_le_bytes());
    Ok(end + TRAILER)
}

/// Write one link frame: [`write_frame`] with the link sequence number `seq` first in the
/// payload, then what `body` writes (every message on a link: rows, beams, acks, rays, tokens).
fn write_link_frame(
    buf: &mut [u8],
    kind: u8,
    seq: u8,
    body: impl FnOnce(&mut SliceWriter<'_>) -> Result<(), EncodeError>,
) -> Result<usize, EncodeError> {
    write_frame(buf, kind, |w| {
        w.u8(seq)?;
        body(w)
    })
}

/// A frame as read off a link: its kind and its (CRC-checked) payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawFrame<'a> {
    /// Frame kind.
    pub kind: u8,
    /// Payload.
    pub payload: &'a [u8],
}

/// Read the frame at the start of `bytes`: returns it and the number of bytes it took.
pub fn read_frame(bytes: &[u8]) -> Result<(RawFrame<'_>, usize), DecodeError> {
    if bytes.len() < HEADER {
        return Err(DecodeError::Truncated);
    }
    let kind = bytes[0];
    let len = u16::from_le_bytes([bytes[1], bytes[2]]) as usize;
    let end = HEADER + len;
    let total = end + TRAILER;
    if bytes.len() < total {
        return Err(DecodeError::Truncated);
    }
    let mut crc = [0u8; TRAILER];
    crc.copy_from_slice(&bytes[end..total]);
    if CRC32.checksum(&bytes[..end]) != u32::from_le_bytes(crc) {
        return Err(DecodeError::BadCrc);
    }
    Ok((RawFrame { kind, payload: &bytes[HEADER..end] }, total))
}

/// An inter-cell message.
// A decoded message lives on the stack for the time of one frame: no point boxing the row
// packet (and no allocator on a cell).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Message<F: FracBits> {
    /// A facet row packet travelling east during loading.
    Row(RowPacket),
    /// A beam travelling to a neighbour during lighting.
    Beam(BeamMsg<F>),
    /// Acknowledges the data frame with this sequence number.
    Ack,
}

/// A message with its link-level sequence number.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame<F: FracBits> {
    /// Link sequence number (0 in traces).
    pub seq: u8,
    /// The message.
    pub msg: Message<F>,
}

/// Write a row packet's fields (payload after `seq`).
pub fn put_row<S: ByteSink + ?Sized>(w: &mut S, p: &RowPacket) -> Result<(), EncodeError> {
    w.u32(p.tag.facet)?;
    w.u16(p.tag.material)?;
    w.u16(p.tag.normal.0)?;
    let pl = p.tag.plane;
    w.u32(pl.id)?;
    w.put(&pl.nx.to_le_bytes())?;
    w.put(&pl.ny.to_le_bytes())?;
    w.i32(pl.nz)?;
    w.u64(pl.m)?;
    let b = p.bbox;
    for v in [b.x_min, b.x_max, b.y_min, b.y_max, b.z_min, b.z_max] {
        w.u16(v)?;
    }
    for v in [p.a, p.c, p.t, p.u] {
        w.i64(v)?;
    }
    w.u8(p.edges.len() as u8)?;
    for e in &p.edges {
        w.i32(e.a)?;
        w.i32(e.c)?;
        w.i64(e.g)?;
        w.i32(e.off)?;
    }
    Ok(())
}

fn within(v: i64, bound: i128, what: &'static str) -> Result<i64, DecodeError> {
    if (v as i128).abs() <= bound {
        Ok(v)
    } else {
        Err(DecodeError::BadValue(what))
    }
}

/// Read a row packet's fields, checking the bit budget of [`crate::voxelize`].
pub fn get_row(r: &mut Reader<'_>) -> Result<RowPacket, DecodeError> {
    let (m, q) = (MAX_LATTICE_SPAN, MAX_LATTICE_Q);
    let (facet, material, normal) = (r.u32()?, r.u16()?, NormalCode(r.u16()?));
    let plane = FacetPlane { id: r.u32()?, nx: r.u16()? as i16, ny: r.u16()? as i16, nz: r.i32()?, m: r.u64()? };
    if !plane.in_budget() {
        return Err(DecodeError::BadValue("facet plane beyond the bit budget"));
    }
    let tag = FacetTag { facet, material, normal, plane };
    let mut bx = [0u16; 6];
    for v in bx.iter_mut() {
        *v = r.u16()?;
    }
    let bbox = FacetBox { x_min: bx[0], x_max: bx[1], y_min: bx[2], y_max: bx[3], z_min: bx[4], z_max: bx[5] };
    if bbox.x_min > bbox.x_max || bbox.y_min > bbox.y_max || bbox.z_min > bbox.z_max {
        return Err(DecodeError::BadValue("empty facet box"));
    }
    let coef = 2 * q * m * m;
    let a = within(r.i64()?, coef, "plane coefficient a beyond the bit budget")?;
    let c = within(r.i64()?, coef, "plane coefficient c beyond the bit budget")?;
    let t = within(r.i64()?, worst_case_t(m, q), "t beyond the bit budget")?;
    let u = within(r.i64()?, worst_case_t(m, q), "u beyond the bit budget")?;
    let count = r.u8()? as usize;
    if count > MAX_EDGES {
        return Err(DecodeError::BadValue("more contour edges than MAX_EDGES"));
    }
    let mut edges = Vec::new();
    for _ in 0..count {
        let ea = within(r.i32()? as i64, q * m, "edge coefficient beyond the bit budget")? as i32;
        let ec = within(r.i32()? as i64, q * m, "edge coefficient beyond the bit budget")? as i32;
        let g = within(r.i64()?, worst_case_g(m, q), "edge value beyond the bit budget")?;
        let off = r.i32()?;
        if !(0..=(q * m) as i32 + EdgeOff::STRICT).contains(&off) {
            return Err(DecodeError::BadValue("edge push beyond the bit budget"));
        }
        // Cannot fail: count ≤ MAX_EDGES was checked.
        let _ = edges.push(RowEdge { a: ea, c: ec, g, off });
    }
    Ok(RowPacket { tag, bbox, a, c, t, u, edges })
}

/// Write a pipeline packet's fields: the row packet it hands its row
/// ([`PipelinePacket::to_row`], as [`put_row`] writes it), then its `b` (i64) and each edge's
/// `b` (i32), in edge order. The grid of boards (firmware `board`) sends the pipeline packets
/// that cross a board edge this way: a pipeline packet is never a cell link's frame, so it has
/// no frame kind here.
pub fn put_pipe<S: ByteSink + ?Sized>(w: &mut S, p: &PipelinePacket) -> Result<(), EncodeError> {
    put_row(w, &p.to_row())?;
    w.i64(p.b)?;
    for e in &p.edges {
        w.i32(e.b)?;
    }
    Ok(())
}

/// Read a pipeline packet's fields ([`put_pipe`]), checking the bit budget of
/// [`crate::voxelize`] as [`get_row`] does (`b` within the plane coefficients' bound, each
/// edge's `b` within the edge coefficients').
pub fn get_pipe(r: &mut Reader<'_>) -> Result<PipelinePacket, DecodeError> {
    let (m, q) = (MAX_LATTICE_SPAN, MAX_LATTICE_Q);
    let row = get_row(r)?;
    let b = within(r.i64()?, 2 * q * m * m, "plane coefficient b beyond the bit budget")?;
    let mut edges = Vec::new();
    for e in &row.edges {
        let eb = within(r.i32()? as i64, q * m, "edge coefficient beyond the bit budget")? as i32;
        // Cannot fail: as many edges as the row packet's, at most MAX_EDGES.
        let _ = edges.push(PipeEdge { a: e.a, b: eb, c: e.c, g: e.g, off: e.off });
    }
    Ok(PipelinePacket { tag: row.tag, bbox: row.bbox, a: row.a, b, c: row.c, t: row.t, u: row.u, edges })
}

/// Write a beam message's fields (payload after `seq`).
pub fn put_beam<F: FracBits, S: ByteSink + ?Sized>(w: &mut S, m: &BeamMsg<F>) -> Result<(), EncodeError> {
    let b = &m.beam;
    w.u8(F::U32 as u8)?;
    w.u16(b.source().0)?;
    w.u8(b.direction().index()
        | (b.is_terminal() as u8) << 7
        | (b.after_empty() as u8) << 6
        | (b.after_outside() as u8) << 5)?;
    w.u32(b.layer().0)?;
    for v in [b.u().lo(), b.u().hi(), b.v().lo(), b.v().hi()] {
        w.i32(v.to_bits())?;
    }
    w.u16(m.z)
}

/// Read a beam message's fields, checking them against the far distance in use.
pub fn get_beam<F: FracBits>(r: &mut Reader<'_>, far: FarDistance<F>) -> Result<BeamMsg<F>, DecodeError> {
    let f = r.u8()?;
    if f as u32 != F::U32 {
        return Err(DecodeError::FracBitsMismatch { found: f, expected: F::U32 as u8 });
    }
    let source = SourceId(r.u16()?);
    let d = r.u8()?;
    let dir = Direction::from_index(d & 0x1f).ok_or(DecodeError::BadValue("beam direction"))?;
    let layer = Layer(r.u32()?);
    let mut v4 = [FarOffset::<F>::ZERO; 4];
    for v in v4.iter_mut() {
        *v = FarOffset::<F>::from_bits(r.i32()?);
    }
    let u = RayRange::new(v4[0], v4[1]).ok_or(DecodeError::BadValue("beam u range"))?;
    let v = RayRange::new(v4[2], v4[3]).ok_or(DecodeError::BadValue("beam v range"))?;
    let beam = Beam::new(source, dir, layer, u, v, far)
        .map_err(|_| DecodeError::BadValue("beam outside D"))?
        .with_terminal(d & 0x80 != 0)
        .with_after_empty(d & 0x40 != 0)
        .with_after_outside(d & 0x20 != 0);
    Ok(BeamMsg::new(beam, r.u16()?))
}

/// Write a termination token's fields (payload after `seq`).
pub fn put_token<S: ByteSink + ?Sized>(w: &mut S, t: &Token) -> Result<(), EncodeError> {
    w.u16(t.phase)?;
    w.i32(t.count)?;
    w.u8(t.black as u8)
}

/// Read a termination token's fields.
pub fn get_token(r: &mut Reader<'_>) -> Result<Token, DecodeError> {
    let (phase, count) = (r.u16()?, r.i32()?);
    let black = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(DecodeError::BadValue("token colour")),
    };
    Ok(Token { phase, count, black })
}

/// A termination token's frame ([`KIND_TOKEN`]) with its link sequence number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TokenFrame {
    /// Link sequence number.
    pub seq: u8,
    /// The token.
    pub token: Token,
}

impl TokenFrame {
    /// Bytes of a token frame on the wire.
    pub const LEN: usize = HEADER + TOKEN_PAYLOAD + TRAILER;

    /// Emit the frame into `buf`; returns its length ([`TokenFrame::LEN`]).
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        write_link_frame(buf, KIND_TOKEN, self.seq, |w| put_token(w, &self.token))
    }

    /// Parse the token frame at the start of `bytes` (CRC, kind, length and colour checked);
    /// returns it and the bytes it took.
    pub fn parse(bytes: &[u8]) -> Result<(Self, usize), DecodeError> {
        let (raw, used) = read_frame(bytes)?;
        Ok((Self::parse_payload(raw)?, used))
    }

    /// Parse a CRC-checked frame's payload as a token.
    pub fn parse_payload(raw: RawFrame<'_>) -> Result<Self, DecodeError> {
        if raw.kind != KIND_TOKEN {
            return Err(DecodeError::UnknownKind(raw.kind));
        }
        let mut r = Reader::new(raw.payload);
        let seq = r.u8()?;
        let token = get_token(&mut r)?;
        r.finish()?;
        Ok(TokenFrame { seq, token })
    }
}

impl<F: FracBits> Message<F> {
    /// Bytes of this message's frame on the wire (header, payload with `seq`, CRC).
    pub fn buffer_len(&self) -> usize {
        HEADER
            + TRAILER
            + match self {
                Message::Row(p) => ROW_PAYLOAD_BASE + p.edges.len() * ROW_EDGE_BYTES,
                Message::Beam(_) => BEAM_PAYLOAD,
                Message::Ack => 1,
            }
    }

    /// Emit this message's frame with link sequence number `seq` into `buf`; returns its
    /// length ([`Message::buffer_len`]).
    pub fn emit(&self, seq: u8, buf: &mut [u8]) -> Result<usize, EncodeError> {
        match self {
            Message::Row(p) => write_link_frame(buf, KIND_ROW, seq, |w| put_row(w, p)),
            Message::Beam(m) => write_link_frame(buf, KIND_BEAM, seq, |w| put_beam(w, m)),
            Message::Ack => write_link_frame(buf, KIND_ACK, seq, |_| Ok(())),
        }
    }
}

impl<F: FracBits> Frame<F> {
    /// Parse the message frame at the start of `bytes` (CRC, kind, length and every field
    /// checked); returns it and the bytes it took.
    pub fn parse(bytes: &[u8], far: FarDistance<F>) -> Result<(Self, usize), DecodeError> {
        let (raw, used) = read_frame(bytes)?;
        Ok((Self::parse_payload(raw, far)?, used))
    }

    /// Parse a CRC-checked frame's payload as a message.
    pub fn parse_payload(raw: RawFrame<'_>, far: FarDistance<F>) -> Result<Self, DecodeError> {
        let mut r = Reader::new(raw.payload);
        let seq = r.u8()?;
        let msg = match raw.kind {
            KIND_ROW => Message::Row(get_row(&mut r)?),
            KIND_BEAM => Message::Beam(get_beam(&mut r, far)?),
            KIND_ACK => Message::Ack,
            k => return Err(DecodeError::UnknownKind(k)),
        };
        r.finish()?;
        Ok(Frame { seq, msg })
    }

    /// Emit this frame into `buf`; returns its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        self.msg.emit(self.seq, buf)
    }
}

/// A ray of the ray phases on a link: a classic shadow ray (§4.1.2) or a reflected ray (§1.3.2).
/// Its frame carries the whole state of the ray (its incremental line included), as a cell
/// holds it: the receiving cell walks on from where the sender stopped.
///
/// ```
/// use cell_core::ray::{Connectivity, ShadowRay, Q};
/// use cell_core::wire::{read_frame, DecodeError, RayMsg, MAX_RAY_FRAME};
///
/// // A shadow ray from voxel (2, 3, 4) toward a source at voxel (20, 9, 30), one step along.
/// let mut ray = ShadowRay::new([2, 3, 4], [20 * Q, 9 * Q, 30 * Q], Connectivity::Six, 7).unwrap();
/// ray.line.step();
/// let mut buf = [0u8; MAX_RAY_FRAME];
/// let len = RayMsg::Shadow(ray).emit(5, &mut buf).unwrap();
/// let (raw, used) = read_frame(&buf[..len]).unwrap();
/// assert_eq!((used, RayMsg::parse_payload(raw)), (len, Ok((5, RayMsg::Shadow(ray)))));
/// // A byte changed on the wire: the frame's CRC refuses it.
/// buf[len / 2] ^= 1;
/// assert_eq!(read_frame(&buf[..len]).err(), Some(DecodeError::BadCrc));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RayMsg {
    /// A shadow ray walking toward its source.
    Shadow(ShadowRay),
    /// A reflected ray.
    Reflect(ReflectRay),
}

impl RayMsg {
    /// Emit this ray's frame with link sequence number `seq` into `buf`; returns its length
    /// (at most [`MAX_RAY_FRAME`]).
    pub fn emit(&self, seq: u8, buf: &mut [u8]) -> Result<usize, EncodeError> {
        match self {
            RayMsg::Shadow(ray) => write_link_frame(buf, KIND_SHADOW_RAY, seq, |w| put_shadow_ray(w, ray)),
            RayMsg::Reflect(ray) => write_link_frame(buf, KIND_REFLECT_RAY, seq, |w| put_reflect_ray(w, ray)),
        }
    }

    /// Parse a CRC-checked ray frame's payload; returns the sequence number and the ray.
    pub fn parse_payload(raw: RawFrame<'_>) -> Result<(u8, Self), DecodeError> {
        let mut r = Reader::new(raw.payload);
        let seq = r.u8()?;
        let ray = match raw.kind {
            KIND_SHADOW_RAY => RayMsg::Shadow(get_shadow_ray(&mut r)?),
            KIND_REFLECT_RAY => RayMsg::Reflect(get_reflect_ray(&mut r)?),
            k => return Err(DecodeError::UnknownKind(k)),
        };
        r.finish()?;
        Ok((seq, ray))
    }
}

/// Write a shadow ray's fields (payload after `seq`): its line ([`Line::put`]), emitter 2×u16,
/// facet u32, emitter z i32, flags u8 (bit 0 fresh, bit 1 surface, bit 2 plane state, bit 3
/// exact state, bit 4 its column untested, bit 5 its segment's near end), grace u8; under the
/// plane rule A 3×i32, D 3×i32, own plane u32, t_in 2×i32, own g 2×i64; under exact occluders
/// the source 3×i32 and the near end 3×i64.
pub fn put_shadow_ray<S: ByteSink + ?Sized>(w: &mut S, ray: &ShadowRay) -> Result<(), EncodeError> {
    ray.line.put(w)?;
    w.u16(ray.emitter[0])?;
    w.u16(ray.emitter[1])?;
    w.u32(ray.facet)?;
    w.i32(ray.emitter_z)?;
    let state = match &ray.walk {
        RayWalk::Thesis => 0,
        RayWalk::Plane(_) => 4,
        RayWalk::Exact(e) => 8 | (e.untested as u8) << 4 | (e.near.is_some() as u8) << 5,
    };
    w.u8(ray.fresh as u8 | (ray.surface as u8) << 1 | state)?;
    w.u8(ray.grace)?;
    match &ray.walk {
        RayWalk::Thesis => {}
        RayWalk::Plane(p) => {
            p.a.iter().chain(&p.d).try_for_each(|&c| w.i32(c))?;
            w.u32(p.own)?;
            w.i32(p.t_in.0)?;
            w.i32(p.t_in.1)?;
            w.i64(p.own_g.0)?;
            w.i64(p.own_g.1)?;
        }
        RayWalk::Exact(e) => {
            e.source.iter().try_for_each(|&c| w.i32(c))?;
            e.near.iter().flatten().try_for_each(|&c| w.i64(c))?;
        }
    }
    Ok(())
}

/// Read a shadow ray written by [`put_shadow_ray`] (its line and segment checked: see
/// [`Line::get`]; t_in within [0, 1]; an exact segment's ends within the occluders' range).
pub fn get_shadow_ray(r: &mut Reader<'_>) -> Result<ShadowRay, DecodeError> {
    let line = Line::get(r)?;
    let emitter = [r.u16()?, r.u16()?];
    let (facet, emitter_z, flags, grace) = (r.u32()?, r.i32()?, r.u8()?, r.u8()?);
    let (plane, exact) = (flags & 4 != 0, flags & 8 != 0);
    if flags >> 6 != 0 || (plane && exact) || (!exact && flags & 0x30 != 0) {
        return Err(DecodeError::BadValue("shadow ray flags"));
    }
    let walk = if plane {
        let a = [r.i32()?, r.i32()?, r.i32()?];
        let d = [r.i32()?, r.i32()?, r.i32()?];
        let own = r.u32()?;
        let t_in = (r.i32()?, r.i32()?);
        let own_g = (r.i64()?, r.i64()?);
        let in_budget = a.iter().all(|c| c.unsigned_abs() <= MAX_COORD as u32)
            && d.iter().all(|c| c.unsigned_abs() <= MAX_SPAN as u32)
            && 0 < t_in.1
            && (0..=t_in.1).contains(&t_in.0);
        if !in_budget {
            return Err(DecodeError::BadValue("shadow ray segment"));
        }
        RayWalk::Plane(PlaneWalk { a, d, own, t_in, own_g })
    } else if exact {
        let source = [r.i32()?, r.i32()?, r.i32()?];
        let near = if flags & 32 != 0 { Some([r.i64()?, r.i64()?, r.i64()?]) } else { None };
        let limit = COORD_LIMIT * (POINT_UNITS / 16);
        let in_budget =
            source.iter().all(|&c| (c as i64).abs() <= COORD_LIMIT) && near.iter().flatten().all(|c| c.abs() <= limit);
        if !in_budget {
            return Err(DecodeError::BadValue("shadow ray segment"));
        }
        RayWalk::Exact(ExactWalk { near, source, untested: flags & 16 != 0 })
    } else {
        RayWalk::Thesis
    };
    Ok(ShadowRay { line, emitter, facet, emitter_z, fresh: flags & 1 != 0, grace, surface: flags & 2 != 0, walk })
}

/// Write a reflected ray's fields (payload after `seq`): its line ([`Line::put`]), direction
/// 3×i32, parent 2×u16, slot u16, facet u32, level u8, weight f32, entry faces u8, fresh u8.
pub fn put_reflect_ray<S: ByteSink + ?Sized>(w: &mut S, ray: &ReflectRay) -> Result<(), EncodeError> {
    ray.line.put(w)?;
    ray.dir.iter().try_for_each(|&c| w.i32(c))?;
    w.u16(ray.parent[0])?;
    w.u16(ray.parent[1])?;
    w.u16(ray.slot)?;
    w.u32(ray.facet)?;
    w.u8(ray.level)?;
    w.f32(ray.weight)?;
    w.u8(ray.entry)?;
    w.u8(ray.fresh as u8)
}

/// Read a reflected ray written by [`put_reflect_ray`] (its line checked: see [`Line::get`]).
pub fn get_reflect_ray(r: &mut Reader<'_>) -> Result<ReflectRay, DecodeError> {
    let line = Line::get(r)?;
    let dir = [r.i32()?, r.i32()?, r.i32()?];
    if dir.iter().any(|c| c.unsigned_abs() > MAX_SPAN as u32) {
        return Err(DecodeError::BadValue("reflected ray direction"));
    }
    let parent = [r.u16()?, r.u16()?];
    let (slot, facet, level, weight, entry) = (r.u16()?, r.u32()?, r.u8()?, r.f32()?, r.u8()?);
    let fresh = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(DecodeError::BadValue("reflected ray flags")),
    };
    if entry >> 3 != 0 {
        return Err(DecodeError::BadValue("reflected ray entry faces"));
    }
    Ok(ReflectRay { line, dir, parent, slot, facet, level, weight, entry, fresh, inside: None })
}

// ---------------------------------------------------------------------------------------------

/// Frame kinds of the board exercises (`firmware/src/bin/board`: a QEMU board per tile of
/// the grid, UART links between boards, the host on a serial port), host ↔ board and board ↔
/// board, in the framing of this module. A cell never sees them: a board's link driver
/// dispatches on the raw frame's kind ([`read_frame`]). Defined here, once, for the firmware
/// and for the host-side tests that drive it (which cannot link the firmware's crate).
pub mod board {
    // The link exercise (`firmware/src/bin/board/main.rs`).
    /// Host → board: id u8, neighbour ids on links E, N, W, S (4 × u8, `0xFF`: no link), frames
    /// per link u16.
    pub const KIND_CONFIG: u8 = 0x60;
    /// Board → host: id u8, then per link E, N, W, S: received u16, mismatches u16, then the
    /// link's counters (sent, acked, retransmitted, duplicates, skipped: 5 × u32) and the UART's
    /// overruns u32.
    pub const KIND_REPORT: u8 = 0x61;
    /// Board → neighbour: one data frame of the exercise.
    pub const KIND_DATA: u8 = 0x62;

    // The termination exercise (`safra.rs`), whose start, declaration and query the tile
    // exercise reuses.
    /// Host → board: the termination exercise's configuration: id u8, neighbour ids on E, N, W,
    /// S (4 × u8, `0xFF`: none), ring position u8, ring length u8, link to the next ring position
    /// u8 (0 … 3: E, N, W, S), busy time per item u16 (µs), children per item u8 (1 or 2).
    pub const KIND_TERM_CONFIG: u8 = 0x63;
    /// Host → board and board → board: a work item, ttl u8, id u32.
    pub const KIND_WORK: u8 = 0x64;
    /// Host → ring position 0: start detecting termination.
    pub const KIND_START: u8 = 0x65;
    /// Ring position 0 → host: termination of a phase declared (the phase, u16: 0, the work's,
    /// then 1, the empty phase whose token told every board of the first declaration).
    pub const KIND_DONE: u8 = 0x66;
    /// Host → board: send your state.
    pub const KIND_QUERY: u8 = 0x67;
    /// Board → host: id u8, processed u32, work frames sent u32 and received u32 (between
    /// boards), injected u32 (from the host), still queued u32 (queue and outgoing children), the
    /// termination counter i32, tokens forwarded u32, overflows u32, the neighbour links'
    /// retransmissions u32 and skipped bytes u32, and late work u32 (items received or processed
    /// after the board learned that phase 0 was declared).
    pub const KIND_STATE: u8 = 0x68;

    // The tile exercise (`tiles.rs`): cells of the grid on each board.
    /// Host → board: the tile exercise's configuration: id u8, neighbour ids on E, N, W, S
    /// (4 × u8, `0xFF`: none), ring position u8, ring length u8, link to the next ring position u8
    /// (0 … 3), tile origin x0 u16, y0 u16, tile side u8 (≤ the board's `SIDE`, 4), grid side
    /// n u16, depth u16, light sources u8 (1 … the board's `SOURCES`, 4).
    pub const KIND_TILE_CONFIG: u8 = 0x69;
    /// Host → board: a source's light setup, a whole `cell_core::trace` light record (its frame
    /// with its own CRC); one per source, in the order they are lit (source i: id and bit i).
    pub const KIND_TILE_LIGHT: u8 = 0x6A;
    /// Host → board 0 and board → board: a pipeline packet at pipeline row y: y u16, then
    /// `wire::put_pipe`.
    pub const KIND_PIPE: u8 = 0x6B;
    /// Board → board: a row packet at cell (x, y): x u16, y u16, then `wire::put_row`.
    pub const KIND_ROW_AT: u8 = 0x6C;
    /// Board → board: a beam for cell (x, y): x u16, y u16, then `wire::put_beam`.
    pub const KIND_TILE_BEAM: u8 = 0x6D;
    /// Board → host: one cell: x u16, y u16, dexels u8, lit runs u8, dexel-store overflows u32,
    /// lost voxels u32, lit-store overflows u32, still busy u32 (0 or 1: a beam left in the cell),
    /// its pixel (a flag u8, 1 when shaded, and rgb 3 × u8: `cell_core::shade::cell_pixel` under
    /// the light setup's lit rule with the [`KIND_TILE_SHADE`] inputs; flag 0 without a visible
    /// surface or before the shading record came), then up to `REPORTED` (16) dexels (lo u16,
    /// hi u16, facet u32) and as many lit runs (lo u16, hi u16, mask u32).
    pub const KIND_TILE_CELL: u8 = 0x6E;
    /// Board → host: id u8, then u32 each: basic frames sent, basic frames received, frames
    /// forwarded (diagonal beams), tokens forwarded, late work, overflows and bad frames, beams
    /// misrouted, loading items processed, cell steps, peak arrived beams, peak work list, the
    /// neighbour links' retransmissions and skipped bytes, the stack's peak in bytes (the board's
    /// whole state lives on it); then the termination counter i32.
    pub const KIND_TILE_STATE: u8 = 0x6F;
    /// Host → board: the shading inputs (materials, lights, ambient, eye), a whole
    /// `cell_core::trace` shading record; the cells shade their pixels when the host asks for the
    /// report, after the lighting was declared.
    pub const KIND_TILE_SHADE: u8 = 0x70;
    /// Host → board, under exact occluders: triangles column (x, y) keeps
    /// (`cell_core::occluder::Triangle`, as host-sim loads them with the facets,
    /// `Triangle::crosses_column`): x u16, y u16, then 1 … 8 triangles, each its vertices
    /// 9 × i32 (sixteenths of a voxel), in the column's order (more come in further frames).
    /// Every light setup of the run uses them (a column's triangles do not depend on the source).
    pub const KIND_TILE_TRIANGLES: u8 = 0x71;
    /// Host → board, under exact occluders, for a cell whose target ray has a contact segment
    /// for a source: x u16, y u16, the source's index in the run u8, its 8 neighbours' answers
    /// to its contact query OR-ed u8 (0 or 1; the trace's `NeighbourContact` record).
    pub const KIND_TILE_CONTACT: u8 = 0x72;
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::beam::Source;
    use fixed::types::extra::{U0, U4};
    use proptest::prelude::*;

    fn far<F: FracBits>() -> FarDistance<F> {
        FarDistance::new(127).unwrap()
    }

    #[test]
    fn crc_is_the_standard_one() {
        assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn beam_round_trip_and_size() {
        let s = Source::at_voxel(SourceId(3), [10, 20, 30]).unwrap();
        for d in Direction::ALL {
            let b = Beam::<U4>::initial(&s, d, far());
            let parts = b.split(&s, far(), d.transverse_of([10, 20, 30])).unwrap();
            for sb in parts {
                let m = BeamMsg::new(sb.beam, 31);
                let mut buf = [0u8; 64];
                let n = Message::Beam(m).emit(9, &mut buf).unwrap();
                assert_eq!(n, HEADER + BEAM_PAYLOAD + TRAILER);
                let (f, used) = Frame::<U4>::parse(&buf[..n], far()).unwrap();
                assert_eq!((f.seq, f.msg, used), (9, Message::Beam(m), n));
            }
        }
    }

    // Known answers: frames written out by hand from the layout in the module doc (kind u8,
    // len u16 LE, payload, CRC-32 LE over kind, len and payload), one field per line. The CRCs
    // were computed independently of this crate, with Python's `zlib.crc32` over the same bytes
    // (`struct.pack('<BH', kind, len) + payload`), not with `CRC32`.

    /// An acknowledgement of sequence number 0x5a.
    const ACK_5A: [u8; 8] = [
        0x30, 0x01, 0x00, // kind ACK, len 1
        0x5a, // seq
        0x60, 0xf5, 0x13, 0x5b, // CRC-32 0x5b13f560
    ];

    /// A black termination token of phase 3 with sum −2, seq 0x11.
    const TOKEN_P3: [u8; 15] = [
        0x40, 0x08, 0x00, // kind TOKEN, len 8
        0x11, // seq
        0x03, 0x00, // phase 3
        0xfe, 0xff, 0xff, 0xff, // sum −2
        0x01, // black
        0x1b, 0xd2, 0x5b, 0x5c, // CRC-32 0x5c5bd21b
    ];

    /// A beam at f = 0: seq 7, source 0x0203, direction −y (3) terminal (bit 7) and after the
    /// outside of a plane (bit 5), layer 17, u −5 ..= 12, v 0 ..= 127, z 320.
    const BEAM_F0: [u8; 34] = [
        0x20, 0x1b, 0x00, // kind BEAM, len 27
        0x07, // seq
        0x00, // fraction bits
        0x03, 0x02, // source 0x0203
        0xa3, // direction 3 | 0x80 | 0x20
        0x11, 0x00, 0x00, 0x00, // layer 17
        0xfb, 0xff, 0xff, 0xff, // u_lo −5
        0x0c, 0x00, 0x00, 0x00, // u_hi 12
        0x00, 0x00, 0x00, 0x00, // v_lo 0
        0x7f, 0x00, 0x00, 0x00, // v_hi 127
        0x40, 0x01, // z 320
        0xfa, 0xc6, 0x3b, 0x57, // CRC-32 0x573bc6fa
    ];

    /// A beam at f = 4 (offsets in sixteenths): seq 0xc8, source 0xffff, direction +z (4) after
    /// an empty voxel (bit 6), layer 126, u −1.5 ..= 2.25, v −127 ..= −126.5, z 0.
    const BEAM_F4: [u8; 34] = [
        0x20, 0x1b, 0x00, // kind BEAM, len 27
        0xc8, // seq
        0x04, // fraction bits
        0xff, 0xff, // source 0xffff
        0x44, // direction 4 | 0x40
        0x7e, 0x00, 0x00, 0x00, // layer 126
        0xe8, 0xff, 0xff, 0xff, // u_lo −1.5 = −24/16
        0x24, 0x00, 0x00, 0x00, // u_hi 2.25 = 36/16
        0x10, 0xf8, 0xff, 0xff, // v_lo −127 = −2032/16
        0x18, 0xf8, 0xff, 0xff, // v_hi −126.5 = −2024/16
        0x00, 0x00, // z 0
        0x47, 0x5c, 0xe9, 0x42, // CRC-32 0x42e95c47
    ];

    /// A row packet with two contour edges, seq 0.
    const ROW_2_EDGES: [u8; 121] = [
        0x10, 0x72, 0x00, // kind ROW, len 114 = 74 + 2·20
        0x00, // seq
        0x04, 0x03, 0x02, 0x01, // facet 0x01020304
        0x06, 0x05, // material 0x0506
        0x08, 0x07, // normal code 0x0708
        0x0d, 0x0c, 0x0b, 0x0a, // plane id 0x0a0b0c0d
        0x00, 0xc0, // nx −16384
        0x4d, 0x00, // ny 77
        0x00, 0x00, 0x00, 0xc0, // nz −2³⁰
        0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, // m 2⁴¹
        0x01, 0x00, 0x09, 0x00, // box x 1 ..= 9
        0x02, 0x00, 0x02, 0x00, // box y 2 ..= 2
        0x00, 0x00, 0x64, 0x00, // box z 0 ..= 100
        0xfd, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, // a −3
        0xe8, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // c 1000
        0x15, 0xcd, 0x5b, 0x07, 0x00, 0x00, 0x00, 0x00, // t 123 456 789
        0x4f, 0x97, 0x21, 0xc5, 0xff, 0xff, 0xff, 0xff, // u −987 654 321
        0x02, // edge count
        0x10, 0x00, 0x00, 0x00, // edge 0: a 16
        0xf0, 0xff, 0xff, 0xff, //         c −16
        0x00, 0xf0, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, //         g −4096
        0x08, 0x00, 0x00, 0x00, //         off 8
        0xff, 0xff, 0xff, 0xff, // edge 1: a −1
        0x00, 0x00, 0x00, 0x00, //         c 0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, //         g 2⁴⁰
        0x00, 0x00, 0x00, 0x00, //         off 0
        0xb5, 0xe3, 0x05, 0x3d, // CRC-32 0x3d05e3b5
    ];

    fn beam_msg<F: FracBits>(
        source: u16,
        dir: Direction,
        flags: [bool; 3],
        layer: u32,
        uv: [i32; 4],
        z: u16,
    ) -> BeamMsg<F> {
        let r = |lo: i32, hi: i32| RayRange::new(FarOffset::<F>::from_bits(lo), FarOffset::<F>::from_bits(hi)).unwrap();
        let beam = Beam::new(SourceId(source), dir, Layer(layer), r(uv[0], uv[1]), r(uv[2], uv[3]), far())
            .unwrap()
            .with_terminal(flags[0])
            .with_after_empty(flags[1])
            .with_after_outside(flags[2]);
        BeamMsg::new(beam, z)
    }

    fn row_2_edges() -> RowPacket {
        let plane = FacetPlane { id: 0x0a0b_0c0d, nx: -16384, ny: 77, nz: -(1 << 30), m: 1 << 41 };
        RowPacket {
            tag: FacetTag { facet: 0x0102_0304, material: 0x0506, normal: NormalCode(0x0708), plane },
            bbox: FacetBox { x_min: 1, x_max: 9, y_min: 2, y_max: 2, z_min: 0, z_max: 100 },
            a: -3,
            c: 1000,
            t: 123_456_789,
            u: -987_654_321,
            edges: [RowEdge { a: 16, c: -16, g: -4096, off: 8 }, RowEdge { a: -1, c: 0, g: 1 << 40, off: 0 }]
                .into_iter()
                .collect(),
        }
    }

    #[test]
    fn pipeline_packets_round_trip_and_refuse_a_b_beyond_the_budget() {
        let row = row_2_edges();
        let edges = row.edges.iter().zip([5, -7]).map(|(e, b)| PipeEdge { a: e.a, b, c: e.c, g: e.g, off: e.off });
        let p = PipelinePacket {
            tag: row.tag,
            bbox: row.bbox,
            a: row.a,
            b: -11,
            c: row.c,
            t: row.t,
            u: row.u,
            edges: edges.collect(),
        };
        let mut buf = [0u8; MAX_FRAME + 64];
        let mut w = SliceWriter::new(&mut buf);
        put_pipe(&mut w, &p).unwrap();
        let n = w.len();
        assert_eq!(n, ROW_PAYLOAD_BASE - 1 + 2 * ROW_EDGE_BYTES + 8 + 2 * 4, "row fields, b, the edges' b");
        let mut r = Reader::new(&buf[..n]);
        assert_eq!(get_pipe(&mut r).unwrap(), p);
        r.finish().unwrap();
        assert_eq!(p.to_row(), row, "the row part is the row packet's encoding");
        // b beyond the budget of the plane coefficients.
        let big = PipelinePacket { b: i64::MAX, ..p };
        let mut w = SliceWriter::new(&mut buf);
        put_pipe(&mut w, &big).unwrap();
        let n = w.len();
        assert!(get_pipe(&mut Reader::new(&buf[..n])).is_err());
    }

    /// Encode a known message, compare with the literal frame, decode the literal back.
    fn known_answer<F: FracBits>(seq: u8, msg: Message<F>, literal: &[u8]) {
        let mut buf = [0u8; MAX_FRAME];
        let n = msg.emit(seq, &mut buf).unwrap();
        assert_eq!(&buf[..n], literal, "encoded frame");
        assert_eq!(msg.buffer_len(), literal.len(), "announced frame length");
        // The CRC trailer alone, against the independent computation.
        let crc = u32::from_le_bytes(literal[literal.len() - TRAILER..].try_into().unwrap());
        assert_eq!(CRC32.checksum(&literal[..literal.len() - TRAILER]), crc);
        let (f, used) = Frame::<F>::parse(literal, far()).unwrap();
        assert_eq!((f.seq, f.msg, used), (seq, msg, literal.len()), "decoded literal");
    }

    #[test]
    fn frames_equal_hand_written_bytes() {
        known_answer::<U0>(0x5a, Message::Ack, &ACK_5A);
        let tf = TokenFrame { seq: 0x11, token: Token { phase: 3, count: -2, black: true } };
        let mut buf = [0u8; TokenFrame::LEN];
        assert_eq!(tf.emit(&mut buf), Ok(TOKEN_P3.len()));
        assert_eq!(buf, TOKEN_P3, "encoded token frame");
        assert_eq!(TokenFrame::parse(&TOKEN_P3), Ok((tf, TOKEN_P3.len())), "decoded literal");
        assert_eq!(Frame::<U0>::parse(&TOKEN_P3, far()).unwrap_err(), DecodeError::UnknownKind(KIND_TOKEN));
        assert_eq!(TokenFrame::parse(&ACK_5A).unwrap_err(), DecodeError::UnknownKind(KIND_ACK));
        let mut b = TOKEN_P3;
        b[14] ^= 0x01;
        assert_eq!(TokenFrame::parse(&b).unwrap_err(), DecodeError::BadCrc);
        let m = beam_msg::<U0>(0x0203, Direction::NegY, [true, false, true], 17, [-5, 12, 0, 127], 320);
        known_answer::<U0>(7, Message::Beam(m), &BEAM_F0);
        let m = beam_msg::<U4>(0xffff, Direction::PosZ, [false, true, false], 126, [-24, 36, -2032, -2024], 0);
        known_answer::<U4>(0xc8, Message::Beam(m), &BEAM_F4);
        known_answer::<U0>(0, Message::Row(row_2_edges()), &ROW_2_EDGES);
        // The literal frames with their last CRC byte changed are refused.
        for lit in [&ACK_5A[..], &BEAM_F0[..], &ROW_2_EDGES[..]] {
            let mut b = lit.to_vec();
            *b.last_mut().unwrap() ^= 0x01;
            assert_eq!(Frame::<U0>::parse(&b, far()).unwrap_err(), DecodeError::BadCrc);
        }
    }

    #[test]
    fn every_single_bit_flip_is_caught() {
        let s = Source::at_voxel(SourceId(0), [5, 5, 5]).unwrap();
        let m = BeamMsg::new(Beam::<U0>::initial(&s, Direction::ALL[2], far()), 5);
        let mut buf = [0u8; 64];
        let n = Message::Beam(m).emit(1, &mut buf).unwrap();
        for i in 0..n * 8 {
            let mut b = buf;
            b[i / 8] ^= 1 << (i % 8);
            assert!(Frame::<U0>::parse(&b[..n], far()).is_err(), "flip of bit {i} went through");
        }
        assert_eq!(
            Frame::<U4>::parse(&buf[..n], far()).unwrap_err(),
            DecodeError::FracBitsMismatch { found: 0, expected: 4 }
        );
    }

    proptest! {
        #[test]
        fn token_round_trip(seq in any::<u8>(), phase in any::<u16>(), count in any::<i32>(), black in any::<bool>()) {
            let tf = TokenFrame { seq, token: Token { phase, count, black } };
            let mut buf = [0u8; MAX_FRAME];
            let n = tf.emit(&mut buf).unwrap();
            prop_assert_eq!(n, TokenFrame::LEN);
            prop_assert_eq!(TokenFrame::parse(&buf[..n]), Ok((tf, n)));
            // A colour byte other than 0 or 1 is refused (behind a valid CRC), and so is a
            // payload of another length.
            let mut bad = [0u8; 32];
            let m = write_frame(&mut bad, KIND_TOKEN, |w| { w.put(&buf[HEADER..HEADER + 7])?; w.u8(2) }).unwrap();
            prop_assert_eq!(TokenFrame::parse(&bad[..m]).unwrap_err(), DecodeError::BadValue("token colour"));
            let m = write_frame(&mut bad, KIND_TOKEN, |w| w.put(&buf[HEADER..n - TRAILER + 1])).unwrap();
            prop_assert_eq!(TokenFrame::parse(&bad[..m]).unwrap_err(), DecodeError::BadLength);
        }

        #[test]
        fn row_round_trip(facet in any::<u32>(), a in -1000i64..1000, c in -1000i64..1000, t in any::<i32>(),
                          edges in proptest::collection::vec((-5000i32..5000, -5000i32..5000, any::<i32>()), 0..=MAX_EDGES)) {
            let p = RowPacket {
                tag: FacetTag { facet, material: 3, normal: NormalCode(77), plane: FacetPlane { id: facet ^ 5, nx: -16384, ny: 77, nz: -(1 << 30), m: 1 << 41 } },
                bbox: FacetBox { x_min: 1, x_max: 9, y_min: 2, y_max: 2, z_min: 0, z_max: 100 },
                a, c, t: t as i64, u: t as i64 - 40,
                edges: edges.iter().map(|&(a, c, g)| RowEdge { a, c, g: g as i64, off: (a.unsigned_abs() % 977) as i32 }).collect(),
            };
            let mut buf = [0u8; MAX_FRAME];
            let n = Message::<U0>::Row(p.clone()).emit(0, &mut buf).unwrap();
            prop_assert_eq!(n, HEADER + ROW_PAYLOAD_BASE + ROW_EDGE_BYTES * p.edges.len() + TRAILER);
            let (f, used) = Frame::<U0>::parse(&buf[..n], far()).unwrap();
            prop_assert_eq!(used, n);
            prop_assert_eq!(f.msg, Message::Row(p));
        }

        #[test]
        fn junk_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = Frame::<U0>::parse(&bytes, far());
            // Junk behind a valid header and CRC reaches the field checks.
            let mut buf = [0u8; 512];
            if let Ok(n) = write_frame(&mut buf, bytes.first().map_or(KIND_BEAM, |k| k & 0x30), |w| w.put(&bytes)) {
                let _ = Frame::<U0>::parse(&buf[..n], far());
            }
        }
    }

    #[test]
    fn out_of_budget_rows_are_rejected() {
        // A plane coefficient beyond the loading budget, then a facet plane beyond its own.
        let row = |a: i64, m: u64| {
            let mut buf = [0u8; MAX_FRAME];
            let n = write_frame(&mut buf, KIND_ROW, |w| {
                w.u8(0)?;
                w.put(&[0; 8])?;
                w.put(&[0; 12])?;
                w.u64(m)?;
                for v in [0u16, 1, 0, 1, 0, 1] {
                    w.u16(v)?;
                }
                w.i64(a)?;
                w.put(&[0; 24])?;
                w.u8(0)
            })
            .unwrap();
            Frame::<U0>::parse(&buf[..n], far()).map(|_| ())
        };
        assert_eq!(row(0, 1), Ok(()));
        assert_eq!(row(i64::MAX, 1), Err(DecodeError::BadValue("plane coefficient a beyond the bit budget")));
        assert_eq!(row(0, 0), Err(DecodeError::BadValue("facet plane beyond the bit budget")));
        assert_eq!(row(0, (1 << 41) + 1), Err(DecodeError::BadValue("facet plane beyond the bit budget")));
    }

    #[test]
    fn ray_frames_round_trip_within_their_size() {
        use crate::plane::DexelPlane;
        use crate::ray::{Connectivity, Q};
        let plane = DexelPlane { id: 9, nx: 300, ny: -200, nz: -15000, e: -77 };
        let mut rays = std::vec::Vec::new();
        for c in Connectivity::ALL {
            let r = ShadowRay::new([3, 4, 5], [40 * Q, -9 * Q + 3, 60 * Q], c, 11).unwrap().with_bias(2);
            rays.push(RayMsg::Shadow(r.for_surface()));
            let dir = [-7 * Q, 5 * Q, -31 * Q];
            let mut f = ReflectRay::leaving([9 * Q, 8 * Q, 7 * Q], dir, c, [1, 2], 3, 4, 5, 0.25).unwrap();
            let store = crate::dexel::DexelStore::<4>::new();
            while f.line.remaining() > 20 {
                let _ = f.advance(&store, 64, 64, true);
            }
            rays.push(RayMsg::Reflect(f));
        }
        let plane_ray = ShadowRay::on_plane([5 * Q, 6 * Q, 70], &plane, 4, [50 * Q, 3 * Q, -30 * Q], 2).unwrap();
        rays.push(RayMsg::Shadow(plane_ray.expect("the plane faces the source")));
        // Under exact occluders: with its segment, and without (the source within the gap).
        let p = [5 * 4096, 6 * 4096, 4 * 4096 + 1234];
        let exact = ShadowRay::exact(p, &plane, 4, [50 * Q, 3 * Q, -30 * Q], 2).unwrap().expect("faces it");
        assert!(matches!(exact.walk, crate::ray::RayWalk::Exact(ExactWalk { near: Some(_), untested: true, .. })));
        rays.push(RayMsg::Shadow(exact));
        let mut blind = exact;
        blind.walk = crate::ray::RayWalk::Exact(ExactWalk { near: None, source: [1, 2, 3], untested: false });
        rays.push(RayMsg::Shadow(blind));
        for ray in rays {
            let mut buf = [0u8; MAX_RAY_FRAME + 8];
            let n = ray.emit(7, &mut buf).unwrap();
            assert!(n <= MAX_RAY_FRAME, "{n} bytes");
            let (raw, used) = read_frame(&buf[..n]).unwrap();
            assert_eq!((used, RayMsg::parse_payload(raw)), (n, Ok((7, ray))));
            buf[n / 2] ^= 0x20;
            assert_eq!(read_frame(&buf[..n]).unwrap_err(), DecodeError::BadCrc);
        }
        // The longest: the plane rule's segment on a line with a pending voxel.
        let mut longest = ShadowRay::new([0, 0, 0], [3 * Q, 3 * Q, 3 * Q], Connectivity::Eighteen, 0).unwrap();
        while longest.line.step().is_some_and(|v| v != [1, 1, 0] && v != [1, 0, 1] && v != [0, 1, 1]) {}
        longest.walk = plane_ray.expect("faces it").walk;
        let mut buf = [0u8; MAX_RAY_FRAME + 8];
        assert_eq!(RayMsg::Shadow(longest).emit(0, &mut buf), Ok(MAX_RAY_FRAME));
    }

    #[test]
    fn rays_outside_the_budget_are_rejected() {
        let ray = ShadowRay::new([3, 4, 5], [40 * 16, 0, 0], crate::ray::Connectivity::Six, 1).unwrap();
        let frame = |ray: &ShadowRay, flags: Option<u8>| {
            let mut buf = [0u8; MAX_RAY_FRAME];
            let n = write_frame(&mut buf, KIND_SHADOW_RAY, |w| {
                w.u8(0)?;
                put_shadow_ray(w, ray)
            })
            .unwrap();
            let mut v = buf[..n].to_vec();
            if let Some(f) = flags {
                // The flags byte: after seq, the line (50 bytes), emitter, facet and z.
                v[HEADER + 1 + 50 + 12] = f;
                let end = v.len() - TRAILER;
                let crc = CRC32.checksum(&v[..end]).to_le_bytes();
                v[end..].copy_from_slice(&crc);
            }
            let (raw, _) = read_frame(&v).unwrap();
            RayMsg::parse_payload(raw).map(|_| ())
        };
        assert_eq!(frame(&ray, None), Ok(()));
        for bad in [0x40, 0x0c, 0x10, 0x20] {
            assert_eq!(frame(&ray, Some(bad)), Err(DecodeError::BadValue("shadow ray flags")), "{bad:#x}");
        }
        let mut walk = ray;
        walk.walk = RayWalk::Plane(PlaneWalk { a: [0; 3], d: [1; 3], own: 0, t_in: (2, 1), own_g: (0, 0) });
        assert_eq!(frame(&walk, None), Err(DecodeError::BadValue("shadow ray segment")));
        let limit = COORD_LIMIT * (POINT_UNITS / 16);
        for (near, source) in [([limit, 0, -limit], [0; 3]), ([0; 3], [COORD_LIMIT as i32, 0, 0])] {
            walk.walk = RayWalk::Exact(ExactWalk { near: Some(near), source, untested: true });
            assert_eq!(frame(&walk, None), Ok(()), "at the limits");
        }
        for (near, source) in [([limit + 1, 0, 0], [0; 3]), ([0; 3], [0, 0, -(COORD_LIMIT as i32) - 1])] {
            walk.walk = RayWalk::Exact(ExactWalk { near: Some(near), source, untested: true });
            assert_eq!(frame(&walk, None), Err(DecodeError::BadValue("shadow ray segment")));
        }
        let mut raw = [0u8; 4];
        raw[0] = KIND_SHADOW_RAY;
        assert_eq!(
            RayMsg::parse_payload(RawFrame { kind: KIND_BEAM, payload: &[0] }),
            Err(DecodeError::UnknownKind(KIND_BEAM))
        );
        assert_eq!(
            RayMsg::parse_payload(RawFrame { kind: KIND_REFLECT_RAY, payload: &raw }),
            Err(DecodeError::Truncated)
        );
    }
}

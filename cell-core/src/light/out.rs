//! The cell's eight output buffers (thesis §4.4.2, no loss): their lengths in one word, so
//! that the room check of a split reads 8 bytes ([`OutBuffers`]).

use super::*;

/// The cell's eight output buffers, `OB` messages each, FIFO order. The eight lengths sit
/// together in one word ahead of the messages, so "is anything waiting", "which links have a
/// message" and the no-loss room check read 8 bytes instead of a header per buffer (the host's
/// cell step was bound by those loads). Buffers are tiny (`OB` = 3): popping shifts the rest.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct OutBuffers<F: FracBits, const OB: usize> {
    pub(super) len: [u8; 8],
    msgs: [[BeamMsg<F>; OB]; 8],
}

impl<F: FracBits, const OB: usize> Default for OutBuffers<F, OB> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: FracBits, const OB: usize> OutBuffers<F, OB> {
    const OB_FITS_A_BYTE: () =
        assert!(OB <= 127, "output buffer lengths are bytes, checked eight at a time with a bias of 127 − OB");

    /// Eight empty buffers.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::OB_FITS_A_BYTE;
        OutBuffers { len: [0; 8], msgs: [[BeamMsg::new(Beam::filler(), 0); OB]; 8] }
    }

    /// Messages waiting toward `p`.
    pub fn len(&self, p: Port) -> usize {
        self.len[p.index()] as usize
    }

    /// Whether nothing waits toward `p`.
    pub fn is_empty(&self, p: Port) -> bool {
        self.len[p.index()] == 0
    }

    /// Whether any buffer holds a message.
    pub fn any(&self) -> bool {
        self.lengths() != 0
    }

    /// The eight lengths as one word (byte p: port p).
    pub fn lengths(&self) -> u64 {
        u64::from_le_bytes(self.len)
    }

    /// The links with a message waiting, as a mask (bit p: port p). Each length is at most
    /// 127, so adding 127 to every byte sets its high bit exactly when it is non-zero, with no
    /// carry into the next byte.
    pub fn busy_mask(&self) -> u8 {
        const HIGH: u64 = 0x8080_8080_8080_8080;
        let nonzero = (self.lengths() + (HIGH - 0x0101_0101_0101_0101)) & HIGH;
        // Gather the eight high bits into one byte (bit 7 of byte p lands on bit 56 + p).
        (((nonzero >> 7).wrapping_mul(0x0102_0408_1020_4080)) >> 56) as u8
    }

    /// The links with a message waiting, in port order.
    pub fn busy_ports(&self) -> impl Iterator<Item = Port> {
        Port::each(self.busy_mask())
    }

    /// The oldest message toward `p`.
    pub fn front(&self, p: Port) -> Option<&BeamMsg<F>> {
        self.waiting(p).first()
    }

    /// The messages toward `p`, oldest first.
    pub fn waiting(&self, p: Port) -> &[BeamMsg<F>] {
        &self.msgs[p.index()][..self.len[p.index()] as usize]
    }

    /// Where the slots of buffer `p` start (reads nothing: for a host that prefetches).
    pub fn slots(&self, p: Port) -> *const BeamMsg<F> {
        self.msgs[p.index()].as_ptr()
    }

    /// The messages toward `p`, oldest first, to update in place (merging).
    pub fn waiting_mut(&mut self, p: Port) -> &mut [BeamMsg<F>] {
        &mut self.msgs[p.index()][..self.len[p.index()] as usize]
    }

    /// Queue `m` toward `p`; a full buffer gives it back.
    pub fn push_back(&mut self, p: Port, m: BeamMsg<F>) -> Result<(), BeamMsg<F>> {
        let (q, n) = (&mut self.msgs[p.index()], &mut self.len[p.index()]);
        let Some(slot) = q.get_mut(*n as usize) else { return Err(m) };
        *slot = m;
        *n += 1;
        Ok(())
    }

    /// Take the oldest message toward `p`.
    pub fn pop_front(&mut self, p: Port) -> Option<BeamMsg<F>> {
        let (q, n) = (&mut self.msgs[p.index()], &mut self.len[p.index()]);
        let len = *n as usize;
        if len == 0 {
            return None;
        }
        let m = q[0];
        // Every slot moves up, waiting or not (`OB` is tiny): a fixed-size copy the compiler
        // unrolls, where a copy of `len − 1` slots was a call to `memmove`. Slots past the
        // length are never read.
        for s in 1..OB {
            q[s - 1] = q[s];
        }
        *n -= 1;
        Some(m)
    }
}

/// Whether every byte of `lengths` (each ≤ `OB` ≤ 127) plus the same byte of `need` (each ≤ 9)
/// is at most `OB`: the bytes of `lengths + need + (127 − OB)` are at most 136 (no carry) and
/// reach 128 exactly when the sum exceeds `OB`.
pub(super) const fn room<const OB: usize>(lengths: u64, need: u64) -> bool {
    const HIGH: u64 = 0x8080_8080_8080_8080;
    let bias = u64::from_le_bytes([(127 - OB) as u8; 8]);
    (lengths + need + bias) & HIGH == 0
}

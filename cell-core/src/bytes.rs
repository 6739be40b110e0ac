//! The byte codec every message format of the cell is written with: little-endian fields
//! into a [`ByteSink`] (a buffer, a running digest, a wire), read back by a bounds-checked
//! [`Reader`] that answers a [`DecodeError`], never a panic.
//!
//! Invariant: it knows no message. The frames of the links ([`crate::wire`]) and the codecs of
//! what travels in them (beams, rows, shadow and reflected rays) stand on it, so that the
//! modules defining those messages can encode themselves without importing the link format.

/// Why bytes could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is too small.
    BufferTooSmall,
    /// The payload is longer than a frame's 16-bit length.
    PayloadTooLong,
}

/// Why bytes could not be decoded (a value, never a panic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// Fewer bytes than the header, the length or a field announces.
    Truncated,
    /// The CRC does not match: a corrupted frame.
    BadCrc,
    /// A frame kind this decoder does not know (or not the one expected).
    UnknownKind(u8),
    /// The payload is longer or shorter than its kind requires.
    BadLength,
    /// A field is out of range (direction, ranges, layer, edge count, bit budget …).
    BadValue(&'static str),
    /// A beam encoded with another number of fraction bits than this build's.
    FracBitsMismatch {
        /// Fraction bits in the frame.
        found: u8,
        /// Fraction bits of this build.
        expected: u8,
    },
}

/// Where encoded bytes go: a buffer, a running digest, a wire.
pub trait ByteSink {
    /// Append bytes.
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError>;
}

/// A [`ByteSink`] writing into a slice.
pub struct SliceWriter<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl<'a> SliceWriter<'a> {
    /// Write from the start of `buf`.
    pub fn new(buf: &'a mut [u8]) -> Self {
        SliceWriter { buf, pos: 0 }
    }

    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.pos
    }

    /// Whether nothing was written.
    pub fn is_empty(&self) -> bool {
        self.pos == 0
    }

    /// What was written.
    pub fn written(&self) -> &[u8] {
        &self.buf[..self.pos]
    }
}

impl ByteSink for SliceWriter<'_> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        let end = self.pos.checked_add(bytes.len()).ok_or(EncodeError::BufferTooSmall)?;
        let dst = self.buf.get_mut(self.pos..end).ok_or(EncodeError::BufferTooSmall)?;
        dst.copy_from_slice(bytes);
        self.pos = end;
        Ok(())
    }
}

/// A [`ByteSink`] that only counts (sizes on the wire).
#[derive(Clone, Copy, Debug, Default)]
pub struct CountingSink(pub usize);

impl ByteSink for CountingSink {
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        self.0 += bytes.len();
        Ok(())
    }
}

/// Little-endian field writers over any sink.
pub trait PutExt: ByteSink {
    /// One byte.
    fn u8(&mut self, v: u8) -> Result<(), EncodeError> {
        self.put(&[v])
    }
    /// u16 LE.
    fn u16(&mut self, v: u16) -> Result<(), EncodeError> {
        self.put(&v.to_le_bytes())
    }
    /// u32 LE.
    fn u32(&mut self, v: u32) -> Result<(), EncodeError> {
        self.put(&v.to_le_bytes())
    }
    /// u64 LE.
    fn u64(&mut self, v: u64) -> Result<(), EncodeError> {
        self.put(&v.to_le_bytes())
    }
    /// i32 LE.
    fn i32(&mut self, v: i32) -> Result<(), EncodeError> {
        self.put(&v.to_le_bytes())
    }
    /// i64 LE.
    fn i64(&mut self, v: i64) -> Result<(), EncodeError> {
        self.put(&v.to_le_bytes())
    }
    /// f32 LE (IEEE bits).
    fn f32(&mut self, v: f32) -> Result<(), EncodeError> {
        self.put(&v.to_bits().to_le_bytes())
    }
}

impl<S: ByteSink + ?Sized> PutExt for S {}

/// A bounds-checked little-endian reader.
pub struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// Read `bytes` from the start.
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.bytes.len()
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        if self.bytes.len() < n {
            return Err(DecodeError::Truncated);
        }
        let (a, b) = self.bytes.split_at(n);
        self.bytes = b;
        Ok(a)
    }

    fn array<const K: usize>(&mut self) -> Result<[u8; K], DecodeError> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }

    /// One byte.
    pub fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.array::<1>()?[0])
    }
    /// u16 LE.
    pub fn u16(&mut self) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    /// u32 LE.
    pub fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    /// u64 LE.
    pub fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    /// i32 LE.
    pub fn i32(&mut self) -> Result<i32, DecodeError> {
        Ok(i32::from_le_bytes(self.array()?))
    }
    /// i64 LE.
    pub fn i64(&mut self) -> Result<i64, DecodeError> {
        Ok(i64::from_le_bytes(self.array()?))
    }
    /// f32 LE; NaN and infinities are rejected.
    pub fn f32(&mut self) -> Result<f32, DecodeError> {
        let v = f32::from_bits(self.u32()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(DecodeError::BadValue("non-finite float"))
        }
    }

    /// Fails unless every byte was read.
    pub fn finish(&self) -> Result<(), DecodeError> {
        if self.bytes.is_empty() {
            Ok(())
        } else {
            Err(DecodeError::BadLength)
        }
    }
}

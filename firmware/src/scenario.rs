// The scenario the firmware replays and the host test recomputes: a facet-packet table (bytes,
// as a trace will be) and a digest of what one real `cell_core` cell makes of it.
//
// This file is `mod scenario;` in the firmware and `include!`d by `tests/tests/firmware_qemu.rs`
// on the host, so both sides run the very same code over the very same bytes. It uses only
// `core` and `cell_core` (no_std, no alloc) and never panics on malformed bytes: a record that
// does not decode is a value (it is folded into the digest as such).
//
// Plain `//` comments only: inner doc comments would not survive `include!`.

use cell_core::cell::Cell;
use cell_core::dexel::FacetTag;
use cell_core::facet::{FacetBox, RowEdge, RowPacket};
use cell_core::normal::NormalCode;

/// The cell this scenario runs: column `X`, row `Y`, `DEPTH` voxels deep, `CAP` dexels.
pub const X: u16 = 5;
/// Row of the cell.
pub const Y: u16 = 7;
/// Column depth.
pub const DEPTH: u32 = 256;
/// Dexel capacity of the cell (the host's default).
pub const CAP: usize = 64;

/// Contour edges per record.
pub const REC_EDGES: usize = 4;
/// Bytes per facet record: id u32, material u16, normal u16, box 6 × u16, plane a b c d Kσ
/// (5 × i32), edge count u8, `REC_EDGES` × edge a b c d (4 × i32); all little-endian.
pub const RECORD: usize = 4 + 2 + 2 + 12 + 20 + 1 + REC_EDGES * 16;

/// A facet in the cell's integer frame: `P(x, y, z) = a·x + b·y + c·z + d`, band `|P| ≤ Kσ`,
/// edges `a_i·x + b_i·y + c_i·z + d_i ≥ 0`.
#[derive(Clone, Copy)]
pub struct FacetDef {
    pub id: u32,
    pub material: u16,
    pub normal: u16,
    /// x_min, x_max, y_min, y_max, z_min, z_max.
    pub bbox: [u16; 6],
    /// a, b, c, d, Kσ.
    pub plane: [i32; 5],
    pub n_edges: u8,
    pub edges: [[i32; 4]; REC_EDGES],
}

const NO_EDGES: [[i32; 4]; REC_EDGES] = [[0; 4]; REC_EDGES];
const FULL: [u16; 6] = [0, 15, 0, 15, 0, 255];

const fn f(id: u32, material: u16, normal: u16, bbox: [u16; 6], plane: [i32; 5]) -> FacetDef {
    FacetDef { id, material, normal, bbox, plane, n_edges: 0, edges: NO_EDGES }
}

const fn with_edge(mut d: FacetDef, e: [i32; 4]) -> FacetDef {
    d.edges[d.n_edges as usize] = e;
    d.n_edges += 1;
    d
}

/// Hand-made facets, each exercising one path of `load_step` at (5, 7).
pub const HAND: [FacetDef; 9] = [
    // A floor at z = 3 (c > 0): the dexel 3 ..= 3.
    f(0, 1, 100, FULL, [0, 0, 16, -48, 8]),
    // z = 20 − x, band ±1 voxel (14 ..= 16), an edge z ≥ 15 with c_i ≠ 0 trims it to 15 ..= 16.
    with_edge(f(1, 2, 200, FULL, [16, 0, 16, -320, 16]), [0, 0, 1, -15]),
    // c < 0: z = y + 33 = 40 (bounds swapped).
    f(2, 3, 300, FULL, [0, 16, -16, 528, 8]),
    // c = 0: a wall through x = 5, the whole column clipped to the box 38 ..= 42 (40 is shared).
    f(3, 4, 400, [0, 15, 0, 15, 38, 42], [16, 0, 0, -80, 8]),
    // Same surface as facet 1 (material 2, normal 200), 16 ..= 18: 16 shared, 17 ..= 18 merge.
    f(4, 2, 200, FULL, [16, 0, 16, -352, 16]),
    // Box starts east of the cell: no span, but forwarded.
    f(5, 5, 500, [6, 15, 0, 15, 0, 255], [0, 0, 16, -16 * 60, 8]),
    // Box ends at the cell: span 61 ..= 61, not forwarded.
    f(6, 6, 600, [0, 5, 0, 15, 0, 255], [0, 0, 16, -16 * 61, 8]),
    // An in/out edge (c_i = 0) that rejects the column: x ≤ 4.
    with_edge(f(7, 7, 700, FULL, [0, 0, 16, -16 * 62, 8]), [-1, 0, 0, 4]),
    // Same edge kind accepting the column (x ≤ 9), plus a z edge z ≤ 70 (c_i < 0).
    with_edge(with_edge(f(8, 8, 800, FULL, [3, -2, 16, -16 * 68, 40]), [-1, 0, 0, 9]), [0, 0, -1, 70]),
];

/// Pseudo-random thin facets (a fixed LCG), enough to overflow the 64-dexel store.
pub const N_RANDOM: usize = 80;
/// Total records in the table.
pub const N_FACETS: usize = HAND.len() + N_RANDOM;

const fn lcg(s: u64) -> u64 {
    s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407)
}

const fn random_facet(i: usize, s: u64) -> (FacetDef, u64) {
    let s1 = lcg(s);
    let s2 = lcg(s1);
    let s3 = lcg(s2);
    let z0 = ((s1 >> 33) % 250) as i32; // level at the cell
    let a = ((s2 >> 33) % 7) as i32 - 3; // gentle slope in x
    let b = ((s3 >> 33) % 7) as i32 - 3; // and in y
    let ks = 8 + ((s3 >> 40) % 24) as i32; // 1 to 3 voxels thick

    // P = a(x − X) + b(y − Y) + 16(z − z0)
    let d = -a * X as i32 - b * Y as i32 - 16 * z0;
    let id = (HAND.len() + i) as u32;
    let normal = 1000 + (i as u16 % 40); // a few repeat: some pieces merge
    (f(id, 9 + (i as u16 % 3), normal, FULL, [a, b, 16, d, ks]), s3)
}

const fn put(t: &mut [u8; RECORD * N_FACETS], at: usize, bytes: &[u8]) {
    let mut k = 0;
    while k < bytes.len() {
        t[at + k] = bytes[k];
        k += 1;
    }
}

const fn encode(t: &mut [u8; RECORD * N_FACETS], r: usize, d: &FacetDef) {
    let mut at = r * RECORD;
    put(t, at, &d.id.to_le_bytes());
    put(t, at + 4, &d.material.to_le_bytes());
    put(t, at + 6, &d.normal.to_le_bytes());
    at += 8;
    let mut k = 0;
    while k < 6 {
        put(t, at, &d.bbox[k].to_le_bytes());
        at += 2;
        k += 1;
    }
    k = 0;
    while k < 5 {
        put(t, at, &d.plane[k].to_le_bytes());
        at += 4;
        k += 1;
    }
    t[at] = d.n_edges;
    at += 1;
    k = 0;
    while k < REC_EDGES {
        let mut j = 0;
        while j < 4 {
            put(t, at, &d.edges[k][j].to_le_bytes());
            at += 4;
            j += 1;
        }
        k += 1;
    }
}

const fn build() -> [u8; RECORD * N_FACETS] {
    let mut t = [0u8; RECORD * N_FACETS];
    let mut r = 0;
    while r < HAND.len() {
        encode(&mut t, r, &HAND[r]);
        r += 1;
    }
    let mut s = 0x5EED_0005_0007_u64;
    let mut i = 0;
    while i < N_RANDOM {
        let (d, s2) = random_facet(i, s);
        s = s2;
        encode(&mut t, HAND.len() + i, &d);
        i += 1;
    }
    t
}

/// The packet table (the stand-in for a recorded trace), built at compile time.
pub static TABLE: [u8; RECORD * N_FACETS] = build();

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const K: usize>(&mut self) -> Option<[u8; K]> {
        let s = self.b.get(self.at..self.at.checked_add(K)?)?;
        self.at += K;
        let mut out = [0u8; K];
        out.copy_from_slice(s);
        Some(out)
    }
    fn u8(&mut self) -> Option<u8> {
        Some(self.take::<1>()?[0])
    }
    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take()?))
    }
    fn i32(&mut self) -> Option<i32> {
        Some(i32::from_le_bytes(self.take()?))
    }
}

/// Decode one record into the packet that reaches column (x, y): `t = Kσ − P(x, y)`,
/// `u = −Kσ − P(x, y)`, `g_i = a_i·x + b_i·y + d_i` (what the wave would have stepped it to).
/// `None` when the record is truncated or has too many edges.
pub fn decode(rec: &[u8], x: u16, y: u16) -> Option<RowPacket> {
    let mut r = Reader { b: rec, at: 0 };
    let tag = FacetTag { facet: r.u32()?, material: r.u16()?, normal: NormalCode(r.u16()?) };
    let bbox = FacetBox {
        x_min: r.u16()?,
        x_max: r.u16()?,
        y_min: r.u16()?,
        y_max: r.u16()?,
        z_min: r.u16()?,
        z_max: r.u16()?,
    };
    let (a, b, c, d, ks) = (r.i32()? as i64, r.i32()? as i64, r.i32()? as i64, r.i32()? as i64, r.i32()? as i64);
    let (x, y) = (x as i64, y as i64);
    let p = a * x + b * y + d;
    let mut pkt = RowPacket { tag, bbox, a, c, t: ks - p, u: -ks - p, edges: Default::default() };
    let n = r.u8()? as usize;
    if n > REC_EDGES {
        return None;
    }
    for k in 0..REC_EDGES {
        let (ea, eb, ec, ed) = (r.i32()?, r.i32()?, r.i32()?, r.i32()?);
        if k < n {
            let g = ea as i64 * x + eb as i64 * y + ed as i64;
            pkt.edges.push(RowEdge { a: ea, c: ec, g }).ok()?;
        }
    }
    Some(pkt)
}

/// FNV-1a, 64-bit.
pub struct Fnv(pub u64);

impl Fnv {
    pub const fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

/// What the run produced: the digest and a few counts for the log line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outcome {
    pub digest: u64,
    pub packets: u32,
    pub spans: u32,
    pub forwarded: u32,
    pub undecodable: u32,
    pub dexels: u32,
    pub voxels: u32,
    pub shared: u32,
    pub overflows: u32,
    pub lost: u32,
}

/// Drive a real `Cell<CAP>` at (X, Y) through every record of `table`, folding every output
/// (forward flag, stepped packet) and then the final state (every dexel, the counters).
pub fn run(table: &[u8]) -> Outcome {
    let mut cell: Cell<CAP> = Cell::new(X, Y);
    let mut h = Fnv::new();
    let (mut forwarded, mut undecodable) = (0u32, 0u32);
    for rec in table.chunks(RECORD) {
        match decode(rec, X, Y) {
            Some(mut pkt) => {
                let fwd = cell.load_step(&mut pkt, DEPTH);
                forwarded += fwd as u32;
                h.u64(fwd as u64);
                h.u64(pkt.t as u64);
                h.u64(pkt.u as u64);
                for e in &pkt.edges {
                    h.u64(e.g as u64);
                }
            }
            None => {
                undecodable += 1;
                h.u64(u64::MAX);
            }
        }
    }
    for dx in cell.store.dexels() {
        h.u64(dx.span.lo as u64);
        h.u64(dx.span.hi as u64);
        h.u64(dx.facet as u64);
        h.u64(dx.material as u64);
        h.u64(dx.normal.0 as u64);
    }
    let c = cell.counters;
    for v in [c.packets, c.spans_computed, c.voxels_shared, cell.store.overflows(), cell.store.lost_voxels()] {
        h.u64(v as u64);
    }
    Outcome {
        digest: h.0,
        packets: c.packets,
        spans: c.spans_computed,
        forwarded,
        undecodable,
        dexels: cell.store.dexels().len() as u32,
        voxels: cell.store.voxel_count(),
        shared: c.voxels_shared,
        overflows: cell.store.overflows(),
        lost: cell.store.lost_voxels(),
    }
}

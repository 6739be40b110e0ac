//! The reduction to the supervisor (radiosity thesis §3.4; rc2's merge): every cell's sorted
//! (patch, quanta) list merged westward along the rows, then northward along column 0, to the
//! supervisor at (0, 0) — one message per entry and link, an end marker per link, an entry
//! leaving a cell once each of its inputs has shown a key at least as large (a pipelined merge).
//! Beam shots ([`super::shots`]) reduce what their diffusion left in the cells; proxel shots
//! ([`super::proxels`]) cost their `reduce` update with it.
//!
//! **Invariant (tested):** the totals are the per-patch sums of the cells' lists, and the cycles
//! and messages are those of a hand count on small grids (`tests/integration/radiosity_grid.rs`).

use cell_core::radiosity::PatchId;

use crate::machine::grid::capacity::CellReceived;

/// A stream on a link: (patch, arrival cycle) by increasing patch, closed by an end marker
/// (patch [`END`]).
type Stream = Vec<(u32, u64)>;

/// The end marker's key.
const END: u32 = u32::MAX;

/// The pipelined merge of sorted streams in one cell, as it leaves on the cell's outgoing
/// link (arrival cycles at the receiver): entry p goes once every input has shown its first
/// key ≥ p (then no smaller or equal key can come), one message per cycle; equal keys leave
/// as one entry (their quanta added).
fn merge(inputs: &[&[(u32, u64)]]) -> Stream {
    let mut keys: Vec<u32> = inputs.iter().flat_map(|s| s.iter().map(|e| e.0)).collect();
    keys.sort_unstable();
    keys.dedup();
    let mut at = vec![0usize; inputs.len()];
    let (mut out, mut last) = (Vec::with_capacity(keys.len()), None::<u64>);
    for p in keys {
        let mut ready = 0;
        for (s, i) in inputs.iter().zip(at.iter_mut()) {
            while s[*i].0 < p {
                *i += 1;
            }
            ready = ready.max(s[*i].1);
        }
        let send = last.map_or(ready, |l| ready.max(l + 1));
        last = Some(send);
        out.push((p, send + 1));
    }
    out
}

/// The reduction of every cell's [`CellReceived`] to the supervisor at (0, 0): row streams
/// merged westward, then column 0 northward (module doc). Returns the patch totals, the cycle
/// the supervisor has the end marker, and the messages sent.
pub fn reduce_cost(n: u32, received: &[CellReceived]) -> (Vec<(PatchId, i64)>, u64, u64) {
    let entries: Vec<&[(PatchId, i64)]> = received.iter().map(|r| r.entries()).collect();
    reduce_entries(n, &entries)
}

/// [`reduce_cost`] of any per-cell (patch, quanta) lists, each sorted by patch.
pub fn reduce_entries<E: AsRef<[(PatchId, i64)]>>(n: u32, cells: &[E]) -> (Vec<(PatchId, i64)>, u64, u64) {
    let n = n as usize;
    let mut quanta = std::collections::BTreeMap::<PatchId, i64>::new();
    for &(p, q) in cells.iter().flat_map(|r| r.as_ref()) {
        *quanta.entry(p).or_insert(0) += q;
    }
    let own = |i: usize| -> Stream {
        let mut s: Stream = cells[i].as_ref().iter().map(|e| (e.0 as u32, 0)).collect();
        s.push((END, 0));
        s
    };
    let mut messages = 0u64;
    let mut from_south: Option<Stream> = None;
    for y in (0..n).rev() {
        let mut from_east: Option<Stream> = None;
        for x in (1..n).rev() {
            let mine = own(y * n + x);
            let ins: Vec<&[(u32, u64)]> = [Some(&mine[..]), from_east.as_deref()].into_iter().flatten().collect();
            let out = merge(&ins);
            messages += out.len() as u64;
            from_east = Some(out);
        }
        let mine = own(y * n);
        let ins: Vec<&[(u32, u64)]> =
            [Some(&mine[..]), from_east.as_deref(), from_south.as_deref()].into_iter().flatten().collect();
        let out = merge(&ins);
        messages += out.len() as u64;
        from_south = Some(out);
    }
    let cycles = from_south.as_ref().and_then(|s| s.last()).map_or(0, |e| e.1);
    let totals = quanta.into_iter().collect();
    (totals, cycles, messages)
}

//! Destination-addressed routing (§1.3, §4.1.3; `cell_core::route`, `host_sim::network`):
//! random all-to-all and adversarial traffic on grids with 2-message buffers is delivered
//! exactly once, to the right cell, in bounded cycles, and the stall detector never fires —
//! under both routing policies.

use cell_core::route::{RoutePolicy, Routed};
use host_sim::network::Network;

/// Run `traffic[cell]` (destinations, in injection order; each cell's compute unit injects at
/// most one message per cycle) to completion. Returns the cycles, or an error on a stall.
fn run(n: u32, policy: RoutePolicy, traffic: &[Vec<[u16; 2]>]) -> Result<(u64, Network<u32>), String> {
    let mut net: Network<u32> = Network::new(n, policy);
    let cells = (n * n) as usize;
    let mut next = vec![0usize; cells];
    let mut ids = Vec::new(); // message id → (source, destination)
    let mut base = vec![0u32; cells];
    for (c, t) in traffic.iter().enumerate() {
        base[c] = ids.len() as u32;
        ids.extend(t.iter().map(|d| (c, *d)));
    }
    let mut got = vec![0u32; ids.len()];
    let mut link_used = vec![false; cells * 8];
    let total = ids.len();
    let mut delivered = 0usize;
    let mut cycle = 0u64;
    while delivered < total {
        let mut moved = 0;
        for c in 0..cells {
            if let Some(&d) = traffic[c].get(next[c]) {
                let m = Routed { dest: d, payload: base[c] + next[c] as u32 };
                if net.inject(c, m) {
                    next[c] += 1;
                    moved += 1;
                }
            }
        }
        link_used.iter_mut().for_each(|u| *u = false);
        moved += net.step(&mut link_used, |cell, m| {
            let (_, dest) = ids[m.payload as usize];
            assert_eq!([(cell as u32 % n) as u16, (cell as u32 / n) as u16], dest, "delivered to the wrong cell");
            got[m.payload as usize] += 1;
            delivered += 1;
        });
        cycle += 1;
        if moved == 0 {
            return Err(format!("stall at cycle {cycle}: {} in flight", net.in_flight));
        }
    }
    assert!(got.iter().all(|&g| g == 1), "every message delivered exactly once");
    assert_eq!(net.in_flight, 0);
    Ok((cycle, net))
}

fn lcg(state: &mut u64) -> u64 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    *state >> 33
}

/// Every cell sends one message to every other cell, in a random order per cell.
fn all_to_all(n: u32, seed: u64) -> Vec<Vec<[u16; 2]>> {
    let mut s = seed;
    (0..n * n)
        .map(|c| {
            let mut d: Vec<[u16; 2]> =
                (0..n * n).filter(|&o| o != c).map(|o| [(o % n) as u16, (o / n) as u16]).collect();
            for i in (1..d.len()).rev() {
                d.swap(i, lcg(&mut s) as usize % (i + 1));
            }
            d
        })
        .collect()
}

#[test]
fn random_all_to_all_is_delivered_exactly_once() {
    for policy in [RoutePolicy::DiagonalFirst, RoutePolicy::Adaptive] {
        for (n, seed) in [(4u32, 1u64), (8, 2), (12, 3)] {
            let traffic = all_to_all(n, seed);
            let (cycles, net) = run(n, policy, &traffic).unwrap_or_else(|e| panic!("{policy:?} n = {n}: {e}"));
            // Each cell must eject n² − 1 messages at one per cycle: the lower bound. The
            // bound asserted leaves room for contention but catches livelock and starvation.
            let lb = (n * n - 1) as u64;
            println!(
                "{policy:?} n = {n}: {cycles} cycles (LB {lb}, ratio {:.2}), {} hops",
                cycles as f64 / lb as f64,
                net.hops
            );
            assert!(cycles <= 4 * lb + 4 * n as u64, "{policy:?} n = {n}: {cycles} cycles, LB {lb}");
            // Minimal routing: hops = Σ Chebyshev distances.
            let cheb: u64 = traffic
                .iter()
                .enumerate()
                .flat_map(|(c, t)| {
                    let (x, y) = ((c as u32 % n) as i64, (c as u32 / n) as i64);
                    t.iter().map(move |d| (d[0] as i64 - x).abs().max((d[1] as i64 - y).abs()) as u64)
                })
                .sum();
            assert_eq!(net.hops, cheb, "every path is minimal");
        }
    }
}

#[test]
fn hotspot_and_transpose_traffic() {
    let n = 16u32;
    for policy in [RoutePolicy::DiagonalFirst, RoutePolicy::Adaptive] {
        // Everyone sends 4 messages to one cell near a corner (the source in the shadow-ray
        // phase): the worst case for congestion.
        let hot: Vec<Vec<[u16; 2]>> = (0..n * n).map(|_| vec![[2, 13]; 4]).collect();
        let (cycles, _) = run(n, policy, &hot).unwrap();
        assert!(cycles >= (4 * n * n - 4) as u64, "ejection bound");
        assert!(cycles <= 2 * 4 * (n * n) as u64 + 4 * n as u64, "{policy:?}: {cycles}");
        // Transpose: (x, y) → (y, x), crossing traffic in all four quadrants.
        let tr: Vec<Vec<[u16; 2]>> = (0..n * n).map(|c| vec![[(c / n) as u16, (c % n) as u16]; 8]).collect();
        let (cycles, net) = run(n, policy, &tr).unwrap();
        println!(
            "{policy:?} transpose n = {n}: {cycles} cycles, peak link load {}",
            net.link_load.iter().max().unwrap()
        );
        assert!(cycles <= 8 * 8 * n as u64, "{policy:?}: {cycles}");
    }
}

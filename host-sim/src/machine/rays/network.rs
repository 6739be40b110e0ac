//! The routers of the whole grid (§1.3, §4.1.3): destination-addressed messages moving cycle by
//! cycle through [`cell_core::route::Router`]s, with per-link load counts.
//!
//! Cycle model (docs/ARCHITECTURE.md; thesis §4.4): a link carries at most one message per cycle and direction (shared
//! with the other traffic of the phase through `link_used`); a message moves only into free
//! space (credits); it makes at most one hop per cycle (the moves of a cycle are chosen from the
//! fronts of the channels as they were at its start); a router hands at most one delivered
//! message per cycle to its cell. The caller owns stall detection: a cycle with messages in
//! flight and nothing moving anywhere is a deadlock.

use cell_core::light::Port;
use cell_core::route::{RoutePolicy, Routed, Router};

/// Messages per output channel of the host's routers.
pub const ROUTE_CAP: usize = 2;
/// Delivered messages a router holds for its cell.
pub const INBOX_CAP: usize = 2;

/// The host's router type.
pub type HostRouter<P> = Router<P, ROUTE_CAP, INBOX_CAP>;

/// All routers of an n × n grid.
pub struct Network<P> {
    /// Grid side.
    pub n: u32,
    /// Routers, row-major.
    pub routers: Vec<HostRouter<P>>,
    /// Route choice.
    pub policy: RoutePolicy,
    /// Messages carried per link, index `cell·8 + port` (the sender's side).
    pub link_load: Vec<u32>,
    /// Messages in channels or inboxes.
    pub in_flight: u64,
    /// Link traversals.
    pub hops: u64,
    active: Vec<u32>,
    in_active: Vec<bool>,
    moves: Vec<(u32, u8, u8, u8)>,
}

impl<P: Copy> Network<P> {
    /// Empty routers.
    pub fn new(n: u32, policy: RoutePolicy) -> Self {
        let cells = (n * n) as usize;
        Network {
            n,
            routers: (0..cells).map(|_| Router::new()).collect(),
            policy,
            link_load: vec![0; cells * 8],
            in_flight: 0,
            hops: 0,
            active: Vec::new(),
            in_active: vec![false; cells],
            moves: Vec::new(),
        }
    }

    fn xy(&self, i: usize) -> [u16; 2] {
        [(i as u32 % self.n) as u16, (i as u32 / self.n) as u16]
    }

    fn wake(&mut self, i: usize) {
        if !self.in_active[i] {
            self.in_active[i] = true;
            self.active.push(i as u32);
        }
    }

    /// The cell's compute unit hands a message to its router; `false` (message kept by the
    /// caller) when the channel it needs is full.
    pub fn inject(&mut self, cell: usize, m: Routed<P>) -> bool {
        let r = &mut self.routers[cell];
        let hop = r.route([(cell as u32 % self.n) as u16, (cell as u32 / self.n) as u16], m.dest, self.policy);
        if r.push(hop, m).is_err() {
            return false;
        }
        self.in_flight += 1;
        self.wake(cell);
        true
    }

    /// Whether the router of `cell` could take a message for `dest` from its cell now.
    pub fn can_inject(&self, cell: usize, dest: [u16; 2]) -> bool {
        let r = &self.routers[cell];
        r.can_take(r.route(self.xy(cell), dest, self.policy))
    }

    /// One cycle of the routers: link moves (skipping links already used this cycle, marking
    /// the ones used), then at most one delivery per router, passed to `deliver(cell, msg)`.
    /// Returns the number of moves and deliveries.
    pub fn step(&mut self, link_used: &mut [bool], mut deliver: impl FnMut(usize, Routed<P>)) -> u64 {
        let n = self.n as i64;
        self.active.sort_unstable();
        self.moves.clear();
        for &i in &self.active {
            for p in Port::ALL {
                let r = &self.routers[i as usize];
                let [c0, c1] = r.candidates(p);
                let f0 = r.peek(c0).is_some();
                let f1 = c1 != c0 && r.peek(c1).is_some();
                if f0 || f1 {
                    // Channels empty at the start of the cycle are marked 0xff: a message that
                    // arrives during the cycle does not move again in it.
                    self.moves.push((i, p as u8, if f0 { c0 } else { 0xff }, if f1 { c1 } else { 0xff }));
                }
            }
        }
        let mut moved = 0;
        let moves = std::mem::take(&mut self.moves);
        for &(i, p, c0, c1) in &moves {
            let i = i as usize;
            let link = i * 8 + p as usize;
            if link_used[link] {
                continue;
            }
            let (dx, dy) = Port::ALL[p as usize].delta();
            let j = (i as i64 + dy as i64 * n + dx as i64) as usize;
            for c in [c0, c1] {
                if c == 0xff {
                    continue;
                }
                let Some(m) = self.routers[i].peek(c) else { continue };
                let m = *m;
                let hop = self.routers[j].route(self.xy(j), m.dest, self.policy);
                if !self.routers[j].can_take(hop) {
                    self.routers[i].counters.refused += 1;
                    continue;
                }
                let _ = self.routers[i].pop(c);
                let _ = self.routers[j].push(hop, m);
                link_used[link] = true;
                self.link_load[link] += 1;
                self.hops += 1;
                moved += 1;
                self.wake(j);
                break;
            }
        }
        self.moves = moves;
        let active = std::mem::take(&mut self.active);
        for &i in &active {
            if let Some(m) = self.routers[i as usize].inbox.pop_front() {
                self.in_flight -= 1;
                moved += 1;
                deliver(i as usize, m);
            }
        }
        self.active = active;
        let routers = &self.routers;
        let in_active = &mut self.in_active;
        self.active.retain(|&i| {
            let keep = !routers[i as usize].is_empty();
            in_active[i as usize] = keep;
            keep
        });
        moved
    }

    /// Router cells holding messages (for deadlock reports).
    pub fn busy_cells(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.active.iter().map(|&i| (i as usize, self.routers[i as usize].occupancy()))
    }
}

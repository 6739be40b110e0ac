//! Quiescence (thesis §4.4.4): the global count of beams in flight ([`Activity`]), exact by
//! construction — incremented before a beam becomes visible, decremented when one is consumed.

use super::*;

/// Beams in flight in the whole machine: the global activity detector (§4.4.4).
pub struct Activity {
    count: Mutex<CoreCell<u64>>,
}

impl Default for Activity {
    fn default() -> Self {
        Self::new()
    }
}

impl Activity {
    /// Nothing in flight.
    pub const fn new() -> Self {
        Activity { count: Mutex::new(CoreCell::new(0)) }
    }

    /// `n` beams appeared (before they become visible to any cell).
    pub fn add(&self, n: u64) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get() + n);
        });
    }

    /// One beam was consumed.
    pub fn consume(&self) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get().saturating_sub(1));
        });
    }

    /// Beams in flight.
    pub fn get(&self) -> u64 {
        critical_section::with(|cs| self.count.borrow(cs).get())
    }

    /// No beam anywhere: the diffusion of the current source is over.
    pub fn is_quiescent(&self) -> bool {
        self.get() == 0
    }
}

/// Counts beams appearing and being consumed: the machine-wide [`Activity`], or an
/// [`ActivityDelta`] that a host simulating many cells at once keeps per worker and adds to the
/// [`Activity`] at the end of a phase ([`Activity::apply`]).
pub trait BeamTally {
    /// `n` beams appeared.
    fn add(&self, n: u64);
    /// One beam was consumed.
    fn consume(&self);
}

impl BeamTally for Activity {
    fn add(&self, n: u64) {
        Activity::add(self, n);
    }
    fn consume(&self) {
        Activity::consume(self);
    }
}

/// A local, unsynchronised change of the beam count (not `Sync`: one per worker). Sound
/// because quiescence is only read between phases, after every delta has been applied.
#[derive(Debug, Default)]
pub struct ActivityDelta(CoreCell<i64>);

impl ActivityDelta {
    /// No change yet.
    pub const fn new() -> Self {
        ActivityDelta(CoreCell::new(0))
    }

    /// Net change so far (appeared − consumed).
    pub fn get(&self) -> i64 {
        self.0.get()
    }
}

impl BeamTally for ActivityDelta {
    fn add(&self, n: u64) {
        self.0.set(self.0.get() + n as i64);
    }
    fn consume(&self) {
        self.0.set(self.0.get() - 1);
    }
}

impl Activity {
    /// Add a worker's net change (one critical section per phase instead of one per beam).
    pub fn apply(&self, delta: i64) {
        critical_section::with(|cs| {
            let c = self.count.borrow(cs);
            c.set(c.get().saturating_add_signed(delta));
        });
    }
}

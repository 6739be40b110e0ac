//! The termination exercise's glue (the exercise itself, its protocol and invariant, is
//! `boards::safra`, a sans-IO state machine the host tests drive with in-memory links): drive
//! a [`SafraBoard`] with the board's serial links and its clock (µs), and sleep when it is
//! idle.
//!
//! **Invariant**: every pass polls every connected link's bytes before the board looks at its
//! frames, and the board sleeps only when it has no item queued or in progress (an item's busy
//! time is measured by the clock), so the glue adds no state of its own.

use boards::safra::SafraBoard;
use boards::LINKS;

pub use boards::safra::Config;

use crate::Board;

/// Run the termination exercise for ever (the host stops the board).
pub fn run(mut board: Board, c: Config) -> ! {
    let mut safra = SafraBoard::new(c);
    loop {
        let now = board.now();
        for l in 0..=LINKS {
            if l == 0 || c.ring.connected(l - 1) {
                board.poll(l, now);
            }
        }
        // The clock again: the links' bytes took time, which an item's busy time counts.
        let now = board.now();
        let _ = safra.poll(&mut board.links, now);
        if safra.idle() {
            board.wait();
        }
    }
}

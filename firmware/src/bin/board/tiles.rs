//! The tile exercise's glue (the exercise itself, its protocol and invariant, is
//! `boards::tiles`, a sans-IO state machine the host tests drive with in-memory links): wait
//! for the light setups on the host link (one per source), then drive a [`TileBoard`] with the board's serial
//! links, log what it did (the QEMU test checks the log) and sleep when it is idle.
//!
//! **Invariant**: every pass polls every connected link's bytes before the board looks at its
//! frames, and the board sleeps only when it is idle (nothing to do but wait for a frame), so
//! the glue adds no state of its own: the board's behaviour is `boards::tiles`'s.

use boards::tiles::{light_setup, TileBoard, SOURCES};
#[cfg(feature = "defmt")]
use boards::Event;
use boards::{Links, LINKS};
use cell_core::beam::SplitOrder;
use cell_core::serial::{SerialLink, SerialStats};
use cell_core::trace::LightSetup;
use cell_core::wire::board::KIND_TILE_LIGHT;
use cell_core::wire::RawFrame;

pub use boards::tiles::Config;

use crate::{stack, Board, LINK_BUF, TIMEOUT_US};

/// The board's serial links as [`Links`], with the stack's high-water mark for the report.
struct Wires<'a>(&'a mut [SerialLink<LINK_BUF>; 5]);

impl Links for Wires<'_> {
    fn received(&self, l: usize) -> Option<RawFrame<'_>> {
        self.0.received(l)
    }
    fn pop(&mut self, l: usize) {
        self.0.pop(l)
    }
    fn can_send(&self, l: usize) -> bool {
        self.0.can_send(l)
    }
    fn send(&mut self, l: usize, kind: u8, body: &[u8]) -> bool {
        self.0.send(l, kind, body)
    }
    fn stats(&self, l: usize) -> SerialStats {
        self.0[l].stats()
    }
    fn stack_peak(&self) -> u32 {
        stack::peak() as u32
    }
}

/// Wait for the light setups on the host link (the host sends them right after the
/// configuration, one per source in order), then run the exercise.
pub fn run(mut board: Board, c: Config) -> ! {
    // The neighbour links carry row and pipeline packets: lift the short exercises' frame
    // limit. They have carried nothing yet (nothing goes between boards before the start).
    for l in &mut board.links[1..] {
        *l = SerialLink::new(TIMEOUT_US);
    }
    let mut setups: heapless::Vec<LightSetup, SOURCES> = heapless::Vec::new();
    while setups.len() < usize::from(c.sources) {
        let now = board.now();
        board.poll(0, now);
        let Some(f) = board.links[0].received() else {
            board.wait();
            continue;
        };
        let s = (f.kind == KIND_TILE_LIGHT).then(|| light_setup(f.payload)).flatten();
        board.links[0].pop();
        if let Some(s) = s.filter(|s| s.n == u32::from(c.n) && s.depth == u32::from(c.depth)) {
            let _ = setups.push(s);
        }
    }
    let order = SplitOrder::default();
    let envs = setups.iter().map(|s| s.env(&order)).collect::<Result<heapless::Vec<_, SOURCES>, _>>();
    let Ok(envs) = envs else { panic!("light setup beyond the bit budget") };
    let mut tile = TileBoard::new(c, envs);
    log!(
        "board {=u8}: state {=usize} B ({=usize} B a cell, {=usize} cells at most)",
        c.ring.id,
        core::mem::size_of::<TileBoard>(),
        boards::tiles::CELL_BYTES,
        boards::tiles::SIDE * boards::tiles::SIDE
    );
    log!(
        "board {=u8}: tile of {=u16} x {=u16} cells at ({=u16}, {=u16}), ring position {=u8}, {=usize} of {=u8} sources here",
        c.ring.id,
        c.side,
        c.side,
        c.x0,
        c.y0,
        c.ring.position,
        tile.holds_sources(),
        c.sources
    );
    loop {
        let now = board.now();
        for l in 0..=LINKS {
            if l == 0 || c.ring.connected(l - 1) {
                board.poll(l, now);
            }
        }
        let _events = tile.poll(&mut Wires(&mut board.links));
        #[cfg(feature = "defmt")]
        log_events(&c, &tile, &_events);
        if tile.idle() {
            board.wait();
        }
    }
}

/// Log what the board did (the QEMU test checks these lines).
#[cfg(feature = "defmt")]
fn log_events(c: &Config, tile: &TileBoard, events: &[Event]) {
    let st = tile.state();
    for e in events {
        match *e {
            Event::Entered(p) => {
                log!(
                    "board {=u8}: entered phase {=u16} ({=u32} frames sent, {=u32} received)",
                    c.ring.id,
                    p,
                    st.sent,
                    st.received
                );
            }
            Event::Declared(p) => {
                log!("board {=u8}: declared the end of phase {=u16}", c.ring.id, p);
            }
            Event::Queried => {
                log!(
                    "board {=u8}: report ({=u32} late, {=u32} overflows, {=u32} beams forwarded)",
                    c.ring.id,
                    st.late,
                    st.overflows,
                    st.forwarded
                );
            }
        }
    }
}

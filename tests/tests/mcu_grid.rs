//! A grid of microcontrollers on real serial links: 2 × 2 emulated Cortex-M4F boards (four
//! QEMU `mps2-an386` processes running `firmware/src/bin/board`), each UART a TCP character
//! device to a port this test listens on. The test relays the bytes between neighbouring
//! boards' UARTs (E ↔ W, N ↔ S), in the fault runs corrupting and dropping bytes on the
//! wire from a seeded generator, and talks to each board's host link (UART 0) itself, through
//! the same `cell_core::serial::SerialLink` the boards run.
//!
//! Each board sends [`COUNT`] data frames on each of its links and checks the frames it
//! receives against what its neighbour sent, in order (the board's doc has the exercise); its
//! report must say every frame arrived exactly once, unaltered, and every one it sent was
//! acknowledged. A board that does not report within [`GRID_TIMEOUT`] fails the test, with
//! every board's QEMU output; every QEMU child is killed on every exit path.
//!
//! This proves the links of the MCU grid (issue 25, item 4: the UART driver, the frame link
//! with its CRC, acknowledgement and no loss). The boards do not run tiles of cells yet.
//!
//! Needs `qemu-system-arm` and the `thumbv7em-none-eabihf` target: under CI a missing tool is
//! a failure, elsewhere a skip ([`rc2_tests::qemu::tools_present`]).

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cell_core::serial::SerialLink;
use rc2_tests::qemu::{self, QEMU};

/// Data frames each board sends on each of its links.
const COUNT: u16 = 120;
/// The whole run (boot, exercise, reports) must end within this.
const GRID_TIMEOUT: Duration = Duration::from_secs(60);
/// Grid side: `SIDE × SIDE` boards.
const SIDE: usize = 2;
/// Frame kinds of the exercise (firmware/src/bin/board/main.rs).
const KIND_CONFIG: u8 = 0x60;
const KIND_REPORT: u8 = 0x61;
/// Link buffer of the host's end (the board's `LINK_BUF`).
const LINK_BUF: usize = 128;
/// No neighbour.
const NONE: u8 = 0xFF;

/// The board image, built once per test binary.
fn board_elf() -> &'static Path {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware-board");
        qemu::build_firmware(&dir, None, &["--bin", "board"]).join("board")
    })
}

/// The QEMU runs share two cores with everything else: one grid at a time.
static ONE_GRID: Mutex<()> = Mutex::new(());

/// Faults injected on every inter-board byte stream, per 10 000 bytes.
#[derive(Clone, Copy, Debug)]
struct Faults {
    corrupt: u64,
    drop: u64,
    seed: u64,
}

const CLEAN: Faults = Faults { corrupt: 0, drop: 0, seed: 0 };

/// Neighbour of board `b` on link `l` (0 E, 1 N, 2 W, 3 S), if any; board `b` is at
/// `(b % SIDE, b / SIDE)`, N is +y.
fn neighbour(b: usize, l: usize) -> Option<usize> {
    let (x, y) = (b % SIDE, b / SIDE);
    let (nx, ny) = match l {
        0 => (x + 1, y),
        1 => (x, y + 1),
        2 => (x.checked_sub(1)?, y),
        _ => (x, y.checked_sub(1)?),
    };
    (nx < SIDE && ny < SIDE).then_some(ny * SIDE + nx)
}

/// The QEMU processes and relay threads of one grid: killed and stopped when dropped, whatever
/// the test's path out.
struct Grid {
    boards: Vec<Child>,
    output: Vec<Arc<Mutex<String>>>,
    stop: Arc<AtomicBool>,
    relays: Vec<JoinHandle<(u64, u64)>>,
}

impl Grid {
    /// Every board's QEMU output so far (a panic message, QEMU's own errors).
    fn outputs(&self) -> String {
        let mut s = String::new();
        for (b, o) in self.output.iter().enumerate() {
            s += &format!("--- board {b} ---\n{}\n", o.lock().unwrap());
        }
        s
    }

    /// Stop the relays; returns (bytes relayed, faults injected).
    fn stop_relays(&mut self) -> (u64, u64) {
        self.stop.store(true, Ordering::SeqCst);
        self.relays.drain(..).map(|h| h.join().unwrap_or((0, 0))).fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }
}

impl Drop for Grid {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for c in &mut self.boards {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Accept the connection QEMU makes to `l`, within the deadline.
fn accept(l: &TcpListener, deadline: Instant, grid: &Grid) -> TcpStream {
    l.set_nonblocking(true).unwrap();
    loop {
        match l.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false).unwrap();
                s.set_nodelay(true).unwrap();
                return s;
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(5))
            }
            Err(e) => panic!("a board's UART did not connect ({e}); QEMU said:\n{}", grid.outputs()),
        }
    }
}

/// xorshift64*: the relays' fault generator.
fn next(rng: &mut u64) -> u64 {
    *rng ^= *rng >> 12;
    *rng ^= *rng << 25;
    *rng ^= *rng >> 27;
    rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11
}

/// Copy bytes from `src` to `dst` until `stop`, corrupting (flipping bits of) and dropping
/// bytes as `faults` says. Returns (bytes read, faults injected).
fn relay(mut src: TcpStream, mut dst: TcpStream, faults: Faults, stream: u64, stop: Arc<AtomicBool>) -> (u64, u64) {
    let mut rng = (faults.seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15)) | 1;
    src.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
    let (mut bytes, mut injected) = (0, 0);
    let mut buf = [0u8; 256];
    let mut out = Vec::with_capacity(256);
    while !stop.load(Ordering::SeqCst) {
        let n = match src.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => continue,
            Err(_) => break,
        };
        bytes += n as u64;
        out.clear();
        for &b in &buf[..n] {
            let r = next(&mut rng) % 10_000;
            if r < faults.drop {
                injected += 1;
            } else if r < faults.drop + faults.corrupt {
                injected += 1;
                out.push(b ^ (next(&mut rng) % 255 + 1) as u8);
            } else {
                out.push(b);
            }
        }
        if dst.write_all(&out).is_err() {
            break;
        }
    }
    (bytes, injected)
}

/// The host's end of a board's UART 0: a TCP stream behind `embedded-io`, never blocking on
/// read.
struct HostPort {
    s: TcpStream,
    peeked: Option<u8>,
}

impl embedded_io::ErrorType for HostPort {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::ReadReady for HostPort {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        if self.peeked.is_some() {
            return Ok(true);
        }
        let mut b = [0u8; 1];
        match self.s.read(&mut b) {
            Ok(0) => Err(embedded_io::ErrorKind::BrokenPipe),
            Ok(_) => {
                self.peeked = Some(b[0]);
                Ok(true)
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(false),
            Err(_) => Err(embedded_io::ErrorKind::Other),
        }
    }
}

impl embedded_io::Read for HostPort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        match (self.peeked.take(), buf.is_empty()) {
            (_, true) => Ok(0),
            (Some(b), false) => {
                buf[0] = b;
                Ok(1)
            }
            (None, false) => loop {
                if embedded_io::ReadReady::read_ready(self)? {
                    return self.read(buf);
                }
                std::thread::sleep(Duration::from_millis(1));
            },
        }
    }
}

impl embedded_io::WriteReady for HostPort {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(true)
    }
}

impl embedded_io::Write for HostPort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.s.set_nonblocking(false).map_err(|_| embedded_io::ErrorKind::Other)?;
        let r = self.s.write(buf).map_err(|_| embedded_io::ErrorKind::BrokenPipe);
        self.s.set_nonblocking(true).map_err(|_| embedded_io::ErrorKind::Other)?;
        r
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// One link of a board's report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LinkReport {
    received: u16,
    mismatches: u16,
    sent: u32,
    acked: u32,
    retransmitted: u32,
    duplicates: u32,
    skipped: u32,
    overruns: u32,
}

fn parse_report(p: &[u8]) -> (u8, [LinkReport; 4]) {
    assert_eq!(p.len(), 1 + 4 * 28, "report length");
    let u16_at = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes(p[i..i + 4].try_into().unwrap());
    let links = std::array::from_fn(|l| {
        let o = 1 + 28 * l;
        LinkReport {
            received: u16_at(o),
            mismatches: u16_at(o + 2),
            sent: u32_at(o + 4),
            acked: u32_at(o + 8),
            retransmitted: u32_at(o + 12),
            duplicates: u32_at(o + 16),
            skipped: u32_at(o + 20),
            overruns: u32_at(o + 24),
        }
    });
    (p[0], links)
}

/// What a grid run gave: each board's report, bytes relayed, faults injected, wall time.
struct Run {
    reports: Vec<[LinkReport; 4]>,
    bytes: u64,
    injected: u64,
    wall: Duration,
}

/// Boot the 2 × 2 grid, configure it, relay with `faults`, collect every board's report.
fn run_grid(faults: Faults) -> Run {
    let elf = board_elf();
    let boards = SIDE * SIDE;
    let t0 = Instant::now();
    let deadline = t0 + GRID_TIMEOUT;
    // One listener per connected UART: 0 (host link) and each link with a neighbour.
    let listeners: Vec<Vec<Option<TcpListener>>> = (0..boards)
        .map(|b| {
            (0..5)
                .map(|u| (u == 0 || neighbour(b, u - 1).is_some()).then(|| TcpListener::bind("127.0.0.1:0").unwrap()))
                .collect()
        })
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let mut grid = Grid { boards: Vec::new(), output: Vec::new(), stop: stop.clone(), relays: Vec::new() };
    for ls in &listeners {
        let mut cmd = Command::new(QEMU);
        cmd.args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-display", "none", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"]);
        for (u, l) in ls.iter().enumerate() {
            match l {
                Some(l) => {
                    let port = l.local_addr().unwrap().port();
                    cmd.arg("-chardev").arg(format!("socket,id=u{u},host=127.0.0.1,port={port},server=off"));
                    cmd.arg("-serial").arg(format!("chardev:u{u}"));
                }
                None => {
                    cmd.args(["-serial", "null"]);
                }
            }
        }
        let mut child = cmd
            .arg("-kernel")
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start qemu-system-arm");
        let out = Arc::new(Mutex::new(String::new()));
        for mut pipe in
            [Box::new(child.stdout.take().unwrap()) as Box<dyn Read + Send>, Box::new(child.stderr.take().unwrap())]
        {
            let out = out.clone();
            std::thread::spawn(move || {
                let mut buf = [0u8; 512];
                while let Ok(n @ 1..) = pipe.read(&mut buf) {
                    out.lock().unwrap().push_str(&String::from_utf8_lossy(&buf[..n]));
                }
            });
        }
        grid.boards.push(child);
        grid.output.push(out);
    }
    let mut socks: Vec<Vec<Option<TcpStream>>> = listeners
        .iter()
        .map(|ls| ls.iter().map(|l| l.as_ref().map(|l| accept(l, deadline, &grid))).collect())
        .collect();

    // Relays: link l of board b to link (l + 2) % 4 of its neighbour, each direction once.
    let mut stream = 0;
    for b in 0..boards {
        for l in 0..2 {
            let Some(c) = neighbour(b, l) else { continue };
            let here = socks[b][l + 1].take().unwrap();
            let there = socks[c][(l + 2) % 4 + 1].take().unwrap();
            for (src, dst) in [(here.try_clone().unwrap(), there.try_clone().unwrap()), (there, here)] {
                let stop = stop.clone();
                stream += 1;
                let s = stream;
                grid.relays.push(std::thread::spawn(move || relay(src, dst, faults, s, stop)));
            }
        }
    }

    // Host links: configure every board, then wait for every report.
    let mut hosts: Vec<(HostPort, SerialLink<LINK_BUF>)> = socks
        .iter_mut()
        .map(|s| {
            let s = s[0].take().unwrap();
            s.set_nonblocking(true).unwrap();
            (HostPort { s, peeked: None }, SerialLink::new(100))
        })
        .collect();
    for (b, (_, link)) in hosts.iter_mut().enumerate() {
        let mut config = vec![b as u8];
        config.extend((0..4).map(|l| neighbour(b, l).map_or(NONE, |c| c as u8)));
        config.extend(COUNT.to_le_bytes());
        link.send(KIND_CONFIG, &config).unwrap();
    }
    let mut reports: Vec<Option<[LinkReport; 4]>> = vec![None; boards];
    while reports.iter().any(Option::is_none) {
        let now = t0.elapsed().as_millis() as u64;
        if Instant::now() > deadline {
            let missing: Vec<usize> = (0..boards).filter(|&b| reports[b].is_none()).collect();
            panic!(
                "boards {missing:?} did not report within {GRID_TIMEOUT:?} (a hang, or a lost frame); \
                 reports so far: {reports:?}\nQEMU said:\n{}",
                grid.outputs()
            );
        }
        for (b, (port, link)) in hosts.iter_mut().enumerate() {
            if let Err(e) = link.poll(now, port) {
                panic!("board {b}'s host link failed ({e:?}): its QEMU stopped?\nQEMU said:\n{}", grid.outputs());
            }
            if let Some(f) = link.received() {
                assert_eq!(f.kind, KIND_REPORT, "board {b} sent an unknown frame");
                let (id, r) = parse_report(f.payload);
                assert_eq!(id as usize, b, "board {b} reported as {id}");
                assert!(reports[b].is_none(), "board {b} reported twice");
                reports[b] = Some(r);
                link.pop();
            }
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    // Acknowledge the reports before the boards go.
    let settle = Instant::now();
    while hosts.iter().any(|(_, l)| !l.idle()) && settle.elapsed() < Duration::from_secs(1) {
        let now = t0.elapsed().as_millis() as u64;
        for (port, link) in &mut hosts {
            let _ = link.poll(now, port);
        }
    }
    let wall = t0.elapsed();
    let (bytes, injected) = grid.stop_relays();
    drop(grid);
    Run { reports: reports.into_iter().map(Option::unwrap).collect(), bytes, injected, wall }
}

/// Every board received every frame of each neighbour exactly once, unaltered and in order,
/// and had all of its own acknowledged; returns the links' total retransmissions and skipped
/// bytes.
fn check_exactly_once(run: &Run) -> (u32, u32) {
    let (mut retransmitted, mut skipped) = (0, 0);
    for (b, r) in run.reports.iter().enumerate() {
        for (l, link) in r.iter().enumerate() {
            if neighbour(b, l).is_none() {
                assert_eq!(*link, LinkReport::default(), "board {b} link {l} has no neighbour");
                continue;
            }
            assert_eq!(
                (link.received, link.mismatches, link.sent, link.acked),
                (COUNT, 0, COUNT as u32, COUNT as u32),
                "board {b} link {l}: received, mismatched, sent, acknowledged ({link:?})"
            );
            assert_eq!(link.overruns, 0, "board {b} link {l}: the UART lost bytes");
            retransmitted += link.retransmitted;
            skipped += link.skipped;
        }
    }
    (retransmitted, skipped)
}

#[test]
fn a_2x2_grid_of_boards_exchanges_every_frame_exactly_once() {
    if !qemu::tools_present("a_2x2_grid_of_boards_exchanges_every_frame_exactly_once") {
        return;
    }
    let _one = ONE_GRID.lock().unwrap_or_else(|e| e.into_inner());
    let run = run_grid(CLEAN);
    let (retransmitted, skipped) = check_exactly_once(&run);
    eprintln!(
        "clean wire: {} bytes relayed in {:?}, {retransmitted} retransmissions, {skipped} bytes skipped",
        run.bytes, run.wall
    );
    assert_eq!(run.injected, 0, "a clean wire corrupts nothing");
}

#[test]
fn corrupted_and_dropped_bytes_between_boards_are_recovered_by_the_link() {
    if !qemu::tools_present("corrupted_and_dropped_bytes_between_boards_are_recovered_by_the_link") {
        return;
    }
    let _one = ONE_GRID.lock().unwrap_or_else(|e| e.into_inner());
    // About one byte in 250 corrupted and one in 250 dropped: some 10 % of the data frames.
    let run = run_grid(Faults { corrupt: 40, drop: 40, seed: 0x5AFE_2025 });
    let (retransmitted, skipped) = check_exactly_once(&run);
    eprintln!(
        "faulty wire: {} bytes relayed in {:?}, {} faults injected, {retransmitted} retransmissions, \
         {skipped} bytes skipped",
        run.bytes, run.wall, run.injected
    );
    assert!(run.injected > 0, "the relays injected no fault");
    assert!(retransmitted > 0 && skipped > 0, "faults were injected, so the links must have repaired some");
}

//! The host's side of the grid of boards on serial links (`firmware/src/bin/board`), shared by
//! the tests that run it (`mcu_grid.rs`: the link and termination exercises; `mcu_tiles.rs`:
//! tiles of cells loading and lighting a scene): 2 × 2 QEMU `mps2-an386` processes whose UARTs
//! are TCP character devices connected to ports the test listens on, the relays between
//! neighbouring boards' UARTs (which can corrupt, drop and hold back bytes), and the host's end
//! of each board's UART 0 (a `cell_core::serial::SerialLink` over the TCP stream).
//!
//! **Invariant**: every QEMU child of a [`Grid`] is killed when the grid is dropped, whatever
//! the test's path out; [`Booted::poll`] fails the test past its deadline (a hang) or when a
//! host link fails (a QEMU gone), with every board's output.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cell_core::serial::SerialLink;

use crate::qemu::{self, QEMU};

/// Grid side: `SIDE × SIDE` boards.
pub const SIDE: usize = 2;
/// Link buffer of the host's end (the board's `LINK_BUF`).
pub const LINK_BUF: usize = 512;
/// No neighbour.
pub const NONE: u8 = 0xFF;
pub use cell_core::wire::board::{KIND_DONE, KIND_QUERY, KIND_START};

/// The board image, built once per test run under `tmp` (the test's
/// `env!("CARGO_TARGET_TMPDIR")`, which only integration tests see).
pub fn board_elf(tmp: &Path) -> &'static Path {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        let dir = tmp.join("firmware-board");
        // With its defmt log (stdout over semihosting), which a failing test shows decoded, and
        // the default cell's features (exact occluders and rays from the light in cell-core: the
        // boards run `render`'s lit rule).
        qemu::build_firmware(&dir, None, &["--bin", "board", "--features", "defmt"]).join("board")
    })
}

/// Faults injected on every inter-board byte stream, per 10 000 bytes.
#[derive(Clone, Copy, Debug)]
pub struct Faults {
    pub corrupt: u64,
    pub drop: u64,
    pub seed: u64,
}

pub const CLEAN: Faults = Faults { corrupt: 0, drop: 0, seed: 0 };

/// Wires that deliver their bytes late (a delay line, [`relay`]).
#[derive(Clone, Copy, Debug)]
pub enum Slow {
    /// Both directions of every link of the board.
    Board(usize, Duration),
    /// One direction of one link: the bytes board `from` sends board `to`.
    Wire { from: usize, to: usize, delay: Duration },
}

impl Slow {
    /// The delay of the bytes board `from` sends board `to`.
    pub fn delay(self, from: usize, to: usize) -> Duration {
        match self {
            Slow::Board(b, d) if b == from || b == to => d,
            Slow::Wire { from: f, to: t, delay } if (f, t) == (from, to) => delay,
            _ => Duration::ZERO,
        }
    }
}

/// Neighbour of board `b` on link `l` (0 E, 1 N, 2 W, 3 S), if any; board `b` is at
/// `(b % SIDE, b / SIDE)`, N is +y.
pub fn neighbour(b: usize, l: usize) -> Option<usize> {
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
pub struct Grid {
    pub boards: Vec<Child>,
    /// The image the boards run (its defmt table decodes their logs).
    pub elf: PathBuf,
    /// Each board's stdout: its defmt log frames, as they came.
    pub log: Vec<Arc<Mutex<Vec<u8>>>>,
    /// Each board's stderr: a panic's message, QEMU's own errors.
    pub output: Vec<Arc<Mutex<String>>>,
    pub stop: Arc<AtomicBool>,
    pub relays: Vec<JoinHandle<(u64, u64)>>,
}

impl Grid {
    /// Every board's QEMU output so far: its log, decoded ([`Grid::logs`]), then its stderr
    /// (a panic message, QEMU's own errors).
    pub fn outputs(&self) -> String {
        let mut s = String::new();
        for (b, (log, o)) in self.logs().iter().zip(&self.output).enumerate() {
            s += &format!("--- board {b} ---\n{}\n{}\n", log.join("\n"), o.lock().unwrap());
        }
        s
    }

    /// Every board's defmt log so far, decoded with the image's table, a line per frame.
    pub fn logs(&self) -> Vec<Vec<String>> {
        let elf = std::fs::read(&self.elf).unwrap_or_default();
        self.log.iter().map(|l| decode_log(&elf, &l.lock().unwrap())).collect()
    }

    /// Stop the relays; returns (bytes relayed, faults injected).
    pub fn stop_relays(&mut self) -> (u64, u64) {
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
pub fn accept(l: &TcpListener, deadline: Instant, grid: &Grid) -> TcpStream {
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
pub fn next(rng: &mut u64) -> u64 {
    *rng ^= *rng >> 12;
    *rng ^= *rng << 25;
    *rng ^= *rng >> 27;
    rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11
}

/// Copy bytes from `src` to `dst` until `stop`, corrupting (flipping bits of) and dropping
/// bytes as `faults` says, every byte delivered `delay` after it was read (a delay line: the
/// wire's latency grows, its throughput does not shrink, and the bytes keep their order).
/// Returns (bytes read, faults injected).
pub fn relay(
    (mut src, mut dst): (TcpStream, TcpStream),
    faults: Faults,
    stream: u64,
    delay: Duration,
    stop: Arc<AtomicBool>,
) -> (u64, u64) {
    let mut rng = (faults.seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15)) | 1;
    let tick = if delay.is_zero() { Duration::from_millis(20) } else { Duration::from_millis(5) };
    src.set_read_timeout(Some(tick)).unwrap();
    let (mut bytes, mut injected) = (0, 0);
    let mut buf = [0u8; 256];
    let mut line: VecDeque<(Instant, Vec<u8>)> = VecDeque::new();
    while !stop.load(Ordering::SeqCst) {
        match src.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                bytes += n as u64;
                let mut out = Vec::with_capacity(n);
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
                line.push_back((Instant::now() + delay, out));
            }
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
        while line.front().is_some_and(|(at, _)| *at <= Instant::now()) {
            let Some((_, out)) = line.pop_front() else { break };
            if dst.write_all(&out).is_err() {
                return (bytes, injected);
            }
        }
    }
    (bytes, injected)
}

/// The host's end of a board's UART 0: a TCP stream behind `embedded-io`, never blocking on
/// read.
pub struct HostPort {
    pub s: TcpStream,
    pub peeked: Option<u8>,
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

/// A booted grid: its processes and relays, the host's end of each board's UART 0, the time
/// it started.
pub struct Booted {
    pub grid: Grid,
    pub hosts: Vec<(HostPort, SerialLink<LINK_BUF>)>,
    pub t0: Instant,
    /// The whole run must end within this: a board that has not answered by then is a hang.
    pub timeout: Duration,
}

impl Booted {
    /// Poll every host link once, then wait a little; a failed link (a QEMU gone) or the
    /// deadline passed fails the test, saying `what` was awaited.
    pub fn poll(&mut self, what: &dyn Fn() -> String) {
        let now = self.t0.elapsed().as_millis() as u64;
        if self.t0.elapsed() > self.timeout {
            panic!("{} not within {:?} (a hang)\nQEMU said:\n{}", what(), self.timeout, self.grid.outputs());
        }
        for (b, (port, link)) in self.hosts.iter_mut().enumerate() {
            if let Err(e) = link.poll(now, port) {
                panic!("board {b}'s host link failed ({e:?}): its QEMU stopped?\nQEMU said:\n{}", self.grid.outputs());
            }
        }
        std::thread::sleep(Duration::from_micros(200));
    }

    /// Send `body` of `kind` to board `b`, waiting for the link to take it.
    pub fn send(&mut self, b: usize, kind: u8, body: &[u8]) {
        while !self.hosts[b].1.can_send() {
            self.poll(&|| format!("board {b}'s acknowledgement"));
        }
        self.hosts[b].1.send(kind, body).unwrap();
    }

    /// Start the detection at ring position 0 and wait for its declarations of phases 0 …
    /// `phases` − 1, in order, while ring position 0 sends nothing else and no other board
    /// sends anything; `what(k)` names phase k in a failure. Returns when each came, from the
    /// start.
    pub fn declarations(&mut self, phases: usize, what: &dyn Fn(usize) -> String) -> Vec<Duration> {
        let start = Instant::now();
        self.send(RING[0], KIND_START, &[]);
        let mut declared = Vec::new();
        while declared.len() < phases {
            self.poll(&|| format!("the declaration of {}", what(declared.len())));
            for (b, (_, link)) in self.hosts.iter_mut().enumerate() {
                if let Some(f) = link.received() {
                    assert_eq!((b, f.kind), (RING[0], KIND_DONE), "only ring position 0 declares, nothing else comes");
                    assert_eq!(f.payload, &(declared.len() as u16).to_le_bytes(), "phases in order");
                    declared.push(start.elapsed());
                    link.pop();
                }
            }
        }
        declared
    }

    /// Wait until every host link has nothing outstanding (every frame taken by its board).
    pub fn settle(&mut self) {
        while self.hosts.iter().any(|(_, l)| !l.idle()) {
            self.poll(&|| "the boards' acknowledgements".to_string());
        }
    }
}

/// Boot the 2 × 2 grid of `elf` ([`board_elf`]), relaying with `faults`, the wires `slow`
/// says late; the run must end within `timeout`.
pub fn boot(elf: &Path, faults: Faults, slow: Option<Slow>, timeout: Duration) -> Booted {
    let boards = SIDE * SIDE;
    let t0 = Instant::now();
    let deadline = t0 + timeout;
    // One listener per connected UART: 0 (host link) and each link with a neighbour.
    let listeners: Vec<Vec<Option<TcpListener>>> = (0..boards)
        .map(|b| {
            (0..5)
                .map(|u| (u == 0 || neighbour(b, u - 1).is_some()).then(|| TcpListener::bind("127.0.0.1:0").unwrap()))
                .collect()
        })
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let mut grid = Grid {
        boards: Vec::new(),
        elf: elf.to_path_buf(),
        log: Vec::new(),
        output: Vec::new(),
        stop: stop.clone(),
        relays: Vec::new(),
    };
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
        let (log, out) = (Arc::new(Mutex::new(Vec::new())), Arc::new(Mutex::new(String::new())));
        let (mut stdout, mut stderr) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
        let to = log.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            while let Ok(n @ 1..) = stdout.read(&mut buf) {
                to.lock().unwrap().extend_from_slice(&buf[..n]);
            }
        });
        let to = out.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            while let Ok(n @ 1..) = stderr.read(&mut buf) {
                to.lock().unwrap().push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        grid.boards.push(child);
        grid.log.push(log);
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
            let ends = [(here.try_clone().unwrap(), there.try_clone().unwrap()), (there, here)];
            for (ends, (from, to)) in ends.into_iter().zip([(b, c), (c, b)]) {
                let delay = slow.map_or(Duration::ZERO, |s| s.delay(from, to));
                let stop = stop.clone();
                stream += 1;
                let s = stream;
                grid.relays.push(std::thread::spawn(move || relay(ends, faults, s, delay, stop)));
            }
        }
    }

    let hosts = socks
        .iter_mut()
        .map(|s| {
            let s = s[0].take().unwrap();
            s.set_nonblocking(true).unwrap();
            (HostPort { s, peeked: None }, SerialLink::new(100))
        })
        .collect();
    Booted { grid, hosts, t0, timeout }
}

/// The ring over the 2 × 2 boards (board ids in ring order) and, per board, the link to its
/// successor (0 E, 1 N, 2 W, 3 S).
pub const RING: [usize; 4] = [0, 1, 3, 2];
pub const RING_NEXT: [u8; 4] = [0, 1, 3, 2];

/// The head of every exercise's configuration of board `b`: its id and its neighbours' ids on
/// links E, N, W, S ([`NONE`] where there is none).
pub fn board_config(b: usize) -> Vec<u8> {
    let mut config = vec![b as u8];
    config.extend((0..4).map(|l| neighbour(b, l).map_or(NONE, |c| c as u8)));
    config
}

/// [`board_config`], then what the ring's exercises add: `b`'s position in the [`RING`], the
/// ring's length and the link to its successor.
pub fn ring_config(b: usize) -> Vec<u8> {
    let mut config = board_config(b);
    let position = RING.iter().position(|&r| r == b).unwrap();
    config.extend([position as u8, RING.len() as u8, RING_NEXT[b]]);
    config
}

/// The defmt frames of `bytes` (a board's stdout), decoded with the table of `elf`: one line
/// per frame; a line saying why where the log cannot be decoded (no table, a malformed frame
/// the encoding cannot recover from, bytes left after the last whole frame).
pub fn decode_log(elf: &[u8], bytes: &[u8]) -> Vec<String> {
    use defmt_decoder::{DecodeError, Table};
    let table = match Table::parse(elf) {
        Ok(Some(t)) => t,
        Ok(None) => return vec!["(no defmt table in the image: built without its defmt feature)".into()],
        Err(e) => return vec![format!("(the image's defmt table does not parse: {e})")],
    };
    let mut decoder = table.new_stream_decoder();
    decoder.received(bytes);
    let mut lines = Vec::new();
    loop {
        match decoder.decode() {
            Ok(frame) => lines.push(frame.display_message().to_string()),
            Err(DecodeError::UnexpectedEof) => break,
            Err(DecodeError::Malformed) if table.encoding().can_recover() => lines.push("(a malformed frame)".into()),
            Err(DecodeError::Malformed) => {
                lines.push("(a malformed frame: the rest of the log cannot be decoded)".into());
                break;
            }
        }
    }
    lines
}

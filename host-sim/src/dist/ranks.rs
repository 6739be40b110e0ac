//! The MPI side of [`super`] (rsmpi over the system's MPI): starting, the ranks' places,
//! gathering the lighting parts on rank 0, the tiles' seam ([`MpiHalo`]), aborting every
//! rank.

use std::sync::OnceLock;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Threading;
use mpi::request::{Request, Scope};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;

pub use mpi::environment::Universe;

use crate::machine::lighting::diffuse::{decode_part, encode_part, Halo, Lighting, Tile, Traffic};
use crate::machine::shooting::shots::{shot_from_bytes, shot_to_bytes, Shot, ShotFarm};

/// (rank, ranks), once MPI is started.
static PLACE: OnceLock<(usize, usize)> = OnceLock::new();

/// (rank, ranks) when MPI was started.
pub fn place() -> Option<(usize, usize)> {
    PLACE.get().copied()
}

/// Whether an MPI launcher started this process: Open MPI's `mpirun` sets
/// `OMPI_COMM_WORLD_SIZE`, PMIx and PMI launchers (MPICH's hydra, Slurm) `PMIX_RANK` or
/// `PMI_RANK`. Run by hand, the binary is one process and never touches MPI.
fn launched() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK"].iter().any(|v| std::env::var_os(v).is_some())
}

/// Start MPI when launched by an MPI launcher. The jobs run on the thread pool's threads, one
/// MPI call at a time: `MPI_THREAD_SERIALIZED`.
pub fn start() -> Result<Option<Universe>> {
    if !launched() {
        return Ok(None);
    }
    let (universe, threading) =
        mpi::initialize_with_threading(Threading::Serialized).context("MPI was already started in this process")?;
    if threading < Threading::Serialized {
        bail!("this MPI library gives threading level {threading:?}: host-sim needs Serialized");
    }
    let world = universe.world();
    let _ = PLACE.set((world.rank() as usize, world.size() as usize));
    Ok(Some(universe))
}

/// Abort every rank of the run (`MPI_Abort` on the world), with exit status `code`.
pub fn abort(code: i32) -> ! {
    SimpleCommunicator::world().abort(code)
}

/// Send this rank's part to rank 0; on rank 0, every rank's part in rank order, its own first.
///
/// `RC2_MPI_DIE_RANK=r` (a test's hook) makes rank r abort here, its part diffused and not
/// sent; `RC2_MPI_PANIC_RANK=r` makes it panic: the run must end with an error, never wait for
/// the part.
pub fn gather(part: Lighting) -> Result<Option<Vec<Lighting>>> {
    let world = SimpleCommunicator::world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let hook = |var: &str| std::env::var(var).ok().and_then(|r| r.parse::<usize>().ok()) == Some(rank);
    if hook("RC2_MPI_DIE_RANK") {
        eprintln!("rank {rank}: RC2_MPI_DIE_RANK={rank}: dying before sending its lighting part");
        std::process::abort();
    }
    if hook("RC2_MPI_PANIC_RANK") {
        panic!("rank {rank}: RC2_MPI_PANIC_RANK={rank}: panicking before sending its lighting part");
    }
    let root = world.process_at_rank(0);
    if rank > 0 {
        let bytes = encode_part(&part)?;
        let len = Count::try_from(bytes.len()).with_context(|| {
            format!("rank {rank}'s lighting part is {} bytes: more than one MPI message holds", bytes.len())
        })?;
        mpi::request::scope(|scope| {
            settle(root.immediate_gather_into(scope, &len));
            settle(root.immediate_gather_varcount_into(scope, &bytes[..]));
        });
        return Ok(None);
    }
    // Rank 0 keeps its own part and sends itself nothing.
    let mut counts = vec![0 as Count; size];
    mpi::request::scope(|scope| settle(root.immediate_gather_into_root(scope, &(0 as Count), &mut counts[..])));
    let (displs, total) = offsets(&counts).context("the lighting parts")?;
    let mut buf = vec![0u8; total];
    {
        let mut into = PartitionMut::new(&mut buf[..], &counts[..], &displs[..]);
        let empty: &[u8] = &[];
        mpi::request::scope(|scope| settle(root.immediate_gather_varcount_into_root(scope, empty, &mut into)));
    }
    let mut parts = Vec::with_capacity(size);
    parts.push(part);
    for r in 1..size {
        let (at, len) = (displs[r] as usize, counts[r] as usize);
        parts.push(decode_part(&buf[at..at + len]).with_context(|| format!("rank {r}'s lighting part"))?);
    }
    Ok(Some(parts))
}

/// Where each rank's bytes start in a gathered buffer, and the buffer's length; an error when
/// they do not fit one MPI message.
fn offsets(counts: &[Count]) -> Result<(Vec<Count>, usize)> {
    let mut displs = Vec::with_capacity(counts.len());
    let mut total: i64 = 0;
    for c in counts {
        displs.push(Count::try_from(total).context("together more than one MPI message holds")?);
        total += i64::from(*c);
    }
    Ok((displs, usize::try_from(total)?))
}

/// Wait until every rank is here (a barrier, tested every millisecond: [`settle`]).
pub fn wait_for_all() {
    let world = SimpleCommunicator::world();
    settle(world.immediate_barrier());
}

/// Wait for `req` without keeping a core busy: test it every millisecond. (A blocking
/// collective polls at full speed, and the rank that waits — one whose share is done — would
/// take a core from the ranks still diffusing on every core.)
fn settle<'a, D: ?Sized, S: Scope<'a>>(mut req: Request<'a, D, S>) {
    loop {
        match req.test() {
            Ok(_) => return,
            Err(r) => {
                req = r;
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
    }
}

/// The tiles of one grid over the ranks ([`Halo`]): rank r steps band r of the rows, the
/// offers and answers across its edges go to ranks r − 1 and r + 1 once per cycle
/// (non-blocking sends, blocking receives), the machine-wide sums are an `MPI_Allreduce`.
pub struct MpiHalo {
    world: SimpleCommunicator,
    tile: Tile,
    traffic: Traffic,
}

impl MpiHalo {
    /// The seam of this rank's `tile` (band `rank` of as many as there are ranks).
    pub fn new(tile: Tile) -> Self {
        MpiHalo { world: SimpleCommunicator::world(), tile, traffic: Traffic::default() }
    }
}

/// The tag of the messages between neighbouring tiles (a cycle's offers, then its answers:
/// messages between two ranks with one tag arrive in the order sent).
const TAG_EDGE: mpi::Tag = 55;

impl Halo for MpiHalo {
    fn tile(&self) -> Tile {
        self.tile.clone()
    }

    fn traffic(&self) -> Traffic {
        self.traffic
    }

    fn swap(&mut self, up: &[u8], down: &[u8]) -> Result<(Vec<u8>, Vec<u8>)> {
        let (i, k) = (self.tile.index as i32, self.tile.of as i32);
        self.traffic.add(&self.tile, up.len(), down.len());
        let (world, t0) = (&self.world, Instant::now());
        let got = mpi::request::scope(|scope| {
            let sent_up = (i > 0).then(|| world.process_at_rank(i - 1).immediate_send_with_tag(scope, up, TAG_EDGE));
            let sent_down =
                (i + 1 < k).then(|| world.process_at_rank(i + 1).immediate_send_with_tag(scope, down, TAG_EDGE));
            let above =
                if i > 0 { world.process_at_rank(i - 1).receive_vec_with_tag::<u8>(TAG_EDGE).0 } else { Vec::new() };
            let below = if i + 1 < k {
                world.process_at_rank(i + 1).receive_vec_with_tag::<u8>(TAG_EDGE).0
            } else {
                Vec::new()
            };
            for r in [sent_up, sent_down].into_iter().flatten() {
                r.wait();
            }
            (above, below)
        });
        self.traffic.seconds += t0.elapsed().as_secs_f64();
        Ok(got)
    }

    fn gather(&mut self, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
        let t0 = Instant::now();
        let all = all_gather(&self.world, mine);
        self.traffic.seconds += t0.elapsed().as_secs_f64();
        all
    }

    fn sum(&mut self, v: &mut [i64]) -> Result<()> {
        let (mine, t0) = (v.to_vec(), Instant::now());
        self.world.all_reduce_into(&mine[..], v, SystemOperation::sum());
        self.traffic.seconds += t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// Every rank's `mine`, in rank order, on every rank (`MPI_Allgather` of the lengths, then
/// `MPI_Allgatherv` of the bytes).
fn all_gather(world: &SimpleCommunicator, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
    let size = world.size() as usize;
    let len = Count::try_from(mine.len()).context("a rank's bytes exceed one MPI message")?;
    let mut counts = vec![0 as Count; size];
    world.all_gather_into(&len, &mut counts[..]);
    let (displs, total) = offsets(&counts).context("the ranks' bytes")?;
    let mut buf = vec![0u8; total];
    {
        let mut into = PartitionMut::new(&mut buf[..], &counts[..], &displs[..]);
        world.all_gather_varcount_into(mine, &mut into);
    }
    Ok((0..size).map(|r| buf[displs[r] as usize..][..counts[r] as usize].to_vec()).collect())
}

/// Radiosity shots in flight spread over the ranks ([`ShotFarm`]): of the shots handed over
/// together, rank r computes those at positions p with p mod K = r, and every rank gets every
/// shot (`MPI_Allgatherv`), so that every rank's supervisor applies the same shots in the same
/// order and chooses the same next ones.
pub struct MpiFarm {
    world: SimpleCommunicator,
}

impl MpiFarm {
    /// The farm of every rank of the run.
    pub fn new() -> Self {
        MpiFarm { world: SimpleCommunicator::world() }
    }
}

impl ShotFarm for MpiFarm {
    fn shoot_all(&mut self, picks: &[usize], shoot: &mut dyn FnMut(usize) -> Result<Shot>) -> Result<Vec<Shot>> {
        let (rank, size) = (self.world.rank() as usize, self.world.size() as usize);
        let mut mine = Vec::new();
        for (at, &i) in picks.iter().enumerate().filter(|(at, _)| at % size == rank) {
            let bytes = shot_to_bytes(&shoot(i)?).with_context(|| format!("shot {at} of patch {i}"))?;
            mine.extend(bytes);
        }
        let all = all_gather(&self.world, &mine)?;
        let mut rest: Vec<&[u8]> = all.iter().map(Vec::as_slice).collect();
        let mut shots = Vec::with_capacity(picks.len());
        for at in 0..picks.len() {
            let (shot, after) =
                shot_from_bytes(rest[at % size]).with_context(|| format!("rank {}'s shot", at % size))?;
            if shot.log.patch != picks[at] {
                bail!("rank {} sent the shot of patch {} where patch {} was due", at % size, shot.log.patch, picks[at]);
            }
            rest[at % size] = after;
            shots.push(shot);
        }
        Ok(shots)
    }
}

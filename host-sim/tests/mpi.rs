//! `--features mpi` (docs/MPI.md): `mpirun -np K host-sim render|light …` gives the
//! one-process run's files byte for byte — PNG, lit voxels, statistics without their host
//! timings — and summary lines (but the wall times), for K = 1, 2, 3, 4 ranks sharing the
//! sources and 1, 2, 3, 4, 9 ranks sharing the grid as tiles; a rank that dies ends the run
//! with an error, never a hang.
//!
//! Compiled only with the feature (`cargo test -p host-sim --features mpi --test mpi`); needs
//! Open MPI's `mpirun` (Debian: openmpi-bin libopenmpi-dev).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_host-sim");

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rc2-mpi-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `mpirun` (with `opts` of its own) starting `ranks` copies of host-sim; it may run as root
/// here (CI's machine) and start more ranks than cores.
fn mpirun_with(ranks: usize, opts: &[&str]) -> Command {
    let mut c = Command::new("mpirun");
    c.env("OMPI_ALLOW_RUN_AS_ROOT", "1").env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    c.args(["--oversubscribe", "-np", &ranks.to_string()]).args(opts).args([BIN, "--threads", "1"]);
    c
}

fn mpirun(ranks: usize) -> Command {
    mpirun_with(ranks, &[])
}

/// The binary as one plain process (no MPI launcher's variables).
fn plain() -> Command {
    let mut c = Command::new(BIN);
    for (k, _) in std::env::vars_os() {
        if k.to_string_lossy().starts_with("OMPI_") || k.to_string_lossy().starts_with("PMI") {
            c.env_remove(k);
        }
    }
    c
}

/// Run to the end within `limit`, or kill it (by its id) and fail: never a hang.
fn run_within(mut c: Command, limit: Duration) -> Output {
    let child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {:?}: {e} (install openmpi-bin libopenmpi-dev)", c.get_program()));
    let id = child.id();
    let waiter = std::thread::spawn(move || child.wait_with_output().unwrap());
    let t0 = Instant::now();
    while !waiter.is_finished() {
        if t0.elapsed() > limit {
            let _ = Command::new("kill").args(["-9", &id.to_string()]).status();
            panic!("{c:?} still running after {limit:?}: a hang");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    waiter.join().unwrap()
}

/// Run and require success; its stderr.
fn ok(c: Command) -> String {
    let desc = format!("{c:?}");
    let out = run_within(c, Duration::from_secs(300));
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{desc} failed: {err}");
    err
}

/// The statistics without what the host's clock or memory says (different from run to run).
fn untimed(path: &Path) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|k, _| !k.contains("seconds") && k != "peak_rss_mib");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    strip(&mut v);
    v
}

/// The summary without its wall times (and without the line saying how the ranks shared the
/// run, which one process does not print, and the files' names).
fn summary(stderr: &str) -> Vec<String> {
    // A line that ends with its seconds (`…, 0.3 s`) loses them; lines naming the files
    // written (whose names differ by run) go.
    let untimed = |l: &str| match l.rsplit_once(", ") {
        Some((head, t)) if t.strip_suffix(" s").is_some_and(|v| v.parse::<f64>().is_ok()) => head.to_string(),
        _ => l.to_string(),
    };
    stderr
        .lines()
        .filter(|l| !l.contains("wall") && !l.starts_with("ranks: ") && !l.trim_start().starts_with("wrote "))
        .map(untimed)
        .collect()
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `host-sim <args> --out|--lit-out X --stats Y` in one process and under mpirun with each of
/// `ranks`: the same files (`files`: the options naming the files compared byte for byte), the
/// same statistics but the timings, the same summary but the wall times.
fn same_as_one_process(name: &str, args: &[&str], files: &[(&str, &str)], ranks: &[usize]) {
    let dir = scratch(name);
    let with = |c: &mut Command, tag: &str| {
        c.args(args);
        for (opt, file) in files {
            c.arg(opt).arg(dir.join(format!("{tag}-{file}")));
        }
        c.arg("--stats").arg(dir.join(format!("{tag}-stats.json")));
    };
    let mut one = plain();
    with(&mut one, "one");
    let one_err = ok(one);
    let one_stats = untimed(&dir.join("one-stats.json"));
    for k in ranks {
        let tag = format!("np{k}");
        let mut c = mpirun(*k);
        with(&mut c, &tag);
        let err = ok(c);
        for (_, file) in files {
            let (a, b) = (dir.join(format!("one-{file}")), dir.join(format!("{tag}-{file}")));
            assert!(bytes(&a) == bytes(&b), "{name}: {} differs from {} with {k} ranks", b.display(), a.display());
        }
        assert_eq!(untimed(&dir.join(format!("{tag}-stats.json"))), one_stats, "{name}: statistics with {k} ranks");
        assert_eq!(summary(&err), summary(&one_err), "{name}: summary with {k} ranks");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Five lights on the Cornell box: more sources than ranks, and fewer.
const FIVE_LIGHTS: [&str; 10] = [
    "--light",
    "0.5,0.9,0.5",
    "--light",
    "0.2,0.5,0.3",
    "--light",
    "0.8,0.3,0.7",
    "--light",
    "0.5,0.5,0.5",
    "--light",
    "0.3,0.8,0.8",
];

#[test]
fn cornell_renders_alike_on_1_2_4_ranks() {
    let png = [("--out", "image.png")];
    // With the f64 reference (rank 0's alone) and its comparison in the statistics.
    same_as_one_process("cornell", &["render", "cornell", "--n", "32", "--reference"], &png, &[1, 2, 4]);
    let mut five = vec!["render", "cornell", "--n", "32"];
    five.extend(FIVE_LIGHTS);
    same_as_one_process("cornell5", &five, &png, &[2, 4]);
}

/// The classroom's 26 lights (the many-light scene the spread is for).
#[test]
fn classe_renders_alike_on_2_and_4_ranks() {
    same_as_one_process("classe", &["render", "classe", "--n", "32"], &[("--out", "image.png")], &[2, 4]);
}

/// `light`: the lit voxels (every one, with its sources: the full lit store) and statistics;
/// the thesis's preset too.
#[test]
fn light_finds_the_same_lit_voxels_on_3_ranks() {
    let mut args = vec!["light", "cornell", "--n", "32"];
    args.extend(FIVE_LIGHTS);
    same_as_one_process("light5", &args, &[("--lit-out", "lit.csv")], &[3]);
    args.push("--thesis");
    same_as_one_process("light5-thesis", &args, &[("--lit-out", "lit.csv")], &[2]);
}

/// The diffusion spread, then rank 0's own phases on the merged lit sets: the shadow-edge
/// refinement (five lights), mirror reflections (the full lit store) and 2 × 2 samples per
/// pixel (their lights from the merged lit masks).
#[test]
fn refined_and_reflected_renders_alike_on_2_ranks() {
    let png = [("--out", "image.png")];
    let mut refined = vec!["render", "cornell", "--n", "32", "--lighting", "refined"];
    refined.extend(FIVE_LIGHTS);
    same_as_one_process("refined", &refined, &png, &[2]);
    same_as_one_process("mirror", &["render", "cornell-mirror", "--n", "32", "--reflections", "2"], &png, &[2]);
    same_as_one_process("samples", &["render", "cornell", "--n", "32", "--samples", "2"], &png, &[2]);
}

/// The grid cut into bands of rows, one per rank (`--spread tiles`), the messages across the
/// bands' edges carried between ranks every cycle: the Cornell box through its camera,
/// teapot-floor and bureau1 alike on 1, 2, 4 and 9 ranks (bands of 3 or 4 rows), and `light`'s
/// lit voxels over faulty links (each link with its receiver's rank).
#[test]
fn tiles_render_alike_on_1_2_4_9_ranks() {
    let png = [("--out", "image.png")];
    for scene in ["cornell", "teapot-floor", "bureau1"] {
        let args = ["--spread", "tiles", "render", scene, "--n", "32"];
        same_as_one_process(&format!("tiles-{scene}"), &args, &png, &[1, 2, 4, 9]);
    }
    // Bands of 5, 15 and 12 rows where the user cuts them.
    let cut = ["--spread", "tiles", "--tile-rows", "5,20", "render", "cornell", "--n", "32"];
    same_as_one_process("tiles-cut", &cut, &png, &[3]);
    let mut faults = vec!["--spread", "tiles", "light", "cornell", "--n", "24"];
    faults.extend(["--link-faults", "corrupt=0.01,drop=0.01,delay=0.02,seed=7"]);
    faults.extend(&FIVE_LIGHTS[..4]);
    same_as_one_process("tiles-faults", &faults, &[("--lit-out", "lit.csv")], &[3]);
}

/// A tile holds its band's lighting cells only: under a memory limit the whole grid's lighting
/// cells exceed, one process refuses the run, and two ranks of tiles each fit their band and
/// render the one-process image.
#[test]
fn a_tile_needs_memory_for_its_band_only() {
    let dir = scratch("band-memory");
    let args = ["render", "--n", "64", "--quiet"];
    // 64² lighting cells of 3 848 bytes are 15.0 MiB, a band of 32 rows 7.5 MiB; the loading
    // cells (64² of 1 880 bytes) 7.3 MiB.
    let limit = ("RC2_MEMORY_LIMIT_MIB", "11");
    let mut one = plain();
    one.args(args).arg("--out").arg(dir.join("one.png"));
    ok(one);
    let mut whole = plain();
    whole.env(limit.0, limit.1).args(args).arg("--out").arg(dir.join("refused.png"));
    let out = run_within(whole, Duration::from_secs(300));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("the grid of lighting cells needs"), "{err}");
    let mut tiles = mpirun(2);
    tiles.env(limit.0, limit.1).args(["--spread", "tiles"]).args(args).arg("--out").arg(dir.join("np2.png"));
    ok(tiles);
    assert!(bytes(&dir.join("one.png")) == bytes(&dir.join("np2.png")), "the image of two bands differs");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The lit-ray ratio (`--visibility ratio`, each pixel weighed by the share of its target
/// voxel's rays that arrive): the pixel weights travel with the parts, split by sources (five
/// lights, 2 ranks) and cut into tiles (one light, 3 ranks), the PNG and statistics of one
/// process.
#[test]
fn counted_rays_render_alike_split_by_sources_and_by_tiles() {
    let png = [("--out", "image.png")];
    let mut sources = vec!["--spread", "sources", "render", "cornell", "--n", "32", "--visibility", "ratio"];
    sources.extend(FIVE_LIGHTS);
    same_as_one_process("ratio-sources", &sources, &png, &[2]);
    let tiles = ["--spread", "tiles", "render", "teapot-floor", "--n", "32", "--visibility", "ratio"];
    same_as_one_process("ratio-tiles", &tiles, &png, &[3]);
    // Spread, not run on rank 0 alone (which would give the same image).
    let dir = scratch("ratio-spread");
    for (args, ranks, what) in [(&sources[..], 2, "each diffusing its share"), (&tiles[..], 3, "each stepping a band")]
    {
        let mut c = mpirun(ranks);
        c.args(args).arg("--out").arg(dir.join("image.png"));
        let err = ok(c);
        assert!(err.contains(what) && !err.contains("rank 0 diffuses them all"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Radiosity with several shots in flight, the shots of each batch spread over the ranks
/// (every rank runs the supervisor): the patches, the shots and the residual plot of one
/// process, under Feda's table and Thomin's rounds.
#[test]
fn shots_in_flight_spread_alike_on_2_and_3_ranks() {
    let files = [("--patches-csv", "patches.csv"), ("--shots-csv", "shots.csv"), ("--residual-plot", "residual.png")];
    for choice in ["table", "rounds"] {
        let args =
            ["radiosity", "cornell", "--n", "32", "--residual", "0.05", "--in-flight", "4", "--shooter-choice", choice];
        same_as_one_process(&format!("shots-{choice}"), &args, &files, &[2, 3]);
    }
}

/// What is not spread runs on rank 0 alone, with the same result: classic shadow rays, and a
/// diffusion over faulty links split by sources (each link's faults run on from source to
/// source; `--spread auto` cuts it into tiles instead, above).
#[test]
fn what_is_not_spread_runs_on_rank_0_alike() {
    let mut classic = vec!["render", "cornell", "--n", "32", "--lighting", "classic"];
    classic.extend(FIVE_LIGHTS);
    same_as_one_process("classic", &classic, &[("--out", "image.png")], &[2]);
    let mut faults = vec!["--spread", "sources", "light", "cornell", "--n", "16"];
    faults.extend(["--link-faults", "corrupt=0.01,drop=0.01,seed=7"]);
    faults.extend(&FIVE_LIGHTS[..4]);
    let dir = scratch("faults");
    let (one, two) = (dir.join("one.csv"), dir.join("two.csv"));
    ok({
        let mut c = plain();
        c.args(&faults).arg("--lit-out").arg(&one);
        c
    });
    let err = ok({
        let mut c = mpirun(2);
        c.args(&faults).arg("--lit-out").arg(&two);
        c
    });
    assert!(err.contains("rank 0 diffuses them all"), "{err}");
    assert_eq!(bytes(&one), bytes(&two));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A rank that dies before sending its part (`RC2_MPI_DIE_RANK`), rank 0 or another: the run
/// ends soon, with a non-zero status and a message naming the death.
#[test]
fn a_rank_that_dies_ends_the_run_with_an_error() {
    for die in ["1", "0"] {
        let dir = scratch(&format!("die{die}"));
        let mut c = mpirun_with(2, &["-x", "RC2_MPI_DIE_RANK"]);
        c.env("RC2_MPI_DIE_RANK", die).args(["render", "cornell", "--n", "32"]).args(FIVE_LIGHTS);
        c.arg("--out").arg(dir.join("x.png"));
        let out = run_within(c, Duration::from_secs(120));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "rank {die} died and the run succeeded: {err}");
        assert!(err.contains(&format!("RC2_MPI_DIE_RANK={die}")), "{err}");
        assert!(err.contains("signal") || err.contains("abort"), "mpirun names the death: {err}");
        assert!(!dir.join("x.png").exists(), "no image from a run that lost a rank");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A rank that panics (a bug; `RC2_MPI_PANIC_RANK`) before sending its part: it aborts every
/// rank instead of leaving rank 0 waiting.
#[test]
fn a_rank_that_panics_ends_the_run_with_an_error() {
    let dir = scratch("panic");
    let mut c = mpirun_with(2, &["-x", "RC2_MPI_PANIC_RANK"]);
    c.env("RC2_MPI_PANIC_RANK", "1").args(["render", "cornell", "--n", "32"]).args(FIVE_LIGHTS);
    c.arg("--out").arg(dir.join("x.png"));
    let out = run_within(c, Duration::from_secs(120));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "rank 1 panicked and the run succeeded: {err}");
    assert!(err.contains("RC2_MPI_PANIC_RANK=1"), "{err}");
    assert!(err.contains("error (rank 1 of 2): panicked (a bug): aborting every rank"), "{err}");
    assert!(!dir.join("x.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The ranks of a running `mpirun` (by id), from /proc: (pid, rank).
fn ranks_of(mpirun: u32) -> Vec<(u32, String)> {
    let mut out = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{mpirun}/task")) else { return out };
    for t in tasks.flatten() {
        let children = std::fs::read_to_string(t.path().join("children")).unwrap_or_default();
        for pid in children.split_whitespace().filter_map(|p| p.parse::<u32>().ok()) {
            let env = std::fs::read(format!("/proc/{pid}/environ")).unwrap_or_default();
            let rank = env.split(|b| *b == 0).find_map(|v| {
                v.strip_prefix(b"OMPI_COMM_WORLD_RANK=").map(|r| String::from_utf8_lossy(r).into_owned())
            });
            if let Some(r) = rank {
                out.push((pid, r));
            }
        }
    }
    out
}

/// A rank killed (SIGKILL) in the middle of a long diffusion, its sources or its tile: mpirun
/// ends the run with an error instead of leaving rank 0 waiting for its part, or the other
/// tiles for its messages.
#[test]
fn a_killed_rank_ends_the_run_with_an_error() {
    for spread in ["sources", "tiles"] {
        killed_rank(spread);
    }
}

fn killed_rank(spread: &str) {
    let dir = scratch(&format!("killed-{spread}"));
    let mut c = mpirun(2);
    // The full lit store of the classroom's 26 lights: minutes of work, killed after a second.
    c.args(["--spread", spread, "light", "classe", "--n", "64", "--quiet", "--lit-out"]).arg(dir.join("lit.csv"));
    let desc = format!("{c:?}");
    let child = c.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("mpirun");
    let id = child.id();
    let t0 = Instant::now();
    let victim = loop {
        let ranks = ranks_of(id);
        if let Some((pid, _)) = ranks.iter().find(|(_, r)| r == "1") {
            if ranks.len() == 2 {
                break *pid;
            }
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "{desc}: no rank 1 after a minute");
        std::thread::sleep(Duration::from_millis(50));
    };
    std::thread::sleep(Duration::from_secs(1));
    assert!(Command::new("kill").args(["-9", &victim.to_string()]).status().unwrap().success());
    let waiter = std::thread::spawn(move || child.wait_with_output().unwrap());
    let t1 = Instant::now();
    while !waiter.is_finished() {
        if t1.elapsed() > Duration::from_secs(60) {
            let _ = Command::new("kill").args(["-9", &id.to_string()]).status();
            panic!("{desc}: still running a minute after rank 1 was killed: a hang");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = waiter.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{desc}: a run that lost a rank succeeded: {err}");
    assert!(err.contains("signal 9") || err.contains("Killed"), "mpirun names the killed rank: {err}");
    assert!(!dir.join("lit.csv").exists(), "no lit voxels from a run that lost a rank");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bad input, met by every rank: one clear error (rank 0's), a non-zero status, no hang.
#[test]
fn a_bad_input_under_mpirun_is_one_clear_error() {
    let mut c = mpirun(2);
    c.args(["render", "no-such-scene", "--n", "16", "--out"]).arg(std::env::temp_dir().join("rc2-mpi-never.png"));
    let out = run_within(c, Duration::from_secs(60));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("error (rank 0 of 2): scene 'no-such-scene' is neither a file nor a built-in scene"), "{err}");
    // Tile cuts that do not give one band per rank, or lie outside the grid.
    for (rows, says) in [("5", "give 2 rows"), ("5,40", "must increase strictly within")] {
        let mut c = mpirun(3);
        c.args(["--spread", "tiles", "--tile-rows", rows, "render", "cornell", "--n", "32", "--out"]);
        c.arg(std::env::temp_dir().join("rc2-mpi-never.png"));
        let out = run_within(c, Duration::from_secs(60));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--tile-rows {rows}: {err}");
        assert!(err.contains("error (rank 0 of 3)") && err.contains(says), "--tile-rows {rows}: {err}");
    }
}

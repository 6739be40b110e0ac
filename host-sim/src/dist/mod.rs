//! Past one process (docs/MPI.md): with the `mpi` feature and `mpirun -np K host-sim …`, the
//! lighting run is shared by the K ranks ([`Spread`]). Each rank loads the same scene
//! (deterministic), then either diffuses the sources s with s % K = rank on its own copy of the
//! grid ([`Share`]) or steps band `rank` of the grid's rows, the messages across the bands'
//! edges going between ranks every cycle (`crate::machine::lighting::diffuse::Tile`, through
//! `ranks::MpiHalo`); rank 0 gathers the parts, merges them
//! ([`crate::machine::lighting::diffuse::merge_parts`], `merge_tiles`) and carries on alone:
//! shading, files, summary. The result is the one-process run's, byte for byte. The other
//! ranks stop once their part is sent ([`Finished`]).
//!
//! Without the feature (the default build), or run without `mpirun`, this is one process:
//! [`run_diffusion`] is the machine's own. Nothing of MPI leaves this folder; the machine
//! knows shares of sources, not ranks.

use std::time::Instant;

use anyhow::Result;

use crate::machine::lighting::diffuse::{Halo, LightConfig, Lighting, Share, Tile, Traffic};
use crate::machine::lighting::run::{self, LightStats};
use crate::machine::loading::loaded_scene::LoadedScene;
use crate::scene::Mesh;

#[cfg(feature = "mpi")]
mod ranks;

/// The error a rank other than 0 stops with once its part of the work is handed to rank 0:
/// not a failure ([`is_finished`]), the process exits successfully and says nothing.
#[derive(Debug)]
pub struct Finished;

impl std::fmt::Display for Finished {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("this rank's part is done; rank 0 carries on")
    }
}

impl std::error::Error for Finished {}

/// Whether `e` is [`Finished`]: this rank's work is done, not failed.
pub fn is_finished(e: &anyhow::Error) -> bool {
    e.downcast_ref::<Finished>().is_some()
}

/// This process's rank and the number of ranks: (0, 1) without MPI.
pub fn place() -> (usize, usize) {
    #[cfg(feature = "mpi")]
    if let Some(p) = ranks::place() {
        return p;
    }
    (0, 1)
}

/// Whether this process is a rank other than 0: it neither prints a summary nor writes a file,
/// and takes part only in what is spread over the ranks.
pub fn helper() -> bool {
    place().0 > 0
}

/// What `main` holds for the whole run: MPI, started when the process was launched by
/// `mpirun` (with the `mpi` feature), finalised when this is dropped.
pub struct Session {
    #[cfg(feature = "mpi")]
    _universe: Option<ranks::Universe>,
}

impl Drop for Session {
    /// At the end of a run of several ranks, wait for every rank before MPI is finalised, one
    /// test a millisecond (a rank done early waits for rank 0 without keeping a core busy).
    /// A rank that panicked aborts them all instead: the others may be waiting for its part.
    fn drop(&mut self) {
        #[cfg(feature = "mpi")]
        if self._universe.is_some() {
            if std::thread::panicking() {
                let (rank, size) = place();
                eprintln!("error (rank {rank} of {size}): panicked (a bug): aborting every rank");
                ranks::abort(101);
            }
            ranks::wait_for_all();
        }
    }
}

/// Start MPI if this process was launched by `mpirun` and has the `mpi` feature; else nothing.
pub fn start() -> Result<Session> {
    Ok(Session {
        #[cfg(feature = "mpi")]
        _universe: ranks::start()?,
    })
}

/// End a failed run: print `e` and, with several ranks, abort them all (`MPI_Abort`: a rank
/// that fails never leaves the others waiting for its part). Returns the exit status of a run
/// of one process.
pub fn fail(e: &anyhow::Error) -> std::process::ExitCode {
    let (rank, size) = place();
    if size > 1 {
        if rank > 0 {
            // An error of every rank (a bad input) is rank 0's to tell: its abort ends this
            // rank within the pause. An error of this rank alone is told after it.
            std::thread::sleep(std::time::Duration::from_secs(2));
        }
        eprintln!("error (rank {rank} of {size}): {e:#}");
        #[cfg(feature = "mpi")]
        ranks::abort(1);
    }
    eprintln!("error: {e:#}");
    std::process::ExitCode::FAILURE
}

/// How the ranks of an MPI run share a lighting run (`--spread`). The result is the same
/// whichever is chosen (docs/MPI.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Spread {
    /// Sources when there are at least as many as ranks and they can be split, else tiles.
    #[default]
    Auto,
    /// Each rank diffuses its share of the sources on its own copy of the grid.
    Sources,
    /// The grid cut into bands of rows, one per rank, the messages that cross a band's edge
    /// carried between ranks every cycle.
    Tiles,
}

/// The run's choice (`--spread`, and `--tile-rows`: where the tiles' bands are cut), set once
/// by the CLI.
static SPREAD: std::sync::OnceLock<(Spread, Option<Vec<u32>>)> = std::sync::OnceLock::new();

/// Choose how the ranks share lighting runs and, for tiles, the rows above which the bands are
/// cut (`None`: bands of equal height). The first call stands.
pub fn set_spread(s: Spread, tile_rows: Option<Vec<u32>>) {
    let _ = SPREAD.set((s, tile_rows));
}

/// The bands of an n × n grid for `ranks` ranks: cut above `cuts` (one fewer than the ranks),
/// or of equal height.
fn bands(n: u32, ranks: usize, cuts: Option<&[u32]>) -> Result<Vec<Tile>> {
    match cuts {
        Some(c) if c.len() + 1 != ranks => {
            anyhow::bail!(
                "--tile-rows {c:?} cuts the grid into {} bands for {ranks} ranks: give {} rows",
                c.len() + 1,
                ranks - 1
            )
        }
        Some(c) => Tile::bands(n, c),
        None => Tile::bands(n, &Tile::even_cuts(ranks, n)?),
    }
}

/// What this run's ranks do with a lighting run of `lights` sources under `cfg`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Sources,
    Tiles,
    /// Rank 0 alone, with the reason.
    Alone(&'static str),
}

/// `cuttable`: the grid can be cut into a band per rank.
fn mode(spread: Spread, lights: usize, ranks: usize, cuttable: bool, cfg: &LightConfig) -> Mode {
    let sources_ok = Share::spreads(cfg, false);
    let tiles_ok = !cfg.record_visits && cuttable;
    match spread {
        Spread::Sources if sources_ok => Mode::Sources,
        Spread::Sources => {
            Mode::Alone("this run's sources share more than their lit marks (link faults, a snapshot, visited voxels)")
        }
        Spread::Tiles if tiles_ok => Mode::Tiles,
        Spread::Tiles => Mode::Alone("this run cannot be cut into tiles (visited voxels, or more ranks than rows)"),
        Spread::Auto if sources_ok && lights >= ranks => Mode::Sources,
        Spread::Auto if tiles_ok => Mode::Tiles,
        Spread::Auto if sources_ok => Mode::Sources,
        Spread::Auto => Mode::Alone("this run can be neither split by sources nor cut into tiles (visited voxels)"),
    }
}

/// The lighting run of every source ([`run::run_diffusion`]), shared by the ranks when there
/// are several (`--spread`: by sources, or by tiles of the grid): rank 0 returns the whole run,
/// the other ranks [`Finished`] once their part is sent. A run that can be shared neither way
/// runs on rank 0 alone.
pub fn run_diffusion(
    mesh: &Mesh,
    scene: &LoadedScene,
    lights: &[[f64; 3]],
    cfg: &LightConfig,
    mut progress: impl FnMut(usize, u64),
) -> Result<(Lighting, LightStats)> {
    let (rank, size) = place();
    if size == 1 {
        return run::run_diffusion(mesh, scene, lights, cfg, progress);
    }
    let t0 = Instant::now();
    let (spread, cuts) = SPREAD.get().cloned().unwrap_or_default();
    let n = scene.grid.n;
    let tiles = bands(n, size, cuts.as_deref());
    if cuts.is_some() {
        // Rows the user gave that do not cut this grid into a band per rank: a bad input.
        tiles.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
    }
    let mode = mode(spread, lights.len(), size, tiles.is_ok(), cfg);
    if rank == 0 {
        // What ran (not part of the summary, which is the one-process run's).
        match (mode, &tiles) {
            (Mode::Sources, _) => eprintln!("ranks: {size}, each diffusing its share of the {} sources", lights.len()),
            (Mode::Tiles, Ok(t)) => {
                let rows: Vec<String> = t.iter().map(|t| format!("{}..{}", t.rows.start, t.rows.end)).collect();
                eprintln!("ranks: {size}, each stepping a band of the grid's {n} rows: {}", rows.join(", "));
            }
            _ => {}
        }
    }
    let lighting = match mode {
        Mode::Alone(why) => {
            if rank > 0 {
                return Err(Finished.into());
            }
            eprintln!("note: {why}: rank 0 diffuses them all");
            return run::run_diffusion(mesh, scene, lights, cfg, progress);
        }
        Mode::Sources => {
            let part = run::diffuse_part(scene, lights, cfg, Share { index: rank, of: size }, &mut progress)?;
            let Some(parts) = gather(part)? else { return Err(Finished.into()) };
            crate::machine::lighting::diffuse::merge_parts(parts)?
        }
        Mode::Tiles => {
            let mut halo = halo(tiles?.swap_remove(rank))?;
            let part = run::diffuse_tile_part(scene, lights, cfg, &mut *halo, &mut progress)?;
            // Every rank's traffic, for rank 0's account of the run.
            let traffic = halo.gather(&halo.traffic().to_bytes())?;
            let Some(parts) = gather(part)? else { return Err(Finished.into()) };
            let lighting = crate::machine::lighting::diffuse::merge_tiles(parts)?;
            let traffic = traffic.iter().map(|b| Traffic::from_bytes(b)).collect::<Result<Vec<_>>>()?;
            eprintln!("{}", tiles_account(&lighting, &traffic, &bands(n, size, cuts.as_deref())?));
            lighting
        }
    };
    run::summarise(mesh, scene, cfg, lighting, t0.elapsed().as_secs_f64())
}

/// What each rank of a tiled run did: the bytes it sent across its tile's edges a cycle, the
/// host seconds it spent in the seam (sending, and waiting for the others: every cycle waits
/// for the busiest band), and each band's share of the beams processed.
fn tiles_account(lighting: &Lighting, traffic: &[Traffic], tiles: &[Tile]) -> String {
    let size = traffic.len();
    let per_band: Vec<u64> = tiles
        .iter()
        .map(|t| lighting.cells.iter().filter(|c| t.rows.contains(&(c.y as u32))).map(|c| c.counters.processed).sum())
        .collect();
    let total = per_band.iter().sum::<u64>().max(1) as f64;
    let list = |f: &dyn Fn(usize) -> String| (0..size).map(f).collect::<Vec<_>>().join(", ");
    let cycles = traffic.first().map_or(0, |t| t.swaps / 2).max(1) as f64;
    let account = format!(
        "ranks: by rank, bytes sent across the tile's edges a cycle: {}; seconds in the seam (sending and waiting): {}; share of the beams processed: {}",
        list(&|r| format!("{:.0}", traffic[r].bytes as f64 / cycles)),
        list(&|r| format!("{:.2}", traffic[r].seconds)),
        list(&|r| format!("{:.0} %", 100.0 * per_band[r] as f64 / total)),
    );
    format!("{account}\n{}", balance_hint(lighting, size, per_band.iter().max().copied().unwrap_or(0) as f64 / total))
}

/// The cuts that would have balanced this run's beams over `size` bands (for the next run of
/// the same scene), against `largest`, the largest band's share in this run.
fn balance_hint(lighting: &Lighting, size: usize, largest: f64) -> String {
    let mut per_row = vec![0u64; lighting.n as usize];
    for c in &lighting.cells {
        per_row[c.y as usize] += c.counters.processed;
    }
    let total = per_row.iter().sum::<u64>().max(1) as f64;
    match Tile::balanced_cuts(&per_row, size) {
        Ok(cuts) => {
            let best = Tile::band_loads(&per_row, &cuts).into_iter().max().unwrap_or(0);
            let rows: Vec<String> = cuts.iter().map(u32::to_string).collect();
            format!(
                "ranks: bands balancing this run's beams: --tile-rows {} (largest share {:.0} %; this run's {:.0} %)",
                rows.join(","),
                100.0 * best as f64 / total,
                100.0 * largest
            )
        }
        Err(e) => format!("ranks: no balanced bands: {e:#}"),
    }
}

/// Where a radiosity run's shots in flight are computed: spread over the ranks when there
/// are several (every rank runs the supervisor, each computes its share of the shots under way),
/// `None` in one process.
pub fn shot_farm() -> Option<Box<dyn crate::machine::shooting::shots::ShotFarm>> {
    #[cfg(feature = "mpi")]
    if place().1 > 1 {
        return Some(Box::new(ranks::MpiFarm::new()));
    }
    None
}

/// This rank's tile of the grid and its seam to the others.
#[cfg(feature = "mpi")]
fn halo(tile: Tile) -> Result<Box<dyn Halo>> {
    Ok(Box::new(ranks::MpiHalo::new(tile)))
}

/// One process has no other tiles (never called: one process runs the grid whole).
#[cfg(not(feature = "mpi"))]
fn halo(_: Tile) -> Result<Box<dyn Halo>> {
    anyhow::bail!("tiles over ranks need the `mpi` feature")
}

/// Every rank's part on rank 0, in rank order (`None` on the other ranks, once sent).
#[cfg(feature = "mpi")]
fn gather(part: Lighting) -> Result<Option<Vec<Lighting>>> {
    ranks::gather(part)
}

/// One process: its own part is the whole run.
#[cfg(not(feature = "mpi"))]
fn gather(part: Lighting) -> Result<Option<Vec<Lighting>>> {
    Ok(Some(vec![part]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Preset;
    use cell_core::visibility::Visibility;

    /// `auto` splits by sources when each rank gets one, by tiles otherwise; an explicit choice
    /// stands where the run allows it, and rank 0 works alone where neither does.
    #[test]
    fn the_spread_follows_the_run() {
        let render = Preset::Render.light();
        let faults = LightConfig { faults: Some("drop=0.01".parse().unwrap()), ..render };
        let ratio = LightConfig { visibility: Visibility::Ratio, ..render };
        assert_eq!(mode(Spread::Auto, 26, 2, true, &render), Mode::Sources);
        assert_eq!(mode(Spread::Auto, 1, 2, true, &render), Mode::Tiles);
        assert_eq!(mode(Spread::Auto, 1, 200, false, &render), Mode::Sources, "more ranks than rows");
        assert_eq!(mode(Spread::Auto, 26, 2, true, &faults), Mode::Tiles, "faults run on from source to source");
        assert_eq!(mode(Spread::Sources, 1, 2, true, &render), Mode::Sources);
        assert_eq!(mode(Spread::Tiles, 26, 2, true, &render), Mode::Tiles);
        assert!(matches!(mode(Spread::Sources, 26, 2, true, &faults), Mode::Alone(_)));
        assert!(matches!(mode(Spread::Tiles, 1, 200, false, &render), Mode::Alone(_)));
        // The lit-ray ratio's weights travel with the parts, either way.
        assert_eq!(mode(Spread::Auto, 3, 2, true, &ratio), Mode::Sources);
        assert_eq!(mode(Spread::Tiles, 3, 2, true, &ratio), Mode::Tiles);
        let visits = LightConfig { record_visits: true, ..render };
        for s in [Spread::Auto, Spread::Sources, Spread::Tiles] {
            assert!(matches!(mode(s, 3, 2, true, &visits), Mode::Alone(_)), "{s:?}: visited voxels travel in no part");
        }
        // Even bands, or the user's cuts (one per rank boundary).
        let rows = |t: Vec<Tile>| t.into_iter().map(|t| t.rows).collect::<Vec<_>>();
        assert_eq!(rows(bands(10, 3, None).unwrap()), [0..3, 3..6, 6..10]);
        assert_eq!(rows(bands(10, 2, Some(&[7])).unwrap()), [0..7, 7..10]);
        assert!(bands(10, 3, Some(&[7])).unwrap_err().to_string().contains("give 2 rows"));
        assert!(bands(4, 5, None).is_err());
    }
}

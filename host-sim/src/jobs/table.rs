//! The `diffusion-table` job, the thesis's experiment (§4.4.3): an empty scene, one source at
//! the centre, the diffusion time T for each grid size N, FIFO size FA, policy and timing
//! ([`Timing`], docs/DIFFUSION-TIMING.md), as CSV and a plot beside the thesis's published
//! values, with the ratio ours / published in the CSV. Optionally the thesis's time-lapse of
//! the 16³ run (which voxels beams reached, which cells hold beams, at given times).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use cell_core::light::Policy;

use crate::machine::lighting::diffuse::LightConfig;
use crate::machine::lighting::run::{run_diffusion, LightStats};
use crate::machine::lighting::sequential::ray_by_ray;
use crate::machine::lighting::timing::Timing;
use crate::machine::loading::loaded_scene::{load_scene, resolve_lights, LoadedScene};
use crate::precompute::LoadConfig;
use crate::report::files::create;
use crate::report::plot::{plot_diffusion, plot_timelapse, DiffusionRow, Snapshot, THESIS_T, THESIS_T_UNBOUNDED};
use crate::report::progress;
use crate::scene::Mesh;

/// What the `diffusion-table` job measures and writes.
#[derive(Clone, Debug)]
pub struct TableOptions {
    /// Grid sizes N.
    pub n: Vec<u32>,
    /// FIFO sizes FA.
    pub fa: Vec<usize>,
    /// Policies.
    pub policies: Vec<Policy>,
    /// Beam merging; `None`: on for the policies that pick by layer, off for the thesis's.
    pub merge: Option<bool>,
    /// Fraction bits f.
    pub frac_bits: u32,
    /// Timing rules to run, each under its name.
    pub timings: Vec<NamedTiming>,
    /// The source at the grid's origin corner, voxel (0, 0, 0), instead of its centre.
    pub origin: bool,
    /// Run every (N, FA) the thesis published ([`THESIS_T`], N ≥ 4) instead of `n` × `fa`.
    pub published: bool,
    /// Also write the 16³ time-lapse, one PNG per FA of `timelapse_fa` (path stem + `.faK.png`).
    pub timelapse: Option<PathBuf>,
    /// FIFO sizes of the time-lapse.
    pub timelapse_fa: Vec<usize>,
    /// Output CSV.
    pub out: PathBuf,
    /// Output PNG plot.
    pub plot: PathBuf,
    /// No progress bar.
    pub quiet: bool,
}

/// A timing and the name its rows carry (`rc2`, `thesis`, with overrides appended).
#[derive(Clone, Debug)]
pub struct NamedTiming {
    /// Name in the CSV and the plot.
    pub name: String,
    /// The rules.
    pub timing: Timing,
}

/// The CSV's columns ([`write_row`]).
const HEADER: &str = "n,fa,policy,timing,frac_bits,cycles,lower_bound,t_over_lb,lb_distance,lb_cell_load,\
beams_processed,messages,peak_fifo,fifo_limit,blocked_cell_cycles,thesis_t,ratio,thesis_fa_large,thesis_t_large,ratio_large,\
t_with_detector,ray_by_ray_t,ray_by_ray_messages,wall_seconds";

/// Run the `diffusion-table` job.
pub fn run(o: &TableOptions) -> Result<()> {
    // Refuse a timing the cells cannot run before writing anything.
    let fas: Vec<usize> = o.points().into_iter().flat_map(|(_, fa)| fa).chain(o.timelapse_fa.iter().copied()).collect();
    for t in &o.timings {
        for &fa in &fas {
            t.timing.check(fa, true)?;
        }
    }
    let mut rows = Vec::new();
    let mut csv = create(&o.out)?;
    writeln!(csv, "{HEADER}")?;
    let mesh = crate::scene::load("empty")?;
    let pb = progress::bar(o.quiet, "table");
    let points = o.points();
    pb.set_length((points.iter().map(|(_, fa)| fa.len()).sum::<usize>() * o.policies.len() * o.timings.len()) as u64);
    for (n, fas) in points {
        let loaded = load_scene(&mesh, &LoadConfig::watertight(n))?;
        let lights = source_lights(&mesh, &loaded, n, o.origin)?;
        let sequential = ray_by_ray(n, o.origin, o.frac_bits)?;
        for t in &o.timings {
            for &policy in &o.policies {
                for &fa in &fas {
                    let (_, s) = run_diffusion(&mesh, &loaded, &lights, &o.config(fa, policy, t.timing), |_, _| {})?;
                    let row = Row { n, fa, timing: t, stats: &s, sequential };
                    write_row(&mut csv, &row)?;
                    rows.push(row.plotted());
                    pb.inc(1);
                }
            }
        }
    }
    pb.finish_and_clear();
    csv.flush()?;
    plot_diffusion(&rows, &o.plot)?;
    print_table(&rows);
    eprintln!("wrote {} and {}", o.out.display(), o.plot.display());
    if let Some(path) = &o.timelapse {
        timelapse(o, path)?;
    }
    Ok(())
}

/// The thesis's source at the centre, voxel (n/2, n/2, n/2), or at the origin (`origin`),
/// once per light of the scene.
fn source_lights(mesh: &Mesh, loaded: &LoadedScene, n: u32, origin: bool) -> Result<Vec<[f64; 3]>> {
    let c = if origin { 0.0 } else { (n / 2) as f64 };
    Ok(resolve_lights(mesh, loaded, &[])?.iter().map(|_| [c, c, c]).collect())
}

/// The thesis's snapshot times of its 16³ time-lapse (§4.4.3 figures: FA = 1 at 0, 50, 100,
/// 200, 300, 400, 464; FA = 16 at 0, 25, 50, 75, 100, 144), the last one replaced by our T.
fn snapshot_times(fa: usize, t: u64) -> Vec<u64> {
    let thesis: &[u64] = if fa == 1 { &[0, 50, 100, 200, 300, 400] } else { &[0, 25, 50, 75, 100] };
    let mut times: Vec<u64> = thesis.iter().copied().filter(|&s| s < t).collect();
    times.push(t);
    times
}

/// The 16³ time-lapse under the first timing and policy: for each FA, a full run for T, then
/// one run stopped at each snapshot time (which voxels a beam was processed in, which cells
/// hold a beam).
fn timelapse(o: &TableOptions, path: &std::path::Path) -> Result<()> {
    const N: u32 = 16;
    let mesh = crate::scene::load("empty")?;
    let loaded = load_scene(&mesh, &LoadConfig::watertight(N))?;
    let lights = source_lights(&mesh, &loaded, N, false)?;
    let timing = o.timings.first().map_or(Timing::RC2, |t| t.timing);
    let policy = o.policies.first().copied().unwrap_or(Policy::Thesis);
    for &fa in &o.timelapse_fa {
        let cfg = LightConfig { record_visits: true, ..o.config(fa, policy, timing) };
        let (_, s) = run_diffusion(&mesh, &loaded, &lights, &cfg, |_, _| {})?;
        let mut frames = Vec::new();
        for t in snapshot_times(fa, s.totals.cycles) {
            let (l, _) = run_diffusion(&mesh, &loaded, &lights, &LightConfig { stop_at: Some(t), ..cfg }, |_, _| {})?;
            let reached = l.visited.unwrap_or_default();
            let active = l.cells.iter().map(|c| c.queued > 0).collect();
            frames.push(Snapshot { t, reached, active });
        }
        let out = path.with_extension(format!("fa{fa}.png"));
        let title = format!(
            "N = {N}, FA = {fa}, {} policy, {} timing (T = {})",
            s.policy,
            o.timings.first().map_or("rc2", |t| &t.name),
            s.totals.cycles
        );
        plot_timelapse(N, &frames, &title, &out)?;
        eprintln!("wrote {}", out.display());
    }
    Ok(())
}

impl TableOptions {
    /// The grid sizes to run, each with its FIFO sizes.
    fn points(&self) -> Vec<(u32, Vec<usize>)> {
        if !self.published {
            return self.n.iter().map(|&n| (n, self.fa.clone())).collect();
        }
        let mut points: Vec<(u32, Vec<usize>)> = Vec::new();
        // N = 2 and 3 are left out: the loader needs N ≥ 4.
        for &(n, fa, _) in THESIS_T.iter().filter(|p| p.0 >= 4) {
            match points.last_mut() {
                Some((m, fas)) if *m == n => fas.push(fa as usize),
                _ => points.push((n, vec![fa as usize])),
            }
        }
        points
    }

    /// The lighting configuration of one row.
    fn config(&self, fa: usize, policy: Policy, timing: Timing) -> LightConfig {
        LightConfig {
            fa,
            policy,
            timing,
            merge: self.merge.unwrap_or(policy.by_layer()),
            record_visits: false,
            // The thesis's experiment measures diffusion through an empty scene, which the
            // skips would drop entirely.
            skip_receding: false,
            skip_dead_directions: false,
            frac_bits: self.frac_bits,
            ..crate::config::plane_rule()
        }
    }
}

/// One measured row and what it is compared with.
struct Row<'a> {
    n: u32,
    fa: usize,
    timing: &'a NamedTiming,
    stats: &'a LightStats,
    /// The ray-by-ray mode on the same grid (§4.2.4): (cycles, messages).
    sequential: (u64, u64),
}

impl Row<'_> {
    /// The FIFO limit the cells applied (FA, plus one under an input register).
    fn fifo_limit(&self) -> usize {
        self.timing.timing.fifo_limit(self.fa)
    }

    /// The thesis's T for this (N, FA) from its FA sweeps, if published.
    fn thesis_t(&self) -> Option<u64> {
        THESIS_T.iter().find(|&&(n, fa, _)| n == self.n && fa as usize == self.fa).map(|&(_, _, t)| t)
    }

    /// The thesis's (FA, T) with FIFOs "large enough" for this N, when our FIFO never filled
    /// (so that ours was large enough too).
    fn thesis_large(&self) -> Option<(u32, u64)> {
        let never_full = (self.stats.sources[0].counts.peak_fifo as usize) < self.fifo_limit();
        THESIS_T_UNBOUNDED.iter().find(|&&(n, _, _)| n == self.n && never_full).map(|&(_, fa, t)| (fa, t))
    }

    /// The plot's row: the policy labelled with the timing unless it is rc2's.
    fn plotted(&self) -> DiffusionRow {
        let r = &self.stats.sources[0];
        let policy = if self.timing.name == "rc2" {
            self.stats.policy.clone()
        } else {
            format!("{}, {} timing", self.stats.policy, self.timing.name)
        };
        DiffusionRow {
            n: self.n,
            fa: self.fa as u32,
            policy,
            cycles: r.counts.cycles,
            lower_bound: r.counts.lower_bound,
        }
    }
}

/// The termination detector as a network mechanism (§4.4.4): T plus the latency of two
/// pipelined counting waves over the grid (Mattern's four counters: the second of two
/// consecutive waves that see equal beam counts confirms), each n − 1 hops from the far
/// corner to the source's corner in the worst case: T + 2(n − 1).
fn with_detector(t: u64, n: u32) -> u64 {
    t + 2 * (n as u64 - 1)
}

/// `a / b` to 4 places, or empty.
fn ratio(a: u64, b: Option<u64>) -> String {
    b.map_or(String::new(), |b| format!("{:.4}", a as f64 / b as f64))
}

fn write_row(csv: &mut impl Write, row: &Row<'_>) -> Result<()> {
    let (s, r) = (row.stats, &row.stats.sources[0].counts);
    let (thesis, large) = (row.thesis_t(), row.thesis_large());
    let opt = |v: Option<u64>| v.map_or(String::new(), |v| v.to_string());
    writeln!(
        csv,
        "{},{},{},{},{},{},{},{:.4},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.4}",
        row.n,
        row.fa,
        s.policy,
        row.timing.name,
        s.frac_bits,
        r.cycles,
        r.lower_bound,
        s.t_over_lb,
        r.lb_distance,
        r.lb_cell_load,
        r.beams_processed,
        r.messages,
        r.peak_fifo,
        row.fifo_limit(),
        r.blocked_cell_cycles,
        opt(thesis),
        ratio(r.cycles, thesis),
        opt(large.map(|l| l.0 as u64)),
        opt(large.map(|l| l.1)),
        ratio(r.cycles, large.map(|l| l.1)),
        with_detector(r.cycles, row.n),
        row.sequential.0,
        row.sequential.1,
        s.wall_seconds
    )?;
    Ok(())
}

/// The table as Markdown on stderr.
fn print_table(rows: &[DiffusionRow]) {
    eprintln!("| N | FA | policy | T | LB | T/LB |");
    eprintln!("|---|---|---|---|---|---|");
    for r in rows {
        eprintln!(
            "| {} | {} | {} | {} | {} | {:.2} |",
            r.n,
            r.fa,
            r.policy,
            r.cycles,
            r.lower_bound,
            r.cycles as f64 / r.lower_bound.max(1) as f64
        );
    }
}

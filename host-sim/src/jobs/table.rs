//! The `diffusion-table` job, the thesis's experiment (§4.4.3): an empty scene, one source at
//! the centre, the diffusion time T for each grid size N, FIFO size FA and policy, as CSV and a
//! plot beside the thesis's published values.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use cell_core::beam::FracBits;
use cell_core::light::Policy;

use crate::jobs::light::unsupported_frac_bits;
use crate::machine::diffuse::LightConfig;
use crate::machine::lighting::{run_diffusion, LightStats};
use crate::machine::loaded::{load_scene, resolve_lights};
use crate::precompute::LoadConfig;
use crate::report::files::create;
use crate::report::plot::{plot_diffusion, DiffusionRow};
use crate::report::progress;

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
    /// Output CSV.
    pub out: PathBuf,
    /// Output PNG plot.
    pub plot: PathBuf,
    /// No progress bar.
    pub quiet: bool,
}

/// Run the `diffusion-table` job.
pub fn run(o: &TableOptions) -> Result<()> {
    let f = o.frac_bits;
    cell_core::with_frac_bits!(f, F => run_with::<F>(o)).unwrap_or_else(|| Err(unsupported_frac_bits(f)))
}

fn run_with<F: FracBits>(o: &TableOptions) -> Result<()> {
    let mut rows = Vec::new();
    let mut csv = create(&o.out)?;
    writeln!(csv, "n,fa,policy,frac_bits,cycles,lower_bound,t_over_lb,lb_distance,lb_cell_load,beams_processed,messages,peak_fifo,blocked_cell_cycles,wall_seconds")?;
    let mesh = crate::scene::load("empty")?;
    let pb = progress::bar(o.quiet, "table");
    pb.set_length((o.n.len() * o.fa.len() * o.policies.len()) as u64);
    for &n in &o.n {
        let loaded = load_scene(&mesh, &LoadConfig::watertight(n))?;
        // The thesis's source at the centre: voxel (n/2, n/2, n/2).
        let c = (n / 2) as f64;
        let lights = resolve_lights(&mesh, &loaded, &[])?.iter().map(|_| [c, c, c]).collect::<Vec<_>>();
        for &policy in &o.policies {
            for &fa in &o.fa {
                let (_, s) = run_diffusion::<F>(&mesh, &loaded, &lights, &o.config(fa, policy), |_, _| {})?;
                write_row(&mut csv, n, fa, &s)?;
                let r = &s.sources[0];
                rows.push(DiffusionRow {
                    n,
                    fa: fa as u32,
                    policy: s.policy.clone(),
                    cycles: r.counts.cycles,
                    lower_bound: r.counts.lower_bound,
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    csv.flush()?;
    plot_diffusion(&rows, &o.plot)?;
    print_table(&rows);
    eprintln!("wrote {} and {}", o.out.display(), o.plot.display());
    Ok(())
}

impl TableOptions {
    /// The lighting configuration of one row.
    fn config(&self, fa: usize, policy: Policy) -> LightConfig {
        LightConfig {
            fa,
            policy,
            merge: self.merge.unwrap_or(policy.by_layer()),
            record_visits: false,
            // The thesis's experiment measures diffusion through an empty scene, which the
            // skips would drop entirely.
            skip_receding: false,
            skip_dead_directions: false,
            ..Default::default()
        }
    }
}

fn write_row(csv: &mut impl Write, n: u32, fa: usize, s: &LightStats) -> Result<()> {
    let r = &s.sources[0];
    writeln!(
        csv,
        "{n},{fa},{},{},{},{},{:.4},{},{},{},{},{},{},{:.4}",
        s.policy,
        s.frac_bits,
        r.counts.cycles,
        r.counts.lower_bound,
        s.t_over_lb,
        r.counts.lb_distance,
        r.counts.lb_cell_load,
        r.counts.beams_processed,
        r.counts.messages,
        r.counts.peak_fifo,
        r.counts.blocked_cell_cycles,
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

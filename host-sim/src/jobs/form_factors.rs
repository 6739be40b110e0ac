//! `host-sim form-factors`: the projective form-factor methods of the radiosity thesis
//! (ch. 2, [`crate::truth::projective`]); `--tables` computes §2.5's Tables 2.1–2.3 from each
//! method's own surface, prints them beside the published values and writes them as CSV.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::report::files::create;
use crate::truth::projective::{figure, tables};

/// Options of the `form-factors` job.
#[derive(Clone, Debug, Default)]
pub struct FormFactorsOptions {
    /// Compute and print Tables 2.1–2.3.
    pub tables: bool,
    /// Write the tables as CSV here.
    pub csv: Option<PathBuf>,
    /// Draw §2.5.4's comparison (Fig. 2.18) into this PNG.
    pub figure: Option<PathBuf>,
    /// Write the figure's points as CSV here.
    pub figure_csv: Option<PathBuf>,
}

/// The hemicube resolutions of the figure's x axis: every even R from 16 to 96.
fn figure_resolutions() -> Vec<u32> {
    (16..=96).step_by(2).collect()
}

/// Run the job: the tables, printed, and the CSV if asked; the figure if asked.
pub fn run(o: &FormFactorsOptions) -> Result<()> {
    if !o.tables && o.figure.is_none() {
        bail!("form-factors: nothing to do (pass --tables or --figure F.png)");
    }
    if o.tables {
        run_tables(o)?;
    }
    if let Some(png) = &o.figure {
        run_figure(png, o.figure_csv.as_deref())?;
    }
    Ok(())
}

/// §2.5.4's figure: computed, drawn, and its points written as CSV if asked.
fn run_figure(png: &std::path::Path, csv: Option<&std::path::Path>) -> Result<()> {
    let mut file = csv.map(create).transpose()?;
    // The picture's file too, before any work: a path that cannot be written fails first.
    drop(create(png)?);
    let points = figure::compute(&figure_resolutions())?;
    crate::report::ff_figure::plot_figure(&points, png)?;
    eprintln!("figure written to {}", png.display());
    if let (Some(f), Some(path)) = (file.as_mut(), csv) {
        f.write_all(figure::csv(&points).as_bytes())?;
        f.flush()?;
        eprintln!("figure points written to {}", path.display());
    }
    Ok(())
}

/// The tables, printed, and the CSV if asked.
fn run_tables(o: &FormFactorsOptions) -> Result<()> {
    // The file first, so that a path that cannot be written fails before any work.
    let mut file = o.csv.as_ref().map(|p| create(p)).transpose()?;
    let cells = tables::compute()?;
    print!("{}", tables::render(&cells));
    let off: Vec<String> =
        cells.iter().filter(|c| !c.agrees).map(|c| format!("{} {} {}", c.table, c.row, c.method)).collect();
    println!(
        "{} of {} cells within one unit of the published last digit; disagreeing: {}",
        cells.len() - off.len(),
        cells.len(),
        if off.is_empty() { "none".into() } else { off.join(", ") }
    );
    if let (Some(f), Some(path)) = (file.as_mut(), &o.csv) {
        f.write_all(tables::csv(&cells).as_bytes())?;
        f.flush()?;
        eprintln!("written to {}", path.display());
    }
    Ok(())
}

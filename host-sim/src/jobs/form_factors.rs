//! `host-sim form-factors`: the projective form-factor methods of the radiosity thesis
//! (ch. 2, [`crate::truth::projective`]); `--tables` computes §2.5's Tables 2.1–2.3 from each
//! method's own surface, prints them beside the published values and writes them as CSV.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::report::files::create;
use crate::truth::projective::tables;

/// Options of the `form-factors` job.
#[derive(Clone, Debug, Default)]
pub struct FormFactorsOptions {
    /// Compute and print Tables 2.1–2.3.
    pub tables: bool,
    /// Write the tables as CSV here.
    pub csv: Option<PathBuf>,
}

/// Run the job: the tables, printed, and the CSV if asked.
pub fn run(o: &FormFactorsOptions) -> Result<()> {
    if !o.tables {
        bail!("form-factors: nothing to do (pass --tables)");
    }
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

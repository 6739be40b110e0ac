//! Output files: creating them with the path in the error, JSON documents.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{bail, Context, Result};

/// Create (or truncate) `path` for buffered writing; the error names the path.
pub fn create(path: &Path) -> Result<BufWriter<File>> {
    // Under MPI only rank 0 writes (docs/MPI.md): a helper rank that got here is a bug, not a
    // second copy of the file.
    let (rank, size) = crate::dist::place();
    if rank > 0 {
        bail!("rank {rank} of {size} would write {}: only rank 0 writes files", path.display());
    }
    let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(BufWriter::new(f))
}

/// Write `value` as pretty-printed JSON to `path`.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    serde_json::to_writer_pretty(create(path)?, value)?;
    Ok(())
}

//! Output files: creating them with the path in the error, JSON documents.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};

/// Create (or truncate) `path` for buffered writing; the error names the path.
pub fn create(path: &Path) -> Result<BufWriter<File>> {
    let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(BufWriter::new(f))
}

/// Write `value` as pretty-printed JSON to `path`.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    serde_json::to_writer_pretty(create(path)?, value)?;
    Ok(())
}

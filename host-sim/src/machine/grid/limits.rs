//! Resource limits checked before a grid is allocated: a grid of n × n cells that
//! cannot fit in memory is refused with a one-line error instead of aborting in the allocator
//! (`memory allocation of … bytes failed`) or being killed by the kernel half-way.
//!
//! The estimate is `n² × size_of(cell)`, compared with the memory the kernel says is available
//! (`MemAvailable` in `/proc/meminfo`; without it, 1 TiB, i.e. only absurd sizes are refused).
//! `RC2_MEMORY_LIMIT_MIB` overrides the limit (tests use it to exercise the refusal).

use anyhow::{bail, Result};

/// Bytes this process may use for a grid: `RC2_MEMORY_LIMIT_MIB`, else `MemAvailable`.
pub fn memory_limit_bytes() -> u64 {
    if let Some(mib) = std::env::var("RC2_MEMORY_LIMIT_MIB").ok().and_then(|v| v.trim().parse::<u64>().ok()) {
        return mib.saturating_mul(1 << 20);
    }
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        })
        .map_or(1 << 40, |kib| kib.saturating_mul(1024))
}

/// Refuse a grid of `n × n` cells of `bytes_per_cell` bytes each (`what` names it) when it
/// does not fit [`memory_limit_bytes`].
pub fn check_grid_memory(what: &str, n: u32, bytes_per_cell: usize) -> Result<()> {
    check_cells_memory(what, n, (n as u64).pow(2), bytes_per_cell)
}

/// Refuse `cells` cells of `bytes_per_cell` bytes each of an `n × n` grid (all of them, or the
/// band a tile of the grid holds; `what` names them) when they do not fit
/// [`memory_limit_bytes`].
pub fn check_cells_memory(what: &str, n: u32, cells: u64, bytes_per_cell: usize) -> Result<()> {
    let need = cells.saturating_mul(bytes_per_cell as u64);
    let limit = memory_limit_bytes();
    if need > limit {
        let size = |b: u64| match b >= 1 << 30 {
            true => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
            false => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        };
        let count = if cells == (n as u64).pow(2) { format!("{n}² cells") } else { format!("{cells} cells of {n}²") };
        bail!(
            "--n {n}: the {what} needs {} ({count} × {bytes_per_cell} bytes), more than the {} of memory \
             available; use a smaller --n",
            size(need),
            size(limit)
        );
    }
    Ok(())
}

/// Peak resident set size of this process in MiB (Linux only).
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

//! `host-sim audit`: what one cell costs in RAM for a scene, against the per-cell budget in
//! `memory.x`, and in flash, module by module, for the firmware images ([`flash`]). Static sizes are `size_of` of the cell's types with the host's
//! compile-time capacities; used sizes come from a real load + light run (peak dexels, peak FIFO,
//! peak lit runs over all cells, with the cell that needs the most); "needed" is a cell compiled
//! with exactly the capacities the scene used.

pub mod dwarf;
pub mod flash;
pub mod names;

use std::mem::size_of;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use cell_core::beam::frac::U0;
use cell_core::cell::{Cell, DEFAULT_DEXELS};
use cell_core::dexel::{Dexel, DexelStore};
use cell_core::facet::{PipelinePacket, RowPacket};
use cell_core::light::{BeamMsg, LitRun, LitRuns, OutBuffers};
use cell_core::trace::{LightSetup, ShadeSetup};
use cell_core::wire::{BEAM_PAYLOAD, HEADER, MAX_FRAME, ROW_PAYLOAD_BASE, TRAILER};

use crate::machine::lighting::diffuse::{FrustumBlocks, LightConfig};

use crate::machine::grid::capacity::{FA_CAP, LIT_CAP, OB_CAP, TRIANGLE_CAP};
use crate::machine::lighting::run::run_diffusion;
use crate::machine::loading::loaded_scene::{load_scene, resolve_lights};
use crate::precompute::LoadConfig;
use crate::scene::Mesh;

pub use flash::{budget_of, flash_table, FlashTable, DEFAULT_CELL_FLASH_BUDGET, FLASH_BUDGET};

/// The per-cell RAM budget: the RAM `LENGTH` of the top-level `memory.x`.
pub const MEMORY_X: &str = include_str!("../../../../memory.x");

/// Bytes of the `RAM` region in a linker memory script (`LENGTH = 64K`, `0x10000`, `65536`).
pub fn ram_budget(memory_x: &str) -> Option<usize> {
    region_length(memory_x, "RAM")
}

/// Bytes of a region (`FLASH`, `RAM`) in a linker memory script.
pub fn region_length(memory_x: &str, region: &str) -> Option<usize> {
    let line = memory_x.lines().find(|l| {
        let t = l.trim_start();
        t.starts_with(region) && t[region.len()..].trim_start().starts_with(':')
    })?;
    let len = line.split("LENGTH").nth(1)?.trim_start().trim_start_matches('=').trim();
    let len = len.trim_end_matches(|c: char| c == ',' || c.is_whitespace());
    let (num, mul) = match len.chars().last()? {
        'K' | 'k' => (&len[..len.len() - 1], 1024),
        'M' | 'm' => (&len[..len.len() - 1], 1024 * 1024),
        _ => (len, 1),
    };
    let v =
        if let Some(hex) = num.strip_prefix("0x") { usize::from_str_radix(hex, 16).ok()? } else { num.parse().ok()? };
    Some(v * mul)
}

/// Sizes and usage of one cell for a scene.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Audit {
    /// Scene name.
    pub scene: String,
    /// Grid side.
    pub n: u32,
    /// `size_of` a dexel, a beam message, a row packet, a pipeline packet, a lit run.
    pub bytes_dexel: usize,
    /// See `bytes_dexel`.
    pub bytes_beam_message: usize,
    /// See `bytes_dexel`.
    pub bytes_row_packet: usize,
    /// See `bytes_dexel`.
    pub bytes_pipeline_packet: usize,
    /// See `bytes_dexel`.
    pub bytes_lit_run: usize,
    /// Static: the dexel store with the host's capacity.
    pub static_dexel_store: usize,
    /// Static: the whole loading cell (store, coordinates, counters).
    pub static_cell: usize,
    /// Static: the FIFO (host capacity).
    pub static_fifo: usize,
    /// Static: the 8 output buffers.
    pub static_output_buffers: usize,
    /// Static: the lit runs.
    pub static_lit_runs: usize,
    /// Static: the whole lighting state of a cell.
    pub static_light_cell: usize,
    /// Static total: loading cell + one inbound row-packet register + lighting state.
    pub static_total: usize,
    /// The occupancy summary a cell holds when `--skip-frustum` or `--skip-hidden` is on, for
    /// 8, 16 and 32 blocks per axis (`--frustum-blocks`); not in the totals, which are those of
    /// a cell without the skips.
    pub frustum_summary: [usize; 3],
    /// The column's triangle store under exact occluders (`--lit-rule exact`, the default with
    /// diffusion): `TRIANGLE_CAP` triangles of 36 B and a count; not in the totals.
    pub triangle_store: usize,
    /// The most triangles one column of this scene keeps, and that column.
    pub used_triangles: usize,
    /// See `used_triangles`.
    pub used_triangles_cell: [u32; 2],
    /// Triangles left out of full columns: columns that met more than `TRIANGLE_CAP` (light
    /// passes where they stand); 0 when every column keeps all its triangles.
    pub triangle_overflows: u64,
    /// What a cell holds for one source's diffusion (the light setup; its frustum summary
    /// is the 8-block one) and, while it shades, the shading inputs (lights and materials).
    pub bytes_light_setup: usize,
    /// See `bytes_light_setup`.
    pub bytes_shade_setup: usize,
    /// Capacities compiled into the host.
    pub capacity_dexels: usize,
    /// See `capacity_dexels`.
    pub capacity_fifo: usize,
    /// See `capacity_dexels`.
    pub capacity_lit_runs: usize,
    /// Peak dexels in one cell, and that cell.
    pub used_dexels: usize,
    /// The cell with the most dexels.
    pub used_dexels_cell: [u32; 2],
    /// Peak FIFO occupancy in one cell, and that cell.
    pub used_fifo: usize,
    /// The cell with the fullest FIFO.
    pub used_fifo_cell: [u32; 2],
    /// Peak lit runs in one cell, and that cell.
    pub used_lit_runs: usize,
    /// The cell with the most lit runs.
    pub used_lit_runs_cell: [u32; 2],
    /// A cell compiled with exactly the used capacities (code excluded).
    pub needed_total: usize,
    /// The per-cell RAM budget of `memory.x`.
    pub budget_ram: Option<usize>,
    /// Whether `needed_total` fits the budget.
    pub fits_budget: Option<bool>,
    /// Link frame sizes on the wire (header, payload, CRC-32): a beam.
    pub wire_beam: usize,
    /// A row packet without contour edges.
    pub wire_row_min: usize,
    /// A row packet with the most contour edges.
    pub wire_row_max: usize,
    /// An acknowledgement.
    pub wire_ack: usize,
    /// The firmware images read (`--elf`, or the release builds under `firmware/`): sections,
    /// RAM of the replay image's `CELL` static, flash by module.
    pub images: Vec<Image>,
}

/// One firmware image: its flash table and the RAM its cell state takes, where a symbol says.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Image {
    /// Flash by module ([`flash::flash_table`]).
    pub flash: FlashTable,
    /// The replay image's cell state (its `CELL` static: dexels, FIFO, output buffers, lit
    /// runs, counters, replay bookkeeping), if the symbol is there.
    pub cell_static: Option<u64>,
    /// FLASH length of `memory.x` (what the linker allows; the cell budget is
    /// [`FLASH_BUDGET`]).
    pub memory_x_flash: Option<usize>,
}

/// Read an image: its flash table and the size of its `CELL` static.
pub fn image(path: &Path) -> Result<Image> {
    use object::{Object, ObjectSymbol};
    let flash = flash_table(path)?;
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let elf = object::File::parse(&*bytes).with_context(|| format!("{} is not an ELF file", path.display()))?;
    let cell_static = elf.symbols().find(|y| y.name().is_ok_and(|n| n.contains("rc2_firmware4CELL"))).map(|y| y.size());
    Ok(Image { flash, cell_static, memory_x_flash: region_length(MEMORY_X, "FLASH") })
}

/// Where `cd firmware && cargo build --release` puts the ELFs, relative to the workspace root:
/// the production image (the default cell, driven by its links) and the trace-replaying one;
/// and where `cargo build --profile thesis --bin cell --no-default-features` puts the thesis's
/// cell.
pub const FIRMWARE_ELFS: [&str; 3] = [
    "firmware/target/thumbv7em-none-eabihf/release/cell",
    "firmware/target/thumbv7em-none-eabihf/thesis/cell",
    "firmware/target/thumbv7em-none-eabihf/release/rc2-firmware",
];

/// The most any cell of a run used of each store, and the cell that used it.
#[derive(Clone, Copy, Debug, Default)]
struct Peaks {
    dexels: (usize, [u32; 2]),
    fifo: (usize, [u32; 2]),
    lit_runs: (usize, [u32; 2]),
    triangles: (usize, [u32; 2]),
    /// Triangles left out of full columns (more than `TRIANGLE_CAP` met one).
    triangle_overflows: u64,
}

/// Load and light a scene (from `lights`, or its own lights if none), and find the peaks of
/// its cells.
fn peaks(mesh: &Mesh, cfg: &LoadConfig, light: &LightConfig, lights: &[[f64; 3]]) -> Result<Peaks> {
    let loaded = load_scene(mesh, cfg)?;
    let lights = resolve_lights(mesh, &loaded, lights)?;
    let (lighting, _) = run_diffusion(mesh, &loaded, &lights, light, |_, _| {})?;
    let mut p = Peaks { triangle_overflows: loaded.grid.triangles.overflows(), ..Peaks::default() };
    let raise = |slot: &mut (usize, [u32; 2]), v: usize, x: u16, y: u16| {
        if v > slot.0 {
            *slot = (v, [x as u32, y as u32]);
        }
    };
    for c in &loaded.grid.cells {
        raise(&mut p.dexels, c.store.dexels().len(), c.x, c.y);
        raise(&mut p.triangles, loaded.grid.triangles.column(c.x as u32, c.y as u32).len(), c.x, c.y);
    }
    for c in &lighting.cells {
        raise(&mut p.fifo, c.counters.peak_fifo as usize, c.x, c.y);
        raise(&mut p.lit_runs, c.lit.runs().len(), c.x, c.y);
    }
    Ok(p)
}

/// Load and light a scene under `light` (from `lights`, or its own lights if none), measure
/// its cells, and read the firmware images `elfs`.
pub fn audit(
    mesh: &Mesh,
    cfg: &LoadConfig,
    light: &LightConfig,
    lights: &[[f64; 3]],
    elfs: &[PathBuf],
) -> Result<Audit> {
    let p = peaks(mesh, cfg, light, lights)?;
    type Light = crate::machine::grid::capacity::HostLightCell<U0>;
    let (b_dexel, b_msg, b_run) = (size_of::<Dexel>(), size_of::<BeamMsg<U0>>(), size_of::<LitRun>());
    let static_cell = size_of::<Cell<DEFAULT_DEXELS>>();
    let static_light = size_of::<Light>();
    let static_total = static_cell + size_of::<RowPacket>() + static_light;
    // The same cell with every capacity cut to what the scene used.
    let needed_total = static_total
        - (DEFAULT_DEXELS - p.dexels.0) * b_dexel
        - (FA_CAP - p.fifo.0) * b_msg
        - (LIT_CAP - p.lit_runs.0) * b_run;
    let budget = ram_budget(MEMORY_X);
    Ok(Audit {
        scene: mesh.name.clone(),
        n: cfg.n,
        bytes_dexel: b_dexel,
        bytes_beam_message: b_msg,
        bytes_row_packet: size_of::<RowPacket>(),
        bytes_pipeline_packet: size_of::<PipelinePacket>(),
        bytes_lit_run: b_run,
        static_dexel_store: size_of::<DexelStore<DEFAULT_DEXELS>>(),
        static_cell,
        static_fifo: size_of::<heapless::Vec<BeamMsg<U0>, FA_CAP>>(),
        static_output_buffers: size_of::<OutBuffers<U0, OB_CAP>>(),
        static_lit_runs: size_of::<LitRuns<LIT_CAP>>(),
        static_light_cell: static_light,
        static_total,
        frustum_summary: [FrustumBlocks::B8, FrustumBlocks::B16, FrustumBlocks::B32].map(FrustumBlocks::bytes),
        triangle_store: size_of::<cell_core::occluder::TriangleStore<TRIANGLE_CAP>>(),
        used_triangles: p.triangles.0,
        used_triangles_cell: p.triangles.1,
        triangle_overflows: p.triangle_overflows,
        bytes_light_setup: size_of::<LightSetup>(),
        bytes_shade_setup: size_of::<ShadeSetup>(),
        capacity_dexels: DEFAULT_DEXELS,
        capacity_fifo: FA_CAP,
        capacity_lit_runs: LIT_CAP,
        used_dexels: p.dexels.0,
        used_dexels_cell: p.dexels.1,
        used_fifo: p.fifo.0,
        used_fifo_cell: p.fifo.1,
        used_lit_runs: p.lit_runs.0,
        used_lit_runs_cell: p.lit_runs.1,
        needed_total,
        budget_ram: budget,
        fits_budget: budget.map(|b| needed_total <= b),
        wire_beam: HEADER + BEAM_PAYLOAD + TRAILER,
        wire_row_min: HEADER + ROW_PAYLOAD_BASE + TRAILER,
        wire_row_max: MAX_FRAME,
        wire_ack: HEADER + 1 + TRAILER,
        images: elfs.iter().map(|e| image(e)).collect::<Result<_>>()?,
    })
}

/// The RAM table: each store's static size with the host's capacities and what the scene used.
fn print_ram(a: &Audit) {
    println!("{} at n = {}: RAM of one cell (code excluded)", a.scene, a.n);
    println!("| part | static (host capacities) | used by this scene |");
    println!("|---|---|---|");
    println!(
        "| dexel store | {} B ({} × {} B) | {} dexels, cell {:?} |",
        a.static_dexel_store, a.capacity_dexels, a.bytes_dexel, a.used_dexels, a.used_dexels_cell
    );
    println!(
        "| FIFO | {} B ({} × {} B) | peak {} beams, cell {:?} |",
        a.static_fifo, a.capacity_fifo, a.bytes_beam_message, a.used_fifo, a.used_fifo_cell
    );
    println!(
        "| output buffers | {} B (8 × {OB_CAP} × {} B + 8 lengths) | |",
        a.static_output_buffers, a.bytes_beam_message
    );
    println!(
        "| lit runs | {} B ({} × {} B) | {} runs, cell {:?} |",
        a.static_lit_runs, a.capacity_lit_runs, a.bytes_lit_run, a.used_lit_runs, a.used_lit_runs_cell
    );
    println!("| inbound row packet | {} B | |", a.bytes_row_packet);
    println!("| **total** | {} B | {} B with exactly the capacities used |", a.static_total, a.needed_total);
    let [s8, s16, s32] = a.frustum_summary;
    println!(
        "with --skip-frustum or --skip-hidden, add the occupancy summary: {s8} B (--frustum-blocks 8), {s16} B (16), {s32} B (32)"
    );
    println!(
        "with exact occluders (--lit-rule exact, the default with diffusion), add the column's triangle store: {} B ({TRIANGLE_CAP} × 36 B); this scene keeps at most {} triangles in a column, cell {:?}",
        a.triangle_store, a.used_triangles, a.used_triangles_cell
    );
    if a.triangle_overflows > 0 {
        println!(
            "  {} triangle(s) left out of full columns: some column meets more than {TRIANGLE_CAP}",
            a.triangle_overflows
        );
    }
    println!(
        "per phase, besides the stores: the light setup {} B (lighting), the shading inputs {} B (shading, on the stack)",
        a.bytes_light_setup, a.bytes_shade_setup
    );
    match (a.budget_ram, a.fits_budget) {
        (Some(b), Some(fit)) => println!(
            "memory.x RAM budget {} B: {} (anchors: MasPar PE 16 KB; thesis §4.3.2: 16 KB per cell is too much)",
            b,
            if fit { "fits" } else { "DOES NOT FIT" }
        ),
        _ => println!("memory.x: no RAM length found"),
    }
}

/// Message sizes in memory and on the wire.
fn print_messages(a: &Audit) {
    println!(
        "messages in memory: row packet {} B, pipeline packet {} B, beam {} B",
        a.bytes_row_packet, a.bytes_pipeline_packet, a.bytes_beam_message
    );
    println!(
        "messages on the wire (framed, CRC-32): beam {} B, row packet {}..{} B, ack {} B",
        a.wire_beam, a.wire_row_min, a.wire_row_max, a.wire_ack
    );
}

/// One image: sections, then flash by concern and module against the budget.
pub fn print_image(i: &Image) {
    let f = &i.flash;
    println!(
        "firmware {}: vector table {} B, text {} B, rodata {} B, data {} B, bss {} B; flash {} B of the {} B cell budget ({}){}",
        f.elf,
        f.vector_table,
        f.text,
        f.rodata,
        f.data,
        f.bss,
        f.flash,
        f.budget,
        if f.flash <= f.budget { "fits" } else { "DOES NOT FIT" },
        i.cell_static.map_or(String::new(), |b| format!("; its cell state (CELL static) {b} B of RAM"))
    );
    println!(
        "| concern | module | code B | rodata B | total B |  (code by {})",
        if f.by_debug_info { "DWARF: the innermost project frame" } else { "symbol" }
    );
    println!("|---|---|---:|---:|---:|");
    for m in &f.modules {
        println!("| {} | {} | {} | {} | {} |", m.concern, m.module, m.code, m.data, m.code + m.data);
    }
    for (c, n) in f.concerns().iter().filter(|(_, n)| *n > 0) {
        println!("| **{c}** | | | | **{n}** |");
    }
    println!("| **total** | | | | **{}** |", f.flash);
}

/// The one-screen report.
pub fn print(a: &Audit) {
    print_ram(a);
    print_messages(a);
    if a.images.is_empty() {
        println!("firmware: not built (cd firmware && cargo build --release), or give --elf");
    }
    for i in &a.images {
        print_image(i);
    }
}

/// The flash tables as CSV: one row per image and module.
pub fn write_flash_csv(path: &Path, images: &[Image]) -> Result<()> {
    use std::io::Write;
    let mut w = crate::report::files::create(path)?;
    writeln!(w, "elf,concern,module,code,rodata,total")?;
    for i in images {
        for m in &i.flash.modules {
            writeln!(w, "{},{:?},{},{},{},{}", i.flash.elf, m.concern, m.module, m.code, m.data, m.code + m.data)?;
        }
        writeln!(w, "{},\"total\",,{},{},{}", i.flash.elf, i.flash.text, i.flash.flash - i.flash.text, i.flash.flash)?;
    }
    Ok(())
}

/// What the `audit` job measures and writes.
#[derive(Clone, Debug)]
pub struct AuditOptions {
    /// An .obj file or a built-in scene name.
    pub scene: String,
    /// The view: fitted, the scene's camera, or a camera of the user's.
    pub view: crate::scene::camera::ViewChoice,
    /// Grid side and surfaces.
    pub load: LoadConfig,
    /// FIFO size of the lighting run.
    pub fa: usize,
    /// The `--light` lights (none: the scene's own).
    pub lights: Vec<[f64; 3]>,
    /// Write the audit as JSON here.
    pub json: Option<PathBuf>,
    /// Write the flash tables as CSV here.
    pub csv: Option<PathBuf>,
    /// The firmware ELFs to report (default: those of [`FIRMWARE_ELFS`] that exist).
    pub elfs: Vec<PathBuf>,
}

/// Run the `audit` job: a load + light run (`render`'s lighting configuration), the cell's
/// sizes, the firmware images' flash by module; printed and optionally written as JSON and CSV.
pub fn run(o: &AuditOptions) -> Result<()> {
    o.load.validate()?;
    let mesh = crate::scene::camera::apply(crate::scene::load(&o.scene)?, &o.view, o.load.n)?;
    // The cell `render` runs by default (exact occluders, rays from the light, the radial
    // policy, the visible-only lit store, the skips): the one the default firmware image is.
    let lcfg = LightConfig { fa: o.fa, ..crate::config::Preset::Render.light() };
    let elfs = if o.elfs.is_empty() {
        FIRMWARE_ELFS.iter().map(PathBuf::from).filter(|p| p.exists()).collect()
    } else {
        o.elfs.clone()
    };
    let a = audit(&mesh, &o.load, &lcfg, &o.lights, &elfs)?;
    print(&a);
    if let Some(p) = &o.json {
        crate::report::files::write_json(p, &a)?;
    }
    if let Some(p) = &o.csv {
        write_flash_csv(p, &a.images)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_ram_length_of_memory_x() {
        assert_eq!(ram_budget(MEMORY_X), Some(64 * 1024));
        assert_eq!(ram_budget("MEMORY {\n RAM : ORIGIN = 0x20000000, LENGTH = 0x8000\n}"), Some(0x8000));
        assert_eq!(ram_budget("MEMORY { FLASH : ORIGIN = 0, LENGTH = 1M }"), None);
        assert_eq!(region_length(MEMORY_X, "FLASH"), Some(256 * 1024));
    }
}

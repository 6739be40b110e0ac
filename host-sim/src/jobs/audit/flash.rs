//! What each part of a firmware image costs in flash, read from its ELF.
//!
//! **Invariant: every byte of the image's flash sections (vector table, code, read-only data,
//! initialised data) is counted in exactly one row, and the rows add up to the image.**
//!
//! * **Code** is attributed byte by byte through the DWARF debug info the release profile
//!   keeps in the ELF (not in flash): a byte counts for the innermost *project* source file it
//!   came from — `cell-core/src/beam.rs` for split code inlined into the light cell's step,
//!   the light cell for a `core` slice helper inlined into it — found by walking the line
//!   table's file and then the call sites of the inlined subroutines around the byte, innermost
//!   first. Code with no project frame (`memcpy`, 64-bit division, `core` functions called
//!   out of line) counts for its own crate. Without debug info, code counts for the symbol that
//!   holds it, by its demangled path.
//! * **Read-only data** counts for its symbol's demangled path; LLVM's anonymous constants
//!   are searched for the tables whose bytes are known (the gamma thresholds of
//!   `cell_core::shade`, the CRC-32 table of the link codec, the CRC-64 table of the trace
//!   digest), and the rest of them is one row.
//! * Modules are grouped into the concerns of the cell ([`CONCERNS`]).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use object::{Object, ObjectSection, ObjectSymbol, SymbolKind};

use super::dwarf;
use super::names::{demangle, module_of_symbol, Sym, FIRMWARE_BINS};

/// The budget a production cell image is held to: 16 KiB of flash (the thesis's §4.3.2: 16 KB
/// per cell is already "inenvisageable" for a machine of many cells).
pub const FLASH_BUDGET: u64 = 16 * 1024;

/// The budget the default cell's image is held to (`firmware/src/bin/cell` with the firmware's
/// default features: every phase and option `host-sim render` uses by default). The goal is
/// 32 KiB; the image is 66 836 B since its host link takes the column's triangles and its
/// light steps under them (before, with no occluders ever passed, the compiler left most of the
/// exact visit out: 59 252 B), so the budget is what it reached plus a small margin: growth
/// fails (docs/FIRMWARE.md, "Flash budget", says where the bytes go and what the floor is).
pub const DEFAULT_CELL_FLASH_BUDGET: u64 = 66 * 1024;

/// The budget of the image at `path`: [`DEFAULT_CELL_FLASH_BUDGET`] for an image named `cell`
/// outside a `thesis` profile directory (the default cell, `cargo build --release`), else
/// [`FLASH_BUDGET`] (the thesis's cell, `cargo build --profile thesis --no-default-features`,
/// and the replay image, which is not held to one).
pub fn budget_of(path: &Path) -> u64 {
    let in_thesis = path.parent().and_then(|d| d.file_name()).is_some_and(|d| d == "thesis");
    if path.file_name().is_some_and(|f| f == "cell") && !in_thesis {
        DEFAULT_CELL_FLASH_BUDGET
    } else {
        FLASH_BUDGET
    }
}

/// The concerns of a cell and the source modules (paths under `cell-core/src`, or crate
/// names) that make each, in the order the table lists them.
pub const CONCERNS: &[(&str, &[&str])] = &[
    ("beam split (§4.3)", &["cell_core::beam"]),
    ("dexel store (§3.4)", &["cell_core::dexel", "cell_core::normal", "cell_core::plane", "cell_core::cell"]),
    (
        "loading: row cell, visible surface (§3.5–3.9)",
        &["cell_core::voxelize", "cell_core::facet", "cell_core::visible"],
    ),
    ("lighting cell: FIFO, ports, lit store (§4.4, §5.5)", &["cell_core::light", "cell_core::lit", "cell_core::units"]),
    (
        "exact occluders: triangles, target ray (rays from the light)",
        &["cell_core::occluder", "cell_core::receiver", "cell_core::triangle"],
    ),
    ("empty-frustum skip", &["cell_core::occupancy"]),
    ("shading + gamma table (§5.2)", &["cell_core::shade"]),
    ("codec + CRC-32 table", &["cell_core::wire", "cell_core::link", "crc"]),
    ("host records (trace codec)", &["cell_core::trace", "cell_core::trace::rays"]),
    ("routing (§1.3, §4.1.3)", &["cell_core::route"]),
    ("reflection (§2.3)", &["cell_core::reflect", "cell_core::ray"]),
    ("firmware: main loop, drivers", &["firmware"]),
    ("runtime: core, compiler builtins, vector table", &["core", "compiler_builtins", "cortex_m_rt", "vector table"]),
];

/// Bytes of one module in an image.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ModuleSize {
    /// `cell_core::beam`, `firmware`, `core`, `heapless` …
    pub module: String,
    /// The concern it belongs to ([`CONCERNS`]; "other" if none).
    pub concern: String,
    /// Code bytes.
    pub code: u64,
    /// Read-only data (and initialised data) bytes.
    pub data: u64,
}

/// The flash of one image, by module.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FlashTable {
    /// The ELF read.
    pub elf: String,
    /// Section sizes: vector table, code, read-only data, initialised data (flash), zeroed
    /// data (RAM only).
    pub vector_table: u64,
    /// See `vector_table`.
    pub text: u64,
    /// See `vector_table`.
    pub rodata: u64,
    /// See `vector_table`.
    pub data: u64,
    /// See `vector_table`.
    pub bss: u64,
    /// Flash: vector table + code + read-only data + initialised data.
    pub flash: u64,
    /// The image's budget ([`budget_of`]).
    pub budget: u64,
    /// Whether code came from DWARF line tables (else from symbols).
    pub by_debug_info: bool,
    /// The rows, in [`CONCERNS`] order, then the rest by size.
    pub modules: Vec<ModuleSize>,
}

impl FlashTable {
    /// Bytes per concern, in [`CONCERNS`] order, then "other".
    pub fn concerns(&self) -> Vec<(String, u64)> {
        let mut out: Vec<(String, u64)> = CONCERNS.iter().map(|(c, _)| (c.to_string(), 0)).collect();
        out.push(("other".into(), 0));
        for m in &self.modules {
            let i = out.iter().position(|(c, _)| *c == m.concern).unwrap_or(out.len() - 1);
            out[i].1 += m.code + m.data;
        }
        out
    }
}

/// The concern of a module: the one listing it, or the module it is part of
/// (`cell_core::light::fate` belongs where `cell_core::light` does).
pub fn concern_of(module: &str) -> &'static str {
    concern_index(module).map_or("other", |i| CONCERNS[i].0)
}

/// The index in [`CONCERNS`] of a module's concern ([`concern_of`]).
fn concern_index(module: &str) -> Option<usize> {
    let within = |m: &str| module == m || module.strip_prefix(m).is_some_and(|rest| rest.starts_with("::"));
    CONCERNS.iter().position(|(_, ms)| ms.iter().any(|m| within(m)))
}

/// Tables whose bytes are known, searched in anonymous read-only data: (module, bytes).
pub fn known_tables() -> Vec<(&'static str, Vec<u8>)> {
    let gamma: Vec<u8> = cell_core::shade::GAMMA_THRESHOLDS.iter().flat_map(|t| t.to_le_bytes()).collect();
    let crc32: Vec<u8> = crc_table(0xEDB8_8320u32 as u64, 32).iter().flat_map(|&v| (v as u32).to_le_bytes()).collect();
    let crc64: Vec<u8> = crc_table(0xC96C_5795_D787_0F42, 64).iter().flat_map(|v| v.to_le_bytes()).collect();
    vec![("cell_core::shade", gamma), ("cell_core::wire", crc32), ("cell_core::trace", crc64)]
}

/// The 256-entry table of a reflected CRC with reversed polynomial `poly` of `bits` bits.
fn crc_table(poly: u64, bits: u32) -> Vec<u64> {
    let mask = if bits == 64 { u64::MAX } else { (1 << bits) - 1 };
    (0..256u64).map(|i| (0..8).fold(i, |c, _| if c & 1 == 1 { (c >> 1) ^ poly } else { c >> 1 }) & mask).collect()
}

/// Attribute a read-only data section (`bytes` at `base`) to modules: named symbols by their
/// path, known tables where their bytes are found, the rest as "anonymous constants".
pub fn attribute_rodata(base: u64, bytes: &[u8], syms: &[Sym], bins: &[&str]) -> BTreeMap<String, u64> {
    let mut owner: Vec<Option<String>> = vec![None; bytes.len()];
    for s in syms {
        if s.name.starts_with(".L") && !s.name.starts_with(".Lswitch.table.") {
            continue;
        }
        let m = module_of_symbol(&demangle(&s.name), bins);
        for o in slot_range(&mut owner, base, s.addr, s.size) {
            *o = Some(m.clone());
        }
    }
    for (m, table) in known_tables() {
        let mut at = 0;
        while let Some(i) = find(&bytes[at..], &table) {
            let start = at + i;
            owner[start..start + table.len()].iter_mut().for_each(|o| *o = Some(m.to_string()));
            at = start + table.len();
        }
    }
    let mut out = BTreeMap::new();
    for o in owner {
        *out.entry(o.unwrap_or_else(|| "anonymous constants".into())).or_insert(0) += 1;
    }
    out
}

fn slot_range<T>(v: &mut [T], base: u64, addr: u64, size: u64) -> &mut [T] {
    let lo = (addr.saturating_sub(base) as usize).min(v.len());
    let hi = ((addr + size).saturating_sub(base) as usize).clamp(lo, v.len());
    &mut v[lo..hi]
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() || hay.len() < needle.len() {
        return None;
    }
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Attribute a code section by symbol names only (an ELF without debug info).
pub fn attribute_code_by_symbols(base: u64, len: u64, syms: &[Sym], bins: &[&str]) -> BTreeMap<String, u64> {
    let mut owner: Vec<Option<String>> = vec![None; len as usize];
    for s in syms {
        let m = module_of_symbol(&demangle(&s.name), bins);
        for o in slot_range(&mut owner, base, s.addr, s.size) {
            *o = Some(m.clone());
        }
    }
    let mut out = BTreeMap::new();
    for o in owner {
        *out.entry(o.unwrap_or_else(|| "padding".into())).or_insert(0) += 1;
    }
    out
}

/// The sized symbols of section `name`, Thumb bits cleared.
fn symbols_in(elf: &object::File<'_>, name: &str) -> Vec<Sym> {
    let Some(sec) = elf.section_by_name(name) else { return Vec::new() };
    elf.symbols()
        .filter(|y| y.section_index() == Some(sec.index()) && y.size() > 0)
        .map(|y| Sym {
            addr: if y.kind() == SymbolKind::Text { y.address() & !1 } else { y.address() },
            size: y.size(),
            name: y.name().unwrap_or("").to_string(),
        })
        .collect()
}

/// Code bytes by module: through DWARF when the ELF has it (`true`), else by symbol.
fn attribute_text(elf: &object::File<'_>) -> Result<(BTreeMap<String, u64>, bool)> {
    let Some(text) = elf.section_by_name(".text") else { return Ok((BTreeMap::new(), false)) };
    let (base, len, syms) = (text.address(), text.size(), symbols_in(elf, ".text"));
    Ok(match dwarf::attribute_code(elf, base, len, &syms, FIRMWARE_BINS)? {
        Some(rows) => (rows, true),
        None => (attribute_code_by_symbols(base, len, &syms, FIRMWARE_BINS), false),
    })
}

/// Read the flash table of a firmware ELF.
pub fn flash_table(path: &Path) -> Result<FlashTable> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let elf = object::File::parse(&*bytes).with_context(|| format!("{} is not an ELF file", path.display()))?;
    let size = |name: &str| elf.section_by_name(name).map_or(0, |s| s.size());
    let mut rows: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    let (code, by_debug_info) = attribute_text(&elf)?;
    for (m, n) in code {
        rows.entry(m).or_default().0 += n;
    }
    for name in [".rodata", ".data"] {
        if let Some(sec) = elf.section_by_name(name) {
            let data = sec.data().unwrap_or(&[]);
            for (m, n) in attribute_rodata(sec.address(), data, &symbols_in(&elf, name), FIRMWARE_BINS) {
                rows.entry(m).or_default().1 += n;
            }
        }
    }
    rows.entry("vector table".into()).or_default().1 += size(".vector_table");
    Ok(FlashTable {
        elf: path.display().to_string(),
        vector_table: size(".vector_table"),
        text: size(".text"),
        rodata: size(".rodata"),
        data: size(".data"),
        bss: size(".bss") + size(".uninit"),
        flash: size(".vector_table") + size(".text") + size(".rodata") + size(".data"),
        budget: budget_of(path),
        by_debug_info,
        modules: ordered(rows),
    })
}

/// Rows in [`CONCERNS`] order, then the rest by size.
fn ordered(rows: BTreeMap<String, (u64, u64)>) -> Vec<ModuleSize> {
    let rank = |m: &str| concern_index(m).unwrap_or(CONCERNS.len());
    let mut v: Vec<ModuleSize> = rows
        .into_iter()
        .filter(|(_, (c, d))| c + d > 0)
        .map(|(m, (code, data))| ModuleSize { concern: concern_of(&m).into(), module: m, code, data })
        .collect();
    v.sort_by_key(|m| (rank(&m.module), std::cmp::Reverse(m.code + m.data)));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module folder's files count for the module's concern; a name that only starts alike
    /// does not.
    #[test]
    fn submodules_count_for_their_modules_concern() {
        assert_eq!(concern_of("cell_core::light"), concern_of("cell_core::light::fate"));
        assert_eq!(concern_of("cell_core::light::out"), "lighting cell: FIFO, ports, lit store (§4.4, §5.5)");
        assert_eq!(concern_of("cell_core::lighting"), "other");
        assert_eq!(concern_of("heapless"), "other");
    }

    /// The known tables are the standard CRCs' (checked against a bitwise CRC of "123456789")
    /// and the gamma thresholds; a section holding them at odd places is split around them.
    #[test]
    fn known_tables_are_found_in_anonymous_data() {
        let tables = known_tables();
        let crc32 = &tables.iter().find(|t| t.0 == "cell_core::wire").unwrap().1;
        let entry = |i: usize| u32::from_le_bytes(crc32[4 * i..4 * i + 4].try_into().unwrap());
        let crc = b"123456789".iter().fold(!0u32, |c, &b| (c >> 8) ^ entry(((c ^ b as u32) & 0xff) as usize));
        assert_eq!(!crc, 0xCBF4_3926, "CRC-32/ISO-HDLC check value");
        let crc64 = &tables.iter().find(|t| t.0 == "cell_core::trace").unwrap().1;
        let e64 = |i: usize| u64::from_le_bytes(crc64[8 * i..8 * i + 8].try_into().unwrap());
        let c = b"123456789".iter().fold(!0u64, |c, &b| (c >> 8) ^ e64(((c ^ b as u64) & 0xff) as usize));
        assert_eq!(!c, 0x995D_C9BB_DF19_39FA, "CRC-64/XZ check value");

        let gamma = &tables.iter().find(|t| t.0 == "cell_core::shade").unwrap().1;
        let mut section = vec![7u8; 10];
        section.extend_from_slice(gamma);
        section.extend_from_slice(&[1, 2, 3]);
        section.extend_from_slice(crc32);
        section.extend_from_slice(&[9; 5]);
        let base = 0x8000;
        let named = Sym { addr: base + 2, size: 4, name: "_ZN9cell_core4beam5TABLE17h0123456789abcdefE".into() };
        let rows = attribute_rodata(base, &section, &[named], FIRMWARE_BINS);
        assert_eq!(rows["cell_core::shade"], 1020);
        assert_eq!(rows["cell_core::wire"], 1024);
        assert_eq!(rows["cell_core::beam"], 4);
        assert_eq!(rows["anonymous constants"], 10 - 4 + 3 + 5);
        assert_eq!(rows.values().sum::<u64>(), section.len() as u64, "every byte in one row");
    }
}

//! Code bytes attributed to source modules through DWARF: the line table says which file each
//! instruction came from (the innermost inlined function's), the inlined-subroutine entries
//! where each inlined call was made. A byte counts for the innermost project file on that
//! chain ([`super::flash`] module docs).

use std::borrow::Cow;
use std::collections::BTreeMap;

use anyhow::Result;
use gimli::{AttributeValue, EndianSlice, LittleEndian};
use object::{Object, ObjectSection};

use super::names::{demangle, is_project, module_of_file, module_of_symbol, Sym};

/// Instructions `lo..hi` came from a file of `module` (`None`: unknown file).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LineSpan {
    /// First address.
    pub lo: u64,
    /// One past the last.
    pub hi: u64,
    /// The file's module.
    pub module: Option<String>,
}

/// An inlined call covering `lo..hi`, made from a file of `call_module`, at DIE depth `depth`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Inlined {
    /// First address.
    pub lo: u64,
    /// One past the last.
    pub hi: u64,
    /// Nesting depth of the entry (deeper: inlined into an inlined call).
    pub depth: isize,
    /// Module of the file the call is in.
    pub call_module: Option<String>,
}

/// Attribute the code section `base .. base + len`: the innermost project module on each
/// byte's chain (line file, then the call files of its inlined calls, innermost first); else
/// the symbol holding it if that is project code; else the line file's module; else the
/// symbol's; else "padding".
pub fn attribute(
    base: u64,
    len: u64,
    lines: &[LineSpan],
    inlined: &[Inlined],
    syms: &[Sym],
    bins: &[&str],
) -> BTreeMap<String, u64> {
    let n = len as usize;
    let index = |a: u64| (a.saturating_sub(base) as usize).min(n);
    let mut line: Vec<Option<&str>> = vec![None; n];
    for l in lines {
        line[index(l.lo)..index(l.hi).max(index(l.lo))].iter_mut().for_each(|s| *s = l.module.as_deref());
    }
    let mut call: Vec<(isize, Option<&str>)> = vec![(isize::MIN, None); n];
    for i in inlined.iter().filter(|i| i.call_module.as_deref().is_some_and(is_project)) {
        for c in &mut call[index(i.lo)..index(i.hi).max(index(i.lo))] {
            if i.depth > c.0 {
                *c = (i.depth, i.call_module.as_deref());
            }
        }
    }
    let mut by_symbol: Vec<Option<String>> = vec![None; n];
    for s in syms {
        let m = module_of_symbol(&demangle(&s.name), bins);
        by_symbol[index(s.addr)..index(s.addr + s.size).max(index(s.addr))]
            .iter_mut()
            .for_each(|o| *o = Some(m.clone()));
    }
    let mut out = BTreeMap::new();
    for b in 0..n {
        let symbol = by_symbol[b].as_deref();
        let m = match (line[b], call[b].1, symbol) {
            (Some(l), _, _) if is_project(l) => l,
            (_, Some(c), _) => c,
            // Library code in a project function with no inlined-call entry around it (LLVM
            // drops those of the smallest inlined calls).
            (_, None, Some(s)) if is_project(s) => s,
            (Some(l), None, _) => l,
            (None, None, s) => s.unwrap_or("padding"),
        };
        *out.entry(m.to_string()).or_insert(0) += 1;
    }
    out
}

type Reader<'a> = EndianSlice<'a, LittleEndian>;

/// Attribute the code section of `elf` through its DWARF; `None` when it has no line table.
pub fn attribute_code(
    elf: &object::File<'_>,
    base: u64,
    len: u64,
    syms: &[Sym],
    bins: &[&str],
) -> Result<Option<BTreeMap<String, u64>>> {
    if elf.section_by_name(".debug_line").is_none() {
        return Ok(None);
    }
    let load = |id: gimli::SectionId| -> Result<Cow<'_, [u8]>, gimli::Error> {
        Ok(elf.section_by_name(id.name()).and_then(|s| s.data().ok()).map_or(Cow::Borrowed(&[][..]), Cow::Borrowed))
    };
    let sections = gimli::DwarfSections::load(load)?;
    let dwarf = sections.borrow(|s| EndianSlice::new(s, LittleEndian));
    let (mut lines, mut inlined) = (Vec::new(), Vec::new());
    let mut units = dwarf.units();
    while let Some(header) = units.next()? {
        let unit = dwarf.unit(header)?;
        read_lines(&dwarf, &unit, &mut lines)?;
        read_inlined(&dwarf, &unit, &mut inlined)?;
    }
    Ok(Some(attribute(base, len, &lines, &inlined, syms, bins)))
}

/// The module of file `index` of a unit's line program.
fn file_module(dwarf: &gimli::Dwarf<Reader<'_>>, unit: &gimli::Unit<Reader<'_>>, index: u64) -> Option<String> {
    let program = unit.line_program.as_ref()?;
    let header = program.header();
    let file = header.file(index)?;
    let mut path = String::new();
    if let Some(dir) = file.directory(header) {
        path += &dwarf.attr_string(unit, dir).ok()?.to_string_lossy();
        path.push('/');
    }
    path += &dwarf.attr_string(unit, file.path_name()).ok()?.to_string_lossy();
    module_of_file(&path)
}

/// Every row of a unit's line table as a span up to the next row.
fn read_lines(dwarf: &gimli::Dwarf<Reader<'_>>, unit: &gimli::Unit<Reader<'_>>, out: &mut Vec<LineSpan>) -> Result<()> {
    let Some(program) = unit.line_program.clone() else { return Ok(()) };
    let mut rows = program.rows();
    let mut modules: BTreeMap<u64, Option<String>> = BTreeMap::new();
    let mut open: Option<(u64, Option<String>)> = None;
    while let Some((_, row)) = rows.next_row()? {
        if let Some((lo, module)) = open.take() {
            if row.address() > lo {
                out.push(LineSpan { lo, hi: row.address(), module });
            }
        }
        if !row.end_sequence() {
            // Line 0: code of no source line (spills, jumps); it counts for the function or
            // inlined call around it, not for the file the row happens to name.
            let m = match row.line() {
                None => None,
                Some(_) => modules
                    .entry(row.file_index())
                    .or_insert_with(|| file_module(dwarf, unit, row.file_index()))
                    .clone(),
            };
            open = Some((row.address(), m));
        }
    }
    Ok(())
}

/// Every inlined-subroutine entry of a unit, with its ranges, depth and call file.
fn read_inlined(
    dwarf: &gimli::Dwarf<Reader<'_>>,
    unit: &gimli::Unit<Reader<'_>>,
    out: &mut Vec<Inlined>,
) -> Result<()> {
    let mut entries = unit.entries();
    let mut depth = 0isize;
    let mut modules: BTreeMap<u64, Option<String>> = BTreeMap::new();
    while let Some((delta, entry)) = entries.next_dfs()? {
        depth += delta;
        if entry.tag() != gimli::DW_TAG_inlined_subroutine {
            continue;
        }
        let call_module = match entry.attr_value(gimli::DW_AT_call_file)? {
            Some(AttributeValue::FileIndex(i)) | Some(AttributeValue::Udata(i)) => {
                modules.entry(i).or_insert_with(|| file_module(dwarf, unit, i)).clone()
            }
            _ => None,
        };
        let mut ranges = dwarf.die_ranges(unit, entry)?;
        while let Some(r) = ranges.next()? {
            out.push(Inlined { lo: r.begin, hi: r.end, depth, call_module: call_module.clone() });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(lo: u64, hi: u64, m: &str) -> LineSpan {
        LineSpan { lo, hi, module: Some(m.into()) }
    }

    fn inl(lo: u64, hi: u64, depth: isize, m: &str) -> Inlined {
        Inlined { lo, hi, depth, call_module: Some(m.into()) }
    }

    /// A step function of the light cell (0x100..0x140) with the beam split inlined into it
    /// (0x110..0x130), and a `core` slice helper inlined into the split (0x118..0x120) and into
    /// the step (0x130..0x138); `memcpy` (0x140..0x150) has no line info and no project frame;
    /// `core` code in `panic_fmt` (0x150..0x158) is core's, in the firmware's `main` with no
    /// inlined-call entry (0x158..0x160) the firmware's; 0x160..0x168 is nobody's.
    #[test]
    fn code_counts_for_the_innermost_project_frame() {
        let lines = [
            span(0x100, 0x110, "cell_core::light"),
            span(0x110, 0x118, "cell_core::beam"),
            span(0x118, 0x120, "core"),
            span(0x120, 0x130, "cell_core::beam"),
            span(0x130, 0x138, "core"),
            span(0x138, 0x140, "cell_core::light"),
            span(0x150, 0x158, "core"),
            span(0x158, 0x160, "core"),
        ];
        let inlined = [
            inl(0x110, 0x130, 2, "cell_core::light"), // the split, called from light.rs
            inl(0x118, 0x120, 3, "cell_core::beam"),  // the helper, called from beam.rs
            inl(0x130, 0x138, 2, "cell_core::light"), // the helper, called from light.rs
            inl(0x150, 0x154, 2, "core"),             // core inlined into core
        ];
        let syms = [
            Sym { addr: 0x140, size: 0x10, name: "_RNvNtCs7NhdfSRABLd_17compiler_builtins3mem6memcpy".into() },
            Sym { addr: 0x150, size: 0x08, name: "_RNvNtCs7ldSeZOOJos_4core9panicking9panic_fmt".into() },
            Sym { addr: 0x158, size: 0x08, name: "_ZN4cell4main17h0123456789abcdefE".into() },
        ];
        let got = attribute(0x100, 0x68, &lines, &inlined, &syms, &["cell"]);
        let want: BTreeMap<String, u64> = [
            ("cell_core::light".to_string(), 0x10 + 0x8 + 0x8),
            ("cell_core::beam".to_string(), 0x20),
            ("compiler_builtins".to_string(), 0x10),
            ("core".to_string(), 0x8),
            ("firmware".to_string(), 0x8),
            ("padding".to_string(), 0x8),
        ]
        .into_iter()
        .collect();
        assert_eq!(got, want);
        assert_eq!(got.values().sum::<u64>(), 0x68, "every byte in one row");
    }
}

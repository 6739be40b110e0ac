//! Which module a symbol or a source file counts for: demangled Rust paths (legacy in full,
//! v0 to crate and module) and source paths (`cell-core/src/…`, `firmware/src/…`, library and
//! registry crates).

/// The crate names of the firmware's binaries (their own code counts as `firmware`).
pub const FIRMWARE_BINS: &[&str] = &["cell", "rc2_firmware"];

/// One symbol of a flash section.
#[derive(Clone, Debug)]
pub struct Sym {
    /// Address (the Thumb bit cleared).
    pub addr: u64,
    /// Size in bytes.
    pub size: u64,
    /// Raw (mangled) name.
    pub name: String,
}

/// Decode a Rust symbol's path: legacy mangling (`_ZN9cell_core4beam10split_axis17h…E`) in
/// full, v0 (`_RNv…`, the standard library's) to its crate and first module. Unmangled names
/// come back as they are.
pub fn demangle(sym: &str) -> String {
    let sym = sym.strip_prefix(".Lswitch.table.").unwrap_or(sym);
    let sym = sym.split(".llvm.").next().unwrap_or(sym);
    if let Some(rest) = sym.strip_prefix("_ZN") {
        return demangle_legacy(rest).unwrap_or_else(|| sym.to_string());
    }
    if let Some(rest) = sym.strip_prefix("_R") {
        return demangle_v0_prefix(rest).unwrap_or_else(|| sym.to_string());
    }
    sym.to_string()
}

/// Length-prefixed identifiers up to `E`, joined with `::`; the hash component dropped.
fn demangle_legacy(mut s: &str) -> Option<String> {
    let mut parts = Vec::new();
    while !s.starts_with('E') {
        let digits = s.find(|c: char| !c.is_ascii_digit())?;
        let len: usize = s[..digits].parse().ok()?;
        let ident = s.get(digits..digits + len)?;
        s = &s[digits + len..];
        let is_hash = ident.len() == 17 && ident.starts_with('h') && ident[1..].chars().all(|c| c.is_ascii_hexdigit());
        if !is_hash {
            parts.push(unescape_legacy(ident));
        }
    }
    Some(parts.join("::"))
}

fn unescape_legacy(ident: &str) -> String {
    const CODES: &[(&str, &str)] = &[
        ("$LT$", "<"),
        ("$GT$", ">"),
        ("$RF$", "&"),
        ("$BP$", "*"),
        ("$SP$", "@"),
        ("$LP$", "("),
        ("$RP$", ")"),
        ("$C$", ","),
        ("$u20$", " "),
        ("$u27$", "'"),
        ("$u3b$", ";"),
        ("$u5b$", "["),
        ("$u5d$", "]"),
        ("$u7b$", "{"),
        ("$u7d$", "}"),
        ("$u7e$", "~"),
    ];
    let mut s = ident.strip_prefix('_').filter(|r| r.starts_with('$')).unwrap_or(ident).replace("..", "::");
    for (code, c) in CODES {
        s = s.replace(code, c);
    }
    s
}

/// The crate and the identifier after it (`core::fmt`) of a v0 symbol.
fn demangle_v0_prefix(s: &str) -> Option<String> {
    let mut idents = Vec::new();
    let b = s.as_bytes();
    let mut i = s.find('C')? + 1;
    while i < b.len() && idents.len() < 2 {
        if b[i] == b's' && idents.is_empty() {
            // crate disambiguator: s<base-62>_
            i += s[i..].find('_')? + 1;
            continue;
        }
        if b[i].is_ascii_digit() {
            let digits = s[i..].find(|c: char| !c.is_ascii_digit())?;
            let len: usize = s[i..i + digits].parse().ok()?;
            let start = i + digits + (b.get(i + digits) == Some(&b'_')) as usize;
            idents.push(s.get(start..start + len)?.to_string());
            i = start + len;
        } else {
            i += 1;
        }
    }
    (!idents.is_empty()).then(|| idents.join("::"))
}

/// The module a demangled symbol path counts for: `cell_core::<module>` for the cell's
/// library, `firmware` for a firmware binary's own code (its crate is one of `bins`), the
/// crate otherwise; the first path in the name decides (the self type of `<A as B>::f`).
pub fn module_of_symbol(demangled: &str, bins: &[&str]) -> String {
    let runtime = ["Reset", "main", "DefaultHandler", "DefaultHandler_", "HardFault_", "HardFault", "__pre_init"];
    if runtime.contains(&demangled) {
        return "cortex_m_rt".into();
    }
    if demangled.starts_with("__") || ["memcpy", "memmove", "memset", "memcmp", "fmaxf", "fminf"].contains(&demangled) {
        return "compiler_builtins".into();
    }
    let path = first_path(demangled);
    let mut segs = path.split("::");
    let krate = segs.next().unwrap_or("");
    match krate {
        "cell_core" => segs.next().map_or("cell_core".into(), |m| format!("cell_core::{m}")),
        k if bins.contains(&k) => "firmware".into(),
        "" => "other".into(),
        k => k.into(),
    }
}

/// The first `a::b::c` path in a demangled name.
fn first_path(s: &str) -> &str {
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut start = 0;
    for (i, c) in s.char_indices() {
        if !is_ident(c) && c != ':' {
            start = i + c.len_utf8();
            continue;
        }
        if s[i..].starts_with("::") && i > start {
            let end = s[start..].find(|c: char| !is_ident(c) && c != ':').map_or(s.len(), |e| start + e);
            return &s[start..end];
        }
    }
    ""
}

/// The module a source file counts for: `cell_core::beam` for `…/cell-core/src/beam.rs`
/// (`cell_core::machine::classic` for `…/cell-core/src/machine/classic.rs`), `firmware` for
/// `…/firmware/src/…`, the crate for library and registry code, `None` if unknown.
pub fn module_of_file(path: &str) -> Option<String> {
    let path = path.replace('\\', "/");
    if let Some(rest) = path.split("/cell-core/src/").nth(1) {
        let rest = rest.trim_end_matches(".rs").trim_end_matches("/mod");
        return Some(if rest == "lib" {
            "cell_core".into()
        } else {
            format!("cell_core::{}", rest.replace('/', "::"))
        });
    }
    if path.contains("/firmware/src/") {
        return Some("firmware".into());
    }
    if let Some(rest) = path.split("/library/").nth(1) {
        return rest.split('/').next().map(|c| c.replace('-', "_"));
    }
    if path.contains("compiler-builtins") || path.contains("compiler_builtins") {
        return Some("compiler_builtins".into());
    }
    // …/registry/src/<index>/<name>-<version>/…
    let krate = path.split("/registry/src/").nth(1)?.split('/').nth(1)?;
    let name =
        krate
            .rsplit_once('-')
            .map_or(krate, |(n, v)| if v.starts_with(|c: char| c.is_ascii_digit()) { n } else { krate });
    Some(name.replace('-', "_"))
}

/// Whether a module is the project's own code (the cell library or the firmware).
pub fn is_project(module: &str) -> bool {
    module.starts_with("cell_core") || module == "firmware"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legacy_and_v0_symbols_name_their_module() {
        let bins = FIRMWARE_BINS;
        let cases = [
            ("_ZN9cell_core4beam10split_axis17hbd674ff168acb734E", "cell_core::beam"),
            (
                "_ZN114_$LT$cell_core..occupancy..OccupancySummary$LT$_$C$R$GT$$u20$as$u20$cell_core..occupancy..\
                 FrustumTest$LT$F$GT$$GT$13frustum_empty17ha6a38f737c506ebcE",
                "cell_core::occupancy",
            ),
            ("_ZN42_$LT$$RF$T$u20$as$u20$core..fmt..Debug$GT$3fmt17h8314c89e52e7c15bE", "core"),
            ("_ZN4cell4Node6accept17h45631c2fdf256cd8E", "firmware"),
            ("_ZN12rc2_firmware4CELL17h1332907407e1027dE", "firmware"),
            ("_RNvMsa_NtCs7ldSeZOOJos_4core3fmtNtB5_9Formatter12pad_integral", "core"),
            ("_RNvNtCs7NhdfSRABLd_17compiler_builtins3mem6memcpy", "compiler_builtins"),
            ("_ZN3crc5crc3259_$LT$impl$u20$crc..Crc$LT$u32$C$crc..Table$LT$_$GT$$GT$$GT$8checksum17h9f05ea3934906fe3E", "crc"),
            (".Lswitch.table._ZN9cell_core5light4Step3new17h0123456789abcdefE", "cell_core::light"),
            ("__aeabi_memcpy4", "compiler_builtins"),
            ("HardFault_", "cortex_m_rt"),
        ];
        for (sym, module) in cases {
            assert_eq!(module_of_symbol(&demangle(sym), bins), module, "{sym} → {}", demangle(sym));
        }
        assert_eq!(
            demangle("_ZN9cell_core5light30LightCell$LT$F$C$_$C$_$C$_$GT$4fate17h5ce731d2b60551b7E"),
            "cell_core::light::LightCell<F,_,_,_>::fate"
        );
        assert_eq!(demangle("_RNvNtCs7ldSeZOOJos_4core9panicking9panic_fmt"), "core::panicking");
    }

    #[test]
    fn source_files_name_their_module() {
        let cases = [
            ("/work/x/cell-core/src/beam.rs", Some("cell_core::beam")),
            ("/work/x/cell-core/src/machine/classic.rs", Some("cell_core::machine::classic")),
            ("/work/x/cell-core/src/machine/mod.rs", Some("cell_core::machine")),
            ("/work/x/firmware/src/bin/cell/main.rs", Some("firmware")),
            ("/rustc/59807616e1fa/library/core/src/slice/mod.rs", Some("core")),
            ("/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/heapless-0.8.0/src/vec.rs", Some("heapless")),
            (
                "/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/cortex-m-rt-0.7.5/src/lib.rs",
                Some("cortex_m_rt"),
            ),
            ("/rustc/x/library/compiler-builtins/compiler-builtins/src/mem/impls.rs", Some("compiler_builtins")),
            ("<unknown>", None),
        ];
        for (path, module) in cases {
            assert_eq!(module_of_file(path).as_deref(), module, "{path}");
        }
    }
}

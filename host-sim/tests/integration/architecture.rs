//! The layering of host-sim, read from its source: no import circles between modules (in
//! host-sim and in cell-core), nor between folders (`machine/`'s phase folders among them), the
//! machine and the truth below the jobs, reports and command line, nothing but the command line
//! importing it, clap only in `cli/`.
//!
//! A module is a source file (`machine/grid/capacity.rs` is `machine::grid::capacity`,
//! `scene/mod.rs` is `scene`). A module depends on another when its non-test code names a
//! `crate::…` or `super::…` path into it (a path is resolved to the longest module it names:
//! `crate::scene::Mesh` is `scene`, the folder's `mod.rs`, which re-exports its children).
//! Comments and `#[cfg(test)]` modules are left out: a doc link or a unit test that looks upward
//! is not an import. A folder depends on a sibling when a module anywhere inside it depends on
//! one anywhere inside the sibling (`machine::rays::classic` → `machine::lighting::run` is
//! `machine::rays` → `machine::lighting`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn source_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            source_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `machine/grid/capacity.rs` → ["machine", "grid", "capacity"]; `scene/mod.rs` → ["scene"]; `lib.rs` → [].
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without its `#[cfg(test)]` module.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// Every `crate::a::b…` and `super::a…` path of `code` (groups `{…}` expanded one level), as
/// absolute segment lists.
fn paths_in(code: &str, module: &[String], is_folder_root: bool) -> Vec<Vec<String>> {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut out = Vec::new();
    for start in ["crate::", "super::"] {
        let mut rest = code;
        while let Some(i) = rest.find(start) {
            let before = rest[..i].chars().last();
            rest = &rest[i..];
            if before.is_some_and(ident) {
                rest = &rest[start.len()..];
                continue;
            }
            let mut segs: Vec<String> = Vec::new();
            let mut s = &rest[start.len()..];
            // `super::super::…` climbs one folder per `super`.
            let mut supers = 1;
            while let Some(t) = s.strip_prefix("super::").filter(|_| start == "super::") {
                supers += 1;
                s = t;
            }
            loop {
                let end = s.find(|c: char| !ident(c)).unwrap_or(s.len());
                if end == 0 {
                    break;
                }
                segs.push(s[..end].to_string());
                s = &s[end..];
                if let Some(t) = s.strip_prefix("::") {
                    s = t;
                } else {
                    break;
                }
            }
            // `use crate::a::{b, c::d}`: one path per member.
            let mut members = vec![Vec::new()];
            if let Some(t) = s.strip_prefix('{') {
                let body = &t[..t.find('}').unwrap_or(t.len())];
                members = body
                    .split(',')
                    .map(|m| m.trim().split("::").map(|x| x.trim().to_string()).filter(|x| !x.is_empty()).collect())
                    .collect();
            }
            let base: Vec<String> = if start == "crate::" {
                Vec::new()
            } else {
                // `super` of a folder's `mod.rs` is the folder's parent; of a file, its folder.
                let up = supers + usize::from(is_folder_root);
                module[..module.len().saturating_sub(up)].to_vec()
            };
            for m in members {
                let mut p = base.clone();
                p.extend(segs.iter().cloned());
                p.extend(m);
                out.push(p);
            }
            rest = &rest[start.len() * supers..];
        }
    }
    out
}

/// Module (or folder) → the modules (or folders) it depends on.
type Graph = BTreeMap<Vec<String>, BTreeSet<Vec<String>>>;

struct Crate {
    /// Module → the modules it depends on.
    deps: Graph,
    /// Module → its code.
    code: BTreeMap<Vec<String>, String>,
}

fn read_crate() -> Crate {
    read_crate_at(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"))
}

/// The crate whose sources are under `src`.
fn read_crate_at(src: &Path) -> Crate {
    let mut files = Vec::new();
    source_files(src, &mut files);
    let mut code = BTreeMap::new();
    let mut roots = BTreeSet::new();
    for f in &files {
        let m = module_of(src, f);
        if f.file_name().is_some_and(|n| n == "mod.rs") {
            roots.insert(m.clone());
        }
        if !m.is_empty() {
            code.insert(m, code_of(&std::fs::read_to_string(f).unwrap()));
        }
    }
    let modules: BTreeSet<Vec<String>> = code.keys().cloned().collect();
    let mut deps = BTreeMap::new();
    for (m, c) in &code {
        let mut d = BTreeSet::new();
        for p in paths_in(c, m, roots.contains(m)) {
            // The longest prefix of the path that is a module.
            if let Some(target) = (1..=p.len()).rev().map(|k| p[..k].to_vec()).find(|q| modules.contains(q)) {
                // A folder's mod.rs declaring its children is structure, not an import.
                let declares = target.len() == m.len() + 1 && target.starts_with(m) && roots.contains(m);
                if &target != m && !declares {
                    d.insert(target);
                }
            }
        }
        deps.insert(m.clone(), d);
    }
    Crate { deps, code }
}

fn name(m: &[String]) -> String {
    m.join("::")
}

#[test]
fn the_parser_sees_imports_grouped_nested_and_through_super() {
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    let code = "use crate::machine::{grid::Grid, diffuse};\nfn f() { super::office::generate(); crate::truth::compare::psnr(); }";
    let got = paths_in(code, &m("scene::builtin"), false);
    assert!(got.contains(&m("machine::grid::Grid")), "{got:?}");
    assert!(got.contains(&m("machine::diffuse")), "{got:?}");
    assert!(got.contains(&m("scene::office::generate")), "{got:?}");
    assert!(got.contains(&m("truth::compare::psnr")), "{got:?}");
    // `super` from a folder's mod.rs goes above the folder.
    assert_eq!(paths_in("super::precompute::Fit", &m("scene"), true), vec![m("precompute::Fit")]);
    // `super::super::` climbs two folders, and is one path.
    assert_eq!(paths_in("use super::super::a::W;", &m("b::c::z"), false), vec![m("b::a::W")]);
    assert_eq!(paths_in("use super::super::a::W;", &m("b::c"), true), vec![m("a::W")]);
    // Comments and unit tests are not imports.
    assert_eq!(
        code_of("// crate::jobs::x\nfn a() {}\n#[cfg(test)]\nmod tests { use crate::cli::y; }").trim(),
        "fn a() {}"
    );
}

#[test]
fn the_crate_is_read() {
    let c = read_crate();
    for m in ["machine::lighting::diffuse", "machine::grid", "jobs::render", "truth::refrender", "cli", "scene::mesh"] {
        let m: Vec<String> = m.split("::").map(String::from).collect();
        assert!(c.code.contains_key(&m), "module {} not found: the layout changed, update this test", name(&m));
    }
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    let diffuse = &c.deps[&m("machine::lighting::diffuse")];
    assert!(diffuse.contains(&m("machine::grid")), "{diffuse:?}");
    let machine = &between_folders(&c)[&m("machine::lighting")];
    assert!(machine.contains(&m("machine::grid")) && machine.contains(&m("machine::links")), "{machine:?}");
}

#[test]
fn no_import_circles_between_modules() {
    assert_no_circle(&read_crate());
}

/// What one cell runs has no import circle either: each thesis concern's module stands on
/// the ones below it.
#[test]
fn no_import_circles_in_cell_core() {
    let c = read_crate_at(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../cell-core/src"));
    assert!(c.code.contains_key(&vec!["light".to_string()]), "cell-core's layout changed: update this test");
    assert_no_circle(&c);
}

/// The phase folders of `machine/` (and every other folder) stand on one another in one order:
/// no module of a folder imports a sibling folder that imports it back, even where the files
/// themselves form no circle.
#[test]
fn no_import_circles_between_folders() {
    let c = read_crate();
    let phases = c.code.keys().filter(|m| m.len() == 2 && m[0] == "machine").count();
    assert!(phases >= 5, "machine/ is no longer in phase folders: update this test");
    let found = folders_with_circles(&between_folders(&c));
    let circles: Vec<&str> = found.iter().map(|(_, c)| c.as_str()).collect();
    assert!(found.is_empty(), "import circles between folders:\n{}", circles.join("\n"));
    let cell = read_crate_at(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../cell-core/src"));
    assert_no_circle_in(&between_folders(&cell));
}

/// The folders whose children (sibling folders and files) import in a circle, each with one
/// such circle.
fn folders_with_circles(g: &Graph) -> Vec<(String, String)> {
    let mut by_parent: BTreeMap<Vec<String>, Graph> = BTreeMap::new();
    for (m, deps) in g {
        by_parent.entry(m[..m.len() - 1].to_vec()).or_default().insert(m.clone(), deps.clone());
    }
    by_parent
        .into_iter()
        .filter_map(|(p, g)| {
            let circle = find_circle(&g)?;
            Some((name(&p), circle.iter().map(|m| name(m)).collect::<Vec<_>>().join(" → ")))
        })
        .collect()
}

/// A made-up crate whose files form no circle but whose folders do: `a/x.rs` imports
/// `b/y.rs`, `b/z.rs` imports `a/w.rs`.
#[test]
fn a_circle_between_folders_is_seen_where_the_files_have_none() {
    let src = std::env::temp_dir().join(format!("rc2-architecture-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&src);
    for (file, text) in [
        ("lib.rs", "pub mod a;\npub mod b;\n"),
        ("a/mod.rs", "pub mod w;\npub mod x;\n"),
        ("a/w.rs", "pub struct W;\n"),
        ("a/x.rs", "use crate::b::y::Y;\n"),
        ("b/mod.rs", "pub mod y;\npub mod z;\n"),
        ("b/y.rs", "pub struct Y;\n"),
        ("b/z.rs", "use super::super::a::w::W;\n// crate::a::x is a comment\n"),
    ] {
        let p = src.join(file);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let c = read_crate_at(&src);
    std::fs::remove_dir_all(&src).unwrap();
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    assert_eq!(c.deps[&m("b::z")], BTreeSet::from([m("a::w")]));
    assert_eq!(find_circle(&c.deps), None, "the files form no circle");
    let folders = between_folders(&c);
    assert_eq!(folders[&m("a")], BTreeSet::from([m("b")]));
    let circle = find_circle(&folders).expect("the folders form a circle");
    assert_eq!(circle.len(), 3, "{circle:?}");
    assert!(circle.contains(&m("a")) && circle.contains(&m("b")), "{circle:?}");
    let found = folders_with_circles(&folders);
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].0, "", "the crate's root holds a and b");
    // Within a folder, a file and its folder's root are structure, not a sibling edge.
    let mut deps = BTreeMap::new();
    deps.insert(m("a::x"), BTreeSet::from([m("a")]));
    deps.insert(m("a"), BTreeSet::from([m("a::x::y")]));
    let c = Crate { deps, code: BTreeMap::new() };
    assert!(between_folders(&c).is_empty());
}

/// The graph between sibling folders and files: each dependency m → d becomes an edge between
/// the two children of their nearest common folder that hold them (none when one holds the
/// other).
fn between_folders(c: &Crate) -> Graph {
    let mut g: Graph = BTreeMap::new();
    for (m, deps) in &c.deps {
        for d in deps {
            let k = m.iter().zip(d).take_while(|(a, b)| a == b).count();
            if k < m.len() && k < d.len() {
                g.entry(m[..=k].to_vec()).or_default().insert(d[..=k].to_vec());
            }
        }
    }
    g
}

fn assert_no_circle(c: &Crate) {
    assert_no_circle_in(&c.deps);
}

fn assert_no_circle_in(deps: &Graph) {
    if let Some(circle) = find_circle(deps) {
        let names: Vec<String> = circle.iter().map(|m| name(m)).collect();
        panic!("import circle: {}", names.join(" → "));
    }
}

/// A circle of `deps`, if any (depth-first search for a back edge; the circle it closes).
fn find_circle(deps: &Graph) -> Option<Vec<Vec<String>>> {
    // Depth-first search for a back edge; report the circle it closes.
    fn visit(
        m: &Vec<String>,
        deps: &Graph,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<Vec<String>>> {
        state.insert(m.clone(), 1);
        stack.push(m.clone());
        for d in deps.get(m).into_iter().flatten() {
            match state.get(d).copied().unwrap_or(0) {
                1 => {
                    let i = stack.iter().position(|x| x == d).unwrap();
                    let mut circle = stack[i..].to_vec();
                    circle.push(d.clone());
                    return Some(circle);
                }
                0 => {
                    if let Some(c) = visit(d, deps, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(m.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in deps.keys() {
        if state.get(m).copied().unwrap_or(0) == 0 {
            let mut stack = Vec::new();
            if let Some(circle) = visit(m, deps, &mut state, &mut stack) {
                return Some(circle);
            }
        }
    }
    None
}

#[test]
fn the_machine_and_the_truth_never_import_jobs_reports_or_the_cli() {
    let c = read_crate();
    let mut bad = Vec::new();
    for (m, deps) in &c.deps {
        let below = matches!(m[0].as_str(), "machine" | "truth" | "scene" | "precompute" | "rng");
        for d in deps {
            let above = matches!(d[0].as_str(), "jobs" | "report" | "cli" | "config");
            // The truth is independent of the machine it judges.
            let judged = m[0] == "truth" && d[0] == "machine";
            if (below && above) || judged {
                bad.push(format!("{} imports {}", name(m), name(d)));
            }
        }
    }
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
}

#[test]
fn only_the_cli_imports_the_cli() {
    let c = read_crate();
    let bad: Vec<String> = c
        .deps
        .iter()
        .filter(|(m, deps)| m[0] != "cli" && deps.iter().any(|d| d[0] == "cli"))
        .map(|(m, _)| name(m))
        .collect();
    assert!(bad.is_empty(), "the jobs take plain options, never the command line's types: {bad:?} import cli/");
}

#[test]
fn clap_only_in_the_cli() {
    let c = read_crate();
    let bad: Vec<String> =
        c.code.iter().filter(|(m, code)| m[0] != "cli" && code.contains("clap")).map(|(m, _)| name(m)).collect();
    assert!(bad.is_empty(), "clap outside cli/: {bad:?}");
}

/// f (the rays' fraction bits) is a type parameter of the cells only: the host picks the cells'
/// build for a run's f inside the lighting run (`machine::lighting::diffuse::with_f`), and nothing above
/// the machine — jobs, their results, reports, the configuration, the CLI — is generic over it
/// or expands per f.
#[test]
fn f_is_confined_to_the_machine() {
    let c = read_crate();
    let bad: Vec<String> = c
        .code
        .iter()
        .filter(|(m, code)| m[0] != "machine" && (code.contains("FracBits") || code.contains("with_frac_bits")))
        .map(|(m, _)| name(m))
        .collect();
    assert!(bad.is_empty(), "generic over f or dispatching on it outside machine/: {bad:?}");
    let dispatch: Vec<String> =
        c.code.iter().filter(|(_, code)| code.contains("with_frac_bits!")).map(|(m, _)| name(m)).collect();
    assert_eq!(dispatch, ["machine::lighting::diffuse"], "one place picks the cells' build for an f");
}

/// The places in `code` that decide something by the lit rule's variant: a `match` arm on it
/// (`LitRule::Plane =>`, `LitRule::Thesis | …`) or a comparison with one (`== LitRule::Exact`).
/// Naming a variant as a value (a preset, a parsed option) is not a decision.
fn rule_decisions(code: &str) -> usize {
    let mut n = 0;
    for (i, _) in code.match_indices("LitRule::") {
        let rest = &code[i + "LitRule::".len()..];
        let variant = rest.find(|ch: char| !ch.is_alphanumeric() && ch != '_').unwrap_or(rest.len());
        if !rest[..variant].starts_with(|ch: char| ch.is_uppercase()) {
            continue; // a method or constant (`LitRule::from_code`, `LitRule::ALL`)
        }
        let after = rest[variant..].trim_start();
        // An arm, alone or closing a tuple pattern (`(true, LitRule::Plane) =>`).
        let closed = after.trim_start_matches(|ch: char| ch == ')' || ch.is_whitespace());
        let arm = after.starts_with("=>") || (after.starts_with(')') && closed.starts_with("=>"));
        let or = after.starts_with('|') && !after.starts_with("||");
        let before = code[..i].trim_end_matches(|ch: char| ch.is_alphanumeric() || ch == '_' || ch == ':').trim_end();
        let compared = before.ends_with("==") || before.ends_with("!=");
        let alternative = before.ends_with('|') && !before.ends_with("||");
        // `if let LitRule::Plane = …`, `if let (LitRule::Plane, …) = …`, `matches!(r, LitRule::Plane)`.
        let line = &code[code[..i].rfind('\n').map_or(0, |k| k + 1)..i];
        let pattern = line.rfind("if let ").is_some_and(|k| !line[k..].contains('='))
            || line.rfind("matches!(").is_some_and(|k| !line[k..].contains(')'));
        n += (arm || or || compared || alternative || pattern) as usize;
    }
    n
}

#[test]
fn rule_decisions_are_arms_and_comparisons_not_values() {
    let decided = "match r { LitRule::Thesis => 0, cell_core::lit::LitRule::Plane | LitRule::Exact => 1 }\n\
                   if cfg.rule == LitRule::Exact {} if a != cell_core::lit::LitRule::Thesis {}\n\
                   match (v, r) { (true, LitRule::Plane) => 1, _ => 0 }\n\
                   if let (LitRule::Plane, Some(s)) = (r, s) {}\n\
                   matches!(r, LitRule::Exact)";
    assert_eq!(rule_decisions(decided), 8);
    let values = "let r = LitRule::Plane; f(LitRule::Exact, x); LitRule::from_code(2); LitRule::ALL;\n\
                  a || LitRule::Thesis.is_exact(); if let Some(r) = f(LitRule::Plane) {} rule: LitRule::Exact,";
    assert_eq!(rule_decisions(values), 0);
}

/// The lit rule is asked in one place (issue: "the lit rule re-decided at ~65 lines"): what a
/// pixel reads, which marks a cell keeps, which voxels receive, what needs triangles, how a rule
/// is encoded or named are methods of `cell_core::lit::LitRule`; the rule's ray-by-ray work is
/// dispatched once per algorithm. Nothing else matches on its variants or compares with one.
#[test]
fn the_lit_rule_is_asked_in_one_place() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    // (crate, module) → decisions allowed there, and why.
    let allowed: BTreeMap<(&str, &str), usize> = [
        // The rule's own answers.
        (("cell-core", "lit"), usize::MAX),
        // A beam's fate: the rule's algorithm, dispatched once per visit.
        (("cell-core", "light::fate"), 3),
        // A classic shadow ray's emission point: the rule's algorithm, dispatched once per ray.
        (("cell-core", "shadow"), 1),
        // A radiosity shot is defined under the thesis's rule only: a validation.
        (("host-sim", "machine::lighting::diffuse"), 1),
    ]
    .into();
    let mut bad = Vec::new();
    for (krate, src) in [("host-sim", here.join("src")), ("cell-core", here.join("../cell-core/src"))] {
        for (m, code) in &read_crate_at(&src).code {
            let (name, n) = (name(m), rule_decisions(code));
            let limit = allowed.get(&(krate, name.as_str())).copied().unwrap_or(0);
            if n > limit {
                bad.push(format!("{krate} {name}: {n} (allowed {limit})"));
            }
        }
    }
    assert!(bad.is_empty(), "the lit rule decided by its variants outside cell_core::lit: {bad:?}");
}

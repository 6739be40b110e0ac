//! §2.5 of the radiosity thesis reproduced: Table 2.1 (equivalent resolutions: the resolution
//! of each method whose compared delta form factor is the hemicube's largest, §2.5.2), Table 2.2
//! (proxels used, §2.5.3) and Table 2.3 (memory in Mo = 10⁶ bytes, §2.5.3's byte model), each
//! cell computed from the method's own surface and set beside the published value.
//!
//! Rules (docs/FORM-FACTORS.md):
//! * Table 2.1: for the hemicube at R, the reference is its largest FFE (a central top proxel);
//!   each method's resolution is the smallest whose compared FFE
//!   ([`ProjectionSurface::equivalence_delta_ff`]) is at most the reference (at least the
//!   hemicube's precision); Recker's R1 and R2 each so, R2 on the outer FFE at the inner
//!   square's corner ([`ReckerPlane::outer_corner_delta`]).
//! * Tables 2.2 and 2.3: each surface at the resolutions the thesis published in Table 2.1
//!   ("les résolutions équivalentes pouvant être obtenues dans la Table 2.1"), so that each
//!   table is checked on its own.
//! * A computed cell agrees when it is within one unit of the published cell's last digit
//!   (rounding); the cells that do not are [`INCONSISTENT`], each with the reason.

use std::fmt::Write as _;

use anyhow::Result;

use super::disk::Disk;
use super::hemicube::Hemicube;
use super::hemisphere::Hemisphere;
use super::hemisphere_uniform::UniformHemisphere;
use super::recker::ReckerPlane;
use super::sillion::SillionPlane;
use super::{ProjectionSurface, MAX_RESOLUTION};

/// The methods, in the tables' column order (CSV names, and the names of
/// [`super::SurfaceSpec::parse`]).
pub const METHODS: [&str; 6] = ["hemicube", "sillion", "recker", "hemisphere-uniform", "hemisphere", "disk"];

/// [`METHODS`], then every other method in `present` (the grid's shot), in order of appearance:
/// the columns of a table, the lines of a figure.
pub fn methods_with<'a>(present: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut methods: Vec<&str> = METHODS.to_vec();
    for m in present {
        if !methods.contains(&m) {
            methods.push(m);
        }
    }
    methods
}

/// The hemicube resolutions of the rows.
pub const ROWS: [u32; 6] = [100, 200, 400, 600, 800, 1000];

/// Table 2.1 as published: the reference form factor, then one resolution per method
/// (Recker's as `R1/R2`).
pub const TABLE_2_1: [(&str, [&str; 6]); 6] = [
    ("1.27e-4", ["100", "98", "180/67", "56", "45", "100"]),
    ("3.18e-5", ["200", "197", "360/134", "112", "89", "200"]),
    ("7.96e-6", ["400", "393", "720/267", "223", "178", "400"]),
    ("3.54e-6", ["600", "590", "1080/401", "334", "266", "600"]),
    ("1.99e-6", ["800", "786", "1440/535", "445", "355", "800"]),
    ("1.27e-6", ["1000", "983", "1800/668", "556", "444", "1000"]),
];

/// Table 2.2 as published, rows by hemicube resolution ([`ROWS`]).
pub const TABLE_2_2: [[&str; 6]; 6] = [
    ["30000", "9604", "36291", "12544", "8100", "10000"],
    ["120000", "38809", "145158", "59536", "31684", "40000"],
    ["480000", "154449", "580628", "198916", "126736", "160000"],
    ["1080000", "348100", "1306411", "446224", "283024", "360000"],
    ["1920000", "617796", "2322508", "792100", "504100", "640000"],
    ["3000000", "966289", "3628917", "1236544", "788544", "1000000"],
];

/// Table 2.3 as published (Mo), rows by hemicube resolution ([`ROWS`]).
pub const TABLE_2_3: [[&str; 6]; 6] = [
    ["0.25", "0.04", "0.31", "0.10", "0.06", "0.06"],
    ["1", "0.16", "1.25", "0.40", "0.25", "0.25"],
    ["4", "0.72", "5.01", "1.59", "1.01", "1.03"],
    ["9", "1.44", "11.28", "3.57", "2.26", "2.29"],
    ["16", "2.56", "20.05", "6.83", "4.03", "4.09"],
    ["25", "4.00", "31.33", "9.89", "6.30", "6.40"],
];

/// The published cells that disagree with the thesis's own formulas: (table, row's hemicube
/// resolution, method, why). docs/FORM-FACTORS.md explains each.
pub const INCONSISTENT: &[(&str, u32, &str, &str)] = &[
    ("2.2", 100, "recker", RECKER_COUNT),
    ("2.2", 200, "recker", RECKER_COUNT),
    ("2.2", 400, "recker", RECKER_COUNT),
    ("2.2", 600, "recker", RECKER_COUNT),
    ("2.2", 800, "recker", RECKER_COUNT),
    ("2.2", 1000, "recker", RECKER_COUNT),
    ("2.2", 200, "hemisphere-uniform", "59536 = 4 × 122², but Table 2.1 gives R = 112 (4 × 112² = 50176) and Table 2.3's 0.40 Mo at this row is 112's (122 would be 0.48): a typo"),
    ("2.3", 400, "sillion", SILLION_MEMORY),
    ("2.3", 600, "sillion", SILLION_MEMORY),
    ("2.3", 800, "sillion", SILLION_MEMORY),
    ("2.3", 1000, "sillion", SILLION_MEMORY),
    ("2.3", 800, "hemisphere-uniform", "Q_hsu = 32 R² + 4 R at R = 445 is 6.34 Mo; 6.83 is no resolution near 445's (it would need R = 462), and the column otherwise follows the formula: a typo"),
    ("2.3", 200, "disk", DISK_MEMORY),
    ("2.3", 400, "disk", DISK_MEMORY),
    ("2.3", 600, "disk", DISK_MEMORY),
    ("2.3", 800, "disk", DISK_MEMORY),
    ("2.3", 1000, "disk", DISK_MEMORY),
];

const RECKER_COUNT: &str = "the published count is R1² + R2′²(1 − (1.8/5)²) with R2′ = 5 R (1 + 2/R²) / 7.48 unrounded (the area of the outer square outside the inner one, in proxels; [`recker_thesis_count`] reproduces all six), not a count of whole proxels of an R1/R2 surface";
const SILLION_MEMORY: &str = "the published column is 4 R² at the hemicube's R (1.44 = 4 × 600², 2.56, 4.00), not at Sillion's own (590, 786, 983); 0.72 at 400 is neither (4 × 400² = 0.64, 4 × 393² = 0.62)";
const DISK_MEMORY: &str = "the published column is not the text's Q_d = 17/2 R² π/4 (6.68 Mo at R = 1000); it lies 0.00–0.10 Mo above the non-uniform hemisphere's, as the text says it should ('quasiment identique'), which Q_d (0.37 Mo above) does not";

/// Table 2.2's Recker cell by the thesis's own arithmetic for the hemicube at `r`: R1 = 1.8 R,
/// R2′ = 5 R (1 + 2/R²) / 7.48 (the hemicube's central FFE by §2.3.1's formula at the proxel's
/// centre `(1/R, 1/R)`, the outer one at the inner square's corner), and the outer grid counted
/// by area outside the inner square.
pub fn recker_thesis_count(r: u32) -> f64 {
    let r = r as f64;
    let r1 = 1.8 * r;
    let r2 = 5.0 * r * (1.0 + 2.0 / (r * r)) / 7.48;
    r1 * r1 + r2 * r2 * (1.0 - (1.8f64 / 5.0).powi(2))
}

/// One cell of a table.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// `2.1`, `2.2` or `2.3`.
    pub table: &'static str,
    /// The row: the reference form factor (2.1) or the hemicube resolution (2.2, 2.3).
    pub reference: String,
    /// The hemicube resolution of the row.
    pub row: u32,
    /// The method (CSV name).
    pub method: &'static str,
    /// The computed value, formatted as the published one.
    pub computed: String,
    /// The published value.
    pub published: String,
    /// Within one unit of the published last digit.
    pub agrees: bool,
}

/// The smallest resolution (a multiple of `step`) whose FFE `f(r)` is at most `reference`,
/// searched from the guess `g` by `f`'s 1/R² law, then step by step (Table 2.1's criterion).
pub fn smallest(reference: f64, g: u32, step: u32, f: impl Fn(u32) -> Result<f64>) -> Result<u32> {
    let ok = |r: u32| -> Result<bool> { Ok(f(r)? <= reference * (1.0 + 1e-12)) };
    let est = (g as f64 * (f(g)? / reference).sqrt()).ceil().max(1.0) as u32;
    let mut r = est.div_ceil(step).max(1) * step;
    while !ok(r)? {
        r += step;
        anyhow::ensure!(r <= MAX_RESOLUTION, "no resolution up to {MAX_RESOLUTION} reaches {reference:e}");
    }
    while r > step && ok(r - step)? {
        r -= step;
    }
    Ok(r)
}

/// Table 2.1's computed resolutions for the hemicube at `r`: the reference FFE and one string
/// per method.
pub fn equivalent_resolutions(r: u32) -> Result<(f64, [String; 6])> {
    let reference = Hemicube::new(r)?.largest_delta_ff();
    let eq = |s: &dyn ProjectionSurface| s.equivalence_delta_ff();
    let hc = smallest(reference, r, 2, |k| Ok(eq(&Hemicube::new(k)?)))?;
    let si = smallest(reference, r, 1, |k| Ok(eq(&SillionPlane::new(k)?)))?;
    let r1 = smallest(reference, r, 1, |k| Ok(ReckerPlane::new(k, 1)?.inner_largest()))?;
    let r2 = smallest(reference, r, 1, |k| Ok(ReckerPlane::new(MAX_RESOLUTION, k)?.outer_corner_delta()))?;
    let hu = smallest(reference, r, 1, |k| Ok(eq(&UniformHemisphere::new(k)?)))?;
    let hn = smallest(reference, r, 1, |k| Ok(eq(&Hemisphere::new(k)?)))?;
    let di = smallest(reference, r, 1, |k| Ok(eq(&Disk::new(k)?)))?;
    let s = |v: u32| v.to_string();
    Ok((reference, [s(hc), s(si), format!("{r1}/{r2}"), s(hu), s(hn), s(di)]))
}

/// The surfaces at the resolutions published in Table 2.1's row `i`.
fn published_surfaces(i: usize) -> Result<Vec<Box<dyn ProjectionSurface>>> {
    let res = TABLE_2_1[i].1;
    let n = |k: usize| res[k].parse::<u32>().map_err(anyhow::Error::from);
    let (a, b) = res[2].split_once('/').expect("R1/R2");
    Ok(vec![
        Box::new(Hemicube::new(n(0)?)?),
        Box::new(SillionPlane::new(n(1)?)?),
        Box::new(ReckerPlane::new(a.parse()?, b.parse()?)?),
        Box::new(UniformHemisphere::new(n(3)?)?),
        Box::new(Hemisphere::new(n(4)?)?),
        Box::new(Disk::new(n(5)?)?),
    ])
}

/// Decimals of a published number.
fn decimals(s: &str) -> usize {
    s.split_once('.').map_or(0, |(_, f)| f.len())
}

/// Whether `computed` is within one unit of `published`'s last digit (both as published).
fn close(computed: f64, published: &str) -> bool {
    let p: f64 = published.parse().unwrap_or(f64::NAN);
    let unit = 10f64.powi(-(decimals(published) as i32));
    (computed - p).abs() <= unit * (1.0 + 1e-9)
}

/// A form factor as the thesis writes it: three significant digits, `1.27e-4`.
pub fn sci3(x: f64) -> String {
    let e = x.log10().floor() as i32;
    let m = x / 10f64.powi(e);
    let (m, e) = if format!("{m:.2}") == "10.00" { (m / 10.0, e + 1) } else { (m, e) };
    format!("{m:.2}e{e}")
}

fn table_2_1() -> Result<Vec<Cell>> {
    let mut cells = Vec::new();
    for (i, &r) in ROWS.iter().enumerate() {
        let (reference, got) = equivalent_resolutions(r)?;
        let (key, published) = TABLE_2_1[i];
        cells.push(Cell {
            table: "2.1",
            reference: key.into(),
            row: r,
            method: "reference",
            computed: sci3(reference),
            published: key.into(),
            agrees: sci3(reference) == key,
        });
        for (k, m) in METHODS.iter().enumerate() {
            let agrees = resolutions_close(&got[k], published[k]);
            cells.push(Cell {
                table: "2.1",
                reference: key.into(),
                row: r,
                method: m,
                computed: got[k].clone(),
                published: published[k].into(),
                agrees,
            });
        }
    }
    Ok(cells)
}

/// Resolutions (or `R1/R2` pairs) within one of each other.
fn resolutions_close(a: &str, b: &str) -> bool {
    let parts = |s: &str| s.split('/').map(|x| x.parse::<f64>().unwrap_or(f64::NAN)).collect::<Vec<_>>();
    let (a, b) = (parts(a), parts(b));
    a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1.0)
}

fn tables_2_2_and_2_3() -> Result<Vec<Cell>> {
    let mut cells = Vec::new();
    for (i, &r) in ROWS.iter().enumerate() {
        let surfaces = published_surfaces(i)?;
        for (k, s) in surfaces.iter().enumerate() {
            let (p2, p3) = (TABLE_2_2[i][k], TABLE_2_3[i][k]);
            let proxels = s.proxels();
            let mo = s.memory_bytes() as f64 / 1e6;
            let computed3 = format!("{mo:.*}", decimals(p3));
            cells.push(Cell {
                table: "2.2",
                reference: r.to_string(),
                row: r,
                method: METHODS[k],
                computed: proxels.to_string(),
                published: p2.into(),
                agrees: close(proxels as f64, p2),
            });
            cells.push(Cell {
                table: "2.3",
                reference: r.to_string(),
                row: r,
                method: METHODS[k],
                computed: computed3.clone(),
                published: p3.into(),
                agrees: close(computed3.parse()?, p3),
            });
        }
    }
    cells.sort_by_key(|c| c.table);
    Ok(cells)
}

/// Every cell of Tables 2.1–2.3, in table, row, method order (Table 2.1 with a `reference` cell
/// per row: the hemicube's largest FFE against the published reference form factor).
pub fn compute() -> Result<Vec<Cell>> {
    let mut cells = table_2_1()?;
    cells.extend(tables_2_2_and_2_3()?);
    Ok(cells)
}

/// The CSV: `table,reference,method,computed,published` (the `reference` cells of Table 2.1
/// are left out: the row's `reference` column carries the published value, the test checks it).
pub fn csv(cells: &[Cell]) -> String {
    let mut out = String::from("table,reference,method,computed,published\n");
    for c in cells.iter().filter(|c| c.method != "reference") {
        let _ = writeln!(out, "{},{},{},{},{}", c.table, c.reference, c.method, c.computed, c.published);
    }
    out
}

/// The tables for a terminal: per table, one line per row, `computed (published)` per method
/// (`computed` alone where nothing is published), `*` on a cell that disagrees.
pub fn render(cells: &[Cell]) -> String {
    let mut out = String::new();
    let titles = [
        ("2.1", "equivalent resolutions (reference form factor = hemicube's largest FFE)"),
        ("2.2", "proxels used"),
        ("2.3", "memory (Mo = 10^6 bytes)"),
    ];
    let methods = methods_with(cells.iter().map(|c| c.method).filter(|&m| m != "reference"));
    for (t, title) in titles {
        let _ = writeln!(out, "Table {t}: {title}; computed (published), * = disagrees");
        let _ = writeln!(out, "{:>17} {}", "reference", methods.iter().map(|m| format!("{m:>20}")).collect::<String>());
        for &r in &ROWS {
            let row: Vec<&Cell> =
                cells.iter().filter(|c| c.table == t && c.row == r && c.method != "reference").collect();
            let key = row.first().map_or(String::new(), |c| c.reference.clone());
            // Table 2.1's key is the published reference; the computed one beside it.
            let key = match cells.iter().find(|c| c.table == t && c.row == r && c.method == "reference") {
                Some(c) => format!("{}{} ({key})", if c.agrees { "" } else { "*" }, c.computed),
                None => key,
            };
            let body: String = row
                .iter()
                .map(|c| match c.published.as_str() {
                    "" => format!("{:>20}", c.computed),
                    p => format!("{:>20}", format!("{}{} ({p})", if c.agrees { "" } else { "*" }, c.computed)),
                })
                .collect();
            let _ = writeln!(out, "{key:>17} {body}");
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_published_tables_are_reproduced_but_the_inconsistent_cells() {
        let cells = compute().unwrap();
        assert_eq!(cells.len(), 6 * 7 + 2 * 36);
        let mut off: Vec<(&str, u32, &str)> =
            cells.iter().filter(|c| !c.agrees).map(|c| (c.table, c.row, c.method)).collect();
        off.sort();
        let mut expected: Vec<(&str, u32, &str)> = INCONSISTENT.iter().map(|&(t, r, m, _)| (t, r, m)).collect();
        expected.sort();
        let shown: Vec<String> = cells
            .iter()
            .filter(|c| !c.agrees)
            .map(|c| format!("{} {} {}: {} vs {}", c.table, c.row, c.method, c.computed, c.published))
            .collect();
        assert_eq!(off, expected, "{shown:#?}");
    }

    #[test]
    fn the_thesis_arithmetic_gives_the_published_recker_counts() {
        for (i, &r) in ROWS.iter().enumerate() {
            let published: f64 = TABLE_2_2[i][2].parse().unwrap();
            assert!(
                (recker_thesis_count(r) - published).abs() <= 1.0,
                "{r}: {} vs {published}",
                recker_thesis_count(r)
            );
        }
    }

    #[test]
    fn formatting() {
        assert_eq!(sci3(1.2732e-4), "1.27e-4");
        assert_eq!(sci3(9.996e-6), "1.00e-5");
        assert!(close(0.26, "0.25") && !close(0.27, "0.25") && close(24.0, "25"));
        assert!(resolutions_close("180/68", "180/67") && !resolutions_close("180/69", "180/67"));
    }
}

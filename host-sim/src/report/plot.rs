//! # plot — the light-diffusion experiment as a PNG (thesis §4.4.3)
//!
//! [`plot_diffusion`] draws our diffusion times `T` (cycles until the last beam is consumed,
//! empty scene, one source at the centre) beside the thesis's published values
//! ([`THESIS_T`], [`THESIS_T_UNBOUNDED`]) in one 1600 × 700 PNG with two panels:
//!
//! * left, "T against N (log–log)": one solid line per (policy, FA) for a few FA values
//!   (the smallest FA present, FA = 16 when present, and the largest FA run for each N swept
//!   over FA); the thesis's T for FA = 1, for its largest tabled FA per N and for its "large
//!   enough" FIFOs as black/grey dashed lines; the ideal `T = N` and our lower bound `LB` (max
//!   over the rows of each N) as dashed references;
//! * right, "T against FA": one colour per N swept over FA (every N when none was), our
//!   policies as solid lines (one marker shape per policy), the thesis's `T(FA)` for the same
//!   N as crosses of the same colour.
//!
//! [`plot_timelapse`] draws the thesis's time-lapse of the 16³ run: the slices of the voxels
//! reached so far and the cells holding beams, one row per snapshot time.
//!
//! Each panel's legend sits in a strip under its chart (never over the data), laid out in as
//! many columns as fit. The titles read "T against N (log–log)" and "T against FA" (an en
//! space after the T: plotters' ab_glyph text renderer sets "T" + space too tight).
//!
//! Text is drawn with an embedded DejaVu Sans (`host-sim/assets/DejaVuSans.ttf`, Bitstream
//! Vera licence in `assets/DejaVuSans-LICENSE.txt`) registered through plotters' `ab_glyph`
//! backend, so no system font or fontconfig is needed.
#![forbid(unsafe_code)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Context, Result};
use plotters::chart::MeshStyle;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One run of the diffusion experiment: grid size `n` (scene `n³`), FIFO size `fa`, the
/// scheduling `policy`, the measured `cycles` (T) and the run's lower bound `lower_bound`
/// (LB = max(distance to the farthest voxel, most beam steps any single cell must process);
/// 0 = unknown, not drawn).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DiffusionRow {
    pub n: u32,
    pub fa: u32,
    pub policy: String,
    pub cycles: u64,
    pub lower_bound: u64,
}

/// The thesis's published diffusion times, `(N, FA, T)`, FIFOs of length FA
/// (Vidal 1992, RC² thesis, §4.4.3 "Résultats de simulation de RC²": the tables
/// "Réseau de taille 64", "Réseau de taille 128", "Réseau de taille 32", and "Temps de
/// diffusion en fonction de la taille du réseau (N) en utilisant des files d'attente de
/// longueur 1" for FA = 1, N = 2…79). Sorted by (N, FA), one entry per
/// (N, FA) (the FA = 1 table repeats its N = 79 line; kept once). The thesis's N = 16
/// activity snapshots (FA = 1 and 16) are figure frames, not tabled T, and are not here.
#[rustfmt::skip]
pub const THESIS_T: &[(u32 /*N*/, u32 /*FA*/, u64 /*T*/)] = &[
    (2, 1, 8), (3, 1, 10), (4, 1, 21), (5, 1, 33), (6, 1, 49), (7, 1, 61), (8, 1, 61),
    (9, 1, 99), (10, 1, 121), (11, 1, 137), (12, 1, 163), (13, 1, 196), (14, 1, 282),
    (15, 1, 280), (16, 1, 345), (17, 1, 401), (18, 1, 381), (19, 1, 440), (20, 1, 500),
    (21, 1, 543), (22, 1, 635), (23, 1, 645), (24, 1, 744), (25, 1, 814), (26, 1, 887),
    (27, 1, 933), (28, 1, 993), (29, 1, 1029), (30, 1, 1155), (31, 1, 1223), (32, 1, 1315),
    (32, 2, 1005), (32, 3, 695), (32, 4, 576), (32, 5, 468), (32, 6, 442), (32, 7, 422),
    (32, 8, 317), (32, 9, 263), (32, 10, 291), (32, 11, 255), (32, 12, 241), (32, 13, 221),
    (32, 14, 211), (32, 15, 210), (32, 16, 201), (32, 17, 198), (32, 18, 195), (32, 19, 193),
    (32, 20, 196), (32, 21, 196), (32, 22, 195), (32, 23, 195), (32, 24, 195), (32, 25, 196),
    (32, 26, 196), (32, 27, 195), (32, 28, 195), (32, 29, 195), (32, 30, 195), (32, 31, 195),
    (32, 32, 195), (33, 1, 1376), (34, 1, 1536), (35, 1, 1529), (36, 1, 1602), (37, 1, 1735),
    (38, 1, 1793), (39, 1, 1942), (40, 1, 2121), (41, 1, 2108), (42, 1, 2264), (43, 1, 2352),
    (44, 1, 2482), (45, 1, 2627), (46, 1, 2767), (47, 1, 2823), (48, 1, 2943), (49, 1, 3138),
    (50, 1, 3330), (51, 1, 3397), (52, 1, 3604), (53, 1, 3538), (54, 1, 3846), (55, 1, 4049),
    (56, 1, 4096), (57, 1, 4133), (58, 1, 4432), (59, 1, 4541), (60, 1, 4550), (61, 1, 4829),
    (62, 1, 5071), (63, 1, 5202), (64, 1, 5537), (64, 2, 3947), (64, 3, 3178), (64, 4, 3413),
    (64, 5, 2730), (64, 6, 2539), (64, 7, 2510), (64, 8, 2134), (64, 9, 2410), (64, 10, 1887),
    (64, 11, 1951), (64, 12, 1728), (64, 13, 1705), (64, 14, 1690), (64, 15, 1592),
    (64, 16, 1477), (64, 17, 1383), (64, 18, 1359), (64, 19, 1326), (64, 20, 1276),
    (64, 21, 1214), (64, 22, 1133), (64, 23, 1137), (64, 24, 1048), (64, 25, 895),
    (64, 26, 849), (64, 27, 898), (64, 28, 842), (64, 29, 860), (64, 30, 837), (64, 31, 810),
    (64, 32, 805), (64, 33, 789), (64, 34, 792), (64, 35, 771), (64, 36, 797), (64, 37, 750),
    (64, 38, 765), (64, 39, 762), (64, 40, 748), (64, 41, 744), (64, 42, 735), (64, 43, 754),
    (64, 44, 740), (64, 45, 728), (64, 46, 734), (64, 47, 731), (64, 48, 725), (64, 49, 724),
    (64, 50, 720), (64, 51, 708), (64, 52, 709), (64, 53, 704), (64, 54, 695), (64, 55, 695),
    (64, 56, 699), (64, 57, 702), (64, 58, 701), (64, 59, 697), (64, 60, 697), (64, 61, 693),
    (64, 62, 691), (65, 1, 5246), (66, 1, 5761), (67, 1, 5805), (68, 1, 5740), (69, 1, 6161),
    (70, 1, 6548), (71, 1, 6495), (72, 1, 6511), (73, 1, 6975), (74, 1, 7260), (75, 1, 7391),
    (76, 1, 7723), (77, 1, 7637), (78, 1, 7908), (79, 1, 8109), (128, 1, 20556),
    (128, 2, 15421), (128, 3, 12737), (128, 4, 11243), (128, 5, 10950), (128, 6, 10372),
    (128, 7, 9913), (128, 8, 9918), (128, 9, 9239), (128, 10, 7496), (128, 11, 8797),
    (128, 12, 7903), (128, 13, 7997), (128, 14, 7730), (128, 15, 6847), (128, 16, 6398),
    (128, 17, 6920), (128, 18, 6342), (128, 19, 6361), (128, 20, 5802), (128, 21, 5493),
    (128, 22, 5167), (128, 23, 5131), (128, 24, 4768), (128, 25, 5005), (128, 26, 4669),
    (128, 27, 4711), (128, 28, 4113), (128, 29, 4225), (128, 30, 3881), (128, 31, 3701),
    (128, 32, 4371), (128, 33, 4152), (128, 34, 3719),
];

/// The thesis's second N-sweep, `(N, FA, T)` with FIFOs "large enough to hold every beam
/// received" (§4.4.3, table "Temps de diffusion T en fonction de la taille du réseau N en
/// utilisant des files d'attentes de longueur maximale", N = 1…64; its N = 32 line is printed
/// twice, kept once). Here FA is the FIFO length the thesis lists for that run (read as the
/// largest occupancy needed; FA = 0 for N ≤ 3). Kept apart from [`THESIS_T`] because it is a
/// different experiment: at (32, 19) it gives T = 145 where the FA-capped sweep gives 193,
/// and at (64, 53) T = 509 against 704. This is the thesis's "T ~ N·log N" curve.
#[rustfmt::skip]
pub const THESIS_T_UNBOUNDED: &[(u32 /*N*/, u32 /*FA*/, u64 /*T*/)] = &[
    (1, 0, 1), (2, 0, 2), (3, 0, 3), (4, 3, 7), (5, 4, 11), (6, 4, 12), (7, 3, 16), (8, 3, 18),
    (9, 6, 25), (10, 6, 26), (11, 6, 31), (12, 6, 35), (13, 11, 44), (14, 11, 45),
    (15, 11, 55), (16, 11, 59), (17, 7, 53), (18, 10, 61), (19, 18, 81), (20, 17, 90),
    (21, 16, 87), (22, 16, 88), (23, 15, 101), (24, 15, 102), (25, 23, 125), (26, 23, 126),
    (27, 23, 133), (28, 23, 147), (29, 23, 144), (30, 23, 153), (31, 19, 145), (32, 19, 145),
    (33, 28, 189), (34, 28, 193), (35, 29, 207), (36, 29, 215), (37, 28, 197), (38, 28, 210),
    (39, 28, 223), (40, 28, 226), (41, 36, 275), (42, 36, 281), (43, 34, 266), (44, 35, 280),
    (45, 35, 292), (46, 35, 304), (47, 35, 306), (48, 35, 317), (49, 32, 309), (50, 32, 313),
    (51, 44, 366), (52, 44, 375), (53, 43, 392), (54, 43, 397), (55, 42, 399), (56, 42, 399),
    (57, 41, 394), (58, 41, 406), (59, 41, 411), (60, 41, 427), (61, 53, 487), (62, 53, 499),
    (63, 53, 505), (64, 53, 509),
];

/// One frame of the thesis's 16³ time-lapse (§4.4.3): at cycle `t`, the voxels a beam was
/// processed in so far (`reached`, index `(y·n + x)·n + z`) and the cells holding a beam
/// (`active`, row-major).
#[derive(Clone, Debug)]
pub struct Snapshot {
    pub t: u64,
    pub reached: Vec<bool>,
    pub active: Vec<bool>,
}

/// Pixels per voxel of a time-lapse slice, and the gap between slices.
const SLICE_PX: u32 = 5;
const SLICE_GAP: u32 = 6;

/// The thesis's time-lapse figure (§4.4.3, N = 16, FA = 1 and 16): one row per snapshot, the
/// n slices z = 0 … n − 1 of the voxels reached so far (black: reached), then the cells
/// holding a beam at that time (black: active), as the thesis draws them.
pub fn plot_timelapse(n: u32, frames: &[Snapshot], title: &str, path: &Path) -> Result<()> {
    ensure_font()?;
    if frames.iter().any(|f| f.reached.len() != (n * n * n) as usize || f.active.len() != (n * n) as usize) {
        bail!("time-lapse frames must hold n³ voxels and n² cells (n = {n})");
    }
    let (side, label_w, top) = (n * SLICE_PX, 90u32, 40u32);
    let w = label_w + (n + 1) * (side + SLICE_GAP) + 2 * SLICE_GAP;
    let h = top + frames.len() as u32 * (side + SLICE_GAP) + 24;
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let text = |s: &str, x: u32, y: u32, size: u32| {
        root.draw(&Text::new(s.to_string(), (x as i32, y as i32), (FONT, size).into_font())).map_err(plot_err)
    };
    text(title, 10, 8, 18)?;
    let slice_x = |i: u32| label_w + i * (side + SLICE_GAP) + if i == n { 2 * SLICE_GAP } else { 0 };
    for i in (0..n).step_by(4) {
        text(&format!("z = {i}"), slice_x(i), top - 14, 11)?;
    }
    text("active cells", slice_x(n), top - 14, 11)?;
    for (row, f) in frames.iter().enumerate() {
        let y0 = top + row as u32 * (side + SLICE_GAP);
        text(&format!("t = {}", f.t), 10, y0 + side / 2 - 7, 14)?;
        for z in 0..=n {
            let on = |x: u32, y: u32| {
                if z == n {
                    f.active[(y * n + x) as usize]
                } else {
                    f.reached[((y * n + x) * n + z) as usize]
                }
            };
            let x0 = slice_x(z);
            let frame = [(x0 as i32 - 1, y0 as i32 - 1), ((x0 + side) as i32, (y0 + side) as i32)];
            root.draw(&Rectangle::new(frame, BLACK.mix(0.4))).map_err(plot_err)?;
            for y in 0..n {
                for x in 0..n {
                    if on(x, y) {
                        let (px, py) = ((x0 + x * SLICE_PX) as i32, (y0 + (n - 1 - y) * SLICE_PX) as i32);
                        let r = [(px, py), (px + SLICE_PX as i32 - 1, py + SLICE_PX as i32 - 1)];
                        root.draw(&Rectangle::new(r, BLACK.filled())).map_err(plot_err)?;
                    }
                }
            }
        }
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

/// Width and height of the PNG [`plot_diffusion`] writes, in pixels.
pub const PLOT_SIZE: (u32, u32) = (1600, 700);

/// DejaVu Sans (Bitstream Vera licence, see `assets/DejaVuSans-LICENSE.txt`).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
/// The family name plotters' default styles ask for; the embedded font is registered under it.
pub(crate) const FONT: &str = "sans-serif";

/// Colours of our series (matplotlib's "tab10", its grey swapped for navy: greys and black
/// are the thesis's).
pub(crate) const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(0, 0, 128),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
const THESIS_DARK: RGBColor = RGBColor(0, 0, 0);
const THESIS_MID: RGBColor = RGBColor(100, 100, 100);
const THESIS_LIGHT: RGBColor = RGBColor(160, 160, 160);
const LB_COLOUR: RGBColor = RGBColor(178, 34, 34);

/// Registers the embedded font with plotters, once per process.
pub(crate) fn ensure_font() -> Result<()> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES)
            .map_err(|_| "the embedded DejaVu Sans could not be parsed".to_string())
    })
    .clone()
    .map_err(|e| anyhow!(e))
}

pub(crate) fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e}")
}

/// Our rows, merged: duplicate (policy, FA, N) runs are averaged.
struct Data {
    /// Policy names in order of first appearance.
    policies: Vec<String>,
    /// (policy index, FA, N) → mean cycles.
    t: BTreeMap<(usize, u32, u32), f64>,
    /// N → largest lower bound over that N's rows (rows with LB = 0 left out).
    lb: BTreeMap<u32, u64>,
    ns: BTreeSet<u32>,
}

impl Data {
    fn new(rows: &[DiffusionRow]) -> Result<Self> {
        let mut policies: Vec<String> = Vec::new();
        let mut sums: BTreeMap<(usize, u32, u32), (f64, u32)> = BTreeMap::new();
        let mut lb = BTreeMap::new();
        let mut ns = BTreeSet::new();
        for (i, r) in rows.iter().enumerate() {
            if r.n == 0 {
                bail!("row {i} ({r:?}): N = 0 cannot be drawn on a log axis");
            }
            if r.cycles == 0 {
                bail!("row {i} ({r:?}): T = 0 cycles cannot be drawn on a log axis");
            }
            let p = match policies.iter().position(|q| *q == r.policy) {
                Some(p) => p,
                None => {
                    policies.push(r.policy.clone());
                    policies.len() - 1
                }
            };
            let e = sums.entry((p, r.fa, r.n)).or_insert((0.0, 0));
            e.0 += r.cycles as f64;
            e.1 += 1;
            if r.lower_bound > 0 {
                let m = lb.entry(r.n).or_insert(0u64);
                *m = (*m).max(r.lower_bound);
            }
            ns.insert(r.n);
        }
        let t = sums.into_iter().map(|(k, (s, c))| (k, s / f64::from(c))).collect();
        Ok(Self { policies, t, lb, ns })
    }

    /// The Ns run with several FAs (FA sweeps); all Ns when none was.
    fn swept(&self) -> BTreeSet<u32> {
        let mut fas: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
        for &(_, fa, n) in self.t.keys() {
            fas.entry(n).or_default().insert(fa);
        }
        let swept: BTreeSet<u32> = fas.iter().filter(|(_, f)| f.len() > 1).map(|(&n, _)| n).collect();
        if swept.is_empty() {
            self.ns.clone()
        } else {
            swept
        }
    }

    /// (FA, T) of one policy at one N, by FA.
    fn sweep(&self, p: usize, n: u32) -> Vec<(f64, f64)> {
        self.t.iter().filter(|((q, _, m), _)| *q == p && *m == n).map(|(&(_, fa, _), &t)| (f64::from(fa), t)).collect()
    }
}

/// Marker shapes. Policies get `POLICY_MARKS[p % 4]`; the cross is the thesis's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mark {
    Dot,
    Triangle,
    Ring,
    Target,
    Cross,
}

const POLICY_MARKS: [Mark; 4] = [Mark::Dot, Mark::Triangle, Mark::Ring, Mark::Target];

fn policy_mark(p: usize) -> Mark {
    POLICY_MARKS[p % POLICY_MARKS.len()]
}

/// How a legend entry or a series looks.
#[derive(Debug, Clone, Copy)]
struct Look {
    colour: RGBColor,
    width: u32,
    /// `None`: no line; `Some(false)`: solid; `Some(true)`: dashed.
    dashed: Option<bool>,
    mark: Option<Mark>,
}

/// One of our lines.
struct Line {
    label: String,
    look: Look,
    points: Vec<(f64, f64)>,
}

/// The left panel's lines: for each policy, T(N) at the smallest FA, at FA = 16 when
/// present, and at the largest FA run for each N.
fn lines_against_n(d: &Data) -> Vec<Line> {
    let fas: BTreeSet<u32> = d.t.keys().map(|&(_, fa, _)| fa).collect();
    let mut fixed: Vec<u32> = fas.iter().next().copied().into_iter().collect();
    if fas.contains(&16) && !fixed.contains(&16) {
        fixed.push(16);
    }
    // The largest FA of each (policy, N), for the Ns swept over FA.
    let swept = d.swept();
    let mut largest: BTreeMap<(usize, u32), (u32, f64)> = BTreeMap::new();
    for (&(p, fa, n), &t) in d.t.iter().filter(|((_, _, n), _)| swept.contains(n)) {
        let e = largest.entry((p, n)).or_insert((fa, t));
        if fa >= e.0 {
            *e = (fa, t);
        }
    }
    let largest_fas: BTreeSet<u32> = largest.values().map(|&(fa, _)| fa).collect();
    let largest_label = match largest_fas.iter().collect::<Vec<_>>().as_slice() {
        [k] if fixed.contains(k) => None,
        [k] => Some(format!("FA = {k}")),
        _ => Some("largest FA run per N".to_string()),
    };

    let look = |si: usize, p: usize| Look {
        colour: PALETTE[si % PALETTE.len()],
        width: 2,
        dashed: Some(false),
        mark: Some(policy_mark(p)),
    };
    let mut out = Vec::new();
    for (si, &fa) in fixed.iter().enumerate() {
        for (p, name) in d.policies.iter().enumerate() {
            let points: Vec<(f64, f64)> =
                d.t.iter()
                    .filter(|((q, f, _), _)| *q == p && *f == fa)
                    .map(|(&(_, _, n), &t)| (f64::from(n), t))
                    .collect();
            if !points.is_empty() {
                out.push(Line { label: format!("{name}, FA = {fa}"), look: look(si, p), points });
            }
        }
    }
    if let Some(what) = largest_label {
        for (p, name) in d.policies.iter().enumerate() {
            let points: Vec<(f64, f64)> =
                largest.iter().filter(|((q, _), _)| *q == p).map(|(&(_, n), &(_, t))| (f64::from(n), t)).collect();
            if !points.is_empty() {
                out.push(Line { label: format!("{name}, {what}"), look: look(fixed.len(), p), points });
            }
        }
    }
    out
}

/// Draws `mark` at each of `points` (data coordinates).
fn draw_marks<DB: DrawingBackend, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    points: &[(f64, f64)],
    mark: Mark,
    colour: RGBColor,
) -> Result<()>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let pts = points.iter().copied();
    match mark {
        Mark::Dot => {
            chart.draw_series(pts.map(|p| Circle::new(p, 4, colour.filled()))).map_err(plot_err)?;
        }
        Mark::Triangle => {
            chart.draw_series(pts.map(|p| TriangleMarker::new(p, 6, colour.filled()))).map_err(plot_err)?;
        }
        Mark::Ring => {
            chart.draw_series(pts.map(|p| Circle::new(p, 5, colour.stroke_width(2)))).map_err(plot_err)?;
        }
        Mark::Target => {
            chart.draw_series(pts.clone().map(|p| Circle::new(p, 6, colour.stroke_width(1)))).map_err(plot_err)?;
            chart.draw_series(pts.map(|p| Circle::new(p, 2, colour.filled()))).map_err(plot_err)?;
        }
        Mark::Cross => {
            chart.draw_series(pts.map(|p| Cross::new(p, 4, colour.stroke_width(2)))).map_err(plot_err)?;
        }
    }
    Ok(())
}

/// Draws `mark` centred at the pixel `c` of `area`.
fn draw_mark_px<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    c: (i32, i32),
    mark: Mark,
    colour: RGBColor,
) -> Result<()> {
    let r = match mark {
        Mark::Dot => area.draw(&Circle::new(c, 4, colour.filled())),
        Mark::Triangle => area.draw(&TriangleMarker::new(c, 6, colour.filled())),
        Mark::Ring => area.draw(&Circle::new(c, 5, colour.stroke_width(2))),
        Mark::Target => area
            .draw(&Circle::new(c, 6, colour.stroke_width(1)))
            .and_then(|_| area.draw(&Circle::new(c, 2, colour.filled()))),
        Mark::Cross => area.draw(&Cross::new(c, 4, colour.stroke_width(2))),
    };
    r.map_err(plot_err)
}

/// Draws a series: its line (solid or dashed) and its marks.
fn draw_line<DB: DrawingBackend, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    points: &[(f64, f64)],
    look: Look,
) -> Result<()>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let style = look.colour.stroke_width(look.width);
    match look.dashed {
        Some(false) => {
            chart.draw_series(LineSeries::new(points.iter().copied(), style)).map_err(plot_err)?;
        }
        Some(true) => {
            let (dash, gap) = if look.width <= 1 { (8, 5) } else { (7, 4) };
            chart.draw_series(DashedLineSeries::new(points.iter().copied(), dash, gap, style)).map_err(plot_err)?;
        }
        None => {}
    }
    if let Some(m) = look.mark {
        draw_marks(chart, points, m, look.colour)?;
    }
    Ok(())
}

const LEGEND_FONT: u32 = 14;
/// Legend sample width, gap to the text, padding, row height and column gap, in pixels.
const LEGEND_SAMPLE: i32 = 30;
const LEGEND_GAP: i32 = 8;
const LEGEND_PAD: i32 = 6;
const LEGEND_ROW: i32 = LEGEND_FONT as i32 + 7;
const LEGEND_COL_GAP: i32 = 26;
/// Left margin of each panel's plotting area (chart margin + y label area).
const PANEL_MARGIN: u32 = 16;
const Y_LABEL_AREA: u32 = 78;

/// Lays a legend out in columns under a chart `width` pixels wide: returns (columns, rows,
/// column width).
fn legend_layout<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Look)],
    width: i32,
) -> Result<(usize, usize, i32)> {
    let font = (FONT, LEGEND_FONT).into_font().color(&BLACK);
    let mut text_w = 0i32;
    for (label, _) in entries {
        let (w, _) = area.estimate_text_size(label, &font).map_err(plot_err)?;
        text_w = text_w.max(w as i32);
    }
    let col_w = LEGEND_SAMPLE + LEGEND_GAP + text_w + LEGEND_COL_GAP;
    let cols = ((width + LEGEND_COL_GAP) / col_w).max(1) as usize;
    let cols = cols.min(entries.len().max(1));
    let rows = entries.len().div_ceil(cols);
    Ok((cols, rows, col_w))
}

/// The height a legend needs under a chart `width` pixels wide.
fn legend_height<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Look)],
    width: i32,
) -> Result<u32> {
    if entries.is_empty() {
        return Ok(0);
    }
    let (_, rows, _) = legend_layout(area, entries, width)?;
    Ok((2 * LEGEND_PAD + rows as i32 * LEGEND_ROW) as u32)
}

/// Draws a legend in columns (filled column by column) into `area`, starting `x0` pixels
/// from its left and spanning `width` pixels. (Drawn by hand, outside the plotting area so
/// it never hides data, rather than with plotters' series labels, whose line-plus-marker
/// samples would need a `'static` backend.)
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Look)],
    x0: i32,
    width: i32,
) -> Result<()> {
    if entries.is_empty() {
        return Ok(());
    }
    let (cols, rows, col_w) = legend_layout(area, entries, width)?;
    let used_w = (cols as i32 * col_w - LEGEND_COL_GAP).min(width);
    let box_h = 2 * LEGEND_PAD + rows as i32 * LEGEND_ROW;
    area.draw(&Rectangle::new([(x0 - LEGEND_PAD, 0), (x0 + used_w + LEGEND_PAD, box_h - 1)], BLACK.mix(0.35)))
        .map_err(plot_err)?;
    let font = (FONT, LEGEND_FONT).into_font().color(&BLACK);
    for (i, (label, look)) in entries.iter().enumerate() {
        let (col, row) = ((i / rows) as i32, (i % rows) as i32);
        let cy = LEGEND_PAD + row * LEGEND_ROW + LEGEND_ROW / 2;
        let sx0 = x0 + col * col_w;
        let sx1 = sx0 + LEGEND_SAMPLE;
        let style = look.colour.stroke_width(look.width);
        match look.dashed {
            Some(false) => area.draw(&PathElement::new(vec![(sx0, cy), (sx1, cy)], style)),
            Some(true) => area.draw(&DashedPathElement::new(vec![(sx0, cy), (sx1, cy)], 6, 3, style)),
            None => Ok(()),
        }
        .map_err(plot_err)?;
        if let Some(m) = look.mark {
            draw_mark_px(area, ((sx0 + sx1) / 2, cy), m, look.colour)?;
        }
        area.draw(&Text::new(label.clone(), (sx1 + LEGEND_GAP, cy), font.pos(Pos::new(HPos::Left, VPos::Center))))
            .map_err(plot_err)?;
    }
    Ok(())
}

/// Splits a panel into its chart and, below it, its legend's strip; draws the legend.
/// `legend_h`: the strip's height (both panels use the larger of their needs), or `None`
/// to only measure this legend's need.
fn split_for_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Look)],
    legend_h: Option<u32>,
) -> Result<Panel<DB>> {
    let (w, h) = area.dim_in_pixel();
    let x0 = (PANEL_MARGIN + Y_LABEL_AREA) as i32;
    let width = w as i32 - x0 - PANEL_MARGIN as i32;
    let need = legend_height(area, entries, width)?.min(h / 2);
    let Some(lh) = legend_h else {
        return Ok(Panel::Measured(need));
    };
    let lh = lh.max(need).min(h / 2);
    let (chart_area, legend_area) = area.split_vertically(h - lh - PANEL_MARGIN);
    draw_legend(&legend_area, entries, x0, width)?;
    Ok(Panel::Chart(chart_area))
}

/// What [`split_for_legend`] gives back.
enum Panel<DB: DrawingBackend> {
    /// Measuring only: the legend strip's needed height.
    Measured(u32),
    /// The area left for the chart, the legend drawn below it.
    Chart(DrawingArea<DB, Shift>),
}

/// A log axis range around `[min, max]` (both > 0): `[min / pad, max · pad]`, widened
/// about its centre to span at least a factor 3 (so a 1–2–5 tick always falls inside).
pub(crate) fn log_range(min: f64, max: f64, pad: f64) -> std::ops::Range<f64> {
    let (lo, hi) = (min / pad, max * pad);
    let ratio = hi / lo;
    if ratio >= 3.0 {
        lo..hi
    } else {
        let grow = (3.0 / ratio).sqrt();
        lo / grow..hi * grow
    }
}

/// Ticks of a base-10 log axis over `r`: (labelled 1–2–5 × 10^k, light k × 10^j others).
pub(crate) fn decade_ticks(r: &std::ops::Range<f64>) -> (Vec<f64>, Vec<f64>) {
    let (mut bold, mut light) = (Vec::new(), Vec::new());
    let mut e = r.start.log10().floor() as i32;
    while 10f64.powi(e) <= r.end {
        for m in 1..10 {
            let v = f64::from(m) * 10f64.powi(e);
            if r.contains(&v) {
                if matches!(m, 1 | 2 | 5) {
                    bold.push(v);
                } else {
                    light.push(v);
                }
            }
        }
        e += 1;
    }
    (bold, light)
}

/// Ticks of the N axis over `r`: powers of two, or `ns` when fewer than two powers fall in.
fn n_ticks(r: &std::ops::Range<f64>, ns: &BTreeSet<u32>) -> Vec<f64> {
    let mut t: Vec<f64> = (0..32).map(|k| f64::from(1u32 << k)).filter(|v| r.contains(v)).collect();
    if t.len() < 2 {
        t.extend(ns.iter().map(|&n| f64::from(n)).filter(|v| r.contains(v)));
        t.sort_by(f64::total_cmp);
        t.dedup();
    }
    t
}

/// The mesh of a diffusion panel (T on y): integer labels, faint grid lines, the panel's x
/// description; `tune` adds the panel's own settings.
fn draw_t_mesh<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    x_desc: &str,
    tune: impl FnOnce(&mut MeshStyle<'a, '_, X, Y, DB>),
) -> Result<()>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&label_int)
        .y_label_formatter(&label_int)
        .bold_line_style(BLACK.mix(0.15))
        .light_line_style(BLACK.mix(0.05))
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .x_desc(x_desc)
        .y_desc("T\u{2002}(cycles)");
    tune(&mut mesh);
    mesh.draw().map_err(plot_err)
}

pub(crate) fn label_int(v: &f64) -> String {
    if (v - v.round()).abs() < 1e-6 {
        format!("{}", v.round() as i64)
    } else {
        format!("{v:.1}")
    }
}

/// Draws the light-diffusion experiment — T against N (log–log) and T against FA — beside
/// the thesis's published values ([`THESIS_T`], [`THESIS_T_UNBOUNDED`], thesis §4.4.3) as
/// a [`PLOT_SIZE`] PNG at `path` (parent folders are created; give it a `.png` name). With
/// no rows it draws the thesis's values alone. Errors on a row with N = 0 or T = 0 (not
/// drawable on log axes) and on a path it cannot write.
pub fn plot_diffusion(rows: &[DiffusionRow], path: &Path) -> Result<()> {
    let data = Data::new(rows)?;
    ensure_font()?;
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
    }
    let root = BitMapBackend::new(path, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (left, right) = root.split_horizontally(PLOT_SIZE.0 / 2);
    let legend_h = draw_against_n(&left, &data, None)?.max(draw_against_fa(&right, &data, None)?);
    draw_against_n(&left, &data, Some(legend_h))?;
    draw_against_fa(&right, &data, Some(legend_h))?;
    root.present().map_err(plot_err).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Left panel: T against N, log–log.
/// With `legend_h = None` only measures: returns the legend strip's needed height.
fn draw_against_n<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, d: &Data, legend_h: Option<u32>) -> Result<u32> {
    let ours = lines_against_n(d);
    let (n_min, n_max) = match (d.ns.first(), d.ns.last()) {
        (Some(&a), Some(&b)) => (f64::from(a), f64::from(b)),
        _ => (16.0, 128.0),
    };
    let xr = log_range(n_min, n_max, 1.15);
    let in_x = |n: u32| xr.contains(&f64::from(n));

    let thesis_fa1: Vec<(f64, f64)> =
        THESIS_T.iter().filter(|&&(n, fa, _)| fa == 1 && in_x(n)).map(|&(n, _, t)| (f64::from(n), t as f64)).collect();
    // Crosses on the FA = 1 line only at our Ns (or at powers of two), not at all 78 Ns.
    let thesis_fa1_marks: Vec<(f64, f64)> = thesis_fa1
        .iter()
        .copied()
        .filter(|&(n, _)| {
            let n = n as u32;
            if d.ns.is_empty() {
                n.is_power_of_two()
            } else {
                d.ns.contains(&n)
            }
        })
        .collect();
    // The thesis's largest tabled FA for each N it swept FA on.
    let mut sweep_max: BTreeMap<u32, (u32, u64)> = BTreeMap::new();
    let mut counts: BTreeMap<u32, usize> = BTreeMap::new();
    for &(n, fa, t) in THESIS_T {
        *counts.entry(n).or_default() += 1;
        let e = sweep_max.entry(n).or_insert((fa, t));
        if fa >= e.0 {
            *e = (fa, t);
        }
    }
    let thesis_max: Vec<(u32, u32, f64)> =
        sweep_max.iter().filter(|(n, _)| counts[n] > 1 && in_x(**n)).map(|(&n, &(fa, t))| (n, fa, t as f64)).collect();
    let thesis_max_pts: Vec<(f64, f64)> = thesis_max.iter().map(|&(n, _, t)| (f64::from(n), t)).collect();
    let thesis_unb: Vec<(f64, f64)> = THESIS_T_UNBOUNDED
        .iter()
        .filter(|&&(n, _, t)| n > 0 && t > 0 && in_x(n))
        .map(|&(n, _, t)| (f64::from(n), t as f64))
        .collect();
    let ideal = vec![(xr.start, xr.start), (xr.end, xr.end)];
    let lb: Vec<(f64, f64)> = d.lb.iter().map(|(&n, &b)| (f64::from(n), b as f64)).collect();

    let fa1_look = Look { colour: THESIS_DARK, width: 2, dashed: Some(true), mark: Some(Mark::Cross) };
    let max_look = Look { colour: THESIS_MID, width: 2, dashed: Some(true), mark: Some(Mark::Cross) };
    let unb_look = Look { colour: THESIS_LIGHT, width: 2, dashed: Some(true), mark: None };
    let lb_look = Look { colour: LB_COLOUR, width: 2, dashed: Some(true), mark: Some(Mark::Ring) };
    let ideal_look = Look { colour: BLACK, width: 1, dashed: Some(true), mark: None };

    let mut entries: Vec<(String, Look)> = ours.iter().map(|l| (format!("ours: {}", l.label), l.look)).collect();
    if !thesis_fa1.is_empty() {
        entries.push(("thesis §4.4.3, FA = 1".into(), fa1_look));
    }
    if !thesis_max.is_empty() {
        let fas: Vec<String> = thesis_max.iter().map(|&(_, fa, _)| fa.to_string()).collect();
        entries.push((format!("thesis, largest FA tabled (FA = {})", fas.join(", ")), max_look));
    }
    if !thesis_unb.is_empty() {
        entries.push(("thesis, FIFOs large enough (~ N log N)".into(), unb_look));
    }
    if !lb.is_empty() {
        entries.push(("our lower bound LB (max per N)".into(), lb_look));
    }
    entries.push(("ideal T = N".into(), ideal_look));
    let chart_area = match split_for_legend(area, &entries, legend_h)? {
        Panel::Measured(h) => return Ok(h),
        Panel::Chart(a) => a,
    };

    let (y_min, y_max) = ours
        .iter()
        .flat_map(|l| l.points.iter().map(|p| p.1))
        .chain(thesis_fa1.iter().map(|p| p.1))
        .chain(thesis_max.iter().map(|p| p.2))
        .chain(thesis_unb.iter().map(|p| p.1))
        .chain(ideal.iter().map(|p| p.1))
        .chain(lb.iter().map(|p| p.1))
        .fold((f64::INFINITY, 0f64), |(a, b), y| (a.min(y), b.max(y)));
    let yr = log_range(y_min, y_max, 1.25);
    let (y_bold, y_light) = decade_ticks(&yr);
    let x_ticks = n_ticks(&xr, &d.ns);

    let mut chart = ChartBuilder::on(&chart_area)
        .caption("T\u{2002}against N (log–log)", (FONT, 26))
        .margin(PANEL_MARGIN)
        .x_label_area_size(50)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(
            xr.clone().log_scale().with_key_points(x_ticks),
            yr.log_scale().with_key_points(y_bold).with_light_points(y_light),
        )
        .map_err(plot_err)?;
    draw_t_mesh(&mut chart, "N (grid size; scene N³)", |_| {})?;

    // References first (underneath), then the thesis, then ours on top.
    draw_line(&mut chart, &ideal, ideal_look)?;
    draw_line(&mut chart, &thesis_unb, unb_look)?;
    draw_line(&mut chart, &lb, lb_look)?;
    draw_line(&mut chart, &thesis_fa1, Look { mark: None, ..fa1_look })?;
    draw_marks(&mut chart, &thesis_fa1_marks, Mark::Cross, THESIS_DARK)?;
    draw_line(&mut chart, &thesis_max_pts, max_look)?;
    for l in &ours {
        draw_line(&mut chart, &l.points, l.look)?;
    }
    Ok(0)
}

/// Right panel: T against FA for each N (linear FA, log T).
/// With `legend_h = None` only measures: returns the legend strip's needed height.
fn draw_against_fa<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, d: &Data, legend_h: Option<u32>) -> Result<u32> {
    // The Ns drawn: ours swept over FA; with no data, the thesis's FA sweeps.
    let ns: Vec<u32> = if d.ns.is_empty() {
        let mut c: BTreeMap<u32, usize> = BTreeMap::new();
        for &(n, _, _) in THESIS_T {
            *c.entry(n).or_default() += 1;
        }
        c.into_iter().filter(|&(_, k)| k > 1).map(|(n, _)| n).collect()
    } else {
        d.swept().into_iter().collect()
    };
    let mut lines = Vec::new();
    let mut thesis: Vec<(RGBColor, Vec<(f64, f64)>)> = Vec::new();
    for (i, &n) in ns.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        for (p, name) in d.policies.iter().enumerate() {
            let points = d.sweep(p, n);
            if !points.is_empty() {
                let look = Look { colour, width: 2, dashed: Some(false), mark: Some(policy_mark(p)) };
                lines.push(Line { label: format!("{name}, N = {n}"), look, points });
            }
        }
        let pts: Vec<(f64, f64)> =
            THESIS_T.iter().filter(|&&(m, _, _)| m == n).map(|&(_, fa, t)| (f64::from(fa), t as f64)).collect();
        thesis.push((colour, pts));
    }

    // The legend is factorised: colour = N, mark = policy, cross = thesis.
    let mut entries: Vec<(String, Look)> = ns
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let colour = PALETTE[i % PALETTE.len()];
            (format!("N = {n}"), Look { colour, width: 3, dashed: Some(false), mark: None })
        })
        .collect();
    for (p, name) in d.policies.iter().enumerate() {
        let look = Look { colour: BLACK, width: 2, dashed: Some(false), mark: Some(policy_mark(p)) };
        entries.push((format!("ours: {name}"), look));
    }
    if thesis.iter().any(|(_, p)| !p.is_empty()) {
        let look = Look { colour: BLACK, width: 2, dashed: None, mark: Some(Mark::Cross) };
        entries.push(("thesis §4.4.3 (colour = N)".into(), look));
    }
    let chart_area = match split_for_legend(area, &entries, legend_h)? {
        Panel::Measured(h) => return Ok(h),
        Panel::Chart(a) => a,
    };

    let all = || {
        lines.iter().flat_map(|l| l.points.iter().copied()).chain(thesis.iter().flat_map(|(_, p)| p.iter().copied()))
    };
    let fa_max = all().map(|p| p.0).fold(2.0f64, f64::max);
    let (y_min, y_max) = all().fold((f64::INFINITY, 0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let (y_min, y_max) = if y_min.is_finite() { (y_min, y_max) } else { (10.0, 1000.0) };
    let yr = log_range(y_min, y_max, 1.25);
    let (y_bold, y_light) = decade_ticks(&yr);
    let xr = 0.0..(fa_max * 1.04 + 0.5);

    let mut chart = ChartBuilder::on(&chart_area)
        .caption("T\u{2002}against FA", (FONT, 26))
        .margin(PANEL_MARGIN)
        .x_label_area_size(50)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(xr, yr.log_scale().with_key_points(y_bold).with_light_points(y_light))
        .map_err(plot_err)?;
    draw_t_mesh(&mut chart, "FA (FIFO size, beams per cell)", |m| {
        m.x_labels(14).x_max_light_lines(1);
    })?;

    for (colour, pts) in &thesis {
        draw_marks(&mut chart, pts, Mark::Cross, *colour)?;
    }
    for l in &lines {
        draw_line(&mut chart, &l.points, l.look)?;
    }
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn out_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rc2-plot-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Checks the file is a PNG of [`PLOT_SIZE`] (signature and IHDR) and not trivially small.
    fn check_png(path: &Path) -> usize {
        let bytes = std::fs::read(path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR");
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        assert_eq!((w, h), PLOT_SIZE);
        assert!(bytes.len() > 10_000, "only {} bytes", bytes.len());
        bytes.len()
    }

    /// Two policies, N ∈ {16, 32, 64, 128}, FA ∈ {1, 2, 4, 8, 16, 32}: T ≈ c·N² at FA = 1
    /// falling to ≈ N·log₂N at FA = 32.
    fn synthetic() -> Vec<DiffusionRow> {
        let mut rows = Vec::new();
        for (policy, c) in [("fifo-xy-first", 1.25), ("round-robin", 1.6)] {
            for n in [16u32, 32, 64, 128] {
                let nf = f64::from(n);
                let hi = c * nf * nf;
                let lo = nf * nf.log2() * c / 1.1;
                for fa in [1u32, 2, 4, 8, 16, 32] {
                    let s = f64::from(fa - 1) / 31.0;
                    let t = hi * (lo / hi).powf(s.sqrt());
                    rows.push(DiffusionRow {
                        n,
                        fa,
                        policy: policy.to_string(),
                        cycles: t.round() as u64,
                        lower_bound: (3 * n / 2) as u64 + u64::from(n) / 4 * u64::from(c > 1.5),
                    });
                }
            }
        }
        rows
    }

    #[test]
    fn plot_synthetic_writes_png() {
        let path = out_dir("synthetic").join("diffusion.png");
        plot_diffusion(&synthetic(), &path).unwrap();
        let len = check_png(&path);
        eprintln!("wrote {} ({len} bytes)", path.display());
    }

    #[test]
    fn plot_empty_draws_thesis_only() {
        let path = out_dir("empty").join("sub/dir/empty.png");
        plot_diffusion(&[], &path).unwrap();
        check_png(&path);
    }

    #[test]
    fn plot_single_row() {
        let path = out_dir("single").join("single.png");
        let row = DiffusionRow { n: 48, fa: 4, policy: "p".into(), cycles: 900, lower_bound: 0 };
        plot_diffusion(&[row], &path).unwrap();
        check_png(&path);
    }

    #[test]
    fn plot_rejects_zero_cycles() {
        let path = out_dir("zero").join("zero.png");
        let row = DiffusionRow { n: 16, fa: 1, policy: "p".into(), cycles: 0, lower_bound: 0 };
        assert!(plot_diffusion(&[row], &path).is_err());
    }

    #[test]
    fn thesis_tables_are_sorted_unique_and_hold_the_spec_values() {
        for table in [THESIS_T, THESIS_T_UNBOUNDED] {
            for w in table.windows(2) {
                assert!((w[0].0, w[0].1) < (w[1].0, w[1].1), "{:?} then {:?}", w[0], w[1]);
            }
        }
        // The thesis's §4.4.3 table.
        for (n, fa, t) in [
            (16, 1, 345),
            (32, 1, 1315),
            (32, 16, 201),
            (64, 1, 5537),
            (64, 16, 1477),
            (64, 32, 805),
            (64, 62, 691),
            (128, 1, 20556),
            (128, 16, 6398),
            (128, 34, 3719),
        ] {
            assert!(THESIS_T.contains(&(n, fa, t)), "({n}, {fa}, {t}) missing");
        }
        assert!(THESIS_T_UNBOUNDED.contains(&(32, 19, 145)));
        assert!(THESIS_T_UNBOUNDED.contains(&(64, 53, 509)));
        assert_eq!(THESIS_T.len(), 204);
        assert_eq!(THESIS_T_UNBOUNDED.len(), 64);
    }

    #[test]
    fn log_axes_always_have_labelled_ticks() {
        for (lo, hi) in [(200.0, 900.0), (16.0, 128.0), (48.0, 48.0), (1.0, 1.0), (7.0, 9.0)] {
            let r = log_range(lo, hi, 1.2);
            assert!(r.start <= lo && r.end >= hi);
            assert!(!decade_ticks(&r).0.is_empty(), "{lo}..{hi} → {r:?}");
            let r = log_range(lo, hi, 1.15);
            let ns: BTreeSet<u32> = [lo as u32, hi as u32].into();
            assert!(!n_ticks(&r, &ns).is_empty(), "{lo}..{hi} → {r:?}");
        }
    }
}

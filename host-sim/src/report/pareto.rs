//! # pareto — a sweep's error against its cost, as a PNG
//!
//! [`plot_pareto`] draws the configurations of a speed/accuracy sweep (`host-sim bench`) in two
//! panels side by side, the same error axis on both: shadow disagreement against **machine
//! cycles** (what the simulated RC² spends) and against **host seconds** (what the simulator
//! spends). The error axis is logarithmic: the front lives in the bottom few per cent of a
//! linear one. Points on the Pareto front ([`pareto_front`], over cycles, error and bytes per
//! cell) are blue, the default configuration red, dominated ones grey. Front points carry a
//! number beside their mark, placed where it overlaps no other number; a key under the panels
//! says what each number is (knobs and bytes per cell). Points at exactly 0 % sit on the axis's
//! floor (the key says so).

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::report::plot::{decade_ticks, ensure_font, label_int, log_range, plot_err, FONT};

/// One configuration of a speed/accuracy sweep.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ParetoPoint {
    /// Short label (the knobs that differ from the default).
    pub label: String,
    /// Machine cycles (load + light + shade).
    pub cycles: f64,
    /// Error (shadow disagreement, %).
    pub error: f64,
    /// Memory of a cell built for this configuration (bytes).
    pub bytes: f64,
    /// Host wall seconds of the run (mean over the sweep's scenes).
    pub seconds: f64,
    /// Whether this is the default configuration.
    pub is_default: bool,
}

/// Indices of the points on the Pareto front over (cycles, error, bytes per cell): no other point
/// is at least as good in all three and strictly better in one (FIFO size trades memory for
/// speed, so memory is an objective too). Sorted by cycles.
pub fn pareto_front(points: &[ParetoPoint]) -> Vec<usize> {
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let p = &points[i];
            !points.iter().any(|q| {
                q.cycles <= p.cycles
                    && q.error <= p.error
                    && q.bytes <= p.bytes
                    && (q.cycles < p.cycles || q.error < p.error || q.bytes < p.bytes)
            })
        })
        .collect();
    front.sort_by(|&a, &b| points[a].cycles.total_cmp(&points[b].cycles));
    front
}

/// The picture's width; its height is the title's, the panels' and the key's
/// ([`pareto_size`]).
const WIDTH: u32 = 1600;
const TITLE_HEIGHT: u32 = 40;
const PANELS_HEIGHT: u32 = 760;
const KEY_FONT: u32 = 13;
const KEY_ROW: i32 = KEY_FONT as i32 + 5;
const NUMBER_FONT: u32 = 13;
const GREY: RGBColor = RGBColor(150, 150, 150);

/// A point's colour: the default red, the front blue, the others grey.
fn colour(p: &ParetoPoint, on_front: bool) -> RGBColor {
    if p.is_default {
        RED
    } else if on_front {
        BLUE
    } else {
        GREY
    }
}

/// The picture's size for `numbered` points in the key (two columns of lines, then a note): the
/// panels keep their height however long the front is.
pub fn pareto_size(numbered: usize) -> (u32, u32) {
    let key_rows = numbered.div_ceil(2) as u32 + 2;
    (WIDTH, TITLE_HEIGHT + PANELS_HEIGHT + key_rows * KEY_ROW as u32 + 20)
}

/// Which points are numbered: the front and the default, by cycles (then error).
fn numbered(points: &[ParetoPoint], front: &[usize]) -> Vec<usize> {
    let mut shown: Vec<usize> = front.to_vec();
    if let Some(d) = points.iter().position(|p| p.is_default).filter(|d| !front.contains(d)) {
        shown.push(d);
    }
    shown.sort_by(|&a, &b| {
        points[a].cycles.total_cmp(&points[b].cycles).then(points[a].error.total_cmp(&points[b].error))
    });
    shown
}

/// Error against machine cycles and against host seconds for a sweep (see the module doc).
pub fn plot_pareto(points: &[ParetoPoint], title: &str, path: &Path) -> Result<()> {
    ensure_font()?;
    let bad = |p: &ParetoPoint| !(p.cycles > 0.0 && p.error.is_finite() && p.error >= 0.0 && p.seconds.is_finite());
    if points.is_empty() || points.iter().any(bad) {
        return Err(anyhow!("nothing to plot (or a point with no cycles / a non-finite or negative error)"));
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let front = pareto_front(points);
    let shown = numbered(points, &front);
    let root = BitMapBackend::new(path, pareto_size(shown.len())).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (title_area, rest) = root.split_vertically(TITLE_HEIGHT);
    title_area
        .draw_text(
            title,
            &TextStyle::from((FONT, 24).into_font()).pos(Pos::new(HPos::Center, VPos::Center)),
            (WIDTH as i32 / 2, TITLE_HEIGHT as i32 / 2),
        )
        .map_err(plot_err)?;
    let (panels, key) = rest.split_vertically(PANELS_HEIGHT);
    let (left, right) = panels.split_horizontally(WIDTH / 2);
    let floor = error_floor(points);
    let errors = log_range(
        points.iter().map(|p| p.error.max(floor)).fold(f64::MAX, f64::min),
        points.iter().map(|p| p.error).fold(floor, f64::max),
        1.3,
    );
    let cycles = |p: &ParetoPoint| p.cycles;
    let seconds = |p: &ParetoPoint| p.seconds.max(1e-3);
    let by_cycles = Axis { desc: "machine cycles (load + light + shade)", value: &cycles, join: true };
    let by_seconds = Axis { desc: "host wall seconds (mean over the scenes)", value: &seconds, join: false };
    draw_panel(&left, points, &front, &shown, floor, &errors, &by_cycles)?;
    draw_panel(&right, points, &front, &shown, floor, &errors, &by_seconds)?;
    draw_key(&key, points, &front, &shown, floor)?;
    root.present().map_err(plot_err)?;
    Ok(())
}

/// Where a 0 % error is drawn: a third of the smallest positive error, at most 0.01 %.
fn error_floor(points: &[ParetoPoint]) -> f64 {
    points.iter().map(|p| p.error).filter(|&e| e > 0.0).fold(f64::MAX, f64::min).min(0.03) / 3.0
}

/// A panel's x axis: its description, a point's value on it, and whether the front is joined.
struct Axis<'a> {
    desc: &'a str,
    value: &'a dyn Fn(&ParetoPoint) -> f64,
    join: bool,
}

/// One panel: error (log) against `axis` (log), the front joined by cycles (`join`: on the cycles
/// panel; against seconds the same points zigzag), the numbered points labelled.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[ParetoPoint],
    front: &[usize],
    shown: &[usize],
    floor: f64,
    errors: &std::ops::Range<f64>,
    axis: &Axis<'_>,
) -> Result<()> {
    let Axis { desc: x_desc, value: x, join } = *axis;
    let (lo, hi) = points.iter().map(x).fold((f64::MAX, 0f64), |(a, b), v| (a.min(v), b.max(v)));
    let xr = log_range(lo, hi, 1.15);
    let (x_bold, x_light) = decade_ticks(&xr);
    let (y_bold, y_light) = decade_ticks(errors);
    let mut chart = ChartBuilder::on(area)
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(
            xr.log_scale().with_key_points(x_bold).with_light_points(x_light),
            errors.clone().log_scale().with_key_points(y_bold).with_light_points(y_light),
        )
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("shadow disagreement vs f64 reference (%, log)")
        .x_label_formatter(&|v| if *v >= 10.0 { label_int(v) } else { format!("{v}") })
        .y_label_formatter(&|v| format!("{v}"))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .draw()
        .map_err(plot_err)?;
    let at = |p: &ParetoPoint| (x(p), p.error.max(floor));
    if join {
        chart
            .draw_series(LineSeries::new(front.iter().map(|&i| at(&points[i])), BLUE.mix(0.5).stroke_width(2)))
            .map_err(plot_err)?;
    }
    // Grey first, then the front, the default on top.
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| (points[i].is_default, front.contains(&i)));
    for i in order {
        let p = &points[i];
        let size = if p.is_default {
            8
        } else if front.contains(&i) {
            5
        } else {
            4
        };
        let c = colour(p, front.contains(&i));
        chart.draw_series(std::iter::once(Circle::new(at(p), size, c.filled()))).map_err(plot_err)?;
    }
    // Numbers beside the marks, each where it overlaps no number placed before it.
    let mut placed: Vec<(i32, i32, i32, i32)> = Vec::new();
    for (k, &i) in shown.iter().enumerate() {
        let p = &points[i];
        let text = format!("{}", k + 1);
        let (px, py) = chart.backend_coord(&at(p));
        let (w, h) = (7 * text.len() as i32 + 2, NUMBER_FONT as i32 + 2);
        let spot =
            [(7, -h), (7, 2), (-w - 7, -h), (-w - 7, 2), (7, -2 * h), (7, h + 2), (-w - 7, -2 * h), (-w - 7, h + 2)]
                .into_iter()
                .map(|(dx, dy)| (px + dx, py + dy, w, h))
                .find(|r| !placed.iter().any(|q| overlap(r, q)))
                .unwrap_or((px + 7, py - h, w, h));
        placed.push(spot);
        let c = colour(p, front.contains(&i));
        let base = area.get_base_pixel();
        area.draw_text(&text, &text_style(&c, NUMBER_FONT), (spot.0 - base.0, spot.1 - base.1)).map_err(plot_err)?;
    }
    Ok(())
}

/// Text of `size` in `c`, anchored at its top left.
fn text_style(c: &RGBColor, size: u32) -> TextStyle<'_> {
    TextStyle::from((FONT, size).into_font()).color(c).pos(Pos::new(HPos::Left, VPos::Top))
}

/// Whether two rectangles (x, y, w, h) overlap.
fn overlap(a: &(i32, i32, i32, i32), b: &(i32, i32, i32, i32)) -> bool {
    a.0 < b.0 + b.2 && b.0 < a.0 + a.2 && a.1 < b.1 + b.3 && b.1 < a.1 + a.3
}

/// The key: what each number is, in two columns, and how to read the marks.
fn draw_key<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[ParetoPoint],
    front: &[usize],
    shown: &[usize],
    floor: f64,
) -> Result<()> {
    let rows = shown.len().div_ceil(2);
    let col_w = WIDTH as i32 / 2;
    for (k, &i) in shown.iter().enumerate() {
        let p = &points[i];
        let (col, row) = ((k / rows.max(1)) as i32, (k % rows.max(1)) as i32);
        let who = if p.is_default { "default: " } else { "" };
        let line = format!(
            "{}  {who}{} — {} cycles, {:.2} %, {:.2} s, {} B/cell",
            k + 1,
            p.label,
            p.cycles.round(),
            p.error,
            p.seconds,
            p.bytes
        );
        let c = colour(p, front.contains(&i));
        area.draw_text(&line, &text_style(&c, KEY_FONT), (30 + col * col_w, 6 + row * KEY_ROW)).map_err(plot_err)?;
    }
    let zero = points.iter().any(|p| p.error == 0.0);
    let note = format!(
        "blue: on the front over cycles, error and bytes per cell (joined by cycles on the left); red: the default; grey: dominated (the CSV has their knobs){}",
        if zero { format!("; 0 % is drawn at {floor:.4} %") } else { String::new() }
    );
    area.draw_text(&note, &text_style(&BLACK, KEY_FONT), (30, 10 + rows as i32 * KEY_ROW)).map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(label: &str, cycles: f64, error: f64, bytes: f64) -> ParetoPoint {
        ParetoPoint { label: label.into(), cycles, error, bytes, seconds: cycles / 1000.0, is_default: false }
    }

    #[test]
    fn the_front_is_every_undominated_point() {
        let pts = vec![
            point("a", 100.0, 1.0, 10.0),
            point("b", 200.0, 0.5, 10.0),
            point("c", 200.0, 0.6, 10.0), // dominated by b
            point("d", 50.0, 2.0, 20.0),
            point("e", 300.0, 0.5, 5.0),  // cheaper in bytes than b: on the front
            point("f", 300.0, 0.5, 10.0), // dominated by b (and e)
        ];
        // Brute force over every pair, independently of `pareto_front`'s filter.
        let dominated = |i: usize| {
            (0..pts.len()).any(|j| {
                let (p, q) = (&pts[i], &pts[j]);
                j != i
                    && q.cycles <= p.cycles
                    && q.error <= p.error
                    && q.bytes <= p.bytes
                    && (q.cycles, q.error, q.bytes) != (p.cycles, p.error, p.bytes)
            })
        };
        let mut want: Vec<usize> = (0..pts.len()).filter(|&i| !dominated(i)).collect();
        want.sort_by(|&a, &b| pts[a].cycles.total_cmp(&pts[b].cycles));
        assert_eq!(pareto_front(&pts), want);
        assert_eq!(want.iter().map(|&i| pts[i].label.as_str()).collect::<Vec<_>>(), ["d", "a", "b", "e"]);
    }

    #[test]
    fn a_sweep_plots_with_crowded_points_and_zero_errors() {
        let mut pts: Vec<ParetoPoint> = (0..40)
            .map(|i| {
                point(&format!("knob set {i}"), 3000.0 + 37.0 * f64::from(i % 7), 0.2 + 0.01 * f64::from(i % 5), 6600.0)
            })
            .collect();
        pts.push(ParetoPoint { is_default: true, ..point("f = 0", 5000.0, 0.26, 6600.0) });
        pts.push(point("exact", 9000.0, 0.0, 6600.0));
        let dir = std::env::temp_dir().join(format!("rc2-pareto-{}", std::process::id()));
        let path = dir.join("p.png");
        plot_pareto(&pts, "synthetic sweep", &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let (w, h) = (
            u32::from_be_bytes(bytes[16..20].try_into().unwrap()),
            u32::from_be_bytes(bytes[20..24].try_into().unwrap()),
        );
        assert_eq!((w, h), pareto_size(numbered(&pts, &pareto_front(&pts)).len()));
        assert!(bytes.len() > 20_000, "a nearly empty picture: {} bytes", bytes.len());
        std::fs::remove_dir_all(dir).ok();
    }

    /// A sweep whose every point is on the front: the key grows, the panels keep their room.
    #[test]
    fn a_long_front_gets_a_taller_picture() {
        let pts: Vec<ParetoPoint> =
            (1..=200).map(|i| point(&format!("k{i}"), 1000.0 * f64::from(i), 10.0 / f64::from(i), 100.0)).collect();
        assert_eq!(pareto_front(&pts).len(), 200);
        let path = std::env::temp_dir().join(format!("rc2-pareto-long-{}.png", std::process::id()));
        plot_pareto(&pts, "every point on the front", &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        assert_eq!(h, pareto_size(200).1);
        assert!(h > TITLE_HEIGHT + PANELS_HEIGHT + 100 * KEY_ROW as u32);
        std::fs::remove_file(path).ok();
    }

    #[test]
    fn bad_points_are_refused() {
        let path = std::env::temp_dir().join("rc2-pareto-never.png");
        assert!(plot_pareto(&[], "t", &path).is_err());
        assert!(plot_pareto(&[point("nan", 1.0, f64::NAN, 1.0)], "t", &path).is_err());
        assert!(plot_pareto(&[point("zero", 0.0, 1.0, 1.0)], "t", &path).is_err());
    }
}

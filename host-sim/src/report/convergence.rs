//! # convergence — a solver's residual against its iterations, as a PNG
//!
//! [`plot_residuals`] draws one line per [`Series`] (the machine's progressive radiosity, the
//! f64 reference's on the same patches …): the residual (unshot over emitted power, radiosity
//! thesis §1.3.2) on a log axis against the shot count, with the stopping fraction as a dashed
//! horizontal line when one is given. 900 × 560 pixels, legend under the chart, the embedded
//! font of [`crate::report::plot`].
#![forbid(unsafe_code)]

use std::path::Path;

use anyhow::{bail, Result};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use crate::report::plot::{ensure_font, plot_err, FONT};

/// One solver's curve: `points[k] = (iteration, residual after it)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (iteration, residual) pairs, iterations increasing, residuals > 0.
    pub points: Vec<(f64, f64)>,
}

const COLOURS: [RGBColor; 4] =
    [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), RGBColor(148, 103, 189)];

/// Draw `series` (residual on a log axis against iterations) with `title`, and `stop` (the
/// stopping fraction) as a dashed line, into the PNG at `path`. An empty series, a residual
/// ≤ 0 or not finite (a log axis cannot show it) is an error naming the series.
pub fn plot_residuals(title: &str, x_label: &str, series: &[Series], stop: Option<f64>, path: &Path) -> Result<()> {
    if series.is_empty() {
        bail!("residual plot: nothing to draw");
    }
    for s in series {
        if s.points.is_empty() {
            bail!("residual plot: series '{}' has no points", s.label);
        }
        if let Some(p) = s.points.iter().find(|p| !(p.1.is_finite() && p.1 > 0.0 && p.0.is_finite())) {
            bail!("residual plot: series '{}' has a point {:?} a log axis cannot show", s.label, p);
        }
    }
    ensure_font()?;
    let all = || series.iter().flat_map(|s| s.points.iter());
    let x_max = all().map(|p| p.0).fold(1.0, f64::max);
    let y_lo = all().map(|p| p.1).chain(stop.filter(|s| *s > 0.0)).fold(f64::INFINITY, f64::min) * 0.8;
    let y_hi = all().map(|p| p.1).fold(0.0, f64::max).max(y_lo * 10.0) * 1.25;
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let legend_rows = (series.len() + usize::from(stop.is_some())).div_ceil(2) as u32;
    let (chart_area, legend_area) = root.split_vertically(560 - 28 * legend_rows - 12);
    let mut chart = ChartBuilder::on(&chart_area)
        .caption(title, (FONT, 22))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x_max, (y_lo..y_hi).log_scale().with_key_points(ticks_125(y_lo, y_hi)))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("residual (unshot / emitted power)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(238, 238, 238))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{}", (v * 1e6).round() / 1e6))
        .draw()
        .map_err(plot_err)?;
    if let Some(s) = stop.filter(|s| *s > 0.0) {
        chart
            .draw_series(std::iter::once(DashedPathElement::new(
                vec![(0.0, s), (x_max, s)],
                6,
                4,
                BLACK.stroke_width(1),
            )))
            .map_err(plot_err)?;
    }
    for (k, s) in series.iter().enumerate() {
        let c = COLOURS[k % COLOURS.len()];
        chart.draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2))).map_err(plot_err)?;
    }
    let mut legend: Vec<(String, ShapeStyle)> =
        series.iter().enumerate().map(|(k, s)| (s.label.clone(), COLOURS[k % COLOURS.len()].stroke_width(3))).collect();
    if let Some(s) = stop {
        legend.push((format!("stop at {s}"), BLACK.stroke_width(1)));
    }
    let (w, _) = legend_area.dim_in_pixel();
    for (k, (label, style)) in legend.into_iter().enumerate() {
        let (x, y) = (20 + (k % 2) as i32 * (w as i32 / 2), 6 + (k / 2) as i32 * 28);
        legend_area.draw(&PathElement::new(vec![(x, y + 9), (x + 36, y + 9)], style)).map_err(plot_err)?;
        legend_area.draw(&Text::new(label, (x + 44, y), (FONT, 15).into_font())).map_err(plot_err)?;
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

/// The 1-2-5 values of each decade in `[lo, hi]`: the log axis's labelled lines.
fn ticks_125(lo: f64, hi: f64) -> Vec<f64> {
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    (first..=last).flat_map(|e| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(e))).filter(|v| (lo..=hi).contains(v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn out(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rc2-convergence-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        let _ = std::fs::remove_file(&p);
        p
    }

    fn decreasing(label: &str, k: usize) -> Series {
        Series { label: label.into(), points: (1..=k).map(|i| (i as f64, 1.0 / i as f64)).collect() }
    }

    /// Decode the PNG: its size, and how many pixels have exactly colour `c`.
    fn decode(path: &Path, c: RGBColor) -> ((u32, u32), usize) {
        let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        let hits = buf[..info.buffer_size()].chunks(3).filter(|p| p == &[c.0, c.1, c.2]).count();
        ((info.width, info.height), hits)
    }

    #[test]
    fn draws_each_series_in_its_colour() {
        let path = out("two.png");
        plot_residuals("t", "shots", &[decreasing("machine", 50), decreasing("reference", 40)], Some(0.01), &path)
            .unwrap();
        let (size, machine) = decode(&path, COLOURS[0]);
        assert_eq!(size, (900, 560));
        // A line across the chart and its legend swatch: hundreds of pixels of each colour,
        // none of a third series'.
        assert!(machine > 300, "{machine} machine pixels");
        assert!(decode(&path, COLOURS[1]).1 > 300);
        assert_eq!(decode(&path, COLOURS[2]).1, 0);
    }

    #[test]
    fn log_axis_ticks_are_1_2_5_per_decade() {
        assert_eq!(ticks_125(0.008, 1.25), vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0]);
        assert_eq!(ticks_125(0.3, 0.9), vec![0.5]);
    }

    #[test]
    fn refuses_what_a_log_axis_cannot_show() {
        let path = out("bad.png");
        let zero = Series { label: "z".into(), points: vec![(1.0, 0.5), (2.0, 0.0)] };
        let e = plot_residuals("t", "shots", &[zero], None, &path).unwrap_err().to_string();
        assert!(e.contains("'z'"), "{e}");
        assert!(plot_residuals("t", "shots", &[], None, &path).is_err());
        let empty = Series { label: "e".into(), points: vec![] };
        assert!(plot_residuals("t", "shots", &[empty], None, &path).unwrap_err().to_string().contains("no points"));
        assert!(!path.exists());
    }
}

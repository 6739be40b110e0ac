//! The plot of §2.5.4's comparison (radiosity thesis Fig. 2.18): each projective method's form
//! factor to facets 1 and 4 against the hemicube resolution its own is equivalent to, as the
//! relative error to the exact value (0 % is exact), one panel per facet and distance
//! ([`crate::truth::projective::figure`]), and any other method's points given (the grid's beam
//! shot) as one more line.

use std::path::Path;

use anyhow::{bail, Result};
use plotters::prelude::*;

use crate::report::plot::{ensure_font, plot_err, FONT, PALETTE};
use crate::truth::projective::figure::{FigurePoint, DISTANCES, FACETS, METHODS};
use crate::truth::projective::tables::methods_with;

/// Draw `points` into the PNG at `path`. No points, or a point without a finite relative error,
/// is an error.
pub fn plot_figure(points: &[FigurePoint], path: &Path) -> Result<()> {
    let rel = |p: &FigurePoint| 100.0 * (p.computed / p.exact - 1.0);
    if points.is_empty() {
        bail!("form-factor figure: nothing to draw");
    }
    if let Some(p) = points.iter().find(|p| !rel(p).is_finite()) {
        bail!("form-factor figure: {p:?} has no finite relative error");
    }
    ensure_font()?;
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (title, rest) = root.split_vertically(40);
    title
        .draw_text(
            "Form factor of facets 1 and 4 against resolution (relative error to the exact value)",
            &(FONT, 20).into_text_style(&title),
            (16, 10),
        )
        .map_err(plot_err)?;
    let (panels, key) = rest.split_vertically(820);
    let methods = methods_with(points.iter().map(|p| p.method));
    let x_max = points.iter().map(|p| p.hemicube_r).max().unwrap_or(1) as f64;
    let x_min = points.iter().map(|p| p.hemicube_r).min().unwrap_or(0) as f64;
    for (area, (facet, distance)) in
        panels.split_evenly((2, 2)).iter().zip(FACETS.iter().flat_map(|&f| DISTANCES.iter().map(move |&d| (f, d))))
    {
        let mine: Vec<&FigurePoint> = points.iter().filter(|p| p.facet == facet && p.distance == distance).collect();
        // The scale of the thesis's six methods; another line (the grid's shot, far coarser at
        // small n) is drawn clamped to it (its values are in the CSV).
        let span = mine.iter().filter(|p| METHODS.contains(&p.method)).map(|p| rel(p).abs()).fold(0.5, f64::max) * 1.1;
        let mut chart = ChartBuilder::on(area)
            .caption(format!("facet {facet}, distance {distance}"), (FONT, 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x_min..x_max, -span..span)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("equivalent hemicube resolution R")
            .y_desc("error (%)")
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .light_line_style(WHITE)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(plot_err)?;
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(x_min, 0.0), (x_max, 0.0)], BLACK)))
            .map_err(plot_err)?;
        for (method, colour) in methods.iter().zip(PALETTE) {
            let line: Vec<(f64, f64)> = mine
                .iter()
                .filter(|p| p.method == *method)
                .map(|p| (p.hemicube_r as f64, rel(p).clamp(-span, span)))
                .collect();
            chart.draw_series(LineSeries::new(line, colour.stroke_width(2))).map_err(plot_err)?;
        }
    }
    for (i, (method, colour)) in methods.iter().zip(PALETTE).enumerate() {
        let x = 20 + 165 * i as i32;
        key.draw(&PathElement::new(vec![(x, 20), (x + 30, 20)], colour.stroke_width(3))).map_err(plot_err)?;
        key.draw_text(method, &(FONT, 15).into_text_style(&key), (x + 36, 12)).map_err(plot_err)?;
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::projective::figure::compute;

    /// A figure is a 1200 × 900 PNG; no points, or a point with no exact value, is refused.
    #[test]
    fn the_figure_is_drawn_and_bad_points_are_refused() {
        let dir = std::env::temp_dir().join(format!("rc2-ff-figure-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("fig.png");
        let mut points = compute(&[16, 18]).unwrap();
        plot_figure(&points, &path).unwrap();
        let info = png::Decoder::new(std::fs::File::open(&path).unwrap()).read_info().unwrap().info().clone();
        assert_eq!((info.width, info.height), (1200, 900));
        assert!(plot_figure(&[], &path).is_err());
        points[3].exact = 0.0;
        assert!(plot_figure(&points, &path).unwrap_err().to_string().contains("no finite relative error"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

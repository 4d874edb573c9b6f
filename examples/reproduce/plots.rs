//! Stacked line plots sharing the time axis (Figures 5 and 6 of the paper),
//! drawn with plotters as SVG.

use plotters::prelude::*;
use std::path::Path;

/// One line of a plot. Non-finite values leave a gap.
pub struct Series<'a> {
    pub name: &'a str,
    pub color: RGBColor,
    pub x: &'a [f64],
    pub y: Vec<f64>,
}

/// One panel of a stacked plot.
pub struct Panel<'a> {
    pub title: String,
    pub series: Vec<Series<'a>>,
}

/// The truth's colour, then the estimators' in registry order.
pub const TRUTH_COLOR: RGBColor = BLACK;
pub const COLORS: [RGBColor; 8] = [
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// The finite range of `values`, padded; `None` when there is none.
fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    Some((lo - pad, hi + pad))
}

/// The runs of consecutive finite points of a series.
fn segments(s: &Series) -> Vec<Vec<(f64, f64)>> {
    let mut out = vec![Vec::new()];
    for (&x, &y) in s.x.iter().zip(&s.y) {
        if y.is_finite() {
            out.last_mut().expect("never empty").push((x, y));
        } else if !out.last().expect("never empty").is_empty() {
            out.push(Vec::new());
        }
    }
    out
}

/// Draws `panels` (those with a finite point) one above the other into `path`.
pub fn panels(
    path: &Path,
    title: &str,
    panels: &[Panel],
) -> Result<(), Box<dyn std::error::Error>> {
    let drawn: Vec<&Panel> = panels
        .iter()
        .filter(|p| range(p.series.iter().flat_map(|s| s.y.iter().copied())).is_some())
        .collect();
    let height = 40 + 250 * drawn.len().max(1) as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 18))?;
    for (area, panel) in root.split_evenly((drawn.len().max(1), 1)).iter().zip(drawn) {
        let points = || {
            panel
                .series
                .iter()
                .flat_map(|s| s.x.iter().copied().zip(s.y.iter().copied()))
        };
        let finite = || points().filter(|(_, y)| y.is_finite());
        let (Some(x), Some(y)) = (range(finite().map(|p| p.0)), range(finite().map(|p| p.1)))
        else {
            continue;
        };
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart.configure_mesh().x_desc("time (s)").draw()?;
        for s in &panel.series {
            let color = s.color;
            let mut first = true;
            for segment in segments(s) {
                let drawn = chart.draw_series(LineSeries::new(segment, &color))?;
                if first {
                    drawn
                        .label(s.name)
                        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
                    first = false;
                }
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

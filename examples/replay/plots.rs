//! SVG plots of a replay: the delay estimate over time, and roll, pitch,
//! yaw of each estimator against the reference.

use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Failure = Box<dyn Error>;

const COLORS: [RGBColor; 5] = [RED, BLUE, GREEN, MAGENTA, CYAN];

fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() {
        return None;
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    Some((lo - pad, hi + pad))
}

/// `delay.svg`: each estimator's delay estimate (s) over log time (s).
pub fn delay(path: &Path, tracks: &[(&str, &[(f64, f64)])]) -> Result<(), Failure> {
    let points = || tracks.iter().flat_map(|(_, t)| t.iter());
    let (Some(x), Some(y)) = (range(points().map(|p| p.0)), range(points().map(|p| p.1))) else {
        eprintln!(
            "no estimator has a delay estimate: {} not written",
            path.display()
        );
        return Ok(());
    };
    let root = SVGBackend::new(path, (900, 400)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("GPS delay estimate", ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    chart
        .configure_mesh()
        .x_desc("log time (s)")
        .y_desc("delay (s)")
        .draw()?;
    for (k, (name, track)) in tracks
        .iter()
        .enumerate()
        .filter(|(_, (_, t))| !t.is_empty())
    {
        let color = COLORS[k % COLORS.len()];
        chart
            .draw_series(LineSeries::new(track.iter().copied(), &color))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// `roll.svg`, `pitch.svg`, `yaw.svg`: each estimator (aligned like the
/// reference) and the reference, degrees over log time.
pub fn attitude(
    dir: &Path,
    traces: &[(String, Vec<[f64; 4]>)],
    reference: Option<&[[f64; 4]]>,
) -> Result<(), Failure> {
    for (axis, name) in [(1, "roll"), (2, "pitch"), (3, "yaw")] {
        let mut series: Vec<(&str, &[[f64; 4]])> = traces
            .iter()
            .map(|(n, t)| (n.as_str(), t.as_slice()))
            .collect();
        if let Some(r) = reference {
            series.push(("reference", r));
        }
        let points = || series.iter().flat_map(|(_, t)| t.iter());
        let (Some(x), Some(y)) = (
            range(points().map(|p| p[0])),
            range(points().map(|p| p[axis])),
        ) else {
            continue;
        };
        let path = dir.join(format!("{name}.svg"));
        let root = SVGBackend::new(&path, (900, 400)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("{name} (deg)"), ("sans-serif", 20))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart
            .configure_mesh()
            .x_desc("log time (s)")
            .y_desc(format!("{name} (deg)"))
            .draw()?;
        for (k, (label, trace)) in series.iter().enumerate() {
            let color = if *label == "reference" {
                BLACK
            } else {
                COLORS[k % COLORS.len()]
            };
            chart
                .draw_series(LineSeries::new(
                    trace.iter().map(|p| (p[0], p[axis])),
                    &color,
                ))?
                .label(*label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
    }
    Ok(())
}

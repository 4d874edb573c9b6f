//! SVG plots of a replay: the delay estimate over time, and roll, pitch,
//! yaw of each estimator against the reference.

use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Failure = Box<dyn Error>;

const COLORS: [RGBColor; 5] = [RED, BLUE, GREEN, MAGENTA, CYAN];

/// One line of a chart.
struct Line<'a> {
    label: &'a str,
    color: RGBColor,
    points: Vec<(f64, f64)>,
}

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

/// Draws `lines` over log time into `path`; `false` when there is nothing to draw.
fn line_chart(path: &Path, title: &str, y_desc: &str, lines: &[Line]) -> Result<bool, Failure> {
    let points = || lines.iter().flat_map(|l| l.points.iter());
    let (Some(x), Some(y)) = (range(points().map(|p| p.0)), range(points().map(|p| p.1))) else {
        return Ok(false);
    };
    let root = SVGBackend::new(path, (900, 400)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    chart
        .configure_mesh()
        .x_desc("log time (s)")
        .y_desc(y_desc)
        .draw()?;
    for line in lines {
        let color = line.color;
        chart
            .draw_series(LineSeries::new(line.points.iter().copied(), &color))?
            .label(line.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(true)
}

/// `delay.svg`: each estimator's delay estimate (s) over log time (s).
pub fn delay(path: &Path, tracks: &[(&str, &[(f64, f64)])]) -> Result<(), Failure> {
    let lines: Vec<Line> = tracks
        .iter()
        .enumerate()
        .map(|(k, (label, track))| Line {
            label,
            color: COLORS[k % COLORS.len()],
            points: track.to_vec(),
        })
        .collect();
    if !line_chart(path, "GPS delay estimate", "delay (s)", &lines)? {
        eprintln!(
            "no estimator has a delay estimate: {} not written",
            path.display()
        );
    }
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
        let along = |trace: &[[f64; 4]]| trace.iter().map(|p| (p[0], p[axis])).collect();
        let mut lines: Vec<Line> = traces
            .iter()
            .enumerate()
            .map(|(k, (label, trace))| Line {
                label,
                color: COLORS[k % COLORS.len()],
                points: along(trace),
            })
            .collect();
        if let Some(r) = reference {
            lines.push(Line {
                label: "reference",
                color: BLACK,
                points: along(r),
            });
        }
        let path = dir.join(format!("{name}.svg"));
        line_chart(
            &path,
            &format!("{name} (deg)"),
            &format!("{name} (deg)"),
            &lines,
        )?;
    }
    Ok(())
}

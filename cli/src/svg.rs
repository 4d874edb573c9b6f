//! Inline SVG plots for the flight report: no script, no network. Every
//! plot is an `<svg class="plot" data-plot="NAME">` whose data are
//! `<polyline>`, `<polygon>` and `<rect>` elements (what the browser test
//! counts).

use std::fmt::Write as _;

/// Colours of the series, in order.
pub const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#7f7f7f", "#9467bd", "#ff7f0e",
];

const WIDTH: f64 = 900.0;
const HEIGHT: f64 = 260.0;
const LEFT: f64 = 60.0;
const RIGHT: f64 = 150.0;
const TOP: f64 = 24.0;
const BOTTOM: f64 = 36.0;

/// One line of a plot.
pub struct Series<'a> {
    /// Its name in the legend.
    pub name: &'a str,
    /// Its colour.
    pub colour: &'a str,
    /// `(x, y)` points; non-finite ones are dropped.
    pub points: Vec<(f64, f64)>,
    /// A band around the line, `(x, low, high)`.
    pub band: Vec<(f64, f64, f64)>,
    /// Draw dots rather than a line.
    pub dots: bool,
}

impl<'a> Series<'a> {
    /// A line.
    pub fn line(name: &'a str, colour: &'a str, points: Vec<(f64, f64)>) -> Self {
        Self {
            name,
            colour,
            points: points
                .into_iter()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect(),
            band: Vec::new(),
            dots: false,
        }
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Ticks: about five round values covering `[lo, hi]`.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-9);
    let raw = span / 5.0;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * magnitude);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + 1e-9 && out.len() < 20 {
        out.push(t);
        t += step;
    }
    out
}

/// A plot's frame: the data's ranges mapped to the drawing.
pub struct Frame {
    x: (f64, f64),
    y: (f64, f64),
    /// Same scale on both axes (a track).
    equal: bool,
}

impl Frame {
    /// The frame fitting `points` (`y_floor`: the y range includes it).
    pub fn fit(points: impl Iterator<Item = (f64, f64)>, y_include: &[f64], equal: bool) -> Self {
        let (mut x, mut y) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
        for (px, py) in points.filter(|(a, b)| a.is_finite() && b.is_finite()) {
            x = (x.0.min(px), x.1.max(px));
            y = (y.0.min(py), y.1.max(py));
        }
        for &v in y_include {
            y = (y.0.min(v), y.1.max(v));
        }
        if x.0 > x.1 {
            x = (0.0, 1.0);
        }
        if y.0 > y.1 {
            y = (0.0, 1.0);
        }
        if x.1 - x.0 < 1e-9 {
            x = (x.0 - 0.5, x.1 + 0.5);
        }
        if y.1 - y.0 < 1e-9 {
            y = (y.0 - 0.5, y.1 + 0.5);
        }
        let pad = (y.1 - y.0) * 0.05;
        let mut frame = Self {
            x,
            y: (y.0 - pad, y.1 + pad),
            equal,
        };
        if equal {
            // Same metres per pixel on both axes: widen the narrower range.
            let (w, h) = (WIDTH - LEFT - RIGHT, HEIGHT * 2.0 - TOP - BOTTOM);
            let scale = ((frame.x.1 - frame.x.0) / w).max((frame.y.1 - frame.y.0) / h);
            let (cx, cy) = ((frame.x.0 + frame.x.1) / 2.0, (frame.y.0 + frame.y.1) / 2.0);
            frame.x = (cx - scale * w / 2.0, cx + scale * w / 2.0);
            frame.y = (cy - scale * h / 2.0, cy + scale * h / 2.0);
        }
        frame
    }

    fn height(&self) -> f64 {
        if self.equal { HEIGHT * 2.0 } else { HEIGHT }
    }

    fn px(&self, x: f64) -> f64 {
        LEFT + (x - self.x.0) / (self.x.1 - self.x.0) * (WIDTH - LEFT - RIGHT)
    }

    fn py(&self, y: f64) -> f64 {
        let h = self.height();
        h - BOTTOM - (y - self.y.0) / (self.y.1 - self.y.0) * (h - TOP - BOTTOM)
    }
}

/// An SVG plot of `series` named `id`, titled, with axis labels; `hlines`
/// are dashed horizontal lines (a gate) with their labels.
pub fn plot(
    id: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    hlines: &[(f64, &str)],
    equal: bool,
) -> String {
    let all = series.iter().flat_map(|s| {
        s.points
            .iter()
            .copied()
            .chain(s.band.iter().flat_map(|&(x, lo, hi)| [(x, lo), (x, hi)]))
    });
    let levels: Vec<f64> = hlines.iter().map(|h| h.0).collect();
    let frame = Frame::fit(all, &levels, equal);
    let height = frame.height();
    let mut svg = String::new();
    let _ = write!(
        svg,
        r#"<svg class="plot" data-plot="{id}" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {height}" width="{WIDTH}" height="{height}" role="img" aria-label="{t}">"#,
        t = escape(title)
    );
    let _ = write!(
        svg,
        r#"<text x="{LEFT}" y="16" class="title">{}</text>"#,
        escape(title)
    );
    let (x0, x1) = (frame.px(frame.x.0), frame.px(frame.x.1));
    let (y0, y1) = (frame.py(frame.y.0), frame.py(frame.y.1));
    let _ = write!(
        svg,
        r#"<rect x="{x0:.1}" y="{y1:.1}" width="{:.1}" height="{:.1}" class="axes"/>"#,
        x1 - x0,
        y0 - y1
    );
    for t in ticks(frame.x.0, frame.x.1) {
        let x = frame.px(t);
        let _ = write!(
            svg,
            r#"<line x1="{x:.1}" y1="{y0:.1}" x2="{x:.1}" y2="{:.1}" class="tick"/><text x="{x:.1}" y="{:.1}" class="xt">{}</text>"#,
            y0 + 4.0,
            y0 + 16.0,
            trim(t)
        );
    }
    for t in ticks(frame.y.0, frame.y.1) {
        let y = frame.py(t);
        let _ = write!(
            svg,
            r#"<line x1="{:.1}" y1="{y:.1}" x2="{x0:.1}" y2="{y:.1}" class="tick"/><text x="{:.1}" y="{:.1}" class="yt">{}</text><line x1="{x0:.1}" y1="{y:.1}" x2="{x1:.1}" y2="{y:.1}" class="grid"/>"#,
            x0 - 4.0,
            x0 - 6.0,
            y + 4.0,
            trim(t)
        );
    }
    let _ = write!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" class="xl">{}</text><text x="12" y="{:.1}" class="yl" transform="rotate(-90 12 {:.1})">{}</text>"#,
        (x0 + x1) / 2.0,
        height - 4.0,
        escape(x_label),
        (y0 + y1) / 2.0,
        (y0 + y1) / 2.0,
        escape(y_label)
    );
    for (level, label) in hlines {
        let y = frame.py(*level);
        let _ = write!(
            svg,
            r#"<line x1="{x0:.1}" y1="{y:.1}" x2="{x1:.1}" y2="{y:.1}" class="gate"/><text x="{:.1}" y="{:.1}" class="gl">{}</text>"#,
            x1 + 4.0,
            y + 4.0,
            escape(label)
        );
    }
    for s in series {
        if !s.band.is_empty() {
            let upper = s.band.iter().map(|&(x, _, hi)| (x, hi));
            let lower = s.band.iter().rev().map(|&(x, lo, _)| (x, lo));
            let pts: Vec<String> = upper
                .chain(lower)
                .map(|(x, y)| format!("{:.1},{:.1}", frame.px(x), frame.py(y)))
                .collect();
            let _ = write!(
                svg,
                r#"<polygon class="band" fill="{}" fill-opacity="0.2" stroke="none" points="{}"/>"#,
                s.colour,
                pts.join(" ")
            );
        }
        if s.dots {
            let _ = write!(svg, r#"<g class="dots" fill="{}">"#, s.colour);
            for &(x, y) in &s.points {
                let _ = write!(
                    svg,
                    r#"<rect x="{:.1}" y="{:.1}" width="3" height="3"/>"#,
                    frame.px(x) - 1.5,
                    frame.py(y) - 1.5
                );
            }
            svg.push_str("</g>");
        } else if !s.points.is_empty() {
            let pts: Vec<String> = s
                .points
                .iter()
                .map(|&(x, y)| format!("{:.1},{:.1}", frame.px(x), frame.py(y)))
                .collect();
            let _ = write!(
                svg,
                r#"<polyline class="series" fill="none" stroke="{}" stroke-width="1.2" points="{}"/>"#,
                s.colour,
                pts.join(" ")
            );
        }
    }
    for (k, s) in series.iter().enumerate() {
        let y = TOP + 14.0 + 16.0 * k as f64;
        let _ = write!(
            svg,
            r#"<rect x="{:.1}" y="{:.1}" width="14" height="3" fill="{}"/><text x="{:.1}" y="{:.1}" class="lg">{}</text>"#,
            x1 + 8.0,
            y - 4.0,
            s.colour,
            x1 + 26.0,
            y,
            escape(s.name)
        );
    }
    svg.push_str("</svg>");
    svg
}

/// A timeline's row: its name and its `(t from, t to, on)` segments.
pub type TimelineRow = (String, Vec<(f64, f64, bool)>);

/// A timeline: one row per name, a coloured segment where its state is on
/// (`true`), grey where off. `rows`: `(name, [(t from, t to, on)])`.
pub fn timeline(id: &str, title: &str, rows: &[TimelineRow]) -> String {
    let all = rows
        .iter()
        .flat_map(|(_, r)| r.iter().flat_map(|&(a, b, _)| [(a, 0.0), (b, 0.0)]));
    let frame = Frame::fit(all, &[], false);
    let row_h = 20.0;
    let height = TOP + BOTTOM + row_h * rows.len() as f64;
    let mut svg = String::new();
    let _ = write!(
        svg,
        r#"<svg class="plot" data-plot="{id}" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {height}" width="{WIDTH}" height="{height}" role="img" aria-label="{t}"><text x="{LEFT}" y="16" class="title">{t}</text>"#,
        t = escape(title)
    );
    for (k, (name, segments)) in rows.iter().enumerate() {
        let y = TOP + row_h * k as f64;
        for &(a, b, on) in segments {
            let (xa, xb) = (frame.px(a), frame.px(b));
            let _ = write!(
                svg,
                r#"<rect class="{}" x="{xa:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/>"#,
                if on { "on" } else { "off" },
                y + 2.0,
                (xb - xa).max(0.5),
                row_h - 4.0
            );
        }
        let _ = write!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" class="lg">{}</text>"#,
            frame.px(frame.x.1) + 8.0,
            y + 14.0,
            escape(name)
        );
    }
    let y0 = TOP + row_h * rows.len() as f64;
    for t in ticks(frame.x.0, frame.x.1) {
        let x = frame.px(t);
        let _ = write!(
            svg,
            r#"<text x="{x:.1}" y="{:.1}" class="xt">{}</text>"#,
            y0 + 14.0,
            trim(t)
        );
    }
    let _ = write!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" class="xl">time on the log's clock, s</text></svg>"#,
        (frame.px(frame.x.0) + frame.px(frame.x.1)) / 2.0,
        height - 4.0
    );
    svg
}

/// A tick's label: no trailing zeros.
fn trim(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(ticks(0.0, 10.0), [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(ticks(84.7, 228.5), [100.0, 150.0, 200.0]);
        assert_eq!(trim(0.30000000000000004), "0.3");
    }

    #[test]
    fn a_plot_draws_each_series_and_drops_non_finite_points() {
        let s = [Series::line(
            "a",
            COLOURS[0],
            vec![(0.0, 1.0), (1.0, f64::NAN), (2.0, 3.0)],
        )];
        let svg = plot("p", "T", "x", "y", &s, &[(1.0, "gate")], false);
        assert!(svg.starts_with(r#"<svg class="plot" data-plot="p""#));
        assert_eq!(svg.matches("<polyline").count(), 1);
        assert!(!svg.contains("NaN"));
    }
}

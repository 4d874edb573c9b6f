//! `delaynav report LOG -o FILE.html`: the replay, then one self-contained
//! HTML page (inline SVG and CSS, no script, nothing fetched) with the
//! attitude of each estimator against the onboard solution, the delay with
//! its sigma and status, the GPS and magnetometer innovations against their
//! gates, the health timeline, the track, the derived defaults, the window
//! and the warnings.
//!
//! The innovations and the health timeline are the `proposed` navigator's,
//! recorded on a pass of its own through the same window with the same
//! configuration (`ReplaySetup::nav`): its figures are those of the table.

use crate::Failure;
use crate::args::LogArgs;
use crate::replay::{Console, open, run};
use crate::svg::{COLOURS, Series, TimelineRow, plot, timeline};
use clap::Args;
use delaynav::replay::session::{ReplayReport, ReplaySetup, table_header};
use delaynav::replay::{FusionRecords, LogReader, SensorEvent};
use delaynav::{DelayCompensatedNav, Navigator};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Flags of `report`.
#[derive(Debug, Clone, Args)]
pub struct ReportArgs {
    #[command(flatten)]
    pub log: LogArgs,
    /// The HTML file to write.
    #[arg(short = 'o', long = "output", value_name = "FILE.html")]
    pub output: PathBuf,
    /// Also write the replay's summary as JSON to this file.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// What the `proposed` navigator's own pass records.
#[derive(Debug, Default)]
struct Recorded {
    /// `(t s, position test ratio, velocity test ratio, both fused)`.
    gps: Vec<(f64, f64, f64, bool)>,
    /// `(t s, test ratio, fused)`.
    mag: Vec<(f64, f64, bool)>,
    /// `(t s, [aligned, tilt, heading, velocity, position, delay])` each second.
    health: Vec<(f64, [bool; 6])>,
}

const HEALTH_ROWS: [&str; 6] = [
    "aligned",
    "tilt valid",
    "heading valid",
    "velocity valid",
    "position valid",
    "delay valid",
];

/// The `proposed` navigator through the replayed window, its fusions and
/// health recorded.
fn record(setup: &ReplaySetup) -> Result<Recorded, Failure> {
    let mut nav = Box::new(DelayCompensatedNav::<f64>::new(setup.nav)?);
    let mut out = Recorded::default();
    let (start, end) = (setup.run.start_us.unwrap_or(0), setup.run.end_us);
    let (mut last_gps, mut last_mag, mut next_health) = (None, None, 0);
    for event in LogReader::<f64>::open(&setup.files, &setup.reader)? {
        let t = event.time_us();
        if t < start {
            continue;
        }
        if end.is_some_and(|e| t > e) {
            break;
        }
        // A refused sample is counted by the navigator (the table's
        // `refused`); the report reads what it fused.
        let _ = match event {
            SensorEvent::Imu(imu) => nav.push_imu(&imu).map(drop),
            SensorEvent::Gps(fix) => nav.push_gps(&fix).map(drop),
            SensorEvent::Mag(mag) => nav.push_mag(&mag).map(drop),
        };
        if let Some((p, v)) = FusionRecords::last_gps_fusion(&*nav)
            && last_gps != Some(p.t_us)
        {
            last_gps = Some(p.t_us);
            out.gps.push((
                p.t_us as f64 * 1e-6,
                p.test_ratio,
                v.test_ratio,
                p.fused && v.fused,
            ));
        }
        if let Some(m) = FusionRecords::last_mag_fusion(&*nav)
            && last_mag != Some(m.t_us)
        {
            last_mag = Some(m.t_us);
            out.mag.push((m.t_us as f64 * 1e-6, m.test_ratio, m.fused));
        }
        if t >= next_health {
            let h = nav.health();
            let aligned = nav.estimate().is_some();
            out.health.push((
                t as f64 * 1e-6,
                [
                    aligned,
                    h.tilt_valid,
                    h.heading_valid,
                    h.velocity_valid,
                    h.position_valid,
                    h.delay_valid,
                ],
            ));
            next_health = t + 1_000_000;
        }
    }
    Ok(out)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// `(t from, t to, on)` segments of a sampled flag.
fn segments(samples: &[(f64, [bool; 6])], k: usize) -> Vec<(f64, f64, bool)> {
    let mut out: Vec<(f64, f64, bool)> = Vec::new();
    for w in samples.windows(2) {
        let (t0, t1, on) = (w[0].0, w[1].0, w[0].1[k]);
        match out.last_mut() {
            Some(last) if last.2 == on => last.1 = t1,
            _ => out.push((t0, t1, on)),
        }
    }
    out
}

/// The page.
fn html(
    report: &ReplayReport,
    traces: &[(String, Vec<delaynav::Estimate<f64>>)],
    recorded: &Recorded,
) -> Result<String, Failure> {
    let setup = &report.setup;
    let s = |t: Option<u64>| t.map(|t| t as f64 * 1e-6);
    let (from, to) = (s(setup.run.score_from_us), s(setup.run.end_us));
    let in_window = |t: f64| from.is_none_or(|f| t >= f) && to.is_none_or(|e| t <= e);
    let reference = setup.reference_attitude_deg()?;
    let mut body = String::new();

    // Title, window, warnings.
    let log = setup
        .options
        .inputs
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let _ = write!(
        body,
        "<h1>Flight report: {}</h1><p class=\"sub\">{} &middot; {} IMU, {} GPS, {} magnetometer records &middot; delaynav {}</p>",
        escape(&log),
        setup.files.format,
        report.scan.counts.imu,
        report.scan.counts.gps,
        report.scan.counts.mag,
        env!("CARGO_PKG_VERSION")
    );
    body.push_str("<h2 id=\"window\">Window</h2><p>");
    match (from, to) {
        (Some(f), Some(t)) => {
            let _ = write!(
                body,
                "Scored {f:.1}-{t:.1} s on the log's clock, replayed from {:.1} s (warm-up, not scored).",
                s(setup.run.start_us).unwrap_or(0.0)
            );
        }
        _ => body.push_str("The whole log is scored (no flight found)."),
    }
    body.push_str("</p>");
    let warnings: Vec<String> = setup.notes.iter().map(|n| n.to_string()).collect();
    body.push_str("<h2 id=\"warnings\">Notes and warnings</h2><ul class=\"notes\">");
    for w in &warnings {
        let class = if w.starts_with("warning") {
            " class=\"warn\""
        } else {
            ""
        };
        let _ = write!(body, "<li{class}>{}</li>", escape(w));
    }
    if warnings.is_empty() {
        body.push_str("<li>none</li>");
    }
    body.push_str("</ul>");

    // The scores.
    body.push_str("<h2 id=\"scores\">Scores against the onboard solution</h2><pre>");
    body.push_str(&escape(&table_header()));
    body.push('\n');
    for e in &report.estimators {
        body.push_str(&escape(&e.table_row()));
        body.push('\n');
    }
    body.push_str("</pre>");

    // Attitude against the onboard solution.
    body.push_str("<h2 id=\"attitude\">Attitude against the onboard solution</h2>");
    if reference.is_none() {
        body.push_str("<p>The log has no onboard attitude: the estimators alone.</p>");
    }
    for (axis, name) in ["roll", "pitch", "yaw"].iter().enumerate() {
        // Yaw is unwrapped (no jump at +-180 deg), each estimator on the
        // reference's turn where there is one.
        let yaw = *name == "yaw";
        let onboard: Option<Vec<(f64, f64)>> = reference.as_ref().map(|r| {
            let mut points: Vec<(f64, f64)> = r
                .iter()
                .map(|r| (r[0], r[axis + 1]))
                .filter(|(t, _)| in_window(*t))
                .collect();
            if yaw {
                unwrap_deg(&mut points, None);
            }
            points
        });
        let first_onboard = onboard.as_ref().and_then(|o| o.first().map(|p| p.1));
        let mut series: Vec<Series> = traces
            .iter()
            .enumerate()
            .map(|(k, (estimator, trace))| {
                let mut points: Vec<(f64, f64)> = trace
                    .iter()
                    .map(|e| (e.t_us as f64 * 1e-6, setup.aligned_euler_deg(e)[axis]))
                    .filter(|(t, _)| in_window(*t))
                    .collect();
                if yaw {
                    unwrap_deg(&mut points, first_onboard);
                }
                Series::line(estimator, COLOURS[k % COLOURS.len()], points)
            })
            .collect();
        if let Some(points) = onboard {
            series.push(Series::line("onboard", "#000000", points));
        }
        let title = if yaw {
            "yaw, degrees (unwrapped)".to_string()
        } else {
            format!("{name}, degrees")
        };
        body.push_str(&plot(
            &format!("attitude-{name}"),
            &title,
            "time on the log's clock, s",
            "degrees",
            &series,
            &[],
            false,
        ));
    }

    // The delay with its sigma and status.
    body.push_str("<h2 id=\"delay\">GPS delay</h2>");
    let mut delay_series = Vec::new();
    let mut statuses: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (k, e) in report.estimators.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let windows = &e.summary.delay_windows;
        if !windows.is_empty() {
            let mut s = Series::line(
                e.estimator.name,
                colour,
                windows.iter().map(|w| (w.t_s, w.delay_s)).collect(),
            );
            s.band = windows
                .iter()
                .filter(|w| w.delay_std_s.is_finite())
                .map(|w| (w.t_s, w.delay_s - w.delay_std_s, w.delay_s + w.delay_std_s))
                .collect();
            delay_series.push(s);
            for w in windows {
                match statuses.iter_mut().find(|(name, _)| *name == w.status) {
                    Some((_, points)) => points.push((w.t_s, w.delay_s)),
                    None => statuses.push((w.status.clone(), vec![(w.t_s, w.delay_s)])),
                }
            }
        } else if !e.summary.delay_track.is_empty() {
            delay_series.push(Series::line(
                e.estimator.name,
                colour,
                e.summary.delay_track.clone(),
            ));
        }
    }
    if delay_series.is_empty() {
        body.push_str("<p>No estimator with a delay estimate was run.</p>");
    } else {
        body.push_str(
            "<p>Each delay-loop update (one correlation window) with &plusmn;1 sigma shaded; \
             estimators without a loop: their delay every second.</p>",
        );
        body.push_str(&plot(
            "delay",
            "estimated GPS delay, s",
            "time on the log's clock, s",
            "s",
            &delay_series,
            &[],
            false,
        ));
    }
    if !statuses.is_empty() {
        let series: Vec<Series> = statuses
            .iter()
            .enumerate()
            .map(|(k, (name, points))| {
                let mut s = Series::line(name, COLOURS[(k + 2) % COLOURS.len()], points.clone());
                s.dots = true;
                s
            })
            .collect();
        body.push_str(&plot(
            "delay-status",
            "the delay loop's status after each update (proposed)",
            "time on the log's clock, s",
            "delay, s",
            &series,
            &[],
            false,
        ));
    }

    // Innovations and gates.
    body.push_str(
        "<h2 id=\"innovations\">Innovations against their gates (proposed)</h2>\
         <p>Normalized innovation squared divided by the gate's chi-square threshold: above 1 \
         the measurement is rejected.</p>",
    );
    let gps_pos = recorded.gps.iter().map(|g| (g.0, g.1)).collect();
    let gps_vel = recorded.gps.iter().map(|g| (g.0, g.2)).collect();
    body.push_str(&plot(
        "innovations-gps",
        "GPS test ratios",
        "time on the log's clock, s",
        "test ratio",
        &[
            Series::line("position", COLOURS[0], gps_pos),
            Series::line("velocity", COLOURS[1], gps_vel),
        ],
        &[(1.0, "gate")],
        false,
    ));
    let mag = recorded.mag.iter().map(|m| (m.0, m.1)).collect();
    body.push_str(&plot(
        "innovations-mag",
        "magnetometer test ratio",
        "time on the log's clock, s",
        "test ratio",
        &[Series::line("magnetometer", COLOURS[2], mag)],
        &[(1.0, "gate")],
        false,
    ));
    let rejected = recorded.gps.iter().filter(|g| !g.3).count();
    let mag_rejected = recorded.mag.iter().filter(|m| !m.2).count();
    let _ = write!(
        body,
        "<p>{} GPS fusions, {rejected} with a block rejected; {} magnetometer fusions, {mag_rejected} rejected.</p>",
        recorded.gps.len(),
        recorded.mag.len()
    );

    // Health.
    body.push_str("<h2 id=\"health\">Health timeline (proposed)</h2>");
    let rows: Vec<TimelineRow> = HEALTH_ROWS
        .iter()
        .enumerate()
        .map(|(k, name)| (name.to_string(), segments(&recorded.health, k)))
        .collect();
    body.push_str(&timeline("health", "what the navigator vouches for", &rows));
    let _ = write!(
        body,
        "<p>Coloured: valid; grey: not.</p><pre>{}</pre>",
        escape(&report.health())
    );

    // Track.
    body.push_str("<h2 id=\"track\">Track</h2>");
    let tracks: Vec<Series> = traces
        .iter()
        .enumerate()
        .map(|(k, (name, trace))| {
            let points = trace
                .iter()
                .filter(|e| in_window(e.t_us as f64 * 1e-6))
                .map(|e| (e.position_ned_m.y, e.position_ned_m.x))
                .collect();
            Series::line(name, COLOURS[k % COLOURS.len()], points)
        })
        .collect();
    body.push_str(&plot(
        "track",
        "position, north against east, metres from the first fix",
        "east, m",
        "north, m",
        &tracks,
        &[],
        true,
    ));

    // Derived defaults.
    let _ = write!(
        body,
        "<h2 id=\"defaults\">Defaults derived from the log</h2><pre>{}</pre>\
         <h2 id=\"log\">Records read and skipped</h2><pre>{}\n{}</pre>",
        escape(&setup.derived.to_string()),
        escape(&setup.log_line(&report.scan)),
        escape(&report.scan.skips.to_string())
    );

    Ok(format!(
        r##"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>delaynav flight report</title>
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 1.5em auto; max-width: 960px; color: #222; }}
h1 {{ font-size: 1.4em; margin-bottom: 0; }} h2 {{ font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }}
.sub {{ color: #666; margin-top: 0.2em; }} pre {{ background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 12px; }}
li.warn {{ color: #a40; }} nav a {{ margin-right: 0.8em; }}
svg.plot {{ display: block; margin: 0.6em 0; max-width: 100%; height: auto; }}
svg .title {{ font-size: 13px; font-weight: 600; }} svg .axes {{ fill: none; stroke: #999; }}
svg .tick {{ stroke: #999; }} svg .grid {{ stroke: #eee; }} svg .xt {{ font-size: 11px; text-anchor: middle; }}
svg .yt {{ font-size: 11px; text-anchor: end; }} svg .xl, svg .yl {{ font-size: 12px; text-anchor: middle; }}
svg .lg {{ font-size: 12px; }} svg .gate {{ stroke: #a40; stroke-dasharray: 4 3; }} svg .gl {{ font-size: 11px; fill: #a40; }}
svg rect.on {{ fill: #2ca02c; }} svg rect.off {{ fill: #ccc; }}
</style></head>
<body>
<nav><a href="#window">window</a><a href="#scores">scores</a><a href="#attitude">attitude</a><a href="#delay">delay</a><a href="#innovations">innovations</a><a href="#health">health</a><a href="#track">track</a><a href="#defaults">defaults</a></nav>
{body}
</body></html>
"##
    ))
}

/// `delaynav report`.
pub fn main(args: &ReportArgs) -> Result<(), Failure> {
    let opened = open(&args.log, true)?;
    let recorded = record(&opened.setup)?;
    let mut console = Console::new(args.log.quiet, true);
    let report = run(opened, "all", &mut console)?;
    print!("{report}");
    let page = html(&report, &console.traces, &recorded)?;
    if let Some(parent) = args.output.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::write(&args.output, page)?;
    eprintln!("report written to {}", args.output.display());
    if let Some(path) = &args.json {
        crate::replay::write_json(path, &report.to_json())?;
    }
    Ok(())
}

/// Makes an angle series (degrees) continuous: each point moved by whole
/// turns to within 180 deg of the one before; the first point moved to
/// within 180 deg of `near` when given (an estimator onto the reference's
/// turn).
fn unwrap_deg(points: &mut [(f64, f64)], near: Option<f64>) {
    let Some(first) = points.first().map(|p| p.1) else {
        return;
    };
    let mut previous = match near {
        Some(n) if n.is_finite() && first.is_finite() => {
            first + 360.0 * ((n - first) / 360.0).round()
        }
        _ => first,
    };
    for p in points.iter_mut() {
        if !(p.1.is_finite() && previous.is_finite()) {
            continue;
        }
        p.1 += 360.0 * ((previous - p.1) / 360.0).round();
        previous = p.1;
    }
}

#[cfg(test)]
mod tests {
    use super::unwrap_deg;

    #[test]
    fn yaw_is_unwrapped_across_180_and_put_on_the_reference_turn() {
        let mut yaw = vec![(0.0, 170.0), (1.0, 179.0), (2.0, -178.0), (3.0, -170.0)];
        unwrap_deg(&mut yaw, None);
        assert_eq!(
            yaw.iter().map(|p| p.1).collect::<Vec<_>>(),
            [170.0, 179.0, 182.0, 190.0]
        );
        let mut estimator = vec![(0.0, -175.0), (1.0, 175.0)];
        unwrap_deg(&mut estimator, Some(540.0));
        assert_eq!(
            estimator.iter().map(|p| p.1).collect::<Vec<_>>(),
            [545.0, 535.0]
        );
        let mut gap = vec![(0.0, 10.0), (1.0, f64::NAN), (2.0, 350.0)];
        unwrap_deg(&mut gap, None);
        assert_eq!(gap[2].1, -10.0);
    }
}

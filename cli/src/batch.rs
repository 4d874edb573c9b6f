//! `delaynav batch DIR`: every log under DIR replayed with the defaults
//! derived from it, in parallel on all cores (rayon), one row per log in a
//! CSV and a JSON table. A log that cannot be read is a row with its error,
//! never a stop: the command exits 0 and counts the failures.
//!
//! The logs: every `.bin` and `.ulg` file, and every folder holding a CSV
//! log (`imu.csv`, or a PX4 `*_sensor_combined_<n>.csv`), searched
//! recursively. A folder holding both a `.bin` and its CSV export gives two
//! rows.

use crate::Failure;
use crate::replay::write_json;
use clap::Args;
use delaynav::replay::session::{ReplayOptions, ReplayReport, ReplaySetup, select_estimators};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Flags of `batch`.
#[derive(Debug, Clone, Args)]
pub struct BatchArgs {
    /// The folder searched (recursively) for logs.
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,
    /// Write the table as JSON to this file.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write the table as CSV to this file.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Logs replayed at once, 1 to 256 (default: every core).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=256))]
    pub jobs: Option<u16>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Whether `dir` holds a CSV log.
fn is_csv_log(dir: &Path) -> bool {
    dir.join("imu.csv").is_file()
        || std::fs::read_dir(dir).is_ok_and(|entries| {
            entries.flatten().any(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.contains("_sensor_combined_") && name.ends_with(".csv")
            })
        })
}

/// The logs under `dir`, sorted.
pub fn find_logs(dir: &Path) -> Result<Vec<PathBuf>, Failure> {
    let mut logs = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        if is_csv_log(&d) {
            logs.push(d.clone());
        }
        let entries = std::fs::read_dir(&d).map_err(|e| format!("{}: {e}", d.display()))?;
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("bin") || x.eq_ignore_ascii_case("ulg"))
            {
                logs.push(path);
            }
        }
    }
    logs.sort();
    Ok(logs)
}

/// One log replayed: its report, or its error.
fn replay_one(path: &Path) -> Result<ReplayReport, String> {
    let options = ReplayOptions::new([path]);
    let setup = ReplaySetup::from_log(&options).map_err(|e| e.to_string())?;
    let scan = setup.scan().map_err(|e| e.to_string())?;
    let estimators = select_estimators("all").map_err(|e| e.to_string())?;
    setup
        .run(scan, &estimators, &mut ())
        .map_err(|e| e.to_string())
}

/// A row of the table.
fn row(path: &Path, outcome: &Result<ReplayReport, String>, wall_s: f64) -> Value {
    let mut row = json!({"file": path.display().to_string(), "wall_time_s": wall_s});
    let report = match outcome {
        Ok(r) => r,
        Err(e) => {
            row["error"] = json!(e);
            return row;
        }
    };
    let setup = &report.setup;
    let s = |t: Option<u64>| t.map(|t| t as f64 * 1e-6);
    row["error"] = Value::Null;
    row["format"] = json!(setup.files.format.to_string());
    row["vehicle_window_s"] = setup.window.map_or(Value::Null, |w| {
        json!([w.from_us as f64 * 1e-6, w.to_us as f64 * 1e-6])
    });
    row["scored_window_s"] = json!([s(setup.run.score_from_us), s(setup.run.end_us)]);
    for e in &report.estimators {
        let summary = &e.summary;
        let last = summary.delay_windows.last();
        let rms = summary.reference_rms;
        row[e.estimator.name] = json!({
            "delay_s": summary.final_delay_s,
            "delay_std_s": last.map(|w| w.delay_std_s),
            "delay_status": last.map(|w| w.status.clone()),
            "roll_rms_deg": rms.map(|r| r.roll_deg),
            "pitch_rms_deg": rms.map(|r| r.pitch_deg),
            "yaw_rms_deg": rms.map(|r| r.yaw_deg),
            "health": e.health.to_json(),
        });
    }
    row
}

/// The CSV's columns: the row's keys, the `proposed` and `ekf16` figures
/// flattened.
const COLUMNS: [&str; 14] = [
    "file",
    "error",
    "format",
    "window_from_s",
    "window_to_s",
    "proposed.delay_s",
    "proposed.delay_std_s",
    "proposed.delay_status",
    "proposed.roll_rms_deg",
    "proposed.pitch_rms_deg",
    "proposed.yaw_rms_deg",
    "proposed.health.alignment",
    "ekf16.yaw_rms_deg",
    "wall_time_s",
];

/// A CSV cell of `row` for `column`.
fn cell(row: &Value, column: &str) -> String {
    let value = match column {
        "window_from_s" => &row["vehicle_window_s"][0],
        "window_to_s" => &row["vehicle_window_s"][1],
        _ => column.split('.').fold(row, |v, key| &v[key]),
    };
    let text = match value {
        Value::Null => String::new(),
        Value::String(s) => s.clone(),
        Value::Number(n) => n
            .as_f64()
            .map_or_else(|| n.to_string(), |f| format!("{f:.4}")),
        v => v.to_string(),
    };
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text
    }
}

/// The table as CSV.
fn to_csv(rows: &[Value]) -> String {
    let mut out = COLUMNS.join(",") + "\n";
    for r in rows {
        let cells: Vec<String> = COLUMNS.iter().map(|c| cell(r, c)).collect();
        out += &(cells.join(",") + "\n");
    }
    out
}

/// `delaynav batch`.
pub fn main(args: &BatchArgs) -> Result<(), Failure> {
    let logs = find_logs(&args.dir)?;
    if logs.is_empty() {
        return Err(format!(
            "no log (.bin, .ulg, CSV folder) under {}",
            args.dir.display()
        )
        .into());
    }
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(logs.len() as u64)
    };
    if let Ok(style) = ProgressStyle::with_template("[{wide_bar}] {pos}/{len} logs ({eta} left)") {
        bar.set_style(style);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.map_or(0, usize::from))
        .build()?;
    let rows: Vec<Value> = pool.install(|| {
        logs.par_iter()
            .map(|path| {
                let started = Instant::now();
                // A panic is a bug, but still one row, not a stop.
                let outcome = std::panic::catch_unwind(|| replay_one(path)).unwrap_or_else(|_| {
                    Err("the replay panicked (a bug: please report it)".into())
                });
                let row = row(path, &outcome, started.elapsed().as_secs_f64());
                bar.inc(1);
                row
            })
            .collect()
    });
    bar.finish_and_clear();
    let failed = rows.iter().filter(|r| !r["error"].is_null()).count();
    print!("{}", to_csv(&rows));
    eprintln!(
        "{} logs, {} replayed, {failed} failed to read",
        rows.len(),
        rows.len() - failed
    );
    if let Some(path) = &args.csv {
        std::fs::write(path, to_csv(&rows))?;
        eprintln!("table written to {}", path.display());
    }
    if let Some(path) = &args.json {
        write_json(
            path,
            &json!({"dir": args.dir.display().to_string(), "logs": rows.len(), "failed": failed, "rows": rows}),
        )?;
        eprintln!("table written to {}", path.display());
    }
    Ok(())
}

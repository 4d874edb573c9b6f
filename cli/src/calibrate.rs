//! `delaynav calibrate`: the offline delay calibration of a log
//! (`delaynav::delay::OfflineCalibrator`, the paper's sec. 2.2.2) over the
//! replayed window: the delay, the peak correlation, each axis' peak, and
//! the correlation curve.

use crate::Failure;
use crate::args::LogArgs;
use crate::replay::{open, write_json};
use clap::Args;
use delaynav::delay::{CalibrationConfig, DefaultCalibrator};
use delaynav::replay::{LogReader, SensorEvent};
use serde_json::{Value, json};
use std::path::PathBuf;

/// Flags of `calibrate`.
#[derive(Debug, Clone, Args)]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub log: LogArgs,
    /// Write the result and the curve as JSON to this file.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

/// The calibration of a log: what `calibrate` prints and writes.
#[derive(Debug, Clone, PartialEq)]
pub struct LogCalibration {
    /// The record calibrated, seconds on the log's clock.
    pub record_s: (f64, f64),
    /// The result, or why there is none.
    pub result: Result<delaynav::delay::Calibration<f64>, String>,
    /// `(shift s, R, pairs)` for every shift.
    pub curve: Vec<(f64, f64, usize)>,
}

impl LogCalibration {
    /// The JSON: `record_s`, `delay_s`, `peak`, `pairs`, `refused`,
    /// `axes` (`peak`, `shift_s`, `interior` north, east, down), `error`,
    /// `curve` (`[shift s, R, pairs]`).
    pub fn to_json(&self, period_s: f64) -> Value {
        let mut v = json!({
            "record_s": [self.record_s.0, self.record_s.1],
            "curve": self.curve.iter().map(|&(s, r, n)| json!([s, r, n])).collect::<Vec<_>>(),
        });
        match &self.result {
            Ok(c) => {
                v["delay_s"] = json!(c.delay_s);
                v["peak"] = json!(c.peak);
                v["pairs"] = json!(c.pairs);
                v["refused"] = json!(c.refused);
                v["axes"] = c
                    .axes
                    .iter()
                    .map(|a| {
                        json!({"peak": a.peak, "shift_s": a.shift_samples * period_s,
                               "interior": a.interior})
                    })
                    .collect();
            }
            Err(e) => v["error"] = json!(e),
        }
        v
    }
}

/// Calibrates the IMU and GPS of `reader`'s events between `from_us` and
/// `to_us`.
pub fn calibrate(
    events: impl Iterator<Item = SensorEvent<f64>>,
    from_us: u64,
    to_us: Option<u64>,
) -> Result<LogCalibration, Failure> {
    let mut calibrator = Box::new(DefaultCalibrator::<f64>::new(CalibrationConfig::default())?);
    let mut refused = 0;
    let mut last_us = from_us;
    for event in events {
        let t = event.time_us();
        if t < from_us {
            continue;
        }
        if to_us.is_some_and(|end| t > end) {
            break;
        }
        last_us = t;
        let outcome = match event {
            SensorEvent::Imu(imu) => calibrator.push_imu(&imu),
            SensorEvent::Gps(fix) => calibrator.push_gps(&fix),
            SensorEvent::Mag(_) => Ok(()),
        };
        refused += usize::from(outcome.is_err());
    }
    let result = calibrator
        .result()
        .map(|mut c| {
            c.refused = refused;
            c
        })
        .map_err(|e| e.to_string());
    Ok(LogCalibration {
        record_s: (from_us as f64 * 1e-6, last_us as f64 * 1e-6),
        result,
        curve: calibrator.curve().collect(),
    })
}

/// `delaynav calibrate`.
pub fn main(args: &CalibrateArgs) -> Result<(), Failure> {
    let opened = open(&args.log, true)?;
    let setup = &opened.setup;
    let events = LogReader::<f64>::open(&setup.files, &setup.reader)?;
    let c = calibrate(events, setup.run.start_us.unwrap_or(0), setup.run.end_us)?;
    let period_s = 1.0 / CalibrationConfig::<f64>::default().correlation_rate_hz;
    println!(
        "offline calibration over {:.1}-{:.1} s of the log (+-6 s of shifts, 50 Hz grid):",
        c.record_s.0, c.record_s.1
    );
    match &c.result {
        Ok(r) => {
            println!(
                "  delay {:.3} s, peak correlation {:.3} ({} pairs at the peak, {} samples refused)",
                r.delay_s, r.peak, r.pairs, r.refused
            );
            for (axis, a) in ["north", "east", "down"].iter().zip(&r.axes) {
                println!(
                    "  {axis:>5}: peak {:.3} at {:.3} s{}",
                    a.peak,
                    a.shift_samples * period_s,
                    if a.interior {
                        ""
                    } else {
                        " (on the edge of the shifts: no peak)"
                    }
                );
            }
        }
        Err(e) => println!("  no result: {e}"),
    }
    if let Some(path) = &args.json {
        write_json(path, &c.to_json(period_s))?;
        eprintln!("calibration written to {}", path.display());
    }
    Ok(())
}

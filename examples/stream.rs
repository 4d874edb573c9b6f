//! Streams a log's records, in the reader's order, through one
//! delay-compensated navigator (`f64`) built from a configuration merged
//! over the defaults, and writes the estimate after every IMU sample: the
//! Rust side the Python package's streaming `Navigator` is checked against,
//! sample by sample (`python/tests`), and the per-sample loop its
//! `push_imu_array` is timed against (`python/bench/speed.py`).
//!
//! ```text
//! cargo run --release --features replay --example stream -- \
//!     ../shared/data/ardupilot-log171/log171.bin --config nav.toml --out estimates.csv
//! cargo run --release --features replay --example stream -- \
//!     ../shared/data/ardupilot-log171/log171.bin --imu-only --repeat 20
//! ```
//!
//! - `--config FILE`: TOML merged over `DelayCompensatedNavConfig::default()`
//!   (`delaynav::replay::config_file::merge_config`; a missing file: the
//!   defaults).
//! - `--out CSV`: after each IMU sample, `t_us` then the estimate's attitude
//!   (w, x, y, z), position and velocity NED, accelerometer and gyro biases,
//!   covariance diagonal, delay and its sigma; `NaN` before the first
//!   estimate or for a delay the estimator does not have. Numbers are
//!   written in Rust's shortest round-trip form: read back they are the
//!   same `f64`.
//! - `--imu-only`: push the IMU samples alone (no GPS, no magnetometer),
//!   `--repeat N` times with a fresh navigator, and print the median
//!   nanoseconds per sample of the loop (the records read beforehand).
//!   A refused sample (an error) is counted and the stream goes on.

use delaynav::replay::config_file::merge_config;
use delaynav::replay::{LogReader, ReaderOptions, SensorEvent};
use delaynav::{DelayCompensatedNav, DelayCompensatedNavConfig, Estimate, Imu, Navigator};
use std::error::Error;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

/// The estimate after a sample as CSV fields (see the module docs).
fn row(t_us: u64, e: Option<&Estimate<f64>>) -> String {
    let Some(e) = e else {
        return format!("{t_us}{}", ",NaN".repeat(34));
    };
    let q = e.attitude.quaternion();
    let mut fields = vec![q.w, q.i, q.j, q.k];
    for v in [
        &e.position_ned_m,
        &e.velocity_ned_m_s,
        &e.accel_bias_m_s2,
        &e.gyro_bias_rad_s,
    ] {
        fields.extend(v.iter());
    }
    fields.extend(e.covariance_diagonal.iter());
    fields.push(e.delay_s.unwrap_or(f64::NAN));
    fields.push(e.delay_std_s.unwrap_or(f64::NAN));
    let text: Vec<String> = fields.iter().map(|x| format!("{x:?}")).collect();
    format!("{},{}", e.t_us, text.join(","))
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let (mut log, mut config, mut out, mut imu_only, mut repeat) =
        (None, None, None, false, 1usize);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--config" => config = args.next().map(PathBuf::from),
            "--out" => out = args.next().map(PathBuf::from),
            "--imu-only" => imu_only = true,
            "--repeat" => repeat = args.next().ok_or("--repeat N")?.parse()?,
            _ if log.is_none() => log = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument `{a}`").into()),
        }
    }
    let log =
        log.ok_or("usage: stream LOG [--config FILE] [--out CSV] [--imu-only] [--repeat N]")?;
    let text = match &config {
        Some(path) => std::fs::read_to_string(path)?,
        None => String::new(),
    };
    let config = merge_config(DelayCompensatedNavConfig::default(), &text)?;
    let events: Vec<SensorEvent<f64>> =
        LogReader::<f64>::open_paths(&[log], None, &ReaderOptions::default())?.collect();

    if imu_only {
        let imu: Vec<Imu<f64>> = events
            .iter()
            .filter_map(|e| match e {
                SensorEvent::Imu(s) => Some(*s),
                _ => None,
            })
            .collect();
        let mut per_sample_ns = Vec::new();
        let mut refused = 0usize;
        for _ in 0..repeat.max(1) {
            let mut nav = Box::new(DelayCompensatedNav::<f64>::new(config)?);
            let started = Instant::now();
            for s in &imu {
                refused += usize::from(nav.push_imu(s).is_err());
            }
            per_sample_ns.push(started.elapsed().as_nanos() as f64 / imu.len().max(1) as f64);
            std::hint::black_box(nav.estimate());
        }
        per_sample_ns.sort_by(f64::total_cmp);
        println!(
            "{} IMU samples, {} runs, median {:.1} ns per sample, min {:.1} ns, {refused} refused",
            imu.len(),
            per_sample_ns.len(),
            per_sample_ns[per_sample_ns.len() / 2],
            per_sample_ns[0]
        );
        return Ok(());
    }

    let mut nav = Box::new(DelayCompensatedNav::<f64>::new(config)?);
    let mut writer = match &out {
        Some(path) => Some(BufWriter::new(std::fs::File::create(path)?)),
        None => None,
    };
    let (mut samples, mut refused) = (0usize, 0usize);
    for event in &events {
        let ok = match event {
            SensorEvent::Imu(s) => nav.push_imu(s).is_ok(),
            SensorEvent::Gps(g) => nav.push_gps(g).is_ok(),
            SensorEvent::Mag(m) => nav.push_mag(m).is_ok(),
        };
        refused += usize::from(!ok);
        if let SensorEvent::Imu(s) = event {
            samples += 1;
            if let Some(w) = writer.as_mut() {
                writeln!(w, "{}", row(s.t_us, nav.estimate().as_ref()))?;
            }
        }
    }
    if let Some(w) = writer.as_mut() {
        w.flush()?;
    }
    eprintln!("{samples} IMU samples streamed, {refused} records refused with an error");
    Ok(())
}

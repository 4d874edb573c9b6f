//! `--delay-suite` and `--delay-trace`: the flags mapped to
//! `delaynav::sim::suite::delay`'s options, its rows printed as they end, its
//! JSON written and judged; a row's trace written as CSV with its figures on
//! stderr.

use super::{Args, enforce, write_json};
use delaynav::sim::suite::ProgressFn;
use delaynav::sim::suite::delay::{
    self, DelayOptions, EXTRA_TRACES, HoverSetup, LoopTuning, ROW_NAMES, TRACE_ROWS, TraceOptions,
};
use std::error::Error;
use std::io::Write as _;
use std::path::PathBuf;

/// The delay suite's and the traces' flags (in `Args`, `--delay-trace` to
/// `--delay-measurement-noise`).
#[derive(Debug, clap::Args)]
pub struct DelayFlags {
    /// Write a per-second trace of the delay suite's row ROW (seed --seed,
    /// with --delay-rate-std / --delay-rate-time-constant) as CSV to --csv
    /// (a file here) [default: target/delay-trace/ROW-seedS.csv];
    /// `aekf17_hover` traces AEKF17 (--duration sets the hover's length);
    /// `calibrated_low` and `calibrated_high` trace the runs of
    /// `sigma_coverage`.
    #[arg(long, value_name = "ROW")]
    delay_trace: Option<String>,
    /// With --delay-trace aekf17_hover: AEKF17's `delay_random_walk` [default: its own].
    #[arg(long, value_name = "S_PER_SQRT_S")]
    aekf17_delay_random_walk: Option<f64>,
    /// With --delay-trace aekf17_hover: AEKF17's `accel_smoothing_s` (0: the
    /// paper's last sample) [default: its own].
    #[arg(long, value_name = "S")]
    aekf17_accel_smoothing: Option<f64>,
    /// With --delay-trace: two more delay loops beside the navigator's, fed
    /// the oracle navigator's acceleration and the true acceleration plus
    /// the accelerometer's noise (their estimates as two more columns, the
    /// three RMSEs from 20 s printed).
    #[arg(long)]
    compare_accel: bool,
    /// With --delay-suite or --integrity: only these rows (comma-separated names) [default: all].
    #[arg(long, value_delimiter = ',', value_name = "ROW,...")]
    rows: Option<Vec<String>>,
    /// With --delay-suite or --delay-trace: the drift-rate state of the `proposed` navigator's
    /// delay loop on, `GainFusionConfig::rate_std` in ms/s, in every row
    /// [default: the loop's, off].
    #[arg(long, value_name = "MS_PER_S")]
    delay_rate_std: Option<f64>,
    /// With --delay-suite or --delay-trace: `GainFusionConfig::rate_time_constant_s`, s, in
    /// every row [default: the loop's].
    #[arg(long, value_name = "S")]
    delay_rate_time_constant: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `process_noise_ms2_per_s` (`q`), ms^2/s, in every row [default: the loop's].
    #[arg(long, value_name = "MS2_PER_S")]
    delay_process_noise: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_window_s` (the horizon innovations' observation), s; 0
    /// turns it off [default: the loop's].
    #[arg(long, value_name = "S")]
    delay_innovation_window: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_noise_scale` [default: the loop's].
    #[arg(long, value_name = "FACTOR")]
    delay_innovation_noise_scale: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_reacquire_sigma` (0: off) [default: the loop's].
    #[arg(long, value_name = "SIGMA")]
    delay_innovation_reacquire_sigma: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_before_lock` on (fuse the innovation windows before
    /// lock too, each when it agrees with the previous one).
    #[arg(long)]
    delay_innovation_before_lock: bool,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `acquisition_motion_exponent` (1 to 4) [default: the loop's].
    #[arg(long, value_name = "EXPONENT")]
    delay_acquisition_exponent: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `smoothing_cutoff_hz` (both accelerations' common low-pass), Hz
    /// [default: the loop's; `adapted_to_gps_rate` rows set their own].
    #[arg(long, value_name = "HZ")]
    delay_smoothing_cutoff: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_acquire_noise_scale` [default: the loop's].
    #[arg(long, value_name = "FACTOR")]
    delay_innovation_acquire_noise_scale: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `measurement_noise_ms2` (the correlation peaks'), ms^2, every axis
    /// [default: the loop's].
    #[arg(long, value_name = "MS2")]
    delay_measurement_noise: Option<f64>,
}

impl DelayFlags {
    /// `--delay-trace`: the row to trace.
    pub fn trace_row(&self) -> Option<&str> {
        self.delay_trace.as_deref()
    }

    /// `--rows`: only these rows.
    pub fn rows(&self) -> Option<&[String]> {
        self.rows.as_deref()
    }
}

/// The delay loop's changes that the `--delay-*` flags ask for.
pub fn tuning(args: &Args) -> LoopTuning {
    LoopTuning {
        rate_std: args
            .delay_flags
            .delay_rate_std
            .map(|ms_per_s| ms_per_s * 1e-3),
        rate_time_constant_s: args.delay_flags.delay_rate_time_constant,
        process_noise_ms2_per_s: args.delay_flags.delay_process_noise,
        innovation_window_s: args.delay_flags.delay_innovation_window,
        innovation_noise_scale: args.delay_flags.delay_innovation_noise_scale,
        innovation_reacquire_sigma: args.delay_flags.delay_innovation_reacquire_sigma,
        innovation_before_lock: args.delay_flags.delay_innovation_before_lock,
        innovation_acquire_noise_scale: args.delay_flags.delay_innovation_acquire_noise_scale,
        measurement_noise_ms2: args.delay_flags.delay_measurement_noise,
        acquisition_motion_exponent: args.delay_flags.delay_acquisition_exponent,
        smoothing_cutoff_hz: args.delay_flags.delay_smoothing_cutoff,
    }
}

/// The suite's options: `seeds_n` seeds from `--seed`, `--rows`, the loop's
/// tuning; an error names a row the suite does not have.
pub fn options(args: &Args, seeds_n: u64) -> Result<DelayOptions, String> {
    let mut options = DelayOptions::full(args.seed, seeds_n);
    if let Some(names) = &args.delay_flags.rows {
        if let Some(n) = names.iter().find(|n| delay::row_name(n).is_none()) {
            return Err(format!(
                "--rows: no row {n:?} (rows: {})",
                ROW_NAMES.join(", ")
            ));
        }
        options.rows = Some(names.clone());
    }
    options.tuning = tuning(args);
    options.filter_rate_hz = args.filter_rate_hz;
    Ok(options)
}

/// `--delay-suite`: runs the rows, writes the JSON, judges it with `--check`.
pub fn run(args: &Args, seeds_n: u64, progress: ProgressFn) -> Result<(), Box<dyn Error>> {
    let options = options(args, seeds_n)?;
    let result = delay::run(&options, progress)?;
    write_json(&args.json, &result.to_json())?;
    if args.check {
        enforce(&result.verdicts(), &args.known_failures)?;
    }
    Ok(())
}

/// Where `--delay-trace` writes (its directory created).
fn trace_path(args: &Args) -> std::io::Result<PathBuf> {
    let row = args.delay_flags.delay_trace.as_deref().unwrap_or("trace");
    let path = args.csv.clone().unwrap_or_else(|| {
        PathBuf::from(format!("target/delay-trace/{row}-seed{}.csv", args.seed))
    });
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    Ok(path)
}

/// `--delay-trace ROW`: the row's run on `--seed` as CSV, its figures on stderr.
pub fn trace(args: &Args) -> Result<(), Box<dyn Error>> {
    let row = args.delay_flags.delay_trace.clone().unwrap_or_default();
    let seed = args.seed;
    let path = trace_path(args)?;
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
    if row == "aekf17_hover" {
        let setup = HoverSetup {
            duration_s: args.duration,
            delay_random_walk: args.delay_flags.aekf17_delay_random_walk,
            accel_smoothing_s: args.delay_flags.aekf17_accel_smoothing,
        };
        let end = delay::write_hover_trace(seed, &setup, &mut out)?;
        out.flush()?;
        eprintln!(
            "aekf17_hover seed {seed}: final estimate {:.4} s, sigma {:.4} s, ratio {:.4}, {} clamps",
            end.estimate_s, end.sigma_s, end.ratio, end.clamps
        );
        eprintln!("wrote {} rows to {}", end.rows, path.display());
        return Ok(());
    }
    let options = TraceOptions {
        row: row.clone(),
        seed,
        tuning: tuning(args),
        compare_accel: args.delay_flags.compare_accel,
        filter_rate_hz: args.filter_rate_hz,
    };
    let Some(summary) = delay::write_trace(&options, &mut out)? else {
        return Err(format!(
            "--delay-trace: no navigator trace for {row:?} (rows: {}, {})",
            TRACE_ROWS.join(", "),
            EXTRA_TRACES.join(", ")
        )
        .into());
    };
    out.flush()?;
    for (estimate, rmse_ms) in &summary.rmse_ms {
        eprintln!("{row} seed {seed}: {estimate} delay RMSE from 20 s {rmse_ms:.4} ms");
    }
    eprintln!(
        "{row} seed {seed}: information bound (Cramér-Rao from every GPS velocity since the start), RMS from 20 s {:.4} ms",
        summary.information_bound_ms
    );
    eprintln!(
        "{row} seed {seed}: navigator error within its reported 1-sigma from 20 s: {:.3} of the time",
        summary.sigma_coverage
    );
    let (far, valid) = summary.valid_but_far;
    eprintln!(
        "{row} seed {seed}: delay_valid with |error| > 3 sigma: {far} of {valid} points (10 ms apart, from the start)"
    );
    eprintln!("wrote {} rows to {}", summary.rows, path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The flags reach the library's options (the suites themselves are tested in
    //! `src/sim/suite` and `tests/delay_suite.rs`).

    use super::*;
    use clap::Parser;

    fn parse(flags: &[&str]) -> Args {
        Args::try_parse_from(std::iter::once("reproduce").chain(flags.iter().copied()))
            .expect("the flags parse")
    }

    /// `--rows`, `--delay-rate-std` (ms/s), `--delay-rate-time-constant`,
    /// `--delay-process-noise` and `--filter-rate-hz` reach the suite's options and its JSON;
    /// a row the suite does not have is refused with the list.
    #[test]
    fn suite_flags_reach_the_options() {
        let args = parse(&[
            "--delay-suite",
            "--rows",
            "delay_step,aekf17_hover",
            "--seed",
            "3",
            "--delay-rate-std",
            "2",
            "--delay-rate-time-constant",
            "300",
            "--delay-process-noise",
            "0.5",
            "--filter-rate-hz",
            "200",
        ]);
        let options = options(&args, 2).expect("known rows");
        assert_eq!(
            options.rows,
            Some(vec!["delay_step".to_string(), "aekf17_hover".to_string()])
        );
        assert_eq!(options.seeds, [3, 4]);
        assert_eq!(options.filter_rate_hz, Some(200.0));
        let tuning = options.tuning;
        assert!((tuning.rate_std.expect("set") - 2e-3).abs() < 1e-12);
        assert_eq!(tuning.rate_time_constant_s, Some(300.0));
        assert_eq!(tuning.process_noise_ms2_per_s, Some(0.5));
        assert_eq!(tuning.to_json()["rate_time_constant_s"], 300.0);
        let defaults = super::options(&parse(&["--delay-suite"]), 5).expect("no rows named");
        assert_eq!(defaults, DelayOptions::default());
        let tried = parse(&[
            "--delay-suite",
            "--delay-acquisition-exponent",
            "3",
            "--delay-smoothing-cutoff",
            "0.7",
        ]);
        let tuning = super::options(&tried, 1).expect("valid").tuning;
        let mut config = delaynav::delay::DelayLoopConfig::<f64>::clean_input();
        tuning.apply(&mut config);
        assert_eq!(config.acquisition_motion_exponent, 3.0);
        assert_eq!(config.smoothing_cutoff_hz, 0.7);
        let bad = super::options(&parse(&["--delay-suite", "--rows", "cold_start"]), 1);
        assert!(bad.is_err_and(|e| e.contains("cold_start_low")));
    }

    /// `--delay-trace ROW` and `--delay-trace aekf17_hover`: the flags parse to what the
    /// traces take.
    #[test]
    fn trace_flags_parse() {
        let args = parse(&[
            "--delay-trace",
            "cold_start_high",
            "--compare-accel",
            "--seed",
            "2",
            "--delay-rate-std",
            "1",
        ]);
        assert_eq!(
            args.delay_flags.delay_trace.as_deref(),
            Some("cold_start_high")
        );
        assert!(args.delay_flags.compare_accel && args.seed == 2);
        assert_eq!(tuning(&args).rate_std, Some(1e-3));
        let hover = parse(&[
            "--delay-trace",
            "aekf17_hover",
            "--duration",
            "30",
            "--aekf17-delay-random-walk",
            "0",
            "--aekf17-accel-smoothing",
            "0",
        ]);
        assert_eq!(hover.duration, Some(30.0));
        assert_eq!(hover.delay_flags.aekf17_delay_random_walk, Some(0.0));
        assert_eq!(hover.delay_flags.aekf17_accel_smoothing, Some(0.0));
    }
}

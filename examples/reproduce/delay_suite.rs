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

/// The delay loop's changes that the `--delay-*` flags ask for.
pub fn tuning(args: &Args) -> LoopTuning {
    LoopTuning {
        rate_std: args.delay_rate_std.map(|ms_per_s| ms_per_s * 1e-3),
        rate_time_constant_s: args.delay_rate_time_constant,
        process_noise_ms2_per_s: args.delay_process_noise,
        innovation_window_s: args.delay_innovation_window,
        innovation_noise_scale: args.delay_innovation_noise_scale,
        innovation_reacquire_sigma: args.delay_innovation_reacquire_sigma,
        innovation_before_lock: args.delay_innovation_before_lock,
        innovation_acquire_noise_scale: args.delay_innovation_acquire_noise_scale,
        measurement_noise_ms2: args.delay_measurement_noise,
        acquisition_motion_exponent: args.delay_acquisition_exponent,
        smoothing_cutoff_hz: args.delay_smoothing_cutoff,
    }
}

/// The suite's options: `seeds_n` seeds from `--seed`, `--rows`, the loop's
/// tuning; an error names a row the suite does not have.
pub fn options(args: &Args, seeds_n: u64) -> Result<DelayOptions, String> {
    let mut options = DelayOptions::full(args.seed, seeds_n);
    if let Some(names) = &args.rows {
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
    let row = args.delay_trace.as_deref().unwrap_or("trace");
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
    let row = args.delay_trace.clone().unwrap_or_default();
    let seed = args.seed;
    let path = trace_path(args)?;
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
    if row == "aekf17_hover" {
        let setup = HoverSetup {
            duration_s: args.duration,
            delay_random_walk: args.aekf17_delay_random_walk,
            accel_smoothing_s: args.aekf17_accel_smoothing,
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
        compare_accel: args.compare_accel,
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
        assert_eq!(args.delay_trace.as_deref(), Some("cold_start_high"));
        assert!(args.compare_accel && args.seed == 2);
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
        assert_eq!(hover.aekf17_delay_random_walk, Some(0.0));
        assert_eq!(hover.aekf17_accel_smoothing, Some(0.0));
    }
}

//! Reproduces the paper's simulation study (section 3.1, Tables 5 and 6,
//! Figures 5 and 6) on the crate's simulator, and runs the suites that define
//! what the crate promises: a front end of `delaynav::sim::suite`.
//!
//! The default run prints the RMSE table with the paper's figures and the noise
//! floor beside ours, the bias table, the paired differences and the
//! consistency (`sim::suite::tables`), and writes the JSON results and SVG plots.
//!
//! ```text
//! cargo run --release --features sim --example reproduce              # everything
//! cargo run --release --features sim --example reproduce -- --quick --json out.json
//! cargo run --release --features sim --example reproduce -- --quick --csv target/logs   # CSV logs too
//! cargo run --release --features sim --example reproduce -- --seeds 20                  # Monte Carlo
//! cargo run --release --features sim --example reproduce -- --sweep delay --json target/sweep.json
//! cargo run --release --features sim --example reproduce -- --faults --json target/faults.json   # fault suite
//! cargo run --release --features sim --example reproduce -- --faults --seeds 5   # on seeds 1-5
//! cargo run --release --features sim --example reproduce -- --delay-suite --json d.json  # delay suite
//! cargo run --release --features sim --example reproduce -- --integrity --json target/integrity.json
//! cargo run --release --features sim --example reproduce -- --seed 4 \
//!     --integrity-trace "high seed 5 proposed reset_inflight"             # one run, every 50 ms
//! cargo run --release --features sim --example reproduce -- --delay-suite --rows delay_ramp,gps_2hz \
//!     --delay-rate-std 1 --delay-rate-time-constant 30 --json d.json      # rows with the drift-rate state
//! cargo run --release --features sim --example reproduce -- --delay-trace cold_start_low --seed 1 \
//!     --csv target/low.csv                                                 # a row's run, per second
//! cargo run --release --features sim --example reproduce -- --check \
//!     --known-failures low.proposed_tilt_vs_bound,high.proposed_tilt_vs_bound   # verdicts enforced
//! ```
//!
//! What each suite measures, its rows, verdicts and JSON keys: the docs of
//! `delaynav::sim::suite` and its modules. This program maps the flags to the
//! suites' options, shows their progress (one line per step on stderr, and a
//! bar below them on a terminal), prints their text, writes their JSON, draws
//! the plots (`plots`), and adds the peer `fusion_nav` (`fusion_nav`, the
//! `fusion-nav` crate) to the tables' rows ([`estimators`]).

mod args;
mod delay_suite;
mod fusion_nav;
mod plots;

use args::{Args, ScenarioChoice};
use clap::Parser;
use delaynav::sim::suite::check::{Verdict, judge};
use delaynav::sim::suite::faults::{self, FaultsOptions};
use delaynav::sim::suite::integrity::{self, IntegrityOptions};
use delaynav::sim::suite::sweep::{self, SweepOptions};
use delaynav::sim::suite::tables::{self, Estimator, TablesOptions, score};
use delaynav::sim::suite::{Progress, ProgressFn};
use delaynav::sim::{Scenario, Simulation, csv::write_run};
use fusion_nav::FusionNav;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::Value;
use std::error::Error;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Every row of the tables: the library's, then the peer `fusion_nav`.
fn estimators() -> Vec<Estimator> {
    let mut rows = tables::estimators();
    rows.push(Estimator::new("fusion_nav", |s| {
        Ok(score::<f32, _>(FusionNav::new(&s.config), s, |_| None))
    }));
    rows
}

/// Progress on stderr: the suites' lines, with the time since the start, and a
/// bar below them (indicatif draws it on a terminal only).
struct Reporter {
    bar: ProgressBar,
    started: Instant,
}

impl Reporter {
    fn new() -> Self {
        let bar = ProgressBar::new(0);
        if let Ok(style) = ProgressStyle::with_template("[{wide_bar}] {pos}/{len} ({eta} left)") {
            bar.set_style(style);
        }
        Self {
            bar,
            started: Instant::now(),
        }
    }

    fn report(&self, progress: Progress) {
        let elapsed = self.started.elapsed().as_secs_f64();
        let line = match &progress {
            Progress::Step { done, total, .. } => {
                self.bar.set_length(*total as u64);
                self.bar.set_position(*done as u64);
                format!("{progress} (elapsed {elapsed:.0} s)")
            }
            Progress::Calibrated { .. } => format!("{progress} ({elapsed:.0} s)"),
            _ => progress.to_string(),
        };
        self.bar.suspend(|| eprintln!("{line}"));
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// `--integrity-trace RUN`: one run of the integrity suite, every 50 ms, as CSV (errors against
/// the truth beside the protection levels and flags, `integrity::EpochRecord`), and its
/// misleading time on stderr.
fn integrity_trace(args: &Args, run: &str, progress: ProgressFn) -> Result<(), Box<dyn Error>> {
    use std::io::Write;
    let seeds = args.seeds.unwrap_or(3);
    let options = IntegrityOptions {
        seeds: (args.seed..args.seed + seeds).collect(),
        scale: args.duration.unwrap_or(60.0) / 60.0,
        ..IntegrityOptions::default()
    };
    let epochs = integrity::trace(&options, run, progress)?;
    let path = args.csv.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "target/integrity-trace/{}.csv",
            run.replace(' ', "-")
        ))
    });
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
    writeln!(
        out,
        "t_s,error_north_deg,error_east_deg,error_down_deg,tilt_deg,tilt_pl_deg,tilt_valid,\
         heading_deg,heading_pl_deg,heading_valid,horizontal_m,horizontal_pl_m,horizontal_valid,\
         velocity_m_s,velocity_pl_m_s,velocity_valid,resets"
    )?;
    let (mut rows, mut next_s) = (0usize, f64::NEG_INFINITY);
    let mut misleading = [0.0f64; 4];
    let mut previous: Option<&integrity::EpochRecord> = None;
    for e in &epochs {
        // An epoch's MI lasts until the next sample, as the suite charges it.
        if let Some(p) = previous {
            let dt = (e.t_s - p.t_s).max(0.0);
            for (q, m) in misleading.iter_mut().enumerate() {
                if p.valid[q] && p.errors[q] > p.levels[q] {
                    *m += dt;
                }
            }
        }
        previous = Some(e);
        // Every 50 ms of the truth's clock (a clock that steps back starts again).
        if e.t_s < next_s - 0.05 || e.t_s >= next_s {
            next_s = e.t_s + 0.05;
            let [n, east, d] = e.attitude_error_ned_deg;
            write!(out, "{:.4},{n:.4},{east:.4},{d:.4}", e.t_s)?;
            for q in 0..4 {
                write!(
                    out,
                    ",{:.4},{:.4},{}",
                    e.errors[q],
                    e.levels[q],
                    u8::from(e.valid[q])
                )?;
            }
            writeln!(out, ",{}", e.resets)?;
            rows += 1;
        }
    }
    out.flush()?;
    eprintln!(
        "{run}: valid with the error above its level (s, charged as the suite does): tilt {:.3}, \
         heading {:.3}, horizontal {:.3}, velocity {:.3}",
        misleading[0], misleading[1], misleading[2], misleading[3]
    );
    eprintln!("wrote {rows} rows to {}", path.display());
    Ok(())
}

/// Writes a suite's JSON document to `path` (its folder created).
fn write_json(path: &Path, json: &Value) -> Result<(), Box<dyn Error>> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::write(path, serde_json::to_string_pretty(json)? + "\n")?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// `--check`: prints every verdict; an error when the run fails.
fn enforce(verdicts: &[Verdict], known: &[String]) -> Result<(), Box<dyn Error>> {
    let judgement = judge(verdicts, known);
    eprint!("{judgement}");
    judgement
        .failure()
        .map_or(Ok(()), |reason| Err(reason.into()))
}

fn main() -> Result<(), Box<dyn Error>> {
    let args = Args::parse();
    if args.check
        && (args.sweep.is_some() || args.bound_study || args.delay_flags.trace_row().is_some())
    {
        return Err(
            "--check applies to the default run, --faults, --integrity and --delay-suite".into(),
        );
    }
    let reporter = Reporter::new();
    let progress = |p: Progress| reporter.report(p);
    if args.faults {
        let options = FaultsOptions {
            seed: args.seed,
            scale: args.duration.unwrap_or(60.0) / 60.0,
            filter_rate_hz: args.filter_rate_hz,
            debug_row: std::env::var("FAULT_DEBUG").ok(),
            ..FaultsOptions::default()
        };
        if let Some(n) = args.seeds {
            // The suite on seeds S..S+N: each row's figure per seed, its median and worst.
            let seeds: Vec<u64> = (args.seed..args.seed + n).collect();
            let result = faults::run_seeds(&options, &seeds, &progress)?;
            eprint!("{result}");
            write_json(&args.json, &result.to_json())?;
            if args.check {
                enforce(&result.verdicts(), &args.known_failures)?;
            }
            return Ok(());
        }
        let result = faults::run(&options, &progress)?;
        eprint!("{result}");
        write_json(&args.json, &result.to_json())?;
        if args.check {
            enforce(&result.verdicts(), &args.known_failures)?;
        }
        return Ok(());
    }
    if let Some(run) = &args.integrity_trace {
        return integrity_trace(&args, run, &progress);
    }
    if args.integrity {
        let seeds = args.seeds.unwrap_or(3);
        let mut options = IntegrityOptions {
            seeds: (args.seed..args.seed + seeds).collect(),
            scale: args.duration.unwrap_or(60.0) / 60.0,
            rows: args.delay_flags.rows().map(<[String]>::to_vec),
            ..IntegrityOptions::default()
        };
        if let Some(threads) = args.threads {
            options.threads = threads;
        }
        let result = integrity::run(&options, &progress)?;
        eprint!("{result}");
        eprintln!("integrity: {:.1} s wall", result.wall_s);
        write_json(&args.json, &result.to_json())?;
        let dir = args
            .plots
            .clone()
            .unwrap_or_else(|| PathBuf::from("target/integrity"));
        std::fs::create_dir_all(&dir)?;
        for (diagram, (quantity, unit)) in
            result.stanford.iter().zip(integrity::STANFORD_QUANTITIES)
        {
            let path = dir.join(format!("stanford-{quantity}.svg"));
            plots::stanford(&path, quantity, unit, diagram)?;
            eprintln!("wrote {}", path.display());
        }
        if args.check {
            enforce(&result.verdicts(), &args.known_failures)?;
        }
        return Ok(());
    }
    let seeds_n = args.seeds.unwrap_or(if args.quick { 2 } else { 5 });
    let duration_s = args
        .duration
        .unwrap_or(if args.quick { 20.0 } else { 60.0 });
    if seeds_n == 0 {
        return Err("--seeds must be at least 1".into());
    }
    if !(args.skip >= 0.0 && duration_s > args.skip) {
        return Err(format!(
            "--duration ({duration_s} s) must exceed the convergence time ({} s)",
            args.skip
        )
        .into());
    }
    if args.delay_flags.trace_row().is_some() {
        return delay_suite::trace(&args);
    }
    if args.delay_suite {
        return delay_suite::run(&args, seeds_n, &progress);
    }
    let plots = match (&args.plots, args.quick) {
        (Some(dir), _) => Some(dir.clone()),
        (None, false) => Some(PathBuf::from("target/reproduce")),
        (None, true) => None,
    };
    let mut options = TablesOptions {
        scenarios: match args.scenario {
            ScenarioChoice::Low => vec![Scenario::Low],
            ScenarioChoice::High => vec![Scenario::High],
            ScenarioChoice::All => Scenario::ALL.to_vec(),
        },
        seeds: (args.seed..args.seed + seeds_n).collect(),
        duration_s,
        skip_s: args.skip,
        delay_s: args.delay,
        keep_trace: plots.is_some(),
        calibrated: !args.no_calibration,
        filter_rate_hz: args.filter_rate_hz,
        ..TablesOptions::default()
    };
    if let Some(threads) = args.threads {
        options.threads = threads;
    }
    if let Some(dir) = &args.csv {
        for &scenario in &options.scenarios {
            let seed = options.seeds[0];
            let path = dir.join(format!("{}-seed{seed}", scenario.name()));
            let n = write_run(&path, Simulation::new(options.sim_config(scenario, seed))?)?;
            eprintln!("wrote {n} events to {}", path.display());
        }
    }
    if let Some(choice) = args.sweep {
        let options = SweepOptions {
            parameter: choice.into(),
            tables: options,
        };
        return run_sweep(&options, &args.json, plots, &progress);
    }
    let registry = if args.bound_study {
        tables::bound_study()
    } else {
        estimators()
    };
    let result = tables::run(&options, &registry, &progress)?;
    print!("{result}");
    write_json(&args.json, &result.to_json())?;
    if let Some(dir) = plots {
        for r in &result.scenarios {
            for path in plots::scenario(&dir, r)? {
                eprintln!("wrote {}", path.display());
            }
        }
    }
    if args.check {
        enforce(&result.verdicts(), &args.known_failures)?;
    }
    Ok(())
}

/// Runs a sweep, prints its tables, writes the JSON and a plot per scenario
/// (under `target/reproduce` unless `--plots`); `REPRODUCE_SWEEP_FULL` prints
/// every point's full tables too.
fn run_sweep(
    options: &SweepOptions,
    json: &Path,
    plots: Option<PathBuf>,
    progress: ProgressFn,
) -> Result<(), Box<dyn Error>> {
    let result = sweep::run(options, &estimators(), progress)?;
    print!("{result}");
    write_json(json, &result.to_json())?;
    let dir = plots.unwrap_or_else(|| PathBuf::from("target/reproduce"));
    std::fs::create_dir_all(&dir)?;
    for (k, scenario) in result.scenarios().into_iter().enumerate() {
        let name = format!("sweep-{}-{}.svg", result.parameter.name(), scenario.name());
        let path = dir.join(name);
        plots::sweep(&path, result.parameter, scenario, &result.column(k))?;
        eprintln!("wrote {}", path.display());
    }
    if std::env::var_os("REPRODUCE_SWEEP_FULL").is_some() {
        print!("{}", result.full_tables());
    }
    Ok(())
}

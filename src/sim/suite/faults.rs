//! The fault suite: the navigator through the eighteen faults of
//! [`sim::faults::fault_suite`](crate::sim::faults::fault_suite), each row judged by its own
//! criterion (docs/faults.md explains every row).
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --faults --json target/faults.json
//! cargo run --release --features sim --example reproduce -- --faults --duration 30   # times scaled by 0.5
//! ```
//!
//! **Scenario.** The high scenario with a constant 0.2 s delay, 60 s scaled by
//! [`FaultsOptions::scale`] ([`base_config`]); every row is one faulty run of it. The
//! navigator of every row is `proposed` (the delay-compensated navigator, delay estimated),
//! started from the offline calibration of a separate run as in the tables
//! ([`setup::calibrated_start`](super::setup::calibrated_start)). The rows that measure a
//! ratio run their fault-free reference too. Runs go on [`FaultsOptions::threads`] threads.
//!
//! **Verdicts** ([`FaultsResult::verdicts`]): one per row, its figure within its limit; a figure
//! that is NaN (no estimate where the row counts, an empty window) or infinite (a settle row
//! that never settles) fails it.
//!
//! **JSON** ([`FaultsResult::to_json`]): `seed`, `duration_s`, `estimator` (`proposed`), and
//! `faults`: per row `name`, `passed`, `criterion`, `measured` (`null` when not finite),
//! `limit`, and the row's second figure where it has one (`max_tilt_deg` of the magnetic row).
//!
//! **Text** (`Display` of [`FaultsResult`]): one line per row, `name measured (limit L)
//! pass|FAIL`, after the row's errors once a second when it is [`FaultsOptions::debug_row`].
//!
//! **Seeds** ([`run_seeds`], `reproduce --faults --seeds N`): the suite once per seed; a row
//! passes when more than half of the seeds pass it, its figure the median of theirs
//! ([`FaultsSeedsResult`], its JSON in [`FaultsSeedsResult::to_json`]).

use super::setup::{DelayStart, calibrated_start, proposed};
use super::{Progress, ProgressFn, Steps, SuiteError, Task, json_number, parallel_map};
use crate::nav::DelayCompensatedNav;
use crate::sim::SimConfig;
use crate::sim::faults::{
    FaultCase, FaultResult, FaultySimulation, OnTimeBackwards, Reference, TracePoint, base_config,
    evaluate, fault_suite, run_trace,
};
use core::fmt;
use serde_json::{Value, json};
use std::time::Instant;

/// Spacing of the points of a debugged row's errors, in trace points (IMU samples).
pub const DEBUG_STEP: usize = 1000;

/// The options of the fault suite; `Default` is `reproduce --faults`.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultsOptions {
    /// Seed of every run [default: 1].
    pub seed: u64,
    /// Every time of the suite scaled by this (1: the 60 s runs) [default: 1].
    pub scale: f64,
    /// A row whose errors the result keeps once a second ([`FaultsResult::debug`]); `"clean"`
    /// keeps the clean run's.
    pub debug_row: Option<String>,
    /// Runs at once [default: 2].
    pub threads: usize,
    /// Prediction rate of the navigator's horizon filter, Hz (`None`: its default).
    pub filter_rate_hz: Option<f64>,
}

impl Default for FaultsOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            scale: 1.0,
            debug_row: None,
            threads: 2,
            filter_rate_hz: None,
        }
    }
}

/// A run of the fault suite.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultsResult {
    /// The options it ran with.
    pub options: FaultsOptions,
    /// Where the navigator's delay started (the calibration).
    pub start: DelayStart,
    /// Every row's outcome, in the suite's order.
    pub rows: Vec<FaultResult>,
    /// The debugged row's name and its errors every [`DEBUG_STEP`] IMU samples.
    pub debug: Option<(&'static str, Vec<TracePoint>)>,
}

/// One simulated run of the suite: a reference run or a row.
enum Job<'a> {
    Reference(Reference),
    Case(&'a FaultCase),
}

impl Job<'_> {
    fn name(&self) -> String {
        match self {
            Job::Reference(r) => format!("reference {r:?}"),
            Job::Case(c) => c.name.to_string(),
        }
    }

    /// Runs the job to its trace with the navigator `proposed` from `start`.
    fn trace(
        &self,
        base: &SimConfig,
        start: DelayStart,
        filter_rate_hz: Option<f64>,
    ) -> Result<Vec<TracePoint>, SuiteError> {
        let (sim, faults, on_backwards) = match self {
            Job::Reference(r) => (r.config(base), Vec::new(), OnTimeBackwards::Ignore),
            Job::Case(c) => (c.sim.clone(), c.faults.clone(), c.on_backwards),
        };
        let events = FaultySimulation::new(sim.clone(), &faults)
            .map_err(|e| SuiteError::config(self.name(), e))?;
        let nav =
            proposed(&sim, start, filter_rate_hz).map_err(|e| SuiteError::config("proposed", e))?;
        Ok(run_trace(
            events,
            nav,
            on_backwards,
            DelayCompensatedNav::reset,
        ))
    }
}

/// Runs the suite, reporting [`Progress::Calibrated`] and a [`Progress::Step`] per run.
pub fn run(options: &FaultsOptions, progress: ProgressFn) -> Result<FaultsResult, SuiteError> {
    let seed = options.seed;
    let scale = options.scale;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(SuiteError::InvalidOption {
            option: "scale",
            reason: format!("({scale}) must be positive"),
        });
    }
    let base = base_config(seed, scale);
    base.validate()
        .map_err(|e| SuiteError::config("simulation", e))?;
    let start = calibrated_start(&base).map_err(|e| SuiteError::config("calibration", e))?;
    progress(Progress::Calibrated {
        delay_s: start.delay_s,
    });
    let cases = fault_suite(seed, scale);
    let mut jobs = vec![Job::Reference(Reference::Clean)];
    for c in &cases {
        if c.reference != Reference::None
            && !jobs
                .iter()
                .any(|j| matches!(j, Job::Reference(r) if *r == c.reference))
        {
            jobs.push(Job::Reference(c.reference));
        }
    }
    let first_case = jobs.len();
    jobs.extend(cases.iter().map(Job::Case));
    let steps = Steps::new(jobs.len(), progress);
    let traces: Vec<Vec<TracePoint>> = parallel_map(&jobs, options.threads, |_, job| {
        let t0 = Instant::now();
        let trace = job.trace(&base, start, options.filter_rate_hz)?;
        let task = Task::Fault { name: job.name() };
        steps.step(task, t0.elapsed().as_secs_f64());
        Ok(trace)
    })
    .into_iter()
    .collect::<Result<_, SuiteError>>()?;
    let reference_trace = |r: Reference| {
        jobs.iter()
            .position(|j| matches!(j, Job::Reference(x) if *x == r))
            .map(|k| traces[k].as_slice())
    };
    let mut debug = None;
    if options.debug_row.as_deref() == Some("clean") {
        let clean = reference_trace(Reference::Clean).unwrap_or_default();
        debug = Some(("clean", clean.iter().step_by(DEBUG_STEP).copied().collect()));
    }
    let rows = cases
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let trace = &traces[first_case + i];
            if options.debug_row.as_deref() == Some(c.name) {
                let points = trace.iter().step_by(DEBUG_STEP).copied().collect();
                debug = Some((c.name, points));
            }
            evaluate(c, trace, reference_trace(c.reference))
        })
        .collect();
    Ok(FaultsResult {
        options: options.clone(),
        start,
        rows,
        debug,
    })
}

impl FaultsResult {
    /// The suite's rows as verdicts (a NaN figure fails).
    pub fn verdicts(&self) -> Vec<super::check::Verdict> {
        self.rows
            .iter()
            .map(|r| super::check::Verdict {
                name: r.name.to_string(),
                passed: r.passed,
                measured: Some(r.measured),
                limit: format!("{} ({})", r.limit, r.criterion),
            })
            .collect()
    }

    /// The suite's JSON document (see the module's docs).
    pub fn to_json(&self) -> Value {
        let rows: Vec<Value> = self
            .rows
            .iter()
            .map(|r| {
                let mut row = json!({
                    "name": r.name,
                    "passed": r.passed,
                    "criterion": r.criterion,
                    "measured": json_number(r.measured),
                    "limit": r.limit,
                });
                if let Some((key, value)) = r.note {
                    row[key] = json_number(value);
                }
                row
            })
            .collect();
        json!({
            "seed": self.options.seed,
            "duration_s": 60.0 * self.options.scale,
            "estimator": "proposed",
            "faults": rows,
        })
    }
}

impl fmt::Display for FaultsResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let write_debug = |f: &mut fmt::Formatter<'_>, row: &str| -> fmt::Result {
            let Some((name, points)) = &self.debug else {
                return Ok(());
            };
            if *name != row {
                return Ok(());
            }
            for p in points {
                writeln!(
                    f,
                    "{:.1} tilt {:.2} heading {:.2} herr {:.2}",
                    p.t_s,
                    p.tilt_deg,
                    p.heading_deg,
                    p.horizontal_error_m([0.0; 2])
                )?;
            }
            Ok(())
        };
        write_debug(f, "clean")?;
        for r in &self.rows {
            write_debug(f, r.name)?;
            writeln!(
                f,
                "{:<24} {:>10.3} (limit {:>5}) {}",
                r.name,
                r.measured,
                r.limit,
                if r.passed { "pass" } else { "FAIL" }
            )?;
        }
        Ok(())
    }
}

/// The suite on several seeds ([`run_seeds`]): one run per seed, and per row the seeds'
/// figures, their median and the worst of them.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultsSeedsResult {
    /// One run per seed, in the order of the seeds.
    pub runs: Vec<FaultsResult>,
}

/// One row over the seeds of a [`FaultsSeedsResult`].
#[derive(Debug, Clone, PartialEq)]
pub struct FaultSeedsRow {
    /// The row's name.
    pub name: &'static str,
    /// What is measured.
    pub criterion: &'static str,
    /// The limit.
    pub limit: f64,
    /// The figure of each seed (NaN: none; infinite: never settled).
    pub per_seed: Vec<f64>,
    /// Seeds whose run passed the row.
    pub passed_seeds: usize,
}

impl FaultSeedsRow {
    /// The median of the seeds' figures, a NaN counted as the worst (+inf); the mean of
    /// the two middle ones for an even count.
    pub fn median(&self) -> f64 {
        let mut v: Vec<f64> = self.per_seed.iter().map(|&x| worst_if_nan(x)).collect();
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => f64::NAN,
            n if n % 2 == 1 => v[n / 2],
            n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        }
    }

    /// The largest figure, a NaN counted as +inf (every row's figure is worse when larger).
    pub fn worst(&self) -> f64 {
        self.per_seed
            .iter()
            .map(|&x| worst_if_nan(x))
            .fold(f64::NAN, f64::max)
    }

    /// More than half of the seeds passed the row.
    pub fn passed(&self) -> bool {
        2 * self.passed_seeds > self.per_seed.len()
    }
}

fn worst_if_nan(x: f64) -> f64 {
    if x.is_nan() { f64::INFINITY } else { x }
}

/// Runs the suite once per seed of `seeds` (each as [`run`] with `options.seed` replaced).
pub fn run_seeds(
    options: &FaultsOptions,
    seeds: &[u64],
    progress: ProgressFn,
) -> Result<FaultsSeedsResult, SuiteError> {
    if seeds.is_empty() {
        return Err(SuiteError::InvalidOption {
            option: "seeds",
            reason: "at least one seed is needed".into(),
        });
    }
    let runs = seeds
        .iter()
        .map(|&seed| {
            let options = FaultsOptions {
                seed,
                ..options.clone()
            };
            run(&options, progress)
        })
        .collect::<Result<_, _>>()?;
    Ok(FaultsSeedsResult { runs })
}

impl FaultsSeedsResult {
    /// The seeds, in order.
    pub fn seeds(&self) -> Vec<u64> {
        self.runs.iter().map(|r| r.options.seed).collect()
    }

    /// Each row over the seeds, in the suite's order.
    pub fn rows(&self) -> Vec<FaultSeedsRow> {
        let Some(first) = self.runs.first() else {
            return Vec::new();
        };
        first
            .rows
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let outcomes = self.runs.iter().filter_map(|run| run.rows.get(i));
                FaultSeedsRow {
                    name: r.name,
                    criterion: r.criterion,
                    limit: r.limit,
                    per_seed: outcomes.clone().map(|o| o.measured).collect(),
                    passed_seeds: outcomes.filter(|o| o.passed).count(),
                }
            })
            .collect()
    }

    /// One verdict per row: passed on more than half of the seeds; the figure is the median.
    pub fn verdicts(&self) -> Vec<super::check::Verdict> {
        let n = self.runs.len();
        self.rows()
            .iter()
            .map(|r| super::check::Verdict {
                name: r.name.to_string(),
                passed: r.passed(),
                measured: Some(r.median()),
                limit: format!(
                    "{} on more than half of {n} seeds, median shown ({})",
                    r.limit, r.criterion
                ),
            })
            .collect()
    }

    /// The JSON document: `seeds`, `duration_s`, `estimator`, and `faults`: per row `name`,
    /// `criterion`, `limit`, `measured` (the median; `null` when not finite), `per_seed`
    /// (`null` where not finite), `worst`, `passed_seeds`, `passed` (more than half).
    pub fn to_json(&self) -> Value {
        let rows: Vec<Value> = self
            .rows()
            .iter()
            .map(|r| {
                json!({
                    "name": r.name,
                    "criterion": r.criterion,
                    "limit": r.limit,
                    "measured": json_number(r.median()),
                    "per_seed": r.per_seed.iter().map(|&x| json_number(x)).collect::<Vec<_>>(),
                    "worst": json_number(r.worst()),
                    "passed_seeds": r.passed_seeds,
                    "passed": r.passed(),
                })
            })
            .collect();
        json!({
            "seeds": self.seeds(),
            "duration_s": self.runs.first().map_or(60.0, |r| 60.0 * r.options.scale),
            "estimator": "proposed",
            "faults": rows,
        })
    }
}

impl fmt::Display for FaultsSeedsResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.runs.len();
        write!(f, "{:<24}", "row / seed")?;
        for seed in self.seeds() {
            write!(f, " {seed:>8}")?;
        }
        writeln!(f, " {:>8} {:>8} {:>6}  passed", "median", "worst", "limit")?;
        for r in self.rows() {
            write!(f, "{:<24}", r.name)?;
            for x in &r.per_seed {
                write!(f, " {x:>8.3}")?;
            }
            writeln!(
                f,
                " {:>8.3} {:>8.3} {:>6}  {}/{n} {}",
                r.median(),
                r.worst(),
                r.limit,
                r.passed_seeds,
                if r.passed() { "pass" } else { "FAIL" }
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::suite::setup::UNCALIBRATED_START;

    fn row(name: &'static str, passed: bool, measured: f64) -> FaultResult {
        FaultResult {
            name,
            passed,
            criterion: "synthetic",
            measured,
            limit: 5.0,
            note: None,
        }
    }

    fn result(rows: Vec<FaultResult>) -> FaultsResult {
        FaultsResult {
            options: FaultsOptions {
                seed: 3,
                scale: 0.5,
                ..FaultsOptions::default()
            },
            start: UNCALIBRATED_START,
            rows,
            debug: None,
        }
    }

    /// Each row's verdict reaches the JSON as it is; a figure that is not a number (no
    /// estimate, an empty window, never settled) is written `null`, never a number.
    #[test]
    fn the_json_keeps_each_verdict_and_writes_no_figure_it_has_not() {
        let mag = FaultResult {
            note: Some(("max_tilt_deg", 2.5)),
            ..row("mag", false, 1.0)
        };
        let lost = FaultResult {
            note: Some(("max_tilt_deg", f64::NAN)),
            ..row("lost", false, f64::NAN)
        };
        let results = result(vec![
            row("settled", true, 2.9),
            row("never", false, f64::INFINITY),
            mag,
            lost,
        ]);
        let json = results.to_json();
        assert_eq!(
            (json["seed"].as_u64(), json["duration_s"].as_f64()),
            (Some(3), Some(30.0))
        );
        let rows = json["faults"].as_array().expect("rows");
        let passed: Vec<bool> = rows.iter().map(|r| r["passed"] == true).collect();
        assert_eq!(passed, [true, false, false, false]);
        assert_eq!(rows[0]["measured"], 2.9);
        assert!(rows[1]["measured"].is_null() && rows[3]["measured"].is_null());
        assert_eq!(rows[2]["max_tilt_deg"], 2.5);
        assert!(rows[3]["max_tilt_deg"].is_null());
        assert!(rows[0].get("max_tilt_deg").is_none());
        // The verdicts: a NaN or infinite figure never holds.
        let holds: Vec<bool> = results.verdicts().iter().map(|v| v.holds()).collect();
        assert_eq!(holds, [true, false, false, false]);
        let text = results.to_string();
        assert!(text.starts_with("settled                       2.900 (limit     5) pass\n"));
    }

    /// Over seeds, a row holds when more than half of them pass it; its median and worst
    /// count a missing figure as the worst, and the JSON keeps every seed's figure.
    #[test]
    fn over_seeds_a_row_is_judged_on_the_majority_and_its_median() {
        let run = |seed: u64, rows: Vec<FaultResult>| FaultsResult {
            options: FaultsOptions {
                seed,
                ..FaultsOptions::default()
            },
            ..result(rows)
        };
        let seeds = FaultsSeedsResult {
            runs: vec![
                run(1, vec![row("a", true, 1.0), row("b", false, 6.0)]),
                run(2, vec![row("a", false, 7.0), row("b", false, f64::NAN)]),
                run(3, vec![row("a", true, 2.0), row("b", true, 4.0)]),
            ],
        };
        let rows = seeds.rows();
        assert_eq!((rows[0].median(), rows[0].worst()), (2.0, 7.0));
        assert_eq!((rows[1].median(), rows[1].worst()), (6.0, f64::INFINITY));
        assert_eq!((rows[0].passed(), rows[1].passed()), (true, false));
        let json = seeds.to_json();
        assert_eq!(json["seeds"], json!([1, 2, 3]));
        let b = &json["faults"][1];
        assert_eq!(b["per_seed"], json!([6.0, null, 4.0]));
        assert!(b["worst"].is_null());
        assert_eq!(
            (b["measured"].as_f64(), b["passed_seeds"].as_u64()),
            (Some(6.0), Some(1))
        );
        let holds: Vec<bool> = seeds.verdicts().iter().map(|v| v.holds()).collect();
        assert_eq!(holds, [true, false]);
        assert!(
            run_seeds(
                &FaultsOptions::default(),
                &[],
                &crate::sim::suite::no_progress
            )
            .is_err()
        );
    }

    #[test]
    fn a_bad_scale_is_refused() {
        for scale in [0.0, -1.0, f64::NAN] {
            let options = FaultsOptions {
                scale,
                ..FaultsOptions::default()
            };
            let refused = run(&options, &crate::sim::suite::no_progress);
            assert!(matches!(refused, Err(SuiteError::InvalidOption { .. })));
        }
    }
}

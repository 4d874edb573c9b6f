//! The suites that define what the crate promises, as library code (feature `sim`).
//!
//! Each suite runs the crate's estimators on the simulator, scores them against the truth and
//! judges the figures. A front end (the `reproduce` example, a command-line tool, a Python
//! package) builds a suite's options, calls its `run`, and prints, writes or plots the typed
//! result; every result writes the suite's JSON document ([`serde_json::Value`], `to_json`),
//! its console text (`Display`) and its `--check` verdicts (`verdicts`, judged by
//! [`check::judge`]).
//!
//! | suite | what it measures | command |
//! |---|---|---|
//! | [`tables`] | the paper's simulation study: every estimator's RMSE, biases, consistency (NEES, NIS) and paired differences over seeds, in the low and high scenarios; the bound study | `reproduce`, `reproduce --seeds 20`, `reproduce --bound-study` |
//! | [`sweep`] | the tables' estimators against one parameter (GPS rate, IMU rate, true delay) | `reproduce --sweep gps_rate` |
//! | [`faults`] | the navigator through thirteen faults (GPS outage and jumps, IMU dropouts and jitter, time going back, magnetic disturbance, in-flight start) | `reproduce --faults` |
//! | [`integrity`] | the protection levels: misleading information under seventeen faults and on clean runs of the three estimators, availability, tightness, the EKFs' future stamps and divergence | `reproduce --integrity` |
//! | [`delay`] | the delay loop: lock-on, steps, ramps, jitter, slow GPS, negative and out-of-range delays, honest sigma, AEKF17 at hover | `reproduce --delay-suite` |
//!
//! [`check`] judges verdicts, [`stats`] holds the statistics over seeds, [`setup`] the
//! navigator as the suites configure it and where its delay starts.
//!
//! ```no_run
//! use delaynav::sim::suite::{faults, check};
//!
//! let options = faults::FaultsOptions { scale: 0.5, ..faults::FaultsOptions::default() };
//! let result = faults::run(&options, &|p| eprintln!("{p}"))?;
//! println!("{}", serde_json::to_string_pretty(&result.to_json())?);
//! let judgement = check::judge(&result.verdicts(), &[]);
//! eprint!("{judgement}");
//! assert!(judgement.passed());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Runs are deterministic: a seed gives the same figures on any number of threads. Only the
//! timing figures (`us_per_imu_sample`) differ between runs.
//!
//! Bad options are refused with a [`SuiteError`], never a panic; an estimator that refuses its
//! configuration in a row fails that row (a `null` figure) where the suite's JSON has a row for
//! it, and fails the run otherwise.

pub mod check;
pub mod delay;
pub mod faults;
pub mod integrity;
pub mod setup;
pub mod stats;
pub mod sweep;
pub mod tables;

use crate::sim::Scenario;
use core::fmt;
use serde_json::{Value, json};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// Why a suite refused to run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SuiteError {
    /// An option is out of its range.
    #[error("`{option}` {reason}")]
    InvalidOption {
        /// The option's field name.
        option: &'static str,
        /// What it must be.
        reason: String,
    },
    /// A row named in the options that the suite does not have.
    #[error("no row {name:?} (rows: {known})")]
    UnknownRow {
        /// The name given.
        name: String,
        /// The suite's rows, comma-separated.
        known: String,
    },
    /// A simulation or an estimator refused its configuration.
    #[error("{context}: {source}")]
    Config {
        /// What was being configured (an estimator's name, `simulation`, `calibration`).
        context: String,
        /// The refusal.
        source: crate::Error,
    },
    /// Writing a trace failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

impl SuiteError {
    /// A refusal of `source` while configuring `context`.
    pub(crate) fn config(context: impl Into<String>, source: crate::Error) -> Self {
        Self::Config {
            context: context.into(),
            source,
        }
    }
}

/// What a suite reports while it runs (to the callback of its `run`).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum Progress {
    /// One unit of work ended: the `done`-th of `total`, in `seconds`.
    Step {
        /// Units ended so far, this one included.
        done: usize,
        /// Units of the whole run.
        total: usize,
        /// What ended.
        task: Task,
        /// Its time, s.
        seconds: f64,
    },
    /// A sweep starts the runs at one value of its parameter.
    SweepValue {
        /// The parameter's name (`gps_rate`, `imu_rate`, `delay`).
        parameter: &'static str,
        /// The value.
        value: f64,
    },
    /// A suite's offline delay calibration ended (the fault suite's, or the integrity suite's per
    /// scenario).
    Calibrated {
        /// The calibrated start, s.
        delay_s: f64,
    },
    /// A row of the delay suite ended (printed as [`delay::Row`]'s `Display`).
    DelayRow(delay::Row),
}

/// A unit of work of [`Progress::Step`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Task {
    /// One estimator on one seed of a scenario (tables, sweeps, bound study).
    Run {
        /// The scenario.
        scenario: Scenario,
        /// The seed.
        seed: u64,
        /// The estimator's name.
        estimator: &'static str,
    },
    /// One run of the fault suite: a fault-free reference or a row.
    Fault {
        /// `reference Clean`, `reference SteadyImuRate { .. }` or the row's name.
        name: String,
    },
    /// One run of the integrity suite.
    Integrity {
        /// Scenario, seed, estimator and case, e.g. `high seed 2 proposed imu_gap_2s`.
        name: String,
    },
}

impl fmt::Display for Task {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Task::Run {
                scenario,
                seed,
                estimator,
            } => write!(f, "{} seed {seed} {estimator}", scenario.name()),
            Task::Fault { name } | Task::Integrity { name } => f.write_str(name),
        }
    }
}

/// One line per event, as the `reproduce` example prints them (without its elapsed time):
/// `[3/24] low seed 1 proposed: 1.2 s`, `gps_rate = 2`, `calibrated start 0.201 s`, a
/// delay suite row.
impl fmt::Display for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Progress::Step {
                done,
                total,
                task,
                seconds,
            } => write!(f, "[{done}/{total}] {task}: {seconds:.1} s"),
            Progress::SweepValue { parameter, value } => write!(f, "{parameter} = {value}"),
            Progress::Calibrated { delay_s } => {
                write!(f, "calibrated start {delay_s:.3} s")
            }
            Progress::DelayRow(row) => write!(f, "{row}"),
        }
    }
}

/// The progress callback of a suite's `run` (called from its worker threads).
pub type ProgressFn<'a> = &'a (dyn Fn(Progress) + Sync);

/// A callback that ignores the progress.
pub fn no_progress(_: Progress) {}

/// Counts the units of work of a run and reports each as it ends.
pub(crate) struct Steps<'a> {
    done: Mutex<usize>,
    total: usize,
    progress: ProgressFn<'a>,
}

impl<'a> Steps<'a> {
    pub(crate) fn new(total: usize, progress: ProgressFn<'a>) -> Self {
        Self {
            done: Mutex::new(0),
            total,
            progress,
        }
    }

    /// Reports that `task` ended after `seconds` (in the order the units end).
    pub(crate) fn step(&self, task: Task, seconds: f64) {
        let mut done = self.done.lock().unwrap_or_else(PoisonError::into_inner);
        *done += 1;
        (self.progress)(Progress::Step {
            done: *done,
            total: self.total,
            task,
            seconds,
        });
    }

    pub(crate) fn report(&self, progress: Progress) {
        (self.progress)(progress);
    }
}

/// `f` on every item on `threads` threads (at least one, at most one per item), each taking
/// the next item not yet started; the results in the items' order.
pub(crate) fn parallel_map<T: Sync, R: Send>(
    items: &[T],
    threads: usize,
    f: impl Fn(usize, &T) -> R + Sync,
) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..items.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..threads.clamp(1, items.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(item) = items.get(k) else { break };
                    let r = f(k, item);
                    results.lock().unwrap_or_else(PoisonError::into_inner)[k] = Some(r);
                }
            });
        }
    });
    // Every worker ran to the end of the items (a panic in `f` propagates from the scope).
    results
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
        .into_iter()
        .flatten()
        .collect()
}

/// A number, or `null` when it is not finite.
pub(crate) fn json_number(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

/// A pair `[lo, hi]` of [`json_number`]s.
pub(crate) fn json_pair((lo, hi): (f64, f64)) -> Value {
    json!([json_number(lo), json_number(hi)])
}

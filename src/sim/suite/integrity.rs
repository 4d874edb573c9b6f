//! The integrity suite: are the protection levels honest, and are they tight?
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --integrity --json target/integrity.json
//! ```
//!
//! **Runs.** Every run is 60 s (times scaled by [`IntegrityOptions::scale`]) on the
//! [`seeds`](IntegrityOptions::seeds) (default 1, 2, 3) in the low and the high scenario (true
//! delay 0.2 s), the errors read after every IMU sample against the truth, with the estimator's
//! [`Navigator::integrity`] (its protection levels and flags) at the same instant:
//!
//! - the navigator (`proposed`, delay estimated from the offline calibration of each scenario,
//!   as in the fault suite) through the fault suite's thirteen faults (on the scenario's own
//!   trajectory; the in-flight start keeps its turn) and four more: `gps_drift_20m` (fixes
//!   drifting 20 m north over 30 s from 30 s, velocity good), `imu_gap_2s` (no IMU sample from
//!   30 to 32 s), `reset_inflight` (the in-flight start's 15 m/s banked turn; every clock back
//!   1 s at 30 s, the caller calls `reset()` when told, as the docs say) and `delay_drift` (the
//!   true delay 0.2 -> 0.25 s linearly over the run);
//! - the three estimators (`proposed`, `ekf16`, `aekf17`) on the clean runs;
//! - `ekf16` and `aekf17` with one IMU sample stamped 1 h ahead at 30 s;
//! - `ekf16` with the GPS delay 0.5 s (unmodelled).
//!
//! **Epochs.** One epoch per IMU sample, lasting until the next (s of true time). An epoch is
//! **misleading** (MI) for a quantity (tilt, heading, horizontal position, velocity) when the
//! quantity is valid and its error exceeds its protection level; errors are the rotation-vector
//! tilt and heading (`sim::tilt_heading_error_rad`), the horizontal distance and the norm of
//! the NED velocity error. Without an estimate nothing is valid.
//!
//! **Rows** ([`IntegrityResult::rows`], names as in the JSON):
//!
//! | name | measured | limit |
//! |---|---|---|
//! | `mi_<fault>` | seconds with an MI epoch (any of the four quantities), summed over the fault's runs | 0.5 |
//! | `mi_clean` | MI (quantity, epoch) pairs over valid pairs, the clean runs of the three estimators | 1e-3 |
//! | `availability_clean` | share of the navigator's epochs after its first estimate with all six flags valid, clean | >= 0.95 |
//! | `pl_tightness_tilt` | median tilt PL over the tilt RMSE (epochs with tilt valid), navigator, clean | 6 |
//! | `ekf16_future_stamp`, `aekf17_future_stamp` | tilt RMSE from 10 s, stamped runs over clean runs (pooled) | 1.1 |
//! | `ekf16_divergence_reported` | s from the first tilt error above 30 deg to a reported reset or an invalid tilt (largest over the runs; 0 when the error never exceeds 30 deg; infinite when never reported) | 5 |
//!
//! **JSON** ([`IntegrityResult::to_json`]): `seeds`, `scenarios`, `duration_s`, `integrity`:
//! per row `name`, `passed`, `measured` (`null` when not finite), `limit`; and `details`: per
//! row name, what it adds (MI seconds per quantity, epochs counted, the runs where the tilt
//! error never reached 30 deg).

use super::setup::{DelayStart, calibrated_start, ekf16_config, proposed};
use super::{Progress, ProgressFn, Steps, SuiteError, Task, json_number, parallel_map};
use crate::estimate::Navigator;
use crate::nav::DelayCompensatedNav;
use crate::sim::faults::{
    Fault, FaultySimulation, OnTimeBackwards, base_config_in, fault_suite_in, feed, inflight_config,
};
use crate::sim::{DelayProfile, Scenario, SimConfig, SimEvent, tilt_heading_error_rad};
use crate::{AugmentedEkf17, AugmentedEkf17Config, Ekf16};
use core::fmt;
use serde_json::{Value, json};
use std::time::Instant;

/// Limit of every `mi_<fault>` row, s.
pub const MI_FAULT_LIMIT_S: f64 = 0.5;
/// Limit of `mi_clean`.
pub const MI_CLEAN_LIMIT: f64 = 1e-3;
/// Lower limit of `availability_clean`.
pub const AVAILABILITY_LIMIT: f64 = 0.95;
/// Limit of `pl_tightness_tilt`.
pub const TIGHTNESS_LIMIT: f64 = 6.0;
/// Limit of the future-stamp rows.
pub const FUTURE_STAMP_LIMIT: f64 = 1.1;
/// Limit of `ekf16_divergence_reported`, s.
pub const DIVERGENCE_LIMIT_S: f64 = 5.0;
/// Tilt error that counts as a divergence in `ekf16_divergence_reported`, degrees.
pub const DIVERGED_TILT_DEG: f64 = 30.0;
/// Every this many epochs one tilt PL is kept for the median of `pl_tightness_tilt`.
const PL_SAMPLE_STRIDE: usize = 10;

/// The options of the integrity suite; `Default` is `reproduce --integrity`.
#[derive(Debug, Clone, PartialEq)]
pub struct IntegrityOptions {
    /// Seeds of every case [default: 1, 2, 3].
    pub seeds: Vec<u64>,
    /// Scenarios of every case [default: low, high].
    pub scenarios: Vec<Scenario>,
    /// Every time of the suite scaled by this (1: the 60 s runs) [default: 1].
    pub scale: f64,
    /// Runs at once [default: 2].
    pub threads: usize,
    /// Only these rows, by name, and the runs they need (all when `None`).
    pub rows: Option<Vec<String>>,
}

impl Default for IntegrityOptions {
    fn default() -> Self {
        Self {
            seeds: vec![1, 2, 3],
            scenarios: Scenario::ALL.to_vec(),
            scale: 1.0,
            threads: 2,
            rows: None,
        }
    }
}

/// The estimator of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The delay-compensated navigator, delay estimated.
    Proposed,
    /// The 16-state EKF (no delay handling).
    Ekf16,
    /// The 17-state EKF with the delay as a state.
    Aekf17,
}

impl Estimator {
    /// Its name in the suite (`proposed`, `ekf16`, `aekf17`).
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Proposed => "proposed",
            Estimator::Ekf16 => "ekf16",
            Estimator::Aekf17 => "aekf17",
        }
    }
}

/// What a run is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Purpose {
    /// A fault of `mi_<name>`.
    Fault(&'static str),
    /// A clean run.
    Clean,
    /// One IMU sample stamped 1 h ahead at 30 s.
    FutureStamp,
    /// The GPS delay 0.5 s, unmodelled.
    Divergence,
}

/// One simulated run of the suite.
#[derive(Debug, Clone)]
struct Job {
    purpose: Purpose,
    estimator: Estimator,
    scenario: Scenario,
    seed: u64,
    sim: SimConfig,
    faults: Vec<Fault>,
    on_backwards: OnTimeBackwards,
}

impl Job {
    /// Whether the row `row` needs this run.
    fn feeds(&self, row: &str) -> bool {
        match self.purpose {
            Purpose::Fault(name) => row.strip_prefix("mi_") == Some(name),
            Purpose::Clean => {
                row == "mi_clean"
                    || (self.estimator == Estimator::Proposed
                        && ["availability_clean", "pl_tightness_tilt"].contains(&row))
                    || row == format!("{}_future_stamp", self.estimator.name())
            }
            Purpose::FutureStamp => row == format!("{}_future_stamp", self.estimator.name()),
            Purpose::Divergence => row == "ekf16_divergence_reported",
        }
    }

    fn name(&self) -> String {
        let what = match self.purpose {
            Purpose::Fault(name) => name,
            Purpose::Clean => "clean",
            Purpose::FutureStamp => "future_stamp",
            Purpose::Divergence => "delay_0.5s",
        };
        format!(
            "{} seed {} {} {what}",
            self.scenario.name(),
            self.seed,
            self.estimator.name()
        )
    }
}

/// What one run measured, per epoch accumulated.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunStats {
    /// Time with at least one MI quantity, s.
    pub mi_s: f64,
    /// MI time per quantity (tilt, heading, horizontal, velocity), s.
    pub mi_quantity_s: [f64; 4],
    /// (quantity, epoch) pairs valid.
    pub valid_pairs: u64,
    /// (quantity, epoch) pairs valid and MI.
    pub mi_pairs: u64,
    /// Epochs after the first estimate.
    pub epochs: u64,
    /// Of those, epochs with all six flags valid.
    pub all_valid_epochs: u64,
    /// Of those, epochs with each flag valid (tilt, heading, horizontal, vertical, velocity,
    /// delay).
    pub valid_epochs: [u64; 6],
    /// Sum of squared tilt errors (deg^2) over epochs with tilt valid, and their count.
    pub tilt_valid_sq: (f64, u64),
    /// Sum of squared tilt errors (deg^2) from 10 s (scaled), and their count; an epoch
    /// without an estimate makes it NaN.
    pub tilt_from_10s_sq: (f64, u64),
    /// First time the tilt error exceeded [`DIVERGED_TILT_DEG`], s.
    pub diverged_at_s: Option<f64>,
    /// First time at or after it with a new reset or tilt not valid, s.
    pub reported_at_s: Option<f64>,
    /// End of the run, s.
    pub end_s: f64,
}

/// A run's measurements and a sample of its tilt protection levels.
#[derive(Debug, Clone)]
struct RunOutcome {
    stats: RunStats,
    tilt_pl_deg: Vec<f64>,
}

/// Feeds `events` to `nav` and measures it (module docs).
fn measure<N: Navigator<f64>>(
    events: impl Iterator<Item = SimEvent>,
    mut nav: N,
    on_backwards: OnTimeBackwards,
    mut reset: impl FnMut(&mut N),
    skip_s: f64,
) -> RunOutcome {
    let mut s = RunStats::default();
    let mut tilt_pl = Vec::new();
    let mut last_t: Option<f64> = None;
    let mut previous_mi = [false; 4];
    let mut last_resets = 0u32;
    let mut started = false;
    let mut k = 0usize;
    for event in events {
        feed(&mut nav, &event, on_backwards, &mut reset);
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        let t = truth.t_us as f64 * 1e-6;
        // The previous epoch lasted until this sample: its MI is charged with the interval.
        let dt = last_t.map_or(0.0, |l| (t - l).max(0.0));
        last_t = Some(t);
        for (q, &mi) in previous_mi.iter().enumerate() {
            if mi {
                s.mi_quantity_s[q] += dt;
            }
        }
        if previous_mi.iter().any(|&mi| mi) {
            s.mi_s += dt;
        }
        previous_mi = [false; 4];
        s.end_s = t;
        let estimate = nav.estimate();
        let integrity = nav.integrity();
        let Some(est) = estimate else {
            if started {
                s.epochs += 1;
            }
            if t >= skip_s {
                s.tilt_from_10s_sq.0 = f64::NAN;
            }
            continue;
        };
        started = true;
        let (tilt, heading) = tilt_heading_error_rad(&est.attitude, &truth.attitude);
        let (tilt, heading) = (tilt.to_degrees(), heading.to_degrees());
        let d = est.position_ned_m - truth.position_m;
        let horizontal = d.x.hypot(d.y);
        let velocity = (est.velocity_ned_m_s - truth.velocity_m_s).norm();
        let l = integrity.levels;
        let quantities = [
            (integrity.tilt_valid, tilt, l.tilt_deg),
            (integrity.heading_valid, heading, l.heading_deg),
            (integrity.horizontal_valid, horizontal, l.horizontal_m),
            (integrity.velocity_valid, velocity, l.velocity_m_s),
        ];
        for (q, &(valid, error, level)) in quantities.iter().enumerate() {
            if valid {
                s.valid_pairs += 1;
                // A NaN error while valid is misleading too.
                let covered = error <= level;
                if !covered {
                    s.mi_pairs += 1;
                    previous_mi[q] = true;
                }
            }
        }
        s.epochs += 1;
        let flags = [
            integrity.tilt_valid,
            integrity.heading_valid,
            integrity.horizontal_valid,
            integrity.vertical_valid,
            integrity.velocity_valid,
            integrity.delay_valid,
        ];
        for (n, _) in s.valid_epochs.iter_mut().zip(flags).filter(|(_, f)| *f) {
            *n += 1;
        }
        if flags.iter().all(|&f| f) {
            s.all_valid_epochs += 1;
        }
        if integrity.tilt_valid {
            s.tilt_valid_sq.0 += tilt * tilt;
            s.tilt_valid_sq.1 += 1;
            if k.is_multiple_of(PL_SAMPLE_STRIDE) {
                tilt_pl.push(l.tilt_deg);
            }
            k += 1;
        }
        if t >= skip_s {
            s.tilt_from_10s_sq.0 += tilt * tilt;
            s.tilt_from_10s_sq.1 += 1;
        }
        if s.diverged_at_s.is_none() && tilt > DIVERGED_TILT_DEG {
            s.diverged_at_s = Some(t);
        }
        let new_reset = integrity.resets > last_resets;
        last_resets = integrity.resets;
        if s.diverged_at_s.is_some()
            && s.reported_at_s.is_none()
            && (new_reset || !integrity.tilt_valid)
        {
            s.reported_at_s = Some(t);
        }
    }
    RunOutcome {
        stats: s,
        tilt_pl_deg: tilt_pl,
    }
}

/// One row of the suite (the `"integrity"` entries of the JSON).
#[derive(Debug, Clone, PartialEq)]
pub struct IntegrityRow {
    /// The row's name.
    pub name: String,
    /// The figure within its limit (NaN fails).
    pub passed: bool,
    /// The figure.
    pub measured: f64,
    /// The limit (a lower limit for `availability_clean`).
    pub limit: f64,
    /// What the row adds to its figure (the JSON's `details`).
    pub details: Value,
}

/// A run of the integrity suite.
#[derive(Debug, Clone, PartialEq)]
pub struct IntegrityResult {
    /// The options it ran with.
    pub options: IntegrityOptions,
    /// Where the navigator's delay started, per scenario.
    pub starts: Vec<(Scenario, DelayStart)>,
    /// The rows, in the module docs' order.
    pub rows: Vec<IntegrityRow>,
    /// Wall time of the runs, s.
    pub wall_s: f64,
}

/// The jobs of the suite (module docs).
fn jobs(options: &IntegrityOptions) -> Vec<Job> {
    let scale = options.scale;
    let mut jobs = Vec::new();
    for &scenario in &options.scenarios {
        for &seed in &options.seeds {
            let base = base_config_in(scenario, seed, scale);
            let job = |purpose, estimator, sim: &SimConfig, faults: Vec<Fault>| Job {
                purpose,
                estimator,
                scenario,
                seed,
                sim: sim.clone(),
                faults,
                on_backwards: OnTimeBackwards::Ignore,
            };
            for case in fault_suite_in(scenario, seed, scale) {
                jobs.push(Job {
                    on_backwards: case.on_backwards,
                    ..job(
                        Purpose::Fault(case.name),
                        Estimator::Proposed,
                        &case.sim,
                        case.faults,
                    )
                });
            }
            let at = |t: f64| t * scale;
            jobs.push(job(
                Purpose::Fault("gps_drift_20m"),
                Estimator::Proposed,
                &base,
                vec![Fault::GpsPositionDrift {
                    from_s: at(30.0),
                    duration_s: at(30.0),
                    offset_m: [20.0, 0.0, 0.0],
                }],
            ));
            jobs.push(job(
                Purpose::Fault("imu_gap_2s"),
                Estimator::Proposed,
                &base,
                vec![Fault::ImuGap {
                    from_s: at(30.0),
                    to_s: at(30.0) + 2.0,
                }],
            ));
            jobs.push(Job {
                on_backwards: OnTimeBackwards::Reset,
                ..job(
                    Purpose::Fault("reset_inflight"),
                    Estimator::Proposed,
                    &inflight_config(seed, base.duration_s),
                    vec![Fault::ClockBack {
                        at_s: at(30.0),
                        back_s: 1.0,
                    }],
                )
            });
            let drifting = SimConfig {
                delay: DelayProfile {
                    drift_s_per_s: 0.05 / base.duration_s,
                    ..DelayProfile::constant(0.2)
                },
                ..base.clone()
            };
            jobs.push(job(
                Purpose::Fault("delay_drift"),
                Estimator::Proposed,
                &drifting,
                Vec::new(),
            ));
            for estimator in [Estimator::Proposed, Estimator::Ekf16, Estimator::Aekf17] {
                jobs.push(job(Purpose::Clean, estimator, &base, Vec::new()));
            }
            for estimator in [Estimator::Ekf16, Estimator::Aekf17] {
                jobs.push(job(
                    Purpose::FutureStamp,
                    estimator,
                    &base,
                    vec![Fault::ImuFutureSample {
                        at_s: at(30.0),
                        ahead_s: 3600.0,
                    }],
                ));
            }
            let late = SimConfig {
                delay: DelayProfile::constant(0.5),
                ..base.clone()
            };
            jobs.push(job(
                Purpose::Divergence,
                Estimator::Ekf16,
                &late,
                Vec::new(),
            ));
        }
    }
    jobs
}

impl Job {
    /// Runs the job with its estimator (`start`: the navigator's and `aekf17`'s delay).
    fn run(&self, start: DelayStart, skip_s: f64) -> Result<RunOutcome, SuiteError> {
        let events = FaultySimulation::new(self.sim.clone(), &self.faults)
            .map_err(|e| SuiteError::config(self.name(), e))?;
        let refused = |e| SuiteError::config(self.estimator.name(), e);
        Ok(match self.estimator {
            Estimator::Proposed => {
                let nav = proposed(&self.sim, start, None).map_err(refused)?;
                measure(
                    events,
                    nav,
                    self.on_backwards,
                    DelayCompensatedNav::reset,
                    skip_s,
                )
            }
            Estimator::Ekf16 => {
                let filter = Ekf16::new(ekf16_config::<f64>(&self.sim)).map_err(refused)?;
                measure(events, filter, self.on_backwards, |_| {}, skip_s)
            }
            Estimator::Aekf17 => {
                let mut config = AugmentedEkf17Config::with_nav(ekf16_config::<f64>(&self.sim));
                config.initial_delay_s = start.delay_s;
                if let Some(std) = start.std_s {
                    config.initial_delay_std_s = std;
                }
                let filter = AugmentedEkf17::new(config).map_err(refused)?;
                measure(events, filter, self.on_backwards, |_| {}, skip_s)
            }
        })
    }
}

/// Runs the suite, reporting [`Progress::Calibrated`] per scenario and a [`Progress::Step`]
/// per run.
pub fn run(
    options: &IntegrityOptions,
    progress: ProgressFn,
) -> Result<IntegrityResult, SuiteError> {
    let scale = options.scale;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(SuiteError::InvalidOption {
            option: "scale",
            reason: format!("({scale}) must be positive"),
        });
    }
    if options.seeds.is_empty() || options.scenarios.is_empty() {
        return Err(SuiteError::InvalidOption {
            option: "seeds",
            reason: "seeds and scenarios must not be empty".into(),
        });
    }
    let t0 = Instant::now();
    let first_seed = options.seeds[0];
    let starts: Vec<(Scenario, DelayStart)> =
        parallel_map(&options.scenarios, options.threads, |_, &scenario| {
            let base = base_config_in(scenario, first_seed, scale);
            base.validate()
                .map_err(|e| SuiteError::config("simulation", e))?;
            let start =
                calibrated_start(&base).map_err(|e| SuiteError::config("calibration", e))?;
            progress(Progress::Calibrated {
                delay_s: start.delay_s,
            });
            Ok((scenario, start))
        })
        .into_iter()
        .collect::<Result<_, SuiteError>>()?;
    let start_of = |scenario: Scenario| {
        starts
            .iter()
            .find(|(s, _)| *s == scenario)
            .map_or(super::setup::UNCALIBRATED_START, |(_, d)| *d)
    };
    let mut jobs = jobs(options);
    if let Some(only) = &options.rows {
        jobs.retain(|j| only.iter().any(|row| j.feeds(row)));
    }
    let steps = Steps::new(jobs.len(), progress);
    let skip_s = 10.0 * scale;
    let outcomes: Vec<RunOutcome> = parallel_map(&jobs, options.threads, |_, job| {
        let t = Instant::now();
        let outcome = job.run(start_of(job.scenario), skip_s)?;
        steps.step(
            Task::Integrity { name: job.name() },
            t.elapsed().as_secs_f64(),
        );
        Ok(outcome)
    })
    .into_iter()
    .collect::<Result<_, SuiteError>>()?;
    let mut rows = rows(&jobs, &outcomes);
    if let Some(only) = &options.rows {
        rows.retain(|r| only.contains(&r.name));
    }
    Ok(IntegrityResult {
        options: options.clone(),
        starts,
        rows,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

fn upper(name: String, measured: f64, limit: f64, details: Value) -> IntegrityRow {
    IntegrityRow {
        name,
        passed: measured <= limit,
        measured,
        limit,
        details,
    }
}

/// The rows from the runs (module docs).
fn rows(jobs: &[Job], outcomes: &[RunOutcome]) -> Vec<IntegrityRow> {
    let of = |purpose: Purpose, estimator: Option<Estimator>| {
        jobs.iter()
            .zip(outcomes)
            .filter(move |(j, _)| {
                j.purpose == purpose && estimator.is_none_or(|e| j.estimator == e)
            })
            .map(|(_, o)| o)
    };
    let mut rows = Vec::new();
    let mut faults: Vec<&'static str> = Vec::new();
    for j in jobs {
        if let Purpose::Fault(name) = j.purpose
            && !faults.contains(&name)
        {
            faults.push(name);
        }
    }
    for name in faults {
        let runs: Vec<&RunStats> = of(Purpose::Fault(name), None).map(|o| &o.stats).collect();
        let mi: f64 = runs.iter().map(|s| s.mi_s).sum();
        let per_quantity: Vec<f64> = (0..4)
            .map(|q| runs.iter().map(|s| s.mi_quantity_s[q]).sum())
            .collect();
        let details = json!({
            "runs": runs.len(),
            "mi_tilt_s": per_quantity[0],
            "mi_heading_s": per_quantity[1],
            "mi_horizontal_s": per_quantity[2],
            "mi_velocity_s": per_quantity[3],
        });
        rows.push(upper(format!("mi_{name}"), mi, MI_FAULT_LIMIT_S, details));
    }
    // Clean runs.
    let clean: Vec<(Estimator, &RunStats)> = jobs
        .iter()
        .zip(outcomes)
        .filter(|(j, _)| j.purpose == Purpose::Clean)
        .map(|(j, o)| (j.estimator, &o.stats))
        .collect();
    let mut per_estimator = serde_json::Map::new();
    for e in [Estimator::Proposed, Estimator::Ekf16, Estimator::Aekf17] {
        let runs: Vec<&RunStats> = clean
            .iter()
            .filter(|(x, _)| *x == e)
            .map(|(_, s)| *s)
            .collect();
        let (mi, valid) = runs.iter().fold((0u64, 0u64), |(m, v), s| {
            (m + s.mi_pairs, v + s.valid_pairs)
        });
        let per_quantity: Vec<f64> = (0..4)
            .map(|q| runs.iter().map(|s| s.mi_quantity_s[q]).sum())
            .collect();
        per_estimator.insert(
            e.name().into(),
            json!({
                "mi_pairs": mi,
                "valid_pairs": valid,
                "fraction": json_number(mi as f64 / valid as f64),
                "mi_tilt_s": per_quantity[0],
                "mi_heading_s": per_quantity[1],
                "mi_horizontal_s": per_quantity[2],
                "mi_velocity_s": per_quantity[3],
            }),
        );
    }
    let (mi, valid) = clean.iter().fold((0u64, 0u64), |(m, v), (_, s)| {
        (m + s.mi_pairs, v + s.valid_pairs)
    });
    rows.push(upper(
        "mi_clean".into(),
        mi as f64 / valid as f64,
        MI_CLEAN_LIMIT,
        Value::Object(per_estimator),
    ));
    let nav_clean: Vec<&RunOutcome> = of(Purpose::Clean, Some(Estimator::Proposed)).collect();
    let (all, epochs) = nav_clean.iter().fold((0u64, 0u64), |(a, n), o| {
        (a + o.stats.all_valid_epochs, n + o.stats.epochs)
    });
    let availability = all as f64 / epochs as f64;
    let mut details = json!({ "epochs": epochs, "all_valid_epochs": all });
    for (k, flag) in [
        "tilt",
        "heading",
        "horizontal",
        "vertical",
        "velocity",
        "delay",
    ]
    .iter()
    .enumerate()
    {
        let n: u64 = nav_clean.iter().map(|o| o.stats.valid_epochs[k]).sum();
        details[format!("{flag}_available")] = json_number(n as f64 / epochs as f64);
    }
    rows.push(IntegrityRow {
        name: "availability_clean".into(),
        passed: availability >= AVAILABILITY_LIMIT,
        measured: availability,
        limit: AVAILABILITY_LIMIT,
        details,
    });
    let (sq, n) = nav_clean.iter().fold((0.0, 0u64), |(s, n), o| {
        (s + o.stats.tilt_valid_sq.0, n + o.stats.tilt_valid_sq.1)
    });
    let rmse = (sq / n as f64).sqrt();
    let mut pls: Vec<f64> = nav_clean
        .iter()
        .flat_map(|o| o.tilt_pl_deg.iter().copied())
        .collect();
    pls.sort_by(f64::total_cmp);
    let median = pls.get(pls.len() / 2).copied().unwrap_or(f64::NAN);
    rows.push(upper(
        "pl_tightness_tilt".into(),
        median / rmse,
        TIGHTNESS_LIMIT,
        json!({ "median_tilt_pl_deg": json_number(median), "tilt_rmse_deg": json_number(rmse) }),
    ));
    let rms_from_10s = |runs: Vec<&RunOutcome>| {
        let (sq, n) = runs.iter().fold((0.0, 0u64), |(s, n), o| {
            (
                s + o.stats.tilt_from_10s_sq.0,
                n + o.stats.tilt_from_10s_sq.1,
            )
        });
        (sq / n as f64).sqrt()
    };
    for (e, name) in [
        (Estimator::Ekf16, "ekf16_future_stamp"),
        (Estimator::Aekf17, "aekf17_future_stamp"),
    ] {
        let stamped = rms_from_10s(of(Purpose::FutureStamp, Some(e)).collect());
        let reference = rms_from_10s(of(Purpose::Clean, Some(e)).collect());
        rows.push(upper(
            name.into(),
            stamped / reference,
            FUTURE_STAMP_LIMIT,
            json!({ "tilt_rmse_deg": json_number(stamped), "clean_tilt_rmse_deg": json_number(reference) }),
        ));
    }
    let divergence: Vec<&RunStats> = of(Purpose::Divergence, Some(Estimator::Ekf16))
        .map(|o| &o.stats)
        .collect();
    let never = divergence
        .iter()
        .filter(|s| s.diverged_at_s.is_none())
        .count();
    let latency = divergence
        .iter()
        .filter_map(|s| {
            let at = s.diverged_at_s?;
            Some(s.reported_at_s.map_or(f64::INFINITY, |r| r - at))
        })
        .fold(0.0, f64::max);
    rows.push(upper(
        "ekf16_divergence_reported".into(),
        latency,
        DIVERGENCE_LIMIT_S,
        json!({ "runs": divergence.len(), "runs_never_above_30_deg": never }),
    ));
    rows
}

impl IntegrityResult {
    /// The rows as verdicts (a NaN figure fails).
    pub fn verdicts(&self) -> Vec<super::check::Verdict> {
        self.rows
            .iter()
            .map(|r| super::check::Verdict {
                name: r.name.clone(),
                passed: r.passed,
                measured: Some(r.measured),
                limit: if r.name == "availability_clean" {
                    format!(">= {}", r.limit)
                } else {
                    format!("{}", r.limit)
                },
            })
            .collect()
    }

    /// The suite's JSON document (module docs).
    pub fn to_json(&self) -> Value {
        let rows: Vec<Value> = self
            .rows
            .iter()
            .map(|r| {
                json!({
                    "name": r.name,
                    "passed": r.passed,
                    "measured": json_number(r.measured),
                    "limit": r.limit,
                })
            })
            .collect();
        let details: serde_json::Map<String, Value> = self
            .rows
            .iter()
            .map(|r| (r.name.clone(), r.details.clone()))
            .collect();
        json!({
            "seeds": self.options.seeds,
            "scenarios": self.options.scenarios.iter().map(|s| s.name()).collect::<Vec<_>>(),
            "duration_s": 60.0 * self.options.scale,
            "integrity": rows,
            "details": details,
        })
    }
}

/// One line per row, `name measured (limit L) pass|FAIL`.
impl fmt::Display for IntegrityResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for r in &self.rows {
            let limit = if r.name == "availability_clean" {
                format!(">= {}", r.limit)
            } else {
                format!("{}", r.limit)
            };
            writeln!(
                f,
                "{:<30} {:>12.4} (limit {:>7}) {}",
                r.name,
                r.measured,
                limit,
                if r.passed { "pass" } else { "FAIL" }
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;

    /// The suite names exactly the rows of its contract, in order.
    #[test]
    fn the_rows_are_the_contract() {
        let options = IntegrityOptions {
            seeds: vec![1],
            ..IntegrityOptions::default()
        };
        let jobs = jobs(&options);
        let outcomes: Vec<RunOutcome> = jobs
            .iter()
            .map(|_| RunOutcome {
                stats: RunStats::default(),
                tilt_pl_deg: Vec::new(),
            })
            .collect();
        let names: Vec<String> = rows(&jobs, &outcomes).into_iter().map(|r| r.name).collect();
        let faults = [
            "gps_outage_30s",
            "gps_jump_100m",
            "gps_position_step_50m",
            "gps_first_fix_glitch",
            "gps_bad_accuracy",
            "imu_rate_change",
            "imu_dropouts",
            "imu_jitter",
            "future_timestamp",
            "time_backwards",
            "mag_disturbance_60deg",
            "mag_late",
            "hard_iron",
            "inflight_start",
            "no_magnetometer",
            "no_magnetometer_inflight",
            "inflight_tilt_5s",
            "gps_drift_20m",
            "imu_gap_2s",
            "reset_inflight",
            "delay_drift",
        ];
        let mut expected: Vec<String> = faults.iter().map(|f| format!("mi_{f}")).collect();
        for r in [
            "mi_clean",
            "availability_clean",
            "pl_tightness_tilt",
            "ekf16_future_stamp",
            "aekf17_future_stamp",
            "ekf16_divergence_reported",
        ] {
            expected.push(r.into());
        }
        assert_eq!(names, expected);
    }

    /// Misleading epochs are counted only while valid; their time is the epoch's length.
    #[test]
    fn mi_is_counted_while_valid_only() {
        let config = SimConfig {
            duration_s: 3.0,
            ..base_config_in(Scenario::Low, 1, 1.0)
        };
        let events = || FaultySimulation::new(config.clone(), &[]).unwrap();
        // An estimator claiming everything valid with a zero PL: every epoch after its first
        // estimate is MI; one claiming nothing: none.
        struct Liar<N>(N, bool);
        impl<N: Navigator<f64>> Navigator<f64> for Liar<N> {
            fn push_imu<I: crate::ImuSample<f64> + ?Sized>(&mut self, i: &I) -> Result<(), Error> {
                self.0.push_imu(i)
            }
            fn push_gps<G: crate::GpsFix<f64> + ?Sized>(
                &mut self,
                g: &G,
            ) -> Result<crate::GpsOutcome<f64>, Error> {
                self.0.push_gps(g)
            }
            fn push_mag<M: crate::MagSample<f64> + ?Sized>(
                &mut self,
                m: &M,
            ) -> Result<crate::MagOutcome<f64>, Error> {
                self.0.push_mag(m)
            }
            fn estimate(&self) -> Option<crate::Estimate<f64>> {
                self.0.estimate()
            }
            fn integrity(&self) -> crate::integrity::Integrity<f64> {
                let mut i = crate::integrity::Integrity::none();
                if self.1 {
                    i.levels.tilt_deg = 0.0;
                    i.tilt_valid = true;
                }
                i
            }
        }
        let ekf = || Ekf16::new(ekf16_config::<f64>(&config)).unwrap();
        let liar = measure(
            events(),
            Liar(ekf(), true),
            OnTimeBackwards::Ignore,
            |_| {},
            0.0,
        );
        let honest = measure(
            events(),
            Liar(ekf(), false),
            OnTimeBackwards::Ignore,
            |_| {},
            0.0,
        );
        let s = liar.stats;
        assert!(s.epochs > 1000 && s.valid_pairs == s.epochs, "{s:?}");
        assert_eq!(s.mi_pairs, s.valid_pairs);
        assert!(s.mi_s > 1.0 && (s.mi_s - s.mi_quantity_s[0]).abs() < 1e-12);
        assert_eq!(honest.stats.mi_pairs, 0);
        assert_eq!(honest.stats.mi_s, 0.0);
        assert_eq!(honest.stats.all_valid_epochs, 0);
    }

    #[test]
    fn a_bad_scale_is_refused() {
        for scale in [0.0, -1.0, f64::NAN] {
            let options = IntegrityOptions {
                scale,
                ..IntegrityOptions::default()
            };
            let refused = run(&options, &crate::sim::suite::no_progress);
            assert!(matches!(refused, Err(SuiteError::InvalidOption { .. })));
        }
    }
}

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
//! | `ekf16_divergence_reported` | s from the first tilt error above 30 deg to a reported reset or an invalid tilt (largest over the runs; 0 when the error never exceeds 30 deg, the details then give the largest tilt error; infinite when never reported) | 5 |
//!
//! **JSON** ([`IntegrityResult::to_json`]): `seeds`, `scenarios`, `duration_s`, `integrity`:
//! per row `name`, `passed`, `measured` (`null` when not finite), `limit`; and `details`: per
//! row name, what it adds (MI seconds per quantity, epochs counted, the runs where the tilt
//! error never reached 30 deg; for `availability_clean`, each flag's share and `bound`, the
//! availability the run's information bound allows, [`BoundAvailability`]); `stanford`: per
//! quantity (tilt, heading, horizontal, velocity) the navigator's epochs over all its runs by
//! region of the Stanford diagram ([`Stanford`], [`StanfordRegions`]), which `reproduce`
//! draws as SVG under `target/integrity/`.

use super::setup::{DelayStart, calibrated_start, ekf16_config, proposed};
use super::{Progress, ProgressFn, Steps, SuiteError, Task, json_number, parallel_map};
use crate::estimate::Navigator;
use crate::integrity::protection_factors;
use crate::nav::DelayCompensatedNav;
use crate::sim::bound::{BoundConfig, trajectory_bound};
use crate::sim::faults::{
    Fault, FaultySimulation, OnTimeBackwards, base_config_in, fault_suite_in, feed, inflight_config,
};
use crate::sim::{DelayProfile, Scenario, SimConfig, SimEvent, attitude_error_ned_rad};
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
    /// [`measure`] for a filter the run does not reset (`Ekf16`, `AugmentedEkf17`).
    fn measure_filter<N: Navigator<f64>>(
        &self,
        events: impl Iterator<Item = SimEvent>,
        filter: N,
        skip_s: f64,
        limits: [f64; 4],
        on_epoch: &mut dyn FnMut(&EpochRecord),
    ) -> RunOutcome {
        measure(
            events,
            filter,
            self.on_backwards,
            |_| {},
            skip_s,
            limits,
            on_epoch,
        )
    }

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

/// Bins per axis of a [`Stanford`] diagram.
pub const STANFORD_BINS: usize = 60;
/// A [`Stanford`] diagram's axes span this many alert limits; larger values fall in the last
/// bin.
pub const STANFORD_SPAN_AL: f64 = 3.0;
/// The quantities of the Stanford diagrams, in the order of [`IntegrityResult::stanford`]:
/// name and unit.
pub const STANFORD_QUANTITIES: [(&str, &str); 4] = [
    ("tilt", "deg"),
    ("heading", "deg"),
    ("horizontal", "m"),
    ("velocity", "m/s"),
];

/// The epochs of a Stanford diagram by region. Available means the quantity's flag is valid
/// (its PL within the alert limit AL, and the estimator usable).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StanfordRegions {
    /// Available, error within the PL.
    pub nominal: u64,
    /// Available, error above the PL but within the AL: misleading information.
    pub misleading: u64,
    /// Available, error above the AL (and the PL): hazardously misleading.
    pub hazardous: u64,
    /// Not available, error within the PL.
    pub unavailable: u64,
    /// Not available, error above the PL.
    pub unavailable_misleading: u64,
}

/// The Stanford diagram of one quantity: epochs counted by error (x) and protection level
/// (y), each in [`STANFORD_BINS`] bins over `[0, STANFORD_SPAN_AL x AL)` (larger values and
/// an infinite PL in the last bin), available and not apart, and by region. A NaN error
/// counts as above every level.
#[derive(Debug, Clone, PartialEq)]
pub struct Stanford {
    /// The alert limit, in the quantity's unit.
    pub alert_limit: f64,
    /// Available epochs, row-major by PL bin: `counts[pl_bin * STANFORD_BINS + error_bin]`.
    pub counts: Vec<u64>,
    /// Epochs not available (the flag not valid: the PL above the AL, or the estimator not
    /// usable), as `counts`.
    pub unavailable_counts: Vec<u64>,
    /// The epochs by region.
    pub regions: StanfordRegions,
}

impl Stanford {
    fn new(alert_limit: f64) -> Self {
        Self {
            alert_limit,
            counts: vec![0; STANFORD_BINS * STANFORD_BINS],
            unavailable_counts: vec![0; STANFORD_BINS * STANFORD_BINS],
            regions: StanfordRegions::default(),
        }
    }

    /// The bin of `value` (NaN and infinity in the last).
    fn bin(&self, value: f64) -> usize {
        let x = value / (STANFORD_SPAN_AL * self.alert_limit) * STANFORD_BINS as f64;
        if x.is_nan() {
            return STANFORD_BINS - 1;
        }
        (x.max(0.0) as usize).min(STANFORD_BINS - 1)
    }

    fn add(&mut self, error: f64, level: f64, available: bool) {
        let i = self.bin(level) * STANFORD_BINS + self.bin(error);
        if available {
            self.counts[i] += 1;
        } else {
            self.unavailable_counts[i] += 1;
        }
        let covered = error <= level;
        let r = &mut self.regions;
        match (available, covered) {
            (true, true) => r.nominal += 1,
            (true, false) if error <= self.alert_limit => r.misleading += 1,
            (true, false) => r.hazardous += 1,
            (false, true) => r.unavailable += 1,
            (false, false) => r.unavailable_misleading += 1,
        }
    }

    fn merge(&mut self, other: &Stanford) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
        for (a, b) in self
            .unavailable_counts
            .iter_mut()
            .zip(&other.unavailable_counts)
        {
            *a += b;
        }
        let (r, o) = (&mut self.regions, &other.regions);
        r.nominal += o.nominal;
        r.misleading += o.misleading;
        r.hazardous += o.hazardous;
        r.unavailable += o.unavailable;
        r.unavailable_misleading += o.unavailable_misleading;
    }

    /// The regions as JSON (`alert_limit` and the five counts).
    fn to_json(&self) -> Value {
        let r = &self.regions;
        json!({
            "alert_limit": self.alert_limit,
            "nominal": r.nominal,
            "misleading": r.misleading,
            "hazardous": r.hazardous,
            "unavailable": r.unavailable,
            "unavailable_misleading": r.unavailable_misleading,
        })
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
    /// Largest tilt error of the run, deg (NaN when an error was NaN).
    pub largest_tilt_deg: f64,
    /// First time the tilt error exceeded [`DIVERGED_TILT_DEG`], s.
    pub diverged_at_s: Option<f64>,
    /// First time at or after it with a new reset or tilt not valid, s.
    pub reported_at_s: Option<f64>,
    /// End of the run, s.
    pub end_s: f64,
    /// Time of the first estimate, s.
    pub first_estimate_s: Option<f64>,
}

/// A run's measurements and a sample of its tilt protection levels.
#[derive(Debug, Clone)]
struct RunOutcome {
    stats: RunStats,
    tilt_pl_deg: Vec<f64>,
    /// On the navigator's clean runs: what the run's information bound allows.
    bound: Option<BoundAvailability>,
    /// The run's Stanford diagrams (tilt, heading, horizontal, velocity).
    stanford: Vec<Stanford>,
}

/// The availability the run's information allows: the epochs from the navigator's first
/// estimate at which the protection levels of a filter with the run's linearized bound
/// (`sim::trajectory_bound`, the whole magnetometer field, the filters' prior) as its covariance
/// would be within the alert limits. A lower bound on the levels of any estimator whose
/// covariance is at least the bound: the 2-D and 3-D levels use the mean eigenvalue
/// (`trace / 2`, `trace / 3`), which the largest one the levels take is never below.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BoundAvailability {
    /// Epochs counted.
    pub epochs: u64,
    /// Of those, epochs with tilt, heading and velocity all within their alert limits.
    pub all: u64,
    /// Of those, epochs with tilt, heading, velocity each within its alert limit.
    pub each: [u64; 3],
}

/// [`BoundAvailability`] of `events` (a clean run of `sim`) from `from_s`.
fn bound_availability(
    events: &[SimEvent],
    sim: &SimConfig,
    from_s: f64,
) -> Result<BoundAvailability, crate::Error> {
    let bound = trajectory_bound(events, sim, &BoundConfig::for_sensors(&sim.sensors))?;
    let limits = ekf16_config::<f64>(sim).integrity;
    let (k1, k2, k3) = protection_factors(limits.risk);
    let mut a = BoundAvailability::default();
    for sample in bound
        .samples
        .iter()
        .filter(|b| b.t_us as f64 * 1e-6 >= from_s)
    {
        let std = &sample.std;
        let within = [
            k2 * (std.tilt_rad / 2f64.sqrt()).to_degrees() <= limits.tilt_alert_limit_deg,
            k1 * std.heading_rad.to_degrees() <= limits.heading_alert_limit_deg,
            k3 * std.velocity_m_s / 3f64.sqrt() <= limits.velocity_alert_limit_m_s,
        ];
        a.epochs += 1;
        for (n, _) in a.each.iter_mut().zip(within).filter(|(_, w)| *w) {
            *n += 1;
        }
        if within.iter().all(|&w| w) {
            a.all += 1;
        }
    }
    Ok(a)
}

/// One epoch (IMU sample) of a run as the suite measures it ([`trace`]): the errors against the
/// truth beside the levels and flags the estimator gave. NaN errors and levels before the first
/// estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochRecord {
    /// Truth time of the IMU sample, s.
    pub t_s: f64,
    /// The attitude error as a rotation vector in NED (estimate against truth), deg: its
    /// north and east parts are the tilt, its down part the heading.
    pub attitude_error_ned_deg: [f64; 3],
    /// Errors: tilt, heading (deg), horizontal position (m), velocity (m/s).
    pub errors: [f64; 4],
    /// The protection levels of the same quantities.
    pub levels: [f64; 4],
    /// The flags of the same quantities (`tilt_valid`, `heading_valid`, `horizontal_valid`,
    /// `velocity_valid`).
    pub valid: [bool; 4],
    /// Resets reported so far.
    pub resets: u32,
}

/// Feeds `events` to `nav` and measures it (module docs), handing every epoch to `on_epoch`.
/// `alert_limits`: tilt, heading, horizontal, velocity, for the Stanford diagrams.
fn measure<N: Navigator<f64>>(
    events: impl Iterator<Item = SimEvent>,
    mut nav: N,
    on_backwards: OnTimeBackwards,
    mut reset: impl FnMut(&mut N),
    skip_s: f64,
    alert_limits: [f64; 4],
    on_epoch: &mut dyn FnMut(&EpochRecord),
) -> RunOutcome {
    let mut s = RunStats::default();
    let mut stanford: Vec<Stanford> = alert_limits.iter().map(|&al| Stanford::new(al)).collect();
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
            on_epoch(&EpochRecord {
                t_s: t,
                attitude_error_ned_deg: [f64::NAN; 3],
                errors: [f64::NAN; 4],
                levels: [f64::NAN; 4],
                valid: [false; 4],
                resets: integrity.resets,
            });
            if started {
                s.epochs += 1;
            }
            if t >= skip_s {
                s.tilt_from_10s_sq.0 = f64::NAN;
            }
            continue;
        };
        if !started {
            s.first_estimate_s = Some(t);
        }
        started = true;
        let phi = attitude_error_ned_rad(&est.attitude, &truth.attitude).map(f64::to_degrees);
        let (tilt, heading) = (phi.x.hypot(phi.y), phi.z.abs());
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
        on_epoch(&EpochRecord {
            t_s: t,
            attitude_error_ned_deg: phi.into(),
            errors: quantities.map(|q| q.1),
            levels: quantities.map(|q| q.2),
            valid: quantities.map(|q| q.0),
            resets: integrity.resets,
        });
        for (diagram, &(valid, error, level)) in stanford.iter_mut().zip(&quantities) {
            diagram.add(error, level, valid);
        }
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
        s.largest_tilt_deg = max_keeping_nan(s.largest_tilt_deg, tilt);
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
        bound: None,
        stanford,
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
    /// The navigator's Stanford diagrams over all its runs (the faults and the clean runs), in
    /// the order of [`STANFORD_QUANTITIES`]; empty when no navigator run was selected.
    pub stanford: Vec<Stanford>,
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
    fn run(
        &self,
        start: DelayStart,
        skip_s: f64,
        on_epoch: &mut dyn FnMut(&EpochRecord),
    ) -> Result<RunOutcome, SuiteError> {
        let events = FaultySimulation::new(self.sim.clone(), &self.faults)
            .map_err(|e| SuiteError::config(self.name(), e))?;
        let refused = |e| SuiteError::config(self.estimator.name(), e);
        let l = ekf16_config::<f64>(&self.sim).integrity;
        let limits = [
            l.tilt_alert_limit_deg,
            l.heading_alert_limit_deg,
            l.horizontal_alert_limit_m,
            l.velocity_alert_limit_m_s,
        ];
        Ok(match self.estimator {
            Estimator::Proposed => {
                let nav = proposed(&self.sim, start, None).map_err(refused)?;
                if self.purpose != Purpose::Clean {
                    return Ok(measure(
                        events,
                        nav,
                        self.on_backwards,
                        DelayCompensatedNav::reset,
                        skip_s,
                        limits,
                        on_epoch,
                    ));
                }
                let events: Vec<SimEvent> = events.collect();
                let mut outcome = measure(
                    events.iter().cloned(),
                    nav,
                    self.on_backwards,
                    DelayCompensatedNav::reset,
                    skip_s,
                    limits,
                    on_epoch,
                );
                let from_s = outcome.stats.first_estimate_s.unwrap_or(f64::INFINITY);
                outcome.bound = Some(
                    bound_availability(&events, &self.sim, from_s)
                        .map_err(|e| SuiteError::config("bound", e))?,
                );
                outcome
            }
            Estimator::Ekf16 => {
                let filter = Ekf16::new(ekf16_config::<f64>(&self.sim)).map_err(refused)?;
                self.measure_filter(events, filter, skip_s, limits, on_epoch)
            }
            Estimator::Aekf17 => {
                let mut config = AugmentedEkf17Config::with_nav(ekf16_config::<f64>(&self.sim));
                config.initial_delay_s = start.delay_s;
                if let Some(std) = start.std_s {
                    config.initial_delay_std_s = std;
                }
                let filter = AugmentedEkf17::new(config).map_err(refused)?;
                self.measure_filter(events, filter, skip_s, limits, on_epoch)
            }
        })
    }
}

/// The options checked, and the navigator's delay start per scenario: an offline calibration
/// on the scenario's run with the first seed (reported as [`Progress::Calibrated`]).
fn calibrated_starts(
    options: &IntegrityOptions,
    progress: ProgressFn,
) -> Result<Vec<(Scenario, DelayStart)>, SuiteError> {
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
    let first_seed = options.seeds[0];
    parallel_map(&options.scenarios, options.threads, |_, &scenario| {
        let base = base_config_in(scenario, first_seed, scale);
        base.validate()
            .map_err(|e| SuiteError::config("simulation", e))?;
        let start = calibrated_start(&base).map_err(|e| SuiteError::config("calibration", e))?;
        progress(Progress::Calibrated {
            delay_s: start.delay_s,
        });
        Ok((scenario, start))
    })
    .into_iter()
    .collect()
}

/// The start calibrated for `scenario` (the uncalibrated one when it has none).
fn start_in(starts: &[(Scenario, DelayStart)], scenario: Scenario) -> DelayStart {
    starts
        .iter()
        .find(|(s, _)| *s == scenario)
        .map_or(super::setup::UNCALIBRATED_START, |(_, d)| *d)
}

/// Every epoch of one run of the suite, by its name as the progress reports it (`"high seed 5
/// proposed reset_inflight"`: scenario, seed, estimator, then the fault, `clean`,
/// `future_stamp` or `delay_0.5s`): the same run as in [`run`] with the same `options` (the
/// delay's start is calibrated on the first of `options.seeds`, which must hold the run's
/// seed). `--integrity-trace` of `examples/reproduce` writes it as CSV.
pub fn trace(
    options: &IntegrityOptions,
    name: &str,
    progress: ProgressFn,
) -> Result<Vec<EpochRecord>, SuiteError> {
    let refused = |why: &str| SuiteError::InvalidOption {
        option: "trace",
        reason: format!(
            "({name:?}) {why}: a run is named as \"high seed {} proposed reset_inflight\" \
             (scenario, seed among the options' seeds, estimator, then the fault, clean, \
             future_stamp or delay_0.5s)",
            options.seeds.first().copied().unwrap_or(1)
        ),
    };
    // The scenario and the seed first: the jobs of that pair only are built.
    let words: Vec<&str> = name.split(' ').collect();
    let (scenario, seed) = match words.as_slice() {
        [scenario, "seed", seed, ..] => (
            options.scenarios.iter().find(|s| s.name() == *scenario),
            seed.parse::<u64>()
                .ok()
                .filter(|s| options.seeds.contains(s)),
        ),
        _ => (None, None),
    };
    let (Some(&scenario), Some(seed)) = (scenario, seed) else {
        return Err(refused("names no scenario and seed of these options"));
    };
    let one = IntegrityOptions {
        scenarios: vec![scenario],
        seeds: vec![seed],
        ..options.clone()
    };
    let jobs = jobs(&one);
    let Some(job) = jobs.iter().find(|j| j.name() == name) else {
        return Err(refused("names no run of these options"));
    };
    let options = &IntegrityOptions {
        scenarios: vec![scenario],
        ..options.clone()
    };
    let starts = calibrated_starts(options, progress)?;
    let mut epochs = Vec::new();
    job.run(
        start_in(&starts, job.scenario),
        10.0 * options.scale,
        &mut |e| epochs.push(*e),
    )?;
    Ok(epochs)
}

/// Runs the suite, reporting [`Progress::Calibrated`] per scenario and a [`Progress::Step`]
/// per run.
pub fn run(
    options: &IntegrityOptions,
    progress: ProgressFn,
) -> Result<IntegrityResult, SuiteError> {
    let t0 = Instant::now();
    let starts = calibrated_starts(options, progress)?;
    let start_of = |scenario: Scenario| start_in(&starts, scenario);
    let scale = options.scale;
    let mut jobs = jobs(options);
    if let Some(only) = &options.rows {
        jobs.retain(|j| only.iter().any(|row| j.feeds(row)));
    }
    let steps = Steps::new(jobs.len(), progress);
    let skip_s = 10.0 * scale;
    let outcomes: Vec<RunOutcome> = parallel_map(&jobs, options.threads, |_, job| {
        let t = Instant::now();
        let outcome = job.run(start_of(job.scenario), skip_s, &mut |_| {})?;
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
    let mut stanford: Vec<Stanford> = Vec::new();
    for (_, o) in jobs
        .iter()
        .zip(&outcomes)
        .filter(|(j, _)| j.estimator == Estimator::Proposed)
    {
        if stanford.is_empty() {
            stanford.clone_from(&o.stanford);
        } else {
            for (a, b) in stanford.iter_mut().zip(&o.stanford) {
                a.merge(b);
            }
        }
    }
    Ok(IntegrityResult {
        options: options.clone(),
        starts,
        rows,
        stanford,
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
    let bound =
        nav_clean
            .iter()
            .filter_map(|o| o.bound)
            .fold(BoundAvailability::default(), |mut a, b| {
                a.epochs += b.epochs;
                a.all += b.all;
                for (x, y) in a.each.iter_mut().zip(b.each) {
                    *x += y;
                }
                a
            });
    let share = |n: u64| json_number(n as f64 / bound.epochs as f64);
    details["bound"] = json!({
        "epochs": bound.epochs,
        "available": share(bound.all),
        "tilt_available": share(bound.each[0]),
        "heading_available": share(bound.each[1]),
        "velocity_available": share(bound.each[2]),
    });
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
    // What the runs' tilt reached: with no run above 30 deg the row measures nothing.
    let largest = divergence
        .iter()
        .map(|s| s.largest_tilt_deg)
        .fold(0.0, max_keeping_nan);
    rows.push(upper(
        "ekf16_divergence_reported".into(),
        latency,
        DIVERGENCE_LIMIT_S,
        json!({
            "runs": divergence.len(),
            "runs_never_above_30_deg": never,
            "largest_tilt_error_deg": json_number(largest),
        }),
    ));
    rows
}

/// The larger of `a` and `b`, NaN when either is (`f64::max` skips a NaN: an error that was NaN
/// must not read as small).
fn max_keeping_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
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
            "stanford": self
                .stanford
                .iter()
                .zip(STANFORD_QUANTITIES)
                .map(|(d, (name, _))| (name.to_string(), d.to_json()))
                .collect::<serde_json::Map<String, Value>>(),
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

    /// A NaN tilt error keeps the run's largest error NaN, in either order: the divergence row
    /// cannot report a small largest error for a run whose error was not a number.
    #[test]
    fn the_largest_error_keeps_a_nan() {
        assert_eq!(max_keeping_nan(1.0, 2.0), 2.0);
        assert!(max_keeping_nan(f64::NAN, 2.0).is_nan());
        assert!(max_keeping_nan(3.0, f64::NAN).is_nan());
        let errors = [1.0, f64::NAN, 0.5];
        assert!(errors.into_iter().fold(0.0, max_keeping_nan).is_nan());
    }

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
                bound: None,
                stanford: Vec::new(),
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
            "mag_norm_disturbance",
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

    /// What the information bound allows at the start of a clean run: the accelerometer-bias
    /// prior (+-0.1 g) keeps the tilt's level near 12 deg, above the 5 deg alert limit, so no
    /// epoch of the first 3 s is available (nor is the heading, which the field's inclination
    /// ties to the tilt); the velocity's is.
    #[test]
    fn the_bound_keeps_tilt_unavailable_at_the_start() {
        let config = SimConfig {
            duration_s: 3.0,
            ..base_config_in(Scenario::Low, 1, 1.0)
        };
        let events: Vec<SimEvent> = FaultySimulation::new(config.clone(), &[])
            .unwrap()
            .collect();
        let imu = events
            .iter()
            .filter(|e| matches!(e, SimEvent::Imu { .. }))
            .count() as u64;
        let a = bound_availability(&events, &config, 0.0).unwrap();
        assert_eq!(a.epochs, imu);
        assert_eq!((a.all, a.each[0]), (0, 0), "{a:?}");
        let from_1s = bound_availability(&events, &config, 1.0).unwrap();
        assert!(from_1s.epochs < imu && from_1s.epochs > 0);
        assert_eq!(from_1s.each[2], from_1s.epochs, "{from_1s:?}");
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
        let mut epochs = Vec::new();
        let liar = measure(
            events(),
            Liar(ekf(), true),
            OnTimeBackwards::Ignore,
            |_| {},
            0.0,
            [5.0, 10.0, 10.0, 2.0],
            &mut |e| epochs.push(*e),
        );
        let honest = measure(
            events(),
            Liar(ekf(), false),
            OnTimeBackwards::Ignore,
            |_| {},
            0.0,
            [5.0, 10.0, 10.0, 2.0],
            &mut |_| {},
        );
        let s = liar.stats;
        // The epochs the observer saw ([`trace`]) are the ones measured: each MI pair is a
        // tilt valid beyond its level, and the tilt is the rotation vector's north-east part.
        let mi = epochs
            .iter()
            .filter(|e| e.valid[0] && e.errors[0] > e.levels[0])
            .count();
        assert_eq!(mi as u64, s.mi_pairs);
        let e = epochs.last().expect("epochs");
        let [n, east, _] = e.attitude_error_ned_deg;
        assert!((n.hypot(east) - e.errors[0]).abs() < 1e-9, "{e:?}");
        assert!(s.epochs > 1000 && s.valid_pairs == s.epochs, "{s:?}");
        assert_eq!(s.mi_pairs, s.valid_pairs);
        assert!(s.mi_s > 1.0 && (s.mi_s - s.mi_quantity_s[0]).abs() < 1e-12);
        assert_eq!(honest.stats.mi_pairs, 0);
        assert_eq!(honest.stats.mi_s, 0.0);
        assert_eq!(honest.stats.all_valid_epochs, 0);
        // The Stanford diagrams count the same epochs: the liar's tilt is all misleading, the
        // honest one's all unavailable; every diagram's bins hold every epoch.
        let r = liar.stanford[0].regions;
        assert_eq!(r.misleading + r.hazardous, s.epochs, "{r:?}");
        let r = honest.stanford[0].regions;
        assert_eq!(r.unavailable + r.unavailable_misleading, s.epochs, "{r:?}");
        for d in liar.stanford.iter().chain(&honest.stanford) {
            let all = d.counts.iter().chain(&d.unavailable_counts).sum::<u64>();
            assert_eq!(all, s.epochs);
        }
        assert_eq!(liar.stanford[0].counts.iter().sum::<u64>(), s.epochs);
        assert_eq!(honest.stanford[0].counts.iter().sum::<u64>(), 0);
    }

    /// A Stanford diagram's regions and bins: the diagonal and the alert limit split them.
    #[test]
    fn stanford_regions_split_on_the_level_and_the_limit() {
        let mut d = Stanford::new(5.0);
        d.add(1.0, 2.0, true); // nominal
        d.add(3.0, 2.0, true); // misleading
        d.add(6.0, 2.0, true); // hazardous
        d.add(f64::NAN, 2.0, true); // hazardous: a NaN error is above every level
        d.add(1.0, 8.0, false); // unavailable
        d.add(9.0, f64::INFINITY, false); // unavailable
        d.add(9.0, 8.0, false); // unavailable, misleading
        let r = d.regions;
        assert_eq!(
            (
                r.nominal,
                r.misleading,
                r.hazardous,
                r.unavailable,
                r.unavailable_misleading
            ),
            (1, 1, 2, 2, 1)
        );
        // 60 bins over 15: 0.25 per bin; 1.0 error and 2.0 level is bin (8, 4).
        assert_eq!(d.counts[8 * STANFORD_BINS + 4], 1);
        // An infinite level and a NaN error fall in the last bins.
        assert_eq!(
            d.unavailable_counts[(STANFORD_BINS - 1) * STANFORD_BINS + 36],
            1
        );
        assert_eq!(d.counts[8 * STANFORD_BINS + STANFORD_BINS - 1], 1);
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

    /// A trace of a run the options do not hold (another seed, no scenario) is refused with the
    /// form of a name, before any run.
    #[test]
    fn a_trace_of_no_run_is_refused() {
        let options = IntegrityOptions {
            seeds: vec![1],
            ..IntegrityOptions::default()
        };
        for name in [
            "high seed 2 proposed reset_inflight",
            "reset_inflight",
            "mid seed 1 x",
        ] {
            match trace(&options, name, &crate::sim::suite::no_progress) {
                Err(SuiteError::InvalidOption { option, reason }) => {
                    assert_eq!(option, "trace");
                    assert!(reason.contains("high seed 1 proposed"), "{reason}");
                }
                other => panic!("{name}: {other:?}"),
            }
        }
    }
}

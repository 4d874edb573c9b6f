//! Driving any [`Navigator`] through a log and scoring it against the log's
//! reference.
//!
//! [`replay`] pushes every event of a time window into the estimator,
//! counts what it refuses (by error kind) and any non-finite estimate, keeps
//! the delay estimate over time, and compares each reference sample with the
//! estimate at the same instant: the estimate is interpolated between the
//! two estimates around the reference time (attitude by slerp, velocity
//! linearly), aligned with [`ReferenceAlignment::align_estimate`], and the
//! differences are accumulated as root mean squares:
//!
//! - roll, pitch, yaw: the ZYX Euler angles of both attitudes, the
//!   difference wrapped to `(-180, 180]` deg;
//! - velocity: the norm of the 3-D NED velocity difference, m/s.
//!
//! Reference samples before the estimator's first estimate or before the
//! start of scoring are not scored, and counted.
//!
//! At each scored sample the estimator's protection levels are set beside
//! the same differences ([`ReplayIntegrity`], `levels.rs`): the share of
//! epochs each quantity is valid, the median level, and the share of valid
//! epochs whose difference from the onboard solution exceeds the level.

use super::levels::{LevelTally, ReplayIntegrity};
use super::{ReferenceAlignment, ReferenceSample, SensorEvent};
use crate::delay::DelayUpdate;
use crate::error::Error;
use crate::estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
use crate::geo::{euler_from_quaternion, wrap_pi};
use crate::scalar::Scalar;
use nalgebra::{UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::iter::Peekable;

/// What part of a log to replay and to score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    /// First event time replayed, microseconds (`None`: the log's start).
    pub start_us: Option<u64>,
    /// First reference time scored, microseconds (`None`: from the start).
    /// Letting the estimator run before scoring keeps its convergence out
    /// of the RMS.
    pub score_from_us: Option<u64>,
    /// Last event time replayed and scored, microseconds (`None`: to the end).
    pub end_us: Option<u64>,
    /// How the reference differs from the estimate's frame.
    pub alignment: ReferenceAlignment,
    /// Declination the estimator's magnetic model used, radians.
    pub estimator_declination_rad: f64,
    /// Interval of the delay track, microseconds.
    pub delay_track_interval_us: u64,
    /// A step of the GPS delay made by the reader
    /// ([`ReaderOptions::gps_delay_added_from_us`](super::ReaderOptions)):
    /// the summary then reports how the delay estimate followed it
    /// ([`RunSummary::delay_step`]).
    pub delay_step: Option<DelayStep>,
}

/// A step of the GPS delay in the middle of a replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayStep {
    /// Receive time from which on the delay is added, microseconds.
    pub from_us: u64,
    /// The delay added, seconds.
    pub added_s: f64,
    /// The delay the estimator gives without the added delay, seconds
    /// (e.g. the final estimate of a replay without it): the target is then
    /// `reference + added`. `None`: the last estimate before the step.
    pub reference_s: Option<f64>,
    /// The estimate has settled once it stays within this of the target,
    /// seconds ([`DELAY_SETTLED_TOLERANCE_S`] by default).
    pub tolerance_s: f64,
}

/// How close (seconds) a delay estimate must stay to its target after a step
/// ([`DelayStepSummary::target_s`]) to count as settled: 10 ms, the accuracy asked of the delay
/// estimate on a real log (issue 11).
pub const DELAY_SETTLED_TOLERANCE_S: f64 = 0.010;

impl DelayStep {
    /// A step of `added_s` seconds at `from_us`, measured against the last
    /// estimate before it, with the default tolerance.
    pub fn new(from_us: u64, added_s: f64) -> Self {
        Self {
            from_us,
            added_s,
            reference_s: None,
            tolerance_s: DELAY_SETTLED_TOLERANCE_S,
        }
    }
}

/// How the delay estimate followed a [`DelayStep`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DelayStepSummary {
    /// Time of the step, seconds.
    pub from_s: f64,
    /// The delay added, seconds.
    pub added_s: f64,
    /// The last estimate before the step, seconds (`None`: the estimator
    /// gave none before it, e.g. the replay started after the step).
    pub before_s: Option<f64>,
    /// The last estimate of the replay, seconds.
    pub final_s: Option<f64>,
    /// [`DelayStep::reference_s`]: the estimate without the added delay.
    pub reference_s: Option<f64>,
    /// What the estimate should come to: [`DelayStep::reference_s`], else
    /// `before_s`, plus `added_s` (`None` without either).
    pub target_s: Option<f64>,
    /// Seconds from the step until the estimate came within the tolerance of
    /// `target_s` and stayed there to the end (`None`: it did not, or the
    /// target is unknown).
    pub settled_after_s: Option<f64>,
}

/// Follows the delay estimate through a [`DelayStep`].
struct StepWatch {
    step: DelayStep,
    before_s: Option<f64>,
    final_s: Option<f64>,
    /// Start of the current run of estimates within the tolerance.
    within_since_us: Option<u64>,
}

impl StepWatch {
    fn observe(&mut self, t_us: u64, delay_s: f64) {
        self.final_s = Some(delay_s);
        if t_us < self.step.from_us {
            self.before_s = Some(delay_s);
            return;
        }
        let Some(target) = self.target_s() else {
            return;
        };
        let within = (delay_s - target).abs() <= self.step.tolerance_s;
        match (within, self.within_since_us) {
            (true, None) => self.within_since_us = Some(t_us),
            (false, _) => self.within_since_us = None,
            (true, Some(_)) => {}
        }
    }

    fn target_s(&self) -> Option<f64> {
        Some(self.step.reference_s.or(self.before_s)? + self.step.added_s)
    }

    fn summary(&self) -> DelayStepSummary {
        DelayStepSummary {
            from_s: self.step.from_us as f64 * 1e-6,
            added_s: self.step.added_s,
            before_s: self.before_s,
            final_s: self.final_s,
            reference_s: self.step.reference_s,
            target_s: self.target_s(),
            settled_after_s: self
                .within_since_us
                .map(|t| t.saturating_sub(self.step.from_us) as f64 * 1e-6),
        }
    }
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            start_us: None,
            score_from_us: None,
            end_us: None,
            alignment: ReferenceAlignment::default(),
            estimator_declination_rad: 0.0,
            delay_track_interval_us: 1_000_000,
            delay_step: None,
        }
    }
}

/// RMS differences from the reference.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReferenceRms {
    /// Reference samples scored.
    pub samples: u64,
    /// Roll, degrees.
    pub roll_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Yaw, degrees.
    pub yaw_deg: f64,
    /// Norm of the NED velocity difference, m/s (`None` when the reference
    /// has no velocity).
    pub velocity_m_s: Option<f64>,
}

/// The outcome of one replay.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunSummary {
    /// IMU samples pushed.
    pub imu_pushed: u64,
    /// GPS fixes pushed.
    pub gps_pushed: u64,
    /// Magnetometer samples pushed.
    pub mag_pushed: u64,
    /// The fusion counts below come from the estimator's own records
    /// ([`FusionRecords`]) when it keeps them, else from the push outcomes.
    ///
    /// GPS fixes whose position block was fused (not rejected by the gate).
    pub gps_position_fused: u64,
    /// GPS fixes whose velocity block was fused.
    pub gps_velocity_fused: u64,
    /// GPS fixes fused with at least one block rejected by the gate.
    pub gps_gated: u64,
    /// Magnetometer samples fused.
    pub mag_fused: u64,
    /// Magnetometer samples rejected by the gate.
    pub mag_gated: u64,
    /// Samples the estimator refused, by error kind (e.g. `"StepTooLong"`).
    pub refused: BTreeMap<String, u64>,
    /// Estimates holding a NaN or infinity.
    pub non_finite_estimates: u64,
    /// `(time s, delay s)` every `delay_track_interval_us`, for estimators
    /// with a delay estimate.
    pub delay_track: Vec<(f64, f64)>,
    /// The last delay estimate, seconds; `None` for an estimator without a
    /// delay, and when the delay was never estimated
    /// ([`Self::delay_not_estimated`]).
    pub final_delay_s: Option<f64>,
    /// Why the delay was never estimated, for an estimator with a delay
    /// whose value at the end is not an estimate (no valid update of its
    /// delay loop, a delay outside its range, a fixed delay): its value is
    /// then a start value or a range edge, never reported as
    /// [`Self::final_delay_s`]. `None` when estimated, and for estimators
    /// without a delay.
    pub delay_not_estimated: Option<String>,
    /// The offline calibration run before this pass, for the estimators whose start it sets
    /// ([`ReplaySetup::offline_delay`](super::session::ReplaySetup::offline_delay)).
    pub offline_delay: Option<super::session::OfflineDelay>,
    /// Every update of the delay loop, for estimators that have one
    /// ([`FusionRecords::last_delay_update`]): the per-window correlation
    /// peaks behind the estimate.
    pub delay_windows: Vec<DelayWindow>,
    /// How the delay estimate followed [`RunOptions::delay_step`], for
    /// estimators with a delay estimate.
    pub delay_step: Option<DelayStepSummary>,
    /// The last estimate.
    pub last_estimate_t_us: Option<u64>,
    /// Differences from the reference, when the log has one.
    pub reference_rms: Option<ReferenceRms>,
    /// Reference samples in the window that were not scored (before the
    /// first estimate or before `score_from_us`).
    pub reference_unscored: u64,
    /// The protection levels at the scored reference samples, against the
    /// reference (`None` without a scored sample).
    pub integrity: Option<ReplayIntegrity>,
}

/// One update of a delay loop (one correlation window), in seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayWindow {
    /// Receive time of the fix that closed the window, s.
    pub t_s: f64,
    /// The fused estimate after the update, s.
    pub delay_s: f64,
    /// Its standard deviation, s.
    pub delay_std_s: f64,
    /// The loop's status after the update ([`crate::DelayStatus`], debug form).
    pub status: String,
    /// North, east, down.
    pub axes: [WindowAxis; 3],
}

/// One axis of a [`DelayWindow`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowAxis {
    /// The measurement was fused.
    pub valid: bool,
    /// The refined correlation peak as a delay, s.
    pub measured_delay_s: f64,
    /// The normalized correlation at the peak.
    pub peak: f64,
    /// Variance of the IMU acceleration over the window, (m/s^2)^2.
    pub accel_variance: f64,
    /// False when the peak sits on an edge of the shift window.
    pub interior: bool,
}

impl DelayWindow {
    fn of<T: Scalar>(u: &DelayUpdate<T>) -> Self {
        Self {
            t_s: u.t_us as f64 * 1e-6,
            delay_s: u.delay_s.as_f64(),
            delay_std_s: u.delay_std_s.as_f64(),
            status: format!("{:?}", u.status),
            axes: u.axes.map(|a| WindowAxis {
                valid: a.valid,
                measured_delay_s: a.measured_delay_s.as_f64(),
                peak: a.correlation.peak.as_f64(),
                accel_variance: a.correlation.accel_variance.as_f64(),
                interior: a.correlation.interior,
            }),
        }
    }
}

impl RunSummary {
    /// Whether the delay was estimated: `Some(true)` with a
    /// [`Self::final_delay_s`], `Some(false)` with a
    /// [`Self::delay_not_estimated`], `None` for an estimator without a delay.
    pub fn delay_estimated(&self) -> Option<bool> {
        match (self.final_delay_s, &self.delay_not_estimated) {
            (_, Some(_)) => Some(false),
            (Some(_), None) => Some(true),
            (None, None) => None,
        }
    }

    /// Samples refused, all kinds together.
    pub fn samples_refused(&self) -> u64 {
        self.refused.values().sum()
    }

    fn count_gps<T: Scalar>(&mut self, outcome: &GpsOutcome<T>) {
        self.gps_pushed += 1;
        if let GpsOutcome::Fused { position, velocity } = outcome {
            self.gps_position_fused += u64::from(position.fused);
            self.gps_velocity_fused += u64::from(velocity.fused);
            self.gps_gated += u64::from(!(position.fused && velocity.fused));
        }
    }

    fn count_mag<T: Scalar>(&mut self, outcome: &MagOutcome<T>) {
        self.mag_pushed += 1;
        if let MagOutcome::Fused(record) = outcome {
            self.mag_fused += u64::from(record.fused);
            self.mag_gated += u64::from(!record.fused);
        }
    }
}

/// The records an estimator keeps of its last GPS and magnetometer
/// fusions. [`replay`] counts fusions from them, so a sample the estimator
/// queues and fuses later (the delay-compensated navigator fuses the
/// magnetometer at its delayed horizon) is counted when it is really fused
/// or gated. An estimator without records (the defaults) is counted from
/// the outcomes its push calls return.
///
/// One new record per stream is seen per pushed sample: a sample fused in
/// the same call as another of its stream would be missed (not the case when
/// the magnetometer and GPS rates are below the IMU rate).
pub trait FusionRecords<T: Scalar> {
    /// The last GPS fusion: (position, velocity).
    fn last_gps_fusion(&self) -> Option<(FusionRecord<T, 3>, FusionRecord<T, 3>)> {
        None
    }
    /// The last magnetometer fusion.
    fn last_mag_fusion(&self) -> Option<FusionRecord<T, 3>> {
        None
    }
    /// The delay loop's last update.
    fn last_delay_update(&self) -> Option<DelayUpdate<T>> {
        None
    }
}

macro_rules! records_of_filter {
    ($($ty:ident),*) => {$(
        impl<T: Scalar> FusionRecords<T> for crate::$ty<T> {
            fn last_gps_fusion(&self) -> Option<(FusionRecord<T, 3>, FusionRecord<T, 3>)> {
                crate::$ty::last_gps_fusion(self)
            }
            fn last_mag_fusion(&self) -> Option<FusionRecord<T, 3>> {
                crate::$ty::last_mag_fusion(self)
            }
        }
    )*};
}
records_of_filter!(Ekf16, AugmentedEkf17);

impl<T: Scalar> FusionRecords<T> for crate::DelayCompensatedNav<T> {
    fn last_gps_fusion(&self) -> Option<(FusionRecord<T, 3>, FusionRecord<T, 3>)> {
        self.horizon_filter().last_gps_fusion()
    }
    fn last_mag_fusion(&self) -> Option<FusionRecord<T, 3>> {
        self.horizon_filter().last_mag_fusion()
    }
    fn last_delay_update(&self) -> Option<DelayUpdate<T>> {
        crate::DelayCompensatedNav::last_delay_update(self).copied()
    }
}

/// Fusions counted from an estimator's records, and the time of the last
/// record seen per stream.
#[derive(Default)]
struct RecordTally {
    seen: bool,
    gps_us: Option<u64>,
    mag_us: Option<u64>,
    counts: RunSummary,
}

impl RecordTally {
    fn observe<T: Scalar, N: FusionRecords<T>>(&mut self, nav: &N) {
        if let Some((position, velocity)) = nav.last_gps_fusion() {
            self.seen = true;
            if self.gps_us.replace(position.t_us) != Some(position.t_us) {
                let c = &mut self.counts;
                c.gps_position_fused += u64::from(position.fused);
                c.gps_velocity_fused += u64::from(velocity.fused);
                c.gps_gated += u64::from(!(position.fused && velocity.fused));
            }
        }
        if let Some(record) = nav.last_mag_fusion() {
            self.seen = true;
            if self.mag_us.replace(record.t_us) != Some(record.t_us) {
                self.counts.mag_fused += u64::from(record.fused);
                self.counts.mag_gated += u64::from(!record.fused);
            }
        }
    }
}

/// The name of an error's variant, for the refusal counts.
pub fn error_kind(e: &Error) -> String {
    let text = format!("{e:?}");
    text.split([' ', '{', '('])
        .next()
        .unwrap_or_default()
        .to_string()
}

/// Running sums of squared differences.
#[derive(Default)]
struct Squares {
    n: u64,
    roll: f64,
    pitch: f64,
    yaw: f64,
    velocity: f64,
    velocity_n: u64,
}

impl Squares {
    fn rms(&self) -> Option<ReferenceRms> {
        let mean = |s: f64, n: u64| (s / n as f64).sqrt();
        (self.n > 0).then(|| ReferenceRms {
            samples: self.n,
            roll_deg: mean(self.roll, self.n).to_degrees(),
            pitch_deg: mean(self.pitch, self.n).to_degrees(),
            yaw_deg: mean(self.yaw, self.n).to_degrees(),
            velocity_m_s: (self.velocity_n > 0).then(|| mean(self.velocity, self.velocity_n)),
        })
    }
}

/// An estimate narrowed to what the comparison needs, in `f64`.
#[derive(Clone, Copy)]
struct Snapshot {
    t_us: u64,
    attitude: UnitQuaternion<f64>,
    velocity: Vector3<f64>,
}

impl Snapshot {
    fn of<T: Scalar>(e: &Estimate<T>) -> Self {
        let q = e.attitude.quaternion();
        Self {
            t_us: e.t_us,
            attitude: UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                q.w.as_f64(),
                q.i.as_f64(),
                q.j.as_f64(),
                q.k.as_f64(),
            )),
            velocity: e.velocity_ned_m_s.map(Scalar::as_f64),
        }
    }

    /// The snapshot at `t_us` between `self` and `next`.
    fn interpolate(&self, next: &Snapshot, t_us: u64) -> Snapshot {
        let span = next.t_us.saturating_sub(self.t_us);
        let w = if span == 0 {
            1.0
        } else {
            (t_us - self.t_us) as f64 / span as f64
        };
        Snapshot {
            t_us,
            attitude: self
                .attitude
                .try_slerp(&next.attitude, w, 1e-9)
                .unwrap_or(next.attitude),
            velocity: self.velocity.lerp(&next.velocity, w),
        }
    }
}

fn is_finite<T: Scalar>(e: &Estimate<T>) -> bool {
    let q = e.attitude.quaternion();
    [q.w, q.i, q.j, q.k].iter().all(|v| v.is_finite())
        && e.position_ned_m.iter().all(|v| v.is_finite())
        && e.velocity_ned_m_s.iter().all(|v| v.is_finite())
        && e.delay_s.is_none_or(|d| d.is_finite())
}

/// Replays `events` through `nav`, scores it against `reference`, and
/// calls `on_estimate` with the estimate after every IMU sample.
pub fn replay<T, N, E, R, F>(
    nav: &mut N,
    events: E,
    reference: Option<R>,
    options: &RunOptions,
    mut on_estimate: F,
) -> RunSummary
where
    T: Scalar,
    N: Navigator<T> + FusionRecords<T>,
    E: IntoIterator<Item = SensorEvent<T>>,
    R: Iterator<Item = ReferenceSample>,
    F: FnMut(&Estimate<T>),
{
    replay_with(nav, events, reference, options, |e, _| on_estimate(e))
}

/// [`replay`], with the estimator beside each estimate: `on_estimate` may
/// read its health or its [`Navigator::integrity`] at that sample.
pub fn replay_with<T, N, E, R, F>(
    nav: &mut N,
    events: E,
    reference: Option<R>,
    options: &RunOptions,
    mut on_estimate: F,
) -> RunSummary
where
    T: Scalar,
    N: Navigator<T> + FusionRecords<T>,
    E: IntoIterator<Item = SensorEvent<T>>,
    R: Iterator<Item = ReferenceSample>,
    F: FnMut(&Estimate<T>, &N),
{
    let mut summary = RunSummary::default();
    let mut squares = Squares::default();
    let mut reference: Option<Peekable<R>> = reference.map(Iterator::peekable);
    let mut previous: Option<Snapshot> = None;
    let mut records = RecordTally::default();
    let mut levels = LevelTally::default();
    records.observe(nav);
    // Records already there before the window (none for a new estimator).
    records.counts = RunSummary::default();
    let mut next_track_us = 0;
    let mut step = options.delay_step.map(|step| StepWatch {
        step,
        before_s: None,
        final_s: None,
        within_since_us: None,
    });
    let start = options.start_us.unwrap_or(0);
    let end = options.end_us.unwrap_or(u64::MAX);
    let score_from = options.score_from_us.unwrap_or(start).max(start);

    for event in events.into_iter().skip_while(|e| e.time_us() < start) {
        if event.time_us() > end {
            break;
        }
        let outcome = match &event {
            SensorEvent::Imu(s) => nav.push_imu(s).map(|()| summary.imu_pushed += 1),
            SensorEvent::Gps(s) => nav.push_gps(s).map(|o| summary.count_gps(&o)),
            SensorEvent::Mag(s) => nav.push_mag(s).map(|o| summary.count_mag(&o)),
        };
        if let Err(e) = outcome {
            *summary.refused.entry(error_kind(&e)).or_default() += 1;
        }
        records.observe(nav);
        if let Some(u) = nav.last_delay_update()
            && summary.delay_windows.last().map(|w| w.t_s) != Some(u.t_us as f64 * 1e-6)
        {
            summary.delay_windows.push(DelayWindow::of(&u));
        }
        if !matches!(event, SensorEvent::Imu(_)) {
            continue;
        }
        let Some(estimate) = nav.estimate() else {
            continue;
        };
        if !is_finite(&estimate) {
            summary.non_finite_estimates += 1;
            continue;
        }
        on_estimate(&estimate, nav);
        summary.last_estimate_t_us = Some(estimate.t_us);
        if let Some(d) = estimate.delay_s {
            summary.final_delay_s = Some(d.as_f64());
            if let Some(watch) = step.as_mut() {
                watch.observe(estimate.t_us, d.as_f64());
            }
            if estimate.t_us >= next_track_us {
                summary
                    .delay_track
                    .push((estimate.t_us as f64 * 1e-6, d.as_f64()));
                next_track_us = estimate.t_us + options.delay_track_interval_us;
            }
        }
        let current = Snapshot::of(&estimate);
        if let Some(refs) = reference.as_mut() {
            while let Some(r) = refs.next_if(|r| r.t_us <= current.t_us) {
                match previous {
                    Some(p) if r.t_us >= p.t_us && r.t_us >= score_from && r.t_us >= start => {
                        let at = p.interpolate(&current, r.t_us);
                        let (aligned, velocity_error) = score(&mut squares, &at, &r, options);
                        levels.add(&nav.integrity(), &aligned, &r.attitude, velocity_error);
                    }
                    _ if r.t_us >= start => summary.reference_unscored += 1,
                    _ => {}
                }
            }
        }
        previous = Some(current);
    }
    summary.reference_rms = squares.rms();
    summary.integrity = levels.summary();
    // Estimators without a delay estimate report no step.
    summary.delay_step = step.filter(|w| w.final_s.is_some()).map(|w| w.summary());
    if records.seen {
        let c = records.counts;
        summary.gps_position_fused = c.gps_position_fused;
        summary.gps_velocity_fused = c.gps_velocity_fused;
        summary.gps_gated = c.gps_gated;
        summary.mag_fused = c.mag_fused;
        summary.mag_gated = c.mag_gated;
    }
    summary
}

/// Adds one sample's squared differences; the aligned estimate and the
/// velocity difference's norm (when the reference has velocity).
fn score(
    squares: &mut Squares,
    estimate: &Snapshot,
    reference: &ReferenceSample,
    options: &RunOptions,
) -> (UnitQuaternion<f64>, Option<f64>) {
    let aligned = options
        .alignment
        .align_estimate(&estimate.attitude, options.estimator_declination_rad);
    let e = euler_from_quaternion(aligned.quaternion());
    let r = euler_from_quaternion(reference.attitude.quaternion());
    squares.n += 1;
    squares.roll += wrap_pi(e.x - r.x).powi(2);
    squares.pitch += wrap_pi(e.y - r.y).powi(2);
    squares.yaw += wrap_pi(e.z - r.z).powi(2);
    let velocity_error = reference.velocity_ned_m_s.map(|v| {
        let e = (estimate.velocity - v).norm_squared();
        squares.velocity += e;
        squares.velocity_n += 1;
        e.sqrt()
    });
    (aligned, velocity_error)
}

/// The magnetic inclination (radians, positive when the field points below
/// the horizon) seen at the start of a log, while the vehicle stands still:
/// with `f̄` the mean specific force and `m̄` the mean magnetometer direction
/// over the first `window_us` after the first sample, down is `-f̄/|f̄|` in
/// the body frame and `I = asin(m̄/|m̄| · (-f̄/|f̄|))`.
///
/// `None` when the window holds no IMU or no magnetometer sample. Meaningful
/// only when the vehicle is at rest in that window (logs usually start on
/// the ground); the estimators only need it for their magnetic model.
pub fn inclination_at_rest<T: Scalar>(
    events: impl IntoIterator<Item = SensorEvent<T>>,
    window_us: u64,
) -> Option<f64> {
    let mut first_us = None;
    let (mut force, mut field) = (Vector3::<f64>::zeros(), Vector3::<f64>::zeros());
    let (mut n_imu, mut n_mag) = (0u32, 0u32);
    for event in events {
        let start = *first_us.get_or_insert(event.time_us());
        if event.time_us() > start + window_us {
            break;
        }
        match event {
            SensorEvent::Imu(s) => {
                force += s.accel_m_s2.map(Scalar::as_f64);
                n_imu += 1;
            }
            SensorEvent::Mag(s) => {
                field += s.field_body.map(Scalar::as_f64).normalize();
                n_mag += 1;
            }
            SensorEvent::Gps(_) => {}
        }
    }
    if n_imu == 0 || n_mag == 0 || force.norm() == 0.0 || field.norm() == 0.0 {
        return None;
    }
    let down = -force.normalize();
    Some(field.normalize().dot(&down).clamp(-1.0, 1.0).asin())
}

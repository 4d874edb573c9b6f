//! Faults as data: what goes wrong with the sensor streams, applied to a
//! simulated run, and the fault suite that judges a navigator by it.
//!
//! A [`Fault`] describes one departure from a clean run. A
//! [`FaultySimulation`] is a [`Simulation`] with a list of faults: an
//! iterator of the same [`SimEvent`]s, with fixes dropped, moved or given
//! bad accuracies, IMU samples dropped, decimated or mis-stamped, the
//! magnetic field rotated, the clock moved back, or the start cut. The truth
//! carried by the IMU events stays the truth at the instant the sensors saw
//! (its `t_us` is never shifted), so a navigator is always scored against
//! what really happened.
//!
//! Times of faults are seconds of true time from the start of the run (the
//! simulator's clock before any clock fault).
//!
//! # The suite
//! [`fault_suite`] lists the thirteen rows of issue 10 and the three of
//! issue 25 (no magnetometer, an in-flight start): a scenario
//! ([`FaultCase`]: simulated run, faults, the navigator's duty when told the
//! clock went back), the quantity measured ([`Metric`]), its limit, and the
//! run it is compared with ([`Reference`]). [`run_trace`] feeds a run to any
//! [`Navigator`] and records, per IMU sample, the rotation-vector tilt and
//! heading errors ([`tilt_heading_error_rad`])
//! and the horizontal position; [`evaluate`] turns a trace (and the
//! reference's) into a [`FaultResult`]. [`suite::faults`](super::suite::faults) runs it
//! (`reproduce --faults`); `docs/faults.md` has the table.

use super::trajectory::{PathTerm, Scenario, TrajectoryConfig};
use super::{SimConfig, SimEvent, Simulation, VibrationHarmonic, tilt_heading_error_rad};
use crate::error::Error;
use crate::estimate::Navigator;
use crate::sensors::GpsPosition;
use nalgebra::{Rotation3, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

/// The bad accuracies a [`Fault::GpsBadAccuracy`] cycles through: NaN,
/// infinite, zero, negative, and an absurd 1e12 m (or m/s).
pub const BAD_ACCURACIES: [f64; 5] = [f64::NAN, f64::INFINITY, 0.0, -1.0, 1e12];

/// One fault applied to a simulated run's sensor streams.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// No GPS fix received in `[from_s, to_s)`.
    GpsOutage {
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
    },
    /// The first fix received at or after `at_s` is `offset_m` (NED) off.
    GpsJump {
        /// Time, s.
        at_s: f64,
        /// Position offset, NED, m.
        offset_m: [f64; 3],
    },
    /// Every fix from `from_s` on is `offset_m` (NED) off; velocities stay good.
    GpsPositionStep {
        /// Start, s.
        from_s: f64,
        /// Position offset, NED, m.
        offset_m: [f64; 3],
    },
    /// Every fix from `from_s` on is moved by an offset growing linearly from
    /// zero to `offset_m` (NED) over `duration_s`, then staying there; velocities
    /// stay good (a slow drift, multipath).
    GpsPositionDrift {
        /// Start, s.
        from_s: f64,
        /// Time to reach the full offset, s.
        duration_s: f64,
        /// Final position offset, NED, m.
        offset_m: [f64; 3],
    },
    /// The first fix of the run is `offset_m` (NED) off.
    GpsFirstFixGlitch {
        /// Position offset, NED, m.
        offset_m: [f64; 3],
    },
    /// A random `fraction` of the fixes report all three accuracies
    /// (horizontal, vertical, speed) as the next of [`BAD_ACCURACIES`].
    GpsBadAccuracy {
        /// Share of the fixes affected, in `[0, 1]`.
        fraction: f64,
        /// Seed of the choice.
        seed: u64,
    },
    /// From `at_s` on the IMU runs at `rate_hz` (the simulated stream is
    /// decimated: only samples whose time is a multiple of the new period
    /// are kept, so the new period must be a multiple of the simulated one).
    ImuRateChange {
        /// Time, s.
        at_s: f64,
        /// New rate, Hz.
        rate_hz: f64,
    },
    /// A random `fraction` of the IMU samples are lost.
    ImuDropouts {
        /// Share of the samples dropped, in `[0, 1)`.
        fraction: f64,
        /// Seed of the choice.
        seed: u64,
    },
    /// No IMU sample in `[from_s, to_s)` (GPS and magnetometer go on).
    ImuGap {
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
    },
    /// The IMU samples at jittered instants, each period up to `+-fraction`
    /// of the nominal one ([`Simulation::with_imu_period_jitter`]).
    ImuPeriodJitter {
        /// Peak deviation of one period, fraction of the nominal period, `[0, 1)`.
        fraction: f64,
    },
    /// The first IMU sample at or after `at_s` is stamped `ahead_s` in the
    /// future (its values are right).
    ImuFutureSample {
        /// Time, s.
        at_s: f64,
        /// How far ahead its stamp is, s.
        ahead_s: f64,
    },
    /// The shared clock (IMU, GPS and magnetometer are stamped on the IMU's
    /// clock) jumps back by `back_s` at `at_s`: every later event is stamped
    /// `back_s` earlier.
    ClockBack {
        /// Time, s.
        at_s: f64,
        /// Jump, s.
        back_s: f64,
    },
    /// The measured magnetic field is rotated by `angle_rad` about the
    /// vertical (NED down) in `[from_s, to_s)`: a local disturbance that
    /// keeps the field's norm and inclination.
    MagRotation {
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
        /// Rotation about down, rad.
        angle_rad: f64,
    },
    /// The magnetometer's field multiplied by `factor` in `[from_s, to_s)`: a
    /// local disturbance along the field (a steel structure passed, a current
    /// near the sensor) that keeps its direction and changes its norm.
    MagScale {
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
        /// Factor on the field.
        factor: f64,
    },
    /// No magnetometer sample until `after_s` after the first fix received.
    MagLate {
        /// Wait after the first fix, s.
        after_s: f64,
    },
    /// The navigator is switched on at `t_s`: every event before is dropped
    /// (an in-flight start when the vehicle is moving then).
    StartAt {
        /// Time, s.
        t_s: f64,
    },
}

fn us(t_s: f64) -> u64 {
    (t_s.max(0.0) * 1e6).round() as u64
}

/// A uniform number in `[0, 1)` from `(seed, n)` (splitmix64): the
/// stateless random source of the jittered IMU instants.
pub(crate) fn unit_hash(seed: u64, n: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(n)
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// A simulated run with faults: an iterator of [`SimEvent`]s (see the module docs).
#[derive(Debug)]
pub struct FaultySimulation {
    sim: Simulation,
    faults: Vec<Fault>,
    rng: ChaCha8Rng,
    bad_accuracy_index: usize,
    first_fix_us: Option<u64>,
    jumped: bool,
    stamped_ahead: bool,
}

impl FaultySimulation {
    /// The run of `config` with `faults` applied (in list order, per event).
    pub fn new(config: SimConfig, faults: &[Fault]) -> Result<Self, Error> {
        let mut sim = Simulation::new(config)?;
        let mut seed = 0;
        for fault in faults {
            let bad = |reason| {
                Err(Error::InvalidConfig {
                    field: "fault".into(),
                    value: None,
                    bound: crate::error::Bound::Rule(reason),
                })
            };
            match *fault {
                Fault::ImuPeriodJitter { fraction } => {
                    sim = sim.with_imu_period_jitter(fraction)?;
                }
                Fault::GpsBadAccuracy { fraction, seed: s }
                | Fault::ImuDropouts { fraction, seed: s } => {
                    if !(0.0..=1.0).contains(&fraction) {
                        return bad("a fraction must be in [0, 1]");
                    }
                    seed = s;
                }
                Fault::MagScale { factor, .. } if !(factor.is_finite() && factor > 0.0) => {
                    return bad("a field factor must be finite and positive");
                }
                Fault::ImuRateChange { rate_hz, .. } => {
                    let old = 1e6 / sim.config().sensors.imu_rate_hz;
                    let new = 1e6 / rate_hz;
                    if !(rate_hz > 0.0 && new >= old && (new / old).fract() == 0.0) {
                        return bad("the new IMU period must be a multiple of the simulated one");
                    }
                }
                _ => {}
            }
        }
        Ok(Self {
            sim,
            faults: faults.to_vec(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            bad_accuracy_index: 0,
            first_fix_us: None,
            jumped: false,
            stamped_ahead: false,
        })
    }

    /// The underlying clean run.
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    fn offset(&self, position: GpsPosition<f64>, offset: [f64; 3]) -> GpsPosition<f64> {
        let d = Vector3::from(offset);
        match position {
            GpsPosition::Ned(p) => GpsPosition::Ned(p + d),
            GpsPosition::Geodetic(g) => {
                let frame = self.sim.frame();
                GpsPosition::Geodetic(frame.to_geodetic(&(frame.to_ned(&g) + d)))
            }
        }
    }

    /// Applies every fault to one event; `None` drops it.
    fn apply(&mut self, mut event: SimEvent) -> Option<SimEvent> {
        let t = event.t_us();
        for k in 0..self.faults.len() {
            let fault = self.faults[k];
            match (fault, &mut event) {
                (Fault::StartAt { t_s }, _) if t < us(t_s) => return None,
                (Fault::GpsOutage { from_s, to_s }, SimEvent::Gps { .. })
                    if t >= us(from_s) && t < us(to_s) =>
                {
                    return None;
                }
                (Fault::GpsJump { at_s, offset_m }, SimEvent::Gps { fix, .. })
                    if !self.jumped && t >= us(at_s) =>
                {
                    self.jumped = true;
                    fix.position = self.offset(fix.position, offset_m);
                }
                (Fault::GpsPositionStep { from_s, offset_m }, SimEvent::Gps { fix, .. })
                    if t >= us(from_s) =>
                {
                    fix.position = self.offset(fix.position, offset_m);
                }
                (
                    Fault::GpsPositionDrift {
                        from_s,
                        duration_s,
                        offset_m,
                    },
                    SimEvent::Gps { fix, .. },
                ) if t >= us(from_s) => {
                    let share = if duration_s > 0.0 {
                        ((t as f64 * 1e-6 - from_s) / duration_s).min(1.0)
                    } else {
                        1.0
                    };
                    fix.position = self.offset(fix.position, offset_m.map(|x| x * share));
                }
                (Fault::ImuGap { from_s, to_s }, SimEvent::Imu { .. })
                    if t >= us(from_s) && t < us(to_s) =>
                {
                    return None;
                }
                (Fault::GpsFirstFixGlitch { offset_m }, SimEvent::Gps { fix, .. })
                    if self.first_fix_us.is_none() =>
                {
                    fix.position = self.offset(fix.position, offset_m);
                }
                (Fault::GpsBadAccuracy { fraction, .. }, SimEvent::Gps { fix, .. })
                    if self.rng.random::<f64>() < fraction =>
                {
                    let bad = BAD_ACCURACIES[self.bad_accuracy_index % BAD_ACCURACIES.len()];
                    self.bad_accuracy_index += 1;
                    fix.horizontal_accuracy_m = Some(bad);
                    fix.vertical_accuracy_m = Some(bad);
                    fix.speed_accuracy_m_s = Some(bad);
                }
                (Fault::ImuRateChange { at_s, rate_hz }, SimEvent::Imu { .. }) => {
                    let period_us = (1e6 / rate_hz).round() as u64;
                    if t >= us(at_s) && !t.is_multiple_of(period_us) {
                        return None;
                    }
                }
                (Fault::ImuDropouts { fraction, .. }, SimEvent::Imu { .. })
                    if self.rng.random::<f64>() < fraction =>
                {
                    return None;
                }
                (Fault::ImuFutureSample { at_s, ahead_s }, SimEvent::Imu { sample, .. })
                    if !self.stamped_ahead && t >= us(at_s) =>
                {
                    self.stamped_ahead = true;
                    sample.t_us = sample.t_us.saturating_add(us(ahead_s));
                }
                (
                    Fault::MagRotation {
                        from_s,
                        to_s,
                        angle_rad,
                    },
                    SimEvent::Mag(m),
                ) if t >= us(from_s) && t < us(to_s) => {
                    // b' = R^T Rz(a) R b: the NED field turned about down.
                    let r = self.sim.trajectory().rotation(t as f64 * 1e-6);
                    let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), angle_rad);
                    m.field_body = r.transpose() * (rz * (r * m.field_body));
                }
                (
                    Fault::MagScale {
                        from_s,
                        to_s,
                        factor,
                    },
                    SimEvent::Mag(m),
                ) if t >= us(from_s) && t < us(to_s) => {
                    m.field_body *= factor;
                }
                (Fault::MagLate { after_s }, SimEvent::Mag(_))
                    if self
                        .first_fix_us
                        .is_none_or(|f| t < f.saturating_add(us(after_s))) =>
                {
                    return None;
                }
                _ => {}
            }
        }
        if let SimEvent::Gps { .. } = event {
            self.first_fix_us.get_or_insert(t);
        }
        for fault in &self.faults {
            if let Fault::ClockBack { at_s, back_s } = *fault
                && t >= us(at_s)
            {
                let shift = |x: &mut u64| *x = x.saturating_sub(us(back_s));
                match &mut event {
                    SimEvent::Imu { sample, .. } => shift(&mut sample.t_us),
                    SimEvent::Mag(m) => shift(&mut m.t_us),
                    SimEvent::Gps { fix, .. } => shift(&mut fix.t_us),
                }
            }
        }
        Some(event)
    }
}

impl Iterator for FaultySimulation {
    type Item = SimEvent;

    fn next(&mut self) -> Option<SimEvent> {
        loop {
            let event = self.sim.next()?;
            if let Some(e) = self.apply(event) {
                return Some(e);
            }
        }
    }
}

/// The errors of a navigator at one IMU sample (NaN without an estimate).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracePoint {
    /// True time of the sample, s.
    pub t_s: f64,
    /// Rotation-vector tilt error, degrees.
    pub tilt_deg: f64,
    /// Rotation-vector heading error, degrees.
    pub heading_deg: f64,
    /// Estimated north, east position, m.
    pub estimate_ne_m: [f64; 2],
    /// True north, east position, m.
    pub truth_ne_m: [f64; 2],
}

impl TracePoint {
    /// Horizontal distance of the estimate from the truth moved by `offset_ne_m`, m.
    pub fn horizontal_error_m(&self, offset_ne_m: [f64; 2]) -> f64 {
        (self.estimate_ne_m[0] - self.truth_ne_m[0] - offset_ne_m[0])
            .hypot(self.estimate_ne_m[1] - self.truth_ne_m[1] - offset_ne_m[1])
    }
}

/// What a navigator does when the clock goes back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnTimeBackwards {
    /// Nothing: the error is ignored, as every other refusal.
    Ignore,
    /// The caller resets the navigator when `push_imu` returns
    /// [`Error::TimeWentBackwards`], then pushes the sample again.
    Reset,
}

/// Pushes one event to `nav`, its refusals ignored (the navigator counts them); with
/// [`OnTimeBackwards::Reset`] a backwards IMU sample calls `reset` and is pushed again.
pub(crate) fn feed<N: Navigator<f64>>(
    nav: &mut N,
    event: &SimEvent,
    on_backwards: OnTimeBackwards,
    reset: &mut impl FnMut(&mut N),
) {
    match event {
        SimEvent::Imu { sample, .. } => {
            let result = nav.push_imu(sample);
            if on_backwards == OnTimeBackwards::Reset
                && matches!(result, Err(Error::TimeWentBackwards { .. }))
            {
                reset(nav);
                let _ = nav.push_imu(sample);
            }
        }
        SimEvent::Mag(m) => {
            let _ = nav.push_mag(m);
        }
        SimEvent::Gps { fix, .. } => {
            let _ = nav.push_gps(fix);
        }
    }
}

/// Feeds `events` to `nav` and records its errors at every IMU sample.
/// Refusals are the navigator's business (it counts them); with
/// [`OnTimeBackwards::Reset`] a backwards IMU sample calls `reset`.
pub fn run_trace<N: Navigator<f64>>(
    events: impl Iterator<Item = SimEvent>,
    mut nav: N,
    on_backwards: OnTimeBackwards,
    mut reset: impl FnMut(&mut N),
) -> Vec<TracePoint> {
    let mut trace = Vec::new();
    for event in events {
        feed(&mut nav, &event, on_backwards, &mut reset);
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        let mut point = TracePoint {
            t_s: truth.t_us as f64 * 1e-6,
            tilt_deg: f64::NAN,
            heading_deg: f64::NAN,
            estimate_ne_m: [f64::NAN; 2],
            truth_ne_m: [truth.position_m.x, truth.position_m.y],
        };
        if let Some(est) = nav.estimate() {
            let (tilt, heading) = tilt_heading_error_rad(&est.attitude, &truth.attitude);
            point.tilt_deg = tilt.to_degrees();
            point.heading_deg = heading.to_degrees();
            point.estimate_ne_m = [est.position_ned_m.x, est.position_ned_m.y];
        }
        trace.push(point);
    }
    trace
}

/// The run a ratio is taken against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reference {
    /// None: the measured figure stands alone.
    None,
    /// The same run without the fault.
    Clean,
    /// The same run with the IMU at a steady `rate_hz` from the start.
    SteadyImuRate {
        /// Rate, Hz.
        rate_hz: f64,
    },
}

impl Reference {
    /// The simulated run of the reference, from the faulty case's.
    pub fn config(&self, case: &SimConfig) -> SimConfig {
        let mut c = case.clone();
        if let Reference::SteadyImuRate { rate_hz } = *self {
            c.sensors.imu_rate_hz = rate_hz;
        }
        c
    }
}

/// What a row measures, from the trace (times in s of true time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Metric {
    /// Seconds from `from_s` to the last sample whose horizontal error
    /// (against the truth moved by `offset_ne_m`) exceeds `threshold_m` (a
    /// sample without an estimate counts as exceeding it); 0 when none does,
    /// infinite when the last sample of the run does (it never settled),
    /// NaN when no sample lies at or after `from_s`.
    SettleHorizontal {
        /// Start, s.
        from_s: f64,
        /// Error bound, m.
        threshold_m: f64,
        /// The truth the estimate should follow, moved by this, m.
        offset_ne_m: [f64; 2],
    },
    /// Largest horizontal error at or after `from_s`, m.
    MaxHorizontal {
        /// Start, s.
        from_s: f64,
    },
    /// Horizontal error at the first sample at or after `t_s`, m.
    HorizontalAt {
        /// Time, s.
        t_s: f64,
    },
    /// Tilt RMSE at or after `from_s` over the reference's, same window.
    TiltRmseRatio {
        /// Start, s.
        from_s: f64,
    },
    /// Heading RMSE at or after `from_s` over the reference's.
    HeadingRmseRatio {
        /// Start, s.
        from_s: f64,
    },
    /// Largest heading error at or after `from_s`, degrees; the row also
    /// needs the largest tilt error there at most `max_tilt_deg`.
    MaxHeading {
        /// Start, s.
        from_s: f64,
        /// Bound on the tilt error in the same window, degrees.
        max_tilt_deg: f64,
    },
    /// Tilt error at the first sample at or after `t_s`, degrees.
    TiltAt {
        /// Time, s.
        t_s: f64,
    },
    /// Heading error at the first sample at or after `t_s`, degrees.
    HeadingAt {
        /// Time, s.
        t_s: f64,
    },
}

/// One row of the suite.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultCase {
    /// The row's name (issue 10's table).
    pub name: &'static str,
    /// What is measured, in words.
    pub criterion: &'static str,
    /// The limit the measured figure must not exceed.
    pub limit: f64,
    /// The simulated run.
    pub sim: SimConfig,
    /// The faults applied to it.
    pub faults: Vec<Fault>,
    /// What the caller does when told the clock went back.
    pub on_backwards: OnTimeBackwards,
    /// The figure.
    pub metric: Metric,
    /// The run a ratio is taken against.
    pub reference: Reference,
}

/// The outcome of one row (the `"faults"` entries of the suite's JSON).
#[derive(Debug, Clone, PartialEq)]
pub struct FaultResult {
    /// The row's name.
    pub name: &'static str,
    /// Measured figure within the limit (NaN fails).
    pub passed: bool,
    /// What is measured.
    pub criterion: &'static str,
    /// The figure (NaN when the navigator had no estimate where it counts or
    /// the window holds no sample; infinite when a settle row never settles).
    pub measured: f64,
    /// The limit.
    pub limit: f64,
    /// A second figure the row reports (the tilt bound of the magnetic row).
    pub note: Option<(&'static str, f64)>,
}

/// The high scenario, `60 scale` s long, true delay 0.2 s (constant).
pub fn base_config(seed: u64, scale: f64) -> SimConfig {
    base_config_in(Scenario::High, seed, scale)
}

/// Speed of the in-flight start, m/s.
pub const INFLIGHT_SPEED_M_S: f64 = 15.0;
/// Bank (tilt) of the in-flight start's steady turn, degrees.
pub const INFLIGHT_BANK_DEG: f64 = 20.0;
/// RMS of the in-flight start's accelerometer vibration, per axis, m/s^2.
pub const INFLIGHT_VIBRATION_RMS_M_S2: f64 = 2.0;
/// When the navigator is switched on in the in-flight row, s (the turn is
/// steady from the 8 s start ramp on).
pub const INFLIGHT_START_S: f64 = 12.0;

/// A steady level turn at [`INFLIGHT_SPEED_M_S`] with a tilt of
/// [`INFLIGHT_BANK_DEG`] (centripetal `a = g tan(bank)`, radius `v^2 / a`),
/// reached through the usual start ramp, with an accelerometer vibration of
/// [`INFLIGHT_VIBRATION_RMS_M_S2`] RMS per axis (a 120 Hz and a 47 Hz line)
/// and the scenario's sensors otherwise. The chirp manoeuvre is pushed out
/// to a 600 s period, its limit the lowest (in 0.5 m/s^2 steps) above the
/// circle's own peak, so that it stays negligible during the run.
pub fn inflight_config(seed: u64, duration_s: f64) -> SimConfig {
    let g = super::STANDARD_GRAVITY;
    let a = g * INFLIGHT_BANK_DEG.to_radians().tan();
    let radius = INFLIGHT_SPEED_M_S * INFLIGHT_SPEED_M_S / a;
    let period_s = core::f64::consts::TAU * radius / INFLIGHT_SPEED_M_S;
    let mut trajectory = TrajectoryConfig {
        accel_limit_m_s2: a + 0.5,
        path: vec![
            PathTerm {
                amplitude_m: Vector3::new(radius, 0.0, 0.0),
                period_s,
                phase_rad: 0.0,
            },
            PathTerm {
                amplitude_m: Vector3::new(0.0, radius, 0.0),
                period_s,
                phase_rad: core::f64::consts::FRAC_PI_2,
            },
        ],
        manoeuvre_period_s: 600.0,
        yaw_amplitude_rad: 0.0,
        ..TrajectoryConfig::for_scenario(Scenario::High)
    };
    // The lowest limit (0.5 m/s^2 steps) above the ramped circle's own peak.
    while super::Trajectory::new(trajectory.clone(), duration_s).is_err()
        && trajectory.accel_limit_m_s2 < 100.0
    {
        trajectory.accel_limit_m_s2 += 0.5;
    }
    let mut config = SimConfig {
        trajectory,
        duration_s,
        delay: super::DelayProfile::constant(0.2),
        ..SimConfig::for_scenario(Scenario::High, seed)
    };
    // Two lines of equal amplitude A per axis: RMS = A (per axis).
    let amplitude = INFLIGHT_VIBRATION_RMS_M_S2;
    config.sensors.vibration = vec![
        VibrationHarmonic {
            frequency_hz: 120.0,
            gyro_amplitude_rad_s: 0.0,
            accel_amplitude_m_s2: amplitude,
        },
        VibrationHarmonic {
            frequency_hz: 47.0,
            gyro_amplitude_rad_s: 0.0,
            accel_amplitude_m_s2: amplitude,
        },
    ];
    config
}

/// Hard-iron offset of the `hard_iron` row, as a fraction of the field norm.
pub const HARD_IRON_FRACTION: f64 = 0.3;

/// The `hard_iron` row's offset: [`HARD_IRON_FRACTION`] of the (unit) field,
/// body FRD, horizontal at level, 45 deg between forward and right.
pub fn hard_iron_offset() -> Vector3<f64> {
    Vector3::new(1.0, 1.0, 0.0).normalize() * HARD_IRON_FRACTION
}

/// Issue 10's thirteen rows and issue 25's four, with times scaled by `scale` (1: the 60 s runs
/// of the issue; tests run shorter). See `docs/faults.md`.
pub fn fault_suite(seed: u64, scale: f64) -> Vec<FaultCase> {
    fault_suite_in(Scenario::High, seed, scale)
}

/// [`base_config`] in `scenario`.
pub fn base_config_in(scenario: Scenario, seed: u64, scale: f64) -> SimConfig {
    SimConfig {
        duration_s: 60.0 * scale,
        delay: super::DelayProfile::constant(0.2),
        ..SimConfig::for_scenario(scenario, seed)
    }
}

/// [`fault_suite`] on `scenario` instead of the high one (the in-flight start
/// keeps its own turn).
pub fn fault_suite_in(scenario: Scenario, seed: u64, scale: f64) -> Vec<FaultCase> {
    let base = base_config_in(scenario, seed, scale);
    let s = |t: f64| t * scale;
    let skip = s(10.0);
    let case = |name, criterion, limit, faults: Vec<Fault>, metric, reference| FaultCase {
        name,
        criterion,
        limit,
        sim: base.clone(),
        faults,
        on_backwards: OnTimeBackwards::Ignore,
        metric,
        reference,
    };
    let mut rows = vec![
        case(
            "gps_outage_30s",
            "s after GPS returns until horizontal error <= 5 m",
            5.0,
            vec![Fault::GpsOutage {
                from_s: s(20.0),
                to_s: s(50.0),
            }],
            Metric::SettleHorizontal {
                from_s: s(50.0),
                threshold_m: 5.0,
                offset_ne_m: [0.0; 2],
            },
            Reference::None,
        ),
        case(
            "gps_jump_100m",
            "max horizontal error after it, m",
            3.0,
            vec![Fault::GpsJump {
                at_s: s(30.0),
                offset_m: [100.0, 0.0, 0.0],
            }],
            Metric::MaxHorizontal { from_s: s(30.0) },
            Reference::None,
        ),
        case(
            "gps_position_step_50m",
            "s until the estimate follows within 5 m",
            10.0,
            vec![Fault::GpsPositionStep {
                from_s: s(30.0),
                offset_m: [50.0, 0.0, 0.0],
            }],
            Metric::SettleHorizontal {
                from_s: s(30.0),
                threshold_m: 5.0,
                offset_ne_m: [50.0, 0.0],
            },
            Reference::None,
        ),
        case(
            "gps_first_fix_glitch",
            "horizontal error at 20 s, m",
            5.0,
            vec![Fault::GpsFirstFixGlitch {
                offset_m: [1.0e6, 0.0, 0.0],
            }],
            Metric::HorizontalAt { t_s: s(20.0) },
            Reference::None,
        ),
        case(
            "gps_bad_accuracy",
            "tilt RMSE / clean",
            1.1,
            vec![Fault::GpsBadAccuracy {
                fraction: 0.1,
                seed: seed ^ 0xACC,
            }],
            Metric::TiltRmseRatio { from_s: skip },
            Reference::Clean,
        ),
        case(
            "imu_rate_change",
            "tilt RMSE after 35 s / a steady 200 Hz run",
            1.2,
            vec![Fault::ImuRateChange {
                at_s: s(30.0),
                rate_hz: 200.0,
            }],
            Metric::TiltRmseRatio { from_s: s(35.0) },
            Reference::SteadyImuRate { rate_hz: 200.0 },
        ),
        case(
            "imu_dropouts",
            "tilt RMSE / clean",
            1.2,
            vec![Fault::ImuDropouts {
                fraction: 0.1,
                seed: seed ^ 0xD80,
            }],
            Metric::TiltRmseRatio { from_s: skip },
            Reference::Clean,
        ),
        case(
            "imu_jitter",
            "tilt RMSE / clean",
            1.2,
            vec![Fault::ImuPeriodJitter { fraction: 0.3 }],
            Metric::TiltRmseRatio { from_s: skip },
            Reference::Clean,
        ),
        case(
            "future_timestamp",
            "tilt RMSE / clean",
            1.1,
            vec![Fault::ImuFutureSample {
                at_s: s(30.0),
                ahead_s: 3600.0,
            }],
            Metric::TiltRmseRatio { from_s: skip },
            Reference::Clean,
        ),
        FaultCase {
            on_backwards: OnTimeBackwards::Reset,
            ..case(
                "time_backwards",
                "tilt RMSE over the last 20 s / clean",
                1.5,
                vec![Fault::ClockBack {
                    at_s: s(30.0),
                    back_s: 1.0,
                }],
                Metric::TiltRmseRatio { from_s: s(40.0) },
                Reference::Clean,
            )
        },
        case(
            "mag_disturbance_60deg",
            "max yaw error, deg (and max tilt error <= 2 deg)",
            5.0,
            vec![Fault::MagRotation {
                from_s: s(30.0),
                to_s: s(40.0),
                angle_rad: 60f64.to_radians(),
            }],
            Metric::MaxHeading {
                from_s: s(30.0),
                max_tilt_deg: 2.0,
            },
            Reference::None,
        ),
        case(
            "mag_late",
            "yaw RMSE / clean",
            1.2,
            vec![Fault::MagLate { after_s: 5.0 }],
            Metric::HeadingRmseRatio { from_s: skip },
            Reference::Clean,
        ),
    ];
    let mut hard_iron = base.clone();
    hard_iron.sensors.mag_hard_iron = hard_iron_offset();
    rows.push(FaultCase {
        sim: hard_iron,
        ..case(
            "hard_iron",
            "yaw RMSE / clean (hard-iron offset not in the config)",
            1.5,
            vec![],
            Metric::HeadingRmseRatio { from_s: skip },
            Reference::Clean,
        )
    });
    let inflight_end = (60.0 * scale).max(INFLIGHT_START_S + 10.0);
    rows.push(FaultCase {
        sim: inflight_config(seed, inflight_end),
        ..case(
            "inflight_start",
            "tilt error 5 s after start, deg",
            2.0,
            vec![Fault::StartAt {
                t_s: INFLIGHT_START_S,
            }],
            Metric::TiltAt {
                t_s: INFLIGHT_START_S + 5.0,
            },
            Reference::None,
        )
    });
    // Without a magnetometer the heading comes from the GPS velocity and the
    // IMU alone (the yaw estimator of `src/nav/yaw_gsf.rs`).
    let mut no_mag = base.clone();
    no_mag.sensors.mag_rate_hz = 0.0;
    let no_mag_end = (60.0 * scale).max(INFLIGHT_NO_MAG_START_S + 20.0);
    rows.push(FaultCase {
        sim: no_mag.clone(),
        ..case(
            "no_magnetometer",
            "yaw error at 30 s, deg",
            5.0,
            Vec::new(),
            Metric::HeadingAt { t_s: s(30.0) },
            Reference::None,
        )
    });
    rows.push(FaultCase {
        sim: SimConfig {
            duration_s: no_mag_end,
            ..no_mag
        },
        ..case(
            "no_magnetometer_inflight",
            "yaw error at 35 s (in-flight start at 20 s), deg",
            5.0,
            vec![Fault::StartAt {
                t_s: INFLIGHT_NO_MAG_START_S,
            }],
            Metric::HeadingAt {
                t_s: INFLIGHT_NO_MAG_START_S + 15.0,
            },
            Reference::None,
        )
    });
    rows.push(FaultCase {
        sim: SimConfig {
            duration_s: no_mag_end,
            ..base.clone()
        },
        ..case(
            "inflight_tilt_5s",
            "tilt error at 25 s (in-flight start at 20 s), deg",
            2.5,
            vec![Fault::StartAt {
                t_s: INFLIGHT_NO_MAG_START_S,
            }],
            Metric::TiltAt {
                t_s: INFLIGHT_NO_MAG_START_S + 5.0,
            },
            Reference::None,
        )
    });
    rows.push(case(
        "mag_norm_disturbance",
        "tilt RMSE after 35 s / clean",
        1.2,
        vec![Fault::MagScale {
            from_s: s(30.0),
            to_s: s(32.0),
            factor: 1.3,
        }],
        Metric::TiltRmseRatio { from_s: s(35.0) },
        Reference::Clean,
    ));
    rows
}

/// When the navigator is switched on in the in-flight rows of the `high`
/// scenario (`no_magnetometer_inflight`, `inflight_tilt_5s`), s: the
/// vehicle is manoeuvring then. Not scaled: the rows' runs last at least
/// 20 s past it.
pub const INFLIGHT_NO_MAG_START_S: f64 = 20.0;

fn rms(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for x in xs {
        sum += x * x;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Largest value; NaN when any is NaN or there is none.
fn max_of(xs: impl Iterator<Item = f64>) -> f64 {
    let mut m = f64::NAN;
    for (k, x) in xs.enumerate() {
        if x.is_nan() {
            return f64::NAN;
        }
        m = if k == 0 { x } else { m.max(x) };
    }
    m
}

/// Scores a case's trace; `reference` is the trace of its [`Reference`]
/// run (needed by the ratio metrics, NaN without it).
pub fn evaluate(
    case: &FaultCase,
    trace: &[TracePoint],
    reference: Option<&[TracePoint]>,
) -> FaultResult {
    let from = |t: f64| trace.iter().filter(move |p| p.t_s >= t);
    let at = |t: f64| trace.iter().find(|p| p.t_s >= t);
    let ratio = |t: f64, f: fn(&TracePoint) -> f64| {
        let ours = rms(from(t).map(f));
        let theirs = reference.map_or(f64::NAN, |r| rms(r.iter().filter(|p| p.t_s >= t).map(f)));
        ours / theirs
    };
    let mut note = None;
    let measured = match case.metric {
        Metric::SettleHorizontal {
            from_s,
            threshold_m,
            offset_ne_m,
        } => {
            // NaN (no estimate) counts as outside the bound.
            let outside = |p: &TracePoint| {
                let e = p.horizontal_error_m(offset_ne_m);
                e.is_nan() || e > threshold_m
            };
            match trace.last() {
                // No sample in the window: nothing measured.
                None => f64::NAN,
                Some(last) if last.t_s < from_s => f64::NAN,
                // Outside at the end of the run: it never settled, however
                // little of the run was left.
                Some(last) if outside(last) => f64::INFINITY,
                Some(_) => trace
                    .iter()
                    .rev()
                    .take_while(|p| p.t_s >= from_s)
                    .find(|p| outside(p))
                    .map_or(0.0, |p| p.t_s - from_s),
            }
        }
        Metric::MaxHorizontal { from_s } => {
            max_of(from(from_s).map(|p| p.horizontal_error_m([0.0; 2])))
        }
        Metric::HorizontalAt { t_s } => {
            at(t_s).map_or(f64::NAN, |p| p.horizontal_error_m([0.0; 2]))
        }
        Metric::TiltRmseRatio { from_s } => ratio(from_s, |p| p.tilt_deg),
        Metric::HeadingRmseRatio { from_s } => ratio(from_s, |p| p.heading_deg),
        Metric::MaxHeading { from_s, .. } => {
            let tilt = max_of(from(from_s).map(|p| p.tilt_deg));
            note = Some(("max_tilt_deg", tilt));
            max_of(from(from_s).map(|p| p.heading_deg))
        }
        Metric::TiltAt { t_s } => at(t_s).map_or(f64::NAN, |p| p.tilt_deg),
        Metric::HeadingAt { t_s } => at(t_s).map_or(f64::NAN, |p| p.heading_deg),
    };
    let tilt_ok = match (case.metric, note) {
        (Metric::MaxHeading { max_tilt_deg, .. }, Some((_, tilt))) => tilt <= max_tilt_deg,
        _ => true,
    };
    FaultResult {
        name: case.name,
        passed: measured <= case.limit && tilt_ok,
        criterion: case.criterion,
        measured,
        limit: case.limit,
        note,
    }
}

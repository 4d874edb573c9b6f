//! Trajectory and sensor simulator (feature `sim`, needs `std`).
//!
//! The bench on which every accuracy claim of the crate is judged first,
//! built after the paper's simulation (section 3.1, Table 3, Figures 4-6):
//! a multirotor flying a closed-form 3-D path with an exponentially growing
//! pitch manoeuvre ([`trajectory`]), sensors with the paper's noise table
//! ([`sensors`]), a GPS whose fixes describe the vehicle `tau` seconds in
//! the past ([`delay`]), and a CSV writer for the crate's log format
//! ([`csv`]).
//!
//! A run is a [`Simulation`]: an iterator of time-ordered [`SimEvent`]s
//! (IMU samples with the truth at the same instant, magnetometer samples,
//! GPS fixes with their true delay), generated on the fly. At equal
//! timestamps the IMU sample comes first, then the magnetometer, then GPS.
//!
//! ```
//! use delaynav::sim::{Scenario, SimConfig, SimEvent, Simulation};
//!
//! let config = SimConfig { duration_s: 1.0, ..SimConfig::for_scenario(Scenario::High, 42) };
//! let events: Vec<SimEvent> = Simulation::new(config).unwrap().collect();
//! let fixes = events.iter().filter(|e| matches!(e, SimEvent::Gps { .. })).count();
//! let imu = events.iter().filter(|e| matches!(e, SimEvent::Imu { .. })).count();
//! assert_eq!((imu, fixes), (1001, 10)); // 1 kHz IMU from t = 0, 10 Hz GPS from t = 0.1 s
//! if let Some(SimEvent::Gps { delay_s, .. }) = events.iter().find(|e| matches!(e, SimEvent::Gps { .. })) {
//!     assert_eq!(*delay_s, 0.2); // Table 3's maximum delay, the default
//! }
//! ```
//!
//! # Timing
//! Stream `s` at rate `r` has samples at `round(n * 1e6 / r)` microseconds,
//! `n = 0, 1, ...` (GPS from `n = 1`), up to and including the run's
//! duration. A GPS fix received at `t_j` describes the truth at
//! `t_j - tau_j`, evaluated from the closed-form trajectory (no
//! interpolation).
//!
//! # Determinism
//! Every random stream (gyro, accelerometer, magnetometer and GPS noise,
//! biases, jitter, vibration phases) is its own ChaCha8 generator seeded
//! with `(seed, stream id)`; normal deviates come from the polar method,
//! and all the simulator's transcendental functions from the pure-Rust
//! `libm`, never the platform's math library. The same seed therefore
//! gives bit-identical samples, positions, velocities and attitudes on every
//! platform, and changing one stream's rate does not change another
//! stream's noise. (Two derived outputs use the platform's math: the truth's
//! Euler angles and geodetic GPS positions, through [`crate::geo`]; they may
//! differ in the last bit.)
//!
//! # Scoring helpers
//! [`delay_bound_s`] is the physical yardstick for any delay estimate on a
//! run: how well GPS velocities over a window can pin the delay at all;
//! [`delay_ramp_bound_s`] the same for a delay that changes linearly.
//! [`noise_floor()`] derives what Table 3's noise allows any filter to reach
//! at hover; [`trajectory_bound()`] what the run's own sensors allow along
//! its true trajectory, biases and delay included.
//!
//! # The suites
//! [`suite`] runs the estimators on the simulator and judges them: the paper's Monte Carlo
//! tables and the bound study, the sweeps, the fault suite and the delay suite, each with
//! typed results, its JSON document and its verdicts.

pub mod bound;
pub mod csv;
pub mod delay;
pub mod faults;
pub mod noise_floor;
pub mod score;
pub mod sensors;
pub mod suite;
pub mod trajectory;

pub use bound::{
    BoundConfig, BoundMagnetometer, BoundRms, BoundSample, TrajectoryBound, trajectory_bound,
};
pub use delay::{DelayProfile, DelayRamp, DelayStep};
pub use faults::{Fault, FaultySimulation};
pub use noise_floor::{NoiseFloor, noise_floor};
pub use score::{attitude_error_ned_rad, tilt_heading_error_rad};
pub use sensors::{GpsPositionOutput, SensorConfig, VibrationHarmonic};
pub use trajectory::{
    Kinematics, MotionState, PathTerm, STANDARD_GRAVITY, Scenario, Trajectory, TrajectoryConfig,
};

use crate::geo::{LocalFrame, euler_from_quaternion};
use crate::sensors::{Gps, GpsPosition, Imu, Mag};
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

/// Everything that defines one simulated run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The true motion.
    pub trajectory: TrajectoryConfig,
    /// Sensor rates, noise and biases.
    pub sensors: SensorConfig,
    /// The GPS delay.
    pub delay: DelayProfile,
    /// Length of the run, seconds.
    pub duration_s: f64,
    /// Seed of every random stream.
    pub seed: u64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self::for_scenario(Scenario::Low, 0)
    }
}

impl SimConfig {
    /// One of the paper's scenarios with Table 3's sensors, a constant
    /// 0.2 s delay and 60 s duration.
    pub fn for_scenario(scenario: Scenario, seed: u64) -> Self {
        Self {
            trajectory: TrajectoryConfig::for_scenario(scenario),
            sensors: SensorConfig::default(),
            delay: DelayProfile::default(),
            duration_s: 60.0,
            seed,
        }
    }

    /// Checks every part; the error names the first bad field.
    pub fn validate(&self) -> Result<(), crate::Error> {
        self.trajectory.validate()?;
        self.sensors.validate()?;
        self.delay.validate()?;
        if !(self.duration_s.is_finite() && self.duration_s > 0.0 && self.duration_s < 1e6) {
            return Err(crate::Error::InvalidConfig {
                field: "duration_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be positive and below 1e6 s"),
            });
        }
        Ok(())
    }
}

/// The truth at one IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// Time, microseconds.
    pub t_us: u64,
    /// Body-to-NED attitude.
    pub attitude: UnitQuaternion<f64>,
    /// Roll, pitch, yaw (ZYX), radians.
    pub euler_rad: Vector3<f64>,
    /// Position NED, metres.
    pub position_m: Vector3<f64>,
    /// Velocity NED, m/s.
    pub velocity_m_s: Vector3<f64>,
    /// Kinematic acceleration NED, m/s^2.
    pub accel_m_s2: Vector3<f64>,
    /// Angular rate, body FRD, rad/s (without bias or noise).
    pub angular_rate_rad_s: Vector3<f64>,
    /// Gyro bias, body FRD, rad/s.
    pub gyro_bias_rad_s: Vector3<f64>,
    /// Accelerometer bias, body FRD, m/s^2.
    pub accel_bias_m_s2: Vector3<f64>,
    /// GPS delay without jitter at this time, seconds.
    pub gps_delay_s: f64,
}

/// One event of a simulated run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SimEvent {
    /// An IMU sample and the truth at its time.
    Imu {
        /// The measured sample.
        sample: Imu<f64>,
        /// The truth at `sample.t_us`.
        truth: Truth,
    },
    /// A magnetometer sample.
    Mag(Mag<f64>),
    /// A GPS fix stamped with its receive time.
    Gps {
        /// The fix.
        fix: Gps<f64>,
        /// Its true delay (jitter included), seconds.
        delay_s: f64,
        /// The true motion at the instant the fix describes, `t - delay_s`.
        truth_at_validity: Kinematics,
    },
}

impl SimEvent {
    /// The event's timestamp, microseconds.
    pub fn t_us(&self) -> u64 {
        match self {
            SimEvent::Imu { sample, .. } => sample.t_us,
            SimEvent::Mag(m) => m.t_us,
            SimEvent::Gps { fix, .. } => fix.t_us,
        }
    }

    /// The IMU sample of an IMU event.
    pub fn imu_sample(&self) -> Option<Imu<f64>> {
        match self {
            SimEvent::Imu { sample, .. } => Some(*sample),
            _ => None,
        }
    }

    /// The fix of a GPS event.
    pub fn gps_fix(&self) -> Option<Gps<f64>> {
        match self {
            SimEvent::Gps { fix, .. } => Some(*fix),
            _ => None,
        }
    }
}

/// Ids of the random streams (second half of the ChaCha seed).
#[derive(Clone, Copy)]
enum Stream {
    Gyro = 1,
    Accel = 2,
    Mag = 3,
    GpsPosition = 4,
    GpsVelocity = 5,
    Bias = 6,
    BiasWalk = 7,
    Jitter = 8,
    Vibration = 9,
}

fn stream_rng(seed: u64, stream: Stream) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&(stream as u64).to_le_bytes());
    ChaCha8Rng::from_seed(key)
}

/// Standard normal deviates from one ChaCha8 stream by Marsaglia's polar
/// method (uniform pairs in the unit disc, `x sqrt(-2 ln s / s)`), with
/// `libm`'s logarithm: the same numbers on every platform.
#[derive(Debug)]
struct Gaussian {
    rng: ChaCha8Rng,
    spare: Option<f64>,
}

impl Gaussian {
    fn new(seed: u64, stream: Stream) -> Self {
        Self {
            rng: stream_rng(seed, stream),
            spare: None,
        }
    }

    fn next(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        loop {
            let u: f64 = self.rng.random_range(-1.0..1.0);
            let v: f64 = self.rng.random_range(-1.0..1.0);
            let s = u * u + v * v;
            if s > 0.0 && s < 1.0 {
                let k = (-2.0 * libm::log(s) / s).sqrt();
                self.spare = Some(v * k);
                return u * k;
            }
        }
    }

    fn vector(&mut self, std: f64) -> Vector3<f64> {
        let (x, y, z) = (self.next(), self.next(), self.next());
        Vector3::new(x, y, z) * std
    }
}

fn uniform3(rng: &mut ChaCha8Rng, max: f64) -> Vector3<f64> {
    Vector3::from_fn(|_, _| {
        if max > 0.0 {
            rng.random_range(-max..=max)
        } else {
            0.0
        }
    })
}

/// Unit Earth field in NED, `[cos I cos D, cos I sin D, sin I]`
/// ([`geo::magnetic_field_ned`](crate::geo::magnetic_field_ned) with `libm`).
fn field_ned(inclination: f64, declination: f64) -> Vector3<f64> {
    let (si, ci) = (libm::sin(inclination), libm::cos(inclination));
    Vector3::new(ci * libm::cos(declination), ci * libm::sin(declination), si)
}

/// Time of sample `n` of a stream at `rate_hz`, microseconds.
fn sample_time_us(n: u64, rate_hz: f64) -> u64 {
    (n as f64 * 1e6 / rate_hz).round() as u64
}

/// Vibration phases of one harmonic: gyro axes, then accelerometer axes.
type VibrationPhases = [f64; 6];

/// A simulated run: an iterator of time-ordered events.
#[derive(Debug)]
pub struct Simulation {
    config: SimConfig,
    trajectory: Trajectory,
    frame: LocalFrame,
    field_ned: Vector3<f64>,
    duration_us: u64,
    gyro_rng: Gaussian,
    accel_rng: Gaussian,
    mag_rng: Gaussian,
    gps_position_rng: Gaussian,
    gps_velocity_rng: Gaussian,
    bias_walk_rng: Gaussian,
    jitter_rng: Gaussian,
    vibration_phases: Vec<VibrationPhases>,
    gyro_bias: Vector3<f64>,
    accel_bias: Vector3<f64>,
    next_imu: u64,
    next_mag: u64,
    next_gps: u64,
    last_imu_us: Option<u64>,
    /// Peak-to-peak jitter of the IMU sampling instants as a fraction of the
    /// period (0: none); set by [`Simulation::with_imu_period_jitter`].
    imu_jitter: f64,
}

impl Simulation {
    /// Builds a run; fails on an invalid configuration.
    pub fn new(config: SimConfig) -> Result<Self, crate::Error> {
        config.validate()?;
        let trajectory = Trajectory::new(config.trajectory.clone(), config.duration_s)?;
        let sensors = &config.sensors;
        let mut bias_rng = stream_rng(config.seed, Stream::Bias);
        let gyro_bias = uniform3(&mut bias_rng, sensors.gyro_bias_max_rad_s);
        let accel_bias = uniform3(&mut bias_rng, sensors.accel_bias_max_m_s2());
        let mut vibration_rng = stream_rng(config.seed, Stream::Vibration);
        let vibration_phases = sensors
            .vibration
            .iter()
            .map(|_| {
                core::array::from_fn(|_| vibration_rng.random_range(0.0..core::f64::consts::TAU))
            })
            .collect();
        Ok(Self {
            frame: LocalFrame::new(sensors.origin),
            field_ned: field_ned(sensors.inclination_rad, sensors.declination_rad),
            duration_us: (config.duration_s * 1e6).round() as u64,
            gyro_rng: Gaussian::new(config.seed, Stream::Gyro),
            accel_rng: Gaussian::new(config.seed, Stream::Accel),
            mag_rng: Gaussian::new(config.seed, Stream::Mag),
            gps_position_rng: Gaussian::new(config.seed, Stream::GpsPosition),
            gps_velocity_rng: Gaussian::new(config.seed, Stream::GpsVelocity),
            bias_walk_rng: Gaussian::new(config.seed, Stream::BiasWalk),
            jitter_rng: Gaussian::new(config.seed, Stream::Jitter),
            vibration_phases,
            gyro_bias,
            accel_bias,
            next_imu: 0,
            next_mag: 0,
            next_gps: 1,
            last_imu_us: None,
            imu_jitter: 0.0,
            trajectory,
            config,
        })
    }

    /// The same run with the IMU sampled at jittered instants: sample `n` is
    /// taken (and stamped) at `round(n / rate + u_n j / (2 rate))` s, `u_n`
    /// uniform in `[-1, 1]` from a hash of `(seed, n)`, so consecutive
    /// periods vary by up to `+-j` of the nominal one (`j` = `fraction`, in
    /// `[0, 1)`). The sensors read the truth at the jittered instant: this is
    /// a sampling-time jitter with correct timestamps, not timestamp noise.
    pub fn with_imu_period_jitter(mut self, fraction: f64) -> Result<Self, crate::Error> {
        if !(0.0..1.0).contains(&fraction) {
            return Err(crate::Error::InvalidConfig {
                field: "imu_period_jitter".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be in [0, 1)"),
            });
        }
        self.imu_jitter = fraction;
        Ok(self)
    }

    /// Time of IMU sample `n`, microseconds (jittered when configured).
    fn imu_time_us(&self, n: u64) -> u64 {
        let rate = self.config.sensors.imu_rate_hz;
        if self.imu_jitter == 0.0 || n == 0 {
            return sample_time_us(n, rate);
        }
        let u = faults::unit_hash(self.config.seed, n) * 2.0 - 1.0;
        ((n as f64 + 0.5 * u * self.imu_jitter) * 1e6 / rate).round() as u64
    }

    /// The run's configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The true trajectory.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// The unit Earth field in NED.
    pub fn field_ned(&self) -> Vector3<f64> {
        self.field_ned
    }

    /// The local NED frame of geodetic fixes.
    pub fn frame(&self) -> &LocalFrame {
        &self.frame
    }

    fn vibration(&self, t_s: f64) -> (Vector3<f64>, Vector3<f64>) {
        let mut gyro = Vector3::zeros();
        let mut accel = Vector3::zeros();
        for (h, phases) in self
            .config
            .sensors
            .vibration
            .iter()
            .zip(&self.vibration_phases)
        {
            let arg = core::f64::consts::TAU * h.frequency_hz * t_s;
            for axis in 0..3 {
                gyro[axis] += h.gyro_amplitude_rad_s * libm::sin(arg + phases[axis]);
                accel[axis] += h.accel_amplitude_m_s2 * libm::sin(arg + phases[3 + axis]);
            }
        }
        (gyro, accel)
    }

    fn imu_event(&mut self, t_us: u64) -> SimEvent {
        let sensors = &self.config.sensors;
        let t_s = t_us as f64 * 1e-6;
        if let Some(prev) = self.last_imu_us {
            let dt = (t_us - prev) as f64 * 1e-6;
            self.gyro_bias += self
                .bias_walk_rng
                .vector(sensors.gyro_bias_walk_rad_s_sqrt_s * dt.sqrt());
            self.accel_bias += self
                .bias_walk_rng
                .vector(sensors.accel_bias_walk_m_s2_sqrt_s * dt.sqrt());
        }
        self.last_imu_us = Some(t_us);
        let motion = self.trajectory.state(t_s);
        let (vib_gyro, vib_accel) = self.vibration(t_s);
        let sensors = &self.config.sensors;
        let gyro = motion.angular_rate_rad_s
            + self.gyro_bias
            + self.gyro_rng.vector(sensors.gyro_noise_var_rad2_s2.sqrt())
            + vib_gyro;
        let accel = motion.specific_force_m_s2
            + self.accel_bias
            + self.accel_rng.vector(sensors.accel_noise_std_m_s2())
            + vib_accel;
        SimEvent::Imu {
            sample: Imu {
                t_us,
                gyro_rad_s: gyro,
                accel_m_s2: accel,
            },
            truth: Truth {
                t_us,
                attitude: motion.attitude,
                euler_rad: euler_from_quaternion(motion.attitude.quaternion()),
                position_m: motion.kinematics.position_m,
                velocity_m_s: motion.kinematics.velocity_m_s,
                accel_m_s2: motion.kinematics.accel_m_s2,
                angular_rate_rad_s: motion.angular_rate_rad_s,
                gyro_bias_rad_s: self.gyro_bias,
                accel_bias_m_s2: self.accel_bias,
                gps_delay_s: self.config.delay.nominal_s(t_s),
            },
        }
    }

    fn mag_event(&mut self, t_us: u64) -> SimEvent {
        let rotation = self.trajectory.rotation(t_us as f64 * 1e-6);
        let sensors = &self.config.sensors;
        let noise = self
            .mag_rng
            .vector(self.config.sensors.mag_noise_var.sqrt());
        SimEvent::Mag(Mag {
            t_us,
            field_body: sensors.mag_soft_iron * (rotation.transpose() * self.field_ned)
                + sensors.mag_hard_iron
                + noise,
        })
    }

    fn gps_event(&mut self, t_us: u64) -> SimEvent {
        let t_s = t_us as f64 * 1e-6;
        let delay = &self.config.delay;
        let jitter = if delay.has_jitter() {
            delay.jitter_s(self.jitter_rng.next())
        } else {
            0.0
        };
        let delay_s = delay.with_jitter_s(t_s, jitter);
        let truth = self.trajectory.kinematics(t_s - delay_s);
        let sensors = &self.config.sensors;
        let position_ned = truth.position_m
            + self
                .gps_position_rng
                .vector(sensors.gps_position_var_m2.sqrt());
        let velocity = truth.velocity_m_s
            + self
                .gps_velocity_rng
                .vector(sensors.gps_velocity_var_m2_s2.sqrt());
        let position = match sensors.gps_position_output {
            GpsPositionOutput::Ned => GpsPosition::Ned(position_ned),
            GpsPositionOutput::Geodetic => {
                GpsPosition::Geodetic(self.frame.to_geodetic(&position_ned))
            }
        };
        let (h_acc, v_acc, s_acc) = (
            sensors.gps_position_var_m2.sqrt(),
            sensors.gps_position_var_m2.sqrt(),
            sensors.gps_velocity_var_m2_s2.sqrt(),
        );
        let positive = |x: f64| (x > 0.0).then_some(x);
        SimEvent::Gps {
            fix: Gps {
                t_us,
                position,
                velocity_ned_m_s: velocity,
                horizontal_accuracy_m: positive(h_acc),
                vertical_accuracy_m: positive(v_acc),
                speed_accuracy_m_s: positive(s_acc),
            },
            delay_s,
            truth_at_validity: truth,
        }
    }
}

impl Iterator for Simulation {
    type Item = SimEvent;

    fn next(&mut self) -> Option<SimEvent> {
        let sensors = &self.config.sensors;
        let end = self.duration_us;
        let imu_t = self.imu_time_us(self.next_imu);
        // A rate of 0: no magnetometer (never the earliest).
        let mag_t = if sensors.mag_rate_hz > 0.0 {
            sample_time_us(self.next_mag, sensors.mag_rate_hz)
        } else {
            u64::MAX
        };
        let gps_t = sample_time_us(self.next_gps, sensors.gps_rate_hz);
        // Ties: IMU, then magnetometer, then GPS.
        let earliest = [imu_t, mag_t, gps_t]
            .into_iter()
            .filter(|&t| t <= end)
            .min()?;
        if imu_t == earliest {
            self.next_imu += 1;
            Some(self.imu_event(imu_t))
        } else if mag_t == earliest {
            self.next_mag += 1;
            Some(self.mag_event(mag_t))
        } else {
            self.next_gps += 1;
            Some(self.gps_event(gps_t))
        }
    }
}

/// GPS velocities' power to pin the delay, as the RMS of a Cramér-Rao-like
/// bound over the scored fixes.
///
/// A fix's velocity `v(t_j - tau) + n` depends on the delay through
/// `dv/dtau = -a(t_j - tau)`; with white noise of variance `sigma_v^2` per
/// axis, the Fisher information of the fixes received in the window
/// up to and including fix `k` is
/// `F_k = sum_j |a(t_j - tau_j)|^2 / sigma_v^2`, and no unbiased estimate
/// built from them can beat `1 / sqrt(F_k)`. Returns the RMS of that bound
/// over the fixes received at or after `skip_us`, `None` when no fix is
/// scored or one has no information (no acceleration); zero noise gives
/// a zero bound.
///
/// `fixes` are `(receive time in microseconds, true acceleration at
/// validity)` in time order; the window holds the fixes received in
/// `(t_k - window_us, t_k]`.
pub fn delay_bound_s(
    fixes: &[(u64, Vector3<f64>)],
    velocity_var_m2_s2: f64,
    window_us: u64,
    skip_us: u64,
) -> Option<f64> {
    let mut sum_sq = 0.0;
    let mut count = 0usize;
    let mut first = 0usize;
    for (k, &(t_k, _)) in fixes.iter().enumerate() {
        while fixes[first].0 + window_us <= t_k {
            first += 1;
        }
        if t_k < skip_us {
            continue;
        }
        let information: f64 = fixes[first..=k].iter().map(|f| f.1.norm_squared()).sum();
        if information <= 0.0 {
            return None;
        }
        sum_sq += velocity_var_m2_s2 / information;
        count += 1;
    }
    (count > 0).then(|| (sum_sq / count as f64).sqrt())
}

/// The same bound for a delay that changes linearly, `tau(t) = tau_0 + r t`,
/// estimated from every fix since the first (no window).
///
/// With the regressor `h_j = (1, t_j)` and the weights
/// `w_j = |a(t_j - tau_j)|^2 / sigma_v^2`, the Fisher information of
/// `(tau_0, r)` after fix `k` is `F_k = sum_{j <= k} w_j h_j h_j^T`, and no
/// unbiased estimate of `tau(t_k)` can have a variance below
/// `h_k^T F_k^-1 h_k`. Returns the RMS of that bound over the fixes received
/// at or after `skip_us`; `None` while `F_k` is singular at a scored fix
/// (fewer than two fixes with motion). An estimator that does not know the
/// delay is a straight line cannot do better than this; one that models it
/// as constant is bounded by [`delay_bound_s`] with a window of the whole run,
/// which is only valid while it is constant.
pub fn delay_ramp_bound_s(
    fixes: &[(u64, Vector3<f64>)],
    velocity_var_m2_s2: f64,
    skip_us: u64,
) -> Option<f64> {
    let t0 = fixes.first()?.0;
    // Fisher information entries in seconds from the first fix.
    let (mut f00, mut f01, mut f11) = (0.0f64, 0.0f64, 0.0f64);
    let mut sum_sq = 0.0;
    let mut count = 0usize;
    for &(t_us, accel) in fixes {
        let t = (t_us - t0) as f64 * 1e-6;
        let w = accel.norm_squared();
        f00 += w;
        f01 += w * t;
        f11 += w * t * t;
        if t_us < skip_us {
            continue;
        }
        let det = f00 * f11 - f01 * f01;
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        sum_sq += velocity_var_m2_s2 * (f11 - 2.0 * t * f01 + t * t * f00) / det;
        count += 1;
    }
    (count > 0).then(|| (sum_sq / count as f64).sqrt())
}

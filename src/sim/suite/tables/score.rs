//! One estimator on one run, scored against the truth at every IMU sample.

use super::RunSetup;
use crate::ekf16::state as ekf16_state;
use crate::geo::wrap_pi;
use crate::nav::DelayCompensatedNav;
use crate::sensors::{Gps, GpsPosition, Imu, Mag};
use crate::sim::suite::stats::Rms;
use crate::sim::{STANDARD_GRAVITY, SimEvent, tilt_heading_error_rad};
use crate::{AugmentedEkf17, Ekf16, Estimate, GpsOutcome, Navigator, Scalar};
use nalgebra::{Matrix6, Quaternion, SMatrix, UnitQuaternion, Vector3};
use std::time::{Duration, Instant};

/// Spacing of the points kept for the plots, µs.
pub const TRACE_STEP_US: u64 = 20_000;
/// Spacing of the instants at which the NEES is sampled, µs.
pub const NEES_STEP_US: u64 = 100_000;

/// Time series of one estimator on one run, for the plots: every [`TRACE_STEP_US`] from the
/// start when the run keeps traces.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Trace {
    /// Times, s.
    pub t_s: Vec<f64>,
    /// Roll, pitch, yaw error, degrees.
    pub attitude_err_deg: Vec<[f64; 3]>,
    /// Estimated pitch, degrees.
    pub pitch_deg: Vec<f64>,
    /// Estimated delay, s (NaN for an estimator without one).
    pub delay_s: Vec<f64>,
}

/// The scores of one estimator on one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunScore {
    /// Its figures.
    pub metrics: Metrics,
    /// Its time series (empty unless the run keeps traces).
    pub trace: Trace,
    /// NEES at every NEES instant after the skip (NaN without an estimate or a covariance).
    pub nees_series: Vec<f64>,
    /// Sum and count of the GPS NIS after the skip.
    pub nis: (f64, usize),
}

/// RMS errors and cost of one estimator: of one run, or one statistic
/// (mean, interval bound, median) over the seeds of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Metrics {
    /// Roll error (ZYX Euler angles, wrapped), degrees.
    pub roll_deg: f64,
    /// Pitch error, degrees.
    pub pitch_deg: f64,
    /// Yaw error, degrees.
    pub yaw_deg: f64,
    /// RMS of the rotation-vector tilt error (`sim::tilt_heading_error_rad`), degrees.
    pub tilt_deg: f64,
    /// RMS of the rotation-vector heading error, degrees.
    pub heading_deg: f64,
    /// RMS of the 3-D velocity error norm, m/s.
    pub vel_m_s: f64,
    /// RMS of the 3-D position error norm, m.
    pub pos_m: f64,
    /// RMS of estimate minus true delay, s; `None` for an estimator without a delay.
    pub delay_s: Option<f64>,
    /// Per-axis RMS gyro bias errors, rad/s.
    pub gyro_bias_rad_s: [f64; 3],
    /// Per-axis RMS accelerometer bias errors, g.
    pub accel_bias_g: [f64; 3],
    /// Mean NEES of `[position, velocity]` over the scored NEES instants.
    pub nees: Option<f64>,
    /// Mean NIS of the GPS fixes fused after the skip.
    pub nis: Option<f64>,
    /// Time inside the estimator's own `push_*` calls per IMU sample, µs (a timing figure).
    pub us_per_imu_sample: f64,
}

/// What a filter reports about its own position and velocity error: the
/// instant its estimate describes, the estimate, and the 6x6 covariance of
/// `[position, velocity]` (NED, m and m/s).
pub type PosVelCovariance = (u64, Vector3<f64>, Vector3<f64>, Matrix6<f64>);

/// Position-velocity covariance of the 16-state EKF.
pub fn ekf16_covariance<T: Scalar>(f: &Ekf16<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(&f.estimate()?, f.covariance()))
}

/// Position-velocity covariance of the augmented EKF.
pub fn aekf17_covariance<T: Scalar>(f: &AugmentedEkf17<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(&f.estimate()?, f.covariance()))
}

/// Position-velocity covariance of the navigator's horizon EKF, at the
/// horizon (its forward-reckoned present carries no covariance of its own).
pub fn nav_covariance<T: Scalar>(n: &DelayCompensatedNav<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(
        &n.horizon_estimate()?,
        n.horizon_filter().covariance(),
    ))
}

/// The `[position, velocity]` block of a 16- (or 17-) state covariance in
/// `Ekf16`'s state order (q0..q3, position, velocity, biases[, delay]).
fn pos_vel_block<T: Scalar, const N: usize>(
    estimate: &Estimate<T>,
    p: &SMatrix<T, N, N>,
) -> PosVelCovariance {
    (
        estimate.t_us,
        estimate.position_ned_m.map(T::as_f64),
        estimate.velocity_ned_m_s.map(T::as_f64),
        p.fixed_view::<6, 6>(ekf16_state::POS, ekf16_state::POS)
            .map(T::as_f64),
    )
}

/// One simulated sample converted to the estimator's float type.
enum Sample<T: Scalar> {
    Imu(Imu<T>),
    Mag(Mag<T>),
    Gps(Gps<T>),
}

impl<T: Scalar> Sample<T> {
    fn of(event: &SimEvent) -> Self {
        match event {
            SimEvent::Imu { sample: s, .. } => Sample::Imu(Imu {
                t_us: s.t_us,
                gyro_rad_s: s.gyro_rad_s.map(T::lit),
                accel_m_s2: s.accel_m_s2.map(T::lit),
            }),
            SimEvent::Mag(m) => Sample::Mag(Mag {
                t_us: m.t_us,
                field_body: m.field_body.map(T::lit),
            }),
            SimEvent::Gps { fix: g, .. } => Sample::Gps(Gps {
                t_us: g.t_us,
                position: match g.position {
                    GpsPosition::Ned(p) => GpsPosition::Ned(p.map(T::lit)),
                    GpsPosition::Geodetic(p) => GpsPosition::Geodetic(p),
                },
                velocity_ned_m_s: g.velocity_ned_m_s.map(T::lit),
                horizontal_accuracy_m: g.horizontal_accuracy_m.map(T::lit),
                vertical_accuracy_m: g.vertical_accuracy_m.map(T::lit),
                speed_accuracy_m_s: g.speed_accuracy_m_s.map(T::lit),
            }),
        }
    }
}

/// Normalized innovation squared of a GPS fusion, position and velocity
/// (6 degrees of freedom), from the records' innovations and the diagonal
/// of their innovation covariance.
fn gps_nis<T: Scalar>(outcome: &GpsOutcome<T>) -> Option<f64> {
    let GpsOutcome::Fused { position, velocity } = outcome else {
        return None;
    };
    let mut nis = 0.0;
    for r in [position, velocity] {
        for i in 0..3 {
            let s = r.innovation_variance[i].as_f64();
            if s.is_nan() || s <= 0.0 {
                return None;
            }
            nis += r.innovation[i].as_f64().powi(2) / s;
        }
    }
    Some(nis)
}

/// The NEES instants: the first IMU sample at or after each `50 ms + k 100 ms`
/// (half-way between two 10 Hz fixes), the same on every seed.
struct NeesClock {
    next_us: u64,
}

impl NeesClock {
    fn new() -> Self {
        Self {
            next_us: NEES_STEP_US / 2,
        }
    }

    /// Whether the sample at `t_us` is an instant (call once per IMU sample).
    fn tick(&mut self, t_us: u64) -> bool {
        if t_us < self.next_us {
            return false;
        }
        while self.next_us <= t_us {
            self.next_us += NEES_STEP_US;
        }
        true
    }
}

/// The running sums of one run's figures.
#[derive(Default)]
struct Accumulated {
    /// Roll, pitch, yaw, tilt, heading (deg), velocity (m/s), position (m) errors.
    figures: [Rms; 7],
    /// Gyro bias x, y, z (rad/s), accelerometer bias x, y, z (g) errors.
    biases: [Rms; 6],
    /// Delay errors (s), for an estimator with a delay estimate.
    delay: Option<Rms>,
    /// Scored samples without an estimate.
    missing: usize,
    /// Time inside the estimator's calls, and the IMU samples.
    busy: (Duration, usize),
    /// Sum and count of the GPS NIS after the skip.
    nis: (f64, usize),
}

impl Accumulated {
    /// The run's figures; an estimator without an estimate after the
    /// convergence time fails the run (every figure NaN).
    fn metrics(&self, nees_series: &[f64]) -> Metrics {
        let penalty = if self.missing > 0 { f64::NAN } else { 0.0 };
        let finite_nees: Vec<f64> = nees_series
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .collect();
        let [roll, pitch, yaw, tilt, heading, vel, pos] = self.figures.map(|r| r.value() + penalty);
        let biases = self.biases.map(|r| r.value() + penalty);
        let (nis_sum, nis_count) = self.nis;
        let (busy, imu_samples) = self.busy;
        Metrics {
            roll_deg: roll,
            pitch_deg: pitch,
            yaw_deg: yaw,
            tilt_deg: tilt,
            heading_deg: heading,
            vel_m_s: vel,
            pos_m: pos,
            delay_s: self.delay.map(|d| d.value() + penalty),
            gyro_bias_rad_s: [biases[0], biases[1], biases[2]],
            accel_bias_g: [biases[3], biases[4], biases[5]],
            nees: (!finite_nees.is_empty())
                .then(|| finite_nees.iter().sum::<f64>() / finite_nees.len() as f64 + penalty),
            nis: (nis_count > 0).then(|| nis_sum / nis_count as f64 + penalty),
            us_per_imu_sample: busy.as_secs_f64() * 1e6 / imu_samples.max(1) as f64,
        }
    }
}

/// Feeds a run to a navigator in float type `T`, timing only its own calls,
/// and scores its estimate against the truth at every IMU sample after the
/// skip; `covariance` reads the filter's position-velocity covariance for
/// the NEES (`|_| None` for an estimator without one).
///
/// Refusals are the estimator's business (it counts them); scoring goes on with whatever
/// estimate it holds. An estimator without an estimate at a scored sample fails the run:
/// every figure NaN.
pub fn score<T: Scalar, N: Navigator<T>>(
    mut nav: N,
    setup: &RunSetup,
    covariance: impl Fn(&N) -> Option<PosVelCovariance>,
) -> RunScore {
    let mut acc = Accumulated::default();
    let mut trace = Trace::default();
    let mut nees_series = Vec::new();
    let mut nees_clock = NeesClock::new();
    for event in &setup.events {
        // Conversion to `T` happens outside the timed call.
        let converted = Sample::<T>::of(event);
        let start = Instant::now();
        let outcome = match &converted {
            Sample::Imu(s) => {
                let _ = nav.push_imu(s);
                None
            }
            Sample::Mag(m) => {
                let _ = nav.push_mag(m);
                None
            }
            Sample::Gps(g) => nav.push_gps(g).ok(),
        };
        acc.busy.0 += start.elapsed();
        if let Some(nis) = outcome.as_ref().and_then(gps_nis)
            && event.t_us() >= setup.skip_us
        {
            acc.nis.0 += nis;
            acc.nis.1 += 1;
        }
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        acc.busy.1 += 1;
        let nees_instant = nees_clock.tick(truth.t_us);
        if truth.t_us < setup.skip_us && !setup.keep_trace {
            continue;
        }
        let Some(est) = nav.estimate() else {
            if truth.t_us >= setup.skip_us {
                acc.missing += 1;
                if nees_instant {
                    nees_series.push(f64::NAN);
                }
            }
            continue;
        };
        let attitude = UnitQuaternion::new_normalize(Quaternion::from(
            est.attitude.quaternion().coords.map(T::as_f64),
        ));
        let e = est.euler_rad().map(T::as_f64);
        let err_deg: [f64; 3] =
            core::array::from_fn(|i| wrap_pi(e[i] - truth.euler_rad[i]).to_degrees());
        let delay_err = est.delay_s.map(|d| d.as_f64() - truth.gps_delay_s);
        if setup.keep_trace && truth.t_us.is_multiple_of(TRACE_STEP_US) {
            trace.t_s.push(truth.t_us as f64 * 1e-6);
            trace.attitude_err_deg.push(err_deg);
            trace.pitch_deg.push(e[1].to_degrees());
            trace.delay_s.push(est.delay_s.map_or(f64::NAN, T::as_f64));
        }
        if truth.t_us < setup.skip_us {
            continue;
        }
        if nees_instant {
            nees_series.push(covariance(&nav).map_or(f64::NAN, |c| setup.nees(&c)));
        }
        let (tilt_rad, heading_rad) = tilt_heading_error_rad(&attitude, &truth.attitude);
        let figures = [
            err_deg[0],
            err_deg[1],
            err_deg[2],
            tilt_rad.to_degrees(),
            heading_rad.to_degrees(),
            (est.velocity_ned_m_s.map(T::as_f64) - truth.velocity_m_s).norm(),
            (est.position_ned_m.map(T::as_f64) - truth.position_m).norm(),
        ];
        let gyro_bias = est.gyro_bias_rad_s.map(T::as_f64) - truth.gyro_bias_rad_s;
        let accel_bias = est.accel_bias_m_s2.map(T::as_f64) - truth.accel_bias_m_s2;
        let biases = [
            gyro_bias.x,
            gyro_bias.y,
            gyro_bias.z,
            accel_bias.x / STANDARD_GRAVITY,
            accel_bias.y / STANDARD_GRAVITY,
            accel_bias.z / STANDARD_GRAVITY,
        ];
        for (rms, x) in acc
            .figures
            .iter_mut()
            .chain(&mut acc.biases)
            .zip(figures.into_iter().chain(biases))
        {
            rms.add(x);
        }
        if let Some(d) = delay_err {
            acc.delay.get_or_insert_default().add(d);
        }
    }
    RunScore {
        metrics: acc.metrics(&nees_series),
        trace,
        nees_series,
        nis: acc.nis,
    }
}

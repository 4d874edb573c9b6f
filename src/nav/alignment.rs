//! Control apart from fusion: where the start-up stands, how an alignment
//! made in motion or after a reset is refined, and what a reset keeps.

use super::health::{AlignmentState, ResetCause, ResetRecord};
use super::timeline::StreamClock;
use super::{DelayCompensatedNav, MOVING_SPEED_M_S, MOVING_TILT_STD_RAD};
use crate::ekf16::state::{ACCEL_BIAS, GYRO_BIAS, QUAT, attitude_covariance};
use crate::scalar::Scalar;
use crate::zero_option::ZeroOption;
use nalgebra::{SVector, Vector3};

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// Restarts the navigator as if new, keeping its configuration and its
    /// refusal counters (recorded as [`ResetCause::Requested`] in
    /// [`health`](Self::health)). Call it when a push returns
    /// [`Error::TimeWentBackwards`](crate::Error::TimeWentBackwards) for a clock that really went back (a
    /// rebooted sensor hub): every later sample would be refused otherwise.
    /// No allocation; the horizon EKF and the delay loop are configured
    /// again in place from the configuration, which
    /// [`configure`](Self::configure) validated. Nothing happens to a
    /// navigator not configured.
    pub fn reset(&mut self) {
        if !self.configured {
            return;
        }
        if let Some(x) = self.ekf.nav_state() {
            let p = self.ekf.covariance();
            let mut biases = SVector::<T, 6>::zeros();
            let mut variances = SVector::<T, 6>::zeros();
            for i in 0..3 {
                biases[i] = x.accel_bias_m_s2[i];
                biases[3 + i] = x.gyro_bias_rad_s[i];
                variances[i] = p[(ACCEL_BIAS + i, ACCEL_BIAS + i)];
                variances[3 + i] = p[(GYRO_BIAS + i, GYRO_BIAS + i)];
            }
            self.retained_biases = Some((biases, variances));
        }
        // Validated by `configure`: neither fails (a failure would leave
        // the part refusing, never half reset).
        let refusals = self.horizon_refusals();
        if self.ekf.configure(self.config.ekf).is_ok() {
            self.refusals.horizon = refusals;
        }
        let _ = self.delay_loop.configure(self.config.loop_config());
        self.accel_whitening.reset();
        self.gyro_whitening.reset();
        self.history.clear();
        self.times.clear();
        self.forward.reset();
        self.deltas.clear();
        self.mags_due = false;
        self.mags.clear();
        self.mag_spacing_us = 0;
        self.last_reset = ZeroOption::Some(ResetRecord {
            t_us: self.imu_clock.last(),
            cause: ResetCause::Requested,
        });
        self.last_imu = None;
        self.imu_clock = StreamClock::default();
        self.gps_clock = StreamClock::default();
        self.mag_clock = StreamClock::default();
        self.last_update = ZeroOption::None;
        self.pending_delay_fix = None;
        self.last_fix_velocity = None;
        self.valid_delay_updates = 0;
        self.mag_at_horizon = false;
        self.geodetic_fixes = ZeroOption::None;
        self.present_accel = Vector3::zeros();
    }

    /// Where the navigator is in its start-up.
    pub fn alignment(&self) -> AlignmentState {
        if !self.configured {
            AlignmentState::NotConfigured
        } else if self.forward.is_ready() {
            AlignmentState::Aligned
        } else if self.ekf.is_initialized() {
            AlignmentState::CarryingForward
        } else if self.ekf.time_us().is_some() {
            AlignmentState::WaitingForGps
        } else {
            AlignmentState::WaitingForImu
        }
    }

    /// Right after the horizon EKF initialized itself from a fix: when the
    /// vehicle was moving faster than [`MOVING_SPEED_M_S`] (an in-flight
    /// start, a reset in flight) the accelerometer is probably not the vertical, so the tilt variance is raised to
    /// [`MOVING_TILT_STD_RAD`] for the GPS velocity to resolve it; after a
    /// [`reset`](Self::reset) the IMU biases and their variances are carried
    /// over. The EKF is rebuilt from its own state (same time and origin).
    pub(super) fn refine_alignment(&mut self, speed_m_s: T) {
        let moving = speed_m_s > T::lit(MOVING_SPEED_M_S);
        let retained = self.retained_biases.take();
        if !moving && retained.is_none() {
            return;
        }
        let (Some(mut x), Some(t_us)) = (self.ekf.nav_state(), self.ekf.time_us()) else {
            return;
        };
        let mut p = *self.ekf.covariance();
        if moving {
            let c = &self.config.ekf;
            let tilt = T::lit(MOVING_TILT_STD_RAD).max(c.initial_tilt_std_rad);
            let yaw = if self.mag_at_horizon {
                c.initial_yaw_std_rad
            } else {
                c.initial_yaw_std_no_mag_rad
            };
            p.fixed_view_mut::<4, 4>(QUAT, QUAT)
                .copy_from(&attitude_covariance(&x.attitude, tilt, tilt, yaw));
        }
        if let Some((biases, variances)) = retained {
            x.accel_bias_m_s2 = biases.fixed_rows::<3>(0).into_owned();
            x.gyro_bias_rad_s = biases.fixed_rows::<3>(3).into_owned();
            for i in 0..3 {
                for j in 0..16 {
                    for k in [ACCEL_BIAS + i, GYRO_BIAS + i] {
                        p[(k, j)] = T::zero();
                        p[(j, k)] = T::zero();
                    }
                }
                p[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = variances[i];
                p[(GYRO_BIAS + i, GYRO_BIAS + i)] = variances[3 + i];
            }
        }
        let mut config = self.config.ekf;
        if let Some(frame) = self.ekf.frame() {
            config.origin = Some(frame.origin());
        }
        // In place (this runs in a push): the old filter's counters are
        // kept; on error nothing changed.
        let refusals = self.horizon_refusals();
        if self.ekf.configure_from_state(config, t_us, &x, &p).is_ok() {
            self.refusals.horizon = refusals;
        }
    }
}

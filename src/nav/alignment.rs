//! Control apart from fusion: where the start-up stands, how an alignment
//! made in motion or after a reset is refined, and what a reset keeps.

use super::health::HEADING_STALE_US;
use super::health::{AlignmentState, ResetCause, ResetRecord};
use super::timeline::StreamClock;
use super::{
    DELAY_KNOWN_STD_S, DelayCompensatedNav, GSF_DISAGREEMENT_FIXES, GSF_DISAGREEMENT_RAD,
    GSF_PREDICT_PERIOD_US, HEADING_UNKNOWN_STD_RAD, MOVING_SPEED_M_S, MOVING_TILT_STD_RAD,
};
use crate::ekf16::NavState;
use crate::ekf16::measurement::yaw_direction;
use crate::ekf16::state::{ACCEL_BIAS, GYRO_BIAS, QUAT, StateCovariance, VEL, attitude_covariance};
use crate::geo::wrap_pi;
use crate::scalar::Scalar;
use crate::zero_option::ZeroOption;
use nalgebra::{Quaternion, SVector, UnitQuaternion, Vector3};

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
        self.aligned_moving = false;
        self.heading_checked = false;
        self.geodetic_fixes = ZeroOption::None;
        self.present_accel = Vector3::zeros();
        self.imu_gap_end_us = 0;
        self.yaw_gsf.clear();
        self.gsf_disagreements = 0;
        self.gsf_step = ([T::zero(); 2], T::zero(), 0);
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
        self.aligned_moving = moving;
        self.heading_checked = false;
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
        self.rebuild_horizon(t_us, &x, &p);
    }

    /// Rebuilds the horizon EKF from a state and covariance (same time and
    /// origin), in place (this runs in a push): the old filter's counters
    /// are kept; on error nothing changed.
    fn rebuild_horizon(&mut self, t_us: u64, x: &NavState<T>, p: &StateCovariance<T>) -> bool {
        let mut config = self.config.ekf;
        if let Some(frame) = self.ekf.frame() {
            config.origin = Some(frame.origin());
        }
        let refusals = self.horizon_refusals();
        let rebuilt = self.ekf.configure_from_state(config, t_us, x, p).is_ok();
        if rebuilt {
            self.refusals.horizon = refusals;
        }
        rebuilt
    }

    /// The horizon filter's horizontal velocity (NED, m/s), its heading as
    /// the unit vector `[cos yaw, sin yaw]` (from the rotation matrix's
    /// first column, no trigonometry) and its time; `None` until
    /// initialized or when the body x axis is vertical.
    pub(super) fn horizon_heading(&self) -> Option<([T; 2], [T; 2], u64)> {
        let t_us = self.ekf.time_us().filter(|_| self.ekf.is_initialized())?;
        let x = self.ekf.state_vector();
        let (q0, q1, q2, q3) = (x[QUAT], x[QUAT + 1], x[QUAT + 2], x[QUAT + 3]);
        let two = T::lit(2.0);
        let (r00, r10) = (
            T::one() - two * (q2 * q2 + q3 * q3),
            two * (q1 * q2 + q0 * q3),
        );
        let h = r00.hypot(r10);
        (h > T::lit(1e-3)).then(|| ([x[VEL], x[VEL + 1]], [r00 / h, r10 / h], t_us))
    }

    /// After a prediction of the horizon filter from `before` (its
    /// [`horizon_heading`](Self::horizon_heading) then): the step's
    /// horizontal velocity change, turned into the heading frame, and its
    /// yaw change are added to the yaw estimator's step (turned by the yaw
    /// accumulated so far, to second order); the estimator predicts over
    /// its step once it spans [`GSF_PREDICT_PERIOD_US`] (`yaw_gsf.rs`).
    /// The changes are the prediction's alone: fusions happen outside it.
    pub(super) fn predict_yaw_gsf(&mut self, before: Option<([T; 2], [T; 2], u64)>) {
        let (Some((v0, h0, t0)), Some((v1, h1, t1))) = (before, self.horizon_heading()) else {
            return;
        };
        if t1 <= t0 || self.mag_recent(t1) {
            return;
        }
        // sin of the yaw change: the change itself to third order.
        let dyaw = h0[0] * h1[1] - h0[1] * h1[0];
        let (dvn, dve) = (v1[0] - v0[0], v1[1] - v0[1]);
        let (hx, hy) = (h0[0] * dvn + h0[1] * dve, h0[0] * dve - h0[1] * dvn);
        let (dv, yaw, us) = &mut self.gsf_step;
        let (c, s) = (T::one() - *yaw * *yaw * T::lit(0.5), *yaw);
        dv[0] += c * hx - s * hy;
        dv[1] += s * hx + c * hy;
        *yaw += dyaw;
        *us = us.saturating_add(u32::try_from(t1 - t0).unwrap_or(u32::MAX));
        if u64::from(*us) >= GSF_PREDICT_PERIOD_US {
            self.flush_yaw_gsf();
        }
    }

    /// The horizon filter's heading variance, rad^2, from its quaternion
    /// covariance (`dpsi/dq = 4 dq/dpsi` for a unit `q`).
    fn horizon_heading_var(&self) -> T {
        let x = self.ekf.state_vector();
        let q = Quaternion::new(x[QUAT], x[QUAT + 1], x[QUAT + 2], x[QUAT + 3]);
        let d = yaw_direction(&q) * T::lit(4.0);
        let p = self.ekf.covariance().fixed_view::<4, 4>(QUAT, QUAT);
        (d.transpose() * p * d)[0].max(T::zero())
    }

    /// The horizon filter, aligned in motion, does not know its heading:
    /// the yaw estimator has not converged since, no magnetometer update is
    /// recent ([`HEADING_STALE_US`]) and its heading standard deviation is
    /// above [`HEADING_UNKNOWN_STD_RAD`]. A start at rest is left out: its
    /// fixes carry little acceleration to turn the wrong way, and keeping
    /// them off the tilt until the heading is known cost `mag_late` (a
    /// magnetometer from 5 s) a third more yaw error.
    pub(super) fn heading_unknown(&self) -> bool {
        let std = T::lit(HEADING_UNKNOWN_STD_RAD);
        self.aligned_moving_without_mag()
            && !self.heading_checked
            && self.horizon_heading_var() > std * std
    }

    /// The horizon filter was aligned in motion, is initialized, and no
    /// magnetometer update is recent ([`HEADING_STALE_US`]).
    fn aligned_moving_without_mag(&self) -> bool {
        self.aligned_moving
            && self.ekf.is_initialized()
            && self.ekf.time_us().is_some_and(|t| !self.mag_recent(t))
    }

    /// After an alignment made in motion without a recent magnetometer
    /// update, the fixes are kept off the attitude and the biases while the
    /// heading is unknown ([`heading_unknown`](Self::heading_unknown)) or
    /// the delay loop's standard deviation is above [`DELAY_KNOWN_STD_S`]:
    /// without a magnetometer the heading is seen only through the GPS
    /// velocity's turns, and a fix timed wrong turns the wrong way.
    pub(super) fn attitude_from_gps_withheld(&self) -> bool {
        self.heading_unknown()
            || (self.aligned_moving_without_mag() && self.delay_std_s() > T::lit(DELAY_KNOWN_STD_S))
    }

    /// A magnetometer update was fused within [`HEADING_STALE_US`] of the
    /// horizon time `t_h_us`: the yaw estimator rests.
    fn mag_recent(&self, t_h_us: u64) -> bool {
        self.ekf
            .last_mag_fused_us()
            .is_some_and(|t| t_h_us <= t.saturating_add(HEADING_STALE_US))
    }

    /// The yaw estimator predicts over the step accumulated since its last
    /// prediction.
    pub(super) fn flush_yaw_gsf(&mut self) {
        let (dv, yaw, us) = self.gsf_step;
        if us > 0 {
            self.yaw_gsf.predict(
                dv,
                yaw,
                T::seconds_from_us(u64::from(us)),
                self.ekf.tilt_std(),
            );
            self.gsf_step = ([T::zero(); 2], T::zero(), 0);
        }
    }

    /// After a fix fused (or the alignment from it) at the horizon: the
    /// yaw estimator fuses its velocity when no magnetometer update is
    /// recent ([`HEADING_STALE_US`]; else it rests, cleared); once it has
    /// converged, the horizon
    /// filter's heading is set from it when the two disagree for
    /// [`GSF_DISAGREEMENT_FIXES`] fixes in a row, by more than
    /// [`GSF_DISAGREEMENT_RAD`] and three standard deviations of their
    /// difference: the alignment in flight without a magnetometer, or
    /// with one that is refused. Each reset is counted in
    /// `Health::yaw_gsf.yaw_resets` and recorded as [`ResetCause::YawGsf`].
    #[inline(never)]
    pub(super) fn fuse_yaw_gsf(&mut self, velocity_ned_m_s: &Vector3<T>, std_m_s: Option<T>) {
        let std = std_m_s.unwrap_or(self.config.ekf.gps_velocity_std_m_s);
        if self.ekf.time_us().is_some_and(|t| self.mag_recent(t)) {
            // The magnetometer holds the heading: the bank rests, and
            // starts afresh when the magnetometer goes stale.
            if self.yaw_gsf.is_started() {
                self.yaw_gsf.clear();
                self.gsf_step = ([T::zero(); 2], T::zero(), 0);
            }
            self.gsf_disagreements = 0;
            return;
        }
        self.flush_yaw_gsf();
        self.yaw_gsf
            .update([velocity_ned_m_s[0], velocity_ned_m_s[1]], std);
        let (Some((yaw, var)), Some((_, h, _))) =
            (self.yaw_gsf.converged_yaw(), self.horizon_heading())
        else {
            self.gsf_disagreements = 0;
            return;
        };
        let ours_var = self.horizon_heading_var();
        let diff = wrap_pi(yaw - h[1].atan2(h[0]));
        let bound = T::lit(GSF_DISAGREEMENT_RAD).max(T::lit(3.0) * (var + ours_var).sqrt());
        if self.heading_unknown() {
            // The first convergence: the heading is checked. Set at once
            // where the two disagree; the tilt and the biases were kept
            // from the GPS while the heading was unknown (`push_gps`),
            // nothing to reopen. Where they agree the estimator's yaw is
            // not taken: levelled by a tilt the fixes could not correct
            // yet, it can be sure and wrong (docs/nav.md).
            self.heading_checked = true;
            if diff.abs() > bound {
                self.reset_yaw(diff, var, false);
            }
            return;
        }
        if diff.abs() > bound {
            self.gsf_disagreements = self.gsf_disagreements.saturating_add(1);
        } else {
            self.gsf_disagreements = 0;
        }
        if self.gsf_disagreements >= GSF_DISAGREEMENT_FIXES {
            self.reset_yaw(diff, var, true);
        }
    }

    /// Turns the horizon filter's attitude by `diff_rad` about down and
    /// sets its heading variance to `var_rad2` (the attitude's
    /// cross-covariances cleared). With `reopen` the tilt and the
    /// accelerometer bias were fitted to the GPS velocity through the wrong
    /// heading, so they are reopened: the tilt standard deviation raised to
    /// at least [`MOVING_TILT_STD_RAD`], the accelerometer bias set back to
    /// its configured start and variance (its cross-covariances cleared).
    #[inline(never)]
    fn reset_yaw(&mut self, diff_rad: T, var_rad2: T, reopen: bool) {
        let (Some(mut x), Some(t_us)) = (self.ekf.nav_state(), self.ekf.time_us()) else {
            return;
        };
        let mut p = *self.ekf.covariance();
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), diff_rad);
        x.attitude = turn * x.attitude;
        let c = &self.config.ekf;
        let tilt = self.ekf.tilt_std();
        let tilt = if reopen {
            tilt.max(T::lit(MOVING_TILT_STD_RAD))
                .max(c.initial_tilt_std_rad)
        } else {
            tilt
        };
        let bias = if reopen { 3 } else { 0 };
        for i in (QUAT..QUAT + 4).chain(ACCEL_BIAS..ACCEL_BIAS + bias) {
            for j in 0..16 {
                p[(i, j)] = T::zero();
                p[(j, i)] = T::zero();
            }
        }
        if reopen {
            x.accel_bias_m_s2 = c.initial_accel_bias_m_s2;
            let bias_var = c.initial_accel_bias_std_m_s2 * c.initial_accel_bias_std_m_s2;
            for i in ACCEL_BIAS..ACCEL_BIAS + 3 {
                p[(i, i)] = bias_var;
            }
        }
        p.fixed_view_mut::<4, 4>(QUAT, QUAT)
            .copy_from(&attitude_covariance(
                &x.attitude,
                tilt,
                tilt,
                var_rad2.sqrt(),
            ));
        self.gsf_disagreements = 0;
        if self.rebuild_horizon(t_us, &x, &p) {
            self.gsf_yaw_resets = self.gsf_yaw_resets.saturating_add(1);
            self.last_reset = ZeroOption::Some(ResetRecord {
                t_us: self.imu_clock.last(),
                cause: ResetCause::YawGsf,
            });
        }
    }
}

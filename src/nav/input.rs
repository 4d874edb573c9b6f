//! Input: every sample checked, timed and counted before it moves
//! anything (the [`Navigator`] implementation: the five steps of an IMU
//! sample, a GPS fix fused at the horizon, a magnetometer sample queued).

use super::health::{ResetCause, ResetRecord};
use super::refusals::{bump, counted};
use super::timeline::SampleTimes;
use super::{DELAY_UPDATE_MAX_WAIT, DelayCompensatedNav};
use crate::delay::MAX_INPUT_MAGNITUDE;
use crate::ekf16::nav_core::GAP_MOTION_MAX_S;
use crate::ekf16::nav_core::check_position_kind;
use crate::ekf16::state::{ACCEL_BIAS, GYRO_BIAS, POS, VEL, quaternion_of};
use crate::error::Error;
use crate::estimate::{Estimate, GpsOutcome, MagOutcome, Navigator};
use crate::geo::rotation_matrix;
use crate::kalman::GainRestriction;
use crate::scalar::{Scalar, us_to_s};
use crate::sensors::{GpsFix, Imu, ImuSample, MagSample, checked_gps, checked_imu, checked_mag};
use crate::zero_option::ZeroOption;
use nalgebra::{SVector, UnitQuaternion, Vector3};

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    fn check_imu(&mut self, imu: &(impl ImuSample<T> + ?Sized)) -> Result<Imu<T>, Error> {
        let s = checked_imu(imu).inspect_err(|_| bump(&mut self.refusals.imu_non_finite))?;
        let c = &self.config.ekf;
        if s.gyro_rad_s.iter().any(|v| v.abs() > c.max_gyro_rad_s)
            || s.accel_m_s2.iter().any(|v| v.abs() > c.max_accel_m_s2)
        {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu",
                reason: "above the configured max_gyro_rad_s or max_accel_m_s2",
            });
        }
        let max_jump = self.config.max_time_jump_us;
        counted(
            self.imu_clock
                .check("imu", "imu.time", s.t_us, None, max_jump),
            &mut self.refusals.imu_ahead,
            &mut self.refusals.imu_time,
        )?;
        Ok(s)
    }
}

impl<T: Scalar, const HIST: usize> Navigator<T> for DelayCompensatedNav<T, HIST> {
    /// One IMU sample through the five steps of the module docs. Refused,
    /// state unchanged: non-finite, implausible, not later than the previous
    /// sample. A gap longer than the EKF's `max_imu_step_us` restarts the
    /// history and returns [`Error::StepTooLong`] after keeping the sample.
    #[inline(never)]
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let s = self.check_imu(imu)?;
        let dt_us = self.last_imu.map_or(0, |p| s.t_us.saturating_sub(p.t_us));
        let max_step = self.config.ekf.max_imu_step_us;
        let gap = dt_us > max_step;
        if gap {
            // The present's levels take the gap's growth until the horizon crosses it.
            self.imu_gap_end_us = s.t_us;
        }
        // A step the history's sample times cannot hold (8.1 s at 530
        // samples) restarts the history too (the EKF integrates it as usual).
        if gap || dt_us >= SampleTimes::<HIST>::MAX_STEP_US {
            bump(&mut self.refusals.imu_gap);
            self.last_reset = ZeroOption::Some(ResetRecord {
                t_us: Some(s.t_us),
                cause: ResetCause::ImuGap,
            });
            self.history.clear();
            self.times.clear();
            self.accel_whitening.reset();
            self.gyro_whitening.reset();
        }
        let accel = self.accel_whitening.filter(s.accel_m_s2);
        let gyro = self.gyro_whitening.filter(s.gyro_rad_s);
        let mut channels = SVector::<T, 6>::zeros();
        channels.fixed_rows_mut::<3>(0).copy_from(&accel);
        channels.fixed_rows_mut::<3>(3).copy_from(&gyro);
        // Finite and bounded by the checks above: the history cannot refuse it.
        let _ = self.history.push(channels);
        if self.times.push(s.t_us) {
            // A ninth long step within the span: the oldest times forgotten.
            bump(&mut self.refusals.imu_gap);
        }
        self.imu_samples = self.imu_samples.saturating_add(1);

        if self.forward.is_started() {
            if gap {
                let carried_s = us_to_s::<T>(dt_us).min(T::lit(GAP_MOTION_MAX_S));
                self.forward
                    .hold(s.t_us, carried_s, &s.gyro_rad_s, &s.accel_m_s2);
            } else {
                let g = self.config.ekf.gravity_m_s2;
                self.forward.step(s.t_us, &s.gyro_rad_s, &s.accel_m_s2, g);
            }
        }
        self.last_imu = Some(s);

        let stepped = self
            .horizon_target(s.t_us, dt_us)
            .is_some_and(|t_h| self.step_horizon(s.t_us, t_h, false));
        let mut busy = stepped;
        if stepped {
            self.horizon_moved();
            self.correct_present();
        } else if self.fuse_due_mags() {
            busy = true;
            self.correct_present();
        }

        if self.forward.is_started() {
            let (x, _) = self.forward.state();
            let rot = rotation_matrix(&quaternion_of(x));
            let bias = x.fixed_rows::<3>(ACCEL_BIAS).into_owned();
            let gravity = Vector3::new(T::zero(), T::zero(), self.config.ekf.gravity_m_s2);
            self.present_accel = rot * (s.accel_m_s2 - bias) + gravity;
            if self.is_estimating() {
                let a_fwd = rot * (accel - bias) + gravity;
                if self.delay_loop.push_imu(s.t_us, a_fwd).is_err() {
                    bump(&mut self.refusals.delay_loop_refused);
                }
            }
        }
        if let Some((_, _, waited)) = &mut self.pending_delay_fix {
            *waited = waited.saturating_add(1);
            if !busy || *waited >= DELAY_UPDATE_MAX_WAIT {
                self.update_delay();
            }
        }
        if gap {
            return Err(Error::StepTooLong {
                dt_us,
                max_us: max_step,
            });
        }
        Ok(())
    }

    /// Fuses the fix at the horizon at once; its velocity goes to the delay
    /// loop at a later IMU sample (module docs). Refused, state unchanged: invalid values,
    /// a velocity beyond the loop's plausible range, time not increasing.
    #[inline(never)]
    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let fix = checked_gps(gps).inspect_err(|e| {
            bump(&mut self.refusals.gps_invalid);
            if let Error::NonFinite { field } | Error::OutOfRange { field, .. } = e
                && field.ends_with("accuracy")
            {
                bump(&mut self.refusals.gps_accuracy);
            }
        })?;
        if fix
            .velocity_ned_m_s
            .iter()
            .any(|v| v.abs() > T::lit(MAX_INPUT_MAGNITUDE))
        {
            bump(&mut self.refusals.gps_invalid);
            return Err(Error::OutOfRange {
                field: "gps.velocity",
                reason: "beyond the plausible range",
            });
        }
        let geodetic = check_position_kind(self.geodetic_fixes.get(), &fix.position)
            .inspect_err(|_| bump(&mut self.refusals.gps_mixed_frames))?;
        let newest_imu = self.imu_clock.last();
        let max_jump = self.config.max_time_jump_us;
        let mut clock = self.gps_clock;
        counted(
            clock.check(
                "gps",
                "gps.time",
                fix.t_us,
                newest_imu.or(Some(fix.t_us)),
                max_jump,
            ),
            &mut self.refusals.gps_ahead,
            &mut self.refusals.gps_time,
        )?;
        self.advance_horizon_to_fix(fix.t_us);
        if !self.ekf.is_initialized() && self.mag_clock.last().is_some() && !self.mag_at_horizon {
            // Alignment waits for what it sets: the heading needs a
            // magnetometer sample at the horizon, one delay after it arrived.
            self.gps_clock = clock;
            return Ok(GpsOutcome::Waiting);
        }
        let resets_before = self.ekf.last_gps_reset();
        let innovations = self.delay_loop.config().innovation_window_s > T::zero();
        let prior = if innovations {
            self.horizon_prior()
        } else {
            None
        };
        let (timing_variance_s2, accel) = self.gps_timing_noise();
        // Through an unknown heading, or at an unknown time, a fix would set
        // the tilt and the biases to whatever turns the IMU's accelerations
        // into the GPS velocity's: it corrects the position and the velocity
        // alone (`alignment.rs`).
        let restriction = self
            .attitude_from_gps_withheld()
            .then_some(GainRestriction::KeepRows(POSITION_VELOCITY_ROWS));
        let outcome =
            self.ekf
                .push_gps_with_timing_noise(&fix, timing_variance_s2, &accel, restriction)?;
        if restriction.is_some() && matches!(outcome, GpsOutcome::Fused { .. }) {
            self.fixes_position_velocity_only = self.fixes_position_velocity_only.saturating_add(1);
        }
        if let (Some(t_us), Some(x)) = (self.ekf.time_us(), self.ekf.nav_state()) {
            self.last_fix_velocity = Some((t_us, x.velocity_ned_m_s));
        }
        let reset = self.ekf.last_gps_reset() != resets_before;
        if self.is_estimating()
            && let (Some(prior), GpsOutcome::Fused { position, velocity }) = (prior, outcome)
        {
            self.push_horizon_fix(&fix, &prior, &position, &velocity, reset);
        }
        if let Some(reset) = self.ekf.last_gps_reset()
            && resets_before != Some(reset)
        {
            self.last_reset = ZeroOption::Some(ResetRecord {
                t_us: self.imu_clock.last(),
                cause: ResetCause::Gps(reset),
            });
        }
        self.gps_clock = clock;
        self.geodetic_fixes = ZeroOption::Some(geodetic);
        if self.is_estimating() {
            // The loop's update waits for a lighter IMU sample (bounded
            // work per call); a fix still waiting goes first.
            self.update_delay();
            self.pending_delay_fix = Some((fix.t_us, fix.velocity_ned_m_s, 0));
        }
        if outcome == GpsOutcome::Initialized {
            self.refine_alignment(fix.velocity_ned_m_s.norm());
        }
        if matches!(outcome, GpsOutcome::Initialized | GpsOutcome::Fused { .. }) {
            self.fuse_yaw_gsf(&fix.velocity_ned_m_s, fix.speed_accuracy_m_s);
        }
        if matches!(outcome, GpsOutcome::Initialized | GpsOutcome::Fused { .. }) {
            self.correct_present();
        }
        Ok(outcome)
    }

    /// Queues the sample until the horizon reaches its time (module docs).
    /// Refused, state unchanged: non-finite or zero field, time not increasing.
    #[inline(never)]
    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let m = checked_mag(mag).inspect_err(|_| bump(&mut self.refusals.mag_invalid))?;
        let newest_imu = self.imu_clock.last().or(Some(m.t_us));
        let max_jump = self.config.max_time_jump_us;
        counted(
            self.mag_clock
                .check("mag", "mag.time", m.t_us, newest_imu, max_jump),
            &mut self.refusals.mag_ahead,
            &mut self.refusals.mag_time,
        )?;
        Ok(self.enqueue_mag(m))
    }

    /// The [`Health`](super::Health) as the trait reports it.
    fn integrity(&self) -> crate::integrity::Integrity<T> {
        self.health().integrity()
    }

    /// The present solution: attitude, position and velocity at the newest
    /// IMU sample; biases and covariance are the horizon EKF's. `None` until
    /// the first correction has reached the present (module docs).
    fn estimate(&self) -> Option<Estimate<T>> {
        if !(self.configured && self.forward.is_ready()) {
            return None;
        }
        let horizon = self.ekf.estimate()?;
        let (x, t_us) = self.forward.state();
        Some(self.with_delay(Estimate {
            t_us,
            attitude: UnitQuaternion::new_normalize(quaternion_of(x)),
            position_ned_m: x.fixed_rows::<3>(POS).into_owned(),
            velocity_ned_m_s: x.fixed_rows::<3>(VEL).into_owned(),
            accel_bias_m_s2: x.fixed_rows::<3>(ACCEL_BIAS).into_owned(),
            gyro_bias_rad_s: x.fixed_rows::<3>(GYRO_BIAS).into_owned(),
            ..horizon
        }))
    }
}

/// The rows of the gain kept when a fusion may move the position and the
/// velocity alone (bit `i` for state `i`).
const POSITION_VELOCITY_ROWS: u32 = (0b111 << POS) | (0b111 << VEL);

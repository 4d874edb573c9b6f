//! Prediction: IMU samples (or accumulated deltas) checked, the state
//! propagated, the covariance predicted with its noise; gaps widened.

use super::*;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Pads a Jacobian over the 16 navigation states with zero columns for the extra states.
    pub(crate) fn widen<const M: usize>(h: &SMatrix<T, M, NAV_STATES>) -> SMatrix<T, M, N> {
        let mut out = SMatrix::<T, M, N>::zeros();
        out.fixed_view_mut::<M, NAV_STATES>(0, 0).copy_from(h);
        out
    }

    /// Adds a sample `dt_us` after the previous one (0 for the first) to the
    /// alignment's accelerometer mean.
    pub(super) fn accumulate_accel(&mut self, accel: &Vector3<T>, dt_us: u64) {
        self.accel_mean.push(accel, self.config.align_window);
        let dt_us = u32::try_from(dt_us).unwrap_or(u32::MAX);
        self.accel_mean_span_us = self.accel_mean_span_us.saturating_add(dt_us);
    }

    /// Feeds one IMU sample (see the module docs).
    ///
    /// The rate and specific force held over the step `[t_prev, t]` are the
    /// mean of the samples at both ends (trapezoidal; equal to a zero-order
    /// hold when the inputs are constant).
    pub(crate) fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let s = checked_imu(imu).inspect_err(|_| bump(&mut self.refusals.imu_non_finite))?;
        let max_w = self.config.max_gyro_rad_s;
        let max_f = self.config.max_accel_m_s2;
        if s.gyro_rad_s.iter().any(|v| v.abs() > max_w) {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu.gyro",
                reason: "above the configured max_gyro_rad_s",
            });
        }
        if s.accel_m_s2.iter().any(|v| v.abs() > max_f) {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu.accel",
                reason: "above the configured max_accel_m_s2",
            });
        }
        check_time("imu", self.imu_clock_us, s.t_us)
            .inspect_err(|_| bump(&mut self.refusals.imu_time))?;
        let Some(clock) = self.imu_clock_us else {
            self.imu_clock_us = Some(s.t_us);
            self.last_imu = Some(s);
            self.accumulate_accel(&s.accel_m_s2, 0);
            return Ok(());
        };
        if s.t_us > clock.saturating_add(MAX_TIME_JUMP_US) {
            let confirmed = self
                .imu_candidate_us
                .is_some_and(|c| s.t_us > c && s.t_us - c <= MAX_TIME_JUMP_US);
            if !confirmed {
                self.imu_candidate_us = Some(s.t_us);
                bump(&mut self.refusals.imu_ahead);
                return Err(Error::OutOfRange {
                    field: "imu.time",
                    reason: "too far ahead of the previous sample (MAX_TIME_JUMP_US); \
                             accepted when the next sample confirms it",
                });
            }
        }
        self.imu_candidate_us = None;
        let dt_us = s.t_us - clock;
        let (gyro, accel) = match self.last_imu {
            Some(prev) => (
                (prev.gyro_rad_s + s.gyro_rad_s) * T::lit(0.5),
                (prev.accel_m_s2 + s.accel_m_s2) * T::lit(0.5),
            ),
            None => (s.gyro_rad_s, s.accel_m_s2),
        };
        self.step(s, dt_us, &gyro, &accel)
    }

    /// Feeds the delta angle and delta velocity of a filter step
    /// ([`ImuDeltas`], accumulated from IMU samples with coning and
    /// sculling corrections): one prediction over the whole step, as
    /// [`push_imu`](Self::push_imu) does over one sample step, with the
    /// same checks on the step's last sample and on the step's start (it
    /// must be the state's time). Before initialization only the last
    /// sample counts (clock, accelerometer mean).
    ///
    /// [`process::propagate`] holds the rate `w` and the specific force `f`
    /// over the step and rotates `f` at mid-step; it is given
    /// `w = Δθ / T` and `f = exp(-Δθ / 2) Δv / T` (`T` the step, s), so
    /// that it adds exactly `R(q) Δv` to the velocity and turns the
    /// attitude by `Δθ` (bias-corrected). The covariance is predicted with
    /// the mean rate and specific force over the step, `Δθ / T`, `Δv / T`.
    pub(crate) fn push_deltas(&mut self, d: &ImuDeltas<T>) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let s = d.last;
        if !(all_finite_fixed(&d.delta_angle_rad) && all_finite_fixed(&d.delta_velocity_m_s)) {
            bump(&mut self.refusals.imu_non_finite);
            return Err(Error::NonFinite {
                field: "imu deltas",
            });
        }
        if self.imu_clock_us != Some(d.t_start_us) {
            return self.push_imu(&s);
        }
        let dt_us = d.dt_us();
        if dt_us == 0 || !self.initialized {
            return self.push_imu(&s);
        }
        checked_imu(&s).inspect_err(|_| bump(&mut self.refusals.imu_non_finite))?;
        let max_w = self.config.max_gyro_rad_s;
        let max_f = self.config.max_accel_m_s2;
        if s.gyro_rad_s.iter().any(|v| v.abs() > max_w)
            || s.accel_m_s2.iter().any(|v| v.abs() > max_f)
        {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu",
                reason: "above the configured max_gyro_rad_s or max_accel_m_s2",
            });
        }
        let step_s: T = us_to_s(dt_us);
        let gyro = d.delta_angle_rad / step_s;
        let half_turn =
            crate::geo::quaternion_from_rotation_vector(&(d.delta_angle_rad * T::lit(-0.5)));
        let accel = (half_turn * d.delta_velocity_m_s) / step_s;
        let mean_accel = d.delta_velocity_m_s / step_s;
        if dt_us > self.config.max_imu_step_us {
            return self.step(s, dt_us, &gyro, &mean_accel);
        }
        self.predict(s, dt_us, &gyro, &accel, &mean_accel)
    }

    /// One step of `dt_us` ending at sample `s` with the rate and specific
    /// force held over it: a gap (`StepTooLong`), the clock alone before
    /// initialization, or a prediction.
    pub(super) fn step(
        &mut self,
        s: Imu<T>,
        dt_us: u64,
        gyro: &Vector3<T>,
        accel: &Vector3<T>,
    ) -> Result<(), Error> {
        if dt_us > self.config.max_imu_step_us {
            return self.gap(s, dt_us, gyro, accel);
        }
        if !self.initialized {
            self.imu_clock_us = Some(s.t_us);
            self.last_imu = Some(s);
            self.accumulate_accel(&s.accel_m_s2, dt_us);
            return Ok(());
        }
        self.predict(s, dt_us, gyro, accel, accel)
    }

    /// A step longer than `max_imu_step_us` ([`step`](Self::step)): the
    /// noise of the gap added (at most `MAX_GAP_NOISE_US` of it) when
    /// initialized, the clock moved, counted, `StepTooLong`. Rare, and out
    /// of line so that its copy of `P` is not in the frame of every step.
    #[cold]
    #[inline(never)]
    fn gap(
        &mut self,
        s: Imu<T>,
        dt_us: u64,
        gyro: &Vector3<T>,
        accel: &Vector3<T>,
    ) -> Result<(), Error> {
        if self.initialized {
            // A gap adds the noise of at most `MAX_GAP_NOISE_US`: beyond
            // it the state is unknown anyway, and larger variances leave
            // the range a later update can handle in floating point.
            let mut p = self.p;
            let dt = us_to_s(dt_us.min(MAX_GAP_NOISE_US));
            process::add_process_noise(
                &mut p,
                &self.nav_state(),
                gyro,
                accel,
                dt,
                &self.config,
                &self.extra_intensity(),
            );
            let mut x = self.x;
            self.carry_over_gap(&mut x, &mut p, dt);
            if cap_quaternion_variance(&mut p) {
                bump(&mut self.refusals.imu_out_of_range);
            }
            if all_finite_fixed(&p) && all_finite_fixed(&x) && variances_not_negative(&p) {
                self.p = p;
                self.x = x;
            }
        } else {
            self.accumulate_accel(&s.accel_m_s2, dt_us);
        }
        self.imu_clock_us = Some(s.t_us);
        self.last_imu = Some(s);
        bump(&mut self.refusals.imu_step_too_long);
        Err(Error::StepTooLong {
            dt_us,
            max_us: self.config.max_imu_step_us,
        })
    }

    /// The prediction of [`step`](Self::step): the state with `accel`
    /// rotated at mid-step ([`process::propagate`]), the covariance with
    /// `jacobian_accel` (the mean specific force in the body frame at the
    /// step's start).
    pub(super) fn predict(
        &mut self,
        s: Imu<T>,
        dt_us: u64,
        gyro: &Vector3<T>,
        accel: &Vector3<T>,
        jacobian_accel: &Vector3<T>,
    ) -> Result<(), Error> {
        let dt: T = us_to_s(dt_us);
        let x16 = process::propagate(&self.nav_state(), gyro, accel, dt, self.config.gravity_m_s2);
        let mut p = self.p;
        process::predict_covariance_in_place(
            &mut p,
            &self.nav_state(),
            gyro,
            jacobian_accel,
            dt,
            &self.config,
            &self.extra_intensity(),
            self.imu_noise_scale,
        );
        let mut x = self.x;
        x.fixed_rows_mut::<NAV_STATES>(0).copy_from(&x16);
        let repaired = project_quaternion_covariance(&mut p, &x);
        if !(all_finite_fixed(&x) && all_finite_fixed(&p) && variances_not_negative(&p)) {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu",
                reason: "the step would make the state non-finite or a variance negative",
            });
        }
        // Integrated, with the quaternion's variances capped and counted.
        if cap_quaternion_variance(&mut p) {
            bump(&mut self.refusals.imu_out_of_range);
        }
        if repaired {
            bump(&mut self.refusals.covariance_repairs);
        }
        self.x = x;
        self.p = p;
        self.imu_clock_us = Some(s.t_us);
        self.last_imu = Some(s);
        Ok(())
    }
}

//! Magnetometer fusion: the field checked against the learned one (norm,
//! inclination), the heading (or the whole field before the tilt is known)
//! fused and gated, the field learned from fused samples.

use super::*;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Feeds one magnetometer sample: kept for the initial heading before
    /// initialization, fused as the heading-only pseudo-measurement after.
    pub(crate) fn push_mag<M: MagSample<T> + ?Sized>(
        &mut self,
        mag: &M,
    ) -> Result<MagOutcome<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let m = checked_mag(mag).inspect_err(|_| bump(&mut self.refusals.mag_invalid))?;
        check_time("mag", self.mag_clock_us, m.t_us)
            .inspect_err(|_| bump(&mut self.refusals.mag_time))?;
        if !self.initialized {
            self.mag_clock_us = Some(m.t_us);
            self.mag_mean
                .push(&m.field_body.normalize(), self.config.align_window);
            self.mag_norm_mean.push(
                &SVector::<T, 1>::new(m.field_body.norm()),
                self.config.align_window,
            );
            return Ok(MagOutcome::Stored);
        }
        let field = self.check_mag_field(&m.field_body);
        let c = &self.config;
        let x16 = self.nav_state();
        let euler = euler_from_quaternion(&quaternion_of(&x16));
        let (roll, pitch) = (euler.x, euler.y);
        let field_ned = self.field_ned;
        // Roll's and pitch's sines and cosines once for the three uses.
        let tilt = measurement::Tilt::new(roll, pitch);
        let heading_mag = tilt_compensated_heading_sc(
            &m.field_body,
            tilt.roll,
            tilt.pitch,
            c.mag_declination_rad,
        );
        let z = measurement::pseudo_measurement(&tilt, heading_mag, &field_ned);
        let (hx, h16) = measurement::model_tilt_coupled(&x16, &tilt, &field_ned);
        let r = Matrix3::identity() * c.mag_noise_variance;
        // A disturbed sample goes through the gate of 0: rejected, with its record.
        let gate = if field.is_some() {
            c.mag_gate
        } else {
            T::zero()
        };
        let q = quaternion_of(&x16);
        let aligning = self.tilt_std() > c.mag_tilt_alignment_std_rad;
        let restriction =
            (!(c.mag_corrects_tilt || aligning)).then(|| measurement::heading_only_restriction(&q));
        let record = self.fuse_restricted(
            m.t_us,
            &(z - hx),
            &Self::widen(&h16),
            &r,
            gate,
            "mag",
            restriction.as_ref(),
        )?;
        let mut record = record;
        self.mag_clock_us = Some(m.t_us);
        match field {
            Some(sample) if record.fused => self.learn_mag_field(sample),
            Some(_) => bump(&mut self.refusals.mag_rejected),
            None => {
                record.test_ratio = T::lit(f64::INFINITY);
                bump(&mut self.refusals.mag_disturbed);
            }
        }
        if record.fused {
            self.mag_fused_us = Some(record.t_us);
        }
        self.last_mag = record;
        self.mag_recorded = true;
        Ok(MagOutcome::Fused(record))
    }

    /// The field norm and inclination of a magnetometer sample (the
    /// inclination seen with the estimated attitude); `None` when either is
    /// too far from the learned field: a disturbance. The first sample of a
    /// filter that learned no field passes as it is.
    pub(super) fn check_mag_field(&self, field_body: &Vector3<T>) -> Option<(T, T)> {
        let rot = rotation_matrix(&quaternion_of(&self.x));
        let sample = (field_body.norm(), field_inclination(&rot, field_body));
        let Some((norm, inclination)) = self.mag_field else {
            return Some(sample);
        };
        let c = &self.config;
        // `!(a <= b)` also refuses NaN.
        let norm_ok = (sample.0 / norm - T::one()).abs() <= c.mag_norm_tolerance;
        let inclination_ok = (sample.1 - inclination).abs() <= c.mag_inclination_tolerance_rad;
        (norm_ok && inclination_ok).then_some(sample)
    }

    /// The larger of the north and east standard deviations (rad) of the
    /// attitude error `dtheta = 2 vec(dq ⊗ q*)` (NED), from `P`:
    /// `dtheta = G dq`, `G = 2 [-v | w I + [v×]]` for `q = (w, v)`.
    pub(crate) fn tilt_std(&self) -> T {
        let cov = crate::integrity::attitude_error_covariance(
            &quaternion_of(&self.x),
            &self.p.fixed_view::<4, 4>(QUAT, QUAT).into_owned(),
        );
        cov[(0, 0)].max(cov[(1, 1)]).max(T::zero()).sqrt()
    }

    /// Moves the learned field toward an accepted sample's norm and
    /// inclination by `mag_field_learning_rate` (an exponential mean).
    pub(super) fn learn_mag_field(&mut self, sample: (T, T)) {
        let w = self.config.mag_field_learning_rate;
        self.mag_field = Some(match self.mag_field {
            None => sample,
            Some((n, i)) => (n + (sample.0 - n) * w, i + (sample.1 - i) * w),
        });
    }
}

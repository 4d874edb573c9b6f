//! Magnetometer fusion: the field checked against the learned one (norm,
//! inclination), then, by the mode of the sample ([`MagMode`]), the 3-axis
//! field direction or the heading (the whole field's heading before the tilt
//! is known) fused and gated, the field learned from fused samples.
//!
//! # Mode switching (units: µs, rad; see `docs/math.md`)
//! - **no fusion**: the sample's norm or inclination is off the learned
//!   field (`mag_norm_tolerance`, `mag_inclination_tolerance_rad`): refused
//!   as disturbed; or the field offset the monitor holds (`mag_monitor.rs`)
//!   can turn the heading beyond its alert limit: refused (counted as
//!   `mag_rejected`).
//! - **3-axis** (`mag_three_axis`): the field has been clean for
//!   [`MAG_THREE_AXIS_HOLD_US`] (never two samples in a row disturbed or
//!   gated out) and the learned inclination is within
//!   [`MAG_THREE_AXIS_INCLINATION_TOLERANCE_RAD`] of the configured one;
//!   or, whatever the hold and the inclination, while the filter is
//!   aligning in motion (its tilt standard deviation above
//!   [`MAG_INFLIGHT_TILT_STD_RAD`]): the configured field is then a second
//!   reference direction beside gravity, which levels a filter started in
//!   flight within seconds (the inclination learned at such a start was
//!   seen through the unlevelled attitude and says nothing yet).
//! - **heading only** otherwise.
//!
//! A second sample in a row disturbed or gated out restarts the clean time:
//! the filter falls back to heading-only at once and returns to 3-axis only
//! after a clean [`MAG_THREE_AXIS_HOLD_US`] (hysteresis). A single one (noise:
//! 0.27 % of clean samples at the 3-sigma gate, and about 0.1 % of the Table 3
//! magnetometer's samples are off the norm or inclination tolerance) is not
//! fused but does not change the mode.

use super::super::MagMode;
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
        let mut m = checked_mag(mag).inspect_err(|_| bump(&mut self.refusals.mag_invalid))?;
        check_time("mag", self.mag_clock_us, m.t_us)
            .inspect_err(|_| bump(&mut self.refusals.mag_time))?;
        m.field_body -= self.config.mag_hard_iron;
        if m.field_body.norm() <= T::zero() {
            // The calibration removed the whole field: nothing to fuse.
            bump(&mut self.refusals.mag_invalid);
            return Err(Error::OutOfRange {
                field: "mag.field_body",
                reason: "zero once the hard-iron offset is removed",
            });
        }
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
        let trusted = field.is_some() && !self.mag_offset_beyond_alert();
        let mode = self.mag_mode(trusted);
        let (heading_before, share) = self.heading_std_and_tilt_share();
        let record = if mode == MagMode::ThreeAxis {
            self.fuse_mag_field(m.t_us, &m.field_body)?
        } else {
            self.fuse_mag_heading(m.t_us, &m.field_body, trusted)?
        };
        if record.fused {
            let kept = self.heading_variance_kept(heading_before);
            self.remember_heading_tilt_coupling(mode, kept, share);
        }
        let dt_us = self.mag_clock_us.map_or(0, |t| m.t_us.saturating_sub(t));
        self.finish_mag(m.t_us, mode, field, record);
        self.monitor_mag(&m.field_body, mode, dt_us);
        Ok(MagOutcome::Fused(self.last_mag))
    }

    /// The magnetometer's integrity monitor with the sample just fused (or not) in `mode`,
    /// `dt_us` after the previous one (`mag_monitor.rs`): a norm beyond its tolerance is
    /// counted in `FilterRefusals::mag_field_offset`, a held offset refuted in
    /// `FilterRefusals::mag_field_offset_cleared`.
    fn monitor_mag(&mut self, field_body: &Vector3<T>, mode: MagMode, dt_us: u64) {
        let c = &self.config;
        let (gate, dof) = if mode == MagMode::ThreeAxis {
            (c.mag_three_axis_gate, T::lit(2.0))
        } else {
            (c.mag_gate, T::one())
        };
        let record = &self.last_mag;
        // test_ratio = NIS / gate (infinite for a disturbed sample): capped at the gate.
        let nis_per_dof = record.test_ratio.min(T::one()) * gate / dof;
        let reading = mag_monitor::MagReading {
            field_body: *field_body,
            fused: record.fused,
            nis_per_dof,
            dt_s: us_to_s(dt_us),
        };
        let (k1, _, _) = crate::integrity::protection_factors(c.integrity.risk);
        let (w, r) = (c.mag_field_learning_rate, c.mag_noise_variance);
        let update = self.mag_monitor.update(&reading, w, r, k1);
        if update.beyond {
            bump(&mut self.refusals.mag_field_offset);
        }
        if update.cleared {
            bump(&mut self.refusals.mag_field_offset_cleared);
        }
    }

    /// Whether the field offset seen by the monitor can turn the heading by more than its alert
    /// limit: `beta > sin(AL) cos I` (`beta` the held relative offset, `I` the configured
    /// inclination; the heading of the horizontal field, `|m| cos I` long, turns by up to
    /// `asin(beta / cos I)`). Such a field is not fused: the heading coasts on the gyro, and
    /// the navigator's yaw estimator takes over once the magnetometer is stale.
    /// (`sin(AL_h) cos I` is computed when the filter is configured.)
    fn mag_offset_beyond_alert(&self) -> bool {
        self.mag_monitor.offset() > self.mag_offset_refusal
    }

    /// The mode of a sample whose field is `consistent` (or not).
    fn mag_mode(&self, consistent: bool) -> MagMode {
        let c = &self.config;
        let inclination_agrees = self.mag_field.is_some_and(|(_, i)| {
            (i - c.mag_inclination_rad).abs() <= T::lit(MAG_THREE_AXIS_INCLINATION_TOLERANCE_RAD)
        });
        if !consistent {
            MagMode::NoFusion
        } else if c.mag_three_axis
            && self.mag_monitor.offset() <= T::zero()
            && ((inclination_agrees && self.mag_clean_us >= MAG_THREE_AXIS_HOLD_US)
                || self.aligning_in_motion())
        {
            MagMode::ThreeAxis
        } else {
            MagMode::HeadingOnly
        }
    }

    /// Whether the filter is aligning in motion, so that a consistent
    /// sample is fused 3-axis at once: the tilt less certain than
    /// [`MAG_INFLIGHT_TILT_STD_RAD`] and than `mag_tilt_alignment_std_rad`
    /// (+inf there keeps the magnetometer from correcting the tilt of an
    /// aligning filter, as its documentation says).
    fn aligning_in_motion(&self) -> bool {
        let tilt_std = self.tilt_std();
        tilt_std > T::lit(MAG_INFLIGHT_TILT_STD_RAD)
            && tilt_std > self.config.mag_tilt_alignment_std_rad
    }

    /// The 3-axis update: the measured direction `m_b / |m_b|` against
    /// `R(q)ᵀ m_n` ([`measurement::mag_field_model`]), the plain gain, the
    /// 2-DOF gate `mag_three_axis_gate` (a disturbed sample is never 3-axis).
    fn fuse_mag_field(
        &mut self,
        t_us: u64,
        field_body: &Vector3<T>,
    ) -> Result<FusionRecord<T, 3>, Error> {
        let c = &self.config;
        let x16 = self.nav_state();
        let (hx, h16) = measurement::mag_field_model(&x16, &self.field_ned);
        let r = Matrix3::identity() * c.mag_noise_variance;
        let gate = c.mag_three_axis_gate;
        self.fuse_restricted(
            t_us,
            &(field_body.normalize() - hx),
            &Self::widen(&h16),
            &r,
            gate,
            "mag",
            None,
        )
    }

    /// The heading-only update (the plain one while aligning or with
    /// `mag_corrects_tilt`), gate `mag_gate` (0 for a disturbed sample).
    fn fuse_mag_heading(
        &mut self,
        t_us: u64,
        field_body: &Vector3<T>,
        consistent: bool,
    ) -> Result<FusionRecord<T, 3>, Error> {
        let c = &self.config;
        let x16 = self.nav_state();
        let euler = euler_from_quaternion(&quaternion_of(&x16));
        let (roll, pitch) = (euler.x, euler.y);
        let field_ned = self.field_ned;
        // Roll's and pitch's sines and cosines once for the three uses.
        let tilt = measurement::Tilt::new(roll, pitch);
        let heading_mag =
            tilt_compensated_heading_sc(field_body, tilt.roll, tilt.pitch, c.mag_declination_rad);
        let z = measurement::pseudo_measurement(&tilt, heading_mag, &field_ned);
        let (hx, h16) = measurement::model_tilt_coupled(&x16, &tilt, &field_ned);
        let r = Matrix3::identity() * c.mag_noise_variance;
        // A disturbed sample goes through the gate of 0: rejected, with its record.
        let gate = if consistent { c.mag_gate } else { T::zero() };
        let q = quaternion_of(&x16);
        let aligning = self.tilt_std() > c.mag_tilt_alignment_std_rad;
        let restriction =
            (!(c.mag_corrects_tilt || aligning)).then(|| measurement::heading_only_restriction(&q));
        self.fuse_restricted(
            t_us,
            &(z - hx),
            &Self::widen(&h16),
            &r,
            gate,
            "mag",
            restriction.as_ref().map(GainRestriction::Matrix),
        )
    }

    /// After a sample's update: its counters, the learned field, the
    /// hysteresis (clean time, gated-out run), the mode and time per mode.
    fn finish_mag(
        &mut self,
        t_us: u64,
        mode: MagMode,
        field: Option<(T, T)>,
        mut record: FusionRecord<T, 3>,
    ) {
        let dt = self.mag_clock_us.map_or(0, |t| t_us.saturating_sub(t));
        self.mag_clock_us = Some(t_us);
        match field {
            Some(sample) if record.fused => {
                self.learn_mag_field(sample);
                self.mag_rejected_run = 0;
                let dt = u32::try_from(dt).unwrap_or(u32::MAX);
                self.mag_clean_us = self.mag_clean_us.saturating_add(dt);
            }
            Some(_) => bump(&mut self.refusals.mag_rejected),
            None => {
                record.test_ratio = T::lit(f64::INFINITY);
                bump(&mut self.refusals.mag_disturbed);
            }
        }
        if !record.fused {
            // One outlier is noise (the Table 3 magnetometer is 3.5 sigma
            // off the tolerances every ~1,000 samples); two in a row are not.
            self.mag_rejected_run = self.mag_rejected_run.saturating_add(1);
            if self.mag_rejected_run >= 2 {
                self.mag_clean_us = 0;
            }
        }
        if record.fused {
            self.mag_fused_us = Some(record.t_us);
        }
        let modes = &mut self.mag_modes;
        let counted = if dt > MAG_GAP_US {
            MagMode::NoFusion
        } else {
            mode
        };
        let slot = &mut modes.time_us[counted.index()];
        *slot = slot.saturating_add(dt);
        if modes.mode != mode && self.mag_recorded {
            modes.switches = modes.switches.saturating_add(1);
        }
        modes.mode = mode;
        self.last_mag = record;
        self.mag_recorded = true;
    }

    /// The field norm and inclination of a magnetometer sample (the
    /// inclination seen with the estimated attitude); `None` when either is
    /// too far from the learned field: a disturbance. While the learned field
    /// is the mean of fewer than [`MAG_FIELD_MIN_SAMPLES`] samples (none at
    /// all when the filter was initialized without a magnetometer sample, or
    /// rebuilt in motion) every sample passes and teaches it: a field learned
    /// from one sample 3 sigma off its norm refused every later sample as
    /// disturbed, and so was never corrected.
    pub(super) fn check_mag_field(&self, field_body: &Vector3<T>) -> Option<(T, T)> {
        let rot = rotation_matrix(&quaternion_of(&self.x));
        let sample = (field_body.norm(), field_inclination(&rot, field_body));
        let learned = self
            .mag_field
            .filter(|_| self.mag_monitor.learned_count() >= MAG_FIELD_MIN_SAMPLES);
        let Some((norm, inclination)) = learned else {
            return Some(sample);
        };
        let c = &self.config;
        // `!(a <= b)` also refuses NaN.
        let norm_ok = (sample.0 / norm - T::one()).abs() <= c.mag_norm_tolerance;
        let inclination_ok = (sample.1 - inclination).abs() <= c.mag_inclination_tolerance_rad;
        (norm_ok && inclination_ok).then_some(sample)
    }

    /// The heading's standard deviation and the heading's share of the tilt's, rad: a
    /// magnetometer heading is turned only by the tilt about the horizontal field's direction
    /// (with the field `(H, 0, Z)` along `a` and a small attitude error `dtheta`, the field seen
    /// through the estimate has the east component `H dtheta_z - Z dtheta_a`: its heading is
    /// off by `dtheta_z - tan(I) dtheta_a`), so the share is `|tan I| sqrt(a^T C a)`, `C` the
    /// attitude error's covariance. With the unit field `f = (cos I cos D, cos I sin D, sin I)`
    /// (`field_ned`) it needs no trigonometry: `sqrt(f_z^2 (f_x^2 C_nn + 2 f_x f_y C_ne +
    /// f_y^2 C_ee)) / (f_x^2 + f_y^2)`.
    pub(super) fn heading_std_and_tilt_share(&self) -> (T, T) {
        let cov = crate::integrity::attitude_error_covariance(
            &quaternion_of(&self.x),
            &self.p.fixed_view::<4, 4>(QUAT, QUAT).into_owned(),
        );
        let f = &self.field_ned;
        let horizontal = f[0] * f[0] + f[1] * f[1];
        let along = f[0] * f[0] * cov[(0, 0)]
            + T::lit(2.0) * f[0] * f[1] * cov[(0, 1)]
            + f[1] * f[1] * cov[(1, 1)];
        let share = (f[2] * f[2] * along).max(T::zero()).sqrt() / horizontal;
        (cov[(2, 2)].max(T::zero()).sqrt(), share)
    }

    /// After a sample fused in `mode`: the share of tilt error the heading holds, given the
    /// share of the heading the update `kept` (`heading_variance_kept`) and the heading's
    /// share of the tilt (`heading_std_and_tilt_share`) before it. A heading-only sample is
    /// the field's heading seen through the estimated tilt, so a tilt error `e` about the
    /// field's direction turns it by `tan(I) e`, and the update, which treats that error as
    /// fresh noise in every sample, cannot know that successive samples share it. The update moves the heading a
    /// fraction `k = 1 - kept` of the way to the sample and the heading keeps the rest of what
    /// it had; as standard deviations added linearly (the samples share the error):
    /// `c <- kept c + k s_tilt`. A 3-axis sample models the field through the whole attitude
    /// (its tilt share is in `P`'s correlations): it adds nothing and replaces its fraction of
    /// the share. So a heading built while the tilt was 3 deg off stays covered after the tilt
    /// has converged, until later samples replace it.
    fn remember_heading_tilt_coupling(&mut self, mode: MagMode, kept: T, share: T) {
        let share = if mode == MagMode::ThreeAxis {
            T::zero()
        } else {
            share
        };
        self.heading_tilt_std = kept * self.heading_tilt_std + (T::one() - kept) * share;
    }

    /// `s_after^2 / s_before^2` of the heading across an update (`heading_before` the standard
    /// deviation before it), at most 1 (1 for a heading with no variance before): `1 - k`, `k`
    /// the update's heading gain. For a 3-axis update it is (on the simulator's runs) larger
    /// than `1 - g^T K H d` (the gain on a heading error alone, `d` a unit turn about down in
    /// the quaternion, `g` its heading row), so it replaces the remembered share more slowly;
    /// that faster form left `mi_reset_inflight` at 1.44 s (docs/integrity.md): the 3-axis
    /// samples after an in-flight start do not bring the heading back at that gain.
    fn heading_variance_kept(&self, heading_before: T) -> T {
        let (heading_after, _) = self.heading_std_and_tilt_share();
        if heading_before > T::zero() {
            let ratio = heading_after / heading_before;
            (ratio * ratio).min(T::one())
        } else {
            T::one()
        }
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

    /// Moves the learned field toward a fused sample's norm and inclination:
    /// a running mean from the alignment's samples on, until it is the mean
    /// of `1 / mag_field_learning_rate` samples, then an exponential mean of
    /// that weight (the magnetometer monitor's weights, `mag_monitor.rs`).
    /// The alignment may have seen a single sample, or none (a magnetometer
    /// heard late, a filter rebuilt in motion): a norm that stayed at it (the
    /// `high` scenario, seed 4: 15 % low) refused the samples on one side of
    /// it for tens of seconds and biased the monitor, and an inclination that
    /// stayed at it (one sample is 8 deg off with the Table 3 noise) kept
    /// the 3-axis update off for as long (`mag_late`, seed 3: 13 s). The
    /// running mean weighs the alignment's own samples, seen through the
    /// accelerometer's tilt, less than the exponential mean would: after `k`
    /// more samples they hold `n0 / (n0 + k)` of it against `(1 - w)^k`.
    /// While the tilt standard deviation is above [`MAG_INFLIGHT_TILT_STD_RAD`]
    /// (an alignment in motion), the inclination follows the samples with
    /// the weight [`MAG_ALIGNING_INCLINATION_RATE`] at least: each is seen
    /// through an attitude being levelled, and the one learned at the start
    /// (through the accelerometer's tilt) says nothing.
    pub(super) fn learn_mag_field(&mut self, sample: (T, T)) {
        let w = self.config.mag_field_learning_rate;
        let wn = self.mag_monitor.next_weight(w);
        let wi = if self.tilt_std() > T::lit(MAG_INFLIGHT_TILT_STD_RAD) {
            wn.max(T::lit(MAG_ALIGNING_INCLINATION_RATE))
        } else {
            wn
        };
        self.mag_field = Some(match self.mag_field {
            None => sample,
            Some((n, i)) => (n + (sample.0 - n) * wn, i + (sample.1 - i) * wi),
        });
    }
}

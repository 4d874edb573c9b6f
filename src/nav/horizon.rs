//! The delayed horizon: where it is, how it steps through the IMU history
//! (eq. 15's reads, the filter period, catching up after the delay
//! shrinks), and how its state reaches the present.
//!
//! # The white noise of the reads
//!
//! The horizon reads one sample of the history per step of the horizon, `h` s apart (the
//! newest sample's period: 1 ms at 1 kHz, 5 ms after a change to 200 Hz, even while the
//! reads still fall in the 1 kHz part of the history). The noise densities of the
//! configuration `d` (`ekf.gyro_noise_density`, `ekf.accel_noise_density`) are those of the
//! configured rate `f0` (`imu_rate_hz`): a per-sample variance `σ² = d² f0`. A stream read
//! every `h > 1 / f0` keeps that per-sample variance (a decimated stream, a dropped sample:
//! nothing averaged the samples left out), and the `σ² h²` each read adds to the integrated
//! rate or specific force is a density of `σ² h = d² f0 h`. Over a filter step of reads
//! `h_1..h_n` (`Δt = Σ h_i`) the horizon filter's white-noise intensities are multiplied by
//! `max(1, f0 Σ h_i² / Δt)` (`Σ h² / Δt`: the mean period, more when the steps are uneven).
//! Measured on the simulator, an IMU decimated from 1 kHz to 200 Hz with the filter told
//! the 1 kHz densities leaves the tilt level at 1.0-1.3 deg where a filter told the
//! 200 Hz densities has 1.5-2.1 deg, and the tilt and velocity errors above the levels
//! (`mi_imu_rate_change`, docs/integrity.md); the integration at 200 Hz itself (coning,
//! sculling, the history's interpolation) adds no error visible against the levels (the
//! same runs with a noise-free IMU: the largest error over level per second within 0.01 of
//! the 1 kHz run's). A sensor that filters its samples to the new rate (a lower density
//! than this assumes) gets levels up to `sqrt(f0 h)` wider than needed: honest, less tight.

use super::refusals::bump;
use super::{DelayCompensatedNav, HISTORY_ORDER};
use crate::ekf16::state::{POS, VEL};
use crate::estimate::Navigator;
use crate::scalar::{Scalar, us_to_s};
use crate::sensors::Imu;
use nalgebra::Vector3;

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// The horizon time for the present `t_us`, or `None` when the horizon
    /// does not move (or cannot be read yet).
    pub(super) fn horizon_target(&self, t_us: u64, dt_us: u64) -> Option<u64> {
        let target = t_us.checked_sub(self.delay_us())?;
        if self.history.len() <= HISTORY_ORDER {
            return None;
        }
        let oldest = self.times.oldest()?;
        let Some(horizon) = self.horizon_us() else {
            return Some(target);
        };
        if target <= horizon {
            return None;
        }
        let max_step = (self.config.max_horizon_step_ratio * T::lit(dt_us as f64))
            .as_f64()
            .max(1.0) as u64;
        let capped = target.min(horizon.saturating_add(max_step));
        // After a gap the history restarted: the capped horizon is no longer
        // readable, jump to the target (the EKF grows P over the gap).
        if capped < oldest {
            Some(target)
        } else {
            Some(capped)
        }
    }

    /// The horizon: the newest instant read from the history (the horizon
    /// EKF's time, or later by the samples accumulated for its next step).
    pub(super) fn horizon_us(&self) -> Option<u64> {
        self.deltas.end_us().max(self.ekf.time_us())
    }

    /// Moves the horizon to `t_h` with the history read at eq. (15)'s
    /// delays. The sample goes to the horizon EKF at once when it predicts
    /// at every sample (or is not initialized), else into the accumulated
    /// step, which the EKF predicts over when it spans the filter period
    /// (to half an IMU step) or when `force` asks for the EKF at `t_h` (a
    /// fix to fuse). True when the EKF's time moved.
    pub(super) fn step_horizon(&mut self, t_us: u64, t_h: u64, force: bool) -> bool {
        let (d_f, d_w) = self.group_delays_s();
        let us = |d: T| (d * T::lit(1e6)).round().as_f64().max(0.0) as u64;
        // The whitened streams at t_h + D (the raw sensors' t_h), by time.
        let (times, history, headers) = (&self.times, &self.history, &mut self.history_headers);
        let mut read = |at_us: u64| {
            let d = times.delay_samples::<T>(at_us.min(t_us))?;
            history.read::<HISTORY_ORDER>(d, headers).ok()
        };
        // Equal group delays (pass-through whitening): one read holds both.
        let a = read(t_h.saturating_add(us(d_f)));
        let (w, reads) = if d_w == d_f {
            (a, 1)
        } else {
            (read(t_h.saturating_add(us(d_w))), 2)
        };
        self.interpolation_taps = self
            .interpolation_taps
            .saturating_add(reads * (HISTORY_ORDER as u64 + 1));
        let (Some(a), Some(w)) = (a, w) else {
            return false;
        };
        let sample = Imu {
            t_us: t_h,
            gyro_rad_s: w.fixed_rows::<3>(3).into_owned(),
            accel_m_s2: a.fixed_rows::<3>(0).into_owned(),
        };
        let step_us = self
            .deltas
            .end_us()
            .map_or(0, |end| t_h.saturating_sub(end));
        let every_sample = self.filter_period_us == 0 || !self.ekf.is_initialized();
        if every_sample || step_us > self.config.ekf.max_imu_step_us {
            // A gap is one step of its own (the EKF grows P over it).
            let flushed = self.flush_deltas();
            self.fuse_due_mags();
            let before = self.horizon_heading();
            let period: T = us_to_s(step_us);
            self.ekf
                .set_imu_noise_scale(period * self.config.imu_rate_hz);
            match self.ekf.push_imu(&sample) {
                Ok(()) => self.horizon_steps = self.horizon_steps.saturating_add(1),
                Err(_) => bump(&mut self.refusals.horizon_refused),
            }
            self.predict_yaw_gsf(before);
            self.deltas.restart(&sample);
            return flushed || self.ekf.time_us() == Some(t_h);
        }
        self.deltas.push(&sample);
        let due = self.deltas.elapsed_us().saturating_add(step_us / 2) >= self.filter_period_us;
        (force || due) && self.flush_deltas()
    }

    /// Predicts the horizon EKF over the accumulated step; true when it
    /// moved the EKF's time.
    fn flush_deltas(&mut self) -> bool {
        let before = self.ekf.time_us();
        // The white noise of the reads over the step (module docs): `f0 Σ h² / Δt`.
        let elapsed: T = us_to_s(self.deltas.elapsed_us());
        let scale = self.deltas.spacing_sq_s2() * self.config.imu_rate_hz / elapsed;
        let Some(deltas) = self.deltas.take() else {
            return false;
        };
        self.ekf.set_imu_noise_scale(scale);
        // Samples due at the EKF's present time are fused before it moves.
        self.fuse_due_mags();
        let heading = self.horizon_heading();
        match self.ekf.push_imu_deltas(&deltas) {
            Ok(()) => self.horizon_steps = self.horizon_steps.saturating_add(1),
            Err(_) => bump(&mut self.refusals.horizon_refused),
        }
        self.predict_yaw_gsf(heading);
        self.ekf.time_us() != before
    }

    /// Steps the horizon to the instant a fix received at `t_fix` describes,
    /// `t_fix - tau`, when that lies between the horizon and the newest IMU
    /// sample's horizon target (a fix arriving between IMU samples), and
    /// brings the horizon EKF to the horizon: the fix is then fused at its
    /// own instant, not up to one IMU step early or one filter step late.
    pub(super) fn advance_horizon_to_fix(&mut self, t_fix_us: u64) {
        let (Some(last), Some(horizon)) = (self.last_imu, self.horizon_us()) else {
            return;
        };
        if let Some(target) = t_fix_us.checked_sub(self.delay_us())
            && target > horizon
            && target <= last.t_us
        {
            self.step_horizon(last.t_us, target, true);
        }
        if self.flush_deltas() || self.ekf.time_us() != Some(horizon) {
            self.horizon_moved();
        }
    }

    /// Brings the horizon state to the present (starts the output state on
    /// the first call after the EKF initialized).
    pub(super) fn correct_present(&mut self) {
        let (Some(t_h), Some(last)) = (self.ekf.time_us(), self.last_imu) else {
            return;
        };
        if !self.ekf.is_initialized() {
            return;
        }
        let x_h = *self.ekf.state_vector();
        if !self.forward.is_started() {
            self.forward
                .start(&x_h, last.t_us, &last.gyro_rad_s, &last.accel_m_s2);
        }
        self.forward.correct(t_h, &x_h);
    }

    /// The horizon EKF's time, velocity and covariance before a fusion.
    pub(super) fn horizon_prior(&self) -> Option<HorizonPrior<T>> {
        if !self.ekf.is_initialized() {
            return None;
        }
        let x = self.ekf.state_vector();
        let p = self.ekf.covariance();
        Some(HorizonPrior {
            t_us: self.ekf.time_us()?,
            velocity: x.fixed_rows::<3>(VEL).into_owned(),
            covariance: core::array::from_fn(|i| {
                [
                    p[(POS + i, POS + i)],
                    p[(POS + i, VEL + i)],
                    p[(VEL + i, VEL + i)],
                ]
            }),
        })
    }
}

/// The horizon EKF before a GPS fusion: its time (us), velocity (NED, m/s)
/// and, per axis, `[P_pp, P_pv, P_vv]`.
#[derive(Debug, Clone, Copy)]
pub(super) struct HorizonPrior<T: Scalar> {
    pub(super) t_us: u64,
    pub(super) velocity: Vector3<T>,
    pub(super) covariance: [[T; 3]; 3],
}

//! The delay loop's side of the navigator: the delay it estimates (or the
//! fixed one) and eq. 15's per-sensor delays, the horizon's record of each
//! fused fix and the fix velocities it is fed, and the GPS noise the
//! delay's uncertainty adds.

use super::refusals::bump;
use super::{DelayCompensatedNav, DelayMode, horizon::HorizonPrior};
use crate::delay::{DelayUpdate, HorizonFix, SensorDelays};
use crate::estimate::{Estimate, FusionRecord};
use crate::scalar::Scalar;
use crate::sensors::Gps;
use crate::zero_option::ZeroOption;
use nalgebra::Vector3;

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// The GPS delay relative to the raw IMU, `tau = tau_f + D_f`, s: the
    /// estimate, or the given delay in fixed mode.
    pub fn delay_s(&self) -> T {
        match self.config.mode {
            DelayMode::Estimated { .. } => {
                self.delay_loop.delay_s() + self.accel_whitening.group_delay_s
            }
            DelayMode::Fixed { delay_s } => delay_s,
        }
    }

    /// Standard deviation of the delay, s (0 in fixed mode).
    pub fn delay_std_s(&self) -> T {
        match self.config.mode {
            DelayMode::Estimated { .. } => self.delay_loop.delay_std_s(),
            DelayMode::Fixed { .. } => T::zero(),
        }
    }

    /// Eq. (15): the delays applied to the whitened accelerometer, the
    /// whitened gyroscope and the raw magnetometer, s.
    pub fn sensor_delays(&self) -> SensorDelays<T> {
        let (d_f, d_w) = self.group_delays_s();
        SensorDelays::new(self.delay_s() - d_f, d_f, d_w)
    }

    /// The last delay update: validity per axis, correlation peaks,
    /// measurements and gains (`None` before the first, and in fixed mode).
    pub fn last_delay_update(&self) -> Option<&DelayUpdate<T>> {
        self.last_update.as_ref()
    }

    pub(super) fn with_delay(&self, mut e: Estimate<T>) -> Estimate<T> {
        e.delay_s = Some(self.delay_s());
        e.delay_std_s = Some(self.delay_std_s());
        e
    }

    /// `tau` in whole microseconds.
    pub(super) fn delay_us(&self) -> u64 {
        (self.delay_s() * T::lit(1e6)).round().as_f64().max(0.0) as u64
    }

    /// What the delay's uncertainty adds to the next fix's noise
    /// ([`DelayCompensatedNavConfig::gps_noise_from_delay`]): the variance of the delay
    /// estimate, s^2, and the horizon's mean NED acceleration since the last
    /// fused fix (its prior velocity minus the velocity after that fix, over
    /// the time between: the IMU's alone, m/s^2; zero before a first fix).
    pub(super) fn gps_timing_noise(&self) -> (T, Vector3<T>) {
        if !(self.config.gps_noise_from_delay && self.is_estimating()) {
            return (T::zero(), Vector3::zeros());
        }
        let accel = match (
            self.last_fix_velocity,
            self.ekf.time_us(),
            self.ekf.nav_state(),
        ) {
            (Some((t0_us, v0)), Some(t_us), Some(x)) if t_us > t0_us => {
                (x.velocity_ned_m_s - v0) / T::lit((t_us - t0_us) as f64 * 1e-6)
            }
            _ => Vector3::zeros(),
        };
        let std = self.delay_std_s();
        (std * std, accel)
    }

    pub(super) fn is_estimating(&self) -> bool {
        matches!(self.config.mode, DelayMode::Estimated { .. })
    }

    /// Gives the delay loop the horizon's record of a fused fix (the
    /// innovation observation of the delay, `delay::innovation`): per axis
    /// the prior position-velocity covariance, the noises recovered from
    /// the innovation variances (position is fused first: `S_p = P_pp +
    /// R_p`; velocity after it: `S_v = P_vv - P_pv^2 / S_p + R_v`), the
    /// position innovation and the velocity's against the prior state.
    pub(super) fn push_horizon_fix(
        &mut self,
        fix: &Gps<T>,
        prior: &HorizonPrior<T>,
        position: &FusionRecord<T, 3>,
        velocity: &FusionRecord<T, 3>,
        reset: bool,
    ) {
        let Some(x) = self.ekf.nav_state() else {
            return;
        };
        let (d_f, _) = self.group_delays_s();
        // Either sign: a negative delay puts the horizon after the fix.
        let delay_us = fix.t_us as f64 - prior.t_us as f64;
        let delay_s = T::lit(delay_us * 1e-6) - d_f;
        let tiny = T::lit(1e-12);
        let horizon_fix = HorizonFix {
            horizon_us: prior.t_us,
            delay_s,
            velocity_prior: prior.velocity,
            velocity_post: x.velocity_ned_m_s,
            covariance: prior.covariance,
            noise: core::array::from_fn(|i| {
                let [p_pp, p_pv, p_vv] = prior.covariance[i];
                let s_p = position.innovation_variance[i];
                let s_v = velocity.innovation_variance[i];
                let r_p = (s_p - p_pp).max(tiny);
                let r_v = (s_v - p_vv + p_pv * p_pv / s_p.max(tiny)).max(tiny);
                [r_p, r_v]
            }),
            innovation: core::array::from_fn(|i| {
                [
                    position.innovation[i],
                    fix.velocity_ned_m_s[i] - prior.velocity[i],
                ]
            }),
            fused: [position.fused, velocity.fused],
            reset,
        };
        self.delay_loop.push_horizon_fix(&horizon_fix);
    }

    /// Gives the waiting fix (if any) to the delay loop: the peak search
    /// and the gain fusion, kept out of the call that fuses the fix.
    pub(super) fn update_delay(&mut self) {
        let Some((t_us, velocity, _)) = self.pending_delay_fix.take() else {
            return;
        };
        match self.delay_loop.push_gps(t_us, velocity) {
            Ok(Some(update)) => {
                if update.axes.iter().any(|a| a.valid) {
                    self.valid_delay_updates = self.valid_delay_updates.saturating_add(1);
                }
                self.last_update = ZeroOption::Some(update);
            }
            Ok(None) => {}
            Err(_) => bump(&mut self.refusals.delay_loop_refused),
        }
    }
}

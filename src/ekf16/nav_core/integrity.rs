//! The protection levels of a core's covariance ([`crate::integrity`]), inflated by what the
//! GPS innovations say.
//!
//! **The monitor.** Per GPS block (position, velocity), an exponential mean of the normalized
//! innovation squared `NIS = y^T S^-1 y` of every fix, fused or rejected, each at most the
//! block's gate (a rejected glitch says more about the fix than about the state), weight
//! [`NIS_MEAN_WEIGHT`] per fix (about 1 s at 10 Hz), starting at 3 (its expectation: three
//! degrees of freedom). A consistent filter keeps it near 3; a covariance that lies about the
//! state (an unmodelled delay, a drift the filter follows) raises it.
//!
//! **The inflation.** Each block's levels are multiplied by `sqrt(max(1, mean / 3))`: the
//! horizontal and vertical levels by the position block's, the velocity and tilt levels by the
//! velocity block's (a tilt error shows in the velocity innovations first).

use super::NavCore;
use crate::ekf16::state::{POS, QUAT, VEL};
use crate::estimate::FusionRecord;
use crate::integrity::{Integrity, ProtectionLevels};
use crate::scalar::Scalar;
use nalgebra::{Matrix3, UnitQuaternion};

/// Standard deviation of the unknown acceleration over an IMU gap, per NED axis, m/s^2.
pub const GAP_ACCEL_STD_M_S2: f64 = 5.0;
/// Standard deviation of the unknown rotation rate over an IMU gap, per axis, rad/s.
pub const GAP_RATE_STD_RAD_S: f64 = 0.2;
/// Largest attitude standard deviation an IMU gap adds, rad (20 deg: beyond it the filter's
/// linearization no longer holds; the in-flight alignment's `MOVING_TILT_STD_RAD`).
pub const GAP_MAX_ATTITUDE_STD_RAD: f64 = 0.35;

/// Longest stretch of an IMU gap that the carry and the unknown motion are computed over, s
/// (beyond it the state is unknown anyway, and larger variances leave the range a later
/// update can handle in `f32`).
pub const GAP_MOTION_MAX_S: f64 = 10.0;

/// Weight of each fix in the NIS means of the integrity monitor (module docs).
pub(crate) const NIS_MEAN_WEIGHT: f64 = 0.1;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Updates the NIS means with one fix's records (module docs).
    pub(super) fn monitor_gps_nis(
        &mut self,
        position: &FusionRecord<T, 3>,
        velocity: &FusionRecord<T, 3>,
    ) {
        let gates = [self.config.gps_position_gate, self.config.gps_velocity_gate];
        for (i, record) in [position, velocity].into_iter().enumerate() {
            // test_ratio = NIS / gate; a NaN ratio (no record) leaves the mean as it is.
            let nis = record.test_ratio.min(T::one()) * gates[i];
            if nis.is_finite() {
                let w = T::lit(NIS_MEAN_WEIGHT);
                self.gps_nis_mean[i] += (nis - self.gps_nis_mean[i]) * w;
            }
        }
    }

    /// An IMU gap of `dt` s (at most [`GAP_MOTION_MAX_S`]) carried by the last known motion:
    /// the position moves by the velocity, `p += v dt` (`F = I + dt E_pv`, `P <- F P F^T`),
    /// attitude, velocity and biases stay; and `P` grows for the motion nobody measured: per
    /// NED axis, a white acceleration of [`GAP_ACCEL_STD_M_S2`] held over the gap (velocity
    /// `(s_a dt)^2`, position `(s_a dt^2 / 2)^2`, their covariance `s_a^2 dt^3 / 2`), and an
    /// attitude error of `min(GAP_RATE_STD_RAD_S dt, GAP_MAX_ATTITUDE_STD_RAD)` per axis
    /// (`s^2 / 4 (I - q q^T)` on the quaternion block: the covariance of `dq = dtheta q / 2`
    /// with `dtheta` isotropic).
    pub(super) fn carry_over_gap(
        &self,
        x: &mut nalgebra::SVector<T, N>,
        p: &mut nalgebra::SMatrix<T, N, N>,
        dt: T,
    ) {
        let dt = dt.min(T::lit(GAP_MOTION_MAX_S));
        for i in 0..3 {
            let v = x[VEL + i];
            x[POS + i] += v * dt;
        }
        for i in 0..3 {
            let row = p.row(VEL + i) * dt;
            let mut target = p.row_mut(POS + i);
            target += row;
        }
        for i in 0..3 {
            let column = p.column(VEL + i) * dt;
            let mut target = p.column_mut(POS + i);
            target += column;
        }
        let sa2 = T::lit(GAP_ACCEL_STD_M_S2 * GAP_ACCEL_STD_M_S2);
        for i in 0..3 {
            p[(VEL + i, VEL + i)] += sa2 * dt * dt;
            p[(POS + i, POS + i)] += sa2 * dt * dt * dt * dt / T::lit(4.0);
            let c = sa2 * dt * dt * dt / T::lit(2.0);
            p[(POS + i, VEL + i)] += c;
            p[(VEL + i, POS + i)] += c;
        }
        let s = (T::lit(GAP_RATE_STD_RAD_S) * dt).min(T::lit(GAP_MAX_ATTITUDE_STD_RAD));
        let q = x.fixed_rows::<4>(QUAT).normalize();
        let tangent = (nalgebra::Matrix4::identity() - q * q.transpose()) * (s * s / T::lit(4.0));
        let mut block = p.fixed_view_mut::<4, 4>(QUAT, QUAT);
        block += tangent;
    }

    /// The inflation factors `(position, velocity)` of the monitor (module docs), at least 1.
    pub(crate) fn nis_inflation(&self) -> (T, T) {
        let factor = |mean: T| (mean / T::lit(3.0)).max(T::one()).sqrt();
        (factor(self.gps_nis_mean[0]), factor(self.gps_nis_mean[1]))
    }

    /// What the filter vouches for: the protection levels of `P` at the configured risk,
    /// inflated by the monitor, each valid when within its alert limit and the filter is
    /// initialized; `delay_std_s` the delay's standard deviation where the filter estimates
    /// one. `resets` counts the GPS block resets.
    pub(crate) fn integrity(&self, delay_std_s: Option<T>) -> Integrity<T> {
        if !self.is_initialized() {
            return Integrity::none();
        }
        let config = &self.config.integrity;
        let q = UnitQuaternion::new_normalize(super::quaternion_of(&self.x));
        let zero = Matrix3::zeros();
        let (position, velocity) = self.nis_inflation();
        let levels =
            ProtectionLevels::from_covariance(&q, &self.p, config.risk, &zero, &zero, delay_std_s)
                .inflated(position, velocity);
        let r = self.refusals;
        Integrity {
            resets: r.gps_position_resets.saturating_add(r.gps_velocity_resets),
            ..Integrity::judged(levels, config, true)
        }
    }
}

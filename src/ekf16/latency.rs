//! What a GPS latency the filter does not model does to its position and velocity, for the
//! protection levels of [`Ekf16`](super::Ekf16) alone.
//!
//! `Ekf16` fuses a fix describing the instant `t - τ` as if it described `t` (the paper's
//! baseline). A filter that follows its fixes then carries the motion over `τ` as error: in
//! position `p(t) - p(t - τ) = v τ - a τ²/2 + ...`, in velocity `a τ + ...` (NED, `v` in m/s,
//! `a` the kinematic acceleration in m/s², `τ` in s). Its covariance knows nothing of it, so
//! its levels would be misleading exactly when the vehicle moves. With `τ` at most the
//! configured allowance `τ_a` ([`IntegrityConfig::gps_latency_allowance_s`]):
//!
//! - horizontal level `+ τ_a |v_h| + τ_a²/2 a_pk`, vertical `+ τ_a |v_d| + τ_a²/2 a_pk`;
//! - velocity level `+ τ_a a_pk`;
//!
//! `a_pk` the peak of `|a|` held over the filter's memory: `a` is the NED acceleration of the
//! estimate, `R(q) (f - b_a) + g e_down`, low-passed over [`ACCEL_SMOOTHING_S`] (the
//! vibration and noise of the accelerometer are not motion), and the peak decays as
//! `exp(-dt / PEAK_MEMORY_S)` (an error the fixes put into the estimate fades as later fixes
//! replace it, over about a second at GPS rates of 5-10 Hz).
//!
//! - tilt level `+ atan(c_pk / g)` (degrees), `c_pk` the decaying peak of the horizontal
//!   acceleration's change over the allowance.
//!
//! The tilt: a filter that follows lagged fixes takes on their acceleration, `a(t - τ)`, while
//! the accelerometer measures `a(t)`; it reconciles the two by turning its attitude until
//! `R f = a(t - τ) - g`, a tilt error of about `|a_h(t) - a_h(t - τ)| / g` (`a_h` horizontal).
//! The change over `τ_a` is read as `c = |a_h - l_h|`, `l_h` the smoothed acceleration
//! low-passed once more with the time constant `τ_a` (a first-order lag delays a ramp by its
//! time constant, and keeps a step's size for about that long), its peak held with the same
//! decay. On the integrity suite's clean runs (the GPS 0.2 s late) `Ekf16`'s tilt was above
//! its level while valid for 7.3 s of 360 s without it (docs/integrity.md).
//!
//! Not covered: the heading the filter turns to explain the lagged horizontal velocity.
//!
//! [`IntegrityConfig::gps_latency_allowance_s`]: crate::integrity::IntegrityConfig::gps_latency_allowance_s

use crate::integrity::ProtectionLevels;
use crate::scalar::{Scalar, zeros_const};
use nalgebra::{UnitQuaternion, Vector2, Vector3};

/// Time constant of the acceleration's low-pass filter, s.
pub const ACCEL_SMOOTHING_S: f64 = 0.05;

/// Time constant of the decay of the acceleration's peak, s.
pub const PEAK_MEMORY_S: f64 = 1.0;

/// The smoothed NED acceleration, its change over the allowance and their decaying peaks.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LatencyMonitor<T: Scalar> {
    /// Low-passed NED acceleration, m/s².
    accel_ned_m_s2: Vector3<T>,
    /// Its horizontal part low-passed again over the allowance `l_h`, m/s² (north, east).
    lagged_horizontal_m_s2: Vector2<T>,
    /// Decaying peak of the acceleration's norm, m/s².
    peak_m_s2: T,
    /// Decaying peak of the horizontal change `|a_h - l_h|`, m/s².
    change_peak_m_s2: T,
}

impl<T: Scalar> LatencyMonitor<T> {
    /// Nothing seen yet.
    pub(crate) const BLANK: Self = Self {
        accel_ned_m_s2: zeros_const(),
        lagged_horizontal_m_s2: zeros_const(),
        peak_m_s2: T::ZERO,
        change_peak_m_s2: T::ZERO,
    };

    /// One IMU step of `dt` s: the specific force `f` (body, m/s²) seen through the estimate
    /// (`attitude` body to NED, accelerometer bias `bias`), `gravity` m/s² added on the down
    /// axis; `allowance_s` the latency allowance `τ_a`. A non-finite acceleration (not
    /// possible from a sound state) is skipped.
    pub(crate) fn update(
        &mut self,
        attitude: &UnitQuaternion<T>,
        specific_force: &Vector3<T>,
        bias: &Vector3<T>,
        gravity: T,
        dt: T,
        allowance_s: T,
    ) {
        let mut a = attitude * (specific_force - bias);
        a.z += gravity;
        if !(a.iter().all(|v| v.is_finite()) && dt.is_finite() && dt >= T::zero()) {
            return;
        }
        let w = (dt / T::lit(ACCEL_SMOOTHING_S)).min(T::one());
        self.accel_ned_m_s2 += (a - self.accel_ned_m_s2) * w;
        let decay = (-dt / T::lit(PEAK_MEMORY_S)).exp();
        self.peak_m_s2 = (self.peak_m_s2 * decay).max(self.accel_ned_m_s2.norm());
        let horizontal = self.accel_ned_m_s2.xy();
        // An allowance of 0 (or below one step) leaves no lag: no change is carried.
        let wl = if allowance_s > dt {
            dt / allowance_s
        } else {
            T::one()
        };
        self.lagged_horizontal_m_s2 += (horizontal - self.lagged_horizontal_m_s2) * wl;
        let change = (horizontal - self.lagged_horizontal_m_s2).norm();
        self.change_peak_m_s2 = (self.change_peak_m_s2 * decay).max(change);
    }

    /// The peak acceleration, m/s².
    #[cfg(test)]
    pub(crate) fn peak_m_s2(&self) -> T {
        self.peak_m_s2
    }

    /// `levels` raised by the allowance `allowance_s` at the velocity `velocity_ned_m_s`,
    /// `gravity` m/s² (module docs).
    pub(crate) fn raise(
        &self,
        levels: ProtectionLevels<T>,
        velocity_ned_m_s: &Vector3<T>,
        allowance_s: T,
        gravity: T,
    ) -> ProtectionLevels<T> {
        let tau = allowance_s;
        if tau <= T::zero() {
            return levels;
        }
        let second_order = tau * tau / T::lit(2.0) * self.peak_m_s2;
        let horizontal = velocity_ned_m_s.x.hypot(velocity_ned_m_s.y);
        let tilt = self.change_peak_m_s2.atan2(gravity) * T::lit(180.0 / core::f64::consts::PI);
        ProtectionLevels {
            tilt_deg: levels.tilt_deg + tilt,
            horizontal_m: levels.horizontal_m + tau * horizontal + second_order,
            vertical_m: levels.vertical_m + tau * velocity_ned_m_s.z.abs() + second_order,
            velocity_m_s: levels.velocity_m_s + tau * self.peak_m_s2,
            ..levels
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At rest the monitor reads zero acceleration (the specific force is gravity's
    /// reaction); a steady 2 m/s² north is reached, and its peak decays once it stops.
    fn the_peak_follows_and_decays<T: Scalar>() {
        let lit = T::lit;
        let g = lit(9.80665);
        let level = UnitQuaternion::identity();
        let zero = Vector3::zeros();
        let mut m = LatencyMonitor::<T>::BLANK;
        let rest = Vector3::new(lit(0.0), lit(0.0), -g);
        for _ in 0..1000 {
            m.update(&level, &rest, &zero, g, lit(0.001), lit(0.4));
        }
        assert!(m.peak_m_s2() < lit(1e-5));
        let north = Vector3::new(lit(2.0), lit(0.0), -g);
        for _ in 0..1000 {
            m.update(&level, &north, &zero, g, lit(0.001), lit(0.4));
        }
        assert!(
            (m.peak_m_s2() - lit(2.0)).abs() < lit(1e-3),
            "{:?}",
            m.peak_m_s2()
        );
        for _ in 0..1000 {
            m.update(&level, &rest, &zero, g, lit(0.001), lit(0.4));
        }
        // One second later: the peak is 2 e^-1 (the smoothed value fell long before).
        let expected = lit(2.0 * (-1.0f64).exp());
        assert!(
            (m.peak_m_s2() - expected).abs() < lit(0.02),
            "{:?}",
            m.peak_m_s2()
        );
    }

    /// The raise is the module's formula: `τ |v_h| + τ²/2 a_pk` horizontally, `τ a_pk` on the
    /// velocity, `atan(c_pk / g)` on the tilt; the heading untouched; an allowance of 0
    /// raises nothing.
    fn the_levels_rise_by_the_motion_over_the_allowance<T: Scalar>() {
        let lit = T::lit;
        let mut m = LatencyMonitor::<T>::BLANK;
        m.peak_m_s2 = lit(3.0);
        m.change_peak_m_s2 = lit(2.0);
        let base = ProtectionLevels {
            tilt_deg: lit(1.0),
            heading_deg: lit(2.0),
            horizontal_m: lit(1.5),
            vertical_m: lit(2.5),
            velocity_m_s: lit(0.3),
            delay_s: lit(0.01),
        };
        let v = Vector3::new(lit(3.0), lit(4.0), lit(-1.0));
        let g = lit(9.80665);
        let raised = m.raise(base, &v, lit(0.4), g);
        let close = |a: T, b: f64| (a.as_f64() - b).abs() < 1e-4;
        assert!(close(raised.horizontal_m, 1.5 + 0.4 * 5.0 + 0.08 * 3.0));
        assert!(close(raised.vertical_m, 2.5 + 0.4 + 0.08 * 3.0));
        assert!(close(raised.velocity_m_s, 0.3 + 1.2));
        assert!(close(
            raised.tilt_deg,
            1.0 + (2.0f64 / 9.80665).atan().to_degrees()
        ));
        assert_eq!(raised.heading_deg, base.heading_deg);
        assert_eq!(m.raise(base, &v, lit(0.0), g), base);
    }

    /// The change over the allowance: a step of 2 m/s² north reads as a change of 2 m/s²
    /// (held in the peak), a steady acceleration as none once the lag has caught up, and
    /// without an allowance there is no lag.
    fn a_step_in_acceleration_is_a_change_a_steady_one_is_not<T: Scalar>() {
        let lit = T::lit;
        let g = lit(9.80665);
        let level = UnitQuaternion::identity();
        let zero = Vector3::zeros();
        let north = Vector3::new(lit(2.0), lit(0.0), -g);
        let mut m = LatencyMonitor::<T>::BLANK;
        for _ in 0..300 {
            m.update(&level, &north, &zero, g, lit(0.001), lit(0.4));
        }
        let held = m.change_peak_m_s2.as_f64();
        assert!(held > 1.2 && held <= 2.0, "{held}");
        let mut steady = m.clone();
        for _ in 0..10_000 {
            steady.update(&level, &north, &zero, g, lit(0.001), lit(0.4));
        }
        let change = (steady.accel_ned_m_s2.xy() - steady.lagged_horizontal_m_s2).norm();
        assert!(change.as_f64() < 1e-3, "{change:?}");
        assert!(steady.change_peak_m_s2.as_f64() < 0.01);
        let mut none = LatencyMonitor::<T>::BLANK;
        for _ in 0..300 {
            none.update(&level, &north, &zero, g, lit(0.001), lit(0.0));
        }
        assert_eq!(none.change_peak_m_s2, T::zero());
    }

    tests_in_both_precisions!(
        the_peak_follows_and_decays,
        the_levels_rise_by_the_motion_over_the_allowance,
        a_step_in_acceleration_is_a_change_a_steady_one_is_not
    );
}

//! Integrity: a protection level beside every estimate, and the flags it decides.
//!
//! A **protection level** (PL) bounds the error of one quantity with a stated probability: the
//! estimator claims `P(|e| > PL) <= risk` per epoch, `risk` the configured integrity risk
//! ([`IntegrityConfig::risk`], default [`DEFAULT_INTEGRITY_RISK`] = 1e-3). The **alert limit**
//! (AL) is what the user tolerates; a quantity is **valid** (available) when its `PL <= AL`.
//! An epoch where the error exceeds the PL while the quantity is valid is **misleading
//! information** (MI); `reproduce --integrity` counts it on the simulator (docs/integrity.md).
//!
//! # The model
//! The error is taken as zero-mean Gaussian with the filter's covariance `P` (16 navigation
//! states: quaternion, position NED, velocity NED, biases; an extra delay state where the
//! estimator has one). With `z(p)` the upper-tail standard normal quantile:
//!
//! - **one-dimensional** (heading about the NED down axis, vertical position, delay):
//!   `PL = k1 s`, `k1 = z(risk / 2)` (risk 1e-3: 3.29), `s` the standard deviation.
//! - **two-dimensional** (tilt: north and east components of the attitude error; horizontal
//!   position north and east): the Rayleigh quantile on the largest axis,
//!   `PL = k2 sqrt(lambda_max)`, `k2 = sqrt(-2 ln risk)` (1e-3: 3.72), `lambda_max` the larger
//!   eigenvalue of the 2x2 block (exact). Conservative: `|e|^2 <= lambda_max e^T P^-1 e`.
//! - **three-dimensional** (velocity, the norm of the NED vector):
//!   `PL = k3 sqrt(lambda_max)`, `k3^2` the chi-square (3 degrees of freedom) quantile of
//!   `risk` by the Wilson-Hilferty approximation, `3 (1 - 2/27 + z(risk) sqrt(2/27))^3`
//!   (1e-3: `k3` = 4.07, the exact 4.03), `lambda_max` bounded above by Gershgorin's circles.
//!
//! The attitude error is the rotation vector of `R(est) R(true)^T` (NED, rad); its covariance
//! is `G P_qq G^T` with `G = 2 [-v, w I + [v x]]` at the estimate `q = (w, v)`. Degrees are
//! reported for tilt and heading.
//!
//! `z` is Abramowitz and Stegun's 26.2.23 (absolute error below 4.5e-4).
//!
//! # What a PL does not cover
//! Errors outside the model: a fault the filter's noise does not describe (a slow GPS drift, a
//! biased magnetometer, an unmodelled delay), a linearization at a wrong state, process noise
//! tuned for the good day. An estimator adds what it knows on top of `P` (the navigator: the
//! delay's uncertainty carried to the present); what it does not know, the monitors must turn
//! into inflation, and the suite measures what is left.

use crate::ekf16::state::{POS, QUAT, VEL};
use crate::scalar::Scalar;
use nalgebra::{Matrix2, Matrix3, Quaternion, SMatrix, UnitQuaternion};

/// Default integrity risk per epoch.
pub const DEFAULT_INTEGRITY_RISK: f64 = 1e-3;

/// Default of [`IntegrityConfig::gps_latency_allowance_s`], s.
pub const DEFAULT_GPS_LATENCY_ALLOWANCE_S: f64 = 0.4;

/// The integrity risk and the alert limits.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct IntegrityConfig<T: Scalar> {
    /// Probability per epoch that an error exceeds its PL, in `(0, 0.5)` [default: 1e-3].
    pub risk: T,
    /// Tilt alert limit, degrees [default: 5].
    pub tilt_alert_limit_deg: T,
    /// Heading alert limit, degrees [default: 10].
    pub heading_alert_limit_deg: T,
    /// Horizontal position alert limit, m [default: 10].
    pub horizontal_alert_limit_m: T,
    /// Vertical position alert limit, m [default: 15].
    pub vertical_alert_limit_m: T,
    /// Velocity (norm of the NED vector) alert limit, m/s [default: 2].
    pub velocity_alert_limit_m_s: T,
    /// Delay alert limit, s [default: 0.1].
    pub delay_alert_limit_s: T,
    /// The GPS latency, s, that the levels of an estimator fusing fixes as current
    /// ([`Ekf16`](crate::Ekf16)) allow for, in `[0, 1]` [default: 0.4, the upper end of a
    /// cheap receiver's delay]: its position and velocity levels rise by the motion over that
    /// time ([`ekf16::latency`](crate::ekf16::latency)); 0 when the fixes' timestamps are
    /// their times of validity. The navigator and `AugmentedEkf17` estimate the delay and
    /// ignore it.
    pub gps_latency_allowance_s: T,
}

impl<T: Scalar> IntegrityConfig<T> {
    /// Every field zero: the configuration of a blank estimator (refused by `validate`).
    pub(crate) const ZEROED: Self = Self {
        risk: T::ZERO,
        tilt_alert_limit_deg: T::ZERO,
        heading_alert_limit_deg: T::ZERO,
        horizontal_alert_limit_m: T::ZERO,
        vertical_alert_limit_m: T::ZERO,
        velocity_alert_limit_m_s: T::ZERO,
        delay_alert_limit_s: T::ZERO,
        gps_latency_allowance_s: T::ZERO,
    };

    /// The risk in `(0, 0.5)`, every alert limit positive (`+inf` allowed: never alert).
    pub fn validate(&self) -> Result<(), crate::Error> {
        let bad = |field: &'static str, value: T, rule| {
            Err(crate::Error::InvalidConfig {
                field: field.into(),
                value: Some(value.as_f64()),
                bound: crate::error::Bound::Rule(rule),
            })
        };
        let risk_in_range = self.risk > T::zero() && self.risk < T::lit(0.5);
        if !risk_in_range {
            return bad("integrity.risk", self.risk, "must be in (0, 0.5)");
        }
        for (field, v) in [
            ("integrity.tilt_alert_limit_deg", self.tilt_alert_limit_deg),
            (
                "integrity.heading_alert_limit_deg",
                self.heading_alert_limit_deg,
            ),
            (
                "integrity.horizontal_alert_limit_m",
                self.horizontal_alert_limit_m,
            ),
            (
                "integrity.vertical_alert_limit_m",
                self.vertical_alert_limit_m,
            ),
            (
                "integrity.velocity_alert_limit_m_s",
                self.velocity_alert_limit_m_s,
            ),
            ("integrity.delay_alert_limit_s", self.delay_alert_limit_s),
        ] {
            crate::error::check::positive(field, v)?;
        }
        let allowance = self.gps_latency_allowance_s;
        if !(allowance >= T::zero() && allowance <= T::one()) {
            return bad(
                "integrity.gps_latency_allowance_s",
                allowance,
                "must be in [0, 1] s",
            );
        }
        Ok(())
    }
}

impl<T: Scalar> Default for IntegrityConfig<T> {
    fn default() -> Self {
        Self {
            risk: T::lit(DEFAULT_INTEGRITY_RISK),
            tilt_alert_limit_deg: T::lit(5.0),
            heading_alert_limit_deg: T::lit(10.0),
            horizontal_alert_limit_m: T::lit(10.0),
            vertical_alert_limit_m: T::lit(15.0),
            velocity_alert_limit_m_s: T::lit(2.0),
            delay_alert_limit_s: T::lit(0.1),
            gps_latency_allowance_s: T::lit(DEFAULT_GPS_LATENCY_ALLOWANCE_S),
        }
    }
}

/// Upper-tail standard normal quantile: `z` with `P(Z > z) = p`, `p` in `(0, 0.5]`
/// (Abramowitz and Stegun 26.2.23, absolute error below 4.5e-4).
pub fn normal_upper_quantile<T: Scalar>(p: T) -> T {
    let p = p.max(T::lit(1e-37));
    let t = (T::lit(-2.0) * p.ln()).sqrt();
    let num = T::lit(2.515517) + t * (T::lit(0.802853) + t * T::lit(0.010328));
    let den = T::one() + t * (T::lit(1.432788) + t * (T::lit(0.189269) + t * T::lit(0.001308)));
    t - num / den
}

/// The multipliers `(k1, k2, k3)` of the standard deviation (1-D), of the square root of the
/// largest eigenvalue (2-D, 3-D) at `risk` (module docs).
pub fn protection_factors<T: Scalar>(risk: T) -> (T, T, T) {
    let k1 = normal_upper_quantile(risk * T::lit(0.5));
    let k2 = (T::lit(-2.0) * risk.ln()).sqrt();
    let a = T::lit(2.0 / 27.0);
    let c = T::one() - a + normal_upper_quantile(risk) * a.sqrt();
    let k3 = (T::lit(3.0) * c * c * c).sqrt();
    (k1, k2, k3)
}

/// Larger eigenvalue of a symmetric 2x2 matrix (0 when it is not positive).
fn largest_eigenvalue_2<T: Scalar>(m: &Matrix2<T>) -> T {
    let half_sum = (m[(0, 0)] + m[(1, 1)]) * T::lit(0.5);
    let half_diff = (m[(0, 0)] - m[(1, 1)]) * T::lit(0.5);
    let off = (m[(0, 1)] + m[(1, 0)]) * T::lit(0.5);
    (half_sum + (half_diff * half_diff + off * off).sqrt()).max(T::zero())
}

/// Gershgorin's bound on the largest eigenvalue of a symmetric 3x3 matrix (not negative).
fn largest_eigenvalue_bound_3<T: Scalar>(m: &Matrix3<T>) -> T {
    let row = |i: usize, j: usize, k: usize| m[(i, i)] + m[(i, j)].abs() + m[(i, k)].abs();
    row(0, 1, 2)
        .max(row(1, 0, 2))
        .max(row(2, 0, 1))
        .max(T::zero())
}

/// Covariance of the NED attitude error (rotation vector, rad) of the estimate `q` from the
/// quaternion block `p_qq` of `P`: `G P_qq G^T`, `G = 2 [-v, w I + [v x]]`.
pub fn attitude_error_covariance<T: Scalar>(
    q: &Quaternion<T>,
    p_qq: &SMatrix<T, 4, 4>,
) -> Matrix3<T> {
    let v = q.imag();
    let mut g = SMatrix::<T, 3, 4>::zeros();
    g.set_column(0, &(-v));
    g.fixed_view_mut::<3, 3>(0, 1)
        .copy_from(&(Matrix3::identity() * q.w + v.cross_matrix()));
    g *= T::lit(2.0);
    g * p_qq * g.transpose()
}

/// Protection levels, each bounding its quantity's error at the configured risk (module docs).
/// `+inf` where the estimator vouches for nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ProtectionLevels<T: Scalar> {
    /// Tilt (norm of the north and east attitude error), degrees.
    pub tilt_deg: T,
    /// Heading (attitude error about down), degrees.
    pub heading_deg: T,
    /// Horizontal position, m.
    pub horizontal_m: T,
    /// Vertical position, m.
    pub vertical_m: T,
    /// Velocity (norm of the NED error), m/s.
    pub velocity_m_s: T,
    /// GPS delay, s.
    pub delay_s: T,
}

impl<T: Scalar> ProtectionLevels<T> {
    /// Every level infinite: nothing vouched for.
    pub fn unbounded() -> Self {
        let inf = T::lit(f64::INFINITY);
        Self {
            tilt_deg: inf,
            heading_deg: inf,
            horizontal_m: inf,
            vertical_m: inf,
            velocity_m_s: inf,
            delay_s: inf,
        }
    }

    /// The levels of the navigation states of `p` (`N >= 16`, the crate's state order) at the
    /// estimate `q` and `risk`; `extra_position` and `extra_velocity` are added to the NED
    /// position and velocity blocks (what the estimator knows beyond `P`); `delay_std_s` the
    /// delay's standard deviation (`None`: no delay estimate, an infinite level).
    pub fn from_covariance<const N: usize>(
        q: &UnitQuaternion<T>,
        p: &SMatrix<T, N, N>,
        risk: T,
        extra_position: &Matrix3<T>,
        extra_velocity: &Matrix3<T>,
        delay_std_s: Option<T>,
    ) -> Self {
        let (k1, k2, k3) = protection_factors(risk);
        let deg = T::lit(180.0 / core::f64::consts::PI);
        let p_qq = p.fixed_view::<4, 4>(QUAT, QUAT).into_owned();
        let att = attitude_error_covariance(q.quaternion(), &p_qq);
        let pos = p.fixed_view::<3, 3>(POS, POS) + extra_position;
        let vel = p.fixed_view::<3, 3>(VEL, VEL) + extra_velocity;
        let sd = |v: T| v.max(T::zero()).sqrt();
        Self {
            tilt_deg: k2
                * largest_eigenvalue_2(&att.fixed_view::<2, 2>(0, 0).into_owned()).sqrt()
                * deg,
            heading_deg: k1 * sd(att[(2, 2)]) * deg,
            horizontal_m: k2
                * largest_eigenvalue_2(&pos.fixed_view::<2, 2>(0, 0).into_owned()).sqrt(),
            vertical_m: k1 * sd(pos[(2, 2)]),
            velocity_m_s: k3 * largest_eigenvalue_bound_3(&vel).sqrt(),
            delay_s: delay_std_s.map_or(T::lit(f64::INFINITY), |s| k1 * sd(s * s)),
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The levels with the horizontal and vertical ones multiplied by `position`, the velocity
    /// and tilt ones by `velocity` (the factors of an innovation monitor, at least 1).
    pub fn inflated(self, position: T, velocity: T) -> Self {
        Self {
            tilt_deg: self.tilt_deg * velocity,
            horizontal_m: self.horizontal_m * position,
            vertical_m: self.vertical_m * position,
            velocity_m_s: self.velocity_m_s * velocity,
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The tilt and heading levels with an isotropic attitude variance `variance_rad2` (rad^2
    /// per axis) added to the attitude error's covariance: `t' = sqrt(t^2 + (k2 s)^2)`,
    /// `h' = sqrt(h^2 + (k1 s)^2)` in degrees, `s` its square root (exact: `s^2 I` adds `s^2`
    /// to both eigenvalues of the tilt block and to the heading's variance).
    pub(crate) fn with_attitude_variance(self, variance_rad2: T, risk: T) -> Self {
        let (k1, k2, _) = protection_factors(risk);
        let s = variance_rad2.max(T::zero()).sqrt() * T::lit(180.0 / core::f64::consts::PI);
        let (t, h) = (k2 * s, k1 * s);
        Self {
            tilt_deg: (self.tilt_deg * self.tilt_deg + t * t).sqrt(),
            heading_deg: (self.heading_deg * self.heading_deg + h * h).sqrt(),
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The levels with `(horizontal, vertical)` m added to the horizontal and vertical ones:
    /// an error the fixes themselves show (the position-against-velocity check's offset).
    pub fn with_position_bias(self, (horizontal, vertical): (T, T)) -> Self {
        Self {
            horizontal_m: self.horizontal_m + horizontal,
            vertical_m: self.vertical_m + vertical,
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The levels with `bias` m/s added to the velocity one: a velocity error the GPS
    /// velocity innovations keep showing (their mean), which the covariance does not hold.
    pub fn with_velocity_bias(self, bias: T) -> Self {
        Self {
            velocity_m_s: self.velocity_m_s + bias,
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The levels of a state carried `span_s` seconds forward by the IMU from the state these
    /// levels bound: an attitude error `e` turns the specific force `f` (m/s², NED), so the
    /// carried velocity gains `|f x e| span` and the position `|f x e| span^2 / 2`, with
    /// `|f x e| <= |f| E(t) + |f_h| E(h)` (the tilt error turns all of `f`, the heading error
    /// only its horizontal part `f_h`), `E(x) = 2 sin(min(x, 180 deg) / 2)` the chord of the
    /// tilt level `t` and the heading level `h`. Added to the levels, not to the covariance:
    /// the attitude error is bounded at its level, where its effect is largest, whatever its
    /// distribution (an alignment in motion leaves errors of tens of degrees that a
    /// linearized variance does not carry).
    pub fn carried(self, specific_force_m_s2: T, horizontal_m_s2: T, span_s: T) -> Self {
        let chord = |deg: T| {
            let half = (deg * T::lit(core::f64::consts::PI / 180.0))
                .min(T::lit(core::f64::consts::PI))
                * T::lit(0.5);
            // `max` also turns a NaN level into 0; the level itself stays NaN.
            T::lit(2.0) * half.max(T::zero()).sin()
        };
        let turned =
            specific_force_m_s2 * chord(self.tilt_deg) + horizontal_m_s2 * chord(self.heading_deg);
        let carried = turned * span_s * span_s * T::lit(0.5);
        Self {
            velocity_m_s: self.velocity_m_s + turned * span_s,
            horizontal_m: self.horizontal_m + carried,
            vertical_m: self.vertical_m + carried,
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The heading level with the tilt's share of a magnetometer heading: a tilt error `e` about
    /// the field's horizontal direction turns the field's horizontal projection by `tan(I) e`
    /// (`I` the field's inclination), so the heading's variance gains `s^2`, `s` that share's
    /// standard deviation (rad, `heading_std_rad`; the filter's gives the larger of what its
    /// fused samples carried and what a sample would carry now): `h' = sqrt(h^2 + (k1 s)^2)`
    /// (degrees).
    pub fn with_heading_tilt_coupling(self, heading_std_rad: T, risk: T) -> Self {
        let (k1, _, _) = protection_factors(risk);
        let share = k1 * heading_std_rad * T::lit(180.0 / core::f64::consts::PI);
        Self {
            heading_deg: (self.heading_deg * self.heading_deg + share * share).sqrt(),
            ..self
        }
    }
}

impl<T: Scalar> ProtectionLevels<T> {
    /// The levels with the magnetometer monitor's share `(factor, heading_rad, tilt_rad)`: the
    /// heading level multiplied by `factor` (at least 1, from the magnetometer's innovations),
    /// then `heading_rad` and `tilt_rad` (a field offset's turn of the heading and of the
    /// tilt) added to the heading and tilt levels (degrees).
    pub fn with_magnetometer(self, (factor, heading_rad, tilt_rad): (T, T, T)) -> Self {
        let deg = T::lit(180.0 / core::f64::consts::PI);
        Self {
            heading_deg: self.heading_deg * factor.max(T::one()) + heading_rad * deg,
            tilt_deg: self.tilt_deg + tilt_rad * deg,
            ..self
        }
    }
}

/// What an estimator vouches for, through the [`Navigator`](crate::Navigator) trait: its
/// protection levels and, per quantity, whether it is valid (`PL <= alert limit` and the
/// estimator's own preconditions), and the resets it made or divergences it reported.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Integrity<T: Scalar> {
    /// The protection levels.
    pub levels: ProtectionLevels<T>,
    /// Tilt valid.
    pub tilt_valid: bool,
    /// Heading valid.
    pub heading_valid: bool,
    /// Horizontal position valid.
    pub horizontal_valid: bool,
    /// Vertical position valid.
    pub vertical_valid: bool,
    /// Velocity valid.
    pub velocity_valid: bool,
    /// Delay valid.
    pub delay_valid: bool,
    /// Resets of a block or of the whole filter, and reported divergences, so far.
    pub resets: u32,
}

impl<T: Scalar> Integrity<T> {
    /// Nothing vouched for: infinite levels, nothing valid (the trait's default).
    pub fn none() -> Self {
        Self {
            levels: ProtectionLevels::unbounded(),
            tilt_valid: false,
            heading_valid: false,
            horizontal_valid: false,
            vertical_valid: false,
            velocity_valid: false,
            delay_valid: false,
            resets: 0,
        }
    }

    /// The flags of `levels` against the alert limits of `config`, each also needing `usable`.
    pub fn judged(levels: ProtectionLevels<T>, config: &IntegrityConfig<T>, usable: bool) -> Self {
        Self {
            levels,
            tilt_valid: usable && levels.tilt_deg <= config.tilt_alert_limit_deg,
            heading_valid: usable && levels.heading_deg <= config.heading_alert_limit_deg,
            horizontal_valid: usable && levels.horizontal_m <= config.horizontal_alert_limit_m,
            vertical_valid: usable && levels.vertical_m <= config.vertical_alert_limit_m,
            velocity_valid: usable && levels.velocity_m_s <= config.velocity_alert_limit_m_s,
            delay_valid: usable && levels.delay_s <= config.delay_alert_limit_s,
            resets: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn factors_match_the_tables<T: Scalar>() {
        let (k1, k2, k3) = protection_factors(T::lit(1e-3));
        assert!((k1.as_f64() - 3.2905).abs() < 2e-3, "k1 {k1:?}");
        assert!((k2.as_f64() - 3.7169).abs() < 1e-3, "k2 {k2:?}");
        // Wilson-Hilferty is above the exact 4.034 (conservative), by little.
        assert!(k3.as_f64() > 4.034 && k3.as_f64() < 4.1, "k3 {k3:?}");
        let (k1, _, _) = protection_factors(T::lit(1e-5));
        assert!((k1.as_f64() - 4.4172).abs() < 2e-3, "k1 {k1:?}");
    }

    fn levels_scale_with_the_covariance<T: Scalar>() {
        let q = UnitQuaternion::<T>::identity();
        let mut p = SMatrix::<T, 16, 16>::zeros();
        // 1 deg tilt, 2 deg heading std: quaternion std half the angle.
        let half = |deg: f64| T::lit((deg.to_radians() * 0.5).powi(2));
        p[(1, 1)] = half(1.0);
        p[(2, 2)] = half(1.0);
        p[(3, 3)] = half(2.0);
        p[(POS, POS)] = T::lit(4.0);
        p[(POS + 1, POS + 1)] = T::lit(1.0);
        p[(POS + 2, POS + 2)] = T::lit(9.0);
        for i in 0..3 {
            p[(VEL + i, VEL + i)] = T::lit(0.01);
        }
        let z = Matrix3::zeros();
        let l = ProtectionLevels::from_covariance(&q, &p, T::lit(1e-3), &z, &z, Some(T::lit(0.01)));
        let close = |a: T, b: f64| (a.as_f64() - b).abs() < 2e-3 * b;
        assert!(close(l.tilt_deg, 3.7169), "{l:?}");
        assert!(close(l.heading_deg, 2.0 * 3.2905), "{l:?}");
        assert!(close(l.horizontal_m, 2.0 * 3.7169), "{l:?}");
        assert!(close(l.vertical_m, 3.0 * 3.2905), "{l:?}");
        assert!(
            l.velocity_m_s.as_f64() > 0.4 && l.velocity_m_s.as_f64() < 0.41,
            "{l:?}"
        );
        assert!(close(l.delay_s, 0.032905), "{l:?}");
        // Judged against the defaults: all within but the tilt's 5 deg... all valid.
        let config = IntegrityConfig::<T>::default();
        let i = Integrity::judged(l, &config, true);
        assert!(i.tilt_valid && i.heading_valid && i.horizontal_valid && i.vertical_valid);
        assert!(i.velocity_valid && i.delay_valid);
        assert!(!Integrity::judged(l, &config, false).tilt_valid);
        let tight = IntegrityConfig {
            horizontal_alert_limit_m: T::lit(7.0),
            ..config
        };
        assert!(!Integrity::judged(l, &tight, true).horizontal_valid);
        // The fixes' offset adds to the position levels; the tilt's share to the heading's.
        let b = l.with_position_bias((T::lit(20.0), T::lit(1.0)));
        assert!(close(b.horizontal_m, 2.0 * 3.7169 + 20.0), "{b:?}");
        assert!(close(b.vertical_m, 3.0 * 3.2905 + 1.0), "{b:?}");
        assert!(!Integrity::judged(b, &config, true).horizontal_valid);
        let c = l.with_heading_tilt_coupling(T::lit(2f64.to_radians()), T::lit(1e-3));
        assert!(close(c.heading_deg, 8f64.sqrt() * 3.2905), "{c:?}");
        assert_eq!(c.tilt_deg, l.tilt_deg);
    }

    /// Carried 0.2 s forward: a 10 m/s² specific force (3 m/s² of it horizontal) turned by
    /// the levels' attitude error at its chord, added to velocity and position; an alignment
    /// in motion's 40 deg tilt level puts the velocity past its 2 m/s alert limit.
    fn a_carried_state_adds_the_turned_force<T: Scalar>() {
        let l = ProtectionLevels {
            tilt_deg: T::lit(3.0),
            heading_deg: T::lit(10.0),
            horizontal_m: T::lit(2.0),
            vertical_m: T::lit(3.0),
            velocity_m_s: T::lit(0.5),
            delay_s: T::lit(0.01),
        };
        let chord = |deg: f64| 2.0 * (deg.to_radians() / 2.0).sin();
        let turned = 10.0 * chord(3.0) + 3.0 * chord(10.0);
        let c = l.carried(T::lit(10.0), T::lit(3.0), T::lit(0.2));
        let close = |a: T, b: f64| (a.as_f64() - b).abs() < 1e-5 * b.max(1.0);
        assert!(close(c.velocity_m_s, 0.5 + turned * 0.2), "{c:?}");
        assert!(close(c.horizontal_m, 2.0 + turned * 0.02), "{c:?}");
        assert!(close(c.vertical_m, 3.0 + turned * 0.02), "{c:?}");
        assert_eq!(
            (c.tilt_deg, c.heading_deg, c.delay_s),
            (l.tilt_deg, l.heading_deg, l.delay_s)
        );
        let config = IntegrityConfig::<T>::default();
        assert!(Integrity::judged(c, &config, true).velocity_valid);
        let aligning = ProtectionLevels {
            tilt_deg: T::lit(40.0),
            heading_deg: T::lit(f64::INFINITY),
            ..l
        };
        let c = aligning.carried(T::lit(10.0), T::lit(3.0), T::lit(0.2));
        assert!(
            close(c.velocity_m_s, 0.5 + (10.0 * chord(40.0) + 3.0 * 2.0) * 0.2),
            "{c:?}"
        );
        assert!(!Integrity::judged(c, &config, true).velocity_valid);
    }

    fn a_bad_configuration_is_refused<T: Scalar>() {
        assert!(IntegrityConfig::<T>::default().validate().is_ok());
        assert!(IntegrityConfig::<T>::ZEROED.validate().is_err());
        for risk in [0.0, 0.5, f64::NAN, -1.0] {
            let c = IntegrityConfig {
                risk: T::lit(risk),
                ..IntegrityConfig::default()
            };
            assert!(c.validate().is_err());
        }
        for allowance in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
            let c = IntegrityConfig {
                gps_latency_allowance_s: T::lit(allowance),
                ..IntegrityConfig::default()
            };
            assert!(c.validate().is_err(), "{allowance}");
        }
        let c = IntegrityConfig {
            velocity_alert_limit_m_s: T::lit(f64::NAN),
            ..IntegrityConfig::default()
        };
        assert!(c.validate().is_err());
    }

    tests_in_both_precisions!(
        factors_match_the_tables,
        levels_scale_with_the_covariance,
        a_carried_state_adds_the_turned_force,
        a_bad_configuration_is_refused
    );
}

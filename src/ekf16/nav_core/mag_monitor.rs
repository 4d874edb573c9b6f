//! The magnetometer's integrity monitor: what the samples say about the heading and tilt
//! levels beyond the filter's covariance (all three estimators, through `NavCore`).
//!
//! Two monitors, both per magnetometer sample after initialization (units: the field
//! relative to its learned norm, dimensionless; directions unit vectors in the body frame FRD;
//! times s).
//!
//! **The innovation monitor.** An exponential mean `nu` (weight [`MAG_NIS_MEAN_WEIGHT`] per
//! sample, about 1 s at 100 Hz, starting at 1) of each sample's normalized innovation squared
//! per degree of freedom, `NIS / d`, `d` = 1 for the heading-only update (a rank-one heading
//! innovation; its expectation is 1 when the heading noise is the configured one) and 2 for
//! the 3-axis update (two directions), each sample at most its gate (`mag_gate / 1`,
//! `mag_three_axis_gate / 2`): a sample refused as disturbed or gated out counts at the cap
//! (it says more about the field than about the state). A consistent filter keeps `nu` within
//! `nu_c = 1 + k1 sqrt(2 w / (2 - w))` (`w` the weight; the mean of chi-square samples of one
//! degree of freedom, variance 2, at the integrity risk: 1.33 at 1e-3), and the heading level
//! is multiplied by `sqrt(max(1, nu / nu_c))`: a field turned away from the model (a
//! disturbance that keeps its norm and inclination) leaves every sample at the gate,
//! `nu -> 9`, the heading level 2.6 times the covariance's while the filter coasts on the gyro.
//!
//! **The field-offset monitor.** A body-frame offset `b` (a hard iron the calibration missed, a
//! magnet near the sensor) moves the measured field `m_b = m + b` away from the Earth's field
//! `m` (body frame) by a vector that turns with the vehicle, which the heading-innovation gate
//! cannot see (the filter's heading follows it) but the field's norm can: to first order in
//! `|b| / |m|`, `|m_b| = |m| + b . u` (`u` the field's body direction), so the norm varies as
//! the vehicle turns; a clean field does not. The monitor learns the field's norm `n_L` and
//! body direction `u_L` (the unit directions `u = m_b / |m_b|` measured) from the fused
//! samples, started at the alignment's means of `n_0` samples: a running mean up to
//! `1 / w` samples, then an exponential mean of weight `w` (`b_k = max(1 / k, w)` for the
//! `k`-th sample, `w = mag_field_learning_rate`; the same weights for both, so that they are
//! means over the same attitudes). Per sample:
//!
//! ```text
//! r = |m_b| / n_L - 1,     e <- e + a (r - e),     d <- d + a (u - d)      (a = MAG_NORM_SMOOTHING)
//! e ~= (b / |m|) . (d - u_L)   so   beta = |b| / |m| >= |e| / |d - u_L|
//! ```
//!
//! `e` is the smoothed relative norm residual and `|d - u_L|` the sweep of the field's body
//! direction the residual was seen over. Without an offset `e` is noise: with
//! `s_r = sqrt(mag_noise_variance)` (the noise of one component of the unit field, so of the
//! norm to first order) the smoothed noise has the variance `s_r^2 a / (2 - a)` and the
//! learned norm's error at most `s_r^2 max(1 / k, w)` (`k` the samples it is the mean of:
//! exact while a running mean, above the exponential mean's `s_r^2 w / (2 - w)` after);
//! `s_e` is the square root of their sum, and the
//! tolerance is `k1 s_e` (`k1` the 1-D factor at the integrity risk, 3.29 at 1e-3). A sample
//! with `|e|` beyond it is counted (`FilterRefusals::mag_field_offset`) and gives the offset a
//! lower bound `beta_k = (|e| - k1 s_e) / max(|d - u_L|, MAG_MIN_SWEEP)` (the norm moved beyond
//! the noise; [`MAG_MIN_SWEEP`] keeps the division above the smoothed direction's own noise,
//! `sqrt(2) s_e`, about 0.014 with the Table 3 magnetometer). The held offset is
//! `beta <- min(1, max(beta max(0, 1 - dt / T), beta_k))`, `T` = [`MAG_OFFSET_MEMORY_S`],
//! `dt` the interval between samples (a decay of time constant `T` at the magnetometer's
//! rate): an offset fixed to the body shows again each time the vehicle turns, a passing
//! disturbance is forgotten. A held offset that has decayed below the tolerance `k1 s_e` (less
//! than a whole sweep of the field's direction could show) is set to 0: without that, one
//! offset seen kept the 3-axis update off for the rest of a flight.
//!
//! A held offset is also set to 0 when the norm has changed by more than any body-fixed offset
//! allows for the change of direction. With a body-fixed offset `b` the measured field is
//! `m + b`, `|m|` fixed, so its norm is a function of its direction `u` alone, whose gradient
//! along the unit sphere is at most `|b| (1 + beta) / sqrt(1 - beta^2)` (`beta = |b| / |m|`):
//! at most the field's norm for offsets up to 0.6 of the field, 0.41 of it at 0.3. So from the
//! sighting `(d_s, N_s)` (the smoothed direction and norm `N = n_L (1 + e)` where the residual
//! was furthest beyond its tolerance since the held offset was last 0), a body-fixed offset keeps
//! `|N - N_s| <= n_L |d - d_s|`. A residual back within its tolerance with
//! `|N - N_s| / n_L > |d - d_s| + sqrt(2) k1 s_e` (the two smoothed norms' noise at the
//! integrity risk) refutes it: what the norm showed was not fixed to the body (a passing
//! disturbance, as a steel structure passed or a current switched on and off), and it is gone.
//! Counted in `FilterRefusals::mag_field_offset_cleared`. The learned norm and direction may
//! have moved since the sighting; the test compares measured norms and directions, not
//! residuals, so that does not enter it.
//!
//! What the offset does to the levels: the tilt-compensated heading reads the horizontal
//! field, `|m| cos I` long (`I` the configured inclination), turned by up to
//! `asin(min(1, beta / cos I))` by an offset `beta |m|`; the 3-axis update turns the tilt by up
//! to `asin(min(1, beta))` (the angle between `m` and `m + b`). Both are added to the heading
//! and tilt levels (degrees), and while `beta > 0` the magnetometer is fused heading-only (a
//! field known to be wrong does not level the tilt); while `beta > sin(AL_h) cos I` (`AL_h` the
//! heading alert limit) it is not fused at all (`NavCore::mag_offset_beyond_alert`). `beta` is
//! a lower bound of the offset: an offset seen over a small sweep of attitudes is larger than
//! it says, and one the vehicle never turned against is not seen at all (docs/integrity.md).

use crate::scalar::{Scalar, zeros_const};
use nalgebra::Vector3;

/// Weight of each sample in the mean NIS per degree of freedom (1 s at 100 Hz).
pub const MAG_NIS_MEAN_WEIGHT: f64 = 0.01;
/// Weight of each sample in the smoothed norm residual and direction (1 s at 100 Hz).
pub const MAG_NORM_SMOOTHING: f64 = 0.01;
/// Smallest sweep `|d - u_L|` of the field's body direction an offset is divided by (a unit
/// vector difference; 0.1 is 5.7 deg).
pub const MAG_MIN_SWEEP: f64 = 0.1;
/// Time constant over which a seen field offset is forgotten, s.
pub const MAG_OFFSET_MEMORY_S: f64 = 30.0;

/// The magnetometer's integrity monitor (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MagMonitor<T: Scalar> {
    /// Learned body direction `u_L` of the field (unit-ish; zero: not started).
    learned_direction: Vector3<T>,
    /// Smoothed body direction `d`.
    direction: Vector3<T>,
    /// Learned field norm `n_L`, sensor units (0: not started).
    learned_norm: T,
    /// Smoothed relative norm residual `e`.
    residual: T,
    /// Held relative offset `beta`, in `[0, 1]`.
    offset: T,
    /// The smoothed direction `d_s` where the residual was furthest beyond its tolerance since
    /// the held offset was last 0.
    seen_direction: Vector3<T>,
    /// Its excess beyond the tolerance there (0: none seen).
    seen_excess: T,
    /// The smoothed norm `N_s` there, sensor units.
    seen_norm: T,
    /// Mean NIS per degree of freedom less its expectation, `nu - 1` (zero bytes in a blank
    /// monitor).
    nis_excess: T,
    /// Samples the learned norm and direction are the mean of (saturating).
    learned_count: u32,
}

/// What one sample told the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct MagMonitorUpdate {
    /// The norm residual was beyond its tolerance.
    pub beyond: bool,
    /// A held offset was refuted (the norm changed by more than a body-fixed offset allows for
    /// the turn since it showed) and set to 0.
    pub cleared: bool,
}

/// One magnetometer sample as the monitor reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MagReading<T: Scalar> {
    /// The calibrated body field, sensor units.
    pub field_body: Vector3<T>,
    /// Whether the sample was fused (it then teaches the learned norm and direction).
    pub fused: bool,
    /// Its NIS per degree of freedom, at most its gate's (module docs).
    pub nis_per_dof: T,
    /// Interval since the previous sample, s.
    pub dt_s: T,
}

impl<T: Scalar> MagMonitor<T> {
    /// Not started: nothing learned, no offset, the NIS mean at its expectation.
    pub(crate) const EMPTY: Self = Self {
        learned_direction: zeros_const(),
        direction: zeros_const(),
        learned_norm: T::ZERO,
        residual: T::ZERO,
        offset: T::ZERO,
        seen_direction: zeros_const(),
        seen_excess: T::ZERO,
        seen_norm: T::ZERO,
        nis_excess: T::ZERO,
        learned_count: 0,
    };

    /// Started at the mean of `count` samples (the alignment's): `direction` the mean of
    /// their body unit directions, `norm` of their norms.
    pub(crate) fn started_at(direction: &Vector3<T>, norm: T, count: u32) -> Self {
        if !(direction.norm() > T::zero() && norm > T::zero()) {
            return Self::EMPTY;
        }
        let u = direction.normalize();
        Self {
            learned_direction: u,
            direction: u,
            learned_norm: norm,
            learned_count: count.max(1),
            ..Self::EMPTY
        }
    }

    /// One sample `s`; `learning_rate` the least weight `w` of a sample in the learned norm
    /// and direction, `noise_variance` the configured `mag_noise_variance` (unit field
    /// squared), `k1` the 1-D factor at the integrity risk. Returns whether the norm residual
    /// was beyond its tolerance, and whether a held offset was refuted (module docs).
    pub(crate) fn update(
        &mut self,
        s: &MagReading<T>,
        learning_rate: T,
        noise_variance: T,
        k1: T,
    ) -> MagMonitorUpdate {
        if s.nis_per_dof.is_finite() {
            let excess = s.nis_per_dof - T::one() - self.nis_excess;
            self.nis_excess += excess * T::lit(MAG_NIS_MEAN_WEIGHT);
        }
        let norm = s.field_body.norm();
        if !(norm > T::zero() && norm.is_finite()) {
            return MagMonitorUpdate::default();
        }
        let u = s.field_body / norm;
        if self.learned_count == 0 {
            *self = Self {
                nis_excess: self.nis_excess,
                offset: self.offset,
                ..Self::started_at(&u, norm, 1)
            };
        }
        let a = T::lit(MAG_NORM_SMOOTHING);
        self.residual += (norm / self.learned_norm - T::one() - self.residual) * a;
        self.direction += (u - self.direction) * a;
        if s.fused {
            let b = self.next_weight(learning_rate);
            self.learned_count = self.learned_count.saturating_add(1);
            self.learned_norm += (norm - self.learned_norm) * b;
            self.learned_direction += (u - self.learned_direction) * b;
        }
        let noise_variance = noise_variance.max(T::zero());
        let count = T::one() / T::lit(f64::from(self.learned_count));
        let learned = noise_variance * count.max(learning_rate);
        let smoothed = noise_variance * a / (T::lit(2.0) - a);
        let tolerance = k1 * (smoothed + learned).sqrt();
        let excess = self.residual.abs() - tolerance;
        let smoothed_norm = self.learned_norm * (T::one() + self.residual);
        let decay = (T::one() - s.dt_s.max(T::zero()) / T::lit(MAG_OFFSET_MEMORY_S)).max(T::zero());
        self.offset *= decay;
        if self.offset < tolerance {
            // Below what a whole sweep of the field's direction could show: forgotten.
            self.offset = T::zero();
        }
        let beyond = excess > T::zero();
        let mut cleared = false;
        if beyond {
            let sweep = (self.direction - self.learned_direction)
                .norm()
                .max(T::lit(MAG_MIN_SWEEP));
            self.offset = self.offset.max(excess / sweep).min(T::one());
            if excess > self.seen_excess {
                self.seen_direction = self.direction;
                self.seen_excess = excess;
                self.seen_norm = smoothed_norm;
            }
        } else if self.offset > T::zero() && self.seen_excess > T::zero() {
            let moved = (self.direction - self.seen_direction).norm();
            let changed = (smoothed_norm - self.seen_norm).abs() / self.learned_norm;
            if changed > moved + T::lit(core::f64::consts::SQRT_2) * k1 * smoothed.sqrt() {
                // More than a body-fixed offset can change the norm for that turn: not one.
                self.offset = T::zero();
                cleared = true;
            }
        }
        if self.offset <= T::zero() {
            self.seen_excess = T::zero();
        }
        MagMonitorUpdate { beyond, cleared }
    }

    /// The weight of the next fused sample in the learned norm and direction,
    /// `b_k = max(1 / k, w)` (`w` = `learning_rate`; module docs).
    pub(crate) fn next_weight(&self, learning_rate: T) -> T {
        let k = self.learned_count.saturating_add(1);
        learning_rate.max(T::one() / T::lit(f64::from(k)))
    }

    /// The samples the learned norm and direction are the mean of (saturating).
    pub(crate) fn learned_count(&self) -> u32 {
        self.learned_count
    }

    /// The held relative offset `beta` (module docs); 0 when none was seen.
    pub(crate) fn offset(&self) -> T {
        self.offset
    }

    /// The heading level's factor `sqrt(max(1, nu / nu_c))` at the 1-D factor `k1` (module
    /// docs).
    pub(crate) fn heading_factor(&self, k1: T) -> T {
        let w = T::lit(MAG_NIS_MEAN_WEIGHT);
        let consistent = T::one() + k1 * (T::lit(2.0) * w / (T::lit(2.0) - w)).sqrt();
        ((T::one() + self.nis_excess) / consistent)
            .max(T::one())
            .sqrt()
    }

    /// What the offset adds to the `(heading, tilt)` levels, rad, with the configured
    /// inclination `inclination_rad` (module docs).
    pub(crate) fn offset_shares(&self, inclination_rad: T) -> (T, T) {
        let beta = self.offset;
        if beta <= T::zero() {
            return (T::zero(), T::zero());
        }
        let horizontal = inclination_rad.cos().abs();
        let heading = if beta < horizontal {
            (beta / horizontal).asin()
        } else {
            T::frac_pi_2()
        };
        (heading, beta.min(T::one()).asin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic standard normal sequence (a 64-bit LCG through Box-Muller).
    struct Normal(u64);

    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }

        fn sample(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (2.0 * core::f64::consts::PI * v).cos()
        }
    }

    /// The Table 3 magnetometer: unit field, 0.02 per component.
    const NOISE: f64 = 0.02;
    /// The simulator's inclination (47 deg 14').
    const INCLINATION: f64 = 0.8244;
    /// The held offset above which the filters refuse the field: `sin(10 deg) cos I`.
    const REFUSAL: f64 = 0.1179;

    /// Feeds 100 Hz samples for `seconds` of a unit field at the simulator's inclination seen
    /// by a vehicle yawing +-20 deg and pitching +-15 deg (periods 45 s and 12 s), plus the
    /// body offset `offset`, the field scaled by `scale.2` from `scale.0` to `scale.1` s; every
    /// sample with NIS per dof `nis`, fused while the held offset is at most [`REFUSAL`].
    /// Returns the monitor, the samples beyond the tolerance and the held offsets cleared.
    fn run_scaled<T: Scalar>(
        seconds: f64,
        offset: [f64; 3],
        nis: f64,
        scale: (f64, f64, f64),
    ) -> (MagMonitor<T>, u32, u32) {
        let mut noise = Normal(7);
        let (si, ci) = INCLINATION.sin_cos();
        let field_at = |t: f64| {
            let yaw = 0.35 * (2.0 * core::f64::consts::PI * t / 45.0).sin();
            let pitch = 0.26 * (2.0 * core::f64::consts::PI * t / 12.0).sin();
            // NED field into the body: yaw then pitch (the field has no east part at yaw 0).
            let (n, d) = (ci * yaw.cos(), si);
            let e = -ci * yaw.sin();
            let (sp, cp) = pitch.sin_cos();
            [n * cp - d * sp, e, n * sp + d * cp]
        };
        let f0 = field_at(0.0);
        let start = (0..3)
            .map(|i| (f0[i] + offset[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        // The alignment's mean of 10 samples: its norm's noise bias `s^2 / |m|` included.
        let mut m = MagMonitor::<T>::started_at(
            &Vector3::from(core::array::from_fn(|i| T::lit(f0[i] + offset[i]))),
            T::lit(start + NOISE),
            10,
        );
        let (mut beyond, mut cleared) = (0, 0);
        for k in 0..(seconds * 100.0) as usize {
            let t = k as f64 * 0.01;
            let f = field_at(t);
            let factor = if (scale.0..scale.1).contains(&t) {
                scale.2
            } else {
                1.0
            };
            let b = Vector3::from(core::array::from_fn::<T, 3, _>(|i| {
                T::lit((f[i] + offset[i]) * factor + NOISE.sqrt() * noise.sample())
            }));
            let reading = MagReading {
                field_body: b,
                // As the filters fuse: not while the held offset can turn the heading beyond
                // its alert limit (10 deg here).
                fused: m.offset() <= T::lit(REFUSAL),
                nis_per_dof: T::lit(nis),
                dt_s: T::lit(0.01),
            };
            let update = m.update(&reading, T::lit(1e-3), T::lit(NOISE), T::lit(3.29));
            beyond += u32::from(update.beyond);
            cleared += u32::from(update.cleared);
        }
        (m, beyond, cleared)
    }

    /// [`run_scaled`] without the scaling.
    fn run<T: Scalar>(seconds: f64, offset: [f64; 3], nis: f64) -> (MagMonitor<T>, u32) {
        let (m, beyond, cleared) = run_scaled::<T>(seconds, offset, nis, (0.0, 0.0, 1.0));
        assert_eq!(
            cleared, 0,
            "a fixed field, or one with a body offset, is never cleared"
        );
        (m, beyond)
    }

    fn a_clean_field_leaves_the_levels_alone<T: Scalar>() {
        let (m, beyond) = run::<T>(120.0, [0.0; 3], 1.0);
        assert_eq!(beyond, 0);
        assert_eq!(m.offset_shares(T::lit(INCLINATION)), (T::zero(), T::zero()));
        assert_eq!(m.heading_factor(T::lit(3.29)), T::one());
    }

    fn a_hard_iron_offset_raises_the_heading_and_tilt_levels<T: Scalar>() {
        // The fault suite's hard iron: 0.3 of the field, horizontal, 45 deg right of forward.
        let h = 0.3 / 2f64.sqrt();
        let (m, beyond) = run::<T>(60.0, [h, h, 0.0], 1.0);
        assert!(beyond > 100, "{beyond}");
        let (heading, tilt) = m.offset_shares(T::lit(INCLINATION));
        // At least a quarter of the offset seen: a turn of the heading by 6 deg at least.
        assert!(heading.as_f64().to_degrees() > 6.0, "{heading:?}");
        assert!(tilt.as_f64() > 0.0 && tilt < heading, "{tilt:?}");
        assert!(m.offset().as_f64() <= 0.3 * 1.2, "{:?}", m.offset());
    }

    fn samples_at_the_gate_raise_the_heading_level<T: Scalar>() {
        let k1 = T::lit(3.29);
        let (m, _) = run::<T>(10.0, [0.0; 3], 9.0);
        let expected = (9.0 / (1.0 + 3.29 * (0.02f64 / 1.99).sqrt())).sqrt();
        let f = m.heading_factor(k1).as_f64();
        assert!((f - expected).abs() < 0.01 && f > 2.5, "{f}");
        // A mean within what a consistent filter shows leaves the level alone.
        let (m, _) = run::<T>(10.0, [0.0; 3], 1.3);
        assert_eq!(m.heading_factor(k1), T::one());
    }

    /// A held offset decays with its memory and, below the tolerance (0.036 here: a norm
    /// learned from 1,000 samples), is forgotten.
    fn a_seen_offset_is_forgotten_over_its_memory<T: Scalar>() {
        let mut m = MagMonitor::<T>::started_at(
            &Vector3::new(T::one(), T::zero(), T::one()),
            T::one(),
            1000,
        );
        m.offset = T::lit(0.2);
        let reading = MagReading {
            field_body: Vector3::new(T::lit(0.7), T::zero(), T::lit(0.7)),
            fused: true,
            nis_per_dof: T::one(),
            dt_s: T::lit(MAG_OFFSET_MEMORY_S / 2.0),
        };
        m.update(&reading, T::lit(1e-3), T::lit(NOISE), T::lit(3.29));
        assert!((m.offset().as_f64() - 0.1).abs() < 1e-6, "{:?}", m.offset());
        m.update(&reading, T::lit(1e-3), T::lit(NOISE), T::lit(3.29));
        assert!(
            (m.offset().as_f64() - 0.05).abs() < 1e-6,
            "{:?}",
            m.offset()
        );
        // 0.05 * 0.6 = 0.03, below the tolerance: 0, not 0.03.
        let reading = MagReading {
            dt_s: T::lit(MAG_OFFSET_MEMORY_S * 0.4),
            ..reading
        };
        m.update(&reading, T::lit(1e-3), T::lit(NOISE), T::lit(3.29));
        assert_eq!(m.offset(), T::zero());
    }

    /// A field 1.3 times its norm for 2 s, in the same direction (a steel structure passed):
    /// the monitor holds an offset while it lasts, and clears it once the norm is back, since
    /// no body-fixed offset changes the norm that much for so small a turn. The same run with
    /// the hard iron of the fault suite never clears it (`run` asserts that).
    fn a_passing_rise_of_the_norm_is_cleared<T: Scalar>() {
        let (m, beyond, cleared) = run_scaled::<T>(30.0, [0.0; 3], 1.0, (20.0, 22.0, 1.3));
        assert!(beyond > 100, "{beyond}");
        assert_eq!(cleared, 1);
        assert_eq!(m.offset(), T::zero());
        // Cut before the norm is back: the offset is still held.
        let (m, _, cleared) = run_scaled::<T>(21.9, [0.0; 3], 1.0, (20.0, 22.0, 1.3));
        assert_eq!(cleared, 0);
        assert!(m.offset() > T::lit(0.5), "{:?}", m.offset());
    }

    tests_in_both_precisions!(
        a_passing_rise_of_the_norm_is_cleared,
        a_clean_field_leaves_the_levels_alone,
        a_hard_iron_offset_raises_the_heading_and_tilt_levels,
        samples_at_the_gate_raise_the_heading_level,
        a_seen_offset_is_forgotten_over_its_memory
    );
}

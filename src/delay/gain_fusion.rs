//! Gain fusion of the three per-axis delay measurements (Table 2, corrected).
//!
//! State: the delay `tau` (s) and its variance `P` (s^2). One iteration, with
//! the three measurements `z_i` (the correlation peaks, s), validities
//! `V_i in {0, 1}`, measurement variances `R_i` and the gain weight `gamma`:
//!
//! ```text
//! local reset     tau_bar = tau,  P_bar = P + Q_f
//! measurement     K_i   = gamma P_bar (P_bar + gamma R_i)^-1
//!                 tau_i = tau_bar + V_i K_i (z_i - tau_bar)
//! global fusion   tau   = sum_i tau_i - (m - 1) tau_bar     (m = 3)
//!                 I_f   = 1 - sum_i V_i K_i
//!                 P     = I_f P_bar I_f + sum_i V_i K_i R_i K_i
//! ```
//!
//! Corrections to the paper's table: the inverse in `K_i` is missing there,
//! and the validity also gates the covariance terms (an axis left out must not
//! shrink `P`). With `gamma = 1/m` and all axes valid, `sum K_i` is the gain
//! of a Kalman filter fusing the average of the `m` measurements (variance
//! `R / m`), and `P` is its Joseph-form posterior.
//!
//! Units: the state is in seconds and seconds squared; `Q_f` and `R_i` are
//! given per iteration, in s^2, by the caller ([`DelayLoop`](super::DelayLoop)
//! derives them from its rate-independent configuration, see there). The
//! estimate is clamped to the configured range `[min, max]`, and `P` is
//! capped at the variance of a uniform distribution over that range, so a
//! long hover cannot make it grow without bound.

use super::grid::{non_negative_finite, positive_finite};
use crate::error::Error;
use crate::scalar::Scalar;

/// Number of fused measurements (one per NED axis).
pub const AXES: usize = 3;

/// Configuration of the gain fusion.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct GainFusionConfig<T: Scalar> {
    /// Gain weight `gamma` (1/3: the three axes weigh the same).
    pub gamma: T,
    /// Smallest delay, s.
    pub delay_min_s: T,
    /// Largest delay, s.
    pub delay_max_s: T,
    /// Initial delay, s (e.g. from the offline calibration).
    pub initial_delay_s: T,
    /// Initial standard deviation of the delay, s.
    pub initial_std_s: T,
}

impl<T: Scalar> Default for GainFusionConfig<T> {
    fn default() -> Self {
        Self {
            gamma: T::lit(1.0 / 3.0),
            delay_min_s: T::zero(),
            delay_max_s: T::one(),
            initial_delay_s: T::lit(0.2),
            initial_std_s: T::lit(0.3),
        }
    }
}

impl<T: Scalar> GainFusionConfig<T> {
    /// Every field zero: the placeholder of a blank value (never valid).
    pub(crate) const ZEROED: Self = Self {
        gamma: T::ZERO,
        delay_min_s: T::ZERO,
        delay_max_s: T::ZERO,
        initial_delay_s: T::ZERO,
        initial_std_s: T::ZERO,
    };

    /// Checks every field.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |field, reason| {
            Err(Error::InvalidConfig {
                field,
                value: None,
                bound: crate::error::Bound::Rule(reason),
            })
        };
        if !(positive_finite(self.gamma) && self.gamma <= T::one()) {
            return bad("gfa.gamma", "must be in (0, 1]");
        }
        if !(self.delay_min_s.is_finite()
            && self.delay_max_s.is_finite()
            && self.delay_min_s < self.delay_max_s)
        {
            return bad("gfa.delay_range", "needs finite min < max");
        }
        if !(self.initial_delay_s >= self.delay_min_s && self.initial_delay_s <= self.delay_max_s) {
            return bad("gfa.initial_delay_s", "must lie in the delay range");
        }
        if !positive_finite(self.initial_std_s) {
            return bad("gfa.initial_std_s", "must be positive and finite");
        }
        Ok(())
    }
}

/// What one GFA iteration did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GainFusionStep<T: Scalar> {
    /// Local gains `K_i` (dimensionless), whether used or not.
    pub gains: [T; AXES],
    /// Innovations `z_i - tau_bar`, s.
    pub innovations_s: [T; AXES],
    /// Fused delay, s.
    pub delay_s: T,
    /// Fused variance, s^2.
    pub variance_s2: T,
}

/// The gain fusion state: delay and variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainFusion<T: Scalar> {
    config: GainFusionConfig<T>,
    delay_s: T,
    variance_s2: T,
}

impl<T: Scalar> GainFusion<T> {
    /// A fusion of a zeroed configuration: the blank value of the delay
    /// loop, replaced by [`new`](Self::new) before use.
    pub(crate) const BLANK: Self = Self {
        config: GainFusionConfig::ZEROED,
        delay_s: T::ZERO,
        variance_s2: T::ZERO,
    };

    /// A validated fusion at the configured initial delay.
    pub fn new(config: GainFusionConfig<T>) -> Result<Self, Error> {
        config.validate()?;
        Ok(Self {
            config,
            delay_s: config.initial_delay_s,
            variance_s2: config.initial_std_s * config.initial_std_s,
        })
    }

    /// Current delay, s.
    pub fn delay_s(&self) -> T {
        self.delay_s
    }

    /// Current variance, s^2.
    pub fn variance_s2(&self) -> T {
        self.variance_s2
    }

    /// The configuration.
    pub fn config(&self) -> &GainFusionConfig<T> {
        &self.config
    }

    /// Largest variance kept: a uniform distribution over the delay range.
    fn variance_cap(&self) -> T {
        let width = self.config.delay_max_s - self.config.delay_min_s;
        width * width / T::lit(12.0)
    }

    /// Restarts from `delay_s` with standard deviation `std_s` (e.g. after an
    /// offline calibration). Refused, state unchanged, when the delay is out
    /// of range or the std is not positive and finite.
    pub fn reset(&mut self, delay_s: T, std_s: T) -> Result<(), Error> {
        if !(delay_s.is_finite() && std_s.is_finite()) {
            return Err(Error::NonFinite { field: "gfa.reset" });
        }
        if delay_s < self.config.delay_min_s
            || delay_s > self.config.delay_max_s
            || std_s <= T::zero()
        {
            return Err(Error::OutOfRange {
                field: "gfa.reset",
                reason: "delay must be in the configured range and std positive",
            });
        }
        self.delay_s = delay_s;
        self.variance_s2 = (std_s * std_s).min(self.variance_cap());
        Ok(())
    }

    /// One iteration (module docs) with measurements `z_s` (s), validities
    /// `V_i`, process noise `Q_f` (s^2) and measurement variances `R_i`
    /// (s^2). Refused, state unchanged: a non-finite valid measurement, a
    /// negative or non-finite `Q_f`, a non-positive or non-finite `R_i`.
    pub fn step(
        &mut self,
        z_s: [T; AXES],
        valid: [bool; AXES],
        process_noise_s2: T,
        measurement_noise_s2: [T; AXES],
    ) -> Result<GainFusionStep<T>, Error> {
        if z_s.iter().zip(valid).any(|(z, v)| v && !z.is_finite()) {
            return Err(Error::NonFinite {
                field: "gfa.measurement",
            });
        }
        if !(non_negative_finite(process_noise_s2)
            && measurement_noise_s2.iter().all(|r| positive_finite(*r)))
        {
            return Err(Error::OutOfRange {
                field: "gfa.noise",
                reason: "Q_f must be finite and >= 0, R_i positive and finite",
            });
        }
        let tau_bar = self.delay_s;
        let p_bar = (self.variance_s2 + process_noise_s2).min(self.variance_cap());
        let gamma = self.config.gamma;
        let mut gains = [T::zero(); AXES];
        let mut innovations_s = [T::zero(); AXES];
        let mut correction = T::zero();
        let mut gain_sum = T::zero();
        let mut noise_terms = T::zero();
        for axis in 0..AXES {
            let r = measurement_noise_s2[axis];
            let k = gamma * p_bar / (p_bar + gamma * r);
            gains[axis] = k;
            if valid[axis] {
                innovations_s[axis] = z_s[axis] - tau_bar;
                correction += k * innovations_s[axis];
                gain_sum += k;
                noise_terms += k * r * k;
            }
        }
        let i_f = T::one() - gain_sum;
        self.delay_s =
            (tau_bar + correction).clamp(self.config.delay_min_s, self.config.delay_max_s);
        self.variance_s2 = (i_f * p_bar * i_f + noise_terms).min(self.variance_cap());
        Ok(GainFusionStep {
            gains,
            innovations_s,
            delay_s: self.delay_s,
            variance_s2: self.variance_s2,
        })
    }
}

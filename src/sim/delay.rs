//! The GPS delay of the simulated receiver.
//!
//! A fix received at time `t` (on the IMU clock) describes the vehicle at
//! `t - tau(t)`, with
//!
//! ```text
//! tau(t) = clamp(tau_0 + drift * t + sum_{steps, t_i <= t} delta_i
//!                + sum_{ramps} delta_r * clamp((t - t_r) / T_r, 0, 1) + e_k,  MIN_DELAY_S, MAX_DELAY_S)
//! e_k    = sigma z_k + w (2 Phi(z_k) - 1)
//! ```
//!
//! where `z_k ~ N(0, 1)` is drawn once per fix, so `e_k` is the sum of a
//! white normal jitter of standard deviation `sigma` (`jitter_std_s`) and,
//! through the normal CDF `Phi`, a uniform jitter on `[-w, w]`
//! (`jitter_uniform_half_width_s`; the two share their draw, so use one at a
//! time). A negative delay is a GPS whose fixes describe a later instant
//! than their receive time (a clock misalignment: the positions lead the
//! IMU). The deterministic part (all but the jitter) is
//! [`DelayProfile::nominal_s`]; the truth record at IMU rate carries it, and
//! every simulated fix carries its own delay, jitter included. The default
//! is the paper's Table 3 maximum, a constant 0.2 s.

/// Largest delay the profile produces, seconds.
pub const MAX_DELAY_S: f64 = 1.0;

/// Smallest delay the profile produces, seconds (negative: fixes ahead of
/// the IMU clock).
pub const MIN_DELAY_S: f64 = -1.0;

/// A step change of the delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayStep {
    /// When the step happens, seconds from the start of the run.
    pub at_s: f64,
    /// Change of the delay, seconds (either sign).
    pub change_s: f64,
}

/// A linear change of the delay over a bounded interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayRamp {
    /// When the ramp starts, seconds from the start of the run.
    pub start_s: f64,
    /// How long it lasts, seconds (> 0).
    pub duration_s: f64,
    /// Total change at its end, seconds (either sign).
    pub change_s: f64,
}

impl DelayRamp {
    /// The part of the change reached at `t_s`, seconds.
    pub fn at(&self, t_s: f64) -> f64 {
        self.change_s * ((t_s - self.start_s) / self.duration_s).clamp(0.0, 1.0)
    }
}

/// How the GPS delay evolves over a run.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayProfile {
    /// Delay at `t = 0`, seconds.
    pub initial_s: f64,
    /// Slow linear drift, seconds per second.
    pub drift_s_per_s: f64,
    /// Step changes.
    pub steps: Vec<DelayStep>,
    /// Bounded linear changes.
    pub ramps: Vec<DelayRamp>,
    /// Standard deviation of the per-fix white normal jitter, seconds.
    pub jitter_std_s: f64,
    /// Half-width of the per-fix white uniform jitter, seconds.
    pub jitter_uniform_half_width_s: f64,
}

impl Default for DelayProfile {
    fn default() -> Self {
        Self::constant(0.2)
    }
}

impl DelayProfile {
    /// A constant delay, seconds.
    pub fn constant(delay_s: f64) -> Self {
        Self {
            initial_s: delay_s,
            drift_s_per_s: 0.0,
            steps: Vec::new(),
            ramps: Vec::new(),
            jitter_std_s: 0.0,
            jitter_uniform_half_width_s: 0.0,
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), crate::Error> {
        use crate::Error::InvalidConfig;
        if !(self.initial_s.is_finite() && (MIN_DELAY_S..=MAX_DELAY_S).contains(&self.initial_s)) {
            return Err(InvalidConfig {
                field: "delay.initial_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be in [-1, 1] s"),
            });
        }
        if !self.drift_s_per_s.is_finite() {
            return Err(InvalidConfig {
                field: "delay.drift_s_per_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite"),
            });
        }
        if self
            .steps
            .iter()
            .any(|s| !s.at_s.is_finite() || !s.change_s.is_finite())
        {
            return Err(InvalidConfig {
                field: "delay.steps".into(),
                value: None,
                bound: crate::error::Bound::Rule("times and changes must be finite"),
            });
        }
        if self.ramps.iter().any(|r| {
            !(r.start_s.is_finite()
                && r.change_s.is_finite()
                && r.duration_s.is_finite()
                && r.duration_s > 0.0)
        }) {
            return Err(InvalidConfig {
                field: "delay.ramps".into(),
                value: None,
                bound: crate::error::Bound::Rule(
                    "times and changes must be finite, durations positive",
                ),
            });
        }
        if !(self.jitter_std_s.is_finite() && self.jitter_std_s >= 0.0) {
            return Err(InvalidConfig {
                field: "delay.jitter_std_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and non-negative"),
            });
        }
        if !(self.jitter_uniform_half_width_s.is_finite()
            && self.jitter_uniform_half_width_s >= 0.0)
        {
            return Err(InvalidConfig {
                field: "delay.jitter_uniform_half_width_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and non-negative"),
            });
        }
        Ok(())
    }

    /// True when fixes carry a random jitter.
    pub fn has_jitter(&self) -> bool {
        self.jitter_std_s > 0.0 || self.jitter_uniform_half_width_s > 0.0
    }

    /// The jitter `e_k` (module docs) of one fix from its standard normal
    /// deviate `z`, seconds.
    pub fn jitter_s(&self, z: f64) -> f64 {
        let phi = 0.5 * (1.0 + libm::erf(z * core::f64::consts::FRAC_1_SQRT_2));
        self.jitter_std_s * z + self.jitter_uniform_half_width_s * (2.0 * phi - 1.0)
    }

    /// The delay without jitter at `t_s`, seconds, clamped to
    /// `[MIN_DELAY_S, MAX_DELAY_S]`.
    pub fn nominal_s(&self, t_s: f64) -> f64 {
        self.with_jitter_s(t_s, 0.0)
    }

    /// The delay at `t_s` with a jitter sample added, clamped to
    /// `[MIN_DELAY_S, MAX_DELAY_S]`.
    pub fn with_jitter_s(&self, t_s: f64, jitter_s: f64) -> f64 {
        let steps: f64 = self
            .steps
            .iter()
            .filter(|s| s.at_s <= t_s)
            .map(|s| s.change_s)
            .sum();
        let ramps: f64 = self.ramps.iter().map(|r| r.at(t_s)).sum();
        (self.initial_s + self.drift_s_per_s * t_s + steps + ramps + jitter_s)
            .clamp(MIN_DELAY_S, MAX_DELAY_S)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_is_linear_between_its_ends() {
        let p = DelayProfile {
            ramps: vec![DelayRamp {
                start_s: 10.0,
                duration_s: 60.0,
                change_s: 0.06,
            }],
            ..DelayProfile::constant(0.2)
        };
        assert_eq!(p.nominal_s(5.0), 0.2);
        assert!((p.nominal_s(40.0) - 0.23).abs() < 1e-12);
        assert!((p.nominal_s(100.0) - 0.26).abs() < 1e-12);
    }

    #[test]
    fn uniform_jitter_stays_in_its_band_and_fills_it() {
        let p = DelayProfile {
            jitter_uniform_half_width_s: 0.02,
            ..DelayProfile::constant(0.2)
        };
        let draws: Vec<f64> = (-400..=400).map(|k| p.jitter_s(k as f64 * 0.01)).collect();
        assert!(draws.iter().all(|e| e.abs() <= 0.02));
        assert!(draws.iter().any(|e| *e > 0.0199) && draws.iter().any(|e| *e < -0.0199));
        assert_eq!(p.jitter_s(0.0), 0.0);
    }

    #[test]
    fn negative_delay_is_allowed_and_clamped_at_minus_one() {
        let p = DelayProfile::constant(-0.15);
        assert!(p.validate().is_ok());
        assert_eq!(p.nominal_s(3.0), -0.15);
        assert_eq!(p.with_jitter_s(3.0, -2.0), MIN_DELAY_S);
        assert!(DelayProfile::constant(-1.5).validate().is_err());
    }
}

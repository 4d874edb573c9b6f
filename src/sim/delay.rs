//! The GPS delay of the simulated receiver.
//!
//! A fix received at time `t` (on the IMU clock) describes the vehicle at
//! `t - tau(t)`, with
//!
//! ```text
//! tau(t) = clamp(tau_0 + drift * t + sum_{steps with t_i <= t} delta_i + e_k, 0, tau_max)
//! ```
//!
//! where `e_k ~ N(0, jitter_std^2)` is drawn once per fix (white jitter) and
//! `tau_max` = 1 s keeps the delay physical. The deterministic part (all but
//! the jitter) is [`DelayProfile::nominal_s`]; the truth record at IMU rate
//! carries it, and every simulated fix carries its own delay, jitter
//! included. The default is the paper's Table 3 maximum, a constant 0.2 s.

/// Largest delay the profile produces, seconds.
pub const MAX_DELAY_S: f64 = 1.0;

/// A step change of the delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayStep {
    /// When the step happens, seconds from the start of the run.
    pub at_s: f64,
    /// Change of the delay, seconds (either sign).
    pub change_s: f64,
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
    /// Standard deviation of the per-fix white jitter, seconds.
    pub jitter_std_s: f64,
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
            jitter_std_s: 0.0,
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), crate::Error> {
        use crate::Error::InvalidConfig;
        if !(self.initial_s.is_finite() && (0.0..=MAX_DELAY_S).contains(&self.initial_s)) {
            return Err(InvalidConfig {
                field: "delay.initial_s",
                reason: "must be in [0, 1] s",
            });
        }
        if !self.drift_s_per_s.is_finite() {
            return Err(InvalidConfig {
                field: "delay.drift_s_per_s",
                reason: "must be finite",
            });
        }
        if self
            .steps
            .iter()
            .any(|s| !s.at_s.is_finite() || !s.change_s.is_finite())
        {
            return Err(InvalidConfig {
                field: "delay.steps",
                reason: "times and changes must be finite",
            });
        }
        if !(self.jitter_std_s.is_finite() && self.jitter_std_s >= 0.0) {
            return Err(InvalidConfig {
                field: "delay.jitter_std_s",
                reason: "must be finite and non-negative",
            });
        }
        Ok(())
    }

    /// The delay without jitter at `t_s`, seconds, clamped to `[0, 1]`.
    pub fn nominal_s(&self, t_s: f64) -> f64 {
        self.with_jitter_s(t_s, 0.0)
    }

    /// The delay at `t_s` with a jitter sample added, clamped to `[0, 1]`.
    pub fn with_jitter_s(&self, t_s: f64, jitter_s: f64) -> f64 {
        let steps: f64 = self
            .steps
            .iter()
            .filter(|s| s.at_s <= t_s)
            .map(|s| s.change_s)
            .sum();
        (self.initial_s + self.drift_s_per_s * t_s + steps + jitter_s).clamp(0.0, MAX_DELAY_S)
    }
}

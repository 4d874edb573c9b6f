//! Delta angle and delta velocity over a filter step, accumulated from IMU
//! samples with coning and sculling corrections: the input of a filter that
//! predicts at a lower rate than the IMU's ([`Ekf16::push_imu_deltas`]).
//!
//! # Model
//! Between two samples `k-1` and `k` (times `t_{k-1}`, `t_k`, step
//! `h = t_k - t_{k-1}` in s) the rate `w` (rad/s) and the specific force `f`
//! (m/s²), both in the body frame FRD, are taken linear in time. The
//! accumulation runs over the samples of one filter step `[t_0, t_n]` and
//! expresses everything in the body frame at `t_0`:
//!
//! ```text
//! dθ_k = h (w_{k-1} + w_k) / 2           rad, the rate integrated over the sample step
//! dv_k = h (f_{k-1} + f_k) / 2           m/s, the specific force integrated
//! α_k  = α_{k-1} + dθ_k                   rad, Σ dθ (α_0 = 0)
//! υ_k  = υ_{k-1} + dv_k                   m/s, Σ dv (υ_0 = 0)
//! β_k  = β_{k-1} + 1/2 α_{k-1} × dθ_k + h²/12 w_{k-1} × w_k                       (coning)
//! σ_k  = σ_{k-1} + 1/2 (α_{k-1} × dv_k + υ_{k-1} × dθ_k)
//!              + h²/12 (w_{k-1} × f_k + f_{k-1} × w_k)                           (sculling)
//!
//! Δθ = α_n + β_n                          rad, the rotation vector from body(t_0) to body(t_n)
//! Δv = υ_n + 1/2 α_n × υ_n + σ_n          m/s, ∫ C(t_0 → t) f dt in body(t_0)
//! ```
//!
//! These are the first-order solutions of the rotation-vector equation
//! `φ' = w + 1/2 φ × w` and of `Δv = ∫ (I + [α(t)×]) f dt`, with
//! `∫ α × f dt = 1/2 α × υ + 1/2 ∫ (α × f + υ × w) dt`; the `h²/12` terms are
//! the exact integrals of `1/2 α × w` and `1/2 (α × f + υ × w)` inside one
//! sample step for linear `w` and `f` (the `α` and `υ` accumulated since
//! `t_{k-1}` are quadratic in time there). What is left is of second order
//! in `|Δθ|` (`|Δθ|² / 12` relative): `5e-6` at 1 rad/s over 10 ms. Without
//! the corrections (`Δθ = α`, `Δv = υ`) a coning motion drifts the attitude
//! and a sculling motion the velocity at every step
//! (`tests/ekf16_deltas.rs` has both against a simulated truth).
//!
//! The accumulation is driven by the timestamps: a dropped sample, jitter or
//! a rate change only changes `h`.
//!
//! [`Ekf16::push_imu_deltas`]: super::Ekf16::push_imu_deltas

use crate::scalar::{Scalar, us_to_s, zeros_const};
use crate::sensors::Imu;
use nalgebra::Vector3;

/// Delta angle and delta velocity over `[t_start_us, t_us]`, in the body
/// frame at `t_start_us` (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuDeltas<T: Scalar> {
    /// Start of the step, µs.
    pub t_start_us: u64,
    /// Rotation vector from the body at the start to the body at the end, rad.
    pub delta_angle_rad: Vector3<T>,
    /// Integrated specific force in the body frame at the start, m/s.
    pub delta_velocity_m_s: Vector3<T>,
    /// The last sample of the step (its time ends the step).
    pub last: Imu<T>,
}

impl<T: Scalar> ImuDeltas<T> {
    /// End of the step, µs.
    pub fn t_us(&self) -> u64 {
        self.last.t_us
    }

    /// Length of the step, µs.
    pub fn dt_us(&self) -> u64 {
        self.last.t_us.saturating_sub(self.t_start_us)
    }
}

/// Sums of the accumulation (module docs' symbols).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sums<T: Scalar> {
    alpha: Vector3<T>,
    upsilon: Vector3<T>,
    coning: Vector3<T>,
    sculling: Vector3<T>,
    /// `Σ h²` over the sample steps, s² (the white noise's share of the step, below).
    spacing_sq: T,
}

impl<T: Scalar> Sums<T> {
    const ZERO: Self = Self {
        alpha: zeros_const(),
        upsilon: zeros_const(),
        coning: zeros_const(),
        sculling: zeros_const(),
        spacing_sq: T::ZERO,
    };
}

/// Accumulates IMU samples into [`ImuDeltas`] (module docs). No storage
/// beyond the sums; `O(1)` per sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeltaAccumulator<T: Scalar> {
    start_us: Option<u64>,
    last: Option<Imu<T>>,
    sums: Sums<T>,
    /// Coning and sculling corrections off (false: a blank value is zero
    /// bytes).
    uncorrected: bool,
}

impl<T: Scalar> Default for DeltaAccumulator<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Scalar> DeltaAccumulator<T> {
    /// An empty accumulator with coning and sculling corrections.
    pub const fn new() -> Self {
        Self {
            start_us: None,
            last: None,
            sums: Sums::ZERO,
            uncorrected: false,
        }
    }

    /// An empty accumulator without the corrections (`Δθ = α`, `Δv = υ`):
    /// for comparison only.
    pub fn uncorrected() -> Self {
        Self {
            uncorrected: true,
            ..Self::new()
        }
    }

    /// Starts a new step at sample `s` (its time and values), dropping what
    /// was accumulated.
    pub fn restart(&mut self, s: &Imu<T>) {
        self.start_us = Some(s.t_us);
        self.last = Some(*s);
        self.sums = Sums::ZERO;
    }

    /// Forgets everything, including the start sample.
    pub fn clear(&mut self) {
        *self = Self {
            uncorrected: self.uncorrected,
            ..Self::new()
        };
    }

    /// Time of the step's start, µs (`None` before the first sample).
    pub fn start_us(&self) -> Option<u64> {
        self.start_us
    }

    /// Time of the newest sample, µs.
    pub fn end_us(&self) -> Option<u64> {
        self.last.map(|s| s.t_us)
    }

    /// Length of the accumulated step, µs.
    pub fn elapsed_us(&self) -> u64 {
        match (self.start_us, self.last) {
            (Some(start), Some(last)) => last.t_us.saturating_sub(start),
            _ => 0,
        }
    }

    /// Adds sample `s`. The first sample (or one not later than the newest)
    /// starts a new step instead.
    pub fn push(&mut self, s: &Imu<T>) {
        let Some(prev) = self.last.filter(|p| s.t_us > p.t_us) else {
            self.restart(s);
            return;
        };
        let h: T = us_to_s(s.t_us - prev.t_us);
        let half = T::lit(0.5);
        let d_theta = (prev.gyro_rad_s + s.gyro_rad_s) * (h * half);
        let d_v = (prev.accel_m_s2 + s.accel_m_s2) * (h * half);
        let sums = &mut self.sums;
        if !self.uncorrected {
            let h2_12 = h * h / T::lit(12.0);
            sums.coning +=
                sums.alpha.cross(&d_theta) * half + prev.gyro_rad_s.cross(&s.gyro_rad_s) * h2_12;
            sums.sculling += (sums.alpha.cross(&d_v) + sums.upsilon.cross(&d_theta)) * half
                + (prev.gyro_rad_s.cross(&s.accel_m_s2) + prev.accel_m_s2.cross(&s.gyro_rad_s))
                    * h2_12;
        }
        sums.alpha += d_theta;
        sums.upsilon += d_v;
        sums.spacing_sq += h * h;
        self.last = Some(*s);
    }

    /// `Σ h²` of the sample steps accumulated so far, s²: white noise of per-sample
    /// variance `σ²` adds `σ² Σ h²` to the variance of `Δθ` (or `Δv`), so `Σ h² / Δt` is the
    /// period at which its density `σ² h` is to be read (the mean period when it is steady,
    /// more when the steps are uneven).
    pub(crate) fn spacing_sq_s2(&self) -> T {
        self.sums.spacing_sq
    }

    /// The accumulated step (`None` when it is empty), and a new step
    /// started at its last sample.
    pub fn take(&mut self) -> Option<ImuDeltas<T>> {
        let (Some(start), Some(last)) = (self.start_us, self.last) else {
            return None;
        };
        if last.t_us <= start {
            return None;
        }
        let s = self.sums;
        let (delta_angle_rad, delta_velocity_m_s) = if !self.uncorrected {
            (
                s.alpha + s.coning,
                s.upsilon + s.alpha.cross(&s.upsilon) * T::lit(0.5) + s.sculling,
            )
        } else {
            (s.alpha, s.upsilon)
        };
        self.restart(&last);
        Some(ImuDeltas {
            t_start_us: start,
            delta_angle_rad,
            delta_velocity_m_s,
            last,
        })
    }
}

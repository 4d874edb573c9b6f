//! Linear-phase FIR for the accelerometer and gyroscope noise whitening (sec. 2.2.4).
//!
//! Motor vibration puts narrow-band, high-frequency energy into the MEMS
//! accelerometer and gyroscope; the paper low-passes both with FIR filters so
//! their noise is close to white at the rates the EKF sees. The filter is
//!
//! ```text
//! y[k] = sum_{i=0}^{TAPS-1} h[i] x[k-i],   h[i] = h[TAPS-1-i]   (symmetric)
//! ```
//!
//! A symmetric impulse response has exactly linear phase,
//! `H(e^{jw}) = e^{-jw D} A(w)` with `A` real and `D = (TAPS - 1) / 2`
//! samples: every frequency is delayed by the same group delay `D`, which is
//! what lets eq. (15) compensate it with a pure delay
//! (see [`SensorDelays`](super::SensorDelays)).
//!
//! [`WhiteningFir::low_pass`] designs `h` as a Hamming-windowed sinc:
//!
//! ```text
//! h[i] = 2 fc/fs sinc(2 fc/fs (i - D)) (0.54 - 0.46 cos(2 pi i / (TAPS - 1))),
//! ```
//!
//! normalized to unit DC gain (`sum h = 1`), so a constant (gravity, a bias)
//! passes unchanged. [`WhiteningFir::from_coefficients`] takes user
//! coefficients (e.g. designed for a measured vibration spectrum) and checks
//! they are symmetric.

use nalgebra::Vector3;

use super::ring::Ring;
use crate::error::Error;
use crate::scalar::{Scalar, all_finite};

/// Symmetric (linear-phase) FIR filter of `TAPS` coefficients on a 3-axis
/// sensor stream.
#[derive(Debug, Clone)]
pub struct WhiteningFir<T: Scalar, const TAPS: usize> {
    coefficients: [T; TAPS],
    history: Ring<Vector3<T>, TAPS>,
}

impl<T: Scalar, const TAPS: usize> WhiteningFir<T, TAPS> {
    /// Hamming-windowed sinc low-pass with cutoff `cutoff_hz` for samples at
    /// `sample_rate_hz`, unit DC gain.
    ///
    /// Errors: non-finite or non-positive rates, cutoff not below Nyquist.
    pub fn low_pass(cutoff_hz: T, sample_rate_hz: T) -> Result<Self, Error> {
        const { assert!(TAPS >= 1, "a FIR needs at least one tap") };
        if !(sample_rate_hz.is_finite() && sample_rate_hz > T::zero()) {
            return Err(Error::InvalidConfig {
                field: "fir.sample_rate_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be positive and finite"),
            });
        }
        if !(cutoff_hz.is_finite()
            && cutoff_hz > T::zero()
            && cutoff_hz < sample_rate_hz * T::lit(0.5))
        {
            return Err(Error::InvalidConfig {
                field: "fir.cutoff_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be positive and below half the sample rate"),
            });
        }
        let fc = (cutoff_hz / sample_rate_hz).as_f64();
        let centre = (TAPS as f64 - 1.0) / 2.0;
        let mut h = [0.0f64; TAPS];
        let mut sum = 0.0;
        for (i, hi) in h.iter_mut().enumerate() {
            let x = i as f64 - centre;
            let arg = 2.0 * fc * x;
            let sinc = if x == 0.0 {
                1.0
            } else {
                let a = core::f64::consts::PI * arg;
                <f64 as nalgebra::ComplexField>::sin(a) / a
            };
            let window = if TAPS == 1 {
                1.0
            } else {
                0.54 - 0.46
                    * <f64 as nalgebra::ComplexField>::cos(
                        2.0 * core::f64::consts::PI * i as f64 / (TAPS as f64 - 1.0),
                    )
            };
            *hi = 2.0 * fc * sinc * window;
            sum += *hi;
        }
        let coefficients = h.map(|v| T::lit(v / sum));
        Ok(Self::with(coefficients))
    }

    /// A filter with the given coefficients, which must be finite and
    /// symmetric (`h[i] == h[TAPS-1-i]` within a relative 1e-6 of the
    /// largest magnitude) so the phase is linear.
    pub fn from_coefficients(coefficients: [T; TAPS]) -> Result<Self, Error> {
        if coefficients.iter().any(|c| !c.is_finite()) {
            return Err(Error::NonFinite {
                field: "fir.coefficients",
            });
        }
        let scale = coefficients.iter().fold(T::zero(), |m, c| m.max(c.abs()));
        let tolerance = scale * T::lit(1e-6);
        if (0..TAPS / 2).any(|i| (coefficients[i] - coefficients[TAPS - 1 - i]).abs() > tolerance) {
            return Err(Error::InvalidConfig {
                field: "fir.coefficients".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be symmetric (linear phase)"),
            });
        }
        Ok(Self::with(coefficients))
    }

    fn with(coefficients: [T; TAPS]) -> Self {
        Self {
            coefficients,
            history: Ring::new(Vector3::zeros()),
        }
    }

    /// The coefficients `h[0..TAPS]`.
    pub fn coefficients(&self) -> &[T; TAPS] {
        &self.coefficients
    }

    /// Group delay `(TAPS - 1) / 2`, samples.
    pub fn group_delay_samples(&self) -> T {
        T::lit((TAPS as f64 - 1.0) / 2.0)
    }

    /// Group delay in seconds for samples at `sample_rate_hz`: the `D_f` or
    /// `D_w` of eq. (15).
    pub fn group_delay_s(&self, sample_rate_hz: T) -> T {
        self.group_delay_samples() / sample_rate_hz
    }

    /// Filters one sample. The first sample fills the whole history (no
    /// start-up step from zero on a gravity-dominated accelerometer). A
    /// non-finite sample is refused and the filter is unchanged.
    pub fn filter(&mut self, x: Vector3<T>) -> Result<Vector3<T>, Error> {
        if !all_finite(&x) {
            return Err(Error::NonFinite { field: "fir.input" });
        }
        if self.history.len() == 0 {
            for _ in 0..TAPS {
                self.history.push(x);
            }
        } else {
            self.history.push(x);
        }
        let mut y = Vector3::zeros();
        for (age, h) in self.coefficients.iter().enumerate() {
            if let Some(past) = self.history.get(age) {
                y += past * *h;
            }
        }
        Ok(y)
    }

    /// Forgets the history (the next sample refills it).
    pub fn reset(&mut self) {
        self.history.clear();
    }
}

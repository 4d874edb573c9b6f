//! A multi-channel delay line read at fractional delays (Lagrange interpolation).
//!
//! # Model
//!
//! Samples `x[k]` (each a vector of `CH` channels) arrive at a uniform period
//! `h`. A read at delay `d >= 0` samples (measured back from the newest sample,
//! which has delay 0) returns the Lagrange polynomial of order `p = ORDER`
//! through `p + 1` consecutive stored samples, evaluated at `d`:
//!
//! ```text
//! y(d) = sum_{j=0}^{p} w_j(t) x[newest - (s0 + j)],   t = d - s0 in [0, p],
//! w_j(t) = prod_{m != j} (t - m) / (j - m)
//! ```
//!
//! The stencil start `s0 = floor(d) - (p - 1) / 2` centres the stencil on the
//! read position; it is clamped to `[0, len - 1 - p]`, so near the newest
//! sample and near the oldest one the stencil is one-sided (never an
//! extrapolation). A read costs `p + 1` taps and `O(p^2)` weight arithmetic,
//! whatever the delay: the delay only selects where the stencil starts.
//!
//! # Error bound
//!
//! For a signal with `|x^(p+1)| <= A w^(p+1)` (e.g. a sine of amplitude `A`
//! and angular frequency `w`, or any signal band-limited to `w` with peak
//! `A`), Lagrange's remainder gives, with `wh = w h` (radians per sample),
//!
//! ```text
//! |y(d) - x(t_newest - d h)| <= A (wh)^(p+1) / (p+1)! * prod_{j=0}^{p} |t - j|
//! ```
//!
//! [`FractionalDelayLine::error_bound`] evaluates it for the actual read. With
//! a centred cubic stencil (`p = 3`, `t` in `[1, 2]`) the product is at most
//! `9/16`, so the bound is `0.0234 A (wh)^4`: at 1 kHz a 10 Hz sine
//! (`wh = 0.063`) is delayed with a relative error below `3.7e-7`; at 50 Hz
//! a 2 Hz motion (`wh = 0.25`) below `9.4e-5`. On the one-sided stencil of
//! the first sample (`d < 1`) the product reaches about 1 (twice as much).
//!
//! # Timing
//!
//! The line is indexed by samples and assumes a uniform rate. To read at a
//! delay in seconds ([`FractionalDelayLine::read_seconds`]) the caller passes
//! the sample period, estimated as the long-run mean of the timestamp
//! differences. Logging jitter (about +-2 ms at 50 Hz on the real log) is then
//! a zero-mean timing noise on individual samples, which the estimate averages
//! out; interpolating on the jittered timestamps instead would build the
//! timestamp noise into every read. That holds for logged timestamps that
//! jitter around a uniform sampling; when the samples themselves are
//! irregular (dropped samples, a rate change, sampling jitter with correct
//! stamps) the mean period moves every later read, and the reader should
//! map its time to a fractional index itself and call
//! [`FractionalDelayLine::read`], as the delay-compensated navigator does
//! (`src/nav/timeline.rs`: 10 % dropped samples cost 18x tilt RMSE with
//! the mean period).

use nalgebra::SVector;

use super::ring::Ring;
use crate::error::Error;
use crate::scalar::{Scalar, all_finite, zeros_const};

/// Ring buffer of `CH`-channel samples, read at any fractional delay with
/// Lagrange interpolation of order `ORDER` through `N` stored samples.
///
/// The delay is a read argument, so it changes at run time with no
/// reallocation. Reading further back than the stored history is an
/// [`Error::DelayBeyondHistory`], never a silent clamp.
///
/// ```
/// use delaynav::delay::FractionalDelayLine;
/// use nalgebra::Vector1;
/// let mut line = FractionalDelayLine::<f64, 1, 16, 3>::new();
/// for k in 0..10 {
///     line.push(Vector1::new(2.0 * k as f64)).unwrap();
/// }
/// // A ramp is reproduced exactly by any Lagrange order >= 1.
/// let y = line.read(2.25).unwrap();
/// assert!((y[0] - 2.0 * (9.0 - 2.25)).abs() < 1e-12);
/// assert!(line.read(9.5).is_err());
/// ```
#[derive(Debug, Clone)]
pub struct FractionalDelayLine<T: Scalar, const CH: usize, const N: usize, const ORDER: usize> {
    ring: Ring<SVector<T, CH>, N>,
}

impl<T: Scalar, const CH: usize, const N: usize, const ORDER: usize> Default
    for FractionalDelayLine<T, CH, N, ORDER>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Scalar, const CH: usize, const N: usize, const ORDER: usize>
    FractionalDelayLine<T, CH, N, ORDER>
{
    /// Number of samples one read combines (`ORDER + 1`).
    pub const TAPS: usize = ORDER + 1;

    /// An empty line (a `const fn`: usable in a `static` or a `const`
    /// blank value, with no stack temporary).
    pub const fn new() -> Self {
        const {
            assert!(ORDER >= 1, "Lagrange order must be at least 1");
            assert!(
                N > ORDER,
                "the line must hold more samples than the interpolation order"
            );
        };
        Self {
            ring: Ring::new(zeros_const()),
        }
    }

    /// Appends the newest sample; a non-finite sample is refused and the line
    /// is unchanged.
    pub fn push(&mut self, sample: SVector<T, CH>) -> Result<(), Error> {
        if !all_finite(&sample) {
            return Err(Error::NonFinite {
                field: "delay_line.sample",
            });
        }
        self.ring.push(sample);
        Ok(())
    }

    /// Number of stored samples.
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// True before the first sample.
    pub fn is_empty(&self) -> bool {
        self.ring.len() == 0
    }

    /// Capacity `N`.
    pub fn capacity(&self) -> usize {
        N
    }

    /// Forgets the history.
    pub fn clear(&mut self) {
        self.ring.clear();
    }

    /// The longest delay a read accepts now, samples: `len - 1` once at least
    /// `ORDER + 1` samples are stored, `None` before.
    pub fn max_delay_samples(&self) -> Option<usize> {
        (self.ring.len() > ORDER).then(|| self.ring.len() - 1)
    }

    /// The sample at `delay_samples` (>= 0, fractional) behind the newest one.
    ///
    /// Errors: non-finite or negative delay; [`Error::DelayBeyondHistory`]
    /// when fewer than `ORDER + 1` samples are stored or the delay exceeds
    /// `len - 1`.
    pub fn read(&self, delay_samples: T) -> Result<SVector<T, CH>, Error> {
        lagrange_read::<T, CH, ORDER>(self.ring.len(), |age| self.ring.get(age), delay_samples)
    }

    /// The sample `delay_s` seconds behind the newest one, for a uniform
    /// sample period `period_s` (see the module docs on timing).
    pub fn read_seconds(&self, delay_s: T, period_s: T) -> Result<SVector<T, CH>, Error> {
        if !(period_s.is_finite() && period_s > T::zero()) {
            return Err(Error::OutOfRange {
                field: "delay_line.period",
                reason: "the sample period must be positive and finite",
            });
        }
        if !delay_s.is_finite() {
            return Err(Error::NonFinite {
                field: "delay_line.delay",
            });
        }
        self.read(delay_s / period_s)
    }

    /// The Lagrange error bound of a read at `delay_samples` (module docs):
    /// `A (wh)^(p+1) / (p+1)! * prod_j |t - j|` for a signal of peak
    /// `amplitude` band-limited to `omega_h` radians per sample. `None` when
    /// the read itself would be refused.
    pub fn error_bound(&self, delay_samples: T, amplitude: T, omega_h: T) -> Option<T> {
        let (_, t) = stencil::<T, ORDER>(self.ring.len(), delay_samples).ok()?;
        let mut node_product = T::one();
        let mut factorial = T::one();
        for j in 0..=ORDER {
            node_product *= (t - T::lit(j as f64)).abs();
            factorial *= T::lit((j + 1) as f64);
        }
        Some(amplitude * omega_h.abs().powi((ORDER + 1) as i32) / factorial * node_product)
    }
}

/// Stencil start and local position `t = d - s0` of a read at
/// `delay_samples` from `len` stored samples (module docs).
pub(crate) fn stencil<T: Scalar, const ORDER: usize>(
    len: usize,
    delay_samples: T,
) -> Result<(usize, T), Error> {
    if !delay_samples.is_finite() {
        return Err(Error::NonFinite {
            field: "delay_line.delay",
        });
    }
    if delay_samples < T::zero() {
        return Err(Error::OutOfRange {
            field: "delay_line.delay",
            reason: "a delay cannot be negative",
        });
    }
    let beyond = || Error::DelayBeyondHistory {
        requested_samples: (delay_samples.as_f64() as u64).saturating_add(1),
        stored_samples: len as u64,
    };
    if len <= ORDER || delay_samples > T::lit((len - 1) as f64) {
        return Err(beyond());
    }
    let whole = delay_samples.floor().as_f64() as usize;
    let s0 = whole.saturating_sub((ORDER - 1) / 2).min(len - 1 - ORDER);
    Ok((s0, delay_samples - T::lit(s0 as f64)))
}

/// The Lagrange read of order `ORDER` at `delay_samples` from `len` samples
/// stored by age (`get(0)` the newest): the read of both delay lines,
/// [`FractionalDelayLine`] and the navigator's 16-bit one.
pub(crate) fn lagrange_read<T: Scalar, const CH: usize, const ORDER: usize>(
    len: usize,
    mut get: impl FnMut(usize) -> Option<SVector<T, CH>>,
    delay_samples: T,
) -> Result<SVector<T, CH>, Error> {
    let (s0, t) = stencil::<T, ORDER>(len, delay_samples)?;
    let mut out = SVector::<T, CH>::zeros();
    for j in 0..=ORDER {
        // s0 + j <= len - 1 by construction of the stencil.
        if let Some(x) = get(s0.wrapping_add(j)) {
            out += x * lagrange_weight::<T, ORDER>(j, t);
        }
    }
    Ok(out)
}

/// The weight `w_j(t)` of node `j` (module docs).
pub(crate) fn lagrange_weight<T: Scalar, const ORDER: usize>(j: usize, t: T) -> T {
    let mut w = T::one();
    for m in 0..=ORDER {
        if m != j {
            w *= (t - T::lit(m as f64)) / (T::lit(j as f64) - T::lit(m as f64));
        }
    }
    w
}

/// The long-run mean sample period of a stream, from its timestamps:
/// `(t_last - t_first) / (count - 1)`, `O(1)` per sample. This is the period
/// [`FractionalDelayLine::read_seconds`] expects (module docs, timing):
/// zero-mean timestamp jitter averages out. A dropped sample biases it (the
/// line's indices assume none are missing), so restart it after a gap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SamplePeriod {
    first_us: Option<u64>,
    last_us: u64,
    intervals: u64,
}

impl SamplePeriod {
    /// No samples yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a timestamp; refused (unchanged) unless later than the previous one.
    pub fn push(&mut self, t_us: u64) -> Result<(), Error> {
        if self.first_us.is_some() {
            crate::sensors::check_time("period", Some(self.last_us), t_us)?;
            self.intervals += 1;
        } else {
            self.first_us = Some(t_us);
        }
        self.last_us = t_us;
        Ok(())
    }

    /// The mean period, s, once two timestamps are in.
    pub fn period_s<T: Scalar>(&self) -> Option<T> {
        let first = self.first_us?;
        (self.intervals > 0)
            .then(|| T::lit((self.last_us - first) as f64 * 1e-6 / self.intervals as f64))
    }

    /// Forgets every timestamp.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

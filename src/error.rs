//! The crate's one error type.
//!
//! A refused input leaves the estimator exactly as it was, with one stated
//! exception: [`Error::StepTooLong`] (see its docs).

/// Why an input or a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A field of a sample was NaN or infinite.
    #[error("non-finite value in `{field}`")]
    NonFinite {
        /// The offending field, e.g. `"gyro"`, `"gps.velocity"`.
        field: &'static str,
    },
    /// A sample's timestamp is earlier than the previous one of the same stream.
    #[error("time went backwards on {stream}: previous {previous_us} us, got {got_us} us")]
    TimeWentBackwards {
        /// `"imu"`, `"gps"` or `"mag"`.
        stream: &'static str,
        /// Timestamp of the last accepted sample.
        previous_us: u64,
        /// Timestamp of the refused sample.
        got_us: u64,
    },
    /// A sample carries the same timestamp as the previous one of its stream.
    #[error("duplicate timestamp {t_us} us on {stream}")]
    DuplicateTimestamp {
        /// `"imu"`, `"gps"` or `"mag"`.
        stream: &'static str,
        /// The repeated timestamp.
        t_us: u64,
    },
    /// The IMU step is longer than the configured maximum.
    ///
    /// The one refusal that is not a no-op: the sample is not integrated,
    /// the state estimate is unchanged, but the filter's clock moves to the
    /// sample and the covariance grows by the process noise of the gap, so
    /// the next sample steps from here and the filter stays honest about the
    /// time it did not see.
    #[error("IMU step of {dt_us} us exceeds the maximum of {max_us} us")]
    StepTooLong {
        /// The refused step.
        dt_us: u64,
        /// The configured maximum.
        max_us: u64,
    },
    /// A configuration value is out of its valid range: which field, its
    /// value and the bound it broke, e.g.
    /// ``invalid configuration: `mode.initial_s` = 0.5, must lie in [0, 0.4]``.
    #[error("invalid configuration: `{field}`{shown}, {bound}", shown = ShownValue(*value))]
    InvalidConfig {
        /// The field, as a path from the configuration checked
        /// (`"delay_loop.fusion.delay_min_s"`, `"ekf.origin.lat_deg"`).
        field: &'static str,
        /// Its value (as `f64`; counts and flags too); `None` where the field
        /// is not a number.
        value: Option<f64>,
        /// The bound or rule it broke.
        bound: Bound,
    },
    /// The innovation covariance was not positive definite (Cholesky failed).
    #[error("innovation covariance of {measurement} is not positive definite")]
    NotPositiveDefinite {
        /// `"gps.position"`, `"gps.velocity"`, `"mag"`...
        measurement: &'static str,
    },
    /// A value outside the range the component supports.
    #[error("`{field}` out of range: {reason}")]
    OutOfRange {
        /// The offending quantity.
        field: &'static str,
        /// What the range is.
        reason: &'static str,
    },
    /// A read reached further back than the stored history.
    #[error("requested {requested_us} us of history, only {available_us} us stored")]
    HistoryExceeded {
        /// How far back the read reached.
        requested_us: u64,
        /// How far back the history goes.
        available_us: u64,
    },
    /// A fractional delay read reached further back than the stored samples.
    #[error("delay of {requested_samples} samples requested, only {stored_samples} samples stored")]
    DelayBeyondHistory {
        /// The requested delay, samples, rounded up.
        requested_samples: u64,
        /// Samples stored in the line.
        stored_samples: u64,
    },
    /// Too little data for a result.
    #[error("not enough data: {what}")]
    NotEnoughData {
        /// What was missing.
        what: &'static str,
    },
    /// The operation needs an initialized estimator.
    #[error("estimator not initialized")]
    NotInitialized,
    /// The estimator is a blank value (`BLANK`) that no successful
    /// `configure` has set up yet (or whose last `configure` failed): every
    /// sample is refused.
    #[error("estimator not configured (a blank value: call configure)")]
    NotConfigured,
}

impl Error {
    /// [`Error::NotConfigured`], built off the hot path: the check every
    /// push makes first then costs its callers no code layout.
    #[cold]
    pub(crate) fn not_configured() -> Self {
        Self::NotConfigured
    }
}

/// The bound a configuration value broke (see [`Error::InvalidConfig`]).
/// Bounds that come from other fields carry those fields' values.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Bound {
    /// Must be finite.
    Finite,
    /// Must be `> 0` (`+inf` allowed).
    Positive,
    /// Must be `> 0` and finite.
    PositiveFinite,
    /// Must be `>= 0` and finite.
    NotNegative,
    /// Must be `>= limit` (and finite).
    AtLeast(f64),
    /// Must be `<= limit`.
    AtMost(f64),
    /// Must be `> limit`.
    Above(f64),
    /// Must be `< limit`.
    Below(f64),
    /// Must lie in `[lo, hi]`.
    Within(f64, f64),
    /// A rule stated in words (relations between fields, capacities).
    Rule(&'static str),
}

impl core::fmt::Display for Bound {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Finite => f.write_str("must be finite"),
            Self::Positive => f.write_str("must be positive"),
            Self::PositiveFinite => f.write_str("must be positive and finite"),
            Self::NotNegative => f.write_str("must be finite and >= 0"),
            Self::AtLeast(l) => write!(f, "must be >= {}", Number(l)),
            Self::AtMost(l) => write!(f, "must be <= {}", Number(l)),
            Self::Above(l) => write!(f, "must be above {}", Number(l)),
            Self::Below(l) => write!(f, "must be below {}", Number(l)),
            Self::Within(lo, hi) => write!(f, "must lie in [{}, {}]", Number(lo), Number(hi)),
            Self::Rule(rule) => f.write_str(rule),
        }
    }
}

/// A value as it was configured: an `f32` converted to `f64` is printed as
/// the `f32` it was (`0.4`, not `0.4000000059604645`).
struct Number(f64);

impl core::fmt::Display for Number {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let narrow = self.0 as f32;
        if f64::from(narrow) == self.0 {
            write!(f, "{narrow}")
        } else {
            write!(f, "{}", self.0)
        }
    }
}

/// ` = value` when there is one.
struct ShownValue(Option<f64>);

impl core::fmt::Display for ShownValue {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(v) => write!(f, " = {}", Number(v)),
            None => Ok(()),
        }
    }
}

/// The checks of the configurations' `validate()`, each naming the field,
/// the value and the bound in its error.
pub(crate) mod check {
    use super::{Bound, Error};
    use crate::scalar::Scalar;

    /// The error for `field = value` against `bound`.
    pub(crate) fn invalid<T: Scalar>(field: &'static str, value: T, bound: Bound) -> Error {
        Error::InvalidConfig {
            field,
            value: Some(value.as_f64()),
            bound,
        }
    }

    fn require<T: Scalar>(ok: bool, field: &'static str, v: T, bound: Bound) -> Result<(), Error> {
        if ok {
            Ok(())
        } else {
            Err(invalid(field, v, bound))
        }
    }

    /// Finite.
    pub(crate) fn finite<T: Scalar>(field: &'static str, v: T) -> Result<(), Error> {
        require(v.is_finite(), field, v, Bound::Finite)
    }

    /// `> 0`, `+inf` allowed (NaN refused).
    pub(crate) fn positive<T: Scalar>(field: &'static str, v: T) -> Result<(), Error> {
        require(v > T::zero(), field, v, Bound::Positive)
    }

    /// `> 0` and finite.
    pub(crate) fn positive_finite<T: Scalar>(field: &'static str, v: T) -> Result<(), Error> {
        require(
            v.is_finite() && v > T::zero(),
            field,
            v,
            Bound::PositiveFinite,
        )
    }

    /// `>= 0` and finite.
    pub(crate) fn not_negative<T: Scalar>(field: &'static str, v: T) -> Result<(), Error> {
        require(
            v.is_finite() && v >= T::zero(),
            field,
            v,
            Bound::NotNegative,
        )
    }

    /// In `[lo, hi]` (NaN refused).
    pub(crate) fn within<T: Scalar>(field: &'static str, v: T, lo: T, hi: T) -> Result<(), Error> {
        require(
            v >= lo && v <= hi,
            field,
            v,
            Bound::Within(lo.as_f64(), hi.as_f64()),
        )
    }

    /// `>= limit` and finite.
    pub(crate) fn at_least<T: Scalar>(field: &'static str, v: T, limit: T) -> Result<(), Error> {
        require(
            v.is_finite() && v >= limit,
            field,
            v,
            Bound::AtLeast(limit.as_f64()),
        )
    }

    /// `<= limit` (NaN refused).
    pub(crate) fn at_most<T: Scalar>(field: &'static str, v: T, limit: T) -> Result<(), Error> {
        require(v <= limit, field, v, Bound::AtMost(limit.as_f64()))
    }

    /// `< limit` (NaN refused).
    pub(crate) fn below<T: Scalar>(field: &'static str, v: T, limit: T) -> Result<(), Error> {
        require(v < limit, field, v, Bound::Below(limit.as_f64()))
    }

    /// A count or other integer: `>= min`.
    pub(crate) fn count_at_least(field: &'static str, v: u64, min: u64) -> Result<(), Error> {
        if v >= min {
            Ok(())
        } else {
            Err(Error::InvalidConfig {
                field,
                value: Some(v as f64),
                bound: Bound::AtLeast(min as f64),
            })
        }
    }
}

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
        /// The field, as a path from the configuration the caller passed
        /// (`delay_loop.fusion.delay_min_s`, `ekf.origin.lat_deg` for a
        /// [`DelayCompensatedNavConfig`](crate::DelayCompensatedNavConfig)), whichever part validated it;
        /// compares equal to that text.
        field: ConfigPath,
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

    /// This error with its configuration path inside the table `section`
    /// of an enclosing configuration (a parent's validation of a nested
    /// one); other errors unchanged.
    pub(crate) fn within(self, section: Section) -> Self {
        match self {
            Self::InvalidConfig {
                field,
                value,
                bound,
            } => Self::InvalidConfig {
                field: field.within(section),
                value,
                bound,
            },
            other => other,
        }
    }
}

/// A table of a configuration that holds another configuration: the
/// segments a parent prepends to the path of a nested configuration's
/// error (one byte each, so that [`Error`] stays small without a heap).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Section {
    /// No segment (the unused slots of a path).
    Empty,
    /// [`DelayCompensatedNavConfig::ekf`](crate::DelayCompensatedNavConfig::ekf).
    Ekf,
    /// [`AugmentedEkf17Config::nav`](crate::AugmentedEkf17Config::nav).
    Nav,
    /// [`DelayCompensatedNavConfig::delay_loop`](crate::DelayCompensatedNavConfig::delay_loop).
    DelayLoop,
    /// [`DelayLoopConfig::fusion`](crate::DelayLoopConfig::fusion).
    Fusion,
}

impl Section {
    fn name(self) -> &'static str {
        match self {
            Self::Empty => "",
            Self::Ekf => "ekf",
            Self::Nav => "nav",
            Self::DelayLoop => "delay_loop",
            Self::Fusion => "fusion",
        }
    }
}

/// Tables a path can cross above its field (`delay_loop.fusion`: 2).
const PATH_DEPTH: usize = 3;

/// Where a configuration error lies: the tables from the configuration the
/// caller passed down to the field, as written in a config file
/// (`delay_loop.fusion.gamma`). Displays as that text and compares equal to
/// it (`field == "delay_loop.fusion.gamma"`).
#[derive(Clone, Copy)]
pub struct ConfigPath {
    /// The enclosing tables, outermost first, then [`Section::Empty`].
    sections: [Section; PATH_DEPTH],
    /// The field within the innermost table (may itself hold a dot, e.g.
    /// `origin.lat_deg`, `mode.initial_s`).
    field: &'static str,
}

impl ConfigPath {
    /// The path of `field` in the configuration checked.
    pub const fn new(field: &'static str) -> Self {
        Self {
            sections: [Section::Empty; PATH_DEPTH],
            field,
        }
    }

    /// The field within its innermost table.
    pub fn field(&self) -> &'static str {
        self.field
    }

    /// Every segment, outermost first: the tables, then the field.
    pub fn segments(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.sections
            .iter()
            .filter(|s| **s != Section::Empty)
            .map(|s| s.name())
            .chain(core::iter::once(self.field))
    }

    /// The text, character by character (no heap).
    fn chars(&self) -> impl Iterator<Item = char> + '_ {
        self.segments()
            .enumerate()
            .flat_map(|(i, segment)| (i > 0).then_some('.').into_iter().chain(segment.chars()))
    }

    /// The path inside `section` (a deeper path than [`PATH_DEPTH`] keeps
    /// its outermost tables: none exists in the crate's configurations).
    fn within(self, section: Section) -> Self {
        let mut sections = [Section::Empty; PATH_DEPTH];
        sections[0] = section;
        sections[1..].copy_from_slice(&self.sections[..PATH_DEPTH - 1]);
        Self { sections, ..self }
    }
}

impl From<&'static str> for ConfigPath {
    fn from(field: &'static str) -> Self {
        Self::new(field)
    }
}

impl core::fmt::Display for ConfigPath {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, segment) in self.segments().enumerate() {
            if i > 0 {
                f.write_str(".")?;
            }
            f.write_str(segment)?;
        }
        Ok(())
    }
}

impl core::fmt::Debug for ConfigPath {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "ConfigPath(\"{self}\")")
    }
}

impl PartialEq for ConfigPath {
    /// Equal when the texts are: `ConfigPath::new("fusion.gamma")` equals
    /// the path of `gamma` inside the `fusion` table.
    fn eq(&self, other: &Self) -> bool {
        self.chars().eq(other.chars())
    }
}

impl Eq for ConfigPath {}

impl PartialEq<str> for ConfigPath {
    fn eq(&self, text: &str) -> bool {
        self.chars().eq(text.chars())
    }
}

impl PartialEq<&str> for ConfigPath {
    fn eq(&self, text: &&str) -> bool {
        *self == **text
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
    /// Must lie in `[lo, hi)`.
    WithinBelow(f64, f64),
    /// Must lie in `(lo, hi]`.
    AboveWithin(f64, f64),
    /// Must be `<= limit` (or `>= limit` when `at_least`), in the field's
    /// unit, for the sizes the configuration gives to fit the const generic
    /// capacity `of`, which holds `samples`.
    Capacity {
        /// The field's largest (smallest) valid value.
        limit: f32,
        /// True: a lower bound.
        at_least: bool,
        /// The capacity.
        of: Capacity,
        /// What it holds, samples.
        samples: u32,
    },
    /// The navigator's history (the field is `HIST`, the value its
    /// capacity in IMU samples) is shorter than the longest delay, `delay_s`
    /// (`delay_loop.fusion.delay_max_s` plus the whitening's group delay),
    /// times the IMU rate `rate_hz`, with margins: it needs `needed`
    /// samples, `short_by` more than it has.
    History {
        /// IMU samples needed.
        needed: u32,
        /// How many more than `HIST`.
        short_by: u32,
        /// The longest delay, s.
        delay_s: f32,
        /// The IMU rate, Hz.
        rate_hz: f32,
    },
    /// A rule stated in words (relations between fields).
    Rule(&'static str),
}

/// A const generic capacity a configuration must fit (see
/// [`Bound::Capacity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Capacity {
    /// [`DelayLoop`](crate::DelayLoop)'s `BUF`: the correlation buffer,
    /// grid samples.
    LoopBuf,
    /// [`DelayLoop`](crate::DelayLoop)'s `LAGS`: the shifts of the delay
    /// range, grid samples.
    LoopLags,
    /// [`DelayLoop`](crate::DelayLoop)'s `HIST`: the IMU grid history (the
    /// buffer, the largest shift and the lead of the IMU stream over the
    /// GPS one), grid samples.
    LoopHist,
    /// The offline calibrator's `SHIFTS`: `2 S + 1` shifts.
    CalibratorShifts,
    /// The offline calibrator's `HIST`: the largest shift and the lead,
    /// grid samples.
    CalibratorHist,
}

impl core::fmt::Display for Capacity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::LoopBuf => "the delay loop's const generic `BUF`",
            Self::LoopLags => "the delay loop's const generic `LAGS`",
            Self::LoopHist => "the delay loop's const generic `HIST`",
            Self::CalibratorShifts => "the calibrator's const generic `SHIFTS`",
            Self::CalibratorHist => "the calibrator's const generic `HIST`",
        })
    }
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
            Self::WithinBelow(lo, hi) => {
                write!(f, "must lie in [{}, {})", Number(lo), Number(hi))
            }
            Self::AboveWithin(lo, hi) => {
                write!(f, "must lie in ({}, {}]", Number(lo), Number(hi))
            }
            Self::Capacity {
                limit,
                at_least,
                of,
                samples,
            } => write!(
                f,
                "must be {} {} to fit {of} ({samples} samples)",
                if at_least { ">=" } else { "<=" },
                Number(limit.into()),
            ),
            Self::History {
                needed,
                short_by,
                delay_s,
                rate_hz,
            } => write!(
                f,
                "must be >= {needed} IMU samples: the longest delay {} s \
                 (`delay_loop.fusion.delay_max_s` plus the whitening's group delay) \
                 times the IMU rate {} Hz, with margins; raise the const generic \
                 `HIST` by {short_by}",
                Number(delay_s.into()),
                Number(rate_hz.into()),
            ),
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
    use super::{Bound, ConfigPath, Error};
    use crate::scalar::Scalar;

    /// The error for `field = value` against `bound`.
    pub(crate) fn invalid<T: Scalar>(field: &'static str, value: T, bound: Bound) -> Error {
        Error::InvalidConfig {
            field: ConfigPath::new(field),
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

    /// In the half-open interval `bound`, [`Bound::WithinBelow`] or
    /// [`Bound::AboveWithin`] (NaN refused; an `f32` compares exactly as
    /// `f64`).
    pub(crate) fn interval<T: Scalar>(
        field: &'static str,
        v: T,
        bound: Bound,
    ) -> Result<(), Error> {
        let x = v.as_f64();
        let ok = match bound {
            Bound::WithinBelow(lo, hi) => x >= lo && x < hi,
            Bound::AboveWithin(lo, hi) => x > lo && x <= hi,
            _ => false,
        };
        require(ok, field, v, bound)
    }

    /// A count or other integer: `>= min`.
    pub(crate) fn count_at_least(field: &'static str, v: u64, min: u64) -> Result<(), Error> {
        count_within(field, v, min, u64::MAX)
    }

    /// A count or other integer: in `[min, max]` (`>= min` when `max` is
    /// `u64::MAX`).
    pub(crate) fn count_within(
        field: &'static str,
        v: u64,
        min: u64,
        max: u64,
    ) -> Result<(), Error> {
        if (min..=max).contains(&v) {
            Ok(())
        } else {
            Err(Error::InvalidConfig {
                field: ConfigPath::new(field),
                value: Some(v as f64),
                bound: if max == u64::MAX {
                    Bound::AtLeast(min as f64)
                } else {
                    Bound::Within(min as f64, max as f64)
                },
            })
        }
    }
}

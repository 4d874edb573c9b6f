//! The crate's one error type.
//!
//! A refused input leaves the estimator exactly as it was, with one stated
//! exception: [`Error::StepTooLong`] (see its docs).

/// Why an input or a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
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
    /// A configuration value is out of its valid range.
    #[error("invalid configuration `{field}`: {reason}")]
    InvalidConfig {
        /// The field name.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
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
}

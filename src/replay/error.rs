//! [`ReplayError`]: why a log could not be opened or replayed.

use super::LogFormat;
use std::path::PathBuf;

/// Why a log could not be opened or replayed. Bad rows are not errors: they
/// are counted in [`SkipCounts`](super::SkipCounts).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    /// A file or directory could not be opened.
    #[error("cannot open {}: {source}", path.display())]
    Open {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A file's header row could not be read.
    #[error("cannot read the header row of {}: {source}", path.display())]
    Header {
        /// The path.
        path: PathBuf,
        /// The CSV error.
        #[source]
        source: csv::Error,
    },
    /// A required column is missing from a file's header.
    #[error("{} has no column `{column}`", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The missing column (or alternatives, separated by `|`).
        column: String,
    },
    /// A required file of the format was not found.
    #[error("no {what} file among the {format} log inputs {searched}")]
    MissingFile {
        /// Which file, e.g. `"imu.csv"` or `"*_sensor_combined_*.csv"`.
        what: &'static str,
        /// The format looked for.
        format: LogFormat,
        /// The inputs searched.
        searched: String,
    },
    /// `--format auto` could not tell the layout.
    #[error(
        "cannot tell the log format of {searched}: expected imu.csv (crate `t_us` or ArduPilot `t_s`) or PX4 `*_sensor_combined_*.csv`"
    )]
    UnknownFormat {
        /// The inputs searched.
        searched: String,
    },
    /// An unknown format name.
    #[error("unknown log format `{0}` (expected auto, csv, ardupilot, px4, bin or ulg)")]
    UnknownFormatName(String),
    /// A binary log's bytes are not a valid record.
    #[error(
        "{} is corrupt{}{}: {reason}",
        path.display(),
        offset.map_or_else(String::new, |o| format!(" at byte {o}")),
        record.as_ref().map_or_else(String::new, |r| format!(" (record {r})"))
    )]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// Byte offset of the bad record, when the parser reports it.
        offset: Option<u64>,
        /// The record's message name, when known.
        record: Option<String>,
        /// What is wrong.
        reason: String,
    },
    /// A binary log lacks the records asked for (e.g. an IMU instance).
    #[error("{} has no {what} records", path.display())]
    MissingRecords {
        /// The file.
        path: PathBuf,
        /// What was looked for.
        what: String,
    },
    /// A duration option (seconds) is negative, NaN or infinite.
    #[error("{name} must be a finite, non-negative number of seconds, not {value}")]
    InvalidSeconds {
        /// The option, e.g. `"added GPS delay"`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// An ArduPilot CSV log has two IMU files: instance 0 (`imu.csv`) and
    /// 1 (`imu2.csv`).
    #[error("IMU instance {instance}: the ArduPilot CSV layout has imu.csv (0) and imu2.csv (1)")]
    NoSuchImu {
        /// The instance asked for.
        instance: u8,
    },
    /// An estimator name that is not registered
    /// ([`session::ESTIMATORS`](super::session::ESTIMATORS)).
    #[error(
        "estimator `{name}` {}; available: {available}",
        if *planned { "is not built into this version" } else { "is unknown" }
    )]
    UnknownEstimator {
        /// The name asked for.
        name: String,
        /// `true` for a name the replay knows but this build lacks.
        planned: bool,
        /// The names that are available, `all` last, comma-separated.
        available: String,
    },
    /// A configuration file could not be read, or its configuration is
    /// invalid ([`config_file`](super::config_file)).
    #[error("config file {}: {source}", path.display())]
    ConfigFile {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: super::config_file::ConfigFileError,
    },
    /// An estimator (or the simulator) refused its configuration.
    #[error(transparent)]
    Config(#[from] crate::Error),
    /// A file could not be written (the simulated run's CSV files).
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// What a [`ReplayObserver`](super::session::ReplayObserver) did with an
    /// estimate failed (e.g. writing it to a file).
    #[error(transparent)]
    Output(Box<dyn std::error::Error + Send + Sync>),
}

/// Seconds to whole microseconds, rounded; values beyond `u64::MAX` µs
/// (584,000 years) saturate there. A negative, NaN or infinite value is
/// [`ReplayError::InvalidSeconds`] naming the option.
pub fn seconds_to_us(name: &'static str, seconds: f64) -> Result<u64, ReplayError> {
    if !seconds.is_finite() || seconds < 0.0 {
        return Err(ReplayError::InvalidSeconds {
            name,
            value: seconds,
        });
    }
    // `as` saturates for finite values above u64::MAX.
    Ok((seconds * 1e6).round() as u64)
}

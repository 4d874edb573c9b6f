//! The flags shared by the subcommands that read a log, and the value
//! parsers that check every number before anything runs.
//!
//! A number is refused by clap (exit 2) with the flag, the value and the
//! bound: `invalid value 'nan' for '--from <S>': must be a finite number of
//! seconds`. What needs the log (a window inside it, a step before its end)
//! is checked once the log is open ([`check_against_log`]), with the same
//! exit code.

use crate::Failure;
use clap::Args;
use delaynav::replay::session::ReplayOptions;
use std::path::PathBuf;

/// A finite number (`nan`, `inf` refused).
fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| "must be a number".to_string())?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err("must be a finite number".into())
    }
}

/// A finite number within `[lo, hi]`, `unit` named in the message.
fn within(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let v = finite(s).map_err(|e| format!("{e} ({unit})"))?;
    if v < lo {
        Err(format!("must be >= {lo} {unit}"))
    } else if v > hi {
        Err(format!("must be <= {hi} {unit}"))
    } else {
        Ok(v)
    }
}

/// A finite number within `(0, hi]`.
fn positive_up_to(s: &str, hi: f64, unit: &str) -> Result<f64, String> {
    let v = within(s, 0.0, hi, unit)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be > 0 {unit}"))
    }
}

/// A time on the log's clock, seconds: finite, not negative.
pub fn log_time_s(s: &str) -> Result<f64, String> {
    within(s, 0.0, 1e7, "s")
}

/// The warm-up, seconds: finite, 0 to an hour.
pub fn warmup_s(s: &str) -> Result<f64, String> {
    within(s, 0.0, 3600.0, "s")
}

/// Largest delay the replay may add to the GPS, seconds.
pub const MAX_ADDED_DELAY_S: f64 = 5.0;

/// The added GPS delay, seconds: 0 to [`MAX_ADDED_DELAY_S`] (fixes can
/// only be made later: a log's own delay cannot be taken away).
pub fn added_delay_s(s: &str) -> Result<f64, String> {
    within(s, 0.0, MAX_ADDED_DELAY_S, "s")
}

/// A declination, degrees east: -180 to 180.
pub fn declination_deg(s: &str) -> Result<f64, String> {
    within(s, -180.0, 180.0, "deg")
}

/// An inclination, degrees down: -90 to 90.
pub fn inclination_deg(s: &str) -> Result<f64, String> {
    within(s, -90.0, 90.0, "deg")
}

/// A mounting trim, radians: -0.5 to 0.5 (ArduPilot limits its own to 10 deg).
pub fn trim_rad(s: &str) -> Result<f64, String> {
    within(s, -0.5, 0.5, "rad")
}

/// An accelerometer noise density, m/s^2/sqrt(Hz): above 0, at most 10.
pub fn accel_density(s: &str) -> Result<f64, String> {
    positive_up_to(s, 10.0, "m/s^2/sqrt(Hz)")
}

/// A gyro noise density, rad/s/sqrt(Hz): above 0, at most 1.
pub fn gyro_density(s: &str) -> Result<f64, String> {
    positive_up_to(s, 1.0, "rad/s/sqrt(Hz)")
}

/// An accelerometer bias random walk, m/s^2/sqrt(s): 0 to 1.
pub fn bias_walk(s: &str) -> Result<f64, String> {
    within(s, 0.0, 1.0, "m/s^2/sqrt(s)")
}

/// A simulated duration, seconds: above 0, at most a day.
pub fn duration_s(s: &str) -> Result<f64, String> {
    positive_up_to(s, 86_400.0, "s")
}

/// A simulated true delay, seconds: 0 to 2.
pub fn sim_delay_s(s: &str) -> Result<f64, String> {
    within(s, 0.0, 2.0, "s")
}

/// A rate, Hz: 0 (every sample) to 10 kHz.
pub fn rate_hz(s: &str) -> Result<f64, String> {
    within(s, 0.0, 10_000.0, "Hz")
}

/// An error of the command line found after clap parsed it (it needs the
/// log): printed like clap's, exit 2.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// A usage error as a [`Failure`].
pub fn usage(message: String) -> Failure {
    Box::new(UsageError(message))
}

/// How a log is read and replayed: the flags of `replay`, `report` and
/// `calibrate` (`batch` takes the defaults).
#[derive(Debug, Clone, Args)]
pub struct LogArgs {
    /// The log: an ArduPilot `.bin` or PX4 `.ulg` file (recognised by its
    /// first bytes), or a directory of CSV files.
    #[arg(required = true, value_name = "LOG")]
    pub inputs: Vec<PathBuf>,
    /// Log layout: auto, csv (the crate's), ardupilot, px4, bin, ulg.
    #[arg(long, default_value = "auto")]
    pub format: String,
    /// Seconds added to every GPS receive time (the added-delay
    /// experiment), 0 to 5.
    #[arg(long, value_name = "S", value_parser = added_delay_s, default_value_t = 0.0)]
    pub add_gps_delay: f64,
    /// Add the delay only to the fixes received from this time on, seconds
    /// on the log's clock (a step of the delay; inside the log).
    #[arg(long, value_name = "S", value_parser = log_time_s, requires = "add_gps_delay")]
    pub add_delay_from: Option<f64>,
    /// Start of the scored window, seconds on the log's clock (default: the
    /// take-off found in the log).
    #[arg(long, value_name = "S", value_parser = log_time_s)]
    pub from: Option<f64>,
    /// End of the replayed and scored window, seconds (default: the end of
    /// the flight found in the log, cut before a loss of control).
    #[arg(long, value_name = "S", value_parser = log_time_s)]
    pub to: Option<f64>,
    /// Seconds replayed before `--from` so the estimators converge; not
    /// scored.
    #[arg(long, value_name = "S", value_parser = warmup_s, default_value_t = 30.0)]
    pub warmup: f64,
    /// Magnetic declination, degrees east, -180 to 180 (default: from the
    /// log, else the World Magnetic Model).
    #[arg(long, value_name = "DEG", value_parser = declination_deg)]
    pub declination_deg: Option<f64>,
    /// Magnetic inclination, degrees down, -90 to 90 (default: measured at
    /// rest, else the World Magnetic Model).
    #[arg(long, value_name = "DEG", value_parser = inclination_deg)]
    pub inclination_deg: Option<f64>,
    /// Mounting trim roll, radians, -0.5 to 0.5 (default: ArduPilot
    /// `AHRS_TRIM_X`, else 0).
    #[arg(long, value_name = "RAD", value_parser = trim_rad)]
    pub trim_roll_rad: Option<f64>,
    /// Mounting trim pitch, radians, -0.5 to 0.5 (default: `AHRS_TRIM_Y`).
    #[arg(long, value_name = "RAD", value_parser = trim_rad)]
    pub trim_pitch_rad: Option<f64>,
    /// Which IMU to read, 0 first (DataFlash `IMU` instance, ULog
    /// `sensor_combined` multi-id, ArduPilot CSV `imu.csv` or `imu2.csv`).
    #[arg(long, value_name = "N", default_value_t = 0,
          value_parser = clap::value_parser!(u8).range(0..=9))]
    pub imu_instance: u8,
    /// Accelerometer noise density of the filters, m/s^2/sqrt(Hz), above 0
    /// (default: measured on the log, never below the filters' default).
    #[arg(long, value_name = "D", value_parser = accel_density)]
    pub accel_noise_density: Option<f64>,
    /// Gyro noise density of the filters, rad/s/sqrt(Hz), above 0.
    #[arg(long, value_name = "D", value_parser = gyro_density)]
    pub gyro_noise_density: Option<f64>,
    /// Accelerometer bias random walk, m/s^2/sqrt(s), 0 to 1.
    #[arg(long, value_name = "W", value_parser = bias_walk)]
    pub accel_bias_random_walk: Option<f64>,
    /// Navigator configuration (TOML, may be partial), merged over the one
    /// derived from the log; its `ekf` table configures every estimator.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Drop the log's magnetometer records: yaw from GPS velocity and the
    /// IMU alone (the navigator's Gaussian sum of yaw filters).
    #[arg(long)]
    pub no_mag: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl LogArgs {
    /// The library's options for these flags; `--from` after `--to` is a
    /// usage error.
    pub fn options(&self) -> Result<ReplayOptions, Failure> {
        if let (Some(from), Some(to)) = (self.from, self.to)
            && from >= to
        {
            return Err(usage(format!(
                "invalid value '{to}' for '--to <S>': must be after --from ({from} s)"
            )));
        }
        Ok(ReplayOptions {
            inputs: self.inputs.clone(),
            format: delaynav::replay::LogFormat::parse_choice(&self.format)
                .map_err(|e| usage(format!("invalid value for '--format': {e}")))?,
            imu_instance: self.imu_instance,
            add_gps_delay_s: self.add_gps_delay,
            add_delay_from_s: self.add_delay_from,
            from_s: self.from,
            to_s: self.to,
            warmup_s: Some(self.warmup),
            fixed_window: false,
            declination_deg: self.declination_deg,
            inclination_deg: self.inclination_deg,
            trim_rad: [self.trim_roll_rad, self.trim_pitch_rad],
            accel_noise_density: self.accel_noise_density,
            gyro_noise_density: self.gyro_noise_density,
            accel_bias_random_walk: self.accel_bias_random_walk,
            config_file: self.config.clone(),
            no_mag: self.no_mag,
        })
    }
}

/// The log's first and last IMU sample, seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogSpan {
    /// First IMU sample, s.
    pub first_s: f64,
    /// Last IMU sample, s.
    pub last_s: f64,
}

/// Checks the times given on the command line against the log's span and
/// the window the log gives: `--from`, `--to` and `--add-delay-from` inside
/// the log, and the window ordered once each end is known.
pub fn check_against_log(
    args: &LogArgs,
    span: LogSpan,
    window_s: (Option<f64>, Option<f64>),
) -> Result<(), Failure> {
    let LogSpan { first_s, last_s } = span;
    for (flag, value) in [
        ("--from", args.from),
        ("--to", args.to),
        ("--add-delay-from", args.add_delay_from),
    ] {
        if let Some(v) = value
            && !(first_s..=last_s).contains(&v)
        {
            return Err(usage(format!(
                "invalid value '{v}' for '{flag} <S>': outside the log, whose IMU samples span \
                 {first_s:.3}-{last_s:.3} s"
            )));
        }
    }
    if let (Some(from), Some(to)) = window_s
        && from >= to
    {
        let (flag, value, bound) = if args.to.is_some() {
            (
                "--to",
                to,
                format!("must be after the window's start, {from:.3} s"),
            )
        } else {
            (
                "--from",
                from,
                format!("must be before the window's end, {to:.3} s"),
            )
        };
        return Err(usage(format!(
            "invalid value '{value}' for '{flag} <S>': {bound}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_finite_and_in_range() {
        assert_eq!(log_time_s("12.5"), Ok(12.5));
        assert_eq!(
            log_time_s("nan"),
            Err("must be a finite number (s)".to_string())
        );
        assert_eq!(log_time_s("-1"), Err("must be >= 0 s".to_string()));
        assert_eq!(warmup_s("-5"), Err("must be >= 0 s".to_string()));
        assert_eq!(added_delay_s("-0.1"), Err("must be >= 0 s".to_string()));
        assert_eq!(added_delay_s("0.2"), Ok(0.2));
        assert_eq!(declination_deg("-12.5"), Ok(-12.5));
        assert_eq!(gyro_density("0"), Err("must be > 0 rad/s/sqrt(Hz)".into()));
        assert_eq!(inclination_deg("91"), Err("must be <= 90 deg".into()));
        assert!(finite("1e400").is_err() && finite("x").is_err());
    }
}

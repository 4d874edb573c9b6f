//! The navigator's configuration as a TOML file, possibly partial, merged
//! over the configuration a replay derives from the log.
//!
//! The file is a [`DelayCompensatedNavConfig`]: what it holds is merged over
//! the defaults given (the replay's: IMU rate, noise and magnetic field from
//! the log), table by table, so `[ekf]` with one key changes that key only.
//! Its `ekf` table configures every estimator (`aekf17` and `ekf16` run on
//! the same `Ekf16Config`). An unknown key or a wrong type is an error
//! naming the key and its line; the merged configuration is then validated,
//! against the navigator's capacities too (the delay loop's buffer and range,
//! the history), and an invalid value is an error naming the field's path as
//! written in the file, its value and its bound. [`read_config_file`] names
//! the file in every error ([`ReplayError::ConfigFile`]).
//!
//! ```
//! use delaynav::DelayCompensatedNavConfig;
//! use delaynav::replay::config_file::{config_to_toml, merge_config};
//!
//! let log = DelayCompensatedNavConfig::<f64> { imu_rate_hz: 400.0, ..Default::default() };
//! let merged = merge_config(log, "[ekf]\nmag_gate = 16.0\n").unwrap();
//! assert_eq!((merged.imu_rate_hz, merged.ekf.mag_gate), (400.0, 16.0));
//! // The printed form reads back equal: a complete file to start from.
//! let text = config_to_toml(&merged).unwrap();
//! assert_eq!(merge_config(DelayCompensatedNavConfig::default(), &text).unwrap(), merged);
//! ```

use super::ReplayError;
use crate::{DelayCompensatedNav, DelayCompensatedNavConfig};
use std::path::Path;
use toml::{Table, Value};

/// Why a configuration file was refused (wrapped, with the file's path, in
/// [`ReplayError::ConfigFile`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigFileError {
    /// The file could not be read.
    #[error(transparent)]
    Read(std::io::Error),
    /// Not TOML, an unknown key or a wrong type (the message names the key
    /// and its line).
    #[error(transparent)]
    Parse(toml::de::Error),
    /// A configuration could not be written as TOML.
    #[error(transparent)]
    Write(toml::ser::Error),
    /// The merged configuration is invalid, or beyond the navigator's
    /// capacities: the field's path, its value and its bound.
    #[error(transparent)]
    Invalid(crate::Error),
}

/// `defaults` with the TOML `text` merged over them, validated (see the
/// module docs). The start delay of the configured mode is written where
/// the delay loop keeps its own ([`DelayCompensatedNavConfig::loop_config`]).
pub fn merge_config(
    defaults: DelayCompensatedNavConfig<f64>,
    text: &str,
) -> Result<DelayCompensatedNavConfig<f64>, ConfigFileError> {
    // Read alone first: unknown keys and wrong types are reported with their line.
    toml::from_str::<DelayCompensatedNavConfig<f64>>(text).map_err(ConfigFileError::Parse)?;
    let file: Table = toml::from_str(text).map_err(ConfigFileError::Parse)?;
    let mut merged = Table::try_from(defaults).map_err(ConfigFileError::Write)?;
    merge(&mut merged, file);
    let mut config: DelayCompensatedNavConfig<f64> = Value::Table(merged)
        .try_into()
        .map_err(ConfigFileError::Parse)?;
    config.validate().map_err(ConfigFileError::Invalid)?;
    // The sizes against the navigator's capacities (the delay loop's
    // buffer and range, the history).
    DelayCompensatedNav::<f64>::new(config).map_err(ConfigFileError::Invalid)?;
    // The start delay is the mode's: show it where the loop keeps its own.
    config.delay_loop = config.loop_config();
    Ok(config)
}

/// `defaults` with the file at `path` merged over them ([`merge_config`]);
/// every error names the file ([`ReplayError::ConfigFile`]).
pub fn read_config_file(
    defaults: DelayCompensatedNavConfig<f64>,
    path: &Path,
) -> Result<DelayCompensatedNavConfig<f64>, ReplayError> {
    let named = |source| ReplayError::ConfigFile {
        path: path.to_path_buf(),
        source,
    };
    let text = std::fs::read_to_string(path).map_err(|e| named(ConfigFileError::Read(e)))?;
    merge_config(defaults, &text).map_err(named)
}

/// The configuration as TOML, as [`merge_config`] reads it back.
pub fn config_to_toml(config: &DelayCompensatedNavConfig<f64>) -> Result<String, ConfigFileError> {
    toml::to_string(config).map_err(ConfigFileError::Write)
}

/// Writes `over` into `base`. A table merges key by key when every one of
/// its keys exists in `base`'s table (a struct); otherwise (another enum
/// variant, an option that was unset) it replaces `base`'s value whole.
fn merge(base: &mut Table, over: Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(Value::Table(b)), Value::Table(o)) if o.keys().all(|k| b.contains_key(k)) => {
                merge(b, o)
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DelayMode;

    fn with_text(
        text: &str,
        defaults: DelayCompensatedNavConfig<f64>,
    ) -> Result<DelayCompensatedNavConfig<f64>, String> {
        merge_config(defaults, text).map_err(|e| e.to_string())
    }

    fn log_defaults() -> DelayCompensatedNavConfig<f64> {
        let mut c = DelayCompensatedNavConfig {
            imu_rate_hz: 400.0,
            ..DelayCompensatedNavConfig::default()
        };
        c.ekf.mag_declination_rad = 0.2;
        c
    }

    #[test]
    fn a_partial_file_keeps_the_log_defaults() {
        let c = with_text(
            "imu_rate_hz = 50.0\n[ekf]\nmag_gate = 16.0\n",
            log_defaults(),
        )
        .unwrap();
        let mut expected = log_defaults();
        expected.imu_rate_hz = 50.0;
        expected.ekf.mag_gate = 16.0;
        assert_eq!(c, expected);
    }

    #[test]
    fn a_partial_nested_table_keeps_the_navigator_thresholds() {
        let c = with_text("[delay_loop.fusion]\ndelay_max_s = 0.6\n", log_defaults()).unwrap();
        let mut expected = log_defaults();
        expected.delay_loop.fusion.delay_max_s = 0.6;
        assert_eq!(c, expected);
    }

    #[test]
    fn another_mode_replaces_the_default_one() {
        let c = with_text("[mode.Fixed]\ndelay_s = 0.25\n", log_defaults()).unwrap();
        assert_eq!(c.mode, DelayMode::Fixed { delay_s: 0.25 });
    }

    #[test]
    fn unknown_keys_and_invalid_values_are_errors() {
        let err = with_text("[ekf]\nmag_gates = 16.0\n", log_defaults()).unwrap_err();
        assert!(err.contains("mag_gates"), "{err}");
        let err = with_text("imu_rate_hz = -5.0\n", log_defaults()).unwrap_err();
        assert!(err.contains("imu_rate_hz"), "{err}");
    }

    #[test]
    fn an_invalid_value_names_the_file_the_path_the_value_and_the_bound() {
        let path = std::env::temp_dir().join(format!(
            "delaynav-config-invalid-buffer-{}.toml",
            std::process::id()
        ));
        std::fs::write(&path, "[delay_loop]\nbuffer_s = 5.1\n").unwrap();
        let err = read_config_file(log_defaults(), &path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(
            matches!(&err, ReplayError::ConfigFile { path: p, source: ConfigFileError::Invalid(_) } if p == &path),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            format!(
                "config file {}: invalid configuration: `delay_loop.buffer_s` = 5.1, must be <= 5 \
                 to fit the delay loop's const generic `BUF` (125 samples)",
                path.display()
            )
        );
        let err = with_text("[delay_loop.fusion]\ngamma = 1.5\n", log_defaults()).unwrap_err();
        assert_eq!(
            err,
            "invalid configuration: `delay_loop.fusion.gamma` = 1.5, must lie in (0, 1]"
        );
        let err = with_text(
            "[ekf.origin]\nlat_deg = 91.0\nlon_deg = 0.0\nalt_m = 0.0\n",
            log_defaults(),
        )
        .unwrap_err();
        assert!(
            err.ends_with("`ekf.origin.lat_deg` = 91, must lie in [-90, 90]"),
            "{err}"
        );
    }

    #[test]
    fn a_missing_file_is_an_error_naming_it() {
        let path = Path::new("/nonexistent/delaynav-config.toml");
        let err = read_config_file(log_defaults(), path).unwrap_err();
        assert!(
            matches!(
                &err,
                ReplayError::ConfigFile {
                    source: ConfigFileError::Read(_),
                    ..
                }
            ),
            "{err:?}"
        );
        assert!(
            err.to_string()
                .starts_with("config file /nonexistent/delaynav-config.toml: "),
            "{err}"
        );
    }

    #[test]
    fn a_table_naming_one_field_changes_that_field_only() {
        // Over the plain defaults too (no merge needed): the file of the
        // issue moved the navigator's validity thresholds.
        let c = with_text(
            "[delay_loop]\nbuffer_s = 4.0\n",
            DelayCompensatedNavConfig::default(),
        )
        .unwrap();
        let mut expected = DelayCompensatedNavConfig::default();
        expected.delay_loop.buffer_s = 4.0;
        assert_eq!(c, expected);
    }

    #[test]
    fn the_printed_config_reads_back_equal() {
        let text = config_to_toml(&log_defaults()).unwrap();
        assert_eq!(
            with_text(&text, DelayCompensatedNavConfig::default()).unwrap(),
            log_defaults()
        );
    }
}

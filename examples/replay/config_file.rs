//! `--config F.toml` and `--print-config`: the navigator's configuration as a
//! TOML file.
//!
//! The file is a [`DelayCompensatedNavConfig`], possibly partial: what it holds is merged
//! over the configuration the replay derives from the log (IMU rate, noise,
//! magnetic field), table by table, so `[ekf]` with one key changes that key
//! only. Its `ekf` table configures every estimator (`aekf17` and `ekf16`
//! run on the same `Ekf16Config`). An unknown key or a wrong type is an error
//! naming the key and its line; the merged configuration is then validated.

use delaynav::{DelayCompensatedNav, DelayCompensatedNavConfig};
use std::path::Path;
use toml::{Table, Value};

type Failure = Box<dyn std::error::Error>;

/// `defaults` with the file at `path` (if any) merged over them, validated.
pub fn resolve(
    defaults: DelayCompensatedNavConfig<f64>,
    path: Option<&Path>,
) -> Result<DelayCompensatedNavConfig<f64>, Failure> {
    let Some(path) = path else {
        return Ok(defaults);
    };
    let shown = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("--config {shown}: {e}"))?;
    // Read alone first: unknown keys and wrong types are reported with their line.
    toml::from_str::<DelayCompensatedNavConfig<f64>>(&text)
        .map_err(|e| format!("--config {shown}: {e}"))?;
    let file: Table = toml::from_str(&text)?;
    let mut merged = Table::try_from(defaults)?;
    merge(&mut merged, file);
    let mut config: DelayCompensatedNavConfig<f64> = Value::Table(merged)
        .try_into()
        .map_err(|e| format!("--config {shown}: {e}"))?;
    config
        .validate()
        .map_err(|e| format!("--config {shown}: {e}"))?;
    // The sizes against the navigator's capacities (the delay loop's
    // buffer and range, the history), still naming the file.
    DelayCompensatedNav::<f64>::new(config).map_err(|e| format!("--config {shown}: {e}"))?;
    // The start delay is the mode's: show it where the loop keeps its own.
    config.delay_loop = config.loop_config();
    Ok(config)
}

/// The configuration as TOML, as `--config` reads it back.
pub fn to_toml(config: &DelayCompensatedNavConfig<f64>) -> Result<String, Failure> {
    Ok(toml::to_string(config)?)
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
    use delaynav::DelayMode;

    fn with_file(
        text: &str,
        defaults: DelayCompensatedNavConfig<f64>,
    ) -> Result<DelayCompensatedNavConfig<f64>, String> {
        let path = std::env::temp_dir().join(format!(
            "delaynav-config-{}-{}.toml",
            std::process::id(),
            text.len()
        ));
        std::fs::write(&path, text).unwrap();
        let result = resolve(defaults, Some(&path)).map_err(|e| e.to_string());
        std::fs::remove_file(&path).unwrap();
        result
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
        let c = with_file(
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
        let c = with_file("[delay_loop.fusion]\ndelay_max_s = 0.6\n", log_defaults()).unwrap();
        let mut expected = log_defaults();
        expected.delay_loop.fusion.delay_max_s = 0.6;
        assert_eq!(c, expected);
    }

    #[test]
    fn another_mode_replaces_the_default_one() {
        let c = with_file("[mode.Fixed]\ndelay_s = 0.25\n", log_defaults()).unwrap();
        assert_eq!(c.mode, DelayMode::Fixed { delay_s: 0.25 });
    }

    #[test]
    fn unknown_keys_and_invalid_values_are_errors() {
        let err = with_file("[ekf]\nmag_gates = 16.0\n", log_defaults()).unwrap_err();
        assert!(err.contains("mag_gates"), "{err}");
        let err = with_file("imu_rate_hz = -5.0\n", log_defaults()).unwrap_err();
        assert!(err.contains("imu_rate_hz"), "{err}");
    }

    #[test]
    fn an_invalid_value_names_the_file_the_path_the_value_and_the_bound() {
        let path = std::env::temp_dir().join("delaynav-config-invalid-buffer.toml");
        std::fs::write(&path, "[delay_loop]\nbuffer_s = 5.1\n").unwrap();
        let err = resolve(log_defaults(), Some(&path))
            .unwrap_err()
            .to_string();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(
            err,
            format!(
                "--config {}: invalid configuration: `delay_loop.buffer_s` = 5.1, must be <= 5 \
                 to fit the delay loop's const generic `BUF` (125 samples)",
                path.display()
            )
        );
        let err = with_file("[delay_loop.fusion]\ngamma = 1.5\n", log_defaults()).unwrap_err();
        assert!(
            err.starts_with("--config ")
                && err.ends_with(
                    ": invalid configuration: `delay_loop.fusion.gamma` = 1.5, must lie in (0, 1]"
                ),
            "{err}"
        );
        let err = with_file(
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
    fn a_table_naming_one_field_changes_that_field_only() {
        // Over the plain defaults too (no merge needed): the file of the
        // issue moved the navigator's validity thresholds.
        let c = with_file(
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
        let text = to_toml(&log_defaults()).unwrap();
        assert_eq!(
            with_file(&text, DelayCompensatedNavConfig::default()).unwrap(),
            log_defaults()
        );
    }
}

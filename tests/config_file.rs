//! Configurations read from TOML: partial files over the defaults, unknown
//! keys refused by name, and a round trip through the serialized form.
#![cfg(feature = "serde")]

use delaynav::delay::calibration::CalibrationConfig;
use delaynav::{
    Aekf17Config, DelayLoopConfig, DelayMode, Ekf16Config, NavConfig, Scalar, SensorDelays,
};
use serde::Serialize;
use serde::de::DeserializeOwned;

fn parse<C: DeserializeOwned>(text: &str) -> Result<C, String> {
    toml::from_str(text).map_err(|e| e.to_string())
}

fn only_the_imu_rate<T: Scalar + DeserializeOwned>() {
    let config: NavConfig<T> = parse("imu_rate_hz = 50.0\n").unwrap();
    let expected = NavConfig {
        imu_rate_hz: T::lit(50.0),
        ..NavConfig::default()
    };
    assert_eq!(config, expected);
    assert!(config.validate().is_ok());
}

#[test]
fn a_file_holding_only_the_imu_rate_keeps_every_other_default() {
    only_the_imu_rate::<f32>();
    only_the_imu_rate::<f64>();
}

#[test]
fn nested_tables_may_be_partial() {
    let text = "\
[ekf]
gps_horizontal_std_m = 3.5

[delay_loop.fusion]
delay_max_s = 0.6

[mode.Fixed]
delay_s = 0.25
";
    let config: NavConfig<f64> = parse(text).unwrap();
    let mut expected = NavConfig::<f64>::default();
    expected.ekf.gps_horizontal_std_m = 3.5;
    // A table that is present starts from its own type's defaults: the
    // navigator's validity thresholds (`NAV_MIN_*`) give way to the loop's.
    expected.delay_loop = DelayLoopConfig::default();
    expected.delay_loop.fusion.delay_max_s = 0.6;
    expected.mode = DelayMode::Fixed { delay_s: 0.25 };
    assert_eq!(config, expected);
}

#[test]
fn an_empty_file_is_the_default_of_every_config() {
    assert_eq!(parse::<NavConfig<f64>>("").unwrap(), NavConfig::default());
    assert_eq!(
        parse::<Ekf16Config<f32>>("").unwrap(),
        Ekf16Config::default()
    );
    assert_eq!(
        parse::<Aekf17Config<f64>>("").unwrap(),
        Aekf17Config::default()
    );
    assert_eq!(
        parse::<DelayLoopConfig<f64>>("").unwrap(),
        DelayLoopConfig::default()
    );
    assert_eq!(
        parse::<CalibrationConfig<f64>>("").unwrap(),
        CalibrationConfig::default()
    );
    assert_eq!(
        parse::<SensorDelays<f64>>("").unwrap(),
        SensorDelays::default()
    );
}

#[test]
fn a_misspelt_key_is_an_error_naming_it() {
    for (text, key) in [
        ("imu_rate_hzz = 50.0\n", "imu_rate_hzz"),
        ("[ekf]\ngps_horizontal_std = 3.0\n", "gps_horizontal_std"),
        (
            "[delay_loop.fusion]\ndelay_maximum_s = 0.6\n",
            "delay_maximum_s",
        ),
        ("[mode.Estimated]\ninitial = 0.3\n", "initial"),
    ] {
        let err = parse::<NavConfig<f64>>(text).unwrap_err();
        assert!(err.contains(key), "{text:?}: {err}");
    }
    let err = parse::<Aekf17Config<f64>>("max_delay = 1.0\n").unwrap_err();
    assert!(err.contains("max_delay"), "{err}");
    let err = parse::<CalibrationConfig<f64>>("max_shift = 6.0\n").unwrap_err();
    assert!(err.contains("max_shift"), "{err}");
}

fn round_trip<C: Serialize + DeserializeOwned + PartialEq + core::fmt::Debug>(config: C) {
    let text = toml::to_string(&config).unwrap();
    assert_eq!(parse::<C>(&text).unwrap(), config, "{text}");
}

#[test]
fn the_written_form_reads_back_equal() {
    let mut nav = NavConfig::<f64> {
        imu_rate_hz: 400.0,
        mode: DelayMode::Fixed { delay_s: 0.15 },
        ..NavConfig::default()
    };
    nav.ekf.origin = Some(delaynav::Geodetic {
        lat_deg: 47.4,
        lon_deg: 8.5,
        alt_m: 400.0,
    });
    round_trip(nav);
    round_trip(NavConfig::<f32>::default());
    round_trip(Aekf17Config::<f64>::default());
    round_trip(CalibrationConfig::<f64>::default());
}

//! Configurations read from TOML: partial files over the defaults, unknown
//! keys refused by name, and a round trip through the serialized form.
#![cfg(feature = "serde")]

use delaynav::delay::CalibrationConfig;
use delaynav::delay::{
    CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4, CLEAN_INPUT_MIN_PEAK, DEFAULT_MIN_ACCEL_VARIANCE_M2_S4,
    DEFAULT_MIN_PEAK, GainFusionConfig,
};
use delaynav::{
    AugmentedEkf17Config, DelayCompensatedNavConfig, DelayLoopConfig, DelayMode, Ekf16Config,
    Scalar, SensorDelays,
};
use serde::Serialize;
use serde::de::DeserializeOwned;
use toml::{Table, Value};

fn parse<C: DeserializeOwned>(text: &str) -> Result<C, String> {
    toml::from_str(text).map_err(|e| e.to_string())
}

fn only_the_imu_rate<T: Scalar + DeserializeOwned>() {
    let config: DelayCompensatedNavConfig<T> = parse("imu_rate_hz = 50.0\n").unwrap();
    let expected = DelayCompensatedNavConfig {
        imu_rate_hz: T::lit(50.0),
        ..DelayCompensatedNavConfig::default()
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
    let config: DelayCompensatedNavConfig<f64> = parse(text).unwrap();
    let mut expected = DelayCompensatedNavConfig::<f64>::default();
    expected.ekf.gps_horizontal_std_m = 3.5;
    // A table that is present starts from its own type's defaults, which
    // are the navigator's: only the named field changes.
    expected.delay_loop.fusion.delay_max_s = 0.6;
    expected.mode = DelayMode::Fixed { delay_s: 0.25 };
    assert_eq!(config, expected);
}

#[test]
fn an_empty_file_is_the_default_of_every_config() {
    assert_eq!(
        parse::<DelayCompensatedNavConfig<f64>>("").unwrap(),
        DelayCompensatedNavConfig::default()
    );
    assert_eq!(
        parse::<Ekf16Config<f32>>("").unwrap(),
        Ekf16Config::default()
    );
    assert_eq!(
        parse::<AugmentedEkf17Config<f64>>("").unwrap(),
        AugmentedEkf17Config::default()
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
        let err = parse::<DelayCompensatedNavConfig<f64>>(text).unwrap_err();
        assert!(err.contains(key), "{text:?}: {err}");
    }
    let err = parse::<AugmentedEkf17Config<f64>>("max_delay = 1.0\n").unwrap_err();
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
    let mut nav = DelayCompensatedNavConfig::<f64> {
        imu_rate_hz: 400.0,
        mode: DelayMode::Fixed { delay_s: 0.15 },
        ..DelayCompensatedNavConfig::default()
    };
    nav.ekf.origin = Some(delaynav::Geodetic {
        lat_deg: 47.4,
        lon_deg: 8.5,
        alt_m: 400.0,
    });
    round_trip(nav);
    round_trip(DelayCompensatedNavConfig::<f32>::default());
    round_trip(AugmentedEkf17Config::<f64>::default());
    round_trip(CalibrationConfig::<f64>::default());
}

/// Every leaf of `table` (a number, a flag, an array) with its path.
fn leaves(table: &Table, path: &mut Vec<String>, out: &mut Vec<(Vec<String>, Value)>) {
    for (key, value) in table {
        path.push(key.clone());
        match value {
            Value::Table(t) => leaves(t, path, out),
            leaf => out.push((path.clone(), leaf.clone())),
        }
        path.pop();
    }
}

/// Another value of the same type (an array changes its first element);
/// `None` for text (an enum's unit variant).
fn changed(value: &Value) -> Option<Value> {
    Some(match value {
        Value::Float(f) => Value::Float(f * 1.5 + 1.0),
        Value::Integer(i) => Value::Integer(i + 1),
        Value::Boolean(b) => Value::Boolean(!b),
        Value::Array(a) => {
            let mut a = a.clone();
            a[0] = changed(&a[0])?;
            Value::Array(a)
        }
        _ => return None,
    })
}

/// `value` at `path` in `table`, creating the tables on the way.
fn set(table: &mut Table, path: &[String], value: Value) {
    let (last, tables) = path.split_last().unwrap();
    let mut t = table;
    for key in tables {
        t = t
            .entry(key.clone())
            .or_insert_with(|| Value::Table(Table::new()))
            .as_table_mut()
            .unwrap();
    }
    t.insert(last.clone(), value);
}

fn read<C: DeserializeOwned>(table: Table) -> C {
    let text = toml::to_string(&table).unwrap();
    parse(&text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

/// For every field of `C`'s default, nested ones too: a file holding that
/// field alone (inside its tables) reads as the default with that field
/// changed (the default written whole, that field changed, read back), and
/// differs from the default. Returns the number of fields.
fn each_field_alone<C>() -> usize
where
    C: Serialize + DeserializeOwned + Default + PartialEq + core::fmt::Debug,
{
    let defaults = Table::try_from(C::default()).unwrap();
    let mut fields = Vec::new();
    leaves(&defaults, &mut Vec::new(), &mut fields);
    let mut tested = 0;
    for (path, value) in fields {
        let Some(other) = changed(&value) else {
            continue;
        };
        let mut alone = Table::new();
        set(&mut alone, &path, other.clone());
        let mut whole = defaults.clone();
        set(&mut whole, &path, other);
        let partial: C = read(alone);
        assert_eq!(partial, read::<C>(whole), "{}", path.join("."));
        assert_ne!(partial, C::default(), "{}", path.join("."));
        tested += 1;
    }
    tested
}

/// The fields tested of each config in precision `T`.
fn every_config_field_alone<T>() -> [usize; 7]
where
    T: Scalar + Serialize + DeserializeOwned,
{
    let counts = [
        each_field_alone::<DelayCompensatedNavConfig<T>>(),
        each_field_alone::<Ekf16Config<T>>(),
        each_field_alone::<AugmentedEkf17Config<T>>(),
        each_field_alone::<DelayLoopConfig<T>>(),
        each_field_alone::<GainFusionConfig<T>>(),
        each_field_alone::<CalibrationConfig<T>>(),
        each_field_alone::<SensorDelays<T>>(),
    ];
    // The numeric and boolean fields (an array once, the unset origin and
    // the unit variants not): a field added later is covered without a
    // change here. The navigator's 76 are the EKF's 38, the loop's 32 (its
    // fusion's 7) and its own 6.
    let at_least = [76, 38, 44, 32, 7, 8, 3];
    assert!(
        counts.iter().zip(at_least).all(|(n, min)| *n >= min),
        "{counts:?}"
    );
    counts
}

#[test]
fn a_file_naming_one_field_changes_that_field_only() {
    // The same fields in both precisions.
    assert_eq!(
        every_config_field_alone::<f32>(),
        every_config_field_alone::<f64>()
    );
}

#[test]
fn the_issue_case_a_delay_loop_table_with_the_buffer_alone() {
    let config: DelayCompensatedNavConfig<f64> = parse("[delay_loop]\nbuffer_s = 5.0\n").unwrap();
    assert_eq!(config, DelayCompensatedNavConfig::default());
    assert_eq!(
        config.delay_loop.min_accel_variance_m2_s4,
        DEFAULT_MIN_ACCEL_VARIANCE_M2_S4
    );
    assert_eq!(config.delay_loop.min_peak, DEFAULT_MIN_PEAK);
}

#[test]
fn an_origin_table_sets_the_origin_and_needs_its_three_fields() {
    let text = "[ekf.origin]\nlat_deg = 47.0\nlon_deg = 8.5\nalt_m = 400.0\n";
    let config: DelayCompensatedNavConfig<f32> = parse(text).unwrap();
    let mut expected = DelayCompensatedNavConfig::default();
    expected.ekf.origin = Some(delaynav::Geodetic {
        lat_deg: 47.0,
        lon_deg: 8.5,
        alt_m: 400.0,
    });
    assert_eq!(config, expected);
    let err =
        parse::<DelayCompensatedNavConfig<f32>>("[ekf.origin]\nlat_deg = 47.0\n").unwrap_err();
    assert!(err.contains("lon_deg"), "{err}");
}

#[test]
fn one_default_per_field() {
    // The navigator's nested configurations are their types' defaults.
    let nav = DelayCompensatedNavConfig::<f64>::default();
    assert_eq!(nav.delay_loop, DelayLoopConfig::default());
    assert_eq!(nav.delay_loop.fusion, GainFusionConfig::default());
    assert_eq!(nav.ekf, Ekf16Config::default());
    assert_eq!(
        AugmentedEkf17Config::<f64>::default().nav,
        Ekf16Config::default()
    );
    // The validity thresholds the navigator has always run with; the clean
    // input preset keeps the values the loop alone had.
    assert_eq!(
        (
            nav.delay_loop.min_accel_variance_m2_s4,
            nav.delay_loop.min_peak
        ),
        (2.0, 0.9)
    );
    let clean = DelayLoopConfig::<f32>::clean_input();
    assert_eq!(
        (clean.min_accel_variance_m2_s4, clean.min_peak),
        (0.25, 0.5)
    );
    assert_eq!(
        (CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4, CLEAN_INPUT_MIN_PEAK),
        (0.25, 0.5)
    );
    assert_eq!(
        DelayLoopConfig {
            min_accel_variance_m2_s4: 2.0,
            min_peak: 0.9,
            ..clean
        },
        DelayLoopConfig::default()
    );
}

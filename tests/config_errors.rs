//! Configuration errors name the field by its path from the configuration
//! passed (`delay_loop.fusion.gamma`), its value and the bound it broke.

use delaynav::delay::{CalibrationConfig, DefaultCalibrator, GainFusionConfig};
use delaynav::error::Bound;
use delaynav::nav::WhiteningFilter;
use delaynav::{
    AugmentedEkf17Config, DefaultDelayLoop, DelayCompensatedNav, DelayCompensatedNavConfig,
    DelayLoopConfig, DelayMode, Ekf16Config, Error, Geodetic, Scalar, history_len,
};

fn nav_error<T: Scalar>(config: DelayCompensatedNavConfig<T>) -> (Error, String) {
    let e = config.validate().unwrap_err();
    (e, e.to_string())
}

fn messages<T: Scalar>() {
    let lit = T::lit;
    // delay_min > delay_max: named as the range, not as the start delay.
    let mut c = DelayCompensatedNavConfig::<T>::default();
    c.delay_loop.fusion.delay_min_s = lit(0.5);
    c.delay_loop.fusion.delay_max_s = lit(0.4);
    let (e, text) = nav_error(c);
    assert_eq!(
        e,
        Error::InvalidConfig {
            field: "delay_loop.fusion.delay_min_s".into(),
            value: Some(lit(0.5).as_f64()),
            bound: Bound::Below(lit(0.4).as_f64()),
        }
    );
    assert_eq!(
        text,
        "invalid configuration: `delay_loop.fusion.delay_min_s` = 0.5, must be below 0.4"
    );

    // The start delay outside the range: its value and the range.
    let c = DelayCompensatedNavConfig {
        mode: DelayMode::Estimated {
            initial_s: lit(0.5),
        },
        ..DelayCompensatedNavConfig::<T>::default()
    };
    let mut c = c;
    c.delay_loop.fusion.delay_max_s = lit(0.4);
    assert_eq!(
        nav_error(c).1,
        "invalid configuration: `mode.initial_s` = 0.5, must lie in [0, 0.4]"
    );

    // Latitude 95 deg is out of range, not "non-finite"; the path is the
    // one from the navigator's configuration.
    let mut c = DelayCompensatedNavConfig::<T>::default();
    c.ekf.origin = Some(Geodetic {
        lat_deg: 95.0,
        lon_deg: 8.0,
        alt_m: 400.0,
    });
    assert_eq!(
        nav_error(c).1,
        "invalid configuration: `ekf.origin.lat_deg` = 95, must lie in [-90, 90]"
    );

    // NaN is shown as such.
    let c = Ekf16Config {
        gps_vertical_std_m: lit(f64::NAN),
        ..Ekf16Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `gps_vertical_std_m` = NaN, must be positive and finite"
    );

    // An integer field's range.
    let c = Ekf16Config {
        align_min_duration_us: 60_000_001,
        ..Ekf16Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `align_min_duration_us` = 60000001, must lie in [0, 60000000]"
    );

    let c = AugmentedEkf17Config {
        initial_delay_s: lit(1.5),
        ..AugmentedEkf17Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `initial_delay_s` = 1.5, must lie in [0, 1]"
    );

    // The history capacity: its value, what it needs and why (the longest
    // delay times the IMU rate), and by how much to raise it.
    let e = DelayCompensatedNav::<T, 512>::new(DelayCompensatedNavConfig::default()).unwrap_err();
    let Error::InvalidConfig {
        field,
        value,
        bound: Bound::History {
            needed, short_by, ..
        },
    } = e
    else {
        panic!("{e:?}")
    };
    assert_eq!((field, value), ("HIST".into(), Some(512.0)));
    // 1 s at 1 kHz with the 2 % rate margin and 5 interpolation samples.
    assert!((1025..=1026).contains(&needed), "{e}");
    assert_eq!(short_by, needed - 512);
    assert_eq!(
        e.to_string(),
        format!(
            "invalid configuration: `HIST` = 512, must be >= {needed} IMU samples: the longest \
             delay 1 s (`delay_loop.fusion.delay_max_s` plus the whitening's group delay) times \
             the IMU rate 1000 Hz, with margins; raise the const generic `HIST` by {short_by}"
        )
    );
}

/// `configure` with the delay range `[0, delay_s]` at `rate_hz` in a
/// navigator of history `HIST`: accepted or refused for its history.
fn fits<T: Scalar, const HIST: usize>(delay_s: f64, rate_hz: f64) -> bool {
    let mut config = DelayCompensatedNavConfig::<T> {
        imu_rate_hz: T::lit(rate_hz),
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.delay_max_s = T::lit(delay_s);
    match DelayCompensatedNav::<T, HIST>::new(config) {
        Ok(_) => true,
        Err(Error::InvalidConfig {
            bound: Bound::History { .. },
            ..
        }) => false,
        Err(e) => panic!("{delay_s} s at {rate_hz} Hz: {e}"),
    }
}

/// `history_len` is the smallest history `configure` accepts, in both
/// precisions.
#[test]
fn history_len_is_the_smallest_history_configure_accepts() {
    macro_rules! smallest {
        ($delay:expr, $rate:expr) => {{
            const N: usize = history_len($delay, $rate);
            for ok in [fits::<f32, N>($delay, $rate), fits::<f64, N>($delay, $rate)] {
                assert!(ok, "{} s at {} Hz: {N} refused", $delay, $rate);
            }
            // One less is refused in the precision that needs it.
            let short = [
                fits::<f32, { N - 1 }>($delay, $rate),
                fits::<f64, { N - 1 }>($delay, $rate),
            ];
            assert!(
                short.contains(&false),
                "{} s at {} Hz: {} accepted",
                $delay,
                $rate,
                N - 1
            );
            N
        }};
    }
    assert_eq!(smallest!(0.4, 1000.0), 413);
    assert_eq!(smallest!(0.5, 1000.0), 515);
    assert_eq!(smallest!(1.0, 1000.0), 1025);
    assert_eq!(smallest!(1.0, 200.0), 209);
    assert_eq!(smallest!(0.3, 400.0), 128);
    assert_eq!(smallest!(0.25, 50.0), 18);
}

#[test]
fn messages_name_the_field_the_value_and_the_bound() {
    messages::<f32>();
    messages::<f64>();
    each_section::<f32>();
    each_section::<f64>();
}

fn fixed_mode_below_the_loop_default<T: Scalar>() {
    // The loop's default start (0.2 s) lies outside this range; the loop is
    // off in Fixed mode and starts at the fixed delay instead.
    let mut c = DelayCompensatedNavConfig::<T> {
        mode: DelayMode::Fixed {
            delay_s: T::lit(0.1),
        },
        ..DelayCompensatedNavConfig::default()
    };
    c.delay_loop.fusion.delay_max_s = T::lit(0.15);
    c.validate().unwrap();
    DelayCompensatedNav::<T>::new(c).unwrap();
    assert_eq!(c.loop_config().fusion.initial_delay_s, T::lit(0.1));

    // Beyond the maximum it is an error naming the mode's delay.
    c.mode = DelayMode::Fixed {
        delay_s: T::lit(0.2),
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `mode.delay_s` = 0.2, must lie in [0, 0.15]"
    );
}

#[test]
fn fixed_mode_with_a_maximum_below_the_loop_default_start_is_valid() {
    fixed_mode_below_the_loop_default::<f32>();
    fixed_mode_below_the_loop_default::<f64>();
}

#[test]
fn the_start_delay_is_set_by_the_mode_only() {
    // The loop's own start is ignored by the navigator: the mode's wins.
    let mut c = DelayCompensatedNavConfig::<f64> {
        mode: DelayMode::Estimated { initial_s: 0.3 },
        ..DelayCompensatedNavConfig::default()
    };
    c.delay_loop.fusion.initial_delay_s = 0.9;
    c.validate().unwrap();
    assert_eq!(c.loop_config().fusion.initial_delay_s, 0.3);
    let nav = DelayCompensatedNav::<f64>::new(c).unwrap();
    assert_eq!(nav.delay_s(), 0.3);
}

/// The text of the error of `config` through `DelayCompensatedNav::new`
/// (validation, then the capacities).
fn nav_text<T: Scalar>(config: DelayCompensatedNavConfig<T>) -> String {
    DelayCompensatedNav::<T>::new(config)
        .err()
        .unwrap()
        .to_string()
}

fn invalid(path_value_bound: &str) -> String {
    format!("invalid configuration: {path_value_bound}")
}

/// Sets one bad value in a configuration.
type Setter<T> = fn(&mut DelayCompensatedNavConfig<T>);

/// A representative bad value in each section of each configuration: the
/// path as written in a file, the value and the bound.
fn each_section<T: Scalar>() {
    let lit = T::lit;
    // DelayCompensatedNavConfig: top level, a variant's field, a whitening filter, [ekf],
    // [delay_loop] (checked by `validate` and by the loop's capacities),
    // [delay_loop.fusion].
    let cases: [(Setter<T>, &str); 9] = [
        (
            |c| c.imu_rate_hz = T::lit(0.0),
            "`imu_rate_hz` = 0, must be positive and finite",
        ),
        (
            |c| {
                c.gyro_whitening = WhiteningFilter::LowPass {
                    cutoff_hz: T::lit(600.0),
                }
            },
            "`gyro_whitening.cutoff_hz` = 600, must be below 500",
        ),
        (
            |c| c.ekf.gps_vertical_std_m = T::lit(-2.0),
            "`ekf.gps_vertical_std_m` = -2, must be positive and finite",
        ),
        (
            |c| c.delay_loop.min_peak = T::lit(1.0),
            "`delay_loop.min_peak` = 1, must lie in [0, 1)",
        ),
        (
            |c| c.delay_loop.buffer_s = T::lit(5.1),
            "`delay_loop.buffer_s` = 5.1, must be <= 5 to fit the delay loop's const generic \
             `BUF` (125 samples)",
        ),
        (
            |c| c.delay_loop.measurement_noise_ms2[1] = T::lit(-1.0),
            "`delay_loop.measurement_noise_ms2[1]` = -1, must be positive and finite",
        ),
        (
            |c| c.delay_loop.max_gps_gap_s = T::lit(0.0),
            "`delay_loop.max_gps_gap_s` = 0, must be positive and finite",
        ),
        (
            |c| c.delay_loop.fusion.gamma = T::lit(0.0),
            "`delay_loop.fusion.gamma` = 0, must lie in (0, 1]",
        ),
        (
            |c| c.delay_loop.fusion.rate_time_constant_s = T::lit(-1.0),
            "`delay_loop.fusion.rate_time_constant_s` = -1, must be positive and finite",
        ),
    ];
    for (set, expected) in cases {
        let mut c = DelayCompensatedNavConfig::<T>::default();
        set(&mut c);
        assert_eq!(nav_text(c), invalid(expected));
    }

    // AugmentedEkf17Config: its [nav] table and its own fields.
    let mut c = AugmentedEkf17Config::<T>::default();
    c.nav.gyro_noise_density = lit(-1.0);
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        invalid("`nav.gyro_noise_density` = -1, must be positive and finite")
    );
    let c = AugmentedEkf17Config {
        delay_random_walk: lit(f64::INFINITY),
        ..AugmentedEkf17Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        invalid("`delay_random_walk` = inf, must be finite and >= 0")
    );

    // DelayLoopConfig alone: paths from the loop's configuration.
    let loop_text =
        |c: DelayLoopConfig<T>| DefaultDelayLoop::<T>::new(c).err().unwrap().to_string();
    let c = DelayLoopConfig::<T> {
        gps_diff_span: 9,
        ..Default::default()
    };
    assert_eq!(
        loop_text(c),
        invalid("`gps_diff_span` = 9, must lie in [1, 8]")
    );
    let mut c = DelayLoopConfig::<T>::default();
    c.fusion.initial_delay_s = lit(1.5);
    assert_eq!(
        loop_text(c),
        invalid("`fusion.initial_delay_s` = 1.5, must lie in [0, 1]")
    );
    let mut c = DelayLoopConfig::<T>::default();
    c.fusion.delay_max_s = lit(1.5);
    assert_eq!(
        loop_text(c),
        invalid(
            "`fusion.delay_max_s` = 1.5, must be <= 1.2 to fit the delay loop's const generic \
             `LAGS` (31 samples)"
        )
    );
    // A range as wide as `LAGS` allows, further out: the buffer, the
    // largest shift and the lead no longer fit the IMU grid history.
    let mut c = DelayLoopConfig::<T>::default();
    c.fusion.delay_min_s = lit(0.5);
    c.fusion.delay_max_s = lit(1.7);
    c.fusion.initial_delay_s = lit(0.6);
    assert_eq!(
        loop_text(c),
        invalid(
            "`buffer_s` = 5, must be <= 4.72 to fit the delay loop's const generic `HIST` \
             (192 samples)"
        )
    );

    // GainFusionConfig alone.
    let c = GainFusionConfig {
        delay_min_s: lit(0.5),
        delay_max_s: lit(0.5),
        ..GainFusionConfig::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        invalid("`delay_min_s` = 0.5, must be below 0.5")
    );

    // CalibrationConfig: a field, and the capacities of the calibrator.
    let c = CalibrationConfig {
        min_pairs: 2,
        ..CalibrationConfig::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        invalid("`min_pairs` = 2, must be >= 3")
    );
    let c = CalibrationConfig {
        max_shift_s: lit(7.0),
        ..CalibrationConfig::<T>::default()
    };
    assert_eq!(
        DefaultCalibrator::<T>::new(c).err().unwrap().to_string(),
        invalid(
            "`max_shift_s` = 7, must be <= 6 to fit the calibrator's const generic `SHIFTS` \
             (601 samples)"
        )
    );
}

#[test]
fn a_path_compares_equal_to_its_text_and_the_error_stays_small() {
    let mut c = DelayCompensatedNavConfig::<f64>::default();
    c.delay_loop.fusion.gamma = 2.0;
    let Err(Error::InvalidConfig { field, .. }) = c.validate() else {
        panic!("expected InvalidConfig")
    };
    assert_eq!(field, "delay_loop.fusion.gamma");
    assert_eq!(field.field(), "gamma");
    assert_eq!(
        field.segments().collect::<Vec<_>>(),
        ["delay_loop", "fusion", "gamma"]
    );
    assert_eq!(
        field,
        delaynav::error::ConfigPath::new("delay_loop.fusion.gamma")
    );
    assert_ne!(field, "delay_loop.fusion");
    assert_ne!(field, "delay_loop.fusion.gamma.x");
    // Returned by every push: the path's tables cost one byte each (56
    // bytes before the paths, 64 with them).
    assert!(core::mem::size_of::<Error>() <= 64);
}

/// The ceilings found by the fuzz targets: each value was accepted before
/// and broke the `f32` state (docs/faults.md); the largest accepted value
/// and the smallest refused one of each.
fn magnitude_ceilings<T: Scalar>() {
    type Set<T> = fn(&mut Ekf16Config<T>, T);
    let cases: [(&str, Set<T>, f64, f64); 5] = [
        (
            "initial_position_std_m",
            |c, v| c.initial_position_std_m = v,
            1e7,
            1e30,
        ),
        (
            "initial_tilt_std_rad",
            |c, v| c.initial_tilt_std_rad = v,
            3.1,
            10_001.0,
        ),
        (
            "gyro_bias_random_walk",
            |c, v| c.gyro_bias_random_walk = v,
            1.0,
            1e30,
        ),
        (
            "accel_noise_density",
            |c, v| c.accel_noise_density = v,
            10.0,
            1e4,
        ),
        (
            "gyro_noise_density",
            |c, v| c.gyro_noise_density = v,
            1.0,
            1.5,
        ),
    ];
    for (field, set, accepted, refused) in cases {
        let mut c = Ekf16Config::<T>::default();
        set(&mut c, T::lit(accepted));
        assert_eq!(c.validate(), Ok(()), "{field} = {accepted}");
        set(&mut c, T::lit(refused));
        match c.validate() {
            Err(Error::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field} = {refused}: {other:?}"),
        }
    }
}

#[test]
fn magnitudes_that_broke_the_f32_state_are_refused() {
    magnitude_ceilings::<f32>();
    magnitude_ceilings::<f64>();
}

/// `max_imu_step_us` is at most `MAX_TIME_JUMP_US` (1 s): the `aekf17`
/// fuzz target configured 1e9 µs, and steps of 1,000 s were integrated
/// (docs/faults.md). The error names the key, the value and the bound.
fn imu_step_bound<T: Scalar>() {
    let mut c = Ekf16Config::<T> {
        max_imu_step_us: delaynav::ekf16::MAX_TIME_JUMP_US,
        ..Ekf16Config::default()
    };
    assert_eq!(c.validate(), Ok(()));
    for refused in [1_000_001, 1_000_000_000] {
        c.max_imu_step_us = refused;
        let e = c.validate().expect_err("refused");
        assert_eq!(
            e.to_string(),
            invalid(&format!(
                "`max_imu_step_us` = {refused}, must lie in [1, 1000000]"
            )),
        );
    }
    c.max_imu_step_us = u64::MAX;
    assert!(matches!(
        c.validate(),
        Err(Error::InvalidConfig { field, .. }) if field == "max_imu_step_us"
    ));
}

#[test]
fn the_imu_step_is_at_most_a_time_jump() {
    imu_step_bound::<f32>();
    imu_step_bound::<f64>();
}

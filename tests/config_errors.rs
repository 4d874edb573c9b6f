//! Configuration errors name the field, its value and the bound it broke.

use delaynav::error::Bound;
use delaynav::{
    Aekf17Config, DelayCompensatedNav, DelayMode, Ekf16Config, Error, Geodetic, NavConfig, Scalar,
};

fn nav_error<T: Scalar>(config: NavConfig<T>) -> (Error, String) {
    let e = config.validate().unwrap_err();
    (e, e.to_string())
}

fn messages<T: Scalar>() {
    let lit = T::lit;
    // delay_min > delay_max: named as the range, not as the start delay.
    let mut c = NavConfig::<T>::default();
    c.delay_loop.fusion.delay_min_s = lit(0.5);
    c.delay_loop.fusion.delay_max_s = lit(0.4);
    let (e, text) = nav_error(c);
    assert_eq!(
        e,
        Error::InvalidConfig {
            field: "delay_loop.fusion.delay_min_s",
            value: Some(lit(0.5).as_f64()),
            bound: Bound::Below(lit(0.4).as_f64()),
        }
    );
    assert_eq!(
        text,
        "invalid configuration: `delay_loop.fusion.delay_min_s` = 0.5, must be below 0.4"
    );

    // The start delay outside the range: its value and the range.
    let c = NavConfig {
        mode: DelayMode::Estimated {
            initial_s: lit(0.5),
        },
        ..NavConfig::<T>::default()
    };
    let mut c = c;
    c.delay_loop.fusion.delay_max_s = lit(0.4);
    assert_eq!(
        nav_error(c).1,
        "invalid configuration: `mode.initial_s` = 0.5, must lie in [0, 0.4]"
    );

    // Latitude 95 deg is out of range, not "non-finite".
    let mut c = NavConfig::<T>::default();
    c.ekf.origin = Some(Geodetic {
        lat_deg: 95.0,
        lon_deg: 8.0,
        alt_m: 400.0,
    });
    assert_eq!(
        nav_error(c).1,
        "invalid configuration: `origin.lat_deg` = 95, must lie in [-90, 90]"
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

    // A relation between fields carries the other field's value.
    let c = Ekf16Config {
        align_min_samples: 300,
        ..Ekf16Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `align_min_samples` = 300, must be <= 200"
    );

    let c = Aekf17Config {
        initial_delay_s: lit(1.5),
        ..Aekf17Config::<T>::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `initial_delay_s` = 1.5, must lie in [0, 1]"
    );

    // The history capacity: its value and what it needs.
    let e = DelayCompensatedNav::<T, 512>::new(NavConfig::default()).unwrap_err();
    assert!(
        matches!(e, Error::InvalidConfig { field: "HIST", value: Some(v), bound: Bound::AtLeast(n) } if v == 512.0 && n > 512.0),
        "{e}"
    );
}

#[test]
fn messages_name_the_field_the_value_and_the_bound() {
    messages::<f32>();
    messages::<f64>();
}

fn fixed_mode_below_the_loop_default<T: Scalar>() {
    // The loop's default start (0.2 s) lies outside this range; the loop is
    // off in Fixed mode and starts at the fixed delay instead.
    let mut c = NavConfig::<T> {
        mode: DelayMode::Fixed {
            delay_s: T::lit(0.1),
        },
        ..NavConfig::default()
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
    let mut c = NavConfig::<f64> {
        mode: DelayMode::Estimated { initial_s: 0.3 },
        ..NavConfig::default()
    };
    c.delay_loop.fusion.initial_delay_s = 0.9;
    c.validate().unwrap();
    assert_eq!(c.loop_config().fusion.initial_delay_s, 0.3);
    let nav = DelayCompensatedNav::<f64>::new(c).unwrap();
    assert_eq!(nav.delay_s(), 0.3);
}

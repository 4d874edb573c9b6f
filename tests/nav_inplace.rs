//! Construction in place: the `const` blank values (`BLANK`) refuse every
//! sample until `configure` succeeds; `configure` on a blank value, on a
//! navigator in use, or twice, gives the navigator `new` gives (same
//! estimates, health and work, f32 and f64); a failed `configure` leaves it
//! refusing.

mod common;

use common::Motion;
use common::flight::{DECLINATION, Flight, FlightEvent, INCLINATION, Suite, feed, fly};
use delaynav::delay::{DefaultDelayLoop, DelayLoopConfig};
use delaynav::nav::{AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Error, Estimate, Gps, GpsPosition,
    Imu, Mag, Navigator, Scalar,
};
use nalgebra::Vector3;

/// History for a 0.5 s range at 1 kHz (515 needed).
const HIST: usize = 520;

fn config<T: Scalar>(mode: DelayMode<T>) -> DelayCompensatedNavConfig<T> {
    let mut config = DelayCompensatedNavConfig {
        ekf: Ekf16Config {
            mag_inclination_rad: T::lit(INCLINATION),
            mag_declination_rad: T::lit(DECLINATION),
            ..Ekf16Config::default()
        },
        mode,
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.delay_max_s = T::lit(0.5);
    config
}

fn estimated<T: Scalar>() -> DelayCompensatedNavConfig<T> {
    config(DelayMode::Estimated {
        initial_s: T::lit(0.15),
    })
}

fn events(seconds: f64) -> Vec<FlightEvent> {
    let flight = Flight::new(Motion::random(11, 6, 0.05, 0.5, [3.0, 3.0, 1.0]));
    fly(&flight, &Suite::simulator(), seconds, |_| 0.2, None)
}

/// The present and the horizon estimate after one IMU sample.
type Estimates<T> = (Option<Estimate<T>>, Option<Estimate<T>>);

/// Every estimate (present and horizon) after each IMU sample.
fn trace<T: Scalar, N: Navigator<T>>(
    nav: &mut N,
    events: &[FlightEvent],
    horizon: impl Fn(&N) -> Option<Estimate<T>>,
) -> Vec<Estimates<T>> {
    events
        .iter()
        .filter_map(|e| feed(nav, e).map(|_| (nav.estimate(), horizon(nav))))
        .collect()
}

/// Every push's outcome and the estimate after each, of any estimator
/// (in its Debug form, which round-trips the values).
fn outcomes<T: Scalar, N: Navigator<T>>(nav: &mut N, events: &[FlightEvent]) -> Vec<String> {
    let v3 = |v: &Vector3<f64>| v.map(T::lit);
    events
        .iter()
        .map(|event| {
            let outcome = match event {
                FlightEvent::Imu(s, _) => format!(
                    "{:?}",
                    nav.push_imu(&Imu {
                        t_us: s.t_us,
                        gyro_rad_s: v3(&s.gyro_rad_s),
                        accel_m_s2: v3(&s.accel_m_s2),
                    })
                ),
                FlightEvent::Mag(m) => format!(
                    "{:?}",
                    nav.push_mag(&Mag {
                        t_us: m.t_us,
                        field_body: v3(&m.field_body),
                    })
                ),
                FlightEvent::Gps(g) => {
                    let GpsPosition::Ned(r) = g.position else {
                        unreachable!("flights use NED fixes")
                    };
                    format!(
                        "{:?}",
                        nav.push_gps(&Gps {
                            t_us: g.t_us,
                            position: GpsPosition::Ned(v3(&r)),
                            velocity_ned_m_s: v3(&g.velocity_ned_m_s),
                            horizontal_accuracy_m: None,
                            vertical_accuracy_m: None,
                            speed_accuracy_m_s: None,
                        })
                    )
                }
            };
            format!("{outcome} {:?}", nav.estimate())
        })
        .collect()
}

fn samples<T: Scalar>() -> (Imu<T>, Gps<T>, Mag<T>) {
    (
        Imu {
            t_us: 1000,
            gyro_rad_s: Vector3::zeros(),
            accel_m_s2: Vector3::new(T::zero(), T::zero(), T::lit(-9.8)),
        },
        Gps {
            t_us: 1000,
            position: GpsPosition::Ned(Vector3::zeros()),
            velocity_ned_m_s: Vector3::zeros(),
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        },
        Mag {
            t_us: 1000,
            field_body: Vector3::new(T::lit(0.3), T::zero(), T::lit(0.4)),
        },
    )
}

/// A navigator that refuses everything and says why.
fn assert_refusing<T: Scalar>(nav: &mut DelayCompensatedNav<T, HIST>) {
    let (imu, gps, mag) = samples::<T>();
    assert!(!nav.is_configured());
    assert_eq!(nav.push_imu(&imu), Err(Error::NotConfigured));
    assert_eq!(nav.push_gps(&gps), Err(Error::NotConfigured));
    assert_eq!(nav.push_mag(&mag), Err(Error::NotConfigured));
    assert_eq!(nav.estimate(), None);
    assert_eq!(nav.horizon_estimate(), None);
    assert_eq!(nav.acceleration_ned_m_s2(), None);
    let health = nav.health();
    assert_eq!(health.alignment, AlignmentState::NotConfigured);
    assert!(!(health.tilt_valid || health.velocity_valid || health.position_valid));
    assert!(health.delay.delay_s.is_finite() && health.delay.delay_std_s.is_finite());
    nav.reset();
    assert_eq!(nav.push_imu(&imu), Err(Error::NotConfigured));
}

fn blank_refuses<T: Scalar>() {
    let mut nav = DelayCompensatedNav::<T, HIST>::BLANK;
    assert_refusing(&mut nav);

    let (imu, gps, mag) = samples::<T>();
    let mut ekf = Ekf16::<T>::BLANK;
    assert!(!ekf.is_configured());
    assert_eq!(ekf.push_imu(&imu), Err(Error::NotConfigured));
    assert_eq!(ekf.push_gps(&gps), Err(Error::NotConfigured));
    assert_eq!(ekf.push_mag(&mag), Err(Error::NotConfigured));
    assert_eq!(ekf.estimate(), None);
    let mut aekf = AugmentedEkf17::<T>::BLANK;
    assert!(!aekf.is_configured());
    assert_eq!(aekf.push_imu(&imu), Err(Error::NotConfigured));
    assert_eq!(aekf.push_gps(&gps), Err(Error::NotConfigured));
    assert_eq!(aekf.estimate(), None);
    let mut delay_loop = DefaultDelayLoop::<T>::BLANK;
    assert!(!delay_loop.is_configured());
    assert_eq!(
        delay_loop.push_imu(1000, Vector3::zeros()),
        Err(Error::NotConfigured)
    );
    assert_eq!(
        delay_loop.push_gps(1000, Vector3::zeros()),
        Err(Error::NotConfigured)
    );
    assert_eq!(
        delay_loop.set_delay(T::lit(0.1), T::lit(0.01)),
        Err(Error::NotConfigured)
    );
}

/// `BLANK` + `configure`, a navigator configured twice (the second time in
/// use) and one whose `configure` failed before a good one all run as the
/// one `new` built.
fn configure_equals_new<T: Scalar>(mode: DelayMode<T>) {
    let events = events(14.0);
    let config = config(mode);
    let horizon = |n: &DelayCompensatedNav<T, HIST>| n.horizon_estimate();

    let mut built = DelayCompensatedNav::<T, HIST>::new(config).unwrap();
    let reference = trace(&mut built, &events, horizon);
    assert!(
        reference.last().is_some_and(|(now, _)| now.is_some()),
        "the navigator aligned"
    );

    let mut nav = DelayCompensatedNav::<T, HIST>::BLANK;
    nav.configure(config).unwrap();
    assert!(nav.is_configured());
    assert_eq!(trace(&mut nav, &events, horizon), reference);
    assert_eq!(nav.health(), built.health());
    assert_eq!(nav.work(), built.work());
    assert_eq!(nav.refusals(), built.refusals());
    assert_eq!(nav.refusals().horizon, built.refusals().horizon);

    // Configured again while in use (after a request to reset, too): as new.
    nav.reset();
    nav.configure(config).unwrap();
    assert_eq!(nav.health().alignment, AlignmentState::WaitingForImu);
    assert_eq!(nav.health().last_reset, None);
    assert_eq!(trace(&mut nav, &events, horizon), reference);
    assert_eq!(nav.health(), built.health());
    assert_eq!(nav.work(), built.work());

    // A failed configure (a range beyond HIST) leaves it refusing, a good
    // one brings it back as new.
    let mut too_long = config;
    too_long.delay_loop.fusion.delay_max_s = T::lit(0.6);
    assert!(matches!(
        nav.configure(too_long),
        Err(Error::InvalidConfig { field, .. }) if field == "HIST"
    ));
    assert_refusing(&mut nav);
    let mut invalid = config;
    invalid.imu_rate_hz = T::lit(f64::NAN);
    assert!(nav.configure(invalid).is_err());
    assert_refusing(&mut nav);
    nav.configure(config).unwrap();
    assert_eq!(trace(&mut nav, &events, horizon), reference);
    assert_eq!(nav.health(), built.health());
}

fn filters_configure_equals_new<T: Scalar>() {
    let events = events(6.0);
    let nav = Ekf16Config::<T> {
        mag_inclination_rad: T::lit(INCLINATION),
        mag_declination_rad: T::lit(DECLINATION),
        ..Ekf16Config::default()
    };

    let mut built = Ekf16::new(nav).unwrap();
    let reference = outcomes(&mut built, &events);
    assert!(
        reference
            .last()
            .is_some_and(|e| e.contains("Some(Estimate"))
    );
    let mut ekf = Ekf16::BLANK;
    ekf.configure(nav).unwrap();
    assert_eq!(outcomes(&mut ekf, &events), reference);
    let mut bad = nav;
    bad.gravity_m_s2 = T::lit(f64::NAN);
    assert!(ekf.configure(bad).is_err());
    assert!(!ekf.is_configured() && ekf.estimate().is_none());
    ekf.configure(nav).unwrap();
    assert_eq!(outcomes(&mut ekf, &events), reference);
    assert_eq!(ekf.refusals(), built.refusals());

    let config = AugmentedEkf17Config {
        initial_delay_s: T::lit(0.2),
        ..AugmentedEkf17Config::with_nav(nav)
    };
    let mut built = AugmentedEkf17::new(config).unwrap();
    let reference = outcomes(&mut built, &events);
    let mut aekf = AugmentedEkf17::BLANK;
    aekf.configure(config).unwrap();
    assert_eq!(outcomes(&mut aekf, &events), reference);
    let mut bad = config;
    bad.initial_delay_s = T::lit(-1.0);
    assert!(aekf.configure(bad).is_err());
    assert!(!aekf.is_configured() && aekf.estimate().is_none());
    aekf.configure(config).unwrap();
    assert_eq!(outcomes(&mut aekf, &events), reference);

    // The delay loop alone: the same updates.
    let loop_config = DelayLoopConfig::<T>::clean_input();
    let mut built = DefaultDelayLoop::new(loop_config).unwrap();
    let mut delay_loop = DefaultDelayLoop::BLANK;
    delay_loop.configure(loop_config).unwrap();
    for pass in 0..2 {
        if pass == 1 {
            built = DefaultDelayLoop::new(loop_config).unwrap();
            delay_loop.configure(loop_config).unwrap();
        }
        for k in 1..=8000u64 {
            let t_us = k * 1000;
            let t = t_us as f64 * 1e-6;
            let a = Vector3::new((1.3 * t).sin(), (0.7 * t).cos(), (2.1 * t).sin()).map(T::lit);
            assert_eq!(built.push_imu(t_us, a), delay_loop.push_imu(t_us, a));
            if k % 100 == 0 {
                let v = Vector3::new(-(1.3 * t).cos() / 1.3, 0.0, 0.0).map(T::lit);
                assert_eq!(built.push_gps(t_us, v), delay_loop.push_gps(t_us, v));
            }
        }
        assert_eq!(built.delay_s(), delay_loop.delay_s());
        assert_eq!(built.multiply_adds(), delay_loop.multiply_adds());
    }
}

macro_rules! inplace_tests {
    ($name:ident, $t:ty) => {
        mod $name {
            use super::*;

            #[test]
            fn blank_values_refuse_every_sample() {
                blank_refuses::<$t>();
            }

            #[test]
            fn configure_in_place_equals_new_estimated() {
                configure_equals_new::<$t>(DelayMode::Estimated {
                    initial_s: <$t>::lit(0.15),
                });
            }

            #[test]
            fn configure_in_place_equals_new_fixed() {
                configure_equals_new::<$t>(DelayMode::Fixed {
                    delay_s: <$t>::lit(0.2),
                });
            }

            #[test]
            fn filters_configure_in_place_equals_new() {
                filters_configure_equals_new::<$t>();
            }
        }
    };
}

inplace_tests!(f32_tests, f32);
inplace_tests!(f64_tests, f64);

/// The pattern of the docs: a `static` (here behind a `Mutex`) holding the
/// blank value, configured where it lives.
#[test]
fn a_static_navigator_is_configured_in_place() {
    use std::sync::Mutex;
    static NAV: Mutex<DelayCompensatedNav<f32, HIST>> = Mutex::new(DelayCompensatedNav::BLANK);
    let mut nav = NAV.lock().unwrap();
    assert_refusing(&mut nav);
    nav.configure(estimated()).unwrap();
    let events = events(8.0);
    for e in &events {
        feed(&mut *nav, e);
    }
    assert_eq!(nav.health().alignment, AlignmentState::Aligned);
}

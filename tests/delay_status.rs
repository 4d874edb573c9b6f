//! The delay loop of issue 11 on synthetic truth (tests/common): status
//! (waiting, acquiring, locked, out of range), negative delays in the range,
//! low GPS rates with `adapted_to_gps_rate`, re-acquisition after a step;
//! f32 and f64.

mod common;

use common::{Event, Motion, Scenario};
use delaynav::Error;
use delaynav::delay::*;
use nalgebra::Vector3;

/// (time s, delay s, status, std s) per update.
type Updates<T> = Vec<(f64, f64, DelayStatus<T>, f64)>;

macro_rules! status_tests {
    ($mod:ident, $t:ty) => {
        mod $mod {
            use super::*;
            type T = $t;

            fn v3(a: [f64; 3]) -> Vector3<T> {
                Vector3::new(a[0] as T, a[1] as T, a[2] as T)
            }

            fn run(
                scenario: &Scenario,
                motion: &Motion,
                delay: impl Fn(f64) -> f64,
                config: DelayLoopConfig<T>,
            ) -> Updates<T> {
                let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
                assert_eq!(delay_loop.status(), DelayStatus::WaitingForData);
                let mut updates = Vec::new();
                for event in scenario.events(motion, &delay) {
                    match event {
                        Event::Imu(t, a) => delay_loop.push_imu(t, v3(a)).unwrap(),
                        Event::Gps(t, v) => {
                            if let Some(u) = delay_loop.push_gps(t, v3(v)).unwrap() {
                                assert_eq!(u.status, delay_loop.status());
                                updates.push((t as f64 * 1e-6, u.delay_s as f64, u.status, u.delay_std_s as f64));
                            }
                        }
                    }
                }
                updates
            }

            fn rmse_after(updates: &Updates<T>, from_s: f64, truth: f64) -> f64 {
                let tail: Vec<f64> = updates.iter().filter(|u| u.0 >= from_s).map(|u| u.1 - truth).collect();
                assert!(tail.len() > 10, "too few updates after {from_s} s");
                (tail.iter().map(|e| e * e).sum::<f64>() / tail.len() as f64).sqrt()
            }

            fn config(start_s: f64, range_s: (f64, f64)) -> DelayLoopConfig<T> {
                let mut config = DelayLoopConfig::<T>::clean_input();
                config.fusion.delay_min_s = range_s.0 as T;
                config.fusion.delay_max_s = range_s.1 as T;
                config.fusion.initial_delay_s = start_s as T;
                config
            }

            fn strong_motion(seed: u64) -> Motion {
                Motion::random(seed, 8, 0.05, 1.0, [6.0, 6.0, 3.0])
            }

            /// From a cold start the loop waits for data, acquires (if only
            /// briefly), then locks;
            /// at hover it waits for motion and never locks.
            #[test]
            fn cold_start_acquires_then_locks_and_hover_waits() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 60.0;
                let updates = run(&scenario, &strong_motion(3), |_| 0.2, config(0.1, (0.0, 1.0)));
                let locked_at = updates.iter().find(|u| u.2.is_locked()).map(|u| u.0);
                let locked_at = locked_at.expect("locks");
                assert!(locked_at < 30.0, "locked at {locked_at} s");
                // Strong motion: locked within seconds of the first full window.
                assert!(locked_at - updates[0].0 < 3.0, "{locked_at} vs {}", updates[0].0);
                assert!(updates.iter().take_while(|u| u.0 < locked_at).all(|u| u.2 == DelayStatus::Acquiring));
                assert!(rmse_after(&updates, 40.0, 0.2) < 5e-3);
                let hover = run(&scenario, &Motion::hover(), |_| 0.2, config(0.1, (0.0, 1.0)));
                assert!(!hover.is_empty());
                assert!(hover.iter().all(|u| u.2 == DelayStatus::WaitingForMotion));
                assert!(hover.iter().all(|u| u.1 == 0.1 as T as f64));
            }

            /// The reported sigma, matched to the innovations once locked,
            /// covers a fair share of the errors: neither the GFA model's
            /// pessimism (nearly every error inside) nor overconfidence.
            #[test]
            fn reported_sigma_covers_the_errors() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 120.0;
                let (mut inside, mut total) = (0usize, 0usize);
                for seed in 1..=4u64 {
                    scenario.seed = seed;
                    let updates = run(&scenario, &strong_motion(40 + seed), |_| 0.2, config(0.2, (0.0, 1.0)));
                    for u in updates.iter().filter(|u| u.0 >= 30.0) {
                        inside += usize::from((u.1 - 0.2).abs() <= u.3);
                        total += 1;
                    }
                }
                let coverage = inside as f64 / total as f64;
                println!("1-sigma coverage {coverage:.3}");
                assert!((0.4..=0.95).contains(&coverage), "{coverage}");
            }

            /// A negative delay (the GPS leads the IMU) inside a range that
            /// includes it is estimated like a positive one.
            #[test]
            fn negative_delay_in_range_is_estimated() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 90.0;
                for tau in [-0.15, -0.42] {
                    let updates = run(&scenario, &strong_motion(8), |_| tau, config(0.1, (-0.5, 0.6)));
                    let rmse = rmse_after(&updates, 45.0, tau);
                    assert!(rmse < 5e-3, "tau {tau}: RMSE {rmse}");
                    assert!(updates.last().unwrap().2.is_locked());
                }
            }

            /// A delay below the range is reported with the edge and the
            /// peak value, not clamped silently; the estimate is not dragged
            /// to the edge.
            #[test]
            fn delay_below_range_is_reported() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 40.0;
                let updates = run(&scenario, &strong_motion(9), |_| -0.15, config(0.3, (0.0, 1.0)));
                let first = updates.iter().find(|u| u.2.is_out_of_range()).expect("reported");
                assert!(first.0 < 15.0, "reported at {} s", first.0);
                match first.2 {
                    DelayStatus::BelowRange { edge_s, peak, share } => {
                        assert!((0.5..=1.0).contains(&share), "{share}");
                        assert_eq!(edge_s, 0.0);
                        assert!(peak > 0.5 && peak <= 1.0, "{peak}");
                    }
                    other => panic!("{other:?}"),
                }
                assert!(updates.iter().all(|u| u.1 > 0.2), "estimate moved toward the edge");
                // And above the range.
                let updates = run(&scenario, &strong_motion(9), |_| 0.75, config(0.3, (0.0, 0.5)));
                assert!(updates.iter().any(|u| matches!(u.2, DelayStatus::AboveRange { edge_s, .. } if edge_s == 0.5 as T)));
            }

            /// 1 and 2 Hz GPS: the adapted configuration estimates the delay
            /// (the default one, gap limit 0.5 s, sees only gaps at 1 Hz).
            #[test]
            fn low_gps_rates_with_adapted_config() {
                for (rate, tol) in [(2.0, 10e-3), (1.0, 20e-3)] {
                    let mut scenario = Scenario::simulator();
                    scenario.gps_hz = rate;
                    scenario.duration_s = 150.0;
                    let config = config(0.1, (0.0, 1.0)).adapted_to_gps_rate(rate as T).unwrap();
                    let updates = run(&scenario, &strong_motion(12), |_| 0.2, config);
                    let rmse = rmse_after(&updates, 90.0, 0.2);
                    println!("{rate} Hz: RMSE from 90 s {:.2} ms", rmse * 1e3);
                    assert!(rmse < tol, "{rate} Hz: RMSE {rmse}");
                }
                let base = DelayLoopConfig::<T>::clean_input();
                for bad in [0.5, 25.0, f64::NAN] {
                    assert!(matches!(base.adapted_to_gps_rate(bad as T), Err(Error::OutOfRange { field: "gps_rate_hz", .. })));
                }
            }

            /// `set_delay` with a calibration-sized sigma locks: the loop's
            /// next update says `Locked` and holds the value through a hover;
            /// a vague one does not (the hover leaves it waiting for motion).
            /// A value outside the range is refused and changes nothing.
            #[test]
            fn set_delay_locks_only_when_certain() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 15.0;
                let base = config(0.1, (0.0, 1.0));
                assert!(base.fusion.initial_std_s > base.lock_std_s);
                for (std_s, want) in [(base.lock_std_s / 2.0, DelayStatus::Locked), (base.lock_std_s * 4.0, DelayStatus::WaitingForMotion)] {
                    let mut delay_loop = DefaultDelayLoop::<T>::new(base).unwrap();
                    delay_loop.set_delay(0.25, std_s).unwrap();
                    assert!(delay_loop.set_delay(2.0, std_s).is_err());
                    assert_eq!(delay_loop.delay_s(), 0.25);
                    let mut statuses = Vec::new();
                    for event in scenario.events(&Motion::hover(), &|_| 0.25) {
                        match event {
                            Event::Imu(t, a) => delay_loop.push_imu(t, v3(a)).unwrap(),
                            Event::Gps(t, v) => statuses.extend(delay_loop.push_gps(t, v3(v)).unwrap().map(|u| u.status)),
                        }
                    }
                    assert!(!statuses.is_empty());
                    assert!(statuses.iter().all(|s| *s == want), "std {std_s}: {statuses:?}");
                    assert_eq!(delay_loop.delay_s(), 0.25);
                }
            }

            /// A step of 0.15 s is re-acquired: within 10 ms of the new delay
            /// within 8 s, then locked again.
            #[test]
            fn step_is_reacquired_within_seconds() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 80.0;
                let tau = |t: f64| if t < 40.0 { 0.2 } else { 0.35 };
                let updates = run(&scenario, &strong_motion(21), tau, config(0.2, (0.0, 1.0)));
                let last_out = updates
                    .iter()
                    .filter(|u| u.0 >= 40.0 && (u.1 - 0.35).abs() > 0.01)
                    .map(|u| u.0)
                    .fold(40.0, f64::max);
                assert!(last_out - 40.0 < 8.0, "settled {} s after the step", last_out - 40.0);
                assert!(updates.last().unwrap().2.is_locked());
            }
        }
    };
}

status_tests!(f64_loop, f64);
status_tests!(f32_loop, f32);

/// A range wider than the capacity is refused, naming the field.
#[test]
fn range_beyond_capacity_is_refused() {
    let mut config = DelayLoopConfig::<f64>::clean_input();
    config.fusion.delay_min_s = -0.9;
    config.fusion.delay_max_s = 0.6;
    assert!(matches!(
        DefaultDelayLoop::<f64>::new(config),
        Err(Error::InvalidConfig { .. })
    ));
}

/// Only `Locked` is locked, only the two range statuses are out of range.
#[test]
fn status_predicates_name_one_state_each() {
    use delaynav::DelayStatus;
    let edge = |edge_s| DelayStatus::<f64>::BelowRange {
        edge_s,
        peak: 0.9,
        share: 0.6,
    };
    let all = [
        DelayStatus::WaitingForData,
        DelayStatus::WaitingForMotion,
        DelayStatus::Acquiring,
        DelayStatus::Locked,
        edge(0.0),
        DelayStatus::AboveRange {
            edge_s: 1.0,
            peak: 0.9,
            share: 0.6,
        },
    ];
    let locked: Vec<bool> = all.iter().map(DelayStatus::is_locked).collect();
    assert_eq!(locked, [false, false, false, true, false, false]);
    let out: Vec<bool> = all.iter().map(DelayStatus::is_out_of_range).collect();
    assert_eq!(out, [false, false, false, false, true, true]);
}

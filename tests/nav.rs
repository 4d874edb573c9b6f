//! nav: the delay-compensated navigator on synthetic flights built here
//! (tests/common/flight.rs), in f32 and f64: forward reckoning exact on
//! perfect inputs, delay recovered and tracked through the whole
//! composition, hover, GPS outage, bad input, work independent of the delay.

mod common;

use common::Motion;
use common::flight::{Flight, FlightEvent, State, Suite, feed, fly, nav_config as config};
use delaynav::nav::{
    AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, ResetCause,
    ResetRecord, WhiteningFilter,
};
use delaynav::{
    DelayStatus, Error, Estimate, Gps, GpsOutcome, GpsPosition, Imu, Mag, MagOutcome, Navigator,
    Scalar,
};
use nalgebra::Vector3;

fn f64s<T: Scalar>(v: &Vector3<T>) -> Vector3<f64> {
    v.map(|x| x.as_f64())
}

/// Attitude error, rad (angle of q_est^-1 q_true).
fn attitude_error<T: Scalar>(e: &Estimate<T>, truth: &State) -> f64 {
    let q = e.attitude.quaternion().coords.map(|x| x.as_f64());
    let q = nalgebra::UnitQuaternion::new_normalize(nalgebra::Quaternion::from(q));
    (q.inverse() * truth.q).angle()
}

/// A lively flight: 3 m/s^2 rms horizontally, 1 m/s^2 vertically, 0.05-0.5 Hz.
fn lively(seed: u64) -> Flight {
    Flight::new(Motion::random(seed, 6, 0.05, 0.5, [3.0, 3.0, 1.0]))
}

/// Runs a navigator in estimated mode over a flight; returns it and the
/// largest step back of its horizon time (must be 0).
fn run_estimated<T: Scalar, const H: usize>(
    flight: &Flight,
    suite: &Suite,
    seconds: f64,
    initial_s: f64,
    delay: impl Fn(f64) -> f64,
    mut each: impl FnMut(&DelayCompensatedNav<T, H>, &State),
) -> DelayCompensatedNav<T, H> {
    let mode = DelayMode::Estimated {
        initial_s: T::lit(initial_s),
    };
    let mut nav = DelayCompensatedNav::<T, H>::new(config(mode, suite.imu_hz)).unwrap();
    let mut horizon = 0u64;
    for event in fly(flight, suite, seconds, delay, None) {
        if let Some(truth) = feed(&mut nav, &event) {
            if let Some(h) = nav.horizon_estimate() {
                assert!(
                    h.t_us >= horizon,
                    "horizon went back: {horizon} -> {}",
                    h.t_us
                );
                horizon = h.t_us;
            }
            each(&nav, &truth);
        }
    }
    nav
}

/// Pushes one event, its refusals ignored (a gap answers `StepTooLong`); the truth after an IMU
/// sample.
fn push_any<T: Scalar>(nav: &mut DelayCompensatedNav<T>, event: &FlightEvent) -> Option<State> {
    let v3 = |v: &Vector3<f64>| v.map(T::lit);
    match event {
        FlightEvent::Imu(s, truth) => {
            let _ = nav.push_imu(&Imu {
                t_us: s.t_us,
                gyro_rad_s: v3(&s.gyro_rad_s),
                accel_m_s2: v3(&s.accel_m_s2),
            });
            Some(*truth)
        }
        FlightEvent::Mag(m) => {
            let _ = nav.push_mag(&Mag {
                t_us: m.t_us,
                field_body: v3(&m.field_body),
            });
            None
        }
        FlightEvent::Gps(g) => {
            let _ = nav.push_gps(&Gps {
                t_us: g.t_us,
                position: match g.position {
                    GpsPosition::Ned(p) => GpsPosition::Ned(v3(&p)),
                    GpsPosition::Geodetic(_) => unreachable!("the flights are in NED"),
                },
                velocity_ned_m_s: v3(&g.velocity_ned_m_s),
                horizontal_accuracy_m: None,
                vertical_accuracy_m: None,
                speed_accuracy_m_s: None,
            });
            None
        }
    }
}

macro_rules! nav_tests {
    ($name:ident, $t:ty, $tol:expr) => {
        mod $name {
            use super::*;
            type T = $t;
            /// Relative slack of this precision (1 for f64).
            const SLACK: f64 = $tol;

            #[test]
            fn perfect_inputs_put_the_present_on_the_truth_and_the_horizon_tau_behind() {
                let tau = 0.2;
                let flight = lively(5);
                let mode = DelayMode::Fixed {
                    delay_s: T::lit(tau),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let events = fly(&flight, &Suite::perfect(), 40.0, |_| tau, None);
                let (mut worst_r, mut worst_v, mut worst_q) = (0.0f64, 0.0f64, 0.0f64);
                let mut worst_span = 0.0f64;
                let mut checked = 0;
                let mut first_present = None;
                for event in &events {
                    let Some(truth) = feed(&mut nav, event) else {
                        continue;
                    };
                    let t = event.t_us();
                    let Some(now) = nav.estimate() else { continue };
                    first_present.get_or_insert(t);
                    assert_eq!(now.t_us, t);
                    // The horizon filter predicts at 100 Hz: its estimate is
                    // at most one filter step behind the horizon.
                    let horizon = nav.horizon_estimate().unwrap();
                    assert!(horizon.t_us <= t - 200_000 && horizon.t_us + 10_000 >= t - 200_000);
                    if t < 20_000_000 {
                        continue;
                    }
                    worst_r = worst_r.max((f64s(&now.position_ned_m) - truth.r).norm());
                    worst_v = worst_v.max((f64s(&now.velocity_ned_m_s) - truth.v).norm());
                    worst_q = worst_q.max(attitude_error(&now, &truth));
                    // Present minus horizon is the motion over tau.
                    let past = flight.state(horizon.t_us as f64 * 1e-6);
                    let moved = f64s(&(now.position_ned_m - horizon.position_ned_m));
                    worst_span = worst_span.max((moved - (truth.r - past.r)).norm());
                    checked += 1;
                }
                // The EKF initializes on the first fix after alignment
                // (0.1 s); the present exists one delay later.
                let first = first_present.unwrap();
                assert!(first <= 600_000, "present from {first} us");
                assert!(checked > 15_000);
                assert!(worst_r < 1e-4 * SLACK, "position {worst_r} m");
                assert!(worst_v < 1e-5 * SLACK, "velocity {worst_v} m/s");
                assert!(worst_q < 1e-6 * SLACK, "attitude {worst_q} rad");
                assert!(
                    worst_span < 1e-4 * SLACK,
                    "present - horizon {worst_span} m"
                );
                let delays = nav.sensor_delays();
                assert_eq!(delays.accel_s, T::lit(tau));
                assert_eq!(delays.gyro_s, T::lit(tau));
                assert_eq!(nav.delay_std_s(), T::lit(0.0));
                assert!(nav.last_delay_update().is_none());
            }

            /// `DelayCompensatedNavConfig::gps_noise_from_delay`: while the loop acquires
            /// (a cold start, sigma 0.29 s while this flight's motion builds
            /// up, 0.04-0.14 s at 10-20 s) the horizon's GPS velocity
            /// innovations are widened by `sigma^2 a a'` (by half the
            /// filter's own 0.12 (m/s)^2 on average); once it has
            /// locked the widening is small. Off, the same flight gives
            /// the paper's navigator, and its innovation variances are the
            /// filter's own. Before the loop locks and over the last 20 s,
            /// the mean of the velocity innovation variances (3 axes) over
            /// the fused fixes.
            #[test]
            fn gps_noise_grows_with_the_delay_uncertainty() {
                let flight = lively(3);
                let suite = Suite::simulator();
                let events = fly(&flight, &suite, 80.0, |_| 0.2, None);
                let run = |widen: bool| {
                    let mode = DelayMode::Estimated {
                        initial_s: T::lit(0.1),
                    };
                    let mut config = config(mode, suite.imu_hz);
                    config.gps_noise_from_delay = widen;
                    let mut nav = DelayCompensatedNav::<T>::new(config).unwrap();
                    let (mut last, mut early, mut late) = (None, (0.0, 0), (0.0, 0));
                    for event in &events {
                        feed(&mut nav, event);
                        let Some((_, velocity)) = nav.horizon_filter().last_gps_fusion() else {
                            continue;
                        };
                        if last == Some(velocity.t_us) {
                            continue;
                        }
                        last = Some(velocity.t_us);
                        let s = velocity.innovation_variance.sum().as_f64() / 3.0;
                        let t_s = velocity.t_us as f64 * 1e-6;
                        let locked = nav.delay_loop().status() == DelayStatus::Locked;
                        if !locked && t_s < 20.0 {
                            early = (early.0 + s, early.1 + 1);
                        } else if t_s >= 60.0 {
                            late = (late.0 + s, late.1 + 1);
                        }
                    }
                    let error_ms = (nav.delay_s().as_f64() - 0.2).abs() * 1e3;
                    (early.0 / early.1 as f64, late.0 / late.1 as f64, error_ms)
                };
                let (early_on, late_on, error_on) = run(true);
                let (early_off, late_off, error_off) = run(false);
                assert!(
                    early_on > 1.3 * early_off,
                    "before lock: {early_on} against {early_off} (m/s)^2"
                );
                assert!(
                    late_on < 1.1 * late_off,
                    "last 20 s: {late_on} against {late_off} (m/s)^2"
                );
                assert!(
                    error_on < 10.0 && error_off < 10.0,
                    "{error_on} / {error_off} ms"
                );
            }

            /// The loop's update for a fix is not done in the call that
            /// fuses it but at one of the next `DELAY_UPDATE_MAX_WAIT` IMU
            /// samples (bounded work per call), and none is lost.
            #[test]
            fn delay_update_runs_within_a_few_imu_samples_after_the_fix() {
                let tau = 0.15;
                let mode = DelayMode::Estimated {
                    initial_s: T::lit(0.2),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let updated =
                    |nav: &DelayCompensatedNav<T>| nav.last_delay_update().map(|u| u.t_us);
                let mut waiting: Option<(u64, u32)> = None;
                let (mut updates, mut fixes) = (0, 0);
                for event in fly(&lively(7), &Suite::simulator(), 30.0, |_| tau, None) {
                    let before = updated(&nav);
                    feed(&mut nav, &event);
                    match &event {
                        FlightEvent::Gps(fix) => {
                            assert_eq!(updated(&nav), before, "updated in push_gps");
                            assert!(waiting.is_none(), "a fix still waiting at {}", fix.t_us);
                            waiting = Some((fix.t_us, 0));
                            fixes += 1;
                        }
                        FlightEvent::Imu(..) => {
                            let max = delaynav::nav::DELAY_UPDATE_MAX_WAIT;
                            let now = updated(&nav);
                            if now != before {
                                // Every update is the waiting fix's, in time.
                                let (t_fix, n) = waiting.expect("an update without a fix");
                                assert_eq!(now, Some(t_fix));
                                assert!(n < max, "after {} samples", n + 1);
                                updates += 1;
                                waiting = None;
                            } else if let Some((t_fix, n)) = waiting {
                                // After `max` samples the loop has had the fix.
                                waiting = (n + 1 < max).then_some((t_fix, n + 1));
                            }
                        }
                        FlightEvent::Mag(_) => {}
                    }
                }
                assert!(
                    fixes > 200 && updates > 20,
                    "{fixes} fixes, {updates} updates"
                );
            }

            #[test]
            fn constant_delay_is_recovered_at_1_khz() {
                let tau = 0.15;
                let nav = run_estimated::<T, 1100>(
                    &lively(7),
                    &Suite::simulator(),
                    90.0,
                    0.35,
                    |_| tau,
                    |_, _| {},
                );
                let d = nav.delay_s().as_f64();
                assert!((d - tau).abs() < 0.01, "delay {d}");
                let update = nav.last_delay_update().unwrap();
                assert!(update.axes.iter().filter(|a| a.valid).count() >= 2);
                assert!(nav.estimate().unwrap().delay_s == Some(nav.delay_s()));
            }

            #[test]
            fn constant_delay_is_recovered_at_the_real_log_rates() {
                let tau = 0.3;
                let nav = run_estimated::<T, 64>(
                    &lively(8),
                    &Suite::real_log_like(),
                    120.0,
                    0.1,
                    |_| tau,
                    |_, _| {},
                );
                let d = nav.delay_s().as_f64();
                assert!((d - tau).abs() < 0.02, "delay {d}");
            }

            #[test]
            fn a_delay_step_is_tracked_and_the_horizon_never_rewinds() {
                let step = |t: f64| if t < 50.0 { 0.1 } else { 0.3 };
                let mut before = 0.0;
                let nav = run_estimated::<T, 1100>(
                    &lively(9),
                    &Suite::simulator(),
                    170.0,
                    0.1,
                    step,
                    |nav, _truth| {
                        if nav.estimate().is_some_and(|e| e.t_us == 49_000_000) {
                            before = nav.delay_s().as_f64();
                        }
                    },
                );
                let d = nav.delay_s().as_f64();
                assert!((before - 0.1).abs() < 0.02, "before the step {before}");
                assert!((d - 0.3).abs() < 0.02, "after the step {d}");
            }

            #[test]
            fn hover_without_horizontal_motion_holds_the_delay() {
                let mut flight = Flight::new(Motion::hover());
                flight.attitude_amplitude = [0.0, 0.0, 0.3];
                let mut updates = 0;
                let nav = run_estimated::<T, 1100>(
                    &flight,
                    &Suite::simulator(),
                    30.0,
                    0.25,
                    |_| 0.1,
                    |nav, _| {
                        if let Some(u) = nav.last_delay_update() {
                            assert!(u.axes.iter().all(|a| !a.valid));
                            updates += 1;
                        }
                    },
                );
                assert!(updates > 1000);
                assert_eq!(nav.delay_s(), T::lit(0.25));
                assert!(nav.estimate().is_some());
            }

            #[test]
            fn gps_outage_keeps_the_present_from_the_imu_and_holds_the_delay() {
                let tau = 0.15;
                let flight = lively(7);
                let suite = Suite::simulator();
                let mode = DelayMode::Estimated {
                    initial_s: T::lit(0.15),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let (start, end) = (40.0, 50.0);
                let mut held = None;
                let mut worst = 0.0f64;
                for event in fly(&flight, &suite, 55.0, |_| tau, Some((start, end))) {
                    let Some(truth) = feed(&mut nav, &event) else {
                        continue;
                    };
                    let t = event.t_us() as f64 * 1e-6;
                    // The last fix before the outage arrives at 39.9 s.
                    if t > start && t < end {
                        let now = nav.estimate().expect("present during the outage");
                        assert_eq!(now.t_us, event.t_us());
                        let d = *held.get_or_insert(nav.delay_s());
                        assert_eq!(nav.delay_s(), d);
                        worst = worst.max((f64s(&now.position_ned_m) - truth.r).norm());
                    }
                }
                // Dead reckoning for 10 s on the IMU: metres, not kilometres.
                assert!(worst > 0.0 && worst < 50.0, "position error {worst} m");
                assert!(nav.estimate().is_some());
            }

            fn running() -> DelayCompensatedNav<T> {
                let mode = DelayMode::Estimated {
                    initial_s: T::lit(0.1),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                for event in fly(&lively(3), &Suite::simulator(), 12.0, |_| 0.1, None) {
                    feed(&mut nav, &event);
                }
                assert!(nav.estimate().is_some());
                nav
            }

            #[test]
            fn bad_input_is_refused_and_leaves_the_navigator_unchanged() {
                let mut nav = running();
                let before = nav.estimate();
                let horizon = nav.horizon_estimate();
                let t = nav.estimate().unwrap().t_us;
                let ok = Imu {
                    t_us: t + 1000,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(T::lit(0.0), T::lit(0.0), T::lit(-9.8)),
                };
                let nan = T::lit(f64::NAN);
                let bad_imu = [
                    Imu {
                        gyro_rad_s: Vector3::new(nan, T::lit(0.0), T::lit(0.0)),
                        ..ok
                    },
                    Imu {
                        accel_m_s2: Vector3::new(T::lit(1e6), T::lit(0.0), T::lit(0.0)),
                        ..ok
                    },
                    Imu { t_us: t, ..ok },
                    Imu {
                        t_us: t - 5000,
                        ..ok
                    },
                ];
                for imu in &bad_imu {
                    assert!(nav.push_imu(imu).is_err());
                }
                let fix = Gps {
                    t_us: t + 500,
                    position: GpsPosition::Ned(Vector3::zeros()),
                    velocity_ned_m_s: Vector3::zeros(),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                };
                let bad_gps = [
                    Gps {
                        position: GpsPosition::Ned(Vector3::new(nan, T::lit(0.0), T::lit(0.0))),
                        ..fix
                    },
                    Gps {
                        velocity_ned_m_s: Vector3::new(T::lit(1e9), T::lit(0.0), T::lit(0.0)),
                        ..fix
                    },
                    Gps { t_us: 1, ..fix },
                ];
                for g in &bad_gps {
                    assert!(nav.push_gps(g).is_err());
                }
                let bad_mag = [
                    Mag {
                        t_us: t,
                        field_body: Vector3::zeros(),
                    },
                    Mag {
                        t_us: t,
                        field_body: Vector3::new(nan, T::lit(1.0), T::lit(0.0)),
                    },
                    Mag {
                        t_us: 1,
                        field_body: Vector3::new(T::lit(1.0), T::lit(0.0), T::lit(0.0)),
                    },
                ];
                for m in &bad_mag {
                    assert!(nav.push_mag(m).is_err());
                }
                assert_eq!(nav.estimate(), before);
                assert_eq!(nav.horizon_estimate(), horizon);
                let r = nav.refusals();
                assert_eq!(
                    (r.imu_non_finite, r.imu_out_of_range, r.imu_time),
                    (1, 1, 2)
                );
                assert_eq!((r.gps_invalid, r.gps_time), (2, 1));
                assert_eq!((r.mag_invalid, r.mag_time), (2, 1));
                // ...and it goes on.
                nav.push_imu(&ok).unwrap();
                assert_eq!(nav.estimate().unwrap().t_us, t + 1000);
            }

            #[test]
            fn a_gap_restarts_the_history_without_nan() {
                let mut nav = running();
                let t = nav.estimate().unwrap().t_us;
                let level = Imu {
                    t_us: t + 2_000_000,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(T::lit(0.0), T::lit(0.0), T::lit(-9.8)),
                };
                assert!(nav.integrity().horizontal_valid);
                // 2 s ahead is beyond max_time_jump_us (1 s): refused once,
                // the next sample confirms the jump, which is then a gap.
                assert!(matches!(
                    nav.push_imu(&level),
                    Err(Error::OutOfRange {
                        field: "imu.time",
                        ..
                    })
                ));
                assert_eq!(nav.refusals().imu_ahead, 1);
                // Until it is decided, the present may be 2 s past the estimate: nothing
                // is valid (the first sample after a 2 s gap was misleading on every
                // quantity: `reproduce --integrity`, `mi_imu_gap_2s`).
                let i = nav.integrity();
                assert!(
                    !(i.tilt_valid
                        || i.heading_valid
                        || i.horizontal_valid
                        || i.vertical_valid
                        || i.velocity_valid),
                    "{i:?}"
                );
                let level = Imu {
                    t_us: level.t_us + 1000,
                    ..level
                };
                assert!(matches!(
                    nav.push_imu(&level),
                    Err(Error::StepTooLong { .. })
                ));
                assert_eq!(
                    nav.health().last_reset.map(|r| r.cause),
                    Some(ResetCause::ImuGap)
                );
                for k in 1..2000u64 {
                    nav.push_imu(&Imu {
                        t_us: level.t_us + k * 1000,
                        ..level
                    })
                    .unwrap();
                }
                let e = nav.estimate().unwrap();
                assert_eq!(e.t_us, level.t_us + 1_999_000);
                assert!(e.position_ned_m.iter().all(|x| x.is_finite()));
                assert_eq!(nav.refusals().imu_gap, 1);
            }

            #[test]
            fn the_present_past_an_imu_gap_is_carried_and_its_levels_cover_the_gap() {
                let mode = DelayMode::Estimated {
                    initial_s: T::lit(0.1),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let events = fly(&lively(3), &Suite::simulator(), 15.0, |_| 0.1, None);
                let (from, to) = (12_000_000u64, 14_000_000u64);
                let mut before: Option<Estimate<T>> = None;
                let mut checked = 0;
                for event in &events {
                    if let FlightEvent::Imu(s, _) = event
                        && (from..to).contains(&s.t_us)
                    {
                        continue;
                    }
                    let Some(truth) = push_any(&mut nav, event) else {
                        continue;
                    };
                    let Some(est) = nav.estimate() else {
                        continue;
                    };
                    if est.t_us < from {
                        before = Some(est);
                        continue;
                    }
                    if nav.horizon_estimate().unwrap().t_us >= to {
                        break;
                    }
                    let b = before.unwrap();
                    if checked == 0 {
                        // Carried by the motion of before over the gap (and one step of 1 ms).
                        let dt = (est.t_us - b.t_us) as f64 * 1e-6;
                        let carried = f64s(&b.position_ned_m) + f64s(&b.velocity_ned_m_s) * dt;
                        let off = (f64s(&est.position_ned_m) - carried).norm();
                        assert!(off < 0.05 * SLACK, "{off} m from the carried position");
                    }
                    // The horizon has not crossed the gap: the levels take its growth.
                    let h = nav.health();
                    let l = h.protection_levels;
                    assert!(!h.velocity_valid && !h.tilt_valid, "{h}");
                    let dv = (f64s(&est.velocity_ned_m_s) - truth.v).norm();
                    let dr = f64s(&est.position_ned_m) - truth.r;
                    assert!(dv <= l.velocity_m_s.as_f64(), "{dv} > {:?}", l.velocity_m_s);
                    assert!(
                        dr.x.hypot(dr.y) <= l.horizontal_m.as_f64(),
                        "{dr} beyond {:?}",
                        l.horizontal_m
                    );
                    checked += 1;
                }
                assert!(checked >= 90, "{checked} samples in the first delay");
            }

            #[test]
            fn a_decimated_imu_widens_the_horizon_filter_noise() {
                // 1 kHz configured; from 10 s every fifth sample only (200 Hz, the
                // per-sample noise kept): the horizon filter's attitude variance follows the
                // 5x density (1.28 times the steady run's over 15-20 s; 0.99 when the
                // prediction keeps the configured density).
                let events = fly(&lively(3), &Suite::simulator(), 20.0, |_| 0.1, None);
                let attitude_variance = |decimated: bool| {
                    let mode = DelayMode::Estimated {
                        initial_s: T::lit(0.1),
                    };
                    let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                    let (mut sum, mut n) = (0.0, 0.0);
                    for event in &events {
                        if let FlightEvent::Imu(s, _) = event
                            && decimated
                            && s.t_us >= 10_000_000
                            && s.t_us % 5000 != 0
                        {
                            continue;
                        }
                        if push_any(&mut nav, event).is_some()
                            && nav.estimate().is_some_and(|e| e.t_us >= 15_000_000)
                        {
                            let p = nav.horizon_filter().covariance();
                            sum += (0..4).map(|i| p[(i, i)].as_f64()).sum::<f64>();
                            n += 1.0;
                        }
                    }
                    sum / n
                };
                let (steady, decimated) = (attitude_variance(false), attitude_variance(true));
                let ratio = decimated / steady;
                assert!(ratio > 1.15 && ratio < 2.3, "attitude variance ratio {ratio}");
            }

            #[test]
            fn a_future_stamp_is_refused_and_the_stream_goes_on() {
                let mut nav = running();
                let t = nav.estimate().unwrap().t_us;
                let level = |t_us| Imu {
                    t_us,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(T::lit(0.0), T::lit(0.0), T::lit(-9.8)),
                };
                assert!(nav.push_imu(&level(t + 3_600_000_000)).is_err());
                for k in 1..=100u64 {
                    nav.push_imu(&level(t + k * 1000)).unwrap();
                }
                assert_eq!(nav.estimate().unwrap().t_us, t + 100_000);
                // GPS and magnetometer stamped an hour ahead of the IMU: refused.
                let fix = Gps {
                    t_us: t + 3_600_000_000,
                    position: GpsPosition::Ned(Vector3::zeros()),
                    velocity_ned_m_s: Vector3::zeros(),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                };
                assert!(nav.push_gps(&fix).is_err());
                let mag = Mag {
                    t_us: t + 3_600_000_000,
                    field_body: Vector3::new(T::lit(1.0), T::lit(0.0), T::lit(0.0)),
                };
                assert!(nav.push_mag(&mag).is_err());
                let h = nav.health();
                assert_eq!(
                    (
                        h.refusals.imu_ahead,
                        h.refusals.gps_ahead,
                        h.refusals.mag_ahead
                    ),
                    (1, 1, 1)
                );
                // A fix with an absurd accuracy is refused and counted as such.
                let bad = Gps {
                    t_us: t + 100_000,
                    horizontal_accuracy_m: Some(T::lit(1e12)),
                    ..fix
                };
                assert!(nav.push_gps(&bad).is_err());
                assert_eq!(nav.health().refusals.gps_accuracy, 1);
                // After NED fixes, a geodetic one is a typed error, not a new origin.
                let geodetic = Gps {
                    t_us: t + 100_000,
                    position: GpsPosition::Geodetic(delaynav::Geodetic {
                        lat_deg: 31.0,
                        lon_deg: 121.0,
                        alt_m: 10.0,
                    }),
                    ..fix
                };
                assert!(matches!(
                    nav.push_gps(&geodetic),
                    Err(Error::OutOfRange {
                        field: "gps.position",
                        ..
                    })
                ));
                assert_eq!(nav.health().refusals.gps_mixed_frames, 1);
            }

            #[test]
            fn reset_restarts_and_is_reported() {
                let mut nav = running();
                let h = nav.health();
                assert_eq!(h.alignment, AlignmentState::Aligned);
                assert!(h.tilt_valid && h.position_valid && h.velocity_valid);
                assert_eq!(h.last_reset, None);
                let t = nav.estimate().unwrap().t_us;
                // The clock goes back 1 s: refused, the caller resets.
                let back = Imu {
                    t_us: t - 1_000_000,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(T::lit(0.0), T::lit(0.0), T::lit(-9.8)),
                };
                assert!(matches!(
                    nav.push_imu(&back),
                    Err(Error::TimeWentBackwards { .. })
                ));
                nav.reset();
                assert_eq!(nav.estimate(), None);
                let h = nav.health();
                assert_eq!(h.alignment, AlignmentState::WaitingForImu);
                assert!(!h.tilt_valid && !h.position_valid);
                assert_eq!(
                    h.last_reset,
                    Some(ResetRecord {
                        t_us: Some(t),
                        cause: ResetCause::Requested
                    })
                );
                assert_eq!(h.refusals.imu_time, 1, "counters survive the reset");
                // Any clock is accepted after the reset: flown again from 0, it aligns again.
                for event in fly(&lively(3), &Suite::simulator(), 8.0, |_| 0.1, None) {
                    feed(&mut nav, &event);
                }
                assert!(nav.estimate().is_some());
                assert_eq!(nav.health().alignment, AlignmentState::Aligned);
            }

            #[test]
            fn a_full_magnetometer_queue_is_averaged_and_counts() {
                let mode = DelayMode::Fixed {
                    delay_s: T::lit(0.1),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let extra = 10;
                for k in 1..=(delaynav::nav::MAG_QUEUE + extra) as u64 {
                    let m = Mag {
                        t_us: k,
                        field_body: Vector3::new(T::lit(1.0), T::lit(0.0), T::lit(0.0)),
                    };
                    assert_eq!(nav.push_mag(&m).unwrap(), MagOutcome::Queued);
                }
                // Full at MAG_QUEUE: neighbours averaged in pairs (2 µs
                // apart), then every other of the `extra` ones averaged into
                // the newest queued one, closer than that spacing.
                let full = delaynav::nav::MAG_QUEUE;
                assert_eq!(nav.queued_mag_samples(), full / 2 + extra / 2);
                assert_eq!(nav.refusals().mag_averaged, (full / 2 + extra / 2) as u32);
            }

            /// A delay longer than the magnetometer queue spans (0.95 s of
            /// 100 Hz samples in 32) averages the queue: fewer samples reach
            /// the EKF, counted, but it keeps fusing them. The spacing
            /// doubles at each averaging, 10 -> 20 -> 40 ms: a quarter as
            /// many, each the mean of about four.
            #[test]
            fn a_delay_beyond_the_magnetometer_queue_still_fuses() {
                let mode = DelayMode::Fixed {
                    delay_s: T::lit(0.95),
                };
                let mut nav = DelayCompensatedNav::<T>::new(config(mode, 1000.0)).unwrap();
                let events = fly(&lively(4), &Suite::simulator(), 8.0, |_| 0.95, None);
                let mags = events
                    .iter()
                    .filter(|e| matches!(e, FlightEvent::Mag(..)))
                    .count();
                for event in &events {
                    feed(&mut nav, event);
                }
                let ekf = nav.horizon_filter();
                let last = ekf.last_mag_fusion().expect("a magnetometer fusion").t_us;
                let t = ekf.time_us().unwrap();
                assert!(
                    t - last <= 150_000,
                    "last fusion at {last} us, filter at {t} us"
                );
                let averaged = nav.refusals().mag_averaged as usize;
                assert!(
                    averaged > mags / 2 && averaged < mags * 7 / 8,
                    "{averaged} of {mags}"
                );
            }

            /// Work over the last 5 s of a 20 s run with the delay `tau`.
            fn work_at(tau: f64) -> delaynav::nav::NavWork {
                work_at_filter_rate(tau, 100.0)
            }

            /// As [`work_at`] with the horizon filter at `rate_hz`.
            fn work_at_filter_rate(tau: f64, rate_hz: f64) -> delaynav::nav::NavWork {
                let mode = DelayMode::Fixed {
                    delay_s: T::lit(tau),
                };
                let mut c = config(mode, 1000.0);
                c.filter_rate_hz = T::lit(rate_hz);
                let mut nav = DelayCompensatedNav::<T>::new(c).unwrap();
                let mut at_15 = None;
                for event in fly(&lively(4), &Suite::simulator(), 20.0, |_| tau, None) {
                    feed(&mut nav, &event);
                    if event.t_us() == 15_000_000 && matches!(event, FlightEvent::Imu(..)) {
                        at_15 = Some(nav.work());
                    }
                }
                let (a, b) = (at_15.unwrap(), nav.work());
                delaynav::nav::NavWork {
                    imu_samples: b.imu_samples - a.imu_samples,
                    horizon_steps: b.horizon_steps - a.horizon_steps,
                    forward_propagations: b.forward_propagations - a.forward_propagations,
                    interpolation_taps: b.interpolation_taps - a.interpolation_taps,
                    ring_cursor_moves: b.ring_cursor_moves - a.ring_cursor_moves,
                    ring_early_entries: b.ring_early_entries - a.ring_early_entries,
                    correlation_multiply_adds: 0,
                }
            }

            /// The magnetometer keeps being fused after alignment whatever
            /// the horizon filter's rate (at every sample, 100 Hz, 250 Hz).
            #[test]
            fn magnetometer_is_fused_at_every_filter_rate() {
                for rate in [0.0, 100.0, 250.0] {
                    let mode = DelayMode::Fixed {
                        delay_s: T::lit(0.1),
                    };
                    let mut c = config(mode, 1000.0);
                    c.filter_rate_hz = T::lit(rate);
                    let mut nav = DelayCompensatedNav::<T>::new(c).unwrap();
                    for event in fly(&lively(4), &Suite::simulator(), 5.0, |_| 0.1, None) {
                        feed(&mut nav, &event);
                    }
                    let ekf = nav.horizon_filter();
                    let last = ekf.last_mag_fusion().expect("a magnetometer fusion").t_us;
                    let t = ekf.time_us().unwrap();
                    assert!(
                        t - last <= 150_000,
                        "rate {rate}: last magnetometer fusion at {last} us, filter at {t} us"
                    );
                }
            }

            #[test]
            fn work_per_sample_does_not_grow_with_the_delay() {
                let short = work_at(0.1);
                let long = work_at(0.5);
                assert_eq!(short.imu_samples, 5000);
                // The output entries fall on the same stride whatever the
                // delay; where the 5 s window cuts them moves one cursor
                // move at most.
                assert_eq!(
                    delaynav::nav::NavWork {
                        ring_cursor_moves: short.ring_cursor_moves,
                        ..long
                    },
                    short
                );
                assert!(short.ring_cursor_moves.abs_diff(long.ring_cursor_moves) <= 1);
                // One 4-tap read (equal group delays) and one propagation
                // per sample; one EKF step per 10 samples (100 Hz filter).
                assert_eq!(short.horizon_steps, 500);
                // At 0 (or the IMU rate) the filter predicts at every sample;
                // at 250 Hz every 4 samples.
                assert_eq!(work_at_filter_rate(0.1, 0.0).horizon_steps, 5000);
                assert_eq!(work_at_filter_rate(0.1, 1000.0).horizon_steps, 5000);
                assert_eq!(work_at_filter_rate(0.1, 250.0).horizon_steps, 1250);
                assert_eq!(short.forward_propagations, 5000);
                assert_eq!(short.interpolation_taps, 4 * 5000);
                // One cursor move per output entry: one every 27 samples
                // (the 1 s range, 1025 samples with margins, in 37 intervals),
                // and one per entry stored early while the vehicle turns fast.
                let entries = 5000 / 28 + short.ring_early_entries;
                assert!(short.ring_cursor_moves.abs_diff(entries) <= 1);
            }

            #[test]
            fn config_defaults_validate_and_bad_fields_are_named() {
                let c = DelayCompensatedNavConfig::<T>::default();
                c.validate().unwrap();
                let field = |c: DelayCompensatedNavConfig<T>| match c.validate() {
                    Err(Error::InvalidConfig { field, .. }) => field,
                    other => panic!("{other:?}"),
                };
                assert_eq!(
                    field(DelayCompensatedNavConfig {
                        imu_rate_hz: T::lit(0.0),
                        ..c
                    }),
                    "imu_rate_hz"
                );
                assert_eq!(
                    field(DelayCompensatedNavConfig {
                        mode: DelayMode::Fixed {
                            delay_s: T::lit(-0.1)
                        },
                        ..c
                    }),
                    "mode.delay_s"
                );
                assert_eq!(
                    field(DelayCompensatedNavConfig {
                        mode: DelayMode::Estimated {
                            initial_s: T::lit(2.0)
                        },
                        ..c
                    }),
                    "mode.initial_s"
                );
                assert_eq!(
                    field(DelayCompensatedNavConfig {
                        accel_whitening: WhiteningFilter::LowPass {
                            cutoff_hz: T::lit(600.0)
                        },
                        ..c
                    }),
                    "accel_whitening.cutoff_hz"
                );
                assert_eq!(
                    field(DelayCompensatedNavConfig {
                        max_horizon_step_ratio: T::lit(0.5),
                        ..c
                    }),
                    "max_horizon_step_ratio"
                );
                // 1 s at 1 kHz does not fit 512 samples; it fits the default.
                assert!(matches!(
                    DelayCompensatedNav::<T, 512>::new(c),
                    Err(Error::InvalidConfig { field, .. }) if field == "HIST"
                ));
                assert!(DelayCompensatedNav::<T>::new(c).is_ok());
            }

            #[test]
            fn whitening_delays_follow_eq_15_and_the_present_stays_on_the_truth() {
                let tau = 0.2;
                let mut c = config::<T>(
                    DelayMode::Fixed {
                        delay_s: T::lit(tau),
                    },
                    1000.0,
                );
                c.accel_whitening = WhiteningFilter::LowPass {
                    cutoff_hz: T::lit(50.0),
                };
                let mut nav = DelayCompensatedNav::<T>::new(c).unwrap();
                let (d_f, d_w) = nav.group_delays_s();
                assert_eq!((d_f.as_f64() * 1e3).round(), 7.0);
                assert_eq!(d_w, T::lit(0.0));
                let delays = nav.sensor_delays();
                assert!((delays.accel_s.as_f64() - (tau - 0.007)).abs() < 1e-6);
                assert!((delays.gyro_s.as_f64() - tau).abs() < 1e-6);
                assert!((delays.mag_s.as_f64() - tau).abs() < 1e-6);
                let mut worst = 0.0f64;
                for event in fly(&lively(5), &Suite::perfect(), 30.0, |_| tau, None) {
                    let Some(truth) = feed(&mut nav, &event) else {
                        continue;
                    };
                    if event.t_us() > 20_000_000 {
                        let now = nav.estimate().unwrap();
                        worst = worst.max((f64s(&now.velocity_ned_m_s) - truth.v).norm());
                    }
                }
                assert!(worst < 0.02 * SLACK, "velocity {worst} m/s");
            }
        }
    };
}

nav_tests!(f64_tests, f64, 1.0);
nav_tests!(f32_tests, f32, 30.0);

#[test]
fn a_fix_between_imu_samples_is_fused_at_its_own_instant() {
    let mode = DelayMode::Fixed { delay_s: 0.1 };
    let mut nav = DelayCompensatedNav::<f64, 64>::new(config(mode, 50.0)).unwrap();
    let level = |t_us| Imu {
        t_us,
        gyro_rad_s: Vector3::zeros(),
        accel_m_s2: Vector3::new(0.0, 0.0, -9.80665),
    };
    let fix = |t_us| Gps {
        t_us,
        position: GpsPosition::Ned(Vector3::zeros()),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    };
    for k in 1..=100u64 {
        nav.push_imu(&level(k * 20_000)).unwrap();
    }
    assert_eq!(
        nav.push_gps(&fix(2_000_000)).unwrap(),
        GpsOutcome::Initialized
    );
    for k in 101..=150u64 {
        nav.push_imu(&level(k * 20_000)).unwrap();
    }
    assert_eq!(nav.horizon_estimate().unwrap().t_us, 2_900_000);
    // 7 ms after the last IMU sample: fused at 3.007 s - 0.1 s.
    assert!(matches!(
        nav.push_gps(&fix(3_007_000)).unwrap(),
        GpsOutcome::Fused { .. }
    ));
    assert_eq!(nav.horizon_estimate().unwrap().t_us, 2_907_000);
    assert_eq!(
        nav.horizon_filter().last_gps_fusion().unwrap().0.t_us,
        3_007_000
    );
    // The next sample continues from there; the horizon never goes back.
    nav.push_imu(&level(3_020_000)).unwrap();
    assert_eq!(nav.horizon_estimate().unwrap().t_us, 2_920_000);
    assert_eq!(nav.estimate().unwrap().t_us, 3_020_000);
}

#[test]
fn initialization_outcomes_follow_ekf16() {
    let mode = DelayMode::Fixed { delay_s: 0.05 };
    let mut nav = DelayCompensatedNav::<f64>::new(config(mode, 1000.0)).unwrap();
    let fix = |t_us| Gps {
        t_us,
        position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0)),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    };
    assert_eq!(nav.push_gps(&fix(1)).unwrap(), GpsOutcome::Waiting);
    let level = |t_us| Imu {
        t_us,
        gyro_rad_s: Vector3::zeros(),
        accel_m_s2: Vector3::new(0.0, 0.0, -9.80665),
    };
    for k in 1..=200u64 {
        nav.push_imu(&level(k * 1000)).unwrap();
    }
    assert!(nav.horizon_estimate().is_none());
    assert_eq!(
        nav.push_gps(&fix(200_000)).unwrap(),
        GpsOutcome::Initialized
    );
    assert_eq!(nav.horizon_estimate().unwrap().t_us, 150_000);
    // No present until the horizon reaches the first output state (50 ms).
    assert!(nav.estimate().is_none());
    for k in 201..=260u64 {
        nav.push_imu(&level(k * 1000)).unwrap();
    }
    let now = nav.estimate().unwrap();
    assert_eq!(now.t_us, 260_000);
    assert!((now.position_ned_m - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-6);
    assert!(matches!(
        nav.push_gps(&fix(260_500)).unwrap(),
        GpsOutcome::Fused { .. }
    ));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn finite() -> impl Strategy<Value = f64> {
        prop_oneof![-1e3f64..1e3, -1e30f64..1e30, Just(0.0), -20.0f64..20.0]
    }

    fn vec3() -> impl Strategy<Value = [f64; 3]> {
        [finite(), finite(), finite()]
    }

    #[derive(Debug, Clone)]
    enum Input {
        Imu {
            dt_us: u64,
            gyro: [f64; 3],
            accel: [f64; 3],
        },
        Gps {
            dt_us: u64,
            p: [f64; 3],
            v: [f64; 3],
        },
        Mag {
            dt_us: u64,
            m: [f64; 3],
        },
    }

    fn input() -> impl Strategy<Value = Input> {
        prop_oneof![
            4 => (prop_oneof![9 => 0u64..20_000, 1 => 0u64..2_000_000], vec3(), vec3())
                .prop_map(|(dt_us, gyro, accel)| Input::Imu { dt_us, gyro, accel }),
            // Near level and slow: the filter initializes and runs.
            12 => (9_000u64..11_000, [-0.2f64..0.2, -0.2..0.2, -0.2..0.2], [-2.0f64..2.0, -2.0..2.0, -11.0..-8.5])
                .prop_map(|(dt_us, gyro, accel)| Input::Imu { dt_us, gyro, accel }),
            1 => (0u64..300_000, vec3(), vec3()).prop_map(|(dt_us, p, v)| Input::Gps { dt_us, p, v }),
            1 => (0u64..100_000, vec3()).prop_map(|(dt_us, m)| Input::Mag { dt_us, m }),
        ]
    }

    fn finite_estimate<T: Scalar>(e: &Estimate<T>) -> bool {
        e.attitude.coords.iter().all(|v| v.is_finite())
            && e.position_ned_m.iter().all(|v| v.is_finite())
            && e.velocity_ned_m_s.iter().all(|v| v.is_finite())
            && e.covariance_diagonal.iter().all(|v| v.is_finite())
    }

    fn run<T: Scalar>(inputs: &[Input], mode: DelayMode<T>) -> Result<(), TestCaseError> {
        let mut nav = DelayCompensatedNav::<T, 128>::new(config(mode, 100.0)).unwrap();
        let (mut t_imu, mut t_gps, mut t_mag) = (0u64, 0u64, 0u64);
        let c = |a: &[f64; 3]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));
        for i in inputs {
            // Results may be errors: only panics and non-finite outputs fail.
            match i {
                Input::Imu { dt_us, gyro, accel } => {
                    t_imu += dt_us;
                    let _ = nav.push_imu(&Imu {
                        t_us: t_imu,
                        gyro_rad_s: c(gyro),
                        accel_m_s2: c(accel),
                    });
                }
                Input::Gps { dt_us, p, v } => {
                    t_gps += dt_us;
                    let _ = nav.push_gps(&Gps {
                        t_us: t_gps,
                        position: GpsPosition::Ned(c(p)),
                        velocity_ned_m_s: c(v),
                        horizontal_accuracy_m: None,
                        vertical_accuracy_m: None,
                        speed_accuracy_m_s: None,
                    });
                }
                Input::Mag { dt_us, m } => {
                    t_mag += dt_us;
                    let _ = nav.push_mag(&Mag {
                        t_us: t_mag,
                        field_body: c(m),
                    });
                }
            }
            if let Some(e) = nav.estimate() {
                prop_assert!(finite_estimate(&e), "non-finite present");
            }
            if let Some(e) = nav.horizon_estimate() {
                prop_assert!(finite_estimate(&e), "non-finite horizon");
            }
            prop_assert!(nav.delay_s().is_finite());
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

        #[test]
        fn arbitrary_finite_inputs_never_panic_or_produce_nan(inputs in proptest::collection::vec(input(), 1..400)) {
            run::<f32>(&inputs, DelayMode::Estimated { initial_s: 0.2 })?;
            run::<f64>(&inputs, DelayMode::Estimated { initial_s: 0.2 })?;
            run::<f64>(&inputs, DelayMode::Fixed { delay_s: 0.05 })?;
        }
    }
}

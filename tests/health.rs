//! health: what `DelayCompensatedNav::health` says, edge by edge, on
//! synthetic flights (tests/common/flight.rs), in f32 and f64. Each flag is
//! shown to rise when its evidence arrives and to fall when it stops
//! (the falling edges are what a failsafe acts on); the alignment goes
//! through its states in order; the delay's validity follows the loop's
//! status (no update yet, locked, out of range).

mod common;

use common::Motion;
use common::flight::{Flight, FlightEvent, Suite, feed, fly, nav_config};
use delaynav::nav::{
    AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, Health,
};
use delaynav::nav::{GPS_STALE_US, HEADING_STALE_US};
use delaynav::{DelayStatus, Navigator, Scalar};

fn config<T: Scalar>(mode: DelayMode<T>) -> DelayCompensatedNavConfig<T> {
    nav_config(mode, 1000.0)
}

/// A lively flight: 3 m/s^2 rms horizontally, 1 m/s^2 vertically, 0.05-0.5 Hz.
fn lively(seed: u64) -> Flight {
    Flight::new(Motion::random(seed, 6, 0.05, 0.5, [3.0, 3.0, 1.0]))
}

/// (present time s, health) after every IMU sample of `events`.
fn health_over<T: Scalar>(
    nav: &mut DelayCompensatedNav<T>,
    events: &[FlightEvent],
) -> Vec<(f64, Health<T>)> {
    events
        .iter()
        .filter_map(|e| feed(nav, e).map(|_| (e.t_us() as f64 * 1e-6, nav.health())))
        .collect()
}

/// Asserts `flag` holds `want` at every IMU sample with present time in
/// `[from, to]` s (and that there are such samples).
fn holds<T: Scalar>(
    trace: &[(f64, Health<T>)],
    (from, to): (f64, f64),
    name: &str,
    flag: impl Fn(&Health<T>) -> bool,
    want: bool,
) {
    let window: Vec<_> = trace
        .iter()
        .filter(|(t, _)| *t >= from && *t <= to)
        .collect();
    assert!(window.len() > 100, "{name}: no samples in {from}-{to} s");
    if let Some((t, h)) = window.iter().find(|(_, h)| flag(h) != want) {
        panic!("{name} should be {want} from {from} to {to} s, is not at {t} s: {h:?}");
    }
}

/// The first present time (s) at or after `from` where `flag` equals `want`.
fn first<T: Scalar>(
    trace: &[(f64, Health<T>)],
    from: f64,
    flag: impl Fn(&Health<T>) -> bool,
    want: bool,
) -> Option<f64> {
    trace
        .iter()
        .find(|(t, h)| *t >= from && flag(h) == want)
        .map(|(t, _)| *t)
}

const TAU: f64 = 0.2;

/// From when the lively flights' heading is valid, s (12-13 s on these seeds: the level holds the
/// tilt share of the samples fused during the first seconds' levelling until later samples
/// replace it; the error is 0.1-0.9 deg by then).
const HEADING_FROM_S: f64 = 14.0;

macro_rules! health_tests {
    ($name:ident, $t:ty) => {
        mod $name {
            use super::*;
            type T = $t;

            fn fixed() -> DelayCompensatedNav<T> {
                DelayCompensatedNav::new(config(DelayMode::Fixed { delay_s: TAU as T })).unwrap()
            }

            /// BLANK, then every start-up state in order, each seen (none
            /// skipped or merged), with the flags and the estimate that go
            /// with it: nothing valid before `Aligned`; tilt once aligned and its
            /// protection level within the alert limit (not at once: the levelling
            /// leaves the tilt uncertain to 0.1 rad).
            #[test]
            fn alignment_goes_through_every_state_in_order() {
                let mut nav = DelayCompensatedNav::<T>::BLANK;
                assert_eq!(nav.alignment(), AlignmentState::NotConfigured);
                let h = nav.health();
                assert!(!(h.tilt_valid || h.heading_valid || h.velocity_valid || h.position_valid));
                nav.configure(config(DelayMode::Fixed { delay_s: TAU as T }))
                    .unwrap();
                let mut seen = vec![nav.alignment()];
                for e in fly(&lively(1), &Suite::simulator(), 20.0, |_| TAU, None) {
                    feed(&mut nav, &e);
                    let h = nav.health();
                    assert_eq!(h.alignment, nav.alignment());
                    let aligned = h.alignment == AlignmentState::Aligned;
                    assert_eq!(nav.estimate().is_some(), aligned, "{h:?}");
                    let limit = nav.config().ekf.integrity.tilt_alert_limit_deg;
                    let within = h.protection_levels.tilt_deg <= limit;
                    assert_eq!(h.tilt_valid, aligned && within, "{h:?}");
                    if !aligned {
                        assert!(
                            !(h.heading_valid || h.velocity_valid || h.position_valid),
                            "{h:?}"
                        );
                    }
                    if seen.last() != Some(&h.alignment) {
                        seen.push(h.alignment);
                    }
                }
                assert_eq!(
                    seen,
                    [
                        AlignmentState::WaitingForImu,
                        AlignmentState::WaitingForGps,
                        AlignmentState::CarryingForward,
                        AlignmentState::Aligned,
                    ]
                );
                let h = nav.health();
                assert!(
                    h.tilt_valid && h.heading_valid && h.velocity_valid && h.position_valid,
                    "{h:?}"
                );
                // A reset starts over: nothing valid until aligned again.
                nav.reset();
                let h = nav.health();
                assert_eq!(h.alignment, AlignmentState::WaitingForImu);
                assert!(!(h.tilt_valid || h.heading_valid || h.velocity_valid || h.position_valid));
                assert!(nav.estimate().is_none());
            }

            /// Velocity and position are valid while fixes are fused; they
            /// fall once the newest fused fix is `GPS_STALE_US` behind the
            /// horizon (a 4 s outage, too short for their sigmas to reach
            /// the bounds: staleness alone turns them off), and rise when
            /// fixes return. Tilt and heading do not depend on the GPS.
            #[test]
            fn gps_flags_fall_when_fixes_stop_and_rise_when_they_return() {
                let (start, end) = (20.0, 24.0);
                let events = fly(
                    &lively(2),
                    &Suite::simulator(),
                    30.0,
                    |_| TAU,
                    Some((start, end)),
                );
                let trace = health_over(&mut fixed(), &events);
                let stale_s = GPS_STALE_US as f64 * 1e-6;
                let pos: fn(&Health<T>) -> bool = |h| h.position_valid;
                let vel: fn(&Health<T>) -> bool = |h| h.velocity_valid;
                holds(&trace, (10.0, start), "position_valid", pos, true);
                holds(&trace, (10.0, start), "velocity_valid", vel, true);
                // The last fix before the outage describes start - tau; the
                // horizon passes it plus the stale time at start + stale.
                let fall = (start + stale_s + TAU + 0.05, end - 0.05);
                holds(&trace, fall, "position_valid", pos, false);
                holds(&trace, fall, "velocity_valid", vel, false);
                for (name, flag) in [("position_valid", pos), ("velocity_valid", vel)] {
                    let fell = first(&trace, start, flag, false).unwrap();
                    assert!(fell > start + stale_s, "{name} fell at {fell} s");
                    let rose = first(&trace, end, flag, true).expect("valid again");
                    assert!(rose < end + 1.0, "{name} rose at {rose} s");
                }
                holds(&trace, (10.0, 30.0), "tilt_valid", |h| h.tilt_valid, true);
                // The heading waits for the samples fused while the tilt converged to be
                // replaced (their share of the tilt is in its level): valid at 12 s here.
                holds(
                    &trace,
                    (HEADING_FROM_S, 30.0),
                    "heading_valid",
                    |h| h.heading_valid,
                    true,
                );
            }

            /// Heading is valid while magnetometer updates are fused; it
            /// falls `HEADING_STALE_US` after they stop and rises when they
            /// return. The GPS flags do not depend on the magnetometer.
            #[test]
            fn heading_falls_when_the_magnetometer_stops() {
                let (start, end) = (15.0, 24.0);
                let events: Vec<_> = fly(&lively(3), &Suite::simulator(), 30.0, |_| TAU, None)
                    .into_iter()
                    .filter(|e| {
                        let t = e.t_us() as f64 * 1e-6;
                        !(matches!(e, FlightEvent::Mag(_)) && t >= start && t < end)
                    })
                    .collect();
                let trace = health_over(&mut fixed(), &events);
                let stale_s = HEADING_STALE_US as f64 * 1e-6;
                let heading = |h: &Health<T>| h.heading_valid;
                holds(
                    &trace,
                    (HEADING_FROM_S, start),
                    "heading_valid",
                    heading,
                    true,
                );
                holds(
                    &trace,
                    (start + stale_s + TAU + 0.05, end - 0.05),
                    "heading_valid",
                    heading,
                    false,
                );
                let fell = first(&trace, start, heading, false).unwrap();
                assert!(fell > start + stale_s - 0.05, "heading fell at {fell} s");
                let rose = first(&trace, end, heading, true).expect("valid again");
                assert!(rose < end + 1.0, "heading rose at {rose} s");
                holds(
                    &trace,
                    (10.0, 30.0),
                    "position_valid",
                    |h| h.position_valid,
                    true,
                );
                holds(&trace, (10.0, 30.0), "tilt_valid", |h| h.tilt_valid, true);
            }

            /// A fixed delay is valid from the start, with no loop status.
            #[test]
            fn a_fixed_delay_is_valid_with_no_loop_status() {
                let nav = fixed();
                let h = nav.health();
                assert!(h.delay_valid && !h.delay.estimated);
                assert_eq!(h.delay.status, None);
                assert_eq!(h.delay.valid_updates, 0);
                assert_eq!(h.delay.delay_s, TAU as T);
            }

            /// An estimated delay is not valid while it is the start value:
            /// at the start and through a hover (nothing to correlate); it
            /// turns valid with the first loop update that had a valid axis,
            /// and the loop locks on a lively flight.
            #[test]
            fn an_estimated_delay_is_valid_only_once_measured() {
                let estimated = || {
                    DelayCompensatedNav::<T>::new(config(DelayMode::Estimated {
                        initial_s: 0.1 as T,
                    }))
                    .unwrap()
                };
                let h = estimated().health();
                assert!(h.delay.estimated && !h.delay_valid, "{h:?}");
                assert_eq!(h.delay.status, Some(DelayStatus::WaitingForData));

                let hover = fly(
                    &Flight::new(Motion::hover()),
                    &Suite::simulator(),
                    25.0,
                    |_| TAU,
                    None,
                );
                let trace = health_over(&mut estimated(), &hover);
                holds(
                    &trace,
                    (0.5, 25.0),
                    "delay_valid (hover)",
                    |h| h.delay_valid,
                    false,
                );
                let h = trace.last().unwrap().1;
                assert_eq!(h.delay.status, Some(DelayStatus::WaitingForMotion), "{h:?}");
                assert_eq!(h.delay.valid_updates, 0);
                assert_eq!(h.delay.delay_s, 0.1 as T);

                let flight = Flight::new(Motion::random(5, 8, 0.05, 1.0, [6.0, 6.0, 3.0]));
                let trace = health_over(
                    &mut estimated(),
                    &fly(&flight, &Suite::simulator(), 40.0, |_| TAU, None),
                );
                let rose = first(&trace, 0.0, |h| h.delay_valid, true).expect("delay valid");
                let (_, at) = trace.iter().find(|(t, _)| *t == rose).unwrap();
                // Valid once measured and its protection level within the alert limit.
                assert!(at.delay.valid_updates >= 1, "{at:?}");
                let limit = nav_config::<T>(DelayMode::Fixed { delay_s: 0.0 }, 1000.0)
                    .ekf
                    .integrity
                    .delay_alert_limit_s;
                assert!(at.protection_levels.delay_s <= limit, "{at:?}");
                let (_, before) = trace.iter().rev().find(|(t, _)| *t < rose).unwrap();
                assert!(
                    before.delay.valid_updates == 0 || before.protection_levels.delay_s > limit,
                    "{before:?}"
                );
                holds(&trace, (rose, 40.0), "delay_valid", |h| h.delay_valid, true);
                let h = trace.last().unwrap().1;
                assert_eq!(h.delay.status, Some(DelayStatus::Locked), "{h:?}");
                assert!((h.delay.delay_s.as_f64() - TAU).abs() < 0.01, "{h:?}");
            }

            /// A start the user vouches for, an initial standard deviation within the alert
            /// limit's reach (what an offline calibration gives), is valid before the loop has
            /// measured, as a fixed delay is; its level is that standard deviation's.
            #[test]
            fn a_calibrated_start_is_valid_before_the_loop_measures() {
                let mut c = config(DelayMode::Estimated {
                    initial_s: 0.2 as T,
                });
                c.delay_loop.fusion.initial_std_s = 0.01 as T;
                let h = DelayCompensatedNav::<T>::new(c).unwrap().health();
                assert!(h.delay_valid && h.delay.valid_updates == 0, "{h:?}");
                let level = h.protection_levels.delay_s.as_f64();
                assert!(level > 0.02 && level < 0.05, "{h:?}");
            }

            /// A delay that leaves the loop's range is no longer valid: after
            /// a lock at 0.2 s the GPS moves to lead the IMU by 0.15 s, below
            /// the range's 0 s edge; the status says below the range and the
            /// flag falls with it.
            #[test]
            fn a_delay_leaving_the_range_is_no_longer_valid() {
                let mut c = config(DelayMode::Estimated {
                    initial_s: 0.2 as T,
                });
                c.delay_loop.fusion.delay_min_s = 0.0 as T;
                let flight = Flight::new(Motion::random(9, 8, 0.05, 1.0, [6.0, 6.0, 3.0]));
                let step_s = 25.0;
                let tau = |t: f64| if t < step_s { TAU } else { -0.15 };
                let events = fly(&flight, &Suite::simulator(), 60.0, tau, None);
                let trace = health_over(&mut DelayCompensatedNav::<T>::new(c).unwrap(), &events);
                let locked = |h: &Health<T>| h.delay.status == Some(DelayStatus::Locked);
                let at = first(&trace, 0.0, locked, true).expect("locked before the step");
                assert!(at < step_s, "locked at {at} s");
                // Valid once its protection level is within the alert limit, until the step.
                let at = first(&trace, at, |h| h.delay_valid, true).expect("valid");
                assert!(at < step_s - 5.0, "valid at {at} s");
                holds(&trace, (at, step_s), "delay_valid", |h| h.delay_valid, true);
                let below =
                    |h: &Health<T>| matches!(h.delay.status, Some(DelayStatus::BelowRange { .. }));
                let at = first(&trace, step_s, below, true).expect("reported below the range");
                for (t, h) in trace.iter().filter(|(t, _)| *t >= at) {
                    assert!(h.delay.valid_updates > 0);
                    assert_eq!(h.delay_valid, !below(h), "at {t} s: {h:?}");
                }
            }
        }
    };
}

health_tests!(f64_nav, f64);
health_tests!(f32_nav, f32);

/// `Health` prints as one line a log or a ground station can show, every
/// flag and the delay's status in it; the status types print in words.
#[test]
fn health_and_its_states_print_in_words() {
    let nav = DelayCompensatedNav::<f64>::new(nav_config(
        DelayMode::Estimated { initial_s: 0.2 },
        1000.0,
    ))
    .unwrap();
    assert_eq!(
        nav.health().to_string(),
        "waiting for IMU; valid: tilt no, heading no, velocity no, position no, delay no; \
         delay 0.2000 s +- 0.2887 s (waiting for data, 0 measured updates); last reset: none"
    );
    let fixed =
        DelayCompensatedNav::<f32>::new(nav_config(DelayMode::Fixed { delay_s: 0.15 }, 1000.0))
            .unwrap();
    assert!(
        fixed
            .health()
            .to_string()
            .contains("delay yes; delay 0.1500 s (fixed)")
    );
    assert_eq!(
        AlignmentState::CarryingForward.to_string(),
        "carrying forward"
    );
    let below = DelayStatus::BelowRange {
        edge_s: 0.0f64,
        peak: 0.874,
        share: 0.6,
    };
    assert_eq!(
        below.to_string(),
        "below the range (edge 0.000 s, peak 0.87, share 0.60)"
    );
    assert_eq!(DelayStatus::<f32>::Locked.to_string(), "locked");
}

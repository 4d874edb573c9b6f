//! The navigator without a magnetometer: heading from the yaw estimator.
#![cfg(feature = "sim")]

use delaynav::Navigator;
use delaynav::nav::{DelayCompensatedNav, ResetCause};
use delaynav::sim::suite::setup::{UNCALIBRATED_START, proposed};
use delaynav::sim::{
    Fault, FaultySimulation, Scenario, SimConfig, SimEvent, tilt_heading_error_rad,
};

/// One second of a run: time, heading and tilt errors (deg).
struct Second {
    t_s: f64,
    heading_deg: f64,
    tilt_deg: f64,
}

/// Runs `sim` without magnetometer from `start_s`: the errors every second, the time (s) the
/// tilt was valid with its error above its protection level (checked every 10 ms), and the
/// navigator at the end.
fn run(sim: SimConfig, start_s: f64) -> (Vec<Second>, f64, DelayCompensatedNav<f64>) {
    let mut nav = proposed(&sim, UNCALIBRATED_START, None).unwrap();
    let events = FaultySimulation::new(sim, &[Fault::StartAt { t_s: start_s }]).unwrap();
    let mut errors = Vec::new();
    let mut misleading_tilt_s = 0.0;
    for event in events {
        match &event {
            SimEvent::Imu { sample, truth } => {
                let _ = nav.push_imu(sample);
                if truth.t_us % 10_000 != 0 {
                    continue;
                }
                let Some((est, health)) = nav.estimate_with_health() else {
                    continue;
                };
                let (tilt, heading) = tilt_heading_error_rad(&est.attitude, &truth.attitude);
                let tilt_deg = tilt.to_degrees();
                if health.tilt_valid && tilt_deg > health.protection_levels.tilt_deg {
                    misleading_tilt_s += 0.01;
                }
                if truth.t_us % 1_000_000 == 0 {
                    errors.push(Second {
                        t_s: truth.t_us as f64 * 1e-6,
                        heading_deg: heading.to_degrees(),
                        tilt_deg,
                    });
                }
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(fix);
            }
            SimEvent::Mag(_) => unreachable!("no magnetometer"),
        }
    }
    (errors, misleading_tilt_s, nav)
}

/// RMS of `f` over the seconds in `[from_s, to_s]`.
fn rms(errors: &[Second], from_s: f64, to_s: f64, f: impl Fn(&Second) -> f64) -> f64 {
    let picked: Vec<f64> = errors
        .iter()
        .filter(|e| e.t_s >= from_s && e.t_s <= to_s)
        .map(|e| f(e).powi(2))
        .collect();
    (picked.iter().sum::<f64>() / picked.len() as f64).sqrt()
}

fn no_mag(scenario: Scenario, seed: u64, duration_s: f64) -> SimConfig {
    let mut sim = SimConfig {
        duration_s,
        ..SimConfig::for_scenario(scenario, seed)
    };
    sim.sensors.mag_rate_hz = 0.0;
    sim
}

/// Switched on in flight at 20 s without a magnetometer, the trajectory turned by 150 deg: the
/// horizon filter aligns its yaw at 0 (0.5 rad of standard deviation), 150 deg off. Until the
/// bank has converged and the delay loop knows the delay, the fixes correct its position and
/// velocity alone. Measured: heading RMS over 25-50 s 10.9 deg (the bank sets the heading at
/// 22 s, 29 deg off, and the fixes bring it within 3 deg at 28 s, once the delay is known), tilt
/// RMS over 30-50 s 2.8 deg, no misleading tilt. When each fix moved the attitude through the wrong heading and the resets
/// reopened tilt and bias: 2.9, 2.1 deg and 0 s on this run, but up to 74 deg of heading and
/// 53 deg of tilt RMS on others (`in_flight_starts_far_from_the_guess`).
#[test]
fn the_yaw_estimator_aligns_the_heading_in_flight_without_a_magnetometer() {
    let mut sim = no_mag(Scenario::Low, 2, 50.0);
    sim.trajectory.yaw_offset_rad = 2.6;
    let (errors, misleading_tilt_s, nav) = run(sim, 20.0);
    let first = errors.iter().find(|e| e.t_s >= 21.0).unwrap();
    assert!(first.heading_deg.abs() > 150.0, "{}", first.heading_deg);
    let heading = rms(&errors, 25.0, 50.0, |e| e.heading_deg);
    let tilt = rms(&errors, 30.0, 50.0, |e| e.tilt_deg);
    eprintln!("heading {heading:.2} tilt {tilt:.2} misleading {misleading_tilt_s:.2}");
    assert!(heading < 15.0, "{heading}");
    assert!(tilt < 5.0, "{tilt}");
    assert_eq!(misleading_tilt_s, 0.0);
    let health = nav.health();
    assert!(
        health.yaw_gsf.converged && health.yaw_gsf.yaw_resets >= 1,
        "{health:?}"
    );
    assert!(health.yaw_gsf.updates >= 290 && health.yaw_gsf.restarts == 0);
    // The fixes before the bank converged and the delay was known moved the position and the
    // velocity alone.
    assert!(
        (20..200).contains(&health.yaw_gsf.fixes_position_velocity_only),
        "{health:?}"
    );
    let weights: f64 = health.yaw_gsf.weights.iter().sum();
    assert!((weights - 1.0).abs() < 1e-9);
    assert!(
        matches!(health.last_reset, Some(r) if r.cause == ResetCause::YawGsf),
        "{health:?}"
    );
}

/// With the magnetometer fused the bank rests and resets nothing.
#[test]
fn with_a_magnetometer_the_yaw_estimator_resets_nothing() {
    let sim = SimConfig {
        duration_s: 30.0,
        ..SimConfig::for_scenario(Scenario::High, 1)
    };
    let mut nav = proposed(&sim, UNCALIBRATED_START, None).unwrap();
    for event in FaultySimulation::new(sim, &[]).unwrap() {
        match &event {
            SimEvent::Imu { sample, .. } => {
                let _ = nav.push_imu(sample);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(fix);
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(m);
            }
        }
    }
    let health = nav.health();
    assert!(health.yaw_gsf.yaw_rad.is_none(), "{health:?}");
    assert_eq!(health.yaw_gsf.yaw_resets, 0);
    assert_eq!(health.yaw_gsf.fixes_position_velocity_only, 0);
    assert_eq!(health.last_reset, None);
}

/// The eight in-flight starts of [`in_flight_starts_far_from_the_guess`] (`low`, `high`; at 20 s
/// turned by 150 deg, at 33 s by -115 deg) for each of `seeds`: per run the heading error 30 s
/// after the start (deg), the tilt RMS over the run's last 20 s (deg) and the misleading tilt (s).
fn far_starts(seeds: &[u64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut headings, mut tilts, mut misleading) = (Vec::new(), Vec::new(), Vec::new());
    for (scenario, name) in [(Scenario::Low, "low"), (Scenario::High, "high")] {
        for &seed in seeds {
            for (start_s, turn_rad) in [(20.0, 2.6), (33.0, -2.0)] {
                let mut sim = no_mag(scenario, seed, start_s + 40.0);
                sim.trajectory.yaw_offset_rad = turn_rad;
                let (errors, misleading_tilt_s, nav) = run(sim, start_s);
                let later = errors.iter().find(|e| e.t_s >= start_s + 30.0).unwrap();
                let tilt = rms(&errors, start_s + 20.0, start_s + 40.0, |e| e.tilt_deg);
                let health = nav.health();
                eprintln!(
                    "{name} seed {seed} start {start_s} turn {:.0} deg: heading {:.1} deg at +30 s, \
                     tilt RMS {tilt:.1} deg over the last 20 s, misleading tilt {misleading_tilt_s:.2} s, \
                     resets {}, fixes fused into position and velocity alone {}",
                    turn_rad.to_degrees(),
                    later.heading_deg.abs(),
                    health.yaw_gsf.yaw_resets,
                    health.yaw_gsf.fixes_position_velocity_only
                );
                headings.push(later.heading_deg.abs());
                tilts.push(tilt);
                misleading.push(misleading_tilt_s);
            }
        }
    }
    (headings, tilts, misleading)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (v[(n - 1) / 2] + v[n / 2]) / 2.0
}

/// The in-flight starts of docs/nav.md ("Yaw without a magnetometer", figures): `low` and
/// `high`, seeds 1-2, switched on at 20 s with the trajectory turned by 150 deg and at 33 s
/// turned by -115 deg. Printed per run: the heading error 30 s after the start, the tilt RMS
/// over the run's last 20 s, the time the tilt was valid beyond its level. Asserted: the median
/// heading error 30 s after the start within 3 deg (1.2 measured; 4.8 when each fix moved the
/// attitude through the unknown heading), every run's tilt RMS over its last 20 s within 6 deg
/// (at most 5.4; up to 53 then), and the eight runs' misleading tilt below 2 s (0.47 s; 34.9 s
/// then).
#[test]
fn in_flight_starts_far_from_the_guess() {
    let (headings, tilts, misleading) = far_starts(&[1, 2]);
    let median = median(headings.clone());
    assert!(median < 3.0, "{headings:?}");
    assert!(tilts.iter().all(|&t| t < 6.0), "{tilts:?}");
    let total: f64 = misleading.iter().sum();
    assert!(total < 2.0, "{misleading:?}");
}

/// The same starts on seeds 3-5, twelve runs the design was not chosen on (`--ignored`, a few
/// seconds in release). Measured: median heading error 30 s after the start 0.8 deg (19.7 deg
/// when each fix moved the attitude), tilt RMS over the last 20 s at most 9.8 deg (up to 67.5),
/// misleading tilt 7.5 s over the twelve runs (30.7 s; 7.0 s of it in `high` seed 3 started at
/// 20 s).
#[test]
#[ignore = "twelve more 60 s runs; a measurement harness (docs/nav.md)"]
fn in_flight_starts_far_from_the_guess_more_seeds() {
    let (headings, tilts, misleading) = far_starts(&[3, 4, 5]);
    let median = median(headings.clone());
    assert!(median < 3.0, "{headings:?}");
    assert!(tilts.iter().all(|&t| t < 12.0), "{tilts:?}");
    let total: f64 = misleading.iter().sum();
    assert!(total < 10.0, "{misleading:?}");
}

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
/// horizon filter aligns its yaw at 0 (0.5 rad of standard deviation), 150 deg off, and does
/// not find the heading by itself (without the bank's resets 54 deg off at 48 s, 82 deg RMS
/// of the 3-s samples over 24-48 s). Through the wrong heading it fits the GPS velocity with
/// 2-5 m/s^2 of accelerometer bias and 20-25 deg of tilt; the bank's resets then reopen both.
/// Measured: heading RMS over 25-50 s 2.9 deg, tilt RMS over 30-50 s 2.1 deg, no misleading
/// tilt. While the resets turned the heading alone: 11.1 and 23.3 deg, and the tilt valid with
/// its error above its level for 8.7 s (from 42 s). On seeds 1 and 4 of the same start the
/// tilt is still 10 and 8 deg off at 60 s (`in_flight_starts_far_from_the_guess`, docs/nav.md).
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
    assert!(heading < 8.0, "{heading}");
    assert!(tilt < 5.0, "{tilt}");
    assert_eq!(misleading_tilt_s, 0.0);
    let health = nav.health();
    assert!(
        health.yaw_gsf.converged && health.yaw_gsf.yaw_resets >= 1,
        "{health:?}"
    );
    assert!(health.yaw_gsf.updates >= 290 && health.yaw_gsf.restarts == 0);
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
    assert_eq!(health.last_reset, None);
}

/// The in-flight starts of docs/nav.md ("Yaw without a magnetometer", figures): `low` and
/// `high`, seeds 1-2, switched on at 20 s with the trajectory turned by 150 deg and at 33 s
/// turned by -115 deg. Printed per run: the heading error 30 s after the start, the tilt RMS
/// over the run's last 20 s, the time the tilt was valid beyond its level. Asserted: the median
/// heading error 30 s after the start is within 10 deg (4.8 measured; 27 while a reset turned
/// the heading alone) and the eight runs' misleading tilt stays below 40 s (34.9 s; 55.1 s
/// then). It is not 0: the tilt level after a start this far off is an open weakness.
#[test]
fn in_flight_starts_far_from_the_guess() {
    let mut misleading = Vec::new();
    let mut headings = Vec::new();
    for (scenario, name) in [(Scenario::Low, "low"), (Scenario::High, "high")] {
        for seed in [1, 2] {
            for (start_s, turn_rad) in [(20.0, 2.6), (33.0, -2.0)] {
                let mut sim = no_mag(scenario, seed, start_s + 40.0);
                sim.trajectory.yaw_offset_rad = turn_rad;
                let (errors, misleading_tilt_s, nav) = run(sim, start_s);
                let later = errors.iter().find(|e| e.t_s >= start_s + 30.0).unwrap();
                let tilt = rms(&errors, start_s + 20.0, start_s + 40.0, |e| e.tilt_deg);
                eprintln!(
                    "{name} seed {seed} start {start_s} turn {:.0} deg: heading {:.1} deg at +30 s, \
                     tilt RMS {tilt:.1} deg over the last 20 s, misleading tilt {misleading_tilt_s:.2} s, \
                     resets {}",
                    turn_rad.to_degrees(),
                    later.heading_deg.abs(),
                    nav.health().yaw_gsf.yaw_resets
                );
                misleading.push(misleading_tilt_s);
                headings.push(later.heading_deg.abs());
            }
        }
    }
    headings.sort_by(f64::total_cmp);
    let median = (headings[3] + headings[4]) / 2.0;
    assert!(median < 10.0, "{headings:?}");
    let total: f64 = misleading.iter().sum();
    assert!(total < 40.0, "{misleading:?}");
}

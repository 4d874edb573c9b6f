//! faults: the simulator's faults do what they say, and the fault suite of
//! issue 10 runs end to end on its 60 s runs with every row asserted.
#![cfg(feature = "sim")]

use delaynav::GpsPosition;
use delaynav::delay::{CalibrationConfig, DefaultCalibrator};
use delaynav::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use delaynav::sim::faults::{
    BAD_ACCURACIES, FaultCase, FaultResult, Metric, OnTimeBackwards, Reference, base_config,
    evaluate, fault_suite, run_trace,
};
use delaynav::sim::{
    BoundConfig, Fault, FaultySimulation, SimConfig, SimEvent, Simulation, trajectory_bound,
};
use nalgebra::Vector3;

fn short(seed: u64) -> SimConfig {
    SimConfig {
        duration_s: 10.0,
        ..base_config(seed, 1.0)
    }
}

fn events(faults: &[Fault]) -> Vec<SimEvent> {
    FaultySimulation::new(short(3), faults).unwrap().collect()
}

fn fixes(events: &[SimEvent]) -> Vec<(u64, Vector3<f64>, Option<f64>)> {
    events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Gps { fix, .. } => match fix.position {
                GpsPosition::Ned(p) => Some((fix.t_us, p, fix.horizontal_accuracy_m)),
                GpsPosition::Geodetic(_) => None,
            },
            _ => None,
        })
        .collect()
}

fn imu_times(events: &[SimEvent]) -> Vec<u64> {
    events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Imu { sample, .. } => Some(sample.t_us),
            _ => None,
        })
        .collect()
}

#[test]
fn no_fault_is_the_clean_run() {
    let clean: Vec<SimEvent> = Simulation::new(short(3)).unwrap().collect();
    assert_eq!(events(&[]), clean);
}

#[test]
fn gps_faults_drop_and_move_the_fixes() {
    let clean = fixes(&events(&[]));
    let out = fixes(&events(&[Fault::GpsOutage {
        from_s: 2.0,
        to_s: 5.0,
    }]));
    assert_eq!(out.len(), clean.len() - 30);
    assert!(out.iter().all(|f| f.0 < 2_000_000 || f.0 >= 5_000_000));
    let jump = fixes(&events(&[Fault::GpsJump {
        at_s: 3.0,
        offset_m: [100.0, 0.0, 0.0],
    }]));
    let moved: Vec<usize> = (0..clean.len())
        .filter(|&k| (jump[k].1 - clean[k].1).norm() > 1e-9)
        .collect();
    assert_eq!(moved.len(), 1);
    assert_eq!(clean[moved[0]].0, 3_000_000);
    assert!((jump[moved[0]].1 - clean[moved[0]].1 - Vector3::new(100.0, 0.0, 0.0)).norm() < 1e-9);
    let step = fixes(&events(&[Fault::GpsPositionStep {
        from_s: 3.0,
        offset_m: [0.0, 50.0, 0.0],
    }]));
    for (a, b) in clean.iter().zip(&step) {
        let expected = if a.0 >= 3_000_000 { 50.0 } else { 0.0 };
        assert!((b.1.y - a.1.y - expected).abs() < 1e-9);
    }
    let glitch = fixes(&events(&[Fault::GpsFirstFixGlitch {
        offset_m: [1e6, 0.0, 0.0],
    }]));
    assert!((glitch[0].1.x - clean[0].1.x - 1e6).abs() < 1e-6);
    assert_eq!(glitch[1..], clean[1..]);
}

#[test]
fn bad_accuracies_cycle_through_every_kind() {
    let bad = fixes(&events(&[Fault::GpsBadAccuracy {
        fraction: 0.5,
        seed: 1,
    }]));
    let reported: Vec<f64> = bad
        .iter()
        .filter_map(|f| f.2)
        .filter(|a| !(a.is_finite() && *a > 0.0 && *a < 1e6))
        .collect();
    assert!(reported.len() >= BAD_ACCURACIES.len(), "{}", reported.len());
    assert!(reported.iter().any(|a| a.is_nan()));
    assert!(reported.contains(&f64::INFINITY));
    assert!(reported.contains(&0.0));
    assert!(reported.iter().any(|a| *a < 0.0));
    assert!(reported.contains(&1e12));
}

#[test]
fn imu_faults_change_the_timestamps() {
    let clean = imu_times(&events(&[]));
    let rate = imu_times(&events(&[Fault::ImuRateChange {
        at_s: 5.0,
        rate_hz: 200.0,
    }]));
    assert!(rate.windows(2).all(|w| {
        let dt = w[1] - w[0];
        if w[0] < 5_000_000 {
            dt == 1000
        } else {
            dt == 5000
        }
    }));
    let dropped = imu_times(&events(&[Fault::ImuDropouts {
        fraction: 0.1,
        seed: 2,
    }]));
    let share = 1.0 - dropped.len() as f64 / clean.len() as f64;
    assert!((0.08..0.12).contains(&share), "{share}");
    let jitter = imu_times(&events(&[Fault::ImuPeriodJitter { fraction: 0.3 }]));
    assert_eq!(jitter.len(), clean.len());
    let (lo, hi) = jitter.windows(2).fold((u64::MAX, 0), |(lo, hi), w| {
        (lo.min(w[1] - w[0]), hi.max(w[1] - w[0]))
    });
    assert!(
        lo >= 700 && hi <= 1300 && lo < 760 && hi > 1240,
        "{lo} {hi}"
    );
    let future = imu_times(&events(&[Fault::ImuFutureSample {
        at_s: 4.0,
        ahead_s: 3600.0,
    }]));
    assert_eq!(future[4000], 3_604_000_000);
    assert_eq!(future[4001], 4_001_000);
    let all = events(&[Fault::ClockBack {
        at_s: 4.0,
        back_s: 1.0,
    }]);
    let back = imu_times(&all);
    assert_eq!((back[3999], back[4000]), (3_999_000, 3_000_000));
    // The fix received at 4 s shares the clock: stamped 3 s, as the one received at 3 s.
    let at_three = fixes(&all).iter().filter(|f| f.0 == 3_000_000).count();
    assert_eq!(at_three, 2, "fixes after the jump share the clock");
}

#[test]
fn magnetic_faults_turn_scale_and_delay_the_field() {
    let mags = |faults: &[Fault]| -> Vec<(u64, Vector3<f64>)> {
        events(faults)
            .into_iter()
            .filter_map(|e| match e {
                SimEvent::Mag(m) => Some((m.t_us, m.field_body)),
                _ => None,
            })
            .collect()
    };
    let clean = mags(&[]);
    let turned = mags(&[Fault::MagRotation {
        from_s: 2.0,
        to_s: 3.0,
        angle_rad: 60f64.to_radians(),
    }]);
    for (a, b) in clean.iter().zip(&turned) {
        let angle = a.1.angle(&b.1).to_degrees();
        assert!((a.1.norm() - b.1.norm()).abs() < 1e-9);
        if (2_000_000..3_000_000).contains(&a.0) {
            assert!(angle > 20.0, "{angle}");
        } else {
            assert!(angle < 1e-5, "{angle}");
        }
    }
    let scaled = mags(&[Fault::MagScale {
        from_s: 2.0,
        to_s: 3.0,
        factor: 1.3,
    }]);
    for (a, b) in clean.iter().zip(&scaled) {
        let factor = if (2_000_000..3_000_000).contains(&a.0) {
            1.3
        } else {
            1.0
        };
        assert!((a.1 * factor - b.1).norm() < 1e-12, "{a:?} {b:?}");
    }
    for factor in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let fault = Fault::MagScale {
            from_s: 2.0,
            to_s: 3.0,
            factor,
        };
        assert!(
            FaultySimulation::new(short(3), &[fault]).is_err(),
            "{factor}"
        );
    }
    let late = mags(&[Fault::MagLate { after_s: 5.0 }]);
    assert_eq!(late[0].0, 5_100_000);
    let started = events(&[Fault::StartAt { t_s: 4.0 }]);
    assert!(started.iter().all(|e| e.t_us() >= 4_000_000));
}

/// The suite's seed and scale: the issue's 60 s runs, every window whole.
const SEED: u64 = 1;
const FULL_SCALE: f64 = 1.0;

/// The suite's start of the delay: the offline calibration of a separate 60 s run of the same
/// sensors (seed + 10,000), as `reproduce --faults` starts it; its sigma one correlation
/// grid sample.
fn calibrated_start(base: &SimConfig) -> (f64, f64) {
    let config = CalibrationConfig::<f64>::default();
    let run = SimConfig {
        seed: base.seed + 10_000,
        duration_s: 60.0,
        ..base.clone()
    };
    let (mut imu, mut gps) = (Vec::new(), Vec::new());
    for event in Simulation::new(run).unwrap() {
        match event {
            SimEvent::Imu { sample, .. } => imu.push(sample),
            SimEvent::Gps { fix, .. } => gps.push(fix),
            SimEvent::Mag(_) => {}
        }
    }
    let found = DefaultCalibrator::<f64>::new(config)
        .unwrap()
        .calibrate(imu, gps)
        .expect("the calibration run calibrates");
    (found.delay_s, 1.0 / config.correlation_rate_hz)
}

/// The suite's navigator (`proposed` of `reproduce`): the EKF configured from the run's
/// sensors, the delay estimated from `start` (delay and sigma, s).
fn nav(sim: &SimConfig, (delay_s, std_s): (f64, f64)) -> DelayCompensatedNav<f64> {
    let mut config = DelayCompensatedNavConfig {
        ekf: sim.sensors.ekf16_config(),
        mode: DelayMode::Estimated { initial_s: delay_s },
        imu_rate_hz: sim.sensors.imu_rate_hz,
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.initial_std_s = std_s;
    DelayCompensatedNav::new(config).unwrap()
}

/// The suite's rows at full scale, scored.
fn suite() -> Vec<FaultResult> {
    let cases = fault_suite(SEED, FULL_SCALE);
    let base = base_config(SEED, FULL_SCALE);
    let start = calibrated_start(&base);
    let reference = |r: Reference| {
        let sim = r.config(&base);
        run_trace(
            FaultySimulation::new(sim.clone(), &[]).unwrap(),
            nav(&sim, start),
            OnTimeBackwards::Ignore,
            |_| {},
        )
    };
    let clean = reference(Reference::Clean);
    let steady = reference(Reference::SteadyImuRate { rate_hz: 200.0 });
    cases
        .iter()
        .map(|c| {
            let trace = run_trace(
                FaultySimulation::new(c.sim.clone(), &c.faults).unwrap(),
                nav(&c.sim, start),
                c.on_backwards,
                DelayCompensatedNav::reset,
            );
            // The trace covers the whole run.
            let last = trace.last().map_or(0.0, |p| p.t_s);
            assert!(
                last > c.sim.duration_s - 0.01,
                "{}: ends at {last} s",
                c.name
            );
            let r = match c.reference {
                Reference::None => None,
                Reference::Clean => Some(clean.as_slice()),
                Reference::SteadyImuRate { .. } => Some(steady.as_slice()),
            };
            evaluate(c, &trace, r)
        })
        .collect()
}

/// The rows that fail today (`.ci/run`'s `--known-failures` of the fault suite).
const KNOWN_FAILURES: [&str; 2] = ["hard_iron", "mag_norm_disturbance"];

/// Every row of issue 10 passes on the issue's 60 s runs (whole windows: see
/// `the_rows_windows_are_the_issue_s`), with the navigator and start of `reproduce --faults`.
#[test]
fn every_row_of_the_suite_passes_at_full_scale() {
    let results = suite();
    let rows: Vec<(&str, f64)> = results.iter().map(|r| (r.name, r.limit)).collect();
    assert_eq!(
        rows,
        [
            ("gps_outage_30s", 5.0),
            ("gps_jump_100m", 3.0),
            ("gps_position_step_50m", 10.0),
            ("gps_first_fix_glitch", 5.0),
            ("gps_bad_accuracy", 1.1),
            ("imu_rate_change", 1.2),
            ("imu_dropouts", 1.2),
            ("imu_jitter", 1.2),
            ("future_timestamp", 1.1),
            ("time_backwards", 1.5),
            ("mag_disturbance_60deg", 5.0),
            ("mag_late", 1.2),
            ("hard_iron", 1.5),
            ("inflight_start", 2.0),
            ("no_magnetometer", 5.0),
            ("no_magnetometer_inflight", 5.0),
            ("inflight_tilt_5s", 2.5),
            ("mag_norm_disturbance", 1.2),
        ]
    );
    for r in &results {
        eprintln!("{} {:.3} {:?} {}", r.name, r.measured, r.note, r.passed);
        assert!(!r.criterion.is_empty());
    }
    // The known failures of `.ci/run` (no hard-iron estimation): they still fail; when one
    // passes, it leaves both lists.
    let failed: Vec<&str> = results
        .iter()
        .filter(|r| !r.passed)
        .map(|r| r.name)
        .collect();
    assert_eq!(failed, KNOWN_FAILURES, "rows failing: {results:?}");
    // The hard-iron row fails, but a field whose seen offset can turn the heading beyond its
    // alert limit is not fused: 6.8 times the clean yaw RMSE, 10.9 with that field fused (9.4
    // and 5.6 before the alignment's 50 ms minimum; seeds 1-5 now 6.8, 10.8, 4.7, 14.1, 14.1,
    // before 5.6, 10.8, 4.5, 11.3, 14.3: the median 10.8 both).
    let hard_iron = &results[12];
    assert!(hard_iron.measured < 8.0, "{hard_iron:?}");
    let mag = &results[10];
    assert!(
        mag.note
            .is_some_and(|(key, tilt)| key == "max_tilt_deg" && tilt <= 2.0)
    );
}

/// A span of true time, (start, end), s.
type Window = (f64, f64);

/// Where a row's fault acts and where it is scored, s of true time: (start, end) of each;
/// a fault at one instant starts and ends there, one that lasts ends with the run.
fn windows(case: &FaultCase) -> (Window, Window) {
    let end = case.sim.duration_s;
    let fault = match case.faults[..] {
        [Fault::GpsOutage { from_s, to_s }]
        | [Fault::MagRotation { from_s, to_s, .. }]
        | [Fault::MagScale { from_s, to_s, .. }] => (from_s, to_s),
        [Fault::GpsJump { at_s, .. }]
        | [Fault::ImuFutureSample { at_s, .. }]
        | [Fault::ClockBack { at_s, .. }] => (at_s, at_s),
        [Fault::GpsPositionStep { from_s, .. }] => (from_s, end),
        [Fault::ImuRateChange { at_s, .. }] => (at_s, end),
        [Fault::GpsFirstFixGlitch { .. }] => (0.0, 0.0),
        [Fault::GpsBadAccuracy { .. }]
        | [Fault::ImuDropouts { .. }]
        | [Fault::ImuPeriodJitter { .. }] => (0.0, end),
        // No magnetometer for `after_s` after the first fix; no event before `t_s`.
        [Fault::MagLate { after_s }] => (0.0, after_s),
        [Fault::StartAt { t_s }] => (0.0, t_s),
        // A sensor error of the whole run (the hard-iron offset), or the simulated run's own
        // fault (no magnetometer): the whole run.
        [] => (0.0, end),
        _ => panic!("{}: one fault per row", case.name),
    };
    let scored = match case.metric {
        Metric::SettleHorizontal { from_s, .. }
        | Metric::MaxHorizontal { from_s }
        | Metric::TiltRmseRatio { from_s }
        | Metric::HeadingRmseRatio { from_s }
        | Metric::MaxHeading { from_s, .. } => (from_s, end),
        Metric::HorizontalAt { t_s } | Metric::TiltAt { t_s } | Metric::HeadingAt { t_s } => {
            (t_s, t_s)
        }
    };
    (fault, scored)
}

/// The windows of every row at full scale are issue 10's: a 30 s outage and 10 s of run after
/// it to settle within 5 s, 30 s after a step to follow within 10 s, ratios over 50 s (25 s
/// after a rate change, the last 20 s after a clock jump), a 10 s magnetic disturbance scored
/// to the end, 60 s runs. Shrinking a window fails here.
#[test]
fn the_rows_windows_are_the_issue_s() {
    let cases = fault_suite(SEED, FULL_SCALE);
    let found: Vec<(&str, f64, Window, Window)> = cases
        .iter()
        .map(|c| {
            let (fault, scored) = windows(c);
            (c.name, c.sim.duration_s, fault, scored)
        })
        .collect();
    let whole = (0.0, 60.0);
    assert_eq!(
        found,
        [
            ("gps_outage_30s", 60.0, (20.0, 50.0), (50.0, 60.0)),
            ("gps_jump_100m", 60.0, (30.0, 30.0), (30.0, 60.0)),
            ("gps_position_step_50m", 60.0, (30.0, 60.0), (30.0, 60.0)),
            ("gps_first_fix_glitch", 60.0, (0.0, 0.0), (20.0, 20.0)),
            ("gps_bad_accuracy", 60.0, whole, (10.0, 60.0)),
            ("imu_rate_change", 60.0, (30.0, 60.0), (35.0, 60.0)),
            ("imu_dropouts", 60.0, whole, (10.0, 60.0)),
            ("imu_jitter", 60.0, whole, (10.0, 60.0)),
            ("future_timestamp", 60.0, (30.0, 30.0), (10.0, 60.0)),
            ("time_backwards", 60.0, (30.0, 30.0), (40.0, 60.0)),
            ("mag_disturbance_60deg", 60.0, (30.0, 40.0), (30.0, 60.0)),
            ("mag_late", 60.0, (0.0, 5.0), (10.0, 60.0)),
            ("hard_iron", 60.0, whole, (10.0, 60.0)),
            ("inflight_start", 60.0, (0.0, 12.0), (17.0, 17.0)),
            ("no_magnetometer", 60.0, whole, (30.0, 30.0)),
            ("no_magnetometer_inflight", 60.0, (0.0, 20.0), (35.0, 35.0)),
            ("inflight_tilt_5s", 60.0, (0.0, 20.0), (25.0, 25.0)),
            ("mag_norm_disturbance", 60.0, (30.0, 32.0), (35.0, 60.0)),
        ]
    );
    // A settle row leaves more of the run than its limit: settling late is seen as late.
    for c in &cases {
        if let Metric::SettleHorizontal { from_s, .. } = c.metric {
            assert!(c.sim.duration_s - from_s >= 2.0 * c.limit, "{}", c.name);
        }
    }
}

/// Runs the suite's navigator (`proposed`, the delay started from `low` or `high` seed 1's
/// calibration as the integrity suite does) over `sim`, calling `each` after every IMU sample
/// with an estimate: the estimate, the integrity and the truth. A magnetometer sample the
/// navigator refuses is counted, not an error (a fault may make it so).
fn over_the_run(
    sim: SimConfig,
    scenario: delaynav::sim::Scenario,
    mut each: impl FnMut(
        &delaynav::Estimate<f64>,
        &delaynav::integrity::Integrity<f64>,
        &delaynav::sim::Truth,
    ),
) {
    use delaynav::Navigator;
    use delaynav::sim::faults::base_config_in;
    use delaynav::sim::suite::setup::{calibrated_start, proposed};
    let start = calibrated_start(&base_config_in(scenario, 1, 1.0)).unwrap();
    let mut nav = proposed(&sim, start, None).unwrap();
    for event in Simulation::new(sim).unwrap() {
        match &event {
            SimEvent::Imu { sample, truth } => {
                nav.push_imu(sample).unwrap();
                if let Some(estimate) = nav.estimate() {
                    each(&estimate, &nav.integrity(), truth);
                }
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(m);
            }
            SimEvent::Gps { fix, .. } => {
                nav.push_gps(fix).unwrap();
            }
        }
    }
}

/// A heading fused while the tilt was off keeps that error after the tilt has converged: an
/// in-flight start on a steady banked circle (low scenario's sensors, seed 2) flies with a
/// 3 deg tilt error for 15 s of heading-only updates, which turn the heading 4 deg; the 3-axis
/// updates then fix the tilt within a second, and the heading takes 8 s more. Its level must
/// remember the tilt the samples were seen through, not only today's (it did not: 5.6 s of
/// heading beyond a valid level).
#[test]
fn a_heading_fused_through_a_wrong_tilt_stays_within_its_level() {
    use delaynav::sim::faults::{base_config_in, inflight_config};
    use delaynav::sim::{Scenario, tilt_heading_error_rad};
    let base = base_config_in(Scenario::Low, 2, 1.0);
    let sim = SimConfig {
        duration_s: 24.0,
        ..inflight_config(2, base.duration_s)
    };
    let (mut valid_s, mut worst) = (0.0, 0.0_f64);
    over_the_run(sim, Scenario::Low, |estimate, integrity, truth| {
        let (_, heading) = tilt_heading_error_rad(&estimate.attitude, &truth.attitude);
        if integrity.heading_valid {
            valid_s += 1e-3;
            worst = worst.max(heading.to_degrees() / integrity.levels.heading_deg);
        }
    });
    assert!(valid_s > 5.0, "heading valid for {valid_s} s only");
    assert!(
        worst <= 1.0,
        "heading error {worst} x its level while valid"
    );
}

/// An unmodelled tilt (a hard-iron offset the 3-axis update levelled the tilt with, 7-8 deg off
/// and known invalid) biases the horizon's velocity by up to 0.9 m/s, beyond its covariance:
/// the GPS velocity innovations show it (their mean 0.4-0.9 m/s), and the velocity level must
/// carry it (it did not: 0.69 s of velocity beyond a valid level on this run).
#[test]
fn a_velocity_bias_the_fixes_show_is_in_the_velocity_level() {
    use delaynav::sim::faults::{base_config_in, hard_iron_offset};
    use delaynav::sim::{Scenario, tilt_heading_error_rad};
    let mut sim = SimConfig {
        duration_s: 36.0,
        ..base_config_in(Scenario::High, 1, 1.0)
    };
    sim.sensors.mag_hard_iron = hard_iron_offset();
    let (mut valid_s, mut worst, mut tilt_off) = (0.0, 0.0_f64, 0.0_f64);
    over_the_run(sim, Scenario::High, |estimate, integrity, truth| {
        let error = (estimate.velocity_ned_m_s - truth.velocity_m_s).norm();
        let (tilt, _) = tilt_heading_error_rad(&estimate.attitude, &truth.attitude);
        if truth.t_us > 30_000_000 {
            tilt_off = tilt_off.max(tilt.to_degrees());
        }
        if integrity.velocity_valid {
            valid_s += 1e-3;
            worst = worst.max(error / integrity.levels.velocity_m_s);
        }
    });
    assert!(
        tilt_off > 5.0,
        "the offset left the tilt {tilt_off} deg off only"
    );
    assert!(valid_s > 20.0, "velocity valid for {valid_s} s only");
    assert!(
        worst <= 1.0,
        "velocity error {worst} x its level while valid"
    );
}

/// What the sensors of a row allow, as the linearized bound of its run (`sim::bound`, the
/// magnetometer's whole field, the filters' priors; the bound's trajectory and noise
/// variances are the same on every seed): `(heading RMS from 10 s, tilt std at `at_s`), deg`.
fn bound_of(sim: &SimConfig, faults: &[Fault], prior: BoundConfig, at_s: f64) -> (f64, f64) {
    let events: Vec<SimEvent> = FaultySimulation::new(sim.clone(), faults)
        .unwrap()
        .collect();
    let bound = trajectory_bound(&events, sim, &prior).unwrap();
    let heading = bound
        .rms_after(10_000_000)
        .map_or(f64::NAN, |r| r.heading_rad);
    let tilt = bound
        .samples
        .iter()
        .find(|s| s.t_us as f64 * 1e-6 >= at_s)
        .map_or(f64::NAN, |s| s.std.tilt_rad);
    (heading.to_degrees(), tilt.to_degrees())
}

/// The `hard_iron` row against what its sensors allow: the bound's filter fusing the whole
/// field, with the offset as three constant states of prior 0.3 of the field per axis (the
/// row's offset is 0.3 of the field, not in the config), has 1.156 times the clean run's
/// heading RMS after 10 s: the row's limit of 1.5 can be met by a filter that estimates the
/// offset with the attitude. Its heading bound is 2.3 deg at 10 s, 1.1 at 15 s, 0.75 at 20 s.
/// A smaller prior changes little (0.05 of the field: 1.127).
#[test]
fn the_bound_of_the_hard_iron_row() {
    let sim = base_config(1, 1.0);
    let at_rest = BoundConfig::for_sensors(&sim.sensors);
    let (clean, _) = bound_of(&sim, &[], at_rest, 0.0);
    let events: Vec<SimEvent> = FaultySimulation::new(sim.clone(), &[]).unwrap().collect();
    let unknown = BoundConfig {
        mag_offset_std: delaynav::sim::faults::HARD_IRON_FRACTION,
        ..at_rest
    };
    let bound = trajectory_bound(&events, &sim, &unknown).unwrap();
    let heading = bound
        .rms_after(10_000_000)
        .unwrap()
        .heading_rad
        .to_degrees();
    let at = |t_s: f64| {
        bound
            .samples
            .iter()
            .find(|s| s.t_us as f64 * 1e-6 >= t_s)
            .map_or(f64::NAN, |s| s.std.heading_rad.to_degrees())
    };
    let ratio = heading / clean;
    eprintln!(
        "hard_iron bound ratio {ratio:.3}; heading {:.2} / {:.2} / {:.2} deg at 10 / 15 / 20 s",
        at(10.0),
        at(15.0),
        at(20.0)
    );
    assert!((1.12..1.19).contains(&ratio), "{ratio}");
    assert!((2.0..2.6).contains(&at(10.0)), "{}", at(10.0));
    assert!((0.6..0.9).contains(&at(20.0)), "{}", at(20.0));
    // The heading models have no offset term: an unknown offset needs the field's.
    let heading_only = BoundConfig {
        magnetometer: delaynav::sim::bound::BoundMagnetometer::FilterHeading,
        ..unknown
    };
    assert!(trajectory_bound(&events, &sim, &heading_only).is_err());
}

/// The `mag_norm_disturbance` row against what its sensors allow: with no magnetometer sample
/// from 30 s (the disturbance's start) to 35 s (where the row's score starts: more than the
/// navigator loses, which refuses the field until the held offset is cleared and fuses the
/// heading alone for the 1 s hold after it), the bound's tilt RMS after 35 s is 1.019 times the
/// clean run's (1.005 for the 2 s of the disturbance alone): of the row's 1.2, the lost samples
/// take 2 %.
#[test]
fn the_bound_of_the_mag_norm_disturbance_row() {
    let sim = base_config(1, 1.0);
    let prior = BoundConfig::for_sensors(&sim.sensors);
    let events: Vec<SimEvent> = FaultySimulation::new(sim.clone(), &[]).unwrap().collect();
    let tilt_after_35 = |events: &[SimEvent]| {
        trajectory_bound(events, &sim, &prior)
            .unwrap()
            .rms_after(35_000_000)
            .unwrap()
            .tilt_rad
    };
    let clean = tilt_after_35(&events);
    let without = |until_s: f64| {
        let kept: Vec<SimEvent> = events
            .iter()
            .filter(|e| match e {
                SimEvent::Mag(m) => !(30_000_000..(until_s * 1e6) as u64).contains(&m.t_us),
                _ => true,
            })
            .cloned()
            .collect();
        assert!(kept.len() < events.len());
        tilt_after_35(&kept) / clean
    };
    let (disturbance, refused) = (without(32.0), without(35.0));
    eprintln!("mag_norm_disturbance bound ratio: 30-32 s {disturbance:.4}, 30-35 s {refused:.4}");
    assert!((1.001..1.01).contains(&disturbance), "{disturbance}");
    assert!((1.01..1.03).contains(&refused), "{refused}");
}

/// The rows whose figure moves most with the seed, against what their sensors allow
/// (docs/faults.md, "Other seeds"). `mag_late`: a magnetometer 5 s late leaves 1.156 times the
/// clean run's heading RMS after 10 s to any filter, so its limit (1.2) leaves 4 % to the
/// filter and the seed. `inflight_start`: a start in a 20 deg bank leaves 2.21 deg of tilt
/// (RMS) 5 s later, above the row's limit of 2 deg: the tilt about the field's direction and
/// the accelerometer bias are told apart only as the turn rotates the bias. `inflight_tilt_5s`:
/// 1.24 deg, half its limit, so a run above the limit is the filter's doing.
#[test]
fn the_bound_of_the_rows_that_depend_on_the_seed() {
    use delaynav::nav::MOVING_TILT_STD_RAD;
    use delaynav::sim::faults::{INFLIGHT_NO_MAG_START_S, INFLIGHT_START_S, inflight_config};
    let sim = base_config(1, 1.0);
    let at_rest = BoundConfig::for_sensors(&sim.sensors);
    let (clean, _) = bound_of(&sim, &[], at_rest, 0.0);
    let no_mag_at_alignment = BoundConfig {
        heading_std_rad: sim.sensors.ekf16_config().initial_yaw_std_no_mag_rad,
        ..at_rest
    };
    let late = [Fault::MagLate { after_s: 5.0 }];
    let (mag_late, _) = bound_of(&sim, &late, no_mag_at_alignment, 0.0);
    let ratio = mag_late / clean;
    let moving = |sim: &SimConfig, start_s: f64| {
        let prior = BoundConfig {
            tilt_std_rad: MOVING_TILT_STD_RAD,
            ..BoundConfig::for_sensors(&sim.sensors)
        };
        let sim = SimConfig {
            duration_s: start_s + 6.0,
            ..sim.clone()
        };
        bound_of(
            &sim,
            &[Fault::StartAt { t_s: start_s }],
            prior,
            start_s + 5.0,
        )
        .1
    };
    let turn = moving(&inflight_config(1, 60.0), INFLIGHT_START_S);
    let high = moving(&sim, INFLIGHT_NO_MAG_START_S);
    eprintln!(
        "mag_late bound ratio {ratio:.3}; tilt at +5 s: inflight_start {turn:.2}, inflight_tilt_5s {high:.2} deg"
    );
    assert!((1.12..1.19).contains(&ratio), "{ratio}");
    assert!((2.1..2.35).contains(&turn), "{turn}");
    assert!((1.1..1.35).contains(&high), "{high}");
}

//! The simulator against its own truth: kinematic consistency, noise
//! statistics, the GPS delay, determinism, the CSV export, and the helpers
//! that score runs.
#![cfg(feature = "sim")]

use delaynav::geo::rotation_matrix;
use delaynav::sim::{
    BoundConfig, BoundMagnetometer, DelayProfile, DelayStep, GpsPositionOutput, STANDARD_GRAVITY,
    Scenario, SensorConfig, SimConfig, SimEvent, Simulation, Truth, VibrationHarmonic, csv,
    delay_bound_s, delay_ramp_bound_s, noise_floor, tilt_heading_error_rad, trajectory_bound,
};
use delaynav::{
    DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, Ekf16Config, GpsPosition, Imu, Mag,
    Navigator,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

fn run(config: SimConfig) -> Vec<SimEvent> {
    Simulation::new(config).expect("valid config").collect()
}

fn imu_with_truth(events: &[SimEvent]) -> Vec<(Imu<f64>, Truth)> {
    events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Imu { sample, truth } => Some((*sample, *truth)),
            _ => None,
        })
        .collect()
}

fn noise_free(scenario: Scenario, duration_s: f64) -> SimConfig {
    SimConfig {
        sensors: SensorConfig::noise_free(),
        duration_s,
        ..SimConfig::for_scenario(scenario, 7)
    }
}

/// Time derivative of the navigation state `(q, v, p)` for one gyro and
/// accelerometer reading.
fn derivative(
    q: &Quaternion<f64>,
    v: &Vector3<f64>,
    gyro: &Vector3<f64>,
    accel: &Vector3<f64>,
) -> (Quaternion<f64>, Vector3<f64>, Vector3<f64>) {
    let dq = q * Quaternion::from_parts(0.0, *gyro) * 0.5;
    let dv = rotation_matrix(q) * accel + Vector3::new(0.0, 0.0, STANDARD_GRAVITY);
    (dq, dv, *v)
}

/// Integrates IMU samples with classical Runge-Kutta on sample triples
/// (step `2 dt`, the middle sample as the half step) from the first truth.
fn integrate(
    samples: &[(Imu<f64>, Truth)],
) -> (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>, usize) {
    let first = &samples[0].1;
    let mut q = *first.attitude.quaternion();
    let mut v = first.velocity_m_s;
    let mut p = first.position_m;
    let mut k = 0;
    while k + 2 < samples.len() {
        let h = (samples[k + 2].0.t_us - samples[k].0.t_us) as f64 * 1e-6;
        let (s0, s1, s2) = (&samples[k].0, &samples[k + 1].0, &samples[k + 2].0);
        let (q1, v1, p1) = derivative(&q, &v, &s0.gyro_rad_s, &s0.accel_m_s2);
        let (q2, v2, p2) = derivative(
            &(q + q1 * (h / 2.0)),
            &(v + v1 * (h / 2.0)),
            &s1.gyro_rad_s,
            &s1.accel_m_s2,
        );
        let (q3, v3, p3) = derivative(
            &(q + q2 * (h / 2.0)),
            &(v + v2 * (h / 2.0)),
            &s1.gyro_rad_s,
            &s1.accel_m_s2,
        );
        let (q4, v4, p4) = derivative(&(q + q3 * h), &(v + v3 * h), &s2.gyro_rad_s, &s2.accel_m_s2);
        q += (q1 + q2 * 2.0 + q3 * 2.0 + q4) * (h / 6.0);
        q = q.normalize();
        v += (v1 + v2 * 2.0 + v3 * 2.0 + v4) * (h / 6.0);
        p += (p1 + p2 * 2.0 + p3 * 2.0 + p4) * (h / 6.0);
        k += 2;
    }
    (UnitQuaternion::new_normalize(q), v, p, k)
}

#[test]
fn noise_free_imu_integrates_to_the_true_trajectory() {
    for scenario in Scenario::ALL {
        let samples = imu_with_truth(&run(noise_free(scenario, 60.0)));
        assert_eq!(samples.len(), 60_001);
        let (q, v, p, last) = integrate(&samples);
        let truth = &samples[last].1;
        assert_eq!(truth.t_us, 60_000_000);
        let pos_err = (p - truth.position_m).norm();
        let vel_err = (v - truth.velocity_m_s).norm();
        let att_err = q.angle_to(&truth.attitude);
        assert!(pos_err < 0.05, "{scenario:?}: position error {pos_err} m");
        assert!(vel_err < 0.01, "{scenario:?}: velocity error {vel_err} m/s");
        assert!(att_err < 1e-4, "{scenario:?}: attitude error {att_err} rad");
    }
}

#[test]
fn acceleration_reaches_the_scenario_limit_and_thrust_is_along_body_z() {
    for scenario in Scenario::ALL {
        let samples = imu_with_truth(&run(noise_free(scenario, 60.0)));
        let max_accel = samples
            .iter()
            .map(|(_, t)| t.accel_m_s2.norm())
            .fold(0.0, f64::max);
        let limit = scenario.accel_limit_m_s2();
        assert!(
            (max_accel - limit).abs() < 1e-3 * limit,
            "{scenario:?}: max |a| {max_accel}"
        );
        for (imu, truth) in &samples {
            // Thrust only: no specific force across the body z axis.
            assert!(imu.accel_m_s2.xy().norm() < 1e-9 * imu.accel_m_s2.norm());
            assert!(imu.accel_m_s2.z < 0.0);
            // And it is the true acceleration minus gravity.
            let f_n = truth.attitude * imu.accel_m_s2;
            let expected = truth.accel_m_s2 - Vector3::new(0.0, 0.0, STANDARD_GRAVITY);
            assert!((f_n - expected).norm() < 1e-9);
        }
    }
}

#[test]
fn the_flight_starts_at_rest_and_level_at_the_origin() {
    let samples = imu_with_truth(&run(noise_free(Scenario::Low, 0.01)));
    let start = &samples[0].1;
    assert_eq!(start.position_m, Vector3::zeros());
    assert_eq!(start.velocity_m_s, Vector3::zeros());
    assert_eq!(start.accel_m_s2, Vector3::zeros());
    assert!(start.euler_rad.xy().norm() < 1e-12);
    assert!(samples[0].0.accel_m_s2.xy().norm() < 1e-9);
}

#[test]
fn pitch_manoeuvre_grows_in_amplitude_and_frequency() {
    let samples = imu_with_truth(&run(noise_free(Scenario::High, 30.0)));
    // Peak pitch and zero crossings of the north acceleration in the first and last 8 s.
    let window = |from: f64, to: f64| {
        let part: Vec<&Truth> = samples
            .iter()
            .map(|(_, t)| t)
            .filter(|t| (from..to).contains(&(t.t_us as f64 * 1e-6)))
            .collect();
        let peak = part.iter().map(|t| t.euler_rad.y.abs()).fold(0.0, f64::max);
        let crossings = part
            .windows(2)
            .filter(|w| w[0].accel_m_s2.x * w[1].accel_m_s2.x < 0.0)
            .count();
        (peak, crossings)
    };
    let (early_peak, early_crossings) = window(2.0, 10.0);
    let (late_peak, late_crossings) = window(20.0, 28.0);
    assert!(
        late_peak > 2.0 * early_peak,
        "pitch {early_peak} -> {late_peak}"
    );
    assert!(
        late_crossings > 3 * early_crossings,
        "crossings {early_crossings} -> {late_crossings}"
    );
}

fn variance(xs: &[f64]) -> f64 {
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (xs.len() - 1) as f64
}

fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

#[test]
fn noise_and_biases_match_the_configuration() {
    let config = SimConfig::for_scenario(Scenario::Low, 3);
    let sensors = config.sensors.clone();
    let events = run(config);
    let samples = imu_with_truth(&events);
    let n = samples.len() as f64;
    for axis in 0..3 {
        let gyro: Vec<f64> = samples
            .iter()
            .map(|(s, t)| s.gyro_rad_s[axis] - t.angular_rate_rad_s[axis])
            .collect();
        let truth = &samples[0].1;
        let accel: Vec<f64> = samples
            .iter()
            .map(|(s, t)| {
                s.accel_m_s2[axis]
                    - (t.attitude.inverse() * (t.accel_m_s2 - Vector3::z() * STANDARD_GRAVITY))
                        [axis]
            })
            .collect();
        // Variance estimate of n normal samples: relative std sqrt(2/n); 5 sigma.
        let tol = 5.0 * (2.0 / n).sqrt();
        let var_g = variance(&gyro);
        assert!(
            (var_g / sensors.gyro_noise_var_rad2_s2 - 1.0).abs() < tol,
            "gyro var {var_g}"
        );
        let var_a = variance(&accel) / STANDARD_GRAVITY.powi(2);
        assert!(
            (var_a / sensors.accel_noise_var_g2 - 1.0).abs() < tol,
            "accel var {var_a} g^2"
        );
        // Constant biases: the mean offset is the true bias, within 5 standard errors.
        let bg = truth.gyro_bias_rad_s[axis];
        assert!(bg.abs() <= sensors.gyro_bias_max_rad_s);
        assert!((mean(&gyro) - bg).abs() < 5.0 * (sensors.gyro_noise_var_rad2_s2 / n).sqrt());
        let ba = truth.accel_bias_m_s2[axis];
        assert!(ba.abs() <= sensors.accel_bias_max_m_s2());
        assert!((mean(&accel) - ba).abs() < 5.0 * sensors.accel_noise_std_m_s2() / n.sqrt());
    }
    // Magnetometer: the unit field rotated into the body, plus noise.
    let truth_at = |t_us: u64| samples[(t_us / 1000) as usize].1;
    let field = Simulation::new(SimConfig::for_scenario(Scenario::Low, 3))
        .unwrap()
        .field_ned();
    let mag_residuals: Vec<f64> = events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Mag(m) => Some(m),
            _ => None,
        })
        .flat_map(|m: &Mag<f64>| {
            let t = truth_at(m.t_us);
            let r = m.field_body - t.attitude.inverse() * field;
            [r.x, r.y, r.z]
        })
        .collect();
    let tol = 5.0 * (2.0 / mag_residuals.len() as f64).sqrt();
    assert!((variance(&mag_residuals) / sensors.mag_noise_var - 1.0).abs() < tol);
    // GPS: pooled over the three axes.
    let (mut pos, mut vel) = (Vec::new(), Vec::new());
    for e in &events {
        if let SimEvent::Gps {
            fix,
            truth_at_validity,
            ..
        } = e
        {
            let GpsPosition::Ned(p) = fix.position else {
                panic!("default output is NED");
            };
            pos.extend((p - truth_at_validity.position_m).iter());
            vel.extend((fix.velocity_ned_m_s - truth_at_validity.velocity_m_s).iter());
        }
    }
    assert_eq!(pos.len(), 3 * 600);
    let tol = 5.0 * (2.0 / pos.len() as f64).sqrt();
    assert!((variance(&pos) / sensors.gps_position_var_m2 - 1.0).abs() < tol);
    assert!((variance(&vel) / sensors.gps_velocity_var_m2_s2 - 1.0).abs() < tol);
}

#[test]
fn biases_spread_over_the_configured_range_across_seeds() {
    let sensors = SensorConfig::default();
    let mut largest_gyro: f64 = 0.0;
    let mut largest_accel: f64 = 0.0;
    for seed in 0..20 {
        let config = SimConfig {
            duration_s: 0.001,
            ..SimConfig::for_scenario(Scenario::Low, seed)
        };
        let events = run(config);
        let SimEvent::Imu { truth, .. } = events[0] else {
            panic!("first event is an IMU sample");
        };
        largest_gyro = largest_gyro.max(truth.gyro_bias_rad_s.amax());
        largest_accel = largest_accel.max(truth.accel_bias_m_s2.amax());
        assert!(truth.gyro_bias_rad_s.amax() <= sensors.gyro_bias_max_rad_s);
        assert!(truth.accel_bias_m_s2.amax() <= sensors.accel_bias_max_m_s2());
    }
    // 60 uniform draws: the largest is below 90% of the maximum with probability 0.9^60 < 0.2%.
    assert!(largest_gyro > 0.9 * sensors.gyro_bias_max_rad_s);
    assert!(largest_accel > 0.9 * sensors.accel_bias_max_m_s2());
}

#[test]
fn gps_fixes_describe_the_vehicle_one_delay_ago() {
    let events = run(noise_free(Scenario::High, 20.0));
    let samples = imu_with_truth(&events);
    let mut fixes = 0;
    for e in &events {
        if let SimEvent::Gps { fix, delay_s, .. } = e {
            assert_eq!(*delay_s, 0.2);
            if fix.t_us < 200_000 {
                continue; // describes the time before the run
            }
            // The IMU truth 200 ms before the receive time.
            let valid_us = fix.t_us - 200_000;
            let truth = samples[(valid_us / 1000) as usize].1;
            assert_eq!(truth.t_us, valid_us);
            let GpsPosition::Ned(p) = fix.position else {
                panic!("default output is NED");
            };
            assert!((p - truth.position_m).norm() < 1e-9);
            assert!((fix.velocity_ned_m_s - truth.velocity_m_s).norm() < 1e-9);
            // And, once accelerating, not the truth of another millisecond nearby.
            let other = samples[(valid_us / 1000) as usize + 5].1;
            if truth.accel_m_s2.norm() > 0.1 {
                assert!((fix.velocity_ned_m_s - other.velocity_m_s).norm() > 1e-4);
            }
            fixes += 1;
        }
    }
    assert_eq!(fixes, 199);
    assert!(samples.iter().all(|(_, t)| t.gps_delay_s == 0.2));
}

#[test]
fn delay_profile_drift_steps_and_jitter_reach_the_fixes() {
    let delay = DelayProfile {
        initial_s: 0.1,
        drift_s_per_s: 0.002,
        steps: vec![DelayStep {
            at_s: 5.0,
            change_s: 0.1,
        }],
        jitter_std_s: 0.01,
        ..DelayProfile::default()
    };
    let config = SimConfig {
        delay: delay.clone(),
        ..noise_free(Scenario::Low, 10.0)
    };
    let sim = Simulation::new(config).unwrap();
    let trajectory = sim.trajectory().clone();
    let mut jitter = Vec::new();
    for e in sim {
        match e {
            SimEvent::Gps {
                fix,
                delay_s,
                truth_at_validity,
            } => {
                let t = fix.t_us as f64 * 1e-6;
                jitter.push(delay_s - delay.nominal_s(t));
                let expected = trajectory.kinematics(t - delay_s);
                assert_eq!(fix.velocity_ned_m_s, expected.velocity_m_s);
                assert_eq!(truth_at_validity, expected);
            }
            SimEvent::Imu { truth, .. } => {
                let t = truth.t_us as f64 * 1e-6;
                let step = if t >= 5.0 { 0.1 } else { 0.0 };
                assert!((truth.gps_delay_s - (0.1 + 0.002 * t + step)).abs() < 1e-12);
            }
            SimEvent::Mag(_) => {}
        }
    }
    let std = variance(&jitter).sqrt();
    assert!((std / 0.01 - 1.0).abs() < 0.3, "jitter std {std}");
}

#[test]
fn same_seed_gives_bit_identical_streams() {
    let config = |seed| SimConfig {
        duration_s: 3.0,
        sensors: SensorConfig {
            gyro_bias_walk_rad_s_sqrt_s: 1e-4,
            accel_bias_walk_m_s2_sqrt_s: 1e-3,
            vibration: vec![VibrationHarmonic {
                frequency_hz: 180.0,
                gyro_amplitude_rad_s: 0.05,
                accel_amplitude_m_s2: 2.0,
            }],
            gps_position_output: GpsPositionOutput::Geodetic,
            ..SensorConfig::default()
        },
        delay: DelayProfile {
            jitter_std_s: 0.005,
            ..DelayProfile::default()
        },
        ..SimConfig::for_scenario(Scenario::High, seed)
    };
    let a = run(config(11));
    let b = run(config(11));
    let c = run(config(12));
    assert_eq!(a.len(), b.len());
    assert!(a == b, "same seed, different stream");
    assert!(a != c, "different seeds, same stream");
    // Time-ordered, IMU first at equal times.
    for w in a.windows(2) {
        assert!(w[0].t_us() <= w[1].t_us());
        if w[0].t_us() == w[1].t_us() {
            assert!(!matches!(w[1], SimEvent::Imu { .. }));
        }
    }
}

#[test]
fn rates_are_configurable_and_validated() {
    let config = SimConfig {
        duration_s: 2.0,
        sensors: SensorConfig {
            imu_rate_hz: 250.0,
            gps_rate_hz: 5.0,
            mag_rate_hz: 50.0,
            ..SensorConfig::default()
        },
        ..SimConfig::default()
    };
    let events = run(config);
    let count = |f: fn(&SimEvent) -> bool| events.iter().filter(|e| f(e)).count();
    assert_eq!(count(|e| matches!(e, SimEvent::Imu { .. })), 501);
    assert_eq!(count(|e| matches!(e, SimEvent::Mag(_))), 101);
    assert_eq!(count(|e| matches!(e, SimEvent::Gps { .. })), 10);
    for bad in [
        SensorConfig {
            imu_rate_hz: 3000.0,
            ..SensorConfig::default()
        },
        SensorConfig {
            gps_rate_hz: 0.5,
            ..SensorConfig::default()
        },
        SensorConfig {
            gyro_noise_var_rad2_s2: f64::NAN,
            ..SensorConfig::default()
        },
    ] {
        let config = SimConfig {
            sensors: bad,
            ..SimConfig::default()
        };
        assert!(Simulation::new(config).is_err());
    }
}

fn parse_rows(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    (
        header,
        lines
            .map(|l| l.split(',').map(str::to_owned).collect())
            .collect(),
    )
}

#[test]
fn csv_export_round_trips_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("delaynav-sim-csv-{}", std::process::id()));
    let config = SimConfig {
        duration_s: 1.0,
        ..SimConfig::default()
    };
    let events = run(config.clone());
    let written = csv::write_run(&dir, Simulation::new(config).unwrap()).unwrap();
    assert_eq!(written, events.len());
    let read = |name: &str| parse_rows(&std::fs::read_to_string(dir.join(name)).unwrap());
    let (imu_header, imu_rows) = read("imu.csv");
    let (_, truth_rows) = read("truth.csv");
    let (gps_header, gps_rows) = read("gps.csv");
    let (_, mag_rows) = read("mag.csv");
    let col = |header: &[String], name: &str| header.iter().position(|h| h == name).unwrap();
    let samples = imu_with_truth(&events);
    assert_eq!(imu_rows.len(), samples.len());
    assert_eq!(truth_rows.len(), samples.len());
    for ((imu, truth), (row, truth_row)) in samples.iter().zip(imu_rows.iter().zip(&truth_rows)) {
        assert_eq!(
            row[col(&imu_header, "t_us")].parse::<u64>().unwrap(),
            imu.t_us
        );
        assert_eq!(
            row[col(&imu_header, "gyro_y_rad_s")]
                .parse::<f64>()
                .unwrap(),
            imu.gyro_rad_s.y
        );
        assert_eq!(
            row[col(&imu_header, "acc_z_m_s2")].parse::<f64>().unwrap(),
            imu.accel_m_s2.z
        );
        assert_eq!(truth_row.len(), csv::TRUTH_HEADER.split(',').count());
        assert_eq!(
            truth_row.last().unwrap().parse::<f64>().unwrap(),
            truth.gps_delay_s
        );
    }
    let fixes: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Gps { fix, .. } => Some(fix),
            _ => None,
        })
        .collect();
    assert_eq!(gps_rows.len(), fixes.len());
    for (fix, row) in fixes.iter().zip(&gps_rows) {
        let GpsPosition::Ned(p) = fix.position else {
            panic!("default output is NED");
        };
        assert_eq!(
            row[col(&gps_header, "pos_e_m")].parse::<f64>().unwrap(),
            p.y
        );
        assert_eq!(
            row[col(&gps_header, "vel_d_m_s")].parse::<f64>().unwrap(),
            fix.velocity_ned_m_s.z
        );
        assert_eq!(
            row[col(&gps_header, "s_acc_m_s")].parse::<f64>().unwrap(),
            0.1f64.sqrt()
        );
    }
    assert_eq!(mag_rows.len(), 101); // 100 Hz magnetometer
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn delay_bound_matches_its_closed_form() {
    // Constant acceleration |a| = 5 m/s^2 at 10 Hz: a 5 s window holds 50
    // fixes once full, so the bound is sigma_v / (|a| sqrt(50)).
    let a = Vector3::new(3.0, 4.0, 0.0);
    let fixes: Vec<(u64, Vector3<f64>)> = (1..=200).map(|j| (j * 100_000, a)).collect();
    let bound = delay_bound_s(&fixes, 0.1, 5_000_000, 10_000_000).unwrap();
    let expected = 0.1f64.sqrt() / (5.0 * 50f64.sqrt());
    assert!(
        (bound / expected - 1.0).abs() < 1e-9,
        "{bound} vs {expected}"
    );
    // No motion: no information.
    let still: Vec<(u64, Vector3<f64>)> =
        (1..=200).map(|j| (j * 100_000, Vector3::zeros())).collect();
    assert!(delay_bound_s(&still, 0.1, 5_000_000, 10_000_000).is_none());
}

#[test]
fn delay_ramp_bound_matches_the_straight_line_fit() {
    // Equal weights: the variance of a least-squares line at its last abscissa
    // is sigma^2 (1/n + (t_n - mean)^2 / sum (t_j - mean)^2), sigma^2 = var / |a|^2.
    let a = Vector3::new(3.0, 4.0, 0.0);
    let fixes: Vec<(u64, Vector3<f64>)> = (1..=20).map(|j| (j * 100_000, a)).collect();
    let skip_us = 2_000_000; // the last fix only
    let bound = delay_ramp_bound_s(&fixes, 0.1, skip_us).unwrap();
    let times: Vec<f64> = (0..20).map(|j| j as f64 * 0.1).collect();
    let mean = times.iter().sum::<f64>() / 20.0;
    let spread: f64 = times.iter().map(|t| (t - mean).powi(2)).sum();
    let expected = (0.1 / 25.0 * (1.0 / 20.0 + (1.9 - mean).powi(2) / spread)).sqrt();
    assert!(
        (bound / expected - 1.0).abs() < 1e-9,
        "{bound} vs {expected}"
    );
    // A line is dearer than a constant: the same fixes pin a constant better.
    let constant = delay_bound_s(&fixes, 0.1, 10_000_000, skip_us).unwrap();
    assert!(constant < bound, "{constant} vs {bound}");
    // One fix with motion cannot fix a line.
    let mut one = fixes.clone();
    for f in one.iter_mut().skip(1) {
        f.1 = Vector3::zeros();
    }
    assert!(delay_ramp_bound_s(&one, 0.1, skip_us).is_none());
}

#[test]
fn noise_floor_heading_matches_the_scalar_riccati_solution() {
    // Magnetometer at the IMU rate: one prediction per update, so the
    // posterior variance solves P^2 + qP - qr = 0.
    let sensors = SensorConfig {
        mag_rate_hz: 1000.0,
        ..SensorConfig::default()
    };
    let floor = noise_floor(&sensors, STANDARD_GRAVITY);
    let dt = 1.0 / sensors.imu_rate_hz;
    let q = sensors.gyro_noise_var_rad2_s2 * dt * dt;
    let r = sensors.mag_noise_var / sensors.inclination_rad.cos().powi(2);
    let p = (-q + (q * q + 4.0 * q * r).sqrt()) / 2.0;
    assert!((floor.heading_mag_only_rad / p.sqrt() - 1.0).abs() < 1e-6);
    // More specific force, more tilt observability; more gyro noise, more tilt error.
    let hard = noise_floor(&sensors, 5.0 * STANDARD_GRAVITY);
    assert!(hard.tilt_rad < floor.tilt_rad);
    let noisy = noise_floor(
        &SensorConfig {
            gyro_noise_var_rad2_s2: 4.0 * sensors.gyro_noise_var_rad2_s2,
            ..sensors.clone()
        },
        STANDARD_GRAVITY,
    );
    assert!(noisy.tilt_rad > floor.tilt_rad);
    assert!(floor.velocity_norm_m_s > floor.horizontal_velocity_m_s);
    eprintln!("noise floor at 1 g: {floor:?}\nat 5 g: {hard:?}");
}

#[test]
fn vibration_adds_its_harmonic_to_gyro_and_accelerometer() {
    let harmonic = VibrationHarmonic {
        frequency_hz: 180.0,
        gyro_amplitude_rad_s: 0.05,
        accel_amplitude_m_s2: 2.0,
    };
    let config = SimConfig {
        sensors: SensorConfig {
            vibration: vec![harmonic],
            ..SensorConfig::noise_free()
        },
        ..noise_free(Scenario::Low, 1.0)
    };
    let samples = imu_with_truth(&run(config));
    for axis in 0..3 {
        // Project the residual on sin and cos at the harmonic's frequency over
        // a whole number of periods (1 s = 180 periods): amplitude sqrt(s² + c²).
        let (mut s, mut c) = (0.0, 0.0);
        let (mut sa, mut ca) = (0.0, 0.0);
        let n = samples.len() - 1;
        for (imu, truth) in &samples[..n] {
            let phase = std::f64::consts::TAU * harmonic.frequency_hz * truth.t_us as f64 * 1e-6;
            let g = imu.gyro_rad_s[axis] - truth.angular_rate_rad_s[axis];
            let f_b =
                truth.attitude.inverse() * (truth.accel_m_s2 - Vector3::z() * STANDARD_GRAVITY);
            let a = imu.accel_m_s2[axis] - f_b[axis];
            s += g * phase.sin();
            c += g * phase.cos();
            sa += a * phase.sin();
            ca += a * phase.cos();
        }
        let amplitude = |s: f64, c: f64| 2.0 * (s * s + c * c).sqrt() / n as f64;
        assert!((amplitude(s, c) / harmonic.gyro_amplitude_rad_s - 1.0).abs() < 1e-6);
        assert!((amplitude(sa, ca) / harmonic.accel_amplitude_m_s2 - 1.0).abs() < 1e-6);
    }
}

/// Still at the origin, level, fixed heading (no path, no manoeuvre).
fn hover(seed: u64, duration_s: f64, delay_s: f64) -> SimConfig {
    let mut config = SimConfig {
        delay: DelayProfile::constant(delay_s),
        duration_s,
        ..SimConfig::for_scenario(Scenario::Low, seed)
    };
    config.trajectory.path.clear();
    config.trajectory.yaw_amplitude_rad = 0.0;
    config.trajectory.accel_limit_m_s2 = 1e-6;
    config
}

/// The bound's prior with the biases known exactly, the magnetometer as a
/// heading only (the noise floor's model).
fn known_biases(sensors: &SensorConfig) -> BoundConfig {
    BoundConfig {
        magnetometer: BoundMagnetometer::Heading,
        accel_bias_std_m_s2: 0.0,
        gyro_bias_std_rad_s: 0.0,
        ..BoundConfig::for_sensors(sensors)
    }
}

#[test]
fn trajectory_bound_at_hover_with_known_biases_is_the_noise_floor() {
    let config = hover(1, 120.0, 0.0);
    let events = run(config.clone());
    let bound = trajectory_bound(&events, &config, &known_biases(&config.sensors)).unwrap();
    assert_eq!(bound.samples.len(), 120_001);
    let rms = bound.rms_after(60_000_000).unwrap();
    let floor = noise_floor(&config.sensors, STANDARD_GRAVITY);
    let close = |name: &str, got: f64, want: f64| {
        assert!(
            (got / want - 1.0).abs() < 0.02,
            "{name}: bound {got}, floor {want}"
        );
    };
    close("tilt", rms.tilt_rad, floor.tilt_rad * 2f64.sqrt());
    close("roll", rms.euler_rad.x, floor.tilt_rad);
    close("pitch", rms.euler_rad.y, floor.tilt_rad);
    close("velocity", rms.velocity_m_s, floor.velocity_norm_m_s);
    close("position", rms.position_m, floor.position_norm_m);
    close("heading", rms.heading_rad, floor.heading_mag_only_rad);
    close("yaw", rms.euler_rad.z, floor.heading_mag_only_rad);
}

#[test]
fn trajectory_bound_grows_with_the_delay_and_with_unknown_biases() {
    let prior = |c: &SimConfig| known_biases(&c.sensors);
    let rms = |delay_s: f64, prior: &dyn Fn(&SimConfig) -> BoundConfig| {
        let config = hover(2, 60.0, delay_s);
        let events = run(config.clone());
        trajectory_bound(&events, &config, &prior(&config))
            .unwrap()
            .rms_after(30_000_000)
            .unwrap()
    };
    let now = rms(0.0, &prior);
    let late = rms(0.4, &prior);
    // A fix 0.4 s old leaves 0.4 s of dead reckoning: velocity and position
    // grow, tilt barely (it moves only with the gyro noise).
    assert!(
        late.velocity_m_s > now.velocity_m_s * 1.05,
        "{late:?} {now:?}"
    );
    assert!(late.position_m > now.position_m, "{late:?} {now:?}");
    assert!((late.tilt_rad / now.tilt_rad - 1.0).abs() < 0.05);
    // At hover an accelerometer bias cannot be told from tilt: unknown
    // biases raise the tilt bound far above the floor.
    let unknown = rms(0.0, &|c| BoundConfig {
        magnetometer: BoundMagnetometer::Heading,
        ..BoundConfig::for_sensors(&c.sensors)
    });
    assert!(unknown.tilt_rad > 5.0 * now.tilt_rad, "{unknown:?} {now:?}");
    assert!(
        unknown.accel_bias_m_s2.x
            > 0.1 * BoundConfig::for_sensors(&SensorConfig::default()).accel_bias_std_m_s2
    );
}

/// Squared errors of the navigator given the true delay on one run, summed
/// from `skip_us` on: tilt, velocity, position, and the count.
fn oracle_squared_errors(config: &SimConfig, events: &[SimEvent], skip_us: u64) -> [f64; 4] {
    let s = &config.sensors;
    let g2 = STANDARD_GRAVITY * STANDARD_GRAVITY;
    let ekf = Ekf16Config {
        mag_inclination_rad: s.inclination_rad,
        mag_declination_rad: s.declination_rad,
        mag_noise_variance: s.mag_noise_var,
        gps_horizontal_std_m: s.gps_position_var_m2.sqrt(),
        gps_vertical_std_m: s.gps_position_var_m2.sqrt(),
        gps_velocity_std_m_s: s.gps_velocity_var_m2_s2.sqrt(),
        initial_accel_bias_std_m_s2: s.accel_bias_max_m_s2() / 3f64.sqrt(),
        initial_gyro_bias_std_rad_s: s.gyro_bias_max_rad_s / 3f64.sqrt(),
        ..Ekf16Config::with_per_sample_imu_variances(
            s.gyro_noise_var_rad2_s2,
            s.accel_noise_var_g2 * g2,
            s.imu_rate_hz,
        )
    };
    let mut nav = DelayCompensatedNav::<f64>::new(DelayCompensatedNavConfig {
        ekf,
        mode: DelayMode::Fixed {
            delay_s: config.delay.initial_s,
        },
        imu_rate_hz: s.imu_rate_hz,
        ..DelayCompensatedNavConfig::default()
    })
    .unwrap();
    let mut sums = [0.0; 4];
    for event in events {
        match event {
            SimEvent::Imu { sample, truth } => {
                let _ = nav.push_imu(sample);
                if truth.t_us >= skip_us {
                    let est = nav.estimate().expect("initialized");
                    sums[0] += tilt_heading_error_rad(&est.attitude, &truth.attitude)
                        .0
                        .powi(2);
                    sums[1] += (est.velocity_ned_m_s - truth.velocity_m_s).norm_squared();
                    sums[2] += (est.position_ned_m - truth.position_m).norm_squared();
                    sums[3] += 1.0;
                }
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(m);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(fix);
            }
        }
    }
    sums
}

#[test]
fn trajectory_bound_is_below_the_navigator_given_the_true_delay() {
    let skip_us = 10_000_000;
    let (mut nav, mut bound) = ([0.0; 4], [0.0; 3]);
    for seed in 1..=3 {
        let config = SimConfig {
            duration_s: 40.0,
            ..SimConfig::for_scenario(Scenario::High, seed)
        };
        let events = run(config.clone());
        let b = trajectory_bound(&events, &config, &BoundConfig::for_sensors(&config.sensors))
            .unwrap()
            .rms_after(skip_us)
            .unwrap();
        bound[0] += b.tilt_rad.powi(2);
        bound[1] += b.velocity_m_s.powi(2);
        bound[2] += b.position_m.powi(2);
        for (sum, x) in nav
            .iter_mut()
            .zip(oracle_squared_errors(&config, &events, skip_us))
        {
            *sum += x;
        }
    }
    // RMS over three runs; position errors decorrelate over seconds, so its
    // RMSE scatters most and gets the widest margin. Tilt: with the 3-axis
    // magnetometer the navigator takes the information the bound takes, and
    // three 30 s windows scatter by more than 10 % (measured: bound 0.0119
    // rad, navigator 0.0108; over 20 seeds of 60 s the bound is below
    // `oracle`, 0.565 against 0.753 deg in `high`).
    for (i, (name, margin)) in [("tilt", 1.2), ("velocity", 1.1), ("position", 1.25)]
        .into_iter()
        .enumerate()
    {
        let est = (nav[i] / nav[3]).sqrt();
        let b = (bound[i] / 3.0).sqrt();
        eprintln!("{name}: bound {b}, navigator {est}");
        assert!(
            b < margin * est,
            "{name}: bound {b} above the navigator's {est}"
        );
    }
}

/// The filters' magnetometer (a tilt-compensated heading) carries less than
/// the whole field, and the filters' heading-only gain cannot beat the
/// optimal gain on that heading: at every instant, so in every RMS.
#[test]
fn trajectory_bound_orders_the_magnetometer_models() {
    let config = SimConfig {
        duration_s: 30.0,
        ..SimConfig::for_scenario(Scenario::Low, 1)
    };
    let events = run(config.clone());
    let rms = |b: BoundConfig| {
        trajectory_bound(&events, &config, &b)
            .unwrap()
            .rms_after(10_000_000)
            .unwrap()
    };
    let filter = config.sensors.ekf16_config::<f64>();
    let field = rms(BoundConfig::for_sensors(&config.sensors));
    let heading = rms(BoundConfig {
        mag_tilt_alignment_std_rad: 0.0,
        ..BoundConfig::for_filter(&filter)
    });
    let gain = rms(BoundConfig::for_filter(&filter));
    let below = |a: f64, b: f64| a <= b * (1.0 + 1e-9);
    for (name, f, h, g) in [
        ("tilt", field.tilt_rad, heading.tilt_rad, gain.tilt_rad),
        (
            "heading",
            field.heading_rad,
            heading.heading_rad,
            gain.heading_rad,
        ),
        (
            "velocity",
            field.velocity_m_s,
            heading.velocity_m_s,
            gain.velocity_m_s,
        ),
    ] {
        assert!(
            below(f, h) && below(h, g),
            "{name}: field {f}, heading {h}, gain {g}"
        );
    }
    // The field's tilt is what the heading lacks: a clear gap, not rounding.
    assert!(
        heading.tilt_rad > 1.3 * field.tilt_rad,
        "{heading:?} {field:?}"
    );
}

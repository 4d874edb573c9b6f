//! ekf16: Jacobians against finite differences, convergence on synthetic
//! trajectories generated here (static level, constant velocity, coordinated
//! turn), invariants over long runs, refusal of bad input, in f32 and f64; the
//! arbitrary-input property also runs the augmented filter on the same core.

use delaynav::ekf16::state::{self, ACCEL_BIAS, GYRO_BIAS, NAV_STATES, POS, QUAT, VEL};
use delaynav::ekf16::{GpsBlock, GpsResetCause};
use delaynav::ekf16::{measurement, process};
use delaynav::geo::{
    euler_from_quaternion, magnetic_field_ned, quaternion_from_euler, rotation_matrix,
    tilt_compensated_heading, wrap_pi,
};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Error, FusionRecord, Geodetic, Gps,
    GpsOutcome, GpsPosition, Imu, Mag, MagOutcome, NavState, Navigator, Scalar,
};
use nalgebra::{SMatrix, SVector, Vector3};

mod flight;
use flight::*;

/// Resets of both GPS blocks so far.
fn gps_resets<T: Scalar>(ekf: &Ekf16<T>) -> u32 {
    let r = ekf.refusals();
    r.gps_position_resets + r.gps_velocity_resets
}

macro_rules! ekf16_tests {
    ($mod:ident, $t:ty, jac_step = $step:expr, jac_tol = $jtol:expr, round = $round:expr) => {
        mod $mod {
            use super::*;
            type T = $t;

            fn lit(x: f64) -> T {
                T::lit(x)
            }

            #[test]
            fn process_jacobian_matches_finite_differences() {
                let x = sample_state::<T>();
                let gyro = Vector3::new(lit(0.5), lit(-0.3), lit(0.8));
                let accel = Vector3::new(lit(1.0), lit(2.0), lit(-9.0));
                let analytic = process::jacobian(&x, &gyro, &accel);
                let numeric = numeric_jacobian(&x, lit($step), |x| {
                    process::derivative(x, &gyro, &accel, lit(G))
                });
                let err = max_abs_diff(&analytic, &numeric);
                assert!(err < $jtol, "F differs from finite differences by {err}");
            }

            #[test]
            fn propagate_agrees_with_the_derivative_over_a_short_step() {
                let x = sample_state::<T>();
                let gyro = Vector3::new(lit(0.5), lit(-0.3), lit(0.8));
                let accel = Vector3::new(lit(1.0), lit(2.0), lit(-9.0));
                let dt = lit(1e-3);
                let slope = (process::propagate(&x, &gyro, &accel, dt, lit(G)) - x) / dt;
                let d = process::derivative(&x, &gyro, &accel, lit(G));
                // The difference is O(dt) times the second derivative (~10 here).
                let err = max_abs_diff(&slope, &d);
                assert!(err < 0.02 + 20.0 * $round / 1e-3, "propagate vs f: {err}");
                let q = process::propagate(&x, &gyro, &accel, lit(0.02), lit(G))
                    .fixed_rows::<4>(QUAT)
                    .norm();
                assert!((q.as_f64() - 1.0).abs() < 4.0 * $round);
            }

            #[test]
            fn propagate_turns_by_the_exact_rotation() {
                // A constant rate for one long step: the quaternion is the exact
                // rotation, not an Euler step.
                let mut x = sample_state::<T>();
                x.fixed_rows_mut::<3>(GYRO_BIAS).fill(lit(0.0));
                let gyro = Vector3::new(lit(0.0), lit(0.0), lit(1.0));
                let out = process::propagate(&x, &gyro, &Vector3::zeros(), lit(0.5), lit(G));
                let q0 = NavState::from_vector(&x).attitude;
                let q1 = NavState::from_vector(&out).attitude;
                let turned = q0.inverse() * q1;
                assert!((turned.angle().as_f64() - 0.5).abs() < 10.0 * $round);
                assert!((turned.axis().unwrap().z.as_f64() - 1.0).abs() < 10.0 * $round);
            }

            #[test]
            fn gps_jacobians_match_finite_differences_with_lever_arm() {
                let x = sample_state::<T>();
                let lever = Vector3::new(lit(0.3), lit(-0.2), lit(-0.5));
                let gyro = Vector3::new(lit(0.5), lit(-0.3), lit(0.8));
                let (_, hp) = measurement::gps_position(&x, &lever);
                let np =
                    numeric_jacobian(&x, lit($step), |x| measurement::gps_position(x, &lever).0);
                let err = max_abs_diff(&hp, &np);
                assert!(err < $jtol, "GPS position H: {err}");
                let (_, hv) = measurement::gps_velocity(&x, &gyro, &lever);
                let nv = numeric_jacobian(&x, lit($step), |x| {
                    measurement::gps_velocity(x, &gyro, &lever).0
                });
                let err = max_abs_diff(&hv, &nv);
                assert!(err < $jtol, "GPS velocity H: {err}");
                // The lever arm terms are really there.
                assert!(hp.fixed_view::<3, 4>(0, QUAT).amax() > lit(0.1));
                assert!(hv.fixed_view::<3, 3>(0, GYRO_BIAS).amax() > lit(0.1));
            }

            #[test]
            fn mag_jacobian_matches_finite_differences_and_is_yaw_only() {
                let x = sample_state::<T>();
                let e = euler_from_quaternion(&state_quaternion(&x));
                let m_n = magnetic_field_ned(lit(INCLINATION), lit(DECLINATION));
                let (_, h) = measurement::mag_model(&x, e.x, e.y, &m_n);
                let n = numeric_jacobian(&x, lit($step), |x| {
                    measurement::mag_model(x, e.x, e.y, &m_n).0
                });
                let err = max_abs_diff(&h, &n);
                assert!(err < $jtol, "mag H: {err}");
                // Rank one, orthogonal to q, and blind to everything but attitude.
                let hq = h.fixed_view::<3, 4>(0, QUAT).into_owned();
                let rank = hq.map(|v| v.as_f64()).svd(false, false).singular_values;
                assert!(rank[1] < 1e3 * $round * rank[0], "rank of H_q: {rank}");
                let q = x.fixed_rows::<4>(QUAT).into_owned();
                assert!((hq * q).amax().as_f64() < 10.0 * $round);
                assert_eq!(h.columns(POS, NAV_STATES - POS).amax(), lit(0.0));
            }

            #[test]
            fn tilt_coupled_mag_jacobian_is_that_of_the_heading_actually_measured() {
                let x = sample_state::<T>();
                let e = euler_from_quaternion(&state_quaternion(&x));
                let (roll, pitch) = (e.x, e.y);
                let decl = lit(DECLINATION);
                let m_n = magnetic_field_ned(lit(INCLINATION), decl);
                // What push_mag measures: the field the state predicts,
                // de-rotated with the roll and pitch held at the estimate.
                let measured = |x: &SVector<T, NAV_STATES>| {
                    let m_b = rotation_matrix(&state_quaternion(x)).transpose() * m_n;
                    let psi = tilt_compensated_heading(&m_b, roll, pitch, decl);
                    measurement::mag_pseudo_measurement(roll, pitch, psi, &m_n)
                };
                let (h, jac) = measurement::mag_model_tilt_coupled(&x, roll, pitch, &m_n);
                assert!((h - measured(&x)).amax() < lit(100.0 * $round));
                let n = numeric_jacobian(&x, lit($step), measured);
                let err = max_abs_diff(&jac, &n);
                assert!(err < $jtol, "tilt-coupled mag H: {err}");
                // Along a pure heading change it is the yaw-only Jacobian; along
                // a tilt change it is not zero (about tan I per radian).
                let q = state_quaternion(&x);
                let (_, yaw_only) = measurement::mag_model(&x, roll, pitch, &m_n);
                let hq = jac.fixed_view::<3, 4>(0, QUAT).into_owned();
                let hq_yaw = yaw_only.fixed_view::<3, 4>(0, QUAT).into_owned();
                let along_yaw = measurement::yaw_direction(&q);
                assert!((hq * along_yaw - hq_yaw * along_yaw).amax() < lit(100.0 * $round));
                let along_roll = state::euler_to_quaternion_jacobian(roll, pitch, e.z)
                    .column(0)
                    .into_owned();
                let tilt_effect = (hq * along_roll).norm().as_f64();
                let dh_dpsi = (hq_yaw * along_yaw).norm().as_f64();
                assert!(tilt_effect > 0.3 * dh_dpsi, "{tilt_effect} vs {dh_dpsi}");
                assert!((hq_yaw * along_roll).norm().as_f64() < 10.0 * $round);
            }

            #[test]
            fn three_axis_mag_jacobian_matches_finite_differences_and_sees_tilt() {
                let x = sample_state::<T>();
                let m_n = magnetic_field_ned(lit(INCLINATION), lit(DECLINATION));
                let (h, jac) = measurement::mag_field_model(&x, &m_n);
                let truth = rotation_matrix(&state_quaternion(&x)).transpose() * m_n;
                assert!((h - truth).amax() < lit(100.0 * $round));
                let n =
                    numeric_jacobian(&x, lit($step), |x| measurement::mag_field_model(x, &m_n).0);
                let err = max_abs_diff(&jac, &n);
                assert!(err < $jtol, "3-axis mag H: {err}");
                // Only the quaternion; a rotation about the field itself
                // (body axis h) is invisible; H q = 2 h (the norm direction).
                assert_eq!(jac.columns(POS, NAV_STATES - POS).amax(), lit(0.0));
                let hq = jac.fixed_view::<3, 4>(0, QUAT).into_owned();
                let qn = state_quaternion(&x);
                let about_field = qn * nalgebra::Quaternion::from_imag(h) * lit(0.5);
                let about_field = SVector::<T, 4>::new(
                    about_field.w,
                    about_field.i,
                    about_field.j,
                    about_field.k,
                );
                assert!((hq * about_field).amax().as_f64() < 100.0 * $round);
                let q = x.fixed_rows::<4>(QUAT).into_owned();
                assert!((hq * q - h * lit(2.0)).amax().as_f64() < 100.0 * $round);
                // A roll change moves the predicted field (the heading-only
                // model's yaw-only Jacobian does not).
                let e = euler_from_quaternion(&state_quaternion(&x));
                let along_roll = state::euler_to_quaternion_jacobian(e.x, e.y, e.z)
                    .column(0)
                    .into_owned();
                assert!((hq * along_roll).norm().as_f64() > 0.3);
            }

            fn state_quaternion(x: &SVector<T, NAV_STATES>) -> nalgebra::Quaternion<T> {
                *NavState::from_vector(x).attitude.quaternion()
            }

            #[test]
            fn attitude_covariance_maps_euler_variances() {
                // J from finite differences of quaternion_from_euler.
                let (r, p, y) = (lit(0.2), lit(-0.3), lit(1.0));
                let j = state::euler_to_quaternion_jacobian(r, p, y);
                let e = Vector3::new(r, p, y);
                let n = numeric_jacobian(&e, lit($step), |e| {
                    quaternion_from_euler(e.x, e.y, e.z).quaternion().coords
                });
                // nalgebra stores [i, j, k, w]: reorder to [w, i, j, k].
                let n = SMatrix::<T, 4, 3>::from_rows(&[n.row(3), n.row(0), n.row(1), n.row(2)]);
                assert!(max_abs_diff(&j, &n) < $jtol);
            }

            #[test]
            fn config_defaults_validate_and_bad_fields_are_named() {
                let c = Ekf16Config::<T>::default();
                c.validate().unwrap();
                let bad = Ekf16Config {
                    gyro_noise_density: lit(-1.0),
                    ..c
                };
                assert_eq!(
                    bad.validate(),
                    Err(Error::InvalidConfig {
                        field: "gyro_noise_density".into(),
                        value: Some(-1.0),
                        bound: delaynav::error::Bound::PositiveFinite,
                    })
                );
                let field_of = |bad: Ekf16Config<T>| match bad.validate() {
                    Err(Error::InvalidConfig { field, .. }) => field,
                    other => panic!("expected InvalidConfig, got {other:?}"),
                };
                assert_eq!(
                    field_of(Ekf16Config {
                        mag_noise_variance: lit(f64::NAN),
                        ..c
                    }),
                    "mag_noise_variance"
                );
                assert_eq!(
                    field_of(Ekf16Config {
                        max_imu_step_us: 0,
                        ..c
                    }),
                    "max_imu_step_us"
                );
                assert_eq!(
                    field_of(Ekf16Config {
                        align_min_duration_us: 60_000_001,
                        ..c
                    }),
                    "align_min_duration_us"
                );
                let bad = Ekf16Config {
                    mag_inclination_rad: lit(1.6),
                    ..c
                };
                assert_eq!(field_of(bad), "mag_inclination_rad");
                let no_gate = Ekf16Config {
                    gps_position_gate: lit(f64::INFINITY),
                    ..c
                };
                no_gate.validate().unwrap();
                assert!(Ekf16::new(bad).is_err());
                // Table 3 per-sample variances at 1 kHz give the default densities.
                let t3 = Ekf16Config::<T>::with_per_sample_imu_variances(
                    lit(0.0017),
                    lit(0.01 * G * G),
                    lit(1000.0),
                );
                assert!(
                    (t3.gyro_noise_density / c.gyro_noise_density - lit(1.0)).abs()
                        < lit(10.0 * $round)
                );
                assert!(
                    (t3.accel_noise_density / c.accel_noise_density - lit(1.0)).abs()
                        < lit(10.0 * $round)
                );
                let d2 = (t3.gyro_noise_density * t3.gyro_noise_density).as_f64();
                assert!((d2 * 1000.0 / 0.0017 - 1.0).abs() < 10.0 * $round);
            }

            #[test]
            fn initializes_from_accelerometer_magnetometer_and_first_fix() {
                let (roll, pitch, yaw) = (0.08, -0.05, 2.1);
                let tr = truth(Motion::Static { roll, pitch, yaw }, 0.0);
                let lever = Vector3::new(0.2, 0.1, -0.3);
                let cfg = Ekf16Config {
                    lever_arm_m: v3(&lever),
                    ..config::<T>()
                };
                let mut ekf = Ekf16::<T>::new(cfg).unwrap();
                let fix = |t_us| {
                    gps_fix(
                        t_us,
                        GpsPosition::Ned(Vector3::new(lit(5.0), lit(6.0), lit(-7.0))),
                        Vector3::zeros(),
                    )
                };
                // No IMU yet: wait.
                assert_eq!(ekf.push_gps(&fix(1)).unwrap(), GpsOutcome::Waiting);
                assert!(ekf.estimate().is_none());
                let m_b = rotation_matrix(tr.q.quaternion()).transpose()
                    * magnetic_field_ned(INCLINATION, DECLINATION);
                assert_eq!(
                    ekf.push_mag(&Mag {
                        t_us: 5,
                        field_body: v3(&m_b)
                    })
                    .unwrap(),
                    MagOutcome::Stored
                );
                // At rest at 1 kHz, a sample each ms of `ms`.
                let align = |nav: &mut Ekf16<T>, ms: core::ops::RangeInclusive<u64>| {
                    for k in ms {
                        let imu = Imu {
                            t_us: k * 1000,
                            gyro_rad_s: Vector3::zeros(),
                            accel_m_s2: v3(&tr.accel),
                        };
                        nav.push_imu(&imu).unwrap();
                    }
                };
                // 49 ms of samples: short of `align_min_duration_us` (50 ms).
                align(&mut ekf, 1..=50);
                assert_eq!(ekf.push_gps(&fix(50_500)).unwrap(), GpsOutcome::Waiting);
                align(&mut ekf, 51..=51);
                assert_eq!(ekf.push_gps(&fix(51_500)).unwrap(), GpsOutcome::Initialized);
                let e = ekf.estimate().unwrap();
                assert_eq!(e.t_us, 51_000);
                let err = euler_error(&e, &tr);
                assert!(err.amax() < 100.0 * $round, "attitude error {err}");
                // Antenna at the fix: IMU at fix - R l.
                let ant = to_f64(&e.position_ned_m) + rotation_matrix(tr.q.quaternion()) * lever;
                assert!((ant - Vector3::new(5.0, 6.0, -7.0)).amax() < 1e3 * $round);
                // Initial P from the configuration: yaw with magnetometer.
                let p = ekf.covariance();
                let pos_var = p[(POS, POS)].as_f64();
                assert!((pos_var - 25.0).abs() < 1e-3);
                assert!((p[(GYRO_BIAS, GYRO_BIAS)].as_f64() - 1e-4).abs() < 1e-8);
                assert!(p.fixed_view::<4, 4>(QUAT, QUAT).trace() > lit(0.0));
                // Without magnetometer: yaw 0, large yaw variance.
                let mut blind = Ekf16::<T>::new(config()).unwrap();
                align(&mut blind, 1..=51);
                blind.push_gps(&fix(51_500)).unwrap();
                let e2 = blind.estimate().unwrap();
                assert!(e2.euler_rad().z.abs() < lit(1e-6));
                let trace = |ekf: &Ekf16<T>| {
                    ekf.covariance()
                        .fixed_view::<4, 4>(QUAT, QUAT)
                        .trace()
                        .as_f64()
                };
                // J^T J = I/4 for a unit quaternion: trace P_qq = (s_roll² + s_pitch² + s_yaw²) / 4.
                let c = config::<f64>();
                let expected =
                    |yaw_std: f64| (2.0 * c.initial_tilt_std_rad.powi(2) + yaw_std.powi(2)) / 4.0;
                assert!((trace(&ekf) / expected(c.initial_yaw_std_rad) - 1.0).abs() < 1e3 * $round);
                assert!(
                    (trace(&blind) / expected(c.initial_yaw_std_no_mag_rad) - 1.0).abs()
                        < 1e3 * $round
                );
            }

            #[test]
            fn static_level_attitude_converges_and_biases_become_observable() {
                // At rest the x/y accelerometer bias and the tilt are one unobservable
                // combination (f_b = R^T(-g) + b_f): the prior on the bias bounds the
                // tilt error, s_b / g = 0.05 / 9.8 = 5 mrad (1 sigma) with the prior
                // of a calibrated IMU. The z bias and the three gyro biases are
                // observable (gravity; tilt drift seen by GPS velocity; magnetometer).
                let gyro_bias = [0.006, -0.004, 0.003];
                let accel_bias = [0.0, 0.0, 0.4];
                let s = Scenario {
                    motion: Motion::Static {
                        roll: 0.0,
                        pitch: 0.0,
                        yaw: 0.7,
                    },
                    imu_rate_hz: 100.0,
                    seconds: 300.0,
                    gyro_bias,
                    accel_bias,
                    noise: 1.0,
                    with_mag: true,
                    first_gps_s: 2.0,
                };
                let cfg = Ekf16Config {
                    initial_accel_bias_std_m_s2: lit(0.05),
                    ..config()
                };
                let mut ekf = Ekf16::<T>::new(cfg).unwrap();
                let mut p0 = None;
                let mut last = None;
                fly(&mut ekf, &s, |ekf, tr| {
                    if let Some(e) = ekf.estimate() {
                        p0.get_or_insert(e.covariance_diagonal);
                        last = Some((e, *tr));
                    }
                });
                let (e, tr) = last.unwrap();
                let p0 = p0.unwrap();
                let err = euler_error(&e, &tr);
                assert!(
                    err.x.abs() < 0.005 && err.y.abs() < 0.005,
                    "roll/pitch error {err}"
                );
                assert!(err.z.abs() < 0.05, "yaw error {err}");
                let bg = to_f64(&e.gyro_bias_rad_s) - Vector3::from(gyro_bias);
                assert!(bg.amax() < 1e-3, "gyro bias error {bg}");
                let bf = to_f64(&e.accel_bias_m_s2) - Vector3::from(accel_bias);
                assert!(bf.z.abs() < 0.05, "accel bias error {bf}");
                for i in 0..3 {
                    let shrink =
                        (e.covariance_diagonal[GYRO_BIAS + i] / p0[GYRO_BIAS + i]).as_f64();
                    assert!(
                        shrink < 0.1,
                        "gyro bias variance {i} only shrank to {shrink}"
                    );
                }
                let shrink = (e.covariance_diagonal[ACCEL_BIAS + 2] / p0[ACCEL_BIAS + 2]).as_f64();
                assert!(
                    shrink < 0.05,
                    "accel z bias variance only shrank to {shrink}"
                );
            }

            #[test]
            fn constant_velocity_converges_at_50_hz_and_1_khz() {
                for rate in [50.0, 1000.0] {
                    let s = Scenario {
                        motion: Motion::ConstantVelocity {
                            velocity: [6.0, -3.0, 0.5],
                        },
                        imu_rate_hz: rate,
                        seconds: 60.0,
                        gyro_bias: [0.003, 0.002, -0.004],
                        accel_bias: [0.0, 0.0, 0.2],
                        noise: 1.0,
                        with_mag: true,
                        first_gps_s: 2.0,
                    };
                    let mut ekf = Ekf16::<T>::new(config()).unwrap();
                    let (mut sum_r, mut sum_v, mut sum_nees, mut n) = (0.0, 0.0, 0.0, 0.0);
                    fly(&mut ekf, &s, |ekf, tr| {
                        if let Some(e) = ekf.estimate() {
                            if e.t_us >= 40_000_000 {
                                let dr = to_f64(&e.position_ned_m) - tr.r;
                                let dv = to_f64(&e.velocity_ned_m_s) - tr.v;
                                sum_r += dr.norm_squared();
                                sum_v += dv.norm_squared();
                                let d = SVector::<f64, 6>::from_iterator(
                                    dr.iter().chain(dv.iter()).copied(),
                                );
                                let p = ekf
                                    .covariance()
                                    .fixed_view::<6, 6>(POS, POS)
                                    .map(|x| x.as_f64());
                                sum_nees += d.dot(&p.cholesky().unwrap().solve(&d));
                                n += 1.0;
                            }
                        }
                    });
                    let (rms_r, rms_v) = ((sum_r / n).sqrt(), (sum_v / n).sqrt());
                    // The filter is honest about position and velocity: the mean
                    // normalized estimation error squared of the 6 states is near 6.
                    // (About 20 s of strongly correlated samples: a wide band.)
                    let nees = sum_nees / n;
                    assert!(nees > 2.0 && nees < 15.0, "{rate} Hz: mean NEES {nees}");
                    // GPS alone: 2 m and 0.32 m/s per axis (3.5 m, 0.55 m/s in 3-D).
                    assert!(rms_r < 1.5, "{rate} Hz: position RMS {rms_r}");
                    assert!(rms_v < 0.15, "{rate} Hz: velocity RMS {rms_v}");
                    assert_eq!(ekf.refusals().gps_position_rejected, 0);
                }
            }

            #[test]
            fn coordinated_turn_converges_from_a_wrong_start() {
                for rate in [50.0, 1000.0] {
                    let motion = Motion::Turn {
                        speed: 12.0,
                        rate: 0.25,
                        yaw0: 0.3,
                    };
                    let s = Scenario {
                        motion,
                        imu_rate_hz: rate,
                        seconds: 90.0,
                        gyro_bias: [0.004, -0.003, 0.002],
                        accel_bias: [0.15, -0.1, 0.2],
                        noise: 1.0,
                        with_mag: true,
                        first_gps_s: 2.0,
                    };
                    let tr0 = truth(motion, 0.0);
                    let e0 = euler_from_quaternion(tr0.q.quaternion());
                    // 3 deg roll, -3 deg pitch, 10 deg yaw, 5 m, 1 m/s off.
                    let start = NavState {
                        attitude: quaternion_from_euler(
                            lit(e0.x + 0.05),
                            lit(e0.y - 0.05),
                            lit(e0.z + 0.17),
                        ),
                        position_ned_m: v3(&(tr0.r + Vector3::new(5.0, -4.0, 2.0))),
                        velocity_ned_m_s: v3(&(tr0.v + Vector3::new(1.0, -1.0, 0.5))),
                        accel_bias_m_s2: Vector3::zeros(),
                        gyro_bias_rad_s: Vector3::zeros(),
                    };
                    let c = config::<T>();
                    let mut p = SMatrix::<T, NAV_STATES, NAV_STATES>::zeros();
                    p.fixed_view_mut::<4, 4>(QUAT, QUAT)
                        .copy_from(&state::attitude_covariance(
                            &start.attitude,
                            lit(0.1),
                            lit(0.1),
                            lit(0.3),
                        ));
                    for i in 0..3 {
                        p[(POS + i, POS + i)] = lit(36.0);
                        p[(VEL + i, VEL + i)] = lit(2.0);
                        p[(ACCEL_BIAS + i, ACCEL_BIAS + i)] =
                            c.initial_accel_bias_std_m_s2 * c.initial_accel_bias_std_m_s2;
                        p[(GYRO_BIAS + i, GYRO_BIAS + i)] =
                            c.initial_gyro_bias_std_rad_s * c.initial_gyro_bias_std_rad_s;
                    }
                    let mut ekf = Ekf16::from_state_with_covariance(c, 0, &start, &p).unwrap();
                    let (mut sum_r, mut sum_v, mut sum_att, mut n) = (0.0, 0.0, 0.0, 0.0);
                    fly(&mut ekf, &s, |ekf, tr| {
                        let e = ekf.estimate().unwrap();
                        if e.t_us >= 60_000_000 {
                            sum_r += (to_f64(&e.position_ned_m) - tr.r).norm_squared();
                            sum_v += (to_f64(&e.velocity_ned_m_s) - tr.v).norm_squared();
                            sum_att += euler_error(&e, tr).norm_squared();
                            n += 1.0;
                        }
                    });
                    let rms_r = (sum_r / n).sqrt();
                    let rms_v = (sum_v / n).sqrt();
                    let rms_att = (sum_att / n).sqrt();
                    assert!(rms_r < 1.5, "{rate} Hz: position RMS {rms_r}");
                    assert!(rms_v < 0.2, "{rate} Hz: velocity RMS {rms_v}");
                    // A constant-rate turn leaves a 3-parameter family unobservable: a
                    // body-frame attitude error d, gyro bias -w x d and accelerometer bias
                    // d x f change no measurement (everything is constant in the body
                    // frame). Part of the initial 3 deg tilt error stays.
                    assert!(rms_att < 0.05, "{rate} Hz: attitude RMS {rms_att} rad");
                }
            }

            #[test]
            fn unit_quaternion_and_symmetric_psd_covariance_over_100k_steps() {
                let s = Scenario {
                    motion: Motion::Turn {
                        speed: 8.0,
                        rate: 0.3,
                        yaw0: -1.0,
                    },
                    imu_rate_hz: 1000.0,
                    seconds: 100.0,
                    gyro_bias: [0.002, 0.001, -0.003],
                    accel_bias: [0.1, 0.05, -0.1],
                    noise: 1.0,
                    with_mag: true,
                    first_gps_s: 2.0,
                };
                let tr0 = truth(s.motion, 0.0);
                let start = NavState {
                    attitude: tr0.q.cast::<T>(),
                    position_ned_m: v3(&tr0.r),
                    velocity_ned_m_s: v3(&tr0.v),
                    accel_bias_m_s2: Vector3::zeros(),
                    gyro_bias_rad_s: Vector3::zeros(),
                };
                let mut p = SVector::<T, NAV_STATES>::from_element(lit(1e-2));
                p.fixed_rows_mut::<4>(QUAT).fill(lit(1e-4));
                let mut ekf = Ekf16::from_state(config(), 0, &start, &p).unwrap();
                let mut steps = 0u32;
                let mut worst_norm: f64 = 0.0;
                let mut worst_eig: f64 = 0.0;
                fly(&mut ekf, &s, |ekf, _| {
                    steps += 1;
                    let q = ekf.state_vector().fixed_rows::<4>(QUAT).norm().as_f64();
                    worst_norm = worst_norm.max((q - 1.0).abs());
                    let p = ekf.covariance();
                    assert_eq!(p, &p.transpose(), "P not symmetric at step {steps}");
                    if steps % 5000 == 0 {
                        worst_eig = worst_eig.min(min_relative_eigenvalue(p));
                    }
                });
                assert!(steps >= 100_000);
                assert!(worst_norm < 4.0 * $round, "|q| - 1 reached {worst_norm}");
                // PSD up to rounding (the quaternion's radial direction has ~0 variance).
                assert!(
                    worst_eig > -1e3 * $round,
                    "smallest relative eigenvalue {worst_eig}"
                );
                assert_eq!(ekf.refusals().imu_time, 1); // the t = 0 sample repeats the start time
            }

            fn running_filter() -> Ekf16<T> {
                running_filter_with(config())
            }

            fn running_filter_with(config: Ekf16Config<T>) -> Ekf16<T> {
                let s = Scenario {
                    motion: Motion::Turn {
                        speed: 8.0,
                        rate: 0.3,
                        yaw0: 0.0,
                    },
                    imu_rate_hz: 100.0,
                    seconds: 5.0,
                    gyro_bias: [0.0; 3],
                    accel_bias: [0.0; 3],
                    noise: 1.0,
                    with_mag: true,
                    first_gps_s: 2.0,
                };
                let mut ekf = Ekf16::<T>::new(config).unwrap();
                fly(&mut ekf, &s, |_, _| {});
                assert!(ekf.is_initialized());
                ekf
            }

            fn snapshot(
                ekf: &Ekf16<T>,
            ) -> (
                SVector<T, NAV_STATES>,
                SMatrix<T, NAV_STATES, NAV_STATES>,
                Option<u64>,
            ) {
                (*ekf.state_vector(), *ekf.covariance(), ekf.time_us())
            }

            #[test]
            fn bad_samples_are_refused_without_changing_the_state() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let before = snapshot(&ekf);
                let g = Vector3::new(lit(0.0), lit(0.0), lit(-9.8));
                let imu = |t_us, gyro: Vector3<T>, accel: Vector3<T>| Imu {
                    t_us,
                    gyro_rad_s: gyro,
                    accel_m_s2: accel,
                };
                let nan = lit(f64::NAN);
                let inf = lit(f64::INFINITY);
                assert_eq!(
                    ekf.push_imu(&imu(t + 10_000, Vector3::new(nan, lit(0.0), lit(0.0)), g)),
                    Err(Error::NonFinite { field: "imu.gyro" })
                );
                assert_eq!(
                    ekf.push_imu(&imu(
                        t + 10_000,
                        Vector3::zeros(),
                        Vector3::new(lit(0.0), inf, lit(0.0))
                    )),
                    Err(Error::NonFinite { field: "imu.accel" })
                );
                assert!(matches!(
                    ekf.push_imu(&imu(
                        t + 10_000,
                        Vector3::new(lit(1e6), lit(0.0), lit(0.0)),
                        g
                    )),
                    Err(Error::OutOfRange {
                        field: "imu.gyro",
                        ..
                    })
                ));
                assert_eq!(
                    ekf.push_imu(&imu(t, Vector3::zeros(), g)),
                    Err(Error::DuplicateTimestamp {
                        stream: "imu",
                        t_us: t
                    })
                );
                assert_eq!(
                    ekf.push_imu(&imu(t - 1, Vector3::zeros(), g)),
                    Err(Error::TimeWentBackwards {
                        stream: "imu",
                        previous_us: t,
                        got_us: t - 1
                    })
                );
                let gps =
                    |t_us, p: Vector3<T>| gps_fix(t_us, GpsPosition::Ned(p), Vector3::zeros());
                assert_eq!(
                    ekf.push_gps(&gps(t + 1, Vector3::new(nan, lit(0.0), lit(0.0)))),
                    Err(Error::NonFinite {
                        field: "gps.position"
                    })
                );
                let last_gps = ekf.last_gps_fusion().unwrap().0.t_us;
                assert!(matches!(
                    ekf.push_gps(&gps(last_gps, Vector3::zeros())),
                    Err(Error::DuplicateTimestamp { stream: "gps", .. })
                ));
                assert!(matches!(
                    ekf.push_gps(&gps(last_gps - 1, Vector3::zeros())),
                    Err(Error::TimeWentBackwards { stream: "gps", .. })
                ));
                let bad_acc = Gps {
                    horizontal_accuracy_m: Some(lit(-1.0)),
                    ..gps(t + 1, Vector3::zeros())
                };
                assert!(matches!(
                    ekf.push_gps(&bad_acc),
                    Err(Error::OutOfRange { .. })
                ));
                assert_eq!(
                    ekf.push_mag(&Mag {
                        t_us: t + 1,
                        field_body: Vector3::new(nan, lit(1.0), lit(0.0))
                    }),
                    Err(Error::NonFinite { field: "mag.field" })
                );
                assert!(matches!(
                    ekf.push_mag(&Mag {
                        t_us: t + 1,
                        field_body: Vector3::zeros()
                    }),
                    Err(Error::OutOfRange {
                        field: "mag.field",
                        ..
                    })
                ));
                let last_mag = ekf.last_mag_fusion().unwrap().t_us;
                assert!(matches!(
                    ekf.push_mag(&Mag {
                        t_us: last_mag,
                        field_body: Vector3::x()
                    }),
                    Err(Error::DuplicateTimestamp { stream: "mag", .. })
                ));
                assert_eq!(
                    snapshot(&ekf),
                    before,
                    "a refused sample changed the filter"
                );
                let r = ekf.refusals();
                assert_eq!(
                    (r.imu_non_finite, r.imu_out_of_range, r.imu_time),
                    (2, 1, 2)
                );
                assert_eq!((r.gps_invalid, r.gps_time), (2, 2));
                assert_eq!((r.mag_invalid, r.mag_time), (2, 1));
                // Still working.
                ekf.push_imu(&imu(t + 10_000, Vector3::zeros(), g)).unwrap();
                assert_eq!(ekf.time_us(), Some(t + 10_000));
            }

            /// A sample an hour ahead waits for the next to confirm the jump; meanwhile the
            /// present may be an hour away, and nothing is valid. The next sample on the old
            /// clock decides it, and the flags are what they were.
            #[test]
            fn nothing_is_valid_while_a_jump_waits_for_confirmation() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let flags = |i: delaynav::integrity::Integrity<T>| {
                    [
                        i.tilt_valid,
                        i.heading_valid,
                        i.horizontal_valid,
                        i.vertical_valid,
                        i.velocity_valid,
                    ]
                };
                let before = flags(ekf.integrity());
                assert!(before.iter().any(|&f| f), "{before:?}");
                let level = |t_us| Imu {
                    t_us,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(lit(0.0), lit(0.0), lit(-9.8)),
                };
                assert!(matches!(
                    ekf.push_imu(&level(t + 3_600_000_000)),
                    Err(Error::OutOfRange {
                        field: "imu.time",
                        ..
                    })
                ));
                assert_eq!(flags(ekf.integrity()), [false; 5]);
                ekf.push_imu(&level(t + 10_000)).unwrap();
                assert_eq!(flags(ekf.integrity()), before);
            }

            /// A gap moves the clock, carries the position by the velocity (nothing else of
            /// the state moves) and grows `P`: the process noise and the unknown motion.
            #[test]
            fn a_long_gap_moves_the_clock_carries_the_position_and_grows_p() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let (x, p, _) = snapshot(&ekf);
                let gap = ekf.config().max_imu_step_us + 1;
                let imu = Imu {
                    t_us: t + gap,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(lit(0.0), lit(0.0), lit(-9.8)),
                };
                assert_eq!(
                    ekf.push_imu(&imu),
                    Err(Error::StepTooLong {
                        dt_us: gap,
                        max_us: ekf.config().max_imu_step_us
                    })
                );
                let mut carried = x;
                let dt = lit(gap as f64 * 1e-6);
                for i in 0..3 {
                    carried[POS + i] += x[VEL + i] * dt;
                }
                assert_eq!(ekf.state_vector(), &carried);
                assert_eq!(ekf.time_us(), Some(t + gap));
                // P grows beyond its carry F P F^T (F = I + dt E_pv).
                let mut f = SMatrix::<T, NAV_STATES, NAV_STATES>::identity();
                for i in 0..3 {
                    f[(POS + i, VEL + i)] = dt;
                }
                let grown = ekf.covariance() - f * p * f.transpose();
                // The unknown motion: at least (5 m/s^2 dt)^2 on each velocity variance.
                for i in 0..3 {
                    let v = grown[(VEL + i, VEL + i)];
                    assert!(v >= lit(25.0) * dt * dt * lit(0.99), "velocity {i}: {v:?}");
                }
                assert!(
                    min_relative_eigenvalue(&grown) > -1e3 * $round,
                    "P shrank over a gap"
                );
                for i in [POS, VEL, ACCEL_BIAS, GYRO_BIAS] {
                    assert!(grown[(i, i)] > lit(0.0), "variance {i} did not grow");
                }
                assert_eq!(ekf.refusals().imu_step_too_long, 1);
                ekf.push_imu(&Imu {
                    t_us: t + gap + 10_000,
                    ..imu
                })
                .unwrap();
            }

            /// Fixes 200 m away, every 0.2 s for 6 s: all gated; once
            /// both blocks have been rejected for `gps_reset_timeout_us`
            /// (5 s after the last accepted fix, which was at most 1 s
            /// before `t`), position and velocity are reset to the fix with
            /// `R` as their variance, and the next such fix is fused. With
            /// the timeout 0 the filter never comes back.
            fn fixes_away(ekf: &mut Ekf16<T>) -> Vec<(u64, bool)> {
                let t = ekf.time_us().unwrap();
                let e = ekf.estimate().unwrap();
                let jump = Vector3::new(lit(200.0), lit(0.0), lit(0.0));
                (1..=30u64)
                    .map(|k| {
                        let fix = gps_fix(
                            t + k * 200_000,
                            GpsPosition::Ned(e.position_ned_m + jump),
                            e.velocity_ned_m_s + jump,
                        );
                        let resets = gps_resets(ekf);
                        ekf.push_gps(&fix).unwrap();
                        (k * 200_000, gps_resets(ekf) > resets)
                    })
                    .collect()
            }

            /// Fixes every 0.2 s for 7 s (no IMU step between them) whose
            /// position is `offset` away from the estimate (the first one's,
            /// or with `runaway` each one's) and whose velocity is the
            /// estimate's: the index (1-based) of the fixes that reset
            /// position, and of those that reset velocity.
            fn position_step(
                ekf: &mut Ekf16<T>,
                offset: Vector3<T>,
                runaway: bool,
            ) -> (Vec<u64>, Vec<u64>) {
                let t = ekf.time_us().unwrap();
                let first = ekf.estimate().unwrap();
                let (mut pos, mut vel) = (Vec::new(), Vec::new());
                for k in 1..=35u64 {
                    let e = if runaway {
                        ekf.estimate().unwrap()
                    } else {
                        first
                    };
                    let fix = gps_fix(
                        t + k * 200_000,
                        GpsPosition::Ned(e.position_ned_m + offset),
                        e.velocity_ned_m_s,
                    );
                    let before = ekf.refusals();
                    ekf.push_gps(&fix).unwrap();
                    let after = ekf.refusals();
                    if after.gps_position_resets > before.gps_position_resets {
                        pos.push(k);
                    }
                    if after.gps_velocity_resets > before.gps_velocity_resets {
                        vel.push(k);
                    }
                }
                (pos, vel)
            }

            #[test]
            fn a_position_step_with_good_velocity_resets_position_only() {
                let mut ekf = running_filter();
                let step = Vector3::new(lit(50.0), lit(0.0), lit(0.0));
                let (pos, vel) = position_step(&mut ekf, step, false);
                // Rejected from the first fix; reset once its own timer
                // (5 s after the last accepted fix, at most 0.1 s before the
                // first of these) ran out; velocity never rejected, never reset.
                assert!(
                    pos == [25] || pos == [26],
                    "position resets at fixes {pos:?}"
                );
                assert!(vel.is_empty(), "velocity resets at fixes {vel:?}");
                let r = ekf.refusals();
                assert_eq!((r.gps_position_resets, r.gps_velocity_resets), (1, 0));
                assert_eq!(r.gps_divergence_resets, 0);
                let reset = ekf.last_gps_reset().unwrap();
                assert_eq!(reset.block, GpsBlock::Position);
                assert_eq!(reset.cause, GpsResetCause::Rejected);
                // The fixes after the reset are fused.
                let (position, velocity) = ekf.last_gps_fusion().unwrap();
                assert!(position.fused && velocity.fused);
                let p = ekf.covariance();
                assert!(p == &p.transpose());
                assert!(min_relative_eigenvalue(p) > -1e3 * $round);
            }

            #[test]
            fn a_consistent_bias_below_the_gate_is_a_divergence() {
                // Every position 5 sigma north of the estimate: each fix
                // passes the 5-sigma gate, but the mean NIS of 20 of them is
                // above the bound of 20.
                let mut ekf = running_filter();
                let sigma = ekf.config().gps_horizontal_std_m;
                let offset = Vector3::new(sigma * lit(5.0), lit(0.0), lit(0.0));
                let (pos, vel) = position_step(&mut ekf, offset, true);
                assert!(!pos.is_empty() && vel.is_empty(), "{pos:?} {vel:?}");
                let r = ekf.refusals();
                assert!(r.gps_divergence_resets >= 1);
                assert_eq!(r.gps_divergence_resets, r.gps_position_resets);
                assert_eq!(ekf.last_gps_reset().unwrap().cause, GpsResetCause::Diverged);
                let p = ekf.covariance();
                assert!(min_relative_eigenvalue(p) > -1e3 * $round);
                // Without the window, no reset.
                let mut off = running_filter_with(Ekf16Config {
                    gps_nis_window: 0,
                    ..config()
                });
                assert_eq!(position_step(&mut off, offset, true).0, Vec::<u64>::new());
            }

            #[test]
            fn a_first_fix_glitch_recovers() {
                // The first fix 1000 km north initializes the filter there;
                // the next ones are right: position rejected, reset after
                // its timeout, velocity fused throughout.
                let mut ekf = Ekf16::<T>::new(config()).unwrap();
                let g = Vector3::new(lit(0.0), lit(0.0), lit(-G));
                for k in 0..=800u64 {
                    let t = k * 10_000;
                    ekf.push_imu(&Imu {
                        t_us: t,
                        gyro_rad_s: Vector3::zeros(),
                        accel_m_s2: g,
                    })
                    .unwrap();
                    if k % 20 == 10 {
                        let north = if k == 10 { lit(1e6) } else { lit(0.0) };
                        let fix = gps_fix(
                            t,
                            GpsPosition::Ned(Vector3::new(north, lit(0.0), lit(0.0))),
                            Vector3::zeros(),
                        );
                        ekf.push_gps(&fix).unwrap();
                    }
                }
                let e = ekf.estimate().unwrap();
                assert!(e.position_ned_m.norm() < lit(5.0), "{:?}", e.position_ned_m);
                let r = ekf.refusals();
                assert_eq!((r.gps_position_resets, r.gps_velocity_resets), (1, 0));
            }

            #[test]
            fn geodetic_and_ned_fixes_do_not_mix() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let before = snapshot(&ekf);
                let geo = GpsPosition::Geodetic(Geodetic {
                    lat_deg: 31.0,
                    lon_deg: 121.0,
                    alt_m: 10.0,
                });
                assert!(matches!(
                    ekf.push_gps(&gps_fix(t + 1, geo, Vector3::zeros())),
                    Err(Error::OutOfRange {
                        field: "gps.position",
                        ..
                    })
                ));
                assert_eq!(snapshot(&ekf), before);
                assert_eq!(ekf.refusals().gps_mixed_frames, 1);
            }

            #[test]
            fn persistently_rejected_gps_resets_position_and_velocity() {
                let mut ekf = running_filter();
                let e = ekf.estimate().unwrap();
                let resets: Vec<_> = fixes_away(&mut ekf)
                    .into_iter()
                    .filter(|r| r.1)
                    .map(|r| r.0)
                    .collect();
                assert_eq!(resets.len(), 1, "{resets:?}");
                assert!((4_000_000..=5_200_000).contains(&resets[0]), "{resets:?}");
                let after = ekf.estimate().unwrap();
                let jump = Vector3::new(lit(200.0), lit(0.0), lit(0.0));
                assert!((after.position_ned_m - e.position_ned_m - jump).norm() < lit(1e-3));
                assert!((after.velocity_ned_m_s - e.velocity_ned_m_s - jump).norm() < lit(1e-3));
                let p = ekf.covariance();
                let r = ekf.config().gps_horizontal_std_m.powi(2);
                assert!(p == &p.transpose());
                assert!(min_relative_eigenvalue(p) > -1e3 * $round);
                assert_eq!(p.row(POS).iter().filter(|v| **v != lit(0.0)).count(), 1);
                // Reset to `R`, then each later fix (same value, no IMU step)
                // fused: `1/P` grows by `1/R` per fix.
                let fused_after = (30 - resets[0] / 200_000) as f64;
                let expected = r.as_f64() / (fused_after + 1.0);
                assert!((p[(POS, POS)].as_f64() / expected - 1.0).abs() < 1e-4);
                assert_eq!(ekf.refusals().gps_position_resets, 1);
                assert_eq!(ekf.refusals().gps_velocity_resets, 1);
                // The fixes after the reset agree with the state: fused.
                let (position, velocity) = ekf.last_gps_fusion().unwrap();
                assert!(position.fused && velocity.fused);

                let mut never = running_filter_with(Ekf16Config {
                    gps_reset_timeout_us: 0,
                    ..config()
                });
                let before = never.estimate().unwrap();
                assert!(fixes_away(&mut never).iter().all(|r| !r.1));
                assert_eq!(gps_resets(&never), 0);
                assert_eq!(
                    never.estimate().unwrap().position_ned_m,
                    before.position_ned_m
                );
            }

            #[test]
            fn gps_outlier_is_gated_out_and_recorded() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let before = snapshot(&ekf);
                let e = ekf.estimate().unwrap();
                let jump = Vector3::new(lit(200.0), lit(0.0), lit(0.0));
                let fix = gps_fix(
                    t + 1,
                    GpsPosition::Ned(e.position_ned_m + jump),
                    e.velocity_ned_m_s + jump,
                );
                let GpsOutcome::Fused { position, velocity } = ekf.push_gps(&fix).unwrap() else {
                    panic!("expected a fusion attempt")
                };
                assert!(!position.fused && !velocity.fused);
                assert!(position.test_ratio > lit(1.0) && velocity.test_ratio > lit(1.0));
                assert!((position.innovation.x - lit(200.0)).abs() < lit(1.0));
                assert!(position.innovation_variance.x > lit(0.0));
                assert_eq!((snapshot(&ekf).0, snapshot(&ekf).1), (before.0, before.1));
                let r = ekf.refusals();
                assert_eq!((r.gps_position_rejected, r.gps_velocity_rejected), (1, 1));
                // A consistent fix is fused, with a test ratio below one.
                let good = Gps {
                    t_us: t + 2,
                    position: GpsPosition::Ned(e.position_ned_m),
                    velocity_ned_m_s: e.velocity_ned_m_s,
                    ..fix
                };
                let GpsOutcome::Fused { position, .. } = ekf.push_gps(&good).unwrap() else {
                    panic!()
                };
                assert!(position.fused && position.test_ratio < lit(1.0));
                // The receiver's accuracy replaces the configured noise.
                let rx = Gps {
                    t_us: t + 3,
                    horizontal_accuracy_m: Some(lit(30.0)),
                    vertical_accuracy_m: Some(lit(40.0)),
                    speed_accuracy_m_s: Some(lit(3.0)),
                    ..good
                };
                let GpsOutcome::Fused { position, velocity } = ekf.push_gps(&rx).unwrap() else {
                    panic!()
                };
                assert!(
                    position.innovation_variance.x > lit(900.0)
                        && position.innovation_variance.z > lit(1600.0)
                );
                assert!(velocity.innovation_variance.y > lit(9.0));
            }

            #[test]
            fn geodetic_fixes_use_the_first_fix_as_origin() {
                let mut ekf = Ekf16::<T>::new(config()).unwrap();
                let g = Vector3::new(lit(0.0), lit(0.0), lit(-G));
                for k in 0..10u64 {
                    ekf.push_imu(&Imu {
                        t_us: k * 10_000,
                        gyro_rad_s: Vector3::zeros(),
                        accel_m_s2: g,
                    })
                    .unwrap();
                }
                let origin = delaynav::Geodetic {
                    lat_deg: -35.36,
                    lon_deg: 149.16,
                    alt_m: 580.0,
                };
                let fix = |t_us, alt_m| {
                    gps_fix(
                        t_us,
                        GpsPosition::Geodetic(delaynav::Geodetic { alt_m, ..origin }),
                        Vector3::zeros(),
                    )
                };
                assert_eq!(
                    ekf.push_gps(&fix(95_000, 580.0)).unwrap(),
                    GpsOutcome::Initialized
                );
                assert_eq!(ekf.frame().unwrap().origin(), origin);
                assert!(ekf.estimate().unwrap().position_ned_m.norm() < lit(1e-6));
                ekf.push_imu(&Imu {
                    t_us: 100_000,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: g,
                })
                .unwrap();
                // 1 m higher is 1 m "up" (negative down).
                let GpsOutcome::Fused { position, .. } =
                    ekf.push_gps(&fix(105_000, 581.0)).unwrap()
                else {
                    panic!()
                };
                assert!((position.innovation.z + lit(1.0)).abs() < lit(1e-3));
            }

            /// Pushes, at t = 1 ms, the noise-free field of a vehicle at
            /// this attitude (rad): the record of the magnetometer update.
            fn mag_seen_at(
                ekf: &mut Ekf16<T>,
                roll: f64,
                pitch: f64,
                yaw: f64,
            ) -> FusionRecord<T, 3> {
                let seen = quaternion_from_euler(roll, pitch, yaw);
                let m_b = rotation_matrix(seen.quaternion()).transpose()
                    * magnetic_field_ned(INCLINATION, DECLINATION);
                let field_body = v3(&m_b);
                match ekf.push_mag(&Mag {
                    t_us: 1_000,
                    field_body,
                }) {
                    Ok(MagOutcome::Fused(rec)) => rec,
                    other => panic!("expected a fusion, got {other:?}"),
                }
            }

            /// At rest at the origin with this attitude (rad), biases 0.
            fn at_rest(roll: f64, pitch: f64, yaw: f64) -> NavState<T> {
                NavState {
                    attitude: quaternion_from_euler(lit(roll), lit(pitch), lit(yaw)),
                    position_ned_m: Vector3::zeros(),
                    velocity_ned_m_s: Vector3::zeros(),
                    accel_bias_m_s2: Vector3::zeros(),
                    gyro_bias_rad_s: Vector3::zeros(),
                }
            }

            #[test]
            fn magnetometer_update_corrects_yaw_and_not_roll_or_pitch() {
                let (roll, pitch, yaw) = (0.17, -0.26, 0.7);
                let start = at_rest(roll, pitch, yaw);
                let mut p = SMatrix::<T, NAV_STATES, NAV_STATES>::identity() * lit(0.01);
                p.fixed_view_mut::<4, 4>(QUAT, QUAT)
                    .copy_from(&state::attitude_covariance(
                        &start.attitude,
                        lit(0.05),
                        lit(0.05),
                        lit(0.3),
                    ));
                // The yaw-only ("consider") mode: roll and pitch stay put.
                let yaw_only = Ekf16Config {
                    mag_corrects_tilt: false,
                    mag_tilt_alignment_std_rad: lit(f64::INFINITY),
                    ..config()
                };
                let mut ekf =
                    Ekf16::from_state_with_covariance(yaw_only, 1_000, &start, &p).unwrap();
                // The magnetometer sees the vehicle 20 deg further right.
                let rec = mag_seen_at(&mut ekf, roll, pitch, yaw + 0.35);
                assert!(rec.fused, "test ratio {}", rec.test_ratio.as_f64());
                let e = to_f64(&ekf.estimate().unwrap().euler_rad());
                let moved = wrap_pi(e.z - yaw);
                assert!(moved > 0.1 && moved < 0.35, "yaw moved by {moved}");
                assert!(
                    (e.x - roll).abs() < 100.0 * $round,
                    "roll moved by {}",
                    e.x - roll
                );
                assert!(
                    (e.y - pitch).abs() < 100.0 * $round,
                    "pitch moved by {}",
                    e.y - pitch
                );
                // Nothing but the attitude moved (no correlations in this P).
                let x = ekf.state_vector();
                assert!(x.rows(POS, NAV_STATES - POS).amax() < lit(100.0 * $round));
            }

            #[test]
            fn a_heading_update_cannot_move_tilt_or_the_accel_bias() {
                // A dense covariance: tilt, yaw, velocity and both biases
                // all correlated (P = A Aᵀ, A with every entry non-zero).
                let (roll, pitch, yaw) = (0.3, -0.2, 1.1);
                let start = at_rest(roll, pitch, yaw);
                let a = SMatrix::<T, NAV_STATES, NAV_STATES>::from_fn(|i, j| {
                    let d = if i == j { 0.2 } else { 0.0 };
                    lit(d + 0.05 * ((3 * i + 7 * j) as f64).sin())
                });
                let p = a * a.transpose();
                let down_before =
                    rotation_matrix(start.attitude.quaternion()).transpose() * Vector3::z();
                // The magnetometer sees the vehicle 60 deg further right.
                // Heading only from the start (no alignment exception), gate open.
                let run = |alignment_std: f64| {
                    let c = Ekf16Config {
                        mag_gate: lit(f64::INFINITY),
                        mag_tilt_alignment_std_rad: lit(alignment_std),
                        ..config()
                    };
                    assert!(!c.mag_corrects_tilt, "heading-only is the default");
                    let mut ekf = Ekf16::from_state_with_covariance(c, 1_000, &start, &p).unwrap();
                    assert!(mag_seen_at(&mut ekf, roll, pitch, yaw + 60f64.to_radians()).fused);
                    let e = ekf.estimate().unwrap();
                    let down_after =
                        rotation_matrix(e.attitude.quaternion()).transpose() * Vector3::z();
                    let tilt = to_f64(&down_before).cross(&to_f64(&down_after)).norm();
                    (ekf, e, tilt)
                };
                let (ekf, e, tilt) = run(f64::INFINITY);
                let moved = wrap_pi(to_f64(&e.euler_rad()).z - yaw);
                assert!(moved.abs() > 0.01, "yaw moved by {moved}");
                // Tilt: the angle between the body-frame down axis before and after.
                assert!(tilt < 1e-6, "tilt moved by {tilt} rad");
                assert!(e.accel_bias_m_s2.amax() == lit(0.0));
                // The gyro bias moved along the body-frame down axis only.
                let bw = to_f64(&e.gyro_bias_rad_s);
                assert!(bw.norm() > 0.0);
                assert!(bw.cross(&to_f64(&down_before)).norm() < 1e-5 * bw.norm().max(1e-3));
                let p = ekf.covariance();
                assert!(p == &p.transpose());
                assert!(min_relative_eigenvalue(p) > -1e3 * $round);
                // With the default alignment bound (2 deg) this tilt, uncertain
                // by far more, is still corrected by the magnetometer.
                assert!(ekf.tilt_std() > lit(0.035));
                let (_, _, tilt) = run(0.035);
                assert!(tilt > 1e-3, "tilt moved by {tilt} rad");
            }

            #[test]
            fn a_disturbed_field_is_refused_and_counted() {
                let mut ekf = running_filter();
                let t = ekf.time_us().unwrap();
                let e = ekf.estimate().unwrap();
                let before = snapshot(&ekf);
                let m_n = magnetic_field_ned(INCLINATION, DECLINATION);
                let body = |m: Vector3<f64>| -> Vector3<T> {
                    rotation_matrix(e.attitude.quaternion()).transpose() * v3::<T>(&m)
                };
                // Twice the norm; then the right norm, 46 deg less inclined.
                let tilted = Vector3::new(m_n.x, m_n.y, 0.0).normalize()
                    * (INCLINATION - 0.8).cos()
                    + Vector3::z() * (INCLINATION - 0.8).sin();
                for (k, m) in [m_n * 2.0, tilted].into_iter().enumerate() {
                    let outcome = ekf.push_mag(&Mag {
                        t_us: t + 1 + k as u64,
                        field_body: body(m),
                    });
                    let Ok(MagOutcome::Fused(rec)) = outcome else {
                        panic!("{outcome:?}")
                    };
                    assert!(!rec.fused && rec.test_ratio.is_infinite(), "{k}: {rec:?}");
                }
                assert_eq!(ekf.refusals().mag_disturbed, 2);
                assert_eq!(snapshot(&ekf).0, before.0);
                assert_eq!(snapshot(&ekf).1, before.1);
                // The undisturbed field still goes through.
                assert!(matches!(
                    ekf.push_mag(&Mag {
                        t_us: t + 3,
                        field_body: body(m_n),
                    }),
                    Ok(MagOutcome::Fused(_))
                ));
            }
        }
    };
}

ekf16_tests!(
    f32_ekf,
    f32,
    jac_step = 1e-2,
    jac_tol = 2e-3,
    round = 1.2e-7
);
ekf16_tests!(
    f64_ekf,
    f64,
    jac_step = 1e-5,
    jac_tol = 1e-7,
    round = 2.3e-16
);

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn finite() -> impl Strategy<Value = f64> {
        prop_oneof![-1e3f64..1e3, -1e30f64..1e30, Just(0.0), -50.0f64..50.0]
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
            acc: Option<f64>,
        },
        Mag {
            dt_us: u64,
            m: [f64; 3],
        },
    }

    fn input() -> impl Strategy<Value = Input> {
        prop_oneof![
            6 => (0u64..300_000, vec3(), vec3()).prop_map(|(dt_us, gyro, accel)| Input::Imu { dt_us, gyro, accel }),
            1 => (0u64..300_000, vec3(), vec3(), proptest::option::of(-1.0f64..100.0))
                .prop_map(|(dt_us, p, v, acc)| Input::Gps { dt_us, p, v, acc }),
            1 => (0u64..300_000, vec3()).prop_map(|(dt_us, m)| Input::Mag { dt_us, m }),
        ]
    }

    /// What the property looks at in a filter: its full state and covariance.
    trait Inspect {
        fn initialized(&self) -> bool;
        /// State and covariance finite, and the quaternion's norm.
        fn health(&self) -> (bool, bool, f64);
    }

    /// Both filters expose the same inherent accessors.
    macro_rules! inspect_filter {
        ($filter:ident) => {
            impl<T: Scalar> Inspect for $filter<T> {
                fn initialized(&self) -> bool {
                    self.is_initialized()
                }
                fn health(&self) -> (bool, bool, f64) {
                    let x = self.state_vector();
                    let finite = |m: &[T]| m.iter().all(|v| v.is_finite());
                    let q = x.fixed_rows::<4>(QUAT).norm().as_f64();
                    (
                        finite(x.as_slice()),
                        finite(self.covariance().as_slice()),
                        q,
                    )
                }
            }
        };
    }
    inspect_filter!(Ekf16);
    inspect_filter!(AugmentedEkf17);

    fn run<T: Scalar, N: Navigator<T> + Inspect>(
        mut ekf: N,
        inputs: &[Input],
    ) -> Result<(), TestCaseError> {
        let (mut t_imu, mut t_gps, mut t_mag) = (0u64, 0u64, 0u64);
        let c = |a: &[f64; 3]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));
        for i in inputs {
            // Results are allowed to be errors: only panics and NaN fail.
            match i {
                Input::Imu { dt_us, gyro, accel } => {
                    t_imu += dt_us;
                    let _ = ekf.push_imu(&Imu {
                        t_us: t_imu,
                        gyro_rad_s: c(gyro),
                        accel_m_s2: c(accel),
                    });
                }
                Input::Gps { dt_us, p, v, acc } => {
                    t_gps += dt_us;
                    let _ = ekf.push_gps(&Gps {
                        t_us: t_gps,
                        position: GpsPosition::Ned(c(p)),
                        velocity_ned_m_s: c(v),
                        horizontal_accuracy_m: acc.map(T::lit),
                        vertical_accuracy_m: None,
                        speed_accuracy_m_s: acc.map(T::lit),
                    });
                }
                Input::Mag { dt_us, m } => {
                    t_mag += dt_us;
                    let _ = ekf.push_mag(&Mag {
                        t_us: t_mag,
                        field_body: c(m),
                    });
                }
            }
            if ekf.initialized() {
                let (state_finite, covariance_finite, n) = ekf.health();
                prop_assert!(state_finite, "non-finite state");
                prop_assert!(covariance_finite, "non-finite covariance");
                prop_assert!((n - 1.0).abs() < 1e-4, "|q| = {}", n);
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        #[test]
        fn arbitrary_finite_inputs_never_panic_or_produce_nan(inputs in proptest::collection::vec(input(), 1..200)) {
            run(Ekf16::<f32>::new(config()).unwrap(), &inputs)?;
            run(Ekf16::<f64>::new(config()).unwrap(), &inputs)?;
            run(AugmentedEkf17::<f32>::new(AugmentedEkf17Config::with_nav(config())).unwrap(), &inputs)?;
            run(AugmentedEkf17::<f64>::new(AugmentedEkf17Config::with_nav(config())).unwrap(), &inputs)?;
        }
    }
}

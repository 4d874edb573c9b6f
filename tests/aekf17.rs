//! aekf17: the delayed GPS Jacobian against finite differences, delay
//! convergence with motion, a delay held (its variance growing) without it, the range
//! clamp, the delay setter and the refusal of bad input, in f32 and f64.

use delaynav::ekf16::state::{ACCEL_BIAS, GYRO_BIAS, NAV_STATES, POS, QUAT, VEL};
use delaynav::geo::{quaternion_from_euler, rotation_matrix};
use delaynav::internals::aekf17_measurement::{
    self as aekf17_measurement, AUGMENTED_STATES, AugmentedStateVector, DELAY,
    navigation_acceleration,
};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Error, Geodetic, GpsOutcome, GpsPosition, Imu,
    Mag, NavState, Navigator, Scalar,
};
use nalgebra::{SMatrix, Vector3};

mod flight;
use flight::*;

/// The augmented filter configured like the 16-state tests' filter.
fn aekf_config<T: Scalar>(initial_delay_s: f64) -> AugmentedEkf17Config<T> {
    AugmentedEkf17Config {
        initial_delay_s: T::lit(initial_delay_s),
        ..AugmentedEkf17Config::with_nav(config())
    }
}

/// The 17-state sample: the 16-state sample plus a delay of 0.2 s.
fn sample_augmented<T: Scalar>() -> AugmentedStateVector<T> {
    let mut x = AugmentedStateVector::zeros();
    x.fixed_rows_mut::<NAV_STATES>(0)
        .copy_from(&sample_state::<T>());
    x[DELAY] = T::lit(0.2);
    x
}

/// Weaving at up to 5 m/s² with a period of 6.3 s: the delay is observable.
///
/// (A steady turn would not do: a delayed fix then looks like the present
/// rotated by `rate * tau`, which a yaw error explains as well as a delay.)
fn weaving(seconds: f64) -> Scenario {
    Scenario {
        motion: Motion::Weave {
            speed: 6.0,
            amplitude: 5.0,
            omega: 1.0,
        },
        imu_rate_hz: 100.0,
        seconds,
        gyro_bias: [0.0; 3],
        accel_bias: [0.0; 3],
        noise: 1.0,
        with_mag: true,
        first_gps_s: 2.0,
    }
}

macro_rules! aekf17_tests {
    ($mod:ident, $t:ty, jac_step = $step:expr, jac_tol = $jtol:expr, round = $round:expr) => {
        mod $mod {
            use super::*;
            type T = $t;

            fn lit(x: f64) -> T {
                T::lit(x)
            }

            #[test]
            fn delayed_gps_jacobians_match_finite_differences_in_every_state() {
                let x = sample_augmented::<T>();
                let lever = Vector3::new(lit(0.3), lit(-0.2), lit(-0.5));
                let gyro = Vector3::new(lit(0.5), lit(-0.3), lit(0.8));
                let accel = Vector3::new(lit(3.0), lit(-2.0), lit(-8.0));
                let g = lit(G);
                let (_, hp) = aekf17_measurement::delayed_gps_position(&x, &accel, &lever, g);
                let np = numeric_jacobian(&x, lit($step), |x| {
                    aekf17_measurement::delayed_gps_position(x, &accel, &lever, g).0
                });
                let err = max_abs_diff(&hp, &np);
                assert!(err < $jtol, "delayed position H: {err}");
                let (_, hv) =
                    aekf17_measurement::delayed_gps_velocity(&x, &gyro, &accel, &lever, g);
                let nv = numeric_jacobian(&x, lit($step), |x| {
                    aekf17_measurement::delayed_gps_velocity(x, &gyro, &accel, &lever, g).0
                });
                let err = max_abs_diff(&hv, &nv);
                assert!(err < $jtol, "delayed velocity H: {err}");
                // Every dependency is there: through v, q, b_f and tau in
                // the position block, through q, b_f, b_w and tau in the
                // velocity block.
                let tau = 0.2;
                assert!((hp[(0, VEL)].as_f64() + tau).abs() < 10.0 * $round);
                assert!(hp.fixed_view::<3, 3>(0, ACCEL_BIAS).amax() > lit(0.5 * tau * tau / 2.0));
                assert!(hv.fixed_view::<3, 3>(0, ACCEL_BIAS).amax() > lit(0.5 * tau));
                assert!(hv.fixed_view::<3, 3>(0, GYRO_BIAS).amax() > lit(0.1));
                let (a, _, _) = navigation_acceleration(&x, &accel, g);
                let v = x.fixed_rows::<3>(VEL).into_owned();
                let dp_dtau = hp.fixed_view::<3, 1>(0, DELAY).into_owned();
                assert!(max_abs_diff(&dp_dtau, &(a * lit(tau) - v)) < 100.0 * $round);
                let dv_dtau = hv.fixed_view::<3, 1>(0, DELAY).into_owned();
                assert!(max_abs_diff(&dv_dtau, &(-a)) < 100.0 * $round);
                // The attitude terms differ from the 16-state ones by the
                // acceleration's dependence on q.
                let (_, h16) = delaynav::internals::measurement::gps_velocity(
                    &sample_state::<T>(),
                    &gyro,
                    &lever,
                );
                let dq = hv.fixed_view::<3, 4>(0, QUAT) - h16.fixed_view::<3, 4>(0, QUAT);
                assert!(dq.amax() > lit(0.5));
            }

            #[test]
            fn with_zero_delay_the_model_is_the_16_state_one() {
                let mut x = sample_augmented::<T>();
                x[DELAY] = lit(0.0);
                let lever = Vector3::new(lit(0.3), lit(-0.2), lit(-0.5));
                let gyro = Vector3::new(lit(0.5), lit(-0.3), lit(0.8));
                let accel = Vector3::new(lit(3.0), lit(-2.0), lit(-8.0));
                let x16 = sample_state::<T>();
                let (hp, jp) = aekf17_measurement::delayed_gps_position(&x, &accel, &lever, lit(G));
                let (hp16, jp16) = delaynav::internals::measurement::gps_position(&x16, &lever);
                assert_eq!(hp, hp16);
                assert_eq!(jp.fixed_view::<3, 16>(0, 0), jp16);
                let (hv, jv) =
                    aekf17_measurement::delayed_gps_velocity(&x, &gyro, &accel, &lever, lit(G));
                let (hv16, jv16) =
                    delaynav::internals::measurement::gps_velocity(&x16, &gyro, &lever);
                assert_eq!(hv, hv16);
                assert_eq!(jv.fixed_view::<3, 16>(0, 0), jv16);
            }

            #[test]
            fn delay_converges_while_weaving_and_its_std_is_honest() {
                let true_delay = 0.15;
                let mut aekf = AugmentedEkf17::<T>::new(aekf_config(0.05)).unwrap();
                let mut worst_late = 0.0f64;
                let mut early_clamps = 0;
                let mut t = 0.0;
                fly_delayed(&mut aekf, &weaving(60.0), true_delay, |nav, _| {
                    t += 0.01;
                    if let Some(e) = nav.estimate() {
                        let err = e.delay_s.unwrap().as_f64() - true_delay;
                        let std = e.delay_std_s.unwrap().as_f64();
                        if t <= 10.0 {
                            early_clamps = nav.delay_clamps();
                        }
                        if t > 30.0 {
                            worst_late = worst_late.max(err.abs());
                            assert!(err.abs() < 4.0 * std, "t {t}: err {err}, std {std}");
                        }
                    }
                });
                let err = aekf.delay_s().as_f64() - true_delay;
                assert!(err.abs() < 0.015, "final delay error {err}");
                assert!(
                    worst_late < 0.03,
                    "worst delay error after 30 s {worst_late}"
                );
                assert!(aekf.delay_std_s().as_f64() < 0.02);
                // The range was only needed while attitude and delay settled.
                assert_eq!(aekf.delay_clamps(), early_clamps);
                // The weave leaves the delay gated only near its zero
                // crossings and while the attitude aligns: a minority of
                // the 580 fixes.
                let gated = aekf.delay_unobservable_fixes();
                assert!(gated > 0 && gated < 200, "{gated} fixes gated");
                let r = aekf.refusals();
                assert_eq!(r.gps_position_rejected + r.gps_velocity_rejected, 0);
            }

            #[test]
            fn with_a_delayed_gps_it_navigates_better_than_the_16_state_filter() {
                let true_delay = 0.2;
                let s = weaving(60.0);
                let velocity_rms = |run: &mut dyn FnMut(&mut dyn FnMut(Vector3<f64>, &Truth))| {
                    let (mut sum, mut n) = (0.0, 0);
                    let mut t = 0.0;
                    run(&mut |v, tr| {
                        t += 0.01;
                        if t > 20.0 {
                            sum += (v - tr.v).norm_squared();
                            n += 1;
                        }
                    });
                    (sum / n as f64).sqrt()
                };
                let aekf = velocity_rms(&mut |each| {
                    let mut nav = AugmentedEkf17::<T>::new(aekf_config(0.1)).unwrap();
                    fly_delayed(&mut nav, &s, true_delay, |nav, tr| {
                        if let Some(e) = nav.estimate() {
                            each(to_f64(&e.velocity_ned_m_s), tr);
                        }
                    });
                });
                let ekf = velocity_rms(&mut |each| {
                    let mut nav = Ekf16::<T>::new(config()).unwrap();
                    fly_delayed(&mut nav, &s, true_delay, |nav, tr| {
                        if let Some(e) = nav.estimate() {
                            each(to_f64(&e.velocity_ned_m_s), tr);
                        }
                    });
                });
                assert!(
                    aekf < 0.5 * ekf,
                    "velocity RMS: aekf17 {aekf} m/s, ekf16 {ekf} m/s"
                );
            }

            /// Runs a motion without horizontal acceleration and returns the
            /// delay standard deviation at the end, after checking the
            /// estimate stayed within 3 sigma of the truth.
            fn unobservable_run(motion: Motion) -> f64 {
                let true_delay = 0.15;
                let s = Scenario {
                    motion,
                    ..weaving(60.0)
                };
                let mut aekf = AugmentedEkf17::<T>::new(aekf_config(0.1)).unwrap();
                fly_delayed(&mut aekf, &s, true_delay, |nav, _| {
                    if let Some(e) = nav.estimate() {
                        let err = e.delay_s.unwrap().as_f64() - true_delay;
                        let std = e.delay_std_s.unwrap().as_f64();
                        assert!(err.abs() < 3.0 * std, "err {err}, std {std}");
                    }
                });
                aekf.delay_std_s().as_f64()
            }

            #[test]
            fn without_horizontal_acceleration_the_delay_variance_does_not_collapse() {
                let initial = AugmentedEkf17Config::<f64>::default().initial_delay_std_s;
                // At rest the only "acceleration" is noise, below the
                // gate (see the aekf17 module docs): the variance grows by
                // the random walk and the estimate stays within its 3 sigma
                // (checked in the run).
                let at_rest = unobservable_run(Motion::Static {
                    roll: 0.1,
                    pitch: -0.05,
                    yaw: 0.4,
                });
                assert!(at_rest > initial, "at rest: std {at_rest}");
                // At constant velocity the position block sees `-v tau`, but
                // a position offset explains it equally well: gated too.
                let cruising = unobservable_run(Motion::ConstantVelocity {
                    velocity: [6.0, 3.0, 0.0],
                });
                assert!(cruising > initial, "cruising: std {cruising}");
            }

            /// A hover of `seconds` (a static attitude, noisy sensors, the
            /// magnetometer on) started at the true delay, with the gate at
            /// `min_accel` m/s²: the largest |delay - truth| (s), the delay
            /// std at the first fix after initialization and its smallest
            /// and final values after it (s), and the fixes fused without a
            /// delay update.
            fn hover_run(seconds: f64, min_accel: f64) -> (f64, f64, f64, f64, u32) {
                let true_delay = 0.15;
                let s = Scenario {
                    motion: Motion::Static {
                        roll: 0.1,
                        pitch: -0.05,
                        yaw: 0.4,
                    },
                    ..weaving(seconds)
                };
                let config = AugmentedEkf17Config {
                    delay_min_accel_m_s2: lit(min_accel),
                    ..aekf_config(true_delay)
                };
                let mut aekf = AugmentedEkf17::<T>::new(config).unwrap();
                let (mut moved, mut first_std, mut min_std) = (0.0f64, None, f64::INFINITY);
                fly_delayed(&mut aekf, &s, true_delay, |nav, _| {
                    if let Some(e) = nav.estimate() {
                        let err = e.delay_s.unwrap().as_f64() - true_delay;
                        let std = e.delay_std_s.unwrap().as_f64();
                        moved = moved.max(err.abs());
                        first_std.get_or_insert(std);
                        min_std = min_std.min(std);
                    }
                });
                let first_std = first_std.unwrap();
                let final_std = aekf.delay_std_s().as_f64();
                (
                    moved,
                    first_std,
                    min_std,
                    final_std,
                    aekf.delay_unobservable_fixes(),
                )
            }

            #[test]
            fn at_a_long_hover_the_delay_holds_and_its_std_grows() {
                // 300 s, GPS at 10 Hz from 2 s: 2980 fixes after the one
                // that initializes.
                let (moved, first, min, last, gated) = hover_run(300.0, 0.5);
                assert_eq!(gated, 2980, "every fix leaves the delay alone");
                // The magnetometer still moves it through its correlations.
                assert!(moved < 0.01, "the delay moved by {moved} s");
                // Its std does not shrink but by what the magnetometer
                // takes through the correlations (0.9993 of the start with
                // the 3-axis update, 0.9999 with the heading-only one it
                // replaced) and grows by the random walk:
                // sqrt(0.1² + 1e-6 * 298) = 0.10148 s.
                assert!(min > 0.999 * first, "std {first} -> {min} s");
                // The 3-axis magnetometer update ends 0.2 ms below it (f32
                // 0.10132, f64 0.10128 s); the heading-only one ended within
                // 0.1 ms, and so does this hover with `mag_three_axis` off.
                let grown = (first * first + 1e-6 * 298.0).sqrt();
                assert!(
                    (last - grown).abs() < 3e-4,
                    "final std {last}, random walk {grown}"
                );
                // Without the gate the same hover drifts while the std
                // collapses: the dishonest case this gate removes.
                let (moved, _, _, last, gated) = hover_run(300.0, 0.0);
                assert_eq!(gated, 0);
                assert!(moved > 0.05, "ungated: the delay moved by {moved} s");
                assert!(last < 0.5 * first, "ungated: final std {last}");
            }

            /// A filter started level at rest, accelerating north at 3 m/s².
            fn accelerating(initial_delay_s: f64) -> AugmentedEkf17<T> {
                let start = NavState {
                    attitude: quaternion_from_euler(lit(0.0), lit(0.0), lit(0.0)),
                    position_ned_m: Vector3::zeros(),
                    velocity_ned_m_s: Vector3::zeros(),
                    accel_bias_m_s2: Vector3::zeros(),
                    gyro_bias_rad_s: Vector3::zeros(),
                };
                let mut diag = SMatrix::<T, NAV_STATES, 1>::repeat(lit(1e-4));
                diag.fixed_rows_mut::<4>(QUAT).fill(lit(1e-6));
                let mut aekf =
                    AugmentedEkf17::from_state(aekf_config(initial_delay_s), 0, &start, &diag)
                        .unwrap();
                for k in 1..=10u64 {
                    aekf.push_imu(&Imu {
                        t_us: k * 10_000,
                        gyro_rad_s: Vector3::zeros(),
                        accel_m_s2: Vector3::new(lit(3.0), lit(0.0), lit(-G)),
                    })
                    .unwrap();
                }
                aekf
            }

            fn assert_symmetric_psd(p: &SMatrix<T, AUGMENTED_STATES, AUGMENTED_STATES>) {
                assert_eq!(*p, p.transpose(), "P lost its symmetry");
                let eig = min_relative_eigenvalue(p);
                assert!(eig > -1e3 * $round, "smallest relative eigenvalue {eig}");
            }

            #[test]
            fn a_delay_pushed_below_zero_is_clamped_and_p_stays_psd() {
                let mut aekf = accelerating(0.02);
                let e = aekf.estimate().unwrap();
                let p_before = *aekf.covariance();
                // A fix 0.3 s *ahead* of the vehicle: a negative delay.
                let v_ahead = e.velocity_ned_m_s + Vector3::new(lit(0.9), lit(0.0), lit(0.0));
                let r_ahead = e.position_ned_m
                    + e.velocity_ned_m_s * lit(0.3)
                    + Vector3::new(lit(0.135), lit(0.0), lit(0.0));
                let fix = gps_fix(100_000, GpsPosition::Ned(r_ahead), v_ahead);
                assert!(matches!(
                    aekf.push_gps(&fix).unwrap(),
                    GpsOutcome::Fused { .. }
                ));
                assert_eq!(aekf.delay_s(), lit(0.0));
                assert!(aekf.delay_clamps() >= 1);
                assert_symmetric_psd(aekf.covariance());
                // The clamp did not touch P: the fusion shrank tau's variance.
                assert!(aekf.covariance()[(DELAY, DELAY)] < p_before[(DELAY, DELAY)]);
                // And the upper end.
                let mut aekf = accelerating(0.98);
                let e = aekf.estimate().unwrap();
                // A fix 1.3 s behind: more than the 1 s admitted.
                let v_behind = e.velocity_ned_m_s - Vector3::new(lit(3.9), lit(0.0), lit(0.0));
                let r_behind = e.position_ned_m - e.velocity_ned_m_s * lit(1.3)
                    + Vector3::new(lit(2.535), lit(0.0), lit(0.0));
                let fix = gps_fix(100_000, GpsPosition::Ned(r_behind), v_behind);
                aekf.push_gps(&fix).unwrap();
                assert_eq!(aekf.delay_s(), aekf.config().max_delay_s);
                assert!(aekf.delay_clamps() >= 1);
                assert_symmetric_psd(aekf.covariance());
            }

            #[test]
            fn set_delay_replaces_value_and_variance_and_refuses_nonsense() {
                let mut fresh = AugmentedEkf17::<T>::new(aekf_config(0.1)).unwrap();
                fresh.set_delay(lit(0.25), lit(0.01)).unwrap();
                assert_eq!(fresh.delay_s(), lit(0.25));
                assert!((fresh.delay_std_s() - lit(0.01)).abs() < lit(10.0 * $round));
                let mut aekf = accelerating(0.1);
                let fix = gps_fix(
                    100_000,
                    GpsPosition::Ned(aekf.estimate().unwrap().position_ned_m),
                    aekf.estimate().unwrap().velocity_ned_m_s,
                );
                aekf.push_gps(&fix).unwrap();
                // The fusion correlated tau with the navigation states.
                assert!(aekf.covariance().row(DELAY).columns(0, NAV_STATES).amax() > lit(0.0));
                aekf.set_delay(lit(0.3), lit(0.02)).unwrap();
                let e = aekf.estimate().unwrap();
                assert_eq!(e.delay_s, Some(lit(0.3)));
                assert!((e.delay_std_s.unwrap() - lit(0.02)).abs() < lit(10.0 * $round));
                let p = *aekf.covariance();
                assert_eq!(p.row(DELAY).columns(0, NAV_STATES).amax(), lit(0.0));
                assert_symmetric_psd(&p);
                let x = *aekf.state_vector();
                for (delay, std) in [
                    (-0.1, 0.01),
                    (1.5, 0.01),
                    (f64::NAN, 0.01),
                    (0.2, 0.0),
                    (0.2, f64::INFINITY),
                ] {
                    assert!(matches!(
                        aekf.set_delay(lit(delay), lit(std)),
                        Err(Error::OutOfRange { .. })
                    ));
                }
                assert_eq!((*aekf.state_vector(), *aekf.covariance()), (x, p));
            }

            #[test]
            fn geodetic_and_ned_fixes_do_not_mix() {
                let mut aekf = accelerating(0.1);
                let t = aekf.time_us().unwrap();
                let e = aekf.estimate().unwrap();
                let ned = GpsPosition::Ned(e.position_ned_m);
                aekf.push_gps(&gps_fix(t, ned, e.velocity_ned_m_s)).unwrap();
                let (x, p) = (*aekf.state_vector(), *aekf.covariance());
                let geo = GpsPosition::Geodetic(Geodetic {
                    lat_deg: 31.0,
                    lon_deg: 121.0,
                    alt_m: 10.0,
                });
                assert!(matches!(
                    aekf.push_gps(&gps_fix(t + 1, geo, Vector3::zeros())),
                    Err(Error::OutOfRange {
                        field: "gps.position",
                        ..
                    })
                ));
                assert_eq!((*aekf.state_vector(), *aekf.covariance()), (x, p));
                assert_eq!(aekf.refusals().gps_mixed_frames, 1);
            }

            #[test]
            fn bad_samples_are_refused_without_changing_the_state() {
                let mut aekf = AugmentedEkf17::<T>::new(aekf_config(0.1)).unwrap();
                fly_delayed(&mut aekf, &weaving(5.0), 0.1, |_, _| {});
                let snapshot = |a: &AugmentedEkf17<T>| {
                    (
                        *a.state_vector(),
                        *a.covariance(),
                        a.time_us(),
                        a.refusals(),
                    )
                };
                let before = snapshot(&aekf);
                let t = aekf.time_us().unwrap();
                let nan = lit(f64::NAN);
                let g = Vector3::new(lit(0.0), lit(0.0), lit(-G));
                let imu = |t_us, gyro: Vector3<T>| Imu {
                    t_us,
                    gyro_rad_s: gyro,
                    accel_m_s2: g,
                };
                assert_eq!(
                    aekf.push_imu(&imu(t + 10_000, Vector3::new(nan, lit(0.0), lit(0.0)))),
                    Err(Error::NonFinite { field: "imu.gyro" })
                );
                assert!(matches!(
                    aekf.push_imu(&imu(t, Vector3::zeros())),
                    Err(Error::DuplicateTimestamp { stream: "imu", .. })
                ));
                assert!(matches!(
                    aekf.push_imu(&imu(t - 1, Vector3::zeros())),
                    Err(Error::TimeWentBackwards { stream: "imu", .. })
                ));
                let fix =
                    |t_us, p: Vector3<T>| gps_fix(t_us, GpsPosition::Ned(p), Vector3::zeros());
                assert_eq!(
                    aekf.push_gps(&fix(t + 1, Vector3::new(nan, lit(0.0), lit(0.0)))),
                    Err(Error::NonFinite {
                        field: "gps.position"
                    })
                );
                let last_gps = aekf.last_gps_fusion().unwrap().0.t_us;
                assert!(matches!(
                    aekf.push_gps(&fix(last_gps, Vector3::zeros())),
                    Err(Error::DuplicateTimestamp { stream: "gps", .. })
                ));
                assert_eq!(
                    aekf.push_mag(&Mag {
                        t_us: t + 1,
                        field_body: Vector3::new(nan, lit(1.0), lit(0.0))
                    }),
                    Err(Error::NonFinite { field: "mag.field" })
                );
                let after = snapshot(&aekf);
                assert_eq!((after.0, after.1, after.2), (before.0, before.1, before.2));
                let r = after.3;
                assert_eq!((r.imu_non_finite, r.imu_time), (1, 2));
                assert_eq!((r.gps_invalid, r.gps_time), (1, 1));
                assert_eq!(r.mag_invalid, 1);
                // An outlier is gated out and recorded, the state unchanged.
                let far = aekf.estimate().unwrap().position_ned_m
                    + Vector3::new(lit(500.0), lit(0.0), lit(0.0));
                let GpsOutcome::Fused { position, .. } = aekf.push_gps(&fix(t + 2, far)).unwrap()
                else {
                    panic!("expected a fusion attempt")
                };
                assert!(!position.fused && position.test_ratio > lit(1.0));
                assert_eq!(aekf.refusals().gps_position_rejected, 1);
                // Still working.
                aekf.push_imu(&imu(t + 10_000, Vector3::zeros())).unwrap();
                assert_eq!(aekf.time_us(), Some(t + 10_000));
            }

            #[test]
            fn config_validates_and_names_the_bad_delay_field() {
                AugmentedEkf17Config::<T>::default().validate().unwrap();
                let c = AugmentedEkf17Config::<T>::default();
                let field_of = |bad: AugmentedEkf17Config<T>| match bad.validate() {
                    Err(Error::InvalidConfig { field, .. }) => field,
                    other => panic!("expected InvalidConfig, got {other:?}"),
                };
                assert_eq!(
                    field_of(AugmentedEkf17Config {
                        max_delay_s: lit(0.0),
                        ..c
                    }),
                    "max_delay_s"
                );
                assert_eq!(
                    field_of(AugmentedEkf17Config {
                        initial_delay_s: lit(2.0),
                        ..c
                    }),
                    "initial_delay_s"
                );
                assert_eq!(
                    field_of(AugmentedEkf17Config {
                        initial_delay_std_s: lit(f64::NAN),
                        ..c
                    }),
                    "initial_delay_std_s"
                );
                assert_eq!(
                    field_of(AugmentedEkf17Config {
                        delay_random_walk: lit(-1.0),
                        ..c
                    }),
                    "delay_random_walk"
                );
                let mut nav = c.nav;
                nav.gps_velocity_std_m_s = lit(0.0);
                assert_eq!(
                    field_of(AugmentedEkf17Config { nav, ..c }),
                    "nav.gps_velocity_std_m_s"
                );
                assert!(AugmentedEkf17::new(AugmentedEkf17Config { nav, ..c }).is_err());
            }

            #[test]
            fn the_estimate_is_the_cores_with_the_delay() {
                let mut aekf = AugmentedEkf17::<T>::new(aekf_config(0.1)).unwrap();
                fly_delayed(&mut aekf, &weaving(4.0), 0.1, |_, _| {});
                let e = aekf.estimate().unwrap();
                let x = aekf.state_vector();
                assert_eq!(e.delay_s, Some(x[DELAY]));
                assert_eq!(
                    e.delay_std_s,
                    Some(aekf.covariance()[(DELAY, DELAY)].sqrt())
                );
                assert_eq!(e.position_ned_m, x.fixed_rows::<3>(POS).into_owned());
                let diag = aekf.covariance().diagonal();
                assert_eq!(e.covariance_diagonal, diag.fixed_rows::<NAV_STATES>(0));
                let level = rotation_matrix(e.attitude.quaternion());
                assert!((level.determinant() - lit(1.0)).abs() < lit(1e3 * $round));
            }
        }
    };
}

aekf17_tests!(
    f32_aekf,
    f32,
    jac_step = 1e-2,
    jac_tol = 2e-3,
    round = 1.2e-7
);
aekf17_tests!(
    f64_aekf,
    f64,
    jac_step = 1e-5,
    jac_tol = 1e-7,
    round = 2.3e-16
);

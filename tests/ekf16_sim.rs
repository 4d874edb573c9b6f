//! `Ekf16` on the simulator, GPS without delay: conventions (noise-free
//! flight), consistency of the magnetometer heading update at a high rate,
//! and the accuracy Table 3's noise allows, in f32 and f64.
#![cfg(feature = "sim")]

use delaynav::ekf16::MagMode;
use delaynav::ekf16::state::{GYRO_BIAS, QUAT};
use delaynav::geo::wrap_pi;
use delaynav::sim::{
    DelayProfile, STANDARD_GRAVITY, Scenario, SensorConfig, SimConfig, SimEvent, Simulation,
};
use delaynav::{Ekf16, Ekf16Config, Gps, GpsPosition, Imu, Mag, MagOutcome, Navigator, Scalar};
use nalgebra::{Matrix3, Quaternion, SMatrix, UnitQuaternion, Vector3};

/// A run with the GPS describing the present (no delay).
fn no_delay(scenario: Scenario, seed: u64, duration_s: f64) -> SimConfig {
    SimConfig {
        delay: DelayProfile::constant(0.0),
        duration_s,
        ..SimConfig::for_scenario(scenario, seed)
    }
}

/// Still at the origin, level, fixed heading (no path, no manoeuvre).
fn hover(mut config: SimConfig) -> SimConfig {
    config.trajectory.path.clear();
    config.trajectory.yaw_amplitude_rad = 0.0;
    config.trajectory.accel_limit_m_s2 = 1e-6;
    config
}

/// The filter told Table 3's noise (read per sample at the IMU rate) and
/// the simulator's field, whatever noise the run really has.
fn table3_filter<T: Scalar>(sim: &SimConfig) -> Ekf16Config<T> {
    let t3 = SensorConfig::default();
    let s = &sim.sensors;
    Ekf16Config {
        mag_inclination_rad: T::lit(s.inclination_rad),
        mag_declination_rad: T::lit(s.declination_rad),
        mag_noise_variance: T::lit(t3.mag_noise_var),
        ..Ekf16Config::with_per_sample_imu_variances(
            T::lit(t3.gyro_noise_var_rad2_s2),
            T::lit(t3.accel_noise_var_g2 * STANDARD_GRAVITY * STANDARD_GRAVITY),
            T::lit(s.imu_rate_hz),
        )
    }
}

fn v<T: Scalar>(x: &Vector3<f64>) -> Vector3<T> {
    x.map(T::lit)
}

/// A simulated IMU sample in `T`.
fn imu_sample<T: Scalar>(s: &Imu<f64>) -> Imu<T> {
    Imu {
        t_us: s.t_us,
        gyro_rad_s: v(&s.gyro_rad_s),
        accel_m_s2: v(&s.accel_m_s2),
    }
}

/// A simulated magnetometer sample in `T`.
fn mag_sample<T: Scalar>(m: &Mag<f64>) -> Mag<T> {
    Mag {
        t_us: m.t_us,
        field_body: v(&m.field_body),
    }
}

/// A simulated fix in `T`, with the configured noise (no receiver accuracies).
fn gps_fix<T: Scalar>(fix: &Gps<f64>) -> Gps<T> {
    let GpsPosition::Ned(p) = fix.position else {
        panic!("the simulator reports NED by default")
    };
    Gps {
        t_us: fix.t_us,
        position: GpsPosition::Ned(v(&p)),
        velocity_ned_m_s: v(&fix.velocity_ned_m_s),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    }
}

/// Errors of one run, from `score_from_s` on.
#[derive(Debug, Default)]
struct RunErrors {
    /// Largest attitude error (rotation angle), deg.
    max_attitude_deg: f64,
    /// Largest velocity error, m/s.
    max_velocity_m_s: f64,
    /// RMS of roll, pitch, yaw errors, deg.
    rms_euler_deg: [f64; 3],
    /// RMS of the gyro z bias error, rad/s.
    rms_gyro_z_bias: f64,
    /// Largest normalized attitude error squared (3 DOF).
    max_attitude_nees: f64,
    /// Mean NIS of the fused magnetometer samples.
    mean_mag_nis: f64,
    /// Magnetometer samples fused.
    mag_fused: usize,
}

/// Attitude error covariance (3x3, rad², NED rotation vector) of the
/// quaternion block: `d theta = 2 vec(dq ⊗ q*)`.
fn attitude_covariance_ned<T: Scalar>(nav: &Ekf16<T>) -> Matrix3<f64> {
    let x = nav.state_vector();
    let q = quaternion_f64(&[x[QUAT], x[QUAT + 1], x[QUAT + 2], x[QUAT + 3]]);
    let mut g = SMatrix::<f64, 3, 4>::zeros();
    for i in 0..4 {
        let mut e = [0.0; 4];
        e[i] = 1.0;
        let d = Quaternion::new(e[0], e[1], e[2], e[3]) * q.conjugate();
        g.set_column(i, &(d.imag() * 2.0));
    }
    let p = nav
        .covariance()
        .fixed_view::<4, 4>(QUAT, QUAT)
        .map(|c| c.as_f64());
    g * p * g.transpose()
}

fn quaternion_f64<T: Scalar>(wxyz: &[T; 4]) -> Quaternion<f64> {
    let [w, i, j, k] = wxyz.map(|c| c.as_f64());
    Quaternion::new(w, i, j, k)
}

fn fly<T: Scalar>(sim: &SimConfig, filter: Ekf16Config<T>, score_from_s: f64) -> RunErrors {
    let mut nav = Ekf16::new(filter).expect("valid filter config");
    let mut out = RunErrors::default();
    let (mut sum_sq, mut n) = ([0.0; 3], 0usize);
    let mut nis_sum = 0.0;
    let gate = filter.mag_gate.as_f64();
    let field_gate = filter.mag_three_axis_gate.as_f64();
    for event in Simulation::new(sim.clone()).expect("valid sim config") {
        match event {
            SimEvent::Imu { sample, truth } => {
                let imu = imu_sample::<T>(&sample);
                nav.push_imu(&imu).expect("plausible IMU sample");
                if (truth.t_us as f64) < score_from_s * 1e6 {
                    continue;
                }
                let est = nav.estimate().expect("initialized by now");
                let a = est.attitude;
                let q = UnitQuaternion::new_normalize(quaternion_f64(&[a.w, a.i, a.j, a.k]));
                let err_ned = (q * truth.attitude.inverse()).scaled_axis();
                out.max_attitude_deg = out.max_attitude_deg.max(err_ned.norm().to_degrees());
                let info = attitude_covariance_ned(&nav)
                    .try_inverse()
                    .expect("attitude covariance invertible");
                let nees = err_ned.dot(&(info * err_ned));
                out.max_attitude_nees = out.max_attitude_nees.max(nees);
                let dv = est.velocity_ned_m_s.map(|c| c.as_f64()) - truth.velocity_m_s;
                out.max_velocity_m_s = out.max_velocity_m_s.max(dv.norm());
                let e = est.euler_rad().map(|c| c.as_f64());
                for (i, s) in sum_sq.iter_mut().enumerate() {
                    *s += wrap_pi(e[i] - truth.euler_rad[i]).to_degrees().powi(2);
                }
                n += 1;
                let bias_err = nav.state_vector()[GYRO_BIAS + 2].as_f64() - truth.gyro_bias_rad_s.z;
                out.rms_gyro_z_bias += bias_err * bias_err;
            }
            SimEvent::Mag(m) => {
                let mag = mag_sample::<T>(&m);
                if let Ok(MagOutcome::Fused(rec)) = nav.push_mag(&mag)
                    && rec.fused
                {
                    let gate = match nav.mag_modes().mode {
                        MagMode::ThreeAxis => field_gate,
                        _ => gate,
                    };
                    nis_sum += rec.test_ratio.as_f64() * gate;
                    out.mag_fused += 1;
                }
            }
            SimEvent::Gps { fix, .. } => {
                let gps = gps_fix::<T>(&fix);
                let _ = nav.push_gps(&gps);
            }
        }
    }
    out.rms_euler_deg = sum_sq.map(|s| (s / n.max(1) as f64).sqrt());
    out.rms_gyro_z_bias = (out.rms_gyro_z_bias / n.max(1) as f64).sqrt();
    out.mean_mag_nis = nis_sum / out.mag_fused.max(1) as f64;
    out
}

macro_rules! ekf16_sim_tests {
    ($mod:ident, $t:ty, attitude_deg = $att:expr, velocity_m_s = $vel:expr) => {
        mod $mod {
            use super::*;
            type T = $t;

            /// Perfect sensors, filter told Table 3: every convention (attitude
            /// direction, specific-force sign, rate frame, field direction and
            /// declination, heading, GPS timing) must agree with the
            /// simulator, or the errors would not vanish.
            #[test]
            fn noise_free_flight_errors_vanish() {
                let sim = SimConfig {
                    sensors: SensorConfig::noise_free(),
                    ..no_delay(Scenario::High, 3, 20.0)
                };
                let errors = fly::<T>(&sim, table3_filter(&sim), 5.0);
                assert!(errors.max_attitude_deg < $att, "{errors:?}");
                assert!(errors.max_velocity_m_s < $vel, "{errors:?}");
            }

            /// Hover, no biases, magnetometer at the IMU rate (1 kHz). The
            /// heading is de-rotated with the estimated roll and pitch; a
            /// model blind to that (yaw-only Jacobian) fed the tilt error
            /// back as heading information and diverged within ~7 s.
            #[test]
            fn mag_at_imu_rate_at_hover_stays_consistent() {
                for corrects_tilt in [true, false] {
                    let mut sim = hover(no_delay(Scenario::Low, 0, 12.0));
                    sim.sensors.gyro_bias_max_rad_s = 0.0;
                    sim.sensors.accel_bias_max_g = 0.0;
                    sim.sensors.mag_rate_hz = sim.sensors.imu_rate_hz;
                    let filter = Ekf16Config {
                        mag_corrects_tilt: corrects_tilt,
                        mag_three_axis: false,
                        ..table3_filter::<T>(&sim)
                    };
                    let errors = fly::<T>(&sim, filter, 1.0);
                    assert!(errors.mag_fused > 10_000, "{errors:?}");
                    assert!(errors.max_attitude_deg < 5.0, "{corrects_tilt}: {errors:?}");
                    // 3-DOF NEES: 99.99 % quantile 21.1.
                    assert!(
                        errors.max_attitude_nees < 25.0,
                        "{corrects_tilt}: {errors:?}"
                    );
                    // The innovation lies along one direction: its NIS has
                    // one degree of freedom, mean 1.
                    assert!(
                        (errors.mean_mag_nis - 1.0).abs() < 0.15,
                        "{corrects_tilt}: {errors:?}"
                    );
                }
            }

            /// The same hover with the 3-axis update (after its first
            /// clean second): consistent, and the NIS of the field direction
            /// has two degrees of freedom (mean 2; the first second's
            /// heading-only samples have mean 1).
            #[test]
            fn three_axis_mag_at_imu_rate_at_hover_stays_consistent() {
                let mut sim = hover(no_delay(Scenario::Low, 0, 12.0));
                sim.sensors.gyro_bias_max_rad_s = 0.0;
                sim.sensors.accel_bias_max_g = 0.0;
                sim.sensors.mag_rate_hz = sim.sensors.imu_rate_hz;
                let filter = table3_filter::<T>(&sim);
                assert!(filter.mag_three_axis, "3-axis is the default");
                let errors = fly::<T>(&sim, filter, 1.0);
                let heading_only = fly::<T>(
                    &sim,
                    Ekf16Config {
                        mag_three_axis: false,
                        ..filter
                    },
                    1.0,
                );
                assert!(errors.mag_fused > 10_000, "{errors:?}");
                assert!(errors.max_attitude_deg < 6.0, "{errors:?}");
                assert!(errors.max_attitude_nees < 25.0, "{errors:?}");
                let expected = (1.0 + 2.0 * 11.0) / 12.0;
                assert!((errors.mean_mag_nis - expected).abs() < 0.2, "{errors:?}");
                // Roll, pitch and yaw all better than heading-only's (1.03,
                // 0.46, 1.13 deg RMS measured; 3-axis 0.67, 0.32, 0.66).
                for i in 0..3 {
                    assert!(
                        errors.rms_euler_deg[i] < 0.8 * heading_only.rms_euler_deg[i],
                        "{errors:?} vs {heading_only:?}"
                    );
                }
            }
        }
    };
}

ekf16_sim_tests!(f64_sim, f64, attitude_deg = 0.01, velocity_m_s = 1e-3);
ekf16_sim_tests!(f32_sim, f32, attitude_deg = 0.2, velocity_m_s = 0.02);

/// Table 3 noise and biases, no delay: the gyro z bias is estimated (the
/// heading update makes it observable) and yaw follows the magnetometer.
#[test]
fn table3_flight_without_delay_estimates_the_gyro_z_bias() {
    let sim = no_delay(Scenario::Low, 0, 40.0);
    let errors = fly::<f64>(&sim, table3_filter(&sim), 10.0);
    // Bias drawn up to 0.01 rad/s. With the yaw-only Jacobian this run had
    // gyro z bias RMS 2.9e-3 rad/s, roll 5.7 deg, yaw 4.2 deg, NEES up to
    // 292; with the tilt-coupled one 0.94e-3, 0.32 deg, 1.0 deg, 4.7.
    assert!(errors.rms_gyro_z_bias < 1.5e-3, "{errors:?}");
    assert!(errors.rms_euler_deg[2] < 1.5, "{errors:?}");
    assert!(errors.rms_euler_deg[0] < 1.0, "{errors:?}");
    assert!(errors.max_attitude_nees < 25.0, "{errors:?}");
}

/// Smallest eigenvalue of a symmetric matrix relative to its largest magnitude.
fn min_relative_eigenvalue<T: Scalar, const N: usize>(p: &SMatrix<T, N, N>) -> f64 {
    let p64 = nalgebra::DMatrix::from_iterator(N, N, p.iter().map(|c| c.as_f64()));
    let eig = p64.symmetric_eigen().eigenvalues;
    eig.min() / eig.amax()
}

/// 100 000 IMU steps in f32 (100 s of the `high` flight at 1 kHz, Table 3
/// noise, GPS at 10 Hz with the default delay, magnetometer) through the
/// structured prediction and the sparse Joseph update, for `Ekf16` and
/// `AugmentedEkf17`: `P` exactly symmetric after every sample, PSD up to
/// f32 rounding (smallest eigenvalue relative to the largest above
/// `-1e3 eps`; the quaternion's radial direction carries ~0 variance), and
/// no fusion refused for a non-positive-definite innovation covariance.
#[test]
fn f32_covariances_stay_symmetric_psd_over_100k_simulated_steps() {
    let sim = SimConfig {
        duration_s: 100.0,
        ..SimConfig::for_scenario(Scenario::High, 11)
    };
    let filter = table3_filter::<f32>(&sim);
    let mut ekf = Ekf16::new(filter).unwrap();
    let mut aekf = delaynav::AugmentedEkf17::new(delaynav::AugmentedEkf17Config {
        nav: filter,
        ..delaynav::AugmentedEkf17Config::default()
    })
    .unwrap();
    let (mut steps, mut worst_16, mut worst_17) = (0u32, 0.0f64, 0.0f64);
    for event in Simulation::new(sim).unwrap() {
        match event {
            SimEvent::Imu { sample, .. } => {
                let imu = imu_sample::<f32>(&sample);
                ekf.push_imu(&imu).unwrap();
                aekf.push_imu(&imu).unwrap();
                steps += 1;
                let (p16, p17) = (ekf.covariance(), aekf.covariance());
                assert_eq!(p16, &p16.transpose(), "Ekf16 P not symmetric at {steps}");
                assert_eq!(p17, &p17.transpose(), "AEKF17 P not symmetric at {steps}");
                if steps % 1000 == 0 && ekf.is_initialized() {
                    worst_16 = worst_16.min(min_relative_eigenvalue(p16));
                    worst_17 = worst_17.min(min_relative_eigenvalue(p17));
                }
            }
            SimEvent::Mag(m) => {
                let mag = mag_sample::<f32>(&m);
                let _ = ekf.push_mag(&mag);
                let _ = aekf.push_mag(&mag);
            }
            SimEvent::Gps { fix, .. } => {
                let gps = gps_fix::<f32>(&fix);
                let _ = ekf.push_gps(&gps);
                let _ = aekf.push_gps(&gps);
            }
        }
    }
    assert!(steps >= 100_000, "{steps} steps");
    eprintln!("smallest relative eigenvalue: Ekf16 {worst_16:.2e}, AEKF17 {worst_17:.2e}");
    let bound = -1e3 * f64::from(f32::EPSILON);
    assert!(
        worst_16 > bound,
        "Ekf16 smallest relative eigenvalue {worst_16:e}"
    );
    assert!(
        worst_17 > bound,
        "AEKF17 smallest relative eigenvalue {worst_17:e}"
    );
    assert_eq!(ekf.refusals().not_positive_definite, 0);
    assert_eq!(aekf.refusals().not_positive_definite, 0);
}

/// The navigator on the fault suite's `high` run (20 s) with `faults`, its
/// EKF configured from the run's sensors: its health at the end.
fn navigator_health(faults: &[delaynav::sim::Fault]) -> delaynav::nav::Health<f64> {
    use delaynav::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
    use delaynav::sim::FaultySimulation;
    use delaynav::sim::faults::base_config;
    let sim = SimConfig {
        duration_s: 20.0,
        ..base_config(1, 1.0)
    };
    let s = &sim.sensors;
    let mut nav = DelayCompensatedNav::<f64>::new(DelayCompensatedNavConfig {
        ekf: Ekf16Config {
            mag_inclination_rad: s.inclination_rad,
            mag_declination_rad: s.declination_rad,
            ..Ekf16Config::with_per_sample_imu_variances(
                s.gyro_noise_var_rad2_s2,
                s.accel_noise_var_g2 * STANDARD_GRAVITY.powi(2),
                s.imu_rate_hz,
            )
        },
        mode: DelayMode::Estimated { initial_s: 0.2 },
        imu_rate_hz: s.imu_rate_hz,
        ..DelayCompensatedNavConfig::default()
    })
    .unwrap();
    for event in FaultySimulation::new(sim.clone(), faults).unwrap() {
        match &event {
            SimEvent::Imu { sample, .. } => {
                let _ = nav.push_imu(sample);
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(m);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(fix);
            }
        }
    }
    nav.health()
}

#[test]
fn a_position_step_resets_position_alone_and_health_says_why() {
    use delaynav::ekf16::{GpsBlock, GpsResetCause};
    use delaynav::nav::ResetCause;
    let clean = navigator_health(&[]);
    assert_eq!(clean.refusals.horizon.gps_position_resets, 0);
    assert_eq!(clean.refusals.horizon.gps_velocity_resets, 0);
    assert_eq!(clean.last_reset, None);
    let h = navigator_health(&[delaynav::sim::Fault::GpsPositionStep {
        from_s: 8.0,
        offset_m: [50.0, 0.0, 0.0],
    }]);
    let r = h.refusals.horizon;
    assert_eq!((r.gps_position_resets, r.gps_velocity_resets), (1, 0));
    let Some(reset) = h.last_reset else {
        panic!("no reset reported")
    };
    let ResetCause::Gps(gps) = reset.cause else {
        panic!("{reset:?}")
    };
    assert_eq!(
        (gps.block, gps.cause),
        (GpsBlock::Position, GpsResetCause::Rejected)
    );
    // 5 s of rejected position blocks after the step (10 Hz GPS).
    assert!(r.gps_position_rejected >= 45, "{r:?}");
    // The estimate follows the moved fixes, but their velocities say the vehicle did not move:
    // the position-against-velocity check puts the 50 m in the horizontal level, so position
    // is not valid (it is on the clean run); velocity's flag is as on the clean run.
    // Every fix after the reset is beyond the check's tolerance (the clean run has a few
    // beyond it too: the tolerance is a 1e-3 level of a white-noise model).
    assert!(clean.position_valid, "{clean:?}");
    assert!(!h.position_valid, "{h:?}");
    assert!(h.protection_levels.horizontal_m > 45.0, "{h:?}");
    let spurious = clean.refusals.horizon.gps_position_inconsistent;
    assert!(
        r.gps_position_inconsistent > spurious + 50,
        "{r:?} {spurious}"
    );
    assert_eq!(h.velocity_valid, clean.velocity_valid);
}

#[test]
fn a_magnetic_disturbance_is_refused_and_counted() {
    let clean = navigator_health(&[]);
    let h = navigator_health(&[delaynav::sim::Fault::MagRotation {
        from_s: 8.0,
        to_s: 13.0,
        angle_rad: 60f64.to_radians(),
    }]);
    // 5 s of a 100 Hz magnetometer: nearly all of the 500 turned samples
    // are refused by the heading gate (the clean run refuses ~0.3 %).
    let refused = h.refusals.horizon.mag_rejected - clean.refusals.horizon.mag_rejected;
    assert!(refused >= 450, "{refused} refused");
    assert!(h.heading_valid);
}

/// The mode of each of the first `n` magnetometer samples fused after
/// initialization, with the tilt standard deviation before it, on a hover,
/// the filter started with the tilt standard deviation `tilt_std_rad`.
fn first_modes<T: Scalar>(n: usize, tilt_std_rad: f64) -> (Vec<(MagMode, f64)>, f64) {
    let sim = hover(no_delay(Scenario::Low, 5, 3.0));
    let filter = Ekf16Config {
        initial_tilt_std_rad: T::lit(tilt_std_rad),
        ..table3_filter::<T>(&sim)
    };
    let mut nav = Ekf16::new(filter).expect("valid filter config");
    let mut modes = Vec::new();
    for event in Simulation::new(sim).expect("valid sim config") {
        match event {
            SimEvent::Imu { sample, .. } => {
                nav.push_imu(&imu_sample::<T>(&sample))
                    .expect("plausible IMU sample");
            }
            SimEvent::Mag(m) if nav.is_initialized() && modes.len() < n => {
                let tilt_std = nav.tilt_std().as_f64();
                if let Ok(MagOutcome::Fused(_)) = nav.push_mag(&mag_sample::<T>(&m)) {
                    modes.push((nav.mag_modes().mode, tilt_std));
                }
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(&mag_sample::<T>(&m));
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(&gps_fix::<T>(&fix));
            }
        }
    }
    (modes, delaynav::ekf16::MAG_INFLIGHT_TILT_STD_RAD)
}

/// While the tilt is uncertain as after a start in motion (its standard
/// deviation above `MAG_INFLIGHT_TILT_STD_RAD`) a consistent sample is fused
/// 3-axis at once, without the 1 s clean hold: the field levels an aligning
/// filter (docs/math.md, "In-flight alignment"). A start at rest (0.1 rad)
/// keeps the hold: heading-only first.
fn an_aligning_filter_fuses_the_three_axis_field<T: Scalar>() {
    let (modes, inflight_std) = first_modes::<T>(3, 0.35);
    assert_eq!(modes.len(), 3, "{modes:?}");
    let (mode, tilt_std) = modes[0];
    assert!(tilt_std > inflight_std, "{tilt_std} rad: not aligning");
    assert_eq!(mode, MagMode::ThreeAxis, "{modes:?}");
    let (modes, _) = first_modes::<T>(1, 0.1);
    assert_eq!(modes[0].0, MagMode::HeadingOnly, "{modes:?}");
}

#[test]
fn an_aligning_filter_fuses_the_three_axis_field_f32() {
    an_aligning_filter_fuses_the_three_axis_field::<f32>();
}

#[test]
fn an_aligning_filter_fuses_the_three_axis_field_f64() {
    an_aligning_filter_fuses_the_three_axis_field::<f64>();
}

/// `Ekf16` over 40 s of the `high` flight (GPS without delay), with or without the fault
/// suite's hard-iron offset (not in the configuration): `(heading level at the end, deg,
/// heading valid at the end, heading valid with an error above the level anywhere after 15 s,
/// samples the field-offset monitor counted)`.
fn hard_iron_run(offset: bool) -> (f64, bool, bool, u32) {
    let mut sim = no_delay(Scenario::High, 4, 40.0);
    if offset {
        sim.sensors.mag_hard_iron = delaynav::sim::faults::hard_iron_offset();
    }
    let mut ekf = Ekf16::new(table3_filter::<f64>(&sim)).unwrap();
    let mut misleading = false;
    for event in Simulation::new(sim).unwrap() {
        match event {
            SimEvent::Imu { sample, truth } => {
                let _ = ekf.push_imu(&sample);
                let Some(est) = ekf.estimate() else { continue };
                let integrity = ekf.integrity();
                let (_, heading) =
                    delaynav::sim::tilt_heading_error_rad(&est.attitude, &truth.attitude);
                if truth.t_us >= 15_000_000
                    && integrity.heading_valid
                    && heading.to_degrees() > integrity.levels.heading_deg
                {
                    misleading = true;
                }
            }
            SimEvent::Mag(m) => {
                let _ = ekf.push_mag(&m);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = ekf.push_gps(&fix);
            }
        }
    }
    let integrity = ekf.integrity();
    (
        integrity.levels.heading_deg,
        integrity.heading_valid,
        misleading,
        ekf.refusals().mag_field_offset,
    )
}

/// A hard-iron offset not in the configuration leaves the heading about 10 deg off: the
/// magnetometer monitor sees the field's norm vary as the vehicle turns, counts it, and
/// raises the heading level above the alert limit, so the heading is not valid (and never
/// misleading once seen); the same flight without the offset keeps a valid heading.
#[test]
fn a_hard_iron_offset_raises_the_heading_level() {
    let (level, valid, misleading, counted) = hard_iron_run(true);
    assert!(counted > 0, "{counted}");
    assert!(
        level > 10.0 && !valid,
        "heading level {level} deg, valid {valid}"
    );
    assert!(!misleading);
    let (level, valid, misleading, counted) = hard_iron_run(false);
    assert!(
        valid && level < 5.0 && !misleading,
        "clean: {level} deg, valid {valid}"
    );
    assert_eq!(counted, 0, "clean: {counted} samples counted");
}

/// An alignment on one magnetometer sample 30 % below the field's norm (a start can have one
/// sample when the first fix follows the first sample; the Table 3 magnetometer's noise is
/// 0.14 of the field per axis): the filter's reference norm and the monitor's learned one are
/// running means from it, so the samples above it are fused within a few samples and no
/// offset is seen on a clean field. A reference kept at the one sample refused the samples
/// above its norm gate and biased the monitor's norm low: here 16 samples counted as an
/// offset; in the navigator's `high` scenario, seed 4 (one sample 15 % low), every sample for
/// 24 s, the 3-axis update stopped all along.
fn one_low_sample_alignment<T: Scalar>() {
    let sim = no_delay(Scenario::High, 4, 40.0);
    let events: Vec<SimEvent> = Simulation::new(sim.clone()).unwrap().collect();
    let first_fix = events
        .iter()
        .find_map(|e| match e {
            SimEvent::Gps { fix, .. } => Some(fix.t_us),
            _ => None,
        })
        .unwrap();
    let mut ekf = Ekf16::new(table3_filter::<T>(&sim)).unwrap();
    let last_before = events
        .iter()
        .rposition(|e| matches!(e, SimEvent::Mag(m) if m.t_us < first_fix))
        .unwrap();
    for (i, event) in events.into_iter().enumerate() {
        match event {
            SimEvent::Imu { sample, .. } => {
                let _ = ekf.push_imu(&imu_sample::<T>(&sample));
            }
            SimEvent::Mag(mut m) => {
                if m.t_us < first_fix && i != last_before {
                    continue;
                }
                if i == last_before {
                    m.field_body *= 0.7;
                }
                let _ = ekf.push_mag(&mag_sample::<T>(&m));
            }
            SimEvent::Gps { fix, .. } => {
                let _ = ekf.push_gps(&gps_fix::<T>(&fix));
            }
        }
    }
    let r = ekf.refusals();
    assert_eq!(r.mag_field_offset, 0, "{r:?}");
    assert_eq!(ekf.mag_modes().mode, MagMode::ThreeAxis);
}

#[test]
fn one_low_sample_alignment_f32() {
    one_low_sample_alignment::<f32>();
}

#[test]
fn one_low_sample_alignment_f64() {
    one_low_sample_alignment::<f64>();
}

/// A magnetometer first heard after the alignment (late, or the filter rebuilt in motion),
/// whose first sample is 45 % below the field's norm and seen 25 deg off its inclination (a
/// 3-sigma norm and a tilt being levelled, as in the fault suite's in-flight start, seed 4):
/// `(samples refused as disturbed, s fused 3-axis)` over 40 s of the `high` flight. The learned
/// field is the running mean of its first samples (norm and inclination alike), and gates no
/// sample before it is the mean of `MAG_FIELD_MIN_SAMPLES`.
fn late_field_from_one_bad_sample<T: Scalar>(bad: bool) -> (u32, f64) {
    let sim = no_delay(Scenario::High, 4, 40.0);
    let events: Vec<SimEvent> = Simulation::new(sim.clone()).unwrap().collect();
    let mut ekf = Ekf16::new(table3_filter::<T>(&sim)).unwrap();
    let mut first = bad;
    for event in events {
        match event {
            SimEvent::Imu { sample, .. } => {
                let _ = ekf.push_imu(&imu_sample::<T>(&sample));
            }
            SimEvent::Mag(_) if !ekf.is_initialized() => {}
            SimEvent::Mag(mut m) => {
                if first {
                    let pitch =
                        nalgebra::Rotation3::from_euler_angles(0.0, 40f64.to_radians(), 0.0);
                    m.field_body = pitch * m.field_body * 0.6;
                    first = false;
                }
                let _ = ekf.push_mag(&mag_sample::<T>(&m));
            }
            SimEvent::Gps { fix, .. } => {
                let _ = ekf.push_gps(&gps_fix::<T>(&fix));
            }
        }
    }
    let three_axis_us = ekf.mag_modes().time_us[MagMode::ThreeAxis.index()];
    (ekf.refusals().mag_disturbed, three_axis_us as f64 * 1e-6)
}

/// Measured (f64): 5 samples refused as disturbed over the run (4 without the bad sample),
/// and 38.8 s of 3-axis fusion. Checking samples against the field from its first
/// sample on refused 9 more (with an in-flight alignment's tilt being levelled, the
/// magnetometer monitor then saw an offset and refused every sample for 2 s: the fault suite's
/// `inflight_tilt_5s`, seed 4, 5.3 deg); an inclination learned at the slow rate alone refused
/// 966 samples.
fn a_field_first_heard_after_the_alignment_is_learned_from_its_first_samples<T: Scalar>() {
    let (clean, _) = late_field_from_one_bad_sample::<T>(false);
    let (disturbed, three_axis_s) = late_field_from_one_bad_sample::<T>(true);
    assert!(
        disturbed <= clean + 2,
        "{disturbed} samples refused as disturbed ({clean} without the bad one)"
    );
    assert!(three_axis_s > 35.0, "{three_axis_s} s of 3-axis fusion");
}

#[test]
fn a_field_first_heard_after_the_alignment_is_learned_from_its_first_samples_f32() {
    a_field_first_heard_after_the_alignment_is_learned_from_its_first_samples::<f32>();
}

#[test]
fn a_field_first_heard_after_the_alignment_is_learned_from_its_first_samples_f64() {
    a_field_first_heard_after_the_alignment_is_learned_from_its_first_samples::<f64>();
}

/// `Ekf16` over 150 s of the `high` flight (GPS without delay) whose field is 1.3 times its norm
/// from 10 to 12 s (a steel structure passed): `(s fused 3-axis from 20 to 60 s, from 60 s on,
/// the mode at the end, the held offsets cleared)`.
fn after_a_passing_rise_of_the_norm<T: Scalar>() -> (f64, f64, MagMode, u32) {
    let sim = no_delay(Scenario::High, 1, 150.0);
    let mut ekf = Ekf16::new(table3_filter::<T>(&sim)).unwrap();
    let mut three_axis_at = [0u64; 2];
    for event in Simulation::new(sim).unwrap() {
        match event {
            SimEvent::Imu { sample, .. } => {
                let _ = ekf.push_imu(&imu_sample::<T>(&sample));
                let three_axis = ekf.mag_modes().time_us[MagMode::ThreeAxis.index()];
                match sample.t_us {
                    20_000_000 => three_axis_at[0] = three_axis,
                    60_000_000 => three_axis_at[1] = three_axis,
                    _ => {}
                }
            }
            SimEvent::Mag(mut m) => {
                if (10_000_000..12_000_000).contains(&m.t_us) {
                    m.field_body *= 1.3;
                }
                let _ = ekf.push_mag(&mag_sample::<T>(&m));
            }
            SimEvent::Gps { fix, .. } => {
                let _ = ekf.push_gps(&gps_fix::<T>(&fix));
            }
        }
    }
    let modes = ekf.mag_modes();
    let end = modes.time_us[MagMode::ThreeAxis.index()];
    let s = |us: u64| us as f64 * 1e-6;
    (
        s(three_axis_at[1] - three_axis_at[0]),
        s(end - three_axis_at[1]),
        modes.mode,
        ekf.refusals().mag_field_offset_cleared,
    )
}

/// The magnetometer monitor takes a passing rise of the norm for a body-fixed offset while it
/// lasts (docs/faults.md, `mag_norm_disturbance`), then clears it: the norm came back by more
/// than any body-fixed offset allows for the turn since (`mag_monitor.rs`). Measured (f64):
/// cleared once; 40.0 s of 3-axis fusion from 20 to 60 s (all of it) and 90.0 s in the
/// last 90 s. Without the clearing, 0 s from 20 to 60 s (the offset held until it had decayed
/// below the monitor's tolerance) and 38.7 s after.
fn a_passing_rise_of_the_norm_is_forgotten<T: Scalar>() {
    let (early, late, mode, cleared) = after_a_passing_rise_of_the_norm::<T>();
    eprintln!("cleared {cleared}; 3-axis {early:.1} s from 20 to 60 s, {late:.1} s after");
    assert_eq!(cleared, 1);
    assert!(early > 20.0, "{early} s of 3-axis fusion from 20 to 60 s");
    assert!(late > 60.0, "{late} s of 3-axis fusion after 60 s");
    assert_eq!(mode, MagMode::ThreeAxis);
}

#[test]
fn a_passing_rise_of_the_norm_is_forgotten_f32() {
    a_passing_rise_of_the_norm_is_forgotten::<f32>();
}

#[test]
fn a_passing_rise_of_the_norm_is_forgotten_f64() {
    a_passing_rise_of_the_norm_is_forgotten::<f64>();
}

//! Delta angle and delta velocity accumulation (`ekf16::delta`) against a
//! simulated truth (coning and sculling motions, integrated finely here),
//! and the 16-state EKF predicting over accumulated steps against the same
//! EKF predicting at every sample, in f32 and f64.

use delaynav::ekf16::state::NAV_STATES;
use delaynav::internals::delta::{DeltaAccumulator, ImuDeltas};
use delaynav::{Ekf16, Ekf16Config, Imu, NavState, Navigator, Scalar};
use nalgebra::{SVector, UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// IMU period, µs (1 kHz).
const IMU_US: u64 = 1_000;
/// Filter step, µs (100 Hz).
const STEP_US: u64 = 10_000;

/// Body rate (rad/s, body) of the attitude `q(t)` by central differences
/// of `q(t)^-1 q(t + e)` (exact to `e²`).
fn rate_of(q: impl Fn(f64) -> UnitQuaternion<f64>, t: f64) -> Vector3<f64> {
    let e = 1e-6;
    (q(t - e).inverse() * q(t + e)).scaled_axis() / (2.0 * e)
}

/// The classic coning motion: the body axis x sweeps a cone of half-angle
/// `theta` at `omega` rad/s.
fn coning(theta: f64, omega: f64) -> impl Fn(f64) -> UnitQuaternion<f64> {
    move |t| {
        let axis = Vector3::new(0.0, (omega * t).cos(), (omega * t).sin());
        UnitQuaternion::from_scaled_axis(axis * theta)
    }
}

fn sample<T: Scalar>(t_us: u64, gyro: Vector3<f64>, accel: Vector3<f64>) -> Imu<T> {
    Imu {
        t_us,
        gyro_rad_s: gyro.map(T::lit),
        accel_m_s2: accel.map(T::lit),
    }
}

fn to_f64<T: Scalar>(v: &Vector3<T>) -> Vector3<f64> {
    v.map(|x| x.as_f64())
}

/// Accumulates the samples `times` of `(gyro, accel)` into steps of
/// `STEP_US` and returns each step.
fn steps<T: Scalar>(
    mut acc: DeltaAccumulator<T>,
    times: &[u64],
    imu: impl Fn(u64) -> (Vector3<f64>, Vector3<f64>),
) -> Vec<ImuDeltas<T>> {
    let mut out = Vec::new();
    for &t in times {
        let (w, f) = imu(t);
        acc.push(&sample(t, w, f));
        if acc.elapsed_us() >= STEP_US
            && let Some(d) = acc.take()
        {
            out.push(d);
        }
    }
    out
}

/// Attitude error (rad) after composing every step's delta angle, and the
/// largest per-step delta-angle error, against the truth `q`.
fn attitude_errors<T: Scalar>(
    steps: &[ImuDeltas<T>],
    q: &impl Fn(f64) -> UnitQuaternion<f64>,
) -> (f64, f64) {
    let s = |t: u64| t as f64 * 1e-6;
    let mut att = q(s(steps[0].t_start_us));
    let mut worst: f64 = 0.0;
    for d in steps {
        let angle = to_f64(&d.delta_angle_rad);
        let truth = (q(s(d.t_start_us)).inverse() * q(s(d.t_us()))).scaled_axis();
        worst = worst.max((angle - truth).norm());
        att *= UnitQuaternion::from_scaled_axis(angle);
    }
    let last = steps.last().map_or(0, |d| d.t_us());
    (att.angle_to(&q(s(last))), worst)
}

macro_rules! delta_tests {
    ($mod:ident, $t:ty, tol = $tol:expr) => {
        mod $mod {
            use super::*;
            type T = $t;

            /// A coning motion of 0.1 rad at 10 Hz for 2 s: the corrected
            /// steps keep the attitude 10x closer to the truth.
            #[test]
            fn coning_correction_matches_the_truth() {
                let q = coning(0.1, 2.0 * PI * 10.0);
                let times: Vec<u64> = (0..=2_000).map(|k| k * IMU_US).collect();
                let imu = |t: u64| (rate_of(&q, t as f64 * 1e-6), Vector3::zeros());
                let corrected = steps::<T>(DeltaAccumulator::new(), &times, imu);
                let plain = steps::<T>(DeltaAccumulator::uncorrected(), &times, imu);
                assert_eq!(corrected.len(), 200);
                let (drift_c, step_c) = attitude_errors(&corrected, &q);
                let (drift_u, step_u) = attitude_errors(&plain, &q);
                assert!(drift_u > 1e-3, "the motion must show coning: {drift_u}");
                assert!(
                    drift_c < drift_u / 50.0,
                    "attitude drift: corrected {drift_c}, uncorrected {drift_u}"
                );
                assert!(step_c < step_u / 5.0, "per step: {step_c} vs {step_u}");
            }

            /// A sculling motion: rolling `A sin(Ωt)` while the specific
            /// force along y is `B sin(Ωt)`, in phase: the rectified velocity
            /// along z must be in the corrected steps, not in the plain sums.
            #[test]
            fn sculling_correction_matches_the_truth() {
                let (a, b, om) = (0.05, 5.0, 2.0 * PI * 10.0);
                let roll = move |t: f64| a * (om * t).sin();
                let force = move |t: f64| Vector3::new(0.0, b * (om * t).sin(), -9.8);
                let imu = move |t_us: u64| {
                    let t = t_us as f64 * 1e-6;
                    (Vector3::new(a * om * (om * t).cos(), 0.0, 0.0), force(t))
                };
                // ∫ C(t0 -> t) f dt in body(t0), Simpson's rule on 2000 intervals.
                let truth = |t0: f64, t1: f64| {
                    let n = 2000;
                    let h = (t1 - t0) / n as f64;
                    let g = |t: f64| {
                        let c =
                            UnitQuaternion::from_scaled_axis(Vector3::x() * (roll(t) - roll(t0)));
                        c * force(t)
                    };
                    let mut sum = g(t0) + g(t1);
                    for i in 1..n {
                        sum += g(t0 + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
                    }
                    sum * (h / 3.0)
                };
                let times: Vec<u64> = (0..=1_000).map(|k| k * IMU_US).collect();
                let error_sum = |acc: DeltaAccumulator<T>| {
                    let mut sum = Vector3::<f64>::zeros();
                    for d in steps::<T>(acc, &times, imu) {
                        let s = |t: u64| t as f64 * 1e-6;
                        sum += to_f64(&d.delta_velocity_m_s) - truth(s(d.t_start_us), s(d.t_us()));
                    }
                    sum.norm()
                };
                let corrected = error_sum(DeltaAccumulator::new());
                let plain = error_sum(DeltaAccumulator::uncorrected());
                assert!(plain > 1e-3, "the motion must show sculling: {plain}");
                assert!(
                    corrected < plain / 10.0,
                    "velocity error over 1 s: corrected {corrected}, uncorrected {plain}"
                );
            }

            /// Constant rate and specific force: dropped samples and jitter
            /// change nothing (the accumulation follows the timestamps).
            #[test]
            fn irregular_timestamps_integrate_exactly() {
                let w = Vector3::new(0.3, -0.2, 0.5);
                let f = Vector3::new(0.5, 0.1, -9.8);
                let times = [0u64, 700, 2_300, 2_900, 5_000, 6_100, 9_000, 10_400];
                let mut acc = DeltaAccumulator::<T>::new();
                for &t in &times {
                    acc.push(&sample(t, w, f));
                }
                let d = acc.take().expect("a step");
                assert_eq!((d.t_start_us, d.t_us()), (0, 10_400));
                let span = 10_400e-6;
                let truth_angle = w * span;
                // Constant rate and force: Δv = ∫ exp(w s) f ds.
                let n = 10_000;
                let mut truth_v = Vector3::zeros();
                for i in 0..n {
                    let s = (i as f64 + 0.5) * span / n as f64;
                    truth_v += UnitQuaternion::from_scaled_axis(w * s) * f * (span / n as f64);
                }
                let ea = (to_f64(&d.delta_angle_rad) - truth_angle).norm();
                let ev = (to_f64(&d.delta_velocity_m_s) - truth_v).norm();
                assert!(ea < $tol && ev < $tol * 10.0, "angle {ea}, velocity {ev}");
                // The next step starts where this one ended.
                assert_eq!(acc.start_us(), Some(10_400));
                assert!(acc.take().is_none());
            }

            /// The EKF predicting over 10 ms steps of deltas stays with the
            /// same EKF predicting at every 1 kHz sample through a turning,
            /// accelerating 3 s.
            #[test]
            fn ekf_on_deltas_follows_the_per_sample_ekf() {
                let state = NavState::<T> {
                    attitude: UnitQuaternion::identity(),
                    position_ned_m: Vector3::zeros(),
                    velocity_ned_m_s: Vector3::new(T::lit(10.0), T::lit(0.0), T::lit(0.0)),
                    accel_bias_m_s2: Vector3::zeros(),
                    gyro_bias_rad_s: Vector3::zeros(),
                };
                let config = Ekf16Config::<T>::default();
                let cov = SVector::<T, NAV_STATES>::from_element(T::lit(1e-4));
                let mut every = Ekf16::from_state(config, 0, &state, &cov).expect("valid");
                let mut multi = every.clone();
                let mut acc = DeltaAccumulator::<T>::new();
                for k in 1..=3_000u64 {
                    let t = k as f64 * 1e-3;
                    let w = Vector3::new(0.4 * (7.0 * t).sin(), 0.3 * (5.0 * t).cos(), 0.2);
                    let f = Vector3::new(2.0 * (3.0 * t).sin(), 1.0, -9.80665);
                    let s = sample::<T>(k * IMU_US, w, f);
                    every.push_imu(&s).expect("accepted");
                    if k == 1 {
                        // The first step has no earlier sample: both filters take it alone.
                        multi.push_imu(&s).expect("accepted");
                    }
                    acc.push(&s);
                    if acc.elapsed_us() >= STEP_US {
                        let d = acc.take().expect("a step");
                        multi.push_imu_deltas(&d).expect("accepted");
                    }
                }
                if let Some(d) = acc.take() {
                    multi.push_imu_deltas(&d).expect("accepted");
                }
                assert_eq!(multi.time_us(), Some(3_000_000));
                let (a, b) = (every.nav_state().unwrap(), multi.nav_state().unwrap());
                let angle = a.attitude.angle_to(&b.attitude).as_f64();
                let dv = to_f64(&(a.velocity_ned_m_s - b.velocity_ned_m_s)).norm();
                let dr = to_f64(&(a.position_ned_m - b.position_ned_m)).norm();
                assert!(
                    angle < 1e-4 && dv < 1e-3 && dr < 1e-3,
                    "{angle} rad, {dv} m/s, {dr} m"
                );
                // The covariances agree too (same process noise over the same time).
                let (pa, pb) = (every.covariance(), multi.covariance());
                for i in 0..NAV_STATES {
                    let (x, y) = (pa[(i, i)].as_f64(), pb[(i, i)].as_f64());
                    assert!(
                        (x - y).abs() <= 0.02 * x.abs().max(1e-9),
                        "P[{i}]: {x} vs {y}"
                    );
                }
            }

            /// A step that does not start at the filter's time is taken as
            /// its last sample alone; non-finite deltas are refused.
            #[test]
            fn ekf_refuses_bad_deltas() {
                let state = NavState::<T> {
                    attitude: UnitQuaternion::identity(),
                    position_ned_m: Vector3::zeros(),
                    velocity_ned_m_s: Vector3::zeros(),
                    accel_bias_m_s2: Vector3::zeros(),
                    gyro_bias_rad_s: Vector3::zeros(),
                };
                let cov = SVector::<T, NAV_STATES>::from_element(T::lit(1e-4));
                let mut ekf =
                    Ekf16::from_state(Ekf16Config::default(), 0, &state, &cov).expect("valid");
                let level = Vector3::new(0.0, 0.0, -9.80665);
                let mut bad = ImuDeltas {
                    t_start_us: 0,
                    delta_angle_rad: Vector3::new(T::lit(f64::NAN), T::lit(0.0), T::lit(0.0)),
                    delta_velocity_m_s: Vector3::zeros(),
                    last: sample::<T>(5_000, Vector3::zeros(), level),
                };
                assert!(ekf.push_imu_deltas(&bad).is_err());
                assert_eq!(ekf.time_us(), Some(0));
                assert_eq!(ekf.refusals().imu_non_finite, 1);
                bad.delta_angle_rad = Vector3::zeros();
                bad.t_start_us = 1_000;
                ekf.push_imu_deltas(&bad).expect("taken as one sample");
                assert_eq!(ekf.time_us(), Some(5_000));
                assert!(ekf.state_vector().iter().all(|v| v.is_finite()));
            }
        }
    };
}

delta_tests!(f64_, f64, tol = 1e-6);
delta_tests!(f32_, f32, tol = 1e-4);

//! The structured (block-sparse) covariance prediction and the sparse Joseph
//! update against the dense forms they replace, on random states and random
//! positive semi-definite covariances, in f32 and f64, for 16 and 17 states;
//! and the small-angle series of the rotation against the exact formula.
//!
//! Tolerances: differences are measured against the dense form evaluated in
//! f64 from the same inputs, relative to the largest entry of the result:
//! below `1e-14` in f64 and `2e-6` in f32. The dense form in the same
//! precision is printed beside it (`--nocapture`): both are at rounding level
//! (measured: structured 4.4e-16 / 3.1e-7, sparse Joseph 4.4e-16 / 1.9e-7;
//! dense 0 / 4.1e-7 and 3.2e-16 / 2.9e-7).

use delaynav::ekf16::state::{NAV_STATES, StateVector};
use delaynav::geo::{quaternion_from_euler, quaternion_from_rotation_vector};
use delaynav::internals::kalman;
use delaynav::internals::process;
use delaynav::{Ekf16Config, Scalar};
use nalgebra::{SMatrix, SVector, Vector3};

mod flight;
use flight::Noise;

/// A random state: attitude anywhere, metres to kilometres, biases.
fn random_state(noise: &mut Noise) -> StateVector<f64> {
    let q = quaternion_from_euler(noise.gauss(), noise.gauss() * 0.5, noise.gauss() * 3.0);
    let mut x = StateVector::<f64>::zeros();
    x.fixed_rows_mut::<4>(0)
        .copy_from(&nalgebra::Vector4::new(q.w, q.i, q.j, q.k));
    for i in 4..7 {
        x[i] = noise.gauss() * 300.0;
    }
    for i in 7..10 {
        x[i] = noise.gauss() * 10.0;
    }
    for i in 10..13 {
        x[i] = noise.gauss() * 0.1;
    }
    for i in 13..16 {
        x[i] = noise.gauss() * 0.01;
    }
    x
}

/// A random symmetric PSD covariance with per-state scales spanning the
/// filter's (quaternion 1e-2, position 10 m, velocity 1 m/s, biases,
/// extras), rank deficient in one direction half of the time.
fn random_covariance<const N: usize>(noise: &mut Noise) -> SMatrix<f64, N, N> {
    let scale = |i: usize| match i {
        0..4 => 1e-2,
        4..7 => 10.0,
        7..10 => 1.0,
        10..13 => 0.05,
        13..16 => 1e-3,
        _ => 0.1,
    };
    let mut l = SMatrix::<f64, N, N>::zeros();
    for i in 0..N {
        for j in 0..N {
            l[(i, j)] = noise.gauss() * scale(i);
        }
    }
    if noise.uniform() < 0.5 {
        l.column_mut(N - 1).fill(0.0);
    }
    let p = l * l.transpose();
    (p + p.transpose()) * 0.5
}

fn cast<T: Scalar, const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> SMatrix<T, R, C> {
    m.map(T::lit)
}

fn to_f64<T: Scalar, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> SMatrix<f64, R, C> {
    m.map(|v| v.as_f64())
}

/// Pads a 16x16 matrix with zeros to `N x N`.
fn widen<const N: usize>(m: &SMatrix<f64, NAV_STATES, NAV_STATES>) -> SMatrix<f64, N, N> {
    let mut out = SMatrix::<f64, N, N>::zeros();
    out.fixed_view_mut::<NAV_STATES, NAV_STATES>(0, 0)
        .copy_from(m);
    out
}

/// The dense prediction `A P A^T + Q`, in f64.
fn dense_prediction<const N: usize>(
    p: &SMatrix<f64, N, N>,
    x: &StateVector<f64>,
    gyro: &Vector3<f64>,
    accel: &Vector3<f64>,
    dt: f64,
    config: &Ekf16Config<f64>,
    extra: &SVector<f64, N>,
) -> SMatrix<f64, N, N> {
    let f = widen::<N>(&process::jacobian(x, gyro, accel));
    let mut intensity = widen::<N>(&process::noise_intensity(x, config));
    for i in NAV_STATES..N {
        intensity[(i, i)] = extra[i];
    }
    let a = process::transition(&f, dt);
    a * p * a.transpose() + process::discretize_noise(&f, &intensity, dt)
}

/// One test per precision and state count (16, 17) with the tolerance of
/// each precision.
macro_rules! precision_cases {
    ($check:ident, f64 = $tol64:expr, f32 = $tol32:expr) => {
        mod $check {
            #[test]
            fn f64_16() {
                super::$check::<f64, 16>($tol64);
            }
            #[test]
            fn f64_17() {
                super::$check::<f64, 17>($tol64);
            }
            #[test]
            fn f32_16() {
                super::$check::<f32, 16>($tol32);
            }
            #[test]
            fn f32_17() {
                super::$check::<f32, 17>($tol32);
            }
        }
    };
}

/// `max |a - b| / max |b|`.
fn relative_error<const R: usize, const C: usize>(
    a: &SMatrix<f64, R, C>,
    b: &SMatrix<f64, R, C>,
) -> f64 {
    (a - b).amax() / b.amax()
}

fn structured_prediction_matches_dense<T: Scalar, const N: usize>(tol: f64) {
    let mut noise = Noise(0x5eed_0000 + N as u64);
    // Large noise densities so Q's blocks are not negligible next to A P A^T.
    let config = Ekf16Config::<f64> {
        gyro_noise_density: 0.05,
        accel_noise_density: 0.5,
        accel_bias_random_walk: 0.01,
        gyro_bias_random_walk: 1e-3,
        ..Ekf16Config::default()
    };
    let config_t = Ekf16Config::<T> {
        gyro_noise_density: T::lit(config.gyro_noise_density),
        accel_noise_density: T::lit(config.accel_noise_density),
        accel_bias_random_walk: T::lit(config.accel_bias_random_walk),
        gyro_bias_random_walk: T::lit(config.gyro_bias_random_walk),
        ..Ekf16Config::default()
    };
    let mut worst: f64 = 0.0;
    let mut worst_dense: f64 = 0.0;
    for case in 0..200 {
        let x = random_state(&mut noise);
        let p = random_covariance::<N>(&mut noise);
        let gyro = noise.vec3(2.0);
        let accel = noise.vec3(5.0) + Vector3::new(0.0, 0.0, -9.8);
        // 1 kHz to 50 Hz, and a long gap now and then.
        let dt = if case % 10 == 9 {
            0.25
        } else {
            [1e-3, 4e-3, 0.02][case % 3]
        };
        let mut extra = SVector::<f64, N>::zeros();
        for i in NAV_STATES..N {
            extra[i] = 1e-4 + noise.uniform() * 1e-2;
        }
        let reference = dense_prediction(&p, &x, &gyro, &accel, dt, &config, &extra);
        let (xt, pt) = (cast::<T, NAV_STATES, 1>(&x), cast::<T, N, N>(&p));
        let (gt, at) = (cast::<T, 3, 1>(&gyro), cast::<T, 3, 1>(&accel));
        let structured = process::predict_covariance(
            &pt,
            &xt,
            &gt,
            &at,
            T::lit(dt),
            &config_t,
            &cast::<T, N, 1>(&extra),
        );
        assert_eq!(structured, structured.transpose(), "not exactly symmetric");
        worst = worst.max(relative_error(&to_f64(&structured), &reference));
        // The dense form in the same precision, for scale.
        let f = {
            let mut f = SMatrix::<T, N, N>::zeros();
            f.fixed_view_mut::<NAV_STATES, NAV_STATES>(0, 0)
                .copy_from(&process::jacobian(&xt, &gt, &at));
            f
        };
        let mut intensity = SMatrix::<T, N, N>::zeros();
        intensity
            .fixed_view_mut::<NAV_STATES, NAV_STATES>(0, 0)
            .copy_from(&process::noise_intensity(&xt, &config_t));
        for i in NAV_STATES..N {
            intensity[(i, i)] = T::lit(extra[i]);
        }
        let a = process::transition(&f, T::lit(dt));
        let dense = a * pt * a.transpose() + process::discretize_noise(&f, &intensity, T::lit(dt));
        worst_dense = worst_dense.max(relative_error(&to_f64(&dense), &reference));
        // The noise alone (the long-gap path).
        let mut q = SMatrix::<T, N, N>::zeros();
        process::add_process_noise(
            &mut q,
            &xt,
            &gt,
            &at,
            T::lit(dt),
            &config_t,
            &cast::<T, N, 1>(&extra),
        );
        let q_ref = dense_prediction(&SMatrix::zeros(), &x, &gyro, &accel, dt, &config, &extra);
        assert!(
            relative_error(&to_f64(&q), &q_ref) < tol,
            "Q differs by {}",
            relative_error(&to_f64(&q), &q_ref)
        );
    }
    eprintln!(
        "{} N={N}: structured {worst:.2e}, dense in the same precision {worst_dense:.2e}",
        core::any::type_name::<T>()
    );
    assert!(
        worst < tol,
        "structured prediction off by {worst:e} (dense in the same precision: {worst_dense:e})"
    );
}

precision_cases!(structured_prediction_matches_dense, f64 = 1e-14, f32 = 2e-6);

/// The dense Joseph update in f64: `(I - K H) P (I - K H)^T + K R K^T`.
fn dense_joseph<const N: usize, const M: usize>(
    p: &SMatrix<f64, N, N>,
    h: &SMatrix<f64, M, N>,
    r: &SMatrix<f64, M, M>,
    restriction: Option<&SMatrix<f64, N, N>>,
) -> SMatrix<f64, N, N> {
    let s = h * p * h.transpose() + r;
    let mut k = p * h.transpose() * s.try_inverse().unwrap();
    if let Some(c) = restriction {
        k = c * k;
    }
    let l = SMatrix::<f64, N, N>::identity() - k * h;
    l * p * l.transpose() + k * r * k.transpose()
}

/// The dense Joseph update in `T`, as the filter computed it before.
fn dense_joseph_in<T: Scalar, const N: usize>(
    p: &SMatrix<T, N, N>,
    h: &SMatrix<T, 3, N>,
    r: &SMatrix<T, 3, 3>,
    restriction: Option<&SMatrix<T, N, N>>,
) -> SMatrix<T, N, N> {
    let pht = p * h.transpose();
    let s = h * pht + r;
    let mut k = s.cholesky().unwrap().solve(&pht.transpose()).transpose();
    if let Some(c) = restriction {
        k = c * k;
    }
    let l = SMatrix::<T, N, N>::identity() - k * h;
    l * p * l.transpose() + k * r * k.transpose()
}

/// A GPS-like block: identity on three states, a few dense columns, zeros elsewhere.
fn sparse_jacobian<const N: usize>(noise: &mut Noise, first: usize) -> SMatrix<f64, 3, N> {
    let mut h = SMatrix::<f64, 3, N>::zeros();
    h.fixed_view_mut::<3, 3>(0, first).fill_with_identity();
    for c in [0, 1, 2, 3, N - 1] {
        if noise.uniform() < 0.6 {
            for m in 0..3 {
                h[(m, c)] += noise.gauss() * 0.3;
            }
        }
    }
    h
}

fn sparse_joseph_matches_dense<T: Scalar, const N: usize>(tol: f64) {
    let mut noise = Noise(0x0005_ea5e + N as u64);
    let mut worst: f64 = 0.0;
    let mut worst_dense: f64 = 0.0;
    for case in 0..200 {
        let p = random_covariance::<N>(&mut noise);
        let h = sparse_jacobian::<N>(&mut noise, if case % 2 == 0 { 4 } else { 7 });
        let r = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::new(
            4.0 * noise.uniform() + 0.01,
            4.0 * noise.uniform() + 0.01,
            4.0 * noise.uniform() + 0.01,
        ));
        // Half of the cases restrict the gain (a consider update).
        let mut c = SMatrix::<f64, N, N>::identity();
        c.fixed_view_mut::<4, 4>(0, 0).fill(0.25);
        let restriction = (case % 4 == 1).then_some(c);
        let reference = dense_joseph(&p, &h, &r, restriction.as_ref());
        let (mut x, mut pt) = (SVector::<T, N>::zeros(), cast::<T, N, N>(&p));
        let ct = restriction.map(|c| cast::<T, N, N>(&c));
        let record = kalman::joseph_update_restricted(
            &mut x,
            &mut pt,
            &SVector::<T, 3>::zeros(),
            &cast::<T, 3, N>(&h),
            &cast::<T, 3, 3>(&r),
            T::lit(f64::INFINITY),
            0,
            "test",
            ct.as_ref(),
        )
        .unwrap();
        assert!(record.fused);
        assert_eq!(pt, pt.transpose(), "not exactly symmetric");
        worst = worst.max(relative_error(&to_f64(&pt), &reference));
        // The dense Joseph form in the same precision, for scale.
        let dense = dense_joseph_in::<T, N>(&cast(&p), &cast(&h), &cast(&r), ct.as_ref());
        worst_dense = worst_dense.max(relative_error(&to_f64(&dense), &reference));
    }
    eprintln!(
        "{} N={N}: sparse Joseph {worst:.2e}, dense Joseph in the same precision {worst_dense:.2e}",
        core::any::type_name::<T>()
    );
    assert!(worst < tol, "sparse Joseph off by {worst:e}");
}

precision_cases!(sparse_joseph_matches_dense, f64 = 1e-14, f32 = 2e-6);

/// The exact rotation `[cos(a/2), sin(a/2) u]` in f64.
fn exact_rotation(theta: &Vector3<f64>) -> [f64; 4] {
    let a = theta.norm();
    let (s, c) = (a / 2.0).sin_cos();
    let k = if a > 0.0 { s / a } else { 0.5 };
    [c, theta.x * k, theta.y * k, theta.z * k]
}

fn rotation_error<T: Scalar>(theta: &Vector3<f64>) -> f64 {
    let q = quaternion_from_rotation_vector(&cast::<T, 3, 1>(theta));
    let e = exact_rotation(theta);
    let got = [q.w, q.i, q.j, q.k].map(|v| v.as_f64());
    (0..4).map(|i| (got[i] - e[i]).abs()).fold(0.0, f64::max)
}

/// Below and above the series' range, with angles from 1e-9 to 3 rad: the
/// error is a few units of the precision's epsilon (the input's own
/// rounding included), so the series and the exact branch agree.
fn small_rotation_is_exact_to_rounding<T: Scalar>() {
    let mut noise = Noise(7);
    let eps = T::EPS.as_f64();
    let mut worst: f64 = 0.0;
    for _ in 0..20_000 {
        let dir = noise.vec3(1.0).normalize();
        let angle = 10f64.powf(-9.0 + 9.5 * noise.uniform());
        worst = worst.max(rotation_error::<T>(&(dir * angle)));
    }
    eprintln!(
        "{}: rotation within {:.2} eps",
        core::any::type_name::<T>(),
        worst / eps
    );
    assert!(worst < 4.0 * eps, "rotation off by {:.2} eps", worst / eps);
}

#[test]
fn small_rotation_is_exact_to_rounding_f32() {
    small_rotation_is_exact_to_rounding::<f32>();
}

#[test]
fn small_rotation_is_exact_to_rounding_f64() {
    small_rotation_is_exact_to_rounding::<f64>();
}

/// Step lengths in f32 go through hardware f32 only and are still the
/// correctly rounded `us / 1e6` (the f64 route's result), up to 2^24 µs.
#[test]
fn f32_step_lengths_are_correctly_rounded() {
    for us in (0..1u64 << 24)
        .step_by(997)
        .chain([1, 999, 1000, 1001, 2500, (1 << 24) - 1])
    {
        let expected = (us as f64 / 1e6) as f32;
        assert_eq!(delaynav::scalar::us_to_s::<f32>(us), expected, "{us} us");
    }
    assert_eq!(
        delaynav::scalar::us_to_s::<f32>(1 << 30),
        1_073.741_824_f64 as f32
    );
    assert_eq!(delaynav::scalar::us_to_s::<f64>(1500), 1.5e-3);
}

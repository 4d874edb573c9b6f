//! One IMU sample (steady state, after initialization) and one GPS fix
//! through `DelayCompensatedNav`, in f32 and f64, delay estimated.

use criterion::{Criterion, criterion_group, criterion_main};
use delaynav::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use delaynav::{Gps, GpsPosition, Imu, Navigator, Scalar};
use nalgebra::Vector3;
use std::hint::black_box;

/// A gentle oscillation so the delay loop and the EKF have motion to see.
fn imu<T: Scalar>(k: u64) -> Imu<T> {
    let t = k as f64 * 1e-3;
    Imu {
        t_us: k * 1000,
        gyro_rad_s: Vector3::new(T::lit(0.01), T::lit(-0.02), T::lit(0.1)),
        accel_m_s2: Vector3::new(T::lit(2.0 * (1.3 * t).sin()), T::lit(0.0), T::lit(-9.8)),
    }
}

fn gps<T: Scalar>(k: u64) -> Gps<T> {
    let t = k as f64 * 1e-3;
    Gps {
        t_us: k * 1000 + 100,
        position: GpsPosition::Ned(Vector3::new(T::lit(0.1), T::lit(0.0), T::lit(0.0))),
        velocity_ned_m_s: Vector3::new(
            T::lit(-2.0 / 1.3 * (1.3 * t).cos()),
            T::lit(0.0),
            T::lit(0.0),
        ),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    }
}

/// A navigator run for 8 s at 1 kHz with 10 Hz GPS (initialized, present
/// ready, correlation buffer full).
fn running<T: Scalar>() -> Box<DelayCompensatedNav<T>> {
    let config = DelayCompensatedNavConfig {
        mode: DelayMode::Estimated {
            initial_s: T::lit(0.2),
        },
        ..DelayCompensatedNavConfig::default()
    };
    let mut nav = Box::new(DelayCompensatedNav::new(config).unwrap());
    for k in 1..=8000 {
        nav.push_imu(&imu::<T>(k)).unwrap();
        if k % 100 == 0 {
            nav.push_gps(&gps::<T>(k)).unwrap();
        }
    }
    assert!(nav.estimate().is_some());
    nav
}

fn bench_precision<T: Scalar>(c: &mut Criterion, name: &str) {
    let mut group = c.benchmark_group(format!("nav_{name}"));
    let base = running::<T>();
    group.bench_function("imu_sample", |b| {
        let mut nav = base.clone();
        let mut k = 8001;
        b.iter(|| {
            nav.push_imu(black_box(&imu::<T>(k))).unwrap();
            k += 1;
        })
    });
    group.bench_function("gps_fix", |b| {
        // Each iteration fuses one fix into a copy of the same navigator.
        let fix = gps::<T>(8050);
        b.iter_batched_ref(
            || base.clone(),
            |nav| nav.push_gps(black_box(&fix)).unwrap(),
            criterion::BatchSize::LargeInput,
        )
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_precision::<f32>(c, "f32");
    bench_precision::<f64>(c, "f64");
}

criterion_group!(nav_benches, benches);
criterion_main!(nav_benches);

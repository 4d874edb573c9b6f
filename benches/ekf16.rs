//! One prediction step and one GPS update of `Ekf16`, in f32 and f64.

use criterion::{Criterion, criterion_group, criterion_main};
use delaynav::{Ekf16, Ekf16Config, Gps, GpsPosition, Imu, Navigator, Scalar};
use nalgebra::Vector3;
use std::hint::black_box;

fn imu<T: Scalar>(k: u64) -> Imu<T> {
    Imu {
        t_us: k * 1000,
        gyro_rad_s: Vector3::new(T::lit(0.01), T::lit(-0.02), T::lit(0.1)),
        accel_m_s2: Vector3::new(T::lit(0.1), T::lit(0.0), T::lit(-9.8)),
    }
}

fn gps<T: Scalar>(k: u64) -> Gps<T> {
    Gps {
        t_us: k * 1000,
        position: GpsPosition::Ned(Vector3::new(T::lit(0.1), T::lit(0.0), T::lit(0.0))),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    }
}

/// A filter initialized and run for a second at 1 kHz.
fn running<T: Scalar>() -> Ekf16<T> {
    let mut ekf = Ekf16::new(Ekf16Config::default()).unwrap();
    for k in 0..1000 {
        ekf.push_imu(&imu::<T>(k)).unwrap();
        if k % 100 == 99 {
            ekf.push_gps(&gps::<T>(k)).unwrap();
        }
    }
    ekf
}

fn bench_precision<T: Scalar>(c: &mut Criterion, name: &str) {
    let mut group = c.benchmark_group(format!("ekf16_{name}"));
    let base = running::<T>();
    group.bench_function("predict", |b| {
        let mut ekf = base.clone();
        let mut k = 1000;
        b.iter(|| {
            ekf.push_imu(black_box(&imu::<T>(k))).unwrap();
            k += 1;
        })
    });
    group.bench_function("gps_update", |b| {
        // Each iteration fuses one fix into a copy of the same filter, so
        // every update sees the same covariance.
        let fix = gps::<T>(1_000_000);
        b.iter_batched_ref(
            || base.clone(),
            |ekf| ekf.push_gps(black_box(&fix)).unwrap(),
            criterion::BatchSize::SmallInput,
        )
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_precision::<f32>(c, "f32");
    bench_precision::<f64>(c, "f64");
}

criterion_group!(ekf16_benches, benches);
criterion_main!(ekf16_benches);

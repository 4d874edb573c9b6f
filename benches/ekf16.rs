//! One prediction step and one GPS update of `Ekf16` and of
//! `AugmentedEkf17`, in f32 and f64, in one run so the ratio is measured on the same
//! machine state.
//!
//! Comparing two commits: build each (`cargo bench --bench ekf16 --no-run`),
//! run the older with `--bench --save-baseline main` and the newer with
//! `--bench --baseline main` one after the other.

use criterion::measurement::WallTime;
use criterion::{BatchSize, BenchmarkGroup, Criterion, criterion_group, criterion_main};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Gps, GpsPosition, Imu, Navigator,
    Scalar,
};
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

/// A navigator initialized and run for a second at 1 kHz with GPS at 10 Hz.
fn running<T: Scalar, N: Navigator<T>>(mut nav: N) -> N {
    for k in 0..1000 {
        nav.push_imu(&imu::<T>(k)).unwrap();
        if k % 100 == 99 {
            nav.push_gps(&gps::<T>(k)).unwrap();
        }
    }
    nav
}

fn bench_filter<T: Scalar, N: Navigator<T> + Clone>(
    group: &mut BenchmarkGroup<'_, WallTime>,
    filter: &str,
    base: &N,
) {
    group.bench_function(format!("{filter}_predict"), |b| {
        let mut nav = base.clone();
        let mut k = 1000;
        b.iter(|| {
            nav.push_imu(black_box(&imu::<T>(k))).unwrap();
            k += 1;
        })
    });
    group.bench_function(format!("{filter}_gps_update"), |b| {
        // Each iteration fuses one fix into a fresh copy of the same filter,
        // made just before (warm in cache, as a running filter's state is);
        // a batch of copies would time cache misses on cold copies instead.
        let fix = gps::<T>(1_000_000);
        b.iter_batched_ref(
            || base.clone(),
            |nav| nav.push_gps(black_box(&fix)).unwrap(),
            BatchSize::PerIteration,
        )
    });
}

fn bench_precision<T: Scalar>(c: &mut Criterion, name: &str) {
    let mut group = c.benchmark_group(format!("ekf16_vs_aekf17_{name}"));
    let ekf = running(Ekf16::<T>::new(Ekf16Config::default()).unwrap());
    bench_filter(&mut group, "ekf16", &ekf);
    let aekf = running(AugmentedEkf17::<T>::new(AugmentedEkf17Config::default()).unwrap());
    bench_filter(&mut group, "aekf17", &aekf);
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_precision::<f32>(c, "f32");
    bench_precision::<f64>(c, "f64");
}

criterion_group!(filter_benches, benches);
criterion_main!(filter_benches);

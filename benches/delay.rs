//! Delay loop costs: one IMU push, one GPS-fix update (sliding correlation,
//! peak search, GFA), one fractional delay read; f32 and f64.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use delaynav::delay::{DefaultDelayLoop, DelayLoopConfig, FractionalDelayLine};
use delaynav::scalar::Scalar;
use nalgebra::{SVector, Vector3};

/// A loop warmed up on 10 s of 1 kHz IMU / 10 Hz GPS sine motion delayed 0.2 s,
/// and the time of its last IMU sample, us.
fn warmed_loop<T: Scalar>() -> (DefaultDelayLoop<T>, u64) {
    let mut delay_loop = DefaultDelayLoop::<T>::new(DelayLoopConfig::clean_input()).unwrap();
    let accel = |t: f64| {
        Vector3::new(
            T::lit((1.3 * t).sin() * 3.0),
            T::lit((0.7 * t).cos() * 3.0),
            T::lit((2.1 * t).sin()),
        )
    };
    let velocity = |t: f64| {
        Vector3::new(
            T::lit(-(1.3 * t).cos() * 3.0 / 1.3),
            T::lit((0.7 * t).sin() * 3.0 / 0.7),
            T::lit(-(2.1 * t).cos() / 2.1),
        )
    };
    let mut t_us = 0;
    for k in 1..=10_000u64 {
        t_us = k * 1000;
        let t = t_us as f64 * 1e-6;
        delay_loop.push_imu(t_us, accel(t)).unwrap();
        if k % 100 == 0 {
            delay_loop.push_gps(t_us, velocity(t - 0.2)).unwrap();
        }
    }
    (delay_loop, t_us)
}

fn bench_precision<T: Scalar>(c: &mut Criterion, name: &str) {
    let (warm, t_end) = warmed_loop::<T>();

    c.bench_function(&format!("delay_loop_push_imu_{name}"), |b| {
        let mut delay_loop = warm.clone();
        let mut t_us = t_end;
        b.iter(|| {
            t_us += 1000;
            delay_loop
                .push_imu(
                    t_us,
                    black_box(Vector3::new(T::lit(0.1), T::lit(0.2), T::lit(0.3))),
                )
                .unwrap();
        })
    });

    // One GPS fix at 10 Hz with its 100 IMU samples: the per-fix cost is the
    // fix's sliding steps, the peak search and the GFA (the IMU part is the
    // bench above, x100).
    c.bench_function(&format!("delay_loop_gps_fix_with_100_imu_{name}"), |b| {
        let mut delay_loop = warm.clone();
        let mut t_us = t_end;
        b.iter(|| {
            for _ in 0..100 {
                t_us += 1000;
                let t = t_us as f64 * 1e-6;
                delay_loop
                    .push_imu(
                        t_us,
                        Vector3::new(T::lit((1.3 * t).sin() * 3.0), T::lit(0.0), T::lit(0.0)),
                    )
                    .unwrap();
            }
            let t = t_us as f64 * 1e-6 - 0.2;
            black_box(
                delay_loop
                    .push_gps(
                        t_us,
                        Vector3::new(
                            T::lit(-(1.3 * t).cos() * 3.0 / 1.3),
                            T::lit(0.0),
                            T::lit(0.0),
                        ),
                    )
                    .unwrap(),
            );
        })
    });

    let mut line = FractionalDelayLine::<T, 3, 1024, 3>::new();
    for k in 0..1024 {
        line.push(SVector::from([T::lit(k as f64); 3])).unwrap();
    }
    c.bench_function(&format!("fractional_delay_read_{name}"), |b| {
        b.iter(|| black_box(line.read(black_box(T::lit(250.37))).unwrap()))
    });
}

fn benches(c: &mut Criterion) {
    bench_precision::<f32>(c, "f32");
    bench_precision::<f64>(c, "f64");
}

criterion_group!(delay, benches);
criterion_main!(delay);

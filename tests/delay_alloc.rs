//! delay: no heap allocation after construction on the per-sample path
//! (counting global allocator; its own test binary so no other test allocates
//! concurrently).

mod common;

use common::{Event, Motion, Scenario};
use delaynav::Imu;
use delaynav::delay::{
    CalibrationConfig, DefaultCalibrator, DefaultDelayLoop, DelayLoopConfig, FractionalDelayLine,
    WhiteningFir,
};
use delaynav::scalar::Scalar;
use nalgebra::{SVector, Vector3};

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::allocations;

fn per_sample_path_does_not_allocate<T: Scalar>() {
    let mut scenario = Scenario::simulator();
    scenario.duration_s = 15.0;
    let motion = Motion::random(2, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
    let events = scenario.events(&motion, |_| 0.2);
    let mut delay_loop = DefaultDelayLoop::<T>::new(DelayLoopConfig::clean_input()).unwrap();
    let mut line = FractionalDelayLine::<T, 3, 512, 3>::new();
    let mut fir = WhiteningFir::<T, 31>::low_pass(T::lit(20.0), T::lit(1000.0)).unwrap();
    let mut calibrator =
        Box::new(DefaultCalibrator::<T>::new(CalibrationConfig::default()).unwrap());
    let v3 = |a: [f64; 3]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));

    let before = allocations();
    let mut updates = 0;
    for event in &events {
        match *event {
            Event::Imu(t, a) => {
                let filtered = fir.filter(v3(a)).unwrap();
                line.push(SVector::from(filtered)).unwrap();
                if let Some(max) = line.max_delay_samples() {
                    let d = T::lit(200.5).min(T::lit(max as f64));
                    std::hint::black_box(line.read(d).unwrap());
                }
                delay_loop.push_imu(t, v3(a)).unwrap();
                let specific_force = v3([a[0], a[1], a[2] - 9.80665]);
                calibrator
                    .push_imu(&Imu {
                        t_us: t,
                        gyro_rad_s: Vector3::zeros(),
                        accel_m_s2: specific_force,
                    })
                    .unwrap();
            }
            Event::Gps(t, v) => {
                if delay_loop.push_gps(t, v3(v)).unwrap().is_some() {
                    updates += 1;
                }
                calibrator
                    .push_gps(&common::velocity_fix(t, v3(v)))
                    .unwrap();
            }
        }
    }
    let calibration = calibrator.result().unwrap();
    let allocations = allocations() - before;
    assert!((calibration.delay_s.as_f64() - 0.2).abs() < 0.05);
    assert!(
        updates > 50,
        "the loop must have run its updates ({updates})"
    );
    assert_eq!(allocations, 0, "allocations on the per-sample path");
}

#[test]
fn no_allocation_after_construction() {
    per_sample_path_does_not_allocate::<f32>();
    per_sample_path_does_not_allocate::<f64>();
}

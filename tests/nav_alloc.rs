//! nav: no heap allocation after construction on the per-sample path
//! (counting global allocator; its own test binary so no other test
//! allocates concurrently), in f32 and f64, estimated and fixed mode.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use common::Motion;
use common::flight::{Flight, FlightEvent, Suite, fly};
use delaynav::nav::{DelayCompensatedNav, DelayMode, NavConfig};
use delaynav::{Gps, GpsPosition, Imu, Mag, Navigator, Scalar};
use nalgebra::Vector3;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn per_sample_path_does_not_allocate<T: Scalar>(mode: DelayMode<T>) {
    let flight = Flight::new(Motion::random(2, 6, 0.05, 0.5, [3.0, 3.0, 1.0]));
    let events = fly(&flight, &Suite::simulator(), 20.0, |_| 0.2, None);
    let v3 = |v: &Vector3<f64>| v.map(T::lit);
    let mut nav = Box::new(
        DelayCompensatedNav::<T>::new(NavConfig {
            mode,
            ..NavConfig::default()
        })
        .unwrap(),
    );
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for event in &events {
        match event {
            FlightEvent::Imu(s, _) => {
                let imu = Imu {
                    t_us: s.t_us,
                    gyro_rad_s: v3(&s.gyro_rad_s),
                    accel_m_s2: v3(&s.accel_m_s2),
                };
                nav.push_imu(&imu).unwrap();
                let _ = nav.estimate();
                let _ = nav.horizon_estimate();
            }
            FlightEvent::Mag(m) => {
                nav.push_mag(&Mag {
                    t_us: m.t_us,
                    field_body: v3(&m.field_body),
                })
                .unwrap();
            }
            FlightEvent::Gps(g) => {
                let GpsPosition::Ned(r) = g.position else {
                    unreachable!()
                };
                let fix = Gps {
                    t_us: g.t_us,
                    position: GpsPosition::Ned(v3(&r)),
                    velocity_ned_m_s: v3(&g.velocity_ned_m_s),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                };
                nav.push_gps(&fix).unwrap();
            }
        }
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(nav.estimate().is_some());
    assert_eq!(after - before, 0, "allocations on the per-sample path");
}

#[test]
fn no_allocation_after_construction() {
    per_sample_path_does_not_allocate::<f32>(DelayMode::Estimated { initial_s: 0.1 });
    per_sample_path_does_not_allocate::<f64>(DelayMode::Estimated { initial_s: 0.1 });
    per_sample_path_does_not_allocate::<f32>(DelayMode::Fixed { delay_s: 0.2 });
    per_sample_path_does_not_allocate::<f64>(DelayMode::Fixed { delay_s: 0.2 });
}

#[test]
fn memory_footprint_of_the_default_history() {
    // Printed for docs/nav.md; bounded so a regression shows.
    let f32_bytes = size_of::<DelayCompensatedNav<f32>>();
    let f64_bytes = size_of::<DelayCompensatedNav<f64>>();
    println!("DelayCompensatedNav<f32>: {f32_bytes} B, <f64>: {f64_bytes} B");
    println!(
        "HIST=256: f32 {} B, f64 {} B",
        size_of::<DelayCompensatedNav<f32, 256>>(),
        size_of::<DelayCompensatedNav<f64, 256>>()
    );
    assert!(f32_bytes < 160_000);
    assert!(f64_bytes < 320_000);
}

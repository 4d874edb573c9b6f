//! nav: no heap allocation after construction on the per-sample path
//! (counting global allocator; its own test binary so no other test
//! allocates concurrently), in f32 and f64, estimated and fixed mode.

mod common;

use common::Motion;
use common::flight::{Flight, FlightEvent, Suite, feed, fly};
use delaynav::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use delaynav::{Navigator, Scalar};

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::allocations;

fn per_sample_path_does_not_allocate<T: Scalar>(mode: DelayMode<T>) {
    let flight = Flight::new(Motion::random(2, 6, 0.05, 0.5, [3.0, 3.0, 1.0]));
    let events = fly(&flight, &Suite::simulator(), 20.0, |_| 0.2, None);
    let mut nav = Box::new(
        DelayCompensatedNav::<T>::new(DelayCompensatedNavConfig {
            mode,
            ..DelayCompensatedNavConfig::default()
        })
        .unwrap(),
    );
    let before = allocations();
    for event in &events {
        feed(&mut *nav, event);
        if matches!(event, FlightEvent::Imu(..)) {
            let _ = nav.estimate();
            let _ = nav.horizon_estimate();
        }
    }
    let after = allocations();
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

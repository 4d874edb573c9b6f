//! The per-sample path of `Ekf16` and `AugmentedEkf17` allocates nothing after construction:
//! a counting global allocator, armed per thread around the measured calls.

use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Gps, GpsOutcome, GpsPosition, Imu,
    Mag, MagOutcome, Navigator, Scalar,
};
use nalgebra::Vector3;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct CountingAllocator;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.with(|a| a.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if ARMED.with(|a| a.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// Allocations made by this thread while running `f`.
fn allocations_in(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    ARMED.with(|a| a.set(true));
    f();
    ARMED.with(|a| a.set(false));
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

fn run<T: Scalar, N: Navigator<T>>(mut ekf: N) {
    let lit = T::lit;
    let imu = |k: u64| Imu {
        t_us: k * 1000,
        gyro_rad_s: Vector3::new(lit(0.01), lit(-0.02), lit(0.1)),
        accel_m_s2: Vector3::new(lit(0.1), lit(0.0), lit(-9.8)),
    };
    let gps = |k: u64| Gps {
        t_us: k * 1000,
        position: GpsPosition::Ned(Vector3::new(lit(1.0), lit(2.0), lit(3.0))),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: Some(lit(2.0)),
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    };
    let mag = |k: u64| Mag {
        t_us: k * 1000,
        field_body: Vector3::new(lit(0.4), lit(0.1), lit(0.8)),
    };
    // Warm-up: alignment and initialization are also allocation-free, but
    // the claim is about the steady per-sample path.
    // 50 ms of samples (`align_min_duration_us`).
    for k in 0..=50 {
        ekf.push_imu(&imu(k)).unwrap();
    }
    assert_eq!(ekf.push_gps(&gps(50)).unwrap(), GpsOutcome::Initialized);
    let mut fused = 0;
    let n = allocations_in(|| {
        for k in 51..2051 {
            ekf.push_imu(&imu(k)).unwrap();
            if k % 100 == 0 {
                if let Ok(GpsOutcome::Fused { .. }) = ekf.push_gps(&gps(k)) {
                    fused += 1;
                }
                if let Ok(MagOutcome::Fused(_)) = ekf.push_mag(&mag(k)) {
                    fused += 1;
                }
            }
            // Refusals take the error path: no allocation there either.
            let _ = ekf.push_imu(&imu(k));
            let _ = ekf.estimate();
        }
    });
    assert_eq!(
        fused, 40,
        "every GPS fix and magnetometer sample reached the update"
    );
    assert_eq!(
        n,
        0,
        "{n} allocations on the per-sample path ({})",
        core::any::type_name::<N>()
    );
}

#[test]
fn predict_and_updates_allocate_nothing() {
    // The counter sees an allocation when there is one.
    assert_eq!(
        allocations_in(|| drop(std::hint::black_box(vec![1u8; 16]))),
        1
    );
    // One test: both precisions in one thread.
    run(Ekf16::<f32>::new(Ekf16Config::default()).unwrap());
    run(Ekf16::<f64>::new(Ekf16Config::default()).unwrap());
    run(AugmentedEkf17::<f32>::new(AugmentedEkf17Config::default()).unwrap());
    run(AugmentedEkf17::<f64>::new(AugmentedEkf17Config::default()).unwrap());
}

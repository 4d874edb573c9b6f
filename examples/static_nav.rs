//! The navigator in a `static`, constructed in place.
//!
//! `DelayCompensatedNav::BLANK` is a `const`: the compiler builds it and the
//! linker lays the `static` out, so no stack holds a copy of the navigator
//! (tens of KB) at any time. `configure` then validates the configuration
//! and sets the navigator up where it lies, on a small stack. On a
//! microcontroller the `static` is a
//! `critical_section::Mutex<RefCell<DelayCompensatedNav<f32, H>>>`, as in
//! the firmware of `examples/embedded/`; here `std`'s `Mutex` stands in for
//! it. A refused sample is routine (the navigator keeps its state and
//! counts it in `health().refusals`): it is counted here, not returned.
//!
//! ```sh
//! cargo run --release --example static_nav
//! ```

use std::sync::Mutex;

use delaynav::prelude::*;

/// History for a 0.5 s maximum delay at 1 kHz: `configure` checks that
/// `ceil(0.5 s x 1000 Hz x 1.02) + 5 = 515 <= HIST` (README, "Sizing the
/// history").
const HIST: usize = 515;

/// The navigator, blank until `main` configures it.
static NAV: Mutex<DelayCompensatedNav<f32, HIST>> = Mutex::new(DelayCompensatedNav::BLANK);

fn main() -> Result<(), Error> {
    let mut nav = NAV.lock().expect("only main locks it");
    assert_eq!(nav.health().alignment, AlignmentState::NotConfigured);

    let mut config = DelayCompensatedNavConfig::<f32>::default();
    config.delay_loop.fusion.delay_max_s = 0.5;
    config.mode = DelayMode::Estimated { initial_s: 0.2 };
    nav.configure(config)?;

    // Level and at rest, 1 kHz IMU; a 10 Hz GPS whose fixes arrive 0.2 s
    // late (at rest they all read the same).
    let gravity = Vector3::new(0.0, 0.0, -9.80665);
    let mut refused = 0u32;
    for k in 1..=3000u64 {
        let t_us = k * 1000;
        refused += u32::from(
            nav.push_imu(&Imu::new(t_us, Vector3::zeros(), gravity))
                .is_err(),
        );
        if k % 100 == 0 {
            let fix = Gps::ned(t_us, Vector3::new(10.0, -5.0, 0.0), Vector3::zeros());
            refused += u32::from(nav.push_gps(&fix).is_err());
        }
    }
    let health = nav.health();
    let now = nav.estimate().ok_or(Error::NotInitialized)?;
    println!(
        "navigator of {} bytes in a static, {:?}, position {:.2?} m at t = {} us, {} samples refused",
        core::mem::size_of::<DelayCompensatedNav<f32, HIST>>(),
        health.alignment,
        now.position_ned_m.as_slice(),
        now.t_us,
        refused,
    );
    // The same static configured again (a new flight): in place too.
    nav.configure(config)?;
    assert_eq!(nav.health().alignment, AlignmentState::WaitingForImu);
    Ok(())
}

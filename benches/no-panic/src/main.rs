//! Link-time check that no panic is reachable from the no_std push API.
//!
//! Every estimator is built and fed through its whole push API with values
//! read with `read_volatile` from statics, so the optimiser can assume
//! nothing about them and keeps every path a real input could take. The
//! panic handler calls a function that exists nowhere: if any panic is
//! reachable after LTO, the link fails naming that symbol. Built as a user's
//! release firmware is (overflow checks off; see Cargo.toml to turn them on).
//!
//! With the feature `report` the handler links instead, and `check` lists
//! the call sites of the panic machinery in the image by source line.
#![no_std]
#![no_main]

use core::hint::black_box;
use core::ptr::read_volatile;

use cortex_m_rt::entry;
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, DelayCompensatedNav, DelayCompensatedNavConfig,
    DelayMode, Ekf16, Ekf16Config, Geodetic, Gps, GpsPosition, Imu, Mag, Navigator,
};
use nalgebra::Vector3;

static F32S: [f32; 32] = [0.0; 32];
static F64S: [f64; 4] = [0.0; 4];
static U64S: [u64; 8] = [0; 8];
static FLAGS: [bool; 8] = [false; 8];

fn f(i: usize) -> f32 {
    // SAFETY: an in-bounds element of a static.
    unsafe { read_volatile(&F32S[i]) }
}

fn d(i: usize) -> f64 {
    // SAFETY: as above.
    unsafe { read_volatile(&F64S[i]) }
}

fn u(i: usize) -> u64 {
    // SAFETY: as above.
    unsafe { read_volatile(&U64S[i]) }
}

fn flag(i: usize) -> bool {
    // SAFETY: as above.
    unsafe { read_volatile(&FLAGS[i]) }
}

fn v3(i: usize) -> Vector3<f32> {
    Vector3::new(f(i), f(i + 1), f(i + 2))
}

fn optional(i: usize) -> Option<f32> {
    flag(i % 8).then(|| f(i))
}

fn ekf_config() -> Ekf16Config<f32> {
    Ekf16Config {
        gyro_noise_density: f(20),
        accel_noise_density: f(21),
        gps_horizontal_std_m: f(22),
        gps_vertical_std_m: f(23),
        gps_velocity_std_m_s: f(24),
        mag_inclination_rad: f(25),
        mag_noise_variance: f(26),
        lever_arm_m: v3(27),
        max_imu_step_us: u(5),
        gps_reset_timeout_us: u(6),
        ..Ekf16Config::default()
    }
}

/// One call of every push and the estimate, with arbitrary values.
fn feed<N: Navigator<f32>>(nav: &mut N) {
    let imu = Imu {
        t_us: u(0),
        gyro_rad_s: v3(0),
        accel_m_s2: v3(3),
    };
    let _ = black_box(nav.push_imu(&imu));
    let mag = Mag {
        t_us: u(1),
        field_body: v3(6),
    };
    let _ = black_box(nav.push_mag(&mag));
    let position = if flag(0) {
        GpsPosition::Ned(v3(9))
    } else {
        GpsPosition::Geodetic(Geodetic {
            lat_deg: d(0),
            lon_deg: d(1),
            alt_m: d(2),
        })
    };
    let gps = Gps {
        t_us: u(2),
        position,
        velocity_ned_m_s: v3(12),
        horizontal_accuracy_m: optional(15),
        vertical_accuracy_m: optional(16),
        speed_accuracy_m_s: optional(17),
    };
    let _ = black_box(nav.push_gps(&gps));
    black_box(nav.estimate());
}

#[inline(never)]
fn ekf16() {
    if let Ok(mut ekf) = Ekf16::new(ekf_config()) {
        while flag(1) {
            feed(&mut ekf);
        }
        black_box(ekf.nav_state());
    }
}

#[inline(never)]
fn aekf17() {
    let config = AugmentedEkf17Config {
        initial_delay_s: f(18),
        max_delay_s: f(19),
        ..AugmentedEkf17Config::with_nav(ekf_config())
    };
    if let Ok(mut aekf) = AugmentedEkf17::new(config) {
        while flag(2) {
            feed(&mut aekf);
            black_box((aekf.delay_s(), aekf.delay_std_s(), aekf.delay_clamps()));
            let _ = black_box(aekf.set_delay(f(30), f(31)));
        }
    }
}

#[inline(never)]
fn nav() {
    let mode = if flag(3) {
        DelayMode::Estimated { initial_s: f(18) }
    } else {
        DelayMode::Fixed { delay_s: f(18) }
    };
    let mut config = DelayCompensatedNavConfig {
        ekf: ekf_config(),
        mode,
        imu_rate_hz: f(30),
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.delay_min_s = f(31);
    config.delay_loop.fusion.delay_max_s = f(19);
    if let Ok(mut nav) = DelayCompensatedNav::<f32>::new(config) {
        while flag(4) {
            feed(&mut nav);
            black_box((nav.delay_s(), nav.delay_std_s(), nav.sensor_delays()));
            black_box((nav.group_delays_s(), nav.last_delay_update().copied()));
            black_box((nav.horizon_estimate(), nav.acceleration_ned_m_s2()));
        }
    }
}

#[entry]
fn main() -> ! {
    ekf16();
    aekf17();
    nav();
    loop {
        core::hint::spin_loop();
    }
}

#[cfg(not(feature = "report"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    unsafe extern "C" {
        /// Defined nowhere: a reachable panic fails the link on this name.
        fn delaynav_no_panic_check_found_a_reachable_panic() -> !;
    }
    // SAFETY: never linked; see above.
    unsafe { delaynav_no_panic_check_found_a_reachable_panic() }
}

/// Uses its argument, so that the panic functions stay distinct (an
/// unused message lets the linker fold them into one) and each site shows
/// its own kind.
#[cfg(feature = "report")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    black_box(info);
    loop {}
}

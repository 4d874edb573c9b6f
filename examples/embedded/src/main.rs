//! The delay-compensated navigator in a Cortex-M4F firmware (`no_std`,
//! `no_main`), as a drone or rover would embed it:
//!
//! - the navigator in a `static` (`critical_section::Mutex<RefCell<..>>`,
//!   shared by the IMU interrupt and the main loop), holding the `const`
//!   blank value and configured where it lies: no stack copy of it ever;
//! - its history `HIST` sized at compile time from the delay range and the
//!   IMU rate by the rule `configure` checks;
//! - the firmware's own driver types fed through the sensor traits
//!   (`drivers.rs`: raw counts converted in the trait methods);
//! - the IMU's data-ready interrupt (here SysTick at 1 kHz) pushing each
//!   sample, and the magnetometer and GPS readings that came with it;
//! - a refused sample treated as routine: counted, never `?` or `unwrap`;
//! - the main loop reading `estimate()` and `health()`.
//!
//! Runs in QEMU on synthetic sensors (`world.rs`, the stand-in for the
//! hardware): `./run` (or `cargo run --release`). It prints a line every
//! 10 s, then a summary, and ends with `PASS`, or `FAIL` and a non-zero
//! exit when the navigator gave no estimate, a non-finite one, one far from
//! the truth, or refused other samples than the glitches planted.
#![no_std]
#![no_main]

mod drivers;
mod world;

use core::cell::{Cell, RefCell};
use core::mem::size_of;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use critical_section::Mutex;
use delaynav::{
    AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, DelayStatus, Error,
    Estimate, Geodetic, Health, Navigator, history_len,
};
use world::{Glitches, Truth, World};

/// The largest GPS delay the navigator must handle, s: the receiver's
/// latency (0.05-0.3 s for most) with a margin. The delay loop searches
/// `[0, MAX_DELAY_S]`.
const MAX_DELAY_S: f32 = 0.4;
/// The IMU's output data rate, Hz.
const IMU_RATE_HZ: f32 = world::IMU_RATE_HZ as f32;

/// The history: the IMU samples `configure` asks for to reach back
/// `MAX_DELAY_S` at `IMU_RATE_HZ` (413 for 0.4 s at 1 kHz). With IMU
/// whitening filters configured, add their group delay to the delay.
const HIST: usize = history_len(MAX_DELAY_S as f64, IMU_RATE_HZ as f64);

type Nav = DelayCompensatedNav<f32, HIST>;

/// RAM set aside for the navigator on this part (128 KB of SRAM).
const NAV_RAM_BUDGET: usize = 24 * 1024;
const _: () = assert!(
    size_of::<Nav>() <= NAV_RAM_BUDGET,
    "the navigator outgrew its RAM budget: shorten MAX_DELAY_S or lower the IMU rate"
);

/// The navigator. `BLANK` is a `const` of zero bytes: the static goes to
/// `.bss` (nothing in flash, nothing copied through the stack) and refuses
/// every sample until `configure` succeeds.
static NAV: Mutex<RefCell<Nav>> = Mutex::new(RefCell::new(Nav::BLANK));

/// Samples the navigator refused, per sensor, written by the interrupt.
static REFUSED: Mutex<Cell<Refused>> = Mutex::new(Cell::new(Refused::NONE));

/// The synthetic world's truth and planted glitches at the newest sample
/// (to check the estimate; a real firmware has no truth).
static TRUTH: Mutex<Cell<(Truth, Glitches)>> = Mutex::new(Cell::new((
    Truth {
        t_us: 0,
        position_m: [0.0; 3],
        velocity_m_s: [0.0; 3],
        yaw_rad: 0.0,
    },
    Glitches {
        imu: 0,
        mag: 0,
        gps: 0,
    },
)));

/// IMU interrupts so far.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// SysTick counts the core clock: 168 MHz on the STM32F405.
const CORE_HZ: u32 = 168_000_000;
/// A status line every this many IMU samples (10 s).
const REPORT_EVERY: u32 = 10 * world::IMU_RATE_HZ;
/// Length of the run in IMU samples (60 s).
const RUN_SAMPLES: u32 = 60 * world::IMU_RATE_HZ;

/// Refusals of one sensor: how many, and the newest reason.
#[derive(Clone, Copy)]
struct Count {
    n: u32,
    last: Option<Error>,
}

impl Count {
    const NONE: Self = Self { n: 0, last: None };

    fn add(&mut self, e: Error) {
        self.n += 1;
        self.last = Some(e);
    }
}

#[derive(Clone, Copy)]
struct Refused {
    imu: Count,
    mag: Count,
    gps: Count,
}

impl Refused {
    const NONE: Self = Self {
        imu: Count::NONE,
        mag: Count::NONE,
        gps: Count::NONE,
    };
}

/// The navigator's configuration for this vehicle.
fn nav_config() -> DelayCompensatedNavConfig<f32> {
    let mut config = DelayCompensatedNavConfig {
        // Start the delay loop from the receiver's datasheet latency; it
        // measures the real one online.
        mode: DelayMode::Estimated { initial_s: 0.15 },
        imu_rate_hz: IMU_RATE_HZ,
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.delay_max_s = MAX_DELAY_S;
    // The local field (from a world magnetic model) and the home point.
    config.ekf.mag_inclination_rad = world::INCLINATION_RAD;
    config.ekf.mag_declination_rad = world::DECLINATION_RAD;
    config.ekf.origin = Some(Geodetic {
        lat_deg: f64::from(world::HOME_LAT_E7) * 1e-7,
        lon_deg: f64::from(world::HOME_LON_E7) * 1e-7,
        alt_m: f64::from(world::HOME_H_MSL_MM) * 1e-3,
    });
    config
}

/// The IMU's data-ready interrupt (SysTick stands in for its EXTI line):
/// reads the sensors and pushes what they delivered.
#[exception]
fn SysTick() {
    // The hardware of this example; a firmware reads its drivers here.
    static mut WORLD: World = World::new();
    let readings = WORLD.step();
    critical_section::with(|cs| {
        let mut nav = NAV.borrow_ref_mut(cs);
        let mut refused = REFUSED.borrow(cs).get();
        // A refusal is the navigator guarding its state against a bad or
        // out-of-order sample: it is counted (and in `health().refusals`),
        // the state is unchanged, and the next sample is pushed as usual.
        if let Err(e) = nav.push_imu(&readings.imu) {
            refused.imu.add(e);
        }
        if let Some(mag) = &readings.mag
            && let Err(e) = nav.push_mag(mag)
        {
            refused.mag.add(e);
        }
        if let Some(fix) = &readings.gps
            && let Err(e) = nav.push_gps(fix)
        {
            refused.gps.add(e);
        }
        REFUSED.borrow(cs).set(refused);
        TRUTH.borrow(cs).set((WORLD.truth(), WORLD.glitches()));
    });
    TICKS.fetch_add(1, Ordering::Release);
}

/// What the main loop reads, at one instant.
struct Snapshot {
    estimate: Option<Estimate<f32>>,
    health: Health<f32>,
    refused: Refused,
    truth: Truth,
    glitches: Glitches,
}

fn snapshot() -> Snapshot {
    critical_section::with(|cs| {
        let nav = NAV.borrow_ref(cs);
        let (truth, glitches) = TRUTH.borrow(cs).get();
        Snapshot {
            estimate: nav.estimate(),
            health: nav.health(),
            refused: REFUSED.borrow(cs).get(),
            truth,
            glitches,
        }
    })
}

/// Errors of an estimate against the truth: horizontal position (m),
/// velocity (m/s), tilt and heading (deg).
struct Errors {
    position_m: f32,
    velocity_m_s: f32,
    tilt_deg: f32,
    heading_deg: f32,
}

fn errors(e: &Estimate<f32>, truth: &Truth) -> Errors {
    let p = &e.position_ned_m;
    let v = &e.velocity_ned_m_s;
    let dp = [p.x - truth.position_m[0], p.y - truth.position_m[1]];
    let dv = [
        v.x - truth.velocity_m_s[0],
        v.y - truth.velocity_m_s[1],
        v.z - truth.velocity_m_s[2],
    ];
    let euler = e.euler_rad();
    // The rover is level: roll and pitch are the tilt errors.
    let tilt = libm::sqrtf(euler.x * euler.x + euler.y * euler.y);
    let mut yaw = euler.z - truth.yaw_rad;
    yaw = libm::atan2f(libm::sinf(yaw), libm::cosf(yaw));
    Errors {
        position_m: libm::sqrtf(dp[0] * dp[0] + dp[1] * dp[1]),
        velocity_m_s: libm::sqrtf(dv.iter().map(|d| d * d).sum()),
        tilt_deg: tilt.to_degrees(),
        heading_deg: yaw.abs().to_degrees(),
    }
}

fn is_finite(e: &Estimate<f32>) -> bool {
    e.attitude.coords.iter().all(|x| x.is_finite())
        && e.position_ned_m.iter().all(|x| x.is_finite())
        && e.velocity_ned_m_s.iter().all(|x| x.is_finite())
        && e.delay_s.is_some_and(f32::is_finite)
}

/// The delay loop's state in a few words.
fn delay_status(h: &Health<f32>) -> &'static str {
    match h.delay.status {
        None => "fixed",
        Some(DelayStatus::WaitingForData) => "waiting for data",
        Some(DelayStatus::WaitingForMotion) => "waiting for motion",
        Some(DelayStatus::Acquiring) => "acquiring",
        Some(DelayStatus::Locked) => "locked",
        Some(DelayStatus::BelowRange { .. }) => "below its range",
        Some(DelayStatus::AboveRange { .. }) => "above its range",
    }
}

fn status_line(s: &Snapshot) {
    let h = &s.health;
    let t_s = s.truth.t_us as f32 * 1e-6;
    match &s.estimate {
        Some(e) => {
            let err = errors(e, &s.truth);
            let p = &e.position_ned_m;
            hprintln!(
                "t={:5.1} s {:?}: position N {:7.2} E {:7.2} D {:5.2} m (error {:.2} m), \
                 velocity error {:.2} m/s, tilt error {:.2} deg, heading error {:.2} deg, \
                 delay {:.3} s ({})",
                t_s,
                h.alignment,
                p.x,
                p.y,
                p.z,
                err.position_m,
                err.velocity_m_s,
                err.tilt_deg,
                err.heading_deg,
                h.delay.delay_s,
                delay_status(h),
            );
        }
        None => hprintln!("t={:5.1} s {:?}: no estimate yet", t_s, h.alignment),
    }
}

/// Bytes of the stack used so far: cortex-m-rt painted it before `main`.
fn stack_peak() -> (usize, usize) {
    unsafe extern "C" {
        static _stack_start: u32;
        static _stack_end: u32;
    }
    // The words between the linker's two symbols are the stack.
    let (top, bottom) = (
        &raw const _stack_start as usize,
        &raw const _stack_end as usize,
    );
    let mut p = bottom;
    // SAFETY: words of the stack region, read below the live frames.
    while p < top && unsafe { (p as *const u32).read_volatile() } == cortex_m_rt::STACK_PAINT_VALUE
    {
        p += 4;
    }
    (top - p, top - bottom)
}

/// The summary, the checks, and the exit code.
fn finish(s: &Snapshot) -> ! {
    let h = &s.health;
    let (stack, stack_room) = stack_peak();
    hprintln!(
        "navigator: DelayCompensatedNav<f32, {}> in a static, {} B (HIST = history_len({} s, {} Hz))",
        HIST,
        size_of::<Nav>(),
        MAX_DELAY_S,
        IMU_RATE_HZ,
    );
    hprintln!("stack: {} B used of {} B", stack, stack_room);
    hprintln!(
        "health: {:?}, valid: tilt {} heading {} velocity {} position {} delay {}; last reset {:?}",
        h.alignment,
        h.tilt_valid,
        h.heading_valid,
        h.velocity_valid,
        h.position_valid,
        h.delay_valid,
        h.last_reset,
    );
    hprintln!(
        "delay: {:.3} s +- {:.3} s ({}, {} valid updates); the receiver's latency is {:.3} s",
        h.delay.delay_s,
        h.delay.delay_std_s,
        delay_status(h),
        h.delay.valid_updates,
        world::GPS_DELAY_US as f32 * 1e-6
    );
    let r = &s.refused;
    for (name, count) in [("imu", &r.imu), ("mag", &r.mag), ("gps", &r.gps)] {
        match count.last {
            Some(e) => hprintln!("refused {}: {} (newest: {})", name, count.n, e),
            None => hprintln!("refused {}: 0", name),
        }
    }
    let g = &s.glitches;
    let n = &h.refusals;
    hprintln!(
        "planted glitches: imu {} mag {} gps {}; navigator's counters: imu_time {} mag_invalid {} \
         gps_invalid {} mag_averaged {}",
        g.imu,
        g.mag,
        g.gps,
        n.imu_time,
        n.mag_invalid,
        n.gps_invalid,
        n.mag_averaged,
    );
    let k = &h.refusals.horizon;
    hprintln!(
        "horizon EKF: gps position/velocity rejected {}/{}, mag rejected {}, disturbed {}, resets {}/{}",
        k.gps_position_rejected,
        k.gps_velocity_rejected,
        k.mag_rejected,
        k.mag_disturbed,
        k.gps_position_resets,
        k.gps_velocity_resets,
    );

    let mut failures = 0;
    let mut check = |ok: bool, what: &str| {
        if !ok {
            failures += 1;
            hprintln!("FAIL {}", what);
        }
    };
    match &s.estimate {
        None => check(false, "no estimate"),
        Some(e) if !is_finite(e) => check(false, "a non-finite estimate"),
        Some(e) => {
            let err = errors(e, &s.truth);
            hprintln!(
                "estimate at t = {} us: errors against the truth: position {:.2} m, velocity {:.3} m/s, \
                 tilt {:.2} deg, heading {:.2} deg",
                e.t_us,
                err.position_m,
                err.velocity_m_s,
                err.tilt_deg,
                err.heading_deg
            );
            check(e.t_us == s.truth.t_us, "the estimate is not at the present");
            check(err.position_m < 2.0, "position error 2 m or more");
            check(err.velocity_m_s < 0.5, "velocity error 0.5 m/s or more");
            check(err.tilt_deg < 2.0, "tilt error 2 deg or more");
            check(err.heading_deg < 5.0, "heading error 5 deg or more");
        }
    }
    check(h.alignment == AlignmentState::Aligned, "not aligned");
    check(
        h.tilt_valid && h.heading_valid && h.velocity_valid && h.position_valid && h.delay_valid,
        "a health flag is not valid",
    );
    let delay_error = h.delay.delay_s - world::GPS_DELAY_US as f32 * 1e-6;
    check(
        delay_error.abs() < 0.03,
        "delay 30 ms or more off the receiver's latency",
    );
    check(
        (r.imu.n, r.mag.n, r.gps.n) == (g.imu, g.mag, g.gps),
        "refusals other than the planted glitches",
    );
    check(
        (n.imu_time, n.mag_invalid, n.gps_invalid) == (g.imu, g.mag, g.gps),
        "the navigator's refusal counters disagree with the glitches",
    );
    check(stack < stack_room, "the stack overflowed its region");
    hprintln!(
        "RESULT size_of={} hist={} stack_peak={} failures={}",
        size_of::<Nav>(),
        HIST,
        stack,
        failures
    );
    if failures == 0 {
        hprintln!("PASS");
        debug::exit(debug::EXIT_SUCCESS);
    } else {
        debug::exit(debug::EXIT_FAILURE);
    }
    loop {
        cortex_m::asm::wfi();
    }
}

fn fail(what: &str, e: Error) -> ! {
    hprintln!("FAIL {}: {}", what, e);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    // Configure the navigator where it lies, before the interrupt starts:
    // a configuration it refuses (e.g. a history too short for the delay
    // range) is a firmware bug, reported once at start-up.
    if let Err(e) = critical_section::with(|cs| NAV.borrow_ref_mut(cs).configure(nav_config())) {
        fail("configure", e);
    }
    hprintln!(
        "navigator configured in place: {} B in .bss, history {} IMU samples for delays up to {} s at {} Hz",
        size_of::<Nav>(),
        HIST,
        MAX_DELAY_S,
        IMU_RATE_HZ
    );

    let Some(mut peripherals) = cortex_m::Peripherals::take() else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    let syst = &mut peripherals.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(CORE_HZ / world::IMU_RATE_HZ - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();

    let mut next_report = REPORT_EVERY;
    loop {
        cortex_m::asm::wfi();
        if TICKS.load(Ordering::Acquire) < next_report {
            continue;
        }
        if next_report >= RUN_SAMPLES {
            syst.disable_interrupt();
            syst.disable_counter();
        }
        let s = snapshot();
        status_line(&s);
        if next_report >= RUN_SAMPLES {
            finish(&s);
        }
        next_report += REPORT_EVERY;
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("FAIL panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

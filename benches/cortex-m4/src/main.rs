//! Cortex-M4F cost of every delaynav estimator, counted under QEMU.
//!
//! One run measures one estimator, named on the semihosting command line
//! (`-append "NAME DELAY_MS"`, e.g. `nav_estimated_f32 500`), over the
//! simulated samples `build.rs` embeds (10 s of the high scenario: 1 kHz
//! IMU, 100 Hz magnetometer, 10 Hz GPS delayed 0.2 s, in f32).
//!
//! # What is counted
//! - Instructions: SysTick runs from the core clock (168 MHz on
//!   netduinoplus2); under `qemu-system-arm -icount shift=0` each executed
//!   instruction advances virtual time by 1 ns, so ticks = 0.168 x
//!   instructions. The ratio is measured at start-up on a loop of known
//!   length and used to convert. SysTick is read before and after every push.
//! - Per IMU sample: the `push_imu` of sample `k` plus every magnetometer and
//!   GPS push that follows it before sample `k + 1` (the simulator stamps
//!   them with the same time step and orders them after the IMU sample).
//!   `estimate()` is counted apart, once per IMU sample.
//! - RAM: `size_of` of the estimator, which is constructed in place at the
//!   top of the part's 128 KB (WORK in `memory.x`) the way a user fills a
//!   `static`: the slot holds the estimator's `const` blank value (`BLANK`,
//!   what the linker puts in a `static`), then `configure` sets it up where
//!   it lies. Below it the thread stack (PSP) is painted, and the deepest
//!   overwritten word after construction and after the pushes gives the
//!   stack peak, construction (`configure`) included. With `stack` on the
//!   command line the estimator is instead a local of the thread's first
//!   frame (`BLANK` then `configure`), its `size_of` subtracted from the
//!   stack figures; with `outside` likewise, but the stack may also use the
//!   SRAM QEMU maps beyond the part's 128 KB: the counts of an estimator
//!   that does not fit. The stack grows towards 0x20000000: an overflow
//!   faults there, and the fault handler, on its own stack (MSP) beyond the
//!   128 KB, reports the estimator as not fitting (`OVERFLOW`) instead of
//!   letting it overwrite memory silently.
//! - Flash: everything loaded into flash minus the embedded samples.
//!
//! - Refusals: `imu_errors`, `mag_errors`, `gps_errors` count the pushes
//!   that returned an error; `no_estimate` the IMU samples after which
//!   `estimate()` had none; `final_estimate` (1 or 0) whether it had one
//!   after the last IMU sample (`report.py --check` requires it, and no more
//!   refusals than limits.json allows).
//!
//! Built with the feature `nav-only`, the image holds the navigator alone
//! (`ekf16_f32` and `aekf17_f32` are then unknown names): the layout of a
//! firmware that embeds only `DelayCompensatedNav`, whose frames LLVM
//! inlines differently (`run` reports its figures apart).
//!
//! Output lines (semihosting): `INFO ...`, then one of `RESULT ...`,
//! `OVERFLOW ...` (did not fit) or `FAULT ...`/`PANIC ...` (a failure);
//! every figure as `key=value`.
#![no_std]
#![no_main]

use core::arch::asm;
use core::hint::black_box;
use core::mem::{align_of, size_of};
use core::sync::atomic::{Ordering, compiler_fence};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use delaynav::nav::HISTORY_ORDER;
#[cfg(not(feature = "nav-only"))]
use delaynav::{AugmentedEkf17, AugmentedEkf17Config, Ekf16};
use delaynav::{
    DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, Ekf16Config, Error, Gps,
    GpsPosition, Imu, Mag, Navigator,
};
use nalgebra::Vector3;

/// Constants written by `build.rs` from the simulator.
mod sim {
    include!(concat!(env!("OUT_DIR"), "/sim.rs"));
}

/// The embedded samples (format in `build.rs`).
static EVENTS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/events.bin"));

/// Word painted over the free stack before a run.
const PAINT: u32 = 0xA5C3_5A3C;
/// SysTick is a 24-bit down-counter.
const SYST_MASK: u32 = 0x00FF_FFFF;
/// Iterations of the calibration loop (two instructions each).
const CALIBRATION_LOOPS: u32 = 100_000;
/// Below this much stack the estimator is not even tried, bytes.
const MIN_STACK: usize = 1024;

unsafe extern "C" {
    static _work_start: u32;
    static _work_end: u32;
    static _outside_end: u32;
    static __sidata: u32;
    static __sdata: u32;
    static __edata: u32;
}

/// What this run measures; kept in `.bss` (the RAM region), which a stack
/// overflow of the thread cannot reach, so the fault handler can read it.
#[derive(Clone, Copy)]
struct Task {
    name: &'static str,
    estimated: bool,
    max_delay_s: f32,
    placement: Placement,
    /// Address of the estimator's slot (unused on the stack).
    slot: usize,
    /// Top of the thread stack.
    stack_top: usize,
    size_of: usize,
    phase: &'static str,
}

/// Where the estimator lives while it runs.
#[derive(Clone, Copy, PartialEq)]
enum Placement {
    /// At the top of WORK, as in a `static`; the stack below it.
    Static,
    /// A local of the thread's first frame (no copy while it is built).
    Stack,
    /// A local as with `Stack`, with the stack reaching beyond the part's
    /// 128 KB into the SRAM QEMU maps above it (188 KB in all): the counts
    /// of an estimator that does not fit.
    Outside,
}

impl Placement {
    fn name(self) -> &'static str {
        match self {
            Placement::Static => "static",
            Placement::Stack => "stack",
            Placement::Outside => "outside",
        }
    }
}

static mut TASK: Task = Task {
    name: "",
    estimated: true,
    max_delay_s: 0.0,
    placement: Placement::Static,
    slot: 0,
    stack_top: 0,
    size_of: 0,
    phase: "start",
};

/// SysTick ticks per instruction, as `(ticks, instructions)` of the
/// calibration loop.
static mut CALIBRATION: (u64, u64) = (168, 1000);

fn task() -> Task {
    // SAFETY: single-threaded; no interrupt handler writes it.
    unsafe { TASK }
}

fn set_phase(phase: &'static str) {
    // SAFETY: as in `task`.
    unsafe { TASK.phase = phase }
}

fn addr_of_symbol(s: &'static u32) -> usize {
    s as *const u32 as usize
}

fn work_start() -> usize {
    // SAFETY: linker symbols; only their addresses are used.
    addr_of_symbol(unsafe { &_work_start })
}

fn work_end() -> usize {
    // SAFETY: as above.
    addr_of_symbol(unsafe { &_work_end })
}

fn outside_end() -> usize {
    // SAFETY: as above.
    addr_of_symbol(unsafe { &_outside_end })
}

/// Bytes of flash the image occupies, the embedded samples excluded.
fn flash_bytes() -> usize {
    // SAFETY: as above.
    let (sidata, sdata, edata) = unsafe {
        (
            addr_of_symbol(&__sidata),
            addr_of_symbol(&__sdata),
            addr_of_symbol(&__edata),
        )
    };
    sidata + (edata - sdata) - 0x0800_0000 - EVENTS.len()
}

fn now() -> u32 {
    SYST::get_current()
}

fn elapsed(t0: u32, t1: u32) -> u32 {
    t0.wrapping_sub(t1) & SYST_MASK
}

fn instructions(ticks: u64) -> u64 {
    // SAFETY: written once before any measurement.
    let (t, i) = unsafe { CALIBRATION };
    (ticks * i + t / 2) / t
}

/// Measures ticks per instruction on a loop of `2 x CALIBRATION_LOOPS`
/// instructions (`subs`, `bne`).
fn calibrate() -> (u64, u64) {
    let t0 = now();
    // SAFETY: a register-only loop.
    unsafe {
        asm!("1:", "subs {n}, #1", "bne 1b", n = inout(reg) CALIBRATION_LOOPS => _,
             options(nomem, nostack));
    }
    let t1 = now();
    (u64::from(elapsed(t0, t1)), 2 * u64::from(CALIBRATION_LOOPS))
}

/// The Ekf16 configuration of the reproduce example, in f32.
fn ekf_config() -> Ekf16Config<f32> {
    Ekf16Config {
        mag_inclination_rad: sim::MAG_INCLINATION_RAD,
        mag_declination_rad: sim::MAG_DECLINATION_RAD,
        mag_noise_variance: sim::MAG_NOISE_VAR,
        gps_horizontal_std_m: sim::GPS_POSITION_STD_M,
        gps_vertical_std_m: sim::GPS_POSITION_STD_M,
        gps_velocity_std_m_s: sim::GPS_VELOCITY_STD_M_S,
        initial_accel_bias_std_m_s2: sim::ACCEL_BIAS_STD_M_S2,
        initial_gyro_bias_std_rad_s: sim::GYRO_BIAS_STD_RAD_S,
        ..Ekf16Config::with_per_sample_imu_variances(
            sim::GYRO_VAR_RAD2_S2,
            sim::ACCEL_VAR_M2_S4,
            sim::IMU_RATE_HZ,
        )
    }
}

/// An estimator this firmware can construct in place from the task.
trait Subject: Navigator<f32> + Sized {
    /// The estimator's `const` blank value.
    const BLANK: Self;
    /// Sets the blank value up for the task where it lies.
    fn configure(&mut self, task: &Task) -> Result<(), Error>;
}

#[cfg(not(feature = "nav-only"))]
impl Subject for Ekf16<f32> {
    const BLANK: Self = Ekf16::BLANK;
    fn configure(&mut self, _: &Task) -> Result<(), Error> {
        Ekf16::configure(self, ekf_config())
    }
}

#[cfg(not(feature = "nav-only"))]
impl Subject for AugmentedEkf17<f32> {
    const BLANK: Self = AugmentedEkf17::BLANK;
    fn configure(&mut self, task: &Task) -> Result<(), Error> {
        let mut config = AugmentedEkf17Config::with_nav(ekf_config());
        config.initial_delay_s = sim::TRUE_DELAY_S;
        config.max_delay_s = task.max_delay_s;
        AugmentedEkf17::configure(self, config)
    }
}

impl<const HIST: usize> Subject for DelayCompensatedNav<f32, HIST> {
    const BLANK: Self = DelayCompensatedNav::BLANK;
    fn configure(&mut self, task: &Task) -> Result<(), Error> {
        let mode = if task.estimated {
            DelayMode::Estimated {
                initial_s: sim::TRUE_DELAY_S,
            }
        } else {
            DelayMode::Fixed {
                delay_s: sim::TRUE_DELAY_S,
            }
        };
        let mut config = DelayCompensatedNavConfig {
            ekf: ekf_config(),
            mode,
            imu_rate_hz: sim::IMU_RATE_HZ,
            ..DelayCompensatedNavConfig::default()
        };
        config.delay_loop.fusion.delay_max_s = task.max_delay_s;
        DelayCompensatedNav::configure(self, config)
    }
}

/// History length the navigator needs for a maximum delay of `ms` at 1 kHz:
/// `ceil(1.02 x samples) + HISTORY_ORDER + 2` as `new()` checks it, plus
/// one sample for rounding in f32.
const fn hist(ms: usize) -> usize {
    (ms * 102).div_ceil(100) + HISTORY_ORDER + 3
}

/// One embedded sample.
enum Event {
    Imu(Imu<f32>),
    Mag(Mag<f32>),
    Gps(Gps<f32>),
}

struct Reader {
    pos: usize,
}

impl Reader {
    fn word(&mut self) -> [u8; 4] {
        let b = &EVENTS[self.pos..self.pos + 4];
        self.pos += 4;
        [b[0], b[1], b[2], b[3]]
    }

    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.word())
    }

    fn vector(&mut self) -> Vector3<f32> {
        let (x, y, z) = (self.f32(), self.f32(), self.f32());
        Vector3::new(x, y, z)
    }

    fn optional(&mut self) -> Option<f32> {
        let v = self.f32();
        (!v.is_nan()).then_some(v)
    }

    fn next(&mut self) -> Option<Event> {
        let tag = *EVENTS.get(self.pos)?;
        self.pos += 1;
        let t_us = u64::from(u32::from_le_bytes(self.word()));
        Some(match tag {
            0 => Event::Imu(Imu {
                t_us,
                gyro_rad_s: self.vector(),
                accel_m_s2: self.vector(),
            }),
            1 => Event::Mag(Mag {
                t_us,
                field_body: self.vector(),
            }),
            _ => Event::Gps(Gps {
                t_us,
                position: GpsPosition::Ned(self.vector()),
                velocity_ned_m_s: self.vector(),
                horizontal_accuracy_m: self.optional(),
                vertical_accuracy_m: self.optional(),
                speed_accuracy_m_s: self.optional(),
            }),
        })
    }
}

/// Ticks of one kind of call.
#[derive(Default, Clone, Copy)]
struct Calls {
    n: u64,
    sum: u64,
    max: u64,
    errors: u64,
}

impl Calls {
    fn add(&mut self, ticks: u32, ok: bool) {
        self.n += 1;
        self.sum += u64::from(ticks);
        self.max = self.max.max(u64::from(ticks));
        self.errors += u64::from(!ok);
    }

    fn mean_instructions(&self) -> u64 {
        instructions(self.sum) / self.n.max(1)
    }
}

#[derive(Default)]
struct Stats {
    /// Per IMU sample, with the pushes attributed to it.
    samples: Calls,
    imu: Calls,
    mag: Calls,
    gps: Calls,
    estimate: Calls,
    /// Time of the most expensive IMU sample, us.
    max_sample_t_us: u64,
    /// Whether `estimate()` had an estimate after the last IMU sample.
    final_estimate: bool,
}

/// Pushes every embedded sample and counts the ticks of each call.
#[inline(never)]
fn measure<E: Subject>(estimator: &mut E, overhead: u32) -> Stats {
    let mut stats = Stats::default();
    let mut reader = Reader { pos: 0 };
    let mut group: Option<(u64, u32)> = None;
    while let Some(event) = reader.next() {
        let event = black_box(event);
        compiler_fence(Ordering::SeqCst);
        let t0 = now();
        let ok = match &event {
            Event::Imu(s) => black_box(estimator.push_imu(s)).is_ok(),
            Event::Mag(m) => black_box(estimator.push_mag(m)).is_ok(),
            Event::Gps(g) => black_box(estimator.push_gps(g)).is_ok(),
        };
        let t1 = now();
        compiler_fence(Ordering::SeqCst);
        let ticks = elapsed(t0, t1).saturating_sub(overhead);
        match &event {
            Event::Imu(s) => {
                if let Some((t_us, g)) = group.take() {
                    close_group(&mut stats, t_us, g);
                }
                group = Some((s.t_us, ticks));
                stats.imu.add(ticks, ok);
                let t0 = now();
                let estimate = black_box(estimator.estimate());
                let t1 = now();
                stats.final_estimate = estimate.is_some();
                stats.estimate.add(
                    elapsed(t0, t1).saturating_sub(overhead),
                    stats.final_estimate,
                );
            }
            Event::Mag(_) => {
                stats.mag.add(ticks, ok);
                group = group.map(|(t, g)| (t, g + ticks));
            }
            Event::Gps(_) => {
                stats.gps.add(ticks, ok);
                group = group.map(|(t, g)| (t, g + ticks));
            }
        }
    }
    if let Some((t_us, g)) = group {
        close_group(&mut stats, t_us, g);
    }
    stats
}

fn close_group(stats: &mut Stats, t_us: u64, ticks: u32) {
    if u64::from(ticks) > stats.samples.max {
        stats.max_sample_t_us = t_us;
    }
    stats.samples.add(ticks, true);
}

/// Builds the estimator in place in `slot`: the blank value is written
/// there (the image a linker gives a `static`; no stack copy of it), then
/// configured where it lies.
#[inline(never)]
fn construct<E: Subject>(slot: *mut E) -> Result<(), Error> {
    // SAFETY: `slot` is aligned for `E` and `size_of::<E>()` bytes of SRAM
    // that nothing else uses.
    let estimator = unsafe {
        slot.write(E::BLANK);
        &mut *slot
    };
    estimator.configure(&task())
}

fn paint(from: usize, to: usize) {
    let mut p = from;
    while p < to {
        // SAFETY: unused stack words of WORK.
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Bytes of stack below `top` that were written since the last paint.
fn stack_used(top: usize) -> usize {
    let mut p = work_start();
    // SAFETY: reads words of WORK below the live stack.
    while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    top - p
}

fn stack_pointer() -> usize {
    let sp: usize;
    // SAFETY: reads SP.
    unsafe { asm!("mov {}, sp", out(reg) sp, options(nomem, nostack)) };
    sp
}

/// Runs on the thread stack (PSP) that `launch` set up.
extern "C" fn thread<E: Subject>() -> ! {
    let t = task();
    set_phase("construct");
    if t.placement == Placement::Static {
        let slot = t.slot as *mut E;
        let constructed = construct::<E>(slot);
        let stack_construct = stack_used(t.stack_top);
        match constructed {
            // SAFETY: constructed above; nothing else refers to the slot.
            Ok(()) => run(unsafe { &mut *slot }, stack_construct, 0),
            Err(e) => fail_construct(e),
        }
    } else {
        on_stack::<E>()
    }
}

/// The estimator as a local of this frame: its bytes count as stack and
/// are subtracted from the stack figures.
#[inline(never)]
fn on_stack<E: Subject>() -> ! {
    let mut estimator = E::BLANK;
    let constructed = estimator.configure(&task());
    let stack_construct = stack_used(task().stack_top);
    match constructed {
        Ok(()) => run(&mut estimator, stack_construct, size_of::<E>()),
        Err(e) => fail_construct(e),
    }
}

fn fail_construct(e: Error) -> ! {
    hprintln!("ERROR name={} construct: {:?}", task().name, e);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

/// Measures the pushes and prints the RESULT line; `object_on_stack` bytes
/// of the stack figures are the estimator itself.
#[inline(never)]
fn run<E: Subject>(estimator: &mut E, stack_construct: usize, object_on_stack: usize) -> ! {
    let t = task();
    // Repaint what construction used, below this frame, for the pushes alone.
    paint(work_start(), stack_pointer() - 64);
    set_phase("push");
    let overhead = {
        let t0 = now();
        let t1 = now();
        elapsed(t0, t1)
    };
    let stats = measure(estimator, overhead);
    let stack_push = stack_used(t.stack_top).saturating_sub(object_on_stack);
    let stack_construct = stack_construct.saturating_sub(object_on_stack);
    set_phase("report");
    let s = &stats;
    hprintln!(
        "RESULT name={} max_delay_s={} placement={} size_of={} stack_peak={} \
         stack_peak_construct={} stack_peak_push={} mean={} max={} max_t_us={} imu_mean={} \
         imu_max={} mag_mean={} mag_max={} gps_mean={} gps_max={} estimate_mean={} \
         estimate_max={} imu_samples={} mag_samples={} gps_fixes={} imu_errors={} mag_errors={} \
         gps_errors={} no_estimate={} final_estimate={} overhead_ticks={} flash={}",
        t.name,
        t.max_delay_s,
        placement(&t),
        t.size_of,
        stack_construct.max(stack_push),
        stack_construct,
        stack_push,
        s.samples.mean_instructions(),
        instructions(s.samples.max),
        s.max_sample_t_us,
        s.imu.mean_instructions(),
        instructions(s.imu.max),
        s.mag.mean_instructions(),
        instructions(s.mag.max),
        s.gps.mean_instructions(),
        instructions(s.gps.max),
        s.estimate.mean_instructions(),
        instructions(s.estimate.max),
        s.imu.n,
        s.mag.n,
        s.gps.n,
        s.imu.errors,
        s.mag.errors,
        s.gps.errors,
        s.estimate.errors,
        u8::from(s.final_estimate),
        overhead,
        flash_bytes(),
    );
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

fn placement(t: &Task) -> &'static str {
    t.placement.name()
}

/// Places the estimator at the top of WORK, paints the stack below it,
/// and continues in `thread::<E>` on that stack.
fn launch<E: Subject>() -> ! {
    let size = size_of::<E>();
    let slot_size = size;
    let align = align_of::<E>().max(8);
    let (slot, top) = match task().placement {
        Placement::Static => {
            let slot = (work_end() - slot_size) & !(align - 1);
            (slot, slot)
        }
        Placement::Stack => (0, work_end() & !7),
        Placement::Outside => (0, outside_end() & !7),
    };
    // SAFETY: single-threaded set-up.
    unsafe {
        TASK.size_of = size;
        TASK.slot = slot;
        TASK.stack_top = top;
    }
    let t = task();
    hprintln!(
        "INFO name={} max_delay_s={} placement={} size_of={} stack_available={} work_bytes={}",
        t.name,
        t.max_delay_s,
        placement(&t),
        size,
        top.saturating_sub(work_start()),
        work_end() - work_start()
    );
    if top < work_start() + MIN_STACK {
        hprintln!(
            "OVERFLOW name={} max_delay_s={} placement={} size_of={} phase=layout",
            t.name,
            t.max_delay_s,
            placement(&t),
            size
        );
        debug::exit(debug::EXIT_SUCCESS);
    }
    paint(work_start(), top);
    let entry: extern "C" fn() -> ! = thread::<E>;
    // SAFETY: PSP points at the top of a painted, unused stack; the thread
    // never returns, so nothing of this frame is needed again.
    unsafe {
        asm!(
            "msr psp, {top}",
            "msr control, {control}",
            "isb",
            "bx {entry}",
            top = in(reg) top,
            control = in(reg) 2u32,
            entry = in(reg) entry,
            options(noreturn),
        )
    }
}

/// Reads `NAME DELAY_MS [static|stack|outside]` from the semihosting
/// command line (QEMU puts the kernel's path first).
fn command_line(buf: &mut [u8; 160]) -> (&str, u32, Placement) {
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    // SAFETY: the block points at `buf` and gives its length.
    let status = unsafe {
        cortex_m_semihosting::syscall1(
            cortex_m_semihosting::nr::GET_CMDLINE,
            block.as_mut_ptr() as usize,
        )
    };
    // SAFETY: the host wrote the length back into the block.
    let len = unsafe { core::ptr::read_volatile(&block[1]) };
    if status != 0 || len > buf.len() {
        return ("", 0, Placement::Static);
    }
    let line = core::str::from_utf8(&buf[..len]).unwrap_or("");
    let mut words = line.split_whitespace().skip(1);
    let name = words.next().unwrap_or("");
    let ms = words.next().and_then(|w| w.parse().ok()).unwrap_or(500);
    let placement = match words.next() {
        Some("stack") => Placement::Stack,
        Some("outside") => Placement::Outside,
        _ => Placement::Static,
    };
    (name, ms, placement)
}

/// Runs the navigator at the maximum delay `ms` when this build has it.
macro_rules! nav_at {
    ($ms:expr, [$($d:literal),*]) => {
        match $ms {
            $( $d => launch::<DelayCompensatedNav<f32, { hist($d) }>>(), )*
            _ => unsupported(),
        }
    };
}

fn launch_nav(ms: u32) -> ! {
    #[cfg(not(feature = "fallback"))]
    nav_at!(ms, [500]);
    #[cfg(feature = "fallback")]
    nav_at!(ms, [500, 450, 400, 350, 300, 250, 200]);
}

fn unsupported() -> ! {
    hprintln!("ERROR unknown estimator or maximum delay (this build)");
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    let mut peripherals = cortex_m::Peripherals::take().expect("taken once");
    let syst = &mut peripherals.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(SYST_MASK);
    syst.clear_current();
    syst.enable_counter();
    let calibration = calibrate();
    // SAFETY: single-threaded set-up.
    unsafe { CALIBRATION = calibration };

    let mut buf = [0u8; 160];
    let (name, ms, placement) = command_line(&mut buf);
    let (name, estimated): (&'static str, bool) = match name {
        "nav_estimated_f32" => ("nav_estimated_f32", true),
        "nav_fixed_f32" => ("nav_fixed_f32", false),
        "ekf16_f32" => ("ekf16_f32", true),
        "aekf17_f32" => ("aekf17_f32", true),
        _ => unsupported(),
    };
    // SAFETY: single-threaded set-up.
    unsafe {
        TASK.name = name;
        TASK.estimated = estimated;
        TASK.placement = placement;
        TASK.max_delay_s = ms as f32 / 1000.0;
    }
    hprintln!(
        "INFO calibration_ticks={} calibration_instructions={} samples_seconds={} seed={} imu_rate_hz={} mag_rate_hz={} gps_rate_hz={} \
         imu_samples={} mag_samples={} gps_fixes={} true_delay_s={} events_bytes={}",
        calibration.0,
        calibration.1,
        sim::SECONDS,
        sim::SEED,
        sim::IMU_RATE_HZ,
        sim::MAG_RATE_HZ,
        sim::GPS_RATE_HZ,
        sim::IMU_SAMPLES,
        sim::MAG_SAMPLES,
        sim::GPS_FIXES,
        sim::TRUE_DELAY_S,
        EVENTS.len()
    );
    match name {
        #[cfg(not(feature = "nav-only"))]
        "ekf16_f32" => launch::<Ekf16<f32>>(),
        #[cfg(not(feature = "nav-only"))]
        "aekf17_f32" => launch::<AugmentedEkf17<f32>>(),
        "nav_estimated_f32" | "nav_fixed_f32" => launch_nav(ms),
        _ => unsupported(),
    }
}

/// A fault: a stack overflow (the thread stack left SRAM, or the fault hit
/// while stacking onto it) is reported as `OVERFLOW`, anything else as
/// `FAULT`. Runs on the handler stack, without reading the faulted frame.
#[exception(trampoline = false)]
unsafe fn HardFault() -> ! {
    // SAFETY: System Control Block fault status registers (CFSR, HFSR,
    // MMFAR, BFAR) and the thread stack pointer.
    let (cfsr, hfsr, bfar) = unsafe {
        (
            core::ptr::read_volatile(0xE000_ED28 as *const u32),
            core::ptr::read_volatile(0xE000_ED2C as *const u32),
            core::ptr::read_volatile(0xE000_ED38 as *const u32),
        )
    };
    let psp = cortex_m::register::psp::read() as usize;
    let t = task();
    let stacking = cfsr & ((1 << 12) | (1 << 4)) != 0; // BFSR.STKERR, MMFSR.MSTKERR
    let bfar_valid = cfsr & (1 << 15) != 0;
    let below = psp < work_start() || (bfar_valid && (bfar as usize) < work_start());
    if stacking || below {
        hprintln!(
            "OVERFLOW name={} max_delay_s={} placement={} size_of={} phase={} stack_available={} \
             psp={:#x} cfsr={:#x} bfar={:#x}",
            t.name,
            t.max_delay_s,
            placement(&t),
            t.size_of,
            t.phase,
            t.stack_top.saturating_sub(work_start()),
            psp,
            cfsr,
            bfar
        );
        debug::exit(debug::EXIT_SUCCESS);
    } else {
        hprintln!(
            "FAULT name={} phase={} psp={:#x} cfsr={:#x} hfsr={:#x} bfar={:#x}",
            t.name,
            t.phase,
            psp,
            cfsr,
            hfsr,
            bfar
        );
        debug::exit(debug::EXIT_FAILURE);
    }
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("PANIC name={} {}", task().name, info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

//! The `const` blank values (`BLANK`) are all zero bytes: a mutable `static`
//! holding one (in a `Mutex`, as a firmware holds it) is laid out in `.bss`
//! (zeroed at start-up, nothing in flash), not in `.data` (an image in
//! flash copied to RAM). The check asks the linker: each static's address
//! must lie between the `__bss_start` and `_end` symbols that GNU ld and
//! lld define for an ELF executable. Anything in a blank value that is not
//! a zero byte (a `None` stored as a niche, a unit quaternion, a float 1)
//! moves the whole static to `.data`.
#![cfg(all(target_os = "linux", target_env = "gnu"))]

use std::sync::Mutex;

use delaynav::delay::DefaultDelayLoop;
use delaynav::nav::DelayCompensatedNav;
use delaynav::{AugmentedEkf17, Ekf16};

/// The firmware's history (a 0.5 s range at 1 kHz).
const HIST: usize = 520;

static NAV_F32: Mutex<DelayCompensatedNav<f32, HIST>> = Mutex::new(DelayCompensatedNav::BLANK);
static NAV_F64: Mutex<DelayCompensatedNav<f64>> = Mutex::new(DelayCompensatedNav::BLANK);
static EKF16_F32: Mutex<Ekf16<f32>> = Mutex::new(Ekf16::BLANK);
static EKF16_F64: Mutex<Ekf16<f64>> = Mutex::new(Ekf16::BLANK);
static AEKF17_F32: Mutex<AugmentedEkf17<f32>> = Mutex::new(AugmentedEkf17::BLANK);
static AEKF17_F64: Mutex<AugmentedEkf17<f64>> = Mutex::new(AugmentedEkf17::BLANK);
static DELAY_LOOP_F32: Mutex<DefaultDelayLoop<f32>> = Mutex::new(DefaultDelayLoop::BLANK);
static DELAY_LOOP_F64: Mutex<DefaultDelayLoop<f64>> = Mutex::new(DefaultDelayLoop::BLANK);

unsafe extern "C" {
    /// First byte of `.bss` (linker-defined).
    static __bss_start: u8;
    /// First byte after `.bss` (linker-defined).
    static _end: u8;
}

/// Whether all of `value` lies in `.bss`.
fn in_bss<V>(value: &'static V) -> bool {
    let start = &raw const __bss_start as usize;
    let end = &raw const _end as usize;
    let at = value as *const V as usize;
    start <= at && at + size_of::<V>() <= end
}

#[test]
fn blank_values_are_zero_bytes() {
    let placed = [
        ("DelayCompensatedNav<f32, 520>", in_bss(&NAV_F32)),
        ("DelayCompensatedNav<f64>", in_bss(&NAV_F64)),
        ("Ekf16<f32>", in_bss(&EKF16_F32)),
        ("Ekf16<f64>", in_bss(&EKF16_F64)),
        ("AugmentedEkf17<f32>", in_bss(&AEKF17_F32)),
        ("AugmentedEkf17<f64>", in_bss(&AEKF17_F64)),
        ("DefaultDelayLoop<f32>", in_bss(&DELAY_LOOP_F32)),
        ("DefaultDelayLoop<f64>", in_bss(&DELAY_LOOP_F64)),
    ];
    let not_zero: Vec<&str> = placed
        .iter()
        .filter(|(_, bss)| !bss)
        .map(|(name, _)| *name)
        .collect();
    assert!(
        not_zero.is_empty(),
        "blank values not all zero bytes (a static of them is in .data): {not_zero:?}"
    );
}

/// The check can fail: a static that is not zero is not found in `.bss`.
#[test]
fn a_static_that_is_not_zero_is_not_in_bss() {
    static ONE: Mutex<[u64; 64]> = Mutex::new([1; 64]);
    static ZERO: Mutex<[u64; 64]> = Mutex::new([0; 64]);
    assert!(!in_bss(&ONE));
    assert!(in_bss(&ZERO));
}

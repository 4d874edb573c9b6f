//! The push API of every estimator (`Ekf16`, `AugmentedEkf17`,
//! `DelayCompensatedNav` with the delay fixed and estimated; `f32` and `f64`)
//! driven by the state machine of `tests/push_api.rs`: the fuzz input seeds
//! proptest's RNG, which draws one case of the machine (a calm start, then
//! IMU, GPS and magnetometer pushes with NaN, inf, huge values, time jumps
//! both ways, duplicates, `estimate`, `reset`), so the inputs and the checks
//! are the machine's own: no panic, a finite sound state after every call,
//! every refusal counted. libFuzzer keeps the inputs whose case reaches new
//! code; a crash prints the case.
//! The time steps are the full machine's: jumps ahead of hours, `u64::MAX`
//! and anywhere.
#![no_main]

#[path = "../../tests/push_api.rs"]
#[allow(dead_code)]
mod push_api;

use libfuzzer_sys::fuzz_target;
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// A ChaCha seed from the whole input: its FNV-1a hash, stretched by
/// splitmix64. (Proptest's pass-through RNG, which hands the bytes over as
/// they are, never finished generating a case here, inside rand's integer
/// samplers, even with 64 KiB of pseudo-random bytes appended to the input.)
fn seed(data: &[u8]) -> [u8; 32] {
    let mut state = data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    let mut seed = [0u8; 32];
    for chunk in seed.chunks_exact_mut(8) {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        chunk.copy_from_slice(&(z ^ (z >> 31)).to_le_bytes());
    }
    seed
}

fuzz_target!(|data: &[u8]| {
    let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &seed(data));
    let mut runner = TestRunner::new_with_rng(Config::default(), rng);
    let Ok(tree) = push_api::case(true).new_tree(&mut runner) else {
        return;
    };
    let (start, ops) = tree.current();
    let failures = push_api::every_estimator(start, &ops);
    assert!(
        failures.is_empty(),
        "{failures:#?}\ncase: start {start:?}, ops {ops:?}"
    );
});

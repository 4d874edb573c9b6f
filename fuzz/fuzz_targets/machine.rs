//! The push-API machine of `tests/push_api.rs`, driven by operations decoded
//! from the fuzz input (`tests/support/fuzz_input.rs` has the layout, the
//! decoder and the encoder of the regression seeds), so that a mutation of
//! one byte changes one operation, one value or one time step (libFuzzer's
//! coverage guidance can steer).
//!
//! The checks are the machine's, after every call: no panic, a finite,
//! sound state, every refusal counted (`tests/push_api.rs`).

#[path = "../../tests/push_api.rs"]
#[allow(dead_code)]
pub(crate) mod push_api;

use push_api::fuzz_input::{self, Input, STARTS_MS, Start};
use std::collections::HashMap;
use std::sync::Mutex;

/// The start and the operations of an input.
pub(crate) fn decode(data: &[u8]) -> Option<Input> {
    fuzz_input::decode(data)
}

/// The saved starts of one estimator (fresh and after each calm flight of
/// [`STARTS_MS`]), with the newest time pushed.
pub(crate) fn starts<T: delaynav::Scalar, S: push_api::Subject<T> + Clone>(
    make: fn() -> S,
) -> Vec<(S, u64)> {
    STARTS_MS
        .iter()
        .map(|ms| {
            let driver =
                push_api::replay(make(), *ms, &[]).expect("the calm start passes the checks");
            driver.into_parts()
        })
        .collect()
}

/// The other calm starts (`Start::Calm`), each flown once per process
/// (a mutation repeats a start byte: flying it in every execution made
/// the runs slow).
pub(crate) type CalmStarts<S> = Mutex<Option<HashMap<u32, (S, u64)>>>;

/// One case from a saved start, or from another calm start (flown once,
/// then cloned); panics (a finding) with the operations.
pub(crate) fn run<T: delaynav::Scalar, S: push_api::Subject<T> + Clone>(
    make: fn() -> S,
    starts: &[(S, u64)],
    calm: &CalmStarts<S>,
    input: &Input,
    name: &str,
) {
    let (s, cursor) = match input.start {
        Start::Saved(i) => starts[i % starts.len()].clone(),
        Start::Calm(ms) => {
            let mut cache = calm.lock().unwrap_or_else(|e| e.into_inner());
            let cache = cache.get_or_insert_with(HashMap::new);
            cache
                .entry(ms)
                .or_insert_with(|| {
                    push_api::replay(make(), Some(ms), &[])
                        .expect("the calm start passes the checks")
                        .into_parts()
                })
                .clone()
        }
    };
    let result = push_api::replay_from(s, cursor, &input.ops);
    if let Err(e) = result {
        panic!(
            "{name}: {e}\nstart {:?} (calm ms {:?}), ops {:?}",
            input.start,
            input.start.calm_ms(),
            input.ops
        );
    }
}

/// A fuzz target for one estimator: `$make32` and `$make64` build it in
/// each precision (functions of `push_api`'s `f32_` and `f64_` modules).
macro_rules! estimator_target {
    ($name:literal, $ty32:ty, $make32:path, $ty64:ty, $make64:path) => {
        use std::sync::OnceLock;

        static STARTS_32: OnceLock<Vec<($ty32, u64)>> = OnceLock::new();
        static STARTS_64: OnceLock<Vec<($ty64, u64)>> = OnceLock::new();
        static CALM_32: machine::CalmStarts<$ty32> = std::sync::Mutex::new(None);
        static CALM_64: machine::CalmStarts<$ty64> = std::sync::Mutex::new(None);

        libfuzzer_sys::fuzz_target!(|data: &[u8]| {
            let Some(input) = machine::decode(data) else {
                return;
            };
            if input.f64 {
                let starts = STARTS_64.get_or_init(|| machine::starts($make64));
                machine::run($make64, starts, &CALM_64, &input, concat!("f64 ", $name));
            } else {
                let starts = STARTS_32.get_or_init(|| machine::starts($make32));
                machine::run($make32, starts, &CALM_32, &input, concat!("f32 ", $name));
            }
        });
    };
}

//! The push-API machine of `tests/push_api.rs`, driven by operations decoded
//! from the fuzz input, so that a mutation of one byte changes one
//! operation, one value or one time step (libFuzzer's coverage guidance can
//! steer).
//!
//! Layout of an input:
//! - byte 0, the start: bit 0 the precision (0 `f32`, 1 `f64`), bits 1-2 a
//!   saved state to start from (fresh, or after 0.3, 1 or 2.5 s of the calm
//!   flight of `tests/push_api.rs`, computed once per process and cloned:
//!   the executions do not fly the calm start again);
//! - then operations, one tag byte each (its low four bits) and the bytes
//!   of its values, until the input ends (at most [`MAX_OPS`]):
//!
//! | tag | operation | bytes |
//! |---|---|---|
//! | 0-5 | IMU sample | time, 3 gyro values, 3 accelerometer values |
//! | 6-8 | GPS fix | time, frame (even NED, odd geodetic), 3 position, 3 velocity, accuracy mask, its values |
//! | 9-10 | magnetometer sample | time, 3 values |
//! | 11 | `estimate()` checked | - |
//! | 12 | `health()` checked | - |
//! | 13 | `reset()` | - |
//! | 14 | `configure` with one field changed | field, scale or value |
//! | 15 | calm flight | duration (1-64 ms) |
//!
//! A value is one byte: below 224, a plausible value (`center ± spread` in
//! 224 steps); from 224, one of 31 hostile values (NaN, infinities, the largest
//! and smallest floats, ...) or the next eight bytes as an `f64`'s bits.
//! A time is one tag byte ([`time`]): steps near the IMU period, gaps, a
//! duplicate, steps back, hours ahead, `u64::MAX` and raw stamps.
//!
//! The checks are the machine's, after every call: no panic, a finite,
//! sound state, every refusal counted (`tests/push_api.rs`).

#[path = "../../tests/push_api.rs"]
#[allow(dead_code)]
pub(crate) mod push_api;

use push_api::{Op, Position, Setting, Time};

/// The most operations decoded from one input.
pub(crate) const MAX_OPS: usize = 256;
/// The starts a case may begin from, ms of calm flight (`None`: fresh).
pub(crate) const STARTS_MS: [Option<u32>; 4] = [None, Some(300), Some(1_000), Some(2_500)];

const GRAVITY: f64 = 9.806_65;

/// More values no sensor should report, after the machine's
/// (`push_api::HOSTILE`, `push_api::LARGEST`): a value byte from 224 picks
/// one of the three lists in that order.
const MORE_HOSTILE: [f64; 20] = [
    -0.0,
    -1e-30,
    -1e4,
    1e9,
    f32::MIN_POSITIVE as f64,
    f64::MIN,
    f64::MIN_POSITIVE,
    5e-324,
    1e15,
    -1e15,
    3.4e38,
    1e200,
    1e-200,
    100.0,
    -100.0,
    1e6,
    0.5,
    2.0,
    -1.0,
    1e-6,
];

/// The `i`-th hostile value (`i` < 31).
fn hostile(i: usize) -> f64 {
    let (a, b) = (push_api::HOSTILE.len(), push_api::LARGEST.len());
    match i {
        i if i < a => push_api::HOSTILE[i],
        i if i < a + b => push_api::LARGEST[i - a],
        i => MORE_HOSTILE[(i - a - b) % MORE_HOSTILE.len()],
    }
}

/// The input, read front to back; `None` once it is exhausted.
pub(crate) struct Bytes<'a>(&'a [u8]);

impl<'a> Bytes<'a> {
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Bytes(data)
    }

    pub(crate) fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }

    pub(crate) fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes([self.u8()?, self.u8()?]))
    }

    pub(crate) fn u64(&mut self) -> Option<u64> {
        let (head, rest) = self.0.split_first_chunk::<8>()?;
        self.0 = rest;
        Some(u64::from_le_bytes(*head))
    }

    /// One value (module docs).
    pub(crate) fn value(&mut self, center: f64, spread: f64) -> Option<f64> {
        let tag = self.u8()?;
        Some(match tag {
            0..=223 => center + spread * (f64::from(tag) - 111.5) / 111.5,
            255 => f64::from_bits(self.u64()?),
            _ => hostile(usize::from(tag - 224)),
        })
    }

    pub(crate) fn vec3(&mut self, center: [f64; 3], spread: f64) -> Option<[f64; 3]> {
        Some([
            self.value(center[0], spread)?,
            self.value(center[1], spread)?,
            self.value(center[2], spread)?,
        ])
    }

    /// One time step (module docs).
    pub(crate) fn time(&mut self) -> Option<Time> {
        let tag = self.u8()?;
        let tag64 = u64::from(tag);
        Some(match tag {
            // Near the 1 ms IMU period: 360 to 1,630 µs.
            0..=127 => Time::After(1_000 + tag64 * 10 - 640),
            // Gaps of 10 ms to 0.48 s.
            128..=175 => Time::After((tag64 - 127) * 10_000),
            // Up to 65 s.
            176..=191 => Time::After(u64::from(self.u16()?) * 1_000),
            192..=199 => Time::Same,
            200..=215 => Time::Before((tag64 - 199) * 1_000),
            216..=223 => Time::Before(u64::from(self.u16()?) * 1_000),
            // Hours ahead.
            224..=231 => Time::After((tag64 - 223) * 3_600_000_000),
            232..=239 => Time::At(u64::MAX - (tag64 - 232)),
            240..=247 => Time::At(self.u64()?),
            _ => Time::Before(self.u64()?),
        })
    }

    /// A reported accuracy: absent unless `present`, else a value near 1.
    fn accuracy(&mut self, present: bool) -> Option<Option<f64>> {
        if present {
            Some(Some(self.value(5.0, 5.0)?))
        } else {
            Some(None)
        }
    }

    /// One operation (module docs).
    pub(crate) fn op(&mut self) -> Option<Op> {
        let tag = self.u8()? & 0x0f;
        Some(match tag {
            0..=5 => Op::Imu {
                t: self.time()?,
                gyro: self.vec3([0.0; 3], 0.5)?,
                accel: self.vec3([0.0, 0.0, -GRAVITY], 3.0)?,
            },
            6..=8 => {
                let t = self.time()?;
                let position = if self.u8()? % 2 == 0 {
                    Position::Ned(self.vec3([0.0; 3], 100.0)?)
                } else {
                    Position::Geodetic(self.vec3([47.0, 8.0, 400.0], 0.01)?)
                };
                let velocity = self.vec3([0.0; 3], 5.0)?;
                let mask = self.u8()?;
                Op::Gps {
                    t,
                    position,
                    velocity,
                    accuracy: [
                        self.accuracy(mask & 1 != 0)?,
                        self.accuracy(mask & 2 != 0)?,
                        self.accuracy(mask & 4 != 0)?,
                    ],
                }
            }
            9 | 10 => Op::Mag {
                t: self.time()?,
                field: self.vec3([0.2, 0.0, 0.4], 0.1)?,
            },
            11 => Op::Estimate,
            12 => Op::Health,
            13 => Op::Reset,
            14 => {
                let field = self.u8()?;
                let how = self.u8()?;
                let value = if how < 128 {
                    // 0.1 to 10, log-spaced.
                    Setting::Scale(10f64.powf((f64::from(how) - 63.5) / 63.5))
                } else {
                    Setting::Set(self.value(1.0, 1.0)?)
                };
                Op::Configure { field, value }
            }
            _ => Op::Calm(u32::from(self.u8()? % 64) + 1),
        })
    }
}

/// The start byte and the operations of an input.
pub(crate) fn decode(data: &[u8]) -> Option<(u8, Vec<Op>)> {
    let mut bytes = Bytes::new(data);
    let start = bytes.u8()?;
    let mut ops = Vec::new();
    while ops.len() < MAX_OPS {
        match bytes.op() {
            Some(op) => ops.push(op),
            None => break,
        }
    }
    Some((start, ops))
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

/// One case from a saved start; panics (a finding) with the operations.
pub(crate) fn run<T: delaynav::Scalar, S: push_api::Subject<T> + Clone>(
    starts: &[(S, u64)],
    start: u8,
    ops: &[Op],
    name: &str,
) {
    let (s, cursor) = &starts[usize::from(start >> 1) % starts.len()];
    if let Err(e) = push_api::replay_from(s.clone(), *cursor, ops) {
        panic!(
            "{name}: {e}\nstart {:?}, ops {ops:?}",
            STARTS_MS[usize::from(start >> 1) % STARTS_MS.len()]
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

        libfuzzer_sys::fuzz_target!(|data: &[u8]| {
            let Some((start, ops)) = machine::decode(data) else {
                return;
            };
            if start & 1 == 0 {
                let starts = STARTS_32.get_or_init(|| machine::starts($make32));
                machine::run(starts, start, &ops, concat!("f32 ", $name));
            } else {
                let starts = STARTS_64.get_or_init(|| machine::starts($make64));
                machine::run(starts, start, &ops, concat!("f64 ", $name));
            }
        });
    };
}

//! The byte layout of the estimator fuzz targets' inputs
//! (`fuzz/fuzz_targets/machine.rs`): [`decode`] reads an input into the
//! operations of the push-API machine (`tests/push_api.rs`), [`encode`]
//! writes a case of the machine as an input, so that the property tests'
//! regression cases are fuzz seeds (`fuzz/corpus/*/regression-*`, checked
//! by `tests/push_api.rs`, `fuzz_seeds_are_the_regression_cases`). A
//! mutation of one byte changes one operation, one value or one time step
//! (libFuzzer's coverage guidance can steer).
//!
//! Layout of an input:
//! - byte 0, the start: bit 0 the precision (0 `f32`, 1 `f64`); below
//!   `0xfe`, the other bits (`byte >> 1`, modulo 5) pick a saved state to
//!   start from (fresh, or after 0.3, 1, 2.5 or 8 s of the machine's calm
//!   flight, [`STARTS_MS`], computed once per process and cloned; after 8 s
//!   the navigator's delay loop is locked, its first valid update coming
//!   after 6 s, beyond what the calm flights' budget can add to a shorter
//!   start); `0xfe` and `0xff` are followed by a `u16`
//!   (little-endian): a calm start of that many ms, flown in every
//!   execution (the regression cases' other starts);
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
//! | 15 | calm flight | duration: a byte `b`, `b % 64 + 1` ms; [`CALM_LONG`] and a `u16`, that many ms |
//!
//! The calm flights (the start's and the operations', short and long) fly
//! at most [`CALM_BUDGET_MS`] in all in one input, the rest cut: a fuzz
//! execution stays short (a calm millisecond is an IMU push, and every 20th
//! a magnetometer one; without the bound on the short ones, the calm flights
//! of the inputs libFuzzer grew were 97 % of the pushes, up to 16 s in one
//! input). The markers of the long ones are rare values (libFuzzer inserts
//! runs of `0xff` and `0x00`; a run of `0xff` is an `f64` start and calm
//! flights of 64 ms).
//!
//! A value is one byte: below 224, a plausible value (`center ± spread` in
//! 224 steps); from 224, one of 31 hostile values (NaN, infinities, the largest
//! and smallest floats, ...), 255 the next eight bytes as an `f64`'s bits.
//! A time is one tag byte ([`Bytes::time`]): steps near the IMU period,
//! gaps, a duplicate, steps back, hours ahead, `u64::MAX` and raw stamps.

use super::{Op, Position, Setting, Time};

/// The most operations decoded from one input.
pub(crate) const MAX_OPS: usize = 256;
/// The saved starts a case may begin from, ms of calm flight (`None`: fresh).
pub(crate) const STARTS_MS: [Option<u32>; 5] =
    [None, Some(300), Some(1_000), Some(2_500), Some(8_000)];
/// The most ms of calm flight in one input, the start's, the short and the
/// long flights together (module docs).
pub(crate) const CALM_BUDGET_MS: u32 = 2_000;
/// The start bytes (`f32`, `f64`) followed by their calm start's duration.
const CALM_START: u8 = 0xfe;
/// The calm-flight byte followed by a `u16` duration.
pub(crate) const CALM_LONG: u8 = 0xc1;
/// The time tag followed by an absolute stamp.
const TIME_AT: u8 = 240;
/// The time tag of a duplicate stamp.
const TIME_SAME: u8 = 192;
/// The value tag followed by an `f64`'s bits.
const VALUE_BITS: u8 = 255;

const GRAVITY: f64 = 9.806_65;

/// More values no sensor should report, after the machine's
/// (`HOSTILE`, `LARGEST`): a value byte from 224 picks one of the three
/// lists in that order.
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
    let (a, b) = (super::HOSTILE.len(), super::LARGEST.len());
    match i {
        i if i < a => super::HOSTILE[i],
        i if i < a + b => super::LARGEST[i - a],
        i => MORE_HOSTILE[(i - a - b) % MORE_HOSTILE.len()],
    }
}

/// Where a case starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Start {
    /// A saved state: the index in [`STARTS_MS`].
    Saved(usize),
    /// A calm start of this many ms, flown in the execution.
    Calm(u32),
}

impl Start {
    /// The calm start of the machine's `replay`.
    pub(crate) fn calm_ms(self) -> Option<u32> {
        match self {
            Start::Saved(i) => STARTS_MS[i],
            Start::Calm(ms) => Some(ms),
        }
    }
}

/// A decoded input.
#[derive(Debug, Clone)]
pub(crate) struct Input {
    /// `f64` (else `f32`).
    pub(crate) f64: bool,
    pub(crate) start: Start,
    pub(crate) ops: Vec<Op>,
}

/// The input, read front to back; `None` once it is exhausted.
pub(crate) struct Bytes<'a>(&'a [u8], u32);

impl<'a> Bytes<'a> {
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Bytes(data, CALM_BUDGET_MS)
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
            VALUE_BITS => f64::from_bits(self.u64()?),
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
            TIME_SAME..=199 => Time::Same,
            200..=215 => Time::Before((tag64 - 199) * 1_000),
            216..=223 => Time::Before(u64::from(self.u16()?) * 1_000),
            // Hours ahead.
            224..=231 => Time::After((tag64 - 223) * 3_600_000_000),
            232..=239 => Time::At(u64::MAX - (tag64 - 232)),
            TIME_AT..=247 => Time::At(self.u64()?),
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

    /// A calm flight's `u16` duration, within what is left of the budget.
    fn calm_ms(&mut self) -> Option<u32> {
        let ms = u32::from(self.u16()?);
        Some(self.spend(ms))
    }

    /// `ms` of calm flight, within what is left of the budget.
    fn spend(&mut self, ms: u32) -> u32 {
        let ms = ms.min(self.1);
        self.1 -= ms;
        ms
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
            _ => match self.u8()? {
                CALM_LONG => Op::Calm(self.calm_ms()?),
                b => Op::Calm(self.spend(u32::from(b % 64) + 1)),
            },
        })
    }
}

/// The start and the operations of an input.
pub(crate) fn decode(data: &[u8]) -> Option<Input> {
    let mut bytes = Bytes::new(data);
    let first = bytes.u8()?;
    let start = if first >= CALM_START {
        Start::Calm(bytes.calm_ms()?)
    } else {
        Start::Saved(usize::from(first >> 1) % STARTS_MS.len())
    };
    let mut ops = Vec::new();
    while ops.len() < MAX_OPS {
        match bytes.op() {
            Some(op) => ops.push(op),
            None => break,
        }
    }
    Some(Input {
        f64: first & 1 == 1,
        start,
        ops,
    })
}

/// The input that flies `ops` after the calm start `start` (ms) in the
/// precision `f64` (else `f32`): every value as its bits, every time as
/// the absolute stamp the machine's cursor gives it, every calm flight
/// whole (together within [`CALM_BUDGET_MS`]). `Setting::Scale` becomes the
/// nearest of the 128 scales of the layout (the regression cases set none).
/// The case it decodes to flies as the original does (`tests/push_api.rs`
/// checks it).
pub(crate) fn encode(start: Option<u32>, f64: bool, ops: &[Op]) -> Vec<u8> {
    let mut out = Vec::new();
    let precision = u8::from(f64);
    match STARTS_MS.iter().position(|s| *s == start) {
        Some(i) => out.push((i as u8) << 1 | precision),
        None => {
            out.push(CALM_START | precision);
            out.extend_from_slice(&calm_u16(start.unwrap_or(0)).to_le_bytes());
        }
    }
    let mut cursor = calm_end(super::START_US, start.unwrap_or(0));
    let value = |out: &mut Vec<u8>, v: f64| {
        out.push(VALUE_BITS);
        out.extend_from_slice(&v.to_bits().to_le_bytes());
    };
    let vec3 = |out: &mut Vec<u8>, v: [f64; 3]| v.into_iter().for_each(|x| value(out, x));
    let time = |out: &mut Vec<u8>, cursor: &mut u64, t: Time| {
        let at = match t {
            Time::After(dt) => cursor.saturating_add(dt),
            Time::Same => *cursor,
            Time::Before(dt) => cursor.saturating_sub(dt),
            Time::At(t) => t,
        };
        if at == *cursor {
            out.push(TIME_SAME);
        } else {
            out.push(TIME_AT);
            out.extend_from_slice(&at.to_le_bytes());
        }
        *cursor = at;
    };
    for op in ops {
        match *op {
            Op::Imu { t, gyro, accel } => {
                out.push(0);
                time(&mut out, &mut cursor, t);
                vec3(&mut out, gyro);
                vec3(&mut out, accel);
            }
            Op::Gps {
                t,
                position,
                velocity,
                accuracy,
            } => {
                out.push(6);
                time(&mut out, &mut cursor, t);
                let (frame, p) = match position {
                    Position::Ned(p) => (0, p),
                    Position::Geodetic(p) => (1, p),
                };
                out.push(frame);
                vec3(&mut out, p);
                vec3(&mut out, velocity);
                out.push(
                    accuracy
                        .iter()
                        .enumerate()
                        .map(|(i, a)| u8::from(a.is_some()) << i)
                        .sum(),
                );
                accuracy
                    .into_iter()
                    .flatten()
                    .for_each(|a| value(&mut out, a));
            }
            Op::Mag { t, field } => {
                out.push(9);
                time(&mut out, &mut cursor, t);
                vec3(&mut out, field);
            }
            Op::Estimate => out.push(11),
            Op::Health => out.push(12),
            Op::Reset => out.push(13),
            Op::Configure { field, value: v } => {
                out.extend_from_slice(&[14, field]);
                match v {
                    Setting::Scale(k) => {
                        let how = (k.log10() * 63.5 + 63.5).round().clamp(0.0, 127.0);
                        out.push(how as u8);
                    }
                    Setting::Set(x) => {
                        out.push(128);
                        value(&mut out, x);
                    }
                }
            }
            Op::Calm(ms @ 1..=64) => {
                out.extend_from_slice(&[15, (ms - 1) as u8]);
                cursor = calm_end(cursor, ms);
            }
            Op::Calm(ms) => {
                out.extend_from_slice(&[15, CALM_LONG]);
                out.extend_from_slice(&calm_u16(ms).to_le_bytes());
                cursor = calm_end(cursor, ms);
            }
        }
    }
    out
}

/// A calm flight's duration as its `u16`; panics above [`CALM_BUDGET_MS`]
/// (the seed test then fails: the case does not fit an input).
fn calm_u16(ms: u32) -> u16 {
    assert!(ms <= CALM_BUDGET_MS, "a calm flight of {ms} ms is too long");
    ms as u16
}

/// The machine's cursor after `ms` of calm flight from `start` (the flight
/// stops at the last millisecond below `u64::MAX`).
fn calm_end(start: u64, ms: u32) -> u64 {
    let room = (u64::MAX - start) / super::IMU_PERIOD_US;
    start + u64::from(ms).min(room) * super::IMU_PERIOD_US
}

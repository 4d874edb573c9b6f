//! Timestamps of the IMU history, and the checks of every stream's clock.
//!
//! # Reading the history by time
//! The history ([`FractionalDelayLine`](crate::delay::FractionalDelayLine))
//! is indexed by samples. [`SampleTimes`] keeps the timestamp of each stored
//! sample, so a read at time `t` finds the stored pair `t_k <= t < t_{k+1}`
//! (binary search, `O(log HIST)`) and reads at the fractional delay
//!
//! ```text
//! d = age(k) - (t - t_k) / (t_{k+1} - t_k)      samples behind the newest
//! ```
//!
//! Rate changes, dropped samples and jitter then move the read to the right
//! sample; a mean period would shift every read after a dropped sample by one
//! period (10 % dropped at 1 kHz: 100 ms of error after one second). Inside
//! the cubic stencil the spacing is taken as uniform: with +-30 % jitter
//! that bends the interpolant by a fraction of one sample's change.
//!
//! # Clock checks
//! Every stream's timestamp must increase ([`Error::DuplicateTimestamp`],
//! [`Error::TimeWentBackwards`]: refused, counted, the stream goes on with
//! the next good sample). An IMU sample more than `max_time_jump_us` after
//! the previous one is refused once ([`Error::OutOfRange`] on
//! `imu.time`) and kept as a candidate: the next sample confirms the jump
//! when it lies after the candidate by at most the bound (a real gap), so
//! one future-stamped sample never blocks the stream. GPS and magnetometer
//! samples more than the bound after the newest IMU sample are refused.

use crate::error::Error;
use crate::scalar::Scalar;

/// The longest step between two stored samples, µs: a step is stored in
/// 16 bits. The navigator restarts the history on a longer IMU gap.
pub(crate) const MAX_SAMPLE_STEP_US: u64 = u16::MAX as u64;

/// Checkpoints of [`SampleTimes`] (a fixed count, whatever `N`).
const CHECKPOINTS: usize = 64;

/// The timestamps of the last `N` IMU samples (see the module docs), kept
/// as the 16-bit step from the previous sample (at most
/// [`MAX_SAMPLE_STEP_US`]), the low 32 bits of every `SPACING`-th time
/// (a checkpoint) and the newest in full. A stored time is its anchor (the
/// nearest newer checkpoint, or the newest time) minus the steps between
/// them: fewer than `SPACING` subtractions, `N / 62` (9 at 530 samples).
/// A push a longer step after the newest forgets the older times.
#[derive(Debug, Clone)]
pub(crate) struct SampleTimes<const N: usize> {
    /// Step from the previous sample, µs, in a ring of `N`.
    steps: [u16; N],
    /// Where the next step is written.
    head: usize,
    len: usize,
    /// Low 32 bits of the checkpoint times, in a ring.
    checkpoints: [u32; CHECKPOINTS],
    /// Where the next checkpoint is written.
    next_checkpoint: usize,
    /// Samples pushed after the newest checkpoint.
    newest_checkpoint_age: usize,
    newest: u64,
    oldest: u64,
}

/// The low 32 bits of a time (truncation intended).
fn low_bits(t_us: u64) -> u32 {
    (t_us & u64::from(u32::MAX)) as u32
}

impl<const N: usize> SampleTimes<N> {
    /// Samples between checkpoints: the `N` stored ones hold at most
    /// `CHECKPOINTS - 2` of them.
    const SPACING: usize = N.div_ceil(CHECKPOINTS - 2);

    pub(crate) const fn new() -> Self {
        const {
            // The span (at most N steps of 65 ms) stays below 2^32 µs.
            assert!(N > 0 && N < 65_536, "1 to 65535 sample times");
        };
        Self {
            steps: [0; N],
            head: 0,
            len: 0,
            checkpoints: [0; CHECKPOINTS],
            next_checkpoint: 0,
            newest_checkpoint_age: 0,
            newest: 0,
            oldest: 0,
        }
    }

    /// Appends the newest time (later than the previous one: the clock
    /// check); a step beyond [`MAX_SAMPLE_STEP_US`] first forgets the older
    /// times.
    pub(crate) fn push(&mut self, t_us: u64) {
        let step = t_us.saturating_sub(self.newest);
        if self.len > 0 && step > MAX_SAMPLE_STEP_US {
            self.clear();
        }
        // Below 2^16 when a previous sample is stored (the check above).
        self.steps[self.head % N] = if self.len > 0 { step as u16 } else { 0 };
        self.head = (self.head + 1) % N;
        if self.len == 0 || self.newest_checkpoint_age + 1 >= Self::SPACING {
            self.checkpoints[self.next_checkpoint % CHECKPOINTS] = low_bits(t_us);
            self.next_checkpoint = (self.next_checkpoint + 1) % CHECKPOINTS;
            self.newest_checkpoint_age = 0;
        } else {
            self.newest_checkpoint_age += 1;
        }
        if self.len == 0 {
            self.oldest = t_us;
        } else if self.len == N {
            // The oldest sample was overwritten: the next one is the oldest.
            self.oldest += self.step(N - 1);
        }
        self.len = (self.len + 1).min(N);
        self.newest = t_us;
    }

    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// The step from the sample of age `age + 1` to the one of age `age`.
    fn step(&self, age: usize) -> u64 {
        u64::from(self.steps[(self.head + 2 * N - 1 - age % N) % N])
    }

    /// Checkpoints stored: those of an age below `len`.
    fn checkpoint_count(&self) -> usize {
        (self.len + Self::SPACING - 1 - self.newest_checkpoint_age) / Self::SPACING
    }

    /// The age and time of checkpoint `i` (0: the newest).
    fn checkpoint(&self, i: usize) -> (usize, u64) {
        let slot = (self.next_checkpoint + CHECKPOINTS - 1 - i % CHECKPOINTS) % CHECKPOINTS;
        let behind = low_bits(self.newest).wrapping_sub(self.checkpoints[slot]);
        (
            self.newest_checkpoint_age + i * Self::SPACING,
            self.newest.saturating_sub(u64::from(behind)),
        )
    }

    /// The oldest stored time.
    pub(crate) fn oldest(&self) -> Option<u64> {
        (self.len > 0).then_some(self.oldest)
    }

    /// The fractional delay, samples behind the newest, of time `t_us`;
    /// `None` outside the stored span.
    pub(crate) fn delay_samples<T: Scalar>(&self, t_us: u64) -> Option<T> {
        let oldest = self.oldest()?;
        if t_us > self.newest || t_us < oldest {
            return None;
        }
        if t_us == self.newest {
            return Some(T::zero());
        }
        // The newest checkpoint at or before t (binary search: times fall
        // as `i` grows), else the oldest sample; then newer step by step to
        // the newest sample at or before t.
        let (mut lo, mut hi) = (0, self.checkpoint_count());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if self.checkpoint(mid).1 <= t_us {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        let (mut age, mut t_k) = if lo < self.checkpoint_count() {
            self.checkpoint(lo)
        } else {
            (self.len - 1, oldest)
        };
        // t < newest: a newer sample exists.
        while age > 0 {
            let span = self.step(age - 1);
            if t_k + span > t_us {
                let span = (span > 0).then_some(span)?;
                return Some(
                    T::lit(age as f64) - T::lit((t_us - t_k) as f64) / T::lit(span as f64),
                );
            }
            t_k += span;
            age -= 1;
        }
        None
    }
}

/// The clock check of one stream (see the module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct StreamClock {
    last: Option<u64>,
    /// A sample refused as too far ahead, waiting for confirmation.
    candidate: Option<u64>,
}

/// Why a timestamp was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ClockRefusal {
    /// Equal to the previous one.
    Duplicate,
    /// Before the previous one.
    Backwards,
    /// Too far ahead.
    Ahead,
}

impl StreamClock {
    /// No sample yet (the `const` of [`Default::default`]).
    pub(crate) const NEW: Self = Self {
        last: None,
        candidate: None,
    };

    /// The last accepted time.
    pub(crate) fn last(&self) -> Option<u64> {
        self.last
    }

    /// Checks `t_us` of stream `stream`; `ahead_of` is the time it may not
    /// exceed by more than `max_jump_us` (`None`: the stream's own last time,
    /// with confirmation by a second sample). Accepted times become the last.
    pub(crate) fn check(
        &mut self,
        stream: &'static str,
        field: &'static str,
        t_us: u64,
        ahead_of: Option<u64>,
        max_jump_us: u64,
    ) -> Result<(), (ClockRefusal, Error)> {
        if let Some(p) = self.last {
            if t_us == p {
                return Err((
                    ClockRefusal::Duplicate,
                    Error::DuplicateTimestamp { stream, t_us },
                ));
            }
            if t_us < p {
                return Err((
                    ClockRefusal::Backwards,
                    Error::TimeWentBackwards {
                        stream,
                        previous_us: p,
                        got_us: t_us,
                    },
                ));
            }
        }
        let confirming = ahead_of.is_none();
        if let Some(reference) = ahead_of.or(self.last)
            && t_us > reference.saturating_add(max_jump_us)
        {
            let confirmed = confirming
                && self
                    .candidate
                    .is_some_and(|c| t_us > c && t_us - c <= max_jump_us);
            if !confirmed {
                if confirming {
                    self.candidate = Some(t_us);
                }
                return Err((
                    ClockRefusal::Ahead,
                    Error::OutOfRange {
                        field,
                        reason: "too far ahead of the stream (max_time_jump_us); \
                                 an IMU jump is accepted when the next sample confirms it",
                    },
                ));
            }
        }
        self.candidate = None;
        self.last = Some(t_us);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_follow_the_timestamps_through_gaps_and_rate_changes() {
        let mut times = SampleTimes::<16>::new();
        // 1 ms, a dropped sample, then 5 ms steps.
        for t in [0, 1000, 2000, 4000, 9000, 14_000] {
            times.push(t);
        }
        let d = |t| times.delay_samples::<f64>(t);
        assert_eq!(d(14_000), Some(0.0));
        assert_eq!(d(11_500), Some(0.5));
        assert_eq!(d(9000), Some(1.0));
        assert_eq!(d(3000), Some(2.5));
        assert_eq!(d(0), Some(5.0));
        assert_eq!(d(14_001), None);
        times.clear();
        assert_eq!(times.delay_samples::<f64>(0), None);
    }

    #[test]
    fn times_beyond_32_bits_read_back_exactly() {
        let mut times = SampleTimes::<4>::new();
        // Across the 2^32 µs boundary of the stored low bits.
        let base = (1u64 << 32) - 1500;
        for k in 0..6 {
            times.push(base + k * 1000);
        }
        assert_eq!(times.oldest(), Some(base + 2000));
        assert_eq!(times.delay_samples::<f64>(base + 3500), Some(1.5));
        assert_eq!(times.delay_samples::<f64>(base + 1999), None);
        // A span of more than 2^32 µs forgets the older times.
        times.push(base + (1 << 32) + 3000);
        assert_eq!(times.oldest(), Some(base + (1 << 32) + 3000));
        assert_eq!(times.delay_samples::<f64>(base + 5000), None);
    }

    /// Every read against the exact times, after every push, through
    /// irregular steps, many checkpoint cycles and a capacity that is not
    /// a multiple of the checkpoint spacing.
    fn matches_the_exact_times<const N: usize>() {
        let mut times = SampleTimes::<N>::new();
        let mut exact = std::collections::VecDeque::new();
        let mut t = (1u64 << 32) - 40_000;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..(5 * N + 77) {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            t += 500 + state % 3000 + if state.is_multiple_of(97) { 60_000 } else { 0 };
            times.push(t);
            exact.push_front(t);
            exact.truncate(N);
            assert_eq!(times.oldest(), exact.back().copied());
            for age in 0..exact.len() {
                let when = exact[age];
                assert_eq!(times.delay_samples::<f64>(when), Some(age as f64));
                if age > 0 {
                    let later = exact[age - 1];
                    let mid = when + (later - when) / 4;
                    let want = age as f64 - (mid - when) as f64 / (later - when) as f64;
                    assert_eq!(times.delay_samples::<f64>(mid), Some(want));
                }
            }
            assert_eq!(times.delay_samples::<f64>(t + 1), None);
            assert_eq!(times.delay_samples::<f64>(exact.back().unwrap() - 1), None);
        }
    }

    #[test]
    fn steps_and_checkpoints_give_the_exact_times() {
        matches_the_exact_times::<1>();
        matches_the_exact_times::<7>();
        matches_the_exact_times::<61>();
        matches_the_exact_times::<530>();
    }

    #[test]
    fn a_step_beyond_16_bits_forgets_the_older_times() {
        let mut times = SampleTimes::<8>::new();
        for t in [0, 1000, 66_535] {
            times.push(t);
        }
        assert_eq!(times.oldest(), Some(0));
        times.push(66_535 + MAX_SAMPLE_STEP_US + 1);
        assert_eq!(times.oldest(), Some(66_535 + MAX_SAMPLE_STEP_US + 1));
        assert_eq!(times.delay_samples::<f64>(66_535), None);
    }

    #[test]
    fn one_future_stamp_is_refused_and_a_real_jump_confirmed() {
        let mut c = StreamClock::default();
        let max = 1_000_000;
        assert!(c.check("imu", "imu.time", 1000, None, max).is_ok());
        let ahead = c.check("imu", "imu.time", 3_600_000_000, None, max);
        assert!(matches!(ahead, Err((ClockRefusal::Ahead, _))));
        assert!(c.check("imu", "imu.time", 2000, None, max).is_ok());
        assert!(matches!(
            c.check("imu", "imu.time", 2000, None, max),
            Err((ClockRefusal::Duplicate, _))
        ));
        assert!(matches!(
            c.check("imu", "imu.time", 1500, None, max),
            Err((ClockRefusal::Backwards, _))
        ));
        // A real 5 s gap: the first sample after it is refused, the next confirms.
        assert!(c.check("imu", "imu.time", 5_002_000, None, max).is_err());
        assert!(c.check("imu", "imu.time", 5_003_000, None, max).is_ok());
        assert_eq!(c.last(), Some(5_003_000));
        // Other streams are bounded by the newest IMU time, without confirmation.
        let mut gps = StreamClock::default();
        assert!(
            gps.check("gps", "gps.time", 9_000_000, Some(5_003_000), max)
                .is_err()
        );
        assert!(
            gps.check("gps", "gps.time", 9_000_001, Some(5_003_000), max)
                .is_err()
        );
        assert!(
            gps.check("gps", "gps.time", 5_000_000, Some(5_003_000), max)
                .is_ok()
        );
    }
}

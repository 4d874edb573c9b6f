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

/// Steps of [`u16::MAX`] µs and longer (a dropout of a few samples at
/// 50 Hz) are kept exactly in a side ring of this many; one more forgets
/// the times older than the oldest of them.
const LONG_STEPS: usize = 8;

/// Checkpoints of [`SampleTimes`] (a fixed count, whatever `N`).
const CHECKPOINTS: usize = 64;

/// The timestamps of the last `N` IMU samples (see the module docs), kept
/// as the 16-bit step from the previous sample (a step of [`u16::MAX`] µs
/// or more is marked so and kept whole in a ring of the last
/// [`LONG_STEPS`], by the push count of its sample), the low 32 bits of
/// every `SPACING`-th time (a checkpoint) and the newest in full. A stored
/// time is its anchor (the nearest newer checkpoint, or the newest time)
/// minus the steps between them: fewer than `SPACING` subtractions,
/// `N / 62` (9 at 530 samples). A step of [`Self::MAX_STEP_US`] or more
/// forgets the older times (the span must stay within 32 bits), and so
/// does a long step whose slot in the ring is taken by a newer one.
#[derive(Debug, Clone)]
pub(crate) struct SampleTimes<const N: usize> {
    /// Step from the previous sample, µs, in a ring of `N`; `u16::MAX`: a
    /// long step, in `long_steps`.
    steps: [u16; N],
    /// Long steps, µs, and the push count of their sample, in a ring.
    long_steps: [(u32, u32); LONG_STEPS],
    /// Where the next long step is written.
    next_long_step: usize,
    /// Samples pushed since the start, wrapping (names the long steps).
    pushes: u32,
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
            assert!(N > 0 && N < 65_536, "1 to 65535 sample times");
        };
        Self {
            steps: [0; N],
            long_steps: [(0, 0); LONG_STEPS],
            next_long_step: 0,
            pushes: 0,
            head: 0,
            len: 0,
            checkpoints: [0; CHECKPOINTS],
            next_checkpoint: 0,
            newest_checkpoint_age: 0,
            newest: 0,
            oldest: 0,
        }
    }

    /// The longest step kept, µs: `N` steps of it span less than 2^32 µs
    /// (the checkpoints' low bits); 8.1 s at 530 samples.
    pub(crate) const MAX_STEP_US: u64 = u32::MAX as u64 / N as u64;

    /// Appends the newest time (later than the previous one: the clock
    /// check); a step of [`Self::MAX_STEP_US`] or more first forgets the
    /// older times. Returns whether a long step's ring slot forgot stored
    /// times (the caller counts it).
    pub(crate) fn push(&mut self, t_us: u64) -> bool {
        let mut forgot = false;
        let step = t_us.saturating_sub(self.newest);
        if self.len > 0 && step >= Self::MAX_STEP_US {
            self.clear();
        }
        let short = if self.len == 0 {
            0
        } else if step < u64::from(u16::MAX) {
            step as u16 // below 2^16: the branch
        } else {
            let slot = self.next_long_step % LONG_STEPS;
            // The long step this one takes the slot of: the step to the
            // sample of age `age` (before this push). If the sample before
            // it is still stored, that sample and every older one are
            // forgotten.
            let age = self.pushes.wrapping_sub(self.long_steps[slot].1) as usize;
            if age.saturating_add(1) < self.len {
                self.oldest = self.time_of(age);
                // No overflow: age + 1 < len <= N.
                self.len = age.wrapping_add(1);
                forgot = true;
            }
            // Below 2^32: under MAX_STEP_US (the check above).
            self.long_steps[slot] = (step as u32, self.pushes.wrapping_add(1));
            self.next_long_step = (slot + 1) % LONG_STEPS;
            u16::MAX
        };
        self.pushes = self.pushes.wrapping_add(1);
        self.steps[self.head % N] = short;
        // No overflow: head < N.
        self.head = self.head.wrapping_add(1) % N;
        // No overflow: newest_checkpoint_age < SPACING.
        if self.len == 0 || self.newest_checkpoint_age.wrapping_add(1) >= Self::SPACING {
            self.checkpoints[self.next_checkpoint % CHECKPOINTS] = low_bits(t_us);
            // No overflow: next_checkpoint < CHECKPOINTS.
            self.next_checkpoint = self.next_checkpoint.wrapping_add(1) % CHECKPOINTS;
            self.newest_checkpoint_age = 0;
        } else {
            // No overflow: below SPACING - 1 here.
            self.newest_checkpoint_age = self.newest_checkpoint_age.wrapping_add(1);
        }
        if self.len == 0 {
            self.oldest = t_us;
        } else if self.len == N {
            // The oldest sample was overwritten: the next one is the oldest.
            self.oldest = self.oldest.saturating_add(self.step(N - 1));
        }
        // No overflow: len <= N.
        self.len = self.len.wrapping_add(1).min(N);
        self.newest = t_us;
        forgot
    }

    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// The step from the sample of age `age + 1` to the one of age `age`.
    #[inline(always)]
    fn step(&self, age: usize) -> u64 {
        // No overflow: head < N and age % N < N: the index is in [N, 3 N).
        let short = self.steps[self.head.wrapping_add(2 * N - 1).wrapping_sub(age % N) % N];
        if short < u16::MAX {
            u64::from(short)
        } else {
            self.long_step(age)
        }
    }

    /// A step marked long: the one kept for the sample of age `age`, the
    /// push numbered `pushes - age`.
    #[cold]
    #[inline(never)]
    fn long_step(&self, age: usize) -> u64 {
        let serial = self.pushes.wrapping_sub(age as u32);
        self.long_steps
            .iter()
            .find(|(_, s)| *s == serial)
            .map_or(0, |(step, _)| u64::from(*step))
    }

    /// The time of the stored sample of age `age` (0: the newest).
    fn time_of(&self, age: usize) -> u64 {
        (0..age).fold(self.newest, |t, a| t.saturating_sub(self.step(a)))
    }

    /// Checkpoints stored: those of an age below `len`.
    fn checkpoint_count(&self) -> usize {
        // No overflow: len <= N and newest_checkpoint_age < SPACING: no wrap.
        self.len
            .wrapping_add(Self::SPACING - 1)
            .wrapping_sub(self.newest_checkpoint_age)
            / Self::SPACING
    }

    /// The age and time of checkpoint `i` (0: the newest).
    fn checkpoint(&self, i: usize) -> (usize, u64) {
        // No overflow: next_checkpoint < CHECKPOINTS and i % CHECKPOINTS < CHECKPOINTS.
        let slot = self
            .next_checkpoint
            .wrapping_add(CHECKPOINTS - 1)
            .wrapping_sub(i % CHECKPOINTS)
            % CHECKPOINTS;
        let behind = low_bits(self.newest).wrapping_sub(self.checkpoints[slot]);
        (
            // No overflow: i < checkpoint_count(): the age is below len <= N.
            self.newest_checkpoint_age
                .wrapping_add(i.wrapping_mul(Self::SPACING)),
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
            // No overflow: lo < hi <= CHECKPOINTS.
            let mid = lo.wrapping_add(hi.wrapping_sub(lo) / 2);
            if self.checkpoint(mid).1 <= t_us {
                hi = mid;
            } else {
                // No overflow: mid < hi.
                lo = mid.wrapping_add(1);
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
            if t_k.saturating_add(span) > t_us {
                let span = (span > 0).then_some(span)?;
                return Some(
                    T::lit(age as f64)
                        - T::lit(t_us.saturating_sub(t_k) as f64) / T::lit(span as f64),
                );
            }
            t_k = t_k.saturating_add(span);
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

    /// A sample too far ahead is waiting for the next one to confirm the jump: the present
    /// may be that far beyond the last accepted time.
    pub(crate) fn jump_pending(&self) -> bool {
        self.candidate.is_some()
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
            t += 500
                + state % 3000
                + if state.is_multiple_of(97) {
                    60_000 + state % 200_000
                } else {
                    0
                };
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
    fn long_steps_are_kept_exactly_and_the_longest_forgets_the_older_times() {
        let mut times = SampleTimes::<8>::new();
        // 50 Hz with dropouts: 80 ms and 200 ms steps.
        for t in [0, 20_000, 100_000, 300_000, 320_000] {
            times.push(t);
        }
        let d = |times: &SampleTimes<8>, t| times.delay_samples::<f64>(t);
        assert_eq!(times.oldest(), Some(0));
        assert_eq!(d(&times, 60_000), Some(2.5));
        assert_eq!(d(&times, 200_000), Some(1.5));
        let max = SampleTimes::<8>::MAX_STEP_US;
        times.push(320_000 + max);
        assert_eq!(times.oldest(), Some(320_000 + max));
        assert_eq!(d(&times, 320_000), None);
    }

    #[test]
    fn a_ninth_long_step_in_the_span_forgets_the_times_before_the_first() {
        let mut times = SampleTimes::<64>::new();
        let mut exact = Vec::new();
        let mut t = 5_000;
        for k in 0..30u64 {
            // Every third step is long (70-290 ms).
            t += if k % 3 == 2 {
                70_000 + k * 7_000
            } else {
                1_000
            };
            times.push(t);
            exact.push(t);
        }
        // Ten long steps pushed (into samples 2, 5, ..., 29): the ninth and
        // the tenth took the slots of the first two, so the samples before
        // the second one's (sample 5) are forgotten.
        let first_kept = exact[5];
        assert_eq!(times.oldest(), Some(first_kept));
        assert_eq!(times.delay_samples::<f64>(first_kept - 1), None);
        for (age, &when) in exact.iter().rev().take(25).enumerate() {
            assert_eq!(times.delay_samples::<f64>(when), Some(age as f64));
        }
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

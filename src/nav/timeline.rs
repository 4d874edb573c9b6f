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

use crate::delay::ring::Ring;
use crate::error::Error;
use crate::scalar::Scalar;

/// The timestamps of the last `N` IMU samples (see the module docs), kept
/// as the low 32 bits of each (half the bytes of a `u64`) and the newest
/// in full: a stored time is the newest minus the wrapping difference of
/// the low bits, exact while the stored span is below `2^32` µs (71 min).
/// A push that would stretch the span beyond that forgets the older times.
#[derive(Debug, Clone)]
pub(crate) struct SampleTimes<const N: usize> {
    low_bits: Ring<u32, N>,
    newest: u64,
}

/// The low 32 bits of a time (truncation intended).
fn low_bits(t_us: u64) -> u32 {
    (t_us & u64::from(u32::MAX)) as u32
}

impl<const N: usize> SampleTimes<N> {
    pub(crate) const fn new() -> Self {
        Self {
            low_bits: Ring::new(0),
            newest: 0,
        }
    }

    pub(crate) fn push(&mut self, t_us: u64) {
        if self
            .oldest()
            .is_some_and(|oldest| t_us.saturating_sub(oldest) > u64::from(u32::MAX))
        {
            self.low_bits.clear();
        }
        self.low_bits.push(low_bits(t_us));
        self.newest = t_us;
    }

    pub(crate) fn clear(&mut self) {
        self.low_bits.clear();
    }

    /// The stored time of age `age` (0: the newest).
    fn get(&self, age: usize) -> Option<u64> {
        let low = self.low_bits.get(age)?;
        let behind = low_bits(self.newest).wrapping_sub(low);
        self.newest.checked_sub(u64::from(behind))
    }

    /// The oldest stored time.
    pub(crate) fn oldest(&self) -> Option<u64> {
        self.get(self.low_bits.len().checked_sub(1)?)
    }

    /// The fractional delay, samples behind the newest, of time `t_us`;
    /// `None` outside the stored span.
    pub(crate) fn delay_samples<T: Scalar>(&self, t_us: u64) -> Option<T> {
        let newest = self.get(0)?;
        if t_us > newest || t_us < self.oldest()? {
            return None;
        }
        if t_us == newest {
            return Some(T::zero());
        }
        // Smallest age whose time is <= t: times fall with age.
        let (mut lo, mut hi) = (1usize, self.low_bits.len() - 1);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if self.get(mid)? <= t_us {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        let (t_k, t_next) = (self.get(lo)?, self.get(lo - 1)?);
        let span = t_next.checked_sub(t_k).filter(|&s| s > 0)?;
        Some(T::lit(lo as f64) - T::lit((t_us - t_k) as f64) / T::lit(span as f64))
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

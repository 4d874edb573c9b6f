//! The control of the loop: a lock followed when it drifts, re-acquired
//! when every axis disagrees, the range's edges watched; axes that disagree
//! with the best measured one left out, and, below 3 Hz once locked, windows
//! far outside the estimate's spread.

use super::sigma::BiasWatch;
use super::{AXES, AxisPeak, DelayLoop};
use crate::scalar::Scalar;

/// Largest difference between the delay the horizon applied to a fix and
/// the loop's estimate for the innovation window to be fused, s.
pub const MAX_APPLIED_DELAY_ERROR_S: f64 = 0.02;

/// Before lock, an innovation window is fused only within this many
/// standard deviations (scaled as fused) of the previous window: 3 gave
/// the same delay suite, 1.5 the same but for one row, 1 was worse
/// (`docs/journal/2026-11-25-delay-robust-acquisition.md`).
pub const ACQUIRE_AGREEMENT_SIGMA: f64 = 2.0;

/// Largest disagreement between two valid axes of one window, in standard
/// deviations `sqrt(R_i + R_j)` of their difference.
pub const AXIS_AGREEMENT_SIGMA: f64 = 3.0;

/// Cross-axis check of one window: every axis measures the same delay, so a
/// valid axis whose peak lies beyond [`AXIS_AGREEMENT_SIGMA`] of the best
/// measured one (smallest `R_i`, the most motion) is left out. Such a peak
/// comes from an error of `a_fwd` that follows the motion (the navigator's
/// tilt), not from the delay: on the 1 Hz high scenario the east axis gave
/// 0.80 s with a peak of 0.97 while north gave 0.19 s.
pub(super) fn drop_inconsistent_axes<T: Scalar>(
    z: &[T; AXES],
    valid: &mut [bool; AXES],
    r: &[T; AXES],
) {
    // The valid axis of smallest `R`, with its `R` (no index kept out of
    // the loop, and `best < AXES` stated: no reachable panic, benches/no-panic).
    let mut best: Option<(usize, T)> = None;
    for axis in (0..AXES).filter(|&a| valid[a]) {
        if best.is_none_or(|(_, r_best)| r[axis] < r_best) {
            best = Some((axis, r[axis]));
        }
    }
    let Some((best, _)) = best.filter(|&(b, _)| b < AXES) else {
        return;
    };
    let k = T::lit(AXIS_AGREEMENT_SIGMA);
    for axis in 0..AXES {
        if axis != best && valid[axis] && (z[axis] - z[best]).abs() > k * (r[axis] + r[best]).sqrt()
        {
            valid[axis] = false;
        }
    }
}

/// On the fix-interval path ([`DelayLoopConfig::matched_fix_intervals`](super::DelayLoopConfig::matched_fix_intervals),
/// below 3 Hz) and once locked, a valid axis whose window peaks beyond this many standard
/// deviations `sqrt(P + R_i)` of the estimate is not fused (counted in
/// [`DelayLoop::outlier_windows`]). A Gaussian window is beyond 3 sigma 0.27 % of the time; at
/// 1 Hz a 10 s buffer holds 10 fix intervals, and a manoeuvre's onset put the peak 101 and
/// 269 ms late with a correlation of 0.94-0.95 (the delay suite's `gps_1hz`, seed 1, 46-48 s).
/// A step of the delay is not lost: the re-acquisition
/// ([`DelayLoopConfig::reacquire_sigma`](super::DelayLoopConfig::reacquire_sigma), 2 sigma)
/// judges the windows before this gate. The grid path (its buffer holds 25 fixes or more) is
/// not gated: at 10 Hz no simulated window was beyond 3 sigma once locked, and on log171's
/// 5 Hz GPS the gate left out 8-13 windows whose delay the replays without them did not fit
/// better (`docs/delay.md`, "Outlying windows").
pub const OUTLIER_SIGMA: f64 = 3.0;

/// Smallest correlation peak of a moving axis for its window to vote in the
/// out-of-range watch (`DelayStatus::BelowRange`):
/// the clean-input peak threshold; the validity threshold of the navigator's
/// loop (0.9) missed the edge peaks of a weakly moving flight (0.887).
pub const OUT_OF_RANGE_MIN_PEAK: f64 = 0.5;

/// Share of the voting windows peaking on one edge at or above which the
/// delay is reported beyond it.
pub const OUT_OF_RANGE_SHARE: f64 = 0.5;

/// Share below which an edge's run ends.
pub const OUT_OF_RANGE_SHARE_END: f64 = 0.1;

/// Time constant of the running share of the votes, s (one buffer).
pub const OUT_OF_RANGE_SHARE_TIME_S: f64 = 5.0;

/// Windows of moving axes voting for one edge of the shift window.
#[derive(Debug, Clone, Copy)]
pub(super) struct EdgeRun<T: Scalar> {
    pub(super) since_us: u64,
    pub(super) below: bool,
    pub(super) peak: T,
    /// Running share of the votes for this edge.
    pub(super) share: T,
}

impl<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize>
    DelayLoop<T, BUF, LAGS, HIST>
{
    /// Re-acquisition after a step (see [`DelayLoop::reacquire`]): the
    /// correlation searches the whole range, so the estimate jumps to each
    /// window's measurement, the mean of the valid axes weighted by
    /// `1 / R_i`, with that mean's variance. Once successive window
    /// measurements have stayed within [`DelayLoopConfig::acquire_sigma`] of
    /// their standard deviation for [`DelayLoopConfig::lock_after_s`], the
    /// loop locks again and the gain fusion keeps the final word. Returns the
    /// weights used (as gains).
    pub(super) fn follow(
        &mut self,
        t_us: u64,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) -> [T; AXES] {
        let mut gains = [T::zero(); AXES];
        let (mut weight, mut weighted) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let w = T::one() / r_buffer_s2[axis];
            weight += w;
            weighted += w * z[axis];
        }
        if weight <= T::zero() {
            self.stable_since_us = None;
            return gains;
        }
        for axis in (0..AXES).filter(|&a| valid[a]) {
            gains[axis] = T::one() / (r_buffer_s2[axis] * weight);
        }
        let mean = weighted / weight;
        let variance = T::one() / weight;
        let agrees =
            (mean - self.fusion.delay_s()).abs() <= self.config.acquire_sigma * variance.sqrt();
        let since = match self.stable_since_us {
            Some(since) if agrees => since,
            _ => t_us,
        };
        self.stable_since_us = Some(since);
        if self.fusion.reset(mean, variance.sqrt()).is_ok()
            && T::lit(t_us.saturating_sub(since) as f64 * 1e-6) >= self.config.lock_after_s
        {
            self.locked = true;
            self.following = false;
            self.stable_since_us = None;
        }
        gains
    }

    /// The out-of-range watch: each window whose moving axes (IMU variance
    /// above the threshold) correlate at least [`OUT_OF_RANGE_MIN_PEAK`]
    /// votes for an edge when all those axes peak on it, for the inside when
    /// one peaks inside (or an axis is valid), and not at all otherwise
    /// (mixed edges, nothing moving). The run of an edge carries the running
    /// share of the votes for it (time constant
    /// [`OUT_OF_RANGE_SHARE_TIME_S`], `dt_s` the time since the last update);
    /// it ends when that share falls below [`OUT_OF_RANGE_SHARE_END`].
    pub(super) fn track_edges(
        &mut self,
        t_us: u64,
        dt_s: T,
        peaks: &[AxisPeak<T>; AXES],
        valid: &[bool; AXES],
    ) {
        let lower_edge = T::lit(self.shift_min as f64);
        let (mut below, mut above, mut inside, mut peak) = (0usize, 0usize, 0usize, T::zero());
        for p in peaks.iter().filter(|p| {
            p.peak >= T::lit(OUT_OF_RANGE_MIN_PEAK)
                && p.accel_variance >= self.config.min_accel_variance_m2_s4
        }) {
            if p.interior {
                inside = inside.saturating_add(1);
            } else if p.shift_samples <= lower_edge {
                below = below.saturating_add(1);
                peak = peak.max(p.peak);
            } else {
                above = above.saturating_add(1);
                peak = peak.max(p.peak);
            }
        }
        let vote = match (valid.iter().any(|&v| v) || inside > 0, below, above) {
            (true, ..) => None,
            (false, b, 0) if b > 0 => Some(true),
            (false, 0, a) if a > 0 => Some(false),
            // Mixed edges, or nothing moving: no vote.
            _ => return,
        };
        let alpha = (dt_s / T::lit(OUT_OF_RANGE_SHARE_TIME_S)).min(T::one());
        self.edge = match (vote, self.edge.get()) {
            (Some(b), Some(run)) if run.below == b => Some(EdgeRun {
                peak: run.peak.max(peak),
                share: run.share + alpha * (T::one() - run.share),
                ..run
            }),
            (Some(b), _) => Some(EdgeRun {
                since_us: t_us,
                below: b,
                peak,
                share: alpha,
            }),
            (None, Some(run)) => Some(EdgeRun {
                share: run.share - alpha * run.share,
                ..run
            })
            .filter(|run| run.share >= T::lit(OUT_OF_RANGE_SHARE_END)),
            (None, None) => None,
        }
        .into();
    }

    /// The edge the delay is reported beyond, with its run: the run's share
    /// of the votes at least [`OUT_OF_RANGE_SHARE`], for at least
    /// [`DelayLoopConfig::out_of_range_after_s`](super::DelayLoopConfig::out_of_range_after_s).
    pub(super) fn out_of_range(&self, t_us: u64) -> Option<EdgeRun<T>> {
        self.edge.get().filter(|run| {
            run.share >= T::lit(OUT_OF_RANGE_SHARE)
                && T::lit(t_us.saturating_sub(run.since_us) as f64 * 1e-6)
                    >= self.config.out_of_range_after_s
        })
    }

    /// Leaves out, on the fix-interval path while locked and not following, the valid axes
    /// beyond [`OUTLIER_SIGMA`] of the estimate, and counts them.
    pub(super) fn refuse_outliers(
        &mut self,
        z: &[T; AXES],
        valid: &mut [bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) {
        if !(self.config.matched_fix_intervals && self.locked) || self.following {
            return;
        }
        let (tau, p) = (self.fusion.delay_s(), self.fusion.variance_s2());
        let k = T::lit(OUTLIER_SIGMA);
        for axis in 0..AXES {
            if valid[axis] && (z[axis] - tau).abs() > k * (p + r_buffer_s2[axis]).sqrt() {
                valid[axis] = false;
                self.outlier_windows = self.outlier_windows.saturating_add(1);
            }
        }
    }

    /// Re-acquisition (see [`DelayLoopConfig::reacquire_sigma`]): restarts the
    /// GFA from the mean of the valid measurements when they all disagree
    /// with the estimate, on one side, for long enough. A deviation from the
    /// paper, whose loop has a fixed gain and follows a delay step only at the
    /// GFA's pace.
    pub(super) fn reacquire(
        &mut self,
        t_us: u64,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) -> bool {
        let k = self.config.reacquire_sigma;
        if k <= T::zero() {
            return false;
        }
        let tau = self.fusion.delay_s();
        let p = self.fusion.variance_s2();
        let (mut count, mut above, mut below) = (0usize, 0usize, 0usize);
        let (mut z_sum, mut r_sum) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let innovation = z[axis] - tau;
            let bound = k * (p + r_buffer_s2[axis]).sqrt();
            count = count.saturating_add(1);
            z_sum += z[axis];
            r_sum += r_buffer_s2[axis];
            if innovation > bound {
                above = above.saturating_add(1);
            } else if innovation < -bound {
                below = below.saturating_add(1);
            }
        }
        if count == 0 || (above != count && below != count) {
            self.disagreeing_since_us = None;
            return false;
        }
        let since = *self.disagreeing_since_us.get_or_insert(t_us);
        if T::lit(t_us.saturating_sub(since) as f64 * 1e-6) < self.config.reacquire_after_s {
            return false;
        }
        self.disagreeing_since_us = None;
        let n = T::lit(count as f64);
        // The mean of `count` measurements of variance mean(R_i): variance
        // mean(R) / count; the loop acquires again from there.
        let restarted = self
            .fusion
            .reset(z_sum / n, (r_sum / (n * n)).sqrt())
            .is_ok();
        if restarted {
            self.bias = BiasWatch::BLANK;
            self.locked = false;
            self.following = true;
            self.stable_since_us = None;
        }
        restarted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis far from the best-measured one is left out; one within its
    /// spread stays; a single valid axis is kept.
    #[test]
    fn inconsistent_axis_is_left_out() {
        let r = [0.0004, 0.0016, 0.0009];
        let mut valid = [true, true, true];
        drop_inconsistent_axes(&[0.20, 0.80, 0.23], &mut valid, &r);
        assert_eq!(valid, [true, false, true]);
        let mut single = [false, true, false];
        drop_inconsistent_axes(&[0.0, 0.80, 0.0], &mut single, &r);
        assert_eq!(single, [false, true, false]);
    }

    /// On the fix-interval path and once locked, a window beyond `OUTLIER_SIGMA` standard
    /// deviations `sqrt(P + R_i)` is left out and counted; one within stays; acquiring, or on
    /// the grid path, nothing is left out.
    fn outlying_windows_are_left_out_once_locked<T: Scalar>() {
        use crate::delay::{DefaultDelayLoop, DelayLoopConfig};
        let mut config = DelayLoopConfig::<T>::clean_input()
            .adapted_to_gps_rate(T::one())
            .unwrap();
        assert!(config.matched_fix_intervals);
        config.fusion.initial_delay_s = T::lit(0.2);
        // P = (8 ms)^2 and R = (6 ms)^2: sqrt(P + R) = 10 ms, the gate at 30 ms.
        config.fusion.initial_std_s = T::lit(0.008);
        let r = [T::lit(0.006 * 0.006); AXES];
        let z = [T::lit(0.229), T::lit(0.231), T::lit(0.171)];
        let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
        assert!(delay_loop.locked);
        let mut valid = [true, true, false];
        delay_loop.refuse_outliers(&z, &mut valid, &r);
        assert_eq!(valid, [true, false, false]);
        assert_eq!(delay_loop.outlier_windows(), 1);
        let mut valid = [true; AXES];
        delay_loop.refuse_outliers(&z, &mut valid, &r);
        assert_eq!(valid, [true, false, true]);
        assert_eq!(delay_loop.outlier_windows(), 2);
        config.fusion.initial_std_s = T::lit(0.1);
        let mut acquiring = DefaultDelayLoop::<T>::new(config).unwrap();
        assert!(!acquiring.locked);
        let mut valid = [true; AXES];
        acquiring.refuse_outliers(&[T::lit(0.9); AXES], &mut valid, &r);
        assert_eq!((valid, acquiring.outlier_windows()), ([true; AXES], 0));
        config.fusion.initial_std_s = T::lit(0.008);
        config.matched_fix_intervals = false;
        let mut grid = DefaultDelayLoop::<T>::new(config).unwrap();
        assert!(grid.locked);
        let mut valid = [true; AXES];
        grid.refuse_outliers(&[T::lit(0.9); AXES], &mut valid, &r);
        assert_eq!((valid, grid.outlier_windows()), ([true; AXES], 0));
    }

    tests_in_both_precisions!(outlying_windows_are_left_out_once_locked);
}

//! Correlation over the GPS fix intervals themselves, for slow GPS (below
//! [`MATCHED_BELOW_HZ`](super::MATCHED_BELOW_HZ)).
//!
//! The GPS acceleration of eq. (14), `a_gps,k = (v_k - v_{k-n}) / (t_k - t_{k-n})`,
//! is the mean acceleration over the interval `[t_{k-n}, t_k]` (receive
//! times), `tau` earlier. At 10 Hz that interval is short and the grid path
//! (`grid`, [`SlidingCorrelator`](super::SlidingCorrelator)) can compare a
//! smoothed, interpolated `a_gps` with the smoothed IMU acceleration. At 1 Hz
//! it is a 1 s box sampled once a second: the motion above 0.5 Hz is aliased
//! into the GPS stream and nowhere else, and no common smoothing makes the two
//! streams alike (on the high scenario, clean GPS velocities, the grid path's
//! peak fell to 0.2-0.6 and wandered 0.15-0.35 s away from the delay).
//!
//! Here the IMU side is averaged over exactly the same intervals, shifted:
//! for every shift `s` of the window and every fix interval `k` of the
//! buffer,
//!
//! ```text
//! x_k(s) = mean of the IMU grid acceleration over [t_{k-n} - s Tc, t_k - s Tc]
//! y_k    = a_gps,k
//! R(s)   = Pearson(x(s), y) over the intervals of the last buffer_s seconds
//! ```
//!
//! so both streams carry the same box and the same sampling (and therefore
//! the same aliasing) at the true shift. The IMU grid samples are bin means
//! (not smoothed in this mode); each is taken as constant over its bin, so
//! the mean over an interval with fractional ends is exact for that
//! piecewise-constant signal.
//!
//! Cost per update: `M L (w + 2)` vector products for `M` intervals, `L`
//! shifts and `w` grid samples per interval (1 Hz, 25 Hz grid, 10 s buffer,
//! 1 s range: 10 x 26 x 27 = 7 020), recomputed from the stored grid samples,
//! so there is no running sum to drift; nothing per IMU sample beyond the
//! grid.

use nalgebra::Vector3;

use super::correlation::{AxisPeak, parabolic_offset, pearson};
use super::grid::MAX_GPS_DIFF_SPAN;
use super::ring::Ring;
use crate::scalar::{Scalar, zeros_const};

/// Fix intervals kept (32: a 10 s buffer at up to 3.2 Hz, the rates that
/// [`DelayLoopConfig::adapted_to_gps_rate`](super::DelayLoopConfig::adapted_to_gps_rate)
/// sends here hold at most 15; a faster GPS correlates over its last 32
/// intervals).
pub const MATCHED_INTERVALS: usize = 32;

/// One GPS fix interval and its mean acceleration.
#[derive(Debug, Clone, Copy)]
struct Interval<T: Scalar> {
    start_us: u64,
    end_us: u64,
    accel: Vector3<T>,
}

/// The fix-interval correlator: the last fixes, their intervals, and the
/// shift window (signed grid samples).
#[derive(Debug, Clone)]
pub(crate) struct MatchedCorrelator<T: Scalar> {
    period_us: u64,
    /// Smallest shift, grid samples (either sign).
    shift_lo: i64,
    lags: usize,
    buffer_us: u64,
    span: usize,
    fixes: Ring<(u64, Vector3<T>), { MAX_GPS_DIFF_SPAN + 1 }>,
    intervals: Ring<Interval<T>, MATCHED_INTERVALS>,
}

impl<T: Scalar> MatchedCorrelator<T> {
    /// Sized by [`configure`](Self::configure) before use (the delay
    /// loop's blank value).
    pub(crate) const BLANK: Self = Self {
        period_us: 0,
        shift_lo: 0,
        lags: 0,
        buffer_us: 0,
        span: 0,
        fixes: Ring::new((0, zeros_const())),
        intervals: Ring::new(Interval {
            start_us: 0,
            end_us: 0,
            accel: zeros_const(),
        }),
    };

    #[cfg(test)]
    pub(crate) fn new(
        period_us: u64,
        shift_lo: i64,
        lags: usize,
        buffer_us: u64,
        span: usize,
    ) -> Self {
        let mut m = Self::BLANK;
        m.configure(period_us, shift_lo, lags, buffer_us, span);
        m
    }

    /// Sets the sizes and forgets the stream, in place.
    pub(crate) fn configure(
        &mut self,
        period_us: u64,
        shift_lo: i64,
        lags: usize,
        buffer_us: u64,
        span: usize,
    ) {
        self.period_us = period_us;
        self.shift_lo = shift_lo;
        self.lags = lags;
        self.buffer_us = buffer_us;
        self.span = span.clamp(1, MAX_GPS_DIFF_SPAN);
        self.reset();
    }

    /// Forgets the GPS stream (after a gap).
    pub(crate) fn reset(&mut self) {
        self.fixes.clear();
        self.intervals.clear();
    }

    /// Adds one fix (time strictly increasing): a new interval once `n + 1`
    /// fixes are known.
    pub(crate) fn push_fix(&mut self, t_us: u64, v: Vector3<T>) {
        self.fixes.push((t_us, v));
        if let Some((t_old, v_old)) = self.fixes.get(self.span)
            && t_us > t_old
        {
            let dt_s = T::lit((t_us - t_old) as f64 * 1e-6);
            self.intervals.push(Interval {
                start_us: t_old,
                end_us: t_us,
                accel: (v - v_old) / dt_s,
            });
        }
    }

    /// The bin `round(t / Tc)` of a time in µs.
    fn bin(&self, t_us: i64) -> i64 {
        // `period_us >= 1` (`validate_grid`); `max` only makes the divisor
        // provably positive (no reachable panic: benches/no-panic).
        let tc = (self.period_us as i64).max(1);
        t_us.saturating_add(tc / 2).div_euclid(tc)
    }

    /// Mean of the piecewise-constant IMU grid signal (bin `j` covers
    /// `[(j - 1/2) Tc, (j + 1/2) Tc)`) over `[p, q]` µs; `None` when a bin
    /// is missing.
    fn box_mean(
        &self,
        p: i64,
        q: i64,
        imu: &impl Fn(i64) -> Option<Vector3<T>>,
    ) -> Option<Vector3<T>> {
        let tc = self.period_us as i64;
        let mut sum = Vector3::zeros();
        for j in self.bin(p)..=self.bin(q) {
            let lo = j.saturating_mul(2).saturating_sub(1).saturating_mul(tc);
            let hi = j.saturating_mul(2).saturating_add(1).saturating_mul(tc);
            let overlap = q
                .saturating_mul(2)
                .min(hi)
                .saturating_sub(p.saturating_mul(2).max(lo));
            if overlap > 0 {
                sum += imu(j)? * T::lit(overlap as f64);
            }
        }
        Some(sum / T::lit(q.saturating_sub(p).saturating_mul(2) as f64))
    }

    /// The refined correlation peak of each axis over the intervals of the
    /// last buffer whose shifted spans the IMU grid covers (`imu(j)` is grid
    /// sample `j`, `None` when not stored); `None` until the covered
    /// intervals reach back a whole buffer. `shift_samples` counts from
    /// `shift_lo - offset`, as the grid path's does.
    pub(crate) fn peaks<const LAGS: usize>(
        &self,
        offset: usize,
        imu: impl Fn(i64) -> Option<Vector3<T>>,
    ) -> Option<[AxisPeak<T>; 3]> {
        let tc = self.period_us as i64;
        let lags = self.lags.min(LAGS);
        let shift_hi = self.shift_lo.saturating_add(lags as i64).saturating_sub(1);
        let covered = |k: &Interval<T>| {
            let earliest = (k.start_us as i64).saturating_sub(shift_hi.saturating_mul(tc));
            let latest = (k.end_us as i64).saturating_sub(self.shift_lo.saturating_mul(tc));
            imu(self.bin(earliest)).is_some() && imu(self.bin(latest)).is_some()
        };
        // Newest covered interval; the window reaches a buffer back from its end.
        let newest = (0..self.intervals.len())
            .filter_map(|age| self.intervals.get(age))
            .find(|k| covered(k))?;
        let window_start = newest.end_us.checked_sub(self.buffer_us)?;
        let oldest_stored = self.intervals.oldest()?;
        if oldest_stored.start_us > window_start && self.intervals.len() < MATCHED_INTERVALS {
            return None;
        }
        let mut sxy = [[T::zero(); LAGS]; 3];
        let mut sx = [[T::zero(); LAGS]; 3];
        let mut sxx = [[T::zero(); LAGS]; 3];
        let (mut sy, mut syy, mut n) = (Vector3::<T>::zeros(), Vector3::<T>::zeros(), 0usize);
        for age in 0..self.intervals.len() {
            let Some(k) = self.intervals.get(age) else {
                break;
            };
            if k.end_us > newest.end_us || !covered(&k) {
                continue;
            }
            if k.start_us < window_start {
                break;
            }
            let mut means = [Vector3::zeros(); LAGS];
            let mut complete = true;
            for (lag, mean) in means.iter_mut().enumerate().take(lags) {
                let s = self.shift_lo.saturating_add(lag as i64).saturating_mul(tc);
                match self.box_mean(
                    (k.start_us as i64).saturating_sub(s),
                    (k.end_us as i64).saturating_sub(s),
                    &imu,
                ) {
                    Some(m) => *mean = m,
                    None => complete = false,
                }
            }
            if !complete {
                continue;
            }
            let y = k.accel;
            for (lag, x) in means.iter().enumerate().take(lags) {
                for axis in 0..3 {
                    sxy[axis][lag] += x[axis] * y[axis];
                    sx[axis][lag] += x[axis];
                    sxx[axis][lag] += x[axis] * x[axis];
                }
            }
            sy += y;
            syy += y.component_mul(&y);
            n = n.saturating_add(1);
        }
        if n < 3 {
            return None;
        }
        let nt = T::lit(n as f64);
        let mut out = [AxisPeak::default(); 3];
        for (axis, peak) in out.iter_mut().enumerate() {
            let r = |lag: usize| {
                pearson(
                    nt,
                    sxy[axis][lag],
                    sx[axis][lag],
                    sy[axis],
                    sxx[axis][lag],
                    syy[axis],
                )
            };
            let mut best = (0, -T::one() - T::one());
            for lag in 0..lags {
                let value = r(lag);
                if value > best.1 {
                    best = (lag, value);
                }
            }
            let (lag, value) = best;
            let interior = lag > 0 && lag + 1 < lags;
            let refine = if interior {
                parabolic_offset(r(lag - 1), value, r(lag + 1))
            } else {
                T::zero()
            };
            // `lag < lags <= LAGS`: the fallbacks are never taken; `get`
            // keeps a bounds check that could panic out of the push API.
            let at = |sums: &[[T; LAGS]; 3]| sums[axis].get(lag).copied().unwrap_or_else(T::zero);
            let (sx_lag, sxx_lag) = (at(&sx), at(&sxx));
            let x_mean = sx_lag / nt;
            let y_mean = sy[axis] / nt;
            *peak = AxisPeak {
                peak: value,
                shift_samples: T::lit(
                    (offset as i64)
                        .saturating_add(self.shift_lo)
                        .saturating_add(lag as i64) as f64,
                ) + refine,
                accel_variance: (sxx_lag / nt - x_mean * x_mean).max(T::zero()),
                gps_accel_variance: (syy[axis] / nt - y_mean * y_mean).max(T::zero()),
                interior,
            };
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mean over an interval with fractional ends weighs each bin by its
    /// overlap: bins of value `j` (bin `j` covers `[(j - 1/2) Tc, (j + 1/2) Tc)`).
    #[test]
    fn box_mean_weighs_bins_by_overlap() {
        let m = MatchedCorrelator::<f64>::new(20_000, 0, 3, 5_000_000, 1);
        let imu = |j: i64| (j >= 0).then(|| Vector3::repeat(j as f64));
        // [0, 40 ms]: half of bin 0 (10 ms at 0), bin 1 (20 ms at 1), half of bin 2 (10 ms at 2).
        let mean = m.box_mean(0, 40_000, &imu).unwrap();
        assert!((mean[0] - (10.0 * 0.0 + 20.0 * 1.0 + 10.0 * 2.0) / 40.0).abs() < 1e-12);
        // Within one bin: that bin's value.
        assert_eq!(m.box_mean(31_000, 45_000, &imu).unwrap()[1], 2.0);
        // A missing bin: no mean.
        assert!(m.box_mean(-30_000, 10_000, &imu).is_none());
    }

    /// Noise-free: a GPS velocity `tau` late, differenced over each fix
    /// interval, peaks at `tau` against the IMU means over the same
    /// intervals, however fast the motion is against the 1 Hz fixes.
    #[test]
    fn peaks_at_the_delay_with_aliased_motion() {
        let period_us = 40_000u64;
        let tau_s = 0.2;
        // Signed shifts 0..=25 (0 to 1 s at 25 Hz).
        let mut m = MatchedCorrelator::<f64>::new(period_us, 0, 26, 10_000_000, 1);
        let velocity = |t: f64| -3.0 / 1.7 * (1.7 * t).cos() - 2.0 / 4.1 * (4.1 * t).cos();
        // Acceleration 3 sin(1.7 t) + 2 sin(4.1 t): the 0.65 Hz term is above
        // the 1 Hz fixes' Nyquist frequency.
        let samples: std::collections::BTreeMap<i64, f64> = (0..1000i64)
            .map(|j| {
                // The bin mean of the acceleration.
                let t = j as f64 * 0.04;
                let mean = (velocity(t + 0.02) - velocity(t - 0.02)) / 0.04;
                (j, mean)
            })
            .collect();
        let imu = |j: i64| samples.get(&j).map(|&a| Vector3::new(a, 0.0, 0.0));
        for k in 1..=30u64 {
            let t_us = k * 1_000_000 + 3_000;
            let t = t_us as f64 * 1e-6;
            m.push_fix(t_us, Vector3::new(velocity(t - tau_s), 0.0, 0.0));
        }
        let peaks = m.peaks::<61>(0, imu).unwrap();
        let z = peaks[0].shift_samples * 0.04;
        assert!(peaks[0].interior && peaks[0].peak > 0.999, "{:?}", peaks[0]);
        assert!((z - tau_s).abs() < 0.004, "{z}");
    }
}

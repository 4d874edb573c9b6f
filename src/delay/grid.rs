//! From raw streams to the uniform correlation grid (sec. 2.2.2, eq. 14).
//!
//! The correlation runs on a uniform grid of period `Tc` (integer
//! microseconds): grid index `j` is the time `j Tc` on the IMU clock.
//!
//! - IMU side: the NED acceleration samples are averaged per grid bin
//!   (`[j Tc - Tc/2, j Tc + Tc/2)`); each bin mean is placed at the mean
//!   timestamp of its samples (exact for a locally linear signal, so a 50 Hz
//!   stream with +-2 ms jitter is not biased by where its samples fall in the
//!   bins), and the bin means are linearly interpolated onto the grid times.
//!   At 1 kHz the bin mean is a 20-sample box filter (anti-aliasing); at
//!   50 Hz it is a plain linear resampling.
//! - GPS side (eq. 14): `a_gps = (v_k - v_{k-n}) / (t_k - t_{k-n})` with the
//!   fixes' own receive timestamps. It is the mean acceleration over the span,
//!   so it is placed at the middle of the span, `(t_k + t_{k-n}) / 2`: this is
//!   how the lag `n dt / 2` of the difference is accounted for, exactly and
//!   with the real (jittered) fix times. The points are linearly interpolated
//!   onto the grid.
//! - Both grid streams then pass through the same smoothing filter (two
//!   cascaded first-order low-passes, cutoff `fc`). Filtering both signals with
//!   the same `h` turns their cross-correlation into `(h * h~) * R_xy`, and
//!   `h * h~` is symmetric: the filter's lag cancels and the peak does not move.
//!
//! Every step is `O(1)` per input sample; a grid sample is emitted once both
//! of its neighbours are known.

use nalgebra::Vector3;

use super::ring::Ring;
use crate::error::{Error, check};
use crate::scalar::{Scalar, all_finite, zeros_const};
use crate::sensors::check_time;

/// Longest GPS differencing span `n` supported.
pub const MAX_GPS_DIFF_SPAN: usize = 8;

/// Linear interpolation of irregular points onto the grid `j Tc`.
#[derive(Debug, Clone)]
struct GridResampler<T: Scalar> {
    previous: Option<(u64, Vector3<T>)>,
    next_index: u64,
}

impl<T: Scalar> GridResampler<T> {
    const fn new() -> Self {
        Self {
            previous: None,
            next_index: 0,
        }
    }

    /// Adds a point at `t_us` (strictly after the previous one) and emits
    /// every grid sample between the previous point and this one.
    fn push(
        &mut self,
        period_us: u64,
        t_us: u64,
        v: Vector3<T>,
        emit: &mut impl FnMut(u64, Vector3<T>),
    ) {
        match self.previous {
            Some((tp, vp)) if t_us > tp => {
                let span = T::lit((t_us - tp) as f64);
                while self.next_index.saturating_mul(period_us) < t_us {
                    let tj = self.next_index.saturating_mul(period_us);
                    let frac = T::lit(tj.saturating_sub(tp) as f64) / span;
                    emit(self.next_index, vp + (v - vp) * frac);
                    self.next_index = self.next_index.saturating_add(1);
                }
            }
            Some(_) => return,
            // `period_us >= 1` (`validate_grid`: rate <= 1 MHz); `max` only
            // makes the divisor provably non-zero (benches/no-panic).
            None => self.next_index = t_us.div_ceil(period_us.max(1)),
        }
        self.previous = Some((t_us, v));
    }
}

/// Two cascaded first-order low-passes: `s1 += a (x - s1)`, `s2 += a (s1 - s2)`,
/// `a = 1 - exp(-2 pi fc Tc)`; primed with the first sample.
#[derive(Debug, Clone)]
struct Smoother<T: Scalar> {
    alpha: T,
    stages: Option<(Vector3<T>, Vector3<T>)>,
}

impl<T: Scalar> Smoother<T> {
    /// A smoother of gain 0, set by `new` before use (blank values).
    const BLANK: Self = Self {
        alpha: T::ZERO,
        stages: None,
    };

    fn new(cutoff_hz: T, period_s: T) -> Self {
        Self {
            alpha: T::one() - (-T::two_pi() * cutoff_hz * period_s).exp(),
            stages: None,
        }
    }

    fn apply(&mut self, x: Vector3<T>) -> Vector3<T> {
        let (mut s1, mut s2) = self.stages.unwrap_or((x, x));
        s1 += (x - s1) * self.alpha;
        s2 += (s1 - s2) * self.alpha;
        self.stages = Some((s1, s2));
        s2
    }
}

/// Irregular points to smoothed grid samples: the resampler, then the smoother.
#[derive(Debug, Clone)]
struct SmoothedGrid<T: Scalar> {
    period_us: u64,
    resampler: GridResampler<T>,
    smoother: Smoother<T>,
}

impl<T: Scalar> SmoothedGrid<T> {
    const BLANK: Self = Self {
        period_us: 0,
        resampler: GridResampler::new(),
        smoother: Smoother::BLANK,
    };

    fn new(period_us: u64, cutoff_hz: T) -> Self {
        Self {
            period_us,
            resampler: GridResampler::new(),
            smoother: Smoother::new(cutoff_hz, T::lit(period_us as f64 * 1e-6)),
        }
    }

    fn reset(&mut self) {
        self.resampler = GridResampler::new();
        self.smoother.stages = None;
    }

    fn push(&mut self, t_us: u64, v: Vector3<T>, emit: &mut impl FnMut(u64, Vector3<T>)) {
        let smoother = &mut self.smoother;
        self.resampler.push(self.period_us, t_us, v, &mut |j, x| {
            emit(j, smoother.apply(x))
        });
    }
}

/// IMU side: bin means at their mean time, resampled and smoothed.
#[derive(Debug, Clone)]
pub(crate) struct ImuToGrid<T: Scalar> {
    period_us: u64,
    /// Open bin: index, sum of values, sum of time offsets from the bin centre (us), count.
    bin: Option<(u64, Vector3<T>, i64, i64)>,
    grid: SmoothedGrid<T>,
}

impl<T: Scalar> ImuToGrid<T> {
    /// Period 0, replaced by `new` before use (the delay loop's blank value).
    pub(crate) const BLANK: Self = Self {
        period_us: 0,
        bin: None,
        grid: SmoothedGrid::BLANK,
    };

    pub(crate) fn new(period_us: u64, cutoff_hz: T) -> Self {
        Self {
            period_us,
            bin: None,
            grid: SmoothedGrid::new(period_us, cutoff_hz),
        }
    }

    /// The bin means resampled onto the grid, without the smoothing (the
    /// fix-interval correlation averages them itself).
    pub(crate) fn unsmoothed(period_us: u64) -> Self {
        let mut grid = Self::new(period_us, T::one());
        grid.grid.smoother.alpha = T::one();
        grid
    }

    /// Forgets the stream (after a gap); the configuration stays.
    pub(crate) fn reset(&mut self) {
        self.bin = None;
        self.grid.reset();
    }

    /// Adds one sample; emits smoothed grid samples `(j, x_j)`. Refused,
    /// state unchanged: `t_us` beyond [`MAX_GRID_TIME_US`] (the bin and grid
    /// arithmetic would overflow).
    pub(crate) fn push(
        &mut self,
        t_us: u64,
        a: Vector3<T>,
        emit: &mut impl FnMut(u64, Vector3<T>),
    ) -> Result<(), Error> {
        let p = self.period_us;
        let index = grid_index(t_us, p)?;
        // No overflow: index = round(t / p) and t <= MAX_GRID_TIME_US (`grid_index`): |offset| <= p / 2.
        let offset = (t_us as i64).wrapping_sub(index.wrapping_mul(p) as i64);
        match &mut self.bin {
            Some((b, sum, off, n)) if *b == index => {
                *sum += a;
                *off = off.saturating_add(offset);
                *n = n.saturating_add(1);
            }
            open => {
                if let Some((b, sum, off, n)) = open.take() {
                    // round(off / n), half up; n >= 1 in an open bin
                    // (`max` only makes the divisor provably non-zero).
                    let n = n.max(1);
                    let mean_t = (b.saturating_mul(p) as i64).saturating_add(rounded_mean(off, n));
                    let mean = sum / T::lit(n as f64);
                    self.grid.push(mean_t.max(0) as u64, mean, emit);
                }
                *open = Some((index, a, offset, 1));
            }
        }
        Ok(())
    }
}

/// `round(sum / n)` for `n >= 1`, halves rounded up: `floor((2 sum + n) / 2n)`
/// computed as `floor((sum + floor(n / 2)) / n)`, the same value (for odd
/// `n`, `2 sum + n` is odd and `2n` even, so the half dropped from `n / 2`
/// never crosses a multiple of `n`), with `n` itself as the divisor.
fn rounded_mean(sum: i64, n: i64) -> i64 {
    sum.saturating_add(n / 2).div_euclid(n)
}

/// Largest timestamp the correlation grid accepts, us (an eighth of `u64`,
/// about 73 000 years): bin centres, grid times, their signed differences
/// (`i64`) and the shift offsets of negative delays then stay far from
/// overflow.
pub const MAX_GRID_TIME_US: u64 = u64::MAX / 8;

/// The grid bin `round(t / Tc)` of `t_us`, with checked arithmetic: refused
/// beyond [`MAX_GRID_TIME_US`].
pub(crate) fn grid_index(t_us: u64, period_us: u64) -> Result<u64, Error> {
    let refuse = Error::OutOfRange {
        field: "delay.t_us",
        reason: "timestamp beyond MAX_GRID_TIME_US",
    };
    if t_us > MAX_GRID_TIME_US || period_us == 0 {
        return Err(refuse);
    }
    t_us.checked_add(period_us / 2)
        .map(|t| t / period_us)
        .ok_or(refuse)
}

/// GPS side: velocity differences over `n` fixes at the span's midpoint,
/// resampled and smoothed.
#[derive(Debug, Clone)]
pub(crate) struct GpsToGrid<T: Scalar> {
    span: usize,
    fixes: Ring<(u64, Vector3<T>), { MAX_GPS_DIFF_SPAN + 1 }>,
    grid: SmoothedGrid<T>,
}

impl<T: Scalar> GpsToGrid<T> {
    /// Replaced by `new` before use (the delay loop's blank value).
    pub(crate) const BLANK: Self = Self {
        span: 0,
        fixes: Ring::new((0, zeros_const())),
        grid: SmoothedGrid::BLANK,
    };

    pub(crate) fn new(period_us: u64, span: usize, cutoff_hz: T) -> Self {
        Self {
            span: span.clamp(1, MAX_GPS_DIFF_SPAN),
            fixes: Ring::new((0, Vector3::zeros())),
            grid: SmoothedGrid::new(period_us, cutoff_hz),
        }
    }

    /// Forgets the stream (after a gap); the configuration stays.
    pub(crate) fn reset(&mut self) {
        self.fixes.clear();
        self.grid.reset();
    }

    /// Adds one fix (time strictly increasing); emits smoothed grid samples.
    pub(crate) fn push(
        &mut self,
        t_us: u64,
        v: Vector3<T>,
        emit: &mut impl FnMut(u64, Vector3<T>),
    ) {
        self.fixes.push((t_us, v));
        if let Some((t_old, v_old)) = self.fixes.get(self.span) {
            let dt_s = T::lit(t_us.saturating_sub(t_old) as f64 * 1e-6);
            let accel = (v - v_old) / dt_s;
            let mid = t_old.saturating_add(t_us.saturating_sub(t_old) / 2);
            self.grid.push(mid, accel, emit);
        }
    }
}

/// Grid period in whole microseconds for a rate in Hz (rounded).
pub(crate) fn grid_period_us<T: Scalar>(rate_hz: T) -> u64 {
    ((1e6 / rate_hz.as_f64()) + 0.5) as u64
}

/// A duration `>= 0` in grid samples, rounded to nearest.
pub(crate) fn grid_samples<T: Scalar>(seconds: T, period_us: u64) -> usize {
    (seconds.as_f64() * 1e6 / period_us as f64 + 0.5) as usize
}

/// A duration of either sign in grid samples, rounded to nearest.
pub(crate) fn signed_grid_samples<T: Scalar>(seconds: T, period_us: u64) -> i64 {
    let samples = seconds.as_f64() * 1e6 / period_us as f64;
    // `f64::round` needs std: round half away from zero by hand.
    if samples >= 0.0 {
        (samples + 0.5) as i64
    } else {
        ((-samples + 0.5) as i64).saturating_neg()
    }
}

/// How far, in grid samples, the IMU grid stream can run ahead of the GPS
/// one: the GPS difference is placed `n/2` fix gaps back and a grid sample
/// needs the next point, so up to `(n/2 + 1)` of the longest GPS gap, plus
/// the IMU gap and two samples of resampling.
pub(crate) fn lead_samples<T: Scalar>(
    gps_diff_span: usize,
    max_gps_gap_s: T,
    max_imu_gap_s: T,
    period_us: u64,
) -> usize {
    let lead_s =
        (gps_diff_span as f64 / 2.0 + 1.0) * max_gps_gap_s.as_f64() + max_imu_gap_s.as_f64();
    let samples = lead_s * 1e6 / period_us as f64;
    (samples as usize).saturating_add(3)
}

/// `v` is finite and `> 0`.
pub(crate) fn positive_finite<T: Scalar>(v: T) -> bool {
    v.is_finite() && v > T::zero()
}

/// `v` is finite and `>= 0`.
pub(crate) fn non_negative_finite<T: Scalar>(v: T) -> bool {
    v.is_finite() && v >= T::zero()
}

/// Checks the settings shared by the online loop and the offline calibration:
/// grid rate, GPS differencing span, smoothing cutoff, and the duration
/// (`extent`, named `extent_field`) the correlation spans.
pub(crate) fn validate_grid<T: Scalar>(
    rate_hz: T,
    gps_diff_span: usize,
    smoothing_cutoff_hz: T,
    (extent_field, extent_s): (&'static str, T),
) -> Result<(), Error> {
    check::positive_finite(extent_field, extent_s)?;
    check::positive_finite("correlation_rate_hz", rate_hz)?;
    check::at_most("correlation_rate_hz", rate_hz, T::lit(1e6))?;
    check::count_within(
        "gps_diff_span",
        gps_diff_span as u64,
        1,
        MAX_GPS_DIFF_SPAN as u64,
    )?;
    check::positive_finite("smoothing_cutoff_hz", smoothing_cutoff_hz)?;
    check::below(
        "smoothing_cutoff_hz",
        smoothing_cutoff_hz,
        rate_hz * T::lit(0.5),
    )?;
    Ok(())
}

/// Largest magnitude accepted for an acceleration (m/s^2) or velocity (m/s)
/// component: far beyond any vehicle, small enough that the correlation's
/// sums of squares over a buffer cannot overflow `f32`.
pub const MAX_INPUT_MAGNITUDE: f64 = 1e4;

/// Admits one sample of a stream before any state changes: finite values
/// (`field` names them) within [`MAX_INPUT_MAGNITUDE`] and a strictly
/// increasing time no later than [`MAX_GRID_TIME_US`]. Returns whether the
/// gap since the previous sample exceeds `max_gap_s` (the caller restarts
/// its resampling).
pub(crate) fn admit_sample<T: Scalar>(
    stream: &'static str,
    field: &'static str,
    value: &Vector3<T>,
    previous_us: Option<u64>,
    t_us: u64,
    max_gap_s: T,
) -> Result<bool, Error> {
    if !all_finite(value) {
        return Err(Error::NonFinite { field });
    }
    if value.amax() > T::lit(MAX_INPUT_MAGNITUDE) {
        return Err(Error::OutOfRange {
            field,
            reason: "component magnitude above MAX_INPUT_MAGNITUDE",
        });
    }
    if t_us > MAX_GRID_TIME_US {
        return Err(Error::OutOfRange {
            field: "delay.t_us",
            reason: "timestamp beyond MAX_GRID_TIME_US",
        });
    }
    check_time(stream, previous_us, t_us)?;
    Ok(previous_us.is_some_and(|p| T::lit(t_us.saturating_sub(p) as f64 * 1e-6) > max_gap_s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounded_mean_is_the_half_up_rounding_of_the_mean() {
        for n in 1..40i64 {
            for sum in -500..500i64 {
                assert_eq!(
                    rounded_mean(sum, n),
                    (2 * sum + n).div_euclid(2 * n),
                    "{sum} / {n}"
                );
            }
        }
    }

    /// The IMU and GPS paths have no relative lag: a ramp acceleration
    /// `a = c t` fed as jittered 50 Hz IMU samples, and the matching velocity
    /// `v = c t^2 / 2` fed as jittered 5 Hz GPS fixes, give the same grid
    /// samples once the smoothing transients are gone (bin means at their
    /// mean time, differences at their midpoint, linear interpolation: all
    /// exact for these signals).
    #[test]
    fn imu_and_gps_paths_agree_on_a_ramp() {
        let c = 0.7;
        let period_us = 20_000;
        for span in [1, 2, 3] {
            let mut imu = ImuToGrid::<f64>::new(period_us, 1.0);
            let mut gps = GpsToGrid::<f64>::new(period_us, span, 1.0);
            let mut x = std::collections::BTreeMap::new();
            let mut y = std::collections::BTreeMap::new();
            let mut seed = 1u64;
            let mut jitter = |amplitude: i64| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((seed >> 33) as i64 % (2 * amplitude + 1)) - amplitude
            };
            for k in 1..3000u64 {
                let t_us = (1_000_000 + k as i64 * 20_000 + jitter(2_000)) as u64;
                let t = t_us as f64 * 1e-6;
                imu.push(t_us, Vector3::repeat(c * t), &mut |j, v| {
                    x.insert(j, v[0]);
                })
                .unwrap();
            }
            for k in 1..300u64 {
                let t_us = (1_000_000 + k as i64 * 200_000 + jitter(20_000)) as u64;
                let t = t_us as f64 * 1e-6;
                gps.push(t_us, Vector3::repeat(c * t * t / 2.0), &mut |j, v| {
                    y.insert(j, v[0]);
                });
            }
            let first = *y.keys().next().unwrap();
            let mut compared = 0;
            for (j, yv) in y.range(first + 500..) {
                if let Some(xv) = x.get(j) {
                    assert!((xv - yv).abs() < 1e-5, "span {span}, j {j}: {xv} vs {yv}");
                    compared += 1;
                }
            }
            assert!(compared > 1500, "{compared}");
        }
    }

    /// Timestamps near `u64::MAX` are refused with a typed error instead of
    /// overflowing `t + Tc/2` (a panic in debug builds).
    #[test]
    fn timestamps_near_u64_max_are_refused() {
        let mut imu = ImuToGrid::<f64>::new(20_000, 1.0);
        for t_us in [u64::MAX, u64::MAX - 5_000, MAX_GRID_TIME_US + 1] {
            let r = imu.push(t_us, Vector3::zeros(), &mut |_, _| {
                panic!("nothing emitted")
            });
            assert!(
                matches!(
                    r,
                    Err(Error::OutOfRange {
                        field: "delay.t_us",
                        ..
                    })
                ),
                "{r:?}"
            );
        }
        assert!(imu.bin.is_none());
        imu.push(MAX_GRID_TIME_US, Vector3::zeros(), &mut |_, _| {})
            .unwrap();
        assert_eq!(grid_index(u64::MAX, 20_000).ok(), None);
        assert_eq!(grid_index(30_000, 20_000).ok(), Some(2));
        let refused = admit_sample("imu", "a", &Vector3::<f32>::zeros(), None, u64::MAX, 0.1);
        assert!(matches!(refused, Err(Error::OutOfRange { .. })));
    }

    /// Each grid index is emitted once, in order, without gaps.
    #[test]
    fn grid_indices_are_consecutive() {
        let mut imu = ImuToGrid::<f32>::new(20_000, 1.0);
        let mut last: Option<u64> = None;
        for k in 1..2000u64 {
            // 1 kHz with an uneven pattern of intervals.
            let t_us = k * 1000 + (k % 7) * 50;
            imu.push(t_us, Vector3::zeros(), &mut |j, _| {
                if let Some(l) = last {
                    assert_eq!(j, l + 1);
                }
                last = Some(j);
            })
            .unwrap();
        }
        assert!(last.unwrap() > 90);
    }
}

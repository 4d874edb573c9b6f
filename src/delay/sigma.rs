//! The reported standard deviation: the gain fusion's, matched to the
//! innovations the loop actually sees from its first valid update, plus the
//! bias its windows keep showing on one side; the horizon's
//! innovation windows as a second observation of the delay.

use super::delay_loop::acquiring_window_variance;
use super::{AXES, DelayLoop};
use crate::scalar::Scalar;
use crate::zero_option::ZeroOption;

/// Time constant of the innovation match that scales the reported sigma, s
/// (two independent 5 s buffers). Until it has seen that many updates, the
/// match is the plain mean of the windows so far (weight `1 / n` for the
/// `n`-th, `n` counted up to 255): one window alone would set it.
pub const SIGMA_MATCH_TIME_S: f64 = 10.0;

/// Smallest squared scale of the reported sigma (the scale never exceeds 1:
/// it only removes the pessimism of the noise model).
pub const SIGMA_SCALE2_MIN: f64 = 0.01;

/// The bias watch ([`DelayLoop::delay_std_s`]) counts the squared running mean of the
/// innovations beyond this many times the variance the windows' own scatter gives that mean
/// (1 would be its unbiased estimate; 2 keeps the calibrated runs' sigma from growing on the
/// noise of the mean: the delay suite's `sigma_coverage` stays within its band).
pub const BIAS_NOISE_FACTOR: f64 = 2.0;

/// Largest squared scale of the reported sigma with the innovation
/// observation on (its windows' variances are measured, not pessimistic, so
/// the match may widen the sigma as well as narrow it).
pub const SIGMA_SCALE2_MAX: f64 = 16.0;

/// The bias watch: the running mean `m` of the windows' innovation (the valid axes' mean
/// weighted by `1 / R_i`, s), the running mean of its squared deviation from that mean
/// (`spread`, s^2), and the time the windows it has seen span (s).
///
/// Successive windows share most of their data (at 10 Hz, 49 of 50 fixes of a 5 s buffer), so
/// neither their count nor their scatter says how much the mean has averaged:
///
/// ```text
/// n      = clamp(span / T_buffer, 1, 2 T_match / T_buffer)     independent windows in m
/// s_w^2  = spread max(1, T_buffer / span)                      one window's variance
/// b^2    = max(0, m^2 - k s_w^2 / n)                           k = BIAS_NOISE_FACTOR
/// ```
///
/// Over a span shorter than one buffer the windows are one measurement (`n = 1`), and their
/// scatter is the drift of a moving window, about `span / T_buffer` of one window's variance.
/// Counting windows instead made the first two or three windows after a calibrated start
/// (one measurement, 60-90 ms from the estimate on the low scenario's first manoeuvre) a
/// bias: the reported sigma went from 22 to 92 ms and the delay invalid for 5 s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BiasWatch<T> {
    mean: T,
    spread: T,
    span_s: T,
}

impl<T: Scalar> BiasWatch<T> {
    /// No window seen.
    pub(crate) const BLANK: Self = Self {
        mean: T::ZERO,
        spread: T::ZERO,
        span_s: T::ZERO,
    };

    /// One window's innovation `e` (s), with the running mean's weight `alpha` and the time
    /// since the previous window `dt_s`.
    fn add(&mut self, e: T, alpha: T, dt_s: T) {
        let d = e - self.mean;
        self.mean += alpha * d;
        self.spread += alpha * (d * d - self.spread);
        self.span_s += dt_s;
    }

    /// The squared bias beyond the noise of the mean, s^2 (type docs).
    fn bias2(&self, buffer_s: T) -> T {
        if buffer_s <= T::zero() {
            return T::zero();
        }
        let span = self.span_s.max(T::lit(1e-6));
        let independent = (span / buffer_s)
            .min(T::lit(2.0 * SIGMA_MATCH_TIME_S) / buffer_s)
            .max(T::one());
        let window_variance = self.spread * (buffer_s / span).max(T::one());
        let k = T::lit(BIAS_NOISE_FACTOR);
        (self.mean * self.mean - k * window_variance / independent).max(T::zero())
    }
}

impl<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize>
    DelayLoop<T, BUF, LAGS, HIST>
{
    /// The squared scale applied to the GFA's variance: the mean normalized
    /// innovation squared from the first valid update on (1 before it, and while
    /// following after a re-acquisition), within `[SIGMA_SCALE2_MIN, 1]`.
    pub(super) fn sigma_scale2(&self) -> T {
        if self.config.innovation_window_s > T::zero() {
            return if self.locked && !self.following && self.window_nis > T::zero() {
                self.window_nis
                    .clamp(T::lit(SIGMA_SCALE2_MIN), T::lit(SIGMA_SCALE2_MAX))
            } else {
                T::one()
            };
        }
        if self.innovations_matched > 0 && !self.following {
            self.innovation_ratio
                .clamp(T::lit(SIGMA_SCALE2_MIN), T::one())
        } else {
            T::one()
        }
    }

    /// The bias watch, s^2 ([`BiasWatch::bias2`]); 0 while following after a
    /// re-acquisition.
    pub(super) fn bias2(&self) -> T {
        if self.following || self.innovations_matched == 0 {
            return T::zero();
        }
        self.bias.bias2(self.config.buffer_s)
    }

    /// Covariance matching: the running mean, over [`SIGMA_MATCH_TIME_S`],
    /// of the valid axes' squared innovations `(z_i - tau)^2` divided by their
    /// predicted variance `P + Q + R_i` (one buffer's `R_i`: successive
    /// windows share their data, so one window is one measurement of that
    /// variance); and the bias watch's running mean and variance of the
    /// innovation of the valid axes' mean weighted by `1 / R_i`
    /// ([`bias2`](Self::bias2)). From the first valid update on, acquiring or
    /// locked (one sigma throughout, no step at the lock); not while following.
    pub(super) fn match_innovations(
        &mut self,
        dt_s: T,
        q_s2: T,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) {
        if self.following {
            return;
        }
        let tau = self.fusion.delay_s();
        let p = self.fusion.variance_s2() + q_s2;
        let (mut sum, mut n) = (T::zero(), T::zero());
        let (mut weighted, mut weight) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let e = z[axis] - tau;
            sum += e * e / (p + r_buffer_s2[axis]);
            n += T::one();
            weighted += e / r_buffer_s2[axis];
            weight += T::one() / r_buffer_s2[axis];
        }
        if n > T::zero() {
            self.innovations_matched = self.innovations_matched.saturating_add(1);
            let alpha = (dt_s / T::lit(SIGMA_MATCH_TIME_S))
                .min(T::one())
                .max(T::one() / T::lit(f64::from(self.innovations_matched)));
            self.innovation_ratio += alpha * (sum / n - self.innovation_ratio);
            if weight > T::zero() {
                self.bias.add(weighted / weight, alpha, dt_s);
            }
        }
    }

    /// The last window of the innovation observation: `(delay, std)`, s.
    pub fn innovation_estimate(&self) -> Option<(T, T)> {
        self.innovation_window.get()
    }

    /// Fuses the innovation window, when one is complete, into the gain
    /// fusion with its variance times
    /// [`DelayLoopConfig::innovation_noise_scale`].
    pub(super) fn fuse_innovations(&mut self, t_us: u64) {
        let window_s = self.config.innovation_window_s;
        if window_s <= T::zero() {
            return;
        }
        let Some((z, variance)) = self.innovation.take(t_us, window_s) else {
            return;
        };
        let previous = self.innovation_window.get();
        self.innovation_window = ZeroOption::Some((z, variance.sqrt()));
        if !(self.locked || self.config.innovation_before_lock) {
            return;
        }
        let r = if self.locked {
            variance * self.config.innovation_noise_scale
        } else {
            match acquiring_window_variance(&self.config, (z, variance), previous) {
                Some(r) => r,
                None => return,
            }
        };
        let e = z - self.fusion.delay_s();
        let nis = e * e / (self.fusion.variance_s2() + r);
        if self.locked && !self.following {
            let alpha = if self.window_nis > T::zero() {
                (window_s / T::lit(SIGMA_MATCH_TIME_S)).min(T::one())
            } else {
                T::one()
            };
            self.window_nis += alpha * (nis - self.window_nis);
        }
        // A window far outside the estimate's spread: the delay moved (a
        // step); restart from the window rather than pull at the GFA's pace.
        let k = self.config.innovation_reacquire_sigma;
        if k > T::zero() && nis > k * k && self.fusion.reset(z, r.sqrt()).is_ok() {
            return;
        }
        let _ = self.fusion.update(z, r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delay::*;
    use approx::assert_relative_eq;

    /// The innovation match starts as the plain mean of the windows: a first
    /// window at 4x its predicted variance and a second at 0 give 2, not the
    /// first window's 4 (then forgetting at `dt / SIGMA_MATCH_TIME_S`).
    fn match_starts_as_a_mean<T: Scalar>() {
        let mut config = DelayLoopConfig::<T>::clean_input();
        config.fusion.initial_std_s = T::lit(0.01);
        let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
        assert!(delay_loop.locked);
        let tau = delay_loop.delay_s();
        let (dt, q) = (T::lit(0.1), T::zero());
        let r = [T::lit(0.01 * 0.01); AXES];
        // (z - tau)^2 / (P + R) = 4 with P = R = 1e-4 s^2.
        let far = [tau + T::lit(0.02 * 2.0_f64.sqrt()); AXES];
        let valid = [true; AXES];
        delay_loop.match_innovations(dt, q, &far, &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(4.0),
            max_relative = T::lit(1e-4)
        );
        delay_loop.match_innovations(dt, q, &[tau; AXES], &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(2.0),
            max_relative = T::lit(1e-4)
        );
        // The mean of 4 and 98 zeros after 100 windows; then forgetting at
        // dt / SIGMA_MATCH_TIME_S = 0.01 per window.
        for _ in 0..98 {
            delay_loop.match_innovations(dt, q, &[tau; AXES], &valid, &r);
        }
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(0.04),
            max_relative = T::lit(1e-3)
        );
        delay_loop.match_innovations(dt, q, &far, &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(0.04 + 0.01 * (4.0 - 0.04)),
            max_relative = T::lit(1e-3)
        );
    }

    /// The bias watch: windows that keep disagreeing with the estimate on one side
    /// (+20 ms) put that disagreement into the reported sigma; windows scattered as much
    /// on both sides (+-20 ms) do not.
    fn bias_watch_counts_a_persistent_offset<T: Scalar>() {
        let mut config = DelayLoopConfig::<T>::clean_input();
        config.fusion.initial_std_s = T::lit(0.01);
        let (dt, q) = (T::lit(0.1), T::zero());
        let r = [T::lit(0.01 * 0.01); AXES];
        let valid = [true; AXES];
        let run = |offset: fn(usize) -> f64| {
            let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
            let tau = delay_loop.delay_s();
            for k in 0..200 {
                let z = [tau + T::lit(offset(k)); AXES];
                delay_loop.match_innovations(dt, q, &z, &valid, &r);
            }
            (
                delay_loop.bias2().sqrt().as_f64(),
                delay_loop.delay_std_s().as_f64(),
            )
        };
        let (bias, std) = run(|_| 0.02);
        assert!((bias - 0.02).abs() < 1e-4, "{bias}");
        assert!(std >= 0.02, "{std}");
        let (bias, std) = run(|k| if k % 2 == 0 { 0.02 } else { -0.02 });
        assert!(bias < 1e-6, "{bias}");
        assert!(std < 0.011, "{std}");
    }

    /// The first windows after a calibrated start are one measurement: three windows 0.1 s
    /// apart, 80 ms from the estimate, raise no bias (counted as three independent windows,
    /// they made it 71 ms); the same offset held for 20 s is a bias.
    fn bias_watch_waits_for_independent_windows<T: Scalar>() {
        let mut config = DelayLoopConfig::<T>::clean_input();
        config.fusion.initial_std_s = T::lit(0.01);
        let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
        let tau = delay_loop.delay_s();
        let (dt, q) = (T::lit(0.1), T::zero());
        let r = [T::lit(0.04 * 0.04); AXES];
        let valid = [true; AXES];
        let z = [tau + T::lit(0.08); AXES];
        for _ in 0..3 {
            delay_loop.match_innovations(dt, q, &z, &valid, &r);
        }
        assert_eq!(delay_loop.bias2(), T::zero());
        for _ in 0..200 {
            delay_loop.match_innovations(dt, q, &z, &valid, &r);
        }
        let bias = delay_loop.bias2().sqrt().as_f64();
        assert!((bias - 0.08).abs() < 1e-3, "{bias}");
    }

    tests_in_both_precisions!(
        match_starts_as_a_mean,
        bias_watch_counts_a_persistent_offset,
        bias_watch_waits_for_independent_windows
    );
}

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

    /// The bias watch, s^2: the square of the running mean innovation `m` beyond
    /// [`BIAS_NOISE_FACTOR`] times the variance its own scatter gives it,
    /// `max(0, m^2 - k s_e^2 / n)`, `s_e^2` the running variance of the windows' innovations
    /// and `n` the independent windows in the running mean (`2 T_match / T_buffer`, at most
    /// the windows seen): an error the windows keep showing on one side, which the
    /// normalized squares of [`match_innovations`](Self::match_innovations) hide under the
    /// noise model's `R_i`. 0 while following after a re-acquisition.
    pub(super) fn bias2(&self) -> T {
        if self.following || self.innovations_matched == 0 {
            return T::zero();
        }
        let n = T::lit(f64::from(self.innovations_matched));
        let independent = (T::lit(2.0 * SIGMA_MATCH_TIME_S) / self.config.buffer_s).min(n);
        let k = T::lit(BIAS_NOISE_FACTOR);
        (self.bias_mean * self.bias_mean - k * self.bias_spread / independent).max(T::zero())
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
            if weight <= T::zero() {
                return;
            }
            let d = weighted / weight - self.bias_mean;
            self.bias_mean += alpha * d;
            self.bias_spread += alpha * (d * d - self.bias_spread);
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

    tests_in_both_precisions!(
        match_starts_as_a_mean,
        bias_watch_counts_a_persistent_offset
    );
}

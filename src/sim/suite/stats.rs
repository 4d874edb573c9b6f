//! Monte Carlo statistics of the suites.
//!
//! - **Confidence interval of a figure** ([`mean_ci95`]): the Student t-interval of the mean
//!   over the seeds, `mean ± t_{0.975, n-1} s / sqrt(n)` with `s` the sample standard deviation
//!   (seeds are independent runs; a figure is one run's RMSE, close enough to normal over 20
//!   seeds for the interval to hold).
//! - **Chi-square band** ([`chi2_band95`]): a consistent filter's NEES (or NIS) of `d` degrees
//!   of freedom is chi-square with `d` degrees; the average of `n` independent ones lies, with
//!   95 % probability, in `[chi2_{0.025}(n d) / n, chi2_{0.975}(n d) / n]` (Bar-Shalom, Li and
//!   Kirubarajan, *Estimation with Applications to Tracking and Navigation*, sec. 5.4).
//! - **Medians** ([`median`], [`median_ordered`]) and the root mean square ([`Rms`]).
//!
//! A failed run (a figure that is not finite) shows as NaN in every statistic instead of being
//! averaged away.

use statrs::distribution::{ChiSquared, ContinuousCDF, StudentsT};

/// Mean of the values and the 95 % t-interval of the mean, `(mean, lo, hi)`.
/// NaN everywhere when a value is not finite (a failed run shows); the
/// interval is NaN with fewer than two values.
pub fn mean_ci95(xs: &[f64]) -> (f64, f64, f64) {
    if xs.is_empty() || xs.iter().any(|x| !x.is_finite()) {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    if xs.len() < 2 {
        return (mean, f64::NAN, f64::NAN);
    }
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let t = StudentsT::new(0.0, 1.0, n - 1.0).map_or(f64::NAN, |d| d.inverse_cdf(0.975));
    let half = t * (var / n).sqrt();
    (mean, mean - half, mean + half)
}

/// The 95 % band of the average of `count` independent chi-square variables
/// of `dof` degrees each, `(lo, hi)`; NaN for no variables.
pub fn chi2_band95(dof: usize, count: usize) -> (f64, f64) {
    let k = (dof * count) as f64;
    match ChiSquared::new(k) {
        Ok(d) if count > 0 => (
            d.inverse_cdf(0.025) / count as f64,
            d.inverse_cdf(0.975) / count as f64,
        ),
        _ => (f64::NAN, f64::NAN),
    }
}

/// Median of finite values; NaN when any is not finite (a failed run shows).
pub fn median(xs: Vec<f64>) -> f64 {
    if xs.iter().any(|x| !x.is_finite()) {
        return f64::NAN;
    }
    median_ordered(xs)
}

/// Median in `f64::total_cmp` order (infinities sort to the ends, so a run
/// that never settled counts as the slowest); NaN for no values.
pub fn median_ordered(mut xs: Vec<f64>) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Median that keeps infinite values (a run that never settled) in order and
/// is NaN when a value is NaN.
pub fn median_with_infinity(xs: Vec<f64>) -> f64 {
    if xs.iter().any(|x| x.is_nan()) {
        return f64::NAN;
    }
    median_ordered(xs)
}

/// Root mean square accumulator.
#[derive(Debug, Default, Clone, Copy)]
pub struct Rms {
    sum_sq: f64,
    n: usize,
}

impl Rms {
    /// Adds one value.
    pub fn add(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }

    /// The root mean square of the values added; NaN for none.
    pub fn value(self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_interval_and_chi_square_band_match_tables() {
        // t_{0.975, 4} = 2.776; chi2_{0.025, 6} = 1.237, chi2_{0.975, 6} = 14.449.
        let (m, lo, hi) = mean_ci95(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!((m - 3.0).abs() < 1e-12);
        assert!((hi - m - 2.776 * (2.5f64 / 5.0).sqrt()).abs() < 1e-3);
        assert!((m - lo - (hi - m)).abs() < 1e-12);
        let (lo, hi) = chi2_band95(6, 1);
        assert!((lo - 1.237).abs() < 1e-3 && (hi - 14.449).abs() < 1e-3);
        // The average of 2: chi2_{0.025, 12} / 2 = 4.404 / 2, chi2_{0.975, 12} / 2 = 23.337 / 2.
        let (lo, hi) = chi2_band95(6, 2);
        assert!((lo - 4.404 / 2.0).abs() < 1e-3 && (hi - 23.337 / 2.0).abs() < 1e-3);
    }

    /// A failed run (a value not finite) shows as NaN instead of being averaged away; one value
    /// has a mean and no interval; nothing has neither.
    #[test]
    fn a_failed_or_missing_run_shows() {
        let all_nan = |(m, lo, hi): (f64, f64, f64)| m.is_nan() && lo.is_nan() && hi.is_nan();
        assert!(all_nan(mean_ci95(&[1.0, f64::NAN, 3.0])));
        assert!(all_nan(mean_ci95(&[1.0, f64::INFINITY, 3.0])));
        assert!(all_nan(mean_ci95(&[])));
        let (m, lo, hi) = mean_ci95(&[2.5]);
        assert!(m == 2.5 && lo.is_nan() && hi.is_nan());
        assert_eq!(mean_ci95(&[2.0, 2.0, 2.0]), (2.0, 2.0, 2.0));
        let (lo, hi) = chi2_band95(6, 0);
        assert!(lo.is_nan() && hi.is_nan());
    }

    #[test]
    fn medians_keep_failed_runs_visible() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(vec![1.0, f64::NAN, 2.0]).is_nan());
        assert!(median(vec![1.0, f64::INFINITY, 2.0]).is_nan());
        assert!(median(Vec::new()).is_nan());
        assert_eq!(median_ordered(vec![f64::INFINITY, 1.0, 2.0]), 2.0);
        assert_eq!(
            median_ordered(vec![f64::INFINITY, 1.0, f64::INFINITY]),
            f64::INFINITY
        );
        assert_eq!(median_with_infinity(vec![2.0, f64::INFINITY, 3.0]), 3.0);
        assert!(median_with_infinity(vec![2.0, f64::NAN, 3.0]).is_nan());
        let mut rms = Rms::default();
        assert!(rms.value().is_nan());
        rms.add(3.0);
        rms.add(-4.0);
        assert!((rms.value() - 12.5f64.sqrt()).abs() < 1e-12);
    }
}

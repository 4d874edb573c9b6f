//! Statistics over the seeds of a scenario: every figure's mean, 95 % interval and median
//! ([`Summary`]), the filters' consistency ([`Consistency`]), and the paired differences of
//! `proposed` against other rows on the same seeds.

use super::ScenarioResult;
use super::score::{Metrics, RunScore};
use crate::sim::suite::stats::{chi2_band95, mean_ci95, median};

/// Degrees of freedom of the NEES (position and velocity) and of the GPS NIS.
pub const CONSISTENCY_DOF: usize = 6;

/// A scalar figure of an entry: its JSON name and how to read it.
pub type Figure = (&'static str, fn(&Metrics) -> Option<f64>);

/// The scalar figures of an estimator's JSON entry, in order.
pub const FIGURES: [Figure; 10] = [
    ("roll_deg", |m| Some(m.roll_deg)),
    ("pitch_deg", |m| Some(m.pitch_deg)),
    ("yaw_deg", |m| Some(m.yaw_deg)),
    ("tilt_deg", |m| Some(m.tilt_deg)),
    ("heading_deg", |m| Some(m.heading_deg)),
    ("vel_m_s", |m| Some(m.vel_m_s)),
    ("pos_m", |m| Some(m.pos_m)),
    ("delay_s", |m| m.delay_s),
    ("nis_run_mean", |m| m.nis),
    ("us_per_imu_sample", |m| Some(m.us_per_imu_sample)),
];

/// Figures of the paired comparison: the errors of [`FIGURES`] (roll to position).
pub const PAIRED_FIGURES: &[Figure] = FIGURES.split_at(7).0;

/// The paired comparisons printed and written: `proposed` against each.
pub const PAIRED_AGAINST: [&str; 4] = ["oracle", "aekf17", "ekf16", "calibrated"];

/// A mean over the seeds with its 95 % interval, `(mean, lo, hi)`.
pub type MeanCi = (f64, f64, f64);

/// Mean over the seeds of every figure, the bounds of its 95 %
/// t-interval ([`mean_ci95`]), and its median.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Means.
    pub mean: Metrics,
    /// Lower ends of the 95 % t-intervals.
    pub lo: Metrics,
    /// Upper ends of the 95 % t-intervals.
    pub hi: Metrics,
    /// Medians.
    pub median: Metrics,
}

/// One statistic over the seeds of every figure of an estimator.
fn metrics_over(runs: &[Metrics], stat: &dyn Fn(&[f64]) -> f64) -> Metrics {
    let m = |f: &dyn Fn(&Metrics) -> f64| stat(&runs.iter().map(f).collect::<Vec<_>>());
    let opt = |f: &dyn Fn(&Metrics) -> Option<f64>| {
        runs.first()
            .and_then(f)
            .is_some()
            .then(|| m(&|r| f(r).unwrap_or(f64::NAN)))
    };
    // Every field of `Metrics`: the scalars, the optional ones, the per-axis ones.
    macro_rules! over {
        ($($scalar:ident)*; $($optional:ident)*; $($axes:ident)*) => {
            Metrics {
                $($scalar: m(&|r| r.$scalar),)*
                $($optional: opt(&|r| r.$optional),)*
                $($axes: core::array::from_fn(|i| m(&|r| r.$axes[i])),)*
            }
        };
    }
    over!(
        roll_deg pitch_deg yaw_deg tilt_deg heading_deg vel_m_s pos_m us_per_imu_sample;
        delay_s nees nis;
        gyro_bias_rad_s accel_bias_g
    )
}

/// Every figure of `runs` (one per seed) summarized over the seeds; a figure that the first
/// run has not (no delay) stays absent, and one that a later run lacks is NaN.
pub fn summarize(runs: &[Metrics]) -> Summary {
    Summary {
        mean: metrics_over(runs, &|xs| mean_ci95(xs).0),
        lo: metrics_over(runs, &|xs| mean_ci95(xs).1),
        hi: metrics_over(runs, &|xs| mean_ci95(xs).2),
        median: metrics_over(runs, &|xs| median(xs.to_vec())),
    }
}

/// Filter consistency of one estimator over the seeds of a scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Consistency {
    /// Time average of the seed-averaged NEES (position and velocity); NaN when an instant
    /// has no estimate.
    pub nees_mean: f64,
    /// 95 % band of a seed-averaged NEES at one instant.
    pub nees_band: (f64, f64),
    /// Share of the NEES instants whose seed average lies in the band.
    pub nees_in_band: f64,
    /// Mean GPS NIS over every scored fix of every seed.
    pub nis_mean: f64,
    /// 95 % band of that mean (innovations of a consistent filter are white).
    pub nis_band: (f64, f64),
}

/// The consistency of one estimator from its runs on every seed: the NEES averaged over the
/// seeds at each instant (the instants every seed has), then over time; the NIS over every
/// scored fix.
pub fn consistency(scores: &[RunScore]) -> Consistency {
    let instants = scores
        .iter()
        .map(|s| s.nees_series.len())
        .min()
        .unwrap_or(0);
    let seeds = scores.len();
    let averaged: Vec<f64> = (0..instants)
        .map(|k| scores.iter().map(|s| s.nees_series[k]).sum::<f64>() / seeds as f64)
        .collect();
    let finite: Vec<f64> = averaged.iter().copied().filter(|x| x.is_finite()).collect();
    let nees_band = chi2_band95(CONSISTENCY_DOF, seeds);
    let nees_mean = if finite.is_empty() || finite.len() < averaged.len() {
        f64::NAN
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    };
    let inside = finite
        .iter()
        .filter(|x| (nees_band.0..=nees_band.1).contains(*x))
        .count();
    let (nis_sum, nis_count) = scores
        .iter()
        .fold((0.0, 0), |(s, n), r| (s + r.nis.0, n + r.nis.1));
    Consistency {
        nees_mean,
        nees_band,
        nees_in_band: inside as f64 / averaged.len().max(1) as f64,
        nis_mean: if nis_count > 0 {
            nis_sum / nis_count as f64
        } else {
            f64::NAN
        },
        nis_band: chi2_band95(CONSISTENCY_DOF, nis_count),
    }
}

impl ScenarioResult {
    /// Per figure of [`PAIRED_FIGURES`], the mean over the seeds of `proposed - other` on the
    /// same seed and its 95 % t-interval, `(mean, lo, hi)`; `None` when a row is missing.
    pub fn paired(&self, other: &str) -> Option<Vec<(&'static str, MeanCi)>> {
        let runs = |name: &str| {
            self.per_seed
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, m)| m)
        };
        let (p, o) = (runs("proposed")?, runs(other)?);
        Some(
            PAIRED_FIGURES
                .iter()
                .map(|(name, get)| {
                    let d: Vec<f64> = p
                        .iter()
                        .zip(o)
                        .map(|(a, b)| get(a).unwrap_or(f64::NAN) - get(b).unwrap_or(f64::NAN))
                        .collect();
                    (*name, mean_ci95(&d))
                })
                .collect(),
        )
    }

    /// The mean figures of the row `name`.
    pub fn mean(&self, name: &str) -> Option<&Metrics> {
        self.summaries
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, s)| &s.mean)
    }
}

#[cfg(test)]
mod tests {
    //! The tables' statistics over seeds on made-up figures.

    use super::*;
    use crate::sim::suite::tables::Trace;

    /// Every figure of one run equal to `x` (delay, NEES and NIS present).
    fn metrics(x: f64) -> Metrics {
        Metrics {
            roll_deg: x,
            pitch_deg: x,
            yaw_deg: x,
            tilt_deg: x,
            heading_deg: x,
            vel_m_s: x,
            pos_m: x,
            delay_s: Some(x),
            gyro_bias_rad_s: [x; 3],
            accel_bias_g: [x; 3],
            nees: Some(x),
            nis: Some(x),
            us_per_imu_sample: x,
        }
    }

    fn run(nees_series: Vec<f64>, nis: (f64, usize)) -> RunScore {
        RunScore {
            metrics: metrics(1.0),
            trace: Trace::default(),
            nees_series,
            nis,
        }
    }

    #[test]
    fn every_figure_is_summarized_over_the_seeds() {
        let runs = [metrics(1.0), metrics(2.0), metrics(6.0)];
        let summary = summarize(&runs);
        assert_eq!(summary.mean.pos_m, 3.0);
        assert_eq!(summary.median.vel_m_s, 2.0);
        assert_eq!(summary.mean.accel_bias_g, [3.0; 3]);
        assert_eq!(summary.mean.delay_s, Some(3.0));
        assert!(summary.lo.tilt_deg < 3.0 && summary.hi.tilt_deg > 3.0);
        assert!(
            (summary.mean.tilt_deg - summary.lo.tilt_deg - (summary.hi.tilt_deg - 3.0)).abs()
                < 1e-12
        );
        // A figure the estimator does not have stays absent; one seed without it fails it.
        let mut without = runs.clone();
        for r in &mut without {
            r.delay_s = None;
        }
        assert_eq!(summarize(&without).mean.delay_s, None);
        without[0].delay_s = Some(1.0);
        assert!(summarize(&without).mean.delay_s.is_some_and(f64::is_nan));
        // A failed seed shows in the mean and the median.
        let mut failed = runs.clone();
        failed[1].pos_m = f64::NAN;
        let summary = summarize(&failed);
        assert!(summary.mean.pos_m.is_nan() && summary.median.pos_m.is_nan());
    }

    #[test]
    fn consistency_averages_over_seeds_then_over_time() {
        // Two seeds: seed-averaged NEES 6, 6, 100 (the last outside the 95 % band).
        let scores = [
            run(vec![5.0, 7.0, 100.0], (12.0, 2)),
            run(vec![7.0, 5.0, 100.0], (0.0, 0)),
        ];
        let c = consistency(&scores);
        assert!((c.nees_mean - 112.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.nees_band, chi2_band95(CONSISTENCY_DOF, 2));
        assert!((c.nees_in_band - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.nis_mean, 6.0);
        assert_eq!(c.nis_band, chi2_band95(CONSISTENCY_DOF, 2));
        // An instant without an estimate makes the mean NaN, and is not in the band.
        let lost = [
            run(vec![5.0, f64::NAN, 6.0], (0.0, 0)),
            run(vec![7.0, 5.0, 6.0], (0.0, 0)),
        ];
        let c = consistency(&lost);
        assert!(c.nees_mean.is_nan() && c.nis_mean.is_nan());
        assert!((c.nees_in_band - 2.0 / 3.0).abs() < 1e-12);
        // Seeds of different lengths: the common instants only.
        let c = consistency(&[run(vec![6.0, 6.0], (0.0, 0)), run(vec![6.0], (0.0, 0))]);
        assert_eq!((c.nees_mean, c.nees_in_band), (6.0, 1.0));
    }
}

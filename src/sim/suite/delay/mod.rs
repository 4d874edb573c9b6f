//! The delay suite: how fast the delay loop locks on, how it follows changes, at which GPS
//! rates it works, what it reports outside its range, whether its sigma is honest, and how the
//! augmented EKF's delay state behaves at hover. docs/delay.md explains every row.
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --delay-suite --json target/delay-suite.json
//! cargo run --release --features sim --example reproduce -- --delay-trace cold_start_high --seed 1
//! ```
//!
//! **Scenario.** Unless a row says otherwise: the `proposed` navigator with the delay loop's
//! defaults whatever the GPS rate (nothing adapted by the caller), no offline calibration, start
//! 0.1 s, [`RUN_S`] runs, [`DelayOptions::seeds`] with the median reported, delay RMSE scored
//! from [`SCORE_FROM_S`]. Rows ([`ROW_NAMES`]): `cold_start_low`, `cold_start_high` (constant
//! 0.2 s), `delay_step` (0.2 -> 0.35 s at 20 s, calibrated start: the settle time), `delay_ramp`
//! (+60 ms over the run) and `delay_ramp_coverage` (its runs' share of samples within 1 sigma
//! from 20 s), `delay_jitter` (uniform +-20 ms), `gps_2hz`, `gps_1hz`, `gps_rate_drop` (10 Hz,
//! then one fix in ten from 30 s: RMSE from 40 s), `negative_delay` (true -0.15 s, range
//! -0.5..0.6 s), `out_of_range_reported` (true -0.15 s, default range: the time until the
//! below-range status) and `out_of_range_weak` (the same in the low scenario with the GPS
//! velocity noise doubled), `sigma_coverage` (low and high, calibrated start, pooled over
//! [`DelayOptions::coverage_seeds`]), `gentle_motion` (a ground vehicle shuttling at 2 m/s^2
//! peak, 200 Hz IMU, true 0.15 s, start 0.2 s, 120 s: RMSE from 60 s), `acquisition_sigma`
//! (`cold_start_high`'s runs from the first valid update until `Locked`: median of sigma over
//! |error|), `valid_means_close` (the runs in range: share of the samples with `delay_valid`
//! whose error exceeds 3 sigma), `aekf17_hover` (AEKF17 at hover: final error over final
//! sigma). [`LoopTuning`] changes the loop's defaults in every row. Seeds run on
//! [`DelayOptions::threads`] threads.
//!
//! **Verdicts** ([`DelayResult::verdicts`], [`Row::passed`]): a row with an information bound
//! is judged on its ratio to the bound ([`Row::ratio`]), the others on their figure; a finite
//! judged figure within the row's [`Limit`] passes. A row whose navigator refuses its
//! configuration has no figure and fails; it is never skipped.
//!
//! **JSON** ([`DelayResult::to_json`]): `suite`, `seeds`, `coverage_seeds`, `loop_tuning`
//! ([`LoopTuning`]'s fields, `null` for the loop's defaults), `run_s`, `score_from_s`,
//! `delay_scenarios` (per row `name`, `passed`, `criterion`, `measured` (`null` without a
//! finite figure), `bound` and `ratio` (`null` for a row without a bound), `limit` (a number,
//! or `[lo, hi]` for a band; a ratio for a row with a bound)), and `information_bounds`:
//! per RMSE row with a bound, the delay RMSE that no estimator can beat on the same runs (the
//! Cramér-Rao bound of every GPS velocity since the start, the acceleration known; for
//! `delay_ramp`, of a line), so that a row's figure can be read against what its motion allows.
//!
//! **Text**: one line per row as it ends ([`Row`]'s `Display`, reported as
//! [`Progress::DelayRow`]).
//!
//! **Traces** ([`write_trace`], [`write_hover_trace`]): one row's run on one seed, per second
//! as CSV, with what the suite scores on it.

mod rows;
#[cfg(test)]
mod tests;
mod trace;

pub use rows::information_bound_ms;
pub use trace::{
    HoverSetup, HoverSummary, TraceOptions, TraceSummary, write_hover_trace, write_trace,
};

use super::check::Verdict;
use super::{Progress, ProgressFn, SuiteError};
use crate::delay::DelayLoopConfig;
use core::fmt;
use serde_json::{Value, json};

/// Length of every run, s.
pub const RUN_S: f64 = 60.0;
/// Scored from here, s (the simulator's trajectories carry little motion before 15 s).
pub const SCORE_FROM_S: f64 = 20.0;

/// What a row accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit {
    /// The measured figure must be at most this.
    Max(f64),
    /// The measured figure must lie in `[lo, hi]`.
    Band(f64, f64),
}

impl Limit {
    /// Whether `x` is within the limit.
    pub fn accepts(self, x: f64) -> bool {
        match self {
            Limit::Max(max) => x <= max,
            Limit::Band(lo, hi) => (lo..=hi).contains(&x),
        }
    }

    fn to_json(self) -> Value {
        match self {
            Limit::Max(max) => json!(max),
            Limit::Band(lo, hi) => json!([lo, hi]),
        }
    }
}

/// One row of the suite.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The row's name ([`ROW_NAMES`]).
    pub name: &'static str,
    /// What is measured, with its unit.
    pub criterion: &'static str,
    /// The measured figure; `None` when the behaviour cannot run.
    pub measured: Option<f64>,
    /// The row's limit.
    pub limit: Limit,
    /// For the RMSE rows, what no estimator can beat on the row's runs, in
    /// the row's unit (median over seeds; see [`information_bound_ms`]).
    pub bound: Option<f64>,
}

impl Row {
    /// The measured figure over the row's information bound, for a row with a bound (`None`
    /// without a bound or a figure).
    pub fn ratio(&self) -> Option<f64> {
        Some(self.measured? / self.bound?)
    }

    /// The figure the row is judged on: [`Self::ratio`] for a row with a bound, else the
    /// measured figure.
    pub fn judged(&self) -> Option<f64> {
        if self.bound.is_some() {
            self.ratio()
        } else {
            self.measured
        }
    }

    /// A finite judged figure ([`Self::judged`]) within the limit.
    pub fn passed(&self) -> bool {
        self.judged()
            .is_some_and(|x| x.is_finite() && self.limit.accepts(x))
    }

    /// The row's entry of `delay_scenarios`.
    pub fn to_json(&self) -> Value {
        let finite = |x: Option<f64>| x.filter(|x| x.is_finite());
        json!({
            "name": self.name,
            "passed": self.passed(),
            "criterion": self.criterion,
            "measured": finite(self.measured),
            "bound": finite(self.bound),
            "ratio": finite(self.ratio()),
            "limit": self.limit.to_json(),
        })
    }
}

/// `name PASS|FAIL measured M limit L (information bound B, ratio R)`; the limit of a row
/// with a bound is on the ratio.
impl fmt::Display for Row {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<22} {:<6} measured {:>10} limit {:?}{}",
            self.name,
            if self.passed() { "PASS" } else { "FAIL" },
            self.measured.map_or("null".into(), |x| format!("{x:.4}")),
            self.limit,
            self.bound.map_or(String::new(), |b| format!(
                " (information bound {b:.2}, ratio {})",
                self.ratio().map_or("null".into(), |r| format!("{r:.3}"))
            )),
        )
    }
}

/// The suite's rows, in the order they run: first the rows of one `proposed` run each
/// ([`TRACE_ROWS`]), then those that pool or reuse runs, and AEKF17's.
pub const ROW_NAMES: [&str; 17] = [
    "cold_start_low",
    "cold_start_high",
    "delay_step",
    "delay_ramp",
    "delay_jitter",
    "gps_2hz",
    "gps_1hz",
    "gps_rate_drop",
    "negative_delay",
    "out_of_range_reported",
    "out_of_range_weak",
    "gentle_motion",
    "delay_ramp_coverage",
    "sigma_coverage",
    "acquisition_sigma",
    "valid_means_close",
    "aekf17_hover",
];

/// The rows [`write_trace`] can trace (the `proposed` navigator on one run): the first twelve
/// (`delay_ramp_coverage` scores `delay_ramp`'s runs, `acquisition_sigma` `cold_start_high`'s).
pub const TRACE_ROWS: &[&str] = ROW_NAMES.split_at(12).0;

/// Runs [`write_trace`] can trace beside [`TRACE_ROWS`]: the two scenarios
/// of `sigma_coverage` (constant 0.2 s, calibrated start).
pub const EXTRA_TRACES: [&str; 2] = ["calibrated_low", "calibrated_high"];

/// The row named `name` (its static name), `None` when the suite has none.
pub fn row_name(name: &str) -> Option<&'static str> {
    ROW_NAMES.iter().copied().find(|&n| n == name)
}

/// Defines [`LoopTuning`] from one table: each field's documentation, its name, its key in
/// the suite's JSON, and where its value goes in the delay loop's configuration.
macro_rules! loop_tuning {
    ($($(#[$doc:meta])* $field:ident, $key:literal: |$config:ident, $value:ident| $set:expr;)*) => {
        /// Changes to the delay loop's defaults (`None`: the default).
        #[derive(Debug, Clone, Copy, Default, PartialEq)]
        pub struct LoopTuning {
            $($(#[$doc])* pub $field: Option<f64>,)*
            /// [`DelayLoopConfig::innovation_before_lock`] on.
            pub innovation_before_lock: bool,
        }

        impl LoopTuning {
            /// Sets the fields given on `config` (the others keep its values).
            pub fn apply(self, config: &mut DelayLoopConfig<f64>) {
                $(if let Some($value) = self.$field {
                    let $config = &mut *config;
                    $set;
                })*
                if self.innovation_before_lock {
                    config.innovation_before_lock = true;
                }
            }

            /// The `loop_tuning` object of the suite's JSON (`null` for the loop's defaults).
            pub fn to_json(self) -> Value {
                let mut json = json!({ "innovation_before_lock": self.innovation_before_lock });
                $(json[$key] = json!(self.$field);)*
                json
            }
        }
    };
}

loop_tuning! {
    /// [`GainFusionConfig::rate_std`](crate::delay::GainFusionConfig::rate_std), s/s.
    rate_std, "rate_std_s_per_s": |c, v| c.fusion.rate_std = v;
    /// [`GainFusionConfig::rate_time_constant_s`](crate::delay::GainFusionConfig::rate_time_constant_s), s.
    rate_time_constant_s, "rate_time_constant_s": |c, v| c.fusion.rate_time_constant_s = v;
    /// [`DelayLoopConfig::process_noise_ms2_per_s`], ms^2/s.
    process_noise_ms2_per_s, "process_noise_ms2_per_s": |c, v| c.process_noise_ms2_per_s = v;
    /// [`DelayLoopConfig::innovation_window_s`], s (0: off).
    innovation_window_s, "innovation_window_s": |c, v| c.innovation_window_s = v;
    /// [`DelayLoopConfig::innovation_noise_scale`].
    innovation_noise_scale, "innovation_noise_scale": |c, v| c.innovation_noise_scale = v;
    /// [`DelayLoopConfig::innovation_reacquire_sigma`].
    innovation_reacquire_sigma, "innovation_reacquire_sigma":
        |c, v| c.innovation_reacquire_sigma = v;
    /// [`DelayLoopConfig::innovation_acquire_noise_scale`].
    innovation_acquire_noise_scale, "innovation_acquire_noise_scale":
        |c, v| c.innovation_acquire_noise_scale = v;
    /// [`DelayLoopConfig::measurement_noise_ms2`], ms^2, every axis.
    measurement_noise_ms2, "measurement_noise_ms2": |c, v| c.measurement_noise_ms2 = [v; 3];
    /// [`DelayLoopConfig::acquisition_motion_exponent`].
    acquisition_motion_exponent, "acquisition_motion_exponent":
        |c, v| c.acquisition_motion_exponent = v;
    /// [`DelayLoopConfig::smoothing_cutoff_hz`], Hz.
    smoothing_cutoff_hz, "smoothing_cutoff_hz": |c, v| c.smoothing_cutoff_hz = v;
}

/// How much of the suite to run; `Default` is `reproduce --delay-suite`.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayOptions {
    /// Seeds of every row but `sigma_coverage` [default: 1 to 5].
    pub seeds: Vec<u64>,
    /// Seeds of `sigma_coverage`, per scenario [default: 1 to 20].
    pub coverage_seeds: Vec<u64>,
    /// Only these rows, by name (all when `None`).
    pub rows: Option<Vec<String>>,
    /// Changes to the delay loop's defaults, applied to the `proposed`
    /// navigator of every row.
    pub tuning: LoopTuning,
    /// Seeds run at once [default: 2].
    pub threads: usize,
    /// Prediction rate of the navigator's horizon filter, Hz (`None`: its default).
    pub filter_rate_hz: Option<f64>,
}

impl Default for DelayOptions {
    fn default() -> Self {
        Self::full(1, 5)
    }
}

impl DelayOptions {
    /// The whole suite: `seeds` seeds from `first` (20 for the coverage).
    pub fn full(first: u64, seeds: u64) -> Self {
        Self {
            seeds: (first..first + seeds).collect(),
            coverage_seeds: (first..first + 20).collect(),
            rows: None,
            tuning: LoopTuning::default(),
            threads: 2,
            filter_rate_hz: None,
        }
    }

    fn wants(&self, name: &str) -> bool {
        self.rows
            .as_ref()
            .is_none_or(|r| r.iter().any(|n| n == name))
    }

    /// Checks the options: a seed at least, and only rows the suite has.
    pub fn validate(&self) -> Result<(), SuiteError> {
        if self.seeds.is_empty() {
            return Err(SuiteError::InvalidOption {
                option: "seeds",
                reason: "must hold at least one seed".into(),
            });
        }
        for name in self.rows.iter().flatten() {
            if row_name(name).is_none() {
                return Err(SuiteError::UnknownRow {
                    name: name.clone(),
                    known: ROW_NAMES.join(", "),
                });
            }
        }
        Ok(())
    }
}

/// A run of the delay suite.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayResult {
    /// The options it ran with.
    pub options: DelayOptions,
    /// The rows run, in [`ROW_NAMES`] order.
    pub rows: Vec<Row>,
}

/// Runs the suite's rows that `options` selects, reporting each as it ends
/// ([`Progress::DelayRow`]).
pub fn run(options: &DelayOptions, progress: ProgressFn) -> Result<DelayResult, SuiteError> {
    options.validate()?;
    let mut rows = Vec::new();
    let mut runs = rows::Runs::default();
    for name in ROW_NAMES {
        if !options.wants(name) {
            continue;
        }
        let row = rows::run_row(name, options, &mut runs);
        progress(Progress::DelayRow(row.clone()));
        rows.push(row);
    }
    Ok(DelayResult {
        options: options.clone(),
        rows,
    })
}

impl DelayResult {
    /// The suite's rows as verdicts (a row that cannot run fails).
    pub fn verdicts(&self) -> Vec<Verdict> {
        self.rows
            .iter()
            .map(|r| Verdict {
                name: r.name.to_string(),
                passed: r.passed(),
                measured: r.judged(),
                limit: format!("{:?} ({})", r.limit, r.criterion),
            })
            .collect()
    }

    /// The suite's JSON document (see the module's docs).
    pub fn to_json(&self) -> Value {
        json!({
            "suite": "delay (issue 11)",
            "seeds": self.options.seeds,
            "coverage_seeds": self.options.coverage_seeds,
            "loop_tuning": self.options.tuning.to_json(),
            "run_s": RUN_S,
            "score_from_s": SCORE_FROM_S,
            "delay_scenarios": self.rows.iter().map(Row::to_json).collect::<Vec<_>>(),
            "information_bounds": self
                .rows
                .iter()
                .filter_map(|r| Some((r.name.to_string(), json!(r.bound?))))
                .collect::<serde_json::Map<String, Value>>(),
        })
    }
}

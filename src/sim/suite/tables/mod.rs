//! The paper's simulation study (section 3.1, Tables 5 and 6, Figures 5 and 6) on the crate's
//! simulator: scenarios x estimators x seeds, the Monte Carlo tables.
//!
//! ```text
//! cargo run --release --features sim --example reproduce                     # 5 seeds, both scenarios
//! cargo run --release --features sim --example reproduce -- --seeds 20       # docs/RESULTS.md's tables
//! cargo run --release --features sim --example reproduce -- --seeds 20 --bound-study
//! ```
//!
//! **Scenario.** Each seed of each scenario ([`Scenario::Low`], [`Scenario::High`]: the
//! paper's low and high acceleration limits, Table 3's sensors, a constant 0.2 s GPS delay,
//! 60 s) is simulated once; every row ([`Estimator`]: [`estimators`], or [`bound_study`]) runs
//! on the same events. The delay estimators start from an offline calibration on a separate
//! run ([`setup::calibrated_start`](crate::sim::suite::setup::calibrated_start)) unless
//! [`TablesOptions::calibrated`] is off. Seeds run in parallel ([`TablesOptions::threads`]).
//!
//! **Figures.** Every figure is the mean over the seeds of one run's RMSE, counted after
//! `skip_s` seconds (the convergence time), with the 95 % t-interval of that mean
//! ([`stats::mean_ci95`](crate::sim::suite::stats::mean_ci95)). Attitude errors are the
//! differences of ZYX Euler angles wrapped to (-180, 180] degrees, and beside them the tilt
//! and heading errors of the attitude error's rotation vector
//! ([`tilt_heading_error_rad`](crate::sim::tilt_heading_error_rad), invariant to the vehicle's
//! own attitude); velocity and position errors are the RMS of the 3-D error norm; delay is the
//! RMS of estimate minus true delay; biases are per-axis RMS errors. `us_per_imu_sample` is
//! the time spent inside the estimator's own `push_*` calls divided by the number of IMU
//! samples (the one figure that differs between two runs).
//!
//! **Consistency.** The NEES of `[position, velocity]` (6 degrees of freedom) against each
//! filter's own 6x6 covariance block at the instant its estimate describes (the horizon for the
//! delay-compensated navigator), sampled every 100 ms and averaged over the seeds, with the
//! 95 % chi-square band of an average over that many seeds; and the NIS of the GPS fixes
//! (position and velocity, 6 degrees of freedom, from the fusion records' innovations and the
//! diagonal of their innovation covariance) averaged over every scored fix, with its band.
//!
//! **Verdicts.** [`TablesResult::verdicts`]: `proposed` against `oracle`, the bounds, its
//! `f32` build, `ekf16` and `aekf17`, and its NEES band, per scenario.
//!
//! **JSON** ([`TablesResult::to_json`]): `duration_s`, `skip_s`, `seeds`, and `scenarios`, one
//! object per scenario with `name`, `accel_limit_m_s2`, `true_delay_s`, `delay_bound_s`,
//! `calibrated_delay_s` (per seed), `calibration_rms_error_s`, `noise_floor` (`tilt_deg`,
//! `vel_m_s`, `pos_m`, `heading_mag_only_deg`), `paired` (`proposed_minus_<row>`: per figure
//! `mean` and `ci95`) and `estimators`: per row every figure of [`FIGURES`] with its
//! `<figure>_ci95`, `delay_s_median`, `gyro_bias_rad_s`, `accel_bias_g` and their `_ci95`,
//! `nees_mean`, `nees_band95`, `nees_in_band_fraction`, `nis_mean`, `nis_band95`. A figure
//! that is not finite is `null`.
//!
//! **Text** (`Display` of [`TablesResult`]): per scenario the RMSE table beside the paper's
//! Table 6 and the noise floor, the bias table beside Table 5, the paired differences and the
//! consistency table, in markdown.

mod estimators;
mod json;
mod render;
mod score;
mod summary;
mod verdicts;

pub use estimators::{
    Estimator, IMU_CALIBRATION_ACCEL_STD_G, IMU_CALIBRATION_GYRO_STD_DEG_S, bound_study,
    estimators, imu_calibration,
};
pub use render::{PAPER_TABLE5, fmt_value, paper_table6};
pub use score::{
    Metrics, NEES_STEP_US, PosVelCovariance, RunScore, TRACE_STEP_US, Trace, aekf17_covariance,
    ekf16_covariance, nav_covariance, score,
};
pub use summary::{
    CONSISTENCY_DOF, Consistency, FIGURES, Figure, MeanCi, PAIRED_AGAINST, PAIRED_FIGURES, Summary,
    consistency, summarize,
};

use super::setup::{DelayStart, UNCALIBRATED_START, calibrated_start, fix_accelerations};
use super::stats::median;
use super::{ProgressFn, Steps, SuiteError, Task, parallel_map};
use crate::sim::{
    DelayProfile, NoiseFloor, STANDARD_GRAVITY, Scenario, SimConfig, SimEvent, Simulation,
    Trajectory, delay_bound_s, noise_floor,
};
use nalgebra::Vector6;
use std::time::Instant;

/// Window of GPS fixes over which the delay bound counts information, µs.
pub const DELAY_BOUND_WINDOW_US: u64 = 5_000_000;

/// One simulated run, shared by every estimator.
#[derive(Debug, Clone)]
pub struct RunSetup {
    /// The simulation.
    pub config: SimConfig,
    /// Its events.
    pub events: Vec<SimEvent>,
    /// Scored from here, µs.
    pub skip_us: u64,
    /// Whether the scores keep a trace for the plots (the first seed, when asked).
    pub keep_trace: bool,
    /// Where `proposed`, `calibrated` and `aekf17` start their delay estimate.
    pub start: DelayStart,
    /// The closed-form truth, for states a filter reports at a past instant.
    pub trajectory: Trajectory,
    /// Prediction rate of the navigator's horizon filter, Hz (`None`: its default).
    pub filter_rate_hz: Option<f64>,
}

impl RunSetup {
    /// NEES of a position-velocity estimate against the truth at its instant; NaN when the
    /// covariance is not positive definite.
    pub fn nees(&self, (t_us, p, v, cov): &PosVelCovariance) -> f64 {
        let truth = self.trajectory.kinematics(*t_us as f64 * 1e-6);
        let mut e = Vector6::zeros();
        e.fixed_rows_mut::<3>(0).copy_from(&(p - truth.position_m));
        e.fixed_rows_mut::<3>(3)
            .copy_from(&(v - truth.velocity_m_s));
        cov.cholesky().map_or(f64::NAN, |c| e.dot(&c.solve(&e)))
    }
}

/// The options of a run of the tables; `Default` is `reproduce`'s default run.
#[derive(Debug, Clone, PartialEq)]
pub struct TablesOptions {
    /// The scenarios, in order [default: low, high].
    pub scenarios: Vec<Scenario>,
    /// The seeds of every scenario [default: 1 to 5].
    pub seeds: Vec<u64>,
    /// Length of each run, s [default: 60].
    pub duration_s: f64,
    /// True GPS delay, s, constant; `None`: the scenario's (0.2 s).
    pub delay_s: Option<f64>,
    /// Convergence time not scored, s [default: 10].
    pub skip_s: f64,
    /// GPS rate, Hz, when not the default (sweeps).
    pub gps_rate_hz: Option<f64>,
    /// Start the delay estimators from an offline calibration [default: on]; off, from 0.1 s.
    pub calibrated: bool,
    /// IMU rate, Hz, when not the default (sweeps); the magnetometer at most at this rate.
    pub imu_rate_hz: Option<f64>,
    /// Keep the first seed's traces for the plots [default: on].
    pub keep_trace: bool,
    /// Prediction rate of the navigator's horizon filter, Hz; 0 predicts at every IMU sample
    /// (`None`: its default).
    pub filter_rate_hz: Option<f64>,
    /// Seeds run at once [default: the machine's available parallelism].
    pub threads: usize,
}

impl Default for TablesOptions {
    fn default() -> Self {
        Self {
            scenarios: Scenario::ALL.to_vec(),
            seeds: (1..=5).collect(),
            duration_s: 60.0,
            delay_s: None,
            skip_s: 10.0,
            gps_rate_hz: None,
            calibrated: true,
            imu_rate_hz: None,
            keep_trace: true,
            filter_rate_hz: None,
            threads: std::thread::available_parallelism().map_or(1, std::num::NonZero::get),
        }
    }
}

impl TablesOptions {
    /// The simulation of one scenario and seed with these options.
    pub fn sim_config(&self, scenario: Scenario, seed: u64) -> SimConfig {
        let mut config = SimConfig {
            duration_s: self.duration_s,
            ..SimConfig::for_scenario(scenario, seed)
        };
        if let Some(d) = self.delay_s {
            config.delay = DelayProfile::constant(d);
        }
        if let Some(r) = self.gps_rate_hz {
            config.sensors.gps_rate_hz = r;
        }
        if let Some(r) = self.imu_rate_hz {
            config.sensors.imu_rate_hz = r;
            // The magnetometer cannot outrun the IMU (100 Hz by default).
            config.sensors.mag_rate_hz = config.sensors.mag_rate_hz.min(r);
        }
        config
    }

    /// Checks the options: at least one scenario and one seed, a convergence time shorter than
    /// the run, and a valid simulation.
    pub fn validate(&self) -> Result<(), SuiteError> {
        let invalid = |option, reason: &str| {
            Err(SuiteError::InvalidOption {
                option,
                reason: reason.into(),
            })
        };
        if self.seeds.is_empty() {
            return invalid("seeds", "must hold at least one seed");
        }
        if self.scenarios.is_empty() {
            return invalid("scenarios", "must hold at least one scenario");
        }
        if !(self.skip_s >= 0.0 && self.duration_s > self.skip_s) {
            return invalid(
                "duration_s",
                &format!(
                    "({} s) must exceed the convergence time `skip_s` ({} s)",
                    self.duration_s, self.skip_s
                ),
            );
        }
        for &scenario in &self.scenarios {
            self.sim_config(scenario, self.seeds[0])
                .validate()
                .map_err(|e| SuiteError::config("simulation", e))?;
        }
        Ok(())
    }
}

/// Everything measured in one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioResult {
    /// The scenario.
    pub scenario: Scenario,
    /// Its true (initial) delay, s.
    pub true_delay_s: f64,
    /// Median over the seeds of the delay bound ([`delay_bound_s`] over
    /// [`DELAY_BOUND_WINDOW_US`] of fixes), s.
    pub delay_bound_s: f64,
    /// Steady-state errors of an ideal filter with the run's noise at hover.
    pub floor_hover: NoiseFloor,
    /// Every row's statistics over the seeds, in registry order.
    pub summaries: Vec<(&'static str, Summary)>,
    /// Every row's consistency, in registry order.
    pub consistency: Vec<(&'static str, Consistency)>,
    /// Every seed's metrics per row, in registry order (paired comparisons).
    pub per_seed: Vec<(&'static str, Vec<Metrics>)>,
    /// First seed's traces per row (empty without traces).
    pub traces: Vec<(&'static str, Trace)>,
    /// The truth on the first seed every [`TRACE_STEP_US`]: time s, pitch deg, delay s.
    pub truth_trace: Vec<(f64, f64, f64)>,
    /// Calibrated delay per seed, s (empty without the calibration).
    pub calibrated_delays_s: Vec<f64>,
}

impl ScenarioResult {
    /// RMS error of the calibrated delays, s.
    pub fn calibration_rms_error_s(&self) -> Option<f64> {
        (!self.calibrated_delays_s.is_empty()).then(|| {
            let n = self.calibrated_delays_s.len() as f64;
            (self
                .calibrated_delays_s
                .iter()
                .map(|d| (d - self.true_delay_s).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
        })
    }
}

/// A run of the tables: the options it ran with and every scenario's results.
#[derive(Debug, Clone, PartialEq)]
pub struct TablesResult {
    /// The options (their seeds, duration and convergence time shape the text and the JSON).
    pub options: TablesOptions,
    /// One result per scenario, in the options' order.
    pub scenarios: Vec<ScenarioResult>,
}

/// Runs every row of `estimators` on every seed of every scenario of `options`, reporting a
/// [`Progress::Step`](super::Progress::Step) per row and seed.
pub fn run(
    options: &TablesOptions,
    estimators: &[Estimator],
    progress: ProgressFn,
) -> Result<TablesResult, SuiteError> {
    options.validate()?;
    let total = options.scenarios.len() * options.seeds.len() * estimators.len();
    let steps = Steps::new(total, progress);
    let scenarios = options
        .scenarios
        .iter()
        .map(|&s| run_scenario(s, options, estimators, &steps))
        .collect::<Result<_, _>>()?;
    Ok(TablesResult {
        options: options.clone(),
        scenarios,
    })
}

/// What one seed of a scenario gives.
struct SeedResult {
    delay_bound_s: f64,
    calibrated_delay_s: Option<f64>,
    /// One score per registered estimator, in registry order.
    scores: Vec<RunScore>,
    /// The truth's pitch and delay, for the plots (first seed only).
    truth_trace: Vec<(f64, f64, f64)>,
}

/// Simulates one seed, calibrates, and runs every estimator on it.
fn run_seed(
    scenario: Scenario,
    seed: u64,
    first: bool,
    options: &TablesOptions,
    registry: &[Estimator],
    steps: &Steps,
) -> Result<SeedResult, SuiteError> {
    let config = options.sim_config(scenario, seed);
    let simulation =
        Simulation::new(config.clone()).map_err(|e| SuiteError::config("simulation", e))?;
    let trajectory = simulation.trajectory().clone();
    let events: Vec<SimEvent> = simulation.collect();
    let skip_us = (options.skip_s * 1e6).round() as u64;
    let fixes = fix_accelerations(&events);
    let delay_bound_s = delay_bound_s(
        &fixes,
        config.sensors.gps_velocity_var_m2_s2,
        DELAY_BOUND_WINDOW_US,
        skip_us,
    )
    .unwrap_or(f64::NAN);
    let truth_trace = if first {
        events
            .iter()
            .filter_map(|e| match e {
                SimEvent::Imu { truth, .. } if truth.t_us.is_multiple_of(TRACE_STEP_US) => Some((
                    truth.t_us as f64 * 1e-6,
                    truth.euler_rad.y.to_degrees(),
                    truth.gps_delay_s,
                )),
                _ => None,
            })
            .collect()
    } else {
        Vec::new()
    };
    let (start, calibrated_delay_s) = if options.calibrated {
        let start = calibrated_start(&config).map_err(|e| SuiteError::config("calibration", e))?;
        (start, Some(start.delay_s))
    } else {
        (UNCALIBRATED_START, None)
    };
    let setup = RunSetup {
        config,
        events,
        skip_us,
        keep_trace: first,
        start,
        trajectory,
        filter_rate_hz: options.filter_rate_hz,
    };
    let scores = registry
        .iter()
        .map(|estimator| {
            let started = Instant::now();
            let s = (estimator.run)(&setup).map_err(|e| SuiteError::config(estimator.name, e))?;
            let task = Task::Run {
                scenario,
                seed,
                estimator: estimator.name,
            };
            steps.step(task, started.elapsed().as_secs_f64());
            Ok(s)
        })
        .collect::<Result<_, SuiteError>>()?;
    Ok(SeedResult {
        delay_bound_s,
        calibrated_delay_s,
        scores,
        truth_trace,
    })
}

/// Runs the seeds of a scenario on `options.threads` threads, each taking
/// the next seed not yet started, and summarizes them.
pub(crate) fn run_scenario(
    scenario: Scenario,
    options: &TablesOptions,
    registry: &[Estimator],
    steps: &Steps,
) -> Result<ScenarioResult, SuiteError> {
    let seeds = &options.seeds;
    let mut per_seed: Vec<SeedResult> = parallel_map(seeds, options.threads, |k, &seed| {
        let first = k == 0 && options.keep_trace;
        run_seed(scenario, seed, first, options, registry, steps)
    })
    .into_iter()
    .collect::<Result<_, _>>()?;
    let mut by_estimator: Vec<Vec<RunScore>> = registry.iter().map(|_| Vec::new()).collect();
    let mut bounds = Vec::new();
    let mut calibrated_delays_s = Vec::new();
    let truth_trace = per_seed
        .first_mut()
        .map(|s| std::mem::take(&mut s.truth_trace))
        .unwrap_or_default();
    for seed in per_seed {
        bounds.push(seed.delay_bound_s);
        calibrated_delays_s.extend(seed.calibrated_delay_s);
        for (i, score) in seed.scores.into_iter().enumerate() {
            by_estimator[i].push(score);
        }
    }
    let config = options.sim_config(scenario, seeds[0]);
    let mut traces = Vec::new();
    let mut summaries = Vec::new();
    let mut consistencies = Vec::new();
    let mut per_seed = Vec::new();
    for (estimator, scores) in registry.iter().zip(&mut by_estimator) {
        let metrics: Vec<Metrics> = scores.iter().map(|s| s.metrics.clone()).collect();
        summaries.push((estimator.name, summarize(&metrics)));
        per_seed.push((estimator.name, metrics));
        consistencies.push((estimator.name, consistency(scores)));
        if options.keep_trace {
            traces.push((estimator.name, std::mem::take(&mut scores[0].trace)));
        }
    }
    Ok(ScenarioResult {
        scenario,
        true_delay_s: config.delay.initial_s,
        delay_bound_s: median(bounds),
        floor_hover: noise_floor(&config.sensors, STANDARD_GRAVITY),
        summaries,
        consistency: consistencies,
        per_seed,
        traces,
        truth_trace,
        calibrated_delays_s,
    })
}

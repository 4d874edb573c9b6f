//! The rows of the delay suite: each row's runs, its navigator, and its figure.

use super::{DelayOptions, Limit, LoopTuning, RUN_S, Row, SCORE_FROM_S};
use crate::delay::{DelayLoopConfig, DelayStatus};
use crate::nav::{DelayCompensatedNav, DelayMode};
use crate::sim::PathTerm;
use crate::sim::suite::parallel_map;
use crate::sim::suite::setup::{
    DelayStart, UNCALIBRATED_START, calibrated_start, ekf16_config, fix_accelerations, nav_config,
};
use crate::sim::suite::stats::{median, median_with_infinity};
use crate::sim::{
    DelayProfile, DelayRamp, DelayStep, Scenario, SimConfig, SimEvent, Simulation, Truth,
    delay_bound_s, delay_ramp_bound_s,
};
use crate::{AugmentedEkf17, AugmentedEkf17Config, Navigator};
use nalgebra::Vector3;

/// When `delay_step`'s delay steps, s.
pub(super) const STEP_AT_S: f64 = 20.0;
/// `delay_step`'s step: 0.2 -> 0.35 s at [`STEP_AT_S`].
const STEP: DelayStep = DelayStep {
    at_s: STEP_AT_S,
    change_s: 0.15,
};
/// `delay_ramp`'s ramp: +60 ms over the run.
const RAMP: DelayRamp = DelayRamp {
    start_s: 0.0,
    duration_s: RUN_S,
    change_s: 0.06,
};
/// Spacing of the trace points, us.
pub(super) const TRACE_STEP_US: u64 = 10_000;

/// What configures the `proposed` navigator of every row beyond the row's own setup.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Tuned {
    /// Changes to the delay loop's defaults.
    pub tuning: LoopTuning,
    /// Prediction rate of the horizon filter, Hz (`None`: its default).
    pub filter_rate_hz: Option<f64>,
}

impl DelayOptions {
    fn tuned(&self) -> Tuned {
        Tuned {
            tuning: self.tuning,
            filter_rate_hz: self.filter_rate_hz,
        }
    }
}

/// The delay estimate of one run at regular instants.
#[derive(Debug, Default, Clone)]
pub(super) struct DelayTrace {
    pub t_s: Vec<f64>,
    pub estimate_s: Vec<f64>,
    pub std_s: Vec<f64>,
    pub truth_s: Vec<f64>,
    /// What the navigator said of its delay at each point (empty for AEKF17).
    pub health: Vec<PointHealth>,
}

/// The navigator's word on its delay at one trace point.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub(super) struct PointHealth {
    /// `Health::delay_valid`.
    pub valid: bool,
    /// The loop had made a valid update.
    pub updated: bool,
    /// The loop's status is `Locked`.
    pub locked: bool,
    /// `Health::delay`'s delay and standard deviation, s: what `valid` vouches for (the
    /// navigator's estimate has no delay before it aligns, its health has).
    pub delay_s: f64,
    pub std_s: f64,
}

impl DelayTrace {
    fn errors_from(&self, from_s: f64) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        (0..self.t_s.len())
            .filter(move |&k| self.t_s[k] >= from_s)
            .map(|k| {
                (
                    self.t_s[k],
                    self.estimate_s[k] - self.truth_s[k],
                    self.std_s[k],
                )
            })
    }

    /// Delay RMSE from `from_s`, s; NaN without points.
    pub fn rmse_from(&self, from_s: f64) -> f64 {
        let (sum, n) = self
            .errors_from(from_s)
            .fold((0.0, 0usize), |(s, n), (_, e, _)| (s + e * e, n + 1));
        if n == 0 {
            f64::NAN
        } else {
            (sum / n as f64).sqrt()
        }
    }

    /// Time from `from_s` until the error stays within `tolerance_s` to the
    /// end, s; infinite when it ends outside.
    pub fn settle_after(&self, from_s: f64, tolerance_s: f64) -> f64 {
        let mut last_out = None;
        let mut any = false;
        for (t, e, _) in self.errors_from(from_s) {
            any = true;
            if e.is_nan() || e.abs() > tolerance_s {
                last_out = Some(t);
            }
        }
        match last_out {
            _ if !any => f64::INFINITY,
            None => 0.0,
            Some(t) if t >= *self.t_s.last().unwrap_or(&0.0) => f64::INFINITY,
            Some(t) => t + TRACE_STEP_US as f64 * 1e-6 - from_s,
        }
    }

    /// Points with a valid delay ([`PointHealth::valid`]) whose error exceeds three sigma, as
    /// (far, valid): the health's own delay and sigma against the truth.
    pub fn valid_but_far(&self) -> (usize, usize) {
        self.health
            .iter()
            .zip(&self.truth_s)
            .filter(|(h, _)| h.valid)
            .fold((0, 0), |(far, n), (h, truth)| {
                let far_point = beyond_three_sigma(h.delay_s, h.std_s, *truth);
                (far + usize::from(far_point), n + 1)
            })
    }

    /// `sigma / |error|` at the points from the loop's first valid update until it locks.
    pub fn acquisition_sigma_ratios(&self) -> impl Iterator<Item = f64> + '_ {
        self.health
            .iter()
            .zip(self.errors_from(0.0))
            .skip_while(|(h, _)| !h.updated)
            .take_while(|(h, _)| !h.locked)
            .map(|(_, (_, e, s))| s / e.abs())
    }

    /// Fraction of points from `from_s` whose error is within one sigma,
    /// as (inside, total).
    pub fn coverage_from(&self, from_s: f64) -> (usize, usize) {
        self.errors_from(from_s)
            .fold((0, 0), |(inside, n), (_, e, s)| {
                (inside + usize::from(e.abs() <= s), n + 1)
            })
    }
}

/// Whether a delay is more than 3 sigma from the truth (s); a NaN delay or sigma counts as
/// beyond: `valid_means_close`'s test of one point.
pub(super) fn beyond_three_sigma(delay_s: f64, std_s: f64, truth_s: f64) -> bool {
    let error = (delay_s - truth_s).abs();
    error.is_nan() || std_s.is_nan() || error > 3.0 * std_s
}

/// Feeds one event to an estimator (refusals are its business).
pub(super) fn feed<N: Navigator<f64>>(estimator: &mut N, event: &SimEvent) {
    let _ = match event {
        SimEvent::Imu { sample, .. } => estimator.push_imu(sample),
        SimEvent::Mag(m) => estimator.push_mag(m).map(drop),
        SimEvent::Gps { fix, .. } => estimator.push_gps(fix).map(drop),
    };
}

/// The truth at `event` when it is a trace point: an IMU sample on the [`TRACE_STEP_US`] grid.
pub(super) fn trace_point(event: &SimEvent) -> Option<&Truth> {
    match event {
        SimEvent::Imu { truth, .. } if truth.t_us.is_multiple_of(TRACE_STEP_US) => Some(truth),
        _ => None,
    }
}

/// Feeds a run to an estimator (refusals are its business) and records its
/// delay estimate every [`TRACE_STEP_US`], with what `health` says of it (`None`: nothing).
fn trace<N: Navigator<f64>>(
    mut estimator: N,
    events: &[SimEvent],
    health: impl Fn(&N) -> Option<PointHealth>,
) -> DelayTrace {
    let mut out = DelayTrace::default();
    for event in events {
        feed(&mut estimator, event);
        let Some(truth) = trace_point(event) else {
            continue;
        };
        out.health.extend(health(&estimator));
        let est = estimator.estimate();
        out.t_s.push(truth.t_us as f64 * 1e-6);
        out.estimate_s
            .push(est.and_then(|e| e.delay_s).unwrap_or(f64::NAN));
        out.std_s
            .push(est.and_then(|e| e.delay_std_s).unwrap_or(f64::NAN));
        out.truth_s.push(truth.gps_delay_s);
    }
    out
}

/// A 60 s run of `scenario` with `seed` and the delay `profile`.
fn sim(scenario: Scenario, seed: u64, profile: DelayProfile) -> SimConfig {
    SimConfig {
        duration_s: RUN_S,
        delay: profile,
        ..SimConfig::for_scenario(scenario, seed)
    }
}

/// The events of a run; `None` when the simulator refuses it.
pub(super) fn events(config: &SimConfig) -> Option<Vec<SimEvent>> {
    Some(Simulation::new(config.clone()).ok()?.collect())
}

/// How the navigator of a row is configured beyond the simulator's EKF.
#[derive(Debug, Clone, Copy)]
pub(super) struct NavSetup {
    calibrated: bool,
    /// Delay range of the loop, s (`None`: the default).
    range_s: Option<(f64, f64)>,
    /// Start value of the delay, s (`None`: [`UNCALIBRATED_START`]'s).
    start_s: Option<f64>,
    /// From this time on, s, one GPS fix in ten reaches the navigator (`None`: all).
    gps_tenth_from_s: Option<f64>,
}

const COLD: NavSetup = NavSetup {
    calibrated: false,
    range_s: None,
    start_s: None,
    gps_tenth_from_s: None,
};

const CALIBRATED: NavSetup = NavSetup {
    calibrated: true,
    ..COLD
};

/// The `proposed` navigator of a row; `None` when it refuses the setup.
pub(super) fn proposed(
    config: &SimConfig,
    setup: NavSetup,
    tuned: Tuned,
) -> Option<DelayCompensatedNav<f64>> {
    let start = if setup.calibrated {
        // The offline calibration of the seed on its own run (as the tables' calibrated runs),
        // with a constant delay equal to the profile's start.
        let constant = SimConfig {
            delay: DelayProfile::constant(config.delay.initial_s),
            ..config.clone()
        };
        calibrated_start(&constant).ok()?
    } else {
        UNCALIBRATED_START
    };
    let DelayStart { delay_s, std_s } = start;
    let mode = DelayMode::Estimated {
        initial_s: setup.start_s.unwrap_or(delay_s),
    };
    let mut nav_config = nav_config(config, mode, std_s, tuned.filter_rate_hz);
    // The loop's defaults whatever the GPS rate: nothing adapted by the caller (`nav_config`
    // adapts the loop to the simulated rate, as the sweeps' user would).
    let initial_std_s = nav_config.delay_loop.fusion.initial_std_s;
    nav_config.delay_loop = DelayLoopConfig::default();
    nav_config.delay_loop.fusion.initial_std_s = initial_std_s;
    if let Some((min, max)) = setup.range_s {
        nav_config.delay_loop.fusion.delay_min_s = min;
        nav_config.delay_loop.fusion.delay_max_s = max;
    }
    tuned.tuning.apply(&mut nav_config.delay_loop);
    DelayCompensatedNav::new(nav_config).ok()
}

/// The run and the navigator setup of the `proposed` row `name` (or one of
/// [`EXTRA_TRACES`](super::EXTRA_TRACES)) on `seed`; `None` for `sigma_coverage` (two
/// scenarios) and `aekf17_hover` (not the navigator), and for names the suite does not have.
pub(super) fn row_run(name: &str, seed: u64) -> Option<(SimConfig, NavSetup)> {
    let constant = |scenario, delay_s| sim(scenario, seed, DelayProfile::constant(delay_s));
    // The high scenario from a constant 0.2 s, changed by `change`.
    let high = |change: fn(&mut DelayProfile)| {
        let mut profile = DelayProfile::constant(0.2);
        change(&mut profile);
        sim(Scenario::High, seed, profile)
    };
    Some(match name {
        "calibrated_low" => (constant(Scenario::Low, 0.2), CALIBRATED),
        "calibrated_high" => (constant(Scenario::High, 0.2), CALIBRATED),
        "cold_start_low" => (constant(Scenario::Low, 0.2), COLD),
        "cold_start_high" => (constant(Scenario::High, 0.2), COLD),
        "delay_step" => (high(|p| p.steps.push(STEP)), CALIBRATED),
        "delay_ramp" => (high(|p| p.ramps.push(RAMP)), COLD),
        "delay_jitter" => (high(|p| p.jitter_uniform_half_width_s = 0.020), COLD),
        "gps_2hz" | "gps_1hz" => {
            let mut config = constant(Scenario::High, 0.2);
            config.sensors.gps_rate_hz = if name == "gps_2hz" { 2.0 } else { 1.0 };
            (config, COLD)
        }
        "gps_rate_drop" => {
            let setup = NavSetup {
                gps_tenth_from_s: Some(GPS_DROP_AT_S),
                ..COLD
            };
            (constant(Scenario::High, 0.2), setup)
        }
        "negative_delay" => {
            let setup = NavSetup {
                range_s: Some((-0.5, 0.6)),
                ..COLD
            };
            (constant(Scenario::High, -0.15), setup)
        }
        "out_of_range_reported" => (constant(Scenario::High, -0.15), COLD),
        "out_of_range_weak" => {
            let mut config = constant(Scenario::Low, -0.15);
            // The velocity noise's standard deviation doubled.
            config.sensors.gps_velocity_var_m2_s2 *= 4.0;
            (config, COLD)
        }
        "gentle_motion" => {
            let setup = NavSetup {
                start_s: Some(0.2),
                ..COLD
            };
            (gentle_motion(seed), setup)
        }
        _ => return None,
    })
}

/// `gps_rate_drop`'s GPS goes from 10 Hz to 1 Hz here, s.
const GPS_DROP_AT_S: f64 = 30.0;
/// `gentle_motion`'s run, s.
const GENTLE_RUN_S: f64 = 120.0;
/// `gentle_motion` is scored from here, s.
const GENTLE_SCORE_FROM_S: f64 = 60.0;

/// `gentle_motion`'s run: a ground vehicle shuttling north and back with a 6 s period (the slow
/// path peaks at 1.8 m/s^2, the simulator's manoeuvre fills it up to a 2 m/s^2 peak), no yaw
/// swing, IMU 200 Hz, GPS 10 Hz, true delay 0.15 s, [`GENTLE_RUN_S`] long.
fn gentle_motion(seed: u64) -> SimConfig {
    let mut config = sim(Scenario::Low, seed, DelayProfile::constant(0.15));
    let period_s = 6.0;
    let w = core::f64::consts::TAU / period_s;
    config.trajectory.path = vec![PathTerm {
        amplitude_m: Vector3::new(1.8 / (w * w), 0.0, 0.0),
        period_s,
        phase_rad: 0.0,
    }];
    config.trajectory.accel_limit_m_s2 = 2.0;
    config.trajectory.yaw_amplitude_rad = 0.0;
    config.sensors.imu_rate_hz = 200.0;
    config.sensors.gps_rate_hz = 10.0;
    config.duration_s = GENTLE_RUN_S;
    config
}

/// The events of a row's run as its navigator sees them: [`events`], with one GPS fix in ten
/// from [`NavSetup::gps_tenth_from_s`] on.
pub(super) fn row_events(config: &SimConfig, setup: NavSetup) -> Option<Vec<SimEvent>> {
    let mut all = events(config)?;
    if let Some(from_s) = setup.gps_tenth_from_s {
        let from_us = (from_s * 1e6) as u64;
        let mut fixes = 0u64;
        all.retain(|e| match e {
            SimEvent::Gps { .. } if e.t_us() >= from_us => {
                fixes += 1;
                fixes % 10 == 1
            }
            _ => true,
        });
    }
    Some(all)
}

/// Runs `f` on every seed on `threads` threads; results in seed order.
fn per_seed<R: Send>(seeds: &[u64], threads: usize, f: impl Fn(u64) -> R + Sync) -> Vec<R> {
    parallel_map(seeds, threads, |_, &seed| f(seed))
}

/// Delay traces of the `proposed` navigator of `run` (a row or one of
/// [`EXTRA_TRACES`](super::EXTRA_TRACES)) on every seed; `None` when it refuses the setup.
fn row_traces(run: &str, seeds: &[u64], options: &DelayOptions) -> Option<Vec<DelayTrace>> {
    let tuned = options.tuned();
    per_seed(seeds, options.threads, |seed| {
        let (config, setup) = row_run(run, seed)?;
        let estimator = proposed(&config, setup, tuned)?;
        Some(trace(estimator, &row_events(&config, setup)?, |nav| {
            let h = nav.health();
            Some(PointHealth {
                valid: h.delay_valid,
                updated: h.delay.valid_updates > 0,
                locked: h.delay.status.is_some_and(|s| s.is_locked()),
                delay_s: h.delay.delay_s,
                std_s: h.delay.delay_std_s,
            })
        }))
    })
    .into_iter()
    .collect()
}

/// Median over the seeds of the delay RMSE from 20 s, ms.
pub(super) fn median_rmse_ms(traces: &[DelayTrace]) -> f64 {
    median_rmse_ms_from(traces, SCORE_FROM_S)
}

/// Median over the seeds of the delay RMSE from `from_s`, ms.
fn median_rmse_ms_from(traces: &[DelayTrace], from_s: f64) -> f64 {
    median(traces.iter().map(|t| t.rmse_from(from_s) * 1e3).collect())
}

/// The runs whose traces `valid_means_close` pools: every row's `proposed` run whose true
/// delay lies in the loop's range, and `sigma_coverage`'s two.
fn valid_runs() -> impl Iterator<Item = &'static str> {
    super::TRACE_ROWS
        .iter()
        .copied()
        .filter(|r| !r.starts_with("out_of_range"))
        .chain(super::EXTRA_TRACES)
}

/// The traces of the runs made so far, by run name: the rows that score the same runs
/// (`delay_ramp_coverage`, `acquisition_sigma`, `valid_means_close`) share them.
#[derive(Default)]
pub(super) struct Runs {
    traces: Vec<(&'static str, Option<Vec<DelayTrace>>)>,
}

impl Runs {
    /// The traces of `run` (a row, or one of [`EXTRA_TRACES`](super::EXTRA_TRACES) on the
    /// coverage seeds), made on first use; `None` when its navigator refuses the setup.
    fn traces(&mut self, run: &'static str, options: &DelayOptions) -> Option<&[DelayTrace]> {
        if !self.traces.iter().any(|(n, _)| *n == run) {
            let seeds = if super::EXTRA_TRACES.contains(&run) {
                &options.coverage_seeds
            } else {
                &options.seeds
            };
            self.traces.push((run, row_traces(run, seeds, options)));
        }
        self.traces
            .iter()
            .find(|(n, _)| *n == run)
            .and_then(|(_, t)| t.as_deref())
    }
}

/// Runs the row `name` (one of [`ROW_NAMES`](super::ROW_NAMES)), with the traces of `runs`.
pub(super) fn run_row(name: &'static str, options: &DelayOptions, runs: &mut Runs) -> Row {
    let ratio = "delay RMSE from 20 s, ms (median over seeds), judged on its ratio to the bound";
    match name {
        "cold_start_low" => bound_row(name, options, runs, 2.0, ratio),
        "cold_start_high" => bound_row(name, options, runs, 1.2, ratio),
        "delay_step" => delay_step_row(options, runs),
        "delay_ramp" => bound_row(
            name,
            options,
            runs,
            1.6,
            "delay RMSE from 20 s, ms (median), judged on its ratio to the bound of a line",
        ),
        "delay_ramp_coverage" => {
            let share = runs
                .traces("delay_ramp", options)
                .and_then(|t| pooled_share(t.iter().map(|t| t.coverage_from(SCORE_FROM_S))));
            Row {
                name,
                criterion: "delay_ramp's runs: fraction of samples from 20 s with |error| <= reported 1-sigma, pooled",
                measured: share,
                limit: Limit::Band(0.5, 0.9),
                bound: None,
            }
        }
        "delay_jitter" => bound_row(
            name,
            options,
            runs,
            1.25,
            "delay RMSE against 0.2 s from 20 s, ms (median), judged on its ratio to the bound",
        ),
        "gps_2hz" => bound_row(name, options, runs, 1.5, ratio),
        "gps_1hz" => bound_row(name, options, runs, 2.0, ratio),
        "gps_rate_drop" => Row {
            name,
            criterion: "GPS 10 Hz, then 1 Hz from 30 s: delay RMSE from 40 s, ms (median)",
            measured: runs
                .traces(name, options)
                .map(|t| median_rmse_ms_from(t, 40.0)),
            limit: Limit::Max(40.0),
            bound: None,
        },
        "negative_delay" => bound_row(
            name,
            options,
            runs,
            2.0,
            "delay RMSE from 20 s, true -0.15 s, range -0.5..0.6 s, ms (median), judged on its ratio to the bound",
        ),
        "out_of_range_reported" => out_of_range_row(
            name,
            options,
            30.0,
            "s from the start until the below-range status is raised, true -0.15 s, default range (median)",
        ),
        "out_of_range_weak" => out_of_range_row(
            name,
            options,
            40.0,
            "low, GPS velocity noise doubled: s until the below-range status, true -0.15 s, default range (median)",
        ),
        "sigma_coverage" => sigma_coverage_row(options, runs),
        "gentle_motion" => Row {
            name,
            criterion: "ground vehicle shuttling at 2 m/s^2 peak, true 0.15 s, start 0.2 s: delay RMSE from 60 s, ms (median)",
            measured: runs
                .traces(name, options)
                .map(|t| median_rmse_ms_from(t, GENTLE_SCORE_FROM_S)),
            limit: Limit::Max(10.0),
            bound: None,
        },
        "acquisition_sigma" => {
            let ratios: Option<Vec<f64>> = runs.traces("cold_start_high", options).map(|t| {
                t.iter()
                    .flat_map(DelayTrace::acquisition_sigma_ratios)
                    .collect()
            });
            Row {
                name,
                criterion: "cold_start_high's runs, from the first valid update until Locked: median of sigma / |error|, pooled",
                measured: ratios.map(super::super::stats::median_ordered),
                limit: Limit::Band(0.5, 5.0),
                bound: None,
            }
        }
        "valid_means_close" => {
            let mut pooled = Some(Vec::new());
            for run in valid_runs() {
                match (runs.traces(run, options), pooled.as_mut()) {
                    (Some(t), Some(p)) => p.extend(t.iter().map(DelayTrace::valid_but_far)),
                    _ => pooled = None,
                }
            }
            Row {
                name,
                criterion: "every row's run with the delay in range: fraction of the samples with delay_valid whose |error| > 3 sigma, pooled",
                measured: pooled.and_then(|p| pooled_share(p.into_iter())),
                limit: Limit::Max(0.01),
                bound: None,
            }
        }
        _ => aekf17_hover_row(options),
    }
}

/// `sum(count) / sum(total)` of `(count, total)` pairs; `None` without a total.
fn pooled_share(pairs: impl Iterator<Item = (usize, usize)>) -> Option<f64> {
    let (k, n) = pairs.fold((0, 0), |(k, n), (a, b)| (k + a, n + b));
    (n > 0).then(|| k as f64 / n as f64)
}

/// A row of the delay RMSE from 20 s with its information bound, judged on the ratio (at most
/// `limit_ratio`).
fn bound_row(
    name: &'static str,
    options: &DelayOptions,
    runs: &mut Runs,
    limit_ratio: f64,
    criterion: &'static str,
) -> Row {
    Row {
        name,
        criterion,
        measured: runs.traces(name, options).map(median_rmse_ms),
        limit: Limit::Max(limit_ratio),
        bound: information_bound_ms(name, &options.seeds, options.threads),
    }
}

/// The delay information of row `name`'s runs on `seeds`, as the RMS from
/// [`SCORE_FROM_S`] of the Cramér-Rao bound of an estimator that knows the
/// acceleration exactly and keeps every GPS velocity since the start: a
/// constant delay ([`delay_bound_s`] with a window of the whole run) or, for
/// `delay_ramp`, a straight line ([`delay_ramp_bound_s`]); median over the
/// seeds, ms; `None` for a row that is not one navigator's run. The position fixes are left
/// out (they carry `|v|^2 / sigma_p^2` more, a few per cent here), and so are the unknown
/// velocity offset, attitude and biases, which a real estimator must also find: no estimator
/// does better, and a real one does worse.
pub fn information_bound_ms(name: &str, seeds: &[u64], threads: usize) -> Option<f64> {
    let bounds: Option<Vec<f64>> = per_seed(seeds, threads, |seed| {
        let (config, _) = row_run(name, seed)?;
        run_information_bound_s(name, &config, &events(&config)?)
    })
    .into_iter()
    .collect();
    bounds.map(|b| median(b.into_iter().map(|x| x * 1e3).collect()))
}

/// [`information_bound_ms`] of one run of row `name`, s.
pub(super) fn run_information_bound_s(
    name: &str,
    config: &SimConfig,
    events: &[SimEvent],
) -> Option<f64> {
    let fixes = fix_accelerations(events);
    let var = config.sensors.gps_velocity_var_m2_s2;
    let skip_us = (SCORE_FROM_S * 1e6) as u64;
    if name == "delay_ramp" {
        delay_ramp_bound_s(&fixes, var, skip_us)
    } else {
        let whole_run_us = (config.duration_s * 1e6) as u64 + 1;
        delay_bound_s(&fixes, var, whole_run_us, skip_us)
    }
}

/// High, calibrated start, 0.2 -> 0.35 s at 20 s: seconds after the step
/// until the error stays within 10 ms (median; infinite when never).
fn delay_step_row(options: &DelayOptions, runs: &mut Runs) -> Row {
    let measured = runs.traces("delay_step", options).map(|traces| {
        median_with_infinity(
            traces
                .iter()
                .map(|t| t.settle_after(STEP_AT_S, 0.010))
                .collect(),
        )
    });
    Row {
        name: "delay_step",
        criterion: "s after the 0.2 -> 0.35 s step at 20 s until the error stays <= 10 ms (median)",
        measured,
        limit: Limit::Max(8.0),
        bound: None,
    }
}

/// True -0.15 s with the default range `[0, 1] s`: seconds from the start
/// until the loop reports the delay below its range (median; infinite when
/// never), at most `limit_s`.
fn out_of_range_row(
    name: &'static str,
    options: &DelayOptions,
    limit_s: f64,
    criterion: &'static str,
) -> Row {
    let tuned = options.tuned();
    let times = per_seed(&options.seeds, options.threads, |seed| {
        let (config, setup) = row_run(name, seed)?;
        let mut estimator = proposed(&config, setup, tuned)?;
        for event in &events(&config)? {
            feed(&mut estimator, event);
            let below = matches!(
                estimator.delay_loop().status(),
                DelayStatus::BelowRange { .. }
            );
            // Checked after every event: the navigator runs the loop's
            // update at an IMU sample after the fix.
            if below {
                return Some(event.t_us() as f64 * 1e-6);
            }
        }
        Some(f64::INFINITY)
    });
    Row {
        name,
        criterion,
        measured: times
            .into_iter()
            .collect::<Option<Vec<f64>>>()
            .map(median_with_infinity),
        limit: Limit::Max(limit_s),
        bound: None,
    }
}

/// Low and high, calibrated start, pooled over the coverage seeds: fraction
/// of the trace points from 10 s whose error is within the reported 1-sigma.
fn sigma_coverage_row(options: &DelayOptions, runs: &mut Runs) -> Row {
    let mut pooled = Some(Vec::new());
    for run in super::EXTRA_TRACES {
        match (runs.traces(run, options), pooled.as_mut()) {
            (Some(t), Some(p)) => p.extend(t.iter().map(|t| t.coverage_from(10.0))),
            _ => pooled = None,
        }
    }
    Row {
        name: "sigma_coverage",
        criterion: "fraction of samples from 10 s with |error| <= reported 1-sigma, low and high, calibrated start, pooled",
        measured: pooled.and_then(|p| pooled_share(p.into_iter())),
        limit: Limit::Band(0.55, 0.80),
        bound: None,
    }
}

/// AEKF17 at hover for 60 s, started at the true 0.2 s with its default
/// sigma: |final error| / final sigma (median).
fn aekf17_hover_row(options: &DelayOptions) -> Row {
    let ratios = per_seed(&options.seeds, options.threads, |seed| {
        let (config, aekf) = aekf17_hover(seed, &super::HoverSetup::default())?;
        let t = trace(aekf, &events(&config)?, |_| None);
        let k = t.t_s.len().checked_sub(1)?;
        Some((t.estimate_s[k] - t.truth_s[k]).abs() / t.std_s[k])
    });
    let measured = ratios
        .into_iter()
        .collect::<Option<Vec<f64>>>()
        .map(median_with_infinity);
    Row {
        name: "aekf17_hover",
        criterion: "AEKF17, 60 s hover, true 0.2 s: |final error| / final sigma (median)",
        measured,
        limit: Limit::Max(3.0),
        bound: None,
    }
}

/// Still at the origin, level, fixed heading.
fn hover(mut config: SimConfig) -> SimConfig {
    config.trajectory.path.clear();
    config.trajectory.yaw_amplitude_rad = 0.0;
    config.trajectory.accel_limit_m_s2 = 1e-6;
    config
}

/// The run and the filter of the `aekf17_hover` row on `seed`, changed by `setup`; `None`
/// when the filter refuses its configuration.
pub(super) fn aekf17_hover(
    seed: u64,
    setup: &super::HoverSetup,
) -> Option<(SimConfig, AugmentedEkf17<f64>)> {
    let mut config = hover(sim(Scenario::High, seed, DelayProfile::constant(0.2)));
    if let Some(duration_s) = setup.duration_s {
        config.duration_s = duration_s;
    }
    let mut aekf = AugmentedEkf17Config::with_nav(ekf16_config(&config));
    aekf.initial_delay_s = 0.2;
    if let Some(q) = setup.delay_random_walk {
        aekf.delay_random_walk = q;
    }
    if let Some(t) = setup.accel_smoothing_s {
        aekf.accel_smoothing_s = t;
    }
    let filter = AugmentedEkf17::new(aekf).ok()?;
    Some((config, filter))
}

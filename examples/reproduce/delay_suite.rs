//! The delay suite of issue 11: how fast the delay loop locks on, how it
//! follows changes, at which GPS rates it works, what it reports outside its
//! range, and whether its sigma is honest.
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --delay-suite --json target/delay-suite.json
//! ```
//!
//! writes `"delay_scenarios": [{"name", "passed", "criterion", "measured", "limit"}]`. Unless a
//! row says otherwise: the `proposed` navigator, no offline calibration, start 0.1 s, 60 s runs,
//! `--seeds` seeds (default 5) with the median reported, delay RMSE scored from 20 s. A row whose
//! behaviour cannot run (the navigator refuses its configuration) has `measured: null` and
//! `passed: false`; it is never skipped. Seeds run on two threads. Beside the rows (whose keys
//! stay the issue's), `information_bounds` maps each RMSE row to the delay RMSE that no
//! estimator can beat on the same runs (the Cramér-Rao bound of every GPS velocity since the
//! start, the acceleration known), so that a row's figure can be read against what its motion
//! allows.

use super::{
    CALIBRATION_DURATION_S, CALIBRATION_SEED_OFFSET, DelayStart, UNCALIBRATED_START, calibrate,
    ekf16_config, median, nav,
};
use delaynav::delay::{DefaultDelayLoop, DelayLoopConfig, DelayStatus};
use delaynav::nav::{DelayCompensatedNav, DelayMode};
use delaynav::sim::{
    DelayProfile, DelayRamp, DelayStep, STANDARD_GRAVITY, Scenario, SimConfig, SimEvent,
    Simulation, delay_bound_s, delay_ramp_bound_s,
};
use delaynav::{AugmentedEkf17, AugmentedEkf17Config, Navigator};
use nalgebra::Vector3;
use serde_json::{Value, json};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Length of every run, s.
const RUN_S: f64 = 60.0;
/// Scored from here, s (the simulator's trajectories carry little motion before 15 s).
const SCORE_FROM_S: f64 = 20.0;
/// When `delay_step`'s delay steps, s.
const STEP_AT_S: f64 = 20.0;
/// Spacing of the trace points, us.
const TRACE_STEP_US: u64 = 10_000;
/// Worker threads (the machine's two cores).
const THREADS: usize = 2;

/// What a row accepts.
#[derive(Debug, Clone, Copy)]
pub enum Limit {
    /// The measured figure must be at most this.
    Max(f64),
    /// The measured figure must lie in `[lo, hi]`.
    Band(f64, f64),
}

impl Limit {
    fn accepts(self, x: f64) -> bool {
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
#[derive(Debug, Clone)]
pub struct Row {
    /// The issue's name of the row.
    pub name: &'static str,
    /// What is measured, with its unit.
    pub criterion: &'static str,
    /// The measured figure; `None` when the behaviour cannot run.
    pub measured: Option<f64>,
    /// The issue's limit.
    pub limit: Limit,
    /// For the RMSE rows, what no estimator can beat on the row's runs, in
    /// the row's unit: the Cramér-Rao bound of the GPS velocities given the
    /// true acceleration and every fix since the start (median over seeds;
    /// see [`information_bound_ms`]).
    pub bound: Option<f64>,
}

impl Row {
    /// A finite measured figure within the limit.
    pub fn passed(&self) -> bool {
        self.measured
            .is_some_and(|x| x.is_finite() && self.limit.accepts(x))
    }

    fn to_json(&self) -> Value {
        json!({
            "name": self.name,
            "passed": self.passed(),
            "criterion": self.criterion,
            "measured": self.measured.filter(|x| x.is_finite()),
            "limit": self.limit.to_json(),
        })
    }
}

/// How much of the suite to run.
#[derive(Debug, Clone)]
pub struct SuiteOptions {
    /// Seeds of every row but `sigma_coverage`.
    pub seeds: Vec<u64>,
    /// Seeds of `sigma_coverage`, per scenario.
    pub coverage_seeds: Vec<u64>,
    /// Only these rows (all when `None`).
    pub rows: Option<Vec<&'static str>>,
    /// Changes to the delay loop's defaults, applied to the `proposed`
    /// navigator of every row.
    pub tuning: LoopTuning,
}

/// The suite's rows, in the order they run.
pub const ROW_NAMES: [&str; 11] = [
    "cold_start_low",
    "cold_start_high",
    "delay_step",
    "delay_ramp",
    "delay_jitter",
    "gps_2hz",
    "gps_1hz",
    "negative_delay",
    "out_of_range_reported",
    "sigma_coverage",
    "aekf17_hover",
];

/// The rows [`write_trace`] can trace (the `proposed` navigator on one
/// run): every row but the last two, which are not one navigator's run.
pub const TRACE_ROWS: &[&str] = ROW_NAMES.split_at(ROW_NAMES.len() - 2).0;

/// Runs [`write_trace`] can trace beside [`TRACE_ROWS`]: the two scenarios
/// of `sigma_coverage` (constant 0.2 s, calibrated start).
pub const EXTRA_TRACES: [&str; 2] = ["calibrated_low", "calibrated_high"];

/// The row named `name` (its static name), `None` when the suite has none.
pub fn row_name(name: &str) -> Option<&'static str> {
    ROW_NAMES.iter().copied().find(|&n| n == name)
}

/// Changes to the delay loop's defaults (`None`: the default).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoopTuning {
    /// [`GainFusionConfig::rate_std`](delaynav::delay::GainFusionConfig::rate_std), s/s.
    pub rate_std: Option<f64>,
    /// [`GainFusionConfig::rate_time_constant_s`](delaynav::delay::GainFusionConfig::rate_time_constant_s), s.
    pub rate_time_constant_s: Option<f64>,
    /// [`DelayLoopConfig::process_noise_ms2_per_s`], ms^2/s.
    pub process_noise_ms2_per_s: Option<f64>,
    /// [`DelayLoopConfig::innovation_window_s`], s (0: off).
    pub innovation_window_s: Option<f64>,
    /// [`DelayLoopConfig::innovation_noise_scale`].
    pub innovation_noise_scale: Option<f64>,
    /// [`DelayLoopConfig::innovation_reacquire_sigma`].
    pub innovation_reacquire_sigma: Option<f64>,
    /// [`DelayLoopConfig::innovation_before_lock`] on.
    pub innovation_before_lock: bool,
    /// [`DelayLoopConfig::innovation_acquire_noise_scale`].
    pub innovation_acquire_noise_scale: Option<f64>,
    /// [`DelayLoopConfig::measurement_noise_ms2`], ms^2, every axis.
    pub measurement_noise_ms2: Option<f64>,
    /// [`DelayLoopConfig::acquisition_motion_exponent`].
    pub acquisition_motion_exponent: Option<f64>,
    /// [`DelayLoopConfig::smoothing_cutoff_hz`], Hz.
    pub smoothing_cutoff_hz: Option<f64>,
}

impl LoopTuning {
    /// Sets the fields given on `config` (the others keep its values).
    pub fn apply(self, config: &mut DelayLoopConfig<f64>) {
        if let Some(rate_std) = self.rate_std {
            config.fusion.rate_std = rate_std;
        }
        if let Some(t) = self.rate_time_constant_s {
            config.fusion.rate_time_constant_s = t;
        }
        if let Some(q) = self.process_noise_ms2_per_s {
            config.process_noise_ms2_per_s = q;
        }
        if let Some(w) = self.innovation_window_s {
            config.innovation_window_s = w;
        }
        if let Some(k) = self.innovation_noise_scale {
            config.innovation_noise_scale = k;
        }
        if let Some(k) = self.innovation_reacquire_sigma {
            config.innovation_reacquire_sigma = k;
        }
        if self.innovation_before_lock {
            config.innovation_before_lock = true;
        }
        if let Some(k) = self.innovation_acquire_noise_scale {
            config.innovation_acquire_noise_scale = k;
        }
        if let Some(r) = self.measurement_noise_ms2 {
            config.measurement_noise_ms2 = [r; 3];
        }
        if let Some(e) = self.acquisition_motion_exponent {
            config.acquisition_motion_exponent = e;
        }
        if let Some(f) = self.smoothing_cutoff_hz {
            config.smoothing_cutoff_hz = f;
        }
    }

    fn to_json(self) -> Value {
        json!({
            "rate_std_s_per_s": self.rate_std,
            "rate_time_constant_s": self.rate_time_constant_s,
            "process_noise_ms2_per_s": self.process_noise_ms2_per_s,
            "innovation_window_s": self.innovation_window_s,
            "innovation_noise_scale": self.innovation_noise_scale,
            "innovation_reacquire_sigma": self.innovation_reacquire_sigma,
            "innovation_before_lock": self.innovation_before_lock,
            "innovation_acquire_noise_scale": self.innovation_acquire_noise_scale,
            "measurement_noise_ms2": self.measurement_noise_ms2,
            "acquisition_motion_exponent": self.acquisition_motion_exponent,
            "smoothing_cutoff_hz": self.smoothing_cutoff_hz,
        })
    }
}

impl SuiteOptions {
    /// The issue's suite: `seeds` seeds from `first` (20 for the coverage).
    pub fn full(first: u64, seeds: u64) -> Self {
        Self {
            seeds: (first..first + seeds).collect(),
            coverage_seeds: (first..first + 20).collect(),
            rows: None,
            tuning: LoopTuning::default(),
        }
    }

    fn wants(&self, name: &str) -> bool {
        self.rows.as_ref().is_none_or(|r| r.contains(&name))
    }
}

/// The delay estimate of one run at regular instants.
#[derive(Debug, Default, Clone)]
struct DelayTrace {
    t_s: Vec<f64>,
    estimate_s: Vec<f64>,
    std_s: Vec<f64>,
    truth_s: Vec<f64>,
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
    fn rmse_from(&self, from_s: f64) -> f64 {
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
    fn settle_after(&self, from_s: f64, tolerance_s: f64) -> f64 {
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

    /// Fraction of points from `from_s` whose error is within one sigma,
    /// as (inside, total).
    fn coverage_from(&self, from_s: f64) -> (usize, usize) {
        self.errors_from(from_s)
            .fold((0, 0), |(inside, n), (_, e, s)| {
                (inside + usize::from(e.abs() <= s), n + 1)
            })
    }
}

/// Feeds one event to an estimator (refusals are its business).
fn feed<N: Navigator<f64>>(estimator: &mut N, event: &SimEvent) {
    match event {
        SimEvent::Imu { sample, .. } => {
            let _ = estimator.push_imu(sample);
        }
        SimEvent::Mag(m) => {
            let _ = estimator.push_mag(m);
        }
        SimEvent::Gps { fix, .. } => {
            let _ = estimator.push_gps(fix);
        }
    }
}

/// Feeds a run to an estimator (refusals are its business) and records its
/// delay estimate every [`TRACE_STEP_US`].
fn trace<N: Navigator<f64>>(mut estimator: N, events: &[SimEvent]) -> DelayTrace {
    let mut out = DelayTrace::default();
    for event in events {
        feed(&mut estimator, event);
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        if !truth.t_us.is_multiple_of(TRACE_STEP_US) {
            continue;
        }
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

/// Runs `f` on every seed, on [`THREADS`] threads; results in seed order.
fn per_seed<R: Send>(seeds: &[u64], f: impl Fn(u64) -> R + Sync) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..seeds.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..THREADS.min(seeds.len()) {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&seed) = seeds.get(k) else { break };
                    let r = f(seed);
                    results.lock().expect("no worker panicked")[k] = Some(r);
                }
            });
        }
    });
    results
        .into_inner()
        .expect("no worker panicked")
        .into_iter()
        .map(|r| r.expect("every seed ran"))
        .collect()
}

/// A 60 s run of `scenario` with `seed` and the delay `profile`.
fn sim(scenario: Scenario, seed: u64, profile: DelayProfile) -> SimConfig {
    SimConfig {
        duration_s: RUN_S,
        delay: profile,
        ..SimConfig::for_scenario(scenario, seed)
    }
}

fn events(config: &SimConfig) -> Vec<SimEvent> {
    Simulation::new(config.clone())
        .expect("valid simulation config")
        .collect()
}

/// The offline calibration of `config`'s seed on its own run (as the
/// calibrated reproduce runs do), with a constant delay equal to the
/// profile's start.
fn calibrated_start(config: &SimConfig) -> DelayStart {
    let mut cal = config.clone();
    cal.seed = config.seed + CALIBRATION_SEED_OFFSET;
    cal.duration_s = CALIBRATION_DURATION_S;
    cal.delay = DelayProfile::constant(config.delay.initial_s);
    calibrate(&cal)
}

/// How the navigator of a row is configured beyond the simulator's EKF.
#[derive(Debug, Clone, Copy)]
struct NavSetup {
    calibrated: bool,
    /// Delay range of the loop, s (`None`: the default).
    range_s: Option<(f64, f64)>,
    /// The loop adapted to this GPS rate, Hz (`None`: the 10 Hz defaults).
    gps_rate_hz: Option<f64>,
}

const COLD: NavSetup = NavSetup {
    calibrated: false,
    range_s: None,
    gps_rate_hz: None,
};

const CALIBRATED: NavSetup = NavSetup {
    calibrated: true,
    ..COLD
};

/// The `proposed` navigator of a row; `None` when it refuses the setup.
fn proposed(
    config: &SimConfig,
    setup: NavSetup,
    tuning: LoopTuning,
) -> Option<DelayCompensatedNav<f64>> {
    let start = if setup.calibrated {
        calibrated_start(config)
    } else {
        UNCALIBRATED_START
    };
    let mode = DelayMode::Estimated {
        initial_s: start.delay_s,
    };
    let mut nav_config = *nav(config, mode, start.std_s).config();
    if let Some(rate_hz) = setup.gps_rate_hz {
        nav_config.delay_loop = nav_config.delay_loop.adapted_to_gps_rate(rate_hz).ok()?;
    }
    if let Some((min, max)) = setup.range_s {
        nav_config.delay_loop.fusion.delay_min_s = min;
        nav_config.delay_loop.fusion.delay_max_s = max;
    }
    tuning.apply(&mut nav_config.delay_loop);
    DelayCompensatedNav::new(nav_config).ok()
}

/// The run and the navigator setup of the `proposed` row `name` (or one of
/// [`EXTRA_TRACES`]) on `seed`; `None` for `sigma_coverage` (two scenarios)
/// and `aekf17_hover` (not the navigator), and for names the suite does not
/// have.
fn row_run(name: &str, seed: u64) -> Option<(SimConfig, NavSetup)> {
    let constant = |scenario, delay_s| sim(scenario, seed, DelayProfile::constant(delay_s));
    let high = |profile| sim(Scenario::High, seed, profile);
    Some(match name {
        "calibrated_low" => (constant(Scenario::Low, 0.2), CALIBRATED),
        "calibrated_high" => (constant(Scenario::High, 0.2), CALIBRATED),
        "cold_start_low" => (constant(Scenario::Low, 0.2), COLD),
        "cold_start_high" => (constant(Scenario::High, 0.2), COLD),
        "delay_step" => {
            let profile = DelayProfile {
                steps: vec![DelayStep {
                    at_s: STEP_AT_S,
                    change_s: 0.15,
                }],
                ..DelayProfile::constant(0.2)
            };
            (high(profile), CALIBRATED)
        }
        "delay_ramp" => {
            let profile = DelayProfile {
                ramps: vec![DelayRamp {
                    start_s: 0.0,
                    duration_s: RUN_S,
                    change_s: 0.06,
                }],
                ..DelayProfile::constant(0.2)
            };
            (high(profile), COLD)
        }
        "delay_jitter" => {
            let profile = DelayProfile {
                jitter_uniform_half_width_s: 0.020,
                ..DelayProfile::constant(0.2)
            };
            (high(profile), COLD)
        }
        "gps_2hz" | "gps_1hz" => {
            let rate_hz = if name == "gps_2hz" { 2.0 } else { 1.0 };
            let setup = NavSetup {
                gps_rate_hz: Some(rate_hz),
                ..COLD
            };
            (with_gps_rate(constant(Scenario::High, 0.2), rate_hz), setup)
        }
        "negative_delay" => {
            let setup = NavSetup {
                range_s: Some((-0.5, 0.6)),
                ..COLD
            };
            (constant(Scenario::High, -0.15), setup)
        }
        "out_of_range_reported" => (constant(Scenario::High, -0.15), COLD),
        _ => return None,
    })
}

/// Delay traces of the `proposed` navigator of row `name` on every seed;
/// `None` when it refuses the setup.
fn row_traces(name: &str, seeds: &[u64], tuning: LoopTuning) -> Option<Vec<DelayTrace>> {
    per_seed(seeds, |seed| {
        let (config, setup) = row_run(name, seed)?;
        proposed_trace(&config, setup, tuning)
    })
    .into_iter()
    .collect()
}

/// The delay trace of the `proposed` navigator on `config`'s run; `None`
/// when it refuses the setup.
fn proposed_trace(config: &SimConfig, setup: NavSetup, tuning: LoopTuning) -> Option<DelayTrace> {
    let estimator = proposed(config, setup, tuning)?;
    Some(trace(estimator, &events(config)))
}

/// Median over the seeds of the delay RMSE from 20 s, ms.
fn median_rmse_ms(traces: &[DelayTrace]) -> f64 {
    median(
        traces
            .iter()
            .map(|t| t.rmse_from(SCORE_FROM_S) * 1e3)
            .collect(),
    )
}

/// Median that keeps infinite values (a run that never settled) in order.
fn median_with_infinity(xs: Vec<f64>) -> f64 {
    if xs.iter().any(|x| x.is_nan()) {
        return f64::NAN;
    }
    super::median_ordered(xs)
}

fn rmse_row(
    name: &'static str,
    options: &SuiteOptions,
    limit_ms: f64,
    criterion: &'static str,
) -> Row {
    let measured = row_traces(name, &options.seeds, options.tuning).map(|t| median_rmse_ms(&t));
    Row {
        name,
        criterion,
        measured,
        limit: Limit::Max(limit_ms),
        bound: information_bound_ms(name, &options.seeds),
    }
}

/// The delay information of row `name`'s runs, as the RMS from
/// [`SCORE_FROM_S`] of the Cramér-Rao bound of an estimator that knows the
/// acceleration exactly and keeps every GPS velocity since the start: a
/// constant delay ([`delay_bound_s`] with a window of the whole run) or, for
/// `delay_ramp`, a straight line ([`delay_ramp_bound_s`]); median over the
/// seeds, ms. The position fixes are left out (they carry `|v|^2 / sigma_p^2`
/// more, a few per cent here), and so are the unknown velocity offset,
/// attitude and biases, which a real estimator must also find: no estimator
/// does better, and a real one does worse.
fn information_bound_ms(name: &str, seeds: &[u64]) -> Option<f64> {
    let bounds: Option<Vec<f64>> = per_seed(seeds, |seed| {
        let (config, _) = row_run(name, seed)?;
        run_information_bound_s(name, &config, &events(&config))
    })
    .into_iter()
    .collect();
    bounds.map(|b| median(b.into_iter().map(|x| x * 1e3).collect()))
}

/// [`information_bound_ms`] of one run of row `name`, s.
fn run_information_bound_s(name: &str, config: &SimConfig, events: &[SimEvent]) -> Option<f64> {
    let fixes = super::fix_accelerations(events);
    let var = config.sensors.gps_velocity_var_m2_s2;
    let skip_us = (SCORE_FROM_S * 1e6) as u64;
    if name == "delay_ramp" {
        delay_ramp_bound_s(&fixes, var, skip_us)
    } else {
        let whole_run_us = (config.duration_s * 1e6) as u64 + 1;
        delay_bound_s(&fixes, var, whole_run_us, skip_us)
    }
}

fn with_gps_rate(mut config: SimConfig, rate_hz: f64) -> SimConfig {
    config.sensors.gps_rate_hz = rate_hz;
    config
}

/// Still at the origin, level, fixed heading.
fn hover(mut config: SimConfig) -> SimConfig {
    config.trajectory.path.clear();
    config.trajectory.yaw_amplitude_rad = 0.0;
    config.trajectory.accel_limit_m_s2 = 1e-6;
    config
}

/// Runs the suite's rows that `options` selects, printing each as it ends.
pub fn run(options: &SuiteOptions) -> Vec<Row> {
    let mut rows = Vec::new();
    let mut push = |row: Row| {
        eprintln!(
            "{:<22} {:<6} measured {:>10} limit {:?}{}",
            row.name,
            if row.passed() { "PASS" } else { "FAIL" },
            row.measured.map_or("null".into(), |x| format!("{x:.4}")),
            row.limit,
            row.bound
                .map_or(String::new(), |b| format!(" (information bound {b:.2})")),
        );
        rows.push(row);
    };
    let rmse = "delay RMSE from 20 s, ms (median over seeds)";
    for name in ROW_NAMES {
        if !options.wants(name) {
            continue;
        }
        push(match name {
            "cold_start_low" => rmse_row(name, options, 6.0, rmse),
            "cold_start_high" => rmse_row(name, options, 4.0, rmse),
            "delay_step" => delay_step_row(options),
            "delay_ramp" => rmse_row(name, options, 10.0, rmse),
            "delay_jitter" => rmse_row(
                name,
                options,
                5.0,
                "delay RMSE against 0.2 s from 20 s, ms (median)",
            ),
            "gps_2hz" => rmse_row(name, options, 20.0, rmse),
            "gps_1hz" => rmse_row(name, options, 40.0, rmse),
            "negative_delay" => rmse_row(
                name,
                options,
                10.0,
                "delay RMSE from 20 s, true -0.15 s, range -0.5..0.6 s, ms (median)",
            ),
            "out_of_range_reported" => out_of_range_row(options),
            "sigma_coverage" => sigma_coverage_row(options),
            _ => aekf17_hover_row(options),
        });
    }
    rows
}

/// High, calibrated start, 0.2 -> 0.35 s at 20 s: seconds after the step
/// until the error stays within 10 ms (median; infinite when never).
fn delay_step_row(options: &SuiteOptions) -> Row {
    let measured = row_traces("delay_step", &options.seeds, options.tuning).map(|traces| {
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
/// never).
fn out_of_range_row(options: &SuiteOptions) -> Row {
    let times = per_seed(&options.seeds, |seed| {
        let (config, setup) = row_run("out_of_range_reported", seed)?;
        let mut estimator = proposed(&config, setup, options.tuning)?;
        for event in &events(&config) {
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
        name: "out_of_range_reported",
        criterion: "s from the start until the below-range status is raised, true -0.15 s, default range (median)",
        measured: times
            .into_iter()
            .collect::<Option<Vec<f64>>>()
            .map(median_with_infinity),
        limit: Limit::Max(30.0),
        bound: None,
    }
}

/// Low and high, calibrated start, pooled over the coverage seeds: fraction
/// of the trace points from 10 s whose error is within the reported 1-sigma.
fn sigma_coverage_row(options: &SuiteOptions) -> Row {
    let mut inside = 0usize;
    let mut total = 0usize;
    let mut refused = false;
    for run in EXTRA_TRACES {
        let traces: Option<Vec<DelayTrace>> = per_seed(&options.coverage_seeds, |seed| {
            let (config, setup) = row_run(run, seed)?;
            proposed_trace(&config, setup, options.tuning)
        })
        .into_iter()
        .collect();
        match traces {
            Some(traces) => {
                for t in &traces {
                    let (i, n) = t.coverage_from(10.0);
                    inside += i;
                    total += n;
                }
            }
            None => refused = true,
        }
    }
    Row {
        name: "sigma_coverage",
        criterion: "fraction of samples from 10 s with |error| <= reported 1-sigma, low and high, calibrated start, pooled",
        measured: (!refused && total > 0).then(|| inside as f64 / total as f64),
        limit: Limit::Band(0.55, 0.80),
        bound: None,
    }
}

/// AEKF17 at hover for 60 s, started at the true 0.2 s with its default
/// sigma: |final error| / final sigma (median).
fn aekf17_hover_row(options: &SuiteOptions) -> Row {
    let ratios = per_seed(&options.seeds, |seed| {
        let (config, aekf) = aekf17_hover(seed, &HoverSetup::default());
        let t = trace(aekf, &events(&config));
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

/// Changes to the `aekf17_hover` row for [`write_hover_trace`] (`None`: the
/// row's).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HoverSetup {
    /// Length of the hover, s [default: 60].
    pub duration_s: Option<f64>,
    /// `AugmentedEkf17Config::delay_random_walk`.
    pub delay_random_walk: Option<f64>,
    /// `AugmentedEkf17Config::accel_smoothing_s`.
    pub accel_smoothing_s: Option<f64>,
}

/// The run and the filter of the `aekf17_hover` row on `seed`.
fn aekf17_hover(seed: u64, setup: &HoverSetup) -> (SimConfig, AugmentedEkf17<f64>) {
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
    let filter = AugmentedEkf17::new(aekf).expect("valid Aekf17 config");
    (config, filter)
}

/// The end of [`write_hover_trace`]'s run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoverSummary {
    /// CSV rows written (one a second).
    pub rows: usize,
    /// Delay estimate at the last 10 ms point, s.
    pub estimate_s: f64,
    /// Its sigma, s.
    pub sigma_s: f64,
    /// |error| / sigma there (the row's figure for this seed).
    pub ratio: f64,
    /// Times the filter clamped the delay into its range.
    pub clamps: u32,
}

/// Runs AEKF17 on the `aekf17_hover` row's run of `seed`, changed by
/// `setup`, and writes every second the true delay, the estimate, its
/// sigma, |error| / sigma and the clamp count as CSV to `out`.
pub fn write_hover_trace(
    seed: u64,
    setup: &HoverSetup,
    out: &mut impl std::io::Write,
) -> std::io::Result<HoverSummary> {
    let (config, mut aekf) = aekf17_hover(seed, setup);
    writeln!(out, "t_s,truth_s,estimate_s,sigma_s,ratio,clamps")?;
    let mut summary = HoverSummary {
        rows: 0,
        estimate_s: f64::NAN,
        sigma_s: f64::NAN,
        ratio: f64::NAN,
        clamps: 0,
    };
    for event in &events(&config) {
        feed(&mut aekf, event);
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        if !truth.t_us.is_multiple_of(TRACE_STEP_US) {
            continue;
        }
        let est = aekf.estimate();
        summary.estimate_s = est.and_then(|e| e.delay_s).unwrap_or(f64::NAN);
        summary.sigma_s = est.and_then(|e| e.delay_std_s).unwrap_or(f64::NAN);
        summary.ratio = (summary.estimate_s - truth.gps_delay_s).abs() / summary.sigma_s;
        summary.clamps = aekf.delay_clamps();
        if truth.t_us.is_multiple_of(CSV_STEP_US) {
            writeln!(
                out,
                "{:.1},{:.6},{:.6},{:.6},{:.4},{}",
                truth.t_us as f64 * 1e-6,
                truth.gps_delay_s,
                summary.estimate_s,
                summary.sigma_s,
                summary.ratio,
                summary.clamps,
            )?;
            summary.rows += 1;
        }
    }
    Ok(summary)
}

/// The suite's rows as `--check` verdicts (a row that cannot run fails).
pub fn verdicts(rows: &[Row]) -> Vec<super::check::Verdict> {
    rows.iter()
        .map(|r| super::check::Verdict {
            name: r.name.to_string(),
            passed: r.passed(),
            measured: r.measured,
            limit: format!("{:?} ({})", r.limit, r.criterion),
        })
        .collect()
}

/// The suite's JSON document.
pub fn to_json(rows: &[Row], options: &SuiteOptions) -> Value {
    json!({
        "suite": "delay (issue 11)",
        "seeds": options.seeds,
        "coverage_seeds": options.coverage_seeds,
        "loop_tuning": options.tuning.to_json(),
        "run_s": RUN_S,
        "score_from_s": SCORE_FROM_S,
        "delay_scenarios": rows.iter().map(Row::to_json).collect::<Vec<_>>(),
        "information_bounds": rows
            .iter()
            .filter_map(|r| Some((r.name.to_string(), json!(r.bound?))))
            .collect::<serde_json::Map<String, Value>>(),
    })
}

/// Spacing of the rows of [`write_trace`], us.
const CSV_STEP_US: u64 = 1_000_000;

/// Names of the loop's axes, in [`DelayUpdate::axes`] order.
const AXIS_NAMES: [&str; 3] = ["north", "east", "down"];

fn status_name(status: DelayStatus<f64>) -> &'static str {
    match status {
        DelayStatus::WaitingForData => "waiting_for_data",
        DelayStatus::WaitingForMotion => "waiting_for_motion",
        DelayStatus::Acquiring => "acquiring",
        DelayStatus::Locked => "locked",
        DelayStatus::BelowRange { .. } => "below_range",
        DelayStatus::AboveRange { .. } => "above_range",
    }
}

/// What [`write_trace`] wrote and measured.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceSummary {
    /// CSV rows written (one a second).
    pub rows: usize,
    /// Delay RMSE from 20 s at the suite's 10 ms spacing, ms, per estimate:
    /// `navigator` (as the suite scores it), and with `compare` `oracle_accel`
    /// and `true_accel`.
    pub rmse_ms: Vec<(&'static str, f64)>,
    /// The row's information bound on this run ([`information_bound_ms`]:
    /// the Cramér-Rao bound from every GPS velocity since the start, a line
    /// for `delay_ramp`), RMS from 20 s, ms.
    pub information_bound_ms: f64,
    /// Fraction of the navigator's points from 20 s (10 ms spacing) whose
    /// error is within its reported 1-sigma.
    pub sigma_coverage: f64,
}

/// Squared-error sum and count from [`SCORE_FROM_S`] of one estimate.
#[derive(Debug, Default, Clone, Copy)]
struct Score {
    sum: f64,
    n: usize,
}

impl Score {
    fn add(&mut self, t_s: f64, error_s: f64) {
        if t_s >= SCORE_FROM_S {
            self.sum += error_s * error_s;
            self.n += 1;
        }
    }

    fn rmse_ms(self) -> f64 {
        (self.sum / self.n as f64).sqrt() * 1e3
    }
}

/// Two more delay loops beside the navigator's, configured as its loop and
/// fed the same GPS fixes: one the `oracle` navigator's NED acceleration
/// (the navigator in fixed mode, given the true start delay; its `a_fwd`
/// when the accelerometer whitening is a pass-through, as here), one the
/// measured specific force rotated with the true attitude, true bias
/// removed, gravity added (the true acceleration plus the accelerometer's
/// noise).
struct Comparison {
    oracle: DelayCompensatedNav<f64>,
    oracle_loop: Box<DefaultDelayLoop<f64>>,
    true_loop: Box<DefaultDelayLoop<f64>>,
}

impl Comparison {
    fn new(config: &SimConfig, nav: &DelayCompensatedNav<f64>) -> Option<Self> {
        let mode = DelayMode::Fixed {
            delay_s: config.delay.initial_s,
        };
        let loop_config = *nav.delay_loop().config();
        Some(Self {
            oracle: super::nav(config, mode, None),
            oracle_loop: Box::new(DefaultDelayLoop::new(loop_config).ok()?),
            true_loop: Box::new(DefaultDelayLoop::new(loop_config).ok()?),
        })
    }

    /// Refusals are the loops' business, as the navigator's.
    fn feed(&mut self, event: &SimEvent) {
        feed(&mut self.oracle, event);
        match event {
            SimEvent::Imu { sample, truth } => {
                if let Some(a) = self.oracle.acceleration_ned_m_s2() {
                    let _ = self.oracle_loop.push_imu(sample.t_us, a);
                }
                let gravity = Vector3::new(0.0, 0.0, STANDARD_GRAVITY);
                let a = truth.attitude * (sample.accel_m_s2 - truth.accel_bias_m_s2) + gravity;
                let _ = self.true_loop.push_imu(sample.t_us, a);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = self.oracle_loop.push_gps_fix(fix);
                let _ = self.true_loop.push_gps_fix(fix);
            }
            SimEvent::Mag(_) => {}
        }
    }
}

/// Runs the `proposed` navigator of row `name` on `seed` and writes, every
/// second, the true delay, the navigator's estimate and sigma, the loop's
/// drift-rate estimate and status, the gain fusion's own sigma, the last
/// innovation window (estimate and std, when the observation is on), and the last delay update's axes (valid flag, window peak, peak
/// correlation, IMU acceleration variance over the buffer) as CSV to `out`.
/// Delays are relative to the raw IMU (the loop's values plus the
/// accelerometer whitening's group delay), as the suite scores them. With
/// `compare`, two more loops fed other accelerations ([`Comparison`]) add
/// their estimates. `Ok(None)` when the row has no navigator trace or the
/// navigator refuses its setup.
pub fn write_trace(
    name: &str,
    seed: u64,
    tuning: LoopTuning,
    compare: bool,
    out: &mut impl std::io::Write,
) -> std::io::Result<Option<TraceSummary>> {
    let Some((config, setup)) = row_run(name, seed) else {
        return Ok(None);
    };
    let Some(mut nav) = proposed(&config, setup, tuning) else {
        return Ok(None);
    };
    let mut comparison = None;
    if compare {
        let Some(c) = Comparison::new(&config, &nav) else {
            return Ok(None);
        };
        comparison = Some(c);
    }
    let (group_delay_s, _) = nav.group_delays_s();
    write!(
        out,
        "t_s,truth_s,estimate_s,sigma_s,error_ms,rate_ms_per_s,status,gfa_std_s,innovation_estimate_s,innovation_std_s,update_t_s"
    )?;
    for axis in AXIS_NAMES {
        write!(
            out,
            ",{axis}_valid,{axis}_peak_s,{axis}_peak_error_ms,{axis}_correlation,{axis}_accel_variance_m2_s4"
        )?;
    }
    if compare {
        write!(out, ",oracle_accel_estimate_s,true_accel_estimate_s")?;
    }
    writeln!(out)?;
    let mut rows = 0;
    let mut scores = [Score::default(); 3];
    let mut covered = (0usize, 0usize);
    for event in &events(&config) {
        feed(&mut nav, event);
        if let Some(c) = &mut comparison {
            c.feed(event);
        }
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        if !truth.t_us.is_multiple_of(TRACE_STEP_US) {
            continue;
        }
        let t_s = truth.t_us as f64 * 1e-6;
        let truth_s = truth.gps_delay_s;
        let others = comparison.as_ref().map(|c| {
            [
                c.oracle_loop.delay_s() + group_delay_s,
                c.true_loop.delay_s() + group_delay_s,
            ]
        });
        let estimate_s = nav.estimate().and_then(|e| e.delay_s).unwrap_or(f64::NAN);
        scores[0].add(t_s, estimate_s - truth_s);
        if t_s >= SCORE_FROM_S {
            covered.0 += usize::from((estimate_s - truth_s).abs() <= nav.delay_std_s());
            covered.1 += 1;
        }
        for (score, other) in scores[1..].iter_mut().zip(others.iter().flatten()) {
            score.add(t_s, other - truth_s);
        }
        if !truth.t_us.is_multiple_of(CSV_STEP_US) {
            continue;
        }
        write!(
            out,
            "{t_s:.1},{truth_s:.6},{estimate_s:.6},{:.6},{:.3},{:.4},{}",
            nav.delay_std_s(),
            (estimate_s - truth_s) * 1e3,
            nav.delay_loop().delay_rate() * 1e3,
            status_name(nav.delay_loop().status()),
        )?;
        write!(out, ",{:.6}", nav.delay_loop().fusion_std_s())?;
        match nav.delay_loop().innovation_estimate() {
            Some((z, std)) => write!(out, ",{:.6},{std:.6}", z + group_delay_s)?,
            None => write!(out, ",,")?,
        }
        match nav.last_delay_update() {
            Some(update) => {
                write!(out, ",{:.3}", update.t_us as f64 * 1e-6)?;
                for axis in &update.axes {
                    let peak_s = axis.measured_delay_s + group_delay_s;
                    write!(
                        out,
                        ",{},{peak_s:.6},{:.3},{:.4},{:.4}",
                        u8::from(axis.valid),
                        (peak_s - truth_s) * 1e3,
                        axis.correlation.peak,
                        axis.correlation.accel_variance,
                    )?;
                }
            }
            None => write!(out, "{}", ",".repeat(1 + 5 * AXIS_NAMES.len()))?,
        }
        if let Some([oracle_s, true_s]) = others {
            write!(out, ",{oracle_s:.6},{true_s:.6}")?;
        }
        writeln!(out)?;
        rows += 1;
    }
    let names = ["navigator", "oracle_accel", "true_accel"];
    let kept = if compare { 3 } else { 1 };
    let information_bound_ms =
        run_information_bound_s(name, &config, &events(&config)).map_or(f64::NAN, |s| s * 1e3);
    Ok(Some(TraceSummary {
        information_bound_ms,
        sigma_coverage: covered.0 as f64 / covered.1.max(1) as f64,
        rows,
        rmse_ms: names
            .into_iter()
            .zip(scores.map(Score::rmse_ms))
            .take(kept)
            .collect(),
    }))
}

#[cfg(test)]
mod tests {
    //! The suite's figures and verdicts on synthetic delay traces whose errors are known.

    use super::*;

    /// A trace every [`TRACE_STEP_US`] from 0 to 60 s, true delay 0.25 s; `error(t)` gives the
    /// estimate's error and its reported sigma at `t`, s.
    fn delay_trace(error: impl Fn(f64) -> (f64, f64)) -> DelayTrace {
        let step_s = TRACE_STEP_US as f64 * 1e-6;
        let mut trace = DelayTrace::default();
        for k in 0..=(RUN_S / step_s).round() as usize {
            let t = k as f64 * step_s;
            let (e, std) = error(t);
            trace.t_s.push(t);
            trace.truth_s.push(0.25);
            trace.estimate_s.push(0.25 + e);
            trace.std_s.push(std);
        }
        trace
    }

    /// An error of 150 ms until `until_s`, 5 ms after (sigma 10 ms).
    fn stepped(until_s: f64) -> DelayTrace {
        delay_trace(|t| (if t < until_s { 0.150 } else { 0.005 }, 0.010))
    }

    fn row(measured: Option<f64>, limit: Limit) -> Row {
        Row {
            name: "synthetic",
            criterion: "synthetic",
            measured,
            limit,
            bound: None,
        }
    }

    #[test]
    fn rmse_is_scored_from_its_start() {
        // 100 ms before 20 s (not scored), 3 ms from it.
        let t = delay_trace(|t| (if t < SCORE_FROM_S { 0.1 } else { -0.003 }, 0.01));
        assert!((t.rmse_from(SCORE_FROM_S) - 0.003).abs() < 1e-12);
        // The median over seeds of 1, 9 and 2 ms.
        let seeds: Vec<DelayTrace> = [0.001, 0.009, 0.002]
            .into_iter()
            .map(|e| delay_trace(move |_| (e, 0.01)))
            .collect();
        let median = median_rmse_ms(&seeds);
        assert!((median - 2.0).abs() < 1e-9, "{median}");
        assert!(row(Some(median), Limit::Max(2.5)).passed());
        assert!(!row(Some(median), Limit::Max(1.5)).passed());
        // An empty window, or one seed without an estimate, fails the row.
        assert!(t.rmse_from(RUN_S + 1.0).is_nan());
        let lost = delay_trace(|t| (if t > 30.0 { f64::NAN } else { 0.001 }, 0.01));
        let median = median_rmse_ms(&[seeds[0].clone(), lost, seeds[2].clone()]);
        assert!(!row(Some(median), Limit::Max(1e9)).passed(), "{median}");
    }

    #[test]
    fn a_step_that_settles_passes_with_its_settle_time() {
        // Last point outside 10 ms: 23.49 s; settled one trace step later, 3.5 s after 20 s.
        let settle = stepped(23.5).settle_after(STEP_AT_S, 0.010);
        assert!((settle - 3.5).abs() < 1e-9, "{settle}");
        assert!(row(Some(settle), Limit::Max(8.0)).passed());
        let late = stepped(28.5).settle_after(STEP_AT_S, 0.010);
        assert!((late - 8.5).abs() < 1e-9 && !row(Some(late), Limit::Max(8.0)).passed());
        assert_eq!(stepped(10.0).settle_after(STEP_AT_S, 0.010), 0.0);
        // Outside by a missing estimate counts as outside.
        let gap = delay_trace(|t| {
            (
                if (t - 30.0).abs() < 1e-6 {
                    f64::NAN
                } else {
                    0.0
                },
                0.01,
            )
        });
        let settle = gap.settle_after(STEP_AT_S, 0.010);
        assert!((settle - 10.01).abs() < 1e-9, "{settle}");
    }

    #[test]
    fn a_step_that_never_settles_fails() {
        let never = stepped(f64::INFINITY).settle_after(STEP_AT_S, 0.010);
        assert_eq!(never, f64::INFINITY);
        assert!(!row(Some(never), Limit::Max(8.0)).passed());
        // Even against an infinite limit: the figure must be finite.
        assert!(!row(Some(never), Limit::Max(f64::INFINITY)).passed());
        // Back within, then out again at the end.
        let relapse = delay_trace(|t| (if (21.0..59.0).contains(&t) { 0.0 } else { 0.15 }, 0.01));
        assert_eq!(relapse.settle_after(STEP_AT_S, 0.010), f64::INFINITY);
        // No estimate at the end; no point after the step at all.
        let lost = delay_trace(|t| (if t > 50.0 { f64::NAN } else { 0.0 }, 0.01));
        assert_eq!(lost.settle_after(STEP_AT_S, 0.010), f64::INFINITY);
        assert_eq!(stepped(0.0).settle_after(RUN_S + 1.0, 0.010), f64::INFINITY);
        // The median over seeds keeps a seed that never settled in order.
        let settles = |xs: &[f64]| median_with_infinity(xs.to_vec());
        assert_eq!(settles(&[2.0, f64::INFINITY, 3.0]), 3.0);
        assert_eq!(settles(&[2.0, f64::INFINITY, f64::INFINITY]), f64::INFINITY);
        assert!(
            !row(
                Some(settles(&[2.0, f64::INFINITY, f64::INFINITY])),
                Limit::Max(8.0)
            )
            .passed()
        );
        assert!(settles(&[2.0, f64::NAN, 3.0]).is_nan());
    }

    #[test]
    fn coverage_counts_the_errors_within_their_sigma() {
        // From 10 s, in turn: 5 ms within a 10 ms sigma, 20 ms outside it, 125 ms on a
        // 125 ms sigma (inside: the bound is inclusive), no sigma (outside). 50 ms and no sigma
        // before 10 s (not counted).
        let t = delay_trace(|t| {
            let k = (t * 100.0).round() as u64;
            match (t < 10.0, k % 4) {
                (true, _) => (0.05, f64::NAN),
                (false, 0) => (0.005, 0.01),
                (false, 1) => (0.02, 0.01),
                (false, 2) => (-0.125, 0.125),
                _ => (0.0, f64::NAN),
            }
        });
        let (inside, total) = t.coverage_from(10.0);
        assert_eq!(total, 5001);
        // k = 1000..=6000: 1251 points with k % 4 == 0, 1250 with k % 4 == 2 (|e| = sigma: inside).
        assert_eq!(inside, 1251 + 1250);
    }

    #[test]
    fn a_row_passes_only_on_a_finite_figure_within_its_limit() {
        assert!(!row(None, Limit::Max(1e9)).passed());
        assert!(!row(Some(f64::NAN), Limit::Max(1e9)).passed());
        assert!(row(Some(6.0), Limit::Max(6.0)).passed());
        assert!(!row(Some(6.001), Limit::Max(6.0)).passed());
        let band = Limit::Band(0.55, 0.80);
        for (x, inside) in [
            (0.55, true),
            (0.8, true),
            (0.7, true),
            (0.549, false),
            (0.81, false),
        ] {
            assert_eq!(row(Some(x), band).passed(), inside, "{x}");
        }
        assert!(!row(Some(f64::NAN), band).passed());
        let json = row(Some(f64::INFINITY), Limit::Max(8.0)).to_json();
        assert_eq!(json["passed"], false);
        assert!(json["measured"].is_null());
        assert_eq!(row(Some(0.6), band).to_json()["limit"], json!([0.55, 0.8]));
    }

    #[test]
    fn the_trace_score_counts_from_twenty_seconds() {
        let mut score = Score::default();
        assert!(score.rmse_ms().is_nan());
        score.add(SCORE_FROM_S - 0.01, 1.0);
        assert!(score.rmse_ms().is_nan());
        score.add(SCORE_FROM_S, 0.003);
        score.add(30.0, -0.004);
        assert!((score.rmse_ms() - 12.5f64.sqrt()).abs() < 1e-9);
    }
}

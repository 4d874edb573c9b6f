//! Reproduces the paper's simulation study (section 3.1, Tables 5 and 6,
//! Figures 5 and 6) on the crate's simulator.
//!
//! Runs scenarios x estimators x seeds, prints the RMSE table with the
//! paper's figures and the noise floor beside ours, the bias table, and
//! writes the JSON results and SVG plots.
//!
//! ```text
//! cargo run --release --features sim --example reproduce              # everything
//! cargo run --release --features sim --example reproduce -- --quick --json out.json
//! cargo run --release --features sim --example reproduce -- --quick --csv target/logs   # CSV logs too
//! ```
//!
//! Every figure is the median over the seeds of one run's RMSE, counted
//! after `skip_s` seconds (the convergence time). Attitude errors are the
//! differences of ZYX Euler angles wrapped to (-180, 180] degrees, and
//! beside them the tilt and heading errors of the attitude error's rotation
//! vector (`sim::tilt_heading_error_rad`, invariant to the vehicle's own
//! attitude); velocity and position errors are the RMS of the 3-D error norm; delay is
//! the RMS of estimate minus true delay; biases are per-axis RMS errors.
//! `us_per_imu_sample` is the time spent inside the estimator's own
//! `push_*` calls divided by the number of IMU samples.
//!
//! Estimators are registered in one place, [`estimators`]: adding a row is
//! one line there.

use clap::{Parser, ValueEnum};
use delaynav::Navigator;
use delaynav::delay::{CalibrationConfig, DefaultCalibrator};
use delaynav::geo::wrap_pi;
use delaynav::nav::{DelayCompensatedNav, DelayMode, NavConfig};
use delaynav::sim::{
    DelayProfile, NoiseFloor, STANDARD_GRAVITY, Scenario, SimConfig, SimEvent, Simulation,
    csv::write_run, delay_bound_s, noise_floor, tilt_heading_error_rad,
};
use delaynav::{Aekf17Config, AugmentedEkf17, Ekf16, Ekf16Config};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Window of GPS fixes over which the delay bound counts information, µs.
const DELAY_BOUND_WINDOW_US: u64 = 5_000_000;
/// Spacing of the points kept for the plots, µs.
const TRACE_STEP_US: u64 = 20_000;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ScenarioChoice {
    Low,
    High,
    All,
}

/// Reproduce the paper's simulation tables on the crate's simulator.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Which acceleration scenario to run.
    #[arg(long, value_enum, default_value = "all")]
    scenario: ScenarioChoice,
    /// Number of seeds per scenario [default: 5, quick: 2].
    #[arg(long)]
    seeds: Option<u64>,
    /// First seed; the run uses seeds S, S+1, ...
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of each run, seconds [default: 60, quick: 20].
    #[arg(long)]
    duration: Option<f64>,
    /// True GPS delay, seconds (constant) [default: 0.2, Table 3's maximum].
    #[arg(long)]
    delay: Option<f64>,
    /// Convergence time not scored, seconds.
    #[arg(long, default_value_t = 10.0)]
    skip: f64,
    /// Where to write the JSON results.
    #[arg(long, default_value = "target/reproduce/results.json")]
    json: PathBuf,
    /// Where to write the SVG plots [default: target/reproduce, none with --quick].
    #[arg(long)]
    plots: Option<PathBuf>,
    /// A short run for CI and tests (2 seeds of 20 s, no plots unless --plots).
    #[arg(long)]
    quick: bool,
    /// Also write each scenario's first-seed run as a CSV log under DIR/<scenario>-seed<S>/.
    #[arg(long, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Start `proposed` and `aekf17` from the fixed 0.1 s instead of an
    /// offline calibration on a separate run (sec. 2.2.2).
    #[arg(long)]
    no_calibration: bool,
}

/// One simulated run, shared by every estimator.
struct RunSetup {
    config: SimConfig,
    events: Vec<SimEvent>,
    skip_us: u64,
    keep_trace: bool,
    /// Where `proposed` and `aekf17` start their delay estimate.
    start: DelayStart,
}

/// The initial delay of the estimators that estimate it.
#[derive(Debug, Clone, Copy)]
struct DelayStart {
    delay_s: f64,
    /// Initial standard deviation, s; `None` keeps each estimator's default.
    std_s: Option<f64>,
}

/// The uncalibrated start: 100 ms below the default true delay.
const UNCALIBRATED_START: DelayStart = DelayStart {
    delay_s: 0.1,
    std_s: None,
};

/// Seed offset of the calibration run of each seed.
const CALIBRATION_SEED_OFFSET: u64 = 10_000;

/// Length of each calibration run, s, whatever the scored run's length (a
/// 20 s record holds too little motion: two of the scenario's strong
/// manoeuvres need 60 s).
const CALIBRATION_DURATION_S: f64 = 60.0;

/// Offline calibration (sec. 2.2.2) on a separate simulated run with the
/// same sensors and true delay: IMU-only attitude, correlation over +-6 s.
/// The initial standard deviation is one correlation grid sample.
fn calibrate(config: &SimConfig) -> DelayStart {
    let cal_config = CalibrationConfig::<f64>::default();
    let mut calibrator =
        Box::new(DefaultCalibrator::<f64>::new(cal_config).expect("valid calibration config"));
    let events: Vec<SimEvent> = Simulation::new(config.clone())
        .expect("valid calibration run")
        .collect();
    let imu = events.iter().filter_map(|e| match e {
        SimEvent::Imu { sample, .. } => Some(*sample),
        _ => None,
    });
    let gps = events.iter().filter_map(|e| match e {
        SimEvent::Gps { fix, .. } => Some(*fix),
        _ => None,
    });
    match calibrator.calibrate(imu, gps) {
        Ok(c) => DelayStart {
            delay_s: c.delay_s.clamp(0.0, 1.0),
            std_s: Some(1.0 / cal_config.correlation_rate_hz),
        },
        Err(_) => UNCALIBRATED_START,
    }
}

/// Time series of one estimator on one run, for the plots.
#[derive(Default)]
struct Trace {
    t_s: Vec<f64>,
    /// Roll, pitch, yaw error, degrees.
    attitude_err_deg: Vec<[f64; 3]>,
    /// Estimated pitch, degrees.
    pitch_deg: Vec<f64>,
    delay_s: Vec<f64>,
}

/// RMS errors and cost of one estimator: of one run, or medians over the
/// seeds of a scenario.
struct Metrics {
    roll_deg: f64,
    pitch_deg: f64,
    yaw_deg: f64,
    /// RMS of the rotation-vector tilt error (`sim::tilt_heading_error_rad`), degrees.
    tilt_deg: f64,
    /// RMS of the rotation-vector heading error, degrees.
    heading_deg: f64,
    vel_m_s: f64,
    pos_m: f64,
    delay_s: Option<f64>,
    gyro_bias_rad_s: [f64; 3],
    accel_bias_g: [f64; 3],
    us_per_imu_sample: f64,
}

/// The scores of one estimator on one run.
struct RunScore {
    metrics: Metrics,
    trace: Trace,
}

/// A registered estimator: its JSON name and how to run it on a setup.
struct Estimator {
    name: &'static str,
    run: fn(&RunSetup) -> RunScore,
}

/// Every estimator of the comparison, in table order. One line each.
fn estimators() -> Vec<Estimator> {
    vec![
        Estimator {
            name: "ekf16",
            run: |s| {
                score(
                    Ekf16::new(ekf16_config(&s.config)).expect("valid Ekf16 config"),
                    s,
                )
            },
        },
        Estimator {
            name: "aekf17",
            run: |s| {
                let mut config = Aekf17Config::with_nav(ekf16_config(&s.config));
                config.initial_delay_s = s.start.delay_s;
                if let Some(std) = s.start.std_s {
                    config.initial_delay_std_s = std;
                }
                score(AugmentedEkf17::new(config).expect("valid Aekf17 config"), s)
            },
        },
        Estimator {
            name: "proposed",
            run: |s| {
                score(
                    nav(
                        &s.config,
                        DelayMode::Estimated {
                            initial_s: s.start.delay_s,
                        },
                        s.start.std_s,
                    ),
                    s,
                )
            },
        },
        Estimator {
            name: "oracle",
            run: |s| {
                score(
                    nav(
                        &s.config,
                        DelayMode::Fixed {
                            delay_s: s.config.delay.initial_s,
                        },
                        None,
                    ),
                    s,
                )
            },
        },
    ]
}

/// The delay-compensated navigator on the same EKF configuration as `ekf16`:
/// `proposed` estimates the delay (initial std `initial_std_s`, else the
/// loop's default), `oracle` is given the true (constant) one.
fn nav(
    sim: &SimConfig,
    mode: DelayMode<f64>,
    initial_std_s: Option<f64>,
) -> DelayCompensatedNav<f64> {
    let mut config = NavConfig {
        ekf: ekf16_config(sim),
        mode,
        imu_rate_hz: sim.sensors.imu_rate_hz,
        ..NavConfig::default()
    };
    if let Some(std) = initial_std_s {
        config.delay_loop.fusion.initial_std_s = std;
    }
    DelayCompensatedNav::new(config).expect("valid navigator config")
}

/// The 16-state EKF configured with the simulator's own noise (Table 3 read
/// per sample at the IMU rate), magnetic field and bias spread (the standard
/// deviation of a uniform draw in `[-max, max]` is `max / sqrt(3)`).
fn ekf16_config(sim: &SimConfig) -> Ekf16Config<f64> {
    let s = &sim.sensors;
    let g2 = STANDARD_GRAVITY * STANDARD_GRAVITY;
    Ekf16Config {
        mag_inclination_rad: s.inclination_rad,
        mag_declination_rad: s.declination_rad,
        mag_noise_variance: s.mag_noise_var,
        gps_horizontal_std_m: s.gps_position_var_m2.sqrt(),
        gps_vertical_std_m: s.gps_position_var_m2.sqrt(),
        gps_velocity_std_m_s: s.gps_velocity_var_m2_s2.sqrt(),
        initial_accel_bias_std_m_s2: (s.accel_bias_max_m_s2() / 3f64.sqrt()).max(1e-3),
        initial_gyro_bias_std_rad_s: (s.gyro_bias_max_rad_s / 3f64.sqrt()).max(1e-4),
        ..Ekf16Config::with_per_sample_imu_variances(
            s.gyro_noise_var_rad2_s2,
            s.accel_noise_var_g2 * g2,
            s.imu_rate_hz,
        )
    }
}

/// Root mean square accumulator.
#[derive(Default, Clone, Copy)]
struct Rms {
    sum_sq: f64,
    n: usize,
}

impl Rms {
    fn add(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }
    fn value(self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}

/// Feeds a run to a navigator, timing only its own calls, and scores its
/// estimate against the truth at every IMU sample after the skip.
fn score<N: Navigator<f64>>(mut nav: N, setup: &RunSetup) -> RunScore {
    let mut euler = [Rms::default(); 3];
    let (mut tilt, mut heading) = (Rms::default(), Rms::default());
    let (mut vel, mut pos, mut delay) = (Rms::default(), Rms::default(), Rms::default());
    let mut gyro_bias = [Rms::default(); 3];
    let mut accel_bias = [Rms::default(); 3];
    let mut has_delay = false;
    let mut missing = 0usize;
    let mut busy = std::time::Duration::ZERO;
    let mut imu_samples = 0usize;
    let mut trace = Trace::default();
    for event in &setup.events {
        let start = Instant::now();
        // Refusals are the estimator's business (it counts them); scoring
        // goes on with whatever estimate it holds.
        match event {
            SimEvent::Imu { sample, .. } => {
                let _ = nav.push_imu(sample);
            }
            SimEvent::Mag(m) => {
                let _ = nav.push_mag(m);
            }
            SimEvent::Gps { fix, .. } => {
                let _ = nav.push_gps(fix);
            }
        }
        busy += start.elapsed();
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        imu_samples += 1;
        if truth.t_us < setup.skip_us && !setup.keep_trace {
            continue;
        }
        let Some(est) = nav.estimate() else {
            if truth.t_us >= setup.skip_us {
                missing += 1;
            }
            continue;
        };
        let e = est.euler_rad();
        let err_deg: [f64; 3] =
            core::array::from_fn(|i| wrap_pi(e[i] - truth.euler_rad[i]).to_degrees());
        let delay_err = est.delay_s.map(|d| d - truth.gps_delay_s);
        if setup.keep_trace && truth.t_us.is_multiple_of(TRACE_STEP_US) {
            trace.t_s.push(truth.t_us as f64 * 1e-6);
            trace.attitude_err_deg.push(err_deg);
            trace.pitch_deg.push(e[1].to_degrees());
            trace.delay_s.push(est.delay_s.unwrap_or(f64::NAN));
        }
        if truth.t_us < setup.skip_us {
            continue;
        }
        let (tilt_rad, heading_rad) = tilt_heading_error_rad(&est.attitude, &truth.attitude);
        tilt.add(tilt_rad.to_degrees());
        heading.add(heading_rad.to_degrees());
        for i in 0..3 {
            euler[i].add(err_deg[i]);
            gyro_bias[i].add(est.gyro_bias_rad_s[i] - truth.gyro_bias_rad_s[i]);
            accel_bias[i]
                .add((est.accel_bias_m_s2[i] - truth.accel_bias_m_s2[i]) / STANDARD_GRAVITY);
        }
        vel.add((est.velocity_ned_m_s - truth.velocity_m_s).norm());
        pos.add((est.position_ned_m - truth.position_m).norm());
        if let Some(d) = delay_err {
            has_delay = true;
            delay.add(d);
        }
    }
    // An estimator without an estimate after the convergence time fails the run.
    let penalty = if missing > 0 { f64::NAN } else { 0.0 };
    let metrics = Metrics {
        roll_deg: euler[0].value() + penalty,
        pitch_deg: euler[1].value() + penalty,
        yaw_deg: euler[2].value() + penalty,
        tilt_deg: tilt.value() + penalty,
        heading_deg: heading.value() + penalty,
        vel_m_s: vel.value() + penalty,
        pos_m: pos.value() + penalty,
        delay_s: has_delay.then(|| delay.value() + penalty),
        gyro_bias_rad_s: gyro_bias.map(|r| r.value() + penalty),
        accel_bias_g: accel_bias.map(|r| r.value() + penalty),
        us_per_imu_sample: busy.as_secs_f64() * 1e6 / imu_samples.max(1) as f64,
    };
    RunScore { metrics, trace }
}

/// Median of finite values; NaN when any is not finite (a failed run shows).
fn median(mut xs: Vec<f64>) -> f64 {
    if xs.is_empty() || xs.iter().any(|x| !x.is_finite()) {
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

/// Medians over the seeds of one estimator's metrics.
fn summarize(runs: &[Metrics]) -> Metrics {
    let m = |f: &dyn Fn(&Metrics) -> f64| median(runs.iter().map(f).collect());
    Metrics {
        roll_deg: m(&|r| r.roll_deg),
        pitch_deg: m(&|r| r.pitch_deg),
        yaw_deg: m(&|r| r.yaw_deg),
        tilt_deg: m(&|r| r.tilt_deg),
        heading_deg: m(&|r| r.heading_deg),
        vel_m_s: m(&|r| r.vel_m_s),
        pos_m: m(&|r| r.pos_m),
        delay_s: runs[0]
            .delay_s
            .is_some()
            .then(|| m(&|r| r.delay_s.unwrap_or(f64::NAN))),
        gyro_bias_rad_s: core::array::from_fn(|i| m(&|r| r.gyro_bias_rad_s[i])),
        accel_bias_g: core::array::from_fn(|i| m(&|r| r.accel_bias_g[i])),
        us_per_imu_sample: m(&|r| r.us_per_imu_sample),
    }
}

/// The paper's Table 6 for a scenario: (proposed, AEKF) per row, in the
/// order pitch, roll, yaw, velocity, position, delay.
fn paper_table6(scenario: Scenario) -> [(f64, f64); 6] {
    match scenario {
        Scenario::Low => [
            (0.059, 0.2237),
            (0.0616, 0.2868),
            (0.181, 0.3116),
            (0.0163, 0.0229),
            (0.381, 0.4462),
            (0.000678, 0.00396),
        ],
        Scenario::High => [
            (0.0878, 1.1467),
            (0.1276, 0.8195),
            (0.1644, 1.0829),
            (0.0192, 0.0425),
            (0.0344, 0.4896),
            (0.000492, 0.00506),
        ],
    }
}

/// The paper's Table 5 (scenario not stated): (EKF without delay handling,
/// proposed) for gyro x, y, z (rad/s) and accelerometer x, y, z (g).
const PAPER_TABLE5: [(f64, f64); 6] = [
    (0.000945, 0.000112),
    (0.000675, 0.000075),
    (0.000130, 0.000080),
    (0.055240, 0.009653),
    (0.057460, 0.006093),
    (0.043000, 0.005345),
];

/// Everything measured in one scenario.
struct ScenarioResult {
    scenario: Scenario,
    true_delay_s: f64,
    delay_bound_s: f64,
    floor_hover: NoiseFloor,
    summaries: Vec<(&'static str, Metrics)>,
    /// First seed's traces per estimator, and the truth's pitch and delay.
    traces: Vec<(&'static str, Trace)>,
    truth_trace: Vec<(f64, f64, f64)>,
    /// Calibrated delay per seed, s (empty with `--no-calibration`).
    calibrated_delays_s: Vec<f64>,
}

impl ScenarioResult {
    /// RMS error of the calibrated delays, s.
    fn calibration_rms_error_s(&self) -> Option<f64> {
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

fn fmt_value(x: f64) -> String {
    if !x.is_finite() {
        "fail".into()
    } else if x == 0.0 {
        "0".into()
    } else if x.abs() >= 0.01 {
        format!("{x:.4}")
    } else {
        format!("{x:.2e}")
    }
}

/// One row of the RMSE table: label, how to read it, the paper's
/// (proposed, AEKF), and the floor column.
type TableRow<'a> = (
    &'a str,
    &'a dyn Fn(&Metrics) -> Option<f64>,
    Option<(f64, f64)>,
    String,
);

fn print_tables(results: &[ScenarioResult], seeds: usize, duration_s: f64, skip_s: f64) -> String {
    let mut out = String::new();
    for r in results {
        let names: Vec<&str> = r.summaries.iter().map(|(n, _)| *n).collect();
        let _ = writeln!(
            out,
            "\n### `{}`: acceleration limit {} m/s², true delay {} s; median over {} seeds of the RMSE after {} s of {} s\n",
            r.scenario.name(),
            r.scenario.accel_limit_m_s2(),
            r.true_delay_s,
            seeds,
            skip_s,
            duration_s
        );
        let start = match r.calibration_rms_error_s() {
            Some(rms) => format!(
                "`proposed` and `aekf17` start from an offline calibration on a separate \
                 {CALIBRATION_DURATION_S} s run (seed + {CALIBRATION_SEED_OFFSET}): {} s per seed, \
                 RMS error {:.2} ms",
                r.calibrated_delays_s
                    .iter()
                    .map(|d| format!("{d:.4}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                rms * 1e3
            ),
            None => format!(
                "`proposed` and `aekf17` start from {} s, uncalibrated",
                UNCALIBRATED_START.delay_s
            ),
        };
        let _ = writeln!(out, "{start}\n");
        let _ = writeln!(
            out,
            "| RMSE | {} | paper proposed | paper AEKF | floor |",
            names.join(" | ")
        );
        let _ = writeln!(out, "|---|{}---|---|---|", "---|".repeat(names.len()));
        let paper = paper_table6(r.scenario);
        let f = &r.floor_hover;
        let rows: [TableRow; 8] = [
            (
                "pitch (deg)",
                &|s| Some(s.pitch_deg),
                Some(paper[0]),
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "roll (deg)",
                &|s| Some(s.roll_deg),
                Some(paper[1]),
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "yaw (deg)",
                &|s| Some(s.yaw_deg),
                Some(paper[2]),
                format!(
                    "{} (mag only)",
                    fmt_value(f.heading_mag_only_rad.to_degrees())
                ),
            ),
            (
                "tilt (deg)",
                &|s| Some(s.tilt_deg),
                None,
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "heading (deg)",
                &|s| Some(s.heading_deg),
                None,
                format!(
                    "{} (mag only)",
                    fmt_value(f.heading_mag_only_rad.to_degrees())
                ),
            ),
            (
                "velocity (m/s)",
                &|s| Some(s.vel_m_s),
                Some(paper[3]),
                fmt_value(f.velocity_norm_m_s),
            ),
            (
                "position (m)",
                &|s| Some(s.pos_m),
                Some(paper[4]),
                fmt_value(f.position_norm_m),
            ),
            (
                "delay (s)",
                &|s| s.delay_s,
                Some(paper[5]),
                format!("{} (bound)", fmt_value(r.delay_bound_s)),
            ),
        ];
        for (label, get, paper, floor) in rows {
            let ours: Vec<String> = r
                .summaries
                .iter()
                .map(|(_, s)| get(s).map_or("-".into(), fmt_value))
                .collect();
            let (p_prop, p_aekf) = paper.map_or(("-".into(), "-".into()), |(p, a)| {
                (fmt_value(p), fmt_value(a))
            });
            let _ = writeln!(
                out,
                "| {label} | {} | {p_prop} | {p_aekf} | {floor} |",
                ours.join(" | "),
            );
        }
        let timing: Vec<String> = r
            .summaries
            .iter()
            .map(|(_, s)| format!("{:.2}", s.us_per_imu_sample))
            .collect();
        let _ = writeln!(out, "| µs per IMU sample | {} | | | |", timing.join(" | "));

        let _ = writeln!(
            out,
            "\nBias RMSE (`{}`; the paper's Table 5 beside, scenario not stated there)\n",
            r.scenario.name()
        );
        let _ = writeln!(
            out,
            "| bias | {} | paper EKF | paper proposed |",
            names.join(" | ")
        );
        let _ = writeln!(out, "|---|{}---|---|", "---|".repeat(names.len()));
        let labels = [
            "gyro x (rad/s)",
            "gyro y (rad/s)",
            "gyro z (rad/s)",
            "accel x (g)",
            "accel y (g)",
            "accel z (g)",
        ];
        for (i, label) in labels.iter().enumerate() {
            let ours: Vec<String> = r
                .summaries
                .iter()
                .map(|(_, s)| {
                    fmt_value(if i < 3 {
                        s.gyro_bias_rad_s[i]
                    } else {
                        s.accel_bias_g[i - 3]
                    })
                })
                .collect();
            let (p_ekf, p_prop) = PAPER_TABLE5[i];
            let _ = writeln!(
                out,
                "| {label} | {} | {} | {} |",
                ours.join(" | "),
                fmt_value(p_ekf),
                fmt_value(p_prop)
            );
        }
    }
    let _ = writeln!(
        out,
        "\nfloor: steady-state error of an ideal filter with this noise at hover (docs/RESULTS.md); \
         delay bound: RMS over the scored fixes of 1/sqrt(sum |a|²/σv²) over the last 5 s of fixes."
    );
    out
}

fn json_number(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

fn to_json(results: &[ScenarioResult], seeds: &[u64], duration_s: f64, skip_s: f64) -> Value {
    let scenarios: Vec<Value> = results
        .iter()
        .map(|r| {
            let mut estimators = serde_json::Map::new();
            for (name, s) in &r.summaries {
                estimators.insert(
                    (*name).into(),
                    json!({
                        "roll_deg": json_number(s.roll_deg),
                        "pitch_deg": json_number(s.pitch_deg),
                        "yaw_deg": json_number(s.yaw_deg),
                        "tilt_deg": json_number(s.tilt_deg),
                        "heading_deg": json_number(s.heading_deg),
                        "vel_m_s": json_number(s.vel_m_s),
                        "pos_m": json_number(s.pos_m),
                        "delay_s": s.delay_s.map_or(Value::Null, json_number),
                        "gyro_bias_rad_s": s.gyro_bias_rad_s.map(json_number),
                        "accel_bias_g": s.accel_bias_g.map(json_number),
                        "us_per_imu_sample": json_number(s.us_per_imu_sample),
                    }),
                );
            }
            let f = &r.floor_hover;
            json!({
                "name": r.scenario.name(),
                "accel_limit_m_s2": r.scenario.accel_limit_m_s2(),
                "true_delay_s": r.true_delay_s,
                "delay_bound_s": json_number(r.delay_bound_s),
                "calibrated_delay_s": r.calibrated_delays_s,
                "calibration_rms_error_s": r.calibration_rms_error_s().map_or(Value::Null, json_number),
                "noise_floor": {
                    "tilt_deg": f.tilt_rad.to_degrees(),
                    "vel_m_s": f.velocity_norm_m_s,
                    "pos_m": f.position_norm_m,
                    "heading_mag_only_deg": f.heading_mag_only_rad.to_degrees(),
                },
                "estimators": estimators,
            })
        })
        .collect();
    json!({
        "duration_s": duration_s,
        "skip_s": skip_s,
        "seeds": seeds,
        "scenarios": scenarios,
    })
}

/// One line of a plot.
struct Series<'a> {
    name: &'a str,
    color: &'static str,
    x: &'a [f64],
    y: Vec<f64>,
}

/// One panel of a stacked plot.
struct Panel<'a> {
    title: String,
    series: Vec<Series<'a>>,
}

/// Line colours: the truth, then the estimators in registry order.
const TRUTH_COLOR: &str = "#000000";
const COLORS: [&str; 5] = ["#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e"];

/// A minimal SVG line plot: stacked panels sharing the time axis.
fn svg_panels(title: &str, panels: &[Panel]) -> String {
    let panels: Vec<&Panel> = panels.iter().filter(|p| !p.series.is_empty()).collect();
    let (width, panel_h, left, top, gap) = (900.0, 200.0, 70.0, 40.0, 50.0);
    let plot_w = width - left - 160.0;
    let height = top + panels.len() as f64 * (panel_h + gap);
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{left}" y="20" font-size="15">{title}</text>"#
    );
    for (p, panel) in panels.iter().enumerate() {
        let y0 = top + p as f64 * (panel_h + gap);
        let points = || {
            panel
                .series
                .iter()
                .flat_map(|s| s.x.iter().zip(&s.y))
                .filter(|(_, y)| y.is_finite())
        };
        let (mut x_min, mut x_max, mut y_min, mut y_max) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (x, y) in points() {
            x_min = x_min.min(*x);
            x_max = x_max.max(*x);
            y_min = y_min.min(*y);
            y_max = y_max.max(*y);
        }
        if x_min >= x_max {
            continue;
        }
        if y_max - y_min < 1e-12 {
            y_min -= 1.0;
            y_max += 1.0;
        }
        let sx = |x: f64| left + (x - x_min) / (x_max - x_min) * plot_w;
        let sy = |y: f64| y0 + panel_h - (y - y_min) / (y_max - y_min) * panel_h;
        let _ = writeln!(
            svg,
            r##"<rect x="{left}" y="{y0}" width="{plot_w}" height="{panel_h}" fill="none" stroke="#888"/>"##
        );
        let _ = writeln!(
            svg,
            r#"<text x="{left}" y="{}">{}</text>"#,
            y0 - 6.0,
            panel.title
        );
        for (value, y) in [(y_max, y0 + 10.0), (y_min, y0 + panel_h)] {
            let _ = writeln!(
                svg,
                r#"<text x="{}" y="{y}" text-anchor="end">{value:.3}</text>"#,
                left - 4.0
            );
        }
        if y_min < 0.0 && y_max > 0.0 {
            let _ = writeln!(
                svg,
                r##"<line x1="{left}" x2="{0}" y1="{1}" y2="{1}" stroke="#ccc"/>"##,
                left + plot_w,
                sy(0.0)
            );
        }
        let _ = writeln!(
            svg,
            r#"<text x="{left}" y="{0}">{x_min:.0} s</text><text x="{1}" y="{0}" text-anchor="end">{x_max:.0} s</text>"#,
            y0 + panel_h + 14.0,
            left + plot_w
        );
        // A tick every 5 s.
        let mut tick = (x_min / 5.0).ceil() * 5.0;
        while tick <= x_max {
            let _ = writeln!(
                svg,
                r##"<line x1="{0}" x2="{0}" y1="{1}" y2="{2}" stroke="#888"/>"##,
                sx(tick),
                y0 + panel_h,
                y0 + panel_h + 5.0
            );
            tick += 5.0;
        }
        for (i, s) in panel.series.iter().enumerate() {
            let color = s.color;
            let mut d = String::new();
            let mut pen_down = false;
            for (x, y) in s.x.iter().zip(&s.y) {
                if y.is_finite() {
                    let _ = write!(
                        d,
                        "{}{:.1},{:.1} ",
                        if pen_down { "L" } else { "M" },
                        sx(*x),
                        sy(*y)
                    );
                    pen_down = true;
                } else {
                    pen_down = false;
                }
            }
            let _ = writeln!(
                svg,
                r#"<path d="{d}" fill="none" stroke="{color}" stroke-width="1"/>"#
            );
            let _ = writeln!(
                svg,
                r#"<text x="{}" y="{}" fill="{color}">{}</text>"#,
                left + plot_w + 10.0,
                y0 + 14.0 + 16.0 * i as f64,
                s.name
            );
        }
    }
    svg.push_str("</svg>\n");
    svg
}

/// Figures 5 and 6: true and estimated pitch, attitude errors, delay estimate.
fn write_plots(dir: &Path, r: &ScenarioResult) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let truth_t: Vec<f64> = r.truth_trace.iter().map(|p| p.0).collect();
    let mut pitch = Panel {
        title: "pitch (deg): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.1).collect(),
        }],
    };
    let mut errors: Vec<Panel> = ["roll", "pitch", "yaw"]
        .iter()
        .map(|axis| Panel {
            title: format!("{axis} error (deg)"),
            series: Vec::new(),
        })
        .collect();
    let mut delay = Panel {
        title: "GPS delay (s): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.2).collect(),
        }],
    };
    for (k, (name, trace)) in r.traces.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        pitch.series.push(Series {
            name,
            color,
            x: &trace.t_s,
            y: trace.pitch_deg.clone(),
        });
        for (axis, panel) in errors.iter_mut().enumerate() {
            panel.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.attitude_err_deg.iter().map(|e| e[axis]).collect(),
            });
        }
        if trace.delay_s.iter().any(|d| d.is_finite()) {
            delay.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.delay_s.clone(),
            });
        }
    }
    let name = r.scenario.name();
    let attitude_path = dir.join(format!("{name}-attitude.svg"));
    let mut panels = vec![pitch];
    panels.extend(errors);
    let title = format!("scenario {name}: attitude (first seed)");
    std::fs::write(&attitude_path, svg_panels(&title, &panels))?;
    let delay_path = dir.join(format!("{name}-delay.svg"));
    let title = format!("scenario {name}: GPS delay (first seed)");
    std::fs::write(&delay_path, svg_panels(&title, &[delay]))?;
    Ok(vec![attitude_path, delay_path])
}

/// The simulation of one scenario and seed with the run's options.
fn sim_config(scenario: Scenario, seed: u64, duration_s: f64, delay_s: Option<f64>) -> SimConfig {
    let mut config = SimConfig {
        duration_s,
        ..SimConfig::for_scenario(scenario, seed)
    };
    if let Some(d) = delay_s {
        config.delay = DelayProfile::constant(d);
    }
    config
}

fn run_scenario(
    scenario: Scenario,
    seeds: &[u64],
    options: &RunOptions,
    progress: &mut Progress,
) -> ScenarioResult {
    let RunOptions {
        delay_s,
        duration_s,
        skip_s,
        keep_trace,
        calibrated,
    } = *options;
    let mut calibrated_delays_s = Vec::new();
    let registry = estimators();
    let mut scores: Vec<Vec<Metrics>> = registry.iter().map(|_| Vec::new()).collect();
    let mut bounds = Vec::new();
    let mut traces = Vec::new();
    let mut truth_trace = Vec::new();
    let mut floor_hover = None;
    let mut true_delay_s = 0.0;
    for (k, &seed) in seeds.iter().enumerate() {
        let config = sim_config(scenario, seed, duration_s, delay_s);
        true_delay_s = config.delay.initial_s;
        floor_hover.get_or_insert_with(|| noise_floor(&config.sensors, STANDARD_GRAVITY));
        let events: Vec<SimEvent> = Simulation::new(config.clone())
            .expect("valid simulation config")
            .collect();
        let skip_us = (skip_s * 1e6).round() as u64;
        let fixes: Vec<(u64, nalgebra::Vector3<f64>)> = events
            .iter()
            .filter_map(|e| match e {
                SimEvent::Gps {
                    fix,
                    truth_at_validity,
                    ..
                } => Some((fix.t_us, truth_at_validity.accel_m_s2)),
                _ => None,
            })
            .collect();
        bounds.push(
            delay_bound_s(
                &fixes,
                config.sensors.gps_velocity_var_m2_s2,
                DELAY_BOUND_WINDOW_US,
                skip_us,
            )
            .unwrap_or(f64::NAN),
        );
        let first = k == 0 && keep_trace;
        if first {
            truth_trace = events
                .iter()
                .filter_map(|e| match e {
                    SimEvent::Imu { truth, .. } if truth.t_us.is_multiple_of(TRACE_STEP_US) => {
                        Some((
                            truth.t_us as f64 * 1e-6,
                            truth.euler_rad.y.to_degrees(),
                            truth.gps_delay_s,
                        ))
                    }
                    _ => None,
                })
                .collect();
        }
        let start = if calibrated {
            let mut cal = config.clone();
            cal.seed = seed + CALIBRATION_SEED_OFFSET;
            cal.duration_s = CALIBRATION_DURATION_S;
            let start = calibrate(&cal);
            calibrated_delays_s.push(start.delay_s);
            start
        } else {
            UNCALIBRATED_START
        };
        let setup = RunSetup {
            config,
            events,
            skip_us,
            keep_trace: first,
            start,
        };
        for (i, estimator) in registry.iter().enumerate() {
            let started = Instant::now();
            let s = (estimator.run)(&setup);
            progress.step(
                scenario.name(),
                seed,
                estimator.name,
                started.elapsed().as_secs_f64(),
            );
            if first {
                traces.push((estimator.name, s.trace));
            }
            scores[i].push(s.metrics);
        }
    }
    ScenarioResult {
        scenario,
        true_delay_s,
        delay_bound_s: median(bounds),
        floor_hover: floor_hover.expect("at least one seed"),
        summaries: registry
            .iter()
            .zip(&scores)
            .map(|(e, s)| (e.name, summarize(s)))
            .collect(),
        traces,
        truth_trace,
        calibrated_delays_s,
    }
}

/// The options shared by every scenario of a run.
struct RunOptions {
    /// True delay, s, when not the scenario's default.
    delay_s: Option<f64>,
    duration_s: f64,
    skip_s: f64,
    keep_trace: bool,
    /// Start the delay estimators from an offline calibration.
    calibrated: bool,
}

/// Progress on stderr: one line per estimator run.
struct Progress {
    done: usize,
    total: usize,
    started: Instant,
}

impl Progress {
    fn step(&mut self, scenario: &str, seed: u64, estimator: &str, seconds: f64) {
        self.done += 1;
        eprintln!(
            "[{}/{}] {scenario} seed {seed} {estimator}: {seconds:.1} s (elapsed {:.0} s)",
            self.done,
            self.total,
            self.started.elapsed().as_secs_f64()
        );
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let seeds_n = args.seeds.unwrap_or(if args.quick { 2 } else { 5 });
    let duration_s = args
        .duration
        .unwrap_or(if args.quick { 20.0 } else { 60.0 });
    if seeds_n == 0 {
        return Err("--seeds must be at least 1".into());
    }
    if !(args.skip >= 0.0 && duration_s > args.skip) {
        return Err(format!(
            "--duration ({duration_s} s) must exceed the convergence time ({} s)",
            args.skip
        )
        .into());
    }
    let plots = match (&args.plots, args.quick) {
        (Some(dir), _) => Some(dir.clone()),
        (None, false) => Some(PathBuf::from("target/reproduce")),
        (None, true) => None,
    };
    let scenarios: Vec<Scenario> = match args.scenario {
        ScenarioChoice::Low => vec![Scenario::Low],
        ScenarioChoice::High => vec![Scenario::High],
        ScenarioChoice::All => Scenario::ALL.to_vec(),
    };
    let seeds: Vec<u64> = (args.seed..args.seed + seeds_n).collect();
    let mut progress = Progress {
        done: 0,
        total: scenarios.len() * seeds.len() * estimators().len(),
        started: Instant::now(),
    };
    if let Some(dir) = &args.csv {
        for &scenario in &scenarios {
            let config = sim_config(scenario, seeds[0], duration_s, args.delay);
            let path = dir.join(format!("{}-seed{}", scenario.name(), seeds[0]));
            let n = write_run(&path, Simulation::new(config)?)?;
            eprintln!("wrote {n} events to {}", path.display());
        }
    }
    let options = RunOptions {
        delay_s: args.delay,
        duration_s,
        skip_s: args.skip,
        keep_trace: plots.is_some(),
        calibrated: !args.no_calibration,
    };
    let results: Vec<ScenarioResult> = scenarios
        .iter()
        .map(|&s| run_scenario(s, &seeds, &options, &mut progress))
        .collect();
    print!(
        "{}",
        print_tables(&results, seeds.len(), duration_s, args.skip)
    );
    if let Some(parent) = args.json.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let json = to_json(&results, &seeds, duration_s, args.skip);
    std::fs::write(&args.json, serde_json::to_string_pretty(&json)? + "\n")?;
    eprintln!("wrote {}", args.json.display());
    if let Some(dir) = plots {
        for r in &results {
            for path in write_plots(&dir, r)? {
                eprintln!("wrote {}", path.display());
            }
        }
    }
    Ok(())
}

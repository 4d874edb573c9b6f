//! One row's run on one seed, per second as CSV: what a delay figure is made of.

use super::rows::{
    Tuned, aekf17_hover, beyond_three_sigma, events, feed, proposed, row_events, row_run,
    run_information_bound_s, trace_point,
};
use super::{LoopTuning, SCORE_FROM_S};
use crate::delay::{DefaultDelayLoop, DelayStatus};
use crate::nav::{DelayCompensatedNav, DelayMode};
use crate::sim::suite::SuiteError;
use crate::sim::suite::setup::nav;
use crate::sim::{STANDARD_GRAVITY, SimConfig, SimEvent};
use crate::{Error, Navigator};
use nalgebra::Vector3;
use std::io::Write;

/// Spacing of the rows of the traces, us.
const CSV_STEP_US: u64 = 1_000_000;

/// Names of the loop's axes, in `DelayUpdate::axes` order.
const AXIS_NAMES: [&str; 3] = ["north", "east", "down"];

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

/// Runs AEKF17 on the `aekf17_hover` row's run of `seed`, changed by
/// `setup`, and writes every second the true delay, the estimate, its
/// sigma, |error| / sigma and the clamp count as CSV to `out`. An error when the filter or
/// the simulation refuses `setup`, or writing fails.
pub fn write_hover_trace(
    seed: u64,
    setup: &HoverSetup,
    out: &mut impl Write,
) -> Result<HoverSummary, SuiteError> {
    let refused = |field: &'static str| {
        SuiteError::config(
            "aekf17_hover",
            Error::InvalidConfig {
                field: field.into(),
                value: None,
                bound: crate::error::Bound::Rule("refused by the filter or the simulation"),
            },
        )
    };
    let (config, mut aekf) = aekf17_hover(seed, setup).ok_or_else(|| refused("hover setup"))?;
    let events = events(&config).ok_or_else(|| refused("duration_s"))?;
    writeln!(out, "t_s,truth_s,estimate_s,sigma_s,ratio,clamps")?;
    let mut summary = HoverSummary {
        rows: 0,
        estimate_s: f64::NAN,
        sigma_s: f64::NAN,
        ratio: f64::NAN,
        clamps: 0,
    };
    for event in &events {
        feed(&mut aekf, event);
        let Some(truth) = trace_point(event) else {
            continue;
        };
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

/// What [`write_trace`] traces.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceOptions {
    /// The row ([`TRACE_ROWS`](super::TRACE_ROWS) or [`EXTRA_TRACES`](super::EXTRA_TRACES)).
    pub row: String,
    /// The seed [default: 1].
    pub seed: u64,
    /// Changes to the delay loop's defaults.
    pub tuning: LoopTuning,
    /// Two more delay loops beside the navigator's, fed the oracle navigator's acceleration
    /// and the true acceleration plus the accelerometer's noise.
    pub compare_accel: bool,
    /// Prediction rate of the navigator's horizon filter, Hz (`None`: its default).
    pub filter_rate_hz: Option<f64>,
}

impl Default for TraceOptions {
    fn default() -> Self {
        Self {
            row: "cold_start_high".into(),
            seed: 1,
            tuning: LoopTuning::default(),
            compare_accel: false,
            filter_rate_hz: None,
        }
    }
}

/// What [`write_trace`] wrote and measured.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceSummary {
    /// CSV rows written (one a second).
    pub rows: usize,
    /// Delay RMSE from 20 s at the suite's 10 ms spacing, ms, per estimate:
    /// `navigator` (as the suite scores it), and with `compare_accel` `oracle_accel`
    /// and `true_accel`.
    pub rmse_ms: Vec<(&'static str, f64)>,
    /// The row's information bound on this run ([`information_bound_ms`](super::information_bound_ms)
    /// on one seed), RMS from 20 s, ms.
    pub information_bound_ms: f64,
    /// Fraction of the navigator's points from 20 s (10 ms spacing) whose
    /// error is within its reported 1-sigma.
    pub sigma_coverage: f64,
    /// The navigator's points (10 ms spacing, from the start) with `delay_valid` whose
    /// health delay is more than 3 sigma from the truth, and the points with
    /// `delay_valid`: this run's share of the suite's `valid_means_close`.
    pub valid_but_far: (usize, usize),
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
    fn new(
        config: &SimConfig,
        nav_: &DelayCompensatedNav<f64>,
        filter_rate_hz: Option<f64>,
    ) -> Option<Self> {
        let mode = DelayMode::Fixed {
            delay_s: config.delay.initial_s,
        };
        let loop_config = *nav_.delay_loop().config();
        Some(Self {
            oracle: nav(config, mode, None, filter_rate_hz).ok()?,
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

/// The CSV header of [`write_trace`].
fn write_header(out: &mut impl Write, compare: bool) -> std::io::Result<()> {
    write!(
        out,
        "t_s,truth_s,estimate_s,sigma_s,error_ms,rate_ms_per_s,status,delay_valid,gfa_std_s,innovation_estimate_s,innovation_std_s,update_t_s"
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
    writeln!(out)
}

/// One CSV row of [`write_trace`] (after the time, truth and estimate).
fn write_loop_state(
    out: &mut impl Write,
    nav: &DelayCompensatedNav<f64>,
    group_delay_s: f64,
    truth_s: f64,
) -> std::io::Result<()> {
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
    Ok(())
}

/// Runs the `proposed` navigator of the row `options.row` on `options.seed` and writes, every
/// second, the true delay, the navigator's estimate and sigma, the loop's drift-rate estimate
/// and status, `Health::delay_valid`, the gain fusion's own sigma, the last innovation window
/// (estimate and std, when the observation is on), and the last delay update's axes (valid flag, window peak, peak
/// correlation, IMU acceleration variance over the buffer) as CSV to `out`. Delays are
/// relative to the raw IMU (the loop's values plus the accelerometer whitening's group delay),
/// as the suite scores them. With `compare_accel`, two more loops fed other accelerations add
/// their estimates. `Ok(None)` when the row has no navigator trace or the navigator refuses
/// its setup.
pub fn write_trace(
    options: &TraceOptions,
    out: &mut impl Write,
) -> Result<Option<TraceSummary>, SuiteError> {
    let name = options.row.as_str();
    let compare = options.compare_accel;
    let tuned = Tuned {
        tuning: options.tuning,
        filter_rate_hz: options.filter_rate_hz,
    };
    let Some((config, setup)) = row_run(name, options.seed) else {
        return Ok(None);
    };
    let (Some(mut nav), Some(events)) =
        (proposed(&config, setup, tuned), row_events(&config, setup))
    else {
        return Ok(None);
    };
    let mut comparison = None;
    if compare {
        let Some(c) = Comparison::new(&config, &nav, options.filter_rate_hz) else {
            return Ok(None);
        };
        comparison = Some(c);
    }
    let (group_delay_s, _) = nav.group_delays_s();
    write_header(out, compare)?;
    let mut rows = 0;
    let mut scores = [Score::default(); 3];
    let mut covered = (0usize, 0usize);
    let mut valid_but_far = (0usize, 0usize);
    for event in &events {
        feed(&mut nav, event);
        if let Some(c) = &mut comparison {
            c.feed(event);
        }
        let Some(truth) = trace_point(event) else {
            continue;
        };
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
        let health = nav.health();
        if health.delay_valid {
            let far = beyond_three_sigma(health.delay.delay_s, health.delay.delay_std_s, truth_s);
            valid_but_far.0 += usize::from(far);
            valid_but_far.1 += 1;
        }
        for (score, other) in scores[1..].iter_mut().zip(others.iter().flatten()) {
            score.add(t_s, other - truth_s);
        }
        if !truth.t_us.is_multiple_of(CSV_STEP_US) {
            continue;
        }
        write!(
            out,
            "{t_s:.1},{truth_s:.6},{estimate_s:.6},{:.6},{:.3},{:.4},{},{}",
            nav.delay_std_s(),
            (estimate_s - truth_s) * 1e3,
            nav.delay_loop().delay_rate() * 1e3,
            status_name(nav.delay_loop().status()),
            u8::from(health.delay_valid),
        )?;
        write_loop_state(out, &nav, group_delay_s, truth_s)?;
        if let Some([oracle_s, true_s]) = others {
            write!(out, ",{oracle_s:.6},{true_s:.6}")?;
        }
        writeln!(out)?;
        rows += 1;
    }
    let names = ["navigator", "oracle_accel", "true_accel"];
    let kept = if compare { 3 } else { 1 };
    let information_bound_ms =
        run_information_bound_s(name, &config, &events).map_or(f64::NAN, |s| s * 1e3);
    Ok(Some(TraceSummary {
        information_bound_ms,
        sigma_coverage: covered.0 as f64 / covered.1.max(1) as f64,
        valid_but_far,
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
    use super::*;

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

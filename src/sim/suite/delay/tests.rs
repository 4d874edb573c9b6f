//! The suite's figures and verdicts on synthetic delay traces whose errors are known.

use super::rows::{DelayTrace, STEP_AT_S, TRACE_STEP_US, median_rmse_ms};
use super::{Limit, RUN_S, Row, SCORE_FROM_S};
use crate::sim::suite::stats::median_with_infinity;
use serde_json::json;

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
fn valid_but_far_judges_the_delay_the_health_vouches_for() {
    use super::rows::PointHealth;
    // The navigator's estimate has no delay (NaN) before 1 s; its health has one all along:
    // 10 ms off with a 5 ms sigma (within 3 sigma) before 30 s, 20 ms off after (beyond).
    // Valid from 0.5 s to 40 s.
    let mut t = delay_trace(|t| (if t < 1.0 { f64::NAN } else { 0.0 }, 0.005));
    t.health = t
        .t_s
        .iter()
        .map(|&s| PointHealth {
            valid: (0.5..40.0).contains(&s),
            delay_s: 0.25 + if s < 30.0 { 0.01 } else { 0.02 },
            std_s: 0.005,
            ..PointHealth::default()
        })
        .collect();
    let (far, valid) = t.valid_but_far();
    assert_eq!(valid, 3950);
    assert_eq!(far, 1000);
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
fn the_row_line_says_pass_fail_and_the_bound() {
    let passing = Row {
        bound: Some(1.234),
        ..row(Some(2.0), Limit::Max(6.0))
    };
    assert_eq!(
        passing.to_string(),
        "synthetic              PASS   measured     2.0000 limit Max(6.0) (information bound 1.23, ratio 1.621)"
    );
    assert_eq!(
        row(None, Limit::Band(0.55, 0.8)).to_string(),
        "synthetic              FAIL   measured       null limit Band(0.55, 0.8)"
    );
}

#[test]
fn a_row_with_a_bound_is_judged_on_its_ratio() {
    let bounded = |measured: Option<f64>, bound: f64| Row {
        bound: Some(bound),
        ..row(measured, Limit::Max(2.0))
    };
    // 9 ms against a 5 ms bound: 1.8x, within 2 (the 9 ms itself is not judged).
    let near = bounded(Some(9.0), 5.0);
    assert_eq!(near.ratio(), Some(1.8));
    assert!(near.passed());
    let far = bounded(Some(10.5), 5.0);
    assert!(!far.passed());
    let json = far.to_json();
    assert_eq!(json["measured"], 10.5);
    assert_eq!(json["bound"], 5.0);
    assert_eq!(json["ratio"], 2.1);
    assert_eq!(json["limit"], 2.0);
    // No figure: no ratio, a failure; a row without a bound has a null bound and ratio.
    assert!(!bounded(None, 5.0).passed() && bounded(None, 5.0).ratio().is_none());
    let absolute = row(Some(1.5), Limit::Max(2.0)).to_json();
    assert!(absolute["bound"].is_null() && absolute["ratio"].is_null());
    assert_eq!(absolute["passed"], true);
}

#[test]
fn unknown_rows_and_no_seeds_are_refused() {
    use super::{DelayOptions, run};
    use crate::sim::suite::{SuiteError, no_progress};
    let unknown = DelayOptions {
        rows: Some(vec!["cold_start".into()]),
        ..DelayOptions::default()
    };
    let refused = run(&unknown, &no_progress);
    assert!(
        matches!(&refused, Err(SuiteError::UnknownRow { name, known })
            if name == "cold_start" && known.contains("cold_start_low")),
        "{refused:?}"
    );
    let none = DelayOptions {
        seeds: Vec::new(),
        ..DelayOptions::default()
    };
    assert!(matches!(
        run(&none, &no_progress),
        Err(SuiteError::InvalidOption {
            option: "seeds",
            ..
        })
    ));
}

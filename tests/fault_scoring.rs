//! fault_scoring: the fault suite's figures and verdicts (`sim::faults::evaluate`) on synthetic
//! traces whose errors are known: a fault that recovers passes with its settle time, one that
//! never recovers fails whatever is left of the run, the magnetic row fails on its tilt bound
//! alone, and an empty window or a missing estimate fails instead of passing.
#![cfg(feature = "sim")]

use delaynav::sim::faults::{
    FaultCase, FaultResult, Metric, OnTimeBackwards, Reference, TracePoint, base_config, evaluate,
};

/// Trace points every 0.1 s from 0 to `end_s` (inclusive), the vehicle moving 1 m north per
/// sample; `errors(t)` gives the tilt, heading (deg) and north position error (m) at `t`.
fn trace(end_s: f64, errors: impl Fn(f64) -> (f64, f64, f64)) -> Vec<TracePoint> {
    let samples = (end_s * 10.0).round() as usize;
    (0..=samples)
        .map(|k| {
            let t_s = k as f64 / 10.0;
            let (tilt_deg, heading_deg, north_m) = errors(t_s);
            let truth_ne_m = [k as f64, -3.0];
            TracePoint {
                t_s,
                tilt_deg,
                heading_deg,
                estimate_ne_m: [truth_ne_m[0] + north_m, truth_ne_m[1]],
                truth_ne_m,
            }
        })
        .collect()
}

/// A row measuring `metric` against `limit`.
fn case(metric: Metric, limit: f64) -> FaultCase {
    FaultCase {
        name: "synthetic",
        criterion: "synthetic",
        limit,
        sim: base_config(1, 1.0),
        faults: Vec::new(),
        on_backwards: OnTimeBackwards::Ignore,
        metric,
        reference: Reference::None,
    }
}

fn score(metric: Metric, limit: f64, trace: &[TracePoint]) -> FaultResult {
    evaluate(&case(metric, limit), trace, None)
}

/// The gps_outage row's figure: GPS back at 50 s, error bound 5 m.
const SETTLE: Metric = Metric::SettleHorizontal {
    from_s: 50.0,
    threshold_m: 5.0,
    offset_ne_m: [0.0; 2],
};

/// A position error of 20 m until `until_s`, 1 m after.
fn recovering(until_s: f64) -> impl Fn(f64) -> (f64, f64, f64) {
    move |t| (0.5, 0.5, if t < until_s { 20.0 } else { 1.0 })
}

#[test]
fn a_fault_that_recovers_passes_with_its_settle_time() {
    // Last sample outside the bound: 52.9 s, 2.9 s after the return.
    let result = score(SETTLE, 5.0, &trace(60.0, recovering(53.0)));
    assert!((result.measured - 2.9).abs() < 1e-9, "{result:?}");
    assert!(result.passed);
    // Settled before the window: 0 s.
    let early = score(SETTLE, 5.0, &trace(60.0, recovering(40.0)));
    assert_eq!((early.measured, early.passed), (0.0, true));
    // Settled too late: 7.9 s against 5.
    let late = score(SETTLE, 5.0, &trace(60.0, recovering(58.0)));
    assert!(
        (late.measured - 7.9).abs() < 1e-9 && !late.passed,
        "{late:?}"
    );
    // The offset: the estimate should follow a truth moved 50 m north.
    let step = Metric::SettleHorizontal {
        from_s: 30.0,
        threshold_m: 5.0,
        offset_ne_m: [50.0, 0.0],
    };
    let followed = score(
        step,
        10.0,
        &trace(60.0, |t| (0.5, 0.5, (t - 34.0).clamp(0.0, 50.0))),
    );
    // A ramp that would reach +50 m only at 84 s: never within 5 m of it in the run.
    assert_eq!(followed.measured, f64::INFINITY);
    assert!(!followed.passed);
    let followed = score(
        step,
        10.0,
        &trace(60.0, |t| (0.5, 0.5, if t < 34.0 { 0.0 } else { 50.0 })),
    );
    assert!(
        (followed.measured - 3.9).abs() < 1e-9 && followed.passed,
        "{followed:?}"
    );
}

#[test]
fn a_fault_that_never_recovers_fails_whatever_is_left_of_the_run() {
    // Outside the bound to the end of a 60 s run: never settled.
    let never = score(SETTLE, 5.0, &trace(60.0, recovering(f64::INFINITY)));
    assert_eq!(never.measured, f64::INFINITY);
    assert!(!never.passed);
    // The same with less of the run left after the return than the limit (3 s of 5): still a
    // failure, not "3 s".
    let short = score(SETTLE, 5.0, &trace(53.0, recovering(f64::INFINITY)));
    assert_eq!(short.measured, f64::INFINITY);
    assert!(!short.passed);
    // Back inside, then out again at the end: not settled either.
    let relapse = score(
        SETTLE,
        5.0,
        &trace(60.0, |t| {
            (0.5, 0.5, if (51.0..59.0).contains(&t) { 1.0 } else { 20.0 })
        }),
    );
    assert_eq!(relapse.measured, f64::INFINITY);
    assert!(!relapse.passed);
    // The other figures of a fault that never recovers.
    let max = score(
        Metric::MaxHorizontal { from_s: 30.0 },
        3.0,
        &trace(60.0, recovering(f64::INFINITY)),
    );
    assert!((max.measured - 20.0).abs() < 1e-9 && !max.passed, "{max:?}");
}

#[test]
fn a_missing_estimate_fails() {
    let without = |from: f64| {
        move |t: f64| {
            if t >= from {
                (f64::NAN, f64::NAN, f64::NAN)
            } else {
                (0.5, 0.5, 1.0)
            }
        }
    };
    // Lost at 55 s and never back.
    let settle = score(SETTLE, 5.0, &trace(60.0, without(55.0)));
    assert!(!settle.passed, "{settle:?}");
    // Position lost for the one sample at `at` (1 m error otherwise).
    let lost_at = |at: f64| {
        trace(60.0, move |t| {
            let north = if (t - at).abs() < 0.05 { f64::NAN } else { 1.0 };
            (0.5, 0.5, north)
        })
    };
    // Lost for one sample in the middle of a settle window counts as outside the bound.
    let gap = score(SETTLE, 5.0, &lost_at(56.0));
    assert!((gap.measured - 6.0).abs() < 1e-9 && !gap.passed, "{gap:?}");
    // One missing sample makes a maximum unknown, not smaller.
    let max = score(Metric::MaxHorizontal { from_s: 30.0 }, 3.0, &lost_at(45.0));
    assert!(max.measured.is_nan() && !max.passed, "{max:?}");
    for metric in [
        Metric::HorizontalAt { t_s: 57.0 },
        Metric::TiltAt { t_s: 57.0 },
        Metric::MaxHeading {
            from_s: 30.0,
            max_tilt_deg: 2.0,
        },
    ] {
        let result = score(metric, 1e9, &trace(60.0, without(55.0)));
        assert!(result.measured.is_nan() && !result.passed, "{result:?}");
    }
}

#[test]
fn an_empty_window_fails() {
    // Every window starts after the last sample (a 40 s run scored from 50 s).
    let short = trace(40.0, |_| (0.5, 0.5, 1.0));
    let metrics = [
        SETTLE,
        Metric::MaxHorizontal { from_s: 50.0 },
        Metric::HorizontalAt { t_s: 50.0 },
        Metric::TiltRmseRatio { from_s: 50.0 },
        Metric::HeadingRmseRatio { from_s: 50.0 },
        Metric::MaxHeading {
            from_s: 50.0,
            max_tilt_deg: 2.0,
        },
        Metric::TiltAt { t_s: 50.0 },
    ];
    for metric in metrics {
        let result = evaluate(&case(metric, 1e9), &short, Some(&short));
        assert!(result.measured.is_nan() && !result.passed, "{result:?}");
        // No trace at all.
        let none = evaluate(&case(metric, 1e9), &[], Some(&short));
        assert!(none.measured.is_nan() && !none.passed, "{none:?}");
    }
}

/// The magnetic row: largest heading error from 30 s, limit 5 deg, tilt at most 2 deg.
const MAG: Metric = Metric::MaxHeading {
    from_s: 30.0,
    max_tilt_deg: 2.0,
};

#[test]
fn the_magnetic_row_fails_on_its_tilt_bound_alone() {
    // Heading error 1 deg (limit 5); one tilt error of `peak` at 45 s; 9 deg before 30 s
    // (outside the window).
    let with_tilt = |peak: f64| {
        trace(60.0, move |t| {
            let tilt = if t < 30.0 {
                9.0
            } else if (t - 45.0).abs() < 0.05 {
                peak
            } else {
                0.5
            };
            (tilt, if t < 30.0 { 40.0 } else { 1.0 }, 0.0)
        })
    };
    let tilted = score(MAG, 5.0, &with_tilt(2.5));
    assert_eq!(tilted.measured, 1.0);
    assert_eq!(tilted.note, Some(("max_tilt_deg", 2.5)));
    assert!(
        !tilted.passed,
        "heading within 5 deg, tilt 2.5 > 2 deg: {tilted:?}"
    );
    let level = score(MAG, 5.0, &with_tilt(1.9));
    assert_eq!(level.note, Some(("max_tilt_deg", 1.9)));
    assert!(level.passed, "{level:?}");
    // The bound is inclusive, as the limit.
    assert!(score(MAG, 5.0, &with_tilt(2.0)).passed);
    let unknown = score(MAG, 5.0, &with_tilt(f64::NAN));
    assert!(unknown.note.is_some_and(|(_, t)| t.is_nan()) && !unknown.passed);
    // And the heading error fails it alone too.
    let turned = score(MAG, 0.9, &with_tilt(1.9));
    assert!(!turned.passed);
}

/// A 60 s trace with the errors `before` until `switch_s`, `after` from it.
fn two_phases(switch_s: f64, before: (f64, f64, f64), after: (f64, f64, f64)) -> Vec<TracePoint> {
    trace(60.0, |t| if t < switch_s { before } else { after })
}

#[test]
fn ratio_rows_divide_by_the_reference_over_the_same_window() {
    // Ours: tilt 1.5, heading 3 deg from 10 s (50 deg before, outside the window); the
    // reference: tilt 1, heading 1.5 deg (0 before).
    let ours = two_phases(10.0, (50.0, 50.0, 0.0), (1.5, 3.0, 0.0));
    let clean = two_phases(10.0, (0.0, 0.0, 0.0), (1.0, 1.5, 0.0));
    let tilt = |limit| {
        let mut c = case(Metric::TiltRmseRatio { from_s: 10.0 }, limit);
        c.reference = Reference::Clean;
        evaluate(&c, &ours, Some(&clean))
    };
    assert!((tilt(1.2).measured - 1.5).abs() < 1e-12);
    assert!(!tilt(1.2).passed && tilt(1.5).passed);
    let heading = evaluate(
        &case(Metric::HeadingRmseRatio { from_s: 10.0 }, 1.2),
        &ours,
        Some(&clean),
    );
    assert!((heading.measured - 2.0).abs() < 1e-12 && !heading.passed);
    // An RMS, not a mean: tilt 1 deg over 250 samples, 3 deg over 251, over a reference of 1.
    let mixed = two_phases(35.0, (1.0, 0.0, 0.0), (3.0, 0.0, 0.0));
    let from_ten = two_phases(10.0, (f64::NAN, 0.0, 0.0), (1.0, 0.0, 0.0));
    let rms = evaluate(
        &case(Metric::TiltRmseRatio { from_s: 10.0 }, 10.0),
        &mixed,
        Some(&from_ten),
    );
    let expected = ((250.0 + 9.0 * 251.0) / 501.0f64).sqrt();
    assert!((rms.measured - expected).abs() < 1e-12, "{rms:?}");
    // Without a reference run, or one with no error at all, the ratio fails.
    let alone = evaluate(
        &case(Metric::TiltRmseRatio { from_s: 10.0 }, 1e9),
        &ours,
        None,
    );
    assert!(alone.measured.is_nan() && !alone.passed);
    let perfect = trace(60.0, |_| (0.0, 0.0, 0.0));
    let over_zero = evaluate(
        &case(Metric::TiltRmseRatio { from_s: 10.0 }, 1e9),
        &ours,
        Some(&perfect),
    );
    assert!(!over_zero.passed, "{over_zero:?}");
}

#[test]
fn instant_and_maximum_rows_read_their_samples() {
    // Position error 50 m before 30 s, 2.7 m at 40 s, 1 m otherwise; tilt = t / 10 deg.
    let errors = trace(60.0, |t| {
        let north = if t < 30.0 {
            50.0
        } else if t == 40.0 {
            2.7
        } else {
            1.0
        };
        (t / 10.0, 0.0, north)
    });
    let max = score(Metric::MaxHorizontal { from_s: 30.0 }, 3.0, &errors);
    assert!((max.measured - 2.7).abs() < 1e-9 && max.passed, "{max:?}");
    assert!(!score(Metric::MaxHorizontal { from_s: 30.0 }, 2.6, &errors).passed);
    // The first sample at or after the instant.
    let at = score(Metric::HorizontalAt { t_s: 40.0 }, 5.0, &errors);
    assert!((at.measured - 2.7).abs() < 1e-9 && at.passed, "{at:?}");
    let tilt = score(Metric::TiltAt { t_s: 17.0 }, 2.0, &errors);
    assert!((tilt.measured - 1.7).abs() < 1e-12 && tilt.passed);
    let tilt = score(Metric::TiltAt { t_s: 25.0 }, 2.0, &errors);
    assert!((tilt.measured - 2.5).abs() < 1e-12 && !tilt.passed);
    // The limit is inclusive: a figure equal to it passes.
    assert!(score(Metric::HorizontalAt { t_s: 40.0 }, at.measured, &errors).passed);
}

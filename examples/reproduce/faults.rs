//! The fault suite of issue 10 (`--faults`): the thirteen rows of
//! `delaynav::sim::faults::fault_suite` run on `proposed` (the
//! delay-compensated navigator, delay estimated from an offline calibration
//! as in the main tables), on two threads, with a progress line per row.
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --faults --json target/faults.json
//! ```
//!
//! The JSON holds `"faults": [{"name", "passed", "criterion", "measured", "limit"}]`
//! (`measured` is `null` when the navigator had no estimate where the row
//! counts, the window is empty or a settle row never settles: each fails the
//! row); `docs/faults.md` explains every row. `FAULT_DEBUG=<row name>`
//! prints that row's errors once a second.

use super::{CALIBRATION_DURATION_S, CALIBRATION_SEED_OFFSET, DelayStart, calibrate, nav};
use delaynav::nav::{DelayCompensatedNav, DelayMode};
use delaynav::sim::SimConfig;
use delaynav::sim::faults::{
    FaultCase, FaultResult, FaultySimulation, Reference, TracePoint, base_config, evaluate,
    fault_suite, run_trace,
};
use serde_json::{Value, json};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Worker threads (the machine's two cores).
const THREADS: usize = 2;

/// One simulated run of the suite: a reference run or a row.
enum Job<'a> {
    Reference(Reference),
    Case(&'a FaultCase),
}

/// The navigator of every row: `proposed` on the run's sensors.
fn proposed(sim: &SimConfig, start: DelayStart) -> DelayCompensatedNav<f64> {
    nav(
        sim,
        DelayMode::Estimated {
            initial_s: start.delay_s,
        },
        start.std_s,
    )
}

/// Runs one job to its trace.
fn trace(job: &Job, base: &SimConfig, start: DelayStart) -> Vec<TracePoint> {
    let (sim, faults, on_backwards) = match job {
        Job::Reference(r) => (
            r.config(base),
            Vec::new(),
            delaynav::sim::faults::OnTimeBackwards::Ignore,
        ),
        Job::Case(c) => (c.sim.clone(), c.faults.clone(), c.on_backwards),
    };
    let events = FaultySimulation::new(sim.clone(), &faults).expect("valid fault run");
    run_trace(
        events,
        proposed(&sim, start),
        on_backwards,
        DelayCompensatedNav::reset,
    )
}

/// Runs the suite for `seed` with times scaled by `scale` (1: the issue's 60 s runs).
pub fn run(seed: u64, scale: f64) -> Vec<FaultResult> {
    let started = Instant::now();
    let base = base_config(seed, scale);
    let mut cal = base.clone();
    cal.seed = seed + CALIBRATION_SEED_OFFSET;
    cal.duration_s = CALIBRATION_DURATION_S;
    let start = calibrate(&cal);
    eprintln!(
        "faults: calibrated start {:.3} s ({:.0} s)",
        start.delay_s,
        started.elapsed().as_secs_f64()
    );
    let cases = fault_suite(seed, scale);
    let mut jobs = vec![Job::Reference(Reference::Clean)];
    for c in &cases {
        if c.reference != Reference::None
            && !jobs
                .iter()
                .any(|j| matches!(j, Job::Reference(r) if *r == c.reference))
        {
            jobs.push(Job::Reference(c.reference));
        }
    }
    let first_case = jobs.len();
    jobs.extend(cases.iter().map(Job::Case));
    let next = AtomicUsize::new(0);
    let traces: Mutex<Vec<Option<Vec<TracePoint>>>> =
        Mutex::new(jobs.iter().map(|_| None).collect());
    let done = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..THREADS {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(job) = jobs.get(k) else { break };
                    let t0 = Instant::now();
                    let tr = trace(job, &base, start);
                    let name = match job {
                        Job::Reference(r) => format!("reference {r:?}"),
                        Job::Case(c) => c.name.to_string(),
                    };
                    let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                    eprintln!(
                        "[{n}/{}] {name}: {:.1} s (elapsed {:.0} s)",
                        jobs.len(),
                        t0.elapsed().as_secs_f64(),
                        started.elapsed().as_secs_f64()
                    );
                    traces.lock().expect("no poisoned lock")[k] = Some(tr);
                }
            });
        }
    });
    let traces: Vec<Vec<TracePoint>> = traces
        .into_inner()
        .expect("no poisoned lock")
        .into_iter()
        .map(|t| t.expect("every job ran"))
        .collect();
    let reference_trace = |r: Reference| {
        jobs.iter()
            .position(|j| matches!(j, Job::Reference(x) if *x == r))
            .map(|k| traces[k].as_slice())
    };
    cases
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let result = evaluate(c, &traces[first_case + i], reference_trace(c.reference));
            if std::env::var("FAULT_DEBUG").is_ok_and(|v| v == c.name) {
                for p in traces[first_case + i].iter().step_by(1000) {
                    eprintln!(
                        "{:.1} tilt {:.2} heading {:.2} herr {:.2}",
                        p.t_s,
                        p.tilt_deg,
                        p.heading_deg,
                        p.horizontal_error_m([0.0; 2])
                    );
                }
            }
            eprintln!(
                "{:<24} {:>10.3} (limit {:>5}) {}",
                result.name,
                result.measured,
                result.limit,
                if result.passed { "pass" } else { "FAIL" }
            );
            result
        })
        .collect()
}

/// The suite's rows as `--check` verdicts (a NaN figure fails).
pub fn verdicts(results: &[FaultResult]) -> Vec<super::check::Verdict> {
    results
        .iter()
        .map(|r| super::check::Verdict {
            name: r.name.to_string(),
            passed: r.passed,
            measured: Some(r.measured),
            limit: format!("{} ({})", r.limit, r.criterion),
        })
        .collect()
}

/// A float, or `null` when it is not finite.
fn number(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

/// The suite's JSON.
pub fn to_json(results: &[FaultResult], seed: u64, scale: f64) -> Value {
    let rows: Vec<Value> = results
        .iter()
        .map(|r| {
            let mut row = json!({
                "name": r.name,
                "passed": r.passed,
                "criterion": r.criterion,
                "measured": number(r.measured),
                "limit": r.limit,
            });
            if let Some((key, value)) = r.note {
                row[key] = number(value);
            }
            row
        })
        .collect();
    json!({
        "seed": seed,
        "duration_s": 60.0 * scale,
        "estimator": "proposed",
        "faults": rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(name: &'static str, passed: bool, measured: f64) -> FaultResult {
        FaultResult {
            name,
            passed,
            criterion: "synthetic",
            measured,
            limit: 5.0,
            note: None,
        }
    }

    /// Each row's verdict reaches the JSON as it is; a figure that is not a number (no
    /// estimate, an empty window, never settled) is written `null`, never a number.
    #[test]
    fn the_json_keeps_each_verdict_and_writes_no_figure_it_has_not() {
        let mag = FaultResult {
            note: Some(("max_tilt_deg", 2.5)),
            ..row("mag", false, 1.0)
        };
        let lost = FaultResult {
            note: Some(("max_tilt_deg", f64::NAN)),
            ..row("lost", false, f64::NAN)
        };
        let results = [
            row("settled", true, 2.9),
            row("never", false, f64::INFINITY),
            mag,
            lost,
        ];
        let json = to_json(&results, 3, 0.5);
        assert_eq!(
            (json["seed"].as_u64(), json["duration_s"].as_f64()),
            (Some(3), Some(30.0))
        );
        let rows = json["faults"].as_array().expect("rows");
        let passed: Vec<bool> = rows.iter().map(|r| r["passed"] == true).collect();
        assert_eq!(passed, [true, false, false, false]);
        assert_eq!(rows[0]["measured"], 2.9);
        assert!(rows[1]["measured"].is_null() && rows[3]["measured"].is_null());
        assert_eq!(rows[2]["max_tilt_deg"], 2.5);
        assert!(rows[3]["max_tilt_deg"].is_null());
        assert!(rows[0].get("max_tilt_deg").is_none());
    }
}

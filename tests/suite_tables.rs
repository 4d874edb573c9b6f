//! The tables' JSON contract (`delaynav::sim::suite::tables`, `reproduce --seeds N --json
//! PATH`) on two short seeds, with a row added by the caller: the peer `fusion_nav` of the
//! `reproduce` example. Each scenario's `estimators` has `bound`, `fusion_nav` and
//! `proposed_f32`; each entry `tilt_deg`, `heading_deg`, every figure's `<name>_ci95` and
//! `nees_mean`; the top level the seeds. Bad options are refused, not a panic.
#![cfg(feature = "sim")]

#[allow(dead_code)]
#[path = "../examples/reproduce/fusion_nav.rs"]
mod fusion_nav;

use delaynav::sim::Scenario;
use delaynav::sim::suite::tables::{self, Estimator, FIGURES, TablesOptions, score};
use delaynav::sim::suite::{Progress, SuiteError, Task, no_progress};
use fusion_nav::FusionNav;
use serde_json::{Value, json};
use std::sync::Mutex;

fn options() -> TablesOptions {
    TablesOptions {
        scenarios: vec![Scenario::Low],
        seeds: vec![1, 2],
        duration_s: 12.0,
        skip_s: 10.0,
        keep_trace: false,
        calibrated: false,
        threads: 2,
        ..TablesOptions::default()
    }
}

#[test]
fn the_run_json_has_the_issue_keys() {
    let names = ["bound", "proposed", "proposed_f32", "fusion_nav"];
    let mut registry: Vec<Estimator> = tables::estimators()
        .into_iter()
        .filter(|e| names.contains(&e.name))
        .collect();
    registry.push(Estimator::new("fusion_nav", |s| {
        Ok(score::<f32, _>(FusionNav::new(&s.config), s, |_| None))
    }));
    assert_eq!(registry.len(), names.len());
    let steps = Mutex::new(Vec::new());
    let progress = |p: Progress| {
        if let Progress::Step {
            done, total, task, ..
        } = p
        {
            steps.lock().expect("no panic").push((done, total, task));
        }
    };
    let result = tables::run(&options(), &registry, &progress).expect("valid options");
    let steps = steps.into_inner().expect("no panic");
    assert_eq!(steps.len(), 8);
    assert!(
        steps
            .iter()
            .enumerate()
            .all(|(k, (done, total, _))| *done == k + 1 && *total == 8)
    );
    assert!(steps.iter().any(|(_, _, task)| *task
        == Task::Run {
            scenario: Scenario::Low,
            seed: 2,
            estimator: "fusion_nav"
        }));
    let json = result.to_json();
    assert_eq!(json["seeds"], json!([1, 2]));
    let estimators = &json["scenarios"][0]["estimators"];
    for name in names {
        let entry = estimators[name].as_object().expect("an entry per row");
        for key in ["tilt_deg", "heading_deg", "vel_m_s", "pos_m"] {
            assert!(
                entry[key].as_f64().is_some_and(f64::is_finite),
                "{name}.{key}"
            );
            let ci = entry[&format!("{key}_ci95")].as_array().expect("a pair");
            assert!(
                ci.len() == 2 && ci.iter().all(Value::is_number),
                "{name}.{key}_ci95"
            );
        }
        for (figure, _) in FIGURES {
            assert!(
                entry.contains_key(&format!("{figure}_ci95")),
                "{name}.{figure}_ci95"
            );
        }
        assert!(entry.contains_key("nees_mean"), "{name}.nees_mean");
    }
    assert!(estimators["proposed_f32"]["nees_mean"].is_number());
    // The text names every row; the verdicts of a registry without `oracle` fail on it.
    let text = result.to_string();
    assert!(text.contains("| RMSE | bound | proposed | proposed_f32 | fusion_nav |"));
    let verdicts = result.verdicts();
    let oracle = verdicts
        .iter()
        .find(|v| v.name == "low.proposed_vs_oracle")
        .expect("the check is there");
    assert!(!oracle.holds() && oracle.measured.is_none());
}

#[test]
fn bad_options_are_refused() {
    let registry = tables::estimators();
    let refused = |o: TablesOptions| tables::run(&o, &registry, &no_progress).map(|_| ());
    let option = |o| match refused(o) {
        Err(SuiteError::InvalidOption { option, .. }) => Some(option),
        _ => None,
    };
    let no_seeds = TablesOptions {
        seeds: Vec::new(),
        ..options()
    };
    assert_eq!(option(no_seeds), Some("seeds"));
    let too_short = TablesOptions {
        duration_s: 5.0,
        ..options()
    };
    assert_eq!(option(too_short), Some("duration_s"));
    let bad_rate = TablesOptions {
        gps_rate_hz: Some(-1.0),
        ..options()
    };
    assert!(matches!(refused(bad_rate), Err(SuiteError::Config { .. })));
    // A navigator configuration it refuses: a negative filter rate.
    let bad_filter = TablesOptions {
        filter_rate_hz: Some(-5.0),
        ..options()
    };
    let err = refused(bad_filter).expect_err("refused");
    assert!(err.to_string().contains("proposed"), "{err}");
}

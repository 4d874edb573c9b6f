//! The delay suite of issue 11 (`examples/reproduce/delay_suite.rs`),
//! shortened: one seed, a few rows. Checks the JSON shape the lead's
//! tooling reads and the rows the loop passes today.
#![cfg(feature = "sim")]

#[allow(dead_code, unused_imports)]
#[path = "../examples/reproduce/main.rs"]
mod reproduce;

use reproduce::delay_suite::{LoopTuning, SuiteOptions, run, to_json};

const ROWS: [&str; 4] = [
    "delay_step",
    "negative_delay",
    "out_of_range_reported",
    "aekf17_hover",
];

#[test]
fn shortened_suite_writes_the_issue_rows() {
    let options = SuiteOptions {
        seeds: vec![1],
        coverage_seeds: vec![1],
        rows: Some(ROWS.to_vec()),
        tuning: LoopTuning::default(),
    };
    let rows = run(&options);
    let json = to_json(&rows, &options);
    let scenarios = json["delay_scenarios"].as_array().expect("an array");
    let names: Vec<&str> = scenarios
        .iter()
        .map(|r| r["name"].as_str().expect("a name"))
        .collect();
    assert_eq!(names, ROWS);
    for row in scenarios {
        let object = row.as_object().expect("an object");
        let mut keys: Vec<&str> = object.keys().map(String::as_str).collect();
        keys.sort_unstable();
        assert_eq!(keys, ["criterion", "limit", "measured", "name", "passed"]);
        assert!(row["passed"].is_boolean() && row["criterion"].is_string());
        assert!(row["measured"].is_number() || row["measured"].is_null());
        assert!(row["limit"].is_number());
        if row["measured"].is_null() {
            assert_eq!(row["passed"], false, "{row}");
        }
    }
    let passed = |name: &str| {
        scenarios
            .iter()
            .find(|r| r["name"] == name)
            .is_some_and(|r| r["passed"] == true)
    };
    // The rows the loop passes (seed 1 measured 2.3 s, 3.5 ms, 20.4 s).
    for name in ["delay_step", "negative_delay", "out_of_range_reported"] {
        assert!(passed(name), "{name}: {json:#}");
    }
}

//! The delay suite (`delaynav::sim::suite::delay`), shortened: one seed, a few
//! rows. Checks the JSON shape the tooling reads, the rows the loop passes
//! today, and that a row's trace measures what the suite measures.
#![cfg(feature = "sim")]

use delaynav::sim::suite::delay::{
    DelayOptions, HoverSetup, LoopTuning, TraceOptions, run, write_hover_trace, write_trace,
};
use delaynav::sim::suite::no_progress;

const ROWS: [&str; 4] = [
    "delay_step",
    "negative_delay",
    "out_of_range_reported",
    "aekf17_hover",
];

/// The suite's options on one seed and `rows`.
fn one_seed(seed: u64, rows: &[&str], tuning: LoopTuning) -> DelayOptions {
    DelayOptions {
        seeds: vec![seed],
        coverage_seeds: vec![seed],
        rows: Some(rows.iter().map(|r| r.to_string()).collect()),
        tuning,
        ..DelayOptions::default()
    }
}

#[test]
fn shortened_suite_writes_the_issue_rows() {
    let options = one_seed(1, &ROWS, LoopTuning::default());
    let result = run(&options, &no_progress).expect("known rows");
    let json = result.to_json();
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
        assert_eq!(
            keys,
            [
                "bound",
                "criterion",
                "limit",
                "measured",
                "name",
                "passed",
                "ratio"
            ]
        );
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
    // Only the RMSE rows have an information bound (3.14 ms measured for
    // negative_delay), and they are judged on the ratio to it.
    let bounds = json["information_bounds"].as_object().expect("an object");
    assert_eq!(bounds.keys().collect::<Vec<_>>(), ["negative_delay"]);
    let bound = bounds["negative_delay"].as_f64().expect("a number");
    assert!(bound > 1.0 && bound < 10.0, "{bound}");
    let negative = scenarios
        .iter()
        .find(|r| r["name"] == "negative_delay")
        .expect("the row");
    assert_eq!(negative["bound"], bound);
    let ratio = negative["measured"].as_f64().expect("a figure") / bound;
    assert!((negative["ratio"].as_f64().expect("a ratio") - ratio).abs() < 1e-12);
    assert_eq!(
        negative["passed"],
        ratio <= negative["limit"].as_f64().expect("a limit")
    );
    for row in scenarios.iter().filter(|r| r["name"] != "negative_delay") {
        assert!(row["bound"].is_null() && row["ratio"].is_null(), "{row}");
    }
    // The rows the loop passes (seed 1 measured 2.3 s and 20.4 s). negative_delay, a known
    // failure of the full suite (2.63x its bound on 5 seeds), measured 2.17x on seed 1 with the
    // 3-axis magnetometer update (1.1x before it): not asserted.
    for name in ["delay_step", "out_of_range_reported"] {
        assert!(passed(name), "{name}: {json:#}");
    }
    // The verdicts are the rows'.
    let verdicts = result.verdicts();
    assert_eq!(verdicts.len(), ROWS.len());
    for (v, row) in verdicts.iter().zip(&result.rows) {
        assert_eq!((v.name.as_str(), v.holds()), (row.name, row.passed()));
    }
}

/// A row's trace (`--delay-trace ROW --compare-accel`): one CSV row a second with the two
/// comparison columns, and the navigator's RMSE the suite's row measures on that seed with
/// the same tuning.
#[test]
fn trace_agrees_with_the_suite() {
    let tuning = LoopTuning {
        rate_std: Some(1e-3),
        ..LoopTuning::default()
    };
    let options = TraceOptions {
        row: "cold_start_high".into(),
        seed: 2,
        tuning,
        compare_accel: true,
        filter_rate_hz: None,
    };
    let mut csv = Vec::new();
    let summary = write_trace(&options, &mut csv)
        .expect("writes to memory")
        .expect("a navigator row");
    let text = String::from_utf8(csv).expect("UTF-8");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(summary.rows, 61);
    assert_eq!(lines.len(), 62);
    let columns = lines[0].split(',').count();
    // 9 (delay_valid the ninth) + the GFA's sigma and the innovation window (3), 5 per axis,
    // 2 compared.
    assert_eq!(columns, 12 + 3 * 5 + 2);
    assert!(lines.iter().all(|l| l.split(',').count() == columns));
    assert!(lines[0].ends_with("oracle_accel_estimate_s,true_accel_estimate_s"));
    let names: Vec<&str> = summary.rmse_ms.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, ["navigator", "oracle_accel", "true_accel"]);
    assert!(
        summary
            .rmse_ms
            .iter()
            .all(|(_, x)| x.is_finite() && *x > 0.0)
    );
    // The Cramer-Rao bound from every GPS velocity so far: below what each
    // of the three loops reaches on this seed (a bound on the mean square
    // over the noise; one lucky seed may score below it).
    let bound = summary.information_bound_ms;
    assert!(bound > 1.0 && summary.rmse_ms.iter().all(|(_, x)| *x > bound));
    // The sigma's coverage (10 ms spacing) agrees with the CSV's rows
    // (1 s spacing) from 20 s: columns sigma_s and error_ms.
    let (mut inside, mut n) = (0.0, 0.0);
    for line in lines[1..].iter().map(|l| l.split(',').collect::<Vec<_>>()) {
        let value = |i: usize| line[i].parse::<f64>().expect("a number");
        if value(0) >= 20.0 {
            inside += f64::from(u8::from(value(4).abs() * 1e-3 <= value(3)));
            n += 1.0;
        }
    }
    assert!((0.0..=1.0).contains(&summary.sigma_coverage));
    assert!((summary.sigma_coverage - inside / n).abs() < 0.05);
    // The points with delay_valid (10 ms spacing) agree with the CSV's delay_valid column
    // (1 s spacing), and so does their share beyond 3 sigma (none on this run).
    let (mut valid, mut far) = (0usize, 0usize);
    for line in lines[1..].iter().map(|l| l.split(',').collect::<Vec<_>>()) {
        if line[7] == "1" {
            let value = |i: usize| line[i].parse::<f64>().expect("a number");
            valid += 1;
            far += usize::from(value(4).abs() * 1e-3 > 3.0 * value(3));
        }
    }
    let (suite_far, suite_valid) = summary.valid_but_far;
    assert!(valid > 30, "{valid}");
    assert!(
        suite_valid.abs_diff(100 * valid) <= 100,
        "{suite_valid} {valid}"
    );
    assert_eq!((suite_far, far), (0, 0));
    let suite = run(&one_seed(2, &["cold_start_high"], tuning), &no_progress)
        .expect("a known row")
        .rows[0]
        .measured
        .expect("measured");
    assert_eq!(summary.rmse_ms[0].1, suite);
    let none = TraceOptions {
        row: "sigma_coverage".into(),
        ..TraceOptions::default()
    };
    let written = write_trace(&none, &mut Vec::new());
    assert!(written.expect("nothing written").is_none());
}

/// `--delay-trace aekf17_hover`: the default trace ends on the suite row's figure for that
/// seed; a setup the filter refuses is an error, not a panic.
#[test]
fn hover_trace_agrees_with_the_suite() {
    let mut csv = Vec::new();
    let end = write_hover_trace(1, &HoverSetup::default(), &mut csv).expect("writes to memory");
    let text = String::from_utf8(csv).expect("UTF-8");
    assert_eq!(end.rows, 61);
    assert_eq!(text.lines().count(), 62);
    assert!(end.ratio.is_finite() && end.sigma_s > 0.0);
    let suite = run(
        &one_seed(1, &["aekf17_hover"], LoopTuning::default()),
        &no_progress,
    )
    .expect("a known row")
    .rows[0]
        .measured
        .expect("measured");
    assert_eq!(end.ratio, suite);
    let refused = HoverSetup {
        delay_random_walk: Some(-1.0),
        ..HoverSetup::default()
    };
    assert!(write_hover_trace(1, &refused, &mut Vec::new()).is_err());
}

/// The innovation observation on the navigator (`cold_start_high`, seed 1,
/// observed but not fused): from 20 s its windows scatter as their variance
/// says (mean normalized error squared 1.04 measured) and their weighted
/// mean is within a fraction of its standard deviation of the truth
/// (+0.43 ms against 1.35 ms measured).
#[test]
fn innovation_windows_match_their_variance() {
    let tuning = LoopTuning {
        innovation_window_s: Some(1.0),
        innovation_noise_scale: Some(1e9),
        innovation_reacquire_sigma: Some(0.0),
        ..LoopTuning::default()
    };
    let options = TraceOptions {
        tuning,
        ..TraceOptions::default()
    };
    let mut csv = Vec::new();
    write_trace(&options, &mut csv)
        .expect("writes to memory")
        .expect("a navigator row");
    let text = String::from_utf8(csv).expect("UTF-8");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let column = |name: &str| header.iter().position(|&h| h == name).expect(name);
    let (t, truth, z, std) = (
        column("t_s"),
        column("truth_s"),
        column("innovation_estimate_s"),
        column("innovation_std_s"),
    );
    let (mut nis, mut n, mut weight, mut weighted) = (0.0, 0.0, 0.0, 0.0);
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let value = |i: usize| cells[i].parse::<f64>().ok();
        let (Some(t), Some(truth), Some(z), Some(std)) =
            (value(t), value(truth), value(z), value(std))
        else {
            continue;
        };
        if t < 20.0 {
            continue;
        }
        let e = z - truth;
        nis += (e / std).powi(2);
        n += 1.0;
        weight += 1.0 / (std * std);
        weighted += e / (std * std);
    }
    assert!(n >= 30.0, "{n} windows");
    let nis = nis / n;
    assert!(
        (0.5..=2.0).contains(&nis),
        "mean normalized error squared {nis}"
    );
    let (mean, sigma) = (weighted / weight, weight.powf(-0.5));
    assert!(
        mean.abs() <= 2.0 * sigma,
        "mean error {mean} s, sigma {sigma} s"
    );
}

//! The replay as library calls (`delaynav::replay::session`): the simulated
//! run through every estimator, with the JSON's keys and the console's text;
//! log171's derived setup (when `../shared` is there; a failure under
//! `CI=true`, see `common::shared_data`); the errors a front end shows.
#![cfg(feature = "replay")]
#![cfg_attr(not(feature = "sim"), allow(dead_code, unused_imports))]

mod common;

use delaynav::Estimate;
use delaynav::replay::ReplayError;
use delaynav::replay::session::{
    DeclinationSource, EstimatorReport, InclinationSource, ReplayObserver, ReplayOptions,
    ReplaySetup, SetupNote, select_estimators,
};

/// Counts what an observer is shown.
#[derive(Default)]
struct Counting {
    passes: Vec<(String, Option<u64>)>,
    finished: usize,
    estimates: u64,
    last_progress_s: u64,
    reports: Vec<String>,
}

impl ReplayObserver for Counting {
    fn started(&mut self, estimator: &str, length_s: Option<u64>) {
        self.passes.push((estimator.to_string(), length_s));
    }
    fn progress(&mut self, replayed_s: u64) {
        self.last_progress_s = replayed_s;
    }
    fn estimate(
        &mut self,
        _: &str,
        _: &Estimate<f64>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.estimates += 1;
        Ok(())
    }
    fn finished(&mut self) {
        self.finished += 1;
    }
    fn report(&mut self, report: &EstimatorReport) {
        self.reports.push(report.table_row());
    }
}

#[cfg(feature = "sim")]
#[test]
fn the_simulated_run_through_every_estimator() {
    let dir = std::env::temp_dir().join(format!("delaynav-session-sim-{}", std::process::id()));
    let mut options = ReplayOptions::default();
    let written = options.simulated_log(&dir).unwrap();
    assert_eq!(written, 60_001 + 600 + 6_001);
    assert!(options.fixed_window && options.declination_deg.is_some());
    assert_eq!((options.from_s, options.warmup_s), (Some(10.0), Some(10.0)));

    let setup = ReplaySetup::open(&options).unwrap();
    assert!(setup.notes.is_empty(), "{:?}", setup.notes);
    assert_eq!(setup.imu_rate_hz, 1000.0);
    assert_eq!(setup.derived.declination_rad.1, DeclinationSource::Given);
    assert_eq!(setup.derived.inclination_rad.1, InclinationSource::Given);
    let scan = setup.scan().unwrap();
    assert_eq!(
        (scan.counts.imu, scan.counts.gps, scan.counts.mag),
        (60_001, 600, 6_001)
    );
    assert!(setup.log_line(&scan).starts_with("log: "));

    let mut observer = Counting::default();
    let estimators = select_estimators("all").unwrap();
    let report = setup.run(scan, &estimators, &mut observer).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();

    let names: Vec<_> = report.estimators.iter().map(|e| e.estimator.name).collect();
    assert_eq!(names, ["proposed", "aekf17", "ekf16"]);
    assert_eq!(observer.passes.len(), 3);
    assert_eq!(observer.finished, 3);
    assert!(observer.passes.iter().all(|(_, length)| length.is_none()));
    assert!(observer.estimates > 100_000, "{}", observer.estimates);
    assert!(
        observer.last_progress_s >= 59,
        "{}",
        observer.last_progress_s
    );
    for e in &report.estimators {
        let rms = e.summary.reference_rms.expect("scored against truth.csv");
        assert!(
            rms.roll_deg < 5.0 && rms.pitch_deg < 5.0,
            "{}: {rms:?}",
            e.estimator.name
        );
        assert_eq!(e.summary.samples_refused(), 0, "{}", e.estimator.name);
    }
    assert!(report.estimators[0].summary.final_delay_s.is_some());
    // The delay-compensated navigator beats the filter that ignores the delay.
    let tilt = |e: &EstimatorReport| {
        let rms = e.summary.reference_rms.unwrap();
        rms.roll_deg.hypot(rms.pitch_deg)
    };
    assert!(tilt(&report.estimators[0]) < tilt(&report.estimators[2]));

    // The console's text: the rows as the observer was shown them, then the rest.
    let text = report.to_string();
    let lines: Vec<_> = text.lines().collect();
    assert_eq!(lines[0], delaynav::replay::session::table_header());
    assert_eq!(lines[1..4], observer.reports[..]);
    assert!(text.contains("\nhealth at the end of the replay"));
    // The offline calibration's line only (no delay step, every delay estimated).
    let offline = report.estimators[0]
        .summary
        .offline_delay
        .as_ref()
        .expect("a calibration of the simulated run");
    assert!(offline.applied && offline.peak > 0.5, "{offline:?}");
    assert!((offline.delay_s - 0.2).abs() < 0.03, "{offline:?}");
    assert_eq!(
        report.delay_steps(),
        format!("proposed: {}\n", offline.line())
    );

    // The JSON: every key of the contract (docs/replay.md).
    let json = report.to_json();
    let keys: Vec<_> = json.as_object().unwrap().keys().cloned().collect();
    assert_eq!(
        keys,
        [
            "accel_bias_random_walk",
            "accel_noise_density",
            "counts",
            "declination_deg",
            "derived",
            "estimators",
            "format",
            "gps_delay_added_from_s",
            "gps_delay_added_s",
            "gyro_noise_density",
            "imu_instance",
            "imu_rate_hz",
            "inclination_deg",
            "log",
            "replayed_from_s",
            "scored_from_s",
            "to_s",
            "trim_pitch_rad",
            "trim_roll_rad",
            "window_s",
        ]
    );
    assert_eq!(json["format"], "csv");
    assert_eq!(json["replayed_from_s"], 0.0);
    assert_eq!(json["scored_from_s"], 10.0);
    assert_eq!(json["derived"]["declination_source"], "command line");
    assert_eq!(json["estimators"][2]["estimator"], "ekf16");
    assert_eq!(
        json["estimators"][2]["final_delay_s"],
        serde_json::Value::Null
    );
    assert_eq!(json["estimators"][0]["health"]["alignment"], "Aligned");
    assert_eq!(json["estimators"][0]["delay_estimated"], true);
    assert_eq!(json["estimators"][0]["offline_delay"]["applied"], true);
    assert!(
        json["estimators"][0]["offline_delay"]["curve"]
            .as_array()
            .is_some_and(|c| c.len() > 100)
    );
    assert_eq!(
        json["estimators"][1]["offline_delay"],
        serde_json::Value::Null
    );
    assert_eq!(
        json["estimators"][2]["delay_estimated"],
        serde_json::Value::Null
    );
}

#[test]
fn log171_derives_its_window_rates_and_field() {
    let Some(bin) = common::shared_data::shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let setup = ReplaySetup::from_log(&ReplayOptions::new([bin])).unwrap();
    let window = setup.window.expect("log171 flies");
    assert_eq!(
        setup.notes[0],
        SetupNote::FlightWindow {
            window,
            overridden: false
        }
    );
    assert!(
        setup.notes[0]
            .to_string()
            .starts_with("flight window from the log: 84.7-228.5 s")
    );
    // Cut before the loss of control (a roll to 40 deg at 229 s), not 2 s before the impact.
    assert!(
        window.impact_us.is_some_and(|t| t > 239_000_000),
        "{window:?}"
    );
    assert!(window.to_us <= 230_000_000, "{window:?}");
    assert_eq!(window.loss_of_control_us, Some(window.to_us));
    assert!(matches!(setup.notes[1], SetupNote::ModelDateClamped { .. }));
    assert_eq!(setup.imu_rate_hz, 50.0);
    assert!((setup.gps_rate_hz.unwrap() - 4.975).abs() < 0.01);
    let (declination, source) = setup.derived.declination_rad;
    assert_eq!(source, DeclinationSource::MagneticModelNearestDate);
    assert!((declination.to_degrees() - 12.48).abs() < 0.01);
    let derived = setup.derived.to_json();
    assert_eq!(derived["log_date"], "2015-11-21");
    assert_eq!(derived["inclination_source"], "stationary segment");
    assert!(
        setup
            .derived
            .to_string()
            .starts_with("derived from the log (docs/replay.md, \"Defaults from the log\"):\n")
    );
    // Replayed from 30 s before the take-off, scored from it.
    assert_eq!(setup.run.score_from_us, Some(window.from_us));
    assert_eq!(setup.run.start_us, Some(window.from_us - 30_000_000));
    assert_eq!(setup.nav, setup.log_config().unwrap());
}

#[test]
fn a_front_end_gets_typed_errors() {
    let err = select_estimators("ekf17").unwrap_err();
    assert!(matches!(err, ReplayError::UnknownEstimator { .. }), "{err}");
    let err = ReplaySetup::open(&ReplayOptions::new(["/nonexistent/log171"])).unwrap_err();
    assert!(matches!(err, ReplayError::Open { .. }), "{err}");
    let options = ReplayOptions {
        add_gps_delay_s: f64::NAN,
        ..ReplayOptions::new(["/nonexistent/log171"])
    };
    let err = ReplaySetup::open(&options).unwrap_err();
    assert!(matches!(err, ReplayError::InvalidSeconds { .. }), "{err}");
}

#[test]
fn a_log_without_a_magnetometer_has_no_measured_inclination() {
    let dir = std::env::temp_dir().join(format!("delaynav-session-nomag-{}", std::process::id()));
    let mut options = ReplayOptions::default();
    options.simulated_log(&dir).unwrap();
    std::fs::remove_file(dir.join("mag.csv")).unwrap();
    // What the log gives, not the simulator's field.
    options.inclination_deg = None;
    let setup = ReplaySetup::from_log(&options);
    std::fs::remove_dir_all(&dir).unwrap();
    let setup = setup.unwrap();
    // No magnetometer sample and no geodetic fix (no model): nothing measured it.
    assert_eq!(
        setup.derived.inclination_rad,
        (0.0, InclinationSource::None)
    );
    let text = setup.derived.to_string();
    assert!(
        text.contains("inclination 0.00 deg (none (0: no magnetometer sample to measure it on))"),
        "{text}"
    );
    assert!(!text.contains("first 10 s"), "{text}");
}

/// A window too short for any valid update of the delay loop: the start
/// value is not reported as an estimate (JSON null, `delay_estimated` false
/// with the reason, `-` on the console with the reason).
#[cfg(feature = "sim")]
#[test]
fn a_delay_never_estimated_is_not_reported_as_one() {
    let dir = std::env::temp_dir().join(format!("delaynav-session-still-{}", std::process::id()));
    let mut options = ReplayOptions {
        from_s: Some(1.0),
        warmup_s: Some(1.0),
        to_s: Some(4.0),
        ..ReplayOptions::default()
    };
    options.simulated_log(&dir).unwrap();
    let setup = ReplaySetup::open(&options).unwrap();
    let scan = setup.scan().unwrap();
    let estimators = select_estimators("proposed").unwrap();
    let report = setup.run(scan, &estimators, &mut ()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();

    let proposed = &report.estimators[0];
    assert_eq!(proposed.summary.final_delay_s, None);
    let reason = proposed.summary.delay_not_estimated.as_deref().unwrap();
    assert!(
        reason.starts_with("no valid update of the delay loop"),
        "{reason}"
    );
    let json = report.to_json();
    assert_eq!(
        json["estimators"][0]["final_delay_s"],
        serde_json::Value::Null
    );
    assert_eq!(json["estimators"][0]["delay_estimated"], false);
    assert_eq!(json["estimators"][0]["delay_not_estimated_reason"], reason);
    let text = report.to_string();
    assert!(
        text.lines()
            .nth(1)
            .unwrap()
            .starts_with("proposed          -"),
        "{text}"
    );
    assert!(text.contains(&format!("proposed: delay_s - (not estimated: {reason})")));
    // Three seconds: not enough for an offline result either.
    assert_eq!(proposed.summary.offline_delay, None);
}

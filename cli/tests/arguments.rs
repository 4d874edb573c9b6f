//! Bad invocations of `delaynav`: each exits 2 with a message naming the
//! flag, the value and the bound, before anything is replayed. The checks
//! against a log's span run on log171 (skipped with a note when the shared
//! data is absent, a failure with `CI=true`).

use std::path::PathBuf;
use std::process::{Command, Output};

/// The shared data: `$DELAYNAV_SHARED_DATA`, else `../shared/data` beside
/// the repository.
fn shared(relative: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("DELAYNAV_SHARED_DATA").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
        PathBuf::from,
    );
    let path = dir.join(relative);
    if path.exists() {
        return Some(path);
    }
    assert_ne!(
        std::env::var("CI").as_deref(),
        Ok("true"),
        "CI=true but {} is missing",
        path.display()
    );
    println!("skipped: {} not found", path.display());
    None
}

fn delaynav(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_delaynav"))
        .args(args)
        .output()
        .expect("delaynav runs")
}

/// Runs `args`, asserts exit 2 and that stderr holds every one of `words`.
fn refused(args: &[&str], words: &[&str]) {
    let out = delaynav(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    for w in words {
        assert!(stderr.contains(w), "{args:?}: {w:?} not in {stderr}");
    }
}

#[test]
fn numbers_that_are_not_finite_or_out_of_range_exit_2_naming_flag_value_and_bound() {
    // The log is never opened: clap refuses the value first.
    let log = "no-such-log.bin";
    refused(
        &["replay", log, "--from", "nan"],
        &["'--from <S>'", "'nan'", "finite"],
    );
    refused(
        &["replay", log, "--to", "nan"],
        &["'--to <S>'", "'nan'", "finite"],
    );
    refused(
        &["replay", log, "--warmup=-5"],
        &["'--warmup <S>'", "'-5'", ">= 0 s"],
    );
    refused(
        &["replay", log, "--from", "inf"],
        &["'--from <S>'", "finite"],
    );
    refused(
        &["calibrate", log, "--inclination-deg", "95"],
        &["'--inclination-deg <DEG>'", "'95'", "<= 90 deg"],
    );
    refused(
        &["simulate", "--seeds", "0"],
        &["'--seeds <SEEDS>'", "'0'", "1..=1000"],
    );
}

#[test]
fn a_negative_value_is_taken_as_a_value() {
    // Not "unexpected argument '-0'": the value is read, and refused by its bound.
    refused(
        &["replay", "no-such-log.bin", "--add-gps-delay", "-0.1"],
        &["'--add-gps-delay <S>'", "'-0.1'", ">= 0 s"],
    );
    // A negative declination is a value in range: the command goes on to the
    // log (missing here: exit 1, not a usage error).
    let out = delaynav(&["replay", "no-such-log.bin", "--declination-deg", "-12.5"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot open no-such-log.bin"), "{stderr}");
}

#[test]
fn an_inverted_window_exits_2() {
    refused(
        &["replay", "no-such-log.bin", "--from", "30", "--to", "20"],
        &["'--to <S>'", "'20'", "after --from (30 s)"],
    );
}

#[test]
fn times_outside_the_log_exit_2() {
    let Some(log) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let log = log.to_str().expect("a UTF-8 path");
    let span = "11.460-254.061 s";
    refused(
        &["replay", log, "--to", "5000", "--quiet"],
        &["'--to <S>'", "'5000'", "outside the log", span],
    );
    refused(
        &["replay", log, "--from", "300", "--quiet"],
        &["'--from <S>'", "'300'", span],
    );
    refused(
        &[
            "replay",
            log,
            "--add-gps-delay",
            "0.1",
            "--add-delay-from",
            "400",
        ],
        &["'--add-delay-from <S>'", "'400'", span],
    );
    // Inside the log, but after the end of the window the log gives.
    refused(
        &["replay", log, "--from", "250", "--quiet"],
        &["'--from <S>'", "'250'", "before the window's end"],
    );
}

#[test]
fn a_config_error_names_the_file_the_key_the_value_and_the_bound() {
    let Some(log) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("delaynav-cli-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("wide.toml");
    std::fs::write(&file, "[delay_loop.fusion]\ndelay_max_s = 2.0\n").unwrap();
    refused(
        &[
            "replay",
            log.to_str().unwrap(),
            "--config",
            file.to_str().unwrap(),
            "--quiet",
        ],
        &[
            "--config",
            "wide.toml",
            "`delay_loop.fusion.delay_max_s` = 2",
            "must be <= 1.2",
        ],
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn every_subcommand_has_an_example_in_its_help() {
    for command in [
        "replay",
        "report",
        "calibrate",
        "batch",
        "simulate",
        "suite",
    ] {
        let out = delaynav(&[command, "--help"]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{command}: {stdout}");
        assert!(
            stdout.contains(&format!("Examples:\n  delaynav {command}")),
            "{command}: {stdout}"
        );
    }
}

#[test]
fn batch_counts_a_log_it_cannot_read_as_an_error_row_and_exits_0() {
    let Some(log) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("delaynav-cli-batch-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::copy(&log, dir.join("sub/log171.bin")).unwrap();
    // The first 5 kB of the log: a DataFlash file without an IMU record.
    let head = std::fs::read(&log).unwrap()[..5000].to_vec();
    std::fs::write(dir.join("corrupt.bin"), head).unwrap();
    std::fs::write(dir.join("notes.txt"), "not a log").unwrap();
    let json = dir.join("table.json");
    let csv = dir.join("table.csv");
    let out = delaynav(&[
        "batch",
        dir.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("2 logs, 1 replayed, 1 failed to read"),
        "{stderr}"
    );
    let table: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        (table["logs"].as_u64(), table["failed"].as_u64()),
        (Some(2), Some(1))
    );
    let rows = table["rows"].as_array().unwrap();
    assert!(rows[0]["file"].as_str().unwrap().ends_with("corrupt.bin"));
    assert!(rows[0]["error"].as_str().unwrap().contains("corrupt.bin"));
    let good = &rows[1];
    assert!(good["error"].is_null());
    let to = good["vehicle_window_s"][1].as_f64().unwrap();
    assert!(to <= 230.0, "{good}");
    assert!(
        good["proposed"]["yaw_rms_deg"].as_f64().unwrap() < 5.0,
        "{good}"
    );
    let csv = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_report_is_one_self_contained_page_with_every_plot() {
    let Some(log) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("delaynav-cli-report-{}", std::process::id()));
    let page = dir.join("nested/report.html");
    let out = delaynav(&[
        "report",
        log.to_str().unwrap(),
        "-o",
        page.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let html = std::fs::read_to_string(&page).unwrap();
    for plot in [
        "attitude-roll",
        "attitude-pitch",
        "attitude-yaw",
        "delay",
        "delay-status",
        "innovations-gps",
        "innovations-mag",
        "health",
        "track",
    ] {
        assert!(
            html.contains(&format!(r#"data-plot="{plot}""#)),
            "no plot {plot}"
        );
    }
    // Nothing to fetch, no script, no NaN drawn.
    assert!(!html.contains("src=") && !html.contains("<script") && !html.contains("NaN"));
    assert!(html.contains("Scored 84.7-228.5 s"));
    assert!(html.contains("warning: the log is dated 2015-11-21"));
    std::fs::remove_dir_all(&dir).ok();
}

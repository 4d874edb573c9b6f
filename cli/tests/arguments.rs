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
    for command in ["replay", "calibrate", "simulate", "suite"] {
        let out = delaynav(&[command, "--help"]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{command}: {stdout}");
        assert!(
            stdout.contains(&format!("Examples:\n  delaynav {command}")),
            "{command}: {stdout}"
        );
    }
}

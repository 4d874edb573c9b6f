//! The CSV readers (crate format, ArduPilot export, PX4 `ulog2csv`): the
//! first byte picks the layout, the rest is split at `0xFF` bytes into the
//! layout's files, written to a directory that the reader is given.
#![no_main]

mod common;

use delaynav::replay::LogFormat;
use libfuzzer_sys::fuzz_target;

const LAYOUTS: [(LogFormat, &[&str]); 3] = [
    (
        LogFormat::Crate,
        &["imu.csv", "gps.csv", "mag.csv", "truth.csv"],
    ),
    (
        LogFormat::ArduPilot,
        &[
            "imu.csv",
            "gps.csv",
            "mag.csv",
            "gps_accuracy.csv",
            "ekf1_reference.csv",
            "imu2.csv",
        ],
    ),
    (
        LogFormat::Px4,
        &[
            "log_sensor_combined_0.csv",
            "log_vehicle_gps_position_0.csv",
            "log_vehicle_magnetometer_0.csv",
            "log_vehicle_attitude_0.csv",
        ],
    ),
];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let (format, names) = LAYOUTS[usize::from(pick) % LAYOUTS.len()];
    let dir = common::scratch().join("csv");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("csv directory");
    for (name, contents) in names.iter().zip(rest.split(|&b| b == 0xFF)) {
        std::fs::write(dir.join(name), contents).expect("write a file");
    }
    common::read_log(&[&dir], Some(format));
    common::read_log(&[&dir], None);
});

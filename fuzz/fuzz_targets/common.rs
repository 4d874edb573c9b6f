//! Shared by the targets: a scratch directory per process, and reading a
//! whole log through the public reader API (every sample, the reference,
//! the counts). Any panic is a finding; errors are expected.

use delaynav::replay::{
    ArduPilotImu, LogFiles, LogFormat, LogReader, ReaderOptions, ReferenceReader,
};
use std::path::{Path, PathBuf};

/// A scratch directory for this fuzzing process.
pub fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("delaynav-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// Reads the log at `inputs`: every sample in f64 for IMU instance 0 (with
/// the merged order checked), in f32 for instance 1, and the reference.
pub fn read_log(inputs: &[&Path], format: Option<LogFormat>) {
    for imu_instance in [0, 1] {
        let options = ReaderOptions {
            imu_instance,
            ardupilot_imu: if imu_instance == 0 {
                ArduPilotImu::First
            } else {
                ArduPilotImu::Second
            },
            gps_delay_added_us: 200_000,
            ..ReaderOptions::default()
        };
        let Ok(files) = LogFiles::locate(inputs, format, &options) else {
            continue;
        };
        if imu_instance == 0 {
            if let Ok(mut reader) = LogReader::<f64>::open(&files, &options) {
                let mut last = None;
                let mut read = 0u64;
                for event in reader.by_ref() {
                    let key = (event.time_us(), event.kind());
                    assert!(last.is_none_or(|l| l <= key), "merged stream out of order");
                    last = Some(key);
                    read += 1;
                }
                let accepted: u64 = reader.skip_counts().files().map(|(_, c)| c.accepted).sum();
                assert!(read <= accepted, "a sample that no count holds");
            }
            if let Ok(Some(reference)) = ReferenceReader::open(&files) {
                reference.for_each(drop);
            }
        } else if let Ok(reader) = LogReader::<f32>::open(&files, &options) {
            reader.for_each(drop);
        }
    }
}

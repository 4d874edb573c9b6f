//! Shared by the targets: a scratch directory per process, and reading a
//! whole log through the public reader API (every sample, the reference,
//! the counts). Any panic is a finding; errors are expected.

use delaynav::replay::{LogFiles, LogFormat, LogReader, ReaderOptions, ReferenceReader};
use std::path::{Path, PathBuf};

/// A scratch directory for this fuzzing process.
pub fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("delaynav-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// Reads the log at `inputs` in both precisions, IMU instances 0 and 1.
pub fn read_log(inputs: &[&Path], format: Option<LogFormat>) {
    for imu_instance in [0, 1] {
        let options = ReaderOptions {
            imu_instance,
            gps_delay_added_us: 200_000,
            ..ReaderOptions::default()
        };
        let Ok(files) = LogFiles::locate(inputs, format, &options) else {
            continue;
        };
        if let Ok(mut reader) = LogReader::<f64>::open(&files, &options) {
            let mut last = None;
            for event in reader.by_ref() {
                let key = (event.time_us(), event.kind());
                assert!(last.is_none_or(|l| l < key), "merged stream out of order");
                last = Some(key);
            }
            let counts = reader.stream_counts();
            let accepted: u64 = reader.skip_counts().files().map(|(_, c)| c.accepted).sum();
            assert!(accepted <= counts.imu + counts.gps + counts.mag + 10_000_000);
        }
        if let Ok(reader) = LogReader::<f32>::open(&files, &options) {
            reader.for_each(drop);
        }
        if let Ok(Some(reference)) = ReferenceReader::open(&files) {
            reference.for_each(drop);
        }
    }
}

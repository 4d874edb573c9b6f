//! ArduPilot DataFlash `.bin`: the parser on the bytes, then the whole
//! reader on the bytes written as a file.
#![no_main]

mod common;

use delaynav::replay::LogFormat;
use delaynav::replay::dataflash::DataFlashLog;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(log) = DataFlashLog::parse(data.to_vec()) {
        for record in log.records() {
            let _ = (record.name(), record.get("TimeUS"), record.text("Name"));
        }
        let _ = log.params();
    }
    let path = common::scratch().join("log.bin");
    std::fs::write(&path, data).expect("write the log");
    common::read_log(&[&path], Some(LogFormat::DataFlash));
});

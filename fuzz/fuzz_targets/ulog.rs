//! PX4 ULog `.ulg`: the whole reader on the bytes written as a file. Inputs
//! start with the magic so the fuzzer spends its time past the header.
#![no_main]

mod common;

use delaynav::replay::LogFormat;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("log.ulg");
    let mut bytes = b"ULog".to_vec();
    bytes.extend_from_slice(data.strip_prefix(b"ULog").unwrap_or(data));
    std::fs::write(&path, &bytes).expect("write the log");
    common::read_log(&[&path], Some(LogFormat::Ulog));
});

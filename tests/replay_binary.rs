//! replay: the binary readers (ArduPilot DataFlash `.bin`, PX4 `.ulg`) on the
//! shared real logs, against the CSV files made from the same log and
//! pyulog's counts, and on bytes crafted to be bad.
#![cfg(feature = "replay")]

mod common;

use delaynav::replay::dataflash::{DataFlashFault, DataFlashLog};
use delaynav::replay::{
    ArduPilotImu, LogFiles, LogFormat, LogReader, ReaderOptions, ReferenceReader, ReplayError,
    SensorEvent, SkipCounts, SkipKind, StreamCounts, StreamKind,
};
use delaynav::{GpsPosition, Scalar};
use std::path::{Path, PathBuf};

use common::shared_data::shared;

fn read_all<T: Scalar>(
    inputs: &[&Path],
    options: &ReaderOptions,
) -> (Vec<SensorEvent<T>>, SkipCounts, StreamCounts) {
    let mut reader = LogReader::<T>::open_paths(inputs, None, options).unwrap();
    let events: Vec<_> = reader.by_ref().collect();
    (events, reader.skip_counts().clone(), reader.stream_counts())
}

fn of_kind<T: Scalar>(events: &[SensorEvent<T>], kind: StreamKind) -> Vec<SensorEvent<T>> {
    events
        .iter()
        .copied()
        .filter(|e| e.kind() == kind)
        .collect()
}

#[test]
fn binary_logs_are_detected_by_their_first_bytes() {
    let (Some(bin), Some(ulg)) = (
        shared("ardupilot-log171/log171.bin"),
        shared("px4-pyulog-sample/sample_log_small.ulg"),
    ) else {
        return;
    };
    let options = ReaderOptions::default();
    assert_eq!(LogFormat::sniff(&bin).unwrap(), Some(LogFormat::DataFlash));
    assert_eq!(LogFormat::sniff(&ulg).unwrap(), Some(LogFormat::Ulog));
    let csv = bin.with_file_name("imu.csv");
    assert_eq!(LogFormat::sniff(&csv).unwrap(), None);
    let files = LogFiles::locate(&[&bin], None, &options).unwrap();
    assert_eq!(files.format, LogFormat::DataFlash);
    assert_eq!(files.imu, bin);
    let files = LogFiles::locate(&[&ulg], None, &options).unwrap();
    assert_eq!(files.format, LogFormat::Ulog);
    let dir = bin.parent().unwrap();
    let files = LogFiles::locate(&[dir], None, &options).unwrap();
    assert_eq!(files.format, LogFormat::ArduPilot);
}

/// The `.bin` reader gives the same IMU, GPS and magnetometer samples as the
/// CSV files converted from it, for the chosen IMU.
fn bin_matches_csv<T: Scalar>(imu: ArduPilotImu, instance: u8) {
    let Some(bin) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let dir = bin.parent().unwrap();
    let csv_options = ReaderOptions {
        ardupilot_imu: imu,
        ..ReaderOptions::default()
    };
    let bin_options = ReaderOptions {
        imu_instance: instance,
        ..ReaderOptions::default()
    };
    let (from_csv, csv_skips, _) = read_all::<T>(&[dir], &csv_options);
    let (from_bin, bin_skips, counts) = read_all::<T>(&[&bin], &bin_options);
    assert_eq!(from_bin.len(), from_csv.len());

    // IMU and magnetometer: float32 in the log, printed exactly in the CSV.
    for kind in [StreamKind::Imu, StreamKind::Mag] {
        let (a, b) = (of_kind(&from_bin, kind), of_kind(&from_csv, kind));
        assert!(a.len() > 1000, "{kind:?}: {} samples", a.len());
        assert_eq!(a.len(), b.len(), "{kind:?} counts");
        if let Some(i) = (0..a.len()).find(|&i| a[i] != b[i]) {
            panic!("{kind:?} sample {i} differs: {:?} against {:?}", a[i], b[i]);
        }
    }
    // GPS: the same fixes at the same times; values equal to the CSV's
    // printed decimals (velocity from speed and course, accuracies joined).
    let (a, b) = (
        of_kind(&from_bin, StreamKind::Gps),
        of_kind(&from_csv, StreamKind::Gps),
    );
    assert_eq!(a.len(), b.len());
    // f32 samples are rounded to 24 bits once converted.
    let relative = if T::EPS.as_f64() > 1e-10 { 1e-6 } else { 1e-9 };
    let close = |x: f64, y: f64, what: &str| {
        assert!(
            (x - y).abs() <= relative * (1.0 + y.abs()),
            "{what}: {x} against {y}"
        );
    };
    for pair in a.iter().zip(&b) {
        let (SensorEvent::Gps(g), SensorEvent::Gps(h)) = pair else {
            panic!("not GPS")
        };
        assert_eq!(g.t_us, h.t_us);
        let (GpsPosition::Geodetic(p), GpsPosition::Geodetic(q)) = (g.position, h.position) else {
            panic!("geodetic fixes expected");
        };
        close(p.lat_deg, q.lat_deg, "latitude");
        close(p.lon_deg, q.lon_deg, "longitude");
        close(p.alt_m, q.alt_m, "altitude");
        for i in 0..3 {
            let (x, y) = (g.velocity_ned_m_s[i], h.velocity_ned_m_s[i]);
            close(x.as_f64(), y.as_f64(), "velocity");
        }
        for (x, y) in [
            (g.horizontal_accuracy_m, h.horizontal_accuracy_m),
            (g.vertical_accuracy_m, h.vertical_accuracy_m),
            (g.speed_accuracy_m_s, h.speed_accuracy_m_s),
        ] {
            match (x, y) {
                (Some(x), Some(y)) => close(x.as_f64(), y.as_f64(), "accuracy"),
                (x, y) => assert_eq!(x.is_some(), y.is_some(), "accuracy presence"),
            }
        }
    }
    // The same rows were refused, for the same reasons.
    for kind in SkipKind::ALL {
        assert_eq!(bin_skips.count(kind), csv_skips.count(kind), "{kind}");
    }
    assert_eq!(counts.imu, 11_916);
    assert_eq!(counts.gps, 1_199);
    assert_eq!(counts.mag, 2_384);
}

#[test]
fn bin_matches_csv_f64() {
    bin_matches_csv::<f64>(ArduPilotImu::First, 0);
}

#[test]
fn bin_matches_csv_f32() {
    bin_matches_csv::<f32>(ArduPilotImu::First, 0);
}

#[test]
fn bin_second_imu_matches_imu2_csv() {
    bin_matches_csv::<f64>(ArduPilotImu::Second, 1);
}

#[test]
fn bin_missing_imu_instance_is_an_error() {
    let Some(bin) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let options = ReaderOptions {
        imu_instance: 5,
        ..ReaderOptions::default()
    };
    let err = LogReader::<f64>::open_paths(&[&bin], None, &options)
        .err()
        .unwrap();
    assert!(matches!(err, ReplayError::MissingRecords { .. }), "{err}");
    assert!(err.to_string().contains("IMU instance 5"), "{err}");
}

#[test]
fn bin_reference_matches_ekf1_csv() {
    let Some(bin) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let options = ReaderOptions::default();
    let open = |inputs: &[&Path]| {
        let files = LogFiles::locate(inputs, None, &options).unwrap();
        ReferenceReader::open(&files)
            .unwrap()
            .unwrap()
            .collect::<Vec<_>>()
    };
    let from_bin = open(&[&bin]);
    let from_csv = open(&[bin.parent().unwrap()]);
    assert_eq!(from_bin.len(), from_csv.len());
    assert!(from_bin.len() > 2000);
    for (a, b) in from_bin.iter().zip(&from_csv) {
        assert_eq!(a.t_us, b.t_us);
        assert!(a.attitude.angle_to(&b.attitude) < 1e-9);
        let (va, vb) = (a.velocity_ned_m_s.unwrap(), b.velocity_ned_m_s.unwrap());
        assert!((va - vb).norm() < 1e-5, "{va} {vb}");
        let (pa, pb) = (a.position_ned_m.unwrap(), b.position_ned_m.unwrap());
        assert!((pa - pb).norm() < 1e-5, "{pa} {pb}");
    }
}

#[test]
fn bin_params_hold_the_trim() {
    let Some(bin) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let params = DataFlashLog::open(&bin).unwrap().params();
    assert!(params.len() > 400);
    assert!((params["AHRS_TRIM_X"] - 0.020_519_794).abs() < 1e-6);
    assert_eq!(params["COMPASS_AUTODEC"], 1.0);
}

/// pyulog's counts of `sensor_combined`, `vehicle_gps_position` and
/// `vehicle_magnetometer` (the shared README).
fn ulog_counts<T: Scalar>(name: &str, expected: StreamCounts) {
    let Some(ulg) = shared(&format!("px4-pyulog-sample/{name}")) else {
        return;
    };
    let (events, skips, counts) = read_all::<T>(&[&ulg], &ReaderOptions::default());
    assert_eq!(counts, expected, "{skips}");
    assert!(!events.is_empty());
    // Every message read is either a sample or a counted skip.
    let accepted: u64 = skips.files().map(|(_, c)| c.accepted).sum();
    assert_eq!(accepted, events.len() as u64);
    let files = LogFiles::locate(&[&ulg], None, &ReaderOptions::default()).unwrap();
    let reference: Vec<_> = ReferenceReader::open(&files).unwrap().unwrap().collect();
    assert!(!reference.is_empty());
}

#[test]
fn ulog_events_counts_equal_pyulog() {
    ulog_counts::<f64>(
        "sample_px4_events.ulg",
        StreamCounts {
            imu: 7_783,
            gps: 583,
            mag: 459,
        },
    );
}

#[test]
fn ulog_small_counts_equal_pyulog() {
    ulog_counts::<f32>(
        "sample_log_small.ulg",
        StreamCounts {
            imu: 1_298,
            gps: 32,
            mag: 319,
        },
    );
}

// ---- crafted bytes -------------------------------------------------------

/// An `FMT` record defining `kind` as `name` with `letters` and `columns`,
/// declaring `length`.
fn fmt_record(kind: u8, length: u8, name: &str, letters: &str, columns: &str) -> Vec<u8> {
    let mut r = vec![0xA3, 0x95, 128, kind, length];
    let mut pad = |text: &str, n: usize| {
        let mut b = text.as_bytes().to_vec();
        b.resize(n, 0);
        r.extend(b);
    };
    pad(name, 4);
    pad(letters, 16);
    pad(columns, 64);
    r
}

/// A small valid log: an IMU format and `n` IMU records 20 ms apart.
fn small_log(n: u32) -> Vec<u8> {
    let mut log = fmt_record(
        131,
        3 + 4 + 24,
        "IMU",
        "Iffffff",
        "TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ",
    );
    for i in 0..n {
        log.extend([0xA3, 0x95, 131]);
        log.extend((1000 + 20 * i).to_le_bytes());
        for v in [0.01f32, 0.0, 0.0, 0.0, 0.0, -9.8] {
            log.extend(v.to_le_bytes());
        }
    }
    log
}

fn fault(bytes: Vec<u8>) -> (u64, Option<String>, DataFlashFault) {
    let e = DataFlashLog::parse(bytes).err().expect("a corrupt log");
    (e.offset, e.record, e.fault)
}

#[test]
fn dataflash_fmt_with_length_two_is_an_error_at_its_offset() {
    let mut log = small_log(3);
    let at = log.len();
    log.extend(fmt_record(200, 2, "BAD", "", ""));
    let (offset, record, why) = fault(log);
    assert_eq!(offset, at as u64);
    assert_eq!(record.as_deref(), Some("FMT"));
    assert_eq!(
        why,
        DataFlashFault::LengthMismatch {
            declared: 2,
            needed: 3
        }
    );
}

#[test]
fn dataflash_bad_bytes_are_errors_that_say_where() {
    // A bad header after three good records.
    let mut log = small_log(3);
    let at = log.len();
    log.extend([0x00, 0x12, 0x34, 0x56]);
    assert_eq!(fault(log).0, at as u64);
    // An undefined type.
    let mut log = small_log(1);
    let at = log.len();
    log.extend([0xA3, 0x95, 7, 0, 0, 0]);
    assert_eq!(
        fault(log),
        (at as u64, None, DataFlashFault::UnknownType(7))
    );
    // An unknown letter, and columns that do not match the letters.
    let (_, _, why) = fault(fmt_record(9, 4, "X", "x", "A"));
    assert_eq!(why, DataFlashFault::UnknownLetter('x'));
    let (_, _, why) = fault(fmt_record(9, 5, "X", "BB", "A"));
    assert_eq!(
        why,
        DataFlashFault::ColumnCount {
            letters: 2,
            columns: 1
        }
    );
    // 300 bogus headers do not end the log silently: the first is the error.
    let mut log = small_log(2);
    let at = log.len();
    for _ in 0..300 {
        log.extend([0xA3, 0x95, 250]);
    }
    assert_eq!(fault(log).0, at as u64);
}

#[test]
fn dataflash_truncation_and_padding_are_reported_or_ignored() {
    let dir = std::env::temp_dir().join(format!("delaynav-binary-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let options = ReaderOptions::default();
    // Cut inside the last record: the records before it are read, the cut
    // one is counted.
    let mut log = small_log(5);
    log.truncate(log.len() - 10);
    let path = dir.join("cut.bin");
    std::fs::write(&path, &log).unwrap();
    let (events, skips, counts) = read_all::<f64>(&[&path], &options);
    assert_eq!(events.len(), 4);
    assert_eq!(counts.imu, 4);
    assert_eq!(
        skips.file("cut.bin").unwrap().skipped(SkipKind::Unparsable),
        1
    );
    // Zero padding after the last record is not data.
    let mut log = small_log(5);
    log.extend([0u8; 512]);
    let path = dir.join("padded.bin");
    std::fs::write(&path, &log).unwrap();
    let (events, skips, _) = read_all::<f64>(&[&path], &options);
    assert_eq!(events.len(), 5);
    assert_eq!(skips.total(), 0);
    // A corrupt file fails to open with the offset in the message.
    let mut log = small_log(2);
    let at = log.len();
    log.extend([1, 2, 3, 4]);
    let path = dir.join("bad.bin");
    std::fs::write(&path, &log).unwrap();
    let err = LogReader::<f64>::open_paths(&[&path], None, &options)
        .err()
        .unwrap();
    assert!(err.to_string().contains(&format!("at byte {at}")), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ulog_cut_and_corrupt_files_are_reported() {
    let Some(ulg) = shared("px4-pyulog-sample/sample_log_small.ulg") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("delaynav-ulog-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bytes = std::fs::read(&ulg).unwrap();
    let options = ReaderOptions::default();
    // Cut in the middle of the data: a prefix of the samples and one
    // counted cut record, or an error; never a silent end.
    let cut = dir.join("cut.ulg");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3 + 7]).unwrap();
    let (events, skips, counts) = read_all::<f64>(&[&cut], &options);
    assert!(counts.imu > 100 && counts.imu < 1_298, "{counts:?}");
    assert!(!events.is_empty());
    assert_eq!(
        skips.file("cut.ulg").unwrap().skipped(SkipKind::Unparsable),
        1
    );
    // Header only: an error.
    let short = dir.join("short.ulg");
    std::fs::write(&short, b"ULog\x01\x12\x35").unwrap();
    let err = LogReader::<f64>::open_paths(&[&short], None, &options).err();
    assert!(
        matches!(
            err,
            Some(ReplayError::Corrupt { .. }) | Some(ReplayError::MissingRecords { .. })
        ),
        "{err:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn flight_window_of_log171_is_the_flight_before_the_crash() {
    use delaynav::replay::flight_window;
    let Some(bin) = shared("ardupilot-log171/log171.bin") else {
        return;
    };
    let options = ReaderOptions::default();
    let window = |inputs: &[&Path]| {
        flight_window(LogReader::<f64>::open_paths(inputs, None, &options).unwrap()).unwrap()
    };
    let from_bin = window(&[&bin]);
    assert_eq!(from_bin, window(&[bin.parent().unwrap()]));
    // The README: flight from about 75 s, a hard impact at about 230-245 s
    // (|acc| up to 108 m/s^2). The window starts once moving and ends before it.
    let (from_s, to_s) = (from_bin.from_us as f64 * 1e-6, from_bin.to_us as f64 * 1e-6);
    assert!((75.0..95.0).contains(&from_s), "from {from_s}");
    let impact_s = from_bin.impact_us.unwrap() as f64 * 1e-6;
    assert!((230.0..245.0).contains(&impact_s), "impact {impact_s}");
    assert!(to_s < impact_s && to_s > 220.0, "to {to_s}");
}

#[test]
fn flight_windows_of_the_ulog_samples() {
    use delaynav::replay::flight_window;
    let (Some(events), Some(small)) = (
        shared("px4-pyulog-sample/sample_px4_events.ulg"),
        shared("px4-pyulog-sample/sample_log_small.ulg"),
    ) else {
        return;
    };
    let open = |path: &Path| {
        LogReader::<f32>::open_paths(&[path], None, &ReaderOptions::default()).unwrap()
    };
    // The SITL vehicle hops: up at about 0.9 m/s, down at 0.8 m/s, no
    // horizontal motion (below 0.05 m/s).
    let hop = flight_window(open(&events)).unwrap();
    let seconds = (hop.to_us - hop.from_us) as f64 * 1e-6;
    assert!((3.0..10.0).contains(&seconds), "{hop:?}");
    assert_eq!(hop.impact_us, None);
    // The CubeOrange log never leaves the ground.
    assert_eq!(flight_window(open(&small)), None);
}

// ---- crafted ULog --------------------------------------------------------

fn ulog_message(kind: u8, body: &[u8]) -> Vec<u8> {
    let mut m = (body.len() as u16).to_le_bytes().to_vec();
    m.push(kind);
    m.extend_from_slice(body);
    m
}

/// A ULog header, optional flag bits, an IMU format and subscription.
fn ulog_head(flag_bits: Option<[u64; 3]>) -> Vec<u8> {
    let mut log = b"ULog\x01\x12\x35\x01".to_vec();
    log.extend(0u64.to_le_bytes());
    if let Some(offsets) = flag_bits {
        let mut body = vec![0u8; 16];
        body[8] = u8::from(offsets.iter().any(|&o| o != 0));
        for o in offsets {
            body.extend(o.to_le_bytes());
        }
        log.extend(ulog_message(b'B', &body));
    }
    log.extend(ulog_message(
        b'F',
        b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2",
    ));
    log.extend(ulog_message(b'A', b"\x00\x07\x00sensor_combined"));
    log
}

fn ulog_imu(t_us: u64) -> Vec<u8> {
    let mut body = 7u16.to_le_bytes().to_vec();
    body.extend(t_us.to_le_bytes());
    for v in [0.0f32, 0.0, 0.01, 0.0, 0.0, -9.8] {
        body.extend(v.to_le_bytes());
    }
    ulog_message(b'D', &body)
}

fn write_temp(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("delaynav-ulog-crafted-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn ulog_crafted_logs_read_or_say_where() {
    let options = ReaderOptions::default();
    let imu_times = |path: &Path| {
        let (events, skips, counts) = read_all::<f64>(&[path], &options);
        let times: Vec<u64> = events.iter().map(|e| e.time_us()).collect();
        (times, skips, counts)
    };
    // A clean log.
    let mut log = ulog_head(None);
    for t in [1_000, 2_000, 3_000] {
        log.extend(ulog_imu(t));
    }
    let (times, skips, _) = imu_times(&write_temp("clean.ulg", &log));
    assert_eq!(times, [1_000, 2_000, 3_000]);
    assert_eq!(skips.total(), 0);

    // Appended data: the main section ends at the offset (here in the
    // middle of a torn message), the appended section is read after it.
    let head = ulog_head(Some([0; 3]));
    let mut main = head.clone();
    main.extend(ulog_imu(1_000));
    main.extend(&ulog_imu(2_000)[..10]);
    let offset = main.len() as u64;
    let mut log = ulog_head(Some([offset, 0, 0]));
    log.extend_from_slice(&main[head.len()..]);
    log.extend(ulog_imu(5_000));
    let (times, skips, counts) = imu_times(&write_temp("appended.ulg", &log));
    assert_eq!(times, [1_000, 5_000]);
    assert_eq!(counts.imu, 2);
    assert_eq!(
        skips
            .file("appended.ulg")
            .unwrap()
            .skipped(SkipKind::Unparsable),
        1
    );

    // Corrupt: the error names the byte offset and the message type.
    let corrupt = |bytes: &[u8]| {
        let path = write_temp("corrupt.ulg", bytes);
        LogReader::<f64>::open_paths(&[&path], None, &options)
            .err()
            .unwrap()
            .to_string()
    };
    // A message appended to a valid head: the error names its offset and says why.
    for (kind, body, why) in [
        (b'Z', &b"??"[..], "'Z'"),
        (b'D', &b"\x09\x00abc"[..], "msg_id 9"),
    ] {
        let mut log = ulog_head(None);
        let at = log.len();
        log.extend(ulog_message(kind, body));
        let e = corrupt(&log);
        assert!(
            e.contains(&format!("at byte {at}")) && e.contains(why),
            "{e}"
        );
    }
    let mut log = ulog_head(None);
    log.extend(ulog_message(b'A', b"\x00\x08\x00no_such_format"));
    assert!(corrupt(&log).contains("no_such_format"));
    let e = corrupt(b"ULog\x01\x12");
    assert!(e.contains("at byte 0"), "{e}");
    // The fuzzer's finding that panicked px4-ulog 0.6.1 (an information
    // message whose key length runs past its end): read, no panic.
    let mut log = b"ULog\x01\x12\x35\x01".to_vec();
    log.extend(0u64.to_le_bytes());
    log.extend(ulog_message(b'I', b"\xF0char[40] ver"));
    log.extend(ulog_message(b'F', b"sensor_combined:uint64_t timestamp"));
    let e = corrupt(&log);
    assert!(e.contains("no sensor_combined instance 0"), "{e}");
}

//! replay: the readers on the real ArduPilot log (when `../shared` is there)
//! and on small CSV files of every layout written by the tests themselves.
#![cfg(feature = "replay")]

mod common;

use approx::assert_relative_eq;
use delaynav::geo::{euler_from_quaternion, quaternion_from_euler, roll_pitch_from_accel};
use delaynav::replay::{
    LogFiles, LogFormat, LogReader, ReaderOptions, ReferenceReader, ReplayError, SensorEvent,
    SkipCounts, SkipKind, StreamKind, ardupilot,
};
use delaynav::{GpsPosition, Scalar};
use std::path::{Path, PathBuf};

/// The real log's directory, or `None` when it is absent (a failure under
/// `CI=true`, see `common::shared_data`).
fn log171() -> Option<PathBuf> {
    common::shared_data::shared("ardupilot-log171")
}

/// The rows of a CSV file as text cells, read independently of the crate's
/// readers (plain split: the log has no quoting).
fn raw_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

fn column(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).unwrap()
}

fn read_all<T: Scalar>(dir: &Path, options: &ReaderOptions) -> (Vec<SensorEvent<T>>, SkipCounts) {
    let mut reader = LogReader::<T>::open_paths(&[dir], None, options).unwrap();
    let events: Vec<_> = reader.by_ref().collect();
    (events, reader.skip_counts().clone())
}

fn assert_time_ordered<T: Scalar>(events: &[SensorEvent<T>]) {
    for pair in events.windows(2) {
        let (a, b) = (
            (pair[0].time_us(), pair[0].kind()),
            (pair[1].time_us(), pair[1].kind()),
        );
        assert!(a < b, "merged stream out of order: {a:?} then {b:?}");
    }
}

#[test]
fn ardupilot_log_is_detected_with_its_files() {
    let Some(dir) = log171() else { return };
    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    assert_eq!(files.format, LogFormat::ArduPilot);
    assert_eq!(files.imu, dir.join("imu.csv"));
    assert_eq!(files.gps, dir.join("gps.csv"));
    assert_eq!(files.mag, Some(dir.join("mag.csv")));
    assert_eq!(files.gps_accuracy, Some(dir.join("gps_accuracy.csv")));
    assert_eq!(files.reference, Some(dir.join("ekf1_reference.csv")));
    let second = ReaderOptions {
        ardupilot_imu: delaynav::replay::ArduPilotImu::Second,
        ..ReaderOptions::default()
    };
    let files = LogFiles::locate(&[&dir], Some(LogFormat::ArduPilot), &second).unwrap();
    assert_eq!(files.imu, dir.join("imu2.csv"));
}

fn ardupilot_counts_match_the_files<T: Scalar>() {
    let Some(dir) = log171() else { return };
    let (events, skips) = read_all::<T>(&dir, &ReaderOptions::default());
    let (_, imu_rows) = raw_rows(&dir.join("imu.csv"));
    let (gps_header, gps_rows) = raw_rows(&dir.join("gps.csv"));
    let (_, mag_rows) = raw_rows(&dir.join("mag.csv"));
    let fix = column(&gps_header, "fix_status");
    let with_fix = gps_rows
        .iter()
        .filter(|r| r[fix].parse::<f64>().unwrap() >= 3.0)
        .count();

    let count = |k: StreamKind| events.iter().filter(|e| e.kind() == k).count();
    assert_eq!(count(StreamKind::Imu), imu_rows.len());
    assert_eq!(count(StreamKind::Mag), mag_rows.len());
    assert_eq!(count(StreamKind::Gps), with_fix);
    assert!(with_fix > 1000 && with_fix < gps_rows.len());

    let gps = skips.file("gps.csv").unwrap();
    assert_eq!(gps.accepted as usize, with_fix);
    assert_eq!(
        gps.skipped(SkipKind::NoFix) as usize,
        gps_rows.len() - with_fix
    );
    assert_eq!(gps.skipped_total(), gps.skipped(SkipKind::NoFix));
    assert_eq!(skips.file("imu.csv").unwrap().skipped_total(), 0);
    assert_eq!(skips.file("mag.csv").unwrap().skipped_total(), 0);
    assert_time_ordered(&events);
}

#[test]
fn ardupilot_counts_match_the_files_f64() {
    ardupilot_counts_match_the_files::<f64>();
}

#[test]
fn ardupilot_counts_match_the_files_f32() {
    ardupilot_counts_match_the_files::<f32>();
}

#[test]
fn ardupilot_accuracy_duplicates_are_counted() {
    let Some(dir) = log171() else { return };
    let (_, rows) = raw_rows(&dir.join("gps_accuracy.csv"));
    let repeats = rows.windows(2).filter(|w| w[0][0] == w[1][0]).count();
    assert!(repeats > 0, "log171's gps_accuracy.csv repeats timestamps");
    let (_, skips) = read_all::<f64>(&dir, &ReaderOptions::default());
    let acc = skips.file("gps_accuracy.csv").unwrap();
    assert_eq!(acc.skipped(SkipKind::Duplicate) as usize, repeats);
    assert_eq!(skips.count(SkipKind::Duplicate) as usize, repeats);
    // The report prints every file with its kinds.
    let report = skips.to_string();
    println!("{report}");
    assert!(
        report.contains("gps.csv:") && report.contains("no_fix"),
        "{report}"
    );
    assert!(report.contains("duplicate"), "{report}");
}

#[test]
fn ardupilot_first_fix_has_file_values_and_joined_accuracy() {
    let Some(dir) = log171() else { return };
    let (header, rows) = raw_rows(&dir.join("gps.csv"));
    let fix = column(&header, "fix_status");
    let first = rows
        .iter()
        .find(|r| r[fix].parse::<f64>().unwrap() >= 3.0)
        .unwrap();
    let value = |name: &str| first[column(&header, name)].parse::<f64>().unwrap();
    let (acc_header, acc_rows) = raw_rows(&dir.join("gps_accuracy.csv"));
    let acc = acc_rows
        .iter()
        .find(|r| r[0] == first[0])
        .expect("an accuracy row at the fix time");
    let acc_value = |name: &str| acc[column(&acc_header, name)].parse::<f64>().unwrap();

    let (events, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let gps = events
        .iter()
        .find_map(|e| {
            if let SensorEvent::Gps(g) = e {
                Some(*g)
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(gps.t_us, (value("t_s") * 1e6).round() as u64);
    // README: GPS 3D fix from about 45 s.
    assert!(
        (44.0..46.0).contains(&(gps.t_us as f64 * 1e-6)),
        "first fix at {} us",
        gps.t_us
    );
    let GpsPosition::Geodetic(g) = gps.position else {
        panic!("ArduPilot fixes are geodetic")
    };
    assert_eq!(g.lat_deg, value("lat_deg"));
    assert_eq!(g.lon_deg, value("lon_deg"));
    assert_eq!(g.alt_m, value("alt_msl_m"));
    assert_eq!(gps.velocity_ned_m_s.x, value("vel_n_m_s"));
    assert_eq!(gps.velocity_ned_m_s.y, value("vel_e_m_s"));
    assert_eq!(gps.velocity_ned_m_s.z, value("vel_d_m_s"));
    assert_eq!(gps.horizontal_accuracy_m, Some(acc_value("hAcc_m")));
    assert_eq!(gps.vertical_accuracy_m, Some(acc_value("vAcc_m")));
    assert_eq!(gps.speed_accuracy_m_s, Some(acc_value("sAcc_m_s")));
    // Every fix found an accuracy row within 50 ms (both files run at 5 Hz on one clock).
    let joined = events
        .iter()
        .filter(|e| matches!(e, SensorEvent::Gps(g) if g.horizontal_accuracy_m.is_some()))
        .count();
    let fixes = events
        .iter()
        .filter(|e| e.kind() == StreamKind::Gps)
        .count();
    assert_eq!(joined, fixes);
}

#[test]
fn ardupilot_velocity_matches_speed_and_course() {
    // The file's NED columns agree with its speed/course columns, which the
    // reader uses when the NED columns are absent.
    let Some(dir) = log171() else { return };
    let (header, rows) = raw_rows(&dir.join("gps.csv"));
    let get = |r: &Vec<String>, n: &str| r[column(&header, n)].parse::<f64>().unwrap();
    let mut checked = 0;
    for r in rows.iter().filter(|r| get(r, "speed_m_s") > 2.0) {
        let (s, c) = (get(r, "speed_m_s"), get(r, "course_deg").to_radians());
        assert_relative_eq!(get(r, "vel_n_m_s"), s * c.cos(), epsilon = 1e-3);
        assert_relative_eq!(get(r, "vel_e_m_s"), s * c.sin(), epsilon = 1e-3);
        checked += 1;
    }
    assert!(checked > 100, "only {checked} moving rows");
}

/// `drop_mag` (the replay's `--no-mag`) leaves every IMU and GPS record and no magnetometer one.
#[test]
fn dropping_the_magnetometer_keeps_every_other_record() {
    let Some(dir) = log171() else { return };
    let (all, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let options = ReaderOptions {
        drop_mag: true,
        ..ReaderOptions::default()
    };
    let (without, _) = read_all::<f64>(&dir, &options);
    let is_mag = |e: &&SensorEvent<f64>| matches!(e, SensorEvent::Mag(_));
    assert!(all.iter().filter(is_mag).count() > 1000);
    assert_eq!(without.iter().filter(is_mag).count(), 0);
    let others: Vec<&SensorEvent<f64>> = all.iter().filter(|e| !is_mag(e)).collect();
    assert_eq!(without.iter().collect::<Vec<_>>(), others);
}

#[test]
fn ardupilot_magnetometer_is_in_gauss() {
    let Some(dir) = log171() else { return };
    let (header, rows) = raw_rows(&dir.join("mag.csv"));
    let x0 = rows[0][column(&header, "mag_x_mGauss")]
        .parse::<f64>()
        .unwrap();
    let (events, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let mags: Vec<f64> = events
        .iter()
        .filter_map(|e| {
            if let SensorEvent::Mag(m) = e {
                Some(m.field_body.norm())
            } else {
                None
            }
        })
        .collect();
    let first = events
        .iter()
        .find_map(|e| {
            if let SensorEvent::Mag(m) = e {
                Some(*m)
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(first.field_body.x, x0 / 1000.0);
    let mut sorted = mags.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    // Earth's field at Canberra is about 0.58 gauss; a magnetometer reads
    // within a few tens of percent of it.
    assert!((0.3..0.9).contains(&median), "median |mag| {median} gauss");
}

#[test]
fn ardupilot_added_gps_delay_shifts_fixes_only() {
    let Some(dir) = log171() else { return };
    let (plain, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let options = ReaderOptions {
        gps_delay_added_us: 300_000,
        ..ReaderOptions::default()
    };
    let (delayed, skips) = read_all::<f64>(&dir, &options);
    assert_eq!(plain.len(), delayed.len());
    assert_time_ordered(&delayed);
    let times = |events: &[SensorEvent<f64>], k| -> Vec<u64> {
        events
            .iter()
            .filter(|e| e.kind() == k)
            .map(|e| e.time_us())
            .collect()
    };
    for (a, b) in times(&plain, StreamKind::Gps)
        .iter()
        .zip(times(&delayed, StreamKind::Gps))
    {
        assert_eq!(a + 300_000, b);
    }
    assert_eq!(
        times(&plain, StreamKind::Imu),
        times(&delayed, StreamKind::Imu)
    );
    assert!(skips.count(SkipKind::NoFix) > 0);
}

#[test]
fn ardupilot_gps_delay_added_from_a_time_shifts_later_fixes_only() {
    let Some(dir) = log171() else { return };
    let (plain, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let options = ReaderOptions::default()
        .with_added_gps_delay(0.2, Some(150.0))
        .unwrap();
    assert_eq!(options.gps_delay_added_us, 200_000);
    assert_eq!(options.gps_delay_added_from_us, 150_000_000);
    let (stepped, _) = read_all::<f64>(&dir, &options);
    assert_eq!(plain.len(), stepped.len());
    assert_time_ordered(&stepped);
    let fixes = |events: &[SensorEvent<f64>]| -> Vec<u64> {
        events
            .iter()
            .filter(|e| e.kind() == StreamKind::Gps)
            .map(|e| e.time_us())
            .collect()
    };
    let (before, after) = (fixes(&plain), fixes(&stepped));
    assert_eq!(before.len(), after.len());
    let mut shifted = 0;
    for (a, b) in before.iter().zip(&after) {
        let expected = if *a >= 150_000_000 { a + 200_000 } else { *a };
        assert_eq!(*b, expected);
        shifted += usize::from(*a >= 150_000_000);
    }
    assert!(
        shifted > 100 && shifted < before.len(),
        "{shifted} fixes shifted"
    );
}

#[test]
fn added_gps_delay_options_are_checked() {
    let base = ReaderOptions::default();
    for (delay, from) in [
        (-0.1, None),
        (f64::NAN, None),
        (f64::INFINITY, None),
        (0.2, Some(-1.0)),
        (0.2, Some(f64::NAN)),
        (0.2, Some(f64::NEG_INFINITY)),
    ] {
        let err = base.with_added_gps_delay(delay, from).unwrap_err();
        assert!(
            matches!(err, ReplayError::InvalidSeconds { .. }),
            "{delay} from {from:?}: {err}"
        );
    }
    let err = base.with_added_gps_delay(0.2, Some(-1.0)).unwrap_err();
    assert!(
        err.to_string().contains("start of the added GPS delay"),
        "{err}"
    );
    // Huge values saturate instead of overflowing, and so does the shift.
    let huge = base.with_added_gps_delay(1e300, Some(1e300)).unwrap();
    assert_eq!(huge.gps_delay_added_us, u64::MAX);
    assert_eq!(huge.gps_delay_added_from_us, u64::MAX);
    let from_start = base.with_added_gps_delay(0.25, None).unwrap();
    assert_eq!(
        (
            from_start.gps_delay_added_us,
            from_start.gps_delay_added_from_us
        ),
        (250_000, 0)
    );
    let dir = temp_dir("huge-delay");
    write(
        &dir,
        "imu.csv",
        "t_us,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2\n\
         0,0,0,0,0,0,-9.8\n",
    );
    write(
        &dir,
        "gps.csv",
        "t_us,lat_deg,lon_deg,alt_m,vel_n_m_s,vel_e_m_s,vel_d_m_s\n10,1,2,3,0,0,0\n",
    );
    let shifted = base.with_added_gps_delay(1e300, None).unwrap();
    let events: Vec<SensorEvent<f64>> = LogReader::open_paths(&[&dir], None, &shifted)
        .unwrap()
        .collect();
    assert_eq!(events.len(), 2);
    assert_eq!(events[1].time_us(), u64::MAX);
}

#[test]
fn ardupilot_reference_and_trim() {
    let Some(dir) = log171() else { return };
    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    let mut params_skips = SkipCounts::default();
    let params = ardupilot::read_params(files.params.as_ref().unwrap(), &mut params_skips).unwrap();
    assert_eq!(params_skips.total(), 0);
    let alignment =
        ardupilot::alignment_from_params(&params, ardupilot::LOG171_ALIGNMENT.declination_rad);
    assert_eq!(alignment, ardupilot::LOG171_ALIGNMENT);

    let (ref_header, ref_rows) = raw_rows(&dir.join("ekf1_reference.csv"));
    let mut reference = ReferenceReader::open(&files).unwrap().unwrap();
    let samples: Vec<_> = reference.by_ref().collect();
    assert_eq!(samples.len(), ref_rows.len());
    assert_eq!(reference.skip_counts().total(), 0);
    let roll0 = ref_rows[0][column(&ref_header, "roll_deg")]
        .parse::<f64>()
        .unwrap();
    assert_relative_eq!(
        euler_from_quaternion(samples[0].attitude.quaternion())
            .x
            .to_degrees(),
        roll0,
        epsilon = 1e-9
    );
    assert!(
        samples
            .iter()
            .all(|s| s.velocity_ned_m_s.is_some() && s.position_ned_m.is_some())
    );

    // On the ground (50-70 s) the accelerometer's roll and pitch describe the
    // IMU frame; aligned by the trim they match the onboard attitude far
    // better than unaligned (README: 2.68/1.46 deg against 1.45/1.10 deg).
    let (events, _) = read_all::<f64>(&dir, &ReaderOptions::default());
    let ground = |t: u64| (50_000_000..70_000_000).contains(&t);
    let (mut sum_roll, mut sum_pitch, mut n) = (0.0, 0.0, 0.0);
    for e in &events {
        if let SensorEvent::Imu(imu) = e
            && ground(imu.t_us)
        {
            let (r, p) = roll_pitch_from_accel(&imu.accel_m_s2);
            sum_roll += r;
            sum_pitch += p;
            n += 1.0;
        }
    }
    let ref_ground: Vec<_> = samples.iter().filter(|s| ground(s.t_us)).collect();
    let ref_mean = |i: usize| {
        ref_ground
            .iter()
            .map(|s| euler_from_quaternion(s.attitude.quaternion())[i])
            .sum::<f64>()
            / ref_ground.len() as f64
    };
    let imu_attitude = quaternion_from_euler(sum_roll / n, sum_pitch / n, 0.0);
    let aligned = euler_from_quaternion(
        alignment
            .align_estimate(&imu_attitude, alignment.declination_rad)
            .quaternion(),
    );
    let (raw_gap, aligned_gap) = (
        (
            (sum_roll / n - ref_mean(0)).to_degrees(),
            (sum_pitch / n - ref_mean(1)).to_degrees(),
        ),
        (
            (aligned.x - ref_mean(0)).to_degrees(),
            (aligned.y - ref_mean(1)).to_degrees(),
        ),
    );
    println!("ground gaps, deg (roll, pitch): unaligned {raw_gap:?}, aligned {aligned_gap:?}");
    assert!(raw_gap.0.abs() > 0.9, "unaligned roll gap {raw_gap:?}");
    assert!(
        aligned_gap.0.abs() < 0.1 && aligned_gap.1.abs() < 0.1,
        "aligned gaps {aligned_gap:?}"
    );
    assert!(aligned_gap.1.abs() < raw_gap.1.abs());
}

#[test]
fn alignment_rotates_yaw_by_the_missing_declination() {
    let a = ardupilot::LOG171_ALIGNMENT;
    let q = quaternion_from_euler(0.1, -0.2, 0.5);
    let aligned = a.align_estimate(&(q * a.trim()), 0.0);
    let e = euler_from_quaternion(aligned.quaternion());
    assert_relative_eq!(e.x, 0.1, epsilon = 1e-12);
    assert_relative_eq!(e.y, -0.2, epsilon = 1e-12);
    assert_relative_eq!(e.z, 0.5 + a.declination_rad, epsilon = 1e-12);
    // An estimator already configured with the declination needs no yaw turn.
    let same = a.align_estimate(&(q * a.trim()), a.declination_rad);
    assert_relative_eq!(same.angle_to(&q), 0.0, epsilon = 1e-12);
}

// ---------------------------------------------------------------------------
// Small files written by the tests.

/// A fresh, empty temporary directory for one test.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("delaynav-replay-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).unwrap();
}

#[test]
fn crate_csv_rows_ties_and_skips() {
    let dir = temp_dir("crate");
    // Columns in a free order, an extra column, and one bad row of each kind.
    write(
        &dir,
        "imu.csv",
        "acc_x_m_s2,acc_y_m_s2,acc_z_m_s2,t_us,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,extra\n\
         0.1,0.2,-9.8,1000,0.01,0.02,0.03,x\n\
         0.1,0.2,-9.8,2000,NaN,0.02,0.03,x\n\
         0.1,0.2,-9.8,2000,0.01,0.02,0.03,x\n\
         0.1,0.2,-9.8,2000,0.01,0.02,0.03,x\n\
         0.1,0.2,-9.8,1500,0.01,0.02,0.03,x\n\
         0.1,abc,-9.8,2500,0.01,0.02,0.03,x\n\
         0.1,0.2,-9.8,-3000,0.01,0.02,0.03,x\n\
         0.1,0.2,-9.8,3000,0.01,0.02,0.03,x\n",
    );
    write(
        &dir,
        "gps.csv",
        "t_us,lat_deg,lon_deg,alt_m,pos_n_m,pos_e_m,pos_d_m,vel_n_m_s,vel_e_m_s,vel_d_m_s,h_acc_m,v_acc_m,s_acc_m_s\n\
         2000,-35.36,149.16,580,1,2,3,1.5,-0.5,0.25,,,\n\
         3000,95.0,149.16,580,1,2,3,1.5,-0.5,0.25,2.5,4,0.3\n\
         3000,-35.36,149.16,580,1,2,3,1.5,-0.5,0.25,2.5,4,0.3\n\
         4000,-35.36,149.16,580,1,2,3,1.5,-0.5,0.25,0,4,0.3\n",
    );
    write(
        &dir,
        "mag.csv",
        "t_us,mag_x,mag_y,mag_z\n2000,0.2,0,0.5\n2500,0,0,0\n3000,inf,0,0.5\n",
    );

    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    assert_eq!(files.format, LogFormat::Crate);
    assert_eq!(files.reference, None);
    let mut reader = LogReader::<f64>::open(&files, &ReaderOptions::default()).unwrap();
    let events: Vec<_> = reader.by_ref().collect();
    let order: Vec<_> = events.iter().map(|e| (e.time_us(), e.kind())).collect();
    assert_eq!(
        order,
        [
            (1000, StreamKind::Imu),
            (2000, StreamKind::Imu),
            (2000, StreamKind::Mag),
            (2000, StreamKind::Gps),
            (3000, StreamKind::Imu),
            (3000, StreamKind::Gps),
        ]
    );
    let SensorEvent::Imu(imu) = events[0] else {
        panic!()
    };
    assert_eq!(imu.gyro_rad_s.as_slice(), &[0.01, 0.02, 0.03]);
    assert_eq!(imu.accel_m_s2.as_slice(), &[0.1, 0.2, -9.8]);
    let SensorEvent::Gps(first) = events[3] else {
        panic!()
    };
    assert!(
        matches!(first.position, GpsPosition::Geodetic(g) if g.lat_deg == -35.36 && g.alt_m == 580.0)
    );
    assert_eq!(first.horizontal_accuracy_m, None);
    let SensorEvent::Gps(second) = events[5] else {
        panic!()
    };
    assert_eq!(second.horizontal_accuracy_m, Some(2.5));
    assert_eq!(second.speed_accuracy_m_s, Some(0.3));

    let skips = reader.skip_counts();
    let imu = skips.file("imu.csv").unwrap();
    assert_eq!(imu.accepted, 3);
    assert_eq!(imu.skipped(SkipKind::NonFinite), 1);
    assert_eq!(imu.skipped(SkipKind::Duplicate), 1);
    assert_eq!(imu.skipped(SkipKind::TimeWentBackwards), 1);
    assert_eq!(imu.skipped(SkipKind::Unparsable), 1);
    assert_eq!(imu.skipped(SkipKind::OutOfRange), 1);
    let gps = skips.file("gps.csv").unwrap();
    // Latitude 95 deg and a zero accuracy are out of range.
    assert_eq!((gps.accepted, gps.skipped(SkipKind::OutOfRange)), (2, 2));
    let mag = skips.file("mag.csv").unwrap();
    assert_eq!(
        (
            mag.accepted,
            mag.skipped(SkipKind::OutOfRange),
            mag.skipped(SkipKind::NonFinite)
        ),
        (1, 1, 1)
    );
    assert_eq!(skips.total(), 5 + 2 + 2);
    assert_eq!(
        skips.by_kind(),
        [
            (SkipKind::Unparsable, 1),
            (SkipKind::NonFinite, 2),
            (SkipKind::OutOfRange, 4),
            (SkipKind::TimeWentBackwards, 1),
            (SkipKind::Duplicate, 1)
        ]
    );
}

#[test]
fn crate_csv_ned_positions_and_truth_reference() {
    let dir = temp_dir("crate-ned");
    write(
        &dir,
        "imu.csv",
        "t_us,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2\n10,0,0,0,0,0,-9.81\n",
    );
    write(
        &dir,
        "gps.csv",
        "t_us,pos_n_m,pos_e_m,pos_d_m,vel_n_m_s,vel_e_m_s,vel_d_m_s\n20,1.5,-2,3,0,0,0\n",
    );
    let q = quaternion_from_euler(0.1, 0.2, 0.3);
    let qq = q.quaternion();
    write(
        &dir,
        "truth.csv",
        &format!(
            "t_us,q0,q1,q2,q3,pos_n_m,pos_e_m,pos_d_m,vel_n_m_s,vel_e_m_s,vel_d_m_s\n10,{},{},{},{},1,2,3,4,5,6\n",
            qq.w, qq.i, qq.j, qq.k
        ),
    );
    let files = LogFiles::locate(
        &[
            dir.join("imu.csv"),
            dir.join("gps.csv"),
            dir.join("truth.csv"),
        ],
        None,
        &ReaderOptions::default(),
    )
    .unwrap();
    assert_eq!(files.mag, None);
    let events: Vec<SensorEvent<f32>> = LogReader::open(&files, &ReaderOptions::default())
        .unwrap()
        .collect();
    assert_eq!(events.len(), 2);
    let SensorEvent::Gps(g) = events[1] else {
        panic!()
    };
    assert!(matches!(g.position, GpsPosition::Ned(p) if p.as_slice() == [1.5f32, -2.0, 3.0]));
    let truth: Vec<_> = ReferenceReader::open(&files).unwrap().unwrap().collect();
    assert_eq!(truth.len(), 1);
    assert_relative_eq!(truth[0].attitude.angle_to(&q), 0.0, epsilon = 1e-12);
    assert_eq!(
        truth[0].velocity_ned_m_s.unwrap().as_slice(),
        &[4.0, 5.0, 6.0]
    );
}

#[test]
fn missing_files_and_columns_are_errors() {
    let dir = temp_dir("missing");
    write(
        &dir,
        "imu.csv",
        "t_us,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2\n",
    );
    let err = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            ReplayError::MissingFile {
                what: "gps.csv",
                ..
            }
        ),
        "{err}"
    );
    write(&dir, "gps.csv", "t_us,vel_n_m_s,vel_e_m_s,vel_d_m_s\n");
    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    let err = LogReader::<f64>::open(&files, &ReaderOptions::default())
        .err()
        .unwrap();
    assert!(
        matches!(&err, ReplayError::MissingColumn { column, .. } if column.contains("lat_deg")),
        "{err}"
    );
    let empty = temp_dir("unknown");
    let err = LogFiles::locate(&[empty], None, &ReaderOptions::default()).unwrap_err();
    assert!(matches!(err, ReplayError::UnknownFormat { .. }), "{err}");
    assert!(matches!(
        LogFormat::parse_choice("rosbag"),
        Err(ReplayError::UnknownFormatName(_))
    ));
    assert_eq!(LogFormat::parse_choice("auto").unwrap(), None);
}

const PX4_IMU: &str = "timestamp,gyro_rad[0],gyro_rad[1],gyro_rad[2],gyro_integral_dt,accelerometer_timestamp_relative,accelerometer_m_s2[0],accelerometer_m_s2[1],accelerometer_m_s2[2],accelerometer_integral_dt\n\
    1000000,0.01,-0.02,0.03,4000,0,0.1,-0.1,-9.8,4000\n\
    1004000,0.01,-0.02,0.03,4000,2147483647,0.1,-0.1,-9.8,4000\n\
    1008000,0.01,-0.02,0.03,4000,0,0.1,-0.1,-9.8,4000\n\
    1200000,0.01,-0.02,0.03,4000,0,0.1,-0.1,-9.8,4000\n";

const PX4_MAG: &str = "timestamp,device_id,magnetometer_ga[0],magnetometer_ga[1],magnetometer_ga[2],calibration_count\n\
    1004000,1,0.21,0.02,-0.48,1\n1004000,1,0.21,0.02,-0.48,1\n";

#[test]
fn px4_older_integer_gps_layout() {
    let dir = temp_dir("px4-old");
    write(&dir, "flight_sensor_combined_0.csv", PX4_IMU);
    write(&dir, "flight_sensor_combined_1.csv", "timestamp\n");
    write(&dir, "flight_vehicle_magnetometer_0.csv", PX4_MAG);
    write(
        &dir,
        "flight_vehicle_gps_position_0.csv",
        "timestamp,lat,lon,alt,alt_ellipsoid,s_variance_m_s,c_variance_rad,fix_type,eph,epv,hdop,vdop,vel_m_s,vel_n_m_s,vel_e_m_s,vel_d_m_s,cog_rad,vel_ned_valid,satellites_used\n\
         1000000,473977418,85455939,488123,535000,0.4,0.1,2,5.0,8.0,1.2,1.5,0,0,0,0,0,1,6\n\
         1200000,473977418,85455939,488123,535000,0.4,0.1,3,2.5,3.5,0.9,1.1,1.1,1.0,-0.4,0.2,0,1,9\n\
         1400000,473977418,85455939,488123,535000,0.4,0.1,3,2.5,3.5,0.9,1.1,1.1,1.0,-0.4,0.2,0,0,9\n",
    );
    write(
        &dir,
        "flight_vehicle_attitude_0.csv",
        "timestamp,q[0],q[1],q[2],q[3],delta_q_reset[0]\n1000000,1,0,0,0,0\n1004000,0,0,0,0,0\n",
    );
    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    assert_eq!(files.format, LogFormat::Px4);
    assert_eq!(files.imu, dir.join("flight_sensor_combined_0.csv"));
    let mut reader = LogReader::<f64>::open(&files, &ReaderOptions::default()).unwrap();
    let events: Vec<_> = reader.by_ref().collect();
    let order: Vec<_> = events.iter().map(|e| (e.time_us(), e.kind())).collect();
    assert_eq!(
        order,
        [
            (1_000_000, StreamKind::Imu),
            (1_004_000, StreamKind::Mag),
            (1_008_000, StreamKind::Imu),
            (1_200_000, StreamKind::Imu),
            (1_200_000, StreamKind::Gps),
        ]
    );
    let SensorEvent::Gps(g) = events[4] else {
        panic!()
    };
    let GpsPosition::Geodetic(p) = g.position else {
        panic!()
    };
    assert_relative_eq!(p.lat_deg, 47.397_741_8, epsilon = 1e-12);
    assert_relative_eq!(p.lon_deg, 8.545_593_9, epsilon = 1e-12);
    assert_relative_eq!(p.alt_m, 488.123, epsilon = 1e-12);
    assert_eq!(g.velocity_ned_m_s.as_slice(), &[1.0, -0.4, 0.2]);
    assert_eq!(
        (
            g.horizontal_accuracy_m,
            g.vertical_accuracy_m,
            g.speed_accuracy_m_s
        ),
        (Some(2.5), Some(3.5), Some(0.4))
    );
    let SensorEvent::Mag(m) = events[1] else {
        panic!()
    };
    assert_eq!(m.field_body.as_slice(), &[0.21, 0.02, -0.48]);

    let skips = reader.skip_counts();
    let gps = skips.file("flight_vehicle_gps_position_0.csv").unwrap();
    assert_eq!(
        (gps.skipped(SkipKind::NoFix), gps.skipped(SkipKind::Invalid)),
        (1, 1)
    );
    let imu = skips.file("flight_sensor_combined_0.csv").unwrap();
    assert_eq!((imu.accepted, imu.skipped(SkipKind::Invalid)), (3, 1));
    assert_eq!(
        skips
            .file("flight_vehicle_magnetometer_0.csv")
            .unwrap()
            .skipped(SkipKind::Duplicate),
        1
    );

    let mut reference = ReferenceReader::open(&files).unwrap().unwrap();
    assert_eq!(reference.by_ref().count(), 1);
    assert_eq!(reference.skip_counts().count(SkipKind::OutOfRange), 1);
}

#[test]
fn px4_newer_degree_gps_layout() {
    let dir = temp_dir("px4-new");
    write(&dir, "log_0_sensor_combined_0.csv", PX4_IMU);
    write(
        &dir,
        "log_0_sensor_gps_0.csv",
        "timestamp,timestamp_sample,device_id,latitude_deg,longitude_deg,altitude_msl_m,altitude_ellipsoid_m,s_variance_m_s,fix_type,eph,epv,vel_n_m_s,vel_e_m_s,vel_d_m_s,vel_ned_valid\n\
         1100000,1050000,7,47.3977418,8.5455939,488.123,535.0,0.35,3,1.8,2.9,-0.5,2.0,-0.1,1\n",
    );
    let files = LogFiles::locate(&[&dir], Some(LogFormat::Px4), &ReaderOptions::default()).unwrap();
    assert_eq!(files.mag, None);
    assert_eq!(files.reference, None);
    let gps: Vec<_> = LogReader::<f32>::open(&files, &ReaderOptions::default())
        .unwrap()
        .filter_map(|e| {
            if let SensorEvent::Gps(g) = e {
                Some(g)
            } else {
                None
            }
        })
        .collect();
    assert_eq!(gps.len(), 1);
    assert_eq!(gps[0].t_us, 1_100_000);
    let GpsPosition::Geodetic(p) = gps[0].position else {
        panic!()
    };
    assert_eq!(
        (p.lat_deg, p.lon_deg, p.alt_m),
        (47.3977418, 8.5455939, 488.123)
    );
    assert_eq!(gps[0].velocity_ned_m_s.as_slice(), &[-0.5f32, 2.0, -0.1]);
    assert_eq!(gps[0].speed_accuracy_m_s, Some(0.35f32));
}

// ---------------------------------------------------------------------------
// The replay runner, with a navigator whose answers are known.

/// Reports a fixed attitude and velocity at every IMU time, refuses every
/// `refuse_every`-th IMU sample, and reports a delay that grows by 1 ms per
/// IMU sample.
struct KnownNav {
    t_us: Option<u64>,
    imu_seen: u64,
    refuse_every: u64,
    attitude: nalgebra::UnitQuaternion<f64>,
}

/// No fusion records: the replay counts its push outcomes.
impl delaynav::replay::FusionRecords<f64> for KnownNav {}

impl delaynav::Navigator<f64> for KnownNav {
    fn push_imu<I: delaynav::ImuSample<f64> + ?Sized>(
        &mut self,
        imu: &I,
    ) -> Result<(), delaynav::Error> {
        self.imu_seen += 1;
        if self.imu_seen.is_multiple_of(self.refuse_every) {
            return Err(delaynav::Error::StepTooLong {
                dt_us: 1,
                max_us: 0,
            });
        }
        self.t_us = Some(imu.time_us());
        Ok(())
    }
    fn push_gps<G: delaynav::GpsFix<f64> + ?Sized>(
        &mut self,
        gps: &G,
    ) -> Result<delaynav::GpsOutcome<f64>, delaynav::Error> {
        // Position fused, velocity rejected by the gate.
        let record = |fused| delaynav::FusionRecord {
            t_us: gps.time_us(),
            innovation: nalgebra::Vector3::zeros(),
            innovation_variance: nalgebra::Vector3::zeros(),
            test_ratio: 0.0,
            fused,
        };
        Ok(delaynav::GpsOutcome::Fused {
            position: record(true),
            velocity: record(false),
        })
    }
    fn push_mag<M: delaynav::MagSample<f64> + ?Sized>(
        &mut self,
        _: &M,
    ) -> Result<delaynav::MagOutcome<f64>, delaynav::Error> {
        Ok(delaynav::MagOutcome::Queued)
    }
    fn estimate(&self) -> Option<delaynav::Estimate<f64>> {
        Some(delaynav::Estimate {
            t_us: self.t_us?,
            attitude: self.attitude,
            position_ned_m: nalgebra::Vector3::zeros(),
            velocity_ned_m_s: nalgebra::Vector3::new(1.0, 0.0, 0.0),
            accel_bias_m_s2: nalgebra::Vector3::zeros(),
            gyro_bias_rad_s: nalgebra::Vector3::zeros(),
            covariance_diagonal: nalgebra::SVector::zeros(),
            delay_s: Some(self.imu_seen as f64 * 1e-3),
            delay_std_s: None,
        })
    }
}

#[test]
fn runner_scores_a_known_offset_and_counts_refusals() {
    use delaynav::replay::{ReferenceAlignment, ReferenceSample, RunOptions, replay};
    let imu = |t_us| {
        SensorEvent::Imu(delaynav::Imu {
            t_us,
            gyro_rad_s: nalgebra::Vector3::zeros(),
            accel_m_s2: nalgebra::Vector3::zeros(),
        })
    };
    let mut events: Vec<SensorEvent<f64>> = (0..100).map(|k| imu(k * 10_000)).collect();
    // Three fixes inside the window, one before it.
    for t_us in [50_000, 300_000, 400_000, 500_000] {
        events.push(SensorEvent::Gps(delaynav::Gps {
            t_us,
            position: GpsPosition::Ned(nalgebra::Vector3::zeros()),
            velocity_ned_m_s: nalgebra::Vector3::zeros(),
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        }));
    }
    events.sort_by_key(|e| (e.time_us(), e.kind()));
    // Reference: 2 deg more roll, 1 deg less pitch, 3 deg more yaw, 0.5 m/s slower north.
    let truth = quaternion_from_euler(0.1, 0.05, 1.0);
    let reported = quaternion_from_euler(
        0.1 + 2f64.to_radians(),
        0.05 - 1f64.to_radians(),
        1.0 + 3f64.to_radians(),
    );
    let reference: Vec<ReferenceSample> = (0..20)
        .map(|k| ReferenceSample {
            t_us: 5_000 + k * 50_000,
            attitude: reported,
            velocity_ned_m_s: Some(nalgebra::Vector3::new(0.5, 0.0, 0.0)),
            position_ned_m: None,
        })
        .collect();
    let mut nav = KnownNav {
        t_us: None,
        imu_seen: 0,
        refuse_every: 10,
        attitude: truth,
    };
    let options = RunOptions {
        start_us: Some(100_000),
        score_from_us: Some(200_000),
        end_us: Some(900_000),
        alignment: ReferenceAlignment::default(),
        ..RunOptions::default()
    };
    let mut estimates = 0;
    let summary = replay(
        &mut nav,
        events,
        Some(reference.into_iter()),
        &options,
        |_| estimates += 1,
    );
    // IMU 100 000..=900 000 us: 81 samples, every 10th refused.
    assert_eq!(summary.imu_pushed + summary.samples_refused(), 81);
    assert_eq!(summary.refused.get("StepTooLong"), Some(&8));
    assert_eq!(estimates, 81);
    assert_eq!(
        (
            summary.gps_pushed,
            summary.gps_position_fused,
            summary.gps_velocity_fused,
            summary.gps_gated
        ),
        (3, 3, 0, 3)
    );
    let rms = summary.reference_rms.unwrap();
    // Reference at 205 000 .. 855 000 us step 50 000: 14 scored.
    assert_eq!(rms.samples, 14);
    assert_relative_eq!(rms.roll_deg, 2.0, epsilon = 1e-9);
    assert_relative_eq!(rms.pitch_deg, 1.0, epsilon = 1e-9);
    assert_relative_eq!(rms.yaw_deg, 3.0, epsilon = 1e-9);
    assert_relative_eq!(rms.velocity_m_s.unwrap(), 0.5, epsilon = 1e-12);
    // 105 000 .. 155 000 us are in the window but before scoring starts.
    assert_eq!(summary.reference_unscored, 2);
    assert_eq!(summary.non_finite_estimates, 0);
    // The delay grows 1 ms per IMU sample pushed: 81 pushed.
    assert_relative_eq!(summary.final_delay_s.unwrap(), 0.081, epsilon = 1e-12);
    assert_eq!(summary.delay_track.len(), 1);

    // The alignment of log171 is applied to the estimate: an estimate equal
    // to the reference rotated into the IMU frame scores zero.
    let a = ardupilot::LOG171_ALIGNMENT;
    let imu_frame = quaternion_from_euler(0.0, 0.0, -a.declination_rad) * reported * a.trim();
    let mut nav = KnownNav {
        t_us: None,
        imu_seen: 0,
        refuse_every: u64::MAX,
        attitude: imu_frame,
    };
    let reference = (0..5).map(|k| ReferenceSample {
        t_us: 5_000 + k * 20_000,
        attitude: reported,
        velocity_ned_m_s: None,
        position_ned_m: None,
    });
    let options = RunOptions {
        alignment: a,
        ..RunOptions::default()
    };
    let summary = replay(
        &mut nav,
        (0..10).map(|k| imu(k * 10_000)),
        Some(reference),
        &options,
        |_| {},
    );
    let rms = summary.reference_rms.unwrap();
    assert_eq!((rms.samples, rms.velocity_m_s), (5, None));
    assert!(
        rms.roll_deg < 1e-9 && rms.pitch_deg < 1e-9 && rms.yaw_deg < 1e-9,
        "{rms:?}"
    );
}

#[test]
fn ardupilot_inclination_at_rest_is_canberras() {
    // Canberra's field points about 66 deg above the horizon (southern
    // hemisphere: negative inclination, World Magnetic Model).
    let Some(dir) = log171() else { return };
    let reader = LogReader::<f64>::open_paths(&[dir], None, &ReaderOptions::default()).unwrap();
    let inclination = delaynav::replay::inclination_at_rest(reader, 10_000_000)
        .unwrap()
        .to_degrees();
    println!("log171 inclination at rest: {inclination:.2} deg");
    assert!(
        (-72.0..-60.0).contains(&inclination),
        "inclination {inclination} deg"
    );
}

#[test]
fn inclination_at_rest_of_a_known_field() {
    // Level at rest: f = [0, 0, -g]; field 30 deg below the horizon, heading 40 deg.
    let (i, h) = (30f64.to_radians(), 40f64.to_radians());
    let field = nalgebra::Vector3::new(i.cos() * h.cos(), -i.cos() * h.sin(), i.sin()) * 0.5;
    let events = (0..20u64).flat_map(|k| {
        [
            SensorEvent::Imu(delaynav::Imu {
                t_us: k * 10_000,
                gyro_rad_s: nalgebra::Vector3::zeros(),
                accel_m_s2: nalgebra::Vector3::new(0.0, 0.0, -9.81),
            }),
            SensorEvent::Mag(delaynav::Mag {
                t_us: k * 10_000 + 1,
                field_body: field,
            }),
        ]
    });
    let got = delaynav::replay::inclination_at_rest::<f64>(events, 1_000_000).unwrap();
    assert_relative_eq!(got, i, epsilon = 1e-12);
}

// ---------------------------------------------------------------------------
// Every estimator through log171's flight window (75-225 s).

/// Replays the log of `files` through one estimator.
fn run_on<N: delaynav::Navigator<f64> + delaynav::replay::FusionRecords<f64>>(
    mut nav: N,
    files: &LogFiles,
    reader: &ReaderOptions,
    options: &delaynav::replay::RunOptions,
) -> delaynav::replay::RunSummary {
    let events = LogReader::open(files, reader).unwrap();
    let reference = ReferenceReader::open(files).unwrap();
    delaynav::replay::replay(&mut nav, events, reference, options, |_| {})
}

/// Every estimator of the crate, configured for log171 (its declination and
/// measured inclination), replayed with `options`. A new estimator is one
/// more entry.
fn run_every_estimator(
    dir: &Path,
    reader: &ReaderOptions,
    options: &delaynav::replay::RunOptions,
) -> Vec<(&'static str, delaynav::replay::RunSummary)> {
    let files = LogFiles::locate(&[dir], None, reader).unwrap();
    let ekf16 = log171_filter_config(&files, reader, options);
    let proposed = log171_proposed(ekf16);
    let aekf17 =
        delaynav::AugmentedEkf17::new(delaynav::AugmentedEkf17Config::with_nav(ekf16)).unwrap();
    let ekf16 = delaynav::Ekf16::new(ekf16).unwrap();
    vec![
        ("proposed", run_on(proposed, &files, reader, options)),
        ("aekf17", run_on(aekf17, &files, reader, options)),
        ("ekf16", run_on(ekf16, &files, reader, options)),
    ]
}

/// The filters' configuration for log171: its declination, its measured
/// inclination, and the hand-tuned IMU noise (docs/TUNING.md): its in-flight
/// noise, the accelerometer's raised by half (the paper's Table 3 noise made
/// the filters overconfident here: fixes gated, velocity diverging).
fn log171_filter_config(
    files: &LogFiles,
    reader: &ReaderOptions,
    options: &delaynav::replay::RunOptions,
) -> delaynav::Ekf16Config<f64> {
    let at_rest = LogReader::<f64>::open(files, reader).unwrap();
    let inclination = delaynav::replay::inclination_at_rest(at_rest, 10_000_000).unwrap();
    delaynav::Ekf16Config {
        mag_inclination_rad: inclination,
        mag_declination_rad: options.estimator_declination_rad,
        accel_noise_density: 0.05,
        gyro_noise_density: 0.005,
        ..delaynav::Ekf16Config::default()
    }
}

/// The delay-compensated navigator for log171 (its IMU runs at 50 Hz).
fn log171_proposed(ekf: delaynav::Ekf16Config<f64>) -> delaynav::DelayCompensatedNav<f64> {
    let config = delaynav::DelayCompensatedNavConfig {
        ekf,
        imu_rate_hz: 50.0,
        ..delaynav::DelayCompensatedNavConfig::default()
    };
    delaynav::DelayCompensatedNav::<f64>::new(config).unwrap()
}

fn flight_window() -> delaynav::replay::RunOptions {
    let alignment = ardupilot::LOG171_ALIGNMENT;
    delaynav::replay::RunOptions {
        start_us: Some(75_000_000),
        end_us: Some(225_000_000),
        alignment,
        estimator_declination_rad: alignment.declination_rad,
        ..delaynav::replay::RunOptions::default()
    }
}

#[test]
fn every_estimator_replays_the_flight_window_cleanly() {
    let Some(dir) = log171() else { return };
    let (header, rows) = raw_rows(&dir.join("imu.csv"));
    let t = column(&header, "t_s");
    let in_window = rows
        .iter()
        .filter(|r| (75.0..=225.0).contains(&r[t].parse::<f64>().unwrap()))
        .count() as u64;
    for (name, s) in run_every_estimator(&dir, &ReaderOptions::default(), &flight_window()) {
        println!(
            "{name}: refused {:?}, gps fused pos/vel {}/{} gated {}, rms {:?}, final delay {:?}",
            s.refused,
            s.gps_position_fused,
            s.gps_velocity_fused,
            s.gps_gated,
            s.reference_rms,
            s.final_delay_s
        );
        assert_eq!(s.samples_refused(), 0, "{name} refused {:?}", s.refused);
        assert_eq!(
            s.non_finite_estimates, 0,
            "{name} produced a non-finite estimate"
        );
        assert_eq!(s.imu_pushed, in_window, "{name}");
        assert!(s.gps_pushed > 600 && s.mag_pushed > 1400, "{name}: {s:?}");
        assert!(
            s.last_estimate_t_us.unwrap() > 224_900_000,
            "{name} stopped estimating"
        );
        let rms = s.reference_rms.expect("log171 has a reference");
        assert!(rms.samples > 1400, "{name}: {rms:?}");
        assert!(
            rms.roll_deg.is_finite()
                && rms.yaw_deg.is_finite()
                && rms.velocity_m_s.unwrap().is_finite()
        );
    }
}

#[test]
fn added_gps_delay_experiment() {
    // The paper's Table 7 on log171: 0.3 s added to every GPS receive time.
    // The crate's method must see its delay estimate grow by 0.3 s (within
    // 0.1 s; the paper's flight: +0.297 s). The augmented baseline must move
    // the right way (the paper's AEKF: +0.258 s; its change is printed).
    // An estimator without a delay estimate must get a larger tilt error:
    // it fuses fixes 0.3 s staler.
    let Some(dir) = log171() else { return };
    let plain = run_every_estimator(&dir, &ReaderOptions::default(), &flight_window());
    let added = ReaderOptions {
        gps_delay_added_us: 300_000,
        ..ReaderOptions::default()
    };
    let delayed = run_every_estimator(&dir, &added, &flight_window());
    for ((name, a), (_, b)) in plain.iter().zip(&delayed) {
        assert_eq!(b.samples_refused(), 0, "{name} refused {:?}", b.refused);
        assert_eq!(b.non_finite_estimates, 0, "{name}");
        let (ra, rb) = (a.reference_rms.unwrap(), b.reference_rms.unwrap());
        println!(
            "{name}: delay {:?} -> {:?}, rms {ra:?} -> {rb:?}",
            a.final_delay_s, b.final_delay_s
        );
        match (a.final_delay_s, b.final_delay_s) {
            (Some(da), Some(db)) => {
                let change = db - da;
                // proposed: the paper's method moved by 0.297 s (7 ms off);
                // here it must be within 15 ms (measured: 1 ms).
                let expected = if *name == "proposed" {
                    0.285..0.315
                } else {
                    // aekf17: measured +0.115 s; its first-order delayed-GPS
                    // model saturates at ~0.33 s on this flight (docs/RESULTS.md).
                    0.09..0.45
                };
                assert!(
                    expected.contains(&change),
                    "{name}: delay change {change} s for 0.3 s added, expected {expected:?}"
                );
            }
            _ => assert!(
                rb.roll_deg.hypot(rb.pitch_deg) > ra.roll_deg.hypot(ra.pitch_deg),
                "{name}: tilt error did not grow with 0.3 s more GPS delay: {ra:?} -> {rb:?}"
            ),
        }
    }
}

/// Issue 6's accuracy targets for the delay-compensated navigator on log171
/// (flight window scored from 75 s after a 30 s warm-up, as the replay
/// example runs it): roll and pitch within 2 deg RMS, yaw within 5 deg RMS of
/// the onboard EKF, the delay in 0.15-0.40 s (the crude offline checks put
/// it at 0.26-0.30 s), and added GPS delays of 0.1 and 0.2 s moving the
/// estimate by the added amount within 15 ms. No fix may be gated and the
/// velocity must stay within 1 m/s RMS of the onboard EKF's.
#[test]
fn proposed_meets_the_flight_log_targets() {
    let Some(dir) = log171() else { return };
    let window = delaynav::replay::RunOptions {
        start_us: Some(45_000_000),
        score_from_us: Some(75_000_000),
        ..flight_window()
    };
    let run = |added_us: u64| {
        let reader = ReaderOptions {
            gps_delay_added_us: added_us,
            ..ReaderOptions::default()
        };
        let (name, s) = run_every_estimator(&dir, &reader, &window).remove(0);
        assert_eq!(name, "proposed");
        s
    };
    let plain = run(0);
    let rms = plain.reference_rms.unwrap();
    println!(
        "proposed: {rms:?}, delay {:?}, gated {}",
        plain.final_delay_s, plain.gps_gated
    );
    assert!(rms.roll_deg < 2.0 && rms.pitch_deg < 2.0, "{rms:?}");
    assert!(rms.yaw_deg < 5.0, "{rms:?}");
    assert!(rms.velocity_m_s.unwrap() < 1.0, "{rms:?}");
    assert_eq!(plain.gps_gated, 0);
    let delay = plain.final_delay_s.unwrap();
    assert!((0.15..=0.40).contains(&delay), "delay {delay} s");
    for added_s in [0.1, 0.2] {
        let moved = run((added_s * 1e6) as u64).final_delay_s.unwrap() - delay;
        println!("added {added_s} s: moved {moved} s");
        assert!(
            (moved - added_s).abs() < 0.015,
            "added {added_s} s, the estimate moved {moved} s"
        );
    }
}

/// log171's flight window as `delaynav replay` runs it: replayed from
/// 45 s, scored from 75 s.
fn replay_command_window() -> delaynav::replay::RunOptions {
    delaynav::replay::RunOptions {
        start_us: Some(45_000_000),
        score_from_us: Some(75_000_000),
        ..flight_window()
    }
}

/// The proposed navigator on log171 with the filters of
/// [`log171_filter_config`]. `adapt`: the delay loop adapted to the log's
/// measured GPS rate, as `delaynav replay` configures it; else the
/// library's default delay loop.
fn proposed_on_log171(
    dir: &Path,
    adapt: bool,
    reader: &ReaderOptions,
    options: &delaynav::replay::RunOptions,
) -> delaynav::replay::RunSummary {
    let files = LogFiles::locate(&[dir], None, reader).unwrap();
    let mut config = delaynav::DelayCompensatedNavConfig {
        ekf: log171_filter_config(&files, reader, options),
        imu_rate_hz: 50.0,
        ..delaynav::DelayCompensatedNavConfig::default()
    };
    if adapt {
        let events = LogReader::<f64>::open(&files, &ReaderOptions::default()).unwrap();
        let rate = delaynav::replay::LogDefaults::measure(events, None)
            .gps_rate_hz
            .unwrap();
        config.delay_loop = config.delay_loop.adapted_to_gps_rate(rate).unwrap();
    }
    let proposed = delaynav::DelayCompensatedNav::<f64>::new(config).unwrap();
    run_on(proposed, &files, reader, options)
}

/// Issue 11 on the real log, the paper's Table 7 as `delaynav replay` runs
/// it (loop adapted to the 4.98 Hz GPS): 0.1, 0.2 and 0.3 s added to every
/// fix move the estimate by the added delay within 3 ms (measured: 0.101 /
/// 0.201 / 0.302 s; 0.286 s for 0.3 s when one second of disagreement
/// re-acquired at 5 Hz, docs/delay.md "Re-acquisition at low rates").
#[test]
fn rate_adapted_loop_moves_by_the_added_delay() {
    let Some(dir) = log171() else { return };
    let window = replay_command_window();
    let final_with = |added_s: f64| {
        let reader = ReaderOptions::default()
            .with_added_gps_delay(added_s, None)
            .unwrap();
        let summary = proposed_on_log171(&dir, true, &reader, &window);
        assert_eq!(summary.non_finite_estimates, 0);
        // One record per loop update (a 5 s window every fix from about
        // 50 s on), in time order: what `replay --delay-windows` writes.
        let windows = &summary.delay_windows;
        assert!(windows.len() > 500, "{} loop updates", windows.len());
        assert!(windows.windows(2).all(|w| w[0].t_s < w[1].t_s));
        summary
            .final_delay_s
            .expect("the navigator estimates a delay")
    };
    let plain = final_with(0.0);
    for added in [0.1, 0.2, 0.3] {
        let change = final_with(added) - plain;
        println!("{added} s added: change {change} s");
        assert!(
            (change - added).abs() <= 0.003,
            "{added} s added moved the estimate by {change} s (from {plain} s)"
        );
    }
}

/// The proposed navigator through log171's flight window (replayed from
/// 45 s, scored from 75 s, as `delaynav replay` runs it), without and with
/// 0.2 s added to the fixes received from 150 s on: (final delay without,
/// the step's summary against it). `adapt`: the delay loop adapted to the
/// log's measured GPS rate, as `delaynav replay` configures it; else the
/// library's default delay loop.
fn proposed_through_a_delay_step(
    dir: &Path,
    adapt: bool,
) -> (f64, delaynav::replay::DelayStepSummary) {
    let run = |reader: &ReaderOptions, options: &delaynav::replay::RunOptions| {
        proposed_on_log171(dir, adapt, reader, options)
    };
    let window = replay_command_window();
    let plain = run(&ReaderOptions::default(), &window);
    let without = plain.final_delay_s.unwrap();
    let reader = ReaderOptions::default()
        .with_added_gps_delay(0.2, Some(150.0))
        .unwrap();
    let step = delaynav::replay::DelayStep {
        reference_s: Some(without),
        ..delaynav::replay::DelayStep::new(reader.gps_delay_added_from_us, 0.2)
    };
    let options = delaynav::replay::RunOptions {
        delay_step: Some(step),
        ..window
    };
    let stepped = run(&reader, &options);
    // From 45 s the warm-up holds the log's 2 s IMU gap (docs/replay.md):
    // the samples around it are refused, as without the step.
    assert_eq!(stepped.refused, plain.refused);
    assert_eq!(stepped.non_finite_estimates, 0);
    let summary = stepped.delay_step.expect("the navigator estimates a delay");
    println!("without {without} s, {summary:?}");
    assert_eq!(summary.final_s, stepped.final_delay_s);
    assert_eq!(summary.target_s, Some(without + 0.2));
    (without, summary)
}

/// Issue 11 on the real log: 0.2 s added to the fixes from 150 s on (the
/// motion ends at about 200 s). The estimate must end within 10 ms of its
/// value without the added delay plus 0.2 s and stay there for good before
/// the motion ends (measured: 0.4900 s against 0.4963 s, settled 31.3 s
/// after the step).
#[test]
fn proposed_follows_a_delay_step_on_the_flight_log() {
    let Some(dir) = log171() else { return };
    let (without, step) = proposed_through_a_delay_step(&dir, false);
    let end = step.final_s.unwrap();
    assert!(
        (end - (without + 0.2)).abs() <= 0.010,
        "ended at {end} s, without the added delay {without} s"
    );
    let settled = step.settled_after_s.expect("the estimate never settled");
    assert!(settled < 50.0, "settled after {settled} s");
}

/// The same with the delay loop adapted to the log's GPS rate, as the replay
/// example runs it (4.98 Hz: the grid path, `delay::MATCHED_BELOW_HZ`; with
/// the fix-interval correlation it ended 15 ms short).
#[test]
fn proposed_follows_a_delay_step_with_the_rate_adapted_loop() {
    let Some(dir) = log171() else { return };
    let (without, step) = proposed_through_a_delay_step(&dir, true);
    let end = step.final_s.unwrap();
    assert!(
        (end - (without + 0.2)).abs() <= 0.010,
        "ended at {end} s, without the added delay {without} s"
    );
}

// ---------------------------------------------------------------------------
// The simulator writes the crate's format; the reader gives its samples back.

#[cfg(feature = "sim")]
#[test]
fn simulated_run_round_trips_through_the_crate_format() {
    use delaynav::sim::{Scenario, SimConfig, SimEvent, Simulation};
    let config = SimConfig {
        duration_s: 2.0,
        ..SimConfig::for_scenario(Scenario::High, 7)
    };
    let events: Vec<SimEvent> = Simulation::new(config.clone()).unwrap().collect();
    let dir = temp_dir("sim");
    delaynav::sim::csv::write_run(&dir, Simulation::new(config).unwrap()).unwrap();

    let files = LogFiles::locate(&[&dir], None, &ReaderOptions::default()).unwrap();
    assert_eq!(files.format, LogFormat::Crate);
    assert_eq!(files.reference, Some(dir.join("truth.csv")));
    let mut reader = LogReader::<f64>::open(&files, &ReaderOptions::default()).unwrap();
    let read: Vec<_> = reader.by_ref().collect();
    assert_eq!(reader.skip_counts().total(), 0, "{}", reader.skip_counts());
    assert_eq!(read.len(), events.len());
    let mut truths = Vec::new();
    for (got, written) in read.iter().zip(&events) {
        match (got, written) {
            (SensorEvent::Imu(a), SimEvent::Imu { sample, truth }) => {
                assert_eq!(a, sample);
                truths.push(*truth);
            }
            (SensorEvent::Mag(a), SimEvent::Mag(b)) => assert_eq!(a, b),
            (SensorEvent::Gps(a), SimEvent::Gps { fix, .. }) => assert_eq!(a, fix),
            other => panic!("stream order differs: {other:?}"),
        }
    }
    let reference: Vec<_> = ReferenceReader::open(&files).unwrap().unwrap().collect();
    assert_eq!(reference.len(), truths.len());
    for (r, t) in reference.iter().zip(&truths) {
        assert_eq!(r.t_us, t.t_us);
        assert!(r.attitude.angle_to(&t.attitude) < 1e-12);
        assert_eq!(r.velocity_ned_m_s, Some(t.velocity_m_s));
        assert_eq!(r.position_ned_m, Some(t.position_m));
    }
}

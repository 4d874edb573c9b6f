//! replay: the defaults measured from a log (`replay::defaults`), on
//! synthetic streams with known rates and noise, and on the shared logs when
//! `../shared` is there (skipped with a note otherwise).
#![cfg(feature = "replay")]

mod common;

use delaynav::replay::defaults::{BLOCK_US, time::Date};
use delaynav::replay::{
    FlightWindow, ImuNoise, LogDefaults, LogFiles, LogReader, NoiseSource, ReaderOptions,
    SensorEvent, flight_window, log_date, magnetic_model,
};
use delaynav::{Geodetic, Gps, GpsPosition, Imu, Mag};
use nalgebra::Vector3;

use common::shared_data::shared;

/// Standard normal draws from a fixed-seed generator (xorshift, Box-Muller).
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
    fn vector(&mut self, std: f64) -> Vector3<f64> {
        Vector3::new(self.next(), self.next(), self.next()) * std
    }
}

const RATE_HZ: f64 = 200.0;
const STEP_US: u64 = 5_000;
/// Per-sample standard deviations: still, then in flight.
const STILL: (f64, f64) = (0.02, 0.001);
const FLIGHT: (f64, f64) = (0.5, 0.05);

/// 20 s still, then 40 s of "flight" (noisier, and moving): IMU at 200 Hz
/// with every 10th sample dropped, GPS at 5 Hz reporting accuracies,
/// magnetometer at 50 Hz.
fn synthetic() -> (Vec<SensorEvent<f64>>, FlightWindow) {
    let mut noise = Normal(0x9E37_79B9_7F4A_7C15);
    let mut events = Vec::new();
    let take_off_us = 20_000_000;
    let end_us = 60_000_000;
    for k in 1..end_us / STEP_US {
        let t_us = k * STEP_US;
        let (accel_std, gyro_std) = if t_us < take_off_us { STILL } else { FLIGHT };
        if k % 10 != 3 {
            events.push(SensorEvent::Imu(Imu {
                t_us,
                gyro_rad_s: noise.vector(gyro_std),
                accel_m_s2: Vector3::new(0.0, 0.0, -9.80665) + noise.vector(accel_std),
            }));
        }
        if k % 4 == 0 {
            events.push(SensorEvent::Mag(Mag {
                t_us,
                field_body: Vector3::new(0.2, 0.0, 0.4),
            }));
        }
        if k % 40 == 0 {
            events.push(SensorEvent::Gps(Gps {
                t_us,
                position: GpsPosition::Geodetic(Geodetic {
                    lat_deg: 47.0,
                    lon_deg: 8.0,
                    alt_m: 500.0,
                }),
                velocity_ned_m_s: Vector3::new(
                    if t_us < take_off_us { 0.0 } else { 5.0 },
                    0.0,
                    0.0,
                ),
                horizontal_accuracy_m: Some(if k % 80 == 0 { 1.0 } else { 3.0 }),
                vertical_accuracy_m: Some(2.0),
                speed_accuracy_m_s: None,
            }));
        }
    }
    events.sort_by_key(|e| (e.time_us(), e.kind()));
    let window = FlightWindow {
        from_us: take_off_us,
        to_us: end_us,
        landing_us: end_us,
        impact_us: None,
        loss_of_control_us: None,
    };
    (events, window)
}

fn assert_close(measured: f64, expected: f64, tolerance: f64, what: &str) {
    assert!(
        (measured / expected - 1.0).abs() < tolerance,
        "{what}: measured {measured}, expected {expected}"
    );
}

#[test]
fn rates_are_median_intervals_despite_dropouts() {
    let (events, window) = synthetic();
    let d = LogDefaults::measure(events, Some(&window));
    assert_close(d.imu_rate_hz.unwrap(), RATE_HZ, 1e-9, "IMU rate");
    assert_close(d.gps_rate_hz.unwrap(), 5.0, 1e-9, "GPS rate");
    assert_close(d.mag_rate_hz.unwrap(), 50.0, 1e-9, "magnetometer rate");
    // Median of 1 m and 3 m alternating: 3 m; never reported: None.
    assert_eq!(d.gps_horizontal_accuracy_m, Some(3.0));
    assert_eq!(d.gps_vertical_accuracy_m, Some(2.0));
    assert_eq!(d.gps_speed_accuracy_m_s, None);
    assert_eq!(d.first_fix.map(|g| g.lat_deg), Some(47.0));
}

#[test]
fn stationary_and_in_flight_noise_match_the_simulated_densities() {
    let (events, window) = synthetic();
    let d = LogDefaults::measure(events, Some(&window));
    let dt = STEP_US as f64 * 1e-6;
    let still = d.stationary.expect("20 s still before take-off");
    assert!(still.to_us <= window.from_us, "{still:?}");
    assert!(still.to_us - still.from_us >= 15 * BLOCK_US, "{still:?}");
    let flight = d.in_flight.expect("a flight window");
    for axis in 0..3 {
        // Density = per-sample std * sqrt(dt), to the sampling error of a
        // few thousand differences.
        assert_close(
            still.accel_density[axis],
            STILL.0 * dt.sqrt(),
            0.05,
            "still accel",
        );
        assert_close(
            still.gyro_density[axis],
            STILL.1 * dt.sqrt(),
            0.05,
            "still gyro",
        );
        assert_close(
            flight.accel_density[axis],
            FLIGHT.0 * dt.sqrt(),
            0.05,
            "flight accel",
        );
        assert_close(
            flight.gyro_density[axis],
            FLIGHT.1 * dt.sqrt(),
            0.05,
            "flight gyro",
        );
    }
    // The flight's noise is chosen over a lower floor; a higher floor stays.
    let (noise, sources) = d.imu_noise(ImuNoise {
        accel_noise_density: 1e-4,
        gyro_noise_density: 1.0,
    });
    assert_eq!(sources, [NoiseSource::InFlight, NoiseSource::Default]);
    assert_eq!(noise.gyro_noise_density, 1.0);
    // Without a flight window the still segment is used, never below the floor.
    let (events, _) = synthetic();
    let still_only: Vec<_> = events
        .into_iter()
        .filter(|e| e.time_us() < window.from_us)
        .collect();
    let d = LogDefaults::measure(still_only, None);
    assert!(d.in_flight.is_none());
    let (_, sources) = d.imu_noise(ImuNoise {
        accel_noise_density: 1e-6,
        gyro_noise_density: 1e-6,
    });
    assert_eq!(sources, [NoiseSource::Stationary, NoiseSource::Stationary]);
}

#[test]
fn a_log_moving_from_the_start_has_no_stationary_segment() {
    let (events, _) = synthetic();
    let moving: Vec<_> = events
        .into_iter()
        .map(|e| match e {
            SensorEvent::Imu(mut s) => {
                s.gyro_rad_s.z += 0.5; // turning at 29 deg/s throughout
                SensorEvent::Imu(s)
            }
            other => other,
        })
        .collect();
    let d = LogDefaults::measure(moving, None);
    assert!(d.stationary.is_none(), "{:?}", d.stationary);
}

#[test]
fn the_magnetic_model_uses_the_nearest_covered_date_outside_its_range() {
    let canberra = Geodetic {
        lat_deg: -35.36,
        lon_deg: 149.17,
        alt_m: 580.0,
    };
    let in_range =
        Date::from_calendar_date(2024, delaynav::replay::defaults::time::Month::June, 1).unwrap();
    let m = magnetic_model(&canberra, in_range).unwrap();
    assert!(!m.date_clamped);
    assert_eq!(m.model_date, in_range);
    // Canberra: about +12.5 deg east, inclination about -66 deg.
    assert!((m.declination_rad.to_degrees() - 12.5).abs() < 1.5, "{m:?}");
    assert!(m.inclination_rad.to_degrees() < -60.0, "{m:?}");
    let old = Date::from_calendar_date(2015, delaynav::replay::defaults::time::Month::November, 21)
        .unwrap();
    let clamped = magnetic_model(&canberra, old).unwrap();
    assert!(clamped.date_clamped);
    assert!(clamped.model_date > old);
    // What clamping costs: the model's own change over its ten years here.
    let first = magnetic_model(&canberra, clamped.model_date).unwrap();
    let last =
        Date::from_calendar_date(2029, delaynav::replay::defaults::time::Month::December, 31)
            .unwrap();
    let last = magnetic_model(&canberra, last).unwrap();
    let drift = (last.declination_rad - first.declination_rad).to_degrees();
    println!(
        "Canberra declination: {:.2} deg at {}, {:.2} deg at {} ({drift:+.2} deg), 1-sigma {:.2} deg",
        first.declination_rad.to_degrees(),
        first.model_date,
        last.declination_rad.to_degrees(),
        last.model_date,
        first.declination_std_rad.to_degrees()
    );
    assert!(drift.abs() < 1.0, "{drift}");
    // Latitude out of the model: no field.
    let nowhere = Geodetic {
        lat_deg: 95.0,
        ..canberra
    };
    assert!(magnetic_model(&nowhere, in_range).is_none());
}

/// Every default derived from log171, the same from the `.bin` and from its
/// CSV export.
#[test]
fn log171_defaults_are_measured_and_equal_across_layouts() {
    let (Some(bin), Some(dir)) = (
        shared("ardupilot-log171/log171.bin"),
        shared("ardupilot-log171"),
    ) else {
        return;
    };
    let options = ReaderOptions::default();
    let mut found = Vec::new();
    for input in [bin, dir] {
        let files = LogFiles::locate(&[&input], None, &options).unwrap();
        let open = || LogReader::<f64>::open(&files, &options).unwrap();
        let window = flight_window(open()).expect("log171 flies");
        let d = LogDefaults::measure(open(), Some(&window));
        let date = log_date(&files).unwrap();
        println!(
            "{}: window {window:?}, {d:?}, date {date:?}",
            input.display()
        );
        found.push((window, d, date));
    }
    // The same but for the last digit of the first fix's longitude (the CSV
    // holds it in decimal, the .bin as 1e-7 deg integers).
    let fix = |k: usize| found[k].1.first_fix.unwrap();
    assert!((fix(0).lon_deg - fix(1).lon_deg).abs() < 1e-9);
    found[1].1.first_fix = Some(fix(0));
    assert_eq!(found[0], found[1], ".bin and CSV disagree");
    let (window, d, date) = &found[0];
    // README: flight from about 75-85 s, impact at about 230-245 s; the
    // window ends at the loss of control before it (a roll to 40 deg at 229 s),
    // the same in both layouts.
    assert!(
        (80_000_000..90_000_000).contains(&window.from_us),
        "{window:?}"
    );
    let impact = window.impact_us.expect("log171 ends in a crash");
    assert!(impact > 239_000_000, "{window:?}");
    assert_eq!(Some(window.to_us), window.loss_of_control_us);
    assert!(
        (228_000_000..=230_000_000).contains(&window.to_us),
        "{window:?}"
    );
    // README: IMU 49-50 Hz, GPS 4.9-5 Hz, magnetometer 9.8-10 Hz.
    assert!((d.imu_rate_hz.unwrap() - 50.0).abs() < 1.0, "{d:?}");
    assert!((d.gps_rate_hz.unwrap() - 5.0).abs() < 0.2, "{d:?}");
    assert!((d.mag_rate_hz.unwrap() - 10.0).abs() < 0.3, "{d:?}");
    // The receiver reports its accuracies (UBX3 / gps_accuracy.csv).
    assert!(
        d.gps_horizontal_accuracy_m
            .is_some_and(|h| h > 0.1 && h < 10.0)
    );
    assert!(d.gps_speed_accuracy_m_s.is_some());
    // README: on the ground from 45 s, flight from about 75-85 s; the still
    // segment ends before take-off and its noise is far below the flight's.
    let still = d.stationary.expect("log171 stands still before take-off");
    let flight = d.in_flight.expect("log171 flies");
    assert!(still.to_us <= window.from_us && still.to_us - still.from_us >= 10_000_000);
    for axis in 0..3 {
        assert!(still.accel_density[axis] * 5.0 < flight.accel_density[axis]);
        assert!(still.gyro_density[axis] * 5.0 < flight.gyro_density[axis]);
    }
    let (_, sources) = d.imu_noise(ImuNoise {
        accel_noise_density: 0.031,
        gyro_noise_density: 0.0013,
    });
    assert_eq!(sources, [NoiseSource::InFlight, NoiseSource::InFlight]);
    // Flown in November 2015 (GPS week 1871), outside WMM2020-2029: the
    // model at its first date, within 1 deg of the log's measured +11.8.
    let date = date.expect("log171 records the GPS week");
    assert_eq!(date.year(), 2015);
    let m = magnetic_model(&d.first_fix.unwrap(), date).unwrap();
    assert!(m.date_clamped, "{m:?}");
    assert!((m.declination_rad.to_degrees() - 11.8).abs() < 1.0, "{m:?}");
}

#[test]
fn ulog_dates_and_rates_are_read() {
    for (name, year, imu_hz) in [
        ("sample_px4_events.ulg", 2024, 250.0),
        ("sample_log_small.ulg", 2021, 204.6),
    ] {
        let Some(ulg) = shared(&format!("px4-pyulog-sample/{name}")) else {
            return;
        };
        let options = ReaderOptions::default();
        let files = LogFiles::locate(&[&ulg], None, &options).unwrap();
        let open = || LogReader::<f64>::open(&files, &options).unwrap();
        let window = flight_window(open());
        let d = LogDefaults::measure(open(), window.as_ref());
        assert_eq!(log_date(&files).unwrap().map(|d| d.year()), Some(year));
        assert!(
            (d.imu_rate_hz.unwrap() - imu_hz).abs() < 0.5,
            "{name}: {d:?}"
        );
        assert!(d.stationary.is_some(), "{name}: on the ground");
        let m = magnetic_model(&d.first_fix.unwrap(), log_date(&files).unwrap().unwrap());
        assert!(m.is_some_and(|m| !m.date_clamped), "{name}: {m:?}");
    }
}

//! Reader of the per-topic CSV files that PX4's `ulog2csv` writes, named
//! `<log>_<topic>_<instance>.csv`, with the `timestamp` column in
//! microseconds since boot (one clock for all topics). Array fields are
//! columns `field[0]`, `field[1]`, `field[2]`. The lowest instance of each
//! topic is read.
//!
//! | topic | columns read | conversion |
//! |---|---|---|
//! | `sensor_combined` | `timestamp, gyro_rad[0..2], accelerometer_m_s2[0..2]`, optional `accelerometer_timestamp_relative` | none (body FRD, rad/s, m/s²); a relative timestamp equal to `RELATIVE_TIMESTAMP_INVALID` (2147483647) marks the accelerometer invalid |
//! | `vehicle_gps_position`, else `sensor_gps` | `timestamp, fix_type, vel_[ned]_m_s`, optional `eph, epv, s_variance_m_s, vel_ned_valid`; position `latitude_deg, longitude_deg, altitude_msl_m` (newer layout) or `lat, lon` (1e-7 deg) and `alt` (mm) (older layout) | integers scaled to degrees and metres; `fix_type < 3` counted as no-fix |
//! | `vehicle_magnetometer` | `timestamp, magnetometer_ga[0..2]` | none (gauss) |
//! | `vehicle_attitude` (reference) | `timestamp, q[0..3]` | none (Hamilton, scalar first, body FRD to NED) |
//!
//! The IMU time is `timestamp` (the gyro's sample time); the accelerometer
//! offset `accelerometer_timestamp_relative` is at most a fraction of a
//! sample and is not applied. The GPS time is `timestamp`, the time the
//! driver published the fix on the autopilot's clock (its receive time),
//! which is what the delay estimators need; `eph`, `epv` and
//! `s_variance_m_s` (a standard deviation despite its name) become the fix's
//! accuracies.

use super::columns::{
    AccuracyColumns, Clock, GeodeticColumns, ImuLayout, MagLayout, RowFlag, TimeUnit, check_flags,
    imu_stream, mag_stream,
};
use super::table::{CsvTable, RowParser, RowStream, microseconds, unit_quaternion, vector3};
use super::{
    GpsRow, GpsRowPosition, LogFiles, LogFormat, ReferenceSample, ReplayError, SensorEvent,
    SensorStreams, SkipCounts, SkipKind,
};
use crate::scalar::Scalar;
use csv::StringRecord;
use std::path::{Path, PathBuf};

/// The time column of every topic, microseconds.
pub const TIME_COLUMN: &str = "timestamp";
/// IMU topic.
pub const IMU_TOPIC: &str = "sensor_combined";
/// GPS topics, in order of preference.
pub const GPS_TOPICS: [&str; 2] = ["vehicle_gps_position", "sensor_gps"];
/// Magnetometer topic.
pub const MAG_TOPIC: &str = "vehicle_magnetometer";
/// Reference attitude topic.
pub const ATTITUDE_TOPIC: &str = "vehicle_attitude";
/// `sensor_combined`'s marker of an invalid relative timestamp.
pub const RELATIVE_TIMESTAMP_INVALID: i64 = 2_147_483_647;
/// Lowest `fix_type` accepted: 3 is a 3-D fix.
pub const MIN_FIX_TYPE: f64 = 3.0;
/// `sensor_combined` gyro fields, rad/s, body FRD.
pub(crate) const GYRO_FIELDS: [&str; 3] = ["gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"];
/// `sensor_combined` accelerometer fields, m/s², body FRD.
pub(crate) const ACCEL_FIELDS: [&str; 3] = [
    "accelerometer_m_s2[0]",
    "accelerometer_m_s2[1]",
    "accelerometer_m_s2[2]",
];
/// `sensor_combined`'s accelerometer time relative to the gyro's.
pub(crate) const ACCEL_RELATIVE_FIELD: &str = "accelerometer_timestamp_relative";
/// `vehicle_magnetometer` field, gauss, body FRD.
pub(crate) const MAG_FIELDS: [&str; 3] = [
    "magnetometer_ga[0]",
    "magnetometer_ga[1]",
    "magnetometer_ga[2]",
];
/// GPS position fields of the newer layout (deg, deg, m) and the older one
/// (1e-7 deg, 1e-7 deg, mm).
pub(crate) const GPS_POSITION_FIELDS: [[&str; 3]; 2] = [
    ["latitude_deg", "longitude_deg", "altitude_msl_m"],
    ["lat", "lon", "alt"],
];
/// Factors from the older GPS layout's units to degrees, degrees and metres.
pub(crate) const OLD_GPS_POSITION_SCALE: [f64; 3] = [
    1.0 / SCALED_DEG_PER_DEG,
    1.0 / SCALED_DEG_PER_DEG,
    1.0 / MM_PER_M,
];
/// GPS velocity fields, m/s NED.
pub(crate) const GPS_VELOCITY_FIELDS: [&str; 3] = ["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"];
/// GPS horizontal, vertical and speed accuracy fields (m, m, m/s).
pub(crate) const GPS_ACCURACY_FIELDS: [&str; 3] = ["eph", "epv", "s_variance_m_s"];
/// Attitude quaternion fields, scalar first.
pub(crate) const ATTITUDE_FIELDS: [&str; 4] = ["q[0]", "q[1]", "q[2]", "q[3]"];

/// The file of `topic` with the lowest instance number, if any: a name
/// ending in `_<topic>_<digits>.csv`.
pub fn find_topic<'a>(files: &'a [PathBuf], topic: &str) -> Option<&'a PathBuf> {
    files
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_str()?;
            let stem = name.strip_suffix(".csv")?;
            let (before, instance) = stem.rsplit_once('_')?;
            let instance: u32 = instance.parse().ok()?;
            let matches = before == topic || before.ends_with(&format!("_{topic}"));
            matches.then_some((instance, p))
        })
        .min_by_key(|&(instance, _)| instance)
        .map(|(_, p)| p)
}

fn require_topic(
    files: &[PathBuf],
    topic: &'static str,
    searched: &str,
) -> Result<PathBuf, ReplayError> {
    super::required(find_topic(files, topic), topic, LogFormat::Px4, searched)
}

pub(crate) fn locate(files: &[PathBuf], searched: &str) -> Result<LogFiles, ReplayError> {
    let gps = match GPS_TOPICS.iter().find_map(|t| find_topic(files, t)) {
        Some(p) => p.clone(),
        None => require_topic(files, "vehicle_gps_position | sensor_gps", searched)?,
    };
    Ok(LogFiles {
        format: LogFormat::Px4,
        imu: require_topic(files, IMU_TOPIC, searched)?,
        gps,
        mag: find_topic(files, MAG_TOPIC).cloned(),
        gps_accuracy: None,
        reference: find_topic(files, ATTITUDE_TOPIC).cloned(),
        params: None,
    })
}

/// PX4's clock: integer microseconds since boot in `timestamp`.
const CLOCK: Clock = Clock {
    column: TIME_COLUMN,
    unit: TimeUnit::Microseconds,
};

pub(crate) fn open_streams<T: Scalar>(files: &LogFiles) -> Result<SensorStreams<T>, ReplayError> {
    let imu = ImuLayout {
        clock: CLOCK,
        gyro: GYRO_FIELDS,
        accel: ACCEL_FIELDS,
    };
    let mag = MagLayout {
        clock: CLOCK,
        field: MAG_FIELDS,
        scale: 1.0,
    };
    let accel_invalid = |table: &CsvTable| {
        vec![RowFlag {
            column: table.find(ACCEL_RELATIVE_FIELD),
            rejects: |relative| relative == RELATIVE_TIMESTAMP_INVALID as f64,
            kind: SkipKind::Invalid,
        }]
    };
    Ok(SensorStreams {
        imu: imu_stream(&files.imu, &imu, accel_invalid)?,
        gps: gps_stream(&files.gps)?,
        mag: files
            .mag
            .as_deref()
            .map(|p| mag_stream(p, &mag, |_| Vec::new()))
            .transpose()?,
    })
}

/// 1e-7 degree units per degree.
const SCALED_DEG_PER_DEG: f64 = 1e7;
/// Millimetres per metre.
const MM_PER_M: f64 = 1e3;

struct GpsColumns {
    t: usize,
    flags: [RowFlag; 2],
    position: GeodeticColumns,
    velocity: [usize; 3],
    accuracy: AccuracyColumns,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for GpsColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = microseconds(rec, self.t)?;
        check_flags(&self.flags, rec)?;
        GpsRow {
            t_us,
            position: GpsRowPosition::Geodetic(self.position.read(rec)?),
            velocity_ned_m_s: vector3(rec, self.velocity)?,
            accuracy: self.accuracy.read(rec)?,
        }
        .into_event()
    }
}

fn gps_stream<T: Scalar>(path: &Path) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let position = match table.one_of3(&GPS_POSITION_FIELDS)? {
        // Newer layout: degrees and metres.
        (0, idx) => GeodeticColumns::unscaled(idx),
        // Older layout: lat/lon in 1e-7 deg, alt in mm.
        (_, idx) => GeodeticColumns {
            idx,
            scale: OLD_GPS_POSITION_SCALE,
        },
    };
    let parser = GpsColumns {
        t: table.column(TIME_COLUMN)?,
        flags: [
            RowFlag {
                column: Some(table.column("fix_type")?),
                rejects: |fix| fix < MIN_FIX_TYPE,
                kind: SkipKind::NoFix,
            },
            RowFlag {
                column: table.find("vel_ned_valid"),
                rejects: |valid| valid == 0.0,
                kind: SkipKind::Invalid,
            },
        ],
        position,
        velocity: table.columns3(GPS_VELOCITY_FIELDS)?,
        accuracy: AccuracyColumns::find(&table, GPS_ACCURACY_FIELDS),
    };
    Ok(RowStream::new(table, Box::new(parser), "gps"))
}

struct AttitudeColumns {
    t: usize,
    q: [usize; 4],
}

impl RowParser<ReferenceSample> for AttitudeColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<ReferenceSample, SkipKind> {
        Ok(ReferenceSample {
            t_us: microseconds(rec, self.t)?,
            attitude: unit_quaternion(rec, self.q)?,
            velocity_ned_m_s: None,
            position_ned_m: None,
        })
    }
}

/// `vehicle_attitude` as a reference stream.
pub(crate) fn reference_stream(path: &Path) -> Result<RowStream<ReferenceSample>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = AttitudeColumns {
        t: table.column(TIME_COLUMN)?,
        q: table.columns4(ATTITUDE_FIELDS)?,
    };
    Ok(RowStream::new(table, Box::new(parser), "reference"))
}

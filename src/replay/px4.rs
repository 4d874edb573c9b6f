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

use super::table::{
    CsvTable, RowParser, RowStream, microseconds, number, optional_number, unit_quaternion, vector3,
};
use super::{
    GpsRow, GpsRowPosition, LogFiles, LogFormat, ReferenceSample, ReplayError, SensorEvent,
    SkipCounts, SkipKind, StreamKind, imu_event, mag_event,
};
use crate::scalar::Scalar;
use crate::sensors::Geodetic;
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
    find_topic(files, topic)
        .cloned()
        .ok_or_else(|| ReplayError::MissingFile {
            what: topic,
            format: LogFormat::Px4,
            searched: searched.to_string(),
        })
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

type Streams<T> = Vec<(StreamKind, RowStream<SensorEvent<T>>)>;

pub(crate) fn open_streams<T: Scalar>(files: &LogFiles) -> Result<Streams<T>, ReplayError> {
    let mut streams = vec![
        (StreamKind::Imu, imu_stream(&files.imu)?),
        (StreamKind::Gps, gps_stream(&files.gps)?),
    ];
    if let Some(mag) = &files.mag {
        streams.push((StreamKind::Mag, mag_stream(mag)?));
    }
    Ok(streams)
}

/// Indices of the array columns `name[0]`, `name[1]`, `name[2]`.
fn array3(table: &CsvTable, name: &str) -> Result<[usize; 3], ReplayError> {
    Ok([
        table.column(&format!("{name}[0]"))?,
        table.column(&format!("{name}[1]"))?,
        table.column(&format!("{name}[2]"))?,
    ])
}

struct ImuColumns {
    t: usize,
    gyro: [usize; 3],
    accel: [usize; 3],
    accel_relative: Option<usize>,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for ImuColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = microseconds(rec, self.t)?;
        if let Some(rel) = optional_number(rec, self.accel_relative)?
            && rel == RELATIVE_TIMESTAMP_INVALID as f64
        {
            return Err(SkipKind::Invalid);
        }
        imu_event(t_us, vector3(rec, self.gyro)?, vector3(rec, self.accel)?)
    }
}

fn imu_stream<T: Scalar>(path: &Path) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = ImuColumns {
        t: table.column(TIME_COLUMN)?,
        gyro: array3(&table, "gyro_rad")?,
        accel: array3(&table, "accelerometer_m_s2")?,
        accel_relative: table.find("accelerometer_timestamp_relative"),
    };
    Ok(RowStream::new(table, Box::new(parser), "imu"))
}

/// The two position layouts of PX4's GPS topics.
enum PositionColumns {
    /// `latitude_deg, longitude_deg, altitude_msl_m` (PX4 1.14 and later).
    Degrees([usize; 3]),
    /// `lat, lon` in 1e-7 deg, `alt` in mm (older releases).
    Scaled([usize; 3]),
}

/// 1e-7 degree units per degree.
const SCALED_DEG_PER_DEG: f64 = 1e7;
/// Millimetres per metre.
const MM_PER_M: f64 = 1e3;

struct GpsColumns {
    t: usize,
    fix: usize,
    position: PositionColumns,
    velocity: [usize; 3],
    velocity_valid: Option<usize>,
    eph: Option<usize>,
    epv: Option<usize>,
    speed_accuracy: Option<usize>,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for GpsColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = microseconds(rec, self.t)?;
        if number(rec, self.fix)? < MIN_FIX_TYPE {
            return Err(SkipKind::NoFix);
        }
        if optional_number(rec, self.velocity_valid)? == Some(0.0) {
            return Err(SkipKind::Invalid);
        }
        let geodetic = match self.position {
            PositionColumns::Degrees([lat, lon, alt]) => Geodetic {
                lat_deg: number(rec, lat)?,
                lon_deg: number(rec, lon)?,
                alt_m: number(rec, alt)?,
            },
            PositionColumns::Scaled([lat, lon, alt]) => Geodetic {
                lat_deg: number(rec, lat)? / SCALED_DEG_PER_DEG,
                lon_deg: number(rec, lon)? / SCALED_DEG_PER_DEG,
                alt_m: number(rec, alt)? / MM_PER_M,
            },
        };
        GpsRow {
            t_us,
            position: GpsRowPosition::Geodetic(geodetic),
            velocity_ned_m_s: vector3(rec, self.velocity)?,
            horizontal_accuracy_m: optional_number(rec, self.eph)?,
            vertical_accuracy_m: optional_number(rec, self.epv)?,
            speed_accuracy_m_s: optional_number(rec, self.speed_accuracy)?,
        }
        .into_event()
    }
}

fn gps_stream<T: Scalar>(path: &Path) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let position = match table.columns3(["latitude_deg", "longitude_deg", "altitude_msl_m"]) {
        Ok(idx) => PositionColumns::Degrees(idx),
        Err(_) => match table.columns3(["lat", "lon", "alt"]) {
            Ok(idx) => PositionColumns::Scaled(idx),
            Err(_) => {
                return Err(ReplayError::MissingColumn {
                    path: path.to_path_buf(),
                    column: "latitude_deg,longitude_deg,altitude_msl_m | lat,lon,alt".to_string(),
                });
            }
        },
    };
    let parser = GpsColumns {
        t: table.column(TIME_COLUMN)?,
        fix: table.column("fix_type")?,
        position,
        velocity: table.columns3(["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"])?,
        velocity_valid: table.find("vel_ned_valid"),
        eph: table.find("eph"),
        epv: table.find("epv"),
        speed_accuracy: table.find("s_variance_m_s"),
    };
    Ok(RowStream::new(table, Box::new(parser), "gps"))
}

struct MagColumns {
    t: usize,
    field: [usize; 3],
}

impl<T: Scalar> RowParser<SensorEvent<T>> for MagColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        mag_event(microseconds(rec, self.t)?, vector3(rec, self.field)?)
    }
}

fn mag_stream<T: Scalar>(path: &Path) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = MagColumns {
        t: table.column(TIME_COLUMN)?,
        field: array3(&table, "magnetometer_ga")?,
    };
    Ok(RowStream::new(table, Box::new(parser), "mag"))
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
        q: table.columns4(["q[0]", "q[1]", "q[2]", "q[3]"])?,
    };
    Ok(RowStream::new(table, Box::new(parser), "reference"))
}

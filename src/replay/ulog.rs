//! Reader of PX4 ULog binary logs (`.ulg`), on the PX4 organisation's
//! `px4-ulog` crate (see `docs/replay.md` for why).
//!
//! The topics, fields, units and checks are those of the `ulog2csv` reader
//! ([`super::px4`]): `sensor_combined` (IMU; multi-id = the IMU instance),
//! `vehicle_gps_position` (else `sensor_gps`, multi-id 0),
//! `vehicle_magnetometer` (multi-id 0) and `vehicle_attitude` (reference).
//! Every data message of those subscriptions is one row: the counts equal
//! pyulog's (tested on `../shared/data/px4-pyulog-sample`). Appended data
//! sections are read.
//!
//! # Bad bytes
//! `px4-ulog` parses the whole file when the log is opened. A header or
//! definitions section that cannot be parsed, or a malformed record in the
//! data section, is a [`ReplayError::Corrupt`] carrying the parser's
//! description (the crate reports no byte offset). A file cut inside a record
//! (power loss) keeps the records before it and counts the cut one as an
//! [`SkipKind::Unparsable`] row of the file.

use super::px4::{
    ACCEL_FIELDS, ACCEL_RELATIVE_FIELD, ATTITUDE_FIELDS, ATTITUDE_TOPIC, GPS_ACCURACY_FIELDS,
    GPS_POSITION_FIELDS, GPS_TOPICS, GPS_VELOCITY_FIELDS, GYRO_FIELDS, IMU_TOPIC, MAG_FIELDS,
    MAG_TOPIC, MIN_FIX_TYPE, OLD_GPS_POSITION_SCALE, RELATIVE_TIMESTAMP_INVALID,
};
use super::table::{RowStream, file_label, quaternion_wxyz};
use super::{
    GpsRow, GpsRowPosition, ReferenceSample, ReplayError, SensorEvent, SensorStreams, SkipCounts,
    SkipKind, imu_event, mag_event,
};
use crate::scalar::Scalar;
use crate::sensors::Geodetic;
use nalgebra::Vector3;
use px4_ulog::stream_parser::model::{Completeness, FlattenedFieldType, FlattenedFormat};
use px4_ulog::stream_parser::{DataMessage, Message, SimpleCallbackResult};
use std::collections::HashMap;
use std::path::Path;

/// The first bytes of every ULog file.
pub const MAGIC: &[u8] = b"ULog";

/// One data message of a wanted topic: its timestamp and the wanted fields
/// (`None` when the topic lacks a field or it is not a number).
struct Row {
    t_us: Option<u64>,
    values: Vec<Option<f64>>,
}

/// How to read the wanted fields out of one subscription's messages.
struct Plan {
    topic: usize,
    multi_id: u8,
    fields: Vec<Option<(FlattenedFieldType, usize)>>,
    timestamp: Option<usize>,
}

/// What is read from a log: for each topic, the fields wanted.
struct Wanted<'w> {
    topics: &'w [(&'static str, Vec<&'static str>)],
}

/// The rows of the wanted topics by `(topic index, multi-id)`, and whether
/// the file was cut inside a record.
struct Decoded {
    rows: HashMap<(usize, u8), Vec<Row>>,
    truncated: bool,
}

impl Decoded {
    fn take(&mut self, topic: usize, multi_id: u8) -> Option<Vec<Row>> {
        self.rows.remove(&(topic, multi_id))
    }
}

fn plan(format: &FlattenedFormat, topic: usize, multi_id: u8, wanted: &[&str]) -> Plan {
    let find = |name: &str| {
        format
            .field_iter()
            .find(|f| f.flattened_field_name == name)
            .map(|f| (f.field_type.clone(), usize::from(f.offset)))
    };
    Plan {
        topic,
        multi_id,
        fields: wanted.iter().map(|n| find(n)).collect(),
        timestamp: format
            .timestamp_field
            .as_ref()
            .map(|t| usize::from(t.offset)),
    }
}

/// `N` bytes at `offset`, if the message holds them.
fn bytes_at<const N: usize>(data: &[u8], offset: usize) -> Option<[u8; N]> {
    data.get(offset..offset.checked_add(N)?)?.try_into().ok()
}

/// A field's value as a number.
fn value(data: &[u8], kind: &FlattenedFieldType, offset: usize) -> Option<f64> {
    use FlattenedFieldType as F;
    Some(match kind {
        F::Int8 => f64::from(i8::from_le_bytes(bytes_at(data, offset)?)),
        F::UInt8 | F::Bool => f64::from(u8::from_le_bytes(bytes_at(data, offset)?)),
        F::Int16 => f64::from(i16::from_le_bytes(bytes_at(data, offset)?)),
        F::UInt16 => f64::from(u16::from_le_bytes(bytes_at(data, offset)?)),
        F::Int32 => f64::from(i32::from_le_bytes(bytes_at(data, offset)?)),
        F::UInt32 => f64::from(u32::from_le_bytes(bytes_at(data, offset)?)),
        F::Int64 => i64::from_le_bytes(bytes_at(data, offset)?) as f64,
        F::UInt64 => u64::from_le_bytes(bytes_at(data, offset)?) as f64,
        F::Float => f64::from(f32::from_le_bytes(bytes_at(data, offset)?)),
        F::Double => f64::from_le_bytes(bytes_at(data, offset)?),
        F::Char => return None,
    })
}

fn row(plan: &Plan, msg: &DataMessage<'_>) -> Row {
    Row {
        t_us: plan
            .timestamp
            .and_then(|o| bytes_at(msg.data, o))
            .map(u64::from_le_bytes),
        values: plan
            .fields
            .iter()
            .map(|f| f.as_ref().and_then(|(kind, o)| value(msg.data, kind, *o)))
            .collect(),
    }
}

/// Parses the log at `path`, keeping the wanted topics' rows.
fn decode(path: &Path, wanted: &Wanted<'_>) -> Result<Decoded, ReplayError> {
    let corrupt = |reason: String| ReplayError::Corrupt {
        path: path.to_path_buf(),
        offset: None,
        record: None,
        reason,
    };
    let name = path.to_str().ok_or_else(|| ReplayError::Open {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "path is not UTF-8"),
    })?;
    let mut plans: HashMap<u16, Plan> = HashMap::new();
    let mut rows: HashMap<(usize, u8), Vec<Row>> = HashMap::new();
    let mut callback = |message: &Message<'_>| {
        if let Message::Data(msg) = message {
            let format = msg.flattened_format;
            let multi_id = msg.multi_id.value();
            let stale = plans.get(&msg.msg_id).is_none_or(|p| {
                p.multi_id != multi_id || wanted.topics[p.topic].0 != format.message_name()
            });
            if stale {
                plans.remove(&msg.msg_id);
                if let Some(topic) = wanted
                    .topics
                    .iter()
                    .position(|(t, _)| *t == format.message_name())
                {
                    let p = plan(format, topic, multi_id, &wanted.topics[topic].1);
                    plans.insert(msg.msg_id, p);
                }
            }
            if let Some(p) = plans.get(&msg.msg_id) {
                rows.entry((p.topic, p.multi_id))
                    .or_default()
                    .push(row(p, msg));
            }
        }
        SimpleCallbackResult::KeepReading
    };
    let completeness = px4_ulog::stream_parser::read_file_with_simple_callback(name, &mut callback)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound | std::io::ErrorKind::PermissionDenied => {
                ReplayError::Open {
                    path: path.to_path_buf(),
                    source: e,
                }
            }
            _ => corrupt(format!("header or definitions: {e}")),
        })?;
    match completeness {
        Completeness::Complete => Ok(Decoded {
            rows,
            truncated: false,
        }),
        Completeness::Truncated => Ok(Decoded {
            rows,
            truncated: true,
        }),
        Completeness::MalformedRecord(why) => Err(corrupt(format!("malformed record: {why}"))),
    }
}

/// The value of field `i` of a row, or why the row is skipped.
fn required(row: &Row, i: usize) -> Result<f64, SkipKind> {
    row.values[i].ok_or(SkipKind::Unparsable)
}

fn vector(row: &Row, first: usize) -> Result<Vector3<f64>, SkipKind> {
    Ok(Vector3::new(
        required(row, first)?,
        required(row, first + 1)?,
        required(row, first + 2)?,
    ))
}

fn time(row: &Row) -> Result<u64, SkipKind> {
    row.t_us.ok_or(SkipKind::Unparsable)
}

/// IMU fields: gyro (0-2), accelerometer (3-5), accelerometer relative time (6).
fn imu_fields() -> Vec<&'static str> {
    GYRO_FIELDS
        .into_iter()
        .chain(ACCEL_FIELDS)
        .chain([ACCEL_RELATIVE_FIELD])
        .collect()
}

/// GPS fields: fix type (0), velocity valid (1), new position (2-4), old
/// position (5-7), velocity (8-10), accuracies (11-13).
fn gps_fields() -> Vec<&'static str> {
    ["fix_type", "vel_ned_valid"]
        .into_iter()
        .chain(GPS_POSITION_FIELDS[0])
        .chain(GPS_POSITION_FIELDS[1])
        .chain(GPS_VELOCITY_FIELDS)
        .chain(GPS_ACCURACY_FIELDS)
        .collect()
}

fn imu_row<T: Scalar>(row: &Row) -> Result<SensorEvent<T>, SkipKind> {
    let t_us = time(row)?;
    if row.values[6] == Some(RELATIVE_TIMESTAMP_INVALID as f64) {
        return Err(SkipKind::Invalid);
    }
    imu_event(t_us, vector(row, 0)?, vector(row, 3)?)
}

fn gps_row<T: Scalar>(row: &Row) -> Result<SensorEvent<T>, SkipKind> {
    let t_us = time(row)?;
    if required(row, 0)? < MIN_FIX_TYPE {
        return Err(SkipKind::NoFix);
    }
    if row.values[1] == Some(0.0) {
        return Err(SkipKind::Invalid);
    }
    let position = match vector(row, 2) {
        Ok(p) => p,
        Err(_) => vector(row, 5)?.component_mul(&Vector3::from(OLD_GPS_POSITION_SCALE)),
    };
    GpsRow {
        t_us,
        position: GpsRowPosition::Geodetic(Geodetic {
            lat_deg: position.x,
            lon_deg: position.y,
            alt_m: position.z,
        }),
        velocity_ned_m_s: vector(row, 8)?,
        accuracy: [row.values[11], row.values[12], row.values[13]],
    }
    .into_event()
}

fn mag_row<T: Scalar>(row: &Row) -> Result<SensorEvent<T>, SkipKind> {
    mag_event(time(row)?, vector(row, 0)?)
}

/// The IMU, GPS and magnetometer streams of a log, and the cut record if any.
pub(crate) fn open_streams<T: Scalar>(
    path: &Path,
    imu_instance: u8,
) -> Result<(SensorStreams<T>, SkipCounts), ReplayError> {
    let mut topics = vec![(IMU_TOPIC, imu_fields()), (MAG_TOPIC, MAG_FIELDS.to_vec())];
    topics.extend(GPS_TOPICS.iter().map(|&t| (t, gps_fields())));
    let mut decoded = decode(path, &Wanted { topics: &topics })?;
    let file = file_label(path);
    let mut skips = SkipCounts::default();
    if decoded.truncated {
        skips.skip(&file, SkipKind::Unparsable);
    }
    let imu = decoded
        .take(0, imu_instance)
        .ok_or_else(|| ReplayError::MissingRecords {
            path: path.to_path_buf(),
            what: format!("{IMU_TOPIC} instance {imu_instance}"),
        })?;
    let (gps_topic, gps) = (2..topics.len())
        .find_map(|i| decoded.take(i, 0).map(|rows| (topics[i].0, rows)))
        .unwrap_or((GPS_TOPICS[0], Vec::new()));
    let mag = decoded.take(1, 0);
    let stream = |rows: Vec<Row>, topic: &str, kind, parse: fn(&Row) -> _| {
        RowStream::decoded(
            rows.iter().map(parse).collect(),
            format!("{file}:{topic}"),
            kind,
        )
    };
    let streams = SensorStreams {
        imu: stream(imu, IMU_TOPIC, "imu", imu_row::<T>),
        gps: stream(gps, gps_topic, "gps", gps_row::<T>),
        mag: mag.map(|rows| stream(rows, MAG_TOPIC, "mag", mag_row::<T>)),
    };
    Ok((streams, skips))
}

/// `vehicle_attitude` (multi-id 0) as a reference stream.
pub(crate) fn reference_stream(path: &Path) -> Result<RowStream<ReferenceSample>, ReplayError> {
    let topics = [(ATTITUDE_TOPIC, ATTITUDE_FIELDS.to_vec())];
    let mut decoded = decode(path, &Wanted { topics: &topics })?;
    let samples = decoded
        .take(0, 0)
        .unwrap_or_default()
        .iter()
        .map(|row| {
            let q = [0, 1, 2, 3].map(|i| required(row, i));
            Ok(ReferenceSample {
                t_us: time(row)?,
                attitude: quaternion_wxyz([q[0]?, q[1]?, q[2]?, q[3]?])?,
                velocity_ned_m_s: None,
                position_ned_m: None,
            })
        })
        .collect();
    Ok(RowStream::decoded(
        samples,
        format!("{}:{ATTITUDE_TOPIC}", file_label(path)),
        "reference",
    ))
}

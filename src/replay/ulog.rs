//! Reader of PX4 ULog binary logs (`.ulg`), written for this crate on the
//! published format (see `docs/replay.md` for why `px4-ulog` is not used).
//!
//! # Format
//! A 16-byte header (`ULog 01 12 35`, version, start time), then messages
//! `u16 size, u8 type, body`: `B` flag bits (appended-data offsets), `F`
//! formats (`name:type field;type[n] field;...`, types `int8_t` ...
//! `uint64_t`, `float`, `double`, `bool`, `char` or another format), `A`
//! subscriptions (`multi_id u8, msg_id u16, format name`), `D` data
//! (`msg_id u16`, then the fields packed little-endian in format order,
//! padding included), `R` unsubscribe, and information, parameter, logging,
//! sync and dropout messages (skipped). Data sections appended after a crash
//! (flag bits) are read from their offsets.
//!
//! The topics, fields, units and checks are those of the `ulog2csv` reader
//! ([`super::px4`]): `sensor_combined` (IMU; multi-id = the IMU instance),
//! `vehicle_gps_position` (else `sensor_gps`, multi-id 0),
//! `vehicle_magnetometer` (multi-id 0) and `vehicle_attitude` (reference).
//! Every data message of those subscriptions is one row: the counts equal
//! pyulog's (tested on `../shared/data/px4-pyulog-sample`).
//!
//! # Bad bytes
//! The whole file is checked when it is opened. No header, unknown
//! incompatible flags, an appended-data offset outside the file, a message
//! too short for its type, an unknown message type, a format that is not
//! `name:type field;...` or nests undefined formats, or data for a msg_id
//! never subscribed: a [`ReplayError::Corrupt`] naming the byte offset and
//! the message type. A file (or the main section before appended data) that
//! ends inside a message keeps the messages before it and counts the cut one
//! as an [`SkipKind::Unparsable`] row of the file.

use super::dataflash::bytes_at;
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
use std::collections::HashMap;
use std::fmt;
use std::path::Path;

/// The first bytes of every ULog file.
pub const MAGIC: &[u8] = b"ULog";

/// One data message of a wanted topic: its timestamp and the wanted fields
/// (`None` when the topic lacks a field, it is not a number, or the message
/// is too short to hold it).
struct Row {
    t_us: Option<u64>,
    values: Vec<Option<f64>>,
}

/// What is read from a log: for each topic, the fields wanted.
struct Wanted<'w> {
    topics: &'w [(&'static str, Vec<&'static str>)],
}

/// The rows of the wanted topics by `(topic index, multi-id)`, and the
/// records the file or a section ends inside of.
struct Decoded {
    rows: HashMap<(usize, u8), Vec<Row>>,
    truncated: u64,
}

impl Decoded {
    fn take(&mut self, topic: usize, multi_id: u8) -> Option<Vec<Row>> {
        self.rows.remove(&(topic, multi_id))
    }
}

/// Why a ULog file is corrupt.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum UlogFault {
    /// The file does not start with the 16-byte ULog header.
    BadHeader,
    /// The flag bits mark an incompatibility this reader does not know.
    UnknownIncompatibleFlags([u8; 8]),
    /// An appended-data offset points outside the file or backwards.
    BadAppendedOffset(u64),
    /// A message is shorter than its type requires.
    ShortMessage {
        /// Bytes required.
        needed: usize,
        /// Bytes present.
        size: usize,
    },
    /// A message type letter that ULog does not define.
    UnknownMessageType(u8),
    /// A format or subscription is not `name:type field;...` text.
    BadFormat(String),
    /// A subscription names a format that was not defined, or nests
    /// formats too deeply (a cycle).
    UnknownFormat(String),
    /// A data message's subscription was not added.
    UnknownSubscription(u16),
}

impl fmt::Display for UlogFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BadHeader => write!(f, "no ULog header (ULog 01 12 35 version timestamp)"),
            Self::UnknownIncompatibleFlags(flags) => {
                write!(f, "unknown incompatible flags {flags:02X?}")
            }
            Self::BadAppendedOffset(o) => write!(f, "appended data offset {o} is invalid"),
            Self::ShortMessage { needed, size } => {
                write!(f, "message of {size} bytes, its type needs {needed}")
            }
            Self::UnknownMessageType(t) => write!(f, "unknown message type 0x{t:02X}"),
            Self::BadFormat(why) => write!(f, "bad format: {why}"),
            Self::UnknownFormat(name) => write!(f, "format `{name}` is not defined"),
            Self::UnknownSubscription(id) => write!(f, "data for msg_id {id}, never subscribed"),
        }
    }
}

/// A corrupt ULog message: where it is and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UlogError {
    /// Byte offset of the message in the file.
    pub offset: u64,
    /// The message type letter (`F`, `A`, `D`...) when the header was read.
    pub record: Option<char>,
    /// What is wrong.
    pub fault: UlogFault,
}

impl UlogError {
    /// The replay error for the log at `path`.
    pub fn at(self, path: &Path) -> ReplayError {
        ReplayError::Corrupt {
            path: path.to_path_buf(),
            offset: Some(self.offset),
            record: self.record.map(|c| format!("ULog message '{c}'")),
            reason: self.fault.to_string(),
        }
    }
}

/// Bytes of the file header.
const HEADER_LENGTH: usize = 16;
/// Bytes of a message header (`u16 size, u8 type`).
const MESSAGE_HEADER: usize = 3;
/// Deepest nesting of formats accepted.
const MAX_NESTING: usize = 16;
/// The incompatible flag bit for appended data.
const DATA_APPENDED: u8 = 1;

/// A basic ULog type: its size and how to read it as a number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Basic {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
    Bool,
    Char,
}

impl Basic {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "int8_t" => Self::I8,
            "uint8_t" => Self::U8,
            "int16_t" => Self::I16,
            "uint16_t" => Self::U16,
            "int32_t" => Self::I32,
            "uint32_t" => Self::U32,
            "int64_t" => Self::I64,
            "uint64_t" => Self::U64,
            "float" => Self::F32,
            "double" => Self::F64,
            "bool" => Self::Bool,
            "char" => Self::Char,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 | Self::Bool | Self::Char => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }

    fn read(self, data: &[u8], offset: usize) -> Option<f64> {
        Some(match self {
            Self::I8 => f64::from(i8::from_le_bytes(bytes_at(data, offset)?)),
            Self::U8 | Self::Bool => f64::from(u8::from_le_bytes(bytes_at(data, offset)?)),
            Self::I16 => f64::from(i16::from_le_bytes(bytes_at(data, offset)?)),
            Self::U16 => f64::from(u16::from_le_bytes(bytes_at(data, offset)?)),
            Self::I32 => f64::from(i32::from_le_bytes(bytes_at(data, offset)?)),
            Self::U32 => f64::from(u32::from_le_bytes(bytes_at(data, offset)?)),
            Self::I64 => i64::from_le_bytes(bytes_at(data, offset)?) as f64,
            Self::U64 => u64::from_le_bytes(bytes_at(data, offset)?) as f64,
            Self::F32 => f64::from(f32::from_le_bytes(bytes_at(data, offset)?)),
            Self::F64 => f64::from_le_bytes(bytes_at(data, offset)?),
            Self::Char => return None,
        })
    }
}

/// One field of a format as written: type name, array length, field name.
#[derive(Debug, Clone)]
struct FieldDef {
    kind: String,
    count: usize,
    name: String,
}

/// Parses `name:type field;type[n] field;...`.
fn parse_format(text: &str) -> Result<(String, Vec<FieldDef>), UlogFault> {
    let bad = |why: &str| UlogFault::BadFormat(why.to_string());
    let (name, body) = text.split_once(':').ok_or_else(|| bad("no `:`"))?;
    let mut fields = Vec::new();
    for field in body.split(';').filter(|f| !f.is_empty()) {
        let (kind, field_name) = field
            .trim()
            .split_once(' ')
            .ok_or_else(|| bad("a field without a type"))?;
        let (kind, count) = match kind.split_once('[') {
            Some((k, n)) => {
                let n = n.strip_suffix(']').ok_or_else(|| bad("unclosed `[`"))?;
                (k, n.parse::<usize>().map_err(|_| bad("array length"))?)
            }
            None => (kind, 1),
        };
        fields.push(FieldDef {
            kind: kind.to_string(),
            count,
            name: field_name.trim().to_string(),
        });
    }
    Ok((name.to_string(), fields))
}

/// The byte size of format `name`, nested formats included.
fn format_size(
    formats: &HashMap<String, Vec<FieldDef>>,
    name: &str,
    depth: usize,
) -> Result<usize, UlogFault> {
    let unknown = || UlogFault::UnknownFormat(name.to_string());
    if depth > MAX_NESTING {
        return Err(unknown());
    }
    let fields = formats.get(name).ok_or_else(unknown)?;
    let mut size: usize = 0;
    for f in fields {
        let one = match Basic::parse(&f.kind) {
            Some(b) => b.size(),
            None => format_size(formats, &f.kind, depth + 1)?,
        };
        size = one
            .checked_mul(f.count)
            .and_then(|s| size.checked_add(s))
            .ok_or_else(unknown)?;
    }
    Ok(size)
}

/// How to read the wanted fields out of one subscription's data messages
/// (offsets into the payload after the `msg_id`).
struct Plan {
    topic: usize,
    multi_id: u8,
    fields: Vec<Option<(Basic, usize)>>,
    timestamp: Option<usize>,
}

/// Where top-level field `wanted` (`name` or `name[i]`) of a basic type lies.
fn locate_field(
    formats: &HashMap<String, Vec<FieldDef>>,
    fields: &[FieldDef],
    wanted: &str,
) -> Result<Option<(Basic, usize)>, UlogFault> {
    let (name, index) = match wanted.split_once('[') {
        Some((n, i)) => (n, i.trim_end_matches(']').parse::<usize>().ok()),
        None => (wanted, None),
    };
    let mut offset = 0;
    for f in fields {
        let basic = Basic::parse(&f.kind);
        let one = match basic {
            Some(b) => b.size(),
            None => format_size(formats, &f.kind, 1)?,
        };
        if f.name == name {
            let i = index.unwrap_or(0);
            let is_array = f.count > 1 || index.is_some();
            return Ok(match basic {
                Some(b) if i < f.count && (is_array == index.is_some()) => {
                    Some((b, offset + i * one))
                }
                _ => None,
            });
        }
        offset += one * f.count;
    }
    Ok(None)
}

fn plan(
    formats: &HashMap<String, Vec<FieldDef>>,
    format: &str,
    topic: usize,
    multi_id: u8,
    wanted: &[&str],
) -> Result<Plan, UlogFault> {
    let fields = formats
        .get(format)
        .ok_or_else(|| UlogFault::UnknownFormat(format.to_string()))?;
    format_size(formats, format, 0)?;
    let timestamp = match locate_field(formats, fields, "timestamp")? {
        Some((Basic::U64, o)) => Some(o),
        _ => None,
    };
    Ok(Plan {
        topic,
        multi_id,
        fields: wanted
            .iter()
            .map(|w| locate_field(formats, fields, w))
            .collect::<Result<_, _>>()?,
        timestamp,
    })
}

fn row(plan: &Plan, payload: &[u8]) -> Row {
    Row {
        t_us: plan
            .timestamp
            .and_then(|o| bytes_at(payload, o))
            .map(u64::from_le_bytes),
        values: plan
            .fields
            .iter()
            .map(|f| f.and_then(|(kind, o)| kind.read(payload, o)))
            .collect(),
    }
}

/// Text of a message body.
fn text(body: &[u8]) -> Result<&str, UlogFault> {
    std::str::from_utf8(body).map_err(|_| UlogFault::BadFormat("not UTF-8".to_string()))
}

/// The incompatible flags of a flag-bits body, checked; whether data is appended.
fn check_flags(body: &[u8]) -> Result<bool, UlogFault> {
    let incompatible: [u8; 8] = bytes_at(body, 8).unwrap_or([0; 8]);
    let known = [DATA_APPENDED, 0, 0, 0, 0, 0, 0, 0];
    if incompatible.iter().zip(known).any(|(f, k)| f & !k != 0) {
        return Err(UlogFault::UnknownIncompatibleFlags(incompatible));
    }
    Ok(incompatible[0] & DATA_APPENDED != 0)
}

/// The byte ranges to parse: after the header up to the first appended-data
/// offset, then each appended section up to the next one or the end. The
/// flag bits, when present, are the first message.
fn sections(bytes: &[u8]) -> Result<Vec<(usize, usize)>, UlogError> {
    let mut sections = vec![(HEADER_LENGTH, bytes.len())];
    let at = HEADER_LENGTH;
    let Some(head) = bytes.get(at..at + MESSAGE_HEADER) else {
        return Ok(sections);
    };
    let size = usize::from(u16::from_le_bytes([head[0], head[1]]));
    let body_start = at + MESSAGE_HEADER;
    let (Some(body), b'B') = (bytes.get(body_start..body_start + size), head[2]) else {
        return Ok(sections);
    };
    let fail = |fault| UlogError {
        offset: at as u64,
        record: Some('B'),
        fault,
    };
    if size < 40 {
        return Err(fail(UlogFault::ShortMessage { needed: 40, size }));
    }
    if !check_flags(body).map_err(fail)? {
        return Ok(sections);
    }
    let mut previous = body_start + size;
    for o in (0..3).filter_map(|i| bytes_at(body, 16 + 8 * i).map(u64::from_le_bytes)) {
        if o == 0 {
            continue;
        }
        let start = usize::try_from(o)
            .ok()
            .filter(|&s| s >= previous && s <= bytes.len())
            .ok_or_else(|| fail(UlogFault::BadAppendedOffset(o)))?;
        if let Some(last) = sections.last_mut() {
            last.1 = start;
        }
        sections.push((start, bytes.len()));
        previous = start;
    }
    Ok(sections)
}

/// Parses a whole log, keeping the wanted topics' rows (see the module's
/// "Bad bytes").
fn decode_bytes(bytes: &[u8], wanted: &Wanted<'_>) -> Result<Decoded, UlogError> {
    let error = |offset: usize, record: Option<u8>, fault| UlogError {
        offset: offset as u64,
        record: record.map(char::from),
        fault,
    };
    if bytes.len() < HEADER_LENGTH || !bytes.starts_with(MAGIC) || bytes[4..7] != [1, 0x12, 0x35] {
        return Err(error(0, None, UlogFault::BadHeader));
    }
    let mut formats: HashMap<String, Vec<FieldDef>> = HashMap::new();
    let mut plans: HashMap<u16, Option<Plan>> = HashMap::new();
    let mut decoded = Decoded {
        rows: HashMap::new(),
        truncated: 0,
    };
    let sections = sections(bytes)?;
    for &(start, end) in &sections {
        let mut pos = start;
        while pos < end {
            if end - pos < MESSAGE_HEADER {
                decoded.truncated += 1;
                break;
            }
            let size = usize::from(u16::from_le_bytes([bytes[pos], bytes[pos + 1]]));
            let kind = bytes[pos + 2];
            let body_start = pos + MESSAGE_HEADER;
            if end - body_start < size {
                decoded.truncated += 1;
                break;
            }
            let body = &bytes[body_start..body_start + size];
            let fail = |fault| error(pos, Some(kind), fault);
            let need = |n: usize| {
                if size < n {
                    Err(fail(UlogFault::ShortMessage { needed: n, size }))
                } else {
                    Ok(())
                }
            };
            match kind {
                b'B' => {
                    need(40)?;
                    check_flags(body).map_err(fail)?;
                }
                b'F' => {
                    let (name, fields) = parse_format(text(body).map_err(fail)?).map_err(fail)?;
                    formats.insert(name, fields);
                }
                b'A' => {
                    need(3)?;
                    let multi_id = body[0];
                    let msg_id = u16::from_le_bytes([body[1], body[2]]);
                    let name = text(&body[3..]).map_err(fail)?;
                    let plan = match wanted.topics.iter().position(|(t, _)| *t == name) {
                        Some(topic) => Some(
                            plan(&formats, name, topic, multi_id, &wanted.topics[topic].1)
                                .map_err(fail)?,
                        ),
                        None => {
                            format_size(&formats, name, 0).map_err(fail)?;
                            None
                        }
                    };
                    plans.insert(msg_id, plan);
                }
                b'D' => {
                    need(2)?;
                    let msg_id = u16::from_le_bytes([body[0], body[1]]);
                    match plans.get(&msg_id) {
                        Some(Some(p)) => decoded
                            .rows
                            .entry((p.topic, p.multi_id))
                            .or_default()
                            .push(row(p, &body[2..])),
                        Some(None) => {}
                        None => return Err(fail(UlogFault::UnknownSubscription(msg_id))),
                    }
                }
                b'R' => {
                    need(2)?;
                    plans.remove(&u16::from_le_bytes([body[0], body[1]]));
                }
                b'I' | b'M' | b'P' | b'Q' | b'L' | b'C' | b'S' | b'O' => {}
                other => return Err(fail(UlogFault::UnknownMessageType(other))),
            }
            pos = body_start + size;
        }
    }
    Ok(decoded)
}

/// Parses the log at `path`, keeping the wanted topics' rows.
fn decode(path: &Path, wanted: &Wanted<'_>) -> Result<Decoded, ReplayError> {
    let bytes = std::fs::read(path).map_err(|source| ReplayError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    decode_bytes(&bytes, wanted).map_err(|e| e.at(path))
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
    for _ in 0..decoded.truncated {
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

/// UTC time, microseconds since 1970, of the first GPS message (the topic
/// [`open_streams`] reads) with a 3-D fix and a non-zero `time_utc_usec`;
/// `Ok(None)` when no message has one.
pub(crate) fn gps_utc_us(path: &Path) -> Result<Option<u64>, ReplayError> {
    let topics: Vec<_> = GPS_TOPICS
        .iter()
        .map(|&t| (t, vec!["fix_type", "time_utc_usec"]))
        .collect();
    let mut decoded = decode(path, &Wanted { topics: &topics })?;
    let Some(rows) = (0..topics.len()).find_map(|i| decoded.take(i, 0)) else {
        return Ok(None);
    };
    Ok(rows
        .iter()
        .find_map(|row| match (row.values[0], row.values[1]) {
            (Some(fix), Some(t)) if fix >= MIN_FIX_TYPE && t > 0.0 => Some(t as u64),
            _ => None,
        }))
}

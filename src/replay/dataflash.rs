//! Reader of ArduPilot DataFlash binary logs (`.bin`), written for this
//! crate on the published format (see `docs/replay.md` for why no crate is
//! wrapped).
//!
//! # Format
//! A log is a sequence of records, each `A3 95 <type u8> <payload>`. Type 128
//! is `FMT` (89 bytes with the header): `Type u8, Length u8, Name char[4],
//! Format char[16], Columns char[64]`; it defines the record `Type` as
//! `Length` bytes (header included) whose payload holds one field per
//! `Format` letter, named by the comma-separated `Columns`. Little-endian:
//!
//! | letters | type | value |
//! |---|---|---|
//! | `b B M` / `h H` / `i I` / `q Q` | int8 uint8 uint8 / int16 uint16 / int32 uint32 / int64 uint64 | as stored |
//! | `f` / `d` | float32 / float64 | as stored |
//! | `c C` / `e E` | int16 uint16 / int32 uint32 | stored ÷ 100 (centi-units) |
//! | `L` | int32 | stored × 1e-7 (degrees of latitude or longitude) |
//! | `n N Z` | char\[4\] char\[16\] char\[64\] | text |
//! | `a` | int16\[32\] | not a number |
//!
//! # What is read
//! | stream | records | conversion |
//! |---|---|---|
//! | IMU | `IMU` (instance `N` by its `I` field, or `IMU`, `IMU2`, `IMU3` in older logs) | `TimeUS` µs, or `TimeMS` × 1000; `Gyr*` rad/s, `Acc*` m/s², body FRD |
//! | GPS | `GPS` (instance 0) | time `TimeUS`, else `T` (ms, the autopilot clock; older logs' `TimeMS` is GPS time of week), else `TimeMS`; `Status < 3` is no-fix; `Lat, Lng` deg, `Alt` m; NED velocity from `Spd` (m/s), `GCrs` (deg), `VZ` (m/s down) as in [`super::ardupilot`] |
//! | GPS accuracy | `GPA` (`HAcc, VAcc, SAcc`) or `UBX3` (`hAcc, vAcc, sAcc`) | joined to the fix nearest in time within 50 ms, like `gps_accuracy.csv` |
//! | magnetometer | `MAG` (instance 0) | `Mag*` mGauss ÷ 1000 to gauss; `Health == 0` is invalid |
//! | reference | `EKF1`, `NKF1` or `XKF1` (core 0), else `ATT` | degrees to the body-to-NED quaternion (ZYX) |
//! | parameters | `PARM` | `Name`, `Value` |
//!
//! The CSV files of `../shared/data/ardupilot-log171` were made from these
//! records, and the two readers give the same samples (tested).
//!
//! # Bad bytes
//! The whole file is checked when it is opened. A record that does not start
//! with `A3 95`, a type no `FMT` defined, or an `FMT` whose letters are
//! unknown, whose length disagrees with its letters, or whose names do not
//! match its letters is a [`ReplayError::Corrupt`] naming the byte offset and
//! the record. A file that ends inside a record (power cut, crash) keeps the
//! records before it; the cut record is counted as one
//! [`SkipKind::Unparsable`] row of the file. Bytes after the last record
//! that are all `00` or all `FF` (padding of a block-written log) are not
//! records and are ignored.

use super::ardupilot::{
    ACCURACY_JOIN_WINDOW_US, Accuracy, AccuracyJoin, AccuracyRow, MILLIGAUSS_PER_GAUSS,
    MIN_FIX_STATUS, ned_from_speed_course,
};
use super::table::{RowStream, file_label};
use super::{
    GpsRow, GpsRowPosition, ReferenceSample, ReplayError, SensorEvent, SensorStreams, SkipCounts,
    SkipKind, imu_event, mag_event,
};
use crate::geo::quaternion_from_euler;
use crate::scalar::Scalar;
use crate::sensors::Geodetic;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// The two bytes that start every record.
pub const RECORD_HEADER: [u8; 2] = [0xA3, 0x95];
/// The type of `FMT` records.
pub const FMT_TYPE: u8 = 128;
/// Length of an `FMT` record, header included, bytes.
pub const FMT_LENGTH: usize = 89;
/// Bytes of the record header (`A3 95 type`).
const HEADER_LENGTH: usize = 3;

// Keep the join window the CSV reader documents.
const _: () = assert!(ACCURACY_JOIN_WINDOW_US == 50_000);

/// Why a DataFlash log is corrupt.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum DataFlashFault {
    /// The two bytes where a record starts are not `A3 95`.
    BadHeader([u8; 2]),
    /// A record's type has no `FMT` before it.
    UnknownType(u8),
    /// An `FMT` format letter is not one of the documented letters.
    UnknownLetter(char),
    /// An `FMT`'s declared length differs from what its letters need.
    LengthMismatch {
        /// Declared length, header included.
        declared: usize,
        /// Length the letters need, header included.
        needed: usize,
    },
    /// An `FMT`'s column names are not one per letter.
    ColumnCount {
        /// Format letters.
        letters: usize,
        /// Column names.
        columns: usize,
    },
    /// An `FMT` redefines `FMT` itself with another layout.
    FmtRedefined,
    /// An `FMT`'s name, format or columns are not text.
    NotText,
}

impl fmt::Display for DataFlashFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BadHeader([a, b]) => {
                write!(f, "expected record header A3 95, found {a:02X} {b:02X}")
            }
            Self::UnknownType(t) => write!(f, "record type {t} has no FMT before it"),
            Self::UnknownLetter(c) => write!(f, "unknown format letter {c:?}"),
            Self::LengthMismatch { declared, needed } => write!(
                f,
                "declared length {declared} bytes but its format needs {needed}"
            ),
            Self::ColumnCount { letters, columns } => {
                write!(f, "{letters} format letters but {columns} column names")
            }
            Self::FmtRedefined => write!(f, "redefines FMT with another layout"),
            Self::NotText => write!(f, "name, format or columns are not text"),
        }
    }
}

/// A corrupt record: where it is and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DataFlashError {
    /// Byte offset of the record in the file.
    pub offset: u64,
    /// The record's message name when known (`FMT` for a bad definition).
    pub record: Option<String>,
    /// What is wrong.
    pub fault: DataFlashFault,
}

impl DataFlashError {
    /// The replay error for the log at `path`.
    pub fn at(self, path: &Path) -> ReplayError {
        ReplayError::Corrupt {
            path: path.to_path_buf(),
            offset: Some(self.offset),
            record: self.record,
            reason: self.fault.to_string(),
        }
    }
}

/// One field of a record layout.
#[derive(Debug, Clone)]
struct Field {
    name: String,
    letter: u8,
    offset: usize,
}

/// A record layout defined by an `FMT`.
#[derive(Debug, Clone)]
struct Format {
    name: String,
    length: usize,
    fields: Vec<Field>,
}

impl Format {
    fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }
}

/// Bytes of one value of format letter `letter`, or `None` for an unknown letter.
fn letter_size(letter: u8) -> Option<usize> {
    Some(match letter {
        b'b' | b'B' | b'M' => 1,
        b'h' | b'H' | b'c' | b'C' => 2,
        b'i' | b'I' | b'f' | b'e' | b'E' | b'L' | b'n' => 4,
        b'd' | b'q' | b'Q' => 8,
        b'N' => 16,
        b'Z' | b'a' => 64,
        _ => return None,
    })
}

/// Text of a zero-padded char array.
fn text(bytes: &[u8]) -> Option<&str> {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    std::str::from_utf8(&bytes[..end]).ok()
}

/// `N` bytes at `offset`, if the payload holds them (also used by the ULog reader).
pub(crate) fn bytes_at<const N: usize>(payload: &[u8], offset: usize) -> Option<[u8; N]> {
    payload.get(offset..offset.checked_add(N)?)?.try_into().ok()
}

/// The numeric value of a field, scaled as its letter says.
fn number(payload: &[u8], letter: u8, offset: usize) -> Option<f64> {
    let p = payload;
    Some(match letter {
        b'b' => f64::from(i8::from_le_bytes(bytes_at(p, offset)?)),
        b'B' | b'M' => f64::from(u8::from_le_bytes(bytes_at(p, offset)?)),
        b'h' => f64::from(i16::from_le_bytes(bytes_at(p, offset)?)),
        b'H' => f64::from(u16::from_le_bytes(bytes_at(p, offset)?)),
        b'i' => f64::from(i32::from_le_bytes(bytes_at(p, offset)?)),
        b'I' => f64::from(u32::from_le_bytes(bytes_at(p, offset)?)),
        b'q' => i64::from_le_bytes(bytes_at(p, offset)?) as f64,
        b'Q' => u64::from_le_bytes(bytes_at(p, offset)?) as f64,
        b'f' => f64::from(f32::from_le_bytes(bytes_at(p, offset)?)),
        b'd' => f64::from_le_bytes(bytes_at(p, offset)?),
        b'c' => f64::from(i16::from_le_bytes(bytes_at(p, offset)?)) / 100.0,
        b'C' => f64::from(u16::from_le_bytes(bytes_at(p, offset)?)) / 100.0,
        b'e' => f64::from(i32::from_le_bytes(bytes_at(p, offset)?)) / 100.0,
        b'E' => f64::from(u32::from_le_bytes(bytes_at(p, offset)?)) / 100.0,
        b'L' => f64::from(i32::from_le_bytes(bytes_at(p, offset)?)) * 1e-7,
        _ => return None,
    })
}

/// A record that the file ends inside of.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Truncation {
    /// Byte offset where the cut record starts.
    pub offset: u64,
    /// Its message name when its type was defined.
    pub record: Option<String>,
}

/// A checked DataFlash log held in memory: every record's layout and place.
pub struct DataFlashLog {
    bytes: Vec<u8>,
    formats: Vec<Format>,
    /// `(index into formats, offset of the record's payload)`.
    records: Vec<(usize, usize)>,
    truncated: Option<Truncation>,
}

/// One record of a log.
#[derive(Clone, Copy)]
pub struct Record<'a> {
    format: &'a Format,
    payload: &'a [u8],
}

impl<'a> Record<'a> {
    /// The record's message name (`IMU`, `GPS`, ...).
    pub fn name(&self) -> &'a str {
        &self.format.name
    }

    /// The numeric value of field `name`, scaled as its format letter says
    /// (see the module table); `None` when the record has no such numeric field.
    pub fn get(&self, name: &str) -> Option<f64> {
        let field = self.format.field(name)?;
        number(self.payload, field.letter, field.offset)
    }

    /// The text of a `n`, `N` or `Z` field.
    pub fn text(&self, name: &str) -> Option<&'a str> {
        let field = self.format.field(name)?;
        let size = match field.letter {
            b'n' | b'N' | b'Z' => letter_size(field.letter)?,
            _ => return None,
        };
        text(self.payload.get(field.offset..field.offset + size)?)
    }

    /// Whether the record has a field `name`.
    pub fn has(&self, name: &str) -> bool {
        self.format.field(name).is_some()
    }
}

impl DataFlashLog {
    /// Checks a whole log (see the module's "Bad bytes").
    pub fn parse(bytes: Vec<u8>) -> Result<Self, DataFlashError> {
        let mut formats: Vec<Format> = Vec::new();
        let mut by_type: [Option<usize>; 256] = [None; 256];
        let mut records = Vec::new();
        let mut truncated = None;
        let mut pos = 0;
        while pos < bytes.len() {
            let rest = &bytes[pos..];
            let error = |record: Option<&str>, fault| DataFlashError {
                offset: pos as u64,
                record: record.map(str::to_string),
                fault,
            };
            if rest.iter().all(|&b| b == 0) || rest.iter().all(|&b| b == 0xFF) {
                break;
            }
            if rest.len() < HEADER_LENGTH {
                truncated = Some(Truncation {
                    offset: pos as u64,
                    record: None,
                });
                break;
            }
            if rest[..2] != RECORD_HEADER {
                return Err(error(None, DataFlashFault::BadHeader([rest[0], rest[1]])));
            }
            let kind = rest[2];
            let (length, name) = if kind == FMT_TYPE {
                (FMT_LENGTH, "FMT")
            } else {
                match by_type[usize::from(kind)] {
                    Some(i) => (formats[i].length, formats[i].name.as_str()),
                    None => return Err(error(None, DataFlashFault::UnknownType(kind))),
                }
            };
            if rest.len() < length {
                truncated = Some(Truncation {
                    offset: pos as u64,
                    record: Some(name.to_string()),
                });
                break;
            }
            if kind == FMT_TYPE {
                let (defined, format) = parse_fmt(&rest[HEADER_LENGTH..FMT_LENGTH])
                    .map_err(|fault| error(Some("FMT"), fault))?;
                if defined == FMT_TYPE && format.length != FMT_LENGTH {
                    return Err(error(Some("FMT"), DataFlashFault::FmtRedefined));
                }
                by_type[usize::from(defined)] = Some(formats.len());
                formats.push(format);
            } else if let Some(i) = by_type[usize::from(kind)] {
                records.push((i, pos + HEADER_LENGTH));
            }
            pos += length;
        }
        Ok(Self {
            bytes,
            formats,
            records,
            truncated,
        })
    }

    /// Reads and checks the log at `path`.
    pub fn open(path: &Path) -> Result<Self, ReplayError> {
        let bytes = std::fs::read(path).map_err(|source| ReplayError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(bytes).map_err(|e| e.at(path))
    }

    /// The record the file ends inside of, if any.
    pub fn truncated(&self) -> Option<&Truncation> {
        self.truncated.as_ref()
    }

    /// Every data record (not `FMT`), in file order.
    pub fn records(&self) -> impl Iterator<Item = Record<'_>> {
        self.records.iter().map(|&(i, start)| {
            let format = &self.formats[i];
            Record {
                format,
                payload: &self.bytes[start..start + format.length - HEADER_LENGTH],
            }
        })
    }

    /// The records named `name`, in file order.
    pub fn named<'s>(&'s self, name: &'s str) -> impl Iterator<Item = Record<'s>> + 's {
        self.records().filter(move |r| r.name() == name)
    }

    /// Whether any record is named `name`.
    pub fn has(&self, name: &str) -> bool {
        self.named(name).next().is_some()
    }

    /// The parameters (`PARM` records; a later value of a name replaces an earlier one).
    pub fn params(&self) -> BTreeMap<String, f64> {
        self.named("PARM")
            .filter_map(|r| Some((r.text("Name")?.to_string(), r.get("Value")?)))
            .collect()
    }
}

/// An `FMT` payload: the type it defines and the layout.
fn parse_fmt(payload: &[u8]) -> Result<(u8, Format), DataFlashFault> {
    let defined = payload[0];
    let declared = usize::from(payload[1]);
    let name = text(&payload[2..6]).ok_or(DataFlashFault::NotText)?;
    let letters = text(&payload[6..22]).ok_or(DataFlashFault::NotText)?;
    let columns = text(&payload[22..86]).ok_or(DataFlashFault::NotText)?;
    let names: Vec<&str> = if columns.is_empty() {
        Vec::new()
    } else {
        columns.split(',').collect()
    };
    if names.len() != letters.len() {
        return Err(DataFlashFault::ColumnCount {
            letters: letters.len(),
            columns: names.len(),
        });
    }
    let mut fields = Vec::with_capacity(names.len());
    let mut offset = 0;
    for (letter, name) in letters.bytes().zip(names) {
        let size = letter_size(letter).ok_or(DataFlashFault::UnknownLetter(char::from(letter)))?;
        fields.push(Field {
            name: name.to_string(),
            letter,
            offset,
        });
        offset += size;
    }
    let needed = offset + HEADER_LENGTH;
    if needed != declared {
        return Err(DataFlashFault::LengthMismatch { declared, needed });
    }
    Ok((
        defined,
        Format {
            name: name.to_string(),
            length: declared,
            fields,
        },
    ))
}

/// A record's time, microseconds: `TimeUS`, else `time_ms_field` × 1000.
fn time_us(r: &Record<'_>, time_ms_field: &str) -> Result<u64, SkipKind> {
    let (t, scale) = match r.get("TimeUS") {
        Some(t) => (t, 1.0),
        None => (r.get(time_ms_field).ok_or(SkipKind::Unparsable)?, 1000.0),
    };
    let us = (t * scale).round();
    if (0.0..u64::MAX as f64).contains(&us) {
        Ok(us as u64)
    } else {
        Err(SkipKind::OutOfRange)
    }
}

/// Three numeric fields as a vector.
fn vector(r: &Record<'_>, names: [&str; 3]) -> Result<Vector3<f64>, SkipKind> {
    let get = |n| r.get(n).ok_or(SkipKind::Unparsable);
    Ok(Vector3::new(get(names[0])?, get(names[1])?, get(names[2])?))
}

/// The records of instance `instance` of message `name`: by the `I` field
/// when the records have one, else `name`, `name2`, `name3` for instances 0, 1, 2.
fn instance<'s>(log: &'s DataFlashLog, name: &'static str, instance: u8) -> Vec<Record<'s>> {
    let by_field = log.named(name).next().is_some_and(|r| r.has("I"));
    if by_field {
        log.named(name)
            .filter(|r| r.get("I") == Some(f64::from(instance)))
            .collect()
    } else {
        let numbered = match instance {
            0 => name.to_string(),
            n => format!("{name}{}", n + 1),
        };
        log.records().filter(|r| r.name() == numbered).collect()
    }
}

/// The IMU, GPS and magnetometer streams of a log, and the rows counted
/// while opening them (a truncated record, accuracy records refused).
pub(crate) fn open_streams<T: Scalar>(
    path: &Path,
    imu_instance: u8,
) -> Result<(SensorStreams<T>, SkipCounts), ReplayError> {
    let log = DataFlashLog::open(path)?;
    let file = file_label(path);
    let label = |name: &str| format!("{file}:{name}");
    let mut skips = SkipCounts::default();
    if log.truncated().is_some() {
        skips.skip(&file, SkipKind::Unparsable);
    }

    let imu = instance(&log, "IMU", imu_instance);
    if imu.is_empty() {
        return Err(ReplayError::MissingRecords {
            path: path.to_path_buf(),
            what: format!("IMU instance {imu_instance}"),
        });
    }
    let imu_name = imu[0].name().to_string();
    let imu = imu
        .iter()
        .map(|r| {
            let t_us = time_us(r, "TimeMS")?;
            imu_event(
                t_us,
                vector(r, ["GyrX", "GyrY", "GyrZ"])?,
                vector(r, ["AccX", "AccY", "AccZ"])?,
            )
        })
        .collect();

    let mut join = accuracy_join(&log, &file);
    let gps = instance(&log, "GPS", 0)
        .iter()
        .map(|r| gps_event(r, &mut join, &mut skips))
        .collect();

    let mag = instance(&log, "MAG", 0);
    let mag = (!mag.is_empty()).then(|| {
        let events = mag
            .iter()
            .map(|r| {
                let t_us = time_us(r, "TimeMS")?;
                if r.get("Health") == Some(0.0) {
                    return Err(SkipKind::Invalid);
                }
                // The CSV reader multiplies by the reciprocal: the same rounding.
                let field = vector(r, ["MagX", "MagY", "MagZ"])? * (1.0 / MILLIGAUSS_PER_GAUSS);
                mag_event(t_us, field)
            })
            .collect();
        RowStream::decoded(events, label("MAG"), "mag")
    });
    let streams = SensorStreams {
        imu: RowStream::decoded(imu, label(&imu_name), "imu"),
        gps: RowStream::decoded(gps, label("GPS"), "gps"),
        mag,
    };
    Ok((streams, skips))
}

/// The join of the receiver's accuracy records (`GPA`, else `UBX3`) to the fixes.
fn accuracy_join(log: &DataFlashLog, file: &str) -> AccuracyJoin {
    let (name, fields) = if log.has("GPA") {
        ("GPA", ["HAcc", "VAcc", "SAcc"])
    } else {
        ("UBX3", ["hAcc", "vAcc", "sAcc"])
    };
    let rows = instance(log, name, 0)
        .iter()
        .map(|r| {
            Ok(AccuracyRow(Accuracy::new(
                time_us(r, "TimeMS")?,
                vector(r, fields)?,
            )?))
        })
        .collect();
    AccuracyJoin::from_stream(RowStream::decoded(
        rows,
        format!("{file}:{name}"),
        "gps_accuracy",
    ))
}

/// A `GPS` record as a checked fix.
fn gps_event<T: Scalar>(
    r: &Record<'_>,
    join: &mut AccuracyJoin,
    skips: &mut SkipCounts,
) -> Result<SensorEvent<T>, SkipKind> {
    let t_us = if r.has("TimeUS") {
        time_us(r, "TimeUS")?
    } else if r.has("T") {
        time_us(r, "T")?
    } else {
        time_us(r, "TimeMS")?
    };
    if r.get("Status").ok_or(SkipKind::Unparsable)? < MIN_FIX_STATUS {
        return Err(SkipKind::NoFix);
    }
    let [lat, lon, alt] = ["Lat", "Lng", "Alt"].map(|n| r.get(n).ok_or(SkipKind::Unparsable));
    let position = Geodetic {
        lat_deg: lat?,
        lon_deg: lon?,
        alt_m: alt?,
    };
    let [speed, course, down] = ["Spd", "GCrs", "VZ"].map(|n| r.get(n).ok_or(SkipKind::Unparsable));
    GpsRow {
        t_us,
        position: GpsRowPosition::Geodetic(position),
        velocity_ned_m_s: ned_from_speed_course(speed?, course?, down?),
        accuracy: join.at(t_us, skips).map_or([None; 3], Accuracy::as_row),
    }
    .into_event()
}

/// The onboard solution of a log: `EKF1`, `NKF1` or `XKF1` (core 0) with
/// velocity and position, else `ATT` (attitude only).
pub(crate) fn reference_stream(path: &Path) -> Result<RowStream<ReferenceSample>, ReplayError> {
    let log = DataFlashLog::open(path)?;
    let name = ["EKF1", "NKF1", "XKF1", "ATT"]
        .into_iter()
        .find(|n| log.has(n))
        .unwrap_or("EKF1");
    let samples = log
        .named(name)
        .filter(|r| r.get("C").is_none_or(|core| core == 0.0))
        .map(|r| {
            let e = vector(&r, ["Roll", "Pitch", "Yaw"])?.map(f64::to_radians);
            let full = r.has("VN");
            Ok(ReferenceSample {
                t_us: time_us(&r, "TimeMS")?,
                attitude: quaternion_from_euler(e.x, e.y, e.z),
                velocity_ned_m_s: full.then(|| vector(&r, ["VN", "VE", "VD"])).transpose()?,
                position_ned_m: full.then(|| vector(&r, ["PN", "PE", "PD"])).transpose()?,
            })
        })
        .collect();
    Ok(RowStream::decoded(
        samples,
        format!("{}:{name}", file_label(path)),
        "reference",
    ))
}

//! Row parsers shared by the layouts: how a row is stamped, validity flags,
//! and the IMU and magnetometer rows, which differ between layouts only in
//! column names, time unit, field scale and flags.

use super::table::{
    CsvTable, RowParser, RowStream, microseconds, optional_number, seconds_as_us, vector3,
};
use super::{ReplayError, SensorEvent, SkipCounts, SkipKind, imu_event, mag_event};
use crate::scalar::Scalar;
use crate::sensors::Geodetic;
use csv::StringRecord;
use std::path::Path;

/// Gyro columns of the crate's and ArduPilot's IMU files (rad/s, body FRD).
pub(crate) const GYRO_COLUMNS: [&str; 3] = ["gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"];
/// Accelerometer columns of the crate's and ArduPilot's IMU files (m/s², body FRD).
pub(crate) const ACCEL_COLUMNS: [&str; 3] = ["acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"];

/// How a file stamps its rows.
#[derive(Debug, Clone, Copy)]
pub(crate) enum TimeColumn {
    /// Integer microseconds (crate format `t_us`, PX4 `timestamp`).
    Microseconds(usize),
    /// Seconds, rounded to microseconds (ArduPilot `t_s`).
    Seconds(usize),
}

impl TimeColumn {
    /// Finds the time column `name` of unit `unit`.
    pub(crate) fn find(table: &CsvTable, name: &str, unit: TimeUnit) -> Result<Self, ReplayError> {
        let idx = table.column(name)?;
        Ok(match unit {
            TimeUnit::Microseconds => Self::Microseconds(idx),
            TimeUnit::Seconds => Self::Seconds(idx),
        })
    }

    /// The row's time, microseconds.
    pub(crate) fn read(self, rec: &StringRecord) -> Result<u64, SkipKind> {
        match self {
            Self::Microseconds(idx) => microseconds(rec, idx),
            Self::Seconds(idx) => seconds_as_us(rec, idx),
        }
    }
}

/// Unit of a layout's time column.
#[derive(Debug, Clone, Copy)]
pub(crate) enum TimeUnit {
    Microseconds,
    Seconds,
}

/// The name and unit of a layout's time column.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Clock {
    pub(crate) column: &'static str,
    pub(crate) unit: TimeUnit,
}

/// A per-row validity flag: when the cell's value satisfies `rejects`, the
/// row is skipped as `kind`. An absent column or empty cell passes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowFlag {
    pub(crate) column: Option<usize>,
    pub(crate) rejects: fn(f64) -> bool,
    pub(crate) kind: SkipKind,
}

impl RowFlag {
    pub(crate) fn check(&self, rec: &StringRecord) -> Result<(), SkipKind> {
        match optional_number(rec, self.column)? {
            Some(v) if (self.rejects)(v) => Err(self.kind),
            _ => Ok(()),
        }
    }
}

/// Checks every flag of a row.
pub(crate) fn check_flags(flags: &[RowFlag], rec: &StringRecord) -> Result<(), SkipKind> {
    flags.iter().try_for_each(|f| f.check(rec))
}

/// An IMU row: time, gyro and accelerometer triples, flags.
struct ImuColumns {
    time: TimeColumn,
    gyro: [usize; 3],
    accel: [usize; 3],
    flags: Vec<RowFlag>,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for ImuColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = self.time.read(rec)?;
        check_flags(&self.flags, rec)?;
        imu_event(t_us, vector3(rec, self.gyro)?, vector3(rec, self.accel)?)
    }
}

/// The column names of an IMU file.
pub(crate) struct ImuLayout {
    pub(crate) clock: Clock,
    pub(crate) gyro: [&'static str; 3],
    pub(crate) accel: [&'static str; 3],
}

/// The IMU stream of `path`; `flags` builds the validity flags from the table.
pub(crate) fn imu_stream<T: Scalar>(
    path: &Path,
    layout: &ImuLayout,
    flags: impl FnOnce(&CsvTable) -> Vec<RowFlag>,
) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = ImuColumns {
        time: TimeColumn::find(&table, layout.clock.column, layout.clock.unit)?,
        gyro: table.columns3(layout.gyro)?,
        accel: table.columns3(layout.accel)?,
        flags: flags(&table),
    };
    Ok(RowStream::new(table, Box::new(parser), "imu"))
}

/// A magnetometer row: time, field triple times `scale`, flags.
struct MagColumns {
    time: TimeColumn,
    field: [usize; 3],
    scale: f64,
    flags: Vec<RowFlag>,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for MagColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = self.time.read(rec)?;
        check_flags(&self.flags, rec)?;
        mag_event(t_us, vector3(rec, self.field)? * self.scale)
    }
}

/// The column names and unit of a magnetometer file.
pub(crate) struct MagLayout {
    pub(crate) clock: Clock,
    pub(crate) field: [&'static str; 3],
    /// Multiplies the file's values (e.g. 1e-3 from mGauss to gauss).
    pub(crate) scale: f64,
}

/// The magnetometer stream of `path`.
pub(crate) fn mag_stream<T: Scalar>(
    path: &Path,
    layout: &MagLayout,
    flags: impl FnOnce(&CsvTable) -> Vec<RowFlag>,
) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = MagColumns {
        time: TimeColumn::find(&table, layout.clock.column, layout.clock.unit)?,
        field: table.columns3(layout.field)?,
        scale: layout.scale,
        flags: flags(&table),
    };
    Ok(RowStream::new(table, Box::new(parser), "mag"))
}

/// Latitude, longitude and height columns, and the factors that turn their
/// values into degrees, degrees and metres.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GeodeticColumns {
    pub(crate) idx: [usize; 3],
    pub(crate) scale: [f64; 3],
}

impl GeodeticColumns {
    /// Columns already in degrees and metres.
    pub(crate) fn unscaled(idx: [usize; 3]) -> Self {
        Self {
            idx,
            scale: [1.0; 3],
        }
    }

    pub(crate) fn read(&self, rec: &StringRecord) -> Result<Geodetic, SkipKind> {
        let v = vector3(rec, self.idx)?;
        Ok(Geodetic {
            lat_deg: v.x * self.scale[0],
            lon_deg: v.y * self.scale[1],
            alt_m: v.z * self.scale[2],
        })
    }
}

/// Optional horizontal (m), vertical (m) and speed (m/s) accuracy columns;
/// an absent column or empty cell is "not reported".
#[derive(Debug, Clone, Copy)]
pub(crate) struct AccuracyColumns([Option<usize>; 3]);

impl AccuracyColumns {
    pub(crate) fn find(table: &CsvTable, names: [&str; 3]) -> Self {
        Self(names.map(|n| table.find(n)))
    }

    pub(crate) fn read(&self, rec: &StringRecord) -> Result<[Option<f64>; 3], SkipKind> {
        Ok([
            optional_number(rec, self.0[0])?,
            optional_number(rec, self.0[1])?,
            optional_number(rec, self.0[2])?,
        ])
    }
}

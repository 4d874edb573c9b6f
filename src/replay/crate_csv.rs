//! Reader of the crate's own CSV format (`docs/csv-format.md`), the format
//! the simulator writes.
//!
//! No unit conversion: times are integer microseconds (`t_us`), angular rate
//! rad/s, specific force m/s² (body FRD), GPS position geodetic
//! (`lat_deg, lon_deg, alt_m`) or local NED (`pos_[ned]_m`; geodetic wins
//! when both are present), velocity NED m/s (down positive), optional
//! accuracies (`h_acc_m, v_acc_m, s_acc_m_s`; empty cell = not reported),
//! magnetometer in any unit. The format has no fix flag, so no row is
//! counted as [`NoFix`](super::SkipKind::NoFix). `truth.csv` is read as the
//! reference: attitude from `q0..q3`, velocity and position NED.

use super::columns::{
    ACCEL_COLUMNS, AccuracyColumns, Clock, GYRO_COLUMNS, GeodeticColumns, ImuLayout, MagLayout,
    TimeUnit, imu_stream, mag_stream,
};
use super::table::{CsvTable, RowParser, RowStream, microseconds, unit_quaternion, vector3};
use super::{
    GpsRow, GpsRowPosition, LogFiles, LogFormat, ReferenceSample, ReplayError, SensorEvent,
    SensorStreams, SkipCounts, SkipKind, named, require,
};
use crate::scalar::Scalar;
use csv::StringRecord;
use std::path::{Path, PathBuf};

/// The time column of every file of the format.
pub const TIME_COLUMN: &str = "t_us";

pub(crate) fn locate(files: &[PathBuf], searched: &str) -> Result<LogFiles, ReplayError> {
    Ok(LogFiles {
        format: LogFormat::Crate,
        imu: require(files, "imu.csv", LogFormat::Crate, searched)?,
        gps: require(files, "gps.csv", LogFormat::Crate, searched)?,
        mag: named(files, "mag.csv").cloned(),
        gps_accuracy: None,
        reference: named(files, "truth.csv").cloned(),
        params: None,
    })
}

/// The crate format's clock: integer microseconds in `t_us`.
const CLOCK: Clock = Clock {
    column: TIME_COLUMN,
    unit: TimeUnit::Microseconds,
};

pub(crate) fn open_streams<T: Scalar>(files: &LogFiles) -> Result<SensorStreams<T>, ReplayError> {
    let imu = ImuLayout {
        clock: CLOCK,
        gyro: GYRO_COLUMNS,
        accel: ACCEL_COLUMNS,
    };
    let mag = MagLayout {
        clock: CLOCK,
        field: ["mag_x", "mag_y", "mag_z"],
        scale: 1.0,
    };
    Ok(SensorStreams {
        imu: imu_stream(&files.imu, &imu, |_| Vec::new())?,
        gps: gps_stream(&files.gps)?,
        mag: files
            .mag
            .as_deref()
            .map(|p| mag_stream(p, &mag, |_| Vec::new()))
            .transpose()?,
    })
}

enum PositionColumns {
    Geodetic(GeodeticColumns),
    Ned([usize; 3]),
}

struct GpsColumns {
    t: usize,
    position: PositionColumns,
    velocity: [usize; 3],
    accuracy: AccuracyColumns,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for GpsColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let position = match self.position {
            PositionColumns::Geodetic(columns) => GpsRowPosition::Geodetic(columns.read(rec)?),
            PositionColumns::Ned(idx) => GpsRowPosition::Ned(vector3(rec, idx)?),
        };
        GpsRow {
            t_us: microseconds(rec, self.t)?,
            position,
            velocity_ned_m_s: vector3(rec, self.velocity)?,
            accuracy: self.accuracy.read(rec)?,
        }
        .into_event()
    }
}

/// The stream of a `gps.csv` of the crate's format.
fn gps_stream<T: Scalar>(path: &Path) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let position = match table.one_of3(&[
        ["lat_deg", "lon_deg", "alt_m"],
        ["pos_n_m", "pos_e_m", "pos_d_m"],
    ])? {
        (0, idx) => PositionColumns::Geodetic(GeodeticColumns::unscaled(idx)),
        (_, idx) => PositionColumns::Ned(idx),
    };
    let parser = GpsColumns {
        t: table.column(TIME_COLUMN)?,
        position,
        velocity: table.columns3(["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"])?,
        accuracy: AccuracyColumns::find(&table, ["h_acc_m", "v_acc_m", "s_acc_m_s"]),
    };
    Ok(RowStream::new(table, Box::new(parser), "gps"))
}

struct TruthColumns {
    t: usize,
    q: [usize; 4],
    velocity: [usize; 3],
    position: [usize; 3],
}

impl RowParser<ReferenceSample> for TruthColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<ReferenceSample, SkipKind> {
        Ok(ReferenceSample {
            t_us: microseconds(rec, self.t)?,
            attitude: unit_quaternion(rec, self.q)?,
            velocity_ned_m_s: Some(vector3(rec, self.velocity)?),
            position_ned_m: Some(vector3(rec, self.position)?),
        })
    }
}

/// The simulator's `truth.csv` as a reference stream.
pub(crate) fn reference_stream(path: &Path) -> Result<RowStream<ReferenceSample>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = TruthColumns {
        t: table.column(TIME_COLUMN)?,
        q: table.columns4(["q0", "q1", "q2", "q3"])?,
        velocity: table.columns3(["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"])?,
        position: table.columns3(["pos_n_m", "pos_e_m", "pos_d_m"])?,
    };
    Ok(RowStream::new(table, Box::new(parser), "truth"))
}

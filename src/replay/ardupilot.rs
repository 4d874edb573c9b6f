//! Reader of an ArduPilot DataFlash log exported to one CSV per message
//! (the layout of `../shared/data/ardupilot-log171`).
//!
//! | file | columns read | conversion |
//! |---|---|---|
//! | `imu.csv` (or `imu2.csv`) | `t_s, gyro_[xyz]_rad_s, acc_[xyz]_m_s2` | `t_us = round(t_s 1e6)`; body FRD, rad/s, m/s² kept |
//! | `gps.csv` | `t_s, fix_status, lat_deg, lon_deg, alt_msl_m, vel_n_m_s, vel_e_m_s, vel_d_m_s` | `fix_status < 3` counted as no-fix; without the `vel_n/vel_e` columns, `v_n = speed cos(course)`, `v_e = speed sin(course)` from `speed_m_s, course_deg` |
//! | `gps_accuracy.csv` | `t_s, hAcc_m, vAcc_m, sAcc_m_s` | joined to the fix with the nearest `t_s` within 50 ms |
//! | `mag.csv` | `t_s, mag_[xyz]_mGauss, health` | mGauss to gauss (÷1000); `health == 0` counted as invalid |
//! | `ekf1_reference.csv` | `t_s, roll_deg, pitch_deg, yaw_deg, vel_*, pos_*` | degrees to the body-to-NED quaternion (ZYX) |
//! | `att.csv` | `t_s, roll_deg, pitch_deg, yaw_deg` | the same |
//! | `params.csv` | `name, value` | `AHRS_TRIM_X/Y` for [`ReferenceAlignment`] |
//!
//! The GPS time is the receive time on the autopilot's clock, which is the
//! clock of the IMU: exactly what the delay estimators need.
//!
//! # Comparing with the onboard attitude
//! The onboard attitude is that of the vehicle frame, the IMU frame with the
//! trim `AHRS_TRIM_X` (roll), `AHRS_TRIM_Y` (pitch) taken off, and its yaw is
//! true heading (the autopilot applied the declination it looked up). Read
//! the trim with [`alignment_from_params`]; log171's values are
//! [`LOG171_ALIGNMENT`].

use super::columns::{
    ACCEL_COLUMNS, Clock, GYRO_COLUMNS, GeodeticColumns, ImuLayout, MagLayout, RowFlag, TimeUnit,
    imu_stream, mag_stream,
};
use super::table::{CsvTable, RowParser, RowStream, number, seconds_as_us, vector3};
use super::{
    ArduPilotImu, ArduPilotReference, GpsRow, GpsRowPosition, LogFiles, LogFormat, ReaderOptions,
    ReferenceAlignment, ReferenceSample, ReplayError, SensorEvent, SensorStreams, SkipCounts,
    SkipKind, named, require,
};
use crate::geo::quaternion_from_euler;
use crate::scalar::Scalar;
use csv::StringRecord;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The time column of every file of the layout, seconds.
pub const TIME_COLUMN: &str = "t_s";

/// Lowest `fix_status` accepted: 3 is a 3-D fix.
pub const MIN_FIX_STATUS: f64 = 3.0;

/// Largest time difference, microseconds, between a fix and the
/// `gps_accuracy.csv` row joined to it.
pub const ACCURACY_JOIN_WINDOW_US: u64 = 50_000;

/// Milligauss per gauss: `mag.csv` is in mGauss, the reader returns gauss.
pub const MILLIGAUSS_PER_GAUSS: f64 = 1000.0;

/// log171's alignment: `AHRS_TRIM_X = 0.0205 rad`, `AHRS_TRIM_Y = 0.0053 rad`
/// (from its `params.csv`), declination +11.8 deg (measured on the log: the
/// median gap between tilt-compensated magnetic heading and onboard yaw;
/// `COMPASS_AUTODEC = 1` looked up about +12 deg at Canberra).
pub const LOG171_ALIGNMENT: ReferenceAlignment = ReferenceAlignment {
    trim_roll_rad: 0.020_519_794_896_245_003,
    trim_pitch_rad: 0.005_281_575_489_789_247_5,
    declination_rad: 11.8 * core::f64::consts::PI / 180.0,
};

pub(crate) fn locate(
    files: &[PathBuf],
    searched: &str,
    options: &ReaderOptions,
) -> Result<LogFiles, ReplayError> {
    let imu_name = match options.ardupilot_imu {
        ArduPilotImu::First => "imu.csv",
        ArduPilotImu::Second => "imu2.csv",
    };
    let reference = match options.ardupilot_reference {
        ArduPilotReference::Ekf1 => {
            named(files, "ekf1_reference.csv").or_else(|| named(files, "att.csv"))
        }
        ArduPilotReference::Att => named(files, "att.csv"),
    };
    Ok(LogFiles {
        format: LogFormat::ArduPilot,
        imu: require(files, imu_name, LogFormat::ArduPilot, searched)?,
        gps: require(files, "gps.csv", LogFormat::ArduPilot, searched)?,
        mag: named(files, "mag.csv").cloned(),
        gps_accuracy: named(files, "gps_accuracy.csv").cloned(),
        reference: reference.cloned(),
        params: named(files, "params.csv").cloned(),
    })
}

/// ArduPilot's clock: seconds in `t_s`.
const CLOCK: Clock = Clock {
    column: TIME_COLUMN,
    unit: TimeUnit::Seconds,
};

pub(crate) fn open_streams<T: Scalar>(files: &LogFiles) -> Result<SensorStreams<T>, ReplayError> {
    let imu = ImuLayout {
        clock: CLOCK,
        gyro: GYRO_COLUMNS,
        accel: ACCEL_COLUMNS,
    };
    let mag = MagLayout {
        clock: CLOCK,
        field: ["mag_x_mGauss", "mag_y_mGauss", "mag_z_mGauss"],
        scale: 1.0 / MILLIGAUSS_PER_GAUSS,
    };
    let unhealthy = |table: &CsvTable| {
        vec![RowFlag {
            column: table.find("health"),
            rejects: |health| health == 0.0,
            kind: SkipKind::Invalid,
        }]
    };
    Ok(SensorStreams {
        imu: imu_stream(&files.imu, &imu, |_| Vec::new())?,
        gps: gps_stream(&files.gps, files.gps_accuracy.as_deref())?,
        mag: files
            .mag
            .as_deref()
            .map(|p| mag_stream(p, &mag, unhealthy))
            .transpose()?,
    })
}

/// Where the NED velocity comes from.
enum VelocityColumns {
    /// `vel_n_m_s, vel_e_m_s, vel_d_m_s`.
    Ned([usize; 3]),
    /// Ground speed (m/s), course over ground (deg, clockwise from true
    /// north) and vertical velocity (down positive).
    SpeedCourse {
        speed: usize,
        course: usize,
        down: usize,
    },
}

impl VelocityColumns {
    fn read(&self, rec: &StringRecord) -> Result<Vector3<f64>, SkipKind> {
        match *self {
            Self::Ned(idx) => vector3(rec, idx),
            Self::SpeedCourse {
                speed,
                course,
                down,
            } => {
                let (s, c) = (number(rec, speed)?, number(rec, course)?);
                Ok(ned_from_speed_course(s, c, number(rec, down)?))
            }
        }
    }
}

/// NED velocity from ground speed (m/s), course over ground (deg, clockwise
/// from true north) and vertical velocity (m/s, down positive):
/// `v_n = speed cos(course)`, `v_e = speed sin(course)`.
pub(crate) fn ned_from_speed_course(
    speed_m_s: f64,
    course_deg: f64,
    down_m_s: f64,
) -> Vector3<f64> {
    let c = course_deg.to_radians();
    Vector3::new(speed_m_s * c.cos(), speed_m_s * c.sin(), down_m_s)
}

/// One row of `gps_accuracy.csv` (or one receiver-accuracy record of a
/// DataFlash log).
#[derive(Clone, Copy)]
pub(crate) struct Accuracy {
    pub(crate) t_us: u64,
    pub(crate) horizontal_m: f64,
    pub(crate) vertical_m: f64,
    pub(crate) speed_m_s: f64,
}

impl Accuracy {
    /// The accuracy from the horizontal, vertical and speed values; a
    /// non-positive one is `OutOfRange`.
    pub(crate) fn new(t_us: u64, values: Vector3<f64>) -> Result<Self, SkipKind> {
        if values.iter().any(|&a| a <= 0.0) {
            return Err(SkipKind::OutOfRange);
        }
        Ok(Self {
            t_us,
            horizontal_m: values.x,
            vertical_m: values.y,
            speed_m_s: values.z,
        })
    }

    /// The three accuracies as a GPS row holds them.
    pub(crate) fn as_row(self) -> [Option<f64>; 3] {
        [
            Some(self.horizontal_m),
            Some(self.vertical_m),
            Some(self.speed_m_s),
        ]
    }
}

/// The streaming join of `gps_accuracy.csv` to the fixes: the accuracy rows
/// just before and just after the fix time are held, the nearest one within
/// [`ACCURACY_JOIN_WINDOW_US`] is used.
pub(crate) struct AccuracyJoin {
    stream: RowStream<AccuracyRow>,
    before: Option<Accuracy>,
    after: Option<Accuracy>,
    exhausted: bool,
}

/// Wrapper so an accuracy row can go through [`RowStream`].
pub(crate) struct AccuracyRow(pub(crate) Accuracy);

impl super::Timed for AccuracyRow {
    fn time_us(&self) -> u64 {
        self.0.t_us
    }
}

struct AccuracyColumns {
    t: usize,
    values: [usize; 3],
}

impl RowParser<AccuracyRow> for AccuracyColumns {
    fn parse(&mut self, rec: &StringRecord, _: &mut SkipCounts) -> Result<AccuracyRow, SkipKind> {
        let v = vector3(rec, self.values)?;
        Ok(AccuracyRow(Accuracy::new(seconds_as_us(rec, self.t)?, v)?))
    }
}

impl AccuracyJoin {
    fn open(path: &Path) -> Result<Self, ReplayError> {
        let table = CsvTable::open(path)?;
        let parser = AccuracyColumns {
            t: table.column(TIME_COLUMN)?,
            values: table.columns3(["hAcc_m", "vAcc_m", "sAcc_m_s"])?,
        };
        Ok(Self::from_stream(RowStream::new(
            table,
            Box::new(parser),
            "gps_accuracy",
        )))
    }

    /// The join over any stream of accuracy rows.
    pub(crate) fn from_stream(stream: RowStream<AccuracyRow>) -> Self {
        Self {
            stream,
            before: None,
            after: None,
            exhausted: false,
        }
    }

    /// The accuracy row nearest to `t_us` within the window. Fix times
    /// increase, so rows behind the current fix are dropped as it goes.
    pub(crate) fn at(&mut self, t_us: u64, skips: &mut SkipCounts) -> Option<Accuracy> {
        loop {
            match self.after {
                Some(a) if a.t_us <= t_us => self.before = self.after.take(),
                Some(_) => break,
                None if self.exhausted => break,
                None => match self.stream.next_value(skips) {
                    Some(AccuracyRow(a)) => self.after = Some(a),
                    None => self.exhausted = true,
                },
            }
        }
        [self.before, self.after]
            .into_iter()
            .flatten()
            .map(|a| (a.t_us.abs_diff(t_us), a))
            .filter(|&(gap, _)| gap <= ACCURACY_JOIN_WINDOW_US)
            .min_by_key(|&(gap, _)| gap)
            .map(|(_, a)| a)
    }
}

struct GpsColumns {
    t: usize,
    fix: RowFlag,
    position: GeodeticColumns,
    velocity: VelocityColumns,
    accuracy: Option<AccuracyJoin>,
}

impl<T: Scalar> RowParser<SensorEvent<T>> for GpsColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        skips: &mut SkipCounts,
    ) -> Result<SensorEvent<T>, SkipKind> {
        let t_us = seconds_as_us(rec, self.t)?;
        self.fix.check(rec)?;
        let position = GpsRowPosition::Geodetic(self.position.read(rec)?);
        let velocity_ned_m_s = self.velocity.read(rec)?;
        let accuracy = self.accuracy.as_mut().and_then(|join| join.at(t_us, skips));
        GpsRow {
            t_us,
            position,
            velocity_ned_m_s,
            accuracy: accuracy.map_or([None; 3], Accuracy::as_row),
        }
        .into_event()
    }
}

fn gps_stream<T: Scalar>(
    path: &Path,
    accuracy: Option<&Path>,
) -> Result<RowStream<SensorEvent<T>>, ReplayError> {
    let table = CsvTable::open(path)?;
    let velocity = match table.columns3(["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"]) {
        Ok(idx) => VelocityColumns::Ned(idx),
        Err(_) => VelocityColumns::SpeedCourse {
            speed: table.column("speed_m_s")?,
            course: table.column("course_deg")?,
            down: table.column("vel_d_m_s")?,
        },
    };
    let parser = GpsColumns {
        t: table.column(TIME_COLUMN)?,
        fix: RowFlag {
            column: Some(table.column("fix_status")?),
            rejects: |status| status < MIN_FIX_STATUS,
            kind: SkipKind::NoFix,
        },
        position: GeodeticColumns::unscaled(table.columns3(["lat_deg", "lon_deg", "alt_msl_m"])?),
        velocity,
        accuracy: accuracy.map(AccuracyJoin::open).transpose()?,
    };
    Ok(RowStream::new(table, Box::new(parser), "gps"))
}

struct ReferenceColumns {
    t: usize,
    euler_deg: [usize; 3],
    velocity: Option<[usize; 3]>,
    position: Option<[usize; 3]>,
}

impl RowParser<ReferenceSample> for ReferenceColumns {
    fn parse(
        &mut self,
        rec: &StringRecord,
        _: &mut SkipCounts,
    ) -> Result<ReferenceSample, SkipKind> {
        let e = vector3(rec, self.euler_deg)?.map(f64::to_radians);
        Ok(ReferenceSample {
            t_us: seconds_as_us(rec, self.t)?,
            attitude: quaternion_from_euler(e.x, e.y, e.z),
            velocity_ned_m_s: self.velocity.map(|idx| vector3(rec, idx)).transpose()?,
            position_ned_m: self.position.map(|idx| vector3(rec, idx)).transpose()?,
        })
    }
}

/// `ekf1_reference.csv` or `att.csv` as a reference stream (velocity and
/// position when the file has them).
pub(crate) fn reference_stream(path: &Path) -> Result<RowStream<ReferenceSample>, ReplayError> {
    let table = CsvTable::open(path)?;
    let parser = ReferenceColumns {
        t: table.column(TIME_COLUMN)?,
        euler_deg: table.columns3(["roll_deg", "pitch_deg", "yaw_deg"])?,
        velocity: table.columns3(["vel_n_m_s", "vel_e_m_s", "vel_d_m_s"]).ok(),
        position: table.columns3(["pos_n_m", "pos_e_m", "pos_d_m"]).ok(),
    };
    Ok(RowStream::new(table, Box::new(parser), "reference"))
}

/// Reads `params.csv` (`name,value`) into a map. Rows whose value is not a
/// number are left out of the map and counted in `skips`.
pub fn read_params(
    path: &Path,
    skips: &mut SkipCounts,
) -> Result<BTreeMap<String, f64>, ReplayError> {
    let mut table = CsvTable::open(path)?;
    let (name, value) = (table.column("name")?, table.column("value")?);
    let label = table.label().to_string();
    let mut params = BTreeMap::new();
    while let Some(rec) = table.next_record(skips) {
        match (rec.get(name), number(rec, value)) {
            (Some(n), Ok(v)) if !n.is_empty() => {
                params.insert(n.to_string(), v);
                skips.accept(&label);
            }
            (_, Err(kind)) => skips.skip(&label, kind),
            _ => skips.skip(&label, SkipKind::Unparsable),
        }
    }
    Ok(params)
}

/// The alignment of an ArduPilot log's reference: trim from `AHRS_TRIM_X`
/// and `AHRS_TRIM_Y` when the parameters have them (else zero), and the
/// given declination (ArduPilot does not log the value `COMPASS_AUTODEC`
/// looked up; `COMPASS_DEC` holds it only when set by hand, so it is used
/// when `COMPASS_AUTODEC` is 0).
pub fn alignment_from_params(
    params: &BTreeMap<String, f64>,
    declination_rad: f64,
) -> ReferenceAlignment {
    let manual_declination = params.get("COMPASS_AUTODEC") == Some(&0.0);
    ReferenceAlignment {
        trim_roll_rad: params.get("AHRS_TRIM_X").copied().unwrap_or(0.0),
        trim_pitch_rad: params.get("AHRS_TRIM_Y").copied().unwrap_or(0.0),
        declination_rad: match params.get("COMPASS_DEC") {
            Some(&d) if manual_declination => d,
            _ => declination_rad,
        },
    }
}

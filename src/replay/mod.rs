//! Log replay (feature `replay`): streaming readers that turn a vehicle's log
//! into one time-ordered stream of the crate's sensor types.
//!
//! Three layouts are read (details, units and caveats in `docs/replay.md`):
//!
//! | [`LogFormat`] | files | conversions |
//! |---|---|---|
//! | [`Crate`](LogFormat::Crate) | `imu.csv`, `gps.csv`, `mag.csv` of `docs/csv-format.md` | none |
//! | [`ArduPilot`](LogFormat::ArduPilot) | DataFlash log exported to CSV (`imu.csv`, `gps.csv`, `gps_accuracy.csv`, `mag.csv`) | seconds to µs, mGauss to gauss, speed/course to NED velocity when the NED columns are absent |
//! | [`Px4`](LogFormat::Px4) | `ulog2csv` output `<log>_<topic>_<instance>.csv` | 1e-7 deg and mm to deg and m (older GPS layout) |
//! | [`DataFlash`](LogFormat::DataFlash) | ArduPilot DataFlash `.bin`, starts `A3 95` ([`dataflash`]) | as the ArduPilot CSV, from the records' format letters |
//! | [`Ulog`](LogFormat::Ulog) | PX4 ULog `.ulg`, starts `ULog` ([`ulog`]) | as the PX4 CSV |
//!
//! A single file given as the log is recognised by its first bytes; a
//! directory is a CSV layout.
//!
//! # Streaming
//! Each file has its own CSV reader and holds one parsed row at a time; the
//! [`LogReader`] merges the per-file streams by timestamp (a k-way merge over
//! the head of each stream). Equal timestamps come out IMU first, then
//! magnetometer, then GPS ([`StreamKind`]'s order), so a GPS fix received at
//! the instant of an IMU sample is fused after that sample is integrated.
//! Times in seconds become integer microseconds by rounding:
//! `t_us = round(t_s * 1e6)`.
//!
//! # Bad rows
//! Nothing is dropped in silence. A row is skipped and counted in
//! [`SkipCounts`], by [`SkipKind`] and by file, when it cannot be parsed,
//! holds a NaN or infinity, is out of range (negative time, latitude beyond
//! 90 deg, zero magnetic field, non-positive accuracy), is flagged invalid by
//! the logger, has no 3-D fix, or is not later than the previous accepted row
//! of its file (time going backwards, duplicate).
//!
//! # Reference
//! A log may carry an onboard solution to compare against: the simulator's
//! `truth.csv`, ArduPilot's `ekf1_reference.csv` or `att.csv`, PX4's
//! `vehicle_attitude`. [`ReferenceReader`] streams it as [`ReferenceSample`]s;
//! [`ReferenceAlignment`] holds the mounting trim and declination needed to
//! compare like with like.
//!
//! # Replaying through the estimators
//! [`replay`] drives one estimator through a log and scores it. The whole
//! replay `delaynav replay` runs is [`session`]: [`ReplayOptions`] to a
//! [`ReplaySetup`] (defaults derived from the log, a TOML file of
//! [`config_file`] merged over them), run through the [`ESTIMATORS`] into a
//! [`ReplayReport`] (its JSON summary and console text).

mod columns;
mod error;
mod skips;
mod table;

pub mod ardupilot;
pub mod config_file;
pub mod crate_csv;
pub mod dataflash;
pub mod defaults;
pub mod estimates_csv;
mod levels;
pub mod px4;
mod reference;
pub mod run;
pub mod session;
pub mod ulog;
pub mod window;

pub use defaults::{ImuNoise, LogDefaults, MagneticModel, NoiseSource, log_date, magnetic_model};
pub use error::{ReplayError, seconds_to_us};
pub use estimates_csv::EstimateWriter;
pub use levels::{LevelSummary, ReplayIntegrity};
pub use reference::{ReferenceAlignment, ReferenceReader, ReferenceSample};
pub use run::{
    DelayStep, DelayStepSummary, DelayWindow, FusionRecords, ReferenceRms, RunOptions, RunSummary,
    WindowAxis, inclination_at_rest, replay, replay_with,
};
pub use session::{
    ESTIMATORS, EstimatorReport, HealthSummary, RegisteredEstimator, ReplayObserver, ReplayOptions,
    ReplayReport, ReplaySetup, select_estimators,
};
pub use skips::{FileCounts, SkipCounts, SkipKind};
pub use window::{FlightWindow, flight_window};

use crate::geo::quaternion_from_euler;
use crate::scalar::Scalar;
use crate::sensors::{Geodetic, Gps, GpsPosition, Imu, Mag, checked_gps, checked_imu, checked_mag};
use nalgebra::{UnitQuaternion, Vector3};
use std::fmt;
use std::path::{Path, PathBuf};
use table::RowStream;

/// One sample of the merged stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorEvent<T: Scalar> {
    /// An IMU sample.
    Imu(Imu<T>),
    /// A GPS fix, stamped with its receive time.
    Gps(Gps<T>),
    /// A magnetometer sample.
    Mag(Mag<T>),
}

impl<T: Scalar> SensorEvent<T> {
    /// The sample's timestamp, microseconds.
    pub fn time_us(&self) -> u64 {
        match self {
            Self::Imu(s) => s.t_us,
            Self::Gps(s) => s.t_us,
            Self::Mag(s) => s.t_us,
        }
    }

    /// Which stream the sample belongs to.
    pub fn kind(&self) -> StreamKind {
        match self {
            Self::Imu(_) => StreamKind::Imu,
            Self::Gps(_) => StreamKind::Gps,
            Self::Mag(_) => StreamKind::Mag,
        }
    }
}

/// The three sensor streams, in the order the merge emits equal timestamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum StreamKind {
    /// Inertial samples come first at a tie.
    Imu,
    /// Then magnetometer samples.
    Mag,
    /// GPS fixes last.
    Gps,
}

/// Anything with a timestamp in microseconds (rows of every stream).
pub(crate) trait Timed {
    fn time_us(&self) -> u64;
}

impl<T: Scalar> Timed for SensorEvent<T> {
    fn time_us(&self) -> u64 {
        SensorEvent::time_us(self)
    }
}

impl Timed for ReferenceSample {
    fn time_us(&self) -> u64 {
        self.t_us
    }
}

/// The log layouts the readers understand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LogFormat {
    /// The crate's own CSV format (`docs/csv-format.md`).
    Crate,
    /// ArduPilot DataFlash log exported to per-message CSV files.
    ArduPilot,
    /// PX4 ULog exported by `ulog2csv`.
    Px4,
    /// ArduPilot DataFlash binary log (`.bin`).
    DataFlash,
    /// PX4 ULog binary log (`.ulg`).
    Ulog,
}

impl LogFormat {
    /// The name used on command lines: `csv`, `ardupilot`, `px4`, `bin`, `ulg`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Crate => "csv",
            Self::ArduPilot => "ardupilot",
            Self::Px4 => "px4",
            Self::DataFlash => "bin",
            Self::Ulog => "ulg",
        }
    }

    /// The binary format a file starts with: `ULog` is PX4 ULog, `A3 95`
    /// an ArduPilot DataFlash log; `Ok(None)` for anything else.
    pub fn sniff(path: &Path) -> Result<Option<Self>, ReplayError> {
        use std::io::Read;
        let mut head = [0u8; 4];
        let mut file = std::fs::File::open(path).map_err(|source| ReplayError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        let mut read = 0;
        while read < head.len() {
            match file.read(&mut head[read..]) {
                Ok(0) => break,
                Ok(n) => read += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(ReplayError::Open {
                        path: path.to_path_buf(),
                        source,
                    });
                }
            }
        }
        Ok(if head[..read].starts_with(ulog::MAGIC) {
            Some(Self::Ulog)
        } else if head[..read].starts_with(&dataflash::RECORD_HEADER) {
            Some(Self::DataFlash)
        } else {
            None
        })
    }

    /// Parses a command-line name; `auto` gives `Ok(None)`.
    pub fn parse_choice(name: &str) -> Result<Option<Self>, ReplayError> {
        match name {
            "auto" => Ok(None),
            "csv" | "crate" => Ok(Some(Self::Crate)),
            "ardupilot" => Ok(Some(Self::ArduPilot)),
            "px4" => Ok(Some(Self::Px4)),
            "bin" | "dataflash" => Ok(Some(Self::DataFlash)),
            "ulg" | "ulog" => Ok(Some(Self::Ulog)),
            other => Err(ReplayError::UnknownFormatName(other.to_string())),
        }
    }
}

impl fmt::Display for LogFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which of ArduPilot's two IMUs to read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ArduPilotImu {
    /// `imu.csv` (the primary IMU).
    #[default]
    First,
    /// `imu2.csv`.
    Second,
}

/// Which onboard solution of an ArduPilot log is the reference.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ArduPilotReference {
    /// `ekf1_reference.csv`: attitude, velocity and position of the onboard EKF.
    #[default]
    Ekf1,
    /// `att.csv`: the AHRS attitude only.
    Att,
}

/// Choices made when opening a log.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReaderOptions {
    /// Added to every GPS receive time, microseconds: the added-delay
    /// experiment (the paper's Table 7). The merge keeps the stream ordered.
    pub gps_delay_added_us: u64,
    /// The delay is added to the fixes received at or after this time
    /// (on the log's clock, before the shift), microseconds; 0: every fix.
    /// A later start makes a step of the delay in the middle of a log: the
    /// fixes after it arrive `gps_delay_added_us` later, still in order.
    pub gps_delay_added_from_us: u64,
    /// ArduPilot CSV: which IMU file.
    pub ardupilot_imu: ArduPilotImu,
    /// Binary logs: which IMU (DataFlash `IMU` instance, ULog
    /// `sensor_combined` multi-id); 0 is the first.
    pub imu_instance: u8,
    /// ArduPilot: which reference file.
    pub ardupilot_reference: ArduPilotReference,
    /// Drop every magnetometer record: the log replayed as if it had no
    /// magnetometer (heading from the GPS velocity and the IMU alone).
    pub drop_mag: bool,
}

impl ReaderOptions {
    /// These options with `delay_s` seconds added to the receive time of
    /// every fix received at or after `from_s` seconds (`None`: from the
    /// start). A negative, NaN or infinite value is
    /// [`ReplayError::InvalidSeconds`]; huge values saturate.
    pub fn with_added_gps_delay(
        self,
        delay_s: f64,
        from_s: Option<f64>,
    ) -> Result<Self, ReplayError> {
        Ok(Self {
            gps_delay_added_us: seconds_to_us("added GPS delay", delay_s)?,
            gps_delay_added_from_us: match from_s {
                Some(from) => seconds_to_us("start of the added GPS delay", from)?,
                None => 0,
            },
            ..self
        })
    }
}

/// The files of one log, found from directories and/or file paths.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogFiles {
    /// The layout.
    pub format: LogFormat,
    /// IMU file.
    pub imu: PathBuf,
    /// GPS file.
    pub gps: PathBuf,
    /// Magnetometer file, if the log has one.
    pub mag: Option<PathBuf>,
    /// ArduPilot receiver accuracies (`gps_accuracy.csv`), joined to the fixes.
    pub gps_accuracy: Option<PathBuf>,
    /// Onboard reference (truth, onboard EKF or AHRS), if present.
    pub reference: Option<PathBuf>,
    /// ArduPilot parameters (`params.csv`), if present.
    pub params: Option<PathBuf>,
}

impl LogFiles {
    /// Finds the files of a log. Each input is a directory (its files are
    /// used) or a file. With `format == None` the layout is detected: PX4
    /// when a `*_sensor_combined_*.csv` is present, else from the time column
    /// of `imu.csv` (`t_us`: the crate's format, `t_s`: ArduPilot).
    pub fn locate<P: AsRef<Path>>(
        inputs: &[P],
        format: Option<LogFormat>,
        options: &ReaderOptions,
    ) -> Result<Self, ReplayError> {
        if let [single] = inputs
            && single.as_ref().is_file()
        {
            let path = single.as_ref();
            let binary = match format {
                Some(f @ (LogFormat::DataFlash | LogFormat::Ulog)) => Some(f),
                Some(_) => None,
                None => LogFormat::sniff(path)?,
            };
            if let Some(format) = binary {
                return Ok(Self::binary(path, format));
            }
        }
        let files = list_files(inputs)?;
        let searched = inputs
            .iter()
            .map(|p| p.as_ref().display().to_string())
            .collect::<Vec<_>>()
            .join(", ");
        let format = match format {
            Some(f) => f,
            None => detect_format(&files, &searched)?,
        };
        match format {
            LogFormat::Crate => crate_csv::locate(&files, &searched),
            LogFormat::ArduPilot => ardupilot::locate(&files, &searched, options),
            LogFormat::Px4 => px4::locate(&files, &searched),
            LogFormat::DataFlash | LogFormat::Ulog => Err(ReplayError::UnknownFormat { searched }),
        }
    }

    /// A binary log: every stream, the reference and the parameters come
    /// from the one file.
    fn binary(path: &Path, format: LogFormat) -> Self {
        Self {
            format,
            imu: path.to_path_buf(),
            gps: path.to_path_buf(),
            mag: Some(path.to_path_buf()),
            gps_accuracy: None,
            reference: Some(path.to_path_buf()),
            params: Some(path.to_path_buf()),
        }
    }
}

/// The files named by the inputs: directories are listed (not recursively), in name order.
fn list_files<P: AsRef<Path>>(inputs: &[P]) -> Result<Vec<PathBuf>, ReplayError> {
    let mut files = Vec::new();
    for input in inputs.iter().map(AsRef::as_ref) {
        if input.is_dir() {
            let entries = std::fs::read_dir(input).map_err(|source| ReplayError::Open {
                path: input.to_path_buf(),
                source,
            })?;
            let mut found: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect();
            found.sort();
            files.extend(found);
        } else if input.is_file() {
            files.push(input.to_path_buf());
        } else {
            return Err(ReplayError::Open {
                path: input.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no such file or directory",
                ),
            });
        }
    }
    Ok(files)
}

/// The file of `files` with exactly this file name.
pub(crate) fn named<'a>(files: &'a [PathBuf], name: &str) -> Option<&'a PathBuf> {
    files
        .iter()
        .find(|p| p.file_name().is_some_and(|n| n == name))
}

fn detect_format(files: &[PathBuf], searched: &str) -> Result<LogFormat, ReplayError> {
    if px4::find_topic(files, px4::IMU_TOPIC).is_some() {
        return Ok(LogFormat::Px4);
    }
    if let Some(imu) = named(files, "imu.csv") {
        let table = table::CsvTable::open(imu)?;
        if table.find(crate_csv::TIME_COLUMN).is_some() {
            return Ok(LogFormat::Crate);
        }
        if table.find(ardupilot::TIME_COLUMN).is_some() {
            return Ok(LogFormat::ArduPilot);
        }
    }
    Err(ReplayError::UnknownFormat {
        searched: searched.to_string(),
    })
}

/// The required file `name`, or the error naming it.
pub(crate) fn require(
    files: &[PathBuf],
    name: &'static str,
    format: LogFormat,
    searched: &str,
) -> Result<PathBuf, ReplayError> {
    required(named(files, name), name, format, searched)
}

/// The required file `what` of a `format` log, if `found`, or the error
/// naming it.
pub(crate) fn required(
    found: Option<&PathBuf>,
    what: &'static str,
    format: LogFormat,
    searched: &str,
) -> Result<PathBuf, ReplayError> {
    found.cloned().ok_or_else(|| ReplayError::MissingFile {
        what,
        format,
        searched: searched.to_string(),
    })
}

/// The per-file streams of one log.
pub(crate) struct SensorStreams<T: Scalar> {
    pub(crate) imu: RowStream<SensorEvent<T>>,
    pub(crate) gps: RowStream<SensorEvent<T>>,
    pub(crate) mag: Option<RowStream<SensorEvent<T>>>,
}

/// One file's stream inside the merge, with the sample at its head.
struct MergeInput<T: Scalar> {
    stream: RowStream<SensorEvent<T>>,
    head: Option<SensorEvent<T>>,
    shift_us: u64,
    shift_from_us: u64,
}

impl<T: Scalar> MergeInput<T> {
    fn advance(&mut self, skips: &mut SkipCounts) {
        self.head = self.stream.next_value(skips).map(|mut e| {
            if let SensorEvent::Gps(g) = &mut e
                && g.t_us >= self.shift_from_us
            {
                // Saturates instead of overflowing: a receive time within
                // the added delay of u64::MAX µs (584,000 years) is kept
                // at u64::MAX, still after every earlier sample.
                g.t_us = g.t_us.saturating_add(self.shift_us);
            }
            e
        });
    }
}

/// The merged, time-ordered stream of a log's IMU, GPS and magnetometer
/// samples. Iterate it; read [`skip_counts`](Self::skip_counts) at any time
/// (complete once the iterator has ended).
pub struct LogReader<T: Scalar> {
    inputs: Vec<MergeInput<T>>,
    skips: SkipCounts,
    format: LogFormat,
}

impl<T: Scalar> LogReader<T> {
    /// Opens the files of a log (see [`LogFiles::locate`]).
    pub fn open(files: &LogFiles, options: &ReaderOptions) -> Result<Self, ReplayError> {
        let (streams, skips) = match files.format {
            LogFormat::Crate => (crate_csv::open_streams(files)?, SkipCounts::default()),
            LogFormat::ArduPilot => (ardupilot::open_streams(files)?, SkipCounts::default()),
            LogFormat::Px4 => (px4::open_streams(files)?, SkipCounts::default()),
            LogFormat::DataFlash => dataflash::open_streams(&files.imu, options.imu_instance)?,
            LogFormat::Ulog => ulog::open_streams(&files.imu, options.imu_instance)?,
        };
        let input = |stream, shift_us| MergeInput {
            stream,
            head: None,
            shift_us,
            shift_from_us: options.gps_delay_added_from_us,
        };
        let mut inputs = vec![
            input(streams.imu, 0),
            input(streams.gps, options.gps_delay_added_us),
        ];
        if !options.drop_mag {
            inputs.extend(streams.mag.map(|m| input(m, 0)));
        }
        let mut reader = Self {
            inputs,
            skips,
            format: files.format,
        };
        for input in &mut reader.inputs {
            input.advance(&mut reader.skips);
        }
        Ok(reader)
    }

    /// Locates and opens a log in one call.
    pub fn open_paths<P: AsRef<Path>>(
        inputs: &[P],
        format: Option<LogFormat>,
        options: &ReaderOptions,
    ) -> Result<Self, ReplayError> {
        Self::open(&LogFiles::locate(inputs, format, options)?, options)
    }

    /// Rows accepted and skipped so far, by file and kind.
    pub fn skip_counts(&self) -> &SkipCounts {
        &self.skips
    }

    /// The layout being read.
    pub fn format(&self) -> LogFormat {
        self.format
    }

    /// The names of the files being merged.
    pub fn file_names(&self) -> Vec<&str> {
        self.inputs.iter().map(|i| i.stream.label()).collect()
    }

    /// Rows or records read so far (accepted and skipped) per stream:
    /// once the iterator has ended, the samples each stream of the log holds.
    pub fn stream_counts(&self) -> StreamCounts {
        let read = |i: usize| {
            self.inputs.get(i).map_or(0, |input| {
                self.skips
                    .file(input.stream.label())
                    .map_or(0, |c| c.accepted + c.skipped_total())
            })
        };
        StreamCounts {
            imu: read(0),
            gps: read(1),
            mag: read(2),
        }
    }
}

impl<T: Scalar> Iterator for LogReader<T> {
    type Item = SensorEvent<T>;

    fn next(&mut self) -> Option<SensorEvent<T>> {
        let next = self
            .inputs
            .iter()
            .enumerate()
            .filter_map(|(i, input)| input.head.map(|e| ((e.time_us(), e.kind()), i)))
            .min()?
            .1;
        let event = self.inputs[next].head.take();
        self.inputs[next].advance(&mut self.skips);
        event
    }
}

/// Rows or records per stream of a log ([`LogReader::stream_counts`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// IMU samples.
    pub imu: u64,
    /// GPS fixes (with or without a fix).
    pub gps: u64,
    /// Magnetometer samples.
    pub mag: u64,
}

/// An IMU event from `f64` values, checked like the estimators check it.
pub(crate) fn imu_event<T: Scalar>(
    t_us: u64,
    gyro_rad_s: Vector3<f64>,
    accel_m_s2: Vector3<f64>,
) -> Result<SensorEvent<T>, SkipKind> {
    let imu = Imu {
        t_us,
        gyro_rad_s: gyro_rad_s.map(T::lit),
        accel_m_s2: accel_m_s2.map(T::lit),
    };
    Ok(SensorEvent::Imu(checked_imu(&imu)?))
}

/// A magnetometer event from `f64` values, checked.
pub(crate) fn mag_event<T: Scalar>(
    t_us: u64,
    field_body: Vector3<f64>,
) -> Result<SensorEvent<T>, SkipKind> {
    let mag = Mag {
        t_us,
        field_body: field_body.map(T::lit),
    };
    Ok(SensorEvent::Mag(checked_mag(&mag)?))
}

/// GPS values as read, before conversion to `T`.
pub(crate) struct GpsRow {
    pub(crate) t_us: u64,
    pub(crate) position: GpsRowPosition,
    pub(crate) velocity_ned_m_s: Vector3<f64>,
    /// Horizontal (m), vertical (m) and speed (m/s) accuracy, if reported.
    pub(crate) accuracy: [Option<f64>; 3],
}

/// A GPS position as read.
pub(crate) enum GpsRowPosition {
    Geodetic(Geodetic),
    Ned(Vector3<f64>),
}

impl GpsRow {
    /// The checked GPS event.
    pub(crate) fn into_event<T: Scalar>(self) -> Result<SensorEvent<T>, SkipKind> {
        if let GpsRowPosition::Geodetic(g) = &self.position
            && g.lat_deg.abs() > 90.0
        {
            return Err(SkipKind::OutOfRange);
        }
        let gps = Gps {
            t_us: self.t_us,
            position: match self.position {
                GpsRowPosition::Geodetic(g) => GpsPosition::Geodetic(g),
                GpsRowPosition::Ned(p) => GpsPosition::Ned(p.map(T::lit)),
            },
            velocity_ned_m_s: self.velocity_ned_m_s.map(T::lit),
            horizontal_accuracy_m: self.accuracy[0].map(T::lit),
            vertical_accuracy_m: self.accuracy[1].map(T::lit),
            speed_accuracy_m_s: self.accuracy[2].map(T::lit),
        };
        Ok(SensorEvent::Gps(checked_gps(&gps)?))
    }
}

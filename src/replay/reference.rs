//! A log's onboard reference solution (attitude, velocity, position), read
//! in time order, and its alignment to the estimators' body frame.

use super::*;

/// One sample of a log's onboard reference solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSample {
    /// Time, microseconds.
    pub t_us: u64,
    /// Body-to-NED attitude as the log reports it (before any
    /// [`ReferenceAlignment`]).
    pub attitude: UnitQuaternion<f64>,
    /// Velocity NED, m/s, when the reference has it.
    pub velocity_ned_m_s: Option<Vector3<f64>>,
    /// Position NED, metres, about the reference's own origin, when present.
    pub position_ned_m: Option<Vector3<f64>>,
}

/// The reference solution of a log, streamed in time order.
pub struct ReferenceReader {
    stream: RowStream<ReferenceSample>,
    skips: SkipCounts,
}

impl ReferenceReader {
    /// Opens the reference of a log; `Ok(None)` when the log has none.
    pub fn open(files: &LogFiles) -> Result<Option<Self>, ReplayError> {
        let Some(path) = &files.reference else {
            return Ok(None);
        };
        let stream = match files.format {
            LogFormat::Crate => crate_csv::reference_stream(path)?,
            LogFormat::ArduPilot => ardupilot::reference_stream(path)?,
            LogFormat::Px4 => px4::reference_stream(path)?,
            LogFormat::DataFlash => dataflash::reference_stream(path)?,
            LogFormat::Ulog => ulog::reference_stream(path)?,
        };
        Ok(Some(Self {
            stream,
            skips: SkipCounts::default(),
        }))
    }

    /// Rows accepted and skipped so far.
    pub fn skip_counts(&self) -> &SkipCounts {
        &self.skips
    }

    /// The reference file's name.
    pub fn file_name(&self) -> &str {
        self.stream.label()
    }
}

impl Iterator for ReferenceReader {
    type Item = ReferenceSample;

    fn next(&mut self) -> Option<ReferenceSample> {
        self.stream.next_value(&mut self.skips)
    }
}

/// What separates a log's reference attitude from the crate's estimate of
/// the IMU's attitude.
///
/// - **Mounting trim.** Autopilots report the attitude of the vehicle frame,
///   the IMU frame rotated by a small trim (ArduPilot `AHRS_TRIM_X` roll,
///   `AHRS_TRIM_Y` pitch). The crate estimates the IMU frame, so
///   `q_imu = q_vehicle ⊗ q_trim` with `q_trim = quaternion_from_euler(trim_x, trim_y, 0)`:
///   level vehicle frame, IMU rolled by `trim_x`.
/// - **Declination.** An onboard yaw is true heading when the autopilot
///   applied a declination `D` (east positive). An estimator run with a
///   magnetic model of declination `D_est` reports yaw that differs by
///   `D - D_est`; [`align_estimate`](Self::align_estimate) rotates it by
///   that about NED down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceAlignment {
    /// Roll trim, radians (ArduPilot `AHRS_TRIM_X`).
    pub trim_roll_rad: f64,
    /// Pitch trim, radians (ArduPilot `AHRS_TRIM_Y`).
    pub trim_pitch_rad: f64,
    /// Declination the reference yaw includes, radians east of true north.
    pub declination_rad: f64,
}

impl Default for ReferenceAlignment {
    /// No trim, no declination: the reference describes the IMU frame
    /// (the simulator's truth).
    fn default() -> Self {
        Self {
            trim_roll_rad: 0.0,
            trim_pitch_rad: 0.0,
            declination_rad: 0.0,
        }
    }
}

impl ReferenceAlignment {
    /// The estimate of the IMU attitude, made from an estimator whose
    /// magnetic model used declination `estimator_declination_rad`,
    /// expressed as the reference reports attitude:
    /// `Rz(D - D_est) ⊗ q_est ⊗ q_trim⁻¹`.
    pub fn align_estimate(
        &self,
        estimate: &UnitQuaternion<f64>,
        estimator_declination_rad: f64,
    ) -> UnitQuaternion<f64> {
        let yaw = quaternion_from_euler(0.0, 0.0, self.declination_rad - estimator_declination_rad);
        yaw * estimate * self.trim().inverse()
    }

    /// The trim rotation `q_trim` (vehicle frame to IMU frame).
    pub fn trim(&self) -> UnitQuaternion<f64> {
        quaternion_from_euler(self.trim_roll_rad, self.trim_pitch_rad, 0.0)
    }
}

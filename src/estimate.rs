//! What every estimator reports, and the surface they share.
//!
//! [`Ekf16`](crate::Ekf16), the augmented baseline and the delay-compensated
//! navigator all implement [`Navigator`], so examples, tests and benchmarks
//! swap them freely: push IMU, GPS and magnetometer samples, read an
//! [`Estimate`].

use crate::error::Error;
use crate::geo::euler_from_quaternion;
use crate::scalar::Scalar;
use crate::sensors::{GpsFix, ImuSample, MagSample};
use nalgebra::{SVector, UnitQuaternion, Vector3};

/// One fusion of one measurement (PX4-style): what was observed, how far it
/// was from the prediction, how surprising that was, and whether it was used.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FusionRecord<T: Scalar, const M: usize> {
    /// Time of the measurement, microseconds.
    pub t_us: u64,
    /// Innovation `z - h(x)`.
    pub innovation: SVector<T, M>,
    /// Diagonal of the innovation covariance `S = H P H^T + R`.
    pub innovation_variance: SVector<T, M>,
    /// Normalized innovation squared `y^T S^-1 y` divided by the gate
    /// (chi-square threshold): above 1 the measurement is rejected.
    pub test_ratio: T,
    /// True when the measurement corrected the state.
    pub fused: bool,
}

/// What happened to a GPS fix.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GpsOutcome<T: Scalar> {
    /// Kept for initialization: the estimator has not seen enough IMU data
    /// to align yet.
    Waiting,
    /// This fix initialized position and velocity.
    Initialized,
    /// Fused: one record for position, one for velocity.
    Fused {
        /// Position (NED, metres).
        position: FusionRecord<T, 3>,
        /// Velocity (NED, m/s).
        velocity: FusionRecord<T, 3>,
    },
    /// Stored to be fused once the estimator's delayed horizon reaches it.
    Queued,
}

/// What happened to a magnetometer sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MagOutcome<T: Scalar> {
    /// Kept to set the initial heading.
    Stored,
    /// Heading update: the record of the 3-D pseudo-measurement.
    Fused(FusionRecord<T, 3>),
    /// Stored to be fused once the estimator's delayed horizon reaches it.
    Queued,
}

/// The navigation solution at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Estimate<T: Scalar> {
    /// The instant described, microseconds on the IMU clock.
    pub t_us: u64,
    /// Body-to-NED attitude.
    pub attitude: UnitQuaternion<T>,
    /// Position NED, metres from the local origin.
    pub position_ned_m: Vector3<T>,
    /// Velocity NED, m/s.
    pub velocity_ned_m_s: Vector3<T>,
    /// Accelerometer bias, body FRD, m/s^2.
    pub accel_bias_m_s2: Vector3<T>,
    /// Gyro bias, body FRD, rad/s.
    pub gyro_bias_rad_s: Vector3<T>,
    /// Diagonal of the 16-state covariance, in state order
    /// (q0..q3, position, velocity, accelerometer bias, gyro bias).
    pub covariance_diagonal: SVector<T, 16>,
    /// GPS delay estimate, seconds, for estimators that have one.
    pub delay_s: Option<T>,
    /// Standard deviation of the delay estimate, seconds.
    pub delay_std_s: Option<T>,
}

impl<T: Scalar> Estimate<T> {
    /// Roll, pitch, yaw in radians (ZYX; yaw in `(-pi, pi]`).
    pub fn euler_rad(&self) -> Vector3<T> {
        euler_from_quaternion(self.attitude.quaternion())
    }
}

/// The surface every estimator of the crate shares.
pub trait Navigator<T: Scalar> {
    /// Feeds one IMU sample. Time must increase.
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error>;
    /// Feeds one GPS fix, stamped with its receive time on the IMU clock.
    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error>;
    /// Feeds one magnetometer sample.
    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error>;
    /// The current solution, `None` until initialized.
    fn estimate(&self) -> Option<Estimate<T>>;
    /// What the estimator vouches for now: its protection levels and the validity of each
    /// quantity ([`Integrity`](crate::integrity::Integrity)). The default vouches for
    /// nothing (infinite levels, nothing valid).
    fn integrity(&self) -> crate::integrity::Integrity<T> {
        crate::integrity::Integrity::none()
    }
}

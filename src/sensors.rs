//! Sensor input: the traits the estimators read, and plain structs implementing them.
//!
//! Frames and units:
//! - body frame FRD (x forward, y right, z down);
//! - navigation frame NED (north, east, down) about a local origin;
//! - timestamps are integer microseconds on **one clock shared by all
//!   sensors** (the IMU's). A GPS timestamp is the time the fix was received
//!   on that clock, not the receiver's own time of validity: the difference is
//!   exactly the delay this crate estimates.
//!
//! A user's driver types can implement the traits directly; the structs
//! [`Imu`], [`Gps`] and [`Mag`] are there for everyone else.

use crate::error::Error;
use crate::scalar::{Scalar, all_finite};
use nalgebra::Vector3;

/// One IMU sample: angular rate and specific force in body FRD.
pub trait ImuSample<T: Scalar> {
    /// Sample time, microseconds.
    fn time_us(&self) -> u64;
    /// Angular rate of body relative to inertial space, body FRD, rad/s.
    fn gyro_rad_s(&self) -> Vector3<T>;
    /// Specific force (accelerometer), body FRD, m/s^2. Level and at rest it
    /// reads about `[0, 0, -9.81]`.
    fn accel_m_s2(&self) -> Vector3<T>;
}

/// One magnetometer sample in body FRD. Only the direction is used, so the
/// unit is free (gauss, microtesla, normalized).
pub trait MagSample<T: Scalar> {
    /// Sample time, microseconds.
    fn time_us(&self) -> u64;
    /// Magnetic field in body FRD, any unit.
    fn field_body(&self) -> Vector3<T>;
}

/// WGS-84 geodetic position. Kept in `f64` in every precision: an `f32`
/// latitude in radians resolves only about 0.4 m.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Geodetic {
    /// Latitude, degrees, north positive.
    pub lat_deg: f64,
    /// Longitude, degrees, east positive.
    pub lon_deg: f64,
    /// Height, metres, positive up. Ellipsoidal or MSL: only differences from
    /// the local origin are used, so be consistent.
    pub alt_m: f64,
}

impl Geodetic {
    /// A position from latitude and longitude (degrees) and height (metres).
    pub const fn new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Self {
        Self {
            lat_deg,
            lon_deg,
            alt_m,
        }
    }

    /// True when the three fields are finite and latitude/longitude are in range.
    pub fn is_valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.alt_m.is_finite()
            && self.lat_deg.abs() <= 90.0
            && self.lon_deg.abs() <= 360.0
    }
}

/// Where a GPS fix says the antenna was.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GpsPosition<T: Scalar> {
    /// WGS-84 latitude, longitude, height; converted to local NED about the
    /// estimator's origin (the first fix unless configured).
    Geodetic(Geodetic),
    /// Already local NED, metres.
    Ned(Vector3<T>),
}

/// What kind of solution a receiver reports (NMEA GGA quality, u-blox
/// `fixType`, ArduPilot `GPS.Status`, PX4 `fix_type`), from worst to best.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum FixType {
    /// No position: the fix is refused ([`checked_gps`]).
    NoFix,
    /// Dead reckoning only (the receiver's own inertial extrapolation).
    DeadReckoning,
    /// Horizontal only; the altitude is held or assumed.
    Fix2d,
    /// A 3-D GNSS fix.
    Fix3d,
    /// 3-D with differential corrections (SBAS, DGPS).
    Differential,
    /// RTK with float ambiguities (decimetres).
    RtkFloat,
    /// RTK with fixed ambiguities (centimetres).
    RtkFixed,
}

/// One GPS fix.
///
/// Only the time, position and velocity are required; the reported
/// accuracies and fix quality have default methods returning `None` (not
/// reported), so a driver implements what its receiver gives.
pub trait GpsFix<T: Scalar> {
    /// Time the fix was received, on the IMU's clock, microseconds.
    fn time_us(&self) -> u64;
    /// Antenna position.
    fn position(&self) -> GpsPosition<T>;
    /// Velocity, NED, m/s (down positive).
    fn velocity_ned_m_s(&self) -> Vector3<T>;
    /// Receiver's horizontal position accuracy (1 sigma), metres, if reported.
    /// When present it replaces the configured horizontal position noise.
    fn horizontal_accuracy_m(&self) -> Option<T> {
        None
    }
    /// Receiver's vertical position accuracy (1 sigma), metres, if reported.
    fn vertical_accuracy_m(&self) -> Option<T> {
        None
    }
    /// Receiver's speed accuracy (1 sigma per axis), m/s, if reported.
    fn speed_accuracy_m_s(&self) -> Option<T> {
        None
    }
    /// The kind of solution, if reported. [`FixType::NoFix`] is refused by
    /// every estimator (counted as an invalid fix); the others are fused
    /// with their accuracies, so report a 2-D fix's vertical accuracy as
    /// large.
    fn fix_type(&self) -> Option<FixType> {
        None
    }
    /// Satellites used in the solution, if reported. Not used by the
    /// estimators (the accuracies carry the information); there for logging
    /// and for a caller's own gate.
    fn satellites(&self) -> Option<u8> {
        None
    }
}

/// A plain IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Imu<T: Scalar> {
    /// Sample time, microseconds.
    pub t_us: u64,
    /// Angular rate, body FRD, rad/s.
    pub gyro_rad_s: Vector3<T>,
    /// Specific force, body FRD, m/s^2.
    pub accel_m_s2: Vector3<T>,
}

impl<T: Scalar> Imu<T> {
    /// A sample at `t_us` (µs) with the angular rate (rad/s) and the
    /// specific force (m/s^2), both in body FRD.
    pub const fn new(t_us: u64, gyro_rad_s: Vector3<T>, accel_m_s2: Vector3<T>) -> Self {
        Self {
            t_us,
            gyro_rad_s,
            accel_m_s2,
        }
    }
}

impl<T: Scalar> ImuSample<T> for Imu<T> {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn gyro_rad_s(&self) -> Vector3<T> {
        self.gyro_rad_s
    }
    fn accel_m_s2(&self) -> Vector3<T> {
        self.accel_m_s2
    }
}

/// A plain magnetometer sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Mag<T: Scalar> {
    /// Sample time, microseconds.
    pub t_us: u64,
    /// Field, body FRD, any unit.
    pub field_body: Vector3<T>,
}

impl<T: Scalar> Mag<T> {
    /// A sample at `t_us` (µs) of the field in body FRD (any unit).
    pub const fn new(t_us: u64, field_body: Vector3<T>) -> Self {
        Self { t_us, field_body }
    }
}

impl<T: Scalar> MagSample<T> for Mag<T> {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn field_body(&self) -> Vector3<T> {
        self.field_body
    }
}

/// A plain GPS fix.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Gps<T: Scalar> {
    /// Receive time on the IMU clock, microseconds.
    pub t_us: u64,
    /// Antenna position.
    pub position: GpsPosition<T>,
    /// Velocity NED, m/s.
    pub velocity_ned_m_s: Vector3<T>,
    /// Horizontal accuracy (1 sigma), metres.
    pub horizontal_accuracy_m: Option<T>,
    /// Vertical accuracy (1 sigma), metres.
    pub vertical_accuracy_m: Option<T>,
    /// Speed accuracy (1 sigma), m/s.
    pub speed_accuracy_m_s: Option<T>,
}

impl<T: Scalar> Gps<T> {
    /// A fix received at `t_us` (µs, IMU clock) at a local NED position (m)
    /// with a NED velocity (m/s), no accuracy reported.
    pub const fn ned(t_us: u64, position_ned_m: Vector3<T>, velocity_ned_m_s: Vector3<T>) -> Self {
        Self::at(t_us, GpsPosition::Ned(position_ned_m), velocity_ned_m_s)
    }

    /// A fix received at `t_us` (µs, IMU clock) at a WGS-84 position with a
    /// NED velocity (m/s), no accuracy reported.
    pub const fn geodetic(t_us: u64, position: Geodetic, velocity_ned_m_s: Vector3<T>) -> Self {
        Self::at(t_us, GpsPosition::Geodetic(position), velocity_ned_m_s)
    }

    const fn at(t_us: u64, position: GpsPosition<T>, velocity_ned_m_s: Vector3<T>) -> Self {
        Self {
            t_us,
            position,
            velocity_ned_m_s,
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        }
    }

    /// The same fix with the receiver's 1-sigma accuracies: horizontal and
    /// vertical position (m), speed per axis (m/s).
    pub const fn with_accuracy(mut self, horizontal_m: T, vertical_m: T, speed_m_s: T) -> Self {
        self.horizontal_accuracy_m = Some(horizontal_m);
        self.vertical_accuracy_m = Some(vertical_m);
        self.speed_accuracy_m_s = Some(speed_m_s);
        self
    }
}

impl<T: Scalar> GpsFix<T> for Gps<T> {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn position(&self) -> GpsPosition<T> {
        self.position
    }
    fn velocity_ned_m_s(&self) -> Vector3<T> {
        self.velocity_ned_m_s
    }
    fn horizontal_accuracy_m(&self) -> Option<T> {
        self.horizontal_accuracy_m
    }
    fn vertical_accuracy_m(&self) -> Option<T> {
        self.vertical_accuracy_m
    }
    fn speed_accuracy_m_s(&self) -> Option<T> {
        self.speed_accuracy_m_s
    }
}

/// Copy any [`ImuSample`] into an [`Imu`], refusing non-finite values.
pub fn checked_imu<T: Scalar, I: ImuSample<T> + ?Sized>(imu: &I) -> Result<Imu<T>, Error> {
    let s = Imu {
        t_us: imu.time_us(),
        gyro_rad_s: imu.gyro_rad_s(),
        accel_m_s2: imu.accel_m_s2(),
    };
    if !all_finite(&s.gyro_rad_s) {
        return Err(Error::NonFinite { field: "imu.gyro" });
    }
    if !all_finite(&s.accel_m_s2) {
        return Err(Error::NonFinite { field: "imu.accel" });
    }
    Ok(s)
}

/// Copy any [`MagSample`] into a [`Mag`], refusing non-finite or zero fields.
pub fn checked_mag<T: Scalar, M: MagSample<T> + ?Sized>(mag: &M) -> Result<Mag<T>, Error> {
    let s = Mag {
        t_us: mag.time_us(),
        field_body: mag.field_body(),
    };
    if !all_finite(&s.field_body) {
        return Err(Error::NonFinite { field: "mag.field" });
    }
    if s.field_body.norm_squared() <= T::zero() {
        return Err(Error::OutOfRange {
            field: "mag.field",
            reason: "zero field has no direction",
        });
    }
    Ok(s)
}

/// Largest reported position accuracy (1 sigma) a fix may carry, metres.
/// A receiver reporting more has no usable fix (u-blox reports kilometres
/// before its first fix); beyond it the fix is refused. The bound also keeps
/// the accuracy's square, the measurement variance, far from overflow in
/// `f32` (`1e4^2 = 1e8`, against `f32::MAX ~ 3.4e38`).
pub const MAX_POSITION_ACCURACY_M: f64 = 1.0e4;

/// Largest reported speed accuracy (1 sigma) a fix may carry, m/s (see
/// [`MAX_POSITION_ACCURACY_M`]).
pub const MAX_SPEED_ACCURACY_M_S: f64 = 1.0e3;

/// Smallest reported accuracy (1 sigma, position in m or speed in m/s) a fix
/// may carry. No receiver resolves better than a millimetre; a smaller value
/// is a driver's placeholder, and as a measurement variance (`< 1e-6`) it
/// would let one fix collapse the covariance below what `f32` resolves
/// (negative variances after the update). Below it the fix is refused.
pub const MIN_ACCURACY: f64 = 1.0e-3;

/// Largest magnitude of a NED position component a fix may carry, metres:
/// 10,000 km from the origin is beyond any local frame's validity.
pub const MAX_NED_POSITION_M: f64 = 1.0e7;

/// Largest magnitude of a velocity component a fix may carry, m/s (twenty
/// times the 515 m/s at which receivers stop reporting).
pub const MAX_GPS_VELOCITY_M_S: f64 = 1.0e4;

/// Copy any [`GpsFix`] into a [`Gps`], refusing a fix reported as
/// [`FixType::NoFix`], non-finite values, NED
/// positions and velocities beyond [`MAX_NED_POSITION_M`] /
/// [`MAX_GPS_VELOCITY_M_S`], and reported accuracies that are not finite,
/// below [`MIN_ACCURACY`], or above
/// [`MAX_POSITION_ACCURACY_M`] / [`MAX_SPEED_ACCURACY_M_S`]: every accuracy
/// is checked here, before it can touch a covariance (the estimators count
/// the refusal as an invalid fix).
pub fn checked_gps<T: Scalar, G: GpsFix<T> + ?Sized>(gps: &G) -> Result<Gps<T>, Error> {
    if gps.fix_type() == Some(FixType::NoFix) {
        return Err(Error::OutOfRange {
            field: "gps.fix_type",
            reason: "the receiver reports no fix",
        });
    }
    let s = Gps {
        t_us: gps.time_us(),
        position: gps.position(),
        velocity_ned_m_s: gps.velocity_ned_m_s(),
        horizontal_accuracy_m: gps.horizontal_accuracy_m(),
        vertical_accuracy_m: gps.vertical_accuracy_m(),
        speed_accuracy_m_s: gps.speed_accuracy_m_s(),
    };
    match s.position {
        GpsPosition::Geodetic(g)
            if !(g.lat_deg.is_finite() && g.lon_deg.is_finite() && g.alt_m.is_finite()) =>
        {
            return Err(Error::NonFinite {
                field: "gps.position",
            });
        }
        GpsPosition::Geodetic(g) if g.lat_deg.abs() > 90.0 => {
            return Err(Error::OutOfRange {
                field: "gps.position.lat_deg",
                reason: "latitude must lie in [-90, 90] deg",
            });
        }
        GpsPosition::Geodetic(g) if g.lon_deg.abs() > 360.0 => {
            return Err(Error::OutOfRange {
                field: "gps.position.lon_deg",
                reason: "longitude must lie in [-360, 360] deg",
            });
        }
        GpsPosition::Ned(p) if !all_finite(&p) => {
            return Err(Error::NonFinite {
                field: "gps.position",
            });
        }
        GpsPosition::Ned(p) if p.amax() > T::lit(MAX_NED_POSITION_M) => {
            return Err(Error::OutOfRange {
                field: "gps.position",
                reason: "NED position beyond sensors::MAX_NED_POSITION_M",
            });
        }
        _ => {}
    }
    if !all_finite(&s.velocity_ned_m_s) {
        return Err(Error::NonFinite {
            field: "gps.velocity",
        });
    }
    if s.velocity_ned_m_s.amax() > T::lit(MAX_GPS_VELOCITY_M_S) {
        return Err(Error::OutOfRange {
            field: "gps.velocity",
            reason: "velocity beyond sensors::MAX_GPS_VELOCITY_M_S",
        });
    }
    for (acc, field, max) in [
        (
            s.horizontal_accuracy_m,
            "gps.horizontal_accuracy",
            MAX_POSITION_ACCURACY_M,
        ),
        (
            s.vertical_accuracy_m,
            "gps.vertical_accuracy",
            MAX_POSITION_ACCURACY_M,
        ),
        (
            s.speed_accuracy_m_s,
            "gps.speed_accuracy",
            MAX_SPEED_ACCURACY_M_S,
        ),
    ] {
        if let Some(a) = acc {
            if !a.is_finite() {
                return Err(Error::NonFinite { field });
            }
            if a < T::lit(MIN_ACCURACY) {
                return Err(Error::OutOfRange {
                    field,
                    reason: "accuracy below sensors::MIN_ACCURACY (or not positive)",
                });
            }
            if a > T::lit(max) {
                return Err(Error::OutOfRange {
                    field,
                    reason: "accuracy above the plausible bound (sensors::MAX_*_ACCURACY)",
                });
            }
        }
    }
    Ok(s)
}

/// Checks a new timestamp of one stream against the previous accepted one.
#[allow(dead_code)] // used by the estimators
pub(crate) fn check_time(
    stream: &'static str,
    previous_us: Option<u64>,
    got_us: u64,
) -> Result<(), Error> {
    match previous_us {
        Some(p) if got_us < p => Err(Error::TimeWentBackwards {
            stream,
            previous_us: p,
            got_us,
        }),
        Some(p) if got_us == p => Err(Error::DuplicateTimestamp {
            stream,
            t_us: got_us,
        }),
        _ => Ok(()),
    }
}

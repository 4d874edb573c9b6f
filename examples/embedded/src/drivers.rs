//! The firmware's own sensor types, as its drivers hand them over: raw
//! counts and a timestamp on the IMU clock. The navigator reads them through
//! the sensor traits; the unit and axis conversions live in the trait
//! methods, so nothing is copied into the crate's own sample structs.

use delaynav::nalgebra::Vector3;
use delaynav::{FixType, Geodetic, GpsFix, GpsPosition, ImuSample, MagSample};

/// Standard gravity, m/s^2.
pub const G: f32 = 9.80665;
/// Accelerometer at +-16 g: 2048 counts per g.
pub const ACCEL_COUNTS_PER_G: f32 = 2048.0;
/// Gyroscope at +-2000 deg/s: 16.4 counts per deg/s.
pub const GYRO_COUNTS_PER_DEG_S: f32 = 16.4;
/// Magnetometer at +-4 gauss: 6842 counts per gauss.
pub const MAG_COUNTS_PER_GAUSS: f32 = 6842.0;

/// One sample of the IMU's FIFO (an ICM-42688-like part), in the chip's
/// axes. The chip is mounted turned 90 deg about z: its x axis points to the
/// vehicle's right, its y axis to the rear, its z axis down.
#[derive(Clone, Copy, Default)]
pub struct RawImu {
    /// Data-ready time on the IMU clock, us.
    pub t_us: u64,
    /// Angular rate, chip axes, counts.
    pub gyro: [i16; 3],
    /// Specific force, chip axes, counts.
    pub accel: [i16; 3],
}

/// Chip axes to body FRD (x forward, y right, z down).
fn chip_to_body(c: [f32; 3]) -> Vector3<f32> {
    Vector3::new(-c[1], c[0], c[2])
}

impl ImuSample<f32> for RawImu {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn gyro_rad_s(&self) -> Vector3<f32> {
        let scale = (1.0 / GYRO_COUNTS_PER_DEG_S).to_radians();
        chip_to_body(self.gyro.map(|c| f32::from(c) * scale))
    }
    fn accel_m_s2(&self) -> Vector3<f32> {
        let scale = G / ACCEL_COUNTS_PER_G;
        chip_to_body(self.accel.map(|c| f32::from(c) * scale))
    }
}

/// One magnetometer reading (a LIS3MDL-like part, mounted with its axes on
/// the vehicle's FRD axes).
#[derive(Clone, Copy, Default)]
pub struct RawMag {
    /// Read time on the IMU clock, us.
    pub t_us: u64,
    /// Field, counts.
    pub field: [i16; 3],
}

impl MagSample<f32> for RawMag {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn field_body(&self) -> Vector3<f32> {
        // Only the direction is used: gauss, for readable logs.
        Vector3::from(self.field.map(|c| f32::from(c) / MAG_COUNTS_PER_GAUSS))
    }
}

/// The fields of a u-blox UBX-NAV-PVT message the navigator needs, as
/// decoded from the UART, stamped with the time its last byte arrived on
/// the IMU clock (the receiver's latency is the delay the navigator
/// measures).
#[derive(Clone, Copy, Default)]
pub struct NavPvt {
    /// Receive time on the IMU clock, us.
    pub t_us: u64,
    /// `fixType`: 0 no fix, 2 2-D, 3 3-D, ...
    pub fix_type: u8,
    /// `numSV`.
    pub num_sv: u8,
    /// Latitude, 1e-7 deg.
    pub lat: i32,
    /// Longitude, 1e-7 deg.
    pub lon: i32,
    /// Height above mean sea level, mm.
    pub h_msl: i32,
    /// NED velocity, mm/s.
    pub vel_ned: [i32; 3],
    /// Horizontal accuracy, mm.
    pub h_acc: u32,
    /// Vertical accuracy, mm.
    pub v_acc: u32,
    /// Speed accuracy, mm/s.
    pub s_acc: u32,
}

impl GpsFix<f32> for NavPvt {
    fn time_us(&self) -> u64 {
        self.t_us
    }
    fn position(&self) -> GpsPosition<f32> {
        // Geodetic positions stay in f64: an f32 latitude resolves 0.4 m.
        GpsPosition::Geodetic(Geodetic {
            lat_deg: f64::from(self.lat) * 1e-7,
            lon_deg: f64::from(self.lon) * 1e-7,
            alt_m: f64::from(self.h_msl) * 1e-3,
        })
    }
    fn velocity_ned_m_s(&self) -> Vector3<f32> {
        Vector3::from(self.vel_ned.map(|v| v as f32 * 1e-3))
    }
    fn horizontal_accuracy_m(&self) -> Option<f32> {
        Some(self.h_acc as f32 * 1e-3)
    }
    fn vertical_accuracy_m(&self) -> Option<f32> {
        Some(self.v_acc as f32 * 1e-3)
    }
    fn speed_accuracy_m_s(&self) -> Option<f32> {
        Some(self.s_acc as f32 * 1e-3)
    }
    fn fix_type(&self) -> Option<FixType> {
        Some(match self.fix_type {
            0 => FixType::NoFix,
            1 => FixType::DeadReckoning,
            2 => FixType::Fix2d,
            _ => FixType::Fix3d,
        })
    }
    fn satellites(&self) -> Option<u8> {
        Some(self.num_sv)
    }
}

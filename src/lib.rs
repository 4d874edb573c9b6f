//! # delaynav
//!
//! GPS/IMU navigation for small robots that estimates and compensates the GPS
//! time delay online (Liao et al., *Dynamic Attitude Estimation Improvement for
//! Low-cost MEMS IMU by Integrating Low-cost GPS*).
//!
//! A cheap GPS receiver reports where the vehicle was 0.1-0.4 s ago. Fused as if
//! it were current, it corrupts attitude exactly when the vehicle accelerates.
//!
//! ## Features
//!
//! | feature | default | what it adds |
//! |---|---|---|
//! | `std` | yes | `std` support in the dependencies; without it the crate is `no_std` and allocation-free |
//! | `serde` | no | `Serialize`/`Deserialize` for configurations, samples and estimates; a config file may be partial (missing fields take their defaults), an unknown key is an error |
//! | `sim` | no | the `sim` module: trajectory and sensor simulator with the paper's noise table, CSV export (needs `std`) |
//! | `replay` | no | log readers (ArduPilot `.bin`, PX4 `.ulg`, crate CSV, ArduPilot and PX4 CSV forms) merged into one sensor stream, flight window; implies `std` and `serde` |
//!
//! ## On a microcontroller (`no_std`, `f32`)
//!
//! Build with `default-features = false`. Nothing allocates after
//! construction; your driver types feed the filter through the sensor traits:
//!
//! ```
//! use delaynav::{Ekf16, Ekf16Config, ImuSample, Navigator};
//! use nalgebra::Vector3;
//!
//! /// What an MPU-9250 driver might hand over: raw counts and a timestamp.
//! struct RawImu { t_us: u64, gyro: [i16; 3], accel: [i16; 3] }
//!
//! impl ImuSample<f32> for RawImu {
//!     fn time_us(&self) -> u64 { self.t_us }
//!     fn gyro_rad_s(&self) -> Vector3<f32> {
//!         // +-2000 deg/s full scale
//!         Vector3::from(self.gyro.map(|c| c as f32 * (2000.0 / 32768.0) * core::f32::consts::PI / 180.0))
//!     }
//!     fn accel_m_s2(&self) -> Vector3<f32> {
//!         // +-16 g full scale
//!         Vector3::from(self.accel.map(|c| c as f32 * (16.0 * 9.80665 / 32768.0)))
//!     }
//! }
//!
//! let mut ekf = Ekf16::<f32>::new(Ekf16Config::default()).expect("default config is valid");
//! // Level and at rest: z reads -1 g (2048 counts at +-16 g).
//! let sample = RawImu { t_us: 1_000, gyro: [0; 3], accel: [0, 0, -2048] };
//! ekf.push_imu(&sample).expect("a finite sample is accepted");
//! // A duplicate timestamp is refused with a typed error.
//! assert!(ekf.push_imu(&sample).is_err());
//! ```
//!
//! ## Conventions
//! Navigation frame NED, body frame FRD, quaternions Hamilton scalar-first
//! rotating body to NED, timestamps integer microseconds on the IMU clock.
//! See [`geo`] and [`sensors`]; the equations are in `docs/math.md`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

/// Unit tests in both precisions: `tests_in_both_precisions!(a, b)` makes the
/// tests `in_f32::a`, `in_f64::a`, `in_f32::b`, ... calling the generic test bodies
/// `a::<f32>()`, `a::<f64>()`, ... of the enclosing module.
#[cfg(test)]
macro_rules! tests_in_both_precisions {
    ($($name:ident),+ $(,)?) => {
        mod in_f32 {
            $(#[test]
            fn $name() {
                super::$name::<f32>();
            })+
        }
        mod in_f64 {
            $(#[test]
            fn $name() {
                super::$name::<f64>();
            })+
        }
    };
}

pub mod aekf17;
pub mod delay;
pub mod ekf16;
pub mod error;
pub mod estimate;
pub mod geo;
pub mod integrity;
#[doc(hidden)]
pub mod kalman;
pub mod nav;
#[cfg(feature = "replay")]
pub mod replay;
pub mod scalar;
pub mod sensors;
#[cfg(feature = "sim")]
pub mod sim;
mod zero_option;

/// The filters' algebra, for those who verify or extend the filters; not
/// needed to navigate, and not held to the stability of the rest of the API.
///
/// The process model of [`Ekf16`] and its Jacobian ([`process`](crate::internals::process)),
/// its measurement models ([`measurement`](crate::internals::measurement)), the delta
/// angle and velocity accumulation ([`delta`](crate::internals::delta)), the delayed GPS
/// measurement of [`AugmentedEkf17`] ([`aekf17_measurement`](crate::internals::aekf17_measurement))
/// and the Kalman update shared by every filter ([`kalman`]). The
/// tests check each Jacobian against finite differences through these paths.
pub mod internals {
    #[doc(inline)]
    pub use crate::aekf17::measurement as aekf17_measurement;
    #[doc(inline)]
    pub use crate::ekf16::{delta, measurement, process};
    #[doc(inline)]
    pub use crate::kalman;
}

/// The linear algebra of the API (`Vector3`, `UnitQuaternion`, ...): use
/// this re-export to get the version the crate was built with.
pub use nalgebra;

pub use aekf17::{AugmentedEkf17, AugmentedEkf17Config};
pub use delay::{
    DefaultDelayLoop, DelayLoop, DelayLoopConfig, DelayStatus, DelayUpdate, SensorDelays,
};
pub use ekf16::{Ekf16, Ekf16Config, FilterRefusals, NavState};
pub use error::Error;
pub use estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
pub use nav::{
    AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode, Health, history_len,
};
pub use scalar::Scalar;
pub use sensors::{FixType, Geodetic, Gps, GpsFix, GpsPosition, Imu, ImuSample, Mag, MagSample};

/// What a program that feeds an estimator needs, in one import.
///
/// ```
/// use delaynav::prelude::*;
///
/// let mut nav = DelayCompensatedNav::<f32>::new(DelayCompensatedNavConfig::default())?;
/// let at_rest = Imu { t_us: 1_000, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.81) };
/// nav.push_imu(&at_rest)?;
/// let health: Health<f32> = nav.health();
/// assert_eq!(health.alignment, AlignmentState::WaitingForImu);
/// # Ok::<(), Error>(())
/// ```
pub mod prelude {
    pub use crate::{
        AlignmentState, AugmentedEkf17, AugmentedEkf17Config, DelayCompensatedNav,
        DelayCompensatedNavConfig, DelayLoopConfig, DelayMode, DelayStatus, Ekf16, Ekf16Config,
        Error, Estimate, Geodetic, Gps, GpsFix, GpsOutcome, GpsPosition, Health, Imu, ImuSample,
        Mag, MagOutcome, MagSample, Navigator, Scalar,
    };
    pub use nalgebra::{UnitQuaternion, Vector3};
}

/// The README's examples, compiled and run as doctests so they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

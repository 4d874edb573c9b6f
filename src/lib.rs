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
//! | `serde` | no | `Serialize`/`Deserialize` for configurations, samples and estimates |
//!
//! ## Conventions
//! Navigation frame NED, body frame FRD, quaternions Hamilton scalar-first
//! rotating body to NED, timestamps integer microseconds on the IMU clock.
//! See [`geo`] and [`sensors`].
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod aekf17;
pub mod ekf16;
pub mod error;
pub mod estimate;
pub mod geo;
pub mod kalman;
pub mod scalar;
pub mod sensors;

pub use aekf17::{Aekf17Config, AugmentedEkf17};
pub use ekf16::{Ekf16, Ekf16Config, NavState, RefusalCounters};
pub use error::Error;
pub use estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
pub use scalar::Scalar;
pub use sensors::{Geodetic, Gps, GpsFix, GpsPosition, Imu, ImuSample, Mag, MagSample};

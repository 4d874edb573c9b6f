//! The Rust peer `fusion-nav` (crates.io, a 15-state error-state Kalman
//! filter, `f32`) on the simulator's samples, behind delaynav's
//! [`Navigator`] so the harness scores it like its own estimators.
//!
//! `fusion-nav` cannot estimate a GPS delay: the caller gives each fix the
//! time it was taken. Here that is the receive time minus the run's **true**
//! delay, so its row is a known-delay peer like `oracle`. It accepts ages up
//! to its `LATENCY_HORIZON` (0.3 s) and refuses older fixes
//! (`Fusion::OutOfHorizon`): with a longer delay it never sees a fix and its
//! row fails.
//!
//! Configuration from the simulator's own noise: Table 3's per-sample IMU
//! variances as densities (`variance / rate`, square-rooted per √Hz), GPS
//! noise as the fixes' variances, the magnetometer as a heading of variance
//! `s_m² / cos² I`, the simulator's declination; everything else is the
//! crate's default. It starts from a static window of its default length
//! (the simulated vehicle is at rest for the first seconds).

use delaynav::estimate::{Estimate, GpsOutcome, MagOutcome, Navigator};
use delaynav::sensors::{GpsFix, GpsPosition, ImuSample, MagSample};
use delaynav::sim::SimConfig;
use delaynav::{Error, Scalar};
use fusion_nav::prelude as fnav;
use nalgebra::{Quaternion, SVector, UnitQuaternion, Vector3};

/// `fusion_nav::Eskf` fed like a delaynav estimator.
#[derive(Clone)]
pub struct FusionNav {
    filter: fnav::Eskf,
    window: fnav::StaticWindow,
    initialized: bool,
    latency_us: u64,
    last_imu_us: Option<u64>,
    last_mag: Option<fnav::MagField<fnav::Body>>,
    period_s: f32,
    position_noise: (f32, f32),
    velocity_noise: f32,
    heading_noise: f32,
}

impl FusionNav {
    /// The peer configured for a simulated run, told its true (initial) delay.
    pub fn new(sim: &SimConfig) -> Self {
        let s = &sim.sensors;
        let mut config = fnav::Config::default();
        config.imu.gyro_white = (s.gyro_noise_var_rad2_s2 / s.imu_rate_hz).sqrt() as f32;
        let accel_var = s.accel_noise_std_m_s2().powi(2);
        config.imu.accel_white = (accel_var / s.imu_rate_hz).sqrt() as f32;
        config.gravity = delaynav::sim::STANDARD_GRAVITY as f32;
        let mut filter = fnav::Eskf::new(config).expect("valid fusion-nav config");
        let _ =
            filter.set_magnetic_declination(fnav::Radians::from_radians(s.declination_rad as f32));
        Self {
            filter,
            window: fnav::StaticWindow::new(),
            initialized: false,
            latency_us: (sim.delay.initial_s * 1e6).round() as u64,
            last_imu_us: None,
            last_mag: None,
            period_s: (1.0 / s.imu_rate_hz) as f32,
            position_noise: (
                s.gps_position_var_m2.max(1e-6) as f32,
                s.gps_position_var_m2.max(1e-6) as f32,
            ),
            velocity_noise: s.gps_velocity_var_m2_s2.max(1e-6) as f32,
            heading_noise: (s.mag_noise_var / s.inclination_rad.cos().powi(2)).max(1e-8) as f32,
        }
    }

    fn taken(&self, t_us: u64) -> fnav::Timestamp {
        fnav::Timestamp::from_micros(t_us.saturating_sub(self.latency_us))
    }
}

fn f32s<T: Scalar>(v: &Vector3<T>) -> [f32; 3] {
    [
        v.x.as_f64() as f32,
        v.y.as_f64() as f32,
        v.z.as_f64() as f32,
    ]
}

impl<T: Scalar> Navigator<T> for FusionNav {
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        let t_us = imu.time_us();
        let dt = self
            .last_imu_us
            .map_or(self.period_s, |p| t_us.saturating_sub(p) as f32 * 1e-6);
        self.last_imu_us = Some(t_us);
        let [gx, gy, gz] = f32s(&imu.gyro_rad_s());
        let [ax, ay, az] = f32s(&imu.accel_m_s2());
        let sample = fnav::ImuSample::from_rates(
            fnav::Timestamp::from_micros(t_us),
            fnav::AngularRate::body(gx, gy, gz),
            fnav::Acceleration::body(ax, ay, az),
            fnav::Seconds::from_secs(dt),
        );
        if self.initialized {
            let _ = self.filter.predict(sample);
        } else {
            let _ = self.window.push(fnav::StaticSample {
                imu: sample,
                mag: self.last_mag,
                ..fnav::StaticSample::default()
            });
            if self.window.is_long_enough(self.filter.config()) {
                self.initialized = self.filter.initialize(&self.window).is_ok();
                if !self.initialized {
                    self.window = fnav::StaticWindow::new();
                }
            }
        }
        Ok(())
    }

    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        if !self.initialized {
            return Ok(GpsOutcome::Waiting);
        }
        let GpsPosition::Ned(p) = gps.position() else {
            return Err(Error::InvalidConfig {
                field: "gps.position".into(),
                value: None,
                bound: delaynav::error::Bound::Rule("the fusion-nav row takes NED fixes"),
            });
        };
        let time = self.taken(gps.time_us());
        let [n, e, d] = f32s(&p);
        let (h, v) = self.position_noise;
        let _ = self.filter.fuse_gnss_position(
            time,
            fnav::Position::ned(n, e, d),
            fnav::PositionNoise::from_variance(h, h, v),
            fnav::Position::zero(),
        );
        let [vn, ve, vd] = f32s(&gps.velocity_ned_m_s());
        let var = self.velocity_noise;
        let _ = self.filter.fuse_gnss_velocity(
            time,
            fnav::Velocity::ned(vn, ve, vd),
            fnav::VelocityNoise::from_variance(var, var, var),
            fnav::Position::zero(),
        );
        Ok(GpsOutcome::Queued)
    }

    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error> {
        let [x, y, z] = f32s(&mag.field_body());
        let field = fnav::MagField::body(x, y, z);
        self.last_mag = Some(field);
        if self.initialized {
            let _ = self.filter.fuse_mag_heading(
                fnav::Timestamp::from_micros(mag.time_us()),
                field,
                fnav::HeadingNoise::from_variance(self.heading_noise),
            );
        }
        Ok(MagOutcome::Stored)
    }

    fn estimate(&self) -> Option<Estimate<T>> {
        if !self.initialized {
            return None;
        }
        let s = self.filter.state();
        let q = s.attitude.body_to_ned();
        let v3 = |a: [f32; 3]| Vector3::new(a[0], a[1], a[2]).map(|x| T::lit(f64::from(x)));
        Some(Estimate {
            t_us: self.last_imu_us.unwrap_or(0),
            attitude: UnitQuaternion::new_normalize(Quaternion::new(
                T::lit(f64::from(q.w)),
                T::lit(f64::from(q.x)),
                T::lit(f64::from(q.y)),
                T::lit(f64::from(q.z)),
            )),
            position_ned_m: v3(s.position.to_array()),
            velocity_ned_m_s: v3(s.velocity.to_array()),
            accel_bias_m_s2: v3(s.accel_bias.to_array()),
            gyro_bias_rad_s: v3(s.gyro_bias.to_array()),
            covariance_diagonal: SVector::zeros(),
            delay_s: None,
            delay_std_s: None,
        })
    }
}

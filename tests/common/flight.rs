//! Synthetic 3-D flights for the navigator tests: closed-form position and
//! attitude, the IMU, magnetometer and delayed GPS derived from them.

use super::{Lcg, Motion};
use delaynav::geo::{magnetic_field_ned, quaternion_from_euler, rotation_matrix};
use delaynav::nav::{DelayCompensatedNavConfig, DelayMode};
use delaynav::{Ekf16Config, Gps, GpsPosition, Imu, Mag, Scalar};
use nalgebra::{UnitQuaternion, Vector3};

pub const G: f64 = 9.806_65;
pub const INCLINATION: f64 = 1.1;
pub const DECLINATION: f64 = 0.2;

/// The navigator's default configuration for these flights' magnetic field
/// at `imu_hz`.
pub fn nav_config<T: Scalar>(mode: DelayMode<T>, imu_hz: f64) -> DelayCompensatedNavConfig<T> {
    DelayCompensatedNavConfig {
        ekf: Ekf16Config {
            mag_inclination_rad: T::lit(INCLINATION),
            mag_declination_rad: T::lit(DECLINATION),
            ..Ekf16Config::default()
        },
        mode,
        imu_rate_hz: T::lit(imu_hz),
        ..DelayCompensatedNavConfig::default()
    }
}

/// At rest and level until `start_s`, then the motion fades in over `ramp_s`
/// (quintic smoothstep, continuous to the second derivative).
pub struct Flight {
    /// NED acceleration sines (position = their double integral).
    pub motion: Motion,
    /// Roll, pitch, yaw oscillation amplitudes, rad.
    pub attitude_amplitude: [f64; 3],
    pub yaw0: f64,
    pub start_s: f64,
    pub ramp_s: f64,
}

/// The truth at one instant.
#[derive(Debug, Clone, Copy)]
pub struct State {
    pub q: UnitQuaternion<f64>,
    pub r: Vector3<f64>,
    pub v: Vector3<f64>,
    /// Kinematic acceleration, NED.
    pub a: Vector3<f64>,
    /// Angular rate, body.
    pub gyro: Vector3<f64>,
    /// Specific force, body.
    pub accel: Vector3<f64>,
}

impl Flight {
    pub fn new(motion: Motion) -> Self {
        Self {
            motion,
            attitude_amplitude: [0.12, 0.1, 0.5],
            yaw0: 0.4,
            start_s: 3.0,
            ramp_s: 4.0,
        }
    }

    fn envelope(&self, t: f64) -> f64 {
        let x = ((t - self.start_s) / self.ramp_s).clamp(0.0, 1.0);
        x * x * x * (x * (6.0 * x - 15.0) + 10.0)
    }

    fn position(&self, t: f64) -> Vector3<f64> {
        let p = self.motion.position(t);
        Vector3::from(p) * self.envelope(t)
    }

    fn euler(&self, t: f64) -> Vector3<f64> {
        let e = self.envelope(t);
        let [ar, ap, ay] = self.attitude_amplitude;
        Vector3::new(
            e * ar * (0.8 * t).sin(),
            e * ap * (0.6 * t + 1.0).sin(),
            self.yaw0 + e * ay * (0.3 * t).sin(),
        )
    }

    /// The truth at `t` seconds (derivatives by central differences of the
    /// closed forms, accurate to about 1e-5 in m/s^2 and rad/s).
    pub fn state(&self, t: f64) -> State {
        let h = 1e-3;
        let (r_m, r, r_p) = (self.position(t - h), self.position(t), self.position(t + h));
        let v = (r_p - r_m) / (2.0 * h);
        let a = (r_p - 2.0 * r + r_m) / (h * h);
        let e = self.euler(t);
        let de = (self.euler(t + h) - self.euler(t - h)) / (2.0 * h);
        let (phi, theta) = (e.x, e.y);
        let gyro = Vector3::new(
            de.x - de.z * theta.sin(),
            de.y * phi.cos() + de.z * phi.sin() * theta.cos(),
            -de.y * phi.sin() + de.z * phi.cos() * theta.cos(),
        );
        let q = quaternion_from_euler(e.x, e.y, e.z);
        let accel = rotation_matrix(q.quaternion()).transpose() * (a - Vector3::new(0.0, 0.0, G));
        State {
            q,
            r,
            v,
            a,
            gyro,
            accel,
        }
    }
}

/// Rates and noise of a sensor suite (standard deviations per sample).
#[derive(Debug, Clone, Copy)]
pub struct Suite {
    pub imu_hz: f64,
    pub gps_hz: f64,
    pub mag_hz: f64,
    pub gyro_std: f64,
    pub accel_std: f64,
    pub mag_std: f64,
    pub gps_position_std: f64,
    pub gps_velocity_std: f64,
    /// IMU timestamp jitter, +- us (uniform).
    pub imu_jitter_us: f64,
    /// GPS receive-time jitter, +- us (uniform).
    pub gps_jitter_us: f64,
    pub seed: u64,
}

impl Suite {
    /// Perfect sensors at 1 kHz / 10 Hz / 100 Hz, GPS on IMU ticks.
    pub fn perfect() -> Self {
        Self {
            imu_hz: 1000.0,
            gps_hz: 10.0,
            mag_hz: 100.0,
            gyro_std: 0.0,
            accel_std: 0.0,
            mag_std: 0.0,
            gps_position_std: 0.0,
            gps_velocity_std: 0.0,
            imu_jitter_us: 0.0,
            gps_jitter_us: 0.0,
            seed: 3,
        }
    }

    /// The default `Ekf16Config` noise at 1 kHz (densities times sqrt(rate)).
    pub fn simulator() -> Self {
        let c = delaynav::Ekf16Config::<f64>::default();
        let imu_hz: f64 = 1000.0;
        Self {
            gyro_std: c.gyro_noise_density * imu_hz.sqrt(),
            accel_std: c.accel_noise_density * imu_hz.sqrt(),
            mag_std: c.mag_noise_variance.sqrt(),
            gps_position_std: c.gps_horizontal_std_m,
            gps_velocity_std: c.gps_velocity_std_m_s,
            ..Self::perfect()
        }
    }

    /// The real log's rates: IMU 50 Hz with +-2 ms jitter, GPS 5 Hz with +-12 ms.
    pub fn real_log_like() -> Self {
        let imu_hz: f64 = 50.0;
        let c = delaynav::Ekf16Config::<f64>::default();
        Self {
            imu_hz,
            gps_hz: 5.0,
            mag_hz: 50.0,
            gyro_std: c.gyro_noise_density * imu_hz.sqrt(),
            accel_std: c.accel_noise_density * imu_hz.sqrt(),
            imu_jitter_us: 2000.0,
            gps_jitter_us: 12_000.0,
            ..Self::simulator()
        }
    }
}

/// One sensor event, in time order.
#[derive(Debug, Clone, Copy)]
pub enum FlightEvent {
    Imu(Imu<f64>, State),
    Mag(Mag<f64>),
    Gps(Gps<f64>),
}

impl FlightEvent {
    pub fn t_us(&self) -> u64 {
        match self {
            Self::Imu(s, _) => s.t_us,
            Self::Mag(m) => m.t_us,
            Self::Gps(g) => g.t_us,
        }
    }
}

/// The event stream of `flight` seen by `suite` for `seconds`; a fix
/// received at `t` describes the flight at `t - delay(t)`; no fix is
/// received inside `outage` (s, s).
pub fn fly(
    flight: &Flight,
    suite: &Suite,
    seconds: f64,
    delay: impl Fn(f64) -> f64,
    outage: Option<(f64, f64)>,
) -> Vec<FlightEvent> {
    let mut rng = Lcg(suite.seed);
    let mut noise = |std: f64| {
        if std == 0.0 {
            Vector3::zeros()
        } else {
            let mut n = || rng.normal() * std;
            Vector3::new(n(), n(), n())
        }
    };
    let m_n = magnetic_field_ned(INCLINATION, DECLINATION);
    let mut events = Vec::new();
    let imu_dt = 1e6 / suite.imu_hz;
    for k in 1..=(seconds * suite.imu_hz) as u64 {
        let jitter = if suite.imu_jitter_us > 0.0 {
            (Lcg(suite.seed ^ k).uniform() * 2.0 - 1.0) * suite.imu_jitter_us
        } else {
            0.0
        };
        let t_us = (k as f64 * imu_dt + jitter).round() as u64;
        let s = flight.state(t_us as f64 * 1e-6);
        let imu = Imu {
            t_us,
            gyro_rad_s: s.gyro + noise(suite.gyro_std),
            accel_m_s2: s.accel + noise(suite.accel_std),
        };
        events.push(FlightEvent::Imu(imu, s));
    }
    let mag_dt = 1e6 / suite.mag_hz;
    for k in 1..=(seconds * suite.mag_hz) as u64 {
        let t_us = (k as f64 * mag_dt).round() as u64;
        let s = flight.state(t_us as f64 * 1e-6);
        let field = rotation_matrix(s.q.quaternion()).transpose() * m_n + noise(suite.mag_std);
        events.push(FlightEvent::Mag(Mag {
            t_us,
            field_body: field,
        }));
    }
    let gps_dt = 1e6 / suite.gps_hz;
    for k in 1..=(seconds * suite.gps_hz) as u64 {
        let epoch_us = k as f64 * gps_dt;
        let epoch = epoch_us * 1e-6;
        if outage.is_some_and(|(a, b)| epoch >= a && epoch < b) {
            continue;
        }
        let jitter = (Lcg(suite.seed ^ (k << 20)).uniform() * 2.0 - 1.0) * suite.gps_jitter_us;
        let t_us = (epoch_us + jitter).round() as u64;
        let s = flight.state(epoch - delay(epoch));
        events.push(FlightEvent::Gps(Gps {
            t_us,
            position: GpsPosition::Ned(s.r + noise(suite.gps_position_std)),
            velocity_ned_m_s: s.v + noise(suite.gps_velocity_std),
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        }));
    }
    // At equal times: IMU, then magnetometer, then GPS.
    events.sort_by_key(|e| {
        let rank = match e {
            FlightEvent::Imu(..) => 0,
            FlightEvent::Mag(_) => 1,
            FlightEvent::Gps(_) => 2,
        };
        (e.t_us(), rank)
    });
    events
}

/// Feeds one event to a navigator in precision `T`; returns the truth after
/// an IMU sample. Every sample must be accepted.
pub fn feed<T: delaynav::Scalar, N: delaynav::Navigator<T>>(
    nav: &mut N,
    event: &FlightEvent,
) -> Option<State> {
    let v3 = |v: &Vector3<f64>| v.map(T::lit);
    match event {
        FlightEvent::Imu(s, truth) => {
            nav.push_imu(&Imu {
                t_us: s.t_us,
                gyro_rad_s: v3(&s.gyro_rad_s),
                accel_m_s2: v3(&s.accel_m_s2),
            })
            .unwrap();
            Some(*truth)
        }
        FlightEvent::Mag(m) => {
            assert_eq!(
                nav.push_mag(&Mag {
                    t_us: m.t_us,
                    field_body: v3(&m.field_body),
                })
                .unwrap(),
                delaynav::MagOutcome::Queued
            );
            None
        }
        FlightEvent::Gps(g) => {
            let GpsPosition::Ned(r) = g.position else {
                unreachable!("flights use NED fixes")
            };
            nav.push_gps(&Gps {
                t_us: g.t_us,
                position: GpsPosition::Ned(v3(&r)),
                velocity_ned_m_s: v3(&g.velocity_ned_m_s),
                horizontal_accuracy_m: None,
                vertical_accuracy_m: None,
                speed_accuracy_m_s: None,
            })
            .unwrap();
            None
        }
    }
}

//! Synthetic flights, sensors and numeric helpers shared by the filter tests
//! (`ekf16`, `aekf17`): closed-form trajectories, a deterministic noise
//! source, a flight loop feeding any `Navigator`, finite differences.
#![allow(dead_code)]

use delaynav::ekf16::state::NAV_STATES;
use delaynav::geo::{
    euler_from_quaternion, magnetic_field_ned, quaternion_from_euler, rotation_matrix, wrap_pi,
};
use delaynav::{
    Ekf16Config, Error, Estimate, Gps, GpsPosition, Imu, Mag, NavState, Navigator, Scalar,
};
use nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3};

pub const G: f64 = 9.806_65;
pub const INCLINATION: f64 = 1.1; // rad, 63 deg down
pub const DECLINATION: f64 = 0.2; // rad east

// ---------------------------------------------------------------- truth

/// The true motion, f64.
#[derive(Clone, Copy)]
pub enum Motion {
    /// At rest at the origin with a fixed attitude.
    Static { roll: f64, pitch: f64, yaw: f64 },
    /// Straight, level, constant velocity; nose along the velocity.
    ConstantVelocity { velocity: [f64; 3] },
    /// Coordinated level turn at constant speed (m/s) and yaw rate (rad/s).
    Turn { speed: f64, rate: f64, yaw0: f64 },
    /// Level, nose north, flying north at `speed` (m/s) while sliding east
    /// and west, `amplitude * sin(omega t)` (m, rad/s): an acceleration
    /// whose magnitude changes.
    Weave {
        speed: f64,
        amplitude: f64,
        omega: f64,
    },
}

#[derive(Clone, Copy)]
pub struct Truth {
    pub q: UnitQuaternion<f64>,
    pub r: Vector3<f64>,
    pub v: Vector3<f64>,
    pub gyro: Vector3<f64>,
    pub accel: Vector3<f64>,
}

pub fn truth(m: Motion, t: f64) -> Truth {
    let (q, r, v, gyro, a) = match m {
        Motion::Static { roll, pitch, yaw } => (
            quaternion_from_euler(roll, pitch, yaw),
            Vector3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
        ),
        Motion::ConstantVelocity { velocity } => {
            let v = Vector3::from(velocity);
            (
                quaternion_from_euler(0.0, 0.0, v.y.atan2(v.x)),
                v * t,
                v,
                Vector3::zeros(),
                Vector3::zeros(),
            )
        }
        Motion::Turn { speed, rate, yaw0 } => {
            let yaw = yaw0 + rate * t;
            let bank = (speed * rate / G).atan();
            let (s, c) = yaw.sin_cos();
            let (s0, c0) = yaw0.sin_cos();
            (
                quaternion_from_euler(bank, 0.0, yaw),
                Vector3::new(s - s0, c0 - c, 0.0) * (speed / rate),
                Vector3::new(c, s, 0.0) * speed,
                Vector3::new(0.0, rate * bank.sin(), rate * bank.cos()),
                Vector3::new(-s, c, 0.0) * (speed * rate),
            )
        }
        Motion::Weave {
            speed,
            amplitude,
            omega,
        } => {
            let (s, c) = (omega * t).sin_cos();
            (
                quaternion_from_euler(0.0, 0.0, 0.0),
                Vector3::new(speed * t, amplitude * s, 0.0),
                Vector3::new(speed, amplitude * omega * c, 0.0),
                Vector3::zeros(),
                Vector3::new(0.0, -amplitude * omega * omega * s, 0.0),
            )
        }
    };
    let accel = rotation_matrix(q.quaternion()).transpose() * (a - Vector3::new(0.0, 0.0, G));
    Truth {
        q,
        r,
        v,
        gyro,
        accel,
    }
}

// ---------------------------------------------------------------- sensors

/// Deterministic Gaussian noise (xorshift64* and Box-Muller).
pub struct Noise(pub u64);

impl Noise {
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (core::f64::consts::TAU * v).cos()
    }
    pub fn vec3(&mut self, std: f64) -> Vector3<f64> {
        Vector3::new(self.gauss(), self.gauss(), self.gauss()) * std
    }
}

/// A sensor suite flying a motion.
#[derive(Clone, Copy)]
pub struct Scenario {
    pub motion: Motion,
    pub imu_rate_hz: f64,
    pub seconds: f64,
    pub gyro_bias: [f64; 3],
    pub accel_bias: [f64; 3],
    /// Scale of every noise (0 = perfect sensors, 1 = the default config's noise).
    pub noise: f64,
    pub with_mag: bool,
    /// Time of the first GPS fix, s (the filter aligns before it).
    pub first_gps_s: f64,
}

pub fn config<T: Scalar>() -> Ekf16Config<T> {
    Ekf16Config {
        mag_inclination_rad: T::lit(INCLINATION),
        mag_declination_rad: T::lit(DECLINATION),
        ..Ekf16Config::default()
    }
}

pub fn v3<T: Scalar>(v: &Vector3<f64>) -> Vector3<T> {
    v.map(T::lit)
}

pub fn to_f64<T: Scalar>(v: &Vector3<T>) -> Vector3<f64> {
    v.map(|x| x.as_f64())
}

/// Runs a scenario through a navigator: IMU every tick, GPS and
/// magnetometer at 10 Hz (right after the IMU sample of the same tick).
/// `each` sees the navigator and the truth after every IMU tick.
pub fn fly<T: Scalar, N: Navigator<T>>(nav: &mut N, s: &Scenario, each: impl FnMut(&N, &Truth)) {
    fly_delayed(nav, s, 0.0, each);
}

/// As [`fly`] with a GPS delay: the fix received at `t` carries the truth
/// at `t - delay_s` (noise drawn in the same order, so a zero delay is
/// exactly [`fly`]).
pub fn fly_delayed<T: Scalar, N: Navigator<T>>(
    nav: &mut N,
    s: &Scenario,
    delay_s: f64,
    mut each: impl FnMut(&N, &Truth),
) {
    let c = config::<f64>();
    let mut rng = Noise(0x9E37_79B9_7F4A_7C15);
    let gyro_std = s.noise * c.gyro_noise_density * s.imu_rate_hz.sqrt();
    let accel_std = s.noise * c.accel_noise_density * s.imu_rate_hz.sqrt();
    let period_us = (1e6 / s.imu_rate_hz).round() as u64;
    let ticks = (s.seconds * s.imu_rate_hz) as u64;
    let aux_every = (s.imu_rate_hz / 10.0).round() as u64;
    let m_n = magnetic_field_ned(INCLINATION, DECLINATION);
    for k in 0..=ticks {
        let t_us = k * period_us;
        let tr = truth(s.motion, t_us as f64 * 1e-6);
        let imu = Imu {
            t_us,
            gyro_rad_s: v3(&(tr.gyro + Vector3::from(s.gyro_bias) + rng.vec3(gyro_std))),
            accel_m_s2: v3(&(tr.accel + Vector3::from(s.accel_bias) + rng.vec3(accel_std))),
        };
        match nav.push_imu(&imu) {
            // A filter started from a state at t = 0 already has this time.
            Err(Error::DuplicateTimestamp { .. }) if k == 0 => {}
            r => r.unwrap(),
        }
        if k % aux_every == 0 {
            if s.with_mag {
                let m_b = rotation_matrix(tr.q.quaternion()).transpose() * m_n
                    + rng.vec3(s.noise * c.mag_noise_variance.sqrt());
                nav.push_mag(&Mag {
                    t_us,
                    field_body: v3(&m_b),
                })
                .unwrap();
            }
            if k > 0 && t_us as f64 >= s.first_gps_s * 1e6 {
                let seen = truth(s.motion, t_us as f64 * 1e-6 - delay_s);
                let gps = Gps {
                    t_us,
                    position: GpsPosition::Ned(v3(
                        &(seen.r + rng.vec3(s.noise * c.gps_horizontal_std_m))
                    )),
                    velocity_ned_m_s: v3(&(seen.v + rng.vec3(s.noise * c.gps_velocity_std_m_s))),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                };
                nav.push_gps(&gps).unwrap();
            }
        }
        each(nav, &tr);
    }
}

/// A GPS fix without receiver accuracies.
pub fn gps_fix<T: Scalar>(t_us: u64, position: GpsPosition<T>, velocity: Vector3<T>) -> Gps<T> {
    Gps {
        t_us,
        position,
        velocity_ned_m_s: velocity,
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    }
}

/// Roll, pitch, yaw errors (rad, wrapped) of an estimate against the truth.
pub fn euler_error<T: Scalar>(e: &Estimate<T>, tr: &Truth) -> Vector3<f64> {
    let est = to_f64(&e.euler_rad());
    let tru = euler_from_quaternion(tr.q.quaternion());
    (est - tru).map(wrap_pi)
}

/// Smallest eigenvalue of a symmetric matrix, relative to its largest magnitude.
pub fn min_relative_eigenvalue<T: Scalar, const N: usize>(p: &SMatrix<T, N, N>) -> f64 {
    let p64 = nalgebra::DMatrix::from_iterator(N, N, p.iter().map(|x| x.as_f64()));
    let eig = p64.symmetric_eigen().eigenvalues;
    eig.min() / eig.amax()
}

/// Central finite-difference Jacobian of `f` at `x`.
pub fn numeric_jacobian<T: Scalar, const N: usize, const M: usize>(
    x: &SVector<T, N>,
    step: T,
    f: impl Fn(&SVector<T, N>) -> SVector<T, M>,
) -> SMatrix<T, M, N> {
    let mut jac = SMatrix::<T, M, N>::zeros();
    for j in 0..N {
        let mut xp = *x;
        let mut xm = *x;
        xp[j] += step;
        xm[j] -= step;
        jac.set_column(j, &((f(&xp) - f(&xm)) / (step + step)));
    }
    jac
}

/// A state off the axes: tilted attitude, motion, biases.
pub fn sample_state<T: Scalar>() -> SVector<T, NAV_STATES> {
    NavState {
        attitude: quaternion_from_euler(T::lit(0.3), T::lit(-0.4), T::lit(2.0)),
        position_ned_m: Vector3::new(T::lit(10.0), T::lit(-5.0), T::lit(-2.0)),
        velocity_ned_m_s: Vector3::new(T::lit(3.0), T::lit(-1.0), T::lit(0.5)),
        accel_bias_m_s2: Vector3::new(T::lit(0.1), T::lit(-0.2), T::lit(0.3)),
        gyro_bias_rad_s: Vector3::new(T::lit(0.01), T::lit(-0.02), T::lit(0.005)),
    }
    .to_vector()
}

pub fn max_abs_diff<T: Scalar, const R: usize, const C: usize>(
    a: &SMatrix<T, R, C>,
    b: &SMatrix<T, R, C>,
) -> f64 {
    (a - b).amax().as_f64()
}

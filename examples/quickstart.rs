//! A minute of simulated S-turns through `Ekf16<f64>`: IMU at
//! 200 Hz, GPS and magnetometer at 10 Hz, noise of the paper's Table 3 (scaled
//! to the IMU rate). Prints the errors at the end.
//!
//! `cargo run --release --example quickstart`

use delaynav::geo::{
    euler_from_quaternion, magnetic_field_ned, quaternion_from_euler, rotation_matrix, wrap_pi,
};
use delaynav::prelude::*;

/// Uniform noise with the standard deviation `std` (a small LCG: no dependency).
struct Noise(u64);
impl Noise {
    fn next(&mut self, std: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let u = (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        u * std * 12f64.sqrt()
    }
    fn vec3(&mut self, std: f64) -> Vector3<f64> {
        Vector3::new(self.next(std), self.next(std), self.next(std))
    }
}

fn main() -> Result<(), delaynav::Error> {
    let (g, speed, turn_rate, rate_hz): (f64, f64, f64, f64) = (9.806_65, 10.0, 0.3, 200.0);
    let (inclination, declination): (f64, f64) = (1.0, 0.1);
    let config = Ekf16Config {
        mag_inclination_rad: inclination,
        mag_declination_rad: declination,
        ..Ekf16Config::default()
    };
    let mut ekf = Ekf16::new(config)?;
    let mut noise = Noise(7);
    let gyro_bias = Vector3::new(0.003, -0.002, 0.004);
    let accel_bias = Vector3::new(0.1, -0.05, 0.15);
    // S-turns: the yaw rate swings as w0 sin(2 pi t / period), the vehicle
    // banks to turn at constant speed (coordinated, level). Varying the turn
    // keeps every bias observable.
    let period = 20.0;
    let k_w = core::f64::consts::TAU / period;
    let yaw_of = |t: f64| turn_rate / k_w * (1.0 - (k_w * t).cos());
    // Attitude, velocity, body rate and specific force at time t.
    let truth = |t: f64| {
        let (yaw, yaw_rate) = (yaw_of(t), turn_rate * (k_w * t).sin());
        let yaw_acc = turn_rate * k_w * (k_w * t).cos();
        let kb = speed / g;
        let bank = (kb * yaw_rate).atan();
        let bank_rate = kb * yaw_acc / (1.0 + (kb * yaw_rate).powi(2));
        let q = quaternion_from_euler(bank, 0.0, yaw);
        let (s, c) = yaw.sin_cos();
        let v = Vector3::new(c, s, 0.0) * speed;
        let a = Vector3::new(-s, c, 0.0) * (speed * yaw_rate);
        let w = Vector3::new(bank_rate, yaw_rate * bank.sin(), yaw_rate * bank.cos());
        let f = rotation_matrix(q.quaternion()).transpose() * (a - Vector3::new(0.0, 0.0, g));
        (q, v, w, f)
    };
    // Position: the velocity integrated with 10 midpoint substeps per IMU step.
    let mut r = Vector3::zeros();
    let gyro_std = config.gyro_noise_density * rate_hz.sqrt();
    let accel_std = config.accel_noise_density * rate_hz.sqrt();
    let m_n = magnetic_field_ned(inclination, declination);
    let steps = (60.0 * rate_hz) as u64;
    for k in 0..=steps {
        let t_us = k * 5_000;
        let t = t_us as f64 * 1e-6;
        if k > 0 {
            for j in 0..10 {
                r += truth(t - 5e-3 + (j as f64 + 0.5) * 5e-4).1 * 5e-4;
            }
        }
        let (q, v, w, f) = truth(t);
        // A refused sample leaves the filter unchanged and is counted in
        // `ekf.refusals()` (printed at the end): routine, not a reason to stop.
        let gyro = w + gyro_bias + noise.vec3(gyro_std);
        let _ = ekf.push_imu(&Imu::new(
            t_us,
            gyro,
            f + accel_bias + noise.vec3(accel_std),
        ));
        if k % 20 == 0 {
            let field_body = rotation_matrix(q.quaternion()).transpose() * m_n + noise.vec3(0.14);
            let _ = ekf.push_mag(&Mag::new(t_us, field_body));
        }
        if k % 20 == 10 {
            let _ = ekf.push_gps(&Gps::ned(t_us, r + noise.vec3(2.0), v + noise.vec3(0.3)));
        }
    }
    let (q, v, _, _) = truth(steps as f64 * 5e-3);
    let e = ekf.estimate().expect("initialized by the first GPS fix");
    let att = (e.euler_rad() - euler_from_quaternion(q.quaternion())).map(wrap_pi);
    println!(
        "after 60 s: roll {:+.2} deg, pitch {:+.2} deg, yaw {:+.2} deg off",
        att.x.to_degrees(),
        att.y.to_degrees(),
        att.z.to_degrees()
    );
    println!(
        "position {:.2} m, velocity {:.3} m/s off; gyro bias {:.4} rad/s off",
        (e.position_ned_m - r).norm(),
        (e.velocity_ned_m_s - v).norm(),
        (e.gyro_bias_rad_s - gyro_bias).norm()
    );
    println!("refused or gated out: {:?}", ekf.refusals());
    Ok(())
}

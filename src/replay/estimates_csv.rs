//! Writer of per-sample estimates as CSV, one row per [`Estimate`].
//!
//! Columns (units in the names, frames as in [`Estimate`]): `estimator,
//! t_us, q0..q3, roll_deg, pitch_deg, yaw_deg, pos_[ned]_m, vel_[ned]_m_s,
//! acc_bias_[xyz]_m_s2, gyro_bias_[xyz]_rad_s, delay_s, delay_std_s`; the
//! delay cells are empty for estimators without a delay estimate.

use crate::estimate::Estimate;
use crate::scalar::Scalar;
use std::io::Write;

/// The header row of the estimates file.
pub const ESTIMATE_COLUMNS: [&str; 23] = [
    "estimator",
    "t_us",
    "q0",
    "q1",
    "q2",
    "q3",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "pos_n_m",
    "pos_e_m",
    "pos_d_m",
    "vel_n_m_s",
    "vel_e_m_s",
    "vel_d_m_s",
    "acc_bias_x_m_s2",
    "acc_bias_y_m_s2",
    "acc_bias_z_m_s2",
    "gyro_bias_x_rad_s",
    "gyro_bias_y_rad_s",
    "gyro_bias_z_rad_s",
    "delay_s",
    "delay_std_s",
];

/// Streams estimates to CSV.
pub struct EstimateWriter<W: Write> {
    writer: csv::Writer<W>,
}

impl<W: Write> EstimateWriter<W> {
    /// Wraps `out` and writes the header row.
    pub fn new(out: W) -> csv::Result<Self> {
        let mut writer = csv::Writer::from_writer(out);
        writer.write_record(ESTIMATE_COLUMNS)?;
        Ok(Self { writer })
    }

    /// Writes one estimate of the estimator named `estimator`.
    pub fn write<T: Scalar>(&mut self, estimator: &str, e: &Estimate<T>) -> csv::Result<()> {
        let q = e.attitude.quaternion();
        let euler = e.euler_rad().map(|a| a.as_f64().to_degrees());
        let mut row: Vec<String> = vec![estimator.to_string(), e.t_us.to_string()];
        let numbers = [q.w, q.i, q.j, q.k]
            .into_iter()
            .map(Scalar::as_f64)
            .chain(euler.iter().copied())
            .chain(e.position_ned_m.iter().map(|v| v.as_f64()))
            .chain(e.velocity_ned_m_s.iter().map(|v| v.as_f64()))
            .chain(e.accel_bias_m_s2.iter().map(|v| v.as_f64()))
            .chain(e.gyro_bias_rad_s.iter().map(|v| v.as_f64()));
        row.extend(numbers.map(|v| v.to_string()));
        for d in [e.delay_s, e.delay_std_s] {
            row.push(d.map(|v| v.as_f64().to_string()).unwrap_or_default());
        }
        self.writer.write_record(&row)
    }

    /// Flushes the underlying writer.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.writer.flush()
    }
}

//! Initialization: the attitude levelled from the accelerometer mean and
//! headed from the magnetometer (or left uncertain without one), the
//! position and velocity from the first fix.

use super::*;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Initial state and covariance from the accelerometer mean, the latest
    /// magnetometer direction and a GPS fix.
    pub(super) fn initialize(&mut self, fix: &GpsMeasurement<T>) -> Result<(), Error> {
        let c = self.config;
        let (roll, pitch) =
            roll_pitch_from_accel(&(self.accel_mean.mean - c.initial_accel_bias_m_s2));
        let (yaw, yaw_std) = match self.mag_mean.count {
            1.. => (
                tilt_compensated_heading(&self.mag_mean.mean, roll, pitch, c.mag_declination_rad),
                c.initial_yaw_std_rad,
            ),
            0 => (T::zero(), c.initial_yaw_std_no_mag_rad),
        };
        let q = quaternion_from_euler(roll, pitch, yaw);
        let rot = rotation_matrix(q.quaternion());
        if self.mag_mean.count > 0 {
            let norm = self.mag_norm_mean.mean[0];
            let inclination = field_inclination(&rot, &self.mag_mean.mean);
            self.mag_field = Some((norm, inclination));
            self.mag_monitor = mag_monitor::MagMonitor::started_at(
                &self.mag_mean.mean,
                norm,
                self.mag_norm_mean.count,
            );
        }
        let gyro =
            self.last_imu.map_or_else(Vector3::zeros, |s| s.gyro_rad_s) - c.initial_gyro_bias_rad_s;
        let mut x = self.extras_vector(|e| e.initial);
        x.fixed_rows_mut::<4>(QUAT)
            .copy_from(&q.quaternion().coords_wxyz());
        x.fixed_rows_mut::<3>(POS)
            .copy_from(&(fix.position_ned_m - rot * c.lever_arm_m));
        x.fixed_rows_mut::<3>(VEL)
            .copy_from(&(fix.velocity_ned_m_s - rot * gyro.cross(&c.lever_arm_m)));
        x.fixed_rows_mut::<3>(ACCEL_BIAS)
            .copy_from(&c.initial_accel_bias_m_s2);
        x.fixed_rows_mut::<3>(GYRO_BIAS)
            .copy_from(&c.initial_gyro_bias_rad_s);
        let mut p = SMatrix::<T, N, N>::from_diagonal(&self.extras_vector(|e| e.initial_variance));
        p.fixed_view_mut::<4, 4>(QUAT, QUAT)
            .copy_from(&attitude_covariance(
                &q,
                c.initial_tilt_std_rad,
                c.initial_tilt_std_rad,
                yaw_std,
            ));
        let sq = |v: T| v * v;
        for i in 0..3 {
            p[(POS + i, POS + i)] = sq(c.initial_position_std_m);
            p[(VEL + i, VEL + i)] = sq(c.initial_velocity_std_m_s);
            p[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = sq(c.initial_accel_bias_std_m_s2);
            p[(GYRO_BIAS + i, GYRO_BIAS + i)] = sq(c.initial_gyro_bias_std_rad_s);
        }
        if !(all_finite_fixed(&x) && all_finite_fixed(&p)) {
            return Err(Error::NonFinite {
                field: "initial state",
            });
        }
        self.x = x;
        self.p = p;
        self.initialized = true;
        Ok(())
    }
}

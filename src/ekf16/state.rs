//! The paper's 16-state vector (eq. 1), its named indices, and attitude
//! covariance helpers.
//!
//! ```text
//! x = [ q0 q1 q2 q3 | r_n r_e r_d | v_n v_e v_d | b_fx b_fy b_fz | b_wx b_wy b_wz ]
//!       QUAT (0..4)   POS (4..7)    VEL (7..10)   ACCEL_BIAS       GYRO_BIAS
//!                                                 (10..13)         (13..16)
//! ```
//!
//! - `q`: Hamilton, scalar first, body FRD to NED (unit norm after every step);
//! - `r`: position NED, metres from the local origin;
//! - `v`: velocity NED, m/s;
//! - `b_f`: accelerometer bias, body FRD, m/s^2 (the sensor reads `f + b_f`);
//! - `b_w`: gyro bias, body FRD, rad/s (the sensor reads `w + b_w`).
//!
//! Filters with more states (the augmented 17-state baseline) append them
//! after [`NAV_STATES`].

use crate::geo::euler_from_quaternion;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Matrix4, Quaternion, SMatrix, SVector, UnitQuaternion, Vector3};

/// First index of the quaternion `q0..q3`.
pub const QUAT: usize = 0;
/// First index of the position NED (m).
pub const POS: usize = 4;
/// First index of the velocity NED (m/s).
pub const VEL: usize = 7;
/// First index of the accelerometer bias, body (m/s^2).
pub const ACCEL_BIAS: usize = 10;
/// First index of the gyro bias, body (rad/s).
pub const GYRO_BIAS: usize = 13;
/// Number of navigation states (the paper's 16).
pub const NAV_STATES: usize = 16;

/// The 16-state vector.
pub type StateVector<T> = SVector<T, NAV_STATES>;
/// The 16x16 covariance.
pub type StateCovariance<T> = SMatrix<T, NAV_STATES, NAV_STATES>;

/// The navigation state with named fields (the paper's eq. 1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavState<T: Scalar> {
    /// Body-to-NED attitude.
    pub attitude: UnitQuaternion<T>,
    /// Position NED, metres from the local origin.
    pub position_ned_m: Vector3<T>,
    /// Velocity NED, m/s.
    pub velocity_ned_m_s: Vector3<T>,
    /// Accelerometer bias, body FRD, m/s^2.
    pub accel_bias_m_s2: Vector3<T>,
    /// Gyro bias, body FRD, rad/s.
    pub gyro_bias_rad_s: Vector3<T>,
}

impl<T: Scalar> NavState<T> {
    /// The state vector in the order of eq. (1).
    pub fn to_vector(&self) -> StateVector<T> {
        let mut x = StateVector::zeros();
        x.fixed_rows_mut::<4>(QUAT)
            .copy_from(&self.attitude.quaternion().coords_wxyz());
        x.fixed_rows_mut::<3>(POS).copy_from(&self.position_ned_m);
        x.fixed_rows_mut::<3>(VEL).copy_from(&self.velocity_ned_m_s);
        x.fixed_rows_mut::<3>(ACCEL_BIAS)
            .copy_from(&self.accel_bias_m_s2);
        x.fixed_rows_mut::<3>(GYRO_BIAS)
            .copy_from(&self.gyro_bias_rad_s);
        x
    }

    /// The named state of a state vector (the quaternion is normalized).
    pub fn from_vector(x: &StateVector<T>) -> Self {
        Self {
            attitude: UnitQuaternion::new_normalize(quaternion_of(x)),
            position_ned_m: x.fixed_rows::<3>(POS).into_owned(),
            velocity_ned_m_s: x.fixed_rows::<3>(VEL).into_owned(),
            accel_bias_m_s2: x.fixed_rows::<3>(ACCEL_BIAS).into_owned(),
            gyro_bias_rad_s: x.fixed_rows::<3>(GYRO_BIAS).into_owned(),
        }
    }
}

/// Scalar-first quaternion coordinates `[q0 q1 q2 q3]`.
pub(crate) trait WxyzCoords<T: Scalar> {
    /// `[w, i, j, k]`.
    fn coords_wxyz(&self) -> nalgebra::Vector4<T>;
}

impl<T: Scalar> WxyzCoords<T> for Quaternion<T> {
    fn coords_wxyz(&self) -> nalgebra::Vector4<T> {
        nalgebra::Vector4::new(self.w, self.i, self.j, self.k)
    }
}

/// The quaternion `q0..q3` stored at the start of a state vector (any length).
pub(crate) fn quaternion_of<T: Scalar, const N: usize>(x: &SVector<T, N>) -> Quaternion<T> {
    Quaternion::new(x[QUAT], x[QUAT + 1], x[QUAT + 2], x[QUAT + 3])
}

/// Jacobian `dq / d(roll, pitch, yaw)` of the ZYX Euler-to-quaternion map
/// ([`quaternion_from_euler`](crate::geo::quaternion_from_euler)), 4x3, radians.
pub fn euler_to_quaternion_jacobian<T: Scalar>(roll: T, pitch: T, yaw: T) -> SMatrix<T, 4, 3> {
    let half = T::lit(0.5);
    let (sr, cr) = (roll * half).sin_cos();
    let (sp, cp) = (pitch * half).sin_cos();
    let (sy, cy) = (yaw * half).sin_cos();
    SMatrix::<T, 4, 3>::new(
        // d/droll
        -sr * cp * cy + cr * sp * sy,
        // d/dpitch
        -cr * sp * cy + sr * cp * sy,
        // d/dyaw
        -cr * cp * sy + sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
        -sr * sp * cy - cr * cp * sy,
        -sr * cp * sy - cr * sp * cy,
        -sr * sp * cy + cr * cp * sy,
        cr * cp * cy - sr * sp * sy,
        -cr * sp * sy + sr * cp * cy,
        -sr * cp * sy - cr * sp * cy,
        -cr * sp * sy - sr * cp * cy,
        cr * cp * cy + sr * sp * sy,
    ) * half
}

/// Quaternion covariance (4x4) of independent roll, pitch and yaw errors with
/// the given standard deviations (radians) about the attitude `q`:
/// `P_qq = J diag(s_roll², s_pitch², s_yaw²) J^T` with `J = dq/d(roll, pitch, yaw)`.
///
/// Built this way, the yaw-only magnetometer update of an uncorrelated
/// filter moves yaw alone: `dpsi/dq J = [0 0 1]`. The map degenerates at
/// pitch `+-90 deg` (gimbal lock), where roll and yaw are one rotation.
pub fn attitude_covariance<T: Scalar>(
    q: &UnitQuaternion<T>,
    roll_std: T,
    pitch_std: T,
    yaw_std: T,
) -> Matrix4<T> {
    let e = euler_from_quaternion(q.quaternion());
    // quaternion_from_euler(e) is +q or -q: the sign cancels in J D J^T.
    let j = euler_to_quaternion_jacobian(e.x, e.y, e.z);
    let d = Matrix3::from_diagonal(&Vector3::new(
        roll_std * roll_std,
        pitch_std * pitch_std,
        yaw_std * yaw_std,
    ));
    j * d * j.transpose()
}

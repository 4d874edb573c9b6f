//! Measurement models of the 16-state EKF: GPS position and velocity (with
//! the antenna lever arm), the heading-only magnetometer pseudo-measurement
//! and the 3-axis field direction. Pure functions returning `h(x)` and
//! `H = ∂h/∂x`.
//!
//! Equation numbers follow the published paper, where the pseudo-measurement
//! and its three rotation matrices form eq. (6), the measurement model
//! `z = h(x) + e` eq. (7) and its Jacobian `H` eq. (8).
//!
//! # GPS (eq. 7 rows 4-9 and eq. 8, plus the lever arm)
//! The antenna sits at `l_b` (m, body FRD) from the IMU. With `w` the last
//! measured rate:
//!
//! ```text
//! h_r(x) = r + R(q) l_b                          (m, NED)
//! h_v(x) = v + R(q) ((w - b_w) × l_b)            (m/s, NED)
//!
//! ∂h_r/∂r = I      ∂h_r/∂q = ∂(R(q) l_b)/∂q
//! ∂h_v/∂v = I      ∂h_v/∂q = ∂(R(q) u)/∂q, u = (w - b_w) × l_b
//!                  ∂h_v/∂b_w = R(q) [l_b ×]
//! ```
//!
//! With `l_b = 0` these are the identity blocks of eq. (8).
//!
//! # Magnetometer (eqs. 6-8, with `C_psi(3,3) = 1`)
//! The paper does not fuse the raw field. From the magnetometer it takes
//! only the tilt-compensated true heading `psi_mag`
//! ([`tilt_compensated_heading`](crate::geo::tilt_compensated_heading)) and
//! rebuilds a unit field with the *estimated* roll and pitch:
//!
//! ```text
//! m~ = C_phi(phi^) C_theta(theta^) C_psi(psi_mag) m_n
//!
//!          | 1    0      0   |            | cos θ  0  -sin θ |           |  cos ψ  sin ψ  0 |
//! C_phi  = | 0  cos φ  sin φ |  C_theta = |   0    1     0   |  C_psi =  | -sin ψ  cos ψ  0 |
//!          | 0 -sin φ  cos φ |            | sin θ  0   cos θ |           |    0      0    1 |
//! ```
//!
//! (the paper prints `C_psi(3,3) = 0`, which would drop the vertical field;
//! with 1 the product is the NED-to-body matrix `R(q)^T` of the Euler angles).
//! `m_n = [cos I cos D, cos I sin D, sin I]` with inclination `I` down from
//! horizontal and declination `D` east of north (the paper's text swaps
//! sine and cosine of `I` there, measuring it from the vertical).
//!
//! Eq. (7) writes the model as `R(q)^T m_n`, whose Jacobian `H^m` would let
//! the raw field pull roll and pitch. The model here holds `phi^`,
//! `theta^` at the current estimate and, as a first reading of the paper's
//! text, lets only yaw depend on the state ([`mag_model`]):
//!
//! ```text
//! h_m(x) = C_phi(phi^) C_theta(theta^) C_psi(psi(q)) m_n
//! psi(q) = atan2(2(q1 q2 + q0 q3), q0² + q1² - q2² - q3²)
//! H_m    = [C_phi C_theta (dC_psi/dpsi) m_n] (dpsi/dq)      (3x4, rank one)
//! ```
//!
//! That Jacobian is wrong for the number actually fused: `psi_mag` is the
//! heading of the field de-rotated with the *estimated* roll and pitch, so
//! with an inclined field it is off by about `tan(I)` times the tilt error.
//! The filter uses [`mag_model_tilt_coupled`], the Jacobian of
//! `psi_mag(R(q)^T m_n; phi^, theta^)`, which equals the one above along a
//! heading change and is not zero along a tilt change. Whether the update may
//! then move roll and pitch is
//! [`Ekf16Config::mag_corrects_tilt`](super::config::Ekf16Config::mag_corrects_tilt)
//! (see `docs/math.md`, "Magnetometer"). The homogeneous form of `psi(q)`
//! makes `dpsi/dq` orthogonal to `q`, and `psi_mag` does not change when the
//! field is scaled: neither Jacobian changes the quaternion's norm to first
//! order.

use super::state::{ACCEL_BIAS, GYRO_BIAS, NAV_STATES, POS, QUAT, StateVector, VEL, quaternion_of};
use crate::ekf16::process::rotation_jacobian;
use crate::geo::rotation_matrix;
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Quaternion, RowVector3, RowVector4, SMatrix, Vector3};

/// Jacobian of a 3-D measurement with respect to the 16 navigation states.
pub type MeasurementJacobian<T> = SMatrix<T, 3, NAV_STATES>;

/// GPS antenna position model `r + R(q) l_b` and its Jacobian.
pub fn gps_position<T: Scalar>(
    x: &StateVector<T>,
    lever_arm: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let q = quaternion_of(x);
    let h = x.fixed_rows::<3>(POS) + rotation_matrix(&q) * lever_arm;
    let mut jac = MeasurementJacobian::zeros();
    jac.fixed_view_mut::<3, 3>(0, POS).fill_with_identity();
    jac.fixed_view_mut::<3, 4>(0, QUAT)
        .copy_from(&rotation_jacobian(&q, lever_arm));
    (h, jac)
}

/// GPS antenna velocity model `v + R(q)((w - b_w) × l_b)` and its Jacobian;
/// `gyro` is the measured rate (rad/s, body).
pub fn gps_velocity<T: Scalar>(
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    lever_arm: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let q = quaternion_of(x);
    let r = rotation_matrix(&q);
    let u = (gyro - x.fixed_rows::<3>(GYRO_BIAS)).cross(lever_arm);
    let h = x.fixed_rows::<3>(VEL) + r * u;
    let mut jac = MeasurementJacobian::zeros();
    jac.fixed_view_mut::<3, 3>(0, VEL).fill_with_identity();
    jac.fixed_view_mut::<3, 4>(0, QUAT)
        .copy_from(&rotation_jacobian(&q, &u));
    jac.fixed_view_mut::<3, 3>(0, GYRO_BIAS)
        .copy_from(&(r * lever_arm.cross_matrix()));
    (h, jac)
}

/// The paper's `C_phi`: NED-to-body rotation by roll alone.
pub fn c_roll<T: Scalar>(roll: T) -> Matrix3<T> {
    c_roll_sc(roll.sin_cos())
}

fn c_roll_sc<T: Scalar>((s, c): (T, T)) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(o, z, z, z, c, s, z, -s, c)
}

/// The paper's `C_theta`: NED-to-body rotation by pitch alone.
pub fn c_pitch<T: Scalar>(pitch: T) -> Matrix3<T> {
    c_pitch_sc(pitch.sin_cos())
}

fn c_pitch_sc<T: Scalar>((s, c): (T, T)) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(c, z, -s, z, o, z, s, z, c)
}

/// The paper's `C_psi` with its (3,3) entry corrected to 1.
pub fn c_yaw<T: Scalar>(yaw: T) -> Matrix3<T> {
    c_yaw_sc(yaw.sin_cos())
}

fn c_yaw_sc<T: Scalar>((s, c): (T, T)) -> Matrix3<T> {
    let (o, z) = (T::one(), T::zero());
    Matrix3::new(c, s, z, -s, c, z, z, z, o)
}

/// `dC_psi/dpsi` from `(sin psi, cos psi)`.
fn c_yaw_derivative_sc<T: Scalar>((s, c): (T, T)) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(-s, c, z, -c, -s, z, z, z, z)
}

/// Sines and cosines of the roll and pitch a magnetometer update holds
/// fixed, `(sin, cos)` each: computed once per sample and shared by the
/// tilt-compensated heading, the pseudo-measurement and the model (in `f32`
/// on a Cortex-M4 each `sin_cos` is a software `f64` evaluation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tilt<T: Scalar> {
    pub(crate) roll: (T, T),
    pub(crate) pitch: (T, T),
}

impl<T: Scalar> Tilt<T> {
    pub(crate) fn new(roll: T, pitch: T) -> Self {
        Self {
            roll: roll.sin_cos(),
            pitch: pitch.sin_cos(),
        }
    }

    /// `C_phi C_theta`.
    fn matrix(&self) -> Matrix3<T> {
        c_roll_sc(self.roll) * c_pitch_sc(self.pitch)
    }
}

/// Yaw (radians, `(-pi, pi]`) of a quaternion, homogeneous in `q`.
pub fn heading<T: Scalar>(q: &Quaternion<T>) -> T {
    let (a, b) = heading_terms(q);
    a.atan2(b)
}

fn heading_terms<T: Scalar>(q: &Quaternion<T>) -> (T, T) {
    let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
    (
        T::lit(2.0) * (q1 * q2 + q0 * q3),
        q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3,
    )
}

/// `dpsi/dq` (1x4) of [`heading`].
pub fn heading_jacobian<T: Scalar>(q: &Quaternion<T>) -> RowVector4<T> {
    let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
    let (a, b) = heading_terms(q);
    let two = T::lit(2.0);
    let da = RowVector4::new(q3, q2, q1, q0) * two;
    let db = RowVector4::new(q0, q1, -q2, -q3) * two;
    (da * b - db * a) / (a * a + b * b)
}

/// The pseudo-measurement `m~ = C_phi(roll) C_theta(pitch) C_psi(heading) m_n`
/// (eq. 6 with `C_psi(3,3) = 1`). Angles in radians, `m_n` unit NED field.
pub fn mag_pseudo_measurement<T: Scalar>(
    roll: T,
    pitch: T,
    heading: T,
    field_ned: &Vector3<T>,
) -> Vector3<T> {
    pseudo_measurement(&Tilt::new(roll, pitch), heading, field_ned)
}

/// [`mag_pseudo_measurement`] for a precomputed [`Tilt`].
pub(crate) fn pseudo_measurement<T: Scalar>(
    tilt: &Tilt<T>,
    heading: T,
    field_ned: &Vector3<T>,
) -> Vector3<T> {
    tilt.matrix() * (c_yaw(heading) * field_ned)
}

/// The magnetometer model `h_m(x)` with roll and pitch held at `roll`,
/// `pitch` (the current estimate), and its rank-one Jacobian through yaw
/// only (not the one the filter fuses with: see [`mag_model_tilt_coupled`]).
pub fn mag_model<T: Scalar>(
    x: &StateVector<T>,
    roll: T,
    pitch: T,
    field_ned: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let q = quaternion_of(x);
    mag_model_with_heading_jacobian(
        &q,
        &Tilt::new(roll, pitch),
        field_ned,
        &heading_jacobian(&q),
    )
}

/// `h_m` at the heading of `q` and the Jacobian `dh_m/dpsi dpsi_dq` for the
/// given heading Jacobian `dpsi_dq` (1x4).
fn mag_model_with_heading_jacobian<T: Scalar>(
    q: &Quaternion<T>,
    tilt: &Tilt<T>,
    field_ned: &Vector3<T>,
    dpsi_dq: &RowVector4<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let psi = heading(q).sin_cos();
    let tilt = tilt.matrix();
    let h = tilt * (c_yaw_sc(psi) * field_ned);
    let dh_dpsi = tilt * (c_yaw_derivative_sc(psi) * field_ned);
    let mut jac = MeasurementJacobian::zeros();
    jac.fixed_view_mut::<3, 4>(0, QUAT)
        .copy_from(&(dh_dpsi * dpsi_dq));
    (h, jac)
}

/// `d psi_mag / d m_b` (1x3): how the tilt-compensated heading
/// ([`tilt_compensated_heading`](crate::geo::tilt_compensated_heading)) of a
/// body field `m_b` moves with the field, roll and pitch held at `roll`, `pitch`.
pub fn tilt_compensated_heading_gradient<T: Scalar>(
    field_body: &Vector3<T>,
    roll: T,
    pitch: T,
) -> RowVector3<T> {
    heading_gradient(field_body, &Tilt::new(roll, pitch))
}

/// [`tilt_compensated_heading_gradient`] for a precomputed [`Tilt`].
fn heading_gradient<T: Scalar>(field_body: &Vector3<T>, tilt: &Tilt<T>) -> RowVector3<T> {
    let ((sr, cr), (sp, cp)) = (tilt.roll, tilt.pitch);
    let m = field_body;
    let xh = cp * m.x + sp * (sr * m.y + cr * m.z);
    let yh = cr * m.y - sr * m.z;
    let dxh = RowVector3::new(cp, sp * sr, sp * cr);
    let dyh = RowVector3::new(T::zero(), cr, -sr);
    // psi = atan2(-yh, xh): d psi = (yh dxh - xh dyh) / (xh² + yh²).
    (dxh * yh - dyh * xh) / (xh * xh + yh * yh)
}

/// `d(R(q)^T u)/dq` (3x4) for a fixed NED vector `u`: the body-frame
/// reading of `u` as the attitude moves (`R(q)^T = R(q*)`).
pub fn inverse_rotation_jacobian<T: Scalar>(q: &Quaternion<T>, u: &Vector3<T>) -> SMatrix<T, 3, 4> {
    let mut j = rotation_jacobian(&q.conjugate(), u);
    for c in 1..4 {
        j.column_mut(c).neg_mut();
    }
    j
}

/// The magnetometer model of [`mag_model`] with the Jacobian of the heading
/// the filter actually measures: `psi_mag(m_b, roll^, pitch^)` with the body
/// field `m_b = R(q)^T m_n` and roll, pitch held at the estimate used to
/// de-rotate it,
///
/// ```text
/// H_m = [C_phi C_theta (dC_psi/dpsi) m_n] (d psi_mag/d m_b) d(R(q)^T m_n)/dq
/// ```
///
/// Along a pure yaw change this equals [`mag_model`]'s `dpsi/dq`; along a
/// tilt change it is not zero when the field is inclined: a heading
/// computed with a wrong roll or pitch is wrong by about `tan(I)` times the
/// tilt error. Ignoring that term (as [`mag_model`] does) makes the filter
/// treat the tilt error it feeds in as information on yaw.
pub fn mag_model_tilt_coupled<T: Scalar>(
    x: &StateVector<T>,
    roll: T,
    pitch: T,
    field_ned: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    model_tilt_coupled(x, &Tilt::new(roll, pitch), field_ned)
}

/// [`mag_model_tilt_coupled`] for a precomputed [`Tilt`].
pub(crate) fn model_tilt_coupled<T: Scalar>(
    x: &StateVector<T>,
    tilt: &Tilt<T>,
    field_ned: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let q = quaternion_of(x);
    let field_body = rotation_matrix(&q).transpose() * field_ned;
    let dpsi_dq = heading_gradient(&field_body, tilt) * inverse_rotation_jacobian(&q, field_ned);
    mag_model_with_heading_jacobian(&q, tilt, field_ned, &dpsi_dq)
}

/// The 3-axis magnetometer model: the body-frame direction of the Earth
/// field `m_n` (unit, NED) at the attitude of `x`, and its Jacobian,
///
/// ```text
/// h_f(x) = R(q)ᵀ m_n                      (unit, body FRD)
/// H_f    = ∂(R(q)ᵀ m_n)/∂q                (3x4 in the quaternion columns)
/// ```
///
/// fused against the measured direction `z = (m_b − b_hi) / |m_b − b_hi|`
/// (hard-iron offset `b_hi` removed, see `docs/math.md`, "Magnetometer:
/// 3-axis field"). Unlike the heading pseudo-measurement it observes roll
/// and pitch directly: the field is a second reference direction beside
/// gravity (a rotation about the field itself is the one it cannot see).
/// `H_f q = 2 h_f`, which is orthogonal to every rotation: the
/// component along `q` is removed by the covariance projection and the
/// renormalization (and the innovation of two unit vectors has no first-order
/// component along `h_f`).
pub fn mag_field_model<T: Scalar>(
    x: &StateVector<T>,
    field_ned: &Vector3<T>,
) -> (Vector3<T>, MeasurementJacobian<T>) {
    let q = quaternion_of(x);
    let h = rotation_matrix(&q).transpose() * field_ned;
    let mut jac = MeasurementJacobian::zeros();
    jac.fixed_view_mut::<3, 4>(0, QUAT)
        .copy_from(&inverse_rotation_jacobian(&q, field_ned));
    (h, jac)
}

/// `dq/dpsi` (4x1) of a pure heading change at fixed roll and pitch: the
/// rotation about the NED down axis, `[0, 0, 0, 1/2] ⊗ q`.
pub fn yaw_direction<T: Scalar>(q: &Quaternion<T>) -> nalgebra::Vector4<T> {
    let half = T::lit(0.5);
    nalgebra::Vector4::new(-q.k, -q.j, q.i, q.w) * half
}

/// The gain restriction `C` (`N x N`) of the heading-only magnetometer
/// update: `K' = C K` (see `docs/math.md`, "Heading-only update").
///
/// - quaternion rows: `(dq/dpsi)(dpsi/dq)`, the correction's rotation is
///   about the NED down axis only ([`yaw_direction`], [`heading_jacobian`]);
///   roll and pitch cannot move;
/// - accelerometer-bias rows: 0 (through them a heading update would move
///   the tilt at the next steps);
/// - gyro-bias rows: `d dᵀ` with `d = R(q)ᵀ [0, 0, 1]` the body-frame down
///   axis: only the bias of the heading rate is corrected, not the roll and
///   pitch rates';
/// - every other row (position, velocity, extra states): kept.
pub fn heading_only_restriction<T: Scalar, const N: usize>(q: &Quaternion<T>) -> SMatrix<T, N, N> {
    let mut keep = SMatrix::<T, N, N>::identity();
    keep.fixed_view_mut::<4, 4>(QUAT, QUAT)
        .copy_from(&(yaw_direction(q) * heading_jacobian(q)));
    keep.fixed_view_mut::<3, 3>(ACCEL_BIAS, ACCEL_BIAS)
        .fill(T::zero());
    let down = rotation_matrix(q).transpose() * Vector3::z();
    keep.fixed_view_mut::<3, 3>(GYRO_BIAS, GYRO_BIAS)
        .copy_from(&(down * down.transpose()));
    keep
}

//! The delayed GPS measurement of the augmented EKF (paper eq. 11, rows
//! 4-9) and its Jacobian over the 17 states. Pure functions returning
//! `h(x)` and `H = ∂h/∂x`.
//!
//! # Model
//! A fix received at `t` describes the antenna at `t - tau`. Expanding the
//! IMU point's trajectory to second order around the current state, with
//! `a` the navigation-frame acceleration of the process model (eq. 2) at
//! the current IMU sample `f~`:
//!
//! ```text
//! a(x)   = R(q) (f~ - b_f) + [0, 0, g]                        (m/s², NED)
//! h_r(x) = r - v tau + a tau² / 2 + R(q) l_b                  (m, NED)
//! h_v(x) = v - a tau             + R(q) ((w~ - b_w) × l_b)    (m/s, NED)
//! ```
//!
//! The lever-arm terms are those of the 16-state filter
//! ([`internals::measurement`](crate::internals::measurement)) taken at the current
//! attitude and rate: their change over `tau` is `O(|w| tau |l_b|)`,
//! centimetres for a lever arm of decimetres, below the GPS noise.
//!
//! # Jacobian (3x17 per block; the 9x17 of the paper with the magnetometer rows)
//! With `u = f~ - b_f` and `J_R(q, u) = ∂(R(q) u)/∂q`
//! ([`rotation_jacobian`]):
//!
//! ```text
//!            ∂/∂q                      ∂/∂r   ∂/∂v     ∂/∂b_f            ∂/∂b_w        ∂/∂tau
//! h_r :  J_R(q,l_b) + tau²/2 J_R(q,u)   I    -tau I   -tau²/2 R(q)         0          -v + a tau
//! h_v :  J_R(q,w×l_b) - tau J_R(q,u)    0      I       tau R(q)       R(q)[l_b ×]        -a
//! ```
//!
//! The terms through `q` and `b_f` are those the paper leaves implicit: they
//! let the delayed fix correct attitude and accelerometer bias through the
//! acceleration it predicts. `∂/∂tau` is what makes `tau` observable: the
//! velocity block sees it through the acceleration, the position block
//! through the velocity; with neither (hover) `tau` is not observable.

use crate::ekf16::measurement::{gps_position, gps_velocity};
use crate::ekf16::nav_core::NavCore;
use crate::ekf16::process::rotation_jacobian;
use crate::ekf16::state::{ACCEL_BIAS, NAV_STATES, QUAT, StateVector, VEL, quaternion_of};
use crate::geo::rotation_matrix;
use crate::scalar::Scalar;
use core::ops::{AddAssign, SubAssign};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// Index of the delay `tau` (seconds), right after the 16 navigation states.
pub const DELAY: usize = NAV_STATES;
/// Number of states of the augmented filter.
pub const AUGMENTED_STATES: usize = NAV_STATES + 1;

/// The 17-state vector `[x; tau]`.
pub type AugmentedStateVector<T> = SVector<T, AUGMENTED_STATES>;
/// The 17x17 covariance.
pub type AugmentedCovariance<T> = SMatrix<T, AUGMENTED_STATES, AUGMENTED_STATES>;
/// Jacobian of a 3-D measurement with respect to the 17 states.
pub type AugmentedJacobian<T> = SMatrix<T, 3, AUGMENTED_STATES>;

fn navigation_part<T: Scalar>(x: &AugmentedStateVector<T>) -> StateVector<T> {
    x.fixed_rows::<NAV_STATES>(0).into_owned()
}

/// The acceleration of the process model `a = R(q)(f~ - b_f) + [0, 0, g]`
/// (m/s², NED) for the specific force sample `accel` (m/s², body), with its
/// Jacobians `∂a/∂q` (3x4) and `∂a/∂b_f` (3x3).
pub fn navigation_acceleration<T: Scalar>(
    x: &AugmentedStateVector<T>,
    accel: &Vector3<T>,
    gravity: T,
) -> (Vector3<T>, SMatrix<T, 3, 4>, Matrix3<T>) {
    let q = quaternion_of(x);
    let rot = rotation_matrix(&q);
    let u = accel - x.fixed_rows::<3>(ACCEL_BIAS);
    let a = rot * u + Vector3::new(T::zero(), T::zero(), gravity);
    (a, rotation_jacobian(&q, &u), -rot)
}

/// The delayed antenna position `r - v tau + a tau²/2 + R(q) l_b` and its
/// Jacobian (see the module docs). `accel`: the current specific force
/// sample (m/s², body); `gravity`: m/s², positive.
pub fn delayed_gps_position<T: Scalar>(
    x: &AugmentedStateVector<T>,
    accel: &Vector3<T>,
    lever_arm: &Vector3<T>,
    gravity: T,
) -> (Vector3<T>, AugmentedJacobian<T>) {
    let tau = x[DELAY];
    let half_tau2 = tau * tau * T::lit(0.5);
    let v = x.fixed_rows::<3>(VEL).into_owned();
    let (a, da_dq, da_dbf) = navigation_acceleration(x, accel, gravity);
    let (h16, jac16) = gps_position(&navigation_part(x), lever_arm);
    let h = h16 - v * tau + a * half_tau2;
    let mut jac = NavCore::<T, AUGMENTED_STATES>::widen(&jac16);
    jac.fixed_view_mut::<3, 4>(0, QUAT)
        .add_assign(da_dq * half_tau2);
    jac.fixed_view_mut::<3, 3>(0, VEL)
        .sub_assign(Matrix3::identity() * tau);
    jac.fixed_view_mut::<3, 3>(0, ACCEL_BIAS)
        .add_assign(da_dbf * half_tau2);
    jac.fixed_view_mut::<3, 1>(0, DELAY)
        .copy_from(&(a * tau - v));
    (h, jac)
}

/// The delayed antenna velocity `v - a tau + R(q)((w~ - b_w) × l_b)` and
/// its Jacobian (see the module docs). `gyro` (rad/s) and `accel` (m/s²):
/// the current IMU sample, body.
pub fn delayed_gps_velocity<T: Scalar>(
    x: &AugmentedStateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    lever_arm: &Vector3<T>,
    gravity: T,
) -> (Vector3<T>, AugmentedJacobian<T>) {
    let tau = x[DELAY];
    let (a, da_dq, da_dbf) = navigation_acceleration(x, accel, gravity);
    let (h16, jac16) = gps_velocity(&navigation_part(x), gyro, lever_arm);
    let h = h16 - a * tau;
    let mut jac = NavCore::<T, AUGMENTED_STATES>::widen(&jac16);
    jac.fixed_view_mut::<3, 4>(0, QUAT).sub_assign(da_dq * tau);
    jac.fixed_view_mut::<3, 3>(0, ACCEL_BIAS)
        .sub_assign(da_dbf * tau);
    jac.fixed_view_mut::<3, 1>(0, DELAY).copy_from(&(-a));
    (h, jac)
}

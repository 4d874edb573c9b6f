//! Process model of the 16-state EKF: pure functions, no covariance, no
//! filter state. [`propagate`] is also the forward-reckoning step of the
//! delay-compensated navigator.
//!
//! # Continuous-time model (paper eq. 2)
//! With the measured rate `w` (rad/s, body) and specific force `f` (m/s²,
//! body), both held over the step:
//!
//! ```text
//! q' = 1/2 Ξ(q) (w - b_w)            = 1/2 q ⊗ [0, w - b_w]
//! r' = v                               (m/s, NED)
//! v' = R(q) (f - b_f) + [0, 0, g]      (m/s², NED; g > 0, down)
//! b_f' = 0,  b_w' = 0                  (random walks, in Q only)
//!
//!        | -q1 -q2 -q3 |
//! Ξ(q) = |  q0 -q3  q2 |     the 4x3 matrix of eq. (2), see [`xi`]
//!        |  q3  q0 -q1 |
//!        | -q2  q1  q0 |
//! ```
//!
//! `R(q)` is eq. (3) with the sign of its (3,1) entry corrected
//! ([`rotation_matrix`]). Earth rate and transport rate are neglected, as in
//! the paper.
//!
//! # Discrete propagation ([`propagate`])
//! The paper's eq. (4) is one Euler step `x += dt x'`. Here the attitude is
//! integrated with the exact rotation of the bias-corrected rate over the
//! step, and velocity and position with the specific force rotated at
//! mid-step (exact for a constant rate and specific force):
//!
//! ```text
//! q_{k+1} = q_k ⊗ exp((w - b_w) dt)                    (renormalized)
//! a       = R(q_k ⊗ exp((w - b_w) dt / 2)) (f - b_f) + [0, 0, g]
//! v_{k+1} = v_k + a dt
//! r_{k+1} = r_k + v_k dt + a dt² / 2
//! ```
//!
//! # Linearization and discretization
//! [`jacobian`] is `F = ∂x'/∂x` of the continuous model (16x16). Its non-zero blocks:
//!
//! ```text
//! ∂q'/∂q   = 1/2 Ω(w - b_w)      (q ⊗ [0, u] = Ω(u) q, see [`omega`])
//! ∂q'/∂b_w = -1/2 Ξ(q)
//! ∂r'/∂v   = I
//! ∂v'/∂q   = ∂(R(q) u)/∂q,  u = f - b_f     (see [`rotation_jacobian`])
//! ∂v'/∂b_f = -R(q)
//! ```
//!
//! [`transition`] discretizes it to second order, `A = I + F dt + (F dt)²/2`,
//! used in the covariance prediction of eq. (5), written here with the
//! transpose the paper's print lost: `P = A P A^T + Q`.
//!
//! # Process noise ([`noise_intensity`], [`discretize_noise`])
//! The gyro white noise `n_w` enters as `q' = 1/2 Ξ(q)(w - n_w - b_w)`, the
//! accelerometer's as `v' = R(q)(f - n_f - b_f) + g`, the biases drift as
//! random walks. With `G` the noise-input matrix (blocks `-1/2 Ξ(q)`,
//! `-R(q)`, `I`, `I`) and `Q_c = diag(σ_w², σ_f², σ_bf², σ_bw²)` the
//! densities squared, the continuous intensity is `Q' = G Q_c G^T` and
//!
//! ```text
//! Q = ∫_0^dt (I + F s) Q' (I + F s)^T ds
//!   = Q' dt + (F Q' + Q' F^T) dt²/2 + F Q' F^T dt³/3
//! ```
//!
//! which is positive semi-definite for any `dt` (an integral of PSD terms)
//! and carries velocity noise into position (`σ_f² dt³/3`).

use super::state::{
    ACCEL_BIAS, GYRO_BIAS, NAV_STATES, POS, QUAT, StateCovariance, StateVector, VEL, quaternion_of,
};
use crate::ekf16::config::Ekf16Config;
use crate::geo::{normalize_near_unit, quaternion_from_rotation_vector, rotation_matrix};
use crate::scalar::Scalar;
use nalgebra::{Matrix3, Matrix4, Quaternion, SMatrix, SVector, Vector3};

/// The 4x3 matrix `Ξ(q)` of eq. (2): `q ⊗ [0, u] = Ξ(q) u`.
pub fn xi<T: Scalar>(q: &Quaternion<T>) -> SMatrix<T, 4, 3> {
    let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
    SMatrix::<T, 4, 3>::new(-q1, -q2, -q3, q0, -q3, q2, q3, q0, -q1, -q2, q1, q0)
}

/// The 4x4 matrix `Ω(u)` with `q ⊗ [0, u] = Ω(u) q` (quaternions as `[q0 q1 q2 q3]`).
pub fn omega<T: Scalar>(u: &Vector3<T>) -> Matrix4<T> {
    let z = T::zero();
    Matrix4::new(
        z, -u.x, -u.y, -u.z, //
        u.x, z, u.z, -u.y, //
        u.y, -u.z, z, u.x, //
        u.z, u.y, -u.x, z,
    )
}

/// `∂(R(q) u)/∂q` (3x4) for a fixed body vector `u`, with `R(q)` the
/// homogeneous form of eq. (3) (`R(q) u = (q0² - |q_v|²) u + 2 (q_v·u) q_v + 2 q0 q_v × u`).
pub fn rotation_jacobian<T: Scalar>(q: &Quaternion<T>, u: &Vector3<T>) -> SMatrix<T, 3, 4> {
    let two = T::lit(2.0);
    let q0 = q.w;
    let qv = Vector3::new(q.i, q.j, q.k);
    let d_q0 = (u * q0 + qv.cross(u)) * two;
    let d_qv = (-u * qv.transpose() + Matrix3::identity() * qv.dot(u) + qv * u.transpose()
        - u.cross_matrix() * q0)
        * two;
    let mut j = SMatrix::<T, 3, 4>::zeros();
    j.fixed_columns_mut::<1>(0).copy_from(&d_q0);
    j.fixed_columns_mut::<3>(1).copy_from(&d_qv);
    j
}

/// The continuous-time model `x' = f(x, w, f)` of eq. (2).
///
/// `gyro` rad/s and `accel` m/s² in body FRD, `gravity` m/s² (positive).
pub fn derivative<T: Scalar>(
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    gravity: T,
) -> StateVector<T> {
    let q = quaternion_of(x);
    let w = gyro - x.fixed_rows::<3>(GYRO_BIAS);
    let f = accel - x.fixed_rows::<3>(ACCEL_BIAS);
    let mut d = StateVector::zeros();
    d.fixed_rows_mut::<4>(QUAT)
        .copy_from(&(xi(&q) * w * T::lit(0.5)));
    d.fixed_rows_mut::<3>(POS)
        .copy_from(&x.fixed_rows::<3>(VEL));
    let a = rotation_matrix(&q) * f + Vector3::new(T::zero(), T::zero(), gravity);
    d.fixed_rows_mut::<3>(VEL).copy_from(&a);
    d
}

/// `F = ∂f/∂x` (16x16) of the continuous model ([`derivative`]).
pub fn jacobian<T: Scalar>(
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
) -> StateCovariance<T> {
    let half = T::lit(0.5);
    let q = quaternion_of(x);
    let w = gyro - x.fixed_rows::<3>(GYRO_BIAS);
    let f = accel - x.fixed_rows::<3>(ACCEL_BIAS);
    let mut jac = StateCovariance::zeros();
    jac.fixed_view_mut::<4, 4>(QUAT, QUAT)
        .copy_from(&(omega(&w) * half));
    jac.fixed_view_mut::<4, 3>(QUAT, GYRO_BIAS)
        .copy_from(&(xi(&q) * (-half)));
    jac.fixed_view_mut::<3, 3>(POS, VEL).fill_with_identity();
    jac.fixed_view_mut::<3, 4>(VEL, QUAT)
        .copy_from(&rotation_jacobian(&q, &f));
    jac.fixed_view_mut::<3, 3>(VEL, ACCEL_BIAS)
        .copy_from(&(-rotation_matrix(&q)));
    jac
}

/// One step of the process model over `dt` seconds with the rate `gyro` and
/// specific force `accel` held over the step (see the module docs for the
/// scheme). The quaternion of `x` need not be unit; the result's is.
pub fn propagate<T: Scalar>(
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    dt: T,
    gravity: T,
) -> StateVector<T> {
    let q = normalize_near_unit(quaternion_of(x));
    let w = gyro - x.fixed_rows::<3>(GYRO_BIAS);
    let f = accel - x.fixed_rows::<3>(ACCEL_BIAS);
    let q_mid = q * quaternion_from_rotation_vector(&(w * (dt * T::lit(0.5))));
    let a = q_mid * f + Vector3::new(T::zero(), T::zero(), gravity);
    let q_next = normalize_near_unit((q * quaternion_from_rotation_vector(&(w * dt))).into_inner());
    let v = x.fixed_rows::<3>(VEL).into_owned();
    let mut out = *x;
    let qn = q_next.quaternion();
    out.fixed_rows_mut::<4>(QUAT)
        .copy_from(&nalgebra::Vector4::new(qn.w, qn.i, qn.j, qn.k));
    out.fixed_rows_mut::<3>(POS)
        .copy_from(&(x.fixed_rows::<3>(POS) + v * dt + a * (dt * dt * T::lit(0.5))));
    out.fixed_rows_mut::<3>(VEL).copy_from(&(v + a * dt));
    out
}

/// `A = I + F dt + (F dt)² / 2`, the second-order discretization of `F`.
pub fn transition<T: Scalar, const N: usize>(f: &SMatrix<T, N, N>, dt: T) -> SMatrix<T, N, N> {
    let fdt = f * dt;
    SMatrix::<T, N, N>::identity() + fdt + fdt * fdt * T::lit(0.5)
}

/// Continuous noise intensity `Q' = G Q_c G^T` (16x16) of the navigation
/// states at the attitude of `x` (see the module docs).
pub fn noise_intensity<T: Scalar>(
    x: &StateVector<T>,
    config: &Ekf16Config<T>,
) -> StateCovariance<T> {
    let q = quaternion_of(x);
    let sw2 = config.gyro_noise_density * config.gyro_noise_density;
    let sf2 = config.accel_noise_density * config.accel_noise_density;
    let g_q = xi(&q) * T::lit(0.5);
    let r = rotation_matrix(&q);
    let mut qc = StateCovariance::zeros();
    qc.fixed_view_mut::<4, 4>(QUAT, QUAT)
        .copy_from(&(g_q * g_q.transpose() * sw2));
    qc.fixed_view_mut::<3, 3>(VEL, VEL)
        .copy_from(&(r * r.transpose() * sf2));
    let bf2 = config.accel_bias_random_walk * config.accel_bias_random_walk;
    let bw2 = config.gyro_bias_random_walk * config.gyro_bias_random_walk;
    for i in 0..3 {
        qc[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = bf2;
        qc[(GYRO_BIAS + i, GYRO_BIAS + i)] = bw2;
    }
    debug_assert_eq!(GYRO_BIAS + 3, NAV_STATES);
    qc
}

/// `Q = Q' dt + (F Q' + Q' F^T) dt²/2 + F Q' F^T dt³/3`, the covariance of
/// the process noise accumulated over `dt` seconds (see the module docs).
pub fn discretize_noise<T: Scalar, const N: usize>(
    f: &SMatrix<T, N, N>,
    intensity: &SMatrix<T, N, N>,
    dt: T,
) -> SMatrix<T, N, N> {
    let fq = f * intensity;
    let dt2 = dt * dt;
    let mut q = intensity * dt
        + (fq + fq.transpose()) * (dt2 * T::lit(0.5))
        + fq * f.transpose() * (dt2 * dt / T::lit(3.0));
    crate::kalman::symmetrize(&mut q);
    q
}

/// The Jacobian's non-zero blocks at one state and input (see the module
/// docs): everything the structured prediction needs.
#[derive(Debug, Clone, Copy, PartialEq)]
struct JacobianBlocks<T: Scalar> {
    /// `∂q'/∂q = 1/2 Ω(w - b_w)`.
    qq: Matrix4<T>,
    /// `∂q'/∂b_w = -1/2 Ξ(q)`.
    q_bw: SMatrix<T, 4, 3>,
    /// `∂v'/∂q = ∂(R(q) u)/∂q`, `u = f - b_f`.
    v_q: SMatrix<T, 3, 4>,
    /// `R(q)` (`∂v'/∂b_f = -R(q)`).
    rot: Matrix3<T>,
}

impl<T: Scalar> JacobianBlocks<T> {
    fn new(x: &StateVector<T>, gyro: &Vector3<T>, accel: &Vector3<T>) -> Self {
        let half = T::lit(0.5);
        let q = quaternion_of(x);
        let w = gyro - x.fixed_rows::<3>(GYRO_BIAS);
        let f = accel - x.fixed_rows::<3>(ACCEL_BIAS);
        Self {
            qq: omega(&w) * half,
            q_bw: xi(&q) * (-half),
            v_q: rotation_jacobian(&q, &f),
            rot: rotation_matrix(&q),
        }
    }
}

/// Writes `block` (`R x C`, at rows `i0..`, columns `j0..`) into the
/// symmetric `p` together with its mirror image `p[J, I] = p[I, J]^T`,
/// adding to what is there (`accumulate`) or replacing it. A diagonal block
/// (`i0 == j0`, `R == C`) contributes its lower triangle only, mirrored, so
/// `p` stays exactly symmetric whatever rounding `block` carries.
fn put_symmetric_block<T: Scalar, const N: usize, const R: usize, const C: usize>(
    p: &mut SMatrix<T, N, N>,
    i0: usize,
    j0: usize,
    block: &SMatrix<T, R, C>,
    accumulate: bool,
) {
    for c in 0..C {
        for r in 0..R {
            let (i, j) = (i0 + r, j0 + c);
            if i0 == j0 && j > i {
                continue;
            }
            let v = if accumulate {
                p[(i, j)] + block[(r, c)]
            } else {
                block[(r, c)]
            };
            p[(i, j)] = v;
            p[(j, i)] = v;
        }
    }
}

/// Adds the process noise `Q` of a step of `dt` seconds to the symmetric
/// `N x N` covariance `p`, block by block: the same matrix as
/// [`discretize_noise`] of [`jacobian`] and [`noise_intensity`] (padded with
/// zeros beyond the 16 navigation states), plus `extra_intensity[i] dt` on
/// the diagonal of each state `i >= 16` (entries below 16 are ignored).
/// See `docs/math.md` ("Structured covariance prediction") for the blocks.
/// `p` stays exactly symmetric.
pub fn add_process_noise<T: Scalar, const N: usize>(
    p: &mut SMatrix<T, N, N>,
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    dt: T,
    config: &Ekf16Config<T>,
    extra_intensity: &SVector<T, N>,
) {
    let jac = JacobianBlocks::new(x, gyro, accel);
    add_noise_blocks(p, &jac, x, dt, config, extra_intensity, T::one());
}

/// The blocks of [`add_process_noise`]; the white-noise intensities (gyro, accelerometer)
/// multiplied by `white_scale` (at least 1: the densities are those of the configured IMU
/// rate, and a stream read more sparsely keeps its per-sample variance, so its density is
/// that many times larger; see `src/nav/horizon.rs`).
fn add_noise_blocks<T: Scalar, const N: usize>(
    p: &mut SMatrix<T, N, N>,
    jac: &JacobianBlocks<T>,
    x: &StateVector<T>,
    dt: T,
    config: &Ekf16Config<T>,
    extra_intensity: &SVector<T, N>,
    white_scale: T,
) {
    let q = quaternion_of(x);
    let white_scale = white_scale.max(T::one());
    let sw2 = config.gyro_noise_density * config.gyro_noise_density * white_scale;
    let sf2 = config.accel_noise_density * config.accel_noise_density * white_scale;
    let bf2 = config.accel_bias_random_walk * config.accel_bias_random_walk;
    let bw2 = config.gyro_bias_random_walk * config.gyro_bias_random_walk;
    let (d1, d2, d3) = (dt, dt * dt * T::lit(0.5), dt * dt * dt / T::lit(3.0));
    // Continuous intensities: W_q = 1/4 Ξ Ξ^T σ_w², W_v = R R^T σ_f².
    let g_q = xi(&q) * T::lit(0.5);
    let w_q = g_q * g_q.transpose() * sw2;
    let w_v = jac.rot * jac.rot.transpose() * sf2;
    let fqq_wq = jac.qq * w_q;
    let q_qq = w_q * d1
        + (fqq_wq + fqq_wq.transpose()) * d2
        + (fqq_wq * jac.qq.transpose() + jac.q_bw * jac.q_bw.transpose() * bw2) * d3;
    put_symmetric_block(p, QUAT, QUAT, &q_qq, true);
    let wq_jt = w_q * jac.v_q.transpose();
    put_symmetric_block(p, QUAT, VEL, &(wq_jt * d2 + jac.qq * wq_jt * d3), true);
    put_symmetric_block(p, QUAT, GYRO_BIAS, &(jac.q_bw * (bw2 * d2)), true);
    put_symmetric_block(p, POS, POS, &(w_v * d3), true);
    put_symmetric_block(p, POS, VEL, &(w_v * d2), true);
    let q_vv =
        w_v * d1 + (jac.v_q * w_q * jac.v_q.transpose() + jac.rot * jac.rot.transpose() * bf2) * d3;
    put_symmetric_block(p, VEL, VEL, &q_vv, true);
    put_symmetric_block(p, VEL, ACCEL_BIAS, &(jac.rot * (-bf2 * d2)), true);
    for i in 0..3 {
        p[(ACCEL_BIAS + i, ACCEL_BIAS + i)] += bf2 * d1;
        p[(GYRO_BIAS + i, GYRO_BIAS + i)] += bw2 * d1;
    }
    for i in NAV_STATES..N {
        p[(i, i)] += extra_intensity[i] * d1;
    }
}

/// The blocks of `A = I + F dt + (F dt)²/2` besides the identity; every
/// other block of `F²` is zero (see `docs/math.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct TransitionBlocks<T: Scalar> {
    dt: T,
    qq: Matrix4<T>,
    q_bw: SMatrix<T, 4, 3>,
    r_q: SMatrix<T, 3, 4>,
    r_bf: Matrix3<T>,
    v_q: SMatrix<T, 3, 4>,
    v_bf: Matrix3<T>,
    v_bw: Matrix3<T>,
}

impl<T: Scalar> TransitionBlocks<T> {
    fn new(jac: &JacobianBlocks<T>, dt: T) -> Self {
        let dt2 = dt * dt * T::lit(0.5);
        Self {
            dt,
            qq: Matrix4::identity() + jac.qq * dt + jac.qq * jac.qq * dt2,
            q_bw: jac.q_bw * dt + jac.qq * jac.q_bw * dt2,
            r_q: jac.v_q * dt2,
            r_bf: jac.rot * (-dt2),
            v_q: jac.v_q * dt + jac.v_q * jac.qq * dt2,
            v_bf: jac.rot * (-dt),
            v_bw: jac.v_q * jac.q_bw * dt2,
        }
    }

    /// Rows q of `M = A P`: `A_qq P_q + A_qbw P_bw` (`P_s` the rows of
    /// state block `s`), entry by entry without temporaries.
    #[inline(never)]
    fn rows_q<const N: usize>(&self, p: &SMatrix<T, N, N>) -> SMatrix<T, 4, N> {
        SMatrix::from_fn(|r, j| {
            block_product(&self.qq, p, QUAT, r, j) + block_product(&self.q_bw, p, GYRO_BIAS, r, j)
        })
    }

    /// Rows r of `M = A P`: `P_r + P_v dt + A_rq P_q + A_rbf P_bf`.
    #[inline(never)]
    fn rows_r<const N: usize>(&self, p: &SMatrix<T, N, N>) -> SMatrix<T, 3, N> {
        SMatrix::from_fn(|r, j| {
            p[(POS + r, j)]
                + p[(VEL + r, j)] * self.dt
                + block_product(&self.r_q, p, QUAT, r, j)
                + block_product(&self.r_bf, p, ACCEL_BIAS, r, j)
        })
    }

    /// Rows v of `M = A P`: `P_v + A_vq P_q + A_vbf P_bf + A_vbw P_bw`.
    #[inline(never)]
    fn rows_v<const N: usize>(&self, p: &SMatrix<T, N, N>) -> SMatrix<T, 3, N> {
        SMatrix::from_fn(|r, j| {
            p[(VEL + r, j)]
                + block_product(&self.v_q, p, QUAT, r, j)
                + block_product(&self.v_bf, p, ACCEL_BIAS, r, j)
                + block_product(&self.v_bw, p, GYRO_BIAS, r, j)
        })
    }

    /// `(M A^T)[:, q]` for a block row `m` of `M = A P`.
    fn col_q<const R: usize, const N: usize>(&self, m: &SMatrix<T, R, N>) -> SMatrix<T, R, 4> {
        m.fixed_columns::<4>(QUAT) * self.qq.transpose()
            + m.fixed_columns::<3>(GYRO_BIAS) * self.q_bw.transpose()
    }

    /// `(M A^T)[:, r]`.
    fn col_r<const R: usize, const N: usize>(&self, m: &SMatrix<T, R, N>) -> SMatrix<T, R, 3> {
        m.fixed_columns::<3>(POS)
            + m.fixed_columns::<3>(VEL) * self.dt
            + m.fixed_columns::<4>(QUAT) * self.r_q.transpose()
            + m.fixed_columns::<3>(ACCEL_BIAS) * self.r_bf.transpose()
    }

    /// `(M A^T)[:, v]`.
    fn col_v<const R: usize, const N: usize>(&self, m: &SMatrix<T, R, N>) -> SMatrix<T, R, 3> {
        m.fixed_columns::<3>(VEL)
            + m.fixed_columns::<4>(QUAT) * self.v_q.transpose()
            + m.fixed_columns::<3>(ACCEL_BIAS) * self.v_bf.transpose()
            + m.fixed_columns::<3>(GYRO_BIAS) * self.v_bw.transpose()
    }
}

/// Entry `(r, j)` of `a P[i0..i0 + K, :]`, summed in the order of
/// nalgebra's product of fixed-size matrices (`k = 0` first, each term
/// added to the sum so far): the same bits as the product, without its
/// `R x N` temporary.
#[inline(always)]
fn block_product<T: Scalar, const R: usize, const K: usize, const N: usize>(
    a: &SMatrix<T, R, K>,
    p: &SMatrix<T, N, N>,
    i0: usize,
    r: usize,
    j: usize,
) -> T {
    let mut sum = a[(r, 0)] * p[(i0, j)];
    for k in 1..K {
        sum = a[(r, k)] * p[(i0 + k, j)] + sum;
    }
    sum
}

/// Writes the block row `m` (`R x N`, rows `i0..i0 + R`) of `A P` against
/// the states `A` leaves alone (`b_f`, `b_w`, extras: columns `10..N`) into
/// `out`, mirrored.
fn set_against_unchanged<T: Scalar, const N: usize, const R: usize>(
    out: &mut SMatrix<T, N, N>,
    i0: usize,
    m: &SMatrix<T, R, N>,
) {
    for j in ACCEL_BIAS..N {
        for r in 0..R {
            out[(i0 + r, j)] = m[(r, j)];
            out[(j, i0 + r)] = m[(r, j)];
        }
    }
}

/// The covariance prediction `A P A^T + Q` of one step, computed from the
/// blocks of the Jacobian instead of dense `N x N` products; equal (up to
/// rounding) to `transition(F) P transition(F)^T + discretize_noise(F, Q', dt)`
/// with `F` = [`jacobian`] and `Q'` = [`noise_intensity`] padded with zeros
/// for the states beyond the 16 navigation ones, whose intensities are
/// `extra_intensity[16..]` (random walks; entries below 16 are ignored).
///
/// `p` must be symmetric; the result is exactly symmetric (one triangle is
/// computed, then mirrored). The blocks and the operation count:
/// `docs/math.md`, "Structured covariance prediction".
pub fn predict_covariance<T: Scalar, const N: usize>(
    p: &SMatrix<T, N, N>,
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    dt: T,
    config: &Ekf16Config<T>,
    extra_intensity: &SVector<T, N>,
) -> SMatrix<T, N, N> {
    let mut out = *p;
    predict_covariance_in_place(
        &mut out,
        x,
        gyro,
        accel,
        dt,
        config,
        extra_intensity,
        T::one(),
    );
    out
}

/// [`predict_covariance`] written over `p` (the same numbers, no copy of
/// `P`): the block rows of `A P` are computed from `p` before any of it
/// changes. Not inlined, and the block rows in functions of their own, so
/// that their temporaries share no frame with the caller's (the push stack
/// of a firmware; `docs/PERFORMANCE.md`). The white-noise intensities are multiplied by
/// `white_scale` (at least 1; [`add_noise_blocks`]).
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn predict_covariance_in_place<T: Scalar, const N: usize>(
    p: &mut SMatrix<T, N, N>,
    x: &StateVector<T>,
    gyro: &Vector3<T>,
    accel: &Vector3<T>,
    dt: T,
    config: &Ekf16Config<T>,
    extra_intensity: &SVector<T, N>,
    white_scale: T,
) {
    const { assert!(N >= NAV_STATES) };
    let jac = JacobianBlocks::new(x, gyro, accel);
    let a = TransitionBlocks::new(&jac, dt);
    // M = A P on the ten rows A changes (q, r, v); the other rows of A P are P's.
    let m_q = a.rows_q(p);
    let m_r = a.rows_r(p);
    let m_v = a.rows_v(p);
    // A P A^T: the unchanged states among themselves keep P; against the
    // changed ones it is M; among the changed ones M A^T, lower block
    // triangle computed and mirrored.
    set_against_unchanged(p, QUAT, &m_q);
    set_against_unchanged(p, POS, &m_r);
    set_against_unchanged(p, VEL, &m_v);
    put_symmetric_block(p, QUAT, QUAT, &a.col_q(&m_q), false);
    put_symmetric_block(p, POS, QUAT, &a.col_q(&m_r), false);
    put_symmetric_block(p, POS, POS, &a.col_r(&m_r), false);
    put_symmetric_block(p, VEL, QUAT, &a.col_q(&m_v), false);
    put_symmetric_block(p, VEL, POS, &a.col_r(&m_v), false);
    put_symmetric_block(p, VEL, VEL, &a.col_v(&m_v), false);
    add_noise_blocks(p, &jac, x, dt, config, extra_intensity, white_scale);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `A P` on the rows of q, r and v as nalgebra's products compute it
    /// (the code the entry-by-entry block rows replaced for the push stack).
    fn rows_by_products<T: Scalar, const N: usize>(
        a: &TransitionBlocks<T>,
        p: &SMatrix<T, N, N>,
    ) -> (SMatrix<T, 4, N>, SMatrix<T, 3, N>, SMatrix<T, 3, N>) {
        let p_q = p.fixed_rows::<4>(QUAT);
        let p_v = p.fixed_rows::<3>(VEL);
        let p_bf = p.fixed_rows::<3>(ACCEL_BIAS);
        let p_bw = p.fixed_rows::<3>(GYRO_BIAS);
        (
            a.qq * p_q + a.q_bw * p_bw,
            p.fixed_rows::<3>(POS) + p_v * a.dt + a.r_q * p_q + a.r_bf * p_bf,
            p_v + a.v_q * p_q + a.v_bf * p_bf + a.v_bw * p_bw,
        )
    }

    /// A deterministic pseudo-random number in `[-1, 1)` (xorshift64*).
    fn next(state: &mut u64) -> f64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        let bits = state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
        2.0 * (bits as f64 / (1u64 << 53) as f64) - 1.0
    }

    /// The block rows computed entry by entry are the products' bits, and
    /// the covariance predicted in place is the returned one's.
    fn block_rows_are_the_products_bits<T: Scalar, const N: usize>(seed: u64) {
        let mut s = seed;
        for _ in 0..50 {
            let mut x = StateVector::<T>::from_fn(|_, _| T::lit(next(&mut s)));
            let q = x.fixed_rows::<4>(QUAT).normalize();
            x.fixed_rows_mut::<4>(QUAT).copy_from(&q);
            let gyro = Vector3::from_fn(|_, _| T::lit(next(&mut s)));
            let accel = Vector3::from_fn(|_, _| T::lit(10.0 * next(&mut s)));
            let l = SMatrix::<T, N, N>::from_fn(|_, _| T::lit(next(&mut s)));
            let p = l * l.transpose();
            let p = (p + p.transpose()) * T::lit(0.5);
            let dt = T::lit(0.001 + 0.01 * next(&mut s).abs());
            let a = TransitionBlocks::new(&JacobianBlocks::new(&x, &gyro, &accel), dt);
            let (m_q, m_r, m_v) = rows_by_products(&a, &p);
            assert_eq!(a.rows_q(&p), m_q);
            assert_eq!(a.rows_r(&p), m_r);
            assert_eq!(a.rows_v(&p), m_v);
            let config = Ekf16Config::<T>::default();
            let extra = SVector::<T, N>::from_fn(|_, _| T::lit(next(&mut s).abs()));
            let out = predict_covariance(&p, &x, &gyro, &accel, dt, &config, &extra);
            let mut in_place = p;
            predict_covariance_in_place(
                &mut in_place,
                &x,
                &gyro,
                &accel,
                dt,
                &config,
                &extra,
                T::one(),
            );
            assert_eq!(out, in_place);
        }
    }

    fn block_rows_16<T: Scalar>() {
        block_rows_are_the_products_bits::<T, 16>(0x9e37_79b9_7f4a_7c15);
    }

    fn block_rows_17<T: Scalar>() {
        block_rows_are_the_products_bits::<T, 17>(0x2545_f491_4f6c_dd1d);
    }

    tests_in_both_precisions!(block_rows_16, block_rows_17);
}

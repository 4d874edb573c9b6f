//! Kalman measurement-update algebra shared by every filter of the crate.
//!
//! One function, [`joseph_update`], fuses an `M`-dimensional measurement block
//! into an `N`-state filter. It is the correction step of the paper's
//! eqs. (9)-(10), with eq. (9)'s slip fixed (the paper writes `H^T P H^T`; the
//! innovation covariance is `H P H^T + R`):
//!
//! ```text
//! S   = H P H^T + R                      innovation covariance (M x M)
//! S   = L L^T                            Cholesky; failure -> Error::NotPositiveDefinite
//! NIS = y^T S^-1 y                       normalized innovation squared
//! test_ratio = NIS / gate                gate: chi-square threshold with M degrees of freedom
//! K   = P H^T S^-1                       gain (N x M)
//! x  += K y                              eq. (10)
//! P   = (I - K H) P (I - K H)^T + K R K^T    Joseph form, one triangle, mirrored
//! ```
//!
//! The Joseph form keeps `P` symmetric positive semi-definite under rounding
//! and for any gain, unlike the short form `(I - K H) P`.
//!
//! ## Cost: H is sparse
//! A GPS block's `H` selects position or velocity and touches a few
//! attitude, bias and delay columns; the magnetometer's touches the
//! quaternion only. Every product with `H` runs over its non-zero columns
//! (found at run time), and the Joseph form is evaluated in factored order
//! without `I - K H` (see `joseph_covariance`): `P H^T` costs `N s M`
//! multiply-adds for `s` non-zero columns, the Joseph form `~1.5 N² M + N s M`,
//! against `~2 N³` for the dense products. Why the Joseph form and not the
//! cheaper `P - K S K^T`: `docs/math.md`, "Sparse measurement update".
//!
//! ## Gating ("should I fuse" apart from "fuse it")
//! The measurement is used only when `test_ratio <= 1`. Under the filter's
//! own model `NIS` is chi-square distributed with `M` degrees of freedom, so
//! the gate is a chi-square quantile. [`GATE_5_SIGMA_3DOF`] (31.81) has the
//! same tail probability as a two-sided 5-sigma Gaussian test,
//! `5.73e-7`: a healthy filter rejects about one good 3-D measurement in two
//! million. A rejected measurement leaves `x` and `P` exactly as they were
//! and still yields a [`FusionRecord`] (with `fused = false`).
//!
//! Everything is computed into temporaries and committed only when the
//! measurement is accepted and the new `x` and `P` are finite.

use crate::error::Error;
use crate::estimate::FusionRecord;
use crate::scalar::{Scalar, all_finite_fixed};
use nalgebra::{SMatrix, SVector};

/// Chi-square threshold for 3 degrees of freedom with the tail probability of
/// a two-sided 5-sigma Gaussian test (`P(NIS > 31.81) = 5.73e-7`).
pub const GATE_5_SIGMA_3DOF: f64 = 31.812;

/// Chi-square threshold for 1 degree of freedom with the tail probability of
/// a two-sided 5-sigma Gaussian test (`5^2`).
pub const GATE_5_SIGMA_1DOF: f64 = 25.0;

/// Replaces `P` by `(P + P^T) / 2`.
pub fn symmetrize<T: Scalar, const N: usize>(p: &mut SMatrix<T, N, N>) {
    let half = T::lit(0.5);
    for i in 0..N {
        for j in (i + 1)..N {
            let m = (p[(i, j)] + p[(j, i)]) * half;
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
}

/// Fuses one measurement block into the state `x` and covariance `p`.
///
/// - `innovation`: `y = z - h(x)` (the caller computes it: angles wrap, a
///   model may be nonlinear);
/// - `h`: the measurement Jacobian `H = dh/dx` (`M x N`);
/// - `r`: measurement noise covariance (`M x M`, symmetric positive definite);
/// - `gate`: chi-square threshold on the NIS (`+inf` disables gating);
/// - `t_us`, `measurement`: stamped into the record and the error.
///
/// Returns the [`FusionRecord`]; `fused` tells whether `x` and `p` changed.
/// `Err(Error::NotPositiveDefinite)` when `S` has no Cholesky factor; then
/// nothing changed. A result with non-finite entries is not committed and is
/// reported as rejected (`fused = false`, `test_ratio = inf`).
#[allow(clippy::too_many_arguments)]
pub fn joseph_update<T: Scalar, const N: usize, const M: usize>(
    x: &mut SVector<T, N>,
    p: &mut SMatrix<T, N, N>,
    innovation: &SVector<T, M>,
    h: &SMatrix<T, M, N>,
    r: &SMatrix<T, M, M>,
    gate: T,
    t_us: u64,
    measurement: &'static str,
) -> Result<FusionRecord<T, M>, Error> {
    joseph_update_restricted(x, p, innovation, h, r, gate, t_us, measurement, None)
}

/// [`joseph_update`] with the gain restricted to `K' = C K` by a matrix `C`
/// (`N x N`, `None`: no restriction), a "consider" (Schmidt) update.
///
/// `C` keeps the part of the correction a measurement may make; the
/// directions it removes are not corrected but their uncertainty still
/// enters `S` and, through `H`, the correlations that shape the gain. The
/// Joseph form `(I - K'H) P (I - K'H)^T + K' R K'^T` is the exact
/// covariance of the update for any gain, so `P` stays consistent: the
/// states left alone keep their variance instead of shrinking.
#[allow(clippy::too_many_arguments)]
pub fn joseph_update_restricted<T: Scalar, const N: usize, const M: usize>(
    x: &mut SVector<T, N>,
    p: &mut SMatrix<T, N, N>,
    innovation: &SVector<T, M>,
    h: &SMatrix<T, M, N>,
    r: &SMatrix<T, M, M>,
    gate: T,
    t_us: u64,
    measurement: &'static str,
    gain_restriction: Option<&SMatrix<T, N, N>>,
) -> Result<FusionRecord<T, M>, Error> {
    // H's non-zero columns: GPS rows select a few states, the magnetometer
    // row only the quaternion. Products with H run over these columns only.
    // A mask over `0..N`, not a list of indices: every index then comes
    // from a `0..N` loop, so no bounds check on it can fail (a link-time
    // check proves the push API panic-free: benches/no-panic).
    let mut support = [false; N];
    for (c, used) in support.iter_mut().enumerate() {
        *used = (0..M).any(|m| h[(m, c)] != T::zero());
    }
    // U = P H^T (N x M), from the columns of P in the support.
    let mut pht = SMatrix::<T, N, M>::zeros();
    for c in columns(&support) {
        for m in 0..M {
            pht.column_mut(m).axpy(h[(m, c)], &p.column(c), T::one());
        }
    }
    let mut s = *r;
    for c in columns(&support) {
        for m2 in 0..M {
            for m1 in 0..M {
                s[(m1, m2)] += h[(m1, c)] * pht[(c, m2)];
            }
        }
    }
    symmetrize(&mut s);
    let chol = s
        .cholesky()
        .ok_or(Error::NotPositiveDefinite { measurement })?;
    let nis = innovation.dot(&chol.solve(innovation));
    let ratio = if nis.is_finite() {
        nis / gate
    } else {
        T::lit(f64::INFINITY)
    };
    let mut record = FusionRecord {
        t_us,
        innovation: *innovation,
        innovation_variance: s.diagonal(),
        test_ratio: ratio,
        fused: false,
    };
    // `!(a <= b)` also rejects a NaN ratio.
    if !(nis.is_finite() && ratio <= T::one()) {
        return Ok(record);
    }
    // K = P H^T S^-1  <=>  S K^T = H P (S symmetric).
    let mut k: SMatrix<T, N, M> = chol.solve(&pht.transpose()).transpose();
    if let Some(c) = gain_restriction {
        k = c * k;
    }
    let x_new = *x + k * innovation;
    let p_new = joseph_covariance(p, h, r, &k, &pht, &support);
    if !(all_finite_fixed(&x_new) && all_finite_fixed(&p_new)) {
        record.test_ratio = T::lit(f64::INFINITY);
        return Ok(record);
    }
    *x = x_new;
    *p = p_new;
    record.fused = true;
    Ok(record)
}

/// The Joseph form `L P L^T + K R K^T`, `L = I - K H`, for any gain `K`,
/// without forming `L` or any dense `N x N` product with it (see the module
/// docs): with `U = P H^T` (`P` symmetric, so `H P = U^T`)
///
/// ```text
/// L P       = P - K U^T                         (N² M)
/// L P L^T   = L P - (L P H^T) K^T                (H's non-zero columns only)
/// P'        = L P + (K R - L P H^T) K^T          (one triangle, mirrored)
/// ```
///
/// `support[c]` tells whether column `c` of `H` is not zero. The result is
/// exactly symmetric.
fn joseph_covariance<T: Scalar, const N: usize, const M: usize>(
    p: &SMatrix<T, N, N>,
    h: &SMatrix<T, M, N>,
    r: &SMatrix<T, M, M>,
    k: &SMatrix<T, N, M>,
    pht: &SMatrix<T, N, M>,
    support: &[bool; N],
) -> SMatrix<T, N, N> {
    let mut lp = *p;
    lp.gemm(-T::one(), k, &pht.transpose(), T::one());
    // Z = K R - L P H^T.
    let mut z: SMatrix<T, N, M> = k * r;
    for c in columns(support) {
        for m in 0..M {
            z.column_mut(m).axpy(-h[(m, c)], &lp.column(c), T::one());
        }
    }
    // The lower triangle in place, column `j` from row `j` down, then
    // mirrored. Iterators, not run-time indices: after unrolling, the
    // optimiser could not prove `lp[(i, j)]` in bounds for `j <= i < N`, and
    // the push API must have no reachable panic (benches/no-panic).
    for (j, (mut column, k_row)) in lp.column_iter_mut().zip(k.row_iter()).enumerate() {
        for (entry, z_row) in column.iter_mut().zip(z.row_iter()).skip(j) {
            for m in 0..M {
                *entry += z_row[m] * k_row[m];
            }
        }
    }
    lp.fill_upper_triangle_with_lower_triangle();
    lp
}

/// The indices `c < N` with `support[c]` set, in increasing order.
fn columns<const N: usize>(support: &[bool; N]) -> impl Iterator<Item = usize> + '_ {
    (0..N).filter(|&c| support[c])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    /// Three states, a 1-D measurement of `x0 + x1`, state 1 correlated with 2.
    fn restricted_update_leaves_the_excluded_state_and_its_variance<T: Scalar>(tol: f64) {
        let p0 = Matrix3::new(
            T::lit(2.0),
            T::lit(0.3),
            T::zero(),
            T::lit(0.3),
            T::lit(1.0),
            T::lit(0.5),
            T::zero(),
            T::lit(0.5),
            T::lit(1.5),
        );
        let h = SMatrix::<T, 1, 3>::new(T::one(), T::one(), T::zero());
        let r = SMatrix::<T, 1, 1>::new(T::lit(0.4));
        let y = SVector::<T, 1>::new(T::lit(0.7));
        let run = |c: Option<&Matrix3<T>>| {
            let (mut x, mut p) = (Vector3::<T>::zeros(), p0);
            let rec = joseph_update_restricted(&mut x, &mut p, &y, &h, &r, T::lit(1e9), 0, "t", c)
                .unwrap();
            assert!(rec.fused);
            (x, p)
        };
        // No restriction and the identity are the plain update.
        let (x_plain, p_plain) = run(None);
        let (x_id, p_id) = run(Some(&Matrix3::identity()));
        let (mut x_ref, mut p_ref) = (Vector3::<T>::zeros(), p0);
        joseph_update(&mut x_ref, &mut p_ref, &y, &h, &r, T::lit(1e9), 0, "t").unwrap();
        assert_eq!((x_plain, p_plain), (x_ref, p_ref));
        assert!((x_id - x_plain).amax().as_f64() < tol && (p_id - p_plain).amax().as_f64() < tol);
        // Excluding state 1: it keeps its value and variance, the others
        // still move, and the covariance is that of the applied gain.
        let keep = Matrix3::from_diagonal(&Vector3::new(T::one(), T::zero(), T::one()));
        let (x, p) = run(Some(&keep));
        assert_eq!(x[1], T::zero());
        assert!((p[(1, 1)] - p0[(1, 1)]).abs().as_f64() < tol);
        assert!(x[0] != T::zero() && x[2] != T::zero());
        let s = (h * p0 * h.transpose())[(0, 0)] + r[(0, 0)];
        let k = keep * p0 * h.transpose() / s;
        let i_kh = Matrix3::identity() - k * h;
        let expected = i_kh * p0 * i_kh.transpose() + k * r * k.transpose();
        assert!((p - expected).amax().as_f64() < tol);
        // The restricted update is less informative than the optimal one.
        assert!(p[(0, 0)] >= p_plain[(0, 0)] && p[(2, 2)] >= p_plain[(2, 2)]);
    }

    #[test]
    fn restricted_update_f64() {
        restricted_update_leaves_the_excluded_state_and_its_variance::<f64>(1e-12);
    }

    #[test]
    fn restricted_update_f32() {
        restricted_update_leaves_the_excluded_state_and_its_variance::<f32>(1e-5);
    }
}

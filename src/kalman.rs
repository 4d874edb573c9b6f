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
//! ## Cost: H is sparse, P is updated in place
//! A GPS block's `H` selects position or velocity and touches a few
//! attitude, bias and delay columns; the magnetometer's touches the
//! quaternion only. Every product with `H` runs over its non-zero columns
//! (found at run time), and the Joseph form is evaluated in factored order
//! without `I - K H`, on the lower triangle of `P` only and in place (see
//! `joseph_in_place`): `P H^T` costs `N s M` multiply-adds for `s` non-zero
//! columns, the Joseph form `N(N+1)/2 * 2M + 2 N s M + N M²`, against
//! `~2 N³` for the dense products (for a GPS block of `Ekf16`, `N = 16`,
//! `M = 3`, `s = 3`: about 1,600 in all, against 10,700). No copy of `P` is
//! made. A gain restriction `C`
//! costs one multiply-add per non-zero entry of `C` and column of `K`.
//! Why the Joseph form and not the cheaper `P - K S K^T`: `docs/math.md`,
//! "Sparse measurement update".

//! ## Gating ("should I fuse" apart from "fuse it")
//! The measurement is used only when `test_ratio <= 1`. Under the filter's
//! own model `NIS` is chi-square distributed with `M` degrees of freedom, so
//! the gate is a chi-square quantile. [`GATE_5_SIGMA_3DOF`] (31.81) has the
//! same tail probability as a two-sided 5-sigma Gaussian test,
//! `5.73e-7`: a healthy filter rejects about one good 3-D measurement in two
//! million. A rejected measurement leaves `x` and `P` exactly as they were
//! and still yields a [`FusionRecord`] (with `fused = false`).
//!
//! Nothing is changed unless the measurement is accepted, the new `x` and
//! `P` are finite and no new variance is negative: `x` is computed into a
//! temporary and checked first; `P` is updated in place on its lower
//! triangle, and restored from its upper triangle (`P` is kept exactly
//! symmetric) when the result is not finite or has a negative variance
//! (rounding in an ill-conditioned `P`: the update is reported rejected).

use crate::error::Error;
use crate::estimate::FusionRecord;
use crate::scalar::{Scalar, all_finite_fixed};
use nalgebra::{ArrayStorage, SMatrix, SVector};

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
/// `p` must be exactly symmetric (every filter of the crate keeps it so); the
/// result is.
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
    joseph_update_checked(
        x,
        p,
        innovation,
        h,
        r,
        gate,
        t_us,
        measurement,
        gain_restriction.map(GainRestriction::Matrix),
        |_| true,
    )
}

/// How a fusion's gain is restricted (crate-internal form of
/// [`joseph_update_restricted`]'s argument).
#[derive(Debug, Clone, Copy)]
pub(crate) enum GainRestriction<'a, T: Scalar, const N: usize> {
    /// `K' = C K` for a matrix `C`.
    Matrix(&'a SMatrix<T, N, N>),
    /// Only the rows whose bit is set (bit `i` for state `i`) are kept,
    /// the others zero: `C` diagonal with ones and zeros, without storing
    /// it (1 KB of stack in `f32` for 16 states).
    KeepRows(u32),
}

/// [`joseph_update_restricted`] with a last check of the updated state:
/// when `accept(x_new)` is false nothing is committed and the measurement is
/// reported as rejected (`test_ratio = inf`), as for a non-finite result.
/// The check runs before `P` is touched, so a refused update costs no copy
/// of `P` to undo.
#[allow(clippy::too_many_arguments)]
pub(crate) fn joseph_update_checked<T: Scalar, const N: usize, const M: usize>(
    x: &mut SVector<T, N>,
    p: &mut SMatrix<T, N, N>,
    innovation: &SVector<T, M>,
    h: &SMatrix<T, M, N>,
    r: &SMatrix<T, M, M>,
    gate: T,
    t_us: u64,
    measurement: &'static str,
    gain_restriction: Option<GainRestriction<'_, T, N>>,
    accept: impl FnOnce(&SVector<T, N>) -> bool,
) -> Result<FusionRecord<T, M>, Error> {
    // Plain arrays, column-major as nalgebra stores them: `h_cols[c]` is
    // column `c` of H, `p.data.0[j]` column `j` of P. Every loop below walks
    // them with iterators or with indices bounded by the array lengths, so
    // no bounds check can fail (the push API is proven panic-free:
    // benches/no-panic).
    let h_cols = &h.data.0;
    // H's non-zero columns: GPS rows select a few states, the magnetometer
    // row only the quaternion. Products with H run over these columns only.
    let mut support = [false; N];
    for (used, column) in support.iter_mut().zip(h_cols) {
        *used = column.iter().any(|v| *v != T::zero());
    }
    // U = P H^T, stored by rows: `u[i]` is row `i` of U (`N x M`), which is
    // also column `i` of U^T (`M x N`) in nalgebra's layout.
    let mut u = [[T::zero(); M]; N];
    for ((&used, h_col), p_col) in support.iter().zip(h_cols).zip(&p.data.0) {
        if used {
            for (u_row, &p_ic) in u.iter_mut().zip(p_col) {
                for (u_im, &h_mc) in u_row.iter_mut().zip(h_col) {
                    *u_im += h_mc * p_ic;
                }
            }
        }
    }
    // S = H U + R.
    let mut s = *r;
    for ((&used, h_col), u_row) in support.iter().zip(h_cols).zip(&u) {
        if used {
            for (s_col, &u_cm) in s.data.0.iter_mut().zip(u_row) {
                for (s_entry, &h_mc) in s_col.iter_mut().zip(h_col) {
                    *s_entry += h_mc * u_cm;
                }
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
    // K = U S^-1  <=>  K^T = S^-1 U^T (S symmetric); `k[i]` is row `i` of K.
    let mut k = chol.solve(&SMatrix::from_data(ArrayStorage(u))).data.0;
    match gain_restriction {
        Some(GainRestriction::Matrix(c)) => k = restricted_gain(c, &k),
        Some(GainRestriction::KeepRows(rows)) => {
            for (i, k_row) in k.iter_mut().enumerate() {
                if i >= 32 || rows & (1 << i) == 0 {
                    *k_row = [T::zero(); M];
                }
            }
        }
        None => {}
    }
    let mut x_new = *x;
    for (x_i, k_row) in x_new.iter_mut().zip(&k) {
        *x_i += dot(k_row, &innovation.data.0[0]);
    }
    if !(all_finite_fixed(&x_new) && accept(&x_new)) {
        record.test_ratio = T::lit(f64::INFINITY);
        return Ok(record);
    }
    if !joseph_in_place(p, h, &support, r, &k, &u) {
        record.test_ratio = T::lit(f64::INFINITY);
        return Ok(record);
    }
    *x = x_new;
    record.fused = true;
    Ok(record)
}

/// The rows of `K' = C K` from the rows `k` of `K`, over the non-zero
/// entries of `C` (a restriction is mostly identity and zero blocks).
fn restricted_gain<T: Scalar, const N: usize, const M: usize>(
    c: &SMatrix<T, N, N>,
    k: &[[T; M]; N],
) -> [[T; M]; N] {
    let mut out = [[T::zero(); M]; N];
    // Column `j` of C scales row `j` of K into every row `i` of K'. Indices
    // below their arrays' lengths (no failing bounds check): iterators
    // zipped three ways cost the M4 twice the instructions.
    #[allow(clippy::needless_range_loop)]
    for j in 0..N {
        for i in 0..N {
            let c_ij = c.data.0[j][i];
            if c_ij != T::zero() {
                for m in 0..M {
                    out[i][m] += c_ij * k[j][m];
                }
            }
        }
    }
    out
}

/// `a . b` for two rows of `M` entries.
fn dot<T: Scalar, const M: usize>(a: &[T; M], b: &[T; M]) -> T {
    a.iter().zip(b).fold(T::zero(), |acc, (&a, &b)| acc + a * b)
}

/// The Joseph form `L P L^T + K R K^T`, `L = I - K H`, for any gain `K`, in
/// place, without forming `L` or any `N x N` product: with `U = P H^T` (`P`
/// symmetric, so `H P = U^T`)
///
/// ```text
/// (L P)_ij = P_ij - k_i . u_j                     k_i, u_i: rows i of K and U
/// Z        = K R - (L P) H^T                      H's non-zero columns c only
/// P'_ij    = (L P)_ij + z_i . k_j                 lower triangle, mirrored
/// ```
///
/// since `L P L^T = L P - (L P H^T) K^T`. In exact arithmetic `Z = K S - U`
/// (zero for the optimal gain), but `Z` is taken from the computed `L P`:
/// the rounding of `P - K U^T`, large when a variance shrinks by orders of
/// magnitude, is then multiplied by `L^T`, small in the observed directions,
/// instead of staying in `P'` as in the expanded `P - K U^T - U K^T + K S
/// K^T` (`docs/math.md`, "Sparse measurement update"). `L P` is computed on
/// the lower triangle and `H`'s non-zero columns only: `2 M` multiply-adds
/// an entry of the triangle.
///
/// Returns false, with `P` as it was, when an entry of the result is not
/// finite or a variance is negative: the sum of the new lower triangle is
/// checked (a sum of finite numbers is finite unless it overflows, which
/// also refuses), and so is the sign of each new variance (exact arithmetic
/// keeps it; rounding does not when `P` is ill-conditioned, e.g. in `f32`
/// after steps of large rotations: such a result is no covariance). The
/// old lower triangle is restored from the untouched upper one and the
/// saved diagonal.
fn joseph_in_place<T: Scalar, const N: usize, const M: usize>(
    p: &mut SMatrix<T, N, N>,
    h: &SMatrix<T, M, N>,
    support: &[bool; N],
    r: &SMatrix<T, M, M>,
    k: &[[T; M]; N],
    u: &[[T; M]; N],
) -> bool {
    // Rows of Z: K R (R symmetric: row i of K R is R k_i) ...
    let mut z = [[T::zero(); M]; N];
    for (z_row, k_row) in z.iter_mut().zip(k) {
        for (z_im, r_col) in z_row.iter_mut().zip(&r.data.0) {
            *z_im = dot(r_col, k_row);
        }
    }
    // ... minus (L P) H^T, from the columns c of L P in H's support.
    for (((&used, h_col), p_col), u_c) in support.iter().zip(&h.data.0).zip(&p.data.0).zip(u) {
        if used {
            for ((z_row, k_row), &p_ic) in z.iter_mut().zip(k).zip(p_col) {
                let lp_ic = p_ic - dot(k_row, u_c);
                for (z_im, &h_mc) in z_row.iter_mut().zip(h_col) {
                    *z_im -= lp_ic * h_mc;
                }
            }
        }
    }
    let diagonal = p.diagonal();
    let mut sum = T::zero();
    let mut negative = false;
    let columns = &mut p.data.0;
    // Indices below their arrays' lengths, as in `restricted_gain`.
    #[allow(clippy::needless_range_loop)]
    for j in 0..N {
        let (k_j, u_j) = (&k[j], &u[j]);
        for i in j..N {
            let entry = (columns[j][i] - dot(&k[i], u_j)) + dot(&z[i], k_j);
            columns[j][i] = entry;
            sum += entry;
        }
        negative |= columns[j][j] < T::zero();
    }
    if negative || !sum.is_finite() {
        p.fill_lower_triangle_with_upper_triangle();
        // Indices below the arrays' lengths (not `enumerate`: its counter
        // has an overflow check).
        #[allow(clippy::needless_range_loop)]
        for j in 0..N {
            p.data.0[j][j] = diagonal.data.0[0][j];
        }
        return false;
    }
    p.fill_upper_triangle_with_lower_triangle();
    true
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
        // The same restriction given as the rows kept (bits 0 and 2), without the matrix.
        let (mut x_rows, mut p_rows) = (Vector3::<T>::zeros(), p0);
        joseph_update_checked(
            &mut x_rows,
            &mut p_rows,
            &y,
            &h,
            &r,
            T::lit(1e9),
            0,
            "t",
            Some(GainRestriction::KeepRows(0b101)),
            |_| true,
        )
        .unwrap();
        assert_eq!((x_rows, p_rows), (x, p));
    }

    #[test]
    fn restricted_update_f64() {
        restricted_update_leaves_the_excluded_state_and_its_variance::<f64>(1e-12);
    }

    #[test]
    fn restricted_update_f32() {
        restricted_update_leaves_the_excluded_state_and_its_variance::<f32>(1e-5);
    }

    /// A small deterministic generator (xorshift64*), for random matrices.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }

        /// Uniform in `[-1, 1)`.
        fn signed(&mut self) -> f64 {
            2.0 * self.next() - 1.0
        }
    }

    /// A random case: `P = L L^T` with per-state scales from `10^-spread` to
    /// `10^spread` (variances twice as many orders of magnitude) (rank deficient one time in four), a sparse `H`
    /// (an identity block plus a few dense columns, as a GPS block; or dense
    /// on four states only, as the magnetometer's), a diagonal `R` from
    /// `1e-3` to `4`, and one time in three a gain restriction `C`.
    struct Case<const N: usize> {
        p: SMatrix<f64, N, N>,
        h: SMatrix<f64, 3, N>,
        r: SMatrix<f64, 3, 3>,
        c: Option<SMatrix<f64, N, N>>,
        y: SVector<f64, 3>,
    }

    fn random_case<const N: usize>(rng: &mut Rng, spread: f64) -> Case<N> {
        let scale: [f64; N] = core::array::from_fn(|_| 10f64.powf(spread * rng.signed()));
        let l = SMatrix::<f64, N, N>::from_fn(|i, j| {
            if j == N - 1 && rng.0.is_multiple_of(4) {
                0.0
            } else {
                rng.signed() * scale[i]
            }
        });
        let p = l * l.transpose();
        let p = (p + p.transpose()) * 0.5;
        let mut h = SMatrix::<f64, 3, N>::zeros();
        if rng.next() < 0.7 {
            let first = 4 + (rng.next() * (N - 7) as f64) as usize;
            h.fixed_view_mut::<3, 3>(0, first).fill_with_identity();
            for c in 0..N {
                if rng.next() < 0.15 {
                    for m in 0..3 {
                        h[(m, c)] += rng.signed();
                    }
                }
            }
        } else {
            h.fixed_view_mut::<3, 4>(0, 0)
                .copy_from(&SMatrix::<f64, 3, 4>::from_fn(|_, _| rng.signed()));
        }
        let r = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::from_fn(|_, _| {
            10f64.powf(-2.0 + 2.6 * rng.next())
        }));
        let c = (rng.next() < 1.0 / 3.0).then(|| {
            let mut c = SMatrix::<f64, N, N>::identity();
            c.fixed_view_mut::<4, 4>(0, 0)
                .copy_from(&SMatrix::<f64, 4, 4>::from_fn(|_, _| 0.5 * rng.signed()));
            for i in 10..13 {
                c[(i, i)] = 0.0;
            }
            c
        });
        let y = Vector3::from_fn(|_, _| rng.signed());
        Case { p, h, r, c, y }
    }

    /// The dense Joseph update in `T`, `(I - K H) P (I - K H)^T + K R K^T`
    /// with `K = C P H^T S^-1` (a Cholesky solve), and the state correction
    /// `K y`.
    fn dense_joseph<T: Scalar, const N: usize>(
        case: &Case<N>,
    ) -> (SVector<T, N>, SMatrix<T, N, N>) {
        let cast = |v: f64| T::lit(v);
        let (p, h, r, y) = (
            case.p.map(cast),
            case.h.map(cast),
            case.r.map(cast),
            case.y.map(cast),
        );
        let pht = p * h.transpose();
        let s = h * pht + r;
        let mut k = s.cholesky().unwrap().solve(&pht.transpose()).transpose();
        if let Some(c) = case.c {
            k = c.map(cast) * k;
        }
        let l = SMatrix::<T, N, N>::identity() - k * h;
        (k * y, l * p * l.transpose() + k * r * k.transpose())
    }

    /// The errors of the state correction and the covariance computed in
    /// `T` against the dense form in f64, each relative to the largest entry
    /// of the reference: of [`joseph_update_restricted`], then of the dense
    /// form in `T` (for scale).
    fn errors<T: Scalar, const N: usize>(case: &Case<N>) -> [(f64, f64); 2] {
        let cast = |v: f64| T::lit(v);
        let (mut x, mut p) = (SVector::<T, N>::zeros(), case.p.map(cast));
        let c = case.c.map(|c| c.map(cast));
        let record = joseph_update_restricted(
            &mut x,
            &mut p,
            &case.y.map(cast),
            &case.h.map(cast),
            &case.r.map(cast),
            T::lit(f64::INFINITY),
            0,
            "test",
            c.as_ref(),
        )
        .unwrap();
        assert!(record.fused);
        assert_eq!(p, p.transpose(), "not exactly symmetric");
        let (dx, expected) = dense_joseph::<f64, N>(case);
        let error = |x: SVector<T, N>, p: SMatrix<T, N, N>| {
            (
                (x.map(|v| v.as_f64()) - dx).amax() / dx.amax(),
                (p.map(|v| v.as_f64()) - expected).amax() / expected.amax(),
            )
        };
        let (x_dense, p_dense) = dense_joseph::<T, N>(case);
        [error(x, p), error(x_dense, p_dense)]
    }

    /// Over 300 cases with variances spanning eight orders of magnitude:
    /// the worst errors are at most twice those of the dense form in the
    /// same precision, plus `(x_floor, p_floor)` (for f64, where that form
    /// is the reference itself). Both grow with the conditioning of `S` (of
    /// the gain); measured in f32 for N = 16: x 1.9e-2, P 6.3e-5, the dense
    /// form 3.5e-2, 5.2e-5; in f64 x 2.1e-10, P 7.4e-14.
    fn matches_the_dense_joseph_form<T: Scalar, const N: usize>((x_floor, p_floor): (f64, f64)) {
        let mut rng = Rng(0x6a09_e667_f3bc_c908 ^ N as u64);
        let mut worst = [(0f64, 0f64); 2];
        for _ in 0..300 {
            let case = random_case::<N>(&mut rng, 2.0);
            for (w, e) in worst.iter_mut().zip(errors::<T, N>(&case)) {
                *w = (w.0.max(e.0), w.1.max(e.1));
            }
        }
        let [(x, p), (x_dense, p_dense)] = worst;
        eprintln!(
            "{} N={N}: x {x:.1e} P {p:.1e}; the dense form in the same precision: x {x_dense:.1e} P {p_dense:.1e}",
            core::any::type_name::<T>(),
        );
        assert!(x <= 2.0 * x_dense + x_floor && p <= 2.0 * p_dense + p_floor);
    }

    #[test]
    fn matches_the_dense_joseph_form_f64() {
        matches_the_dense_joseph_form::<f64, 16>((1e-9, 1e-12));
        matches_the_dense_joseph_form::<f64, 17>((1e-9, 1e-12));
    }

    #[test]
    fn matches_the_dense_joseph_form_f32() {
        matches_the_dense_joseph_form::<f32, 16>((0.0, 0.0));
        matches_the_dense_joseph_form::<f32, 17>((0.0, 0.0));
    }

    /// The condition number of `S = H P H^T + R` of a case (in f64).
    fn innovation_condition<const N: usize>(case: &Case<N>) -> f64 {
        let s = case.h * case.p * case.h.transpose() + case.r;
        let eigenvalues = s.symmetric_eigenvalues();
        eigenvalues.max() / eigenvalues.min()
    }

    /// The check of [`matches_the_dense_joseph_form_on_any_seed`] on the
    /// case of `seed` (variances spanning four orders of magnitude): f64
    /// against the dense form in f64 (the reference); f32 within 5x of the
    /// dense form's own f32 error, or under a floor: the larger of 1e-3 (x)
    /// / 3e-5 (P) and `2 eps_f32 cond(S)`, the forward error of the gain's
    /// solve that any f32 algorithm may make. The dense form in f32 is at
    /// times far better than that bound, and the ratio alone then failed:
    /// seeds 8833327133248184445 and 17609281231349481892 (x 2.5e-3 and
    /// 1.5e-3, 10.9x and 5.1x the dense form's; cond(S) 4.2e4 and 3.1e4,
    /// floor 1.0e-2 and 7.5e-3) and 5410732532479343997 (P 3.1e-5; cond(S)
    /// 7.3e3). Scanned over 2,000,000 random seeds (2026-11-28): no failure,
    /// the worst f32 errors 0.91x (x) and 0.30x (P) of their bounds, the
    /// worst f64 errors 4.0e-12 (x) and 2.2e-13 (P).
    fn check_seed(seed: u64) -> Result<(), String> {
        let case = random_case::<16>(&mut Rng(seed), 1.0);
        let [(x, p), _] = errors::<f64, 16>(&case);
        if !(x < 1e-11 && p < 1e-12) {
            return Err(format!("seed {seed}, f64: {x:e} {p:e}"));
        }
        let [(x, p), (x_dense, p_dense)] = errors::<f32, 16>(&case);
        let floor = 2.0 * f64::from(f32::EPSILON) * innovation_condition(&case);
        if x < 1e-3f64.max(5.0 * x_dense).max(floor) && p < 3e-5f64.max(5.0 * p_dense).max(floor) {
            Ok(())
        } else {
            Err(format!(
                "seed {seed}, f32: {x:e} {p:e}, the dense form {x_dense:e} {p_dense:e}, \
                 conditioning floor {floor:e}"
            ))
        }
    }

    proptest::proptest! {
        // A fixed generator seed and no failure file: the same 256 cases on
        // every run, and a failure never writes into the checkout.
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 256,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x6a09_e667_f3bc_c908),
            failure_persistence: None,
            ..proptest::prelude::ProptestConfig::default()
        })]
        /// [`check_seed`] on 256 seeds drawn from a fixed generator seed.
        #[test]
        fn matches_the_dense_joseph_form_on_any_seed(seed in 1u64..) {
            check_seed(seed).map_err(proptest::test_runner::TestCaseError::fail)?;
        }
    }

    /// The seeds that failed [`check_seed`]'s bounds before its conditioning
    /// floor (one random run in about a thousand): ill-conditioned `S`, and
    /// within the floor.
    #[test]
    fn matches_the_dense_joseph_form_on_the_ill_conditioned_seeds() {
        for seed in [
            8_833_327_133_248_184_445,
            17_609_281_231_349_481_892,
            5_410_732_532_479_343_997,
        ] {
            let case = random_case::<16>(&mut Rng(seed), 1.0);
            assert!(innovation_condition(&case) > 5e3, "seed {seed}");
            assert_eq!(check_seed(seed), Ok(()));
        }
    }

    /// A refused state (the check) or an overflowing covariance leaves `x`
    /// and `P` exactly as they were.
    #[test]
    fn a_refused_update_changes_nothing() {
        let mut rng = Rng(7);
        let case = random_case::<16>(&mut rng, 1.0);
        let (x0, p0) = (SVector::<f32, 16>::repeat(0.25), case.p.map(|v| v as f32));
        let (h, r, y) = (
            case.h.map(|v| v as f32),
            case.r.map(|v| v as f32),
            case.y.map(|v| v as f32),
        );
        let (mut x, mut p) = (x0, p0);
        let record = joseph_update_checked(
            &mut x,
            &mut p,
            &y,
            &h,
            &r,
            f32::INFINITY,
            0,
            "t",
            None,
            |_| false,
        )
        .unwrap();
        assert!(!record.fused && record.test_ratio == f32::INFINITY);
        assert_eq!((x, p), (x0, p0));
        // A gain that overflows f32 in `K U^T`: P is restored bit for bit.
        let mut support = [false; 16];
        for (used, col) in support.iter_mut().zip(&h.data.0) {
            *used = col.iter().any(|v| *v != 0.0);
        }
        let huge = [[1e20f32; 3]; 16];
        assert!(!joseph_in_place(&mut p, &h, &support, &r, &huge, &huge));
        assert_eq!(p, p0);
    }
}

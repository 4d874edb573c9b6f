//! The one float bound of the crate.
//!
//! Every estimator is generic over `T: Scalar`, implemented for `f32` (the
//! microcontroller build) and `f64` (log replay on a laptop). `Scalar` is
//! `nalgebra::RealField` plus two conversions; all math goes through
//! `RealField`/`ComplexField` methods (`x.sin()`, `x.sqrt()`), which `libm`
//! provides under `no_std`.
//!
//! Literals are written `T::lit(0.5)`, never `as` casts.

use nalgebra::RealField;

/// The float bound used by every type of the crate: `f32` or `f64`.
pub trait Scalar: RealField + Copy + Default + core::fmt::Debug + 'static {
    /// A constant from an `f64` literal (rounded to nearest for `f32`).
    fn lit(x: f64) -> Self;
    /// The value as `f64` (exact for both precisions).
    fn as_f64(self) -> f64;
    /// An `f32` value (exact for both precisions; no software `f64` on an
    /// FPU without it).
    fn from_f32_exact(x: f32) -> Self;
    /// The value rounded to `f32` (exact for `f32`).
    fn round_to_f32(self) -> f32;
    /// Machine epsilon of the precision.
    const EPS: Self;
    /// Zero, usable in `const` items (the blank values of the estimators).
    const ZERO: Self;
    /// One, usable in `const` items.
    const ONE: Self;
    /// Largest rotation angle (radians) for which
    /// [`quaternion_from_rotation_vector`](crate::geo::quaternion_from_rotation_vector)
    /// uses its series instead of `sin`/`cos`: where the first neglected
    /// term stays below half an ulp of 1 (1 rad in f32, 0.2 rad in f64).
    const SMALL_ROTATION_MAX_RAD: f64;
    /// Integer microseconds as seconds, rounded to nearest (see [`us_to_s`]).
    fn seconds_from_us(us: u64) -> Self;
}

impl Scalar for f32 {
    #[inline]
    fn lit(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn as_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn from_f32_exact(x: f32) -> Self {
        x
    }
    #[inline]
    fn round_to_f32(self) -> f32 {
        self
    }
    const EPS: Self = f32::EPSILON;
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const SMALL_ROTATION_MAX_RAD: f64 = 1.0;
    #[inline]
    fn seconds_from_us(us: u64) -> Self {
        // Below 2^24 µs (16.7 s: every step length) the integer is exact in
        // f32 and the division by the exact 1e6 rounds once, all in
        // hardware f32; the f64 route costs a software double on an FPU
        // without f64.
        if us < 1 << 24 {
            us as u32 as f32 / 1e6
        } else {
            (us as f64 * 1e-6) as f32
        }
    }
}

impl Scalar for f64 {
    #[inline]
    fn lit(x: f64) -> Self {
        x
    }
    #[inline]
    fn as_f64(self) -> f64 {
        self
    }
    #[inline]
    fn from_f32_exact(x: f32) -> Self {
        x as f64
    }
    #[inline]
    fn round_to_f32(self) -> f32 {
        self as f32
    }
    const EPS: Self = f64::EPSILON;
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const SMALL_ROTATION_MAX_RAD: f64 = 0.2;
    #[inline]
    fn seconds_from_us(us: u64) -> Self {
        us as f64 * 1e-6
    }
}

/// Microseconds to seconds, in `T`. Timestamps stay integer microseconds
/// (`u64`) everywhere; only *differences* of timestamps become floats.
#[inline]
pub fn us_to_s<T: Scalar>(us: u64) -> T {
    T::seconds_from_us(us)
}

/// Seconds to integer microseconds, rounded to nearest; negative and
/// non-finite inputs give `None`.
#[inline]
pub fn s_to_us<T: Scalar>(s: T) -> Option<u64> {
    let us = s.as_f64() * 1e6;
    if us.is_finite() && us >= 0.0 && us < u64::MAX as f64 {
        Some((us + 0.5) as u64)
    } else {
        None
    }
}

/// True when every component of a vector or matrix is finite.
#[inline]
pub(crate) fn all_finite<T: Scalar, R: nalgebra::Dim, C: nalgebra::Dim, S>(
    m: &nalgebra::Matrix<T, R, C, S>,
) -> bool
where
    S: nalgebra::RawStorage<T, R, C>,
{
    m.iter().all(|v| v.is_finite())
}

/// [`all_finite`] for a fixed-size matrix: a branch-free scan of its
/// contiguous storage (the generic iterator costs several times more on
/// a 16x16 covariance checked after every step).
#[inline]
pub(crate) fn all_finite_fixed<T: Scalar, const R: usize, const C: usize>(
    m: &nalgebra::SMatrix<T, R, C>,
) -> bool {
    m.as_slice().iter().fold(true, |ok, v| ok & v.is_finite())
}

/// A fixed-size matrix of zeros, in `const` items.
pub(crate) const fn zeros_const<T: Scalar, const R: usize, const C: usize>()
-> nalgebra::SMatrix<T, R, C> {
    nalgebra::SMatrix::from_array_storage(nalgebra::ArrayStorage([[T::ZERO; R]; C]))
}

/// A zero quaternion typed as a unit one: the placeholder of an attitude
/// in a `const` blank value, set before it is read.
pub(crate) const fn zero_quaternion_const<T: Scalar>() -> nalgebra::UnitQuaternion<T> {
    nalgebra::Unit::new_unchecked(nalgebra::Quaternion::new(
        T::ZERO,
        T::ZERO,
        T::ZERO,
        T::ZERO,
    ))
}

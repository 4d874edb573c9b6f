//! Frames, rotations and WGS-84 geodesy.
//!
//! # Conventions
//! - Navigation frame NED, body frame FRD.
//! - Quaternion `q = [q0 q1 q2 q3]`, Hamilton, scalar first, rotating body to
//!   navigation: `v_n = R(q) v_b` with
//!
//!   ```text
//!   R(q) = | 1-2(q2²+q3²)   2(q1q2-q0q3)   2(q1q3+q0q2) |
//!          | 2(q1q2+q0q3)   1-2(q1²+q3²)   2(q2q3-q0q1) |
//!          | 2(q1q3-q0q2)   2(q2q3+q0q1)   1-2(q1²+q2²) |
//!   ```
//!
//!   (the paper's eq. (3), which it calls `C_n^b`; its (3,1) entry is printed
//!   with a `+` sign, the correct entry is `2(q1q3 - q0q2)`).
//! - Euler angles roll `phi`, pitch `theta`, yaw `psi`, ZYX order:
//!   `R = Rz(psi) Ry(theta) Rx(phi)`; yaw is clockwise from north seen from above.
//! - Earth magnetic field in NED, unit length, inclination `I` measured
//!   downwards from the horizontal and declination `D` east of true north:
//!   `m_n = [cos I cos D, cos I sin D, sin I]`.
//!
//! # Geodesy
//! WGS-84 geodetic (latitude, longitude, height) goes to ECEF and then to a
//! local NED frame tangent at an origin. Computed in `f64` in every precision;
//! only the local NED result, metres from the origin, is narrowed to `T`.
//! The tangent plane is exact (no flat-earth approximation): the NED axes are
//! those of the origin, so far from the origin "down" tilts from local vertical
//! by `distance / 6371 km` radians (0.09 deg at 10 km).

use crate::scalar::Scalar;
use crate::sensors::Geodetic;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
// Under no_std, f64 has no inherent math methods: take them from nalgebra's traits (libm).
#[cfg(not(any(test, feature = "std")))]
use nalgebra::{ComplexField, RealField};

/// WGS-84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS-84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS-84 first eccentricity squared.
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// Body-to-navigation rotation matrix of a (not necessarily unit) quaternion,
/// eq. (3) with the sign of the (3,1) entry corrected. For a quaternion of norm
/// `n` the result is `n²` times a rotation.
pub fn rotation_matrix<T: Scalar>(q: &Quaternion<T>) -> Matrix3<T> {
    let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
    let two = T::lit(2.0);
    let n2 = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3;
    Matrix3::new(
        n2 - two * (q2 * q2 + q3 * q3),
        two * (q1 * q2 - q0 * q3),
        two * (q1 * q3 + q0 * q2),
        two * (q1 * q2 + q0 * q3),
        n2 - two * (q1 * q1 + q3 * q3),
        two * (q2 * q3 - q0 * q1),
        two * (q1 * q3 - q0 * q2),
        two * (q2 * q3 + q0 * q1),
        n2 - two * (q1 * q1 + q2 * q2),
    )
}

/// Quaternion of roll, pitch, yaw (radians, ZYX).
pub fn quaternion_from_euler<T: Scalar>(roll: T, pitch: T, yaw: T) -> UnitQuaternion<T> {
    let half = T::lit(0.5);
    let (sr, cr) = (roll * half).sin_cos();
    let (sp, cp) = (pitch * half).sin_cos();
    let (sy, cy) = (yaw * half).sin_cos();
    UnitQuaternion::new_unchecked(Quaternion::new(
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ))
}

/// Roll, pitch, yaw (radians, ZYX) of a quaternion; yaw in `(-pi, pi]`.
/// Pitch is clamped to `[-pi/2, pi/2]` at the singularity.
pub fn euler_from_quaternion<T: Scalar>(q: &Quaternion<T>) -> Vector3<T> {
    let (q0, q1, q2, q3) = (q.w, q.i, q.j, q.k);
    let one = T::one();
    let two = T::lit(2.0);
    let roll = (two * (q0 * q1 + q2 * q3)).atan2(one - two * (q1 * q1 + q2 * q2));
    let s = (two * (q0 * q2 - q3 * q1)).clamp(-one, one);
    let pitch = s.asin();
    let yaw = (two * (q0 * q3 + q1 * q2)).atan2(one - two * (q2 * q2 + q3 * q3));
    Vector3::new(roll, pitch, yaw)
}

/// The exact rotation of a rotation vector `theta` (axis times angle, radians)
/// as a unit quaternion: `[cos(|theta|/2), sin(|theta|/2) theta/|theta|]`.
///
/// Up to [`Scalar::SMALL_ROTATION_MAX_RAD`] (1 rad in f32, 0.2 rad in f64:
/// every per-sample rotation `w dt` of an IMU up to 1 kHz, 35 rad/s) the
/// two functions are the series in `y = |theta|² / 4`, no trigonometry and
/// no square root of the angle:
///
/// ```text
/// cos(a/2)     = 1 - y/2 + y²/24 - y³/720 + y⁴/40320          (+ O(y⁵/10!))
/// sin(a/2) / a = (1 - y/6 + y²/120 - y³/5040 + y⁴/362880) / 2  (+ O(y⁵/11!))
/// ```
///
/// The first neglected term, `(a/2)^10 / 10!`, is below `2.7e-10` at 1 rad
/// and below `2.8e-17` at 0.2 rad: under half an ulp of 1 in each precision
/// (`5.96e-8`, `1.11e-16`), so the series is the exact formula to rounding.
/// Beyond, the exact formula (`sin_cos` of `a/2`).
pub fn quaternion_from_rotation_vector<T: Scalar>(theta: &Vector3<T>) -> UnitQuaternion<T> {
    let angle2 = theta.norm_squared();
    let half = T::lit(0.5);
    let limit = T::lit(T::SMALL_ROTATION_MAX_RAD * T::SMALL_ROTATION_MAX_RAD);
    let (w, k) = if angle2 <= limit {
        let y = angle2 * T::lit(0.25);
        let c = T::one()
            - y * (half
                - y * (T::lit(1.0 / 24.0)
                    - y * (T::lit(1.0 / 720.0) - y * T::lit(1.0 / 40_320.0))));
        let s = T::one()
            - y * (T::lit(1.0 / 6.0)
                - y * (T::lit(1.0 / 120.0)
                    - y * (T::lit(1.0 / 5040.0) - y * T::lit(1.0 / 362_880.0))));
        (c, s * half)
    } else {
        let angle = angle2.sqrt();
        let (s, c) = (angle * half).sin_cos();
        (c, s / angle)
    };
    normalize_near_unit(Quaternion::new(w, theta.x * k, theta.y * k, theta.z * k))
}

/// The unit quaternion of `q`, without a square root when `q` is already
/// unit to within rounding (the per-sample case: a product of unit
/// quaternions, a renormalized state).
///
/// With `s = |q|² = 1 + e`, one Newton step for `1/sqrt(s)` from 1 gives
/// `(3 - s)/2 = 1 - e/2`, off by `3e²/8 + O(e³)`; it is used when that is
/// below the precision's epsilon (`|e| < ~1.8e-4` in f32, `~1.7e-8` in f64),
/// so the result is the normalized quaternion to rounding. Otherwise (and
/// for any `q` far from unit) it divides by `sqrt(s)`. `q` must not be zero.
pub fn normalize_near_unit<T: Scalar>(q: Quaternion<T>) -> UnitQuaternion<T> {
    let s = q.norm_squared();
    let e = s - T::one();
    if e * e * T::lit(0.375) < T::EPS {
        UnitQuaternion::new_unchecked(q * ((T::lit(3.0) - s) * T::lit(0.5)))
    } else {
        UnitQuaternion::new_normalize(q)
    }
}

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap_pi<T: Scalar>(a: T) -> T {
    let two_pi = T::two_pi();
    let mut w = a - two_pi * ((a + T::pi()) / two_pi).floor();
    if w <= -T::pi() {
        w += two_pi;
    }
    w
}

/// Unit Earth magnetic field in NED from inclination (down from horizontal)
/// and declination (east of north), radians.
pub fn magnetic_field_ned<T: Scalar>(inclination: T, declination: T) -> Vector3<T> {
    let (si, ci) = inclination.sin_cos();
    let (sd, cd) = declination.sin_cos();
    Vector3::new(ci * cd, ci * sd, si)
}

/// Tilt-compensated true heading (radians, `(-pi, pi]`) from a body-frame
/// magnetometer sample, roll and pitch (radians), and the declination.
///
/// The field is de-rotated by roll and pitch into the level heading frame,
/// `m_h = Ry(theta) Rx(phi) m_b`; magnetic heading is `atan2(-m_h.y, m_h.x)`,
/// and true heading adds the declination.
pub fn tilt_compensated_heading<T: Scalar>(
    field_body: &Vector3<T>,
    roll: T,
    pitch: T,
    declination: T,
) -> T {
    tilt_compensated_heading_sc(field_body, roll.sin_cos(), pitch.sin_cos(), declination)
}

/// [`tilt_compensated_heading`] from the sines and cosines of roll and
/// pitch, `(sin, cos)` each (computed once by a caller that needs them
/// again).
pub(crate) fn tilt_compensated_heading_sc<T: Scalar>(
    field_body: &Vector3<T>,
    (sr, cr): (T, T),
    (sp, cp): (T, T),
    declination: T,
) -> T {
    let m = field_body;
    // Rx(phi) m
    let y1 = cr * m.y - sr * m.z;
    let z1 = sr * m.y + cr * m.z;
    // Ry(theta) (Rx m)
    let xh = cp * m.x + sp * z1;
    let yh = y1;
    wrap_pi((-yh).atan2(xh) + declination)
}

/// Roll and pitch (radians) of a level-frame specific force: the attitude at
/// which gravity alone would give this accelerometer reading. Meaningful
/// when the vehicle is not accelerating.
pub fn roll_pitch_from_accel<T: Scalar>(accel_body: &Vector3<T>) -> (T, T) {
    // At rest f_b = R^T [0 0 -g]: f = g [sin(th), -sin(ph)cos(th), -cos(ph)cos(th)].
    let f = accel_body;
    let roll = (-f.y).atan2(-f.z);
    let pitch = f.x.atan2((f.y * f.y + f.z * f.z).sqrt());
    (roll, pitch)
}

/// Earth-centred, Earth-fixed coordinates (metres) of a geodetic position.
pub fn geodetic_to_ecef(p: &Geodetic) -> Vector3<f64> {
    let lat = p.lat_deg.to_radians_s();
    let lon = p.lon_deg.to_radians_s();
    let (sl, cl) = lat.sin_cos();
    let (so, co) = lon.sin_cos();
    let n = WGS84_A / (1.0 - WGS84_E2 * sl * sl).sqrt();
    Vector3::new(
        (n + p.alt_m) * cl * co,
        (n + p.alt_m) * cl * so,
        (n * (1.0 - WGS84_E2) + p.alt_m) * sl,
    )
}

/// Geodetic position of ECEF coordinates (metres). Iterates the latitude
/// to below 1e-12 rad (sub-millimetre); not meant for points near the
/// Earth's centre. Height uses `h = p cos(lat) + z sin(lat) - a sqrt(1 - e² sin²(lat))`,
/// well conditioned at the poles.
pub fn ecef_to_geodetic(e: &Vector3<f64>) -> Geodetic {
    let lon = e.y.atan2(e.x);
    let p = (e.x * e.x + e.y * e.y).sqrt();
    let mut lat = e.z.atan2(p * (1.0 - WGS84_E2));
    let mut h = 0.0;
    for _ in 0..10 {
        let (s, c) = lat.sin_cos();
        let n = WGS84_A / (1.0 - WGS84_E2 * s * s).sqrt();
        // Stable at every latitude, unlike p / cos(lat) - n.
        h = p * c + e.z * s - WGS84_A * (1.0 - WGS84_E2 * s * s).sqrt();
        let next = e.z.atan2(p * (1.0 - WGS84_E2 * n / (n + h)));
        let done = (next - lat).abs() < 1e-12;
        lat = next;
        if done {
            break;
        }
    }
    Geodetic {
        lat_deg: lat.to_degrees_s(),
        lon_deg: lon.to_degrees_s(),
        alt_m: h,
    }
}

/// A local NED frame tangent to the WGS-84 ellipsoid at an origin.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LocalFrame {
    origin: Geodetic,
    origin_ecef: Vector3<f64>,
    /// Rows: north, east, down unit vectors in ECEF.
    ecef_to_ned: Matrix3<f64>,
}

impl LocalFrame {
    /// A frame about `origin`.
    pub fn new(origin: Geodetic) -> Self {
        let lat = origin.lat_deg.to_radians_s();
        let lon = origin.lon_deg.to_radians_s();
        let (sl, cl) = lat.sin_cos();
        let (so, co) = lon.sin_cos();
        let ecef_to_ned = Matrix3::new(
            -sl * co,
            -sl * so,
            cl,
            -so,
            co,
            0.0,
            -cl * co,
            -cl * so,
            -sl,
        );
        Self {
            origin,
            origin_ecef: geodetic_to_ecef(&origin),
            ecef_to_ned,
        }
    }

    /// The origin.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// NED coordinates (metres, `f64`) of a geodetic position.
    pub fn to_ned(&self, p: &Geodetic) -> Vector3<f64> {
        self.ecef_to_ned * (geodetic_to_ecef(p) - self.origin_ecef)
    }

    /// NED coordinates (metres) of a geodetic position, in `T`.
    pub fn to_ned_t<T: Scalar>(&self, p: &Geodetic) -> Vector3<T> {
        self.to_ned(p).map(T::lit)
    }

    /// Geodetic position of NED coordinates (metres) in this frame.
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> Geodetic {
        ecef_to_geodetic(&(self.origin_ecef + self.ecef_to_ned.transpose() * ned))
    }
}

/// Degree/radian conversions through `Scalar` so they work under `no_std`.
trait Angles {
    fn to_radians_s(self) -> Self;
    fn to_degrees_s(self) -> Self;
}

impl Angles for f64 {
    fn to_radians_s(self) -> Self {
        self * (core::f64::consts::PI / 180.0)
    }
    fn to_degrees_s(self) -> Self {
        self * (180.0 / core::f64::consts::PI)
    }
}

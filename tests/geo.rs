//! geo: rotations, Euler angles, magnetic heading and WGS-84 against known values.

use approx::assert_relative_eq;
use delaynav::Geodetic;
use delaynav::geo::*;
use nalgebra::Vector3;

#[test]
fn ecef_known_points() {
    let e = geodetic_to_ecef(&Geodetic {
        lat_deg: 0.0,
        lon_deg: 0.0,
        alt_m: 0.0,
    });
    assert_relative_eq!(e, Vector3::new(6_378_137.0, 0.0, 0.0), epsilon = 1e-6);
    let e = geodetic_to_ecef(&Geodetic {
        lat_deg: 90.0,
        lon_deg: 0.0,
        alt_m: 0.0,
    });
    // WGS-84 semi-minor axis b = a (1 - f) = 6 356 752.314245 m.
    assert_relative_eq!(e.z, 6_356_752.314_245, epsilon = 1e-5);
    assert!(e.x.abs() < 1e-6);
    let e = geodetic_to_ecef(&Geodetic {
        lat_deg: 0.0,
        lon_deg: 90.0,
        alt_m: 100.0,
    });
    assert_relative_eq!(e, Vector3::new(0.0, 6_378_237.0, 0.0), epsilon = 1e-6);
}

#[test]
fn ecef_round_trip() {
    for (lat, lon, h) in [
        (-35.364, 149.165, 580.0),
        (31.23, 121.47, 4.0),
        (89.9, -170.0, -50.0),
        (0.0, 0.0, 0.0),
    ] {
        let g = Geodetic {
            lat_deg: lat,
            lon_deg: lon,
            alt_m: h,
        };
        let back = ecef_to_geodetic(&geodetic_to_ecef(&g));
        assert_relative_eq!(back.lat_deg, lat, epsilon = 1e-9);
        assert_relative_eq!(back.lon_deg, lon, epsilon = 1e-9);
        assert_relative_eq!(back.alt_m, h, epsilon = 1e-4);
    }
}

#[test]
fn local_ned_axes_and_scale() {
    let origin = Geodetic {
        lat_deg: 0.0,
        lon_deg: 0.0,
        alt_m: 0.0,
    };
    let f = LocalFrame::new(origin);
    // One degree of latitude at the equator is 110 574.3 m along the meridian
    // (the tangent plane sees a little less north and some "down").
    let n = f.to_ned(&Geodetic {
        lat_deg: 0.001,
        lon_deg: 0.0,
        alt_m: 0.0,
    });
    assert_relative_eq!(n.x, 110.574_3, epsilon = 2e-3);
    assert!(n.y.abs() < 1e-9);
    let e = f.to_ned(&Geodetic {
        lat_deg: 0.0,
        lon_deg: 0.001,
        alt_m: 0.0,
    });
    // One degree of longitude at the equator is 111 319.49 m.
    assert_relative_eq!(e.y, 111.319_49, epsilon = 2e-3);
    let d = f.to_ned(&Geodetic {
        lat_deg: 0.0,
        lon_deg: 0.0,
        alt_m: 10.0,
    });
    assert_relative_eq!(d, Vector3::new(0.0, 0.0, -10.0), epsilon = 1e-9);
    let ned = Vector3::new(1234.5, -678.9, -42.0);
    assert_relative_eq!(f.to_ned(&f.to_geodetic(&ned)), ned, epsilon = 1e-6);
}

macro_rules! rotation_tests {
    ($mod:ident, $t:ty, $tol:expr) => {
        mod $mod {
            use super::*;
            type T = $t;

            #[test]
            fn euler_round_trip_and_nalgebra_agree() {
                for &(r, p, y) in &[
                    (0.1, -0.2, 0.3),
                    (-1.0, 0.5, -2.5),
                    (0.0, 0.0, 3.1),
                    (2.0, -1.2, 0.0),
                ] {
                    let (r, p, y) = (r as T, p as T, y as T);
                    let q = quaternion_from_euler(r, p, y);
                    let e = euler_from_quaternion(q.quaternion());
                    assert_relative_eq!(e, Vector3::new(r, p, y), epsilon = $tol);
                    let reference = nalgebra::UnitQuaternion::from_euler_angles(r, p, y);
                    assert_relative_eq!(
                        q.to_rotation_matrix().into_inner(),
                        reference.to_rotation_matrix().into_inner(),
                        epsilon = $tol
                    );
                    assert_relative_eq!(
                        rotation_matrix(q.quaternion()),
                        reference.to_rotation_matrix().into_inner(),
                        epsilon = $tol
                    );
                }
            }

            #[test]
            fn rotation_matrix_known_yaw() {
                // Yaw of +90 deg: body x (forward) points east.
                let q = quaternion_from_euler(0.0 as T, 0.0, core::f64::consts::FRAC_PI_2 as T);
                let v = rotation_matrix(q.quaternion()) * Vector3::new(1.0 as T, 0.0, 0.0);
                assert_relative_eq!(v, Vector3::new(0.0, 1.0, 0.0), epsilon = $tol);
                // Pitch up +90 deg: body x points up (-down).
                let q = quaternion_from_euler(0.0 as T, core::f64::consts::FRAC_PI_2 as T, 0.0);
                let v = rotation_matrix(q.quaternion()) * Vector3::new(1.0 as T, 0.0, 0.0);
                assert_relative_eq!(v, Vector3::new(0.0, 0.0, -1.0), epsilon = $tol);
            }

            #[test]
            fn rotation_vector_is_exact_and_smooth_at_zero() {
                let axis = Vector3::new(1.0 as T, -2.0, 0.5).normalize();
                for &angle in &[0.0 as T, 1e-7, 1e-3, 0.5, 3.0] {
                    let q = quaternion_from_rotation_vector(&(axis * angle));
                    let reference = nalgebra::UnitQuaternion::from_axis_angle(
                        &nalgebra::Unit::new_normalize(axis),
                        angle,
                    );
                    assert_relative_eq!(q.coords, reference.coords, epsilon = $tol);
                }
            }

            #[test]
            fn wrap_pi_range() {
                let pi = core::f64::consts::PI as T;
                for &a in &[0.0 as T, 3.0, -3.0, 7.0, -7.0, 100.0, pi, -pi] {
                    let w = wrap_pi(a);
                    assert!(w > -pi - $tol && w <= pi + $tol, "{a} -> {w}");
                    assert_relative_eq!(w.sin(), a.sin(), epsilon = 100.0 * $tol);
                    assert_relative_eq!(w.cos(), a.cos(), epsilon = 100.0 * $tol);
                }
            }

            #[test]
            fn tilt_compensated_heading_recovers_yaw() {
                let decl = (-6.0 - 2.0 / 60.0 as T).to_radians();
                let incl = (47.0 + 14.0 / 60.0 as T).to_radians();
                let m_n = magnetic_field_ned(incl, decl);
                for &(r, p, y) in &[(0.1 as T, -0.2, 0.3), (-0.5, 0.4, -2.5), (0.0, 0.0, 3.0)] {
                    let q = quaternion_from_euler(r, p, y);
                    let m_b = rotation_matrix(q.quaternion()).transpose() * m_n;
                    let h = tilt_compensated_heading(&m_b, r, p, decl);
                    assert_relative_eq!(wrap_pi(h - y), 0.0, epsilon = 10.0 * $tol);
                }
            }

            #[test]
            fn roll_pitch_from_gravity() {
                let g = 9.81 as T;
                for &(r, p) in &[(0.1 as T, -0.2), (-0.7, 0.4), (0.0, 0.0)] {
                    let q = quaternion_from_euler(r, p, 1.0);
                    let f_b =
                        rotation_matrix(q.quaternion()).transpose() * Vector3::new(0.0, 0.0, -g);
                    let (rr, pp) = roll_pitch_from_accel(&f_b);
                    assert_relative_eq!(rr, r, epsilon = 10.0 * $tol);
                    assert_relative_eq!(pp, p, epsilon = 10.0 * $tol);
                }
            }

            #[test]
            fn magnetic_field_is_unit_and_dips_down() {
                let m = magnetic_field_ned(0.8 as T, 0.2);
                assert_relative_eq!(m.norm(), 1.0, epsilon = $tol);
                assert!(m.z > 0.0 && m.x > 0.0 && m.y > 0.0);
            }
        }
    };
}

rotation_tests!(f32_rot, f32, 2e-5);
rotation_tests!(f64_rot, f64, 1e-10);

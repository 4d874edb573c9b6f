//! sensors: the input checks refuse what must be refused and pass the rest through unchanged.

use delaynav::sensors::{checked_gps, checked_imu, checked_mag};
use delaynav::{Error, Geodetic, Gps, GpsPosition, Imu, Mag};
use nalgebra::Vector3;

macro_rules! sensor_tests {
    ($mod:ident, $t:ty) => {
        mod $mod {
            use super::*;
            type T = $t;

            fn gps() -> Gps<T> {
                Gps {
                    t_us: 5,
                    position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0)),
                    velocity_ned_m_s: Vector3::new(0.1, 0.2, 0.3),
                    horizontal_accuracy_m: Some(1.5),
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: Some(0.2),
                }
            }

            #[test]
            fn valid_samples_pass_unchanged() {
                let imu = Imu::<T> {
                    t_us: 7,
                    gyro_rad_s: Vector3::new(0.1, -0.2, 0.3),
                    accel_m_s2: Vector3::new(0.0, 0.0, -9.8),
                };
                assert_eq!(checked_imu(&imu), Ok(imu));
                let mag = Mag::<T> {
                    t_us: 7,
                    field_body: Vector3::new(0.2, 0.0, 0.4),
                };
                assert_eq!(checked_mag(&mag), Ok(mag));
                assert_eq!(checked_gps(&gps()), Ok(gps()));
                let mut g = gps();
                g.position = GpsPosition::Geodetic(Geodetic {
                    lat_deg: 31.2,
                    lon_deg: 121.5,
                    alt_m: 4.0,
                });
                assert_eq!(checked_gps(&g), Ok(g));
            }

            #[test]
            fn non_finite_fields_are_named() {
                let mut imu = Imu::<T> {
                    t_us: 7,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::zeros(),
                };
                imu.gyro_rad_s.y = T::NAN;
                assert_eq!(
                    checked_imu(&imu),
                    Err(Error::NonFinite { field: "imu.gyro" })
                );
                imu.gyro_rad_s.y = 0.0;
                imu.accel_m_s2.z = T::INFINITY;
                assert_eq!(
                    checked_imu(&imu),
                    Err(Error::NonFinite { field: "imu.accel" })
                );

                let mut g = gps();
                g.velocity_ned_m_s.x = T::NAN;
                assert_eq!(
                    checked_gps(&g),
                    Err(Error::NonFinite {
                        field: "gps.velocity"
                    })
                );
                let mut g = gps();
                g.position = GpsPosition::Ned(Vector3::new(0.0, T::NEG_INFINITY, 0.0));
                assert_eq!(
                    checked_gps(&g),
                    Err(Error::NonFinite {
                        field: "gps.position"
                    })
                );
                let mut g = gps();
                g.position = GpsPosition::Geodetic(Geodetic {
                    lat_deg: f64::NAN,
                    lon_deg: 0.0,
                    alt_m: 0.0,
                });
                assert_eq!(
                    checked_gps(&g),
                    Err(Error::NonFinite {
                        field: "gps.position"
                    })
                );
                let mut g = gps();
                g.speed_accuracy_m_s = Some(T::NAN);
                assert_eq!(
                    checked_gps(&g),
                    Err(Error::NonFinite {
                        field: "gps.speed_accuracy"
                    })
                );

                let mag = Mag::<T> {
                    t_us: 1,
                    field_body: Vector3::new(T::NAN, 0.0, 0.0),
                };
                assert_eq!(
                    checked_mag(&mag),
                    Err(Error::NonFinite { field: "mag.field" })
                );
            }

            #[test]
            fn out_of_range_values_are_refused() {
                let mut g = gps();
                g.horizontal_accuracy_m = Some(0.0);
                assert!(matches!(
                    checked_gps(&g),
                    Err(Error::OutOfRange {
                        field: "gps.horizontal_accuracy",
                        ..
                    })
                ));
                // Every accuracy is bounded: 1e12 m is refused (its square
                // would overflow f32), so is a negative one; the bound itself passes.
                for (field, set) in [
                    (
                        "gps.horizontal_accuracy",
                        (|g: &mut Gps<T>, a| g.horizontal_accuracy_m = Some(a)) as fn(&mut Gps<T>, T),
                    ),
                    ("gps.vertical_accuracy", |g, a| g.vertical_accuracy_m = Some(a)),
                    ("gps.speed_accuracy", |g, a| g.speed_accuracy_m_s = Some(a)),
                ] {
                    for bad in [1e12, -1.0, 1.1e4] {
                        let mut g = gps();
                        set(&mut g, bad as T);
                        assert!(
                            matches!(checked_gps(&g), Err(Error::OutOfRange { field: f, .. }) if f == field),
                            "{field} {bad}"
                        );
                    }
                    let mut g = gps();
                    set(&mut g, 999.0);
                    assert!(checked_gps(&g).is_ok(), "{field}");
                }
                let mut g = gps();
                g.position = GpsPosition::Geodetic(Geodetic {
                    lat_deg: 91.0,
                    lon_deg: 0.0,
                    alt_m: 0.0,
                });
                assert!(checked_gps(&g).is_err());
                let mag = Mag::<T> {
                    t_us: 1,
                    field_body: Vector3::zeros(),
                };
                assert!(matches!(
                    checked_mag(&mag),
                    Err(Error::OutOfRange {
                        field: "mag.field",
                        ..
                    })
                ));
            }

            #[test]
            fn constructors_fill_every_field() {
                let (gyro, accel) = (Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.0, 0.0, -9.8));
                let imu = Imu::<T>::new(7, gyro, accel);
                assert_eq!((imu.t_us, imu.gyro_rad_s, imu.accel_m_s2), (7, gyro, accel));
                let mag = Mag::<T>::new(8, Vector3::new(0.2, 0.0, 0.4));
                assert_eq!((mag.t_us, mag.field_body), (8, Vector3::new(0.2, 0.0, 0.4)));
                let fix = Gps::<T>::ned(5, Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.2, 0.3))
                    .with_accuracy(1.5, 2.5, 0.2);
                let expected = Gps {
                    vertical_accuracy_m: Some(2.5),
                    ..gps()
                };
                assert_eq!(fix, expected);
                let plain = Gps::<T>::ned(5, Vector3::zeros(), Vector3::zeros());
                assert_eq!(
                    (plain.horizontal_accuracy_m, plain.vertical_accuracy_m, plain.speed_accuracy_m_s),
                    (None, None, None)
                );
                let place = Geodetic::new(31.2, 121.5, 4.0);
                assert_eq!((place.lat_deg, place.lon_deg, place.alt_m), (31.2, 121.5, 4.0));
                let fix = Gps::<T>::geodetic(9, place, Vector3::zeros());
                assert_eq!(fix.position, GpsPosition::Geodetic(place));
            }
        }
    };
}

sensor_tests!(f32_sensors, f32);
sensor_tests!(f64_sensors, f64);

#[test]
fn errors_display_what_was_wrong() {
    let e = Error::TimeWentBackwards {
        stream: "imu",
        previous_us: 10,
        got_us: 5,
    };
    assert_eq!(
        e.to_string(),
        "time went backwards on imu: previous 10 us, got 5 us"
    );
    let e = Error::NonFinite { field: "imu.gyro" };
    assert_eq!(e.to_string(), "non-finite value in `imu.gyro`");
}

#[test]
fn a_latitude_out_of_range_is_named_as_such_not_as_non_finite() {
    let mut g = Gps::<f64> {
        t_us: 5,
        position: GpsPosition::Geodetic(Geodetic {
            lat_deg: 95.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        }),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    };
    let e = checked_gps(&g).unwrap_err();
    assert!(
        matches!(
            e,
            Error::OutOfRange {
                field: "gps.position.lat_deg",
                ..
            }
        ),
        "{e}"
    );
    g.position = GpsPosition::Geodetic(Geodetic {
        lat_deg: 45.0,
        lon_deg: 400.0,
        alt_m: 400.0,
    });
    let e = checked_gps(&g).unwrap_err();
    assert!(
        matches!(
            e,
            Error::OutOfRange {
                field: "gps.position.lon_deg",
                ..
            }
        ),
        "{e}"
    );
}

/// A driver's fix type with the quality a receiver reports.
struct ReceiverFix {
    fix_type: delaynav::FixType,
    satellites: u8,
}

impl delaynav::GpsFix<f64> for ReceiverFix {
    fn time_us(&self) -> u64 {
        1_000
    }
    fn position(&self) -> GpsPosition<f64> {
        GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0))
    }
    fn velocity_ned_m_s(&self) -> Vector3<f64> {
        Vector3::zeros()
    }
    fn fix_type(&self) -> Option<delaynav::FixType> {
        Some(self.fix_type)
    }
    fn satellites(&self) -> Option<u8> {
        Some(self.satellites)
    }
}

#[test]
fn fix_quality_defaults_to_not_reported_and_no_fix_is_refused_and_counted() {
    use delaynav::{Ekf16, Ekf16Config, FixType, GpsFix, Navigator};
    let plain = Gps::<f64> {
        t_us: 5,
        position: GpsPosition::Ned(Vector3::zeros()),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    };
    assert_eq!((plain.fix_type(), plain.satellites()), (None, None));

    let fix = |fix_type| ReceiverFix {
        fix_type,
        satellites: 9,
    };
    assert_eq!(fix(FixType::Fix3d).satellites(), Some(9));
    assert!(checked_gps(&fix(FixType::Fix3d)).is_ok());
    assert!(checked_gps(&fix(FixType::Fix2d)).is_ok());
    assert_eq!(
        checked_gps(&fix(FixType::NoFix)),
        Err(Error::OutOfRange {
            field: "gps.fix_type",
            reason: "the receiver reports no fix",
        })
    );
    let mut ekf = Ekf16::<f64>::new(Ekf16Config::default()).unwrap();
    assert!(ekf.push_gps(&fix(FixType::NoFix)).is_err());
    assert_eq!(ekf.refusals().gps_invalid, 1);
}

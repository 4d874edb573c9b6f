//! A calibrated IMU: the initial bias estimate and its uncertainty in
//! `Ekf16Config` set the bias states, their covariance and the initial tilt
//! (the accelerometer mean is corrected before roll and pitch are taken).

use delaynav::ekf16::state::{ACCEL_BIAS, GYRO_BIAS};
use delaynav::geo::euler_from_quaternion;
use delaynav::nalgebra::Vector3;
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Gps, GpsPosition, Imu, Navigator,
    Scalar,
};

const ACCEL_BIAS_M_S2: [f64; 3] = [0.3, -0.2, 0.1];
const GYRO_BIAS_RAD_S: [f64; 3] = [0.01, -0.02, 0.005];

fn v<T: Scalar>(a: [f64; 3]) -> Vector3<T> {
    Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]))
}

/// Level and at rest with biased sensors, then one fix.
fn align<T: Scalar, N: Navigator<T>>(nav: &mut N) {
    let accel = v::<T>([0.0, 0.0, -9.80665]) + v::<T>(ACCEL_BIAS_M_S2);
    for k in 1..=100u64 {
        nav.push_imu(&Imu {
            t_us: k * 1000,
            gyro_rad_s: v::<T>(GYRO_BIAS_RAD_S),
            accel_m_s2: accel,
        })
        .unwrap();
    }
    nav.push_gps(&Gps {
        t_us: 100_500,
        position: GpsPosition::Ned(Vector3::zeros()),
        velocity_ned_m_s: Vector3::zeros(),
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    })
    .unwrap();
}

fn calibrated<T: Scalar>() -> Ekf16Config<T> {
    Ekf16Config {
        initial_accel_bias_m_s2: v(ACCEL_BIAS_M_S2),
        initial_accel_bias_std_m_s2: T::lit(0.01),
        initial_gyro_bias_rad_s: v(GYRO_BIAS_RAD_S),
        initial_gyro_bias_std_rad_s: T::lit(1e-3),
        ..Ekf16Config::default()
    }
}

fn tilt_rad<T: Scalar, N: Navigator<T>>(nav: &N) -> f64 {
    let e = euler_from_quaternion(nav.estimate().unwrap().attitude.quaternion());
    e.x.as_f64().hypot(e.y.as_f64())
}

fn starts_from_the_calibration<T: Scalar>() {
    let mut ekf = Ekf16::<T>::new(calibrated()).unwrap();
    align(&mut ekf);
    let state = ekf.nav_state().unwrap();
    assert_eq!(state.accel_bias_m_s2, v::<T>(ACCEL_BIAS_M_S2));
    assert_eq!(state.gyro_bias_rad_s, v::<T>(GYRO_BIAS_RAD_S));
    let p = ekf.covariance();
    for i in 0..3 {
        let ab = p[(ACCEL_BIAS + i, ACCEL_BIAS + i)].as_f64();
        let gb = p[(GYRO_BIAS + i, GYRO_BIAS + i)].as_f64();
        assert!(
            (ab.sqrt() / 0.01 - 1.0).abs() < 1e-3,
            "accel bias std {}",
            ab.sqrt()
        );
        assert!(
            (gb.sqrt() / 1e-3 - 1.0).abs() < 1e-3,
            "gyro bias std {}",
            gb.sqrt()
        );
    }
    // The bias-corrected accelerometer says level.
    let calibrated_tilt = tilt_rad(&ekf);
    assert!(calibrated_tilt < 1e-4, "{calibrated_tilt} rad");

    // Without the calibration the accelerometer bias tilts the start by
    // about |b_xy| / g = 0.037 rad, and the bias states start at zero.
    let mut plain = Ekf16::<T>::new(Ekf16Config::default()).unwrap();
    align(&mut plain);
    let plain_tilt = tilt_rad(&plain);
    assert!(plain_tilt > 0.03, "{plain_tilt} rad");
    assert_eq!(plain.nav_state().unwrap().accel_bias_m_s2, Vector3::zeros());

    // The augmented filter starts from the same core.
    let mut aekf = AugmentedEkf17::<T>::new(AugmentedEkf17Config::with_nav(calibrated())).unwrap();
    align(&mut aekf);
    assert!(tilt_rad(&aekf) < 1e-4);
}

#[test]
fn the_filters_start_from_the_calibrated_biases() {
    starts_from_the_calibration::<f32>();
    starts_from_the_calibration::<f64>();
}

#[test]
fn a_bias_beyond_the_plausible_sample_is_refused() {
    let c = Ekf16Config::<f64> {
        initial_accel_bias_m_s2: Vector3::new(0.0, 500.0, 0.0),
        ..Ekf16Config::default()
    };
    assert_eq!(
        c.validate().unwrap_err().to_string(),
        "invalid configuration: `initial_accel_bias_m_s2.y` = 500, must lie in [-400, 400]"
    );
    let c = Ekf16Config::<f64> {
        initial_gyro_bias_rad_s: Vector3::new(f64::NAN, 0.0, 0.0),
        ..Ekf16Config::default()
    };
    assert!(c.validate().is_err());
}

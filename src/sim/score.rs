//! Attitude errors split the way a navigator's user reads them.
//!
//! Euler roll and pitch errors inflate at high attitude (a yaw error leaks
//! into them through the ZYX sequence), so the suites score attitude by the
//! rotation vector of the error instead:
//!
//! `dR = R(q_est) R(q_true)^T` (navigation frame, NED), `phi = log(dR)`,
//! the rotation vector of the error, radians. Its horizontal part
//! `|(phi_N, phi_E)|` is the **tilt error** (how far the estimated vertical
//! is from the true one); its down component `|phi_D|` is the **heading
//! error**. Both are invariant to the vehicle's own attitude.

use nalgebra::{UnitQuaternion, Vector3};

/// Rotation vector of the attitude error `R(estimate) R(truth)^T`, NED, rad.
pub fn attitude_error_ned_rad(
    estimate: &UnitQuaternion<f64>,
    truth: &UnitQuaternion<f64>,
) -> Vector3<f64> {
    (estimate * truth.inverse()).scaled_axis()
}

/// Tilt and heading errors, radians: the horizontal norm and the absolute
/// down component of [`attitude_error_ned_rad`].
pub fn tilt_heading_error_rad(
    estimate: &UnitQuaternion<f64>,
    truth: &UnitQuaternion<f64>,
) -> (f64, f64) {
    let phi = attitude_error_ned_rad(estimate, truth);
    (phi.x.hypot(phi.y), phi.z.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tilt_and_heading_separate_at_any_attitude() {
        let truth = UnitQuaternion::from_euler_angles(0.7, -0.5, 2.0);
        // An error of 0.01 rad about north and 0.03 rad about down, applied in NED.
        let error = UnitQuaternion::from_scaled_axis(Vector3::new(0.01, 0.0, 0.03));
        let (tilt, heading) = tilt_heading_error_rad(&(error * truth), &truth);
        assert!((tilt - 0.01).abs() < 1e-12, "tilt {tilt}");
        assert!((heading - 0.03).abs() < 1e-12, "heading {heading}");
        let (tilt, heading) = tilt_heading_error_rad(&truth, &truth);
        assert!(tilt < 1e-15 && heading < 1e-15);
    }
}

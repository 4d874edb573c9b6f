//! The flight window of a log, found from its own samples: from take-off to
//! landing, cut before an impact.
//!
//! A log holds more than the flight: minutes on the ground before arming,
//! and often a crash at the end, where the specific force reaches tens of g
//! and no navigation filter (nor the onboard reference) is meaningful.
//! Scoring those spans scores the log, not the estimator. The window is
//! found from the samples every layout has, so a `.bin`, a `.ulg` and a CSV
//! export of the same log give the same window:
//!
//! - **moving**: a GPS fix with ground speed `√(v_n² + v_e²) > 1 m/s` or
//!   vertical speed `|v_d| > 0.5 m/s` (a vehicle on the ground reads below
//!   0.3 m/s on the shared logs);
//! - **take-off** `t_from`: the first moving fix;
//! - **landing** `t_land`: the last moving fix;
//! - **impact** `t_impact`: the first IMU sample after take-off whose
//!   specific force exceeds [`IMPACT_SPECIFIC_FORCE_M_S2`] (4 g; a
//!   multicopter in flight stays below 2-3 g);
//! - the window is `[t_from, min(t_land, t_impact − IMPACT_MARGIN_US)]`.
//!
//! Without a moving fix (a vehicle that never left the ground) there is no
//! window. Times are the log's clock, microseconds.

use super::SensorEvent;
use crate::scalar::Scalar;
use crate::sensors::Imu;

/// Ground speed above which a fix counts as moving, m/s.
pub const MOVING_GROUND_SPEED_M_S: f64 = 1.0;
/// Vertical speed above which a fix counts as moving, m/s.
pub const MOVING_VERTICAL_SPEED_M_S: f64 = 0.5;
/// Specific force that marks an impact, m/s² (4 g).
pub const IMPACT_SPECIFIC_FORCE_M_S2: f64 = 4.0 * 9.806_65;
/// Time cut before an impact, microseconds: the seconds before a crash are
/// already out of control (tumbling, a motor lost).
pub const IMPACT_MARGIN_US: u64 = 2_000_000;

/// The flight found in a log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlightWindow {
    /// Start: the first moving fix, µs.
    pub from_us: u64,
    /// End: the landing, or [`IMPACT_MARGIN_US`] before the impact, µs.
    pub to_us: u64,
    /// The last moving fix, µs.
    pub landing_us: u64,
    /// The first impact after take-off, µs, if any.
    pub impact_us: Option<u64>,
}

fn specific_force<T: Scalar>(imu: &Imu<T>) -> f64 {
    imu.accel_m_s2.map(T::as_f64).norm()
}

/// The flight window of a time-ordered stream (see the module docs), or
/// `None` when no fix shows the vehicle moving.
pub fn flight_window<T: Scalar>(
    events: impl IntoIterator<Item = SensorEvent<T>>,
) -> Option<FlightWindow> {
    let mut take_off = None;
    let mut landing = None;
    let mut impact = None;
    for event in events {
        match event {
            SensorEvent::Gps(fix) => {
                let v = fix.velocity_ned_m_s.map(T::as_f64);
                let moving = v.x.hypot(v.y) > MOVING_GROUND_SPEED_M_S
                    || v.z.abs() > MOVING_VERTICAL_SPEED_M_S;
                if moving && impact.is_none() {
                    take_off.get_or_insert(fix.t_us);
                    landing = Some(fix.t_us);
                }
            }
            SensorEvent::Imu(imu) => {
                if take_off.is_some()
                    && impact.is_none()
                    && specific_force(&imu) > IMPACT_SPECIFIC_FORCE_M_S2
                {
                    impact = Some(imu.t_us);
                }
            }
            SensorEvent::Mag(_) => {}
        }
    }
    let (from_us, landing_us) = (take_off?, landing?);
    let to_us = impact.map_or(landing_us, |t| {
        landing_us.min(t.saturating_sub(IMPACT_MARGIN_US))
    });
    Some(FlightWindow {
        from_us,
        to_us: to_us.max(from_us),
        landing_us,
        impact_us: impact,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::{Gps, GpsPosition};
    use nalgebra::Vector3;

    fn fix(t_s: f64, speed: f64) -> SensorEvent<f64> {
        SensorEvent::Gps(Gps {
            t_us: (t_s * 1e6) as u64,
            position: GpsPosition::Ned(Vector3::zeros()),
            velocity_ned_m_s: Vector3::new(speed, 0.0, 0.0),
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        })
    }

    fn imu(t_s: f64, accel: f64) -> SensorEvent<f64> {
        SensorEvent::Imu(Imu {
            t_us: (t_s * 1e6) as u64,
            gyro_rad_s: Vector3::zeros(),
            accel_m_s2: Vector3::new(0.0, 0.0, -accel),
        })
    }

    #[test]
    fn window_spans_the_moving_fixes() {
        let events = [
            fix(1.0, 0.1),
            imu(1.5, 60.0), // a knock on the ground before take-off: not an impact
            fix(2.0, 3.0),
            imu(3.0, 9.8),
            fix(4.0, 5.0),
            fix(5.0, 0.2),
        ];
        let w = flight_window(events).unwrap();
        assert_eq!((w.from_us, w.to_us), (2_000_000, 4_000_000));
        assert_eq!(w.impact_us, None);
    }

    #[test]
    fn window_is_cut_before_an_impact() {
        let events = [
            fix(10.0, 3.0),
            imu(20.0, 9.8),
            fix(30.0, 3.0),
            imu(31.0, 50.0),
            fix(32.0, 8.0), // tumbling after the impact: not flight
        ];
        let w = flight_window(events).unwrap();
        assert_eq!(w.from_us, 10_000_000);
        assert_eq!(w.impact_us, Some(31_000_000));
        assert_eq!(w.to_us, 29_000_000);
        assert_eq!(w.landing_us, 30_000_000);
    }

    #[test]
    fn no_window_without_motion() {
        assert_eq!(flight_window([fix(1.0, 0.2), imu(2.0, 9.8)]), None);
        assert_eq!(flight_window(Vec::<SensorEvent<f32>>::new()), None);
    }
}

//! The flight window of a log, found from its own samples: from take-off to
//! landing, cut before a loss of control and before an impact.
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
//! - **loss of control** `t_loss`, only when there is an impact: the end of
//!   the last steady stretch before it. The angular rate is smoothed,
//!   `ω̄_k = ω̄_{k−1} + (Δt / τ) (ω_k − ω̄_{k−1})` with `τ =`
//!   [`RATE_SMOOTHING_US`] (0.1 s; `Δt / τ` at most 1), which averages out
//!   vibration; a sample is *steady* when `|ω̄| <` [`STEADY_RATE_RAD_S`]
//!   (0.5 rad/s, 29 °/s) and the latest fix does not show the vehicle
//!   falling (`v_d <` [`FALLING_SPEED_M_S`], 1 m/s down: a vehicle that
//!   stopped turning while it drops is not back in control; log171 levels
//!   out for 2.2 s at 234 s while it falls at up to 1.9 m/s), and `t_loss`
//!   is the last steady sample of a run
//!   of steady samples lasting at least [`STEADY_SPAN_US`] (2 s). From there
//!   to the impact the vehicle never held still for 2 s: the excursion that
//!   ended in the crash (on log171 a roll to 40° at 229 s, the ground
//!   speed from 0.7 to 5.5 m/s within a second, a fall; the 4 g impact at
//!   239 s). A flight's own manoeuvres are excursions too (log171 rolls to
//!   41° and turns at 3.4 rad/s at 127 s), so no threshold on the
//!   excursion alone tells them from a crash: the impact does, and the
//!   cut goes back to where the vehicle last held still;
//! - the window is `[t_from, min(t_land, t_impact − IMPACT_MARGIN_US, t_loss)]`.
//!
//! Without a moving fix (a vehicle that never left the ground) there is no
//! window. Times are the log's clock, microseconds.

use super::SensorEvent;
use crate::scalar::Scalar;
use crate::sensors::Imu;
use nalgebra::Vector3;

/// Ground speed above which a fix counts as moving, m/s.
pub const MOVING_GROUND_SPEED_M_S: f64 = 1.0;
/// Vertical speed above which a fix counts as moving, m/s.
pub const MOVING_VERTICAL_SPEED_M_S: f64 = 0.5;
/// Specific force that marks an impact, m/s² (4 g).
pub const IMPACT_SPECIFIC_FORCE_M_S2: f64 = 4.0 * 9.806_65;
/// Time cut before an impact, microseconds: the seconds before a crash are
/// already out of control (tumbling, a motor lost).
pub const IMPACT_MARGIN_US: u64 = 2_000_000;
/// Time constant of the angular rate's smoothing for the steady test, µs.
pub const RATE_SMOOTHING_US: u64 = 100_000;
/// Smoothed angular rate below which the vehicle is steady, rad/s.
pub const STEADY_RATE_RAD_S: f64 = 0.5;
/// Downward speed of the latest fix at or above which the vehicle is not
/// steady (falling), m/s.
pub const FALLING_SPEED_M_S: f64 = 1.0;
/// How long the vehicle must be steady for a steady stretch, µs.
pub const STEADY_SPAN_US: u64 = 2_000_000;

/// The flight found in a log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlightWindow {
    /// Start: the first moving fix, µs.
    pub from_us: u64,
    /// End: the landing, or the loss of control, or [`IMPACT_MARGIN_US`]
    /// before the impact, whichever is first, µs.
    pub to_us: u64,
    /// The last moving fix, µs.
    pub landing_us: u64,
    /// The first impact after take-off, µs, if any.
    pub impact_us: Option<u64>,
    /// With an impact: the end of the last steady stretch before it (see
    /// the module docs), µs, if the flight had one.
    pub loss_of_control_us: Option<u64>,
}

/// The steady test of the module docs, one IMU sample at a time.
#[derive(Debug, Clone, Copy, Default)]
struct Steadiness {
    /// Smoothed angular rate, rad/s, and the time of its last sample.
    rate: Option<(Vector3<f64>, u64)>,
    /// Start of the current run of steady samples.
    run_from_us: Option<u64>,
    /// Last steady sample of a run lasting [`STEADY_SPAN_US`].
    last_steady_us: Option<u64>,
}

impl Steadiness {
    fn push(&mut self, t_us: u64, gyro: Vector3<f64>, falling: bool) {
        let smoothed = match self.rate {
            Some((previous, t0)) if t_us > t0 => {
                let gain = ((t_us - t0) as f64 / RATE_SMOOTHING_US as f64).min(1.0);
                previous + (gyro - previous) * gain
            }
            Some((previous, _)) => previous,
            None => gyro,
        };
        self.rate = Some((smoothed, t_us));
        if smoothed.norm() < STEADY_RATE_RAD_S && !falling {
            let from = *self.run_from_us.get_or_insert(t_us);
            if t_us - from >= STEADY_SPAN_US {
                self.last_steady_us = Some(t_us);
            }
        } else {
            self.run_from_us = None;
        }
    }
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
    let mut steadiness = Steadiness::default();
    let mut falling = false;
    for event in events {
        match event {
            SensorEvent::Gps(fix) => {
                let v = fix.velocity_ned_m_s.map(T::as_f64);
                let moving = v.x.hypot(v.y) > MOVING_GROUND_SPEED_M_S
                    || v.z.abs() > MOVING_VERTICAL_SPEED_M_S;
                falling = v.z >= FALLING_SPEED_M_S;
                if moving && impact.is_none() {
                    take_off.get_or_insert(fix.t_us);
                    landing = Some(fix.t_us);
                }
            }
            SensorEvent::Imu(imu) => {
                if take_off.is_some() && impact.is_none() {
                    if specific_force(&imu) > IMPACT_SPECIFIC_FORCE_M_S2 {
                        impact = Some(imu.t_us);
                    } else {
                        steadiness.push(imu.t_us, imu.gyro_rad_s.map(T::as_f64), falling);
                    }
                }
            }
            SensorEvent::Mag(_) => {}
        }
    }
    let (from_us, landing_us) = (take_off?, landing?);
    let loss_of_control_us = impact.and(steadiness.last_steady_us);
    let to_us = impact.map_or(landing_us, |t| {
        let cut = landing_us.min(t.saturating_sub(IMPACT_MARGIN_US));
        loss_of_control_us.map_or(cut, |loss| cut.min(loss))
    });
    Some(FlightWindow {
        from_us,
        to_us: to_us.max(from_us),
        landing_us,
        impact_us: impact,
        loss_of_control_us,
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

    /// IMU samples at 50 Hz from `from_s` to `to_s` turning at `rate` rad/s.
    fn turning(from_s: f64, to_s: f64, rate: f64) -> impl Iterator<Item = SensorEvent<f64>> {
        let n = ((to_s - from_s) * 50.0).round() as u64;
        (0..n).map(move |k| {
            SensorEvent::Imu(Imu {
                t_us: (from_s * 1e6) as u64 + k * 20_000,
                gyro_rad_s: Vector3::new(rate, 0.0, 0.0),
                accel_m_s2: Vector3::new(0.0, 0.0, -9.8),
            })
        })
    }

    fn flight(parts: Vec<Vec<SensorEvent<f64>>>) -> Vec<SensorEvent<f64>> {
        let mut events: Vec<_> = parts.into_iter().flatten().collect();
        events.sort_by_key(|e| e.time_us());
        events
    }

    #[test]
    fn window_ends_where_the_excursion_before_an_impact_begins() {
        let events = flight(vec![
            vec![fix(10.0, 3.0), fix(24.0, 3.0)],
            turning(10.0, 20.0, 0.05).collect(),
            turning(20.0, 25.0, 2.0).collect(), // tumbling: never steady again
            vec![imu(25.0, 50.0)],
        ]);
        let w = flight_window(events).unwrap();
        assert_eq!(w.impact_us, Some(25_000_000));
        // The first tumbling sample smooths to 0.05 + 0.2 (2 - 0.05) = 0.44 rad/s,
        // still steady; the second to 0.83: the last steady sample is 20.0 s.
        assert_eq!(w.loss_of_control_us, Some(20_000_000));
        assert_eq!(w.to_us, 20_000_000);
    }

    #[test]
    fn a_vehicle_falling_without_turning_is_not_steady() {
        let down = |t_s: f64, v_d: f64| match fix(t_s, 0.0) {
            SensorEvent::Gps(mut g) => {
                g.velocity_ned_m_s.z = v_d;
                SensorEvent::Gps(g)
            }
            e => e,
        };
        let events = flight(vec![
            vec![fix(10.0, 3.0), down(22.0, 1.5), down(29.5, 1.5)],
            turning(10.0, 20.0, 0.05).collect(),
            turning(20.0, 22.0, 3.0).collect(), // a tumble,
            turning(22.0, 30.0, 0.1).collect(), // then level but falling
            vec![imu(30.0, 50.0)],
        ]);
        let w = flight_window(events).unwrap();
        // 3 rad/s smooths to 0.64 rad/s at its first sample: the last steady one is before.
        assert_eq!(w.loss_of_control_us, Some(19_980_000));
        assert_eq!(w.to_us, 19_980_000);
    }

    #[test]
    fn a_manoeuvre_followed_by_a_steady_stretch_is_flight() {
        let events = flight(vec![
            vec![fix(10.0, 3.0), fix(29.5, 3.0)],
            turning(10.0, 20.0, 0.05).collect(),
            turning(20.0, 22.0, 3.0).collect(), // a fast turn
            turning(22.0, 30.0, 0.1).collect(), // steady again until the impact
            vec![imu(30.0, 50.0)],
        ]);
        let w = flight_window(events).unwrap();
        assert!(w.loss_of_control_us.unwrap() > 29_900_000);
        assert_eq!(w.to_us, 28_000_000); // 2 s before the impact
        // Without an impact nothing is cut, whatever the rates.
        let events = flight(vec![
            vec![fix(10.0, 3.0), fix(40.0, 3.0)],
            turning(10.0, 20.0, 0.05).collect(),
            turning(20.0, 45.0, 3.0).collect(),
        ]);
        let w = flight_window(events).unwrap();
        assert_eq!((w.to_us, w.loss_of_control_us), (40_000_000, None));
    }

    #[test]
    fn no_window_without_motion() {
        assert_eq!(flight_window([fix(1.0, 0.2), imu(2.0, 9.8)]), None);
        assert_eq!(flight_window(Vec::<SensorEvent<f32>>::new()), None);
    }
}

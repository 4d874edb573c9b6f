//! The protection levels of a replay against the log's onboard solution.
//!
//! At every reference sample [`replay`](super::replay) scores, the
//! estimator's [`Integrity`] (its protection levels and validity flags, read
//! through the [`Navigator`](crate::Navigator) trait) is set beside the
//! difference between the aligned estimate and the onboard solution:
//!
//! - attitude: the rotation `δ = q_ref ⊗ q_est⁻¹` (navigation frame, NED)
//!   as a rotation vector `θ` (axis times angle, the angle in `[0, π]`);
//!   tilt is `hypot(θ_N, θ_E)`, heading `|θ_D|`, degrees;
//! - velocity: the norm of the NED difference, m/s (when the reference has
//!   velocity).
//!
//! Per quantity it keeps the share of epochs the estimator called valid, the
//! median level, and, of the valid epochs, the share whose difference from
//! the onboard solution exceeds the level. The onboard solution is not the
//! truth: an exceedance is an epoch where the two disagree by more than the
//! level, the onboard estimate's own error included, so it bounds the
//! estimator's misleading share from above only when the onboard error is
//! small against the level. The logs carry no reference position: the
//! horizontal and vertical levels have a valid share and a median, no
//! exceedance.

use crate::integrity::Integrity;
use crate::scalar::Scalar;
use nalgebra::{UnitQuaternion, Vector3};

/// One quantity's levels over the scored epochs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LevelSummary {
    /// Share of the epochs with the quantity valid (its level within its alert limit).
    pub valid_share: f64,
    /// Median level over the epochs (infinite levels included), in the
    /// quantity's unit; `None` without an epoch.
    pub median_level: Option<f64>,
    /// Of the valid epochs, the share whose difference from the onboard
    /// solution exceeds the level; `None` without a valid epoch or a
    /// reference for the quantity.
    pub exceeded_share: Option<f64>,
}

/// The levels of one replay (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayIntegrity {
    /// Reference epochs scored.
    pub epochs: u64,
    /// Share of the epochs with tilt, heading, horizontal position and
    /// velocity all valid.
    pub availability: f64,
    /// Tilt, degrees.
    pub tilt: LevelSummary,
    /// Heading, degrees.
    pub heading: LevelSummary,
    /// Horizontal position, m (no exceedance: no reference position).
    pub horizontal: LevelSummary,
    /// Vertical position, m (no exceedance).
    pub vertical: LevelSummary,
    /// Velocity, m/s.
    pub velocity: LevelSummary,
}

/// One quantity's running counts.
#[derive(Default)]
struct Tally {
    valid: u64,
    compared: u64,
    exceeded: u64,
    levels: Vec<f64>,
}

impl Tally {
    fn add(&mut self, level: f64, valid: bool, error: Option<f64>) {
        self.levels.push(level);
        if valid {
            self.valid += 1;
            if let Some(e) = error {
                self.compared += 1;
                self.exceeded += u64::from(e > level);
            }
        }
    }

    fn summary(&mut self, epochs: u64) -> LevelSummary {
        let share = |n: u64, of: u64| n as f64 / of as f64;
        self.levels.sort_by(f64::total_cmp);
        let median = match self.levels.len() {
            0 => None,
            n if n % 2 == 1 => Some(self.levels[n / 2]),
            n => Some((self.levels[n / 2 - 1] + self.levels[n / 2]) / 2.0),
        };
        LevelSummary {
            valid_share: if epochs == 0 {
                0.0
            } else {
                share(self.valid, epochs)
            },
            median_level: median,
            exceeded_share: (self.compared > 0).then(|| share(self.exceeded, self.compared)),
        }
    }
}

/// The running counts of a replay.
#[derive(Default)]
pub(super) struct LevelTally {
    epochs: u64,
    available: u64,
    tilt: Tally,
    heading: Tally,
    horizontal: Tally,
    vertical: Tally,
    velocity: Tally,
}

/// Tilt and heading differences, degrees, of `estimate` from `reference`
/// (both body to NED).
fn attitude_difference_deg(
    estimate: &UnitQuaternion<f64>,
    reference: &UnitQuaternion<f64>,
) -> (f64, f64) {
    let theta: Vector3<f64> = (reference * estimate.inverse()).scaled_axis();
    (
        theta.x.hypot(theta.y).to_degrees(),
        theta.z.abs().to_degrees(),
    )
}

impl LevelTally {
    /// One scored epoch: the estimator's integrity, the aligned estimate and
    /// the reference attitude, and the velocity difference when the
    /// reference has one.
    pub(super) fn add<T: Scalar>(
        &mut self,
        integrity: &Integrity<T>,
        estimate: &UnitQuaternion<f64>,
        reference: &UnitQuaternion<f64>,
        velocity_error_m_s: Option<f64>,
    ) {
        let l = &integrity.levels;
        let (tilt, heading) = attitude_difference_deg(estimate, reference);
        self.epochs += 1;
        self.available += u64::from(
            integrity.tilt_valid
                && integrity.heading_valid
                && integrity.horizontal_valid
                && integrity.velocity_valid,
        );
        self.tilt
            .add(l.tilt_deg.as_f64(), integrity.tilt_valid, Some(tilt));
        self.heading.add(
            l.heading_deg.as_f64(),
            integrity.heading_valid,
            Some(heading),
        );
        self.horizontal
            .add(l.horizontal_m.as_f64(), integrity.horizontal_valid, None);
        self.vertical
            .add(l.vertical_m.as_f64(), integrity.vertical_valid, None);
        self.velocity.add(
            l.velocity_m_s.as_f64(),
            integrity.velocity_valid,
            velocity_error_m_s,
        );
    }

    /// The summary; `None` without a scored epoch.
    pub(super) fn summary(mut self) -> Option<ReplayIntegrity> {
        let n = self.epochs;
        (n > 0).then(|| ReplayIntegrity {
            epochs: n,
            availability: self.available as f64 / n as f64,
            tilt: self.tilt.summary(n),
            heading: self.heading.summary(n),
            horizontal: self.horizontal.summary(n),
            vertical: self.vertical.summary(n),
            velocity: self.velocity.summary(n),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::quaternion_from_euler;
    use crate::integrity::ProtectionLevels;

    fn integrity(tilt_deg: f64, heading_deg: f64, valid: bool) -> Integrity<f64> {
        Integrity {
            levels: ProtectionLevels {
                tilt_deg,
                heading_deg,
                horizontal_m: 3.0,
                vertical_m: 5.0,
                velocity_m_s: 0.5,
                delay_s: 0.02,
            },
            tilt_valid: valid,
            heading_valid: valid,
            horizontal_valid: valid,
            vertical_valid: valid,
            velocity_valid: valid,
            delay_valid: valid,
            resets: 0,
        }
    }

    #[test]
    fn attitude_differences_split_into_tilt_and_heading() {
        let reference = quaternion_from_euler(0.1, -0.2, 1.0);
        let yawed = quaternion_from_euler(0.0, 0.0, 3f64.to_radians()) * reference;
        let (tilt, heading) = attitude_difference_deg(&yawed, &reference);
        assert!(
            tilt < 1e-9 && (heading - 3.0).abs() < 1e-9,
            "{tilt} {heading}"
        );
        let tilted = quaternion_from_euler(2f64.to_radians(), 0.0, 0.0) * reference;
        let (tilt, heading) = attitude_difference_deg(&tilted, &reference);
        assert!(
            (tilt - 2.0).abs() < 1e-9 && heading < 1e-9,
            "{tilt} {heading}"
        );
    }

    #[test]
    fn exceedance_counts_valid_epochs_whose_difference_is_above_the_level() {
        let reference = quaternion_from_euler(0.0, 0.0, 0.5);
        let off = quaternion_from_euler(0.0, 0.0, 0.5 + 4f64.to_radians());
        let mut tally = LevelTally::default();
        // Heading 4 deg off: above a 3 deg level, below a 5 deg one; an
        // invalid epoch is never an exceedance.
        tally.add(&integrity(1.0, 3.0, true), &off, &reference, Some(0.1));
        tally.add(&integrity(1.0, 5.0, true), &off, &reference, Some(0.9));
        tally.add(&integrity(1.0, 1.0, false), &off, &reference, Some(9.0));
        let s = tally.summary().unwrap();
        assert_eq!(s.epochs, 3);
        assert!((s.availability - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(s.heading.exceeded_share, Some(0.5));
        assert_eq!(s.heading.median_level, Some(3.0));
        assert_eq!(s.tilt.exceeded_share, Some(0.0));
        assert_eq!(s.velocity.exceeded_share, Some(0.5));
        assert_eq!(s.horizontal.exceeded_share, None);
        assert!((s.horizontal.valid_share - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(LevelTally::default().summary(), None);
    }
}

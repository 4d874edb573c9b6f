//! The magnetometer queue: samples wait until the horizon reaches their
//! time, a full queue averages neighbours, and the horizon EKF fuses what
//! it reached (module docs of `nav`, "Magnetometer").

use super::refusals::bump;
use super::{DelayCompensatedNav, MAG_QUEUE};
use crate::delay::ring::Ring;
use crate::estimate::{MagOutcome, Navigator};
use crate::scalar::{Scalar, zeros_const};
use crate::sensors::Mag;
use nalgebra::Vector3;

/// A magnetometer sample waiting for the horizon: the mean field of
/// `samples` raw samples at their mean time (one sample until a full queue
/// averages neighbours: module docs).
#[derive(Debug, Clone, Copy)]
pub(super) struct QueuedMag<T: Scalar> {
    t_us: u64,
    field_body: Vector3<T>,
    samples: u16,
}

impl<T: Scalar> QueuedMag<T> {
    /// An empty entry (a blank queue's filling).
    pub(super) const BLANK: Self = Self {
        t_us: 0,
        field_body: zeros_const(),
        samples: 0,
    };

    pub(super) fn new(m: Mag<T>) -> Self {
        Self {
            t_us: m.t_us,
            field_body: m.field_body,
            samples: 1,
        }
    }

    /// The mean of `self` and a `newer` one, each weighed by its samples.
    fn averaged_with(self, newer: Self) -> Self {
        // n >= 1 even for blank entries (never averaged), so that no
        // division can fail or give NaN. The offset is at most `dt_us` (in
        // u128 the product cannot overflow), so the sum stays within u64.
        let n = (u32::from(self.samples) + u32::from(newer.samples)).max(1);
        let dt_us = newer.t_us.saturating_sub(self.t_us);
        let share = T::from_f32_exact(f32::from(newer.samples)) / T::from_f32_exact(n as f32);
        let offset_us = u128::from(dt_us) * u128::from(newer.samples) / u128::from(n);
        Self {
            t_us: self.t_us.saturating_add(offset_us as u64),
            field_body: self.field_body + (newer.field_body - self.field_body) * share,
            samples: u16::try_from(n).unwrap_or(u16::MAX),
        }
    }
}

/// Averages the waiting samples of a full queue in pairs, oldest first (the
/// oldest alone when their number is odd, so that the newest is in a pair);
/// returns how many samples were averaged into another.
fn average_pairs<T: Scalar, const N: usize>(ring: &mut Ring<QueuedMag<T>, N>) -> u32 {
    let len = ring.len();
    let mut averaged = 0u32;
    let mut older = None;
    for k in 0..len {
        let Some(m) = ring.pop_oldest() else {
            break;
        };
        if (len - k).is_multiple_of(2) {
            older = Some(m);
            continue;
        }
        ring.push(match older.take() {
            Some(o) => {
                averaged = averaged.saturating_add(1);
                o.averaged_with(m)
            }
            None => m,
        });
    }
    averaged
}

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// Queues an accepted sample (module docs of `nav`, "Magnetometer"):
    /// averaged into the newest queued one when closer to it than the
    /// queue's spacing, the queue thinned in pairs when full.
    pub(super) fn enqueue_mag(&mut self, m: Mag<T>) -> MagOutcome<T> {
        if self.mags.len() <= MAG_QUEUE / 4 {
            self.mag_spacing_us = 0;
        }
        let m = QueuedMag::new(m);
        if let Some(newest) = self.mags.get(0)
            && m.t_us < self.mag_newest_start_us.saturating_add(self.mag_spacing_us)
        {
            self.mags.replace_newest(newest.averaged_with(m));
            bump(&mut self.refusals.mag_averaged);
            return MagOutcome::Queued;
        }
        if self.mags.len() == MAG_QUEUE {
            let averaged = average_pairs(&mut self.mags);
            self.refusals.mag_averaged = self.refusals.mag_averaged.saturating_add(averaged);
            if let (Some(oldest), Some(newest)) = (self.mags.oldest(), self.mags.get(0)) {
                let gaps = (self.mags.len() as u64).saturating_sub(1).max(1);
                self.mag_spacing_us = newest.t_us.saturating_sub(oldest.t_us) / gaps;
            }
        }
        self.mags.push(m);
        self.mag_newest_start_us = m.t_us;
        MagOutcome::Queued
    }

    /// After the horizon EKF moved: the magnetometer samples it reached are
    /// fused at the next IMU sample ([`fuse_due_mags`](Self::fuse_due_mags)),
    /// not in the same call as the prediction (or a GPS fusion): the EKF does
    /// not move before then, so they are fused at the same state time, and
    /// no single call does a prediction, a GPS and a magnetometer fusion.
    /// Before initialization they go to the EKF at once (the alignment waits
    /// for them).
    pub(super) fn horizon_moved(&mut self) {
        if self.ekf.is_initialized() {
            self.mags_due = true;
        } else {
            self.drain_mags();
        }
    }

    /// Fuses the magnetometer samples the horizon EKF reached at its last
    /// move; true when there were some to look at.
    pub(super) fn fuse_due_mags(&mut self) -> bool {
        if !self.mags_due {
            return false;
        }
        self.mags_due = false;
        self.drain_mags();
        true
    }

    /// Fuses the queued magnetometer samples the horizon has reached.
    fn drain_mags(&mut self) {
        let Some(horizon) = self.ekf.time_us() else {
            return;
        };
        while let Some(m) = self.mags.oldest() {
            if m.t_us > horizon {
                break;
            }
            self.mags.pop_oldest();
            self.mag_at_horizon = true;
            // Refusals (gate, time) are counted by the EKF.
            let _ = self.ekf.push_mag(&Mag {
                t_us: m.t_us,
                field_body: m.field_body,
            });
        }
    }
}

#[cfg(test)]
mod queue_tests {
    use super::*;

    fn sample<T: Scalar>(t_us: u64, x: f64) -> QueuedMag<T> {
        QueuedMag::new(Mag {
            t_us,
            field_body: Vector3::new(T::lit(x), T::one(), T::zero()),
        })
    }

    /// A full queue of 5 samples (odd: the oldest stays alone) becomes 3,
    /// each the mean of its pair at the pair's mean time; a pair and a
    /// single sample average with weights 2 and 1.
    fn pairs_are_averaged<T: Scalar>() {
        let mut ring = Ring::<QueuedMag<T>, 5>::new(sample(0, 0.0));
        for k in 0..5u32 {
            ring.push(sample(100 * u64::from(k), f64::from(k)));
        }
        assert_eq!(average_pairs(&mut ring), 2);
        let kept: Vec<_> = (0..ring.len())
            .rev()
            .filter_map(|age| ring.get(age))
            .collect();
        assert_eq!(
            kept.iter().map(|m| m.t_us).collect::<Vec<_>>(),
            [0, 150, 350]
        );
        assert_eq!(
            kept.iter().map(|m| m.samples).collect::<Vec<_>>(),
            [1, 2, 2]
        );
        let x: Vec<f64> = kept.iter().map(|m| m.field_body.x.as_f64()).collect();
        assert_eq!(x, [0.0, 1.5, 3.5]);
        let three = kept[2].averaged_with(sample(500, 6.5));
        assert_eq!((three.t_us, three.samples), (400, 3));
        assert_eq!(three.field_body.x.as_f64(), 4.5);
        assert_eq!(three.field_body.y.as_f64(), 1.0);
    }

    tests_in_both_precisions!(pairs_are_averaged);
}

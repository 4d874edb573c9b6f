//! The navigator's counters: samples refused or gated out per sensor and
//! reason ([`NavRefusals`], the horizon filter's among them), and the work
//! done ([`NavWork`]).

use super::timeline::ClockRefusal;
use crate::ekf16::FilterRefusals;
use crate::error::Error;

/// Samples refused, dropped or gated out, per sensor and reason: the
/// navigator's input checks in the flat fields, the horizon filter's checks,
/// gates and resets in [`horizon`](Self::horizon).
///
/// The two levels count different events: a sample the navigator refuses
/// never reaches the horizon filter, and `horizon` counts what the filter did
/// with the samples it was given at the delayed horizon.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavRefusals {
    /// IMU samples with a non-finite value.
    pub imu_non_finite: u32,
    /// IMU samples above the EKF's plausible range.
    pub imu_out_of_range: u32,
    /// IMU samples duplicated or going back in time.
    pub imu_time: u32,
    /// IMU samples stamped more than `max_time_jump_us` ahead and not
    /// confirmed by the next sample.
    pub imu_ahead: u32,
    /// IMU gaps longer than the EKF's `max_imu_step_us` or than the
    /// history's longest step, `u32::MAX / HIST` µs (history restarted),
    /// and steps of 65,535 µs or more that made the history forget its
    /// oldest samples (a ninth within its span, `docs/nav.md`).
    pub imu_gap: u32,
    /// GPS fixes with a non-finite or implausible value.
    pub gps_invalid: u32,
    /// GPS fixes duplicated or going back in time.
    pub gps_time: u32,
    /// GPS fixes whose reported accuracy is not finite, not positive or
    /// above its bound (also counted in `gps_invalid`).
    pub gps_accuracy: u32,
    /// GPS fixes stamped more than `max_time_jump_us` after the newest IMU sample.
    pub gps_ahead: u32,
    /// GPS fixes whose position kind (geodetic or NED) differs from the first
    /// accepted fix's.
    pub gps_mixed_frames: u32,
    /// Magnetometer samples with a non-finite or zero field.
    pub mag_invalid: u32,
    /// Magnetometer samples duplicated or going back in time.
    pub mag_time: u32,
    /// Magnetometer samples stamped more than `max_time_jump_us` after the newest IMU sample.
    pub mag_ahead: u32,
    /// Magnetometer samples averaged into a neighbour because the queue was
    /// full (module docs): fused, at a lower rate.
    pub mag_averaged: u32,
    /// Horizon steps the EKF refused (e.g. a step longer than its maximum).
    pub horizon_refused: u32,
    /// Samples the delay loop refused.
    pub delay_loop_refused: u32,
    /// Horizon states the output predictor could not compare with the present, the horizon
    /// older than its ring's oldest entry (`src/nav/forward.rs`): the present went without
    /// those corrections.
    pub forward_corrections_missed: u32,
    /// The horizon filter's refusals, gates and GPS resets, over the
    /// navigator's whole life (the counters of horizon filters replaced at
    /// [`reset`](crate::nav::DelayCompensatedNav::reset) and alignment are kept).
    pub horizon: FilterRefusals,
}

impl NavRefusals {
    /// Nothing counted (the `const` of [`Default::default`]).
    pub(super) const ZERO: Self = Self {
        imu_non_finite: 0,
        imu_out_of_range: 0,
        imu_time: 0,
        imu_ahead: 0,
        imu_gap: 0,
        gps_invalid: 0,
        gps_time: 0,
        gps_accuracy: 0,
        gps_ahead: 0,
        gps_mixed_frames: 0,
        mag_invalid: 0,
        mag_time: 0,
        mag_ahead: 0,
        mag_averaged: 0,
        horizon_refused: 0,
        delay_loop_refused: 0,
        forward_corrections_missed: 0,
        horizon: FilterRefusals::ZERO,
    };
}

/// Work done so far, counted (the cost per sample must not grow with the delay).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavWork {
    /// IMU samples accepted.
    pub imu_samples: u64,
    /// Horizon EKF steps (one per filter period, or per IMU sample at the
    /// IMU rate).
    pub horizon_steps: u64,
    /// `process::propagate` calls of the output predictor.
    pub forward_propagations: u64,
    /// Stored samples combined by the Lagrange reads of the history.
    pub interpolation_taps: u64,
    /// Moves of the output ring's cursor.
    pub ring_cursor_moves: u64,
    /// Entries of the output ring stored before their stride was up, the vehicle turning
    /// fast (`src/nav/forward.rs`).
    pub ring_early_entries: u64,
    /// Products of the delay loop's sliding correlation.
    pub correlation_multiply_adds: u64,
}

pub(super) fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// A clock check's outcome with its refusal counted: `ahead` for a
/// timestamp too far ahead, `time` for a duplicate or one going back.
pub(super) fn counted(
    check: Result<(), (ClockRefusal, Error)>,
    ahead: &mut u32,
    time: &mut u32,
) -> Result<(), Error> {
    check.map_err(|(why, e)| {
        bump(if why == ClockRefusal::Ahead {
            ahead
        } else {
            time
        });
        e
    })
}

//! What the navigator can vouch for: a [`Health`] value beside every estimate.
//!
//! [`DelayCompensatedNav::health`](super::DelayCompensatedNav::health) (and
//! [`estimate_with_health`](super::DelayCompensatedNav::estimate_with_health))
//! reports, at the present time:
//!
//! - **validity per quantity.** Tilt and heading need the alignment done
//!   ([`AlignmentState::Aligned`]); heading also a magnetometer update fused
//!   at the horizon within [`HEADING_STALE_US`]. Velocity and position need a
//!   fix with their own block (velocity, position) fused within [`GPS_STALE_US`]
//!   of the horizon (a fix whose position block was refused does not make
//!   position valid) and a standard
//!   deviation (square root of the horizon EKF's covariance, NED axes) below
//!   [`MAX_VELOCITY_STD_M_S`] / [`MAX_POSITION_STD_M`]. The delay needs its
//!   level within its alert limit and, estimated, the loop's estimate inside
//!   its range. The level is the configured one in fixed mode; estimated, it
//!   follows the loop's standard deviation, which starts at the configured
//!   `initial_std_s`: the default start (0.3 s) is not valid until the loop has
//!   measured, a start the user vouches for with a tight standard deviation
//!   (an offline calibration's) is valid from the start, as a fixed delay is.
//! - **the alignment state** ([`AlignmentState`]).
//! - **the last reset and its cause** ([`ResetRecord`]).
//! - **refusals per sensor and reason** ([`NavRefusals`]): the navigator's
//!   input checks, and the horizon filter's checks, gates and GPS resets
//!   ([`NavRefusals::horizon`]).
//! - **the delay status** ([`DelayHealth`], with the loop's [`DelayStatus`]): filled from what the delay loop
//!   exposes today (estimate, standard deviation, validity of the last
//!   update's axes); a richer status from the loop (waiting for motion,
//!   outside its range) is meant to replace `last_valid_axes`.

use super::{DelayCompensatedNav, NavRefusals};
use crate::delay::DelayStatus;
use crate::ekf16::nav_core::gap_growth;
use crate::ekf16::state::{POS, VEL};
use crate::ekf16::{GpsBlock, GpsReset, MagModeHealth};
use crate::estimate::{Estimate, Navigator};
use crate::integrity::{Integrity, ProtectionLevels, protection_factors};
use crate::scalar::{Scalar, us_to_s};
use nalgebra::{Matrix3, Vector3};

/// Longest time since the last fused GPS fix for velocity and position to
/// count as valid, µs.
pub const GPS_STALE_US: u64 = 2_000_000;
/// Longest time since the last fused magnetometer update for heading to
/// count as valid, µs.
pub const HEADING_STALE_US: u64 = 5_000_000;
/// Largest horizontal position standard deviation counted valid, m.
pub const MAX_POSITION_STD_M: f64 = 10.0;
/// Largest velocity standard deviation counted valid, m/s.
pub const MAX_VELOCITY_STD_M_S: f64 = 2.0;

/// Where the navigator is in its start-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum AlignmentState {
    /// A blank navigator ([`DelayCompensatedNav::BLANK`](super::DelayCompensatedNav::BLANK))
    /// not configured yet, or whose last
    /// [`configure`](super::DelayCompensatedNav::configure) failed: every
    /// sample is refused with [`Error::NotConfigured`](crate::Error::NotConfigured).
    NotConfigured,
    /// Not enough IMU history to reach the delayed horizon yet.
    WaitingForImu,
    /// The horizon EKF waits for a GPS fix (and its levelling window).
    WaitingForGps,
    /// The horizon EKF is initialized; the present is one delay away.
    CarryingForward,
    /// The present estimate exists.
    Aligned,
}

/// Why the navigator was reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ResetCause {
    /// [`reset`](super::DelayCompensatedNav::reset) was called (e.g. after
    /// [`Error::TimeWentBackwards`](crate::Error::TimeWentBackwards)).
    Requested,
    /// An IMU gap longer than the EKF's `max_imu_step_us` restarted the
    /// history (the EKF state is kept).
    ImuGap,
    /// The horizon EKF reset one GPS block (position or velocity) to a fix:
    /// sustained rejection or divergence (the record says which).
    Gps(GpsReset),
    /// The horizon EKF's heading was set from the yaw estimator
    /// ([`Health::yaw_gsf`]): the alignment without a magnetometer, or a
    /// sustained disagreement with it.
    YawGsf,
}

/// The last reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ResetRecord {
    /// Newest IMU time when it happened, µs (`None` before any sample).
    pub t_us: Option<u64>,
    /// Why.
    pub cause: ResetCause,
}

/// The delay estimate as the navigator uses it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DelayHealth<T: Scalar> {
    /// True when the delay is estimated online, false when fixed.
    pub estimated: bool,
    /// The delay, s.
    pub delay_s: T,
    /// Its standard deviation, s (0 when fixed).
    pub delay_std_s: T,
    /// Validity `V_i` of each axis at the last loop update (`None` before
    /// the first, and in fixed mode). All false: the loop waits for motion.
    pub last_valid_axes: Option<[bool; 3]>,
    /// Loop updates with at least one valid axis so far.
    pub valid_updates: u32,
    /// Valid axes the loop left out as outliers (below 3 Hz, once locked)
    /// ([`DelayLoop::outlier_windows`](crate::delay::DelayLoop::outlier_windows)).
    pub outlier_windows: u32,
    /// The delay loop's own status (acquiring, locked, waiting for motion,
    /// below or above its range); `None` in fixed mode.
    pub status: Option<DelayStatus<T>>,
}

/// What the navigator can vouch for at the present (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Health<T: Scalar> {
    /// The present time, µs (newest accepted IMU sample).
    pub t_us: Option<u64>,
    /// Start-up state.
    pub alignment: AlignmentState,
    /// Tilt (roll, pitch) can be trusted.
    pub tilt_valid: bool,
    /// Heading can be trusted.
    pub heading_valid: bool,
    /// Velocity can be trusted.
    pub velocity_valid: bool,
    /// Position can be trusted.
    pub position_valid: bool,
    /// Vertical position can be trusted.
    pub vertical_valid: bool,
    /// The delay can be trusted.
    pub delay_valid: bool,
    /// The protection levels of the present estimate at the configured integrity risk
    /// ([`crate::integrity`]): each `*_valid` needs its level within its alert limit.
    pub protection_levels: ProtectionLevels<T>,
    /// The last reset, if any.
    pub last_reset: Option<ResetRecord>,
    /// Refusals, gates and resets, the horizon filter's among them.
    pub refusals: NavRefusals,
    /// The delay's status.
    pub delay: DelayHealth<T>,
    /// The horizon filter's magnetometer fusion mode (3-axis, heading only,
    /// none) and the time spent in each.
    pub mag: MagModeHealth,
    /// The yaw estimator without a magnetometer: its yaw, weights and the
    /// headings set from it.
    pub yaw_gsf: super::YawGsfHealth<T>,
}

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// What the navigator can vouch for now (see [`Health`]).
    pub fn health(&self) -> Health<T> {
        let alignment = self.alignment();
        let aligned = alignment == AlignmentState::Aligned;
        let horizon = self.ekf.time_us().unwrap_or(0);
        let recent =
            |t: Option<u64>, stale: u64| t.is_some_and(|t| horizon <= t.saturating_add(stale));
        let p = self.ekf.covariance();
        let std = |i: usize| p[(i, i)].max(T::zero()).sqrt();
        let horizontal_std = (p[(POS, POS)] + p[(POS + 1, POS + 1)])
            .max(T::zero())
            .sqrt();
        let velocity_std = std(VEL).max(std(VEL + 1)).max(std(VEL + 2));
        // Per block: a fix whose position block was refused does not make position valid.
        let position_recent = recent(
            self.ekf.last_gps_block_fused_us(GpsBlock::Position),
            GPS_STALE_US,
        );
        let velocity_recent = recent(
            self.ekf.last_gps_block_fused_us(GpsBlock::Velocity),
            GPS_STALE_US,
        );
        let mag_fused = self.ekf.last_mag_fused_us();
        let estimated = self.is_estimating();
        let levels = self.protection_levels();
        let limits = &self.config.ekf.integrity;
        // While an IMU time jump waits for confirmation the present may be a gap beyond the
        // estimate (after a 2 s gap it was: tilt, position and velocity all beyond their
        // alert limits for that sample): nothing is vouched for.
        let judged = Integrity::judged(levels, limits, aligned && !self.imu_clock.jump_pending());
        Health {
            t_us: self.imu_clock.last(),
            alignment,
            tilt_valid: judged.tilt_valid,
            heading_valid: judged.heading_valid && recent(mag_fused, HEADING_STALE_US),
            velocity_valid: judged.velocity_valid
                && velocity_recent
                && velocity_std <= T::lit(MAX_VELOCITY_STD_M_S),
            position_valid: judged.horizontal_valid
                && position_recent
                && horizontal_std <= T::lit(MAX_POSITION_STD_M),
            vertical_valid: judged.vertical_valid && position_recent,
            delay_valid: levels.delay_s <= limits.delay_alert_limit_s
                && !(estimated && self.delay_loop.status().is_out_of_range()),
            protection_levels: levels,
            last_reset: self.last_reset.get(),
            refusals: self.refusals(),
            delay: DelayHealth {
                estimated,
                delay_s: self.delay_s(),
                delay_std_s: self.delay_std_s(),
                last_valid_axes: self.last_update.get().map(|u| u.axes.map(|a| a.valid)),
                valid_updates: self.valid_delay_updates,
                outlier_windows: self.delay_loop.outlier_windows(),
                status: estimated.then(|| self.delay_loop.status()),
            },
            mag: self.ekf.mag_modes(),
            yaw_gsf: self
                .yaw_gsf
                .health(self.gsf_yaw_resets, self.fixes_position_velocity_only),
        }
    }

    /// The protection levels of the present estimate: the horizon filter's covariance, plus
    /// what the delay's uncertainty `s_tau` adds when the horizon is carried to the present
    /// (a delay error `d` shifts the present by `v d` in position and `a d` in velocity:
    /// `v v^T s_tau^2` and `a a^T s_tau^2` added to the NED blocks); the delay's own level
    /// from `s_tau` (0 in fixed mode: the given delay is taken as exact); inflated by the
    /// horizon filter's innovation monitor (`src/ekf16/nav_core/integrity.rs`). The others are
    /// unbounded before the horizon filter is initialized. While the horizon filter's time is
    /// before the end of the newest IMU gap (the first delay after it: the present is past the
    /// gap, the horizon not yet), the growth that crossing the gap will give the horizon's
    /// covariance (the carry, the unknown acceleration and rotation over `t_gap_end - t_h`) is
    /// added. Then the position-against-velocity check's offset added to the position levels,
    /// the tilt's share of the magnetometer's heading, the magnetometer monitor's (its heading
    /// factor, a field offset's turn of the heading and the tilt), and the horizon's attitude
    /// error, at these levels, carried over the span `D` to the present through the present's
    /// specific force (`ProtectionLevels::carried`; docs/integrity.md).
    pub fn protection_levels(&self) -> ProtectionLevels<T> {
        let s = self.delay_std_s();
        let Some(horizon) = self.ekf.estimate() else {
            let (k1, _, _) = protection_factors(self.config.ekf.integrity.risk);
            return ProtectionLevels {
                delay_s: k1 * s,
                ..ProtectionLevels::unbounded()
            };
        };
        let present = self.estimate().unwrap_or(horizon);
        let v = present.velocity_ned_m_s * s;
        let a = self.present_accel * s;
        let (position, velocity) = self.ekf.nis_inflation();
        // The horizon's attitude error carried over the span to the present turns the
        // specific force `f` (NED).
        let span: T = us_to_s(present.t_us.saturating_sub(horizon.t_us));
        let gravity = Vector3::new(T::zero(), T::zero(), self.config.ekf.gravity_m_s2);
        let f = self.present_accel - gravity;
        // The present past an IMU gap the horizon has not crossed yet: what the crossing
        // will add (the carry and the unknown motion from the horizon to the gap's end).
        let p = self.ekf.covariance();
        let (gap_position, gap_velocity, gap_attitude) = if horizon.t_us < self.imu_gap_end_us {
            gap_growth(p, us_to_s(self.imu_gap_end_us - horizon.t_us))
        } else {
            (Matrix3::zeros(), Matrix3::zeros(), T::zero())
        };
        let risk = self.config.ekf.integrity.risk;
        ProtectionLevels::from_covariance(
            &present.attitude,
            p,
            risk,
            &(v * v.transpose() + gap_position),
            &(a * a.transpose() + gap_velocity),
            Some(s),
        )
        .with_attitude_variance(gap_attitude, risk)
        .inflated(position, velocity)
        .with_position_bias(self.ekf.position_velocity_bias())
        .with_velocity_bias(self.ekf.velocity_innovation_bias())
        .with_heading_tilt_coupling(
            self.ekf.heading_tilt_coupling(),
            self.config.ekf.integrity.risk,
        )
        .with_magnetometer(self.ekf.mag_integrity())
        .carried(f.norm(), f.x.hypot(f.y), span)
    }

    /// The present estimate with its [`Health`] (`None` until aligned).
    pub fn estimate_with_health(&self) -> Option<(Estimate<T>, Health<T>)> {
        Some((self.estimate()?, self.health()))
    }
}

impl<T: Scalar> Health<T> {
    /// The flags and levels as the [`Navigator`] trait reports them; `resets` counts the
    /// horizon filter's GPS block resets and the IMU gaps that restarted the history.
    pub fn integrity(&self) -> Integrity<T> {
        let h = &self.refusals.horizon;
        Integrity {
            levels: self.protection_levels,
            tilt_valid: self.tilt_valid,
            heading_valid: self.heading_valid,
            horizontal_valid: self.position_valid,
            vertical_valid: self.vertical_valid,
            velocity_valid: self.velocity_valid,
            delay_valid: self.delay_valid,
            resets: h
                .gps_position_resets
                .saturating_add(h.gps_velocity_resets)
                .saturating_add(self.refusals.imu_gap),
        }
    }
}

impl core::fmt::Display for AlignmentState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::NotConfigured => "not configured",
            Self::WaitingForImu => "waiting for IMU",
            Self::WaitingForGps => "waiting for GPS",
            Self::CarryingForward => "carrying forward",
            Self::Aligned => "aligned",
        })
    }
}

impl core::fmt::Display for ResetCause {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        use crate::ekf16::{GpsBlock, GpsResetCause};
        match self {
            Self::Requested => f.write_str("requested"),
            Self::ImuGap => f.write_str("IMU gap"),
            Self::Gps(r) => write!(
                f,
                "GPS {} {} (fix at {} us)",
                match r.block {
                    GpsBlock::Position => "position",
                    GpsBlock::Velocity => "velocity",
                },
                match r.cause {
                    GpsResetCause::Rejected => "rejected too long",
                    GpsResetCause::Diverged => "diverged",
                },
                r.t_us
            ),
            Self::YawGsf => f.write_str("heading from the yaw estimator"),
        }
    }
}

/// One line: the alignment, each flag, the delay and its status, the last
/// reset (the counters are in the fields and in `{:?}`), e.g.
/// `aligned; valid: tilt yes, heading yes, velocity yes, position yes, delay yes; delay
/// 0.2013 s +- 0.0042 s (locked, 57 measured updates); last reset: none`.
impl<T: Scalar> core::fmt::Display for Health<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let yes = |b: bool| if b { "yes" } else { "no" };
        write!(
            f,
            "{}; valid: tilt {}, heading {}, velocity {}, position {}, delay {}; delay {:.4} s",
            self.alignment,
            yes(self.tilt_valid),
            yes(self.heading_valid),
            yes(self.velocity_valid),
            yes(self.position_valid),
            yes(self.delay_valid),
            self.delay.delay_s.as_f64(),
        )?;
        match self.delay.status {
            Some(status) => write!(
                f,
                " +- {:.4} s ({status}, {} measured updates)",
                self.delay.delay_std_s.as_f64(),
                self.delay.valid_updates
            )?,
            None => f.write_str(" (fixed)")?,
        }
        match self.last_reset {
            Some(ResetRecord {
                t_us: Some(t_us),
                cause,
            }) => write!(f, "; last reset at {t_us} us: {cause}"),
            Some(ResetRecord { t_us: None, cause }) => write!(f, "; last reset: {cause}"),
            None => f.write_str("; last reset: none"),
        }
    }
}

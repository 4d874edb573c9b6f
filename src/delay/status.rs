//! What the loop says: its [`DelayStatus`] and each update's record
//! ([`DelayUpdate`], per axis [`AxisUpdate`]).

use super::{AXES, AxisPeak};
use crate::scalar::Scalar;

/// What the correlation and the fusion made of one axis at one update.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AxisUpdate<T: Scalar> {
    /// Validity `V_i`: the measurement was fused.
    pub valid: bool,
    /// The delay measurement `z_i` (refined correlation peak), s.
    pub measured_delay_s: T,
    /// The local gain `K_i` (applied only when valid).
    pub gain: T,
    /// The correlation peak it came from.
    pub correlation: AxisPeak<T>,
}

/// The record of one delay update (one GFA iteration).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DelayUpdate<T: Scalar> {
    /// Receive time of the GPS fix that triggered the update, us.
    pub t_us: u64,
    /// Fused delay estimate, s.
    pub delay_s: T,
    /// Its standard deviation as the GFA models it (see the noise units of
    /// [`DelayLoopConfig`](crate::delay::DelayLoopConfig)), s; not validated as a calibrated uncertainty.
    pub delay_std_s: T,
    /// True when this update re-acquired the delay (see
    /// [`DelayLoopConfig::reacquire_sigma`](crate::delay::DelayLoopConfig::reacquire_sigma)).
    pub reacquired: bool,
    /// The loop's status after this update.
    pub status: DelayStatus<T>,
    /// North, east, down.
    pub axes: [AxisUpdate<T>; AXES],
}

/// What the loop can say about the delay (see [`DelayLoop::status`](crate::delay::DelayLoop::status)).
///
/// The navigator, or the user, reads it to know whether [`DelayLoop::delay_s`](crate::delay::DelayLoop::delay_s)
/// is an estimate (`Locked`), a provisional value (`Acquiring`), or the
/// start value the motion has not yet allowed to estimate; and whether the
/// true delay lies outside the configured range, which the loop never
/// clamps silently.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DelayStatus<T: Scalar> {
    /// The correlation buffer is not full yet (start, or after a gap in a
    /// stream): the estimate is the start value.
    WaitingForData,
    /// Not locked, and no axis of the last window moved enough (or
    /// correlated well enough) to measure the delay.
    WaitingForMotion,
    /// Following the per-window correlation peaks (the coarse search over
    /// the whole range) until they settle.
    Acquiring,
    /// Locked: the gain fusion refines the estimate (it holds it when the
    /// motion stops).
    Locked,
    /// For at least [`DelayLoopConfig::out_of_range_after_s`](crate::delay::DelayLoopConfig::out_of_range_after_s),
    /// the windows whose moving axes correlate (peak at least 0.5) have
    /// peaked at the smallest delay of the range in a running share of at
    /// least 0.5 (time constant 5 s; `docs/delay.md`, "Range and status"):
    /// the delay is below `edge_s`. The estimate is not moved there.
    BelowRange {
        /// The range's lower edge, s.
        edge_s: T,
        /// The largest peak value (normalized correlation) seen at the edge.
        peak: T,
        /// The running share of the voting windows that peaked at this edge, `[0, 1]`.
        share: T,
    },
    /// As [`DelayStatus::BelowRange`], at the largest delay of the range.
    AboveRange {
        /// The range's upper edge, s.
        edge_s: T,
        /// The largest peak value (normalized correlation) seen at the edge.
        peak: T,
        /// The running share of the voting windows that peaked at this edge, `[0, 1]`.
        share: T,
    },
}

impl<T: Scalar> DelayStatus<T> {
    /// True when the delay is estimated (`Locked`).
    pub fn is_locked(&self) -> bool {
        matches!(self, DelayStatus::Locked)
    }

    /// True when the delay lies outside the configured range.
    pub fn is_out_of_range(&self) -> bool {
        matches!(
            self,
            DelayStatus::BelowRange { .. } | DelayStatus::AboveRange { .. }
        )
    }
}

impl<T: Scalar> core::fmt::Display for DelayStatus<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::WaitingForData => f.write_str("waiting for data"),
            Self::WaitingForMotion => f.write_str("waiting for motion"),
            Self::Acquiring => f.write_str("acquiring"),
            Self::Locked => f.write_str("locked"),
            Self::BelowRange {
                edge_s,
                peak,
                share,
            } => write!(
                f,
                "below the range (edge {:.3} s, peak {:.2}, share {:.2})",
                edge_s.as_f64(),
                peak.as_f64(),
                share.as_f64()
            ),
            Self::AboveRange {
                edge_s,
                peak,
                share,
            } => write!(
                f,
                "above the range (edge {:.3} s, peak {:.2}, share {:.2})",
                edge_s.as_f64(),
                peak.as_f64(),
                share.as_f64()
            ),
        }
    }
}

//! The offline calibration before the online pass ([`ReplaySetup::offline_delay`]): the
//! paper's Figure 3 (`docs/delay.md`, "7. Offline calibration") over the replayed window, on
//! the host, for shifts of [`OFFLINE_MAX_SHIFT_S`] either way, so that a log whose delay lies
//! outside the loop's default range, or is negative, replays right with no flag.
//!
//! Its result sets the `proposed` navigator's start ([`ReplaySetup::nav_with_offline`]) when its
//! peak is at least [`OFFLINE_MIN_PEAK`] and inside the searched shifts: the start is the
//! offline delay; the loop's range is kept when it holds the offline delay with
//! [`OFFLINE_RANGE_MARGIN_S`] to spare, and is otherwise moved, its width kept, to be centred
//! on it.

use super::ReplaySetup;
use crate::delay::{CalibrationConfig, DefaultCalibrator};
use crate::nav::{DelayCompensatedNavConfig, DelayMode};
use crate::replay::{LogReader, ReaderOptions, ReplayError, SensorEvent};
use serde_json::{Value, json};

/// Largest shift searched either way, s.
pub const OFFLINE_MAX_SHIFT_S: f64 = 1.5;
/// Smallest three-axis correlation peak for the calibration to set the start.
pub const OFFLINE_MIN_PEAK: f64 = 0.5;
/// Margin the loop's range must keep around the offline delay, s, or it is moved.
pub const OFFLINE_RANGE_MARGIN_S: f64 = 0.1;

/// The offline calibration of one replay.
#[derive(Debug, Clone, PartialEq)]
pub struct OfflineDelay {
    /// The refined peak of the three-axis correlation, s.
    pub delay_s: f64,
    /// Its value.
    pub peak: f64,
    /// The correlation at every shift, `(delay s, R, pairs)`; a shift with fewer pairs than the
    /// calibration's `min_pairs` is never its peak.
    pub curve: Vec<(f64, f64, usize)>,
    /// Samples the calibrator refused (non-finite, time not increasing, gaps restart it).
    pub refused: u64,
    /// Whether it set the online loop's start: a peak of at least [`OFFLINE_MIN_PEAK`], inside
    /// the searched shifts.
    pub applied: bool,
    /// The online loop's range after it, s.
    pub range_s: (f64, f64),
}

impl OfflineDelay {
    /// The JSON's `offline_delay`: `delay_s`, `peak`, `applied`, `range_s`, `refused`, `curve`
    /// (`[delay_s, R, pairs]` per shift).
    pub fn to_json(&self) -> Value {
        json!({
            "delay_s": self.delay_s,
            "peak": self.peak,
            "applied": self.applied,
            "range_s": [self.range_s.0, self.range_s.1],
            "refused": self.refused,
            "curve": self.curve,
        })
    }

    /// The console's line.
    pub fn line(&self) -> String {
        format!(
            "offline delay {:.3} s (peak {:.2}, shifts -{s:.1}..{s:.1} s, {} refused): {} the online range {:.2}..{:.2} s",
            self.delay_s,
            self.peak,
            self.refused,
            if self.applied {
                "the online start, in"
            } else {
                "not used (weak or at an edge);"
            },
            self.range_s.0,
            self.range_s.1,
            s = OFFLINE_MAX_SHIFT_S,
        )
    }
}

/// The online loop's range `(lo, hi)`, s, for the offline delay `d`: kept when it holds `d` with
/// [`OFFLINE_RANGE_MARGIN_S`] to spare, else moved, its width kept, to be centred on `d`.
fn online_range((lo, hi): (f64, f64), d: f64) -> (f64, f64) {
    if (lo + OFFLINE_RANGE_MARGIN_S..=hi - OFFLINE_RANGE_MARGIN_S).contains(&d) {
        (lo, hi)
    } else {
        let half = 0.5 * (hi - lo);
        (d - half, d + half)
    }
}

impl ReplaySetup {
    /// The offline calibration over the replayed window read with `reader`; `None` when the
    /// window has too little data for a result.
    pub fn offline_delay(
        &self,
        reader: &ReaderOptions,
    ) -> Result<Option<OfflineDelay>, ReplayError> {
        let config = CalibrationConfig {
            max_shift_s: OFFLINE_MAX_SHIFT_S,
            ..CalibrationConfig::default()
        };
        let mut calibrator = Box::new(DefaultCalibrator::<f64>::new(config)?);
        let start = self.run.start_us.unwrap_or(0);
        let end = self.run.end_us.unwrap_or(u64::MAX);
        let mut refused = 0;
        for event in LogReader::<f64>::open(&self.files, reader)? {
            let t = event.time_us();
            if t < start {
                continue;
            }
            if t > end {
                break;
            }
            let outcome = match &event {
                SensorEvent::Imu(s) => calibrator.push_imu(s),
                SensorEvent::Gps(g) => calibrator.push_gps(g),
                SensorEvent::Mag(_) => Ok(()),
            };
            refused += u64::from(outcome.is_err());
        }
        let Ok(result) = calibrator.result() else {
            return Ok(None);
        };
        let edge = OFFLINE_MAX_SHIFT_S - 1.0 / config.correlation_rate_hz;
        let applied = result.peak >= OFFLINE_MIN_PEAK && result.delay_s.abs() < edge;
        let fusion = &self.nav.delay_loop.fusion;
        let range = (fusion.delay_min_s, fusion.delay_max_s);
        let d = result.delay_s;
        Ok(Some(OfflineDelay {
            range_s: if applied {
                online_range(range, d)
            } else {
                range
            },
            delay_s: d,
            peak: result.peak,
            curve: calibrator.curve().collect(),
            refused,
            applied,
        }))
    }

    /// The navigator's configuration ([`Self::nav`]) with the offline delay's start and range
    /// when it applies (an estimated delay only).
    pub fn nav_with_offline(
        &self,
        offline: Option<&OfflineDelay>,
    ) -> DelayCompensatedNavConfig<f64> {
        let mut nav = self.nav;
        if let (Some(o), DelayMode::Estimated { .. }) = (offline.filter(|o| o.applied), nav.mode) {
            nav.mode = DelayMode::Estimated {
                initial_s: o.delay_s,
            };
            nav.delay_loop.fusion.delay_min_s = o.range_s.0;
            nav.delay_loop.fusion.delay_max_s = o.range_s.1;
        }
        nav
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_moves_only_when_it_does_not_hold_the_offline_delay() {
        assert_eq!(online_range((0.0, 1.0), 0.31), (0.0, 1.0));
        assert_eq!(online_range((0.0, 1.0), 0.9), (0.0, 1.0));
        let (lo, hi) = online_range((0.0, 1.0), -0.47);
        assert!(
            (lo + 0.97).abs() < 1e-12 && (hi - 0.03).abs() < 1e-12,
            "{lo} {hi}"
        );
        let (lo, hi) = online_range((0.0, 1.0), 0.95);
        assert!(
            (lo - 0.45).abs() < 1e-12 && (hi - 1.45).abs() < 1e-12,
            "{lo} {hi}"
        );
    }
}

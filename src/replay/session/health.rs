//! [`HealthSummary`]: what an estimator reports about itself at the end of a
//! replay (`docs/replay.md`, "Health summary").

use crate::ekf16::GpsReset;
use crate::{AugmentedEkf17, FilterRefusals, Health};
use serde_json::{Value, json};
use std::fmt::Write;

/// What an estimator reports about itself at the end of a replay: counters
/// as `(name, count)`, non-zero ones only, in the counters' order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HealthSummary {
    /// Alignment state (the navigator's [`AlignmentState`](crate::AlignmentState);
    /// the filters: `Initialized` or `NotInitialized`).
    pub alignment: Option<String>,
    /// Samples refused, by sensor and reason (the navigator's own prefixed
    /// `nav.`, its horizon filter's `horizon.`).
    pub refused: Vec<(String, u64)>,
    /// Fusions rejected by a gate.
    pub gated: Vec<(String, u64)>,
    /// Resets by block and cause (and the navigator's history restarts
    /// after an IMU gap, `nav.imu_gap_restarts`).
    pub resets: Vec<(String, u64)>,
    /// The last reset, its cause and time.
    pub last_reset: Option<String>,
    /// The delay estimate's status.
    pub delay_status: Option<String>,
}

/// `(name, value)` of the named fields of a counter struct.
macro_rules! fields {
    ($c:expr; $($f:ident),* $(,)?) => {
        vec![$((stringify!($f).to_string(), u64::from($c.$f))),*]
    };
}

fn non_zero(list: Vec<(String, u64)>) -> Vec<(String, u64)> {
    list.into_iter().filter(|(_, n)| *n > 0).collect()
}

fn prefixed(prefix: &str, list: Vec<(String, u64)>) -> impl Iterator<Item = (String, u64)> {
    list.into_iter()
        .map(move |(k, v)| (format!("{prefix}.{k}"), v))
}

impl HealthSummary {
    /// A filter's counters ([`FilterRefusals`]) and its last GPS reset.
    pub fn of_filter(c: FilterRefusals, last: Option<GpsReset>) -> Self {
        Self {
            refused: non_zero(fields!(c; imu_non_finite, imu_out_of_range, imu_time,
                imu_step_too_long, imu_ahead, gps_invalid, gps_time, gps_mixed_frames, mag_invalid,
                mag_time, not_positive_definite, covariance_repairs)),
            gated: non_zero(fields!(c; gps_position_rejected, gps_velocity_rejected,
                mag_rejected, mag_disturbed, gps_position_inconsistent, mag_field_offset)),
            resets: non_zero(fields!(c; gps_position_resets, gps_velocity_resets,
                gps_divergence_resets, mag_field_offset_cleared)),
            last_reset: last.map(|r| {
                format!(
                    "{:?} block, {:?}, at {:.1} s",
                    r.block,
                    r.cause,
                    r.t_us as f64 * 1e-6
                )
            }),
            ..Self::default()
        }
    }

    /// The alignment of a filter without an alignment state: initialized
    /// (it gives an estimate) or not.
    pub fn initialized(&mut self, yes: bool) {
        self.alignment = Some(if yes { "Initialized" } else { "NotInitialized" }.to_string());
    }

    /// The 17-state baseline: its counters, alignment and delay state (the
    /// estimate, its standard deviation, how often it was clamped to its
    /// range and held without the motion to observe it).
    pub fn of_aekf17(nav: &AugmentedEkf17<f64>, initialized: bool) -> Self {
        let mut health = Self::of_filter(nav.refusals(), nav.last_gps_reset());
        health.initialized(initialized);
        health.delay_status = Some(format!(
            "state estimate {:.3} s +- {:.3} s, clamped to its range {} times, \
             held on {} fixes without the motion to observe it",
            nav.delay_s(),
            nav.delay_std_s(),
            nav.delay_clamps(),
            nav.delay_unobservable_fixes()
        ));
        health
    }

    /// The navigator's [`Health`]: its own refusals, its horizon filter's
    /// counters, alignment, last reset and delay status.
    pub fn of_navigator(h: &Health<f64>) -> Self {
        let mut summary = Self::of_filter(h.refusals.horizon, None);
        let n = h.refusals;
        let own = fields!(n; imu_non_finite, imu_out_of_range, imu_time, imu_ahead,
            gps_invalid, gps_time, gps_accuracy, gps_ahead, gps_mixed_frames, mag_invalid,
            mag_time, mag_ahead, mag_averaged, horizon_refused, delay_loop_refused,
            forward_corrections_missed);
        summary.refused = prefixed("nav", non_zero(own))
            .chain(prefixed("horizon", summary.refused))
            .collect();
        // An IMU gap is not a refused sample: the history restarts (a reset
        // whose cause `last_reset` names, `ImuGap`), so it is listed with
        // the horizon filter's GPS resets.
        let gaps = vec![("imu_gap_restarts".to_string(), u64::from(n.imu_gap))];
        summary.resets = prefixed("nav", non_zero(gaps))
            .chain(prefixed("horizon", summary.resets))
            .collect();
        let outliers = vec![(
            "outlier_windows".to_string(),
            u64::from(h.delay.outlier_windows),
        )];
        summary.gated.extend(prefixed("delay", non_zero(outliers)));
        summary.alignment = Some(format!("{:?}", h.alignment));
        summary.last_reset = h.last_reset.map(|r| {
            let at = r
                .t_us
                .map_or_else(String::new, |t| format!(" at {:.1} s", t as f64 * 1e-6));
            format!("{:?}{at}", r.cause)
        });
        summary.delay_status = Some(match h.delay.status {
            Some(status) => format!(
                "{status:?}, {:.3} s +- {:.3} s, {} valid updates",
                h.delay.delay_s, h.delay.delay_std_s, h.delay.valid_updates
            ),
            None => format!("fixed at {:.3} s", h.delay.delay_s),
        });
        summary
    }

    /// The JSON's `"health"`: `alignment`, `refused`, `gated`, `resets`
    /// (objects of counts), `last_reset`, `delay_status`.
    pub fn to_json(&self) -> Value {
        let map = |list: &[(String, u64)]| {
            list.iter()
                .map(|(k, v)| (k.clone(), json!(v)))
                .collect::<serde_json::Map<_, _>>()
        };
        json!({
            "alignment": self.alignment,
            "refused": map(&self.refused),
            "gated": map(&self.gated),
            "resets": map(&self.resets),
            "last_reset": self.last_reset,
            "delay_status": self.delay_status,
        })
    }

    /// The console's lines for the estimator `name`: its name, then one
    /// indented line per item (`none` for an empty list).
    pub fn lines(&self, name: &str) -> String {
        let list = |l: &[(String, u64)]| {
            if l.is_empty() {
                "none".to_string()
            } else {
                l.iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        let mut out = format!("{name}\n");
        let rows = [
            ("alignment", self.alignment.clone()),
            ("refused", Some(list(&self.refused))),
            ("gated", Some(list(&self.gated))),
            ("resets", Some(list(&self.resets))),
            (
                "last reset",
                Some(self.last_reset.clone().unwrap_or_else(|| "none".into())),
            ),
            ("delay", self.delay_status.clone()),
        ];
        for (label, value) in rows {
            if let Some(v) = value {
                let _ = writeln!(out, "  {label:<10} {v}");
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf16::{GpsBlock, GpsResetCause};
    use crate::{DelayCompensatedNav, DelayCompensatedNavConfig};

    #[test]
    fn a_filter_lists_its_non_zero_counters_and_its_last_reset() {
        let c = FilterRefusals {
            imu_step_too_long: 1,
            gps_velocity_rejected: 25,
            gps_position_resets: 2,
            ..FilterRefusals::default()
        };
        let reset = GpsReset {
            t_us: 151_250_000,
            block: GpsBlock::Position,
            cause: GpsResetCause::Rejected,
        };
        let mut h = HealthSummary::of_filter(c, Some(reset));
        h.initialized(true);
        assert_eq!(h.refused, [("imu_step_too_long".to_string(), 1)]);
        assert_eq!(h.gated, [("gps_velocity_rejected".to_string(), 25)]);
        assert_eq!(h.resets, [("gps_position_resets".to_string(), 2)]);
        assert_eq!(
            h.last_reset.as_deref(),
            Some("Position block, Rejected, at 151.2 s")
        );
        assert_eq!(
            h.lines("ekf16"),
            "ekf16\n  alignment  Initialized\n  refused    imu_step_too_long 1\n  \
             gated      gps_velocity_rejected 25\n  resets     gps_position_resets 2\n  \
             last reset Position block, Rejected, at 151.2 s\n"
        );
        assert_eq!(
            h.to_json(),
            json!({
                "alignment": "Initialized",
                "refused": {"imu_step_too_long": 1},
                "gated": {"gps_velocity_rejected": 25},
                "resets": {"gps_position_resets": 2},
                "last_reset": "Position block, Rejected, at 151.2 s",
                "delay_status": null,
            })
        );
    }

    #[test]
    fn an_empty_summary_prints_none_and_leaves_out_what_it_lacks() {
        let h = HealthSummary::default();
        assert_eq!(
            h.lines("x"),
            "x\n  refused    none\n  gated      none\n  resets     none\n  last reset none\n"
        );
        let json = h.to_json();
        let keys: Vec<_> = json.as_object().unwrap().keys().cloned().collect();
        assert_eq!(
            keys.join(","),
            "alignment,delay_status,gated,last_reset,refused,resets"
        );
    }

    #[test]
    fn the_navigator_prefixes_its_own_and_its_horizon_filters_counters() {
        let nav = DelayCompensatedNav::<f64>::new(DelayCompensatedNavConfig::default()).unwrap();
        let mut health = nav.health();
        health.refusals.imu_ahead = 1;
        health.refusals.imu_gap = 1;
        health.refusals.horizon.imu_step_too_long = 1;
        health.refusals.horizon.gps_velocity_resets = 3;
        let h = HealthSummary::of_navigator(&health);
        assert_eq!(
            h.refused,
            [
                ("nav.imu_ahead".to_string(), 1),
                ("horizon.imu_step_too_long".to_string(), 1)
            ]
        );
        assert_eq!(
            h.resets,
            [
                ("nav.imu_gap_restarts".to_string(), 1),
                ("horizon.gps_velocity_resets".to_string(), 3)
            ]
        );
        assert!(h.gated.is_empty());
        assert_eq!(h.alignment.as_deref(), Some("WaitingForImu"));
        assert_eq!(h.last_reset, None);
        assert!(
            h.delay_status
                .as_deref()
                .unwrap()
                .starts_with("WaitingForData, "),
            "{:?}",
            h.delay_status
        );
    }
}

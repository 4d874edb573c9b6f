//! The tables' JSON document (see the module's docs for its keys).

use super::score::Metrics;
use super::summary::{Consistency, FIGURES, PAIRED_AGAINST, Summary};
use super::{ScenarioResult, TablesResult};
use crate::sim::suite::{json_number, json_pair};
use serde_json::{Map, Value, json};

/// One estimator's entry: every figure's mean over the seeds and, as
/// `<name>_ci95`, its 95 % t-interval; `delay_s_median`, the delay RMSE's
/// median over the seeds; the biases and their intervals; the consistency.
fn estimator_json(s: &Summary, c: &Consistency) -> Map<String, Value> {
    let mut entry = Map::new();
    for (name, get) in FIGURES {
        entry.insert(name.into(), get(&s.mean).map_or(Value::Null, json_number));
        let ci = match (get(&s.lo), get(&s.hi)) {
            (Some(lo), Some(hi)) => json_pair((lo, hi)),
            _ => Value::Null,
        };
        entry.insert(format!("{name}_ci95"), ci);
    }
    entry.insert(
        "delay_s_median".into(),
        s.median.delay_s.map_or(Value::Null, json_number),
    );
    type Biases = fn(&Metrics) -> [f64; 3];
    let biases: [(&str, Biases); 2] = [
        ("gyro_bias_rad_s", |m| m.gyro_bias_rad_s),
        ("accel_bias_g", |m| m.accel_bias_g),
    ];
    for (name, get) in biases {
        entry.insert(name.into(), json!(get(&s.mean).map(json_number)));
        let (lo, hi) = (get(&s.lo), get(&s.hi));
        let ci: Vec<Value> = (0..3).map(|i| json_pair((lo[i], hi[i]))).collect();
        entry.insert(format!("{name}_ci95"), Value::Array(ci));
    }
    entry.insert("nees_mean".into(), json_number(c.nees_mean));
    entry.insert("nees_band95".into(), json_pair(c.nees_band));
    entry.insert("nees_in_band_fraction".into(), json_number(c.nees_in_band));
    entry.insert("nis_mean".into(), json_number(c.nis_mean));
    entry.insert("nis_band95".into(), json_pair(c.nis_band));
    entry
}

impl ScenarioResult {
    /// The scenario's entry of `scenarios`.
    pub fn to_json(&self) -> Value {
        let mut estimators = Map::new();
        for ((name, s), (_, c)) in self.summaries.iter().zip(&self.consistency) {
            estimators.insert((*name).into(), Value::Object(estimator_json(s, c)));
        }
        let f = &self.floor_hover;
        let mut paired = Map::new();
        for other in PAIRED_AGAINST {
            if let Some(diffs) = self.paired(other) {
                let entry: Map<String, Value> = diffs
                    .iter()
                    .map(|(n, (m, lo, hi))| {
                        (
                            (*n).to_string(),
                            json!({"mean": json_number(*m), "ci95": json_pair((*lo, *hi))}),
                        )
                    })
                    .collect();
                paired.insert(format!("proposed_minus_{other}"), Value::Object(entry));
            }
        }
        json!({
            "name": self.scenario.name(),
            "paired": paired,
            "accel_limit_m_s2": self.scenario.accel_limit_m_s2(),
            "true_delay_s": self.true_delay_s,
            "delay_bound_s": json_number(self.delay_bound_s),
            "calibrated_delay_s": self.calibrated_delays_s,
            "calibration_rms_error_s": self.calibration_rms_error_s().map_or(Value::Null, json_number),
            "noise_floor": {
                "tilt_deg": f.tilt_rad.to_degrees(),
                "vel_m_s": f.velocity_norm_m_s,
                "pos_m": f.position_norm_m,
                "heading_mag_only_deg": f.heading_mag_only_rad.to_degrees(),
            },
            "estimators": estimators,
        })
    }
}

impl TablesResult {
    /// The run's JSON document: `duration_s`, `skip_s`, `seeds` and one entry per scenario.
    pub fn to_json(&self) -> Value {
        json!({
            "duration_s": self.options.duration_s,
            "skip_s": self.options.skip_s,
            "seeds": self.options.seeds,
            "scenarios": self.scenarios.iter().map(ScenarioResult::to_json).collect::<Vec<_>>(),
        })
    }
}

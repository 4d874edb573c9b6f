//! What a replay gives: [`ReplayReport`], one [`EstimatorReport`] per
//! estimator, as the JSON summary, the console's text and the CSV of the
//! delay loop's updates.

use super::{HealthSummary, LogScan, RegisteredEstimator, ReplaySetup};
use crate::replay::{LevelSummary, ReplayIntegrity, RunSummary, SkipCounts, SkipKind};
use serde_json::{Value, json};
use std::fmt;
use std::io::Write;

/// One estimator's replay: its scores and its health at the end.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorReport {
    /// The estimator (its name and what it is).
    pub estimator: &'static RegisteredEstimator,
    /// Its scores against the reference, counts and delay track.
    pub summary: RunSummary,
    /// What it reports about itself at the end.
    pub health: HealthSummary,
}

/// A whole replay: the setup, the log's counts and every estimator's report.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    /// What was replayed and how.
    pub setup: ReplaySetup,
    /// The log's records and skipped rows.
    pub scan: LogScan,
    /// One report per estimator, in the order they ran.
    pub estimators: Vec<EstimatorReport>,
}

/// The JSON's `rows_skipped`: `total`, `by_kind` (every [`SkipKind`]) and
/// `by_file` (`accepted` and the non-zero kinds).
fn skips_json(skips: &SkipCounts) -> Value {
    let by_kind: serde_json::Map<String, Value> = SkipKind::ALL
        .iter()
        .map(|&k| (k.name().to_string(), json!(skips.count(k))))
        .collect();
    let by_file: serde_json::Map<String, Value> = skips
        .files()
        .map(|(file, c)| {
            let mut entry = serde_json::Map::new();
            entry.insert("accepted".into(), json!(c.accepted));
            for k in SkipKind::ALL.iter().filter(|&&k| c.skipped(k) > 0) {
                entry.insert(k.name().into(), json!(c.skipped(*k)));
            }
            (file.to_string(), Value::Object(entry))
        })
        .collect();
    json!({ "total": skips.total(), "by_kind": by_kind, "by_file": by_file })
}

/// The console table's header row.
pub fn table_header() -> String {
    format!(
        "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}",
        "estimator", "delay_s", "roll_deg", "pitch_deg", "yaw_deg", "vel_m_s", "refused", "nonfin"
    )
}

impl EstimatorReport {
    /// The estimator's entry of the JSON's `estimators` (see the module
    /// docs); `skips`: the log's, written as its `rows_skipped`.
    pub fn to_json(&self, skips: &SkipCounts) -> Value {
        let s = &self.summary;
        let rms = s.reference_rms;
        let mut entry = json!({
            "estimator": self.estimator.name,
            "final_delay_s": s.final_delay_s,
            "delay_estimated": s.delay_estimated(),
            "delay_not_estimated_reason": s.delay_not_estimated,
            "offline_delay": s.offline_delay.as_ref().map(super::OfflineDelay::to_json),
            "delay_step": s.delay_step.map(|d| json!({
                "from_s": d.from_s,
                "added_s": d.added_s,
                "before_s": d.before_s,
                "final_s": d.final_s,
                "reference_s": d.reference_s,
                "target_s": d.target_s,
                "settled_after_s": d.settled_after_s,
            })),
            "delay_track": s.delay_track,
            "roll_rms_deg": rms.map(|r| r.roll_deg),
            "pitch_rms_deg": rms.map(|r| r.pitch_deg),
            "yaw_rms_deg": rms.map(|r| r.yaw_deg),
            "velocity_rms_m_s": rms.and_then(|r| r.velocity_m_s),
            "reference_samples_scored": rms.map_or(0, |r| r.samples),
            "reference_samples_unscored": s.reference_unscored,
            "samples_refused": s.samples_refused(),
            "refused_by_kind": s.refused,
            "non_finite_estimates": s.non_finite_estimates,
            "samples_pushed": { "imu": s.imu_pushed, "gps": s.gps_pushed, "mag": s.mag_pushed },
            "gps_position_fused": s.gps_position_fused,
            "gps_velocity_fused": s.gps_velocity_fused,
            "gps_gated": s.gps_gated,
            "mag_fused": s.mag_fused,
            "mag_gated": s.mag_gated,
            "rows_skipped": skips_json(skips),
        });
        entry["integrity"] = s.integrity.as_ref().map_or(Value::Null, integrity_json);
        entry["about"] = json!(self.estimator.about);
        entry["health"] = self.health.to_json();
        entry
    }

    /// The estimator's row of the console table ([`table_header`]):
    /// final delay, RMS roll, pitch, yaw, velocity, refused samples,
    /// non-finite estimates (`-` for what it does not have).
    pub fn table_row(&self) -> String {
        let s = &self.summary;
        let rms = s.reference_rms;
        let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |x| format!("{x:.3}"));
        format!(
            "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}",
            self.estimator.name,
            opt(s.final_delay_s),
            opt(rms.map(|r| r.roll_deg)),
            opt(rms.map(|r| r.pitch_deg)),
            opt(rms.map(|r| r.yaw_deg)),
            opt(rms.and_then(|r| r.velocity_m_s)),
            s.samples_refused(),
            s.non_finite_estimates,
        )
    }

    /// Why the estimator's delay was never estimated, one line (`-` in the
    /// table's `delay_s`), for an estimator with a delay that was not
    /// ([`RunSummary::delay_not_estimated`]).
    pub fn delay_not_estimated_line(&self) -> Option<String> {
        let reason = self.summary.delay_not_estimated.as_ref()?;
        Some(format!(
            "{}: delay_s - (not estimated: {reason})",
            self.estimator.name
        ))
    }

    /// How the delay estimate followed a delay step, one line, for an
    /// estimator with a delay estimate in a replay with a step.
    pub fn delay_step_line(&self) -> Option<String> {
        let opt = |v: Option<f64>, digits: usize| {
            v.map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
        };
        self.summary.delay_step.map(|d| {
            format!(
                "{}: delay step +{:.3} s at {:.1} s: before {} s, final {} s, without the added delay {} s, within 10 ms of the target {} s after {} s",
                self.estimator.name,
                d.added_s,
                d.from_s,
                opt(d.before_s, 4),
                opt(d.final_s, 4),
                opt(d.reference_s, 4),
                opt(d.target_s, 4),
                opt(d.settled_after_s, 1),
            )
        })
    }
}

impl ReplayReport {
    /// The JSON summary (`delaynav replay --json`; keys in the module docs).
    pub fn to_json(&self) -> Value {
        let setup = &self.setup;
        let (options, run) = (&setup.options, &setup.run);
        let counts = self.scan.counts;
        let seconds = |t: Option<u64>| t.map(|t| t as f64 * 1e-6);
        json!({
            "log": options.inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "format": setup.files.format.name(),
            "imu_instance": setup.reader.imu_instance,
            "counts": { "imu": counts.imu, "gps": counts.gps, "mag": counts.mag },
            "gps_delay_added_s": options.add_gps_delay_s,
            "gps_delay_added_from_s": options.add_delay_from_s,
            "replayed_from_s": seconds(run.start_us),
            "scored_from_s": seconds(run.score_from_us),
            "to_s": seconds(run.end_us),
            "window_s": [
                run.score_from_us.map(|t| t as f64 / 1e6),
                run.end_us.map(|t| t as f64 / 1e6),
            ],
            "declination_deg": setup.declination_rad.to_degrees(),
            "inclination_deg": setup.inclination_rad.to_degrees(),
            "imu_rate_hz": setup.imu_rate_hz,
            "accel_noise_density": setup.imu_noise.accel_noise_density,
            "gyro_noise_density": setup.imu_noise.gyro_noise_density,
            "accel_bias_random_walk": setup.accel_bias_random_walk,
            "trim_roll_rad": run.alignment.trim_roll_rad,
            "trim_pitch_rad": run.alignment.trim_pitch_rad,
            "derived": setup.derived.to_json(),
            "estimators": self.estimators.iter()
                .map(|e| e.to_json(&self.scan.skips))
                .collect::<Vec<_>>(),
        })
    }

    /// The console's lines on the delay under the table: the offline calibration
    /// ([`OfflineDelay::line`](super::OfflineDelay::line)), why a delay was not estimated
    /// ([`EstimatorReport::delay_not_estimated_line`]), then the delay steps
    /// ([`EstimatorReport::delay_step_line`]).
    pub fn delay_steps(&self) -> String {
        let offline = self.estimators.iter().filter_map(|e| {
            let o = e.summary.offline_delay.as_ref()?;
            Some(format!("{}: {}", e.estimator.name, o.line()))
        });
        let not_estimated = self
            .estimators
            .iter()
            .filter_map(EstimatorReport::delay_not_estimated_line);
        let steps = self
            .estimators
            .iter()
            .filter_map(EstimatorReport::delay_step_line);
        offline
            .chain(not_estimated)
            .chain(steps)
            .map(|line| line + "\n")
            .collect()
    }

    /// The console's health summary: a blank line, a heading, then each
    /// estimator's [`HealthSummary::lines`].
    pub fn health(&self) -> String {
        let mut out =
            "\nhealth at the end of the replay (docs/replay.md, \"Health summary\"):\n".to_string();
        for e in &self.estimators {
            out += &e.health.lines(e.estimator.name);
        }
        out
    }
}

/// The JSON's `integrity` of one estimator (docs/replay.md, "Protection levels").
fn integrity_json(i: &ReplayIntegrity) -> Value {
    let level = |l: &LevelSummary| {
        json!({
            "valid_share": l.valid_share,
            "median_level": l.median_level.filter(|m| m.is_finite()),
            "exceeded_share": l.exceeded_share,
        })
    };
    json!({
        "epochs": i.epochs,
        "availability": i.availability,
        "tilt_deg": level(&i.tilt),
        "heading_deg": level(&i.heading),
        "horizontal_m": level(&i.horizontal),
        "vertical_m": level(&i.vertical),
        "velocity_m_s": level(&i.velocity),
    })
}

impl EstimatorReport {
    /// The protection levels at the scored samples, two lines (`None`
    /// without a scored sample): the median level and the valid share per
    /// quantity, the availability, and the share of valid epochs whose
    /// difference from the onboard solution exceeds the level.
    pub fn integrity_lines(&self) -> Option<String> {
        let i = self.summary.integrity.as_ref()?;
        let median = |l: &LevelSummary, unit: &str| match l.median_level {
            Some(m) if m.is_finite() => format!("{m:.2} {unit}"),
            _ => "none".to_string(),
        };
        let share =
            |s: Option<f64>| s.map_or_else(|| "-".to_string(), |x| format!("{:.1}%", 100.0 * x));
        let quantities = [
            ("tilt", &i.tilt, "deg"),
            ("heading", &i.heading, "deg"),
            ("horizontal", &i.horizontal, "m"),
            ("vertical", &i.vertical, "m"),
            ("velocity", &i.velocity, "m/s"),
        ];
        let levels: Vec<String> = quantities
            .iter()
            .map(|(name, l, unit)| {
                format!(
                    "{name} {} (valid {:.1}%)",
                    median(l, unit),
                    100.0 * l.valid_share
                )
            })
            .collect();
        Some(format!(
            "  {}: median levels {}; all valid {:.1}% of {} epochs\n  {}: beyond the level against the onboard solution, of the valid epochs: tilt {}, heading {}, velocity {}\n",
            self.estimator.name,
            levels.join(", "),
            100.0 * i.availability,
            i.epochs,
            self.estimator.name,
            share(i.tilt.exceeded_share),
            share(i.heading.exceeded_share),
            share(i.velocity.exceeded_share),
        ))
    }
}

impl ReplayReport {
    /// The protection levels of every estimator at the scored samples
    /// ([`EstimatorReport::integrity_lines`]), under a heading line; empty
    /// when none was scored.
    pub fn integrity(&self) -> String {
        let lines: String = self
            .estimators
            .iter()
            .filter_map(EstimatorReport::integrity_lines)
            .collect();
        if lines.is_empty() {
            return lines;
        }
        format!(
            "\nprotection levels at the scored samples (docs/replay.md, \"Protection levels\"):\n{lines}"
        )
    }
}

impl fmt::Display for ReplayReport {
    /// What the console shows once the estimators have run: the table, the
    /// delay steps, the health summary.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", table_header())?;
        for e in &self.estimators {
            writeln!(f, "{}", e.table_row())?;
        }
        write!(
            f,
            "{}{}{}",
            self.delay_steps(),
            self.health(),
            self.integrity()
        )
    }
}

/// The CSV of every delay-loop update of each estimator that has a loop
/// (`delaynav replay --delay-windows`): `estimator, t_s, delay_s,
/// delay_std_s, status`, then per axis `n`, `e`, `d` its `_valid`,
/// `_delay_s`, `_peak`, `_accel_var` and `_interior`.
pub fn write_delay_windows<W: Write>(
    out: W,
    estimators: &[EstimatorReport],
) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(out);
    write!(w, "estimator,t_s,delay_s,delay_std_s,status")?;
    for axis in ["n", "e", "d"] {
        write!(
            w,
            ",{axis}_valid,{axis}_delay_s,{axis}_peak,{axis}_accel_var,{axis}_interior"
        )?;
    }
    writeln!(w)?;
    for e in estimators {
        for win in &e.summary.delay_windows {
            // The status's debug form may hold commas (out of range).
            let status = win.status.replace(',', ";");
            write!(
                w,
                "{},{:.3},{:.5},{:.5},{status}",
                e.estimator.name, win.t_s, win.delay_s, win.delay_std_s
            )?;
            for a in &win.axes {
                write!(
                    w,
                    ",{},{:.5},{:.4},{:.4},{}",
                    u8::from(a.valid),
                    a.measured_delay_s,
                    a.peak,
                    a.accel_variance,
                    u8::from(a.interior)
                )?;
            }
            writeln!(w)?;
        }
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replay::{DelayStepSummary, DelayWindow, ReferenceRms, WindowAxis};

    const ESTIMATORS_ABOUT: &str =
        "delay-compensated navigator: delay loop, delayed-horizon EKF, forward reckoning";

    fn report() -> EstimatorReport {
        let mut summary = RunSummary {
            imu_pushed: 10,
            final_delay_s: Some(0.2963),
            reference_rms: Some(ReferenceRms {
                samples: 5,
                roll_deg: 1.6961,
                pitch_deg: 1.1,
                yaw_deg: 2.4834,
                velocity_m_s: None,
            }),
            delay_step: Some(DelayStepSummary {
                from_s: 150.0,
                added_s: 0.2,
                before_s: Some(0.29551),
                final_s: Some(0.49041),
                reference_s: Some(0.2963),
                target_s: Some(0.4963),
                settled_after_s: None,
            }),
            ..RunSummary::default()
        };
        summary.refused.insert("StepTooLong".into(), 3);
        summary.delay_windows.push(DelayWindow {
            t_s: 50.2,
            delay_s: 0.25,
            delay_std_s: 0.01,
            status: "OutOfRange { low: 0.1, high: 0.5 }".into(),
            axes: [WindowAxis {
                valid: true,
                measured_delay_s: 0.24,
                peak: 0.95,
                accel_variance: 3.0,
                interior: false,
            }; 3],
        });
        EstimatorReport {
            estimator: &super::super::ESTIMATORS[0],
            summary,
            health: HealthSummary::default(),
        }
    }

    #[test]
    fn the_table_row_lines_up_under_the_header() {
        let r = report();
        assert_eq!(
            table_header(),
            "estimator   delay_s  roll_deg pitch_deg   yaw_deg    vel_m_s  refused   nonfin"
        );
        assert_eq!(
            r.table_row(),
            "proposed      0.296     1.696     1.100     2.483          -        3        0"
        );
        assert_eq!(
            r.delay_step_line().unwrap(),
            "proposed: delay step +0.200 s at 150.0 s: before 0.2955 s, final 0.4904 s, without \
             the added delay 0.2963 s, within 10 ms of the target 0.4963 s after - s"
        );
    }

    #[test]
    fn an_estimator_entry_has_every_key_of_the_contract() {
        let mut skips = SkipCounts::default();
        skips.accept("gps.csv");
        skips.skip("gps.csv", SkipKind::NoFix);
        let v = report().to_json(&skips);
        let keys: Vec<_> = v.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(
            keys,
            [
                "about",
                "delay_estimated",
                "delay_not_estimated_reason",
                "delay_step",
                "delay_track",
                "estimator",
                "final_delay_s",
                "gps_gated",
                "gps_position_fused",
                "gps_velocity_fused",
                "health",
                "integrity",
                "mag_fused",
                "mag_gated",
                "non_finite_estimates",
                "offline_delay",
                "pitch_rms_deg",
                "reference_samples_scored",
                "reference_samples_unscored",
                "refused_by_kind",
                "roll_rms_deg",
                "rows_skipped",
                "samples_pushed",
                "samples_refused",
                "velocity_rms_m_s",
                "yaw_rms_deg",
            ]
        );
        assert_eq!(v["estimator"], "proposed");
        assert_eq!(v["delay_estimated"], true);
        assert_eq!(v["delay_not_estimated_reason"], Value::Null);
        assert_eq!(v["about"], ESTIMATORS_ABOUT);
        assert_eq!(v["samples_refused"], 3);
        assert_eq!(v["refused_by_kind"], json!({"StepTooLong": 3}));
        assert_eq!(v["velocity_rms_m_s"], Value::Null);
        // No scored sample in this report: no levels.
        assert_eq!(v["integrity"], Value::Null);
        assert_eq!(v["reference_samples_scored"], 5);
        assert_eq!(v["delay_step"]["settled_after_s"], Value::Null);
        assert_eq!(v["delay_step"]["target_s"], 0.4963);
        assert_eq!(v["samples_pushed"], json!({"imu": 10, "gps": 0, "mag": 0}));
        assert_eq!(
            v["rows_skipped"],
            json!({
                "total": 1,
                "by_kind": {
                    "unparsable": 0, "non_finite": 0, "out_of_range": 0, "invalid": 0,
                    "no_fix": 1, "time_went_backwards": 0, "duplicate": 0,
                },
                "by_file": {"gps.csv": {"accepted": 1, "no_fix": 1}},
            })
        );
    }

    #[test]
    fn a_delay_never_estimated_is_null_false_and_a_dash_with_its_reason() {
        let mut r = report();
        r.summary.final_delay_s = None;
        r.summary.delay_step = None;
        r.summary.delay_not_estimated = Some("no valid update".into());
        let v = r.to_json(&SkipCounts::default());
        assert_eq!(v["final_delay_s"], Value::Null);
        assert_eq!(v["delay_estimated"], false);
        assert_eq!(v["delay_not_estimated_reason"], "no valid update");
        assert!(r.table_row().starts_with("proposed          -     1.696"));
        assert_eq!(
            r.delay_not_estimated_line().unwrap(),
            "proposed: delay_s - (not estimated: no valid update)"
        );
        assert_eq!(report().delay_not_estimated_line(), None);
    }

    #[test]
    fn the_delay_windows_csv_has_a_row_per_update_and_no_stray_comma() {
        let mut out = Vec::new();
        write_delay_windows(&mut out, &[report()]).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<_> = text.lines().collect();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].split(',').count(), 5 + 3 * 5);
        assert_eq!(lines[1].split(',').count(), 5 + 3 * 5);
        assert!(
            lines[1].starts_with(
                "proposed,50.200,0.25000,0.01000,OutOfRange { low: 0.1; high: 0.5 },1,0.24000,0.9500,3.0000,0"
            ),
            "{}",
            lines[1]
        );
    }
}

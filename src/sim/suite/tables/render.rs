//! The tables as text (markdown): what `reproduce` prints.

use super::score::Metrics;
use super::summary::{PAIRED_AGAINST, PAIRED_FIGURES};
use super::{ScenarioResult, TablesOptions, TablesResult};
use crate::sim::Scenario;
use crate::sim::suite::setup::{
    CALIBRATION_DURATION_S, CALIBRATION_SEED_OFFSET, UNCALIBRATED_START,
};
use core::fmt;

/// The paper's Table 6 for a scenario: (proposed, AEKF) per row, in the
/// order pitch, roll, yaw, velocity, position, delay.
pub fn paper_table6(scenario: Scenario) -> [(f64, f64); 6] {
    match scenario {
        Scenario::Low => [
            (0.059, 0.2237),
            (0.0616, 0.2868),
            (0.181, 0.3116),
            (0.0163, 0.0229),
            (0.381, 0.4462),
            (0.000678, 0.00396),
        ],
        Scenario::High => [
            (0.0878, 1.1467),
            (0.1276, 0.8195),
            (0.1644, 1.0829),
            (0.0192, 0.0425),
            (0.0344, 0.4896),
            (0.000492, 0.00506),
        ],
    }
}

/// The paper's Table 5 (scenario not stated): (EKF without delay handling,
/// proposed) for gyro x, y, z (rad/s) and accelerometer x, y, z (g).
pub const PAPER_TABLE5: [(f64, f64); 6] = [
    (0.000945, 0.000112),
    (0.000675, 0.000075),
    (0.000130, 0.000080),
    (0.055240, 0.009653),
    (0.057460, 0.006093),
    (0.043000, 0.005345),
];

/// A mean and the half-width of its 95 % interval.
fn fmt_ci(mean: f64, lo: f64, hi: f64) -> String {
    let half = 0.5 * (hi - lo);
    // The bound is the same on every seed: no interval to show.
    if half.abs() <= 1e-9 * mean.abs() {
        return fmt_value(mean);
    }
    if mean.is_finite() && lo.is_finite() && hi.is_finite() {
        format!("{} ±{}", fmt_value(mean), fmt_short(half))
    } else {
        fmt_value(mean)
    }
}

/// Two significant digits.
fn fmt_short(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x.abs() >= 0.01 {
        format!("{x:.3}")
    } else {
        format!("{x:.1e}")
    }
}

/// A figure as the tables print it: `fail` when not finite, four decimals, or two significant
/// digits in scientific notation below 0.01.
pub fn fmt_value(x: f64) -> String {
    if !x.is_finite() {
        "fail".into()
    } else if x == 0.0 {
        "0".into()
    } else if x.abs() >= 0.01 {
        format!("{x:.4}")
    } else {
        format!("{x:.2e}")
    }
}

/// One row of the RMSE table: label, how to read it, the paper's
/// (proposed, AEKF), and the floor column.
type TableRow<'a> = (
    &'a str,
    &'a dyn Fn(&Metrics) -> Option<f64>,
    Option<(f64, f64)>,
    String,
);

/// The printed tables of every scenario: the RMSE table beside the paper's figures and the
/// noise floor, the bias table beside the paper's Table 5, the paired differences, the
/// consistency table; then the footnote on the floor and the delay bound.
impl fmt::Display for TablesResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for r in &self.scenarios {
            r.fmt_rmse(f, &self.options)?;
            r.fmt_biases(f)?;
            r.fmt_paired(f)?;
            r.fmt_consistency(f)?;
        }
        writeln!(
            f,
            "\nfloor: steady-state error of an ideal filter with this noise at hover (docs/RESULTS.md); \
             delay bound: RMS over the scored fixes of 1/sqrt(sum |a|²/σv²) over the last 5 s of fixes."
        )
    }
}

impl ScenarioResult {
    fn names(&self) -> Vec<&'static str> {
        self.summaries.iter().map(|(n, _)| *n).collect()
    }

    fn fmt_rmse(&self, f: &mut fmt::Formatter<'_>, options: &TablesOptions) -> fmt::Result {
        let names = self.names();
        writeln!(
            f,
            "\n### `{}`: acceleration limit {} m/s², true delay {} s; mean ±95 % t-interval over {} seeds of the RMSE after {} s of {} s\n",
            self.scenario.name(),
            self.scenario.accel_limit_m_s2(),
            self.true_delay_s,
            options.seeds.len(),
            options.skip_s,
            options.duration_s
        )?;
        let start = match self.calibration_rms_error_s() {
            Some(rms) => format!(
                "`proposed`, `calibrated` and `aekf17` start from an offline delay calibration on a separate \
                 {CALIBRATION_DURATION_S} s run (seed + {CALIBRATION_SEED_OFFSET}): {} s per seed, \
                 RMS error {:.2} ms",
                self.calibrated_delays_s
                    .iter()
                    .map(|d| format!("{d:.4}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                rms * 1e3
            ),
            None => format!(
                "`proposed` and `aekf17` start from {} s, uncalibrated",
                UNCALIBRATED_START.delay_s
            ),
        };
        writeln!(f, "{start}\n")?;
        writeln!(
            f,
            "| RMSE | {} | paper proposed | paper AEKF | floor |",
            names.join(" | ")
        )?;
        writeln!(f, "|---|{}---|---|---|", "---|".repeat(names.len()))?;
        let paper = paper_table6(self.scenario);
        let fl = &self.floor_hover;
        let tilt_floor = fmt_value(fl.tilt_rad.to_degrees());
        let heading_floor = format!(
            "{} (mag only)",
            fmt_value(fl.heading_mag_only_rad.to_degrees())
        );
        let rows: [TableRow; 8] = [
            (
                "pitch (deg)",
                &|s| Some(s.pitch_deg),
                Some(paper[0]),
                tilt_floor.clone(),
            ),
            (
                "roll (deg)",
                &|s| Some(s.roll_deg),
                Some(paper[1]),
                tilt_floor.clone(),
            ),
            (
                "yaw (deg)",
                &|s| Some(s.yaw_deg),
                Some(paper[2]),
                heading_floor.clone(),
            ),
            ("tilt (deg)", &|s| Some(s.tilt_deg), None, tilt_floor),
            (
                "heading (deg)",
                &|s| Some(s.heading_deg),
                None,
                heading_floor,
            ),
            (
                "velocity (m/s)",
                &|s| Some(s.vel_m_s),
                Some(paper[3]),
                fmt_value(fl.velocity_norm_m_s),
            ),
            (
                "position (m)",
                &|s| Some(s.pos_m),
                Some(paper[4]),
                fmt_value(fl.position_norm_m),
            ),
            (
                "delay (s)",
                &|s| s.delay_s,
                Some(paper[5]),
                format!("{} (bound)", fmt_value(self.delay_bound_s)),
            ),
        ];
        for (label, get, paper, floor) in rows {
            let ours: Vec<String> = self
                .summaries
                .iter()
                .map(|(_, s)| {
                    get(&s.mean).map_or("-".into(), |m| {
                        fmt_ci(
                            m,
                            get(&s.lo).unwrap_or(f64::NAN),
                            get(&s.hi).unwrap_or(f64::NAN),
                        )
                    })
                })
                .collect();
            let (p_prop, p_aekf) = paper.map_or(("-".into(), "-".into()), |(p, a)| {
                (fmt_value(p), fmt_value(a))
            });
            writeln!(
                f,
                "| {label} | {} | {p_prop} | {p_aekf} | {floor} |",
                ours.join(" | "),
            )?;
        }
        let timing: Vec<String> = self
            .summaries
            .iter()
            .map(|(_, s)| format!("{:.2}", s.mean.us_per_imu_sample))
            .collect();
        writeln!(f, "| µs per IMU sample | {} | | | |", timing.join(" | "))?;
        // The calibrated runs' delay RMSE as medians too.
        let delay_medians: Vec<String> = self
            .summaries
            .iter()
            .filter_map(|(name, s)| Some(format!("{name} {:.2}", s.median.delay_s? * 1e3)))
            .collect();
        writeln!(
            f,
            "\nDelay RMSE, median over the seeds (ms): {}",
            delay_medians.join(", ")
        )
    }

    fn fmt_biases(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names = self.names();
        writeln!(
            f,
            "\nBias RMSE (`{}`; the paper's Table 5 beside, scenario not stated there)\n",
            self.scenario.name()
        )?;
        writeln!(
            f,
            "| bias | {} | paper EKF | paper proposed |",
            names.join(" | ")
        )?;
        writeln!(f, "|---|{}---|---|", "---|".repeat(names.len()))?;
        let labels = [
            "gyro x (rad/s)",
            "gyro y (rad/s)",
            "gyro z (rad/s)",
            "accel x (g)",
            "accel y (g)",
            "accel z (g)",
        ];
        for (i, label) in labels.iter().enumerate() {
            let ours: Vec<String> = self
                .summaries
                .iter()
                .map(|(_, s)| {
                    let get = |m: &Metrics| {
                        if i < 3 {
                            m.gyro_bias_rad_s[i]
                        } else {
                            m.accel_bias_g[i - 3]
                        }
                    };
                    fmt_ci(get(&s.mean), get(&s.lo), get(&s.hi))
                })
                .collect();
            let (p_ekf, p_prop) = PAPER_TABLE5[i];
            writeln!(
                f,
                "| {label} | {} | {} | {} |",
                ours.join(" | "),
                fmt_value(p_ekf),
                fmt_value(p_prop)
            )?;
        }
        Ok(())
    }

    fn fmt_paired(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "\nPaired differences (`{}`): `proposed` minus each row on the same seeds, mean \
             ±95 % t-interval; negative: `proposed` lower\n",
            self.scenario.name()
        )?;
        writeln!(
            f,
            "| proposed minus | {} |",
            PAIRED_FIGURES
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(" | ")
        )?;
        writeln!(f, "|---|{}", "---|".repeat(PAIRED_FIGURES.len()))?;
        for other in PAIRED_AGAINST {
            if let Some(diffs) = self.paired(other) {
                let cells: Vec<String> = diffs
                    .iter()
                    .map(|(_, (m, lo, hi))| fmt_ci(*m, *lo, *hi))
                    .collect();
                writeln!(f, "| {other} | {} |", cells.join(" | "))?;
            }
        }
        Ok(())
    }

    fn fmt_consistency(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "\nConsistency (`{}`): NEES of [position, velocity] (6 dof, the filter's own covariance \
             at the instant its estimate describes), every 100 ms, averaged over the seeds; GPS NIS \
             (6 dof, diagonal of S) over every scored fix\n",
            self.scenario.name()
        )?;
        writeln!(
            f,
            "| estimator | NEES mean | NEES 95 % band | instants in band | NIS mean | NIS 95 % band |"
        )?;
        writeln!(f, "|---|---|---|---|---|---|")?;
        for (name, c) in &self.consistency {
            if c.nees_mean.is_nan() && c.nis_mean.is_nan() && c.nis_band.0.is_nan() {
                // The bound: no estimate, no innovations.
                continue;
            }
            writeln!(
                f,
                "| {name} | {} | [{:.2}, {:.2}] | {:.0} % | {} | [{:.2}, {:.2}] |",
                fmt_value(c.nees_mean),
                c.nees_band.0,
                c.nees_band.1,
                100.0 * c.nees_in_band,
                fmt_value(c.nis_mean),
                c.nis_band.0,
                c.nis_band.1
            )?;
        }
        Ok(())
    }
}

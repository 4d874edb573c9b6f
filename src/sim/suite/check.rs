//! Verdicts: a suite's rows judged as one pass or fail.
//!
//! Every suite turns its rows into [`Verdict`]s (`TablesResult::verdicts`,
//! `FaultsResult::verdicts`, `DelayResult::verdicts`); [`judge`] weighs them against a list of
//! known failures. A run fails when a verdict does not hold (it failed, or its figure is NaN or
//! missing) and is not listed as known, or when a listed name does not exist or passes (so the
//! list cannot go stale). The command line's `--check` and `--known-failures` are this function:
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --check
//! cargo run --release --features sim --example reproduce -- --faults --check
//! cargo run --release --features sim --example reproduce -- --delay-suite --check \
//!     --known-failures cold_start_low,delay_ramp
//! ```

use core::fmt::{self, Write as _};

/// One verdict of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The row's name (unique in a run).
    pub name: String,
    /// The run's own verdict on the measured figure.
    pub passed: bool,
    /// The figure judged; `None` when the run has none (no estimate).
    pub measured: Option<f64>,
    /// The limit, as printed.
    pub limit: String,
}

impl Verdict {
    /// Passed, on a finite figure.
    pub fn holds(&self) -> bool {
        self.passed && self.measured.is_some_and(f64::is_finite)
    }
}

/// What [`judge`] found: the printed report and the reasons the run fails.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    /// One line per verdict (`PASS`, `FAIL`, `FAIL (known)`, `PASS (listed as known failure)`),
    /// then a count; starts with an empty line.
    pub report: String,
    /// Why the run fails: a verdict that does not hold and is not known, a known name that no
    /// verdict has, or one whose verdict holds. Empty when the run passes.
    pub failures: Vec<String>,
}

impl Judgement {
    /// Whether the run passes.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// Why the run fails, on one line (`--check: REASON; REASON`); `None` when it passes.
    pub fn failure(&self) -> Option<String> {
        (!self.passed()).then(|| format!("--check: {}", self.failures.join("; ")))
    }
}

impl fmt::Display for Judgement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.report)
    }
}

/// Judges every verdict against the names of `known` failures (see the module's docs).
pub fn judge(verdicts: &[Verdict], known: &[String]) -> Judgement {
    let mut failures = Vec::new();
    let mut out = String::from("\ncheck:\n");
    for v in verdicts {
        let listed = known.contains(&v.name);
        let status = match (v.holds(), listed) {
            (true, false) => "PASS",
            (false, true) => "FAIL (known)",
            (false, false) => {
                failures.push(format!("{} failed", v.name));
                "FAIL"
            }
            (true, true) => {
                failures.push(format!(
                    "{} passes but is listed in --known-failures",
                    v.name
                ));
                "PASS (listed as known failure)"
            }
        };
        let measured = v
            .measured
            .map_or_else(|| "none".to_string(), |x| format!("{x:.4}"));
        let _ = writeln!(
            out,
            "  {status:<31} {:<48} measured {measured:>10}  limit {}",
            v.name, v.limit
        );
    }
    for name in known {
        if !verdicts.iter().any(|v| &v.name == name) {
            failures.push(format!(
                "--known-failures names {name}, which this run has not"
            ));
        }
    }
    let _ = writeln!(
        out,
        "check: {} verdicts, {} failing, {} known failures listed: {}",
        verdicts.len(),
        verdicts.iter().filter(|v| !v.holds()).count(),
        known.len(),
        if failures.is_empty() { "ok" } else { "FAILED" }
    );
    Judgement {
        report: out,
        failures,
    }
}

/// The largest of `ratios` (name, ratio); the first NaN when one is NaN,
/// NaN when there is none.
pub(crate) fn worst(ratios: impl IntoIterator<Item = (&'static str, f64)>) -> (&'static str, f64) {
    let ratios: Vec<_> = ratios.into_iter().collect();
    ratios
        .iter()
        .find(|(_, r)| r.is_nan())
        .or_else(|| ratios.iter().max_by(|a, b| a.1.total_cmp(&b.1)))
        .copied()
        .unwrap_or(("none", f64::NAN))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn verdict(name: &str, passed: bool, measured: Option<f64>) -> Verdict {
        Verdict {
            name: name.into(),
            passed,
            measured,
            limit: "<= 1".into(),
        }
    }

    #[test]
    fn a_failing_or_nan_row_fails_the_run() {
        let rows = [verdict("a", true, Some(0.5)), verdict("b", true, Some(0.9))];
        assert!(judge(&rows, &[]).passed());
        assert_eq!(judge(&rows, &[]).failure(), None);
        let failing = [
            verdict("a", true, Some(0.5)),
            verdict("b", false, Some(2.0)),
        ];
        assert_eq!(judge(&failing, &[]).failures, ["b failed"]);
        // A NaN or missing figure fails even where the row says it passed.
        let nan = [verdict("a", true, Some(f64::NAN)), verdict("b", true, None)];
        assert_eq!(judge(&nan, &[]).failures, ["a failed", "b failed"]);
        assert_eq!(
            judge(&nan, &[]).failure().as_deref(),
            Some("--check: a failed; b failed")
        );
        let judgement = judge(&failing, &[]);
        assert!(!judgement.passed());
        assert!(
            judgement
                .to_string()
                .ends_with("known failures listed: FAILED\n")
        );
    }

    #[test]
    fn known_failures_pass_only_while_they_fail_and_exist() {
        let rows = [
            verdict("a", false, Some(2.0)),
            verdict("b", true, Some(0.5)),
        ];
        assert!(judge(&rows, &["a".into()]).passed());
        assert_eq!(
            judge(&rows, &["a".into(), "b".into()]).failures,
            ["b passes but is listed in --known-failures"]
        );
        assert_eq!(
            judge(&rows, &["a".into(), "c".into()]).failures,
            ["--known-failures names c, which this run has not"]
        );
    }

    #[test]
    fn worst_takes_the_largest_and_keeps_a_nan() {
        assert_eq!(worst([("x", 1.0), ("y", 3.0), ("z", 2.0)]), ("y", 3.0));
        let (name, x) = worst([("x", 1.0), ("y", f64::NAN), ("z", 2.0)]);
        assert!(name == "y" && x.is_nan());
        assert!(worst([]).1.is_nan());
    }
}

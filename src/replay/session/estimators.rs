//! The estimators a replay can run ([`ESTIMATORS`]), and the run itself:
//! each estimator through the log's window ([`ReplaySetup::run`]), watched
//! by a [`ReplayObserver`].

use super::{EstimatorReport, HealthSummary, LogScan, ReplayReport, ReplaySetup};
use crate::estimate::{Estimate, Navigator};
use crate::integrity::Integrity;
use crate::replay::{
    DelayStep, FusionRecords, LogReader, ReaderOptions, ReferenceReader, ReplayError, RunOptions,
    RunSummary, replay_with,
};
use crate::{AugmentedEkf17, AugmentedEkf17Config, DelayCompensatedNav, Ekf16, Health};

/// What watches a replay: progress, every estimate, each estimator's
/// report. Every method does nothing by default; `()` watches nothing.
pub trait ReplayObserver {
    /// A pass of `estimator` through the window starts; `length_s`: the
    /// window's length in whole seconds when it has an end. A delay step
    /// makes two passes per estimator (the first without the added delay).
    fn started(&mut self, estimator: &str, length_s: Option<u64>) {
        let _ = (estimator, length_s);
    }

    /// Whole seconds of the window replayed so far (after every estimate).
    fn progress(&mut self, replayed_s: u64) {
        let _ = replayed_s;
    }

    /// Every finite estimate of the reported pass (not of the pass without
    /// the added delay). An error ends the replay once the pass is over
    /// ([`ReplayError::Output`]; the first one is kept).
    fn estimate(
        &mut self,
        estimator: &str,
        estimate: &Estimate<f64>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let _ = (estimator, estimate);
        Ok(())
    }

    /// [`Self::estimate`] with the estimator's protection levels and
    /// validity flags at that sample, computed only when `integrity` is
    /// called: override this one to record them. By default it calls
    /// [`Self::estimate`].
    fn estimate_with_integrity(
        &mut self,
        estimator: &str,
        estimate: &Estimate<f64>,
        integrity: &dyn Fn() -> Integrity<f64>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let _ = integrity;
        self.estimate(estimator, estimate)
    }

    /// The pass started last has ended.
    fn finished(&mut self) {}

    /// An estimator's report is complete (its table row can be printed).
    fn report(&mut self, report: &EstimatorReport) {
        let _ = report;
    }
}

impl ReplayObserver for () {}

/// One pass through the window: how the log is read, the window, and who
/// watches.
struct Pass<'a> {
    reader: ReaderOptions,
    run: RunOptions,
    observer: &'a mut dyn ReplayObserver,
    /// Estimates go to the observer (the reported pass).
    reported: bool,
}

/// What one pass of an estimator gives: its scores and its health at the end.
type Outcome = Result<(RunSummary, HealthSummary), ReplayError>;

/// One estimator the replay can run. Adding one is one entry of
/// [`ESTIMATORS`].
pub struct RegisteredEstimator {
    /// Its name (`--estimator NAME`, the JSON's `estimator`).
    pub name: &'static str,
    /// One line on what it is (the JSON's `about`).
    pub about: &'static str,
    run: fn(&ReplaySetup, &mut Pass) -> Outcome,
}

impl PartialEq for RegisteredEstimator {
    /// The same name.
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl core::fmt::Debug for RegisteredEstimator {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("RegisteredEstimator")
            .field("name", &self.name)
            .field("about", &self.about)
            .finish_non_exhaustive()
    }
}

/// Every estimator a replay can run, in report order, each configured from
/// [`ReplaySetup::nav`] (the filters from its `ekf`).
pub const ESTIMATORS: &[RegisteredEstimator] = &[
    RegisteredEstimator {
        name: "proposed",
        about: "delay-compensated navigator: delay loop, delayed-horizon EKF, forward reckoning",
        run: |setup, pass| {
            // The offline calibration first: the online loop's start and range.
            let offline = setup.offline_delay(&pass.reader)?;
            let config = setup.nav_with_offline(offline.as_ref());
            let mut nav = DelayCompensatedNav::<f64>::new(config)?;
            let mut summary = run_one(setup, pass, "proposed", &mut nav)?;
            summary.offline_delay = offline;
            let health = nav.health();
            withhold_unestimated_delay(&mut summary, &health);
            let mut health = HealthSummary::of_navigator(&health);
            let delay_loop = nav.delay_loop();
            if let Some(status) = health.delay_status.as_mut()
                && delay_loop.gps_rate_changes() > 0
            {
                *status += &format!(
                    ", followed {} GPS rate changes (now {:.2} Hz)",
                    delay_loop.gps_rate_changes(),
                    delay_loop.config().gps_rate_hz
                );
            }
            Ok((summary, health))
        },
    },
    RegisteredEstimator {
        name: "aekf17",
        about: "17-state augmented EKF with the delay as a state (the paper's baseline)",
        run: |setup, pass| {
            let config = AugmentedEkf17Config::with_nav(setup.ekf16_config());
            let mut nav = AugmentedEkf17::new(config)?;
            let summary = run_one(setup, pass, "aekf17", &mut nav)?;
            let health = HealthSummary::of_aekf17(&nav, nav.estimate().is_some());
            Ok((summary, health))
        },
    },
    RegisteredEstimator {
        name: "ekf16",
        about: "16-state EKF, GPS fused as if current (no delay handling)",
        run: |setup, pass| {
            let mut nav = Ekf16::new(setup.ekf16_config())?;
            let summary = run_one(setup, pass, "ekf16", &mut nav)?;
            let mut health = HealthSummary::of_filter(nav.refusals(), nav.last_gps_reset());
            health.initialized(nav.estimate().is_some());
            Ok((summary, health))
        },
    },
];

/// A delay never estimated is never reported as one: when the navigator's
/// delay is not valid at the end ([`Health::delay_valid`]: no valid update of
/// its delay loop, or a delay outside the loop's range) or is fixed by its
/// configuration, `final_delay_s` is `None` and `delay_not_estimated` says
/// why (the status, and the value that is not an estimate).
fn withhold_unestimated_delay(summary: &mut RunSummary, health: &Health<f64>) {
    let d = &health.delay;
    let reason = match d.status {
        None => format!("fixed by the configuration at {:.3} s", d.delay_s),
        Some(_) if health.delay_valid => return,
        Some(status) if d.valid_updates == 0 => format!(
            "no valid update of the delay loop ({status}); {:.3} s is its start value",
            d.delay_s
        ),
        Some(status) => format!(
            "the delay lies outside the loop's range ({status}); {:.3} s is not an estimate",
            d.delay_s
        ),
    };
    summary.final_delay_s = None;
    summary.delay_not_estimated = Some(reason);
}

/// The names a replay understands, including those not built yet.
const PLANNED: [&str; 3] = ["proposed", "aekf17", "ekf16"];

/// The estimators named `name` (one of [`ESTIMATORS`], or `all`); another
/// name is [`ReplayError::UnknownEstimator`] listing the available ones.
pub fn select_estimators(name: &str) -> Result<Vec<&'static RegisteredEstimator>, ReplayError> {
    if name == "all" {
        return Ok(ESTIMATORS.iter().collect());
    }
    if let Some(r) = ESTIMATORS.iter().find(|r| r.name == name) {
        return Ok(vec![r]);
    }
    let available: Vec<_> = ESTIMATORS.iter().map(|r| r.name).chain(["all"]).collect();
    Err(ReplayError::UnknownEstimator {
        name: name.to_string(),
        planned: PLANNED.contains(&name),
        available: available.join(", "),
    })
}

/// Replays `nav` through the pass's window and scores it.
fn run_one<N: Navigator<f64> + FusionRecords<f64>>(
    setup: &ReplaySetup,
    pass: &mut Pass,
    name: &str,
    nav: &mut N,
) -> Result<RunSummary, ReplayError> {
    let events = LogReader::<f64>::open(&setup.files, &pass.reader)?;
    let reference = ReferenceReader::open(&setup.files)?;
    let start_us = pass.run.start_us.unwrap_or(0);
    let length_s = pass
        .run
        .end_us
        .map(|end| end.saturating_sub(start_us) / 1_000_000);
    let (observer, reported) = (&mut *pass.observer, pass.reported);
    observer.started(name, length_s);
    let mut output_error = None;
    let summary = replay_with(
        nav,
        events,
        reference,
        &pass.run,
        |e: &Estimate<f64>, nav| {
            observer.progress(e.t_us.saturating_sub(start_us) / 1_000_000);
            if reported
                && output_error.is_none()
                && let Err(err) = observer.estimate_with_integrity(name, e, &|| nav.integrity())
            {
                output_error = Some(err);
            }
        },
    );
    observer.finished();
    match output_error {
        Some(err) => Err(ReplayError::Output(err)),
        None => Ok(summary),
    }
}

impl ReplaySetup {
    /// Replays each of `estimators` through the window and scores it
    /// against the log's reference; `scan` is [`Self::scan`]'s. With a delay
    /// step ([`ReplayOptions::add_delay_from_s`](super::ReplayOptions::add_delay_from_s)),
    /// each estimator is first replayed without the added delay, the
    /// reference of its step. `observer` sees every pass and each report
    /// as it completes.
    pub fn run(
        &self,
        scan: LogScan,
        estimators: &[&'static RegisteredEstimator],
        observer: &mut dyn ReplayObserver,
    ) -> Result<ReplayReport, ReplayError> {
        let mut reports = Vec::new();
        for r in estimators {
            let mut run = self.run;
            if let Some(step) = run.delay_step {
                // The reference of the step: the same replay without the added delay.
                let mut without = Pass {
                    reader: ReaderOptions {
                        gps_delay_added_us: 0,
                        ..self.reader
                    },
                    run: RunOptions {
                        delay_step: None,
                        ..self.run
                    },
                    observer: &mut *observer,
                    reported: false,
                };
                let (summary, _) = (r.run)(self, &mut without)?;
                run.delay_step = Some(DelayStep {
                    reference_s: summary.final_delay_s,
                    ..step
                });
            }
            let mut pass = Pass {
                reader: self.reader,
                run,
                observer: &mut *observer,
                reported: true,
            };
            let (summary, health) = (r.run)(self, &mut pass)?;
            let report = EstimatorReport {
                estimator: r,
                summary,
                health,
            };
            observer.report(&report);
            reports.push(report);
        }
        Ok(ReplayReport {
            setup: self.clone(),
            scan,
            estimators: reports,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_names_every_estimator_and_one_name_its_own() {
        let names = |v: Vec<&RegisteredEstimator>| v.iter().map(|r| r.name).collect::<Vec<_>>();
        assert_eq!(
            names(select_estimators("all").unwrap()),
            ["proposed", "aekf17", "ekf16"]
        );
        assert_eq!(names(select_estimators("aekf17").unwrap()), ["aekf17"]);
        for r in ESTIMATORS {
            assert!(PLANNED.contains(&r.name) && !r.about.is_empty());
        }
    }

    #[test]
    fn an_unknown_name_lists_the_available_ones() {
        let err = select_estimators("nope").unwrap_err();
        assert!(
            matches!(&err, ReplayError::UnknownEstimator { planned: false, .. }),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "estimator `nope` is unknown; available: proposed, aekf17, ekf16, all"
        );
    }
}

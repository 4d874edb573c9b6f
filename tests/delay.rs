//! delay: fractional delay line, whitening FIR, gain fusion, the delay loop
//! on synthetic truth (tests/common), offline calibration; f32 and f64.

mod common;

use common::{Event, Lcg, Motion, Scenario};
use delaynav::delay::*;
use delaynav::{Error, Gps, Imu};
use nalgebra::{SVector, Vector3};

/// The loop's trace: (time s, delay s, validities) per update.
struct Trace {
    updates: Vec<(f64, f64, [bool; 3], bool)>,
    multiply_adds_per_fix: Vec<u64>,
}

macro_rules! delay_tests {
    ($mod:ident, $t:ty, $tol:expr) => {
        mod $mod {
            use super::*;
            type T = $t;
            const TOL: f64 = $tol;

            fn v3(a: [f64; 3]) -> Vector3<T> {
                Vector3::new(a[0] as T, a[1] as T, a[2] as T)
            }

            fn run(
                scenario: &Scenario,
                motion: &Motion,
                delay: impl Fn(f64) -> f64,
                config: DelayLoopConfig<T>,
            ) -> Trace {
                let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
                let mut trace = Trace { updates: vec![], multiply_adds_per_fix: vec![] };
                for event in scenario.events(motion, &delay) {
                    match event {
                        Event::Imu(t, a) => delay_loop.push_imu(t, v3(a)).unwrap(),
                        Event::Gps(t, v) => {
                            let before = delay_loop.multiply_adds();
                            let update = delay_loop.push_gps(t, v3(v)).unwrap();
                            trace.multiply_adds_per_fix.push(delay_loop.multiply_adds() - before);
                            if let Some(u) = update {
                                assert!(u.delay_s.is_finite() && u.delay_std_s.is_finite());
                                trace.updates.push((
                                    t as f64 * 1e-6,
                                    u.delay_s as f64,
                                    u.axes.map(|a| a.valid),
                                    u.reacquired,
                                ));
                            }
                        }
                    }
                }
                trace
            }

            fn rmse_after(trace: &Trace, from_s: f64, truth: f64) -> f64 {
                let tail: Vec<f64> = trace.updates.iter().filter(|u| u.0 >= from_s).map(|u| u.1 - truth).collect();
                assert!(tail.len() > 10, "too few updates after {from_s} s");
                (tail.iter().map(|e| e * e).sum::<f64>() / tail.len() as f64).sqrt()
            }

            fn start_at(delay_s: f64) -> DelayLoopConfig<T> {
                let mut config = DelayLoopConfig::<T>::clean_input();
                config.fusion.initial_delay_s = delay_s as T;
                config
            }

            /// RMSE over the last 60 s of a 120 s run at a constant delay `tau`.
            fn constant_delay_rmse(mut scenario: Scenario, motion: &Motion, tau: f64, seed: u64, start_s: f64) -> f64 {
                scenario.seed = seed;
                scenario.duration_s = 120.0;
                let trace = run(&scenario, motion, |_| tau, start_at(start_s));
                rmse_after(&trace, 60.0, tau)
            }

            /// RMS over seeds of the per-run RMSE, and the worst run.
            fn over_seeds(scenario: fn() -> Scenario, motion_seed: u64, rms: [f64; 3], tau: f64, start_s: f64) -> (f64, f64) {
                let runs: Vec<f64> = (1..=8u64)
                    .map(|seed| {
                        let motion = Motion::random(motion_seed + seed, 8, 0.05, 1.0, rms);
                        constant_delay_rmse(scenario(), &motion, tau, seed, start_s)
                    })
                    .collect();
                let rms = (runs.iter().map(|r| r * r).sum::<f64>() / runs.len() as f64).sqrt();
                (rms, runs.iter().copied().fold(0.0, f64::max))
            }

            /// A delay drifting at 1 ms/s (0.2 to 0.32 s over 120 s) under continuous
            /// strong motion (simulator-like, 6/6/3 m/s^2 rms): with the drift-rate
            /// state (1 ms/s, 1000 s) the loop follows it within a few ms over the
            /// last 60 s; the scalar filter lags by its time constant.
            #[test]
            fn drift_is_followed_with_the_rate_state() {
                let drift = |t: f64| 0.2 + 1e-3 * t;
                let rmse = |rate_std: f64| {
                    let runs: Vec<f64> = (1..=4u64)
                        .map(|seed| {
                            let mut scenario = Scenario::simulator();
                            scenario.seed = seed;
                            scenario.duration_s = 120.0;
                            let motion = Motion::random(40 + seed, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                            let mut config = start_at(0.2);
                            config.fusion.rate_std = rate_std as T;
                            config.fusion.rate_time_constant_s = 1000.0;
                            let trace = run(&scenario, &motion, drift, config);
                            let tail: Vec<f64> =
                                trace.updates.iter().filter(|u| u.0 >= 60.0).map(|u| u.1 - drift(u.0)).collect();
                            (tail.iter().map(|e| e * e).sum::<f64>() / tail.len() as f64).sqrt()
                        })
                        .collect();
                    (runs.iter().map(|r| r * r).sum::<f64>() / runs.len() as f64).sqrt()
                };
                let (scalar, with_rate) = (rmse(0.0), rmse(1e-3));
                println!("1 ms/s drift, RMSE over the last 60 s (RMS of 4 runs): scalar {:.2} ms, with the rate {:.2} ms", scalar * 1e3, with_rate * 1e3);
                // Measured: scalar 21.2 ms, with the rate 5.9 ms (f32 and f64).
                assert!(with_rate < 8e-3 && with_rate < 0.4 * scalar, "{with_rate} vs {scalar}");
            }

            /// Simulator-like: IMU 1 kHz, GPS 10 Hz, strong motion (6/6/3 m/s^2 rms),
            /// true delay 0.2 s (on the grid) and 0.237 s (between grid samples),
            /// starting 0.1 s off; 8 motions and noise realizations each.
            #[test]
            fn recovers_constant_delay_simulator() {
                for tau in [0.2, 0.237] {
                    let (rms, worst) = over_seeds(Scenario::simulator, 30, [6.0, 6.0, 3.0], tau, tau - 0.1);
                    println!("simulator tau {tau}: RMSE over the last 60 s, RMS of 8 runs {:.2} ms, worst {:.2} ms", rms * 1e3, worst * 1e3);
                    assert!(rms < 3e-3 && worst < 5e-3, "RMSE {rms}, worst {worst}");
                }
            }

            /// Real-log-like: IMU 50 Hz with +-2 ms jitter, GPS 5 Hz with +-12 ms
            /// receive jitter, moderate motion (3/3/1.5 m/s^2 rms), delay 0.28 s and
            /// the 0.58 s of the log with 0.3 s added.
            #[test]
            fn recovers_constant_delay_real_log_rates() {
                for tau in [0.28, 0.58] {
                    let (rms, worst) = over_seeds(Scenario::real_log_like, 40, [3.0, 3.0, 1.5], tau, 0.2);
                    println!("50 Hz / 5 Hz tau {tau}: RMSE over the last 60 s, RMS of 8 runs {:.2} ms, worst {:.2} ms", rms * 1e3, worst * 1e3);
                    // Noise-limited: the Cramer-Rao bound of a 50 s average at this
                    // motion and 0.1 (m/s)^2 at 5 Hz is about 4.5 ms.
                    assert!(rms < 7e-3 && worst < 12e-3, "RMSE {rms}, worst {worst}");
                }
            }

            /// A step of the delay from 0.1 s to 0.3 s at 60 s is tracked: within
            /// 10 ms of the new delay 20 s after the step, and stays there.
            #[test]
            fn tracks_delay_step() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 140.0;
                let motion = Motion::random(21, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                let step_at = 60.0;
                let tau = |t: f64| if t < step_at { 0.1 } else { 0.3 };
                let trace = run(&scenario, &motion, tau, start_at(0.1));
                let before = rmse_after(&Trace { updates: trace.updates.iter().copied().filter(|u| u.0 < step_at).collect(), multiply_adds_per_fix: vec![] }, 30.0, 0.1);
                let settled = trace
                    .updates
                    .iter()
                    .filter(|u| u.0 >= step_at)
                    .rev()
                    .take_while(|u| (u.1 - 0.3).abs() < 0.01)
                    .last()
                    .map(|u| u.0 - step_at)
                    .unwrap();
                println!("before the step: RMSE {:.2} ms; within 10 ms of 0.3 s from {settled:.1} s after the step", before * 1e3);
                assert!(before < 5e-3);
                assert!(settled < 20.0, "settled after {settled} s");
                assert!(trace.updates.iter().any(|u| u.3), "the step should trigger a re-acquisition");
            }

            /// The caller may push each GPS fix before the IMU samples leading up to
            /// its receive time (here 0.3 s early in the call order): the GPS grid
            /// samples wait for the IMU stream and the estimate is as good.
            #[test]
            fn gps_pushed_ahead_of_imu() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 90.0;
                let motion = Motion::random(33, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                let mut events = scenario.events(&motion, |_| 0.2);
                events.sort_by_key(|e| match *e {
                    Event::Imu(t, _) => (t, 1),
                    Event::Gps(t, _) => (t.saturating_sub(300_000), 0),
                });
                let mut delay_loop = DefaultDelayLoop::<T>::new(start_at(0.1)).unwrap();
                let mut errors = vec![];
                for event in events {
                    match event {
                        Event::Imu(t, a) => delay_loop.push_imu(t, v3(a)).unwrap(),
                        Event::Gps(t, v) => {
                            if let Some(u) = delay_loop.push_gps(t, v3(v)).unwrap() {
                                if t > 40_000_000 {
                                    errors.push(u.delay_s as f64 - 0.2);
                                }
                            }
                        }
                    }
                }
                let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
                assert!(errors.len() > 400, "{} updates", errors.len());
                assert!(rmse < 4e-3, "{rmse}");
                assert_eq!(delay_loop.restarts(), 0);
            }

            /// The sliding sums (with their periodic shadow resync) give the same
            /// peaks as a brute-force Pearson correlation over the same samples,
            /// after many times the buffer length (no drift), in both precisions.
            #[test]
            fn sliding_correlation_matches_brute_force() {
                const B: usize = 40;
                const L: usize = 12;
                let shift_min = 3;
                let mut correlator = SlidingCorrelator::<T, B, L, 80>::new(B, shift_min, L).unwrap();
                let mut rng = Lcg(17);
                let mut xs: Vec<[f64; 3]> = vec![];
                let mut ys: Vec<[f64; 3]> = vec![];
                let delay = 7usize;
                let mut compared = 0;
                for j in 0..2000usize {
                    // A smooth-ish random walk plus an offset, so means matter.
                    let prev = xs.last().copied().unwrap_or([5.0, -3.0, 0.0]);
                    let x = prev.map(|p| 0.9 * p + rng.normal() + 0.5);
                    xs.push(x);
                    correlator.push_x(j as u64, v3(x));
                    let y = if j >= delay { xs[j - delay].map(|v| v + 0.5 * rng.normal()) } else { [0.0; 3] };
                    ys.push(y);
                    correlator.push_y(j as u64, v3(y));
                    let Some(peaks) = correlator.peaks() else { continue };
                    if j % 97 != 0 {
                        continue;
                    }
                    for axis in 0..3 {
                        let r = |lag: usize| {
                            let s = shift_min + lag;
                            let pairs: Vec<(f64, f64)> = (j + 1 - B..=j).map(|i| (xs[i - s][axis], ys[i][axis])).collect();
                            let n = B as f64;
                            let (mx, my) = (pairs.iter().map(|p| p.0).sum::<f64>() / n, pairs.iter().map(|p| p.1).sum::<f64>() / n);
                            let cov: f64 = pairs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
                            let vx: f64 = pairs.iter().map(|p| (p.0 - mx).powi(2)).sum();
                            let vy: f64 = pairs.iter().map(|p| (p.1 - my).powi(2)).sum();
                            cov / (vx * vy).sqrt()
                        };
                        let best = (0..L).max_by(|&a, &b| r(a).partial_cmp(&r(b)).unwrap()).unwrap();
                        let tol = if TOL > 1e-6 { 2e-3 } else { 1e-9 };
                        assert!((peaks[axis].peak as f64 - r(best)).abs() < tol, "j {j} axis {axis}");
                        let (left, right) = (r(best - 1), r(best + 1));
                        let offset = 0.5 * (left - right) / (left - 2.0 * r(best) + right);
                        let expected = (shift_min + best) as f64 + offset;
                        assert!((peaks[axis].shift_samples as f64 - expected).abs() < 50.0 * tol, "j {j} axis {axis}");
                        assert_eq!(shift_min + best, delay);
                        compared += 1;
                    }
                }
                assert!(compared > 15, "{compared}");
            }

            /// Updating every third fix: a third of the updates, same accuracy
            /// (the noise settings are per second and per buffer, not per update).
            #[test]
            fn update_every_third_fix() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 120.0;
                scenario.seed = 2;
                let motion = Motion::random(32, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                let mut every = start_at(0.1);
                every.fixes_per_update = 3;
                let sparse = run(&scenario, &motion, |_| 0.2, every);
                let dense = run(&scenario, &motion, |_| 0.2, start_at(0.1));
                let ratio = dense.updates.len() as f64 / sparse.updates.len() as f64;
                assert!((ratio - 3.0).abs() < 0.05, "{ratio}");
                let (rmse_sparse, rmse_dense) = (rmse_after(&sparse, 60.0, 0.2), rmse_after(&dense, 60.0, 0.2));
                assert!(rmse_sparse < 4e-3 && (rmse_sparse - rmse_dense).abs() < 2e-3, "{rmse_sparse} vs {rmse_dense}");
            }

            /// No motion (a(t) = 0, noise only): every V_i = 0 and the estimate
            /// stays exactly where it was.
            #[test]
            fn hover_holds_estimate() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 30.0;
                let trace = run(&scenario, &Motion::hover(), |_| 0.2, start_at(0.25));
                assert!(trace.updates.len() > 100);
                for u in &trace.updates {
                    assert_eq!(u.2, [false; 3]);
                    assert_eq!(u.1, 0.25 as T as f64);
                }
            }

            /// Motion on the north axis only: only north is valid.
            #[test]
            fn validity_follows_motion_per_axis() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 40.0;
                let motion = Motion::random(4, 8, 0.05, 1.0, [6.0, 0.0, 0.0]);
                let trace = run(&scenario, &motion, |_| 0.2, start_at(0.2));
                let tail: Vec<_> = trace.updates.iter().filter(|u| u.0 > 20.0).collect();
                assert!(tail.iter().all(|u| !u.2[1] && !u.2[2]));
                assert!(tail.iter().filter(|u| u.2[0]).count() * 10 > tail.len() * 9);
            }

            /// A vehicle shuttling gently on one axis (a sine of 1.8 m/s^2 amplitude and 6 s
            /// period: 1.6 (m/s^2)^2 over a buffer, below the default motion threshold of 2)
            /// gets its delay with the default configuration: its windows count once the axis
            /// has moved at half the threshold for two buffer lengths (10 s of updates after the
            /// buffer filled at 5 s), and the loop converges from a 50 ms error (one frequency:
            /// the windows scatter by +-20 ms, so the estimate settles over a minute; measured
            /// 2.5 ms RMS from 90 s).
            #[test]
            fn sustained_gentle_motion_is_valid() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 120.0;
                let w = core::f64::consts::TAU / 6.0;
                let motion = Motion { terms: [vec![(1.8, w, 0.0)], vec![], vec![]] };
                let mut config = DelayLoopConfig::<T>::default();
                config.fusion.initial_delay_s = 0.2;
                let trace = run(&scenario, &motion, |_| 0.15, config);
                let first_valid = trace.updates.iter().find(|u| u.2[0]).map(|u| u.0);
                assert!(first_valid.is_some_and(|t| (14.9..17.0).contains(&t)), "{first_valid:?}");
                assert!(trace.updates.iter().all(|u| !u.2[1] && !u.2[2]));
                let rmse = rmse_after(&trace, 90.0, 0.15);
                assert!(rmse < 0.006, "{rmse}");
            }

            /// The per-fix work is the same whatever the delay (counted products).
            #[test]
            fn work_per_fix_independent_of_delay() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 20.0;
                let motion = Motion::random(5, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                let work = |tau: f64| {
                    let trace = run(&scenario, &motion, |_| tau, start_at(0.2));
                    trace.multiply_adds_per_fix[150..].to_vec()
                };
                let (short, long) = (work(0.05), work(0.9));
                assert_eq!(short, long);
                // 10 Hz fixes on a 25 Hz grid: 3 and 2 sliding steps in turn, of 3 axes x 26 shifts
                // x 3 products.
                let step = 3 * 26 * 3;
                assert!(short.iter().all(|&w| w == 3 * step || w == 2 * step), "{:?}", &short[..5]);
                assert!(short.windows(2).all(|w| w[0] + w[1] == 5 * step), "{:?}", &short[..5]);
            }

            #[test]
            fn bad_input_is_refused_and_state_unchanged() {
                let mut scenario = Scenario::simulator();
                scenario.duration_s = 12.0;
                let motion = Motion::random(6, 8, 0.05, 1.0, [6.0, 6.0, 3.0]);
                let mut delay_loop = DefaultDelayLoop::<T>::new(start_at(0.2)).unwrap();
                let mut last = (0, 0);
                for event in scenario.events(&motion, |_| 0.2) {
                    match event {
                        Event::Imu(t, a) => {
                            delay_loop.push_imu(t, v3(a)).unwrap();
                            last.0 = t;
                        }
                        Event::Gps(t, v) => {
                            delay_loop.push_gps(t, v3(v)).unwrap();
                            last.1 = t;
                        }
                    }
                }
                let before = format!("{delay_loop:?}");
                let nan = Vector3::new(T::NAN, 0.0, 0.0);
                assert!(matches!(delay_loop.push_imu(last.0 + 1000, nan), Err(Error::NonFinite { .. })));
                assert!(matches!(delay_loop.push_gps(last.1 + 100_000, nan), Err(Error::NonFinite { .. })));
                assert!(matches!(
                    delay_loop.push_imu(last.0 - 1, Vector3::zeros()),
                    Err(Error::TimeWentBackwards { .. })
                ));
                assert!(matches!(
                    delay_loop.push_gps(last.1, Vector3::zeros()),
                    Err(Error::DuplicateTimestamp { .. })
                ));
                assert!(delay_loop.set_delay(2.0, 0.01).is_err());
                assert_eq!(before, format!("{delay_loop:?}"));
            }

            #[test]
            fn invalid_configurations_are_refused() {
                let d = DelayLoopConfig::<T>::clean_input();
                assert!(d.validate().is_ok());
                let mut c = d;
                c.buffer_s = -1.0;
                assert!(c.validate().is_err());
                let mut c = d;
                c.gps_diff_span = 0;
                assert!(c.validate().is_err());
                let mut c = d;
                c.min_peak = 1.5;
                assert!(c.validate().is_err());
                let mut c = d;
                c.fusion.delay_max_s = 3.0; // 151 shifts > LAGS = 51
                assert!(matches!(DefaultDelayLoop::<T>::new(c), Err(Error::InvalidConfig { .. })));
                let mut c = d;
                c.buffer_s = 10.0; // 500 samples > BUF = 250
                assert!(DefaultDelayLoop::<T>::new(c).is_err());
                let mut c = d;
                c.fusion.initial_delay_s = 1.5;
                assert!(c.validate().is_err());
                let mut c = d;
                c.measurement_noise_ms2[1] = 0.0;
                assert!(c.validate().is_err());
            }

            /// Lagrange delay of a sine: the error stays within the documented
            /// bound (plus rounding), for integer and fractional delays, on
            /// centred and one-sided stencils.
            #[test]
            fn fractional_delay_meets_error_bound() {
                fn check<const ORDER: usize>(omega_h: f64) {
                    let mut line = FractionalDelayLine::<T, 2, 64, ORDER>::new();
                    let n = 64;
                    let x = |k: f64| [(omega_h * k).sin(), 0.5 * (omega_h * k + 1.0).cos()];
                    for k in 0..n {
                        line.push(SVector::from(x(k as f64).map(|v| v as T))).unwrap();
                    }
                    let newest = (n - 1) as f64;
                    let mut worst_ratio: f64 = 0.0;
                    for i in 0..=630 {
                        let d = i as f64 * 0.1;
                        let y = line.read(d as T).unwrap();
                        let truth = x(newest - d);
                        let bound = line.error_bound(d as T, 1.0, omega_h as T).unwrap() as f64;
                        let err = (y[0] as f64 - truth[0]).abs().max((y[1] as f64 - truth[1]).abs());
                        assert!(err <= bound + TOL, "order {ORDER}, d {d}: error {err} > bound {bound}");
                        if bound > 10.0 * TOL {
                            worst_ratio = worst_ratio.max(err / bound);
                        }
                    }
                    // The bound is tight to within a small factor, not vacuous.
                    assert!(worst_ratio > 0.05, "order {ORDER}: bound loose ({worst_ratio})");
                }
                check::<3>(0.3);
                check::<3>(0.8);
                check::<5>(0.5);
                check::<4>(0.5);
            }

            #[test]
            fn fractional_delay_history_and_work() {
                let mut line = FractionalDelayLine::<T, 1, 16, 3>::new();
                for k in 0..3 {
                    line.push(SVector::from([k as T])).unwrap();
                }
                assert!(matches!(line.read(0.5), Err(Error::DelayBeyondHistory { .. })));
                for k in 3..40 {
                    line.push(SVector::from([k as T])).unwrap();
                }
                assert_eq!(line.len(), 16);
                assert_eq!(line.max_delay_samples(), Some(15));
                assert!(line.read(15.0).is_ok());
                assert!(matches!(line.read(15.01), Err(Error::DelayBeyondHistory { .. })));
                assert!(line.read(-0.1).is_err());
                assert!(line.read(T::NAN).is_err());
                assert!(line.push(SVector::from([T::INFINITY])).is_err());
                // A ramp is exact (within rounding) at any delay; the newest is 39.
                for d in [0.0, 0.3, 7.5, 14.9] {
                    let y = line.read(d as T).unwrap()[0] as f64;
                    assert!((y - (39.0 - d)).abs() < 50.0 * TOL, "{d}: {y}");
                }
                assert!(line.read_seconds(0.1, 0.01).is_ok());
                assert!(line.read_seconds(0.1, 0.0).is_err());
            }

            /// The mean period of a jittered 50 Hz stream is 20 ms to within the
            /// jitter over the span; bad timestamps are refused.
            #[test]
            fn sample_period_averages_jitter() {
                let mut period = SamplePeriod::new();
                assert_eq!(period.period_s::<T>(), None);
                let mut rng = Lcg(3);
                for k in 0..1000u64 {
                    let jitter = ((rng.uniform() * 2.0 - 1.0) * 2000.0) as i64;
                    period.push((1_000_000 + k as i64 * 20_000 + jitter) as u64).unwrap();
                }
                let p = period.period_s::<T>().unwrap() as f64;
                // Endpoint jitter of +-2 ms over 999 intervals: +-4 us.
                assert!((p - 0.02).abs() < 4.1e-6, "{p}");
                let before = period;
                assert!(period.push(1_000).is_err());
                assert_eq!(before, period);
            }

            /// Linear phase: H(w) e^{jwD} is real; group delay (TAPS-1)/2; unit
            /// DC gain; a passband sine comes out delayed by D samples.
            #[test]
            fn fir_linear_phase_and_group_delay() {
                let mut fir = WhiteningFir::<T, 31>::low_pass(20.0, 1000.0).unwrap();
                let h = *fir.coefficients();
                let d = fir.group_delay_samples() as f64;
                assert_eq!(d, 15.0);
                assert!((fir.group_delay_s(1000.0) as f64 - 0.015).abs() < 1e-7);
                let dc: f64 = h.iter().map(|&c| c as f64).sum();
                assert!((dc - 1.0).abs() < 10.0 * TOL);
                for w in [0.01, 0.1, 0.5, 1.0, 2.0, 3.0] {
                    let (mut re, mut im) = (0.0, 0.0);
                    for (k, &c) in h.iter().enumerate() {
                        let phase = w * (d - k as f64);
                        re += c as f64 * phase.cos();
                        im += c as f64 * phase.sin();
                    }
                    assert!(im.abs() < 10.0 * TOL * (1.0 + re.abs()), "w {w}: im {im}");
                }
                // Sine at 2 Hz, 1 kHz: steady-state output equals input D samples earlier
                // (gain at 2 Hz within 0.5 % of 1).
                let w = 2.0 * std::f64::consts::PI * 2.0 / 1000.0;
                let mut worst: f64 = 0.0;
                for k in 0..400 {
                    let y = fir.filter(Vector3::repeat((w * k as f64).sin() as T)).unwrap();
                    if k > 40 {
                        worst = worst.max((y[0] as f64 - (w * (k as f64 - d)).sin()).abs());
                    }
                }
                assert!(worst < 5e-3, "{worst}");
                // Refusals.
                assert!(WhiteningFir::<T, 5>::from_coefficients([0.1, 0.2, 0.4, 0.2, 0.1]).is_ok());
                assert!(WhiteningFir::<T, 5>::from_coefficients([0.1, 0.2, 0.4, 0.25, 0.1]).is_err());
                assert!(WhiteningFir::<T, 5>::low_pass(600.0, 1000.0).is_err());
                let snapshot = format!("{fir:?}");
                assert!(fir.filter(Vector3::new(T::NAN, 0.0, 0.0)).is_err());
                assert_eq!(snapshot, format!("{fir:?}"));
            }

            /// Eq. (15): every stream ends up delayed by tau_raw from its raw sensor.
            #[test]
            fn sensor_delays_eq15() {
                let (tau_raw, d_f, d_w) = (0.25, 0.015, 0.007);
                let tau_f = tau_raw - d_f; // what the loop measures on whitened accel
                let s = SensorDelays::<T>::new(tau_f as T, d_f as T, d_w as T);
                assert!(((s.accel_s as f64 + d_f) - tau_raw).abs() < TOL);
                assert!(((s.gyro_s as f64 + d_w) - tau_raw).abs() < TOL);
                assert!((s.mag_s as f64 - tau_raw).abs() < TOL);
            }

            /// With all axes valid and a constant measurement, the GFA converges to
            /// it and P to the fixed point of a Kalman filter fusing the mean of the
            /// three measurements: P = Pbar r / (Pbar + r), r = R/3, Pbar = P + Q.
            #[test]
            fn gain_fusion_fixed_point() {
                let config = GainFusionConfig::<T> { initial_delay_s: 0.1, initial_std_s: 0.1, rate_std: 0.0, ..Default::default() };
                let mut gfa = GainFusion::new(config).unwrap();
                let (q, r): (f64, f64) = (1e-6, 1e-4);
                for _ in 0..2000 {
                    gfa.step([0.3; 3], [true; 3], 0.1, q as T, [r as T; 3]).unwrap();
                }
                let r3 = r / 3.0;
                let p_bar = (q + (q * q + 4.0 * q * r3).sqrt()) / 2.0;
                let p_star = p_bar - q;
                assert!((gfa.delay_s() as f64 - 0.3).abs() < 100.0 * TOL);
                assert!((gfa.variance_s2() as f64 - p_star).abs() < 1e-3 * p_star + TOL * 1e-4, "{} vs {p_star}", gfa.variance_s2());
                // All invalid: the estimate holds, P grows by Q.
                let before = (gfa.delay_s(), gfa.variance_s2() as f64);
                let step = gfa.step([0.9; 3], [false; 3], 0.1, q as T, [r as T; 3]).unwrap();
                assert_eq!(step.delay_s, before.0);
                assert!((gfa.variance_s2() as f64 - (before.1 + q)).abs() < 1e-3 * q);
                // The estimate stays in range; a bad step is refused with no change.
                for _ in 0..100 {
                    gfa.step([5.0; 3], [true; 3], 0.1, 1e-2, [1e-4; 3]).unwrap();
                }
                assert_eq!(gfa.delay_s(), 1.0);
                let snapshot = gfa;
                assert!(gfa.step([T::NAN, 0.2, 0.2], [true; 3], 0.1, q as T, [r as T; 3]).is_err());
                assert!(gfa.step([0.2; 3], [true; 3], 0.1, -1.0, [r as T; 3]).is_err());
                assert_eq!(snapshot, gfa);
            }

            /// Offline calibration (IMU-only attitude, +-6 s) finds the delay
            /// within one correlation sample (20 ms at 50 Hz).
            #[test]
            fn offline_calibration_finds_delay() {
                for (tau, imu_hz, gps_hz, seed) in [(0.2, 1000.0, 10.0, 12), (0.58, 50.0, 5.0, 13)] {
                    let (imu, gps) = recorded_session(tau, imu_hz, gps_hz, seed);
                    let mut calibrator = Box::new(DefaultCalibrator::<T>::new(CalibrationConfig::default()).unwrap());
                    let result = calibrator.calibrate(imu.iter().copied(), gps.iter().copied()).unwrap();
                    println!("calibration {imu_hz} Hz / {gps_hz} Hz: {:.4} s (true {tau}), peak {:.2}", result.delay_s, result.peak);
                    assert!((result.delay_s as f64 - tau).abs() < 0.02, "{} vs {tau}", result.delay_s);
                    assert!(result.peak > 0.5);
                    assert_eq!(result.refused, 0);
                    // The curve: every shift of +-6 s on the 50 Hz grid, its highest
                    // point the peak's grid shift (the result refines it between shifts).
                    let curve: Vec<_> = calibrator.curve().collect();
                    assert_eq!(curve.len(), 601);
                    assert!((curve[0].0 as f64 + 6.0).abs() < 1e-4 && (curve[600].0 as f64 - 6.0).abs() < 1e-4);
                    let top = curve.iter().filter(|c| c.2 >= 500).max_by(|a, b| a.1.partial_cmp(&b.1).unwrap()).unwrap();
                    assert!((top.0 as f64 - result.delay_s as f64).abs() <= 0.02, "{} vs {}", top.0, result.delay_s);
                    assert!((top.1 as f64 - result.peak as f64).abs() < 1e-6 && top.2 >= result.pairs.min(500));
                }
            }

            /// A recorded session on a platform held level with a constant heading
            /// (the paper's calibration rig), moved in all three axes; the gyro
            /// sees only noise. Specific force f = R^T (a - g).
            fn recorded_session(tau: f64, imu_hz: f64, gps_hz: f64, seed: u64) -> (Vec<Imu<T>>, Vec<Gps<T>>) {
                let mut scenario = Scenario::simulator();
                scenario.imu_hz = imu_hz;
                scenario.gps_hz = gps_hz;
                scenario.duration_s = 120.0;
                scenario.seed = seed;
                let motion = Motion::random(seed, 8, 0.05, 1.0, [3.0, 3.0, 3.0]);
                let mut rng = Lcg(seed + 100);
                let mut imu = vec![];
                let mut gps = vec![];
                for event in scenario.events(&motion, |_| tau) {
                    match event {
                        Event::Imu(t, a) => imu.push(Imu {
                            t_us: t,
                            gyro_rad_s: v3([0.0; 3].map(|_: f64| 0.01 * rng.normal())),
                            accel_m_s2: v3([a[0], a[1], a[2] - 9.80665]),
                        }),
                        Event::Gps(t, v) => gps.push(common::velocity_fix(t, v3(v))),
                    }
                }
                (imu, gps)
            }

            #[test]
            fn calibration_needs_data() {
                let calibrator = Box::new(DefaultCalibrator::<T>::new(CalibrationConfig::default()).unwrap());
                assert!(matches!(calibrator.result(), Err(Error::NotEnoughData { .. })));
                let mut config = CalibrationConfig::<T>::default();
                config.max_shift_s = 10.0;
                assert!(DefaultCalibrator::<T>::new(config).is_err());
            }
        }
    };
}

delay_tests!(f64_tests, f64, 1e-9);
delay_tests!(f32_tests, f32, 2e-5);

/// The default loop fits a Cortex-M4F's RAM comfortably in f32.
#[test]
fn default_sizes() {
    use std::mem::size_of;
    let sizes = [
        size_of::<DefaultDelayLoop<f32>>(),
        size_of::<DefaultDelayLoop<f64>>(),
        size_of::<DefaultCalibrator<f32>>(),
        size_of::<DefaultCalibrator<f64>>(),
    ];
    println!(
        "DefaultDelayLoop f32/f64 {} / {} bytes; DefaultCalibrator f32/f64 {} / {} bytes",
        sizes[0], sizes[1], sizes[2], sizes[3]
    );
    assert!(sizes[0] < 24 * 1024);
}

mod no_panic {
    use super::*;
    use proptest::prelude::*;

    fn value() -> impl Strategy<Value = f64> {
        prop_oneof![
            8 => -20.0..20.0f64,
            1 => Just(f64::NAN),
            1 => Just(f64::INFINITY),
            1 => prop_oneof![Just(1e5), Just(-1e30), Just(9.9e3)],
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Any input sequence (bad values, repeated or backward times, gaps):
        /// no panic, the estimate stays finite and in range.
        #[test]
        fn loop_never_panics_or_leaves_range(
            steps in proptest::collection::vec((0u64..400_000, any::<bool>(), value(), value(), value()), 200..1500)
        ) {
            let mut delay_loop = DefaultDelayLoop::<f32>::new(DelayLoopConfig::clean_input()).unwrap();
            let mut t = 1_000_000u64;
            for (dt, is_gps, a, b, c) in steps {
                // Mostly 1 ms steps, sometimes long gaps or going backwards.
                t = if dt > 390_000 { t.saturating_sub(dt - 390_000) } else { t + dt % 20_000 };
                let v = Vector3::new(a as f32, b as f32, c as f32);
                let _ = if is_gps { delay_loop.push_gps(t, v).map(|_| ()) } else { delay_loop.push_imu(t, v) };
                let d = delay_loop.delay_s();
                prop_assert!(d.is_finite() && (0.0..=1.0).contains(&d));
                prop_assert!(delay_loop.delay_std_s().is_finite());
            }
        }
    }
}

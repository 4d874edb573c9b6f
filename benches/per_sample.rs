//! Cost per IMU sample of every estimator, in f32 and f64, beside the
//! crates.io peers `eskf` and `fusion-nav` (both f32 only), all on the same
//! simulated samples and in one run (issue 12 item 7).
//!
//! The simulator's high scenario, seed 1 (1 kHz IMU, 100 Hz magnetometer,
//! 10 Hz GPS with a true delay of 0.2 s, NED fixes) is generated once. Every
//! estimator is run untimed through its first [`WARM_UP_S`] (initialisation,
//! and the delay loop's 5 s of correlation buffer); the next [`STRETCH_S`]
//! of IMU, magnetometer and GPS samples are then pushed into a copy of it
//! per iteration, in time order. The time of the whole stretch over its
//! number of IMU samples is the cost of one 1 kHz period, GPS and
//! magnetometer work amortised as in flight: the group's throughput is
//! `Elements(IMU samples)`. `estimate()` is not called (the Cortex-M4 bench
//! counts it apart; it costs a few hundred instructions).
//!
//! What each is fed:
//! - `nav_estimated_*` / `nav_fixed_*`: `DelayCompensatedNav`, the delay
//!   estimated from 0.2 s or fixed at the true 0.2 s, 0.5 s maximum delay,
//!   the EKF configured as the reproduce example does (the simulator's own
//!   noise): everything.
//! - `ekf16_*`: everything; it fuses a fix as if taken at its receive time.
//! - `aekf17_*`: everything, the delay estimated from 0.2 s (0.5 s maximum).
//! - `fusion_nav_f32`: the reproduce example's adapter: IMU, magnetometer
//!   heading, GPS position and velocity stamped with the time they were
//!   taken (receive time minus the **true** delay: it cannot estimate one).
//! - `eskf_f32`: IMU, GPS position and velocity, fused at the receive time
//!   (it has no timestamps, so no delay). No magnetometer: its only attitude
//!   observation takes a whole attitude, and 0.2.0 forms its residual as
//!   `measurement * orientation`, which is not small when both agree. No
//!   alignment either: it starts from the true state at t = 0.
//!
//! Time is the thread's CPU time ([`ThreadCpuTime`]), so a loaded machine
//! does not count its other processes' turns. Criterion prints the time of
//! one stretch and, as `thrpt`, the time per IMU sample (`µs/elem`).
//!
//! `cargo bench --features sim --bench per_sample`; comparing two commits
//! (`--save-baseline` / `--baseline`): docs/PERFORMANCE.md.

#[path = "../examples/reproduce/fusion_nav.rs"]
mod fusion_nav;

use cpu_time::ThreadTime;
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use delaynav::estimate::{Estimate, GpsOutcome, MagOutcome};
use delaynav::sim::{STANDARD_GRAVITY, Scenario, SimConfig, SimEvent, Simulation, Truth};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, DelayCompensatedNav, DelayCompensatedNavConfig,
    DelayMode, Ekf16, Ekf16Config, Error, Gps, GpsFix, GpsPosition, Imu, ImuSample, Mag, MagSample,
    Navigator, Scalar,
};
use fusion_nav::FusionNav;
use nalgebra::{SVector, UnitQuaternion, Vector3};
use nalgebra_eskf as na25;
use std::hint::black_box;
use std::time::Duration;

/// Seed of the simulated run.
const SEED: u64 = 1;
/// Untimed run-in of every estimator, seconds.
const WARM_UP_S: f64 = 10.0;
/// The timed stretch after it, seconds.
const STRETCH_S: f64 = 4.0;
/// Largest delay the delay-estimating filters are configured for, seconds.
const MAX_DELAY_S: f64 = 0.5;

/// One sample in the estimators' float type.
enum Event<T: Scalar> {
    Imu(Imu<T>),
    Mag(Mag<T>),
    Gps(Gps<T>),
}

/// The simulated run split into run-in and timed stretch.
struct Samples<T: Scalar> {
    warm_up: Vec<Event<T>>,
    stretch: Vec<Event<T>>,
    imu_in_stretch: u64,
}

fn samples<T: Scalar>(events: &[SimEvent]) -> Samples<T> {
    let start_us = (WARM_UP_S * 1e6) as u64;
    let (mut warm_up, mut stretch) = (Vec::new(), Vec::new());
    for e in events {
        let event = match e {
            SimEvent::Imu { sample, .. } => Event::Imu(Imu {
                t_us: sample.t_us,
                gyro_rad_s: sample.gyro_rad_s.map(T::lit),
                accel_m_s2: sample.accel_m_s2.map(T::lit),
            }),
            SimEvent::Mag(m) => Event::Mag(Mag {
                t_us: m.t_us,
                field_body: m.field_body.map(T::lit),
            }),
            SimEvent::Gps { fix, .. } => {
                let GpsPosition::Ned(p) = fix.position else {
                    panic!("the simulator is configured for NED fixes");
                };
                Event::Gps(Gps {
                    t_us: fix.t_us,
                    position: GpsPosition::Ned(p.map(T::lit)),
                    velocity_ned_m_s: fix.velocity_ned_m_s.map(T::lit),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                })
            }
        };
        if e.t_us() < start_us {
            warm_up.push(event);
        } else {
            stretch.push(event);
        }
    }
    let imu_in_stretch = stretch
        .iter()
        .filter(|e| matches!(e, Event::Imu(_)))
        .count() as u64;
    Samples {
        warm_up,
        stretch,
        imu_in_stretch,
    }
}

/// Pushes every sample in order; returns how many were refused.
fn feed<T: Scalar, N: Navigator<T>>(nav: &mut N, events: &[Event<T>]) -> usize {
    let mut refused = 0;
    for event in events {
        let accepted = match event {
            Event::Imu(s) => nav.push_imu(s).is_ok(),
            Event::Mag(m) => nav.push_mag(m).is_ok(),
            Event::Gps(g) => nav.push_gps(g).is_ok(),
        };
        refused += usize::from(!accepted);
    }
    refused
}

/// The Ekf16 configuration of the reproduce example (the simulator's own
/// noise, field and bias spread).
fn ekf_config<T: Scalar>(sim: &SimConfig) -> Ekf16Config<T> {
    sim.sensors.ekf16_config()
}

fn nav<T: Scalar>(sim: &SimConfig, mode: DelayMode<T>) -> DelayCompensatedNav<T> {
    let mut config = DelayCompensatedNavConfig {
        ekf: ekf_config(sim),
        mode,
        imu_rate_hz: T::lit(sim.sensors.imu_rate_hz),
        ..DelayCompensatedNavConfig::default()
    };
    config.delay_loop.fusion.delay_max_s = T::lit(MAX_DELAY_S);
    DelayCompensatedNav::new(config).expect("valid navigator config")
}

fn aekf17<T: Scalar>(sim: &SimConfig) -> AugmentedEkf17<T> {
    let mut config = AugmentedEkf17Config::with_nav(ekf_config(sim));
    config.initial_delay_s = T::lit(sim.delay.initial_s);
    config.max_delay_s = T::lit(MAX_DELAY_S);
    AugmentedEkf17::new(config).expect("valid Aekf17 config")
}

/// The crates.io `eskf` 0.2 (18 error states, gravity among them; f32)
/// behind [`Navigator`].
#[derive(Clone)]
struct EskfPeer {
    filter: eskf::ESKF,
    last_imu_us: Option<u64>,
    period_us: u64,
    position_variance: f32,
    velocity_variance: f32,
}

impl EskfPeer {
    /// Configured from the simulator's noise (per-sample standard deviations,
    /// which its builder squares), started at the true state `start`.
    fn new(sim: &SimConfig, start: &Truth) -> Self {
        let s = &sim.sensors;
        let mut filter = eskf::Builder::new()
            .acceleration_variance(s.accel_noise_std_m_s2() as f32)
            .rotation_variance(s.gyro_noise_var_rad2_s2.sqrt() as f32)
            .acceleration_bias(s.accel_bias_walk_m_s2_sqrt_s as f32)
            .rotation_bias(s.gyro_bias_walk_rad_s_sqrt_s as f32)
            .initial_covariance(1e-2)
            .build();
        let [n, e, d] = start.position_m.map(|x| x as f32).into();
        filter.position = na25::Point3::new(n, e, d);
        let [vn, ve, vd] = start.velocity_m_s.map(|x| x as f32).into();
        filter.velocity = na25::Vector3::new(vn, ve, vd);
        let q = start.attitude.quaternion();
        let [w, i, j, k] = [q.w, q.i, q.j, q.k].map(|x| x as f32);
        filter.orientation =
            na25::UnitQuaternion::from_quaternion(na25::Quaternion::new(w, i, j, k));
        filter.gravity = na25::Vector3::new(0.0, 0.0, STANDARD_GRAVITY as f32);
        Self {
            filter,
            last_imu_us: None,
            period_us: (1e6 / s.imu_rate_hz).round() as u64,
            position_variance: s.gps_position_var_m2 as f32,
            velocity_variance: s.gps_velocity_var_m2_s2 as f32,
        }
    }
}

fn na25_vector<T: Scalar>(v: &Vector3<T>) -> na25::Vector3<f32> {
    na25::Vector3::new(
        v.x.as_f64() as f32,
        v.y.as_f64() as f32,
        v.z.as_f64() as f32,
    )
}

impl<T: Scalar> Navigator<T> for EskfPeer {
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        let t_us = imu.time_us();
        let step_us = self
            .last_imu_us
            .map_or(self.period_us, |p| t_us.saturating_sub(p));
        self.last_imu_us = Some(t_us);
        self.filter.predict(
            na25_vector(&imu.accel_m_s2()),
            na25_vector(&imu.gyro_rad_s()),
            Duration::from_micros(step_us),
        );
        Ok(())
    }

    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        let GpsPosition::Ned(p) = gps.position() else {
            return Err(Error::InvalidConfig {
                field: "gps.position".into(),
                value: None,
                bound: delaynav::error::Bound::Rule("the eskf row takes NED fixes"),
            });
        };
        let p = na25_vector(&p);
        let _ = self.filter.observe_position(
            na25::Point3::new(p.x, p.y, p.z),
            eskf::ESKF::variance_from_element(self.position_variance),
        );
        let _ = self.filter.observe_velocity(
            na25_vector(&gps.velocity_ned_m_s()),
            eskf::ESKF::variance_from_element(self.velocity_variance),
        );
        Ok(GpsOutcome::Queued)
    }

    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, _: &M) -> Result<MagOutcome<T>, Error> {
        Ok(MagOutcome::Stored)
    }

    fn estimate(&self) -> Option<Estimate<T>> {
        let f = &self.filter;
        let v = |a: &na25::Vector3<f32>| Vector3::new(a.x, a.y, a.z).map(|x| T::lit(f64::from(x)));
        let q = f.orientation.quaternion();
        Some(Estimate {
            t_us: self.last_imu_us.unwrap_or(0),
            attitude: UnitQuaternion::new_normalize(nalgebra::Quaternion::new(
                T::lit(f64::from(q.w)),
                T::lit(f64::from(q.i)),
                T::lit(f64::from(q.j)),
                T::lit(f64::from(q.k)),
            )),
            position_ned_m: v(&f.position.coords),
            velocity_ned_m_s: v(&f.velocity),
            accel_bias_m_s2: v(&f.accel_bias),
            gyro_bias_rad_s: v(&f.rot_bias),
            covariance_diagonal: SVector::zeros(),
            delay_s: None,
            delay_std_s: None,
        })
    }
}

/// Runs `nav` through the run-in, checks it on one untimed stretch (a finite
/// estimate; refused samples and the position error are printed), then
/// times the stretch on a fresh copy of the run-in state per iteration.
fn bench_estimator<T: Scalar, N: Navigator<T> + Clone>(
    group: &mut BenchmarkGroup<'_, ThreadCpuTime>,
    id: &str,
    mut nav: N,
    samples: &Samples<T>,
    end: &Truth,
) {
    feed(&mut nav, &samples.warm_up);
    assert!(
        nav.estimate().is_some(),
        "{id}: no estimate after the run-in"
    );
    let mut check = nav.clone();
    let refused = feed(&mut check, &samples.stretch);
    let estimate = check.estimate().expect("an estimate after the stretch");
    let error_m = (estimate.position_ned_m.map(T::as_f64) - end.position_m).norm();
    assert!(error_m.is_finite(), "{id}: non-finite position");
    eprintln!(
        "{id}: {refused} of {} samples refused; position error at the end {error_m:.2} m",
        samples.stretch.len()
    );
    group.bench_function(id, |b| {
        b.iter_batched_ref(
            || nav.clone(),
            |nav| black_box(feed(nav, &samples.stretch)),
            BatchSize::PerIteration,
        )
    });
}

fn ours<T: Scalar>(
    group: &mut BenchmarkGroup<'_, ThreadCpuTime>,
    precision: &str,
    sim: &SimConfig,
    samples: &Samples<T>,
    end: &Truth,
) {
    let delay = T::lit(sim.delay.initial_s);
    let estimated = nav(sim, DelayMode::Estimated { initial_s: delay });
    let id = format!("nav_estimated_{precision}");
    bench_estimator(group, &id, estimated, samples, end);
    let fixed = nav(sim, DelayMode::Fixed { delay_s: delay });
    let id = format!("nav_fixed_{precision}");
    bench_estimator(group, &id, fixed, samples, end);
    let ekf = Ekf16::<T>::new(ekf_config(sim)).expect("valid Ekf16 config");
    bench_estimator(group, &format!("ekf16_{precision}"), ekf, samples, end);
    let aekf = aekf17::<T>(sim);
    bench_estimator(group, &format!("aekf17_{precision}"), aekf, samples, end);
}

fn per_sample(c: &mut Criterion<ThreadCpuTime>) {
    let sim = SimConfig {
        duration_s: WARM_UP_S + STRETCH_S,
        ..SimConfig::for_scenario(Scenario::High, SEED)
    };
    let events: Vec<SimEvent> = Simulation::new(sim.clone())
        .expect("valid simulation")
        .collect();
    let truth = |e: &SimEvent| match e {
        SimEvent::Imu { truth, .. } => Some(*truth),
        _ => None,
    };
    let start = events.iter().find_map(truth).expect("an IMU sample");
    let end = events.iter().rev().find_map(truth).expect("an IMU sample");
    let samples_f32 = samples::<f32>(&events);
    let samples_f64 = samples::<f64>(&events);

    let mut group = c.benchmark_group("per_imu_sample");
    group.throughput(Throughput::Elements(samples_f32.imu_in_stretch));
    ours::<f32>(&mut group, "f32", &sim, &samples_f32, &end);
    ours::<f64>(&mut group, "f64", &sim, &samples_f64, &end);
    let eskf = EskfPeer::new(&sim, &start);
    bench_estimator::<f32, _>(&mut group, "eskf_f32", eskf, &samples_f32, &end);
    let fusion = FusionNav::new(&sim);
    bench_estimator::<f32, _>(&mut group, "fusion_nav_f32", fusion, &samples_f32, &end);
    group.finish();
}

/// CPU time of the benchmark's thread: unlike wall time it does not count
/// the time the thread waits while other processes run, so a loaded machine
/// slows a figure only through shared caches and clocks.
struct ThreadCpuTime;

impl Measurement for ThreadCpuTime {
    type Intermediate = ThreadTime;
    type Value = Duration;

    fn start(&self) -> ThreadTime {
        ThreadTime::now()
    }

    fn end(&self, start: ThreadTime) -> Duration {
        start.elapsed()
    }

    fn add(&self, a: &Duration, b: &Duration) -> Duration {
        *a + *b
    }

    fn zero(&self) -> Duration {
        Duration::ZERO
    }

    fn to_f64(&self, value: &Duration) -> f64 {
        value.as_nanos() as f64
    }

    fn formatter(&self) -> &dyn ValueFormatter {
        &Nanoseconds
    }
}

/// Nanoseconds shown in a unit that suits the typical value; a throughput
/// is shown as time per element (per IMU sample: the only throughput this
/// bench sets).
struct Nanoseconds;

impl Nanoseconds {
    fn unit(typical_ns: f64) -> (f64, &'static str) {
        match typical_ns {
            t if t < 1e3 => (1.0, "ns"),
            t if t < 1e6 => (1e-3, "µs"),
            t if t < 1e9 => (1e-6, "ms"),
            _ => (1e-9, "s"),
        }
    }
}

impl ValueFormatter for Nanoseconds {
    fn scale_values(&self, typical_ns: f64, values: &mut [f64]) -> &'static str {
        let (factor, unit) = Self::unit(typical_ns);
        values.iter_mut().for_each(|v| *v *= factor);
        unit
    }

    fn scale_throughputs(
        &self,
        typical_ns: f64,
        throughput: &Throughput,
        values: &mut [f64],
    ) -> &'static str {
        let per = match *throughput {
            Throughput::Elements(n) | Throughput::ElementsAndBytes { elements: n, .. } => n,
            Throughput::Bytes(n) | Throughput::BytesDecimal(n) | Throughput::Bits(n) => n,
        }
        .max(1) as f64;
        let (factor, unit) = Self::unit(typical_ns / per);
        values.iter_mut().for_each(|v| *v *= factor / per);
        match unit {
            "ns" => "ns/elem",
            "µs" => "µs/elem",
            "ms" => "ms/elem",
            _ => "s/elem",
        }
    }

    fn scale_for_machines(&self, _: &mut [f64]) -> &'static str {
        "ns"
    }
}

criterion_group! {
    name = benches;
    // A stretch takes 4-8 ms of CPU: 10 samples over 4 s of CPU time each
    // keep the whole run to a few minutes (docs/PERFORMANCE.md).
    config = Criterion::default()
        .with_measurement(ThreadCpuTime)
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    targets = per_sample
}
criterion_main!(benches);

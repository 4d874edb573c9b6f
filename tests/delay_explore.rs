mod common;
use common::*;
use delaynav::delay::*;
use nalgebra::Vector3;

fn run(sc: &Scenario, motion: &Motion, delay: impl Fn(f64) -> f64, cfg: DelayLoopConfig<f64>) -> Vec<(f64, f64, [bool;3], [f64;3], [f64;3])> {
    let mut l = DefaultDelayLoop::<f64>::new(cfg).unwrap();
    let mut out = vec![];
    for e in sc.events(motion, &delay) {
        match e {
            Event::Imu(t, a) => l.push_imu(t, Vector3::from(a)).unwrap(),
            Event::Gps(t, v) => {
                if let Some(u) = l.push_gps(t, Vector3::from(v)).unwrap() {
                    out.push((t as f64 * 1e-6, u.delay_s, u.axes.map(|a| a.valid), u.axes.map(|a| a.measured_delay_s), u.axes.map(|a| a.correlation.peak)));
                }
            }
        }
    }
    out
}

#[test]
fn explore() {
    let clean = |mut s: Scenario| { s.accel_sigma = 0.0; s.gps_sigma = 0.0; s };
    let seeded = |mut s: Scenario, k| { s.seed = k; s.duration_s = 120.0; s };
    for (name, sc, tau) in [("sim-clean", clean(Scenario::simulator()), 0.2), ("log-clean", clean(Scenario::real_log_like()), 0.28), ("sim-s1", seeded(Scenario::simulator(), 1), 0.2), ("sim-s2", seeded(Scenario::simulator(), 2), 0.2), ("log-s3", seeded(Scenario::real_log_like(), 3), 0.28), ("log-s4", seeded(Scenario::real_log_like(), 4), 0.28), ("sim-s5", seeded(Scenario::simulator(), 5), 0.237)] {
        let motion = if name.starts_with("sim") { Motion::random(3, 8, 0.05, 1.0, [6.0, 6.0, 3.0]) } else { Motion::random(3, 8, 0.05, 1.0, [3.0, 3.0, 1.5]) };
        for span in [1usize] {
            for fc in [25.0] {
                let mut cfg = DelayLoopConfig::<f64>::default();
                cfg.gps_diff_span = span; cfg.process_noise_ms2_per_s = 1600.0*5.0/3.0/(fc*fc);
                cfg.fusion.initial_delay_s = 0.1;
                let r = run(&sc, &motion, |_| tau, cfg);
                let tail: Vec<_> = r.iter().filter(|x| x.0 > sc.duration_s - 60.0).collect();
                let rmse = (tail.iter().map(|x| (x.1 - tau).powi(2)).sum::<f64>() / tail.len() as f64).sqrt();
                let zs: Vec<f64> = tail.iter().flat_map(|x| x.3.iter().copied()).collect();
                let zrms = (zs.iter().map(|z| (z - tau).powi(2)).sum::<f64>() / zs.len() as f64).sqrt();
                let validfrac = tail.iter().flat_map(|x| x.2.iter()).filter(|v| **v).count() as f64 / (3 * tail.len()) as f64;
                let peak = tail.iter().flat_map(|x| x.4.iter()).sum::<f64>() / (3 * tail.len()) as f64;
                let zm = zs.iter().sum::<f64>()/zs.len() as f64;
                let per_axis: Vec<f64> = (0..3).map(|a| tail.iter().map(|x| x.3[a]).sum::<f64>()/tail.len() as f64 - tau).collect();
                println!("  bias {:.1} ms per-axis {:?}", (zm - tau)*1e3, per_axis.iter().map(|b| (b*1e4).round()/10.0).collect::<Vec<_>>());
                println!("{name} n={span} fc={fc}: rmse {:.2} ms, z rms {:.1} ms valid {:.2} peak {:.2} final {:.4}", rmse*1e3, zrms*1e3, validfrac, peak, r.last().unwrap().1);
            }
        }
    }
}

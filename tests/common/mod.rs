//! Synthetic truth for the delay tests: band-limited random NED motion, IMU
//! accelerations and delayed, noisy GPS velocities. No `rand`: a tiny LCG
//! with a fixed seed.
#![allow(dead_code)]

pub mod flight;
pub mod shared_data;

/// Knuth's MMIX linear congruential generator.
pub struct Lcg(pub u64);

impl Lcg {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Sum of sines per NED axis: a(t) = sum A sin(w t + p), v(t) = sum -A/w cos(w t + p).
pub struct Motion {
    /// (amplitude m/s^2, angular frequency rad/s, phase rad) per axis.
    pub terms: [Vec<(f64, f64, f64)>; 3],
}

impl Motion {
    /// `count` sines per axis with frequencies uniform in [f_lo, f_hi] Hz and
    /// amplitudes scaled so each axis has the given rms acceleration.
    pub fn random(seed: u64, count: usize, f_lo: f64, f_hi: f64, rms: [f64; 3]) -> Self {
        let mut rng = Lcg(seed);
        let terms = rms.map(|r| {
            let amp = if count == 0 {
                0.0
            } else {
                r * (2.0 / count as f64).sqrt()
            };
            (0..count)
                .map(|_| {
                    let f = f_lo + (f_hi - f_lo) * rng.uniform();
                    (
                        amp,
                        2.0 * std::f64::consts::PI * f,
                        2.0 * std::f64::consts::PI * rng.uniform(),
                    )
                })
                .collect()
        });
        Self { terms }
    }

    pub fn hover() -> Self {
        Self {
            terms: [vec![], vec![], vec![]],
        }
    }

    pub fn accel(&self, t: f64) -> [f64; 3] {
        core::array::from_fn(|i| {
            self.terms[i]
                .iter()
                .map(|&(a, w, p)| a * (w * t + p).sin())
                .sum()
        })
    }

    /// The double integral of `accel` (zero-mean sines).
    pub fn position(&self, t: f64) -> [f64; 3] {
        core::array::from_fn(|i| {
            self.terms[i]
                .iter()
                .map(|&(a, w, p)| -a / (w * w) * (w * t + p).sin())
                .sum()
        })
    }

    pub fn velocity(&self, t: f64) -> [f64; 3] {
        core::array::from_fn(|i| {
            self.terms[i]
                .iter()
                .map(|&(a, w, p)| -a / w * (w * t + p).cos())
                .sum()
        })
    }
}

/// One sensor event in time order.
#[derive(Debug, Clone, Copy)]
pub enum Event {
    /// IMU NED acceleration (truth + noise) at t_us.
    Imu(u64, [f64; 3]),
    /// GPS velocity received at t_us describing the vehicle at t - delay.
    Gps(u64, [f64; 3]),
}

pub struct Scenario {
    pub imu_hz: f64,
    pub gps_hz: f64,
    pub duration_s: f64,
    /// Accelerometer-side noise sigma per sample, m/s^2 (0.01 g^2 variance: 0.98).
    pub accel_sigma: f64,
    /// GPS velocity noise sigma, m/s (0.1 (m/s)^2 variance: 0.316).
    pub gps_sigma: f64,
    /// IMU timestamp jitter, +- us (uniform).
    pub imu_jitter_us: f64,
    /// GPS receive-time jitter, +- us (uniform), around the fix's epoch plus
    /// the delay (the real log: std 7 ms, range +-20 ms).
    pub gps_jitter_us: f64,
    pub seed: u64,
}

impl Scenario {
    pub fn simulator() -> Self {
        Self {
            imu_hz: 1000.0,
            gps_hz: 10.0,
            duration_s: 60.0,
            accel_sigma: 0.98,
            gps_sigma: 0.1f64.sqrt(),
            imu_jitter_us: 0.0,
            gps_jitter_us: 0.0,
            seed: 7,
        }
    }

    pub fn real_log_like() -> Self {
        Self {
            imu_hz: 50.0,
            gps_hz: 5.0,
            duration_s: 90.0,
            accel_sigma: 0.98,
            gps_sigma: 0.1f64.sqrt(),
            imu_jitter_us: 2000.0,
            gps_jitter_us: 12_000.0,
            seed: 11,
        }
    }

    /// The event stream for a motion and a delay schedule `delay(t)` (s).
    pub fn events(&self, motion: &Motion, delay: impl Fn(f64) -> f64) -> Vec<Event> {
        let mut rng = Lcg(self.seed);
        let mut events = Vec::new();
        let imu_dt = 1e6 / self.imu_hz;
        let n_imu = (self.duration_s * self.imu_hz) as u64;
        for k in 1..=n_imu {
            let jitter = if self.imu_jitter_us > 0.0 {
                (rng.uniform() * 2.0 - 1.0) * self.imu_jitter_us
            } else {
                0.0
            };
            let t_us = (k as f64 * imu_dt + jitter).round() as u64;
            let a = motion.accel(t_us as f64 * 1e-6);
            events.push(Event::Imu(
                t_us,
                a.map(|x| x + self.accel_sigma * rng.normal()),
            ));
        }
        let gps_dt = 1e6 / self.gps_hz;
        let n_gps = (self.duration_s * self.gps_hz) as u64;
        for k in 1..=n_gps {
            let epoch_us = k as f64 * gps_dt + 137.0;
            let jitter = (rng.uniform() * 2.0 - 1.0) * self.gps_jitter_us;
            let t_us = (epoch_us + jitter).round() as u64;
            let epoch = epoch_us * 1e-6;
            let v = motion.velocity(epoch - delay(epoch));
            events.push(Event::Gps(
                t_us,
                v.map(|x| x + self.gps_sigma * rng.normal()),
            ));
        }
        // GPS after IMU at equal times: the receiver's message arrives after the sample.
        events.sort_by_key(|e| match *e {
            Event::Imu(t, _) => (t, 0),
            Event::Gps(t, _) => (t, 1),
        });
        events
    }
}

/// A GPS fix carrying only a velocity (the delay loop reads nothing else).
pub fn velocity_fix<T: delaynav::Scalar>(
    t_us: u64,
    velocity: nalgebra::Vector3<T>,
) -> delaynav::Gps<T> {
    delaynav::Gps {
        t_us,
        position: delaynav::GpsPosition::Ned(nalgebra::Vector3::zeros()),
        velocity_ned_m_s: velocity,
        horizontal_accuracy_m: None,
        vertical_accuracy_m: None,
        speed_accuracy_m_s: None,
    }
}

//! A stand-in for the hardware, so that the firmware runs in QEMU: a rover
//! on a test field and what its sensors would read, as raw counts. A real
//! firmware has none of this; its drivers fill the structs of `drivers.rs`.
//!
//! The rover stands still for 2 s (the navigator levels on it), then drives
//! at 6-10 m/s along a slalom (heading swinging +-0.5 rad every 4 s) that
//! turns one full circle a minute. Body FRD, the rover level: the gyroscope
//! reads the heading rate on z, the accelerometer the speed change on x,
//! the centripetal acceleration on y and `-g` on z. The sensors add noise
//! (and the gyroscope a bias); the GPS receiver reports each fix 0.25 s
//! after its time of validity, and has no fix for its first 2 s.
//!
//! Three glitches a firmware meets in the field are planted, for the
//! navigator to refuse: the IMU driver hands the same FIFO sample twice
//! (at 20 s), a magnetometer read fails and returns zeros (at 30 s), and the
//! receiver's first fixes are no-fix reports. [`Glitches`] counts them.

use crate::drivers::{
    ACCEL_COUNTS_PER_G, G, GYRO_COUNTS_PER_DEG_S, MAG_COUNTS_PER_GAUSS, NavPvt, RawImu, RawMag,
};
use libm::{cosf, roundf, sinf, sqrtf};

/// IMU sample rate, Hz (one SysTick per sample).
pub const IMU_RATE_HZ: u32 = 1000;
/// Magnetometer: one reading every 10 IMU samples (100 Hz).
const MAG_EVERY: u32 = 10;
/// GPS: one fix every 100 IMU samples (10 Hz).
const GPS_EVERY: u32 = 100;
/// The receiver's latency, us: the GPS delay the navigator has to find.
pub const GPS_DELAY_US: u64 = 250_000;
/// The receiver reports no fix before this time of validity, us.
const FIRST_FIX_US: u64 = 2_000_000;
/// The IMU driver hands its previous sample again at this sample.
const DUPLICATE_IMU_AT: u32 = 20_000;
/// The magnetometer read fails at this IMU sample.
const FAILED_MAG_AT: u32 = 30_000;

/// Start of the drive, s, and the time the speed and turn take to ramp up.
const START_S: f32 = 2.0;
const RAMP_S: f32 = 3.0;
/// Mean speed, its swing and the swing's period.
const SPEED_M_S: f32 = 8.0;
const SPEED_SWING_M_S: f32 = 2.0;
const SPEED_PERIOD_S: f32 = 10.0;
/// Slalom: heading swing and its period; the mean turn rate.
const SLALOM_RAD: f32 = 0.5;
const SLALOM_PERIOD_S: f32 = 4.0;
const TURN_RAD_S: f32 = core::f32::consts::TAU / 60.0;

/// The home point (origin of NED), 1e-7 deg and mm above mean sea level.
pub const HOME_LAT_E7: i32 = 473_977_420;
pub const HOME_LON_E7: i32 = 85_455_940;
pub const HOME_H_MSL_MM: i32 = 488_000;
/// Earth's field at home: inclination and declination, rad; strength, gauss.
pub const INCLINATION_RAD: f32 = 1.103;
pub const DECLINATION_RAD: f32 = 0.052;
const FIELD_GAUSS: f32 = 0.48;

/// Sensor noise (1 sigma) and gyroscope bias, counts.
const ACCEL_NOISE_COUNTS: f32 = 4.0;
const GYRO_NOISE_COUNTS: f32 = 3.0;
const GYRO_BIAS_COUNTS: [f32; 3] = [4.0, -3.0, 5.0];
const MAG_NOISE_COUNTS: f32 = 20.0;
/// GPS noise (1 sigma): horizontal and vertical position, m; velocity, m/s.
const GPS_H_NOISE_M: f32 = 0.3;
const GPS_V_NOISE_M: f32 = 0.5;
const GPS_VEL_NOISE_M_S: f32 = 0.05;

/// What the rover really does at one instant (to check the estimate).
#[derive(Clone, Copy, Default)]
pub struct Truth {
    /// Time, us.
    pub t_us: u64,
    /// Position NED about home, m.
    pub position_m: [f32; 3],
    /// Velocity NED, m/s.
    pub velocity_m_s: [f32; 3],
    /// Heading (yaw), rad.
    pub yaw_rad: f32,
}

/// The glitches planted so far, per sensor.
#[derive(Clone, Copy, Default, PartialEq, Eq, Debug)]
pub struct Glitches {
    /// IMU samples handed twice.
    pub imu: u32,
    /// Magnetometer reads that failed.
    pub mag: u32,
    /// No-fix reports.
    pub gps: u32,
}

/// What the sensors deliver at one IMU tick.
pub struct Readings {
    pub imu: RawImu,
    pub mag: Option<RawMag>,
    pub gps: Option<NavPvt>,
}

/// A fix waiting in the receiver for its latency to pass.
#[derive(Clone, Copy)]
struct Pending {
    due_us: u64,
    fix: NavPvt,
}

/// The rover and its sensors.
pub struct World {
    tick: u32,
    yaw_rad: f32,
    position_m: [f32; 3],
    rng: u32,
    last_imu: RawImu,
    /// Fixes in the receiver, oldest first (the latency spans 3 of them).
    pending: [Option<Pending>; 4],
    /// Metres per 1e-7 deg of latitude and of longitude at home.
    m_per_lat_e7: f32,
    m_per_lon_e7: f32,
    glitches: Glitches,
}

impl World {
    /// The rover at home, at rest (a `const fn`: the world lives in a
    /// `static` of the SysTick handler).
    pub const fn new() -> Self {
        Self {
            tick: 0,
            yaw_rad: 0.3,
            position_m: [0.0; 3],
            rng: 0x2545_F491,
            last_imu: RawImu {
                t_us: 0,
                gyro: [0; 3],
                accel: [0; 3],
            },
            pending: [None; 4],
            m_per_lat_e7: 0.0,
            m_per_lon_e7: 0.0,
            glitches: Glitches {
                imu: 0,
                mag: 0,
                gps: 0,
            },
        }
    }

    /// The glitches planted so far.
    pub fn glitches(&self) -> Glitches {
        self.glitches
    }

    /// The truth at the newest tick.
    pub fn truth(&self) -> Truth {
        let (speed, _, _) = motion(self.t_s());
        Truth {
            t_us: self.t_us(),
            position_m: self.position_m,
            velocity_m_s: [speed * cosf(self.yaw_rad), speed * sinf(self.yaw_rad), 0.0],
            yaw_rad: self.yaw_rad,
        }
    }

    fn t_us(&self) -> u64 {
        u64::from(self.tick) * 1_000_000 / u64::from(IMU_RATE_HZ)
    }

    fn t_s(&self) -> f32 {
        self.tick as f32 / IMU_RATE_HZ as f32
    }

    /// Advances one IMU period and returns what the sensors deliver.
    pub fn step(&mut self) -> Readings {
        if self.m_per_lat_e7 == 0.0 {
            self.set_home();
        }
        // Midpoint integration of heading and position over the period.
        let dt = 1.0 / IMU_RATE_HZ as f32;
        let mid = self.t_s() + 0.5 * dt;
        let (speed_mid, _, rate_mid) = motion(mid);
        let yaw_mid = self.yaw_rad + 0.5 * dt * rate_mid;
        self.position_m[0] += dt * speed_mid * cosf(yaw_mid);
        self.position_m[1] += dt * speed_mid * sinf(yaw_mid);
        self.yaw_rad += dt * rate_mid;
        self.tick += 1;
        let t_us = self.t_us();

        let imu = if self.tick == DUPLICATE_IMU_AT {
            self.glitches.imu += 1;
            self.last_imu
        } else {
            self.read_imu(t_us)
        };
        self.last_imu = imu;
        let mag = self
            .tick
            .is_multiple_of(MAG_EVERY)
            .then(|| self.read_mag(t_us));
        if self.tick.is_multiple_of(GPS_EVERY) {
            self.make_fix(t_us);
        }
        Readings {
            imu,
            mag,
            gps: self.deliver_fix(t_us),
        }
    }

    fn read_imu(&mut self, t_us: u64) -> RawImu {
        let (speed, accel, rate) = motion(self.t_s());
        // Body FRD: speed change forward, centripetal to the right of a
        // right turn, -g down (level).
        let f = [accel, speed * rate, -G];
        let w = [0.0, 0.0, rate];
        let a_counts = ACCEL_COUNTS_PER_G / G;
        let w_counts = GYRO_COUNTS_PER_DEG_S.to_degrees();
        let mut accel_body = [0i16; 3];
        let mut gyro_body = [0i16; 3];
        for i in 0..3 {
            accel_body[i] = self.counts(f[i] * a_counts, ACCEL_NOISE_COUNTS);
            gyro_body[i] = self.counts(w[i] * w_counts + GYRO_BIAS_COUNTS[i], GYRO_NOISE_COUNTS);
        }
        // Body to the chip's axes (see `RawImu`).
        let to_chip = |b: [i16; 3]| [b[1], -b[0], b[2]];
        RawImu {
            t_us,
            gyro: to_chip(gyro_body),
            accel: to_chip(accel_body),
        }
    }

    fn read_mag(&mut self, t_us: u64) -> RawMag {
        if self.tick == FAILED_MAG_AT {
            self.glitches.mag += 1;
            return RawMag {
                t_us,
                field: [0; 3],
            };
        }
        let (ci, si) = (cosf(INCLINATION_RAD), sinf(INCLINATION_RAD));
        let n = FIELD_GAUSS * ci * cosf(DECLINATION_RAD);
        let e = FIELD_GAUSS * ci * sinf(DECLINATION_RAD);
        let d = FIELD_GAUSS * si;
        let (c, s) = (cosf(self.yaw_rad), sinf(self.yaw_rad));
        let body = [c * n + s * e, -s * n + c * e, d];
        let mut field = [0i16; 3];
        for (f, b) in field.iter_mut().zip(body) {
            *f = self.counts(b * MAG_COUNTS_PER_GAUSS, MAG_NOISE_COUNTS);
        }
        RawMag { t_us, field }
    }

    /// The receiver computes a fix valid now and reports it after its
    /// latency.
    fn make_fix(&mut self, t_us: u64) {
        let truth = self.truth();
        let mut fix = NavPvt {
            t_us: t_us + GPS_DELAY_US,
            fix_type: 3,
            num_sv: 14,
            h_acc: 500,
            v_acc: 800,
            s_acc: 100,
            ..NavPvt::default()
        };
        if t_us < FIRST_FIX_US {
            self.glitches.gps += 1;
            fix.fix_type = 0;
            fix.num_sv = 2;
        } else {
            let n = truth.position_m[0] + GPS_H_NOISE_M * self.gauss();
            let e = truth.position_m[1] + GPS_H_NOISE_M * self.gauss();
            let d = truth.position_m[2] + GPS_V_NOISE_M * self.gauss();
            fix.lat = HOME_LAT_E7 + roundf(n / self.m_per_lat_e7) as i32;
            fix.lon = HOME_LON_E7 + roundf(e / self.m_per_lon_e7) as i32;
            fix.h_msl = HOME_H_MSL_MM - roundf(d * 1000.0) as i32;
            for i in 0..3 {
                let v = truth.velocity_m_s[i] + GPS_VEL_NOISE_M_S * self.gauss();
                fix.vel_ned[i] = roundf(v * 1000.0) as i32;
            }
        }
        if let Some(slot) = self.pending.iter_mut().find(|p| p.is_none()) {
            *slot = Some(Pending {
                due_us: fix.t_us,
                fix,
            });
        }
    }

    fn deliver_fix(&mut self, t_us: u64) -> Option<NavPvt> {
        let due = self.pending[0].filter(|p| p.due_us <= t_us)?;
        self.pending.rotate_left(1);
        self.pending[3] = None;
        Some(due.fix)
    }

    /// Metres per 1e-7 deg at home (WGS-84 radii of curvature).
    fn set_home(&mut self) {
        const A: f32 = 6_378_137.0;
        const E2: f32 = 6.694_38e-3;
        let lat = (HOME_LAT_E7 as f32 * 1e-7).to_radians();
        let s = sinf(lat);
        let w = sqrtf(1.0 - E2 * s * s);
        let meridian = A * (1.0 - E2) / (w * w * w);
        let normal = A / w;
        let per_e7 = 1e-7f32.to_radians();
        self.m_per_lat_e7 = meridian * per_e7;
        self.m_per_lon_e7 = normal * cosf(lat) * per_e7;
    }

    /// `value` plus Gaussian-like noise of `sigma`, rounded to counts.
    fn counts(&mut self, value: f32, sigma: f32) -> i16 {
        let v = roundf(value + sigma * self.gauss());
        v.clamp(i16::MIN as f32, i16::MAX as f32) as i16
    }

    /// Zero mean, unit variance: the sum of four uniforms (xorshift32).
    fn gauss(&mut self) -> f32 {
        let mut sum = 0.0;
        for _ in 0..4 {
            self.rng ^= self.rng << 13;
            self.rng ^= self.rng >> 17;
            self.rng ^= self.rng << 5;
            sum += self.rng as f32 / u32::MAX as f32 - 0.5;
        }
        // Four uniforms on [-0.5, 0.5] have variance 4/12.
        sum * sqrtf(3.0)
    }
}

/// Speed (m/s), its rate (m/s^2) and heading rate (rad/s) at time `t`
/// (s): zero before the start, ramped in smoothly.
fn motion(t: f32) -> (f32, f32, f32) {
    let (r, dr) = ramp(t);
    let ws = core::f32::consts::TAU / SPEED_PERIOD_S;
    let wh = core::f32::consts::TAU / SLALOM_PERIOD_S;
    let tau = t - START_S;
    let speed = SPEED_M_S + SPEED_SWING_M_S * sinf(ws * tau);
    let speed_rate = SPEED_SWING_M_S * ws * cosf(ws * tau);
    let turn = TURN_RAD_S + SLALOM_RAD * wh * cosf(wh * tau);
    (r * speed, dr * speed + r * speed_rate, r * turn)
}

/// The smooth step `3u^2 - 2u^3` from the start over the ramp, and its rate.
fn ramp(t: f32) -> (f32, f32) {
    let u = ((t - START_S) / RAMP_S).clamp(0.0, 1.0);
    (u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u) / RAMP_S)
}

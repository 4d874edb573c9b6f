//! The simulated multirotor's true motion, in closed form.
//!
//! # Position
//! Position NED is a sum of two closed-form parts, each with analytic
//! velocity and acceleration:
//!
//! - a slow 3-D path, `p_path(t) = sum_i A_i sin(2 pi t / T_i + phi_i)` with
//!   per-axis amplitude vectors `A_i` (the figure-of-eight-like loops of the
//!   paper's Figure 4);
//! - the pitch manoeuvre of the paper's Figure 6 along north: a chirp whose
//!   amplitude and frequency both grow exponentially over one manoeuvre
//!   period `T_m` (30 s by default) and then start again,
//!
//!   ```text
//!   tau  = t mod T_m
//!   c(tau)   = k A(tau) sin(phi(tau)),  A(tau) = exp(tau / T_a),
//!   phi(tau) = w0 T_f (exp(tau / T_f) - 1),  phi' = w0 exp(tau / T_f),
//!   T_a = T_m / ln(amplitude growth),  T_f = T_m / ln(f_end / f_start),
//!   x_chirp(t) = w(tau) c(tau)
//!   ```
//!
//!   where `w` is a taper that rises from 0 to 1 over `T_r` seconds at the
//!   start of each period and falls back to 0 over the last `T_r` seconds,
//!   built from the ninth-degree smooth step
//!   `S(u) = 126u^5 - 420u^6 + 540u^7 - 315u^8 + 70u^9` whose first four
//!   derivatives vanish at `u = 0` and `u = 1`. Position is therefore C^6,
//!   acceleration C^4 and the angular rate C^2 across the period boundaries.
//!
//! Both parts are multiplied by a start ramp `r(t) = S(t / T_s)` (8 s by
//! default; `r = 0` before `t = 0`), so the vehicle starts at rest and
//! level at the origin, as a real flight does (and as an accelerometer
//! levelling assumes), and accelerates smoothly:
//! `p(t) = r(t) (p_path(t) - p_path(0) + e_n x_chirp(t))`, differentiated
//! by the product rule.
//!
//! The scale `k` is solved (bisection) so that the largest norm of the
//! kinematic acceleration `|a(t)|` over `[0, max(horizon, T_m)]`, sampled
//! every millisecond, equals the scenario's acceleration limit (19.61 or
//! 50.45 m/s^2). The trajectory for a scenario is therefore the same for
//! every run at least one manoeuvre period long; a shorter run is a prefix
//! of it.
//!
//! # Attitude
//! A multirotor's thrust acts along body `-z`, so the body z axis points
//! along `-f_n`, the negated specific force in NED:
//!
//! ```text
//! f_n = a - [0, 0, g],   z_b = -f_n / |f_n|
//! y_c = [-sin psi, cos psi, 0]          (free yaw psi(t))
//! x_b = (y_c x z_b) / |y_c x z_b|,   y_b = z_b x x_b
//! R   = [x_b  y_b  z_b]                 (body FRD to NED, columns)
//! ```
//!
//! `x_b` is orthogonal to `y_c`, so the ZYX yaw of `R` is exactly `psi(t)`;
//! here `psi(t) = psi_0 + psi_a sin(2 pi t / T_psi)`. The specific force in
//! body axes is `f_b = R^T f_n` (level and at rest: `[0, 0, -g]`).
//!
//! # Angular rate
//! `[w_b]x = R^T dR/dt`, with `dR/dt` from the fourth-order central
//! difference of the closed-form `R(t)` with step `h = 1 ms`:
//! `dR/dt ~ (R(t-2h) - 8R(t-h) + 8R(t+h) - R(t+2h)) / 12h`. Its truncation
//! error is `h^4 R^(5) / 30`, below 1e-9 rad/s for these manoeuvres, and
//! its rounding error near `eps / h`, about 1e-13 rad/s (tested against an
//! integration of the rate in `tests/sim.rs`).

use libm::{cos, exp, log, sin};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Standard gravity, m/s^2: the unit `g` of the paper's Table 3 and the
/// gravity of the simulated world (NED down positive); the one the EKF uses.
pub use crate::ekf16::STANDARD_GRAVITY;

/// Step of the central difference that gives the angular rate, seconds.
const RATE_DIFFERENCE_STEP_S: f64 = 1e-3;

/// Grid on which the acceleration limit is enforced, seconds.
const LIMIT_GRID_STEP_S: f64 = 1e-3;

/// The paper's two dynamic scenarios (Table 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Scenario {
    /// Acceleration limited to 19.61 m/s^2 (2 g).
    Low,
    /// Acceleration limited to 50.45 m/s^2.
    High,
}

impl Scenario {
    /// Both scenarios, `low` first.
    pub const ALL: [Scenario; 2] = [Scenario::Low, Scenario::High];

    /// The scenario's name in the reproduce harness and its JSON (`"low"`, `"high"`).
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Low => "low",
            Scenario::High => "high",
        }
    }

    /// Largest norm of the kinematic acceleration, m/s^2.
    pub fn accel_limit_m_s2(self) -> f64 {
        match self {
            Scenario::Low => 19.61,
            Scenario::High => 50.45,
        }
    }
}

/// One sinusoid of the slow 3-D path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathTerm {
    /// Amplitude per NED axis, metres.
    pub amplitude_m: Vector3<f64>,
    /// Period, seconds (> 0).
    pub period_s: f64,
    /// Phase at `t = 0`, radians.
    pub phase_rad: f64,
}

/// Shape of the true trajectory. `Default` is the `low` scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryConfig {
    /// Largest norm of the kinematic acceleration over the run, m/s^2.
    pub accel_limit_m_s2: f64,
    /// The slow 3-D path.
    pub path: Vec<PathTerm>,
    /// Length of one pitch manoeuvre (chirp period), seconds.
    pub manoeuvre_period_s: f64,
    /// Chirp frequency at the start of a manoeuvre, Hz.
    pub chirp_start_hz: f64,
    /// Chirp frequency at the end of a manoeuvre, Hz.
    pub chirp_end_hz: f64,
    /// Ratio of the chirp amplitude at the end of a manoeuvre to its start.
    pub amplitude_growth: f64,
    /// Duration of the taper at each end of a manoeuvre, seconds.
    pub taper_s: f64,
    /// Duration of the start ramp from rest, seconds.
    pub start_ramp_s: f64,
    /// Mean yaw, radians.
    pub yaw_offset_rad: f64,
    /// Yaw swing amplitude, radians.
    pub yaw_amplitude_rad: f64,
    /// Yaw swing period, seconds.
    pub yaw_period_s: f64,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self::for_scenario(Scenario::Low)
    }
}

impl TrajectoryConfig {
    /// The default shape with a scenario's acceleration limit.
    pub fn for_scenario(scenario: Scenario) -> Self {
        Self {
            accel_limit_m_s2: scenario.accel_limit_m_s2(),
            path: vec![
                PathTerm {
                    amplitude_m: Vector3::new(40.0, 0.0, 0.0),
                    period_s: 60.0,
                    phase_rad: 0.0,
                },
                PathTerm {
                    amplitude_m: Vector3::new(0.0, 30.0, 0.0),
                    period_s: 40.0,
                    phase_rad: 0.5,
                },
                PathTerm {
                    amplitude_m: Vector3::new(0.0, 0.0, 8.0),
                    period_s: 30.0,
                    phase_rad: 1.0,
                },
                PathTerm {
                    amplitude_m: Vector3::new(10.0, 10.0, 0.0),
                    period_s: 15.0,
                    phase_rad: 2.0,
                },
            ],
            manoeuvre_period_s: 30.0,
            chirp_start_hz: 0.1,
            chirp_end_hz: 0.8,
            amplitude_growth: 10.0,
            taper_s: 1.5,
            start_ramp_s: 8.0,
            yaw_offset_rad: 0.0,
            yaw_amplitude_rad: 0.35,
            yaw_period_s: 45.0,
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), crate::Error> {
        use crate::Error::InvalidConfig;
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(self.accel_limit_m_s2) {
            return Err(InvalidConfig {
                field: "accel_limit_m_s2".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and positive"),
            });
        }
        for term in &self.path {
            if !positive(term.period_s)
                || !term.phase_rad.is_finite()
                || !term.amplitude_m.iter().all(|a| a.is_finite())
            {
                return Err(InvalidConfig {
                    field: "path".into(),
                    value: None,
                    bound: crate::error::Bound::Rule(
                        "periods must be positive, amplitudes and phases finite",
                    ),
                });
            }
        }
        if !positive(self.manoeuvre_period_s)
            || !positive(self.taper_s)
            || 2.0 * self.taper_s > self.manoeuvre_period_s
        {
            return Err(InvalidConfig {
                field: "manoeuvre_period_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be positive and at least twice taper_s"),
            });
        }
        if !(positive(self.chirp_start_hz)
            && self.chirp_end_hz.is_finite()
            && self.chirp_end_hz > self.chirp_start_hz)
        {
            return Err(InvalidConfig {
                field: "chirp_end_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule("chirp frequencies must be positive and grow"),
            });
        }
        if !positive(self.start_ramp_s) {
            return Err(InvalidConfig {
                field: "start_ramp_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and positive"),
            });
        }
        if !(self.amplitude_growth.is_finite() && self.amplitude_growth > 1.0) {
            return Err(InvalidConfig {
                field: "amplitude_growth".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and above 1"),
            });
        }
        if !self.yaw_offset_rad.is_finite()
            || !self.yaw_amplitude_rad.is_finite()
            || !positive(self.yaw_period_s)
        {
            return Err(InvalidConfig {
                field: "yaw_period_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("yaw terms must be finite, the period positive"),
            });
        }
        Ok(())
    }
}

/// Position, velocity and acceleration at one instant, NED.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    /// Position, metres.
    pub position_m: Vector3<f64>,
    /// Velocity, m/s.
    pub velocity_m_s: Vector3<f64>,
    /// Kinematic acceleration, m/s^2.
    pub accel_m_s2: Vector3<f64>,
}

/// The full true motion at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionState {
    /// Time, seconds.
    pub t_s: f64,
    /// Position, velocity, acceleration, NED.
    pub kinematics: Kinematics,
    /// Body-to-NED rotation.
    pub rotation: Matrix3<f64>,
    /// The same rotation as a unit quaternion (scalar part >= 0).
    pub attitude: UnitQuaternion<f64>,
    /// Angular rate of the body, body FRD, rad/s.
    pub angular_rate_rad_s: Vector3<f64>,
    /// Specific force `R^T (a - [0, 0, g])`, body FRD, m/s^2.
    pub specific_force_m_s2: Vector3<f64>,
}

/// The ninth-degree smooth step and its first two derivatives, clamped to
/// `[0, 1]` outside the unit interval.
fn smooth_step(u: f64) -> [f64; 3] {
    if u <= 0.0 {
        return [0.0, 0.0, 0.0];
    }
    if u >= 1.0 {
        return [1.0, 0.0, 0.0];
    }
    // S = u^5 (126 - 420u + 540u^2 - 315u^3 + 70u^4)
    let u3 = u * u * u;
    let s = u3 * u * u * (126.0 + u * (-420.0 + u * (540.0 + u * (-315.0 + u * 70.0))));
    // S' = 630 u^4 (1 - u)^4
    let v = 1.0 - u;
    let v3 = v * v * v;
    let ds = 630.0 * u3 * u * v3 * v;
    // S'' = 2520 u^3 (1 - u)^3 (1 - 2u)
    let dds = 2520.0 * u3 * v3 * (1.0 - 2.0 * u);
    [s, ds, dds]
}

/// The closed-form true trajectory of one scenario.
#[derive(Debug, Clone)]
pub struct Trajectory {
    config: TrajectoryConfig,
    chirp_scale_m: f64,
}

impl Trajectory {
    /// Builds the trajectory and solves the chirp scale so that the largest
    /// acceleration norm over `[0, max(horizon_s, manoeuvre period)]` equals
    /// the configured limit.
    pub fn new(config: TrajectoryConfig, horizon_s: f64) -> Result<Self, crate::Error> {
        config.validate()?;
        if !(horizon_s.is_finite() && horizon_s > 0.0) {
            return Err(crate::Error::InvalidConfig {
                field: "duration_s".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite and positive"),
            });
        }
        let mut traj = Self {
            config,
            chirp_scale_m: 0.0,
        };
        let span = horizon_s.max(traj.config.manoeuvre_period_s);
        let n = (span / LIMIT_GRID_STEP_S).ceil() as usize + 1;
        let mut path_accel = Vec::with_capacity(n);
        let mut chirp_accel = Vec::with_capacity(n);
        for i in 0..n {
            let t = i as f64 * LIMIT_GRID_STEP_S;
            path_accel.push(traj.ramped_path(t).accel_m_s2);
            chirp_accel.push(traj.ramped_chirp(t)[2]);
        }
        let max_norm = |k: f64| {
            path_accel
                .iter()
                .zip(&chirp_accel)
                .map(|(p, c)| (p + Vector3::new(k * c, 0.0, 0.0)).norm())
                .fold(0.0, f64::max)
        };
        let limit = traj.config.accel_limit_m_s2;
        if max_norm(0.0) >= limit {
            return Err(crate::Error::InvalidConfig {
                field: "accel_limit_m_s2".into(),
                value: None,
                bound: crate::error::Bound::Rule("the slow path alone already reaches the limit"),
            });
        }
        let mut hi = 1.0;
        while max_norm(hi) < limit {
            hi *= 2.0;
        }
        let mut lo = 0.0;
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if max_norm(mid) < limit {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        traj.chirp_scale_m = 0.5 * (lo + hi);
        Ok(traj)
    }

    /// The configuration.
    pub fn config(&self) -> &TrajectoryConfig {
        &self.config
    }

    /// Amplitude of the chirp at the start of a manoeuvre, metres (the
    /// solved scale `k`).
    pub fn chirp_scale_m(&self) -> f64 {
        self.chirp_scale_m
    }

    fn path(&self, t: f64) -> Kinematics {
        let mut k = Kinematics {
            position_m: Vector3::zeros(),
            velocity_m_s: Vector3::zeros(),
            accel_m_s2: Vector3::zeros(),
        };
        for term in &self.config.path {
            let w = core::f64::consts::TAU / term.period_s;
            let arg = w * t + term.phase_rad;
            let (s, c) = (sin(arg), cos(arg));
            k.position_m += term.amplitude_m * s;
            k.velocity_m_s += term.amplitude_m * (w * c);
            k.accel_m_s2 -= term.amplitude_m * (w * w * s);
        }
        k
    }

    /// The tapered chirp with unit scale: position, velocity, acceleration
    /// along north.
    fn unit_chirp(&self, t: f64) -> [f64; 3] {
        let cfg = &self.config;
        if t <= 0.0 {
            return [0.0; 3];
        }
        let period = cfg.manoeuvre_period_s;
        let tau = t.rem_euclid(period);
        let t_a = period / log(cfg.amplitude_growth);
        let t_f = period / log(cfg.chirp_end_hz / cfg.chirp_start_hz);
        let w0 = core::f64::consts::TAU * cfg.chirp_start_hz;
        // c = A sin(phi)
        let amp = exp(tau / t_a);
        let (d_amp, dd_amp) = (amp / t_a, amp / (t_a * t_a));
        let growth = exp(tau / t_f);
        let phi = w0 * t_f * (growth - 1.0);
        let d_phi = w0 * growth;
        let dd_phi = d_phi / t_f;
        let (s, c) = (sin(phi), cos(phi));
        let chirp = [
            amp * s,
            d_amp * s + amp * d_phi * c,
            dd_amp * s + 2.0 * d_amp * d_phi * c + amp * dd_phi * c - amp * d_phi * d_phi * s,
        ];
        // w = S(tau / T_r) S((T - tau) / T_r)
        let rise = smooth_step(tau / cfg.taper_s);
        let fall = smooth_step((period - tau) / cfg.taper_s);
        let r = cfg.taper_s;
        let taper = [
            rise[0] * fall[0],
            rise[1] * fall[0] / r - rise[0] * fall[1] / r,
            rise[2] * fall[0] / (r * r) - 2.0 * rise[1] * fall[1] / (r * r)
                + rise[0] * fall[2] / (r * r),
        ];
        [
            taper[0] * chirp[0],
            taper[1] * chirp[0] + taper[0] * chirp[1],
            taper[2] * chirp[0] + 2.0 * taper[1] * chirp[1] + taper[0] * chirp[2],
        ]
    }

    /// The slow path times the start ramp.
    fn ramped_path(&self, t: f64) -> Kinematics {
        let r = self.ramp(t);
        let mut p = self.path(t);
        p.position_m -= self.path(0.0).position_m;
        Kinematics {
            position_m: p.position_m * r[0],
            velocity_m_s: p.velocity_m_s * r[0] + p.position_m * r[1],
            accel_m_s2: p.accel_m_s2 * r[0] + p.velocity_m_s * (2.0 * r[1]) + p.position_m * r[2],
        }
    }

    /// The unit chirp times the start ramp.
    fn ramped_chirp(&self, t: f64) -> [f64; 3] {
        let r = self.ramp(t);
        let c = self.unit_chirp(t);
        [
            r[0] * c[0],
            r[0] * c[1] + r[1] * c[0],
            r[0] * c[2] + 2.0 * r[1] * c[1] + r[2] * c[0],
        ]
    }

    /// The start ramp and its first two time derivatives.
    fn ramp(&self, t: f64) -> [f64; 3] {
        let ramp_s = self.config.start_ramp_s;
        let s = smooth_step(t / ramp_s);
        [s[0], s[1] / ramp_s, s[2] / (ramp_s * ramp_s)]
    }

    /// Position, velocity and acceleration at `t_s` (any real time; the
    /// vehicle rests at the origin before `t = 0`).
    pub fn kinematics(&self, t_s: f64) -> Kinematics {
        let mut k = self.ramped_path(t_s);
        let chirp = self.ramped_chirp(t_s);
        k.position_m.x += self.chirp_scale_m * chirp[0];
        k.velocity_m_s.x += self.chirp_scale_m * chirp[1];
        k.accel_m_s2.x += self.chirp_scale_m * chirp[2];
        k
    }

    /// Yaw at `t_s`, radians.
    pub fn yaw_rad(&self, t_s: f64) -> f64 {
        let cfg = &self.config;
        cfg.yaw_offset_rad
            + cfg.yaw_amplitude_rad * sin(core::f64::consts::TAU * t_s / cfg.yaw_period_s)
    }

    /// Body-to-NED rotation from an acceleration and a yaw (thrust along body `-z`).
    fn rotation_from(accel: &Vector3<f64>, yaw: f64) -> Matrix3<f64> {
        let f_n = accel - Vector3::new(0.0, 0.0, STANDARD_GRAVITY);
        let z_b = -f_n / f_n.norm();
        let y_c = Vector3::new(-sin(yaw), cos(yaw), 0.0);
        let x_b = y_c.cross(&z_b).normalize();
        let y_b = z_b.cross(&x_b);
        Matrix3::from_columns(&[x_b, y_b, z_b])
    }

    /// Body-to-NED rotation at `t_s`.
    pub fn rotation(&self, t_s: f64) -> Matrix3<f64> {
        Self::rotation_from(&self.kinematics(t_s).accel_m_s2, self.yaw_rad(t_s))
    }

    /// Everything true about the motion at `t_s`.
    pub fn state(&self, t_s: f64) -> MotionState {
        let kinematics = self.kinematics(t_s);
        let rotation = Self::rotation_from(&kinematics.accel_m_s2, self.yaw_rad(t_s));
        let h = RATE_DIFFERENCE_STEP_S;
        let d_rot = (self.rotation(t_s - 2.0 * h) - 8.0 * self.rotation(t_s - h)
            + 8.0 * self.rotation(t_s + h)
            - self.rotation(t_s + 2.0 * h))
            / (12.0 * h);
        let skew = rotation.transpose() * d_rot;
        // vee of the (nearly) skew matrix, averaging its two halves
        let angular_rate_rad_s = Vector3::new(
            0.5 * (skew[(2, 1)] - skew[(1, 2)]),
            0.5 * (skew[(0, 2)] - skew[(2, 0)]),
            0.5 * (skew[(1, 0)] - skew[(0, 1)]),
        );
        let mut attitude =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
        if attitude.w < 0.0 {
            attitude = UnitQuaternion::new_unchecked(-attitude.into_inner());
        }
        let specific_force_m_s2 = rotation.transpose()
            * (kinematics.accel_m_s2 - Vector3::new(0.0, 0.0, STANDARD_GRAVITY));
        MotionState {
            t_s,
            kinematics,
            rotation,
            attitude,
            angular_rate_rad_s,
            specific_force_m_s2,
        }
    }
}

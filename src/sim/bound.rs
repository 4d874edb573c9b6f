//! The linearized bound of a run: the covariance of an extended Kalman filter
//! linearized about the **true** trajectory, with the true noise.
//!
//! Any estimator on a simulated run is judged against what the run's
//! sensors allow. [`noise_floor`](super::noise_floor()) answers that for
//! hover with known biases; this module answers it for the run itself: the
//! same trajectory, the same sample and fix times, the same delay, biases to
//! estimate.
//!
//! # Model
//! Error state (15), attitude as the NED rotation vector of the error
//! `R_est R^T = exp([phi]x)` (the error [`tilt_heading_error_rad`] scores),
//! biases in body FRD:
//!
//! ```text
//! x = [phi, dp, dv, db_a, db_g, b_m]
//! phi' = -R db_g + R n_g
//! dp'  = dv
//! dv'  = -[f_n]x phi - R db_a + R n_a
//! db_a' = w_a,  db_g' = w_g,  b_m' = 0
//! ```
//!
//! `b_m` is the magnetometer's body-field (hard-iron) offset in units of the field: a constant
//! with the prior [`BoundConfig::mag_offset_std`] per axis (0, the default: known, and the
//! bound is the 15-state one).
//!
//! `R` is the true body-to-NED rotation and `f_n = a - [0, 0, g]` the true
//! specific force in NED, both at the start of each IMU step: the Jacobians
//! are evaluated on the truth, so no estimation error feeds back. Per IMU
//! step of `dt` seconds, with `F` the matrix above,
//!
//! ```text
//! Phi   = I + F dt + F² dt²/2 + F³ dt³/6
//! Gamma = (I dt + F dt²/2 + F² dt³/6) G        (G maps n_g, n_a into phi', dv')
//! P    <- Phi P Phi^T + Gamma diag(s_g², s_a²) Gamma^T + diag(0, 0, 0, q_a dt, q_g dt)
//! ```
//!
//! with `s_g²`, `s_a²` the per-sample variances of the simulator's gyro and
//! accelerometer noise and `q_a`, `q_g` its bias random walks (the same
//! discretization as [`noise_floor`](super::noise_floor()), which this
//! reduces to at hover with the biases known).
//!
//! Measurements, with the simulator's own variances:
//!
//! - GPS position and velocity, `H = [0 I 0 0 0; 0 0 I 0 0]`, fused at the
//!   instant the fix describes (`t - tau`, the true delay);
//! - the magnetometer ([`BoundMagnetometer`]): by default the whole field,
//!   `m_b = R^T m_n + b_m + n_m`, `H = [R^T [m_n]x, 0..., I3]`, variance `s_m²` per
//!   axis: two degrees of attitude, tilt included. The crate's filters take
//!   one degree from it, the heading of the field de-rotated with their
//!   estimated tilt, `H = [-tan I cos D, -tan I sin D, 1, 0...]`, variance
//!   `s_m² / cos² I` ([`BoundMagnetometer::FilterHeading`]; with the optimal
//!   gain, the bound of any filter taking that heading; with their
//!   heading-only gain once the tilt is known, their own covariance about
//!   the truth). Or a heading sensor,
//!   `H = [tan(theta) cos(psi), tan(theta) sin(psi), 1, 0...]` (the ZYX yaw
//!   change of a rotation-vector error `phi`), variance `s_m² / cos² I`, the
//!   model of [`noise_floor`](super::noise_floor()).
//!
//! # Causality
//! A fix received at `t` describes `t - tau`, so at time `t` the best any
//! filter can know is the covariance after the fixes *received* by `t`. The
//! bound runs a chain at validity time, fusing each fix at the IMU sample at
//! or before `t - tau`, and when a fix arrives re-propagates a copy of that
//! chain to the present through the buffered truth (magnetometer included):
//! the per-time bound is that present covariance, evaluated at every IMU
//! sample after the fixes received strictly before it.
//!
//! # What it bounds
//! The covariance is the error covariance of the linear(ized) optimal filter
//! for this run; no causal estimator that uses the same measurements can do
//! better in expectation, to first order in the errors. It does not include
//! the delay's own uncertainty (known delay), so it is a bound for every
//! estimator, not a prediction of any. The per-time RMS bounds are
//! square roots of the relevant covariance sums: tilt
//! `sqrt(P_phiN + P_phiE)`, heading `sqrt(P_phiD)`, 3-D velocity and
//! position `sqrt(trace)`; Euler angles through the ZYX map from `phi`.
//!
//! [`tilt_heading_error_rad`]: super::tilt_heading_error_rad

use super::{STANDARD_GRAVITY, SensorConfig, SimConfig, SimEvent};
use crate::Ekf16Config;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// Size of the error state: the 15 navigation errors, then the magnetometer's body-field offset.
const N: usize = 18;
/// Size of the navigation part of the error state (the part the motion propagates).
const NAV: usize = 15;
/// Index of the attitude error.
const PHI: usize = 0;
/// Index of the position error.
const POS: usize = 3;
/// Index of the velocity error.
const VEL: usize = 6;
/// Index of the accelerometer bias error.
const BA: usize = 9;
/// Index of the gyro bias error.
const BG: usize = 12;
/// Index of the magnetometer's body-field (hard-iron) offset, unit field, body FRD.
const OFF: usize = 15;

type Cov = SMatrix<f64, N, N>;
/// The transition of the navigation errors (the offset is constant).
type NavMatrix = SMatrix<f64, NAV, NAV>;

/// What the bound's filter takes from the magnetometer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoundMagnetometer {
    /// The whole field: heading and tilt (module docs).
    Field,
    /// A heading alone, the ZYX yaw, as [`noise_floor`](super::noise_floor()) models it.
    Heading,
    /// What the crate's filters take from the magnetometer: the heading of
    /// the field de-rotated with the *estimated* tilt, which a tilt error
    /// along the field's horizontal direction moves by `tan I` times
    /// (`dpsi = phi_D - tan I (phi_N cos D + phi_E sin D)`), variance
    /// `s_m² / cos² I`. Fused with the optimal gain while the tilt is less
    /// certain than [`BoundConfig::mag_tilt_alignment_std_rad`], after that
    /// with the filters' heading-only gain (`Ekf16Config::mag_corrects_tilt`
    /// false: the correction turns about the vertical only, the
    /// accelerometer biases and the body roll and pitch rate biases stay,
    /// Joseph form). With a threshold of 0 the gain is always optimal: a
    /// bound for any filter taking that heading; above 0, not a bound but
    /// the covariance of the filters' own gain about the truth.
    FilterHeading,
}

/// Prior of the bound's filter (standard deviations at the first IMU
/// sample) and its use of the magnetometer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundConfig {
    /// What the magnetometer contributes.
    pub magnetometer: BoundMagnetometer,
    /// With [`BoundMagnetometer::FilterHeading`]: the optimal gain is used
    /// while the larger of the north and east attitude standard deviations
    /// is above this, rad (`Ekf16Config::mag_tilt_alignment_std_rad`); 0:
    /// always.
    pub mag_tilt_alignment_std_rad: f64,
    /// Tilt, per horizontal axis, radians.
    pub tilt_std_rad: f64,
    /// Heading, radians.
    pub heading_std_rad: f64,
    /// Position, per axis, metres.
    pub position_std_m: f64,
    /// Velocity, per axis, m/s.
    pub velocity_std_m_s: f64,
    /// Accelerometer bias, per axis, m/s^2.
    pub accel_bias_std_m_s2: f64,
    /// Gyro bias, per axis, rad/s.
    pub gyro_bias_std_rad_s: f64,
    /// The magnetometer's body-field (hard-iron) offset, per axis, in units of the field (0:
    /// known, as calibrated). Above 0 only with [`BoundMagnetometer::Field`]: the heading models
    /// have no offset term.
    pub mag_offset_std: f64,
}

impl BoundConfig {
    /// The prior the crate's filters start from on a simulated run
    /// ([`SensorConfig::ekf16_config`]: biases with the spread of the
    /// simulator's uniform draw, `max / sqrt(3)`, tilt 0.1 rad, heading
    /// 0.3 rad, position 5 m, velocity 1 m/s); the whole magnetometer field.
    pub fn for_sensors(sensors: &SensorConfig) -> Self {
        Self {
            magnetometer: BoundMagnetometer::Field,
            ..Self::for_filter(&sensors.ekf16_config())
        }
    }

    /// The prior of a filter configured with `filter` (its initial standard
    /// deviations, the heading one with a magnetometer), and the
    /// magnetometer as it uses it ([`BoundMagnetometer::FilterHeading`]):
    /// with `mag_corrects_tilt`, the optimal gain throughout (threshold 0),
    /// else its heading-only gain once the tilt is below its alignment
    /// threshold.
    pub fn for_filter(filter: &Ekf16Config<f64>) -> Self {
        Self {
            magnetometer: BoundMagnetometer::FilterHeading,
            mag_tilt_alignment_std_rad: if filter.mag_corrects_tilt {
                0.0
            } else {
                filter.mag_tilt_alignment_std_rad
            },
            tilt_std_rad: filter.initial_tilt_std_rad,
            heading_std_rad: filter.initial_yaw_std_rad,
            position_std_m: filter.initial_position_std_m,
            velocity_std_m_s: filter.initial_velocity_std_m_s,
            accel_bias_std_m_s2: filter.initial_accel_bias_std_m_s2,
            gyro_bias_std_rad_s: filter.initial_gyro_bias_std_rad_s,
            mag_offset_std: 0.0,
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), crate::Error> {
        let fields = [
            ("tilt_std_rad", self.tilt_std_rad),
            ("heading_std_rad", self.heading_std_rad),
            ("position_std_m", self.position_std_m),
            ("velocity_std_m_s", self.velocity_std_m_s),
            ("accel_bias_std_m_s2", self.accel_bias_std_m_s2),
            ("gyro_bias_std_rad_s", self.gyro_bias_std_rad_s),
            ("mag_offset_std", self.mag_offset_std),
            (
                "mag_tilt_alignment_std_rad",
                self.mag_tilt_alignment_std_rad,
            ),
        ];
        for (field, x) in fields {
            if !(x.is_finite() && x >= 0.0) {
                return Err(crate::Error::InvalidConfig {
                    field: field.into(),
                    value: Some(x),
                    bound: crate::error::Bound::NotNegative,
                });
            }
        }
        if self.mag_offset_std > 0.0 && self.magnetometer != BoundMagnetometer::Field {
            return Err(crate::Error::InvalidConfig {
                field: "mag_offset_std".into(),
                value: Some(self.mag_offset_std),
                bound: crate::error::Bound::Rule(
                    "an unknown magnetometer offset needs the whole-field magnetometer model",
                ),
            });
        }
        Ok(())
    }
}

/// Standard deviations (RMS bounds) of the scored figures: at one instant
/// ([`BoundSample`]) or as the RMS over time of a run
/// ([`TrajectoryBound::rms_after`], the square root of the mean variance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundRms {
    /// Tilt, radians.
    pub tilt_rad: f64,
    /// Heading (down component of the rotation-vector error), radians.
    pub heading_rad: f64,
    /// Roll, pitch, yaw (ZYX), radians.
    pub euler_rad: Vector3<f64>,
    /// 3-D velocity error norm, m/s.
    pub velocity_m_s: f64,
    /// 3-D position error norm, metres.
    pub position_m: f64,
    /// Accelerometer bias per body axis, m/s^2.
    pub accel_bias_m_s2: Vector3<f64>,
    /// Gyro bias per body axis, rad/s.
    pub gyro_bias_rad_s: Vector3<f64>,
}

/// The bound at one IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundSample {
    /// Time, microseconds.
    pub t_us: u64,
    /// The standard deviations at that time.
    pub std: BoundRms,
}

/// The per-time bound of a run, one sample per IMU sample.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryBound {
    /// The bound at every IMU sample, in time order.
    pub samples: Vec<BoundSample>,
}

impl TrajectoryBound {
    /// RMS over the samples at or after `skip_us`; `None` when there is none.
    pub fn rms_after(&self, skip_us: u64) -> Option<BoundRms> {
        let counted: Vec<&BoundSample> =
            self.samples.iter().filter(|s| s.t_us >= skip_us).collect();
        if counted.is_empty() {
            return None;
        }
        let n = counted.len() as f64;
        let rms = |f: &dyn Fn(&BoundRms) -> f64| {
            (counted.iter().map(|s| f(&s.std).powi(2)).sum::<f64>() / n).sqrt()
        };
        let rms3 =
            |f: &dyn Fn(&BoundRms) -> Vector3<f64>| Vector3::from_fn(|i, _| rms(&|s| f(s)[i]));
        Some(BoundRms {
            tilt_rad: rms(&|s| s.tilt_rad),
            heading_rad: rms(&|s| s.heading_rad),
            euler_rad: rms3(&|s| s.euler_rad),
            velocity_m_s: rms(&|s| s.velocity_m_s),
            position_m: rms(&|s| s.position_m),
            accel_bias_m_s2: rms3(&|s| s.accel_bias_m_s2),
            gyro_bias_rad_s: rms3(&|s| s.gyro_bias_rad_s),
        })
    }
}

/// The truth at one IMU sample, as the bound's Jacobians need it.
struct Step {
    t_us: u64,
    rotation: Matrix3<f64>,
    specific_force_ned: Vector3<f64>,
    euler: Vector3<f64>,
    /// Magnetometer samples fused at this step.
    mags: usize,
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The bound's filter: its noise, and the covariance steps.
struct Model {
    var_g: f64,
    var_a: f64,
    walk_a: f64,
    walk_g: f64,
    var_p: f64,
    var_v: f64,
    var_heading: f64,
    var_field: f64,
    field_ned: Vector3<f64>,
    magnetometer: BoundMagnetometer,
    mag_tilt_alignment_var: f64,
    /// `d psi / d phi` of [`BoundMagnetometer::FilterHeading`].
    filter_heading_jacobian: Vector3<f64>,
}

impl Model {
    /// Propagates `p` over the step from `from` (Jacobians at `from`) to `to_us`.
    fn propagate(&self, p: &mut Cov, from: &Step, to_us: u64) {
        let dt = to_us.saturating_sub(from.t_us) as f64 * 1e-6;
        if dt <= 0.0 {
            return;
        }
        let r = from.rotation;
        let fx = skew(&from.specific_force_ned);
        let fxr = fx * r;
        let (dt2, dt3) = (dt * dt / 2.0, dt.powi(3) / 6.0);
        // Phi = I + F dt + F² dt²/2 + F³ dt³/6, written by blocks (F is
        // nilpotent: F² and F³ have the few blocks below).
        let mut phi = NavMatrix::identity();
        phi.fixed_view_mut::<3, 3>(PHI, BG).copy_from(&(-r * dt));
        phi.fixed_view_mut::<3, 3>(POS, VEL)
            .copy_from(&(Matrix3::identity() * dt));
        phi.fixed_view_mut::<3, 3>(POS, PHI).copy_from(&(-fx * dt2));
        phi.fixed_view_mut::<3, 3>(POS, BA).copy_from(&(-r * dt2));
        phi.fixed_view_mut::<3, 3>(POS, BG).copy_from(&(fxr * dt3));
        phi.fixed_view_mut::<3, 3>(VEL, PHI).copy_from(&(-fx * dt));
        phi.fixed_view_mut::<3, 3>(VEL, BA).copy_from(&(-r * dt));
        phi.fixed_view_mut::<3, 3>(VEL, BG).copy_from(&(fxr * dt2));
        // Gamma = (I dt + F dt²/2 + F² dt³/6) G: gyro noise, then accelerometer.
        let mut gamma = SMatrix::<f64, NAV, 6>::zeros();
        gamma.fixed_view_mut::<3, 3>(PHI, 0).copy_from(&(r * dt));
        gamma
            .fixed_view_mut::<3, 3>(VEL, 0)
            .copy_from(&(-fxr * dt2));
        gamma
            .fixed_view_mut::<3, 3>(POS, 0)
            .copy_from(&(-fxr * dt3));
        gamma.fixed_view_mut::<3, 3>(VEL, 3).copy_from(&(r * dt));
        gamma.fixed_view_mut::<3, 3>(POS, 3).copy_from(&(r * dt2));
        let mut noise = SVector::<f64, 6>::zeros();
        noise.fixed_rows_mut::<3>(0).fill(self.var_g);
        noise.fixed_rows_mut::<3>(3).fill(self.var_a);
        let scaled = gamma * SMatrix::<f64, 6, 6>::from_diagonal(&noise);
        // The offset is constant: its block stays, its correlations move with the navigation
        // errors.
        let nav = p.fixed_view::<NAV, NAV>(0, 0).into_owned();
        let cross = p.fixed_view::<NAV, 3>(0, OFF).into_owned();
        p.fixed_view_mut::<NAV, NAV>(0, 0)
            .copy_from(&(phi * nav * phi.transpose() + scaled * gamma.transpose()));
        let cross = phi * cross;
        p.fixed_view_mut::<NAV, 3>(0, OFF).copy_from(&cross);
        p.fixed_view_mut::<3, NAV>(OFF, 0)
            .copy_from(&cross.transpose());
        for i in 0..3 {
            p[(BA + i, BA + i)] += self.walk_a * dt;
            p[(BG + i, BG + i)] += self.walk_g * dt;
        }
    }

    /// Fuses a GPS fix (position and velocity) into `p`.
    fn fuse_gps(&self, p: &mut Cov) {
        let mut s = p.fixed_view::<6, 6>(POS, POS).into_owned();
        for i in 0..3 {
            s[(i, i)] += self.var_p;
            s[(3 + i, 3 + i)] += self.var_v;
        }
        let Some(chol) = s.cholesky() else {
            return;
        };
        let ph = p.fixed_columns::<6>(POS).into_owned();
        let k = chol.solve(&ph.transpose());
        *p -= ph * k;
        symmetrize(p);
    }

    /// Fuses one magnetometer sample at the attitude of `step` into `p`.
    fn fuse_mag(&self, p: &mut Cov, step: &Step) {
        match self.magnetometer {
            BoundMagnetometer::Field => self.fuse_field(p, step),
            BoundMagnetometer::Heading => self.fuse_heading(p, step),
            BoundMagnetometer::FilterHeading => self.fuse_filter_heading(p, step),
        }
    }

    /// Fuses the whole field: `H = R^T [m_n]x` on the attitude error, `I3` on the offset.
    fn fuse_field(&self, p: &mut Cov, step: &Step) {
        let h_att = step.rotation.transpose() * skew(&self.field_ned);
        let p_att = p.fixed_rows::<3>(PHI).into_owned();
        let p_off = p.fixed_rows::<3>(OFF).into_owned();
        // H P = h_att P[PHI rows] + P[OFF rows]; S = H P H^T + R.
        let hp = h_att * p_att + p_off;
        let mut s = hp.fixed_columns::<3>(PHI) * h_att.transpose() + hp.fixed_columns::<3>(OFF);
        for i in 0..3 {
            s[(i, i)] += self.var_field;
        }
        let Some(chol) = s.cholesky() else {
            return;
        };
        let k_t = chol.solve(&hp);
        *p -= hp.transpose() * k_t;
        symmetrize(p);
    }

    /// Fuses a magnetometer heading at the attitude of `step` into `p`.
    fn fuse_heading(&self, p: &mut Cov, step: &Step) {
        let (pitch, yaw) = (step.euler.y, step.euler.z);
        let t = pitch.tan();
        let mut h = SVector::<f64, N>::zeros();
        h[PHI] = t * yaw.cos();
        h[PHI + 1] = t * yaw.sin();
        h[PHI + 2] = 1.0;
        let ph = *p * h;
        let s = h.dot(&ph) + self.var_heading;
        if !(s.is_finite() && s > 0.0) {
            return;
        }
        *p -= ph * ph.transpose() / s;
        symmetrize(p);
    }

    /// Fuses the filters' heading ([`BoundMagnetometer::FilterHeading`]).
    fn fuse_filter_heading(&self, p: &mut Cov, step: &Step) {
        let mut h = SVector::<f64, N>::zeros();
        h.fixed_rows_mut::<3>(PHI)
            .copy_from(&self.filter_heading_jacobian);
        let ph = *p * h;
        let s = h.dot(&ph) + self.var_heading;
        if !(s.is_finite() && s > 0.0) {
            return;
        }
        let mut k = ph / s;
        let aligning = p[(PHI, PHI)].max(p[(PHI + 1, PHI + 1)]) > self.mag_tilt_alignment_var;
        if !aligning {
            // The filters' restriction: the correction is a turn about the
            // NED down axis by the ZYX yaw change the gain asks for; no
            // accelerometer bias; of the gyro bias, its body-down part.
            let (pitch, yaw) = (step.euler.y, step.euler.z);
            let yaw_row = Vector3::new(pitch.tan() * yaw.cos(), pitch.tan() * yaw.sin(), 1.0);
            let dyaw = yaw_row.dot(&k.fixed_rows::<3>(PHI));
            k.fixed_rows_mut::<3>(PHI)
                .copy_from(&Vector3::new(0.0, 0.0, dyaw));
            k.fixed_rows_mut::<3>(BA).fill(0.0);
            let down = step.rotation.transpose() * Vector3::z();
            let kg = down * down.dot(&k.fixed_rows::<3>(BG));
            k.fixed_rows_mut::<3>(BG).copy_from(&kg);
        }
        let a = Cov::identity() - k * h.transpose();
        *p = a * *p * a.transpose() + k * k.transpose() * self.var_heading;
        symmetrize(p);
    }

    /// Propagates `p` from step `from` to step `to` (indices), fusing the
    /// magnetometer samples of every step reached.
    fn advance(&self, p: &mut Cov, steps: &[Step], from: usize, to: usize) {
        for k in from + 1..=to {
            self.propagate(p, &steps[k - 1], steps[k].t_us);
            for _ in 0..steps[k].mags {
                self.fuse_mag(p, &steps[k]);
            }
        }
    }
}

fn symmetrize(p: &mut Cov) {
    *p = (*p + p.transpose()) * 0.5;
}

/// The bound at one step from the present covariance.
fn sample(p: &Cov, step: &Step) -> BoundSample {
    let att = p.fixed_view::<3, 3>(PHI, PHI).into_owned();
    let (pitch, yaw) = (step.euler.y, step.euler.z);
    // Columns: NED rotation vector of a unit roll, pitch and yaw change (ZYX).
    let a = Matrix3::new(
        yaw.cos() * pitch.cos(),
        -yaw.sin(),
        0.0,
        yaw.sin() * pitch.cos(),
        yaw.cos(),
        0.0,
        -pitch.sin(),
        0.0,
        1.0,
    );
    let euler = a.try_inverse().map_or(Vector3::repeat(f64::NAN), |ai| {
        (ai * att * ai.transpose())
            .diagonal()
            .map(|v| v.max(0.0).sqrt())
    });
    let diag = |i: usize| Vector3::new(p[(i, i)], p[(i + 1, i + 1)], p[(i + 2, i + 2)]);
    let sum = |i: usize| diag(i).sum().max(0.0).sqrt();
    BoundSample {
        t_us: step.t_us,
        std: BoundRms {
            tilt_rad: (att[(0, 0)] + att[(1, 1)]).max(0.0).sqrt(),
            heading_rad: att[(2, 2)].max(0.0).sqrt(),
            euler_rad: euler,
            velocity_m_s: sum(VEL),
            position_m: sum(POS),
            accel_bias_m_s2: diag(BA).map(|v| v.max(0.0).sqrt()),
            gyro_bias_rad_s: diag(BG).map(|v| v.max(0.0).sqrt()),
        },
    }
}

/// The linearized bound of a simulated run (module docs): one
/// [`BoundSample`] per IMU sample of `events` (a run of `config`, in time
/// order, as [`Simulation`](super::Simulation) yields it).
///
/// Fails on an invalid `bound` prior or simulation configuration; a run
/// without IMU samples gives an empty bound.
pub fn trajectory_bound(
    events: &[SimEvent],
    config: &SimConfig,
    bound: &BoundConfig,
) -> Result<TrajectoryBound, crate::Error> {
    config.validate()?;
    bound.validate()?;
    let sensors = &config.sensors;
    let mut steps: Vec<Step> = Vec::new();
    // Fixes as (receive time, index of the IMU step at or before validity).
    let mut fixes: Vec<(u64, usize)> = Vec::new();
    let mut pending_fixes: Vec<(u64, u64)> = Vec::new();
    for event in events {
        match event {
            SimEvent::Imu { truth, .. } => steps.push(Step {
                t_us: truth.t_us,
                rotation: *truth.attitude.to_rotation_matrix().matrix(),
                specific_force_ned: truth.accel_m_s2 - Vector3::new(0.0, 0.0, STANDARD_GRAVITY),
                euler: truth.euler_rad,
                mags: 0,
            }),
            SimEvent::Mag(_) => {
                if let Some(last) = steps.last_mut() {
                    last.mags += 1;
                }
            }
            SimEvent::Gps { fix, delay_s, .. } => {
                let delay_us = (delay_s * 1e6).round().max(0.0) as u64;
                pending_fixes.push((fix.t_us, fix.t_us.saturating_sub(delay_us)));
            }
        }
    }
    if steps.is_empty() {
        return Ok(TrajectoryBound {
            samples: Vec::new(),
        });
    }
    for (received, valid) in pending_fixes {
        if valid < steps[0].t_us {
            continue;
        }
        let index = steps.partition_point(|s| s.t_us <= valid) - 1;
        fixes.push((received, index));
    }
    let model = Model {
        var_g: sensors.gyro_noise_var_rad2_s2,
        var_a: sensors.accel_noise_std_m_s2().powi(2),
        walk_a: sensors.accel_bias_walk_m_s2_sqrt_s.powi(2),
        walk_g: sensors.gyro_bias_walk_rad_s_sqrt_s.powi(2),
        var_p: sensors.gps_position_var_m2,
        var_v: sensors.gps_velocity_var_m2_s2,
        var_heading: sensors.mag_noise_var / sensors.inclination_rad.cos().powi(2),
        var_field: sensors.mag_noise_var,
        field_ned: super::field_ned(sensors.inclination_rad, sensors.declination_rad),
        magnetometer: bound.magnetometer,
        mag_tilt_alignment_var: bound.mag_tilt_alignment_std_rad.powi(2),
        filter_heading_jacobian: {
            let (i, d) = (sensors.inclination_rad, sensors.declination_rad);
            Vector3::new(-i.tan() * d.cos(), -i.tan() * d.sin(), 1.0)
        },
    };
    let mut p0 = Cov::zeros();
    let b = bound;
    let prior = [
        (PHI, b.tilt_std_rad),
        (PHI + 1, b.tilt_std_rad),
        (PHI + 2, b.heading_std_rad),
    ]
    .into_iter()
    .chain((0..3).map(|i| (POS + i, b.position_std_m)))
    .chain((0..3).map(|i| (VEL + i, b.velocity_std_m_s)))
    .chain((0..3).map(|i| (BA + i, b.accel_bias_std_m_s2)))
    .chain((0..3).map(|i| (BG + i, b.gyro_bias_std_rad_s)))
    .chain((0..3).map(|i| (OFF + i, b.mag_offset_std)));
    for (i, std) in prior {
        p0[(i, i)] = std * std;
    }
    for _ in 0..steps[0].mags {
        model.fuse_mag(&mut p0, &steps[0]);
    }
    // Validity chain (at `valid_index`) and present chain (at `k`).
    let mut valid = p0;
    let mut valid_index = 0usize;
    let mut present = p0;
    let mut next_fix = 0usize;
    let mut samples = Vec::with_capacity(steps.len());
    samples.push(sample(&present, &steps[0]));
    for k in 1..steps.len() {
        model.advance(&mut present, &steps, k - 1, k);
        let mut arrived = false;
        while let Some(&(received, index)) = fixes.get(next_fix) {
            if received >= steps[k].t_us {
                break;
            }
            let index = index.max(valid_index);
            model.advance(&mut valid, &steps, valid_index, index);
            valid_index = index;
            model.fuse_gps(&mut valid);
            next_fix += 1;
            arrived = true;
        }
        if arrived {
            present = valid;
            model.advance(&mut present, &steps, valid_index, k);
        }
        samples.push(sample(&present, &steps[k]));
    }
    Ok(TrajectoryBound { samples })
}

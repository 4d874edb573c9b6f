//! Yaw without a magnetometer: a Gaussian sum of [`YAW_GSF_MODELS`] small
//! yaw filters driven by the GPS velocity and the IMU (the idea of PX4's
//! EKF-GSF and ArduPilot's EKF3 GSF yaw estimator; written here from the
//! equations below).
//!
//! # States and frames
//! Model `i` holds `x_i = [v_n, v_e, psi]`: the horizontal velocity, NED,
//! m/s, and the yaw of the body frame (FRD) about down, rad, east of north;
//! its covariance `P_i` (3x3, stored as its upper triangle) and its weight
//! `w_i` (the weights sum to 1). The models differ only in their yaw: they
//! start spread evenly over the circle, `psi_i = -pi + (i + 1/2) 2 pi / M`,
//! with the variance `(pi / M)^2`, the velocity at the first GPS velocity,
//! the weights at `1 / M`.
//!
//! Tilt is not estimated here: the caller gives the delta velocity in the
//! *heading frame*, the body frame levelled by roll and pitch (x forward
//! in the horizontal plane, y right), and the yaw increment. The navigator
//! takes both from its horizon filter's prediction: the horizontal velocity
//! change over the step rotated by minus its yaw, and the change of its
//! yaw (`src/nav/alignment.rs`). That filter's tilt is what levels the
//! delta velocity; a model's yaw is what turns it north.
//!
//! # Prediction (every filter step, `dt` s)
//! With `dv = [dv_x, dv_y]` in the heading frame (m/s) and `dpsi` (rad):
//!
//! ```text
//! [dv_n, dv_e] = [c dv_x - s dv_y, s dv_x + c dv_y]      c = cos psi_i, s = sin psi_i
//! v_n += dv_n,   v_e += dv_e,   psi_i += dpsi
//! F = [1 0 -dv_e; 0 1 dv_n; 0 0 1]
//! P_i = F P_i F^T + diag(q_v, q_v, q_psi),   q_v = (ACCEL_NOISE dt)^2,  q_psi = (GYRO_NOISE dt)^2
//! ```
//!
//! [`ACCEL_NOISE_M_S2`] stands for everything the delta velocity gets wrong
//! (noise, vibration, a tilt error times `g`); [`GYRO_NOISE_RAD_S`] for the
//! yaw rate's errors.
//!
//! # Update (every GPS velocity, `z = [v_n, v_e]`, std `sigma` m/s)
//! ```text
//! y = z - [v_n, v_e]                  S = P_i[0..2, 0..2] + r I,  r = max(sigma, VELOCITY_STD_MIN)^2
//! K = P_i[:, 0..2] S^-1               x_i += K y,   P_i -= K P_i[0..2, :]
//! w_i <- w_i N(y; 0, S) / sum_j w_j N(y_j; 0, S_j)
//! ```
//!
//! The likelihoods are taken in the log domain, `-y^T S^-1 y / 2 - ln det S / 2`,
//! less their largest before `exp`, so that no weight underflows to zero
//! together with all the others, in `f32` too. A model whose yaw is wrong
//! turns the vehicle's accelerations the wrong way: its velocity drifts from
//! the GPS one and its weight falls. A hover or a straight line at constant
//! speed has no horizontal acceleration and moves no weight.
//!
//! # The composite yaw
//! The weighted circular mean and the spread about it:
//!
//! ```text
//! psi = atan2(sum w_i sin psi_i, sum w_i cos psi_i)
//! var = sum w_i (P_i[2,2] + wrap(psi_i - psi)^2)      rad^2
//! ```
//!
//! The variance counts both each model's own uncertainty and their
//! disagreement: it is small only when the weight has gathered on models
//! that agree. [`YawGsf::converged_yaw`] gives the yaw once the variance is
//! below [`CONVERGED_YAW_STD_RAD`] squared.
//!
//! # Refusals and restarts
//! A non-finite input is ignored (the bank is left as it was) and counted
//! with the caller's refusals. When the weights cannot be normalized (every
//! likelihood non-finite) or a state becomes non-finite, the bank restarts
//! from the last GPS velocity ([`YawGsf::restarts`]).
//!
//! # Cost
//! `M = 5` models of 3 states: 10 numbers each (state, 6 covariance
//! entries, weight), 204 B in `f32`. No allocation, no panic.

use crate::ekf16::STANDARD_GRAVITY;
use crate::geo::wrap_pi;
use crate::scalar::Scalar;

/// Number of yaw models of the bank.
pub const YAW_GSF_MODELS: usize = 5;
/// Standard deviation of the delta velocity's error per second, m/s^2.
pub const ACCEL_NOISE_M_S2: f64 = 2.0;
/// Standard deviation of the yaw rate's error, rad/s.
pub const GYRO_NOISE_RAD_S: f64 = 0.1;
/// Smallest standard deviation of a GPS velocity the bank fuses, m/s.
pub const VELOCITY_STD_MIN_M_S: f64 = 0.5;
/// The composite yaw is trusted below this standard deviation, rad (15 deg).
pub const CONVERGED_YAW_STD_RAD: f64 = 0.2618;

const M: usize = YAW_GSF_MODELS;
// Upper triangle of the 3x3 covariance: P00, P01, P02, P11, P12, P22.
const P00: usize = 0;
const P01: usize = 1;
const P02: usize = 2;
const P11: usize = 3;
const P12: usize = 4;
const P22: usize = 5;

/// The bank of yaw filters (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YawGsf<T: Scalar> {
    /// Per model: north, east velocity (m/s), yaw (rad).
    x: [[T; 3]; M],
    /// Per model: the covariance's upper triangle.
    p: [[T; 6]; M],
    /// Per model: the weight.
    w: [T; M],
    /// GPS velocities fused since the start (saturates).
    updates: u16,
    /// Restarts after a non-finite state or weights (saturates).
    restarts: u16,
    /// Started from a GPS velocity.
    started: bool,
}

impl<T: Scalar> Default for YawGsf<T> {
    fn default() -> Self {
        Self::BLANK
    }
}

impl<T: Scalar> YawGsf<T> {
    /// A bank not started: every number zero.
    pub const BLANK: Self = Self {
        x: [[T::ZERO; 3]; M],
        p: [[T::ZERO; 6]; M],
        w: [T::ZERO; M],
        updates: 0,
        restarts: 0,
        started: false,
    };

    /// Starts (or restarts) the bank at the GPS velocity `[v_n, v_e]` (m/s,
    /// std `velocity_std_m_s`): yaws spread over the circle, equal weights.
    /// Keeps the restart counter. Non-finite input: nothing happens.
    pub fn start(&mut self, velocity_ne_m_s: [T; 2], velocity_std_m_s: T) {
        if !(velocity_ne_m_s[0].is_finite()
            && velocity_ne_m_s[1].is_finite()
            && velocity_std_m_s.is_finite())
        {
            return;
        }
        let pi = T::pi();
        let spread = T::two_pi() / T::lit(M as f64);
        let r = velocity_std_m_s.max(T::lit(VELOCITY_STD_MIN_M_S));
        let yaw_var = (pi / T::lit(M as f64)) * (pi / T::lit(M as f64));
        for i in 0..M {
            let yaw = -pi + (T::lit(i as f64) + T::lit(0.5)) * spread;
            self.x[i] = [velocity_ne_m_s[0], velocity_ne_m_s[1], yaw];
            self.p[i] = [r * r, T::zero(), T::zero(), r * r, T::zero(), yaw_var];
            self.w[i] = T::one() / T::lit(M as f64);
        }
        self.updates = 0;
        self.started = true;
    }

    /// Back to [`BLANK`](Self::BLANK), the restart counter kept.
    pub fn clear(&mut self) {
        let restarts = self.restarts;
        *self = Self::BLANK;
        self.restarts = restarts;
    }

    /// True once [`start`](Self::start)ed.
    pub fn is_started(&self) -> bool {
        self.started
    }

    /// GPS velocities fused since the start (saturates at `u16::MAX`).
    pub fn updates(&self) -> u16 {
        self.updates
    }

    /// Restarts after a non-finite state or weights (saturates).
    pub fn restarts(&self) -> u16 {
        self.restarts
    }

    /// The models' weights (zero before the start).
    pub fn weights(&self) -> [T; M] {
        self.w
    }

    /// The models' yaws, rad.
    pub fn yaws(&self) -> [T; M] {
        core::array::from_fn(|i| self.x[i][2])
    }

    /// Predicts every model over `dt_s` with the heading-frame delta
    /// velocity `dv_heading_m_s` (m/s) and the yaw increment `dyaw_rad`
    /// (module docs). Not started or non-finite input: nothing happens.
    pub fn predict(&mut self, dv_heading_m_s: [T; 2], dyaw_rad: T, dt_s: T, level_std_rad: T) {
        let [dvx, dvy] = dv_heading_m_s;
        if !(self.started
            && dvx.is_finite()
            && dvy.is_finite()
            && dyaw_rad.is_finite()
            && dt_s.is_finite()
            && dt_s >= T::zero()
            && level_std_rad.is_finite())
        {
            return;
        }
        let q_v = {
            let level = T::lit(STANDARD_GRAVITY) * level_std_rad.min(T::one());
            let a = T::lit(ACCEL_NOISE_M_S2);
            (a * a + level * level) * dt_s * dt_s
        };
        let q_psi = {
            let s = T::lit(GYRO_NOISE_RAD_S) * dt_s;
            s * s
        };
        for (x, p) in self.x.iter_mut().zip(self.p.iter_mut()) {
            let (s, c) = x[2].sin_cos();
            let dvn = c * dvx - s * dvy;
            let dve = s * dvx + c * dvy;
            x[0] += dvn;
            x[1] += dve;
            x[2] = wrap_pi(x[2] + dyaw_rad);
            // F P F^T with F = [1 0 a; 0 1 b; 0 0 1], a = -dv_e, b = dv_n.
            let (a, b) = (-dve, dvn);
            let [p00, p01, p02, p11, p12, p22] = *p;
            *p = [
                p00 + (p02 + p02 + a * p22) * a + q_v,
                p01 + a * p12 + b * p02 + a * b * p22,
                p02 + a * p22,
                p11 + (p12 + p12 + b * p22) * b + q_v,
                p12 + b * p22,
                p22 + q_psi,
            ];
        }
    }

    /// Fuses the GPS velocity `[v_n, v_e]` (m/s, std `velocity_std_m_s`)
    /// into every model and moves the weights (module docs). Starts the bank
    /// when it is not started. False when refused (non-finite input).
    pub fn update(&mut self, velocity_ne_m_s: [T; 2], velocity_std_m_s: T) -> bool {
        let [zn, ze] = velocity_ne_m_s;
        if !(zn.is_finite() && ze.is_finite() && velocity_std_m_s.is_finite()) {
            return false;
        }
        if !self.started {
            self.start(velocity_ne_m_s, velocity_std_m_s);
            return true;
        }
        let r = {
            let s = velocity_std_m_s.max(T::lit(VELOCITY_STD_MIN_M_S));
            s * s
        };
        let mut log_l = [T::zero(); M];
        for ((x, p), l) in self.x.iter_mut().zip(self.p.iter_mut()).zip(&mut log_l) {
            let (yn, ye) = (zn - x[0], ze - x[1]);
            let (s00, s01, s11) = (p[P00] + r, p[P01], p[P11] + r);
            let det = s00 * s11 - s01 * s01;
            // Not positive (or NaN): this model gets no weight.
            if det.partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) {
                *l = T::lit(f64::NEG_INFINITY);
                continue;
            }
            let inv = T::one() / det;
            let (i00, i01, i11) = (s11 * inv, -s01 * inv, s00 * inv);
            // K rows: [P_r0, P_r1] S^-1.
            let rows = [[p[P00], p[P01]], [p[P01], p[P11]], [p[P02], p[P12]]];
            let k: [[T; 2]; 3] = core::array::from_fn(|j| {
                let [a, b] = rows[j];
                [a * i00 + b * i01, a * i01 + b * i11]
            });
            for j in 0..3 {
                x[j] += k[j][0] * yn + k[j][1] * ye;
            }
            x[2] = wrap_pi(x[2]);
            // P -= K [P_0.; P_1.] (upper triangle).
            // P_0c, P_1c are rows[c] (symmetry); the slots in P00..P22 order.
            for (slot, (r_, c_)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
                .into_iter()
                .enumerate()
            {
                let [a, b] = rows[c_];
                p[slot] -= k[r_][0] * a + k[r_][1] * b;
            }
            let floor = T::lit(1e-9);
            p[P00] = p[P00].max(floor);
            p[P11] = p[P11].max(floor);
            p[P22] = p[P22].max(floor);
            let m = yn * (i00 * yn + i01 * ye) + ye * (i01 * yn + i11 * ye);
            *l = -(m + det.ln()) * T::lit(0.5);
        }
        let best = log_l
            .iter()
            .copied()
            .fold(T::lit(f64::NEG_INFINITY), T::max);
        let mut total = T::zero();
        for (w, l) in self.w.iter_mut().zip(&log_l) {
            *w *= (*l - best).exp();
            total += *w;
        }
        let finite = self.x.iter().flatten().all(|v| v.is_finite())
            && self.p.iter().flatten().all(|v| v.is_finite());
        if !(best.is_finite() && total.is_finite() && total > T::zero() && finite) {
            self.restarts = self.restarts.saturating_add(1);
            self.start(velocity_ne_m_s, velocity_std_m_s);
            return true;
        }
        for w in &mut self.w {
            *w /= total;
        }
        self.updates = self.updates.saturating_add(1);
        true
    }

    /// The composite yaw and its variance, `(rad, rad^2)`: the weighted
    /// circular mean of the models' yaws and the spread about it (module
    /// docs). `None` before the start.
    pub fn yaw(&self) -> Option<(T, T)> {
        if !self.started {
            return None;
        }
        let (mut s, mut c) = (T::zero(), T::zero());
        for (x, w) in self.x.iter().zip(&self.w) {
            let (si, ci) = x[2].sin_cos();
            s += *w * si;
            c += *w * ci;
        }
        let yaw = s.atan2(c);
        let mut var = T::zero();
        for ((x, p), w) in self.x.iter().zip(&self.p).zip(&self.w) {
            let d = wrap_pi(x[2] - yaw);
            var += *w * (p[P22] + d * d);
        }
        Some((yaw, var))
    }

    /// The composite yaw and its variance once the standard deviation is
    /// below [`CONVERGED_YAW_STD_RAD`] after at least one fused velocity.
    pub fn converged_yaw(&self) -> Option<(T, T)> {
        let limit = T::lit(CONVERGED_YAW_STD_RAD * CONVERGED_YAW_STD_RAD);
        self.yaw()
            .filter(|&(_, var)| self.updates > 0 && var < limit)
    }
}

/// The yaw estimator as the navigator reports it in
/// [`Health::yaw_gsf`](super::Health::yaw_gsf).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct YawGsfHealth<T: Scalar> {
    /// The composite yaw, rad east of north, and its standard deviation,
    /// rad (module docs); `None` before the bank started.
    pub yaw_rad: Option<(T, T)>,
    /// The models' weights (sum 1 once started, all 0 before).
    pub weights: [T; YAW_GSF_MODELS],
    /// The composite's standard deviation is below
    /// [`CONVERGED_YAW_STD_RAD`] after at least one fused velocity.
    pub converged: bool,
    /// GPS velocities fused since the bank's start (saturates).
    pub updates: u16,
    /// Restarts after a non-finite state or weights (saturates).
    pub restarts: u16,
    /// Times the navigator set its heading from the bank: the alignment
    /// without a magnetometer, and each reset after a sustained
    /// disagreement (saturates).
    pub yaw_resets: u16,
    /// GPS fixes the navigator fused into its position and velocity alone:
    /// after an alignment in motion without a recent magnetometer update,
    /// while its heading was unknown
    /// ([`HEADING_UNKNOWN_STD_RAD`](crate::nav::HEADING_UNKNOWN_STD_RAD)) or
    /// the delay not yet known
    /// ([`DELAY_KNOWN_STD_S`](crate::nav::DELAY_KNOWN_STD_S)); saturates.
    pub fixes_position_velocity_only: u16,
}

impl<T: Scalar> YawGsf<T> {
    /// The bank's part of [`YawGsfHealth`] (`yaw_resets` and
    /// `fixes_position_velocity_only` are the caller's).
    pub fn health(&self, yaw_resets: u16, fixes_position_velocity_only: u16) -> YawGsfHealth<T> {
        YawGsfHealth {
            yaw_rad: self.yaw().map(|(y, var)| (y, var.max(T::zero()).sqrt())),
            weights: self.w,
            converged: self.converged_yaw().is_some(),
            updates: self.updates,
            restarts: self.restarts,
            yaw_resets,
            fixes_position_velocity_only,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vehicle on a horizontal Lissajous path (accelerations up to
    /// about 2 m/s^2) whose yaw swings about `yaw0`: velocity, yaw and the
    /// NED acceleration at `t` s.
    fn truth(t: f64, yaw0: f64) -> ([f64; 2], f64, [f64; 2]) {
        let (wa, wb) = (0.2, 0.13);
        let (a, b) = (8.0, 12.0);
        let v = [a * (wa * t).sin(), b * (wb * t).cos()];
        let acc = [a * wa * (wa * t).cos(), -b * wb * (wb * t).sin()];
        (v, yaw0 + 0.4 * (0.3 * t).sin(), acc)
    }

    /// A deterministic noise in `[-1, 1)`.
    fn noise(n: &mut u64) -> f64 {
        *n = n
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*n >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// Runs the bank for `seconds` at 100 Hz prediction, 10 Hz GPS
    /// velocity (noise 0.3 m/s); `motion` 0 holds the vehicle still.
    fn run<T: Scalar>(yaw0: f64, seconds: f64, motion: f64) -> (YawGsf<T>, f64) {
        let mut gsf = YawGsf::<T>::BLANK;
        let dt = 0.01;
        let mut n = 7u64;
        let steps = (seconds / dt) as usize;
        let mut yaw_true = yaw0;
        for k in 0..=steps {
            let t = k as f64 * dt;
            let (v, yaw, _) = truth(t, yaw0);
            yaw_true = yaw;
            if k % 10 == 0 {
                let z = [
                    motion * v[0] + 0.3 * noise(&mut n),
                    motion * v[1] + 0.3 * noise(&mut n),
                ];
                assert!(gsf.update([T::lit(z[0]), T::lit(z[1])], T::lit(0.3)));
            }
            // The step's mean acceleration and yaw, turned into the heading frame.
            let (_, yaw_next, _) = truth(t + dt, yaw0);
            let (_, _, acc) = truth(t + 0.5 * dt, yaw0);
            let mid = 0.5 * (yaw + yaw_next) + 0.05 * noise(&mut n);
            let (s, c) = mid.sin_cos();
            let dv = [
                motion * (c * acc[0] + s * acc[1]) * dt,
                motion * (-s * acc[0] + c * acc[1]) * dt,
            ];
            gsf.predict(
                [T::lit(dv[0]), T::lit(dv[1])],
                T::lit(yaw_next - yaw),
                T::lit(dt),
                T::zero(),
            );
        }
        (gsf, yaw_true)
    }

    /// From every starting yaw, the weights gather on the true yaw while the
    /// vehicle accelerates: after 4 s the models still far from it (more
    /// than 10 deg) have lost their weight, the composite is within 5 deg
    /// and says it has converged, its standard deviation honest (the error
    /// within 3 sigma); after 40 s it still holds.
    fn converges_on_the_true_yaw_from_any_heading<T: Scalar>() {
        for (yaw0, seconds) in [
            (0.0, 4.0),
            (1.0, 4.0),
            (2.5, 4.0),
            (-2.0, 4.0),
            (-0.7, 40.0),
        ] {
            let (gsf, yaw_true) = run::<T>(yaw0, seconds, 1.0);
            let (yaw, var) = gsf.converged_yaw().expect("converged");
            let err = wrap_pi(yaw.as_f64() - yaw_true).abs();
            assert!(err < 5f64.to_radians(), "{yaw0}: error {err}");
            assert!(err < 3.0 * var.as_f64().sqrt(), "{yaw0}: {err} vs {var:?}");
            for (model, w) in gsf.yaws().iter().zip(gsf.weights()) {
                let off = wrap_pi(model.as_f64() - yaw_true).abs();
                assert!(
                    off < 10f64.to_radians() || w.as_f64() < 1e-3,
                    "{yaw0}: {off} {w:?}"
                );
            }
            let updates = (seconds * 10.0) as u16 + 1;
            assert_eq!((gsf.restarts(), gsf.updates()), (0, updates - 1));
            let sum: f64 = gsf.weights().iter().map(|w| w.as_f64()).sum();
            assert!((sum - 1.0).abs() < 1e-4);
        }
    }

    /// Standing still the velocity says nothing of yaw: the weights stay
    /// equal and the composite never claims convergence.
    fn a_vehicle_at_rest_moves_no_weight<T: Scalar>() {
        let (gsf, _) = run::<T>(1.0, 30.0, 0.0);
        for w in gsf.weights() {
            assert!((w.as_f64() - 0.2).abs() < 0.02, "{:?}", gsf.weights());
        }
        assert!(gsf.yaw().is_some() && gsf.converged_yaw().is_none());
    }

    /// Non-finite input leaves the bank as it was; nothing runs before the
    /// start, and the first velocity starts it.
    fn bad_input_changes_nothing<T: Scalar>() {
        let mut gsf = YawGsf::<T>::BLANK;
        gsf.predict([T::one(), T::zero()], T::zero(), T::lit(0.01), T::zero());
        assert_eq!(gsf, YawGsf::BLANK);
        assert!(gsf.yaw().is_none());
        assert!(!gsf.update([T::lit(f64::NAN), T::zero()], T::one()));
        assert!(gsf.update([T::one(), T::zero()], T::lit(0.3)));
        assert!(gsf.is_started());
        let before = gsf;
        gsf.predict(
            [T::lit(f64::NAN), T::zero()],
            T::zero(),
            T::lit(0.01),
            T::zero(),
        );
        gsf.predict(
            [T::zero(), T::zero()],
            T::lit(f64::INFINITY),
            T::lit(0.01),
            T::zero(),
        );
        assert!(!gsf.update([T::one(), T::zero()], T::lit(f64::NAN)));
        assert_eq!(gsf, before);
        // An absurd velocity leaves every likelihood finite in the log domain.
        assert!(gsf.update([T::lit(1e6), T::zero()], T::lit(0.3)));
        assert!(
            gsf.yaw()
                .is_some_and(|(y, v)| y.is_finite() && v.is_finite())
        );
    }

    tests_in_both_precisions!(
        converges_on_the_true_yaw_from_any_heading,
        a_vehicle_at_rest_moves_no_weight,
        bad_input_changes_nothing,
    );
}

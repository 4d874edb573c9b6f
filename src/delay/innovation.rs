//! A second observation of the delay: the horizon filter's GPS innovations.
//!
//! The horizon EKF runs at `t_h = t_fix - tau_hat`; the fix received at
//! `t_fix` describes the vehicle at `t_fix - tau`. With `dd = tau - tau_hat`
//! the fix sees position `p(t_h - dd) ~ p(t_h) - v dd` and velocity
//! `v(t_h - dd) ~ v(t_h) - a dd`: per NED axis the innovation
//! `nu = z - h(x)` of the pair (position, velocity) is `J dd` plus the
//! filter's own error, with `J = -[v; a]`.
//!
//! The filter absorbs part of a delay error into its state: a steady
//! velocity turns `-v dd` into a position offset the filter takes in, and
//! only *changes* of the motion stay visible. Regressing `nu` on `J` alone
//! would be biased toward zero. The absorbed error is tracked as a
//! sensitivity (a Schmidt "consider" parameter, kept outside the EKF): per
//! axis the filter's error from the delay is `e = s tau - u`, where
//! `s = d x / d tau` and `u` carries the delays the horizon used, both
//! propagated like the state's error (`p += v dt`) and updated with the
//! filter's gain at each fix (`s += K (J - s)`, `u += K (J tau_hat - u)`).
//! Then
//!
//! ```text
//! nu + J tau_hat - u = (J - s) tau + noise,     g = J - s
//! info = sum g' S^-1 g,     tau_hat_w = sum g' S^-1 (nu + J tau_hat - u) / info
//! ```
//!
//! a scalar weighted least squares over a window, with `S` the innovation
//! covariance. What is left out: the per-axis 2x2 block (position, velocity)
//! stands for the 16-state filter, so the delay error the filter puts into
//! its attitude and biases is not tracked (measured in
//! `docs/journal/2026-11-25-delay-innovation-observation.md`).
//!
//! Cost: per fix about 100 flops per axis; nothing per IMU sample.

use nalgebra::Vector3;

use crate::delay::gain_fusion::AXES;
use crate::scalar::Scalar;

/// What the navigator knows about one fused fix, per NED axis, at the
/// horizon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HorizonFix<T: Scalar> {
    /// Time of the horizon state the fix was fused at, us.
    pub horizon_us: u64,
    /// The delay the horizon used for this fix, in the loop's units, s.
    pub delay_s: T,
    /// Velocity of the horizon state before the fusion, m/s.
    pub velocity_prior: Vector3<T>,
    /// Velocity of the horizon state after the fusion, m/s.
    pub velocity_post: Vector3<T>,
    /// Per axis, the prior covariance of (position, velocity):
    /// `[P_pp, P_pv, P_vv]`.
    pub covariance: [[T; 3]; AXES],
    /// Per axis, the measurement noise variances `[R_p, R_v]`.
    pub noise: [[T; 2]; AXES],
    /// Per axis, the innovations `[nu_p, nu_v]` against the prior state.
    pub innovation: [[T; 2]; AXES],
    /// Which blocks (position, velocity) corrected the state: a block gated
    /// out is still observed (leaving out the fixes the gate rejects would
    /// keep the large, informative innovations out), but moves no
    /// sensitivity.
    pub fused: [bool; 2],
    /// A block was reset to the fix: the sensitivity restarts.
    pub reset: bool,
}

/// The windowed least squares of the delay from the horizon's innovations
/// (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InnovationDelay<T: Scalar> {
    /// Per axis `[s_p, s_v]`.
    sensitivity: [[T; 2]; AXES],
    /// Per axis `[u_p, u_v]`.
    used: [[T; 2]; AXES],
    last_horizon_us: Option<u64>,
    last_velocity: Vector3<T>,
    last_accel: Option<Vector3<T>>,
    info: T,
    weighted: T,
    window_start_us: Option<u64>,
}

/// Longest interval between two fixes, s: the acceleration is the
/// filter's mean over the interval, and over a longer one (1 Hz GPS) it
/// averages away the motion that carries the delay; the sensitivity
/// restarts after it.
pub const MAX_FIX_INTERVAL_S: f64 = 0.6;

impl<T: Scalar> InnovationDelay<T> {
    /// Nothing seen.
    pub const BLANK: Self = Self {
        sensitivity: [[T::ZERO; 2]; AXES],
        used: [[T::ZERO; 2]; AXES],
        last_horizon_us: None,
        last_velocity: Vector3::new(T::ZERO, T::ZERO, T::ZERO),
        last_accel: None,
        info: T::ZERO,
        weighted: T::ZERO,
        window_start_us: None,
    };

    /// Forgets everything (a gap, a reset of the filter).
    pub fn reset(&mut self) {
        *self = Self::BLANK;
    }

    /// Information accumulated in the current window, 1/s^2.
    pub fn information(&self) -> T {
        self.info
    }

    /// One fused fix. The acceleration at the horizon is the filter's own
    /// velocity change over the fix interval (IMU only, no GPS noise),
    /// carried half an interval forward.
    pub fn observe(&mut self, fix: &HorizonFix<T>) {
        let dt_s = match self.last_horizon_us {
            Some(last) if fix.horizon_us > last => T::lit((fix.horizon_us - last) as f64 * 1e-6),
            _ => T::zero(),
        };
        if dt_s <= T::zero() || dt_s > T::lit(MAX_FIX_INTERVAL_S) {
            let blank = Self::BLANK;
            self.sensitivity = blank.sensitivity;
            self.used = blank.used;
            self.last_accel = None;
            self.last_horizon_us = Some(fix.horizon_us);
            self.last_velocity = fix.velocity_post;
            return;
        }
        let mean_accel = (fix.velocity_prior - self.last_velocity) / dt_s;
        let accel = match self.last_accel {
            Some(previous) => mean_accel + (mean_accel - previous) * T::lit(0.5),
            None => mean_accel,
        };
        self.last_accel = Some(mean_accel);
        self.last_horizon_us = Some(fix.horizon_us);
        self.last_velocity = fix.velocity_post;
        let tau_hat = fix.delay_s;
        let (mut info, mut weighted) = (T::zero(), T::zero());
        let mut ok = !fix.reset;
        let mut gains = [[[T::zero(); 2]; 2]; AXES];
        for axis in 0..AXES {
            let s = &mut self.sensitivity[axis];
            let u = &mut self.used[axis];
            s[0] += s[1] * dt_s;
            u[0] += u[1] * dt_s;
            let j = [-fix.velocity_prior[axis], -accel[axis]];
            let g = [j[0] - s[0], j[1] - s[1]];
            let [p_pp, p_pv, p_vv] = fix.covariance[axis];
            let [r_p, r_v] = fix.noise[axis];
            let (s_pp, s_pv, s_vv) = (p_pp + r_p, p_pv, p_vv + r_v);
            let det = s_pp * s_vv - s_pv * s_pv;
            if !(det > T::zero() && det.is_finite()) {
                ok = false;
                continue;
            }
            // S^-1 = [[s_vv, -s_pv], [-s_pv, s_pp]] / det.
            let inv = [s_vv / det, -s_pv / det, s_pp / det];
            let w = [inv[0] * g[0] + inv[1] * g[1], inv[1] * g[0] + inv[2] * g[1]];
            let nu = fix.innovation[axis];
            let y = [nu[0] + j[0] * tau_hat - u[0], nu[1] + j[1] * tau_hat - u[1]];
            info += w[0] * g[0] + w[1] * g[1];
            weighted += w[0] * y[0] + w[1] * y[1];
            // K = P H' (H P H' + R)^-1 over the blocks that were fused.
            gains[axis] = match fix.fused {
                [true, true] => [
                    [p_pp * inv[0] + p_pv * inv[1], p_pp * inv[1] + p_pv * inv[2]],
                    [p_pv * inv[0] + p_vv * inv[1], p_pv * inv[1] + p_vv * inv[2]],
                ],
                [true, false] => [[p_pp / s_pp, T::zero()], [p_pv / s_pp, T::zero()]],
                [false, true] => [[T::zero(), p_pv / s_vv], [T::zero(), p_vv / s_vv]],
                [false, false] => [[T::zero(); 2]; 2],
            };
        }
        if !(ok && info.is_finite() && weighted.is_finite()) {
            self.sensitivity = Self::BLANK.sensitivity;
            self.used = Self::BLANK.used;
            return;
        }
        for axis in 0..AXES {
            let k = gains[axis];
            let j = [-fix.velocity_prior[axis], -accel[axis]];
            let s = &mut self.sensitivity[axis];
            let ds = [j[0] - s[0], j[1] - s[1]];
            s[0] += k[0][0] * ds[0] + k[0][1] * ds[1];
            s[1] += k[1][0] * ds[0] + k[1][1] * ds[1];
            let u = &mut self.used[axis];
            let du = [j[0] * tau_hat - u[0], j[1] * tau_hat - u[1]];
            u[0] += k[0][0] * du[0] + k[0][1] * du[1];
            u[1] += k[1][0] * du[0] + k[1][1] * du[1];
        }
        self.info += info;
        self.weighted += weighted;
        self.window_start_us.get_or_insert(fix.horizon_us);
    }

    /// Drops what the current window accumulated (the sensitivity stays).
    pub fn discard_window(&mut self) {
        self.info = T::zero();
        self.weighted = T::zero();
        self.window_start_us = None;
    }

    /// The window's estimate of the delay and its variance `(tau, 1 / info)`
    /// (s, s^2) once the window spans `window_s`; the window restarts.
    /// `None` before, or when it carried no information.
    pub fn take(&mut self, t_us: u64, window_s: T) -> Option<(T, T)> {
        let start = self.window_start_us?;
        if T::lit(t_us.saturating_sub(start) as f64 * 1e-6) < window_s {
            return None;
        }
        let (info, weighted) = (self.info, self.weighted);
        self.info = T::zero();
        self.weighted = T::zero();
        self.window_start_us = None;
        (info > T::zero()).then(|| (weighted / info, T::one() / info))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A filter that takes the fix only weakly (large noise): the
    /// innovations are the delay's own, and the window finds it.
    fn synthetic_delay_is_found<T: Scalar>() {
        let tau = 0.2;
        let tau_hat = 0.1;
        let mut est = InnovationDelay::<T>::BLANK;
        let mut out = None;
        for k in 0..=100u64 {
            let t = k as f64 * 0.1;
            let v = |t: f64| [3.0 * (0.7 * t).sin(), 2.0 * (0.5 * t).cos(), 0.5];
            let a = |t: f64| [2.1 * (0.7 * t).cos(), -(0.5 * t).sin(), 0.0];
            let vel = v(t);
            let acc = a(t);
            let dd = tau - tau_hat;
            let fix = HorizonFix {
                horizon_us: k * 100_000,
                delay_s: T::lit(tau_hat),
                velocity_prior: Vector3::from_fn(|i, _| T::lit(vel[i])),
                velocity_post: Vector3::from_fn(|i, _| T::lit(vel[i])),
                covariance: [[T::lit(1e-6), T::zero(), T::lit(1e-6)]; AXES],
                noise: [[T::lit(0.25), T::lit(0.01)]; AXES],
                innovation: core::array::from_fn(|i| [T::lit(-vel[i] * dd), T::lit(-acc[i] * dd)]),
                fused: [true, true],
                reset: false,
            };
            est.observe(&fix);
            out = est.take(fix.horizon_us, T::lit(5.0)).or(out);
        }
        let (z, variance) = out.expect("a window");
        assert!((z.as_f64() - tau).abs() < 2e-3, "{}", z.as_f64());
        assert!(variance > T::zero() && variance.as_f64() < 1e-3);
    }

    /// A per-axis Kalman filter of (position, velocity) with a perfect IMU
    /// runs 0.1 s behind a fix delayed by 0.2 s and takes the fixes in,
    /// absorbing part of the delay error. The sensitivity recovers the
    /// delay within 3 ms; the plain regression on `-[v; a]` (no
    /// sensitivity) is biased toward the horizon's delay by more than a
    /// third of the error.
    fn absorbing_filter<T: Scalar>() {
        let (tau, tau_hat) = (0.2, 0.1);
        let position = |t: f64| {
            [
                5.0 * t + 3.0 / 0.49 * (0.7 * t).sin(),
                -2.0 / 0.25 * (0.5 * t).cos(),
                0.0,
            ]
        };
        let velocity = |t: f64| {
            [
                5.0 + 3.0 / 0.7 * (0.7 * t).cos(),
                2.0 / 0.5 * (0.5 * t).sin(),
                0.0,
            ]
        };
        let (r_p, r_v) = (0.25, 0.01);
        let mut x = [[0.0f64; 2]; AXES];
        let mut p = [[1.0, 0.0, 1.0f64]; AXES];
        let mut est = InnovationDelay::<T>::BLANK;
        let (mut naive_info, mut naive_weighted) = (0.0, 0.0);
        let mut last_v = [0.0; AXES];
        let mut window = None;
        let dt = 0.1;
        for k in 0..=600u64 {
            let t_h = 1.0 + k as f64 * dt;
            let (pos, vel) = (position(t_h), velocity(t_h));
            if k == 0 {
                for i in 0..AXES {
                    x[i] = [pos[i], vel[i]];
                }
            } else {
                let (pos0, vel0) = (position(t_h - dt), velocity(t_h - dt));
                for i in 0..AXES {
                    // Perfect IMU: the true increments.
                    x[i][0] += x[i][1] * dt + (pos[i] - pos0[i] - vel0[i] * dt);
                    x[i][1] += vel[i] - vel0[i];
                    let [pp, pv, vv] = p[i];
                    p[i] = [
                        pp + 2.0 * dt * pv + dt * dt * vv + 1e-4,
                        pv + dt * vv,
                        vv + 1e-3,
                    ];
                }
            }
            let (z_p, z_v) = (
                position(t_h - (tau - tau_hat)),
                velocity(t_h - (tau - tau_hat)),
            );
            let prior_v = Vector3::from_fn(|i, _| T::lit(x[i][1]));
            let innovation: [[f64; 2]; AXES] =
                core::array::from_fn(|i| [z_p[i] - x[i][0], z_v[i] - x[i][1]]);
            let covariance = p;
            for i in 0..AXES {
                let [pp, pv, vv] = p[i];
                let (spp, svv) = (pp + r_p, vv + r_v);
                let det = spp * svv - pv * pv;
                let inv = [svv / det, -pv / det, spp / det];
                let kk = [
                    [pp * inv[0] + pv * inv[1], pp * inv[1] + pv * inv[2]],
                    [pv * inv[0] + vv * inv[1], pv * inv[1] + vv * inv[2]],
                ];
                let nu = innovation[i];
                x[i][0] += kk[0][0] * nu[0] + kk[0][1] * nu[1];
                x[i][1] += kk[1][0] * nu[0] + kk[1][1] * nu[1];
                // P - K P (K = P S^-1).
                p[i] = [
                    pp - (kk[0][0] * pp + kk[0][1] * pv),
                    pv - (kk[0][0] * pv + kk[0][1] * vv),
                    vv - (kk[1][0] * pv + kk[1][1] * vv),
                ];
                if k > 300 {
                    // The plain regression: J = -[v; a], no sensitivity.
                    let a = (x[i][1] - last_v[i]) / dt;
                    let j = [-vel[i], -a];
                    let w = [inv[0] * j[0] + inv[1] * j[1], inv[1] * j[0] + inv[2] * j[1]];
                    naive_info += w[0] * j[0] + w[1] * j[1];
                    naive_weighted +=
                        w[0] * (nu[0] + j[0] * tau_hat) + w[1] * (nu[1] + j[1] * tau_hat);
                }
                last_v[i] = x[i][1];
            }
            let fix = HorizonFix {
                horizon_us: (t_h * 1e6) as u64,
                delay_s: T::lit(tau_hat),
                velocity_prior: prior_v,
                velocity_post: Vector3::from_fn(|i, _| T::lit(x[i][1])),
                covariance: covariance.map(|c| c.map(T::lit)),
                noise: [[T::lit(r_p), T::lit(r_v)]; AXES],
                innovation: innovation.map(|c| c.map(T::lit)),
                fused: [true, true],
                reset: false,
            };
            est.observe(&fix);
            if k == 300 {
                est.discard_window();
            }
            window = est.take(fix.horizon_us, T::lit(29.0)).or(window);
        }
        let (z, _) = window.expect("a window");
        assert!((z.as_f64() - tau).abs() < 3e-3, "{}", z.as_f64());
        let naive = naive_weighted / naive_info;
        assert!((naive - tau).abs() > 0.35 * (tau - tau_hat), "{naive}");
    }

    tests_in_both_precisions!(absorbing_filter, synthetic_delay_is_found);
}

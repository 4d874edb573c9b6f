//! The protection levels of a core's covariance ([`crate::integrity`]), inflated by what the
//! GPS innovations say.
//!
//! **The monitor.** Per GPS block (position, velocity), an exponential mean of the normalized
//! innovation squared `NIS = y^T S^-1 y` of every fix, fused or rejected, each at most the
//! block's gate (a rejected glitch says more about the fix than about the state), weight
//! [`NIS_MEAN_WEIGHT`] per fix (about 1 s at 10 Hz), starting at 3 (its expectation: three
//! degrees of freedom). A consistent filter keeps it near 3; a covariance that lies about the
//! state (an unmodelled delay, a drift the filter follows) raises it.
//!
//! **The inflation.** Each block's levels are multiplied by `sqrt(max(1, mean / 3))`: the
//! horizontal and vertical levels by the position block's, the velocity and tilt levels by the
//! velocity block's (a tilt error shows in the velocity innovations first).
//!
//! **The velocity innovations' mean.** An exponential mean `u` (the same weight per fix) of the
//! fused GPS velocity innovations `z - h(x)` (NED, m/s; zero at the alignment and when the
//! velocity block is reset). A velocity error the covariance does not hold (an unmodelled
//! specific-force error: a tilt levelled on a wrong magnetic field) shows in every fix with
//! the same sign; `|u|` is added to the velocity level. On a consistent filter `u` is the
//! smoothed noise, about `sqrt(w / (2 - w))` = 0.23 of the innovations' standard deviation
//! per axis.
//!
//! **The position-against-velocity check** ([`PvMonitor`]). A GPS position that moves without
//! its velocity (a slow drift, multipath, a step the filter resets to) is followed by the filter
//! with a consistent covariance: its innovations cannot show it. The GPS's own velocity can.
//! Per fix `k` (NED, m): a track integrates the fixes' velocities by the trapezoid,
//! `r_k = r_{k-1} + (v_{k-1} + v_k) dt / 2`, and the raw inconsistency is `d_k = p_k - r_k`.
//! The track is anchored at the mean of its first [`PV_ANCHOR_FIXES`] fused fixes
//! (`r += (d_k - o) / (n + 1)` at the `n`-th after the anchor fix; nothing is tested
//! meanwhile): anchored at one fix, that fix's noise stayed in every later `d_k`, and a fix
//! 2.5 sigma off held the offset beyond its tolerance for the whole run
//! (`an_anchor_fix_off_by_its_noise_is_averaged_out`).
//! From then, the smoothed `o <- o + a (d_k - o)` ([`PV_SMOOTHING`] per fix whose position block
//! was fused; a rejected position block teaches nothing; the fix a position block is reset to
//! sets `o = d_k` at once) is the **offset**. While the offset is within its tolerance the track
//! learns it (`r += b o`, `o -= b o`, `b = max(1 / n, PV_BASELINE_RATE)` at the `n`-th fused
//! fix after the anchor, slowing to [`PV_BASELINE_RATE`]; the integration's own random walk is
//! absorbed, a drift barely); beyond it the track is held
//! and the fix is counted (`FilterRefusals::gps_position_inconsistent`), so a lasting offset
//! stays until the fixes come back to the track (or `reset()`). The tolerance is the 2-D level
//! (`k2` at the integrity risk) of the offset's standard deviation without a fault,
//! `s_o^2 = s_p^2 (a / (2 - a) + 1 / N_a) + s_v^2 dt^2 / b` (the smoothed white position noise
//! `s_p`, the anchor's mean of `N_a` fixes, the velocity noise `s_v` integrated over the `1 / b`
//! fixes the track learns over), `s_p`, `s_v` the fix's noise (horizontal for the horizontal
//! test, vertical with `k1` for the down axis).
//! The horizontal level is raised by the horizontal norm of the offset, the vertical one by its
//! down component: the part of the error the fixes themselves disagree about.
//! A gap of more than [`PV_MAX_GAP_US`] between fixes re-anchors the track at the fix (the
//! offset kept: what was found stays found; a step inside a GPS outage is not seen). A block
//! reset before [`PV_CONFIRM_FIXES`] fused position blocks confirmed the anchor (the first fix
//! was the glitch, not the later ones) re-anchors instead, with no offset.

use super::GpsMeasurement;
use super::NavCore;
use crate::ekf16::state::{POS, QUAT, VEL};
use crate::estimate::FusionRecord;
use crate::integrity::{Integrity, ProtectionLevels};
use crate::scalar::Scalar;
use crate::scalar::{all_finite_fixed, us_to_s, zeros_const};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// Standard deviation of the unknown acceleration over an IMU gap, per NED axis, m/s^2.
pub const GAP_ACCEL_STD_M_S2: f64 = 5.0;
/// Standard deviation of the unknown rotation rate over an IMU gap, per axis, rad/s.
pub const GAP_RATE_STD_RAD_S: f64 = 0.2;
/// Largest attitude standard deviation an IMU gap adds, rad (20 deg: beyond it the filter's
/// linearization no longer holds; the in-flight alignment's `MOVING_TILT_STD_RAD`).
pub const GAP_MAX_ATTITUDE_STD_RAD: f64 = 0.35;

/// Longest stretch of an IMU gap that the carry and the unknown motion are computed over, s
/// (beyond it the state is unknown anyway, and larger variances leave the range a later
/// update can handle in `f32`).
pub const GAP_MOTION_MAX_S: f64 = 10.0;

/// The motion nobody measured over an IMU gap of `dt` s (at most [`GAP_MOTION_MAX_S`]), per
/// NED axis: `[velocity, position, their covariance, attitude]` variances, `(s_a dt)^2` (m/s)^2,
/// `(s_a dt^2 / 2)^2` m^2, `s_a^2 dt^3 / 2` m^2/s, `min(s_w dt, s_max)^2` rad^2
/// ([`GAP_ACCEL_STD_M_S2`], [`GAP_RATE_STD_RAD_S`], [`GAP_MAX_ATTITUDE_STD_RAD`]).
fn gap_motion_variances<T: Scalar>(dt: T) -> [T; 4] {
    let dt = dt.min(T::lit(GAP_MOTION_MAX_S));
    let sa2 = T::lit(GAP_ACCEL_STD_M_S2 * GAP_ACCEL_STD_M_S2);
    let s = (T::lit(GAP_RATE_STD_RAD_S) * dt).min(T::lit(GAP_MAX_ATTITUDE_STD_RAD));
    [
        sa2 * dt * dt,
        sa2 * dt * dt * dt * dt / T::lit(4.0),
        sa2 * dt * dt * dt / T::lit(2.0),
        s * s,
    ]
}

/// What crossing an IMU gap of `dt` s will add to the covariance `p` (`NavCore`'s
/// `carry_over_gap`, without touching the state): to the NED position block
/// `dt (P_rv + P_vr) + dt^2 P_vv` (the carry `F P F^T`, `F = I + dt E_rv`) and the unknown
/// position, to the velocity block the unknown velocity, and the attitude variance per axis
/// (rad^2): `(position, velocity, attitude)`. The navigator's present is past a gap its
/// horizon filter has not crossed yet for one delay; its levels take this growth then.
pub(crate) fn gap_growth<T: Scalar, const N: usize>(
    p: &nalgebra::SMatrix<T, N, N>,
    dt: T,
) -> (Matrix3<T>, Matrix3<T>, T) {
    let dt = dt.min(T::lit(GAP_MOTION_MAX_S));
    let [velocity, position, _, attitude] = gap_motion_variances(dt);
    let rv = p.fixed_view::<3, 3>(POS, VEL);
    let vv = p.fixed_view::<3, 3>(VEL, VEL);
    let carried = (rv + rv.transpose()) * dt + vv * (dt * dt);
    (
        carried + Matrix3::identity() * position,
        Matrix3::identity() * velocity,
        attitude,
    )
}

/// Weight of each fused fix in the smoothed position-velocity offset (2 s at 10 Hz).
pub const PV_SMOOTHING: f64 = 0.05;
/// Smallest weight of a consistent fix in the track's learning of the offset (30 s at
/// 10 Hz; `1 / n` for the `n`-th fused fix after the anchor until then: a running mean).
pub const PV_BASELINE_RATE: f64 = 1.0 / 300.0;
/// Longest interval between fixes the track integrates the velocity over, µs.
pub const PV_MAX_GAP_US: u64 = 1_000_000;
/// Fused position blocks after which the track's anchor counts as confirmed.
pub const PV_CONFIRM_FIXES: u16 = 50;
/// Fixes whose mean anchors the track (the anchor fix and the next fused ones; `1 /
/// PV_SMOOTHING`, 2 s at 10 Hz): nothing is tested before.
pub const PV_ANCHOR_FIXES: u16 = 20;

/// The GPS position-against-velocity consistency check (module docs). All zero: not anchored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PvMonitor<T: Scalar> {
    /// The integrated velocity track, shifted by what it learned, NED m.
    track: Vector3<T>,
    /// The last fix's velocity, NED m/s.
    velocity: Vector3<T>,
    /// The smoothed offset of the fixes from the track, NED m.
    offset: Vector3<T>,
    /// Time of the last fix, µs.
    t_us: u64,
    /// Fused position blocks since the anchor (saturating).
    confirmed: u16,
    /// Whether the track is anchored.
    anchored: bool,
}

impl<T: Scalar> PvMonitor<T> {
    /// Not anchored.
    pub(crate) const EMPTY: Self = Self {
        track: zeros_const(),
        velocity: zeros_const(),
        offset: zeros_const(),
        t_us: 0,
        confirmed: 0,
        anchored: false,
    };

    /// The horizontal norm and the down component's magnitude of the offset, m.
    pub(crate) fn bias(&self) -> (T, T) {
        let o = &self.offset;
        ((o[0] * o[0] + o[1] * o[1]).sqrt(), o[2].abs())
    }

    /// Anchors the track at the fix `m` with no offset.
    fn anchor(&mut self, m: &GpsMeasurement<T>) {
        *self = Self {
            track: m.position_ned_m,
            velocity: m.velocity_ned_m_s,
            t_us: m.t_us,
            anchored: true,
            ..Self::EMPTY
        };
    }

    /// One fix `m` after its fusion: whether its position block was fused, whether the
    /// position block was reset to it; `risk` the integrity risk. Returns whether the offset
    /// is beyond its tolerance (module docs).
    pub(crate) fn update(
        &mut self,
        m: &GpsMeasurement<T>,
        position_fused: bool,
        position_reset: bool,
        risk: T,
    ) -> bool {
        let gap = m.t_us.saturating_sub(self.t_us);
        if !self.anchored || gap > PV_MAX_GAP_US || m.t_us <= self.t_us {
            let offset = self.offset;
            self.anchor(m);
            self.offset = offset;
            self.track -= offset;
            return false;
        }
        let dt: T = us_to_s(gap);
        self.track += (self.velocity + m.velocity_ned_m_s) * (dt * T::lit(0.5));
        self.velocity = m.velocity_ned_m_s;
        self.t_us = m.t_us;
        let d = m.position_ned_m - self.track;
        if position_reset {
            if self.confirmed < PV_CONFIRM_FIXES {
                self.anchor(m);
                return false;
            }
            self.offset = d;
        } else if position_fused {
            self.confirmed = self.confirmed.saturating_add(1);
            if self.confirmed < PV_ANCHOR_FIXES {
                // The anchor as the running mean of the fixes against the integrated velocity
                // (the offset found before a re-anchoring kept): one fix's noise alone is
                // beyond the smoothed offset's tolerance.
                let fixes = T::lit(f64::from(self.confirmed) + 1.0);
                self.track += (d - self.offset) / fixes;
                return false;
            }
            self.offset += (d - self.offset) * T::lit(PV_SMOOTHING);
        } else {
            return false;
        }
        let (k1, k2, _) = crate::integrity::protection_factors(risk);
        let a = T::lit(PV_SMOOTHING);
        let b = T::lit(PV_BASELINE_RATE).max(T::one() / T::lit(f64::from(self.confirmed.max(1))));
        let noise = a / (T::lit(2.0) - a) + T::one() / T::lit(f64::from(PV_ANCHOR_FIXES));
        let walk = m.velocity_noise[(0, 0)] * dt * dt / b;
        let horizontal = k2 * (m.position_noise[(0, 0)] * noise + walk).sqrt();
        let vertical = k1 * (m.position_noise[(2, 2)] * noise + walk).sqrt();
        let (h, v) = self.bias();
        let consistent = h <= horizontal && v <= vertical;
        if consistent {
            let learned = self.offset * b;
            self.track += learned;
            self.offset -= learned;
        }
        !consistent
    }
}

/// Weight of each fix in the NIS means of the integrity monitor (module docs).
pub(crate) const NIS_MEAN_WEIGHT: f64 = 0.1;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Updates the NIS means with one fix's records (module docs).
    pub(super) fn monitor_gps_nis(
        &mut self,
        position: &FusionRecord<T, 3>,
        velocity: &FusionRecord<T, 3>,
    ) {
        let gates = [self.config.gps_position_gate, self.config.gps_velocity_gate];
        for (i, record) in [position, velocity].into_iter().enumerate() {
            // test_ratio = NIS / gate; a NaN ratio (no record) leaves the mean as it is.
            let nis = record.test_ratio.min(T::one()) * gates[i];
            if nis.is_finite() {
                let w = T::lit(NIS_MEAN_WEIGHT);
                self.gps_nis_mean[i] += (nis - self.gps_nis_mean[i]) * w;
            }
        }
        if velocity.fused && all_finite_fixed(&velocity.innovation) {
            let w = T::lit(NIS_MEAN_WEIGHT);
            let mean = &mut self.gps_velocity_innovation_mean;
            *mean += (velocity.innovation - *mean) * w;
        }
    }

    /// The velocity error the GPS velocity innovations keep showing, m/s: the norm of their
    /// exponential mean (module docs), what the velocity level is raised by.
    pub(crate) fn velocity_innovation_bias(&self) -> T {
        self.gps_velocity_innovation_mean.norm()
    }

    /// An IMU gap of `dt` s (at most [`GAP_MOTION_MAX_S`]) carried by the last known motion:
    /// the position moves by the velocity, `p += v dt` (`F = I + dt E_pv`, `P <- F P F^T`),
    /// attitude, velocity and biases stay; and `P` grows for the motion nobody measured: per
    /// NED axis, a white acceleration of [`GAP_ACCEL_STD_M_S2`] held over the gap (velocity
    /// `(s_a dt)^2`, position `(s_a dt^2 / 2)^2`, their covariance `s_a^2 dt^3 / 2`), and an
    /// attitude error of `min(GAP_RATE_STD_RAD_S dt, GAP_MAX_ATTITUDE_STD_RAD)` per axis
    /// (`s^2 / 4 (I - q q^T)` on the quaternion block: the covariance of `dq = dtheta q / 2`
    /// with `dtheta` isotropic).
    pub(super) fn carry_over_gap(
        &self,
        x: &mut nalgebra::SVector<T, N>,
        p: &mut nalgebra::SMatrix<T, N, N>,
        dt: T,
    ) {
        let dt = dt.min(T::lit(GAP_MOTION_MAX_S));
        let [velocity, position, covariance, attitude] = gap_motion_variances(dt);
        for i in 0..3 {
            let v = x[VEL + i];
            x[POS + i] += v * dt;
        }
        for i in 0..3 {
            let row = p.row(VEL + i) * dt;
            let mut target = p.row_mut(POS + i);
            target += row;
        }
        for i in 0..3 {
            let column = p.column(VEL + i) * dt;
            let mut target = p.column_mut(POS + i);
            target += column;
        }
        for i in 0..3 {
            p[(VEL + i, VEL + i)] += velocity;
            p[(POS + i, POS + i)] += position;
            p[(POS + i, VEL + i)] += covariance;
            p[(VEL + i, POS + i)] += covariance;
        }
        let q = x.fixed_rows::<4>(QUAT).normalize();
        let tangent =
            (nalgebra::Matrix4::identity() - q * q.transpose()) * (attitude / T::lit(4.0));
        let mut block = p.fixed_view_mut::<4, 4>(QUAT, QUAT);
        block += tangent;
    }

    /// The heading's standard deviation from tilt errors once a magnetometer sample was fused
    /// (0 before), rad: the larger of the share the fused heading-only samples carried into
    /// the heading (`mag.rs`, `remember_heading_tilt_coupling`) and the share a sample would
    /// carry now, `|tan I|` of the configured inclination times the tilt's standard deviation
    /// about the field's direction (`ProtectionLevels::with_heading_tilt_coupling`).
    pub(crate) fn heading_tilt_coupling(&self) -> T {
        if self.mag_fused_us.is_some() {
            let (_, now) = self.heading_std_and_tilt_share();
            now.max(self.heading_tilt_std)
        } else {
            T::zero()
        }
    }

    /// The magnetometer monitor's share of the levels (`mag_monitor.rs`): the heading level's
    /// factor (at least 1) and what the field offset adds to the heading and tilt levels, rad.
    pub(crate) fn mag_integrity(&self) -> (T, T, T) {
        let (heading, tilt) = self
            .mag_monitor
            .offset_shares(self.config.mag_inclination_rad);
        let (k1, _, _) = crate::integrity::protection_factors(self.config.integrity.risk);
        (self.mag_monitor.heading_factor(k1), heading, tilt)
    }

    /// The position-against-velocity check's offset: its horizontal norm and its down
    /// component's magnitude, m (module docs), what the position levels are raised by.
    pub(crate) fn position_velocity_bias(&self) -> (T, T) {
        self.pv.bias()
    }

    /// The position-against-velocity check with one fused fix (module docs).
    pub(super) fn monitor_position_velocity(
        &mut self,
        m: &GpsMeasurement<T>,
        position_fused: bool,
        position_reset: bool,
    ) {
        let risk = self.config.integrity.risk;
        if self.pv.update(m, position_fused, position_reset, risk) {
            self.refusals.gps_position_inconsistent =
                self.refusals.gps_position_inconsistent.saturating_add(1);
        }
    }

    /// The inflation factors `(position, velocity)` of the monitor (module docs), at least 1.
    pub(crate) fn nis_inflation(&self) -> (T, T) {
        let factor = |mean: T| (mean / T::lit(3.0)).max(T::one()).sqrt();
        (factor(self.gps_nis_mean[0]), factor(self.gps_nis_mean[1]))
    }

    /// What the filter vouches for: the protection levels of `P` at the configured risk,
    /// inflated by the monitor, each valid when within its alert limit, the filter is
    /// initialized and no IMU time jump waits for confirmation; `delay_std_s` the delay's
    /// standard deviation where the filter estimates one. `resets` counts the GPS block resets.
    pub(crate) fn integrity(&self, delay_std_s: Option<T>) -> Integrity<T> {
        if !self.is_initialized() {
            return Integrity::none();
        }
        let config = &self.config.integrity;
        let q = UnitQuaternion::new_normalize(super::quaternion_of(&self.x));
        let zero = Matrix3::zeros();
        let (position, velocity) = self.nis_inflation();
        let levels =
            ProtectionLevels::from_covariance(&q, &self.p, config.risk, &zero, &zero, delay_std_s)
                .inflated(position, velocity)
                .with_position_bias(self.pv.bias())
                .with_velocity_bias(self.velocity_innovation_bias())
                .with_heading_tilt_coupling(self.heading_tilt_coupling(), config.risk)
                .with_magnetometer(self.mag_integrity());
        let r = self.refusals;
        Integrity {
            resets: r.gps_position_resets.saturating_add(r.gps_velocity_resets),
            ..Integrity::judged(levels, config, !self.imu_jump_pending())
        }
    }

    /// An IMU sample too far ahead waits for the next one to confirm the jump: the present
    /// may be that far beyond the state's time, so nothing is valid until it is decided.
    pub(crate) fn imu_jump_pending(&self) -> bool {
        self.imu_candidate_us.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fix at `t` s on a circle of radius 20 m at 0.5 rad/s (position and velocity
    /// consistent), moved by `offset` m north, with the Table 3 noise variances as `R` and a
    /// deterministic wobble of the position (0.5 m) standing in for its noise.
    fn fix<T: Scalar>(t: f64, offset: f64) -> GpsMeasurement<T> {
        let (s, c) = (0.5 * t).sin_cos();
        let wobble = 0.5 * (7.3 * t).sin();
        GpsMeasurement {
            t_us: (t * 1e6).round() as u64,
            position_ned_m: Vector3::new(
                T::lit(20.0 * c + offset + wobble),
                T::lit(20.0 * s - wobble),
                T::lit(wobble),
            ),
            velocity_ned_m_s: Vector3::new(T::lit(-10.0 * s), T::lit(10.0 * c), T::zero()),
            position_noise: Matrix3::identity() * T::lit(4.0),
            velocity_noise: Matrix3::identity() * T::lit(0.1),
        }
    }

    /// Runs fixes at 10 Hz over `[from, to)` s; returns the inconsistent fixes.
    fn feed<T: Scalar>(
        m: &mut PvMonitor<T>,
        from: f64,
        to: f64,
        offset: impl Fn(f64) -> f64,
        fused: impl Fn(f64) -> bool,
    ) -> u32 {
        let mut count = 0;
        let mut k = (from * 10.0).round() as u64;
        while (k as f64) < to * 10.0 {
            let t = k as f64 / 10.0;
            count += u32::from(m.update(&fix::<T>(t, offset(t)), fused(t), false, T::lit(1e-3)));
            k += 1;
        }
        count
    }

    fn a_consistent_track_leaves_the_levels_alone<T: Scalar>() {
        let mut m = PvMonitor::<T>::EMPTY;
        let flagged = feed(&mut m, 0.0, 120.0, |_| 0.0, |_| true);
        let (h, v) = m.bias();
        assert_eq!(flagged, 0);
        assert!(h.as_f64() < 0.5 && v.as_f64() < 0.5, "{h:?} {v:?}");
    }

    fn a_drift_and_a_step_show_in_the_offset<T: Scalar>() {
        // 20 m north over 30 s from 30 s: the offset follows the drift (smoothed), the
        // track does not learn it.
        let drift = |t: f64| (t - 30.0).clamp(0.0, 30.0) * 20.0 / 30.0;
        let mut m = PvMonitor::<T>::EMPTY;
        feed(&mut m, 0.0, 30.0, drift, |_| true);
        let flagged = feed(&mut m, 30.0, 60.0, drift, |_| true);
        let (h, _) = m.bias();
        assert!(h.as_f64() > 17.0 && h.as_f64() < 21.0, "{h:?}");
        assert!(flagged > 200, "{flagged}");
        // A 50 m step the filter rejects for 5 s, then resets its position block to: the
        // rejected fixes teach nothing, the reset sets the offset at once.
        let step = |t: f64| if t >= 30.0 { 50.0 } else { 0.0 };
        let mut m = PvMonitor::<T>::EMPTY;
        feed(&mut m, 0.0, 30.0, step, |_| true);
        feed(&mut m, 30.0, 35.0, step, |_| false);
        assert!(m.bias().0.as_f64() < 0.5);
        m.update(&fix::<T>(35.0, 50.0), false, true, T::lit(1e-3));
        let (h, _) = m.bias();
        assert!((h.as_f64() - 50.0).abs() < 1.5, "{h:?}");
        feed(&mut m, 35.1, 60.0, step, |_| true);
        assert!((m.bias().0.as_f64() - 50.0).abs() < 1.5, "{:?}", m.bias());
        // Back on the track, the offset goes.
        feed(&mut m, 60.0, 80.0, |_| 0.0, |_| true);
        assert!(m.bias().0.as_f64() < 1.0, "{:?}", m.bias());
    }

    fn a_reset_from_an_unconfirmed_anchor_anchors_again<T: Scalar>() {
        // The first fix 1 km off (it initialized the filter), every later one rejected until
        // the reset: the first fix was the glitch, no offset.
        let mut m = PvMonitor::<T>::EMPTY;
        m.update(&fix::<T>(0.0, 1000.0), true, false, T::lit(1e-3));
        feed(&mut m, 0.1, 5.0, |_| 0.0, |_| false);
        m.update(&fix::<T>(5.0, 0.0), false, true, T::lit(1e-3));
        feed(&mut m, 5.1, 20.0, |_| 0.0, |_| true);
        assert!(m.bias().0.as_f64() < 0.5, "{:?}", m.bias());
    }

    fn a_gap_anchors_again_and_keeps_the_offset<T: Scalar>() {
        let step = |t: f64| if t >= 10.0 { 30.0 } else { 0.0 };
        let mut m = PvMonitor::<T>::EMPTY;
        feed(&mut m, 0.0, 30.0, step, |_| true);
        let before = m.bias().0;
        assert!(before.as_f64() > 28.0, "{before:?}");
        // 20 s without a fix: the track is anchored again at the next one, the offset kept.
        feed(&mut m, 50.0, 60.0, step, |_| true);
        assert!((m.bias().0 - before).abs().as_f64() < 1.0, "{:?}", m.bias());
    }

    fn an_anchor_fix_off_by_its_noise_is_averaged_out<T: Scalar>() {
        // The first fix 5 m north of the track (2.5 sigma of its 2 m noise), the rest on it:
        // the track is anchored at the first fixes' mean, and nothing is flagged. Anchored at
        // the first fix alone, 582 of the 600 fixes were flagged from 1.8 s on, and the
        // offset stayed at 3.3 m in the level.
        let mut m = PvMonitor::<T>::EMPTY;
        let flagged = feed(
            &mut m,
            0.0,
            60.0,
            |t| if t == 0.0 { 5.0 } else { 0.0 },
            |_| true,
        );
        assert_eq!(flagged, 0);
        assert!(m.bias().0.as_f64() < 0.5, "{:?}", m.bias());
    }

    tests_in_both_precisions!(
        an_anchor_fix_off_by_its_noise_is_averaged_out,
        a_consistent_track_leaves_the_levels_alone,
        a_drift_and_a_step_show_in_the_offset,
        a_reset_from_an_unconfirmed_anchor_anchors_again,
        a_gap_anchors_again_and_keeps_the_offset
    );
}

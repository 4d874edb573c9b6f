//! Forward reckoning from the delayed horizon to the present, `O(1)` per IMU
//! sample whatever the delay.
//!
//! # The output predictor
//!
//! A present-time *output state* `o(t) = (q, r, v)` is propagated every IMU
//! sample with [`process::propagate`] on the raw sample (the mean of the
//! sample and its predecessor, as the EKF does) and the EKF's latest biases.
//! A ring keeps the past output states with their times. After every horizon
//! step or fusion, the EKF state `x(t_h)` is compared with the output state
//! at `t_h` and the difference is applied to the present:
//!
//! ```text
//! dq = q_x(t_h) ⊗ q_o(t_h)^-1    attitude: q_o(t) <- dq ⊗ q_o(t)
//! dv = v_x(t_h) - v_o(t_h)        velocity: v_o(t) <- v_o(t) + dv
//! dr = r_x(t_h) - r_o(t_h)        position: r_o(t) <- r_o(t) + dr + dv (t - t_h)
//! ```
//!
//! With the same biases the propagation is exact under a left-multiplied
//! attitude change (`q ⊗ exp(w dt)` commutes with `dq ⊗ .`), and a velocity
//! offset `dv` at `t_h` is an offset `dv` at `t` and adds `dv (t - t_h)` to
//! the position. The term left out is second order: an attitude correction
//! `dq` also turns the velocity gained over `[t_h, t]`, `(R(dq) - I) Δv`; it
//! is picked up by the next comparisons as the horizon moves on (one delay
//! later), not lost.
//!
//! # Corrections are applied once
//!
//! The ring entry at `t_h` was stored before the corrections applied since.
//! Each correction, seen as a function of time, is a constant rotation `dq`,
//! a constant velocity `dv` and a position `dr + dv (u - t_h)` for every
//! `u >= t_h`; horizons only move forward, so every correction applied since
//! the entry was stored also applies at the entry's time. The cumulative
//! corrections are kept as
//!
//! ```text
//! Q = dq_n ⊗ ... ⊗ dq_1,   B = sum dv_i,   P(t) = sum (dr_i + dv_i (t - t_h,i))   (dP/dt = B)
//! ```
//!
//! and each entry stores its output state in the *corrected frame* of its
//! storage time: `q' = Q^-1 ⊗ q_o`, `v' = v_o - B`, `r' = r_o - P`. The
//! output state at `t_h` with every correction applied so far is then
//! `(Q ⊗ q'(t_h), v'(t_h) + B, r'(t_h) + P(t) - B (t - t_h))`: two quaternion
//! products and a few vector sums, `O(1)`.
//!
//! # Between entries
//!
//! `t_h` falls between two stored entries (the stride below, IMU jitter,
//! fractional delay). The entries are interpolated: the attitude and the
//! velocity by a cubic Lagrange polynomial through the two bracketing
//! entries and their outer neighbours (fewer at the ends of the ring; the
//! quaternion normalized after), the position by a cubic Hermite with the
//! velocities as end slopes (exact for a constant acceleration, as the
//! propagation itself assumes over a step). The entry pair is found by a
//! cursor that only moves forward with the horizon: amortized `O(1)`, at
//! most `max_horizon_step_ratio + 1` moves per sample.
//!
//! # One entry every `stride_us`
//!
//! The ring keeps one entry at the first IMU sample `stride_us` or more
//! after the newest (chosen by the navigator so that `N` entries span its
//! largest delay: 14 samples at 1 kHz for 0.5 s), not one per sample; a
//! stride in time, not in samples, keeps the spacing when the IMU rate
//! drops. One entry per sample is not needed: the horizon moves at the filter rate, and the interpolation
//! above errs by `O(h^4)` in the spacing `h` (a linear one would cost
//! `jerk h^2 / 8` of velocity: 1e-4 m/s for a 10 m/s^3 jerk over 10 ms,
//! above what the tests of perfect inputs allow). The present is the newest point of the
//! interpolation without being stored: a horizon after the newest entry is
//! read between that entry and the present, and an IMU gap stores the
//! present on both sides of the gap (carried over it by its velocity,
//! [`ForwardReckoner::hold`]).
//!
//! # And sooner when the vehicle turns fast
//!
//! The stride is sized for the largest delay (28 ms at 1 kHz for the default 1 s range), and
//! a flip does not fit a cubic over it: through the `high` scenario's flips (a roll rate rising
//! to 31 rad/s and back in 0.15 s) the interpolated attitude at the horizon erred, and each
//! correction carried that error into the present (tilt errors of 2 deg for
//! 20-40 ms against a tilt level of 1 deg). So an entry is also stored before the stride is up
//! once, since the newest entry, the raw rate `w` (the mean of two samples, rad/s, body frame)
//! has turned the body by
//!
//! ```text
//! ∫ |w|_1 dt >= ENTRY_TURN_RAD (0.15 rad)      or   |∫ (w - w_e) dt| >= ENTRY_DEPARTURE_RAD (0.005 rad)
//! ```
//!
//! (`w_e` the raw rate when the newest entry was stored): the second bounds how far the motion
//! between two entries departs from a constant rate, the first the angle a cubic in the
//! quaternion's components spans. Such an entry is stored only when the one it evicts can no
//! longer be read, the ring not yet full or its oldest entry older than the one before the
//! cursor (horizons only move forward): what it costs is the span left for a delay that grows
//! later while such entries are still in the ring (at most `N` strides, 1 s by default). A
//! horizon then older than the oldest entry is not compared with the present; each such
//! correction is counted (`NavRefusals::forward_corrections_missed`), and the early entries in
//! `NavWork::ring_early_entries`. On the flip of the unit test (`a_flip_does_not_disturb_the_present`, a 30 rad/s
//! roll pulse, 27 ms stride, horizon 0.2 s back) the present stays within 0.05 deg of the exact
//! one, against 0.67 deg with the stride alone.

use crate::delay::ring::Ring;
use crate::ekf16::process;
use crate::ekf16::state::{ACCEL_BIAS, GYRO_BIAS, POS, QUAT, StateVector, VEL, quaternion_of};
use crate::scalar::{Scalar, us_to_s, zero_quaternion_const, zeros_const};
use nalgebra::{Quaternion, UnitQuaternion, Vector3, Vector4};

/// One stored output state, in the corrected frame of its storage time.
#[derive(Debug, Clone, Copy)]
struct Entry<T: Scalar> {
    t_us: u64,
    attitude: UnitQuaternion<T>,
    velocity: Vector3<T>,
    position: Vector3<T>,
}

/// The output predictor (see the module docs). `N` entries of history, one
/// every `stride_us` or more.
#[derive(Debug, Clone)]
pub(crate) struct ForwardReckoner<T: Scalar, const N: usize> {
    /// Present output state (16 states; biases are the EKF's latest).
    x: StateVector<T>,
    t_us: u64,
    last_input: (Vector3<T>, Vector3<T>),
    ring: Ring<Entry<T>, N>,
    /// Least time between stored entries, µs.
    stride_us: u64,
    /// IMU steps since the newest stored entry.
    unstored: u32,
    /// Angle turned since the newest stored entry (the raw rate's 1-norm integrated, an
    /// upper bound), rad.
    turned: T,
    /// The raw rate's departure from its value at the newest stored entry, integrated
    /// (`∫ (w - w_e) dt`), rad.
    departure: Vector3<T>,
    /// The raw rate at the newest stored entry, rad/s.
    entry_rate: Vector3<T>,
    /// Entries pushed since the start; absolute index of the newest is `pushed - 1`.
    pushed: u64,
    /// Absolute index of the last entry at or before the horizon.
    cursor: u64,
    rotation: UnitQuaternion<T>,
    velocity: Vector3<T>,
    position: Vector3<T>,
    started: bool,
    ready: bool,
    propagations: u64,
    cursor_moves: u64,
    /// Entries stored before their stride was up (work counter, saturating).
    early_entries: u32,
    /// Corrections skipped after the first because the horizon was older than the oldest
    /// entry (saturating).
    missed_corrections: u32,
}

/// Angle turned after which an entry is stored before its stride is up, rad, when the entry
/// it evicts is one no interpolation can use again (module docs).
pub(crate) const ENTRY_TURN_RAD: f64 = 0.15;

/// Departure of the rate from its value at the newest entry, integrated, after which an
/// entry is stored before its stride is up, rad, on the same condition (module docs).
pub(crate) const ENTRY_DEPARTURE_RAD: f64 = 0.005;

/// Entries the attitude and velocity interpolation combines at most.
const STENCIL: usize = 4;

/// `t - u` in seconds, signed.
fn seconds_between<T: Scalar>(t: u64, u: u64) -> T {
    if t >= u {
        us_to_s(t - u)
    } else {
        -us_to_s::<T>(u - t)
    }
}

fn attitude_of<T: Scalar>(x: &StateVector<T>) -> UnitQuaternion<T> {
    UnitQuaternion::new_normalize(quaternion_of(x))
}

fn set_attitude<T: Scalar>(x: &mut StateVector<T>, q: &UnitQuaternion<T>) {
    let q = q.quaternion();
    x.fixed_rows_mut::<4>(QUAT)
        .copy_from(&Vector4::new(q.w, q.i, q.j, q.k));
}

impl<T: Scalar, const N: usize> ForwardReckoner<T, N> {
    /// An output predictor not started (a `const fn`: the navigator's
    /// blank value). The attitudes are zero until [`start`](Self::start)
    /// (through [`reset`](Self::reset)) sets them; an entry is stored at
    /// every sample until [`configure`](Self::configure) sets the stride.
    pub(crate) const fn new() -> Self {
        let empty = Entry {
            t_us: 0,
            attitude: zero_quaternion_const(),
            velocity: zeros_const(),
            position: zeros_const(),
        };
        Self {
            x: zeros_const(),
            t_us: 0,
            last_input: (zeros_const(), zeros_const()),
            ring: Ring::new(empty),
            stride_us: 0,
            unstored: 0,
            turned: T::ZERO,
            departure: zeros_const(),
            entry_rate: zeros_const(),
            pushed: 0,
            cursor: 0,
            rotation: zero_quaternion_const(),
            velocity: zeros_const(),
            position: zeros_const(),
            started: false,
            ready: false,
            propagations: 0,
            cursor_moves: 0,
            early_entries: 0,
            missed_corrections: 0,
        }
    }

    /// [`clear`](Self::clear), then one entry stored at the first IMU
    /// sample at least `stride_us` after the newest (`0`: at every sample).
    pub(crate) fn configure(&mut self, stride_us: u64) {
        self.clear();
        self.stride_us = stride_us;
    }

    /// Back to the state of [`new`](Self::new) in place, the work counters
    /// included (a navigator configured again); the stride is kept.
    pub(crate) fn clear(&mut self) {
        self.reset();
        self.x.fill(T::zero());
        self.t_us = 0;
        self.last_input = (Vector3::zeros(), Vector3::zeros());
        self.propagations = 0;
        self.cursor_moves = 0;
        self.early_entries = 0;
        self.missed_corrections = 0;
    }

    /// Back to the state of [`new`](Self::new) without building a new ring.
    pub(crate) fn reset(&mut self) {
        self.ring.clear();
        self.unstored = 0;
        self.turned = T::zero();
        self.departure = Vector3::zeros();
        self.pushed = 0;
        self.cursor = 0;
        self.rotation = UnitQuaternion::identity();
        self.velocity = Vector3::zeros();
        self.position = Vector3::zeros();
        self.started = false;
        self.ready = false;
    }

    /// True once started from a horizon state.
    pub(crate) fn is_started(&self) -> bool {
        self.started
    }

    /// True once a correction has reached an output state (the present is
    /// then the horizon state carried forward, not the horizon state itself).
    pub(crate) fn is_ready(&self) -> bool {
        self.ready
    }

    /// The present output state and its time.
    pub(crate) fn state(&self) -> (&StateVector<T>, u64) {
        (&self.x, self.t_us)
    }

    /// `process::propagate` calls so far (work counter).
    pub(crate) fn propagations(&self) -> u64 {
        self.propagations
    }

    /// Ring cursor moves so far (work counter).
    pub(crate) fn cursor_moves(&self) -> u64 {
        self.cursor_moves
    }

    /// Entries stored before their stride was up, the vehicle turning fast (work counter).
    pub(crate) fn early_entries(&self) -> u32 {
        self.early_entries
    }

    /// Corrections skipped once started because the horizon was older than the oldest
    /// entry: the present was not corrected by those horizon states.
    pub(crate) fn missed_corrections(&self) -> u32 {
        self.missed_corrections
    }

    /// Starts the output state at the present time `t_us` from the horizon
    /// state `x_h`, with the present raw input held.
    pub(crate) fn start(
        &mut self,
        x_h: &StateVector<T>,
        t_us: u64,
        gyro: &Vector3<T>,
        accel: &Vector3<T>,
    ) {
        self.reset();
        self.x = *x_h;
        self.t_us = t_us;
        self.last_input = (*gyro, *accel);
        self.started = true;
        self.store();
    }

    /// The present in the corrected frame of now: what [`store`](Self::store) stores.
    fn present_entry(&self) -> Entry<T> {
        Entry {
            t_us: self.t_us,
            attitude: self.rotation.inverse() * attitude_of(&self.x),
            velocity: self.x.fixed_rows::<3>(VEL) - self.velocity,
            position: self.x.fixed_rows::<3>(POS) - self.position,
        }
    }

    fn store(&mut self) {
        self.ring.push(self.present_entry());
        self.pushed = self.pushed.saturating_add(1);
        self.unstored = 0;
        self.turned = T::zero();
        self.departure = Vector3::zeros();
        self.entry_rate = self.last_input.0;
    }

    /// Whether storing one more entry evicts only an entry no interpolation
    /// can use again: the ring is not full, or its oldest entry is older
    /// than the one before the cursor (horizons only move forward).
    fn evicts_dead_only(&self) -> bool {
        self.ring.len() < N || self.pushed.saturating_sub(N as u64).saturating_add(1) < self.cursor
    }

    /// Propagates the present to `t_us` (> the present time) with the raw
    /// sample, then stores the new present.
    pub(crate) fn step(&mut self, t_us: u64, gyro: &Vector3<T>, accel: &Vector3<T>, gravity: T) {
        let dt: T = us_to_s(t_us.saturating_sub(self.t_us));
        let half = T::lit(0.5);
        let w = (self.last_input.0 + gyro) * half;
        let f = (self.last_input.1 + accel) * half;
        let next = process::propagate(&self.x, &w, &f, dt, gravity);
        self.propagations = self.propagations.saturating_add(1);
        self.x = next;
        self.position += self.velocity * dt;
        self.t_us = t_us;
        self.last_input = (*gyro, *accel);
        self.unstored = self.unstored.saturating_add(1);
        // The 1-norm bounds the angle from above without a square root.
        self.turned += w.lp_norm(1) * dt;
        self.departure += (w - self.entry_rate) * dt;
        let newest = self.ring.get(0).map_or(0, |e| e.t_us);
        let fast = self.turned >= T::lit(ENTRY_TURN_RAD)
            || self.departure.norm_squared() >= T::lit(ENTRY_DEPARTURE_RAD * ENTRY_DEPARTURE_RAD);
        if t_us.saturating_sub(newest) >= self.stride_us {
            self.store();
        } else if fast && self.evicts_dead_only() {
            self.early_entries = self.early_entries.saturating_add(1);
            self.store();
        }
    }

    /// Moves the clock to `t_us` without integrating a sample (after an IMU gap): the
    /// present is carried by its last known motion, as the horizon filter carries its state
    /// over the gap (`NavCore::carry_over_gap`): the position moves by the velocity over
    /// `carried_s` s (the gap, at most `GAP_MOTION_MAX_S`), attitude and velocity stay; the
    /// cumulative correction's position moves by its velocity over the whole gap
    /// (`dP/dt = B`), so that the entries on both sides of the gap stay in one frame. Stored again at the new time.
    pub(crate) fn hold(&mut self, t_us: u64, carried_s: T, gyro: &Vector3<T>, accel: &Vector3<T>) {
        if self.unstored > 0 {
            self.store();
        }
        let r = self.x.fixed_rows::<3>(POS) + self.x.fixed_rows::<3>(VEL) * carried_s;
        self.x.fixed_rows_mut::<3>(POS).copy_from(&r);
        self.position += self.velocity * us_to_s::<T>(t_us.saturating_sub(self.t_us));
        self.t_us = t_us;
        self.last_input = (*gyro, *accel);
        self.store();
    }

    /// The stored entry of absolute index `i`, if still in the ring; index
    /// `pushed` is the present (not stored).
    fn entry(&self, i: u64) -> Option<Entry<T>> {
        if i == self.pushed {
            return Some(self.present_entry());
        }
        let age = self.pushed.checked_sub(i.checked_add(1)?)?;
        self.ring.get(usize::try_from(age).ok()?)
    }

    /// The output state at `t_h` in the corrected frame of its storage, by
    /// interpolation between the bracketing entries; `None` outside the ring.
    fn at(&mut self, t_h: u64) -> Option<Entry<T>> {
        let oldest = self.pushed.saturating_sub(self.ring.len() as u64);
        self.cursor = self.cursor.max(oldest);
        // The cursor stays on stored entries; the present (index `pushed`)
        // only closes the last interval.
        while self.cursor.saturating_add(1) < self.pushed
            && self
                .entry(self.cursor.saturating_add(1))
                .is_some_and(|next| next.t_us <= t_h)
        {
            self.cursor = self.cursor.saturating_add(1);
            self.cursor_moves = self.cursor_moves.saturating_add(1);
        }
        let a = self.entry(self.cursor)?;
        if a.t_us > t_h {
            return None;
        }
        if a.t_us == t_h {
            return Some(a);
        }
        let b = self.entry(self.cursor.saturating_add(1))?;
        let h: T = us_to_s(b.t_us.saturating_sub(a.t_us));
        let s: T = us_to_s::<T>(t_h.saturating_sub(a.t_us)) / h;
        let one = T::one();
        let (two, three) = (T::lit(2.0), T::lit(3.0));
        let s2 = s * s;
        let s3 = s2 * s;
        let h00 = two * s3 - three * s2 + one;
        let h10 = s3 - two * s2 + s;
        let h01 = three * s2 - two * s3;
        let h11 = s3 - s2;
        let position =
            a.position * h00 + a.velocity * (h10 * h) + b.position * h01 + b.velocity * (h11 * h);
        // Attitude and velocity: Lagrange through `a`, `b` and their outer
        // neighbours when spaced like them (within `[h/2, 2h]`: an uneven
        // stencil, e.g. across an IMU gap or with the present just after
        // the newest entry, would weigh a near-difference heavily), so that
        // the stride costs `O(h^4)`, not the `O(h^2)` of a linear
        // interpolation. Linear when the result is not a usable rotation.
        let even = |d: u64| {
            let d: T = us_to_s(d);
            d + d >= h && d <= h + h
        };
        let mut stencil = [a, b, a, a];
        let mut n = 2;
        if self.cursor > oldest
            && let Some(e) = self.entry(self.cursor.saturating_sub(1))
            && even(a.t_us.saturating_sub(e.t_us))
        {
            stencil[n] = e;
            n += 1;
        }
        // The present (index `pushed`), unless just stored: then it is the
        // newest entry.
        let newest = self.pushed.saturating_sub(u64::from(self.unstored == 0));
        if self.cursor.saturating_add(2) <= newest
            && let Some(e) = self.entry(self.cursor.saturating_add(2))
            && e.t_us > b.t_us
            && even(e.t_us - b.t_us)
        {
            stencil[n] = e;
            n += 1;
        }
        let stencil = stencil.get(..n)?;
        // Times from `a`, s: one conversion per entry, one division per weight.
        let mut at = [T::zero(); STENCIL];
        for (d, e) in at.iter_mut().zip(stencil) {
            *d = seconds_between(e.t_us, a.t_us);
        }
        let x = s * h;
        let qa = a.attitude.into_inner();
        // Same hemisphere as `a`.
        let aligned = |e: &Entry<T>| {
            let q = e.attitude.into_inner();
            if qa.dot(&q) < T::zero() { -q } else { q }
        };
        let mut q = Quaternion::new(T::zero(), T::zero(), T::zero(), T::zero());
        let mut velocity = Vector3::zeros();
        // A range, not `enumerate`: its counter has an overflow check.
        for (i, (e, &ti)) in (0..stencil.len()).zip(stencil.iter().zip(&at)) {
            let (mut num, mut den) = (one, one);
            for (j, &tj) in at.iter().take(n).enumerate() {
                if j != i {
                    num *= x - tj;
                    den *= ti - tj;
                }
            }
            let w = num / den;
            q += aligned(e) * w;
            velocity += e.velocity * w;
        }
        let norm = q.norm();
        if !(norm > T::lit(0.5) && norm < T::lit(1.5) && velocity.iter().all(|v| v.is_finite())) {
            q = qa * (one - s) + aligned(&b) * s;
            velocity = a.velocity * (one - s) + b.velocity * s;
        }
        Some(Entry {
            t_us: t_h,
            attitude: UnitQuaternion::new_normalize(q),
            velocity,
            position,
        })
    }

    /// Compares the horizon state `x_h` at `t_h` with the output state at
    /// `t_h` and applies the difference to the present (module docs). The
    /// present takes the horizon's biases. Returns false (nothing applied
    /// but the biases) when `t_h` is outside the stored entries.
    pub(crate) fn correct(&mut self, t_h: u64, x_h: &StateVector<T>) -> bool {
        if !self.started {
            return false;
        }
        self.x
            .fixed_rows_mut::<3>(ACCEL_BIAS)
            .copy_from(&x_h.fixed_rows::<3>(ACCEL_BIAS));
        self.x
            .fixed_rows_mut::<3>(GYRO_BIAS)
            .copy_from(&x_h.fixed_rows::<3>(GYRO_BIAS));
        if t_h > self.t_us {
            return false;
        }
        let Some(e) = self.at(t_h) else {
            // Before the first correction the horizon is still behind the start: expected.
            if self.ready {
                self.missed_corrections = self.missed_corrections.saturating_add(1);
            }
            return false;
        };
        let span: T = us_to_s(self.t_us.saturating_sub(t_h));
        let attitude = self.rotation * e.attitude;
        let velocity = e.velocity + self.velocity;
        let position = e.position + self.position - self.velocity * span;
        let dq = attitude_of(x_h) * attitude.inverse();
        let dv = x_h.fixed_rows::<3>(VEL) - velocity;
        let dr = x_h.fixed_rows::<3>(POS) - position + dv * span;
        let q = dq * attitude_of(&self.x);
        set_attitude(&mut self.x, &q);
        let v = self.x.fixed_rows::<3>(VEL) + dv;
        self.x.fixed_rows_mut::<3>(VEL).copy_from(&v);
        let r = self.x.fixed_rows::<3>(POS) + dr;
        self.x.fixed_rows_mut::<3>(POS).copy_from(&r);
        self.rotation = UnitQuaternion::new_normalize((dq * self.rotation).into_inner());
        self.velocity += dv;
        self.position += dr;
        self.ready = true;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf16::state::StateVector;
    use std::vec::Vec;

    /// Roll rate of a flip (rad/s, a Gaussian pulse peaking at 30 rad/s at 0.6 s: about
    /// 2.6 rad in 0.15 s, like the `high` scenario's), a slow yaw rate beside it.
    fn flip_rate(t_s: f64) -> Vector3<f64> {
        let x = (t_s - 0.6) / 0.035;
        Vector3::new(30.0 * (-0.5 * x * x).exp(), 0.0, 0.3)
    }

    /// Largest attitude difference, deg, between the present of an output predictor corrected
    /// every 10 ms from a horizon 0.2 s back and the exact present, through [`flip_rate`]. The
    /// horizon state is the output state itself (the same propagation stored at every sample),
    /// so every correction should be the identity: what it is not is the interpolation's error.
    fn flip_present_error_deg<T: Scalar>() -> f64 {
        let gravity = T::lit(9.806_65);
        let accel = Vector3::new(T::zero(), T::zero(), -gravity);
        let gyro = |k: u64| flip_rate(k as f64 * 1e-3).map(T::lit);
        let mut x0 = StateVector::<T>::zeros();
        x0[QUAT] = T::one();
        // 27 ms: the stride of the default 1 s delay range at 1 kHz.
        let mut tested = ForwardReckoner::<T, 40>::new();
        tested.configure(27_000);
        tested.start(&x0, 0, &gyro(0), &accel);
        let mut exact = ForwardReckoner::<T, 40>::new();
        exact.configure(0);
        exact.start(&x0, 0, &gyro(0), &accel);
        let mut states: Vec<StateVector<T>> = Vec::from([x0]);
        let mut worst = 0.0f64;
        for k in 1..=1200u64 {
            let t_us = k * 1000;
            tested.step(t_us, &gyro(k), &accel, gravity);
            exact.step(t_us, &gyro(k), &accel, gravity);
            states.push(*exact.state().0);
            if k >= 200 && k % 10 == 0 {
                let h = usize::try_from(k - 200).unwrap();
                assert!(tested.correct(t_us - 200_000, &states[h]));
            }
            let q = attitude_of(tested.state().0);
            let q_exact = attitude_of(exact.state().0);
            worst = worst.max((q.inverse() * q_exact).angle().as_f64().to_degrees());
        }
        worst
    }

    /// Through a flip, entries stored by the angle turned keep the interpolation's error
    /// out of the present.
    fn a_flip_does_not_disturb_the_present<T: Scalar>() {
        let worst = flip_present_error_deg::<T>();
        assert!(worst < 0.05, "present off by {worst} deg through the flip");
    }

    tests_in_both_precisions!(a_flip_does_not_disturb_the_present);
}

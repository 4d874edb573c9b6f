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
//! `t_h` falls between two stored entries (IMU jitter, fractional delay).
//! The entries are interpolated: normalized linear interpolation of the
//! attitude, linear of the velocity, cubic Hermite of the position with the
//! velocities as end slopes (exact for a constant acceleration, as the
//! propagation itself assumes over a step). The entry pair is found by a
//! cursor that only moves forward with the horizon: amortized `O(1)`, at
//! most `max_horizon_step_ratio + 1` moves per sample.

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

/// The output predictor (see the module docs). `N` entries of history.
#[derive(Debug, Clone)]
pub(crate) struct ForwardReckoner<T: Scalar, const N: usize> {
    /// Present output state (16 states; biases are the EKF's latest).
    x: StateVector<T>,
    t_us: u64,
    last_input: (Vector3<T>, Vector3<T>),
    ring: Ring<Entry<T>, N>,
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
    /// (through [`reset`](Self::reset)) sets them.
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
            pushed: 0,
            cursor: 0,
            rotation: zero_quaternion_const(),
            velocity: zeros_const(),
            position: zeros_const(),
            started: false,
            ready: false,
            propagations: 0,
            cursor_moves: 0,
        }
    }

    /// Back to the state of [`new`](Self::new) in place, the work counters
    /// included (a navigator configured again).
    pub(crate) fn clear(&mut self) {
        self.reset();
        self.x.fill(T::zero());
        self.t_us = 0;
        self.last_input = (Vector3::zeros(), Vector3::zeros());
        self.propagations = 0;
        self.cursor_moves = 0;
    }

    /// Back to the state of [`new`](Self::new) without building a new ring.
    pub(crate) fn reset(&mut self) {
        self.ring.clear();
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

    fn store(&mut self) {
        let entry = Entry {
            t_us: self.t_us,
            attitude: self.rotation.inverse() * attitude_of(&self.x),
            velocity: self.x.fixed_rows::<3>(VEL) - self.velocity,
            position: self.x.fixed_rows::<3>(POS) - self.position,
        };
        self.ring.push(entry);
        self.pushed += 1;
    }

    /// Propagates the present to `t_us` (> the present time) with the raw
    /// sample, then stores the new present.
    pub(crate) fn step(&mut self, t_us: u64, gyro: &Vector3<T>, accel: &Vector3<T>, gravity: T) {
        let dt: T = us_to_s(t_us.saturating_sub(self.t_us));
        let half = T::lit(0.5);
        let w = (self.last_input.0 + gyro) * half;
        let f = (self.last_input.1 + accel) * half;
        let next = process::propagate(&self.x, &w, &f, dt, gravity);
        self.propagations += 1;
        self.x = next;
        self.position += self.velocity * dt;
        self.t_us = t_us;
        self.last_input = (*gyro, *accel);
        self.store();
    }

    /// Moves the clock to `t_us` without propagating (after an IMU gap):
    /// the present is held and stored again at the new time.
    pub(crate) fn hold(&mut self, t_us: u64, gyro: &Vector3<T>, accel: &Vector3<T>) {
        self.t_us = t_us;
        self.last_input = (*gyro, *accel);
        self.store();
    }

    /// The stored entry of absolute index `i`, if still in the ring.
    fn entry(&self, i: u64) -> Option<Entry<T>> {
        let age = self.pushed.checked_sub(i + 1)?;
        self.ring.get(usize::try_from(age).ok()?)
    }

    /// The output state at `t_h` in the corrected frame of its storage, by
    /// interpolation between the bracketing entries; `None` outside the ring.
    fn at(&mut self, t_h: u64) -> Option<Entry<T>> {
        let oldest = self.pushed.saturating_sub(self.ring.len() as u64);
        self.cursor = self.cursor.max(oldest);
        while self
            .entry(self.cursor + 1)
            .is_some_and(|next| next.t_us <= t_h)
        {
            self.cursor += 1;
            self.cursor_moves += 1;
        }
        let a = self.entry(self.cursor)?;
        if a.t_us > t_h {
            return None;
        }
        if a.t_us == t_h {
            return Some(a);
        }
        let b = self.entry(self.cursor + 1)?;
        let h: T = us_to_s(b.t_us - a.t_us);
        let s: T = us_to_s::<T>(t_h - a.t_us) / h;
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
        let qa = a.attitude.into_inner();
        // Same hemisphere, then normalized linear interpolation.
        let qb = if qa.dot(&b.attitude.into_inner()) < T::zero() {
            -b.attitude.into_inner()
        } else {
            b.attitude.into_inner()
        };
        let q: Quaternion<T> = qa * (one - s) + qb * s;
        Some(Entry {
            t_us: t_h,
            attitude: UnitQuaternion::new_normalize(q),
            velocity: a.velocity * (one - s) + b.velocity * s,
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
            return false;
        };
        let span: T = us_to_s(self.t_us - t_h);
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

//! The augmented 17-state EKF of the paper's section 2.2.1: the baseline the
//! delay-compensated navigator is compared against. The GPS delay `tau` is
//! a 17th state and the delayed fix is predicted by a second-order Taylor
//! expansion of the current state (eq. 11).
//!
//! | part | where | paper |
//! |---|---|---|
//! | state `x^d = [q r v b_f b_w tau]` | [`aekf17_measurement::DELAY`](crate::internals::aekf17_measurement::DELAY) | eq. (12) |
//! | process model, `F`, `A`, `Q` (shared with [`Ekf16`](crate::Ekf16)) | [`internals::process`](crate::internals::process) | eqs. (2)-(5) |
//! | delayed GPS model and its `H` (9x17 with the magnetometer rows) | [`internals::aekf17_measurement`](crate::internals::aekf17_measurement) | eq. (11) |
//! | magnetometer update, gating, Joseph update (shared) | [`internals::measurement`](crate::internals::measurement), [`internals::kalman`](crate::internals::kalman) | eqs. (6)-(10) |
//! | configuration | [`AugmentedEkf17Config`] | |
//!
//! # One filter, two state sizes
//! [`Ekf16`](crate::Ekf16) and this filter run the same core: the
//! propagation, the covariance prediction, the magnetometer update, the
//! gating, the Joseph update, the initialization and the refusal of bad
//! input are one code path generic over the state size. This module adds
//! only what the augmentation changes: the delay state and the GPS model.
//!
//! # Delay state
//! - Process: `tau' = 0` plus white noise of density `delay_random_walk`
//!   (s/√s): over a step `dt` its variance grows by `delay_random_walk² dt`.
//!   `tau` is uncorrelated with the navigation states until a GPS fix links
//!   them through `∂h/∂tau`.
//! - Initial value and standard deviation: `initial_delay_s`,
//!   `initial_delay_std_s`; [`AugmentedEkf17::set_delay`] replaces them
//!   (before or after initialization), e.g. with the result of an offline
//!   calibration.
//!
//! # GPS fix
//! A fix received at `t` is fused at the filter's time (the last IMU
//! sample) with the model of [`internals::aekf17_measurement`](crate::internals::aekf17_measurement): position block
//! `r - v tau + a tau²/2` then velocity block `v - a tau` (each with its
//! lever-arm terms), where `a = R(q)(f - b_f) + [0 0 g]`. Each block is
//! gated on its NIS and recorded as in [`Ekf16`](crate::Ekf16); the
//! velocity block is linearized after the position update.
//!
//! # The acceleration `a`: smoothed, and its noise counted
//! The paper takes `f` from the current IMU sample. A single sample
//! carries the accelerometer's white noise `n_a` (about 1 m/s² per sample at
//! 1 kHz for the paper's Table 3), and the model treats it as exact: the
//! velocity innovation then holds `+n_a tau` while `∂h/∂tau = -(a + n_a)`,
//! so the filter regresses the innovation on a noisy regressor and its
//! `tau` is pulled toward zero by the factor `|a|² / (|a|² + σ_a²)`
//! (errors in variables); at rest it is pulled to zero outright while its
//! variance shrinks, which is dishonest. Two measures:
//! - `a` is a first-order low-pass (time constant `accel_smoothing_s`) of
//!   the navigation-frame acceleration `R(q_k)(f~_k - b_f) + [0 0 g]` of
//!   each IMU sample. Filtering in the navigation frame keeps the low-pass
//!   from mixing gravity into the horizontal while the body turns. The GPS
//!   model uses it through the body-frame specific force
//!   `f = R(q)^T (a_s - [0 0 g]) + b_f` at the current state, so `h`
//!   evaluates to `a_s` and `H` keeps its terms through `q` and `b_f`.
//!   The low-pass lags by its time constant, an error `j T tau` (jerk `j`)
//!   smaller than the Taylor expansion's own `j tau² / 2` when `T < tau / 2`.
//!   `accel_smoothing_s = 0` is the paper's raw sample.
//! - The remaining noise of `a` (variance `σ_s²` per axis, propagated
//!   through the low-pass from the density `accel_noise_density`: per
//!   sample `σ_s² <- (1 - α)² σ_s² + α² d² / dt`, `α = 1 - exp(-dt / T)`)
//!   is added to the measurement noise: `R_r + (tau² / 2)² σ_s² I`,
//!   `R_v + tau² σ_s² I`. Its correlation between the two blocks (the same
//!   `a` in both) is neglected.
//!
//! # Keeping `tau` in `[0, max_delay_s]`
//! After each fusion, a `tau` outside the range is clamped to its nearer
//! end; the covariance is left as it is. Why this choice:
//! - it is the projection of the estimate on the admissible set, the
//!   maximum a posteriori estimate under a box constraint when the other
//!   states are held;
//! - `P` is not touched, so it keeps its symmetry and positive
//!   semi-definiteness exactly (no ad hoc reduction to get wrong);
//! - truncating a Gaussian to a half-line shrinks its variance, so keeping
//!   the untruncated `P` overstates the uncertainty of `tau`: the filter
//!   stays conservative, never overconfident.
//!
//! The alternative, projecting the whole state (`x -= P D^T (D P D^T)^-1 (D x - d)`
//! with `D` selecting `tau`), would also move the states correlated with
//! `tau`; with the clamp acting only after bad linearization (a delay
//! estimate drifting out of range is a symptom, not a measurement) moving
//! the navigation states on its account is not warranted. Clamps are
//! counted ([`AugmentedEkf17::delay_clamps`]).
//!
//! # Observability: `tau` is updated only under acceleration
//! `tau` enters the fix through `∂h_r/∂tau = a tau - v` (m/s) and
//! `∂h_v/∂tau = -a` (m/s², NED). A constant velocity does not make it
//! observable: `r(t - tau) = r(t) - v tau` differs from `r(t)` by a
//! constant offset that the position state absorbs as well; only a change
//! of velocity (`a != 0`) tells the delay from a position error. At hover
//! `a` is noise (the accelerometer's, and tilt and bias errors times `g`);
//! regressing the innovations on it drifts `tau` while its variance shrinks.
//! So a fix updates `tau` only when the excitation clears a threshold
//! above what the errors of `a_s` alone would give (m²/s⁴):
//!
//! ```text
//! |a_s|²  >=  a_min² + 16.27 σ_s² + 2 g² σ_tilt² + tr P_bf      a_min = delay_min_accel_m_s2
//! ```
//!
//! - `a_s`: the smoothed acceleration of the GPS model (m/s², NED, all three
//!   axes: a vertical manoeuvre shows `tau` too);
//! - `16.27 σ_s²`: its white noise (variance `σ_s²` per axis, above) has a
//!   square norm `σ_s² χ²(3)`, below this 99.9 % quantile on 999 fixes in
//!   1000, so noise alone almost never opens the gate (with the default
//!   50 ms smoothing and the Table 3 noise, `σ_s ≈ 0.1 m/s²`: 0.16 m²/s⁴;
//!   with the raw sample, `accel_smoothing_s = 0`, 16 m²/s⁴);
//! - `2 g² σ_tilt²`: a tilt error `δθ` (rad, `σ_tilt` the larger north/east
//!   standard deviation, [`tilt_std`](AugmentedEkf17::tilt_std)) shows `g δθ`
//!   of gravity in each horizontal axis, large while the attitude aligns;
//! - `tr P_bf`: the accelerometer bias's variance (m²/s⁴, the trace is the
//!   same in the body and navigation frames).
//!
//! Otherwise the fix
//! is fused with a Schmidt (consider) update: the gain's row of `tau` is
//! zeroed, `K' = C K` with `C = I - e_tau e_tau^T`
//! ([`kalman::joseph_update_restricted`](crate::internals::kalman::joseph_update_restricted)):
//!
//! - `tau` keeps its value; the 16 other states take the fix with the gain
//!   `K` of the full filter, whose `S = H P H^T + R` still counts the
//!   uncertainty of `tau` through `∂h/∂tau`;
//! - the Joseph form `P' = (I - K'H) P (I - K'H)^T + K' R K'^T` is the
//!   covariance of the error for any gain. Row `tau` of `I - K'H` is
//!   `e_tau^T`, so `P'_tau,tau = P_tau,tau`: the fix does not shrink it, and
//!   between fixes it grows by `delay_random_walk² dt` (s²). The
//!   cross-covariances `P'_tau,j = (P (I - K'H)^T)_tau,j` follow the other
//!   states' correction, so `P` stays symmetric, positive semi-definite and
//!   consistent with the errors;
//! - the fix is counted in [`AugmentedEkf17::delay_unobservable_fixes`].
//!
//! Without a smoothed acceleration (no IMU step since initialization or
//! since a gap) the gate is closed. `delay_min_accel_m_s2 = 0` never gates:
//! the paper's filter. With no motion at all, the variance of `tau` grows
//! with the random walk (tested).
//!
//! # Bad input
//! As [`Ekf16`](crate::Ekf16): refused samples return a typed [`Error`],
//! leave the filter unchanged and are counted in [`FilterRefusals`].

mod config;
#[doc(hidden)]
pub mod measurement;

pub use config::AugmentedEkf17Config;

use crate::ekf16::nav_core::{ExtraState, GpsBlock, GpsBlockModel, GpsMeasurement, NavCore};
use crate::ekf16::state::{ACCEL_BIAS, NAV_STATES, StateVector, quaternion_of};
use crate::ekf16::{FilterRefusals, NavState};
use crate::error::Error;
use crate::estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
use crate::geo::{LocalFrame, rotation_matrix};
use crate::kalman::GainRestriction;
use crate::scalar::{Scalar, us_to_s};
use crate::sensors::{GpsFix, ImuSample, MagSample};
use measurement::{AUGMENTED_STATES, AugmentedCovariance, AugmentedStateVector, DELAY};
use nalgebra::{Matrix3, Vector3};

/// The augmented 17-state EKF (paper section 2.2.1): the 16-state filter
/// plus the GPS delay `tau` as a state.
///
/// ```
/// use delaynav::{AugmentedEkf17Config, AugmentedEkf17, Gps, GpsOutcome, GpsPosition, Imu, Navigator};
/// use nalgebra::{Matrix3, Vector3};
///
/// let config = AugmentedEkf17Config::<f64> { initial_delay_s: 0.2, ..AugmentedEkf17Config::default() };
/// let mut aekf = AugmentedEkf17::new(config)?;
/// for k in 0..100u64 {
///     let imu = Imu { t_us: k * 10_000, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.80665) };
///     aekf.push_imu(&imu)?;
/// }
/// let fix = Gps {
///     t_us: 990_500,
///     position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0)),
///     velocity_ned_m_s: Vector3::zeros(),
///     horizontal_accuracy_m: None,
///     vertical_accuracy_m: None,
///     speed_accuracy_m_s: None,
/// };
/// assert_eq!(aekf.push_gps(&fix)?, GpsOutcome::Initialized);
/// let e = aekf.estimate().unwrap();
/// assert_eq!(e.delay_s, Some(0.2));
/// assert!((e.delay_std_s.unwrap() - 0.1).abs() < 1e-12);
/// # Ok::<(), delaynav::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct AugmentedEkf17<T: Scalar> {
    core: NavCore<T, AUGMENTED_STATES>,
    config: AugmentedEkf17Config<T>,
    delay_clamps: u32,
    delay_unobservable_fixes: u32,
    smoothed: Option<SmoothedAcceleration<T>>,
}

/// The 99.9 % quantile of a chi-square of 3 degrees of freedom: the square
/// norm of the smoothed acceleration's noise stays below it times `σ_s²`
/// on 999 samples in 1000 (module docs, "Observability").
const NOISE_QUANTILE_CHI2_3DOF: f64 = 16.27;

/// The low-passed navigation-frame acceleration and the variance of its noise.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SmoothedAcceleration<T: Scalar> {
    /// `a_s`, m/s², NED.
    ned_m_s2: Vector3<T>,
    /// Noise variance per axis, (m/s²)².
    noise_variance: T,
}

/// The delay state as the shared core describes an extra state.
fn delay_extra_state<T: Scalar>(c: &AugmentedEkf17Config<T>) -> ExtraState<T> {
    ExtraState {
        initial: c.initial_delay_s,
        initial_variance: c.initial_delay_std_s * c.initial_delay_std_s,
        random_walk_intensity: c.delay_random_walk * c.delay_random_walk,
    }
}

impl<T: Scalar> AugmentedEkf17<T> {
    /// An uninitialized filter; it initializes itself from the first GPS
    /// fix as [`Ekf16`](crate::Ekf16) does, with `tau` at its configured
    /// initial value. Fails when the configuration does not validate.
    pub fn new(config: AugmentedEkf17Config<T>) -> Result<Self, Error> {
        let mut aekf = Self::BLANK;
        aekf.configure(config)?;
        Ok(aekf)
    }

    /// A filter not configured yet: a `const` value the compiler builds (in
    /// a `static`, no stack at all). It refuses every sample
    /// ([`Error::NotConfigured`]) until [`configure`](Self::configure)
    /// succeeds.
    pub const BLANK: Self = Self {
        core: NavCore::BLANK,
        config: AugmentedEkf17Config::ZEROED,
        delay_clamps: 0,
        delay_unobservable_fixes: 0,
        smoothed: None,
    };

    /// Validates `config` and (re)starts the filter with it in place, as
    /// [`new`](Self::new) would build it (counters included). On error the
    /// filter is left not configured: it refuses every sample.
    pub fn configure(&mut self, config: AugmentedEkf17Config<T>) -> Result<(), Error> {
        let configured = config.validate().and_then(|()| {
            self.core
                .configure(config.nav, &[delay_extra_state(&config)])
        });
        if configured.is_err() {
            self.core.unconfigure();
        }
        configured?;
        self.config = config;
        self.delay_clamps = 0;
        self.delay_unobservable_fixes = 0;
        self.smoothed = None;
        Ok(())
    }

    /// True once a [`configure`](Self::configure) (or [`new`](Self::new))
    /// succeeded.
    pub fn is_configured(&self) -> bool {
        self.core.is_configured()
    }

    /// A filter initialized at time `t_us` (microseconds, IMU clock) with a
    /// known navigation state and diagonal covariance (16 states, as
    /// [`Ekf16::from_state`](crate::Ekf16::from_state)); `tau` starts at its
    /// configured initial value and variance.
    pub fn from_state(
        config: AugmentedEkf17Config<T>,
        t_us: u64,
        state: &NavState<T>,
        covariance_diagonal: &StateVector<T>,
    ) -> Result<Self, Error> {
        config.validate()?;
        let extra = delay_extra_state(&config);
        let mut x = AugmentedStateVector::zeros();
        x.fixed_rows_mut::<NAV_STATES>(0)
            .copy_from(&state.to_vector());
        x[DELAY] = extra.initial;
        let mut d = AugmentedStateVector::zeros();
        d.fixed_rows_mut::<NAV_STATES>(0)
            .copy_from(covariance_diagonal);
        d[DELAY] = extra.initial_variance;
        Ok(Self {
            core: NavCore::from_state(
                config.nav,
                &[extra],
                t_us,
                &x,
                &AugmentedCovariance::from_diagonal(&d),
            )?,
            config,
            delay_clamps: 0,
            delay_unobservable_fixes: 0,
            smoothed: None,
        })
    }

    /// The configuration (every field zero on a filter not configured: see
    /// [`is_configured`](Self::is_configured)).
    pub fn config(&self) -> &AugmentedEkf17Config<T> {
        &self.config
    }

    /// The 17-state vector `[x; tau]` (meaningful once initialized).
    pub fn state_vector(&self) -> &AugmentedStateVector<T> {
        self.core.state()
    }

    /// The named navigation state, `None` until initialized.
    pub fn nav_state(&self) -> Option<NavState<T>> {
        self.is_initialized()
            .then(|| NavState::from_vector(&self.core.nav_state()))
    }

    /// The covariance (17x17).
    pub fn covariance(&self) -> &AugmentedCovariance<T> {
        self.core.covariance()
    }

    /// The delay estimate `tau`, seconds (the initial one until initialized).
    pub fn delay_s(&self) -> T {
        self.core.extra_state(DELAY).0
    }

    /// The standard deviation of `tau`, seconds.
    pub fn delay_std_s(&self) -> T {
        self.core.extra_state(DELAY).1.sqrt()
    }

    /// Sets `tau` to `delay_s` with standard deviation `std_s` (seconds),
    /// uncorrelated with the navigation states, e.g. from the offline
    /// calibration. Before initialization this replaces the configured
    /// initial values. Refused (nothing changes) unless `delay_s` lies in
    /// `[0, max_delay_s]` and `std_s` is finite and positive.
    pub fn set_delay(&mut self, delay_s: T, std_s: T) -> Result<(), Error> {
        if !(delay_s.is_finite() && delay_s >= T::zero() && delay_s <= self.config.max_delay_s) {
            return Err(Error::OutOfRange {
                field: "delay_s",
                reason: "must lie in [0, max_delay_s]",
            });
        }
        if !(std_s.is_finite() && std_s > T::zero()) {
            return Err(Error::OutOfRange {
                field: "delay_std_s",
                reason: "must be finite and positive",
            });
        }
        self.core.reset_extra_state(DELAY, delay_s, std_s * std_s);
        Ok(())
    }

    /// How many times `tau` left `[0, max_delay_s]` after a fusion and was
    /// clamped back (see the module docs).
    pub fn delay_clamps(&self) -> u32 {
        self.delay_clamps
    }

    /// How many fixes were fused without updating `tau` because the
    /// motion did not make it observable (`delay_min_accel_m_s2`, see the
    /// module docs); `tau` then kept its value and its variance grew.
    pub fn delay_unobservable_fixes(&self) -> u32 {
        self.delay_unobservable_fixes
    }

    /// True when the smoothed acceleration clears `delay_min_accel_m_s2`
    /// above what its errors alone would give (see the module docs, m²/s⁴).
    /// Without a smoothed value (no IMU step since initialization or a gap)
    /// the excitation is unknown: false unless the gate is off.
    fn delay_observable(&self) -> bool {
        let a_min = self.config.delay_min_accel_m_s2;
        if a_min == T::zero() {
            return true;
        }
        let Some(a) = self.smoothed else {
            return false;
        };
        let g_tilt = self.config.nav.gravity_m_s2 * self.core.tilt_std();
        let bias_variance = self
            .core
            .covariance()
            .fixed_view::<3, 3>(ACCEL_BIAS, ACCEL_BIAS)
            .trace();
        let errors = T::lit(NOISE_QUANTILE_CHI2_3DOF) * a.noise_variance
            + T::lit(2.0) * g_tilt * g_tilt
            + bias_variance;
        a.ned_m_s2.norm_squared() >= a_min * a_min + errors
    }

    crate::ekf16::nav_core::core_accessors!();

    /// Feeds the accepted IMU sample to the acceleration low-pass (see the
    /// module docs); `dt` is its step, seconds.
    fn smooth_acceleration(&mut self, dt: T) {
        let Some(sample) = self.core.last_imu() else {
            return;
        };
        let c = &self.config;
        let (a, _, _) = measurement::navigation_acceleration(
            self.core.state(),
            &sample.accel_m_s2,
            c.nav.gravity_m_s2,
        );
        let sample_variance = c.nav.accel_noise_density * c.nav.accel_noise_density / dt;
        let time_constant = c.accel_smoothing_s;
        self.smoothed = Some(match self.smoothed {
            Some(prev) if time_constant > T::zero() => {
                let alpha = T::one() - (-dt / time_constant).exp();
                let keep = T::one() - alpha;
                SmoothedAcceleration {
                    ned_m_s2: prev.ned_m_s2 + (a - prev.ned_m_s2) * alpha,
                    noise_variance: keep * keep * prev.noise_variance
                        + alpha * alpha * sample_variance,
                }
            }
            _ => SmoothedAcceleration {
                ned_m_s2: a,
                noise_variance: sample_variance,
            },
        });
    }
}

/// The delayed GPS model of one block at the core's current state (see the
/// module docs): `h`, `H` and the fix's noise plus the acceleration noise
/// carried through `tau`.
///
/// The inputs: the measured rate and the body-frame specific force for
/// which the model's `a` is the smoothed acceleration. Without a smoothed
/// value yet (no IMU step since initialization) the last sample is used,
/// with no noise counted; without any sample (a filter started from a
/// state), a zero rate and the specific force of rest (`a = 0`).
fn delayed_gps_model<T: Scalar>(
    core: &NavCore<T, AUGMENTED_STATES>,
    config: &AugmentedEkf17Config<T>,
    smoothed: Option<SmoothedAcceleration<T>>,
    block: GpsBlock,
    m: &GpsMeasurement<T>,
) -> GpsBlockModel<T, AUGMENTED_STATES> {
    let x = core.state();
    let nav = &config.nav;
    let rot = rotation_matrix(&quaternion_of(x));
    let g = Vector3::new(T::zero(), T::zero(), nav.gravity_m_s2);
    let body_force = |a: &Vector3<T>| rot.transpose() * (a - g) + x.fixed_rows::<3>(ACCEL_BIAS);
    let (gyro, accel, accel_variance) = match (core.last_imu(), smoothed) {
        (Some(s), Some(a)) => (s.gyro_rad_s, body_force(&a.ned_m_s2), a.noise_variance),
        (Some(s), None) => (s.gyro_rad_s, s.accel_m_s2, T::zero()),
        (None, _) => (Vector3::zeros(), body_force(&Vector3::zeros()), T::zero()),
    };
    let tau = x[DELAY];
    match block {
        GpsBlock::Position => {
            let (h, jac) =
                measurement::delayed_gps_position(x, &accel, &nav.lever_arm_m, nav.gravity_m_s2);
            let half_tau2 = tau * tau * T::lit(0.5);
            let extra = accel_variance * half_tau2 * half_tau2;
            (h, jac, m.position_noise + Matrix3::identity() * extra)
        }
        GpsBlock::Velocity => {
            let (h, jac) = measurement::delayed_gps_velocity(
                x,
                &gyro,
                &accel,
                &nav.lever_arm_m,
                nav.gravity_m_s2,
            );
            let extra = accel_variance * tau * tau;
            (h, jac, m.velocity_noise + Matrix3::identity() * extra)
        }
    }
}

impl<T: Scalar> Navigator<T> for AugmentedEkf17<T> {
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        let before = self.core.time_us();
        let result = self.core.push_imu(imu);
        match (&result, before, self.core.time_us()) {
            (Ok(()), Some(t0), Some(t1)) if self.core.is_initialized() && t1 > t0 => {
                self.smooth_acceleration(us_to_s(t1 - t0));
            }
            // A gap: the low-pass restarts from the next sample.
            (Err(Error::StepTooLong { .. }), ..) => self.smoothed = None,
            _ => {}
        }
        result
    }

    /// Fuses the delayed position then the delayed velocity (eq. 11, see
    /// [`internals::aekf17_measurement`](crate::internals::aekf17_measurement)), each block gated on its own, `tau` kept in range
    /// after each; without the motion that makes `tau` observable, its row
    /// of the gain is zero (see the module docs).
    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        let unobservable = !self.delay_observable();
        let restriction = unobservable.then(|| {
            let mut c = AugmentedCovariance::<T>::identity();
            c[(DELAY, DELAY)] = T::zero();
            c
        });
        let (config, smoothed) = (&self.config, self.smoothed);
        let clamps = &mut self.delay_clamps;
        let outcome = self.core.push_gps(
            gps,
            |core, block, m| delayed_gps_model(core, config, smoothed, block, m),
            restriction.as_ref().map(GainRestriction::Matrix),
            // Keep tau in [0, max_delay_s], P untouched (see the module docs).
            |core| {
                if core.clamp_extra_state(DELAY, T::zero(), config.max_delay_s) {
                    *clamps = clamps.saturating_add(1);
                }
            },
        )?;
        if unobservable && matches!(outcome, GpsOutcome::Fused { .. }) {
            self.delay_unobservable_fixes = self.delay_unobservable_fixes.saturating_add(1);
        }
        Ok(outcome)
    }

    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error> {
        self.core.push_mag(mag)
    }

    /// The core's estimate with the delay and its standard deviation.
    fn estimate(&self) -> Option<Estimate<T>> {
        self.core.estimate().map(|e| Estimate {
            delay_s: Some(self.delay_s()),
            delay_std_s: Some(self.delay_std_s()),
            ..e
        })
    }

    /// The protection levels of the covariance, the delay's from its state.
    fn integrity(&self) -> crate::integrity::Integrity<T> {
        self.core.integrity(Some(self.delay_std_s()))
    }
}

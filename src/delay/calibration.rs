//! Offline calibration of the rough initial delay (sec. 2.2.2, Figure 3).
//!
//! Before the online loop runs, a recorded IMU and GPS session gives a first
//! delay, so the loop starts near the right peak. With no GPS in the
//! attitude, the IMU alone estimates it with a complementary filter:
//!
//! ```text
//! d_hat = R(q)^T [0, 0, 1]             predicted "down" in the body frame
//! d_m   = -f / |f|                      "down" measured by the accelerometer
//! w_c   = w + k (d_m x d_hat)           tilt correction (only when | |f| - g | < 0.1 g)
//! q    <- q (x) exp(w_c dt)             exact rotation of the corrected rate
//! a_nav = R(q) f + [0, 0, g]            NED acceleration
//! ```
//!
//! The heading is the gyro's integral from zero: it drifts, which rotates the
//! horizontal axes but never the vertical one. The paper's calibration moves
//! the platform vertically for that reason; any motion works as long as the
//! heading holds over the record.
//!
//! `a_nav` and the GPS acceleration (eq. 14) go through the same grid and
//! smoothing as the online loop; the normalized cross-correlation (Pearson)
//! is then accumulated over the **whole record** for every shift in
//! `[-S, S]` (the paper: +-6 s). Each pair `(x_i, y_j)` with `|j - i| <= S`
//! is added once, when the later of its two samples arrives, so the record
//! streams through (slices or iterators, no storage of the record) in
//! `O(S)` per grid sample. The three axes are combined as one vector
//! correlation,
//! `R(s) = sum_axes cov_a(s) / sqrt(sum_axes var_x,a(s) sum_axes var_y,a(s))`,
//! which weighs each axis by its motion; the refined peak of `R` is the
//! rough delay.

use nalgebra::{UnitQuaternion, Vector3};

use super::correlation::{AxisPeak, parabolic_offset, pearson};
use super::gain_fusion::AXES;
use super::grid::{
    GpsToGrid, ImuToGrid, admit_sample, grid_period_us, grid_samples, lead_samples, validate_grid,
};
use super::ring::Ring;
use crate::error::{Bound, Capacity, Error, check};
use crate::geo::{
    quaternion_from_euler, quaternion_from_rotation_vector, roll_pitch_from_accel, rotation_matrix,
};
use crate::scalar::{Scalar, all_finite};
use crate::sensors::{GpsFix, ImuSample, checked_gps, checked_imu};

/// Configuration of the offline calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct CalibrationConfig<T: Scalar> {
    /// Rate of the correlation grid, Hz.
    pub correlation_rate_hz: T,
    /// Largest shift searched either way, s (the paper: 6 s).
    pub max_shift_s: T,
    /// GPS velocity differencing span `n`, fixes.
    pub gps_diff_span: usize,
    /// Cutoff of the smoothing of both accelerations, Hz.
    pub smoothing_cutoff_hz: T,
    /// Complementary filter tilt-correction gain `k`, 1/s.
    pub tilt_gain_per_s: T,
    /// Gravity, m/s^2.
    pub gravity_m_s2: T,
    /// Longest gap in either stream, s; a longer one restarts the resampling.
    pub max_gap_s: T,
    /// Fewest grid pairs at the peak shift for a result.
    pub min_pairs: usize,
}

impl<T: Scalar> Default for CalibrationConfig<T> {
    fn default() -> Self {
        Self {
            correlation_rate_hz: T::lit(50.0),
            max_shift_s: T::lit(6.0),
            gps_diff_span: 2,
            smoothing_cutoff_hz: T::lit(1.0),
            tilt_gain_per_s: T::lit(0.2),
            gravity_m_s2: T::lit(9.80665),
            max_gap_s: T::lit(0.5),
            min_pairs: 500,
        }
    }
}

impl<T: Scalar> CalibrationConfig<T> {
    /// Checks every field (the sizes against the capacities are checked by
    /// [`OfflineCalibrator::new`]).
    pub fn validate(&self) -> Result<(), Error> {
        let extent = ("max_shift_s", self.max_shift_s);
        let rate = self.correlation_rate_hz;
        validate_grid(rate, self.gps_diff_span, self.smoothing_cutoff_hz, extent)?;
        check::not_negative("tilt_gain_per_s", self.tilt_gain_per_s)?;
        check::positive_finite("gravity_m_s2", self.gravity_m_s2)?;
        check::positive_finite("max_gap_s", self.max_gap_s)?;
        check::count_at_least("min_pairs", self.min_pairs as u64, 3)?;
        Ok(())
    }
}

/// The result of an offline calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Calibration<T: Scalar> {
    /// Rough delay: refined peak of the three-axis correlation, s.
    pub delay_s: T,
    /// Value of that peak.
    pub peak: T,
    /// Each axis' own peak (shift in grid samples, may be negative).
    pub axes: [AxisPeak<T>; AXES],
    /// Grid pairs at the peak shift.
    pub pairs: usize,
    /// Samples refused (non-finite, time not increasing) by [`OfflineCalibrator::calibrate`].
    pub refused: usize,
}

/// Sums of one shift over the record.
#[derive(Debug, Clone, Copy)]
struct ShiftSums<T: Scalar> {
    xy: Vector3<T>,
    x: Vector3<T>,
    y: Vector3<T>,
    xx: Vector3<T>,
    yy: Vector3<T>,
    n: usize,
}

impl<T: Scalar> ShiftSums<T> {
    fn zero() -> Self {
        let z = Vector3::zeros();
        Self {
            xy: z,
            x: z,
            y: z,
            xx: z,
            yy: z,
            n: 0,
        }
    }

    fn add(&mut self, x: &Vector3<T>, y: &Vector3<T>) {
        self.xy += x.component_mul(y);
        self.x += x;
        self.y += y;
        self.xx += x.component_mul(x);
        self.yy += y.component_mul(y);
        self.n += 1;
    }

    /// `(cov, var_x, var_y)` of one axis, unnormalized.
    fn moments(&self, axis: usize) -> (T, T, T) {
        let n = T::lit(self.n.max(1) as f64);
        (
            self.xy[axis] - self.x[axis] * self.y[axis] / n,
            (self.xx[axis] - self.x[axis] * self.x[axis] / n).max(T::zero()),
            (self.yy[axis] - self.y[axis] * self.y[axis] / n).max(T::zero()),
        )
    }

    fn axis_coefficient(&self, axis: usize) -> T {
        let n = T::lit(self.n.max(1) as f64);
        pearson(
            n,
            self.xy[axis],
            self.x[axis],
            self.y[axis],
            self.xx[axis],
            self.yy[axis],
        )
    }

    fn vector_coefficient(&self) -> T {
        let (mut cov, mut vx, mut vy) = (T::zero(), T::zero(), T::zero());
        for axis in 0..AXES {
            let (c, x, y) = self.moments(axis);
            cov += c;
            vx += x;
            vy += y;
        }
        if vx > T::zero() && vy > T::zero() {
            (cov / (vx * vy).sqrt()).clamp(-T::one(), T::one())
        } else {
            T::zero()
        }
    }
}

/// A grid stream kept for pairing: the last `HIST` samples and the newest index.
#[derive(Debug, Clone)]
struct GridHistory<T: Scalar, const HIST: usize> {
    ring: Ring<Vector3<T>, HIST>,
    newest: Option<u64>,
}

impl<T: Scalar, const HIST: usize> GridHistory<T, HIST> {
    fn new() -> Self {
        Self {
            ring: Ring::new(Vector3::zeros()),
            newest: None,
        }
    }

    fn push(&mut self, j: u64, v: Vector3<T>) {
        if self.newest.is_some_and(|n| j != n + 1) {
            self.ring.clear();
        }
        self.ring.push(v);
        self.newest = Some(j);
    }

    /// The sample at grid index `j`, if stored.
    fn at(&self, j: u64) -> Option<Vector3<T>> {
        let newest = self.newest?;
        if j > newest {
            return None;
        }
        usize::try_from(newest - j)
            .ok()
            .and_then(|age| self.ring.get(age))
    }
}

/// Which stream a new grid sample belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stream {
    Imu,
    Gps,
}

/// Adds the pairs a new grid sample (`index`, `value`) of `stream` forms with
/// the other stream's stored samples. Shift `k - S` pairs IMU `i` with GPS
/// `j = i + k - S`.
fn add_pairs<T: Scalar, const SHIFTS: usize, const HIST: usize>(
    sums: &mut [ShiftSums<T>; SHIFTS],
    max_shift: usize,
    other: &GridHistory<T, HIST>,
    index: u64,
    value: Vector3<T>,
    stream: Stream,
) {
    let s = max_shift as u64;
    for (k, shift_sums) in sums.iter_mut().enumerate().take(2 * max_shift + 1) {
        let k = k as u64;
        let partner = match stream {
            Stream::Imu => (index + k).checked_sub(s),
            Stream::Gps => (index + s).checked_sub(k),
        };
        if let Some(other_value) = partner.and_then(|p| other.at(p)) {
            match stream {
                Stream::Imu => shift_sums.add(&value, &other_value),
                Stream::Gps => shift_sums.add(&other_value, &value),
            }
        }
    }
}

/// Streaming offline calibrator over shifts `-S..=S` (`2 S + 1 <= SHIFTS`)
/// keeping `HIST` grid samples of each stream (at least `S` plus the lead of
/// the IMU stream, ~1 s).
#[derive(Debug, Clone)]
pub struct OfflineCalibrator<T: Scalar, const SHIFTS: usize, const HIST: usize> {
    config: CalibrationConfig<T>,
    max_shift: usize,
    period_s: T,
    attitude: Option<UnitQuaternion<T>>,
    last_imu_us: Option<u64>,
    last_gps_us: Option<u64>,
    imu_grid: ImuToGrid<T>,
    gps_grid: GpsToGrid<T>,
    x: GridHistory<T, HIST>,
    y: GridHistory<T, HIST>,
    sums: [ShiftSums<T>; SHIFTS],
}

/// A calibrator for the default configuration: 50 Hz grid, +-6 s (601 shifts).
pub type DefaultCalibrator<T> = OfflineCalibrator<T, 601, 384>;

impl<T: Scalar, const SHIFTS: usize, const HIST: usize> OfflineCalibrator<T, SHIFTS, HIST> {
    /// A calibrator for a validated configuration whose shifts fit `SHIFTS`
    /// and `HIST`.
    pub fn new(config: CalibrationConfig<T>) -> Result<Self, Error> {
        config.validate()?;
        let period_us = grid_period_us(config.correlation_rate_hz);
        let max_shift = grid_samples(config.max_shift_s, period_us);
        let period_s = period_us as f64 * 1e-6;
        let capacity = |limit: f64, of, samples: usize| {
            check::invalid(
                "max_shift_s",
                config.max_shift_s,
                Bound::Capacity {
                    limit: limit as f32,
                    at_least: false,
                    of,
                    samples: samples as u32,
                },
            )
        };
        if 2 * max_shift + 1 > SHIFTS {
            let limit = (SHIFTS.saturating_sub(1) / 2) as f64 * period_s;
            return Err(capacity(limit, Capacity::CalibratorShifts, SHIFTS));
        }
        let lead = lead_samples(
            config.gps_diff_span,
            config.max_gap_s,
            config.max_gap_s,
            period_us,
        );
        if max_shift + lead >= HIST {
            // The largest shift and the lead need fewer than `HIST` samples.
            let limit = (HIST as f64 - 1.0 - lead as f64) * period_s;
            return Err(capacity(limit, Capacity::CalibratorHist, HIST));
        }
        Ok(Self {
            config,
            max_shift,
            period_s: T::lit(period_us as f64 * 1e-6),
            attitude: None,
            last_imu_us: None,
            last_gps_us: None,
            imu_grid: ImuToGrid::new(period_us, config.smoothing_cutoff_hz),
            gps_grid: GpsToGrid::new(period_us, config.gps_diff_span, config.smoothing_cutoff_hz),
            x: GridHistory::new(),
            y: GridHistory::new(),
            sums: [ShiftSums::zero(); SHIFTS],
        })
    }

    /// One IMU sample, in time order with the GPS fixes. Refused, state
    /// unchanged: non-finite values, time not increasing.
    pub fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, sample: &I) -> Result<(), Error> {
        let imu = checked_imu(sample)?;
        let gap = admit_sample(
            "imu",
            "imu.accel",
            &imu.accel_m_s2,
            self.last_imu_us,
            imu.t_us,
            self.config.max_gap_s,
        )?;
        let f = imu.accel_m_s2;
        let g = self.config.gravity_m_s2;
        let q = match (self.attitude, self.last_imu_us) {
            (Some(q), Some(last)) if !gap => {
                let dt = T::lit((imu.t_us - last) as f64 * 1e-6);
                let mut w = imu.gyro_rad_s;
                let norm = f.norm();
                if (norm - g).abs() < g * T::lit(0.1) {
                    let down_measured = -f / norm;
                    let down_predicted = q.inverse_transform_vector(&Vector3::z());
                    w += down_measured.cross(&down_predicted) * self.config.tilt_gain_per_s;
                }
                q * quaternion_from_rotation_vector(&(w * dt))
            }
            _ => {
                let (roll, pitch) = roll_pitch_from_accel(&f);
                quaternion_from_euler(roll, pitch, T::zero())
            }
        };
        let a_nav = rotation_matrix(q.quaternion()) * f + Vector3::new(T::zero(), T::zero(), g);
        if !all_finite(&a_nav) {
            return Err(Error::NonFinite {
                field: "calibration.accel_ned",
            });
        }
        if gap {
            self.imu_grid.reset();
        }
        self.attitude = Some(q);
        self.last_imu_us = Some(imu.t_us);
        let (x_hist, y_hist, sums, s) = (&mut self.x, &self.y, &mut self.sums, self.max_shift);
        // Cannot fail: `admit_sample` refused timestamps beyond the grid's range.
        self.imu_grid.push(imu.t_us, a_nav, &mut |i, x| {
            x_hist.push(i, x);
            add_pairs(sums, s, y_hist, i, x, Stream::Imu);
        })
    }

    /// One GPS fix, in time order with the IMU samples. Refused, state
    /// unchanged: non-finite values, time not increasing.
    pub fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, fix: &G) -> Result<(), Error> {
        let gps = checked_gps(fix)?;
        let gap = admit_sample(
            "gps",
            "gps.velocity",
            &gps.velocity_ned_m_s,
            self.last_gps_us,
            gps.t_us,
            self.config.max_gap_s,
        )?;
        if gap {
            self.gps_grid.reset();
        }
        self.last_gps_us = Some(gps.t_us);
        let (x_hist, y_hist, sums, s) = (&self.x, &mut self.y, &mut self.sums, self.max_shift);
        self.gps_grid
            .push(gps.t_us, gps.velocity_ned_m_s, &mut |j, y| {
                y_hist.push(j, y);
                add_pairs(sums, s, x_hist, j, y, Stream::Gps);
            });
        Ok(())
    }

    /// Peak of a coefficient over the shifts: (index, value, refined shift in samples).
    fn peak_of(&self, coefficient: impl Fn(&ShiftSums<T>) -> T) -> (usize, T, T) {
        let count = 2 * self.max_shift + 1;
        let mut best = (0, -T::one() - T::one());
        for (k, sums) in self.sums.iter().enumerate().take(count) {
            let r = coefficient(sums);
            if sums.n >= self.config.min_pairs && r > best.1 {
                best = (k, r);
            }
        }
        let (k, r) = best;
        let offset = if k > 0 && k + 1 < count {
            parabolic_offset(
                coefficient(&self.sums[k - 1]),
                r,
                coefficient(&self.sums[k + 1]),
            )
        } else {
            T::zero()
        };
        (k, r, T::lit(k as f64 - self.max_shift as f64) + offset)
    }

    /// The three-axis correlation `R(s)` of every shift with `min_pairs` pairs so far, as
    /// (shift as a delay, s; `R`), from the most negative shift.
    pub fn curve(&self) -> impl Iterator<Item = (T, T)> + '_ {
        let shifts = 2 * self.max_shift + 1;
        self.sums
            .iter()
            .enumerate()
            .take(shifts)
            .filter(|(_, s)| s.n >= self.config.min_pairs)
            .map(move |(k, s)| {
                let shift = T::lit(k as f64 - self.max_shift as f64);
                (shift * self.period_s, s.vector_coefficient())
            })
    }

    /// The rough delay from everything pushed so far.
    ///
    /// Errors: [`Error::NotEnoughData`] when no shift has `min_pairs` pairs.
    pub fn result(&self) -> Result<Calibration<T>, Error> {
        let (k, peak, shift) = self.peak_of(ShiftSums::vector_coefficient);
        let pairs = self.sums[k].n;
        if pairs < self.config.min_pairs {
            return Err(Error::NotEnoughData {
                what: "calibration: grid pairs at every shift below min_pairs",
            });
        }
        let axes = core::array::from_fn(|axis| {
            let (ka, r, shift_a) = self.peak_of(|s| s.axis_coefficient(axis));
            let (_, var_x, var_y) = self.sums[ka].moments(axis);
            let n = T::lit(self.sums[ka].n.max(1) as f64);
            AxisPeak {
                peak: r,
                shift_samples: shift_a,
                accel_variance: var_x / n,
                gps_accel_variance: var_y / n,
                interior: ka > 0 && ka < 2 * self.max_shift,
            }
        });
        Ok(Calibration {
            delay_s: shift * self.period_s,
            peak,
            axes,
            pairs,
            refused: 0,
        })
    }

    /// Streams a whole record (IMU samples and GPS fixes, each in time order;
    /// merged here by timestamp) and returns the rough delay. Refused samples
    /// are skipped and counted in [`Calibration::refused`].
    pub fn calibrate<I, G>(&mut self, imu: I, gps: G) -> Result<Calibration<T>, Error>
    where
        I: IntoIterator,
        I::Item: ImuSample<T>,
        G: IntoIterator,
        G::Item: GpsFix<T>,
    {
        let mut imu = imu.into_iter().peekable();
        let mut gps = gps.into_iter().peekable();
        let mut refused = 0;
        loop {
            let take_imu = match (imu.peek(), gps.peek()) {
                (Some(i), Some(g)) => i.time_us() <= g.time_us(),
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (None, None) => break,
            };
            let outcome = if take_imu {
                imu.next().map(|s| self.push_imu(&s))
            } else {
                gps.next().map(|f| self.push_gps(&f))
            };
            if let Some(Err(_)) = outcome {
                refused += 1;
            }
        }
        let mut result = self.result()?;
        result.refused = refused;
        Ok(result)
    }
}

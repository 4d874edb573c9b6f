//! Sliding normalized cross-correlation of IMU and GPS accelerations (eq. 13).
//!
//! On the correlation grid (see the `grid` docs), `x_j` is the smoothed IMU
//! NED acceleration at grid time `j` and `y_j` the smoothed GPS acceleration.
//! The GPS describes the vehicle `tau` earlier, so `y_j ~ x_{j - tau/Tc}`. For
//! each axis and each shift `s` of the window `[s_min, s_min + L - 1]`, over
//! the last `B` pairs ending at `j`:
//!
//! ```text
//! Sxy(s) = sum_{i=j-B+1}^{j} x_{i-s} y_i,    Sx(s) = sum x_{i-s},   Sxx(s) = sum x_{i-s}^2
//! Sy = sum y_i,  Syy = sum y_i^2
//! R(s) = (Sxy - Sx Sy / B) / sqrt((Sxx - Sx^2 / B)(Syy - Sy^2 / B))
//! ```
//!
//! `R` is the Pearson coefficient: eq. (13) of the paper without mean removal
//! would let a constant offset (an accelerometer bias rotated into NED, a
//! residual of gravity) add a shift-independent term `c Sy` to every `Sxy`.
//!
//! # Why a sliding update
//!
//! A full recomputation per GPS fix costs `3 L B` products (3 x 26 x 125 =
//! 9 750 at the defaults) for every fix. Instead every sum is updated when a
//! grid pair arrives: add the product entering the window, subtract the one
//! leaving it, `3 L` products each way, i.e. `Tgps / Tc` times that per fix
//! (2 x 195 products per 10 Hz fix at 25 Hz, 25x fewer, and the same at any
//! delay: the shift only selects which stored `x` is used). The window sums
//! `Sx(s), Sxx(s)` of `x` are computed by the peak search from the stored
//! `x`, not kept per grid time: the first shift's window is summed (`B`
//! additions), and each next shift slides it by one sample (add the one
//! entering, subtract the one leaving), `O(B + L)` per search. The peak
//! search then costs `3 L` Pearson evaluations per fix.
//!
//! Add-and-subtract sums drift by rounding (a concern in `f32`). Each running
//! sum of the sliding update (`Sxy`, `Sy`, `Syy`) has a shadow that only
//! adds; after exactly `B` additions the shadow *is* the window sum,
//! computed without subtraction, and replaces the running sum. The drift is
//! thus bounded to `B` steps, at the price of one more addition per product.
//! The search's `Sx, Sxx` start from an add-only sum at every search and
//! slide at most `L - 1` steps: their drift is bounded the same way.
//!
//! # Peak
//!
//! The largest `R(s)` is refined below one sample by the vertex of the
//! parabola through its neighbours,
//! `delta = (R(s-1) - R(s+1)) / (2 (R(s-1) - 2 R(s) + R(s+1)))`, in
//! `[-1/2, 1/2]`. A maximum on the window's edge is reported as not interior:
//! the true peak may be outside the window.

use nalgebra::Vector3;

use super::ring::Ring;
use crate::error::{Error, check};
use crate::scalar::{Scalar, zeros_const};

/// The correlation peak of one NED axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AxisPeak<T: Scalar> {
    /// Largest normalized correlation `R(s)`, in `[-1, 1]`.
    pub peak: T,
    /// Shift of the refined peak, correlation samples (fractional).
    pub shift_samples: T,
    /// Variance of the smoothed IMU acceleration over the buffer at the
    /// peak shift, (m/s^2)^2: the axis' motion energy.
    pub accel_variance: T,
    /// Variance of the smoothed GPS acceleration over the buffer, (m/s^2)^2.
    pub gps_accel_variance: T,
    /// False when the maximum sits on the first or last shift of the window.
    pub interior: bool,
}

/// Pearson coefficient from sums over `n` pairs; 0 when either signal has no
/// variance.
pub(crate) fn pearson<T: Scalar>(n: T, sxy: T, sx: T, sy: T, sxx: T, syy: T) -> T {
    let vx = sxx - sx * sx / n;
    let vy = syy - sy * sy / n;
    if vx > T::zero() && vy > T::zero() {
        let r = (sxy - sx * sy / n) / (vx * vy).sqrt();
        r.clamp(-T::one(), T::one())
    } else {
        T::zero()
    }
}

/// Vertex offset of the parabola through `(-1, left), (0, centre), (1, right)`,
/// in `[-1/2, 1/2]`; 0 when the three points do not bend down.
pub(crate) fn parabolic_offset<T: Scalar>(left: T, centre: T, right: T) -> T {
    let curvature = left - centre * T::lit(2.0) + right;
    if curvature < T::zero() {
        let half = T::lit(0.5);
        (half * (left - right) / curvature).clamp(-half, half)
    } else {
        T::zero()
    }
}

/// Running window sums of a 3-axis stream with an add-only shadow that
/// replaces them every `window` additions (bounded rounding drift).
#[derive(Debug, Clone, Copy)]
struct WindowSums<T: Scalar> {
    sum: Vector3<T>,
    squares: Vector3<T>,
    shadow_sum: Vector3<T>,
    shadow_squares: Vector3<T>,
    shadow_count: usize,
}

impl<T: Scalar> WindowSums<T> {
    const fn new() -> Self {
        Self {
            sum: zeros_const(),
            squares: zeros_const(),
            shadow_sum: zeros_const(),
            shadow_squares: zeros_const(),
            shadow_count: 0,
        }
    }

    fn add(&mut self, entering: Vector3<T>, leaving: Option<Vector3<T>>, window: usize) {
        let entering_sq = entering.component_mul(&entering);
        self.sum += entering;
        self.squares += entering_sq;
        if let Some(old) = leaving {
            self.sum -= old;
            self.squares -= old.component_mul(&old);
        }
        self.shadow_sum += entering;
        self.shadow_squares += entering_sq;
        self.shadow_count = self.shadow_count.saturating_add(1);
        if self.shadow_count == window {
            self.sum = self.shadow_sum;
            self.squares = self.shadow_squares;
            self.shadow_sum = Vector3::zeros();
            self.shadow_squares = Vector3::zeros();
            self.shadow_count = 0;
        }
    }
}

/// Sliding normalized cross-correlation of two 3-axis grid streams over a
/// buffer of `B <= BUF` pairs and `L <= LAGS` shifts; `HIST` grid samples of
/// the IMU stream are kept (at least `B + s_min + L` plus the lead of the IMU
/// stream over the GPS stream).
#[derive(Debug, Clone)]
pub struct SlidingCorrelator<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize> {
    buffer_len: usize,
    shift_min: usize,
    lags: usize,
    x: Ring<Vector3<T>, HIST>,
    x_newest: Option<u64>,
    y: Ring<Vector3<T>, BUF>,
    y_newest: Option<u64>,
    y_sums: WindowSums<T>,
    cross: [[T; LAGS]; 3],
    cross_shadow: [[T; LAGS]; 3],
    cross_shadow_count: usize,
    pairs: usize,
    /// GPS grid samples waiting for the IMU stream to reach them.
    pending: Ring<(u64, Vector3<T>), PENDING_GPS_SAMPLES>,
    multiply_adds: u64,
}

/// GPS grid samples that can wait for the IMU stream (1.28 s at the default
/// 25 Hz grid): the caller may push a GPS fix before the IMU samples of the
/// same instant.
pub const PENDING_GPS_SAMPLES: usize = 32;

impl<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize>
    SlidingCorrelator<T, BUF, LAGS, HIST>
{
    /// A correlator over `buffer_len` pairs and the shifts
    /// `shift_min..shift_min + lags` (grid samples).
    ///
    /// Errors: `buffer_len` not in `2..=BUF`, `lags` not in `3..=LAGS`, or
    /// `buffer_len + shift_min + lags > HIST`.
    pub fn new(buffer_len: usize, shift_min: usize, lags: usize) -> Result<Self, Error> {
        let mut correlator = Self::BLANK;
        correlator.configure(buffer_len, shift_min, lags)?;
        Ok(correlator)
    }

    /// A correlator of no buffer, to be [`configure`](Self::configure)d
    /// (the delay loop's blank value: built by the compiler, no stack).
    /// Never pushed to before then.
    pub(crate) const BLANK: Self = Self {
        buffer_len: 0,
        shift_min: 0,
        lags: 0,
        x: Ring::new(zeros_const()),
        x_newest: None,
        y: Ring::new(zeros_const()),
        y_newest: None,
        y_sums: WindowSums::new(),
        cross: [[T::ZERO; LAGS]; 3],
        cross_shadow: [[T::ZERO; LAGS]; 3],
        cross_shadow_count: 0,
        pairs: 0,
        pending: Ring::new((0, zeros_const())),
        multiply_adds: 0,
    };

    /// [`new`](Self::new) in place: checks the sizes (unchanged on error),
    /// then sets them and empties every buffer through `&mut` (no copy of
    /// the buffers), the work counter included.
    pub(crate) fn configure(
        &mut self,
        buffer_len: usize,
        shift_min: usize,
        lags: usize,
    ) -> Result<(), Error> {
        check::count_within("buffer_len", buffer_len as u64, 2, BUF as u64)?;
        check::count_within("lags", lags as u64, 3, LAGS as u64)?;
        // The history holds the buffer and the largest shift.
        let room = HIST.saturating_sub(shift_min.saturating_add(lags));
        check::count_within("buffer_len", buffer_len as u64, 2, room as u64)?;
        self.buffer_len = buffer_len;
        self.shift_min = shift_min;
        self.lags = lags;
        self.multiply_adds = 0;
        self.reset();
        Ok(())
    }

    /// Forgets both streams.
    pub fn reset(&mut self) {
        self.x.clear();
        self.x_newest = None;
        self.reset_pairs();
    }

    pub(crate) fn reset_pairs(&mut self) {
        self.y.clear();
        self.y_newest = None;
        self.y_sums = WindowSums::new();
        for sums in self.cross.iter_mut().chain(self.cross_shadow.iter_mut()) {
            sums.fill(T::zero());
        }
        self.cross_shadow_count = 0;
        self.pairs = 0;
        self.pending.clear();
    }

    /// True once the buffer holds `B` pairs.
    pub fn is_ready(&self) -> bool {
        self.pairs >= self.buffer_len
    }

    /// The IMU grid sample `j`, while stored.
    pub(crate) fn imu_at(&self, j: i64) -> Option<Vector3<T>> {
        let newest = i64::try_from(self.x_newest?).ok()?;
        let age = usize::try_from(newest.checked_sub(j)?).ok()?;
        self.x.get(age)
    }

    /// Products accumulated so far: the work counter of the sliding update.
    pub fn multiply_adds(&self) -> u64 {
        self.multiply_adds
    }

    /// Adds the IMU grid sample `j`. A non-consecutive index restarts both
    /// streams.
    pub fn push_x(&mut self, j: u64, x: Vector3<T>) {
        if self.x_newest.is_some_and(|n| Some(j) != n.checked_add(1)) {
            self.reset();
        }
        self.x.push(x);
        self.x_newest = Some(j);
        self.pair_pending();
    }

    /// Queues the GPS grid sample `j`; it is paired as soon as the IMU stream
    /// reaches `j` (at once, normally: the GPS side lags). If more than
    /// [`PENDING_GPS_SAMPLES`] wait, the oldest are dropped and the buffer
    /// restarts.
    pub fn push_y(&mut self, j: u64, y: Vector3<T>) {
        self.pending.push((j, y));
        self.pair_pending();
    }

    fn pair_pending(&mut self) {
        while let (Some((j, y)), Some(x_newest)) = (self.pending.oldest(), self.x_newest) {
            if j > x_newest {
                break;
            }
            self.pending.pop_oldest();
            self.pair(j, y);
        }
    }

    /// Pairs the GPS grid sample `j` (`<=` the newest IMU index) with the
    /// stored IMU samples `j - s` and slides every sum. Skipped while the IMU
    /// history is too short; a non-consecutive index restarts the buffer.
    fn pair(&mut self, j: u64, y: Vector3<T>) {
        let Some(x_newest) = self.x_newest.filter(|&n| n >= j) else {
            return;
        };
        if self.y_newest.is_some_and(|n| Some(j) != n.checked_add(1)) {
            self.reset_pairs();
        }
        let age = (x_newest - j) as usize;
        let mut full = self.pairs >= self.buffer_len;
        // No overflow: shift_min + lags <= HIST, lags >= 3 (`configure`): no wrap.
        let shift_max = self.shift_min.wrapping_add(self.lags).wrapping_sub(1);
        // No overflow: shift_max + buffer_len <= HIST (`configure`).
        if full && age.saturating_add(shift_max.wrapping_add(self.buffer_len)) >= self.x.len() {
            self.reset_pairs();
            full = false;
        }
        if age.saturating_add(shift_max) >= self.x.len() {
            return;
        }
        let y_old = if full {
            // No overflow: buffer_len >= 2 (`configure`).
            self.y.get(self.buffer_len.wrapping_sub(1))
        } else {
            None
        };
        // `lags <= LAGS` (checked in `new`); the `min` only lets the
        // compiler drop the bounds checks below (benches/no-panic).
        for lag in 0..self.lags.min(LAGS) {
            // No overflow: shift_min + lag < shift_min + lags <= HIST; age + s below x.len() (checked above).
            let s = self.shift_min.wrapping_add(lag);
            let x = self
                .x
                .get(age.wrapping_add(s))
                .unwrap_or_else(Vector3::zeros);
            let x_old = if full {
                self.x
                    .get(age.wrapping_add(s).wrapping_add(self.buffer_len))
            } else {
                None
            };
            for axis in 0..3 {
                let product = x[axis] * y[axis];
                self.cross[axis][lag] += product;
                self.cross_shadow[axis][lag] += product;
                if let (Some(xo), Some(yo)) = (x_old, y_old) {
                    self.cross[axis][lag] -= xo[axis] * yo[axis];
                }
            }
        }
        self.multiply_adds = self
            .multiply_adds
            .saturating_add((self.lags.min(LAGS) * if full { 9 } else { 6 }) as u64);
        self.cross_shadow_count = self.cross_shadow_count.saturating_add(1);
        if self.cross_shadow_count == self.buffer_len {
            self.cross = self.cross_shadow;
            self.cross_shadow = [[T::zero(); LAGS]; 3];
            self.cross_shadow_count = 0;
        }
        self.y_sums.add(y, y_old, self.buffer_len);
        self.y.push(y);
        self.y_newest = Some(j);
        self.pairs = self.pairs.saturating_add(1).min(self.buffer_len);
    }

    /// Normalized correlation of `axis` from the window sums `(Sx, Sxx)` of
    /// one shift, and the IMU variance of that shift.
    fn coefficient(&self, window: &(Vector3<T>, Vector3<T>), axis: usize, lag: usize) -> (T, T) {
        let n = T::lit(self.buffer_len as f64);
        let (sx, sxx) = window;
        // `axis < 3` (the callers) and `lag < lags <= LAGS` (`new`): neither
        // the reduction nor the fallback changes anything; they only keep
        // bounds checks that could panic out of the push API (benches/no-panic).
        let axis = axis % 3;
        let sxy = self.cross[axis].get(lag).copied().unwrap_or_else(T::zero);
        let r = pearson(
            n,
            sxy,
            sx[axis],
            self.y_sums.sum[axis],
            sxx[axis],
            self.y_sums.squares[axis],
        );
        let mean = sx[axis] / n;
        (r, (sxx[axis] / n - mean * mean).max(T::zero()))
    }

    /// The refined correlation peak of each axis, `None` until the buffer is
    /// full. Costs `3 L` coefficient evaluations.
    pub fn peaks(&self) -> Option<[AxisPeak<T>; 3]> {
        let (Some(x_newest), Some(y_newest)) = (self.x_newest, self.y_newest) else {
            return None;
        };
        if !self.is_ready() || x_newest < y_newest {
            return None;
        }
        let age = (x_newest - y_newest) as usize;
        let first = age.saturating_add(self.shift_min);
        // Every window of the search must still be stored.
        // No overflow: lags + buffer_len <= HIST and x.len() <= HIST (`configure`): no wrap.
        if first.saturating_add(self.lags.wrapping_add(self.buffer_len))
            > self.x.len().wrapping_add(1)
        {
            return None;
        }
        let n = T::lit(self.buffer_len as f64);
        let x = |a: usize| self.x.get(a).unwrap_or_else(Vector3::zeros);
        // Window sums of the first shift, add-only.
        let mut window = (Vector3::zeros(), Vector3::zeros());
        // No overflow: first + lags + buffer_len <= x.len() + 1 (checked above) from here on: no wrap.
        for a in first..first.wrapping_add(self.buffer_len) {
            let v = x(a);
            window.0 += v;
            window.1 += v.component_mul(&v);
        }
        // Per axis: the best shift so far (lag, R, variance), R of the
        // shift before the best, R of the shift after it.
        let mut best = [(0usize, -T::one() - T::one(), T::zero()); 3];
        let mut left = [T::zero(); 3];
        let mut right = [T::zero(); 3];
        let mut previous = [T::zero(); 3];
        for lag in 0..self.lags {
            if lag > 0 {
                // Slide by one shift: the window moves one sample older.
                // No overflow: first + lags + buffer_len <= x.len() + 1 (checked above).
                let (entering, leaving) = (
                    x(first
                        .wrapping_add(lag)
                        .wrapping_add(self.buffer_len)
                        .wrapping_sub(1)),
                    x(first.wrapping_add(lag).wrapping_sub(1)),
                );
                window.0 += entering - leaving;
                window.1 += entering.component_mul(&entering) - leaving.component_mul(&leaving);
            }
            for axis in 0..3 {
                let (r, var) = self.coefficient(&window, axis, lag);
                // No overflow: best[axis].0 < lags <= LAGS.
                if lag > 0 && best[axis].0.wrapping_add(1) == lag {
                    right[axis] = r;
                }
                if r > best[axis].1 {
                    best[axis] = (lag, r, var);
                    left[axis] = previous[axis];
                }
                previous[axis] = r;
            }
        }
        let mut out = [AxisPeak::default(); 3];
        for (axis, peak) in out.iter_mut().enumerate() {
            let (lag, r, var) = best[axis];
            // No overflow: lag < lags <= LAGS.
            let interior = lag > 0 && lag.wrapping_add(1) < self.lags;
            let offset = if interior {
                parabolic_offset(left[axis], r, right[axis])
            } else {
                T::zero()
            };
            let y_mean = self.y_sums.sum[axis] / n;
            *peak = AxisPeak {
                peak: r,
                // No overflow: shift_min + lag < HIST.
                shift_samples: T::lit(self.shift_min.wrapping_add(lag) as f64) + offset,
                accel_variance: var,
                gps_accel_variance: (self.y_sums.squares[axis] / n - y_mean * y_mean)
                    .max(T::zero()),
                interior,
            };
        }
        Some(out)
    }
}

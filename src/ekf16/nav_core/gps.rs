//! GPS fusion: a fix checked and put in the filter's frame, position then
//! velocity fused, each block judged (rejection timer, NIS window) and
//! reset to the fix when it must be; the records kept.

use super::*;

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// Checks and converts a GPS fix; initializes the filter from it when
    /// the filter is not yet initialized (see the module docs).
    pub(crate) fn begin_gps<G: GpsFix<T> + ?Sized>(
        &mut self,
        gps: &G,
    ) -> Result<GpsStep<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let fix = checked_gps(gps).inspect_err(|_| bump(&mut self.refusals.gps_invalid))?;
        check_time("gps", self.gps_clock_us, fix.t_us)
            .inspect_err(|_| bump(&mut self.refusals.gps_time))?;
        let geodetic = check_position_kind(self.geodetic_fixes.get(), &fix.position)
            .inspect_err(|_| bump(&mut self.refusals.gps_mixed_frames))?;
        let (frame, position) = match fix.position {
            GpsPosition::Ned(p) => (self.frame, p),
            GpsPosition::Geodetic(g) => {
                let frame = self.frame.unwrap_or_else(|| LocalFrame::new(g));
                (Some(frame), frame.to_ned_t(&g))
            }
        };
        if !all_finite(&position) {
            bump(&mut self.refusals.gps_invalid);
            return Err(Error::NonFinite {
                field: "gps.position",
            });
        }
        let c = &self.config;
        let use_rx = c.use_receiver_accuracy;
        let pick = |reported: Option<T>, configured: T| match reported {
            Some(a) if use_rx => a * a,
            _ => configured * configured,
        };
        let h = pick(fix.horizontal_accuracy_m, c.gps_horizontal_std_m);
        let v = pick(fix.vertical_accuracy_m, c.gps_vertical_std_m);
        let s = pick(fix.speed_accuracy_m_s, c.gps_velocity_std_m_s);
        let m = GpsMeasurement {
            t_us: fix.t_us,
            position_ned_m: position,
            velocity_ned_m_s: fix.velocity_ned_m_s,
            position_noise: Matrix3::from_diagonal(&Vector3::new(h, h, v)),
            velocity_noise: Matrix3::identity() * s,
        };
        self.geodetic_fixes = ZeroOption::Some(geodetic);
        if self.initialized {
            self.gps_clock_us = Some(fix.t_us);
            self.frame = frame;
            return Ok(GpsStep::Measure(m));
        }
        if self.last_imu.is_none() || self.accel_mean_span_us < self.config.align_min_duration_us {
            self.gps_clock_us = Some(fix.t_us);
            return Ok(GpsStep::Waiting);
        }
        self.initialize(&m)?;
        self.gps_accepted_us = [Some(fix.t_us); 2];
        self.gps_nis = [(T::zero(), 0); 2];
        self.gps_nis_mean = [T::lit(3.0); 2];
        self.gps_velocity_innovation_mean = Vector3::zeros();
        self.monitor_position_velocity(&m, true, false);
        self.gps_clock_us = Some(fix.t_us);
        self.frame = frame;
        Ok(GpsStep::Initialized)
    }

    /// Fuses one `M`-dimensional block `y = z - h(x)`, `H` (`M x N`), `R`
    /// with the given chi-square gate and the gain restricted to `C K`
    /// (`None`: unrestricted; see [`kalman::joseph_update_restricted`]),
    /// then renormalizes the quaternion. A fusion that would leave the
    /// quaternion far from unit norm (an absurd correction) is reverted and
    /// reported as rejected.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn fuse_restricted<const M: usize>(
        &mut self,
        t_us: u64,
        innovation: &SVector<T, M>,
        h: &SMatrix<T, M, N>,
        r: &SMatrix<T, M, M>,
        gate: T,
        measurement: &'static str,
        gain_restriction: Option<GainRestriction<'_, T, N>>,
    ) -> Result<FusionRecord<T, M>, Error> {
        // An absurd correction (the quaternion far from unit norm) is
        // refused before `P` changes.
        let mut norm = T::one();
        let record = kalman::joseph_update_checked(
            &mut self.x,
            &mut self.p,
            innovation,
            h,
            r,
            gate,
            t_us,
            measurement,
            gain_restriction,
            |x| {
                norm = quaternion_of(x).norm();
                norm > T::lit(0.5) && norm < T::lit(2.0)
            },
        )
        .inspect_err(|_| bump(&mut self.refusals.not_positive_definite))?;
        if record.fused {
            self.x.fixed_rows_mut::<4>(QUAT).unscale_mut(norm);
            if project_quaternion_covariance(&mut self.p, &self.x) {
                bump(&mut self.refusals.covariance_repairs);
            }
        }
        Ok(record)
    }

    /// Feeds one GPS fix: [`NavCore::begin_gps`], then the position block
    /// and the velocity block, each linearized by `model` at the state left
    /// by the previous step, fused with its gate (and the gain restricted by
    /// `gain_restriction`, see [`NavCore::fuse_restricted`]) and followed by
    /// `after_fusion`; the records are stored with [`NavCore::record_gps`].
    pub(crate) fn push_gps<G: GpsFix<T> + ?Sized>(
        &mut self,
        gps: &G,
        mut model: impl FnMut(&Self, GpsBlock, &GpsMeasurement<T>) -> GpsBlockModel<T, N>,
        gain_restriction: Option<GainRestriction<'_, T, N>>,
        mut after_fusion: impl FnMut(&mut Self),
    ) -> Result<GpsOutcome<T>, Error> {
        let m = match self.begin_gps(gps)? {
            GpsStep::Waiting => return Ok(GpsOutcome::Waiting),
            GpsStep::Initialized => return Ok(GpsOutcome::Initialized),
            GpsStep::Measure(m) => m,
        };
        let (h, jac, r) = model(self, GpsBlock::Position, &m);
        let gate = self.config.gps_position_gate;
        let position = self.fuse_restricted(
            m.t_us,
            &(m.position_ned_m - h),
            &jac,
            &r,
            gate,
            "gps.position",
            gain_restriction,
        )?;
        after_fusion(self);
        let (h, jac, r) = model(self, GpsBlock::Velocity, &m);
        let gate = self.config.gps_velocity_gate;
        let velocity = self.fuse_restricted(
            m.t_us,
            &(m.velocity_ned_m_s - h),
            &jac,
            &r,
            gate,
            "gps.velocity",
            gain_restriction,
        )?;
        after_fusion(self);
        self.record_gps(position, velocity);
        let mut position_reset = false;
        for (block, record, gate) in [
            (GpsBlock::Position, &position, self.config.gps_position_gate),
            (GpsBlock::Velocity, &velocity, self.config.gps_velocity_gate),
        ] {
            if let Some(cause) = self.gps_block_verdict(block, record, gate) {
                // Linearized again: the other block's fusion moved the state.
                let (h, _, _) = model(self, block, &m);
                self.reset_gps_block(block, &h, &m, cause);
                position_reset |= block == GpsBlock::Position;
            }
        }
        self.monitor_position_velocity(&m, position.fused, position_reset);
        Ok(GpsOutcome::Fused { position, velocity })
    }

    /// Updates a GPS block's rejection timer and divergence window with the
    /// record of its fusion; returns why the block must be reset, if it must.
    ///
    /// - Rejected: the block of every fix since the last accepted one was
    ///   rejected for at least `gps_reset_timeout_us` (never when it is 0).
    /// - Diverged: the mean NIS of the last `gps_nis_window` accepted
    ///   fusions (consecutive windows, no overlap) is above `gps_nis_bound`
    ///   (never when the window is 0).
    pub(super) fn gps_block_verdict(
        &mut self,
        block: GpsBlock,
        record: &FusionRecord<T, 3>,
        gate: T,
    ) -> Option<GpsResetCause> {
        let i = block as usize;
        let t_us = record.t_us;
        if !record.fused {
            let timeout = self.config.gps_reset_timeout_us;
            // A filter started from a given state: count from this rejection.
            let since = *self.gps_accepted_us[i].get_or_insert(t_us);
            return (timeout > 0 && t_us.saturating_sub(since) >= timeout)
                .then_some(GpsResetCause::Rejected);
        }
        self.gps_accepted_us[i] = Some(t_us);
        let window = self.config.gps_nis_window;
        if window == 0 {
            return None;
        }
        let (sum, count) = &mut self.gps_nis[i];
        *sum += record.test_ratio * gate;
        *count = count.saturating_add(1);
        if *count < window {
            return None;
        }
        let mean = *sum / T::lit(f64::from(*count));
        self.gps_nis[i] = (T::zero(), 0);
        (mean > self.config.gps_nis_bound).then_some(GpsResetCause::Diverged)
    }

    /// Resets one GPS block to the fix: the states are shifted by the
    /// innovation `z - h(x)` (`h` the filter's own model at the current
    /// state, lever arm and delay term included, so it then predicts the
    /// fix), their rows and columns of `P` are cleared and their variances
    /// set to the fix's noise `R`. `P` stays symmetric PSD (a block-diagonal
    /// of PSD blocks). Every other state keeps its value. Counted per block,
    /// recorded with its cause, and the block's timer and window restart.
    pub(super) fn reset_gps_block(
        &mut self,
        block: GpsBlock,
        h: &Vector3<T>,
        m: &GpsMeasurement<T>,
        cause: GpsResetCause,
    ) {
        let (start, z, noise, counter) = match block {
            GpsBlock::Position => (
                POS,
                m.position_ned_m,
                &m.position_noise,
                &mut self.refusals.gps_position_resets,
            ),
            GpsBlock::Velocity => (
                VEL,
                m.velocity_ned_m_s,
                &m.velocity_noise,
                &mut self.refusals.gps_velocity_resets,
            ),
        };
        bump(counter);
        let innovation = z - h;
        for i in 0..3 {
            let k = start + i;
            self.x[k] += innovation[i];
            self.p.row_mut(k).fill(T::zero());
            self.p.column_mut(k).fill(T::zero());
            self.p[(k, k)] = noise[(i, i)];
        }
        if cause == GpsResetCause::Diverged {
            bump(&mut self.refusals.gps_divergence_resets);
        }
        let i = block as usize;
        self.gps_accepted_us[i] = Some(m.t_us);
        self.gps_nis[i] = (T::zero(), 0);
        if block == GpsBlock::Velocity {
            // The velocity is the fix's now: what the innovations showed is gone with it.
            self.gps_velocity_innovation_mean = Vector3::zeros();
        }
        self.last_gps_reset = ZeroOption::Some(GpsReset {
            t_us: m.t_us,
            block,
            cause,
        });
    }

    /// Stores the records of one GPS fusion and counts rejections.
    pub(crate) fn record_gps(
        &mut self,
        position: FusionRecord<T, 3>,
        velocity: FusionRecord<T, 3>,
    ) {
        if !position.fused {
            bump(&mut self.refusals.gps_position_rejected);
        }
        if !velocity.fused {
            bump(&mut self.refusals.gps_velocity_rejected);
        }
        if position.fused || velocity.fused {
            self.gps_fused_us = Some(position.t_us);
        }
        self.monitor_gps_nis(&position, &velocity);
        self.last_gps = (position, velocity);
        self.gps_recorded = true;
    }
}

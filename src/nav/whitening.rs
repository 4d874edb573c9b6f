//! The optional whitening FIR of one IMU stream (accelerometer or
//! gyroscope) and its group delay (`D_f`, `D_w` of eq. 15).

use super::config::{WHITENING_TAPS, WhiteningFilter};
use crate::delay::WhiteningFir;
use crate::error::Error;
use crate::scalar::Scalar;
use nalgebra::Vector3;

/// Either a whitening FIR or nothing.
#[derive(Debug, Clone)]
pub(super) struct Whitening<T: Scalar> {
    fir: Option<WhiteningFir<T, WHITENING_TAPS>>,
    pub(super) group_delay_s: T,
}

impl<T: Scalar> Whitening<T> {
    pub(super) const BLANK: Self = Self {
        fir: None,
        group_delay_s: T::ZERO,
    };

    pub(super) fn new(filter: WhiteningFilter<T>, rate_hz: T) -> Result<Self, Error> {
        Ok(Self {
            fir: match filter {
                WhiteningFilter::PassThrough => None,
                WhiteningFilter::LowPass { cutoff_hz } => {
                    Some(WhiteningFir::low_pass(cutoff_hz, rate_hz)?)
                }
            },
            group_delay_s: filter.group_delay_s(rate_hz),
        })
    }

    pub(super) fn filter(&mut self, x: Vector3<T>) -> Vector3<T> {
        match &mut self.fir {
            // The input was checked finite: the filter cannot refuse it.
            Some(fir) => fir.filter(x).unwrap_or(x),
            None => x,
        }
    }

    pub(super) fn reset(&mut self) {
        if let Some(fir) = &mut self.fir {
            fir.reset();
        }
    }
}

//! Sample storage in 16 bits: block floating point with a full-precision
//! staging block.
//!
//! # Format
//!
//! Samples of `CH` channels arrive one at a time. The newest, incomplete
//! block of `BLOCK` samples is kept as it came (the staging block). When it
//! completes, each channel of it is stored as 16-bit integers `m` with the
//! block's own offset `o` and scale `s` (both `f32`):
//!
//! ```text
//! o = (min + max) / 2,   s = max |x - o| / 32766,   m = round((x - o) / s),   x' = o + m s
//! ```
//!
//! so `|m| <= 32767` for every sample of the block (none saturates), and a
//! read returns `x'` with `|x' - x| <= s / 2`, about `(max - min) / 2^17`:
//! the resolution is relative to the block's spread, not to the value, as a
//! 16-bit sensor ADC's. A block whose channel is constant stores it exactly
//! (`s = 0`; in `f64`, to the `f32` rounding of the offset).
//!
//! # Where the block header goes
//!
//! Each stored row is the `CH` mantissas and one 16-bit side word. The `2 CH`
//! header values of a block (`o` and `s` of every channel, `4 CH` words) are
//! spread over the side words of the block's rows, hence `BLOCK >= 4 CH`.
//! A separate header array would need `N / BLOCK` entries, a length stable
//! Rust cannot compute from the capacity `N`. With `CH = 6` and `BLOCK = 24`
//! that is 14 bytes a sample and 576 bytes of staging in `f32`, against 24
//! bytes a sample unpacked.
//!
//! # Capacity
//!
//! `N` samples are readable (once pushed): the staging block holds the
//! newest `0..BLOCK`, whole blocks the rest. The rows are `N` plus `BLOCK`
//! spare ones, so `(N + BLOCK) / BLOCK` whole blocks fit, always at least `N`
//! samples behind the staging block.

use nalgebra::SVector;

use super::fractional_delay::{lagrange_read, lagrange_weight, stencil};
use crate::error::Error;
use crate::scalar::{Scalar, zeros_const};

/// The largest mantissa: `i16::MIN` is never written, so `-m` is one too.
const MANTISSA_MAX: f32 = 32_767.0;

/// The largest magnitude a packed sample may have (the offset and scale are
/// `f32`, and `max - min` must not overflow).
pub(crate) const PACKED_LIMIT: f64 = 1e30;

/// One stored sample: its mantissas and one word of its block's header.
#[derive(Debug, Clone, Copy)]
struct Row<const CH: usize> {
    mantissas: [i16; CH],
    side: u16,
}

impl<const CH: usize> Row<CH> {
    const ZERO: Self = Self {
        mantissas: [0; CH],
        side: 0,
    };
}

/// A ring of the last `N` samples of `CH` channels in 16 bits (module docs);
/// `BLOCK` samples share an offset and a scale per channel.
#[derive(Debug, Clone)]
pub(crate) struct PackedRing<T: Scalar, const CH: usize, const N: usize, const BLOCK: usize> {
    rows: [Row<CH>; N],
    spare: [Row<CH>; BLOCK],
    /// The newest samples, not yet packed.
    staging: [SVector<T, CH>; BLOCK],
    staged: usize,
    /// Block slot written next.
    next_block: usize,
    /// Whole blocks stored.
    blocks: usize,
    /// Blocks sealed since construction (never reset: the newest block's
    /// identity for a [`HeaderCache`]).
    sealed: u64,
}

/// The decoded offsets and scales of the last two blocks a reader used,
/// by block identity: a Lagrange read near the last one decodes no header.
/// Kept by the reader (a `&self` read, no interior mutability).
#[derive(Debug, Clone)]
pub(crate) struct HeaderCache<T: Scalar, const CH: usize> {
    entries: [(u64, [(T, T); CH]); 2],
    /// The entry replaced next.
    next: usize,
}

impl<T: Scalar, const CH: usize> HeaderCache<T, CH> {
    /// Empty (no block has identity 0: all zero bytes, a blank value in
    /// `.bss`).
    pub(crate) const fn new() -> Self {
        Self {
            entries: [(0, [(T::ZERO, T::ZERO); CH]); 2],
            next: 0,
        }
    }

    /// The headers of block `block`, decoded by `decode` on a miss.
    fn headers(&mut self, block: u64, decode: impl FnOnce() -> [(T, T); CH]) -> [(T, T); CH] {
        // Two entries, compared one by one (`find` on their iterator kept
        // an overflow check of its count: benches/no-panic).
        let [(b0, h0), (b1, h1)] = self.entries;
        if b0 == block {
            return h0;
        }
        if b1 == block {
            return h1;
        }
        let entry = self.next % 2;
        let headers = decode();
        self.entries[entry] = (block, headers);
        // No overflow: entry < 2.
        self.next = entry.wrapping_add(1);
        headers
    }
}

impl<T: Scalar, const CH: usize, const N: usize, const BLOCK: usize> PackedRing<T, CH, N, BLOCK> {
    /// Whole blocks the rows hold.
    const SLOTS: usize = (N + BLOCK) / BLOCK;

    /// An empty ring (a `const fn`: no stack in a `const` blank value).
    pub(crate) const fn new() -> Self {
        const {
            assert!(N > 0 && CH > 0, "a packed ring needs room and channels");
            assert!(
                BLOCK >= 4 * CH,
                "a block's side words must hold its header: BLOCK >= 4 CH"
            );
        };
        Self {
            rows: [Row::ZERO; N],
            spare: [Row::ZERO; BLOCK],
            staging: [zeros_const(); BLOCK],
            staged: 0,
            next_block: 0,
            blocks: 0,
            sealed: 0,
        }
    }

    /// Readable samples (at most `N`).
    pub(crate) fn len(&self) -> usize {
        self.blocks
            .saturating_mul(BLOCK)
            .saturating_add(self.staged)
            .min(N)
    }

    /// Forgets every sample.
    pub(crate) fn clear(&mut self) {
        self.staged = 0;
        self.next_block = 0;
        self.blocks = 0;
    }

    /// Appends the newest sample. Refused, ring unchanged: a non-finite
    /// value or one beyond [`PACKED_LIMIT`] in magnitude.
    pub(crate) fn push(&mut self, sample: SVector<T, CH>) -> Result<(), Error> {
        if !sample.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                field: "packed.sample",
            });
        }
        if sample.iter().any(|v| v.abs() > T::lit(PACKED_LIMIT)) {
            return Err(Error::OutOfRange {
                field: "packed.sample",
                reason: "beyond the 16-bit storage's range (1e30)",
            });
        }
        // `staged < BLOCK` always; reduced so that the index is provably in
        // bounds (benches/no-panic).
        self.staging[self.staged % BLOCK] = sample;
        self.staged = self.staged.saturating_add(1);
        if self.staged >= BLOCK {
            self.seal();
        }
        Ok(())
    }

    /// Where the sample of age `age` is: `Ok(index)` in the staging block,
    /// `Err((block, first, row))` packed, in the block of identity `block`
    /// starting at row `first`.
    fn locate(&self, age: usize) -> Option<Result<usize, (u64, usize, usize)>> {
        if age >= self.len() {
            return None;
        }
        if age < self.staged {
            return Some(Ok((self.staged - 1 - age) % BLOCK));
        }
        let packed_age = age - self.staged;
        let back = packed_age / BLOCK;
        // No overflow: next_block < SLOTS, back % SLOTS < SLOTS, and the
        // row below is within the block `first..first + BLOCK`.
        let slot = self
            .next_block
            .wrapping_add(Self::SLOTS - 1)
            .wrapping_sub(back % Self::SLOTS)
            % Self::SLOTS;
        let first = slot * BLOCK;
        // The newest whole block is `sealed` (0 is no block).
        let block = self.sealed.wrapping_sub(back as u64);
        let row = first
            .wrapping_add(BLOCK - 1)
            .wrapping_sub(packed_age % BLOCK);
        Some(Err((block, first, row)))
    }

    /// Offsets and scales of every channel of the block starting at row
    /// `first`: side words `4c..4c + 4` of the block, low half first.
    fn headers(&self, first: usize) -> [(T, T); CH] {
        // No overflow: `first` starts a block, whose rows hold the 4 CH
        // side words (a loop, not `array::from_fn`: its counter has an
        // overflow check).
        let word = |k: usize| u32::from(self.row(first.wrapping_add(k)).side);
        let mut out = [(T::ZERO, T::ZERO); CH];
        for (c, h) in (0..CH).zip(out.iter_mut()) {
            let k = c.wrapping_mul(4);
            let half = |k: usize| word(k) | word(k.wrapping_add(1)) << 16;
            *h = (
                T::from_f32_exact(f32::from_bits(half(k))),
                T::from_f32_exact(f32::from_bits(half(k.wrapping_add(2)))),
            );
        }
        out
    }

    /// The packed sample in row `row`, with its block's headers.
    fn unpack(&self, row: usize, headers: &[(T, T); CH]) -> SVector<T, CH> {
        let mantissas = &self.row(row).mantissas;
        SVector::from_fn(|c, _| {
            let (offset, scale) = headers[c % CH];
            offset + T::from_f32_exact(f32::from(mantissas[c % CH])) * scale
        })
    }

    /// The sample pushed `age` pushes ago (0 = newest), while readable
    /// (the tests' reference; reads go through [`read`](Self::read)).
    #[cfg(test)]
    pub(crate) fn get(&self, age: usize) -> Option<SVector<T, CH>> {
        Some(match self.locate(age)? {
            Ok(index) => self.staging[index % BLOCK],
            Err((_, first, row)) => self.unpack(row, &self.headers(first)),
        })
    }

    /// The Lagrange read of order `ORDER` at `delay_samples` behind the
    /// newest sample, as [`FractionalDelayLine::read`](super::FractionalDelayLine::read);
    /// the headers of the blocks read are decoded through `cache`. When the
    /// stencil lies in one packed block (most reads), the mantissas are
    /// combined first: `o + s sum_j w_j m_j`.
    pub(crate) fn read<const ORDER: usize>(
        &self,
        delay_samples: T,
        cache: &mut HeaderCache<T, CH>,
    ) -> Result<SVector<T, CH>, Error> {
        let (s0, t) = stencil::<T, ORDER>(self.len(), delay_samples)?;
        if let (Some(Err((block, first, newest_row))), Some(Err((oldest_block, ..)))) =
            // No overflow: s0 <= len - 1 - ORDER (`stencil`).
            (self.locate(s0), self.locate(s0.wrapping_add(ORDER)))
            && block == oldest_block
        {
            let headers = cache.headers(block, || self.headers(first));
            let (mut sum, mut weights) = ([T::zero(); CH], T::zero());
            for j in 0..=ORDER {
                let w = lagrange_weight::<T, ORDER>(j, t);
                weights += w;
                // Older samples sit in earlier rows of the block.
                let mantissas = &self.row(newest_row.saturating_sub(j)).mantissas;
                for (acc, &m) in sum.iter_mut().zip(mantissas) {
                    *acc += T::from_f32_exact(f32::from(m)) * w;
                }
            }
            return Ok(SVector::from_fn(|c, _| {
                let (offset, scale) = headers[c % CH];
                offset * weights + scale * sum[c % CH]
            }));
        }
        lagrange_read::<T, CH, ORDER>(self.len(), |age| self.get_cached(age, cache), delay_samples)
    }

    /// The sample pushed `age` pushes ago (0 = newest), while readable, the
    /// headers of its block decoded through `cache`.
    fn get_cached(&self, age: usize, cache: &mut HeaderCache<T, CH>) -> Option<SVector<T, CH>> {
        Some(match self.locate(age)? {
            Ok(index) => self.staging[index % BLOCK],
            Err((block, first, row)) => {
                let headers = cache.headers(block, || self.headers(first));
                self.unpack(row, &headers)
            }
        })
    }

    /// Row `i` of the `SLOTS * BLOCK` in use (`N` rows, then the spare ones).
    fn row(&self, i: usize) -> &Row<CH> {
        if i < N {
            &self.rows[i]
        } else {
            &self.spare[(i - N) % BLOCK]
        }
    }

    fn row_mut(&mut self, i: usize) -> &mut Row<CH> {
        if i < N {
            &mut self.rows[i]
        } else {
            &mut self.spare[(i - N) % BLOCK]
        }
    }

    /// Packs the full staging block into the next block slot.
    fn seal(&mut self) {
        let first = (self.next_block % Self::SLOTS) * BLOCK;
        // Per channel: the range, then the offset and the scale.
        let (mut lo, mut hi) = (self.staging[0], self.staging[0]);
        for sample in &self.staging {
            for c in 0..CH {
                if sample[c] < lo[c] {
                    lo[c] = sample[c];
                }
                if sample[c] > hi[c] {
                    hi[c] = sample[c];
                }
            }
        }
        let mut codes = [(T::zero(), T::zero()); CH];
        for (c, code) in codes.iter_mut().enumerate() {
            let half = T::lit(0.5);
            let offset = (lo[c] * half + hi[c] * half).round_to_f32();
            let offset_t = T::from_f32_exact(offset);
            let reach = (hi[c] - offset_t).max(offset_t - lo[c]);
            // Dividing by 32766 rather than 32767 leaves a margin far above
            // the rounding of `scale`, so no quotient exceeds 32767.
            let mut scale = (reach / T::lit(f64::from(MANTISSA_MAX) - 1.0)).round_to_f32();
            if scale < 1e-30 {
                // Constant to within 3e-26: the offset alone.
                scale = 0.0;
            }
            *code = (
                offset_t,
                if scale > 0.0 {
                    T::one() / T::from_f32_exact(scale)
                } else {
                    T::zero()
                },
            );
            let (o, s) = (offset.to_bits(), scale.to_bits());
            for (k, word) in [o, o >> 16, s, s >> 16].into_iter().enumerate() {
                // Truncation to the low 16 bits intended.
                self.row_mut(first + 4 * c + k).side = (word & 0xffff) as u16;
            }
        }
        for i in 0..BLOCK {
            let sample = self.staging[i];
            let row = self.row_mut(first + i);
            for (c, &(offset, inverse)) in codes.iter().enumerate() {
                let q = ((sample[c] - offset) * inverse).round_to_f32();
                let rounded = q + if q >= 0.0 { 0.5 } else { -0.5 };
                // `as` saturates; the clamp keeps `i16::MIN` out.
                row.mantissas[c % CH] = rounded.clamp(-MANTISSA_MAX, MANTISSA_MAX) as i16;
            }
        }
        // No overflow: next_block < SLOTS.
        self.next_block = self.next_block.wrapping_add(1) % Self::SLOTS;
        self.blocks = self.blocks.saturating_add(1).min(Self::SLOTS);
        self.sealed = self.sealed.wrapping_add(1);
        self.staged = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delay::ring::Ring;

    /// Round-trip error bound of one stored sample: `spread * 2^-15` of its
    /// block's channel, plus the rounding of the arithmetic (`f32` offset and
    /// scale, `T` reads) relative to the values.
    fn bound(spread: f64, magnitude: f64) -> f64 {
        spread * 2f64.powi(-15) + 4.0 * f64::from(f32::EPSILON) * magnitude + 1e-24
    }

    /// Pushes `values` through a packed ring and an exact one side by side
    /// and checks every readable sample after every push.
    fn round_trip<T: Scalar, const N: usize, const B: usize>(values: &[[f64; 3]]) {
        let mut packed = PackedRing::<T, 3, N, B>::new();
        let mut exact = Ring::<[f64; 3], N>::new([0.0; 3]);
        let mut pushed = 0usize;
        for v in values {
            packed.push(SVector::from(v.map(T::lit))).unwrap();
            exact.push(*v);
            pushed += 1;
            assert_eq!(packed.len(), pushed.min(N));
            for age in 0..packed.len() {
                let got = packed.get(age).unwrap();
                let want = exact.get(age).unwrap();
                // The block of this sample: `age` within the staging block
                // is exact; a packed one is in the block of its push index.
                let index = pushed - 1 - age;
                let staged = pushed % B;
                let packed_block = (age >= staged).then(|| index / B);
                for c in 0..3 {
                    let got = got[c].as_f64();
                    assert!(got.is_finite());
                    let err = (got - want[c]).abs();
                    match packed_block {
                        None => assert_eq!(got, T::lit(want[c]).as_f64()),
                        Some(b) => {
                            let block = &values[b * B..(b + 1) * B];
                            let lo = block.iter().map(|x| x[c]).fold(f64::MAX, f64::min);
                            let hi = block.iter().map(|x| x[c]).fold(f64::MIN, f64::max);
                            let mag = lo.abs().max(hi.abs());
                            assert!(
                                err <= bound(hi - lo, mag),
                                "age {age} ch {c}: {got} vs {} (block {lo}..{hi})",
                                want[c]
                            );
                        }
                    }
                }
            }
            assert_eq!(packed.get(packed.len()), None);
        }
    }

    fn wave(len: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut state = seed | 1;
        (0..len)
            .map(|k| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                let t = k as f64 * 1e-3;
                [
                    9.81 + 0.3 * (7.0 * t).sin() + 0.05 * noise,
                    -2.0e3 * (0.5 * t).cos(),
                    if k % 40 < 20 { 0.0 } else { 1e-3 * noise },
                ]
            })
            .collect()
    }

    #[test]
    fn reads_every_position_within_the_bound_f32_and_f64() {
        let values = wave(300, 3);
        round_trip::<f32, 100, 12>(&values);
        round_trip::<f64, 100, 12>(&values);
        // A capacity that is a multiple of the block.
        round_trip::<f32, 96, 12>(&values[..150]);
        round_trip::<f64, 12, 12>(&values[..60]);
    }

    /// The Lagrange reads (headers decoded once per block) against the
    /// unpacked line's, at delays across staging and block boundaries.
    #[test]
    fn lagrange_reads_match_the_unpacked_line() {
        let values = wave(200, 5);
        let mut packed = PackedRing::<f64, 3, 100, 12>::new();
        let mut line = crate::delay::FractionalDelayLine::<f64, 3, 100, 3>::new();
        for v in &values {
            packed.push(SVector::from(*v)).unwrap();
            line.push(SVector::from(*v)).unwrap();
        }
        // Within 3x a sample's bound over the whole stream's spread.
        let spread = [0.7, 4.0e3, 1e-3];
        let mut cache = HeaderCache::new();
        for k in 0..=990 {
            let d = k as f64 * 0.1;
            let got = packed.read::<3>(d, &mut cache).unwrap();
            let want = line.read(d).unwrap();
            for c in 0..3 {
                let err = (got[c] - want[c]).abs();
                assert!(err <= 3.0 * bound(spread[c], 1e4), "d {d} ch {c}: {err}");
            }
        }
        assert!(packed.read::<3>(99.5, &mut cache).is_err());
    }

    #[test]
    fn a_constant_channel_reads_back_exactly() {
        let mut ring = PackedRing::<f32, 1, 8, 4>::new();
        for _ in 0..20 {
            ring.push(SVector::from([9.80665f32])).unwrap();
        }
        for age in 0..8 {
            assert_eq!(ring.get(age), Some(SVector::from([9.80665f32])));
        }
    }

    #[test]
    fn bad_samples_are_refused_and_change_nothing() {
        let mut ring = PackedRing::<f64, 1, 8, 4>::new();
        ring.push(SVector::from([1.0])).unwrap();
        assert!(ring.push(SVector::from([f64::NAN])).is_err());
        assert!(ring.push(SVector::from([1e31])).is_err());
        assert_eq!(ring.len(), 1);
        // The extremes that are accepted neither overflow nor saturate.
        for x in [1e30, -1e30, 1e30, -1e30] {
            ring.push(SVector::from([x])).unwrap();
        }
        assert_eq!(ring.len(), 5);
        for age in 0..4 {
            let x = ring.get(age).unwrap()[0];
            let want = if age % 2 == 0 { -1e30 } else { 1e30 };
            assert!((x - want).abs() <= 1e30 * 1e-4, "{x}");
        }
        ring.clear();
        assert_eq!((ring.len(), ring.get(0)), (0, None));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Any values (magnitudes 1e-6 to 1e6, any mix of scales per
        /// block): every read within the bound, finite, in both precisions.
        #[test]
        fn any_values_round_trip(
            raw in proptest::collection::vec(
                (-1.0f64..1.0, -6i32..6, -1.0f64..1.0, -1.0f64..1.0),
                1..120,
            )
        ) {
            let values: Vec<[f64; 3]> = raw
                .iter()
                .map(|&(a, e, b, c)| [a * 10f64.powi(e), b, 1e3 + c])
                .collect();
            round_trip::<f32, 37, 12>(&values);
            round_trip::<f64, 37, 12>(&values);
        }
    }
}

//! `halton`: the Halton sequence, dimension d in the d-th prime base.
//!
//! Randomisation: every dimension's digits go through a random permutation seeded by
//! the render seed (breaks the correlation between large prime bases; tables built
//! once per seed and shared), and each stream (pixel) gets its own Cranley–Patterson
//! rotation per dimension (one hash of a per-stream key) so neighbouring pixels are
//! decorrelated. Sample `index` of a stream is point `index` of the sequence, so only
//! the few digits of a small index are visited. Dimensions beyond the prime table
//! are hashed uniform values. With `scramble = false` (tests) the plain radical
//! inverses are returned.

use super::radical::DigitTables;
use super::{PRIMES, Sampler, dim_hash, frac_to_f32, stream_key};
use std::sync::Arc;

/// Salt of the hashed values of dimensions beyond the prime table.
const SALT_BEYOND: u64 = 0x5851_F42D_4C95_7F2D;

/// Halton sampler.
#[derive(Clone)]
pub struct HaltonSampler {
    seed: u64,
    tables: Arc<DigitTables>,
    scramble: bool,
    stream: u64,
    key: u64,
    index: u64,
    dim: u32,
    /// The current stream's rotations of the table dimensions, each hashed on first
    /// use (bit k of `rot_known`): a pixel's samples share them.
    rot: [u32; PRIMES.len()],
    rot_known: u64,
}

impl HaltonSampler {
    /// Randomised Halton sampler (digit permutations + per-stream rotation).
    pub fn new(seed: u64) -> Self {
        Self::with_scramble(seed, true)
    }
    /// With `scramble == false`: the raw sequence, no permutation, no rotation.
    pub fn with_scramble(seed: u64, scramble: bool) -> Self {
        let tables = Arc::new(DigitTables::new(seed, scramble));
        HaltonSampler {
            seed,
            tables,
            scramble,
            stream: 0,
            key: stream_key(seed, 0),
            index: 0,
            dim: 0,
            rot: [0; PRIMES.len()],
            rot_known: 0,
        }
    }
    /// Value of dimension `dim` for the current stream and index.
    #[inline]
    pub fn value(&self, dim: u32) -> f32 {
        frac_to_f32(fraction(&self.tables, self.scramble, self.key, self.index, dim as usize, dim))
    }
    /// [`HaltonSampler::value`], reading the stream's rotation from its cache.
    #[inline(always)]
    fn value_cached(&mut self, dim: u32) -> f32 {
        let k = dim as usize;
        if !self.scramble || k >= self.tables.len() || k >= PRIMES.len() {
            return self.value(dim);
        }
        if self.rot_known & (1 << k) == 0 {
            self.rot[k] = (dim_hash(self.key, dim, 0) >> 32) as u32;
            self.rot_known |= 1 << k;
        }
        frac_to_f32(self.tables.fraction(k, self.index).wrapping_add(self.rot[k]))
    }
    /// [`HaltonSampler::value`] of another stream key and index.
    #[inline]
    fn value_of(&self, key: u64, index: u64, dim: u32) -> f32 {
        frac_to_f32(fraction(&self.tables, self.scramble, key, index, dim as usize, dim))
    }
}

/// Fraction of table dimension `k` (sampler dimension `dim`) with the stream's
/// rotation; hashed values past the table (shared with `hammersley`).
#[inline]
pub(crate) fn fraction(tables: &DigitTables, scramble: bool, key: u64, index: u64, k: usize, dim: u32) -> u32 {
    if k < tables.len() {
        let f = tables.fraction(k, index);
        if scramble { f.wrapping_add((dim_hash(key, dim, 0) >> 32) as u32) } else { f }
    } else {
        (dim_hash(key ^ index.wrapping_mul(0xD6E8_FEB8_6659_FD93), dim, SALT_BEYOND) >> 32) as u32
    }
}

/// Starts a stream, reusing the stream key when the stream does not change.
#[inline]
pub(crate) fn restart(seed: u64, stream: &mut u64, key: &mut u64, new_stream: u64) {
    if *stream != new_stream {
        *stream = new_stream;
        *key = stream_key(seed, new_stream);
    }
}

impl Sampler for HaltonSampler {
    fn name(&self) -> &'static str {
        "halton"
    }
    #[inline]
    fn start(&mut self, stream: u64, index: u64) {
        if stream != self.stream {
            self.rot_known = 0;
        }
        restart(self.seed, &mut self.stream, &mut self.key, stream);
        self.index = index;
        self.dim = 0;
    }
    fn current(&self) -> (u64, u64) {
        (self.stream, self.index)
    }
    fn values_at(&self, stream: u64, index: u64, dim: u32, out: &mut [f32]) {
        let key = if stream == self.stream { self.key } else { stream_key(self.seed, stream) };
        for (d, o) in (dim..).zip(out.iter_mut()) {
            *o = self.value_of(key, index, d);
        }
    }
    super::dimension_methods!(value_cached);
    fn to_any(&self) -> Option<super::AnySampler> {
        Some(super::AnySampler::Halton(self.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::PRIMES;

    /// The cached rotations give the values `value` computes, across stream changes,
    /// dimensions past the table and clones.
    #[test]
    fn cached_rotations_equal_computed_values() {
        let mut s = HaltonSampler::new(3);
        for (stream, index) in [(0u64, 0u64), (0, 5), (17, 5), (17, 2000), (0, 1), (17, 1)] {
            s.start(stream, index);
            let mut c = s.clone();
            for d in 0..(PRIMES.len() as u32 + 8) {
                let want = s.value_of(stream_key(3, stream), index, d);
                let got = if d % 3 == 0 { c.next_2d()[0] } else { c.next_1d() };
                if d % 3 == 0 {
                    c.set_dimension(d + 1);
                }
                assert_eq!(got.to_bits(), want.to_bits(), "stream {stream} index {index} dim {d}");
            }
            s.set_dimension(0);
            let _ = s.next_2d();
        }
    }

    #[test]
    fn raw_first_values() {
        let mut s = HaltonSampler::with_scramble(0, false);
        let mut got = Vec::new();
        for i in 0..4 {
            s.start(0, i);
            got.push(s.next_2d());
        }
        let want = [[0.0, 0.0], [0.5, 1.0 / 3.0], [0.25, 2.0 / 3.0], [0.75, 1.0 / 9.0]];
        for (g, w) in got.iter().zip(want) {
            assert!((g[0] - w[0]).abs() < 1e-6 && (g[1] - w[1]).abs() < 1e-6, "{g:?} vs {w:?}");
        }
    }

    #[test]
    fn scrambled_values_in_range_and_stratified() {
        let mut s = HaltonSampler::new(42);
        // First 2^k points of base-2 dimension stay one per stratum under permutation+rotation.
        let mut strata = [0u32; 16];
        for i in 0..16 {
            s.start(9, i);
            let v = s.next_1d();
            assert!((0.0..1.0).contains(&v));
            strata[(v * 16.0) as usize] += 1;
        }
        // A rotation shifts strata boundaries, so allow at most 2 per bin.
        assert!(strata.iter().all(|&c| c <= 2), "{strata:?}");
        for i in 0..200 {
            s.start(i, i);
            for _ in 0..(PRIMES.len() + 16) {
                let v = s.next_1d();
                assert!((0.0..1.0).contains(&v));
            }
        }
    }
}

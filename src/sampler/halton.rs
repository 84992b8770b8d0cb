//! `halton`: the Halton sequence, dimension d in the d-th prime base.
//!
//! Randomisation: every dimension's digits go through a random permutation seeded by
//! the render seed (breaks the correlation between large prime bases), and each
//! stream (pixel) gets its own Cranley–Patterson rotation per dimension so
//! neighbouring pixels are decorrelated. Sample `index` of a stream is point `index`
//! of the sequence. Dimensions beyond the prime table fall back to `random`.
//! With `scramble = false` (tests) the plain radical inverses are returned.

use super::random::RandomSampler;
use super::{PRIMES, Sampler, cp_shift, digit_permutations, radical_inverse, rotate, scrambled_radical_inverse};
use std::sync::Arc;

/// Halton sampler.
#[derive(Clone)]
pub struct HaltonSampler {
    seed: u64,
    perms: Option<Arc<Vec<Vec<u16>>>>,
    stream: u64,
    index: u64,
    dim: u32,
    fallback: RandomSampler,
}

impl HaltonSampler {
    /// Randomised Halton sampler (digit permutations + per-stream rotation).
    pub fn new(seed: u64) -> Self {
        Self::with_scramble(seed, true)
    }
    /// With `scramble == false`: the raw sequence, no permutation, no rotation.
    pub fn with_scramble(seed: u64, scramble: bool) -> Self {
        let perms = scramble.then(|| Arc::new(digit_permutations(seed, PRIMES.len())));
        HaltonSampler { seed, perms, stream: 0, index: 0, dim: 0, fallback: RandomSampler::new(seed) }
    }
    /// Value of dimension `dim` for the current stream and index.
    #[inline]
    pub fn value(&self, dim: u32) -> f32 {
        let base = PRIMES[dim as usize];
        match &self.perms {
            Some(p) => rotate(scrambled_radical_inverse(base, &p[dim as usize], self.index), cp_shift(self.seed, self.stream, dim)),
            None => (radical_inverse(base, self.index) as f32).min(crate::math::ONE_MINUS_EPSILON),
        }
    }
}

impl Sampler for HaltonSampler {
    fn name(&self) -> &'static str {
        "halton"
    }
    fn start(&mut self, stream: u64, index: u64) {
        self.stream = stream;
        self.index = index;
        self.dim = 0;
        self.fallback.start(stream, index);
    }
    fn set_dimension(&mut self, dim: u32) {
        self.dim = dim;
        if dim as usize >= PRIMES.len() {
            self.fallback.set_dimension(dim);
        }
    }
    fn dimension(&self) -> u32 {
        self.dim
    }
    fn current(&self) -> (u64, u64) {
        (self.stream, self.index)
    }
    #[inline]
    fn next_1d(&mut self) -> f32 {
        let d = self.dim;
        self.dim = self.dim.saturating_add(1);
        if (d as usize) < PRIMES.len() {
            self.value(d)
        } else {
            if d as usize == PRIMES.len() {
                self.fallback.set_dimension(d);
            }
            self.fallback.next_1d()
        }
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            for _ in 0..80 {
                let v = s.next_1d();
                assert!((0.0..1.0).contains(&v));
            }
        }
    }
}

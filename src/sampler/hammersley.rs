//! `hammersley`: the Hammersley point set of a known size N. Dimension 0 is i/N,
//! dimension d ≥ 1 the radical inverse in the d-th prime base (2, 3, 5, …), with the
//! same digit permutations and per-stream Cranley–Patterson rotation as `halton`.
//! It needs N up front: building one without a sample count is an error.

use super::random::RandomSampler;
use super::{PRIMES, Sampler, cp_shift, digit_permutations, radical_inverse, rotate, scrambled_radical_inverse};
use std::sync::Arc;

/// Hammersley sampler over a fixed number of samples per stream.
#[derive(Clone)]
pub struct HammersleySampler {
    seed: u64,
    n: u64,
    perms: Option<Arc<Vec<Vec<u16>>>>,
    stream: u64,
    index: u64,
    dim: u32,
    fallback: RandomSampler,
}

impl HammersleySampler {
    /// Randomised Hammersley set of `n` points per stream.
    pub fn new(seed: u64, n: u64) -> Result<Self, String> {
        Self::with_scramble(seed, n, true)
    }
    /// With `scramble == false`: the raw point set.
    pub fn with_scramble(seed: u64, n: u64, scramble: bool) -> Result<Self, String> {
        if n == 0 {
            return Err("the hammersley sampler needs the number of samples up front (got 0)".into());
        }
        let perms = scramble.then(|| Arc::new(digit_permutations(seed, PRIMES.len())));
        Ok(HammersleySampler { seed, n, perms, stream: 0, index: 0, dim: 0, fallback: RandomSampler::new(seed) })
    }
    #[inline]
    fn value(&self, dim: u32) -> f32 {
        let x = if dim == 0 {
            (self.index % self.n) as f64 / self.n as f64
        } else {
            let base = PRIMES[dim as usize - 1];
            match &self.perms {
                Some(p) => scrambled_radical_inverse(base, &p[dim as usize - 1], self.index),
                None => radical_inverse(base, self.index),
            }
        };
        match &self.perms {
            Some(_) => rotate(x, cp_shift(self.seed, self.stream, dim)),
            None => (x as f32).min(crate::math::ONE_MINUS_EPSILON),
        }
    }
}

impl Sampler for HammersleySampler {
    fn name(&self) -> &'static str {
        "hammersley"
    }
    fn start(&mut self, stream: u64, index: u64) {
        self.stream = stream;
        self.index = index;
        self.dim = 0;
        self.fallback.start(stream, index);
    }
    fn set_dimension(&mut self, dim: u32) {
        self.dim = dim;
        if dim as usize > PRIMES.len() {
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
        if (d as usize) <= PRIMES.len() {
            self.value(d)
        } else {
            if d as usize == PRIMES.len() + 1 {
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
        let mut s = HammersleySampler::with_scramble(0, 4, false).unwrap();
        let want = [[0.0, 0.0, 0.0], [0.25, 0.5, 1.0 / 3.0], [0.5, 0.25, 2.0 / 3.0], [0.75, 0.75, 1.0 / 9.0]];
        for (i, w) in want.iter().enumerate() {
            s.start(0, i as u64);
            let g = [s.next_1d(), s.next_1d(), s.next_1d()];
            for k in 0..3 {
                assert!((g[k] - w[k]).abs() < 1e-6, "{g:?} vs {w:?}");
            }
        }
        assert!(HammersleySampler::new(0, 0).is_err());
    }

    #[test]
    fn scrambled_first_dimension_is_stratified() {
        let mut s = HammersleySampler::new(5, 64).unwrap();
        let mut strata = [0u32; 64];
        for i in 0..64 {
            s.start(17, i);
            let v = s.next_1d();
            assert!((0.0..1.0).contains(&v));
            strata[(v * 64.0) as usize] += 1;
        }
        assert!(strata.iter().all(|&c| c == 1), "{strata:?}");
    }
}

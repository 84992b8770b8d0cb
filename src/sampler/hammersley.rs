//! `hammersley`: the Hammersley point set of a known size N. Dimension 0 is i/N,
//! dimension d ≥ 1 the radical inverse in the d-th prime base (2, 3, 5, …), with the
//! same digit permutations and per-stream Cranley–Patterson rotation as `halton`.
//! It needs N up front: building one without a sample count is an error.

use super::halton::{fraction, restart};
use super::radical::DigitTables;
use super::{Sampler, dim_hash, frac_to_f32, stream_key};
use std::sync::Arc;

/// Hammersley sampler over a fixed number of samples per stream.
#[derive(Clone)]
pub struct HammersleySampler {
    seed: u64,
    n: u64,
    tables: Arc<DigitTables>,
    scramble: bool,
    stream: u64,
    key: u64,
    index: u64,
    dim: u32,
}

impl HammersleySampler {
    /// Randomised Hammersley set of `n` points per stream.
    pub fn new(seed: u64, n: u64) -> anyhow::Result<Self> {
        Self::with_scramble(seed, n, true)
    }
    /// With `scramble == false`: the raw point set.
    pub fn with_scramble(seed: u64, n: u64, scramble: bool) -> anyhow::Result<Self> {
        if n == 0 {
            anyhow::bail!("the hammersley sampler needs the number of samples up front (got 0)");
        }
        let tables = Arc::new(DigitTables::new(seed, scramble));
        Ok(HammersleySampler { seed, n, tables, scramble, stream: 0, key: stream_key(seed, 0), index: 0, dim: 0 })
    }
    #[inline]
    fn value(&self, dim: u32) -> f32 {
        self.value_of(self.key, self.index, dim)
    }
    /// Value of dimension `dim` of sample `index` of the stream with key `key`.
    #[inline]
    fn value_of(&self, key: u64, index: u64, dim: u32) -> f32 {
        if dim == 0 {
            // floor((i mod N) / N · 2^32), exact.
            let f = (((index % self.n) as u128) << 32) / self.n as u128;
            let f = f as u32;
            frac_to_f32(if self.scramble { f.wrapping_add((dim_hash(key, 0, 0) >> 32) as u32) } else { f })
        } else {
            frac_to_f32(fraction(&self.tables, self.scramble, key, index, dim as usize - 1, dim))
        }
    }
}

impl Sampler for HammersleySampler {
    fn name(&self) -> &'static str {
        "hammersley"
    }
    #[inline]
    fn start(&mut self, stream: u64, index: u64) {
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
    super::dimension_methods!();
    fn to_any(&self) -> Option<super::AnySampler> {
        Some(super::AnySampler::Hammersley(self.clone()))
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

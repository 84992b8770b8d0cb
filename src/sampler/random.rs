//! `random`: independent uniform numbers from PCG32 (rand_pcg), reseeded from a hash of
//! (seed, stream, index, dimension) at every sample start and dimension jump.

use super::Sampler;
use crate::math::{hash_words, u32_to_unit};
use rand_core::Rng;
use rand_pcg::Pcg32;

/// Independent random sampler.
#[derive(Clone)]
pub struct RandomSampler {
    seed: u64,
    stream: u64,
    index: u64,
    dim: u32,
    rng: Pcg32,
}

impl RandomSampler {
    /// New sampler for a render seed.
    pub fn new(seed: u64) -> Self {
        RandomSampler { seed, stream: 0, index: 0, dim: 0, rng: Pcg32::new(seed, 0) }
    }
    fn reseed(&mut self) {
        let h = hash_words(&[self.seed, self.stream, self.index, self.dim as u64]);
        self.rng = Pcg32::new(h, 0xDA3E_39CB_94B9_5BDB);
    }
}

impl Sampler for RandomSampler {
    fn name(&self) -> &'static str {
        "random"
    }
    fn start(&mut self, stream: u64, index: u64) {
        self.stream = stream;
        self.index = index;
        self.dim = 0;
        self.reseed();
    }
    fn set_dimension(&mut self, dim: u32) {
        self.dim = dim;
        self.reseed();
    }
    fn dimension(&self) -> u32 {
        self.dim
    }
    fn current(&self) -> (u64, u64) {
        (self.stream, self.index)
    }
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.dim = self.dim.saturating_add(1);
        u32_to_unit(self.rng.next_u32())
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
    fn to_any(&self) -> Option<super::AnySampler> {
        Some(super::AnySampler::Random(self.clone()))
    }
    fn values_at(&self, stream: u64, index: u64, dim: u32, out: &mut [f32]) {
        let mut rng = Pcg32::new(hash_words(&[self.seed, stream, index, dim as u64]), 0xDA3E_39CB_94B9_5BDB);
        out.iter_mut().for_each(|o| *o = u32_to_unit(rng.next_u32()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_in_unit_interval_and_reproducible() {
        let mut a = RandomSampler::new(7);
        let mut b = RandomSampler::new(7);
        a.start(3, 4);
        b.start(3, 4);
        for _ in 0..1000 {
            let x = a.next_1d();
            assert!((0.0..1.0).contains(&x));
            assert_eq!(x, b.next_1d());
        }
        a.set_dimension(5);
        let v = a.next_1d();
        a.set_dimension(5);
        assert_eq!(v, a.next_1d());
    }
}

//! Sample generators (plug-ins chosen by name: `random`, `halton`, `hammersley`,
//! `sobol`).
//!
//! Every value is a pure function of (seed, stream, sample index, dimension): a
//! *stream* is a pixel (y·width + x) for the render pass or a light-path id for the
//! photon pass, so images do not depend on thread count or scheduling.
//!
//! Dimension bookkeeping is explicit: integrators call [`Sampler::set_dimension`] with
//! the layout below at the start of every bounce, so that (for example) the light
//! sample of bounce k always uses the same dimensions whatever happened earlier.

pub mod halton;
pub mod hammersley;
pub mod radical;
pub mod random;
pub mod sobol;

use crate::math::mix64;
use anyhow::{Result, bail};

/// Dimensions 0–1: position inside the pixel (box filter).
pub const DIM_PIXEL: u32 = 0;
/// First dimension of bounce 0.
pub const DIM_FIRST_BOUNCE: u32 = 2;
/// Dimensions reserved per bounce (see the `BOUNCE_*` offsets).
pub const DIMS_PER_BOUNCE: u32 = 8;
/// Offset: which light to sample.
pub const BOUNCE_LIGHT_SELECT: u32 = 0;
/// Offset: point on the light (2 dims).
pub const BOUNCE_LIGHT_POINT: u32 = 1;
/// Offset: BSDF lobe choice.
pub const BOUNCE_BSDF_LOBE: u32 = 3;
/// Offset: BSDF direction (2 dims).
pub const BOUNCE_BSDF_DIR: u32 = 4;
/// Offset: Russian-roulette decision.
pub const BOUNCE_RR: u32 = 6;
const _: () = assert!(BOUNCE_RR < DIMS_PER_BOUNCE);

/// First dimension used by bounce `depth` (0 = the camera ray's first hit).
#[inline]
pub fn bounce_dim(depth: u32) -> u32 {
    DIM_FIRST_BOUNCE.saturating_add(depth.saturating_mul(DIMS_PER_BOUNCE))
}

/// A sample generator. Implementations are cheap to clone (tables are shared).
pub trait Sampler: Send + Sync {
    /// Configuration name.
    fn name(&self) -> &'static str;
    /// Starts sample `index` of `stream`; the dimension resets to 0.
    fn start(&mut self, stream: u64, index: u64);
    /// Jumps to dimension `dim` of the current sample.
    fn set_dimension(&mut self, dim: u32);
    /// Current dimension.
    fn dimension(&self) -> u32;
    /// Current (stream, sample index).
    fn current(&self) -> (u64, u64);
    /// Next value in [0, 1); advances the dimension by one.
    fn next_1d(&mut self) -> f32;
    /// Next pair of values; advances the dimension by two.
    #[inline]
    fn next_2d(&mut self) -> [f32; 2] {
        let a = self.next_1d();
        let b = self.next_1d();
        [a, b]
    }
    /// A boxed copy (for per-thread use).
    fn clone_box(&self) -> Box<dyn Sampler>;
    /// A copy by value as an [`AnySampler`], for loops that dispatch statically
    /// ([`with_sampler!`]); `None` for samplers that are not one of [`make`]'s.
    fn to_any(&self) -> Option<AnySampler> {
        None
    }
    /// Values of dimensions `dim..dim + out.len()` of sample `index` of `stream`:
    /// what `start(stream, index)`, `set_dimension(dim)` and `out.len()` calls of
    /// `next_1d` would give, without touching this sampler. The gathers draw their
    /// rays with it from the samplers their context shares between threads, so a
    /// shading point needs no clone (the default here clones; every sampler of
    /// [`make`] overrides it without).
    fn values_at(&self, stream: u64, index: u64, dim: u32, out: &mut [f32]) {
        let mut s = self.clone_box();
        s.start(stream, index);
        s.set_dimension(dim);
        out.iter_mut().for_each(|o| *o = s.next_1d());
    }
}

/// The [`Sampler`] methods of a sampler whose values are a pure function of the
/// dimension (its `value(d)` and `dim` field): dimension bookkeeping, `next_1d`,
/// `next_2d` and `clone_box`. Used inside `impl Sampler for …` by `halton` (with its
/// cached `value_cached(d)`), `hammersley` and `sobol`.
macro_rules! dimension_methods {
    () => {
        $crate::sampler::dimension_methods!(value);
    };
    ($value:ident) => {
        #[inline]
        fn set_dimension(&mut self, dim: u32) {
            self.dim = dim;
        }
        fn dimension(&self) -> u32 {
            self.dim
        }
        #[inline]
        fn next_1d(&mut self) -> f32 {
            let d = self.dim;
            self.dim = self.dim.saturating_add(1);
            self.$value(d)
        }
        #[inline]
        fn next_2d(&mut self) -> [f32; 2] {
            let d = self.dim;
            self.dim = self.dim.saturating_add(2);
            [self.$value(d), self.$value(d.saturating_add(1))]
        }
        fn clone_box(&self) -> Box<dyn Sampler> {
            Box::new(self.clone())
        }
    };
}
pub(crate) use dimension_methods;

/// Key of a (seed, stream) pair, computed once per stream: per-dimension hashes
/// derive from it with one [`mix64`] each (with salt 0, the same hash as the
/// per-(seed, stream, dimension) rotations of earlier versions).
#[inline]
pub(crate) fn stream_key(seed: u64, stream: u64) -> u64 {
    mix64(seed ^ 0xA076_1D64_78BD_642F) ^ mix64(stream.wrapping_add(0xE703_7ED1_A0B4_28DB))
}

/// Hash of (stream key, dimension, salt): one mixing round.
#[inline]
pub(crate) fn dim_hash(key: u64, dim: u32, salt: u64) -> u64 {
    mix64(key ^ (dim as u64).wrapping_mul(0x8EBC_6AF0_9C88_C6E3) ^ salt)
}

/// A 32-bit fixed-point fraction as an f32 in [0, 1) (its 24 high bits, exact).
#[inline]
pub(crate) fn frac_to_f32(x: u32) -> f32 {
    crate::math::u32_to_unit(x)
}

/// First primes, one base per low-discrepancy dimension.
pub const PRIMES: [u32; 64] = [
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97, 101, 103, 107, 109, 113, 127, 131, 137,
    139, 149, 151, 157, 163, 167, 173, 179, 181, 191, 193, 197, 199, 211, 223, 227, 229, 233, 239, 241, 251, 257, 263, 269, 271, 277, 281,
    283, 293, 307, 311,
];

/// Radical inverse of `index` in `base` (van der Corput), exact in f64.
#[inline]
pub fn radical_inverse(base: u32, mut index: u64) -> f64 {
    if base == 2 {
        return (index.reverse_bits() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
    }
    let b = base as u64;
    let inv = 1.0 / base as f64;
    let mut rev: u64 = 0;
    let mut inv_n = 1.0f64;
    while index > 0 {
        let next = index / b;
        let digit = index - next * b;
        rev = rev * b + digit;
        inv_n *= inv;
        index = next;
    }
    (rev as f64 * inv_n).min(1.0 - f64::EPSILON)
}

/// Sampler names.
pub const NAMES: &[&str] = &["random", "halton", "hammersley", "sobol"];

/// Builds a sampler. `count` is the number of samples per stream when known up
/// front (required by `hammersley`).
pub fn make(name: &str, seed: u64, count: Option<u64>) -> Result<Box<dyn Sampler>> {
    Ok(make_any(name, seed, count)?.boxed())
}

/// One sampler of [`make`] by value, for hot loops that run monomorphised per
/// sampler type (static dispatch: no virtual call per dimension, and the digit
/// loops inline into the caller): match it with [`with_sampler!`].
// `halton` carries its stream's 64 rotations (312 bytes): a sampler is made once and
// cloned once per tile or thread, so the size costs nothing and a box would cost a
// pointer chase per value.
#[allow(clippy::large_enum_variant)]
#[derive(Clone)]
pub enum AnySampler {
    /// `random`.
    Random(random::RandomSampler),
    /// `halton`.
    Halton(halton::HaltonSampler),
    /// `hammersley`.
    Hammersley(hammersley::HammersleySampler),
    /// `sobol`.
    Sobol(sobol::SobolSampler),
}

impl AnySampler {
    /// The sampler behind a trait object.
    pub fn boxed(self) -> Box<dyn Sampler> {
        with_sampler!(self, s => Box::new(s))
    }
}

/// `with_sampler!(any, s => expr)`: evaluates `expr` with `s` bound to the concrete
/// sampler inside the [`AnySampler`] `any` (by value, `&` or `&mut`, as `any` is), so
/// `expr` is compiled once per sampler type.
#[macro_export]
macro_rules! with_sampler {
    ($any:expr, $s:ident => $body:expr) => {
        match $any {
            $crate::sampler::AnySampler::Random($s) => $body,
            $crate::sampler::AnySampler::Halton($s) => $body,
            $crate::sampler::AnySampler::Hammersley($s) => $body,
            $crate::sampler::AnySampler::Sobol($s) => $body,
        }
    };
}
pub use with_sampler;

/// [`make`] without the box.
pub fn make_any(name: &str, seed: u64, count: Option<u64>) -> Result<AnySampler> {
    Ok(match name {
        "random" => AnySampler::Random(random::RandomSampler::new(seed)),
        "halton" => AnySampler::Halton(halton::HaltonSampler::new(seed)),
        "sobol" => AnySampler::Sobol(sobol::SobolSampler::new(seed)),
        "hammersley" => match count {
            Some(n) => AnySampler::Hammersley(hammersley::HammersleySampler::new(seed, n)?),
            None => bail!("sampler `hammersley` needs the sample count up front, which is unknown here; use `halton` or `random`"),
        },
        _ => bail!("unknown sampler `{name}` (known: {})", NAMES.join(", ")),
    })
}

/// Checks a sampler name without building it.
pub fn check(name: &str) -> Result<()> {
    if NAMES.contains(&name) { Ok(()) } else { Err(anyhow::anyhow!("unknown sampler `{name}` (known: {})", NAMES.join(", "))) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radical_inverse_known_values() {
        let b2: Vec<f64> = (0..5).map(|i| radical_inverse(2, i)).collect();
        assert_eq!(b2, vec![0.0, 0.5, 0.25, 0.75, 0.125]);
        let b3: Vec<f64> = (0..5).map(|i| radical_inverse(3, i)).collect();
        let want = [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0 / 9.0, 4.0 / 9.0];
        for (a, b) in b3.iter().zip(want) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!((radical_inverse(5, 7) - (2.0 / 5.0 + 1.0 / 25.0)).abs() < 1e-12);
    }

    /// `values_at` of every sampler equals a fresh start, jump and draws, whatever
    /// stream the sampler itself is on, and leaves the sampler as it was.
    #[test]
    fn values_at_equals_start_and_draws() {
        for name in NAMES {
            let mut s = make(name, 11, Some(64)).unwrap();
            s.start(5, 3);
            s.set_dimension(4);
            for (stream, index, dim) in [(5u64, 3u64, 0u32), (5, 7, 2), (9, 0, 0), (9, 63, 5), (123_456, 40, 30), (7, 1 << 33, 1)] {
                let mut got = [0.0f32; 7];
                s.values_at(stream, index, dim, &mut got);
                let mut fresh = make(name, 11, Some(64)).unwrap();
                fresh.start(stream, index);
                fresh.set_dimension(dim);
                let want: Vec<f32> = (0..7).map(|_| fresh.next_1d()).collect();
                assert_eq!(got.to_vec(), want, "{name} stream {stream} index {index} dim {dim}");
                assert_eq!((s.current(), s.dimension()), ((5, 3), 4), "{name}: values_at moved the sampler");
            }
        }
    }

    /// Drawing through [`with_sampler!`] (static dispatch) gives what the boxed
    /// sampler of [`make`] gives, for every sampler.
    #[test]
    fn static_dispatch_draws_equal_the_boxed_sampler() {
        fn draws<S: Sampler + ?Sized>(s: &mut S) -> Vec<f32> {
            let mut v = Vec::new();
            for (stream, index) in [(0u64, 0u64), (7, 3), (u64::MAX - 1, 1000), (123, 63)] {
                s.start(stream, index);
                v.push(s.next_1d());
                v.extend(s.next_2d());
                s.set_dimension(bounce_dim(3));
                v.extend(s.next_2d());
            }
            v
        }
        for name in NAMES {
            let mut any = make_any(name, 5, Some(64)).unwrap();
            let got = with_sampler!(&mut any, s => draws(s));
            let mut boxed = make(name, 5, Some(64)).unwrap();
            assert_eq!(got, draws(boxed.as_mut()), "{name}");
            assert_eq!(any.boxed().name(), *name);
        }
    }

    #[test]
    fn bounce_dims_do_not_overlap() {
        assert_eq!(bounce_dim(0), 2);
        assert_eq!(bounce_dim(1), 2 + DIMS_PER_BOUNCE);
        assert_eq!(bounce_dim(u32::MAX), u32::MAX);
    }
}

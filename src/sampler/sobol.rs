//! `sobol`: Owen-scrambled Sobol' points with Burley's hash-based scrambling
//! (Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)).
//!
//! Dimensions are taken in 4-D groups ("padding"): within a group, the four values
//! are the first four Sobol' dimensions at a shuffled index, each Owen-scrambled
//! with its own seed; groups are independent (their index shuffles and scrambles
//! come from different seeds). The groups follow the camera layout of
//! [`super`]: the pixel position (dimensions 0–1) is one group, and each bounce's
//! eight dimensions are two groups — {light choice, light point (2), lobe} and
//! {BSDF direction (2), roulette, unused} — with every 2-D draw on Sobol' dimensions
//! 0 and 1, which together form a (0, 2)-sequence: stratified in 2-D at every
//! power-of-two prefix.
//!
//! Index shuffling and output scrambling are base-2 nested uniform scrambles
//! approximated by Burley's Laine–Karras-style hash, applied to bit-reversed values.
//! The shuffle keeps every power-of-two-aligned block of sample indices a
//! (0, m, 2)-net. Everything is a pure function of (seed, stream, index, dimension);
//! indices at or above 2^32 hash their high half into the seeds.

use super::{BOUNCE_BSDF_DIR, BOUNCE_BSDF_LOBE, BOUNCE_LIGHT_POINT, BOUNCE_LIGHT_SELECT, BOUNCE_RR};
use super::{DIM_FIRST_BOUNCE, DIMS_PER_BOUNCE, Sampler, dim_hash, frac_to_f32, stream_key};

/// Sobol' lane (0–3) of each of a bounce's eight dimensions, by offset: 2-D draws on
/// lanes 0 and 1 (offsets 0–3 form one group, 4–7 the next).
const LANE_OF_OFFSET: [u32; 8] = [2, 0, 1, 3, 0, 1, 2, 3];
const _: () = assert!(
    DIMS_PER_BOUNCE == 8
        && DIM_FIRST_BOUNCE == 2
        && BOUNCE_LIGHT_SELECT == 0
        && BOUNCE_LIGHT_POINT == 1
        && BOUNCE_BSDF_LOBE == 3
        && BOUNCE_BSDF_DIR == 4
        && BOUNCE_RR == 6
);

/// (group, Sobol' lane) of a sampler dimension.
#[inline]
pub fn group_of(dim: u32) -> (u32, u32) {
    if dim < DIM_FIRST_BOUNCE {
        (0, dim)
    } else {
        let r = dim - DIM_FIRST_BOUNCE;
        (1 + r / 4, LANE_OF_OFFSET[(r % 8) as usize])
    }
}

/// Direction numbers (bit 31 first) of Sobol' dimensions 1–3, from their primitive
/// polynomials x + 1, x² + x + 1, x³ + x + 1 (degree s, inner coefficients a) and
/// initial values m = (1), (1, 3), (1, 3, 1); dimension 0 is the bit reversal.
const fn directions(s: usize, a: u32, m_init: [u32; 3]) -> [u32; 32] {
    let mut m = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        if k < s {
            m[k] = m_init[k];
        } else {
            let mut v = m[k - s] ^ (m[k - s] << s);
            let mut j = 1;
            while j < s {
                if (a >> (s - 1 - j)) & 1 == 1 {
                    v ^= m[k - j] << j;
                }
                j += 1;
            }
            m[k] = v;
        }
        k += 1;
    }
    let mut v = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        v[k] = m[k] << (31 - k);
        k += 1;
    }
    v
}

/// Byte tables of the generator matrices in the bit-reversed domain: for
/// r = reverse(i), `TABLES[d][byte][b]` is the XOR of reverse(v_{31−j}) of dimension
/// d + 1 over the bits j of byte `byte` of r set in `b`, so that the XOR of the four
/// bytes' entries is reverse(Sobol'_{d+1}(i)): the index arrives reversed from the
/// shuffle and the value leaves reversed for the scramble, with no bit reversal.
const fn byte_tables() -> [[[u32; 256]; 4]; 3] {
    let dirs = [directions(1, 0, [1, 0, 0]), directions(2, 1, [1, 3, 0]), directions(3, 1, [1, 3, 1])];
    let mut t = [[[0u32; 256]; 4]; 3];
    let mut d = 0;
    while d < 3 {
        let mut byte = 0;
        while byte < 4 {
            let mut b = 0;
            while b < 256 {
                let mut x = 0u32;
                let mut bit = 0;
                while bit < 8 {
                    if (b >> bit) & 1 == 1 {
                        x ^= dirs[d][31 - (byte * 8 + bit)].reverse_bits();
                    }
                    bit += 1;
                }
                t[d][byte][b] = x;
                b += 1;
            }
            byte += 1;
        }
        d += 1;
    }
    t
}

static TABLES: [[[u32; 256]; 4]; 3] = byte_tables();

/// reverse(Sobol' dimension `lane` (0–3) of index reverse(`r`)), 32-bit fractions.
#[inline]
fn sobol_reversed(lane: u32, r: u32) -> u32 {
    if lane == 0 {
        return r.reverse_bits();
    }
    let t = &TABLES[(lane - 1) as usize & 3];
    let b = r.to_le_bytes();
    t[0][b[0] as usize] ^ t[1][b[1] as usize] ^ t[2][b[2] as usize] ^ t[3][b[3] as usize]
}

/// Unscrambled Sobol' dimension `lane` (0–3) of a 32-bit index, as a 32-bit fraction.
#[inline]
pub fn sobol_fraction(lane: u32, i: u32) -> u32 {
    sobol_reversed(lane, i.reverse_bits()).reverse_bits()
}

/// A 32-bit integer hash (two multiply–xorshift rounds).
#[inline]
fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846C_A68B);
    x ^ (x >> 16)
}

/// Burley's hash permutation of bit-reversed values: flips each bit by a function
/// of the bits below it (the Laine–Karras construction with better constants).
#[inline]
fn lk_permutation(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3D20_ADEA);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6C56);
    x ^= x.wrapping_mul(0x53A2_2864);
    x
}

/// Base-2 nested uniform (Owen) scramble of a fraction: each bit flipped by a hash of
/// the bits above it.
#[inline]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    lk_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// Sobol' sampler.
#[derive(Clone)]
pub struct SobolSampler {
    seed: u64,
    scramble: bool,
    stream: u64,
    /// High half of the sample index (hashed into the key).
    high: u64,
    key: u64,
    index: u32,
    dim: u32,
    /// Last group evaluated (u32::MAX: none) with its reversed shuffled index and
    /// lane-seed base: a cache, so values stay a pure function of the inputs.
    group: u32,
    shuffled: u32,
    lane_seeds: [u32; 4],
    /// Bit-reversed sample index.
    rindex: u32,
    /// False only for the statistical suite's planted control (see
    /// [`SobolSampler::planted_unnested`]).
    nested: bool,
}

impl SobolSampler {
    /// Owen-scrambled, shuffled Sobol' sampler for a render seed.
    pub fn new(seed: u64) -> Self {
        Self::with_scramble(seed, true)
    }
    /// With `scramble == false`: the plain Sobol' points, every group the same.
    pub fn with_scramble(seed: u64, scramble: bool) -> Self {
        SobolSampler {
            seed,
            scramble,
            stream: 0,
            high: 0,
            key: stream_key(seed, 0),
            index: 0,
            dim: 0,
            group: u32::MAX,
            shuffled: 0,
            lane_seeds: [0; 4],
            rindex: 0,
            nested: true,
        }
    }
    /// Planted defect for `photonlab stats` (not a plug-in): the output scramble
    /// hashes each bit from the bits *below* it (no bit reversal), which is a
    /// bijection but not a nested scramble, so it breaks the nets.
    pub fn planted_unnested(seed: u64) -> Self {
        SobolSampler { nested: false, ..Self::new(seed) }
    }
    #[inline(always)]
    fn value(&mut self, dim: u32) -> f32 {
        let (g, lane) = group_of(dim);
        if !self.scramble {
            return frac_to_f32(sobol_fraction(lane, self.index));
        }
        if g != self.group {
            // Index shuffle of the group: an Owen scramble of the index, kept reversed.
            let h = dim_hash(self.key, g, 0x2545_F491_4F6C_DD1D);
            self.group = g;
            self.shuffled = lk_permutation(self.rindex, h as u32);
            let base = (h >> 32) as u32;
            self.lane_seeds = [0u32, 1, 2, 3].map(|l| hash32(base ^ l.wrapping_mul(0x9E37_79B9)));
        }
        let y = sobol_reversed(lane, self.shuffled);
        let seed = self.lane_seeds[lane as usize & 3];
        let z = if self.nested { lk_permutation(y, seed).reverse_bits() } else { lk_permutation(y.reverse_bits(), seed) };
        frac_to_f32(z)
    }
}

impl Sampler for SobolSampler {
    fn name(&self) -> &'static str {
        "sobol"
    }
    #[inline]
    fn start(&mut self, stream: u64, index: u64) {
        let high = index >> 32;
        if self.stream != stream || self.high != high {
            self.stream = stream;
            self.high = high;
            self.key = stream_key(self.seed ^ high.wrapping_mul(0xC2B2_AE3D_27D4_EB4F), stream);
        }
        self.index = index as u32;
        self.rindex = self.index.reverse_bits();
        self.dim = 0;
        self.group = u32::MAX;
    }
    fn current(&self) -> (u64, u64) {
        (self.stream, (self.high << 32) | self.index as u64)
    }
    fn values_at(&self, stream: u64, index: u64, dim: u32, out: &mut [f32]) {
        // A copy on the stack (no shared tables to count references to).
        let mut s = self.clone();
        s.start(stream, index);
        s.dim = dim;
        out.iter_mut().for_each(|o| *o = s.next_1d());
    }
    super::dimension_methods!();
    fn to_any(&self) -> Option<super::AnySampler> {
        Some(super::AnySampler::Sobol(self.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_sobol_first_values() {
        // Worked by hand from the direction numbers m = 1, 3, 5 (x + 1), 1, 3, 3
        // (x² + x + 1), 1, 3, 1 (x³ + x + 1): point i is the XOR of m_k / 2^k over
        // the set bits k of i.
        let want: [[f32; 4]; 8] = [
            [0.0, 0.0, 0.0, 0.0],
            [0.5, 0.5, 0.5, 0.5],
            [0.25, 0.75, 0.75, 0.75],
            [0.75, 0.25, 0.25, 0.25],
            [0.125, 0.625, 0.375, 0.125],
            [0.625, 0.125, 0.875, 0.625],
            [0.375, 0.375, 0.625, 0.875],
            [0.875, 0.875, 0.125, 0.375],
        ];
        for (i, w) in want.iter().enumerate() {
            for lane in 0..4 {
                let got = sobol_fraction(lane, i as u32) as f64 / 4_294_967_296.0;
                assert_eq!(got as f32, w[lane as usize], "index {i} lane {lane}");
            }
        }
    }

    #[test]
    fn groups_follow_the_layout() {
        assert_eq!(group_of(0), (0, 0));
        assert_eq!(group_of(1), (0, 1));
        let b = super::super::bounce_dim(3);
        assert_eq!(group_of(b + BOUNCE_LIGHT_POINT), (group_of(b).0, 0));
        assert_eq!(group_of(b + BOUNCE_LIGHT_POINT + 1), (group_of(b).0, 1));
        assert_eq!(group_of(b + BOUNCE_BSDF_DIR), (group_of(b).0 + 1, 0));
        assert_eq!(group_of(b + BOUNCE_BSDF_DIR + 1), (group_of(b).0 + 1, 1));
        assert_eq!(group_of(b + BOUNCE_RR).0, group_of(b).0 + 1);
        assert_eq!(group_of(u32::MAX).0, 1 + (u32::MAX - 2) / 4);
    }

    #[test]
    fn scrambled_pairs_are_stratified_at_every_power_of_two() {
        let mut s = SobolSampler::new(11);
        for dim in [0u32, super::super::bounce_dim(2) + BOUNCE_LIGHT_POINT, super::super::bounce_dim(0) + BOUNCE_BSDF_DIR] {
            for m in [2u32, 4, 6, 8] {
                let n = 1usize << m;
                // Elementary intervals 2^a × 2^(m−a) each hold one point.
                for a in 0..=m {
                    let (nx, ny) = (1usize << a, 1usize << (m - a));
                    let mut seen = vec![0u32; n];
                    for i in 0..n as u64 {
                        s.start(77, i);
                        s.set_dimension(dim);
                        let [x, y] = s.next_2d();
                        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                        seen[(x * nx as f32) as usize * ny + (y * ny as f32) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "dim {dim} m {m} a {a}");
                }
            }
        }
    }

    #[test]
    fn pure_function_of_its_inputs() {
        let mut a = SobolSampler::new(5);
        let mut b = SobolSampler::new(5);
        a.start(3, 9);
        let first: Vec<f32> = (0..40).map(|_| a.next_1d()).collect();
        // Another stream in between, then jump straight to dimension 17.
        b.start(4, 9);
        b.next_1d();
        b.start(3, 9);
        b.set_dimension(17);
        assert_eq!(b.next_1d(), first[17]);
        b.set_dimension(10);
        let [x, y] = b.next_2d();
        assert_eq!([x, y], [first[10], first[11]]);
        // Indices past 2^32 still give values in range, different from index 9.
        a.start(3, (1 << 32) + 9);
        let far = a.next_1d();
        assert!((0.0..1.0).contains(&far) && far != first[0]);
    }
}

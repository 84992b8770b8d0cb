//! Scrambled radical inverses for `halton` and `hammersley`, built once per seed.
//!
//! Every prime base gets one random permutation of its digits (the same at every
//! digit position, applied also to the infinite tail of leading zeros, whose value
//! `perm[0] / (b − 1)` is precomputed). Evaluation visits only the digits of the
//! index, divides by multiplying with a precomputed reciprocal (exact for indices
//! below 2^32; larger ones fall back to plain division), allocates nothing and
//! returns a 32-bit fixed-point fraction, so a Cranley–Patterson rotation is one
//! wrapping addition. The fractions of the first [`SMALL`] indices are kept in a table
//! (index-major: one sample's dimensions are adjacent), so the sample indices of a
//! render pass (below the sample count per pixel) are one load each.

use super::PRIMES;
use crate::math::mix64;

#[derive(Clone, Copy, Debug)]
struct Base {
    base: u32,
    /// ceil(2^64 / base): `(i · magic) >> 64 == i / base` for every i < 2^32.
    magic: u64,
    inv_base: f64,
    /// Value of the infinite tail of permuted zero digits, in units of the last digit.
    tail: f64,
    /// Offset of this base's permutation in [`DigitTables::perms`].
    at: u32,
    /// Base 2 with the permutation that swaps 0 and 1 (a bitwise complement).
    flip: bool,
}

/// Indices whose fractions [`DigitTables`] keeps (all bases): 256 KiB.
pub const SMALL: u64 = 1024;

/// Digit permutations of the first [`PRIMES`] bases for one seed.
#[derive(Clone, Debug)]
pub struct DigitTables {
    bases: Vec<Base>,
    perms: Vec<u16>,
    /// `fraction(k, i)` at `i * bases.len() + k` for every i < [`SMALL`].
    small: Vec<u32>,
}

impl DigitTables {
    /// Random permutations from `seed`; `scramble == false` keeps every digit
    /// (identity permutations: the plain radical inverse).
    pub fn new(seed: u64, scramble: bool) -> Self {
        let mut bases = Vec::with_capacity(PRIMES.len());
        let mut perms = Vec::new();
        for (d, &b) in PRIMES.iter().enumerate() {
            let mut p: Vec<u16> = (0..b as u16).collect();
            if scramble {
                let mut s = mix64(seed ^ (d as u64).wrapping_mul(0x9E37_79B9));
                for i in (1..b as usize).rev() {
                    s = mix64(s);
                    p.swap(i, (s % (i as u64 + 1)) as usize);
                }
            }
            bases.push(Base {
                base: b,
                magic: u64::MAX / b as u64 + 1,
                inv_base: 1.0 / b as f64,
                tail: p[0] as f64 / (b - 1) as f64,
                at: perms.len() as u32,
                flip: b == 2 && p[0] == 1,
            });
            perms.extend_from_slice(&p);
        }
        let mut t = DigitTables { bases, perms, small: Vec::new() };
        let n = t.bases.len();
        t.small = (0..SMALL as usize * n).map(|j| t.digits(j % n, (j / n) as u64)).collect();
        t
    }

    /// Number of bases (dimensions) covered.
    pub fn len(&self) -> usize {
        self.bases.len()
    }

    /// True when no base is covered (never, for tables built by [`DigitTables::new`]).
    pub fn is_empty(&self) -> bool {
        self.bases.is_empty()
    }

    /// Scrambled radical inverse of `index` in base `PRIMES[k]` as a 32-bit fraction
    /// (rounded down). `k < self.len()`.
    #[inline(always)]
    pub fn fraction(&self, k: usize, index: u64) -> u32 {
        if index < SMALL {
            return self.small[index as usize * self.bases.len() + k];
        }
        self.digits(k, index)
    }

    /// [`DigitTables::fraction`] computed from the digits of `index`.
    #[inline(never)]
    fn digits(&self, k: usize, index: u64) -> u32 {
        let b = self.bases[k];
        if b.base == 2 {
            let x = (index.reverse_bits() >> 32) as u32;
            return if b.flip { !x } else { x };
        }
        let perm = &self.perms[b.at as usize..b.at as usize + b.base as usize];
        let base = b.base as u64;
        let (mut rev, mut inv_n) = (0u64, 1.0f64);
        let mut i = index;
        if i < 1 << 32 {
            while i > 0 {
                let q = ((i as u128 * b.magic as u128) >> 64) as u64;
                let digit = (i - q * base) as usize;
                rev = rev * base + perm[digit] as u64;
                inv_n *= b.inv_base;
                i = q;
            }
        } else {
            while i > 0 {
                let q = i / base;
                let digit = (i - q * base) as usize;
                rev = rev.wrapping_mul(base).wrapping_add(perm[digit] as u64);
                inv_n *= b.inv_base;
                i = q;
            }
        }
        // Saturating cast: a value that rounds to 1 becomes the largest fraction.
        ((rev as f64 + b.tail) * inv_n * 4_294_967_296.0) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::radical_inverse;

    /// The kept fractions are the computed ones, bit for bit (and indices past the
    /// table are computed).
    #[test]
    fn kept_fractions_equal_computed_ones() {
        for (seed, scramble) in [(0, false), (7, true)] {
            let t = DigitTables::new(seed, scramble);
            assert_eq!(t.small.len(), SMALL as usize * PRIMES.len());
            for (k, base) in PRIMES.iter().enumerate() {
                for i in (0..SMALL).step_by(7).chain([SMALL - 1]) {
                    assert_eq!(t.fraction(k, i), t.digits(k, i), "base {base} index {i}");
                }
                assert_eq!(t.fraction(k, SMALL), t.digits(k, SMALL));
            }
        }
    }

    #[test]
    fn identity_tables_match_the_plain_radical_inverse() {
        let t = DigitTables::new(0, false);
        for k in [0usize, 1, 2, 5, 63] {
            for i in (0..2000u64).chain([(1 << 32) - 1, 1 << 32, 123_456_789_012]) {
                let want = (radical_inverse(PRIMES[k], i) * 4_294_967_296.0) as u32;
                let got = t.fraction(k, i);
                assert!(got.abs_diff(want) <= 2, "base {} index {i}: {got} vs {want}", PRIMES[k]);
            }
        }
    }

    #[test]
    fn scrambled_digits_stay_stratified_and_include_the_tail() {
        let t = DigitTables::new(9, true);
        for k in [1usize, 2, 3] {
            let b = PRIMES[k] as usize;
            // The first b^2 indices have every pair of leading digits exactly once.
            let mut seen = vec![0u32; b * b];
            for i in 0..(b * b) as u64 {
                let f = t.fraction(k, i) as f64 / 4_294_967_296.0;
                // A tail of (b − 1) digits carries into the next stratum: count modulo b².
                seen[(f * (b * b) as f64 + 1e-6) as usize % (b * b)] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "base {b}: {seen:?}");
            // Index 0 is the tail alone: perm[0] / (b − 1).
            let want = t.bases[k].tail;
            assert!((t.fraction(k, 0) as f64 / 4_294_967_296.0 - want).abs() < 1e-9);
        }
    }
}

//! Hash grid over a pass's light vertices for vertex merging (as SmallVCM's
//! `HashGrid`): cells of edge 2r hashed into as many buckets as there are points,
//! filled by a stable counting sort, so each bucket lists its points in input order
//! and every query visits them in the same order for any thread count.
//!
//! The grid keeps, in bucket order, a 16-byte key per point (its position and its
//! index), so the radius test of a candidate reads that key in sequence instead of
//! the 120-byte light vertex at a random place (as `sppm`'s photon grid keeps
//! positions apart); only points within the radius are looked up. The bucket of a
//! cell is its hash modulo the point count, taken with Lemire's exact multiply-shift
//! remainder instead of a division (eight per query).

use crate::photon::nearest::{prefetch, prefetch_all};
use glam::Vec3;
use std::ops::Range;

/// What the radius test reads of a stored point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Key {
    /// Position.
    pub p: Vec3,
    /// Index of the point in the input.
    pub index: u32,
}

/// Points bucketed by cell, their keys in bucket order.
#[derive(Clone, Debug, Default)]
pub struct HashGrid {
    cell: f32,
    lo: Vec3,
    /// Buckets (the point count, at least 1).
    buckets: u32,
    /// ⌊2⁶⁴ / buckets⌋ + 1, for [`fast_mod`].
    magic: u64,
    starts: Vec<u32>,
    keys: Vec<Key>,
    /// Bucket of each input point (build scratch, kept for reuse).
    scratch: Vec<u32>,
}

/// a mod d for any 32-bit a and d ≥ 1, with `magic` = ⌊(2⁶⁴ − 1) / d⌋ + 1 mod 2⁶⁴ (Lemire,
/// Kaser & Kurz, "Faster remainder by direct computation", 2019: exact for 32-bit
/// operands).
#[inline]
fn fast_mod(a: u32, d: u32, magic: u64) -> u32 {
    let low = magic.wrapping_mul(a as u64);
    ((low as u128 * d as u128) >> 64) as u32
}

impl HashGrid {
    /// Rebuilds the grid over `points` (in input order) for queries of radius `r`,
    /// reusing its buffers.
    pub fn build(&mut self, points: &[Vec3], r: f32) {
        let n = points.len();
        assert!(n < u32::MAX as usize, "too many points for one grid ({n})");
        let mut lo = Vec3::splat(f32::INFINITY);
        for &p in points {
            lo = lo.min(p);
        }
        self.cell = 2.0 * r;
        self.lo = lo;
        self.buckets = (n as u32).max(1);
        self.magic = (u64::MAX / self.buckets as u64).wrapping_add(1);
        self.starts.clear();
        self.starts.resize(n + 1, 0);
        self.keys.clear();
        if n == 0 || r.is_nan() || r <= 0.0 {
            return;
        }
        self.scratch.clear();
        for &p in points {
            let b = self.bucket(self.cell_of(p));
            self.scratch.push(b);
            self.starts[b as usize + 1] += 1;
        }
        for i in 0..n {
            self.starts[i + 1] += self.starts[i];
        }
        self.keys.resize(n, Key::default());
        // Scatter in input order, advancing each bucket's start; afterwards bucket b's
        // start is where b + 1's began, so shifting the starts back restores them.
        for (i, (&p, &b)) in points.iter().zip(&self.scratch).enumerate() {
            let slot = &mut self.starts[b as usize];
            self.keys[*slot as usize] = Key { p, index: i as u32 };
            *slot += 1;
        }
        self.starts.copy_within(0..n, 1);
        self.starts[0] = 0;
    }

    /// Points stored.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True when no point is stored.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The keys of `slots` (a range [`HashGrid::for_each_bucket`] hands out).
    #[inline]
    pub fn keys(&self, slots: Range<usize>) -> &[Key] {
        &self.keys[slots]
    }

    #[inline]
    fn cell_of(&self, p: Vec3) -> [i32; 3] {
        let c = ((p - self.lo) / self.cell).floor();
        [c.x as i32, c.y as i32, c.z as i32]
    }

    #[inline]
    fn bucket(&self, c: [i32; 3]) -> u32 {
        let h = (c[0] as u32).wrapping_mul(73_856_093) ^ (c[1] as u32).wrapping_mul(19_349_663) ^ (c[2] as u32).wrapping_mul(83_492_791);
        fast_mod(h, self.buckets, self.magic)
    }

    /// Calls `f` with the slots (for [`HashGrid::keys`]) of the buckets of every cell
    /// that the ball of radius r (the build radius) around `p` touches: a superset of
    /// the points within r, each once, buckets in increasing order and each bucket's
    /// points in input order.
    #[inline]
    pub fn for_each_bucket(&self, p: Vec3, mut f: impl FnMut(Range<usize>)) {
        if self.keys.is_empty() {
            return;
        }
        let r = 0.5 * self.cell;
        let (a, b) = (self.cell_of(p - Vec3::splat(r)), self.cell_of(p + Vec3::splat(r)));
        let mut buckets = [0u32; 8];
        let mut n = 0;
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    if n < 8 {
                        buckets[n] = self.bucket([x, y, z]);
                        n += 1;
                    }
                }
            }
        }
        let buckets = &mut buckets[..n];
        for &bk in buckets.iter() {
            prefetch(&self.starts[bk as usize]);
        }
        buckets.sort_unstable();
        // Their keys' first lines too, once the starts are in.
        let mut last = u32::MAX;
        for &bk in buckets.iter() {
            if bk != last
                && let Some(key) = self.keys.get(self.starts[bk as usize] as usize)
            {
                prefetch_all(key);
            }
            last = bk;
        }
        let mut last = u32::MAX;
        for &bk in buckets.iter() {
            if bk == last {
                continue;
            }
            last = bk;
            f(self.starts[bk as usize] as usize..self.starts[bk as usize + 1] as usize);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The multiply-shift remainder equals `%` (edge operands and random ones).
    #[test]
    fn fast_mod_is_the_remainder() {
        let mut s = 3u64;
        let mut ds = vec![1u32, 2, 3, 7, 1000, 4095, 4096, 65_537, u32::MAX - 1, u32::MAX];
        let mut r#as = vec![0u32, 1, 2, u32::MAX, u32::MAX - 1, 1 << 31];
        for _ in 0..200 {
            s = crate::math::mix64(s);
            ds.push((s >> 32) as u32 >> (s % 31) | 1);
            r#as.push(s as u32);
        }
        for &d in &ds {
            let magic = (u64::MAX / d as u64).wrapping_add(1);
            for &a in &r#as {
                assert_eq!(fast_mod(a, d, magic), a % d, "{a} mod {d}");
            }
        }
    }

    /// Every point within the radius is visited exactly once, points of one bucket in
    /// input order, and a rebuild over fewer points (buffers reused) forgets the old ones.
    #[test]
    fn finds_every_point_within_the_radius_once() {
        let mut s = 7u64;
        let mut rnd = || {
            s = crate::math::mix64(s);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut g = HashGrid::default();
        for count in [2000usize, 300] {
            let pts: Vec<Vec3> = (0..count).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
            let r = 0.05;
            g.build(&pts, r);
            assert_eq!(g.len(), count);
            for _ in 0..200 {
                let q = Vec3::new(rnd(), rnd(), rnd());
                let mut got = Vec::new();
                g.for_each_bucket(q, |slots| {
                    let keys = g.keys(slots);
                    assert!(keys.windows(2).all(|w| w[0].index < w[1].index), "a bucket out of input order");
                    for k in keys {
                        assert_eq!(k.p, pts[k.index as usize]);
                        if k.p.distance_squared(q) <= r * r {
                            got.push(k.index)
                        }
                    }
                });
                let mut sorted = got.clone();
                sorted.sort_unstable();
                sorted.dedup();
                assert_eq!(sorted.len(), got.len(), "a point reported twice");
                let want: Vec<u32> = (0..count as u32).filter(|&i| pts[i as usize].distance_squared(q) <= r * r).collect();
                assert_eq!(sorted, want);
            }
        }
    }
}

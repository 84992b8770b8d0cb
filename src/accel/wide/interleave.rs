//! Closest hits of a stream of rays, K of them traversed at once: each step advances
//! every ray in flight by one node or leaf, round robin, so the memory fetches of K
//! independent rays overlap where one ray alone would wait on each node in turn.
//! Each ray takes exactly the single-ray traversal's path (same order, same culling,
//! same ties), so the hits are those of [`crate::accel::Accel::intersect`] bit for bit.
//! Float nodes only (the quantised tree traces one ray at a time). An AVX-512 CPU runs
//! the AVX2 stream: its single-ray traversal uses the same node test and the same
//! ordering of hit children, so the path is the same.

use super::WideBvh;
use super::cpu::{AVX2, PORTABLE, Simd};
use super::node::LEAF;
use super::ray::{ROBUST, RayPre, traceable};
use super::stack::{Items, Stack, items};
use super::traverse::STACK;
use crate::accel::{Accel, TraversalStats};
use crate::geometry::{Hit, Ray};

/// One ray in flight.
struct Lane {
    r: RayPre,
    ray: Ray,
    best: Option<Hit>,
    t_best: f32,
    stack: Stack<Items<STACK>>,
    cur: u32,
    /// Index of the ray in the stream.
    idx: usize,
    node_tests: u64,
    tri_tests: u64,
}

/// The next ray of the stream to put in flight, answering the untraceable ones on
/// the way (no hit, as the single-ray traversal answers them).
#[inline(always)]
fn claim(rays: &[(Ray, f32)], out: &mut [Option<Hit>], next: &mut usize) -> Option<usize> {
    while *next < rays.len() {
        let idx = *next;
        *next += 1;
        if traceable(&rays[idx].0) {
            return Some(idx);
        }
        out[idx] = None;
    }
    None
}

impl<const N: usize> WideBvh<N> {
    /// Closest hits of `rays` (each with its own t_max) into `out`, `k` rays in flight
    /// (1, 2, 4 or 8; others trace one at a time).
    pub(super) fn interleaved(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], k: usize, stats: &mut TraversalStats) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        let interleaved = !self.quant && !self.nodes.is_empty();
        match (interleaved, k) {
            (true, 2) => self.stream_level::<2>(rays, out, stats),
            (true, 4) => self.stream_level::<4>(rays, out, stats),
            (true, 8) => self.stream_level::<8>(rays, out, stats),
            _ => {
                for ((ray, t_max), o) in rays.iter().zip(out.iter_mut()) {
                    *o = self.intersect(ray, *t_max, stats);
                }
            }
        }
    }

    fn stream_level<const K: usize>(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], stats: &mut TraversalStats) {
        #[cfg(target_arch = "x86_64")]
        if self.simd != Simd::Portable {
            // SAFETY: `simd` names only a level the CPU reported (`detect_simd`), and
            // AVX-512 CPUs have AVX2 and FMA.
            return unsafe { self.stream_avx2::<K>(rays, out, stats) };
        }
        self.stream_impl::<K, PORTABLE>(rays, out, stats)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1,bmi2")]
    fn stream_avx2<const K: usize>(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], stats: &mut TraversalStats) {
        self.stream_impl::<K, AVX2>(rays, out, stats)
    }

    /// Puts ray `idx` into `lane` (in place: the stack is not moved).
    #[inline(always)]
    fn start<const L: u8>(&self, lane: &mut Lane, rays: &[(Ray, f32)], idx: usize) {
        let (ray, t_max) = rays[idx];
        lane.r = self.ray_pre::<L, false>(&ray);
        lane.ray = ray;
        lane.best = None;
        lane.t_best = t_max;
        lane.stack.clear();
        lane.cur = 0;
        lane.idx = idx;
        lane.node_tests = 0;
        lane.tri_tests = 0;
    }

    #[inline(always)]
    fn stream_impl<const K: usize, const L: u8>(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], stats: &mut TraversalStats) {
        stats.rays += rays.len() as u64;
        let placeholder = Ray::new(glam::Vec3::ZERO, glam::Vec3::X);
        let mut lanes: [Lane; K] = std::array::from_fn(|_| Lane {
            r: RayPre::new::<N>(&placeholder),
            ray: placeholder,
            best: None,
            t_best: 0.0,
            stack: Stack::new(items()),
            cur: 0,
            idx: 0,
            node_tests: 0,
            tri_tests: 0,
        });
        let mut active = [false; K];
        let mut next = 0usize;
        for (lane, a) in lanes.iter_mut().zip(active.iter_mut()) {
            if let Some(idx) = claim(rays, out, &mut next) {
                self.start::<L>(lane, rays, idx);
                *a = true;
            }
        }
        let mut live = active.iter().filter(|a| **a).count();
        let mut tmin = [0.0f32; N];
        while live > 0 {
            for (lane, a) in lanes.iter_mut().zip(active.iter_mut()) {
                if !*a || self.step::<L>(lane, &mut tmin) {
                    continue;
                }
                out[lane.idx] = lane.best;
                // Counted in the lane's memory either way (no registers to spare
                // here), reported only when asked, as by the single-ray traversal.
                if stats.count_work {
                    stats.node_tests += lane.node_tests;
                    stats.tri_tests += lane.tri_tests;
                }
                if let Some(idx) = claim(rays, out, &mut next) {
                    self.start::<L>(lane, rays, idx);
                } else {
                    *a = false;
                    live -= 1;
                }
            }
        }
    }

    /// One node or leaf of one ray (the body of the single-ray loop in `traverse`);
    /// false when the ray is finished.
    #[inline(always)]
    fn step<const L: u8>(&self, s: &mut Lane, tmin: &mut [f32; N]) -> bool {
        if s.cur & LEAF == 0 {
            let (mut mask, child) = self.visit::<L, false>(s.cur, &s.r, s.t_best, tmin);
            s.node_tests += N as u64;
            if mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if mask == 0 {
                    s.cur = child[i];
                    self.prefetch::<false>(s.cur);
                    return true;
                }
                let j = mask.trailing_zeros() as usize;
                if mask & (mask - 1) == 0 {
                    self.prefetch::<false>(child[i]);
                    self.prefetch::<false>(child[j]);
                    let (near, far) = if tmin[j] < tmin[i] { (j, i) } else { (i, j) };
                    s.stack.push((child[far], tmin[far]));
                    s.cur = child[near];
                    return true;
                }
                s.cur = self.order_many::<L, false>(i, mask, tmin, child, &mut s.stack);
                return true;
            }
        } else {
            s.tri_tests += self.leaf_closest(s.cur, s.ray.o, s.ray.d, &mut s.t_best, &mut s.best);
        }
        loop {
            match s.stack.pop() {
                None => return false,
                Some((c, t)) if t <= s.t_best * ROBUST + s.r.slack => {
                    s.cur = c;
                    return true;
                }
                Some(_) => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::trees_at_every_level;
    use crate::accel::TraversalStats;
    use crate::geometry::Ray;
    use glam::Vec3;

    fn rnd(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Every level this CPU runs (and the portable one), bvh4, bvh8 and bvh8q: a stream
    /// with 1–8 rays in flight gives the single-ray hits and traversal counts.
    #[test]
    fn interleaved_hits_equal_single_ray_hits() {
        let mut seed = 7u64;
        let v = |s: &mut u64| Vec3::new(rnd(s), rnd(s), rnd(s)) * 10.0;
        let tris: Vec<[Vec3; 3]> = (0..3000)
            .map(|_| {
                let c = v(&mut seed);
                let e = |s: &mut u64| Vec3::new(rnd(s) - 0.5, rnd(s) - 0.5, rnd(s) - 0.5) * 1.5;
                [c, c + e(&mut seed), c + e(&mut seed)]
            })
            .collect();
        let rays: Vec<(Ray, f32)> = (0..4000)
            .map(|i| {
                let o = v(&mut seed);
                let d = Vec3::new(rnd(&mut seed) - 0.5, rnd(&mut seed) - 0.5, rnd(&mut seed) - 0.5).normalize();
                (Ray::new(o, d), if i % 3 == 0 { 2.0 } else { f32::INFINITY })
            })
            .collect();
        for (simd, bvh) in trees_at_every_level(&tris) {
            let mut st = TraversalStats::counting_work();
            let single: Vec<_> = rays.iter().map(|(r, t)| bvh.intersect(r, *t, &mut st)).collect();
            assert!(single.iter().filter(|h| h.is_some()).count() > 1000);
            assert!(st.node_tests > 0 && st.tri_tests > 0, "{st:?}");
            for k in [1, 2, 3, 4, 8] {
                let mut out = vec![None; rays.len()];
                let mut s2 = TraversalStats::counting_work();
                bvh.intersect_stream(&rays, &mut out, k, &mut s2);
                assert_eq!(out, single, "{} {simd:?} k = {k}", bvh.name());
                assert_eq!(s2, st, "{} {simd:?} k = {k}: same node and triangle tests", bvh.name());
            }
        }
    }
}

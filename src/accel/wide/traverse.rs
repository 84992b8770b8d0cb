//! The closest-hit and any-hit traversals, one generic loop compiled once per SIMD
//! level (portable, AVX2, AVX-512), and the [`Accel`] implementation that picks the
//! level chosen at build time.

use super::cpu::{AVX2, AVX512, PORTABLE, Simd};
use super::node::{LEAF, Node, node_index};
use super::node_test::{node_test, qnode_test};
use super::qnode::QNode;
use super::ray::{ROBUST, RayPre, traceable};
use super::stack::{Entry, Stack, items};
use super::tri_block::TriBlock;
#[cfg(target_arch = "x86_64")]
use super::x86;
use super::{MAX_DEPTH, WideBvh};
use crate::accel::{Accel, TraversalStats, replaces, test_limit};
use crate::geometry::{Hit, Ray};
use glam::Vec3;
use std::mem::MaybeUninit;

/// Stack capacity for the widest tree (N = 8).
pub(super) const STACK: usize = 7 * MAX_DEPTH + 8;

/// The closest-hit and any-hit entry points of one traversal level, compiled with
/// that level's target features (the `#[inline(always)]` traversal is compiled
/// into each), one function per counting choice W.
macro_rules! simd_entries {
    ($intersect:ident, $occluded:ident, $level:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $intersect<const W: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
            if self.quant {
                self.intersect_impl::<$level, true, W>(ray, t_max, stats)
            } else {
                self.intersect_impl::<$level, false, W>(ray, t_max, stats)
            }
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
            if self.quant {
                self.occluded_impl::<$level, true>(ray, t_max, stats)
            } else {
                self.occluded_impl::<$level, false>(ray, t_max, stats)
            }
        }
    };
}

/// Calls `$f::<W>` with the counting choice of `$stats`.
macro_rules! counting {
    ($bvh:expr, $f:ident, $ray:expr, $t_max:expr, $stats:expr) => {
        if $stats.count_work { $bvh.$f::<true>($ray, $t_max, $stats) } else { $bvh.$f::<false>($ray, $t_max, $stats) }
    };
}

impl<const N: usize> WideBvh<N> {
    /// The closest-hit traversal at SIMD level L, on quantised nodes if Q, counting
    /// box and triangle tests if W.
    #[inline(always)]
    fn intersect_impl<const L: u8, const Q: bool, const W: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        stats.rays += 1;
        if (self.nodes.is_empty() && self.qnodes.is_empty()) || !traceable(ray) {
            return None;
        }
        let r = self.ray_pre::<L, Q>(ray);
        let (o, d) = (ray.o, ray.d);
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        let mut store = items::<STACK>();
        let mut stack = Stack::new(&mut store);
        let mut cur = 0u32;
        let mut tmin = [0.0f32; N];
        // Counted locally (kept in registers), added to `stats` on return; without W
        // they stay 0 and take no register.
        let (mut node_tests, mut tri_tests) = (0u64, 0u64);
        loop {
            if cur & LEAF == 0 {
                let (mut mask, child) = self.visit::<L, Q>(cur, &r, t_best, &mut tmin);
                node_tests += W as u64 * N as u64;
                if mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if mask == 0 {
                        cur = child[i];
                        // Requests all of the child's lines at once (the node test
                        // loads its planes in order and the child references last; a
                        // multi-block leaf is tested block by block), as Embree does:
                        // 1.05–1.10× on the DRAM-bound sphere-inside diffuse rays,
                        // neutral on the dragon and Sponza.
                        self.prefetch::<Q>(cur);
                        continue;
                    }
                    let j = mask.trailing_zeros() as usize;
                    if mask & (mask - 1) == 0 {
                        // Two (the common case): no sort. Both are prefetched before the
                        // comparison (which waits for the entry distances the node test
                        // stored), so that the nearer one's lines are already on their way.
                        self.prefetch::<Q>(child[i]);
                        self.prefetch::<Q>(child[j]);
                        let (near, far) = if tmin[j] < tmin[i] { (j, i) } else { (i, j) };
                        stack.push((child[far], tmin[far]));
                        cur = child[near];
                        continue;
                    }
                    // Three or more: visit the nearest now, stack the rest farthest first.
                    cur = self.order_many::<L, Q>(i, mask, &tmin, child, &mut stack);
                    continue;
                }
            } else {
                tri_tests += W as u64 * self.leaf_closest(cur, o, d, &mut t_best, &mut best);
            }
            // Pop the next entry that can still hold a closer hit.
            loop {
                match stack.pop() {
                    None => {
                        stats.node_tests += node_tests;
                        stats.tri_tests += tri_tests;
                        return best;
                    }
                    Some((c, t)) if t <= t_best * ROBUST + r.slack => {
                        cur = c;
                        break;
                    }
                    Some(_) => {}
                }
            }
        }
    }

    /// The any-hit traversal, with the parameters L and Q of [`Self::intersect_impl`].
    /// It always counts its tests: without the two counters LLVM kept the node
    /// test's per-ray vectors in memory for the whole loop (three times the loads
    /// per query on Sponza-inside shadow rays, and slower), so counting is free here.
    #[inline(always)]
    fn occluded_impl<const L: u8, const Q: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        stats.shadow_rays += 1;
        if (self.nodes.is_empty() && self.qnodes.is_empty()) || !traceable(ray) {
            return false;
        }
        let r = self.ray_pre::<L, Q>(ray);
        let (o, d) = (ray.o, ray.d);
        let mut store = items::<STACK>();
        let mut stack = Stack::new(&mut store);
        let mut cur = 0u32;
        let mut tmin = [0.0f32; N];
        // Counted locally (kept in registers), added to `stats` on return.
        let (mut node_tests, mut tri_tests) = (0u64, 0u64);
        loop {
            if cur & LEAF == 0 {
                let (mut mask, child) = self.visit::<L, Q>(cur, &r, t_max, &mut tmin);
                node_tests += N as u64;
                if mask != 0 {
                    // Any order finds an occluder; go down the first, stack the others.
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    while mask != 0 {
                        let j = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        stack.push((child[j], 0.0));
                    }
                    cur = child[i];
                    continue;
                }
            } else {
                for block in self.leaf(cur) {
                    tri_tests += 4;
                    if block.intersect(o, d, t_max).0 != 0 {
                        stats.node_tests += node_tests;
                        stats.tri_tests += tri_tests;
                        return true;
                    }
                }
            }
            match stack.pop() {
                None => {
                    stats.node_tests += node_tests;
                    stats.tri_tests += tri_tests;
                    return false;
                }
                Some((c, _)) => cur = c,
            }
        }
    }

    /// Three or more hit children (lane `i` and the lanes of `mask`): all but the
    /// nearest stacked farthest first, each prefetched; returns the nearest. With
    /// 8-wide float nodes on x86 a branch-free sorting network orders them (on Sponza
    /// inside a closest-hit query meets one such node on average, and the insertion
    /// sort took ~100 instructions and data-dependent branches: docs/benchmarks.md).
    #[inline(always)]
    pub(super) fn order_many<const L: u8, const Q: bool>(
        &self,
        i: usize,
        mask: u32,
        tmin: &[f32; N],
        child: &[u32; N],
        stack: &mut Stack<impl AsMut<[MaybeUninit<Entry>]>>,
    ) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if N == 8 && L >= AVX2 && !Q {
            let full = mask | 1 << i;
            // SAFETY: L is AVX2 or AVX512 only inside those traversals (CPU checked
            // at build); `tmin` and `child` hold 8 values, the node test left
            // non-negative distances in `tmin`.
            let cur = unsafe { x86::sort_hits8(tmin.as_ptr(), full, child.as_ptr(), stack.top8()) };
            stack.grow(full.count_ones() as usize - 1);
            // Every hit child but the lowest lane's: prefetching all of them
            // (the nearest is loaded next anyway) measured 0.94–0.97× on the
            // Sponza-inside diffuse rays.
            let mut m = mask;
            while m != 0 {
                self.prefetch::<Q>(child[m.trailing_zeros() as usize]);
                m &= m - 1;
            }
            return cur;
        }
        self.push_sorted::<Q>(i, mask, tmin, child, stack)
    }

    /// The insertion-sort form of [`Self::order_many`].
    #[inline(always)]
    pub(super) fn push_sorted<const Q: bool>(
        &self,
        i: usize,
        mut mask: u32,
        tmin: &[f32; N],
        child: &[u32; N],
        stack: &mut Stack<impl AsMut<[MaybeUninit<Entry>]>>,
    ) -> u32 {
        let mut hits: [(u32, f32); N] = [(0, 0.0); N];
        hits[0] = (child[i], tmin[i]);
        let mut k = 1;
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let e = (child[i], tmin[i]);
            // Insertion sort, descending by distance.
            let mut j = k;
            while j > 0 && hits[j - 1].1 < e.1 {
                hits[j] = hits[j - 1];
                j -= 1;
            }
            hits[j] = e;
            k += 1;
        }
        for h in &hits[..k - 1] {
            self.prefetch::<Q>(h.0);
            stack.push(*h);
        }
        hits[k - 1].0
    }

    /// Tests the triangle blocks of leaf `cur` against the ray, keeping the closest
    /// hit (by [`replaces`]) within `t_best`; returns the triangle tests made.
    #[inline(always)]
    pub(super) fn leaf_closest(&self, cur: u32, o: Vec3, d: Vec3, t_best: &mut f32, best: &mut Option<Hit>) -> u64 {
        let blocks = self.leaf(cur);
        // The bound of the next test, updated with each new best hit.
        let mut limit = test_limit(*t_best, best);
        let mut k = 0;
        loop {
            let block = &blocks[k];
            let (mut mask, t, u, v) = block.intersect(o, d, limit);
            if mask != 0 {
                // The lane of least (t, triangle index).
                let mut j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                while mask != 0 {
                    let k = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if t[k] < t[j] || (t[k] == t[j] && block.id[k] < block.id[j]) {
                        j = k;
                    }
                }
                if replaces(t[j], block.id[j], best) {
                    *t_best = t[j];
                    *best = Some(Hit { t: t[j], tri: block.id[j], b1: u[j], b2: v[j] });
                    limit = test_limit(t[j], best);
                }
            }
            k += 1;
            if k == blocks.len() {
                break;
            }
            // Most leaves are one block (1.06 per leaf on Sponza): marking the loop's
            // back edge cold keeps LLVM from treating the triangle test as the hottest
            // code, which made it spill the node test's per-ray vectors for the whole
            // traversal instead of around leaves.
            std::hint::cold_path();
        }
        4 * blocks.len() as u64
    }

    /// Per-ray values; with quantised nodes the slack also covers their rounding.
    #[inline(always)]
    pub(super) fn ray_pre<const L: u8, const Q: bool>(&self, ray: &Ray) -> RayPre {
        let mut r = RayPre::new::<N>(ray);
        if Q {
            r.quantised_planes::<N>();
            r.slack += QNode::<N>::slack(r.o.to_array(), r.inv.to_array(), self.cmax);
        } else if L >= AVX2 && N == 8 {
            r.fast_planes(self.cmax);
            // Its entry distances err only relatively (within ROBUST), so popping
            // needs no absolute slack (and the set-up none of its instructions).
            r.slack = 0.0;
        }
        r
    }

    /// Tests the ray against the children of interior node `cur`: the hit mask
    /// (entry distances in `tmin`) and the child references.
    #[inline(always)]
    pub(super) fn visit<const L: u8, const Q: bool>(&self, cur: u32, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> (u32, &[u32; N]) {
        if Q {
            debug_assert!(node_index::<N>(cur) < self.qnodes.len());
            // SAFETY: as in `node`, for the quantised copy of the node array.
            let q = unsafe { self.qnodes.get_unchecked(node_index::<N>(cur)) };
            (qnode_test::<N, L>(q, r, t_max, tmin), &q.child)
        } else {
            let n = self.node(cur);
            (node_test::<N, L>(n, r, t_max, tmin), &n.child)
        }
    }

    /// The address of the float node of an interior reference (its byte offset / 8,
    /// `node_ref`), for `node` and `prefetch`.
    #[inline(always)]
    fn node_ptr(&self, child: u32) -> *const Node<N> {
        (self.nodes.as_ptr() as *const u8).wrapping_add(child as usize * 8).cast()
    }

    /// The node of an interior reference.
    #[inline(always)]
    fn node(&self, child: u32) -> &Node<N> {
        debug_assert!(node_index::<N>(child) < self.nodes.len());
        // SAFETY: interior references are made only by `collapse` (or are the root,
        // 0, of a non-empty tree), each the `node_ref` of a node it pushed.
        unsafe { &*self.node_ptr(child) }
    }

    /// Starts fetching a child (its node's lines, or the first two triangle blocks of
    /// its leaf), so that the memory latency overlaps the traversal of the nearer
    /// children. Unrolled: a loop over the line count cost ~20 instructions a
    /// child (cachegrind: docs/benchmarks.md).
    #[inline(always)]
    pub(super) fn prefetch<const Q: bool>(&self, child: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            // Float nodes span 4 lines, quantised ones 2; a block 2.5 lines (160 B,
            // at a multiple of 32 B, so 3 lines hold one and 5 two).
            let (p, lines) = if child & LEAF == 0 {
                if Q {
                    (self.qnodes.as_ptr().wrapping_add(node_index::<N>(child)) as *const i8, 2)
                } else {
                    (self.node_ptr(child) as *const i8, 4)
                }
            } else {
                (self.blocks.as_ptr().wrapping_add(((child & !LEAF) >> 3) as usize) as *const i8, if child & 7 == 0 { 3 } else { 5 })
            };
            // SAFETY (all): prefetching is a hint that never faults, even out of bounds.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
                if lines > 2 {
                    _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
                    if lines > 3 {
                        _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(192));
                        if lines > 4 {
                            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(256));
                        }
                    }
                }
            }
        }
    }

    simd_entries!(intersect_avx2, occluded_avx2, AVX2, "avx2,fma,popcnt,bmi1,bmi2");

    /// The entry points of the portable level (no target features).
    fn intersect_portable<const W: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        if self.quant {
            self.intersect_impl::<PORTABLE, true, W>(ray, t_max, stats)
        } else {
            self.intersect_impl::<PORTABLE, false, W>(ray, t_max, stats)
        }
    }

    simd_entries!(intersect_avx512, occluded_avx512, AVX512, "avx2,fma,popcnt,bmi1,bmi2,avx512f,avx512vl,avx512bw,avx512dq");
}

impl<const N: usize> Accel for WideBvh<N> {
    fn name(&self) -> &'static str {
        match (N, self.quant) {
            (8, true) => "bvh8q",
            (8, false) => "bvh8",
            _ => "bvh4",
        }
    }

    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: `simd` names only a level the CPU reported (`detect_simd`).
            Simd::Avx512 => return unsafe { counting!(self, intersect_avx512, ray, t_max, stats) },
            // SAFETY: as above.
            Simd::Avx2 => return unsafe { counting!(self, intersect_avx2, ray, t_max, stats) },
            Simd::Portable => {}
        }
        counting!(self, intersect_portable, ray, t_max, stats)
    }

    fn occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: as in `intersect`.
            Simd::Avx512 => return unsafe { self.occluded_avx512(ray, t_max, stats) },
            // SAFETY: as in `intersect`.
            Simd::Avx2 => return unsafe { self.occluded_avx2(ray, t_max, stats) },
            Simd::Portable => {}
        }
        if self.quant {
            self.occluded_impl::<PORTABLE, true>(ray, t_max, stats)
        } else {
            self.occluded_impl::<PORTABLE, false>(ray, t_max, stats)
        }
    }

    fn intersect_stream(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], k: usize, stats: &mut TraversalStats) {
        self.interleaved(rays, out, k, stats)
    }

    fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node<N>>()
            + self.qnodes.len() * std::mem::size_of::<QNode<N>>()
            + self.blocks.len() * std::mem::size_of::<TriBlock>()
    }

    fn simd_level(&self) -> Option<&'static str> {
        Some(match self.simd {
            Simd::Portable => "portable",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        })
    }

    fn sah_cost(&self) -> Option<f64> {
        let s = self.shape();
        Some(s.node_sah + s.leaf_sah)
    }
}

#[cfg(test)]
mod tests {
    use super::super::cpu::detect_simd;
    use super::super::trees_at_every_level;
    use super::*;
    use glam::Vec3;

    /// Rays with a zero, infinite or NaN direction, or a non-finite origin, hit
    /// nothing and are never occluded, on every tree and level (such a ray used to
    /// enter empty child slots and read outside the triangle blocks).
    #[test]
    fn degenerate_rays_hit_nothing() {
        let tris: Vec<[Vec3; 3]> = (0..50)
            .map(|k| {
                let c = Vec3::new((k % 5) as f32, (k / 5 % 5) as f32, (k / 25) as f32);
                [c, c + Vec3::X * 0.7, c + Vec3::Y * 0.7]
            })
            .collect();
        let (inf, nan) = (f32::INFINITY, f32::NAN);
        let rays = [
            Ray::new(Vec3::splat(0.3), Vec3::ZERO),
            Ray::new(Vec3::ZERO, Vec3::ZERO),
            Ray::new(Vec3::splat(0.3), Vec3::new(inf, 0.0, 0.0)),
            Ray::new(Vec3::splat(0.3), Vec3::new(nan, 0.0, 1.0)),
            Ray::new(Vec3::new(0.3, 0.3, -inf), Vec3::Z),
            Ray::new(Vec3::new(nan, 0.3, -1.0), Vec3::Z),
        ];
        for (simd, bvh) in trees_at_every_level(&tris) {
            let mut s = TraversalStats::default();
            for ray in &rays {
                assert_eq!(bvh.intersect(ray, inf, &mut s), None, "{} {simd:?} {ray:?}", bvh.name());
                assert!(!bvh.occluded(ray, inf, &mut s), "{} {simd:?} {ray:?}", bvh.name());
            }
            let stream: Vec<(Ray, f32)> =
                rays.iter().map(|r| (*r, inf)).chain([(Ray::new(Vec3::new(0.3, 0.3, -1.0), Vec3::Z), inf)]).collect();
            let mut out = vec![None; stream.len()];
            bvh.intersect_stream(&stream, &mut out, 4, &mut s);
            assert!(out[..rays.len()].iter().all(Option::is_none) && out[rays.len()].is_some(), "{} {simd:?} stream", bvh.name());
        }
    }

    /// The portable traversal (the one non-AVX2 CPUs run) finds the same hits as the
    /// SIMD one, for float and quantised nodes and both widths.
    #[test]
    fn portable_and_simd_traversals_agree() {
        use crate::math::{hash_words, uniform_sphere};
        let unit = |h: u64| (h >> 40) as f32 / (1u64 << 24) as f32;
        let p = |k: u64, s: u64| uniform_sphere([unit(hash_words(&[k, s])), unit(hash_words(&[k, s + 1]))]);
        let tris: Vec<[Vec3; 3]> = (0..3000u64)
            .map(|k| {
                let c = p(k, 0) * (1.0 + unit(hash_words(&[k, 9])));
                [c, c + p(k, 2) * 0.2, c + p(k, 4) * 0.2]
            })
            .collect();
        // Tree `kind` (bvh4, bvh8, bvh8q) with the given traversal level.
        let make = |kind: usize, simd: Simd| -> Box<dyn Accel> {
            match kind {
                0 => Box::new(WideBvh::<4> { simd, ..WideBvh::<4>::build(&tris) }),
                1 => Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build(&tris) }),
                _ => Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build_quantized(&tris) }),
            }
        };
        let mut s = TraversalStats::default();
        // Every level this CPU runs, each against the portable traversal.
        let levels: &[Simd] = match detect_simd() {
            Simd::Avx512 => &[Simd::Avx2, Simd::Avx512],
            Simd::Avx2 => &[Simd::Avx2],
            Simd::Portable => &[],
        };
        for (kind, &level) in (0..3).flat_map(|k| levels.iter().map(move |l| (k, l))) {
            let (a, b) = (make(kind, level), make(kind, Simd::Portable));
            let mut hits = 0;
            for k in 0..20_000u64 {
                let ray = Ray::new(p(k, 20) * 3.0, p(k, 22));
                let t_max = if k % 3 == 0 { 2.0 } else { f32::INFINITY };
                let (x, y) = (a.intersect(&ray, t_max, &mut s), b.intersect(&ray, t_max, &mut s));
                assert_eq!(x.map(|h| (h.tri, h.t.to_bits())), y.map(|h| (h.tri, h.t.to_bits())), "{} ray {k}", a.name());
                assert_eq!(a.occluded(&ray, t_max, &mut s), b.occluded(&ray, t_max, &mut s), "{} shadow ray {k}", a.name());
                hits += x.is_some() as u32;
            }
            assert!(hits > 1_000, "{}: {hits} hits", a.name());
        }
    }
}

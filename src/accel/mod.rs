//! Ray-scene intersection structures (plug-ins chosen by name: `none`, `bvh`,
//! `bvh4`, `bvh8`, `bvh8q`; the last three are configurations of [`wide`]).
//!
//! Every implementation uses [`crate::geometry::intersect_triangle`] on the same
//! precomputed (v0, e1, e2) data and keeps hits by [`replaces`], so all return the
//! same closest hit, bit for bit, whatever order they visit the triangles in.

pub mod bvh;
pub mod bvh4;
pub mod bvh8;
pub mod bvh8q;
pub mod linear;
mod sbvh;
pub mod wide;

use crate::geometry::{Hit, Ray};
use glam::Vec3;

/// Traversal counters, kept per thread and summed afterwards (no atomics in the
/// hot loop).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Closest-hit queries.
    pub rays: u64,
    /// Any-hit (shadow) queries.
    pub shadow_rays: u64,
    /// Ray/box tests (counted where [`TraversalStats::count_work`] is set).
    pub node_tests: u64,
    /// Ray/triangle tests (counted where [`TraversalStats::count_work`] is set).
    pub tri_tests: u64,
    /// Whether queries count their box and triangle tests. Off by default: no
    /// renderer reads them, and in the wide BVH's closest-hit loop the two counters
    /// cost ~4 % of the instructions (their registers were otherwise spills); the
    /// benchmarks and tests that report them switch it on. Accelerators may count
    /// regardless.
    pub count_work: bool,
}

impl TraversalStats {
    /// Counters that also count box and triangle tests.
    pub fn counting_work() -> Self {
        TraversalStats { count_work: true, ..Default::default() }
    }
    /// Adds another set of counters.
    pub fn add(&mut self, o: &TraversalStats) {
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
        self.node_tests += o.node_tests;
        self.tri_tests += o.tri_tests;
    }
    /// All queries.
    pub fn total_rays(&self) -> u64 {
        self.rays + self.shadow_rays
    }
}

/// An acceleration structure over a fixed triangle list.
pub trait Accel: Send + Sync {
    /// Configuration name.
    fn name(&self) -> &'static str;
    /// Closest hit with 0 < t < t_max.
    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit>;
    /// True when anything is hit with 0 < t < t_max (early exit).
    fn occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool;
    /// Closest hits of a stream of rays (each with its own t_max) into `out`, with up
    /// to `k` rays in flight where the structure can interleave their traversals
    /// (the same hits as [`Accel::intersect`] ray by ray, which is the default).
    fn intersect_stream(&self, rays: &[(Ray, f32)], out: &mut [Option<Hit>], k: usize, stats: &mut TraversalStats) {
        let _ = k;
        for ((ray, t_max), o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect(ray, *t_max, stats);
        }
    }
    /// Bytes used by the structure (nodes + its triangle copy).
    fn memory_bytes(&self) -> usize;
    /// SAH cost of the tree with node-visit and block-test costs 1, relative to the
    /// root's area, as Embree's build statistics print it (for comparing tree quality).
    fn sah_cost(&self) -> Option<f64> {
        None
    }
    /// The instruction-set level the traversal runs at (`portable`, `avx2`,
    /// `avx512`), where the accelerator has several.
    fn simd_level(&self) -> Option<&'static str> {
        None
    }
}

/// The closest-hit rule of every accelerator: a hit at distance `t` on triangle `tri`
/// replaces the best so far when it is nearer, or as near with a lower triangle
/// index. The result is the least (t, index) over the triangles hit, which does not
/// depend on the traversal order, so accelerators, SIMD levels and stream widths
/// (which visit equal-distance children or leaves in different orders) return the
/// same hit at exact ties too: duplicated triangles, or edges shared at the same t.
#[inline(always)]
pub fn replaces(t: f32, tri: u32, best: &Option<Hit>) -> bool {
    match best {
        None => true,
        Some(b) => t < b.t || (t == b.t && tri < b.tri),
    }
}

/// The exclusive distance bound for the next triangle test of a closest-hit query:
/// the query's `t_max` before any hit, after it one ulp above the best hit's distance
/// `t`, so that an equal-distance hit is still found and judged by [`replaces`].
#[inline(always)]
pub fn test_limit(t: f32, best: &Option<Hit>) -> f32 {
    if best.is_some() { t.next_up() } else { t }
}

/// Triangle in the form the intersection test wants.
#[derive(Clone, Copy, Debug)]
pub struct PreTriangle {
    /// First vertex.
    pub v0: Vec3,
    /// v1 − v0.
    pub e1: Vec3,
    /// v2 − v0.
    pub e2: Vec3,
}

impl PreTriangle {
    /// From three vertices.
    #[inline]
    pub fn new(t: &[Vec3; 3]) -> Self {
        PreTriangle { v0: t[0], e1: t[1] - t[0], e2: t[2] - t[0] }
    }
}

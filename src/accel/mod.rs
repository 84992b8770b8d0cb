//! Ray-scene intersection structures (plug-ins chosen by name: `none`, `bvh`,
//! `bvh4`, `bvh8`, `bvh8q`; the last three are configurations of [`wide`]).
//!
//! Every implementation uses [`crate::geometry::intersect_triangle`] on the same
//! precomputed (v0, e1, e2) data, so all return the same closest hit.

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
    /// Ray/box tests.
    pub node_tests: u64,
    /// Ray/triangle tests.
    pub tri_tests: u64,
}

impl TraversalStats {
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

/// Rays in flight for [`Accel::intersect_stream`] where a caller has a batch of
/// independent rays: 8 when the structure is larger than the processor's last-level
/// cache (its traversal then waits on memory, and 8 interleaved rays traced a
/// 55.6 MB tree 1.6× faster), else 1 (where the tree fits the caches, interleaving's
/// bookkeeping made it 0.72–1.0× as fast; docs/benchmarks.md). 1 where the cache size
/// is unknown.
pub fn stream_width(accel: &dyn Accel) -> usize {
    match last_level_cache_bytes() {
        Some(llc) if accel.memory_bytes() > llc => 8,
        _ => 1,
    }
}

/// Size of the largest CPU cache, from Linux's sysfs (None elsewhere or unreadable).
pub fn last_level_cache_bytes() -> Option<usize> {
    static LLC: std::sync::OnceLock<Option<usize>> = std::sync::OnceLock::new();
    *LLC.get_or_init(|| {
        let dir = std::fs::read_dir("/sys/devices/system/cpu/cpu0/cache").ok()?;
        dir.filter_map(|e| std::fs::read_to_string(e.ok()?.path().join("size")).ok()).filter_map(|t| parse_cache_size(t.trim())).max()
    })
}

/// A sysfs cache size ("32768K", "1M", "512").
fn parse_cache_size(t: &str) -> Option<usize> {
    let (num, mul) = match t.chars().last()? {
        'K' => (&t[..t.len() - 1], 1 << 10),
        'M' => (&t[..t.len() - 1], 1 << 20),
        'G' => (&t[..t.len() - 1], 1 << 30),
        _ => (t, 1),
    };
    num.parse::<usize>().ok().map(|n| n * mul)
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

#[cfg(test)]
mod tests {
    #[test]
    fn cache_sizes_parse() {
        assert_eq!(super::parse_cache_size("32768K"), Some(32 << 20));
        assert_eq!(super::parse_cache_size("1M"), Some(1 << 20));
        assert_eq!(super::parse_cache_size("512"), Some(512));
        assert_eq!(super::parse_cache_size("x"), None);
        assert_eq!(super::parse_cache_size(""), None);
    }
}

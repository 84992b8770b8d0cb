//! `none`: tests every triangle. The ground truth the other structures are checked
//! against, and the baseline of the acceleration experiments.

use super::{Accel, PreTriangle, TraversalStats};
use crate::geometry::{Hit, Ray, intersect_triangle};
use glam::Vec3;

/// Brute-force intersector.
pub struct Linear {
    tris: Vec<PreTriangle>,
}

impl Linear {
    /// Builds (copies) the triangle list.
    pub fn build(tris: &[[Vec3; 3]]) -> Self {
        Linear { tris: tris.iter().map(PreTriangle::new).collect() }
    }
}

impl Accel for Linear {
    fn name(&self) -> &'static str {
        "none"
    }
    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        stats.rays += 1;
        stats.tri_tests += self.tris.len() as u64;
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        // In index order, so keeping only strictly nearer hits is [`super::replaces`].
        for (i, t) in self.tris.iter().enumerate() {
            if let Some((th, b1, b2)) = intersect_triangle(ray.o, ray.d, t.v0, t.e1, t.e2, t_best) {
                t_best = th;
                best = Some(Hit { t: th, tri: i as u32, b1, b2 });
            }
        }
        best
    }
    fn occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        stats.shadow_rays += 1;
        for t in &self.tris {
            stats.tri_tests += 1;
            if intersect_triangle(ray.o, ray.d, t.v0, t.e1, t.e2, t_max).is_some() {
                return true;
            }
        }
        false
    }
    fn memory_bytes(&self) -> usize {
        self.tris.len() * std::mem::size_of::<PreTriangle>()
    }
}

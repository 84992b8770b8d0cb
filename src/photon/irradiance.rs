//! Christensen's (2000) precomputed irradiance: irradiance estimated at every n-th
//! stored photon before rendering, kept in its own kd-tree, and looked up at
//! final-gather hits (the `precomputed` gather, and `irradiance_cache` with
//! `precomputed_irradiance`).

use super::estimate::{self, EstimateParams, with_heap};
use super::kdtree::{KdPoint, KdTree};
use super::record::Photon;
use crate::accel::TraversalStats;
use crate::math::Color;
use crate::world::World;
use glam::Vec3;
use rayon::prelude::*;

/// A precomputed irradiance sample.
#[derive(Clone, Copy, Debug)]
pub struct IrradiancePoint {
    /// Position (of the photon it was computed at).
    pub pos: Vec3,
    /// Surface normal on the lit side.
    pub normal: Vec3,
    /// Irradiance from all photon maps.
    pub irradiance: Color,
}

impl KdPoint for IrradiancePoint {
    fn pos(&self) -> Vec3 {
        self.pos
    }
}

/// Computes irradiance at every `stride`-th photon of `global` (in parallel; the
/// result is independent of the thread count).
///
/// With `prm.area_probes` > 0 each estimate divides by the area of surface inside its
/// region rather than the disc's ([`estimate::coverage`]), so points on thin or
/// curved geometry and near edges are not darkened by the part of the disc that
/// holds no surface.
pub fn precompute(world: &World, global: &KdTree<Photon>, stride: usize, prm: &EstimateParams) -> KdTree<IrradiancePoint> {
    let pts: Vec<IrradiancePoint> = (0..global.len())
        .into_par_iter()
        .step_by(stride.max(1))
        .map(|i| {
            let (n, pos) = (global.points[i].normal(), global.position(i));
            let mut stats = TraversalStats::default();
            let e = with_heap(|h| estimate::irradiance_covered(world, global, pos, n, prm, h, &mut stats));
            IrradiancePoint { pos, normal: n, irradiance: e }
        })
        .collect();
    KdTree::build(pts)
}

/// Irradiance of the nearest precomputed point within `radius` whose normal agrees
/// with `n` (so it was lit from the side the query looks from) and that lies within
/// `thickness` of the query's tangent plane — without the plane test a parallel
/// surface a little above or below (the other side of a thin slab, a lamp over a
/// roof) lends its irradiance through the wall.
pub fn lookup(tree: &KdTree<IrradiancePoint>, p: Vec3, n: Vec3, radius: f32, thickness: f32) -> Option<Color> {
    with_heap(|h| {
        tree.knn(p, 1, radius * radius, h, &|q: &IrradiancePoint, pos: Vec3| q.normal.dot(n) >= 0.7 && (pos - p).dot(n).abs() <= thickness);
        h.items.first().map(|&(_, i)| tree.points[i as usize].irradiance)
    })
}

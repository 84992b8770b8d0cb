//! `precomputed`: final gathering whose hits look up Christensen's precomputed
//! irradiance (2000) instead of a full photon estimate. Irradiance is estimated at
//! every n-th global photon before rendering and kept in its own kd-tree; a lookup
//! takes the nearest point whose normal agrees.

use super::{Gather, PhotonContext, ShadeKey, with_heap};
use crate::accel::TraversalStats;
use crate::material::Bsdf;
use crate::math::Color;
use crate::photon::estimate::{self, EstimateParams};
use crate::photon::kdtree::{KdPoint, KdTree};
use crate::photon::record::Photon;
use crate::world::{Interaction, World};
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
pub fn precompute(global: &KdTree<Photon>, stride: usize, prm: &EstimateParams) -> KdTree<IrradiancePoint> {
    let pts: Vec<IrradiancePoint> = (0..global.len())
        .into_par_iter()
        .step_by(stride.max(1))
        .map(|i| {
            let (n, pos) = (global.points[i].normal(), global.position(i));
            let e = with_heap(|h| estimate::irradiance(global, pos, n, prm, h));
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
    super::with_heap(|h| {
        tree.knn(p, 1, radius * radius, h, &|q: &IrradiancePoint, pos: Vec3| q.normal.dot(n) >= 0.7 && (pos - p).dot(n).abs() <= thickness);
        h.items.first().map(|&(_, i)| tree.points[i as usize].irradiance)
    })
}

/// Final gather over precomputed irradiance.
pub struct PrecomputedGather;

impl Gather for PrecomputedGather {
    fn name(&self) -> &'static str {
        "precomputed"
    }
    #[allow(clippy::too_many_arguments)]
    fn indirect(
        &self,
        ctx: &PhotonContext,
        world: &World,
        it: &Interaction,
        wo: Vec3,
        bsdf: &Bsdf,
        key: ShadeKey,
        stats: &mut TraversalStats,
    ) -> Color {
        ctx.gathered_indirect(world, it, wo, bsdf, 0, key, stats)
    }
}

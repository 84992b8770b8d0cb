//! Christensen's (2000) precomputed irradiance: irradiance estimated at every n-th
//! stored photon before rendering, kept in a grid built for nearest-point queries
//! ([`super::nearest`]), and looked up at
//! final-gather hits (the `precomputed` gather, and `irradiance_cache` with
//! `precomputed_irradiance`).

use super::estimate::{self, EstimateParams, with_heap};
use super::kdtree::KdPoint;
use super::nearest::{CELL_SPACINGS, DiscGrid, PhotonGrid};
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

/// Precomputed irradiance points in a grid built for nearest-point lookups with
/// the lookup's filter ([`DiscGrid`]; a lookup is one per final-gather ray):
/// positions and normals stored apart and tested eight at a time, the irradiance
/// read for the point found only.
#[derive(Clone, Debug, Default)]
pub struct PrecomputedIrradiance {
    grid: DiscGrid<Color>,
}

impl PrecomputedIrradiance {
    /// Indexes `points` for lookups (normals kept as 16-bit octahedral codes:
    /// exactly when they were decoded from one, as a photon's are).
    pub fn new(points: Vec<IrradiancePoint>) -> Self {
        let pos: Vec<Vec3> = points.iter().map(|p| p.pos).collect();
        let normals: Vec<Vec3> = points.iter().map(|p| p.normal).collect();
        let irradiance: Vec<Color> = points.iter().map(|p| p.irradiance).collect();
        PrecomputedIrradiance { grid: DiscGrid::build(&pos, &normals, &irradiance, CELL_SPACINGS) }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.grid.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.grid.is_empty()
    }

    /// Point `i` (lookup order).
    pub fn point(&self, i: usize) -> IrradiancePoint {
        IrradiancePoint { pos: self.grid.position(i), normal: self.grid.normal(i), irradiance: *self.grid.item(i) }
    }

    /// Irradiance of the nearest precomputed point within `radius` whose normal
    /// agrees with `n` (so it was lit from the side the query looks from) and that
    /// lies within `thickness` of the query's tangent plane — without the plane test a
    /// parallel surface a little above or below (the other side of a thin slab, a
    /// lamp over a roof) lends its irradiance through the wall.
    #[inline]
    pub fn lookup(&self, p: Vec3, n: Vec3, radius: f32, thickness: f32) -> Option<Color> {
        self.lookup_point(p, n, radius, thickness).map(|(e, _)| e)
    }

    /// [`PrecomputedIrradiance::lookup`] with the position of the point found.
    #[inline]
    pub fn lookup_point(&self, p: Vec3, n: Vec3, radius: f32, thickness: f32) -> Option<(Color, Vec3)> {
        self.grid.nearest_disc(p, n, thickness, 0.7, radius * radius).map(|(i, _)| (*self.grid.item(i), self.grid.position(i)))
    }
}

/// Computes irradiance at every `stride`-th photon of `global` (in parallel; the
/// result is independent of the thread count).
///
/// With `prm.area_probes` > 0 each estimate divides by the area of surface inside its
/// region rather than the disc's ([`estimate::coverage`]), so points on thin or
/// curved geometry and near edges are not darkened by the part of the disc that
/// holds no surface.
pub fn precompute(world: &World, global: &PhotonGrid, stride: usize, prm: &EstimateParams) -> PrecomputedIrradiance {
    let stride = stride.max(1);
    // Point j is photon j·stride of the grid: only the irradiance is collected, and
    // the positions and normal codes are read from the grid as the points' grid is built.
    let irradiance: Vec<Color> = (0..global.len())
        .into_par_iter()
        .step_by(stride)
        .map(|i| {
            let (n, pos) = (global.normal(i), global.position(i));
            let mut stats = TraversalStats::default();
            with_heap(|h| estimate::irradiance_covered(world, global, pos, n, Some(i as u32), prm, h, &mut stats))
        })
        .collect();
    let m = irradiance.len();
    let coord = |a: usize| (0..m).into_par_iter().map(|j| global.position(j * stride)[a]).collect();
    let normals = (0..m).into_par_iter().map(|j| global.normal_code(j * stride)).collect();
    PrecomputedIrradiance { grid: DiscGrid::build_soa(coord(0), coord(1), coord(2), normals, irradiance, CELL_SPACINGS, false) }
}

/// [`PrecomputedIrradiance::lookup`], free-standing.
pub fn lookup(pre: &PrecomputedIrradiance, p: Vec3, n: Vec3, radius: f32, thickness: f32) -> Option<Color> {
    pre.lookup(p, n, radius, thickness)
}

//! A scene made ready for rendering: its accelerator, its lights, and the surface
//! interaction computed from a hit.

use crate::accel::{Accel, TraversalStats};
use crate::geometry::{Hit, Ray, offset_origin};
use crate::light::LightSet;
use crate::material::{Material, ShadingPoint};
use crate::scene::{NO_NORMALS, Scene};
use glam::Vec3;

/// Scene + accelerator + light set.
pub struct World {
    /// The scene.
    pub scene: Scene,
    /// Its acceleration structure.
    pub accel: Box<dyn Accel>,
    /// Its lights.
    pub lights: LightSet,
}

/// Everything an integrator needs about a surface hit.
#[derive(Clone, Copy, Debug)]
pub struct Interaction {
    /// Hit point.
    pub p: Vec3,
    /// Shading frame and geometric normal.
    pub sp: ShadingPoint,
    /// Triangle index.
    pub tri: u32,
    /// Ray distance to the hit (in units of the ray direction).
    pub t: f32,
    /// True when the ray arrived on the triangle's front (winding-normal) side.
    pub front: bool,
}

impl World {
    /// Bundles a scene with an accelerator; builds the light set.
    pub fn new(scene: Scene, accel: Box<dyn Accel>) -> anyhow::Result<Self> {
        scene.validate()?;
        let lights = LightSet::build(&scene)?;
        Ok(World { scene, accel, lights })
    }

    /// Closest hit along `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Interaction> {
        let hit = self.accel.intersect(ray, f32::INFINITY, stats)?;
        Some(self.interaction(ray, &hit))
    }

    /// Builds the interaction record for a hit.
    #[inline]
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> Interaction {
        let tri = &self.scene.triangles[hit.tri as usize];
        let b0 = 1.0 - hit.b1 - hit.b2;
        let p = tri[0] * b0 + tri[1] * hit.b1 + tri[2] * hit.b2;
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
        let ni = self.scene.tri_normals[hit.tri as usize];
        let ns = if ni == NO_NORMALS {
            ng
        } else {
            let n = &self.scene.normals[ni as usize];
            (n[0] * b0 + n[1] * hit.b1 + n[2] * hit.b2).try_normalize().unwrap_or(ng)
        };
        Interaction { p, sp: ShadingPoint::new(ng, ns), tri: hit.tri, t: hit.t, front: ray.d.dot(ng) < 0.0 }
    }

    /// Material at an interaction.
    #[inline]
    pub fn material(&self, it: &Interaction) -> &Material {
        self.scene.material(it.tri)
    }

    /// Spawns a ray leaving the surface in direction `d`.
    #[inline]
    pub fn spawn(&self, it: &Interaction, d: Vec3) -> Ray {
        Ray::new(offset_origin(it.p, it.sp.ng, d), d)
    }

    /// True when the segment from the surface point to `target` is unblocked.
    /// `target_normal` (zero for point lights) offsets the far end off its surface.
    #[inline]
    pub fn visible(&self, it: &Interaction, target: Vec3, target_normal: Vec3, stats: &mut TraversalStats) -> bool {
        let dir = target - it.p;
        let o = offset_origin(it.p, it.sp.ng, dir);
        let t = if target_normal == Vec3::ZERO { target } else { offset_origin(target, target_normal, -dir) };
        let ray = Ray::new(o, t - o);
        !self.accel.occluded(&ray, 1.0 - 1e-4, stats)
    }

    /// True when nothing blocks the direction `d` to infinity (directional lights).
    #[inline]
    pub fn unoccluded_dir(&self, it: &Interaction, d: Vec3, stats: &mut TraversalStats) -> bool {
        let ray = self.spawn(it, d);
        !self.accel.occluded(&ray, f32::INFINITY, stats)
    }
}

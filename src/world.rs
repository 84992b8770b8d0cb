//! A scene made ready for rendering: its accelerator, its lights, and the surface
//! interaction computed from a hit.

use crate::accel::{Accel, TraversalStats};
use crate::geometry::{Hit, Ray, offset_origin};
use crate::light::LightSet;
use crate::material::{Bsdf, Material, ShadingPoint};
use crate::math::Color;
use crate::scene::{NO_NORMALS, NO_UVS, Scene};
use crate::texture::{Binding, Slot};
use glam::{Vec2, Vec3};
use std::borrow::Cow;
use std::ops::Range;

/// Scene + accelerator + light set.
pub struct World {
    /// The scene.
    pub scene: Scene,
    /// Its acceleration structure.
    pub accel: Box<dyn Accel>,
    /// Its lights.
    pub lights: LightSet,
    /// Texture bindings sorted by material, and each material's range of them (empty
    /// when the scene has no textures).
    tex_bindings: Vec<Binding>,
    tex_ranges: Vec<Range<u32>>,
    /// Per triangle, the shading point of its flat (geometric-normal) shading: the
    /// unit winding normal and the frame around it, computed once here with the very
    /// operations `interaction` used per hit (same bits). Triangles with vertex
    /// normals read only its `ng`.
    flat: Vec<ShadingPoint>,
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
    /// Texture coordinates (the barycentrics (b1, b2) where the mesh has none, as in
    /// Mitsuba).
    pub uv: Vec2,
}

impl World {
    /// Bundles a scene with an accelerator; builds the light set.
    pub fn new(scene: Scene, accel: Box<dyn Accel>) -> anyhow::Result<Self> {
        scene.validate()?;
        let lights = LightSet::build(&scene)?;
        let mut tex_bindings = scene.textures.bindings.clone();
        tex_bindings.sort_by_key(|b| b.material);
        let mut tex_ranges = Vec::new();
        if !tex_bindings.is_empty() {
            tex_ranges = vec![0..0; scene.materials.len()];
            for (k, b) in tex_bindings.iter().enumerate() {
                let r = tex_ranges
                    .get_mut(b.material as usize)
                    .ok_or_else(|| anyhow::anyhow!("texture bound to a material that does not exist"))?;
                if r.start == r.end {
                    *r = k as u32..k as u32;
                }
                r.end = k as u32 + 1;
            }
        }
        let flat = scene
            .triangles
            .iter()
            .map(|t| {
                let ng = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
                ShadingPoint::new(ng, ng)
            })
            .collect();
        Ok(World { scene, accel, lights, tex_bindings, tex_ranges, flat })
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
        let flat = &self.flat[hit.tri as usize];
        let ng = flat.ng;
        let ni = self.scene.tri_normals[hit.tri as usize];
        let sp = if ni == NO_NORMALS {
            *flat
        } else {
            let n = &self.scene.normals[ni as usize];
            ShadingPoint::new(ng, (n[0] * b0 + n[1] * hit.b1 + n[2] * hit.b2).try_normalize().unwrap_or(ng))
        };
        let uv = match self.scene.tri_uvs.get(hit.tri as usize) {
            Some(&k) if k != NO_UVS => {
                let t = &self.scene.uvs[k as usize];
                t[0] * b0 + t[1] * hit.b1 + t[2] * hit.b2
            }
            _ => Vec2::new(hit.b1, hit.b2),
        };
        Interaction { p, sp, tri: hit.tri, t: hit.t, front: ray.d.dot(ng) < 0.0, uv }
    }

    /// The BSDF at an interaction with its textured parameters filled in (borrowed,
    /// without any work, for untextured materials).
    #[inline]
    pub fn bsdf_at(&self, it: &Interaction) -> Cow<'_, Bsdf> {
        let m = self.scene.tri_material[it.tri as usize] as usize;
        let bsdf = &self.scene.materials[m].bsdf;
        match self.tex_ranges.get(m) {
            Some(r) if r.start < r.end => {
                let mut b = bsdf.clone();
                for bind in &self.tex_bindings[r.start as usize..r.end as usize] {
                    let t = &self.scene.textures.textures[bind.texture as usize];
                    set_slot(&mut b, bind.slot, || t.eval(it.uv), |alpha| t.eval_1(it.uv, alpha));
                }
                Cow::Owned(b)
            }
            _ => Cow::Borrowed(bsdf),
        }
    }

    /// Radiance of the environment along a ray that left the scene in direction `d`.
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Color {
        self.lights.escaped(d)
    }

    /// Material at an interaction (its untextured parameters: use
    /// [`World::bsdf_at`] for scattering).
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

/// Writes a textured value into a BSDF parameter (nested ones included: a mask's
/// BSDF, both sides of a two-sided one). Slots a BSDF does not have are left alone
/// (the loaders bind only slots the material has).
fn set_slot(b: &mut Bsdf, slot: Slot, rgb: impl Fn() -> Color, scalar: impl Fn(bool) -> f32) {
    match slot {
        Slot::DiffuseReflectance => {
            b.set_color_param("diffuse_reflectance", rgb());
        }
        Slot::SpecularReflectance => {
            b.set_color_param("specular_reflectance", rgb());
        }
        Slot::SpecularTransmittance => {
            b.set_color_param("specular_transmittance", rgb());
        }
        Slot::Opacity { alpha } => {
            if let Bsdf::Mask(m) = b {
                m.opacity = scalar(alpha).clamp(0.0, 1.0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::linear::Linear;
    use crate::material::{Mask, TwoSided};
    use crate::texture::{Checkerboard, Texture};
    use glam::Mat3;

    /// Textures reach nested parameters: a mask's opacity, and the diffuse reflectance
    /// of the two-sided BSDF inside it.
    #[test]
    fn textured_slots_reach_nested_bsdfs() {
        let mut scene = crate::scene::builtin::cornell();
        let lam = Bsdf::Lambertian(crate::material::Lambertian { albedo: Color::splat(0.5) });
        scene.materials[0].bsdf = Bsdf::Mask(Mask { opacity: 1.0, nested: Box::new(Bsdf::TwoSided(TwoSided::new(lam))) });
        let checker = |a: f32, b: f32| {
            Texture::Checkerboard(Checkerboard { color0: Color::splat(a), color1: Color::splat(b), to_uv: Mat3::IDENTITY })
        };
        scene.textures.bind(0, Slot::Opacity { alpha: false }, checker(0.25, 0.75));
        scene.textures.bind(0, Slot::DiffuseReflectance, checker(0.1, 0.9));
        let tri = (0..scene.triangles.len() as u32).find(|&t| scene.tri_material[t as usize] == 0).unwrap();
        let accel = Box::new(Linear::build(&scene.triangles));
        let world = World::new(scene, accel).unwrap();
        let it = |u: f32| Interaction {
            p: Vec3::ZERO,
            sp: ShadingPoint::new(Vec3::Z, Vec3::Z),
            tri,
            t: 1.0,
            front: true,
            uv: Vec2::new(u, 0.25),
        };
        // (The scalar checkerboard has Mitsuba's opposite phase: see `Checkerboard::eval_1`.)
        for (u, opacity, albedo) in [(0.25, 0.75, 0.1), (0.75, 0.25, 0.9)] {
            let Bsdf::Mask(m) = &*world.bsdf_at(&it(u)) else { panic!("not a mask") };
            assert_eq!(m.opacity, opacity);
            let Bsdf::TwoSided(t) = &*m.nested else { panic!("not two-sided") };
            for side in [&t.front, &t.back] {
                assert!(matches!(**side, Bsdf::Lambertian(ref l) if l.albedo == Color::splat(albedo)), "{side:?}");
            }
        }
    }
}

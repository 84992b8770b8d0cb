//! The light quantities bidirectional methods need beyond next-event estimation:
//! emission with its densities (the first light-subpath vertex), direct sampling with
//! the density of emitting the same ray, and the densities of an emitter a camera path
//! hit. Densities follow SmallVCM's convention: `direct_pdf_a` is the area density of
//! the point under direct sampling, `emission_pdf_w` the area density of the point
//! times the solid-angle density of the direction; both include the light's selection
//! probability (proportional to power, [`crate::light::LightSet`]).

use crate::light::{Light, LightSet, spot_falloff};
use crate::math::{Color, Frame, concentric_disc, cosine_hemisphere, uniform_cone, uniform_cone_pdf, uniform_sphere, uniform_triangle};
use crate::scene::{LightDesc, Scene};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// A sampled emitted ray (the light subpath's start).
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    /// Ray origin (offset off emitting surfaces).
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// Le·cos / (emission_pdf_w): the light subpath's initial throughput.
    pub throughput: Color,
    /// Area density of the point under direct sampling (delta lights: the selection
    /// probability).
    pub direct_pdf_a: f32,
    /// Density of the emitted ray (point × direction).
    pub emission_pdf_w: f32,
    /// Cosine at the light between its normal and the direction (1 for point-like).
    pub cos: f32,
    /// Delta position or direction (cannot be hit by a camera path).
    pub delta: bool,
    /// False for lights at infinity (directional).
    pub finite: bool,
}

/// A light point sampled towards a receiver (the connection s = 1).
#[derive(Clone, Copy, Debug)]
pub struct Illumination {
    /// Unit direction from the receiver towards the light.
    pub wi: Vec3,
    /// Distance (infinite for directional lights).
    pub dist: f32,
    /// Incident radiance Le, or intensity / irradiance for delta lights.
    pub radiance: Color,
    /// Solid-angle density at the receiver of direct sampling, without selection
    /// (point-like lights: d², directional: 1, as SmallVCM).
    pub direct_pdf_w: f32,
    /// Density of emitting this ray from the light, without selection.
    pub emission_pdf_w: f32,
    /// Cosine at the light.
    pub cos_at_light: f32,
    /// Selection probability of the light.
    pub pick: f32,
    /// Delta light.
    pub delta: bool,
    /// The point on the light (shadow-ray end).
    pub point: Vec3,
    /// The light's normal there (zero for point-like lights).
    pub normal: Vec3,
}

fn triangle_point(scene: &Scene, tri: u32, u: [f32; 2]) -> Vec3 {
    let t = &scene.triangles[tri as usize];
    let b = uniform_triangle(u);
    t[0] * (1.0 - b[0] - b[1]) + t[1] * b[0] + t[2] * b[1]
}

/// Samples an emitted ray: light by power (`u_sel`), position (`u_pos`), direction (`u_dir`).
pub fn emit(lights: &LightSet, scene: &Scene, u_sel: f32, u_pos: [f32; 2], u_dir: [f32; 2]) -> Option<Emission> {
    let (idx, pick) = lights.distribution.sample(u_sel);
    if pick <= 0.0 {
        return None;
    }
    let e = match &lights.lights[idx] {
        Light::Area { tri, radiance, area, normal } => {
            let p = triangle_point(scene, *tri, u_pos);
            let local = cosine_hemisphere(u_dir);
            if local.z <= 0.0 {
                return None;
            }
            let d = Frame::new(*normal).to_world(local);
            let pdf_w = local.z * FRAC_1_PI / area * pick;
            Emission {
                origin: crate::geometry::offset_origin(p, *normal, d),
                dir: d,
                throughput: *radiance * (local.z / pdf_w),
                direct_pdf_a: pick / area,
                emission_pdf_w: pdf_w,
                cos: local.z,
                delta: false,
                finite: true,
            }
        }
        Light::Desc(LightDesc::Point { position, intensity }) => {
            let pdf_w = crate::math::UNIFORM_SPHERE_PDF * pick;
            Emission {
                origin: *position,
                dir: uniform_sphere(u_dir),
                throughput: *intensity / pdf_w,
                direct_pdf_a: pick,
                emission_pdf_w: pdf_w,
                cos: 1.0,
                delta: true,
                finite: true,
            }
        }
        Light::Desc(LightDesc::Spot { position, direction, intensity, cone_deg, falloff_deg }) => {
            let cos_max = falloff_deg.max(*cone_deg).min(180.0).to_radians().cos();
            let local = uniform_cone(u_dir, cos_max);
            let w = spot_falloff(local.z.clamp(-1.0, 1.0).acos().to_degrees(), *cone_deg, *falloff_deg);
            let pdf_w = uniform_cone_pdf(cos_max) * pick;
            Emission {
                origin: *position,
                dir: Frame::new(*direction).to_world(local),
                throughput: *intensity * (w / pdf_w),
                direct_pdf_a: pick,
                emission_pdf_w: pdf_w,
                cos: 1.0,
                delta: true,
                finite: true,
            }
        }
        Light::Desc(LightDesc::Directional { direction, irradiance }) => {
            let r = lights.scene_radius;
            let f = Frame::new(*direction);
            let q = concentric_disc(u_pos);
            let origin = lights.scene_center - *direction * (2.0 * r) + (f.s * q[0] + f.t * q[1]) * r;
            let pdf_w = pick / (PI * r * r);
            Emission {
                origin,
                dir: *direction,
                throughput: *irradiance / pdf_w,
                direct_pdf_a: pick,
                emission_pdf_w: pdf_w,
                cos: 1.0,
                delta: true,
                finite: false,
            }
        }
        Light::Env(env) => {
            // SmallVCM's `BackgroundLight`: a direction towards the environment by its
            // own sampling, the ray starting on a disc of the bounding sphere's radius
            // perpendicular to it, outside the sphere, travelling inwards.
            let (w, radiance, dir_pdf) = env.sample(u_dir)?;
            if dir_pdf <= 0.0 {
                return None;
            }
            let r = lights.scene_radius;
            let f = Frame::new(w);
            let q = concentric_disc(u_pos);
            let origin = lights.scene_center + w * (2.0 * r) + (f.s * q[0] + f.t * q[1]) * r;
            let pdf_w = dir_pdf / (PI * r * r) * pick;
            Emission {
                origin,
                dir: -w,
                throughput: radiance / pdf_w,
                // As SmallVCM, the "area" density of a light at infinity is the
                // direction's solid-angle density.
                direct_pdf_a: dir_pdf * pick,
                emission_pdf_w: pdf_w,
                cos: 1.0,
                delta: false,
                finite: false,
            }
        }
        // Environment descriptions become `Light::Env` in `LightSet::build`.
        Light::Desc(LightDesc::Constant { .. } | LightDesc::Envmap { .. }) => return None,
    };
    Some(e)
}

/// Samples a light point towards the receiver `p` (light by power).
pub fn illuminate(lights: &LightSet, scene: &Scene, p: Vec3, u_sel: f32, u: [f32; 2]) -> Option<Illumination> {
    let (idx, pick) = lights.distribution.sample(u_sel);
    if pick <= 0.0 {
        return None;
    }
    let point_like = |position: Vec3, radiance: Color, emission_pdf_w: f32| {
        let d = position - p;
        let d2 = d.length_squared();
        (d2 > 0.0).then(|| Illumination {
            wi: d / d2.sqrt(),
            dist: d2.sqrt(),
            radiance,
            direct_pdf_w: d2,
            emission_pdf_w,
            cos_at_light: 1.0,
            pick,
            delta: true,
            point: position,
            normal: Vec3::ZERO,
        })
    };
    match &lights.lights[idx] {
        Light::Area { tri, radiance, area, normal } => {
            let y = triangle_point(scene, *tri, u);
            let d = y - p;
            let d2 = d.length_squared();
            if d2 <= 0.0 {
                return None;
            }
            let dist = d2.sqrt();
            let wi = d / dist;
            let cos_l = -wi.dot(*normal);
            if cos_l <= 0.0 {
                return None;
            }
            Some(Illumination {
                wi,
                dist,
                radiance: *radiance,
                direct_pdf_w: d2 / (cos_l * area),
                emission_pdf_w: cos_l * FRAC_1_PI / area,
                cos_at_light: cos_l,
                pick,
                delta: false,
                point: y,
                normal: *normal,
            })
        }
        Light::Desc(LightDesc::Point { position, intensity }) => point_like(*position, *intensity, crate::math::UNIFORM_SPHERE_PDF),
        Light::Desc(LightDesc::Spot { position, direction, intensity, cone_deg, falloff_deg }) => {
            let d = (p - *position).normalize_or_zero();
            let w = spot_falloff(d.dot(*direction).clamp(-1.0, 1.0).acos().to_degrees(), *cone_deg, *falloff_deg);
            if w <= 0.0 {
                return None;
            }
            let cos_max = falloff_deg.max(*cone_deg).min(180.0).to_radians().cos();
            point_like(*position, *intensity * w, uniform_cone_pdf(cos_max))
        }
        Light::Desc(LightDesc::Directional { direction, irradiance }) => {
            let r = lights.scene_radius;
            Some(Illumination {
                wi: -*direction,
                dist: f32::INFINITY,
                radiance: *irradiance,
                direct_pdf_w: 1.0,
                emission_pdf_w: 1.0 / (PI * r * r),
                cos_at_light: 1.0,
                pick,
                delta: true,
                point: Vec3::ZERO,
                normal: Vec3::ZERO,
            })
        }
        Light::Env(env) => {
            let (wi, radiance, dir_pdf) = env.sample(u)?;
            if dir_pdf <= 0.0 {
                return None;
            }
            let r = lights.scene_radius;
            Some(Illumination {
                wi,
                dist: f32::INFINITY,
                radiance,
                direct_pdf_w: dir_pdf,
                emission_pdf_w: dir_pdf / (PI * r * r),
                cos_at_light: 1.0,
                pick,
                delta: false,
                point: Vec3::ZERO,
                normal: Vec3::ZERO,
            })
        }
        Light::Desc(LightDesc::Constant { .. } | LightDesc::Envmap { .. }) => None,
    }
}

/// Densities of an emitting triangle hit by a camera path, seen along `-w` where `w`
/// (unit) points from the emitter back to the previous vertex: (direct_pdf_a,
/// emission_pdf_w), selection included. `None` when the triangle is no light.
pub fn emitter_pdfs(lights: &LightSet, tri: u32, w: Vec3) -> Option<(f32, f32)> {
    let li = *lights.tri_light.get(tri as usize)?;
    if li == u32::MAX {
        return None;
    }
    let Light::Area { area, normal, .. } = &lights.lights[li as usize] else { return None };
    let pick = lights.distribution.pmf(li as usize);
    let cos = w.dot(*normal).max(0.0);
    Some((pick / area, pick * cos * FRAC_1_PI / area))
}

/// A camera path that left the scene along unit direction `d` (pointing away from
/// it): the environment's radiance there and its densities (direct_pdf_a,
/// emission_pdf_w), selection included, as SmallVCM's `BackgroundLight::GetRadiance`.
/// `None` without an environment.
pub fn env_radiance(lights: &LightSet, d: Vec3) -> Option<(Color, f32, f32)> {
    let idx = lights.env? as usize;
    let Light::Env(env) = &lights.lights[idx] else { return None };
    let pick = lights.distribution.pmf(idx);
    let r = lights.scene_radius;
    let direct_pdf_a = env.pdf(d) * pick;
    Some((env.eval(d), direct_pdf_a, direct_pdf_a / (PI * r * r)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Emission's throughput is the light's power over its selection probability, and
    /// direct sampling's densities agree with the emission's at the same point.
    #[test]
    fn emission_and_illumination_densities_agree() {
        let scene = crate::scene::builtin::cornell();
        let lights = LightSet::build(&scene).unwrap();
        let e = emit(&lights, &scene, 0.3, [0.2, 0.7], [0.4, 0.1]).unwrap();
        let (idx, pick) = lights.distribution.sample(0.3);
        let power = lights.lights[idx].power(lights.scene_radius);
        assert!((crate::math::mean(e.throughput) * pick / power - 1.0).abs() < 1e-4);
        // A receiver along the emitted ray: direct sampling of the same light gives
        // emission_pdf_w·cos_receiver/d² = emission density of the same ray in area terms.
        let p = e.origin + e.dir * (0.2 * lights.scene_radius);
        let il = illuminate(&lights, &scene, p, 0.3, [0.2, 0.7]).unwrap();
        assert!((il.pick - pick).abs() < 1e-7 && !il.delta);
        assert!((il.emission_pdf_w * pick / e.emission_pdf_w - 1.0).abs() < 1e-3, "{} {}", il.emission_pdf_w * pick, e.emission_pdf_w);
        assert!((il.direct_pdf_w * il.cos_at_light / (il.dist * il.dist) * pick / e.direct_pdf_a - 1.0).abs() < 1e-3);
        let tri = match &lights.lights[idx] {
            Light::Area { tri, .. } => *tri,
            _ => unreachable!(),
        };
        let (da, ew) = emitter_pdfs(&lights, tri, e.dir).unwrap();
        assert!((da / e.direct_pdf_a - 1.0).abs() < 1e-5 && (ew / e.emission_pdf_w - 1.0).abs() < 1e-3);
    }

    /// The Cornell box lit only by a constant environment (its ceiling light off).
    pub(crate) fn env_lit_cornell() -> Scene {
        let mut scene = crate::scene::builtin::cornell();
        for m in &mut scene.materials {
            m.emission = Color::ZERO;
        }
        scene.lights.push(LightDesc::Constant { radiance: Color::new(0.8, 0.9, 1.0) });
        scene
    }

    /// The same agreement for the environment, a light at infinity: its emitted ray
    /// starts outside the bounding sphere and travels inwards, its "area" density is
    /// the direction's density (SmallVCM's `BackgroundLight`), and a camera ray
    /// escaping along the reverse direction sees the same densities.
    #[test]
    fn emission_and_illumination_densities_agree_for_the_environment() {
        let scene = env_lit_cornell();
        let lights = LightSet::build(&scene).unwrap();
        assert_eq!(lights.lights.len(), 1);
        let r = lights.scene_radius;
        for k in 0..16 {
            let u = |a: f32| (a + 0.618 * k as f32) % 1.0;
            let e = emit(&lights, &scene, u(0.3), [u(0.2), u(0.7)], [u(0.4), u(0.1)]).unwrap();
            assert!(!e.delta && !e.finite && e.cos == 1.0);
            assert!((e.origin - lights.scene_center).length() > r, "starts outside the bounding sphere");
            // Its line passes within r of the centre.
            let c = lights.scene_center - e.origin;
            assert!((c - e.dir * c.dot(e.dir)).length() <= r * (1.0 + 1e-4) && c.dot(e.dir) > 0.0);
            let power = lights.lights[0].power(r);
            assert!((crate::math::mean(e.throughput) / power - 1.0).abs() < 1e-4);
            let dir_pdf = crate::math::UNIFORM_SPHERE_PDF;
            assert!((e.direct_pdf_a / dir_pdf - 1.0).abs() < 1e-5);
            assert!((e.emission_pdf_w * PI * r * r / dir_pdf - 1.0).abs() < 1e-4);
            let p = lights.scene_center;
            let il = illuminate(&lights, &scene, p, u(0.3), [u(0.2), u(0.7)]).unwrap();
            assert!(il.dist.is_infinite() && !il.delta && il.cos_at_light == 1.0 && il.pick == 1.0);
            assert!((il.emission_pdf_w * il.pick / e.emission_pdf_w - 1.0).abs() < 1e-4);
            assert!((il.direct_pdf_w * il.pick / e.direct_pdf_a - 1.0).abs() < 1e-4);
            assert_eq!(il.radiance, Color::new(0.8, 0.9, 1.0));
            let (le, da, ew) = env_radiance(&lights, -e.dir).unwrap();
            assert_eq!(le, Color::new(0.8, 0.9, 1.0));
            assert!((da / e.direct_pdf_a - 1.0).abs() < 1e-5 && (ew / e.emission_pdf_w - 1.0).abs() < 1e-4);
        }
        // Without an environment a camera ray that escapes sees nothing.
        let plain = crate::scene::builtin::cornell();
        assert!(env_radiance(&LightSet::build(&plain).unwrap(), Vec3::Y).is_none());
    }
}

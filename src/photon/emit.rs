//! Photon emission from every light type. Each function returns the photon's origin,
//! unit direction and power Φ/p (the light's share of the total is applied by the
//! caller through the selection probability).

use crate::light::{Light, LightSet, spot_falloff};
use crate::math::{Color, Frame, concentric_disc, cosine_hemisphere, uniform_cone, uniform_cone_pdf, uniform_sphere, uniform_triangle};
use crate::scene::{LightDesc, Scene};
use glam::Vec3;
use std::f32::consts::PI;

/// An emitted photon before tracing.
#[derive(Clone, Copy, Debug)]
pub struct Emitted {
    /// Origin (already offset off emitting surfaces).
    pub origin: Vec3,
    /// Unit travel direction.
    pub dir: Vec3,
    /// Power carried (already divided by the sampling pdfs, not yet by the photon count).
    pub power: Color,
}

/// Samples one photon: light by power (`u_sel`), position (`u_pos`), direction (`u_dir`).
pub fn emit_photon(lights: &LightSet, scene: &Scene, u_sel: f32, u_pos: [f32; 2], u_dir: [f32; 2]) -> Option<Emitted> {
    let (idx, p_sel) = lights.distribution.sample(u_sel);
    if p_sel <= 0.0 {
        return None;
    }
    let e = match &lights.lights[idx] {
        Light::Area { tri, radiance, area, normal } => {
            // Area-uniform point, cosine-distributed direction about the front normal:
            // Φ = L_e·cos / (1/A · cos/π) = L_e·π·A.
            let t = &scene.triangles[*tri as usize];
            let b = uniform_triangle(u_pos);
            let p = t[0] * (1.0 - b[0] - b[1]) + t[1] * b[0] + t[2] * b[1];
            let d = Frame::new(*normal).to_world(cosine_hemisphere(u_dir));
            Emitted { origin: crate::geometry::offset_origin(p, *normal, d), dir: d, power: *radiance * (PI * area) }
        }
        Light::Desc(LightDesc::Point { position, intensity }) => {
            Emitted { origin: *position, dir: uniform_sphere(u_dir), power: *intensity * (4.0 * PI) }
        }
        Light::Desc(LightDesc::Spot { position, direction, intensity, cone_deg, falloff_deg }) => {
            // Uniform within the outer cone, weighted by the falloff.
            let outer = falloff_deg.max(*cone_deg).min(180.0);
            let cos_max = outer.to_radians().cos();
            let local = uniform_cone(u_dir, cos_max);
            let d = Frame::new(*direction).to_world(local);
            let w = spot_falloff(local.z.clamp(-1.0, 1.0).acos().to_degrees(), *cone_deg, *falloff_deg);
            Emitted { origin: *position, dir: d, power: *intensity * (w / uniform_cone_pdf(cos_max)) }
        }
        Light::Desc(LightDesc::Directional { direction, irradiance }) => {
            // From a disc of the scene's bounding-sphere radius, facing the light.
            let r = lights.scene_radius;
            let f = Frame::new(*direction);
            let q = concentric_disc(u_pos);
            let origin = lights.scene_center - *direction * (2.0 * r) + (f.s * q[0] + f.t * q[1]) * r;
            Emitted { origin, dir: *direction, power: *irradiance * (PI * r * r) }
        }
        Light::Env(env) => {
            // Direction towards the environment by its own sampling, then a point on
            // the disc of the scene's bounding sphere facing it; the photon travels
            // inwards: Φ = L(ω) · π r² / p(ω).
            let (w, l, pdf) = env.sample(u_dir)?;
            let r = lights.scene_radius;
            let f = Frame::new(w);
            let q = concentric_disc(u_pos);
            let origin = lights.scene_center + w * (2.0 * r) + (f.s * q[0] + f.t * q[1]) * r;
            Emitted { origin, dir: -w, power: l * (PI * r * r / pdf) }
        }
        Light::Desc(LightDesc::Constant { .. } | LightDesc::Envmap { .. }) => return None,
    };
    Some(Emitted { power: e.power / p_sel, ..e })
}

//! Lights: emissive triangles (area lights) and the contract's point, spot and
//! directional lights, with one power-proportional distribution over all of them
//! for next-event estimation and (later) photon emission.

mod area;
mod constant;
mod directional;
pub mod envmap;
mod point;
mod spot;

pub use spot::spot_falloff;

use crate::geometry::Aabb;
use crate::math::{Color, mean};
use crate::scene::{LightDesc, Scene};
use glam::Vec3;
use std::f32::consts::PI;

/// A light ready for sampling.
#[derive(Clone, Debug)]
pub enum Light {
    /// One emissive triangle.
    Area {
        /// Triangle index.
        tri: u32,
        /// Emitted radiance (front side).
        radiance: Color,
        /// Triangle area.
        area: f32,
        /// Front (winding) normal.
        normal: Vec3,
    },
    /// Non-geometric light.
    Desc(LightDesc),
    /// Environment light (`constant` or `envmap`), at infinity in every direction.
    Env(Environment),
}

/// An environment light.
#[derive(Clone, Debug)]
pub enum Environment {
    /// Uniform radiance.
    Constant(Color),
    /// Equirectangular map.
    Map(Box<envmap::EnvMap>),
}

impl Environment {
    /// Radiance arriving from direction `d` (pointing away from the scene).
    #[inline]
    pub fn eval(&self, d: Vec3) -> Color {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(m) => m.eval(d),
        }
    }
    /// Samples a direction towards the environment: (direction, radiance, pdf).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Color, f32)> {
        match self {
            Environment::Constant(c) => Some(constant::sample(*c, u)),
            Environment::Map(m) => m.sample(u),
        }
    }
    /// Solid-angle pdf of [`Environment::sample`].
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => crate::math::UNIFORM_SPHERE_PDF,
            Environment::Map(m) => m.pdf(d),
        }
    }
    /// ∫ mean(L) dω.
    pub fn integral(&self) -> f32 {
        match self {
            Environment::Constant(c) => constant::integral(*c),
            Environment::Map(m) => m.integral(),
        }
    }
}

/// Result of sampling incident light at a point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the sampled light point (infinite for directional lights).
    pub dist: f32,
    /// Incident radiance (area) or irradiance-equivalent (delta lights: I/d², E).
    pub li: Color,
    /// Solid-angle pdf including the light-selection probability (delta lights:
    /// the selection probability alone).
    pub pdf: f32,
    /// True for point, spot and directional lights.
    pub delta: bool,
    /// The sampled point on the light (for shadow-ray end points).
    pub point: Vec3,
    /// Light's normal at the sampled point (area lights).
    pub normal: Vec3,
}

/// Discrete distribution with O(log n) sampling.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f64>,
    pmf: Vec<f32>,
}

impl Distribution1D {
    /// Builds from non-negative weights; `None` if they sum to zero.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for &w in weights {
            acc += w.max(0.0) as f64;
            cdf.push(acc);
        }
        if acc <= 0.0 || !acc.is_finite() {
            return None;
        }
        let pmf = weights.iter().map(|&w| (w.max(0.0) as f64 / acc) as f32).collect();
        for c in cdf.iter_mut() {
            *c /= acc;
        }
        Some(Distribution1D { cdf, pmf })
    }
    /// Samples an index with probability proportional to its weight.
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let u = u as f64;
        // First index whose upper cdf bound exceeds u.
        let mut lo = 0usize;
        let mut hi = self.pmf.len();
        while lo + 1 < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid] <= u { lo = mid } else { hi = mid }
        }
        // Skip zero-probability entries that share the same cdf value.
        while self.pmf[lo] == 0.0 && lo + 1 < self.pmf.len() {
            lo += 1;
        }
        (lo, self.pmf[lo])
    }
    /// Probability of index `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }
    /// Number of entries.
    pub fn len(&self) -> usize {
        self.pmf.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }
}

/// All lights of a scene with their power-proportional selection distribution.
#[derive(Clone, Debug)]
pub struct LightSet {
    /// The lights.
    pub lights: Vec<Light>,
    /// Selection distribution (proportional to emitted power).
    pub distribution: Distribution1D,
    /// For each triangle, its light index or `u32::MAX`.
    pub tri_light: Vec<u32>,
    /// Scene bounding sphere (centre, radius) for directional lights.
    pub scene_center: Vec3,
    /// Bounding sphere radius.
    pub scene_radius: f32,
    /// Index of the environment light in `lights`, if any.
    pub env: Option<u32>,
}

impl LightSet {
    /// Collects emissive triangles and the scene's lights. Fails when nothing emits.
    pub fn build(scene: &Scene) -> anyhow::Result<Self> {
        let bounds: Aabb = scene.bounds;
        let scene_center = bounds.center();
        let scene_radius = (0.5 * bounds.diagonal().length()).max(1e-6);
        let mut lights = Vec::new();
        let mut tri_light = vec![u32::MAX; scene.triangles.len()];
        for (i, &m) in scene.tri_material.iter().enumerate() {
            let mat = &scene.materials[m as usize];
            if mat.is_emitter() {
                tri_light[i] = lights.len() as u32;
                lights.push(Light::Area {
                    tri: i as u32,
                    radiance: mat.emission,
                    area: scene.triangle_area(i as u32),
                    normal: scene.geometric_normal(i as u32),
                });
            }
        }
        let mut env = None;
        for l in &scene.lights {
            let e = match l {
                LightDesc::Constant { radiance } => Environment::Constant(*radiance),
                LightDesc::Envmap { image, scale, to_world } => {
                    Environment::Map(Box::new(envmap::EnvMap::new(image.clone(), *scale, *to_world)?))
                }
                other => {
                    lights.push(Light::Desc(other.clone()));
                    continue;
                }
            };
            if env.is_some() {
                anyhow::bail!("scene has more than one environment light");
            }
            env = Some(lights.len() as u32);
            lights.push(Light::Env(e));
        }
        let powers: Vec<f32> = lights.iter().map(|l| l.power(scene_radius)).collect();
        let distribution = Distribution1D::new(&powers).ok_or_else(|| anyhow::anyhow!("scene has no light with positive power"))?;
        Ok(LightSet { lights, distribution, tri_light, scene_center, scene_radius, env })
    }

    /// Picks one light by power and samples incident light at `p` from it.
    #[inline]
    pub fn sample_li(&self, scene: &Scene, p: Vec3, u_select: f32, u: [f32; 2]) -> Option<LightSample> {
        let (idx, p_sel) = self.distribution.sample(u_select);
        let mut s = match &self.lights[idx] {
            Light::Area { tri, radiance, area, normal } => area::sample_li(scene, *tri, *radiance, *area, *normal, p, u)?,
            Light::Desc(LightDesc::Point { position, intensity }) => point::sample_li(*position, *intensity, p)?,
            Light::Desc(LightDesc::Spot { position, direction, intensity, cone_deg, falloff_deg }) => {
                spot::sample_li(*position, *direction, *intensity, *cone_deg, *falloff_deg, p)?
            }
            Light::Desc(LightDesc::Directional { direction, irradiance }) => directional::sample_li(*direction, *irradiance)?,
            Light::Env(e) => {
                let (wi, li, pdf) = e.sample(u)?;
                LightSample { wi, dist: f32::INFINITY, li, pdf, delta: false, point: Vec3::ZERO, normal: Vec3::ZERO }
            }
            // Environment descriptions become `Light::Env` in `build`.
            Light::Desc(LightDesc::Constant { .. } | LightDesc::Envmap { .. }) => return None,
        };
        s.pdf *= p_sel;
        Some(s)
    }

    /// Solid-angle pdf that [`LightSet::sample_li`] would have produced the point `p_light`
    /// on emissive triangle `tri` when seen from `p_ref`.
    #[inline]
    pub fn pdf_area(&self, tri: u32, p_ref: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        let li = self.tri_light[tri as usize];
        if li == u32::MAX {
            return 0.0;
        }
        let Light::Area { area, .. } = &self.lights[li as usize] else { return 0.0 };
        let d = p_light - p_ref;
        let d2 = d.length_squared();
        let cos = (d.dot(n_light) / d2.sqrt()).abs();
        if cos <= 0.0 {
            return 0.0;
        }
        self.distribution.pmf(li as usize) * d2 / (cos * area)
    }

    /// The environment light, if any.
    #[inline]
    pub fn environment(&self) -> Option<&Environment> {
        match self.lights.get(self.env? as usize)? {
            Light::Env(e) => Some(e),
            _ => None,
        }
    }

    /// Radiance of the environment seen along direction `d` (zero without one): what
    /// a ray that leaves the scene returns.
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Color {
        self.environment().map_or(Color::ZERO, |e| e.eval(d))
    }

    /// Solid-angle pdf with which [`LightSet::sample_li`] picks the environment and
    /// samples direction `d` from it.
    #[inline]
    pub fn pdf_env(&self, d: Vec3) -> f32 {
        match (self.env, self.environment()) {
            (Some(i), Some(e)) => self.distribution.pmf(i as usize) * e.pdf(d),
            _ => 0.0,
        }
    }

    /// Total emitted power (mean over channels), the normaliser of photon power.
    pub fn total_power(&self) -> f32 {
        self.lights.iter().map(|l| l.power(self.scene_radius)).sum()
    }
}

impl Light {
    /// Emitted power (mean over channels); directional lights over the scene's disc.
    pub fn power(&self, scene_radius: f32) -> f32 {
        match self {
            Light::Area { radiance, area, .. } => PI * area * mean(*radiance),
            Light::Desc(LightDesc::Point { intensity, .. }) => 4.0 * PI * mean(*intensity),
            Light::Desc(LightDesc::Spot { intensity, cone_deg, falloff_deg, .. }) => spot::power(mean(*intensity), *cone_deg, *falloff_deg),
            Light::Desc(LightDesc::Directional { irradiance, .. }) => PI * scene_radius * scene_radius * mean(*irradiance),
            // Radiance through the scene's disc from every direction: π r² ∫ L dω.
            Light::Env(e) => PI * scene_radius * scene_radius * e.integral(),
            Light::Desc(LightDesc::Constant { .. } | LightDesc::Envmap { .. }) => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distribution_samples_by_weight() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample(0.1).0, 0);
        assert_eq!(d.sample(0.3).0, 2);
        assert_eq!(d.sample(0.9999).0, 2);
        assert!((d.pmf(2) - 0.75).abs() < 1e-6);
        assert!(Distribution1D::new(&[0.0, 0.0]).is_none());
    }
}

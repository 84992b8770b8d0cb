//! The photon integrator's shading in pass 2, shared by every gather plug-in:
//! distribution-ray-traced direct light, the caustic estimate, Whitted specular
//! chains, the final gather (diffuse part) and the glossy-lobe gather, and the radiance
//! at final-gather hits (a full photon estimate, or Christensen's precomputed
//! irradiance for the diffuse part). [`PhotonContext`] holds the maps and samplers the
//! integrator's pre-pass built; a [`GatherPoint`] is the point being shaded.

use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::material::{Bsdf, TransportMode};
use crate::math::{Color, Frame, cosine_hemisphere, hash_words, u32_to_unit};
use crate::photon::PhotonMaps;
use crate::photon::estimate::{self, EstimateParams, facing_normal, facing_shading_normal, with_heap};
use crate::photon::irradiance::PrecomputedIrradiance;
use crate::photon::nearest::PhotonGrid;
use crate::sampler::Sampler;
use crate::world::{Interaction, World};
use glam::Vec3;

/// Specular bounces followed before giving up (Whitted chains).
pub const MAX_SPECULAR: u32 = 12;
/// Specular depth up to which both glass branches are followed (deeper: one, by weight).
pub const SPLIT_DEPTH: u32 = 2;

/// Identifies one shading point for its private random numbers (pixel stream,
/// sample index, path branch): gather and light samples are a pure function of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadeKey(pub u64);

impl ShadeKey {
    /// Key of the camera sample the sampler is on.
    pub fn from_sampler(s: &dyn Sampler) -> Self {
        let (a, b) = s.current();
        ShadeKey(hash_words(&[a, b]))
    }
    /// Derived key for a sub-path.
    #[inline]
    pub fn child(self, what: u64) -> Self {
        ShadeKey(hash_words(&[self.0, what]))
    }
    /// A uniform number for decision `i`.
    #[inline]
    pub fn uniform(self, i: u64) -> f32 {
        u32_to_unit((hash_words(&[self.0, 0x5EED, i]) >> 32) as u32)
    }
}

/// Result of a final gather.
#[derive(Clone, Copy, Debug, Default)]
pub struct GatherResult {
    /// Incident indirect irradiance about the facing shading normal.
    pub irradiance: Color,
    /// Harmonic mean of the gather-ray hit distances (report eq. 11).
    pub harmonic_distance: f32,
}

/// The end of a camera or gather ray followed through mirrors and glass.
#[derive(Clone, Copy, Debug)]
pub struct SpecularPath {
    /// First non-specular surface.
    pub it: Interaction,
    /// Direction towards the previous vertex.
    pub wo: Vec3,
    /// Accumulated specular weight.
    pub weight: Color,
    /// Distance to the first surface hit (specular or not).
    pub first_dist: f32,
    /// Length of the whole chain (for the pixel footprint at its end).
    pub length: f32,
}

/// A point shaded in pass 2 (camera hit or gather hit): the surface, the direction
/// towards the viewer, its BSDF and the key of its private random numbers.
#[derive(Clone, Copy)]
pub struct GatherPoint<'a> {
    /// The scene.
    pub world: &'a World,
    /// The surface point.
    pub it: &'a Interaction,
    /// Unit direction towards the viewer (previous vertex).
    pub wo: Vec3,
    /// The surface's BSDF.
    pub bsdf: &'a Bsdf,
    /// Key of the point's random numbers.
    pub key: ShadeKey,
    /// The camera sample this point shades, when it is a camera path's first
    /// non-specular point (its first-level gather may take its share of a pixel's
    /// rays, [`PixelSplit`]); `None` at gather hits and cache entries.
    pub pixel: Option<PixelSample>,
}

/// A camera sample: its pixel's key (the same for every sample of the pixel, and of
/// the same specular branch) and its index in the pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSample {
    /// Key of the pixel's gather points (stream of the shared gather samplers).
    pub key: ShadeKey,
    /// Sample index within the pixel.
    pub index: u64,
}

/// `gather_per = "pixel"` (the default of `final_gather` and `precomputed`): the
/// first-level gather rays counted per pixel, so a pixel's gather costs the same at any
/// spp (pbrt-v4's and Mitsuba's budgets are per pixel too). Camera
/// sample i of the pixel traces the rays i·n … i·n + n − 1 of one point set per
/// pixel (so the pixel's rays are stratified together), each weighted 1/n: every
/// sample's gather stays an unbiased estimate of its own point's irradiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSplit {
    /// Diffuse gather rays per camera sample (⌈gather_samples / spp⌉).
    pub gather: u32,
    /// Glossy-lobe rays per camera sample (⌈glossy_samples / spp⌉).
    pub glossy: u32,
}

impl PixelSplit {
    /// The split of `gather` and `glossy` rays per pixel over `spp` camera samples.
    pub fn new(gather: u32, glossy: u32, spp: u32) -> Self {
        let per = |n: u32| n.div_ceil(spp.max(1)).max(1);
        PixelSplit { gather: per(gather), glossy: per(glossy) }
    }
}

/// Photon maps plus everything the render pass shares between gather plug-ins.
pub struct PhotonContext {
    /// The maps from pass 1.
    pub maps: PhotonMaps,
    /// Direct + indirect + caustic photons in one tree, for estimates at gather hits.
    pub global: PhotonGrid,
    /// Parameters of global estimates.
    pub est_global: EstimateParams,
    /// Parameters of caustic estimates.
    pub est_caustic: EstimateParams,
    /// Christensen's precomputed irradiance points, when enabled.
    pub precomputed: Option<PrecomputedIrradiance>,
    /// Search radius for precomputed points.
    pub precomputed_radius: f32,
    /// Final-gather sampler per level (sample count fixed per level).
    pub gather_samplers: Vec<Box<dyn Sampler>>,
    /// Rays per level.
    pub gather_counts: Vec<u32>,
    /// Sampler of the glossy-lobe gather (sample count = `glossy_samples`).
    pub glossy_sampler: Box<dyn Sampler>,
    /// Rays sampled from the glossy lobe at glossy gathering points.
    pub glossy_samples: u32,
    /// First-level rays counted per pixel (`gather_per = "pixel"`), or per camera
    /// sample (`None`).
    pub pixel_split: Option<PixelSplit>,
    /// Direct-light sampler (sample count = direct_samples).
    pub direct_sampler: Box<dyn Sampler>,
    /// Shadow rays per shading point.
    pub direct_samples: u32,
}

impl PhotonContext {
    /// Direct light at a non-specular point by distribution ray tracing:
    /// `direct_samples` shadow rays, lights chosen in proportion to power, the samples
    /// stratified by the direct sampler (its first dimension picks the light).
    pub fn direct_light(&self, at: &GatherPoint, stats: &mut TraversalStats) -> Color {
        let GatherPoint { world, it, wo, bsdf, key, .. } = *at;
        let key = key.child(0xD1);
        let n = self.direct_samples.max(1);
        let mut sum = Color::ZERO;
        for j in 0..n {
            // The shared sampler's values, drawn without a per-point clone.
            let mut v = [0.0f32; 3];
            self.direct_sampler.values_at(key.0, j as u64, 0, &mut v);
            let (u_sel, u) = (v[0], [v[1], v[2]]);
            let Some(ls) = world.lights.sample_li(&world.scene, it.p, u_sel, u) else { continue };
            if ls.pdf <= 0.0 {
                continue;
            }
            let f = bsdf.eval(&it.sp, wo, ls.wi);
            if f.max_element() <= 0.0 {
                continue;
            }
            let vis =
                if ls.dist.is_infinite() { world.unoccluded_dir(it, ls.wi, stats) } else { world.visible(it, ls.point, ls.normal, stats) };
            if vis {
                sum += f * ls.li * (ls.wi.dot(it.sp.ns()).abs() / ls.pdf);
            }
        }
        sum / n as f32
    }

    /// Caustic radiance by direct visualisation of the caustic map.
    pub fn caustic(&self, world: &World, it: &Interaction, wo: Vec3, bsdf: &Bsdf, stats: &mut TraversalStats) -> Color {
        if self.maps.caustic.is_empty() {
            return Color::ZERO;
        }
        with_heap(|h| estimate::radiance_in(Some((world, stats)), &self.maps.caustic, it, wo, bsdf, &self.est_caustic, h))
    }

    /// Radiance leaving a final-gather hit towards the gathering point. With
    /// precomputed irradiance: the nearest precomputed point (on the side the hit is
    /// seen from) times Kd/π for the diffuse part, plus a photon estimate with the
    /// glossy lobe alone when the surface has one. Without: a full photon estimate.
    /// Photons and points beyond a surface close to the hit's tangent plane (the lit
    /// top of a thin ceiling over a panel's upper side) are not used
    /// ([`estimate::keep_this_side`]).
    pub fn exitant_at_hit(&self, world: &World, it: &Interaction, wo: Vec3, bsdf: &Bsdf, stats: &mut TraversalStats) -> Color {
        if let Some(pre) = &self.precomputed {
            let n = facing_normal(it, wo);
            let thickness = self.est_global.disc * self.precomputed_radius;
            if let Some((e, q)) = pre.lookup_point(it.p, n, self.precomputed_radius, thickness)
                && estimate::on_this_side(world, it.p, n, q, stats)
            {
                let mut l = bsdf.diffuse_albedo() * std::f32::consts::FRAC_1_PI * e;
                if bsdf.has_glossy() {
                    l += with_heap(|h| {
                        estimate::radiance_with(
                            Some((world, &mut *stats)),
                            &self.global,
                            it,
                            wo,
                            bsdf.transmits_nondelta(),
                            &self.est_global,
                            h,
                            |wi| bsdf.eval_glossy(&it.sp, wo, wi),
                        )
                    });
                }
                return l;
            }
        }
        with_heap(|h| estimate::radiance_in(Some((world, stats)), &self.global, it, wo, bsdf, &self.est_global, h))
    }

    /// Follows a ray through mirrors and glass (one branch, chosen by weight) to the
    /// first non-specular surface. Returns the hit, the direction towards the
    /// previous vertex and the accumulated specular weight.
    pub fn follow_specular(
        &self,
        world: &World,
        ray: Ray,
        key: ShadeKey,
        stats: &mut TraversalStats,
    ) -> Option<(Interaction, Vec3, Color)> {
        self.follow_specular_path(world, ray, key, stats).map(|p| (p.it, p.wo, p.weight))
    }

    /// [`PhotonContext::follow_specular`] with the chain's distances.
    pub fn follow_specular_path(&self, world: &World, mut ray: Ray, key: ShadeKey, stats: &mut TraversalStats) -> Option<SpecularPath> {
        let mut w = Color::ONE;
        let (mut first_dist, mut length) = (0.0f32, 0.0f32);
        for d in 0..MAX_SPECULAR {
            let it = world.intersect(&ray, stats)?;
            let seg = it.t * ray.d.length();
            if d == 0 {
                first_dist = seg;
            }
            length += seg;
            let bsdf = &*world.bsdf_at(&it);
            let wo = -ray.d.normalize();
            if !bsdf.is_delta() {
                // A mixed BSDF (plastic coating, mask): its delta lobes are followed with
                // their sampling probability p, the rest shaded here with weight 1/(1 − p).
                let p = bsdf.delta_probability(&it.sp, wo);
                if p > 0.0 {
                    let u = key.uniform(0xDE17A + d as u64);
                    if u < p
                        && let Some(bs) = bsdf.sample(&it.sp, wo, u, [0.5; 2], TransportMode::Radiance)
                        && bs.delta
                    {
                        w *= bs.weight;
                        ray = world.spawn(&it, bs.wi);
                        continue;
                    }
                    if u < p {
                        return None;
                    }
                    w /= 1.0 - p;
                }
                return Some(SpecularPath { it, wo, weight: w, first_dist, length });
            }
            let (br, n) = bsdf.specular_branches(&it.sp, wo, TransportMode::Radiance);
            let (wi, bw) = pick_branch(&br[..n], key.uniform(d as u64))?;
            w *= bw;
            ray = world.spawn(&it, wi);
        }
        None
    }

    /// Radiance arriving along a gather ray of `level`, shaded where it lands:
    /// a photon-map lookup ([`PhotonContext::exitant_at_hit`]) on the last level, a
    /// full direct + caustic + gather on earlier ones. Also returns the distance to
    /// the first surface (∞ when the ray escapes). A ray that escapes carries no
    /// radiance: the environment seen from the gathering point is its direct light
    /// (light sampling), and seen through mirrors and glass its caustic.
    pub fn gather_ray(&self, world: &World, ray: Ray, level: usize, key: ShadeKey, stats: &mut TraversalStats) -> (Color, f32) {
        let Some(sp) = self.follow_specular_path(world, ray, key, stats) else { return (Color::ZERO, f32::INFINITY) };
        let hb = &*world.bsdf_at(&sp.it);
        let l = if level + 1 < self.gather_counts.len() {
            self.shade(&GatherPoint { world, it: &sp.it, wo: sp.wo, bsdf: hb, key, pixel: None }, level + 1, stats, false)
        } else {
            self.exitant_at_hit(world, &sp.it, sp.wo, hb, stats)
        };
        (l * sp.weight, sp.first_dist)
    }

    /// The rays a gather at `at` on `level` traces: (rays, sampler stream, index of
    /// the first ray). At a camera sample's point with a per-pixel `split` (rays per
    /// sample, [`PixelSplit`]), the sample's share of the pixel's point set (stream:
    /// the pixel's key); otherwise `n` rays from the point's own key (`salt`ed when
    /// given).
    #[inline]
    fn ray_set(at: &GatherPoint, level: usize, n: u32, split: Option<u32>, salt: Option<u64>) -> (u32, u64, u64) {
        let stream = |k: ShadeKey| salt.map_or(k.0, |s| k.child(s).0);
        match (split, at.pixel) {
            (Some(m), Some(px)) if level == 0 => (m, stream(px.key), px.index * m as u64),
            _ => (n, stream(at.key), 0),
        }
    }

    /// Final gather of the irradiance at `it` with the rays of `level` (0 = first
    /// level): directions cosine-distributed about the shading normal on the viewer's
    /// side (as `path` samples a Lambertian surface); directions below the geometric
    /// surface carry no light.
    pub fn final_gather(&self, at: &GatherPoint, level: usize, stats: &mut TraversalStats) -> GatherResult {
        let GatherPoint { world, it, wo, key, .. } = *at;
        let (n, stream, first) = Self::ray_set(at, level, self.gather_counts[level].max(1), self.pixel_split.map(|p| p.gather), None);
        let s = &self.gather_samplers[level];
        let frame = Frame::new(facing_shading_normal(it, wo));
        let (mut irr, mut inv_d) = (Color::ZERO, 0.0f32);
        for j in 0..n {
            let mut u = [0.0f32; 2];
            s.values_at(stream, first + j as u64, 0, &mut u);
            let wi = frame.to_world(cosine_hemisphere(u));
            if wi.dot(it.sp.ng) * wo.dot(it.sp.ng) <= 0.0 {
                continue;
            }
            let (l, dist) = self.gather_ray(world, world.spawn(it, wi), level, key.child(j as u64 + 1), stats);
            inv_d += 1.0 / dist.max(1e-6);
            irr += l;
        }
        // Cosine-weighted: E ≈ π/N Σ L. Rays that escape count as infinitely far.
        let harmonic_distance = if inv_d > 0.0 { n as f32 / inv_d } else { f32::INFINITY };
        GatherResult { irradiance: irr * (std::f32::consts::PI / n as f32), harmonic_distance }
    }

    /// Glossy part of the reflected indirect radiance: `glossy_samples` rays drawn
    /// from the glossy lobe alone, each shaded as a final-gather ray. Zero for
    /// surfaces without a glossy lobe.
    pub fn glossy_gather(&self, at: &GatherPoint, level: usize, stats: &mut TraversalStats) -> Color {
        let GatherPoint { world, it, wo, bsdf, key, .. } = *at;
        if !bsdf.has_glossy() {
            return Color::ZERO;
        }
        let (n, stream, first) = Self::ray_set(at, level, self.glossy_samples.max(1), self.pixel_split.map(|p| p.glossy), Some(0x6105));
        let key = key.child(0x6105);
        let mut sum = Color::ZERO;
        for j in 0..n {
            let mut u = [0.0f32; 2];
            self.glossy_sampler.values_at(stream, first + j as u64, 0, &mut u);
            let Some((wi, w)) = bsdf.sample_glossy(&it.sp, wo, u) else { continue };
            let (l, _) = self.gather_ray(world, world.spawn(it, wi), level, key.child(j as u64 + 1), stats);
            sum += w * l;
        }
        sum / n as f32
    }

    /// Indirect radiance towards `wo` by final gathering: Kd/π times the gathered
    /// irradiance, plus the glossy lobe's own gather.
    pub fn gathered_indirect(&self, at: &GatherPoint, level: usize, stats: &mut TraversalStats) -> Color {
        let kd = at.bsdf.diffuse_albedo();
        let mut l = Color::ZERO;
        if kd.max_element() > 0.0 {
            l += kd * std::f32::consts::FRAC_1_PI * self.final_gather(at, level, stats).irradiance;
        }
        l + self.glossy_gather(at, level, stats)
    }

    /// Full shading of a non-specular point at gather `level`: direct light, caustics
    /// and the indirect light of the next level (or `gather` at the first level).
    pub fn shade(&self, at: &GatherPoint, level: usize, stats: &mut TraversalStats, with_direct: bool) -> Color {
        let mut l = self.caustic(at.world, at.it, at.wo, at.bsdf, stats) + self.gathered_indirect(at, level, stats);
        if with_direct || level > 0 {
            l += self.direct_light(at, stats);
        }
        l
    }
}

/// Picks one branch with probability proportional to its weight's mean, returning
/// the direction and the weight divided by that probability.
#[inline]
pub fn pick_branch(br: &[(Vec3, Color)], u: f32) -> Option<(Vec3, Color)> {
    let total: f32 = br.iter().map(|b| crate::math::mean(b.1)).sum();
    if total <= 0.0 {
        return None;
    }
    let mut acc = 0.0;
    for (i, b) in br.iter().enumerate() {
        let p = crate::math::mean(b.1) / total;
        acc += p;
        if u < acc || i + 1 == br.len() {
            return if p > 0.0 { Some((b.0, b.1 / p)) } else { None };
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::PixelSplit;

    #[test]
    fn pixel_split_gives_each_sample_at_least_its_share() {
        let split = |g, s, spp| PixelSplit::new(g, s, spp);
        assert_eq!(split(64, 16, 16), PixelSplit { gather: 4, glossy: 1 });
        assert_eq!(split(20, 12, 8), PixelSplit { gather: 3, glossy: 2 });
        assert_eq!(split(4, 4, 16), PixelSplit { gather: 1, glossy: 1 });
        assert_eq!(split(64, 16, 1), PixelSplit { gather: 64, glossy: 16 });
        assert_eq!(split(64, 16, 0), PixelSplit { gather: 64, glossy: 16 });
    }
}

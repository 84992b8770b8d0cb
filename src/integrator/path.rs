//! `path`: the reference unbiased path tracer.
//!
//! Next-event estimation at every non-specular vertex (one light chosen in proportion
//! to power, a point sampled on it), combined with BSDF sampling by multiple importance
//! sampling (power heuristic) for area lights; delta lights are sampled only by NEE,
//! delta BSDF lobes only by BSDF sampling (their emitted hits count fully). Rays that
//! leave the scene return the environment light (MIS-weighted against its sampling).
//! Textured parameters are filled in at each hit (`World::bsdf_at`). Russian
//! roulette by the configured policy; `max_depth` bounces at most (unbounded by default).
//!
//! Extra images `direct`, `indirect`, `caustic` split the image by path type, as the
//! photon integrator's AOVs do: with k the first non-delta vertex from the camera,
//! light emitted at or before k, next-event estimation at k and the emitter hit by
//! the BSDF sample leaving k are *direct*; light reaching k through delta (mirror,
//! glass) vertices only is *caustic*; light that met another non-delta vertex after
//! k is *indirect*. The three add up to the full image.

use super::Integrator;
use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::math::{Color, power_heuristic};
use crate::rr::{RrContext, RussianRoulette, roulette};
use crate::sampler::{AnySampler, BOUNCE_BSDF_LOBE, BOUNCE_RR, Sampler, bounce_dim};
use crate::world::World;

/// Path tracer.
pub struct PathIntegrator {
    /// Maximum number of bounces (u32::MAX = unbounded).
    pub max_depth: u32,
    /// Russian-roulette policy.
    pub rr: Box<dyn RussianRoulette>,
    /// Which part of the light `li` returns.
    pub output: PathOutput,
}

/// Part of the image by path type (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathOutput {
    /// Everything.
    #[default]
    All,
    /// Emitted and direct light at the first non-delta vertex.
    Direct,
    /// Light through delta vertices only onto the first non-delta vertex.
    Caustic,
    /// Light that met a further non-delta vertex.
    Indirect,
}

impl PathOutput {
    /// Extra-image names.
    pub const NAMES: &'static [&'static str] = &["direct", "indirect", "caustic"];
}

impl Integrator for PathIntegrator {
    fn name(&self) -> &'static str {
        "path"
    }

    fn set_output(&mut self, aov: &str) -> anyhow::Result<()> {
        self.output = match aov {
            "all" => PathOutput::All,
            "direct" => PathOutput::Direct,
            "indirect" => PathOutput::Indirect,
            "caustic" => PathOutput::Caustic,
            _ => anyhow::bail!("integrator `path` has no extra image `{aov}` (known: {})", PathOutput::NAMES.join(", ")),
        };
        Ok(())
    }

    fn li(&self, world: &World, camera_ray: &Ray, sampler: &mut dyn Sampler, stats: &mut TraversalStats) -> Color {
        self.trace(world, camera_ray, sampler, stats)
    }

    fn li_any(&self, world: &World, ray: &Ray, sampler: &mut AnySampler, stats: &mut TraversalStats) -> Color {
        crate::sampler::with_sampler!(sampler, s => self.trace(world, ray, s, stats))
    }
}

impl PathIntegrator {
    /// [`Integrator::li`] for any sampler type (compiled once per sampler for
    /// [`Integrator::li_any`], once for the trait object).
    #[inline]
    fn trace<S: Sampler + ?Sized>(&self, world: &World, camera_ray: &Ray, sampler: &mut S, stats: &mut TraversalStats) -> Color {
        let want = |class: PathOutput| self.output == PathOutput::All || self.output == class;
        // Path-type state: the first non-delta vertex k seen; vertices after k so far
        // (before the current one); whether one of them was non-delta.
        let (mut k_seen, mut after_k, mut after_k_nondelta) = (false, 0u32, false);
        let mut l = Color::ZERO;
        let mut beta = Color::ONE;
        let mut ray = *camera_ray;
        let mut specular = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.o;
        let mut depth = 0u32;
        loop {
            let emit_class = if !k_seen || after_k == 0 {
                PathOutput::Direct
            } else if after_k_nondelta {
                PathOutput::Indirect
            } else {
                PathOutput::Caustic
            };
            let Some(it) = world.intersect(&ray, stats) else {
                // Escaped: the environment, weighted against its light sampling.
                if want(emit_class) && world.lights.env.is_some() {
                    let le = world.escaped(ray.d.normalize());
                    let w = if specular { 1.0 } else { power_heuristic(prev_pdf, world.lights.pdf_env(ray.d.normalize())) };
                    l += beta * le * w;
                }
                break;
            };
            let mat = world.material(&it);
            if it.front && mat.is_emitter() && want(emit_class) {
                if specular {
                    l += beta * mat.emission;
                } else {
                    let light_pdf = world.lights.pdf_area(it.tri, prev_p, it.p, it.sp.ng);
                    l += beta * mat.emission * power_heuristic(prev_pdf, light_pdf);
                }
            }
            if depth >= self.max_depth {
                break;
            }
            let wo = -ray.d.normalize();
            let bsdf = &*world.bsdf_at(&it);
            let dim = bounce_dim(depth);
            sampler.set_dimension(dim);
            let u_sel = sampler.next_1d();
            let u_light = sampler.next_2d();
            if !bsdf.is_delta()
                && want(if k_seen { PathOutput::Indirect } else { PathOutput::Direct })
                && let Some(ls) = world.lights.sample_li(&world.scene, it.p, u_sel, u_light)
            {
                let f = bsdf.eval(&it.sp, wo, ls.wi);
                if f.max_element() > 0.0 && ls.pdf > 0.0 {
                    let cos = ls.wi.dot(it.sp.ns()).abs();
                    let visible = if ls.dist.is_infinite() {
                        world.unoccluded_dir(&it, ls.wi, stats)
                    } else {
                        world.visible(&it, ls.point, ls.normal, stats)
                    };
                    if visible {
                        let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, bsdf.pdf(&it.sp, wo, ls.wi)) };
                        l += beta * f * ls.li * (cos * w / ls.pdf);
                    }
                }
            }
            sampler.set_dimension(dim + BOUNCE_BSDF_LOBE);
            let u_lobe = sampler.next_1d();
            let u_dir = sampler.next_2d();
            let Some(bs) = bsdf.sample(&it.sp, wo, u_lobe, u_dir, TransportMode::Radiance) else { break };
            if k_seen {
                after_k += 1;
                after_k_nondelta |= !bsdf.is_delta();
            } else {
                k_seen = !bsdf.is_delta();
            }
            beta *= bs.weight;
            if beta.max_element() <= 0.0 {
                break;
            }
            specular = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = it.p;
            depth += 1;
            sampler.set_dimension(dim + BOUNCE_RR);
            let u_rr = sampler.next_1d();
            let ctx = RrContext { depth, throughput: beta, albedo: bsdf.albedo() };
            match roulette(self.rr.as_ref(), &ctx, u_rr) {
                Some(w) => beta *= w,
                None => break,
            }
            ray = world.spawn(&it, bs.wi);
        }
        l
    }
}

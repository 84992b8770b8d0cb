//! `path`: the reference unbiased path tracer.
//!
//! Next-event estimation at every non-specular vertex (one light chosen in proportion
//! to power, a point sampled on it), combined with BSDF sampling by multiple importance
//! sampling (power heuristic) for area lights; delta lights are sampled only by NEE,
//! delta BSDF lobes only by BSDF sampling (their emitted hits count fully). Russian
//! roulette by the configured policy; `max_depth` bounces at most (unbounded by default).

use super::Integrator;
use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::math::{Color, power_heuristic};
use crate::rr::{RrContext, RussianRoulette, roulette};
use crate::sampler::{BOUNCE_BSDF_LOBE, BOUNCE_RR, Sampler, bounce_dim};
use crate::world::World;

/// Path tracer.
pub struct PathIntegrator {
    /// Maximum number of bounces (u32::MAX = unbounded).
    pub max_depth: u32,
    /// Russian-roulette policy.
    pub rr: Box<dyn RussianRoulette>,
}

impl Integrator for PathIntegrator {
    fn name(&self) -> &'static str {
        "path"
    }

    fn li(&self, world: &World, camera_ray: &Ray, sampler: &mut dyn Sampler, stats: &mut TraversalStats) -> Color {
        let mut l = Color::ZERO;
        let mut beta = Color::ONE;
        let mut ray = *camera_ray;
        let mut specular = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.o;
        let mut depth = 0u32;
        while let Some(it) = world.intersect(&ray, stats) {
            let mat = world.material(&it);
            if it.front && mat.is_emitter() {
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
            let bsdf = &mat.bsdf;
            let dim = bounce_dim(depth);
            sampler.set_dimension(dim);
            let u_sel = sampler.next_1d();
            let u_light = sampler.next_2d();
            if !bsdf.is_delta()
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

//! `path` in batches: the samples of a batch advance together, stage by stage —
//! closest hits of all live paths; emission and light sample of each; the shadow rays
//! of all; BSDF sample and roulette of each — so that the processor overlaps the work
//! of independent paths where one path's bounces wait on each other. Every path does
//! the arithmetic and sampler draws of [`PathIntegrator::trace`] in the same order
//! (its own sampler, the same dimensions), so each sample's radiance has the same bits.

use super::{PathIntegrator, PathOutput};
use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::light::LightSample;
use crate::material::{Bsdf, BsdfSample, TransportMode};
use crate::math::{Color, power_heuristic};
use crate::rr::{RrContext, roulette};
use crate::sampler::{AnySampler, BOUNCE_BSDF_LOBE, BOUNCE_RR, Concrete, Sampler, bounce_dim};
use crate::world::{Interaction, World};
use glam::Vec3;
use std::borrow::Cow;

/// Paths advanced together.
pub const LANES: usize = 16;

/// The state [`PathIntegrator::trace`] keeps in locals, per path.
#[derive(Clone, Copy)]
struct Lane {
    ray: Ray,
    l: Color,
    beta: Color,
    specular: bool,
    prev_pdf: f32,
    prev_p: Vec3,
    depth: u32,
    /// Path-type state: the first non-delta vertex k seen; vertices after k so far
    /// (before the current one); whether one of them was non-delta.
    k_seen: bool,
    after_k: u32,
    after_k_nondelta: bool,
}

impl Lane {
    fn new(ray: Ray) -> Self {
        Lane {
            ray,
            l: Color::ZERO,
            beta: Color::ONE,
            specular: true,
            prev_pdf: 0.0,
            prev_p: ray.o,
            depth: 0,
            k_seen: false,
            after_k: 0,
            after_k_nondelta: false,
        }
    }
    /// Class of light emitted at the current vertex (see the module documentation of
    /// `path`).
    #[inline]
    fn emit_class(&self) -> PathOutput {
        if !self.k_seen || self.after_k == 0 {
            PathOutput::Direct
        } else if self.after_k_nondelta {
            PathOutput::Indirect
        } else {
            PathOutput::Caustic
        }
    }
}

/// A next-event estimate waiting for its shadow ray.
struct Pending {
    lane: u8,
    ls: LightSample,
    f: Color,
    cos: f32,
}

impl PathIntegrator {
    /// [`crate::integrator::Integrator::li_batch`] for samplers of type `S`, `LANES`
    /// paths at a time.
    pub(super) fn trace_batch<S: Concrete>(
        &self,
        world: &World,
        rays: &[Ray],
        samplers: &mut [AnySampler],
        stats: &mut TraversalStats,
        out: &mut [Color],
    ) {
        let mut pending = Vec::with_capacity(LANES);
        for ((rays, samplers), out) in rays.chunks(LANES).zip(samplers.chunks_mut(LANES)).zip(out.chunks_mut(LANES)) {
            let mut ss: [Option<&mut S>; LANES] = Default::default();
            for (slot, a) in ss.iter_mut().zip(samplers.iter_mut()) {
                *slot = S::of(a);
            }
            if ss[..rays.len()].iter().any(Option::is_none) {
                // Samplers of mixed types (not what the render pass gives): one by one.
                for ((ray, a), o) in rays.iter().zip(samplers.iter_mut()).zip(out.iter_mut()) {
                    *o = crate::sampler::with_sampler!(a, s => self.trace(world, ray, s, stats));
                }
                continue;
            }
            self.trace_lanes(world, rays, &mut ss, &mut pending, stats, out);
        }
    }

    /// Up to [`LANES`] paths, stage by stage until none lives.
    fn trace_lanes<S: Sampler>(
        &self,
        world: &World,
        rays: &[Ray],
        ss: &mut [Option<&mut S>; LANES],
        pending: &mut Vec<Pending>,
        stats: &mut TraversalStats,
        out: &mut [Color],
    ) {
        let want = |class: PathOutput| self.output == PathOutput::All || self.output == class;
        let n = rays.len().min(LANES);
        let mut lanes = [Lane::new(Ray::new(Vec3::ZERO, Vec3::Z)); LANES];
        let mut live = [0u8; LANES];
        for k in 0..n {
            lanes[k] = Lane::new(rays[k]);
            live[k] = k as u8;
        }
        let mut n_live = n;
        let mut its: [Option<Interaction>; LANES] = [None; LANES];
        let mut bsdfs: [Option<Cow<'_, Bsdf>>; LANES] = Default::default();
        let mut wos = [Vec3::ZERO; LANES];
        // Per lane: (light choice, light point, lobe, direction) numbers; next-event
        // estimation wanted; the BSDF sample.
        let mut us = [(0.0f32, [0.0f32; 2], 0.0f32, [0.0f32; 2]); LANES];
        let mut nee = [false; LANES];
        let mut bss: [Option<BsdfSample>; LANES] = [None; LANES];
        while n_live > 0 {
            // Closest hits.
            for &k in &live[..n_live] {
                its[k as usize] = world.intersect(&lanes[k as usize].ray, stats);
            }
            // Emission (or the environment), the end of paths, light samples.
            pending.clear();
            let mut m = 0;
            for j in 0..n_live {
                let k = live[j] as usize;
                let lane = &mut lanes[k];
                let emit_class = lane.emit_class();
                let Some(it) = &its[k] else {
                    // Escaped: the environment, weighted against its light sampling.
                    if want(emit_class) && world.lights.env.is_some() {
                        let le = world.escaped(lane.ray.d.normalize());
                        let w =
                            if lane.specular { 1.0 } else { power_heuristic(lane.prev_pdf, world.lights.pdf_env(lane.ray.d.normalize())) };
                        lane.l += lane.beta * le * w;
                    }
                    continue;
                };
                let mat = world.material(it);
                if it.front && mat.is_emitter() && want(emit_class) {
                    if lane.specular {
                        lane.l += lane.beta * mat.emission;
                    } else {
                        let light_pdf = world.lights.pdf_area(it.tri, lane.prev_p, it.p, it.sp.ng);
                        lane.l += lane.beta * mat.emission * power_heuristic(lane.prev_pdf, light_pdf);
                    }
                }
                if lane.depth >= self.max_depth {
                    continue;
                }
                let Some(s) = ss[k].as_deref_mut() else { continue };
                let wo = -lane.ray.d.normalize();
                let bsdf = world.bsdf_at(it);
                let dim = bounce_dim(lane.depth);
                s.set_dimension(dim);
                let u_sel = s.next_1d();
                let u_light = s.next_2d();
                s.set_dimension(dim + BOUNCE_BSDF_LOBE);
                us[k] = (u_sel, u_light, s.next_1d(), s.next_2d());
                nee[k] = !bsdf.is_delta() && want(if lane.k_seen { PathOutput::Indirect } else { PathOutput::Direct });
                wos[k] = wo;
                bsdfs[k] = Some(bsdf);
                live[m] = k as u8;
                m += 1;
            }
            n_live = m;
            // Light samples.
            for &k in &live[..n_live] {
                let k = k as usize;
                let (Some(it), Some(bsdf)) = (&its[k], &bsdfs[k]) else { continue };
                let (u_sel, u_light, _, _) = us[k];
                if nee[k]
                    && let Some(ls) = world.lights.sample_li(&world.scene, it.p, u_sel, u_light)
                {
                    let f = bsdf.eval(&it.sp, wos[k], ls.wi);
                    if f.max_element() > 0.0 && ls.pdf > 0.0 {
                        let cos = ls.wi.dot(it.sp.ns()).abs();
                        pending.push(Pending { lane: k as u8, ls, f, cos });
                    }
                }
            }
            n_live = m;
            // Shadow rays.
            for p in pending.iter() {
                let k = p.lane as usize;
                let (Some(it), Some(bsdf)) = (&its[k], &bsdfs[k]) else { continue };
                let ls = &p.ls;
                let visible = if ls.dist.is_infinite() {
                    world.unoccluded_dir(it, ls.wi, stats)
                } else {
                    world.visible(it, ls.point, ls.normal, stats)
                };
                if visible {
                    let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, bsdf.pdf(&it.sp, wos[k], ls.wi)) };
                    let lane = &mut lanes[k];
                    lane.l += lane.beta * p.f * ls.li * (p.cos * w / ls.pdf);
                }
            }
            // BSDF samples.
            for &k in &live[..n_live] {
                let k = k as usize;
                let (Some(it), Some(bsdf)) = (&its[k], &bsdfs[k]) else { continue };
                let (_, _, u_lobe, u_dir) = us[k];
                bss[k] = bsdf.sample(&it.sp, wos[k], u_lobe, u_dir, TransportMode::Radiance);
            }
            // Roulette, the next rays.
            let mut m = 0;
            for j in 0..n_live {
                let k = live[j] as usize;
                let lane = &mut lanes[k];
                let (Some(it), Some(bsdf), Some(bs), Some(s)) = (&its[k], &bsdfs[k], &bss[k], ss[k].as_deref_mut()) else { continue };
                let dim = bounce_dim(lane.depth);
                if lane.k_seen {
                    lane.after_k += 1;
                    lane.after_k_nondelta |= !bsdf.is_delta();
                } else {
                    lane.k_seen = !bsdf.is_delta();
                }
                lane.beta *= bs.weight;
                if lane.beta.max_element() <= 0.0 {
                    continue;
                }
                lane.specular = bs.delta;
                lane.prev_pdf = bs.pdf;
                lane.prev_p = it.p;
                lane.depth += 1;
                s.set_dimension(dim + BOUNCE_RR);
                let u_rr = s.next_1d();
                let ctx = RrContext { depth: lane.depth, throughput: lane.beta, albedo: bsdf.albedo() };
                match roulette(self.rr.as_ref(), &ctx, u_rr) {
                    Some(w) => lane.beta *= w,
                    None => continue,
                }
                lane.ray = world.spawn(it, bs.wi);
                live[m] = k as u8;
                m += 1;
            }
            n_live = m;
        }
        for (o, lane) in out.iter_mut().zip(&lanes[..n]) {
            *o = lane.l;
        }
    }
}

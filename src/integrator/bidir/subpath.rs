//! Subpaths: the shared state of a random walk from the eye or from a light (its
//! throughput and the MIS partials of [`super::mis`]), one scattering step with its
//! forward and reverse densities, and the light subpath — whose non-delta vertices are
//! kept for connections and merging and joined to the eye (light tracing, t = 1).

use super::Ctx;
use super::lights::emit;
use super::mis::{Partials, weight_camera};
use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::material::{Bsdf, ShadingPoint, TransportMode};
use crate::math::Color;
use crate::rr::{RrContext, roulette};
use crate::sampler::{BOUNCE_BSDF_LOBE, BOUNCE_RR, Sampler, bounce_dim};
use crate::world::Interaction;
use glam::Vec3;

/// A stored light-subpath vertex (on a non-delta surface).
#[derive(Clone, Copy, Debug)]
pub struct LightVertex {
    /// The surface point.
    pub it: Interaction,
    /// Unit direction towards the previous vertex (where the light came from).
    pub w_prev: Vec3,
    /// Throughput: emitted power carried so far, divided by the densities.
    pub throughput: Color,
    /// Edges from the light to here (1 at the first hit).
    pub len: u32,
    /// MIS partials at this vertex.
    pub partials: Partials,
}

/// A light-tracing contribution to the pixel `pixel`.
#[derive(Clone, Copy, Debug)]
pub struct Splat {
    /// Pixel index (row-major).
    pub pixel: u32,
    /// Light vertices of the technique (s); the eye is t = 1.
    pub s: u32,
    /// MIS weight.
    pub weight: f32,
    /// Weighted contribution (already divided by the number of light subpaths).
    pub value: Color,
    /// The unidirectional techniques' share of the path's weights ([`super::mis::uni_share`]).
    pub uni: f32,
}

/// pbrt's correction for shading normals on light subpaths (Veach 1997, §5.3): the
/// cosine that replaces |w_out·n_s| when importance flows from `w_in` to `w_out`.
#[inline]
pub fn adjoint_cos(sp: &ShadingPoint, w_in: Vec3, w_out: Vec3) -> f32 {
    let d = w_in.dot(sp.ng).abs();
    if d == 0.0 {
        return 0.0;
    }
    w_in.dot(sp.ns()).abs() * w_out.dot(sp.ng).abs() / d
}

/// One sampled continuation of a subpath at a vertex.
pub struct Step {
    /// The new direction.
    pub wi: Vec3,
    /// Throughput factor (BSDF weight, shading correction, roulette).
    pub weight: Color,
    /// Whether a delta lobe was sampled.
    pub delta: bool,
}

/// Samples the continuation at `it` (incoming direction `wo`), updates the partials
/// with its forward and reverse densities and applies Russian roulette. `depth` is
/// the number of scattering events before this one; `rel` the throughput relative to
/// the start, for the roulette policy.
#[allow(clippy::too_many_arguments)]
pub fn scatter<S: Sampler + ?Sized>(
    ctx: &Ctx,
    s: &mut S,
    bsdf: &Bsdf,
    it: &Interaction,
    wo: Vec3,
    depth: u32,
    mode: TransportMode,
    partials: &mut Partials,
    rel: Color,
) -> Option<Step> {
    let dim = bounce_dim(depth);
    s.set_dimension(dim + BOUNCE_BSDF_LOBE);
    let u_lobe = s.next_1d();
    let u_dir = s.next_2d();
    let bs = bsdf.sample(&it.sp, wo, u_lobe, u_dir, mode)?;
    if bs.pdf <= 0.0 {
        return None;
    }
    let cos_out = bs.wi.dot(it.sp.ng);
    let pdf_rev = if bs.delta { bs.pdf } else { bsdf.pdf(&it.sp, bs.wi, wo) };
    partials.scatter(&ctx.f, cos_out, bs.pdf, pdf_rev, bs.delta);
    let mut weight = bs.weight;
    if mode == TransportMode::Importance {
        let c = bs.wi.dot(it.sp.ns()).abs();
        weight *= if c > 0.0 { adjoint_cos(&it.sp, wo, bs.wi) / c } else { 0.0 };
    }
    if weight.max_element() <= 0.0 || !crate::math::is_finite(weight) {
        return None;
    }
    s.set_dimension(dim + BOUNCE_RR);
    let u_rr = s.next_1d();
    let q = roulette(ctx.rr, &RrContext { depth: depth + 1, throughput: rel * weight, albedo: bsdf.albedo() }, u_rr)?;
    Some(Step { wi: bs.wi, weight: weight * q, delta: bs.delta })
}

/// Traces one light subpath (sample `index` of `stream`): appends its non-delta
/// vertices to `out` (when connections or merging use them) and its light-tracing
/// contributions to `splats`.
pub fn trace_light<S: Sampler + ?Sized>(
    ctx: &Ctx,
    s: &mut S,
    stream: u64,
    index: u64,
    out: &mut Vec<LightVertex>,
    splats: &mut Vec<Splat>,
    stats: &mut TraversalStats,
) {
    let world = ctx.world;
    s.start(stream, index);
    let u_sel = s.next_1d();
    let u_pos = s.next_2d();
    let u_dir = s.next_2d();
    let Some(e) = emit(&world.lights, &world.scene, u_sel, u_pos, u_dir) else { return };
    if e.emission_pdf_w.is_nan() || e.emission_pdf_w <= 0.0 || !crate::math::is_finite(e.throughput) {
        return;
    }
    let mut partials = Partials::light_start(&ctx.f, e.direct_pdf_a, e.emission_pdf_w, e.cos, e.delta, e.finite);
    let initial = e.throughput;
    let mut beta = e.throughput;
    let mut ray = Ray::new(e.origin, e.dir);
    let mut prev = e.origin;
    let mut len = 1u32;
    let keep = ctx.mode.connect || ctx.mode.merge;
    while let Some(it) = world.intersect(&ray, stats) {
        let wo = -ray.d.normalize();
        let d2 = (it.p - prev).length_squared();
        partials.arrive(ctx.f.h, (len > 1 || e.finite).then_some(d2), wo.dot(it.sp.ng));
        let bsdf_at = world.bsdf_at(&it);
        let bsdf: &Bsdf = &bsdf_at;
        if !bsdf.is_delta() {
            let v = LightVertex { it, w_prev: wo, throughput: beta, len, partials };
            if keep {
                out.push(v);
            }
            if (ctx.mode.connect || ctx.mode.lt) && len < ctx.max_len {
                connect_to_camera(ctx, bsdf, &v, splats, stats);
            }
        }
        if len + 2 > ctx.max_len {
            break;
        }
        let rel = Color::new(ratio(beta.x, initial.x), ratio(beta.y, initial.y), ratio(beta.z, initial.z));
        let Some(step) = scatter(ctx, s, bsdf, &it, wo, len - 1, TransportMode::Importance, &mut partials, rel) else { break };
        beta *= step.weight;
        prev = it.p;
        ray = world.spawn(&it, step.wi);
        len += 1;
    }
}

#[inline]
fn ratio(a: f32, b: f32) -> f32 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// Light tracing: joins light vertex `v` to the eye (SmallVCM's `ConnectToCamera`).
fn connect_to_camera(ctx: &Ctx, bsdf: &Bsdf, v: &LightVertex, splats: &mut Vec<Splat>, stats: &mut TraversalStats) {
    let cam = &ctx.world.scene.camera;
    let Some(k) = cam.connect(v.it.p) else { return };
    let f = bsdf.eval(&v.it.sp, k.to_eye, v.w_prev);
    if f.max_element() <= 0.0 {
        return;
    }
    let cos_g = k.to_eye.dot(v.it.sp.ng).abs();
    let inv_d2 = 1.0 / (k.dist * k.dist);
    // Area density of this vertex when sampled from the eye.
    let camera_pdf_a = k.pdf_dir * cos_g * inv_d2;
    let bsdf_rev = super::eye::if_used(v.partials.dvc, || bsdf.pdf(&v.it.sp, k.to_eye, v.w_prev));
    let weight = if ctx.mode.lt { 1.0 } else { weight_camera(&ctx.f, &v.partials, camera_pdf_a, bsdf_rev) };
    let value = v.throughput * f * (weight * adjoint_cos(&v.it.sp, v.w_prev, k.to_eye) * k.pdf_dir * inv_d2 / ctx.f.light_paths);
    if value.max_element() <= 0.0 || !crate::math::is_finite(value) {
        return;
    }
    if !ctx.world.visible(&v.it, cam.eye, Vec3::ZERO, stats) {
        return;
    }
    let (x, y) = (k.raster.0 as u32, k.raster.1 as u32);
    let pixel = y.min(cam.height - 1) * cam.width + x.min(cam.width - 1);
    let uni = super::mis::uni_share(weight, super::mis::uni_camera(&ctx.f, &v.partials, camera_pdf_a, bsdf_rev));
    splats.push(Splat { pixel, s: v.len + 1, weight, value, uni });
}

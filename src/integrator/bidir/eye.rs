//! The camera (eye) subpath of one pixel sample and every technique that ends on it:
//! emitters it hits (s = 0), direct light sampling (s = 1), connections to the
//! vertices of its own light subpath or drawn from the pass's (s ≥ 2, t ≥ 2) and
//! merging with the light vertices of the whole pass near its first non-delta vertex
//! (or each one, `vcm_merge = "all"`; SmallVCM's camera loop).

use super::Ctx;
use super::grid::HashGrid;
use super::lights::{emitter_pdfs, env_radiance, illuminate};
use super::mis::{
    Partials, uni_connect, uni_direct, uni_hit, uni_merge, uni_share, w_to_a, weight_connect, weight_direct, weight_hit, weight_merge,
};
use super::subpath::{LightVertex, adjoint_cos, scatter};
use crate::accel::TraversalStats;
use crate::material::{Bsdf, TransportMode};
use crate::math::Color;
use crate::photon::nearest::prefetch_all;
use crate::sampler::{BOUNCE_LIGHT_SELECT, DIM_PIXEL, Sampler, bounce_dim};
use crate::world::Interaction;
use glam::Vec3;

/// Technique index of merging in [`Record::add`].
pub const MERGE: u32 = u32::MAX;

/// Receives every technique's contribution (per-strategy images).
pub trait Record {
    /// Technique (s light vertices, t camera vertices; s = [`MERGE`] for merging),
    /// its MIS weight and weighted contribution (camera throughput applied).
    fn add(&mut self, s: u32, t: u32, weight: f32, value: Color);
    /// One contribution `value` of a path and the unidirectional techniques' share of
    /// its weights ([`super::mis::uni_share`]), for the pilot of `vcm_select`.
    #[inline]
    fn moment(&mut self, _value: Color, _uni: f32) {}
    /// One merging contribution `value` (also given to [`Record::moment`]), for the
    /// pilot's variance of the merges, which grows as the radius shrinks.
    #[inline]
    fn merged(&mut self, _value: Color) {}
}

/// Records nothing.
pub struct NoRecord;

impl Record for NoRecord {
    #[inline]
    fn add(&mut self, _: u32, _: u32, _: f32, _: Color) {}
}

/// The light vertices a camera subpath may merge with.
pub struct MergeSet<'a> {
    /// All light vertices of the pass.
    pub vertices: &'a [LightVertex],
    /// Their grid.
    pub grid: &'a HashGrid,
}

/// The pass's light vertices, when each camera vertex is joined to
/// [`super::Ctx::pool_draws`] of them drawn uniformly (Davidovič et al. 2014's light
/// vertex cache) instead of to every vertex of its own light subpath.
pub struct Pool<'a> {
    /// All light vertices of the pass.
    pub vertices: &'a [LightVertex],
    /// Vertices / (draws · light subpaths): one drawn vertex's estimate factor.
    pub scale: f32,
}

/// Dimension offset within a bounce of the draw from the pool (the one the `BOUNCE_*`
/// layout leaves free).
const BOUNCE_POOL: u32 = 7;
const _: () = assert!(
    BOUNCE_POOL < crate::sampler::DIMS_PER_BOUNCE
        && BOUNCE_POOL > crate::sampler::BOUNCE_RR
        && BOUNCE_POOL >= crate::sampler::BOUNCE_BSDF_DIR + 2
);

/// Smallest cosine between the normals of a merged light vertex and camera vertex
/// (as `sppm`'s photon test: light on another face of a corner is not merged).
const MERGE_NORMAL_COS: f32 = crate::integrator::progressive::sppm::NORMAL_COS;

/// Radiance estimate of pixel (x, y)'s camera subpath of sample `index`.
#[allow(clippy::too_many_arguments)]
pub fn trace_eye<S: Sampler + ?Sized, R: Record>(
    ctx: &Ctx,
    s: &mut S,
    x: u32,
    y: u32,
    index: u64,
    light_path: &[LightVertex],
    pool: Option<&Pool>,
    merge: Option<&MergeSet>,
    rec: &mut R,
    stats: &mut TraversalStats,
) -> Color {
    let world = ctx.world;
    let cam = &world.scene.camera;
    s.start(y as u64 * cam.width as u64 + x as u64, index);
    s.set_dimension(DIM_PIXEL);
    let u = s.next_2d();
    let mut ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
    let mut partials = Partials::camera_start(&ctx.f, cam.pdf_dir(ray.d));
    let mut beta = Color::ONE;
    let mut l = Color::ZERO;
    let mut prev = ray.o;
    let mut len = 1u32;
    let mut specular_path = true;
    let mode = ctx.mode;
    let pool = pool.filter(|_| mode.connect && !mode.lt);
    loop {
        // The pool draws of the vertex this ray will hit (if it is non-delta), made
        // before the ray is traced so that fetching the drawn vertices (random places
        // in the pass's pool) overlaps the traversal. The sampler's values depend on
        // the dimension only, not on the order of the draws.
        let u_pool = match pool {
            Some(pool) if len < ctx.max_len => {
                s.set_dimension(bounce_dim(len - 1) + BOUNCE_POOL);
                let u = s.next_1d();
                for k in 0..ctx.pool_draws.min(4) {
                    prefetch_all(&pool.vertices[pool_index(k, u, ctx.pool_draws, pool.vertices.len())]);
                }
                u
            }
            _ => 0.0,
        };
        let Some(it) = world.intersect(&ray, stats) else {
            // Left the scene: the environment (s = 0), SmallVCM's background hit. The
            // partials stay as the last scattering left them: a light at infinity has
            // no distance or cosine at its "vertex".
            if let Some((le, da, ew)) = env_radiance(&world.lights, ray.d.normalize()) {
                let w = hit_weight(ctx, len, specular_path, &partials, Some((da, ew)));
                if w > 0.0 && le.max_element() > 0.0 {
                    let v = beta * le * w;
                    l += v;
                    rec.add(0, len + 1, w, v);
                    rec.moment(v, hit_uni(ctx, len, &partials, Some(da), w));
                }
            }
            break;
        };
        let wo = -ray.d.normalize();
        partials.arrive(ctx.f.h, Some((it.p - prev).length_squared()), wo.dot(it.sp.ng));
        let mat = world.material(&it);
        if it.front && mat.is_emitter() {
            let pdfs = emitter_pdfs(&world.lights, it.tri, wo);
            let w = hit_weight(ctx, len, specular_path, &partials, pdfs);
            if w > 0.0 {
                let v = beta * mat.emission * w;
                l += v;
                rec.add(0, len + 1, w, v);
                rec.moment(v, hit_uni(ctx, len, &partials, pdfs.map(|p| p.0), w));
            }
        }
        if mode.lt || len >= ctx.max_len {
            break;
        }
        let bsdf_at = world.bsdf_at(&it);
        let bsdf: &Bsdf = &bsdf_at;
        if !bsdf.is_delta() {
            if mode.connect {
                l += direct(ctx, s, bsdf, &it, wo, &partials, beta, len, rec, stats);
                if let Some(pool) = pool {
                    // Stratified draws: one uniform number (`u_pool`), m evenly spaced picks.
                    let (m, n) = (ctx.pool_draws, pool.vertices.len());
                    for k in 0..m {
                        let v = &pool.vertices[pool_index(k, u_pool, m, n)];
                        if v.len + 1 + len > ctx.max_len {
                            continue;
                        }
                        let (w, c, uni) = connect(ctx, bsdf, &it, wo, &partials, v, stats);
                        if w > 0.0 {
                            let c = beta * c * pool.scale;
                            l += c;
                            rec.add(v.len + 1, len + 1, w, c);
                            rec.moment(c, uni);
                        }
                    }
                } else {
                    for v in light_path {
                        if v.len + 1 + len > ctx.max_len {
                            break;
                        }
                        let (w, c, uni) = connect(ctx, bsdf, &it, wo, &partials, v, stats);
                        if w > 0.0 {
                            let c = beta * c;
                            l += c;
                            rec.add(v.len + 1, len + 1, w, c);
                            rec.moment(c, uni);
                        }
                    }
                }
            }
            if let (true, true, Some(m)) = (mode.merge, partials.merges, merge) {
                let c = beta * merge_at(ctx, bsdf, &it, wo, &partials, len, m, beta * ctx.vm_norm, rec) * ctx.vm_norm;
                l += c;
                rec.add(super::eye::MERGE, len + 1, 1.0, c);
                if mode.ppm {
                    break;
                }
            }
        }
        let Some(step) = scatter(ctx, s, bsdf, &it, wo, len - 1, TransportMode::Radiance, &mut partials, beta) else { break };
        beta *= step.weight;
        specular_path &= step.delta;
        prev = it.p;
        ray = world.spawn(&it, step.wi);
        len += 1;
    }
    l
}

/// A reverse density, which the MIS weights only multiply by its subpath's partial
/// `factor` (dVC or dVM): not evaluated where that is 0 — at a camera subpath's first
/// non-delta vertex after only delta ones (where merging happens by default), at a
/// light subpath's first vertex from a delta light — as 0 · pdf = 0 for any finite
/// density (images unchanged).
#[inline]
pub(super) fn if_used(factor: f32, pdf: impl FnOnce() -> f32) -> f32 {
    if factor == 0.0 { 0.0 } else { pdf() }
}

/// Index of draw `k` of `m` stratified draws from a pool of `n` vertices, by the one
/// uniform number `u`.
#[inline]
fn pool_index(k: u32, u: f32, m: u32, n: usize) -> usize {
    (((k as f32 + u) / m as f32 * n as f32) as usize).min(n - 1)
}

/// Weight of a camera path of `len` edges ending on an emitter (s = 0) with the
/// emitter's densities `pdfs` (direct_pdf_a, emission_pdf_w; `None`: not a light).
#[inline]
fn hit_weight(ctx: &Ctx, len: u32, specular_path: bool, partials: &Partials, pdfs: Option<(f32, f32)>) -> f32 {
    let mode = ctx.mode;
    if len == 1 {
        1.0
    } else if mode.merge && !mode.connect {
        if specular_path { 1.0 } else { 0.0 }
    } else if mode.connect {
        match pdfs {
            Some((da, ew)) => weight_hit(&ctx.f, partials, da, ew),
            None => 0.0,
        }
    } else {
        0.0
    }
}

/// [`uni_share`] of an emitter hit with weight `w` (`direct_pdf_a`: `None` off a light).
#[inline]
fn hit_uni(ctx: &Ctx, len: u32, partials: &Partials, direct_pdf_a: Option<f32>, w: f32) -> f32 {
    match direct_pdf_a {
        _ if len == 1 => 1.0,
        Some(da) if ctx.mode.connect => uni_share(w, uni_hit(&ctx.f, partials, da)),
        _ => w,
    }
}

/// Direct light sampling at a camera vertex (s = 1), weighted and with β applied.
#[allow(clippy::too_many_arguments)]
fn direct<S: Sampler + ?Sized, R: Record>(
    ctx: &Ctx,
    s: &mut S,
    bsdf: &Bsdf,
    it: &Interaction,
    wo: Vec3,
    partials: &Partials,
    beta: Color,
    len: u32,
    rec: &mut R,
    stats: &mut TraversalStats,
) -> Color {
    let world = ctx.world;
    s.set_dimension(bounce_dim(len - 1) + BOUNCE_LIGHT_SELECT);
    let u_sel = s.next_1d();
    let u_light = s.next_2d();
    let Some(il) = illuminate(&world.lights, &world.scene, it.p, u_sel, u_light) else { return Color::ZERO };
    if il.direct_pdf_w.is_nan() || il.direct_pdf_w <= 0.0 {
        return Color::ZERO;
    }
    let f = bsdf.eval(&it.sp, wo, il.wi);
    if f.max_element() <= 0.0 {
        return Color::ZERO;
    }
    let bsdf_dir = bsdf.pdf(&it.sp, wo, il.wi);
    let bsdf_rev = if_used(partials.dvc, || bsdf.pdf(&it.sp, il.wi, wo));
    let w = weight_direct(
        &ctx.f,
        partials,
        il.pick,
        il.direct_pdf_w,
        il.emission_pdf_w,
        il.cos_at_light,
        il.delta,
        bsdf_dir,
        bsdf_rev,
        il.wi.dot(it.sp.ng),
    );
    let c = beta * f * il.radiance * (w * il.wi.dot(it.sp.ns()).abs() / (il.pick * il.direct_pdf_w));
    if c.max_element() <= 0.0 {
        return Color::ZERO;
    }
    let visible =
        if il.dist.is_infinite() { world.unoccluded_dir(it, il.wi, stats) } else { world.visible(it, il.point, il.normal, stats) };
    if !visible {
        return Color::ZERO;
    }
    rec.add(1, len + 1, w, c);
    rec.moment(c, uni_share(w, uni_direct(&ctx.f, il.pick, il.direct_pdf_w, il.delta, bsdf_dir)));
    c
}

/// Connects camera vertex `it` to light vertex `v`: (MIS weight, weighted
/// contribution without the camera throughput, [`uni_share`]); zeros when blocked or zero.
pub fn connect(
    ctx: &Ctx,
    bsdf: &Bsdf,
    it: &Interaction,
    wo: Vec3,
    cam: &Partials,
    v: &LightVertex,
    stats: &mut TraversalStats,
) -> (f32, Color, f32) {
    let none = (0.0, Color::ZERO, 0.0);
    let d = v.it.p - it.p;
    let dist2 = d.length_squared();
    if dist2.is_nan() || dist2 <= 0.0 {
        return none;
    }
    let dir = d / dist2.sqrt();
    let f_c = bsdf.eval(&it.sp, wo, dir);
    if f_c.max_element() <= 0.0 {
        return none;
    }
    let lbsdf_at = ctx.world.bsdf_at(&v.it);
    let lbsdf: &Bsdf = &lbsdf_at;
    let f_l = lbsdf.eval(&v.it.sp, -dir, v.w_prev);
    if f_l.max_element() <= 0.0 {
        return none;
    }
    let (cos_c, cos_l) = (dir.dot(it.sp.ng), dir.dot(v.it.sp.ng));
    let cam_to_light_a = w_to_a(bsdf.pdf(&it.sp, wo, dir), dist2, cos_l);
    let light_to_cam_a = w_to_a(lbsdf.pdf(&v.it.sp, v.w_prev, -dir), dist2, cos_c);
    let light_rev = if_used(v.partials.dvc, || lbsdf.pdf(&v.it.sp, -dir, v.w_prev));
    let w =
        weight_connect(&ctx.f, &v.partials, cam, cam_to_light_a, light_to_cam_a, light_rev, if_used(cam.dvc, || bsdf.pdf(&it.sp, dir, wo)));
    let g = dir.dot(it.sp.ns()).abs() * adjoint_cos(&v.it.sp, v.w_prev, -dir) / dist2;
    let c = f_c * f_l * v.throughput * (w * g);
    if c.max_element() <= 0.0 || !crate::math::is_finite(c) {
        return none;
    }
    if !ctx.world.visible(it, v.it.p, v.it.sp.ng, stats) {
        return none;
    }
    (w, c, uni_share(w, uni_connect(&ctx.f, &v.partials, cam_to_light_a, light_rev)))
}

/// Σ over the pass's light vertices within the radius of w·f·throughput (before
/// the camera throughput and the density normalisation 1/(π r² N), whose product is
/// `scale`); each vertex's term times `scale` is recorded as a [`Record::moment`].
#[allow(clippy::too_many_arguments)]
fn merge_at<R: Record>(
    ctx: &Ctx,
    bsdf: &Bsdf,
    it: &Interaction,
    wo: Vec3,
    cam: &Partials,
    len: u32,
    m: &MergeSet,
    scale: Color,
    rec: &mut R,
) -> Color {
    let r2 = ctx.radius * ctx.radius;
    let n = if wo.dot(it.sp.ng) >= 0.0 { it.sp.ng } else { -it.sp.ng };
    let mut sum = Color::ZERO;
    // The vertices within the radius are gathered (and their fetch started) before any
    // is read, in batches, so their loads overlap; the sum runs in the same order.
    let mut batch = [0u32; MERGE_BATCH];
    let mut k = 0;
    let mut flush = |batch: &[u32], sum: &mut Color| {
        for &i in batch {
            let v = &m.vertices[i as usize];
            if v.len + len > ctx.max_len {
                continue;
            }
            // The light arrived on the camera vertex's side of a surface facing like it.
            if v.it.sp.ng.dot(n).abs() < MERGE_NORMAL_COS || v.w_prev.dot(n) <= 0.0 {
                continue;
            }
            let f = bsdf.eval(&it.sp, wo, v.w_prev);
            if f.max_element() <= 0.0 {
                continue;
            }
            let cam_dir = bsdf.pdf(&it.sp, wo, v.w_prev);
            let w = if ctx.mode.ppm {
                1.0
            } else {
                weight_merge(&ctx.f, &v.partials, cam, cam_dir, if_used(cam.dvm, || bsdf.pdf(&it.sp, v.w_prev, wo)))
            };
            *sum += f * v.throughput * w;
            let c = scale * f * v.throughput * w;
            rec.moment(c, uni_share(w, uni_merge(&ctx.f, &v.partials, cam_dir)));
            rec.merged(c);
        }
    };
    m.grid.for_each_bucket(it.p, |slots| {
        for key in m.grid.keys(slots) {
            if key.p.distance_squared(it.p) > r2 {
                continue;
            }
            prefetch_all(&m.vertices[key.index as usize]);
            batch[k] = key.index;
            k += 1;
            if k == MERGE_BATCH {
                flush(&batch, &mut sum);
                k = 0;
            }
        }
    });
    flush(&batch[..k], &mut sum);
    sum
}

/// Light vertices within the radius gathered before they are read in [`merge_at`].
const MERGE_BATCH: usize = 16;

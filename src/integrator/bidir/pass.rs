//! One pass of the bidirectional estimators: N light subpaths (chunks in parallel;
//! their light-tracing splats kept per chunk), the merging grid over all light
//! vertices (when merging), then a camera subpath per pixel p joined to light subpath
//! p mod N (or to vertices drawn from all light vertices of the pass, with
//! `vcm_connect_draws`) and merged with the pass's light vertices. The splats are added chunk by
//! chunk in order after the camera phase, so the image is bit-identical for any
//! thread count.

use super::Ctx;
use super::eye::{MergeSet, Pool, Record, trace_eye};
use super::grid::HashGrid;
use super::subpath::{LightVertex, Splat, trace_light};
use crate::accel::TraversalStats;
use crate::math::{Color, hash_words, is_finite};
use crate::sampler::AnySampler;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::time::Instant;

/// Sampler stream of light subpath `j` (sample index = pass; bit 62 set, bit 63 clear:
/// never a pixel's camera stream nor `sppm`'s photon streams). With one light subpath
/// per pixel, j is the pixel, as SmallVCM pairs them.
#[inline]
pub fn light_stream(j: u64) -> u64 {
    (hash_words(&[j, 0xB1D1]) & !(1 << 63)) | 1 << 62
}

/// Light subpaths traced by one task of the light phase.
const LIGHT_CHUNK: u32 = 64;

/// One technique's contribution at one pixel (per-strategy images).
#[derive(Clone, Copy, Debug)]
pub struct Item {
    /// Pixel index.
    pub pixel: u32,
    /// Light vertices (or [`super::eye::MERGE`]).
    pub s: u32,
    /// Camera vertices.
    pub t: u32,
    /// MIS weight.
    pub weight: f32,
    /// Weighted contribution.
    pub value: Color,
}

/// Collects items of a row when on, and the row's moments when `moments` is not empty.
struct RowRecord {
    on: bool,
    pixel: u32,
    items: Vec<Item>,
    /// Column of the current pixel.
    x: usize,
    /// Per pixel of the row: see [`PassOut::moments`].
    moments: Vec<(DVec3, DVec3)>,
    /// Per pixel of the row (with moments): see [`PassOut::merged`].
    merged: Vec<DVec3>,
}

impl Record for RowRecord {
    #[inline]
    fn add(&mut self, s: u32, t: u32, weight: f32, value: Color) {
        if self.on {
            self.items.push(Item { pixel: self.pixel, s, t, weight, value });
        }
    }
    #[inline]
    fn moment(&mut self, value: Color, uni: f32) {
        if let Some(m) = self.moments.get_mut(self.x) {
            add_moment(m, value, uni);
        }
    }
    #[inline]
    fn merged(&mut self, value: Color) {
        if let Some(m) = self.merged.get_mut(self.x) {
            *m += value.as_dvec3();
        }
    }
}

/// Adds a contribution's square and its square over the unidirectional share (a
/// share of 0, a path that path tracing cannot sample, counts 10⁹ times).
#[inline]
fn add_moment(m: &mut (DVec3, DVec3), value: Color, uni: f32) {
    let v = value.as_dvec3();
    m.0 += v * v;
    m.1 += v * v / (uni as f64).max(1e-9);
}

/// A pass's image (radiance per pixel, f64) and counters.
#[derive(Default)]
pub struct PassOut {
    /// Pixel estimates of this pass.
    pub pixels: Vec<DVec3>,
    /// Rays traced.
    pub traversal: TraversalStats,
    /// Non-finite samples dropped.
    pub nonfinite: u64,
    /// Light vertices stored.
    pub light_vertices: u64,
    /// Seconds in the light phase (subpaths, splats), the grid and the camera phase.
    pub t_light: f64,
    /// Grid build seconds.
    pub t_grid: f64,
    /// Camera phase seconds.
    pub t_eye: f64,
    /// Technique contributions, when recorded.
    pub items: Vec<Item>,
    /// With `moments`, per pixel: Σ C² over the pass's contributions C to the pixel, and
    /// Σ C² / (w₀ + w₁), the unidirectional techniques' share of each one's weights —
    /// estimates of the second moments, without the terms between contributions, of
    /// this combination and of path tracing's (under the balance heuristic
    /// ∫ f²/Σₜpₜ and ∫ f²/(p₀ + p₁), estimated by Σ C · f/Σₜpₜ = Σ C² and Σ C² Σₜpₜ/(p₀ + p₁)).
    pub moments: Vec<(DVec3, DVec3)>,
    /// With `moments`, per pixel: the merges' part of the pass's estimate.
    pub merged: Vec<DVec3>,
}

/// A row of the camera phase: pixels, counters, non-finite samples, items, moments.
type EyeRow = (Vec<DVec3>, TraversalStats, u64, Vec<Item>, (Vec<(DVec3, DVec3)>, Vec<DVec3>));

struct LightChunk {
    vertices: Vec<LightVertex>,
    /// End of each light subpath of the chunk in `vertices`.
    ends: Vec<u32>,
    splats: Vec<Splat>,
    stats: TraversalStats,
}

/// Runs pass `index` (the sample index of every camera and light stream), merging
/// through `grid` (rebuilt here when merging; its buffers kept for the next pass);
/// `record`: the items, `moments`: [`PassOut::moments`].
pub fn run_pass(
    ctx: &Ctx,
    cam_sampler: &AnySampler,
    light_sampler: &AnySampler,
    index: u64,
    record: bool,
    moments: bool,
    grid: &mut HashGrid,
) -> PassOut {
    let cam = &ctx.world.scene.camera;
    let (w, h) = (cam.width, cam.height);
    let n_light = ctx.light_paths;
    let t0 = Instant::now();
    let chunks: Vec<LightChunk> = (0..n_light.div_ceil(LIGHT_CHUNK))
        .into_par_iter()
        .with_max_len(1)
        .map_init(
            || light_sampler.clone(),
            |s, c| {
                let paths = c * LIGHT_CHUNK..((c + 1) * LIGHT_CHUNK).min(n_light);
                let mut row = LightChunk {
                    vertices: Vec::new(),
                    ends: Vec::with_capacity(paths.len()),
                    splats: Vec::new(),
                    stats: TraversalStats::default(),
                };
                crate::sampler::with_sampler!(&mut *s, s => {
                    for j in paths {
                        trace_light(ctx, s, light_stream(j as u64), index, &mut row.vertices, &mut row.splats, &mut row.stats);
                        row.ends.push(row.vertices.len() as u32);
                    }
                });
                row
            },
        )
        .collect();
    // Light subpath j's vertices.
    let light_path = |j: u32| -> &[LightVertex] {
        let r = &chunks[(j / LIGHT_CHUNK) as usize];
        let k = (j % LIGHT_CHUNK) as usize;
        let start = if k == 0 { 0 } else { r.ends[k - 1] as usize };
        &r.vertices[start..r.ends[k] as usize]
    };
    let mut out = PassOut { t_light: t0.elapsed().as_secs_f64(), ..Default::default() };
    out.light_vertices = chunks.iter().map(|r| r.vertices.len() as u64).sum();
    let t1 = Instant::now();
    let mut all = Vec::new();
    let use_pool = ctx.mode.connect && ctx.pool_draws > 0;
    if ctx.mode.merge || use_pool {
        all.reserve(out.light_vertices as usize);
        for r in &chunks {
            all.extend_from_slice(&r.vertices);
        }
    }
    if ctx.mode.merge {
        let points: Vec<Vec3> = all.iter().map(|v| v.it.p).collect();
        grid.build(&points, ctx.radius);
    }
    let merge = ctx.mode.merge.then_some(MergeSet { vertices: &all, grid: &*grid });
    let pool = (use_pool && !all.is_empty())
        .then(|| Pool { vertices: &all, scale: all.len() as f32 / (ctx.pool_draws as f32 * ctx.light_paths as f32) });
    out.t_grid = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let eye_rows: Vec<EyeRow> = (0..h)
        .into_par_iter()
        .with_max_len(1)
        .map_init(
            || cam_sampler.clone(),
            |s, y| {
                let mut st = TraversalStats::default();
                let mut bad = 0u64;
                let row_moments = if moments { vec![Default::default(); w as usize] } else { Vec::new() };
                let row_merged = if moments { vec![DVec3::ZERO; w as usize] } else { Vec::new() };
                let mut rec = RowRecord { on: record, pixel: 0, items: Vec::new(), x: 0, moments: row_moments, merged: row_merged };
                let mut px = Vec::with_capacity(w as usize);
                crate::sampler::with_sampler!(&mut *s, s => {
                    for x in 0..w {
                        rec.pixel = y * w + x;
                        rec.x = x as usize;
                        let path = light_path(rec.pixel % n_light);
                        let l = trace_eye(ctx, s, x, y, index, path, pool.as_ref(), merge.as_ref(), &mut rec, &mut st);
                        if is_finite(l) {
                            px.push(l.as_dvec3());
                        } else {
                            bad += 1;
                            px.push(DVec3::ZERO);
                        }
                    }
                });
                (px, st, bad, rec.items, (rec.moments, rec.merged))
            },
        )
        .collect();
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for (px, st, bad, items, (m, merged)) in eye_rows {
        pixels.extend(px);
        out.moments.extend(m);
        out.merged.extend(merged);
        out.traversal.add(&st);
        out.nonfinite += bad;
        out.items.extend(items);
    }
    for r in &chunks {
        out.traversal.add(&r.stats);
        for sp in &r.splats {
            if is_finite(sp.value) {
                pixels[sp.pixel as usize] += sp.value.as_dvec3();
                if let Some(m) = out.moments.get_mut(sp.pixel as usize) {
                    add_moment(m, sp.value, sp.uni);
                }
                if record {
                    out.items.push(Item { pixel: sp.pixel, s: sp.s, t: 1, weight: sp.weight, value: sp.value });
                }
            } else {
                out.nonfinite += 1;
            }
        }
    }
    out.t_eye = t2.elapsed().as_secs_f64();
    out.pixels = pixels;
    out
}

//! The render pass: image tiles in parallel (rayon); each pixel's samples depend only
//! on (seed, pixel, sample index), so the image is bit-identical for any thread count.

use super::Integrator;
use crate::accel::TraversalStats;
use crate::film::Film;
use crate::geometry::Ray;
use crate::math::{Color, is_finite};
use crate::progress::progress_bar;
use crate::sampler::{AnySampler, DIM_PIXEL, Sampler, with_sampler};
use crate::world::World;
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// Counters of a render pass.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Traversal counters summed over threads.
    pub traversal: TraversalStats,
    /// Samples whose radiance was NaN or infinite (dropped, counted).
    pub nonfinite_samples: u64,
    /// Wall time of the pass.
    pub seconds: f64,
}

/// Renders `spp` samples per pixel with the integrator. `sampler` is a prototype,
/// cloned once per tile.
pub fn render(world: &World, integrator: &dyn Integrator, sampler: &dyn Sampler, spp: u32, quiet: bool) -> (Film, RenderStats) {
    let cam = &world.scene.camera;
    let (w, h) = (cam.width, cam.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let start = Instant::now();
    let pb = progress_bar((tiles_x * tiles_y) as u64, quiet, "render");
    let results: Vec<(Vec<Color>, TraversalStats, u64)> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let mut out = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
            let (stats, bad) = match sampler.to_any() {
                Some(any) if integrator.batch_lanes() > 1 => render_tile_batched(world, integrator, any, spp, (x0, y0, x1, y1), &mut out),
                any => render_tile(world, integrator, sampler, any, spp, (x0, y0, x1, y1), &mut out),
            };
            pb.inc(1);
            (out, stats, bad)
        })
        .collect();
    pb.finish_and_clear();
    let mut film = Film::new(w, h);
    let mut stats = RenderStats::default();
    for (t, (pixels, st, bad)) in results.into_iter().enumerate() {
        scatter_tile(&mut film.pixels, w, h, t as u32, &pixels);
        stats.traversal.add(&st);
        stats.nonfinite_samples += bad;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    (film, stats)
}

/// Tile corners: (x0, y0) inclusive, (x1, y1) exclusive.
type TileRect = (u32, u32, u32, u32);

/// One tile, sample by sample: appends its pixels (row-major) to `out`; returns the
/// tile's traversal counters and non-finite samples.
fn render_tile(
    world: &World,
    integrator: &dyn Integrator,
    sampler: &dyn Sampler,
    mut any: Option<AnySampler>,
    spp: u32,
    (x0, y0, x1, y1): TileRect,
    out: &mut Vec<Color>,
) -> (TraversalStats, u64) {
    let cam = &world.scene.camera;
    let w = cam.width;
    let mut s = sampler.clone_box();
    // By value where the sampler is one of `sampler::make`'s: the integrator may then
    // draw without virtual calls (`Integrator::li_any`), same values.
    let mut stats = TraversalStats::default();
    let mut bad = 0u64;
    for y in y0..y1 {
        for x in x0..x1 {
            if crate::progress::cancelled() {
                // Stopped (`progress::cancel`): the pipeline discards the image.
                out.push(Color::ZERO);
                continue;
            }
            let stream = y as u64 * w as u64 + x as u64;
            let mut sum = DVec3::ZERO;
            for i in 0..spp {
                let l = match any.as_mut() {
                    Some(a) => {
                        let u = with_sampler!(&mut *a, s => {
                            s.start(stream, i as u64);
                            s.set_dimension(DIM_PIXEL);
                            s.next_2d()
                        });
                        let ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
                        integrator.li_any(world, &ray, a, &mut stats)
                    }
                    None => {
                        s.start(stream, i as u64);
                        s.set_dimension(DIM_PIXEL);
                        let u = s.next_2d();
                        let ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
                        integrator.li(world, &ray, s.as_mut(), &mut stats)
                    }
                };
                if is_finite(l) {
                    sum += l.as_dvec3();
                } else {
                    bad += 1;
                }
            }
            out.push((sum / spp as f64).as_vec3());
        }
    }
    (stats, bad)
}

/// One tile in batches of [`Integrator::batch_lanes`] samples (consecutive samples of
/// a pixel, and of the next pixels where a batch is longer than what is left of
/// one): each sample gets its own copy of the sampler, started and its camera ray
/// drawn as in [`render_tile`], and [`Integrator::li_batch`] traces the batch. Each
/// pixel's sum is then taken in sample order, so the pixels are those of
/// `render_tile` bit for bit.
fn render_tile_batched(
    world: &World,
    integrator: &dyn Integrator,
    proto: AnySampler,
    spp: u32,
    (x0, y0, x1, y1): TileRect,
    out: &mut Vec<Color>,
) -> (TraversalStats, u64) {
    let cam = &world.scene.camera;
    let w = cam.width;
    let lanes = integrator.batch_lanes();
    let mut samplers = vec![proto; lanes];
    let mut rays = Vec::with_capacity(lanes);
    // Pixel (index into `out`) of each sample of the batch.
    let mut owner = Vec::with_capacity(lanes);
    let mut li = vec![Color::ZERO; lanes];
    let mut sums = vec![DVec3::ZERO; ((x1 - x0) * (y1 - y0)) as usize];
    let mut stats = TraversalStats::default();
    let mut bad = 0u64;
    let mut flush = |rays: &mut Vec<Ray>, owner: &mut Vec<usize>, samplers: &mut [AnySampler], stats: &mut TraversalStats| {
        let n = rays.len();
        integrator.li_batch(world, rays, &mut samplers[..n], stats, &mut li[..n]);
        for (&p, &l) in owner.iter().zip(&li[..n]) {
            if is_finite(l) {
                sums[p] += l.as_dvec3();
            } else {
                bad += 1;
            }
        }
        rays.clear();
        owner.clear();
    };
    let mut p = 0;
    for y in y0..y1 {
        for x in x0..x1 {
            if crate::progress::cancelled() {
                // Stopped (`progress::cancel`): the pipeline discards the image.
                p += 1;
                continue;
            }
            let stream = y as u64 * w as u64 + x as u64;
            for i in 0..spp {
                let a = &mut samplers[rays.len()];
                let u = with_sampler!(a, s => {
                    s.start(stream, i as u64);
                    s.set_dimension(DIM_PIXEL);
                    s.next_2d()
                });
                rays.push(cam.generate_ray(x as f32 + u[0], y as f32 + u[1]));
                owner.push(p);
                if rays.len() == lanes {
                    flush(&mut rays, &mut owner, &mut samplers, &mut stats);
                }
            }
            p += 1;
        }
    }
    if !rays.is_empty() {
        flush(&mut rays, &mut owner, &mut samplers, &mut stats);
    }
    out.extend(sums.iter().map(|s| (*s / spp as f64).as_vec3()));
    (stats, bad)
}

/// Copies the pixels of tile `t` (row-major inside the tile, tiles row-major over the
/// image) into the `w` × `h` image `out`.
pub fn scatter_tile<T: Copy>(out: &mut [T], w: u32, h: u32, t: u32, pixels: &[T]) {
    let tiles_x = w.div_ceil(TILE);
    let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
    let x1 = (x0 + TILE).min(w);
    let mut k = 0;
    for y in y0..(y0 + TILE).min(h) {
        for x in x0..x1 {
            out[(y * w + x) as usize] = pixels[k];
            k += 1;
        }
    }
}

//! The render pass: image tiles in parallel (rayon); each pixel's samples depend only
//! on (seed, pixel, sample index), so the image is bit-identical for any thread count.

use super::Integrator;
use crate::accel::TraversalStats;
use crate::film::Film;
use crate::math::{Color, is_finite};
use crate::progress::progress_bar;
use crate::sampler::{DIM_PIXEL, Sampler, with_sampler};
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
    let (tiles, stats) = trace_tiles(world, integrator, sampler, 0, spp, quiet, false);
    let mut film = Film::new(cam.width, cam.height);
    for (t, pixels) in tiles.iter().enumerate() {
        scatter_tile(&mut film.pixels, cam.width, cam.height, t as u32, pixels);
    }
    (film, stats)
}

/// Samples `first` … `first + count − 1` of every pixel, each its own value (a
/// non-finite one as 0, counted): sample `first + j` of pixel p at `p · count + j`.
/// Progressive front ends add them up pass by pass, the per-pixel sums in the order
/// [`render`] adds them.
pub fn render_each(
    world: &World,
    integrator: &dyn Integrator,
    sampler: &dyn Sampler,
    first: u64,
    count: u32,
    quiet: bool,
) -> (Vec<Color>, RenderStats) {
    let cam = &world.scene.camera;
    let (w, h) = (cam.width, cam.height);
    let (tiles, stats) = trace_tiles(world, integrator, sampler, first, count, quiet, true);
    let mut out = vec![Color::ZERO; (w * h) as usize * count as usize];
    for (t, values) in tiles.iter().enumerate() {
        scatter_tile_each(&mut out, w, h, t as u32, values, count as usize);
    }
    (out, stats)
}

/// The tiles in parallel: per tile, row-major, each pixel's mean of its `spp` samples
/// (`each == false`) or the samples themselves.
#[allow(clippy::too_many_arguments)]
fn trace_tiles(
    world: &World,
    integrator: &dyn Integrator,
    sampler: &dyn Sampler,
    first: u64,
    spp: u32,
    quiet: bool,
    each: bool,
) -> (Vec<Vec<Color>>, RenderStats) {
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
            let mut s = sampler.clone_box();
            // By value where the sampler is one of `sampler::make`'s: the integrator
            // may then draw without virtual calls (`Integrator::li_any`), same values.
            let mut any = sampler.to_any();
            let mut stats = TraversalStats::default();
            let mut bad = 0u64;
            let mut out = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize * if each { spp as usize } else { 1 });
            for y in y0..y1 {
                for x in x0..x1 {
                    if crate::progress::cancelled() {
                        // Stopped (`progress::cancel`): the pipeline discards the image.
                        out.extend(std::iter::repeat_n(Color::ZERO, if each { spp as usize } else { 1 }));
                        continue;
                    }
                    let stream = y as u64 * w as u64 + x as u64;
                    let mut sum = DVec3::ZERO;
                    for i in first..first + spp as u64 {
                        let l = match any.as_mut() {
                            Some(a) => {
                                let u = with_sampler!(&mut *a, s => {
                                    s.start(stream, i);
                                    s.set_dimension(DIM_PIXEL);
                                    s.next_2d()
                                });
                                let ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
                                integrator.li_any(world, &ray, a, &mut stats)
                            }
                            None => {
                                s.start(stream, i);
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
                        if each {
                            out.push(if is_finite(l) { l } else { Color::ZERO });
                        }
                    }
                    if !each {
                        out.push((sum / spp as f64).as_vec3());
                    }
                }
            }
            pb.inc(1);
            (out, stats, bad)
        })
        .collect();
    pb.finish_and_clear();
    let mut stats = RenderStats::default();
    let mut tiles = Vec::with_capacity(results.len());
    for (pixels, st, bad) in results {
        tiles.push(pixels);
        stats.traversal.add(&st);
        stats.nonfinite_samples += bad;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    (tiles, stats)
}

/// Copies the pixels of tile `t` (row-major inside the tile, tiles row-major over the
/// image) into the `w` × `h` image `out`.
pub fn scatter_tile<T: Copy>(out: &mut [T], w: u32, h: u32, t: u32, pixels: &[T]) {
    scatter_tile_each(out, w, h, t, pixels, 1);
}

/// As [`scatter_tile`] with `k` values per pixel (pixel p's at `p · k …` in `out`).
fn scatter_tile_each<T: Copy>(out: &mut [T], w: u32, h: u32, t: u32, values: &[T], k: usize) {
    let tiles_x = w.div_ceil(TILE);
    let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
    let mut i = 0;
    for y in y0..(y0 + TILE).min(h) {
        for x in x0..(x0 + TILE).min(w) {
            let p = (y * w + x) as usize * k;
            out[p..p + k].copy_from_slice(&values[i..i + k]);
            i += k;
        }
    }
}

//! The phases of an `sppm` pass ([`super::sppm`]: camera pass, photon pass, gather and
//! update), [`SppmRun`], the state a run carries from pass to pass, and `sppm`'s pass
//! loop, which drives it as `vcm`'s pilot does for one of its candidates.

use super::grid::{GridPhoton, PhotonGrid};
use super::sppm::{PixelStats, SppmIntegrator, VisiblePoint, gather_covered, photon_stream};
use super::{Budget, OnPass, load_checkpoint, save_checkpoint};
use crate::accel::TraversalStats;
use crate::film::Film;
use crate::integrator::render::RenderStats;
use crate::math::hash_words;
use crate::photon::{MapKind, RawPhoton, trace_path_in};
use crate::sampler::{AnySampler, Sampler};
use crate::world::World;
use anyhow::{Result, bail};
use glam::DVec3;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

impl SppmIntegrator {
    /// Runs the passes; returns the final image and its counters.
    pub(super) fn run(&mut self, world: &World, on_pass: OnPass) -> Result<(Film, RenderStats)> {
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let budget = Budget::new(&self.set.prog);
        let mut run = SppmRun::new(self, world, budget.max_passes)?;
        let mut pass = 0u32;
        let mut film = Film::new(w, h);
        if let Some((done, saved)) = load_checkpoint::<Vec<[u64; 8]>>(&self.cfg, &self.set.prog, world)? {
            run.restore(&saved)?;
            pass = done;
            run.write_film(pass, &mut film);
        }
        let pb =
            crate::progress::progress_bar(if budget.max_passes == u32::MAX { 0 } else { budget.max_passes as u64 }, self.quiet, "sppm");
        while budget.more(pass) {
            run.pass(pass);
            pass += 1;
            pb.inc(1);
            run.write_film(pass, &mut film);
            on_pass(pass, budget.elapsed(), &film);
            if self.set.prog.checkpoint_every.is_some_and(|k| pass.is_multiple_of(k)) {
                save_checkpoint(&self.cfg, &self.set.prog, world, pass, &run.state())?;
            }
        }
        pb.finish_and_clear();
        let mut counters = BTreeMap::new();
        let stats = run.finish(pass, budget.elapsed(), &mut counters);
        self.counters = counters;
        Ok((film, stats))
    }
}

/// Photon paths traced per parallel work item.
const PHOTON_CHUNK: u64 = 1024;
/// Most pixels per work item of the gather (and rows per item of the camera pass,
/// photon chunks per item of the photon pass: one). rayon splits a loop further only
/// when a thread steals, so without a cap the last pieces can be thousands of pixels
/// and one thread waits for the other at the end of every pass: measured, the
/// per-pixel gather on 2 threads took 26.4–27.4 ms per pass without the cap and
/// 24.4–25.1 ms with it (cornell 256², 64 passes, alternated).
const GATHER_GRAIN: usize = 256;

/// What the camera pass reports besides the visible points.
pub(super) struct CameraPass {
    /// Rays of the camera paths and shadow rays.
    traversal: TraversalStats,
    /// Camera samples whose radiance was not finite (dropped).
    nonfinite: u64,
    /// Largest radius of a pixel with a visible point (the grid's cell edge; 0 if none).
    r_max: f64,
}

/// The gather's buffers, reused from pass to pass.
#[derive(Default)]
struct GatherBuffers {
    grid: PhotonGrid,
    /// Each pixel's first-pass gather (count, flux), before the density cap.
    found: Vec<Option<(u64, DVec3)>>,
}

/// The three phases of an `sppm` pass, with what every pass of one run reads: the
/// integrator's settings, the world and the samplers.
struct Phases<'a> {
    sppm: &'a SppmIntegrator,
    world: &'a World,
    /// Camera paths (concrete: the camera pass is compiled per sampler type).
    cam_sampler: AnySampler,
    /// Photon paths: every pass traces indices 0 … M − 1 of a stream of its own.
    emit_sampler: AnySampler,
    /// Shadow rays at the visible points.
    direct_sampler: Box<dyn Sampler>,
    /// Photon paths per pass (M).
    m: u64,
    /// Photons' first hits are kept (`sppm_direct = "photons"`).
    keep_first: bool,
}

impl<'a> Phases<'a> {
    fn new(sppm: &'a SppmIntegrator, world: &'a World, m: u64, max_passes: u32) -> Result<Self> {
        let (cfg, set) = (&sppm.cfg, &sppm.set);
        let counts = (max_passes != u32::MAX).then_some(max_passes as u64);
        let n_direct = set.direct.direct_samples.max(1) as u64;
        Ok(Phases {
            sppm,
            world,
            cam_sampler: crate::sampler::make_any(&cfg.sampler, cfg.seed, counts)?,
            emit_sampler: crate::sampler::make_any(&cfg.sampler, cfg.seed, Some(m))?,
            direct_sampler: crate::sampler::make(&set.direct.direct_sampler, cfg.seed, Some(n_direct))?,
            m,
            keep_first: set.p.sppm_direct == "photons",
        })
    }

    /// Phase 1, the camera pass: every pixel's camera path of pass `pass` (rows in parallel),
    /// its emitted + direct radiance added to `pixels` and its visible point written
    /// to `vps` in place.
    fn camera_pass(&self, pass: u32, pixels: &mut [PixelStats], vps: &mut [Option<VisiblePoint>]) -> CameraPass {
        let w = self.world.scene.camera.width as usize;
        // The largest radius is taken while the rows are at hand: radii change only in
        // the update.
        let (traversal, nonfinite, r_max) = pixels
            .par_chunks_mut(w)
            .zip(vps.par_chunks_mut(w))
            .with_max_len(1)
            .enumerate()
            .map_init(
                || (self.cam_sampler.clone(), self.direct_sampler.clone_box()),
                |(s, ds), (y, (prow, vrow))| {
                    let mut st = TraversalStats::default();
                    let (mut bad, mut r_max) = (0u64, 0.0f64);
                    for (x, (px, vp)) in prow.iter_mut().zip(vrow.iter_mut()).enumerate() {
                        let (l, v) = crate::sampler::with_sampler!(&mut *s, s => {
                            self.sppm.camera_path(self.world, x as u32, y as u32, pass, s, ds.as_mut(), &mut st)
                        });
                        if crate::math::is_finite(l) {
                            px.ld += l.as_dvec3();
                        } else {
                            bad += 1;
                        }
                        if v.is_some() {
                            r_max = r_max.max(px.r);
                        }
                        *vp = v;
                    }
                    (st, bad, r_max)
                },
            )
            .reduce(
                || (TraversalStats::default(), 0, 0.0f64),
                |mut a, b| {
                    a.0.add(&b.0);
                    a.1 += b.1;
                    a.2 = a.2.max(b.2);
                    a
                },
            );
        CameraPass { traversal, nonfinite, r_max }
    }

    /// Phase 2, the photon pass: the M photon paths of pass `pass`, in chunks in parallel, each
    /// chunk's kept photons into its own reused buffer of `traced`, in path order.
    fn photon_pass(&self, pass: u32, traced: &mut Vec<Vec<GridPhoton>>) -> TraversalStats {
        let (m, keep_first, world) = (self.m, self.keep_first, self.world);
        let stream = photon_stream(pass);
        let chunks = m.div_ceil(PHOTON_CHUNK) as usize;
        traced.resize_with(chunks, Vec::new);
        traced
            .par_iter_mut()
            .with_max_len(1)
            .enumerate()
            .map_init(
                || self.emit_sampler.clone(),
                |s, (c, out)| {
                    out.clear();
                    let mut st = TraversalStats::default();
                    let c = c as u64;
                    let (rr, depth) = (self.sppm.rr.as_ref(), self.sppm.cfg.depth_limit());
                    // Kept photons go straight into the chunk's buffer, in path order.
                    let mut keep = Kept { out, keep_first };
                    crate::sampler::with_sampler!(&mut *s, s => {
                        for j in c * PHOTON_CHUNK..((c + 1) * PHOTON_CHUNK).min(m) {
                            trace_path_in(world, s, stream, j, rr, depth, &mut st, &mut keep);
                        }
                    });
                    st
                },
            )
            .reduce(TraversalStats::default, |mut a, b| {
                a.add(&b);
                a
            })
    }

    /// Phases 3 and 4, gather and update: the photons of `traced` go into the grid (cell edge a
    /// little over `r_max`), each pixel's visible point gathers those within its
    /// radius and its statistics take them in. In the first pass, with a density cap,
    /// each pixel's count is capped at `sppm_density_cap` × the median count.
    fn gather_update(
        &self,
        pass: u32,
        r_max: f64,
        traced: &[Vec<GridPhoton>],
        vps: &[Option<VisiblePoint>],
        pixels: &mut [PixelStats],
        buf: &mut GatherBuffers,
    ) -> TraversalStats {
        let (world, probes) = (self.world, self.sppm.set.p.sppm_area_probes);
        let alpha = self.sppm.set.prog.alpha as f64;
        let seed = self.sppm.cfg.seed;
        let probe_key = |pixel: usize| hash_words(&[seed, pixel as u64, pass as u64, 0xA2EA]);
        let grid = &mut buf.grid;
        // A little over r_max, so rounding never makes a disc span four cells.
        grid.build(traced, (r_max * (1.0 + 1e-4)) as f32);
        let grid = &*grid;
        let cap_factor = self.sppm.set.p.sppm_density_cap as f64;
        let sum = |mut a: TraversalStats, b: TraversalStats| {
            a.add(&b);
            a
        };
        if pass == 0 && cap_factor > 0.0 {
            // First pass: gather, then cap each pixel's count at cap_factor × the
            // median count (dense light such as caustics starts with a smaller disc).
            let found = &mut buf.found;
            found.clear();
            let mut rays = Vec::new();
            vps.par_iter()
                .zip(pixels.par_iter())
                .with_max_len(GATHER_GRAIN)
                .enumerate()
                .map(|(i, (vp, px))| {
                    let mut st = TraversalStats::default();
                    let f = vp.as_ref().map(|vp| gather_covered(world, grid, vp, px.r as f32, probes, probe_key(i), &mut st));
                    (f, st)
                })
                .unzip_into_vecs(found, &mut rays);
            let cap = cap_factor * alpha * median_count(found);
            let cap = if cap > 0.0 { cap } else { f64::INFINITY };
            pixels.par_iter_mut().zip(vps.par_iter().zip(found.par_iter())).for_each(|(px, (vp, f))| {
                if let (Some(vp), Some((mm, phi))) = (vp, f) {
                    px.update_capped(*mm, *phi * vp.beta.as_dvec3(), alpha, cap);
                }
            });
            rays.into_iter().fold(TraversalStats::default(), sum)
        } else {
            pixels
                .par_iter_mut()
                .zip(vps.par_iter())
                .with_max_len(GATHER_GRAIN)
                .enumerate()
                .map(|(i, (px, vp))| {
                    let mut st = TraversalStats::default();
                    if let Some(vp) = vp {
                        let (mm, phi) = gather_covered(world, grid, vp, px.r as f32, probes, probe_key(i), &mut st);
                        px.update(mm, phi * vp.beta.as_dvec3(), alpha);
                    }
                    st
                })
                .reduce(TraversalStats::default, sum)
        }
    }
}

/// The photon pass's sink: keeps a traced photon as a [`GridPhoton`] unless it is a
/// first hit and first hits are left to the shadow rays.
struct Kept<'a> {
    out: &'a mut Vec<GridPhoton>,
    keep_first: bool,
}

impl Extend<RawPhoton> for Kept<'_> {
    #[inline]
    fn extend<I: IntoIterator<Item = RawPhoton>>(&mut self, photons: I) {
        let keep_first = self.keep_first;
        self.out.extend(photons.into_iter().filter(|p| keep_first || p.kind != MapKind::Direct).map(|p| GridPhoton::from(&p)));
    }
}

/// Median photon count over the pixels that caught photons (0 if none did).
fn median_count(found: &[Option<(u64, DVec3)>]) -> f64 {
    let mut m: Vec<u64> = found.iter().filter_map(|f| f.map(|f| f.0)).filter(|&m| m > 0).collect();
    if m.is_empty() {
        return 0.0;
    }
    let mid = m.len() / 2;
    *m.select_nth_unstable(mid).1 as f64
}

/// An `sppm` run's state from pass to pass: the per-pixel statistics, the buffers
/// reused by every pass (no allocation per pass in the hot loops) and the counters.
pub struct SppmRun<'a> {
    phases: Phases<'a>,
    /// Per-pixel statistics.
    pixels: Vec<PixelStats>,
    /// Each pixel's visible point of the current pass.
    vps: Vec<Option<VisiblePoint>>,
    /// Each photon chunk's kept photons, in path order.
    traced: Vec<Vec<GridPhoton>>,
    gather: GatherBuffers,
    /// Camera paths, shadow rays and the gather's own rays.
    stats: RenderStats,
    photon_rays: TraversalStats,
    t_camera: f64,
    t_photon: f64,
    t_gather: f64,
    kept_total: u64,
}

impl<'a> SppmRun<'a> {
    /// A fresh run of at most `max_passes` passes (`u32::MAX`: unbounded).
    pub fn new(sppm: &'a SppmIntegrator, world: &'a World, max_passes: u32) -> Result<Self> {
        let npix = (world.scene.camera.width * world.scene.camera.height) as usize;
        let m = sppm.photons_per_pass(npix);
        if max_passes != u32::MAX && m.saturating_mul(max_passes as u64) > u32::MAX as u64 * 64 {
            bail!("photons per pass × passes is too large ({m} × {max_passes})");
        }
        let r0 = sppm.set.p.sppm_radius.unwrap_or(super::sppm::DEFAULT_RADIUS_FRACTION * world.lights.scene_radius) as f64;
        Ok(SppmRun {
            phases: Phases::new(sppm, world, m, max_passes)?,
            pixels: vec![PixelStats::new(r0); npix],
            vps: vec![None; npix],
            traced: Vec::new(),
            gather: GatherBuffers::default(),
            stats: RenderStats::default(),
            photon_rays: TraversalStats::default(),
            t_camera: 0.0,
            t_photon: 0.0,
            t_gather: 0.0,
            kept_total: 0,
        })
    }

    /// Runs pass `pass` (from 0): camera pass, photon pass, gather and update.
    pub fn pass(&mut self, pass: u32) {
        let t0 = Instant::now();
        let cam_pass = self.phases.camera_pass(pass, &mut self.pixels, &mut self.vps);
        self.stats.traversal.add(&cam_pass.traversal);
        self.stats.nonfinite_samples += cam_pass.nonfinite;
        self.t_camera += t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        self.photon_rays.add(&self.phases.photon_pass(pass, &mut self.traced));
        let kept: usize = self.traced.iter().map(Vec::len).sum();
        self.kept_total += kept as u64;
        self.t_photon += t1.elapsed().as_secs_f64();

        let t2 = Instant::now();
        if cam_pass.r_max > 0.0 && kept > 0 {
            // The gather's own rays (area probes, side tests) count with the rest.
            let st = self.phases.gather_update(pass, cam_pass.r_max, &self.traced, &self.vps, &mut self.pixels, &mut self.gather);
            self.stats.traversal.add(&st);
        }
        self.t_gather += t2.elapsed().as_secs_f64();
    }

    /// The image after `passes` passes.
    pub fn write_film(&self, passes: u32, film: &mut Film) {
        let m = self.phases.m;
        film.pixels.par_iter_mut().zip(self.pixels.par_iter()).for_each(|(o, px)| *o = px.radiance(passes, m));
    }

    /// Photon paths per pass (M).
    pub fn photons_per_pass(&self) -> u64 {
        self.phases.m
    }

    /// The per-pixel statistics (to compare two passes' states, [`pass_estimates`]).
    pub fn pixels(&self) -> &[PixelStats] {
        &self.pixels
    }

    /// Rays traced so far (camera, shadow, gather and photon rays).
    pub fn rays(&self) -> u64 {
        self.stats.traversal.total_rays() + self.photon_rays.total_rays()
    }

    /// The per-pixel statistics as bits (checkpoints).
    pub fn state(&self) -> Vec<[u64; 8]> {
        self.pixels.iter().map(PixelStats::to_bits).collect()
    }

    /// Continues from a saved [`SppmRun::state`].
    pub fn restore(&mut self, saved: &[[u64; 8]]) -> Result<()> {
        if saved.len() != self.pixels.len() {
            bail!("checkpoint holds {} pixels, the image has {}", saved.len(), self.pixels.len());
        }
        self.pixels = saved.iter().map(PixelStats::from_bits).collect();
        Ok(())
    }

    /// Ends the run after `passes` passes and `seconds`: its render statistics, its
    /// counters added to `c`.
    pub fn finish(self, passes: u32, seconds: f64, c: &mut BTreeMap<String, f64>) -> RenderStats {
        let m = self.phases.m;
        let mut stats = self.stats;
        stats.seconds = seconds;
        stats.traversal.add(&self.photon_rays);
        let threads = rayon::current_num_threads() as f64;
        c.insert("passes".into(), passes as f64);
        c.insert("photons_emitted".into(), (passes as u64 * m) as f64);
        c.insert("photons_kept".into(), self.kept_total as f64);
        c.insert("photon_rays".into(), self.photon_rays.total_rays() as f64);
        c.insert("camera_pass_s".into(), self.t_camera);
        c.insert("photon_pass_s".into(), self.t_photon);
        c.insert("gather_s".into(), self.t_gather);
        c.insert("passes_per_s".into(), passes as f64 / seconds.max(1e-9));
        c.insert("photons_per_s_per_thread".into(), (passes as u64 * m) as f64 / self.t_photon.max(1e-9) / threads);
        let mean_r = self.pixels.iter().map(|p| p.r).sum::<f64>() / self.pixels.len().max(1) as f64;
        c.insert("mean_radius".into(), mean_r);
        stats
    }
}

/// Each pixel's estimate of one pass alone, from the statistics before and after it
/// (`m` photon paths per pass), in two parts: the emitted and direct light it added,
/// and the flux it gathered over M π r², r its radius during the pass (the update
/// τ' = (τ + φ) r'²/r² gives back φ = τ' r²/r'² − τ). Their sum's mean over passes is
/// the image up to the radius rescaling; their spread measures a pass's variance, the
/// flux part's growing as the radius shrinks.
pub fn pass_estimates(before: &[PixelStats], after: &[PixelStats], m: u64) -> (Vec<DVec3>, Vec<DVec3>) {
    before
        .iter()
        .zip(after)
        .map(|(b, a)| {
            let phi = if a.r > 0.0 { a.tau * (b.r * b.r) / (a.r * a.r) - b.tau } else { DVec3::ZERO };
            (a.ld - b.ld, phi / (m as f64 * std::f64::consts::PI * b.r * b.r))
        })
        .unzip()
}

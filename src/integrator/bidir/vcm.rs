//! `vcm`: vertex connection and merging (Georgiev et al. 2012; Hachisuka et al.'s
//! unified path sampling), progressive as SmallVCM's `VertexCM`: pass i (from 1)
//! merges within r_i = r₀ · i^((α−1)/2), α = 0.75 unless `alpha` is set, r₀ =
//! `vcm_radius` or a fraction of the scene's bounding radius; the image after p passes
//! is the mean of the passes' estimates. A pass traces `vcm_light_paths` × W·H light
//! subpaths (½ by default) and joins each camera vertex to `vcm_connect_draws` vertices
//! drawn from all of the pass's light vertices (1 by default; 0: every vertex of its own
//! light subpath), and merges at the first non-delta camera vertex only (`vcm_merge =
//! "first"`, the MIS weights counting merging only there; `"all"`: at every non-delta
//! one — with `vcm_light_paths = 1`, `vcm_connect_draws = 0` SmallVCM's pass). `vcm_mode` restricts
//! the techniques for ablations (SmallVCM's algorithms): `bpt` connections only, `ppm`
//! merging at the first non-delta camera vertex only (no MIS), `lt` light tracing only.
//! With `vcm_mode = "vcm"`, `vcm_select = "efficiency"` (the default) chooses per scene
//! between that pass, path tracing and `sppm` from a pilot ([`super::select`]).

use super::mis::Heuristic;
use super::pass::run_pass;
use super::select;
use super::strategies::Strategies;
use super::{BidirParams, Ctx, Mode};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::path::PathIntegrator;
use crate::integrator::progressive::sppm::{SppmIntegrator, SppmParams, SppmSetup};
use crate::integrator::progressive::sppm_phases::{SppmRun, pass_estimates};
use crate::integrator::progressive::{Budget, OnPass, ProgressiveParams, load_checkpoint, save_checkpoint};
use crate::integrator::render::{RenderStats, render_each};
use crate::rr::RussianRoulette;
use crate::world::World;
use anyhow::{Result, bail};
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};

/// α when `alpha` is not set (SmallVCM's default).
pub const DEFAULT_ALPHA: f32 = 0.75;
/// r₀ as a fraction of the scene's bounding-sphere radius when `vcm_radius` is unset.
pub const DEFAULT_RADIUS_FRACTION: f32 = 0.01;

crate::params! {
    /// Parameters of the `vcm` integrator.
    pub struct VcmParams {
        /// Techniques: `vcm` (connections and merging), `bpt` (connections), `ppm` (merging at the first diffuse vertex), `lt` (light tracing).
        vcm_mode: String = "vcm",
        /// Initial merging radius r₀ (scene units); `auto` = 0.01 × the scene's bounding radius.
        vcm_radius: Option<f32> = "auto",
        /// Light subpaths per pass as a fraction of the pixel count (1 = one per pixel, as SmallVCM); pixel p's camera subpath is joined to light subpath p mod their number.
        vcm_light_paths: f32 = "0.5",
        /// Light vertices each camera vertex is joined to, drawn (stratified) from all light vertices of the pass (Davidovič et al. 2014's light vertex cache); 0 = every vertex of its own light subpath (SmallVCM).
        vcm_connect_draws: u32 = "1",
        /// Camera vertices merged with the pass's light vertices: the `first` non-delta one only (the MIS weights count merging only there) or `all` non-delta ones (SmallVCM).
        vcm_merge: String = "first",
        /// Technique set per scene (with `vcm_mode = "vcm"`): `efficiency` runs 2 pilot passes each of the bidirectional pass, path tracing (`path`'s estimator, one sample per pixel a pass) and `sppm` (its defaults) and renders with the one whose predicted relMSE × counted work is lowest (Grittmann et al. 2022; `sppm`'s bias priced by its difference from the unbiased pilots); `bidir-path`: the first two only; `off`: always the bidirectional pass.
        vcm_select: String = "efficiency",
    }
}

/// Path-tracing passes are traced in batches of at most this many samples over the image
/// (the samples of all of them kept until they are added pass by pass)…
const PATH_BATCH_SAMPLES: usize = 1 << 20;
/// … and at most this many passes.
const PATH_BATCH_PASSES: u32 = 16;

/// Light subpaths of the pilot that measures light vertices per subpath.
const PILOT_PATHS: u64 = 4096;
/// First light stream of the pilot (above any pass's light subpaths).
const PILOT_STREAMS: u64 = 1 << 40;

/// The vertex connection and merging integrator.
pub struct VcmIntegrator {
    cfg: RenderConfig,
    h: Heuristic,
    mode: Mode,
    radius: Option<f32>,
    light_fraction: f32,
    draws: u32,
    alpha: f32,
    prog: ProgressiveParams,
    rr: Box<dyn RussianRoulette>,
    /// Path tracing, a candidate of `vcm_select = "efficiency"` (`None`: off).
    path: Option<PathIntegrator>,
    /// `sppm`, a candidate of `vcm_select = "efficiency"` (`None`: not a candidate).
    sppm: Option<SppmIntegrator>,
    quiet: bool,
    counters: BTreeMap<String, f64>,
}

impl VcmIntegrator {
    /// Builds the integrator (checking its settings).
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        let prog = ProgressiveParams::read_checked(cfg, r)?;
        let p = VcmParams::read(r)?;
        let b = BidirParams::read(r)?;
        if prog.photons_per_pass.is_some() {
            bail!("vcm sets its light subpaths per pass with vcm_light_paths; photons_per_pass does not apply");
        }
        if let Some(r) = p.vcm_radius
            && !(r > 0.0 && r.is_finite())
        {
            bail!("vcm_radius must be positive and finite, got {r}");
        }
        if p.vcm_connect_draws > 64 {
            bail!("vcm_connect_draws must be at most 64, got {}", p.vcm_connect_draws);
        }
        if !(p.vcm_light_paths > 0.0 && p.vcm_light_paths <= 64.0) {
            bail!("vcm_light_paths must be in (0, 64] (a fraction of the pixel count), got {}", p.vcm_light_paths);
        }
        let alpha = if cfg.params.contains("alpha") { prog.alpha } else { DEFAULT_ALPHA };
        let mode = Mode::parse(&p.vcm_mode)?.with_merge(&p.vcm_merge)?;
        let (path, sppm) = match p.vcm_select.as_str() {
            "efficiency" | "bidir-path" if p.vcm_mode == "vcm" => {
                // `path`'s and `sppm`'s own roulette when `rr` is `auto`.
                let path =
                    PathIntegrator { max_depth: cfg.depth_limit(), rr: crate::rr::make_for(&cfg.rr, "path")?, output: Default::default() };
                let sppm = (p.vcm_select == "efficiency")
                    .then(|| -> Result<SppmIntegrator> {
                        // `sppm` as its defaults set it (the run's `alpha`, passes and time limit).
                        let direct = crate::integrator::photon::DirectParams {
                            direct_samples: crate::integrator::progressive::sppm::DEFAULT_DIRECT_SAMPLES,
                            ..Default::default()
                        };
                        let set = SppmSetup { p: SppmParams::default(), prog: prog.clone(), direct };
                        Ok(SppmIntegrator::from_setup(cfg, set, crate::rr::make_for(&cfg.rr, "sppm")?, true))
                    })
                    .transpose()?;
                (Some(path), sppm)
            }
            "efficiency" | "bidir-path" | "off" => (None, None),
            other => bail!("unknown vcm_select `{other}` (known: efficiency, bidir-path, off)"),
        };
        Ok(VcmIntegrator {
            cfg: cfg.clone(),
            h: Heuristic::parse(&b.bdpt_mis)?,
            mode,
            radius: p.vcm_radius,
            light_fraction: p.vcm_light_paths,
            draws: p.vcm_connect_draws,
            alpha,
            prog,
            rr,
            path,
            sppm,
            quiet,
            counters: BTreeMap::new(),
        })
    }

    /// Merging radius of pass `i` (from 1).
    pub fn radius(r0: f32, alpha: f32, i: u32) -> f32 {
        (r0 as f64 * (i as f64).powf(0.5 * (alpha as f64 - 1.0))).max(1e-7) as f32
    }

    /// Light vertices stored per light subpath, from a pilot of [`PILOT_PATHS`] light
    /// subpaths on streams no pass uses: the same for every run of a scene and
    /// configuration (resumed or not, any thread count), and independent of the
    /// passes' own samples, so the MIS weights that use it stay exact.
    fn light_vertices_per_path(&self, world: &World, sampler: &crate::sampler::AnySampler, r0: f32) -> f32 {
        let ctx = Ctx::new(world, self.h, self.mode, self.cfg.depth_limit(), self.rr.as_ref(), r0, 1, None);
        let (mut vertices, mut splats, mut stats) = (Vec::new(), Vec::new(), crate::accel::TraversalStats::default());
        let mut s = sampler.clone();
        let mut count = 0usize;
        crate::sampler::with_sampler!(&mut s, s => {
            for j in 0..PILOT_PATHS {
                super::subpath::trace_light(&ctx, s, super::pass::light_stream(PILOT_STREAMS + j), 0, &mut vertices, &mut splats, &mut stats);
                count += vertices.len();
                vertices.clear();
                splats.clear();
            }
        });
        (count as f32 / PILOT_PATHS as f32).max(1.0 / PILOT_PATHS as f32)
    }

    fn run_passes(&mut self, world: &World, on_pass: OnPass, record: bool) -> Result<(Film, RenderStats, Strategies, u32)> {
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let npix = (w * h) as usize;
        let budget = Budget::new(&self.prog);
        let counts = (budget.max_passes != u32::MAX).then_some(budget.max_passes as u64);
        let cam_sampler = crate::sampler::make_any(&self.cfg.sampler, self.cfg.seed, counts)?;
        let light_paths = ((npix as f64 * self.light_fraction as f64).round() as u64).clamp(1, u32::MAX as u64 / 2) as u32;
        let light_sampler = cam_sampler.clone();
        let path_sampler = cam_sampler.clone().boxed();
        let mut grid = super::grid::HashGrid::default();
        let r0 = self.radius.unwrap_or(DEFAULT_RADIUS_FRACTION * world.lights.scene_radius);
        let joins = (self.draws > 0 && self.mode.connect).then(|| (self.draws, self.light_vertices_per_path(world, &light_sampler, r0)));
        let mut stats = RenderStats::default();
        let mut strategies = Strategies::default();
        let mut times = PhaseTimes::default();
        let (h_mis, mode, alpha, depth, rr) = (self.h, self.mode, self.alpha, self.cfg.depth_limit(), self.rr.as_ref());
        // One pass of the bidirectional estimator, its counters added up.
        let mut bidir_pass = |pass: u32, moments: bool, stats: &mut RenderStats, strategies: &mut Strategies, times: &mut PhaseTimes| {
            let r = Self::radius(r0, alpha, pass + 1);
            let ctx = Ctx::new(world, h_mis, mode, depth, rr, r, light_paths, joins);
            let out = run_pass(&ctx, &cam_sampler, &light_sampler, pass as u64, record, moments, &mut grid);
            stats.traversal.add(&out.traversal);
            stats.nonfinite_samples += out.nonfinite;
            times.add(&out);
            strategies.add(&out.items, npix);
            (out.pixels, out.moments, out.merged)
        };
        // Passes `first` … `first + count − 1` of path tracing (their sample index of
        // every pixel), traced in one go: one parallel loop, each pixel's samples in a row.
        let path_passes = |path: &PathIntegrator, first: u32, count: u32, stats: &mut RenderStats| {
            let (each, st) = render_each(world, path, path_sampler.as_ref(), first as u64, count, true);
            stats.traversal.add(&st.traversal);
            stats.nonfinite_samples += st.nonfinite_samples;
            let k = count as usize;
            (0..k).map(|j| (0..npix).map(|p| each[p * k + j].as_dvec3()).collect::<Vec<DVec3>>()).collect::<VecDeque<_>>()
        };
        let batch = (PATH_BATCH_SAMPLES / npix.max(1)).clamp(1, PATH_BATCH_PASSES as usize) as u32;
        // The pilot (unless recording the bidirectional techniques): the chosen
        // candidate's first passes, and whether it is path tracing.
        let mut ahead: VecDeque<Vec<DVec3>> = VecDeque::new();
        let mut use_path = None;
        // `sppm` when chosen, and its image and state after each pilot pass.
        let mut use_sppm: Option<SppmRun> = None;
        let mut sppm_pilot: Vec<(Vec<Vec3>, Vec<[u64; 8]>)> = Vec::new();
        if let Some(path) = self.path.as_ref().filter(|_| !record) {
            let (mut b, mut moments, mut merged) = (VecDeque::new(), Vec::new(), Vec::new());
            for i in 0..select::PILOT_PASSES {
                let (px, m, mg) = bidir_pass(i, true, &mut stats, &mut strategies, &mut times);
                b.push_back(px);
                moments.push(m);
                merged.push(mg);
            }
            let b_rays = stats.traversal.total_rays();
            let mut p = path_passes(path, 0, select::PILOT_PASSES, &mut stats);
            let p_rays = stats.traversal.total_rays() - b_rays;
            // `sppm`'s pilot (no candidate if it cannot run this many passes).
            let mut sppm = self.sppm.as_ref().and_then(|s| SppmRun::new(s, world, budget.max_passes).ok());
            let (mut direct, mut flux) = (Vec::new(), Vec::new());
            if let Some(run) = sppm.as_mut() {
                let mut f = Film::new(w, h);
                for i in 0..select::PILOT_PASSES {
                    let before = run.pixels().to_vec();
                    run.pass(i);
                    let (d, g) = pass_estimates(&before, run.pixels(), run.photons_per_pass());
                    direct.push(d);
                    flux.push(g);
                    run.write_film(i + 1, &mut f);
                    sppm_pilot.push((f.pixels.clone(), run.state()));
                }
            }
            let pilot = select::Pilot::new(&select::PilotInput {
                bidir: b.make_contiguous(),
                bidir_merged: &merged,
                moments: &moments,
                bidir_rays: b_rays,
                bidir_alpha: alpha as f64,
                path: p.make_contiguous(),
                path_rays: p_rays,
                sppm: sppm.as_ref().map(|r| select::SppmPilot {
                    direct: &direct,
                    flux: &flux,
                    rays: r.rays(),
                    alpha: self.prog.alpha as f64,
                }),
                horizon: if budget.max_passes == u32::MAX { select::HORIZON } else { budget.max_passes.min(1 << 20) },
            });
            let c = &mut self.counters;
            c.insert("pilot_bidir_rel_var".into(), pilot.bidir.rel_var);
            c.insert("pilot_path_rel_var".into(), pilot.path.rel_var);
            c.insert("pilot_path_own_rel_var".into(), pilot.path_own_rel_var);
            c.insert("pilot_bidir_rays_per_pass".into(), pilot.bidir.rays_per_pass);
            c.insert("pilot_path_rays_per_pass".into(), pilot.path.rays_per_pass);
            c.insert("pilot_chose_path".into(), pilot.prefers_path() as u8 as f64);
            c.insert("pilot_advantage".into(), pilot.advantage());
            c.insert("pilot_bidir_predicted".into(), pilot.bidir.rel_mse_passes);
            if let Some(m) = pilot.sppm {
                c.insert("pilot_sppm_rel_var".into(), m.rel_var);
                c.insert("pilot_sppm_rel_bias2".into(), pilot.sppm_rel_bias2);
                c.insert("pilot_sppm_predicted".into(), m.rel_mse_passes);
                c.insert("pilot_sppm_rays_per_pass".into(), m.rays_per_pass);
                c.insert("pilot_chose_sppm".into(), (pilot.choice() == select::Choice::Sppm) as u8 as f64);
            }
            match pilot.choice() {
                select::Choice::Path => {
                    ahead = p;
                    use_path = Some(path);
                }
                select::Choice::Bidir => ahead = b,
                select::Choice::Sppm => use_sppm = sppm.take(),
            }
            if let Some(run) = sppm {
                // Not chosen: its pilot's rays still count.
                stats.traversal.add(&run.finish(0, 0.0, &mut BTreeMap::new()).traversal);
                sppm_pilot.clear();
            }
        }
        let mut sum = vec![DVec3::ZERO; npix];
        let mut pass = 0u32;
        let mut film = Film::new(w, h);
        // Passes the state of `use_sppm` holds.
        let mut sppm_at = sppm_pilot.len() as u32;
        if !record && let Some((done, saved)) = load_checkpoint::<VcmState>(&self.cfg, &self.prog, world)? {
            pass = done;
            match (saved, use_sppm.as_mut()) {
                (VcmState::Sums(saved), None) => {
                    if saved.len() != npix {
                        bail!("checkpoint holds {} pixels, the image has {npix}", saved.len());
                    }
                    sum = saved.iter().map(|b| DVec3::new(f64::from_bits(b[0]), f64::from_bits(b[1]), f64::from_bits(b[2]))).collect();
                    film.pixels = sum.iter().map(|s| (*s / pass.max(1) as f64).as_vec3()).collect();
                }
                (VcmState::Sppm(saved), Some(run)) => {
                    if done > sppm_at {
                        run.restore(&saved)?;
                        sppm_at = done;
                        run.write_film(done, &mut film);
                    } else if let Some((img, _)) = done.checked_sub(1).and_then(|i| sppm_pilot.get(i as usize)) {
                        film.pixels.clone_from(img);
                    }
                }
                _ => bail!(
                    "{}: the checkpoint holds the state of another technique than the pilot chose (re-render from the start)",
                    self.prog.checkpoint_file.as_deref().unwrap_or("checkpoint")
                ),
            }
        }
        let mut run_count = 0u32;
        // Passes `ahead_first` … are in `ahead`.
        let mut ahead_first = 0u32;
        let pb = crate::progress::progress_bar(counts.unwrap_or(0), self.quiet, "vcm");
        while budget.more(pass) {
            if let Some(run) = use_sppm.as_mut() {
                // `sppm`'s passes: its pilot's first, then its own.
                if pass < sppm_at {
                    film.pixels.clone_from(&sppm_pilot[pass as usize].0);
                } else {
                    run.pass(pass);
                    sppm_at = pass + 1;
                    run.write_film(pass + 1, &mut film);
                }
            } else {
                if let Some(path) = use_path
                    && !(ahead_first..ahead_first + ahead.len() as u32).contains(&pass)
                {
                    // Batches grow with the pass count (2, 4, 8, … up to `batch`), so the
                    // images after 2ᵏ passes come as soon as those passes are done.
                    let count = batch.min(pass.max(1)).min(budget.max_passes.saturating_sub(pass)).max(1);
                    ahead = path_passes(path, pass, count, &mut stats);
                    ahead_first = pass;
                }
                let pixels = if let Some(px) = pass.checked_sub(ahead_first).and_then(|i| ahead.get_mut(i as usize)) {
                    std::mem::take(px)
                } else {
                    bidir_pass(pass, false, &mut stats, &mut strategies, &mut times).0
                };
                for (s, p) in sum.iter_mut().zip(&pixels) {
                    *s += *p;
                }
                film.pixels = sum.iter().map(|s| (*s / (pass + 1) as f64).as_vec3()).collect();
            }
            pass += 1;
            run_count += 1;
            pb.inc(1);
            on_pass(pass, budget.elapsed(), &film);
            if !record && self.prog.checkpoint_every.is_some_and(|k| pass.is_multiple_of(k)) {
                let state = match use_sppm.as_ref() {
                    Some(_) if pass < sppm_at => VcmState::Sppm(sppm_pilot[pass as usize - 1].1.clone()),
                    Some(run) => VcmState::Sppm(run.state()),
                    None => VcmState::Sums(sum.iter().map(|s| [s.x.to_bits(), s.y.to_bits(), s.z.to_bits()]).collect()),
                };
                save_checkpoint(&self.cfg, &self.prog, world, pass, &state)?;
            }
        }
        pb.finish_and_clear();
        stats.seconds = budget.elapsed();
        let threads = rayon::current_num_threads() as f64;
        // Bidirectional passes traced (the pilot's included).
        let bpasses = times.passes;
        if record {
            // The per-strategy images' own run: the counters stay those of the image's.
            return Ok((film, stats, strategies, pass));
        }
        let c = &mut self.counters;
        let sppm_passes = if use_sppm.is_some() { run_count as f64 } else { 0.0 };
        if let Some(run) = use_sppm {
            let st = run.finish(pass, stats.seconds, c);
            stats.traversal.add(&st.traversal);
            stats.nonfinite_samples += st.nonfinite_samples;
        }
        c.insert("sppm_passes".into(), sppm_passes);
        c.insert("passes".into(), pass as f64);
        c.insert("path_tracing_passes".into(), if use_path.is_some() { run_count as f64 } else { 0.0 });
        c.insert("light_phase_s".into(), times.light);
        c.insert("grid_s".into(), times.grid);
        c.insert("camera_phase_s".into(), times.eye);
        c.insert("light_vertices".into(), times.vertices as f64);
        c.insert("final_radius".into(), Self::radius(r0, self.alpha, pass.max(1)) as f64);
        c.insert("light_subpaths_per_pass".into(), light_paths as f64);
        if let Some((_, lbar)) = joins {
            c.insert("pilot_light_vertices_per_subpath".into(), lbar as f64);
        }
        if bpasses > 0 {
            c.insert("light_subpaths_per_s_per_thread".into(), bpasses as f64 * light_paths as f64 / times.light.max(1e-9) / threads);
            c.insert("camera_subpaths_per_s_per_thread".into(), bpasses as f64 * npix as f64 / times.eye.max(1e-9) / threads);
        }
        c.insert("passes_per_s".into(), run_count as f64 / stats.seconds.max(1e-9));
        Ok((film, stats, strategies, pass))
    }
}

/// What a `vcm` checkpoint holds: the sums of the passes' estimates (bidirectional
/// passes or path tracing), or `sppm`'s per-pixel statistics when the pilot chose it.
#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum VcmState {
    Sums(Vec<[u64; 3]>),
    Sppm(Vec<[u64; 8]>),
}

/// Seconds in the phases of the bidirectional passes, and light vertices stored.
#[derive(Default)]
struct PhaseTimes {
    light: f64,
    grid: f64,
    eye: f64,
    vertices: u64,
    passes: u64,
}

impl PhaseTimes {
    fn add(&mut self, out: &super::pass::PassOut) {
        self.light += out.t_light;
        self.grid += out.t_grid;
        self.eye += out.t_eye;
        self.vertices += out.light_vertices;
        self.passes += 1;
    }
}

impl crate::integrator::Integrator for VcmIntegrator {
    fn name(&self) -> &'static str {
        "vcm"
    }
    /// Not used: the passes render the whole image.
    fn li(
        &self,
        _: &World,
        _: &crate::geometry::Ray,
        _: &mut dyn crate::sampler::Sampler,
        _: &mut crate::accel::TraversalStats,
    ) -> crate::math::Color {
        crate::math::Color::ZERO
    }
    fn is_progressive(&self) -> bool {
        true
    }
    /// `strategies` is rendered by [`crate::integrator::Integrator::render_aov`]; accepted here so
    /// front ends can ask which integrators have it.
    fn set_output(&mut self, aov: &str) -> Result<()> {
        if aov == "strategies" {
            return Ok(());
        }
        anyhow::bail!("integrator `vcm` has no extra image `{aov}` (known: strategies)")
    }
    fn render_progressive(&mut self, world: &World, on_pass: OnPass) -> Option<Result<(Film, RenderStats)>> {
        Some(self.run_passes(world, on_pass, false).map(|(f, s, _, _)| (f, s)))
    }
    fn render_aov(&mut self, world: &World, aov: &str) -> Option<Result<Vec<(String, Film)>>> {
        (aov == "strategies").then(|| {
            let (w, h) = (world.scene.camera.width, world.scene.camera.height);
            self.run_passes(world, &mut |_, _, _| {}, true).map(|(_, _, s, passes)| s.images(w, h, passes))
        })
    }
    fn stats(&self) -> BTreeMap<String, f64> {
        self.counters.clone()
    }
}

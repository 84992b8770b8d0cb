//! `sppm`: stochastic progressive photon mapping (Hachisuka & Jensen 2009), organised
//! as pbrt-v4's `SPPMIntegrator`.
//!
//! Every pass:
//! 1. **Camera pass.** One camera path per pixel (sample index = pass). Emitters and
//!    the environment (a path that leaves the scene) seen directly or through mirrors
//!    and glass count fully; delta surfaces are followed by sampling one lobe; at the
//!    first non-delta (diffuse or glossy) surface the path stops and leaves a *visible
//!    point* (position, `wo`, BSDF, throughput β). Every BSDF, there and before, has
//!    its textured parameters filled in ([`World::bsdf_at`]).
//!    Direct light is added there by `direct_samples` shadow rays (one unless set, as
//!    pbrt-v4's one light sample per pass), stratified by
//!    `direct_sampler` (`sppm_direct = "trace"`), or left to the photons (`"photons"`).
//!    The light set samples the environment too, and the path stops at the visible
//!    point (no BSDF-sampled ray leaves it), so environment light reaching a visible
//!    point directly is counted once: by the shadow rays, or by the photons' first
//!    hits (`"photons"`; environment photons come from [`crate::photon::emit`]).
//! 2. **Photon pass.** `photons_per_pass` photon paths (2 per pixel unless set;
//!    indices 0 … M − 1 of a sampler stream of the pass's own, so each pass is an
//!    independent randomisation of the same point set and the radical inverses stay
//!    short), traced by [`crate::photon::trace_path_in`]. Photon hits on
//!    non-delta surfaces after at least one bounce are kept (first hits too with
//!    `"photons"`), in path order.
//! 3. **Gather.** The kept photons go into a hash grid rebuilt per pass (cell edge =
//!    the largest pixel radius, so a disc touches at most 3 × 3 × 3 cells; an edge of
//!    twice the radius, 2 × 2 × 2 cells, scans 1.5–2× more photons once most radii have
//!    shrunk below the largest, measured with `bench progressive`). Each pixel's
//!    visible point sums Φ_p f(wo, wi_p) over the photons within its radius that
//!    arrived on its side of the surface (photon and visible-point normals within
//!    ~45°, the photon coming from the visible point's hemisphere).
//! 4. **Update** (per pixel): N' = N + αM, r' = r √(N'/(N + M)), τ' = (τ + βΦ) r'²/r².
//!
//! The image after p passes is L = Σ L_direct / p + τ / (p·M·π r²), where each pass's
//! flux has been divided by its visible point's covered share a of the ball
//! ([`gather_covered`]: `sppm_area_probes` probe rays where the ball leaves the
//! visible point's triangle; 1 without probes): near edges and corners part of the
//! disc holds no surface and no photons, which otherwise darkens them (boundary bias).
//!
//! Determinism: the camera pass and the gather run per pixel; photons are merged in
//! path order and the grid is filled in that order, so each pixel adds its photons
//! in the same order for any thread count (pbrt-v4 splats photons into the visible
//! points with atomic adds instead, whose order depends on the schedule).

use super::ProgressiveParams;
pub use super::grid::{GridPhoton, PhotonGrid};
use crate::accel::TraversalStats;
use crate::config::RenderConfig;
use crate::integrator::photon::DirectParams;
use crate::material::{Bsdf, ShadingPoint, TransportMode};
use crate::math::{Color, hash_words};
use crate::photon::estimate;
use crate::rr::{RrContext, RussianRoulette, roulette};
use crate::sampler::{BOUNCE_BSDF_LOBE, BOUNCE_RR, DIM_PIXEL, Sampler, bounce_dim};
use crate::world::{Interaction, World};
use anyhow::{Result, bail};
use glam::{DVec3, Vec2, Vec3};
use std::borrow::Cow;
use std::collections::BTreeMap;

/// Photon paths per pass and pixel when `photons_per_pass` is unset (measured on
/// `cornell` and `cornell-glass` at 128²: 2 beat 1, 4 and 8 per pixel at equal time).
pub const DEFAULT_PHOTONS_PER_PIXEL: u64 = 2;
/// Default initial radius as a fraction of the scene's bounding-sphere radius
/// (measured with the area probes and `sppm_density_cap = 1` on `cornell`, McGuire's
/// CornellBox-Original and `cornell-glass`: 0.06 beat 0.03 on all three; without the
/// area probes and the cap, 0.03 was best).
pub const DEFAULT_RADIUS_FRACTION: f32 = 0.06;
/// Shadow rays per visible point and pass when `direct_samples` is unset (pbrt-v4's
/// one light sample per pass; more rays per pass did not lower the error per second).
pub const DEFAULT_DIRECT_SAMPLES: u32 = 1;
/// Smallest cosine between a photon's surface normal and the visible point's.
pub const NORMAL_COS: f32 = 0.7;

crate::params! {
    /// Parameters of the `sppm` integrator.
    pub struct SppmParams {
        /// Initial per-pixel radius (scene units); `auto` = 0.06 × the scene's bounding radius.
        sppm_radius: Option<f32> = "auto",
        /// Direct light by `trace` (shadow rays at the visible point) or `photons`.
        sppm_direct: String = "trace",
        /// After the first pass, a pixel whose disc caught more than this × the median photon count keeps only that many and its radius shrinks to match (a smaller start where light is dense, e.g. caustics); 0 = off.
        sppm_density_cap: f32 = "1",
        /// Probe rays per visible point and pass, where its disc leaves its triangle, that measure the share of its ball holding surface (edges, corners: boundary bias); 0 divides by π r².
        sppm_area_probes: u32 = "8",
    }
}

/// Everything `sppm` reads, checked.
#[derive(Clone, Debug)]
pub struct SppmSetup {
    /// Its own parameters.
    pub p: SppmParams,
    /// Pass budget and radius schedule.
    pub prog: ProgressiveParams,
    /// Direct light.
    pub direct: DirectParams,
}

impl SppmSetup {
    /// Reads and checks the `sppm` settings.
    pub fn read(cfg: &RenderConfig, r: &crate::param::Reader) -> Result<Self> {
        let prog = ProgressiveParams::read_checked(cfg, r)?;
        let p = SppmParams::read(r)?;
        let mut direct = DirectParams::read_checked(r)?;
        if !cfg.params.contains("direct_samples") {
            direct.direct_samples = DEFAULT_DIRECT_SAMPLES;
        }
        if !matches!(p.sppm_direct.as_str(), "trace" | "photons") {
            bail!("unknown sppm_direct `{}` (known: trace, photons)", p.sppm_direct);
        }
        if p.sppm_density_cap.is_nan() || p.sppm_density_cap < 0.0 {
            bail!("sppm_density_cap must be 0 (off) or positive, got {}", p.sppm_density_cap);
        }
        if let Some(r) = p.sppm_radius
            && (r.is_nan() || r <= 0.0 || r.is_infinite())
        {
            bail!("sppm_radius must be positive and finite, got {r}");
        }
        if let Some(photons) = prog.photons_per_pass
            && photons.saturating_mul(prog.passes.unwrap_or(1) as u64) > u32::MAX as u64 * 64
        {
            bail!("photons_per_pass × passes is too large ({photons} × {:?})", prog.passes);
        }
        Ok(SppmSetup { p, prog, direct })
    }
}

/// Where a camera path left its visible point.
#[derive(Clone, Copy, Debug)]
pub struct VisiblePoint {
    /// Position.
    pub p: Vec3,
    /// Geometric normal on the side the camera path arrived from.
    pub n: Vec3,
    /// Direction towards the camera (along the path).
    pub wo: Vec3,
    /// Shading frame.
    pub sp: ShadingPoint,
    /// Triangle (its material's BSDF is evaluated per photon).
    pub tri: u32,
    /// Texture coordinates (the material's textured parameters, [`VisiblePoint::bsdf`]).
    pub uv: Vec2,
    /// Camera-path throughput.
    pub beta: Color,
}

impl VisiblePoint {
    /// The BSDF at the visible point, textured parameters filled in ([`World::bsdf_at`]).
    pub fn bsdf<'w>(&self, world: &'w World) -> Cow<'w, Bsdf> {
        let it = Interaction { p: self.p, sp: self.sp, tri: self.tri, t: 0.0, front: true, uv: self.uv };
        world.bsdf_at(&it)
    }
}

/// A camera path's emitted + direct radiance and its visible point.
type CameraSample = (Color, Option<VisiblePoint>);

/// Per-pixel statistics carried from pass to pass.
#[derive(Clone, Copy, Debug)]
pub struct PixelStats {
    /// Sum over passes of emitted + directly lit radiance.
    pub ld: DVec3,
    /// Accumulated (radius-rescaled) flux τ.
    pub tau: DVec3,
    /// Accumulated photon count N.
    pub n: f64,
    /// Current radius.
    pub r: f64,
}

impl PixelStats {
    /// Fresh statistics with radius `r`.
    pub fn new(r: f64) -> Self {
        PixelStats { ld: DVec3::ZERO, tau: DVec3::ZERO, n: 0.0, r }
    }
    /// Folds in one pass's gather: `m` photons with summed flux `phi` (β applied).
    pub fn update(&mut self, m: u64, phi: DVec3, alpha: f64) {
        self.update_capped(m, phi, alpha, f64::INFINITY);
    }
    /// [`PixelStats::update`] keeping at most `cap` photons: N' = min(N + αM, cap),
    /// the radius shrinking to match as in the update (r' = r √(N'/(N + M))).
    pub fn update_capped(&mut self, m: u64, phi: DVec3, alpha: f64, cap: f64) {
        if m == 0 {
            return;
        }
        let m = m as f64;
        let n_new = if cap > self.n { (self.n + alpha * m).min(cap) } else { self.n + alpha * m };
        let r_new = self.r * (n_new / (self.n + m)).sqrt();
        self.tau = (self.tau + phi) * (r_new * r_new) / (self.r * self.r);
        self.n = n_new;
        self.r = r_new;
    }
    /// The statistics as bit patterns (checkpoints).
    pub fn to_bits(&self) -> [u64; 8] {
        let v = [self.ld.x, self.ld.y, self.ld.z, self.tau.x, self.tau.y, self.tau.z, self.n, self.r];
        v.map(f64::to_bits)
    }
    /// Inverse of [`PixelStats::to_bits`].
    pub fn from_bits(b: &[u64; 8]) -> Self {
        let v = b.map(f64::from_bits);
        PixelStats { ld: DVec3::new(v[0], v[1], v[2]), tau: DVec3::new(v[3], v[4], v[5]), n: v[6], r: v[7] }
    }
    /// Radiance estimate after `passes` passes of `photons` emitted paths each.
    pub fn radiance(&self, passes: u32, photons: u64) -> Color {
        let p = passes.max(1) as f64;
        let flux = self.tau / (p * photons as f64 * std::f64::consts::PI * self.r * self.r);
        (self.ld / p + flux).as_vec3()
    }
}

/// The stochastic progressive photon-mapping integrator.
pub struct SppmIntegrator {
    pub(super) cfg: RenderConfig,
    pub(super) set: SppmSetup,
    pub(super) rr: Box<dyn RussianRoulette>,
    pub(super) quiet: bool,
    pub(super) counters: BTreeMap<String, f64>,
}

impl SppmIntegrator {
    /// Builds the integrator (checking its settings).
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        Ok(Self::from_setup(cfg, SppmSetup::read(cfg, r)?, rr, quiet))
    }

    /// Builds the integrator from settings read before.
    pub fn from_setup(cfg: &RenderConfig, set: SppmSetup, rr: Box<dyn RussianRoulette>, quiet: bool) -> Self {
        SppmIntegrator { cfg: cfg.clone(), set, rr, quiet, counters: BTreeMap::new() }
    }

    /// Photon paths per pass: as set, or [`DEFAULT_PHOTONS_PER_PIXEL`] per pixel.
    pub(super) fn photons_per_pass(&self, npix: usize) -> u64 {
        self.set.prog.photons_per_pass.unwrap_or((DEFAULT_PHOTONS_PER_PIXEL * npix as u64).max(1024))
    }

    /// Traces pixel (x, y)'s camera path of pass `pass`: emitted + direct radiance and
    /// the visible point, if the path reaches a non-delta surface.
    /// `direct` is the direct-light sampler (unused with `sppm_direct = "photons"`).
    /// Generic over the camera sampler (static dispatch in the camera pass).
    #[allow(clippy::too_many_arguments)]
    pub fn camera_path<S: Sampler + ?Sized>(
        &self,
        world: &World,
        x: u32,
        y: u32,
        pass: u32,
        s: &mut S,
        direct: &mut dyn Sampler,
        stats: &mut TraversalStats,
    ) -> CameraSample {
        let cam = &world.scene.camera;
        s.start(y as u64 * cam.width as u64 + x as u64, pass as u64);
        s.set_dimension(DIM_PIXEL);
        let u = s.next_2d();
        let mut ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
        let mut beta = Color::ONE;
        let mut l = Color::ZERO;
        let max_depth = self.cfg.depth_limit();
        let mut depth = 0u32;
        loop {
            // Every vertex before the visible point was reached by the camera, a delta
            // lobe or a glossy-only surface passed through by BSDF sampling (which has
            // no light sampling), so emission and the environment count fully.
            let Some(it) = world.intersect(&ray, stats) else {
                if world.lights.env.is_some() {
                    l += beta * world.escaped(ray.d.normalize());
                }
                break;
            };
            let mat = world.material(&it);
            if it.front && mat.is_emitter() {
                l += beta * mat.emission;
            }
            let wo = -ray.d.normalize();
            // Textured parameters filled in (borrowed as is for untextured materials).
            let bsdf_at = world.bsdf_at(&it);
            let bsdf: &Bsdf = &bsdf_at;
            let dim = bounce_dim(depth);
            // As pbrt-v4: the visible point is the first vertex with a diffuse part (or
            // any non-delta one at the depth limit). A mixed BSDF's delta lobes are
            // followed with their sampling probability p instead (same `u_lobe` as
            // the sample below), the visible point weighted by 1/(1 − p).
            let mut stop = !bsdf.is_delta() && (!bsdf.is_glossy_only() || depth >= max_depth);
            if stop {
                let p = if depth < max_depth { bsdf.delta_probability(&it.sp, wo) } else { 0.0 };
                if p > 0.0 {
                    s.set_dimension(dim + BOUNCE_BSDF_LOBE);
                    if s.next_1d() < p {
                        stop = false;
                    } else {
                        beta /= 1.0 - p;
                    }
                }
            }
            if stop {
                if self.set.p.sppm_direct == "trace" {
                    let ds = &mut *direct;
                    // `direct_samples` shadow rays, stratified by the direct sampler on a
                    // stream of its own per (pixel, pass).
                    let n = self.set.direct.direct_samples.max(1);
                    let key = hash_words(&[y as u64 * cam.width as u64 + x as u64, pass as u64, 0xD1]);
                    let mut sum = Color::ZERO;
                    for j in 0..n {
                        ds.start(key, j as u64);
                        let u_sel = ds.next_1d();
                        let u_light = ds.next_2d();
                        sum += direct_light(world, &it, wo, bsdf, u_sel, u_light, stats);
                    }
                    l += beta * sum / n as f32;
                }
                let n = if wo.dot(it.sp.ng) >= 0.0 { it.sp.ng } else { -it.sp.ng };
                return (l, Some(VisiblePoint { p: it.p, n, wo, sp: it.sp, tri: it.tri, uv: it.uv, beta }));
            }
            if depth >= max_depth {
                break;
            }
            s.set_dimension(dim + BOUNCE_BSDF_LOBE);
            let u_lobe = s.next_1d();
            let u_dir = s.next_2d();
            let Some(bs) = bsdf.sample(&it.sp, wo, u_lobe, u_dir, TransportMode::Radiance) else { break };
            beta *= bs.weight;
            if beta.max_element() <= 0.0 {
                break;
            }
            depth += 1;
            s.set_dimension(dim + BOUNCE_RR);
            let u_rr = s.next_1d();
            match roulette(self.rr.as_ref(), &RrContext { depth, throughput: beta, albedo: bsdf.albedo() }, u_rr) {
                Some(w) => beta *= w,
                None => break,
            }
            ray = world.spawn(&it, bs.wi);
        }
        (l, None)
    }
}

/// One shadow-ray estimate of direct light at a visible point (a light chosen by
/// power, a point on it; no BSDF sampling, since the camera path ends here and the
/// light it would reach after one more bounce is carried by photons).
fn direct_light(
    world: &World,
    it: &Interaction,
    wo: Vec3,
    bsdf: &Bsdf,
    u_sel: f32,
    u_light: [f32; 2],
    stats: &mut TraversalStats,
) -> Color {
    let Some(ls) = world.lights.sample_li(&world.scene, it.p, u_sel, u_light) else { return Color::ZERO };
    if ls.pdf <= 0.0 {
        return Color::ZERO;
    }
    let f = bsdf.eval(&it.sp, wo, ls.wi);
    if f.max_element() <= 0.0 {
        return Color::ZERO;
    }
    let visible =
        if ls.dist.is_infinite() { world.unoccluded_dir(it, ls.wi, stats) } else { world.visible(it, ls.point, ls.normal, stats) };
    if !visible {
        return Color::ZERO;
    }
    f * ls.li * (ls.wi.dot(it.sp.ns()).abs() / ls.pdf)
}

/// Sampler stream of pass `pass`'s photon paths (top bit set: never a pixel's stream).
pub fn photon_stream(pass: u32) -> u64 {
    hash_words(&[pass as u64, 0x5991]) | 1 << 63
}

/// [`gather`] with the flux divided by the share of the visible point's ball that
/// holds surface able to catch the photons the gather counts (Hey & Purgathofer's
/// boundary-bias correction, the probe of the precomputed estimate,
/// [`estimate::coverage_sums`]): near edges and corners part of the disc holds no
/// surface and no photons, which otherwise darkens them. The share is measured per
/// visible point, over the whole ball the gather searches (a slab ±r), with `probes`
/// rays of the golden-angle spiral (rotation from `key`), each counting the first
/// surface inside the ball that faces like the visible point (past mirrors, glass and
/// surfaces outside the ball) with 1/cos (true area per projected area), so a crease
/// or a curve is measured, not read as a missing share. A ball within the visible
/// point's own triangle (farther than r from every edge) is covered: no probe. The
/// share is kept in [1/probes, 2] (a surface whose photons were found though no probe
/// met it covers at most about one probe's share). The rays it casts (side tests and
/// probes) are counted in `stats`.
pub fn gather_covered(
    world: &World,
    grid: &PhotonGrid,
    vp: &VisiblePoint,
    r: f32,
    probes: u32,
    key: u64,
    stats: &mut TraversalStats,
) -> (u64, DVec3) {
    let (m, phi) = gather(world, grid, vp, r, stats);
    if probes == 0 || m == 0 || disc_inside_triangle(world, vp, r) {
        return (m, phi);
    }
    let rot = crate::math::u32_to_unit((key >> 32) as u32) * std::f32::consts::TAU;
    let (got, flat) = estimate::coverage_sums(world, vp.p, vp.n, r * r, r, NORMAL_COS, estimate::Filter::Box, probes, rot, stats);
    let share = if flat > 0.0 { (got / flat).clamp(1.0 / probes as f32, 2.0) } else { 1.0 };
    (m, phi / share as f64)
}

/// True when the disc of radius `r` about the visible point lies within its own
/// triangle (every edge farther than r).
fn disc_inside_triangle(world: &World, vp: &VisiblePoint, r: f32) -> bool {
    let t = &world.scene.triangles[vp.tri as usize];
    (0..3).all(|k| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let e = b - a;
        let len2 = e.length_squared();
        // Distance from p to the edge's line, in the triangle's plane.
        len2 > 0.0 && (vp.p - a).cross(e).length_squared() >= r * r * len2
    })
}

/// Photons within `r` of the visible point that arrived on its side: their count and
/// Σ Φ f(wo, wi) (before the visible point's throughput). The diffuse part of f is
/// the same for every photon in the shading hemisphere of wo, so it multiplies the
/// summed power once; only a glossy lobe is evaluated per photon. The side tests'
/// rays are counted in `stats`.
pub fn gather(world: &World, grid: &PhotonGrid, vp: &VisiblePoint, r: f32, stats: &mut TraversalStats) -> (u64, DVec3) {
    let bsdf_at = vp.bsdf(world);
    let bsdf: &Bsdf = &bsdf_at;
    let glossy = bsdf.has_glossy();
    // f ≠ 0 needs wo and wi strictly on one side of the shading normal (and of the
    // geometric one, which `vp.n` already faces).
    let cos_o = vp.wo.dot(vp.sp.ns());
    let ns = if cos_o >= 0.0 { vp.sp.ns() } else { -vp.sp.ns() };
    let lit = cos_o != 0.0 && vp.wo.dot(vp.sp.ng) != 0.0;
    let (mut m, mut diffuse, mut lobe) = (0u64, DVec3::ZERO, DVec3::ZERO);
    // Photons beyond a surface close to the visible point's tangent plane (the lit top
    // of a thin ceiling over a panel's upper side) are not its own: the distances to
    // the nearest surfaces in front and behind, each measured once, when a photon off
    // the plane asks ([`estimate::keep_this_side`]).
    let tiny = estimate::off_plane_tolerance(vp.p);
    let (mut front, mut back) = (None, None);
    grid.for_each_within(vp.p, r, |pos, ph| {
        if ph.normal.dot(vp.n) < NORMAL_COS || ph.dir.dot(vp.n) <= 0.0 {
            return;
        }
        let h = (pos - vp.p).dot(vp.n);
        if h > tiny && h > 0.5 * *front.get_or_insert_with(|| estimate::free_distance(world, vp.p, vp.n, vp.n, 2.0 * r, stats)) {
            return;
        }
        if h < -tiny && -h > 0.5 * *back.get_or_insert_with(|| estimate::free_distance(world, vp.p, vp.n, -vp.n, 2.0 * r, stats)) {
            return;
        }
        m += 1;
        if lit && ph.dir.dot(ns) > 0.0 {
            diffuse += ph.power.as_dvec3();
            if glossy {
                lobe += (bsdf.eval_glossy(&vp.sp, vp.wo, ph.dir) * ph.power).as_dvec3();
            }
        }
    });
    let kd = (bsdf.diffuse_albedo() * std::f32::consts::FRAC_1_PI).as_dvec3();
    (m, diffuse * kd + lobe)
}

super::progressive_integrator!(SppmIntegrator, "sppm");

#[cfg(test)]
#[path = "sppm_tests.rs"]
mod tests;

//! `irradiance_cache`: Ward's irradiance cache (Ward, Rubinstein & Clear 1988) over the
//! final gather, optionally on top of precomputed irradiance.
//!
//! An entry stores the indirect irradiance from a stratified final gather
//! ([`super::hemisphere`]; `ic_samples` rays, one per stratum, then more in the strata
//! whose neighbours vary until the estimated standard error is about `ic_error` of
//! the irradiance — an entry's noise is frozen into every pixel it covers, so noise
//! that a per-pixel gather would average away shows as blotches), its rotational and translational gradients (Ward &
//! Heckbert 1992), the facing shading normal and a valid radius R: the harmonic mean
//! of the gather-ray hit distances (report eq. 11), limited by E/|∇E| (Křivánek et
//! al. 2006), clamped by its neighbours (R_i ≤ R_j + |p_i − p_j|, the same paper) and
//! finally to [`ic_min_pixels`, `ic_max_pixels`] pixel footprints at the entry
//! (Tabellion & Lamorlette 2004) and [`ic_min_radius`, `ic_max_radius`] × the scene's
//! bounding radius. A lookup at P with normal N uses the entries with
//! w_i = 1 / (|P − P_i| / R_i + √(1 − N·N_i)) > 1/a (a = tolerance), which are within
//! a·R_i, have a similar normal, and are not in front of P (Ward's
//! (P − P_i)·(N + N_i)/2 ≥ 0 test), and returns Σ w_i E_i / Σ w_i (eq. 12–13; the report
//! prints eq. 13 without the /R_i and with 1 + N·N_i, which we read as a typo for
//! Ward's form), each E_i extrapolated by its gradients to (P, N) first:
//! E_i + (N_i × N)·∇_r + (P − P_i)·∇_t, clamped at zero. A smaller tolerance a shrinks
//! every entry's reach, so bias falls monotonically with it (at more entries).
//!
//! Reproducibility: the cache is filled before rendering by a deterministic prefill
//! (rounds over the pixels at strides 16, 8, 4, 2, 1, one jittered position per
//! pixel, positions and gather rays a function of the render's seed and the pixel — pixel centres would put whole rows of entries exactly on the edges of
//! symmetric scenes, where gather rays start inside the neighbouring wall and leak
//! light through it; within a round every miss is computed in parallel against the
//! cache of the previous rounds, the new entries are inserted in pixel order and
//! neighbour clamping runs over all entries at once), then frozen. A render-time miss computes a
//! final gather for that point alone and does not insert it, so images are
//! bit-identical for any thread count.

use super::{Gather, hemisphere};
use crate::accel::TraversalStats;
use crate::integrator::photon::context::{GatherPoint, PhotonContext, ShadeKey};
use crate::material::Bsdf;
use crate::math::{Color, hash_words, u32_to_unit};
use crate::photon::estimate::facing_shading_normal;
use crate::photon::kdtree::{KdPoint, KdTree};
use crate::world::World;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// One cache record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CacheEntry {
    /// Position.
    pub pos: Vec3,
    /// Shading normal on the gathered side.
    pub normal: Vec3,
    /// Indirect irradiance.
    pub irradiance: Color,
    /// Valid radius R_i in use (after every clamp).
    pub radius: f32,
    /// Radius before the min/max clamps (what neighbour clamping propagates).
    pub radius_unclamped: f32,
    /// Clamp interval of this entry.
    pub radius_bounds: (f32, f32),
    /// Rotational gradient per channel.
    pub rot_grad: [Vec3; 3],
    /// Translational gradient per channel.
    pub trans_grad: [Vec3; 3],
}

impl KdPoint for CacheEntry {
    fn pos(&self) -> Vec3 {
        self.pos
    }
}

impl CacheEntry {
    /// New entry without gradients.
    pub fn new(pos: Vec3, normal: Vec3, irradiance: Color, radius: f32) -> Self {
        CacheEntry {
            pos,
            normal,
            irradiance,
            radius,
            radius_unclamped: radius,
            radius_bounds: (0.0, f32::INFINITY),
            rot_grad: [Vec3::ZERO; 3],
            trans_grad: [Vec3::ZERO; 3],
        }
    }

    /// The entry's irradiance extrapolated to (p, n) by its gradients, at least zero.
    #[inline]
    pub fn extrapolate(&self, p: Vec3, n: Vec3) -> Color {
        let (cross, dp) = (self.normal.cross(n), p - self.pos);
        let mut e = self.irradiance;
        for c in 0..3 {
            e[c] = (e[c] + cross.dot(self.rot_grad[c]) + dp.dot(self.trans_grad[c])).max(0.0);
        }
        e
    }
}

/// Ward's weight of entry `e` at (p, n); 0 when the entry must not be used.
#[inline]
pub fn weight(e: &CacheEntry, p: Vec3, n: Vec3, tolerance: f32) -> f32 {
    let d = p - e.pos;
    // "Not in front": the entry must not lie in front of the shaded point.
    if d.dot((n + e.normal) * 0.5) < -0.01 * e.radius {
        return 0.0;
    }
    let denom = d.length() / e.radius + (1.0 - n.dot(e.normal)).max(0.0).sqrt();
    if denom <= 0.0 {
        return f32::INFINITY;
    }
    let w = 1.0 / denom;
    if w > 1.0 / tolerance { w } else { 0.0 }
}

crate::params! {
    /// Parameters of the `irradiance_cache` gather.
    pub struct CacheSettings {
        /// Error tolerance a (Ward): entries with weight > 1/a are used; smaller values give every entry a smaller reach (less bias, more entries).
        ic_tolerance: f32 = "0.3",
        /// Smallest valid radius of an entry, as a fraction of the scene's bounding radius.
        ic_min_radius: f32 = "0.01",
        /// Largest valid radius of an entry, as a fraction of the scene's bounding radius.
        ic_max_radius: f32 = "0.25",
        /// Smallest valid radius in pixel footprints at the entry (Tabellion & Lamorlette 2004).
        ic_min_pixels: f32 = "10",
        /// Largest valid radius in pixel footprints at the entry.
        ic_max_pixels: f32 = "100",
        /// Irradiance gradients (Ward & Heckbert 1992) in the interpolation, and the radius limit E/|∇E| (Křivánek et al. 2006).
        ic_gradients: bool = "true",
        /// Rays per entry (stratified M × N with N ≈ πM); entries are reused over many pixels, so their noise becomes blotches: more rays than a per-pixel gather.
        ic_samples: u32 = "256",
        /// Adaptive entries: after one ray per stratum, strata whose neighbours differ get more rays, as many as bring the estimated standard error of the entry's irradiance to this fraction of it (an entry's noise is frozen into every pixel it covers); 0 = exactly `ic_samples` rays.
        ic_error: f32 = "0.03",
        /// Cap on the rays of one adaptive entry: at most ic_max_samples / ic_samples rays per stratum.
        ic_max_samples: u32 = "2048",
        /// Neighbour clamping of radii (Křivánek et al. 2006): R_i ≤ R_j + |p_i − p_j|.
        ic_neighbor_clamp: bool = "true",
        /// Gather over Christensen's precomputed irradiance (`precompute_stride`) instead of full photon estimates at gather hits.
        precomputed_irradiance: bool = "true",
    }
}

impl CacheSettings {
    /// Checks ranges.
    pub fn validate(&self) -> anyhow::Result<()> {
        let bad_px = |v: f32| v.is_nan() || v < 0.0 || v.is_infinite();
        if bad_px(self.ic_min_pixels) || bad_px(self.ic_max_pixels) || self.ic_max_pixels < self.ic_min_pixels {
            anyhow::bail!(
                "irradiance cache: need 0 <= ic_min_pixels <= ic_max_pixels (finite), got {} and {}",
                self.ic_min_pixels,
                self.ic_max_pixels
            );
        }
        let bad = |v: f32| v.is_nan() || v <= 0.0;
        if bad(self.ic_tolerance) || bad(self.ic_min_radius) || bad(self.ic_max_radius) || self.ic_max_radius < self.ic_min_radius {
            anyhow::bail!("irradiance cache: need ic_tolerance > 0 and 0 < ic_min_radius <= ic_max_radius");
        }
        if self.ic_samples == 0 {
            anyhow::bail!("ic_samples must be at least 1");
        }
        if self.ic_error.is_nan() || self.ic_error < 0.0 || self.ic_error >= 1.0 {
            anyhow::bail!("ic_error must be in [0, 1), got {}", self.ic_error);
        }
        Ok(())
    }
}

/// The cache.
pub struct IrradianceCache {
    /// Settings.
    pub settings: CacheSettings,
    tree: KdTree<CacheEntry>,
    largest: f32,
    hits: AtomicU64,
    misses: AtomicU64,
    entry_rays: AtomicU64,
    /// Number of prefill rounds run.
    pub rounds: u32,
}

impl IrradianceCache {
    /// Empty cache.
    pub fn new(settings: CacheSettings) -> Self {
        IrradianceCache {
            settings,
            tree: KdTree::default(),
            largest: 0.0,
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
            entry_rays: AtomicU64::new(0),
            rounds: 0,
        }
    }

    /// Entries.
    pub fn entries(&self) -> &[CacheEntry] {
        &self.tree.points
    }

    /// Interpolated irradiance at (p, n), or `None` when no entry is valid there.
    pub fn lookup(&self, p: Vec3, n: Vec3) -> Option<Color> {
        if self.tree.is_empty() {
            return None;
        }
        let a = self.settings.ic_tolerance;
        let reach = a * self.largest;
        let (mut ws, mut acc) = (0.0f32, Color::ZERO);
        self.tree.for_each_within(p, reach * reach, &mut |i, _| {
            let e = &self.tree.points[i];
            let w = weight(e, p, n, a);
            if w <= 0.0 {
                return;
            }
            let ei = if self.settings.ic_gradients { e.extrapolate(p, n) } else { e.irradiance };
            if w.is_infinite() {
                ws = f32::INFINITY;
                acc = ei;
            } else if ws.is_finite() {
                ws += w;
                acc += ei * w;
            }
        });
        if ws.is_infinite() {
            Some(acc)
        } else if ws > 0.0 {
            Some(acc / ws)
        } else {
            None
        }
    }

    /// Adds entries (rebuilding the tree), then clamps every radius by its
    /// neighbours when enabled.
    pub fn insert(&mut self, new: Vec<CacheEntry>) {
        if new.is_empty() {
            return;
        }
        let mut all = std::mem::take(&mut self.tree.points);
        all.extend(new);
        self.largest = all.iter().map(|e| e.radius).fold(0.0, f32::max);
        self.tree = KdTree::build(all);
        if self.settings.ic_neighbor_clamp {
            self.clamp_neighbours();
        }
    }

    /// Neighbour clamping (Křivánek et al. 2006): R_i ≤ R_j + |p_i − p_j| over all
    /// pairs, computed from the unclamped radii of all entries at once, so the
    /// result does not depend on insertion order.
    fn clamp_neighbours(&mut self) {
        let tree = &self.tree;
        let clamped: Vec<f32> = (0..tree.len())
            .into_par_iter()
            .map(|i| {
                let e = &tree.points[i];
                let mut r = e.radius_unclamped;
                // A neighbour further than the upper clamp cannot change the result.
                let reach = r.min(e.radius_bounds.1);
                tree.for_each_within(e.pos, reach * reach, &mut |j, d2| {
                    if j != i {
                        r = r.min(tree.points[j].radius_unclamped + d2.sqrt());
                    }
                });
                r
            })
            .collect();
        for (e, r) in self.tree.points.iter_mut().zip(clamped) {
            e.radius_unclamped = r;
            e.radius = r.clamp(e.radius_bounds.0, e.radius_bounds.1);
        }
        self.largest = self.tree.points.iter().map(|e| e.radius).fold(0.0, f32::max);
    }

    /// Computes an entry at `at`, whose pixel footprint (scene units) is `footprint`.
    fn entry_at(&self, ctx: &PhotonContext, at: &GatherPoint, footprint: f32, stats: &mut TraversalStats) -> CacheEntry {
        let st = &self.settings;
        let (world, it, wo) = (at.world, at.it, at.wo);
        let refine = hemisphere::Refine { rel_error: st.ic_error, max_rays: st.ic_max_samples };
        let g = hemisphere::gather(ctx, at, st.ic_samples, refine, stats);
        self.entry_rays.fetch_add(g.rays as u64, Ordering::Relaxed);
        let scene_r = world.lights.scene_radius;
        let lo = (st.ic_min_radius * scene_r).max(st.ic_min_pixels * footprint);
        let hi = (st.ic_max_radius * scene_r).min(st.ic_max_pixels * footprint).max(lo);
        let mut r = g.harmonic_distance;
        let mut trans = g.trans_grad;
        if st.ic_gradients {
            // Limit R by the gradient: E changes by no more than itself within R.
            let mean_e = crate::math::mean(g.irradiance);
            let grad = (trans[0] + trans[1] + trans[2]) / 3.0;
            if grad.length() > 0.0 && mean_e > 0.0 {
                r = r.min(mean_e / grad.length());
            }
            // Gradients measured over geometry closer than the smallest radius are
            // unreliable: scale them down (Křivánek et al.).
            if g.min_distance.is_finite() && lo > 0.0 {
                let s = (g.min_distance / lo).min(1.0);
                for t in &mut trans {
                    *t *= s;
                }
            }
        }
        CacheEntry {
            pos: it.p,
            normal: facing_shading_normal(it, wo),
            irradiance: g.irradiance,
            radius: r.clamp(lo, hi),
            radius_unclamped: r,
            radius_bounds: (lo, hi),
            rot_grad: if st.ic_gradients { g.rot_grad } else { [Vec3::ZERO; 3] },
            trans_grad: if st.ic_gradients { trans } else { [Vec3::ZERO; 3] },
        }
    }

    /// Deterministic prefill over jittered pixel positions (see the module docs).
    pub fn prefill(&mut self, ctx: &PhotonContext, world: &World, seed: u64, quiet: bool) {
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        // Angle subtended by one pixel at the image centre.
        let pixel_angle = 2.0 * (0.5 * cam.fov_y_deg.to_radians()).tan() / h as f32;
        let strides = [16u32, 8, 4, 2, 1];
        let pb = crate::progress::progress_bar(strides.len() as u64, quiet, "cache prefill");
        for s in strides {
            let pixels: Vec<(u32, u32)> =
                (0..h).step_by(s as usize).flat_map(|y| (0..w).step_by(s as usize).map(move |x| (x, y))).collect();
            let new: Vec<CacheEntry> = pixels
                .par_iter()
                .filter_map(|&(x, y)| {
                    let mut stats = TraversalStats::default();
                    let pixel = y as u64 * w as u64 + x as u64;
                    let PrefillKeys { path: path_key, gather: key, jitter: (jx, jy) } = PrefillKeys::new(seed, pixel);
                    let ray = cam.generate_ray(x as f32 + jx, y as f32 + jy);
                    let path = ctx.follow_specular_path(world, ray, path_key, &mut stats)?;
                    let (it, wo) = (path.it, path.wo);
                    let bsdf = &*world.bsdf_at(&it);
                    if !cacheable(bsdf) || self.lookup(it.p, facing_shading_normal(&it, wo)).is_some() {
                        return None;
                    }
                    let cos = wo.dot(it.sp.ng).abs().max(0.05);
                    let footprint = path.length * pixel_angle / cos.sqrt();
                    Some(self.entry_at(ctx, &GatherPoint { world, it: &it, wo, bsdf, key, pixel: None }, footprint, &mut stats))
                })
                .collect();
            self.insert(new);
            self.rounds += 1;
            pb.inc(1);
        }
        pb.finish_and_clear();
    }
}

/// The random numbers of the prefill at one pixel, from independent streams: the
/// camera ray's jitter, its mirror and glass choices (`path`: dimension d is the
/// choice at specular depth d) and the entry's gather (`gather`: dimensions 2s, 2s + 1
/// jitter the first ray of stratum s). One key for both would tie the glass branch
/// taken at depth d to the jitter of the gather's stratum d / 2.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PrefillKeys {
    path: ShadeKey,
    gather: ShadeKey,
    jitter: (f32, f32),
}

impl PrefillKeys {
    fn new(seed: u64, pixel: u64) -> Self {
        let gather = ShadeKey(hash_words(&[0xCAC4E, seed, pixel]));
        let j = hash_words(&[0x717E5, seed, pixel]);
        PrefillKeys { path: gather.child(0x5BEC_CA3E), gather, jitter: (u32_to_unit(j as u32), u32_to_unit((j >> 32) as u32)) }
    }
}

/// The cache stores irradiance, which describes the diffuse part of any surface that
/// has one (the glossy lobe is gathered separately).
#[inline]
fn cacheable(bsdf: &Bsdf) -> bool {
    !bsdf.is_delta() && bsdf.diffuse_albedo().max_element() > 0.0
}

impl Gather for IrradianceCache {
    fn name(&self) -> &'static str {
        "irradiance_cache"
    }
    fn prepare(&mut self, ctx: &PhotonContext, world: &World, seed: u64, quiet: bool) -> anyhow::Result<()> {
        self.prefill(ctx, world, seed, quiet);
        Ok(())
    }
    fn indirect(&self, ctx: &PhotonContext, at: &GatherPoint, stats: &mut TraversalStats) -> Color {
        if !cacheable(at.bsdf) {
            return ctx.gathered_indirect(at, 0, stats);
        }
        let e = match self.lookup(at.it.p, facing_shading_normal(at.it, at.wo)) {
            Some(e) => {
                self.hits.fetch_add(1, Ordering::Relaxed);
                e
            }
            None => {
                self.misses.fetch_add(1, Ordering::Relaxed);
                ctx.final_gather(at, 0, stats).irradiance
            }
        };
        at.bsdf.diffuse_albedo() * std::f32::consts::FRAC_1_PI * e + ctx.glossy_gather(at, 0, stats)
    }
    fn counters(&self) -> Vec<(String, f64)> {
        vec![
            ("cache_entries".into(), self.tree.len() as f64),
            ("cache_hits".into(), self.hits.load(Ordering::Relaxed) as f64),
            ("cache_misses".into(), self.misses.load(Ordering::Relaxed) as f64),
            ("cache_entry_rays".into(), self.entry_rays.load(Ordering::Relaxed) as f64),
        ]
    }
    fn debug_points(&self) -> Vec<Vec3> {
        self.tree.points.iter().map(|e| e.pos).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weight_rules() {
        let e = CacheEntry::new(Vec3::ZERO, Vec3::Z, Color::ONE, 1.0);
        // At the entry: infinite weight.
        assert!(weight(&e, Vec3::ZERO, Vec3::Z, 0.3).is_infinite());
        // Within a·R on the plane: valid, weight 1/(d/R).
        let w = weight(&e, Vec3::new(0.2, 0.0, 0.0), Vec3::Z, 0.3);
        assert!((w - 5.0).abs() < 1e-5);
        // Beyond a·R: invalid.
        assert_eq!(weight(&e, Vec3::new(0.35, 0.0, 0.0), Vec3::Z, 0.3), 0.0);
        // Normal too different: invalid.
        let n = Vec3::new(0.5, 0.0, 0.866).normalize();
        assert_eq!(weight(&e, Vec3::new(0.01, 0.0, 0.0), n, 0.3), 0.0);
        // The entry in front of the point (point below the entry's plane): rejected.
        assert_eq!(weight(&e, Vec3::new(0.05, 0.0, -0.05), Vec3::Z, 0.3), 0.0);
        // Behind is fine.
        assert!(weight(&e, Vec3::new(0.05, 0.0, 0.05), Vec3::Z, 0.3) > 0.0);
    }

    fn test_settings() -> CacheSettings {
        CacheSettings::default()
    }

    /// Gradients extrapolate: an entry with ∇_t E = (1, 0, 0) read 0.1 to its right
    /// gives E + 0.1; rotating the normal towards +x with ∇_r E = (0, 2, 0) adds
    /// (N_i × N)·∇_r.
    #[test]
    fn extrapolation_by_gradients() {
        let mut e = CacheEntry::new(Vec3::ZERO, Vec3::Z, Color::splat(1.0), 1.0);
        e.trans_grad = [Vec3::X; 3];
        e.rot_grad = [Vec3::new(0.0, 2.0, 0.0); 3];
        let at = e.extrapolate(Vec3::new(0.1, 0.0, 0.0), Vec3::Z);
        assert!((at.x - 1.1).abs() < 1e-6, "{at}");
        let n = Vec3::new(0.1, 0.0, 1.0).normalize();
        let rot = e.extrapolate(Vec3::ZERO, n);
        assert!((rot.x - (1.0 + Vec3::Z.cross(n).y * 2.0)).abs() < 1e-6 && rot.x > 1.0, "{rot}");
        // Never negative.
        assert_eq!(e.extrapolate(Vec3::new(-5.0, 0.0, 0.0), Vec3::Z).x, 0.0);
    }

    /// Neighbour clamping: a large entry next to a small one is limited to the small
    /// one's radius plus their distance, whatever the insertion order.
    #[test]
    fn neighbour_clamping_is_order_free() {
        let big = CacheEntry::new(Vec3::ZERO, Vec3::Z, Color::ONE, 1.0);
        let small = CacheEntry::new(Vec3::new(0.3, 0.0, 0.0), Vec3::Z, Color::ONE, 0.05);
        let radii = |order: Vec<CacheEntry>| {
            let mut c = IrradianceCache::new(test_settings());
            c.insert(order);
            let mut r: Vec<f32> = c.entries().iter().map(|e| e.radius).collect();
            r.sort_by(f32::total_cmp);
            r
        };
        let a = radii(vec![big, small]);
        assert_eq!(a, radii(vec![small, big]));
        assert!((a[1] - 0.35).abs() < 1e-6 && a[0] == 0.05, "{a:?}");
        let mut off = IrradianceCache::new(CacheSettings { ic_neighbor_clamp: false, ..test_settings() });
        off.insert(vec![big, small]);
        assert!(off.entries().iter().any(|e| e.radius == 1.0));
    }

    /// The prefill's camera-ray choices, its jitter and its gather's stratum jitter
    /// are uncorrelated over pixels (one key for the path and the gather gives a
    /// correlation of 1 between the glass choice at depth d and dimension d).
    #[test]
    fn prefill_draws_are_independent() {
        let n = 4096u64;
        let keys: Vec<PrefillKeys> = (0..n).map(|p| PrefillKeys::new(0x5EED, p)).collect();
        let corr = |a: &dyn Fn(&PrefillKeys) -> f32, b: &dyn Fn(&PrefillKeys) -> f32| {
            let (xs, ys): (Vec<f64>, Vec<f64>) = keys.iter().map(|k| (a(k) as f64, b(k) as f64)).unzip();
            let (mx, my) = (xs.iter().sum::<f64>() / n as f64, ys.iter().sum::<f64>() / n as f64);
            let cov: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
            let (vx, vy): (f64, f64) = (xs.iter().map(|x| (x - mx).powi(2)).sum(), ys.iter().map(|y| (y - my).powi(2)).sum());
            cov / (vx * vy).sqrt()
        };
        // 4096 pairs: an independent correlation has standard deviation 1/64.
        let limit = 5.0 / 64.0;
        let max_spec = crate::integrator::photon::context::MAX_SPECULAR as u64;
        for d in 0..max_spec {
            for g in 0..max_spec + 2 {
                let c = corr(&|k| k.path.uniform(d), &|k| k.gather.uniform(g));
                assert!(c.abs() < limit, "specular choice {d} and gather dimension {g}: correlation {c}");
            }
        }
        for g in 0..max_spec {
            for (name, j) in [("x", &(|k: &PrefillKeys| k.jitter.0) as &dyn Fn(&PrefillKeys) -> f32), ("y", &|k: &PrefillKeys| k.jitter.1)]
            {
                let c = corr(j, &|k| k.gather.uniform(g));
                assert!(c.abs() < limit, "jitter {name} and gather dimension {g}: correlation {c}");
                let c = corr(j, &|k| k.path.uniform(g));
                assert!(c.abs() < limit, "jitter {name} and specular choice {g}: correlation {c}");
            }
        }
    }

    #[test]
    fn lookup_interpolates_by_weight() {
        let mut c = IrradianceCache::new(CacheSettings { ic_tolerance: 0.5, ic_neighbor_clamp: false, ..test_settings() });
        assert!(c.lookup(Vec3::ZERO, Vec3::Z).is_none());
        c.insert(vec![
            CacheEntry::new(Vec3::new(-0.1, 0.0, 0.0), Vec3::Z, Color::splat(1.0), 1.0),
            CacheEntry::new(Vec3::new(0.3, 0.0, 0.0), Vec3::Z, Color::splat(3.0), 1.0),
        ]);
        // Weights 1/0.1 = 10 and 1/0.3 = 3.33: E = (10·1 + 3.33·3)/13.33 = 1.5.
        let e = c.lookup(Vec3::ZERO, Vec3::Z).unwrap();
        assert!((e.x - 1.5).abs() < 1e-4, "{e}");
        // Far away: miss.
        assert!(c.lookup(Vec3::new(5.0, 0.0, 0.0), Vec3::Z).is_none());
    }
}

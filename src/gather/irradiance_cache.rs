//! `irradiance_cache`: Ward's irradiance cache (Ward, Rubinstein & Clear 1988) over the
//! final gather, optionally on top of precomputed irradiance.
//!
//! An entry stores the indirect irradiance from a final gather, the surface normal
//! and a valid radius R = harmonic mean of the gather-ray hit distances (report
//! eq. 11), clamped to [`ic_min_radius`, `ic_max_radius`] × the scene's bounding
//! radius. A lookup at P with normal N uses the entries with
//! w_i = 1 / (|P − P_i| / R_i + √(1 − N·N_i)) > 1/a (a = tolerance), which are within
//! a·R_i, have a similar normal, and are not in front of P (Ward's
//! (P − P_i)·(N + N_i)/2 ≥ 0 test), and returns Σ w_i E_i / Σ w_i (eq. 12–13; the report
//! prints eq. 13 without the /R_i and with 1 + N·N_i, which we read as a typo for
//! Ward's form).
//!
//! Reproducibility: the cache is filled before rendering by a deterministic prefill
//! (rounds over the pixel centres at strides 16, 8, 4, 2, 1; within a round every
//! miss is computed in parallel against the cache of the previous rounds, and the new
//! entries are inserted in pixel order), then frozen. A render-time miss computes a
//! final gather for that point alone and does not insert it, so images are
//! bit-identical for any thread count.

use super::{Gather, PhotonContext, ShadeKey};
use crate::accel::TraversalStats;
use crate::material::Bsdf;
use crate::math::Color;
use crate::photon::estimate::facing_normal;
use crate::photon::kdtree::{KdPoint, KdTree};
use crate::world::{Interaction, World};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// One cache record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CacheEntry {
    /// Position.
    pub pos: Vec3,
    /// Normal on the gathered side.
    pub normal: Vec3,
    /// Indirect irradiance.
    pub irradiance: Color,
    /// Valid radius R_i.
    pub radius: f32,
}

impl KdPoint for CacheEntry {
    fn pos(&self) -> Vec3 {
        self.pos
    }
}

impl CacheEntry {
    /// New entry.
    pub fn new(pos: Vec3, normal: Vec3, irradiance: Color, radius: f32) -> Self {
        CacheEntry { pos, normal, irradiance, radius }
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

/// The cache.
pub struct IrradianceCache {
    /// Tolerance a.
    pub tolerance: f32,
    /// Valid-radius clamp, fraction of the scene's bounding radius.
    pub min_frac: f32,
    /// Valid-radius clamp, fraction of the scene's bounding radius.
    pub max_frac: f32,
    min_radius: f32,
    max_radius: f32,
    tree: KdTree<CacheEntry>,
    largest: f32,
    hits: AtomicU64,
    misses: AtomicU64,
    /// Number of prefill rounds run.
    pub rounds: u32,
}

impl IrradianceCache {
    /// Empty cache; the radius clamps are fractions of the scene's bounding radius.
    pub fn new(tolerance: f32, min_frac: f32, max_frac: f32) -> Self {
        IrradianceCache {
            tolerance,
            min_frac,
            max_frac,
            min_radius: 0.0,
            max_radius: f32::INFINITY,
            tree: KdTree::default(),
            largest: 0.0,
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
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
        let reach = self.tolerance * self.largest;
        let (mut ws, mut acc) = (0.0f32, Color::ZERO);
        self.tree.for_each_within(p, reach * reach, &mut |i, _| {
            let e = &self.tree.points[i];
            let w = weight(e, p, n, self.tolerance);
            if w.is_infinite() {
                ws = f32::INFINITY;
                acc = e.irradiance;
            } else if w > 0.0 && ws.is_finite() {
                ws += w;
                acc += e.irradiance * w;
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

    /// Adds entries (rebuilding the tree).
    pub fn insert(&mut self, new: Vec<CacheEntry>) {
        if new.is_empty() {
            return;
        }
        let mut all = std::mem::take(&mut self.tree.points);
        all.extend(new);
        self.largest = all.iter().map(|e| e.radius).fold(0.0, f32::max);
        self.tree = KdTree::build(all);
    }

    #[allow(clippy::too_many_arguments)]
    fn entry_at(
        &self,
        ctx: &PhotonContext,
        world: &World,
        it: &Interaction,
        wo: Vec3,
        bsdf: &Bsdf,
        key: ShadeKey,
        stats: &mut TraversalStats,
    ) -> CacheEntry {
        let g = ctx.final_gather(world, it, wo, bsdf, 0, key, stats);
        let r = g.harmonic_distance.clamp(self.min_radius, self.max_radius);
        CacheEntry::new(it.p, facing_normal(it, wo), g.irradiance, r)
    }

    /// Deterministic prefill over the pixel centres (see the module docs).
    pub fn prefill(&mut self, ctx: &PhotonContext, world: &World, quiet: bool) {
        self.min_radius = self.min_frac * world.lights.scene_radius;
        self.max_radius = self.max_frac * world.lights.scene_radius;
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let strides = [16u32, 8, 4, 2, 1];
        let pb = crate::render::progress_bar(strides.len() as u64, quiet, "cache prefill");
        for s in strides {
            let pixels: Vec<(u32, u32)> =
                (0..h).step_by(s as usize).flat_map(|y| (0..w).step_by(s as usize).map(move |x| (x, y))).collect();
            let new: Vec<CacheEntry> = pixels
                .par_iter()
                .filter_map(|&(x, y)| {
                    let mut stats = TraversalStats::default();
                    let key = ShadeKey(crate::math::hash_words(&[0xCAC4E, y as u64 * w as u64 + x as u64]));
                    let ray = cam.generate_ray(x as f32 + 0.5, y as f32 + 0.5);
                    let (it, wo, _) = ctx.follow_specular(world, ray, key, &mut stats)?;
                    let bsdf = &world.material(&it).bsdf;
                    if !cacheable(bsdf) || self.lookup(it.p, facing_normal(&it, wo)).is_some() {
                        return None;
                    }
                    Some(self.entry_at(ctx, world, &it, wo, bsdf, key, &mut stats))
                })
                .collect();
            self.insert(new);
            self.rounds += 1;
            pb.inc(1);
        }
        pb.finish_and_clear();
    }
}

/// The cache stores irradiance, which only describes Lambertian reflection.
#[inline]
fn cacheable(bsdf: &Bsdf) -> bool {
    matches!(bsdf, Bsdf::Lambertian(_))
}

impl Gather for IrradianceCache {
    fn name(&self) -> &'static str {
        "irradiance_cache"
    }
    fn prepare(&mut self, ctx: &PhotonContext, world: &World, quiet: bool) -> anyhow::Result<()> {
        self.prefill(ctx, world, quiet);
        Ok(())
    }
    #[allow(clippy::too_many_arguments)]
    fn indirect(
        &self,
        ctx: &PhotonContext,
        world: &World,
        it: &Interaction,
        wo: Vec3,
        bsdf: &Bsdf,
        key: ShadeKey,
        stats: &mut TraversalStats,
    ) -> Color {
        if !cacheable(bsdf) {
            return ctx.final_gather(world, it, wo, bsdf, 0, key, stats).radiance;
        }
        let e = match self.lookup(it.p, facing_normal(it, wo)) {
            Some(e) => {
                self.hits.fetch_add(1, Ordering::Relaxed);
                e
            }
            None => {
                self.misses.fetch_add(1, Ordering::Relaxed);
                ctx.final_gather(world, it, wo, bsdf, 0, key, stats).irradiance
            }
        };
        bsdf.diffuse_albedo() * std::f32::consts::FRAC_1_PI * e
    }
    fn counters(&self) -> Vec<(String, f64)> {
        vec![
            ("cache_entries".into(), self.tree.len() as f64),
            ("cache_hits".into(), self.hits.load(Ordering::Relaxed) as f64),
            ("cache_misses".into(), self.misses.load(Ordering::Relaxed) as f64),
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

    #[test]
    fn lookup_interpolates_by_weight() {
        let mut c = IrradianceCache::new(0.5, 0.01, 10.0);
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

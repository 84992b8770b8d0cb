//! Russian roulette is unbiased: for each policy (`fixed`, `albedo`, `throughput`)
//! Welch's t-test (α = 0.001) compares an estimator using the policy with the same
//! estimator without roulette (`off`), both truncated at the same maximum depth so
//! they estimate exactly the same quantity:
//!
//! - `rr/pixels/*`: the mean radiance of the lower half of a small Cornell box image
//!   (floor, blocks, walls: no pixel sees the light directly), by the `path`
//!   integrator; one observation = one sample of every pixel of the set;
//! - `rr/photons/*`: the total power the photon tracer stores per emitted path
//!   (direct + indirect + caustic maps, before normalisation).
//!
//! The samples are independent (separate seeds), so Welch's test applies; the
//! `mde%` rows report the smallest relative bias each comparison detects with 80 %
//! power at α = 0.001, which must be at most 1 %. The planted control `broken`
//! survives with probability 0.8 but does not divide survivors by it; it must be
//! flagged.

use super::{FamilyReport, Outcome, Settings, TestRow, normal_quantile, welch};
use crate::accel::TraversalStats;
use crate::integrator::Integrator;
use crate::integrator::path::PathIntegrator;
use crate::math::mean;
use crate::photon::trace_path;
use crate::registry::{make_accel, make_rr};
use crate::rr::{RrContext, RussianRoulette};
use crate::sampler::random::RandomSampler;
use crate::sampler::{DIM_PIXEL, Sampler};
use crate::scene::builtin::cornell;
use crate::world::World;
use anyhow::Result;
use rayon::prelude::*;

/// Significance level of every t-test.
pub const ALPHA: f64 = 0.001;
/// Largest relative bias the sample size must be able to detect (80 % power).
pub const DETECT: f64 = 0.01;
/// Bounces of every path, with and without roulette (the common estimand).
pub const MAX_DEPTH: u32 = 64;

/// Planted control: survives with probability `q` but weights survivors by 1, so
/// every roulette decision loses a fraction 1 − q of the energy.
pub struct BrokenRoulette {
    /// Survival probability.
    pub q: f32,
}

impl RussianRoulette for BrokenRoulette {
    fn name(&self) -> &'static str {
        "broken"
    }
    fn survival_probability(&self, _: &RrContext) -> f32 {
        self.q
    }
    fn survivor_weight(&self, _q: f32) -> f32 {
        1.0
    }
}

/// A policy under test: name, policy, expected verdict.
pub type Policy = (String, Box<dyn RussianRoulette>, Outcome);

/// The policies under test with their expected verdicts (the planted one last).
pub fn policies() -> Result<Vec<Policy>> {
    let mut v: Vec<Policy> = Vec::new();
    for name in ["fixed", "albedo", "throughput"] {
        v.push((name.to_string(), make_rr(name)?, Outcome::Pass));
    }
    v.push(("broken".into(), Box::new(BrokenRoulette { q: 0.8 }), Outcome::Fail));
    Ok(v)
}

/// The Cornell box at `res`×`res` pixels with its BVH.
fn cornell_world(res: u32) -> Result<World> {
    let mut scene = cornell();
    scene.camera = scene.camera.with_resolution(res, res)?;
    let accel = make_accel("bvh", &scene.triangles)?;
    World::new(scene, accel)
}

/// `n` observations of the mean radiance (channel mean) over `pixels`, by the path
/// integrator with policy `rr`.
pub fn pixel_samples(world: &World, rr: Box<dyn RussianRoulette>, pixels: &[(u32, u32)], n: usize, seed: u64) -> Vec<f64> {
    let integrator = PathIntegrator { max_depth: MAX_DEPTH, rr, output: Default::default() };
    let cam = &world.scene.camera;
    (0..n)
        .into_par_iter()
        .with_min_len(16)
        .map_init(
            || RandomSampler::new(seed),
            |s, j| {
                let mut stats = TraversalStats::default();
                let mut sum = 0.0f64;
                for &(x, y) in pixels {
                    s.start(y as u64 * cam.width as u64 + x as u64, j as u64);
                    s.set_dimension(DIM_PIXEL);
                    let u = s.next_2d();
                    let ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
                    let l = integrator.li(world, &ray, s, &mut stats);
                    sum += mean(l) as f64;
                }
                sum / pixels.len() as f64
            },
        )
        .collect()
}

/// Total stored power (channel mean) of each of `n` photon paths.
pub fn photon_samples(world: &World, rr: &dyn RussianRoulette, n: usize, seed: u64) -> Vec<f64> {
    (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map_init(
            || (RandomSampler::new(seed), Vec::new()),
            |(s, out), i| {
                out.clear();
                let mut stats = TraversalStats::default();
                trace_path(world, s, i as u64, rr, MAX_DEPTH, &mut stats, out);
                out.iter().map(|p| mean(p.power) as f64).sum::<f64>()
            },
        )
        .collect()
}

/// Rows comparing each policy's observations with the `off` baseline.
fn compare(what: &str, base: &[f64], runs: &[(String, Vec<f64>, Outcome)]) -> Vec<TestRow> {
    // Bias detectable with 80 % power by a two-sided test at level ALPHA.
    let z = normal_quantile(1.0 - ALPHA / 2.0) + normal_quantile(0.8);
    let mut rows = Vec::new();
    for (name, x, expected) in runs {
        let w = welch(x, base);
        rows.push(TestRow::new(format!("rr/{what}/{name}"), w.t, Some(w.p), *expected, w.p >= ALPHA));
        if *expected == Outcome::Pass {
            let mde = z * w.se / w.mean_b.abs();
            rows.push(TestRow::new(format!("rr/{what}/{name}/mde%"), 100.0 * mde, None, Outcome::Pass, mde <= DETECT));
        }
    }
    rows
}

/// Runs the family.
pub fn run(s: &Settings) -> Result<FamilyReport> {
    let res = 16u32;
    let world = cornell_world(res)?;
    // Lower half of the image: floor, blocks and walls; the light is in the top rows.
    let pixels: Vec<(u32, u32)> = (res / 2..res).flat_map(|y| (0..res).map(move |x| (x, y))).collect();
    let n_pix = s.pick(6000, 30000);
    let n_photons = s.pick(300_000, 2_000_000);
    let off = make_rr("off")?;
    let base_pix = pixel_samples(&world, make_rr("off")?, &pixels, n_pix, 1);
    let base_ph = photon_samples(&world, off.as_ref(), n_photons, 1);
    let mut pix = Vec::new();
    let mut ph = Vec::new();
    for (i, (name, policy, expected)) in policies()?.into_iter().enumerate() {
        let seed = 100 + i as u64;
        ph.push((name.clone(), photon_samples(&world, policy.as_ref(), n_photons, seed), expected));
        pix.push((name, pixel_samples(&world, policy, &pixels, n_pix, seed), expected));
    }
    let mut rows = compare("pixels", &base_pix, &pix);
    rows.extend(compare("photons", &base_ph, &ph));
    Ok(FamilyReport { rows, plots: Vec::new() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broken_policy_loses_energy_on_average() {
        let ctx = RrContext { depth: 1, throughput: crate::math::Color::ONE, albedo: crate::math::Color::ONE };
        let b = BrokenRoulette { q: 0.5 };
        let mean_w: f32 = (0..1000).map(|i| crate::rr::roulette(&b, &ctx, (i as f32 + 0.5) / 1000.0).unwrap_or(0.0)).sum::<f32>() / 1000.0;
        assert!((mean_w - 0.5).abs() < 1e-6);
    }
}

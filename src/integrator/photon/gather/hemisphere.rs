//! The stratified hemisphere gather behind irradiance-cache entries, with Ward &
//! Heckbert's (1992) irradiance gradients.
//!
//! The hemisphere about the facing shading normal is split into M × N strata of
//! equal projected solid angle (sin²θ ∈ [j/M, (j+1)/M), φ ∈ [2πk/N, 2π(k+1)/N)), one
//! jittered ray per stratum, so E = π/(MN) Σ L_jk. The rotational gradient is
//! π/(MN) Σ_k v_k Σ_j −tanθ_j L_jk and the translational gradient is the sum over
//! the boundaries between neighbouring strata of the radiance difference divided by
//! the nearer hit distance, in the form of Křivánek & Gautron ("Practical Global
//! Illumination with Irradiance Caching", 2009, eq. 5.5/5.6 for cosine-weighted
//! strata).

use crate::accel::TraversalStats;
use crate::integrator::photon::context::{GatherPoint, PhotonContext};
use crate::math::{Color, Frame};
use crate::photon::estimate::facing_shading_normal;
use glam::Vec3;
use std::f32::consts::PI;

/// What one stratified gather measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct HemisphereResult {
    /// Irradiance about the facing shading normal.
    pub irradiance: Color,
    /// Rotational gradient, one vector per colour channel.
    pub rot_grad: [Vec3; 3],
    /// Translational gradient, one vector per colour channel.
    pub trans_grad: [Vec3; 3],
    /// Harmonic mean of the hit distances (escaped rays count as infinitely far).
    pub harmonic_distance: f32,
    /// Smallest hit distance over rays at least 10° above the tangent plane.
    pub min_distance: f32,
    /// Rays cast (first pass and refinement).
    pub rays: u32,
}

/// Strata (M in θ, N in φ) for about `n` rays: N ≈ πM as Ward recommends.
pub fn strata(n: u32) -> (u32, u32) {
    let m = ((n as f32 / PI).sqrt().round() as u32).max(1);
    let k = ((n as f32 / m as f32).round() as u32).max(3);
    (m, k)
}

/// Adaptive refinement of a gather ([`allocate`]): extra rays in the strata whose
/// neighbourhood varies, so that the estimated standard error of the irradiance is
/// about `rel_error` times the irradiance, with at most `max_rays` / strata rays per
/// stratum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refine {
    /// Target relative standard error (≤ 0 or ≥ 1: no refinement).
    pub rel_error: f32,
    /// Cap on the rays of one gather if every stratum took its largest share.
    pub max_rays: u32,
}

impl Refine {
    /// No refinement: one ray per stratum.
    pub const OFF: Refine = Refine { rel_error: 0.0, max_rays: 0 };
}

/// Samples per stratum of an M × N gather (`m` rows in θ, `nk` columns in φ) from its
/// first pass `y` (one value per stratum, row-major).
///
/// The variance of a sample in stratum s is estimated by the sample variance of the
/// first-pass values of its four neighbours (θ ± 1, φ ± 1 with φ wrapping); the mean
/// radiance by the mean of the other strata. With E = π/count Σ_s mean_s, stratum s
/// contributes (π/count)² σ_s² / n_s to Var E, so n_s = ⌈σ_s² / (ε² ȳ² count)⌉ makes
/// Var E ≤ ε² E² (as long as no stratum reaches the cap).
///
/// Stratum s's count never depends on its own samples, only on other strata's first
/// pass, so every stratum's mean, and the irradiance, stays unbiased. (Refining where a
/// stratum's own samples look noisy does not: a first sample that missed a small
/// bright source is kept alone while one that hit it is diluted by more samples,
/// which reads low — −0.5 % over the image and −5 % blocks under a bright ceiling
/// patch when that was tried.)
pub fn allocate(y: &[f32], m: usize, nk: usize, refine: Refine) -> Vec<u32> {
    let count = m * nk;
    debug_assert_eq!(y.len(), count);
    let cap = (refine.max_rays as usize / count.max(1)).max(1) as u32;
    if !(refine.rel_error > 0.0 && refine.rel_error < 1.0) || cap == 1 || count < 2 {
        return vec![1; count];
    }
    let total: f64 = y.iter().map(|&v| v as f64).sum();
    let eps2 = (refine.rel_error as f64).powi(2);
    (0..count)
        .map(|s| {
            let (j, k) = (s / nk, s % nk);
            let mut nb = [0f64; 4];
            let mut c = 0;
            let mut push = |v: f32| {
                nb[c] = v as f64;
                c += 1;
            };
            push(y[j * nk + (k + 1) % nk]);
            if nk > 2 {
                push(y[j * nk + (k + nk - 1) % nk]);
            }
            if j > 0 {
                push(y[(j - 1) * nk + k]);
            }
            if j + 1 < m {
                push(y[(j + 1) * nk + k]);
            }
            let mean_nb = nb[..c].iter().sum::<f64>() / c as f64;
            let var = if c > 1 { nb[..c].iter().map(|v| (v - mean_nb).powi(2)).sum::<f64>() / (c - 1) as f64 } else { 0.0 };
            let others = (total - y[s] as f64) / (count - 1) as f64;
            if others <= 0.0 || var <= 0.0 {
                return 1;
            }
            let want = var / (eps2 * others * others * count as f64);
            (want.ceil().min(cap as f64) as u32).max(1)
        })
        .collect()
}

/// Gathers at `it` with about `n` stratified rays (more where `refine` asks) and
/// computes the gradients.
pub fn gather(ctx: &PhotonContext, at: &GatherPoint, n: u32, refine: Refine, stats: &mut TraversalStats) -> HemisphereResult {
    let GatherPoint { world, it, wo, key, .. } = *at;
    let (m, nk) = strata(n);
    let nrm = facing_shading_normal(it, wo);
    let frame = Frame::new(nrm);
    let side = wo.dot(it.sp.ng);
    let count = (m * nk) as usize;
    let mut l = vec![Color::ZERO; count];
    let mut d = vec![f32::INFINITY; count];
    let (mut inv_d, mut min_d) = (0.0f32, f32::INFINITY);
    // Sample `s` (0 = the first pass) of stratum `idx`; `None` below the surface.
    let sample = |idx: usize, s: u32, stats: &mut TraversalStats| -> Option<(Color, f32, f32)> {
        let (j, k) = ((idx / nk as usize) as f32, (idx % nk as usize) as f32);
        let sk = if s == 0 { key } else { key.child(0xADA0_0000_0000 | s as u64) };
        let (u0, u1) = (sk.uniform(2 * idx as u64), sk.uniform(2 * idx as u64 + 1));
        let sin2 = (j + u0) / m as f32;
        let (sin_t, cos_t) = (sin2.sqrt(), (1.0 - sin2).max(0.0).sqrt());
        let phi = 2.0 * PI * (k + u1) / nk as f32;
        let wi = frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t));
        if wi.dot(it.sp.ng) * side <= 0.0 {
            return None;
        }
        let rk = if s == 0 { key.child(idx as u64 + 1) } else { sk.child(idx as u64 + 1) };
        let (li, dist) = ctx.gather_ray(world, world.spawn(it, wi), 0, rk, stats);
        Some((li, dist, cos_t))
    };
    for idx in 0..count {
        // Below the geometric surface: no light (a sample of zero).
        if let Some((li, dist, cos_t)) = sample(idx, 0, stats) {
            l[idx] = li;
            d[idx] = dist;
            if dist.is_finite() {
                inv_d += 1.0 / dist.max(1e-6);
                if cos_t > 0.174 {
                    min_d = min_d.min(dist);
                }
            }
        }
    }
    let first: Vec<f32> = l.iter().map(|&c| crate::math::mean(c)).collect();
    let per = allocate(&first, m as usize, nk as usize, refine);
    let mut rays = 0u32;
    for (idx, &ns) in per.iter().enumerate() {
        rays += ns;
        if ns > 1 {
            let mut sum = l[idx];
            for s in 1..ns {
                if let Some((li, _, _)) = sample(idx, s, stats) {
                    sum += li;
                }
            }
            l[idx] = sum / ns as f32;
        }
    }
    let dir = |phi: f32| frame.to_world(Vec3::new(phi.cos(), phi.sin(), 0.0));
    let mut e = Color::ZERO;
    let mut rot = [Vec3::ZERO; 3];
    let mut trans = [Vec3::ZERO; 3];
    let add = |g: &mut [Vec3; 3], c: Color, v: Vec3| {
        for (ch, gv) in g.iter_mut().enumerate() {
            *gv += v * c[ch];
        }
    };
    for j in 0..m {
        let (jm, mf) = (j as f32, m as f32);
        let cos_minus = (1.0 - jm / mf).sqrt();
        let sin_minus = (jm / mf).sqrt();
        let cos_mid = (1.0 - (jm + 0.5) / mf).sqrt();
        let sin_mid = ((jm + 0.5) / mf).sqrt();
        let cos_plus = (1.0 - (jm + 1.0) / mf).max(0.0).sqrt();
        let tan_mid = sin_mid / cos_mid.max(1e-6);
        for k in 0..nk {
            let idx = (j * nk + k) as usize;
            let phi_mid = 2.0 * PI * (k as f32 + 0.5) / nk as f32;
            let u_k = dir(phi_mid);
            let v_k = dir(phi_mid - 0.5 * PI);
            let v_k_minus = dir(2.0 * PI * k as f32 / nk as f32 + 0.5 * PI);
            e += l[idx];
            add(&mut rot, l[idx] * -tan_mid, v_k);
            if j > 0 {
                let other = ((j - 1) * nk + k) as usize;
                let md = d[idx].min(d[other]);
                if md.is_finite() && md > 0.0 {
                    let f = 2.0 * PI * cos_minus * cos_minus * sin_minus / (nk as f32 * md);
                    add(&mut trans, (l[idx] - l[other]) * f, u_k);
                }
            }
            let prev = (j * nk + if k == 0 { nk - 1 } else { k - 1 }) as usize;
            let md = d[idx].min(d[prev]);
            if md.is_finite() && md > 0.0 {
                let f = cos_mid * (cos_minus - cos_plus) / (md * sin_mid.max(1e-6));
                add(&mut trans, (l[idx] - l[prev]) * f, v_k_minus);
            }
        }
    }
    let scale = PI / count as f32;
    for g in &mut rot {
        *g *= scale;
    }
    HemisphereResult {
        irradiance: e * scale,
        rot_grad: rot,
        trans_grad: trans,
        harmonic_distance: if inv_d > 0.0 { count as f32 / inv_d } else { f32::INFINITY },
        min_distance: min_d,
        rays,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stratified estimate of ∫ f over the unit square (the strata of the gather in
    /// (sin²θ, φ/2π)) with the counts `alloc` gives from the first pass; f is a
    /// small bright disc on a dim background, like a lamp-lit ceiling patch.
    /// Samples per stratum from the first pass (`allocate` or a planted rule).
    type Alloc<'a> = &'a dyn Fn(&[f32], usize, usize) -> Vec<u32>;

    fn estimate(alloc: Alloc, trial: u64) -> (f64, u32) {
        let f = |u: f32, v: f32| if (u - 0.43).powi(2) + (v - 0.61).powi(2) < 0.06f32.powi(2) { 20.0 } else { 0.2 };
        let (m, nk) = strata(256);
        let count = (m * nk) as usize;
        let key = crate::integrator::photon::context::ShadeKey(trial);
        let at = |idx: usize, s: u64| {
            let k = key.child(s);
            let (j, c) = ((idx / nk as usize) as f32, (idx % nk as usize) as f32);
            f((j + k.uniform(2 * idx as u64)) / m as f32, (c + k.uniform(2 * idx as u64 + 1)) / nk as f32)
        };
        let first: Vec<f32> = (0..count).map(|i| at(i, 0)).collect();
        let per = alloc(&first, m as usize, nk as usize);
        let mut e = 0.0f64;
        for (i, &n) in per.iter().enumerate() {
            let sum: f32 = first[i] + (1..n).map(|s| at(i, s as u64)).sum::<f32>();
            e += (sum / n as f32) as f64;
        }
        (e / count as f64, per.iter().sum())
    }

    /// Refinement lowers the noise and keeps the estimate unbiased: the mean of 4000
    /// independent estimates is within 4 standard errors of the exact integral (measured:
    /// relative standard deviation 0.237 → 0.151 for 317 instead of 252 rays; the cap
    /// of 8 rays per stratum binds on this 100:1 disc). The planted control refines by
    /// the stratum's own first sample (|y − neighbour|), which reads low (0.386 against
    /// 0.424 in a numpy simulation): a first sample on the disc is diluted, one that
    /// missed it is kept.
    #[test]
    fn refinement_is_unbiased() {
        let exact = 0.2 + (20.0 - 0.2) * std::f64::consts::PI * 0.06 * 0.06;
        let refine = Refine { rel_error: 0.02, max_rays: 2048 };
        let run = |alloc: Alloc| {
            let n = 4000;
            let v: Vec<(f64, u32)> = (0..n).map(|t| estimate(alloc, t)).collect();
            let mean = v.iter().map(|x| x.0).sum::<f64>() / n as f64;
            let var = v.iter().map(|x| (x.0 - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let rays = v.iter().map(|x| x.1 as f64).sum::<f64>() / n as f64;
            (mean, (var / n as f64).sqrt(), var.sqrt() / exact, rays)
        };
        let (mean1, se1, rel1, rays1) = run(&|_, m, nk| vec![1; m * nk]);
        let (mean, se, rel, rays) = run(&|y, m, nk| allocate(y, m, nk, refine));
        eprintln!(
            "exact {exact:.5}; one ray per stratum {mean1:.5} ± {se1:.5} (rel sd {rel1:.4}); refined {mean:.5} ± {se:.5} (rel sd {rel:.4}, {rays:.0} rays)"
        );
        assert!((mean1 - exact).abs() < 4.0 * se1);
        assert!((mean - exact).abs() < 4.0 * se, "refined estimate biased: {mean} vs {exact} (se {se})");
        assert!(rel < 0.8 * rel1 && rays < 2.0 * rays1, "refinement did not lower the noise: {rel} vs {rel1}");
        // Control: the count from the stratum's own sample (its difference to a neighbour).
        let own = |y: &[f32], m: usize, nk: usize| -> Vec<u32> {
            (0..m * nk).map(|s| if (y[s] - y[(s / nk) * nk + (s % nk + 1) % nk]).abs() > 1.0 { 8 } else { 1 }).collect()
        };
        let (mean_c, se_c, _, _) = run(&own);
        assert!(mean_c < exact - 4.0 * se_c, "the control should read low: {mean_c} vs {exact} (se {se_c})");
    }

    /// The gradients point the way the gathered irradiance changes: on the Cornell
    /// box's floor, at the points of a grid where the gradients are steepest (away
    /// from walls and blocks), the first-order change they predict for a step of the
    /// position (±10 mm along the
    /// translational gradient and across it) and a tilt of the normal (±3° about the
    /// rotational gradient's axis and across it) agrees with the central finite
    /// difference of gathers at the displaced points (same sign, within a factor 2) —
    /// same photon map and the same random numbers at every point, so the difference is
    /// smooth. A gradient with its sign flipped predicts the opposite change and fails.
    /// Measured at (375, 0, 125): translation 0.00271 against 0.00285 predicted, tilt
    /// 0.00323 against 0.00328 (E = 0.104).
    #[test]
    fn gradients_match_finite_differences() {
        use crate::integrator::photon::context::ShadeKey;
        use crate::material::ShadingPoint;
        use crate::world::Interaction;
        let scene = crate::scene::builtin::builtin("cornell").unwrap();
        let accel = crate::registry::make_accel("bvh", &scene.triangles).unwrap();
        let world = crate::world::World::new(scene, accel).unwrap();
        let cfg = crate::config::RenderConfig { integrator: "photon".into(), seed: 7, ..Default::default() }
            .with("gather", "final_gather")
            .with("photons", 200_000)
            .with("caustic_photons", 0);
        let r = crate::param::Reader::new(&cfg.params);
        let mut pi = crate::integrator::photon::PhotonIntegrator::new(&cfg, &r, crate::registry::make_rr(&cfg.rr).unwrap(), true).unwrap();
        crate::integrator::Integrator::preprocess(&mut pi, &world).unwrap();
        let ctx = pi.context().unwrap();
        let wo = Vec3::Y;
        let key = ShadeKey(0x6EAD);
        let gather_at = |at: &Interaction, n: u32| {
            let bsdf = &*world.bsdf_at(at);
            let mut st = TraversalStats::default();
            gather(ctx, &GatherPoint { world: &world, it: at, wo, bsdf, key, pixel: None }, n, Refine::OFF, &mut st)
        };
        let mean = |g: &[Vec3; 3]| (g[0] + g[1] + g[2]) / 3.0;
        let e_of = |at: &Interaction| crate::math::mean(gather_at(at, 4096).irradiance) as f64;
        // Floor points of a grid (the box is 0–555 mm wide and deep).
        let mut floor = Vec::new();
        for x in (25..=525).step_by(50) {
            // The box is open at z = 0 (towards the camera): stay 100 mm inside.
            for z in (125..=525).step_by(50) {
                // From just under the ceiling: points under the blocks are not floor hits.
                let down = crate::geometry::Ray::new(Vec3::new(x as f32, 540.0, z as f32), -Vec3::Y);
                if let Some(it) = world.intersect(&down, &mut TraversalStats::default())
                    && it.p.y.abs() < 1.0
                    && it.sp.ng.y > 0.99
                {
                    floor.push((it, gather_at(&it, 1024)));
                }
            }
        }
        assert!(floor.len() > 40, "{} floor points", floor.len());
        // Relative gradients are steepest where E is small: only points at least half
        // as bright as the median compete.
        let mut es: Vec<f32> = floor.iter().map(|f| crate::math::mean(f.1.irradiance)).collect();
        es.sort_by(f32::total_cmp);
        let floor_e = 0.5 * es[es.len() / 2];
        let steepest = |g: &dyn Fn(&HemisphereResult) -> Vec3| {
            let rel = |h: &HemisphereResult| g(h).length() / crate::math::mean(h.irradiance).max(1e-9);
            // Away from walls and blocks (no ray above 10° hits anything within 80 mm), where
            // E is smooth over the steps: at a contact a step crosses the shadow's edge.
            let lit = floor.iter().filter(|f| crate::math::mean(f.1.irradiance) >= floor_e && f.1.min_distance > 80.0);
            lit.max_by(|a, b| rel(&a.1).total_cmp(&rel(&b.1))).map(|(it, _)| *it).unwrap()
        };
        // Along the gradient the prediction has the finite difference's sign and is within
        // a factor 2 of it (Ward & Heckbert's estimates are first-order and approximate).
        // Across the gradient the prediction is 0 (translation) or small: there the change
        // must be at most half the change along it (the gradient points the right way).
        let mut along_fd = 0.0f64;
        let mut agree = |name: &str, pred: f64, fd: f64, e0: f64| {
            if name == "along" || name == "about" {
                along_fd = fd;
                pred / fd >= 0.5 && pred / fd <= 2.0
            } else {
                fd.abs() <= 0.5 * along_fd.abs() + 0.003 * e0 && pred.abs() <= 0.5 * along_fd.abs() + 0.003 * e0
            }
        };
        // Translation: E(p ± δ·d) along the gradient and across it.
        let delta = 10.0f32;
        let it = steepest(&|h| mean(&h.trans_grad) * Vec3::new(1.0, 0.0, 1.0));
        let base = gather_at(&it, 4096);
        let e0 = crate::math::mean(base.irradiance) as f64;
        let along = (mean(&base.trans_grad) * Vec3::new(1.0, 0.0, 1.0)).normalize();
        for (name, d) in [("along", along), ("across", Vec3::Y.cross(along))] {
            let at = |s: f32| e_of(&Interaction { p: it.p + d * (s * delta), ..it });
            let fd = (at(1.0) - at(-1.0)) / 2.0;
            let pred = (mean(&base.trans_grad).dot(d) * delta) as f64;
            eprintln!("translation at {} {name} the gradient: finite difference {fd:.6}, gradient {pred:.6} (E {e0:.5})", it.p);
            if name == "along" {
                assert!(fd.abs() > 0.005 * e0, "the steepest point has too small a gradient: {fd} of {e0}");
            }
            assert!(agree(name, pred, fd, e0), "translational gradient {name}: {pred} against {fd}");
        }
        // Rotation: E with the normal tilted by ±θ about the gradient's axis and across it.
        let theta = 3f32.to_radians();
        let it = steepest(&|h| mean(&h.rot_grad) * Vec3::new(1.0, 0.0, 1.0));
        let base = gather_at(&it, 4096);
        let e0 = crate::math::mean(base.irradiance) as f64;
        let n = facing_shading_normal(&it, wo);
        let axis = (mean(&base.rot_grad) * Vec3::new(1.0, 0.0, 1.0)).normalize();
        for (name, a) in [("about", axis), ("across", n.cross(axis))] {
            // Tilting towards w = a × n turns the normal about a: n × n' = sin θ · a.
            let w = a.cross(n);
            let tilted = |s: f32| n * theta.cos() + w * (s * theta.sin());
            let at = |s: f32| e_of(&Interaction { sp: ShadingPoint::new(it.sp.ng, tilted(s)), ..it });
            let fd = (at(1.0) - at(-1.0)) / 2.0;
            let pred = (mean(&base.rot_grad).dot(n.cross(tilted(1.0)))) as f64;
            eprintln!("tilt at {} {name} the gradient's axis: finite difference {fd:.6}, gradient {pred:.6} (E {e0:.5})", it.p);
            if name == "about" {
                assert!(fd.abs() > 0.005 * e0, "the steepest point has too small a rotational gradient: {fd} of {e0}");
            }
            assert!(agree(name, pred, fd, e0), "rotational gradient {name}: {pred} against {fd}");
        }
    }

    #[test]
    fn strata_follow_ward() {
        assert_eq!(strata(64), (5, 13));
        assert_eq!(strata(1), (1, 3));
        let (m, n) = strata(256);
        assert!((m * n) as i32 - 256 < 12 && n >= 3 * m);
    }
}

//! `vcm_select = "efficiency"`: the technique set of `vcm` chosen per scene from a pilot.
//!
//! On a scene that path tracing handles well (a diffuse box lit by an area light seen
//! from its surfaces), the bidirectional pass spends two to three path samples' worth of
//! work on light subpaths, connections and merges that lower the variance only a little;
//! where light arrives through a gap or a caustic, they are what finds it. Grittmann,
//! Yazici, Georgiev & Slusallek ("Efficiency-aware multiple importance sampling for
//! bidirectional rendering algorithms", SIGGRAPH 2022) choose the sample counts of
//! the techniques per scene from the variance and cost they measure in the first
//! iterations, "no light subpaths" among the choices. This module does the same between
//! two candidates: the configured bidirectional pass, and unidirectional path tracing
//! (`path`'s estimator, emitter hits and light sampling under MIS, one sample per pixel
//! per pass). Each runs [`PILOT_PASSES`] passes; the relative variance of one pass,
//! V = mean over pixels and channels of s²/(m² + ε) (s² the per-pixel variance of a
//! pass, m the mean of all pilot passes of both, ε = relMSE's 10⁻²), times the work of
//! one pass gives each candidate's cost of reaching a given relMSE; the lower one
//! renders the image. The bidirectional pass's s² is the sample variance of its pilot
//! passes. Path tracing's is the larger of its own passes' sample variance, which misses
//! light it rarely finds, and an estimate from the bidirectional samples, which see that
//! light: under the balance heuristic a contribution C of any technique is f/Σₜpₜ, so
//! Σ C²/(w₀ + w₁) — w₀ + w₁ the weights' share of the emitter hit and light sampling,
//! path tracing's two techniques ([`super::mis::uni_share`]) — estimates path tracing's
//! second moment ∫ f²/(p₀ + p₁); less m², as it leaves out the (positive) covariances
//! between path lengths. The cost is counted, not timed, so the choice — and the
//! image — is the same on every run and for any thread count: rays traced (closest hit
//! and shadow), a bidirectional pass's weighted by [`BIDIR_RAY_COST`].
//!
//! The chosen candidate's pilot passes are the image's first passes (its passes 0 … P−1
//! computed ahead, bit-identical to those the pass loop would compute), the other's are
//! only cost. Using the same passes for the choice and the image biases the result only
//! through the choice itself, which is a fixed function of the scene and the seed.

use glam::DVec3;

/// ε of the relative variance: relMSE's (`experiment::cell::REL_EPS`; not imported, as
/// the experiment runner depends on the integrators; a test keeps the two equal).
const REL_EPS: f64 = 1e-2;

/// Pilot passes of each candidate.
pub const PILOT_PASSES: u32 = 2;

/// CPU time per ray of a bidirectional pass relative to a path-tracing pass's: the light
/// vertices, connections' BSDF evaluations, merges and light-tracing splats that come with
/// its rays: on `cornell`, `cornell-glass` and `door-ajar` at 64² (32 passes against 32
/// samples, 2 threads) 1.5–2.3, of which this is the middle (docs/bidirectional.md,
/// "Choosing the technique set per scene").
pub const BIDIR_RAY_COST: f64 = 1.8;

/// What the pilot measured of one candidate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Candidate {
    /// Relative variance of one pass (see the module documentation).
    pub rel_var: f64,
    /// Rays (closest hit and shadow) per pass.
    pub rays_per_pass: f64,
    /// Work per pass in path-tracing ray units.
    pub cost: f64,
}

impl Candidate {
    /// Relative variance × work: the cost of reaching a given relMSE, up to a constant.
    pub fn inefficiency(&self) -> f64 {
        self.rel_var * self.cost
    }
}

/// The pilot's estimates and choice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pilot {
    /// The bidirectional pass.
    pub bidir: Candidate,
    /// Path tracing.
    pub path: Candidate,
    /// Path tracing's relative variance from its own pilot passes alone.
    pub path_own_rel_var: f64,
}

impl Pilot {
    /// Estimates from each candidate's pilot passes (per-pixel pass estimates), rays, and
    /// the bidirectional passes' moments ([`super::pass::PassOut::moments`]).
    pub fn new(bidir: &[Vec<DVec3>], moments: &[Vec<(DVec3, DVec3)>], bidir_rays: u64, path: &[Vec<DVec3>], path_rays: u64) -> Self {
        let mean = pooled_mean(bidir, path);
        let n = mean.len();
        // Path tracing's variance per pixel: the larger of its own passes' and the one
        // from the bidirectional samples — its second moment without the terms between
        // contributions, less the squared mean.
        let mut vp = 0.0;
        for (p, m) in mean.iter().enumerate() {
            let m1 = moments.iter().map(|pass| pass[p].1).sum::<DVec3>() / moments.len().max(1) as f64;
            let model = (m1 - *m * *m).max(DVec3::ZERO);
            vp += (sample_variance(path, p).max(model) / (*m * *m + DVec3::splat(REL_EPS))).element_sum() / 3.0;
        }
        let cand = |k: usize, rel_var: f64, rays: u64, weight: f64| {
            let per = rays as f64 / k.max(1) as f64;
            Candidate { rel_var, rays_per_pass: per, cost: per * weight }
        };
        Pilot {
            bidir: cand(bidir.len(), rel_variance(bidir, &mean), bidir_rays, BIDIR_RAY_COST),
            path: cand(path.len(), vp / n.max(1) as f64, path_rays, 1.0),
            path_own_rel_var: rel_variance(path, &mean),
        }
    }

    /// Whether path tracing reaches a given error at less cost (ties: bidirectional).
    pub fn prefers_path(&self) -> bool {
        self.path.inefficiency() < self.bidir.inefficiency()
    }

    /// How many times more efficient the chosen candidate is estimated to be.
    pub fn advantage(&self) -> f64 {
        let (b, p) = (self.bidir.inefficiency(), self.path.inefficiency());
        if self.prefers_path() { b / p.max(f64::MIN_POSITIVE) } else { p / b.max(f64::MIN_POSITIVE) }
    }
}

/// Per-pixel mean of all passes of both candidates.
fn pooled_mean(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> Vec<DVec3> {
    let n = a.first().or(b.first()).map_or(0, Vec::len);
    let count = (a.len() + b.len()).max(1) as f64;
    (0..n).map(|p| a.iter().chain(b).map(|pass| pass[p]).sum::<DVec3>() / count).collect()
}

/// Sample variance of pixel `p` over the passes (0 with fewer than 2).
fn sample_variance(passes: &[Vec<DVec3>], p: usize) -> DVec3 {
    let k = passes.len();
    if k < 2 {
        return DVec3::ZERO;
    }
    let own = passes.iter().map(|pass| pass[p]).sum::<DVec3>() / k as f64;
    passes.iter().map(|pass| (pass[p] - own) * (pass[p] - own)).sum::<DVec3>() / (k - 1) as f64
}

/// Mean over pixels and channels of the passes' sample variance relative to `mean`²
/// + ε: the expected relMSE of one pass, apart from bias. 0 with fewer than 2 passes.
pub fn rel_variance(passes: &[Vec<DVec3>], mean: &[DVec3]) -> f64 {
    if mean.is_empty() {
        return 0.0;
    }
    let total: f64 =
        mean.iter().enumerate().map(|(p, m)| (sample_variance(passes, p) / (*m * *m + DVec3::splat(REL_EPS))).element_sum() / 3.0).sum();
    total / mean.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::hash_words;

    /// `k` passes of `n` pixels: value 1 plus uniform noise of half-width `a` (variance a²/3).
    fn passes(k: usize, n: usize, a: f64, seed: u64) -> Vec<Vec<DVec3>> {
        (0..k)
            .map(|i| {
                (0..n)
                    .map(|p| {
                        let u = (hash_words(&[seed, i as u64, p as u64]) >> 11) as f64 / (1u64 << 53) as f64;
                        DVec3::splat(1.0 + a * (2.0 * u - 1.0))
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn epsilon_is_relmses() {
        assert_eq!(REL_EPS, crate::experiment::cell::REL_EPS);
    }

    #[test]
    fn relative_variance_matches_the_noise() {
        let x = passes(4, 20_000, 0.3, 1);
        let v = rel_variance(&x, &vec![DVec3::ONE; 20_000]);
        let want = 0.09 / 3.0 / (1.0 + REL_EPS);
        assert!((v / want - 1.0).abs() < 0.03, "{v} vs {want}");
        assert_eq!(rel_variance(&x[..1], &vec![DVec3::ONE; 20_000]), 0.0);
    }

    #[test]
    fn chooses_the_cheaper_way_to_an_error() {
        // Bidirectional: a quarter of the variance at 1.5× the rays (× BIDIR_RAY_COST = 2.7× the work): wins.
        let (b, p) = (passes(4, 4096, 0.1, 2), passes(4, 4096, 0.2, 3));
        let none = vec![vec![(DVec3::ONE, DVec3::ZERO); 4096]; 4];
        let pilot = Pilot::new(&b, &none, 6000, &p, 4000);
        assert!(!pilot.prefers_path(), "{pilot:?}");
        assert!((pilot.advantage() - 4.0 / 2.7).abs() < 0.15, "{pilot:?}");
        // Half the variance at the same cost ratio: path tracing wins.
        let p2 = passes(4, 4096, 0.1 * 2f64.sqrt(), 4);
        let pilot = Pilot::new(&b, &none, 6000, &p2, 4000);
        assert!(pilot.prefers_path(), "{pilot:?}");
        assert!((pilot.advantage() - 2.7 / 2.0).abs() < 0.15, "{pilot:?}");
        // The same, but the bidirectional samples put path tracing's second moment at
        // 1.04 (mean 1: variance about 0.04 — the pooled mean's own noise moves it —,
        // six times what its own pilot saw: light it rarely finds): bidirectional, by
        // about 0.04 / (0.01/3 · 2.7) ≈ 4.4.
        let heavy = vec![vec![(DVec3::ONE, DVec3::splat(1.04)); 4096]; 4];
        let pilot = Pilot::new(&b, &heavy, 6000, &p2, 4000);
        assert!(!pilot.prefers_path(), "{pilot:?}");
        assert!(pilot.advantage() > 3.0 && pilot.advantage() < 6.5, "{pilot:?}");
    }
}

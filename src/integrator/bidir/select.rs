//! `vcm_select = "efficiency"`: the technique set of `vcm` chosen per scene from a pilot.
//!
//! On a scene that path tracing handles well (a diffuse box lit by an area light seen
//! from its surfaces), the bidirectional pass spends two to three path samples' worth of
//! work on light subpaths, connections and merges that lower the variance only a little;
//! where light arrives as a caustic, merging photons at the first diffuse vertex (`sppm`)
//! is cheaper; where it arrives through a gap, the light subpaths are what find it.
//! Grittmann, Yazici, Georgiev & Slusallek ("Efficiency-aware multiple importance
//! sampling for bidirectional rendering algorithms", SIGGRAPH 2022) choose the sample
//! counts of the techniques per scene from the variance and cost they measure in the
//! first iterations. This module chooses between three candidates: the configured
//! bidirectional pass, unidirectional path tracing (`path`'s estimator, emitter hits and
//! light sampling under MIS, one sample per pixel per pass) and `sppm`. Each runs
//! [`PILOT_PASSES`] passes; for each the pilot predicts relMSE × work at the run's pass
//! count (the horizon), and the lowest renders the image.
//!
//! Relative variances are V = mean over pixels and channels of s²/(m² + ε) (s² a
//! pixel's variance of one pass, ε = relMSE's 10⁻²); m² is estimated from the unbiased
//! pilot passes of both the bidirectional pass and path tracing as their squared mean less
//! its variance ([`squared_mean`]), so a spike does not hide its own variance. The
//! bidirectional pass's variance is that of its passes, its merges' part (recorded apart)
//! growing as the merging radius shrinks ([`sppm_error`]). Path tracing's is the larger of
//! its own passes' sample variance, which misses light it rarely finds, and an estimate
//! from the bidirectional samples, which see that light: under the balance heuristic a
//! contribution C of any technique is f/Σₜpₜ, so Σ C²/(w₀ + w₁) — w₀ + w₁ the weights'
//! share of the emitter hit and light sampling, path tracing's two techniques
//! ([`super::mis::uni_share`]) — estimates path tracing's second moment ∫ f²/(p₀ + p₁);
//! less m², as it leaves out the (positive) covariances between path lengths. `sppm`'s is
//! its direct light's variance plus its gathered flux's, which grows as 1/r², plus its
//! squared bias, measured against the bidirectional passes and shrinking as r²
//! ([`sppm_error`]). The work is counted, not timed, so the choice — and the image — is
//! the same on every run and for any thread count: rays traced (closest hit and shadow),
//! a bidirectional pass's weighted by [`BIDIR_RAY_COST`], an `sppm` pass's by
//! [`SPPM_RAY_COST`].
//!
//! The chosen candidate's pilot passes are the image's first passes (its passes 0 … P−1
//! computed ahead, bit-identical to those the pass loop would compute), the others' are
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

/// CPU time per ray of an `sppm` pass relative to a path-tracing pass's (its photon
/// deposits, grid build and gathers): 1.4–2.2 on `cornell`, `cornell-glass` and
/// `door-ajar` at 64² (128 passes against 128 samples, 2 threads), of which this is
/// the middle.
pub const SPPM_RAY_COST: f64 = 1.75;

/// Passes over which the errors are predicted when the run has no pass limit (a time
/// limit only).
pub const HORIZON: u32 = 256;

/// The candidates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    /// The configured bidirectional pass.
    Bidir,
    /// Path tracing.
    Path,
    /// Stochastic progressive photon mapping.
    Sppm,
}

/// What the pilot passes gave: per pass, per pixel estimates.
pub struct PilotInput<'p> {
    /// The bidirectional passes' estimates …
    pub bidir: &'p [Vec<DVec3>],
    /// … their merges' part ([`super::pass::PassOut::merged`]) …
    pub bidir_merged: &'p [Vec<DVec3>],
    /// … and moments ([`super::pass::PassOut::moments`]).
    pub moments: &'p [Vec<(DVec3, DVec3)>],
    /// Rays of the bidirectional pilot passes.
    pub bidir_rays: u64,
    /// α of the bidirectional pass's merging radius.
    pub bidir_alpha: f64,
    /// Path tracing's estimates and rays.
    pub path: &'p [Vec<DVec3>],
    /// Rays of the path-tracing pilot passes.
    pub path_rays: u64,
    /// `sppm`'s, if it is a candidate.
    pub sppm: Option<SppmPilot<'p>>,
    /// Passes the run will render (the errors are predicted there).
    pub horizon: u32,
}

/// What the `sppm` candidate's pilot gave.
pub struct SppmPilot<'p> {
    /// Each pass's emitted and direct light (`progressive::sppm_phases::pass_estimates`) …
    pub direct: &'p [Vec<DVec3>],
    /// … and gathered flux.
    pub flux: &'p [Vec<DVec3>],
    /// Rays of the pilot passes.
    pub rays: u64,
    /// Its radius-reduction parameter α.
    pub alpha: f64,
}

/// What the pilot measured of one candidate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Candidate {
    /// Relative variance of one pilot pass (see the module documentation).
    pub rel_var: f64,
    /// Predicted relMSE at the horizon × the horizon: `rel_var` where the variance of a
    /// pass stays as in the pilot and there is no bias; more where merging radii shrink
    /// or a bias remains.
    pub rel_mse_passes: f64,
    /// Rays (closest hit and shadow) per pass.
    pub rays_per_pass: f64,
    /// Work per pass in path-tracing ray units.
    pub cost: f64,
}

impl Candidate {
    /// Predicted relMSE × work at the horizon: the cost of reaching a given relMSE, up to a
    /// constant.
    pub fn inefficiency(&self) -> f64 {
        self.rel_mse_passes * self.cost
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
    /// `sppm`, if it was a candidate.
    pub sppm: Option<Candidate>,
    /// `sppm`'s relative squared bias in its pilot passes' mean (0 if not a candidate).
    pub sppm_rel_bias2: f64,
}

impl Pilot {
    /// Estimates from each candidate's pilot passes (per-pixel pass estimates) and rays.
    pub fn new(i: &PilotInput) -> Self {
        let (bidir, path) = (i.bidir, i.path);
        // Each pixel's m² + ε, m² estimated without the pilot's noise (spikes otherwise
        // inflate m² and hide their own variance).
        let m2 = squared_mean(bidir, path);
        let scale: Vec<DVec3> = m2.iter().map(|m2| *m2 + DVec3::splat(REL_EPS)).collect();
        let n = scale.len();
        // Path tracing's variance per pixel: the larger of its own passes' and the one
        // from the bidirectional samples — its second moment without the terms between
        // contributions, less the squared mean.
        let mut vp = 0.0;
        for (p, m2) in m2.iter().enumerate() {
            let m1 = i.moments.iter().map(|pass| pass[p].1).sum::<DVec3>() / i.moments.len().max(1) as f64;
            let model = (m1 - *m2).max(DVec3::ZERO);
            vp += (sample_variance(path, p).max(model) / scale[p]).element_sum() / 3.0;
        }
        let vp = vp / n.max(1) as f64;
        let cand = |k: usize, rel_var: f64, rel_mse_passes: f64, rays: u64, weight: f64| {
            let per = rays as f64 / k.max(1) as f64;
            Candidate { rel_var, rel_mse_passes, rays_per_pass: per, cost: per * weight }
        };
        // Merges' variance grows as the radius shrinks; the rest's stays.
        let k = bidir.len() as u32;
        let unmerged: Vec<Vec<DVec3>> =
            bidir.iter().zip(i.bidir_merged).map(|(b, m)| b.iter().zip(m).map(|(b, m)| *b - *m).collect()).collect();
        let growth = |alpha| sppm_error(alpha, k, i.horizon).0 * i.horizon.max(1) as f64;
        let b_passes = if i.bidir_merged.len() == bidir.len() {
            rel_variance(&unmerged, &scale) + rel_variance(i.bidir_merged, &scale) * growth(i.bidir_alpha)
        } else {
            rel_variance(bidir, &scale)
        };
        let (mut sppm, mut sppm_rel_bias2) = (None, 0.0);
        if let Some(s) = &i.sppm {
            let total: Vec<Vec<DVec3>> =
                s.direct.iter().zip(s.flux).map(|(d, f)| d.iter().zip(f).map(|(d, f)| *d + *f).collect()).collect();
            // The bias against the bidirectional passes (whose variance estimate sees
            // caustics and light through gaps, where path tracing's pilot may not).
            sppm_rel_bias2 = rel_bias2(&total, bidir, &scale);
            let (_, b) = sppm_error(s.alpha, s.direct.len() as u32, i.horizon);
            let passes = rel_variance(s.direct, &scale)
                + rel_variance(s.flux, &scale) * growth(s.alpha)
                + sppm_rel_bias2 * b * b * i.horizon.max(1) as f64;
            sppm = Some(cand(total.len(), rel_variance(&total, &scale), passes, s.rays, SPPM_RAY_COST));
        }
        Pilot {
            bidir: cand(bidir.len(), rel_variance(bidir, &scale), b_passes, i.bidir_rays, BIDIR_RAY_COST),
            path: cand(path.len(), vp, vp, i.path_rays, 1.0),
            path_own_rel_var: rel_variance(path, &scale),
            sppm,
            sppm_rel_bias2,
        }
    }

    /// Each candidate's predicted relMSE × work.
    fn inefficiencies(&self) -> [(Choice, f64); 3] {
        let s = self.sppm.map_or(f64::INFINITY, |m| m.inefficiency());
        [(Choice::Bidir, self.bidir.inefficiency()), (Choice::Path, self.path.inefficiency()), (Choice::Sppm, s)]
    }

    /// The candidate that reaches a given error at the least work (ties: the first of
    /// bidirectional, path tracing, `sppm`).
    pub fn choice(&self) -> Choice {
        let all = self.inefficiencies();
        all.iter().fold(all[0], |best, c| if c.1 < best.1 { *c } else { best }).0
    }

    /// Whether path tracing is chosen.
    pub fn prefers_path(&self) -> bool {
        self.choice() == Choice::Path
    }

    /// How many times more efficient the chosen candidate is estimated to be than the
    /// next best.
    pub fn advantage(&self) -> f64 {
        let all = self.inefficiencies();
        let best = self.choice();
        let chosen = all.iter().find(|c| c.0 == best).map_or(1.0, |c| c.1);
        let next = all.iter().filter(|c| c.0 != best).map(|c| c.1).fold(f64::INFINITY, f64::min);
        next / chosen.max(f64::MIN_POSITIVE)
    }
}

/// A progressive merging estimator's error after `n` passes relative to its pilot of
/// `k` passes, by Knaus & Zwicker's model of the radius (r²ᵢ₊₁ = r²ᵢ (i + α)/(i + 1)):
/// pass i's variance grows as 1/r²ᵢ and its bias shrinks as r²ᵢ, and the image is the
/// mean of the passes. Returns (a, b): the variance of the n-pass image over the
/// pilot's mean variance of one pass, Σᵢ≤ₙ r⁻²ᵢ / n² ÷ mean_{i≤k} r⁻²ᵢ, and its bias over
/// the pilot mean's bias, Σᵢ≤ₙ r²ᵢ / n ÷ mean_{i≤k} r²ᵢ. (`vcm`'s radius rᵢ = r₀ i^((α−1)/2)
/// is this schedule's limit.)
pub fn sppm_error(alpha: f64, k: u32, n: u32) -> (f64, f64) {
    let (mut r2, mut sum_inv, mut sum_r2) = (1.0f64, 0.0, 0.0);
    let (mut pilot_inv, mut pilot_r2) = (0.0, 0.0);
    for i in 1..=n.max(k).max(1) {
        if i <= n {
            sum_inv += 1.0 / r2;
            sum_r2 += r2;
        }
        if i <= k {
            pilot_inv += 1.0 / r2;
            pilot_r2 += r2;
        }
        r2 = crate::integrator::progressive::next_radius2(r2, i, alpha);
    }
    let (n, k) = (n.max(1) as f64, k.max(1) as f64);
    (sum_inv / (n * n) / (pilot_inv / k), (sum_r2 / n) / (pilot_r2 / k))
}

/// Relative squared bias of the mean of the passes `biased` against the mean of the
/// unbiased passes `unbiased`: per pixel the squared difference of the means less the
/// variances of both means (which it also holds), over `scale` (m² + ε), averaged over
/// pixels and channels; at least 0.
fn rel_bias2(biased: &[Vec<DVec3>], unbiased: &[Vec<DVec3>], scale: &[DVec3]) -> f64 {
    let (ks, ku) = (biased.len(), unbiased.len());
    if scale.is_empty() || ks == 0 || ku == 0 {
        return 0.0;
    }
    let total: f64 = scale
        .iter()
        .enumerate()
        .map(|(p, sc)| {
            let ms = biased.iter().map(|pass| pass[p]).sum::<DVec3>() / ks as f64;
            let mu = unbiased.iter().map(|pass| pass[p]).sum::<DVec3>() / ku as f64;
            let var = sample_variance(biased, p) / ks as f64 + sample_variance(unbiased, p) / ku as f64;
            let d = ms - mu;
            ((d * d - var) / *sc).element_sum() / 3.0
        })
        .sum();
    (total / scale.len() as f64).max(0.0)
}

/// Per pixel, an unbiased estimate of the squared mean m² from the passes of both
/// candidates: the squared pooled mean less its variance (the passes' sample variances
/// over their count), at least 0.
fn squared_mean(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> Vec<DVec3> {
    let n = a.first().or(b.first()).map_or(0, Vec::len);
    let k = (a.len() + b.len()).max(1) as f64;
    (0..n)
        .map(|p| {
            let m = a.iter().chain(b).map(|pass| pass[p]).sum::<DVec3>() / k;
            let var = (sample_variance(a, p) * a.len() as f64 + sample_variance(b, p) * b.len() as f64) / (k * k);
            (m * m - var).max(DVec3::ZERO)
        })
        .collect()
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

/// Mean over pixels and channels of the passes' sample variance over `scale` (m² + ε):
/// the expected relMSE of one pass, apart from bias. 0 with fewer than 2 passes.
pub fn rel_variance(passes: &[Vec<DVec3>], scale: &[DVec3]) -> f64 {
    if scale.is_empty() {
        return 0.0;
    }
    let total: f64 = scale.iter().enumerate().map(|(p, sc)| (sample_variance(passes, p) / *sc).element_sum() / 3.0).sum();
    total / scale.len() as f64
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

    /// The pilot of a bidirectional pass without merges and path tracing.
    fn two_way(b: &[Vec<DVec3>], moments: &[Vec<(DVec3, DVec3)>], b_rays: u64, p: &[Vec<DVec3>], p_rays: u64) -> Pilot {
        let merged = vec![vec![DVec3::ZERO; b[0].len()]; b.len()];
        Pilot::new(&PilotInput {
            bidir: b,
            bidir_merged: &merged,
            moments,
            bidir_rays: b_rays,
            bidir_alpha: 0.75,
            path: p,
            path_rays: p_rays,
            sppm: None,
            horizon: 64,
        })
    }

    #[test]
    fn epsilon_is_relmses() {
        assert_eq!(REL_EPS, crate::experiment::cell::REL_EPS);
    }

    #[test]
    fn relative_variance_matches_the_noise() {
        let x = passes(4, 20_000, 0.3, 1);
        let v = rel_variance(&x, &vec![DVec3::splat(1.0 + REL_EPS); 20_000]);
        let want = 0.09 / 3.0 / (1.0 + REL_EPS);
        assert!((v / want - 1.0).abs() < 0.03, "{v} vs {want}");
        assert_eq!(rel_variance(&x[..1], &vec![DVec3::splat(1.0 + REL_EPS); 20_000]), 0.0);
    }

    #[test]
    fn chooses_the_cheaper_way_to_an_error() {
        // Bidirectional: a quarter of the variance at 1.5× the rays (× BIDIR_RAY_COST = 2.7× the work): wins.
        let (b, p) = (passes(4, 4096, 0.1, 2), passes(4, 4096, 0.2, 3));
        let none = vec![vec![(DVec3::ONE, DVec3::ZERO); 4096]; 4];
        let pilot = two_way(&b, &none, 6000, &p, 4000);
        assert!(!pilot.prefers_path(), "{pilot:?}");
        assert!((pilot.advantage() - 4.0 / 2.7).abs() < 0.15, "{pilot:?}");
        // Half the variance at the same cost ratio: path tracing wins.
        let p2 = passes(4, 4096, 0.1 * 2f64.sqrt(), 4);
        let pilot = two_way(&b, &none, 6000, &p2, 4000);
        assert!(pilot.prefers_path(), "{pilot:?}");
        assert!((pilot.advantage() - 2.7 / 2.0).abs() < 0.15, "{pilot:?}");
        // The same, but the bidirectional samples put path tracing's second moment at
        // 1.04 (mean 1: variance about 0.04 — the pooled mean's own noise moves it —,
        // six times what its own pilot saw: light it rarely finds): bidirectional, by
        // about 0.04 / (0.01/3 · 2.7) ≈ 4.4.
        let heavy = vec![vec![(DVec3::ONE, DVec3::splat(1.04)); 4096]; 4];
        let pilot = two_way(&b, &heavy, 6000, &p2, 4000);
        assert!(!pilot.prefers_path(), "{pilot:?}");
        assert!(pilot.advantage() > 3.0 && pilot.advantage() < 6.5, "{pilot:?}");
    }

    /// `passes` with a constant `b` added to every value.
    fn shifted(p: &[Vec<DVec3>], b: f64) -> Vec<Vec<DVec3>> {
        p.iter().map(|pass| pass.iter().map(|v| *v + DVec3::splat(b)).collect()).collect()
    }

    #[test]
    fn squared_mean_leaves_out_the_noise() {
        // Mean 1, variance 0.75 (a = 1.5): the pooled mean of 4 passes squared is
        // 1 + 0.75/4 on average; the estimate is 1.
        let (a, b) = (passes(2, 20_000, 1.5, 5), passes(2, 20_000, 1.5, 6));
        let m2 = squared_mean(&a, &b);
        let avg = m2.iter().map(|m| m.x).sum::<f64>() / m2.len() as f64;
        assert!((avg - 1.0).abs() < 0.03, "{avg}");
        let naive = pooled(&a, &b).iter().map(|m| m.x * m.x).sum::<f64>() / m2.len() as f64;
        assert!((naive - 1.1875).abs() < 0.03, "{naive}");
    }

    fn pooled(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> Vec<DVec3> {
        (0..a[0].len()).map(|p| a.iter().chain(b).map(|pass| pass[p]).sum::<DVec3>() / (a.len() + b.len()) as f64).collect()
    }

    #[test]
    fn bias_is_measured_and_noise_is_not_bias() {
        let scale = vec![DVec3::splat(1.0 + REL_EPS); 20_000];
        let (u, s) = (passes(2, 20_000, 0.3, 7), passes(2, 20_000, 0.3, 8));
        // Unbiased against unbiased: about 0, though both are noisy.
        assert!(rel_bias2(&s, &u, &scale) < 2e-3, "{}", rel_bias2(&s, &u, &scale));
        // A planted bias of 0.1: 0.01 / (1 + ε).
        let b = rel_bias2(&shifted(&s, 0.1), &u, &scale);
        assert!((b - 0.01 / (1.0 + REL_EPS)).abs() < 2e-3, "{b}");
    }

    #[test]
    fn merging_error_follows_the_radius() {
        // α = 1: the radius stays, so the variance of n passes is the pilot's over n and
        // the bias stays.
        let (a, b) = sppm_error(1.0, 2, 64);
        assert!((a * 64.0 - 1.0).abs() < 1e-12 && (b - 1.0).abs() < 1e-12, "{a} {b}");
        // α = 2/3: after n passes the variance × n grows about as n^(1/3), the bias
        // shrinks about as n^(−1/3).
        let (a64, b64) = sppm_error(2.0 / 3.0, 2, 64);
        let (a512, b512) = sppm_error(2.0 / 3.0, 2, 512);
        let growth = (a512 * 512.0) / (a64 * 64.0);
        assert!((growth - 2.0).abs() < 0.1, "{growth}");
        assert!((b64 / b512 - 2.0).abs() < 0.1, "{}", b64 / b512);
        // At the pilot's own length: the pilot's variance and bias.
        let (a2, b2) = sppm_error(2.0 / 3.0, 2, 2);
        assert!((a2 * 2.0 - 1.0).abs() < 1e-12 && (b2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sppm_is_chosen_unless_its_bias_costs_more() {
        // Bidirectional and path tracing as in `chooses_the_cheaper_way_to_an_error`;
        // `sppm` with a tenth of the bidirectional variance in each part at the same rays.
        let (b, p) = (passes(4, 4096, 0.2, 2), passes(4, 4096, 0.3, 3));
        let none = vec![vec![(DVec3::ONE, DVec3::ZERO); 4096]; 4];
        let merged = vec![vec![DVec3::ZERO; 4096]; 4];
        let quiet = |seed| shifted(&passes(4, 4096, 0.2 / 20f64.sqrt(), seed), -0.5);
        let (d, f) = (quiet(9), quiet(10));
        let pilot = |f: &[Vec<DVec3>]| {
            Pilot::new(&PilotInput {
                bidir: &b,
                bidir_merged: &merged,
                moments: &none,
                bidir_rays: 6000,
                bidir_alpha: 0.75,
                path: &p,
                path_rays: 4000,
                sppm: Some(SppmPilot { direct: &d, flux: f, rays: 6000, alpha: 2.0 / 3.0 }),
                horizon: 64,
            })
        };
        let unbiased = pilot(&f);
        assert_eq!(unbiased.choice(), Choice::Sppm, "{unbiased:?}");
        assert!(unbiased.sppm_rel_bias2 < 1e-3, "{unbiased:?}");
        // A planted bias of 0.15 (relative squared bias 0.022, still 0.022 · 0.25 ≈ 0.006
        // at 64 passes, × 64 passes ≈ 0.35 per pass): path tracing, the next best.
        let biased = pilot(&shifted(&f, 0.15));
        assert_eq!(biased.choice(), Choice::Path, "{biased:?}");
        assert!((biased.sppm_rel_bias2 - 0.0225 / (1.0 + REL_EPS)).abs() < 4e-3, "{biased:?}");
    }
}

//! Chi-square goodness of fit of every sampling routine against its own pdf.
//!
//! Directions: N samples are histogrammed over (θ, φ) in a frame chosen per routine
//! (θ up to a cut-off, one bin for everything beyond it, one for failed samples);
//! expected counts are N times the integral of the routine's pdf over each bin, by
//! adaptive Gauss–Legendre quadrature in (θ, φ) with the sin θ Jacobian, and the
//! failed-sample bin expects N·(1 − ∫pdf). Bins expecting fewer than 5 samples are
//! pooled. Discrete choices (glass: reflect with the Fresnel probability or refract;
//! thin glass: reflect with the pane's summed reflectance 2F/(1 + F) or pass straight
//! through; mirror: always reflect) are tested on their categories. Every p-value is compared
//! with a Šidák-corrected level that keeps the family-wise level at [`ALPHA`].
//! Planted controls test correct samples against a wrong pdf; they must fail.
//! Rows `chi2/sobol/…` draw from the `sobol` sampler at the dimensions the path
//! integrator uses (one stream, sample index i), with their own planted control; the
//! others from `random`. Low-discrepancy counts are more even than multinomial ones,
//! so their statistic sits far below the chi-square law (p ≈ 1): the p-value is not
//! calibrated there, but a wrong pdf still gives a huge statistic.

mod env;
mod lights;
mod microfacet;

use super::{FamilyReport, Outcome, Settings, TestRow, sidak};
use crate::material::{Bsdf, Dielectric, Glossy, Lambertian, Mirror, ShadingPoint, ThinDielectric, TransportMode};
use crate::math::{Color, Frame, cosine_hemisphere, cosine_hemisphere_pdf, reflect};
use crate::plot::{LinePlot, Series};
use crate::sampler::random::RandomSampler;
use crate::sampler::sobol::SobolSampler;
use crate::sampler::{BOUNCE_BSDF_DIR, BOUNCE_BSDF_LOBE, Sampler, bounce_dim};
use crate::scene::LightDesc;
use anyhow::Result;
use glam::Vec3;
use lights::{area_emission_case, area_emission_positions, area_light_case, delta_emission_case};
use rayon::prelude::*;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;

/// Family-wise significance level of the whole chi-square family.
pub const ALPHA: f64 = 0.01;
/// Bins expecting fewer samples than this are pooled.
pub const MIN_EXPECTED: f64 = 5.0;
const SEED: u64 = 0xC412;
const CHUNK: usize = 1 << 14;
/// Deepest and shallowest subdivision of a histogram bin by the quadrature.
const QUAD_DEPTH: u32 = 9;
const QUAD_MIN_DEPTH: u32 = 3;
/// Shallowest subdivision of bins where the pdf's support ends.
const QUAD_EDGE_MIN_DEPTH: u32 = 5;

type SampleFn = Box<dyn Fn(f32, [f32; 2]) -> Option<Vec3> + Sync>;
type PdfFn = Box<dyn Fn(Vec3) -> f64 + Sync>;

/// A direction-sampling routine and the pdf it claims.
pub struct DirCase {
    /// Row name.
    pub name: String,
    /// `Fail` for planted controls.
    pub expected: Outcome,
    /// Histogram frame: θ is measured from `frame.n`.
    pub frame: Frame,
    /// Histogram covers θ ∈ [0, theta_max]; beyond is one bin.
    pub theta_max: f64,
    /// True when the routine may fail (BSDF samples below the surface): the failure
    /// bin then expects N·(1 − ∫pdf); otherwise it expects nothing, so a quadrature
    /// that misses a sliver of the support cannot pose as lost samples.
    pub can_fail: bool,
    /// Draws a world-space unit direction from (u_lobe, u), or fails.
    pub sample: SampleFn,
    /// Solid-angle density of a world-space unit direction.
    pub pdf: PdfFn,
}

/// Observed and expected counts of one histogram (last two bins: beyond θmax, failed).
pub struct Histogram {
    /// Observed counts.
    pub observed: Vec<u64>,
    /// Expected counts.
    pub expected: Vec<f64>,
    /// θ bins.
    pub n_theta: usize,
    /// φ bins.
    pub n_phi: usize,
}

/// Result of a chi-square test.
#[derive(Clone, Copy, Debug)]
pub struct Chi2 {
    /// Σ (O − E)² / E over the pooled bins (infinite when samples fall where E = 0).
    pub stat: f64,
    /// Degrees of freedom (pooled bins − 1).
    pub df: usize,
    /// Upper-tail probability.
    pub p: f64,
}

/// Pearson's chi-square test with bins expecting fewer than [`MIN_EXPECTED`] pooled
/// (the pool joins the smallest remaining bin when it is itself too small).
pub fn chi2_test(observed: &[u64], expected: &[f64]) -> Chi2 {
    let mut bins: Vec<(f64, f64)> = observed.iter().zip(expected).map(|(&o, &e)| (o as f64, e.max(0.0))).collect();
    bins.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut pool = (0.0, 0.0);
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for (o, e) in bins {
        if e < MIN_EXPECTED {
            pool.0 += o;
            pool.1 += e;
        } else {
            kept.push((o, e));
        }
    }
    if pool.0 > 0.0 || pool.1 > 0.0 {
        if pool.1 >= MIN_EXPECTED || kept.is_empty() {
            kept.push(pool);
        } else {
            kept[0].0 += pool.0;
            kept[0].1 += pool.1;
        }
    }
    let mut stat = 0.0;
    for &(o, e) in &kept {
        if e > 0.0 {
            stat += (o - e) * (o - e) / e;
        } else if o > 0.0 {
            stat = f64::INFINITY;
        }
    }
    let df = kept.len().saturating_sub(1);
    let p = if stat.is_infinite() {
        0.0
    } else if df == 0 {
        1.0
    } else {
        ChiSquared::new(df as f64).map(|d| d.sf(stat)).unwrap_or(0.0)
    };
    Chi2 { stat, df, p }
}

fn dir(frame: &Frame, theta: f64, phi: f64) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    frame.to_world(Vec3::new((st * cp) as f32, (st * sp) as f32, ct as f32)).normalize()
}

/// Gauss–Legendre estimate (2×2 or 3×3 nodes) of ∫∫ pdf sin θ over a (θ, φ) cell.
fn gauss(f: &PdfFn, frame: &Frame, c: Cell, three: bool) -> f64 {
    const N2: [(f64, f64); 2] = [(-0.288_675_134_594_812_9, 0.5), (0.288_675_134_594_812_9, 0.5)];
    const N3: [(f64, f64); 3] = [(-0.387_298_334_620_741_7, 5.0 / 18.0), (0.0, 8.0 / 18.0), (0.387_298_334_620_741_7, 5.0 / 18.0)];
    let nodes: &[(f64, f64)] = if three { &N3 } else { &N2 };
    let (tm, th, pm, ph) = (0.5 * (c.t0 + c.t1), c.t1 - c.t0, 0.5 * (c.p0 + c.p1), c.p1 - c.p0);
    let mut s = 0.0;
    for &(a, wa) in nodes {
        for &(b, wb) in nodes {
            let t = tm + a * th;
            s += wa * wb * f(dir(frame, t, pm + b * ph)) * t.sin();
        }
    }
    s * th * ph
}

/// A (θ, φ) rectangle.
#[derive(Clone, Copy, Debug)]
struct Cell {
    t0: f64,
    t1: f64,
    p0: f64,
    p1: f64,
}

impl Cell {
    fn quarters(self) -> [Cell; 4] {
        let (tm, pm) = (0.5 * (self.t0 + self.t1), 0.5 * (self.p0 + self.p1));
        [Cell { t1: tm, p1: pm, ..self }, Cell { t1: tm, p0: pm, ..self }, Cell { t0: tm, p1: pm, ..self }, Cell { t0: tm, p0: pm, ..self }]
    }
}

/// Adaptive quadrature over a cell: always split down to `min_depth` (so that no
/// node pattern steps over a thin sliver of a discontinuous pdf), then until the
/// 2×2 rule on the four quarters agrees with the 3×3 rule on the whole cell (their
/// nodes differ, so a discontinuity rarely fools both) or `depth` runs out.
fn integrate(f: &PdfFn, frame: &Frame, c: Cell, depth: u32, min_depth: u32) -> f64 {
    let q = c.quarters();
    let fine: f64 = q.iter().map(|&k| gauss(f, frame, k, false)).sum();
    if depth == 0 {
        return fine;
    }
    if min_depth == 0 {
        let coarse = gauss(f, frame, c, true);
        if (fine - coarse).abs() <= 1e-10 + 1e-6 * fine.abs() {
            return fine;
        }
    }
    q.iter().map(|&k| integrate(f, frame, k, depth - 1, min_depth.saturating_sub(1))).sum()
}

/// Samples a direction case and integrates its pdf over the same bins.
pub fn histogram(case: &DirCase, stream: u64, n: usize, n_theta: usize, n_phi: usize) -> Histogram {
    histogram_with(case, stream, n, n_theta, n_phi, &RandomSampler::new(SEED), false)
}

/// As [`histogram`], drawing from a copy of `sampler`; with `layout`, the draws sit
/// where the path integrator puts a bounce's lobe choice and BSDF direction when
/// `bounce_layout` (`bounce_dim(0) + BOUNCE_BSDF_LOBE`, then the 2-D direction),
/// otherwise at dimensions 0–2.
pub fn histogram_with(
    case: &DirCase,
    stream: u64,
    n: usize,
    n_theta: usize,
    n_phi: usize,
    sampler: &dyn Sampler,
    bounce_layout: bool,
) -> Histogram {
    let nb = n_theta * n_phi;
    let (tmax, dphi) = (case.theta_max, 2.0 * PI / n_phi as f64);
    let chunks = n.div_ceil(CHUNK);
    let partial: Vec<Vec<u64>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut h = vec![0u64; nb + 2];
            let mut s = sampler.clone_box();
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                s.start(stream, i as u64);
                if bounce_layout {
                    s.set_dimension(bounce_dim(0) + BOUNCE_BSDF_LOBE);
                }
                let ul = s.next_1d();
                let u = s.next_2d();
                let Some(w) = (case.sample)(ul, u).filter(|w| w.is_finite() && w.length_squared() > 0.0) else {
                    h[nb + 1] += 1;
                    continue;
                };
                let l = case.frame.to_local(w.normalize());
                let theta = (l.z as f64).clamp(-1.0, 1.0).acos();
                if theta >= tmax {
                    h[nb] += 1;
                    continue;
                }
                let mut phi = (l.y as f64).atan2(l.x as f64);
                if phi < 0.0 {
                    phi += 2.0 * PI;
                }
                let it = ((theta / tmax * n_theta as f64) as usize).min(n_theta - 1);
                let ip = ((phi / dphi) as usize).min(n_phi - 1);
                h[it * n_phi + ip] += 1;
            }
            h
        })
        .collect();
    let mut observed = vec![0u64; nb + 2];
    for h in partial {
        for (o, v) in observed.iter_mut().zip(h) {
            *o += v;
        }
    }
    let cell = |t0: f64, t1: f64, p0: f64, p1: f64| integrate(&case.pdf, &case.frame, Cell { t0, t1, p0, p1 }, QUAD_DEPTH, QUAD_MIN_DEPTH);
    let dtheta = tmax / n_theta as f64;
    let bin = |b: usize| {
        let (it, ip) = (b / n_phi, b % n_phi);
        Cell { t0: it as f64 * dtheta, t1: (it + 1) as f64 * dtheta, p0: ip as f64 * dphi, p1: (ip + 1) as f64 * dphi }
    };
    // Where the support of the pdf ends (a bin or a neighbour has both zero and
    // non-zero pdf on an 8 × 8 probe grid), thin slivers of support can hide between
    // quadrature nodes: those bins are subdivided deeper from the start.
    let support: Vec<(bool, bool)> = (0..nb)
        .into_par_iter()
        .map(|b| {
            let c = bin(b);
            let (mut zero, mut nonzero) = (false, false);
            for i in 0..8 {
                for j in 0..8 {
                    let t = c.t0 + (i as f64 + 0.5) / 8.0 * (c.t1 - c.t0);
                    let ph = c.p0 + (j as f64 + 0.5) / 8.0 * (c.p1 - c.p0);
                    if (case.pdf)(dir(&case.frame, t, ph)) > 0.0 { nonzero = true } else { zero = true }
                }
            }
            (zero, nonzero)
        })
        .collect();
    let edge = |b: usize| {
        let (it, ip) = ((b / n_phi) as i64, (b % n_phi) as i64);
        let (mut zero, mut nonzero) = (false, false);
        for dt in -1..=1 {
            for dp in -1..=1 {
                let t = it + dt;
                if t < 0 || t >= n_theta as i64 {
                    continue;
                }
                let p = (ip + dp).rem_euclid(n_phi as i64);
                let (z, n) = support[(t * n_phi as i64 + p) as usize];
                zero |= z;
                nonzero |= n;
            }
        }
        zero && nonzero
    };
    let mut expected: Vec<f64> = (0..nb)
        .into_par_iter()
        .map(|b| {
            let min_depth = if edge(b) { QUAD_EDGE_MIN_DEPTH } else { QUAD_MIN_DEPTH };
            integrate(&case.pdf, &case.frame, bin(b), QUAD_DEPTH, min_depth)
        })
        .collect();
    // Beyond θmax: a coarse grid of cells, each refined adaptively.
    let beyond: f64 = if tmax < PI {
        let (nt, np) = (16, 32);
        let dt = (PI - tmax) / nt as f64;
        let dp = 2.0 * PI / np as f64;
        (0..nt * np)
            .into_par_iter()
            .map(|b| {
                let (it, ip) = (b / np, b % np);
                cell(tmax + it as f64 * dt, tmax + (it + 1) as f64 * dt, ip as f64 * dp, (ip + 1) as f64 * dp)
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum()
    } else {
        0.0
    };
    let total: f64 = expected.iter().sum::<f64>() + beyond;
    expected.push(beyond);
    expected.push(if case.can_fail { (1.0 - total).max(0.0) } else { 0.0 });
    for e in expected.iter_mut() {
        *e *= n as f64;
    }
    Histogram { observed, expected, n_theta, n_phi }
}

impl Histogram {
    /// Observed and expected counts summed over φ, per θ bin (for plots).
    pub fn theta_marginals(&self) -> (Vec<f64>, Vec<f64>) {
        let mut o = vec![0.0; self.n_theta];
        let mut e = vec![0.0; self.n_theta];
        for b in 0..self.n_theta * self.n_phi {
            o[b / self.n_phi] += self.observed[b] as f64;
            e[b / self.n_phi] += self.expected[b];
        }
        (o, e)
    }
}

fn flat() -> ShadingPoint {
    ShadingPoint::new(Vec3::Z, Vec3::Z)
}

fn from_theta(deg: f32) -> Vec3 {
    let t = deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// A case sampling `bsdf` at `sp` for outgoing `wo`, against the BSDF's own pdf
/// (or `pdf_of`'s pdf, for planted controls).
#[allow(clippy::too_many_arguments)]
fn bsdf_case(name: &str, bsdf: Bsdf, pdf_of: Bsdf, sp: ShadingPoint, wo: Vec3, frame: Frame, theta_max: f64, expected: Outcome) -> DirCase {
    DirCase {
        name: name.into(),
        expected,
        frame,
        theta_max,
        can_fail: true,
        sample: Box::new(move |ul, u| bsdf.sample(&sp, wo, ul, u, TransportMode::Radiance).map(|s| s.wi)),
        pdf: Box::new(move |w| pdf_of.pdf(&sp, wo, w) as f64),
    }
}

/// As [`bsdf_case`], with delta samples (mixed BSDFs' delta lobes) counted as
/// failures: the failure bin then expects their probability, N·(1 − ∫pdf).
#[allow(clippy::too_many_arguments)]
fn bsdf_case_filtered(
    name: &str,
    bsdf: Bsdf,
    pdf_of: Bsdf,
    sp: ShadingPoint,
    wo: Vec3,
    frame: Frame,
    theta_max: f64,
    expected: Outcome,
) -> DirCase {
    DirCase {
        name: name.into(),
        expected,
        frame,
        theta_max,
        can_fail: true,
        sample: Box::new(move |ul, u| bsdf.sample(&sp, wo, ul, u, TransportMode::Radiance).filter(|s| !s.delta).map(|s| s.wi)),
        pdf: Box::new(move |w| pdf_of.pdf(&sp, wo, w) as f64),
    }
}

fn phong(kd: f32, ks: f32, exponent: f32) -> Bsdf {
    Bsdf::Glossy(Glossy { kd: Color::splat(kd), ks: Color::splat(ks), exponent })
}

/// θ beyond which a Phong lobe of exponent n holds less than 1e-3 of its mass.
fn lobe_theta(n: f32) -> f64 {
    (1e-3f64.powf(1.0 / (n as f64 + 1.0))).acos().clamp(0.2, PI)
}

/// Every direction case of the suite (planted controls last).
pub fn direction_cases(s: &Settings) -> Result<Vec<DirCase>> {
    let z = Frame::new(Vec3::Z);
    let mut v = vec![DirCase {
        name: "chi2/cosine_hemisphere".into(),
        expected: Outcome::Pass,
        frame: z,
        theta_max: PI,
        can_fail: false,
        sample: Box::new(|_, u| Some(cosine_hemisphere(u))),
        pdf: Box::new(|w| cosine_hemisphere_pdf(w.z) as f64),
    }];
    let lam = Bsdf::Lambertian(Lambertian { albedo: Color::splat(0.7) });
    let wo = Vec3::new(0.3, 0.2, 0.9).normalize();
    v.push(bsdf_case("chi2/lambertian/front", lam.clone(), lam.clone(), flat(), wo, z, PI, Outcome::Pass));
    v.push(bsdf_case(
        "chi2/lambertian/back",
        lam.clone(),
        lam.clone(),
        flat(),
        Vec3::new(0.5, -0.1, -0.6).normalize(),
        z,
        PI,
        Outcome::Pass,
    ));
    // Shading normal tilted 20° from the geometric one: samples crossing the
    // geometric surface are rejected, which the pdf must account for.
    let tilted = ShadingPoint::new(Vec3::Z, Vec3::new(20f32.to_radians().sin(), 0.0, 20f32.to_radians().cos()));
    v.push(bsdf_case("chi2/lambertian/shading_normal", lam.clone(), lam, tilted, wo, z, PI, Outcome::Pass));
    let mut exps = vec![1.0f32, 10.0, 100.0];
    if s.thorough {
        exps.push(1000.0);
    }
    for n in exps {
        let wo = from_theta(30.0);
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        let b = phong(0.0, 1.0, n);
        v.push(bsdf_case(&format!("chi2/phong/n{n}"), b.clone(), b, flat(), wo, Frame::new(r), lobe_theta(n), Outcome::Pass));
    }
    // Grazing: much of the lobe falls below the surface and those samples fail.
    let wo = from_theta(75.0);
    let b = phong(0.0, 1.0, 10.0);
    v.push(bsdf_case("chi2/phong/n10_grazing", b.clone(), b, flat(), wo, Frame::new(Vec3::new(-wo.x, -wo.y, wo.z)), PI, Outcome::Pass));
    let b = phong(0.4, 0.4, 20.0);
    v.push(bsdf_case("chi2/phong/kd0.4_ks0.4_n20", b.clone(), b, flat(), from_theta(45.0), z, PI, Outcome::Pass));
    v.push(area_light_case()?);
    v.push(area_emission_case()?.0);
    v.push(delta_emission_case(LightDesc::Spot {
        position: Vec3::new(0.0, 0.0, 1.0),
        direction: Vec3::new(0.2, -0.3, -1.0).normalize(),
        intensity: Color::ONE,
        cone_deg: 20.0,
        falloff_deg: 35.0,
    })?);
    v.push(delta_emission_case(LightDesc::Point { position: Vec3::new(0.0, 0.0, 1.0), intensity: Color::ONE })?);
    // Mitsuba's BSDFs (their planted controls at the end).
    let (mitsuba_pass, mitsuba_planted): (Vec<_>, Vec<_>) = microfacet::cases(s).into_iter().partition(|c| c.expected == Outcome::Pass);
    v.extend(mitsuba_pass);
    v.extend(env::env_cases()?);
    // Planted: Phong n = 10 samples against the n = 11 pdf; cosine samples against
    // the uniform-hemisphere pdf.
    let wo = from_theta(30.0);
    v.push(bsdf_case(
        "chi2/planted/phong_n10_vs_pdf_n11",
        phong(0.0, 1.0, 10.0),
        phong(0.0, 1.0, 11.0),
        flat(),
        wo,
        Frame::new(Vec3::new(-wo.x, -wo.y, wo.z)),
        lobe_theta(10.0),
        Outcome::Fail,
    ));
    v.push(DirCase {
        name: "chi2/planted/cosine_vs_uniform_pdf".into(),
        expected: Outcome::Fail,
        frame: z,
        theta_max: PI,
        can_fail: false,
        sample: Box::new(|_, u| Some(cosine_hemisphere(u))),
        pdf: Box::new(|w| if w.z > 0.0 { 1.0 / (2.0 * PI) } else { 0.0 }),
    });
    v.extend(mitsuba_planted);
    Ok(v)
}

/// Cases drawn with the `sobol` sampler: cosine-weighted hemisphere, a Phong lobe
/// and, planted, cosine samples against the uniform-hemisphere pdf.
fn sobol_cases() -> Vec<DirCase> {
    let z = Frame::new(Vec3::Z);
    let wo = from_theta(30.0);
    let b = phong(0.0, 1.0, 10.0);
    vec![
        DirCase {
            name: "chi2/sobol/cosine_hemisphere".into(),
            expected: Outcome::Pass,
            frame: z,
            theta_max: PI,
            can_fail: false,
            sample: Box::new(|_, u| Some(cosine_hemisphere(u))),
            pdf: Box::new(|w| cosine_hemisphere_pdf(w.z) as f64),
        },
        bsdf_case(
            "chi2/sobol/phong/n10",
            b.clone(),
            b,
            flat(),
            wo,
            Frame::new(Vec3::new(-wo.x, -wo.y, wo.z)),
            lobe_theta(10.0),
            Outcome::Pass,
        ),
        DirCase {
            name: "chi2/planted/sobol/cosine_vs_uniform_pdf".into(),
            expected: Outcome::Fail,
            frame: z,
            theta_max: PI,
            can_fail: false,
            sample: Box::new(|_, u| Some(cosine_hemisphere(u))),
            pdf: Box::new(|w| if w.z > 0.0 { 1.0 / (2.0 * PI) } else { 0.0 }),
        },
    ]
}

/// Unpolarised Fresnel reflectance (an independent implementation, the oracle of the
/// glass test): light arriving with cosine `cos_i` from index `eta_i` into `eta_t`.
pub fn fresnel(cos_i: f64, eta_i: f64, eta_t: f64) -> f64 {
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    let rp = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Glass (reflect with probability F, else refract by Snell's law) and mirror
/// (always reflect) as discrete choices: (name, observed, expected probabilities).
/// Samples that are neither the reflection nor the refraction, or that report a
/// different probability, land in a last category expecting none.
fn discrete_cases(n: usize) -> Vec<(String, Outcome, Vec<u64>, Vec<f64>)> {
    let glass = Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE));
    let mirror = Bsdf::Mirror(Mirror { reflectance: Color::splat(0.9) });
    let sp = flat();
    let mut out = Vec::new();
    let cases: Vec<(String, &Bsdf, Vec3)> = vec![
        ("chi2/glass/outside_cos0.95".into(), &glass, Vec3::new((1.0f32 - 0.9025).sqrt(), 0.0, 0.95)),
        ("chi2/glass/outside_cos0.5".into(), &glass, Vec3::new(0.75f32.sqrt(), 0.0, 0.5)),
        ("chi2/glass/outside_cos0.1".into(), &glass, Vec3::new(0.99f32.sqrt(), 0.0, 0.1)),
        ("chi2/glass/inside_cos0.9".into(), &glass, Vec3::new(0.19f32.sqrt(), 0.0, -0.9)),
        ("chi2/glass/inside_tir_cos0.5".into(), &glass, Vec3::new(0.75f32.sqrt(), 0.0, -0.5)),
        ("chi2/mirror/cos0.7".into(), &mirror, Vec3::new(0.51f32.sqrt(), 0.0, 0.7)),
        ("chi2/mirror/back_cos0.3".into(), &mirror, Vec3::new(0.91f32.sqrt(), 0.0, -0.3)),
    ];
    for (name, b, wo) in cases {
        let n_side = if wo.z > 0.0 { Vec3::Z } else { -Vec3::Z };
        let cos_o = wo.dot(n_side);
        let (eta_o, eta_t) = if wo.z > 0.0 { (1.0f32, 1.5f32) } else { (1.5, 1.0) };
        let f = if matches!(b, Bsdf::Mirror(_)) { 1.0 } else { fresnel(cos_o as f64, eta_o as f64, eta_t as f64) as f32 };
        let refl = reflect(wo, n_side);
        let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let mut counts = [0u64; 3];
        let mut s = RandomSampler::new(SEED ^ 0xD15C);
        for i in 0..n {
            s.start(0, i as u64);
            let ul = s.next_1d();
            let k = match b.sample(&sp, wo, ul, [0.5, 0.5], TransportMode::Radiance) {
                Some(r) if (r.wi - refl).length() < 1e-4 && (r.pdf - f).abs() < 1e-4 => 0,
                Some(r)
                    if r.wi.z * wo.z < 0.0
                        && ((1.0 - r.wi.z * r.wi.z).max(0.0).sqrt() - eta_o / eta_t * sin_o).abs() < 1e-4
                        && r.wi.y.abs() < 1e-5
                        && r.wi.x * wo.x < 0.0
                        && (r.pdf - (1.0 - f)).abs() < 1e-4 =>
                {
                    1
                }
                _ => 2,
            };
            counts[k] += 1;
        }
        out.push((name, Outcome::Pass, counts.to_vec(), vec![f as f64, 1.0 - f as f64, 0.0]));
    }
    out.extend(thin_cases(n));
    out
}

/// Mitsuba's `thindielectric` (a pane of index 1.5 in air): the mirror direction with
/// probability R' = 2F/(1 + F) (every internal reflection summed, F from [`fresnel`]),
/// else −wo, from either side. Planted: the same samples against a single interface's
/// F, as a pane that forgot its second face would claim.
fn thin_cases(n: usize) -> Vec<(String, Outcome, Vec<u64>, Vec<f64>)> {
    let thin = Bsdf::ThinDielectric(ThinDielectric {
        int_ior: 1.5,
        ext_ior: 1.0,
        specular_reflectance: Color::ONE,
        specular_transmittance: Color::ONE,
    });
    let sp = flat();
    let cases = [
        ("chi2/thindielectric/cos0.9", Vec3::new(0.19f32.sqrt(), 0.0, 0.9), false),
        ("chi2/thindielectric/grazing_cos0.15", Vec3::new((1.0f32 - 0.0225).sqrt(), 0.0, 0.15), false),
        ("chi2/thindielectric/back_cos0.4", Vec3::new(0.84f32.sqrt(), 0.0, -0.4), false),
        ("chi2/planted/thindielectric_single_interface", Vec3::new((1.0f32 - 0.0225).sqrt(), 0.0, 0.15), true),
    ];
    cases
        .into_iter()
        .map(|(name, wo, planted)| {
            let n_side = if wo.z > 0.0 { Vec3::Z } else { -Vec3::Z };
            let f = fresnel(wo.z.abs() as f64, 1.0, 1.5);
            let r = if planted { f } else { 2.0 * f / (1.0 + f) };
            let refl = reflect(wo, n_side);
            let mut counts = [0u64; 3];
            let mut s = RandomSampler::new(SEED ^ 0x7417);
            for i in 0..n {
                s.start(0, i as u64);
                let ul = s.next_1d();
                let k = match thin.sample(&sp, wo, ul, [0.5, 0.5], TransportMode::Radiance) {
                    Some(x) if (x.wi - refl).length() < 1e-4 => 0,
                    Some(x) if (x.wi + wo).length() < 1e-4 => 1,
                    _ => 2,
                };
                counts[k] += 1;
            }
            let expected = if planted { Outcome::Fail } else { Outcome::Pass };
            (name.to_string(), expected, counts.to_vec(), vec![r, 1.0 - r, 0.0])
        })
        .collect()
}

/// Runs the family.
pub fn run(s: &Settings) -> Result<FamilyReport> {
    let n = s.pick(1_000_000, 10_000_000);
    let (nt, np) = s.pick((16, 32), (32, 64));
    let cases = direction_cases(s)?;
    let mut results: Vec<(String, Outcome, Chi2)> = Vec::new();
    let mut marginals = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        let h = histogram(c, i as u64, n, nt, np);
        if c.name == "chi2/phong/n10" || c.name == "chi2/planted/phong_n10_vs_pdf_n11" {
            marginals.push((c.name.clone(), c.theta_max, h.theta_marginals()));
        }
        results.push((c.name.clone(), c.expected, chi2_test(&h.observed, &h.expected)));
    }
    // The `sobol` sampler as the path integrator draws it (lobe, then direction).
    const _: () = assert!(BOUNCE_BSDF_DIR == BOUNCE_BSDF_LOBE + 1);
    let sobol = SobolSampler::new(SEED);
    for (i, c) in sobol_cases().iter().enumerate() {
        let h = histogram_with(c, 1000 + i as u64, n, nt, np, &sobol, true);
        results.push((c.name.clone(), c.expected, chi2_test(&h.observed, &h.expected)));
    }
    let (_, scene, lights, q) = area_emission_case()?;
    let (o, e) = area_emission_positions(&scene, &lights, q, n);
    results.push(("chi2/emit/area/position".into(), Outcome::Pass, chi2_test(&o, &e)));
    for (name, expected, obs, probs) in discrete_cases(n / 5) {
        let total: u64 = obs.iter().sum();
        let exp: Vec<f64> = probs.iter().map(|p| p * total as f64).collect();
        // An outcome of probability zero (wrong direction or probability, refraction
        // under total internal reflection) must never occur.
        let impossible = obs.iter().zip(&probs).any(|(&o, &p)| p == 0.0 && o > 0);
        let c = if impossible { Chi2 { stat: f64::INFINITY, df: 1, p: 0.0 } } else { chi2_test(&obs, &exp) };
        results.push((name, expected, c));
    }
    let alpha = sidak(ALPHA, results.len());
    let rows = results
        .into_iter()
        .map(|(name, expected, c)| {
            // A test with no degrees of freedom (a certain outcome) passes when the
            // impossible outcomes never occur.
            let p = (c.df > 0 || c.stat.is_infinite()).then_some(c.p);
            TestRow::new(name, c.stat, p, expected, c.p >= alpha)
        })
        .collect();
    let mut series = Vec::new();
    if let [(_, tmax, (o, e)), (_, _, (_, e_wrong))] = &marginals[..] {
        let nt = o.len();
        let x = |i: usize| (i as f64 + 0.5) * tmax / nt as f64 * 180.0 / PI;
        series.push(Series { name: "observed (n = 10 samples)".into(), points: o.iter().enumerate().map(|(i, &v)| (x(i), v)).collect() });
        series.push(Series { name: "expected, pdf n = 10".into(), points: e.iter().enumerate().map(|(i, &v)| (x(i), v)).collect() });
        series.push(Series {
            name: "expected, planted pdf n = 11".into(),
            points: e_wrong.iter().enumerate().map(|(i, &v)| (x(i), v)).collect(),
        });
    }
    let plot = LinePlot {
        title: "Phong lobe n = 10: samples per θ bin".into(),
        x_label: "angle from the mirror direction (degrees)".into(),
        y_label: "samples".into(),
        log_x: false,
        log_y: false,
        series,
    };
    Ok(FamilyReport { rows, plots: vec![("chi2_phong_theta".into(), plot)] })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_pools_small_bins_and_flags_impossible_samples() {
        let c = chi2_test(&[100, 100, 2, 1], &[100.0, 100.0, 1.5, 1.5]);
        assert_eq!(c.df, 1);
        assert!(c.p > 0.5);
        let c = chi2_test(&[100, 100, 0], &[100.0, 100.0, 0.0]);
        assert!(c.stat == 0.0 && c.p == 1.0);
        // Known value: O = (60, 40), E = (50, 50): χ² = 4, df = 1, p = 0.0455.
        let c = chi2_test(&[60, 40], &[50.0, 50.0]);
        assert!((c.stat - 4.0).abs() < 1e-12 && (c.p - 0.0455).abs() < 1e-4, "{c:?}");
    }

    #[test]
    fn quadrature_integrates_known_pdfs() {
        let z = Frame::new(Vec3::Z);
        let f: PdfFn = Box::new(|w| cosine_hemisphere_pdf(w.z) as f64);
        let whole = Cell { t0: 0.0, t1: PI, p0: 0.0, p1: 2.0 * PI };
        assert!((integrate(&f, &z, whole, 8, 2) - 1.0).abs() < 1e-6);
        // A discontinuous pdf, uniform in a 30° cone, over bins as the histogram uses.
        let cm = 30f64.to_radians().cos();
        let f: PdfFn = Box::new(move |w| if w.z as f64 >= cm { 1.0 / (2.0 * PI * (1.0 - cm)) } else { 0.0 });
        let (nt, np, tmax) = (16, 32, 0.7);
        let mut v = 0.0;
        for it in 0..nt {
            for ip in 0..np {
                let (t0, p0) = (it as f64 * tmax / nt as f64, ip as f64 * 2.0 * PI / np as f64);
                let c = Cell { t0, t1: t0 + tmax / nt as f64, p0, p1: p0 + 2.0 * PI / np as f64 };
                v += integrate(&f, &z, c, QUAD_DEPTH, QUAD_MIN_DEPTH);
            }
        }
        assert!((v - 1.0).abs() < 2e-4, "{v}");
    }
}

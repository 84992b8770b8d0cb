//! Discrepancy of the samplers' point sets.
//!
//! - Warnock's closed form of the L2-star discrepancy of the first N points of
//!   `random`, `halton` and `hammersley` (as rendering uses them: seeded, scrambled),
//!   N = 2^4 … 2^14, dimensions 2–6 (random: root mean square over 4 seeds). Rows:
//!   `ratio` = T(random) / T(set) at the largest N (must be at least [`MARGIN`]);
//!   `slope` = log–log slope of T over N ≥ 2^8, which must be within
//!   [`SLOPE_TOL`] of the theoretical rate fitted over the same N: (log N)^k / N with
//!   k = d/2 for the Halton sequence and (d − 1)/2 for the Hammersley point set
//!   (Roth's order, attained by randomised constructions), N^−1/2 for random points.
//! - The exact star discrepancy D* in 2-D (O(N²) sweep over the critical boxes) for
//!   N = 2^4 … 2^10 (2^12 thorough), slope fitted over N ≥ 2^6 against the classical
//!   bounds (log N)^2 / N for Halton and log N / N for Hammersley.
//! - `sobol` pads independent 4-D groups (see `sampler::sobol`), so its points are
//!   the four lanes of one group — bounce 0's light point, light choice and lobe,
//!   dimensions 3, 4, 2, 5 — tested for d = 2 … 4 against the rate of scrambled
//!   nets, (log N)^((d − 1)/2) / N (N is a power of two); across groups it is only as
//!   uniform as random points, which no row claims otherwise.
//!   Planted control `sobol-unnested`: the same points with the output scramble
//!   hashing each bit from the bits below it (a bijection, not a nested scramble).
//! - Planted control `diagonal`: every coordinate is the same van der Corput value,
//!   so the points lie on the diagonal and the discrepancy does not decay.

use super::{FamilyReport, Outcome, Settings, TestRow};
use crate::plot::{LinePlot, Series, log_log_slope};
use crate::sampler::halton::HaltonSampler;
use crate::sampler::hammersley::HammersleySampler;
use crate::sampler::random::RandomSampler;
use crate::sampler::sobol::SobolSampler;
use crate::sampler::{Sampler, radical_inverse};
use anyhow::Result;
use rayon::prelude::*;

/// Largest dimension tested.
pub const MAX_DIM: usize = 6;
/// Minimum ratio T(random) / T(low-discrepancy) at the largest N (every dimension).
pub const MARGIN: f64 = 2.5;
/// Largest accepted distance between a fitted slope and the theoretical one.
pub const SLOPE_TOL: f64 = 0.12;
/// Random point sets averaged (root mean square) for the random curve.
pub const RANDOM_SEEDS: u64 = 4;
/// Smallest N used in slope fits (pre-asymptotic sizes excluded).
pub const FIT_FROM: usize = 1 << 8;
const SEED: u64 = 7;

type Point = [f64; MAX_DIM];

/// The first `n` points of a sampler's stream 0, `MAX_DIM` coordinates each.
pub fn points(sampler: &mut dyn Sampler, n: usize) -> Vec<Point> {
    (0..n)
        .map(|i| {
            sampler.start(0, i as u64);
            let mut p = [0.0; MAX_DIM];
            for c in p.iter_mut() {
                *c = sampler.next_1d() as f64;
            }
            p
        })
        .collect()
}

/// The first `n` points of a sampler's stream 0 read at the given dimensions.
pub fn points_at(sampler: &mut dyn Sampler, n: usize, dims: [u32; MAX_DIM]) -> Vec<Point> {
    (0..n)
        .map(|i| {
            sampler.start(0, i as u64);
            let mut p = [0.0; MAX_DIM];
            for (c, &d) in p.iter_mut().zip(&dims) {
                sampler.set_dimension(d);
                *c = sampler.next_1d() as f64;
            }
            p
        })
        .collect()
}

/// Dimensions of one 4-D `sobol` group in lane order (then two of the next group).
const SOBOL_DIMS: [u32; MAX_DIM] = [3, 4, 2, 5, 6, 7];
/// Largest dimension tested on `sobol` point sets (one group).
const SOBOL_MAX_DIM: usize = 4;

/// Points of a named set: `random`, `halton`, `hammersley` (its N-point set) or the
/// planted `diagonal`.
pub fn point_set(name: &str, n: usize) -> Result<Vec<Point>> {
    random_or(name, n, SEED)
}

fn random_or(name: &str, n: usize, seed: u64) -> Result<Vec<Point>> {
    Ok(match name {
        "random" => points(&mut RandomSampler::new(seed), n),
        "halton" => points(&mut HaltonSampler::new(SEED), n),
        "hammersley" => points(&mut HammersleySampler::new(SEED, n as u64)?, n),
        "sobol" => points_at(&mut SobolSampler::new(SEED), n, SOBOL_DIMS),
        "sobol-unnested" => points_at(&mut SobolSampler::planted_unnested(SEED), n, SOBOL_DIMS),
        "diagonal" => (0..n).map(|i| [radical_inverse(2, i as u64); MAX_DIM]).collect(),
        _ => anyhow::bail!("unknown point set `{name}`"),
    })
}

/// Warnock's squared L2-star discrepancy of every prefix of `pts` whose length is
/// in `sizes` (ascending), for dimensions 1..=MAX_DIM (index d − 1):
/// T² = 3^−d − 2^(1−d)/N Σ_i Π_k (1 − x_ik²) + 1/N² Σ_i Σ_j Π_k (1 − max(x_ik, x_jk)).
pub fn warnock_prefixes(pts: &[Point], sizes: &[usize]) -> Vec<[f64; MAX_DIM]> {
    let nmax = sizes.iter().copied().max().unwrap_or(0).min(pts.len());
    // Row j: (2 Σ_{i<j} Π(1 − max) + Π(1 − x_j), Π(1 − x_j²)) per dimension prefix.
    let rows: Vec<([f64; MAX_DIM], [f64; MAX_DIM])> = (0..nmax)
        .into_par_iter()
        .with_min_len(64)
        .map(|j| {
            let pj = &pts[j];
            let mut pair = [0.0f64; MAX_DIM];
            for pi in &pts[..j] {
                let mut prod = 1.0;
                for k in 0..MAX_DIM {
                    prod *= 1.0 - pi[k].max(pj[k]);
                    pair[k] += prod;
                }
            }
            let (mut diag, mut sq, mut pd, mut ps) = ([0.0; MAX_DIM], [0.0; MAX_DIM], 1.0, 1.0);
            for k in 0..MAX_DIM {
                pd *= 1.0 - pj[k];
                ps *= 1.0 - pj[k] * pj[k];
                diag[k] = 2.0 * pair[k] + pd;
                sq[k] = ps;
            }
            (diag, sq)
        })
        .collect();
    let mut out = Vec::new();
    let (mut double, mut single) = ([0.0f64; MAX_DIM], [0.0f64; MAX_DIM]);
    let mut next = 0;
    for (j, (d, s)) in rows.iter().enumerate() {
        for k in 0..MAX_DIM {
            double[k] += d[k];
            single[k] += s[k];
        }
        while next < sizes.len() && sizes[next] == j + 1 {
            let n = (j + 1) as f64;
            let mut t2 = [0.0; MAX_DIM];
            for k in 0..MAX_DIM {
                let dim = (k + 1) as i32;
                t2[k] = 3f64.powi(-dim) - 2f64.powi(1 - dim) / n * single[k] + double[k] / (n * n);
            }
            out.push(t2);
            next += 1;
        }
    }
    out
}

/// Expected squared L2-star discrepancy of N independent uniform points in d dimensions.
pub fn random_expected_t2(d: usize, n: usize) -> f64 {
    (2f64.powi(-(d as i32)) - 3f64.powi(-(d as i32))) / n as f64
}

/// Exact star discrepancy of a 2-D point set: the largest |x·y − A/N| over the
/// critical boxes whose corners are point coordinates or 1 (open boxes for the
/// volume excess, closed ones for the count excess). O(N²).
pub fn star_discrepancy_2d(pts: &[[f64; 2]]) -> f64 {
    let n = pts.len();
    if n == 0 {
        return 1.0;
    }
    let mut xs: Vec<f64> = pts.iter().map(|p| p[0]).collect();
    xs.push(1.0);
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let mut by_y: Vec<usize> = (0..n).collect();
    by_y.sort_by(|&a, &b| pts[a][1].total_cmp(&pts[b][1]));
    let inv = 1.0 / n as f64;
    xs.par_iter()
        .map(|&x| {
            let mut best = 0.0f64;
            let (mut open, mut closed) = (0usize, 0usize);
            let mut i = 0;
            while i < n {
                let y = pts[by_y[i]][1];
                // Open box [0,x)×[0,y): points strictly below y, counted before the group.
                best = best.max(x * y - open as f64 * inv);
                let mut j = i;
                while j < n && pts[by_y[j]][1] == y {
                    let p = pts[by_y[j]];
                    if p[0] < x {
                        open += 1;
                    }
                    if p[0] <= x {
                        closed += 1;
                    }
                    j += 1;
                }
                // Closed box [0,x]×[0,y].
                best = best.max(closed as f64 * inv - x * y);
                i = j;
            }
            best.max(x - open as f64 * inv).max(closed as f64 * inv - x)
        })
        .reduce(|| 0.0, f64::max)
}

/// Least-squares log–log slope of (log N)^k / N over the given N.
pub fn theory_slope(k: f64, sizes: &[f64]) -> f64 {
    let pts: Vec<(f64, f64)> = sizes.iter().map(|&n| (n, n.ln().powf(k) / n)).collect();
    log_log_slope(&pts).unwrap_or(-1.0)
}

fn slope_row(test: String, slope: Option<f64>, theory: f64, expected: Outcome) -> TestRow {
    let s = slope.unwrap_or(f64::NAN);
    TestRow::new(test, s, None, expected, (s - theory).abs() <= SLOPE_TOL)
}

/// Runs the family.
pub fn run(s: &Settings) -> Result<FamilyReport> {
    let max_pow = 14;
    let sizes: Vec<usize> = (4..=max_pow).map(|k| 1usize << k).collect();
    let nmax = *sizes.last().unwrap_or(&16);
    let sets = ["random", "halton", "hammersley", "sobol", "sobol-unnested", "diagonal"];
    // t2[set][size][dim-1]
    let mut t2: Vec<Vec<[f64; MAX_DIM]>> = Vec::new();
    for name in sets {
        if name == "random" {
            // Root mean square over independent seeds (one realisation is noisy).
            let mut acc = vec![[0.0f64; MAX_DIM]; sizes.len()];
            for k in 0..RANDOM_SEEDS {
                for (a, t) in acc.iter_mut().zip(warnock_prefixes(&random_or(name, nmax, SEED + k)?, &sizes)) {
                    for d in 0..MAX_DIM {
                        a[d] += t[d] / RANDOM_SEEDS as f64;
                    }
                }
            }
            t2.push(acc);
        } else if name == "hammersley" {
            // A different point set for every N.
            let mut v = Vec::new();
            for &n in &sizes {
                v.extend(warnock_prefixes(&point_set(name, n)?, &[n]));
            }
            t2.push(v);
        } else {
            t2.push(warnock_prefixes(&point_set(name, nmax)?, &sizes));
        }
    }
    let mut rows = Vec::new();
    let mut plots = Vec::new();
    let curve = |si: usize, d: usize| -> Vec<(f64, f64)> {
        sizes.iter().enumerate().map(|(i, &n)| (n as f64, t2[si][i][d - 1].max(0.0).sqrt())).collect()
    };
    for d in 2..=MAX_DIM {
        let random_t = t2[0].last().map(|t| t[d - 1].max(0.0).sqrt()).unwrap_or(f64::NAN);
        let fit = |c: &[(f64, f64)]| log_log_slope(&c.iter().copied().filter(|p| p.0 >= FIT_FROM as f64).collect::<Vec<_>>());
        let fit_n: Vec<f64> = sizes.iter().map(|&n| n as f64).filter(|&n| n >= FIT_FROM as f64).collect();
        rows.push(slope_row(format!("discrepancy/l2/d{d}/random/slope"), fit(&curve(0, d)), -0.5, Outcome::Pass));
        for (si, name) in sets.iter().enumerate().skip(1) {
            if name.starts_with("sobol") && d > SOBOL_MAX_DIM {
                continue;
            }
            let expected = if matches!(*name, "diagonal" | "sobol-unnested") { Outcome::Fail } else { Outcome::Pass };
            let c = curve(si, d);
            let t = c.last().map(|p| p.1).unwrap_or(f64::NAN);
            let ratio = random_t / t;
            rows.push(TestRow::new(format!("discrepancy/l2/d{d}/{name}/ratio"), ratio, None, expected, ratio >= MARGIN));
            // The diagonal set is held to the Halton rate it fails to reach.
            let k = if *name == "hammersley" || name.starts_with("sobol") { (d as f64 - 1.0) / 2.0 } else { d as f64 / 2.0 };
            rows.push(slope_row(format!("discrepancy/l2/d{d}/{name}/slope"), fit(&c), theory_slope(k, &fit_n), expected));
        }
        let mut series: Vec<Series> = sets
            .iter()
            .take(4)
            .enumerate()
            .filter(|(_, name)| d <= SOBOL_MAX_DIM || !name.starts_with("sobol"))
            .map(|(si, name)| Series { name: name.to_string(), points: curve(si, d) })
            .collect();
        series.push(Series {
            name: "random, expected".into(),
            points: sizes.iter().map(|&n| (n as f64, random_expected_t2(d, n).sqrt())).collect(),
        });
        plots.push((
            format!("discrepancy_l2_d{d}"),
            LinePlot {
                title: format!("L2-star discrepancy, {d} dimensions"),
                x_label: "points N".into(),
                y_label: "T (Warnock)".into(),
                log_x: true,
                log_y: true,
                series,
            },
        ));
    }
    // Exact 2-D star discrepancy.
    let star_sizes: Vec<usize> = (4..=s.pick(10, 12)).map(|k| 1usize << k).collect();
    let mut star_series = Vec::new();
    for name in ["random", "halton", "hammersley", "sobol"] {
        let mut c = Vec::new();
        for &n in &star_sizes {
            let p: Vec<[f64; 2]> = point_set(name, n)?.iter().map(|p| [p[0], p[1]]).collect();
            c.push((n as f64, star_discrepancy_2d(&p)));
        }
        let from = FIT_FROM as f64 / 4.0;
        let sl = log_log_slope(&c.iter().copied().filter(|p| p.0 >= from).collect::<Vec<_>>());
        let fit_n: Vec<f64> = star_sizes.iter().map(|&n| n as f64).filter(|&n| n >= from).collect();
        let theory = match name {
            "random" => -0.5,
            "halton" => theory_slope(2.0, &fit_n),
            // A scrambled (0, 2)-sequence: its power-of-two prefixes are (0, m, 2)-nets.
            _ => theory_slope(1.0, &fit_n),
        };
        rows.push(slope_row(format!("discrepancy/star2d/{name}/slope"), sl, theory, Outcome::Pass));
        star_series.push(Series { name: name.into(), points: c });
    }
    let rnd = star_series[0].points.last().map(|p| p.1).unwrap_or(f64::NAN);
    for sr in &star_series[1..] {
        let ratio = rnd / sr.points.last().map(|p| p.1).unwrap_or(f64::NAN);
        rows.push(TestRow::new(format!("discrepancy/star2d/{}/ratio", sr.name), ratio, None, Outcome::Pass, ratio >= MARGIN));
    }
    plots.push((
        "discrepancy_star_2d".into(),
        LinePlot {
            title: "Exact star discrepancy, 2 dimensions".into(),
            x_label: "points N".into(),
            y_label: "D*".into(),
            log_x: true,
            log_y: true,
            series: star_series,
        },
    ));
    Ok(FamilyReport { rows, plots })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over a fine grid of box corners (a lower bound of D* that reaches
    /// it on the grid containing every coordinate).
    fn brute_star(pts: &[[f64; 2]]) -> f64 {
        let mut cand: Vec<f64> = pts.iter().flat_map(|p| [p[0], p[1]]).collect();
        cand.push(1.0);
        let n = pts.len() as f64;
        let mut best = 0.0f64;
        for &x in &cand {
            for &y in &cand {
                let open = pts.iter().filter(|p| p[0] < x && p[1] < y).count() as f64;
                let closed = pts.iter().filter(|p| p[0] <= x && p[1] <= y).count() as f64;
                best = best.max(x * y - open / n).max(closed / n - x * y);
            }
        }
        best
    }

    #[test]
    fn star_discrepancy_matches_brute_force() {
        assert!((star_discrepancy_2d(&[[0.5, 0.5]]) - 0.75).abs() < 1e-12);
        let pts: Vec<[f64; 2]> = point_set("random", 40).unwrap().iter().map(|p| [p[0], p[1]]).collect();
        assert!((star_discrepancy_2d(&pts) - brute_star(&pts)).abs() < 1e-12);
        let pts: Vec<[f64; 2]> = point_set("hammersley", 32).unwrap().iter().map(|p| [p[0], p[1]]).collect();
        assert!((star_discrepancy_2d(&pts) - brute_star(&pts)).abs() < 1e-12);
    }

    #[test]
    fn warnock_matches_direct_formula_and_known_values() {
        // One point at the origin corner c: T² in 1-D of {c} is 1/3 − (1 − c²) + (1 − c).
        let c = 0.3;
        let t2 = warnock_prefixes(&[[c; MAX_DIM]], &[1]);
        assert!((t2[0][0] - (1.0 / 3.0 - (1.0 - c * c) + (1.0 - c))).abs() < 1e-12);
        // Prefix sums agree with separate evaluations.
        let pts = point_set("halton", 64).unwrap();
        let all = warnock_prefixes(&pts, &[16, 64]);
        let sep = warnock_prefixes(&pts[..16], &[16]);
        for k in 0..MAX_DIM {
            assert!((all[0][k] - sep[0][k]).abs() < 1e-15);
            assert!(all[1][k] > 0.0);
        }
        // Random points: the squared discrepancy averages to its expectation.
        let mut mean = 0.0;
        for seed in 0..200 {
            let p = points(&mut RandomSampler::new(seed), 32);
            mean += warnock_prefixes(&p, &[32])[0][1] / 200.0;
        }
        let e = random_expected_t2(2, 32);
        assert!((mean / e - 1.0).abs() < 0.15, "{mean} vs {e}");
    }
}

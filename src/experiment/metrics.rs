//! Error figures beyond the plain means of `cell.rs`: robust metrics (relative MSE
//! with the largest per-pixel errors discarded, SMAPE, the share of the error carried
//! by the worst pixel), block-averaged signed relative error (the bias you can see,
//! and its worst block), the reference's own noise from two independent half-renders,
//! and time-to-error on a configuration's error/time curve.

use super::cell::REL_EPS;
use crate::film::Film;
use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

/// Fraction of pixels (largest per-pixel relative errors) discarded by the trimmed
/// relative MSE: 0.01 %, as path-guiding papers do (at least one pixel).
pub const TRIM_FRACTION: f64 = 1e-4;
/// ε in SMAPE: mean over pixels and channels of |x − r| / (|x| + |r| + ε).
pub const SMAPE_EPS: f64 = 1e-2;
/// Side of the square blocks of the signed error image (pixels).
pub const BLOCK: u32 = 16;
/// Blocks whose reference mean (over pixels and RGB) is at most this are not
/// measured: their relative error is noise over black.
pub const BLOCK_MIN_REF: f64 = 0.005;
/// Signed relative error at which the diverging colour map saturates (±10 %).
pub const SIGNED_RANGE: f64 = 0.1;
/// A cell whose single worst pixel carries more than this share of its relative
/// squared error is flagged: its relMSE measures that pixel, not the strategy.
pub const PIXEL_SHARE_FLAG: f64 = 0.1;

/// Robust and local error figures of one image against the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RobustMetrics {
    /// Relative MSE with the top [`TRIM_FRACTION`] of per-pixel errors discarded.
    pub relmse_trimmed: f64,
    /// Symmetric mean absolute percentage error (0–1).
    pub smape: f64,
    /// Share of the summed per-pixel relative squared error carried by the worst pixel.
    pub max_pixel_share: f64,
    /// Worst |signed relative error| of a [`BLOCK`]-px block mean over blocks whose
    /// reference mean exceeds [`BLOCK_MIN_REF`] (signed: its sign is kept).
    pub worst_block: f64,
    /// Top-left pixel of that block.
    pub worst_block_at: [u32; 2],
    /// Ratio of the image means, test / reference, over all pixels and channels
    /// (0 in records written before it was measured).
    #[serde(default)]
    pub mean_ratio: f64,
    /// The worst block's difference of means in standard errors of that difference,
    /// estimated from the spread of the per-pixel differences inside the block (as
    /// `photonlab diff --block`): well beyond ±3 the block's error is bias, not noise.
    #[serde(default)]
    pub worst_block_z: f64,
}

fn same_size(a: &Film, b: &Film) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!("image is {}x{} but the reference is {}x{}", a.width, a.height, b.width, b.height);
    }
    Ok(())
}

/// Per-pixel relative squared error, mean over RGB: (x − r)² / (r² + ε).
pub fn pixel_relerr(img: &Film, reference: &Film) -> Vec<f64> {
    img.pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(p, q)| {
            (0..3)
                .map(|c| {
                    let (x, r) = (p[c] as f64, q[c] as f64);
                    (x - r) * (x - r) / (r * r + REL_EPS)
                })
                .sum::<f64>()
                / 3.0
        })
        .collect()
}

/// Block means of the signed relative error: `sum(x) / sum(r) − 1` over each block's
/// pixels and channels, `None` where the block's reference mean is ≤ [`BLOCK_MIN_REF`].
/// Returns (blocks across, blocks down, values row-major).
pub fn block_errors(img: &Film, reference: &Film) -> Result<(u32, u32, Vec<Option<f64>>)> {
    same_size(img, reference)?;
    let (bw, bh) = (img.width.div_ceil(BLOCK), img.height.div_ceil(BLOCK));
    let mut sx = vec![0.0f64; (bw * bh) as usize];
    let mut sr = vec![0.0f64; (bw * bh) as usize];
    let mut n = vec![0u32; (bw * bh) as usize];
    for y in 0..img.height {
        for x in 0..img.width {
            let b = ((y / BLOCK) * bw + x / BLOCK) as usize;
            let (p, q) = (img.get(x, y), reference.get(x, y));
            for c in 0..3 {
                sx[b] += p[c] as f64;
                sr[b] += q[c] as f64;
            }
            n[b] += 1;
        }
    }
    let vals = (0..sx.len()).map(|b| (sr[b] / (3.0 * n[b] as f64) > BLOCK_MIN_REF).then(|| sx[b] / sr[b] - 1.0)).collect();
    Ok((bw, bh, vals))
}

/// All of [`RobustMetrics`] for one image.
pub fn robust_metrics(img: &Film, reference: &Film) -> Result<RobustMetrics> {
    same_size(img, reference)?;
    let mut e = pixel_relerr(img, reference);
    let n = e.len();
    let total: f64 = e.iter().sum();
    let max = e.iter().copied().fold(0.0f64, f64::max);
    e.sort_by(|a, b| b.total_cmp(a));
    let drop = ((n as f64 * TRIM_FRACTION).ceil() as usize).min(n.saturating_sub(1));
    let kept = &e[drop..];
    let relmse_trimmed = kept.iter().sum::<f64>() / kept.len().max(1) as f64;
    let mut smape = 0.0;
    for (p, q) in img.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let (x, r) = (p[c] as f64, q[c] as f64);
            smape += (x - r).abs() / (x.abs() + r.abs() + SMAPE_EPS);
        }
    }
    let (bw, _, blocks) = block_errors(img, reference)?;
    let mut worst = (0.0f64, [0u32, 0u32]);
    for (i, b) in blocks.iter().enumerate() {
        if let Some(v) = b
            && v.abs() > worst.0.abs()
        {
            worst = (*v, [(i as u32 % bw) * BLOCK, (i as u32 / bw) * BLOCK]);
        }
    }
    Ok(RobustMetrics {
        relmse_trimmed,
        smape: smape / (n * 3).max(1) as f64,
        max_pixel_share: if total > 0.0 { max / total } else { 0.0 },
        worst_block: worst.0,
        worst_block_at: worst.1,
        mean_ratio: mean_ratio(img, reference),
        worst_block_z: if blocks.iter().any(|b| b.is_some()) { block_z(img, reference, worst.1) } else { 0.0 },
    })
}

/// Ratio of the image means (test / reference) over all pixels and channels; 0 for a
/// black reference (records are JSON, which has no NaN).
pub fn mean_ratio(img: &Film, reference: &Film) -> f64 {
    let sum = |f: &Film| f.pixels.iter().map(|p| p.as_dvec3().element_sum()).sum::<f64>();
    let r = sum(reference);
    if r > 0.0 { sum(img) / r } else { 0.0 }
}

/// The difference of the means of the [`BLOCK`]-px block at `at` (top-left pixel),
/// over the pixels' RGB means, in standard errors: the sample variance of the
/// per-pixel differences / pixel count. ±`f64::MAX` (shown as ±∞) when the pixels
/// differ by a constant (records are JSON, which has no infinity).
pub fn block_z(img: &Film, reference: &Film, at: [u32; 2]) -> f64 {
    let (mut sd, mut sd2, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for y in at[1]..(at[1] + BLOCK).min(img.height) {
        for x in at[0]..(at[0] + BLOCK).min(img.width) {
            let d = (img.get(x, y).as_dvec3().element_sum() - reference.get(x, y).as_dvec3().element_sum()) / 3.0;
            sd += d;
            sd2 += d * d;
            n += 1.0;
        }
    }
    if n < 2.0 {
        return 0.0;
    }
    let var = ((sd2 - sd * sd / n) / (n - 1.0)).max(0.0);
    let mean = sd / n;
    if mean == 0.0 {
        0.0
    } else if var <= 1e-20 * mean * mean {
        // No spread beyond rounding: a constant offset.
        mean.signum() * f64::MAX
    } else {
        mean / (var / n).sqrt()
    }
}

/// Errors of one component image (e.g. `indirect`) against the component reference.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ComponentMetrics {
    /// Component name.
    pub name: String,
    /// Relative MSE.
    pub relmse: f64,
    /// Robust and block errors.
    pub robust: RobustMetrics,
}

/// [`ComponentMetrics`] of `img` against `reference`.
pub fn component_metrics(name: &str, img: &Film, reference: &Film) -> Result<ComponentMetrics> {
    let relmse = pixel_relerr(img, reference).iter().sum::<f64>() / img.pixels.len().max(1) as f64;
    Ok(ComponentMetrics { name: name.to_string(), relmse, robust: robust_metrics(img, reference)? })
}

/// Diverging colour map (Moreland's cool–warm): −1 blue, 0 light grey, +1 red.
pub fn diverging(t: f64) -> [u8; 3] {
    const NEG: [f64; 3] = [59.0, 76.0, 192.0];
    const MID: [f64; 3] = [221.0, 221.0, 221.0];
    const POS: [f64; 3] = [180.0, 4.0, 38.0];
    let t = if t.is_nan() { 0.0 } else { t.clamp(-1.0, 1.0) };
    let (end, f) = if t < 0.0 { (NEG, -t) } else { (POS, t) };
    let mut out = [0u8; 3];
    for c in 0..3 {
        out[c] = (MID[c] * (1.0 - f) + end[c] * f).round() as u8;
    }
    out
}

/// Colour of blocks that are not measured (reference too dark).
pub const UNMEASURED: [u8; 3] = [40, 40, 40];

/// The signed, block-averaged relative error as a full-resolution PNG: each
/// [`BLOCK`]-px block one colour of [`diverging`] at error / [`SIGNED_RANGE`]
/// (blue: too dark, red: too bright), [`UNMEASURED`] where the reference is black.
pub fn signed_png(img: &Film, reference: &Film) -> Result<Vec<u8>> {
    let (bw, _, blocks) = block_errors(img, reference)?;
    let mut bytes = Vec::with_capacity(img.pixels.len() * 3);
    for y in 0..img.height {
        for x in 0..img.width {
            let b = blocks[((y / BLOCK) * bw + x / BLOCK) as usize];
            bytes.extend_from_slice(&b.map_or(UNMEASURED, |v| diverging(v / SIGNED_RANGE)));
        }
    }
    encode_png(img.width, img.height, bytes)
}

/// PNG bytes of an 8-bit RGB buffer.
pub fn encode_png(width: u32, height: u32, rgb: Vec<u8>) -> Result<Vec<u8>> {
    crate::film::encode_png_rgb8(width, height, &rgb)
}

/// Noise of a reference made as the sample-weighted mean of two independent parts
/// `a` (`na` samples) and `b` (`nb`), as the relative MSE of that mean against its
/// expectation: with σ² the per-sample variance, E[(a − b)²] = σ²(1/na + 1/nb) and
/// the mean's variance is σ²/N (N = na + nb), so it is
/// `mean((a − b)² / (m² + ε)) · na·nb / N²` (¼ for equal halves), with m the mean
/// image (the weights the cells' relMSE uses).
pub fn half_noise(a: &Film, b: &Film, na: u32, nb: u32) -> Result<f64> {
    same_size(a, b)?;
    let n = (na + nb).max(1) as f64;
    let (wa, wb) = (na as f64 / n, nb as f64 / n);
    let mut s = 0.0;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (p[c] as f64, q[c] as f64);
            let m = wa * x + wb * y;
            s += (x - y) * (x - y) / (m * m + REL_EPS);
        }
    }
    Ok(s / (a.pixels.len() * 3).max(1) as f64 * wa * wb)
}

/// What a time-to-error interpolation found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeToError {
    /// Reached at this time (seconds), interpolated log–log between two points.
    At(f64),
    /// Already met by the cheapest point (time of that point: an upper bound).
    AtMost(f64),
    /// The curve stays above the target (it flattens or ends above it).
    NotReached,
}

/// Time for a configuration's error/time curve `points` (time, relMSE; any order) to
/// reach `target`: the first crossing in time order, interpolated linearly in
/// log(time)–log(error) between the two points around it.
pub fn time_to_error(points: &[(f64, f64)], target: f64) -> TimeToError {
    let mut p: Vec<(f64, f64)> = points.iter().copied().filter(|(t, e)| t.is_finite() && e.is_finite() && *t > 0.0 && *e > 0.0).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    let Some(first) = p.first() else { return TimeToError::NotReached };
    if first.1 <= target {
        return TimeToError::AtMost(first.0);
    }
    for w in p.windows(2) {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        if e1 <= target {
            let (l0, l1, lt) = (e0.ln(), e1.ln(), target.ln());
            let f = if (l0 - l1).abs() > 0.0 { (l0 - lt) / (l0 - l1) } else { 1.0 };
            return TimeToError::At((t0.ln() + f * (t1.ln() - t0.ln())).exp());
        }
    }
    TimeToError::NotReached
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;

    fn flat(w: u32, h: u32, v: f32) -> Film {
        let mut f = Film::new(w, h);
        f.pixels.iter_mut().for_each(|p| *p = Color::splat(v));
        f
    }

    #[test]
    fn trimmed_relmse_discards_one_firefly() {
        let r = flat(100, 100, 1.0);
        let mut x = flat(100, 100, 1.1);
        x.pixels[4321] = Color::splat(50.0);
        let m = robust_metrics(&x, &r).unwrap();
        let per = 0.01 / (1.0 + REL_EPS);
        assert!((m.relmse_trimmed - per).abs() < 1e-7, "{}", m.relmse_trimmed);
        assert!(m.max_pixel_share > PIXEL_SHARE_FLAG);
        let clean = robust_metrics(&flat(100, 100, 1.1), &r).unwrap();
        assert!((clean.max_pixel_share - 1e-4).abs() < 1e-7);
        assert!((clean.smape - 0.1 / 2.11).abs() < 1e-6);
    }

    #[test]
    fn worst_block_finds_a_planted_bias_and_skips_black_blocks() {
        let mut r = flat(64, 48, 0.5);
        let mut x = r.clone();
        // A 5 % too bright block at block (2, 1); a black reference block with
        // a huge relative error that must not count.
        for y in 16..32 {
            for xx in 32..48 {
                x.pixels[(y * 64 + xx) as usize] = Color::splat(0.525);
            }
        }
        for y in 32..48 {
            for xx in 0..16 {
                r.pixels[(y * 64 + xx) as usize] = Color::ZERO;
                x.pixels[(y * 64 + xx) as usize] = Color::splat(0.001);
            }
        }
        let m = robust_metrics(&x, &r).unwrap();
        assert!((m.worst_block - 0.05).abs() < 1e-6, "{}", m.worst_block);
        assert_eq!(m.worst_block_at, [32, 16]);
        let png = signed_png(&x, &r).unwrap();
        let im = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(im.get_pixel(40, 20).0, diverging(0.5));
        assert_eq!(im.get_pixel(0, 40).0, UNMEASURED);
        assert_eq!(im.get_pixel(0, 0).0, diverging(0.0));
        assert_eq!(diverging(-1.0), [59, 76, 192]);
    }

    /// The worst block's error in standard errors: a 0.025 offset under ±0.1
    /// alternating pixel noise is 0.025 / (0.1 · √(256/255) / 16) ≈ 3.99 standard
    /// errors; the image mean ratio counts every pixel.
    #[test]
    fn worst_block_in_standard_errors_and_mean_ratio() {
        let r = flat(32, 32, 0.5);
        let mut x = r.clone();
        for y in 0..16 {
            for xx in 16..32 {
                let noise = if (xx + y) % 2 == 0 { 0.1 } else { -0.1 };
                x.pixels[(y * 32 + xx) as usize] = Color::splat(0.525 + noise);
            }
        }
        let m = robust_metrics(&x, &r).unwrap();
        assert_eq!(m.worst_block_at, [16, 0]);
        let want = 0.025 / (0.1 * (256.0f64 / 255.0).sqrt() / 16.0);
        assert!((m.worst_block_z - want).abs() < 0.01 * want, "{} vs {want}", m.worst_block_z);
        assert!((m.mean_ratio - (1.0 + 0.025 / 4.0 / 0.5)).abs() < 1e-6, "{}", m.mean_ratio);
        // Noise alone: the block's mean is exact, zero standard errors.
        let mut noisy = r.clone();
        for (i, p) in noisy.pixels.iter_mut().enumerate() {
            *p += Color::splat(if (i % 32 + i / 32) % 2 == 0 { 0.1 } else { -0.1 });
        }
        let m = robust_metrics(&noisy, &r).unwrap();
        assert!(m.worst_block_z.abs() < 1e-3 && (m.mean_ratio - 1.0).abs() < 1e-6, "{m:?}");
        assert_eq!(mean_ratio(&flat(4, 4, 1.0), &flat(4, 4, 0.0)), 0.0);
        // A constant offset has no spread: the largest finite z, which a JSON record keeps.
        let m = robust_metrics(&flat(16, 16, 0.6), &flat(16, 16, 0.5)).unwrap();
        assert!(m.worst_block_z > 1e300, "{}", m.worst_block_z);
        let back: RobustMetrics = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn half_noise_of_independent_halves() {
        // Two halves with independent ±0.1 noise around 1: σ²_half = 0.01, so the
        // mean's variance is 0.005 and its relative MSE ≈ 0.005 / (1 + ε).
        let mut a = flat(200, 200, 1.0);
        let mut b = a.clone();
        let mut s = 12345u64;
        let mut sign = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            if s >> 63 == 0 { 0.1 } else { -0.1 }
        };
        for (p, q) in a.pixels.iter_mut().zip(b.pixels.iter_mut()) {
            *p += Color::new(sign(), sign(), sign());
            *q += Color::new(sign(), sign(), sign());
        }
        let n = half_noise(&a, &b, 8, 8).unwrap();
        assert!((n - 0.005 / (1.0 + REL_EPS)).abs() < 3e-4, "{n}");
    }

    #[test]
    fn time_to_error_interpolates_and_says_not_reached() {
        let curve = [(1.0, 0.1), (4.0, 0.025), (16.0, 0.02)];
        match time_to_error(&curve, 0.05) {
            TimeToError::At(t) => assert!((t - 2.0).abs() < 1e-9, "{t}"),
            o => panic!("{o:?}"),
        }
        assert_eq!(time_to_error(&curve, 0.01), TimeToError::NotReached);
        assert_eq!(time_to_error(&curve, 0.5), TimeToError::AtMost(1.0));
        assert_eq!(time_to_error(&[], 0.5), TimeToError::NotReached);
    }
}

//! One cell: render a configuration, time it, measure it against the reference, and
//! write its image, error image and record. Also the error metrics themselves.

use super::manifest::{Cell, STRATEGIES_AOV};
use crate::config::RenderConfig;
use crate::film::{Film, write_atomic};
use crate::pipeline::render_scene_observed;
use crate::scene::Scene;
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// ε in the relative MSE (squared error / (reference² + ε)): keeps near-black pixels
/// from dominating; the same value as `photonlab diff`.
pub const REL_EPS: f64 = 1e-2;

/// Integrator-counter prefixes of the progressive curve: `time_at_pass_N` (seconds,
/// counted like `time_total_s`) and `relmse_at_pass_N` for each N of `record_passes`.
pub const PASS_TIME: &str = "time_at_pass_";
/// See [`PASS_TIME`].
pub const PASS_RELMSE: &str = "relmse_at_pass_";

/// The (time, relative MSE) points a progressive cell recorded, in pass order.
pub fn pass_curve(extra: &BTreeMap<String, f64>) -> Vec<(u32, f64, f64)> {
    let mut v: Vec<(u32, f64, f64)> = extra
        .iter()
        .filter_map(|(k, &t)| {
            let p: u32 = k.strip_prefix(PASS_TIME)?.parse().ok()?;
            Some((p, t, *extra.get(&format!("{PASS_RELMSE}{p}"))?))
        })
        .collect();
    v.sort_by_key(|x| x.0);
    v
}

/// Error of an image against a reference, averaged over pixels and RGB channels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorMetrics {
    /// Mean squared error.
    pub mse: f64,
    /// Root mean squared error.
    pub rmse: f64,
    /// Relative MSE: mean of (x − r)² / (r² + ε).
    pub relmse: f64,
    /// Mean absolute error.
    pub mae: f64,
}

/// Compares `img` with `reference` (same size).
pub fn error_metrics(img: &Film, reference: &Film) -> Result<ErrorMetrics> {
    same_size(img, reference)?;
    let (mut se, mut rel, mut ae) = (0.0f64, 0.0f64, 0.0f64);
    for (p, q) in img.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let (x, r) = (p[c] as f64, q[c] as f64);
            let d = x - r;
            se += d * d;
            rel += d * d / (r * r + REL_EPS);
            ae += d.abs();
        }
    }
    let n = (img.pixels.len() * 3).max(1) as f64;
    Ok(ErrorMetrics { mse: se / n, rmse: (se / n).sqrt(), relmse: rel / n, mae: ae / n })
}

fn same_size(a: &Film, b: &Film) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!("image is {}x{} but the reference is {}x{}", a.width, a.height, b.width, b.height);
    }
    Ok(())
}

/// Split of the mean error of repeated renders into squared bias and variance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BiasVariance {
    /// Squared bias (radiance²); `bias2 + variance` = mean MSE of the repeats.
    pub bias2: f64,
    /// Variance of one render (radiance²).
    pub variance: f64,
    /// The same split with every pixel weighted by 1 / (ref² + ε), so
    /// `rel_bias2 + rel_variance` = mean relative MSE of the repeats.
    pub rel_bias2: f64,
    /// Relative variance.
    pub rel_variance: f64,
}

/// Split of the mean MSE of `R ≥ 2` independent renders into squared bias and
/// variance, per pixel and channel, averaged: with m̄ the mean image and s² the
/// unbiased sample variance, `variance = mean(s²)` and
/// `bias² = mean((m̄ − ref)²) − variance / R`, so `bias² + variance` is exactly the
/// mean of the repeats' MSEs. Both are unbiased estimates (bias² may come out
/// slightly negative for an unbiased method). `None` for fewer than two images.
pub fn bias_variance(images: &[&Film], reference: &Film) -> Result<Option<BiasVariance>> {
    let r = images.len();
    if r < 2 {
        return Ok(None);
    }
    for i in images {
        same_size(i, reference)?;
    }
    let mut out = BiasVariance::default();
    for (p, q) in reference.pixels.iter().enumerate() {
        for c in 0..3 {
            let vals = images.iter().map(|im| im.pixels[p][c] as f64);
            let mean = vals.clone().sum::<f64>() / r as f64;
            let s2 = vals.map(|v| (v - mean) * (v - mean)).sum::<f64>() / (r - 1) as f64;
            let d = mean - q[c] as f64;
            let b2 = d * d - s2 / r as f64;
            let w = 1.0 / ((q[c] as f64).powi(2) + REL_EPS);
            out.bias2 += b2;
            out.variance += s2;
            out.rel_bias2 += w * b2;
            out.rel_variance += w * s2;
        }
    }
    let n = (reference.pixels.len() * 3).max(1) as f64;
    out.bias2 /= n;
    out.variance /= n;
    out.rel_bias2 /= n;
    out.rel_variance /= n;
    Ok(Some(out))
}

/// Colour map for error images: black → purple → red → orange → pale yellow.
fn heat(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [[0.0, 0.0, 0.02], [0.33, 0.06, 0.43], [0.73, 0.21, 0.33], [0.98, 0.55, 0.04], [0.99, 1.0, 0.64]];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let mut out = [0u8; 3];
    for c in 0..3 {
        out[c] = ((STOPS[i][c] * (1.0 - f) + STOPS[i + 1][c] * f) * 255.0).round() as u8;
    }
    out
}

/// Lowest and highest per-pixel relative error of the false-colour scale (log).
pub const RELERR_RANGE: (f64, f64) = (1e-3, 1.0);

/// False-colour image of the per-pixel relative error
/// `sqrt(mean_c (x − r)² / (r² + ε))` on a log scale from 10⁻³ (black) to 1 (pale
/// yellow), PNG-encoded.
pub fn relerr_png(img: &Film, reference: &Film) -> Result<Vec<u8>> {
    same_size(img, reference)?;
    let (lo, hi) = (RELERR_RANGE.0.log10(), RELERR_RANGE.1.log10());
    let mut bytes = Vec::with_capacity(img.pixels.len() * 3);
    for (p, q) in img.pixels.iter().zip(&reference.pixels) {
        let mut s = 0.0;
        for c in 0..3 {
            let d = (p[c] - q[c]) as f64;
            s += d * d / ((q[c] as f64).powi(2) + REL_EPS);
        }
        let e = (s / 3.0).sqrt();
        let t = if e.is_nan() { 1.0 } else { (e.max(1e-12).log10() - lo) / (hi - lo) };
        bytes.extend_from_slice(&heat(t));
    }
    crate::film::encode_png_rgb8(img.width, img.height, &bytes).context("cannot encode the error image")
}

/// Everything recorded about one finished cell (`cells/STEM.json`, one row of the tables).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRecord {
    /// File stem of the cell's outputs.
    pub cell: String,
    /// Position in expansion order.
    pub index: usize,
    /// Configuration index.
    pub config_index: usize,
    /// Configuration label.
    pub label: String,
    /// Strategy (plot line).
    pub group: String,
    /// Repeat number.
    pub repeat: u32,
    /// Seed used.
    pub seed: u64,
    /// Swept values (`name` for named configurations).
    pub values: BTreeMap<String, serde_json::Value>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Errors against the reference.
    pub metrics: ErrorMetrics,
    /// Robust and block errors against the reference (absent in older records).
    #[serde(default)]
    pub robust: super::metrics::RobustMetrics,
    /// Errors of the measured component (manifest `component`), if any.
    #[serde(default)]
    pub component: Option<super::metrics::ComponentMetrics>,
    /// Names of the per-strategy images written (`cells/STEM.strategies-NAME.{exr,png}`:
    /// `sS-tT`, `sS-tT-unweighted`, `merge`) when the manifest asked for them and the
    /// integrator has them; `None` when not rendered.
    #[serde(default)]
    pub strategies: Option<Vec<String>>,
    /// Acceleration-structure build, seconds.
    pub accel_build_s: f64,
    /// Integrator pre-pass (photon pass, precomputation, cache prefill), seconds.
    pub preprocess_s: f64,
    /// Render pass, seconds.
    pub render_s: f64,
    /// Sum of the three, seconds.
    pub time_total_s: f64,
    /// Closest-hit rays of the render pass.
    pub camera_rays: u64,
    /// Shadow rays of the render pass.
    pub shadow_rays: u64,
    /// Worker threads.
    pub threads: usize,
    /// Memory of the accelerator, bytes.
    pub accel_bytes: usize,
    /// Samples dropped as NaN/inf.
    pub nonfinite_samples: u64,
    /// Integrator counters and phase times (photons emitted/stored, cache entries, map bytes, …).
    pub extra: BTreeMap<String, f64>,
    /// The exact configuration rendered.
    pub config: RenderConfig,
    /// Key of the reference the errors are measured against.
    pub reference_key: String,
    /// photonlab version.
    pub version: String,
}

/// Paths of a cell's outputs in `dir/cells/`.
pub struct CellPaths {
    /// Record (written last: its presence marks the cell finished).
    pub json: PathBuf,
    /// Linear image.
    pub exr: PathBuf,
    /// sRGB image.
    pub png: PathBuf,
    /// False-colour relative error.
    pub relerr: PathBuf,
    /// Block-averaged signed relative error (diverging colours).
    pub signed: PathBuf,
}

impl CellPaths {
    /// Linear and sRGB paths of the per-strategy image `name` (`s1-t2`, `merge`, …).
    pub fn strategy(&self, name: &str) -> (PathBuf, PathBuf) {
        let base = format!("{STRATEGIES_AOV}-{name}");
        (self.exr.with_extension(format!("{base}.exr")), self.exr.with_extension(format!("{base}.png")))
    }

    /// Paths for a cell stem under an experiment directory.
    pub fn new(dir: &Path, stem: &str) -> Self {
        let d = dir.join("cells");
        CellPaths {
            json: d.join(format!("{stem}.json")),
            exr: d.join(format!("{stem}.exr")),
            png: d.join(format!("{stem}.png")),
            relerr: d.join(format!("{stem}.relerr.png")),
            signed: d.join(format!("{stem}.signed.png")),
        }
    }
}

/// Reads a finished cell's record if it exists, parses, and matches `cell` and the
/// reference; anything else (absent, torn, stale) means the cell must run.
pub fn finished(dir: &Path, cell: &Cell, reference_key: &str) -> Option<CellRecord> {
    let p = CellPaths::new(dir, &cell.stem);
    let text = std::fs::read_to_string(&p.json).ok()?;
    let rec: CellRecord = serde_json::from_str(&text).ok()?;
    (rec.cell == cell.stem
        && rec.config == cell.config
        && rec.reference_key == reference_key
        && p.exr.is_file()
        && (!cell.strategies || rec.strategies.is_some()))
    .then_some(rec)
}

/// Renders one cell, writes its images and then its record (atomically, last).
pub fn run_cell(
    scene: &Scene,
    cell: &Cell,
    reference: &Film,
    component_ref: Option<&Film>,
    reference_key: &str,
    dir: &Path,
    quiet: bool,
) -> Result<CellRecord> {
    // Progressive integrators: the error after each pass of `record_passes`.
    let mut progress: Vec<(u32, f64, ErrorMetrics)> = Vec::new();
    let record = &cell.config.record_passes;
    let mut on_pass = |p: u32, t: f64, f: &Film| {
        if record.contains(&p)
            && let Ok(e) = error_metrics(f, reference)
        {
            progress.push((p, t, e));
        }
    };
    let mut aovs: Vec<String> = cell.component.iter().cloned().collect();
    if cell.strategies {
        aovs.push(STRATEGIES_AOV.to_string());
    }
    let mut o =
        render_scene_observed(scene.clone(), &cell.config, quiet, &aovs, &mut on_pass).with_context(|| format!("cell `{}`", cell.stem))?;
    for (p, t, e) in progress {
        o.extra.insert(format!("{PASS_TIME}{p}"), o.timings.accel_build_s + o.timings.preprocess_s + t);
        o.extra.insert(format!("{PASS_RELMSE}{p}"), e.relmse);
    }
    // Per-strategy images (an extra, untimed render after the timed one).
    let paths = CellPaths::new(dir, &cell.stem);
    let prefix = format!("{STRATEGIES_AOV}-");
    let mut strategies = cell.strategies.then(Vec::new);
    let mut comp_img = None;
    for (name, img) in std::mem::take(&mut o.aovs) {
        match (name.strip_prefix(&prefix), strategies.as_mut()) {
            (Some(n), Some(list)) => {
                let (exr, png) = paths.strategy(n);
                img.write_exr(&exr)?;
                img.write_png(&png)?;
                list.push(n.to_string());
            }
            _ => comp_img = Some((name, img)),
        }
    }
    // The measured component (an extra render pass after the timed one).
    let component = match (comp_img, component_ref) {
        (Some((name, img)), Some(r)) => {
            img.write_exr(&CellPaths::new(dir, &cell.stem).exr.with_extension(format!("{name}.exr")))?;
            Some(super::metrics::component_metrics(&name, &img, r)?)
        }
        _ => None,
    };
    let metrics = error_metrics(&o.film, reference).with_context(|| format!("cell `{}`", cell.stem))?;
    o.film.write_exr(&paths.exr)?;
    o.film.write_png(&paths.png)?;
    write_atomic(&paths.relerr, &relerr_png(&o.film, reference)?)?;
    write_atomic(&paths.signed, &super::metrics::signed_png(&o.film, reference)?)?;
    let robust = super::metrics::robust_metrics(&o.film, reference)?;
    let t = &o.timings;
    let rays = o.rays();
    let rec = CellRecord {
        cell: cell.stem.clone(),
        index: cell.index,
        config_index: cell.config_index,
        label: cell.label.clone(),
        group: cell.group.clone(),
        repeat: cell.repeat,
        seed: cell.config.seed,
        values: cell.values.iter().map(|(k, v)| (k.clone(), serde_json::to_value(v).unwrap_or(serde_json::Value::Null))).collect(),
        width: o.film.width,
        height: o.film.height,
        metrics,
        robust,
        component,
        strategies,
        accel_build_s: t.accel_build_s,
        preprocess_s: t.preprocess_s,
        render_s: t.render_s,
        time_total_s: t.accel_build_s + t.preprocess_s + t.render_s,
        camera_rays: rays.rays,
        shadow_rays: rays.shadow_rays,
        threads: o.threads,
        accel_bytes: o.accel_bytes,
        nonfinite_samples: o.stats.nonfinite_samples,
        extra: o.extra,
        config: cell.config.clone(),
        reference_key: reference_key.to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    write_atomic(&paths.json, serde_json::to_string_pretty(&rec)?.as_bytes())?;
    Ok(rec)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;

    fn film(vals: &[f32]) -> Film {
        let mut f = Film::new(vals.len() as u32, 1);
        for (p, v) in f.pixels.iter_mut().zip(vals) {
            *p = Color::splat(*v);
        }
        f
    }

    #[test]
    fn metrics_of_known_images() {
        let r = film(&[1.0, 0.0, 2.0, 0.5]);
        let x = film(&[1.5, 0.0, 1.0, 0.5]);
        let m = error_metrics(&x, &r).unwrap();
        // Squared errors per pixel: 0.25, 0, 1, 0 (same on every channel).
        assert!((m.mse - 1.25 / 4.0).abs() < 1e-12);
        assert!((m.rmse - (1.25f64 / 4.0).sqrt()).abs() < 1e-12);
        assert!((m.mae - 1.5 / 4.0).abs() < 1e-12);
        let rel = (0.25 / (1.0 + REL_EPS) + 1.0 / (4.0 + REL_EPS)) / 4.0;
        assert!((m.relmse - rel).abs() < 1e-12);
        assert_eq!(error_metrics(&r, &r).unwrap(), ErrorMetrics::default());
        assert!(error_metrics(&film(&[1.0]), &r).is_err());
    }

    /// `repeats` noisy copies of `reference` (uniform noise in [−1, 1], variance 1/3)
    /// shifted by `offset`, from a fixed-seed generator.
    fn noisy(reference: &Film, repeats: usize, offset: f32) -> Vec<Film> {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        (0..repeats)
            .map(|_| {
                let mut f = reference.clone();
                for p in &mut f.pixels {
                    *p += Color::new(next(), next(), next()) + Color::splat(offset);
                }
                f
            })
            .collect()
    }

    #[test]
    fn bias_variance_split() {
        let r = film(&vec![1.0; 2000]);
        for (offset, want_bias2) in [(0.0, 0.0), (0.3, 0.09)] {
            let imgs = noisy(&r, 8, offset);
            let refs: Vec<&Film> = imgs.iter().collect();
            let bv = bias_variance(&refs, &r).unwrap().unwrap();
            let (b2, var) = (bv.bias2, bv.variance);
            // A planted offset shows up as bias², the noise as variance 1/3.
            assert!((b2 - want_bias2).abs() < 0.01, "offset {offset}: bias² {b2}");
            assert!((var - 1.0 / 3.0).abs() < 0.02, "offset {offset}: variance {var}");
            // bias² + variance is exactly the mean of the repeats' MSEs.
            let mean_mse = refs.iter().map(|i| error_metrics(i, &r).unwrap().mse).sum::<f64>() / refs.len() as f64;
            assert!((b2 + var - mean_mse).abs() < 1e-9);
            let mean_rel = refs.iter().map(|i| error_metrics(i, &r).unwrap().relmse).sum::<f64>() / refs.len() as f64;
            assert!((bv.rel_bias2 + bv.rel_variance - mean_rel).abs() < 1e-9);
            assert!((bv.rel_bias2 - b2 / (1.0 + REL_EPS)).abs() < 1e-9);
        }
        assert!(bias_variance(&[&r], &r).unwrap().is_none());
    }

    #[test]
    fn error_image_scale() {
        assert_eq!(heat(0.0), [0, 0, 5]);
        assert_eq!(heat(2.0), heat(1.0));
        let r = film(&[1.0, 1.0]);
        let png = relerr_png(&film(&[1.0, 3.0]), &r).unwrap();
        let im = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(im.get_pixel(0, 0).0, heat(0.0));
        assert_eq!(im.get_pixel(1, 0).0, heat(1.0));
    }
}

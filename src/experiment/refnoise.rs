//! The reference's own noise. A rendered reference is the exact sum of sample
//! ranges ([`crate::accumulate`]); its noise comes from the difference of two halves
//! of those samples — the first and second half of the range when rendered here
//! (two parts instead of one: the same bits), or the shards' parts grouped into
//! ranges below and above spp/2 — as relative MSE ([`half_noise`]). With the
//! `random` sampler the halves are independent; with the low-discrepancy samplers
//! the two halves of one sequence are negatively correlated, which makes the
//! estimate err high (more cells flagged, never fewer).
//!
//! A measured component's reference is rendered whole (it needs the integrator's
//! extra image) as two halves with independent seeds.

use super::metrics::half_noise;
use crate::accumulate::{Part, SampleRange, accumulate, check_range, part_preview, parts_dir, reference_from_parts, render_part};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::pipeline::render_scene_with_aovs;
use crate::scene::Scene;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Seed of the second half of a component reference: the seed with these bits flipped.
pub const SECOND_HALF_SEED: u64 = 0x9E37_79B9_7F4A_7C15;

/// A reference image and its noise, and the same for a measured component.
#[derive(Clone, Debug)]
pub struct RefImages {
    /// The full image.
    pub film: Film,
    /// Its noise as relative MSE, when known.
    pub noise: Option<f64>,
    /// The component's image and noise, when one is measured.
    pub component: Option<(Film, Option<f64>)>,
}

/// The reference through exact sums (see [`reference_from_parts`]: `None` while
/// other shards' parts are missing and `finish` is false) and its noise; returns
/// (image, noise, rendered now).
pub fn reference_with_noise(
    scene: &Scene,
    cfg: &RenderConfig,
    key: &str,
    ref_exr: &Path,
    shard: Option<(usize, usize)>,
    finish: bool,
    quiet: bool,
) -> Result<(Option<Film>, Option<f64>, bool)> {
    let sharded = shard.is_some_and(|(_, n)| n > 1);
    let whole = SampleRange { start: 0, end: cfg.spp };
    if !sharded && cfg.spp >= 2 && check_range(cfg, whole).is_ok() {
        let mid = cfg.spp / 2;
        let mut parts = Vec::new();
        for range in [SampleRange { start: 0, end: mid }, SampleRange { start: mid, end: cfg.spp }] {
            if !quiet {
                eprintln!("rendering reference samples {range} of {} ({} integrator)", cfg.spp, cfg.integrator);
            }
            let o = render_part(scene.clone(), cfg, range, key, quiet).with_context(|| format!("rendering reference samples {range}"))?;
            parts.push((PathBuf::from(format!("samples {range}")), o.part));
        }
        let film = accumulate(&parts)?;
        let noise = halves_noise(&parts.iter().map(|(_, p)| p).collect::<Vec<_>>(), cfg.spp)?;
        return Ok((Some(film), noise, true));
    }
    let (film, rendered) = reference_from_parts(scene, cfg, key, ref_exr, shard, finish, quiet)?;
    let noise = match &film {
        Some(_) if sharded => {
            let parts = read_parts(&parts_dir(ref_exr), key, cfg.spp);
            halves_noise(&parts.iter().collect::<Vec<_>>(), cfg.spp)?
        }
        _ => None,
    };
    Ok((film, noise, rendered))
}

fn read_parts(dir: &Path, key: &str, spp: u32) -> Vec<Part> {
    let Ok(rd) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut paths: Vec<PathBuf> =
        rd.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "psum")).collect();
    paths.sort();
    paths.iter().filter_map(|p| Part::read(p).ok()).filter(|p| p.header.key == key && p.header.spp == spp).collect()
}

/// Noise of the whole from parts grouped into samples below and above spp/2.
fn halves_noise(parts: &[&Part], spp: u32) -> Result<Option<f64>> {
    let mid = spp / 2;
    let group = |low: bool| -> Option<(Film, u32)> {
        let g: Vec<&&Part> = parts.iter().filter(|p| (p.header.range.start < mid) == low).collect();
        let n: u32 = g.iter().map(|p| p.header.range.len()).sum();
        let first = g.first()?;
        let mut f = Film::new(first.header.width, first.header.height);
        for p in &g {
            let w = p.header.range.len() as f32 / n as f32;
            for (a, b) in f.pixels.iter_mut().zip(&part_preview(p).pixels) {
                *a += *b * w;
            }
        }
        Some((f, n))
    };
    match (group(true), group(false)) {
        (Some((a, na)), Some((b, nb))) => Ok(Some(half_noise(&a, &b, na, nb)?)),
        _ => Ok(None),
    }
}

/// The extra image `component` rendered as two halves (⌈spp/2⌉ and ⌊spp/2⌋ samples,
/// seeds `seed` and `seed ^ SECOND_HALF_SEED`): their mean and its noise.
pub fn component_in_halves(scene: &Scene, cfg: &RenderConfig, component: &str, quiet: bool) -> Result<(Film, Option<f64>)> {
    if cfg.spp < 2 {
        return Ok((render_component(scene, cfg, component, quiet)?, None));
    }
    let (na, nb) = (cfg.spp.div_ceil(2), cfg.spp / 2);
    let mut ca = cfg.clone();
    ca.spp = na;
    let mut cb = cfg.clone();
    cb.spp = nb;
    cb.seed = cfg.seed ^ SECOND_HALF_SEED;
    let a = render_component(scene, &ca, component, quiet).context("first half")?;
    let b = render_component(scene, &cb, component, quiet).context("second half")?;
    let noise = half_noise(&a, &b, na, nb)?;
    let (wa, wb) = (na as f32 / cfg.spp as f32, nb as f32 / cfg.spp as f32);
    let mut m = a;
    for (p, q) in m.pixels.iter_mut().zip(&b.pixels) {
        *p = *p * wa + *q * wb;
    }
    Ok((m, Some(noise)))
}

/// The extra image `component` (rendered after the full image with the same pre-pass).
fn render_component(scene: &Scene, cfg: &RenderConfig, component: &str, quiet: bool) -> Result<Film> {
    let mut o = render_scene_with_aovs(scene.clone(), cfg, quiet, &[component.to_string()])?;
    o.aovs.pop().map(|(_, img)| img).context("the integrator wrote no extra image")
}

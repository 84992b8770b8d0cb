//! Sample ranges rendered apart and combined exactly: `photonlab render
//! --sample-range A..B` and `photonlab accumulate`, and the runner's references.
//!
//! Sample `i` of a pixel is a pure function of (seed, pixel, i) (see
//! [`crate::sampler`]), so samples A..B−1 of an N-spp render can be rendered anywhere.
//! What makes the combination independent of the split is the sum: every sample's
//! RGB value is converted to a 128-bit fixed-point integer with [`FRAC_BITS`]
//! fractional bits (truncated toward zero, a per-sample rounding that does not
//! depend on which part the sample is in), and integers add exactly and
//! associatively. A part stores these sums (a `.psum` file: a JSON header with size,
//! sample range, total spp and the configuration key, then the sums); `accumulate`
//! adds them and divides by the sample count once, in f64, then rounds to f32. Any
//! split of 0..N into parts therefore gives the same bits.
//!
//! Against a single [`crate::integrator::render::render`] (which sums the f32 samples in f64 in
//! index order): both means are within a relative (N + 1)·2⁻⁵³ plus an absolute
//! 2⁻⁶⁰ of the exact mean of the samples, so (N ≤ [`MAX_SPP`] = 2²⁶) the two f32 images
//! differ by at most one f32 ulp per channel, plus 2⁻⁶⁰ absolute (tested).

use crate::config::RenderConfig;
use crate::film::{Film, write_atomic};
use crate::integrator::Integrator;
use crate::integrator::render::{RenderStats, TILE, scatter_tile};
use crate::math::is_finite;
use crate::pipeline::{Prepared, Timings, configured_scene, prepare, thread_pool};
use crate::progress::progress_bar;
use crate::sampler::{DIM_PIXEL, Sampler};
use crate::scene::Scene;
use crate::world::World;
use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Instant;

/// Fractional bits of the fixed-point sums.
pub const FRAC_BITS: i32 = 60;
/// Largest sample magnitude the sums accept (2⁴⁰); with at most [`MAX_SPP`] samples a
/// sum stays below 2¹²⁶ units, so it cannot overflow.
pub const MAX_SAMPLE: f64 = (1u64 << 40) as f64;
/// Most samples per pixel of a render split into ranges (2²⁶).
pub const MAX_SPP: u32 = 1 << 26;
/// Integrators whose render pass is a pure function of (pre-pass, pixel, sample
/// index), so that a sample range is meaningful. The photon integrator repeats its
/// (deterministic) pre-pass in every part.
pub const RANGE_INTEGRATORS: &[&str] = &["path", "photon"];
const MAGIC: &[u8; 16] = b"photonlab-psum1\n";

/// Samples `start..end` (end exclusive) of every pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct SampleRange {
    /// First sample index.
    pub start: u32,
    /// One past the last sample index.
    pub end: u32,
}

impl FromStr for SampleRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("sample range `{s}` must be A..B with A < B (samples A to B-1), e.g. 0..256");
        let (a, b) = s.split_once("..").ok_or_else(bad)?;
        let (start, end) = (a.trim().parse().map_err(|_| bad())?, b.trim().parse().map_err(|_| bad())?);
        if start >= end {
            return Err(bad());
        }
        Ok(SampleRange { start, end })
    }
}

impl std::fmt::Display for SampleRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}..{}", self.start, self.end)
    }
}

impl SampleRange {
    /// Number of samples.
    pub fn len(&self) -> u32 {
        self.end - self.start
    }
    /// Whether the range holds no sample.
    pub fn is_empty(&self) -> bool {
        self.end <= self.start
    }
    /// Part `index` (1-based) of `count` equal splits of 0..spp (possibly empty).
    pub fn split(spp: u32, index: usize, count: usize) -> SampleRange {
        let at = |i: usize| (spp as u64 * i as u64 / count as u64) as u32;
        SampleRange { start: at(index - 1), end: at(index) }
    }
}

/// A sample's value as a fixed-point integer (truncated toward zero), or `None` when
/// it is too large for exact sums.
#[inline]
pub fn to_fixed(x: f32) -> Option<i128> {
    let v = x as f64;
    (v.abs() < MAX_SAMPLE).then(|| (v * (FRAC_BITS as f64).exp2()) as i128)
}

/// Header of a `.psum` file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the whole render the range belongs to.
    pub spp: u32,
    /// The samples summed here.
    pub range: SampleRange,
    /// Key of the configuration and scene (parts combine only with equal keys).
    pub key: String,
    /// NaN / infinite samples dropped (they count in the sample count, as in a single render).
    pub nonfinite_samples: u64,
    /// Wall time of the part (pre-pass + render pass), seconds.
    pub seconds: f64,
    /// Configuration rendered (for people reading the file).
    pub config: serde_json::Value,
}

/// The largest fixed-point value of one sample: [`MAX_SAMPLE`] in units of 2^−FRAC_BITS.
fn max_fixed() -> i128 {
    (MAX_SAMPLE as i128) << FRAC_BITS
}

impl PartHeader {
    /// Checks the header against itself and against `data_len`, the bytes of sums that
    /// follow it; the message names the field.
    fn check(&self, data_len: usize) -> std::result::Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("image size {}x{} (width and height must be positive)", self.width, self.height));
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            return Err(format!("spp {} (must lie in 1..={MAX_SPP}, what the exact sums hold)", self.spp));
        }
        if self.range.is_empty() || self.range.end > self.spp {
            return Err(format!("sample range {} is not a non-empty range inside the render's 0..{}", self.range, self.spp));
        }
        let pixels = self.width as u64 * self.height as u64;
        if self.nonfinite_samples > pixels * self.range.len() as u64 {
            return Err(format!(
                "nonfinite_samples {} is more than the {} samples of {} pixels",
                self.nonfinite_samples,
                self.range.len(),
                pixels
            ));
        }
        if self.seconds.is_nan() || self.seconds < 0.0 {
            return Err(format!("seconds {} (must be at least 0)", self.seconds));
        }
        let want = usize::try_from(pixels).ok().and_then(|p| p.checked_mul(48));
        if want != Some(data_len) {
            return Err(format!(
                "{data_len} bytes of sums for {}x{} pixels (expected {}: 3 × 16 bytes per pixel)",
                self.width,
                self.height,
                pixels as u128 * 48
            ));
        }
        Ok(())
    }
}

/// Exact per-pixel sums of a sample range.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// What the sums are.
    pub header: PartHeader,
    /// Per pixel, row-major, RGB sums in units of 2^-FRAC_BITS.
    pub sums: Vec<[i128; 3]>,
}

impl Part {
    /// Writes the part atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let head = serde_json::to_vec(&self.header)?;
        let mut bytes = Vec::with_capacity(MAGIC.len() + 8 + head.len() + self.sums.len() * 48);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(head.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&head);
        for s in &self.sums {
            for c in s {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        write_atomic(path, &bytes)
    }

    /// Reads a part; `PATH.exr` stands for its sidecar `PATH.psum`.
    pub fn read(path: &Path) -> Result<Part> {
        let path = part_path(path);
        let bytes = std::fs::read(&path).with_context(|| format!("{}: cannot read the part", path.display()))?;
        let bad = |what: String| anyhow::anyhow!("{}: not a photonlab sample-range part (.psum): {what}", path.display());
        if bytes.len() < MAGIC.len() + 8 || &bytes[..MAGIC.len()] != MAGIC {
            return Err(bad("wrong magic bytes".into()));
        }
        let n = u64::from_le_bytes(bytes[MAGIC.len()..MAGIC.len() + 8].try_into().unwrap_or_default()) as usize;
        let body = MAGIC.len() + 8;
        let head = bytes.get(body..body.saturating_add(n)).ok_or_else(|| bad("truncated header".into()))?;
        let header: PartHeader = serde_json::from_slice(head).map_err(|e| bad(format!("header: {e}")))?;
        let data = &bytes[body + n..];
        header.check(data.len()).map_err(bad)?;
        let sums: Vec<[i128; 3]> = data
            .chunks_exact(48)
            .map(|c| std::array::from_fn(|k| i128::from_le_bytes(c[k * 16..k * 16 + 16].try_into().unwrap_or_default())))
            .collect();
        // A sum of `len` samples below MAX_SAMPLE each; larger values would let the
        // sums of the parts overflow (wrap) instead of adding exactly.
        let limit = header.range.len() as i128 * max_fixed();
        if let Some((i, c)) =
            sums.iter().enumerate().find_map(|(i, s)| s.iter().position(|v| v.unsigned_abs() > limit as u128).map(|c| (i, c)))
        {
            let (x, y) = (i % header.width as usize, i / header.width as usize);
            return Err(bad(format!(
                "pixel ({x}, {y}) channel {c}: sum {} is larger than {} samples can give (|sample| < {MAX_SAMPLE:e})",
                sums[i][c] as f64 * (-FRAC_BITS as f64).exp2(),
                header.range.len()
            )));
        }
        Ok(Part { header, sums })
    }
}

/// `X.psum` for `X.psum`, `X.exr` or `X`.
pub fn part_path(p: &Path) -> PathBuf {
    match p.extension().and_then(|e| e.to_str()) {
        Some("psum") => p.to_path_buf(),
        Some("exr") => p.with_extension("psum"),
        _ => PathBuf::from(format!("{}.psum", p.display())),
    }
}

/// Renders samples `range` of every pixel into exact sums. Returns the sums, the
/// counters and the number of samples too large for them.
pub fn render_range(
    world: &World,
    integrator: &dyn Integrator,
    sampler: &dyn Sampler,
    range: SampleRange,
    quiet: bool,
) -> (Vec<[i128; 3]>, RenderStats, u64) {
    let cam = &world.scene.camera;
    let (w, h) = (cam.width, cam.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let start = Instant::now();
    let pb = progress_bar((tiles_x * tiles_y) as u64, quiet, &format!("render samples {range}"));
    type Tile = (Vec<[i128; 3]>, crate::accel::TraversalStats, u64, u64);
    let results: Vec<Tile> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let mut s = sampler.clone_box();
            let mut stats = crate::accel::TraversalStats::default();
            let (mut bad, mut big) = (0u64, 0u64);
            let mut out = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
            for y in y0..y1 {
                for x in x0..x1 {
                    if crate::progress::cancelled() {
                        // Stopped (`progress::cancel`): `render_part` discards the sums.
                        out.push([0; 3]);
                        continue;
                    }
                    let stream = y as u64 * w as u64 + x as u64;
                    let mut sum = [0i128; 3];
                    for i in range.start..range.end {
                        s.start(stream, i as u64);
                        s.set_dimension(DIM_PIXEL);
                        let u = s.next_2d();
                        let ray = cam.generate_ray(x as f32 + u[0], y as f32 + u[1]);
                        let l = integrator.li(world, &ray, s.as_mut(), &mut stats);
                        if !is_finite(l) {
                            bad += 1;
                            continue;
                        }
                        match (to_fixed(l.x), to_fixed(l.y), to_fixed(l.z)) {
                            (Some(r), Some(g), Some(b)) => {
                                sum[0] += r;
                                sum[1] += g;
                                sum[2] += b;
                            }
                            _ => big += 1,
                        }
                    }
                    out.push(sum);
                }
            }
            pb.inc(1);
            (out, stats, bad, big)
        })
        .collect();
    pb.finish_and_clear();
    let mut sums = vec![[0i128; 3]; w as usize * h as usize];
    let mut stats = RenderStats::default();
    let mut too_large = 0;
    for (t, (pixels, st, bad, big)) in results.into_iter().enumerate() {
        scatter_tile(&mut sums, w, h, t as u32, &pixels);
        stats.traversal.add(&st);
        stats.nonfinite_samples += bad;
        too_large += big;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    (sums, stats, too_large)
}

/// A rendered part with the run's counters.
pub struct PartOutcome {
    /// The sums.
    pub part: Part,
    /// Phase times.
    pub timings: Timings,
    /// Render-pass counters.
    pub stats: RenderStats,
    /// Worker threads.
    pub threads: usize,
}

/// Checks that `cfg` can be rendered as sample ranges and that `range` lies in 0..spp.
pub fn check_range(cfg: &RenderConfig, range: SampleRange) -> Result<()> {
    if !RANGE_INTEGRATORS.contains(&cfg.integrator.as_str()) {
        bail!(
            "--sample-range: integrator `{}` cannot render sample ranges (supported: {}; progressive integrators change between samples)",
            cfg.integrator,
            RANGE_INTEGRATORS.join(", ")
        );
    }
    if cfg.spp > MAX_SPP {
        bail!("--sample-range: {} samples per pixel is more than the exact sums hold ({MAX_SPP})", cfg.spp);
    }
    if range.is_empty() || range.end > cfg.spp {
        bail!("--sample-range {range} is not inside the render's {} samples per pixel (0..{}; set --spp to the total)", cfg.spp, cfg.spp);
    }
    Ok(())
}

/// Renders samples `range` of the `cfg.spp`-sample render of `scene` (the
/// configuration is validated first). `key` identifies scene + configuration.
pub fn render_part(scene: Scene, cfg: &RenderConfig, range: SampleRange, key: &str, quiet: bool) -> Result<PartOutcome> {
    let scene = configured_scene(scene, cfg)?;
    check_range(cfg, range)?;
    let pool = thread_pool(cfg.threads)?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let t0 = Instant::now();
        let Prepared { world, integrator, sampler, accel_build_s, preprocess_s, .. } = prepare(scene, cfg, quiet)?;
        let (sums, stats, too_large) = render_range(&world, integrator.as_ref(), sampler.as_ref(), range, quiet);
        crate::progress::check_cancel()?;
        if too_large > 0 {
            bail!("{too_large} sample(s) of {range} exceed {MAX_SAMPLE:e} in magnitude, beyond the exact sums' range");
        }
        let cam = &world.scene.camera;
        let mut config = serde_json::to_value(cfg)?;
        config["threads"] = 0.into();
        let header = PartHeader {
            width: cam.width,
            height: cam.height,
            spp: cfg.spp,
            range,
            key: key.to_string(),
            nonfinite_samples: stats.nonfinite_samples,
            seconds: t0.elapsed().as_secs_f64(),
            config,
        };
        let timings = Timings { accel_build_s, preprocess_s, render_s: stats.seconds };
        Ok(PartOutcome { part: Part { header, sums }, timings, stats, threads })
    })
}

/// The image of parts (path, part), checked against each other and against 0..spp:
/// same size, total and key, disjoint, covering every sample. Errors name the files.
pub fn accumulate(parts: &[(PathBuf, Part)]) -> Result<Film> {
    let Some((p0, first)) = parts.first() else { bail!("accumulate: no parts given") };
    let h0 = &first.header;
    for (p, part) in parts {
        let h = &part.header;
        if (h.width, h.height, h.spp) != (h0.width, h0.height, h0.spp) {
            bail!(
                "{}: {}x{} px of a {}-spp render, but {} is {}x{} px of a {}-spp render",
                p.display(),
                h.width,
                h.height,
                h.spp,
                p0.display(),
                h0.width,
                h0.height,
                h0.spp
            );
        }
        if h.key != h0.key {
            bail!("{}: rendered from another scene or configuration (key {}) than {} (key {})", p.display(), h.key, p0.display(), h0.key);
        }
    }
    let mut order: Vec<&(PathBuf, Part)> = parts.iter().collect();
    order.sort_by_key(|(_, p)| p.header.range);
    let mut next = 0u32;
    for w in 0..order.len() {
        let (p, part) = order[w];
        let r = part.header.range;
        if r.start < next {
            bail!("{}: samples {r} overlap {} ({})", p.display(), order[w - 1].0.display(), order[w - 1].1.header.range);
        }
        if r.start > next {
            bail!("samples {next}..{} of {} are in no part (given: {})", r.start, h0.spp, ranges(&order));
        }
        next = r.end;
    }
    if next != h0.spp {
        bail!("samples {next}..{} of {} are in no part (given: {})", h0.spp, h0.spp, ranges(&order));
    }
    Ok(sums_to_film(h0.width, h0.height, h0.spp, order.iter().map(|(_, p)| p)))
}

fn ranges(order: &[&(PathBuf, Part)]) -> String {
    order.iter().map(|(p, part)| format!("{} {}", part.header.range, p.display())).collect::<Vec<_>>().join(", ")
}

/// Adds the parts' sums (exactly) and divides by `count`.
fn sums_to_film<'a>(width: u32, height: u32, count: u32, parts: impl Iterator<Item = &'a Part>) -> Film {
    let mut total = vec![[0i128; 3]; width as usize * height as usize];
    for p in parts {
        for (t, s) in total.iter_mut().zip(&p.sums) {
            for c in 0..3 {
                t[c] += s[c];
            }
        }
    }
    let mut film = Film::new(width, height);
    let scale = (-FRAC_BITS as f64).exp2();
    for (px, t) in film.pixels.iter_mut().zip(&total) {
        *px = (glam::DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64) * scale / count as f64).as_vec3();
    }
    film
}

/// The mean image of one part's samples (a preview; noisier than the whole).
pub fn part_preview(part: &Part) -> Film {
    let h = &part.header;
    sums_to_film(h.width, h.height, h.range.len(), std::iter::once(part))
}

/// `photonlab accumulate OUT.exr PART…`.
pub fn accumulate_cmd(out: &Path, parts: &[PathBuf]) -> Result<()> {
    let parts = parts.iter().map(|p| Ok((part_path(p), Part::read(p)?))).collect::<Result<Vec<_>>>()?;
    let film = accumulate(&parts)?;
    let (exr, png) = film.write_pair(out).context("writing the accumulated image")?;
    let h = &parts[0].1.header;
    let bad: u64 = parts.iter().map(|(_, p)| p.header.nonfinite_samples).sum();
    if bad > 0 {
        eprintln!("warning: {bad} sample(s) were NaN or infinite and were dropped");
    }
    outln!(
        "accumulated {} part(s), samples 0..{} of {}x{} px → {} and {}",
        parts.len(),
        h.spp,
        h.width,
        h.height,
        exr.display(),
        png.display()
    );
    Ok(())
}

/// Where the parts of the cached reference `ref_exr` live: `STEM.parts/`.
pub fn parts_dir(ref_exr: &Path) -> PathBuf {
    ref_exr.with_extension("parts")
}

/// The runner's reference render through exact sums, so that it is the same image
/// whether rendered whole or as parts by the shards of `--shard I/N`.
///
/// With a shard of N > 1, shard I renders samples [`SampleRange::split`]`(spp, I, N)`
/// into `STEM.parts/START-END.psum` (unless that part exists). Then, when the parts
/// present cover every sample, they are accumulated into the image. Otherwise,
/// with `finish` false (`--reference-only`: other array tasks render the rest) it
/// returns `None`; with `finish` true it renders the missing samples itself (any
/// split gives the same bits). Unsharded (or N = 1), the whole range is rendered in
/// memory. Returns the image and whether anything was rendered.
pub fn reference_from_parts(
    scene: &Scene,
    cfg: &RenderConfig,
    key: &str,
    ref_exr: &Path,
    shard: Option<(usize, usize)>,
    finish: bool,
    quiet: bool,
) -> Result<(Option<Film>, bool)> {
    if check_range(cfg, SampleRange { start: 0, end: cfg.spp }).is_err() {
        // Not splittable (e.g. a progressive integrator): rendered whole, as before.
        if !quiet {
            eprintln!("rendering the reference whole (`{}` cannot be split into sample ranges)", cfg.integrator);
        }
        return Ok((Some(crate::pipeline::render_scene(scene.clone(), cfg, quiet)?.film), true));
    }
    let dir = parts_dir(ref_exr);
    let sharded = shard.is_some_and(|(_, n)| n > 1);
    let mut rendered = false;
    let mut parts = if sharded { read_parts(&dir, cfg, key, quiet) } else { Vec::new() };
    let render = |range: SampleRange| -> Result<(PathBuf, Part)> {
        if !quiet {
            eprintln!("rendering reference samples {range} of {} ({} integrator)", cfg.spp, cfg.integrator);
        }
        let o = render_part(scene.clone(), cfg, range, key, quiet).with_context(|| format!("rendering reference samples {range}"))?;
        let path = dir.join(format!("{:010}-{:010}.psum", range.start, range.end));
        if sharded {
            o.part.write(&path)?;
        }
        Ok((path, o.part))
    };
    if let Some((i, n)) = shard.filter(|_| sharded) {
        let mine = SampleRange::split(cfg.spp, i, n);
        if !mine.is_empty() && !parts.iter().any(|(_, p)| p.header.range == mine) {
            render(mine)?;
            rendered = true;
            // Other tasks may have finished their parts meanwhile.
            parts = read_parts(&dir, cfg, key, quiet);
        }
    }
    let (mut chain, gaps) = cover(cfg.spp, &parts);
    if !gaps.is_empty() {
        if !finish && sharded {
            return Ok((None, rendered));
        }
        if sharded && !quiet {
            eprintln!(
                "reference samples {} not rendered by other tasks yet: rendering them here (render the reference first with --reference-only as an array)",
                gaps.iter().map(|g| g.to_string()).collect::<Vec<_>>().join(", ")
            );
        }
        for g in gaps {
            chain.push(render(g)?);
            rendered = true;
        }
    }
    let film = accumulate(&chain)?;
    Ok((Some(film), rendered))
}

/// The readable parts in `dir` that belong to (cfg, key); others are skipped with a warning.
fn read_parts(dir: &Path, cfg: &RenderConfig, key: &str, quiet: bool) -> Vec<(PathBuf, Part)> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut paths: Vec<PathBuf> =
        entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "psum")).collect();
    paths.sort();
    let mut out = Vec::new();
    for p in paths {
        match Part::read(&p) {
            Ok(part) if part.header.key == key && part.header.spp == cfg.spp => out.push((p, part)),
            Ok(_) => {
                if !quiet {
                    eprintln!("warning: {}: part of another reference, ignored", p.display());
                }
            }
            Err(e) => {
                if !quiet {
                    eprintln!("warning: {e:#}; ignored");
                }
            }
        }
    }
    out
}

/// A disjoint chain of `parts` from sample 0 (at each position the part reaching
/// farthest) and the gaps it leaves in 0..spp.
fn cover(spp: u32, parts: &[(PathBuf, Part)]) -> (Vec<(PathBuf, Part)>, Vec<SampleRange>) {
    let (mut chain, mut gaps) = (Vec::new(), Vec::new());
    let mut pos = 0;
    while pos < spp {
        let here = parts.iter().filter(|(_, p)| p.header.range.start == pos).max_by_key(|(_, p)| p.header.range.end);
        if let Some(p) = here {
            chain.push(p.clone());
            pos = p.1.header.range.end;
        } else {
            let next = parts.iter().map(|(_, p)| p.header.range.start).filter(|&s| s > pos).min().unwrap_or(spp).min(spp);
            gaps.push(SampleRange { start: pos, end: next });
            pos = next;
        }
    }
    (chain, gaps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::builtin;

    fn cfg(integrator: &str, spp: u32, res: u32) -> RenderConfig {
        let c = RenderConfig { integrator: integrator.into(), spp, resolution: Some([res, res]), seed: 7, ..Default::default() };
        if integrator == "path" { c } else { c.with("photons", 3000).with("caustic_photons", 0) }
    }

    fn parts(c: &RenderConfig, ranges: &[(u32, u32)]) -> Vec<(PathBuf, Part)> {
        let scene = builtin("cornell").unwrap();
        ranges
            .iter()
            .map(|&(a, b)| {
                let r = SampleRange { start: a, end: b };
                (PathBuf::from(format!("{r}.psum")), render_part(scene.clone(), c, r, "k", true).unwrap().part)
            })
            .collect()
    }

    /// Distance in representable f32 values (same sign assumed: radiance ≥ 0).
    fn ulps(a: f32, b: f32) -> u32 {
        a.to_bits().abs_diff(b.to_bits())
    }

    fn bits(f: &Film) -> Vec<u32> {
        f.pixels.iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect()
    }

    fn check_splits(c: &RenderConfig, splits: &[&[(u32, u32)]]) {
        let images: Vec<Film> = splits.iter().map(|s| accumulate(&parts(c, s)).unwrap()).collect();
        for img in &images[1..] {
            assert_eq!(bits(img), bits(&images[0]), "a different split changed the bits");
        }
        let whole = crate::pipeline::render_scene(builtin("cornell").unwrap(), c, true).unwrap().film;
        let (mut equal, mut n) = (0, 0);
        for (p, q) in images[0].pixels.iter().zip(&whole.pixels) {
            for k in 0..3 {
                let (a, b) = (p[k], q[k]);
                assert!(a >= 0.0 && b >= 0.0);
                assert!(ulps(a, b) <= 1 || (a - b).abs() as f64 <= (-60f64).exp2(), "{a} vs single render {b}");
                equal += (a == b) as usize;
                n += 1;
            }
        }
        // Not vacuous: the image has light, and most values agree exactly.
        assert!(whole.mean().x > 0.05 && equal * 10 > n * 9, "{equal} of {n} equal");
    }

    #[test]
    fn path_splits_are_bit_identical_and_within_one_ulp_of_a_single_render() {
        let c = cfg("path", 16, 24);
        check_splits(&c, &[&[(0, 4), (4, 8), (8, 12), (12, 16)], &[(0, 8), (8, 16)], &[(0, 1), (1, 11), (11, 16)], &[(0, 16)]]);
    }

    #[test]
    fn photon_splits_repeat_the_pre_pass_and_give_the_same_bits() {
        let c = cfg("photon", 4, 16);
        check_splits(&c, &[&[(0, 1), (1, 2), (2, 3), (3, 4)], &[(0, 2), (2, 4)]]);
    }

    #[test]
    fn fixed_point_sums_are_exact_and_order_free() {
        // Values of very different magnitude: an f64 sum depends on the order, the fixed one does not.
        let vals = [1.0e6f32, 3.0e-7, -2.5e5, 0.1, 7.0, 1.0e-3, 123.456];
        let fwd: i128 = vals.iter().map(|&v| to_fixed(v).unwrap()).sum();
        let rev: i128 = vals.iter().rev().map(|&v| to_fixed(v).unwrap()).sum();
        assert_eq!(fwd, rev);
        assert_eq!(to_fixed(1.5), Some(3i128 << (FRAC_BITS - 1)));
        assert_eq!(to_fixed(-0.25), Some(-(1i128 << (FRAC_BITS - 2))));
        assert!(to_fixed(2.0e12).is_none());
        assert_eq!(SampleRange::split(10, 1, 3), SampleRange { start: 0, end: 3 });
        assert_eq!(SampleRange::split(10, 3, 3), SampleRange { start: 6, end: 10 });
        assert!(SampleRange::split(2, 1, 4).is_empty() && SampleRange::split(2, 2, 4).len() == 1);
        assert!("3..3".parse::<SampleRange>().is_err() && "x".parse::<SampleRange>().is_err());
    }

    #[test]
    fn bad_parts_are_errors_naming_the_file() {
        let c = cfg("path", 4, 8);
        let ps = parts(&c, &[(0, 2), (2, 4), (1, 3)]);
        let e = accumulate(&[ps[0].clone(), ps[2].clone(), ps[1].clone()]).unwrap_err().to_string();
        assert!(e.contains("1..3.psum") && e.contains("overlap"), "{e}");
        let e = accumulate(&ps[..1]).unwrap_err().to_string();
        assert!(e.contains("samples 2..4 of 4 are in no part"), "{e}");
        let mut other = ps[1].clone();
        other.1.header.key = "other".into();
        let e = accumulate(&[ps[0].clone(), other]).unwrap_err().to_string();
        assert!(e.contains("2..4.psum") && e.contains("another scene"), "{e}");
        assert!(check_range(&cfg("sppm", 4, 8), SampleRange { start: 0, end: 2 }).is_err());
        // Round trip, then a truncated file.
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let p = dir.join("a.psum");
        ps[0].1.write(&p).unwrap();
        assert_eq!(Part::read(&dir.join("a.exr")).unwrap(), ps[0].1);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 5]).unwrap();
        let e = format!("{:#}", Part::read(&p).unwrap_err());
        assert!(e.contains("a.psum") && e.contains("bytes of sums"), "{e}");
        // Corrupt headers and sums, each named.
        let raw = |head: &serde_json::Value, data: &[u8], len: Option<u64>| {
            let h = serde_json::to_vec(head).unwrap();
            let mut b = MAGIC.to_vec();
            b.extend_from_slice(&len.unwrap_or(h.len() as u64).to_le_bytes());
            b.extend_from_slice(&h);
            b.extend_from_slice(data);
            b
        };
        let good = serde_json::to_value(&ps[0].1.header).unwrap();
        let data = &bytes[bytes.len() - 8 * 8 * 48..];
        let with = |k: &str, v: serde_json::Value| {
            let mut h = good.clone();
            h[k] = v;
            h
        };
        let mut big = data.to_vec();
        big[5 * 48 + 16..5 * 48 + 32].copy_from_slice(&(3 * max_fixed()).to_le_bytes());
        let mut wrap = data.to_vec();
        wrap[48..64].copy_from_slice(&i128::MIN.to_le_bytes());
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (raw(&good, data, None), ""),
            (raw(&with("width", 0.into()), data, None), "image size 0x8"),
            (raw(&with("spp", (MAX_SPP as u64 + 1).into()), data, None), "spp 67108865"),
            (raw(&with("range", serde_json::json!({"start": 2, "end": 5})), data, None), "sample range 2..5"),
            (raw(&with("range", serde_json::json!({"start": 3, "end": 1})), data, None), "sample range 3..1"),
            (raw(&with("nonfinite_samples", 1000.into()), data, None), "nonfinite_samples 1000"),
            (raw(&with("width", 4_000_000_000u64.into()), data, None), "expected 1536000000000"),
            (raw(&with("height", 9.into()), data, None), "bytes of sums for 8x9 pixels"),
            (raw(&with("width", (-3).into()), data, None), "header: "),
            (raw(&good, &big, None), "pixel (5, 0) channel 1"),
            (raw(&good, &wrap, None), "pixel (1, 0) channel 0"),
            (raw(&good, data, Some(u64::MAX)), "truncated header"),
            (raw(&good, data, Some(3)), "header: "),
        ];
        for (b, want) in cases {
            std::fs::write(&p, &b).unwrap();
            match Part::read(&p) {
                Ok(part) => assert!(want.is_empty() && part == ps[0].1, "accepted a part that should fail with `{want}`"),
                Err(e) => {
                    let e = format!("{e:#}");
                    assert!(!want.is_empty() && e.contains("a.psum") && e.contains(want), "want `{want}`: {e}");
                }
            }
        }
        // Gaps left by the parts present.
        let (chain, gaps) = cover(10, &[ps[1].clone()]);
        assert_eq!(chain.len(), 1);
        assert_eq!(gaps, vec![SampleRange { start: 0, end: 2 }, SampleRange { start: 4, end: 10 }]);
    }
}

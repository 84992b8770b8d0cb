//! The experiment runner: `photonlab run MANIFEST [--out DIR] [--force] [--shard I/N]`
//! and `photonlab merge DIR`.
//!
//! A manifest ([`manifest`]) expands into cells (configuration × repeat). Each cell is
//! rendered and measured against a reference ([`cell`]); its image, error image and
//! record land in `DIR/cells/`, the record written last and atomically, so a cell is
//! finished exactly when its record exists and matches — a killed run resumes where
//! it stopped. Shards take `index % N == I − 1`; `merge` (and an unsharded run) turns
//! the records into `cells.csv`, `cells.jsonl`, plots and `summary.md` ([`output`],
//! [`plots`]). The runner only deals in configuration keys: new integrators and
//! strategies need no change here.

pub mod cell;
pub mod html;
pub mod manifest;
pub mod metrics;
pub mod output;
pub mod plots;
pub mod refnoise;
pub mod scene_spec;
pub mod summary;

use crate::film::{Film, write_atomic};
use crate::math::Fnv;
use crate::scene::Scene;
use anyhow::{Context, Result, anyhow, bail};
use cell::{CellPaths, bias_variance, finished, run_cell};
use clap::Args;
use manifest::{Manifest, ReferenceSpec};
use output::Row;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Instant;

/// Flags of `run`.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// Experiment manifest (TOML).
    pub manifest: PathBuf,
    /// Output directory (default: results/NAME).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Recompute every cell, even finished ones.
    #[arg(long)]
    pub force: bool,
    /// Run only shard I of N (1-based): the cells whose index is I−1 modulo N.
    #[arg(long)]
    pub shard: Option<Shard>,
    /// Only make sure the references exist (rendered and cached), then stop: lets a
    /// cluster render them once before the shards start.
    #[arg(long)]
    pub reference_only: bool,
    /// Validate the manifest and list its cells (this shard's, with --shard) and
    /// whether each is finished, without rendering anything.
    #[arg(long)]
    pub list: bool,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

impl RunArgs {
    /// A plain run of `manifest` into `out`, without progress bars (tests, tools).
    pub fn quiet(manifest: impl Into<PathBuf>, out: impl Into<PathBuf>) -> Self {
        RunArgs {
            manifest: manifest.into(),
            out: Some(out.into()),
            force: false,
            shard: None,
            reference_only: false,
            list: false,
            quiet: true,
        }
    }
}

/// Flags of `merge`.
#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// Experiment directory (results/NAME) holding the shards' cells.
    pub dir: PathBuf,
    /// Other directories of the same experiment (shards run on machines without a
    /// shared file system): their finished cells are copied into DIR first.
    pub from: Vec<PathBuf>,
}

/// A deterministic subset of cells: shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based shard number.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("shard `{s}` must be I/N with 1 <= I <= N, e.g. 2/8");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) = (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if index == 0 || count == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// Whether this shard runs the cell at `index`.
    pub fn takes(&self, index: usize) -> bool {
        index % self.count == self.index - 1
    }
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct RunReport {
    /// Experiment directory.
    pub dir: PathBuf,
    /// Cells rendered now.
    pub ran: usize,
    /// Finished cells kept from an earlier run.
    pub kept: usize,
    /// Whether the tables, plots and summary were written.
    pub finalized: bool,
    /// Whether the reference was rendered now (false: cached or read from a file).
    pub reference_rendered: bool,
}

/// Written to `DIR/run.json`: what `merge` needs besides the manifest copy.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct RunInfo {
    name: String,
    manifest: PathBuf,
    /// One per scene, in manifest order.
    references: Vec<RefInfo>,
    version: String,
}

/// A scene's reference: cache key, description, image file in the experiment directory.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RefInfo {
    /// Scene name.
    pub scene: String,
    /// Cache key the cells' errors were measured against.
    pub key: String,
    /// How it was made.
    pub description: String,
    /// Image file (EXR) relative to the experiment directory; a PNG sits beside it.
    pub file: String,
    /// The reference's own noise as relative MSE (from two half-renders), if known.
    #[serde(default)]
    pub noise_relmse: Option<f64>,
    /// The measured component's reference image (EXR, PNG beside it), if any.
    #[serde(default)]
    pub component_file: Option<String>,
    /// Its noise as relative MSE.
    #[serde(default)]
    pub component_noise_relmse: Option<f64>,
}

/// The cache key of a rendered reference: photonlab version, scene and configuration
/// (without the thread count, which does not change images).
pub fn reference_key(scene: &Scene, cfg: &crate::config::RenderConfig) -> Result<String> {
    let mut c = cfg.clone();
    c.threads = 0;
    let mut h = Fnv::default();
    h.str("photonlab-reference-v2"); // v2: references are exact sums (src/accumulate.rs)
    h.str(env!("CARGO_PKG_VERSION"));
    h.write(&scene.fingerprint().to_le_bytes());
    h.str(&toml::to_string(&c)?);
    Ok(format!("{:016x}", h.0))
}

/// The reference image: cached render under `refs_dir` or the manifest's file.
/// Returns (images and noise, key, description, rendered now); the images are `None`
/// when `finish` is false and other shards' reference parts are still missing
/// (see [`crate::accumulate::reference_from_parts`]).
fn ensure_reference(
    m: &Manifest,
    scene: &Scene,
    refs_dir: &Path,
    shard: Option<Shard>,
    finish: bool,
    quiet: bool,
) -> Result<(Option<refnoise::RefImages>, String, String, bool)> {
    match &m.reference {
        ReferenceSpec::File(p) => {
            let bytes = std::fs::read(p).map_err(|e| anyhow!("{}: [reference] file {}: {e}", m.path.display(), p.display()))?;
            let film = Film::read_exr(p).with_context(|| format!("{}: [reference] file", m.path.display()))?;
            if [film.width, film.height] != m.resolution {
                bail!(
                    "{}: [reference] file {} is {}x{} but the manifest's resolution is {}x{}",
                    m.path.display(),
                    p.display(),
                    film.width,
                    film.height,
                    m.resolution[0],
                    m.resolution[1]
                );
            }
            let mut h = Fnv::default();
            h.write(&bytes);
            let images = refnoise::RefImages { film, noise: None, component: None };
            Ok((Some(images), format!("file-{:016x}", h.0), format!("file `{}`", p.display()), false))
        }
        ReferenceSpec::Render(cfg) => {
            let mut key = reference_key(scene, cfg)?;
            if let Some(c) = &m.component {
                key = format!("{key}-{c}");
            }
            let path = refs_dir.join(format!("{}-{key}.exr", manifest_slug(&scene.name)));
            let desc = format!(
                "`{}` integrator, {} spp, seed {} (noise from its two halves of samples), cached as `references/{}`",
                cfg.integrator,
                cfg.spp,
                cfg.seed,
                file_name(&path)
            );
            let comp_path = m.component.as_ref().map(|c| path.with_extension(format!("{c}.exr")));
            if let Ok(f) = Film::read_exr(&path)
                && [f.width, f.height] == m.resolution
            {
                let meta: Option<serde_json::Value> =
                    std::fs::read_to_string(path.with_extension("json")).ok().and_then(|t| serde_json::from_str(&t).ok());
                let num = |k: &str| meta.as_ref().and_then(|v| v.get(k)).and_then(|n| n.as_f64());
                let comp = comp_path.as_ref().map(|p| Film::read_exr(p).ok().map(|f| (f, num("component_noise_relmse"))));
                // A component reference must be cached too, else render both again.
                if comp.as_ref().is_none_or(|c| c.is_some()) {
                    let images = refnoise::RefImages { film: f, noise: num("noise_relmse"), component: comp.flatten() };
                    return Ok((Some(images), key, desc, false));
                }
            }
            if !quiet {
                eprintln!("rendering the reference ({} integrator, {} spp) → {}", cfg.integrator, cfg.spp, path.display());
            }
            let t0 = Instant::now();
            // Exact sums: the same bits whether rendered whole or as the shards' parts.
            let shard = shard.map(|s| (s.index, s.count));
            let (film, noise, rendered) =
                refnoise::reference_with_noise(scene, cfg, &key, &path, shard, finish, quiet).context("rendering the reference")?;
            let Some(film) = film else { return Ok((None, key, desc, rendered)) };
            let component = match &m.component {
                Some(c) => Some(refnoise::component_in_halves(scene, cfg, c, quiet).context("rendering the reference's component")?),
                None => None,
            };
            let images = refnoise::RefImages { film, noise, component };
            images.film.write_exr(&path)?;
            images.film.write_png(&path.with_extension("png"))?;
            if let (Some(p), Some((f, _))) = (&comp_path, &images.component) {
                f.write_pair(p)?;
            }
            let meta = serde_json::json!({
                "key": key, "scene": scene.name, "config": cfg, "seconds": t0.elapsed().as_secs_f64(),
                "version": env!("CARGO_PKG_VERSION"), "noise_relmse": images.noise,
                "component": m.component, "component_noise_relmse": images.component.as_ref().and_then(|c| c.1),
            });
            write_atomic(&path.with_extension("json"), serde_json::to_string_pretty(&meta)?.as_bytes())?;
            Ok((Some(images), key, desc, rendered))
        }
    }
}

fn manifest_slug(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' }).collect()
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// Where references are cached for an experiment directory: `references/` next to it.
pub fn references_dir(out: &Path) -> PathBuf {
    match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.join("references"),
        _ => PathBuf::from("references"),
    }
}

/// Runs (part of) an experiment. See the module documentation.
pub fn run(args: &RunArgs) -> Result<RunReport> {
    let m = Manifest::load(&args.manifest)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("results").join(&m.name));
    if args.list {
        list_cells(&m, &out, args.shard)?;
        return Ok(RunReport { dir: out, ..Default::default() });
    }
    // Every scene loads (and every model file exists) before anything renders.
    let scenes = m.scenes.iter().map(|s| s.load(m.resolution)).collect::<Result<Vec<Scene>>>()?;
    if !args.quiet {
        for w in scenes.iter().flat_map(|s| &s.warnings) {
            eprintln!("warning: {w}");
        }
    }
    std::fs::create_dir_all(out.join("cells")).with_context(|| format!("{}: cannot create the output directory", out.display()))?;
    let mut references = Vec::new();
    let mut infos = Vec::new();
    let mut reference_rendered = false;
    let mut pending = 0;
    for (spec, scene) in m.scenes.iter().zip(&scenes) {
        let (images, key, description, rendered) =
            ensure_reference(&m, scene, &references_dir(&out), args.shard, !args.reference_only, args.quiet)?;
        reference_rendered |= rendered;
        let Some(images) = images else {
            pending += 1;
            continue;
        };
        let file = format!("reference-{}.exr", manifest_slug(&spec.name()));
        // The experiment directory is self-contained: merge needs only what is inside it.
        let mut own = vec![(file.clone(), &images.film)];
        let component_file = m.component.as_ref().map(|c| format!("reference-{}.{c}.exr", manifest_slug(&spec.name())));
        if let (Some(cf), Some((f, _))) = (&component_file, &images.component) {
            own.push((cf.clone(), f));
        }
        for (name, film) in own {
            if Film::read_exr(&out.join(&name)).ok().as_ref() != Some(film) {
                film.write_pair(&out.join(&name))?;
            }
        }
        let (noise_relmse, component_noise_relmse) = (images.noise, images.component.as_ref().and_then(|c| c.1));
        references.push(images);
        infos.push(RefInfo { scene: spec.name(), key, description, file, noise_relmse, component_file, component_noise_relmse });
    }
    if pending > 0 {
        // --reference-only under --shard: this task's reference parts are done.
        if !args.quiet {
            eprintln!("{pending} reference(s) wait for other shards' parts; the last shard to finish its part assembles them");
        }
        return Ok(RunReport { dir: out, reference_rendered, ..Default::default() });
    }
    write_atomic(&out.join("manifest.toml"), m.text.as_bytes())?;
    let info =
        RunInfo { name: m.name.clone(), manifest: m.path.clone(), references: infos.clone(), version: env!("CARGO_PKG_VERSION").into() };
    write_atomic(&out.join("run.json"), serde_json::to_string_pretty(&info)?.as_bytes())?;
    if args.reference_only {
        return Ok(RunReport { dir: out, reference_rendered, ..Default::default() });
    }

    let mine: Vec<&manifest::Cell> = m.cells.iter().filter(|c| args.shard.is_none_or(|s| s.takes(c.index))).collect();
    let todo: Vec<&manifest::Cell> =
        mine.iter().copied().filter(|c| args.force || finished(&out, c, &infos[c.scene].key).is_none()).collect();
    let kept = mine.len() - todo.len();
    if !args.quiet {
        let shard = args.shard.map_or(String::new(), |s| format!(" (shard {}/{})", s.index, s.count));
        eprintln!("{}: {} cells{shard}, {kept} already finished, {} to run → {}", m.name, mine.len(), todo.len(), out.display());
    }
    let pb = crate::progress::progress_bar(todo.len() as u64, args.quiet, "cells");
    pb.enable_steady_tick(std::time::Duration::from_millis(500));
    for (i, c) in todo.iter().enumerate() {
        pb.set_message(format!("cells ({})", c.stem));
        if !args.quiet && i > 0 {
            let eta = pb.eta().as_secs();
            log(
                &pb,
                format!("cell {}/{}: {} repeat {} (all cells: eta {}m {:02}s)", i + 1, todo.len(), c.label, c.repeat, eta / 60, eta % 60),
            );
        }
        // The renderer's own bars (photon pass, cache, render) show inside the cell.
        let (reference, comp_ref) = (&references[c.scene].film, references[c.scene].component.as_ref().map(|x| &x.0));
        let rec = pb.suspend(|| run_cell(&scenes[c.scene], c, reference, comp_ref, &infos[c.scene].key, &out, args.quiet))?;
        if !args.quiet {
            log(
                &pb,
                format!(
                    "  {}: RMSE {} relMSE {} in {} s",
                    c.stem,
                    output::sig(rec.metrics.rmse),
                    output::sig(rec.metrics.relmse),
                    output::sig(rec.time_total_s)
                ),
            );
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut report = RunReport { dir: out.clone(), ran: todo.len(), kept, finalized: false, reference_rendered };
    if args.shard.is_none_or(|s| s.count == 1) {
        finalize(&out, args.quiet)?;
        report.finalized = true;
    } else if !args.quiet {
        eprintln!("shard done; when every shard has finished: photonlab merge {}", out.display());
    }
    Ok(report)
}

/// A line above the progress bar, or on stderr when the bar is hidden (no terminal).
fn log(pb: &indicatif::ProgressBar, line: String) {
    if pb.is_hidden() { eprintln!("{line}") } else { pb.println(line) }
}

/// `--list`: the cells, with shard and state, and the models the scenes need.
fn list_cells(m: &Manifest, out: &Path, shard: Option<Shard>) -> Result<()> {
    for s in &m.scenes {
        s.check_files()?;
    }
    // The reference keys come from the last run's run.json (computing them would
    // mean loading the scenes); without one, nothing counts as finished.
    let info: Option<RunInfo> = std::fs::read_to_string(out.join("run.json")).ok().and_then(|t| serde_json::from_str(&t).ok());
    let mut n = 0;
    for c in m.cells.iter().filter(|c| shard.is_none_or(|s| s.takes(c.index))) {
        let done = info.as_ref().and_then(|i| i.references.get(c.scene)).is_some_and(|r| finished(out, c, &r.key).is_some());
        outln!("{:>5}  {}  {}", c.index, if done { "finished" } else { "to run  " }, c.stem);
        n += 1;
    }
    outln!(
        "{}: {n} of {} cells listed ({} configurations × {} repeats), output {}",
        m.path.display(),
        m.cells.len(),
        m.configurations(),
        m.repeats,
        out.display()
    );
    Ok(())
}

/// The finished cells under `dir`, all or one shard's, in manifest order and without
/// the bias/variance split (which needs every repeat: [`finalize`] adds it).
pub fn finished_rows(dir: &Path, shard: Option<Shard>) -> Result<Vec<Row>> {
    let (info, m) = read_info(dir)?;
    let rows = m
        .cells
        .iter()
        .filter(|c| shard.is_none_or(|s| s.takes(c.index)))
        .filter_map(|c| {
            let r = info.references.get(c.scene)?;
            finished(dir, c, &r.key).map(|rec| Row { rec, split: None, repeats: m.repeats as usize })
        })
        .collect();
    Ok(rows)
}

/// Combines the cells under `dir` (from one run or several shards) into
/// `cells.csv`, `cells.jsonl`, plots and `summary.md`.
pub fn finalize(dir: &Path, quiet: bool) -> Result<()> {
    let (info, m) = read_info(dir)?;
    let mut rows = Vec::new();
    let mut missing = Vec::new();
    for c in &m.cells {
        let Some(r) = info.references.get(c.scene) else { bail!("{}: run.json lists fewer scenes than the manifest", dir.display()) };
        match finished(dir, c, &r.key) {
            Some(rec) => rows.push(Row { rec, split: None, repeats: m.repeats as usize }),
            None => missing.push(c.stem.clone()),
        }
    }
    if !missing.is_empty() {
        let list = missing.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
        bail!(
            "{}: {} of {} cells are not finished ({list}{}); run the missing shards or `photonlab run {}` again",
            dir.display(),
            missing.len(),
            m.cells.len(),
            if missing.len() > 5 { ", …" } else { "" },
            info.manifest.display()
        );
    }
    // Bias² / variance per configuration from the repeats' images.
    if m.repeats >= 2 {
        let refs = info
            .references
            .iter()
            .map(|r| Film::read_exr(&dir.join(&r.file)))
            .collect::<Result<Vec<_>>>()
            .context("bias/variance needs the reference images")?;
        for ci in 0..m.configurations() {
            let Some(reference) = m.cells.iter().find(|c| c.config_index == ci).map(|c| &refs[c.scene]) else { continue };
            let idx: Vec<usize> = rows.iter().enumerate().filter(|(_, r)| r.rec.config_index == ci).map(|(i, _)| i).collect();
            let imgs = idx.iter().map(|&i| Film::read_exr(&CellPaths::new(dir, &rows[i].rec.cell).exr)).collect::<Result<Vec<_>>>();
            let split = match imgs {
                Ok(imgs) => bias_variance(&imgs.iter().collect::<Vec<_>>(), reference)?,
                Err(e) => {
                    eprintln!("warning: no bias/variance for configuration {ci}: {e:#}");
                    None
                }
            };
            for &i in &idx {
                rows[i].split = split;
            }
        }
    }
    output::write_csv(&dir.join("cells.csv"), &rows)?;
    output::write_jsonl(&dir.join("cells.jsonl"), &rows)?;
    let stats = output::aggregate(&rows);
    let plots = plots::make_plots(dir, &m, &stats, &info.references)?;
    let sinfo = summary::SummaryInfo { manifest: &m, references: &info.references, plots: &plots };
    let md = summary::write_summary(&dir.join("summary.md"), &sinfo, &stats)?;
    html::write_report(dir, &sinfo, &rows, &md)?;
    if !quiet {
        eprintln!("wrote {} and {}", dir.join("summary.md").display(), dir.join("index.html").display());
    }
    Ok(())
}

/// `photonlab run`.
pub fn run_cmd(args: &RunArgs) -> Result<()> {
    let r = run(args)?;
    if args.list {
        return Ok(());
    }
    outln!(
        "{}: ran {} cell(s), kept {} finished{}",
        r.dir.display(),
        r.ran,
        r.kept,
        if r.finalized { format!("; see {}", r.dir.join("summary.md").display()) } else { String::new() }
    );
    Ok(())
}

/// `photonlab merge`.
pub fn merge_cmd(args: &MergeArgs) -> Result<()> {
    for other in &args.from {
        let n = import_cells(&args.dir, other)?;
        eprintln!("{}: copied {n} finished cell(s) from {}", args.dir.display(), other.display());
    }
    finalize(&args.dir, false)
}

fn read_info(dir: &Path) -> Result<(RunInfo, Manifest)> {
    let info_path = dir.join("run.json");
    let text = std::fs::read_to_string(&info_path)
        .with_context(|| format!("{}: not an experiment directory (run `photonlab run` first)", info_path.display()))?;
    let info: RunInfo = serde_json::from_str(&text).with_context(|| format!("{}: unreadable", info_path.display()))?;
    let mtext = std::fs::read_to_string(dir.join("manifest.toml")).with_context(|| format!("{}: manifest copy missing", dir.display()))?;
    let mdir = info.manifest.parent().map(Path::to_path_buf).unwrap_or_default();
    let m = Manifest::parse(&mtext, &info.manifest, &mdir)?;
    Ok((info, m))
}

/// Copies the cells finished in `from` (for `dir`'s manifest and references) that
/// `dir` lacks; each record is copied last, so an interrupted copy is redone.
pub fn import_cells(dir: &Path, from: &Path) -> Result<usize> {
    let (info, m) = read_info(dir)?;
    let mut n = 0;
    for c in &m.cells {
        let Some(r) = info.references.get(c.scene) else { continue };
        if finished(dir, c, &r.key).is_some() {
            continue;
        }
        let Some(rec) = finished(from, c, &r.key) else { continue };
        let (src, dst) = (CellPaths::new(from, &c.stem), CellPaths::new(dir, &c.stem));
        let comp = |p: &CellPaths| m.component.as_ref().map_or_else(|| p.exr.clone(), |c| p.exr.with_extension(format!("{c}.exr")));
        let (sc, dc) = (comp(&src), comp(&dst));
        let mut files = vec![
            (src.exr.clone(), dst.exr.clone()),
            (src.png.clone(), dst.png.clone()),
            (src.relerr.clone(), dst.relerr.clone()),
            (src.signed.clone(), dst.signed.clone()),
            (sc, dc),
        ];
        for name in rec.strategies.iter().flatten() {
            let (a, b) = (src.strategy(name), dst.strategy(name));
            files.extend([(a.0, b.0), (a.1, b.1)]);
        }
        files.push((src.json.clone(), dst.json.clone()));
        for (a, b) in &files {
            if a.is_file() {
                let bytes = std::fs::read(a).with_context(|| format!("{}: cannot read", a.display()))?;
                write_atomic(b, &bytes)?;
            }
        }
        n += 1;
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_cells() {
        assert!("0/3".parse::<Shard>().is_err());
        assert!("4/3".parse::<Shard>().is_err());
        assert!("x".parse::<Shard>().is_err());
        let shards: Vec<Shard> = (1..=3).map(|i| format!("{i}/3").parse().unwrap()).collect();
        for idx in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.takes(idx)).count(), 1);
        }
    }

    #[test]
    fn fnv_known_value() {
        let mut h = Fnv::default();
        h.write(b"a");
        assert_eq!(h.0, 0xaf63dc4c8601ec8c);
    }
}

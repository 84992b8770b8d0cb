//! Tables and summary of an experiment: `cells.csv`, `cells.jsonl` (one row per cell
//! and repeat) and `summary.md`. Columns are documented in the README ("## Experiments").

use super::cell::{BiasVariance, CellRecord};
use super::manifest::Manifest;
use crate::film::write_atomic;
use anyhow::Result;
use serde_json::Value as Json;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

/// A finished cell with the bias/variance split of its configuration.
#[derive(Clone, Debug)]
pub struct Row {
    /// The cell's record.
    pub rec: CellRecord,
    /// Bias/variance split of its configuration (repeats ≥ 2).
    pub split: Option<BiasVariance>,
}

/// One configuration averaged over its repeats.
#[derive(Clone, Debug)]
pub struct ConfigStats {
    /// Configuration index.
    pub config_index: usize,
    /// Label.
    pub label: String,
    /// Strategy group.
    pub group: String,
    /// Swept values.
    pub values: BTreeMap<String, Json>,
    /// Stem of the first repeat (for images).
    pub first_stem: String,
    /// Repeats averaged.
    pub repeats: usize,
    /// Mean RMSE.
    pub rmse: f64,
    /// Mean relative MSE.
    pub relmse: f64,
    /// Mean MAE.
    pub mae: f64,
    /// Mean total time, seconds.
    pub time_s: f64,
    /// Mean accelerator build time.
    pub accel_build_s: f64,
    /// Mean pre-pass time.
    pub preprocess_s: f64,
    /// Mean render time.
    pub render_s: f64,
    /// Mean rays traced in the render pass.
    pub rays: f64,
    /// Mean of each integrator counter.
    pub extra: BTreeMap<String, f64>,
    /// Bias/variance split.
    pub split: Option<BiasVariance>,
}

/// Averages rows per configuration, in configuration order.
pub fn aggregate(rows: &[Row]) -> Vec<ConfigStats> {
    let mut by: BTreeMap<usize, Vec<&Row>> = BTreeMap::new();
    for r in rows {
        by.entry(r.rec.config_index).or_default().push(r);
    }
    by.into_iter()
        .map(|(ci, rs)| {
            let n = rs.len() as f64;
            let mean = |f: &dyn Fn(&CellRecord) -> f64| rs.iter().map(|r| f(&r.rec)).sum::<f64>() / n;
            let mut extra: BTreeMap<String, f64> = BTreeMap::new();
            for r in &rs {
                for (k, v) in &r.rec.extra {
                    *extra.entry(k.clone()).or_default() += v / n;
                }
            }
            let first = &rs[0].rec;
            ConfigStats {
                config_index: ci,
                label: first.label.clone(),
                group: first.group.clone(),
                values: first.values.clone(),
                first_stem: first.cell.clone(),
                repeats: rs.len(),
                rmse: mean(&|r| r.metrics.rmse),
                relmse: mean(&|r| r.metrics.relmse),
                mae: mean(&|r| r.metrics.mae),
                time_s: mean(&|r| r.time_total_s),
                accel_build_s: mean(&|r| r.accel_build_s),
                preprocess_s: mean(&|r| r.preprocess_s),
                render_s: mean(&|r| r.render_s),
                rays: mean(&|r| (r.camera_rays + r.shadow_rays) as f64),
                extra,
                split: rs[0].split,
            }
        })
        .collect()
}

/// The fixed leading columns of `cells.csv`.
pub const FIXED_COLUMNS: &[&str] = &[
    "cell",
    "index",
    "config_index",
    "label",
    "group",
    "repeat",
    "seed",
    "width",
    "height",
    "rmse",
    "mse",
    "relmse",
    "mae",
    "bias2",
    "variance",
    "rel_bias2",
    "rel_variance",
    "time_total_s",
    "accel_build_s",
    "preprocess_s",
    "render_s",
    "rays",
    "camera_rays",
    "shadow_rays",
    "threads",
    "accel_bytes",
    "nonfinite_samples",
];

fn json_cell(v: &Json) -> String {
    match v {
        Json::Null => String::new(),
        Json::String(s) => s.clone(),
        Json::Array(a) => a.iter().map(json_cell).collect::<Vec<_>>().join("x"),
        other => other.to_string(),
    }
}

fn csv_escape(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| x.to_string())
}

/// Writes `cells.csv`: the fixed columns, then every integrator counter seen (union,
/// sorted), then every configuration key as `cfg_KEY`.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let extra_keys: BTreeSet<&String> = rows.iter().flat_map(|r| r.rec.extra.keys()).collect();
    let cfg_json: Vec<serde_json::Map<String, Json>> =
        rows.iter().map(|r| serde_json::to_value(&r.rec.config).ok().and_then(|v| v.as_object().cloned()).unwrap_or_default()).collect();
    let cfg_keys: BTreeSet<&String> = cfg_json.iter().flat_map(|m| m.keys()).collect();
    let mut out = String::new();
    let mut header: Vec<String> = FIXED_COLUMNS.iter().map(|s| s.to_string()).collect();
    header.extend(extra_keys.iter().map(|k| k.to_string()));
    header.extend(cfg_keys.iter().map(|k| format!("cfg_{k}")));
    out.push_str(&header.iter().map(|h| csv_escape(h)).collect::<Vec<_>>().join(","));
    out.push('\n');
    for (r, cfg) in rows.iter().zip(&cfg_json) {
        let c = &r.rec;
        let mut f: Vec<String> = vec![
            c.cell.clone(),
            c.index.to_string(),
            c.config_index.to_string(),
            c.label.clone(),
            c.group.clone(),
            c.repeat.to_string(),
            c.seed.to_string(),
            c.width.to_string(),
            c.height.to_string(),
            c.metrics.rmse.to_string(),
            c.metrics.mse.to_string(),
            c.metrics.relmse.to_string(),
            c.metrics.mae.to_string(),
            opt(r.split.map(|b| b.bias2)),
            opt(r.split.map(|b| b.variance)),
            opt(r.split.map(|b| b.rel_bias2)),
            opt(r.split.map(|b| b.rel_variance)),
            c.time_total_s.to_string(),
            c.accel_build_s.to_string(),
            c.preprocess_s.to_string(),
            c.render_s.to_string(),
            (c.camera_rays + c.shadow_rays).to_string(),
            c.camera_rays.to_string(),
            c.shadow_rays.to_string(),
            c.threads.to_string(),
            c.accel_bytes.to_string(),
            c.nonfinite_samples.to_string(),
        ];
        f.extend(extra_keys.iter().map(|k| c.extra.get(*k).map_or(String::new(), |v| v.to_string())));
        f.extend(cfg_keys.iter().map(|k| cfg.get(*k).map_or(String::new(), json_cell)));
        out.push_str(&f.iter().map(|s| csv_escape(s)).collect::<Vec<_>>().join(","));
        out.push('\n');
    }
    write_atomic(path, out.as_bytes())
}

/// Writes `cells.jsonl`: each line the cell's record (as in `cells/STEM.json`) plus
/// `bias2`, `variance`, `rel_bias2` and `rel_variance` of its configuration (null
/// without repeats).
pub fn write_jsonl(path: &Path, rows: &[Row]) -> Result<()> {
    let mut out = String::new();
    for r in rows {
        let mut v = serde_json::to_value(&r.rec)?;
        if let Some(o) = v.as_object_mut() {
            let f = |g: fn(&BiasVariance) -> f64| r.split.as_ref().map_or(Json::Null, |b| Json::from(g(b)));
            o.insert("bias2".into(), f(|b| b.bias2));
            o.insert("variance".into(), f(|b| b.variance));
            o.insert("rel_bias2".into(), f(|b| b.rel_bias2));
            o.insert("rel_variance".into(), f(|b| b.rel_variance));
        }
        out.push_str(&serde_json::to_string(&v)?);
        out.push('\n');
    }
    write_atomic(path, out.as_bytes())
}

/// Three significant digits, scientific for very small or large numbers.
pub fn sig(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return v.to_string();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.2e}")
    } else {
        let digits = (2 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    }
}

fn count(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 { format!("{}", v as i64) } else { sig(v) }
}

/// Error budgets: up to four relative-MSE levels spread log-evenly over the observed range,
/// rounded to two significant digits.
pub fn budgets(stats: &[ConfigStats]) -> Vec<f64> {
    let errs: Vec<f64> = stats.iter().map(|s| s.relmse).filter(|e| e.is_finite() && *e > 0.0).collect();
    let (lo, hi) = errs.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &e| (a.min(e), b.max(e)));
    if errs.is_empty() {
        return vec![];
    }
    let mut out: Vec<f64> = Vec::new();
    let steps = 4;
    for i in 0..steps {
        let t = i as f64 / (steps - 1) as f64;
        let b = (lo.ln() * (1.0 - t) + hi.ln() * t).exp();
        // Round up, so the best configuration always meets the smallest budget.
        let p = 10f64.powf(b.log10().floor() - 1.0);
        let b = (b / p).ceil() * p;
        if !out.iter().any(|x| (x - b).abs() <= 1e-12 * b) {
            out.push(b);
        }
    }
    out
}

/// Context for the summary's header.
pub struct SummaryInfo<'a> {
    /// The manifest.
    pub manifest: &'a Manifest,
    /// The scenes' references.
    pub references: &'a [super::RefInfo],
    /// Plots as (title, file name relative to the experiment directory).
    pub plots: &'a [(String, String)],
}

/// Writes `summary.md`.
pub fn write_summary(path: &Path, info: &SummaryInfo, stats: &[ConfigStats]) -> Result<()> {
    let m = info.manifest;
    let mut s = String::new();
    let _ = writeln!(s, "# Experiment `{}`\n", m.name);
    if !m.description.trim().is_empty() {
        let _ = writeln!(s, "{}\n", m.description.trim());
    }
    let scenes: Vec<String> = m
        .scenes
        .iter()
        .zip(info.references)
        .map(|(sc, r)| {
            let what = match &sc.source {
                super::manifest::SceneSource::Builtin(b) => format!("built-in `{b}`"),
                super::manifest::SceneSource::File(p) => format!("`{}`", p.display()),
                super::manifest::SceneSource::Empty => "defined in the manifest".into(),
            };
            let models = if sc.meshes.is_empty() { String::new() } else { format!(" + {} model(s)", sc.meshes.len()) };
            format!("{what}{models} (reference: {})", r.description)
        })
        .collect();
    let _ = writeln!(
        s,
        "Scene {}; {}×{} pixels. {} configuration(s) × {} repeat(s) = {} cells; photonlab {}. \
         Generated by `photonlab run {}`; every row of `cells.csv` / `cells.jsonl` is one cell.\n",
        scenes.join("; "),
        m.resolution[0],
        m.resolution[1],
        m.configurations(),
        m.repeats,
        m.cells.len(),
        env!("CARGO_PKG_VERSION"),
        m.path.display()
    );
    let has_bv = stats.iter().any(|c| c.split.is_some());
    let _ = writeln!(s, "## Results (mean over repeats)\n");
    let _ = write!(s, "| configuration | RMSE | relMSE | MAE |");
    if has_bv {
        let _ = write!(s, " rel. bias² | rel. variance |");
    }
    let _ = writeln!(s, " time (s) | rays |");
    let _ = write!(s, "|---|---:|---:|---:|");
    if has_bv {
        let _ = write!(s, "---:|---:|");
    }
    let _ = writeln!(s, "---:|---:|");
    for c in stats {
        let _ = write!(s, "| {} | {} | {} | {} |", c.label, sig(c.rmse), sig(c.relmse), sig(c.mae));
        if has_bv {
            let _ = write!(
                s,
                " {} | {} |",
                c.split.map_or("–".into(), |b| sig(b.rel_bias2)),
                c.split.map_or("–".into(), |b| sig(b.rel_variance))
            );
        }
        let _ = writeln!(s, " {} | {} |", sig(c.time_s), count(c.rays.round()));
    }

    // Budgets compare configurations of one scene (errors of different scenes are
    // not comparable).
    let mut scenes: Vec<Option<&Json>> = Vec::new();
    for c in stats {
        let sc = c.values.get("scene");
        if !scenes.contains(&sc) {
            scenes.push(sc);
        }
    }
    let mut header_done = false;
    for sc in scenes {
        let of_scene: Vec<ConfigStats> = stats.iter().filter(|c| c.values.get("scene") == sc).cloned().collect();
        let b = budgets(&of_scene);
        if b.is_empty() {
            continue;
        }
        if !header_done {
            let _ = writeln!(s, "\n## Best configuration per error budget\n");
            let _ = writeln!(s, "The fastest configuration whose mean relative MSE is within each budget.\n");
            header_done = true;
        }
        if let Some(name) = sc {
            let _ = writeln!(s, "Scene `{}`:\n", name.as_str().unwrap_or_default());
        }
        let _ = writeln!(s, "| relMSE ≤ | fastest configuration | its relMSE | time (s) |\n|---:|---|---:|---:|");
        for budget in b {
            let best = of_scene
                .iter()
                .filter(|c| c.relmse <= budget)
                .min_by(|x, y| x.time_s.partial_cmp(&y.time_s).unwrap_or(std::cmp::Ordering::Equal));
            if let Some(c) = best {
                let _ = writeln!(s, "| {} | {} | {} | {} |", sig(budget), c.label, sig(c.relmse), sig(c.time_s));
            }
        }
        let _ = writeln!(s);
    }

    // Phase times: accelerator build, the integrator's own timed phases (extra keys
    // ending in `_s`), any remaining pre-pass time, render.
    let phase_keys: BTreeSet<&String> = stats.iter().flat_map(|c| c.extra.keys()).filter(|k| k.ends_with("_s")).collect();
    let _ = writeln!(s, "\n## Time of each phase (s, mean over repeats)\n");
    let _ = write!(s, "| configuration | accel build |");
    for k in &phase_keys {
        let _ = write!(s, " {} |", k.trim_end_matches("_s").replace('_', " "));
    }
    let _ = writeln!(s, " render | total |");
    let _ = writeln!(s, "|---|{}", "---:|".repeat(phase_keys.len() + 3));
    for c in stats {
        let _ = write!(s, "| {} | {} |", c.label, sig(c.accel_build_s));
        for k in &phase_keys {
            let _ = write!(s, " {} |", c.extra.get(*k).map_or("–".into(), |v| sig(*v)));
        }
        let _ = writeln!(s, " {} | {} |", sig(c.render_s), sig(c.time_s));
    }

    let counter_keys: BTreeSet<&String> = stats.iter().flat_map(|c| c.extra.keys()).filter(|k| !k.ends_with("_s")).collect();
    if !counter_keys.is_empty() {
        let _ = writeln!(s, "\n## Integrator counters (mean over repeats)\n");
        let _ = write!(s, "| configuration |");
        for k in &counter_keys {
            let _ = write!(s, " {} |", k.replace('_', " "));
        }
        let _ = writeln!(s, "\n|---|{}", "---:|".repeat(counter_keys.len()));
        for c in stats {
            let _ = write!(s, "| {} |", c.label);
            for k in &counter_keys {
                let _ = write!(s, " {} |", c.extra.get(*k).map_or("–".into(), |v| count(*v)));
            }
            let _ = writeln!(s);
        }
    }

    if !info.plots.is_empty() {
        let _ = writeln!(s, "\n## Plots\n");
        for (title, file) in info.plots {
            let _ = writeln!(s, "### {title}\n\n![{title}]({file})\n");
        }
    }

    let _ = writeln!(s, "## Images\n");
    let _ = writeln!(
        s,
        "First repeat of each configuration; the error image shows the per-pixel relative error \
         √(mean over RGB of (x − ref)² / (ref² + 0.01)) on a log scale from 0.001 (black) to 1 (pale yellow).\n"
    );
    for r in info.references {
        let png = Path::new(&r.file).with_extension("png");
        let _ = writeln!(s, "Reference `{}`:\n\n![reference {}]({})\n", r.scene, r.scene, png.display());
    }
    let _ = writeln!(s, "| configuration | image | relative error |\n|---|---|---|");
    for c in stats {
        let _ = writeln!(s, "| {} | ![](cells/{}.png) | ![](cells/{}.relerr.png) |", c.label, c.first_stem, c.first_stem);
    }
    write_atomic(path, s.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formatting_and_budgets() {
        assert_eq!(sig(0.012345), "0.0123");
        assert_eq!(sig(12.345), "12.3");
        assert_eq!(sig(1234.5), "1234");
        assert_eq!(sig(1.5e-5), "1.50e-5");
        assert_eq!(csv_escape("a,b"), "\"a,b\"");
        assert_eq!(csv_escape("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(json_cell(&serde_json::json!([64, 32])), "64x32");
        assert_eq!(json_cell(&Json::Null), "");
    }
}

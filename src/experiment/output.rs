//! Tables of an experiment: `cells.csv` and `cells.jsonl` (one row per cell and
//! repeat), and the per-configuration means the summary, plots and report use.
//! Columns are documented in docs/experiments.md ("cells.csv").

use super::cell::{BiasVariance, CellRecord};
use super::metrics::{ComponentMetrics, RobustMetrics};
use crate::film::write_atomic;
use anyhow::{Context, Result};
use serde_json::Value as Json;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A finished cell with the bias/variance split of its configuration.
#[derive(Clone, Debug)]
pub struct Row {
    /// The cell's record.
    pub rec: CellRecord,
    /// Bias/variance split of its configuration (repeats ≥ 2).
    pub split: Option<BiasVariance>,
    /// Repeats of its configuration.
    pub repeats: usize,
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
    /// Robust errors: means over repeats, except `max_pixel_share` (largest) and
    /// `worst_block` (the repeat with the largest magnitude).
    pub robust: RobustMetrics,
    /// Key of the reference the errors are measured against.
    pub reference_key: String,
    /// Errors of the measured component, means over repeats (worst block: largest magnitude).
    pub component: Option<ComponentMetrics>,
}

/// Whether a bias² estimate is resolved: positive and above the noise of the mean
/// image it was measured on (variance / repeats), which the unbiased estimator
/// subtracts and which dominates it otherwise. This is the relative split
/// (`rel_bias2`), the one the summary and plots use.
pub fn bias_resolved(b: &BiasVariance, repeats: usize) -> bool {
    resolved(b.rel_bias2, b.rel_variance, repeats)
}

/// The same test on the unweighted split (`bias2` against `variance`). The two
/// weightings resolve independently: bright pixels dominate `bias2`, dark ones
/// `rel_bias2`, so one may be resolved while the other is still negative.
pub fn abs_bias_resolved(b: &BiasVariance, repeats: usize) -> bool {
    resolved(b.bias2, b.variance, repeats)
}

fn resolved(bias2: f64, variance: f64, repeats: usize) -> bool {
    bias2 > 0.0 && bias2 > variance / repeats.max(1) as f64
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
                robust: RobustMetrics {
                    relmse_trimmed: mean(&|r| r.robust.relmse_trimmed),
                    smape: mean(&|r| r.robust.smape),
                    max_pixel_share: rs.iter().map(|r| r.rec.robust.max_pixel_share).fold(0.0, f64::max),
                    ..rs.iter().map(|r| r.rec.robust).max_by(|a, b| a.worst_block.abs().total_cmp(&b.worst_block.abs())).unwrap_or_default()
                },
                reference_key: first.reference_key.clone(),
                component: mean_component(&rs),
            }
        })
        .collect()
}

fn mean_component(rs: &[&Row]) -> Option<ComponentMetrics> {
    let cs: Vec<&ComponentMetrics> = rs.iter().filter_map(|r| r.rec.component.as_ref()).collect();
    let first = cs.first()?;
    let n = cs.len() as f64;
    let mean = |f: &dyn Fn(&ComponentMetrics) -> f64| cs.iter().map(|c| f(c)).sum::<f64>() / n;
    let worst = cs.iter().map(|c| c.robust).max_by(|a, b| a.worst_block.abs().total_cmp(&b.worst_block.abs())).unwrap_or_default();
    Some(ComponentMetrics {
        name: first.name.clone(),
        relmse: mean(&|c| c.relmse),
        robust: RobustMetrics {
            relmse_trimmed: mean(&|c| c.robust.relmse_trimmed),
            smape: mean(&|c| c.robust.smape),
            max_pixel_share: cs.iter().map(|c| c.robust.max_pixel_share).fold(0.0, f64::max),
            ..worst
        },
    })
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
    "relmse_trimmed",
    "smape",
    "max_pixel_share",
    "worst_block",
    "worst_block_x",
    "worst_block_y",
    "component",
    "comp_relmse",
    "comp_relmse_trimmed",
    "comp_smape",
    "comp_worst_block",
    "bias2",
    "variance",
    "rel_bias2",
    "rel_variance",
    "bias_note",
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

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| x.to_string())
}

/// `bias2` and `rel_bias2` as table values: each empty unless resolved by its own
/// test ([`abs_bias_resolved`], [`bias_resolved`]), so never a negative number.
fn bias_values(split: Option<&BiasVariance>, repeats: usize) -> (Option<f64>, Option<f64>) {
    match split {
        Some(b) => (abs_bias_resolved(b, repeats).then_some(b.bias2), bias_resolved(b, repeats).then_some(b.rel_bias2)),
        None => (None, None),
    }
}

/// Why `bias2` or `rel_bias2` is empty, or nothing.
pub fn bias_note(split: Option<&BiasVariance>, repeats: usize) -> String {
    match split {
        None if repeats < 2 => "one repeat: no bias/variance split (needs >= 2)".into(),
        None => "no split".into(),
        Some(b) => match (abs_bias_resolved(b, repeats), bias_resolved(b, repeats)) {
            (true, true) => String::new(),
            (false, true) => format!("bias2 not resolved by {repeats} repeats (bias2 <= variance/repeats); rel_bias2 is"),
            (true, false) => format!("rel_bias2 not resolved by {repeats} repeats (rel_bias2 <= rel_variance/repeats); bias2 is"),
            (false, false) => format!("bias not resolved by {repeats} repeats (bias2 <= variance/repeats)"),
        },
    }
}

/// Writes `cells.csv` (see [`csv_bytes`]).
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    write_atomic(path, &csv_bytes(rows)?)
}

/// The text of `cells.csv` (with the `csv` crate: one schema for header and rows, RFC
/// 4180 quoting): the fixed columns, then every integrator counter seen (union,
/// sorted), then every configuration key as `cfg_KEY`.
pub fn csv_bytes(rows: &[Row]) -> Result<Vec<u8>> {
    let extra_keys: BTreeSet<&String> = rows.iter().flat_map(|r| r.rec.extra.keys()).collect();
    let cfg_json: Vec<serde_json::Map<String, Json>> =
        rows.iter().map(|r| serde_json::to_value(&r.rec.config).ok().and_then(|v| v.as_object().cloned()).unwrap_or_default()).collect();
    let cfg_keys: BTreeSet<&String> = cfg_json.iter().flat_map(|m| m.keys()).collect();
    let mut w = csv::WriterBuilder::new().terminator(csv::Terminator::Any(b'\n')).from_writer(Vec::new());
    let mut header: Vec<String> = FIXED_COLUMNS.iter().map(|s| s.to_string()).collect();
    header.extend(extra_keys.iter().map(|k| k.to_string()));
    header.extend(cfg_keys.iter().map(|k| format!("cfg_{k}")));
    w.write_record(&header)?;
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
            c.robust.relmse_trimmed.to_string(),
            c.robust.smape.to_string(),
            c.robust.max_pixel_share.to_string(),
            c.robust.worst_block.to_string(),
            c.robust.worst_block_at[0].to_string(),
            c.robust.worst_block_at[1].to_string(),
            c.component.as_ref().map_or(String::new(), |x| x.name.clone()),
            opt(c.component.as_ref().map(|x| x.relmse)),
            opt(c.component.as_ref().map(|x| x.robust.relmse_trimmed)),
            opt(c.component.as_ref().map(|x| x.robust.smape)),
            opt(c.component.as_ref().map(|x| x.robust.worst_block)),
            opt(bias_values(r.split.as_ref(), r.repeats).0),
            opt(r.split.map(|b| b.variance)),
            opt(bias_values(r.split.as_ref(), r.repeats).1),
            opt(r.split.map(|b| b.rel_variance)),
            bias_note(r.split.as_ref(), r.repeats),
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
        debug_assert_eq!(f.len(), FIXED_COLUMNS.len());
        f.extend(extra_keys.iter().map(|k| c.extra.get(*k).map_or(String::new(), |v| v.to_string())));
        f.extend(cfg_keys.iter().map(|k| cfg.get(*k).map_or(String::new(), json_cell)));
        w.write_record(&f)?;
    }
    w.into_inner().context("cannot write cells.csv")
}

/// Writes `cells.jsonl`: each line the cell's record (as in `cells/STEM.json`) plus
/// `bias2`, `variance`, `rel_bias2` and `rel_variance` of its configuration (null
/// without repeats; the bias² null too where it is not resolved, see `bias_note`).
pub fn write_jsonl(path: &Path, rows: &[Row]) -> Result<()> {
    let mut out = String::new();
    for r in rows {
        let mut v = serde_json::to_value(&r.rec)?;
        if let Some(o) = v.as_object_mut() {
            let f = |g: fn(&BiasVariance) -> f64| r.split.as_ref().map_or(Json::Null, |b| Json::from(g(b)));
            let (bias2, rel_bias2) = bias_values(r.split.as_ref(), r.repeats);
            o.insert("bias2".into(), bias2.map_or(Json::Null, Json::from));
            o.insert("variance".into(), f(|b| b.variance));
            o.insert("rel_bias2".into(), rel_bias2.map_or(Json::Null, Json::from));
            o.insert("rel_variance".into(), f(|b| b.rel_variance));
            o.insert("bias_note".into(), Json::from(bias_note(r.split.as_ref(), r.repeats)));
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

/// An integer count, or [`sig`] for fractional values.
pub fn count(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 { format!("{}", v as i64) } else { sig(v) }
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
        assert_eq!(json_cell(&serde_json::json!([64, 32])), "64x32");
        assert_eq!(json_cell(&Json::Null), "");
    }

    #[test]
    fn a_bias_below_its_noise_is_never_printed() {
        let split = |rel_bias2: f64| BiasVariance { bias2: rel_bias2, variance: 0.04, rel_bias2, rel_variance: 0.04 };
        // Unbiased estimates of a zero bias come out ±; with 4 repeats the noise of
        // the mean image is variance / 4 = 0.01.
        for (b, shown) in [(-2e-4, false), (0.0, false), (0.009, false), (0.02, true)] {
            let s = split(b);
            assert_eq!(bias_resolved(&s, 4), shown, "{b}");
            assert_eq!(bias_note(Some(&s), 4).is_empty(), shown, "{b}");
        }
        assert!(bias_note(None, 1).contains("one repeat"));
    }

    /// quick.toml's first configuration: `rel_bias2` resolved while the unweighted
    /// `bias2` estimate came out −1.66e-4 — `cells.csv` and `cells.jsonl` must show
    /// the one and leave the other empty (null), never print it negative.
    #[test]
    fn a_negative_bias2_beside_a_resolved_rel_bias2_is_left_empty() {
        let split = BiasVariance { bias2: -1.66e-4, variance: 2.8e-3, rel_bias2: 3.18e-3, rel_variance: 3.32e-3 };
        let mut rec: CellRecord = serde_json::from_value(serde_json::json!({
            "cell": "c_r0", "index": 0, "config_index": 0, "label": "c", "group": "c", "repeat": 0, "seed": 0,
            "values": {}, "width": 2, "height": 2, "metrics": {"mse": 0.0, "rmse": 0.0, "relmse": 0.0, "mae": 0.0},
            "accel_build_s": 0.0, "preprocess_s": 0.0, "render_s": 0.0, "time_total_s": 0.0, "camera_rays": 0,
            "shadow_rays": 0, "threads": 1, "accel_bytes": 0, "nonfinite_samples": 0, "extra": {},
            "config": {}, "reference_key": "k", "version": "0"
        }))
        .unwrap();
        let rows: Vec<Row> = (0..2)
            .map(|i| {
                rec.repeat = i;
                rec.cell = format!("c_r{i}");
                Row { rec: rec.clone(), split: Some(split), repeats: 2 }
            })
            .collect();
        let text = String::from_utf8(csv_bytes(&rows).unwrap()).unwrap();
        let mut rd = csv::Reader::from_reader(text.as_bytes());
        let header = rd.headers().unwrap().clone();
        let col = |name: &str| header.iter().position(|h| h == name).unwrap();
        for rec in rd.records() {
            let rec = rec.unwrap();
            assert_eq!(&rec[col("bias2")], "", "{text}");
            assert_eq!(rec[col("rel_bias2")].parse::<f64>().unwrap(), 3.18e-3);
            assert_eq!(rec[col("variance")].parse::<f64>().unwrap(), 2.8e-3);
            assert!(rec[col("bias_note")].starts_with("bias2 not resolved"), "{}", &rec[col("bias_note")]);
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cells.jsonl");
        write_jsonl(&p, &rows).unwrap();
        for line in std::fs::read_to_string(&p).unwrap().lines() {
            let v: Json = serde_json::from_str(line).unwrap();
            assert!(v["bias2"].is_null() && v["rel_bias2"].as_f64() == Some(3.18e-3), "{line}");
        }
        // Both resolved: both printed, no note.
        let both = BiasVariance { bias2: 2e-3, ..split };
        assert_eq!(bias_values(Some(&both), 2), (Some(2e-3), Some(3.18e-3)));
        assert_eq!(bias_note(Some(&both), 2), "");
    }
}

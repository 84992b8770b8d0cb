//! Plots of an experiment (PNG + SVG under `plots/`): error vs time, error vs each
//! numeric axis with fitted convergence slopes, bias/variance bars and phase times.
//! The error plots draw each reference's own noise (relative MSE from its two halves)
//! as a band: a measured error cannot fall below it, so a curve that meets it has
//! reached what the reference resolves, not stopped converging.

use super::RefInfo;
use super::cell::BiasVariance;
use super::manifest::Manifest;
use super::output::ConfigStats;
use super::output::sig;
use crate::plot::{Band, LinePlot, Series, StackedBars, bar_plot, line_plot_with_bands, log_log_slope};
use anyhow::Result;
use std::collections::BTreeMap;
use std::path::Path;

/// Axis label (with unit) for a swept key.
fn axis_label(key: &str) -> String {
    match key {
        "spp" => "samples per pixel".into(),
        "photons" => "photons stored in the global maps".into(),
        "caustic_photons" => "photons stored in the caustic map".into(),
        "emit_photons" => "photon paths emitted".into(),
        "gather_samples" => "final-gather rays (per pixel, or per camera sample with gather_per = sample)".into(),
        "direct_samples" => "shadow rays per shading point".into(),
        "k" | "caustic_k" => format!("{key} (photons per estimate)"),
        "max_radius" | "caustic_max_radius" => format!("{key} (scene units)"),
        "max_depth" => "maximum depth (bounces)".into(),
        _ => key.to_string(),
    }
}

fn short(c: &ConfigStats) -> String {
    // Bars have little room: the values alone.
    let v: Vec<String> = c.values.values().map(|v| v.as_str().map_or_else(|| v.to_string(), str::to_string)).collect();
    if v.is_empty() { c.label.clone() } else { v.join(" ") }
}

/// Whether a log axis shows labels: plotters puts log ticks only where the data
/// span a decade, so narrower ranges get a linear axis.
fn log_ok(vals: impl Iterator<Item = f64>) -> bool {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in vals {
        if v <= 0.0 || !v.is_finite() {
            return false;
        }
        lo = lo.min(v);
        hi = hi.max(v);
    }
    lo.is_finite() && hi / lo >= 10.0
}

/// The integrator's timed phases of a configuration (`extra` keys ending in `_s`)
/// that do not overlap: taken longest first while they fit in the pre-pass time.
/// A sub-phase is never longer than the phase containing it, so parents are taken
/// first and their children no longer fit.
fn disjoint_phases(c: &ConfigStats) -> Vec<&String> {
    let mut keys: Vec<(&String, f64)> = c.extra.iter().filter(|(k, _)| k.ends_with("_s")).map(|(k, v)| (k, *v)).collect();
    keys.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(b.0)));
    let budget = c.preprocess_s * 1.001 + 1e-6;
    let mut sum = 0.0;
    let mut out = Vec::new();
    for (k, v) in keys {
        if sum + v <= budget {
            sum += v;
            out.push(k);
        }
    }
    out
}

/// The noise floor of each reference whose noise is known: a band from the bottom of
/// the axis to its relative MSE.
pub fn noise_bands(refs: &[RefInfo]) -> Vec<Band> {
    refs.iter()
        .filter_map(|r| {
            let n = r.noise_relmse.filter(|n| n.is_finite() && *n > 0.0)?;
            Some(Band { name: format!("noise of the {} reference (relMSE {})", r.scene, sig(n)), lo: 0.0, hi: n })
        })
        .collect()
}

/// The scene a configuration ran on, when the manifest has several.
fn scene_of(c: &ConfigStats) -> Option<&str> {
    c.values.get("scene").and_then(|v| v.as_str())
}

/// The scenes of a multi-scene experiment in first-seen order (empty with one scene).
fn scenes(stats: &[ConfigStats]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for sc in stats.iter().filter_map(scene_of) {
        if !out.iter().any(|s| s == sc) {
            out.push(sc.to_string());
        }
    }
    out
}

/// A scene name as a file-name part: anything but letters, digits, `-` and `_` becomes `_`.
fn file_safe(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

/// Relative MSE against time, one line per strategy group (a progressive cell adds its
/// recorded passes), on log axes where every value is positive.
fn error_vs_time(stem: &Path, title: &str, stats: &[ConfigStats], bands: &[Band]) -> Result<()> {
    let mut groups: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut order: Vec<String> = Vec::new();
    for c in stats {
        if !groups.contains_key(&c.group) {
            order.push(c.group.clone());
        }
        let curve = super::cell::pass_curve(&c.extra);
        let g = groups.entry(c.group.clone()).or_default();
        g.extend(curve.iter().map(|&(_, t, e)| (t, e)));
        g.push((c.time_s, c.relmse));
    }
    let series: Vec<Series> = order
        .iter()
        .map(|g| {
            let mut p = groups[g].clone();
            p.sort_by(|a, b| a.0.total_cmp(&b.0));
            Series { name: g.clone(), points: p }
        })
        .collect();
    let (log_x, log_y) = (
        log_ok(series.iter().flat_map(|s| s.points.iter().map(|p| p.0))),
        log_ok(series.iter().flat_map(|s| s.points.iter().map(|p| p.1))),
    );
    line_plot_with_bands(
        stem,
        &LinePlot {
            title: title.to_string(),
            x_label: format!("time: accel build + pre-pass + render (s{})", if log_x { ", log" } else { "" }),
            y_label: format!("relative MSE vs reference (1{})", if log_y { ", log" } else { "" }),
            log_x,
            log_y,
            series,
        },
        bands,
    )?;
    Ok(())
}

/// Draws every plot the data supports; returns (title, relative PNG path) pairs.
pub fn make_plots(dir: &Path, m: &Manifest, stats: &[ConfigStats], refs: &[RefInfo]) -> Result<Vec<(String, String)>> {
    let pdir = dir.join("plots");
    let mut out = Vec::new();
    let bands = noise_bands(refs);

    // Error vs time, one line per strategy (points along the numeric axes); with
    // several scenes, also one plot per scene with only that scene's noise floor.
    let title = "Relative MSE vs render time".to_string();
    error_vs_time(&pdir.join("error_vs_time"), &format!("{}: {title}", m.name), stats, &bands)?;
    out.push((title.clone(), "plots/error_vs_time.png".into()));
    let all_scenes = scenes(stats);
    for scene in all_scenes.iter().filter(|_| all_scenes.len() > 1) {
        let of_scene: Vec<ConfigStats> = stats.iter().filter(|c| scene_of(c) == Some(scene)).cloned().collect();
        let ref_of_scene: Vec<RefInfo> = refs.iter().filter(|r| &r.scene == scene).cloned().collect();
        let stem = format!("error_vs_time-{}", file_safe(scene));
        error_vs_time(&pdir.join(&stem), &format!("{}: {title}, {scene}", m.name), &of_scene, &noise_bands(&ref_of_scene))?;
        out.push((format!("{title}: {scene}"), format!("plots/{stem}.png")));
    }

    // Error vs each numeric axis; one line per combination of the other axes, with
    // the least-squares log–log slope in the legend.
    for axis in &m.numeric_axes {
        let mut lines: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
        let mut order: Vec<String> = Vec::new();
        for c in stats {
            let Some(x) = c.values.get(axis).and_then(|v| v.as_f64()) else { continue };
            let others: Vec<String> = c
                .values
                .iter()
                .filter(|(k, _)| *k != axis)
                .map(|(k, v)| format!("{k}={}", v.as_str().map_or_else(|| v.to_string(), str::to_string)))
                .collect();
            let key = if others.is_empty() { "all".to_string() } else { others.join(" ") };
            if !lines.contains_key(&key) {
                order.push(key.clone());
            }
            lines.entry(key).or_default().push((x, c.relmse));
        }
        let positive = lines.values().flatten().all(|p| p.0 > 0.0);
        let series: Vec<Series> = order
            .iter()
            .map(|k| {
                let mut p = lines[k].clone();
                p.sort_by(|a, b| a.0.total_cmp(&b.0));
                let name = match log_log_slope(&p).filter(|_| positive) {
                    Some(s) => format!("{k} (slope {s:.2})"),
                    None => k.clone(),
                };
                Series { name, points: p }
            })
            .collect();
        let title = format!("Relative MSE vs {axis}");
        let log_x = positive && log_ok(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
        let log_y = log_ok(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
        let stem = format!("error_vs_{axis}");
        line_plot_with_bands(
            &pdir.join(&stem),
            &LinePlot {
                title: format!("{}: {title} (log–log slope in legend)", m.name),
                x_label: format!("{}{}", axis_label(axis), if log_x { " (log)" } else { "" }),
                y_label: format!("relative MSE vs reference (1{})", if log_y { ", log" } else { "" }),
                log_x,
                log_y,
                series,
            },
            &bands,
        )?;
        out.push((title, format!("plots/{stem}.png")));
    }

    // Bias² / variance bars.
    let bv: Vec<(&ConfigStats, BiasVariance)> = stats.iter().filter_map(|c| c.split.map(|s| (c, s))).collect();
    if !bv.is_empty() {
        let title = "Relative MSE split into bias² and variance".to_string();
        bar_plot(
            &pdir.join("bias_variance"),
            &StackedBars {
                title: format!("{}: {title} ({} repeats)", m.name, m.repeats),
                y_label: "relative MSE (1)".into(),
                categories: bv.iter().map(|(c, _)| short(c)).collect(),
                layers: vec![
                    ("bias² (relative)".into(), bv.iter().map(|(_, s)| s.rel_bias2.max(0.0)).collect()),
                    ("variance (relative)".into(), bv.iter().map(|(_, s)| s.rel_variance).collect()),
                ],
            },
        )?;
        out.push((title, "plots/bias_variance.png".into()));
    }

    // Phase times: accel build, the integrator's timed phases, the rest of the
    // pre-pass, render. Integrators may also report sub-phases (a kd-tree build
    // inside the photon pass), so per configuration only a disjoint set is stacked.
    let chosen: Vec<Vec<&String>> = stats.iter().map(disjoint_phases).collect();
    let mut phase_keys: Vec<&String> = chosen.iter().flatten().copied().collect();
    phase_keys.sort();
    phase_keys.dedup();
    let mut layers: Vec<(String, Vec<f64>)> = vec![("accel build".into(), stats.iter().map(|c| c.accel_build_s).collect())];
    for k in &phase_keys {
        let vals =
            stats.iter().zip(&chosen).map(|(c, ch)| if ch.contains(k) { c.extra.get(*k).copied().unwrap_or(0.0) } else { 0.0 }).collect();
        layers.push((k.trim_end_matches("_s").replace('_', " "), vals));
    }
    let rest: Vec<f64> = stats
        .iter()
        .zip(&chosen)
        .map(|(c, ch)| (c.preprocess_s - ch.iter().map(|k| c.extra.get(*k).copied().unwrap_or(0.0)).sum::<f64>()).max(0.0))
        .collect();
    if rest.iter().any(|r| *r > 1e-3) || phase_keys.is_empty() {
        layers.push((if phase_keys.is_empty() { "pre-pass" } else { "other pre-pass" }.into(), rest));
    }
    layers.push(("render".into(), stats.iter().map(|c| c.render_s).collect()));
    let title = "Time of each phase".to_string();
    bar_plot(
        &pdir.join("phase_times"),
        &StackedBars {
            title: format!("{}: {title}", m.name),
            y_label: "wall time (s)".into(),
            categories: stats.iter().map(short).collect(),
            layers,
        },
    )?;
    out.push((title, "plots/phase_times.png".into()));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_phase_times_are_not_stacked_twice() {
        let extra: BTreeMap<String, f64> = [
            ("photon_pass_s", 0.15),
            ("photon_trace_s", 0.12),
            ("kdtree_build_s", 0.04),
            ("precompute_s", 0.4),
            ("prefill_s", 0.19),
            ("photons_emitted", 9.0),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let c = ConfigStats {
            config_index: 0,
            label: "x".into(),
            group: "x".into(),
            values: BTreeMap::new(),
            first_stem: "x_r0".into(),
            repeats: 1,
            rmse: 0.0,
            relmse: 0.0,
            mae: 0.0,
            time_s: 1.0,
            accel_build_s: 0.0,
            preprocess_s: 0.7401,
            render_s: 0.25,
            rays: 0.0,
            extra,
            split: None,
            robust: Default::default(),
            reference_key: String::new(),
            component: None,
        };
        let mut got: Vec<&str> = disjoint_phases(&c).into_iter().map(String::as_str).collect();
        got.sort();
        assert_eq!(got, ["photon_pass_s", "precompute_s", "prefill_s"]);
    }

    fn config(i: usize, group: &str, time_s: f64, relmse: f64) -> ConfigStats {
        ConfigStats {
            config_index: i,
            label: format!("{group} {i}"),
            group: group.into(),
            values: BTreeMap::new(),
            first_stem: format!("c{i}_r0"),
            repeats: 1,
            rmse: relmse.sqrt(),
            relmse,
            mae: 0.0,
            time_s,
            accel_build_s: 0.0,
            preprocess_s: 0.0,
            render_s: time_s,
            rays: 0.0,
            extra: BTreeMap::new(),
            split: None,
            robust: Default::default(),
            reference_key: "k".into(),
            component: None,
        }
    }

    /// A curve that flattens at the reference's noise (as `sppm` on cornell-glass in
    /// the consistency study): the floor is drawn as a band, labelled with its scene
    /// and level, and the y axis reaches down to it even when every point is above.
    #[test]
    fn error_plots_draw_the_reference_noise_floor_as_a_band() {
        let tmp = tempfile::tempdir().unwrap();
        let m = Manifest::parse(
            "scene = \"cornell\"\nresolution = [8, 8]\n[reference]\nspp = 4\n[base]\nspp = 1\n",
            Path::new("m.toml"),
            Path::new("."),
        )
        .unwrap();
        let stats: Vec<ConfigStats> =
            [(1.0, 4e-2), (2.0, 1e-2), (4.0, 3e-3), (8.0, 2.1e-3)].iter().enumerate().map(|(i, &(t, e))| config(i, "sppm", t, e)).collect();
        let svg_of = |refs: &[RefInfo]| {
            let d = tmp.path().join(format!("run{}", refs.len()));
            make_plots(&d, &m, &stats, refs).unwrap();
            std::fs::read_to_string(d.join("plots/error_vs_time.svg")).unwrap()
        };
        let reference = |scene: &str, noise: Option<f64>| RefInfo {
            scene: scene.into(),
            key: "k".into(),
            description: String::new(),
            file: String::new(),
            noise_relmse: noise,
            component_file: None,
            component_noise_relmse: None,
        };
        let without = svg_of(&[]);
        let with = svg_of(&[reference("cornell-glass", Some(2e-3)), reference("unknown", None)]);
        assert!(!without.contains("noise of the"));
        assert!(with.contains("noise of the cornell-glass reference (relMSE 0.00200)"), "legend entry missing");
        assert!(!with.contains("noise of the unknown"), "a reference without a noise estimate has no band");
        // The band itself: a translucent filled rectangle (none without it).
        let translucent =
            |s: &str| s.split("<rect").filter(|r| r.contains("fill-opacity=\"0.18\"") || r.contains("opacity=\"0.18\"")).count();
        assert!(translucent(&with) >= 1 && translucent(&without) == 0, "band rectangle not drawn:\n{with}");
        // A floor far below every point still shows: the axis reaches down to it.
        let low = svg_of(&[reference("low", Some(1e-5)), reference("b", Some(1e-5)), reference("c", Some(1e-5))]);
        assert!(translucent(&low) >= 1, "a floor below the points is still drawn");
        assert_eq!(noise_bands(&[reference("x", Some(0.0)), reference("y", Some(f64::NAN))]).len(), 0);
    }

    /// With several scenes, each gets its own error-vs-time plot holding only its
    /// configurations and its own reference's noise floor (the combined plot stays).
    #[test]
    fn several_scenes_get_one_error_plot_each() {
        let tmp = tempfile::tempdir().unwrap();
        let m = Manifest::parse(
            "scene = [\"cornell\", \"door-ajar\"]\nresolution = [8, 8]\n[reference]\nspp = 4\n[base]\nspp = 1\n",
            Path::new("m.toml"),
            Path::new("."),
        )
        .unwrap();
        let stats: Vec<ConfigStats> = [("cornell", "path", 1.0, 1e-2), ("cornell", "vcm", 2.0, 2e-2), ("door-ajar", "bdpt", 3.0, 5e-2)]
            .iter()
            .enumerate()
            .map(|(i, &(scene, g, t, e))| {
                let mut c = config(i, &format!("scene={scene} {g}"), t, e);
                c.values.insert("scene".into(), serde_json::json!(scene));
                c
            })
            .collect();
        let reference = |scene: &str, noise: f64| RefInfo {
            scene: scene.into(),
            key: "k".into(),
            description: String::new(),
            file: String::new(),
            noise_relmse: Some(noise),
            component_file: None,
            component_noise_relmse: None,
        };
        let plots = make_plots(tmp.path(), &m, &stats, &[reference("cornell", 1e-3), reference("door-ajar", 4e-3)]).unwrap();
        let paths: Vec<&str> = plots.iter().map(|(_, p)| p.as_str()).collect();
        for p in ["plots/error_vs_time.png", "plots/error_vs_time-cornell.png", "plots/error_vs_time-door-ajar.png"] {
            assert!(paths.contains(&p), "{p} missing from {paths:?}");
            assert!(tmp.path().join(p).is_file(), "{p} not written");
        }
        let svg = |n: &str| std::fs::read_to_string(tmp.path().join(format!("plots/{n}.svg"))).unwrap();
        let (all, cornell, door) = (svg("error_vs_time"), svg("error_vs_time-cornell"), svg("error_vs_time-door-ajar"));
        assert!(all.contains("scene=cornell vcm") && all.contains("scene=door-ajar bdpt"));
        assert!(cornell.contains("scene=cornell vcm") && !cornell.contains("scene=door-ajar bdpt"));
        assert!(door.contains("scene=door-ajar bdpt") && !door.contains("scene=cornell path"));
        assert!(cornell.contains("noise of the cornell reference") && !cornell.contains("noise of the door-ajar reference"));
        // One scene: no per-scene copy.
        let one = tempfile::tempdir().unwrap();
        let plots = make_plots(one.path(), &m, &stats[..2], &[]).unwrap();
        assert!(!plots.iter().any(|(_, p)| p.contains("error_vs_time-")), "{plots:?}");
    }
}

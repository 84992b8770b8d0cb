//! `bdpt` and `vcm` against `path`, and their invariants.
//!
//! Images are compared on 16-px block means (8-px on the small images) over the
//! blocks `path` does not leave black: a block passes within 4 standard errors (the
//! spread of the per-pixel differences) plus 2 % of the reference, and the image mean
//! must be within 2 %.

use photonlab::compare::{BlockReport, compare_blocks};
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::{render_scene, render_scene_with_aovs};
use photonlab::scene::builtin::{BUILTINS, builtin};

fn render(scene: &str, cfg: RenderConfig) -> Film {
    render_scene(builtin(scene).unwrap(), &cfg, true).unwrap().film
}

fn cfg(integrator: &str, res: u32, spp: u32, seed: u64) -> RenderConfig {
    RenderConfig { integrator: integrator.into(), spp, resolution: Some([res, res]), seed, ..Default::default() }
}

fn check(name: &str, rep: &BlockReport) {
    let bad = rep.outliers(4.0, 0.02);
    if let Some(w) = rep.worst() {
        eprintln!(
            "{name}: mean ratio {:.4}, worst block {:?} rel {:+.4}, {} of {} outside",
            rep.mean_ratio,
            w.at,
            w.rel(),
            bad.len(),
            rep.blocks.len()
        );
    }
    assert!(rep.mean_ratio.is_nan() || (rep.mean_ratio - 1.0).abs() < 0.02, "{name}: image mean ratio {:.4}", rep.mean_ratio);
    assert!(bad.is_empty(), "{name}: blocks beyond 4 std err + 2 %: {bad:?}");
}

/// Every built-in: `bdpt` (balance heuristic, the default) within noise of `path`
/// (the million-triangle `displaced-sphere` in a test of its own, for its build time).
#[test]
fn bdpt_agrees_with_path_on_every_builtin() {
    for &scene in BUILTINS.iter().filter(|&&s| s != "displaced-sphere") {
        bdpt_against_path(scene);
    }
}

#[test]
fn bdpt_agrees_with_path_on_displaced_sphere() {
    bdpt_against_path("displaced-sphere");
}

fn bdpt_against_path(scene: &str) {
    {
        // sun-slats is lit by one bounce off thin slats: noisier, so 4× the samples.
        let (res, k) = match scene {
            "displaced-sphere" => (24, 1),
            "sun-slats" => (24, 4),
            _ => (32, 1),
        };
        let reference = render(scene, cfg("path", res, 512 * k, 11));
        let img = render(scene, cfg("bdpt", res, 128 * k, 12));
        check(&format!("bdpt {scene}"), &compare_blocks(&img, &reference, 8, 0.005).unwrap());
    }
}

/// The power heuristic and a finite `max_depth` with roulette off change the weights
/// and the techniques' path-length limits, not the expectation.
#[test]
fn bdpt_power_heuristic_and_depth_limit_agree_with_path() {
    let base = |i: &str| RenderConfig { rr: "off".into(), max_depth: Some(3), ..cfg(i, 32, 0, 0) };
    let reference = render("cornell-glass", RenderConfig { spp: 512, seed: 3, ..base("path") });
    let img = render("cornell-glass", RenderConfig { spp: 128, seed: 4, ..base("bdpt") }.with("bdpt_mis", "power"));
    check("bdpt power depth 3", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
}

/// Light tracing alone (`vcm_mode = "lt"`, plus emitters seen directly) on diffuse scenes.
#[test]
fn light_tracing_alone_agrees_with_path_on_diffuse_scenes() {
    for scene in ["cornell", "cornell-contact"] {
        let reference = render(scene, cfg("path", 32, 512, 21));
        let img = render(scene, RenderConfig { seed: 22, ..cfg("vcm", 32, 1, 0) }.with("vcm_mode", "lt").with("passes", 256));
        check(&format!("lt {scene}"), &compare_blocks(&img, &reference, 8, 0.005).unwrap());
    }
}

/// `vcm` with merging converges to `path`: at 128 passes of 32² on the glass box the
/// merging bias is below the noise.
#[test]
fn vcm_agrees_with_path() {
    let reference = render("cornell-glass", cfg("path", 32, 512, 31));
    let img = render("cornell-glass", RenderConfig { seed: 32, ..cfg("vcm", 32, 1, 0) }.with("passes", 128));
    check("vcm cornell-glass", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
}

/// Fewer light subpaths than pixels and camera vertices joined to one vertex drawn
/// from the pass's pool of light vertices (`vcm_light_paths`, `vcm_connect_draws`):
/// the light-tracing and merging normalisations, the pool's estimate factor and the
/// MIS counts keep `vcm` (and connections alone, `bpt`) consistent with `path`.
#[test]
fn vcm_with_fewer_light_subpaths_and_pool_draws_agrees_with_path() {
    let pool = |c: RenderConfig| c.with("vcm_light_paths", 0.25).with("vcm_connect_draws", 1).with("passes", 256);
    let reference = render("cornell-glass", cfg("path", 32, 512, 31));
    let img = render("cornell-glass", pool(RenderConfig { seed: 33, ..cfg("vcm", 32, 1, 0) }));
    check("vcm pool cornell-glass", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
    let reference = render("cornell", cfg("path", 32, 512, 34));
    let img = render("cornell", pool(RenderConfig { seed: 35, ..cfg("vcm", 32, 1, 0) }).with("vcm_mode", "bpt"));
    check("vcm bpt pool cornell", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
}

/// Merging at every non-delta camera vertex (`vcm_merge = "all"`, SmallVCM's) on the
/// glass box, and at the first one only (`"first"`, the default, its MIS weights
/// counting merging only there; `vcm_agrees_with_path` runs it on the glass box) on the
/// diffuse box, stay consistent with `path`.
#[test]
fn vcm_merging_at_the_first_or_every_vertex_agrees_with_path() {
    let first = |c: RenderConfig| c.with("vcm_merge", "first").with("passes", 128);
    let all = |c: RenderConfig| c.with("vcm_merge", "all").with("passes", 128);
    let reference = render("cornell-glass", cfg("path", 32, 512, 31));
    let img = render("cornell-glass", all(RenderConfig { seed: 38, ..cfg("vcm", 32, 1, 0) }));
    check("vcm all cornell-glass", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
    let reference = render("cornell", cfg("path", 32, 512, 34));
    let img = render("cornell", first(RenderConfig { seed: 37, ..cfg("vcm", 32, 1, 0) }).with("vcm_select", "off"));
    check("vcm first cornell", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
}

/// Same seed ⇒ same bits for 1 and 2 threads (the light-tracing splats included).
#[test]
fn images_are_bit_identical_for_any_thread_count() {
    let pool = Some((4u32, 0.3f32, 2u32, "all"));
    let first = Some((4u32, 0.5f32, 1u32, "first"));
    for (integrator, extra) in [("bdpt", None), ("vcm", Some((4u32, 1.0f32, 0u32, "all"))), ("vcm", pool), ("vcm", first)] {
        let run = |threads| {
            let c = RenderConfig { threads, ..cfg(integrator, 40, 4, 5) };
            let c = if let Some((p, f, m, merge)) = extra {
                c.with("passes", p as i64).with("vcm_light_paths", f as f64).with("vcm_connect_draws", m as i64).with("vcm_merge", merge)
            } else {
                c
            };
            render("cornell-glass", c).pixels
        };
        assert!(run(1) == run(2), "{integrator} {extra:?}: 1 and 2 threads differ");
    }
    // `vcm` rendering by path tracing after its pilot (the choice and the batches of
    // passes alike), 5 passes: the two of the pilot, then batches of 2 and 1.
    let run = |threads| render("cornell", RenderConfig { threads, ..cfg("vcm", 40, 1, 5) }.with("passes", 5)).pixels;
    assert!(run(1) == run(2), "vcm choosing path tracing: 1 and 2 threads differ");
}

/// With every path length shown (max_depth 4), the weighted per-technique images add
/// up to the image; the unweighted ones are each an estimate of the same light (here:
/// direct light at the first hit by light sampling s = 1, BSDF sampling s = 0 and light
/// tracing t = 1, within 10 % in the mean).
#[test]
fn strategy_images_add_up_to_the_image() {
    let c = RenderConfig { max_depth: Some(4), ..cfg("bdpt", 24, 8, 9) };
    let o = render_scene_with_aovs(builtin("cornell").unwrap(), &c, true, &["strategies".to_string()]).unwrap();
    let names: Vec<&str> = o.aovs.iter().map(|(n, _)| n.as_str()).collect();
    assert!(names.contains(&"strategies-s1-t2") && names.contains(&"strategies-s3-t1-unweighted"), "{names:?}");
    let mut sum = vec![glam::DVec3::ZERO; o.film.pixels.len()];
    for (n, f) in &o.aovs {
        if !n.ends_with("unweighted") {
            for (s, p) in sum.iter_mut().zip(&f.pixels) {
                *s += p.as_dvec3();
            }
        }
    }
    for (s, p) in sum.iter().zip(&o.film.pixels) {
        assert!((*s - p.as_dvec3()).abs().max_element() <= 1e-4 * (1.0 + p.max_element() as f64), "{s} vs {p}");
    }
    let mean = |n: &str| o.aovs.iter().find(|(a, _)| a == n).unwrap().1.mean().element_sum();
    let (a, b, c) = (mean("strategies-s1-t2-unweighted"), mean("strategies-s0-t3-unweighted"), mean("strategies-s2-t1-unweighted"));
    assert!(
        (a / b - 1.0).abs() < 0.1 && (c / b - 1.0).abs() < 0.1,
        "direct light by light sampling {a}, BSDF sampling {b}, light tracing {c}"
    );
}

/// Interrupted and resumed from a checkpoint = uninterrupted, bit for bit.
#[test]
fn vcm_resumes_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("v.checkpoint.json").to_string_lossy().into_owned();
    // `vcm_select = "efficiency"` picks path tracing on this box: its pilot passes are
    // the first two, so a checkpoint within them (after 1) and one after 6 both resume
    // correctly.
    for (draws, select, first) in [(0u32, "off", 4), (1, "off", 4), (1, "efficiency", 1), (1, "efficiency", 6)] {
        let c = |passes: u32| {
            cfg("vcm", 24, 1, 8)
                .with("passes", passes)
                .with("checkpoint_file", file.clone())
                .with("vcm_connect_draws", draws as i64)
                .with("vcm_select", select)
        };
        let full = render("cornell", c(8));
        render("cornell", c(first).with("checkpoint_every", 1));
        let resumed = render("cornell", c(8).with("resume", true));
        assert!(full.pixels == resumed.pixels, "vcm_connect_draws {draws}, vcm_select {select}, first run {first} passes");
    }
    // The glass box, where the pilot chooses `sppm`: a checkpoint within its pilot
    // passes and one after.
    for first in [1, 5] {
        let c = |passes: u32| cfg("vcm", 48, 1, 0).with("passes", passes).with("checkpoint_file", file.clone());
        let full = render_scene(builtin("cornell-glass").unwrap(), &c(12), true).unwrap();
        assert_eq!(full.extra["pilot_chose_sppm"], 1.0, "{:?}", full.extra);
        render("cornell-glass", c(first).with("checkpoint_every", 1));
        let resumed = render("cornell-glass", c(12).with("resume", true));
        assert!(full.film.pixels == resumed.pixels, "sppm chosen, first run {first} passes");
    }
}

/// `vcm_select = "efficiency"` (the default) renders the diffuse box by path tracing —
/// the very image of `path` with as many samples as passes, bit for bit — and the room lit
/// through a door ajar by the bidirectional pass, the very image of `vcm_select = "off"`;
/// its pilot's estimates say why (path tracing's relative variance 40× higher there).
#[test]
fn vcm_chooses_path_tracing_only_where_it_pays() {
    let outcome = |scene: &str, c: RenderConfig| render_scene(builtin(scene).unwrap(), &c, true).unwrap();
    let v = outcome("cornell", cfg("vcm", 32, 1, 3).with("passes", 12));
    assert_eq!(v.extra["pilot_chose_path"], 1.0);
    assert_eq!(v.extra["path_tracing_passes"], 12.0);
    let p = outcome("cornell", cfg("path", 32, 12, 3));
    assert!(v.film.pixels == p.film.pixels, "vcm's path-tracing passes are not path's samples");

    let v = outcome("door-ajar", cfg("vcm", 32, 1, 3).with("passes", 6));
    assert_eq!(v.extra["pilot_chose_path"], 0.0);
    assert!(v.extra["pilot_path_rel_var"] > 10.0 * v.extra["pilot_bidir_rel_var"], "{:?}", v.extra);
    assert_eq!(v.extra["pilot_chose_sppm"], 0.0);
    assert!(v.extra["pilot_sppm_predicted"] > 2.0 * v.extra["pilot_bidir_predicted"], "{:?}", v.extra);
    let off = outcome("door-ajar", cfg("vcm", 32, 1, 3).with("passes", 6).with("vcm_select", "off"));
    assert!(v.film.pixels == off.film.pixels, "the chosen bidirectional passes differ from vcm_select = off");
    assert!(!off.extra.contains_key("pilot_chose_path"));
}

/// On the box with a glass sphere (caustics on the floor, light through glass), `sppm`
/// reaches a given error at less work than the bidirectional pass and far less than path
/// tracing: the pilot chooses it, and the image is `sppm`'s, bit for bit, on 1 and 2
/// threads; `vcm_select = "bidir-path"` leaves it out.
#[test]
fn vcm_chooses_sppm_where_it_pays() {
    let outcome = |c: RenderConfig| render_scene(builtin("cornell-glass").unwrap(), &c, true).unwrap();
    let v = outcome(cfg("vcm", 48, 1, 0).with("passes", 16));
    assert_eq!(v.extra["pilot_chose_sppm"], 1.0, "{:?}", v.extra);
    assert_eq!(v.extra["sppm_passes"], 16.0);
    assert!(v.extra["pilot_path_rel_var"] > 5.0 * v.extra["pilot_sppm_predicted"], "{:?}", v.extra);
    let s = outcome(cfg("sppm", 48, 1, 0).with("passes", 16));
    assert!(v.film.pixels == s.film.pixels, "vcm's sppm passes are not sppm's");
    let one = outcome(RenderConfig { threads: 1, ..cfg("vcm", 48, 1, 0).with("passes", 16) });
    assert!(one.film.pixels == v.film.pixels, "1 and 2 threads differ");
    let two = outcome(cfg("vcm", 48, 1, 0).with("passes", 16).with("vcm_select", "bidir-path"));
    assert!(!two.extra.contains_key("pilot_chose_sppm"), "{:?}", two.extra);
    assert_eq!(two.extra["pilot_chose_path"], 0.0);
}

/// Bad settings are named.
#[test]
fn bad_settings_are_named() {
    let err = |c: RenderConfig| render_scene(builtin("cornell").unwrap(), &c, true).err().unwrap().to_string();
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_mode", "bdpt")).contains("vcm_mode"));
    assert!(err(cfg("bdpt", 8, 1, 0).with("bdpt_mis", "max")).contains("bdpt_mis"));
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_radius", -1.0)).contains("vcm_radius"));
    assert!(err(cfg("bdpt", 8, 1, 0).with("vcm_mode", "lt")).contains("vcm_mode"));
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_light_paths", 0.0)).contains("vcm_light_paths"));
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_connect_draws", 1000)).contains("vcm_connect_draws"));
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_merge", "second")).contains("vcm_merge"));
    assert!(err(cfg("vcm", 8, 1, 0).with("vcm_select", "always")).contains("vcm_select"));
}

/// An open scene lit only by a constant environment (the Cornell box, ceiling light
/// off, lit through its open front): `bdpt`, with its light subpaths starting on the
/// bounding sphere's disc and camera paths that escape weighted as emitter hits at
/// infinity, agrees with `path`.
#[test]
fn bdpt_agrees_with_path_under_a_constant_environment() {
    let scene = || {
        let mut s = builtin("cornell").unwrap();
        for m in &mut s.materials {
            m.emission = glam::Vec3::ZERO;
        }
        s.lights.push(photonlab::scene::LightDesc::Constant { radiance: glam::Vec3::new(0.8, 0.9, 1.0) });
        s
    };
    let run = |c: RenderConfig| render_scene(scene(), &c, true).unwrap().film;
    let reference = run(cfg("path", 24, 512, 41));
    let img = run(cfg("bdpt", 24, 128, 42));
    check("bdpt constant environment", &compare_blocks(&img, &reference, 8, 0.005).unwrap());
}

//! `gather_per = "pixel"`: the first-level gather rays (diffuse and glossy) counted
//! per pixel, each camera sample tracing ⌈count / spp⌉ of them and weighting them by
//! that share. Its image must have the expectation of the per-sample gather: the same
//! photons (same seed), so only gather noise tells the two apart, and 16-px block
//! means must agree within 4 standard errors plus 2 %.
//!
//! The ray counts are chosen so the split is not exact (20 rays over 8 samples: 3 a
//! sample): a sample weighting its rays by the pixel's count (1/20 instead of 1/3), or
//! tracing 2 and weighting 1/3, darkens the indirect light far beyond the tolerance.

use photonlab::compare::compare_blocks;
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::render_scene;
use photonlab::scene::builtin::builtin;

fn render(scene: &str, gather: &str, per: &str, gather_samples: u32, glossy_samples: u32) -> Film {
    let cfg = RenderConfig { integrator: "photon".into(), spp: 8, resolution: Some([64, 64]), seed: 11, ..Default::default() }
        .with("gather", gather)
        .with("photons", 40_000)
        .with("caustic_photons", 0)
        .with("gather_per", per)
        .with("gather_samples", gather_samples)
        .with("glossy_samples", glossy_samples);
    render_scene(builtin(scene).unwrap(), &cfg, true).unwrap().film
}

#[test]
fn per_pixel_gather_keeps_the_per_sample_mean() {
    for (scene, gather) in [("cornell", "precomputed"), ("cornell-glossy", "precomputed"), ("cornell", "final_gather")] {
        // Per sample: 24 diffuse and 16 glossy rays at each camera sample (the low-noise
        // side); per pixel: 20 and 12 rays per pixel, 3 and 2 per camera sample.
        let per_sample = render(scene, gather, "sample", 24, 16);
        let per_pixel = render(scene, gather, "pixel", 20, 12);
        let rep = compare_blocks(&per_pixel, &per_sample, 16, 0.005).unwrap();
        let bad = rep.outliers(4.0, 0.02);
        eprintln!(
            "{scene} {gather}: mean ratio {:.4}, worst block rel {:+.4}, {} of {} blocks outside",
            rep.mean_ratio,
            rep.worst_rel(),
            bad.len(),
            rep.blocks.len()
        );
        assert!((rep.mean_ratio - 1.0).abs() < 0.02, "{scene} {gather}: image mean ratio {:.4} (pixel / sample)", rep.mean_ratio);
        assert!(bad.is_empty(), "{scene} {gather}: blocks beyond 4 std err + 2 %: {bad:?}");
    }
}

/// A small render of `scene` with `gather`, and the gather keys in `keys` set.
fn render_keys(scene: &str, gather: &str, keys: &[(&str, toml::Value)]) -> Film {
    let mut cfg = RenderConfig { integrator: "photon".into(), spp: 4, resolution: Some([16, 16]), seed: 3, ..Default::default() }
        .with("gather", gather)
        .with("photons", 5_000)
        .with("caustic_photons", 0);
    for (k, v) in keys {
        cfg = cfg.with(k, v.clone());
    }
    render_scene(builtin(scene).unwrap(), &cfg, true).unwrap().film
}

/// The per-pixel split changes the image (the rays are fewer and drawn from the
/// pixel's point set). By default `final_gather` and `precomputed` count their rays
/// per pixel (256 diffuse, 64 glossy; 64 and 16 when counted per sample), while
/// `irradiance_cache` keeps counting them per camera sample (64 diffuse for points no
/// entry covers, 16 glossy): its default image is the one it had before the per-pixel
/// default, and differs from the split.
#[test]
fn gathers_count_per_pixel_by_default_and_the_cache_per_sample() {
    let a = render("cornell", "precomputed", "pixel", 16, 16);
    let b = render("cornell", "precomputed", "sample", 16, 16);
    assert_ne!(a.mean(), b.mean());
    let keys = |per: &str, g: i64, s: i64| vec![("gather_per", per.into()), ("gather_samples", g.into()), ("glossy_samples", s.into())];
    // `cornell-glossy`: the glossy lobe is gathered at camera points, so the glossy
    // count and split show in the image too.
    for gather in ["precomputed", "final_gather"] {
        let default = render_keys("cornell-glossy", gather, &[]);
        assert!(
            default == render_keys("cornell-glossy", gather, &keys("pixel", 256, 64)),
            "{gather}: default is not 256 + 64 rays a pixel"
        );
        assert!(default != render_keys("cornell-glossy", gather, &keys("sample", 256, 64)), "{gather}: the split made no difference");
        // Counted per sample, the counts left `auto` are the per-sample ones.
        let per_sample = render_keys("cornell-glossy", gather, &[("gather_per", "sample".into())]);
        assert!(per_sample == render_keys("cornell-glossy", gather, &keys("sample", 64, 16)), "{gather}: per-sample defaults");
    }
    let default = render_keys("cornell-glossy", "irradiance_cache", &[]);
    assert!(default == render_keys("cornell-glossy", "irradiance_cache", &keys("sample", 64, 16)), "irradiance_cache: default changed");
    assert!(
        default != render_keys("cornell-glossy", "irradiance_cache", &keys("pixel", 64, 16)),
        "irradiance_cache: the split made no difference"
    );
}

#[test]
fn unknown_gather_per_is_an_error() {
    let cfg = RenderConfig { integrator: "photon".into(), spp: 1, resolution: Some([8, 8]), ..Default::default() }
        .with("gather", "precomputed")
        .with("gather_per", "tile");
    let err = render_scene(builtin("cornell").unwrap(), &cfg, true).err().expect("an error");
    assert!(format!("{err:#}").contains("gather_per"), "{err:#}");
}

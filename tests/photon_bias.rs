//! The photon integrator against `path` on scenes built to expose bias: a closed box
//! of zero-thickness walls lit from outside (`leaky-box`), glossy surfaces
//! (`cornell-glossy`), contacts (`cornell-contact`) and thin geometry under a sun
//! (`sun-slats`).
//!
//! Images are compared on 16-px (contacts: 8-px) block means over the blocks `path` does not leave
//! black (reference mean > 0.005). A block passes when its difference is within
//! 4 standard errors plus a floor proportional to the reference. The standard error
//! comes from the spread of the per-pixel differences inside the block (the pixel
//! noise of both images; photon-map blotches larger than a pixel make it an
//! underestimate, which the floor absorbs). The floor is the residual bias of the
//! stated photon budget, stated per test; the image mean must be within 1 %.

use photonlab::compare::{BlockReport, compare_blocks, compare_blocks_below};
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::{render_scene, render_scene_with_aovs};
use photonlab::scene::Scene;
use photonlab::scene::builtin::builtin;

const GATHERS: [&str; 4] = ["direct", "final_gather", "precomputed", "irradiance_cache"];

fn path_reference(scene: &Scene, res: [u32; 2], spp: u32) -> Film {
    let cfg = RenderConfig { spp, resolution: Some(res), seed: 1234, ..Default::default() };
    render_scene(scene.clone(), &cfg, true).unwrap().film
}

fn photon(scene: &Scene, cfg: RenderConfig) -> Film {
    let cfg = RenderConfig { integrator: "photon".into(), seed: 7, ..cfg };
    render_scene(scene.clone(), &cfg, true).unwrap().film
}

fn check_blocks(name: &str, rep: &BlockReport, floor: f64) {
    let bad = rep.outliers(4.0, floor);
    let worst = rep.worst().expect("blocks to judge");
    eprintln!(
        "{name}: mean ratio {:.4}, worst block {:?} rel {:+.4}, {} of {} blocks outside",
        rep.mean_ratio,
        worst.at,
        worst.rel(),
        bad.len(),
        rep.blocks.len()
    );
    assert!((rep.mean_ratio - 1.0).abs() < 0.01, "{name}: image mean ratio {:.4} (photon / path)", rep.mean_ratio);
    assert!(bad.is_empty(), "{name}: blocks beyond 4 std err + {floor} of the reference: {bad:?}");
}

/// No light inside a closed box lit from outside, for every gather method. Before
/// the fix the irradiance cache put entries exactly on the edges between walls (its
/// prefill used pixel centres, which this camera puts on the edges) whose gather rays
/// started outside, and precomputed irradiance borrowed the lamp's underside 20 cm
/// above the roof (no tangent-plane test): the interior glowed at 0.04–0.08.
#[test]
fn leaky_box_interior_stays_dark() {
    let scene = builtin("leaky-box").unwrap();
    let res = [48, 48];
    let reference = path_reference(&scene, res, 64).mean().max_element();
    for gather in GATHERS {
        let cfg = RenderConfig { spp: 2, resolution: Some(res), ..Default::default() }.with("gather", gather).with("photons", 100_000);
        // `direct` does not gather, so it has no gather_samples (setting it is an error).
        let cfg = if gather == "direct" { cfg } else { cfg.with("gather_samples", 32).with("gather_per", "sample") };
        let m = photon(&scene, cfg).mean().max_element();
        assert!(m <= (10.0 * reference).max(1e-5), "{gather}: interior mean {m} vs path {reference}");
    }
}

/// Glossy floor, sphere and box: the glossy lobes at camera hits and at final-gather
/// hits. Before the fix the default render was 3.7 % darker than `path` and 28 % off
/// in the worst block (gather hits reflected only Kd/π·E); budget: 200k photons,
/// 16 spp, floor 8 %.
#[test]
fn glossy_surfaces_match_path() {
    let scene = builtin("cornell-glossy").unwrap();
    let res = [96, 96];
    let reference = path_reference(&scene, res, 384);
    let img = photon(&scene, RenderConfig { spp: 16, resolution: Some(res), ..Default::default() });
    check_blocks("cornell-glossy", &compare_blocks(&img, &reference, 16, 0.005).unwrap(), 0.08);
}

/// A cube standing on the floor and a sphere in a corner, default photon settings
/// (200k photons, 16 spp) at 128² on 8-px blocks, skipping the blocks on the light's
/// outline (sampling of the emitter's edge, not of indirect light); floor 8 %. Before
/// the cache had gradients, neighbour clamping, pixel-footprint radii and 256 rays per
/// entry, the block where the cube meets the floor was 23 % too bright.
#[test]
fn contacts_match_path() {
    let scene = builtin("cornell-contact").unwrap();
    let res = [128, 128];
    let reference = path_reference(&scene, res, 256);
    let img = photon(&scene, RenderConfig { spp: 16, resolution: Some(res), ..Default::default() });
    check_blocks("cornell-contact", &compare_blocks_below(&img, &reference, 8, 0.005, 1.0).unwrap(), 0.08);
}

/// Thin geometry under a sun (`sun-slats`): a wall lit only by light reflected from
/// five 8-cm slats. With 20k photons an estimate's disc is wider than a slat, so
/// dividing by π r² made the slats' precomputed irradiance, and the wall's gathered
/// light, about 20 % too dark (image mean 0.80 of `path`, median 16-px block −20 %).
/// Precomputed irradiance now divides by the surface area inside the disc
/// (`area_probes`): image mean 0.93, median block −3 % (what remains is the wall
/// below the lowest slat, lit only by second bounces). Budget: 20k photons, 4 spp,
/// 64²; the same render with `area_probes = 0` (the old estimate) must fail the bounds.
#[test]
fn thin_geometry_is_not_darkened() {
    let scene = builtin("sun-slats").unwrap();
    let res = [64, 64];
    let reference = path_reference(&scene, res, 128);
    let run = |probes: u32| {
        let cfg =
            RenderConfig { spp: 4, resolution: Some(res), ..Default::default() }.with("photons", 20_000).with("area_probes", probes as i64);
        let rep = compare_blocks(&photon(&scene, cfg), &reference, 16, 0.005).unwrap();
        let mut rel: Vec<f64> = rep.blocks.iter().map(|b| b.rel()).collect();
        rel.sort_by(f64::total_cmp);
        let median = rel[rel.len() / 2];
        eprintln!("sun-slats, area_probes {probes}: mean ratio {:.4}, median 16-px block {median:+.3}, blocks {rel:.2?}", rep.mean_ratio);
        (rep.mean_ratio, median)
    };
    let (mean, median) = run(32);
    assert!(mean > 0.9 && mean < 1.05 && median.abs() < 0.08, "with the area probe: mean ratio {mean:.4}, median block {median:+.3}");
    let (mean, median) = run(0);
    assert!(mean < 0.85 && median < -0.12, "without it the estimate is darkened: mean ratio {mean:.4}, median block {median:+.3}");
}

/// Irradiance-cache entries under a small bright region: the Cornell box lit by a
/// point light just under its ceiling (the lamp quad switched off), so every entry's
/// hemisphere holds a bright ceiling patch a few strata wide. An entry's noise is
/// frozen into every pixel it covers, whatever the spp: with 256 rays per entry,
/// McGuire's Glossy-Floor box had 16-px blocks off by up to +8 % at 10⁶ photons and
/// 16 or 64 spp. Measured here without a reference: two renders with different seeds
/// (independent photons, entry positions and rays) differ, in the indirect component,
/// by the frozen noise of both (pixel noise is small there: at a diffuse camera hit
/// the indirect light is a cache lookup). The default (adaptive entries, `ic_error`)
/// must cut the 16-px block spread of that difference well below the same renders'
/// with one ray per stratum (`ic_error = 0`, the state before: 0.036) and below 2.5 %
/// (measured 0.016). Fails with the refinement removed (checked: 0.036 both).
/// Budget: 128², 100k photons, 2 spp, four renders.
#[test]
fn cache_entries_do_not_freeze_noise() {
    let mut scene = builtin("cornell").unwrap();
    for m in &mut scene.materials {
        m.emission = photonlab::math::Color::ZERO;
    }
    let intensity = photonlab::math::Color::splat(1.5e5);
    scene.lights.push(photonlab::scene::LightDesc::Point { position: glam::Vec3::new(278.0, 500.0, 280.0), intensity });
    let res = [128, 128];
    let indirect = |seed: u64, err: Option<f64>| {
        let cfg = RenderConfig { spp: 2, resolution: Some(res), seed, integrator: "photon".into(), ..Default::default() }
            .with("photons", 100_000);
        let cfg = match err {
            Some(e) => cfg.with("ic_error", e),
            None => cfg,
        };
        let out = render_scene_with_aovs(scene.clone(), &cfg, true, &["indirect".to_string()]).unwrap();
        out.aovs.into_iter().next().unwrap().1
    };
    let spread = |err: Option<f64>| {
        let rep = compare_blocks(&indirect(1, err), &indirect(2, err), 16, 0.005).unwrap();
        let rms = (rep.blocks.iter().map(|b| b.rel().powi(2)).sum::<f64>() / rep.blocks.len() as f64).sqrt();
        eprintln!(
            "point-lit cornell, ic_error {err:?}: seed 1 vs 2, indirect, 16-px blocks rms {rms:.4}, worst {:+.4} of {}",
            rep.worst().unwrap().rel(),
            rep.blocks.len()
        );
        rms
    };
    let (adaptive, fixed) = (spread(None), spread(Some(0.0)));
    assert!(adaptive < 0.6 * fixed && adaptive < 0.025, "block spread between seeds {adaptive:.4} (default) vs {fixed:.4} (ic_error 0)");
}

//! Mitsuba 3's BSDFs in every integrator: the glossy Cornell box with a smooth-plastic
//! floor (a delta coating over a base: a mixed BSDF, whose coating mirrors the room),
//! a rough-plastic block (GGX, nonlinear) and a rough gold sphere (Beckmann). `photon` (default gather), `sppm` and `ppm` must
//! agree with `path` on 16-px block means within 4 standard errors plus a floor
//! proportional to the reference (the residual bias of the stated photon budget), the
//! image mean within 2 %. A planted control — `sppm` on the scene with the plastics'
//! coatings removed, as an integrator that dropped their delta and glossy lobes would
//! render it — must fail the same check.

use photonlab::compare::{BlockReport, compare_blocks};
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::material::{Bsdf, MicrofacetType, Plastic, RoughConductor, RoughPlastic};
use photonlab::math::Color;
use photonlab::pipeline::render_scene_observed;
use photonlab::scene::Scene;
use photonlab::scene::builtin::builtin;

const RES: [u32; 2] = [64, 64];

/// The test scene.
pub fn scene() -> Scene {
    let mut s = builtin("cornell-glossy").unwrap();
    for m in &mut s.materials {
        match m.name.as_str() {
            "glossy-floor" => m.bsdf = Bsdf::Plastic(Plastic::new(Color::new(0.5, 0.45, 0.4), Color::ONE, 1.5, 1.0, false)),
            "glossy-box" => {
                m.bsdf = Bsdf::RoughPlastic(RoughPlastic::new(
                    MicrofacetType::Ggx,
                    0.2,
                    Color::new(0.45, 0.44, 0.42),
                    Color::ONE,
                    1.49,
                    1.000_277,
                    true,
                ))
            }
            "glossy-sphere" => {
                m.bsdf = Bsdf::RoughConductor(RoughConductor {
                    distribution: MicrofacetType::Beckmann,
                    alpha: 0.25,
                    // Gold (Mitsuba's `Au` preset at the RGB primaries, rounded).
                    eta: Color::new(0.143, 0.374, 1.442),
                    k: Color::new(3.983, 2.385, 1.603),
                    specular_reflectance: Color::ONE,
                })
            }
            _ => {}
        }
    }
    s
}

fn render(cfg: RenderConfig) -> Film {
    render_in(scene(), cfg)
}

fn render_in(scene: Scene, cfg: RenderConfig) -> Film {
    let cfg = RenderConfig { resolution: Some(RES), ..cfg };
    let mut cb = |_: u32, _: f64, _: &Film| {};
    let t = std::time::Instant::now();
    let film = render_scene_observed(scene, &cfg, true, &[], &mut cb).unwrap().film;
    eprintln!("{}: {:.1} s", cfg.integrator, t.elapsed().as_secs_f64());
    if let Ok(dir) = std::env::var("PHOTONLAB_TEST_PNG") {
        film.write_png(std::path::Path::new(&dir).join(format!("mitsuba-{}.png", cfg.integrator)).as_path()).ok();
    }
    film
}

fn reference() -> Film {
    render(RenderConfig { spp: 256, seed: 1234, ..Default::default() })
}

fn check(name: &str, rep: &BlockReport, floor: f64) -> Result<(), String> {
    let bad = rep.outliers(4.0, floor);
    let worst = rep.worst().expect("blocks to judge");
    eprintln!(
        "{name}: mean ratio {:.4}, worst block {:?} rel {:+.4}, {} of {} blocks outside 4 SE + {floor}",
        rep.mean_ratio,
        worst.at,
        worst.rel(),
        bad.len(),
        rep.blocks.len()
    );
    if (rep.mean_ratio - 1.0).abs() >= 0.02 {
        return Err(format!("{name}: image mean ratio {:.4}", rep.mean_ratio));
    }
    if !bad.is_empty() {
        return Err(format!("{name}: blocks outside: {bad:?}"));
    }
    Ok(())
}

#[test]
fn every_integrator_agrees_with_path() {
    let reference = reference();
    let runs = [
        ("photon", RenderConfig { integrator: "photon".into(), spp: 4, seed: 7, ..Default::default() }.with("photons", 100_000)),
        ("sppm", sppm()),
        (
            "ppm",
            RenderConfig { integrator: "ppm".into(), spp: 2, seed: 7, ..Default::default() }
                .with("passes", 4)
                .with("photons_per_pass", 40_000),
        ),
    ];
    for (name, cfg) in runs {
        let img = render(cfg);
        check(name, &compare_blocks(&img, &reference, 16, 0.005).unwrap(), FLOOR).unwrap();
    }
    // Planted control: the coatings' delta and glossy reflection dropped (specular
    // reflectance 0 on the plastics) must fail the same check.
    let mut dropped = scene();
    for m in &mut dropped.materials {
        match &mut m.bsdf {
            Bsdf::Plastic(p) => p.specular_reflectance = Color::ZERO,
            Bsdf::RoughPlastic(p) => p.specular_reflectance = Color::ZERO,
            _ => {}
        }
    }
    let img = render_in(dropped, sppm());
    assert!(check("sppm, coatings dropped (control)", &compare_blocks(&img, &reference, 16, 0.005).unwrap(), FLOOR).is_err());
}

/// Residual bias allowed per block, relative to the reference.
const FLOOR: f64 = 0.05;

fn sppm() -> RenderConfig {
    RenderConfig { integrator: "sppm".into(), seed: 7, ..Default::default() }.with("passes", 32).with("photons_per_pass", 40_000)
}

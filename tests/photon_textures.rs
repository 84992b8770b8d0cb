//! The photon integrator sees what `path` sees: textured BSDF parameters at every
//! vertex (photon scattering, camera hits, final-gather hits, precomputed irradiance
//! and the irradiance cache, which store irradiance and take the reflectance of the
//! point they are read at) and the environment (seen directly, and lighting the
//! scene through light sampling and the photons it emits, counted once).
//!
//! Each scene is a Mitsuba XML file written into a tempdir; every gather is compared
//! with a `path` reference on 16-px block means; after the fix every block is within
//! ±3 %. Before it a textured floor (checkerboard 0.85/0.6 over the untextured 0.5)
//! rendered as its constant 0.5 and the environment was black to camera rays: blocks
//! off by −4 … −32 % and −100 %.

use photonlab::compare::{BlockReport, compare_blocks_below};
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::render_scene;
use photonlab::scene::Scene;
use photonlab::scene::loader::load_scene;
use std::path::Path;

const GATHERS: [&str; 4] = ["direct", "final_gather", "precomputed", "irradiance_cache"];

fn sensor(origin: &str, target: &str, fov: f32) -> String {
    format!(
        r#"<sensor type="perspective"><float name="fov" value="{fov}"/><string name="fov_axis" value="y"/>
<transform name="to_world"><lookat origin="{origin}" target="{target}" up="0,1,0"/></transform>
<sampler type="independent"><integer name="sample_count" value="16"/></sampler>
<film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/><rfilter type="box"/></film></sensor>"#
    )
}

fn load(dir: &Path, name: &str, body: &str) -> Scene {
    let p = dir.join(name);
    std::fs::write(&p, format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n")).unwrap();
    load_scene(&p).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn diffuse(refl: &str) -> String {
    format!(r#"<bsdf type="twosided"><bsdf type="diffuse">{refl}</bsdf></bsdf>"#)
}

fn rgb(v: &str) -> String {
    format!(r#"<rgb name="reflectance" value="{v}"/>"#)
}

/// A box open towards the camera, 2 × 2 × 2, its floor a checkerboard (0.85 / 0.6,
/// 4 × 4 checks: the untextured parameter is Mitsuba's 0.5), lit by a small area light
/// under the ceiling.
fn textured_box(dir: &Path) -> Scene {
    let checker = r#"<texture type="checkerboard" name="reflectance">
        <rgb name="color0" value="0.85, 0.85, 0.85"/><rgb name="color1" value="0.6, 0.6, 0.6"/>
        <transform name="to_uv"><scale x="4" y="4"/></transform></texture>"#;
    let wall = |t: &str, m: String| format!(r#"<shape type="rectangle"><transform name="to_world">{t}</transform>{m}</shape>"#);
    let body = [
        sensor("0, 0, 3.6", "0, 0, 0", 40.0),
        wall(r#"<rotate x="1" angle="-90"/><translate y="-1"/>"#, diffuse(checker)),
        wall(r#"<rotate x="1" angle="90"/><translate y="1"/>"#, diffuse(&rgb("0.7, 0.7, 0.7"))),
        wall(r#"<translate z="-1"/>"#, diffuse(&rgb("0.7, 0.7, 0.7"))),
        wall(r#"<rotate y="1" angle="90"/><translate x="-1"/>"#, diffuse(&rgb("0.7, 0.2, 0.2"))),
        wall(r#"<rotate y="1" angle="-90"/><translate x="1"/>"#, diffuse(&rgb("0.2, 0.7, 0.2"))),
        r#"<shape type="rectangle"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="0.98"/></transform>
           <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
           <emitter type="area"><rgb name="radiance" value="12, 12, 12"/></emitter></shape>"#
            .to_string(),
    ]
    .join("\n");
    load(dir, "textured-box.xml", &body)
}

/// An open scene lit by a `constant` environment alone: a floor with a cube and a
/// mirror on it, the upper part of the image sky.
fn open_sky(dir: &Path) -> Scene {
    let body = [
        sensor("0, 0.6, 4", "0, 0, 0", 45.0),
        format!(
            r#"<shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/><translate y="-0.5"/></transform>{}</shape>"#,
            diffuse(&rgb("0.7, 0.6, 0.5"))
        ),
        format!(r#"<shape type="cube"><transform name="to_world"><scale value="0.5"/></transform>{}</shape>"#, diffuse(&rgb("0.5, 0.6, 0.7"))),
        // A mirror showing the sky (camera rays that escape after a specular bounce)
        // and shading the floor in front of it (the sky it reflects there is caustic).
        r#"<shape type="rectangle"><transform name="to_world"><scale x="0.5" y="0.7"/><rotate y="1" angle="-25"/><translate x="1.1" y="0.25" z="-0.3"/></transform>
           <bsdf type="conductor"/></shape>"#
            .to_string(),
        r#"<emitter type="constant"><rgb name="radiance" value="1, 1, 1"/></emitter>"#.to_string(),
    ]
    .join("\n");
    load(dir, "open-sky.xml", &body)
}

fn render(scene: &Scene, cfg: RenderConfig) -> Film {
    render_scene(scene.clone(), &cfg, true).unwrap().film
}

fn reference(scene: &Scene) -> Film {
    render(scene, RenderConfig { spp: 256, resolution: Some([64, 64]), seed: 11, ..Default::default() })
}

fn photon(scene: &Scene, gather: &str) -> Film {
    let specular = scene.materials.iter().any(|m| m.bsdf.has_delta());
    let cfg = RenderConfig { integrator: "photon".into(), spp: 4, resolution: Some([64, 64]), seed: 5, ..Default::default() }
        .with("gather", gather)
        .with("photons", 200_000)
        .with("caustic_photons", if specular { 50_000 } else { 0 });
    render(scene, if gather == "direct" { cfg } else { cfg.with("gather_samples", 32).with("gather_per", "sample") })
}

/// Every gather's 16-px blocks against `path`: the worst |relative error| must stay
/// under `tol` (blocks holding an emitter's pixels are skipped: their error is the
/// outline's sampling).
fn check_every_gather(what: &str, scene: &Scene, tol: f64) {
    let reference = reference(scene);
    let mut bad = Vec::new();
    for g in GATHERS {
        let img = photon(scene, g);
        let rep: BlockReport = compare_blocks_below(&img, &reference, 16, 0.005, 5.0).unwrap();
        assert!(rep.blocks.len() >= 12, "{what}: only {} blocks judged", rep.blocks.len());
        let rel: Vec<String> = rep.blocks.iter().map(|b| format!("{:+.3}", b.rel())).collect();
        eprintln!("{what}, photon {g} vs path, 16-px blocks: {} (image mean ratio {:.3})", rel.join(" "), rep.mean_ratio);
        if rep.worst_rel() > tol {
            bad.push(format!("{g}: worst {:?} ({:+.3})", rep.worst().map(|b| b.at), rep.worst().map_or(0.0, |b| b.rel())));
        }
    }
    assert!(bad.is_empty(), "{what}: blocks off `path` by more than {tol}: {bad:?}");
}

/// Before: the floor rendered with its untextured 0.5 (direct light, photons
/// scattered off it, gather hits on it): floor blocks −27 … −32 % for every gather,
/// the walls, lit by the floor, −4 … −14 %.
#[test]
fn textured_floor_matches_path_for_every_gather() {
    let d = tempfile::tempdir().unwrap();
    let scene = textured_box(d.path());
    assert!(!scene.textures.is_empty());
    check_every_gather("textured box", &scene, 0.06);
}

/// Before: the sky black (blocks −100 %, −73 % where the cube's top edge meets it).
/// The floor and cube were right already: direct light samples the environment (it
/// is one of the light set's lights) and its photons carry the rest. So a
/// final-gather ray that escapes must add nothing; adding `world.escaped` there
/// counts the environment twice: floor blocks +81 … +100 % (`final_gather`,
/// `precomputed`, `irradiance_cache`).
#[test]
fn constant_environment_matches_path_for_every_gather() {
    let d = tempfile::tempdir().unwrap();
    let scene = open_sky(d.path());
    check_every_gather("open sky", &scene, 0.06);
}

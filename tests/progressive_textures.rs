//! The progressive integrators (`sppm`, `ppm`) on a textured, environment-lit scene:
//! an open box (no lid, no front) whose floor is a `checkerboard`-textured diffuse
//! surface (2 × 2 checks, 0.85 and 0.1–0.2), lit by a small area light inside and by a
//! `constant` environment seen above the back wall and below the open front, written
//! as Mitsuba XML into a tempdir. Their 16-px block means must agree with `path`'s
//! within 4 standard errors (pixel noise of both images, `photonlab::compare`) plus a
//! floor for the density estimation's bias at this pass count, and where the floor's
//! checks show, the image must differ from the same box with an untextured floor (the
//! 0.5 a texture leaves in the material, what `World::material` gives) as `path`'s does.

use photonlab::compare::{Block, compare_blocks};
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::render_scene;
use photonlab::scene::loader::load_scene;
use std::path::Path;

/// The floor's reflectance: the checkerboard, or the 0.5 a texture leaves in the material.
const CHECKER: &str = r#"<texture type="checkerboard" name="reflectance"><rgb name="color0" value="0.85, 0.8, 0.75"/><rgb name="color1" value="0.1, 0.15, 0.2"/></texture>"#;
const FLAT: &str = r#"<rgb name="reflectance" value="0.5"/>"#;

/// The open box with the floor's reflectance `floor`, written to `dir/name`.
fn write_box(dir: &Path, name: &str, floor: &str) -> std::path::PathBuf {
    let wall = |transform: &str, rgb: &str| {
        format!(
            r#"<shape type="rectangle"><transform name="to_world">{transform}</transform>
<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="{rgb}"/></bsdf></bsdf></shape>"#
        )
    };
    let body = [
        r#"<sensor type="perspective"><float name="fov" value="45"/><string name="fov_axis" value="y"/>
<transform name="to_world"><lookat origin="0, 2.4, 2.8" target="0, 0.3, 0" up="0, 1, 0"/></transform>
<film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/><rfilter type="box"/></film></sensor>"#
            .to_string(),
        format!(
            r#"<shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/></transform>
<bsdf type="twosided"><bsdf type="diffuse">{floor}</bsdf></bsdf></shape>"#
        ),
        wall(r#"<scale y="0.5"/><translate y="0.5" z="-1"/>"#, "0.6, 0.6, 0.6"),
        wall(r#"<scale y="0.5"/><rotate y="1" angle="90"/><translate x="-1" y="0.5"/>"#, "0.7, 0.3, 0.3"),
        wall(r#"<scale y="0.5"/><rotate y="1" angle="-90"/><translate x="1" y="0.5"/>"#, "0.3, 0.7, 0.3"),
        // A small light facing down inside the box (its top is seen: twosided grey).
        r#"<shape type="rectangle"><transform name="to_world"><scale value="0.2"/><rotate x="1" angle="90"/><translate x="-0.4" y="0.9" z="-0.5"/></transform>
<bsdf type="twosided"><bsdf type="diffuse"/></bsdf><emitter type="area"><rgb name="radiance" value="20"/></emitter></shape>"#
            .to_string(),
        r#"<emitter type="constant"><rgb name="radiance" value="0.6, 0.7, 0.9"/></emitter>"#.to_string(),
    ];
    let path = dir.join(name);
    std::fs::write(&path, format!("<scene version=\"3.0.0\">\n{}\n</scene>\n", body.join("\n"))).unwrap();
    path
}

fn render(scene: &Path, cfg: &RenderConfig) -> Film {
    render_scene(load_scene(scene).unwrap(), cfg, true).unwrap().film
}

/// Ratio of the 8-px block means of two images (column, row, ratio), for blocks
/// whose second mean exceeds 0.005.
fn block_ratios(a: &Film, b: &Film) -> Vec<((u32, u32), f64)> {
    compare_blocks(a, b, 8, 0.005).unwrap().blocks.iter().map(|b| (b.at, b.test / b.reference)).collect()
}

fn report(what: &str, blocks: &[Block]) -> String {
    let rel: Vec<String> =
        blocks.iter().map(|b| format!("{:?} {:+.3} ({:.1}σ)", b.at, b.rel(), (b.test - b.reference) / b.std_err)).collect();
    format!("{what}: {}", rel.join(", "))
}

/// The two boxes (textured, untextured floor), their `path` references and the
/// 8-px blocks where the texture shows (the textured reference differs from the
/// untextured one by over 25 %).
struct Boxes {
    _dir: tempfile::TempDir,
    textured: std::path::PathBuf,
    flat: std::path::PathBuf,
    reference: Film,
    contrast: Vec<((u32, u32), f64)>,
}

fn boxes() -> Boxes {
    let dir = tempfile::tempdir().unwrap();
    let (textured, flat) = (write_box(dir.path(), "box.xml", CHECKER), write_box(dir.path(), "flat.xml", FLAT));
    let path_cfg = RenderConfig { integrator: "path".into(), spp: 256, seed: 1234, ..Default::default() };
    let reference = render(&textured, &path_cfg);
    let contrast: Vec<((u32, u32), f64)> =
        block_ratios(&reference, &render(&flat, &path_cfg)).into_iter().filter(|b| (b.1 - 1.0).abs() > 0.25).collect();
    assert!(contrast.len() >= 8, "{} textured blocks", contrast.len());
    Boxes { _dir: dir, textured, flat, reference, contrast }
}

/// `cfg`'s render of the textured box against `path` (16-px blocks within 4 standard
/// errors + 5 %), and its texture: on the blocks where it shows, the ratio of the
/// textured to the untextured box's image is the reference's within half its
/// distance from 1.
fn check(name: &str, cfg: &RenderConfig) {
    let b = boxes();
    let img = render(&b.textured, cfg);
    let rep = compare_blocks(&img, &b.reference, 16, 0.005).unwrap();
    eprintln!("{}", report(&format!("{name} vs path"), &rep.blocks));
    eprintln!("{name}: image mean ratio {:.4}", rep.mean_ratio);
    let bad = rep.outliers(4.0, 0.05);
    assert!(bad.is_empty(), "{name}: blocks beyond 4 std err + 5 %: {}", report("", &bad));
    let ratios = block_ratios(&img, &render(&b.flat, cfg));
    let off: Vec<String> = b
        .contrast
        .iter()
        .filter_map(|&(at, want)| {
            let got = ratios.iter().find(|r| r.0 == at).map_or(1.0, |r| r.1);
            ((got - want).abs() > 0.5 * (want - 1.0).abs()).then(|| format!("{at:?} {got:.2} vs {want:.2}"))
        })
        .collect();
    assert!(off.is_empty(), "{name}: textured / untextured block ratios unlike the reference's: {}", off.join(", "));
}

/// Measured (64 passes, seed 7): blocks within −2.0 … +8.6 %, the largest 5.5σ where
/// photons scatter off the floor with its untextured reflectance (photon tracing is
/// not `sppm`'s own); within −1.1 … +3.6 % (2.4σ) once photons see the texture.
/// Without textures at the visible points the floor's checks vanish; without the
/// environment on escape the sky is black.
#[test]
fn sppm_sees_textures_and_the_environment() {
    check("sppm", &RenderConfig { integrator: "sppm".into(), seed: 7, ..Default::default() }.with("passes", 64));
}

/// `ppm` with its defaults (gather `direct`, every photon within the pass radius): it
/// renders each pass with the `photon` integrator, so it sees textures and the
/// environment when that integrator does (measured with it: blocks within −1.7 …
/// +0.1 %, image mean ratio 0.994).
#[test]
fn ppm_sees_textures_and_the_environment() {
    let cfg = RenderConfig { integrator: "ppm".into(), seed: 7, spp: 4, ..Default::default() }
        .with("passes", 16)
        .with("photons_per_pass", 20_000);
    check("ppm", &cfg);
}

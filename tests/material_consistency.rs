//! Every integrator agrees with `path` on every Mitsuba material: a box holding a
//! textured rough-plastic floor, a two-sided rough-plastic back wall, a rough gold
//! sphere, a smooth plastic sphere, a rough glass cube, a copper block, a cut-out
//! panel (mask) and a thin glass pane (`thindielectric`), lit by an area light, written as Mitsuba XML into a tempdir.
//!
//! Each integrator's 16-px block means are compared with a `path` reference: the
//! unbiased ones (`bdpt`, `vcm` in its `bpt` mode) within a few standard errors, the
//! consistent ones (`photon` at its default gather, `sppm`, `ppm`, `vcm`) within the
//! tolerance their density-estimation bias allows at this budget, which the materials'
//! own errors (a texture or a lobe ignored, a pdf or a weight wrong) exceed. Photon
//! estimates on the rough glass cube counted only the photons on the viewer's side:
//! its blocks were 21 % (`photon`) and 33 % (`ppm`) dark.

use photonlab::compare::compare_blocks_below;
use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::render_scene;
use photonlab::scene::Scene;
use photonlab::scene::loader::load_scene;
use std::path::Path;

const RES: u32 = 64;

/// The box; `glass_alpha` is the rough glass cube's roughness.
fn scene(dir: &Path, glass_alpha: f32) -> Scene {
    let wall = |t: &str, m: &str| format!(r#"<shape type="rectangle"><transform name="to_world">{t}</transform>{m}</shape>"#);
    let diffuse = |c: &str| format!(r#"<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="{c}"/></bsdf></bsdf>"#);
    let body = [
        format!(
            r#"<sensor type="perspective"><float name="fov" value="40"/>
<transform name="to_world"><lookat origin="0, 0, 3.9" target="0, 0, 0" up="0, 1, 0"/></transform>
<sampler type="independent"><integer name="sample_count" value="16"/></sampler>
<film type="hdrfilm"><integer name="width" value="{RES}"/><integer name="height" value="{RES}"/><rfilter type="box"/></film></sensor>"#
        ),
        wall(
            r#"<rotate x="1" angle="-90"/><translate y="-1"/>"#,
            r#"<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>
               <texture type="checkerboard" name="diffuse_reflectance"><rgb name="color0" value="0.8, 0.75, 0.7"/>
               <rgb name="color1" value="0.2, 0.25, 0.4"/><transform name="to_uv"><scale value="3"/></transform></texture></bsdf>"#,
        ),
        wall(r#"<rotate x="1" angle="90"/><translate y="1"/>"#, &diffuse("0.75, 0.75, 0.75")),
        wall(
            r#"<translate z="-1"/>"#,
            r#"<bsdf type="twosided"><bsdf type="roughplastic"><float name="alpha" value="0.3"/>
               <rgb name="diffuse_reflectance" value="0.6, 0.6, 0.55"/></bsdf></bsdf>"#,
        ),
        wall(r#"<rotate y="1" angle="90"/><translate x="-1"/>"#, &diffuse("0.63, 0.07, 0.05")),
        wall(r#"<rotate y="1" angle="-90"/><translate x="1"/>"#, &diffuse("0.14, 0.45, 0.09")),
        wall(
            r#"<scale value="0.3"/><rotate x="1" angle="90"/><translate y="0.99"/>"#,
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf><emitter type="area"><rgb name="radiance" value="12, 10, 8"/></emitter>"#,
        ),
        r#"<shape type="sphere"><point name="center" x="-0.5" y="-0.65" z="-0.3"/><float name="radius" value="0.35"/>
           <bsdf type="roughconductor"><string name="material" value="Au"/><float name="alpha" value="0.3"/></bsdf></shape>"#
            .into(),
        r#"<shape type="sphere"><point name="center" x="0.1" y="-0.8" z="0.45"/><float name="radius" value="0.2"/>
           <bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.7, 0.1, 0.1"/></bsdf></shape>"#
            .into(),
        wall(
            r#"<scale value="0.25"/><rotate y="1" angle="30"/><translate x="0.5" y="-0.75" z="-0.2"/>"#,
            &format!(r#"<bsdf type="roughdielectric"><float name="alpha" value="{glass_alpha}"/><float name="int_ior" value="1.5"/></bsdf>"#),
        )
        .replace("rectangle", "cube"),
        wall(
            r#"<scale x="0.3" y="0.4"/><rotate y="1" angle="70"/><translate x="-0.75" y="0.2" z="0.1"/>"#,
            r#"<bsdf type="mask"><texture type="checkerboard" name="opacity"><rgb name="color0" value="1"/><rgb name="color1" value="0"/>
               <transform name="to_uv"><scale value="2"/></transform></texture>
               <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></bsdf></bsdf>"#,
        ),
        wall(
            r#"<scale x="0.15" y="0.25"/><rotate y="1" angle="-30"/><translate x="0.7" y="-0.75" z="-0.7"/>"#,
            r#"<bsdf type="conductor"><string name="material" value="Cu"/></bsdf>"#,
        ),
        wall(
            r#"<scale x="0.3" y="0.25"/><rotate y="1" angle="-20"/><translate x="0.35" y="0.35" z="-0.4"/>"#,
            r#"<bsdf type="thindielectric"><float name="int_ior" value="1.5"/></bsdf>"#,
        ),
    ]
    .join("\n");
    let p = dir.join("materials.xml");
    std::fs::write(&p, format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n")).unwrap();
    load_scene(&p).unwrap_or_else(|e| panic!("{e:#}"))
}

fn render(scene: &Scene, cfg: RenderConfig) -> Film {
    render_scene(scene.clone(), &cfg.with_resolution(RES), true).unwrap().film
}

trait Res {
    fn with_resolution(self, r: u32) -> Self;
}
impl Res for RenderConfig {
    fn with_resolution(mut self, r: u32) -> Self {
        self.resolution = Some([r, r]);
        self
    }
}

/// `(integrator, config, tolerance on the worst 16-px block's |relative error|)`; the
/// photon integrator with its default gather (`irradiance_cache`) and each other one.
fn cases() -> Vec<(&'static str, RenderConfig, f64)> {
    let base = |i: &str, spp: u32, seed: u64| RenderConfig { integrator: i.into(), spp, seed, ..Default::default() };
    vec![
        ("bdpt", base("bdpt", 16, 3), 0.06),
        ("photon", base("photon", 8, 4).with("photons", 300_000), 0.06),
        ("photon gather=direct", base("photon", 8, 4).with("photons", 300_000).with("gather", "direct"), 0.08),
        // 16 samples: at 4 the worst block's noise alone spread ±0.05 over seeds 4–9
        // (+0.086 at seed 4 on one CPU, −0.049…+0.016 at the others), so 0.08 judged
        // the draw rather than the bias; at 16 seeds 4 and 5 give +0.014 and −0.032.
        ("photon gather=final_gather", base("photon", 16, 4).with("photons", 300_000).with("gather", "final_gather"), 0.08),
        ("photon gather=precomputed", base("photon", 8, 4).with("photons", 300_000).with("gather", "precomputed"), 0.06),
        ("sppm", base("sppm", 1, 5).with("passes", 32), 0.06),
        ("ppm", base("ppm", 1, 6).with("passes", 8).with("photons", 100_000), 0.08),
        ("vcm", base("vcm", 1, 7).with("passes", 16).with("vcm_select", "off"), 0.06),
    ]
}

#[test]
fn every_integrator_agrees_with_path_on_every_material() {
    let d = tempfile::tempdir().unwrap();
    check(&scene(d.path(), 0.3), cases());
}

/// Narrow rough glass (α = 0.1): the photon integrator passes through it by sampling
/// its BSDF, as through glass, instead of estimating a photon density under a narrow
/// transmission lobe — which put its block +23 % (`gather = "direct"`) and +10 %
/// (`ppm`) off `path` here, and +27 % on Mitsuba's own image of `mi-rough.xml`.
#[test]
fn photon_estimates_pass_through_narrow_rough_glass() {
    let d = tempfile::tempdir().unwrap();
    let photon_family = cases().into_iter().filter(|c| c.0.starts_with("photon") || c.0 == "ppm").collect();
    check(&scene(d.path(), 0.1), photon_family);
}

fn check(scene: &Scene, cases: Vec<(&'static str, RenderConfig, f64)>) {
    assert!(!scene.textures.is_empty());
    let reference = render(scene, RenderConfig { spp: 256, seed: 1, ..Default::default() });
    let mut bad = Vec::new();
    for (name, cfg, tol) in cases {
        let img = render(scene, cfg);
        let rep = compare_blocks_below(&img, &reference, 16, 0.005, 5.0).unwrap();
        assert!(rep.blocks.len() >= 12, "{name}: only {} blocks judged", rep.blocks.len());
        let rel: Vec<String> = rep.blocks.iter().map(|b| format!("{:+.3}", b.rel())).collect();
        eprintln!("{name} vs path, 16-px blocks: {} (image mean ratio {:.4})", rel.join(" "), rep.mean_ratio);
        if rep.worst_rel() > tol {
            bad.push(format!("{name}: worst {:?} {:+.3} > {tol}", rep.worst().map(|b| b.at), rep.worst().map_or(0.0, |b| b.rel())));
        }
    }
    assert!(bad.is_empty(), "{bad:?}");
}

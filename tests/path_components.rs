//! The `path` integrator's extra images split the image by path type: direct,
//! indirect and caustic add up to the full image, each carries light where it should,
//! and a manifest can measure one component against a component reference.

use photonlab::config::RenderConfig;
use photonlab::experiment::manifest::Manifest;
use photonlab::experiment::{RunArgs, run};
use photonlab::pipeline::render_scene_with_aovs;
use photonlab::scene::builtin::builtin;
use std::path::Path;

#[test]
fn direct_indirect_and_caustic_add_up_to_the_image() {
    let mut cfg = RenderConfig { integrator: "path".into(), spp: 4, resolution: Some([48, 48]), max_depth: Some(6), ..Default::default() };
    let aovs: Vec<String> = ["direct", "indirect", "caustic"].iter().map(|s| s.to_string()).collect();
    let scene = builtin("cornell-glass").unwrap();
    let o = render_scene_with_aovs(scene, &cfg, true, &aovs).unwrap();
    let parts: Vec<_> = o.aovs.iter().map(|(_, f)| f).collect();
    let mut worst = 0.0f32;
    for (i, p) in o.film.pixels.iter().enumerate() {
        let sum = parts[0].pixels[i] + parts[1].pixels[i] + parts[2].pixels[i];
        worst = worst.max(((sum - *p).abs() / (p.abs() + glam::Vec3::splat(1e-3))).max_element());
    }
    assert!(worst < 1e-4, "components do not add up: worst relative difference {worst}");
    let mean = |i: usize| parts[i].mean().element_sum();
    let full = o.film.mean().element_sum();
    // Direct light dominates the box; indirect is a sizeable share; the glass sphere
    // focuses a caustic on the floor.
    assert!(mean(0) > 0.4 * full && mean(1) > 0.1 * full && mean(2) > 1e-3 * full, "{} {} {} of {full}", mean(0), mean(1), mean(2));
    // Without mirrors or glass there is no caustic at all, and indirect light remains.
    cfg.resolution = Some([24, 24]);
    let o = render_scene_with_aovs(builtin("cornell").unwrap(), &cfg, true, &aovs).unwrap();
    assert_eq!(o.aovs[2].1.mean().element_sum(), 0.0);
    assert!(o.aovs[1].1.mean().element_sum() > 0.1 * o.film.mean().element_sum());
}

#[test]
fn a_manifest_measures_one_component() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let text = r#"
scene = "cornell"
resolution = [24, 24]
component = "indirect"
[reference]
integrator = "path"
spp = 8
max_depth = 4
[base]
integrator = "photon"
spp = 1
photons = 2000
caustic_photons = 0
gather = "direct"
"#;
    let m = d.join("c.toml");
    std::fs::write(&m, text).unwrap();
    let out = d.join("c");
    run(&RunArgs::quiet(m.clone(), out.clone())).unwrap();
    let read = |p: &str| photonlab::film::Film::read_exr(&out.join(p)).unwrap().mean().element_sum();
    let (full, r, c) = (read("reference-cornell.exr"), read("reference-cornell.indirect.exr"), read("cells/base_r0.indirect.exr"));
    // Indirect light only: darker than the lit box, but not black, in cell and reference.
    assert!(r > 0.0 && r < 0.8 * full && c > 0.0 && c < 3.0 * r && r < 3.0 * c, "full {full} reference {r} cell {c}");
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("Measured component: `indirect`") && summary.contains("| indirect relMSE |"), "{summary}");
    let mut csv = csv::Reader::from_path(out.join("cells.csv")).unwrap();
    let h = csv.headers().unwrap().clone();
    let row = csv.records().next().unwrap().unwrap();
    let col = |name: &str| row[h.iter().position(|x| x == name).unwrap()].to_string();
    assert_eq!(col("component"), "indirect");
    assert!(col("comp_relmse").parse::<f64>().unwrap() > 0.0);
    // A component nothing renders is a clear error naming the line.
    let bad = text.replace("component = \"indirect\"", "component = \"glossy\"");
    let e = Manifest::parse(&bad, Path::new("c.toml"), d).unwrap_err().to_string();
    assert!(e.contains("c.toml:4") && e.contains("glossy"), "{e}");
    std::fs::remove_dir_all(d).ok();
}

//! End-to-end tests of the experiment runner on tiny images: expansion, validation
//! errors with line numbers, outputs, resume after an interruption, shard + merge,
//! the reference cache and determinism.

use photonlab::experiment::manifest::Manifest;
use photonlab::experiment::{RunArgs, RunReport, Shard, run};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A fresh directory for one test (kept: tests inspect it; the OS cleans /tmp).
fn scratch(name: &str) -> PathBuf {
    tempfile::Builder::new().prefix(&format!("photonlab-exp-test-{name}-")).tempdir().unwrap().keep()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Four configurations × two repeats of the path tracer at 12×12.
const TINY: &str = r#"
scene = "cornell"
resolution = [12, 12]

[reference]
integrator = "path"
spp = 16

[base]
integrator = "path"
max_depth = 4

[sweep]
spp = [1, 2]
sampler = ["random", "halton"]
repeats = 2
"#;

fn run_into(manifest: &Path, out: &Path, shard: Option<&str>, force: bool) -> RunReport {
    run(&RunArgs { force, shard: shard.map(|s| s.parse::<Shard>().unwrap()), ..RunArgs::quiet(manifest, out) }).unwrap()
}

/// cells.csv as (header, rows keyed by cell).
fn read_csv(dir: &Path) -> (Vec<String>, BTreeMap<String, Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("cells.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(str::to_string).collect();
    let rows = lines.map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>()).map(|r| (r[0].clone(), r)).collect();
    (header, rows)
}

/// The columns that must not depend on how or when a cell ran (not times).
fn stable(header: &[String], row: &[String]) -> Vec<(String, String)> {
    header.iter().zip(row).filter(|(h, _)| !h.ends_with("_s")).map(|(h, v)| (h.clone(), v.clone())).collect()
}

#[test]
fn manifest_expansion_exclusion_and_repeats() {
    let d = scratch("expand");
    let p = write(
        &d,
        "m.toml",
        &format!("{TINY}exclude = [{{ spp = 2, sampler = \"random\" }}, {{ spp = 1, sampler = \"halton\" }}]\n")
            .replace("repeats = 2", "repeats = 3"),
    );
    let m = Manifest::load(&p).unwrap();
    assert_eq!(m.name, "m");
    assert_eq!(m.axes, ["spp", "sampler"]);
    assert_eq!(m.configurations(), 2);
    assert_eq!(m.cells.len(), 6);
    let labels: Vec<&str> = m.cells.iter().map(|c| c.label.as_str()).collect();
    assert_eq!(labels[0], "spp=1 sampler=random");
    assert_eq!(labels[3], "spp=2 sampler=halton");
    let seeds: Vec<u64> = m.cells.iter().map(|c| c.config.seed).collect();
    assert_eq!(seeds, [0, 1, 2, 0, 1, 2]);
    assert!(m.cells.iter().all(|c| c.config.max_depth == Some(4) && c.config.resolution == Some([12, 12])));
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn validation_errors_name_file_and_line() {
    let d = scratch("errors");
    let cases: &[(&str, &str, &str)] = &[
        ("spp = [1, 2]", "spp = [1, 2]\nsamplr = [\"random\"]", "samplr"),
        ("spp = [1, 2]", "spp = []", "empty axis"),
        ("spp = [1, 2]", "spp = [1, 0]", "spp must be at least 1"),
        ("sampler = [\"random\", \"halton\"]", "sampler = [\"random\", \"latin\"]", "latin"),
        ("max_depth = 4", "max_depth = \"deep\"", "max_depth"),
    ];
    for (from, to, needle) in cases {
        let text = TINY.replacen(from, to, 1);
        let line = text.lines().position(|l| l.starts_with(to.lines().last().unwrap())).unwrap() + 1;
        let p = write(&d, "bad.toml", &text);
        let e = format!("{:#}", Manifest::load(&p).unwrap_err());
        let want = format!("{}:{line}:", p.display());
        assert!(e.starts_with(&want), "expected `{want}` in: {e}");
        assert!(e.contains(needle), "expected `{needle}` in: {e}");
    }
    // A combination that only fails together (rr off needs max_depth) names the axis line.
    let text = TINY.replace("max_depth = 4\n", "").replacen("spp = [1, 2]", "spp = [1, 2]\nrr = [\"throughput\", \"off\"]", 1);
    let p = write(&d, "bad.toml", &text);
    let e = format!("{:#}", Manifest::load(&p).unwrap_err());
    let line = text.lines().position(|l| l.starts_with("rr =")).unwrap() + 1;
    assert!(e.starts_with(&format!("{}:{line}:", p.display())) && e.contains("max_depth"), "{e}");
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn run_writes_tables_images_plots_and_resumes_after_interruption() {
    let d = scratch("run");
    let p = write(&d, "tiny.toml", TINY);
    let out = d.join("tiny");
    let r = run_into(&p, &out, None, false);
    assert_eq!((r.ran, r.kept, r.finalized, r.reference_rendered), (8, 0, true, true));
    let (header, rows) = read_csv(&out);
    assert_eq!(rows.len(), 8);
    for col in
        ["cell", "rmse", "relmse", "mae", "bias2", "variance", "rel_bias2", "time_total_s", "rays", "threads", "cfg_sampler", "cfg_spp"]
    {
        assert!(header.iter().any(|h| h == col), "column {col} missing: {header:?}");
    }
    assert_eq!(std::fs::read_to_string(out.join("cells.jsonl")).unwrap().lines().count(), 8);
    for f in [
        "summary.md",
        "reference-cornell.png",
        "plots/error_vs_time.png",
        "plots/error_vs_time.svg",
        "plots/error_vs_spp.png",
        "plots/bias_variance.svg",
        "plots/phase_times.png",
        "cells/spp-1_sampler-random_r0.exr",
        "cells/spp-1_sampler-random_r0.png",
        "cells/spp-1_sampler-random_r0.relerr.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        summary.contains("| spp=2 sampler=halton |") && summary.contains("![Relative MSE vs spp](plots/error_vs_spp.png)"),
        "{summary}"
    );
    // More samples, less error (same sampler, averaged over repeats).
    let rel = |cell: &str| rows[cell][header.iter().position(|h| h == "relmse").unwrap()].parse::<f64>().unwrap();
    assert!(
        rel("spp-2_sampler-halton_r0") + rel("spp-2_sampler-halton_r1") < rel("spp-1_sampler-halton_r0") + rel("spp-1_sampler-halton_r1")
    );

    // Simulated interruptions: one cell's record never renamed into place (only its
    // temporary file exists), one record torn (a writer that did not rename); and a
    // sentinel in a finished record proves finished cells are kept, not redone.
    let cells = out.join("cells");
    let a = cells.join("spp-1_sampler-halton_r1.json");
    let text_a = std::fs::read_to_string(&a).unwrap();
    std::fs::remove_file(&a).unwrap();
    std::fs::write(cells.join("spp-1_sampler-halton_r1.json.tmp4242"), &text_a[..text_a.len() / 2]).unwrap();
    let b = cells.join("spp-2_sampler-random_r0.json");
    let text_b = std::fs::read_to_string(&b).unwrap();
    std::fs::write(&b, &text_b[..text_b.len() - 10]).unwrap();
    let kept = cells.join("spp-1_sampler-random_r0.json");
    let sentinel = std::fs::read_to_string(&kept).unwrap().replacen("\"render_s\": ", "\"render_s\": 4242.0, \"was\": ", 1);
    std::fs::write(&kept, sentinel).unwrap();
    let r = run_into(&p, &out, None, false);
    assert_eq!((r.ran, r.kept, r.reference_rendered), (2, 6, false));
    let (h2, rows2) = read_csv(&out);
    assert_eq!(rows2["spp-1_sampler-random_r0"][h2.iter().position(|h| h == "render_s").unwrap()], "4242");
    for cell in ["spp-1_sampler-halton_r1", "spp-2_sampler-random_r0"] {
        assert_eq!(stable(&header, &rows[cell]), stable(&h2, &rows2[cell]), "{cell} differs after being redone");
    }
    // --force redoes everything.
    let r = run_into(&p, &out, None, true);
    assert_eq!((r.ran, r.kept), (8, 0));
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn shards_merged_equal_one_run_and_reference_cache() {
    let d = scratch("shard");
    let p = write(&d, "tiny.toml", TINY);
    let one = d.join("one");
    assert!(run_into(&p, &one, None, false).reference_rendered);
    let sharded = d.join("sharded");
    // Shards run in reverse order; the reference is reused from the cache.
    let mut ran = 0;
    for s in ["3/3", "2/3"] {
        let r = run_into(&p, &sharded, Some(s), false);
        assert!(!r.finalized && !r.reference_rendered);
        ran += r.ran;
    }
    let e = format!("{:#}", photonlab::experiment::finalize(&sharded, true).unwrap_err());
    assert!(e.contains("3 of 8 cells are not finished"), "{e}");
    // The last shard on "another machine": its own directory, cells copied over.
    let elsewhere = d.join("elsewhere");
    ran += run_into(&p, &elsewhere, Some("1/3"), false).ran;
    assert_eq!(ran, 8);
    assert_eq!(photonlab::experiment::import_cells(&sharded, &elsewhere).unwrap(), 3);
    assert_eq!(photonlab::experiment::import_cells(&sharded, &elsewhere).unwrap(), 0);
    photonlab::experiment::finalize(&sharded, true).unwrap();
    let (h1, r1) = read_csv(&one);
    let (h2, r2) = read_csv(&sharded);
    assert_eq!(h1, h2);
    assert_eq!(r1.keys().collect::<Vec<_>>(), r2.keys().collect::<Vec<_>>());
    for (cell, row) in &r1 {
        assert_eq!(stable(&h1, row), stable(&h2, &r2[cell]), "{cell}");
    }
    let refs =
        || std::fs::read_dir(d.join("references")).unwrap().filter(|e| e.as_ref().unwrap().path().extension().unwrap() == "exr").count();
    assert_eq!(refs(), 1);
    // Changing anything that affects the reference renders a new one.
    let p2 = write(&d, "tiny.toml", &TINY.replace("spp = 16", "spp = 17"));
    let r = run_into(&p2, &d.join("other"), Some("1/8"), false);
    assert!(r.reference_rendered);
    assert_eq!(refs(), 2);
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn images_do_not_depend_on_threads_and_photon_counters_are_recorded() {
    let d = scratch("threads");
    let text = r#"
scene = "cornell-glass"
resolution = [10, 8]
[reference]
spp = 8
max_depth = 3
[base]
integrator = "photon"
spp = 1
photons = 3000
caustic_photons = 1000
gather = "irradiance_cache"
gather_samples = 8
[sweep]
threads = [1, 2]
"#;
    let p = write(&d, "t.toml", text);
    let out = d.join("t");
    run_into(&p, &out, None, false);
    let (h, rows) = read_csv(&out);
    let col = |name: &str| h.iter().position(|x| x == name).unwrap_or_else(|| panic!("no column {name}: {h:?}"));
    let (a, b) = (&rows["threads-1_r0"], &rows["threads-2_r0"]);
    for name in ["rmse", "relmse", "mae", "photons_emitted", "photons_caustic", "cache_entries", "rays"] {
        assert_eq!(a[col(name)], b[col(name)], "{name}");
    }
    assert!(a[col("photons_emitted")].parse::<f64>().unwrap() > 0.0);
    assert_eq!(a[col("width")], "10");
    let ea = std::fs::read(out.join("cells/threads-1_r0.exr")).unwrap();
    let eb = std::fs::read(out.join("cells/threads-2_r0.exr")).unwrap();
    assert_eq!(ea, eb);
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn shipped_manifests_validate_and_missing_models_are_clear_errors() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let (mut n, mut loaded) = (0, 0);
    for dir in [root.clone(), root.join("external")] {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                let m = Manifest::load(&p).unwrap_or_else(|e| panic!("{}: {e:#}", p.display()));
                assert!(!m.cells.is_empty());
                n += 1;
                // Every scene loads, except external models absent here (which must say where to get them).
                for s in &m.scenes {
                    match s.check_files() {
                        Ok(()) => {
                            s.load(m.resolution).unwrap_or_else(|e| panic!("{e:#}"));
                            loaded += 1;
                        }
                        Err(e) => assert!(format!("{e:#}").contains("download it from"), "{e:#}"),
                    }
                }
            }
        }
    }
    assert!(n >= 9 && loaded >= n - 2, "only {n} manifests, {loaded} scenes loaded");
    eprintln!("{n} manifests, {loaded} scenes loaded");
    // The external models are not in the repository: running says where to get them.
    let d = scratch("external");
    let text = std::fs::read_to_string(root.join("external/dragon.toml")).unwrap();
    let p = write(&d, "dragon.toml", &text);
    // The box it names, copied beside it (the model itself is absent in the copy).
    std::fs::create_dir_all(d.join("cornell-empty")).unwrap();
    for f in ["cornell-empty.toml", "cornell-empty.obj", "cornell-empty.mtl"] {
        std::fs::copy(root.join("external/cornell-empty").join(f), d.join("cornell-empty").join(f)).unwrap();
    }
    let e = run(&RunArgs::quiet(p.clone(), d.join("dragon"))).unwrap_err();
    let e = format!("{e:#}");
    assert!(e.starts_with(&p.display().to_string()) && e.contains("not found") && e.contains("download"), "{e}");
    assert!(!d.join("dragon").exists());
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn sigkill_mid_run_then_resume_gives_the_uninterrupted_results() {
    let d = scratch("kill");
    let text = TINY.replace("[12, 12]", "[40, 40]").replace("spp = [1, 2]", "spp = [8, 16]");
    let p = write(&d, "k.toml", &text);
    // The reference first, alone (as a cluster would before starting the shards).
    let r = run(&RunArgs { reference_only: true, ..RunArgs::quiet(p.clone(), d.join("killed")) }).unwrap();
    assert!(r.reference_rendered && r.ran == 0 && !d.join("killed/cells.csv").exists());
    // A real process killed with SIGKILL as soon as its first cell is recorded.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_photonlab"))
        .args(["run", p.to_str().unwrap(), "--quiet", "--out", d.join("killed").to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let cells = d.join("killed/cells");
    let recorded = || {
        std::fs::read_dir(&cells)
            .map(|r| r.filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "json")).count())
            .unwrap_or(0)
    };
    let start = std::time::Instant::now();
    while recorded() == 0 && start.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    // However far it got, resuming must give exactly the results of a run that was
    // never interrupted (in another directory).
    let r = run_into(&p, &d.join("killed"), None, false);
    assert!(r.kept >= 1 && r.ran + r.kept == 8 && !r.reference_rendered, "{r:?}");
    run_into(&p, &d.join("whole"), None, false);
    let (h1, r1) = read_csv(&d.join("killed"));
    let (h2, r2) = read_csv(&d.join("whole"));
    assert_eq!(r1.len(), 8);
    for (cell, row) in &r1 {
        assert_eq!(stable(&h1, row), stable(&h2, &r2[cell]), "{cell}");
    }
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn several_scenes_get_their_own_references() {
    let d = scratch("scenes");
    let text = TINY.replace("scene = \"cornell\"", "scene = [\"cornell\", \"furnace\"]").replace("repeats = 2", "repeats = 1");
    let p = write(&d, "s.toml", &text);
    let out = d.join("s");
    let r = run_into(&p, &out, None, false);
    assert_eq!(r.ran, 8);
    let (h, rows) = read_csv(&out);
    assert!(rows.contains_key("scene-furnace_spp-2_sampler-halton_r0"));
    for f in ["reference-cornell.exr", "reference-furnace.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // Errors are measured against each scene's own reference: the furnace's image is
    // uniform (L_e / (1 − a)), so even 1 spp is close to it, unlike the Cornell box.
    let rel = |c: &str| rows[c][h.iter().position(|x| x == "relmse").unwrap()].parse::<f64>().unwrap();
    assert!(rel("scene-furnace_spp-1_sampler-random_r0") < 0.5 * rel("scene-cornell_spp-1_sampler-random_r0"));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("![reference furnace](reference-furnace.png)"), "{summary}");
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn scene_table_places_models_and_adds_lights() {
    let d = scratch("model");
    // A tetrahedron in arbitrary units, off-centre: fit_height must normalise it.
    write(&d, "tet.obj", "v 10 5 10\nv 12 5 10\nv 10 5 12\nv 11 9 11\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n");
    let text = r#"
resolution = [12, 12]
[scene]
builtin = "cornell"
[[scene.mesh]]
obj = "tet.obj"
fit_height = 150.0
translate = [278.0, 0.0, 280.0]
material = { type = "diffuse", albedo = [0.5, 0.5, 0.5] }
[[scene.light]]
type = "point"
position = [278.0, 400.0, 280.0]
intensity = [5000.0, 5000.0, 5000.0]
[reference]
spp = 4
[base]
spp = 1
"#;
    let p = write(&d, "m.toml", text);
    let m = Manifest::load(&p).unwrap();
    let scene = m.scenes[0].load(m.resolution).unwrap();
    let plain = photonlab::scene::builtin::builtin("cornell").unwrap();
    assert_eq!(scene.triangles.len(), plain.triangles.len() + 4);
    assert_eq!(scene.lights.len(), plain.lights.len() + 1);
    let added = &scene.triangles[plain.triangles.len()..];
    let ys = added.iter().flatten().map(|v| v.y);
    let (lo, hi) = ys.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
    assert!(lo.abs() < 1e-3 && (hi - 150.0).abs() < 1e-2, "{lo} {hi}");
    let cx = added.iter().flatten().map(|v| v.x).fold(f32::INFINITY, f32::min);
    // Scale 150 / 4 = 37.5, the model 2 wide: centred on x = 278.
    assert!((cx - (278.0 - 37.5)).abs() < 1e-2, "{cx}");
    // It renders, and its reference is not the plain box's.
    let r = run_into(&p, &d.join("m"), None, false);
    assert!(r.reference_rendered && r.finalized);
    let plain_text = "scene = \"cornell\"\nresolution = [12, 12]\n[reference]\nspp = 4\n[base]\nspp = 1\n";
    let plain_manifest = write(&d, "plain.toml", plain_text);
    assert!(run_into(&plain_manifest, &d.join("plain"), None, false).reference_rendered);
    // Without the model, the error names the manifest and the missing file.
    std::fs::remove_file(d.join("tet.obj")).unwrap();
    let e = format!("{:#}", Manifest::load(&p).unwrap().scenes[0].load([12, 12]).unwrap_err());
    assert!(e.contains("m.toml:5: [[scene.mesh]] 1") && e.contains("tet.obj") && e.contains("not found"), "{e}");
    std::fs::remove_dir_all(d).ok();
}

/// A floor quad (2 × 2 at y = 0, facing up) with its own grey MTL material.
fn write_floor(d: &Path) {
    write(d, "floor.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n");
    write(d, "floor.obj", "mtllib floor.mtl\nusemtl grey\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 4 3 2\n");
}

/// The scene of the two tests below in the scene contract's keys: a floor, a raised
/// glossy copy of it (material override), a spot light and a point light.
const CONTRACT_SCENE: &str = r#"
[camera]
eye = [0.0, 1.5, 3.0]
look_at = [0.0, 0.3, 0.0]
fov_y_deg = 50.0
resolution = [12, 12]

[[mesh]]
obj = "floor.obj"

[[mesh]]
obj = "floor.obj"
scale = [0.4, 1.0, 0.3]
rotate_y_deg = 30.0
translate = [0.2, 0.5, 0.0]
material = { type = "glossy", kd = [0.2, 0.3, 0.2], ks = [0.5, 0.5, 0.5], ns = 20 }

[[light]]
type = "spot"
position = [0.0, 2.0, 0.0]
direction = [0.0, -1.0, 0.1]
intensity = [20.0, 18.0, 15.0]
cone_deg = 25.0
falloff_deg = 35.0

[[light]]
type = "point"
position = [1.0, 1.0, 1.0]
intensity = [0.5, 0.5, 0.5]
"#;

/// The contract scene as a manifest's inline `[scene]`: the same tables under `scene.`.
fn inline(scene: &str) -> String {
    scene.replace("[camera]", "[scene.camera]").replace("[[mesh]]", "[[scene.mesh]]").replace("[[light]]", "[[scene.light]]")
}

#[test]
fn inline_scene_with_a_spot_light_and_a_material_override_renders() {
    let d = scratch("inline-spot");
    write_floor(&d);
    // The camera's resolution is left out: the manifest's is used.
    let scene = inline(CONTRACT_SCENE).replace("resolution = [12, 12]\n", "");
    let text = format!(
        "resolution = [12, 12]\n{scene}\n[reference]\nintegrator = \"path\"\nspp = 16\n\n\
         [[configs]]\nname = \"path\"\nintegrator = \"path\"\nspp = 2\n\n\
         [[configs]]\nname = \"photon\"\nintegrator = \"photon\"\nspp = 2\nphotons = 4000\ncaustic_photons = 0\n"
    );
    let p = write(&d, "m.toml", &text);
    let m = Manifest::load(&p).unwrap();
    let s = m.scenes[0].load(m.resolution).unwrap();
    assert_eq!((s.camera.width, s.camera.height), (12, 12));
    assert!(matches!(s.lights[0], photonlab::scene::LightDesc::Spot { cone_deg: 25.0, falloff_deg: 35.0, .. }), "{:?}", s.lights);
    let glossy = s.material(s.triangles.len() as u32 - 1);
    assert!(matches!(glossy.bsdf, photonlab::material::Bsdf::Glossy(_)), "{glossy:?}");
    let r = run_into(&p, &d.join("out"), None, false);
    assert!(r.reference_rendered && r.finalized && r.ran == 2);
    let lit = |dir: &Path| photonlab::film::Film::read_exr(&dir.join("reference-scene.exr")).unwrap().mean();
    let with_override = lit(&d.join("out"));
    assert!(with_override.min_element() > 0.0, "{with_override}");
    // Without the override the raised quad is grey: a different image.
    let plain = write(&d, "plain.toml", &text.replace("material = { type = \"glossy\"", "# material = { type = \"glossy\""));
    run_into(&plain, &d.join("plain"), None, false);
    assert_ne!(lit(&d.join("plain")), with_override);
    std::fs::remove_dir_all(d).ok();
}

#[test]
fn inline_scene_is_the_same_scene_as_the_file() {
    let d = scratch("inline-same");
    write_floor(&d);
    write(&d, "s.toml", CONTRACT_SCENE);
    let tail = "resolution = [12, 12]\n[reference]\nspp = 4\n[base]\nspp = 1\n";
    let from_file = write(&d, "file.toml", &format!("scene = \"s.toml\"\n{tail}"));
    let from_inline = write(&d, "inline.toml", &format!("{tail}{}", inline(CONTRACT_SCENE)));
    let load = |p: &Path| {
        let m = Manifest::load(p).unwrap();
        m.scenes[0].load(m.resolution).unwrap()
    };
    let (a, b) = (load(&from_file), load(&from_inline));
    assert_eq!(a.triangles, b.triangles);
    assert_eq!((&a.tri_material, &a.tri_normals, &a.normals), (&b.tri_material, &b.tri_normals, &b.normals));
    assert_eq!((&a.materials, &a.lights), (&b.materials, &b.lights));
    assert_eq!(format!("{:?}", a.camera), format!("{:?}", b.camera));
    assert_eq!(a.lights.len(), 2);
    let cfg = photonlab::config::RenderConfig { spp: 2, ..Default::default() };
    let render = |s| photonlab::pipeline::render_scene(s, &cfg, true).unwrap().film.pixels;
    let (ia, ib) = (render(a), render(b));
    assert!(ia.iter().zip(&ib).all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)));
    assert!(ia.iter().any(|c| c.max_element() > 0.0));
    std::fs::remove_dir_all(d).ok();
}

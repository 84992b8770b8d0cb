//! End-to-end tests of the progressive integrators (`sppm`, `ppm`): images after every
//! pass bit-identical for any thread count, agreement with the path tracer, the
//! runner's per-pass error curve, and clear errors for bad settings.

use photonlab::config::RenderConfig;
use photonlab::film::Film;
use photonlab::pipeline::render_scene_observed;
use photonlab::scene::builtin::builtin;
use std::process::Command;

/// The image after every pass.
fn passes(scene: &str, cfg: &RenderConfig) -> Vec<Film> {
    let mut out = Vec::new();
    let mut on_pass = |p: u32, _: f64, f: &Film| {
        assert_eq!(p as usize, out.len() + 1);
        out.push(f.clone());
    };
    let o = render_scene_observed(builtin(scene).unwrap(), cfg, true, &[], &mut on_pass).unwrap();
    assert_eq!(out.last().unwrap().pixels, o.film.pixels);
    out
}

fn bits(f: &Film) -> Vec<u32> {
    f.pixels.iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect()
}

#[test]
fn every_pass_is_bit_identical_for_any_thread_count() {
    for (integrator, scene) in [("sppm", "cornell-glass"), ("ppm", "cornell-glass")] {
        let cfg = RenderConfig { integrator: integrator.into(), resolution: Some([24, 24]), spp: 1, seed: 5, ..Default::default() }
            .with("passes", 3)
            .with("photons_per_pass", 6000);
        // `ppm` renders with the photon integrator's gather; `sppm` has none.
        let cfg = if integrator == "ppm" { cfg.with("gather", "direct") } else { cfg };
        let one = passes(scene, &RenderConfig { threads: 1, ..cfg.clone() });
        let two = passes(scene, &RenderConfig { threads: 2, ..cfg.clone() });
        assert_eq!(one.len(), 3);
        for (p, (a, b)) in one.iter().zip(&two).enumerate() {
            assert_eq!(bits(a), bits(b), "{integrator}: pass {} differs between 1 and 2 threads", p + 1);
        }
        // Passes differ from each other (each adds new samples) and are not black.
        assert_ne!(bits(&one[0]), bits(&one[2]), "{integrator}");
        assert!(one[2].mean().max_element() > 0.01, "{integrator}");
        // Another seed gives another image.
        let other = passes(scene, &RenderConfig { seed: 6, threads: 2, ..cfg }.with("passes", 1));
        assert_ne!(bits(&other[0]), bits(&one[0]), "{integrator}");
    }
}

/// Block means (8-px blocks) of sppm and ppm agree with the path tracer's on the
/// Cornell box with mirror and glass spheres.
#[test]
fn block_means_agree_with_the_path_tracer() {
    let res = Some([32, 32]);
    let path = passes_or_render("path", res);
    for integrator in ["sppm", "ppm"] {
        let img = passes_or_render(integrator, res);
        let (mut worst, mut total) = (0.0f32, [0.0f32; 2]);
        for by in 0..4 {
            for bx in 0..4 {
                let mean = |f: &Film| {
                    let mut s = 0.0;
                    for y in by * 8..by * 8 + 8 {
                        for x in bx * 8..bx * 8 + 8 {
                            s += f.get(x, y).element_sum() / 3.0;
                        }
                    }
                    s / 64.0
                };
                let (a, b) = (mean(&img), mean(&path));
                total[0] += a;
                total[1] += b;
                worst = worst.max((a - b).abs() / (b + 0.02));
            }
        }
        assert!(worst < 0.12, "{integrator}: a block mean differs by {worst}");
        assert!((total[0] / total[1] - 1.0).abs() < 0.03, "{integrator}: image mean ratio {}", total[0] / total[1]);
    }
}

fn passes_or_render(integrator: &str, resolution: Option<[u32; 2]>) -> Film {
    let cfg = match integrator {
        "path" => RenderConfig { integrator: "path".into(), spp: 512, resolution, ..Default::default() },
        "sppm" => RenderConfig { integrator: integrator.into(), resolution, ..Default::default() }
            .with("passes", 48)
            .with("photons_per_pass", 40_000),
        // `ppm` with its defaults: every photon within the pass radius, gather `direct`.
        _ => RenderConfig { integrator: integrator.into(), resolution, spp: 4, ..Default::default() }
            .with("passes", 12)
            .with("photons_per_pass", 40_000),
    };
    let mut cb = |_: u32, _: f64, _: &Film| {};
    render_scene_observed(builtin("cornell-glass").unwrap(), &cfg, true, &[], &mut cb).unwrap().film
}

#[test]
fn time_limit_stops_after_the_pass_that_crosses_it() {
    let cfg = RenderConfig { integrator: "sppm".into(), resolution: Some([8, 8]), ..Default::default() }
        .with("time_limit", 1e-6)
        .with("photons_per_pass", 100);
    assert_eq!(passes("cornell", &cfg).len(), 1);
}

/// The runner records the error after the chosen passes as a curve.
#[test]
fn runner_records_the_error_after_chosen_passes() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let m = dir.join("m.toml");
    std::fs::write(
        &m,
        "scene = \"cornell\"\nresolution = [8, 8]\n[reference]\nspp = 8\n[base]\nintegrator = \"sppm\"\nphotons_per_pass = 2000\n\
         [[configs]]\nname = \"sppm\"\npasses = 4\nrecord_passes = [1, 2, 4]\n\
         [[configs]]\nname = \"path 2\"\ngroup = \"path\"\nintegrator = \"path\"\nphotons_per_pass = 0\n",
    )
    .unwrap();
    let out =
        Command::new(env!("CARGO_BIN_EXE_photonlab")).args(["run", "--quiet", "--out"]).arg(dir.join("out")).arg(&m).output().unwrap();
    // photons_per_pass does not apply to `path`: a clear error naming the key.
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("photons_per_pass") && !err.contains("panicked"), "{err}");
    let text = std::fs::read_to_string(&m).unwrap().replace("photons_per_pass = 0\n", "");
    let text = text.replace("[base]\nintegrator = \"sppm\"\nphotons_per_pass = 2000\n", "[base]\n");
    let text = text.replace("name = \"sppm\"\n", "name = \"sppm\"\nintegrator = \"sppm\"\nphotons_per_pass = 2000\n");
    std::fs::write(&m, text).unwrap();
    let out =
        Command::new(env!("CARGO_BIN_EXE_photonlab")).args(["run", "--quiet", "--out"]).arg(dir.join("out")).arg(&m).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("out/cells.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for p in [1, 2, 4] {
        assert!(header.contains(&format!("relmse_at_pass_{p}").as_str()), "{header:?}");
        assert!(header.contains(&format!("time_at_pass_{p}").as_str()));
    }
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    let (e4, last) = (row[col("relmse_at_pass_4")].parse::<f64>().unwrap(), row[col("relmse")].parse::<f64>().unwrap());
    assert!((e4 - last).abs() <= 1e-9 * last.max(1e-12), "pass 4 is the final image: {e4} vs {last}");
    assert!(row[col("time_at_pass_1")].parse::<f64>().unwrap() <= row[col("time_at_pass_4")].parse::<f64>().unwrap());
    assert!(dir.join("out/plots/error_vs_time.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// Bad progressive settings: one `error:` line naming the problem, never a panic.
#[test]
fn bad_settings_are_clear_errors() {
    for (args, needle) in [
        (&["--integrator", "sppm", "--alpha", "1.5"][..], "alpha"),
        (&["--integrator", "sppm", "--passes", "0"][..], "passes"),
        (&["--integrator", "ppm", "--time-limit=-3"][..], "time_limit"),
        (&["--integrator", "sppm", "--sppm-direct", "both"][..], "sppm_direct"),
        (&["--integrator", "sppm", "--sampler", "hammersley"][..], "passes"),
        (&["--integrator", "path", "--passes", "4"][..], "progressive"),
        (&["--integrator", "ppm", "--sppm-radius", "2"][..], "sppm_radius"),
        (&["--integrator", "ppm", "--gather", "nope"][..], "nope"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_photonlab"))
            .args(["render", "--resolution", "4x4", "--quiet", "-o"])
            .arg(tempfile::tempdir().unwrap().path().join("bad.exr"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.starts_with("error: ") && err.contains(needle) && !err.contains("panicked"), "{args:?}: {err}");
    }
}

/// A run stopped after a checkpoint and resumed gives the uninterrupted run's image,
/// bit for bit; a checkpoint of another configuration is refused.
#[test]
fn resume_from_a_checkpoint_is_bit_identical() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let render = |integrator: &str, out: &str, extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_photonlab"))
            .args(["render", "--builtin", "cornell-glass", "--resolution", "12x12", "--quiet", "--photons-per-pass", "3000"])
            .args(["--integrator", integrator, "--spp", "1"])
            // `ppm` renders with the photon integrator's gather; `sppm` has none.
            .args(if integrator == "ppm" { &["--gather", "direct"][..] } else { &[] })
            .arg("-o")
            .arg(dir.join(out))
            .args(extra)
            .output()
            .unwrap();
        (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    for integrator in ["sppm", "ppm"] {
        let (full, part) = (format!("{integrator}-full.exr"), format!("{integrator}-part.exr"));
        assert!(render(integrator, &full, &["--passes", "4"]).0);
        // "Killed" after pass 2: the checkpoint holds 2 passes.
        assert!(render(integrator, &part, &["--passes", "2", "--checkpoint-every", "2"]).0);
        let (ok, err) = render(integrator, &part, &["--passes", "4", "--resume", "--threads", "1"]);
        assert!(ok, "{err}");
        let a = Film::read_exr(&dir.join(&full)).unwrap();
        let b = Film::read_exr(&dir.join(&part)).unwrap();
        assert_eq!(bits(&a), bits(&b), "{integrator}: resumed image differs");
        // Another alpha: refused with a clear message.
        let (ok, err) = render(integrator, &part, &["--passes", "4", "--resume", "--alpha", "0.5"]);
        assert!(!ok && err.contains("another configuration") && !err.contains("panicked"), "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

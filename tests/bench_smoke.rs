//! CI check that `bench accel` runs end to end on a tiny OBJ and prints the harness's
//! JSON fields (benchmarks themselves are not tests: nothing here is timed).

use std::process::Command;

/// A closed box (six quads, one with `v/vt` tokens, one with negative indices) around
/// the origin plus a triangle inside it, so all three ray sets occur from inside.
const BOX_OBJ: &str = "\
v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 2/1 6/1 7/1 3/1\nf -8 -4 -1 -5\nf 4 8 7 3\n\
v -0.5 -0.5 0.3\nv 0.5 -0.5 0.3\nv 0 0.5 0.3\nf 9 10 11\n";

fn run_bench(args: &[&str]) -> (String, String, bool) {
    let out = Command::new(env!("CARGO_BIN_EXE_photonlab")).args(args).output().expect("running photonlab");
    (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned(), out.status.success())
}

/// A fresh temporary folder named after `tag` holding `box.obj`; (folder, OBJ path).
fn box_obj(tag: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("photonlab-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("box.obj");
    std::fs::write(&obj, BOX_OBJ).unwrap();
    (dir, obj)
}

#[test]
fn bench_accel_prints_harness_fields() {
    let (dir, obj) = box_obj("bench-smoke");
    let accels = photonlab::registry::ACCELS.join(",");
    let (stdout, stderr, ok) = run_bench(&[
        "bench",
        "accel",
        "--obj",
        obj.to_str().unwrap(),
        "--inside",
        "--rays",
        "500",
        "--threads",
        "2",
        "--accel",
        &accels,
        "--json",
    ]);
    assert!(ok, "bench accel failed: {stderr}");
    let rows: Vec<serde_json::Value> = stdout.lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    // Every accelerator × (camera, diffuse, shadow).
    assert_eq!(rows.len(), 3 * photonlab::registry::ACCELS.len(), "{stdout}");
    for r in &rows {
        for key in ["engine", "scene", "rays", "api"] {
            assert!(r[key].is_string(), "{key} in {r}");
        }
        for key in ["triangles", "threads", "n_rays"] {
            assert!(r[key].is_u64(), "{key} in {r}");
        }
        for key in ["build_s", "mrays_per_s", "hit_fraction", "node_tests_per_ray", "tri_tests_per_ray"] {
            assert!(r[key].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0), "{key} in {r}");
        }
        assert!(r["engine"].as_str().unwrap().starts_with("photonlab-"));
        assert_eq!(r["scene"], "box-inside");
        assert_eq!(r["triangles"], 13);
        assert_eq!(r["threads"], 2);
        assert!(r["n_rays"].as_u64().unwrap() <= 500);
        let (rays, api) = (r["rays"].as_str().unwrap(), r["api"].as_str().unwrap());
        assert_eq!(api, if rays == "shadow" { "occluded1" } else { "intersect1" });
        // The box is closed, so every camera and diffuse ray hits.
        if rays != "shadow" {
            assert_eq!(r["hit_fraction"], 1.0, "{r}");
        }
    }
    // All accelerators see the same rays and agree on what they hit.
    for set in ["camera", "diffuse", "shadow"] {
        let h: Vec<f64> = rows.iter().filter(|r| r["rays"] == set).map(|r| r["hit_fraction"].as_f64().unwrap()).collect();
        assert!(h.windows(2).all(|w| w[0] == w[1]), "{set}: {h:?}");
    }
    // The table form and a clear error on a missing file.
    let (table, _, ok) = run_bench(&["bench", "accel", "--obj", obj.to_str().unwrap(), "--rays", "100"]);
    assert!(ok && table.contains("Mrays/s") && table.contains("photonlab-bvh"), "{table}");
    let (_, err, ok) = run_bench(&["bench", "accel", "--obj", dir.join("missing.obj").to_str().unwrap()]);
    assert!(!ok && err.contains("missing.obj"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Output into a closed pipe (`photonlab … | head`) is dropped, not a panic: the
/// command finishes and exits 0 (`println!` would abort it with exit code 101).
#[test]
fn closed_stdout_is_not_a_panic() {
    use std::process::Stdio;
    let (dir, obj) = box_obj("bench-pipe");
    let mut child = Command::new(env!("CARGO_BIN_EXE_photonlab"))
        .args(["bench", "accel", "--obj", obj.to_str().unwrap(), "--rays", "100", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("running photonlab");
    // Close the read end before the first line is written.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("panicked"), "{:?}: {err}", out.status);
    std::fs::remove_dir_all(&dir).ok();
}

/// `PHOTONLAB_SIMD` lowers the wide BVHs' traversal level (reported as `simd`), every
/// level finds the same hits, and an unknown value is reported, not fatal.
#[test]
fn simd_level_override() {
    let (dir, obj) = box_obj("bench-simd");
    let run = |level: Option<&str>| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_photonlab"));
        cmd.args(["bench", "accel", "--obj", obj.to_str().unwrap(), "--inside", "--rays", "300", "--accel", "bvh8", "--json"]);
        if let Some(l) = level {
            cmd.env("PHOTONLAB_SIMD", l);
        }
        let out = cmd.output().expect("running photonlab");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let rows: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        (rows, String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (best, _) = run(None);
    let (portable, _) = run(Some("portable"));
    let (capped, _) = run(Some("avx2"));
    let (bogus, err) = run(Some("sse9"));
    assert!(portable.iter().all(|r| r["simd"] == "portable"), "{portable:?}");
    assert!(capped.iter().all(|r| r["simd"] == "portable" || r["simd"] == "avx2"), "{capped:?}");
    assert!(err.contains("PHOTONLAB_SIMD=sse9") && bogus.iter().zip(&best).all(|(a, b)| a["simd"] == b["simd"]), "{err}");
    for rows in [&portable, &capped] {
        for (a, b) in rows.iter().zip(&best) {
            assert_eq!((&a["rays"], &a["hit_fraction"]), (&b["rays"], &b["hit_fraction"]));
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

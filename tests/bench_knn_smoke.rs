//! CI smoke test of `photonlab bench knn` on tiny inputs: it runs, answers every
//! query kind on both distributions, and finds the same neighbours as kiddo.
//! (Benchmarks are not tests: no time is checked.)

use std::process::Command;

fn bench_knn(extra: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_photonlab"))
        .args(["bench", "knn", "--n", "2000", "--queries", "300", "--threads", "1"])
        .args(extra)
        .output()
        .expect("run photonlab");
    (o.status.success(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[cfg(feature = "kiddo")]
#[test]
fn bench_knn_table_and_json() {
    let (ok, out, err) = bench_knn(&[]);
    assert!(ok, "bench knn failed: {err}\n{out}");
    for dist in ["cube", "faces"] {
        for op in ["build", "k=50", "k=100", "k=200", "k=100 r"] {
            let row = format!("| {dist} | {op} | 1 |");
            assert!(out.lines().any(|l| l.starts_with(&row)), "no row `{row}` in\n{out}");
        }
    }
    let (ok, out, err) = bench_knn(&["--json"]);
    assert!(ok, "bench knn --json failed: {err}");
    let rows: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    assert_eq!(rows.len(), 2 * 5, "{out}");
    for r in &rows {
        assert_eq!(r["n"], 2000);
        assert!(r["own_s"].as_f64().unwrap() > 0.0 && r["kiddo_s"].as_f64().unwrap() > 0.0);
        let bytes = r["own_bytes_per_point"].as_f64().unwrap();
        assert!(bytes > 0.0 && bytes < 64.0, "{r}");
        if r["op"] != "build" {
            // Every query kind was checked against kiddo and agreed.
            assert_eq!(r["mismatches"], 0, "{r}");
        }
    }
}

#[cfg(not(feature = "kiddo"))]
#[test]
fn bench_knn_says_how_to_enable_kiddo() {
    let (ok, _, err) = bench_knn(&[]);
    assert!(!ok);
    assert!(err.contains("--features kiddo"), "{err}");
}

#[test]
fn bench_knn_rejects_zero_points() {
    let o = Command::new(env!("CARGO_BIN_EXE_photonlab")).args(["bench", "knn", "--n", "0"]).output().expect("run photonlab");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).starts_with("error: "));
}

/// `bench scaling` on a tiny render: both thread counts run, every phase is timed,
/// and the command's own check that the two images are bit-identical passes.
#[test]
fn bench_scaling_tiny_render() {
    let o = Command::new(env!("CARGO_BIN_EXE_photonlab"))
        .args(["bench", "scaling", "--photons", "5000", "--size", "16", "--spp", "1", "--reps", "1", "--json"])
        .output()
        .expect("run photonlab");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    let phases: Vec<&str> = rows.iter().map(|r| r["phase"].as_str().unwrap()).collect();
    assert_eq!(phases, ["photon tracing", "kd-tree build", "cache prefill", "rendering"]);
    assert!(rows.iter().all(|r| r["t1_s"].as_f64().unwrap() > 0.0 && r["t2_s"].as_f64().unwrap() > 0.0), "{out}");
}

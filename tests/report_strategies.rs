//! Per-strategy images in the experiment report: a manifest with `strategies = true`
//! makes its `bdpt` and `vcm` cells write each technique's weighted and unweighted
//! image (and vcm's merging part) beside the cell, lists them in the cell's record,
//! and `index.html` shows them for the selected cell — checked in headless Chromium
//! (skipped without it, as `tests/report_browser.rs`, except under `CI=true`).
//! Cells of integrators without strategies (`path`) are unaffected, and a manifest
//! asking for strategies that no configuration has is an error naming the line.

use photonlab::experiment::{RunArgs, run};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const MANIFEST: &str = r#"
description = "Strategy images: path, bdpt and vcm on a small Cornell box."
scene = "cornell"
resolution = [24, 24]
strategies = true
[reference]
integrator = "path"
spp = 16
[base]
max_depth = 3
[[configs]]
name = "path"
integrator = "path"
spp = 4
[[configs]]
name = "bdpt"
integrator = "bdpt"
spp = 4
[[configs]]
name = "vcm"
integrator = "vcm"
passes = 4
"#;

fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("PHOTONLAB_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"].iter().map(PathBuf::from).find(|p| p.is_file())
}

/// Headless Chromium's DOM of `url` after the page's scripts ran (killed after 120 s).
fn dump_dom(bin: &Path, profile: &Path, url: &str) -> String {
    let mut child = Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=30000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(url)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", bin.display()));
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("chromium did not finish within 120 s: {url}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    String::from_utf8_lossy(&child.wait_with_output().unwrap().stdout).into_owned()
}

fn record(out: &Path, stem: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("cells").join(format!("{stem}.json"))).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn names(rec: &serde_json::Value) -> Vec<String> {
    rec["strategies"]
        .as_array()
        .unwrap_or_else(|| panic!("no strategy list: {rec}"))
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn bidirectional_cells_show_their_strategy_images() {
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-strategies");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let manifest = root.join("strategies.toml");
    std::fs::write(&manifest, MANIFEST).unwrap();
    let out = root.join("out");
    run(&RunArgs::quiet(manifest, out.clone())).unwrap();

    // Records and files: path has none, bdpt every (s, t) of paths up to 4 edges
    // that contributed (weighted and unweighted), vcm those and its merging part.
    assert!(record(&out, "path_r0")["strategies"].is_null());
    let bdpt = names(&record(&out, "bdpt_r0"));
    let vcm = names(&record(&out, "vcm_r0"));
    for want in ["s0-t2", "s1-t2", "s1-t3", "s2-t2", "s2-t1", "s2-t1-unweighted", "s3-t1"] {
        assert!(bdpt.iter().any(|n| n == want), "bdpt lacks {want}: {bdpt:?}");
    }
    assert!(!bdpt.iter().any(|n| n == "merge"), "{bdpt:?}");
    assert!(vcm.iter().any(|n| n == "merge") && vcm.iter().any(|n| n == "s1-t2-unweighted"), "{vcm:?}");
    for (stem, list) in [("bdpt_r0", &bdpt), ("vcm_r0", &vcm)] {
        for n in list.iter() {
            for ext in ["exr", "png"] {
                let f = out.join("cells").join(format!("{stem}.strategies-{n}.{ext}"));
                assert!(f.is_file(), "{} missing", f.display());
            }
        }
    }
    // The weighted images of one integrator add up to its image (max_depth 3 keeps
    // every path within the shown lengths); the cell's image is the timed render,
    // the strategies an identical second one.
    let img = |p: PathBuf| photonlab::film::Film::read_exr(&p).unwrap();
    let full = img(out.join("cells/bdpt_r0.exr"));
    let mut sum = vec![glam::DVec3::ZERO; full.pixels.len()];
    for n in bdpt.iter().filter(|n| !n.ends_with("-unweighted")) {
        for (s, p) in sum.iter_mut().zip(&img(out.join(format!("cells/bdpt_r0.strategies-{n}.exr"))).pixels) {
            *s += p.as_dvec3();
        }
    }
    let (a, b): (f64, f64) = (sum.iter().map(|p| p.element_sum()).sum(), full.pixels.iter().map(|p| p.as_dvec3().element_sum()).sum());
    assert!((a / b - 1.0).abs() < 1e-4, "weighted strategies sum to {a}, the image to {b}");

    // A second run finds every cell finished (strategy images included): no record is rewritten.
    let mtime = |stem: &str| std::fs::metadata(out.join(format!("cells/{stem}.json"))).unwrap().modified().unwrap();
    let before = ["path_r0", "bdpt_r0", "vcm_r0"].map(mtime);
    run(&RunArgs::quiet(root.join("strategies.toml"), out.clone())).unwrap();
    assert_eq!(["path_r0", "bdpt_r0", "vcm_r0"].map(mtime), before, "a finished cell ran again");

    // The page lists them for the bidirectional cells.
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(html.contains("cells/vcm_r0.strategies-merge.png"), "index.html does not list vcm's merging image");
    assert!(html.contains("cells/bdpt_r0.strategies-s1-t2-unweighted.png"));

    let Some(bin) = chromium() else {
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("CI=true but chromium is missing: .ci/run must install it (apt-get install -y chromium)");
        }
        eprintln!("\n!!!!! SKIPPED: no chromium — the strategy images are NOT checked in a browser !!!!!\n");
        return;
    };
    let url = format!("file://{}#selftest&cell=vcm_r0&mode=cell", out.join("index.html").canonicalize().unwrap().display());
    let dom = dump_dom(&bin, &root.join("profile"), &url);
    let start = dom.find("id=\"selftest-result\"").unwrap_or_else(|| panic!("no self-test element in the DOM:\n{dom}"));
    let json_start = start + dom[start..].find('>').unwrap() + 1;
    let json_end = json_start + dom[json_start..].find("</pre>").unwrap();
    let text = dom[json_start..json_end].replace("&quot;", "\"").replace("&amp;", "&");
    let res: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("self-test did not finish ({e}): `{text}`"));
    assert_eq!(res["done"], true, "{res}");
    assert_eq!(res["selected"], "vcm_r0", "{res}");
    assert_eq!(res["failed"], serde_json::json!([]), "{res}");
    assert_eq!(res["strategies_failed"], serde_json::json!([]), "{res}");
    let mut shown: Vec<String> = res["strategies_shown"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    shown.sort();
    let mut want = vcm.clone();
    want.sort();
    assert_eq!(shown, want, "the page shows other images than the cell wrote: {res}");
    assert!(dom.contains("data-strategy=\"merge\"") && dom.contains("data-strategy=\"s1-t2\""), "no strategy rows in the DOM");
    assert!(dom.contains("data-selftest=\"pass\""), "{res}");
}

#[test]
fn strategies_without_a_bidirectional_configuration_is_an_error() {
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-strategies-error");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let manifest = root.join("bad.toml");
    let text = MANIFEST
        .replace("integrator = \"bdpt\"", "integrator = \"path\"")
        .replace("integrator = \"vcm\"\npasses = 4", "integrator = \"path\"\nspp = 2");
    std::fs::write(&manifest, &text).unwrap();
    let err = run(&RunArgs::quiet(manifest, root.join("out"))).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("bad.toml:5") && msg.contains("strategies"), "{msg}");
}

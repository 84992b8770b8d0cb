//! The experiment report in a real browser: runs a tiny experiment, opens its
//! `index.html` in headless Chromium, lets the viewer's self-test (`#selftest`) switch
//! through every cell in the image, |error| and signed-error modes, and reads the
//! result from the DOM; then saves a screenshot under `target/tmp/report-browser/`.
//!
//! Without Chromium the test is skipped with a loud message, except under `CI=true`,
//! where it fails (`.ci/run` installs Debian's `chromium`). `PHOTONLAB_CHROMIUM`
//! overrides the browser binary.

use photonlab::experiment::{RunArgs, run};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("PHOTONLAB_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"].iter().map(PathBuf::from).find(|p| p.is_file())
}

/// Runs headless Chromium with `args` (after the common flags), killing it after
/// `limit`; returns stdout.
fn run_chromium(bin: &Path, profile: &Path, args: &[String], limit: Duration) -> String {
    let mut cmd = Command::new(bin);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
    ])
    .arg(format!("--user-data-dir={}", profile.display()))
    .args(args)
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("cannot start {}: {e}", bin.display()));
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("chromium did not finish within {limit:?}: {args:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    String::from_utf8_lossy(&out.stdout).into_owned()
}

const MANIFEST: &str = r#"
description = "Browser test: two samplers x two sample counts, two repeats."
scene = "cornell"
resolution = [40, 32]
component = "indirect"
[reference]
integrator = "path"
spp = 16
[base]
integrator = "path"
max_depth = 4
[sweep]
spp = [1, 4]
sampler = ["random", "halton"]
repeats = 2
"#;

#[test]
fn report_loads_and_switches_cells_in_chromium() {
    let Some(bin) = chromium() else {
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("CI=true but chromium is missing: .ci/run must install it (apt-get install -y chromium)");
        }
        eprintln!(
            "\n!!!!! SKIPPED: no chromium at /usr/bin/chromium (apt-get install chromium) — the report is NOT tested in a browser !!!!!\n"
        );
        return;
    };
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-browser");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let manifest = root.join("browser.toml");
    std::fs::write(&manifest, MANIFEST).unwrap();
    let out = root.join("browser");
    run(&RunArgs::quiet(manifest, out.clone())).unwrap();
    let index = out.join("index.html");
    assert!(index.is_file());
    let url = format!("file://{}", index.canonicalize().unwrap().display());
    let cells: Vec<String> = std::fs::read_dir(out.join("cells"))
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().to_str()?.strip_suffix(".json").map(str::to_string))
        .collect();
    assert_eq!(cells.len(), 8);

    // Self-test: every <img> of the page loads, every cell's radiance, |error| and
    // signed error draw in the viewer; it ends on the cell named in the hash.
    let first = "spp-4_sampler-halton_r1";
    let dom = run_chromium(
        &bin,
        &root.join("profile-dom"),
        &["--virtual-time-budget=30000".into(), "--dump-dom".into(), format!("{url}#selftest&cell={first}&mode=signed")],
        Duration::from_secs(120),
    );
    let start = dom.find("id=\"selftest-result\"").unwrap_or_else(|| panic!("no self-test element in the DOM:\n{dom}"));
    let json_start = start + dom[start..].find('>').unwrap() + 1;
    let json_end = json_start + dom[json_start..].find("</pre>").unwrap();
    let text = dom[json_start..json_end].replace("&quot;", "\"").replace("&amp;", "&");
    let res: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("self-test did not finish ({e}): `{text}`"));
    assert_eq!(res["done"], true, "{res}");
    assert_eq!(res["failed"], serde_json::json!([]), "{res}");
    assert_eq!(res["page_images_failed"], serde_json::json!([]), "{res}");
    // Plots (error vs time, vs spp, bias/variance, phases), the reference and three
    // images per configuration in the summary.
    assert!(res["page_images"].as_u64().unwrap() >= 4 + 1 + 3 * 4, "{res}");
    let mut checked: Vec<String> = res["cells_checked"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    checked.sort();
    let mut want = cells.clone();
    want.sort();
    assert_eq!(checked, want, "{res}");
    // The measured component's images (cell and reference) draw too.
    let mut comp: Vec<String> = res["comp_checked"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    comp.sort();
    assert_eq!(comp, want, "{res}");
    assert_eq!(res["selected"], first, "{res}");
    assert!(dom.contains("data-selftest=\"pass\""), "{res}");

    // Screenshot of the slide view, saved with the test's output.
    let shot = root.join("screenshot.png");
    run_chromium(
        &bin,
        &root.join("profile-shot"),
        &[
            "--virtual-time-budget=10000".into(),
            "--window-size=1400,1600".into(),
            format!("--screenshot={}", shot.display()),
            format!("{url}#cell={first}&mode=slide"),
        ],
        Duration::from_secs(120),
    );
    let img = image::open(&shot).unwrap_or_else(|e| panic!("{}: {e}", shot.display())).to_rgb8();
    assert_eq!((img.width(), img.height()), (1400, 1600));
    let distinct: std::collections::BTreeSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 50, "the screenshot looks empty ({} colours)", distinct.len());
    eprintln!("screenshot: {}", shot.display());
}

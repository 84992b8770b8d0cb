//! The bias atlas (`experiments/bias-atlas.toml`) at CI size: the same configurations
//! on every built-in scene (the shipped scenes need models from outside the
//! repository), at 16² with small photon counts and few passes, plus a planted biased
//! configuration — `path` without indirect light — that the table must expose as a
//! dark image many standard errors off.

use std::path::Path;
use std::process::Command;
use toml::Value;

/// The atlas manifest cut to CI size: built-in scenes, 16², a 64-spp reference,
/// small photon counts and four passes; the planted configuration appended.
fn ci_manifest(dir: &Path) -> (std::path::PathBuf, usize, Vec<String>) {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/bias-atlas.toml")).unwrap();
    let mut m: toml::Table = toml::from_str(&text).unwrap();
    let scenes: Vec<Value> = m["scene"].as_array().unwrap().iter().filter(|s| !s.as_str().unwrap().ends_with(".toml")).cloned().collect();
    let names: Vec<String> = scenes.iter().map(|s| s.as_str().unwrap().to_string()).collect();
    m.insert("scene".into(), Value::Array(scenes));
    m.insert("resolution".into(), Value::Array(vec![16.into(), 16.into()]));
    m["reference"].as_table_mut().unwrap().insert("spp".into(), 64.into());
    m["base"].as_table_mut().unwrap().insert("spp".into(), 2.into());
    let configs = m["configs"].as_array_mut().unwrap();
    for c in configs.iter_mut() {
        let t = c.as_table_mut().unwrap();
        let set = |t: &mut toml::Table, k: &str, v: Value| {
            t.insert(k.into(), v);
        };
        match t.get("integrator").and_then(|v| v.as_str()) {
            Some("sppm") => {
                set(t, "passes", 4.into());
            }
            Some("ppm") => {
                set(t, "passes", 4.into());
                set(t, "photons", 4000.into());
                set(t, "caustic_photons", 1000.into());
            }
            _ => {
                set(t, "photons", 4000.into());
                set(t, "caustic_photons", 1000.into());
                match t.get("gather").and_then(|v| v.as_str()) {
                    Some("direct") => {}
                    Some("irradiance_cache") => {
                        set(t, "gather_samples", 8.into());
                        set(t, "ic_samples", 16.into());
                    }
                    _ => {
                        set(t, "gather_samples", 8.into());
                        set(t, "gather_per", "sample".into());
                    }
                }
            }
        }
    }
    let planted: toml::Table =
        toml::from_str("name = \"planted: path max_depth=1\"\nintegrator = \"path\"\nmax_depth = 1\nspp = 16\n").unwrap();
    configs.push(Value::Table(planted));
    let n = configs.len();
    let path = dir.join("bias-atlas-ci.toml");
    std::fs::write(&path, toml::to_string(&m).unwrap()).unwrap();
    (path, n, names)
}

#[test]
fn the_atlas_runs_and_exposes_a_planted_bias() {
    let tmp = tempfile::tempdir().unwrap();
    let (manifest, configs, scenes) = ci_manifest(tmp.path());
    assert!(scenes.len() >= 8, "built-ins in the atlas: {scenes:?}");
    let out = tmp.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_photonlab")).arg("run").arg(&manifest).arg("--out").arg(&out).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = std::fs::read_to_string(out.join("bias.md")).unwrap();
    assert!(std::fs::read_to_string(out.join("summary.md")).unwrap().contains("## Bias against the reference"));
    // One row per scene and configuration: scene | configuration | ratio | block | at | z.
    let rows: Vec<Vec<&str>> = table
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| scene |"))
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), scenes.len() * configs, "{table}");
    for s in &scenes {
        assert_eq!(rows.iter().filter(|r| r[0] == s).count(), configs, "{s}: {table}");
    }
    let num = |v: &str| v.trim_end_matches(" %").replace('−', "-").parse::<f64>().unwrap_or(f64::NAN);
    for r in &rows {
        assert_eq!(r.len(), 6, "{r:?}");
        // Judged blocks come with a mean ratio (`leaky-box`'s reference is black inside).
        if r[5] != "–" {
            assert!(num(r[2]) > 0.0, "no mean ratio: {r:?}");
        }
    }
    // The planted configuration: no indirect light, so the Cornell box is much too dark
    // and its worst block is far beyond the noise.
    let planted = rows.iter().find(|r| r[0] == "cornell" && r[1].starts_with("planted")).unwrap();
    assert!(num(planted[2]) < 0.85, "{planted:?}");
    assert!(num(planted[3]) < -15.0, "{planted:?}");
    assert!(num(planted[5]) < -4.0 || planted[5] == "−∞", "{planted:?}");
    // The photon default on the plain box is not flagged like that: at this size its
    // worst block is noise (measured +18 % at +0.8 standard errors).
    let default = rows.iter().find(|r| r[0] == "cornell" && r[1].starts_with("photon (defaults")).unwrap();
    assert!(num(default[5]).abs() < 4.0, "{default:?}");
}

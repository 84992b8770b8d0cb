//! The real binary on bad input: a non-zero exit with a single `error: …` line on
//! stderr that names the file (and the line where the parser knows it), never a panic.

use std::path::{Path, PathBuf};
use std::process::Command;

/// A fresh, empty temporary directory for one test, removed when dropped.
/// A temporary folder (the `tempfile` crate), removed when dropped.
struct Tmp(tempfile::TempDir);

impl std::ops::Deref for Tmp {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

fn tmp(tag: &str) -> Tmp {
    Tmp(tempfile::Builder::new().prefix(&format!("photonlab-bad-input-{tag}-")).tempdir().unwrap())
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `photonlab render --scene SCENE --spp 1 --resolution 4x4 -o DIR/out --quiet EXTRA…`.
fn render(scene: &Path, extra: &[&str]) -> (bool, String, String) {
    let out = scene.parent().unwrap().join("out.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_photonlab"))
        .args(["render", "--scene"])
        .arg(scene)
        .args(["--spp", "1", "--resolution", "4x4", "-o"])
        .arg(&out)
        .arg("--quiet")
        .args(extra)
        .output()
        .expect("run photonlab");
    (o.status.success(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Asserts failure with exactly one `error:` line containing every needle.
fn assert_error(scene: &Path, extra: &[&str], needles: &[&str]) {
    let (ok, _, err) = render(scene, extra);
    assert!(!ok, "expected failure for {}; stderr: {err}", scene.display());
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "stderr must be one line: {err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    for n in needles {
        assert!(lines[0].contains(n), "`{n}` missing from: {err}");
    }
}

const CAMERA: &str = "[camera]\neye = [0.5, 0.5, 3]\nlook_at = [0.5, 0.5, 0]\nfov_y_deg = 40\nresolution = [4, 4]\n";
const LIGHT: &str = "\n[[light]]\ntype = \"point\"\nposition = [0.5, 0.5, 2]\nintensity = [1, 1, 1]\n";
/// A triangle facing +z (towards the camera).
const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// Writes `<tag>.toml` with the camera, one mesh `obj` and a point light.
fn scene_with_obj(d: &Path, tag: &str, obj_text: &str) -> PathBuf {
    write(d, &format!("{tag}.obj"), obj_text);
    write(d, &format!("{tag}.toml"), &format!("{CAMERA}\n[[mesh]]\nobj = \"{tag}.obj\"\n{LIGHT}"))
}

#[test]
fn good_scene_renders() {
    let d = tmp("good");
    let p = scene_with_obj(&d, "good", TRI);
    let (ok, out, err) = render(&p, &[]);
    assert!(ok, "{err}");
    assert!(err.is_empty(), "{err}");
    assert!(out.contains("1 triangles"), "{out}");
    assert!(d.join("out.exr").is_file() && d.join("out.png").is_file());
}

#[test]
fn missing_files() {
    let d = tmp("missing");
    let p = d.join("nowhere.toml");
    assert_error(&p, &[], &["nowhere.toml"]);
    let p = write(&d, "noobj.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"ghost.obj\"\n{LIGHT}"));
    assert_error(&p, &[], &["noobj.toml:7", "ghost.obj"]);
    let p = scene_with_obj(&d, "nomtl", &format!("# materials:\nmtllib ghost.mtl\n{TRI}"));
    assert_error(&p, &[], &["nomtl.obj:2", "ghost.mtl"]);
}

#[test]
fn malformed_toml_unknown_key_and_type() {
    let d = tmp("toml");
    let p = write(&d, "syntax.toml", "[camera]\neye = [0, 1, 3\nlook_at = [0, 1, 0]\n");
    assert_error(&p, &[], &["syntax.toml:3:1", "comma"]);
    write(&d, "t.obj", TRI);
    let p = write(&d, "key.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\nrotate_z_deg = 1\n{LIGHT}"));
    assert_error(&p, &[], &["key.toml:9:", "rotate_z_deg"]);
    let p = write(&d, "mat.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\nmaterial = {{ type = \"velvet\" }}\n{LIGHT}"));
    assert_error(&p, &[], &["mat.toml:9:", "velvet"]);
    let p = write(&d, "light.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n\n[[light]]\ntype = \"laser\"\n"));
    assert_error(&p, &[], &["light.toml:11:", "laser"]);
}

#[test]
fn unknown_strategy_name() {
    let d = tmp("sampler");
    let p = scene_with_obj(&d, "s", TRI);
    assert_error(&p, &["--sampler", "latin"], &["latin", "halton"]);
}

#[test]
fn bad_obj_content() {
    let d = tmp("obj");
    let p = scene_with_obj(&d, "nan", "v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n");
    assert_error(&p, &[], &["nan.obj:2", "not finite"]);
    let p = scene_with_obj(&d, "inf", "v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n");
    assert_error(&p, &[], &["inf.obj:3", "not finite"]);
    let p = scene_with_obj(&d, "index", "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 7\n");
    assert_error(&p, &[], &["index.obj:5", "out of range"]);
    let p = scene_with_obj(&d, "zero", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    assert_error(&p, &[], &["zero.obj:4", "index 0"]);
    // A short `Kd` line (tobj panics on this one).
    write(&d, "short.mtl", "newmtl a\nKd 0.5 0.5\n");
    let p = scene_with_obj(&d, "short", &format!("mtllib short.mtl\nusemtl a\n{TRI}"));
    assert_error(&p, &[], &["short.mtl:2", "Kd"]);
}

#[test]
fn zero_area_triangles_are_dropped_and_counted() {
    let d = tmp("degenerate");
    let p = scene_with_obj(&d, "deg", &format!("{TRI}v 2 0 0\nf 1 2 4\nf 1 1 3\n"));
    let (ok, out, err) = render(&p, &[]);
    assert!(ok, "{err}");
    assert!(!err.contains("panicked") && !err.contains("error"), "{err}");
    assert!(err.contains("dropped 2 zero-area"), "{err}");
    assert!(out.contains("1 triangles"), "{out}");
}

#[test]
fn scene_level_errors() {
    let d = tmp("scene");
    write(&d, "t.obj", TRI);
    let p = write(&d, "dark.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n"));
    assert_error(&p, &[], &["dark.toml", "no light"]);
    let cam = CAMERA.replace("fov_y_deg = 40", "fov_y_deg = 0");
    let p = write(&d, "fov.toml", &format!("{cam}\n[[mesh]]\nobj = \"t.obj\"\n{LIGHT}"));
    assert_error(&p, &[], &["fov.toml:1", "fov_y_deg"]);
    let cam = CAMERA.replace("resolution = [4, 4]", "resolution = [0, 4]");
    let p = write(&d, "res.toml", &format!("{cam}\n[[mesh]]\nobj = \"t.obj\"\n{LIGHT}"));
    assert_error(&p, &[], &["res.toml:1", "resolution"]);
    let cam = CAMERA.replace("look_at = [0.5, 0.5, 0]", "look_at = [0.5, 0.5, 3]");
    let p = write(&d, "eye.toml", &format!("{cam}\n[[mesh]]\nobj = \"t.obj\"\n{LIGHT}"));
    assert_error(&p, &[], &["eye.toml:1", "coincide"]);
}

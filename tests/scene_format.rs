//! The scene contract (`scene-format.md`) end to end: TOML + OBJ + MTL files written to a
//! temporary directory, loaded with `load_scene`, and export → load round trips.

use glam::Vec3;
use photonlab::camera::Camera;
use photonlab::light::LightSet;
use photonlab::material::{Bsdf, Dielectric, Glossy, Lambertian, Material, Mirror};
use photonlab::math::Color;
use photonlab::scene::builtin::{cornell, furnace};
use photonlab::scene::export::export_scene;
use photonlab::scene::loader::load_scene;
use photonlab::scene::{Face, LightDesc, MeshData, NO_NORMALS, Placement, Scene};
use std::path::{Path, PathBuf};

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
    Tmp(tempfile::Builder::new().prefix(&format!("photonlab-scene-format-{tag}-")).tempdir().unwrap())
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, text).unwrap();
    p
}

const CAMERA: &str = "[camera]\neye = [0, 1, 4]\nlook_at = [0.0, 1.0, 0.0]\nfov_y_deg = 40.0\nresolution = [32, 24]\n";
const POINT: &str = "\n[[light]]\ntype = \"point\"\nposition = [0, 2, 0]\nintensity = [1, 1, 1]\n";
/// One triangle in the y = 0 plane whose counter-clockwise normal points down (-y).
const TRI_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";

fn lambert(c: Color) -> Bsdf {
    Bsdf::Lambertian(Lambertian { albedo: c })
}

fn err_of(path: &Path) -> String {
    format!("{:#}", load_scene(path).expect_err("load should fail"))
}

#[test]
fn camera_and_name() {
    let d = tmp("camera");
    write(&d, "t.obj", TRI_OBJ);
    let p = write(&d, "my-scene.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n{POINT}"));
    let s = load_scene(&p).unwrap();
    assert_eq!(s.name, "my-scene");
    assert_eq!(s.source.as_deref(), Some(p.as_path()));
    let c = &s.camera;
    assert_eq!((c.eye, c.look_at, c.up), (Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y));
    assert_eq!((c.fov_y_deg, c.width, c.height), (40.0, 32, 24));
    // An explicit `up` is used as given.
    let p = write(&d, "up.toml", &format!("{}up = [1, 0, 0]\n[[mesh]]\nobj = \"t.obj\"\n{POINT}", CAMERA));
    assert_eq!(load_scene(&p).unwrap().camera.up, Vec3::X);
    // Missing required key.
    let p = write(&d, "nofov.toml", "[camera]\neye = [0, 1, 4]\nlook_at = [0, 1, 0]\nresolution = [4, 4]\n");
    let e = err_of(&p);
    assert!(e.contains("nofov.toml") && e.contains("fov_y_deg"), "{e}");
}

#[test]
fn placement_scale_rotate_translate_and_relative_paths() {
    let d = tmp("placement");
    // OBJ in a sub-directory, its MTL relative to the OBJ (not to the TOML).
    write(&d, "meshes/mats/m.mtl", "newmtl red\nKd 1 0 0\n");
    write(&d, "meshes/t.obj", "mtllib mats/m.mtl\nusemtl red\nv 1 0 0\nv 1 1 0\nv 1 0 1\nf 1 2 3\n");
    let p = write(
        &d,
        "s.toml",
        &format!("{CAMERA}\n[[mesh]]\nobj = \"meshes/t.obj\"\nscale = [2, 3, 1]\nrotate_y_deg = 90\ntranslate = [0, 0, 1]\n{POINT}"),
    );
    let s = load_scene(&p).unwrap();
    // (1,0,0) -> scale (2,0,0) -> rotate +90° about y (x -> -z) (0,0,-2) -> translate (0,0,-1).
    let t = s.triangles[0];
    let expect = [Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 3.0, -1.0), Vec3::new(1.0, 0.0, -1.0)];
    for k in 0..3 {
        assert!((t[k] - expect[k]).length() < 1e-5, "{k}: {} vs {}", t[k], expect[k]);
    }
    assert_eq!(s.material(0).bsdf, lambert(Color::X));
    // A uniform scale is a number.
    let p = write(&d, "u.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"meshes/t.obj\"\nscale = 0.5\n{POINT}"));
    assert_eq!(load_scene(&p).unwrap().triangles[0][1], Vec3::new(0.5, 0.5, 0.0));
    let p = write(&d, "bad.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"meshes/t.obj\"\nscale = \"big\"\n{POINT}"));
    let e = err_of(&p);
    assert!(e.contains("bad.toml:9:") && e.contains("number"), "{e}");
    let p = write(&d, "zero.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"meshes/t.obj\"\nscale = [1, 0, 1]\n{POINT}"));
    let e = err_of(&p);
    assert!(e.contains("zero.toml:7:") && e.contains("scale"), "{e}");
}

#[test]
fn material_overrides_every_type_alias_and_default() {
    let d = tmp("overrides");
    write(&d, "t.obj", TRI_OBJ);
    let g = |kd: f32, ks: f32, n: f32| Bsdf::Glossy(Glossy { kd: Color::splat(kd), ks: Color::splat(ks), exponent: n });
    let cases: Vec<(&str, Bsdf, Color)> = vec![
        ("{ type = \"diffuse\" }", lambert(Color::splat(0.5)), Color::ZERO),
        ("{ type = \"diffuse\", albedo = [0.1, 0.2, 0.3] }", lambert(Color::new(0.1, 0.2, 0.3)), Color::ZERO),
        ("{ type = \"lambertian\", kd = [0.3, 0.3, 0.3] }", lambert(Color::splat(0.3)), Color::ZERO),
        ("{ type = \"mirror\" }", Bsdf::Mirror(Mirror { reflectance: Color::ONE }), Color::ZERO),
        (
            "{ type = \"mirror\", reflectance = [0.9, 0.8, 0.7] }",
            Bsdf::Mirror(Mirror { reflectance: Color::new(0.9, 0.8, 0.7) }),
            Color::ZERO,
        ),
        ("{ type = \"mirror\", ks = [0.5, 0.5, 0.5] }", Bsdf::Mirror(Mirror { reflectance: Color::splat(0.5) }), Color::ZERO),
        ("{ type = \"glass\" }", Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE)), Color::ZERO),
        (
            "{ type = \"glass\", ior = 1.33, tint = [0.9, 1, 1] }",
            Bsdf::Dielectric(Dielectric::new(1.33, Color::new(0.9, 1.0, 1.0))),
            Color::ZERO,
        ),
        (
            "{ type = \"dielectric\", ior = 2.4, tf = [0.5, 0.5, 0.5] }",
            Bsdf::Dielectric(Dielectric::new(2.4, Color::splat(0.5))),
            Color::ZERO,
        ),
        ("{ type = \"glossy\" }", g(0.5, 0.0, 1.0), Color::ZERO),
        ("{ type = \"glossy\", kd = [0.2, 0.2, 0.2], ks = [0.4, 0.4, 0.4], ns = 50 }", g(0.2, 0.4, 50.0), Color::ZERO),
        ("{ type = \"glossy\", albedo = [0.1, 0.1, 0.1], exponent = 7.5 }", g(0.1, 0.0, 7.5), Color::ZERO),
        ("{ type = \"emitter\" }", lambert(Color::splat(0.5)), Color::ZERO),
        ("{ type = \"emitter\", radiance = [5, 4, 3], albedo = [0.7, 0.7, 0.7] }", lambert(Color::splat(0.7)), Color::new(5.0, 4.0, 3.0)),
        ("{ type = \"emitter\", ke = [1, 2, 3], kd = [0, 0, 0] }", lambert(Color::ZERO), Color::new(1.0, 2.0, 3.0)),
    ];
    for (i, (text, bsdf, emission)) in cases.iter().enumerate() {
        let p = write(&d, &format!("o{i}.toml"), &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\nmaterial = {text}\n{POINT}"));
        let s = load_scene(&p).unwrap_or_else(|e| panic!("{text}: {e:#}"));
        let m = s.material(0);
        assert_eq!((&m.bsdf, m.emission), (bsdf, *emission), "{text}");
    }
    for (text, needle) in [
        ("{ type = \"velvet\" }", "velvet"),
        ("{ type = \"glass\", roughness = 0.1 }", "roughness"),
        ("{ type = \"mirror\", albedo = [1, 1, 1] }", "albedo"),
        ("{ type = \"diffuse\", albedo = [1, 1, 1], kd = [1, 1, 1] }", "duplicate"),
        ("{ albedo = [1, 1, 1] }", "type"),
        ("{ type = \"glass\", ior = -1 }", "ior"),
        ("{ type = \"diffuse\", albedo = [1, -1, 1] }", "albedo"),
    ] {
        let p = write(&d, "bad.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\nmaterial = {text}\n{POINT}"));
        let e = err_of(&p);
        assert!(e.contains("bad.toml:") && e.contains(needle), "{text}: {e}");
    }
}

#[test]
fn every_light_type() {
    let d = tmp("lights");
    write(&d, "t.obj", TRI_OBJ);
    let lights = "[[light]]\ntype = \"point\"\nposition = [1, 2, 3]\nintensity = [10, 20, 30]\n\
                  [[light]]\ntype = \"spot\"\nposition = [0, 1.9, 0]\ndirection = [0, -2, 0]\nintensity = [5, 5, 5]\ncone_deg = 30\nfalloff_deg = 35.5\n\
                  [[light]]\ntype = \"directional\"\ndirection = [3, -4, 0]\nirradiance = [1, 0.5, 0.25]\n";
    let p = write(&d, "l.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n{lights}"));
    let s = load_scene(&p).unwrap();
    assert_eq!(
        s.lights,
        vec![
            LightDesc::Point { position: Vec3::new(1.0, 2.0, 3.0), intensity: Color::new(10.0, 20.0, 30.0) },
            LightDesc::Spot {
                position: Vec3::new(0.0, 1.9, 0.0),
                direction: -Vec3::Y,
                intensity: Color::splat(5.0),
                cone_deg: 30.0,
                falloff_deg: 35.5
            },
            LightDesc::Directional { direction: Vec3::new(0.6, -0.8, 0.0), irradiance: Color::new(1.0, 0.5, 0.25) },
        ]
    );
    for (light, needle) in [
        (
            "type = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\ncone_deg = 40\nfalloff_deg = 30\n",
            "cone_deg",
        ),
        ("type = \"directional\"\ndirection = [0, 0, 0]\nirradiance = [1, 1, 1]\n", "direction"),
        ("type = \"point\"\nposition = [0, 1, 0]\n", "intensity"),
        ("type = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\ncolour = 1\n", "colour"),
        ("type = \"area\"\n", "area"),
    ] {
        let p = write(&d, "bad.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n\n[[light]]\n{light}"));
        let e = err_of(&p);
        assert!(e.contains("bad.toml:") && e.contains(needle), "{light}: {e}");
    }
}

#[test]
fn mtl_rule_order_from_files() {
    let d = tmp("mtl");
    // CRLF, tabs, trailing comments, a single-number colour, tricky rule order.
    let mtl = "# materials\r\n\
               newmtl lampglass\r\n\tKe 2 2 2 # emits\r\n\tillum 7\r\n\tKd 0.25\r\n\
               newmtl dissolved\r\n\td 0.5\r\n\tNi 1.2\r\n\tKs 1 1 1\r\n\tillum 3\r\n\
               newmtl tr\r\n\tTr 0.2\r\n\tNi 0.8\r\n\tTf 0.1 0.2 0.3\r\n\
               newmtl illum4\r\n\tillum 4\r\n\
               newmtl illum6\r\n\tillum 6\r\n\
               newmtl mirror3\r\n\tillum 3\r\n\
               newmtl mirror5\r\n\tillum 5\r\n\tKs 0 0 0\r\n\tKd 0.5\r\n\
               newmtl tintedmirror\r\n\tillum 5\r\n\tKs 0.9 0.8 0.7 # tinted\r\n\
               newmtl ns1\r\n\tKs 0.5 0.5 0.5\r\n\tNs 1\r\n\tKd 0.2 0.3 0.4\r\n\
               newmtl glossy\r\n\tKs 0 0 0.5\r\n\tNs 1.5\r\n\
               newmtl zeroks\r\n\tKs 0 0 0\r\n\tNs 100\r\n\tKd 0.1 0.2 0.3 # coloured\r\n\
               newmtl nothing\r\n\tKa 1 1 1\r\n\tmap_Kd tex.png\r\n";
    let names =
        ["lampglass", "dissolved", "tr", "illum4", "illum6", "mirror3", "mirror5", "tintedmirror", "ns1", "glossy", "zeroks", "nothing"];
    let mut obj = String::from("mtllib m.mtl\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 0 1\r\n");
    for n in names {
        obj.push_str(&format!("usemtl {n}\r\nf 1 2 3\r\n"));
    }
    write(&d, "m.mtl", mtl);
    write(&d, "m.obj", &obj);
    let p = write(&d, "m.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"m.obj\"\n"));
    let s = load_scene(&p).unwrap();
    let glass = |ior: f32, t: Color| Bsdf::Dielectric(Dielectric::new(ior, t));
    let expect: Vec<(Bsdf, Color)> = vec![
        (lambert(Color::splat(0.25)), Color::splat(2.0)),
        (glass(1.2, Color::ONE), Color::ZERO),
        (glass(1.5, Color::new(0.1, 0.2, 0.3)), Color::ZERO),
        (glass(1.5, Color::ONE), Color::ZERO),
        (glass(1.5, Color::ONE), Color::ZERO),
        (Bsdf::Mirror(Mirror { reflectance: Color::ONE }), Color::ZERO),
        (Bsdf::Mirror(Mirror { reflectance: Color::ONE }), Color::ZERO),
        (Bsdf::Mirror(Mirror { reflectance: Color::new(0.9, 0.8, 0.7) }), Color::ZERO),
        (lambert(Color::new(0.2, 0.3, 0.4)), Color::ZERO),
        (Bsdf::Glossy(Glossy { kd: Color::splat(0.5), ks: Color::new(0.0, 0.0, 0.5), exponent: 1.5 }), Color::ZERO),
        (lambert(Color::new(0.1, 0.2, 0.3)), Color::ZERO),
        (lambert(Color::splat(0.5)), Color::ZERO),
    ];
    assert_eq!(s.triangles.len(), names.len());
    for (i, (bsdf, e)) in expect.iter().enumerate() {
        let m = s.material(i as u32);
        assert_eq!(m.name, names[i]);
        assert_eq!((&m.bsdf, m.emission), (bsdf, *e), "{}", names[i]);
    }
    // The one remark: `map_Kd tex.png` names a texture that does not exist.
    assert!(s.warnings.len() == 1 && s.warnings[0].contains("map_Kd"), "{:?}", s.warnings);
}

/// `map_d` (named in another letter case than the file) cuts the material out: a mask
/// whose opacity is the image's alpha channel.
#[test]
fn map_d_is_a_mask_from_the_alpha_channel() {
    use photonlab::texture::Slot;
    let d = tmp("mapd");
    // 2×1 RGBA: left transparent, right opaque (colour channels white in both).
    let img = image::RgbaImage::from_raw(2, 1, vec![255, 255, 255, 0, 255, 255, 255, 255]).unwrap();
    img.save(d.join("Leaf_Mask.png")).unwrap();
    write(&d, "m.mtl", "newmtl leaf\nKd 0 0 0\nmap_d leaf_mask.png\n");
    // A quad at z = 0 with u across x (0 → 1).
    let obj = "mtllib m.mtl\nv -1 0 0\nv 1 0 0\nv 1 2 0\nv -1 2 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
               usemtl leaf\nf 1/1 2/2 3/3 4/4\n";
    write(&d, "m.obj", obj);
    let p = write(&d, "m.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"m.obj\"\n{POINT}"));
    let s = load_scene(&p).unwrap_or_else(|e| panic!("{e:#}"));
    let leaf = s.materials.iter().position(|m| m.name == "leaf").unwrap();
    assert!(matches!(&s.materials[leaf].bsdf, Bsdf::Mask(m) if matches!(*m.nested, Bsdf::Lambertian(_))), "{:?}", s.materials[leaf]);
    assert!(s.textures.bindings.iter().any(|b| b.material as usize == leaf && b.slot == Slot::Opacity { alpha: true }));
    assert!(s.warnings.iter().any(|w| w.contains("map_d") && w.contains("letter case")), "{:?}", s.warnings);
}

#[test]
fn faces_negative_indices_quads_and_normals() {
    let d = tmp("faces");
    // A pentagon (fan: 3 triangles) with relative indices and per-corner normals, then
    // a triangle with absolute `v/vt/vn` references, `o`/`g`/`s` lines and a comment.
    let obj = "o thing\ng part\ns 1\n\
               v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1.5 0\nv 0 1 0 # five\n\
               vt 0 0\nvn 0 0 1\nvn 0 0.6 0.8\nvn 0.6 0 0.8\n\
               f -5//-3 -4//-2 -3//-1 -2//-3 -1//-2\n\
               f 1/1/3\t2/1/2 3/1/1\n\
               f 1 3 5\n";
    write(&d, "f.obj", obj);
    let p = write(&d, "f.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"f.obj\"\n{POINT}"));
    let s = load_scene(&p).unwrap();
    let v = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.5, 1.5, 0.0), Vec3::Y];
    assert_eq!(s.triangles, vec![[v[0], v[1], v[2]], [v[0], v[2], v[3]], [v[0], v[3], v[4]], [v[0], v[1], v[2]], [v[0], v[2], v[4]]]);
    let n = [Vec3::Z, Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.6, 0.0, 0.8)];
    let normals = |t: usize| s.normals[s.tri_normals[t] as usize];
    assert_eq!(normals(0), [n[0], n[1], n[2]]);
    assert_eq!(normals(1), [n[0], n[2], n[0]]);
    assert_eq!(normals(2), [n[0], n[0], n[1]]);
    assert_eq!(normals(3), [n[2], n[1], n[0]]);
    assert_eq!(s.tri_normals[4], NO_NORMALS);
    // No usemtl: the contract's default material.
    assert!((0..5).all(|t| s.material(t).bsdf == lambert(Color::splat(0.5)) && !s.material(t).is_emitter()));
}

#[test]
fn undefined_material_warns_and_degenerates_are_dropped() {
    let d = tmp("warn");
    write(&d, "m.mtl", "newmtl lamp\nKe 1 1 1\n");
    // `usemtl light` is undefined (as in the shipped Glossy Cornell box); two
    // zero-area triangles (collinear, repeated vertex).
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 1\nv 2 0 0\n\
               usemtl light\nf 1 2 3\nf 1 2 4\nusemtl lamp\nf 1 3 2\nf 1 1 3\n";
    write(&d, "w.obj", obj);
    let p = write(&d, "w.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"w.obj\"\n"));
    let s = load_scene(&p).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.dropped_degenerate, 2);
    assert_eq!(s.material(0).bsdf, lambert(Color::splat(0.5)));
    assert!(!s.material(0).is_emitter());
    assert!(s.material(1).is_emitter());
    assert!(s.warnings.iter().any(|w| w.contains("w.obj:6:") && w.contains("`light`")), "{:?}", s.warnings);
    assert!(s.warnings.iter().any(|w| w.contains("dropped 2 zero-area")), "{:?}", s.warnings);
}

#[test]
fn negative_scale_mirrors_and_flips_the_emitting_side() {
    let d = tmp("mirror");
    write(&d, "m.mtl", "newmtl lamp\nKe 1 1 1\n");
    write(&d, "l.obj", &format!("mtllib m.mtl\nusemtl lamp\n{TRI_OBJ}"));
    let plain = write(&d, "a.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"l.obj\"\n"));
    let mirrored = write(&d, "b.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"l.obj\"\nscale = [-1, 1, 1]\n"));
    let a = load_scene(&plain).unwrap();
    let b = load_scene(&mirrored).unwrap();
    assert!(a.geometric_normal(0).y < -0.999);
    assert!(b.geometric_normal(0).y > 0.999, "winding must not be fixed");
    let Some(photonlab::light::Light::Area { normal, .. }) = LightSet::build(&b).unwrap().lights.first().cloned() else { panic!() };
    assert!(normal.y > 0.999);
    assert!(a.warnings.is_empty());
    assert!(b.warnings.iter().any(|w| w.contains("negative scale") && w.contains("b.toml:7")), "{:?}", b.warnings);
}

#[test]
fn errors_name_the_file() {
    let d = tmp("errors");
    write(&d, "t.obj", TRI_OBJ);
    let p = write(&d, "nolight.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n"));
    let e = err_of(&p);
    assert!(e.contains("nolight.toml") && e.contains("no light"), "{e}");
    let p = write(&d, "key.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\nrotate_x_deg = 3\n{POINT}"));
    let e = err_of(&p);
    assert!(e.starts_with(&format!("{}:9:", p.display())) && e.contains("rotate_x_deg"), "{e}");
    assert!(!e.contains('\n'), "{e}");
    write(&d, "nan.obj", "v 0 0 0\nv 1 0 0\nv 0 0 nan\nf 1 2 3\n");
    let p = write(&d, "nan.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"nan.obj\"\n{POINT}"));
    let e = err_of(&p);
    assert!(e.contains("nan.toml") && e.contains("nan.obj:3:"), "{e}");
    write(&d, "nomtl.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\n\nmtllib missing.mtl\nf 1 2 3\n");
    let p = write(&d, "nomtl.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"nomtl.obj\"\n{POINT}"));
    let e = err_of(&p);
    assert!(e.contains("nomtl.obj:5:") && e.contains("missing.mtl"), "{e}");
}

/// Asserts that `b` (exported and re-loaded `a`) has the same triangles, per-triangle
/// materials, vertex normals, camera and lights.
fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.triangles, b.triangles, "{}: triangles", a.name);
    for t in 0..a.triangles.len() as u32 {
        let (ma, mb) = (a.material(t), b.material(t));
        assert_eq!((&ma.bsdf, ma.emission), (&mb.bsdf, mb.emission), "{}: triangle {t} material", a.name);
        let n = |s: &Scene| {
            let i = s.tri_normals[t as usize];
            (i != NO_NORMALS).then(|| s.normals[i as usize])
        };
        assert_eq!(n(a), n(b), "{}: triangle {t} normals", a.name);
    }
    let cam = |c: &Camera| (c.eye, c.look_at, c.up, c.fov_y_deg, c.width, c.height);
    assert_eq!(cam(&a.camera), cam(&b.camera), "{}: camera", a.name);
    assert_eq!(a.lights, b.lights, "{}: lights", a.name);
}

/// Exports `s`, loads it back, checks it is the same scene; returns it and the directory.
fn round_trip(s: &Scene, tag: &str) -> (Scene, Tmp) {
    let d = tmp(tag);
    let toml = export_scene(s, &d).unwrap();
    assert_eq!(toml, d.join(format!("{}.toml", s.name)));
    assert!(d.join(format!("{}.obj", s.name)).is_file() && d.join(format!("{}.mtl", s.name)).is_file());
    let back = load_scene(&toml).unwrap_or_else(|e| panic!("{e:#}"));
    assert_same_scene(s, &back);
    (back, d)
}

#[test]
fn export_round_trips_builtins() {
    let (back, _dir) = round_trip(&cornell(), "rt-cornell");
    // Cornell materials are plain MTL entries, so even the names survive.
    assert_eq!(back.material(0).name, "white");
    round_trip(&furnace(0.5, 1.0, 12), "rt-furnace");
}

/// A scene built in code with every material kind (including the ones MTL cannot
/// express), vertex normals and every light type.
fn kitchen_sink() -> Scene {
    let mat = |name: &str, bsdf: Bsdf, e: Color| Material { name: name.into(), bsdf, emission: e };
    let mut m = MeshData {
        materials: vec![
            mat("white wall", lambert(Color::new(0.7, 0.71, 0.123_456_79)), Color::ZERO),
            mat("lamp", lambert(Color::splat(0.78)), Color::new(17.0, 12.0, 4.0)),
            mat("glass", Bsdf::Dielectric(Dielectric::new(1.333_333_4, Color::new(0.9, 0.95, 1.0))), Color::ZERO),
            mat("mirror", Bsdf::Mirror(Mirror { reflectance: Color::new(0.95, 0.9, 0.1) }), Color::ZERO),
            mat("glossy", Bsdf::Glossy(Glossy { kd: Color::splat(0.3), ks: Color::new(0.2, 0.0, 0.6), exponent: 40.5 }), Color::ZERO),
            mat("flat glossy", Bsdf::Glossy(Glossy { kd: Color::splat(0.3), ks: Color::splat(0.2), exponent: 0.5 }), Color::ZERO),
            mat("dull glossy", Bsdf::Glossy(Glossy { kd: Color::splat(0.3), ks: Color::ZERO, exponent: 20.0 }), Color::ZERO),
            mat("black mirror", Bsdf::Mirror(Mirror { reflectance: Color::ZERO }), Color::ZERO),
            mat("thin glass", Bsdf::Dielectric(Dielectric::new(1.0, Color::ONE)), Color::ZERO),
            // Same name as material 0, different content.
            mat("white wall", lambert(Color::splat(0.1)), Color::ZERO),
        ],
        ..Default::default()
    };
    for i in 0..30 {
        let x = i as f32 * 0.1 + 1e-7;
        m.positions.extend([Vec3::new(x, 0.3, -0.1), Vec3::new(x + 0.07, 0.0, 1.0 / 3.0), Vec3::new(x, 1.0, 1e-20)]);
        m.normals.push(Vec3::new(x, 1.0, 0.2).normalize());
    }
    // Every material, interleaved, half of the faces with vertex normals.
    for i in 0..30u32 {
        let n = (i % 2 == 0).then_some([i, (i + 1) % 30, (i + 2) % 30]);
        m.faces.push(Face { v: [3 * i, 3 * i + 1, 3 * i + 2], n, material: i % 10, line: 0 });
    }
    let cam = Camera::new(Vec3::new(0.1, 0.2, 5.3), Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.01, 1.0, 0.0), 33.3, 40, 30).unwrap();
    let mut s = Scene::new("sink", cam);
    s.add_mesh(&m, &Placement { scale: Vec3::new(1.5, 1.0, 0.7), rotate_y_deg: 17.0, translate: Vec3::new(0.1, 0.0, 0.0) }, None).unwrap();
    s.lights = vec![
        LightDesc::Point { position: Vec3::new(0.1, 1.9, 0.3), intensity: Color::new(3.0, 2.5, 1.0) },
        LightDesc::Spot {
            position: Vec3::new(0.0, 2.0, 0.0),
            direction: Vec3::new(0.1, -1.0, 0.2).normalize(),
            intensity: Color::splat(7.0),
            cone_deg: 25.0,
            falloff_deg: 33.3,
        },
        LightDesc::Directional { direction: Vec3::new(-0.3, -1.0, 0.45).normalize(), irradiance: Color::new(0.5, 0.6, 0.7) },
    ];
    s
}

#[test]
fn export_round_trips_every_material_light_and_normals() {
    let s = kitchen_sink();
    assert!(s.tri_normals.iter().filter(|&&n| n != NO_NORMALS).count() >= 10);
    let (back, d) = round_trip(&s, "rt-sink");
    // Unexpressible materials went to override meshes: more than one OBJ file.
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert!(d.join("sink-1.obj").is_file());
    let mtl = std::fs::read_to_string(d.join("sink.mtl")).unwrap();
    assert!(mtl.contains("newmtl white_wall\n") && mtl.contains("newmtl white_wall-2\n"), "{mtl}");
    // Exporting the re-loaded scene again gives the same scene once more.
    round_trip(&back, "rt-sink2");
}

#[test]
fn scene_files_reject_the_manifest_extensions() {
    let d = tmp("extensions");
    write(&d, "t.obj", TRI_OBJ);
    // CAMERA is lines 1-5, then a blank line, [[mesh]] on 7, obj on 8, the extension on 9.
    for (ext, line) in [("fit_height = 2", 9), ("download = \"https://x\"", 9)] {
        let p = write(&d, "ext.toml", &format!("{CAMERA}\n[[mesh]]\nobj = \"t.obj\"\n{ext}\n{POINT}"));
        let e = err_of(&p);
        assert!(e.contains(&format!("ext.toml:{line}:")) && e.contains("manifest extension"), "{e}");
    }
    let p = write(&d, "base.toml", &format!("builtin = \"cornell\"\n{CAMERA}"));
    let e = err_of(&p);
    assert!(e.contains("base.toml:1:") && e.contains("`builtin`"), "{e}");
    // Without a camera (which an inline scene on a base may leave out) and without a resolution.
    let e = err_of(&write(&d, "nocam.toml", &format!("[[mesh]]\nobj = \"t.obj\"\n{POINT}")));
    assert!(e.contains("nocam.toml") && e.contains("camera"), "{e}");
    let e =
        err_of(&write(&d, "nores.toml", &format!("{}\n[[mesh]]\nobj = \"t.obj\"\n{POINT}", CAMERA.replace("resolution = [32, 24]\n", ""))));
    assert!(e.contains("nores.toml:1:") && e.contains("resolution"), "{e}");
}

//! End-to-end tests of the XML loader: the shipped scenes load, errors name file,
//! line, element and name, and conventions (camera, area light side, textures) hold.

use super::*;
use crate::scene::loader::load_scene;
use std::path::PathBuf;

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments").join("scenes")
}

fn write(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n")).unwrap();
    p
}

const SENSOR: &str = r#"<sensor type="perspective"><float name="fov" value="90"/><string name="fov_axis" value="y"/>
<transform name="to_world"><lookat origin="0,0,3" target="0,0,0" up="0,1,0"/></transform>
<sampler type="independent"><integer name="sample_count" value="7"/></sampler>
<film type="hdrfilm"><integer name="width" value="20"/><integer name="height" value="10"/><rfilter type="box"/></film></sensor>"#;

#[test]
fn shipped_scenes_load() {
    for (name, textured, env) in [
        ("mi-materials", false, false),
        ("mi-textured", true, false),
        ("mi-envmap", false, true),
        ("mi-interior", false, false),
        ("mi-rough", true, false),
        ("mi-open", false, false),
    ] {
        let s = load_scene(&scenes().join(format!("{name}.xml"))).unwrap_or_else(|e| panic!("{name}: {e}"));
        s.validate().unwrap();
        assert!(!s.triangles.is_empty(), "{name}");
        assert_eq!(s.default_spp, Some(64), "{name}");
        assert_eq!(!s.textures.is_empty(), textured, "{name}");
        assert_eq!(s.lights.iter().any(|l| matches!(l, LightDesc::Envmap { .. })), env, "{name}");
    }
}

#[test]
fn camera_area_light_and_spp() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "a.xml",
        &format!(
            "{SENSOR}\n<shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"90\"/><translate y=\"1\"/></transform>\
             <emitter type=\"area\"><rgb name=\"radiance\" value=\"2\"/></emitter></shape>"
        ),
    );
    let s = load_scene(&p).unwrap();
    assert_eq!((s.camera.width, s.camera.height, s.default_spp), (20, 10, Some(7)));
    assert!((s.camera.fov_y_deg - 90.0).abs() < 1e-4);
    assert_eq!(s.camera.eye, Vec3::new(0.0, 0.0, 3.0));
    // Rotated +90° about x, the rectangle's +z normal points down: it lights the floor.
    assert!(s.geometric_normal(0).y < -0.999);
    assert_eq!(s.materials[0].emission, Vec3::splat(2.0));
    // An area light without a BSDF reflects nothing (Mitsuba's default BSDF for an
    // emitter is black diffuse), so it is the same on both sides: no warning.
    assert_eq!(s.materials[0].bsdf.diffuse_albedo(), Vec3::ZERO);
    assert!(!s.warnings.iter().any(|w| w.contains("one-sided")), "{:?}", s.warnings);
}

#[test]
fn default_bsdf_is_grey_diffuse_and_black_on_emitters() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "a.xml",
        &format!(
            "{SENSOR}\n<shape type=\"rectangle\"><transform name=\"to_world\"><translate z=\"-1\"/></transform></shape>\
             <shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"90\"/><translate y=\"1\"/></transform>\
             <emitter type=\"area\"><rgb name=\"radiance\" value=\"2\"/></emitter></shape>"
        ),
    );
    let s = load_scene(&p).unwrap();
    assert_eq!(s.materials.len(), 2);
    // A plain shape: diffuse 0.5, one-sided in Mitsuba, reported.
    assert_eq!(s.materials[0].bsdf.diffuse_albedo(), Vec3::splat(0.5));
    assert!(!s.materials[0].is_emitter());
    assert!(s.warnings.iter().any(|w| w.contains("one-sided") && w.contains("default (diffuse 0.5)")), "{:?}", s.warnings);
    // The emitter: black, so its reflection cannot brighten what it lights.
    assert!(s.materials[1].is_emitter());
    assert_eq!(s.materials[1].bsdf.diffuse_albedo(), Vec3::ZERO);
}

#[test]
fn unsupported_things_are_errors_with_file_and_line() {
    let d = tempfile::tempdir().unwrap();
    let cases = [
        ("<shape type=\"cylinder\"/>", "cylinder"),
        ("<shape type=\"cube\">\n<float name=\"radius\" value=\"2\"/></shape>", "radius"),
        ("<shape type=\"cube\"><bsdf type=\"diffuse\">\n<float name=\"alpha\" value=\"2\"/></bsdf></shape>", "alpha"),
        ("<shape type=\"cube\"><bsdf type=\"principled\"/></shape>", "principled"),
        ("<emitter type=\"skysun\"/>", "skysun"),
        ("<shape type=\"ply\"><string name=\"filename\" value=\"missing.ply\"/></shape>", "missing.ply"),
        ("<shape type=\"cube\"><bsdf type=\"dielectric\"><string name=\"int_ior\" value=\"unobtainium\"/></bsdf></shape>", "unobtainium"),
        ("<shape type=\"cube\"><bsdf type=\"roughconductor\">\n<string name=\"distribution\" value=\"phong\"/></bsdf></shape>", "phong"),
        ("<shape type=\"cube\"><bsdf type=\"twosided\">\n<bsdf type=\"dielectric\"/></bsdf></shape>", "only reflects"),
        (
            "<shape type=\"cube\"><bsdf type=\"conductor\">\n<string name=\"material\" value=\"Au\"/><rgb name=\"eta\" value=\"1\"/></bsdf></shape>",
            "not both",
        ),
    ];
    for (i, (body, needle)) in cases.iter().enumerate() {
        let p = write(d.path(), &format!("e{i}.xml"), &format!("{SENSOR}\n{body}"));
        let e = load_scene(&p).unwrap_err().to_string();
        let file_line = format!("{}:", p.display());
        assert!(e.starts_with(&file_line) && e.contains(needle), "case {i}: {e}");
        // The element's line (the sensor takes lines 2–5).
        let line: u32 = e[file_line.len()..].split(':').next().unwrap().parse().unwrap_or(0);
        assert!(line >= 6, "case {i}: line {line} in {e}");
    }
}

#[test]
fn includes_defaults_and_ply_texture_round_trip() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("quad.ply"), crate::scene::ply::write_binary_ply(&[Vec3::ZERO, Vec3::X, Vec3::Y], &[], &[[0, 1, 2]]))
        .unwrap();
    write(d.path(), "mat.xml", "<bsdf type=\"diffuse\" id=\"m\"><rgb name=\"reflectance\" value=\"$refl\"/></bsdf>");
    let p = write(
        d.path(),
        "main.xml",
        &format!(
            "<default name=\"refl\" value=\"0.25\"/>\n<include filename=\"mat.xml\"/>\n{SENSOR}\n\
             <shape type=\"ply\"><string name=\"filename\" value=\"quad.ply\"/><ref id=\"m\"/></shape>\n\
             <emitter type=\"constant\"/>"
        ),
    );
    let s = load_scene(&p).unwrap();
    assert_eq!(s.triangles.len(), 1);
    assert_eq!(s.materials[0].bsdf, crate::material::Bsdf::Lambertian(crate::material::Lambertian { albedo: Vec3::splat(0.25) }));
    assert!(matches!(s.lights[0], LightDesc::Constant { radiance } if radiance == Vec3::ONE));
}

#[test]
fn every_bsdf_maps_to_its_namesake() {
    use crate::material::{Bsdf, MicrofacetType};
    let d = tempfile::tempdir().unwrap();
    let bsdfs = [
        r#"<bsdf type="conductor"><string name="material" value="Au"/></bsdf>"#,
        r#"<bsdf type="conductor"><rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.4, 1.9"/><float name="ext_eta" value="2"/></bsdf>"#,
        r#"<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf>"#,
        r#"<bsdf type="roughconductor"><string name="material" value="Cu"/></bsdf>"#,
        r#"<bsdf type="plastic"><texture type="checkerboard" name="diffuse_reflectance"/></bsdf>"#,
        r#"<bsdf type="roughplastic"><float name="alpha" value="0.2"/><boolean name="nonlinear" value="true"/></bsdf>"#,
        r#"<bsdf type="roughdielectric"><float name="int_ior" value="1.33"/></bsdf>"#,
        r#"<bsdf type="thindielectric"/>"#,
        r#"<bsdf type="twosided"><bsdf type="roughplastic"/></bsdf>"#,
        r#"<bsdf type="twosided"><bsdf type="diffuse"/><bsdf type="conductor"/></bsdf>"#,
        r#"<bsdf type="mask"><float name="opacity" value="0.25"/><bsdf type="diffuse"/></bsdf>"#,
        r#"<bsdf type="mask"><texture type="checkerboard" name="opacity"/><bsdf type="twosided"><bsdf type="plastic"/></bsdf></bsdf>"#,
    ];
    let body: String = bsdfs.iter().map(|b| format!("<shape type=\"rectangle\">{b}</shape>\n")).collect();
    let p = write(d.path(), "all.xml", &format!("{SENSOR}\n{body}"));
    let s = load_scene(&p).unwrap();
    let m: Vec<&Bsdf> = s.materials.iter().map(|m| &m.bsdf).collect();
    assert_eq!(m.len(), bsdfs.len());
    let au = super::presets::conductor("Au").unwrap();
    // Divided by `ext_eta`, air (1.00028) by default, as Mitsuba 3 does.
    assert!(
        matches!(m[0], Bsdf::Conductor(c) if (c.eta * 1.00028 - au.0).abs().max_element() < 1e-5 && (c.k * 1.00028 - au.1).abs().max_element() < 1e-5)
    );
    assert!(matches!(m[1], Bsdf::Conductor(c) if c.eta == Vec3::new(0.1, 0.45, 0.55) && c.k == Vec3::new(1.95, 1.2, 0.95)));
    assert!(
        matches!(m[2], Bsdf::RoughConductor(c) if c.distribution == MicrofacetType::Ggx && c.alpha == 0.3 && c.eta == Vec3::ZERO && c.k == Vec3::ONE)
    );
    // Mitsuba 3's defaults: Beckmann, α = 0.1.
    assert!(matches!(m[3], Bsdf::RoughConductor(c) if c.distribution == MicrofacetType::Beckmann && c.alpha == 0.1));
    assert!(matches!(m[4], Bsdf::Plastic(_)));
    assert!(matches!(m[5], Bsdf::RoughPlastic(r) if r.nonlinear && r.alpha == 0.2));
    assert!(matches!(m[6], Bsdf::RoughDielectric(r) if r.int_ior == 1.33 && r.ext_ior == 1.00028));
    assert!(matches!(m[7], Bsdf::ThinDielectric(_)));
    assert!(matches!(m[8], Bsdf::TwoSided(t) if matches!(*t.front, Bsdf::RoughPlastic(_)) && t.front == t.back));
    assert!(matches!(m[9], Bsdf::TwoSided(t) if matches!(*t.front, Bsdf::Lambertian(_)) && matches!(*t.back, Bsdf::Mirror(_))));
    assert!(matches!(m[10], Bsdf::Mask(k) if k.opacity == 0.25 && matches!(*k.nested, Bsdf::Lambertian(_))));
    assert!(matches!(m[11], Bsdf::Mask(k) if matches!(*k.nested, Bsdf::TwoSided(_))));
    // The textured slots: the plastic's diffuse reflectance, the last mask's opacity.
    let slots: Vec<(u32, crate::texture::Slot)> = s.textures.bindings.iter().map(|b| (b.material, b.slot)).collect();
    assert!(slots.contains(&(4, crate::texture::Slot::DiffuseReflectance)), "{slots:?}");
    assert!(slots.contains(&(11, crate::texture::Slot::Opacity { alpha: false })), "{slots:?}");
    // Bare diffuse (the mask's) is reported as one-sided; nothing else is.
    assert_eq!(s.warnings.iter().filter(|w| w.contains("one-sided")).count(), 1, "{:?}", s.warnings);
}

#[test]
fn serialized_shape_with_index() {
    use glam::Vec2;
    let d = tempfile::tempdir().unwrap();
    let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
    let uv = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE];
    let data = crate::scene::serialized::write_serialized(&[(&p[..3], &[], &[], &[[0, 1, 2]]), (&p, &[], &uv, &[[0, 1, 2], [1, 3, 2]])]);
    std::fs::write(d.path().join("m.serialized"), data).unwrap();
    let shape = |i: i32| {
        format!(
            "<shape type=\"serialized\"><string name=\"filename\" value=\"m.serialized\"/><integer name=\"shape_index\" value=\"{i}\"/>\
             <transform name=\"to_world\"><translate x=\"2\"/></transform></shape>"
        )
    };
    let s = load_scene(&write(d.path(), "s.xml", &format!("{SENSOR}\n{}", shape(1)))).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.triangles[1][1], Vec3::new(3.0, 1.0, 1.0));
    assert!(!s.uvs.is_empty());
    let e = load_scene(&write(d.path(), "e.xml", &format!("{SENSOR}\n{}", shape(5)))).unwrap_err().to_string();
    assert!(e.contains("m.serialized") && e.contains("out of range"), "{e}");
}

/// A checkerboard on every reflectance parameter of the seven BSDFs that have one
/// loads and binds to its slot (a texture on `specular_reflectance` or
/// `specular_transmittance` used to be an error).
#[test]
fn textures_on_specular_parameters_bind_to_their_slots() {
    use crate::texture::Slot;
    let d = tempfile::tempdir().unwrap();
    let tex = |name: &str| format!(r#"<texture type="checkerboard" name="{name}"/>"#);
    let (r, t) = (tex("specular_reflectance"), tex("specular_transmittance"));
    let bsdfs = [
        format!(r#"<bsdf type="conductor"><string name="material" value="Au"/>{r}</bsdf>"#),
        format!(r#"<bsdf type="conductor">{r}</bsdf>"#),
        format!(r#"<bsdf type="roughconductor"><string name="material" value="Cu"/>{r}</bsdf>"#),
        format!(r#"<bsdf type="dielectric">{r}{t}</bsdf>"#),
        format!(r#"<bsdf type="roughdielectric">{t}</bsdf>"#),
        format!(r#"<bsdf type="thindielectric">{r}{t}</bsdf>"#),
        format!(r#"<bsdf type="plastic">{r}</bsdf>"#),
        format!(r#"<bsdf type="twosided"><bsdf type="roughplastic">{r}{}</bsdf></bsdf>"#, tex("diffuse_reflectance")),
    ];
    let body: String = bsdfs.iter().map(|b| format!("<shape type=\"rectangle\">{b}</shape>\n")).collect();
    let s = load_scene(&write(d.path(), "spec.xml", &format!("{SENSOR}\n{body}"))).unwrap();
    let mut slots: Vec<(u32, Slot)> = s.textures.bindings.iter().map(|b| (b.material, b.slot)).collect();
    slots.sort_by_key(|&(m, slot)| (m, format!("{slot:?}")));
    let (sr, st, dr) = (Slot::SpecularReflectance, Slot::SpecularTransmittance, Slot::DiffuseReflectance);
    let want = [(0, sr), (1, sr), (2, sr), (3, sr), (3, st), (4, st), (5, sr), (5, st), (6, sr), (7, dr), (7, sr)];
    assert_eq!(slots, want);
    assert_eq!(s.textures.textures.len(), 1, "one checkerboard, shared");
}

/// A checkerboard (1 / 0.25) on a smooth gold conductor's `specular_reflectance`, and
/// on a thin pane's `specular_transmittance` (its reflection off), seen face-on under
/// a constant environment: against the untextured BSDF the image keeps every pixel of
/// the `color0` checks bit for bit and is a quarter in the others, in the
/// checkerboard's diagonal pattern with Mitsuba's phase (the rectangle's uv (0, 1)
/// corner, top left in the image, is a `color1` check).
#[test]
fn textured_specular_parameters_change_the_image_where_expected() {
    use crate::config::RenderConfig;
    let d = tempfile::tempdir().unwrap();
    let checker = |name: &str| {
        format!(r#"<texture type="checkerboard" name="{name}"><rgb name="color0" value="1"/><rgb name="color1" value="0.25"/></texture>"#)
    };
    let cases = [
        ("conductor", r#"<string name="material" value="Au"/>"#, checker("specular_reflectance")),
        ("thindielectric", r#"<rgb name="specular_reflectance" value="0"/>"#, checker("specular_transmittance")),
    ];
    for (ty, common, tex) in cases {
        let scene = |extra: &str, name: &str| {
            let body = format!(
                "{SENSOR}\n<shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"10\"/></transform>\
                 <bsdf type=\"{ty}\">{common}{extra}</bsdf></shape>\n<emitter type=\"constant\"/>"
            );
            load_scene(&write(d.path(), name, &body)).unwrap()
        };
        let cfg = RenderConfig { spp: 8, seed: 3, ..Default::default() };
        let render = |s| crate::pipeline::render_scene(s, &cfg, true).unwrap().film;
        let (plain, textured) = (render(scene("", "plain.xml")), render(scene(&tex, "textured.xml")));
        assert_eq!((plain.width, plain.height), (20, 10));
        // The rectangle's uv square maps 2 × 2 checks onto the image's quadrants.
        let (mut full, mut quarter) = (0, 0);
        for y in 0..10 {
            for x in 0..20 {
                let (p, t) = (plain.get(x, y), textured.get(x, y));
                assert!(p.min_element() > 0.2, "{ty} ({x}, {y}): {p}");
                if (x < 10) != (y < 5) {
                    assert_eq!(t, p, "{ty} ({x}, {y})");
                    full += 1;
                } else {
                    assert!((t - p * 0.25).abs().max_element() < 1e-5 * p.max_element(), "{ty} ({x}, {y}): {t} vs {p}");
                    quarter += 1;
                }
            }
        }
        assert_eq!((full, quarter), (100, 100), "{ty}");
    }
}

/// Parameters that cannot take a texture still say so, with file and line.
#[test]
fn textures_on_non_colour_parameters_are_errors_with_file_and_line() {
    let d = tempfile::tempdir().unwrap();
    let cases = [
        (
            "<bsdf type=\"conductor\">\n<texture type=\"checkerboard\" name=\"eta\"/><rgb name=\"k\" value=\"1\"/></bsdf>",
            "a texture on `eta`",
        ),
        ("<bsdf type=\"roughconductor\">\n<texture type=\"checkerboard\" name=\"alpha\"/></bsdf>", "`alpha` must be a <float>"),
        ("<bsdf type=\"roughdielectric\">\n<texture type=\"checkerboard\" name=\"int_ior\"/></bsdf>", "`int_ior` must be"),
    ];
    for (i, (bsdf, needle)) in cases.iter().enumerate() {
        let p = write(d.path(), &format!("t{i}.xml"), &format!("{SENSOR}\n<shape type=\"rectangle\">{bsdf}</shape>"));
        let e = load_scene(&p).unwrap_err().to_string();
        let file_line = format!("{}:7:", p.display());
        assert!(e.starts_with(&file_line) && e.contains(needle), "case {i}: {e}");
    }
}

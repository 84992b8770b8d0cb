//! Tests of the scene TOML reader (`loader.rs`).

use super::*;

#[test]
fn line_col_counts_from_one() {
    assert_eq!(line_col("ab\ncd", 0), (1, 1));
    assert_eq!(line_col("ab\ncd", 4), (2, 2));
}

#[test]
fn override_defaults() {
    let m: OverrideToml = toml::from_str("type = \"glossy\"").unwrap();
    let g = override_material(&m, "x").unwrap();
    assert_eq!(g.bsdf, Bsdf::Glossy(Glossy { kd: Color::splat(0.5), ks: Color::ZERO, exponent: 1.0 }));
    assert!(toml::from_str::<OverrideToml>("type = \"glass\"\nshiny = 1").is_err());
    assert!(toml::from_str::<OverrideToml>("type = \"velvet\"").is_err());
    // Mitsuba's BSDFs with Mitsuba's defaults; bad values name the key.
    let m: OverrideToml = toml::from_str("type = \"roughconductor\"").unwrap();
    let b = override_material(&m, "x").unwrap().bsdf;
    assert!(matches!(b, Bsdf::RoughConductor(ref r) if r.alpha == 0.1 && r.distribution == MicrofacetType::Beckmann));
    let m: OverrideToml = toml::from_str("type = \"roughplastic\"\ndistribution = \"ggx\"\nalpha = 0.3").unwrap();
    assert!(matches!(override_material(&m, "x").unwrap().bsdf, Bsdf::RoughPlastic(ref r) if r.alpha == 0.3));
    let m: OverrideToml = toml::from_str("type = \"roughplastic\"\ndistribution = \"phong\"").unwrap();
    assert!(override_material(&m, "x").unwrap_err().to_string().contains("distribution"));
    let m: OverrideToml = toml::from_str("type = \"roughconductor\"\nalpha = -1.0").unwrap();
    assert!(override_material(&m, "x").unwrap_err().to_string().contains("alpha"));
    assert!(toml::from_str::<OverrideToml>("type = \"plastic\"\nroughness = 1").is_err());
}

/// Parses `text` as a whole document in `dialect`, the description's paths under `d/`.
fn desc(text: &str, dialect: Dialect) -> Result<SceneDesc> {
    let src = TomlSource { file: Path::new("s.toml"), text };
    let doc = DeTable::parse(text).map_err(|e| src.error(&e))?;
    SceneDesc::from_toml(Spanned::new(doc.span(), DeValue::Table(doc.into_inner())), src, Path::new("d"), dialect)
}

const CAM: &str = "[camera]\neye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov_y_deg = 40\n";

#[test]
fn inline_extensions_are_read_and_rejected_in_files() {
    let text = format!(
        "builtin = \"cornell\"\n{CAM}[[mesh]]\nobj = \"m.obj\"\nfit_height = 2\ntranslate = [1, 0, 0]\ndownload = \"https://x\"\n\
         material = {{ type = \"mirror\" }}\n[[light]]\ntype = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\n\
         intensity = [1, 1, 1]\ncone_deg = 20\nfalloff_deg = 30\n"
    );
    let d = desc(&text, Dialect::Inline).unwrap();
    assert_eq!(d.base, Some(SceneBase::Builtin("cornell".into())));
    let c = d.camera.as_ref().unwrap();
    assert_eq!((c.up, c.resolution, c.at.as_str()), (Vec3::Y, None, "s.toml:2: [scene.camera]"));
    let m = &d.meshes[0];
    assert_eq!((m.obj.as_path(), m.fit_height, m.download.as_deref()), (Path::new("d/m.obj"), Some(2.0), Some("https://x")));
    assert_eq!(m.placement.translate, Vec3::X);
    assert_eq!(m.material.as_ref().unwrap().bsdf, Bsdf::Mirror(Mirror { reflectance: Color::ONE }));
    assert!(matches!(d.lights[0], LightDesc::Spot { cone_deg: 20.0, falloff_deg: 30.0, .. }));
    // The same text as a scene file: the first extension is named with its line.
    let e = format!("{:#}", desc(&text, Dialect::File).unwrap_err());
    assert!(e.starts_with("s.toml:1:") && e.contains("`builtin`") && e.contains("manifest"), "{e}");
    let e = format!("{:#}", desc(&text.replacen("builtin = \"cornell\"\n", "", 1), Dialect::File).unwrap_err());
    assert!(e.starts_with("s.toml:1:") && e.contains("resolution"), "{e}");
    let e = format!(
        "{:#}",
        desc(
            &text.replacen("builtin = \"cornell\"\n", "", 1).replace("fov_y_deg = 40\n", "fov_y_deg = 40\nresolution = [4, 4]\n"),
            Dialect::File
        )
        .unwrap_err()
    );
    assert!(e.starts_with("s.toml:8:") && e.contains("fit_height"), "{e}");
}

#[test]
fn inline_errors_name_the_line() {
    let e = |t: &str| format!("{:#}", desc(t, Dialect::Inline).unwrap_err());
    let x = e("[[mesh]]\nobj = \"m.obj\"\n");
    assert!(x.starts_with("s.toml:1:") && x.contains("[scene.camera] is required"), "{x}");
    let x = e(&format!("{CAM}[[mesh]]\nobj = \"m.obj\"\nalbedo = [1, 1, 1]\n"));
    assert!(x.starts_with("s.toml:7:") && x.contains("albedo"), "{x}");
    let x = e(&format!("{CAM}[[mesh]]\nobj = \"m.obj\"\nfit_height = 2\nscale = 3\n"));
    assert!(x.starts_with("s.toml:5:") && x.contains("not both"), "{x}");
    let x = e(&format!("{CAM}[[mesh]]\nobj = \"m.obj\"\nfit_height = -2\n"));
    assert!(x.contains("fit_height must be finite and positive"), "{x}");
    let x = e("builtin = \"cornel\"\n");
    assert!(x.starts_with("s.toml:1:") && x.contains("known: cornell"), "{x}");
    let x = e("builtin = \"cornell\"\nfile = \"a.toml\"\n");
    assert!(x.contains("not both"), "{x}");
    let x = e("builtin = \"cornell\"\n[[light]]\ntype = \"spot\"\nposition = [0, 1, 0]\n");
    assert!(x.starts_with("s.toml:2:") && x.contains("direction"), "{x}");
    let x = e(
        "builtin = \"cornell\"\n[[light]]\ntype = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, 0, 0]\nintensity = [1, 1, 1]\ncone_deg = 20\nfalloff_deg = 30\n",
    );
    assert!(x.starts_with("s.toml:2: [[scene.light]] 1") && x.contains("direction must not be zero"), "{x}");
    let x = e("builtin = \"cornell\"\n[camera]\neye = [0, 1, 0]\nlook_at = [0, 1, 0]\nfov_y_deg = 40\n");
    assert!(x.starts_with("s.toml:2: [scene.camera]") && x.contains("coincide"), "{x}");
}

#[test]
fn builds_on_a_builtin_base() {
    let d =
        desc("builtin = \"cornell\"\n[[light]]\ntype = \"point\"\nposition = [278, 500, 280]\nintensity = [1, 1, 1]\n", Dialect::Inline)
            .unwrap();
    let s = d.build("ignored", Some([8, 8])).unwrap();
    let plain = builtin("cornell").unwrap();
    assert_eq!((s.name.as_str(), s.triangles.len()), ("cornell", plain.triangles.len()));
    assert_eq!(s.lights.len(), plain.lights.len() + 1);
    // The base scene's camera is kept (resolution and all) when none is given.
    assert_eq!(format!("{:?}", s.camera), format!("{:?}", plain.camera));
}

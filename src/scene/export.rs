//! Writes a scene as TOML + OBJ/MTL following the scene contract, so that any tool
//! that follows `scene-format.md` renders the same scene, and [`super::loader`] reads
//! back identical triangles, materials, camera and lights.
//!
//! * Triangles are written with their placed coordinates (no placement in the TOML),
//!   in scene order, with `vn` where the scene has vertex normals.
//! * Each material is written as the MTL lines that the contract's table maps back to
//!   the same material: Lambertian `Kd`; emitter `Ke` + `Kd`; mirror `illum 5` + `Ks`;
//!   glass `illum 7` + `Ni` + `Tf`; glossy `Kd` `Ks` `Ns`. Materials MTL cannot express
//!   (a glossy exponent <= 1 or zero `Ks`, a black mirror, glass with index <= 1) go to
//!   separate OBJ files whose `[[mesh]]` carries a `material = { type = … }` override.
//!   Consecutive triangles that go to the same place form one OBJ file, so triangle
//!   order is kept: `<name>.obj`, then `<name>-1.obj`, … when overrides are needed.
//! * Floats are printed in Rust's shortest round-trip form, so every `f32` reads back
//!   bit-identical (TOML floats always carry a `.` or an exponent).
//! * MTL material names are the scene's, with whitespace and `#` replaced by `_` and a
//!   `-N` suffix where two different materials share a name.

use super::LightDesc;
use super::{NO_NORMALS, Scene};
use crate::material::{Bsdf, Material};
use anyhow::{Context, Result, bail};
use glam::Vec3;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Where a material's triangles go.
#[derive(Clone, Debug, PartialEq)]
enum Target {
    /// An OBJ that uses MTL material `name`.
    Mtl(String),
    /// An OBJ whose `[[mesh]]` has this inline override.
    Override(String),
}

/// A TOML float: shortest round-trip digits, always with `.` or an exponent.
fn tf(x: f32) -> String {
    format!("{x:?}")
}

fn tv(v: Vec3) -> String {
    format!("[{}, {}, {}]", tf(v.x), tf(v.y), tf(v.z))
}

/// OBJ/MTL numbers: shortest round-trip digits, no exponent.
fn ov(v: Vec3) -> String {
    format!("{} {} {}", v.x, v.y, v.z)
}

/// A TOML basic string.
fn tstr(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// File-name-safe version of the scene name.
fn file_stem(name: &str) -> String {
    let s: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') { c } else { '_' }).collect();
    if s.is_empty() || s.starts_with('.') { format!("scene{s}") } else { s }
}

/// MTL-safe material name (one token, no comment character).
fn mtl_name(name: &str) -> String {
    let s: String = name.chars().map(|c| if c.is_whitespace() || c.is_control() || c == '#' { '_' } else { c }).collect();
    if s.is_empty() { "material".into() } else { s }
}

fn check_colour(c: Vec3, what: &str, m: &Material) -> Result<()> {
    if !c.is_finite() || c.min_element() < 0.0 {
        bail!("material `{}`: {what} {:?} is negative or not finite and cannot be written", m.name, c.to_array());
    }
    Ok(())
}

/// How a material is written.
#[derive(Debug)]
enum Written {
    /// MTL body lines (after `newmtl`).
    Mtl(String),
    /// Inline TOML override, for materials MTL cannot express.
    Override(String),
}

/// How to write a material; an error when the contract cannot express it at all.
fn material_lines(m: &Material) -> Result<Written> {
    check_colour(m.emission, "emission", m)?;
    if m.is_emitter() {
        let Bsdf::Lambertian(l) = &m.bsdf else {
            bail!("material `{}` emits but does not reflect diffusely; the scene contract cannot express it", m.name);
        };
        check_colour(l.albedo, "albedo", m)?;
        return Ok(Written::Mtl(format!("illum 2\nKd {}\nKe {}\n", ov(l.albedo), ov(m.emission))));
    }
    Ok(match &m.bsdf {
        Bsdf::Lambertian(l) => {
            check_colour(l.albedo, "albedo", m)?;
            Written::Mtl(format!("illum 2\nKd {}\n", ov(l.albedo)))
        }
        Bsdf::Mirror(r) => {
            check_colour(r.reflectance, "reflectance", m)?;
            if r.reflectance == Vec3::ZERO {
                Written::Override(format!("{{ type = \"mirror\", reflectance = {} }}", tv(r.reflectance)))
            } else {
                Written::Mtl(format!("illum 5\nKs {}\n", ov(r.reflectance)))
            }
        }
        Bsdf::Dielectric(d) => {
            check_colour(d.tint, "tint", m)?;
            if !(d.ior.is_finite() && d.ior > 0.0) {
                bail!("material `{}`: index of refraction {} cannot be written", m.name, d.ior);
            }
            if d.specular_reflectance != Vec3::ONE {
                bail!("material `{}`: a dielectric's specular_reflectance other than 1 cannot be written in the scene contract", m.name);
            }
            if d.ior > 1.0 {
                Written::Mtl(format!("illum 7\nNi {}\nTf {}\n", d.ior, ov(d.tint)))
            } else {
                Written::Override(format!("{{ type = \"glass\", ior = {}, tint = {} }}", tf(d.ior), tv(d.tint)))
            }
        }
        Bsdf::Glossy(g) => {
            check_colour(g.kd, "kd", m)?;
            check_colour(g.ks, "ks", m)?;
            if !(g.exponent.is_finite() && g.exponent >= 0.0) {
                bail!("material `{}`: glossy exponent {} cannot be written", m.name, g.exponent);
            }
            if g.ks.max_element() > 0.0 && g.exponent > 1.0 {
                Written::Mtl(format!("illum 2\nKd {}\nKs {}\nNs {}\n", ov(g.kd), ov(g.ks), g.exponent))
            } else {
                Written::Override(format!("{{ type = \"glossy\", kd = {}, ks = {}, ns = {} }}", tv(g.kd), tv(g.ks), tf(g.exponent)))
            }
        }
        other => bail!("material `{}`: {} cannot be written in the scene contract", m.name, other.kind_name()),
    })
}

/// One output OBJ: a run of consecutive triangles with the same target kind.
struct Run {
    /// `None` for MTL-material runs, else the override text.
    override_text: Option<String>,
    tris: Vec<usize>,
}

/// Writes `DIR/<name>.toml`, `DIR/<name>.obj` (plus `DIR/<name>-N.obj` when overrides
/// are needed) and `DIR/<name>.mtl`; returns the TOML path.
pub fn export_scene(scene: &Scene, dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create directory", dir.display()))?;
    let stem = file_stem(&scene.name);

    // Targets of the materials triangles use, and the MTL file text.
    let mut targets: HashMap<u32, Target> = HashMap::new();
    let mut mtl = format!("# {} (photonlab export, scene-format.md)\n", scene.name);
    let mut written: Vec<(String, Material)> = Vec::new();
    for &mi in &scene.tri_material {
        if targets.contains_key(&mi) {
            continue;
        }
        let m = scene.materials.get(mi as usize).context("triangle refers to a missing material")?;
        let t = match material_lines(m)? {
            Written::Mtl(body) => {
                let base = mtl_name(&m.name);
                let same = |w: &Material| w.bsdf == m.bsdf && w.emission == m.emission;
                let name = match written.iter().find(|(n, w)| *n == base && same(w)) {
                    Some((n, _)) => n.clone(),
                    None => {
                        let mut name = base.clone();
                        let mut k = 2;
                        while written.iter().any(|(n, _)| *n == name) {
                            name = format!("{base}-{k}");
                            k += 1;
                        }
                        let _ = write!(mtl, "\nnewmtl {name}\n{body}");
                        written.push((name.clone(), m.clone()));
                        name
                    }
                };
                Target::Mtl(name)
            }
            Written::Override(o) => Target::Override(o),
        };
        targets.insert(mi, t);
    }

    // Runs of consecutive triangles with the same destination.
    let mut runs: Vec<Run> = Vec::new();
    for (i, mi) in scene.tri_material.iter().enumerate() {
        let over = match &targets[mi] {
            Target::Mtl(_) => None,
            Target::Override(o) => Some(o.clone()),
        };
        match runs.last_mut() {
            Some(r) if r.override_text == over => r.tris.push(i),
            _ => runs.push(Run { override_text: over, tris: vec![i] }),
        }
    }

    let mtl_file = format!("{stem}.mtl");
    std::fs::write(dir.join(&mtl_file), mtl).with_context(|| format!("{}: cannot write", dir.join(&mtl_file).display()))?;

    let mut toml = format!("# {} (photonlab export; see scene-format.md)\n\n[camera]\n", scene.name);
    let c = &scene.camera;
    let _ = writeln!(toml, "eye = {}\nlook_at = {}\nup = {}", tv(c.eye), tv(c.look_at), tv(c.up));
    let _ = writeln!(toml, "fov_y_deg = {}\nresolution = [{}, {}]", tf(c.fov_y_deg), c.width, c.height);

    if runs.is_empty() {
        runs.push(Run { override_text: None, tris: Vec::new() });
    }
    for (k, run) in runs.iter().enumerate() {
        let obj_file = if k == 0 { format!("{stem}.obj") } else { format!("{stem}-{k}.obj") };
        let text = obj_text(scene, run, &targets, &mtl_file);
        let p = dir.join(&obj_file);
        std::fs::write(&p, text).with_context(|| format!("{}: cannot write", p.display()))?;
        let _ = write!(toml, "\n[[mesh]]\nobj = {}\n", tstr(&obj_file));
        if let Some(o) = &run.override_text {
            let _ = writeln!(toml, "material = {o}");
        }
    }

    if let Some(l) = scene.lights.iter().find(|l| matches!(l, LightDesc::Constant { .. } | LightDesc::Envmap { .. })) {
        anyhow::bail!(
            "the scene contract has no environment lights; cannot export {}",
            if matches!(l, LightDesc::Constant { .. }) { "a constant environment" } else { "an environment map" }
        );
    }
    for l in &scene.lights {
        toml.push_str("\n[[light]]\n");
        let _ = match l {
            LightDesc::Point { position, intensity } => {
                writeln!(toml, "type = \"point\"\nposition = {}\nintensity = {}", tv(*position), tv(*intensity))
            }
            LightDesc::Spot { position, direction, intensity, cone_deg, falloff_deg } => writeln!(
                toml,
                "type = \"spot\"\nposition = {}\ndirection = {}\nintensity = {}\ncone_deg = {}\nfalloff_deg = {}",
                tv(*position),
                tv(*direction),
                tv(*intensity),
                tf(*cone_deg),
                tf(*falloff_deg)
            ),
            LightDesc::Directional { direction, irradiance } => {
                writeln!(toml, "type = \"directional\"\ndirection = {}\nirradiance = {}", tv(*direction), tv(*irradiance))
            }
            LightDesc::Constant { .. } | LightDesc::Envmap { .. } => Ok(()), // rejected above
        };
    }
    let toml_path = dir.join(format!("{stem}.toml"));
    std::fs::write(&toml_path, toml).with_context(|| format!("{}: cannot write", toml_path.display()))?;
    Ok(toml_path)
}

/// The OBJ text of one run: deduplicated `v`/`vn`, `usemtl` switches, faces.
fn obj_text(scene: &Scene, run: &Run, targets: &HashMap<u32, Target>, mtl_file: &str) -> String {
    let mut s = format!("# {} (photonlab export)\n", scene.name);
    if run.override_text.is_none() {
        let _ = writeln!(s, "mtllib {mtl_file}");
    }
    let mut verts: HashMap<[u32; 3], usize> = HashMap::new();
    let mut norms: HashMap<[u32; 3], usize> = HashMap::new();
    let mut vtext = String::new();
    let mut ntext = String::new();
    let mut ftext = String::new();
    let mut current: Option<&str> = None;
    let key = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    for &t in &run.tris {
        let mut vi = [0usize; 3];
        for (k, p) in scene.triangles[t].iter().enumerate() {
            let n = verts.len();
            vi[k] = *verts.entry(key(*p)).or_insert_with(|| {
                let _ = writeln!(vtext, "v {}", ov(*p));
                n + 1
            });
        }
        let ni = scene.tri_normals[t];
        let nidx = (ni != NO_NORMALS).then(|| {
            let mut out = [0usize; 3];
            for (k, n) in scene.normals[ni as usize].iter().enumerate() {
                let c = norms.len();
                out[k] = *norms.entry(key(*n)).or_insert_with(|| {
                    let _ = writeln!(ntext, "vn {}", ov(*n));
                    c + 1
                });
            }
            out
        });
        if let Target::Mtl(name) = &targets[&scene.tri_material[t]]
            && current != Some(name.as_str())
        {
            let _ = writeln!(ftext, "usemtl {name}");
            current = Some(name.as_str());
        }
        let _ = match nidx {
            Some(n) => writeln!(ftext, "f {}//{} {}//{} {}//{}", vi[0], n[0], vi[1], n[1], vi[2], n[2]),
            None => writeln!(ftext, "f {} {} {}", vi[0], vi[1], vi[2]),
        };
    }
    s.push_str(&vtext);
    s.push_str(&ntext);
    s.push_str(&ftext);
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{Dielectric, Glossy, Mirror};
    use crate::math::Color;

    #[test]
    fn unexpressible_materials_need_overrides() {
        let g = |ks: f32, e: f32| Material {
            bsdf: Bsdf::Glossy(Glossy { kd: Color::splat(0.2), ks: Color::splat(ks), exponent: e }),
            ..Material::diffuse("g", Color::ZERO)
        };
        assert!(matches!(material_lines(&g(0.5, 10.0)).unwrap(), Written::Mtl(_)));
        assert!(matches!(material_lines(&g(0.5, 1.0)).unwrap(), Written::Override(_)));
        assert!(matches!(material_lines(&g(0.0, 10.0)).unwrap(), Written::Override(_)));
        let mirror = Material { bsdf: Bsdf::Mirror(Mirror { reflectance: Color::ZERO }), ..Material::diffuse("m", Color::ZERO) };
        assert!(matches!(material_lines(&mirror).unwrap(), Written::Override(_)));
        let glass = Material { bsdf: Bsdf::Dielectric(Dielectric::new(1.0, Color::ONE)), ..Material::diffuse("m", Color::ZERO) };
        assert!(matches!(material_lines(&glass).unwrap(), Written::Override(_)));
        let bad = Material { emission: Color::ONE, ..mirror };
        assert!(material_lines(&bad).is_err());
        assert_eq!(mtl_name("a b#c"), "a_b_c");
        assert_eq!(file_stem("x/y"), "x_y");
    }
}

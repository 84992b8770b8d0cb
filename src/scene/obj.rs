//! Wavefront OBJ and MTL reading per `scene-format.md`.
//!
//! Our own parser rather than `tobj`: errors must name `file:line`, and malformed
//! input (short colour lines, NaN coordinates, bad indices) must be an error, never a
//! panic. What is read:
//!
//! * OBJ: `v` (extra w / colour components ignored), `vn`, `vt` (ignored), `f` with
//!   `a`, `a/b`, `a/b/c`, `a//c` and negative (relative) indices, polygons
//!   fan-triangulated as (0,1,2), (0,2,3), …; `usemtl`; `mtllib` (relative to the OBJ,
//!   several allowed). `o`, `g`, `s` and every other statement are ignored.
//! * MTL: `newmtl`, `Kd`, `Ks`, `Ke`, `Tf` (a single number means grey; `xyz` form
//!   converted, `spectral` form ignored with a warning), `Ns`, `Ni`, `d`, `Tr`, `illum`;
//!   everything else is ignored. Each entry becomes a [`Material`] by the contract's
//!   table ([`mtl_to_material`]).
//!
//! Text after `#` is a comment everywhere, so trailing comments on value lines work.
//! Lines may end in CRLF; fields may be separated by tabs.

use super::{Face, MeshData, MeshUvs};
use crate::material::{Bsdf, Dielectric, Glossy, Material, Mirror};
use crate::math::Color;
use anyhow::{Result, anyhow, bail};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Name of the material used for faces before any `usemtl` (and for undefined names'
/// fallback): the contract's default, Lambertian 0.5 grey.
pub const DEFAULT_MATERIAL: &str = "default";

/// The contract's default material: Lambertian with albedo 0.5.
pub fn default_material(name: &str) -> Material {
    Material::diffuse(name, Color::splat(0.5))
}

/// An OBJ file read into a mesh, with the non-fatal remarks made while reading it.
#[derive(Clone, Debug, Default)]
pub struct ObjFile {
    /// The mesh: `materials` holds the materials its faces use, in order of first use.
    pub mesh: MeshData,
    /// Texture coordinates (`vt`, v flipped to Mitsuba's top-down texture space);
    /// `uvs.faces` is parallel to `mesh.faces`.
    pub uvs: MeshUvs,
    /// Texture maps of the materials (`map_Kd`, `map_d`), parallel to `mesh.materials`.
    pub maps: Vec<MtlMaps>,
    /// Warnings, each prefixed with `file:line`.
    pub warnings: Vec<String>,
}

/// One `newmtl` entry as written in the MTL file (absent statements are `None`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MtlEntry {
    /// Diffuse colour `Kd`.
    pub kd: Option<Color>,
    /// Specular colour `Ks`.
    pub ks: Option<Color>,
    /// Emission `Ke`.
    pub ke: Option<Color>,
    /// Transmission filter `Tf`.
    pub tf: Option<Color>,
    /// Phong exponent `Ns`.
    pub ns: Option<f32>,
    /// Index of refraction `Ni`.
    pub ni: Option<f32>,
    /// Dissolve `d`.
    pub d: Option<f32>,
    /// Transparency `Tr`.
    pub tr: Option<f32>,
    /// Illumination model `illum`.
    pub illum: Option<i64>,
    /// Diffuse texture `map_Kd` (path as written, relative to the MTL file).
    pub map_kd: Option<PathBuf>,
    /// Opacity texture `map_d`.
    pub map_d: Option<PathBuf>,
}

/// The texture maps of one OBJ material slot (paths resolved against the MTL's folder).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MtlMaps {
    /// `map_Kd`.
    pub kd: Option<PathBuf>,
    /// `map_d`.
    pub d: Option<PathBuf>,
}

/// A parsed MTL file: entries in file order, and warnings.
#[derive(Clone, Debug, Default)]
pub struct MtlLibrary {
    /// `(name, entry)` in the order of their `newmtl` lines.
    pub entries: Vec<(String, MtlEntry)>,
    /// Warnings, each prefixed with `file:line`.
    pub warnings: Vec<String>,
}

/// True when any channel is positive.
fn any_positive(c: Color) -> bool {
    c.max_element() > 0.0
}

/// Maps an MTL entry to a material by the contract's table, first matching rule wins:
/// emitter (`Ke` > 0) → dielectric (`illum` 4/6/7, `d` < 1, `Tr` > 0) → mirror
/// (`illum` 3/5) → glossy (`Ks` > 0 and `Ns` > 1) → Lambertian.
pub fn mtl_to_material(name: &str, e: &MtlEntry) -> Material {
    let kd = e.kd.unwrap_or(Color::splat(0.5));
    let mut m = default_material(name);
    if let Some(ke) = e.ke.filter(|&k| any_positive(k)) {
        m.bsdf = Bsdf::Lambertian(crate::material::Lambertian { albedo: kd });
        m.emission = ke;
        return m;
    }
    let illum = e.illum.unwrap_or(-1);
    if matches!(illum, 4 | 6 | 7) || e.d.is_some_and(|d| d < 1.0) || e.tr.is_some_and(|t| t > 0.0) {
        let ior = e.ni.filter(|&n| n > 1.0).unwrap_or(1.5);
        m.bsdf = Bsdf::Dielectric(Dielectric::new(ior, e.tf.unwrap_or(Color::ONE)));
        return m;
    }
    if matches!(illum, 3 | 5) {
        let reflectance = e.ks.filter(|&k| k != Color::ZERO).unwrap_or(Color::ONE);
        m.bsdf = Bsdf::Mirror(Mirror { reflectance });
        return m;
    }
    if let (Some(ks), Some(ns)) = (e.ks, e.ns)
        && any_positive(ks)
        && ns > 1.0
    {
        m.bsdf = Bsdf::Glossy(Glossy { kd, ks, exponent: ns });
        return m;
    }
    m.bsdf = Bsdf::Lambertian(crate::material::Lambertian { albedo: kd });
    m
}

/// Reads a text file; invalid UTF-8 (e.g. Latin-1 comments) is replaced, not fatal.
fn read_text(path: &Path) -> std::io::Result<String> {
    let bytes = std::fs::read(path)?;
    Ok(match String::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
    })
}

/// Splits a line into its statement keyword and argument tokens, dropping a `#` comment.
fn tokens(line: &str) -> Option<(&str, Vec<&str>)> {
    let body = line.split('#').next().unwrap_or("");
    let mut it = body.split_whitespace();
    let kw = it.next()?;
    Some((kw, it.collect()))
}

/// The text after the keyword (comment removed, trimmed): names may contain spaces.
fn rest_of_line<'a>(line: &'a str, kw: &str) -> &'a str {
    let body = line.split('#').next().unwrap_or("").trim_start();
    body.strip_prefix(kw).unwrap_or("").trim()
}

/// Parses a finite float; `what` names the field in the message.
fn parse_f32(tok: &str, what: &str) -> anyhow::Result<f32> {
    match tok.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(anyhow::anyhow!("{what} `{tok}` is not finite")),
        Err(_) => Err(anyhow::anyhow!("{what}: cannot parse `{tok}` as a number")),
    }
}

/// Converts CIE XYZ to linear RGB (sRGB primaries), with each row scaled so that an
/// equal-energy XYZ (x = y = z, the form a single `xyz` value takes) stays neutral
/// grey; negative results (out of gamut) are clamped to zero.
pub fn xyz_to_rgb(xyz: Vec3) -> Color {
    const M: [[f32; 3]; 3] =
        [[3.240_454_2, -1.537_138_5, -0.498_531_4], [-0.969_266, 1.876_010_8, 0.041_556], [0.055_643_4, -0.204_025_9, 1.057_225_2]];
    let row = |r: [f32; 3]| (r[0] * xyz.x + r[1] * xyz.y + r[2] * xyz.z) / (r[0] + r[1] + r[2]);
    Color::new(row(M[0]), row(M[1]), row(M[2])).max(Color::ZERO)
}

/// Parses an MTL file's text. `path` is used in messages only.
pub fn parse_mtl(text: &str, path: &Path) -> Result<MtlLibrary> {
    let file = path.display();
    let mut lib = MtlLibrary::default();
    let mut current: Option<(String, MtlEntry)> = None;
    let mut warned_orphan = false;
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let Some((kw, args)) = tokens(line) else { continue };
        let err = |msg: anyhow::Error| anyhow!("{file}:{ln}: {msg}");
        if kw == "newmtl" {
            let name = rest_of_line(line, kw);
            if name.is_empty() {
                return Err(err(anyhow!("`newmtl` without a material name")));
            }
            if let Some(done) = current.take() {
                lib.entries.push(done);
            }
            current = Some((name.to_string(), MtlEntry::default()));
            continue;
        }
        let known = matches!(kw, "Kd" | "Ks" | "Ke" | "Tf" | "Ns" | "Ni" | "d" | "Tr" | "illum" | "map_Kd" | "map_d");
        if !known {
            continue;
        }
        let Some((_, entry)) = current.as_mut() else {
            if !warned_orphan {
                lib.warnings.push(format!("{file}:{ln}: `{kw}` before any `newmtl` is ignored"));
                warned_orphan = true;
            }
            continue;
        };
        match kw {
            "map_Kd" | "map_d" => {
                let rest = rest_of_line(line, kw);
                // Options (`-s 1 1 1`, `-clamp on`, …) are not supported: the file is
                // the last token then.
                let name = if rest.starts_with('-') {
                    lib.warnings.push(format!("{file}:{ln}: `{kw}` options are ignored"));
                    args.last().copied().unwrap_or("")
                } else {
                    rest
                };
                if name.is_empty() {
                    return Err(err(anyhow!("`{kw}` without a file name")));
                }
                let dir = path.parent().unwrap_or(Path::new(""));
                let slot = if kw == "map_Kd" { &mut entry.map_kd } else { &mut entry.map_d };
                *slot = Some(dir.join(name.replace('\\', "/")));
            }
            "Kd" | "Ks" | "Ke" | "Tf" => {
                let c = match args.first().copied() {
                    Some("spectral") => {
                        lib.warnings.push(format!("{file}:{ln}: `{kw} spectral` is not supported; statement ignored"));
                        continue;
                    }
                    Some("xyz") => xyz_to_rgb(parse_colour_numbers(&args[1..], kw).map_err(err)?),
                    _ => parse_colour_numbers(&args, kw).map_err(err)?,
                };
                if c.min_element() < 0.0 {
                    return Err(err(anyhow!("`{kw}` must not be negative, got {:?}", c.to_array())));
                }
                let slot = match kw {
                    "Kd" => &mut entry.kd,
                    "Ks" => &mut entry.ks,
                    "Ke" => &mut entry.ke,
                    _ => &mut entry.tf,
                };
                *slot = Some(c);
            }
            "illum" => {
                let [tok] = args.as_slice() else {
                    return Err(err(anyhow!("`illum` expects one integer, got {} value(s)", args.len())));
                };
                let v = tok.parse::<i64>().map_err(|_| err(anyhow!("`illum`: cannot parse `{tok}` as an integer")))?;
                entry.illum = Some(v);
            }
            _ => {
                // `d -halo 0.5`: the halo flag changes nothing for us.
                let vals: Vec<&str> = if kw == "d" { args.iter().copied().filter(|a| *a != "-halo").collect() } else { args };
                let [tok] = vals.as_slice() else {
                    return Err(err(anyhow!("`{kw}` expects one number, got {} value(s)", vals.len())));
                };
                let v = parse_f32(tok, &format!("`{kw}`")).map_err(err)?;
                let slot = match kw {
                    "Ns" => &mut entry.ns,
                    "Ni" => &mut entry.ni,
                    "d" => &mut entry.d,
                    _ => &mut entry.tr,
                };
                *slot = Some(v);
            }
        }
    }
    if let Some(done) = current.take() {
        lib.entries.push(done);
    }
    Ok(lib)
}

/// One number (grey) or three numbers (RGB).
fn parse_colour_numbers(args: &[&str], kw: &str) -> anyhow::Result<Vec3> {
    let what = format!("`{kw}`");
    match args {
        [g] => Ok(Vec3::splat(parse_f32(g, &what)?)),
        [r, g, b] => Ok(Vec3::new(parse_f32(r, &what)?, parse_f32(g, &what)?, parse_f32(b, &what)?)),
        _ => Err(anyhow::anyhow!("{what} expects 1 or 3 numbers, got {}", args.len())),
    }
}

/// Reads and parses an MTL file.
pub fn load_mtl(path: &Path) -> Result<MtlLibrary> {
    let text = read_text(path).map_err(|e| anyhow!("{}: cannot read material library: {e}", path.display()))?;
    parse_mtl(&text, path)
}

/// Reads an OBJ file and the MTL libraries it names.
pub fn load_obj(path: &Path) -> Result<ObjFile> {
    let text = read_text(path).map_err(|e| anyhow!("{}: cannot read OBJ file: {e}", path.display()))?;
    parse_obj(&text, path)
}

/// A face corner's vertex reference as written: resolved position and normal index.
struct Corner {
    v: i64,
    t: Option<i64>,
    n: Option<i64>,
}

/// Parses one `a`, `a/b`, `a/b/c` or `a//c` corner. Negative indices count back from
/// the current number of elements; positive ones are checked once the file is read.
fn parse_corner(tok: &str, nv: usize, nvt: usize, nvn: usize) -> anyhow::Result<Corner> {
    let parts: Vec<&str> = tok.split('/').collect();
    if parts.len() > 3 || parts[0].is_empty() {
        return Err(anyhow::anyhow!("malformed face vertex `{tok}`"));
    }
    let index = |s: &str, count: usize, what: &str| -> anyhow::Result<i64> {
        let i = s.parse::<i64>().map_err(|_| anyhow::anyhow!("face vertex `{tok}`: cannot parse {what} index `{s}`"))?;
        match i {
            0 => Err(anyhow::anyhow!("face vertex `{tok}`: {what} index 0 is invalid (OBJ indices start at 1)")),
            i if i > 0 => Ok(i - 1),
            i => {
                let r = count as i64 + i;
                if r < 0 {
                    Err(anyhow::anyhow!("face vertex `{tok}`: relative {what} index {i} is out of range ({count} defined)"))
                } else {
                    Ok(r)
                }
            }
        }
    };
    let v = index(parts[0], nv, "vertex")?;
    let t = match parts.get(1).filter(|s| !s.is_empty()) {
        Some(t) => Some(index(t, nvt, "texture")?),
        None => None,
    };
    let n = match parts.get(2).filter(|s| !s.is_empty()) {
        Some(s) => Some(index(s, nvn, "normal")?),
        None => None,
    };
    Ok(Corner { v, t, n })
}

/// Parses an OBJ file's text; `path` locates `mtllib` files and names messages.
pub fn parse_obj(text: &str, path: &Path) -> Result<ObjFile> {
    parse_obj_with(text, path, true)
}

/// Reads an OBJ file's geometry only (`mtllib` is not opened: Mitsuba's `obj` shape
/// takes its material from the scene).
pub fn load_obj_geometry(path: &Path) -> Result<ObjFile> {
    let text = read_text(path).map_err(|e| anyhow!("{}: cannot read OBJ file: {e}", path.display()))?;
    parse_obj_with(&text, path, false)
}

fn parse_obj_with(text: &str, path: &Path, read_mtl: bool) -> Result<ObjFile> {
    let file = path.display();
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut out = ObjFile::default();
    let mut nvt = 0usize;
    // Material "slots" in order of first use; `None` is the default material. Names
    // are resolved after the whole file is read, so `mtllib` may come anywhere.
    let mut slots: Vec<(Option<String>, usize)> = Vec::new();
    let mut current: Option<u32> = None;
    let mut libraries: Vec<(PathBuf, MtlLibrary)> = Vec::new();
    let mut partial_normals_line = None;
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let Some((kw, args)) = tokens(line) else { continue };
        let err = |msg: anyhow::Error| anyhow!("{file}:{ln}: {msg}");
        match kw {
            "v" | "vn" => {
                if args.len() < 3 {
                    return Err(err(anyhow!("`{kw}` needs 3 coordinates, got {}", args.len())));
                }
                let what = if kw == "v" { "vertex coordinate" } else { "normal component" };
                let mut c = [0.0f32; 3];
                for (k, a) in args[..3].iter().enumerate() {
                    c[k] = parse_f32(a, what).map_err(err)?;
                }
                if kw == "v" { &mut out.mesh.positions } else { &mut out.mesh.normals }.push(Vec3::from_array(c));
            }
            "vt" => {
                nvt += 1;
                // `vt u [v [w]]`; Mitsuba's texture space has v downwards.
                let u = args.first().map(|a| parse_f32(a, "texture coordinate")).transpose().map_err(err)?.unwrap_or(0.0);
                let v = args.get(1).map(|a| parse_f32(a, "texture coordinate")).transpose().map_err(err)?.unwrap_or(0.0);
                out.uvs.uvs.push(Vec2::new(u, 1.0 - v));
            }
            "f" => {
                if args.len() < 3 {
                    return Err(err(anyhow!("face needs at least 3 vertices, got {}", args.len())));
                }
                let (nv, nvn) = (out.mesh.positions.len(), out.mesh.normals.len());
                let corners: Vec<Corner> =
                    args.iter().map(|t| parse_corner(t, nv, nvt, nvn)).collect::<anyhow::Result<_>>().map_err(err)?;
                let with_normals = corners.iter().filter(|c| c.n.is_some()).count();
                if with_normals != 0 && with_normals != corners.len() && partial_normals_line.is_none() {
                    partial_normals_line = Some(ln);
                }
                let slot = match current {
                    Some(s) => s,
                    None => {
                        let s = slot_index(&mut slots, None, ln);
                        current = Some(s);
                        s
                    }
                };
                let line_no = u32::try_from(ln).unwrap_or(u32::MAX);
                let idx = |x: i64| u32::try_from(x).unwrap_or(u32::MAX);
                for k in 1..corners.len() - 1 {
                    let tri = [&corners[0], &corners[k], &corners[k + 1]];
                    let n = match (tri[0].n, tri[1].n, tri[2].n) {
                        (Some(a), Some(b), Some(c)) => Some([idx(a), idx(b), idx(c)]),
                        _ => None,
                    };
                    let t = match (tri[0].t, tri[1].t, tri[2].t) {
                        (Some(a), Some(b), Some(c)) => Some([idx(a), idx(b), idx(c)]),
                        _ => None,
                    };
                    out.mesh.faces.push(Face { v: [idx(tri[0].v), idx(tri[1].v), idx(tri[2].v)], n, material: slot, line: line_no });
                    out.uvs.faces.push(t);
                }
            }
            "usemtl" => {
                let name = rest_of_line(line, kw);
                let name = if name.is_empty() { None } else { Some(name.to_string()) };
                current = Some(slot_index(&mut slots, name, ln));
            }
            "mtllib" if !read_mtl => {}
            "mtllib" => {
                let rest = rest_of_line(line, kw);
                if rest.is_empty() {
                    return Err(err(anyhow!("`mtllib` without a file name")));
                }
                // The whole rest may be one file name with spaces; otherwise it is a
                // whitespace-separated list, as the OBJ specification has it.
                let names: Vec<&str> = if dir.join(rest).is_file() { vec![rest] } else { args.clone() };
                for name in names {
                    let p = dir.join(name);
                    if libraries.iter().any(|(q, _)| *q == p) {
                        continue;
                    }
                    if !p.is_file() {
                        return Err(err(anyhow!("material library {} not found", p.display())));
                    }
                    let lib = load_mtl(&p).map_err(|e| anyhow!("{file}:{ln}: mtllib: {e}"))?;
                    libraries.push((p, lib));
                }
            }
            _ => {} // o, g, s, vp, l, p, … carry nothing we render.
        }
    }
    if let Some(ln) = partial_normals_line {
        out.warnings.push(format!("{file}:{ln}: some faces give normals for only some corners; those use the geometric normal"));
    }
    // Index range checks (positive indices may legally refer forward).
    let (nv, nn) = (out.mesh.positions.len(), out.mesh.normals.len());
    for f in &out.mesh.faces {
        if let Some(&bad) = f.v.iter().find(|&&v| v as usize >= nv) {
            bail!("{file}:{}: vertex index {} is out of range ({nv} vertices defined)", f.line, bad as u64 + 1);
        }
        if let Some(&bad) = f.n.iter().flatten().find(|&&v| v as usize >= nn) {
            bail!("{file}:{}: normal index {} is out of range ({nn} normals defined)", f.line, bad as u64 + 1);
        }
    }
    // Texture coordinates are optional: a face whose `vt` indices do not exist keeps
    // its geometry and loses its texture coordinates (reported once).
    let nt = out.uvs.uvs.len();
    let mut bad_vt = None;
    for (f, t) in out.mesh.faces.iter().zip(out.uvs.faces.iter_mut()) {
        if t.iter().flatten().any(|&v| v as usize >= nt) {
            bad_vt.get_or_insert(f.line);
            *t = None;
        }
    }
    if let Some(ln) = bad_vt
        && nt > 0
    {
        out.warnings.push(format!(
            "{file}:{ln}: texture coordinate index out of range ({nt} `vt` defined); those faces have no texture coordinates"
        ));
    }
    // Resolve material names: later libraries override earlier ones.
    let mut defined: HashMap<&str, &MtlEntry> = HashMap::new();
    for (_, lib) in &libraries {
        for (name, e) in &lib.entries {
            defined.insert(name.as_str(), e);
        }
        out.warnings.extend(lib.warnings.iter().cloned());
    }
    for (name, ln) in &slots {
        let maps = name.as_ref().and_then(|n| defined.get(n.as_str())).map(|e| MtlMaps { kd: e.map_kd.clone(), d: e.map_d.clone() });
        out.maps.push(maps.unwrap_or_default());
        let m = match name {
            None => default_material(DEFAULT_MATERIAL),
            Some(n) => match defined.get(n.as_str()) {
                Some(e) => mtl_to_material(n, e),
                None => {
                    out.warnings
                        .push(format!("{file}:{ln}: material `{n}` is not defined in any mtllib; using the default (Lambertian 0.5 grey)"));
                    default_material(n)
                }
            },
        };
        out.mesh.materials.push(m);
    }
    Ok(out)
}

/// Index of the slot for `name`, adding it (with the line of first use) if new.
fn slot_index(slots: &mut Vec<(Option<String>, usize)>, name: Option<String>, ln: usize) -> u32 {
    match slots.iter().position(|(n, _)| *n == name) {
        Some(i) => i as u32,
        None => {
            slots.push((name, ln));
            (slots.len() - 1) as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mtl(text: &str) -> Vec<Material> {
        let lib = parse_mtl(text, Path::new("t.mtl")).unwrap();
        lib.entries.iter().map(|(n, e)| mtl_to_material(n, e)).collect()
    }

    fn tmpdir(tag: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("photonlab-obj-{tag}-")).tempdir().unwrap()
    }

    #[test]
    fn mtl_rule_order() {
        let m = mtl("newmtl a\nKe 1 0 0\nillum 7\nKd 0.2\n\
                     newmtl b\nd 0.5\nillum 5\n\
                     newmtl c\nillum 3\n\
                     newmtl d\nKs 0.5 0 0\nNs 1\nKd 0.3 0.3 0.3\n\
                     newmtl e\nKs 0 0 0\nNs 100\n\
                     newmtl f\nTr 0.1\nNi 0.9\nTf 0.2 0.3 0.4\n\
                     newmtl g\nKs 0.2 0.2 0.2 # shiny\nNs 40\nKd 0.1 0.2 0.3\n\
                     newmtl h\nillum 5\nKs 0 0.5 0\n");
        assert_eq!(m[0].emission, Color::new(1.0, 0.0, 0.0));
        assert_eq!(m[0].bsdf, Bsdf::Lambertian(crate::material::Lambertian { albedo: Color::splat(0.2) }));
        assert_eq!(m[1].bsdf, Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE)));
        assert_eq!(m[2].bsdf, Bsdf::Mirror(Mirror { reflectance: Color::ONE }));
        assert_eq!(m[3].bsdf, Bsdf::Lambertian(crate::material::Lambertian { albedo: Color::splat(0.3) }));
        assert_eq!(m[4].bsdf, Bsdf::Lambertian(crate::material::Lambertian { albedo: Color::splat(0.5) }));
        assert_eq!(m[5].bsdf, Bsdf::Dielectric(Dielectric::new(1.5, Color::new(0.2, 0.3, 0.4))));
        assert_eq!(m[6].bsdf, Bsdf::Glossy(Glossy { kd: Color::new(0.1, 0.2, 0.3), ks: Color::splat(0.2), exponent: 40.0 }));
        assert_eq!(m[7].bsdf, Bsdf::Mirror(Mirror { reflectance: Color::new(0.0, 0.5, 0.0) }));
        assert!(m.iter().skip(1).all(|x| !x.is_emitter()));
    }

    #[test]
    fn mtl_errors_and_forms() {
        let e = parse_mtl("newmtl a\n\nKd 0.5 0.5\n", Path::new("x.mtl")).unwrap_err().to_string();
        assert!(e.starts_with("x.mtl:3:") && e.contains("1 or 3"), "{e}");
        let e = parse_mtl("newmtl a\nNs abc\n", Path::new("x.mtl")).unwrap_err().to_string();
        assert!(e.starts_with("x.mtl:2:"), "{e}");
        let e = parse_mtl("newmtl a\nKd nan 0 0\n", Path::new("x.mtl")).unwrap_err().to_string();
        assert!(e.starts_with("x.mtl:2:") && e.contains("not finite"), "{e}");
        let lib = parse_mtl("newmtl a\r\n\tTf spectral glass.rfl 1.0\r\n\tTf xyz 0.8\r\n\td -halo 0.9\r\n", Path::new("x.mtl")).unwrap();
        assert_eq!(lib.warnings.len(), 1);
        let t = lib.entries[0].1.tf.unwrap();
        assert!((t - Color::splat(0.8)).abs().max_element() < 1e-5, "{t}");
        assert_eq!(lib.entries[0].1.d, Some(0.9));
    }

    #[test]
    fn obj_faces_indices_and_materials() {
        let tmp = tmpdir("faces");
        let d = tmp.path();
        std::fs::write(d.join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
        let text = "# quad with relative indices\r\nmtllib m.mtl\r\nv 0 0 0 1\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0 0.5 0.5 0.5\r\n\
                    vn 0 0 1\r\nf -4 -3 -2 -1\r\nusemtl red\r\nf 1//1 2//1 3//1\r\nusemtl nothing\r\nf 1/1 2/1 3/1\r\n";
        let o = parse_obj(text, &d.join("a.obj")).unwrap();
        let m = &o.mesh;
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.faces.len(), 4);
        assert_eq!(m.faces[0].v, [0, 1, 2]);
        assert_eq!(m.faces[1].v, [0, 2, 3]);
        assert_eq!(m.faces[1].line, 8);
        assert_eq!(m.faces[2].n, Some([0, 0, 0]));
        assert_eq!(m.materials.len(), 3);
        assert_eq!(m.materials[m.faces[0].material as usize], default_material(DEFAULT_MATERIAL));
        assert_eq!(m.materials[m.faces[2].material as usize].name, "red");
        assert_eq!(m.materials[m.faces[3].material as usize], default_material("nothing"));
        assert_eq!(o.warnings.len(), 1, "{:?}", o.warnings);
        assert!(o.warnings[0].contains(":11:"), "{:?}", o.warnings);
    }

    #[test]
    fn obj_errors_name_file_and_line() {
        let p = Path::new("bad.obj");
        for (text, line, needle) in [
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "out of range"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, "index 0"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 -5 2\n", 4, "out of range"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "at least 3"),
            ("v 0 0 0\nv 1 x 0\n", 2, "cannot parse"),
            ("v 0 0 0\nv 1 inf 0\n", 2, "not finite"),
            ("v 0 0 NaN\n", 1, "not finite"),
            ("v 0 0\n", 1, "3 coordinates"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", 5, "normal index"),
            ("mtllib nowhere.mtl\n", 1, "nowhere.mtl"),
        ] {
            let e = parse_obj(text, p).unwrap_err().to_string();
            assert!(e.starts_with(&format!("bad.obj:{line}:")) && e.contains(needle), "{text:?} -> {e}");
        }
    }

    #[test]
    fn agrees_with_tobj_on_geometry() {
        let tmp = tmpdir("tobj");
        let d = tmp.path();
        let text = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nv 1 2 0\nf 1 2 3 4\nf -5 -3 -1\nf 4 3 5\n";
        let path = d.join("x.obj");
        std::fs::write(&path, text).unwrap();
        let ours = parse_obj(text, &path).unwrap().mesh;
        let opts = tobj::LoadOptions { triangulate: true, ..Default::default() };
        let (models, _) = tobj::load_obj(&path, &opts).unwrap();
        let idx: Vec<u32> = models.iter().flat_map(|m| m.mesh.indices.iter().copied()).collect();
        let ours_idx: Vec<u32> = ours.faces.iter().flat_map(|f| f.v).collect();
        assert_eq!(idx, ours_idx);
        let pos: Vec<f32> = ours.positions.iter().flat_map(|p| p.to_array()).collect();
        assert_eq!(models[0].mesh.positions, pos);
    }
}

//! Stanford PLY meshes: `ascii 1.0`, `binary_little_endian 1.0` and
//! `binary_big_endian 1.0`.
//!
//! Read: element `vertex` with `x y z` (required), `nx ny nz` and texture
//! coordinates `u v` (also named `s t`, `texture_u texture_v`, `texture_s
//! texture_t`); element `face` with a list property `vertex_indices` (or
//! `vertex_index`), polygons fan-triangulated. Every other property and element is
//! skipped (named in a warning). Texture coordinates are used as given (Mitsuba's PLY
//! reader does not flip v). Errors name the file and the line (ASCII) or byte offset
//! (binary).

use super::{Face, MeshData, MeshUvs};
use anyhow::{Result, anyhow, bail};
use glam::{Vec2, Vec3};
use std::path::Path;

/// A PLY mesh with its texture coordinates and remarks.
#[derive(Clone, Debug, Default)]
pub struct PlyMesh {
    /// Positions, normals (per vertex, when given) and faces (material 0).
    pub mesh: MeshData,
    /// Per-vertex texture coordinates, when given.
    pub uvs: Option<MeshUvs>,
    /// Non-fatal remarks (skipped properties and elements).
    pub warnings: Vec<String>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    ty: Scalar,
    /// Count type for list properties.
    list: Option<Scalar>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Le,
    Be,
}

/// Values of one element in file order, read by a format-specific source.
trait Source {
    fn scalar(&mut self, ty: Scalar) -> Result<f64>;
    fn end_element(&mut self) -> Result<()>;
    fn where_(&self) -> String;
}

struct Binary<'a> {
    data: &'a [u8],
    pos: usize,
    be: bool,
}

impl Source for Binary<'_> {
    #[inline]
    fn scalar(&mut self, ty: Scalar) -> Result<f64> {
        let n = ty.size();
        let Some(b) = self.data.get(self.pos..self.pos + n) else {
            bail!("unexpected end of file at byte {}", self.pos);
        };
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.be {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
    fn end_element(&mut self) -> Result<()> {
        Ok(())
    }
    fn where_(&self) -> String {
        format!("byte {}", self.pos)
    }
}

struct Ascii<'a> {
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    toks: std::str::SplitAsciiWhitespace<'a>,
    line: usize,
    started: bool,
}

impl Source for Ascii<'_> {
    fn scalar(&mut self, ty: Scalar) -> Result<f64> {
        loop {
            if self.started
                && let Some(t) = self.toks.next()
            {
                let v: f64 = t.parse().map_err(|_| anyhow!("cannot parse `{t}` as a number"))?;
                if matches!(ty, Scalar::F32 | Scalar::F64) || v.fract() == 0.0 {
                    return Ok(v);
                }
                bail!("`{t}` is not an integer");
            }
            let Some((i, l)) = self.lines.next() else { bail!("unexpected end of file") };
            self.line = i + 1;
            self.toks = l.split_ascii_whitespace();
            self.started = true;
        }
    }
    fn end_element(&mut self) -> Result<()> {
        if let Some(t) = self.toks.next() {
            bail!("extra value `{t}` at the end of an element");
        }
        self.started = false;
        Ok(())
    }
    fn where_(&self) -> String {
        format!("line {}", self.line)
    }
}

/// Reads a PLY file.
pub fn load_ply(path: &Path) -> Result<PlyMesh> {
    let data = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read PLY file: {e}", path.display()))?;
    parse_ply(&data, path)
}

/// Parses PLY bytes; `path` names messages.
pub fn parse_ply(data: &[u8], path: &Path) -> Result<PlyMesh> {
    let file = path.display();
    // Header: text lines up to and including `end_header`.
    let mut elements: Vec<Element> = Vec::new();
    let mut format = None;
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut saw_end = false;
    while pos < data.len() {
        let end = data[pos..].iter().position(|&b| b == b'\n').map_or(data.len(), |i| pos + i);
        let raw = &data[pos..end];
        pos = (end + 1).min(data.len());
        line_no += 1;
        let line = std::str::from_utf8(raw).map_err(|_| anyhow!("{file}:{line_no}: header line is not text"))?.trim_end_matches('\r');
        let t: Vec<&str> = line.split_ascii_whitespace().collect();
        let err = |m: String| anyhow!("{file}:{line_no}: {m}");
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(err("not a PLY file (the first line must be `ply`)".into()));
            }
            continue;
        }
        match t.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match (t.get(1).copied(), t.get(2).copied()) {
                    (Some("ascii"), Some("1.0")) => Format::Ascii,
                    (Some("binary_little_endian"), Some("1.0")) => Format::Le,
                    (Some("binary_big_endian"), Some("1.0")) => Format::Be,
                    _ => return Err(err(format!("unsupported format `{line}`"))),
                })
            }
            Some("element") => {
                let (Some(name), Some(n), None) = (t.get(1), t.get(2), t.get(3)) else {
                    return Err(err("`element` needs a name and a count".into()));
                };
                let count = n.parse().map_err(|_| err(format!("element count `{n}` is not a non-negative integer")))?;
                elements.push(Element { name: name.to_string(), count, props: Vec::new() });
            }
            Some("property") => {
                let el = elements.last_mut().ok_or_else(|| err("`property` before any `element`".into()))?;
                let prop = if t.get(1) == Some(&"list") {
                    let (Some(c), Some(i), Some(name), None) = (t.get(2), t.get(3), t.get(4), t.get(5)) else {
                        return Err(err("`property list` needs a count type, an item type and a name".into()));
                    };
                    let ct = Scalar::parse(c).ok_or_else(|| err(format!("unknown type `{c}`")))?;
                    if matches!(ct, Scalar::F32 | Scalar::F64) {
                        return Err(err("a list count must have an integer type".into()));
                    }
                    Property {
                        name: name.to_string(),
                        ty: Scalar::parse(i).ok_or_else(|| err(format!("unknown type `{i}`")))?,
                        list: Some(ct),
                    }
                } else {
                    let (Some(ty), Some(name), None) = (t.get(1), t.get(2), t.get(3)) else {
                        return Err(err("`property` needs a type and a name".into()));
                    };
                    Property {
                        name: name.to_string(),
                        ty: Scalar::parse(ty).ok_or_else(|| err(format!("unknown type `{ty}`")))?,
                        list: None,
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => {
                saw_end = true;
                break;
            }
            Some(other) => return Err(err(format!("unknown header keyword `{other}`"))),
        }
    }
    if !saw_end {
        bail!("{file}: PLY header has no `end_header`");
    }
    let format = format.ok_or_else(|| anyhow!("{file}: PLY header has no `format` line"))?;
    let body = &data[pos..];
    let mut out = PlyMesh::default();
    let result = match format {
        Format::Ascii => {
            let text = std::str::from_utf8(body).map_err(|_| anyhow!("{file}: ASCII PLY body is not text"))?;
            let mut src = Ascii { lines: text.lines().enumerate().peekable(), toks: "".split_ascii_whitespace(), line: 0, started: false };
            let r = read_body(&elements, &mut src, body.len(), &mut out);
            r.map_err(|e| anyhow!("{file}: {} (body {}): {e}", "PLY", src.where_().replace("line ", &format!("line {}+", line_no))))
        }
        Format::Le | Format::Be => {
            let mut src = Binary { data: body, pos: 0, be: format == Format::Be };
            let r = read_body(&elements, &mut src, body.len(), &mut out);
            r.map_err(|e| anyhow!("{file}: PLY body {}: {e}", src.where_()))
        }
    };
    result?;
    for w in out.warnings.iter_mut() {
        *w = format!("{file}: {w}");
    }
    Ok(out)
}

fn read_body(elements: &[Element], src: &mut dyn Source, body_len: usize, out: &mut PlyMesh) -> Result<()> {
    let mut have_vertices = false;
    let mut have_faces = false;
    for el in elements {
        // Capacity no larger than the body could hold (one byte per entry at least).
        let cap = (el.count as usize).min(body_len);
        match el.name.as_str() {
            "vertex" if !have_vertices => {
                have_vertices = true;
                read_vertices(el, src, cap, out)?;
            }
            "face" if !have_faces => {
                have_faces = true;
                read_faces(el, src, cap, out)?;
            }
            _ => {
                out.warnings.push(format!("element `{}` skipped", el.name));
                for _ in 0..el.count {
                    for p in &el.props {
                        skip_prop(p, src)?;
                    }
                    src.end_element()?;
                }
            }
        }
    }
    if !have_vertices {
        bail!("no `vertex` element");
    }
    let nv = out.mesh.positions.len();
    if let Some(f) = out.mesh.faces.iter().find(|f| f.v.iter().any(|&i| i as usize >= nv)) {
        bail!("face {} refers to vertex {:?}, but there are {nv} vertices", f.line, f.v);
    }
    Ok(())
}

fn skip_prop(p: &Property, src: &mut dyn Source) -> Result<()> {
    match p.list {
        None => {
            src.scalar(p.ty)?;
        }
        Some(ct) => {
            let n = src.scalar(ct)?;
            if !(0.0..=1e9).contains(&n) {
                bail!("list length {n} is out of range");
            }
            for _ in 0..n as u64 {
                src.scalar(p.ty)?;
            }
        }
    }
    Ok(())
}

fn read_vertices(el: &Element, src: &mut dyn Source, cap: usize, out: &mut PlyMesh) -> Result<()> {
    let find = |names: &[&str]| el.props.iter().position(|p| p.list.is_none() && names.contains(&p.name.as_str()));
    let (Some(ix), Some(iy), Some(iz)) = (find(&["x"]), find(&["y"]), find(&["z"])) else {
        bail!("element `vertex` needs properties x, y and z");
    };
    let nrm = match (find(&["nx"]), find(&["ny"]), find(&["nz"])) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    let uv = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]]
        .iter()
        .find_map(|[a, b]| Some([find(&[a])?, find(&[b])?]));
    let used: Vec<usize> = [ix, iy, iz].into_iter().chain(nrm.into_iter().flatten()).chain(uv.into_iter().flatten()).collect();
    let skipped: Vec<&str> = el.props.iter().enumerate().filter(|(i, _)| !used.contains(i)).map(|(_, p)| p.name.as_str()).collect();
    if !skipped.is_empty() {
        out.warnings.push(format!("vertex properties skipped: {}", skipped.join(", ")));
    }
    out.mesh.positions.reserve(cap);
    if nrm.is_some() {
        out.mesh.normals.reserve(cap);
    }
    let mut uvs = Vec::new();
    let mut vals = vec![0.0f64; el.props.len()];
    for _ in 0..el.count {
        for (k, p) in el.props.iter().enumerate() {
            if p.list.is_some() {
                skip_prop(p, src)?;
            } else {
                vals[k] = src.scalar(p.ty)?;
            }
        }
        src.end_element()?;
        out.mesh.positions.push(Vec3::new(vals[ix] as f32, vals[iy] as f32, vals[iz] as f32));
        if let Some([a, b, c]) = nrm {
            out.mesh.normals.push(Vec3::new(vals[a] as f32, vals[b] as f32, vals[c] as f32));
        }
        if let Some([a, b]) = uv {
            uvs.push(Vec2::new(vals[a] as f32, vals[b] as f32));
        }
    }
    if uv.is_some() {
        out.uvs = Some(MeshUvs { uvs, faces: Vec::new() });
    }
    Ok(())
}

fn read_faces(el: &Element, src: &mut dyn Source, cap: usize, out: &mut PlyMesh) -> Result<()> {
    let li = el
        .props
        .iter()
        .position(|p| p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index"))
        .ok_or_else(|| anyhow!("element `face` needs a list property `vertex_indices`"))?;
    if el.props.len() > 1 {
        let skipped: Vec<&str> = el.props.iter().enumerate().filter(|(i, _)| *i != li).map(|(_, p)| p.name.as_str()).collect();
        out.warnings.push(format!("face properties skipped: {}", skipped.join(", ")));
    }
    let has_n = !out.mesh.normals.is_empty();
    out.mesh.faces.reserve(cap);
    let mut idx: Vec<u32> = Vec::with_capacity(8);
    for f in 0..el.count {
        for (k, p) in el.props.iter().enumerate() {
            if k != li {
                skip_prop(p, src)?;
                continue;
            }
            let n = src.scalar(p.list.expect("list"))?;
            if !(3.0..=1e6).contains(&n) {
                bail!("face {f} has {n} vertices (3 or more expected)");
            }
            idx.clear();
            for _ in 0..n as u32 {
                let v = src.scalar(p.ty)?;
                if !(0.0..=u32::MAX as f64 - 1.0).contains(&v) {
                    bail!("face {f}: vertex index {v} is out of range");
                }
                idx.push(v as u32);
            }
        }
        src.end_element()?;
        let line = u32::try_from(f).unwrap_or(u32::MAX);
        for k in 1..idx.len() - 1 {
            let v = [idx[0], idx[k], idx[k + 1]];
            out.mesh.faces.push(Face { v, n: has_n.then_some(v), material: 0, line });
        }
    }
    if let Some(u) = &mut out.uvs {
        u.faces = out.mesh.faces.iter().map(|f| Some(f.v)).collect();
    }
    Ok(())
}

/// Writes a binary little-endian PLY (positions, and normals when given) — for
/// tests and the load-time benchmark.
pub fn write_binary_ply(positions: &[Vec3], normals: &[Vec3], tris: &[[u32; 3]]) -> Vec<u8> {
    let mut h = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        positions.len()
    );
    if !normals.is_empty() {
        h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    h.push_str(&format!("element face {}\nproperty list uchar int vertex_indices\nend_header\n", tris.len()));
    let mut out = h.into_bytes();
    for (i, p) in positions.iter().enumerate() {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = normals.get(i) {
            for c in n.to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for t in tris {
        out.push(3);
        for i in t {
            out.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_with_normals_uvs_and_quads() {
        let s = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                 property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\nproperty uchar red\n\
                 element face 1\nproperty list uchar int vertex_indices\nend_header\n\
                 0 0 0 0 0 1 0 0 255\n1 0 0 0 0 1 1 0 255\n1 1 0 0 0 1 1 1 255\n0 1 0 0 0 1 0 1 255\n4 0 1 2 3\n";
        let m = parse_ply(s.as_bytes(), Path::new("q.ply")).unwrap();
        assert_eq!(m.mesh.positions.len(), 4);
        assert_eq!(m.mesh.faces.len(), 2);
        assert_eq!(m.mesh.faces[1].v, [0, 2, 3]);
        assert_eq!(m.mesh.faces[1].n, Some([0, 2, 3]));
        let uv = m.uvs.unwrap();
        assert_eq!(uv.uvs[2], Vec2::new(1.0, 1.0));
        assert_eq!(uv.faces.len(), 2);
        assert!(m.warnings.iter().any(|w| w.contains("red")));
    }

    #[test]
    fn binary_round_trip_and_errors() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let bytes = write_binary_ply(&p, &[], &[[0, 1, 2]]);
        let m = parse_ply(&bytes, Path::new("b.ply")).unwrap();
        assert_eq!(m.mesh.positions, p);
        assert_eq!(m.mesh.faces[0].v, [0, 1, 2]);
        assert!(m.mesh.faces[0].n.is_none());
        // Big endian.
        let be = String::from_utf8_lossy(&bytes).replace("binary_little_endian", "binary_big_endian");
        assert!(!be.is_empty());
        // Truncated body, bad index, bad header.
        let e = parse_ply(&bytes[..bytes.len() - 2], Path::new("b.ply")).unwrap_err().to_string();
        assert!(e.starts_with("b.ply:") && e.contains("end of file"), "{e}");
        let bad = write_binary_ply(&p, &[], &[[0, 1, 7]]);
        assert!(parse_ply(&bad, Path::new("b.ply")).unwrap_err().to_string().contains("vertex"));
        let e = parse_ply(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", Path::new("a.ply")).unwrap_err();
        assert!(e.to_string().contains("x, y and z"), "{e}");
        assert!(parse_ply(b"ply\nformat ascii 2.0\nend_header\n", Path::new("a.ply")).is_err());
        assert!(
            parse_ply(
                b"ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
                Path::new("a.ply")
            )
            .is_err()
        );
    }
}

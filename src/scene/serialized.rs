//! Mitsuba's `serialized` mesh format (Mitsuba 0.6 and 3): a file of one or more
//! meshes, each a little-endian header (format id 0x041C, version 3 or 4) followed by
//! a zlib stream holding the mesh — flags, the name (version 4), vertex and triangle
//! counts, positions, optional vertex normals, texture coordinates and colours (single
//! or double precision), then the triangles' indices (32-bit, 64-bit above 2³² vertices).
//! The file ends with a dictionary: each mesh's byte offset (64-bit in version 4,
//! 32-bit in version 3), then the mesh count (32-bit).

use super::ply::PlyMesh;
use super::{Face, MeshData, MeshUvs};
use anyhow::{Context, Result, anyhow, bail};
use glam::{Vec2, Vec3};
use std::io::Read;
use std::path::Path;

const FORMAT_ID: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_UVS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const FACE_NORMALS: u32 = 0x0010;
const SINGLE: u32 = 0x1000;
const DOUBLE: u32 = 0x2000;

/// Reads mesh `index` of a serialized file. Vertex colours are skipped (a warning);
/// the face-normals flag drops the vertex normals.
pub fn load_serialized(path: &Path, index: u32) -> Result<PlyMesh> {
    let data = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read serialized mesh file: {e}", path.display()))?;
    parse_serialized(&data, index).with_context(|| format!("{}: serialized mesh {index}", path.display()))
}

/// [`load_serialized`] on the file's bytes.
pub fn parse_serialized(data: &[u8], index: u32) -> Result<PlyMesh> {
    let offset = mesh_offset(data, index)?;
    let head = data.get(offset..offset + 4).ok_or_else(|| anyhow!("offset {offset} is past the end of the file"))?;
    let (id, version) = (u16::from_le_bytes([head[0], head[1]]), u16::from_le_bytes([head[2], head[3]]));
    if id != FORMAT_ID {
        bail!("not a serialized mesh (format id {id:#06x} at byte {offset}, expected 0x041c)");
    }
    if version != 3 && version != 4 {
        bail!("format version {version} is not supported (3 or 4)");
    }
    let mut z = flate2::read::ZlibDecoder::new(&data[offset + 4..]);
    let mut r = Reader { z: &mut z };
    let flags = r.u32()?;
    if version == 4 {
        r.name()?;
    }
    let (nv, nt) = (r.u64()?, r.u64()?);
    let double = match (flags & SINGLE != 0, flags & DOUBLE != 0) {
        (true, false) => false,
        (false, true) => true,
        _ => bail!("flags {flags:#x} give neither or both of single and double precision"),
    };
    if nv > (1 << 31) || nt > (1 << 31) {
        bail!("{nv} vertices / {nt} triangles are more than photonlab's 2³¹ limit");
    }
    let (nv, nt) = (nv as usize, nt as usize);
    let mut out = PlyMesh { mesh: MeshData::default(), uvs: None, warnings: Vec::new() };
    out.mesh.positions = r.vec3s(nv, double)?;
    if flags & HAS_NORMALS != 0 {
        out.mesh.normals = r.vec3s(nv, double)?;
        if flags & FACE_NORMALS != 0 {
            out.mesh.normals.clear();
        }
    }
    let uvs = if flags & HAS_UVS != 0 {
        Some((0..nv).map(|_| Ok(Vec2::new(r.real(double)?, r.real(double)?))).collect::<Result<Vec<_>>>()?)
    } else {
        None
    };
    if flags & HAS_COLORS != 0 {
        r.vec3s(nv, double)?;
        out.warnings.push("vertex colours skipped".into());
    }
    let wide = nv > u32::MAX as usize;
    let has_n = !out.mesh.normals.is_empty();
    // The counts come from the file: reserve no more than its data could hold (a
    // corrupt count of 2³¹ triangles would otherwise ask for tens of gigabytes up
    // front and abort the process instead of failing with an error).
    out.mesh.faces.reserve(nt.min(data.len()));
    for t in 0..nt {
        let mut v = [0u32; 3];
        for c in v.iter_mut() {
            let i = if wide { r.u64()? } else { r.u32()? as u64 };
            if i >= nv as u64 {
                bail!("triangle {t}: vertex index {i} out of range ({nv} vertices)");
            }
            *c = i as u32;
        }
        out.mesh.faces.push(Face { v, n: has_n.then_some(v), material: 0, line: u32::try_from(t).unwrap_or(u32::MAX) });
    }
    if let Some(uvs) = uvs {
        let faces = out.mesh.faces.iter().map(|f| Some(f.v)).collect();
        out.uvs = Some(MeshUvs { uvs, faces });
    }
    Ok(out)
}

/// Byte offset of mesh `index`: 0 for the first; from the end-of-file dictionary
/// otherwise.
fn mesh_offset(data: &[u8], index: u32) -> Result<usize> {
    if data.len() < 4 {
        bail!("file too short ({} bytes)", data.len());
    }
    if index == 0 {
        return Ok(0);
    }
    let count = u32::from_le_bytes(data[data.len() - 4..].try_into().expect("4 bytes"));
    let version = u16::from_le_bytes([data[2], data[3]]);
    if index >= count {
        bail!("shape_index {index} is out of range: the file holds {count} meshes");
    }
    let width = if version >= 4 { 8 } else { 4 };
    let table = data
        .len()
        .checked_sub(4 + width * count as usize)
        .ok_or_else(|| anyhow!("the dictionary of {count} meshes does not fit in the file"))?;
    let at = table + width * index as usize;
    let off = if width == 8 {
        u64::from_le_bytes(data[at..at + 8].try_into().expect("8 bytes"))
    } else {
        u32::from_le_bytes(data[at..at + 4].try_into().expect("4 bytes")) as u64
    };
    usize::try_from(off).ok().filter(|&o| o < data.len()).ok_or_else(|| anyhow!("mesh offset {off} is past the end of the file"))
}

struct Reader<'a, R: Read> {
    z: &'a mut R,
}

impl<R: Read> Reader<'_, R> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N]> {
        let mut b = [0u8; N];
        self.z.read_exact(&mut b).map_err(|e| anyhow!("truncated or corrupt mesh data: {e}"))?;
        Ok(b)
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }
    fn real(&mut self, double: bool) -> Result<f32> {
        let v = if double { f64::from_le_bytes(self.bytes()?) as f32 } else { f32::from_le_bytes(self.bytes()?) };
        if !v.is_finite() {
            bail!("non-finite value {v} in the mesh data");
        }
        Ok(v)
    }
    fn vec3s(&mut self, n: usize, double: bool) -> Result<Vec<Vec3>> {
        (0..n).map(|_| Ok(Vec3::new(self.real(double)?, self.real(double)?, self.real(double)?))).collect()
    }
    fn name(&mut self) -> Result<()> {
        for _ in 0..1 << 16 {
            if self.bytes::<1>()?[0] == 0 {
                return Ok(());
            }
        }
        bail!("mesh name longer than 64 KiB")
    }
}

/// One mesh to write: positions, normals and texture coordinates (each empty or one
/// per vertex), triangles.
pub type MeshSlices<'a> = (&'a [Vec3], &'a [Vec3], &'a [Vec2], &'a [[u32; 3]]);

/// Writes meshes in the serialized format (version 4, single precision, with normals
/// and texture coordinates when given) — for tests and the fuzzer's seeds.
pub fn write_serialized(meshes: &[MeshSlices]) -> Vec<u8> {
    let payloads: Vec<Vec<u8>> = meshes.iter().enumerate().map(|(k, m)| mesh_payload(m, &format!("mesh{k}"))).collect();
    wrap_payloads(&payloads)
}

/// The uncompressed body of one version-4 mesh: flags, name, counts, vertex data,
/// triangles.
pub fn mesh_payload((p, n, uv, tris): &MeshSlices, name: &str) -> Vec<u8> {
    let mut raw = Vec::new();
    let flags = SINGLE | if n.is_empty() { 0 } else { HAS_NORMALS } | if uv.is_empty() { 0 } else { HAS_UVS };
    raw.extend_from_slice(&flags.to_le_bytes());
    raw.extend_from_slice(name.as_bytes());
    raw.push(0);
    raw.extend_from_slice(&(p.len() as u64).to_le_bytes());
    raw.extend_from_slice(&(tris.len() as u64).to_le_bytes());
    for v in p.iter().chain(n.iter()) {
        v.to_array().iter().for_each(|x| raw.extend_from_slice(&x.to_le_bytes()));
    }
    for t in uv.iter() {
        t.to_array().iter().for_each(|x| raw.extend_from_slice(&x.to_le_bytes()));
    }
    for t in tris.iter() {
        t.iter().for_each(|i| raw.extend_from_slice(&i.to_le_bytes()));
    }
    raw
}

/// A version-4 file holding the given uncompressed mesh bodies (each behind its
/// header, zlib-compressed), with the dictionary of offsets at the end. The bodies
/// need not be valid: the fuzzer wraps mutated ones, so that the mesh reader sees
/// corrupt counts and flags rather than only a corrupt zlib stream.
pub fn wrap_payloads(payloads: &[Vec<u8>]) -> Vec<u8> {
    use std::io::Write;
    let mut out = Vec::new();
    let mut offsets = Vec::new();
    for raw in payloads {
        offsets.push(out.len() as u64);
        out.extend_from_slice(&FORMAT_ID.to_le_bytes());
        out.extend_from_slice(&4u16.to_le_bytes());
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(raw).expect("in memory");
        out.extend(e.finish().expect("in memory"));
    }
    for o in &offsets {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&(payloads.len() as u32).to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_two_meshes_and_errors() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let n = [Vec3::Z; 4];
        let uv = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE];
        let data = write_serialized(&[(&p[..3], &[], &[], &[[0, 1, 2]]), (&p, &n, &uv, &[[0, 1, 2], [1, 3, 2]])]);
        let a = parse_serialized(&data, 0).unwrap();
        assert_eq!((a.mesh.positions.len(), a.mesh.faces.len(), a.mesh.normals.len()), (3, 1, 0));
        assert!(a.uvs.is_none() && a.mesh.faces[0].n.is_none());
        let b = parse_serialized(&data, 1).unwrap();
        assert_eq!(b.mesh.positions, p);
        assert_eq!(b.mesh.normals, n);
        assert_eq!(b.mesh.faces[1].v, [1, 3, 2]);
        assert_eq!(b.mesh.faces[1].n, Some([1, 3, 2]));
        assert_eq!(b.uvs.unwrap().uvs, uv);
        assert!(parse_serialized(&data, 2).unwrap_err().to_string().contains("out of range"));
        let mut bad = data.clone();
        bad[0] = 0;
        assert!(parse_serialized(&bad, 0).unwrap_err().to_string().contains("format id"));
        let cut = &data[..12];
        assert!(parse_serialized(cut, 0).is_err());
    }

    /// A body claiming 2³¹ triangles over three vertices and no index data: an error
    /// (truncated), not a reservation of tens of gigabytes that aborts the process
    /// (found by `photonlab fuzz` once it mutated the bodies, not only the zlib bytes).
    #[test]
    fn a_huge_triangle_count_is_an_error() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let mut raw = mesh_payload(&(&p[..], &[], &[], &[]), "m");
        // flags (4) + "m\0" (2) + vertex count (8), then the triangle count.
        raw[14..22].copy_from_slice(&(1u64 << 31).to_le_bytes());
        let e = parse_serialized(&wrap_payloads(&[raw]), 0).unwrap_err().to_string();
        assert!(e.contains("truncated or corrupt"), "{e}");
    }
}

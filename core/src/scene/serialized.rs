//! Mitsuba's `.serialized` meshes (file format versions 3 and 4; Mitsuba 3.9.1 writes 4), as
//! Mitsuba 3's `serialized` shape reads them (`src/shapes/serialized.cpp`).
//!
//! A file holds one or more meshes, each a little-endian header (u16 0x041C, u16 version)
//! followed by a zlib stream of: u32 flags; (version 4) the mesh's name, a NUL-terminated
//! string; u64 vertex and triangle counts; the positions, then per flag the normals (0x0001),
//! texture coordinates (0x0002) and vertex colours (0x0008, read past), each per vertex in f32
//! or, with flag 0x2000, f64; then u32 vertex indices, three per triangle. After the meshes, a
//! table of each mesh's byte offset (u64 in version 4, u32 in version 3) and their count (u32),
//! through which `shape_index` finds a mesh other than the first.
//!
//! Bounds: a count is checked against what its stream can hold before anything is allocated
//! (a zlib stream inflates at most 1032-fold), the stream is read for exactly the bytes the
//! counts need (an endless or truncated stream is an error, never a hang), and positions,
//! normals, texture coordinates and indices are checked as the PLY reader checks them.

use crate::geometry::Mesh;
use flate2::read::ZlibDecoder;
use glam::{Vec2, Vec3};
use std::io::{Read, Write};
use std::path::Path;

/// The format's magic number.
const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const SINGLE_PRECISION: u32 = 0x1000;
const DOUBLE_PRECISION: u32 = 0x2000;
/// The most a zlib stream inflates: deflate's limit is 1032:1.
const MAX_INFLATION: u64 = 1032;
/// The longest mesh name read (version 4).
const MAX_NAME: usize = 1 << 16;

/// Loads mesh `shape_index` (0: the first) of a `.serialized` file, with its normals and
/// texture coordinates when it has them.
pub fn load(path: &Path, shape_index: u32) -> Result<Mesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read serialized mesh: {e}"))?;
    parse(&bytes, shape_index)
}

/// [`load`] from the file's bytes.
pub fn parse(bytes: &[u8], shape_index: u32) -> Result<Mesh, String> {
    let (version, start) = header(bytes, 0)?;
    let start = if shape_index == 0 {
        start
    } else {
        let offset = mesh_offset(bytes, version, shape_index)?;
        let (other, start) = header(bytes, offset)?;
        if other != version {
            return Err(format!(
                "mesh {shape_index} at byte {offset} is of version {other}, the file's first of \
                 version {version}"
            ));
        }
        start
    };
    let compressed = &bytes[start..];
    let bound = (compressed.len() as u64).saturating_mul(MAX_INFLATION);
    let mut stream = Stream {
        inner: ZlibDecoder::new(compressed),
        read: 0,
    };
    let flags = u32::from_le_bytes(stream.take::<4>("the flags")?);
    if version == 4 {
        let mut name = Vec::new();
        loop {
            let [c] = stream.take::<1>("the mesh's name")?;
            if c == 0 {
                break;
            }
            if name.len() == MAX_NAME {
                return Err(format!(
                    "the mesh's name is longer than {MAX_NAME} bytes (no NUL found)"
                ));
            }
            name.push(c);
        }
    }
    let vertices = u64::from_le_bytes(stream.take::<8>("the vertex count")?);
    let triangles = u64::from_le_bytes(stream.take::<8>("the triangle count")?);
    let real = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let per_vertex = 3
        + 3 * u64::from(flags & HAS_NORMALS != 0)
        + 2 * u64::from(flags & HAS_TEXCOORDS != 0)
        + 3 * u64::from(flags & HAS_COLORS != 0);
    let needed = vertices
        .checked_mul(per_vertex * real)
        .and_then(|v| triangles.checked_mul(12).and_then(|t| v.checked_add(t)));
    match needed {
        Some(n) if n <= bound && vertices <= u32::MAX as u64 => {}
        _ => {
            return Err(format!(
                "mesh declares {vertices} vertices and {triangles} triangles, more than its \
                 zlib stream of {} bytes can hold (at most {bound} bytes inflated)",
                compressed.len()
            ));
        }
    }
    let (vertices, triangles) = (vertices as usize, triangles as usize);
    let mut reals = |count: usize, what: &str| -> Result<Vec<f32>, String> {
        let mut raw = vec![0u8; count * real as usize];
        stream.fill(&mut raw, what)?;
        Ok(if real == 8 {
            raw.chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
                .collect()
        } else {
            raw.chunks_exact(4)
                .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
                .collect()
        })
    };
    let positions: Vec<Vec3> = reals(3 * vertices, "the positions")?
        .chunks_exact(3)
        .map(Vec3::from_slice)
        .collect();
    let normals = match flags & HAS_NORMALS {
        0 => None,
        _ => Some(
            reals(3 * vertices, "the normals")?
                .chunks_exact(3)
                .map(Vec3::from_slice)
                .collect::<Vec<_>>(),
        ),
    };
    let uvs = match flags & HAS_TEXCOORDS {
        0 => None,
        _ => Some(
            reals(2 * vertices, "the texture coordinates")?
                .chunks_exact(2)
                .map(Vec2::from_slice)
                .collect::<Vec<_>>(),
        ),
    };
    if flags & HAS_COLORS != 0 {
        reals(3 * vertices, "the vertex colours")?;
    }
    let mut raw = vec![0u8; triangles * 12];
    stream.fill(&mut raw, "the triangles")?;
    let indices: Vec<[u32; 3]> = raw
        .chunks_exact(12)
        .map(|b| {
            std::array::from_fn(|k| {
                u32::from_le_bytes(b[4 * k..4 * k + 4].try_into().expect("4 bytes"))
            })
        })
        .collect();

    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "vertex {i}: position {} is not finite",
            positions[i]
        ));
    }
    if let Some(normals) = &normals
        && let Some(i) = normals
            .iter()
            .position(|n| !n.is_finite() || *n == Vec3::ZERO)
    {
        return Err(format!(
            "vertex {i}: normal {} is not a finite non-zero vector",
            normals[i]
        ));
    }
    if let Some(uvs) = &uvs
        && let Some(i) = uvs.iter().position(|t| !t.is_finite())
    {
        return Err(format!(
            "vertex {i}: texture coordinates {} are not finite",
            uvs[i]
        ));
    }
    if let Some((t, &index)) = indices.iter().enumerate().find_map(|(t, tri)| {
        tri.iter()
            .find(|&&i| i as usize >= vertices)
            .map(|i| (t, i))
    }) {
        return Err(format!(
            "triangle {t}: vertex index {index} is out of range ({vertices} vertices)"
        ));
    }
    if indices.is_empty() {
        return Err("the mesh has no triangles".into());
    }
    Ok(Mesh {
        positions,
        normals: normals.map(|n| n.into_iter().map(|n| n.normalize()).collect()),
        indices,
        uvs,
    })
}

/// The version of the mesh header at `offset`, and where its zlib stream starts.
fn header(bytes: &[u8], offset: usize) -> Result<(u16, usize), String> {
    let word = |at: usize| {
        bytes
            .get(at..at + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .ok_or_else(|| format!("truncated: no mesh header at byte {offset}"))
    };
    let magic = word(offset)?;
    if magic != MAGIC {
        return Err(format!(
            "not a Mitsuba serialized mesh (header {magic:#06x} at byte {offset}, expected \
             {MAGIC:#06x})"
        ));
    }
    let version = word(offset + 2)?;
    if !matches!(version, 3 | 4) {
        return Err(format!(
            "serialized format version {version} is not read (versions 3 and 4 are)"
        ));
    }
    Ok((version, offset + 4))
}

/// Byte offset of mesh `index` (from 0) through the table at the end of the file.
fn mesh_offset(bytes: &[u8], version: u16, index: u32) -> Result<usize, String> {
    let tail = |from_end: usize, len: usize| {
        let start = bytes.len().checked_sub(from_end)?;
        bytes.get(start..start + len)
    };
    let count = tail(4, 4)
        .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
        .ok_or("truncated: no mesh table at the end of the file")?;
    if index >= count {
        return Err(format!(
            "`shape_index` {index} is out of range: the file holds {count} meshes (0 to {})",
            count.saturating_sub(1)
        ));
    }
    let entry = if version == 4 { 8 } else { 4 };
    let from_end = 4 + entry * (count - index) as usize;
    let offset = tail(from_end, entry)
        .map(|b| match entry {
            8 => u64::from_le_bytes(b.try_into().expect("8 bytes")),
            _ => u32::from_le_bytes(b.try_into().expect("4 bytes")) as u64,
        })
        .ok_or_else(|| format!("truncated: the mesh table of {count} meshes does not fit"))?;
    usize::try_from(offset)
        .ok()
        .filter(|&o| o < bytes.len())
        .ok_or_else(|| format!("mesh {index}'s offset {offset} is past the end of the file"))
}

/// `meshes` as a `.serialized` file of format `version` (3 or 4), each with its normals and
/// texture coordinates when it has them, in f32 or (`double`) f64: what [`parse`] reads, for
/// tests and the fuzzer's seeds.
pub fn write(meshes: &[Mesh], version: u16, double: bool) -> Vec<u8> {
    let mut out = Vec::new();
    let mut offsets = Vec::new();
    for (k, m) in meshes.iter().enumerate() {
        offsets.push(out.len() as u64);
        out.extend(MAGIC.to_le_bytes());
        out.extend(version.to_le_bytes());
        let mut body = Vec::new();
        let mut flags = 0;
        flags |= if m.normals.is_some() { HAS_NORMALS } else { 0 };
        flags |= if m.uvs.is_some() { HAS_TEXCOORDS } else { 0 };
        flags |= if double {
            DOUBLE_PRECISION
        } else {
            SINGLE_PRECISION
        };
        body.extend(flags.to_le_bytes());
        if version == 4 {
            body.extend(format!("mesh{k}").bytes());
            body.push(0);
        }
        body.extend((m.positions.len() as u64).to_le_bytes());
        body.extend((m.indices.len() as u64).to_le_bytes());
        let real = |body: &mut Vec<u8>, x: f32| {
            if double {
                body.extend((x as f64).to_le_bytes())
            } else {
                body.extend(x.to_le_bytes())
            }
        };
        for p in &m.positions {
            p.to_array().iter().for_each(|&x| real(&mut body, x));
        }
        for n in m.normals.iter().flatten() {
            n.to_array().iter().for_each(|&x| real(&mut body, x));
        }
        for t in m.uvs.iter().flatten() {
            t.to_array().iter().for_each(|&x| real(&mut body, x));
        }
        for t in &m.indices {
            t.iter().for_each(|i| body.extend(i.to_le_bytes()));
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).expect("writing to memory");
        out.extend(z.finish().expect("writing to memory"));
    }
    for o in &offsets {
        if version == 4 {
            out.extend(o.to_le_bytes());
        } else {
            out.extend((*o as u32).to_le_bytes());
        }
    }
    out.extend((meshes.len() as u32).to_le_bytes());
    out
}

/// The inflated stream, read in exact amounts.
struct Stream<'a> {
    inner: ZlibDecoder<&'a [u8]>,
    read: u64,
}

impl Stream<'_> {
    fn fill(&mut self, out: &mut [u8], what: &str) -> Result<(), String> {
        self.inner.read_exact(out).map_err(|e| {
            format!(
                "{what}: the zlib stream ends or is corrupt after {} inflated bytes ({e})",
                self.read
            )
        })?;
        self.read += out.len() as u64;
        Ok(())
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let mut b = [0u8; N];
        self.fill(&mut b, what)?;
        Ok(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::Compression;
    use flate2::write::ZlibEncoder;
    use std::io::Write;

    #[test]
    fn meshes_read_back_in_both_versions_and_precisions() {
        let cube = crate::geometry::cube();
        let rectangle = crate::geometry::rectangle();
        for version in [3, 4] {
            for double in [false, true] {
                let bytes = write(&[cube.clone(), rectangle.clone()], version, double);
                assert_eq!(parse(&bytes, 0).unwrap(), cube, "v{version} {double}");
                assert_eq!(parse(&bytes, 1).unwrap(), rectangle, "v{version} {double}");
                let e = parse(&bytes, 2).unwrap_err();
                assert!(e.contains("out of range") && e.contains("2 meshes"), "{e}");
            }
        }
    }

    #[test]
    fn bad_files_are_refused_with_the_reason() {
        let cube = crate::geometry::cube();
        let good = write(&[cube], 4, false);
        let mut v5 = good.clone();
        v5[2] = 5;
        assert!(parse(&v5, 0).unwrap_err().contains("version 5"));
        assert!(parse(b"PK", 0).unwrap_err().contains("not a Mitsuba"));
        let truncated = &good[..good.len() / 2];
        let e = parse(truncated, 0).unwrap_err();
        assert!(e.contains("ends or is corrupt"), "{e}");
        // A stream that declares 2^62 vertices.
        let mut body = Vec::new();
        body.extend(SINGLE_PRECISION.to_le_bytes());
        body.push(0);
        body.extend((1u64 << 62).to_le_bytes());
        body.extend(1u64.to_le_bytes());
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(&body).unwrap();
        let mut bomb = vec![0x1C, 0x04, 4, 0];
        bomb.extend(z.finish().unwrap());
        let e = parse(&bomb, 0).unwrap_err();
        assert!(e.contains("more than its zlib stream"), "{e}");
    }
}

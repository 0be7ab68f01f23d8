//! glTF 2.0 import (`.gltf` with external or embedded buffers, and `.glb`): triangle meshes with
//! node transforms and, when present, vertex normals and texture coordinates (`TEXCOORD_0`).
//! Textures and materials are not read here: materials come from the scene file (or
//! `gltf_scene`'s mapping of the file's materials).

use crate::geometry::Mesh;
use base64::Engine;
use glam::{Mat4, Vec2, Vec3};
use gltf::mesh::Mode;
use std::path::Path;

/// Loads the triangles of a glTF file in its scene's coordinates (node transforms applied).
/// With `only`, keeps the node of that name (with its children) or else the mesh of that name.
pub fn load(path: &Path, only: Option<&str>) -> Result<Mesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read glTF file: {e}"))?;
    load_bytes(&bytes, path.parent().unwrap_or(Path::new(".")), only)
}

/// As [`load`], from the file's bytes; external buffers are read from `base`. Never panics on
/// bad data.
pub fn load_bytes(bytes: &[u8], base: &Path, only: Option<&str>) -> Result<Mesh, String> {
    let mut mesh = Mesh::default();
    for (_, part) in load_parts(bytes, base, only)? {
        mesh.append(part);
    }
    Ok(mesh)
}

/// Parses and validates a glTF or GLB file (without reading its buffers).
pub(super) fn parse(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    // gltf 1.4's validation indexes `accessors` with a primitive's POSITION index before
    // checking it (it panics on a dangling index, found by fuzzing): check indices first.
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes).map_err(invalid_gltf)?;
    check_accessor_indices(&unchecked)?;
    gltf::Gltf::from_slice(bytes).map_err(invalid_gltf)
}

/// As [`load_bytes`], one mesh per primitive with the index of its material (`None`: the
/// default material), in the order [`load_bytes`] merges them.
pub(super) fn load_parts(
    bytes: &[u8],
    base: &Path,
    only: Option<&str>,
) -> Result<Vec<(Option<usize>, Mesh)>, String> {
    let gltf = parse(bytes)?;
    let buffers = load_buffers(&gltf, base)?;
    let doc = &gltf.document;

    let mut parts = Vec::new();
    let mut found = only.is_none();
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => doc.nodes().collect(),
    };
    let mut stack: Vec<(gltf::Node, Mat4, bool)> = roots
        .into_iter()
        .map(|n| (n, Mat4::IDENTITY, only.is_none()))
        .collect();
    let mut visited = 0usize;
    while let Some((node, parent, selected)) = stack.pop() {
        visited += 1;
        if visited > doc.nodes().len() * 4 + 16 {
            return Err("the node hierarchy has a cycle".into());
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let node_label = || {
            node.name()
                .map_or(format!("node {}", node.index()), |n| format!("node `{n}`"))
        };
        if !world.is_finite() || world.row(3) != glam::Vec4::W {
            return Err(format!(
                "{}: its transform (with its parents') is not finite or not affine",
                node_label()
            ));
        }
        // A node scaled to nothing (a common way to hide one) has no surface: it is skipped.
        let flattened = super::transform::check_affine(&world).is_err();
        let selected = selected
            || only.is_some_and(|name| {
                node.name() == Some(name) || node.mesh().and_then(|m| m.name()) == Some(name)
            });
        found |= selected;
        if selected
            && !flattened
            && let Some(m) = node.mesh()
        {
            for (material, part) in read_mesh(&m, &buffers)? {
                parts.push((material, part.transformed(&world)));
            }
        }
        stack.extend(node.children().map(|c| (c, world, selected)));
    }
    if !found {
        let mut names: Vec<&str> = doc.nodes().filter_map(|n| n.name()).collect();
        names.extend(doc.meshes().filter_map(|m| m.name()));
        names.sort_unstable();
        names.dedup();
        let name = only.unwrap_or_default();
        return Err(format!(
            "no node or mesh named `{name}`{}; names in the file: {}",
            crate::error::did_you_mean(name, names.iter().copied()),
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    }
    if parts.iter().all(|(_, part)| part.indices.is_empty()) {
        return Err("the file has no triangles".into());
    }
    Ok(parts)
}

/// A short message for a file the glTF crate refuses: its validation lists every problem on one
/// line (hundreds of characters for one bad number repeated); the first few suffice.
fn invalid_gltf(e: gltf::Error) -> String {
    const SHOWN: usize = 3;
    let gltf::Error::Validation(problems) = e else {
        return format!("not a valid glTF file: {e}");
    };
    let shown: Vec<String> = problems
        .iter()
        .take(SHOWN)
        .map(|(path, problem)| format!("`{path}`: {problem}"))
        .collect();
    let more = problems.len().saturating_sub(SHOWN);
    // Exporters write infinite bounds as null (JavaScript) or leave them out.
    let bounds = problems.iter().any(|(path, _)| {
        let path = path.to_string();
        path.ends_with(".min") || path.ends_with(".max")
    });
    format!(
        "not a valid glTF file: {}{}{}",
        shown.join("; "),
        if more > 0 {
            format!(" (and {more} more)")
        } else {
            String::new()
        },
        if bounds {
            "; POSITION bounds must be present and finite: are the positions infinite?"
        } else {
            ""
        }
    )
}

/// The file a buffer URI names: a relative path inside the model's folder (glTF URIs are
/// relative by the specification). Absolute paths, other schemes (`file:`, `http:`) and paths
/// that climb out of the folder are refused, so that a model cannot read `/etc/passwd` or
/// `../../secret` as a buffer. Percent escapes are decoded first (`%2e%2e` is `..`).
fn buffer_path(base: &Path, uri: &str) -> Result<std::path::PathBuf, String> {
    let decoded = percent_decode(uri)
        .ok_or_else(|| format!("buffer URI `{uri}` has an invalid percent escape"))?;
    let refuse = |why: &str| {
        Err(format!(
            "buffer URI `{uri}` {why}: only relative paths inside the model's folder and data: URIs are read"
        ))
    };
    if decoded.contains('\0') {
        return refuse("contains a NUL character");
    }
    let scheme_end = decoded.find(':');
    let first_separator = decoded.find(['/', '\\']);
    if let Some(colon) = scheme_end
        && first_separator.is_none_or(|s| colon < s)
    {
        return refuse(&format!("has the scheme `{}:`", &decoded[..colon]));
    }
    if decoded.starts_with(['/', '\\']) {
        return refuse("is an absolute path");
    }
    let mut depth = 0usize;
    for part in decoded.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => match depth.checked_sub(1) {
                Some(d) => depth = d,
                None => return refuse("climbs out of the model's folder"),
            },
            _ => depth += 1,
        }
    }
    Ok(base.join(decoded))
}

/// Decodes `%XX` escapes; `None` for a malformed escape or bytes that are not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = text.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Every accessor a mesh primitive names must exist.
fn check_accessor_indices(gltf: &gltf::Gltf) -> Result<(), String> {
    let json = gltf.document.as_json();
    let count = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for primitive in &mesh.primitives {
            let attributes = primitive.attributes.values().map(|i| i.value());
            let indices = primitive.indices.iter().map(|i| i.value());
            if let Some(bad) = attributes.chain(indices).find(|&i| i >= count) {
                return Err(format!(
                    "mesh {m} refers to accessor {bad}, but the file has {count}"
                ));
            }
        }
    }
    Ok(())
}

fn load_buffers(gltf: &gltf::Gltf, base: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or("buffer refers to the binary chunk, but the file has none")?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, payload) = rest
                        .split_once(";base64,")
                        .ok_or("only base64 data URIs are supported for buffers")?;
                    base64::engine::general_purpose::STANDARD
                        .decode(payload)
                        .map_err(|e| format!("buffer {}: invalid base64: {e}", buffer.index()))?
                } else {
                    let file = buffer_path(base, uri)?;
                    std::fs::read(&file)
                        .map_err(|e| format!("cannot read buffer `{}`: {e}", file.display()))?
                }
            }
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {} holds {} bytes, fewer than the {} it declares",
                buffer.index(),
                data.len(),
                buffer.length()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The mesh's triangle primitives, each with the index of its material.
fn read_mesh(m: &gltf::Mesh, buffers: &[Vec<u8>]) -> Result<Vec<(Option<usize>, Mesh)>, String> {
    let label = m
        .name()
        .map(|n| format!("mesh `{n}`"))
        .unwrap_or(format!("mesh {}", m.index()));
    let mut parts = Vec::new();
    for prim in m.primitives() {
        // Points and lines have no area: nothing to render.
        if !matches!(
            prim.mode(),
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            continue;
        }
        for (_, accessor) in prim.attributes() {
            if accessor.count() == 0 {
                return Err(format!("{label}: an attribute accessor is empty"));
            }
        }
        // The reader trusts accessor types (gltf 1.4 reaches `unreachable!` on float indices,
        // found by fuzzing): check what it will be asked to read.
        use gltf::accessor::{DataType, Dimensions};
        for (semantic, accessor) in prim.attributes() {
            let vec3_f32 =
                accessor.data_type() == DataType::F32 && accessor.dimensions() == Dimensions::Vec3;
            if matches!(
                semantic,
                gltf::Semantic::Positions | gltf::Semantic::Normals
            ) && !vec3_f32
            {
                return Err(format!("{label}: {semantic:?} must be float VEC3"));
            }
        }
        if let Some(acc) = prim.indices()
            && (!matches!(
                acc.data_type(),
                DataType::U8 | DataType::U16 | DataType::U32
            ) || acc.dimensions() != Dimensions::Scalar)
        {
            return Err(format!("{label}: indices must be unsigned integer scalars"));
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| format!("{label}: positions are missing or outside their buffer"))?
            .map(Vec3::from)
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(format!("{label}: a vertex position is not finite"));
        }
        let normals: Option<Vec<Vec3>> = reader
            .read_normals()
            .map(|it| it.map(|n| Vec3::from(n).normalize_or_zero()).collect());
        let normals =
            normals.filter(|n| n.len() == positions.len() && n.iter().all(|v| v.is_finite()));
        // TEXCOORD_0 as written: glTF's v runs down the image, as Mitsuba's does.
        let uvs: Option<Vec<Vec2>> = reader
            .read_tex_coords(0)
            .map(|it| it.into_f32().map(Vec2::from).collect());
        let uvs = uvs.filter(|t| t.len() == positions.len() && t.iter().all(|v| v.is_finite()));
        let indices: Vec<u32> = match prim.indices() {
            Some(acc) if acc.count() == 0 => Vec::new(),
            Some(_) => reader
                .read_indices()
                .ok_or_else(|| format!("{label}: indices lie outside their buffer"))?
                .into_u32()
                .collect(),
            None => (0..positions.len() as u32).collect(),
        };
        if let Some(bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(format!(
                "{label}: index {bad} is out of range for {} vertices",
                positions.len()
            ));
        }
        if prim.mode() == Mode::Triangles && !indices.len().is_multiple_of(3) {
            return Err(format!(
                "{label}: a triangle list of {} {} is not a multiple of 3 (the list is truncated)",
                indices.len(),
                if prim.indices().is_some() {
                    "indices"
                } else {
                    "vertices"
                }
            ));
        }
        let triangles: Vec<[u32; 3]> = match prim.mode() {
            Mode::TriangleStrip => (2..indices.len())
                .map(|i| {
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            Mode::TriangleFan => (2..indices.len())
                .map(|i| [indices[0], indices[i - 1], indices[i]])
                .collect(),
            _ => indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        };
        parts.push((
            prim.material().index(),
            Mesh {
                positions,
                normals,
                indices: triangles,
                uvs,
            },
        ));
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One triangle with `TEXCOORD_0` (f32), in a buffer embedded as a data URI.
    fn triangle_with_uvs(uvs: [[f32; 2]; 3]) -> String {
        let mut bin = Vec::new();
        for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            bin.extend(p.iter().flat_map(|x| x.to_le_bytes()));
        }
        for uv in uvs {
            bin.extend(uv.iter().flat_map(|x| x.to_le_bytes()));
        }
        let data = base64::engine::general_purpose::STANDARD.encode(&bin);
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}}}}]}}],
            "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{data}"}}],
            "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}}]}}"#,
            len = bin.len()
        )
    }

    /// `TEXCOORD_0` is kept as written (glTF's v already runs down the image, as Mitsuba's);
    /// coordinates that are not finite are dropped, not an error.
    #[test]
    fn texture_coordinates_are_kept_as_written() {
        let uvs = [[0.0, 1.0], [1.0, 1.0], [0.25, 0.0]];
        let mesh = load_bytes(triangle_with_uvs(uvs).as_bytes(), Path::new("."), None).unwrap();
        assert_eq!(mesh.uvs.unwrap(), uvs.map(Vec2::from));
        let nan = [[0.0, f32::NAN], [1.0, 1.0], [0.25, 0.0]];
        let mesh = load_bytes(triangle_with_uvs(nan).as_bytes(), Path::new("."), None).unwrap();
        assert_eq!(mesh.uvs, None);
    }
}

//! Wavefront OBJ import: polygonal faces (`f`) over positions (`v`) and, when every face vertex
//! has one, vertex normals (`vn`) and texture coordinates (`vt`, with v turned to 1 − v as
//! Mitsuba 3 turns it, so that v = 0 is the top row of an image as in its other formats).
//!
//! Faces with more than three vertices are split into a fan from their first vertex (as
//! Mitsuba, pbrt and tinyobjloader do: exact for convex planar polygons). Indices may be
//! negative (relative to the last vertex defined so far). `o` and `g` name the faces that
//! follow, so that one object or group can be selected. Materials (`mtllib`, `usemtl`) are not
//! read, so an OBJ file never makes lumis open
//! another file; points and lines have no area and are skipped. Free-form geometry (curves and
//! surfaces) is refused rather than dropped.
//!
//! A small parser of our own rather than `tobj`: its errors are a bare kind without the line,
//! and a file that fails to load must say where and why.

use crate::geometry::Mesh;
use glam::{Vec2, Vec3};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

/// Loads the faces of an OBJ file, all of them or those of the object or group `only`.
pub fn load(path: &Path, only: Option<&str>) -> Result<Mesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read OBJ file: {e}"))?;
    parse(&bytes, only)
}

/// Free-form geometry, which would be lost if it were skipped.
const FREE_FORM: &[&str] = &[
    "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp",
    "end", "con",
];

/// One corner of a face: indices (from 0) of its position, normal and texture coordinates.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Corner {
    position: u32,
    normal: Option<u32>,
    texcoord: Option<u32>,
}

/// Parses OBJ text; errors name the line (from 1).
pub fn parse(bytes: &[u8], only: Option<&str>) -> Result<Mesh, String> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut texcoords: Vec<Vec2> = Vec::new();
    // Triangles of the selected faces, as corners.
    let mut triangles: Vec<[Corner; 3]> = Vec::new();
    let mut every_corner_has_a_normal = true;
    let mut every_corner_has_a_texcoord = true;
    let mut names: Vec<String> = Vec::new();
    let mut object = String::new();
    let mut groups: Vec<String> = Vec::new();
    let mut selected = only.is_none();
    let mut found = only.is_none();
    let mut face = Vec::new();

    for (number, line) in logical_lines(bytes) {
        let err = |m: String| format!("line {number}: {m}");
        let line = String::from_utf8_lossy(&line);
        let line = line.split('#').next().unwrap_or_default();
        let mut tokens = line.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => positions.push(vector(&mut tokens, "v", &[3, 4, 6, 7]).map_err(err)?),
            "vn" => {
                let n = vector(&mut tokens, "vn", &[3]).map_err(err)?;
                if n.length_squared() == 0.0 {
                    return Err(err("vertex normal of zero length".into()));
                }
                normals.push(n.normalize());
            }
            "vt" => {
                let (u, v) = texcoord(&mut tokens).map_err(err)?;
                texcoords.push(Vec2::new(u, 1.0 - v));
            }
            "o" | "g" => {
                let rest: Vec<String> = tokens.map(str::to_string).collect();
                if keyword == "o" {
                    object = rest.join(" ");
                    groups.clear();
                    names.push(object.clone());
                } else {
                    names.extend(rest.iter().cloned());
                    groups = rest;
                }
                selected =
                    only.is_none_or(|name| object == name || groups.iter().any(|g| g == name));
                found |= selected;
            }
            "f" => {
                face.clear();
                for token in tokens {
                    face.push(
                        corner(token, positions.len(), texcoords.len(), normals.len())
                            .map_err(err)?,
                    );
                }
                if face.len() < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 vertices, this one has {}",
                        face.len()
                    )));
                }
                if !selected {
                    continue;
                }
                every_corner_has_a_normal &= face.iter().all(|c| c.normal.is_some());
                every_corner_has_a_texcoord &= face.iter().all(|c| c.texcoord.is_some());
                for i in 2..face.len() {
                    triangles.push([face[0], face[i - 1], face[i]]);
                }
            }
            other if FREE_FORM.contains(&other) => {
                return Err(err(format!(
                    "free-form geometry (`{other}`) is not supported; export polygons"
                )));
            }
            // Texture-space vertices, smoothing groups, materials, points, lines, display
            // attributes and other exporters' extensions: nothing with area.
            _ => {}
        }
    }
    if !found {
        let name = only.unwrap_or_default();
        names.sort_unstable();
        names.dedup();
        return Err(format!(
            "no object or group named `{name}`{}; names in the file: {}",
            crate::error::did_you_mean(name, names.iter().map(String::as_str)),
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    }
    if triangles.is_empty() {
        return Err("the file has no faces".into());
    }
    // One vertex per distinct (position, normal, texture coordinates) corner, in order of first
    // use; a normal or texture coordinates only if every corner has them.
    let mut index: HashMap<Corner, u32> = HashMap::new();
    let mut mesh = Mesh {
        positions: Vec::new(),
        normals: every_corner_has_a_normal.then(Vec::new),
        indices: Vec::with_capacity(triangles.len()),
        uvs: every_corner_has_a_texcoord.then(Vec::new),
    };
    for triangle in &triangles {
        let mut t = [0u32; 3];
        for (k, c) in triangle.iter().enumerate() {
            let c = Corner {
                normal: c.normal.filter(|_| every_corner_has_a_normal),
                texcoord: c.texcoord.filter(|_| every_corner_has_a_texcoord),
                ..*c
            };
            t[k] = *index.entry(c).or_insert_with(|| {
                mesh.positions.push(positions[c.position as usize]);
                if let (Some(n), Some(i)) = (&mut mesh.normals, c.normal) {
                    n.push(normals[i as usize]);
                }
                if let (Some(uvs), Some(i)) = (&mut mesh.uvs, c.texcoord) {
                    uvs.push(texcoords[i as usize]);
                }
                mesh.positions.len() as u32 - 1
            });
        }
        mesh.indices.push(t);
    }
    Ok(mesh)
}

/// Lines numbered from 1, with `\` continuations joined (the number is the first line's), CR
/// stripped; borrowed unless joined.
fn logical_lines(bytes: &[u8]) -> impl Iterator<Item = (usize, Cow<'_, [u8]>)> + '_ {
    let mut physical = bytes.split(|&b| b == b'\n').enumerate();
    std::iter::from_fn(move || {
        let (first, line) = physical.next()?;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.last() != Some(&b'\\') {
            return Some((first + 1, Cow::Borrowed(line)));
        }
        let mut joined = line.to_vec();
        while joined.last() == Some(&b'\\') {
            joined.pop();
            joined.push(b' ');
            let Some((_, next)) = physical.next() else {
                break;
            };
            joined.extend_from_slice(next.strip_suffix(b"\r").unwrap_or(next));
        }
        Some((first + 1, Cow::Owned(joined)))
    })
}

/// The first three of `counts` (an allowed number of) finite numbers.
fn vector<'a>(
    tokens: &mut impl Iterator<Item = &'a str>,
    keyword: &str,
    counts: &[usize],
) -> Result<Vec3, String> {
    let mut values = Vec::with_capacity(7);
    for token in tokens {
        let value: f32 = token
            .parse()
            .map_err(|_| format!("`{keyword}`: `{token}` is not a number"))?;
        if !value.is_finite() {
            return Err(format!("`{keyword}`: `{token}` is not a finite number"));
        }
        values.push(value);
    }
    if !counts.contains(&values.len()) {
        return Err(format!(
            "`{keyword}` takes {} numbers, found {}",
            counts
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(" or "),
            values.len()
        ));
    }
    Ok(Vec3::new(values[0], values[1], values[2]))
}

/// The (u, v) of a `vt` line: one to three finite numbers, v 0 when absent (a 1D texture), the
/// third (w) read past.
fn texcoord<'a>(tokens: &mut impl Iterator<Item = &'a str>) -> Result<(f32, f32), String> {
    let mut values = Vec::with_capacity(3);
    for token in tokens {
        let value: f32 = token
            .parse()
            .map_err(|_| format!("`vt`: `{token}` is not a number"))?;
        if !value.is_finite() {
            return Err(format!("`vt`: `{token}` is not a finite number"));
        }
        values.push(value);
    }
    match values[..] {
        [u] => Ok((u, 0.0)),
        [u, v] | [u, v, _] => Ok((u, v)),
        _ => Err(format!("`vt` takes 1 to 3 numbers, found {}", values.len())),
    }
}

/// One face vertex `v`, `v/t`, `v//n` or `v/t/n`, with indices resolved against the counts
/// defined so far.
fn corner(
    token: &str,
    positions: usize,
    texcoords: usize,
    normals: usize,
) -> Result<Corner, String> {
    let mut split = token.split('/');
    let parts = [split.next(), split.next(), split.next()];
    if split.next().is_some() {
        return Err(format!("face vertex `{token}` has more than three indices"));
    }
    let position = resolve(parts[0].unwrap_or_default(), positions, "vertex", token)?;
    let texcoord = match parts[1].filter(|t| !t.is_empty()) {
        Some(t) => Some(resolve(t, texcoords, "texture coordinate", token)?),
        None => None,
    };
    let normal = match parts[2].filter(|n| !n.is_empty()) {
        Some(n) => Some(resolve(n, normals, "normal", token)?),
        None => None,
    };
    Ok(Corner {
        position,
        normal,
        texcoord,
    })
}

/// An OBJ index (from 1, or negative from the end) as an index from 0 into `count` items.
fn resolve(text: &str, count: usize, what: &str, token: &str) -> Result<u32, String> {
    let i: i64 = text
        .parse()
        .map_err(|_| format!("face vertex `{token}`: `{text}` is not an index"))?;
    let resolved = if i > 0 { i - 1 } else { count as i64 + i };
    if i == 0 || resolved < 0 || resolved >= count as i64 {
        return Err(format!(
            "face vertex `{token}` refers to {what} {i}, but {count} are defined before it"
        ));
    }
    u32::try_from(resolved).map_err(|_| format!("face vertex `{token}`: index {i} is too large"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_are_fans_and_negative_indices_count_back() {
        let text = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n";
        let m = parse(text, None).unwrap();
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.normals, None);
    }

    #[test]
    fn corners_with_one_position_and_two_normals_are_two_vertices() {
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 2\n\
                     f 1//1 2//1 3//1\nf 1//2 3//2 2//2\n";
        let m = parse(text, None).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.normals.as_ref().unwrap()[3], Vec3::Z);
        assert_eq!(m.indices, vec![[0, 1, 2], [3, 4, 5]]);
    }

    /// Texture coordinates are kept (v turned to 1 − v, as Mitsuba reads OBJ) when every corner
    /// has them; a corner is a vertex per distinct position, normal and texture coordinates.
    #[test]
    fn texture_coordinates_are_kept_per_corner_with_v_turned() {
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.75\nvt 1 0\nvt 0.5\n\
                     f 1/1 2/2 3/3\nf 1/2 3/3 2/2\n";
        let m = parse(text, None).unwrap();
        let uvs = m.uvs.as_ref().unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(
            uvs[..],
            [
                Vec2::new(0.25, 0.25),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.5, 1.0),
                Vec2::new(1.0, 1.0)
            ]
        );
        assert_eq!(m.indices, vec![[0, 1, 2], [3, 2, 1]]);
        // A corner without: none are kept, and corners are by position (and normal) only.
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3\n";
        assert_eq!(parse(text, None).unwrap().uvs, None);
        let e = parse(b"vt 0 nan\n", None).unwrap_err();
        assert!(
            e.starts_with("line 1: ") && e.contains("not a finite number"),
            "{e}"
        );
        let e = parse(b"vt\n", None).unwrap_err();
        assert!(e.contains("`vt` takes 1 to 3 numbers, found 0"), "{e}");
    }

    #[test]
    fn groups_and_objects_select_faces() {
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\no a\nf 1 2 3\ng b c\nf 1 2 4\n";
        assert_eq!(parse(text, Some("a")).unwrap().indices.len(), 2);
        assert_eq!(parse(text, Some("c")).unwrap().indices.len(), 1);
        let e = parse(text, Some("d")).unwrap_err();
        assert!(e.contains("names in the file: a, b, c"), "{e}");
    }

    #[test]
    fn errors_name_the_line() {
        for (text, line, needle) in [
            (
                &b"v 0 0 0\nv 1 0\n"[..],
                2,
                "takes 3 or 4 or 6 or 7 numbers",
            ),
            (
                b"v 0 0 0\nv 1 0 0\n\nf 1 2 3\n",
                4,
                "refers to vertex 3, but 2",
            ),
            (b"v 0 0 nan\n", 1, "not a finite number"),
            (b"v 0 0 0\nf 1 0 1\n", 2, "refers to vertex 0"),
            (
                b"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3/1\n",
                4,
                "texture coordinate 1",
            ),
            (b"surf 0 1 0 1 1 2 3\n", 1, "free-form"),
            (b"v 0 0 \\\n0\nv 1 0 0\nf 1 2\n", 4, "at least 3 vertices"),
        ] {
            let e = parse(text, None).unwrap_err();
            assert!(
                e.starts_with(&format!("line {line}: ")) && e.contains(needle),
                "{e}"
            );
        }
    }
}

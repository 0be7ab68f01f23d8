//! Stanford PLY import (ASCII, binary little- and big-endian): the `vertex` element's `x`, `y`,
//! `z`, when all three are present `nx`, `ny`, `nz` as vertex normals, and when a pair is present
//! `u`, `v` (or `s`, `t`, or `texture_u`, `texture_v`, as Mitsuba 3 reads them) as texture
//! coordinates; the `face` element's `vertex_indices` (or `vertex_index`) lists, polygons split
//! into fans from their first vertex. Other elements and properties (colours, edges, materials)
//! are read past.
//!
//! A small parser of our own rather than `ply-rs`: that crate has had no release since 2018,
//! its maintained fork needs a newer Rust than lumis supports, and neither reports the line or
//! byte where a file goes wrong. Every count is checked against the bytes the file holds before
//! anything is allocated for it.
//!
//! Why one file of over 600 lines: the header parser and the ASCII and binary body readers share
//! the property layout they check; with its tests.

use crate::geometry::Mesh;
use glam::{Vec2, Vec3};
use std::path::Path;

/// Loads the faces of a PLY file.
pub fn load(path: &Path) -> Result<Mesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read PLY file: {e}"))?;
    parse(&bytes)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
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
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
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

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from exactly `size()` bytes.
    fn decode(self, b: &[u8], format: Format) -> f64 {
        macro_rules! read {
            ($t:ty) => {{
                let bytes = b.try_into().expect("size checked by the caller");
                (if format == Format::BinaryBigEndian {
                    <$t>::from_be_bytes(bytes)
                } else {
                    <$t>::from_le_bytes(bytes)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => read!(i16),
            Scalar::U16 => read!(u16),
            Scalar::I32 => read!(i32),
            Scalar::U32 => read!(u32),
            Scalar::F32 => read!(f32),
            Scalar::F64 => read!(f64),
        }
    }

    /// Parses one ASCII value of this type.
    fn parse_text(self, token: &str) -> Option<f64> {
        if self.is_integer() {
            let v: i64 = token.parse().ok()?;
            let (lo, hi) = match self {
                Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
                Scalar::U8 => (0, u8::MAX as i64),
                Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
                Scalar::U16 => (0, u16::MAX as i64),
                Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
                _ => (0, u32::MAX as i64),
            };
            (lo..=hi).contains(&v).then_some(v as f64)
        } else {
            token.parse().ok()
        }
    }
}

#[derive(Clone, Debug)]
enum Kind {
    Scalar(Scalar),
    /// Count type, item type.
    List(Scalar, Scalar),
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    /// The fewest bytes one instance takes in a binary file (lists empty).
    fn min_size(&self) -> u64 {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) | Kind::List(s, _) => s.size() as u64,
            })
            .sum()
    }

    fn position(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

/// Where the reader is: a line of an ASCII file, or a byte offset of a binary one.
fn place(format: Format, line: usize, offset: usize) -> String {
    match format {
        Format::Ascii => format!("line {line}"),
        _ => format!("byte {offset}"),
    }
}

/// Parses a whole PLY file.
pub fn parse(bytes: &[u8]) -> Result<Mesh, String> {
    let Header {
        format,
        elements,
        body,
        lines: header_lines,
    } = parse_header(bytes)?;
    let header_len = bytes.len() - body.len();
    let mut reader = Reader {
        format,
        bytes: body,
        offset: 0,
        header_len,
        line: header_lines,
    };
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Option<Vec<Vec3>> = None;
    let mut uvs: Option<Vec<Vec2>> = None;
    let mut indices: Vec<[u32; 3]> = Vec::new();
    // Faces may come before the vertices: their indices are checked against the declared count
    // (which the vertex element must then fill).
    let vertex_count = elements
        .iter()
        .find(|e| e.name == "vertex")
        .map_or(0, |e| e.count);
    let mut seen_vertex = false;
    let mut seen_face = false;
    let mut values: Vec<f64> = Vec::new();
    let mut list: Vec<i64> = Vec::new();
    for element in &elements {
        let bound = reader.max_instances(element);
        if element.count > bound {
            return Err(format!(
                "element `{}` declares {} instances, but the rest of the file holds at most {bound}",
                element.name, element.count
            ));
        }
        let count = element.count as usize;
        match element.name.as_str() {
            "vertex" if !seen_vertex => {
                seen_vertex = true;
                let xyz = ["x", "y", "z"].map(|n| element.position(n));
                let [Some(x), Some(y), Some(z)] = xyz else {
                    return Err("element `vertex` needs properties x, y and z".into());
                };
                for (name, index) in ["x", "y", "z"].iter().zip([x, y, z]) {
                    if !matches!(element.properties[index].kind, Kind::Scalar(_)) {
                        return Err(format!("vertex property `{name}` must not be a list"));
                    }
                }
                let n = ["nx", "ny", "nz"].map(|n| element.position(n));
                let normal_at = match n {
                    [Some(a), Some(b), Some(c)]
                        if [a, b, c]
                            .iter()
                            .all(|&i| matches!(element.properties[i].kind, Kind::Scalar(_))) =>
                    {
                        Some([a, b, c])
                    }
                    _ => None,
                };
                let scalar = |i: usize| matches!(element.properties[i].kind, Kind::Scalar(_));
                let uv_at = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"]]
                    .iter()
                    .find_map(|names| match names.map(|n| element.position(n)) {
                        [Some(u), Some(v)] if scalar(u) && scalar(v) => Some([u, v]),
                        _ => None,
                    });
                positions.reserve(count);
                let mut found_normals = normal_at.map(|_| Vec::with_capacity(count));
                let mut found_uvs = uv_at.map(|_| Vec::with_capacity(count));
                for v in 0..count {
                    let at = reader.place();
                    reader.instance(element, &mut values, &mut |_, _| Ok(()))?;
                    let p = Vec3::new(values[x] as f32, values[y] as f32, values[z] as f32);
                    if !p.is_finite() {
                        return Err(format!("{at}: vertex {v} position {p} is not finite"));
                    }
                    positions.push(p);
                    if let (Some(normals), Some([a, b, c])) = (&mut found_normals, normal_at) {
                        let n = Vec3::new(values[a] as f32, values[b] as f32, values[c] as f32);
                        if !n.is_finite() || n.length_squared() == 0.0 {
                            return Err(format!(
                                "{at}: vertex {v} normal {n} is not finite or has zero length"
                            ));
                        }
                        normals.push(n.normalize());
                    }
                    if let (Some(uvs), Some([iu, iv])) = (&mut found_uvs, uv_at) {
                        let uv = Vec2::new(values[iu] as f32, values[iv] as f32);
                        if !uv.is_finite() {
                            return Err(format!(
                                "{at}: vertex {v} texture coordinates {uv} are not finite"
                            ));
                        }
                        uvs.push(uv);
                    }
                }
                normals = found_normals;
                uvs = found_uvs;
            }
            "face" if !seen_face => {
                seen_face = true;
                let index_list = element
                    .position("vertex_indices")
                    .or_else(|| element.position("vertex_index"))
                    .ok_or("element `face` needs a list property `vertex_indices`")?;
                match element.properties[index_list].kind {
                    Kind::List(_, item) if item.is_integer() => {}
                    _ => {
                        return Err(format!(
                            "face property `{}` must be a list of integers",
                            element.properties[index_list].name
                        ));
                    }
                }
                indices.reserve(count);
                for f in 0..count {
                    let start = reader.place();
                    list.clear();
                    reader.instance(element, &mut values, &mut |property, item| {
                        if property == index_list {
                            list.push(item as i64);
                        }
                        Ok(())
                    })?;
                    // An ASCII face is on the line just read; a binary one starts where it began.
                    let at = match format {
                        Format::Ascii => reader.place_of_last_line(),
                        _ => start,
                    };
                    if list.len() < 3 {
                        return Err(format!(
                            "{at}: face {f} has {} vertices; a face needs at least 3",
                            list.len()
                        ));
                    }
                    if let Some(bad) = list.iter().find(|&&i| i < 0 || i as u64 >= vertex_count) {
                        return Err(format!(
                            "{at}: face {f} refers to vertex {bad}, but the file has {vertex_count}"
                        ));
                    }
                    for i in 2..list.len() {
                        indices.push([list[0] as u32, list[i - 1] as u32, list[i] as u32]);
                    }
                }
            }
            _ => {
                for _ in 0..count {
                    reader.instance(element, &mut values, &mut |_, _| Ok(()))?;
                }
            }
        }
    }
    if !seen_vertex || !seen_face {
        return Err("a mesh needs elements `vertex` and `face`".into());
    }
    if indices.is_empty() {
        return Err("the file has no faces".into());
    }
    Ok(Mesh {
        positions,
        normals,
        indices,
        uvs,
    })
}

/// What the header declares, and where the body starts.
struct Header<'a> {
    format: Format,
    elements: Vec<Element>,
    /// The bytes after `end_header`.
    body: &'a [u8],
    /// The header's line count.
    lines: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header<'_>, String> {
    let mut rest = bytes;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut number = 0usize;
    loop {
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return Err(if number == 0 {
                "not a PLY file (no header)".into()
            } else {
                "the header has no `end_header`".into()
            });
        };
        let raw = &rest[..end];
        rest = &rest[end + 1..];
        number += 1;
        let err = |m: String| format!("line {number}: {m}");
        let line = std::str::from_utf8(raw)
            .map_err(|_| err("the header is not text".into()))?
            .trim_end_matches('\r');
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        if number == 1 {
            if line.trim() != "ply" {
                return Err("not a PLY file (the first line is not `ply`)".into());
            }
            continue;
        }
        match tokens.as_slice() {
            ["format", name, version] => {
                if *version != "1.0" {
                    return Err(err(format!("unsupported PLY version {version}")));
                }
                format = Some(match *name {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLittleEndian,
                    "binary_big_endian" => Format::BinaryBigEndian,
                    other => return Err(err(format!("unknown format `{other}`"))),
                });
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| err(format!("element count `{count}` is not a count")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count, item, name] => {
                let count = Scalar::parse(count)
                    .filter(|s| s.is_integer())
                    .ok_or_else(|| err(format!("list count type `{count}` is not an integer")))?;
                let item = Scalar::parse(item)
                    .ok_or_else(|| err(format!("unknown property type `{item}`")))?;
                push_property(&mut elements, name, Kind::List(count, item)).map_err(err)?;
            }
            ["property", kind, name] => {
                let kind = Scalar::parse(kind)
                    .ok_or_else(|| err(format!("unknown property type `{kind}`")))?;
                push_property(&mut elements, name, Kind::Scalar(kind)).map_err(err)?;
            }
            ["end_header"] => break,
            _ => return Err(err(format!("unrecognised header line `{line}`"))),
        }
    }
    let format = format.ok_or("the header has no `format` line")?;
    Ok(Header {
        format,
        elements,
        body: rest,
        lines: number,
    })
}

fn push_property(elements: &mut [Element], name: &str, kind: Kind) -> Result<(), String> {
    let element = elements
        .last_mut()
        .ok_or("a property comes before any element")?;
    if element.position(name).is_some() {
        return Err(format!(
            "element `{}` has two properties `{name}`",
            element.name
        ));
    }
    element.properties.push(Property {
        name: name.to_string(),
        kind,
    });
    Ok(())
}

/// Reads element instances from the body.
struct Reader<'a> {
    format: Format,
    bytes: &'a [u8],
    /// Offset in `bytes` (the body).
    offset: usize,
    header_len: usize,
    /// The line last read (ASCII).
    line: usize,
}

impl Reader<'_> {
    /// Where the next instance starts.
    fn place(&self) -> String {
        place(self.format, self.line + 1, self.header_len + self.offset)
    }

    fn place_of_last_line(&self) -> String {
        format!("line {}", self.line)
    }

    /// An upper bound on how many instances of `element` the rest of the body can hold.
    fn max_instances(&self, element: &Element) -> u64 {
        let rest = &self.bytes[self.offset..];
        match self.format {
            // Each instance is on a line of its own.
            Format::Ascii => rest.iter().filter(|&&b| b == b'\n').count() as u64 + 1,
            _ => match element.min_size() {
                0 => 0,
                size => rest.len() as u64 / size,
            },
        }
    }

    /// Reads one instance: scalar properties into `values` (by property index; lists leave
    /// 0 there), and each list item to `on_item(property, value)`.
    fn instance(
        &mut self,
        element: &Element,
        values: &mut Vec<f64>,
        on_item: &mut dyn FnMut(usize, f64) -> Result<(), String>,
    ) -> Result<(), String> {
        values.clear();
        match self.format {
            Format::Ascii => self.ascii_instance(element, values, on_item),
            _ => self.binary_instance(element, values, on_item),
        }
    }

    fn ascii_instance(
        &mut self,
        element: &Element,
        values: &mut Vec<f64>,
        on_item: &mut dyn FnMut(usize, f64) -> Result<(), String>,
    ) -> Result<(), String> {
        // Skip blank lines; the instance is the next line with text.
        let text = loop {
            let rest = &self.bytes[self.offset..];
            if rest.is_empty() {
                return Err(format!(
                    "line {}: the file ends inside element `{}`",
                    self.line + 1,
                    element.name
                ));
            }
            let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            self.offset += (end + 1).min(rest.len());
            self.line += 1;
            let line = std::str::from_utf8(&rest[..end])
                .map_err(|_| format!("line {}: not text", self.line))?;
            if !line.trim().is_empty() {
                break line;
            }
        };
        let err = |m: String| format!("line {}: {m}", self.line);
        let mut tokens = text.split_ascii_whitespace();
        let mut next = |ty: Scalar, what: &str| -> Result<f64, String> {
            let token = tokens
                .next()
                .ok_or_else(|| err(format!("element `{}` ends before {what}", element.name)))?;
            ty.parse_text(token)
                .ok_or_else(|| err(format!("{what}: `{token}` is not a valid {ty:?} value")))
        };
        for (i, p) in element.properties.iter().enumerate() {
            match p.kind {
                Kind::Scalar(ty) => values.push(next(ty, &format!("property `{}`", p.name))?),
                Kind::List(count_type, item) => {
                    values.push(0.0);
                    let n = next(count_type, &format!("the length of list `{}`", p.name))?;
                    if n < 0.0 {
                        return Err(err(format!("list `{}` has negative length {n}", p.name)));
                    }
                    for _ in 0..n as u64 {
                        let v = next(item, &format!("an item of list `{}`", p.name))?;
                        on_item(i, v)?;
                    }
                }
            }
        }
        if let Some(extra) = tokens.next() {
            return Err(err(format!(
                "element `{}` has more values than its properties (`{extra}`)",
                element.name
            )));
        }
        Ok(())
    }

    fn binary_instance(
        &mut self,
        element: &Element,
        values: &mut Vec<f64>,
        on_item: &mut dyn FnMut(usize, f64) -> Result<(), String>,
    ) -> Result<(), String> {
        for (i, p) in element.properties.iter().enumerate() {
            match p.kind {
                Kind::Scalar(ty) => values.push(self.binary_value(ty, element)?),
                Kind::List(count_type, item) => {
                    values.push(0.0);
                    let at = self.place();
                    let n = self.binary_value(count_type, element)?;
                    if n < 0.0 {
                        return Err(format!("{at}: list `{}` has negative length {n}", p.name));
                    }
                    let n = n as u64;
                    let remaining = (self.bytes.len() - self.offset) as u64;
                    if n.saturating_mul(item.size() as u64) > remaining {
                        return Err(format!(
                            "{at}: list `{}` of {n} items runs past the end of the file",
                            p.name
                        ));
                    }
                    for _ in 0..n {
                        let v = self.binary_value(item, element)?;
                        on_item(i, v)?;
                    }
                }
            }
        }
        Ok(())
    }

    fn binary_value(&mut self, ty: Scalar, element: &Element) -> Result<f64, String> {
        let size = ty.size();
        let Some(b) = self.bytes.get(self.offset..self.offset + size) else {
            return Err(format!(
                "{}: the file ends inside element `{}`",
                self.place(),
                element.name
            ));
        };
        self.offset += size;
        Ok(ty.decode(b, self.format))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII_QUAD: &str = "ply\nformat ascii 1.0\ncomment a unit square\n\
        element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        property uchar red\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0 0\n4 0 1 2 3\n";

    #[test]
    fn ascii_quads_are_fans() {
        let m = parse(ASCII_QUAD.as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.normals, None);
    }

    /// Texture coordinates under each of the names Mitsuba reads, as written (no v turned).
    #[test]
    fn texture_coordinates_are_read_under_each_name() {
        for (u, v) in [("u", "v"), ("s", "t"), ("texture_u", "texture_v")] {
            let text = ASCII_QUAD.replace(
                "property uchar red",
                &format!("property uchar red\nproperty float {u}\nproperty float {v}"),
            );
            let text = text
                .replace("0 0 0 255\n", "0 0 0 255 0 0.25\n")
                .replace("1 0 0 0\n1 1", "1 0 0 0 1 0.25\n1 1")
                .replace("1 1 0 0\n", "1 1 0 0 1 1\n")
                .replace("0 1 0 0\n", "0 1 0 0 0 1\n");
            let m = parse(text.as_bytes()).unwrap();
            assert_eq!(
                m.uvs.unwrap(),
                [[0.0, 0.25], [1.0, 0.25], [1.0, 1.0], [0.0, 1.0]].map(Vec2::from),
                "{u}, {v}"
            );
        }
        // Only one of a pair: none.
        let one = ASCII_QUAD.replace("property uchar red", "property uchar red\nproperty float u");
        let one = one
            .replace(" 255\n", " 255 0\n")
            .replace("\n1 0 0 0\n", "\n1 0 0 0 0\n");
        let one = one
            .replace("\n1 1 0 0\n", "\n1 1 0 0 0\n")
            .replace("\n0 1 0 0\n", "\n0 1 0 0 0\n");
        assert_eq!(parse(one.as_bytes()).unwrap().uvs, None);
        let nan = ASCII_QUAD.replace(
            "property uchar red",
            "property uchar red\nproperty float s\nproperty float t",
        );
        let nan = nan
            .replace(" 255\n", " 255 0 nan\n")
            .replace("\n1 0 0 0\n", "\n1 0 0 0 0 0\n");
        let nan = nan
            .replace("\n1 1 0 0\n", "\n1 1 0 0 0 0\n")
            .replace("\n0 1 0 0\n", "\n0 1 0 0 0 0\n");
        let e = parse(nan.as_bytes()).unwrap_err();
        assert!(
            e.contains("line 14: vertex 0 texture coordinates") && e.contains("not finite"),
            "{e}"
        );
    }

    #[test]
    fn errors_name_the_line_or_byte() {
        for (text, needle) in [
            (
                ASCII_QUAD.replace("4 0 1 2 3", "4 0 1 2 4"),
                "line 16: face 0 refers to vertex 4",
            ),
            (
                ASCII_QUAD.replace("1 1 0 0\n", "1 nan 0 0\n"),
                "line 14: vertex 2",
            ),
            (
                ASCII_QUAD.replace("1 1 0 0\n", "1 1 0\n"),
                "line 14: element `vertex` ends",
            ),
            (
                ASCII_QUAD.replace("element face 1", "element face 99"),
                "declares 99",
            ),
            (
                ASCII_QUAD.replace("uchar red", "uchar red\nproperty uchar red"),
                "two properties",
            ),
            (
                ASCII_QUAD.replace("format ascii", "format ebcdic"),
                "line 2: unknown format",
            ),
            (ASCII_QUAD.replace("4 0 1 2 3", "2 0 1"), "at least 3"),
        ] {
            let e = parse(text.as_bytes()).unwrap_err();
            assert!(e.contains(needle), "{e}");
        }
        // Binary: a list that claims more items than the file holds.
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\n\
            property list uint int vertex_indices\nend_header\n"
            .to_vec();
        let header = b.len();
        b.extend(std::iter::repeat_n(0u8, 36));
        b.extend(u32::MAX.to_be_bytes());
        let e = parse(&b).unwrap_err();
        assert!(
            e.contains(&format!(
                "byte {}: list `vertex_indices` of 4294967295",
                header + 36
            )),
            "{e}"
        );
    }
}

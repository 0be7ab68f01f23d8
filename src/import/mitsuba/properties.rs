//! Reading Mitsuba XML: attributes with `$name` parameters substituted, and a plugin element's
//! properties through a typed reader that remembers which ones were read, so that every property
//! no converter read is reported, once, with its line.

use super::files::{Version, substitute};
use super::spectrum::{self, Spectrum};
use super::{Report, transform};
use glam::{DMat4, DVec3};
use roxmltree::Node;
use std::collections::BTreeMap;

/// The line of `node` in the XML file, from 1.
pub(super) fn line(node: &Node) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

/// Attribute reader: the scene's `<default>` parameters (and `-D` overrides) substituted for
/// `$name` in every attribute value.
pub(super) struct Xml {
    parameters: BTreeMap<String, String>,
}

impl Xml {
    /// A reader substituting `parameters` (from [`super::files::Sources`]).
    pub(super) fn new(parameters: BTreeMap<String, String>) -> Self {
        Xml { parameters }
    }

    /// An attribute with `$name` parameters substituted.
    pub(super) fn attribute(&self, node: &Node, name: &str) -> Result<Option<String>, String> {
        let Some(raw) = node.attribute(name) else {
            return Ok(None);
        };
        substitute(raw, &self.parameters)
            .map(Some)
            .map_err(|e| format!("line {}: {e}", line(node)))
    }

    pub(super) fn required(&self, node: &Node, name: &str) -> Result<String, String> {
        self.attribute(node, name)?.ok_or_else(|| {
            format!(
                "line {}: <{}> needs a `{name}` attribute",
                line(node),
                node.tag_name().name()
            )
        })
    }

    /// The finite numbers of `text`, separated by commas or white space.
    pub(super) fn numbers(&self, node: &Node, text: &str) -> Result<Vec<f64>, String> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| format!("line {}: `{t}` is not a finite number", line(node)))
            })
            .collect()
    }

    /// A point or vector: `value="x, y, z"` or attributes `x`, `y`, `z` (default `missing`).
    pub(super) fn vector(&self, node: &Node, missing: f64) -> Result<DVec3, String> {
        if let Some(v) = self.attribute(node, "value")? {
            let n = self.numbers(node, &v)?;
            return match n.as_slice() {
                [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                [s] => Ok(DVec3::splat(*s)),
                _ => Err(format!("line {}: expected 3 numbers in `{v}`", line(node))),
            };
        }
        let mut out = [missing; 3];
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            if let Some(t) = self.attribute(node, axis)? {
                out[i] = self.numbers(node, &t)?.first().copied().unwrap_or(missing);
            }
        }
        Ok(DVec3::from(out))
    }
}

/// A property value as written in the XML.
#[derive(Clone, Debug)]
pub(super) enum Value {
    Float(f64),
    Int(i64),
    Bool(bool),
    Str(String),
    /// `rgb` (or a 0.x `srgb`, made linear).
    Color([f64; 3]),
    /// `spectrum`: one value, or wavelength:value pairs.
    Spectrum(Spectrum),
    /// `point` or `vector`.
    Vector(DVec3),
    Transform(DMat4),
    /// A value already reported as not converted (a blackbody spectrum): whatever reads it
    /// gets nothing, not a default.
    Refused,
}

struct Property {
    value: Value,
    line: u32,
    read: bool,
}

/// A plugin element: its `type`, its properties by name, and its nested objects (plugins and
/// references). Read each property through the typed readers; [`Properties::finish`] reports
/// the ones never read.
pub(super) struct Properties<'a, 'input> {
    pub kind: String,
    /// Line of the element.
    pub line: u32,
    pub objects: Vec<Node<'a, 'input>>,
    /// Refused as a whole ([`super::Converter::refuse`]): `finish` reports nothing more.
    pub refused: bool,
    /// From a file older than Mitsuba 2: the names of nested objects are upgraded too
    /// ([`Properties::name_of`]).
    legacy: bool,
    properties: BTreeMap<String, Property>,
}

/// Mitsuba 3's `upgrade_from_v1` name for a property of a file older than 2.0: camelCase to
/// snake_case (a capital after a lower-case letter starts a word; the capitals right after it
/// join that word: `intIOR` is `int_ior`).
pub fn snake_case(name: &str) -> String {
    let chars: Vec<char> = name.chars().collect();
    let mut out = String::with_capacity(name.len() + 4);
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if i > 0 && chars[i - 1].is_ascii_lowercase() && c.is_ascii_uppercase() {
            out.push('_');
            out.push(c.to_ascii_lowercase());
            while i + 1 < chars.len() && chars[i + 1].is_ascii_uppercase() {
                i += 1;
                out.push(chars[i].to_ascii_lowercase());
            }
        } else {
            out.push(c);
        }
        i += 1;
    }
    out
}

/// A property name as Mitsuba 3 reads it from a file of `version` inside a plugin of type
/// `kind`.
pub fn upgraded_name(name: &str, kind: &str, version: Version) -> String {
    if !version.is_legacy() {
        return name.to_string();
    }
    let name = snake_case(name);
    if kind == "diffuse" && name == "diffuse_reflectance" {
        return "reflectance".into();
    }
    name
}

/// Why a blackbody spectrum is refused.
const BLACKBODY: &str = "a blackbody spectrum is not converted: lumis renders in RGB, where \
                         Mitsuba's RGB variants refuse it too (\"Not implemented for non-spectral \
                         modes\")";

/// An 8-bit sRGB-encoded value in [0, 1], linear.
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Reads the properties of the plugin element `node`, from a file of `version`; property
/// elements lumis does not know become problems.
pub(super) fn read<'a, 'input>(
    node: &Node<'a, 'input>,
    xml: &Xml,
    report: &mut Report,
    version: Version,
) -> Result<Properties<'a, 'input>, String> {
    let mut props = Properties {
        kind: xml.attribute(node, "type")?.unwrap_or_default(),
        line: line(node),
        objects: Vec::new(),
        refused: false,
        legacy: version.is_legacy(),
        properties: BTreeMap::new(),
    };
    for child in node.children().filter(Node::is_element) {
        let tag = child.tag_name().name();
        let at = line(&child);
        let value = || xml.required(&child, "value");
        let parsed = match tag {
            "float" => {
                let v = value()?;
                match xml.numbers(&child, &v)?.as_slice() {
                    [x] => Value::Float(*x),
                    _ => return Err(format!("line {at}: `{v}` is not one number")),
                }
            }
            "integer" => {
                let v = value()?;
                Value::Int(
                    v.trim()
                        .parse()
                        .map_err(|_| format!("line {at}: `{v}` is not an integer"))?,
                )
            }
            "boolean" => {
                let v = value()?;
                Value::Bool(match v.trim().to_ascii_lowercase().as_str() {
                    "true" => true,
                    "false" => false,
                    _ => return Err(format!("line {at}: `{v}` is not true or false")),
                })
            }
            "string" => Value::Str(value()?),
            "rgb" => {
                let v = value()?;
                match xml.numbers(&child, &v)?.as_slice() {
                    [g] => Value::Color([*g; 3]),
                    [r, g, b] => Value::Color([*r, *g, *b]),
                    _ => return Err(format!("line {at}: `{v}` is not 1 or 3 numbers")),
                }
            }
            // Mitsuba 0.x: an sRGB-encoded colour (numbers in [0, 1] or #rrggbb).
            "srgb" if version.is_legacy() => {
                let v = value()?;
                let encoded: Vec<f64> = match v.trim().strip_prefix('#') {
                    Some(hex) if hex.len() == 6 && hex.is_ascii() => (0..3)
                        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).map(f64::from))
                        .collect::<Result<Vec<f64>, _>>()
                        .map_err(|_| format!("line {at}: `{v}` is not #rrggbb"))?
                        .into_iter()
                        .map(|c| c / 255.0)
                        .collect(),
                    _ => xml.numbers(&child, &v)?,
                };
                let linear: Vec<f64> = encoded.iter().map(|&c| srgb_to_linear(c)).collect();
                match linear.as_slice() {
                    [g] => Value::Color([*g; 3]),
                    [r, g, b] => Value::Color([*r, *g, *b]),
                    _ => return Err(format!("line {at}: `{v}` is not 1 or 3 numbers")),
                }
            }
            "spectrum" if child.attribute("type") == Some("blackbody") => {
                report.problem(at, BLACKBODY);
                Value::Refused
            }
            "blackbody" if version.is_legacy() => {
                report.problem(at, BLACKBODY);
                Value::Refused
            }
            "spectrum" if child.attribute("type").is_some() => {
                props.objects.push(child);
                continue;
            }
            "spectrum" => {
                if child.attribute("filename").is_some() {
                    report.problem(at, "a <spectrum> read from a file is not converted");
                    continue;
                }
                let v = value()?;
                Value::Spectrum(
                    spectrum::parse(&v).map_err(|e| format!("line {at}: <spectrum>: {e}"))?,
                )
            }
            "point" | "vector" => Value::Vector(xml.vector(&child, 0.0)?),
            "transform" => match transform::read(&child, xml, report, version)? {
                Some(m) => Value::Transform(m),
                None => continue,
            },
            "ref" | "bsdf" | "emitter" | "film" | "sampler" | "rfilter" | "texture" | "shape"
            | "medium" | "phase" | "volume" | "integrator" | "sensor" => {
                props.objects.push(child);
                continue;
            }
            other => {
                report.problem(at, format!("<{other}> is not converted"));
                continue;
            }
        };
        let name = upgraded_name(&xml.required(&child, "name")?, &props.kind, version);
        props.properties.insert(
            name,
            Property {
                value: parsed,
                line: at,
                read: false,
            },
        );
    }
    if version.is_legacy() {
        props.upgrade_uv_transform();
    }
    Ok(props)
}

impl Properties<'_, '_> {
    /// Mitsuba 3's upgrade of a 0.x texture's `uoffset`, `voffset`, `uscale`, `vscale` into
    /// `to_uv` = scale · translate.
    fn upgrade_uv_transform(&mut self) {
        let names = ["uoffset", "voffset", "uscale", "vscale"];
        if !names.iter().any(|n| self.properties.contains_key(*n)) {
            return;
        }
        let mut number = |name: &str, default: f64| {
            let found = self.properties.remove(name);
            let line = found.as_ref().map(|p| p.line);
            let value = match found.map(|p| p.value) {
                Some(Value::Float(x)) => x,
                Some(Value::Int(n)) => n as f64,
                _ => default,
            };
            (value, line)
        };
        let (uo, l1) = number("uoffset", 0.0);
        let (vo, l2) = number("voffset", 0.0);
        let (us, l3) = number("uscale", 1.0);
        let (vs, l4) = number("vscale", 1.0);
        let m = DMat4::from_scale(DVec3::new(us, vs, 1.0))
            * DMat4::from_translation(DVec3::new(uo, vo, 0.0));
        self.properties.insert(
            "to_uv".into(),
            Property {
                value: Value::Transform(m),
                line: [l1, l2, l3, l4]
                    .into_iter()
                    .flatten()
                    .next()
                    .unwrap_or(self.line),
                read: false,
            },
        );
    }

    /// The name a nested object (`<texture name="...">`, a `<ref name>`) is given in its
    /// element, upgraded as its properties' names are in files older than Mitsuba 2.
    pub(super) fn name_of(&self, object: &Node) -> Option<String> {
        let name = object.attribute("name")?;
        Some(upgraded_name(
            name,
            &self.kind,
            if self.legacy {
                Version(0, 0, 0)
            } else {
                Version(3, 0, 0)
            },
        ))
    }

    /// The value and line of property `name`, which counts as read.
    pub(super) fn take(&mut self, name: &str) -> Option<(Value, u32)> {
        let property = self.properties.get_mut(name)?;
        property.read = true;
        Some((property.value.clone(), property.line))
    }

    /// Whether property `name` or a nested object (a texture) of that name is given.
    pub(super) fn has(&self, name: &str) -> bool {
        self.properties.contains_key(name)
            || self
                .objects
                .iter()
                .any(|o| self.name_of(o).as_deref() == Some(name))
    }

    /// Marks property `name` as read without using it (it does not change the image).
    pub(super) fn ignore(&mut self, name: &str) {
        self.take(name);
    }

    /// A number (`float` or `integer`) and its line.
    pub(super) fn number(&mut self, name: &str) -> Result<Option<(f64, u32)>, String> {
        match self.take(name) {
            Some((Value::Float(x), l)) => Ok(Some((x, l))),
            Some((Value::Int(n), l)) => Ok(Some((n as f64, l))),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a number")),
            None => Ok(None),
        }
    }

    /// A `string` and its line.
    pub(super) fn string(&mut self, name: &str) -> Result<Option<(String, u32)>, String> {
        match self.take(name) {
            Some((Value::Str(s), l)) => Ok(Some((s, l))),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a string")),
            None => Ok(None),
        }
    }

    /// A `boolean` and its line.
    pub(super) fn boolean(&mut self, name: &str) -> Result<Option<(bool, u32)>, String> {
        match self.take(name) {
            Some((Value::Bool(b), l)) => Ok(Some((b, l))),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a boolean")),
            None => Ok(None),
        }
    }

    /// A `point`.
    pub(super) fn point(&mut self, name: &str) -> Result<Option<DVec3>, String> {
        match self.take(name) {
            Some((Value::Vector(v), _)) => Ok(Some(v)),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a point")),
            None => Ok(None),
        }
    }

    /// A `<transform>`'s matrix.
    pub(super) fn transform(&mut self, name: &str) -> Result<Option<DMat4>, String> {
        match self.take(name) {
            Some((Value::Transform(m), _)) => Ok(Some(m)),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a <transform>")),
            None => Ok(None),
        }
    }

    /// Whether a nested object stands in the place of property `name` (a texture).
    fn object_named(&self, name: &str) -> bool {
        self.objects
            .iter()
            .any(|o| self.name_of(o).as_deref() == Some(name))
    }

    /// A reflectance-like colour (rgb, float, or spectrum as Mitsuba's RGB variants read it
    /// off an emitter: a sampled spectrum integrated under D65 and kept in [0, 1]), its default,
    /// or `None` when a texture stands in its place (reported with the element's objects).
    pub(super) fn color(&mut self, name: &str, default: f64) -> Result<Option<[f64; 3]>, String> {
        self.color_as(name, default, false)
    }

    /// An emitted colour (radiance, intensity, irradiance) as Mitsuba's RGB variants read it:
    /// rgb and float as they are, a uniform spectrum as the sRGB of that constant spectrum
    /// (not grey: sRGB's white is D65), a sampled spectrum integrated without D65, negative
    /// components clamped.
    pub(super) fn emission(
        &mut self,
        name: &str,
        default: f64,
    ) -> Result<Option<[f64; 3]>, String> {
        self.color_as(name, default, true)
    }

    fn color_as(
        &mut self,
        name: &str,
        default: f64,
        emitter: bool,
    ) -> Result<Option<[f64; 3]>, String> {
        match self.take(name) {
            Some((Value::Color(c), _)) => Ok(Some(c)),
            Some((Value::Float(f), _)) => Ok(Some([f; 3])),
            Some((Value::Int(n), _)) => Ok(Some([n as f64; 3])),
            Some((Value::Spectrum(s), _)) => Ok(Some(spectrum::to_rgb(&s, emitter))),
            Some((Value::Refused, _)) => Ok(None),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a colour")),
            None if self.object_named(name) => Ok(None),
            None => Ok(Some([default; 3])),
        }
    }

    /// Reports every property that was never read, as not converted by `owner`; nothing if
    /// the element was refused as a whole.
    pub(super) fn finish(self, owner: &str, report: &mut Report) {
        if self.refused {
            return;
        }
        for (name, property) in self.properties {
            if !property.read && !matches!(property.value, Value::Refused) {
                report.problem(
                    property.line,
                    format!("property `{name}` of {owner} is not converted"),
                );
            }
        }
    }
}

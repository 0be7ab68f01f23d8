//! Reading Mitsuba XML: attributes with `$name` parameters substituted, and a plugin element's
//! properties through a typed reader that remembers which ones were read, so that every property
//! no converter read is reported, once, with its line.

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
    /// The `<default>` parameters of `root`, then `defines` over them.
    pub(super) fn new(root: &Node, defines: &[(String, String)]) -> Result<Self, String> {
        let mut parameters = BTreeMap::new();
        for node in root.children().filter(Node::is_element) {
            if node.tag_name().name() == "default" {
                let (Some(name), Some(value)) = (node.attribute("name"), node.attribute("value"))
                else {
                    return Err(format!(
                        "line {}: <default> needs `name` and `value`",
                        line(&node)
                    ));
                };
                parameters.insert(name.to_string(), value.to_string());
            }
        }
        for (name, value) in defines {
            parameters.insert(name.clone(), value.clone());
        }
        Ok(Xml { parameters })
    }

    /// An attribute with `$name` parameters substituted.
    pub(super) fn attribute(&self, node: &Node, name: &str) -> Result<Option<String>, String> {
        let Some(raw) = node.attribute(name) else {
            return Ok(None);
        };
        let mut value = raw.to_string();
        // Longest names first, so that `$spp` does not eat into `$spp2`.
        let mut names: Vec<&String> = self.parameters.keys().collect();
        names.sort_by_key(|n| std::cmp::Reverse(n.len()));
        for n in names {
            value = value.replace(&format!("${n}"), &self.parameters[n]);
        }
        if let Some(at) = value.find('$') {
            let name: String = value[at + 1..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            return Err(format!(
                "line {}: `{raw}` uses ${name}, which no <default> or -D defines",
                line(node)
            ));
        }
        Ok(Some(value))
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
    /// `rgb`, or a `spectrum` with one value.
    Color([f64; 3]),
    /// `point` or `vector`.
    Vector(DVec3),
    Transform(DMat4),
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
    properties: BTreeMap<String, Property>,
}

/// Reads the properties of the plugin element `node`; property elements lumis does not know
/// become problems.
pub(super) fn read<'a, 'input>(
    node: &Node<'a, 'input>,
    xml: &Xml,
    report: &mut Report,
) -> Result<Properties<'a, 'input>, String> {
    let mut props = Properties {
        kind: xml.attribute(node, "type")?.unwrap_or_default(),
        line: line(node),
        objects: Vec::new(),
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
                Value::Bool(match v.trim() {
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
            "spectrum" => {
                let v = xml.attribute(&child, "value")?;
                match v.as_deref().map(|v| xml.numbers(&child, v)) {
                    Some(Ok(n)) if n.len() == 1 => Value::Color([n[0]; 3]),
                    _ => {
                        report.problem(
                            at,
                            "a <spectrum> other than one constant value is not converted",
                        );
                        continue;
                    }
                }
            }
            "point" | "vector" => Value::Vector(xml.vector(&child, 0.0)?),
            "transform" => match transform::read(&child, xml, report)? {
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
        let name = xml.required(&child, "name")?;
        props.properties.insert(
            name,
            Property {
                value: parsed,
                line: at,
                read: false,
            },
        );
    }
    Ok(props)
}

impl Properties<'_, '_> {
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
                .any(|o| o.attribute("name") == Some(name))
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

    /// A colour (rgb, constant spectrum or float), its default, or `None` when a texture stands
    /// in its place (reported with the element's objects).
    pub(super) fn color(&mut self, name: &str, default: f64) -> Result<Option<[f64; 3]>, String> {
        match self.take(name) {
            Some((Value::Color(c), _)) => Ok(Some(c)),
            Some((Value::Float(f), _)) => Ok(Some([f; 3])),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a colour")),
            None if self
                .objects
                .iter()
                .any(|o| o.attribute("name") == Some(name)) =>
            {
                Ok(None)
            }
            None => Ok(Some([default; 3])),
        }
    }

    /// Reports every property that was never read, as not converted by `owner`.
    pub(super) fn finish(self, owner: &str, report: &mut Report) {
        for (name, property) in self.properties {
            if !property.read {
                report.problem(
                    property.line,
                    format!("property `{name}` of {owner} is not converted"),
                );
            }
        }
    }
}

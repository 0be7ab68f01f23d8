//! The Mitsuba 3 XML reader and the RON writer.

use glam::{DMat4, DVec3, DVec4};
use roxmltree::Node;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

/// Something in the XML file that has no lumis equivalent.
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Line in the XML file, from 1.
    pub line: u32,
    pub message: String,
}

/// The converted scene, what could not be converted, and notes on conventions.
#[derive(Clone, Debug)]
pub struct Conversion {
    pub ron: String,
    pub problems: Vec<Problem>,
    /// Differences of convention that do not change the expected image, with their lines.
    pub notes: Vec<Problem>,
}

/// Converts Mitsuba XML text. Relative file names in it are relative to `xml_dir`, and are
/// written relative to `out_dir` (where the RON file goes). `defines` override the file's
/// `default` parameters (as `mitsuba -D name=value`). Fails on malformed XML or an undefined
/// `$` parameter; everything else that cannot be converted is listed in `problems`.
pub fn convert(
    xml: &str,
    xml_dir: &Path,
    out_dir: &Path,
    defines: &[(String, String)],
) -> Result<Conversion, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("not valid XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "scene" {
        return Err(format!(
            "line {}: the root element is <{}>, not <scene>",
            line(&root),
            root.tag_name().name()
        ));
    }
    let mut parameters: BTreeMap<String, String> = BTreeMap::new();
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
    let mut c = Converter {
        parameters,
        xml_dir: xml_dir.to_path_buf(),
        out_dir: out_dir.to_path_buf(),
        problems: Vec::new(),
        notes: Vec::new(),
        bsdfs: BTreeMap::new(),
        shapes: Vec::new(),
        emitters: Vec::new(),
        camera: None,
        film: None,
        sampler: None,
        integrator: None,
        anonymous: 0,
    };
    c.scene(&root)?;
    let ron = c.write(&root);
    Ok(Conversion {
        ron,
        problems: c.problems,
        notes: c.notes,
    })
}

fn line(node: &Node) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

/// A film's crop window: x, y, width, height in pixels.
type Crop = (u32, u32, u32, u32);

/// A property value as written in the XML.
#[derive(Clone, Debug)]
enum Value {
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

/// A plugin element's properties by name (with their lines), and its nested objects.
struct Properties<'a, 'input> {
    kind: String,
    values: BTreeMap<String, (Value, u32)>,
    objects: Vec<Node<'a, 'input>>,
}

struct Converter {
    parameters: BTreeMap<String, String>,
    xml_dir: PathBuf,
    out_dir: PathBuf,
    problems: Vec<Problem>,
    notes: Vec<Problem>,
    /// RON texts of the BSDFs, by name.
    bsdfs: BTreeMap<String, String>,
    shapes: Vec<String>,
    emitters: Vec<String>,
    camera: Option<String>,
    film: Option<String>,
    sampler: Option<String>,
    integrator: Option<String>,
    anonymous: usize,
}

/// Fixed-point text of a number that reads back as the same f32.
fn num(x: f64) -> String {
    format!("{}", x as f32)
}

fn triple(v: [f64; 3]) -> String {
    format!("({}, {}, {})", num(v[0]), num(v[1]), num(v[2]))
}

fn ron_string(s: &str) -> String {
    format!("{s:?}")
}

impl Converter {
    fn problem(&mut self, line: u32, message: impl Into<String>) {
        self.problems.push(Problem {
            line,
            message: message.into(),
        });
    }

    fn note(&mut self, line: u32, message: impl Into<String>) {
        self.notes.push(Problem {
            line,
            message: message.into(),
        });
    }

    /// An attribute with `$name` parameters substituted.
    fn attribute(&self, node: &Node, name: &str) -> Result<Option<String>, String> {
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

    fn required(&self, node: &Node, name: &str) -> Result<String, String> {
        self.attribute(node, name)?.ok_or_else(|| {
            format!(
                "line {}: <{}> needs a `{name}` attribute",
                line(node),
                node.tag_name().name()
            )
        })
    }

    fn numbers(&self, node: &Node, text: &str) -> Result<Vec<f64>, String> {
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
    fn vector(&self, node: &Node, missing: f64) -> Result<DVec3, String> {
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

    /// Reads a plugin element's properties; unknown property elements become problems.
    fn properties<'a, 'input>(
        &mut self,
        node: &Node<'a, 'input>,
    ) -> Result<Properties<'a, 'input>, String> {
        let kind = self.attribute(node, "type")?.unwrap_or_default();
        let mut props = Properties {
            kind,
            values: BTreeMap::new(),
            objects: Vec::new(),
        };
        for child in node.children().filter(Node::is_element) {
            let tag = child.tag_name().name();
            let at = line(&child);
            let value = || self.required(&child, "value");
            let parsed = match tag {
                "float" => {
                    let v = value()?;
                    let n = self.numbers(&child, &v)?;
                    match n.as_slice() {
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
                    match self.numbers(&child, &v)?.as_slice() {
                        [g] => Value::Color([*g; 3]),
                        [r, g, b] => Value::Color([*r, *g, *b]),
                        _ => return Err(format!("line {at}: `{v}` is not 1 or 3 numbers")),
                    }
                }
                "spectrum" => {
                    let v = self.attribute(&child, "value")?;
                    match v.as_deref().map(|v| self.numbers(&child, v)) {
                        Some(Ok(n)) if n.len() == 1 => Value::Color([n[0]; 3]),
                        _ => {
                            self.problems.push(Problem {
                                line: at,
                                message: "a <spectrum> other than one constant value is not \
                                          converted"
                                    .into(),
                            });
                            continue;
                        }
                    }
                }
                "point" | "vector" => Value::Vector(self.vector(&child, 0.0)?),
                "transform" => match self.transform(&child)? {
                    Some(m) => Value::Transform(m),
                    None => continue,
                },
                "ref" => {
                    props.objects.push(child);
                    continue;
                }
                "bsdf" | "emitter" | "film" | "sampler" | "rfilter" | "texture" | "shape"
                | "medium" | "phase" | "volume" | "integrator" | "sensor" => {
                    props.objects.push(child);
                    continue;
                }
                other => {
                    self.problems.push(Problem {
                        line: at,
                        message: format!("<{other}> is not converted"),
                    });
                    continue;
                }
            };
            props
                .values
                .insert(self.required(&child, "name")?, (parsed, at));
        }
        Ok(props)
    }

    /// Reports every property the converter did not take.
    fn leftovers(&mut self, owner: &str, props: Properties) {
        for (name, (_, at)) in props.values {
            self.problem(at, format!("property `{name}` of {owner} is not converted"));
        }
    }

    /// A `<transform>`'s matrix (its operations applied in order), or `None` after a problem.
    fn transform(&mut self, node: &Node) -> Result<Option<DMat4>, String> {
        let mut m = DMat4::IDENTITY;
        for op in node.children().filter(Node::is_element) {
            let at = line(&op);
            let step = match op.tag_name().name() {
                "translate" => DMat4::from_translation(self.vector(&op, 0.0)?),
                "scale" => DMat4::from_scale(self.vector(&op, 1.0)?),
                "rotate" => {
                    let axis = self.vector(&op, 0.0)?;
                    let angle = self.required(&op, "angle")?;
                    let angle = self.numbers(&op, &angle)?.first().copied().unwrap_or(0.0);
                    if axis.length_squared() == 0.0 {
                        return Err(format!("line {at}: a rotation axis must not be zero"));
                    }
                    rotation(axis.normalize(), angle)
                }
                "matrix" => {
                    let v = self.required(&op, "value")?;
                    let n = self.numbers(&op, &v)?;
                    match n.len() {
                        16 => DMat4::from_cols_array(&n.try_into().expect("16")).transpose(),
                        9 => {
                            let r =
                                |i: usize| DVec4::new(n[3 * i], n[3 * i + 1], n[3 * i + 2], 0.0);
                            DMat4::from_cols(r(0), r(1), r(2), DVec4::W).transpose()
                        }
                        k => {
                            return Err(format!(
                                "line {at}: a matrix has 9 or 16 numbers, not {k}"
                            ));
                        }
                    }
                }
                "lookat" => {
                    let read = |name: &str| -> Result<Option<DVec3>, String> {
                        match self.attribute(&op, name)? {
                            Some(t) => match self.numbers(&op, &t)?.as_slice() {
                                [x, y, z] => Ok(Some(DVec3::new(*x, *y, *z))),
                                _ => Err(format!("line {at}: `{name}` needs 3 numbers")),
                            },
                            None => Ok(None),
                        }
                    };
                    let (Some(origin), Some(target)) = (read("origin")?, read("target")?) else {
                        return Err(format!("line {at}: <lookat> needs `origin` and `target`"));
                    };
                    let Some(up) = read("up")? else {
                        self.problem(at, "<lookat> without `up` is not converted");
                        return Ok(None);
                    };
                    let dir = (target - origin).normalize_or_zero();
                    let left = up.cross(dir).normalize_or_zero();
                    if dir == DVec3::ZERO || left == DVec3::ZERO {
                        return Err(format!(
                            "line {at}: <lookat> needs distinct origin and target, and `up` not along the view"
                        ));
                    }
                    let new_up = dir.cross(left);
                    DMat4::from_cols(
                        left.extend(0.0),
                        new_up.extend(0.0),
                        dir.extend(0.0),
                        origin.extend(1.0),
                    )
                }
                other => {
                    self.problem(
                        at,
                        format!("transform operation <{other}> is not converted"),
                    );
                    return Ok(None);
                }
            };
            m = step * m;
        }
        Ok(Some(m))
    }

    fn scene(&mut self, root: &Node) -> Result<(), String> {
        for node in root.children().filter(Node::is_element) {
            let at = line(&node);
            match node.tag_name().name() {
                "default" => {}
                "integrator" => self.integrator(&node)?,
                "sensor" => self.sensor(&node)?,
                "bsdf" => {
                    let Some(id) = self.attribute(&node, "id")? else {
                        self.problem(at, "a top-level <bsdf> without `id` is never used");
                        continue;
                    };
                    if let Some(text) = self.bsdf(&node)? {
                        self.bsdfs.insert(id, text);
                    }
                }
                "shape" => self.shape(&node)?,
                "emitter" => self.emitter(&node)?,
                other => self.problem(at, format!("<{other}> is not converted")),
            }
        }
        Ok(())
    }

    fn integrator(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        for o in &p.objects {
            self.problem(
                line(o),
                format!(
                    "<{}> inside the integrator is not converted",
                    o.tag_name().name()
                ),
            );
        }
        if p.kind != "direct" {
            self.problem(
                at,
                format!(
                    "integrator `{}` is not converted: lumis renders direct lighting (`direct`)",
                    p.kind
                ),
            );
            return Ok(());
        }
        let mut count = |name: &str| match p.values.remove(name) {
            Some((Value::Int(n), _)) if n > 0 => Some(n),
            Some((_, l)) => {
                self.problems.push(Problem {
                    line: l,
                    message: format!("`{name}` must be a positive integer"),
                });
                None
            }
            None => None,
        };
        let shading = count("shading_samples").unwrap_or(1);
        let emitter = count("emitter_samples").unwrap_or(shading);
        let bsdf = count("bsdf_samples").unwrap_or(shading);
        if let Some((Value::Bool(true), l)) = p.values.remove("hide_emitters") {
            self.problem(l, "`hide_emitters` is not converted");
        }
        self.note(
            at,
            format!(
                "`direct` ({emitter} emitter + {bsdf} BSDF samples, one light chosen per emitter \
                 sample) becomes lumis `power` with samples {}: the same power-heuristic estimator \
                 of the same image, taking its samples from every light",
                emitter + bsdf
            ),
        );
        self.integrator = Some(format!("(type: \"power\", samples: {})", emitter + bsdf));
        self.leftovers("the integrator", p);
        Ok(())
    }

    fn sensor(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        if p.kind != "perspective" {
            self.problem(
                at,
                format!("sensor `{}` is not converted (perspective only)", p.kind),
            );
            return Ok(());
        }
        let mut width = 768u32;
        let mut height = 576u32;
        let mut crop = None;
        let mut film_seen = false;
        for object in p.objects.clone() {
            let ol = line(&object);
            match object.tag_name().name() {
                "film" => {
                    film_seen = true;
                    let (w, h, c) = self.film(&object)?;
                    (width, height, crop) = (w, h, c);
                }
                "sampler" => self.sampler(&object)?,
                other => self.problem(ol, format!("<{other}> inside the sensor is not converted")),
            }
        }
        if !film_seen {
            self.note(at, "no <film>: Mitsuba's default 768x576 hdrfilm");
        }
        let matrix = match p.values.remove("to_world") {
            Some((Value::Transform(m), _)) => m,
            Some((_, l)) => return Err(format!("line {l}: `to_world` must be a <transform>")),
            None => DMat4::IDENTITY,
        };
        let position = matrix.transform_point3(DVec3::ZERO);
        let forward = matrix.transform_vector3(DVec3::Z);
        let up = matrix.transform_vector3(DVec3::Y);
        let (f, u) = (forward.normalize_or_zero(), up.normalize_or_zero());
        if matrix.determinant() <= 0.0 || f.dot(u).abs() > 1e-4 || f == DVec3::ZERO {
            self.problem(
                at,
                "the sensor's `to_world` mirrors or skews the view, which lumis' camera cannot",
            );
            return Ok(());
        }
        let axis = match p.values.remove("fov_axis") {
            Some((Value::Str(s), _)) => s,
            Some((_, l)) => return Err(format!("line {l}: `fov_axis` must be a string")),
            None => "x".to_string(),
        };
        let fov = match p.values.remove("fov") {
            Some((Value::Float(f), _)) => f,
            Some((Value::Int(i), _)) => i as f64,
            Some((_, l)) => return Err(format!("line {l}: `fov` must be a number")),
            None => {
                self.problem(
                    at,
                    "a sensor without `fov` (a focal length) is not converted",
                );
                return Ok(());
            }
        };
        let (w, h) = (width as f64, height as f64);
        let half = (fov.to_radians() / 2.0).tan();
        let vertical_half = match axis.as_str() {
            "y" => half,
            "x" => half * h / w,
            "diagonal" => half * h / (w * w + h * h).sqrt(),
            "smaller" if w <= h => half * h / w,
            "smaller" => half,
            "larger" if w >= h => half * h / w,
            "larger" => half,
            other => return Err(format!("line {at}: unknown fov_axis `{other}`")),
        };
        let vertical = 2.0 * vertical_half.atan().to_degrees();
        for clip in ["near_clip", "far_clip"] {
            if let Some((_, l)) = p.values.remove(clip) {
                self.note(l, format!("`{clip}` is ignored: lumis does not clip"));
            }
        }
        self.camera = Some(format!(
            "(position: {}, target: {}, up: {}, fov: {})",
            triple(position.to_array()),
            triple((position + f).to_array()),
            triple(u.to_array()),
            num(vertical)
        ));
        let crop = crop.map_or(String::new(), |(x, y, cw, ch)| {
            format!(", crop: (x: {x}, y: {y}, width: {cw}, height: {ch})")
        });
        self.film = Some(format!("(width: {width}, height: {height}{crop})"));
        self.leftovers("the sensor", p);
        Ok(())
    }

    /// Width, height and crop window of an `hdrfilm`.
    fn film(&mut self, node: &Node) -> Result<(u32, u32, Option<Crop>), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        if p.kind != "hdrfilm" {
            self.problem(
                at,
                format!("film `{}` is not converted (hdrfilm only)", p.kind),
            );
        }
        let mut int = |name: &str, default: i64| -> Result<Option<i64>, String> {
            match p.values.remove(name) {
                Some((Value::Int(n), _)) if (0..=65536).contains(&n) => Ok(Some(n)),
                Some((_, l)) => Err(format!(
                    "line {l}: `{name}` must be an integer in 0..=65536"
                )),
                None => Ok((default >= 0).then_some(default)),
            }
        };
        let width = int("width", 768)?.unwrap_or(768) as u32;
        let height = int("height", 576)?.unwrap_or(576) as u32;
        let crop = match (
            int("crop_offset_x", 0)?,
            int("crop_offset_y", 0)?,
            int("crop_width", -1)?,
            int("crop_height", -1)?,
        ) {
            (Some(x), Some(y), cw, ch) if cw.is_some() || ch.is_some() || x > 0 || y > 0 => {
                let cw = cw.unwrap_or(width as i64 - x) as u32;
                let ch = ch.unwrap_or(height as i64 - y) as u32;
                Some((x as u32, y as u32, cw, ch))
            }
            _ => None,
        };
        // Output formats do not change the image.
        for ignored in ["pixel_format", "component_format", "file_format", "banner"] {
            p.values.remove(ignored);
        }
        let mut box_filter = false;
        for object in p.objects.clone() {
            match object.tag_name().name() {
                "rfilter" => {
                    let kind = self.attribute(&object, "type")?.unwrap_or_default();
                    if kind == "box" {
                        box_filter = true;
                    } else {
                        self.problem(
                            line(&object),
                            format!("reconstruction filter `{kind}` is not converted (box only)"),
                        );
                        box_filter = true;
                    }
                }
                other => self.problem(
                    line(&object),
                    format!("<{other}> inside the film is not converted"),
                ),
            }
        }
        if !box_filter {
            self.note(
                at,
                "no <rfilter>: Mitsuba filters with a Gaussian by default, lumis with a box over \
                 the pixel (the same mean image, blurred differently)",
            );
        }
        if let Some((_, l)) = p.values.remove("sample_border") {
            self.note(
                l,
                "`sample_border` is ignored (lumis' box filter stays in its pixel)",
            );
        }
        self.leftovers("the film", p);
        Ok((width, height, crop))
    }

    fn sampler(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        if p.kind != "independent" {
            self.problem(
                at,
                format!("sampler `{}` is not converted (independent only)", p.kind),
            );
            return Ok(());
        }
        let spp = match p.values.remove("sample_count") {
            Some((Value::Int(n), _)) if n > 0 => n,
            Some((_, l)) => {
                return Err(format!(
                    "line {l}: `sample_count` must be a positive integer"
                ));
            }
            None => 4,
        };
        let seed = match p.values.remove("seed") {
            Some((Value::Int(n), _)) if n >= 0 => n,
            Some((_, l)) => return Err(format!("line {l}: `seed` must be a non-negative integer")),
            None => 0,
        };
        self.sampler = Some(format!("(spp: {spp}, seed: {seed})"));
        self.leftovers("the sampler", p);
        Ok(())
    }

    /// A colour property (rgb, constant spectrum or float), its default, or `None` when a
    /// texture stands in its place.
    fn color(
        &self,
        p: &mut Properties,
        name: &str,
        default: f64,
    ) -> Result<Option<[f64; 3]>, String> {
        match p.values.remove(name) {
            Some((Value::Color(c), _)) => Ok(Some(c)),
            Some((Value::Float(f), _)) => Ok(Some([f; 3])),
            Some((_, l)) => Err(format!("line {l}: `{name}` must be a colour")),
            // A texture in its place (an object named `name`) is reported with the objects.
            None if p.objects.iter().any(|o| o.attribute("name") == Some(name)) => Ok(None),
            None => Ok(Some([default; 3])),
        }
    }

    /// A BSDF as RON text, or `None` after a problem.
    fn bsdf(&mut self, node: &Node) -> Result<Option<String>, String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        if p.kind == "twosided" {
            let inner: Vec<Node> = p
                .objects
                .iter()
                .copied()
                .filter(|o| o.tag_name().name() == "bsdf")
                .collect();
            if inner.len() != 1 {
                self.problem(
                    at,
                    "a twosided BSDF with other than one nested BSDF is not converted",
                );
                return Ok(None);
            }
            self.leftovers("the twosided BSDF", p);
            return self.bsdf_inner(&inner[0]);
        }
        let text = self.bsdf_from(&mut p, at)?;
        if text.is_some() {
            self.note(
                at,
                format!(
                    "BSDF `{}` is one-sided in Mitsuba (black seen from behind); lumis surfaces \
                     reflect on both sides",
                    p.kind
                ),
            );
        }
        self.leftovers(&format!("the `{}` BSDF", p.kind), p);
        Ok(text)
    }

    fn bsdf_inner(&mut self, node: &Node) -> Result<Option<String>, String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        let text = self.bsdf_from(&mut p, at)?;
        self.leftovers(&format!("the `{}` BSDF", p.kind), p);
        Ok(text)
    }

    fn bsdf_from(&mut self, p: &mut Properties, at: u32) -> Result<Option<String>, String> {
        for o in p.objects.clone() {
            let name = o
                .attribute("name")
                .map_or(String::new(), |n| format!(" (`{n}`)"));
            self.problem(
                line(&o),
                format!(
                    "<{}>{name} inside a BSDF is not converted",
                    o.tag_name().name()
                ),
            );
        }
        let material_none = |c: &mut Self, p: &mut Properties| -> bool {
            match p.values.remove("material") {
                Some((Value::Str(s), _)) if s == "none" => {
                    for k in ["eta", "k"] {
                        if let Some((_, l)) = p.values.remove(k) {
                            c.problem(l, format!("`{k}` with material `none` is not converted"));
                        }
                    }
                    true
                }
                Some((_, l)) => {
                    c.problem(
                        l,
                        "conductor materials other than `none` (Fresnel 1) are not converted",
                    );
                    false
                }
                None => {
                    c.problem(at, "a conductor without `material: none` (Mitsuba's default is copper) is not converted");
                    false
                }
            }
        };
        let unit_reflectance =
            |c: &mut Self, p: &mut Properties| -> Result<Option<[f64; 3]>, String> {
                c.color(p, "specular_reflectance", 1.0)
            };
        match p.kind.as_str() {
            "diffuse" => {
                let Some(r) = self.color(p, "reflectance", 0.5)? else {
                    return Ok(None);
                };
                Ok(Some(format!(
                    "(type: \"diffuse\", reflectance: {})",
                    triple(r)
                )))
            }
            "roughconductor" => {
                let ok = material_none(self, p);
                match p.values.remove("distribution") {
                    Some((Value::Str(s), _)) if s == "ggx" => {}
                    Some((_, l)) => {
                        self.problem(
                            l,
                            "microfacet distributions other than ggx are not converted",
                        );
                        return Ok(None);
                    }
                    None => {
                        self.problem(at, "roughconductor without `distribution: ggx` (Mitsuba's default is beckmann) is not converted");
                        return Ok(None);
                    }
                }
                let mut alpha = |name: &str| match p.values.remove(name) {
                    Some((Value::Float(a), l)) => Some((a, l)),
                    Some((Value::Int(a), l)) => Some((a as f64, l)),
                    _ => None,
                };
                let (a, l) = match (alpha("alpha"), alpha("alpha_u"), alpha("alpha_v")) {
                    (Some(a), None, None) => a,
                    (None, Some(u), Some(v)) if u.0 == v.0 => u,
                    (None, None, None) => (0.1, at),
                    _ => {
                        self.problem(at, "anisotropic roughness is not converted");
                        return Ok(None);
                    }
                };
                if !(1e-4..=1.0).contains(&a) {
                    self.problem(l, format!("alpha {a} is outside lumis' [0.0001, 1]"));
                    return Ok(None);
                }
                p.values.remove("sample_visible");
                let s = unit_reflectance(self, p)?;
                if s != Some([1.0; 3]) {
                    if s.is_some() {
                        self.problem(at, "a specular_reflectance other than 1 is not converted (Schlick's F0 would not be constant)");
                    }
                    return Ok(None);
                }
                Ok(ok.then(|| {
                    format!(
                        "(type: \"glossy\", roughness: {}, specular: 1, diffuse: 0, masking: \"separable\")",
                        num(a)
                    )
                }))
            }
            "conductor" => {
                let ok = material_none(self, p);
                let Some(s) = unit_reflectance(self, p)? else {
                    return Ok(None);
                };
                Ok(ok.then(|| format!("(type: \"mirror\", reflectance: {})", triple(s))))
            }
            other => {
                self.problem(at, format!("BSDF `{other}` is not converted"));
                Ok(None)
            }
        }
    }

    /// A file name in the XML, as the RON file must write it.
    fn path(&self, name: &str) -> String {
        let path = Path::new(name);
        if path.is_absolute() {
            return name.to_string();
        }
        relative_path(&self.xml_dir.join(path), &self.out_dir)
            .to_string_lossy()
            .replace('\\', "/")
    }

    fn shape(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        let kind = p.kind.clone();
        let mut fields = Vec::new();
        let matrix = match p.values.remove("to_world") {
            Some((Value::Transform(m), _)) => Some(m),
            Some((_, l)) => return Err(format!("line {l}: `to_world` must be a <transform>")),
            None => None,
        };
        match kind.as_str() {
            "obj" | "ply" => {
                let Some((Value::Str(file), _)) = p.values.remove("filename") else {
                    return Err(format!("line {at}: a {kind} shape needs `filename`"));
                };
                fields.push(format!("file: {}", ron_string(&self.path(&file))));
                if let Some((Value::Bool(b), _)) = p.values.remove("face_normals") {
                    fields.push(format!("face_normals: {b}"));
                }
                // Texture coordinates are not used.
                p.values.remove("flip_tex_coords");
            }
            "rectangle" | "cube" => {}
            "disk" => {
                self.note(
                    at,
                    "the disk becomes a polygon of 1024 triangles (99.9994 % of its area)",
                );
                fields.push("segments: 1024".into());
            }
            "sphere" => {
                match p.values.remove("center") {
                    Some((Value::Vector(c), _)) => {
                        fields.push(format!("center: {}", triple(c.to_array())))
                    }
                    Some((_, l)) => return Err(format!("line {l}: `center` must be a point")),
                    None => {}
                }
                match p.values.remove("radius") {
                    Some((Value::Float(r), _)) => fields.push(format!("radius: {}", num(r))),
                    Some((Value::Int(r), _)) => fields.push(format!("radius: {r}")),
                    Some((_, l)) => return Err(format!("line {l}: `radius` must be a number")),
                    None => {}
                }
            }
            other => {
                self.problem(at, format!("shape `{other}` is not converted"));
                return Ok(());
            }
        }
        match p.values.remove("flip_normals") {
            Some((Value::Bool(true), l)) if kind == "sphere" => {
                self.problem(l, "a sphere with `flip_normals` is not converted");
                return Ok(());
            }
            Some((Value::Bool(b), _)) if b => fields.push("flip_normals: true".into()),
            _ => {}
        }
        if let Some(m) = matrix {
            let rows: Vec<String> = (0..4)
                .flat_map(|r| (0..4).map(move |c| (r, c)))
                .map(|(r, c)| num(m.col(c)[r]))
                .collect();
            fields.push(format!("transform: (matrix: ({}))", rows.join(", ")));
        }
        let mut bsdf = None;
        let mut emitter = None;
        for object in p.objects.clone() {
            let ol = line(&object);
            match object.tag_name().name() {
                "ref" => {
                    let id = self.required(&object, "id")?;
                    if self.bsdfs.contains_key(&id) {
                        bsdf = Some(id);
                    } else {
                        self.problem(
                            ol,
                            format!("reference to `{id}`, which is not a converted BSDF"),
                        );
                        return Ok(());
                    }
                }
                "bsdf" => match self.bsdf(&object)? {
                    Some(text) => {
                        self.anonymous += 1;
                        let name = self
                            .attribute(&object, "id")?
                            .unwrap_or(format!("bsdf{}", self.anonymous));
                        self.bsdfs.insert(name.clone(), text);
                        bsdf = Some(name);
                    }
                    None => return Ok(()),
                },
                "emitter" => {
                    let mut e = self.properties(&object)?;
                    for o in e.objects.clone() {
                        let name = o
                            .attribute("name")
                            .map_or(String::new(), |n| format!(" (`{n}`)"));
                        self.problem(
                            line(&o),
                            format!(
                                "<{}>{name} inside an emitter is not converted",
                                o.tag_name().name()
                            ),
                        );
                    }
                    if e.kind != "area" {
                        self.problem(
                            ol,
                            format!("emitter `{}` on a shape is not converted", e.kind),
                        );
                        return Ok(());
                    }
                    let Some(radiance) = self.color(&mut e, "radiance", 1.0)? else {
                        return Ok(());
                    };
                    emitter = Some(format!("(type: \"area\", radiance: {})", triple(radiance)));
                    self.leftovers("the area emitter", e);
                }
                other => {
                    self.problem(ol, format!("<{other}> inside a shape is not converted"));
                    return Ok(());
                }
            }
        }
        let bsdf = match bsdf {
            Some(b) => b,
            None => {
                self.note(
                    at,
                    "a shape without BSDF gets Mitsuba's default, diffuse 0.5",
                );
                self.bsdfs
                    .entry("default".into())
                    .or_insert("(type: \"diffuse\", reflectance: 0.5)".into());
                "default".into()
            }
        };
        let emitter = emitter.map_or(String::new(), |e| format!(", emitter: {e}"));
        let extra = if fields.is_empty() {
            String::new()
        } else {
            format!(", {}", fields.join(", "))
        };
        self.shapes.push(format!(
            "(type: \"{kind}\", bsdf: {}{extra}{emitter})",
            ron_string(&bsdf)
        ));
        self.leftovers(&format!("the `{kind}` shape"), p);
        Ok(())
    }

    fn emitter(&mut self, node: &Node) -> Result<(), String> {
        let at = line(node);
        let mut p = self.properties(node)?;
        for o in p.objects.clone() {
            self.problem(
                line(&o),
                format!(
                    "<{}> inside an emitter is not converted",
                    o.tag_name().name()
                ),
            );
        }
        let matrix = match p.values.remove("to_world") {
            Some((Value::Transform(m), _)) => Some(m),
            Some((_, l)) => return Err(format!("line {l}: `to_world` must be a <transform>")),
            None => None,
        };
        let mut scale = 1.0;
        if let Some((v, l)) = p.values.remove("scale") {
            match v {
                Value::Float(s) => scale = s,
                Value::Int(s) => scale = s as f64,
                _ => return Err(format!("line {l}: `scale` must be a number")),
            }
        }
        let text = match p.kind.as_str() {
            "envmap" => {
                let Some((Value::Str(file), l)) = p.values.remove("filename") else {
                    return Err(format!("line {at}: an envmap needs `filename`"));
                };
                if !file.to_ascii_lowercase().ends_with(".exr") {
                    self.problem(
                        l,
                        format!("env map `{file}`: lumis reads OpenEXR maps only"),
                    );
                    return Ok(());
                }
                if let Some((Value::Bool(true), l)) = p.values.remove("mis_compensation") {
                    self.problem(l, "`mis_compensation` is not converted");
                }
                let m = matrix.unwrap_or(DMat4::IDENTITY);
                // Only a turn about +y: R_y(a) has first row (cos a, 0, sin a).
                let angle = m.col(2)[0].atan2(m.col(0)[0]);
                let expected = DMat4::from_rotation_y(angle);
                if !m.abs_diff_eq(expected, 1e-5) {
                    self.problem(
                        at,
                        "an env map's `to_world` other than a rotation about +y is not converted",
                    );
                    return Ok(());
                }
                format!(
                    "(type: \"envmap\", file: {}, scale: {}, rotation: {}, interpolation: \"bilinear\", orientation: \"mitsuba\")",
                    ron_string(&self.path(&file)),
                    num(scale),
                    num(angle.to_degrees())
                )
            }
            "point" => {
                let position = match (p.values.remove("position"), matrix) {
                    (Some((Value::Vector(v), _)), None) => v,
                    (None, Some(m)) => m.transform_point3(DVec3::ZERO),
                    (None, None) => DVec3::ZERO,
                    _ => {
                        return Err(format!(
                            "line {at}: a point light takes `position` or `to_world`"
                        ));
                    }
                };
                let Some(i) = self.color(&mut p, "intensity", 1.0)? else {
                    return Ok(());
                };
                format!(
                    "(type: \"point\", position: {}, intensity: {}, scale: {})",
                    triple(position.to_array()),
                    triple(i),
                    num(scale)
                )
            }
            "directional" => {
                let direction = match (p.values.remove("direction"), matrix) {
                    (Some((Value::Vector(v), _)), None) => v,
                    (None, Some(m)) => m.transform_vector3(DVec3::Z),
                    (None, None) => DVec3::Z,
                    _ => {
                        return Err(format!(
                            "line {at}: a directional light takes `direction` or `to_world`"
                        ));
                    }
                };
                let Some(e) = self.color(&mut p, "irradiance", 1.0)? else {
                    return Ok(());
                };
                format!(
                    "(type: \"directional\", direction: {}, irradiance: {}, scale: {})",
                    triple(direction.normalize_or_zero().to_array()),
                    triple(e),
                    num(scale)
                )
            }
            other => {
                self.problem(at, format!("emitter `{other}` is not converted"));
                return Ok(());
            }
        };
        self.emitters.push(text);
        self.leftovers(&format!("the `{}` emitter", p.kind), p);
        Ok(())
    }

    fn write(&mut self, root: &Node) -> String {
        let at = line(root);
        let camera = self.camera.clone().unwrap_or_else(|| {
            self.problem(at, "the scene has no convertible perspective sensor");
            "(position: (0, 0, 0), target: (0, 0, 1), fov: 45)".into()
        });
        let film = self
            .film
            .clone()
            .unwrap_or("(width: 768, height: 576)".into());
        let sampler = self
            .sampler
            .clone()
            .unwrap_or_else(|| "(spp: 4, seed: 0)".into());
        let integrator = self.integrator.clone().unwrap_or_else(|| {
            self.note(
                at,
                "no <integrator>: Mitsuba would use `path`; lumis renders direct lighting with \
                 `power`, samples 2",
            );
            "(type: \"power\", samples: 2)".into()
        });
        let mut out = String::new();
        let _ = writeln!(
            out,
            "// Converted from a Mitsuba 3 scene by `lumis import`."
        );
        let _ = writeln!(out, "Scene(");
        let _ = writeln!(out, "    camera: {camera},");
        let _ = writeln!(out, "    film: {film},");
        let _ = writeln!(out, "    sampler: {sampler},");
        let _ = writeln!(out, "    integrator: {integrator},");
        let _ = writeln!(out, "    bsdfs: {{");
        for (name, text) in &self.bsdfs {
            let _ = writeln!(out, "        {}: {text},", ron_string(name));
        }
        let _ = writeln!(out, "    }},");
        let _ = writeln!(out, "    shapes: [");
        for s in &self.shapes {
            let _ = writeln!(out, "        {s},");
        }
        let _ = writeln!(out, "    ],");
        let _ = writeln!(out, "    emitters: [");
        for e in &self.emitters {
            let _ = writeln!(out, "        {e},");
        }
        let _ = writeln!(out, "    ],");
        let _ = writeln!(out, ")");
        out
    }
}

/// Rotation by `degrees` about the unit `axis`, with sin and cos exact at multiples of 90° (as
/// lumis' own `rotate`, so that turned planes stay exactly axis-aligned).
fn rotation(axis: DVec3, degrees: f64) -> DMat4 {
    let quarter_turns = degrees / 90.0;
    let (s, c) = if quarter_turns == quarter_turns.round() {
        [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)]
            [(quarter_turns as i64).rem_euclid(4) as usize]
    } else {
        degrees.to_radians().sin_cos()
    };
    let t = 1.0 - c;
    let DVec3 { x, y, z } = axis;
    DMat4::from_cols(
        DVec4::new(c + t * x * x, t * x * y + s * z, t * x * z - s * y, 0.0),
        DVec4::new(t * x * y - s * z, c + t * y * y, t * y * z + s * x, 0.0),
        DVec4::new(t * x * z + s * y, t * y * z - s * x, c + t * z * z, 0.0),
        DVec4::W,
    )
}

/// The components of `p` with `.` and `..` resolved lexically.
fn normal(p: &Path) -> Vec<Component<'_>> {
    let mut out: Vec<Component> = Vec::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `target` relative to the directory `base` (both made absolute, `.` and `..` resolved
/// lexically).
fn relative_path(target: &Path, base: &Path) -> PathBuf {
    let (Ok(target_abs), Ok(base_abs)) = (std::path::absolute(target), std::path::absolute(base))
    else {
        return target.to_path_buf();
    };
    let (t, b) = (normal(&target_abs), normal(&base_abs));
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_climb_to_the_common_directory() {
        assert_eq!(
            relative_path(Path::new("/a/b/meshes/x.obj"), Path::new("/a/c")),
            PathBuf::from("../b/meshes/x.obj")
        );
        assert_eq!(
            relative_path(Path::new("/a/./b/../x.obj"), Path::new("/a")),
            PathBuf::from("x.obj")
        );
    }
}

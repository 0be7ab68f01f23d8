//! The RON scene schema (what a scene file may say), parsed with serde.
//!
//! Fixed parts (camera, film, sampler, shapes, transforms) are typed structs that refuse unknown
//! fields; plugin parts (BSDFs, emitters, integrator) are a `type` plus free parameters, checked
//! later against the plugin's declared parameter list. See `docs/scene-format.md`.
//!
//! [`SceneDescription::to_ron`] writes a description back as a scene file reads when written by
//! hand (`lumis import` builds one): each part on one line, fields at their defaults left out.
//!
//! Why one file of over 600 lines: the RON schema is written once, here: every struct of a scene
//! file with its serde attributes and the docs the schema reference is checked against.

use ron::Value;
use ron::ser::PrettyConfig;
use ron::value::RawValue;
use serde::de::Error as _;
use serde::ser::{Error as _, SerializeSeq, SerializeTuple};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;

/// A whole scene file: `Scene(camera: ..., film: ..., ...)`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Scene", deny_unknown_fields)]
pub struct SceneDescription {
    #[serde(serialize_with = "on_one_line")]
    pub camera: CameraDescription,
    #[serde(serialize_with = "on_one_line")]
    pub film: FilmDescription,
    #[serde(default, serialize_with = "on_one_line")]
    pub sampler: SamplerDescription,
    pub integrator: PluginSpec,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub bsdfs: BTreeMap<String, PluginSpec>,
    #[serde(serialize_with = "each_on_one_line")]
    pub shapes: Vec<ShapeDescription>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub emitters: Vec<PluginSpec>,
    /// Run-time plugin libraries (paths relative to the scene file).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub plugins: Vec<String>,
}

impl SceneDescription {
    /// The description as scene-file text: `Scene(` with one part per line, each part (camera,
    /// film, sampler, plugin, shape) on one line as the docs write them, without the fields
    /// left at their defaults; it parses back into the same description.
    pub fn to_ron(&self) -> Result<String, ron::Error> {
        let config = PrettyConfig::new().struct_names(true).new_line("\n");
        Ok(ron::ser::to_string_pretty(self, config)? + "\n")
    }
}

/// A perspective pinhole camera: `position`, `target`, `fov` (and `up`), or `gltf` (and `name`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Camera", deny_unknown_fields)]
pub struct CameraDescription {
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub position: Option<[f32; 3]>,
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub target: Option<[f32; 3]>,
    /// Default (0, 1, 0).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub up: Option<[f32; 3]>,
    /// Vertical field of view, degrees.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub fov: Option<f32>,
    /// Take the camera from this glTF file (relative to the scene file) instead.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub gltf: Option<String>,
    /// With `gltf`: the camera node (or camera) of this name; default the first one.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Film", deny_unknown_fields)]
pub struct FilmDescription {
    pub width: u32,
    pub height: u32,
    /// Output EXR path, relative to the working directory; default: the scene's name + `.exr`.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub output: Option<String>,
    /// Render only this window of the film, in pixels.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub crop: Option<CropDescription>,
    /// Exposure of the PNG preview, in stops.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub exposure: f32,
    /// The reconstruction filter; default the box over the pixel.
    #[serde(default, skip_serializing_if = "FilterDescription::is_box")]
    pub filter: FilterDescription,
}

/// A reconstruction filter: `(type: "box")`, `(type: "tent", radius: 1)` or
/// `(type: "gaussian", stddev: 0.5)` (Mitsuba 3's filters; see `lumis_core::filter`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Filter", deny_unknown_fields)]
pub struct FilterDescription {
    #[serde(rename = "type")]
    pub kind: String,
    /// `tent`: half-width in pixels (default 1).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    /// `gaussian`: standard deviation in pixels (default 0.5); the filter is cut at 4 of them.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub stddev: Option<f32>,
}

impl Default for FilterDescription {
    fn default() -> Self {
        FilterDescription {
            kind: "box".into(),
            radius: None,
            stddev: None,
        }
    }
}

impl FilterDescription {
    /// Whether this is the default, the box.
    pub fn is_box(&self) -> bool {
        *self == FilterDescription::default()
    }

    /// The filter, or why it cannot be built.
    pub fn build(&self) -> Result<crate::filter::Filter, String> {
        use crate::filter::Filter;
        let no = |name: &str, given: bool| {
            if given {
                Err(format!(
                    "filter `{name}` does not apply to a {} filter",
                    self.kind
                ))
            } else {
                Ok(())
            }
        };
        match self.kind.as_str() {
            "box" => {
                no("radius", self.radius.is_some())?;
                no("stddev", self.stddev.is_some())?;
                Ok(Filter::box_filter())
            }
            "tent" => {
                no("stddev", self.stddev.is_some())?;
                Filter::tent(self.radius.unwrap_or(1.0))
            }
            "gaussian" => {
                no("radius", self.radius.is_some())?;
                Filter::gaussian(self.stddev.unwrap_or(0.5))
            }
            other => {
                const KINDS: [&str; 3] = ["box", "tent", "gaussian"];
                Err(format!(
                    "unknown filter type `{other}`{}; known filters: {}",
                    crate::error::did_you_mean(other, KINDS),
                    KINDS.join(", ")
                ))
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename = "Crop", deny_unknown_fields)]
pub struct CropDescription {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Sampler", deny_unknown_fields)]
pub struct SamplerDescription {
    /// Camera samples per pixel.
    #[serde(default = "default_spp")]
    pub spp: u32,
    #[serde(default)]
    pub seed: u64,
    /// Camera rays jittered within their pixel (antialiasing); false: through pixel centres.
    #[serde(default = "default_jitter", skip_serializing_if = "is_default_jitter")]
    pub jitter: bool,
}

fn default_spp() -> u32 {
    1
}

fn default_jitter() -> bool {
    true
}

fn is_default_jitter(jitter: &bool) -> bool {
    *jitter == default_jitter()
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

impl Default for SamplerDescription {
    fn default() -> Self {
        SamplerDescription {
            spp: default_spp(),
            seed: 0,
            jitter: default_jitter(),
        }
    }
}

/// A shape: `type` is `gltf`, `obj`, `ply`, `serialized`, `rectangle`, `cube`, `disk` or
/// `sphere`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Shape", deny_unknown_fields)]
pub struct ShapeDescription {
    #[serde(rename = "type")]
    pub kind: String,
    /// Name of a BSDF in `bsdfs`; a `gltf` shape without one takes its glTF materials.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub bsdf: Option<String>,
    #[serde(default, skip_serializing_if = "TransformDescription::is_identity")]
    pub transform: TransformDescription,
    /// An area emitter attached to this shape.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub emitter: Option<PluginSpec>,
    /// `gltf`, `obj`, `ply`: the mesh file, relative to the scene file.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// `gltf`: only the node (with its children) or mesh of this name; `obj`: only the object
    /// or group of this name.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub mesh: Option<String>,
    /// `gltf`, `obj`, `ply`: ignore the file's vertex normals (flat shading).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub face_normals: Option<bool>,
    /// Meshes: turn every face (its front side and its normals) the other way.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub flip_normals: Option<bool>,
    /// `obj`, `ply`, `serialized`: when the file has no vertex normals (or `face_normals`
    /// drops them: then not), compute smooth ones as Mitsuba does (angle-weighted).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub smooth_normals: Option<bool>,
    /// `serialized`: which mesh of the file (from 0, the default).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub shape_index: Option<u32>,
    /// `gltf`: also add the file's `KHR_lights_punctual` point and directional lights.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub lights: Option<bool>,
    /// `sphere`: centre (default origin) before the transform.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub center: Option<[f32; 3]>,
    /// `sphere`: radius (default 1) before the transform.
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    /// `disk`: number of triangles of the disk (default 64).
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub segments: Option<u32>,
}

/// Applied as: scale, then each rotation in order, then translate; or `look_at` (after scale);
/// or a full row-major `matrix`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Transform", deny_unknown_fields)]
pub struct TransformDescription {
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub scale: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rotate: Vec<RotationDescription>,
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub translate: Option<[f32; 3]>,
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub look_at: Option<LookAtDescription>,
    #[serde(default, with = "bare", skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[f32; 16]>,
}

impl TransformDescription {
    /// Whether the transform leaves shapes where they are (nothing given).
    pub fn is_identity(&self) -> bool {
        *self == TransformDescription::default()
    }
}

/// A rotation by `angle` degrees (right-handed) about `axis`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "Rotate", deny_unknown_fields)]
pub struct RotationDescription {
    pub axis: [f32; 3],
    pub angle: f32,
}

/// Places the shape at `origin` with its local +z pointing at `target`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(rename = "LookAt", deny_unknown_fields)]
pub struct LookAtDescription {
    pub origin: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
}

/// A plugin instance: `(type: "name", param: value, ...)`.
#[derive(Clone, Debug, PartialEq)]
pub struct PluginSpec {
    pub kind: String,
    pub params: BTreeMap<String, Value>,
}

impl<'de> Deserialize<'de> for PluginSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let Value::Map(map) = Value::deserialize(d)? else {
            return Err(D::Error::custom(
                "expected a plugin description such as (type: \"diffuse\", reflectance: 0.5)",
            ));
        };
        let mut kind = None;
        let mut params = BTreeMap::new();
        for (key, value) in map {
            let Value::String(key) = key else {
                return Err(D::Error::custom(
                    "plugin parameter names must be identifiers",
                ));
            };
            if key == "type" {
                match value {
                    Value::String(s) => kind = Some(s),
                    _ => {
                        return Err(D::Error::custom(
                            "`type` must be a string, e.g. type: \"diffuse\"",
                        ));
                    }
                }
            } else {
                params.insert(key, value);
            }
        }
        let kind = kind.ok_or_else(|| D::Error::custom("missing `type` (the plugin's name)"))?;
        Ok(PluginSpec { kind, params })
    }
}

/// Builds a plugin instance with typed values, e.g.
/// `PluginSpec::new("diffuse").rgb("reflectance", [0.5, 0.4, 0.3])`.
impl PluginSpec {
    pub fn new(kind: impl Into<String>) -> Self {
        PluginSpec {
            kind: kind.into(),
            params: BTreeMap::new(),
        }
    }

    pub fn float(self, name: &str, x: f32) -> Self {
        self.with(name, Value::Number(x.into()))
    }

    pub fn int(self, name: &str, n: i64) -> Self {
        self.with(name, Value::Number(n.into()))
    }

    pub fn string(self, name: &str, s: impl Into<String>) -> Self {
        self.with(name, Value::String(s.into()))
    }

    /// A colour; a grey is written as one number.
    pub fn rgb(self, name: &str, [r, g, b]: [f32; 3]) -> Self {
        if r == g && g == b {
            self.float(name, r)
        } else {
            self.vec3(name, [r, g, b])
        }
    }

    pub fn vec3(self, name: &str, v: [f32; 3]) -> Self {
        let components = v.iter().map(|&x| Value::Number(x.into())).collect();
        self.with(name, Value::Seq(components))
    }

    /// A plugin written inline as a parameter's value (a texture, a nested BSDF).
    pub fn plugin(self, name: &str, spec: PluginSpec) -> Self {
        self.with(name, spec.into_value())
    }

    /// The plugin as a parameter's value: a map of its `type` and parameters, as a scene file
    /// parses `(type: "checkerboard", color0: 0.2)`.
    pub fn into_value(self) -> Value {
        let mut map = ron::Map::new();
        map.insert(Value::String("type".into()), Value::String(self.kind));
        for (name, value) in self.params {
            map.insert(Value::String(name), value);
        }
        Value::Map(map)
    }

    fn with(mut self, name: &str, value: Value) -> Self {
        self.params.insert(name.to_string(), value);
        self
    }
}

/// Written on one line as `(type: "name", param: value, ...)`, parameters in name order.
impl Serialize for PluginSpec {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut ron = format!(
            "(type: {}",
            one_line_text(&self.kind).map_err(S::Error::custom)?
        );
        for (name, value) in &self.params {
            if !is_identifier(name) {
                return Err(S::Error::custom(format!(
                    "plugin parameter name `{name}` is not an identifier"
                )));
            }
            let value = one_line_text(&ParamValue(value)).map_err(S::Error::custom)?;
            ron += &format!(", {name}: {value}");
        }
        ron.push(')');
        raw(ron).map_err(S::Error::custom)?.serialize(s)
    }
}

/// A parameter value as scene files write it: a list of two or more numbers (a colour, a
/// vector, an interval) as a tuple, `(0.5, 0.4, 0.3)`.
struct ParamValue<'a>(&'a Value);

impl Serialize for ParamValue<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.0 {
            Value::Seq(items)
                if items.len() > 1 && items.iter().all(|v| matches!(v, Value::Number(_))) =>
            {
                let mut tuple = s.serialize_tuple(items.len())?;
                for item in items {
                    tuple.serialize_element(item)?;
                }
                tuple.end()
            }
            // A nested plugin, as a plugin is written: `(type: "checkerboard", ...)`.
            Value::Map(map) => match PluginSpec::deserialize(Value::Map(map.clone())) {
                Ok(spec) => spec.serialize(s),
                Err(_) => self.0.serialize(s),
            },
            other => other.serialize(s),
        }
    }
}

/// A RON identifier, which a parameter name must be to be written as `name: value`.
fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// One-line RON text of a value: structs without their names, `, ` between items.
fn one_line_text<T: Serialize + ?Sized>(value: &T) -> Result<String, ron::Error> {
    ron::ser::to_string_pretty(value, PrettyConfig::new().depth_limit(0))
}

/// RON text that a serializer writes as it is (checked to parse).
fn raw(ron: String) -> Result<Box<RawValue>, ron::error::SpannedError> {
    RawValue::from_boxed_ron(ron.into_boxed_str())
}

/// Writes a part of the scene on one line (`serialize_with`).
fn on_one_line<T: Serialize, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
    let text = one_line_text(value).map_err(S::Error::custom)?;
    raw(text).map_err(S::Error::custom)?.serialize(s)
}

/// Writes each item of a list on one line (`serialize_with`).
fn each_on_one_line<T: Serialize, S: Serializer>(items: &[T], s: S) -> Result<S::Ok, S::Error> {
    struct OneLine<'a, T>(&'a T);
    impl<T: Serialize> Serialize for OneLine<'_, T> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            on_one_line(self.0, s)
        }
    }
    let mut seq = s.serialize_seq(Some(items.len()))?;
    for item in items {
        seq.serialize_element(&OneLine(item))?;
    }
    seq.end()
}

/// Optional fields are written without `Some(...)` in scene files.
mod bare {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de>>(
        d: D,
    ) -> Result<Option<T>, D::Error> {
        T::deserialize(d).map(Some)
    }

    /// Only called for `Some` (the fields skip `None`).
    pub fn serialize<T: Serialize, S: Serializer>(
        value: &Option<T>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        match value {
            Some(v) => v.serialize(s),
            None => s.serialize_none(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every part of the schema, written by hand.
    const FULL: &str = r#"Scene(
        camera: (position: (1, 2, 3), target: (0, 0.5, 0), up: (0, 0, 1), fov: 39.3),
        film: (width: 64, height: 48, output: "out/a b.exr", crop: (x: 1, y: 2, width: 30, height: 20), exposure: -1.5, filter: (type: "gaussian", stddev: 0.25)),
        sampler: (spp: 16, seed: 7, jitter: false),
        integrator: (type: "alpha", samples: 8, mode: "fixed", fixed: 0.3, aovs: ["alpha", "samples"]),
        bsdfs: {
            "white": (type: "diffuse", reflectance: (0.725, 0.71, 0.68)),
            "grey": (type: "diffuse", reflectance: 0.5),
            "metal": (type: "glossy", roughness: 0.1, specular: 1, masking: "separable"),
        },
        shapes: [
            (type: "rectangle", bsdf: "white", transform: (scale: (2, 2, 1), rotate: [(axis: (1, 0, 0), angle: -90), (axis: (0, 1, 0), angle: 30)], translate: (0, 1, 0))),
            (type: "gltf", file: "meshes/bunny.glb", mesh: "bunny", face_normals: true, lights: true),
            (type: "serialized", file: "a.serialized", bsdf: "grey", shape_index: 2, smooth_normals: true),
            (type: "obj", file: "a.obj", bsdf: "grey", flip_normals: true, transform: (look_at: (origin: (0, 3, 0), target: (0, 0, 0), up: (1, 0, 0)))),
            (type: "sphere", bsdf: "metal", center: (0, 1, 0), radius: 0.25, emitter: (type: "area", radiance: (17, 12, 4), two_sided: true)),
            (type: "disk", bsdf: "grey", segments: 32, transform: (matrix: (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1))),
        ],
        emitters: [
            (type: "envmap", file: "sky.exr", scale: 1e-3, rotation: 12.5),
            (type: "point", position: (1, 2, 3), intensity: 4),
        ],
        plugins: ["libexample.so"],
    )"#;

    #[test]
    fn a_written_description_parses_back_into_itself() {
        let description: SceneDescription = ron::from_str(FULL).unwrap();
        let text = description.to_ron().unwrap();
        let again: SceneDescription =
            ron::from_str(&text).unwrap_or_else(|e| panic!("{e}:\n{text}"));
        assert_eq!(again, description, "{text}");
    }

    #[test]
    fn a_description_is_written_as_a_scene_file_is_by_hand() {
        let scene = SceneDescription {
            camera: CameraDescription {
                position: Some([0.0, 1.0, 5.0]),
                target: Some([0.0, 1.0, 4.0]),
                up: None,
                fov: Some(45.0),
                gltf: None,
                name: None,
            },
            film: FilmDescription {
                width: 32,
                height: 24,
                output: None,
                crop: None,
                exposure: 0.0,
                filter: FilterDescription::default(),
            },
            sampler: SamplerDescription {
                spp: 4,
                seed: 0,
                jitter: true,
            },
            integrator: PluginSpec::new("power").int("samples", 2),
            bsdfs: BTreeMap::from([(
                "red".to_string(),
                PluginSpec::new("diffuse").rgb("reflectance", [0.5, 0.25, 0.125]),
            )]),
            shapes: vec![ShapeDescription {
                kind: "sphere".into(),
                bsdf: Some("red".into()),
                transform: TransformDescription::default(),
                emitter: Some(PluginSpec::new("area").rgb("radiance", [2.0; 3])),
                file: None,
                mesh: None,
                face_normals: None,
                flip_normals: None,
                smooth_normals: None,
                shape_index: None,
                lights: None,
                center: None,
                radius: Some(0.5),
                segments: None,
            }],
            emitters: Vec::new(),
            plugins: Vec::new(),
        };
        assert_eq!(
            scene.to_ron().unwrap(),
            r#"Scene(
    camera: (position: (0.0, 1.0, 5.0), target: (0.0, 1.0, 4.0), fov: 45.0),
    film: (width: 32, height: 24),
    sampler: (spp: 4, seed: 0),
    integrator: (type: "power", samples: 2),
    bsdfs: {
        "red": (type: "diffuse", reflectance: (0.5, 0.25, 0.125)),
    },
    shapes: [
        (type: "sphere", bsdf: "red", emitter: (type: "area", radiance: 2.0), radius: 0.5),
    ],
)
"#
        );
    }

    #[test]
    fn a_parameter_name_that_is_not_an_identifier_is_refused() {
        let spec = PluginSpec::new("diffuse").float("two words", 1.0);
        let e = ron::to_string(&spec).unwrap_err().to_string();
        assert!(e.contains("`two words` is not an identifier"), "{e}");
    }
}

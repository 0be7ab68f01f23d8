//! The RON scene schema (what a scene file may say), parsed with serde.
//!
//! Fixed parts (camera, film, sampler, shapes, transforms) are typed structs that refuse unknown
//! fields; plugin parts (BSDFs, emitters, integrator) are a `type` plus free parameters, checked
//! later against the plugin's declared parameter list. See `docs/scene-format.md`.

use ron::Value;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;

/// A whole scene file: `Scene(camera: ..., film: ..., ...)`.
#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Scene", deny_unknown_fields)]
pub struct SceneDescription {
    pub camera: CameraDescription,
    pub film: FilmDescription,
    #[serde(default)]
    pub sampler: SamplerDescription,
    pub integrator: PluginSpec,
    #[serde(default)]
    pub bsdfs: BTreeMap<String, PluginSpec>,
    pub shapes: Vec<ShapeDescription>,
    #[serde(default)]
    pub emitters: Vec<PluginSpec>,
    /// Run-time plugin libraries (paths relative to the scene file).
    #[serde(default)]
    pub plugins: Vec<String>,
}

/// A perspective pinhole camera: `position`, `target`, `fov` (and `up`), or `gltf` (and `name`).
#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Camera", deny_unknown_fields)]
pub struct CameraDescription {
    #[serde(default, deserialize_with = "some")]
    pub position: Option<[f32; 3]>,
    #[serde(default, deserialize_with = "some")]
    pub target: Option<[f32; 3]>,
    /// Default (0, 1, 0).
    #[serde(default, deserialize_with = "some")]
    pub up: Option<[f32; 3]>,
    /// Vertical field of view, degrees.
    #[serde(default, deserialize_with = "some")]
    pub fov: Option<f32>,
    /// Take the camera from this glTF file (relative to the scene file) instead.
    #[serde(default, deserialize_with = "some")]
    pub gltf: Option<String>,
    /// With `gltf`: the camera node (or camera) of this name; default the first one.
    #[serde(default, deserialize_with = "some")]
    pub name: Option<String>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Film", deny_unknown_fields)]
pub struct FilmDescription {
    pub width: u32,
    pub height: u32,
    /// Output EXR path, relative to the working directory; default: the scene's name + `.exr`.
    #[serde(default, deserialize_with = "some")]
    pub output: Option<String>,
    /// Render only this window of the film, in pixels.
    #[serde(default, deserialize_with = "some")]
    pub crop: Option<CropDescription>,
    /// Exposure of the PNG preview, in stops.
    #[serde(default)]
    pub exposure: f32,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename = "Crop", deny_unknown_fields)]
pub struct CropDescription {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Sampler", deny_unknown_fields)]
pub struct SamplerDescription {
    /// Camera samples per pixel.
    #[serde(default = "default_spp")]
    pub spp: u32,
    #[serde(default)]
    pub seed: u64,
    /// Camera rays jittered within their pixel (antialiasing); false: through pixel centres.
    #[serde(default = "default_jitter")]
    pub jitter: bool,
}

fn default_spp() -> u32 {
    1
}

fn default_jitter() -> bool {
    true
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

/// A shape: `type` is `gltf`, `obj`, `ply`, `rectangle`, `cube`, `disk` or `sphere`.
#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Shape", deny_unknown_fields)]
pub struct ShapeDescription {
    #[serde(rename = "type")]
    pub kind: String,
    /// Name of a BSDF in `bsdfs`; a `gltf` shape without one takes its glTF materials.
    #[serde(default, deserialize_with = "some")]
    pub bsdf: Option<String>,
    #[serde(default)]
    pub transform: TransformDescription,
    /// An area emitter attached to this shape.
    #[serde(default, deserialize_with = "some")]
    pub emitter: Option<PluginSpec>,
    /// `gltf`, `obj`, `ply`: the mesh file, relative to the scene file.
    #[serde(default, deserialize_with = "some")]
    pub file: Option<String>,
    /// `gltf`: only the node (with its children) or mesh of this name; `obj`: only the object
    /// or group of this name.
    #[serde(default, deserialize_with = "some")]
    pub mesh: Option<String>,
    /// `gltf`, `obj`, `ply`: ignore the file's vertex normals (flat shading).
    #[serde(default, deserialize_with = "some")]
    pub face_normals: Option<bool>,
    /// Meshes: turn every face (its front side and its normals) the other way.
    #[serde(default, deserialize_with = "some")]
    pub flip_normals: Option<bool>,
    /// `gltf`: also add the file's `KHR_lights_punctual` point and directional lights.
    #[serde(default, deserialize_with = "some")]
    pub lights: Option<bool>,
    /// `sphere`: centre (default origin) before the transform.
    #[serde(default, deserialize_with = "some")]
    pub center: Option<[f32; 3]>,
    /// `sphere`: radius (default 1) before the transform.
    #[serde(default, deserialize_with = "some")]
    pub radius: Option<f32>,
    /// `disk`: number of triangles of the disk (default 64).
    #[serde(default, deserialize_with = "some")]
    pub segments: Option<u32>,
}

/// Applied as: scale, then each rotation in order, then translate; or `look_at` (after scale);
/// or a full row-major `matrix`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(rename = "Transform", deny_unknown_fields)]
pub struct TransformDescription {
    #[serde(default, deserialize_with = "some")]
    pub scale: Option<[f32; 3]>,
    #[serde(default)]
    pub rotate: Vec<RotationDescription>,
    #[serde(default, deserialize_with = "some")]
    pub translate: Option<[f32; 3]>,
    #[serde(default, deserialize_with = "some")]
    pub look_at: Option<LookAtDescription>,
    #[serde(default, deserialize_with = "some")]
    pub matrix: Option<[f32; 16]>,
}

/// A rotation by `angle` degrees (right-handed) about `axis`.
#[derive(Clone, Debug, Deserialize)]
#[serde(rename = "Rotate", deny_unknown_fields)]
pub struct RotationDescription {
    pub axis: [f32; 3],
    pub angle: f32,
}

/// Places the shape at `origin` with its local +z pointing at `target`.
#[derive(Clone, Debug, Deserialize)]
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

/// Optional fields are written without `Some(...)` in scene files.
fn some<'de, D: Deserializer<'de>, T: Deserialize<'de>>(d: D) -> Result<Option<T>, D::Error> {
    T::deserialize(d).map(Some)
}

//! What a glTF file says besides its meshes: the camera (`camera: (gltf: ...)`), the
//! `KHR_lights_punctual` lights (`lights: true` on a `gltf` shape) and the materials (a `gltf`
//! shape without `bsdf`). See docs/scene-format.md for the mappings.
//!
//! Nodes are visited depth first from the default scene's roots (or, without scenes, every
//! node), each before its children, in the file's order, with their world transforms.

use super::description::{CameraDescription, PluginSpec};
use crate::camera::Camera;
use crate::error::{SceneError, did_you_mean};
use crate::geometry::Mesh;
use glam::{Mat4, Vec3};
use ron::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// The scene's camera: from its description, or from the glTF file it names.
pub fn build_camera(
    desc: &CameraDescription,
    scene: &Path,
    base: &Path,
    width: u32,
    height: u32,
) -> Result<Camera, SceneError> {
    let err = |m: String| SceneError::new(scene, m);
    let Some(file) = &desc.gltf else {
        if desc.name.is_some() {
            return Err(err("camera `name` applies only with `gltf`".into()));
        }
        let (Some(position), Some(target), Some(fov)) = (desc.position, desc.target, desc.fov)
        else {
            return Err(err(
                "the camera needs `position`, `target` and `fov`, or `gltf` (a glTF file to take \
                 it from)"
                    .into(),
            ));
        };
        let up = desc.up.unwrap_or([0.0, 1.0, 0.0]);
        return Camera::new(
            Vec3::from(position),
            Vec3::from(target),
            Vec3::from(up),
            fov,
            width,
            height,
        )
        .map_err(err);
    };
    if desc.position.is_some() || desc.target.is_some() || desc.up.is_some() || desc.fov.is_some() {
        return Err(err(
            "a camera taken from `gltf` cannot also give `position`, `target`, `up` or `fov`"
                .into(),
        ));
    }
    let path = base.join(file);
    let asset =
        |m: String| SceneError::new(&path, format!("{m} (the camera of {})", scene.display()));
    let bytes = std::fs::read(&path).map_err(|e| asset(format!("cannot read glTF file: {e}")))?;
    let (eye, forward, up, yfov) = gltf_camera(&bytes, desc.name.as_deref()).map_err(asset)?;
    Camera::new(eye, eye + forward, up, yfov.to_degrees(), width, height).map_err(asset)
}

/// The chosen camera node's position, view direction, up direction and vertical field of view
/// (radians). glTF cameras look down their node's −z with +y up.
pub fn gltf_camera(bytes: &[u8], name: Option<&str>) -> Result<(Vec3, Vec3, Vec3, f32), String> {
    let gltf = super::gltf::parse(bytes)?;
    let nodes = scene_nodes(&gltf.document)?;
    let mut names = Vec::new();
    for (node, world) in &nodes {
        let Some(camera) = node.camera() else {
            continue;
        };
        let label = node.name().or(camera.name());
        names.extend(node.name().into_iter().chain(camera.name()));
        if name.is_some_and(|n| node.name() != Some(n) && camera.name() != Some(n)) {
            continue;
        }
        let label = label.map_or(format!("camera node {}", node.index()), |l| {
            format!("camera `{l}`")
        });
        let gltf::camera::Projection::Perspective(p) = camera.projection() else {
            return Err(format!(
                "{label} is orthographic; lumis has perspective cameras only"
            ));
        };
        let yfov = p.yfov();
        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(format!("{label}: yfov {yfov} must be in (0, π) radians"));
        }
        let eye = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(-Vec3::Z).normalize_or_zero();
        let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
        if !eye.is_finite() || forward == Vec3::ZERO || up == Vec3::ZERO {
            return Err(format!("{label}: its node transform is singular"));
        }
        return Ok((eye, forward, up, yfov));
    }
    Err(match name {
        None => "the file has no camera in its scene".into(),
        Some(n) => format!(
            "no camera named `{n}`{}; cameras in the file: {}",
            did_you_mean(n, names.iter().copied()),
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ),
    })
}

/// The file's `KHR_lights_punctual` point and directional lights as emitter descriptions (the
/// light's or node's name, and the plugin), placed by their nodes and then by `transform` (the
/// shape's). Spot lights are refused: lumis has no spot emitter.
pub fn gltf_lights(bytes: &[u8], transform: &Mat4) -> Result<Vec<(String, PluginSpec)>, String> {
    use gltf::khr_lights_punctual::Kind;
    let gltf = super::gltf::parse(bytes)?;
    let mut lights = Vec::new();
    for (node, world) in scene_nodes(&gltf.document)? {
        let world = *transform * world;
        let Some(light) = node.light() else {
            continue;
        };
        let label = light
            .name()
            .or(node.name())
            .map_or(format!("light {}", light.index()), |n| {
                format!("light `{n}`")
            });
        let power = Vec3::from(light.color()) * light.intensity();
        if !power.is_finite() || power.min_element() < 0.0 {
            return Err(format!(
                "{label}: color × intensity {power} must be finite and non-negative"
            ));
        }
        let spec = match light.kind() {
            Kind::Point => {
                let position = world.transform_point3(Vec3::ZERO);
                PluginSpec {
                    kind: "point".into(),
                    params: params([("position", position), ("intensity", power)]),
                }
            }
            Kind::Directional => {
                let direction = world.transform_vector3(-Vec3::Z).normalize_or_zero();
                if direction == Vec3::ZERO {
                    return Err(format!("{label}: its node transform is singular"));
                }
                PluginSpec {
                    kind: "directional".into(),
                    params: params([("direction", direction), ("irradiance", power)]),
                }
            }
            Kind::Spot { .. } => {
                return Err(format!(
                    "{label} is a spot light, which lumis does not model (point and \
                     directional lights are read); remove it or make it a point light"
                ));
            }
        };
        lights.push((label, spec));
    }
    Ok(lights)
}

/// The triangles of a glTF file grouped by material (in order of first use), each with the
/// material's name and the BSDF it maps to.
pub fn gltf_materials(
    bytes: &[u8],
    base: &Path,
    only: Option<&str>,
) -> Result<Vec<(String, PluginSpec, Mesh)>, String> {
    let gltf = super::gltf::parse(bytes)?;
    let mut groups: Vec<(Option<usize>, Mesh)> = Vec::new();
    for (material, part) in super::gltf::load_parts(bytes, base, only)? {
        match groups.iter_mut().find(|(m, _)| *m == material) {
            Some((_, mesh)) => mesh.append(part),
            None => groups.push((material, part)),
        }
    }
    groups
        .into_iter()
        .filter(|(_, mesh)| !mesh.indices.is_empty())
        .map(|(index, mesh)| {
            let (name, spec) = match index.and_then(|i| gltf.document.materials().nth(i)) {
                Some(m) => {
                    let pbr = m.pbr_metallic_roughness();
                    let name = m
                        .name()
                        .map_or(format!("material {}", m.index().unwrap_or(0)), |n| {
                            format!("material `{n}`")
                        });
                    let base_color = pbr.base_color_factor();
                    let spec = metallic_roughness_bsdf(
                        Vec3::new(base_color[0], base_color[1], base_color[2]),
                        pbr.metallic_factor(),
                        pbr.roughness_factor(),
                    );
                    (name, spec)
                }
                // glTF's default material: white, metallic 1, roughness 1.
                None => (
                    "the default material".to_string(),
                    metallic_roughness_bsdf(Vec3::ONE, 1.0, 1.0),
                ),
            };
            Ok((name, spec, mesh))
        })
        .collect()
}

/// glTF's metallic-roughness model as a lumis BSDF: `diffuse` with reflectance = base colour
/// for a rough dielectric (metallic 0, roughness 1); otherwise `glossy` with GGX α =
/// roughness², F0 = lerp(0.04, base colour, metallic) and a diffuse base of base colour ×
/// (1 − metallic), as the glTF specification's reference BRDF. Out-of-range factors are left
/// to the plugins' own checks.
pub fn metallic_roughness_bsdf(base_color: Vec3, metallic: f32, roughness: f32) -> PluginSpec {
    if metallic == 0.0 && roughness == 1.0 {
        return PluginSpec {
            kind: "diffuse".into(),
            params: params([("reflectance", base_color)]),
        };
    }
    let f0 = Vec3::splat(0.04).lerp(base_color, metallic);
    let mut params = params([("specular", f0), ("diffuse", base_color * (1.0 - metallic))]);
    // GGX α below the plugin's floor is as sharp as it can render.
    params.insert(
        "roughness".into(),
        number((roughness * roughness).max(1e-4)),
    );
    PluginSpec {
        kind: "glossy".into(),
        params,
    }
}

/// `x` as the shortest decimal that reads back as it (so that messages quote `1e30`, not the
/// f32's exact value `1.0000000150474662e30`); the parameter reads the same f32.
fn number(x: f32) -> Value {
    let shortest = x.to_string().parse::<f64>().unwrap_or(x as f64);
    Value::Number(ron::value::Number::from(shortest))
}

fn params<const N: usize>(vectors: [(&str, Vec3); N]) -> BTreeMap<String, Value> {
    vectors
        .into_iter()
        .map(|(name, v)| {
            (
                name.to_string(),
                Value::Seq(v.to_array().into_iter().map(number).collect()),
            )
        })
        .collect()
}

/// Every node reached from the default scene (or every node, without scenes), depth first,
/// parents before children, with its world transform.
fn scene_nodes(doc: &gltf::Document) -> Result<Vec<(gltf::Node<'_>, Mat4)>, String> {
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => doc.nodes().collect(),
    };
    let mut out = Vec::new();
    let mut stack: Vec<(gltf::Node, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        if out.len() > doc.nodes().len() * 4 + 16 {
            return Err("the node hierarchy has a cycle".into());
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let children: Vec<gltf::Node> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, world)));
        out.push((node, world));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(spec: &PluginSpec, name: &str) -> Vec<f32> {
        match &spec.params[name] {
            Value::Seq(s) => s
                .iter()
                .map(|v| match v {
                    Value::Number(n) => n.into_f64() as f32,
                    _ => panic!(),
                })
                .collect(),
            Value::Number(n) => vec![n.into_f64() as f32],
            _ => panic!(),
        }
    }

    #[test]
    fn metallic_roughness_follows_the_stated_mapping() {
        let rough_dielectric = metallic_roughness_bsdf(Vec3::new(0.8, 0.5, 0.2), 0.0, 1.0);
        assert_eq!(rough_dielectric.kind, "diffuse");
        assert_eq!(value(&rough_dielectric, "reflectance"), [0.8, 0.5, 0.2]);
        let gold = metallic_roughness_bsdf(Vec3::new(1.0, 0.8, 0.3), 1.0, 0.5);
        assert_eq!(gold.kind, "glossy");
        assert_eq!(value(&gold, "specular"), [1.0, 0.8, 0.3]);
        assert_eq!(value(&gold, "diffuse"), [0.0, 0.0, 0.0]);
        assert_eq!(value(&gold, "roughness"), [0.25]);
        let plastic = metallic_roughness_bsdf(Vec3::new(0.5, 0.5, 0.5), 0.0, 0.3);
        assert!((value(&plastic, "specular")[0] - 0.04).abs() < 1e-7);
        assert_eq!(value(&plastic, "diffuse"), [0.5, 0.5, 0.5]);
        assert!((value(&plastic, "roughness")[0] - 0.09).abs() < 1e-7);
    }
}

//! Builds a [`Scene`] from a RON file: parse, apply overrides, then construct every part by name
//! through the registries. Every problem becomes a [`SceneError`] naming the file.
//!
//! Why one file of over 600 lines: building a scene is one sequence (plugins, film and camera,
//! BSDFs, shapes and their emitters, lights, integrator) whose steps share the loader's state and
//! error context.

use super::description::{PluginSpec, SceneDescription, ShapeDescription};
use super::overrides::Override;
use super::references::SceneReferences;
use super::shape_check::{check_shape, has_area};
use super::transform::transform_matrix;
use super::{Scene, budget, gltf, gltf_scene, light_check, obj, ply, serialized};
use crate::bsdf::{Absorber, Bsdf, BsdfFlags};
use crate::emitter::{Emitter, EmitterContext};
use crate::error::{SceneError, did_you_mean};
use crate::geometry::{self, Geometry, Mesh, ShapeGeometry, Sphere, UvMapping};
use crate::integrator::Integrator;
use crate::output::Window;
use crate::params::Params;
use crate::registry::{self, BsdfPlugin, EmitterPlugin, IntegratorPlugin};
use glam::Vec3;
use ron::Value;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A built scene with the integrator that renders it.
pub struct LoadedScene {
    pub scene: Scene,
    pub integrator: Box<dyn Integrator>,
    /// The description after overrides, as built.
    pub description: SceneDescription,
    /// Problems that do not stop the render (e.g. no light can reach the camera), as sentences.
    pub warnings: Vec<String>,
}

/// Reads, parses and builds the scene file at `path`, with `--set` overrides applied.
pub fn load_scene(path: &Path, overrides: &[String]) -> Result<LoadedScene, SceneError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SceneError::new(path, format!("cannot read scene file: {e}")))?;
    let description = parse_description(path, &text, overrides)?;
    build_scene(description, path)
}

fn syntax_error(path: &Path, text: &str, e: ron::error::SpannedError) -> SceneError {
    let (line, col, message) = super::syntax::explain(text, &e);
    SceneError::at(path, line, col, message)
}

/// Parses scene text; `path` is used for messages only.
pub fn parse_description(
    path: &Path,
    text: &str,
    overrides: &[String],
) -> Result<SceneDescription, SceneError> {
    // Parse the text as written first, so that its errors carry line and column.
    let description: SceneDescription =
        ron::from_str(text).map_err(|e| syntax_error(path, text, e))?;
    if overrides.is_empty() {
        return Ok(description);
    }
    let mut doc: Value = ron::from_str(text).map_err(|e| syntax_error(path, text, e))?;
    for text in overrides {
        let o = Override::parse(text).map_err(|e| SceneError::new(path, e))?;
        o.apply(&mut doc).map_err(|e| SceneError::new(path, e))?;
    }
    doc.into_rust().map_err(|e| {
        SceneError::new(
            path,
            format!(
                "after applying the --set overrides ({}): {e}",
                overrides.join(", ")
            ),
        )
    })
}

/// Builds the renderable scene; relative paths are resolved against the scene file's directory.
pub fn build_scene(desc: SceneDescription, path: &Path) -> Result<LoadedScene, SceneError> {
    let err = |msg: String| SceneError::new(path, msg);
    let base = path.parent().unwrap_or(Path::new(""));

    for library in &desc.plugins {
        let library = base.join(library);
        crate::dylib::load_library(&library).map_err(|e| {
            SceneError::new(
                &library,
                format!("{e} (listed in the `plugins` of {})", path.display()),
            )
        })?;
    }

    let film = &desc.film;
    let max_side = crate::limits::MAX_FILM_SIDE;
    if film.width == 0 || film.height == 0 || film.width > max_side || film.height > max_side {
        return Err(err(format!(
            "film size {}x{} is invalid: width and height must be in 1..={max_side}",
            film.width, film.height
        )));
    }
    let window = match film.crop {
        None => Window {
            x: 0,
            y: 0,
            width: film.width,
            height: film.height,
        },
        Some(c) => {
            if c.width == 0
                || c.height == 0
                || c.x as u64 + c.width as u64 > film.width as u64
                || c.y as u64 + c.height as u64 > film.height as u64
            {
                return Err(err(format!(
                    "film crop (x: {}, y: {}, width: {}, height: {}) must be non-empty and inside the {}x{} film",
                    c.x, c.y, c.width, c.height, film.width, film.height
                )));
            }
            Window {
                x: c.x,
                y: c.y,
                width: c.width,
                height: c.height,
            }
        }
    };
    if !film.exposure.is_finite() {
        return Err(err(format!(
            "film `exposure` must be finite, found {}",
            film.exposure
        )));
    }
    // The film alone, before anything large is built; the AOVs are added once the integrator
    // says which it writes.
    let memory_limit = crate::limits::memory_limit().map_err(err)?;
    let mut film_memory = crate::limits::MemoryEstimate::default();
    budget::add_film(&mut film_memory, &window, 3);
    film_memory.check(&memory_limit).map_err(err)?;
    let filter = film.filter.build().map_err(|e| err(format!("film: {e}")))?;
    if desc.sampler.spp == 0 {
        return Err(err("sampler `spp` must be at least 1".into()));
    }
    let camera = gltf_scene::build_camera(&desc.camera, path, base, film.width, film.height)?;

    // BSDFs, by name (with the textures and BSDFs they refer to).
    let references = SceneReferences::new(base, desc.bsdfs.clone());
    let mut bsdf_names = Vec::new();
    let mut bsdfs: Vec<Arc<dyn Bsdf>> = Vec::new();
    let mut bsdf_flags = Vec::new();
    let mut one_sided = Vec::new();
    for name in desc.bsdfs.keys() {
        let built = references.named_bsdf(name).map_err(err)?;
        bsdf_names.push(name.as_str());
        bsdfs.push(built.bsdf);
        bsdf_flags.push(built.flags);
        one_sided.push(built.one_sided);
    }
    // The back of the one-sided BSDFs, added once if a shape uses one.
    let mut absorber = None;

    // Shapes, with their area emitters.
    let mut geometries = Vec::new();
    let mut uv_mappings = Vec::new();
    let mut shape_bsdf = Vec::new();
    let mut shape_emitter = Vec::new();
    let mut emitters: Vec<Arc<dyn Emitter>> = Vec::new();
    let mut emitter_weights = Vec::new();
    let mut emitting_triangles = 0u64;
    let mut warnings = Vec::new();
    for (i, shape) in desc.shapes.iter().enumerate() {
        let label = format!("shapes[{i}] ({})", shape.kind);
        let shape_err = |e| match e {
            ShapeError::Scene(msg) => err(format!("{label}: {msg}")),
            ShapeError::Asset(file, msg) => SceneError::new(
                file,
                format!("{msg} (used by {label} of {})", path.display()),
            ),
        };
        // One part per BSDF: a gltf shape without `bsdf` has one per glTF material.
        let mut parts = Vec::new();
        match &shape.bsdf {
            Some(name) => {
                let bsdf = bsdf_names.iter().position(|n| n == name).ok_or_else(|| {
                    err(format!(
                        "{label} uses bsdf `{name}`, which is not defined{}; defined bsdfs: {}",
                        did_you_mean(name, bsdf_names.iter().copied()),
                        if bsdf_names.is_empty() {
                            "none".to_string()
                        } else {
                            bsdf_names.join(", ")
                        }
                    ))
                })?;
                let (geometry, mapping, flat_file) = build_shape(shape, base).map_err(shape_err)?;
                // Invisible, so left out as Mitsuba leaves it; an emitter of no area is refused
                // below (`check_shape`).
                if flat_file && shape.emitter.is_none() {
                    warnings.push(format!(
                        "{label}: no triangle of `{}` has an area (each is a line or a point in \
                         the file itself): the shape is invisible and left out",
                        shape.file.as_deref().unwrap_or_default()
                    ));
                    continue;
                }
                parts.push((bsdf, geometry, mapping));
            }
            None => {
                for (material, spec, geometry) in
                    build_gltf_material_parts(shape, base).map_err(shape_err)?
                {
                    let name = format!("{label} {material}");
                    let plugin = registry::find::<BsdfPlugin>(&spec.kind)
                        .map_err(|e| err(format!("{name}: {e}")))?;
                    let mut params =
                        plugin_params(&name, "bsdf", &spec, plugin.params).map_err(err)?;
                    let bsdf = (plugin.create)(&mut params).map_err(|e| err(e.to_string()))?;
                    params.finish().map_err(|e| err(e.to_string()))?;
                    bsdf_flags.push(bsdf.flags());
                    one_sided.push(false);
                    bsdfs.push(bsdf);
                    parts.push((bsdfs.len() - 1, geometry, UvMapping::Intrinsic));
                }
            }
        }
        for (bsdf, geometry, mapping) in parts {
            check_shape(&geometry).map_err(|e| err(format!("{label}: {e}")))?;
            if shape.emitter.is_some()
                && let ShapeGeometry::Mesh(mesh) = &geometry
            {
                emitting_triangles += mesh.indices.len() as u64;
            }
            let back = if one_sided[bsdf] {
                *absorber.get_or_insert_with(|| {
                    bsdfs.push(Arc::new(Absorber));
                    bsdf_flags.push(BsdfFlags::NONE);
                    one_sided.push(false);
                    bsdfs.len() - 1
                })
            } else {
                bsdf
            };
            shape_bsdf.push([bsdf as u32, back as u32]);
            shape_emitter.push(match &shape.emitter {
                None => None,
                Some(spec) => {
                    let (emitter, weight) =
                        build_emitter(&format!("{label}.emitter"), spec, Some(&geometry), base)
                            .map_err(err)?;
                    emitters.push(emitter);
                    emitter_weights.push(weight);
                    Some(emitters.len() as u32 - 1)
                }
            });
            geometries.push(geometry);
            uv_mappings.push(mapping);
        }
    }
    let mut environment = None;
    for (i, spec) in desc.emitters.iter().enumerate() {
        let (emitter, weight) =
            build_emitter(&format!("emitters[{i}]"), spec, None, base).map_err(err)?;
        if emitter.is_environment() {
            if environment.is_some() {
                return Err(err(format!(
                    "emitters[{i}]: a scene has at most one environment emitter"
                )));
            }
            environment = Some(emitters.len());
        }
        emitters.push(emitter);
        emitter_weights.push(weight);
    }

    // Lights of glTF files (`lights: true`), after the `emitters` list.
    for (i, shape) in desc.shapes.iter().enumerate() {
        if shape.lights != Some(true) {
            continue;
        }
        let file = base.join(shape.file.as_deref().unwrap_or_default());
        let matrix = transform_matrix(&shape.transform).map_err(err)?;
        let lights = std::fs::read(&file)
            .map_err(|e| format!("cannot read glTF file: {e}"))
            .and_then(|bytes| gltf_scene::gltf_lights(&bytes, &matrix))
            .map_err(|m| {
                SceneError::new(
                    &file,
                    format!("{m} (lights of shapes[{i}] of {})", path.display()),
                )
            })?;
        for (name, spec) in lights {
            let label = format!("shapes[{i}] {name}");
            let (emitter, weight) = build_emitter(&label, &spec, None, base).map_err(err)?;
            emitters.push(emitter);
            emitter_weights.push(weight);
        }
    }

    let integrator = build_integrator(&desc.integrator, base).map_err(err)?;

    let mut memory = film_memory;
    budget::add_geometry(&mut memory, &geometries, emitting_triangles);
    memory.check(&memory_limit).map_err(err)?;

    let output = match &film.output {
        Some(o) => PathBuf::from(o),
        None => PathBuf::from(path.file_stem().unwrap_or_default()).with_extension("exr"),
    };
    let mut emitter_shape = vec![None; emitters.len()];
    for (shape, emitter) in shape_emitter.iter().enumerate() {
        if let Some(emitter) = emitter {
            emitter_shape[*emitter as usize] = Some(shape as u32);
        }
    }
    let shadow_ray_skips = emitter_shape
        .iter()
        .zip(&emitters)
        .map(|(shape, emitter)| shape.filter(|_| emitter.own_shape_never_blocks_samples()))
        .collect();
    let scene = Scene {
        camera,
        width: film.width,
        height: film.height,
        window,
        spp: desc.sampler.spp,
        jitter: desc.sampler.jitter,
        filter,
        seed: desc.sampler.seed,
        geometry: Geometry::new(geometries).with_uv_mappings(uv_mappings),
        bsdfs,
        bsdf_flags,
        emitters,
        emitter_weights,
        environment,
        shape_bsdf,
        shape_emitter,
        emitter_shape,
        shadow_ray_skips,
        output,
        exposure: film.exposure,
    };
    // The AOVs depend on the scene (e.g. one per light): known only now, still before the film
    // is allocated.
    let aovs = integrator.aovs(&scene);
    let mut memory = crate::limits::MemoryEstimate::default();
    let channels: usize = aovs.iter().map(|a| a.channels.len()).sum();
    budget::add_film(&mut memory, &window, 3 + channels as u64);
    budget::add_geometry(&mut memory, scene.geometry.shapes(), emitting_triangles);
    memory.check(&memory_limit).map_err(err)?;
    warnings.extend(light_check::light_warnings(&scene));
    Ok(LoadedScene {
        scene,
        integrator,
        description: desc,
        warnings,
    })
}

/// Builds an integrator from its description (paths in its parameters are relative to `base`),
/// e.g. to render one loaded scene with several integrators.
pub fn build_integrator(spec: &PluginSpec, base: &Path) -> Result<Box<dyn Integrator>, String> {
    let plugin =
        registry::find::<IntegratorPlugin>(&spec.kind).map_err(|e| format!("integrator: {e}"))?;
    let mut params = Params::new(
        format!("integrator `{}`", spec.kind),
        plugin.params,
        spec.params.clone(),
    )
    .map_err(|e| e.to_string())?
    .with_base_dir(base);
    let integrator = (plugin.create)(&mut params).map_err(|e| e.to_string())?;
    params.finish().map_err(|e| e.to_string())?;
    Ok(integrator)
}

fn plugin_params(
    name: &str,
    kind: &str,
    spec: &PluginSpec,
    specs: &'static [crate::params::ParamSpec],
) -> Result<Params, String> {
    Params::new(
        format!("{kind} `{name}` ({})", spec.kind),
        specs,
        spec.params.clone(),
    )
    .map_err(|e| e.to_string())
}

/// A parameter of every emitter (Mitsuba's): how often `path` with one light per vertex
/// chooses it, relative to the others' (default 1).
pub const SAMPLING_WEIGHT: &str = "sampling_weight";
/// The largest `sampling_weight`.
const MAX_SAMPLING_WEIGHT: f64 = 1e12;

/// The emitter `spec` describes, and its `sampling_weight`.
fn build_emitter(
    label: &str,
    spec: &PluginSpec,
    shape: Option<&ShapeGeometry>,
    base: &Path,
) -> Result<(Arc<dyn Emitter>, f32), String> {
    let plugin =
        registry::find::<EmitterPlugin>(&spec.kind).map_err(|e| format!("{label}: {e}"))?;
    let mut values = spec.params.clone();
    let weight = match values.remove(SAMPLING_WEIGHT) {
        None => 1.0,
        Some(value) => {
            let number = match &value {
                Value::Number(n) => Some(n.into_f64()),
                _ => None,
            };
            // Not 0: `path` finds a light only through the estimate of the light it chose (a
            // BSDF sample counts the light it was drawn for), so a light never chosen would
            // be missing from the image.
            number
                .filter(|w| *w > 0.0 && *w <= MAX_SAMPLING_WEIGHT)
                .ok_or_else(|| {
                    format!(
                        "{label} ({}): `{SAMPLING_WEIGHT}` must be a number in (0, 1e12] (a \
                         light of weight 0 would never be chosen, and its light would be \
                         missing), found {}",
                        spec.kind,
                        ron::to_string(&value).unwrap_or_default()
                    )
                })? as f32
        }
    };
    let mut params = Params::new(format!("{label} ({})", spec.kind), plugin.params, values)
        .map_err(|e| e.to_string())?
        .with_base_dir(base);
    let emitter = (plugin.create)(&mut params, &EmitterContext { shape })
        .map_err(|e| format!("{label}: {e}"))?;
    params.finish().map_err(|e| e.to_string())?;
    Ok((emitter, weight))
}

enum ShapeError {
    /// A problem with the scene's description of the shape.
    Scene(String),
    /// A problem with a file the shape refers to.
    Asset(PathBuf, String),
}

/// Refuses an unknown shape type, and fields that do not apply to the shape's type.
fn check_shape_fields(shape: &ShapeDescription) -> Result<(), ShapeError> {
    let scene_err = |m: String| ShapeError::Scene(m);
    let allowed: &[&str] = match shape.kind.as_str() {
        "gltf" => &["file", "mesh", "face_normals", "flip_normals", "lights"],
        "obj" => &[
            "file",
            "mesh",
            "face_normals",
            "flip_normals",
            "smooth_normals",
        ],
        "ply" => &["file", "face_normals", "flip_normals", "smooth_normals"],
        "serialized" => &[
            "file",
            "face_normals",
            "flip_normals",
            "smooth_normals",
            "shape_index",
        ],
        "sphere" => &["center", "radius"],
        "disk" => &["segments", "flip_normals"],
        "rectangle" | "cube" => &["flip_normals"],
        other => {
            const KINDS: [&str; 8] = [
                "gltf",
                "rectangle",
                "cube",
                "disk",
                "sphere",
                "obj",
                "ply",
                "serialized",
            ];
            return Err(scene_err(format!(
                "unknown shape type `{other}`{}; known shape types: {}",
                did_you_mean(other, KINDS),
                KINDS.join(", ")
            )));
        }
    };
    let given = [
        ("file", shape.file.is_some()),
        ("mesh", shape.mesh.is_some()),
        ("center", shape.center.is_some()),
        ("radius", shape.radius.is_some()),
        ("segments", shape.segments.is_some()),
        ("face_normals", shape.face_normals.is_some()),
        ("flip_normals", shape.flip_normals.is_some()),
        ("smooth_normals", shape.smooth_normals.is_some()),
        ("shape_index", shape.shape_index.is_some()),
        ("lights", shape.lights.is_some()),
    ];
    if let Some((name, _)) = given
        .iter()
        .find(|(name, set)| *set && !allowed.contains(name))
    {
        return Err(scene_err(format!(
            "`{name}` does not apply to a {} shape",
            shape.kind
        )));
    }
    Ok(())
}

/// The shape's geometry, how its points map to texture coordinates (Mitsuba's
/// parameterisations: in the shape's own frame for a sphere and a disk), and whether it is a
/// mesh read from a file none of whose triangles has an area in the file's own coordinates (as
/// some exported scenes hold: lines kept as triangles).
fn build_shape(
    shape: &ShapeDescription,
    base: &Path,
) -> Result<(ShapeGeometry, UvMapping, bool), ShapeError> {
    let scene_err = |m: String| ShapeError::Scene(m);
    check_shape_fields(shape)?;
    let matrix = transform_matrix(&shape.transform).map_err(scene_err)?;
    let mesh = match shape.kind.as_str() {
        "gltf" => {
            let file = shape
                .file
                .as_ref()
                .ok_or_else(|| scene_err("a gltf shape needs `file`".into()))?;
            let file = base.join(file);
            gltf::load(&file, shape.mesh.as_deref())
                .map_err(|m| ShapeError::Asset(file.clone(), m))?
        }
        "obj" | "ply" | "serialized" => {
            let file = shape
                .file
                .as_ref()
                .ok_or_else(|| scene_err(format!("a {} shape needs `file`", shape.kind)))?;
            let file = base.join(file);
            match shape.kind.as_str() {
                "obj" => obj::load(&file, shape.mesh.as_deref()),
                "ply" => ply::load(&file),
                _ => serialized::load(&file, shape.shape_index.unwrap_or(0)),
            }
            .map_err(|m| ShapeError::Asset(file.clone(), m))?
        }
        "rectangle" => geometry::rectangle(),
        "cube" => geometry::cube(),
        "disk" => {
            let segments = shape.segments.unwrap_or(64);
            if !(3..=1 << 20).contains(&segments) {
                return Err(scene_err(format!(
                    "disk `segments` must be in 3..=1048576, found {segments}"
                )));
            }
            geometry::disk(segments)
        }
        _ => {
            let radius = shape.radius.unwrap_or(1.0);
            let center = Vec3::from(shape.center.unwrap_or([0.0; 3]));
            if !center.is_finite() {
                return Err(scene_err(format!(
                    "sphere `center` must be finite, found {}",
                    crate::limits::fmt_f32s(&center.to_array())
                )));
            }
            if !(radius > 0.0 && radius.is_finite()) {
                return Err(scene_err(format!(
                    "sphere `radius` must be positive and finite, found {radius}"
                )));
            }
            // An analytic sphere stays a sphere only under rotation, uniform scale and translation.
            let (scale, _, _) = matrix.to_scale_rotation_translation();
            let s = scale.abs();
            if (s.x - s.y).abs() > 1e-4 * s.x || (s.x - s.z).abs() > 1e-4 * s.x {
                return Err(scene_err(format!(
                    "a sphere's transform must scale uniformly, found scale {:?}",
                    scale.to_array()
                )));
            }
            let sphere = ShapeGeometry::Sphere(Sphere {
                center: matrix.transform_point3(center),
                radius: radius * s.x,
            });
            let to_object = glam::Mat3::from_mat4(matrix).inverse();
            return Ok((sphere, UvMapping::Sphere { to_object }, false));
        }
    };
    let mapping = match shape.kind.as_str() {
        // Mitsuba's polar coordinates are not linear over the fan's triangles.
        "disk" => UvMapping::Polar {
            to_object: glam::Affine3A::from_mat4(matrix).inverse(),
        },
        _ => UvMapping::Intrinsic,
    };
    let flat_file =
        matches!(shape.kind.as_str(), "gltf" | "obj" | "ply" | "serialized") && !has_area(&mesh);
    Ok((
        ShapeGeometry::Mesh(finish_mesh(shape, mesh, &matrix)),
        mapping,
        flat_file,
    ))
}

/// The shape's normal options, then its transform; smooth normals (`smooth_normals`) are
/// computed in world space, where Mitsuba computes them (angles change under non-uniform
/// scaling).
fn finish_mesh(shape: &ShapeDescription, mut mesh: Mesh, matrix: &glam::Mat4) -> Mesh {
    let face_normals = shape.face_normals == Some(true);
    if face_normals {
        mesh.normals = None;
    }
    if shape.flip_normals == Some(true) {
        mesh = mesh.flipped();
    }
    let mut mesh = mesh.transformed(matrix);
    if shape.smooth_normals == Some(true) && !face_normals && mesh.normals.is_none() {
        mesh.normals = Some(mesh.smooth_normals());
    }
    mesh
}

/// A `gltf` shape without `bsdf`: one part per glTF material, with the BSDF it maps to.
fn build_gltf_material_parts(
    shape: &ShapeDescription,
    base: &Path,
) -> Result<Vec<(String, PluginSpec, ShapeGeometry)>, ShapeError> {
    if shape.kind != "gltf" {
        return Err(ShapeError::Scene(
            "needs `bsdf` (only gltf shapes can take their materials from the file)".into(),
        ));
    }
    check_shape_fields(shape)?;
    let matrix = transform_matrix(&shape.transform).map_err(ShapeError::Scene)?;
    let file = shape
        .file
        .as_ref()
        .ok_or_else(|| ShapeError::Scene("a gltf shape needs `file`".into()))?;
    let file = base.join(file);
    let parts = std::fs::read(&file)
        .map_err(|e| format!("cannot read glTF file: {e}"))
        .and_then(|bytes| {
            gltf_scene::gltf_materials(
                &bytes,
                file.parent().unwrap_or(Path::new(".")),
                shape.mesh.as_deref(),
            )
        })
        .map_err(|m| ShapeError::Asset(file.clone(), m))?;
    Ok(parts
        .into_iter()
        .map(|(name, spec, mesh)| {
            (
                name,
                spec,
                ShapeGeometry::Mesh(finish_mesh(shape, mesh, &matrix)),
            )
        })
        .collect())
}

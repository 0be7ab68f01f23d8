//! `<shape>`: `obj`, `ply`, `serialized`, `rectangle`, `cube`, `disk` and `sphere`, with their
//! BSDF (nested or referenced) and area emitter (nested or referenced).

use super::properties::{Properties, Value, line};
use super::{Converter, bsdf, transform};
use lumis_core::scene::description::{ShapeDescription, TransformDescription};
use roxmltree::Node;

/// Triangles of the polygon that stands for a disk.
const DISK_SEGMENTS: u32 = 1024;

/// Name of the BSDF given to shapes without one.
const DEFAULT_BSDF: &str = "default";

impl Converter {
    pub(super) fn shape(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        let matrix = p.transform("to_world")?;
        let Some(mut shape) = self.shape_geometry(&mut p)? else {
            return Ok(());
        };
        match p.take("flip_normals") {
            Some((Value::Bool(true), l)) if p.kind == "sphere" => {
                self.problem(l, "a sphere with `flip_normals` is not converted");
                return Ok(());
            }
            Some((Value::Bool(true), _)) => shape.flip_normals = Some(true),
            _ => {}
        }
        if let Some(m) = matrix {
            shape.transform = transform::description(m);
        }
        self.shape_objects(&p, &mut shape)?;
        if shape.bsdf.is_none() {
            shape.bsdf = Some(self.default_bsdf(p.line, None));
        }
        self.shapes.push(shape);
        let owner = format!("the `{}` shape", p.kind);
        self.finish(p, &owner);
        Ok(())
    }

    /// The shape's type and the fields that give its geometry, or `None` after a problem.
    fn shape_geometry(&mut self, p: &mut Properties) -> Result<Option<ShapeDescription>, String> {
        let mut shape = ShapeDescription {
            kind: p.kind.clone(),
            bsdf: None,
            transform: TransformDescription::default(),
            emitter: None,
            file: None,
            mesh: None,
            face_normals: None,
            flip_normals: None,
            smooth_normals: None,
            shape_index: None,
            lights: None,
            center: None,
            radius: None,
            segments: None,
        };
        match p.kind.as_str() {
            "obj" | "ply" | "serialized" => {
                let Some((Value::Str(file), l)) = p.take("filename") else {
                    return Err(format!(
                        "line {}: a {} shape needs `filename`",
                        p.line, p.kind
                    ));
                };
                let Some(found) = self.asset(&file, l, "mesh file") else {
                    p.refused = true;
                    return Ok(None);
                };
                shape.file = Some(found);
                match p.take("face_normals") {
                    Some((Value::Bool(true), _)) => shape.face_normals = Some(true),
                    // Mitsuba computes smooth normals for a mesh that has none.
                    _ => shape.smooth_normals = Some(true),
                }
                if p.kind == "serialized" {
                    match p.take("shape_index") {
                        Some((Value::Int(0), _)) => {}
                        Some((Value::Int(n), l)) => {
                            shape.shape_index = Some(u32::try_from(n).map_err(|_| {
                                format!("line {l}: `shape_index` must be a non-negative integer")
                            })?)
                        }
                        Some((_, l)) => {
                            return Err(format!("line {l}: `shape_index` must be an integer"));
                        }
                        None => {}
                    }
                }
                // Texture coordinates: the loaders turn OBJ's as Mitsuba does by default.
                p.ignore("flip_tex_coords");
            }
            "rectangle" | "cube" => {}
            "disk" => {
                self.note(
                    p.line,
                    "the disk becomes a polygon of 1024 triangles (99.9994 % of its area)",
                );
                shape.segments = Some(DISK_SEGMENTS);
            }
            "sphere" => {
                shape.center = p.point("center")?.map(|c| c.as_vec3().to_array());
                shape.radius = p.number("radius")?.map(|(r, _)| r as f32);
            }
            other => {
                let other = other.to_string();
                self.refuse(
                    p,
                    format!(
                        "shape `{other}` is not converted (obj, ply, serialized, rectangle, \
                         cube, disk and sphere are): its geometry is left out"
                    ),
                );
                return Ok(None);
            }
        }
        Ok(Some(shape))
    }

    /// Gives `shape` its BSDF (by name) and area emitter from the element's nested objects. A
    /// BSDF that cannot be converted becomes Mitsuba's default (noted), so that the geometry
    /// stays; an emitter that cannot be converted leaves the shape without one.
    fn shape_objects(
        &mut self,
        p: &Properties,
        shape: &mut ShapeDescription,
    ) -> Result<(), String> {
        for object in p.objects.clone() {
            let at = line(&object);
            match object.tag_name().name() {
                "ref" => {
                    let id = self.xml.required(&object, "id")?;
                    if self.bsdfs.contains_key(&id) {
                        shape.bsdf = Some(id);
                    } else if let Some(&(file, l)) = self.refused_bsdfs.get(&id) {
                        let place = format!("{}:{l}", self.files[file].0.display());
                        shape.bsdf = Some(self.default_bsdf(at, Some(&place)));
                    } else if let Some(emitter) = self.area_emitters.get(&id) {
                        shape.emitter = Some(emitter.clone());
                    } else {
                        let what = self.what_is(&id);
                        self.problem(
                            at,
                            format!(
                                "reference to `{id}`, which names {what}: not a BSDF or area \
                                 emitter this shape can take"
                            ),
                        );
                    }
                }
                "bsdf" => match self.nested_bsdf(&object)? {
                    Some(name) => shape.bsdf = Some(name),
                    None => {
                        let place = format!("line {at}");
                        shape.bsdf = Some(self.default_bsdf(at, Some(&place)));
                    }
                },
                "emitter" => shape.emitter = self.area_emitter(&object)?,
                other => self.problem(at, format!("<{other}> inside a shape is not converted")),
            }
        }
        Ok(())
    }

    /// A BSDF nested in a shape, added to the scene's BSDFs under its `id` or a new name; the
    /// name, or `None` after a problem.
    fn nested_bsdf(&mut self, node: &Node) -> Result<Option<String>, String> {
        let Some(bsdf) = self.bsdf(node)? else {
            return Ok(None);
        };
        self.anonymous += 1;
        let name = self
            .xml
            .attribute(node, "id")?
            .unwrap_or(format!("bsdf{}", self.anonymous));
        self.bsdfs.insert(name.clone(), bsdf);
        Ok(Some(name))
    }

    /// Mitsuba's default BSDF, added to the scene's BSDFs: its name. `refused`: where the
    /// shape's own BSDF was that could not be converted (with --partial the shape keeps its
    /// geometry with this one).
    fn default_bsdf(&mut self, at: u32, refused: Option<&str>) -> String {
        match refused {
            None => self.note(
                at,
                "a shape without BSDF gets Mitsuba's default, diffuse 0.5",
            ),
            Some(place) => self.note(
                at,
                format!(
                    "the shape's BSDF ({place}) is not converted: with --partial the shape \
                     keeps its geometry with Mitsuba's default BSDF, diffuse 0.5"
                ),
            ),
        }
        self.bsdfs
            .entry(DEFAULT_BSDF.into())
            .or_insert_with(bsdf::default_bsdf);
        DEFAULT_BSDF.into()
    }
}

//! `<shape>`: `obj`, `ply`, `rectangle`, `cube`, `disk` and `sphere`, with their BSDF (nested
//! or referenced) and area emitter.

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
        if !self.shape_objects(&p.objects, &mut shape)? {
            return Ok(());
        }
        if shape.bsdf.is_none() {
            shape.bsdf = Some(self.default_bsdf(p.line));
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
            lights: None,
            center: None,
            radius: None,
            segments: None,
        };
        match p.kind.as_str() {
            "obj" | "ply" => {
                let Some((Value::Str(file), _)) = p.take("filename") else {
                    return Err(format!(
                        "line {}: a {} shape needs `filename`",
                        p.line, p.kind
                    ));
                };
                shape.file = Some(self.path(&file));
                if let Some((Value::Bool(b), _)) = p.take("face_normals") {
                    shape.face_normals = Some(b);
                }
                // Texture coordinates are not used.
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
                self.problem(p.line, format!("shape `{other}` is not converted"));
                return Ok(None);
            }
        }
        Ok(Some(shape))
    }

    /// Gives `shape` its BSDF (by name) and area emitter from its nested `objects`; false after
    /// a problem.
    fn shape_objects(
        &mut self,
        objects: &[Node],
        shape: &mut ShapeDescription,
    ) -> Result<bool, String> {
        for object in objects {
            match object.tag_name().name() {
                "ref" => {
                    let id = self.xml.required(object, "id")?;
                    if !self.bsdfs.contains_key(&id) {
                        self.problem(
                            line(object),
                            format!("reference to `{id}`, which is not a converted BSDF"),
                        );
                        return Ok(false);
                    }
                    shape.bsdf = Some(id);
                }
                "bsdf" => match self.nested_bsdf(object)? {
                    Some(name) => shape.bsdf = Some(name),
                    None => return Ok(false),
                },
                "emitter" => match self.area_emitter(object)? {
                    Some(area) => shape.emitter = Some(area),
                    None => return Ok(false),
                },
                other => {
                    self.problem(
                        line(object),
                        format!("<{other}> inside a shape is not converted"),
                    );
                    return Ok(false);
                }
            }
        }
        Ok(true)
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

    /// Mitsuba's default BSDF, added to the scene's BSDFs: its name.
    fn default_bsdf(&mut self, at: u32) -> String {
        self.note(
            at,
            "a shape without BSDF gets Mitsuba's default, diffuse 0.5",
        );
        self.bsdfs
            .entry(DEFAULT_BSDF.into())
            .or_insert_with(bsdf::default_bsdf);
        DEFAULT_BSDF.into()
    }
}

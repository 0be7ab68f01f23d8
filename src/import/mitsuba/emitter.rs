//! `<emitter>`: `area` on a shape; `envmap` (OpenEXR, turned about +y), `point` and
//! `directional` in the scene.

use super::Converter;
use super::properties::{Properties, Value};
use glam::{DMat4, DVec3};
use lumis_core::scene::description::PluginSpec;
use lumis_emitters::{SCALE, area, directional, envmap, point};
use roxmltree::Node;

fn f32s(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

impl Converter {
    /// An emitter nested in a shape, which must be an `area` emitter; `None` after a problem.
    pub(super) fn area_emitter(&mut self, node: &Node) -> Result<Option<PluginSpec>, String> {
        let mut p = self.properties(node)?;
        self.objects_not_converted(&p.objects, "an emitter", true);
        if p.kind != "area" {
            self.problem(
                p.line,
                format!("emitter `{}` on a shape is not converted", p.kind),
            );
            return Ok(None);
        }
        let Some(radiance) = p.color("radiance", 1.0)? else {
            return Ok(None);
        };
        self.finish(p, "the area emitter");
        Ok(Some(
            PluginSpec::new(area::NAME).rgb(area::RADIANCE, f32s(radiance)),
        ))
    }

    /// An emitter of the scene (not on a shape).
    pub(super) fn emitter(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        self.objects_not_converted(&p.objects, "an emitter", false);
        let to_world = p.transform("to_world")?;
        let scale = p.number("scale")?.map_or(1.0, |(s, _)| s) as f32;
        let emitter = match p.kind.as_str() {
            "envmap" => self.envmap(&mut p, to_world)?,
            "point" => self.point(&mut p, to_world)?,
            "directional" => self.directional(&mut p, to_world)?,
            other => {
                self.problem(p.line, format!("emitter `{other}` is not converted"));
                return Ok(());
            }
        };
        let Some(emitter) = emitter else {
            return Ok(());
        };
        self.emitters.push(emitter.float(SCALE.name, scale));
        let owner = format!("the `{}` emitter", p.kind);
        self.finish(p, &owner);
        Ok(())
    }

    /// An OpenEXR map turned about +y: bilinear, in Mitsuba's orientation.
    fn envmap(
        &mut self,
        p: &mut Properties,
        to_world: Option<DMat4>,
    ) -> Result<Option<PluginSpec>, String> {
        let Some((Value::Str(file), l)) = p.take("filename") else {
            return Err(format!("line {}: an envmap needs `filename`", p.line));
        };
        if !file.to_ascii_lowercase().ends_with(".exr") {
            self.problem(
                l,
                format!("env map `{file}`: lumis reads OpenEXR maps only"),
            );
            return Ok(None);
        }
        if let Some((Value::Bool(true), l)) = p.take("mis_compensation") {
            self.problem(l, "`mis_compensation` is not converted");
        }
        let m = to_world.unwrap_or(DMat4::IDENTITY);
        // Only a turn about +y: R_y(a) has first row (cos a, 0, sin a).
        let angle = m.col(2)[0].atan2(m.col(0)[0]);
        if !m.abs_diff_eq(DMat4::from_rotation_y(angle), 1e-5) {
            self.problem(
                p.line,
                "an env map's `to_world` other than a rotation about +y is not converted",
            );
            return Ok(None);
        }
        Ok(Some(
            PluginSpec::new(envmap::NAME)
                .string(envmap::FILE, self.path(&file))
                .float(envmap::ROTATION, angle.to_degrees() as f32)
                .string(envmap::INTERPOLATION, envmap::BILINEAR)
                .string(envmap::ORIENTATION, envmap::MITSUBA),
        ))
    }

    /// A point light at `position` or at the origin of `to_world`.
    fn point(
        &mut self,
        p: &mut Properties,
        to_world: Option<DMat4>,
    ) -> Result<Option<PluginSpec>, String> {
        let position = match (p.take("position"), to_world) {
            (Some((Value::Vector(v), _)), None) => v,
            (None, Some(m)) => m.transform_point3(DVec3::ZERO),
            (None, None) => DVec3::ZERO,
            _ => {
                return Err(format!(
                    "line {}: a point light takes `position` or `to_world`",
                    p.line
                ));
            }
        };
        let Some(intensity) = p.color("intensity", 1.0)? else {
            return Ok(None);
        };
        Ok(Some(
            PluginSpec::new(point::NAME)
                .vec3(point::POSITION, position.as_vec3().to_array())
                .rgb(point::INTENSITY, f32s(intensity)),
        ))
    }

    /// A directional light along `direction` or along the +z of `to_world`.
    fn directional(
        &mut self,
        p: &mut Properties,
        to_world: Option<DMat4>,
    ) -> Result<Option<PluginSpec>, String> {
        let direction = match (p.take("direction"), to_world) {
            (Some((Value::Vector(v), _)), None) => v,
            (None, Some(m)) => m.transform_vector3(DVec3::Z),
            (None, None) => DVec3::Z,
            _ => {
                return Err(format!(
                    "line {}: a directional light takes `direction` or `to_world`",
                    p.line
                ));
            }
        };
        let Some(irradiance) = p.color("irradiance", 1.0)? else {
            return Ok(None);
        };
        Ok(Some(
            PluginSpec::new(directional::NAME)
                .vec3(
                    directional::DIRECTION,
                    direction.normalize_or_zero().as_vec3().to_array(),
                )
                .rgb(directional::IRRADIANCE, f32s(irradiance)),
        ))
    }
}

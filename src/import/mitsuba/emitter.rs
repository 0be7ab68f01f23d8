//! `<emitter>`: `area` on a shape (nested, or given at the scene's level with an `id` that
//! shapes refer to); `envmap` (OpenEXR, under any rotation), `constant`, `point`, `spot` and
//! `directional` in the scene. Emitted colours are read as Mitsuba's RGB variants read them
//! (`Properties::emission`: a uniform spectrum is not grey).

use super::Converter;
use super::properties::{Properties, Value, line};
use glam::{DMat3, DMat4, DQuat, DVec3};
use lumis_core::scene::description::PluginSpec;
use lumis_core::scene::load::SAMPLING_WEIGHT;
use lumis_emitters::{SCALE, area, constant, directional, envmap, point, spot};
use roxmltree::Node;

fn f32s(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// The rotation part of `m` if `m` is a rotation (with a translation, which directions do not
/// see): its columns orthonormal and right-handed, within 1e-5.
fn rotation_of(m: DMat4) -> Option<DMat3> {
    let r = DMat3::from_mat4(m);
    let product = r.transpose() * r;
    (product.abs_diff_eq(DMat3::IDENTITY, 1e-5) && r.determinant() > 0.0).then_some(r)
}

/// `spec` with Mitsuba's `sampling_weight`, if the emitter gave one (lumis reads it on every
/// emitter; the scene loader checks its value).
fn with_sampling_weight(spec: PluginSpec, weight: Option<(f64, u32)>) -> PluginSpec {
    match weight {
        Some((w, _)) => spec.float(SAMPLING_WEIGHT, w as f32),
        None => spec,
    }
}

impl Converter {
    /// An emitter nested in a shape, which must be an `area` emitter; `None` after a problem.
    pub(super) fn area_emitter(&mut self, node: &Node) -> Result<Option<PluginSpec>, String> {
        let mut p = self.properties(node)?;
        if p.kind != "area" {
            let kind = p.kind.clone();
            self.refuse(
                &mut p,
                format!(
                    "emitter `{kind}` on a shape is not converted (area only): the shape is \
                     kept, without emission"
                ),
            );
            return Ok(None);
        }
        self.objects_not_converted(&p.objects, "an emitter", true);
        let Some(radiance) = p.emission("radiance", 1.0)? else {
            return Ok(None);
        };
        let weight = p.number(SAMPLING_WEIGHT)?;
        self.finish(p, "the area emitter");
        let spec = PluginSpec::new(area::NAME).rgb(area::RADIANCE, f32s(radiance));
        Ok(Some(with_sampling_weight(spec, weight)))
    }

    /// An emitter of the scene (not on a shape).
    pub(super) fn emitter(&mut self, node: &Node) -> Result<(), String> {
        if self.xml.attribute(node, "type")?.as_deref() == Some("area") {
            // Given apart for shapes that refer to it by id.
            let id = self.xml.attribute(node, "id")?;
            let spec = self.area_emitter(node)?;
            match (id, spec) {
                (Some(id), Some(spec)) => {
                    self.area_emitters.insert(id, spec);
                }
                (None, _) => self.problem(
                    line(node),
                    "an `area` emitter at the scene's level without `id` is on no shape",
                ),
                (Some(_), None) => {}
            }
            return Ok(());
        }
        let mut p = self.properties(node)?;
        if p.kind == "spot"
            && let Some(texture) = p.objects.first()
        {
            let at = line(texture);
            p.refused = true;
            self.problem(
                at,
                "a spot light with a `texture` (an image projected through its cone) is not \
                 converted: lumis' `spot` has no texture; the light is left out",
            );
            return Ok(());
        }
        self.objects_not_converted(&p.objects, "an emitter", false);
        let to_world = p.transform("to_world")?;
        let scale = p.number("scale")?.map_or(1.0, |(s, _)| s) as f32;
        let weight = p.number(SAMPLING_WEIGHT)?;
        let emitter = match p.kind.as_str() {
            "envmap" => self.envmap(&mut p, to_world)?,
            "constant" => self.constant(&mut p)?,
            "point" => self.point(&mut p, to_world)?,
            "spot" => self.spot(&mut p, to_world)?,
            "directional" => self.directional(&mut p, to_world)?,
            other => {
                let other = other.to_string();
                self.refuse(&mut p, format!("emitter `{other}` is not converted"));
                return Ok(());
            }
        };
        let Some(emitter) = emitter else {
            return Ok(());
        };
        let emitter = emitter.float(SCALE.name, scale);
        self.emitters.push(with_sampling_weight(emitter, weight));
        let owner = format!("the `{}` emitter", p.kind);
        self.finish(p, &owner);
        Ok(())
    }

    /// An OpenEXR map under any rotation: bilinear, in Mitsuba's orientation, turned by the
    /// rotation's angle about its axis.
    fn envmap(
        &mut self,
        p: &mut Properties,
        to_world: Option<DMat4>,
    ) -> Result<Option<PluginSpec>, String> {
        let Some((Value::Str(file), l)) = p.take("filename") else {
            return Err(format!("line {}: an envmap needs `filename`", p.line));
        };
        if !file.to_ascii_lowercase().ends_with(".exr") {
            self.refuse(
                p,
                format!("env map `{file}`: lumis reads OpenEXR maps only"),
            );
            return Ok(None);
        }
        let Some(path) = self.asset(&file, l, "env map") else {
            p.refused = true;
            return Ok(None);
        };
        if let Some((Value::Bool(true), l)) = p.take("mis_compensation") {
            self.problem(l, "`mis_compensation` is not converted");
        }
        let Some(rotation) = rotation_of(to_world.unwrap_or(DMat4::IDENTITY)) else {
            self.refuse(
                p,
                "an env map's `to_world` that scales, skews or mirrors is not converted: \
                 Mitsuba applies it to directions without normalising them (its envmap.cpp \
                 looks the map up at acos(y) of the unnormalised direction and samples \
                 unnormalised directions), so its image is not the map turned",
            );
            return Ok(None);
        };
        let (axis, angle) = DQuat::from_mat3(&rotation).normalize().to_axis_angle();
        let mut spec = PluginSpec::new(envmap::NAME)
            .string(envmap::FILE, path)
            .string(envmap::INTERPOLATION, envmap::BILINEAR)
            .string(envmap::ORIENTATION, envmap::MITSUBA);
        // About +y (or none): the angle alone, as a turn about y is written.
        let about_y = axis.x.abs() < 1e-9 && axis.z.abs() < 1e-9;
        let degrees = angle.to_degrees() * if about_y && axis.y < 0.0 { -1.0 } else { 1.0 };
        let degrees = if degrees > 180.0 {
            degrees - 360.0
        } else {
            degrees
        };
        if degrees != 0.0 {
            spec = spec.float(envmap::ROTATION, degrees as f32);
        }
        if !about_y {
            spec = spec.vec3(envmap::ROTATION_AXIS, axis.as_vec3().to_array());
        }
        Ok(Some(spec))
    }

    /// A uniform environment.
    fn constant(&mut self, p: &mut Properties) -> Result<Option<PluginSpec>, String> {
        let Some(radiance) = p.emission("radiance", 1.0)? else {
            return Ok(None);
        };
        Ok(Some(
            PluginSpec::new(constant::NAME).rgb(constant::RADIANCE, f32s(radiance)),
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
        let Some(intensity) = p.emission("intensity", 1.0)? else {
            return Ok(None);
        };
        Ok(Some(
            PluginSpec::new(point::NAME)
                .vec3(point::POSITION, position.as_vec3().to_array())
                .rgb(point::INTENSITY, f32s(intensity)),
        ))
    }

    /// A spot light at the origin of `to_world`, shining along its +z.
    fn spot(
        &mut self,
        p: &mut Properties,
        to_world: Option<DMat4>,
    ) -> Result<Option<PluginSpec>, String> {
        let m = to_world.unwrap_or(DMat4::IDENTITY);
        let linear = DMat3::from_mat4(m);
        let scales = [linear.x_axis, linear.y_axis, linear.z_axis].map(|c| c.length());
        // Mitsuba measures the angle from the axis through the inverse transform: a
        // non-uniform scale would change the cone's shape.
        if rotation_of(DMat4::from_mat3(linear / scales[0])).is_none() {
            self.refuse(
                p,
                "a spot light's `to_world` that scales unevenly, skews or mirrors is not \
                 converted",
            );
            return Ok(None);
        }
        let Some(intensity) = p.emission("intensity", 1.0)? else {
            return Ok(None);
        };
        let mut spec = PluginSpec::new(spot::NAME)
            .vec3(
                spot::POSITION,
                m.transform_point3(DVec3::ZERO).as_vec3().to_array(),
            )
            .vec3(
                spot::DIRECTION,
                m.transform_vector3(DVec3::Z)
                    .normalize()
                    .as_vec3()
                    .to_array(),
            )
            .rgb(spot::INTENSITY, f32s(intensity));
        for name in [spot::CUTOFF_ANGLE, spot::BEAM_WIDTH] {
            if let Some((degrees, l)) = p.number(name)? {
                let least = if name == spot::CUTOFF_ANGLE {
                    0.0
                } else {
                    -1.0
                };
                if !(degrees > least && degrees <= 180.0) {
                    self.problem(
                        l,
                        format!(
                            "a spot light's `{name}` of {degrees}° is out of range (the cut-off \
                             in (0, 180] degrees: at 0 the cone is empty; the beam in [0, 180])"
                        ),
                    );
                    return Ok(None);
                }
                spec = spec.float(name, degrees as f32);
            }
        }
        Ok(Some(spec))
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
        let Some(irradiance) = p.emission("irradiance", 1.0)? else {
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

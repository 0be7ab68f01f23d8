//! Parameters that are plugins themselves or may be: a colour or number that accepts a texture,
//! a nested BSDF, and a texture's `to_uv` map. Built through the [`References`] the scene
//! loader gives the parameters.

use super::{ParamKind, ParamSpec, Params, PluginError, References, as_number};
use crate::bsdf::Bsdf;
use crate::math::Rgb;
use crate::texture::{Texture, Textured, UvTransform};
use ron::Value;
use std::rc::Rc;
use std::sync::Arc;

impl Params {
    /// A colour parameter that accepts a texture ([`ParamKind::RgbOrTexture`]): a constant
    /// (one number or `(r, g, b)`, each channel in [0, max]) or a texture written inline,
    /// `(type: "checkerboard", ...)`, whose values lie in [0, max].
    pub fn rgb_or_texture(&mut self, name: &str) -> Result<Textured<Rgb>, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::RgbOrTexture { default, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as rgb or texture");
        };
        const EXPECTED: &str =
            "an RGB triple (r, g, b), one number, or a texture such as (type: \"checkerboard\")";
        match value {
            Some(texture @ Value::Map(_)) => {
                let texture = self.texture(spec, &texture, [0.0, max])?;
                Ok(Textured::Texture(texture))
            }
            value => {
                let constant = self.rgb_value(spec, value.as_ref(), default, max, EXPECTED)?;
                Ok(Textured::Constant(constant))
            }
        }
    }

    /// A number parameter that accepts a texture ([`ParamKind::FloatOrTexture`]): a constant in
    /// [min, max] or a texture written inline whose values (`eval_1`) lie in [min, max].
    pub fn float_or_texture(&mut self, name: &str) -> Result<Textured<f32>, PluginError> {
        let (spec, value) = self.take(name);
        let ParamKind::FloatOrTexture { default, min, max } = spec.kind else {
            panic!("parameter `{name}` is not declared as float or texture");
        };
        const EXPECTED: &str = "a number or a texture such as (type: \"checkerboard\")";
        match value {
            Some(texture @ Value::Map(_)) => {
                let texture = self.texture(spec, &texture, [min, max])?;
                Ok(Textured::Texture(texture))
            }
            value => {
                let constant =
                    self.float_value(spec, value.as_ref(), default, [min, max], EXPECTED)?;
                Ok(Textured::Constant(constant))
            }
        }
    }

    /// A nested BSDF ([`ParamKind::Bsdf`]): the name of one of the scene's `bsdfs` (built once
    /// however many refer to it) or one written inline, `(type: "diffuse", ...)`. A texture
    /// given to it makes this plugin vary over the surface too ([`Params::uses_textures`]).
    pub fn bsdf(&mut self, name: &str) -> Result<Arc<dyn Bsdf>, PluginError> {
        let (spec, value) = self.take(name);
        assert!(
            matches!(spec.kind, ParamKind::Bsdf),
            "parameter `{name}` is not declared as a bsdf"
        );
        const EXPECTED: &str =
            "a BSDF: the name of one of the scene's bsdfs, or one such as (type: \"diffuse\")";
        let value = value.ok_or_else(|| self.missing(spec, EXPECTED))?;
        if !matches!(value, Value::String(_) | Value::Map(_)) {
            return Err(self.wrong_type(name, EXPECTED, &value));
        }
        let label = self.label(spec);
        let (bsdf, flags) = self
            .references(spec)?
            .bsdf(&label, &value)
            .map_err(|e| PluginError::Invalid(format!("{label}: {e}")))?;
        self.textured |= flags.spatially_varying();
        Ok(bsdf)
    }

    /// A texture's map of texture coordinates ([`ParamKind::UvTransform`]).
    pub fn uv_transform(&mut self, name: &str) -> Result<UvTransform, PluginError> {
        let (spec, value) = self.take(name);
        assert!(
            matches!(spec.kind, ParamKind::UvTransform),
            "parameter `{name}` is not declared as a uv transform"
        );
        const EXPECTED: &str = "a uv transform such as (scale: (2, 2), rotate: 30, \
             translate: (0.5, 0)) or (matrix: (a, b, c, d, e, f))";
        let Some(value) = value else {
            return Ok(UvTransform::IDENTITY);
        };
        let Value::Map(map) = &value else {
            return Err(self.wrong_type(name, EXPECTED, &value));
        };
        let invalid = |why: String| {
            PluginError::Invalid(format!("{}: {why} (expected {EXPECTED})", self.label(spec)))
        };
        let numbers = |value: &Value, count: usize| -> Option<Vec<f32>> {
            let numbers: Vec<f64> = match value {
                Value::Seq(items) => items.iter().map(as_number).collect::<Option<_>>()?,
                single => vec![as_number(single)?],
            };
            let finite = numbers
                .iter()
                .all(|x| x.is_finite() && x.abs() <= f32::MAX as f64);
            (numbers.len() == count && finite).then(|| numbers.iter().map(|&x| x as f32).collect())
        };
        let (mut scale, mut rotate, mut translate, mut matrix) = (None, None, None, None);
        for (key, value) in map.iter() {
            let Value::String(key) = key else {
                return Err(invalid("its keys must be names".into()));
            };
            let bad = || invalid(format!("`{key}` = {}", super::describe_value(value)));
            match key.as_str() {
                "scale" => {
                    let s = numbers(value, 2).or_else(|| numbers(value, 1).map(|s| vec![s[0]; 2]));
                    scale = Some(s.ok_or_else(bad)?);
                }
                "rotate" => rotate = Some(numbers(value, 1).ok_or_else(bad)?[0]),
                "translate" => translate = Some(numbers(value, 2).ok_or_else(bad)?),
                "matrix" => matrix = Some(numbers(value, 6).ok_or_else(bad)?),
                other => {
                    return Err(invalid(format!(
                        "unknown key `{other}`{}",
                        crate::error::did_you_mean(
                            other,
                            ["scale", "rotate", "translate", "matrix"]
                        )
                    )));
                }
            }
        }
        if let Some(m) = matrix {
            if scale.is_some() || rotate.is_some() || translate.is_some() {
                return Err(invalid(
                    "`matrix` cannot be combined with the other keys".into(),
                ));
            }
            return Ok(UvTransform {
                rows: [[m[0], m[1], m[2]], [m[3], m[4], m[5]]],
            });
        }
        let mut map = UvTransform::IDENTITY;
        if let Some(s) = scale {
            map = UvTransform {
                rows: [[s[0], 0.0, 0.0], [0.0, s[1], 0.0]],
            };
        }
        if let Some(degrees) = rotate {
            let (sin, cos) = degrees.to_radians().sin_cos();
            let rotation = UvTransform {
                rows: [[cos, -sin, 0.0], [sin, cos, 0.0]],
            };
            map = rotation.after(&map);
        }
        if let Some(t) = translate {
            let shift = UvTransform {
                rows: [[1.0, 0.0, t[0]], [0.0, 1.0, t[1]]],
            };
            map = shift.after(&map);
        }
        Ok(map)
    }

    /// "parameter `name` of <plugin>", for messages.
    fn label(&self, spec: &ParamSpec) -> String {
        format!("parameter `{}` of {}", spec.name, self.plugin)
    }

    /// What builds the plugins the parameters refer to, or an error for parameters read
    /// without (by a test, say).
    fn references(&self, spec: &ParamSpec) -> Result<Rc<dyn References>, PluginError> {
        self.references.clone().ok_or_else(|| {
            PluginError::Invalid(format!(
                "{}: textures and nested BSDFs are built only within a scene",
                self.label(spec)
            ))
        })
    }

    /// The texture `value` describes, whose values must lie in `[min, max]`.
    fn texture(
        &mut self,
        spec: &'static ParamSpec,
        value: &Value,
        [min, max]: [f32; 2],
    ) -> Result<Arc<dyn Texture>, PluginError> {
        let label = self.label(spec);
        let texture = self
            .references(spec)?
            .texture(&label, value)
            .map_err(|e| PluginError::Invalid(format!("{label}: {e}")))?;
        let [least, most] = texture.range();
        if !(least >= min && most <= max) {
            return Err(PluginError::Invalid(format!(
                "{label} must be in {}; its texture takes values in [{}, {}]",
                spec.range_text(),
                crate::limits::fmt_f32(least),
                crate::limits::fmt_f32(most)
            )));
        }
        self.textured = true;
        Ok(texture)
    }
}

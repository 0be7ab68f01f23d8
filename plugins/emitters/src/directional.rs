//! `directional`: light arriving from one direction, as from a very distant sun; a delta emitter.
//!
//! Parameters:
//! - `direction` (vector, required): the direction the light travels in (from the light toward
//!   the scene), normalised.
//! - `irradiance` (rgb, required, W/m²): irradiance on a surface facing the light.
//! - `scale` (float, default 1): multiplies `irradiance`.
//!
//! A surface whose normal makes an angle θ with the light receives irradiance·cos θ when nothing
//! occludes it (the shadow ray goes to infinity). BSDF sampling can never hit it.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::sync::Arc;

pub struct DirectionalLight {
    /// Unit direction toward the light.
    to_light: Vec3,
    irradiance: Rgb,
}

impl Emitter for DirectionalLight {
    fn sample_direction(&self, _: &ReferencePoint, _u: Vec2) -> Option<EmitterSample> {
        Some(EmitterSample {
            wi: self.to_light,
            position: None,
            pdf: 1.0,
            radiance: self.irradiance,
        })
    }

    fn pdf_direction(&self, _: &ReferencePoint, _: Vec3, _: Option<&EmitterHit>) -> f32 {
        0.0
    }

    fn eval(&self, _: Vec3, _: Option<&EmitterHit>) -> Rgb {
        Rgb::ZERO
    }

    fn is_delta(&self) -> bool {
        true
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "directional";
pub const DIRECTION: &str = "direction";
pub const IRRADIANCE: &str = "irradiance";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: DIRECTION,
        kind: ParamKind::Vec3 { default: None },
        unit: "",
        description: "direction the light travels in (toward the scene)",
    },
    ParamSpec {
        name: IRRADIANCE,
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/m²",
        description: "irradiance on a surface facing the light",
    },
    crate::SCALE,
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, NAME)?;
    let direction = params.vec3(DIRECTION)?;
    let Some(travel) = direction.try_normalize() else {
        return Err(PluginError::Invalid(format!(
            "{}: `direction` must not be zero",
            params.plugin()
        )));
    };
    let irradiance = params.rgb(IRRADIANCE)? * params.float(crate::SCALE.name)?;
    Ok(Arc::new(DirectionalLight {
        to_light: -travel,
        irradiance,
    }))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "light from one direction, as from a distant sun (delta: one light sample, never hit)",
        params: PARAMS,
        create,
    }
}

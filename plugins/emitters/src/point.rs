//! `point`: an isotropic point light, a delta emitter.
//!
//! Parameters:
//! - `position` (vector, required): where the light is.
//! - `intensity` (rgb, required, W/sr): radiant intensity.
//! - `scale` (float, default 1): multiplies `intensity`.
//!
//! It is reached only by its own sample (one per shading point): the irradiance it gives a
//! surface at distance d is I·cos θ / d². BSDF sampling can never hit it.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::sync::Arc;

pub struct PointLight {
    position: Vec3,
    intensity: Rgb,
}

impl Emitter for PointLight {
    fn sample_direction(&self, reference: &ReferencePoint, _u: Vec2) -> Option<EmitterSample> {
        let to = self.position - reference.position;
        let d2 = to.length_squared();
        // A light at the shading point itself lights nothing measurable.
        if !(d2 > 0.0 && d2.is_finite()) {
            return None;
        }
        let radiance = self.intensity / d2;
        radiance.is_finite().then(|| EmitterSample {
            wi: to / d2.sqrt(),
            position: Some(self.position),
            pdf: 1.0,
            radiance,
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
pub const NAME: &str = "point";
pub const POSITION: &str = "position";
pub const INTENSITY: &str = "intensity";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: POSITION,
        kind: ParamKind::Vec3 { default: None },
        unit: "",
        description: "position of the light",
    },
    ParamSpec {
        name: INTENSITY,
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/sr",
        description: "radiant intensity",
    },
    crate::SCALE,
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, NAME)?;
    let position = params.vec3(POSITION)?;
    let intensity = params.rgb(INTENSITY)? * params.float(crate::SCALE.name)?;
    Ok(Arc::new(PointLight {
        position,
        intensity,
    }))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "isotropic point light (delta: one light sample, never hit)",
        params: PARAMS,
        create,
    }
}

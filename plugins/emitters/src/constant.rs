//! `constant`: a uniform environment, the same radiance arriving from every direction (Mitsuba's
//! `constant` emitter).
//!
//! Parameters:
//! - `radiance` (rgb, required, W/(m²·sr)): the radiance from every direction.
//! - `scale` (float, default 1): multiplies `radiance`.
//!
//! Sampled uniformly over the sphere (density 1/4π), which for a uniform radiance is what an
//! environment map's luminance sampling would give. It is the scene's environment: rays that
//! leave the scene see it.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::f32::consts::{FRAC_1_PI, TAU};
use std::sync::Arc;

pub struct ConstantEnvironment {
    radiance: Rgb,
}

/// The uniform density over the sphere, 1/4π.
const PDF: f32 = FRAC_1_PI / 4.0;

impl Emitter for ConstantEnvironment {
    fn sample_direction(&self, _: &ReferencePoint, u: Vec2) -> Option<EmitterSample> {
        let z = 1.0 - 2.0 * u.x;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sin, cos) = (TAU * u.y).sin_cos();
        Some(EmitterSample {
            wi: Vec3::new(r * cos, r * sin, z),
            position: None,
            pdf: PDF,
            radiance: self.radiance,
        })
    }

    fn pdf_direction(&self, _: &ReferencePoint, _: Vec3, _: Option<&EmitterHit>) -> f32 {
        PDF
    }

    fn eval(&self, _: Vec3, _: Option<&EmitterHit>) -> Rgb {
        self.radiance
    }

    fn is_delta(&self) -> bool {
        false
    }

    fn is_environment(&self) -> bool {
        true
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "constant";
pub const RADIANCE: &str = "radiance";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: RADIANCE,
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/(m²·sr)",
        description: "radiance arriving from every direction",
    },
    crate::SCALE,
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, NAME)?;
    let radiance = params.rgb(RADIANCE)? * params.float(crate::SCALE.name)?;
    Ok(Arc::new(ConstantEnvironment { radiance }))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "uniform environment: the same radiance from every direction, sampled uniformly",
        params: PARAMS,
        create,
    }
}

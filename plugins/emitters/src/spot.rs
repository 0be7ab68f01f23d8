//! `spot`: a point light shining into a cone, with Mitsuba 3's falloff (`src/emitters/spot.cpp`);
//! a delta emitter.
//!
//! Parameters:
//! - `position` (vector, required): where the light is.
//! - `direction` (vector, required): the cone's axis, the way the light shines; not zero.
//! - `intensity` (rgb, required, W/sr): radiant intensity along the axis.
//! - `cutoff_angle` (float, default 20, degrees, in (0, 180]): the cone's half-angle; no light
//!   leaves at this angle from the axis or beyond.
//! - `beam_width` (float, default ¾ of `cutoff_angle`: 15 with the default cut-off, degrees, in
//!   [0, `cutoff_angle`]): within this angle from the axis the intensity is full.
//! - `scale` (float, default 1): multiplies `intensity`.
//!
//! The intensity toward a direction at angle θ from the axis is `intensity` times the falloff
//! 1 for θ ≤ beam width, (cutoff − θ)/(cutoff − beam width) between (linear in the angle), and
//! 0 from the cut-off on: a surface at distance d receives I·falloff(θ)·cos θ_surface / d². Like
//! the point light it is reached only by its own sample; BSDF sampling never hits it.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::EmitterPlugin;
use std::sync::Arc;

pub struct SpotLight {
    position: Vec3,
    /// Unit axis of the cone.
    axis: Vec3,
    intensity: Rgb,
    cutoff: f32,
    cos_cutoff: f32,
    cos_beam: f32,
    /// 1 / (cutoff − beam width), radians.
    inv_transition: f32,
}

impl SpotLight {
    /// The falloff toward unit direction `d` (from the light), as Mitsuba's `falloff_curve`.
    pub fn falloff(&self, d: Vec3) -> f32 {
        let cos_theta = self.axis.dot(d);
        if cos_theta <= self.cos_cutoff {
            0.0
        } else if cos_theta >= self.cos_beam {
            1.0
        } else {
            ((self.cutoff - cos_theta.clamp(-1.0, 1.0).acos()) * self.inv_transition)
                .clamp(0.0, 1.0)
        }
    }
}

impl Emitter for SpotLight {
    fn sample_direction(&self, reference: &ReferencePoint, _u: Vec2) -> Option<EmitterSample> {
        let to = self.position - reference.position;
        let d2 = to.length_squared();
        if !(d2 > 0.0 && d2.is_finite()) {
            return None;
        }
        let wi = to / d2.sqrt();
        let falloff = self.falloff(-wi);
        if falloff <= 0.0 {
            return None;
        }
        let radiance = self.intensity * (falloff / d2);
        radiance.is_finite().then_some(EmitterSample {
            wi,
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
pub const NAME: &str = "spot";
pub const POSITION: &str = "position";
pub const DIRECTION: &str = "direction";
pub const INTENSITY: &str = "intensity";
pub const CUTOFF_ANGLE: &str = "cutoff_angle";
pub const BEAM_WIDTH: &str = "beam_width";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: POSITION,
        kind: ParamKind::Vec3 { default: None },
        unit: "",
        description: "position of the light",
    },
    ParamSpec {
        name: DIRECTION,
        kind: ParamKind::Vec3 { default: None },
        unit: "",
        description: "axis of the cone, the way the light shines (not zero)",
    },
    ParamSpec {
        name: INTENSITY,
        kind: ParamKind::Rgb {
            default: None,
            max: lumis_core::limits::MAX_EMISSION,
        },
        unit: "W/sr",
        description: "radiant intensity along the axis",
    },
    ParamSpec {
        name: CUTOFF_ANGLE,
        kind: ParamKind::Float {
            default: Some(20.0),
            min: 0.0,
            max: 180.0,
        },
        unit: "degrees",
        description: "half-angle of the cone, beyond which no light leaves (more than 0)",
    },
    ParamSpec {
        name: BEAM_WIDTH,
        kind: ParamKind::Float {
            // ¾ of the default cut-off; with another cut-off, ¾ of that (read in `create`).
            default: Some(15.0),
            min: 0.0,
            max: 180.0,
        },
        unit: "degrees",
        description: "half-angle of full intensity, at most `cutoff_angle` (default 3/4 of it)",
    },
    crate::SCALE,
];

fn create(params: &mut Params, context: &EmitterContext) -> Result<Arc<dyn Emitter>, PluginError> {
    crate::not_on_a_shape(context, NAME)?;
    let position = params.vec3(POSITION)?;
    let direction = params.vec3(DIRECTION)?;
    let intensity = params.rgb(INTENSITY)? * params.float(crate::SCALE.name)?;
    let cutoff_degrees = params.float(CUTOFF_ANGLE)?;
    let beam_degrees = if params.is_given(BEAM_WIDTH) {
        params.float(BEAM_WIDTH)?
    } else {
        cutoff_degrees * 0.75
    };
    let invalid = |m: String| PluginError::Invalid(format!("{}: {m}", params.plugin()));
    let axis = lumis_core::geometry::unit_normal(direction);
    if axis == Vec3::ZERO {
        return Err(invalid(format!(
            "`{DIRECTION}` must be a non-zero vector, found {direction}"
        )));
    }
    if cutoff_degrees.is_nan() || cutoff_degrees <= 0.0 {
        return Err(invalid(format!(
            "`{CUTOFF_ANGLE}` must be more than 0 degrees (a cone of no angle lights nothing), \
             found {cutoff_degrees}"
        )));
    }
    if beam_degrees > cutoff_degrees {
        return Err(invalid(format!(
            "`{BEAM_WIDTH}` {beam_degrees} must be at most `{CUTOFF_ANGLE}` {cutoff_degrees}"
        )));
    }
    let (cutoff, beam) = (cutoff_degrees.to_radians(), beam_degrees.to_radians());
    Ok(Arc::new(SpotLight {
        position,
        axis,
        intensity,
        cutoff,
        cos_cutoff: cutoff.cos(),
        cos_beam: beam.cos(),
        // Never read when the beam fills the cone (no angle is between them).
        inv_transition: if cutoff > beam {
            1.0 / (cutoff - beam)
        } else {
            0.0
        },
    }))
}

inventory::submit! {
    EmitterPlugin {
        name: NAME,
        description: "spot light: a point light into a cone with Mitsuba's linear falloff (delta)",
        params: PARAMS,
        create,
    }
}

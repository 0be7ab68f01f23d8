//! Built-in emitter plugins, one per file, each registered under its scene-file name.

pub mod area;
pub mod constant;
pub mod directional;
pub mod envmap;
pub mod point;
pub mod spot;

use lumis_core::emitter::EmitterContext;
use lumis_core::params::{ParamKind, ParamSpec, PluginError};

/// `scale`, a multiplier every emitter takes.
pub const SCALE: ParamSpec = ParamSpec {
    name: "scale",
    kind: ParamKind::Float {
        default: Some(1.0),
        min: 0.0,
        max: lumis_core::limits::MAX_EMITTER_SCALE,
    },
    unit: "",
    description: "multiplies the emitted power",
};

/// Refuses an emitter that exists on its own (point, directional, environment) on a shape.
pub fn not_on_a_shape(context: &EmitterContext, name: &str) -> Result<(), PluginError> {
    match context.shape {
        Some(_) => Err(PluginError::Invalid(format!(
            "a `{name}` emitter cannot be attached to a shape; list it under `emitters`"
        ))),
        None => Ok(()),
    }
}

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

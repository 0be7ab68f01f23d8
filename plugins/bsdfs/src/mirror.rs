//! `mirror`: perfect specular reflection, a Dirac lobe.
//!
//! Parameters:
//! - `reflectance` (rgb, default (1, 1, 1), in [0, 1]): fraction of light reflected.
//!
//! `eval` and `pdf` are zero for every given direction (a delta has no density); `sample`
//! returns the mirror direction flagged `delta`, with probability 1 and weight `reflectance`.
//! Integrators therefore reach mirrors only by BSDF sampling.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::sync::Arc;

pub struct Mirror {
    reflectance: Rgb,
}

impl Bsdf for Mirror {
    fn eval(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    fn sample(&self, _ctx: &BsdfContext, wo: Vec3, _u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        (wo.z > 0.0)
            .then(|| BsdfSample::delta(Vec3::new(-wo.x, -wo.y, wo.z), 1.0, self.reflectance))
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags::DELTA_REFLECTION
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "mirror";
pub const REFLECTANCE: &str = "reflectance";

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: REFLECTANCE,
    kind: ParamKind::Rgb {
        default: Some([1.0, 1.0, 1.0]),
        max: 1.0,
    },
    unit: "",
    description: "fraction of light reflected, per channel in [0, 1]",
}];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let reflectance = params.rgb(REFLECTANCE)?;
    Ok(Arc::new(Mirror { reflectance }))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "perfect specular reflection (a delta lobe, reached only by BSDF sampling)",
        params: PARAMS,
        create,
    }
}

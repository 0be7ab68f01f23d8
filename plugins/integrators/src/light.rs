//! `light`: direct lighting with light sampling only: per camera sample and per light, all N samples from the light; a purely specular BSDF (a mirror), which light sampling can never reach, gets its N samples from the BSDF instead.
//! Delta lights (point, directional) take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::estimator::Heuristic;
use crate::mis;
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

static PARAMS: &[ParamSpec] = &[mis::SAMPLES, mis::AOVS];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    mis::create_fixed(params, 0.0, Heuristic::Balance)
}

inventory::submit! {
    IntegratorPlugin {
        name: "light",
        description: "direct lighting from light sampling only (BSDF sampling only for Dirac lobes)",
        params: PARAMS,
        create,
    }
}

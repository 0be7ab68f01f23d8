//! `bsdf`: direct lighting with BSDF sampling only: per camera sample and per light, all N samples from the BSDF (delta lights still take one light sample each).
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
    mis::create_fixed(params, 1.0, Heuristic::Balance)
}

inventory::submit! {
    IntegratorPlugin {
        name: "bsdf",
        description: "direct lighting from BSDF sampling only",
        params: PARAMS,
        create,
    }
}

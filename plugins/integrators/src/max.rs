//! `max`: direct lighting with the maximum heuristic: per camera sample and per light, N/2 samples from each technique; each sample is kept only by the technique with the larger n_i p_i (weights 1 or 0; ½ each on ties).
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
    mis::create_fixed(params, 0.5, Heuristic::Maximum)
}

inventory::submit! {
    IntegratorPlugin {
        name: "max",
        description: "direct lighting, BSDF and light sampling combined by the maximum heuristic",
        params: PARAMS,
        create,
    }
}

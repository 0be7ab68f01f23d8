//! `power`: direct lighting with the power heuristic (β = 2): per camera sample and per light, N/2 samples from each technique, weighted w_i = (n_i p_i)² / Σ_k (n_k p_k)² (Veach 1997).
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
    mis::create_fixed(params, 0.5, Heuristic::Power)
}

inventory::submit! {
    IntegratorPlugin {
        name: "power",
        description: "direct lighting, BSDF and light sampling combined by the power heuristic (β = 2)",
        params: PARAMS,
        create,
    }
}

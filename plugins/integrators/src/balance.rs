//! `balance`: direct lighting with the balance heuristic: per camera sample and per light, N/2 samples from each technique (n_B = ⌊N/2 + ½⌋), weighted w_i = n_i p_i / Σ_k n_k p_k, which is the mixture (defensive) estimator with α = ½.
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
    mis::create_fixed(params, 0.5, Heuristic::Balance)
}

inventory::submit! {
    IntegratorPlugin {
        name: "balance",
        description: "direct lighting, BSDF and light sampling combined by the balance heuristic",
        params: PARAMS,
        create,
    }
}

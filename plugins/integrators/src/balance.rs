//! `balance`: direct lighting with the balance heuristic: per camera sample and per light, N/2
//! samples from each technique (n_B = ⌊N/2 + ½⌋), weighted w_i = n_i p_i / Σ_k n_k p_k, which
//! is the mixture (defensive) estimator with α = ½. Delta lights (point, directional) take one
//! light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::allocation::Weighted;
use crate::fixed_alpha::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::weighting::{Balance, PerSample};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "balance";

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by the balance heuristic",
        params: PARAMS,
        create,
    }
}

//! `bsdf`: direct lighting with BSDF sampling only: per camera sample and per light, all N
//! samples from the BSDF. Delta lights (point, directional) take one light sample each.
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
pub const NAME: &str = "bsdf";

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    // With n_L = 0 every weight is 1, whatever the heuristic.
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 1.0,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting from BSDF sampling only",
        params: PARAMS,
        create,
    }
}

//! `light`: direct lighting with light sampling only: per camera sample and per light, all N
//! samples from the light, except at a purely specular BSDF (a mirror), which light sampling
//! can never reach and which gets N BSDF samples instead. Delta lights (point, directional)
//! take one light sample each.
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
pub const NAME: &str = "light";

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    // With n_B = 0 every weight is 1, whatever the heuristic.
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 0.0,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting from light sampling only (BSDF sampling only for Dirac lobes)",
        params: PARAMS,
        create,
    }
}

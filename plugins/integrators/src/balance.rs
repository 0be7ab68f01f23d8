//! `balance`: direct lighting with the balance heuristic: per camera sample and per light, N/2
//! samples from each technique (n_B = ⌊N/2 + ½⌋), weighted w_i = n_i p_i / Σ_k n_k p_k, which
//! is the mixture (defensive) estimator with α = ½. Delta lights (point, directional) take one
//! light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::allocation::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC};
use crate::weighting::{Heuristic, PerSample};
use glam::Vec4;
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "balance";

/// w_i = n_i p_i / Σ_k n_k p_k, written with the ratio r = other / mine so that huge or tiny
/// products neither overflow nor divide 0 by 0.
pub struct Balance;

impl Heuristic for Balance {
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        1.0 / (1.0 + other / mine)
    }

    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        Vec4::ONE / (Vec4::ONE + other / mine)
    }
}

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    MisIntegrator::boxed(params, FixedAlpha { alpha: 0.5 }, PerSample(Balance))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by the balance heuristic",
        params: PARAMS,
        create,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn weights_are_a_partition_of_unity() {
        crate::weighting::assert_partition_of_unity(&super::Balance);
    }
}

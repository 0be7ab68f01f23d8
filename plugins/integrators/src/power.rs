//! `power`: direct lighting with the power heuristic (β = 2): per camera sample and per light,
//! N/2 samples from each technique, weighted w_i = (n_i p_i)² / Σ_k (n_k p_k)² (Veach 1997).
//! Delta lights (point, directional) take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::allocation::Weighted;
use crate::fixed_alpha::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::weighting::{Heuristic, PerSample};
use glam::Vec4;
use lumis_core::integrator::Integrator;
use lumis_core::math::lanes::Lanes;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "power";

/// w_i = (n_i p_i)² / Σ_k (n_k p_k)², with the ratio r = other / mine as for [`Balance`].
///
/// [`Balance`]: crate::weighting::Balance
pub struct Power;

impl Heuristic for Power {
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        power(mine, other)
    }

    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        power(mine, other)
    }
}

/// [`Power`]'s weight, for one sample or for several: 1 / (1 + r²), r = other / mine.
#[inline(always)]
fn power<L: Lanes>(mine: L, other: L) -> L {
    let r = other / mine;
    L::splat(1.0) / (L::splat(1.0) + r * r)
}

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Power)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by the power heuristic (β = 2)",
        params: PARAMS,
        create,
    }
}

//! `max`: direct lighting with the maximum heuristic: per camera sample and per light, N/2
//! samples from each technique; each sample has weight 1 if its technique has the larger n_i p_i
//! at its direction, 0 otherwise (½ each on ties) (Veach 1997). Delta lights (point,
//! directional) take one light sample each.
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
pub const NAME: &str = "max";

/// w_i = 1 for the technique with the larger n_i p_i. Decided by comparing the products
/// themselves, not their rounded ratio, so that the two weights always sum to one.
pub struct Maximum;

impl Heuristic for Maximum {
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        maximum(mine, other)
    }

    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        maximum(mine, other)
    }
}

/// [`Maximum`]'s weight, for one sample or for several: 1 where `mine > other`, else 0.
#[inline(always)]
fn maximum<L: Lanes>(mine: L, other: L) -> L {
    L::select(mine.gt(other), L::splat(1.0), L::splat(0.0))
}

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Maximum)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by the maximum heuristic",
        params: PARAMS,
        create,
    }
}

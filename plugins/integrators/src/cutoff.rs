//! `cutoff`: direct lighting with Veach's cutoff heuristic (Veach 1997, §9.2.2): per camera
//! sample and per light, N/2 samples from each technique; a technique whose n_i p_i at a
//! sample's direction is below `threshold` times the larger of the two gets weight 0 there, and
//! the techniques above the cutoff share the weight as in the balance heuristic:
//! w_i = n_i p_i / Σ_{k: n_k p_k ≥ threshold · max} n_k p_k. It sits between the balance
//! heuristic (threshold 0) and the maximum heuristic (threshold 1): it removes the small
//! weights that add variance where one technique is much better, and keeps the balance
//! heuristic's robustness where the two are comparable. Delta lights (point, directional) take
//! one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `threshold` (float, default 0.1, in [0, 1]): Veach's α, the cutoff relative to the larger
//!   n_i p_i; 0.1 is the value Veach compares the heuristics with.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::allocation::Weighted;
use crate::fixed_alpha::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::weighting::{Heuristic, PerSample, balance};
use glam::Vec4;
use lumis_core::integrator::Integrator;
use lumis_core::math::lanes::Lanes;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "cutoff";
/// Parameter: Veach's α, the cutoff relative to the larger n_i p_i.
pub const THRESHOLD: &str = "threshold";

/// The cutoff heuristic for two techniques.
pub struct Cutoff {
    pub threshold: f32,
}

impl Heuristic for Cutoff {
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        cutoff(mine, other, self.threshold)
    }

    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        cutoff(mine, other, self.threshold)
    }
}

/// [`Cutoff`]'s weight, for one sample or for several: 0 where `mine` is below the cutoff, 1
/// where `other` is, the balance heuristic's weight elsewhere.
#[inline(always)]
fn cutoff<L: Lanes>(mine: L, other: L, threshold: f32) -> L {
    let t = L::splat(threshold);
    let kept = L::select(other.lt(t * mine), L::splat(1.0), balance(mine, other));
    L::select(mine.lt(t * other), L::splat(0.0), kept)
}

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: THRESHOLD,
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "Veach's α: a technique whose n·p is below this fraction of the larger one gets weight 0",
    },
    AOVS_SPEC,
];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let threshold = params.float(THRESHOLD)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(
        params,
        Weighted(allocation, PerSample(Cutoff { threshold })),
    )
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by Veach's cutoff heuristic",
        params: PARAMS,
        create,
    }
}

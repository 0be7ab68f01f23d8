//! `power_beta`: direct lighting with Veach's power heuristic for any exponent β (Veach 1997,
//! §9.2.1): per camera sample and per light, N/2 samples from each technique, weighted
//! w_i = (n_i p_i)^β / Σ_k (n_k p_k)^β. β = 1 is the balance heuristic, β = 2 the built-in
//! `power`, and β → ∞ tends to the maximum heuristic. An example of a weighting heuristic
//! written outside lumis (docs/writing-a-plugin.md); delta lights take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `beta` (float, default 3, in [0.5, 16]): the exponent β.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".

use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_integrators::allocation::Weighted;
use lumis_integrators::fixed_alpha::FixedAlpha;
use lumis_integrators::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use lumis_integrators::weighting::{Heuristic, PerSample};

/// The plugin's name in scene files.
pub const NAME: &str = "power_beta";
/// Parameter: the exponent β.
pub const BETA: &str = "beta";

/// w_i = (n_i p_i)^β / Σ_k (n_k p_k)^β, written with the ratio r = other / mine, as the
/// built-in heuristics are, so that huge or tiny products neither overflow nor give 0 / 0.
pub struct PowerBeta {
    pub beta: f32,
}

impl Heuristic for PowerBeta {
    // `weight4` keeps its default, `weight` lane by lane: `powf` has no vector form in glam.
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        1.0 / (1.0 + (other / mine).powf(self.beta))
    }
}

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: BETA,
        kind: ParamKind::Float {
            default: Some(3.0),
            min: 0.5,
            max: 16.0,
        },
        unit: "",
        description: "the exponent β of the power heuristic",
    },
    AOVS_SPEC,
];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let beta = params.float(BETA)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(PowerBeta { beta })))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting, BSDF and light sampling combined by the power heuristic of exponent β",
        params: PARAMS,
        create,
    }
}

//! `exact_alpha`: direct lighting with the fraction α of BSDF samples that exactly minimises the
//! pilot's estimate of the variance, instead of the second-order approximation of Lu et al.
//! 2013 (`alpha`). Per shading point and light, M samples at α = ½ give the estimate of the
//! second moment of the mixture estimator m̂(α) = (1/M) Σ f² / (q_α p̄), q_α = α p_B + (1 − α)
//! p_L, p̄ = (p_B + p_L)/2, f the luminance of the integrand; m̂ is convex in α, and its minimum
//! over the clamp interval is found by safeguarded Newton steps (docs/integrators.md). Where the
//! second-order α̂ saturates near ¼ or ¾ (a concentrated light or lobe) while the optimum is at
//! the clamp, this reaches the clamp. Balance weights for the realised counts, as `alpha`.
//! Delta lights take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "integrated"): "integrated" — M samples at α = ½ give L̂₁ and α,
//!   the other N − M at α give L̂₂, and the estimate is (M·L̂₁ + (N − M)·L̂₂)/N (as the paper's
//!   Table 2); "preprocessed" — M pilot samples at α = ½ give α only, then N fresh samples at α
//!   (as its Table 1).
//! - `alpha_samples` (integer, default 0 = N/2 integrated, 4096 preprocessed): M.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): the interval α is chosen in.
//! - `variance` (choice, default "mixture"): what is minimised: "mixture" — m̂(α), the variance
//!   of the mixture (one-sample) estimator, as the paper; "stratified" — m̂(α) − α μ̂_B(α)² −
//!   (1 − α) μ̂_L(α)², the variance of the stratified estimator the integrators use (exactly
//!   n_B = ⌊αN + ½⌋ BSDF samples), μ̂_t the mean of technique t's samples (ours).
//! - `statistics` (choice, default "pilot"): where α's statistics come from: "pilot" — the M
//!   samples at α = ½ of `mode`; "passes" — the pixel's earlier passes of a render in passes
//!   (docs/integrators.md, "Learned α"): every sample of a pass at the α its pixel and light
//!   learned before it, the objective kept at 17 evenly spaced α of the clamp interval and
//!   minimised through the best one's parabola; the first pass (and a one-pass render) at α = ½.
//!   `mode` and `alpha_samples` do not apply.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! α is ½ (clamped) when the pilot says nothing about it: no sample saw the light, or p_B = p_L
//! wherever one did. Unbiased in both modes: α depends only on samples the estimate at α does
//! not reuse.

use crate::allocation::Weighted;
use crate::alpha_family::{
    self, ALPHA_SAMPLES_SPEC, AlphaRule, CLAMP_SPEC, MODE_SPEC, PilotAlpha, STATISTICS_SPEC,
    TwoPhases, VARIANCE_SPEC, read_clamp, read_learns, read_mode, read_stratified,
};
use crate::learned::{LearnedAlpha, Pooled};
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::moments::{Objective, PilotSamples};
use crate::weighting::{Balance, PerSample};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "exact_alpha";
/// Parameter: how the pilot is used, [`INTEGRATED`] or [`PREPROCESSED`].
pub const MODE: &str = alpha_family::MODE;
pub const INTEGRATED: &str = alpha_family::INTEGRATED;
pub const PREPROCESSED: &str = alpha_family::PREPROCESSED;
/// Parameter: M, the pilot samples at α = ½.
pub const ALPHA_SAMPLES: &str = alpha_family::ALPHA_SAMPLES;
/// Parameter: the interval α is chosen in.
pub const CLAMP: &str = alpha_family::CLAMP;
/// Parameter: which variance is minimised, [`MIXTURE`] or [`STRATIFIED`].
pub const VARIANCE: &str = alpha_family::VARIANCE;
pub const MIXTURE: &str = alpha_family::MIXTURE;
pub const STRATIFIED: &str = alpha_family::STRATIFIED;

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    MODE_SPEC,
    ALPHA_SAMPLES_SPEC,
    CLAMP_SPEC,
    VARIANCE_SPEC,
    STATISTICS_SPEC,
    AOVS_SPEC,
];

/// Minimises a fixed objective of the pilot exactly ([`PilotSamples::minimise`]).
pub struct Minimise(pub Objective);

impl AlphaRule for Minimise {
    fn alpha(&self, pilot: &PilotSamples, _light: usize, clamp: [f64; 2]) -> Option<f64> {
        pilot.minimise(self.0, clamp)
    }
}

/// The allocation of the parameters above but `samples` and `aovs`, for N = `samples` (also
/// `path`'s at its first vertex).
pub fn read_allocation(
    params: &mut Params,
    samples: u32,
) -> Result<PilotAlpha<Minimise>, PluginError> {
    let phases = TwoPhases {
        samples,
        mode: read_mode(params, samples)?,
    };
    let clamp = read_clamp(params)?;
    let objective = if read_stratified(params)? {
        Objective::Stratified
    } else {
        Objective::Mixture
    };
    Ok(PilotAlpha {
        phases,
        clamp,
        rule: Minimise(objective),
    })
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    if read_learns(params)? {
        let clamp = read_clamp(params)?;
        let objective = if read_stratified(params)? {
            Objective::Stratified
        } else {
            Objective::Mixture
        };
        let allocation = LearnedAlpha::new(samples, Pooled::Nodes(objective), clamp, 0);
        return MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)));
    }
    let allocation = read_allocation(params, samples)?;
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the α that exactly minimises the pilot's estimate of the variance (mixture or stratified)",
        params: PARAMS,
        create,
    }
}

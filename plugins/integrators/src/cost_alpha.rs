//! `cost_alpha`: direct lighting with the fraction α of BSDF samples that maximises efficiency
//! rather than minimising variance: per shading point and light, α minimises the pilot's
//! estimate of variance × cost, V̂(α) · (α c_B + (1 − α) c_L), with c_B and c_L the measured
//! costs of one BSDF and one light sample of that light. V̂ is the variance of the mixture
//! estimator, m̂(α) − μ̂² (as `exact_alpha`, μ̂² estimated without bias from the pilot), or of the
//! stratified estimator the integrators use. Balance weights for the realised counts. Delta
//! lights take one light sample each.
//!
//! The costs are measured once per render, in `preprocess`, on the scene itself: one thread
//! times batches of 8 samples of each technique of each light at the shading points of a grid
//! of up to 48 × 48 pixels, alternating which technique goes first, twice (the first round
//! warms the caches), the slowest 1 % of batches dropped; a sample's cost is what the render
//! pays for it: its direction, its ray, the other technique's density (docs/integrators.md has
//! the measured values and their spread). Measured costs make α, and so the image, depend on
//! the machine's timing (still unbiased); `cost_ratio` fixes them instead.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "integrated"): "integrated" — M samples at α = ½ give L̂₁ and α,
//!   the other N − M at α give L̂₂, and the estimate is (M·L̂₁ + (N − M)·L̂₂)/N; "preprocessed" —
//!   M pilot samples at α = ½ give α only, then N fresh samples at α.
//! - `alpha_samples` (integer, default 0 = N/2 integrated, 4096 preprocessed): M.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): the interval α is chosen in.
//! - `variance` (choice, default "mixture"): "mixture" or "stratified", the variance V̂ that is
//!   multiplied by the cost (see `exact_alpha`).
//! - `cost_ratio` (float, default 0, in [0, 1000]): c_B / c_L for every light; 0 measures the
//!   costs of each light on the scene.
//! - `statistics` (choice, default "pilot"): where V̂ comes from: "pilot" — the M samples at
//!   α = ½ per `mode`; "passes" — the render's earlier passes (a render in passes,
//!   docs/integrators.md, "Learned α"): each camera sample adds its V̂ at 17 α, unclamped, to
//!   its pixel's sums, and α of pass k minimises the mean V̂ of passes < k times the cost
//!   (`mode` and `alpha_samples` unused; α = ½ in the first pass).
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".

use crate::allocation::Weighted;
use crate::alpha_family::{
    ALPHA_SAMPLES_SPEC, AlphaRule, CLAMP_SPEC, MODE_SPEC, PilotAlpha, STATISTICS_SPEC, TwoPhases,
    VARIANCE_SPEC, read_clamp, read_learns, read_mode, read_stratified,
};
use crate::learned::{LearnedAlpha, Pooled};
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::moments::{Objective, PilotSamples};
use crate::pilot::{COST_BATCH, COST_GRID, SampleCosts, measure_costs};
use crate::weighting::{Balance, PerSample};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;

/// The plugin's name in scene files.
pub const NAME: &str = "cost_alpha";
/// Parameter: c_B / c_L, or 0 to measure the costs.
pub const COST_RATIO: &str = "cost_ratio";

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    MODE_SPEC,
    ALPHA_SAMPLES_SPEC,
    CLAMP_SPEC,
    VARIANCE_SPEC,
    ParamSpec {
        name: COST_RATIO,
        kind: ParamKind::Float {
            default: Some(0.0),
            min: 0.0,
            max: 1000.0,
        },
        unit: "",
        description: "cost of a BSDF sample over that of a light sample, for every light; 0: measured per light on the scene",
    },
    STATISTICS_SPEC,
    AOVS_SPEC,
];

/// Minimises V̂(α) · (α c_B + (1 − α) c_L) with each light's costs.
pub struct CostAware {
    pub stratified: bool,
    /// c_B / c_L given for every light, or None to measure.
    pub ratio: Option<f64>,
    /// Per light (`scene.emitters` order), once measured or given.
    pub costs: Vec<Option<SampleCosts>>,
}

impl AlphaRule for CostAware {
    fn alpha(&self, pilot: &PilotSamples, light: usize, clamp: [f64; 2]) -> Option<f64> {
        let costs = SampleCosts::of_light(self.ratio, &self.costs, light);
        let objective = Objective::Cost {
            stratified: self.stratified,
            bsdf: costs.bsdf,
            light: costs.light,
        };
        pilot.minimise(objective, clamp)
    }

    fn preprocess(&mut self, scene: &Scene) {
        if self.ratio.is_none() {
            self.costs = measure_costs(scene, COST_GRID, COST_BATCH);
        }
    }
}

/// The allocation of the parameters above but `samples` and `aovs`, for N = `samples` (also
/// `path`'s at its first vertex).
pub fn read_allocation(
    params: &mut Params,
    samples: u32,
) -> Result<PilotAlpha<CostAware>, PluginError> {
    let phases = TwoPhases {
        samples,
        mode: read_mode(params, samples)?,
    };
    let clamp = read_clamp(params)?;
    let stratified = read_stratified(params)?;
    let ratio = params.float(COST_RATIO)? as f64;
    let rule = CostAware {
        stratified,
        ratio: (ratio > 0.0).then_some(ratio),
        costs: Vec::new(),
    };
    Ok(PilotAlpha {
        phases,
        clamp,
        rule,
    })
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    if read_learns(params)? {
        let clamp = read_clamp(params)?;
        let stratified = read_stratified(params)?;
        let ratio = params.float(COST_RATIO)? as f64;
        let allocation = LearnedAlpha::new(samples, Pooled::Cost { stratified }, clamp, 0)
            .with_cost_ratio((ratio > 0.0).then_some(ratio));
        return MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)));
    }
    let allocation = read_allocation(params, samples)?;
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the α that minimises the pilot's variance times the measured cost of the samples",
        params: PARAMS,
        create,
    }
}

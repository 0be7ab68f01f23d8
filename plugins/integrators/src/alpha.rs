//! `alpha`: direct lighting with the second-order adaptive α of Lu, Pacanowski and Granier
//! (Pacific Graphics 2013): per shading point and light, the fraction α of the N samples drawn
//! from the BSDF (the rest from the light) minimises a second-order Taylor approximation of the
//! variance of the mixture estimator, estimated from samples taken at α = ½:
//! α̂ = clamp(½ + ¼ · Î₁/Î₂), Î₁ = mean of f²Δp/p̄³, Î₂ = mean of f²Δp²/p̄⁴, with p̄ = (p_B + p_L)/2
//! and Δp = (p_B − p_L)/2 (α̂ = ½ when Î₂ is zero or not finite). Delta lights take one light
//! sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "integrated"): "integrated" — M samples at α = ½ give L̂₁ and α̂,
//!   the other N − M at α̂ give L̂₂, and the estimate is (M·L̂₁ + (N − M)·L̂₂)/N (paper, Table 2);
//!   "preprocessed" — M pilot samples at α = ½ give α̂ only, then N fresh samples at α̂ (paper,
//!   Table 1); "fixed" — α = `fixed` everywhere (½ reproduces `balance` bit for bit).
//! - `alpha_samples` (integer, default 0 = N/2 integrated, 4096 preprocessed): M.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): bounds of α̂.
//! - `fixed` (float, default 0.5, in [0, 1]): α in "fixed" mode.
//! - `statistics` (choice, default "pilot"): where α̂'s sums come from: "pilot" — the samples
//!   at α = ½ of `mode`; "passes" — the pixel's earlier passes of a render in passes
//!   (docs/integrators.md, "Learned α"): Î₁, Î₂ summed over every earlier sample, each term
//!   reweighted from the split it was drawn at to α = ½; every sample of a pass at the α̂ its
//!   pixel and light learned before it; the first pass (and a one-pass render) at α = ½. `mode`,
//!   `alpha_samples` and `fixed` do not apply.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! Counts: n_B = ⌊α·n + ½⌋ (at least one sample per technique when 0 < α < 1), n_L = n − n_B; the
//! balance weights use these realised counts, so each phase is unbiased for any α̂ chosen from
//! samples it does not reuse.
//!
//! The sums Î₁, Î₂ are `second_order.rs`'s; the two modes' phases, shared with `exact_alpha`
//! and `cost_alpha`, are `alpha_family.rs`'s.

use crate::allocation::{Allocation, Weighted};
use crate::alpha_family::{
    self, ALPHA_SAMPLES_SPEC, CLAMP_SPEC, STATISTICS_SPEC, TwoPhases, mode_named, read_clamp,
    read_learns,
};
use crate::fixed_alpha::FixedAlpha;
use crate::learned::{LearnedAlpha, Pooled};
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::phase::LightEstimate;
use crate::sampling::LightSampling;
use crate::second_order::SecondOrderMoments;
use crate::weighting::{Balance, PerSample, Weighting};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "alpha";
/// Parameter: how α is obtained, one of [`INTEGRATED`], [`PREPROCESSED`], [`FIXED`].
pub const MODE: &str = alpha_family::MODE;
pub const INTEGRATED: &str = alpha_family::INTEGRATED;
pub const PREPROCESSED: &str = alpha_family::PREPROCESSED;
pub const FIXED: &str = "fixed";
/// Parameter: M, the samples at α = ½ that estimate α̂.
pub const ALPHA_SAMPLES: &str = alpha_family::ALPHA_SAMPLES;
/// Parameter: the interval α̂ is clamped to.
pub const CLAMP: &str = alpha_family::CLAMP;
/// Parameter: α in [`FIXED`] mode (its name is the mode's).
pub const FIXED_ALPHA: &str = FIXED;

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: MODE,
        kind: ParamKind::Choice {
            options: &[INTEGRATED, PREPROCESSED, FIXED],
            default: INTEGRATED,
        },
        unit: "",
        description: "how α is obtained: integrated (paper Table 2), preprocessed (Table 1) or fixed",
    },
    ALPHA_SAMPLES_SPEC,
    CLAMP_SPEC,
    ParamSpec {
        name: FIXED_ALPHA,
        kind: ParamKind::Float {
            default: Some(0.5),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "α in fixed mode",
    },
    STATISTICS_SPEC,
    AOVS_SPEC,
];

/// The paper's allocation: α̂ from the sums of a phase at α = ½.
pub struct SecondOrderAlpha {
    pub phases: TwoPhases,
    pub clamp: [f64; 2],
}

impl Allocation for SecondOrderAlpha {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let mut moments = SecondOrderMoments::default();
        self.phases
            .estimate(sampling, weighting, &mut moments, |_, moments| {
                moments.alpha(self.clamp)
            })
    }

    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        self.phases.estimate_together(
            samplings,
            weighting,
            |_, moments: &SecondOrderMoments| moments.alpha(self.clamp),
            estimates,
        );
    }
}

/// The allocation of mode `mode` ([`INTEGRATED`] or [`PREPROCESSED`]) for N = `samples`, with
/// its `alpha_samples` and `clamp`.
fn second_order(
    params: &mut Params,
    mode: &str,
    samples: u32,
) -> Result<SecondOrderAlpha, PluginError> {
    let phases = TwoPhases {
        samples,
        mode: mode_named(params, mode, samples)?,
    };
    let clamp = read_clamp(params)?;
    Ok(SecondOrderAlpha { phases, clamp })
}

/// The allocation of a plugin that declares `mode` as [`MODE_SPEC`] (integrated or
/// preprocessed), `alpha_samples` and `clamp`, for N = `samples`: how `path` takes the paper's
/// α at its first vertex.
///
/// [`MODE_SPEC`]: alpha_family::MODE_SPEC
pub fn read_allocation(params: &mut Params, samples: u32) -> Result<SecondOrderAlpha, PluginError> {
    let mode = params.choice(MODE)?;
    second_order(params, mode, samples)
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let balance = PerSample(Balance);
    if read_learns(params)? {
        let clamp = read_clamp(params)?;
        let allocation = LearnedAlpha::new(samples, Pooled::SecondOrder, clamp, 0);
        return MisIntegrator::boxed(params, Weighted(allocation, balance));
    }
    let mode = params.choice(MODE)?;
    if mode == FIXED {
        let alpha = params.float(FIXED_ALPHA)? as f64;
        let allocation = FixedAlpha { alpha, samples };
        return MisIntegrator::boxed(params, Weighted(allocation, balance));
    }
    let allocation = second_order(params, mode, samples)?;
    MisIntegrator::boxed(params, Weighted(allocation, balance))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the second-order adaptive α between BSDF and light sampling (Lu et al. 2013)",
        params: PARAMS,
        create,
    }
}

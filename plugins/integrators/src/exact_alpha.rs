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
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! α is ½ (clamped) when the pilot says nothing about it: no sample saw the light, or p_B = p_L
//! wherever one did. Unbiased in both modes: α depends only on samples the estimate at α does
//! not reuse.

use crate::allocation::{Allocation, LightEstimate, LightSampling};
use crate::alpha::Mode;
use crate::balance::Balance;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC};
use crate::moments::{Objective, PilotSamples};
use crate::weighting::{PerSample, Weighting};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;

/// The plugin's name in scene files.
pub const NAME: &str = "exact_alpha";
/// Parameter: how the pilot is used, [`INTEGRATED`] or [`PREPROCESSED`].
pub const MODE: &str = crate::alpha::MODE;
pub const INTEGRATED: &str = crate::alpha::INTEGRATED;
pub const PREPROCESSED: &str = crate::alpha::PREPROCESSED;
/// Parameter: M, the pilot samples at α = ½.
pub const ALPHA_SAMPLES: &str = crate::alpha::ALPHA_SAMPLES;
/// Parameter: the interval α is chosen in.
pub const CLAMP: &str = crate::alpha::CLAMP;
/// Parameter: which variance is minimised, [`MIXTURE`] or [`STRATIFIED`].
pub const VARIANCE: &str = "variance";
pub const MIXTURE: &str = "mixture";
pub const STRATIFIED: &str = "stratified";

/// `mode`, shared with `cost_alpha`.
pub const MODE_SPEC: ParamSpec = ParamSpec {
    name: MODE,
    kind: ParamKind::Choice {
        options: &[INTEGRATED, PREPROCESSED],
        default: INTEGRATED,
    },
    unit: "",
    description: "integrated: the pilot's samples are part of the estimate (paper Table 2); preprocessed: a separate pilot (Table 1)",
};

/// `alpha_samples`, shared with `cost_alpha`.
pub const ALPHA_SAMPLES_SPEC: ParamSpec = ParamSpec {
    name: ALPHA_SAMPLES,
    kind: ParamKind::Int {
        default: Some(0),
        min: 0,
        max: 1 << 20,
    },
    unit: "",
    description: "M, pilot samples at α = ½ (0: N/2 integrated, 4096 preprocessed)",
};

/// `clamp`, shared with `cost_alpha`.
pub const CLAMP_SPEC: ParamSpec = ParamSpec {
    name: CLAMP,
    kind: ParamKind::Interval {
        default: [0.025, 0.975],
        min: 0.0,
        max: 1.0,
    },
    unit: "",
    description: "interval α is chosen in",
};

/// `variance`, shared with `cost_alpha`.
pub const VARIANCE_SPEC: ParamSpec = ParamSpec {
    name: VARIANCE,
    kind: ParamKind::Choice {
        options: &[MIXTURE, STRATIFIED],
        default: MIXTURE,
    },
    unit: "",
    description: "variance minimised: of the mixture estimator (as the paper) or of the stratified estimator the integrators use",
};

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    MODE_SPEC,
    ALPHA_SAMPLES_SPEC,
    CLAMP_SPEC,
    VARIANCE_SPEC,
    AOVS_SPEC,
];

/// How α is chosen from a pilot's records (drawn at α = ½).
pub trait AlphaRule: Send + Sync {
    /// α in `clamp` for light `light`, or `None` if the pilot says nothing about it.
    fn alpha(&self, pilot: &PilotSamples, light: usize, clamp: [f64; 2]) -> Option<f64>;

    /// Work once per scene before rendering (e.g. measuring the costs of the techniques).
    fn preprocess(&mut self, _scene: &Scene) {}
}

/// Minimises a fixed objective of the pilot exactly ([`PilotSamples::minimise`]).
pub struct Minimise(pub Objective);

impl AlphaRule for Minimise {
    fn alpha(&self, pilot: &PilotSamples, _light: usize, clamp: [f64; 2]) -> Option<f64> {
        pilot.minimise(self.0, clamp)
    }
}

/// The paper's two uses of a pilot at α = ½ (integrated and preprocessed, see [`Mode`]), with
/// α chosen from the pilot's records by `rule`.
pub struct PilotAlpha<R> {
    pub mode: Mode,
    pub clamp: [f64; 2],
    pub rule: R,
}

impl<R: AlphaRule> PilotAlpha<R> {
    /// α from the last phase `sampling` drew (the pilot), ½ clamped if it says nothing.
    fn alpha_of_last_phase(&self, sampling: &LightSampling) -> f64 {
        let light = sampling.light();
        sampling
            .last_phase()
            .and_then(|(phase, _)| {
                self.rule
                    .alpha(&PilotSamples::new(&phase), light, self.clamp)
            })
            .unwrap_or(0.5)
            .clamp(self.clamp[0], self.clamp[1])
    }
}

impl<R: AlphaRule> Allocation for PilotAlpha<R> {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        self.mode
            .estimate(sampling, weighting, &mut (), |sampling, _| {
                self.alpha_of_last_phase(sampling)
            })
    }

    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        self.mode.estimate_together(
            samplings,
            weighting,
            |sampling, _: &()| self.alpha_of_last_phase(sampling),
            estimates,
        );
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.rule.preprocess(scene);
    }
}

/// Reads `mode` and `alpha_samples` (0: N/2 integrated, 4096 preprocessed; M ≤ N integrated).
pub fn read_mode(params: &mut Params) -> Result<Mode, PluginError> {
    let n = params.int(SAMPLES_SPEC.name)? as u32;
    let given = params.int(ALPHA_SAMPLES)? as u32;
    match params.choice(MODE)? {
        INTEGRATED => {
            let alpha_samples = if given == 0 { n / 2 } else { given };
            if alpha_samples > n {
                return Err(PluginError::Invalid(format!(
                    "{}: `{ALPHA_SAMPLES}` ({alpha_samples}) cannot exceed `{}` ({n}) in integrated mode",
                    params.plugin(),
                    SAMPLES_SPEC.name
                )));
            }
            Ok(Mode::Integrated { alpha_samples })
        }
        _ => Ok(Mode::Preprocessed {
            alpha_samples: if given == 0 { 4096 } else { given },
        }),
    }
}

/// Reads `clamp`.
pub fn read_clamp(params: &mut Params) -> Result<[f64; 2], PluginError> {
    let [lo, hi] = params.interval(CLAMP)?;
    Ok([lo as f64, hi as f64])
}

/// Reads `variance`: whether the stratified estimator's variance is minimised.
pub fn read_stratified(params: &mut Params) -> Result<bool, PluginError> {
    Ok(params.choice(VARIANCE)? == STRATIFIED)
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let mode = read_mode(params)?;
    let clamp = read_clamp(params)?;
    let objective = if read_stratified(params)? {
        Objective::Stratified
    } else {
        Objective::Mixture
    };
    let allocation = PilotAlpha {
        mode,
        clamp,
        rule: Minimise(objective),
    };
    MisIntegrator::boxed(params, allocation, PerSample(Balance))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the α that exactly minimises the pilot's estimate of the variance (mixture or stratified)",
        params: PARAMS,
        create,
    }
}

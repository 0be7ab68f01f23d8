//! `lit_fraction`: direct lighting with the fraction α of BSDF samples chosen, per shading
//! point and light, from which technique's samples reached the light in a first phase: M
//! samples at α = ½ give L̂₁ and the counts of lit BSDF and light samples, l_B and l_L; the
//! other N − M samples, at α = (l_B + 1)/(l_B + l_L + 2) clamped to [0.1, 0.9], give L̂₂; the
//! estimate is (M·L̂₁ + (N − M)·L̂₂)/N. Unbiased: α depends only on the first phase, and each
//! phase is unbiased for its counts. Balance weights. An example of an allocation written
//! outside lumis (docs/writing-a-plugin.md); delta lights take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `alpha_samples` (integer, default 0 = N/4, in [0, 1048576]): M, at most N.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".

use lumis_core::integrator::Integrator;
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_integrators::allocation::{Allocation, Weighted};
use lumis_integrators::alpha_family::{ALPHA_SAMPLES, at_most_samples};
use lumis_integrators::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use lumis_integrators::phase::{LightEstimate, Observer, Phase, PhaseRole, SampleSplit};
use lumis_integrators::sampling::LightSampling;
use lumis_integrators::weighting::{Balance, PerSample, Weighting};

/// The plugin's name in scene files.
pub const NAME: &str = "lit_fraction";
/// The interval α is clamped to: both techniques keep a tenth of the samples.
const CLAMP: [f64; 2] = [0.1, 0.9];

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: ALPHA_SAMPLES,
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description: "M, the first phase's samples, at α = ½ (0: N/4)",
    },
    AOVS_SPEC,
];

/// The lit samples of each technique in the phases it is shown: an observer.
#[derive(Clone, Copy, Debug, Default)]
pub struct LitCounts {
    pub bsdf: u32,
    pub light: u32,
}

impl Observer for LitCounts {
    fn observe(&mut self, phase: &Phase, _contributions: &[Rgb]) {
        let lit = |records: &[lumis_integrators::estimator::SampleRecord]| {
            records.iter().filter(|r| !r.is_black()).count() as u32
        };
        self.bsdf += lit(phase.bsdf_records());
        self.light += lit(phase.light_records());
    }
}

impl LitCounts {
    /// α = (l_B + 1)/(l_B + l_L + 2) in [`CLAMP`]: ½ when nothing was lit.
    pub fn alpha(&self) -> f64 {
        let (b, l) = (self.bsdf as f64, self.light as f64);
        ((b + 1.0) / (b + l + 2.0)).clamp(CLAMP[0], CLAMP[1])
    }
}

/// M samples at α = ½, then N − M at the α their lit counts give.
pub struct LitFraction {
    /// N, samples per light per camera sample.
    pub samples: u32,
    /// M ≤ N.
    pub first: u32,
}

impl Allocation for LitFraction {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let (n, m) = (self.samples, self.first);
        let rest = n - m;
        // Both phases are part of the estimate; V[L₁] is measured on the second unless it has
        // fewer than two samples.
        let first_role = PhaseRole {
            counted: true,
            measured: rest < 2,
        };
        let mut lit = LitCounts::default();
        let first = sampling.phase(SampleSplit::new(0.5, m), first_role, weighting, &mut lit);
        let alpha = lit.alpha();
        if rest == 0 {
            return LightEstimate {
                value: first,
                alpha,
            };
        }
        let second_role = PhaseRole {
            counted: true,
            measured: rest >= 2,
        };
        let split = SampleSplit::new(alpha, rest);
        let second = sampling.phase(split, second_role, weighting, &mut ());
        LightEstimate {
            value: (first * m as f32 + second * rest as f32) / n as f32,
            alpha,
        }
    }
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let given = params.int(ALPHA_SAMPLES)? as u32;
    let first = if given == 0 { samples / 4 } else { given };
    let first = at_most_samples(params, ALPHA_SAMPLES, first, samples, "")?;
    let allocation = LitFraction { samples, first };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with α from which technique's first samples reached the light",
        params: PARAMS,
        create,
    }
}

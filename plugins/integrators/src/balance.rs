//! `balance`: direct lighting with the balance heuristic: per camera sample and per light, N/2
//! samples from each technique (n_B = ⌊N/2 + ½⌋), weighted w_i = n_i p_i / Σ_k n_k p_k, which
//! is the mixture (defensive) estimator with α = ½. Delta lights (point, directional) take one
//! light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (see
//!   docs/integrators.md).

use crate::allocation::Weighted;
use crate::fixed_alpha::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::weighting::{Balance, PerSample};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "balance";

static PARAMS: &[ParamSpec] = &[SAMPLES_SPEC, AOVS_SPEC];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let allocation = FixedAlpha {
        alpha: 0.5,
        samples,
    };
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
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
    use super::*;
    use crate::estimator::SampleRecord;
    use crate::phase::{Phase, SampleSplit};
    use crate::weighting::{
        Weighting, assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };
    use lumis_core::math::Rgb;
    use lumis_core::sampler::Sampler;

    #[test]
    fn weights_are_a_partition_of_unity() {
        assert_partition_of_unity(&Balance);
    }

    #[test]
    fn small_phases_weigh_as_the_lanes_do() {
        assert_small_phases_weigh_as_the_lanes_do(&Balance);
    }

    /// Random records of both techniques, some black, one Dirac (a BSDF sample).
    fn records(split: SampleSplit) -> Vec<SampleRecord> {
        let mut s = Sampler::new(3, 4, 5);
        let mut v: Vec<SampleRecord> = (0..split.total())
            .map(|i| SampleRecord {
                f: if i % 5 == 0 {
                    Rgb::ZERO
                } else {
                    Rgb::new(s.next_1d(), s.next_1d(), s.next_1d())
                },
                p_bsdf: 0.1 + 3.0 * s.next_1d(),
                // Some BSDF samples in directions the light cannot produce.
                p_light: if i < split.n_bsdf && i % 7 == 0 {
                    0.0
                } else {
                    0.1 + 3.0 * s.next_1d()
                },
                delta: false,
            })
            .collect();
        v[1].delta = true;
        v[1].p_light = 0.0;
        v
    }

    /// The balance heuristic is the mixture (defensive) estimator Σ f / (n_B p_B + n_L p_L)
    /// over all samples (a Dirac sample contributing f / n_B), computed here independently.
    #[test]
    fn balance_is_the_mixture_estimator() {
        for split in [
            SampleSplit::new(0.5, 16),
            SampleSplit::new(0.2, 11),
            SampleSplit::new(0.9, 13),
        ] {
            let records = records(split);
            let phase = Phase::of(split, &records);
            let mut contributions = vec![Rgb::ZERO; records.len()];
            let value = PerSample(Balance).weigh(&phase, &mut contributions);
            let (n_b, n_l) = (split.n_bsdf as f64, split.n_light as f64);
            let mut expected = glam::DVec3::ZERO;
            for r in &records {
                if r.delta {
                    expected += r.f.as_dvec3() / n_b;
                } else if !r.is_black() {
                    let mix = n_b * r.p_bsdf as f64 + n_l * r.p_light as f64;
                    expected += r.f.as_dvec3() / mix;
                }
            }
            let sum: Rgb = contributions.iter().copied().sum();
            assert!(
                (value.as_dvec3() - expected).abs().max_element() < 1e-5 * expected.max_element(),
                "{split:?}: {value} vs {expected}"
            );
            assert_eq!(sum, value, "contributions add up to the estimate");
        }
    }
}

//! [`FixedAlpha`]: the one-phase allocation of `bsdf` (α = 1), `light` (α = 0), the heuristics
//! (α = ½), `alpha` in fixed mode and `optimal_mis` in direct mode.

use crate::allocation::{Allocation, estimate_each};
use crate::phase::{EstimatesOnly, LightEstimate, PhaseRole, SampleSplit};
use crate::sampling::LightSampling;
use crate::weighting::Weighting;
use lumis_core::geometry::PACKET_SIZE;
use lumis_core::integrator::WAVE_SIZE;
use lumis_core::math::Rgb;
use lumis_core::math::lanes::widest_width;

/// A fixed fraction α of each light's N samples from the BSDF, in one phase. Light sampling
/// can never reach a Dirac lobe, so α = 0 gives a purely specular BSDF BSDF samples instead.
pub struct FixedAlpha {
    pub alpha: f64,
    /// N, samples per light per camera sample.
    pub samples: u32,
}

impl FixedAlpha {
    /// The split of the N samples at `sampling`'s point: α of them from the BSDF, or all of
    /// them where the BSDF is a Dirac lobe and α = 0 (light sampling cannot reach it).
    fn split(&self, sampling: &LightSampling) -> SampleSplit {
        let alpha = if self.alpha == 0.0 && sampling.shading_point().is_pure_delta() {
            1.0
        } else {
            self.alpha
        };
        SampleSplit::new(alpha, self.samples)
    }

    fn estimate_of(split: SampleSplit, value: Rgb) -> LightEstimate {
        LightEstimate {
            value,
            alpha: split.alpha(),
        }
    }
}

impl Allocation for FixedAlpha {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let split = self.split(sampling);
        let value = sampling.phase(split, PhaseRole::ESTIMATE, weighting, &mut ());
        Self::estimate_of(split, value)
    }

    /// One phase each, a packet's worth at a time (a wave's for more than a packet of
    /// samplings: `path`'s waves), drawn together where they are small, as
    /// [`LightSampling::phases`] decides; written out here so that each split is computed once
    /// (it asks the BSDF whether it is a Dirac lobe) for both uses. (Through `phases`, the race
    /// configuration took 0.3–0.8 % more instructions.)
    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        // Arrays of a packet's size for a packet: lists of a wave's capacity, filled by pushes,
        // cost the race scenes 0.6–0.8 % more instructions.
        if samplings.len() <= PACKET_SIZE {
            self.estimate_in_chunks::<PACKET_SIZE, W>(samplings, weighting, estimates);
        } else {
            self.estimate_in_chunks::<WAVE_SIZE, W>(samplings, weighting, estimates);
        }
    }
}

impl FixedAlpha {
    /// [`Allocation::estimate_together`] `CHUNK` samplings at a time.
    fn estimate_in_chunks<const CHUNK: usize, W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        let lanes = widest_width() as u32;
        let chunks = samplings.chunks_mut(CHUNK).zip(estimates.chunks_mut(CHUNK));
        for (samplings, estimates) in chunks {
            let mut splits = [SampleSplit::new(0.0, 0); CHUNK];
            let mut fills_lanes = false;
            for (split, sampling) in splits.iter_mut().zip(samplings.iter()) {
                if let Some(sampling) = sampling {
                    *split = self.split(sampling);
                    fills_lanes |= split.fills(lanes);
                }
            }
            if fills_lanes {
                estimate_each(samplings, estimates, |sampling| {
                    self.estimate(sampling, weighting)
                });
                continue;
            }
            let splits = &splits[..samplings.len()];
            let mut values = [Rgb::ZERO; CHUNK];
            let values = &mut values[..samplings.len()];
            LightSampling::phases_together(
                samplings,
                splits,
                PhaseRole::ESTIMATE,
                weighting,
                &mut [EstimatesOnly; CHUNK],
                values,
            );
            let results = samplings.iter().zip(splits).zip(values.iter());
            for (((sampling, &split), &value), estimate) in results.zip(estimates) {
                if sampling.is_some() {
                    *estimate = Self::estimate_of(split, value);
                }
            }
        }
    }
}

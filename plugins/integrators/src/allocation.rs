//! Sample allocation: how many of a light's N samples at a shading point each technique gets,
//! possibly in phases (a pilot, then the rest), and how the phases combine into one unbiased
//! estimate. An [`Allocation`] draws its phases through a [`LightSampling`], which runs the
//! shared estimator, the weighting and the observers for each.

use crate::aovs::LightTally;
use crate::estimator::{
    BSDF_SAMPLE_NUMBERS, BatchScratch, BsdfRecords, DeferredLookups, Densities, SampleRecord,
    ShadingPoint, draw_bsdf_samples, draw_light_samples, light_record,
};
use crate::phase::{Observer, Phase, PhaseRole};
use crate::weighting::Weighting;
use glam::UVec2;
use lumis_core::emitter::ReferencePoint;
use lumis_core::geometry::PACKET_SIZE;
use lumis_core::math::Rgb;
use lumis_core::math::lanes::widest_width;
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;

/// How many samples of each technique one phase draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSplit {
    pub n_bsdf: u32,
    pub n_light: u32,
}

impl SampleSplit {
    /// `n` samples with a fraction `alpha` from the BSDF: n_B = ⌊α·n + ½⌋, n_L = n − n_B. When
    /// 0 < α < 1 and n ≥ 2 each technique keeps at least one sample, so that neither technique's
    /// support is ever dropped (a mirror needs BSDF samples, a point-like light light samples).
    /// Weights use these realised counts, so the estimate is unbiased for any α chosen
    /// independently of the samples it weighs; and the counts are deterministic (no random
    /// rounding), so images stay bit-identical across thread counts.
    pub fn new(alpha: f64, n: u32) -> Self {
        // The cast truncates: ⌊·⌋ at or above 0, and below 0 (or NaN) it gives 0, as the cast
        // of the floor would. `f64::floor` is a libm call on baseline x86-64.
        let mut n_bsdf = ((alpha * n as f64 + 0.5) as u32).min(n);
        if alpha > 0.0 && alpha < 1.0 && n >= 2 {
            n_bsdf = n_bsdf.clamp(1, n - 1);
        }
        SampleSplit {
            n_bsdf,
            n_light: n - n_bsdf,
        }
    }

    pub fn total(&self) -> u32 {
        self.n_bsdf + self.n_light
    }

    /// Whether a phase of this split fills batch kernels of `lanes` lanes by itself (as many
    /// samples of a technique), so that drawing it alone costs less than interleaving it with
    /// other points' phases. On the Veach scene with eight lanes, together ran at 0.905 [0.850,
    /// 0.964] of point by point's speed for `balance` at N = 64 and at 0.946 [0.939, 0.952] at
    /// N = 16, and 1.050 [1.044, 1.056] times as fast at N = 8 (docs/performance.md).
    pub fn fills(&self, lanes: u32) -> bool {
        self.n_bsdf >= lanes || self.n_light >= lanes
    }
}

/// One light's estimate at one shading point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightEstimate {
    /// The estimate of the radiance reflected from this light, L̂_j.
    pub value: Rgb,
    /// The fraction of samples the method meant for BSDF sampling (the `alpha` AOV).
    pub alpha: f64,
}

/// How a light's samples are allocated to the techniques, and how phases combine.
pub trait Allocation: Send + Sync {
    /// Estimates the light of `sampling` at its shading point with its N =
    /// `sampling.samples()` samples, each phase weighted by `weighting` (or by a weighting the
    /// method builds itself, e.g. from a pilot).
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate;

    /// [`estimate`](Self::estimate) for the samplings of one light at several shading points
    /// (the camera samples of a pixel): `estimates[k]` for `samplings[k]`, `None` entries
    /// skipped. The default estimates them one by one; an allocation whose phases do not depend
    /// on each other's results may draw them together ([`LightSampling::phases_together`]),
    /// giving each what `estimate` would, bit for bit.
    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        estimate_each(self, samplings, weighting, estimates);
    }

    /// Work once per scene before rendering (e.g. a pilot pass over the image whose
    /// statistics, filtered over neighbouring pixels, `estimate` then reads per pixel and light
    /// through `sampling.pixel()`).
    fn preprocess(&mut self, _scene: &Scene) {}
}

/// Buffers for one phase's records and contributions, reused by each thread: no allocation
/// per sample, and after the first phases none at all.
#[derive(Default)]
pub struct PhaseBuffers {
    records: Vec<SampleRecord>,
    contributions: Vec<Rgb>,
    deferred: DeferredLookups,
}

thread_local! {
    /// One set per camera sample of a packet; the first is also the one of single samples.
    static PHASE_BUFFERS: std::cell::RefCell<[PhaseBuffers; PACKET_SIZE]> =
        std::cell::RefCell::new(Default::default());
}

impl PhaseBuffers {
    /// Runs `f` with this thread's buffers, the ones every MIS integrator reuses for every
    /// light of every camera sample (also for pilot passes that sample lights themselves). Not
    /// re-entrant: `f` must not call it again.
    pub fn with_thread_local<R>(f: impl FnOnce(&mut PhaseBuffers) -> R) -> R {
        PHASE_BUFFERS.with_borrow_mut(|buffers| f(&mut buffers[0]))
    }

    /// Runs `f` with this thread's buffers for the camera samples of one packet, one each (for
    /// [`LightSampling::phases_together`]). Not re-entrant.
    pub fn with_thread_local_packet<R>(f: impl FnOnce(&mut [PhaseBuffers; PACKET_SIZE]) -> R) -> R {
        PHASE_BUFFERS.with_borrow_mut(f)
    }
}

/// The sampling of one non-delta light at one shading point: draws phases for an
/// [`Allocation`].
pub struct LightSampling<'a> {
    scene: &'a Scene,
    point: &'a ShadingPoint<'a>,
    light: usize,
    pixel: UVec2,
    /// Index of the camera sample among the pixel's.
    camera_sample: u32,
    samples: u32,
    sampler: &'a mut Sampler,
    buffers: &'a mut PhaseBuffers,
    /// The AOV statistics of this light, when an AOV asks for them.
    tally: Option<&'a mut LightTally>,
    /// The split of the last phase drawn, whose records are still in `buffers`.
    last_split: Option<SampleSplit>,
}

impl<'a> LightSampling<'a> {
    /// The sampling of light `light` at `point`, seen from `pixel`, with N = `samples`
    /// samples drawn from `sampler` into `buffers`.
    pub fn new(
        scene: &'a Scene,
        point: &'a ShadingPoint<'a>,
        light: usize,
        pixel: UVec2,
        samples: u32,
        sampler: &'a mut Sampler,
        buffers: &'a mut PhaseBuffers,
    ) -> Self {
        LightSampling {
            scene,
            point,
            light,
            pixel,
            camera_sample: 0,
            samples,
            sampler,
            buffers,
            tally: None,
            last_split: None,
        }
    }

    /// Also shows every phase to the AOV statistics `tally`.
    pub(crate) fn with_tally(self, tally: &'a mut LightTally) -> Self {
        LightSampling {
            tally: Some(tally),
            ..self
        }
    }

    /// For camera sample `index` of the pixel (0 unless set).
    pub fn with_camera_sample(self, index: u32) -> Self {
        LightSampling {
            camera_sample: index,
            ..self
        }
    }

    /// Index of the camera sample among the pixel's (a pilot pass in `preprocess` shades camera
    /// sample 0's point, whose estimate may reuse the pilot's samples).
    pub fn camera_sample(&self) -> u32 {
        self.camera_sample
    }

    /// N, the samples the integrator gives each light per camera sample.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    pub fn scene(&self) -> &Scene {
        self.scene
    }

    pub fn shading_point(&self) -> &ShadingPoint<'_> {
        self.point
    }

    /// Index of the light in `scene.emitters`.
    pub fn light(&self) -> usize {
        self.light
    }

    /// The pixel being rendered.
    pub fn pixel(&self) -> UVec2 {
        self.pixel
    }

    /// Draws one phase (`split.n_bsdf` BSDF samples, then `split.n_light` light samples, from
    /// the camera sample's stream), weighs it with `weighting`, shows it to `observer` and to
    /// the AOV statistics (as `role` says), and returns its estimate.
    pub fn phase<W: Weighting + ?Sized, O: Observer + ?Sized>(
        &mut self,
        split: SampleSplit,
        role: PhaseRole,
        weighting: &W,
        observer: &mut O,
    ) -> Rgb {
        let densities = densities_for(weighting);
        self.buffers.records.clear();
        self.prefetch_first_light_sample(split);
        let PhaseBuffers {
            records, deferred, ..
        } = &mut *self.buffers;
        let (scene, point, light) = (self.scene, self.point, self.light);
        let sampler = &mut *self.sampler;
        draw_bsdf_samples(
            scene,
            point,
            light,
            split.n_bsdf,
            sampler,
            records,
            densities,
            Some(deferred),
        );
        draw_light_samples(
            scene,
            point,
            light,
            split.n_light,
            sampler,
            records,
            densities,
        );
        self.finish_phase(split, role, weighting, observer)
    }

    /// [`phase`](Self::phase) for the samplings of one light at several shading points (the
    /// camera samples of a pixel), each with its observer: `splits[k]` for `samplings[k]`,
    /// seen by `observers[k]`, whose estimate goes to `values[k]` (`None` entries skipped).
    /// Drawn together ([`phases_together`](Self::phases_together)) where no phase fills the
    /// batch kernels' lanes by itself ([`SampleSplit::fills`] with [`widest_width`]), one by
    /// one otherwise; either way every sampling gets what `phase` would give it, bit for bit.
    pub fn phases<W: Weighting + ?Sized, O: Observer>(
        samplings: &mut [Option<LightSampling>],
        splits: &[SampleSplit],
        role: PhaseRole,
        weighting: &W,
        observers: &mut [O],
        values: &mut [Rgb],
    ) {
        let splits = &splits[..samplings.len()];
        let lanes = widest_width() as u32;
        let points = samplings.iter().zip(splits);
        if points
            .filter(|(s, _)| s.is_some())
            .any(|(_, split)| split.fills(lanes))
        {
            let each = samplings.iter_mut().zip(splits).zip(observers).zip(values);
            for (((sampling, &split), observer), value) in each {
                if let Some(sampling) = sampling {
                    *value = sampling.phase(split, role, weighting, observer);
                }
            }
        } else {
            Self::phases_together(samplings, splits, role, weighting, observers, values);
        }
    }

    /// [`phase`](Self::phase) for the samplings of one light at several shading points (the
    /// camera samples of a pixel): `splits[k]` for `samplings[k]`, seen by `observers[k]`,
    /// whose estimate goes to `values[k]` (`None` entries skipped). The samples are drawn with
    /// one batch call per technique for all the points (for the BSDF, one per run of points
    /// that share a BSDF), each from its own stream in the order `phase` draws it, so that
    /// every sampling gets what `phase` would give it, bit for bit.
    pub fn phases_together<W: Weighting + ?Sized, O: Observer>(
        samplings: &mut [Option<LightSampling>],
        splits: &[SampleSplit],
        role: PhaseRole,
        weighting: &W,
        observers: &mut [O],
        values: &mut [Rgb],
    ) {
        let densities = densities_for(weighting);
        let Some((scene, light)) = samplings
            .iter()
            .flatten()
            .next()
            .map(|s| (s.scene, s.light))
        else {
            return;
        };
        BatchScratch::with_thread_local(|scratch| {
            scratch.clear();
            for (k, sampling) in samplings.iter_mut().enumerate() {
                let Some(sampling) = sampling else { continue };
                let split = splits[k];
                sampling.buffers.records.clear();
                sampling.prefetch_first_light_sample(split);
                for _ in 0..split.n_bsdf {
                    let numbers = (sampling.sampler.next_1d(), sampling.sampler.next_2d());
                    scratch.owners.push(k);
                    scratch.wo.push(sampling.point.wo);
                    scratch.bsdf_numbers.push(numbers);
                }
            }
            let point_of = |k: usize| samplings[k].as_ref().map(|s| s.point);
            scratch.sample_bsdfs(|k| point_of(k).expect("an owner has a sampling").bsdf);
            for (&owner, &s) in scratch.owners.iter().zip(&scratch.bsdf_samples) {
                let sampling = samplings[owner].as_mut().expect("an owner has a sampling");
                let PhaseBuffers {
                    records, deferred, ..
                } = &mut *sampling.buffers;
                BsdfRecords::new(scene, sampling.point, light, densities).push(
                    s,
                    records,
                    Some(deferred),
                );
            }
            scratch.owners.clear();
            scratch.wo.clear();
            for (k, sampling) in samplings.iter_mut().enumerate() {
                let Some(sampling) = sampling else { continue };
                for _ in 0..splits[k].n_light {
                    scratch.owners.push(k);
                    scratch.wo.push(sampling.point.wo);
                    scratch.references.push(ReferencePoint {
                        position: sampling.point.hit.position,
                    });
                    scratch.light_numbers.push(sampling.sampler.next_2d());
                }
            }
            let point_of = |k: usize| samplings[k].as_ref().map(|s| s.point);
            scratch.sample_light(scene.emitters[light].as_ref(), |k| {
                point_of(k).expect("an owner has a sampling")
            });
            for ((&owner, ls), &value) in scratch
                .owners
                .iter()
                .zip(&scratch.light_samples)
                .zip(&scratch.values)
            {
                let sampling = samplings[owner].as_mut().expect("an owner has a sampling");
                sampling.buffers.records.push(match ls {
                    Some(ls) => light_record(scene, sampling.point, light, ls, densities, || value),
                    None => SampleRecord::default(),
                });
            }
            Self::look_up_together(scene, light, samplings, scratch);
        });
        let finished = samplings.iter_mut().zip(splits).zip(observers).zip(values);
        for (((sampling, &split), observer), value) in finished {
            if let Some(sampling) = sampling {
                *value = sampling.finish_phase(split, role, weighting, observer);
            }
        }
    }

    /// The lookups that the BSDF samples of `samplings` (of light `light`) left to the end of
    /// their phases ([`DeferredLookups`]), in one batch call for all the points: an
    /// environment's conversions of directions to map coordinates run in lanes, where one
    /// phase of the race scenes has one such sample or none.
    fn look_up_together(
        scene: &Scene,
        light: usize,
        samplings: &mut [Option<LightSampling>],
        scratch: &mut BatchScratch,
    ) {
        if scene.environment != Some(light) {
            return;
        }
        scratch.clear_lookups();
        for sampling in samplings.iter().flatten() {
            scratch.add_lookups(sampling.point, &sampling.buffers.deferred);
        }
        if scratch.directions.is_empty() {
            return;
        }
        let mut values = scratch.look_up(scene.emitters[light].as_ref()).copied();
        for sampling in samplings.iter_mut().flatten() {
            let PhaseBuffers {
                records, deferred, ..
            } = &mut *sampling.buffers;
            // Most points of a packet have none.
            if !deferred.is_empty() {
                deferred.fill(records, values.by_ref());
            }
        }
    }

    /// Before a phase of `split` is drawn: lets the light start reading what its first light
    /// sample will need (an environment map's alias slot, a cache miss) while the BSDF samples
    /// trace their rays. Its numbers are known now, after the BSDF samples' three each.
    fn prefetch_first_light_sample(&self, split: SampleSplit) {
        if split.n_light > 0 && split.n_bsdf > 0 {
            let first_light_numbers = || {
                let mut ahead = self.sampler.clone();
                ahead.skip(BSDF_SAMPLE_NUMBERS * split.n_bsdf);
                ahead.next_2d()
            };
            self.scene.emitters[self.light].prefetch_sample(&first_light_numbers);
        }
    }

    /// The rest of a phase whose records are drawn: the deferred lookups, the weights, the
    /// observer and the AOV statistics.
    #[inline(always)]
    fn finish_phase<W: Weighting + ?Sized, O: Observer + ?Sized>(
        &mut self,
        split: SampleSplit,
        role: PhaseRole,
        weighting: &W,
        observer: &mut O,
    ) -> Rgb {
        let PhaseBuffers {
            records,
            contributions,
            deferred,
        } = &mut *self.buffers;
        deferred.look_up(self.scene, self.point, self.light, records);
        contributions.clear();
        contributions.resize(records.len(), Rgb::ZERO);
        let phase = Phase {
            pixel: self.pixel,
            light: self.light,
            split,
            records,
        };
        let value = weighting.weigh(&phase, contributions);
        observer.observe(&phase, contributions);
        if let Some(tally) = self.tally.as_deref_mut() {
            tally.observe(&phase, contributions, role);
        }
        self.last_split = Some(split);
        value
    }

    /// The last phase drawn and its records' contributions, until the next phase replaces
    /// them: for an allocation that needs a pilot's samples themselves (e.g. to minimise a
    /// function of all of them), not only what an observer accumulated.
    pub fn last_phase(&self) -> Option<(Phase<'_>, &[Rgb])> {
        let split = self.last_split?;
        let phase = Phase {
            pixel: self.pixel,
            light: self.light,
            split,
            records: &self.buffers.records,
        };
        Some((phase, &self.buffers.contributions))
    }
}

/// [`Allocation::estimate_together`] one sampling at a time: its default, and an override's
/// way out.
pub fn estimate_each<A: Allocation + ?Sized, W: Weighting + ?Sized>(
    allocation: &A,
    samplings: &mut [Option<LightSampling>],
    weighting: &W,
    estimates: &mut [LightEstimate],
) {
    for (sampling, estimate) in samplings.iter_mut().zip(estimates) {
        if let Some(sampling) = sampling {
            *estimate = allocation.estimate(sampling, weighting);
        }
    }
}

/// The densities the records of a phase weighed by `weighting` need.
fn densities_for<W: Weighting + ?Sized>(weighting: &W) -> Densities {
    if weighting.needs_both_densities() {
        Densities::Both
    } else {
        Densities::Lit
    }
}

/// A fixed fraction α of each light's samples from the BSDF, in one phase: `bsdf` (α = 1),
/// `light` (α = 0), the heuristics (α = ½). Light sampling can never reach a Dirac lobe, so
/// α = 0 gives a purely specular BSDF BSDF samples instead.
pub struct FixedAlpha {
    pub alpha: f64,
}

impl FixedAlpha {
    /// The split of `sampling`'s N samples: α of them from the BSDF, or all of them where the
    /// BSDF is a Dirac lobe and α = 0 (light sampling cannot reach it).
    fn split(&self, sampling: &LightSampling) -> SampleSplit {
        let alpha = if self.alpha == 0.0 && sampling.shading_point().is_pure_delta() {
            1.0
        } else {
            self.alpha
        };
        SampleSplit::new(alpha, sampling.samples())
    }

    fn estimate_of(split: SampleSplit, value: Rgb) -> LightEstimate {
        LightEstimate {
            value,
            alpha: split.n_bsdf as f64 / split.total() as f64,
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

    /// One phase each, a packet's worth at a time, drawn together where they are small, as
    /// [`LightSampling::phases`] decides; written out here so that each split is computed once
    /// (it asks the BSDF whether it is a Dirac lobe) for both uses. (Through `phases`, the race
    /// configuration took 0.3–0.8 % more instructions.)
    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        let lanes = widest_width() as u32;
        let chunks = samplings
            .chunks_mut(PACKET_SIZE)
            .zip(estimates.chunks_mut(PACKET_SIZE));
        for (samplings, estimates) in chunks {
            let mut splits = [SampleSplit::new(0.0, 0); PACKET_SIZE];
            let mut fills_lanes = false;
            for (split, sampling) in splits.iter_mut().zip(samplings.iter()) {
                if let Some(sampling) = sampling {
                    *split = self.split(sampling);
                    fills_lanes |= split.fills(lanes);
                }
            }
            if fills_lanes {
                estimate_each(self, samplings, weighting, estimates);
                continue;
            }
            let splits = &splits[..samplings.len()];
            let mut values = [Rgb::ZERO; PACKET_SIZE];
            let values = &mut values[..samplings.len()];
            LightSampling::phases_together(
                samplings,
                splits,
                PhaseRole::ESTIMATE,
                weighting,
                &mut [(); PACKET_SIZE],
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_splits_round_and_keep_both_techniques() {
        let split = |n_bsdf, n_light| SampleSplit { n_bsdf, n_light };
        assert_eq!(SampleSplit::new(0.5, 256), split(128, 128));
        assert_eq!(SampleSplit::new(0.025, 16), split(1, 15));
        assert_eq!(SampleSplit::new(0.975, 16), split(15, 1));
        assert_eq!(SampleSplit::new(1.0, 16), split(16, 0));
        assert_eq!(SampleSplit::new(0.0, 16), split(0, 16));
        assert_eq!(SampleSplit::new(0.3, 1).total(), 1);
        assert_eq!(SampleSplit::new(0.5, 0), split(0, 0));
    }
}

//! The sampling engine: draws the phases an allocation asks for ([`LightSampling::phase`]),
//! weighs them with a [`Weighting`] and shows them to observers and to the AOV statistics, one
//! shading point at a time or, for the camera samples of a packet, with one batch call per
//! technique for all the points ([`LightSampling::phases_together`]). Its buffers are each
//! thread's own ([`PhaseBuffers`]): nothing is allocated per sample.
//!
//! Allocations ([`crate::allocation`]) draw through it and see whole phases, never records
//! being drawn (only `cost_alpha`'s timing of the techniques, in [`crate::pilot`], calls the
//! estimator's drawing functions itself).

use crate::aovs::LightTally;
use crate::batch::BatchScratch;
use crate::estimator::{
    BSDF_SAMPLE_NUMBERS, BsdfOutcome, BsdfRecords, ContinuationSlot, DeferredLookups, Densities,
    SampleRecord, draw_bsdf_samples, draw_continuing_bsdf_sample, draw_light_samples,
    light_record_any,
};
use crate::phase::{Observer, Phase, PhaseRole, SampleSplit};
use crate::shading_point::ShadingPoint;
use crate::weighting::Weighting;
use glam::UVec2;
use lumis_core::bsdf::BsdfContext;
use lumis_core::emitter::ReferencePoint;
use lumis_core::integrator::WAVE_SIZE;
use lumis_core::math::Rgb;
use lumis_core::math::lanes::widest_width;
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;
use std::iter::Copied;

/// Buffers for one phase's records and contributions, reused by each thread: no allocation
/// per sample, and after the first phases none at all.
#[derive(Default)]
pub struct PhaseBuffers {
    records: Vec<SampleRecord>,
    contributions: Vec<Rgb>,
    deferred: DeferredLookups,
}

thread_local! {
    /// One set per camera sample of a wave; the first is also the one of single samples.
    static PHASE_BUFFERS: std::cell::RefCell<[PhaseBuffers; WAVE_SIZE]> =
        std::cell::RefCell::new(std::array::from_fn(|_| PhaseBuffers::default()));
}

impl PhaseBuffers {
    /// Runs `f` with this thread's buffers, the ones every MIS integrator reuses for every
    /// light of every camera sample (also for pilot passes that sample lights themselves). Not
    /// re-entrant: `f` must not call it again.
    pub fn with_thread_local<R>(f: impl FnOnce(&mut PhaseBuffers) -> R) -> R {
        PHASE_BUFFERS.with_borrow_mut(|buffers| f(&mut buffers[0]))
    }

    /// Runs `f` with this thread's buffers for the camera samples of one wave, one each (for
    /// [`LightSampling::phases_together`]). Not re-entrant.
    pub fn with_thread_local_wave<R>(f: impl FnOnce(&mut [PhaseBuffers; WAVE_SIZE]) -> R) -> R {
        PHASE_BUFFERS.with_borrow_mut(f)
    }
}

/// The sampling of one non-delta light at one shading point: draws phases for an
/// allocation ([`crate::allocation`]).
pub struct LightSampling<'a> {
    scene: &'a Scene,
    point: &'a ShadingPoint<'a>,
    light: usize,
    pixel: UVec2,
    /// Index of the camera sample among the pixel's.
    camera_sample: u32,
    sampler: &'a mut Sampler,
    buffers: &'a mut PhaseBuffers,
    /// The AOV statistics of this light, when an AOV asks for them.
    tally: Option<&'a mut LightTally>,
    /// The split and role of the last phase drawn, whose records are still in `buffers`.
    last_phase: Option<(SampleSplit, PhaseRole)>,
    /// The vertex of the path the point is: 1 for the first surface a camera ray meets.
    depth: u32,
    /// Whether the point is the first surface the camera ray meets (what pilot passes shade).
    primary: bool,
    /// Where a path's continuation is taken from this point's BSDF samples, if it is wanted.
    continuation: Option<&'a mut ContinuationSlot>,
}

impl<'a> LightSampling<'a> {
    /// The sampling of light `light` at `point`, seen from `pixel`, its samples drawn from
    /// `sampler` into `buffers`.
    pub fn new(
        scene: &'a Scene,
        point: &'a ShadingPoint<'a>,
        light: usize,
        pixel: UVec2,
        sampler: &'a mut Sampler,
        buffers: &'a mut PhaseBuffers,
    ) -> Self {
        LightSampling {
            scene,
            point,
            light,
            pixel,
            camera_sample: 0,
            sampler,
            buffers,
            tally: None,
            last_phase: None,
            depth: 1,
            primary: true,
            continuation: None,
        }
    }

    /// At vertex `depth` of a path (1: the first surface the camera ray meets), `primary` if
    /// the point is that first surface (with hidden emitters, the first surface past them is
    /// vertex 1 but not the surface a pilot pass shaded). The default: 1, primary.
    pub fn at_vertex(self, depth: u32, primary: bool) -> Self {
        LightSampling {
            depth,
            primary,
            ..self
        }
    }

    /// Takes a path's continuation from the first BSDF sample drawn while `slot` is
    /// [`ContinuationSlot::Wanted`] ([`phase`](Self::phase), and alike
    /// [`phases_together`](Self::phases_together)): its ray is traced to the closest surface,
    /// and its record is the one it would have had.
    pub fn with_continuation(self, slot: &'a mut ContinuationSlot) -> Self {
        LightSampling {
            continuation: Some(slot),
            ..self
        }
    }

    /// The vertex of the path the point is (1: the first surface the camera ray meets): an
    /// allocation may choose differently at deeper vertices, where no per-pixel statistic
    /// describes the point.
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Whether the point is the first surface the camera ray meets, the one a pilot pass over
    /// the image shades at camera sample 0 ([`crate::pilot`]).
    pub fn is_primary(&self) -> bool {
        self.primary
    }

    /// Also shows every phase to the AOV statistics `tally` (an observer of every phase, besides
    /// the one each phase is drawn with).
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
        let mut n_bsdf = split.n_bsdf;
        if n_bsdf > 0
            && let Some(slot) = self.continuation.as_deref_mut()
            && slot.is_wanted()
        {
            *slot = ContinuationSlot::Drawn(draw_continuing_bsdf_sample(
                scene,
                point,
                light,
                sampler,
                records,
                densities,
                Some(deferred),
            ));
            n_bsdf -= 1;
        }
        draw_bsdf_samples(
            scene,
            point,
            light,
            n_bsdf,
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

    /// [`phase`](Self::phase) for the samplings of one light at several shading points (a
    /// packet of camera samples), each with its observer: `splits[k]` for `samplings[k]`,
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

    /// [`phase`](Self::phase) for the samplings of one light at several shading points (a
    /// packet of camera samples): `splits[k]` for `samplings[k]`, seen by `observers[k]`,
    /// whose estimate goes to `values[k]` (`None` entries skipped). The samples are drawn with
    /// one batch call per technique for all the points (for the BSDF, one per run of points
    /// that share a BSDF), each from its own stream in the order `phase` draws it, so that
    /// every sampling gets what `phase` would give it, bit for bit: a sampling whose
    /// continuation slot is wanted takes its first BSDF sample as the path's continuation, as
    /// `phase` does.
    ///
    /// Where neither the observers nor the caller read the records
    /// ([`Observer::reads_records`]), no AOV statistics are asked for, and the weighting weighs
    /// each record alone ([`Weighting::weighs_records_alone`]), each record is weighed and
    /// added to its estimate as it is drawn, in the order `weigh` sums them, and none is kept:
    /// [`last_phase`](Self::last_phase) is then `None`. For the environment, whose BSDF
    /// samples' lookups are batched after the light samples, only where every phase draws at
    /// most one sample per technique, whose two contributions give the same sum in either
    /// order.
    // Inlined: called for packets and for `path`'s waves, it was no longer inlined into either,
    // and the packets' instructions rose 0.3 %.
    #[inline(always)]
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
        // Summed as drawn, no records kept, where nothing reads the records but a weighting
        // that weighs each alone. An environment's BSDF samples keep their batched lookups,
        // after the light samples: their contributions are added last, which gives `weigh`'s
        // sum bit for bit where a phase has at most one record per technique (two terms
        // commute, and a sum from +0 is never -0).
        let summed_as_drawn = weighting.weighs_records_alone()
            && !observers[..samplings.len()].iter().any(O::reads_records)
            && samplings.iter().flatten().all(|s| s.tally.is_none())
            && (scene.environment != Some(light)
                || splits.iter().all(|s| s.n_bsdf <= 1 && s.n_light <= 1));
        let defer_environment = scene.environment == Some(light);
        if summed_as_drawn {
            for (sampling, value) in samplings.iter().zip(values.iter_mut()) {
                if sampling.is_some() {
                    *value = Rgb::ZERO;
                }
            }
        }
        // One context for every entry where the points share theirs (the same side, no
        // texture coordinates): the batch calls then take it once instead of one per entry.
        let shared = shared_context(samplings);
        BatchScratch::with_thread_local(|scratch| {
            scratch.clear();
            scratch.contexts.extend(shared);
            for (k, sampling) in samplings.iter_mut().enumerate() {
                let Some(sampling) = sampling else { continue };
                let split = splits[k];
                sampling.buffers.records.clear();
                sampling.prefetch_first_light_sample(split);
                for _ in 0..split.n_bsdf {
                    let numbers = (sampling.sampler.next_1d(), sampling.sampler.next_2d());
                    scratch.owners.push(k);
                    scratch.wo.push(sampling.point.wo);
                    if shared.is_none() {
                        scratch.contexts.push(sampling.point.ctx);
                    }
                    scratch.bsdf_numbers.push(numbers);
                }
            }
            let point_of = |k: usize| samplings[k].as_ref().map(|s| s.point);
            scratch.sample_bsdfs(|k| point_of(k).expect("an owner has a sampling").bsdf);
            for (&owner, s) in scratch.owners.iter().zip(&scratch.bsdf_samples) {
                let sampling = samplings[owner].as_mut().expect("an owner has a sampling");
                let bsdf_records = BsdfRecords::new(scene, sampling.point, light, densities);
                if summed_as_drawn {
                    let outcome = match sampling.continuation.as_deref_mut() {
                        Some(slot) if slot.is_wanted() => {
                            let (outcome, continuation) =
                                bsdf_records.continuing_outcome(s.as_ref());
                            *slot = ContinuationSlot::Drawn(continuation);
                            outcome
                        }
                        _ => bsdf_records.outcome_any(s.as_ref()),
                    };
                    let record = match outcome {
                        BsdfOutcome::Environment(sample, wi) if defer_environment => {
                            sampling.buffers.deferred.defer(owner, sample, wi);
                            continue;
                        }
                        outcome => bsdf_records.record_now(outcome),
                    };
                    if !record.is_black() {
                        values[owner] +=
                            weighting.record_contribution(splits[owner], true, &record);
                    }
                    continue;
                }
                let PhaseBuffers {
                    records, deferred, ..
                } = &mut *sampling.buffers;
                match sampling.continuation.as_deref_mut() {
                    // A point's first BSDF sample, the one `phase` would take (the slot is
                    // then drawn, and its later samples are not).
                    Some(slot) if slot.is_wanted() => {
                        let continuation =
                            bsdf_records.push_continuing(s.as_ref(), records, Some(deferred));
                        *slot = ContinuationSlot::Drawn(continuation);
                    }
                    _ => bsdf_records.push_any(s.as_ref(), records, Some(deferred)),
                }
            }
            scratch.owners.clear();
            scratch.wo.clear();
            scratch.contexts.clear();
            scratch.contexts.extend(shared);
            for (k, sampling) in samplings.iter_mut().enumerate() {
                let Some(sampling) = sampling else { continue };
                for _ in 0..splits[k].n_light {
                    scratch.owners.push(k);
                    scratch.wo.push(sampling.point.wo);
                    if shared.is_none() {
                        scratch.contexts.push(sampling.point.ctx);
                    }
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
            for (((&owner, ls), &bsdf_value), wi) in scratch
                .owners
                .iter()
                .zip(&scratch.light_samples)
                .zip(&scratch.values)
                .zip(&scratch.directions)
            {
                let sampling = samplings[owner].as_mut().expect("an owner has a sampling");
                let record = match ls {
                    Some(ls) => {
                        let point = sampling.point;
                        light_record_any(scene, point, light, ls, wi.z, densities, || bsdf_value)
                    }
                    None => SampleRecord::default(),
                };
                if !summed_as_drawn {
                    sampling.buffers.records.push(record);
                } else if !record.is_black() {
                    values[owner] += weighting.record_contribution(splits[owner], false, &record);
                }
            }
            if summed_as_drawn {
                Self::look_up_together(scene, light, samplings, scratch, |buffers, found| {
                    buffers.deferred.drain(found, |owner, record| {
                        if !record.is_black() {
                            values[owner] +=
                                weighting.record_contribution(splits[owner], true, &record);
                        }
                    });
                });
            } else {
                Self::look_up_together(scene, light, samplings, scratch, |buffers, found| {
                    let PhaseBuffers {
                        records, deferred, ..
                    } = buffers;
                    deferred.fill(records, found);
                });
            }
        });
        if summed_as_drawn {
            for sampling in samplings.iter_mut().flatten() {
                sampling.last_phase = None;
            }
            return;
        }
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
    /// phase of the race scenes has one such sample or none. `fill` is given the buffers of
    /// each point that has lookups, with the batch's results, to take its own in order.
    fn look_up_together(
        scene: &Scene,
        light: usize,
        samplings: &mut [Option<LightSampling>],
        scratch: &mut BatchScratch,
        mut fill: impl FnMut(&mut PhaseBuffers, &mut Copied<std::slice::Iter<'_, (Rgb, f32)>>),
    ) {
        if scene.environment != Some(light) {
            return;
        }
        scratch.clear_lookups();
        for sampling in samplings.iter().flatten() {
            sampling.buffers.deferred.add_to(scratch, sampling.point);
        }
        if scratch.directions.is_empty() {
            return;
        }
        let mut values = scratch.look_up(scene.emitters[light].as_ref()).copied();
        for sampling in samplings.iter_mut().flatten() {
            // Most points of a packet have none.
            if !sampling.buffers.deferred.is_empty() {
                fill(sampling.buffers, &mut values);
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
            role,
            records,
        };
        let value = weighting.weigh(&phase, contributions);
        observer.observe(&phase, contributions);
        if let Some(tally) = self.tally.as_deref_mut() {
            tally.observe(&phase, contributions);
        }
        self.last_phase = Some((split, role));
        value
    }

    /// The last phase drawn and its records' contributions, until the next phase replaces
    /// them: for an allocation that needs a pilot's samples themselves (e.g. to minimise a
    /// function of all of them), not only what an observer accumulated. `None` before the
    /// first phase, and after phases summed as they were drawn
    /// ([`phases_together`](Self::phases_together)).
    pub fn last_phase(&self) -> Option<(Phase<'_>, &[Rgb])> {
        let (split, role) = self.last_phase?;
        let phase = Phase {
            pixel: self.pixel,
            light: self.light,
            split,
            role,
            records: &self.buffers.records,
        };
        Some((phase, &self.buffers.contributions))
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

/// The BSDF context of every point of `samplings` if they all have the same one (the common
/// case of a packet of one surface seen from one side, untextured).
fn shared_context(samplings: &[Option<LightSampling>]) -> Option<BsdfContext> {
    let mut contexts = samplings.iter().flatten().map(|s| s.point.ctx);
    let first = contexts.next()?;
    contexts.all(|ctx| ctx == first).then_some(first)
}

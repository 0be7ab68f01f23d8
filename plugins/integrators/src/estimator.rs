//! The shared estimator: draws the samples of one light at one shading point, as batches of
//! [`SampleRecord`]s, and knows nothing of how they are weighted, split or observed.
//!
//! At a shading point x with outgoing direction ωo and one non-delta light j, the integrand is
//! f(ω) = BSDF · |cos θ| · L_e,j · V. BSDF sampling draws ω from the BSDF (density p_B); such a
//! sample counts for light j only if its ray reaches light j (a ray that leaves the scene
//! reaches the environment). Light sampling draws ω from light j (density p_L) and traces a
//! shadow ray. A delta BSDF sample (a mirror) has no density that light sampling could match.
//! Delta lights (point, directional) cannot be reached by BSDF sampling: each takes one light
//! sample, with no MIS ([`estimate_delta_light`]).
//!
//! The records of one technique are drawn together into a buffer the caller reuses (no
//! allocation per sample), so that a method weighs and observes them as plain slices.
//!
//! Why one file of over 600 lines: the estimator's scalar and lane forms of one record (light
//! sample, BSDF sample, Dirac sample) stay together because they must give the same numbers.

use crate::batch::BatchScratch;
use crate::shading_point::ShadingPoint;
use glam::Vec3;
use lumis_core::bsdf::BsdfSample;
use lumis_core::emitter::{Emitter, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::geometry::{FirstHit, Intersection, Ray};
use lumis_core::math::Rgb;
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;

/// One sample of one light at one shading point, as every MIS method sees it. Every drawn
/// sample has a record, black ones included, so that a batch of n records is exactly the n
/// samples its technique drew.
///
/// Of a black sample (f = 0) only the density of the technique that drew it is known (0 if it
/// drew no direction), and the other technique's density is 0 in the record, unless the phase
/// was drawn with [`Densities::Both`] (a weighting that asks for it, such as optimal MIS
/// weights, which sum p_i p_k / p_mix² over every sample): then the other density is computed
/// for every record that has a direction (a pdf evaluation, or, for a BSDF ray that meets
/// something else first, the light intersected on its own). A record with no direction (its
/// technique's density 0) stands for the technique's failed draws, which the light's or BSDF's
/// sampling routine returns with some probability and which no other technique produces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleRecord {
    /// The integrand f = BSDF · |cos θ| · L_e · V in the sample's direction: zero when the
    /// sample drew no direction, leaves on a side of the surface its BSDF does not scatter
    /// toward (a leak through shading normals), misses the light or is occluded. For a Dirac BSDF sample (`delta`), f divided by the Dirac density: the BSDF
    /// sample's weight times L_e.
    pub f: Rgb,
    /// Solid-angle density of BSDF sampling in the sample's direction (for `delta`, the
    /// discrete probability of the lobe).
    pub p_bsdf: f32,
    /// Solid-angle density of sampling this light in the sample's direction.
    pub p_light: f32,
    /// Drawn from a Dirac lobe of the BSDF: only BSDF sampling can produce it.
    pub delta: bool,
}

impl SampleRecord {
    /// Whether the sample contributes nothing to this light.
    #[inline]
    pub fn is_black(&self) -> bool {
        // One test instead of three: ±0 in every channel (NaN is not black).
        let bits = |v: f32| v.to_bits() << 1;
        bits(self.f.x) | bits(self.f.y) | bits(self.f.z) == 0
    }
}

/// Which densities the records of a phase hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Densities {
    /// Both densities for samples that reach the light (f ≠ 0), only the drawing technique's
    /// for black ones: all that the heuristics and the α estimators need, at no extra cost.
    Lit,
    /// Both densities for every sample that has a direction, black ones included.
    Both,
}

/// The light's surface where `ray` first meets shape `shape` (`first`), as the light's density
/// and radiance are asked for it.
fn emitter_hit(scene: &Scene, ray: &Ray, first: &FirstHit) -> EmitterHit {
    let hit = scene.geometry.surface(ray, first);
    EmitterHit {
        position: hit.position,
        normal: hit.geometric_normal,
        distance: hit.t,
    }
}

/// The density with which sampling light `light` produces the direction of `ray` (a BSDF
/// sample that did not reach the light: it met another surface first, or missed): the light is
/// intersected on its own, occluders ignored. Where the light does not emit toward the ray's
/// origin the density is 0, as light sampling discards such directions (a light of zero
/// radiance, whose estimate is 0 whatever the weights, also gets 0).
fn light_density_toward(
    scene: &Scene,
    light: usize,
    light_shape: Option<u32>,
    reference: &ReferencePoint,
    ray: &Ray,
) -> f32 {
    let emitter = scene.emitters[light].as_ref();
    if scene.environment == Some(light) {
        return emitter.pdf_direction(reference, ray.direction, None);
    }
    // Through the BVH with every other shape ignored: a mesh light's triangles one by one made
    // each blocked BSDF sample cost time in proportion to the light's size.
    let Some(first) = light_shape.and_then(|shape| scene.geometry.first_hit_on_shape(ray, shape))
    else {
        return 0.0;
    };
    let hit = emitter_hit(scene, ray, &first);
    if emitter.eval(ray.direction, Some(&hit)) == Rgb::ZERO {
        return 0.0;
    }
    emitter.pdf_direction(reference, ray.direction, Some(&hit))
}

/// The density with which sampling non-delta light `light` from `sp` draws the direction of
/// `ray`, a ray leaving `sp` drawn otherwise (occluders ignored, as [`light_density_toward`]).
pub(crate) fn light_density_of(scene: &Scene, sp: &ShadingPoint, light: usize, ray: &Ray) -> f32 {
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    light_density_toward(scene, light, scene.emitter_shape[light], &reference, ray)
}

/// What a BSDF-sampled ray finds of the light it was drawn for.
enum Reached {
    /// Nothing: it is blocked, or passes the light by.
    Nothing,
    /// The area light's surface, and the radiance arriving from it.
    Surface(EmitterHit, Rgb),
    /// The environment, unblocked; its radiance is looked up later ([`DeferredLookups`]).
    Environment,
}

/// Where a BSDF-sampled ray reaches light `light` (the area emitter of shape `light_shape`, or
/// the environment), if it does. Most BSDF rays reach no light, so the cheapest query that
/// decides is asked: for the environment, whether anything blocks the ray (any hit will do);
/// for an area light, nothing when the ray passes clear of its shape's box, and otherwise the
/// first hit, which must be on the light's shape (only then is its surface computed). The ray
/// leaves surface point `from`, whose triangle it cannot meet.
fn reaches_light(
    scene: &Scene,
    light: usize,
    light_shape: Option<u32>,
    ray: &Ray,
    from: &Intersection,
) -> Reached {
    let emitter = scene.emitters[light].as_ref();
    if scene.environment == Some(light) {
        return reaches_environment(scene, light, ray, from);
    }
    let Some(shape) = light_shape else {
        return Reached::Nothing;
    };
    if !scene.geometry.may_meet(ray, shape) {
        return Reached::Nothing;
    }
    let first = scene.geometry.first_hit_leaving(ray, from);
    let Some(first) = first.filter(|first| first.shape == shape) else {
        return Reached::Nothing;
    };
    let hit = emitter_hit(scene, ray, &first);
    Reached::Surface(hit, emitter.eval(ray.direction, Some(&hit)))
}

/// [`reaches_light`] for the environment light: whether anything blocks the ray. Kept out of
/// `reaches_light`, which every area light's sample runs through: inlined there, this any-hit
/// traversal made it six times larger with code those samples never run.
#[inline(never)]
fn reaches_environment(scene: &Scene, light: usize, ray: &Ray, from: &Intersection) -> Reached {
    if scene.geometry.occluded_by_others(ray, None, Some(from)) {
        return Reached::Nothing;
    }
    // Only for a ray that escapes: its lookup is deferred to the end of the phase, after the
    // light samples, which leaves the read time to arrive.
    scene.emitters[light].prefetch(ray.direction);
    Reached::Environment
}

/// What a BSDF-sampled ray that was traced to its closest surface, `hit` (`None`: it left the
/// scene), finds of light `light`: [`reaches_light`]'s answer from the whole trace, for the ray
/// a path goes on along.
fn reached_from(
    scene: &Scene,
    light: usize,
    light_shape: Option<u32>,
    ray: &Ray,
    hit: Option<&Intersection>,
) -> Reached {
    let emitter = scene.emitters[light].as_ref();
    if scene.environment == Some(light) {
        if hit.is_some() {
            return Reached::Nothing;
        }
        emitter.prefetch(ray.direction);
        return Reached::Environment;
    }
    match hit {
        Some(hit) if Some(hit.shape) == light_shape => {
            let on_light = EmitterHit {
                position: hit.position,
                normal: hit.geometric_normal,
                distance: hit.t,
            };
            Reached::Surface(on_light, emitter.eval(ray.direction, Some(&on_light)))
        }
        _ => Reached::Nothing,
    }
}

/// The way a path goes on from a shading point: a BSDF sample, the ray leaving the point along
/// it, and the closest surface that ray meets (`None`: it leaves the scene).
#[derive(Clone, Copy, Debug)]
pub struct Continuation {
    /// The sample: its weight (eval / pdf, with the 1/η² of a refraction) multiplies the path's
    /// throughput, its η the product a path's Russian roulette reads.
    pub sample: BsdfSample,
    pub ray: Ray,
    pub hit: Option<Intersection>,
}

/// The continuation of a path at one shading point, as the point's light estimates are drawn:
/// the first BSDF sample drawn there for any light is the one the path goes on along (it is
/// drawn from the BSDF like any other, whatever the phase and the light, so the path's next
/// vertex is distributed as BSDF sampling draws it; docs/integrators.md).
#[derive(Clone, Copy, Debug, Default)]
pub enum ContinuationSlot {
    /// The path does not go on from this point: no sample is traced further.
    #[default]
    NotWanted,
    /// The next BSDF sample drawn at the point will be the continuation.
    Wanted,
    /// Drawn: the continuation, or `None` where the sample drew no direction or leaves on a
    /// side of the surface its BSDF does not scatter toward (the path ends).
    Drawn(Option<Continuation>),
}

impl ContinuationSlot {
    /// Whether the next BSDF sample is to be the continuation.
    #[inline(always)]
    pub fn is_wanted(&self) -> bool {
        matches!(self, ContinuationSlot::Wanted)
    }
}

/// Draws a BSDF sample at `sp` ([`BSDF_SAMPLE_NUMBERS`] numbers from `sampler`) and traces it
/// to the closest surface, for no light: the continuation of a path at a point where no light
/// estimate drew a BSDF sample. `None` as [`ContinuationSlot::Drawn`] says.
pub fn draw_continuation(
    scene: &Scene,
    sp: &ShadingPoint,
    sampler: &mut Sampler,
) -> Option<Continuation> {
    let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
    let sample = sp.bsdf.sample(&sp.ctx, sp.wo, u_lobe, u)?;
    let wi = sp.frame.to_world(sample.wi);
    let leaves = if sp.flags.transmission() {
        sp.leaves_toward::<true>(wi, sample.wi)
    } else {
        sp.leaves_toward::<false>(wi, sample.wi)
    };
    if !leaves {
        return None;
    }
    let ray = sp.origin.ray(&sp.hit, wi);
    let hit = scene
        .geometry
        .first_hit_leaving(&ray, &sp.hit)
        .map(|first| scene.geometry.surface(&ray, &first));
    Some(Continuation { sample, ray, hit })
}

/// Draws the first of a phase's BSDF samples for non-delta light `light` at `sp` as
/// [`draw_bsdf_samples`] draws it (the same numbers, the same record) and returns it as the
/// path's continuation, its ray traced to the closest surface.
pub fn draw_continuing_bsdf_sample(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    sampler: &mut Sampler,
    records: &mut Vec<SampleRecord>,
    densities: Densities,
    deferred: Option<&mut DeferredLookups>,
) -> Option<Continuation> {
    let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
    let s = sp.bsdf.sample(&sp.ctx, sp.wo, u_lobe, u);
    BsdfRecords::new(scene, sp, light, densities).push_continuing(s.as_ref(), records, deferred)
}

/// The record of a BSDF sample `s` that reached its light, from which radiance `le` arrives;
/// `p_light()` is the light's density in its direction (asked for only when it counts).
fn reached_record(s: &BsdfSample, le: Rgb, p_light: impl FnOnce() -> f32) -> SampleRecord {
    let black = SampleRecord {
        p_bsdf: s.pdf,
        delta: s.delta,
        ..SampleRecord::default()
    };
    if le == Rgb::ZERO {
        // The light does not emit this way: light sampling never produces the direction.
        black
    } else if s.delta {
        // The Dirac densities cancel: f / p_B is the sample's weight times L_e.
        SampleRecord {
            f: s.weight * le,
            ..black
        }
    } else {
        SampleRecord {
            f: s.weight * s.pdf * le,
            p_bsdf: s.pdf,
            p_light: p_light(),
            delta: false,
        }
    }
}

/// BSDF samples whose rays reached the environment unblocked, their records still to be
/// filled ([`DeferredLookups::look_up`]). The map's texel, asked for when the ray was drawn,
/// is read only after the phase's light samples: an unblocked ray's traversal is short, and
/// reading the texel right after it waited on a cache miss (the dragon's largest single
/// stall); the light samples' work now covers it. The records do not change. The lookups are
/// one [`Emitter::eval_pdf_batch`] call (for a packet of camera samples, one call for all its
/// points), which the environment map runs in lanes.
#[derive(Default)]
pub struct DeferredLookups(Vec<DeferredLookup>);

struct DeferredLookup {
    /// Index of the record in the phase's records (or whatever its caller gave).
    record: usize,
    sample: BsdfSample,
    /// The sample's direction in world space.
    wi: Vec3,
}

impl DeferredLookups {
    /// Fills the records of the deferred samples of light `light` at `sp` (the environment) and
    /// forgets them.
    #[inline]
    pub fn look_up(
        &mut self,
        scene: &Scene,
        sp: &ShadingPoint,
        light: usize,
        records: &mut [SampleRecord],
    ) {
        // Most phases have none (every phase of a scene without an environment): tested where
        // the phase ends, since an empty drain, and even the call, cost more than the test.
        if !self.0.is_empty() {
            self.look_up_each(scene, sp, light, records);
        }
    }

    fn look_up_each(
        &mut self,
        scene: &Scene,
        sp: &ShadingPoint,
        light: usize,
        records: &mut [SampleRecord],
    ) {
        BatchScratch::with_thread_local(|scratch| {
            scratch.clear_lookups();
            self.add_to(scratch, sp);
            let values = scratch.look_up(scene.emitters[light].as_ref());
            self.fill(records, values.copied());
        });
    }

    /// Fills the lookups' records from their emitter's `eval_pdf`, taken in order from
    /// `values`, and forgets them.
    #[inline]
    pub(crate) fn fill(
        &mut self,
        records: &mut [SampleRecord],
        values: impl Iterator<Item = (Rgb, f32)>,
    ) {
        self.drain(values, |index, record| records[index] = record);
    }

    /// Gives each lookup's record, from its emitter's `eval_pdf` taken in order from `values`,
    /// to `each` with the index it was deferred with, and forgets them.
    #[inline]
    pub(crate) fn drain(
        &mut self,
        values: impl Iterator<Item = (Rgb, f32)>,
        mut each: impl FnMut(usize, SampleRecord),
    ) {
        for (d, (le, p_light)) in self.0.drain(..).zip(values) {
            each(d.record, reached_record(&d.sample, le, || p_light));
        }
    }

    /// Leaves the record of BSDF sample `sample`, whose ray along `wi` reached the environment
    /// unblocked, to the lookups, under `index`.
    #[inline]
    pub(crate) fn defer(&mut self, index: usize, sample: BsdfSample, wi: Vec3) {
        self.0.push(DeferredLookup {
            record: index,
            sample,
            wi,
        });
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Adds these lookups, left at shading point `sp`, to `scratch`'s batch.
    pub(crate) fn add_to(&self, scratch: &mut BatchScratch, sp: &ShadingPoint) {
        let reference = ReferencePoint {
            position: sp.hit.position,
        };
        for d in &self.0 {
            scratch.directions.push(d.wi);
            scratch.references.push(reference);
        }
    }
}

/// Numbers a BSDF sample takes from the camera sample's stream (lobe choice, then direction),
/// drawn or not: what follows a phase's BSDF samples is known in advance.
pub const BSDF_SAMPLE_NUMBERS: u32 = 3;

/// Draws `count` BSDF samples for non-delta light `light` at `sp` and appends their records,
/// with the densities `densities` asks for. Each sample takes [`BSDF_SAMPLE_NUMBERS`] numbers
/// from `sampler` (lobe choice, then direction), drawn or not. Given `deferred`, the records of
/// samples that reach the environment are left to it, and its [`DeferredLookups::look_up`] must
/// fill them before they are read (after the phase's light samples); without, they are filled
/// at once. Several samples are drawn with one [`Bsdf::sample_batch`] call, which gives what
/// one call each would.
///
/// [`Bsdf::sample_batch`]: lumis_core::bsdf::Bsdf::sample_batch
#[allow(clippy::too_many_arguments)]
pub fn draw_bsdf_samples(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    count: u32,
    sampler: &mut Sampler,
    records: &mut Vec<SampleRecord>,
    densities: Densities,
    mut deferred: Option<&mut DeferredLookups>,
) {
    if count == 1 {
        let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
        let s = sp.bsdf.sample(&sp.ctx, sp.wo, u_lobe, u);
        BsdfRecords::new(scene, sp, light, densities).push_any(s.as_ref(), records, deferred);
        return;
    }
    // One point's batch, without `BatchScratch::sample_bsdfs`' owners (see `draw_light_samples`).
    BatchScratch::with_thread_local(|scratch| {
        let numbers = &mut scratch.bsdf_numbers;
        numbers.clear();
        numbers.extend((0..count).map(|_| (sampler.next_1d(), sampler.next_2d())));
        let samples = &mut scratch.bsdf_samples;
        samples.clear();
        samples.resize(numbers.len(), None);
        sp.bsdf.sample_batch(
            std::slice::from_ref(&sp.ctx),
            std::slice::from_ref(&sp.wo),
            numbers,
            samples,
        );
        let bsdf_records = BsdfRecords::new(scene, sp, light, densities);
        // The side test chosen once for the batch (see `ShadingPoint::leaves_toward`).
        if sp.flags.transmission() {
            for s in samples.iter() {
                bsdf_records.push::<true>(s.as_ref(), records, deferred.as_deref_mut());
            }
        } else {
            for s in samples.iter() {
                bsdf_records.push::<false>(s.as_ref(), records, deferred.as_deref_mut());
            }
        }
    });
}

/// What the records of one light's BSDF samples at one shading point share.
#[derive(Clone, Copy)]
pub(crate) struct BsdfRecords<'a> {
    scene: &'a Scene,
    sp: &'a ShadingPoint<'a>,
    light: usize,
    emitter: &'a dyn Emitter,
    reference: ReferencePoint,
    light_shape: Option<u32>,
    densities: Densities,
}

impl<'a> BsdfRecords<'a> {
    /// For non-delta light `light` at `sp`, with the densities `densities` asks for.
    pub(crate) fn new(
        scene: &'a Scene,
        sp: &'a ShadingPoint<'a>,
        light: usize,
        densities: Densities,
    ) -> Self {
        BsdfRecords {
            scene,
            sp,
            light,
            emitter: scene.emitters[light].as_ref(),
            reference: ReferencePoint {
                position: sp.hit.position,
            },
            light_shape: scene.emitter_shape[light],
            densities,
        }
    }

    /// [`push`](Self::push) with the side test of the point's BSDF, chosen for this one
    /// sample.
    #[inline(always)]
    pub(crate) fn push_any(
        &self,
        s: Option<&BsdfSample>,
        records: &mut Vec<SampleRecord>,
        deferred: Option<&mut DeferredLookups>,
    ) {
        self.push_outcome(self.outcome_any(s), records, deferred);
    }

    /// Appends the record of BSDF sample `s` (`None`: no direction drawn), as
    /// [`draw_bsdf_samples`] describes. Inlined into its two loops (one point's samples, a
    /// packet's points). `TRANSMITS` is the BSDF's `transmission` flag
    /// ([`ShadingPoint::leaves_toward`]).
    #[inline(always)]
    pub(crate) fn push<const TRANSMITS: bool>(
        &self,
        s: Option<&BsdfSample>,
        records: &mut Vec<SampleRecord>,
        deferred: Option<&mut DeferredLookups>,
    ) {
        self.push_outcome(self.outcome::<TRANSMITS>(s), records, deferred);
    }

    /// [`push`](Self::push) for the BSDF sample a path goes on along: its ray is traced to the
    /// closest surface (what the light is found from, the same record), which is returned with
    /// the sample. `None` where the sample drew no direction or leaves on a side of the surface
    /// its BSDF does not scatter toward: the path ends there.
    #[inline(always)]
    pub(crate) fn push_continuing(
        &self,
        s: Option<&BsdfSample>,
        records: &mut Vec<SampleRecord>,
        deferred: Option<&mut DeferredLookups>,
    ) -> Option<Continuation> {
        let (outcome, continuation) = self.continuing_outcome(s);
        self.push_outcome(outcome, records, deferred);
        continuation
    }

    /// What BSDF sample `s` gives, with the side test of the point's BSDF.
    #[inline(always)]
    pub(crate) fn outcome_any(&self, s: Option<&BsdfSample>) -> BsdfOutcome {
        if self.sp.flags.transmission() {
            self.outcome::<true>(s)
        } else {
            self.outcome::<false>(s)
        }
    }

    #[inline(always)]
    fn outcome<const TRANSMITS: bool>(&self, s: Option<&BsdfSample>) -> BsdfOutcome {
        let (scene, light, light_shape, from) =
            (self.scene, self.light, self.light_shape, &self.sp.hit);
        self.outcome_reaching::<TRANSMITS>(s, |ray| {
            reaches_light(scene, light, light_shape, ray, from)
        })
    }

    /// What BSDF sample `s` gives, and the path's continuation along it, as
    /// [`push_continuing`](Self::push_continuing) returns it.
    #[inline(always)]
    pub(crate) fn continuing_outcome(
        &self,
        s: Option<&BsdfSample>,
    ) -> (BsdfOutcome, Option<Continuation>) {
        let (scene, light, light_shape, from) =
            (self.scene, self.light, self.light_shape, &self.sp.hit);
        let mut traced = None;
        let reach = |ray: &Ray| {
            let hit = scene
                .geometry
                .first_hit_leaving(ray, from)
                .map(|first| scene.geometry.surface(ray, &first));
            traced = Some((*ray, hit));
            reached_from(scene, light, light_shape, ray, hit.as_ref())
        };
        let outcome = if self.sp.flags.transmission() {
            self.outcome_reaching::<true>(s, reach)
        } else {
            self.outcome_reaching::<false>(s, reach)
        };
        let continuation = traced.and_then(|(ray, hit)| {
            Some(Continuation {
                sample: *s?,
                ray,
                hit,
            })
        });
        (outcome, continuation)
    }

    /// Appends `outcome`'s record, or leaves it to `deferred` (a placeholder appended).
    #[inline(always)]
    fn push_outcome(
        &self,
        outcome: BsdfOutcome,
        records: &mut Vec<SampleRecord>,
        deferred: Option<&mut DeferredLookups>,
    ) {
        match (outcome, deferred) {
            (BsdfOutcome::Environment(sample, wi), Some(deferred)) => {
                deferred.defer(records.len(), sample, wi);
                records.push(SampleRecord::default());
            }
            (outcome, _) => records.push(self.record_now(outcome)),
        }
    }

    /// `outcome`'s record, an environment's looked up now.
    #[inline(always)]
    pub(crate) fn record_now(&self, outcome: BsdfOutcome) -> SampleRecord {
        match outcome {
            BsdfOutcome::Record(record) => record,
            BsdfOutcome::Environment(sample, wi) => {
                let (le, p_light) = self.emitter.eval_pdf(&self.reference, wi, None);
                reached_record(&sample, le, || p_light)
            }
        }
    }

    /// What BSDF sample `s` gives, with what the sample's ray finds of the light given by
    /// `reach` (called once, only for a sample that leaves on a side the BSDF scatters toward).
    #[inline(always)]
    fn outcome_reaching<const TRANSMITS: bool>(
        &self,
        s: Option<&BsdfSample>,
        reach: impl FnOnce(&Ray) -> Reached,
    ) -> BsdfOutcome {
        let BsdfRecords {
            scene,
            sp,
            light,
            emitter,
            reference,
            light_shape,
            densities,
        } = *self;
        let Some(s) = s else {
            return BsdfOutcome::Record(SampleRecord::default());
        };
        let black = SampleRecord {
            p_bsdf: s.pdf,
            delta: s.delta,
            ..SampleRecord::default()
        };
        let wi = sp.frame.to_world(s.wi);
        let ray = sp.origin.ray(&sp.hit, wi);
        // A black sample's light density, when asked for (a Dirac sample has none to match).
        let black = || {
            BsdfOutcome::Record(if densities == Densities::Both && !s.delta {
                SampleRecord {
                    p_light: light_density_toward(scene, light, light_shape, &reference, &ray),
                    ..black
                }
            } else {
                black
            })
        };
        if !sp.leaves_toward::<TRANSMITS>(wi, s.wi) {
            return black();
        }
        match reach(&ray) {
            Reached::Nothing => black(),
            Reached::Surface(hit, le) => BsdfOutcome::Record(reached_record(s, le, || {
                emitter.pdf_direction(&reference, wi, Some(&hit))
            })),
            Reached::Environment => BsdfOutcome::Environment(*s, wi),
        }
    }
}

/// What a BSDF sample gives a phase: its record, or, for a sample whose ray reached the
/// environment unblocked, the sample and its direction, whose record the environment's lookup
/// gives.
pub(crate) enum BsdfOutcome {
    Record(SampleRecord),
    Environment(BsdfSample, Vec3),
}

/// Draws `count` samples of non-delta light `light` for `sp` and appends their records, with
/// the densities `densities` asks for. Each sample takes two numbers from `sampler`. Several
/// samples are drawn and their BSDF values computed with one batch call each
/// ([`Emitter::sample_direction_batch`], [`Bsdf::eval_pdf_batch`]), which give what one call
/// each would.
///
/// [`Emitter::sample_direction_batch`]: lumis_core::emitter::Emitter::sample_direction_batch
/// [`Bsdf::eval_pdf_batch`]: lumis_core::bsdf::Bsdf::eval_pdf_batch
pub fn draw_light_samples(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    count: u32,
    sampler: &mut Sampler,
    records: &mut Vec<SampleRecord>,
    densities: Densities,
) {
    let emitter = scene.emitters[light].as_ref();
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    if count == 1 {
        let Some(ls) = emitter.sample_direction(&reference, sampler.next_2d()) else {
            records.push(SampleRecord::default());
            return;
        };
        let wi = sp.frame.to_local(ls.wi);
        records.push(light_record_any(
            scene,
            sp,
            light,
            &ls,
            wi.z,
            densities,
            || sp.bsdf.eval_pdf(&sp.ctx, sp.wo, wi),
        ));
        return;
    }
    // One point's batch, written out rather than through `BatchScratch::sample_light`: its
    // per-entry owners, ωo and frames, which a single point does not need, cost the render loop
    // 5.5 % more instructions when drawn through it.
    BatchScratch::with_thread_local(|scratch| {
        let numbers = &mut scratch.light_numbers;
        numbers.clear();
        numbers.extend((0..count).map(|_| sampler.next_2d()));
        let samples = &mut scratch.light_samples;
        samples.clear();
        samples.resize(numbers.len(), None);
        emitter.sample_direction_batch(std::slice::from_ref(&reference), numbers, samples);
        // The BSDF toward every sample at once; a sample it cannot reflect toward has its value
        // ignored, as `light_record` would not have asked for it.
        let directions = &mut scratch.directions;
        directions.clear();
        directions.extend(
            samples
                .iter()
                .map(|ls| ls.map_or(Vec3::Z, |ls| sp.frame.to_local(ls.wi))),
        );
        let values = &mut scratch.values;
        values.clear();
        values.resize(directions.len(), (Rgb::ZERO, 0.0));
        sp.bsdf.eval_pdf_batch(
            std::slice::from_ref(&sp.ctx),
            std::slice::from_ref(&sp.wo),
            directions,
            values,
        );
        // The side test chosen once for the batch (see `ShadingPoint::scatters_from_sample`).
        if sp.flags.transmission() {
            for ((ls, &value), wi) in samples.iter().zip(values.iter()).zip(directions.iter()) {
                records.push(match ls {
                    Some(ls) => {
                        light_record::<true>(scene, sp, light, ls, wi.z, densities, || value)
                    }
                    None => SampleRecord::default(),
                });
            }
        } else {
            for (ls, &value) in samples.iter().zip(values.iter()) {
                records.push(match ls {
                    Some(ls) => {
                        light_record::<false>(scene, sp, light, ls, 0.0, densities, || value)
                    }
                    None => SampleRecord::default(),
                });
            }
        }
    });
}

/// [`light_record`] with the side test of `sp`'s BSDF, chosen for this one record.
#[inline(always)]
pub(crate) fn light_record_any(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    ls: &EmitterSample,
    wi_local_z: f32,
    densities: Densities,
    eval_pdf: impl FnOnce() -> (Rgb, f32),
) -> SampleRecord {
    if sp.flags.transmission() {
        light_record::<true>(scene, sp, light, ls, wi_local_z, densities, eval_pdf)
    } else {
        light_record::<false>(scene, sp, light, ls, wi_local_z, densities, eval_pdf)
    }
}

/// The record of light `light`'s sample `ls` at `sp` (whose direction has z `wi_local_z` in
/// the shading frame, read only if `TRANSMITS`, the BSDF's [`BsdfFlags::transmission`]),
/// given the BSDF's `eval_pdf` toward it (`eval_pdf()`, asked for only where the surface can
/// scatter light from the sample or both densities are wanted).
///
/// [`BsdfFlags::transmission`]: lumis_core::bsdf::BsdfFlags::transmission
#[inline(always)]
pub(crate) fn light_record<const TRANSMITS: bool>(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    ls: &EmitterSample,
    wi_local_z: f32,
    densities: Densities,
    eval_pdf: impl FnOnce() -> (Rgb, f32),
) -> SampleRecord {
    let both = densities == Densities::Both;
    let reflects = sp.scatters_from_sample::<TRANSMITS>(ls, wi_local_z);
    // Value and density in one call: an unoccluded sample needs both.
    let (f, p_bsdf) = if reflects || both {
        eval_pdf()
    } else {
        (Rgb::ZERO, 0.0)
    };
    if !reflects || f == Rgb::ZERO || !sp.sees(scene, light, ls) {
        return SampleRecord {
            p_light: ls.pdf,
            p_bsdf: if both { p_bsdf } else { 0.0 },
            ..SampleRecord::default()
        };
    }
    SampleRecord {
        f: f * ls.radiance,
        p_bsdf,
        p_light: ls.pdf,
        delta: false,
    }
}

/// One sample of a delta light (point, directional): its contribution, with no MIS.
pub fn estimate_delta_light(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    sampler: &mut Sampler,
) -> Rgb {
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    let Some(ls) = scene.emitters[light].sample_direction(&reference, sampler.next_2d()) else {
        return Rgb::ZERO;
    };
    let f = sp.eval_toward(&ls);
    if f == Rgb::ZERO || !sp.sees(scene, light, &ls) {
        return Rgb::ZERO;
    }
    f * ls.radiance / ls.pdf
}

/// Radiance emitted toward the camera by the surface a primary ray hit (added once per sample).
pub fn emitted(scene: &Scene, hit: &Intersection, wi: Vec3) -> Rgb {
    match scene.emitter_of(hit) {
        Some(e) => {
            let h = EmitterHit {
                position: hit.position,
                normal: hit.geometric_normal,
                distance: hit.t,
            };
            scene.emitters[e].eval(wi, Some(&h))
        }
        None => Rgb::ZERO,
    }
}

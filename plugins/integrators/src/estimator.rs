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

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfSample};
use lumis_core::emitter::{Emitter, EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::geometry::{FirstHit, Intersection, Ray, RayOrigin};
use lumis_core::math::{Frame, Rgb};
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;
use std::cell::RefCell;

/// A surface point seen by the camera, with its shading frame turned toward the viewer
/// (surfaces are two-sided).
pub struct ShadingPoint<'a> {
    pub hit: Intersection,
    pub frame: Frame,
    /// Geometric normal on the viewer's side.
    pub normal: Vec3,
    /// ωo in the local shading frame.
    pub wo: Vec3,
    pub bsdf: &'a dyn Bsdf,
    /// Where its shadow and BSDF rays start (those on the viewer's side).
    pub origin: RayOrigin,
    /// The rounding error of the point across its surface's plane, |n| · error.
    plane_error: f32,
}

impl<'a> ShadingPoint<'a> {
    /// The shading point of `hit`, seen from `wo_world`. Inlined, so that it is built where it
    /// is kept: built apart, it was copied there, and the copy read it back in 64-byte pieces
    /// just after its narrower stores, waiting for them to reach the cache.
    #[inline(always)]
    pub fn new(scene: &'a Scene, hit: Intersection, wo_world: Vec3) -> Self {
        let flip = hit.geometric_normal.dot(wo_world) < 0.0;
        let sign = if flip { -1.0 } else { 1.0 };
        let frame = Frame::from_normal(sign * hit.shading_normal);
        ShadingPoint {
            frame,
            normal: sign * hit.geometric_normal,
            wo: frame.to_local(wo_world),
            bsdf: scene.bsdf(&hit),
            origin: RayOrigin::toward(&hit, wo_world),
            plane_error: hit.geometric_normal.abs().dot(hit.error),
            hit,
        }
    }

    /// Whether the BSDF is a Dirac lobe only (a mirror), which light sampling can never reach.
    pub fn is_pure_delta(&self) -> bool {
        let flags = self.bsdf.flags();
        flags.delta && !flags.diffuse && !flags.glossy
    }

    /// Reflection only: ωi must leave on the viewer's side of the geometric surface, or shading
    /// normals would let light leak through.
    #[inline]
    fn reflects_toward(&self, wi_world: Vec3) -> bool {
        self.normal.dot(wi_world) > 0.0
    }

    /// Whether a sample of light `light` is unoccluded: a shadow ray to its point, or to
    /// infinity.
    fn sees(&self, scene: &Scene, light: usize, sample: &EmitterSample) -> bool {
        let ray = match sample.position {
            Some(target) => self.origin.ray_to(&self.hit, target),
            None => self.origin.ray(&self.hit, sample.wi),
        };
        !scene.occluded_toward_light(&ray, &self.hit, light)
    }

    /// Whether the surface can reflect toward a light sample: ωi on the viewer's side of the
    /// geometric surface. A light point closer to the surface's plane than the rounding error of
    /// the shading point (a light lying on the surface) is on no definite side of it, and lights
    /// nothing.
    fn reflects_toward_sample(&self, sample: &EmitterSample) -> bool {
        let height = self.normal.dot(sample.wi);
        // The distance (a square root) only where the sample is on the viewer's side.
        height > 0.0
            && !sample
                .position
                .is_some_and(|p| height * (p - self.hit.position).length() <= self.plane_error)
    }

    /// BSDF value (with cosine) toward a light sample, zero when it cannot reflect there.
    fn eval_toward(&self, sample: &EmitterSample) -> Rgb {
        if !self.reflects_toward_sample(sample) {
            return Rgb::ZERO;
        }
        self.bsdf.eval(self.wo, self.frame.to_local(sample.wi))
    }
}

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
    /// sample drew no direction, reflects away from the viewer's side, misses the light or is
    /// occluded. For a Dirac BSDF sample (`delta`), f divided by the Dirac density: the BSDF
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

#[cfg(test)]
impl SampleRecord {
    /// A non-delta record of grey integrand `f`, for unit tests.
    pub(crate) fn grey(f: f32, p_bsdf: f32, p_light: f32) -> Self {
        SampleRecord {
            f: Rgb::splat(f),
            p_bsdf,
            p_light,
            delta: false,
        }
    }
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
        if scene.geometry.occluded_by_others(ray, None, Some(from)) {
            return Reached::Nothing;
        }
        // Only for a ray that escapes: its lookup is deferred to the end of the phase, after
        // the light samples, which leaves the read time to arrive.
        emitter.prefetch(ray.direction);
        return Reached::Environment;
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
    /// Index of the record in the phase's records.
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
            scratch.add_lookups(sp, self);
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
        for (d, (le, p_light)) in self.0.drain(..).zip(values) {
            records[d.record] = reached_record(&d.sample, le, || p_light);
        }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Numbers a BSDF sample takes from the camera sample's stream (lobe choice, then direction),
/// drawn or not: what follows a phase's BSDF samples is known in advance.
pub const BSDF_SAMPLE_NUMBERS: u32 = 3;

/// Space for the batch calls of the estimator ([`Bsdf::sample_batch`],
/// [`Emitter::sample_direction_batch`], [`Bsdf::eval_pdf_batch`]): their inputs and results,
/// one entry per sample, reused by each thread so that no sample allocates.
///
/// [`Bsdf::sample_batch`]: lumis_core::bsdf::Bsdf::sample_batch
/// [`Bsdf::eval_pdf_batch`]: lumis_core::bsdf::Bsdf::eval_pdf_batch
/// [`Emitter::sample_direction_batch`]: lumis_core::emitter::Emitter::sample_direction_batch
#[derive(Default)]
pub(crate) struct BatchScratch {
    /// The shading point each entry belongs to (an index the caller gives meaning to).
    pub(crate) owners: Vec<usize>,
    /// ωo of each entry's shading point.
    pub(crate) wo: Vec<Vec3>,
    pub(crate) bsdf_numbers: Vec<(f32, Vec2)>,
    pub(crate) bsdf_samples: Vec<Option<BsdfSample>>,
    pub(crate) references: Vec<ReferencePoint>,
    pub(crate) light_numbers: Vec<Vec2>,
    pub(crate) light_samples: Vec<Option<EmitterSample>>,
    /// Each light sample's direction in its shading point's frame.
    pub(crate) directions: Vec<Vec3>,
    /// The BSDF's `eval_pdf` toward each light sample.
    pub(crate) values: Vec<(Rgb, f32)>,
}

thread_local! {
    static BATCH_SCRATCH: RefCell<BatchScratch> = RefCell::new(BatchScratch::default());
}

impl BatchScratch {
    /// Runs `f` with this thread's scratch space. Not re-entrant.
    pub(crate) fn with_thread_local<R>(f: impl FnOnce(&mut BatchScratch) -> R) -> R {
        BATCH_SCRATCH.with_borrow_mut(f)
    }

    /// Empties every list (keeping their memory).
    pub(crate) fn clear(&mut self) {
        self.owners.clear();
        self.wo.clear();
        self.bsdf_numbers.clear();
        self.bsdf_samples.clear();
        self.references.clear();
        self.light_numbers.clear();
        self.light_samples.clear();
        self.directions.clear();
        self.values.clear();
    }

    /// Starts a batch of deferred lookups ([`DeferredLookups`]) in `references` and
    /// `directions`.
    pub(crate) fn clear_lookups(&mut self) {
        self.references.clear();
        self.directions.clear();
    }

    /// Adds the lookups `lookups` left at shading point `sp` to the batch.
    pub(crate) fn add_lookups(&mut self, sp: &ShadingPoint, lookups: &DeferredLookups) {
        let reference = ReferencePoint {
            position: sp.hit.position,
        };
        for d in &lookups.0 {
            self.directions.push(d.wi);
            self.references.push(reference);
        }
    }

    /// The batch's lookups with one [`Emitter::eval_pdf_batch`] call of `emitter`: radiance
    /// and density along each direction, in the order they were added.
    pub(crate) fn look_up(&mut self, emitter: &dyn Emitter) -> std::slice::Iter<'_, (Rgb, f32)> {
        self.values.clear();
        self.values.resize(self.directions.len(), (Rgb::ZERO, 0.0));
        emitter.eval_pdf_batch(&self.references, &self.directions, &mut self.values);
        self.values.iter()
    }

    /// The BSDF samples of the entries in `bsdf_numbers`, with `wo`, into `bsdf_samples`: one
    /// batch call per run of consecutive entries whose shading points (`owner`'s) share a BSDF.
    pub(crate) fn sample_bsdfs<'a>(&mut self, bsdf_of: impl Fn(usize) -> &'a dyn Bsdf) {
        self.bsdf_samples.resize(self.bsdf_numbers.len(), None);
        for_runs(&self.owners, &bsdf_of, |bsdf, run| {
            bsdf.sample_batch(
                &self.wo[run.clone()],
                &self.bsdf_numbers[run.clone()],
                &mut self.bsdf_samples[run],
            );
        });
    }

    /// The light samples of the entries in `light_numbers` from `references`, into
    /// `light_samples`, and the BSDF toward each (`directions` in its shading point's frame,
    /// `frame_of(owner)`), into `values`: one batch call for the light, one per run of
    /// consecutive entries whose shading points share a BSDF for the BSDF.
    pub(crate) fn sample_light<'a>(
        &mut self,
        emitter: &dyn Emitter,
        point_of: impl Fn(usize) -> &'a ShadingPoint<'a>,
    ) {
        let n = self.light_numbers.len();
        self.light_samples.resize(n, None);
        emitter.sample_direction_batch(
            &self.references,
            &self.light_numbers,
            &mut self.light_samples,
        );
        // The BSDF toward every sample at once; a sample it cannot reflect toward has its value
        // ignored, as `light_record` would not have asked for it.
        self.directions.extend(
            self.light_samples
                .iter()
                .zip(&self.owners)
                .map(|(ls, &owner)| ls.map_or(Vec3::Z, |ls| point_of(owner).frame.to_local(ls.wi))),
        );
        self.values.resize(n, (Rgb::ZERO, 0.0));
        for_runs(&self.owners, &|owner| point_of(owner).bsdf, |bsdf, run| {
            bsdf.eval_pdf_batch(
                &self.wo[run.clone()],
                &self.directions[run.clone()],
                &mut self.values[run],
            );
        });
    }
}

/// Calls `f(bsdf, range)` for each run of consecutive entries of `owners` whose owners have the
/// same BSDF (`bsdf_of`).
fn for_runs<'a>(
    owners: &[usize],
    bsdf_of: &impl Fn(usize) -> &'a dyn Bsdf,
    mut f: impl FnMut(&'a dyn Bsdf, std::ops::Range<usize>),
) {
    let mut start = 0;
    while start < owners.len() {
        let bsdf = bsdf_of(owners[start]);
        let same = |&owner: &usize| std::ptr::addr_eq(bsdf_of(owner), bsdf);
        let end = start + owners[start..].iter().take_while(|o| same(o)).count();
        f(bsdf, start..end);
        start = end;
    }
}

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
        let s = sp.bsdf.sample(sp.wo, u_lobe, u);
        BsdfRecords::new(scene, sp, light, densities).push(s, records, deferred);
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
        sp.bsdf
            .sample_batch(std::slice::from_ref(&sp.wo), numbers, samples);
        let bsdf_records = BsdfRecords::new(scene, sp, light, densities);
        for &s in samples.iter() {
            bsdf_records.push(s, records, deferred.as_deref_mut());
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

    /// Appends the record of BSDF sample `s` (`None`: no direction drawn), as
    /// [`draw_bsdf_samples`] describes. Inlined into its two loops (one point's samples, a
    /// packet's points).
    #[inline(always)]
    pub(crate) fn push(
        &self,
        s: Option<BsdfSample>,
        records: &mut Vec<SampleRecord>,
        deferred: Option<&mut DeferredLookups>,
    ) {
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
            records.push(SampleRecord::default());
            return;
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
            if densities == Densities::Both && !s.delta {
                SampleRecord {
                    p_light: light_density_toward(scene, light, light_shape, &reference, &ray),
                    ..black
                }
            } else {
                black
            }
        };
        if !sp.reflects_toward(wi) {
            records.push(black());
            return;
        }
        match reaches_light(scene, light, light_shape, &ray, &sp.hit) {
            Reached::Nothing => records.push(black()),
            Reached::Surface(hit, le) => records.push(reached_record(&s, le, || {
                emitter.pdf_direction(&reference, wi, Some(&hit))
            })),
            Reached::Environment => match deferred {
                Some(deferred) => {
                    deferred.0.push(DeferredLookup {
                        record: records.len(),
                        sample: s,
                        wi,
                    });
                    records.push(SampleRecord::default());
                }
                None => {
                    let (le, p_light) = emitter.eval_pdf(&reference, wi, None);
                    records.push(reached_record(&s, le, || p_light));
                }
            },
        }
    }
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
        records.push(light_record(scene, sp, light, &ls, densities, || {
            sp.bsdf.eval_pdf(sp.wo, wi)
        }));
        return;
    }
    // One point's batch, written out rather than through `BatchScratch::sample_light`, whose
    // per-entry owners, ωo and frames a single point does not need (through it, the render
    // loop took 5.5 % more instructions in the tenth round).
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
        sp.bsdf
            .eval_pdf_batch(std::slice::from_ref(&sp.wo), directions, values);
        for (ls, &value) in samples.iter().zip(values.iter()) {
            records.push(match ls {
                Some(ls) => light_record(scene, sp, light, ls, densities, || value),
                None => SampleRecord::default(),
            });
        }
    });
}

/// The record of light `light`'s sample `ls` at `sp`, given the BSDF's `eval_pdf` toward it
/// (`eval_pdf()`, asked for only where the surface can reflect toward the sample or both
/// densities are wanted).
#[inline(always)]
pub(crate) fn light_record(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    ls: &EmitterSample,
    densities: Densities,
    eval_pdf: impl FnOnce() -> (Rgb, f32),
) -> SampleRecord {
    let both = densities == Densities::Both;
    let reflects = sp.reflects_toward_sample(ls);
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

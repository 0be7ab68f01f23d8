//! `BatchScratch`: the space for the estimator's batch calls, each thread's own.

use crate::shading_point::ShadingPoint;
use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfSample};
use lumis_core::emitter::{Emitter, EmitterSample, ReferencePoint};
use lumis_core::math::Rgb;
use std::cell::RefCell;

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
    /// The BSDF context of each entry's shading point, or one for all the entries when their
    /// points share it.
    pub(crate) contexts: Vec<BsdfContext>,
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
        self.contexts.clear();
        self.bsdf_numbers.clear();
        self.bsdf_samples.clear();
        self.references.clear();
        self.light_numbers.clear();
        self.light_samples.clear();
        self.directions.clear();
        self.values.clear();
    }

    /// Starts a batch of deferred lookups ([`crate::estimator::DeferredLookups`]) in
    /// `references` and `directions`.
    pub(crate) fn clear_lookups(&mut self) {
        self.references.clear();
        self.directions.clear();
    }

    /// The batch's lookups with one [`Emitter::eval_pdf_batch`] call of `emitter`: radiance
    /// and density along each direction, in the order they were added.
    pub(crate) fn look_up(&mut self, emitter: &dyn Emitter) -> std::slice::Iter<'_, (Rgb, f32)> {
        self.values.clear();
        self.values.resize(self.directions.len(), (Rgb::ZERO, 0.0));
        emitter.eval_pdf_batch(&self.references, &self.directions, &mut self.values);
        self.values.iter()
    }

    /// The BSDF samples of the entries in `bsdf_numbers`, with `contexts` and `wo`, into
    /// `bsdf_samples`: one batch call per run of consecutive entries whose shading points
    /// (`owner`'s) share a BSDF.
    pub(crate) fn sample_bsdfs<'a>(&mut self, bsdf_of: impl Fn(usize) -> &'a dyn Bsdf) {
        self.bsdf_samples.resize(self.bsdf_numbers.len(), None);
        for_runs(&self.owners, &bsdf_of, |bsdf, run| {
            bsdf.sample_batch(
                contexts_of(&self.contexts, run.clone()),
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
                contexts_of(&self.contexts, run.clone()),
                &self.wo[run.clone()],
                &self.directions[run.clone()],
                &mut self.values[run],
            );
        });
    }
}

/// The contexts of the entries `run`: the one every entry shares where `contexts` holds one,
/// else theirs.
fn contexts_of(contexts: &[BsdfContext], run: std::ops::Range<usize>) -> &[BsdfContext] {
    if contexts.len() == 1 {
        contexts
    } else {
        &contexts[run]
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

//! Sample allocation: how many of a light's N samples at a shading point each technique gets,
//! possibly in phases (a pilot, then the rest), and how the phases combine into one unbiased
//! estimate. An [`Allocation`] draws its phases through a [`LightSampling`]
//! ([`crate::sampling`]), each weighed by the [`Weighting`] it is given.
//!
//! What [`crate::mis::MisIntegrator`] runs is a [`Method`]: an allocation with its weighting
//! ([`Weighted`]), or an allocation that makes its own weights (from its own pilot, say), which
//! implements `Method` itself and is given no weighting.

use crate::phase::LightEstimate;
use crate::sampling::LightSampling;
use crate::weighting::Weighting;
use lumis_core::passes::PassContext;
use lumis_core::scene::Scene;

/// How a light's samples are allocated to the techniques, and how phases combine, for any
/// weighting.
pub trait Allocation: Send + Sync {
    /// Estimates the light of `sampling` at its shading point with the allocation's N samples,
    /// each phase weighted by `weighting`.
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate;

    /// [`estimate`](Self::estimate) for the samplings of one light at several shading points
    /// (a packet of camera samples): `estimates[k]` for `samplings[k]`, `None` entries
    /// skipped. The default estimates them one by one; an allocation whose phases do not depend
    /// on each other's results may draw them together ([`LightSampling::phases_together`]),
    /// giving each what `estimate` would, bit for bit.
    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        estimate_each(samplings, estimates, |sampling| {
            self.estimate(sampling, weighting)
        });
    }

    /// Work once per scene before rendering (e.g. a pilot pass over the image whose
    /// statistics, filtered over neighbouring pixels, `estimate` then reads per pixel and light
    /// through `sampling.pixel()`).
    fn preprocess(&mut self, _scene: &Scene) {}

    /// How many f64 sums per pixel [`observe`](Self::observe) adds (statistics learned from
    /// the render's own passes); 0, the default, when the allocation learns nothing.
    fn pixel_sums(&self, _scene: &Scene) -> usize {
        0
    }

    /// Called before each pass of a render in passes with the passes before it: an
    /// allocation that learns reads its statistics there (`pass.sums`, from `offset` in each
    /// pixel's integrator sums), and decides what the pass uses from them only.
    fn begin_pass(&mut self, _scene: &Scene, _pass: &PassContext<'_>, _offset: usize) {}

    /// Whether [`observe`](Self::observe) adds anything in the current pass.
    fn learning(&self) -> bool {
        false
    }

    /// Adds the statistics of the phase `sampling` drew last to `sums` (this allocation's
    /// [`pixel_sums`](Self::pixel_sums) of the pixel): only adds, allocates nothing.
    fn observe(&self, _sampling: &LightSampling, _sums: &mut [f64]) {}
}

/// A MIS method as [`crate::mis::MisIntegrator`] runs it: the estimate of each non-delta light
/// at a shading point. An [`Allocation`] with a [`Weighting`] is one ([`Weighted`]); an
/// allocation that weighs its phases itself implements it directly.
pub trait Method: Send + Sync {
    /// The estimate of the light of `sampling` at its shading point.
    fn estimate(&self, sampling: &mut LightSampling) -> LightEstimate;

    /// [`estimate`](Self::estimate) for the samplings of one light at several shading points,
    /// as [`Allocation::estimate_together`]; the default estimates them one by one.
    fn estimate_together(
        &self,
        samplings: &mut [Option<LightSampling>],
        estimates: &mut [LightEstimate],
    ) {
        estimate_each(samplings, estimates, |sampling| self.estimate(sampling));
    }

    /// Work once per scene before rendering.
    fn preprocess(&mut self, _scene: &Scene) {}

    /// How many f64 sums per pixel [`observe`](Self::observe) adds (statistics learned from
    /// the render's own passes); 0, the default, when the method learns nothing.
    fn pixel_sums(&self, _scene: &Scene) -> usize {
        0
    }

    /// Called before each pass of a render in passes with the passes before it: a
    /// method that learns reads its statistics there (`pass.sums`, from `offset` in each
    /// pixel's integrator sums), and decides what the pass uses from them only.
    fn begin_pass(&mut self, _scene: &Scene, _pass: &PassContext<'_>, _offset: usize) {}

    /// Whether [`observe`](Self::observe) adds anything in the current pass.
    fn learning(&self) -> bool {
        false
    }

    /// Adds the statistics of the phase `sampling` drew last to `sums` (this method's
    /// [`pixel_sums`](Self::pixel_sums) of the pixel): only adds, allocates nothing.
    fn observe(&self, _sampling: &LightSampling, _sums: &mut [f64]) {}
}

/// An allocation with the weighting of all its phases: the method of most plugins (e.g.
/// `balance`: `Weighted(FixedAlpha { alpha: 0.5, samples }, PerSample(Balance))`).
pub struct Weighted<A, W>(pub A, pub W);

impl<A: Allocation, W: Weighting> Method for Weighted<A, W> {
    #[inline]
    fn estimate(&self, sampling: &mut LightSampling) -> LightEstimate {
        self.0.estimate(sampling, &self.1)
    }

    #[inline]
    fn estimate_together(
        &self,
        samplings: &mut [Option<LightSampling>],
        estimates: &mut [LightEstimate],
    ) {
        self.0.estimate_together(samplings, &self.1, estimates);
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.0.preprocess(scene);
        self.1.preprocess(scene);
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        self.0.pixel_sums(scene)
    }

    fn begin_pass(&mut self, scene: &Scene, pass: &PassContext<'_>, offset: usize) {
        self.0.begin_pass(scene, pass, offset);
    }

    #[inline]
    fn learning(&self) -> bool {
        self.0.learning()
    }

    #[inline]
    fn observe(&self, sampling: &LightSampling, sums: &mut [f64]) {
        self.0.observe(sampling, sums);
    }
}

/// The samplings' estimates one at a time, `estimate(samplings[k])` into `estimates[k]`: the
/// default of `estimate_together`, and an override's way out.
pub fn estimate_each(
    samplings: &mut [Option<LightSampling>],
    estimates: &mut [LightEstimate],
    mut estimate: impl FnMut(&mut LightSampling) -> LightEstimate,
) {
    for (sampling, out) in samplings.iter_mut().zip(estimates) {
        if let Some(sampling) = sampling {
            *out = estimate(sampling);
        }
    }
}

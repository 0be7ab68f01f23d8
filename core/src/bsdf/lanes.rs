//! The BSDF interface over [`Lanes`]: a BSDF writes `eval_pdf` and `sample` once
//! ([`BsdfLanes`]) and is a [`Bsdf`](super::Bsdf) by that alone, whose scalar methods run them on one
//! sample (`f32`) and whose batch methods on four or eight, with the same operations in each
//! lane, so that the results agree bit for bit.
//!
//! The lanes need not share a shading point: each lane has its context ([`BsdfContextLanes`])
//! and its parameters resolved at that context ([`BsdfLanes::Params`], a textured reflectance
//! looked up at each lane's uv). For the samples of one shading point the context and the
//! parameters are splats, resolved once per batch.

use super::context::{BsdfContext, Side};
use super::flags::BsdfFlags;
use super::sample::BsdfSample;
use crate::math::Rgb;
use crate::math::lanes::{LaneKernel, Lanes, Mask, V2, V3, by_groups, with_widest_lanes};
use glam::{Vec2, Vec3};

/// [`BsdfContext`] in lanes: each lane's texture coordinates and side.
#[derive(Clone, Copy)]
#[non_exhaustive]
pub struct BsdfContextLanes<L: Lanes> {
    pub uv: V2<L>,
    /// Set where the viewer is on the back of the surface ([`Side::Back`]).
    pub back: L::Mask,
}

impl<L: Lanes> BsdfContextLanes<L> {
    /// `ctx` in every lane.
    #[inline(always)]
    pub fn splat(ctx: &BsdfContext) -> Self {
        let back = ctx.side == Side::Back;
        BsdfContextLanes {
            uv: V2::splat(ctx.uv),
            back: L::Mask::from_fn(|_| back),
        }
    }

    /// The contexts of a batch argument (one for every element, or one each; see
    /// [`one_or_each`](crate::math::lanes::one_or_each)) for the elements `k`, one per lane.
    #[inline(always)]
    pub fn gather<const W: usize>(ctx: &[BsdfContext], k: [usize; W]) -> Self {
        if let [one] = ctx {
            return Self::splat(one);
        }
        BsdfContextLanes {
            uv: V2::from_fn(|i| ctx[k[i]].uv),
            back: L::Mask::from_fn(|i| ctx[k[i]].side == Side::Back),
        }
    }

    /// Lane `i`'s context.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> BsdfContext {
        let side = if self.back.lane(i) {
            Side::Back
        } else {
            Side::Front
        };
        BsdfContext::new(self.uv.lane(i), side)
    }
}

/// Samples of a BSDF written over [`Lanes`]: one per lane, `valid` where the lane drew one.
/// Built with [`BsdfSampleLanes::new`] or [`BsdfSampleLanes::from_pdf`] (then
/// [`with_eta`](Self::with_eta), [`with_delta`](Self::with_delta)): fields may be added.
#[derive(Clone, Copy)]
#[non_exhaustive]
pub struct BsdfSampleLanes<L: Lanes> {
    pub valid: L::Mask,
    pub wi: V3<L>,
    pub pdf: L,
    pub weight: V3<L>,
    /// η = η_i / η_o of each lane's interaction (see [`BsdfSample::eta`]); `None`: 1 in every
    /// lane (reflections), which costs a kernel nothing.
    pub eta: Option<L>,
    /// Set where the lane's sample is of a Dirac lobe; `None`: in no lane.
    pub delta: Option<L::Mask>,
}

impl<L: Lanes> BsdfSampleLanes<L> {
    /// Samples of lobes that have a density, η = 1, valid where `valid` is set.
    #[inline(always)]
    pub fn new(valid: L::Mask, wi: V3<L>, pdf: L, weight: V3<L>) -> Self {
        BsdfSampleLanes {
            valid,
            wi,
            pdf,
            weight,
            eta: None,
            delta: None,
        }
    }

    /// [`sample_from_pdf`](super::sample_from_pdf) in each lane: directions `wi`, drawn where
    /// `drawn` is set, whose `eval_pdf` is `(value, pdf)`; valid off the horizon where the
    /// density and the weight are positive finite numbers.
    #[inline(always)]
    pub fn from_pdf(drawn: L::Mask, wi: V3<L>, (value, pdf): (V3<L>, L)) -> Self {
        let zero = L::splat(0.0);
        let weight = value / pdf;
        let valid = drawn
            & !wi.z.eq(zero)
            & wi.is_finite()
            & pdf.gt(zero)
            & pdf.is_finite()
            & weight.is_finite();
        Self::new(valid, wi, pdf, weight)
    }

    /// These samples with relative indices of refraction `eta`.
    #[inline(always)]
    pub fn with_eta(self, eta: L) -> Self {
        BsdfSampleLanes {
            eta: Some(eta),
            ..self
        }
    }

    /// These samples, of Dirac lobes where `delta` is set.
    #[inline(always)]
    pub fn with_delta(self, delta: L::Mask) -> Self {
        BsdfSampleLanes {
            delta: Some(delta),
            ..self
        }
    }

    /// Lane `i`'s sample, if it drew one. (No closure: one the compiler does not inline is
    /// compiled without the AVX2 of the kernel that calls it.)
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Option<BsdfSample> {
        if !self.valid.lane(i) {
            return None;
        }
        Some(BsdfSample {
            wi: self.wi.lane(i),
            pdf: self.pdf.lane(i),
            weight: self.weight.lane(i),
            delta: match self.delta {
                Some(delta) => delta.lane(i),
                None => false,
            },
            eta: match self.eta {
                Some(eta) => eta.lane(i),
                None => 1.0,
            },
        })
    }
}

/// A BSDF whose `eval_pdf` and `sample` are written over [`Lanes`], once for the scalar
/// methods of its [`Bsdf`](super::Bsdf) (on `f32`) and the batch ones (as many lanes wide as the processor
/// has): every `BsdfLanes` is a [`Bsdf`](super::Bsdf), through the one implementation in `bsdf.rs`.
///
/// A kernel is given each lane's context and the BSDF's parameters resolved at it
/// ([`params_lanes`](Self::params_lanes)): for the samples of one shading point both are the
/// same in every lane and resolved once per batch; a wavefront of many shading points resolves
/// them per lane. A parameter given as a constant resolves to a splat of it (no lookup, no
/// call); one given as a texture to its values at the lanes' uv
/// ([`RgbSource`](crate::texture::RgbSource)).
pub trait BsdfLanes: Send + Sync {
    /// The parameters that may differ from one shading point to the next (textured ones),
    /// resolved in lanes; `()` for a BSDF whose parameters are all constant.
    type Params<L: Lanes>: Copy;

    /// Whether the kernels depend on their contexts (a textured parameter's uv, the side).
    /// `false` for a BSDF whose parameters are constants and that is the same from both
    /// sides: a batch over several shading points then runs it with one context for all,
    /// its parameters resolved once, rather than gathering each group's contexts.
    const READS_CONTEXT: bool = true;

    /// Its lobes, and [`BsdfFlags::SPATIALLY_VARYING`] where a parameter is textured: what its
    /// [`Bsdf::flags`](super::Bsdf::flags) returns.
    fn bsdf_flags(&self) -> BsdfFlags;

    /// The parameters at each lane's context.
    fn params_lanes<L: Lanes>(&self, ctx: &BsdfContextLanes<L>) -> Self::Params<L>;

    /// `eval_pdf(ctx, wo, wi)` in each lane, with the parameters resolved at its context.
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        params: &Self::Params<L>,
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L);

    /// `sample(ctx, wo, u_lobe, (u0, u1))` in each lane, with the parameters resolved at its
    /// context.
    fn sample_lanes<L: Lanes>(
        &self,
        params: &Self::Params<L>,
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        u_lobe: L,
        u: (L, L),
    ) -> BsdfSampleLanes<L>;
}

/// [`Bsdf::eval_pdf`](super::Bsdf::eval_pdf) of a BSDF written over [`Lanes`]: its formula on one lane.
#[inline(always)]
pub(super) fn eval_pdf_one<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    ctx: &BsdfContext,
    wo: Vec3,
    wi: Vec3,
) -> (Rgb, f32) {
    let ctx = BsdfContextLanes::<f32>::splat(ctx);
    let params = bsdf.params_lanes(&ctx);
    let (value, pdf) = bsdf.eval_pdf_lanes(&params, &ctx, V3::splat(wo), V3::splat(wi));
    (value.lane(0), pdf)
}

/// [`Bsdf::sample`](super::Bsdf::sample) of a BSDF written over [`Lanes`]: its formula on one lane.
#[inline(always)]
pub(super) fn sample_one<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    ctx: &BsdfContext,
    wo: Vec3,
    u_lobe: f32,
    u: Vec2,
) -> Option<BsdfSample> {
    let ctx = BsdfContextLanes::<f32>::splat(ctx);
    let params = bsdf.params_lanes(&ctx);
    bsdf.sample_lanes(&params, &ctx, V3::splat(wo), u_lobe, (u.x, u.y))
        .lane(0)
}

/// The contexts and parameters of a group of lanes: resolved once for a batch of one context
/// (`single`), else per group.
#[inline(always)]
fn group_context<B: BsdfLanes + ?Sized, L: Lanes, const W: usize>(
    bsdf: &B,
    single: &Option<(B::Params<L>, BsdfContextLanes<L>)>,
    ctx: &[BsdfContext],
    k: [usize; W],
) -> (B::Params<L>, BsdfContextLanes<L>) {
    match single {
        Some(resolved) => *resolved,
        None => {
            let ctx = BsdfContextLanes::gather(ctx, k);
            (bsdf.params_lanes(&ctx), ctx)
        }
    }
}

/// The context and parameters of a batch whose elements share one context (or of a BSDF that
/// reads none), resolved once.
#[inline(always)]
fn single_context<B: BsdfLanes + ?Sized, L: Lanes>(
    bsdf: &B,
    ctx: &[BsdfContext],
) -> Option<(B::Params<L>, BsdfContextLanes<L>)> {
    match ctx {
        [one, ..] if ctx.len() == 1 || !B::READS_CONTEXT => {
            let ctx = BsdfContextLanes::splat(one);
            Some((bsdf.params_lanes(&ctx), ctx))
        }
        _ => None,
    }
}

/// [`Bsdf::eval_pdf_batch`](super::Bsdf::eval_pdf_batch) for a BSDF written over [`Lanes`]: four or eight pairs at a time
/// ([`with_widest_lanes`]).
#[inline(always)]
pub(super) fn eval_pdf_in_lanes<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    ctx: &[BsdfContext],
    wo: &[Vec3],
    wi: &[Vec3],
    out: &mut [(Rgb, f32)],
) {
    assert!(wi.len() == out.len(), "one result per direction");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per direction"
    );
    assert!(
        ctx.len() == 1 || ctx.len() == out.len(),
        "one context, or one per direction"
    );
    // One direction would fill a whole group of lanes (a path's deep vertices, scattered over
    // the scene's BSDFs, batch one point at a time): the one-lane formula, the same bits.
    if let ([ctx], [wo], [wi], [out]) = (ctx, wo, wi, &mut *out) {
        *out = eval_pdf_one(bsdf, ctx, *wo, *wi);
        return;
    }
    struct EvalPdf<'a, B: ?Sized> {
        bsdf: &'a B,
        ctx: &'a [BsdfContext],
        wo: &'a [Vec3],
        wi: &'a [Vec3],
        out: &'a mut [(Rgb, f32)],
    }
    impl<B: BsdfLanes + ?Sized> LaneKernel for EvalPdf<'_, B> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let EvalPdf {
                bsdf,
                ctx,
                wo,
                wi,
                out,
            } = self;
            let single = single_context::<B, L>(bsdf, ctx);
            by_groups::<W, _>(
                out,
                #[inline(always)]
                |k, out| {
                    let (params, ctx) = group_context(bsdf, &single, ctx, k);
                    let (value, pdf) = bsdf.eval_pdf_lanes::<L>(
                        &params,
                        &ctx,
                        V3::gather(wo, k, |wo| wo),
                        V3::from_fn(|i| wi[k[i]]),
                    );
                    for (i, out) in out.iter_mut().enumerate() {
                        *out = (value.lane(i), pdf.lane(i));
                    }
                },
            );
        }
    }
    with_widest_lanes(EvalPdf {
        bsdf,
        ctx,
        wo,
        wi,
        out,
    });
}

/// [`Bsdf::sample_batch`](super::Bsdf::sample_batch) for a BSDF written over [`Lanes`]: four or eight samples at a time
/// ([`with_widest_lanes`]).
#[inline(always)]
pub(super) fn sample_in_lanes<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    ctx: &[BsdfContext],
    wo: &[Vec3],
    u: &[(f32, Vec2)],
    out: &mut [Option<BsdfSample>],
) {
    assert!(u.len() == out.len(), "one result per sample");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per sample"
    );
    assert!(
        ctx.len() == 1 || ctx.len() == out.len(),
        "one context, or one per sample"
    );
    // One sample: the one-lane formula, as `eval_pdf_in_lanes` for one direction.
    if let ([ctx], [wo], [(u_lobe, u)], [out]) = (ctx, wo, u, &mut *out) {
        *out = sample_one(bsdf, ctx, *wo, *u_lobe, *u);
        return;
    }
    struct Sample<'a, B: ?Sized> {
        bsdf: &'a B,
        ctx: &'a [BsdfContext],
        wo: &'a [Vec3],
        u: &'a [(f32, Vec2)],
        out: &'a mut [Option<BsdfSample>],
    }
    impl<B: BsdfLanes + ?Sized> LaneKernel for Sample<'_, B> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let Sample {
                bsdf,
                ctx,
                wo,
                u,
                out,
            } = self;
            let single = single_context::<B, L>(bsdf, ctx);
            by_groups::<W, _>(
                out,
                #[inline(always)]
                |k, out| {
                    let (params, ctx) = group_context(bsdf, &single, ctx, k);
                    let u_lobe = L::from_fn(|i| u[k[i]].0);
                    let u2 = (L::from_fn(|i| u[k[i]].1.x), L::from_fn(|i| u[k[i]].1.y));
                    let samples =
                        bsdf.sample_lanes(&params, &ctx, V3::gather(wo, k, |wo| wo), u_lobe, u2);
                    for (i, out) in out.iter_mut().enumerate() {
                        *out = samples.lane(i);
                    }
                },
            );
        }
    }
    with_widest_lanes(Sample {
        bsdf,
        ctx,
        wo,
        u,
        out,
    });
}

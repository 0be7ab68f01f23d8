//! The BSDF interface. Everything is in the local shading frame: z is the shading normal,
//! `wo` points toward the viewer, `wi` toward the light; both are unit vectors.

use crate::math::Rgb;
use crate::math::lanes::{LaneKernel, Lanes, V3, by_groups, one_or_each, with_widest_lanes};
use glam::{Vec2, Vec3};

/// Which kinds of lobes a BSDF has; integrators use it to skip work (e.g. light sampling is
/// useless for a purely delta BSDF).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BsdfFlags {
    pub diffuse: bool,
    pub glossy: bool,
    /// A Dirac lobe: `eval` and `pdf` are zero for every given direction.
    pub delta: bool,
}

/// One direction drawn by [`Bsdf::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// Density in solid angle; for a delta lobe, the discrete probability of choosing it.
    pub pdf: f32,
    /// `eval(wo, wi) / pdf` (for a delta lobe, the lobe's weight divided by its probability).
    pub weight: Rgb,
    pub delta: bool,
}

/// A reflectance model. `eval` includes the cosine foreshortening |cos θi|, so the
/// Monte Carlo weight of a sampled direction is `eval / pdf` with no further factor.
pub trait Bsdf: Send + Sync {
    /// f(wo, wi) · |cos θi|.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb;
    /// Solid-angle density with which `sample` draws `wi` (zero for delta lobes).
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;
    /// `eval` and `pdf` of one pair of directions, bit for bit as the two calls give them. The
    /// default makes the two calls; a BSDF whose value and density share work (a microfacet
    /// lobe's D(h) and Λ(ωo)) computes it once, as Mitsuba's `eval_pdf` does. Light sampling
    /// needs both for every unoccluded sample, and so does [`sample_from_pdf`].
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        (self.eval(wo, wi), self.pdf(wo, wi))
    }
    /// Draws a direction; `u_lobe` chooses among lobes, `u` places the direction in it.
    fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample>;
    fn flags(&self) -> BsdfFlags;

    /// [`eval_pdf`](Self::eval_pdf) of each pair `(wo[k], wi[k])`, into `out[k]`: the many
    /// samples of one shading point (then `wo` may hold their one ωo), or one sample each of
    /// several camera samples, at once. `wi` is as long as `out`, `wo` too or of length 1. The
    /// default calls `eval_pdf` for each; a BSDF whose formulas are written over [`Lanes`]
    /// evaluates four at a time, bit for bit as `eval_pdf`.
    fn eval_pdf_batch(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [(Rgb, f32)]) {
        assert!(wi.len() == out.len(), "one result per direction");
        for (k, (wi, out)) in wi.iter().zip(out).enumerate() {
            *out = self.eval_pdf(one_or_each(wo, k), *wi);
        }
    }

    /// [`sample`](Self::sample) for each `wo[k]` and `u[k] = (u_lobe, u)`, into `out[k]`. `u`
    /// is as long as `out`, `wo` too or of length 1 (one shading point). The default calls
    /// `sample` for each; an override must give what `sample` gives, bit for bit.
    fn sample_batch(&self, wo: &[Vec3], u: &[(f32, Vec2)], out: &mut [Option<BsdfSample>]) {
        assert!(u.len() == out.len(), "one result per sample");
        for (k, (&(u_lobe, u), out)) in u.iter().zip(out).enumerate() {
            *out = self.sample(one_or_each(wo, k), u_lobe, u);
        }
    }
}

/// Samples of a BSDF written over [`Lanes`]: one per lane, `valid` where the lane drew one.
pub struct BsdfSampleLanes<L: Lanes> {
    pub valid: L::Mask,
    pub wi: V3<L>,
    pub pdf: L,
    pub weight: V3<L>,
}

impl<L: Lanes> BsdfSampleLanes<L> {
    /// [`sample_from_pdf`] in each lane: directions `wi`, drawn where `drawn` is set, whose
    /// `eval_pdf` is `(value, pdf)`.
    #[inline(always)]
    pub fn from_pdf(drawn: L::Mask, wi: V3<L>, (value, pdf): (V3<L>, L)) -> Self {
        let zero = L::splat(0.0);
        let weight = value / pdf;
        let valid = drawn
            & wi.z.gt(zero)
            & wi.is_finite()
            & pdf.gt(zero)
            & pdf.is_finite()
            & weight.is_finite();
        BsdfSampleLanes {
            valid,
            wi,
            pdf,
            weight,
        }
    }

    /// Lane `i`'s sample, if it drew one.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Option<BsdfSample> {
        use crate::math::lanes::Mask;
        self.valid.lane(i).then(|| BsdfSample {
            wi: self.wi.lane(i),
            pdf: self.pdf.lane(i),
            weight: self.weight.lane(i),
            delta: false,
        })
    }
}

/// The sample of a direction `wi` drawn by a BSDF whose `pdf` is the density it was drawn with:
/// pdf and weight eval/pdf from the BSDF itself, so they agree by construction. `None` below
/// the horizon or where the density or the weight is not a positive finite number.
pub fn sample_from_pdf<B: Bsdf + ?Sized>(bsdf: &B, wo: Vec3, wi: Vec3) -> Option<BsdfSample> {
    // `from_pdf` checks the direction too; checked first, it spares a doomed `eval_pdf`.
    if !(wi.z > 0.0 && wi.is_finite()) {
        return None;
    }
    let (value, pdf) = bsdf.eval_pdf(wo, wi);
    BsdfSampleLanes::<f32>::from_pdf(true, V3::splat(wi), (V3::splat(value), pdf)).lane(0)
}

/// A BSDF whose `eval_pdf` and `sample` are written over [`Lanes`], once for the scalar methods
/// (`f32`) and the batch ones: [`eval_pdf_in_lanes`] and [`sample_in_lanes`] run them as its
/// [`Bsdf::eval_pdf_batch`] and [`Bsdf::sample_batch`], as many lanes wide as the processor
/// has.
pub trait BsdfLanes {
    /// `eval_pdf(wo, wi)` in each lane.
    fn eval_pdf_lanes<L: Lanes>(&self, wo: V3<L>, wi: V3<L>) -> (V3<L>, L);
    /// `sample(wo, u_lobe, (u0, u1))` in each lane.
    fn sample_lanes<L: Lanes>(&self, wo: V3<L>, u_lobe: L, u: (L, L)) -> BsdfSampleLanes<L>;
}

/// [`Bsdf::eval_pdf_batch`] for a BSDF written over [`Lanes`]: four or eight pairs at a time
/// ([`with_widest_lanes`]).
#[inline(always)]
pub fn eval_pdf_in_lanes<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    wo: &[Vec3],
    wi: &[Vec3],
    out: &mut [(Rgb, f32)],
) {
    assert!(wi.len() == out.len(), "one result per direction");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per direction"
    );
    struct EvalPdf<'a, B: ?Sized> {
        bsdf: &'a B,
        wo: &'a [Vec3],
        wi: &'a [Vec3],
        out: &'a mut [(Rgb, f32)],
    }
    impl<B: BsdfLanes + ?Sized> LaneKernel for EvalPdf<'_, B> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let EvalPdf { bsdf, wo, wi, out } = self;
            by_groups::<W, _>(
                out,
                #[inline(always)]
                |k, out| {
                    let (value, pdf) = bsdf
                        .eval_pdf_lanes::<L>(V3::gather(wo, k, |wo| wo), V3::from_fn(|i| wi[k[i]]));
                    for (i, out) in out.iter_mut().enumerate() {
                        *out = (value.lane(i), pdf.lane(i));
                    }
                },
            );
        }
    }
    with_widest_lanes(EvalPdf { bsdf, wo, wi, out });
}

/// [`Bsdf::sample_batch`] for a BSDF written over [`Lanes`]: four or eight samples at a time
/// ([`with_widest_lanes`]).
#[inline(always)]
pub fn sample_in_lanes<B: BsdfLanes + ?Sized>(
    bsdf: &B,
    wo: &[Vec3],
    u: &[(f32, Vec2)],
    out: &mut [Option<BsdfSample>],
) {
    assert!(u.len() == out.len(), "one result per sample");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per sample"
    );
    struct Sample<'a, B: ?Sized> {
        bsdf: &'a B,
        wo: &'a [Vec3],
        u: &'a [(f32, Vec2)],
        out: &'a mut [Option<BsdfSample>],
    }
    impl<B: BsdfLanes + ?Sized> LaneKernel for Sample<'_, B> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let Sample { bsdf, wo, u, out } = self;
            by_groups::<W, _>(
                out,
                #[inline(always)]
                |k, out| {
                    let u_lobe = L::from_fn(|i| u[k[i]].0);
                    let u2 = (L::from_fn(|i| u[k[i]].1.x), L::from_fn(|i| u[k[i]].1.y));
                    let samples = bsdf.sample_lanes(V3::gather(wo, k, |wo| wo), u_lobe, u2);
                    for (i, out) in out.iter_mut().enumerate() {
                        *out = samples.lane(i);
                    }
                },
            );
        }
    }
    with_widest_lanes(Sample { bsdf, wo, u, out });
}

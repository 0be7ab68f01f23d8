//! The BSDF interface. Everything is in the local shading frame: z is the shading normal,
//! `wo` points toward the viewer, `wi` toward the light; both are unit vectors.

use crate::math::Rgb;
use crate::math::lanes::{Lanes, V3, by_fours, one_or_each};
use glam::{Vec2, Vec3, Vec4};

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

/// [`Bsdf::eval_pdf_batch`] for a BSDF whose `eval_pdf` is written over [`Lanes`]
/// (`eval_pdf(wo, wi)`): four pairs at a time.
#[inline(always)]
pub fn eval_pdf_by_fours(
    wo: &[Vec3],
    wi: &[Vec3],
    out: &mut [(Rgb, f32)],
    eval_pdf: impl Fn(V3<Vec4>, V3<Vec4>) -> (V3<Vec4>, Vec4),
) {
    assert!(wi.len() == out.len(), "one result per direction");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per direction"
    );
    by_fours(out, |k, out| {
        let (value, pdf) = eval_pdf(V3::gather(wo, k, |wo| wo), V3::from_fn(|i| wi[k[i]]));
        for (i, out) in out.iter_mut().enumerate() {
            *out = (value.lane(i), pdf[i]);
        }
    });
}

/// [`Bsdf::sample_batch`] for a BSDF whose `sample` is written over [`Lanes`]
/// (`sample(wo, u_lobe, (u0, u1))`): four samples at a time.
#[inline(always)]
pub fn sample_by_fours(
    wo: &[Vec3],
    u: &[(f32, Vec2)],
    out: &mut [Option<BsdfSample>],
    sample: impl Fn(V3<Vec4>, Vec4, (Vec4, Vec4)) -> BsdfSampleLanes<Vec4>,
) {
    assert!(u.len() == out.len(), "one result per sample");
    assert!(
        wo.len() == 1 || wo.len() == out.len(),
        "one ωo, or one per sample"
    );
    by_fours(out, |k, out| {
        let u_lobe = Vec4::from_fn(|i| u[k[i]].0);
        let u2 = (
            Vec4::from_fn(|i| u[k[i]].1.x),
            Vec4::from_fn(|i| u[k[i]].1.y),
        );
        let samples = sample(V3::gather(wo, k, |wo| wo), u_lobe, u2);
        for (i, out) in out.iter_mut().enumerate() {
            *out = samples.lane(i);
        }
    });
}

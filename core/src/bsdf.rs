//! The BSDF interface (plugin API version 4). Everything is in the local shading frame: z is the
//! shading normal turned toward the viewer, `wo` points toward the viewer, `wi` toward the
//! light; both are unit vectors. Each method is also given the shading point's
//! [`BsdfContext`]: its texture coordinates and the side of the surface the viewer is on.
//!
//! Transport is radiance only (lumis traces from the camera): `eval` is the BSDF of radiance
//! transport, f(wo, wi) · |cos θi|, and a transmissive BSDF includes in it, and in its samples'
//! weights, the factor 1/η² of radiance crossing an interface (η = η_i / η_o, the index of
//! refraction on wi's side over wo's), as Mitsuba 3 does in its radiance mode. Such an `eval`
//! is not symmetric: it satisfies f(wo, wi) / η_o² = f(wi, wo) / η_i² (Veach 1997, §5.2), the
//! form the reciprocity tests of transmissive BSDFs check.
//!
//! [`lanes`](self::lanes) holds the form of the interface written over
//! [`Lanes`](crate::math::lanes::Lanes) ([`BsdfLanes`]): one formula for one sample or for
//! several, at one shading point or at several.

mod context;
mod flags;
mod lanes;
mod sample;

pub use context::{BsdfContext, Side};
pub use flags::BsdfFlags;
pub use lanes::{BsdfContextLanes, BsdfLanes, BsdfSampleLanes};
pub use sample::BsdfSample;

use lanes::{eval_pdf_in_lanes, eval_pdf_one, sample_in_lanes, sample_one};

use crate::math::Rgb;
use crate::math::lanes::one_or_each;
use glam::{Vec2, Vec3};

/// A scattering model: reflection, and transmission where its flags say so.
///
/// `eval` includes the cosine foreshortening |cos θi|, so the Monte Carlo weight of a sampled
/// direction is `eval / pdf` with no further factor. Each method is given the shading point's
/// [`BsdfContext`]; a BSDF with textured parameters reads their values at `ctx.uv`.
///
/// Directions: `wo.z > 0` for a viewer above the shading normal (it can be ≤ 0 where the
/// shading normal bends away from the geometric one: the BSDF then returns zero, or handles it
/// as it sees fit). A reflecting BSDF returns zero for `wi.z ≤ 0`; a transmitting one (with a
/// `*_TRANSMISSION` flag) is evaluated and sampled on both sides. The shading point discards a
/// direction whose side of the geometric surface disagrees with its local `wi.z` (shading
/// normals would otherwise leak light), so a BSDF need not check that.
///
/// Sidedness is not a BSDF's business: a BSDF is evaluated the same from both sides (the frame
/// turned toward the viewer). A scene makes a BSDF one-sided (black seen from behind) with the
/// `one_sided` key of its `bsdfs` entry, which the shading point applies (it shades the back of
/// such a surface with [`Absorber`]); a BSDF that differs by side (Mitsuba's `twosided` with a
/// front and a back BSDF, a dielectric) reads [`BsdfContext::side`].
pub trait Bsdf: Send + Sync {
    /// f(wo, wi) · |cos θi|.
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb;
    /// Solid-angle density with which `sample` draws `wi` (zero for delta lobes).
    fn pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32;
    /// `eval` and `pdf` of one pair of directions, bit for bit as the two calls give them. The
    /// default makes the two calls; a BSDF whose value and density share work (a microfacet
    /// lobe's D(h) and Λ(ωo)) computes it once, as Mitsuba's `eval_pdf` does. Light sampling
    /// needs both for every unoccluded sample, and so does [`sample_from_pdf`].
    fn eval_pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        (self.eval(ctx, wo, wi), self.pdf(ctx, wo, wi))
    }
    /// Draws a direction; `u_lobe` chooses among lobes, `u` places the direction in it.
    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample>;
    /// The lobes, and [`BsdfFlags::SPATIALLY_VARYING`] for a BSDF that reads `ctx.uv`.
    fn flags(&self) -> BsdfFlags;

    /// [`eval_pdf`](Self::eval_pdf) of each pair `(wo[k], wi[k])` at `ctx[k]`, into `out[k]`:
    /// the many samples of one shading point (then `ctx` and `wo` may hold their one context
    /// and ωo), or the samples of several points at once. `wi` is as long as `out`; `ctx` and
    /// `wo` too, or of length 1. The default calls `eval_pdf` for each; a BSDF whose formulas
    /// are written over [`Lanes`](crate::math::lanes::Lanes) ([`BsdfLanes`]) evaluates four
    /// or eight at a time, bit for bit as `eval_pdf`.
    fn eval_pdf_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        wi: &[Vec3],
        out: &mut [(Rgb, f32)],
    ) {
        assert!(wi.len() == out.len(), "one result per direction");
        for (k, (wi, out)) in wi.iter().zip(out).enumerate() {
            *out = self.eval_pdf(&one_or_each(ctx, k), one_or_each(wo, k), *wi);
        }
    }

    /// [`sample`](Self::sample) for each `ctx[k]`, `wo[k]` and `u[k] = (u_lobe, u)`, into
    /// `out[k]`. `u` is as long as `out`; `ctx` and `wo` too, or of length 1 (one shading
    /// point). The default calls `sample` for each; an override must give what `sample`
    /// gives, bit for bit.
    fn sample_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        u: &[(f32, Vec2)],
        out: &mut [Option<BsdfSample>],
    ) {
        assert!(u.len() == out.len(), "one result per sample");
        for (k, (&(u_lobe, u), out)) in u.iter().zip(out).enumerate() {
            *out = self.sample(&one_or_each(ctx, k), one_or_each(wo, k), u_lobe, u);
        }
    }
}

/// The [`Bsdf`] of every BSDF written over [`Lanes`](crate::math::lanes::Lanes)
/// ([`BsdfLanes`]): `eval`, `pdf` and `eval_pdf` are its `eval_pdf` formula on one lane (the
/// part a method does not return is dead code the compiler removes), `sample` its `sample`
/// formula, and the batches run both four or eight lanes wide (`bsdf/lanes.rs`).
impl<B: BsdfLanes> Bsdf for B {
    #[inline]
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        eval_pdf_one(self, ctx, wo, wi).0
    }

    #[inline]
    fn pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        eval_pdf_one(self, ctx, wo, wi).1
    }

    #[inline]
    fn eval_pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        eval_pdf_one(self, ctx, wo, wi)
    }

    #[inline]
    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        sample_one(self, ctx, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        self.bsdf_flags()
    }

    fn eval_pdf_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        wi: &[Vec3],
        out: &mut [(Rgb, f32)],
    ) {
        eval_pdf_in_lanes(self, ctx, wo, wi, out);
    }

    fn sample_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        u: &[(f32, Vec2)],
        out: &mut [Option<BsdfSample>],
    ) {
        sample_in_lanes(self, ctx, wo, u, out);
    }
}

/// The sample of a direction `wi` drawn by a BSDF whose `pdf` is the density it was drawn with:
/// pdf and weight eval/pdf from the BSDF itself, so they agree by construction. `None` on the
/// horizon (`wi.z = 0`) or where the density or the weight is not a positive finite number.
pub fn sample_from_pdf<B: Bsdf + ?Sized>(
    bsdf: &B,
    ctx: &BsdfContext,
    wo: Vec3,
    wi: Vec3,
) -> Option<BsdfSample> {
    use crate::math::lanes::V3;
    // `from_pdf` checks the direction too; checked first, it spares a doomed `eval_pdf`.
    if wi.z == 0.0 || !wi.is_finite() {
        return None;
    }
    let (value, pdf) = bsdf.eval_pdf(ctx, wo, wi);
    BsdfSampleLanes::<f32>::from_pdf(true, V3::splat(wi), (V3::splat(value), pdf)).lane(0)
}

/// The surface that scatters nothing: what a shading point sees of a one-sided BSDF from
/// behind (Mitsuba's default for its reflecting BSDFs). Its flags are [`BsdfFlags::NONE`].
pub struct Absorber;

impl Bsdf for Absorber {
    fn eval(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    fn sample(&self, _ctx: &BsdfContext, _wo: Vec3, _u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        None
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags::NONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_combine_and_answer_by_kind() {
        let glass = BsdfFlags::DELTA_REFLECTION | BsdfFlags::DELTA_TRANSMISSION;
        assert!(glass.is_pure_delta() && glass.transmission() && glass.reflection());
        assert!(!glass.diffuse() && !glass.glossy() && !glass.is_black());
        let plastic = BsdfFlags::DELTA_REFLECTION | BsdfFlags::DIFFUSE_REFLECTION;
        assert!(plastic.delta() && !plastic.is_pure_delta() && !plastic.transmission());
        assert!(BsdfFlags::NONE.is_black() && !BsdfFlags::NONE.is_pure_delta());
        let textured = BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::SPATIALLY_VARYING;
        assert!(textured.spatially_varying() && textured.contains(BsdfFlags::DIFFUSE_REFLECTION));
        assert!(BsdfFlags::SPATIALLY_VARYING.is_black());
        assert_eq!(
            textured & BsdfFlags::REFLECTION,
            BsdfFlags::DIFFUSE_REFLECTION
        );
    }

    #[test]
    fn samples_know_their_side_and_eta() {
        let up = BsdfSample::new(Vec3::Z, 0.3, Rgb::ONE);
        assert!(!up.transmission() && !up.delta && up.eta == 1.0);
        let through = BsdfSample::delta(-Vec3::Z, 0.5, Rgb::ONE).with_eta(1.5);
        assert!(through.transmission() && through.delta && through.eta == 1.5);
        assert_eq!(BsdfContext::default(), BsdfContext::FRONT);
        assert_eq!(
            BsdfContext::BACK.with_uv(Vec2::X),
            BsdfContext::new(Vec2::X, Side::Back)
        );
    }

    /// `sample_from_pdf` accepts a transmitted direction where the density is positive, and
    /// refuses the horizon.
    #[test]
    fn samples_from_the_pdf_may_transmit() {
        struct Uniform;
        impl Bsdf for Uniform {
            fn eval(&self, _: &BsdfContext, _: Vec3, wi: Vec3) -> Rgb {
                Rgb::splat(wi.z.abs() / (4.0 * std::f32::consts::PI))
            }
            fn pdf(&self, _: &BsdfContext, _: Vec3, _: Vec3) -> f32 {
                1.0 / (4.0 * std::f32::consts::PI)
            }
            fn sample(&self, _: &BsdfContext, _: Vec3, _: f32, _: Vec2) -> Option<BsdfSample> {
                None
            }
            fn flags(&self) -> BsdfFlags {
                BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::DIFFUSE_TRANSMISSION
            }
        }
        let ctx = BsdfContext::FRONT;
        let down = Vec3::new(0.6, 0.0, -0.8);
        let s = sample_from_pdf(&Uniform, &ctx, Vec3::Z, down).expect("a sample");
        assert!(s.transmission() && s.eta == 1.0 && (s.weight.x - 0.8).abs() < 1e-6);
        assert!(sample_from_pdf(&Uniform, &ctx, Vec3::Z, Vec3::X).is_none());
        assert!(
            Absorber.flags().is_black()
                && Absorber.sample(&ctx, Vec3::Z, 0.5, Vec2::ZERO).is_none()
        );
    }
}

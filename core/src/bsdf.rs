//! The BSDF interface. Everything is in the local shading frame: z is the shading normal,
//! `wo` points toward the viewer, `wi` toward the light; both are unit vectors.

use crate::math::Rgb;
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
}

/// The sample of a direction `wi` drawn by a BSDF whose `pdf` is the density it was drawn with:
/// pdf and weight eval/pdf from the BSDF itself, so they agree by construction. `None` below
/// the horizon or where the density or the weight is not a positive finite number.
pub fn sample_from_pdf<B: Bsdf + ?Sized>(bsdf: &B, wo: Vec3, wi: Vec3) -> Option<BsdfSample> {
    if !(wi.z > 0.0 && wi.is_finite()) {
        return None;
    }
    let (value, pdf) = bsdf.eval_pdf(wo, wi);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    let weight = value / pdf;
    weight.is_finite().then_some(BsdfSample {
        wi,
        pdf,
        weight,
        delta: false,
    })
}

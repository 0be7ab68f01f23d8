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
    /// Draws a direction; `u_lobe` chooses among lobes, `u` places the direction in it.
    fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample>;
    fn flags(&self) -> BsdfFlags;
}

/// cos θ of a direction in the local shading frame.
#[inline]
pub fn cos_theta(w: Vec3) -> f32 {
    w.z
}

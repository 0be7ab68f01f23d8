//! What a BSDF's `sample` returns.

use crate::math::Rgb;
use glam::Vec3;

/// One direction drawn by [`Bsdf::sample`](super::Bsdf::sample). Built with [`BsdfSample::new`] or
/// [`BsdfSample::delta`] (then [`with_eta`](BsdfSample::with_eta) for a refraction): fields
/// may be added in later versions of the interface.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct BsdfSample {
    pub wi: Vec3,
    /// Density in solid angle; for a delta lobe, the discrete probability of choosing it.
    pub pdf: f32,
    /// `eval(wo, wi) / pdf` (for a delta lobe, the lobe's weight divided by its probability),
    /// the 1/η² of radiance transport included for a refraction.
    pub weight: Rgb,
    /// Drawn from a Dirac lobe: `eval` and `pdf` are zero in its direction.
    pub delta: bool,
    /// The relative index of refraction of the sampled interaction, η = η_i / η_o (the index on
    /// wi's side over wo's): 1 for a reflection, and for a transmission that does not bend
    /// (a thin sheet). A path tracer keeps the product of these for its Russian roulette, as
    /// Mitsuba's `path` does.
    pub eta: f32,
}

impl BsdfSample {
    /// A sample of a lobe that has a density: `pdf` in solid angle, `weight` = eval / pdf,
    /// η = 1.
    #[inline(always)]
    pub fn new(wi: Vec3, pdf: f32, weight: Rgb) -> Self {
        BsdfSample {
            wi,
            pdf,
            weight,
            delta: false,
            eta: 1.0,
        }
    }

    /// A sample of a Dirac lobe chosen with probability `probability`, of weight `weight`
    /// (the lobe's weight over `probability`), η = 1.
    #[inline(always)]
    pub fn delta(wi: Vec3, probability: f32, weight: Rgb) -> Self {
        BsdfSample {
            delta: true,
            ..BsdfSample::new(wi, probability, weight)
        }
    }

    /// The sample with relative index of refraction `eta` (η_i / η_o).
    #[inline(always)]
    pub fn with_eta(self, eta: f32) -> Self {
        BsdfSample { eta, ..self }
    }

    /// Whether `wi` crossed the surface: it is on the far side from the viewer (`wi.z < 0` in
    /// the frame turned toward the viewer), a sample of a transmission lobe.
    #[inline(always)]
    pub fn transmission(&self) -> bool {
        self.wi.z < 0.0
    }
}

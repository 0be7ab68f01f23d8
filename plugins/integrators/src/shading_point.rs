//! [`ShadingPoint`]: a surface point seen by the camera, where the estimator
//! ([`crate::estimator`]) draws each light's samples.

use glam::Vec3;
use lumis_core::bsdf::Bsdf;
use lumis_core::emitter::EmitterSample;
use lumis_core::geometry::{Intersection, RayOrigin};
use lumis_core::math::{Frame, Rgb};
use lumis_core::scene::Scene;

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
    pub(crate) fn reflects_toward(&self, wi_world: Vec3) -> bool {
        self.normal.dot(wi_world) > 0.0
    }

    /// Whether a sample of light `light` is unoccluded: a shadow ray to its point, or to
    /// infinity.
    pub(crate) fn sees(&self, scene: &Scene, light: usize, sample: &EmitterSample) -> bool {
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
    pub(crate) fn reflects_toward_sample(&self, sample: &EmitterSample) -> bool {
        let height = self.normal.dot(sample.wi);
        // The distance (a square root) only where the sample is on the viewer's side.
        height > 0.0
            && !sample
                .position
                .is_some_and(|p| height * (p - self.hit.position).length() <= self.plane_error)
    }

    /// BSDF value (with cosine) toward a light sample, zero when it cannot reflect there.
    pub(crate) fn eval_toward(&self, sample: &EmitterSample) -> Rgb {
        if !self.reflects_toward_sample(sample) {
            return Rgb::ZERO;
        }
        self.bsdf.eval(self.wo, self.frame.to_local(sample.wi))
    }
}

//! [`ShadingPoint`]: a surface point seen by the camera, where the estimator
//! ([`crate::estimator`]) draws each light's samples.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, Side};
use lumis_core::emitter::EmitterSample;
use lumis_core::geometry::{Intersection, RayOrigin};
use lumis_core::math::{Frame, Rgb};
use lumis_core::scene::Scene;

/// A surface point seen by the camera, with its shading frame turned toward the viewer
/// whichever side of the surface it is on, and the BSDF seen from that side (the absorber from
/// behind a one-sided BSDF).
pub struct ShadingPoint<'a> {
    pub hit: Intersection,
    pub frame: Frame,
    /// Geometric normal on the viewer's side.
    pub normal: Vec3,
    /// ωo in the local shading frame.
    pub wo: Vec3,
    pub bsdf: &'a dyn Bsdf,
    /// The BSDF's flags, as the scene records them.
    pub flags: BsdfFlags,
    /// What the BSDF is told of the point: its texture coordinates (computed only for a BSDF
    /// that varies over the surface) and the side the viewer is on.
    pub ctx: BsdfContext,
    /// Where its shadow and BSDF rays start (those on the viewer's side; a ray toward the far
    /// side, transmitted, gets its own origin there).
    pub origin: RayOrigin,
    /// The rounding error of the point across its surface's plane, |n| · error.
    plane_error: f32,
}

impl<'a> ShadingPoint<'a> {
    /// The shading point of `hit`, seen from `wo_world`. Inlined, so that it is built where it
    /// is kept: built apart, it was copied there, and the copy read it back in 64-byte pieces
    /// just after its narrower stores, waiting for them to reach the cache. `hit` is borrowed
    /// for the same reason: taken by value, its 60 bytes were first copied to the stack with
    /// overlapping stores and its normal read back across two of them, a wait that stood under
    /// the hottest instruction of `MisIntegrator::shade_together` in a profile.
    #[inline(always)]
    pub fn new(scene: &'a Scene, hit: &Intersection, wo_world: Vec3) -> Self {
        let flip = hit.geometric_normal.dot(wo_world) < 0.0;
        let (sign, side) = if flip {
            (-1.0, Side::Back)
        } else {
            (1.0, Side::Front)
        };
        let frame = Frame::from_normal(sign * hit.shading_normal);
        let (bsdf, flags) = scene.bsdf_seen_from(hit, side);
        let uv = if flags.spatially_varying() {
            scene.geometry.uv(hit)
        } else {
            Vec2::ZERO
        };
        ShadingPoint {
            frame,
            normal: sign * hit.geometric_normal,
            wo: frame.to_local(wo_world),
            bsdf,
            flags,
            ctx: BsdfContext::new(uv, side),
            origin: RayOrigin::toward(hit, wo_world),
            plane_error: hit.geometric_normal.abs().dot(hit.error),
            hit: *hit,
        }
    }

    /// Whether the BSDF is a Dirac lobe only (a mirror), which light sampling can never reach.
    pub fn is_pure_delta(&self) -> bool {
        self.flags.is_pure_delta()
    }

    /// Whether a direction ωi the BSDF sampled (`wi_world`, and `wi_local` in the shading
    /// frame) leaves on the side of the geometric surface its local z says: the viewer's for a
    /// reflection (`wi_local.z > 0`), the far one for a transmission. Otherwise shading normals
    /// would let light leak through the surface (or a transmission turn back). `TRANSMITS`
    /// must be the BSDF's [`BsdfFlags::transmission`]: a BSDF that only reflects samples no
    /// direction below its horizon, and is checked with today's one comparison.
    #[inline(always)]
    pub(crate) fn leaves_toward<const TRANSMITS: bool>(
        &self,
        wi_world: Vec3,
        wi_local: Vec3,
    ) -> bool {
        let height = self.normal.dot(wi_world);
        if !TRANSMITS || wi_local.z > 0.0 {
            height > 0.0
        } else {
            height < 0.0
        }
    }

    /// Whether a sample of light `light` is unoccluded: a shadow ray to its point, or to
    /// infinity (from the far side's origin for a light behind a transmitting surface).
    pub(crate) fn sees(&self, scene: &Scene, light: usize, sample: &EmitterSample) -> bool {
        let ray = match sample.position {
            Some(target) => self.origin.ray_to(&self.hit, target),
            None => self.origin.ray(&self.hit, sample.wi),
        };
        !scene.occluded_toward_light(&ray, &self.hit, light)
    }

    /// Whether the surface can scatter light from a light sample toward the viewer: ωi on the
    /// viewer's side of the geometric surface, or, for a BSDF that transmits (`TRANSMITS`, its
    /// [`BsdfFlags::transmission`]), on either side that its local z (`wi_local_z`) agrees
    /// with. A light point closer to the surface's plane than the rounding error of the shading
    /// point (a light lying on the surface) is on no definite side of it, and lights nothing.
    #[inline(always)]
    pub(crate) fn scatters_from_sample<const TRANSMITS: bool>(
        &self,
        sample: &EmitterSample,
        wi_local_z: f32,
    ) -> bool {
        let height = self.normal.dot(sample.wi);
        let (facing, distance_from_plane) = if TRANSMITS {
            let agree = (height > 0.0 && wi_local_z > 0.0) || (height < 0.0 && wi_local_z < 0.0);
            (agree, height.abs())
        } else {
            (height > 0.0, height)
        };
        // Squared (both sides are non-negative): no square root's latency on the light records'
        // loop, where a profile found it under the hottest instruction.
        facing
            && !sample.position.is_some_and(|p| {
                let distance_squared = (p - self.hit.position).length_squared();
                distance_from_plane * distance_from_plane * distance_squared
                    <= self.plane_error * self.plane_error
            })
    }

    /// BSDF value (with cosine) toward a light sample, zero when it cannot scatter from there.
    pub(crate) fn eval_toward(&self, sample: &EmitterSample) -> Rgb {
        let wi = self.frame.to_local(sample.wi);
        let scatters = if self.flags.transmission() {
            self.scatters_from_sample::<true>(sample, wi.z)
        } else {
            self.scatters_from_sample::<false>(sample, wi.z)
        };
        if !scatters {
            return Rgb::ZERO;
        }
        self.bsdf.eval(&self.ctx, self.wo, wi)
    }
}

//! The emitter interface: light sources, sampled in solid angle from a reference point.

use crate::geometry::ShapeGeometry;
use crate::math::Rgb;
use crate::math::lanes::{LaneKernel, Lanes, Mask, V3, by_groups, one_or_each, with_widest_lanes};
use glam::{Vec2, Vec3};

/// The point being lit.
#[derive(Clone, Copy, Debug)]
pub struct ReferencePoint {
    pub position: Vec3,
}

/// A point on an emitter that a ray hit.
#[derive(Clone, Copy, Debug)]
pub struct EmitterHit {
    pub position: Vec3,
    /// Geometric normal of the emitting surface (unit, as the shape orients it).
    pub normal: Vec3,
    pub distance: f32,
}

/// One direction toward an emitter drawn by [`Emitter::sample_direction`].
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample {
    /// Unit direction from the reference point toward the emitter.
    pub wi: Vec3,
    /// The sampled point on the emitter, for the shadow ray (`None`: infinitely far, as for
    /// directional lights and environments; the shadow ray then goes to infinity).
    pub position: Option<Vec3>,
    /// Density in solid angle; 1 for delta emitters.
    pub pdf: f32,
    /// Radiance arriving along `-wi` (for delta emitters: intensity / distance² or irradiance).
    pub radiance: Rgb,
}

/// A light source.
pub trait Emitter: Send + Sync {
    fn sample_direction(&self, reference: &ReferencePoint, u: Vec2) -> Option<EmitterSample>;
    /// [`sample_direction`](Self::sample_direction) from each `reference[k]` with `u[k]`, into
    /// `out[k]`: the many samples of one shading point (then `reference` may hold its one
    /// point), or one sample each of several camera samples, at once. `u` is as long as `out`,
    /// `reference` too or of length 1. The default calls `sample_direction` for each; an
    /// override (an emitter whose formulas are written over [`crate::math::lanes::Lanes`])
    /// must give what it gives, bit for bit.
    fn sample_direction_batch(
        &self,
        reference: &[ReferencePoint],
        u: &[Vec2],
        out: &mut [Option<EmitterSample>],
    ) {
        assert!(u.len() == out.len(), "one result per sample");
        for (k, (u, out)) in u.iter().zip(out).enumerate() {
            *out = self.sample_direction(&one_or_each(reference, k), *u);
        }
    }
    /// The density `sample_direction` has of producing `wi`, which reaches the emitter at `hit`
    /// (`None` for rays that escape the scene, as for an environment map).
    fn pdf_direction(&self, reference: &ReferencePoint, wi: Vec3, hit: Option<&EmitterHit>) -> f32;
    /// Radiance emitted toward the reference point along `-wi`.
    fn eval(&self, wi: Vec3, hit: Option<&EmitterHit>) -> Rgb;
    /// `eval` and `pdf_direction` of one direction, bit for bit as the two calls give them. The
    /// default makes the two calls; an emitter whose two share work (an environment map's
    /// conversion of the direction to map coordinates) overrides it.
    fn eval_pdf(
        &self,
        reference: &ReferencePoint,
        wi: Vec3,
        hit: Option<&EmitterHit>,
    ) -> (Rgb, f32) {
        (self.eval(wi, hit), self.pdf_direction(reference, wi, hit))
    }
    /// [`eval_pdf`](Self::eval_pdf) of each direction `wi[k]` from `reference[k]` toward no
    /// surface of the emitter (`hit` `None`: rays that escape the scene, toward an
    /// environment), into `out[k]`: the BSDF samples of several shading points that reached the
    /// environment, at once. `out` is as long as `wi`, `reference` too or of length 1. The
    /// default calls `eval_pdf` for each; an override must give what it gives, bit for bit.
    fn eval_pdf_batch(&self, reference: &[ReferencePoint], wi: &[Vec3], out: &mut [(Rgb, f32)]) {
        assert!(wi.len() == out.len(), "one result per direction");
        for (k, (wi, out)) in wi.iter().zip(out).enumerate() {
            *out = self.eval_pdf(&one_or_each(reference, k), *wi, None);
        }
    }
    /// A hint that `eval` and `pdf_direction` of `wi` (a ray that may escape the scene) will
    /// follow once the ray is traced: an emitter whose lookup reads a large table starts the
    /// read now, so that it overlaps the traversal. The default does nothing.
    fn prefetch(&self, _wi: Vec3) {}
    /// A hint that `sample_direction` with the numbers `u()` gives will follow after other
    /// work: an emitter whose sampling reads a large table at a place they decide starts the
    /// read now. `u` computes the numbers (ahead of the stream), so an emitter with nothing to
    /// prefetch, the default, costs nothing.
    fn prefetch_sample(&self, _u: &dyn Fn() -> Vec2) {}
    /// Point and directional lights: reached only by their own samples.
    fn is_delta(&self) -> bool;
    /// Whether the shape the emitter is attached to can never block a shadow ray toward one of
    /// its samples: every sample lies on a part of the shape that the reference point sees past
    /// the rest of it (a sphere sampled in the cone it subtends, a planar shape). Shadow rays
    /// toward the samples then skip that shape's primitives, which their rays would otherwise
    /// test every time, since each ray ends on the shape. The default, false, is always safe: an
    /// emitter that samples a sphere's far side by area relies on the shadow ray to reject it.
    fn own_shape_never_blocks_samples(&self) -> bool {
        false
    }
    /// An environment: reached by rays that leave the scene (`hit` is then `None`).
    fn is_environment(&self) -> bool {
        false
    }
}

/// Samples of an emitter at a finite distance written over [`Lanes`]: one per lane, `valid`
/// where the lane drew one.
pub struct EmitterSampleLanes<L: Lanes> {
    pub valid: L::Mask,
    pub wi: V3<L>,
    pub position: V3<L>,
    pub pdf: L,
}

impl<L: Lanes> EmitterSampleLanes<L> {
    /// Lane `i`'s sample, if it drew one, arriving with `radiance`.
    #[inline(always)]
    pub fn lane(&self, i: usize, radiance: Rgb) -> Option<EmitterSample> {
        self.valid.lane(i).then(|| EmitterSample {
            wi: self.wi.lane(i),
            position: Some(self.position.lane(i)),
            pdf: self.pdf.lane(i),
            radiance,
        })
    }
}

/// An emitter whose `sample_direction` is written over [`Lanes`], once for the scalar method
/// (`f32`) and the batch one: [`sample_direction_in_lanes`] runs it as its
/// [`Emitter::sample_direction_batch`], as many lanes wide as the processor has.
pub trait EmitterLanes {
    /// `sample_direction(reference, (u0, u1))` in each lane.
    fn sample_lanes<L: Lanes>(&self, reference: V3<L>, u: (L, L)) -> EmitterSampleLanes<L>;
}

/// [`Emitter::sample_direction_batch`] for an emitter written over [`Lanes`] whose samples
/// arrive with `radiance`: four or eight samples at a time ([`with_widest_lanes`]).
#[inline(always)]
pub fn sample_direction_in_lanes<E: EmitterLanes + ?Sized>(
    emitter: &E,
    reference: &[ReferencePoint],
    u: &[Vec2],
    out: &mut [Option<EmitterSample>],
    radiance: Rgb,
) {
    assert!(u.len() == out.len(), "one result per sample");
    assert!(
        reference.len() == 1 || reference.len() == out.len(),
        "one reference point, or one per sample"
    );
    struct Sample<'a, E: ?Sized> {
        emitter: &'a E,
        reference: &'a [ReferencePoint],
        u: &'a [Vec2],
        out: &'a mut [Option<EmitterSample>],
        radiance: Rgb,
    }
    impl<E: EmitterLanes + ?Sized> LaneKernel for Sample<'_, E> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let Sample {
                emitter,
                reference,
                u,
                out,
                radiance,
            } = self;
            by_groups::<W, _>(
                out,
                #[inline(always)]
                |k, out| {
                    let u2 = (L::from_fn(|i| u[k[i]].x), L::from_fn(|i| u[k[i]].y));
                    let samples =
                        emitter.sample_lanes(V3::gather(reference, k, |r| r.position), u2);
                    for (i, out) in out.iter_mut().enumerate() {
                        *out = samples.lane(i, radiance);
                    }
                },
            );
        }
    }
    with_widest_lanes(Sample {
        emitter,
        reference,
        u,
        out,
        radiance,
    });
}

/// What an emitter plugin is built from besides its parameters.
pub struct EmitterContext<'a> {
    /// The shape the emitter is attached to, for area emitters.
    pub shape: Option<&'a ShapeGeometry>,
}

//! The integrator interface. Core owns the camera samples ([`crate::render`]): per pixel it
//! draws each camera sample's random stream and primary ray ([`CameraSample::new`]), asks the
//! integrator to shade it, and sums the results; the integrator shades one camera sample at a
//! time and turns a pixel's sums into its AOV values at the end ([`Integrator::resolve`]).
//!
//! Everything an integrator accumulates per pixel is a *sum* over camera samples (f64), so that
//! the samples of a pixel may be shaded in several parts (tiles, shards, sample ranges) whose
//! sums add up exactly to those of one pass; averages are formed only in `resolve`.

use crate::geometry::{Intersection, PACKET_SIZE, Ray};
use crate::math::Rgb;
use crate::output::Aov;
use crate::sampler::Sampler;
use crate::scene::Scene;
use glam::{UVec2, Vec2, Vec3};

/// One camera sample of one pixel: its random stream and its primary ray.
pub struct CameraSample {
    /// Film coordinates of the pixel.
    pub pixel: UVec2,
    /// Index of this sample among the pixel's `spp`.
    pub index: u32,
    /// The sample's random numbers, keyed by (seed, pixel, index): the same for any number of
    /// threads and any order of rendering. The film offset has already been drawn from it.
    pub sampler: Sampler,
    /// The primary ray through the (jittered) film position.
    pub ray: Ray,
    /// The reconstruction filter's weight of the film position, f/p ([`crate::filter`]): the
    /// sample's radiance counts times this in its pixel. 1 for the box and the tent, and for
    /// samples through pixel centres.
    pub weight: f32,
    /// The primary ray's closest intersection, if core traced it with other samples' rays
    /// ([`CameraSample::trace_together`]).
    traced: Option<Option<Intersection>>,
}

impl CameraSample {
    /// Camera sample `index` of `pixel`: its stream and its ray through the pixel, jittered
    /// when the scene asks for it, through the pixel's centre otherwise.
    pub fn new(scene: &Scene, pixel: UVec2, index: u32) -> Self {
        let (sampler, film, weight) = Self::stream(scene, pixel, index);
        CameraSample {
            pixel,
            index,
            sampler,
            ray: scene.camera.generate_ray(film),
            weight,
            traced: None,
        }
    }

    /// Camera samples `indices` of `pixel`, each as [`new`](Self::new) makes it, appended to
    /// `samples`: their rays are computed four at a time (`new`, one ray at a time, was 6 % of
    /// the Cornell box's instructions, its divisions and square root the hottest).
    pub fn extend_pixel(
        scene: &Scene,
        pixel: UVec2,
        indices: std::ops::Range<u32>,
        samples: &mut Vec<CameraSample>,
    ) {
        for first in indices.clone().step_by(4) {
            let count = (indices.end - first).min(4) as usize;
            // A lone sample (one a pixel, or one left after the fours) would make four streams
            // for one ray.
            if count == 1 {
                samples.push(Self::new(scene, pixel, first));
                continue;
            }
            // Each sample is pushed with its stream, its ray filled in after: moved through an
            // iterator of the four, the streams and rays were copied in bulk just after being
            // written, which waits for the stores.
            let start = samples.len();
            let mut films = [Vec2::ZERO; 4];
            for (lane, index) in (first..first + count as u32).enumerate() {
                let (sampler, film, weight) = Self::stream(scene, pixel, index);
                films[lane] = film;
                samples.push(CameraSample {
                    pixel,
                    index,
                    sampler,
                    weight,
                    // Filled in below.
                    ray: Ray {
                        origin: Vec3::ZERO,
                        direction: Vec3::ZERO,
                        t_max: 0.0,
                    },
                    traced: None,
                });
            }
            // Lanes past the last sample repeat its film; their rays are dropped.
            for lane in count..4 {
                films[lane] = films[count - 1];
            }
            let rays = scene.camera.generate_rays(films);
            for (sample, ray) in samples[start..].iter_mut().zip(rays) {
                sample.ray = ray;
            }
        }
    }

    /// Camera sample `index` of `pixel`: its stream, its film position, drawn from the
    /// scene's reconstruction filter when the scene jitters, the pixel's centre otherwise, and
    /// the position's filter weight.
    fn stream(scene: &Scene, pixel: UVec2, index: u32) -> (Sampler, Vec2, f32) {
        let pixel_index = pixel.y as u64 * scene.width as u64 + pixel.x as u64;
        let mut sampler = Sampler::new(scene.seed, pixel_index, index as u64);
        // Drawn either way, so that the rest of the stream does not depend on the jitter.
        let offset = sampler.next_2d();
        let (film, weight) = if scene.jitter {
            let size = UVec2::new(scene.width, scene.height);
            scene.filter.film_position(pixel, offset, size)
        } else {
            (pixel.as_vec2() + Vec2::splat(0.5), 1.0)
        };
        (sampler, film, weight)
    }

    /// The primary ray's closest intersection: the one [`CameraSample::trace_together`] found,
    /// or traced now.
    pub fn intersect(&self, scene: &Scene) -> Option<Intersection> {
        let mut traced_now = None;
        self.hit(scene, &mut traced_now).copied()
    }

    /// [`intersect`](Self::intersect) without a copy: the intersection
    /// [`CameraSample::trace_together`] found, in place, or the one traced now into `traced_now`.
    /// (A copy of the whole record, read back field by field just after, waits for its stores:
    /// the copy's and the reads' widths differ. That wait was 3 % of the Cornell box's time.)
    #[inline]
    pub fn hit<'a>(
        &'a self,
        scene: &Scene,
        traced_now: &'a mut Option<Intersection>,
    ) -> Option<&'a Intersection> {
        match &self.traced {
            Some(hit) => hit.as_ref(),
            None => {
                *traced_now = scene.intersect(&self.ray);
                traced_now.as_ref()
            }
        }
    }

    /// Traces the primary rays of `samples` as packets ([`Geometry::intersect_packet`]): the
    /// camera samples of one pixel and of its neighbours share the camera's origin and nearly a
    /// direction, so they visit the same nodes. Each sample keeps its hit for [`CameraSample::hit`].
    ///
    /// [`Geometry::intersect_packet`]: crate::geometry::Geometry::intersect_packet
    pub fn trace_together(scene: &Scene, samples: &mut [CameraSample]) {
        for samples in samples.chunks_mut(PACKET_SIZE) {
            let n = samples.len();
            // Written in place: an array made by `from_fn` was copied whole, through `memcpy`.
            let mut rays = [samples[n - 1].ray; PACKET_SIZE];
            for (ray, sample) in rays.iter_mut().zip(&samples[..n - 1]) {
                *ray = sample.ray;
            }
            let mut hits = [None; PACKET_SIZE];
            scene.geometry.intersect_packet(&rays[..n], &mut hits[..n]);
            for (sample, hit) in samples.iter_mut().zip(hits) {
                sample.traced = Some(hit);
            }
        }
    }
}

/// The most camera samples the render loop gives [`Integrator::shade_together`] at once (its
/// [`Integrator::wave_size`] is clamped to it): a wave of a tile's consecutive samples, traced in
/// packets of [`PACKET_SIZE`].
pub const WAVE_SIZE: usize = 128;

/// A light-transport algorithm.
pub trait Integrator: Send + Sync {
    /// Extra output layers, if this configuration asks for any (they may depend on the scene,
    /// e.g. one per light).
    fn aovs(&self, _scene: &Scene) -> Vec<Aov> {
        Vec::new()
    }

    /// How many f64 sums per pixel [`shade`](Self::shade) accumulates (the statistics its AOVs
    /// are resolved from); 0, the default, when it keeps none.
    fn pixel_sums(&self, _scene: &Scene) -> usize {
        0
    }

    /// Work done once per scene before the pixels (e.g. estimating α in a separate pass).
    fn preprocess(&mut self, _scene: &Scene) {}

    /// Called before each pass of a render in passes ([`crate::progressive`]; not before the
    /// one pass of a plain render), with what the pass gives each pixel and the sums of the
    /// passes before it: where an allocation that learns from earlier passes reads them. What
    /// it decides for the pass must depend on these only (docs/integrators.md, "Passes").
    fn begin_pass(&mut self, _scene: &Scene, _pass: &crate::passes::PassContext<'_>) {}

    /// What the integrator learned from the passes so far that the pixels' sums do not hold
    /// (`path`'s world-space cache of α), as bytes for a render's state and shard files
    /// ([`crate::progressive::RenderState::learned`]; read between passes): empty, the
    /// default, when it learns nothing of its own.
    fn learned_state(&self) -> Vec<u8> {
        Vec::new()
    }

    /// Continues from `state`, which [`learned_state`](Self::learned_state) wrote for the same
    /// configuration and scene, after [`preprocess`](Self::preprocess); empty: nothing learned
    /// yet. A state it cannot continue from is refused, naming what differs, and leaves the
    /// integrator as it was.
    fn restore_learned_state(&mut self, state: &[u8]) -> Result<(), String> {
        if state.is_empty() {
            Ok(())
        } else {
            Err("this integrator learns nothing across passes, but the state holds what one learned".into())
        }
    }

    /// The learned states `a` and `b` of two shards of one pass (or merges of shards), both
    /// resumed from one state, as one: what one process that rendered both's tiles would have
    /// learned, bit for bit; a mismatch is refused, naming it.
    fn merge_learned_states(&self, a: &[u8], b: &[u8]) -> Result<Vec<u8>, String> {
        if a.is_empty() && b.is_empty() {
            Ok(Vec::new())
        } else {
            Err("this integrator learns nothing across passes, but the shards hold what one learned".into())
        }
    }

    /// How many camera samples the render loop gives [`shade_together`](Self::shade_together)
    /// at once, at most [`WAVE_SIZE`]: one packet ([`PACKET_SIZE`]) by default. An integrator
    /// whose work shared across samples grows with their number asks for more: `path`'s deep
    /// vertices fill the BSDF's lanes only across many paths. A direct integrator does not:
    /// each of its lights revisits every sample's point, which stays in the L1 cache for a
    /// packet and not for a wave of 128 (simulated misses 70 times as many on Veach,
    /// docs/performance.md, "Waves of camera samples").
    fn wave_size(&self) -> usize {
        PACKET_SIZE
    }

    /// Shades one camera sample: returns its radiance estimate and *adds* its statistics to
    /// `sums`, the pixel's `pixel_sums` sums so far (all zero before its first sample). It must
    /// only add: core may shade a pixel's samples in parts and add the parts' sums.
    fn shade(&self, scene: &Scene, sample: &mut CameraSample, sums: &mut [f64]) -> Rgb;

    /// [`shade`](Self::shade) for a wave of camera samples at once, at most
    /// [`wave_size`](Self::wave_size) (core's waves span consecutive pixels of a tile, each
    /// pixel's samples in index order, and are traced in packets,
    /// [`CameraSample::trace_together`]): writes each one's estimate to `radiance` (as
    /// long as `samples`) and adds sample k's statistics to its own pixel's sums,
    /// `sums.of(k)`, in the order of the samples. The default shades them one by one; an
    /// integrator whose work batches across samples overrides it, and must give what `shade`
    /// gives, bit for bit (estimates and sums).
    fn shade_together(
        &self,
        scene: &Scene,
        samples: &mut [CameraSample],
        sums: &mut PacketSums<'_>,
        radiance: &mut [Rgb],
    ) {
        shade_one_by_one(self, scene, samples, sums, radiance);
    }

    /// Turns a pixel's sums over its `samples` camera samples into its AOV values (`aovs`, in
    /// the order of [`aovs`](Self::aovs), channels consecutive). Called once per finished pixel.
    fn resolve(&self, _scene: &Scene, _sums: &[f64], _samples: u32, _aovs: &mut [f32]) {}
}

/// [`Integrator::shade_together`] done one sample at a time with
/// [`shade`](Integrator::shade), each adding to its own pixel's sums: the default, and an
/// override's way out.
pub fn shade_one_by_one<I: Integrator + ?Sized>(
    integrator: &I,
    scene: &Scene,
    samples: &mut [CameraSample],
    sums: &mut PacketSums<'_>,
    radiance: &mut [Rgb],
) {
    assert_eq!(samples.len(), radiance.len(), "one estimate per sample");
    assert_eq!(samples.len(), sums.samples(), "one pixel per sample");
    for (k, (sample, radiance)) in samples.iter_mut().zip(radiance).enumerate() {
        *radiance = integrator.shade(scene, sample, sums.of(k));
    }
}

/// The sums a wave of camera samples adds its statistics to: the sums of the pixels its
/// samples belong to, `stride` ([`Integrator::pixel_sums`]) per pixel, and each sample's pixel.
pub struct PacketSums<'a> {
    sums: &'a mut [f64],
    stride: usize,
    /// Sample k's pixel: its sums are `sums[pixels[k] * stride..][..stride]`.
    pixels: &'a [u32],
}

impl<'a> PacketSums<'a> {
    /// The sums of a wave whose sample k belongs to pixel `pixels[k]` of `sums` (`stride`
    /// sums a pixel, e.g. a tile's).
    pub fn new(sums: &'a mut [f64], stride: usize, pixels: &'a [u32]) -> Self {
        assert!(
            pixels
                .iter()
                .all(|&p| (p as usize + 1) * stride <= sums.len()),
            "every sample's pixel has its sums"
        );
        PacketSums {
            sums,
            stride,
            pixels,
        }
    }

    /// The sums of a wave of `samples` camera samples of one pixel, whose sums are `sums`.
    pub fn one_pixel(sums: &'a mut [f64], samples: usize) -> Self {
        const FIRST: [u32; WAVE_SIZE] = [0; WAVE_SIZE];
        assert!(samples <= WAVE_SIZE, "at most a wave of samples");
        let stride = sums.len();
        PacketSums::new(sums, stride, &FIRST[..samples])
    }

    /// Sample k's pixel's sums.
    #[inline]
    pub fn of(&mut self, k: usize) -> &mut [f64] {
        let first = self.pixels[k] as usize * self.stride;
        &mut self.sums[first..first + self.stride]
    }

    /// The number of samples in the wave.
    pub fn samples(&self) -> usize {
        self.pixels.len()
    }
}

//! Scenes: the RON description, how it is built into renderable form, and the built scene.

pub mod budget;
pub mod description;
pub mod gltf;
pub mod gltf_scene;
pub mod light_check;
pub mod load;
pub mod obj;
pub mod overrides;
pub mod ply;
pub mod references;
pub mod serialized;
pub mod shape_check;
pub mod syntax;
pub mod transform;

use crate::bsdf::{Bsdf, BsdfFlags, Side};
use crate::camera::Camera;
use crate::emitter::Emitter;
use crate::filter::Filter;
use crate::geometry::{Geometry, Intersection, Ray};
use crate::output::Window;
use std::path::PathBuf;
use std::sync::Arc;

/// Everything an integrator needs to render: camera, surfaces, materials and lights.
pub struct Scene {
    pub camera: Camera,
    /// Size of the full film, in pixels.
    pub width: u32,
    pub height: u32,
    /// The part of the film that is rendered.
    pub window: Window,
    /// Camera samples per pixel.
    pub spp: u32,
    pub seed: u64,
    /// Camera rays jittered within their pixel; false: through pixel centres (so that runs with
    /// different seeds shade the same points, as `lumis study` needs).
    pub jitter: bool,
    /// The reconstruction filter, which places each camera sample and weighs it.
    pub filter: Filter,
    pub geometry: Geometry,
    /// Every BSDF a shape uses (and [`Absorber`](crate::bsdf::Absorber), the back of the
    /// one-sided ones, if there are any).
    pub bsdfs: Vec<Arc<dyn Bsdf>>,
    /// Per BSDF: its flags as shading points read them ([`Bsdf::flags`], with
    /// [`BsdfFlags::SPATIALLY_VARYING`] where it was given a texture).
    pub bsdf_flags: Vec<BsdfFlags>,
    /// Every light: area emitters of shapes in shape order, then the scene's `emitters` list.
    pub emitters: Vec<Arc<dyn Emitter>>,
    /// Per light: its `sampling_weight` (1 unless the scene says otherwise), how often `path`
    /// with one light per vertex chooses it relative to the others (positive).
    pub emitter_weights: Vec<f32>,
    /// Index of the environment emitter, which rays leaving the scene reach.
    pub environment: Option<usize>,
    /// Per shape: index of the BSDF seen from its front and from its back (`[front, back]`,
    /// indexed by [`Side`]): the same BSDF but for a one-sided one, whose back is the absorber.
    pub shape_bsdf: Vec<[u32; 2]>,
    /// Per shape: index of its area emitter.
    pub shape_emitter: Vec<Option<u32>>,
    /// Per light: the shape it is the area emitter of (None for the others).
    pub emitter_shape: Vec<Option<u32>>,
    /// Per light: the shape its shadow rays need not test, its own when that shape can never
    /// block its samples ([`Emitter::own_shape_never_blocks_samples`]).
    pub shadow_ray_skips: Vec<Option<u32>>,
    /// Where the EXR goes (the PNG preview goes beside it).
    pub output: PathBuf,
    /// Exposure of the PNG preview, in stops.
    pub exposure: f32,
}

impl Scene {
    pub fn intersect(&self, ray: &Ray) -> Option<Intersection> {
        self.geometry.intersect(ray)
    }

    pub fn occluded(&self, ray: &Ray) -> bool {
        self.geometry.occluded(ray)
    }

    /// Whether the shadow ray from surface point `from` toward a sample of light `light` is
    /// blocked.
    #[inline]
    pub fn occluded_toward_light(&self, ray: &Ray, from: &Intersection, light: usize) -> bool {
        self.geometry
            .occluded_by_others(ray, self.shadow_ray_skips[light], Some(from))
    }

    /// The BSDF of the surface `hit` met, seen from its front.
    pub fn bsdf(&self, hit: &Intersection) -> &dyn Bsdf {
        self.bsdf_seen_from(hit, Side::Front).0
    }

    /// The BSDF of the surface `hit` met, seen from `side` (a one-sided BSDF is black from
    /// its back), with its flags ([`Scene::bsdf_flags`]).
    #[inline(always)]
    pub fn bsdf_seen_from(&self, hit: &Intersection, side: Side) -> (&dyn Bsdf, BsdfFlags) {
        let index = self.shape_bsdf[hit.shape as usize][side as usize] as usize;
        (self.bsdfs[index].as_ref(), self.bsdf_flags[index])
    }

    /// Radiance arriving along `-wi` from the environment, for a ray that left the scene.
    pub fn environment_radiance(&self, wi: glam::Vec3) -> crate::math::Rgb {
        self.environment
            .map_or(crate::math::Rgb::ZERO, |e| self.emitters[e].eval(wi, None))
    }

    /// Index of the area emitter of the shape that was hit, if it emits.
    pub fn emitter_of(&self, hit: &Intersection) -> Option<usize> {
        self.emitter_of_shape(hit.shape)
    }

    /// Index of the area emitter of shape `shape`, if it emits.
    pub fn emitter_of_shape(&self, shape: u32) -> Option<usize> {
        self.shape_emitter[shape as usize].map(|e| e as usize)
    }
}

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
pub mod shape_check;
pub mod syntax;
pub mod transform;

use crate::bsdf::Bsdf;
use crate::camera::Camera;
use crate::emitter::Emitter;
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
    pub geometry: Geometry,
    pub bsdfs: Vec<Arc<dyn Bsdf>>,
    /// Every light: area emitters of shapes in shape order, then the scene's `emitters` list.
    pub emitters: Vec<Arc<dyn Emitter>>,
    /// Index of the environment emitter, which rays leaving the scene reach.
    pub environment: Option<usize>,
    /// Per shape: index of its BSDF and of its area emitter.
    pub shape_bsdf: Vec<u32>,
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

    pub fn bsdf(&self, hit: &Intersection) -> &dyn Bsdf {
        self.bsdfs[self.shape_bsdf[hit.shape as usize] as usize].as_ref()
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

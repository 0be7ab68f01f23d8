//! The integrator interface: computes one pixel's radiance and its optional AOVs.

use crate::math::Rgb;
use crate::scene::Scene;
use glam::UVec2;

/// An output layer besides colour, declared by the integrator so the film allocates only
/// what is asked for. Written to the EXR as channels `name.channel`.
#[derive(Clone, Debug, PartialEq)]
pub struct Aov {
    pub name: String,
    pub channels: Vec<String>,
    /// Also written as `<output>.<name>.png`: three channels of display colours in [0, 1].
    pub preview: bool,
}

/// Where `render_pixel` writes its results.
pub struct PixelOutput<'a> {
    /// The pixel's radiance estimate.
    pub color: Rgb,
    /// The AOV values of this pixel, in the order of `Integrator::aovs`, channels consecutive.
    pub aovs: &'a mut [f32],
}

/// A light-transport algorithm.
pub trait Integrator: Send + Sync {
    /// Extra output layers, if this configuration asks for any (they may depend on the scene,
    /// e.g. one per light).
    fn aovs(&self, _scene: &Scene) -> Vec<Aov> {
        Vec::new()
    }
    /// Work done once per scene before the pixels (e.g. estimating α in a separate pass).
    fn preprocess(&mut self, _scene: &Scene) {}
    /// Renders pixel `pixel` (film coordinates) with the scene's camera samples per pixel.
    fn render_pixel(&self, scene: &Scene, pixel: UVec2, out: &mut PixelOutput<'_>);
}

//! The shape of a render's output, shared by the scene (which part of the film is rendered), the
//! integrators (which layers they declare) and the film (which holds them). It depends on
//! nothing else in the crate, so that none of those three has to depend on another for it.

/// The part of the image that is rendered, in pixels of the full film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// An output layer besides colour, declared by the integrator so the film allocates only
/// what is asked for. Written to the EXR as channels `name.channel`.
#[derive(Clone, Debug, PartialEq)]
pub struct Aov {
    pub name: String,
    pub channels: Vec<String>,
    /// Also written as `<output>.<name>.png`: three channels of display colours in [0, 1].
    pub preview: bool,
}

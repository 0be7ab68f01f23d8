//! What a BSDF is told of the shading point besides the two directions: its texture
//! coordinates and the side of the surface the viewer is on.

use glam::Vec2;

/// The side of a surface: the front is the side its geometric normal points to (for a mesh,
/// the side from which its triangles are counter-clockwise; for a sphere, the outside).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    Front,
    Back,
}

/// What a BSDF knows of the shading point it is evaluated at, besides the two directions.
///
/// A scalar call is given one; a batch call one for all its elements or one per element (see
/// [`Bsdf::eval_pdf_batch`](super::Bsdf::eval_pdf_batch)); a kernel over lanes one per lane ([`BsdfContextLanes`](super::BsdfContextLanes)). Built
/// with [`BsdfContext::new`] (or [`BsdfContext::FRONT`]): fields may be added in later
/// versions of the interface, so plugins read them but do not write the struct out.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct BsdfContext {
    /// The point's texture coordinates, as the shape parameterises its surface (a mesh's
    /// vertex UVs, Mitsuba's parameterisations of the built-in shapes). Computed only for a
    /// BSDF that reads them: one whose [`flags`](super::Bsdf::flags) include
    /// [`BsdfFlags::SPATIALLY_VARYING`](super::BsdfFlags::SPATIALLY_VARYING) or that was given a texture; (0, 0) for the others.
    /// Not filtered: no derivatives are given (as Mitsuba's `bitmap` without MIP-mapping).
    pub uv: Vec2,
    /// The side of the surface the viewer (`wo`) is on, by the geometric normal. The shading
    /// frame is turned toward the viewer whichever side it is, so `wo.z` does not say it: a
    /// transmissive BSDF reads it to know whether the viewer is outside (`Front`, the side
    /// the normal points to) or inside, and orients η accordingly.
    pub side: Side,
}

impl BsdfContext {
    /// Seen from the front, at uv (0, 0): what a BSDF tested on its own is given.
    pub const FRONT: BsdfContext = BsdfContext::new(Vec2::ZERO, Side::Front);
    /// Seen from the back, at uv (0, 0).
    pub const BACK: BsdfContext = BsdfContext::new(Vec2::ZERO, Side::Back);

    pub const fn new(uv: Vec2, side: Side) -> Self {
        BsdfContext { uv, side }
    }

    /// This context at texture coordinates `uv`.
    pub const fn with_uv(self, uv: Vec2) -> Self {
        BsdfContext { uv, ..self }
    }
}

impl Default for BsdfContext {
    fn default() -> Self {
        BsdfContext::FRONT
    }
}

//! What a render will need in memory, estimated from the scene before the large allocations (the
//! BVH, the film) are made, so that a scene too large for the machine is refused with the
//! figure and the limit instead of aborting on a failed allocation.

use crate::geometry::{BVH_BYTES_PER_PRIMITIVE, ShapeGeometry};
use crate::limits::MemoryEstimate;
use crate::output::Window;

/// Bytes per pixel and per f32 channel at the peak of a render: the film, and at most one more
/// copy at a time (the tiles before they are assembled, then the EXR writer's channels).
const BYTES_PER_CHANNEL: u64 = 2 * 4;

/// Bytes per pixel besides: the 8-bit PNG previews, written one at a time.
const BYTES_PER_PIXEL: u64 = 4;

/// Adds the film of `window` with `channels` f32 values per pixel (3 for colour, plus the
/// AOVs). Measured peaks of 4096 × 4096 renders: 24.2, 47.6 and 86.7 bytes per pixel with 3, 6
/// and 11 channels; this gives 28, 52 and 92.
pub fn add_film(estimate: &mut MemoryEstimate, window: &Window, channels: u64) {
    let pixels = window.width as u64 * window.height as u64;
    estimate.add(
        format!(
            "film {}x{} with {channels} channels",
            window.width, window.height
        ),
        pixels.saturating_mul(channels * BYTES_PER_CHANNEL + BYTES_PER_PIXEL),
    );
}

/// Bytes per pixel of a render's sums kept between passes: the sample count, Σ u·colour and Σ u
/// (docs/integrators.md, "Passes").
const SUMS_BYTES_PER_PIXEL: u64 = 4 + 24 + 8;

/// Adds the sums a render in passes keeps for the whole film of `window` (with `stride`
/// integrator sums per pixel and, if `halves`, the half-images of the error estimate), and the
/// colour a preview is resolved to.
pub fn add_film_sums(estimate: &mut MemoryEstimate, window: &Window, stride: u64, halves: bool) {
    let pixels = window.width as u64 * window.height as u64;
    let per_pixel = SUMS_BYTES_PER_PIXEL + 8 * stride + if halves { 16 } else { 0 } + 12;
    estimate.add(
        format!(
            "the sums of {} passes",
            if halves { "error-estimating" } else { "the" }
        ),
        pixels.saturating_mul(per_pixel),
    );
}

/// Adds the BVH over `shapes` (the meshes themselves are already in memory) and the copies area
/// emitters keep of their triangles (`emitting`: triangles of shapes with an area emitter).
pub fn add_geometry(estimate: &mut MemoryEstimate, shapes: &[ShapeGeometry], emitting: u64) {
    let primitives: u64 = shapes
        .iter()
        .map(|s| match s {
            ShapeGeometry::Mesh(m) => m.indices.len() as u64,
            ShapeGeometry::Sphere(_) => 1,
        })
        .sum();
    estimate.add(
        format!("BVH over {primitives} primitives"),
        primitives.saturating_mul(BVH_BYTES_PER_PRIMITIVE),
    );
    // Vertices, normal and area per triangle, and the alias table of areas.
    const EMITTER_BYTES_PER_TRIANGLE: u64 = 36 + 12 + 4 + 16;
    if emitting > 0 {
        estimate.add(
            format!("area emitters over {emitting} triangles"),
            emitting.saturating_mul(EMITTER_BYTES_PER_TRIANGLE),
        );
    }
}

//! Linear RGB radiance (Rec. 709 primaries). Only RGB is modelled: no scene needs spectra.

/// Linear Rec. 709 RGB, used for radiance, reflectance and throughput.
pub type Rgb = glam::Vec3;

/// Luminance Y of a linear Rec. 709 colour.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

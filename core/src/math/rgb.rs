//! Linear RGB radiance (Rec. 709 primaries). Only RGB is modelled: no scene needs spectra.

use crate::math::lanes::{Lanes, V3};

/// Linear Rec. 709 RGB, used for radiance, reflectance and throughput.
pub type Rgb = glam::Vec3;

/// Luminance Y of a linear Rec. 709 colour.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    luminance_lanes::<f32>(V3::splat(c))
}

/// [`luminance`] in each lane.
#[inline(always)]
pub fn luminance_lanes<L: Lanes>(c: V3<L>) -> L {
    L::splat(0.212_671) * c.x + L::splat(0.715_160) * c.y + L::splat(0.072_169) * c.z
}

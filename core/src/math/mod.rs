//! Small numerical building blocks shared by every plugin.

pub mod distribution;
pub mod frame;
pub mod lanes;
pub mod rgb;
pub mod warp;

pub use distribution::{Distribution1D, Distribution2D};
pub use frame::Frame;
pub use rgb::{Rgb, luminance, luminance_lanes};

/// Asks the processor to bring `value`'s cache line in, so that a read soon after finds it
/// there (x86-64; elsewhere nothing). For a table larger than the caches read at a position
/// known well before the read: the miss then overlaps the work in between.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults, and `value` is a valid reference anyway.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// Floating-point rounding error bound γ(n) = n·ε / (1 − n·ε) (pbrt-v4, §6.8.1), with ε = 2⁻²⁴.
#[inline]
pub fn gamma(n: i32) -> f32 {
    let eps = f32::EPSILON * 0.5;
    (n as f32 * eps) / (1.0 - n as f32 * eps)
}

/// The next representable f32 above `v` (positive direction), leaving infinities alone.
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable f32 below `v` (negative direction), leaving infinities alone.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

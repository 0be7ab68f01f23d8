//! Floating-point rounding: error bounds (pbrt-v4 §6.8) and neighbouring values.

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

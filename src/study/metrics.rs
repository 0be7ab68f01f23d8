//! The paper's Lab error (gamma-2.2 tone map, clamp, CIE L*a*b*, ΔE*ab per pixel) and the mean
//! luminance of an image.

use lumis_core::math::{Rgb, luminance};

/// The paper's LDR tone map: scale by 2^exposure, clamp to [0, 1], gamma 1/2.2.
pub fn tone_map(c: Rgb, exposure_scale: f32) -> [f32; 3] {
    c.to_array().map(|v| {
        let v = if v.is_finite() {
            v * exposure_scale
        } else {
            0.0
        };
        v.clamp(0.0, 1.0).powf(1.0 / 2.2)
    })
}

/// CIE L*a*b* (D65 white) of a tone-mapped display colour: decoded with the same gamma 2.2
/// to linear Rec. 709, then XYZ, then Lab.
pub fn display_to_lab(display: [f32; 3]) -> [f64; 3] {
    let [r, g, b] = display.map(|v| (v as f64).powf(2.2));
    let x = 0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b;
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175_0 * b;
    let z = 0.019_333_9 * r + 0.119_192_0 * g + 0.950_304_1 * b;
    // D65 reference white.
    let (xn, yn, zn) = (0.950_47, 1.0, 1.088_83);
    let f = |t: f64| {
        const DELTA: f64 = 6.0 / 29.0;
        if t > DELTA * DELTA * DELTA {
            t.cbrt()
        } else {
            t / (3.0 * DELTA * DELTA) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(x / xn), f(y / yn), f(z / zn));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// Per-pixel CIE76 ΔE*ab between two HDR images after the paper's tone map.
pub fn lab_difference(image: &[Rgb], reference: &[Rgb], exposure_scale: f32) -> Vec<f64> {
    image
        .iter()
        .zip(reference)
        .map(|(&a, &b)| {
            let la = display_to_lab(tone_map(a, exposure_scale));
            let lb = display_to_lab(tone_map(b, exposure_scale));
            la.iter()
                .zip(&lb)
                .map(|(p, q)| (p - q) * (p - q))
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

/// Mean luminance of an image.
pub fn mean_luminance(image: &[Rgb]) -> f64 {
    image.iter().map(|&c| luminance(c) as f64).sum::<f64>() / image.len().max(1) as f64
}

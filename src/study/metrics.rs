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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_of_white_black_and_grey() {
        let white = display_to_lab([1.0; 3]);
        assert!((white[0] - 100.0).abs() < 0.01, "{white:?}");
        assert!(white[1].abs() < 0.01 && white[2].abs() < 0.01, "{white:?}");
        assert_eq!(display_to_lab([0.0; 3]), [0.0; 3]);
        // 18 % grey is L* ≈ 49.5 (CIE definition: L* = 116 · 0.18^(1/3) − 16).
        let grey = display_to_lab([0.18f32.powf(1.0 / 2.2); 3]);
        assert!((grey[0] - 49.5).abs() < 0.05, "{grey:?}");
    }

    #[test]
    fn lab_difference_is_zero_for_equal_images_and_clamps_highlights() {
        let a = vec![Rgb::new(0.2, 0.5, 0.9), Rgb::new(5.0, 5.0, 5.0)];
        assert!(lab_difference(&a, &a, 1.0).iter().all(|&d| d == 0.0));
        // Both pixels clip to white after the tone map.
        let b = vec![Rgb::new(0.2, 0.5, 0.9), Rgb::new(50.0, 50.0, 50.0)];
        assert!(lab_difference(&a, &b, 1.0).iter().all(|&d| d == 0.0));
        // Pure red against black: ΔE*ab = |Lab(red)|.
        let red = display_to_lab([1.0, 0.0, 0.0]);
        let d = lab_difference(&[Rgb::X], &[Rgb::ZERO], 1.0)[0];
        let norm = red.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            (d - norm).abs() < 1e-9 && (red[0] - 53.24).abs() < 0.05,
            "{red:?}"
        );
    }
}

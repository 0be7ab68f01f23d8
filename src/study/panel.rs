//! One image panel per scene (paper Figures 5, 6, 8, 10, 11): reference, balance heuristic and α
//! (at equal time when measured), the α map, their Lab ΔE*ab images, and magnified crops where
//! the balance heuristic errs most.

use super::{Choice, Measurement, SceneResults, metrics};
use anyhow::Result;
use lumis_core::image_io::{linear_to_srgb, write_rgb8_png};
use lumis_core::math::Rgb;
use std::path::Path;

/// ΔE*ab shown as white; the colour ramp runs black → red → yellow → white over [0, this].
const DELTA_E_WHITE: f64 = 10.0;
const GAP: u32 = 4;

/// The images a panel shows, kept while a scene is studied.
#[derive(Default)]
pub struct PanelImages {
    balance: Option<Vec<Rgb>>,
    alpha: Option<Vec<Rgb>>,
    alpha_map: Option<Vec<[f32; 3]>>,
}

impl PanelImages {
    /// Keeps the first run of balance and of integrated α; equal-time runs replace
    /// equal-sample ones.
    pub(super) fn keep(&mut self, choice: &Choice, m: &Measurement, equal_time: bool) {
        if choice.spec.kind == lumis_integrators::balance::NAME
            && (equal_time || self.balance.is_none())
        {
            self.balance = Some(m.image.clone());
        }
        if choice.is_integrated_alpha() && (equal_time || self.alpha.is_none()) {
            self.alpha = Some(m.image.clone());
            self.alpha_map.clone_from(&m.alpha_map);
        }
    }
}

struct Canvas {
    width: u32,
    height: u32,
    bytes: Vec<u8>,
}

impl Canvas {
    fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            bytes: vec![255; (width * height * 3) as usize],
        }
    }

    /// Copies a `w`×`h` image of display colours (row order) to (x, y), magnified `zoom` times.
    fn put(
        &mut self,
        x: u32,
        y: u32,
        w: u32,
        h: u32,
        zoom: u32,
        pixel: impl Fn(u32, u32) -> [u8; 3],
    ) {
        for py in 0..h * zoom {
            for px in 0..w * zoom {
                let (cx, cy) = (x + px, y + py);
                if cx < self.width && cy < self.height {
                    let i = ((cy * self.width + cx) * 3) as usize;
                    self.bytes[i..i + 3].copy_from_slice(&pixel(px / zoom, py / zoom));
                }
            }
        }
    }
}

fn display(c: Rgb, exposure_scale: f32) -> [u8; 3] {
    c.to_array().map(|v| {
        let v = if v.is_finite() {
            v * exposure_scale
        } else {
            0.0
        };
        (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8
    })
}

fn heat(delta_e: f64) -> [u8; 3] {
    let t = (delta_e / DELTA_E_WHITE).clamp(0.0, 1.0) * 3.0;
    let channel = |v: f64| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [channel(t), channel(t - 1.0), channel(t - 2.0)]
}

/// The top-left corner of the `cw`×`ch` window with the largest sum of `error` (summed-area
/// table, positions on an 8-pixel grid).
fn worst_window(error: &[f64], w: u32, h: u32, cw: u32, ch: u32) -> (u32, u32) {
    let (w, h) = (w as usize, h as usize);
    let mut table = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            table[(y + 1) * (w + 1) + x + 1] =
                error[y * w + x] + table[y * (w + 1) + x + 1] + table[(y + 1) * (w + 1) + x]
                    - table[y * (w + 1) + x];
        }
    }
    let sum = |x: usize, y: usize, cw: usize, ch: usize| {
        table[(y + ch) * (w + 1) + x + cw]
            - table[y * (w + 1) + x + cw]
            - table[(y + ch) * (w + 1) + x]
            + table[y * (w + 1) + x]
    };
    let (cw, ch) = (cw as usize, ch as usize);
    let mut best = (0, 0, f64::MIN);
    for y in (0..=h - ch).step_by(8) {
        for x in (0..=w - cw).step_by(8) {
            let s = sum(x, y, cw, ch);
            if s > best.2 {
                best = (x, y, s);
            }
        }
    }
    (best.0 as u32, best.1 as u32)
}

/// Writes `panels/NAME.png` if the balance heuristic and integrated α were both studied.
pub(super) fn write(
    out: &Path,
    results: &SceneResults,
    images: &PanelImages,
    exposure: f32,
) -> Result<()> {
    let (Some(balance), Some(alpha)) = (&images.balance, &images.alpha) else {
        return Ok(());
    };
    let (w, h) = (results.width, results.height);
    let scale = exposure.exp2();
    let reference = &results.reference.pixels;
    let delta_balance = metrics::lab_difference(balance, reference, scale);
    let delta_alpha = metrics::lab_difference(alpha, reference, scale);
    let mut canvas = Canvas::new(4 * w + 3 * GAP, 2 * h + GAP);
    let at = |i: u32, j: u32| (i * (w + GAP), j * (h + GAP));
    let index = |x: u32, y: u32| (y * w + x) as usize;

    for (i, image) in [reference, balance, alpha].into_iter().enumerate() {
        let (x, y) = at(i as u32, 0);
        canvas.put(x, y, w, h, 1, |px, py| display(image[index(px, py)], scale));
    }
    if let Some(map) = &images.alpha_map {
        let (x, y) = at(3, 0);
        canvas.put(x, y, w, h, 1, |px, py| {
            map[index(px, py)].map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
        });
    }
    for (i, delta) in [&delta_balance, &delta_alpha].into_iter().enumerate() {
        let (x, y) = at(i as u32, 1);
        canvas.put(x, y, w, h, 1, |px, py| heat(delta[index(px, py)]));
    }
    let (cw, ch) = ((w / 2).max(1), (h / 2).max(1));
    let (cx, cy) = worst_window(&delta_balance, w, h, cw, ch);
    for (i, image) in [balance, alpha].into_iter().enumerate() {
        let (x, y) = at(2 + i as u32, 1);
        canvas.put(x, y, cw, ch, 2, |px, py| {
            display(image[index(cx + px, cy + py)], scale)
        });
    }
    write_rgb8_png(
        &out.join("panels").join(format!("{}.png", results.name)),
        canvas.width,
        canvas.height,
        canvas.bytes,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worst_window_finds_the_error() {
        let (w, h) = (64, 48);
        let mut error = vec![0.0; (w * h) as usize];
        for y in 24..40 {
            for x in 40..56 {
                error[(y * w + x) as usize] = 1.0;
            }
        }
        assert_eq!(worst_window(&error, w, h, 16, 16), (40, 24));
        assert_eq!(heat(0.0), [0, 0, 0]);
        assert_eq!(heat(DELTA_E_WHITE), [255, 255, 255]);
    }
}

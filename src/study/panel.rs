//! One image panel per scene (paper Figures 5, 6, 8, 10, 11), every tile titled: the reference,
//! the balance heuristic and the headline α (first run, target budget), the α map with its
//! colour key; below, the ΔE*ab images of balance and α with their scale, and magnified crops
//! where balance errs most.

use super::collect::SceneAnalysis;
use super::metrics;
use anyhow::Result;
use lumis_core::image_io::{srgb_byte, write_rgb8_png};
use lumis_core::math::Rgb;
use lumis_integrators::aovs::alpha_color;
use plotters::prelude::*;
use std::path::Path;

/// ΔE*ab shown as white; the colour ramp runs black → red → yellow → white over [0, this].
pub const DELTA_E_WHITE: f64 = 10.0;
const GAP: u32 = 6;
/// Height of a tile's title, and of a colour key with its labels.
const TITLE: u32 = 22;
const KEY: u32 = 40;
/// Tiles are magnified to at least this width, so that titles fit.
const MIN_TILE: u32 = 180;

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
        srgb_byte(v)
    })
}

/// The colour of an error ΔE*ab on the error maps' ramp (black, red, yellow, white at
/// [`DELTA_E_WHITE`]).
pub fn heat(delta_e: f64) -> [u8; 3] {
    let t = (delta_e / DELTA_E_WHITE).clamp(0.0, 1.0) * 3.0;
    let channel = |v: f64| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [channel(t), channel(t - 1.0), channel(t - 2.0)]
}

/// The 8-bit colour of α on the α maps ([`alpha_color`]).
pub fn alpha_display(alpha: f64) -> [u8; 3] {
    alpha_color(alpha).map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// The top-left corner of the `cw`×`ch` window with the largest sum of `error` (summed-area
/// table, positions on an 8-pixel grid).
pub fn worst_window(error: &[f64], w: u32, h: u32, cw: u32, ch: u32) -> (u32, u32) {
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

/// The panel's size for a `w`×`h` film: 4 × 2 titled tiles and a row of colour keys.
pub fn size(w: u32, h: u32) -> (u32, u32) {
    let zoom = MIN_TILE.div_ceil(w).max(1);
    let (tw, th) = (w * zoom, h * zoom);
    (4 * tw + 3 * GAP, 2 * (TITLE + th) + GAP + KEY)
}

/// Writes `panels/NAME.png` if the balance heuristic and an α were both studied.
pub fn write(out: &Path, s: &SceneAnalysis) -> Result<()> {
    let Some(images) = &s.panel else {
        return Ok(());
    };
    let Some((alpha_label, alpha, alpha_map)) = &images.alpha else {
        return Ok(());
    };
    let balance = &images.balance;
    let (w, h) = (s.width, s.height);
    let zoom = MIN_TILE.div_ceil(w).max(1);
    let (tw, th) = (w * zoom, h * zoom);
    let (width, height) = size(w, h);
    let scale = s.exposure_scale;
    let reference = &s.reference_pixels;
    let delta_balance = metrics::lab_difference(balance, reference, scale);
    let delta_alpha = metrics::lab_difference(alpha, reference, scale);
    let mut canvas = Canvas::new(width, height);
    // Top-left corner of tile (i, j)'s image.
    let at = |i: u32, j: u32| (i * (tw + GAP), j * (TITLE + th + GAP) + TITLE);
    let index = |x: u32, y: u32| (y * w + x) as usize;
    let n = images.samples;
    let short = |label: &str| {
        if label.chars().count() > 22 {
            format!("{}…", label.chars().take(21).collect::<String>())
        } else {
            label.to_string()
        }
    };
    let mut titles: Vec<((u32, u32), String)> = vec![
        (at(0, 0), "reference".into()),
        (at(1, 0), format!("balance, N = {n}")),
        (at(2, 0), format!("{}, N = {n}", short(alpha_label))),
    ];
    for (i, image) in [reference, balance, alpha].into_iter().enumerate() {
        let (x, y) = at(i as u32, 0);
        canvas.put(x, y, w, h, zoom, |px, py| {
            display(image[index(px, py)], scale)
        });
    }
    if let Some(map) = alpha_map {
        let (x, y) = at(3, 0);
        canvas.put(x, y, w, h, zoom, |px, py| {
            alpha_display(map[index(px, py)] as f64)
        });
        titles.push((at(3, 0), "α map (BSDF share)".into()));
    }
    for (i, (delta, name)) in [(&delta_balance, "balance"), (&delta_alpha, "α")]
        .into_iter()
        .enumerate()
    {
        let (x, y) = at(i as u32, 1);
        canvas.put(x, y, w, h, zoom, |px, py| heat(delta[index(px, py)]));
        titles.push((at(i as u32, 1), format!("ΔE*ab of {name}")));
    }
    let (cw, ch) = ((w / 2).max(1), (h / 2).max(1));
    let (cx, cy) = worst_window(&delta_balance, w, h, cw, ch);
    for (i, (image, name)) in [(balance, "balance"), (alpha, "α")].into_iter().enumerate() {
        let (x, y) = at(2 + i as u32, 1);
        canvas.put(x, y, cw, ch, 2 * zoom, |px, py| {
            display(image[index(cx + px, cy + py)], scale)
        });
        titles.push((at(2 + i as u32, 1), format!("{name}, worst quarter ×2")));
    }
    // Colour keys under the ΔE images (0 … 10) and under the α map (0 … 1).
    let key_y = height - KEY + 4;
    let bar = 12;
    let delta_key_width = 2 * tw + GAP;
    canvas.put(0, key_y, delta_key_width, bar, 1, |px, _| {
        heat(DELTA_E_WHITE * px as f64 / (delta_key_width - 1).max(1) as f64)
    });
    let map_x = 3 * (tw + GAP);
    if alpha_map.is_some() {
        canvas.put(map_x, key_y, tw, bar, 1, |px, _| {
            alpha_display(px as f64 / (tw - 1).max(1) as f64)
        });
    }

    {
        let root =
            BitMapBackend::with_buffer(&mut canvas.bytes, (width, height)).into_drawing_area();
        let font = ("sans-serif", 14).into_font();
        let small = ("sans-serif", 12).into_font();
        for ((x, y), title) in &titles {
            root.draw_text(
                title,
                &font.clone().into(),
                (*x as i32 + 2, *y as i32 - TITLE as i32 + 3),
            )?;
        }
        let label_y = (key_y + bar + 2) as i32;
        for step in 0..=5 {
            let v = step as f64 * DELTA_E_WHITE / 5.0;
            let x = (v / DELTA_E_WHITE * (delta_key_width - 1) as f64) as i32;
            let text = if step == 5 {
                format!("≥{v:.0}")
            } else {
                format!("{v:.0}")
            };
            root.draw_text(&text, &small.clone().into(), ((x - 6).max(0), label_y))?;
        }
        root.draw_text(
            "ΔE*ab",
            &small.clone().into(),
            (delta_key_width as i32 + 6, key_y as i32),
        )?;
        if alpha_map.is_some() {
            let x0 = map_x as i32;
            root.draw_text("0: light", &small.clone().into(), (x0, label_y))?;
            root.draw_text(
                "½",
                &small.clone().into(),
                (x0 + tw as i32 / 2 - 4, label_y),
            )?;
            root.draw_text(
                "1: BSDF",
                &small.clone().into(),
                (x0 + tw as i32 - 52, label_y),
            )?;
        }
        root.present()?;
    }
    write_rgb8_png(
        &out.join("panels").join(format!("{}.png", s.name)),
        canvas.width,
        canvas.height,
        canvas.bytes,
    )?;
    Ok(())
}

//! What a render's camera samples add up to, per pixel: the mergeable data of a render, kept
//! across its passes, added up from shards, saved for a resume and resolved into a [`Film`].
//!
//! Pixels are stored tile by tile (the window's 16 × 16 tiles in row order, each tile's pixels in
//! row order), so that a tile's sums are one contiguous run that a worker thread owns during a
//! pass, and every statistic over the image visits the pixels in one fixed order.

use crate::film::Film;
use crate::image_io;
use crate::math::Rgb;
use crate::output::Window;
use crate::scene::Scene;
use glam::{DVec3, UVec2};

/// Tile edge in pixels: small enough to balance two cores on small images, large enough that
/// scheduling costs nothing.
pub const TILE_SIZE: u32 = 16;

/// Per pixel of the window (tile-major order), the sums of its camera samples.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSums {
    pub full_width: u32,
    pub full_height: u32,
    pub window: Window,
    /// Camera samples summed in each pixel.
    pub samples: Vec<u32>,
    /// Σ u · colour over the camera samples, u the sample's pass weight
    /// ([`passes::sample_weight`](crate::passes::sample_weight); one in a plain render).
    pub color: Vec<DVec3>,
    /// Σ u over the camera samples: the colour's divisor.
    pub weight: Vec<f64>,
    /// Σ u · luminance over the samples of even and of odd index (the half-images of the error
    /// estimate); empty when the render estimates no error.
    pub halves: Vec<[f64; 2]>,
    /// The integrator's sums, `stride` per pixel, over the samples unweighted.
    pub sums: Vec<f64>,
    pub stride: usize,
}

/// A tile of the window: where it is and where its pixels start in the sums.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Row-order index among the window's tiles.
    pub index: u32,
    /// Position in the window and size.
    pub origin: UVec2,
    pub size: UVec2,
    /// Index of its first pixel in the sums.
    pub first: usize,
}

impl Tile {
    pub fn pixels(&self) -> usize {
        (self.size.x * self.size.y) as usize
    }
}

/// Tiles of a window: how many across, how many down.
pub fn tile_grid(window: Window) -> (u32, u32) {
    (
        window.width.div_ceil(TILE_SIZE),
        window.height.div_ceil(TILE_SIZE),
    )
}

/// The window's tiles in row order, with their pixels' place in the sums.
pub fn tiles(window: Window) -> impl Iterator<Item = Tile> {
    let (tiles_x, tiles_y) = tile_grid(window);
    let mut first = 0;
    (0..tiles_x * tiles_y).map(move |index| {
        let origin = UVec2::new((index % tiles_x) * TILE_SIZE, (index / tiles_x) * TILE_SIZE);
        let size = UVec2::new(
            TILE_SIZE.min(window.width - origin.x),
            TILE_SIZE.min(window.height - origin.y),
        );
        let tile = Tile {
            index,
            origin,
            size,
            first,
        };
        first += tile.pixels();
        tile
    })
}

/// Calls `f` with each pixel of `window` as (its index in the sums, its row-order index in the
/// window), in the sums' order: how a walk over the whole film resolves pixels, without
/// [`FilmSums::row_index`]'s divisions per pixel.
pub fn for_each_pixel_in_rows(window: Window, mut f: impl FnMut(usize, usize)) {
    let width = window.width as usize;
    for tile in tiles(window) {
        let (x0, y0) = (tile.origin.x as usize, tile.origin.y as usize);
        let (w, h) = (tile.size.x as usize, tile.size.y as usize);
        for y in 0..h {
            let (first, row) = (tile.first + y * w, (y0 + y) * width + x0);
            for x in 0..w {
                f(first + x, row + x);
            }
        }
    }
}

/// The sums of one tile, borrowed mutably: what a worker thread adds a pass to.
pub(crate) struct TileSumsMut<'a> {
    pub tile: Tile,
    pub samples: &'a mut [u32],
    pub color: &'a mut [DVec3],
    pub weight: &'a mut [f64],
    /// Empty when no halves are kept.
    pub halves: &'a mut [[f64; 2]],
    pub sums: &'a mut [f64],
}

impl FilmSums {
    /// Sums of no samples for `scene`'s window, `stride` integrator sums per pixel, with the
    /// half-images if `halves`.
    pub fn new(scene: &Scene, stride: usize, halves: bool) -> Self {
        Self::empty(scene.width, scene.height, scene.window, stride, halves)
    }

    /// Sums of no samples for `window` of a `full_width` × `full_height` film.
    pub fn empty(
        full_width: u32,
        full_height: u32,
        window: Window,
        stride: usize,
        halves: bool,
    ) -> Self {
        let n = window.width as usize * window.height as usize;
        FilmSums {
            full_width,
            full_height,
            window,
            samples: vec![0; n],
            color: vec![DVec3::ZERO; n],
            weight: vec![0.0; n],
            halves: if halves {
                vec![[0.0; 2]; n]
            } else {
                Vec::new()
            },
            sums: vec![0.0; n * stride],
            stride,
        }
    }

    /// Each tile's sums, in row order of the tiles, borrowed apart.
    pub(crate) fn tiles_mut(&mut self) -> Vec<TileSumsMut<'_>> {
        let stride = self.stride;
        let keep_halves = !self.halves.is_empty();
        let (mut samples, mut color, mut weight, mut halves, mut sums) = (
            self.samples.as_mut_slice(),
            self.color.as_mut_slice(),
            self.weight.as_mut_slice(),
            self.halves.as_mut_slice(),
            self.sums.as_mut_slice(),
        );
        let mut parts = Vec::new();
        for tile in tiles(self.window) {
            let n = tile.pixels();
            let (s, rest) = std::mem::take(&mut samples).split_at_mut(n);
            samples = rest;
            let (c, rest) = std::mem::take(&mut color).split_at_mut(n);
            color = rest;
            let (w, rest) = std::mem::take(&mut weight).split_at_mut(n);
            weight = rest;
            let (h, rest) =
                std::mem::take(&mut halves).split_at_mut(if keep_halves { n } else { 0 });
            halves = rest;
            let (x, rest) = std::mem::take(&mut sums).split_at_mut(n * stride);
            sums = rest;
            parts.push(TileSumsMut {
                tile,
                samples: s,
                color: c,
                weight: w,
                halves: h,
                sums: x,
            });
        }
        parts
    }

    /// The window's row-order index of the pixel at `p` in the sums.
    pub fn row_index(&self, p: usize) -> usize {
        let (w, h) = (self.window.width as usize, self.window.height as usize);
        let t = TILE_SIZE as usize;
        let (_, tiles_y) = tile_grid(self.window);
        let ty = (p / (t * w)).min(tiles_y as usize - 1);
        let rest = p - ty * t * w;
        let th = t.min(h - ty * t);
        let tx = rest / (t * th);
        let rest = rest - tx * t * th;
        let tw = t.min(w - tx * t);
        (ty * t + rest / tw) * w + tx * t + rest % tw
    }

    /// Adds `other`'s samples (a render of the same window by the same integrator): a pixel
    /// only one of them has is copied, bit for bit.
    pub fn add(&mut self, other: &FilmSums) -> Result<(), String> {
        let shape = |s: &FilmSums| {
            (
                s.full_width,
                s.full_height,
                s.window,
                s.stride,
                s.halves.is_empty(),
            )
        };
        if shape(self) != shape(other) {
            return Err(format!(
                "sums of a {}×{} window at ({}, {}) of a {}×{} film with {} sums per pixel{} cannot be added to those of a {}×{} window at ({}, {}) of a {}×{} film with {}{}",
                other.window.width,
                other.window.height,
                other.window.x,
                other.window.y,
                other.full_width,
                other.full_height,
                other.stride,
                if other.halves.is_empty() {
                    ""
                } else {
                    " and half-images"
                },
                self.window.width,
                self.window.height,
                self.window.x,
                self.window.y,
                self.full_width,
                self.full_height,
                self.stride,
                if self.halves.is_empty() {
                    ""
                } else {
                    " and half-images"
                },
            ));
        }
        let stride = self.stride;
        for p in 0..self.samples.len() {
            let n = other.samples[p];
            if n == 0 {
                continue;
            }
            let theirs = &other.sums[p * stride..(p + 1) * stride];
            let ours = &mut self.sums[p * stride..(p + 1) * stride];
            if self.samples[p] == 0 {
                self.color[p] = other.color[p];
                self.weight[p] = other.weight[p];
                if !self.halves.is_empty() {
                    self.halves[p] = other.halves[p];
                }
                ours.copy_from_slice(theirs);
            } else {
                self.color[p] += other.color[p];
                self.weight[p] += other.weight[p];
                if !self.halves.is_empty() {
                    let [a, b] = other.halves[p];
                    self.halves[p][0] += a;
                    self.halves[p][1] += b;
                }
                ours.iter_mut().zip(theirs).for_each(|(a, b)| *a += b);
            }
            self.samples[p] += n;
        }
        Ok(())
    }

    /// Keeps only the pixels of the tiles `keep` accepts (the others get no samples).
    pub fn retain_tiles(&mut self, keep: impl Fn(u32) -> bool) {
        for part in self.tiles_mut() {
            if !keep(part.tile.index) {
                part.samples.fill(0);
                part.color.fill(DVec3::ZERO);
                part.weight.fill(0.0);
                part.halves.fill([0.0; 2]);
                part.sums.fill(0.0);
            }
        }
    }

    /// The colour the sums resolve to, without AOVs.
    pub fn resolve_color(&self) -> Film {
        let mut film = Film::new(self.full_width, self.full_height, self.window, Vec::new());
        for_each_pixel_in_rows(self.window, |p, row| {
            if self.samples[p] > 0 {
                film.color[row] = pixel_color(self.color[p], self.weight[p]);
            }
        });
        film
    }

    /// The preview PNG's bytes (row order, RGB) of the colour the sums resolve to, scaled by
    /// `scale` (2^exposure): [`image_io::display_bytes`] of [`FilmSums::resolve_color`]'s film in
    /// one walk over the sums, without the film (a preview after each pass).
    pub fn preview_bytes(&self, scale: f32) -> Vec<u8> {
        let mut bytes = vec![0; self.samples.len() * 3];
        for_each_pixel_in_rows(self.window, |p, row| {
            if self.samples[p] > 0 {
                let color = pixel_color(self.color[p], self.weight[p]);
                bytes[row * 3..row * 3 + 3].copy_from_slice(&image_io::display_bytes(color, scale));
            }
        });
        bytes
    }

    /// Pixels with samples.
    pub fn pixels_with_samples(&self) -> u64 {
        self.samples.iter().filter(|&&n| n > 0).count() as u64
    }
}

/// A pixel's colour from its weighted colour sum and weight: the mean of its samples in a
/// plain render (weight = count), the passes' unbiased combination in a render in passes.
#[inline]
pub(crate) fn pixel_color(color: DVec3, weight: f64) -> Rgb {
    (color / weight).as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pixel of windows with whole and partial tiles has one place in the sums, and
    /// `row_index` finds its row-order index.
    #[test]
    fn tile_major_order_maps_back_to_rows() {
        for (width, height) in [(16, 16), (40, 36), (17, 1), (1, 33), (48, 32)] {
            let window = Window {
                x: 3,
                y: 5,
                width,
                height,
            };
            let sums = FilmSums::empty(100, 100, window, 0, false);
            let mut seen = vec![false; (width * height) as usize];
            let mut p = 0;
            for tile in tiles(window) {
                assert_eq!(tile.first, p);
                for y in 0..tile.size.y {
                    for x in 0..tile.size.x {
                        let row = ((tile.origin.y + y) * width + tile.origin.x + x) as usize;
                        assert_eq!(sums.row_index(p), row, "{width}×{height}, pixel {p}");
                        assert!(!seen[row]);
                        seen[row] = true;
                        p += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    /// The preview's bytes, made in one walk over the sums, are the display bytes of the film
    /// the sums resolve to (the PNG a plain render writes), pixel for pixel: on a window of whole
    /// and partial tiles, with pixels without samples (black) and colours beyond the display's
    /// range.
    #[test]
    fn preview_bytes_are_the_resolved_films() {
        let window = Window {
            x: 2,
            y: 1,
            width: 40,
            height: 19,
        };
        let mut sums = FilmSums::empty(50, 30, window, 0, false);
        for p in 0..sums.samples.len() {
            if p % 7 != 3 {
                let v = p as f64;
                sums.samples[p] = 1 + (p % 5) as u32;
                sums.weight[p] = 0.5 + (p % 3) as f64;
                sums.color[p] = DVec3::new(v * 1e-3, (v * 0.37).sin().abs(), 2.0 - v * 1e-3);
            }
        }
        let scale = 1.5;
        let film = sums.resolve_color();
        let bytes = sums.preview_bytes(scale);
        assert_eq!(bytes.len(), film.color.len() * 3);
        for (row, color) in film.color.iter().enumerate() {
            assert_eq!(
                bytes[row * 3..row * 3 + 3],
                image_io::display_bytes(*color, scale),
                "pixel {row}"
            );
        }
        assert!(bytes.contains(&0) && bytes.contains(&255));
    }
}

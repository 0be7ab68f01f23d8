//! The render loop: square tiles rendered in parallel with rayon, assembled into a [`Film`].
//!
//! Core owns the camera samples: per pixel it runs the loop over the scene's `spp` camera
//! samples ([`CameraSample::new`] draws each one's stream and ray), sums the colours the
//! integrator returns (f64) and lets the integrator add its statistics to the pixel's sums. A
//! tile's sums and sample counts are its primary data ([`TileSums`]); only then are they
//! resolved into colours and AOV values. Sums over disjoint sets of camera samples add up, so
//! tiles or sample ranges rendered apart can be merged exactly before resolving.

use crate::accel::take_ray_count;
use crate::film::Film;
use crate::integrator::{CameraSample, Integrator};
use crate::math::Rgb;
use crate::scene::Scene;
use glam::{DVec3, UVec2};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Tile edge in pixels: small enough to balance two cores on small images, large enough that
/// scheduling costs nothing.
pub const TILE_SIZE: u32 = 16;

/// What a render did, for the summary line.
#[derive(Clone, Copy, Debug)]
pub struct RenderStats {
    pub wall_time: Duration,
    /// Camera samples of the finished pixels (finished pixels × spp).
    pub camera_samples: u64,
    /// Ray queries (closest-hit and occlusion).
    pub rays: u64,
    pub threads: usize,
    /// Pixels with all their camera samples, of all the window's pixels: fewer when the render
    /// was cancelled.
    pub pixels_done: u64,
    pub pixels_total: u64,
    /// Tiles all of whose pixels are finished, of all the window's tiles.
    pub tiles_done: u32,
    pub tiles_total: u32,
}

impl RenderStats {
    /// Whether some pixels were left unfinished because the render was cancelled.
    pub fn partial(&self) -> bool {
        self.pixels_done < self.pixels_total
    }
}

/// Renders the scene's window with `threads` worker threads (0: one per core). `on_tile` is
/// called after each tile with the number of pixels finished (e.g. to advance a progress bar).
pub fn render(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    on_tile: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    render_cancellable(scene, integrator, threads, on_tile, &AtomicBool::new(false))
}

/// As [`render`], but stops soon after `cancel` becomes true: it is checked before every
/// camera sample, so a render stops within one camera sample per thread. A pixel is *finished*
/// when all its `spp` camera samples are done; the film holds every finished pixel, the pixels
/// that were not finished stay black (colour and AOVs zero), and the statistics count both.
pub fn render_cancellable(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let window = scene.window;
    let mut film = Film::new(scene.width, scene.height, window, integrator.aovs(scene));
    let channels = film.aov_channels();
    let sums_per_pixel = integrator.pixel_sums(scene);
    let tiles_x = window.width.div_ceil(TILE_SIZE);
    let tiles_y = window.height.div_ceil(TILE_SIZE);
    let start = Instant::now();

    let tiles: Vec<ResolvedTile> = pool.install(|| {
        (0..tiles_x * tiles_y)
            .into_par_iter()
            .filter(|_| !cancel.load(Ordering::Relaxed))
            .map(|t| {
                let origin = UVec2::new((t % tiles_x) * TILE_SIZE, (t / tiles_x) * TILE_SIZE);
                let size = UVec2::new(
                    TILE_SIZE.min(window.width - origin.x),
                    TILE_SIZE.min(window.height - origin.y),
                );
                let sums =
                    TileSums::render(scene, integrator, origin, size, sums_per_pixel, cancel);
                let tile = sums.resolve(scene, integrator, channels);
                on_tile(tile.finished as u64);
                tile
            })
            .collect()
    });
    let wall_time = start.elapsed();
    let rays: u64 = pool.broadcast(|_| take_ray_count()).into_iter().sum();
    let pixels_done: u64 = tiles.iter().map(|t| t.finished as u64).sum();
    let tiles_done = tiles
        .iter()
        .filter(|t| t.finished == t.size.x * t.size.y)
        .count() as u32;

    for tile in tiles {
        let (origin, size) = (tile.origin, tile.size);
        for y in 0..size.y {
            let src = (y * size.x) as usize;
            let dst = ((origin.y + y) * window.width + origin.x) as usize;
            let w = size.x as usize;
            film.color[dst..dst + w].copy_from_slice(&tile.color[src..src + w]);
            film.aov_data[dst * channels..(dst + w) * channels]
                .copy_from_slice(&tile.aovs[src * channels..(src + w) * channels]);
        }
    }
    let stats = RenderStats {
        wall_time,
        camera_samples: pixels_done * scene.spp as u64,
        rays,
        threads: pool.current_num_threads(),
        pixels_done,
        pixels_total: window.width as u64 * window.height as u64,
        tiles_done,
        tiles_total: tiles_x * tiles_y,
    };
    Ok((film, stats))
}

/// What a tile's camera samples add up to, per pixel in row order: the mergeable data.
struct TileSums {
    /// Position in the window and size of the tile.
    origin: UVec2,
    size: UVec2,
    /// Camera samples summed in each pixel.
    samples: Vec<u32>,
    /// Σ of the camera samples' colours.
    color: Vec<DVec3>,
    /// The integrator's sums, `stride` per pixel.
    sums: Vec<f64>,
    stride: usize,
}

/// A tile's finished pixels, resolved.
struct ResolvedTile {
    origin: UVec2,
    size: UVec2,
    /// Pixels with all their camera samples; the others are black.
    finished: u32,
    color: Vec<Rgb>,
    aovs: Vec<f32>,
}

impl TileSums {
    /// Shades every camera sample of the tile's pixels, in row order, until `cancel`; a pixel
    /// whose samples were cut short is dropped (its sums and count reset), so that every pixel
    /// kept has all `spp` samples.
    fn render(
        scene: &Scene,
        integrator: &dyn Integrator,
        origin: UVec2,
        size: UVec2,
        stride: usize,
        cancel: &AtomicBool,
    ) -> Self {
        let n = (size.x * size.y) as usize;
        let mut tile = TileSums {
            origin,
            size,
            samples: vec![0; n],
            color: vec![DVec3::ZERO; n],
            sums: vec![0.0; n * stride],
            stride,
        };
        let window = scene.window;
        'pixels: for y in 0..size.y {
            for x in 0..size.x {
                let i = (y * size.x + x) as usize;
                let pixel = UVec2::new(window.x + origin.x + x, window.y + origin.y + y);
                let sums = &mut tile.sums[i * stride..(i + 1) * stride];
                for s in 0..scene.spp {
                    if cancel.load(Ordering::Relaxed) {
                        sums.fill(0.0);
                        tile.color[i] = DVec3::ZERO;
                        tile.samples[i] = 0;
                        break 'pixels;
                    }
                    let mut sample = CameraSample::new(scene, pixel, s);
                    tile.color[i] += integrator.shade(scene, &mut sample, sums).as_dvec3();
                    tile.samples[i] += 1;
                }
            }
        }
        tile
    }

    /// Colours (means of the samples) and AOV values of the finished pixels.
    fn resolve(&self, scene: &Scene, integrator: &dyn Integrator, channels: usize) -> ResolvedTile {
        let n = self.samples.len();
        let mut tile = ResolvedTile {
            origin: self.origin,
            size: self.size,
            finished: 0,
            color: vec![Rgb::ZERO; n],
            aovs: vec![0.0; n * channels],
        };
        for i in 0..n {
            let samples = self.samples[i];
            if samples == 0 {
                continue;
            }
            tile.color[i] = (self.color[i] / samples as f64).as_vec3();
            integrator.resolve(
                scene,
                &self.sums[i * self.stride..(i + 1) * self.stride],
                samples,
                &mut tile.aovs[i * channels..(i + 1) * channels],
            );
            tile.finished += 1;
        }
        tile
    }
}

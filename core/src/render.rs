//! The render loop: square tiles rendered in parallel with rayon, assembled into a [`Film`].
//!
//! Core owns the camera samples: per pixel it runs the loop over the scene's `spp` camera
//! samples ([`CameraSample::new`] draws each one's stream and ray; their primary rays are traced
//! sixteen at a time, [`CameraSample::trace_together`]), sums the colours the
//! integrator returns (f64) and lets the integrator add its statistics to the pixel's sums. A
//! tile's sums and sample counts are its primary data ([`TileSums`]); only then are they
//! resolved into colours and AOV values. Sums over disjoint sets of camera samples add up, so
//! tiles rendered apart merge exactly before resolving: [`render_shard`] renders a [`Shard`]'s
//! tiles to [`FilmSums`], which add up and resolve, with the code that resolves a tile, to the
//! one-process film bit for bit (docs/distributed.md).

use crate::film::Film;
use crate::geometry::{PACKET_SIZE, take_ray_count};
use crate::integrator::{CameraSample, Integrator};
use crate::math::Rgb;
use crate::output::Window;
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

/// A part of a render for running it as several processes: shard `index` of `count` renders
/// the tiles t (in row order) with t mod `count` = `index`, every camera sample of each of
/// their pixels, with the per-sample seeds of the whole render. Each pixel is computed in one
/// shard exactly as the one-process render computes it, so the shards' [`FilmSums`] added up
/// resolve to the same film, bit for bit, in any shard count. Interleaved tiles rather than
/// bands spread the expensive parts of an image over the shards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// The whole render.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Parses `i/n` (0 ≤ i < n).
    pub fn parse(text: &str) -> Result<Shard, String> {
        let problem = || format!("shard `{text}` is not i/n with 0 ≤ i < n (e.g. 0/4)");
        let (i, n) = text.split_once('/').ok_or_else(problem)?;
        let (index, count) = (
            i.trim().parse::<u32>().map_err(|_| problem())?,
            n.trim().parse::<u32>().map_err(|_| problem())?,
        );
        if index >= count {
            return Err(problem());
        }
        Ok(Shard { index, count })
    }

    /// Whether tile `tile` (row-order index) belongs to this shard.
    pub fn has(&self, tile: u32) -> bool {
        tile % self.count == self.index
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What a render's camera samples add up to, per pixel of the window in row order: the
/// mergeable data of a render (pixels of tiles not rendered have no samples and zero sums).
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSums {
    pub full_width: u32,
    pub full_height: u32,
    pub window: Window,
    /// Camera samples summed in each pixel.
    pub samples: Vec<u32>,
    /// Σ of the camera samples' colours.
    pub color: Vec<DVec3>,
    /// The integrator's sums, `stride` per pixel.
    pub sums: Vec<f64>,
    pub stride: usize,
}

impl FilmSums {
    /// Sums of no samples for `scene`'s window, `stride` integrator sums per pixel.
    pub fn new(scene: &Scene, stride: usize) -> Self {
        let n = scene.window.width as usize * scene.window.height as usize;
        FilmSums {
            full_width: scene.width,
            full_height: scene.height,
            window: scene.window,
            samples: vec![0; n],
            color: vec![DVec3::ZERO; n],
            sums: vec![0.0; n * stride],
            stride,
        }
    }

    /// Adds `other`'s samples (a render of the same window by the same integrator): a pixel
    /// only one of them has is copied, bit for bit.
    pub fn add(&mut self, other: &FilmSums) -> Result<(), String> {
        if (self.full_width, self.full_height, self.window, self.stride)
            != (
                other.full_width,
                other.full_height,
                other.window,
                other.stride,
            )
        {
            return Err(format!(
                "sums of a {}×{} window at ({}, {}) of a {}×{} film with {} sums per pixel cannot be added to those of a {}×{} window at ({}, {}) of a {}×{} film with {}",
                other.window.width,
                other.window.height,
                other.window.x,
                other.window.y,
                other.full_width,
                other.full_height,
                other.stride,
                self.window.width,
                self.window.height,
                self.window.x,
                self.window.y,
                self.full_width,
                self.full_height,
                self.stride
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
                ours.copy_from_slice(theirs);
            } else {
                self.color[p] += other.color[p];
                ours.iter_mut().zip(theirs).for_each(|(a, b)| *a += b);
            }
            self.samples[p] += n;
        }
        Ok(())
    }

    /// The film these sums resolve to with `integrator` (the one that rendered them, on the
    /// same scene): as the one-process render resolves its tiles, pixel by pixel; pixels
    /// without samples stay black.
    pub fn resolve(&self, scene: &Scene, integrator: &dyn Integrator) -> Film {
        let mut film = Film::new(
            self.full_width,
            self.full_height,
            self.window,
            integrator.aovs(scene),
        );
        let channels = film.aov_channels();
        for (p, &samples) in self.samples.iter().enumerate() {
            resolve_pixel(
                scene,
                integrator,
                samples,
                self.color[p],
                &self.sums[p * self.stride..(p + 1) * self.stride],
                &mut film.color[p],
                &mut film.aov_data[p * channels..(p + 1) * channels],
            );
        }
        film
    }

    /// Pixels with samples.
    pub fn pixels_with_samples(&self) -> u64 {
        self.samples.iter().filter(|&&n| n > 0).count() as u64
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
/// packet of camera samples (the [`PACKET_SIZE`] samples of a pixel traced and shaded
/// together), so a render stops within one packet per thread. A pixel is *finished*
/// when all its `spp` camera samples are done; the film holds every finished pixel, the pixels
/// that were not finished stay black (colour and AOVs zero), and the statistics count both.
pub fn render_cancellable(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let window = scene.window;
    let mut film = Film::new(scene.width, scene.height, window, integrator.aovs(scene));
    let channels = film.aov_channels();
    let (tiles, stats) = render_tiles(
        scene,
        integrator,
        threads,
        Shard::WHOLE,
        on_tile,
        cancel,
        |sums| sums.resolve(scene, integrator, channels),
    )?;
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
    Ok((film, stats))
}

/// Renders the tiles of `shard` and returns their sums, unresolved, for [`FilmSums::add`] and
/// [`FilmSums::resolve`]. The statistics count the shard's tiles and pixels only.
pub fn render_shard(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    shard: Shard,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Result<(FilmSums, RenderStats), rayon::ThreadPoolBuildError> {
    let stride = integrator.pixel_sums(scene);
    let mut film = FilmSums::new(scene, stride);
    let (tiles, stats) = render_tiles(scene, integrator, threads, shard, on_tile, cancel, |t| t)?;
    let width = scene.window.width;
    for tile in tiles {
        let (origin, size) = (tile.origin, tile.size);
        for y in 0..size.y {
            let src = (y * size.x) as usize;
            let dst = ((origin.y + y) * width + origin.x) as usize;
            let w = size.x as usize;
            film.samples[dst..dst + w].copy_from_slice(&tile.samples[src..src + w]);
            film.color[dst..dst + w].copy_from_slice(&tile.color[src..src + w]);
            film.sums[dst * stride..(dst + w) * stride]
                .copy_from_slice(&tile.sums[src * stride..(src + w) * stride]);
        }
    }
    Ok((film, stats))
}

/// Tiles of a window: how many across, how many down.
fn tile_grid(window: Window) -> (u32, u32) {
    (
        window.width.div_ceil(TILE_SIZE),
        window.height.div_ceil(TILE_SIZE),
    )
}

/// Renders the tiles of `shard` in parallel, each turned into a `T` by `finish` on its
/// worker thread, and the statistics of the shard.
fn render_tiles<T: Send + Finished>(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    shard: Shard,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
    finish: impl Fn(TileSums) -> T + Sync,
) -> Result<(Vec<T>, RenderStats), rayon::ThreadPoolBuildError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let window = scene.window;
    let sums_per_pixel = integrator.pixel_sums(scene);
    let (tiles_x, tiles_y) = tile_grid(window);
    let start = Instant::now();

    let tiles: Vec<T> = pool.install(|| {
        (0..tiles_x * tiles_y)
            .into_par_iter()
            .filter(|&t| shard.has(t) && !cancel.load(Ordering::Relaxed))
            .map(|t| {
                let origin = UVec2::new((t % tiles_x) * TILE_SIZE, (t / tiles_x) * TILE_SIZE);
                let size = UVec2::new(
                    TILE_SIZE.min(window.width - origin.x),
                    TILE_SIZE.min(window.height - origin.y),
                );
                let sums =
                    TileSums::render(scene, integrator, origin, size, sums_per_pixel, cancel);
                let tile = finish(sums);
                on_tile(tile.finished() as u64);
                tile
            })
            .collect()
    });
    let wall_time = start.elapsed();
    let rays: u64 = pool.broadcast(|_| take_ray_count()).into_iter().sum();
    let pixels_done: u64 = tiles.iter().map(|t| t.finished() as u64).sum();
    let tiles_done = tiles.iter().filter(|t| t.finished() == t.pixels()).count() as u32;
    let (mut pixels_total, mut tiles_total) = (0u64, 0u32);
    for t in (0..tiles_x * tiles_y).filter(|&t| shard.has(t)) {
        let (x, y) = ((t % tiles_x) * TILE_SIZE, (t / tiles_x) * TILE_SIZE);
        pixels_total +=
            u64::from(TILE_SIZE.min(window.width - x) * TILE_SIZE.min(window.height - y));
        tiles_total += 1;
    }
    let stats = RenderStats {
        wall_time,
        camera_samples: pixels_done * scene.spp as u64,
        rays,
        threads: pool.current_num_threads(),
        pixels_done,
        pixels_total,
        tiles_done,
        tiles_total,
    };
    Ok((tiles, stats))
}

/// A rendered tile's count of finished pixels, of all its pixels.
trait Finished {
    fn finished(&self) -> u32;
    fn pixels(&self) -> u32;
}

impl Finished for ResolvedTile {
    fn finished(&self) -> u32 {
        self.finished
    }
    fn pixels(&self) -> u32 {
        self.size.x * self.size.y
    }
}

impl Finished for TileSums {
    fn finished(&self) -> u32 {
        self.samples.iter().filter(|&&n| n > 0).count() as u32
    }
    fn pixels(&self) -> u32 {
        self.size.x * self.size.y
    }
}

/// A pixel's colour (the mean of its samples) and AOV values from its sums; nothing for a
/// pixel without samples (left black). The one place sums become a pixel, so that a render
/// resolved tile by tile and sums merged from shards give the same bits.
fn resolve_pixel(
    scene: &Scene,
    integrator: &dyn Integrator,
    samples: u32,
    color_sum: DVec3,
    sums: &[f64],
    color: &mut Rgb,
    aovs: &mut [f32],
) -> bool {
    if samples == 0 {
        return false;
    }
    *color = (color_sum / samples as f64).as_vec3();
    integrator.resolve(scene, sums, samples, aovs);
    true
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
        // The camera samples of a pixel, made, traced and shaded PACKET_SIZE at a time.
        let mut batch = Vec::with_capacity(PACKET_SIZE);
        let mut radiance = [Rgb::ZERO; PACKET_SIZE];
        'pixels: for y in 0..size.y {
            for x in 0..size.x {
                let i = (y * size.x + x) as usize;
                let pixel = UVec2::new(window.x + origin.x + x, window.y + origin.y + y);
                let sums = &mut tile.sums[i * stride..(i + 1) * stride];
                for first in (0..scene.spp).step_by(PACKET_SIZE) {
                    if cancel.load(Ordering::Relaxed) {
                        sums.fill(0.0);
                        tile.color[i] = DVec3::ZERO;
                        tile.samples[i] = 0;
                        break 'pixels;
                    }
                    let last = (first + PACKET_SIZE as u32).min(scene.spp);
                    batch.clear();
                    CameraSample::extend_pixel(scene, pixel, first..last, &mut batch);
                    CameraSample::trace_together(scene, &mut batch);
                    let radiance = &mut radiance[..batch.len()];
                    integrator.shade_together(scene, &mut batch, sums, radiance);
                    for (r, sample) in radiance.iter().zip(&batch) {
                        tile.color[i] += (*r * sample.weight).as_dvec3();
                        tile.samples[i] += 1;
                    }
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
            let finished = resolve_pixel(
                scene,
                integrator,
                self.samples[i],
                self.color[i],
                &self.sums[i * self.stride..(i + 1) * self.stride],
                &mut tile.color[i],
                &mut tile.aovs[i * channels..(i + 1) * channels],
            );
            tile.finished += u32::from(finished);
        }
        tile
    }
}

//! The render loop: square tiles rendered in parallel with rayon, pass by pass.
//!
//! Core owns the camera samples: a pass gives each pixel camera samples from its count so far up
//! to the pass's end ([`CameraSample::new`] draws each one's stream and ray; their primary rays
//! are traced sixteen at a time across consecutive pixels of a tile,
//! [`CameraSample::trace_together`]), adds each colour the
//! integrator returns times the pass's weight to the pixel's sums (f64), and lets the integrator
//! add its statistics. The sums ([`FilmSums`]) are the primary data; only then are they resolved
//! into colours and AOV values. Sums over disjoint sets of camera samples add up, so tiles
//! rendered apart merge exactly before resolving: [`render_shard`] renders a [`Shard`]'s tiles
//! to sums, which add up and resolve, with the code that resolves a tile, to the one-process film
//! bit for bit (docs/distributed.md). A plain render ([`render`]) is one pass whose tiles are
//! resolved as soon as they are rendered; a render in several passes ([`crate::progressive`])
//! keeps the film's sums between passes ([`render_pass`]).

use crate::film::Film;
pub use crate::film_sums::FilmSums;
use crate::film_sums::{TileSumsMut, for_each_pixel_in_rows, pixel_color, tiles};
use crate::geometry::take_ray_count;
use crate::integrator::{CameraSample, Integrator, PacketSums, WAVE_SIZE};
use crate::math::Rgb;
use crate::passes::{Budget, PlannedPass, give, sample_weight};
use crate::scene::Scene;
use glam::{DVec3, UVec2};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

pub use crate::film_sums::TILE_SIZE;

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
/// wave of camera samples (the [`Integrator::wave_size`] samples of consecutive pixels of a
/// tile traced and shaded together, [`render_tile`]), so a render stops within one wave per
/// thread. A pixel is *finished*
/// when all its `spp` camera samples are done; the film holds every finished pixel, the pixels
/// that were not finished stay black (colour and AOVs zero), and the statistics count both.
///
/// This is one pass of `spp` samples, each tile resolved as soon as it is rendered: no sums are
/// kept for later passes.
pub fn render_cancellable(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let pool = thread_pool(threads)?;
    let window = scene.window;
    let mut film = Film::new(scene.width, scene.height, window, integrator.aovs(scene));
    let channels = film.aov_channels();
    let stride = integrator.pixel_sums(scene);
    let pass = one_pass(scene);
    let start = Instant::now();
    let tiles: Vec<ResolvedTile> = pool.install(|| {
        tiles(window)
            .collect::<Vec<_>>()
            .into_par_iter()
            .filter(|_| !cancel.load(Ordering::Relaxed))
            .map(|tile| {
                let mut sums = OwnedTileSums::new(tile.pixels(), stride);
                let mut part = sums.borrow(tile);
                let done = render_tile(scene, integrator, &mut part, &pass, cancel);
                let resolved = ResolvedTile::new(scene, integrator, &part, channels);
                on_tile(u64::from(done.finished));
                resolved
            })
            .collect()
    });
    let wall_time = start.elapsed();
    let rays: u64 = pool.broadcast(|_| take_ray_count()).into_iter().sum();
    for tile in &tiles {
        let (origin, size) = (tile.tile.origin, tile.tile.size);
        for y in 0..size.y {
            let src = (y * size.x) as usize;
            let dst = ((origin.y + y) * window.width + origin.x) as usize;
            let w = size.x as usize;
            film.color[dst..dst + w].copy_from_slice(&tile.color[src..src + w]);
            film.aov_data[dst * channels..(dst + w) * channels]
                .copy_from_slice(&tile.aovs[src * channels..(src + w) * channels]);
        }
    }
    let pixels_done: u64 = tiles.iter().map(|t| u64::from(t.finished)).sum();
    let stats = RenderStats {
        wall_time,
        camera_samples: pixels_done * u64::from(scene.spp),
        rays,
        threads: pool.current_num_threads(),
        pixels_done,
        pixels_total: window.width as u64 * window.height as u64,
        tiles_done: tiles
            .iter()
            .filter(|t| t.finished as usize == t.tile.pixels())
            .count() as u32,
        tiles_total: tiles_count(scene, Shard::WHOLE),
    };
    Ok((film, stats))
}

/// Renders the tiles of `shard` in one pass of `spp` samples and returns their sums,
/// unresolved, for [`FilmSums::add`] and [`FilmSums::resolve`]. The statistics count the shard's
/// tiles and pixels only.
pub fn render_shard(
    scene: &Scene,
    integrator: &dyn Integrator,
    threads: usize,
    shard: Shard,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> Result<(FilmSums, RenderStats), rayon::ThreadPoolBuildError> {
    let pool = thread_pool(threads)?;
    let mut sums = FilmSums::new(scene, integrator.pixel_sums(scene), false);
    let pass = one_pass(scene);
    let stats = render_pass(
        scene, integrator, &pool, shard, &mut sums, &pass, on_tile, cancel,
    );
    Ok((sums, stats))
}

/// The one pass of a plain render: `spp` samples, planned as the last (every weight one).
fn one_pass(scene: &Scene) -> Budget {
    Budget::uniform(
        f64::from(scene.spp),
        PlannedPass {
            end: scene.spp,
            planned: u64::from(scene.spp),
        },
    )
}

/// A pool of `threads` worker threads (0: one per core).
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build()
}

/// Tiles of the window in `shard`.
fn tiles_count(scene: &Scene, shard: Shard) -> u32 {
    tiles(scene.window).filter(|t| shard.has(t.index)).count() as u32
}

/// Adds one pass to the sums of the tiles of `shard`, on `pool`: each pixel renders its camera
/// samples from its count so far up to the end `budget` gives it, each weighted by
/// [`sample_weight`]; a pixel already at its end (a pass resumed after an interrupt) renders
/// nothing. Stops as [`render_cancellable`]
/// does: a pixel cut short keeps its sums from before the pass. The statistics count the
/// camera samples of this pass and the pixels and tiles of the shard that have their pass.
#[allow(clippy::too_many_arguments)]
pub fn render_pass(
    scene: &Scene,
    integrator: &dyn Integrator,
    pool: &rayon::ThreadPool,
    shard: Shard,
    sums: &mut FilmSums,
    budget: &Budget,
    on_tile: &(dyn Fn(u64) + Sync),
    cancel: &AtomicBool,
) -> RenderStats {
    let start = Instant::now();
    let done: Vec<TileDone> = pool.install(|| {
        sums.tiles_mut()
            .into_par_iter()
            .filter(|part| shard.has(part.tile.index))
            .map(|mut part| {
                let done = if cancel.load(Ordering::Relaxed) {
                    TileDone::default()
                } else {
                    render_tile(scene, integrator, &mut part, budget, cancel)
                };
                on_tile(u64::from(done.finished));
                TileDone {
                    complete: done.finished as usize == part.tile.pixels(),
                    ..done
                }
            })
            .collect()
    });
    let wall_time = start.elapsed();
    let rays: u64 = pool.broadcast(|_| take_ray_count()).into_iter().sum();
    let pixels_total = tiles(scene.window)
        .filter(|t| shard.has(t.index))
        .map(|t| t.pixels() as u64)
        .sum();
    RenderStats {
        wall_time,
        camera_samples: done.iter().map(|d| d.samples).sum(),
        rays,
        threads: pool.current_num_threads(),
        pixels_done: done.iter().map(|d| u64::from(d.finished)).sum(),
        pixels_total,
        tiles_done: done.iter().filter(|d| d.complete).count() as u32,
        tiles_total: tiles_count(scene, shard),
    }
}

/// What a tile's pass did.
#[derive(Clone, Copy, Debug, Default)]
struct TileDone {
    /// Pixels that have their pass (rendered now or before).
    finished: u32,
    /// Camera samples rendered now.
    samples: u64,
    /// Whether every pixel has its pass.
    complete: bool,
}

/// Renders a tile's pass: the pixels in row order, each its camera samples from its count up to
/// its end, made and shaded in waves of the integrator's [`Integrator::wave_size`] (traced in
/// packets of [`PACKET_SIZE`](crate::geometry::PACKET_SIZE)) that span consecutive pixels (a
/// pixel's samples in index order, then the next pixel's: neighbouring pixels' camera rays are
/// coherent too, and a pixel of few samples still fills a packet). Each sample's colour and
/// statistics go to its own pixel's sums, in index order, as they would one pixel at a time.
/// `cancel` is checked before each wave; the pixel the waves so far have cut short gets its
/// sums from before the pass back, so that every pixel kept has all the samples of each pass it
/// has.
fn render_tile(
    scene: &Scene,
    integrator: &dyn Integrator,
    part: &mut TileSumsMut<'_>,
    budget: &Budget,
    cancel: &AtomicBool,
) -> TileDone {
    let tile = part.tile;
    let stride = part.sums.len() / tile.pixels();
    let keep_halves = !part.halves.is_empty();
    let mut done = TileDone::default();
    // The wave: its samples, each one's pixel (its slot in the tile) and estimate, and its
    // runs of samples of one pixel.
    let wave = integrator.wave_size().clamp(1, WAVE_SIZE);
    let mut batch = Vec::with_capacity(wave);
    let mut slots = [0u32; WAVE_SIZE];
    let mut radiance = [Rgb::ZERO; WAVE_SIZE];
    let mut runs = [Run::default(); WAVE_SIZE];
    // The pixel whose samples are being made, and its sums from before the pass.
    let mut open = OpenPixel::default();
    let mut before = vec![0.0; stride];
    let (mut before_color, mut before_halves) = (DVec3::ZERO, [0.0; 2]);
    let mut next_slot = 0;
    loop {
        if cancel.load(Ordering::Relaxed) {
            if open.next < open.end {
                let i = open.slot as usize;
                part.sums[i * stride..(i + 1) * stride].copy_from_slice(&before);
                part.color[i] = before_color;
                if keep_halves {
                    part.halves[i] = before_halves;
                }
                part.samples[i] = open.start;
            }
            return done;
        }
        batch.clear();
        let mut run_count = 0;
        while batch.len() < wave {
            if open.next == open.end {
                // The next pixel with samples in this pass; those without have theirs.
                while next_slot < tile.pixels()
                    && part.samples[next_slot] >= budget.pixel(tile.first + next_slot).end
                {
                    done.finished += 1;
                    next_slot += 1;
                }
                if next_slot == tile.pixels() {
                    break;
                }
                let i = next_slot;
                next_slot += 1;
                open = OpenPixel::new(scene, part, budget, i);
                before.copy_from_slice(&part.sums[i * stride..(i + 1) * stride]);
                before_color = part.color[i];
                if keep_halves {
                    before_halves = part.halves[i];
                }
            }
            let first = batch.len();
            let last = (open.next + (wave - first) as u32).min(open.end);
            CameraSample::extend_pixel(scene, open.pixel, open.next..last, &mut batch);
            slots[first..batch.len()].fill(open.slot);
            runs[run_count] = Run {
                slot: open.slot,
                first,
                end: batch.len(),
                u: open.u,
                finished: (last == open.end).then_some((open.start, open.end)),
            };
            run_count += 1;
            open.next = last;
        }
        if batch.is_empty() {
            return done;
        }
        let n = batch.len();
        CameraSample::trace_together(scene, &mut batch);
        let mut sums = PacketSums::new(part.sums, stride, &slots[..n]);
        integrator.shade_together(scene, &mut batch, &mut sums, &mut radiance[..n]);
        for run in &runs[..run_count] {
            let i = run.slot as usize;
            let samples = &batch[run.first..run.end];
            for (r, sample) in radiance[run.first..run.end].iter().zip(samples) {
                // The reconstruction filter's weight f/p of the sample's film position.
                let r = *r * sample.weight;
                part.color[i] += r.as_dvec3() * run.u;
                if keep_halves {
                    part.halves[i][(sample.index & 1) as usize] += run.u * luminance(r);
                }
            }
            part.samples[i] += samples.len() as u32;
            if let Some((start, end)) = run.finished {
                part.weight[i] = give(part.weight[i], run.u, end - start);
                done.finished += 1;
                done.samples += u64::from(end - start);
            }
        }
    }
}

/// The pixel of a tile whose camera samples [`render_tile`] is making.
#[derive(Default)]
struct OpenPixel {
    /// Its index in the tile.
    slot: u32,
    /// Its film coordinates.
    pixel: UVec2,
    /// Its samples of the pass: `start..end`, of which `next..end` are still to be made.
    start: u32,
    next: u32,
    end: u32,
    /// The weight of its samples in this pass ([`sample_weight`]).
    u: f64,
}

impl OpenPixel {
    /// Pixel `i` of `part`'s tile, from its count so far to its end in `budget`.
    fn new(scene: &Scene, part: &TileSumsMut<'_>, budget: &Budget, i: usize) -> Self {
        let (tile, window) = (part.tile, scene.window);
        let plan = budget.pixel(tile.first + i);
        let (x, y) = (i as u32 % tile.size.x, i as u32 / tile.size.x);
        OpenPixel {
            slot: i as u32,
            pixel: UVec2::new(window.x + tile.origin.x + x, window.y + tile.origin.y + y),
            start: part.samples[i],
            next: part.samples[i],
            end: plan.end,
            u: sample_weight(budget.mass, part.weight[i], plan.planned),
        }
    }
}

/// The samples of one pixel in a wave.
#[derive(Clone, Copy, Default)]
struct Run {
    /// The pixel's index in the tile.
    slot: u32,
    /// Where its samples are in the wave: `first..end`.
    first: usize,
    end: usize,
    /// Their weight ([`sample_weight`]).
    u: f64,
    /// The pixel's samples of the pass, `start..end`, if this run is its last.
    finished: Option<(u32, u32)>,
}

/// The luminance of a colour, in f64 (the error estimate's quantity).
#[inline]
fn luminance(c: Rgb) -> f64 {
    0.212_671 * c.x as f64 + 0.715_160 * c.y as f64 + 0.072_169 * c.z as f64
}

/// The sums of one tile, owned: the lean path of a plain render, which resolves each tile
/// as soon as it is rendered.
struct OwnedTileSums {
    samples: Vec<u32>,
    color: Vec<DVec3>,
    weight: Vec<f64>,
    sums: Vec<f64>,
}

impl OwnedTileSums {
    fn new(pixels: usize, stride: usize) -> Self {
        OwnedTileSums {
            samples: vec![0; pixels],
            color: vec![DVec3::ZERO; pixels],
            weight: vec![0.0; pixels],
            sums: vec![0.0; pixels * stride],
        }
    }

    fn borrow(&mut self, tile: crate::film_sums::Tile) -> TileSumsMut<'_> {
        TileSumsMut {
            tile: crate::film_sums::Tile { first: 0, ..tile },
            samples: &mut self.samples,
            color: &mut self.color,
            weight: &mut self.weight,
            halves: &mut [],
            sums: &mut self.sums,
        }
    }
}

/// A tile's finished pixels, resolved.
struct ResolvedTile {
    tile: crate::film_sums::Tile,
    /// Pixels with all their camera samples; the others are black.
    finished: u32,
    color: Vec<Rgb>,
    aovs: Vec<f32>,
}

impl ResolvedTile {
    /// Colours (the combination of the samples) and AOV values of the finished pixels.
    fn new(
        scene: &Scene,
        integrator: &dyn Integrator,
        part: &TileSumsMut<'_>,
        channels: usize,
    ) -> Self {
        let n = part.samples.len();
        let stride = part.sums.len() / n;
        let mut tile = ResolvedTile {
            tile: part.tile,
            finished: 0,
            color: vec![Rgb::ZERO; n],
            aovs: vec![0.0; n * channels],
        };
        for i in 0..n {
            let finished = resolve_pixel(
                scene,
                integrator,
                part.samples[i],
                part.color[i],
                part.weight[i],
                &part.sums[i * stride..(i + 1) * stride],
                &mut tile.color[i],
                &mut tile.aovs[i * channels..(i + 1) * channels],
            );
            tile.finished += u32::from(finished);
        }
        tile
    }
}

/// Resolving needs the integrator (its AOVs), which the sums' module does not know of.
impl FilmSums {
    /// The film these sums resolve to with `integrator` (the one that rendered them, on the
    /// same scene): each pixel as the one-process render resolves it; pixels without samples
    /// stay black.
    pub fn resolve(&self, scene: &Scene, integrator: &dyn Integrator) -> Film {
        let mut film = Film::new(
            self.full_width,
            self.full_height,
            self.window,
            integrator.aovs(scene),
        );
        let channels = film.aov_channels();
        for_each_pixel_in_rows(self.window, |p, row| {
            resolve_pixel(
                scene,
                integrator,
                self.samples[p],
                self.color[p],
                self.weight[p],
                &self.sums[p * self.stride..(p + 1) * self.stride],
                &mut film.color[row],
                &mut film.aov_data[row * channels..(row + 1) * channels],
            );
        });
        film
    }
}

/// A pixel's colour and AOV values from its sums; nothing for a pixel without samples (left
/// black). The one place sums become a pixel, so that a render resolved tile by tile and sums
/// merged from shards give the same bits.
#[allow(clippy::too_many_arguments)]
fn resolve_pixel(
    scene: &Scene,
    integrator: &dyn Integrator,
    samples: u32,
    color_sum: DVec3,
    weight: f64,
    sums: &[f64],
    color: &mut Rgb,
    aovs: &mut [f32],
) -> bool {
    if samples == 0 {
        return false;
    }
    *color = pixel_color(color_sum, weight);
    integrator.resolve(scene, sums, samples, aovs);
    true
}

//! The render loop: square tiles rendered in parallel with rayon, assembled into a [`Film`].

use crate::accel::take_ray_count;
use crate::film::Film;
use crate::integrator::{Integrator, PixelOutput};
use crate::scene::Scene;
use glam::UVec2;
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
    /// Camera samples (pixels × spp).
    pub camera_samples: u64,
    /// Ray queries (closest-hit and occlusion).
    pub rays: u64,
    pub threads: usize,
    /// Tiles rendered, of all the window's tiles: fewer when the render was cancelled.
    pub tiles_done: u32,
    pub tiles_total: u32,
}

impl RenderStats {
    /// Whether some tiles were skipped because the render was cancelled.
    pub fn partial(&self) -> bool {
        self.tiles_done < self.tiles_total
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

/// As [`render`], but tiles not yet started when `cancel` becomes true are skipped (left black):
/// the film then holds every finished tile, and the statistics say how many.
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
    let tiles_x = window.width.div_ceil(TILE_SIZE);
    let tiles_y = window.height.div_ceil(TILE_SIZE);
    let start = Instant::now();

    let tiles: Vec<(UVec2, UVec2, Vec<glam::Vec3>, Vec<f32>)> = pool.install(|| {
        (0..tiles_x * tiles_y)
            .into_par_iter()
            .filter(|_| !cancel.load(Ordering::Relaxed))
            .map(|t| {
                let origin = UVec2::new((t % tiles_x) * TILE_SIZE, (t / tiles_x) * TILE_SIZE);
                let size = UVec2::new(
                    TILE_SIZE.min(window.width - origin.x),
                    TILE_SIZE.min(window.height - origin.y),
                );
                let n = (size.x * size.y) as usize;
                let mut color = Vec::with_capacity(n);
                let mut aovs = vec![0.0f32; n * channels];
                for y in 0..size.y {
                    for x in 0..size.x {
                        let i = (y * size.x + x) as usize;
                        let pixel = UVec2::new(window.x + origin.x + x, window.y + origin.y + y);
                        let mut out = PixelOutput {
                            color: glam::Vec3::ZERO,
                            aovs: &mut aovs[i * channels..(i + 1) * channels],
                        };
                        integrator.render_pixel(scene, pixel, &mut out);
                        color.push(out.color);
                    }
                }
                on_tile(n as u64);
                (origin, size, color, aovs)
            })
            .collect()
    });
    let wall_time = start.elapsed();
    let rays: u64 = pool.broadcast(|_| take_ray_count()).into_iter().sum();
    let tiles_done = tiles.len() as u32;
    let pixels_done: u64 = tiles.iter().map(|t| (t.1.x * t.1.y) as u64).sum();

    for (origin, size, color, aovs) in tiles {
        for y in 0..size.y {
            let src = (y * size.x) as usize;
            let dst = ((origin.y + y) * window.width + origin.x) as usize;
            let w = size.x as usize;
            film.color[dst..dst + w].copy_from_slice(&color[src..src + w]);
            film.aov_data[dst * channels..(dst + w) * channels]
                .copy_from_slice(&aovs[src * channels..(src + w) * channels]);
        }
    }
    let stats = RenderStats {
        wall_time,
        camera_samples: pixels_done * scene.spp as u64,
        rays,
        threads: pool.current_num_threads(),
        tiles_done,
        tiles_total: tiles_x * tiles_y,
    };
    Ok((film, stats))
}

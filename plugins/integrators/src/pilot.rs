//! Pilot passes over the image, run once per scene in `preprocess` by the methods that steer
//! the render with statistics gathered beforehand (`variance_aware`, `pooled_alpha`), and the
//! measurement of the cost of a sample of each technique (`cost_alpha`).
//!
//! A pilot shades the point of camera sample 0 of each pixel of the window (its primary ray,
//! jittered or not as the scene says) and draws, per non-delta light, M samples at α = ½ with
//! the balance heuristic, from a random stream of its own ([`pilot_sampler`]): independent of
//! every camera sample's stream, so that whatever the pilot decides does not depend on the
//! samples it then steers, and deterministic, so that images stay identical for any number of
//! threads. The pilot's own balance estimate of each light is kept ([`PilotEstimates`]): camera
//! sample 0, which shades the same point, adds it to its own estimate (weighted by sample
//! counts, as the integrated α), so the pilot's samples are not wasted.

use crate::estimator::{Densities, draw_bsdf_samples, draw_light_samples};
use crate::phase::{Phase, PhaseRole, SampleSplit};
use crate::sampling::{LightSampling, PhaseBuffers};
use crate::shading_point::ShadingPoint;
use crate::weighting::{Balance, PerSample};
use glam::{UVec2, Vec3};
use lumis_core::integrator::CameraSample;
use lumis_core::math::Rgb;
use lumis_core::output::Window;
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Sample index of the pilot's stream: camera samples use 0 … spp − 1.
const PILOT_STREAM: u64 = u64::MAX;

/// The pilot's random stream at `pixel` (film coordinates).
pub fn pilot_sampler(scene: &Scene, pixel: UVec2) -> Sampler {
    let pixel_index = pixel.y as u64 * scene.width as u64 + pixel.x as u64;
    Sampler::new(scene.seed, pixel_index, PILOT_STREAM)
}

/// What a pixel's camera sample 0 hit, for filters that pool only similar neighbours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Index of the BSDF seen there (`scene.bsdfs`).
    pub bsdf: u32,
    /// Shading normal, turned toward the viewer.
    pub normal: Vec3,
    /// Distance along the primary ray.
    pub depth: f32,
}

impl Surface {
    /// Whether `other` is close enough to pool statistics with: the same BSDF, normals within
    /// about 25° (cosine ≥ 0.9) and depths within 10 %.
    pub fn similar(&self, other: &Surface) -> bool {
        self.bsdf == other.bsdf
            && self.normal.dot(other.normal) >= 0.9
            && (self.depth - other.depth).abs() <= 0.1 * self.depth.max(other.depth)
    }
}

/// The pilot's balance estimates per pixel of the window and light, which camera sample 0 of
/// the pixel adds to its own.
#[derive(Clone, Debug, Default)]
pub struct PilotEstimates {
    window: Option<Window>,
    lights: usize,
    /// M, the pilot's samples per light.
    samples: u32,
    values: Vec<Rgb>,
}

impl PilotEstimates {
    /// The pilot's estimate of `light` at `pixel` and its sample count M, if a pilot shaded it.
    pub fn get(&self, pixel: UVec2, light: usize) -> Option<(Rgb, u32)> {
        let w = self.window?;
        let (x, y) = (pixel.x.checked_sub(w.x)?, pixel.y.checked_sub(w.y)?);
        if x >= w.width || y >= w.height || self.samples == 0 {
            return None;
        }
        let i = (y * w.width + x) as usize * self.lights + light;
        self.values.get(i).map(|v| (*v, self.samples))
    }

    /// The estimate of N = `samples` samples of `sampling`'s light, `draw(sampling, n)`
    /// drawing n of them (n > 0). At camera sample 0's first surface, the point the pilot shaded,
    /// the pilot's M samples are N's first M: `draw` draws N − M, and the estimate is
    /// (M·L̂_pilot + (N − M)·L̂)/N; elsewhere `draw` draws N. Unbiased whenever whatever steers
    /// `draw` came from the pilot only. (M ≤ N: [`crate::alpha_family::read_pilot_samples`].)
    pub fn reuse_at_camera_sample_zero(
        &self,
        sampling: &mut LightSampling,
        samples: u32,
        draw: impl FnOnce(&mut LightSampling, u32) -> Rgb,
    ) -> Rgb {
        let pilot = if sampling.camera_sample() == 0 && sampling.is_primary() {
            self.get(sampling.pixel(), sampling.light())
        } else {
            None
        };
        let fresh = match pilot {
            Some((_, m)) => samples - m.min(samples),
            None => samples,
        };
        let value = if fresh > 0 {
            draw(sampling, fresh)
        } else {
            Rgb::ZERO
        };
        match pilot {
            Some((pilot, m)) => (pilot * m as f32 + value * fresh as f32) / (m + fresh) as f32,
            None => value,
        }
    }
}

/// Runs a pilot of `samples` samples per non-delta light (α = ½, balance) at every pixel of the
/// window, in parallel over rows. For each pixel and light, `visit(light, phase, values)` sees
/// the pilot's phase and stores what the method needs in `values` (the `per_light` values of
/// that light). Returns, per pixel of the window (row-major), its surface and its `per_light` ×
/// lights values, and the pilot's estimates.
pub fn run<T: Clone + Default + Send + Sync>(
    scene: &Scene,
    samples: u32,
    per_light: usize,
    visit: impl Fn(usize, &Phase, &mut [T]) + Sync,
) -> (Vec<Option<Surface>>, Vec<T>, PilotEstimates) {
    let window = scene.window;
    let lights = scene.emitters.len();
    let row = window.width as usize;
    let mut surfaces = vec![None; row * window.height as usize];
    let mut values = vec![T::default(); row * window.height as usize * lights * per_light];
    let mut estimates = vec![Rgb::ZERO; row * window.height as usize * lights];
    surfaces
        .par_chunks_mut(row)
        .zip(values.par_chunks_mut((row * lights * per_light).max(1)))
        .zip(estimates.par_chunks_mut((row * lights).max(1)))
        .enumerate()
        .for_each(|(y, ((surfaces, values), estimates))| {
            for x in 0..row {
                let pixel = UVec2::new(window.x + x as u32, window.y + y as u32);
                let pixel_values = &mut values[x * lights * per_light..][..lights * per_light];
                let pixel_estimates = &mut estimates[x * lights..][..lights];
                surfaces[x] = pilot_pixel(
                    scene,
                    pixel,
                    samples,
                    (pixel_values, pixel_estimates),
                    per_light,
                    &visit,
                );
            }
        });
    let estimates = PilotEstimates {
        window: Some(window),
        lights,
        samples,
        values: estimates,
    };
    (surfaces, values, estimates)
}

/// The shading point of camera sample 0 of `pixel` and what it hit, if it hit anything.
fn first_surface(scene: &Scene, pixel: UVec2) -> Option<(ShadingPoint<'_>, Surface)> {
    let ray = CameraSample::new(scene, pixel, 0).ray;
    let hit = scene.intersect(&ray)?;
    let point = ShadingPoint::new(scene, &hit, -ray.direction);
    let surface = Surface {
        bsdf: scene.shape_bsdf[hit.shape as usize][point.ctx.side as usize],
        normal: point.frame.to_world(Vec3::Z),
        depth: hit.t * ray.direction.length(),
    };
    Some((point, surface))
}

/// What camera sample 0 of each pixel of the window hit (row order), for filters that pool only
/// similar neighbours without a pilot.
pub fn surfaces(scene: &Scene) -> Vec<Option<Surface>> {
    let window = scene.window;
    let row = window.width as usize;
    let mut surfaces = vec![None; row * window.height as usize];
    surfaces
        .par_chunks_mut(row.max(1))
        .enumerate()
        .for_each(|(y, surfaces)| {
            for (x, surface) in surfaces.iter_mut().enumerate() {
                let pixel = UVec2::new(window.x + x as u32, window.y + y as u32);
                *surface = first_surface(scene, pixel).map(|(_, s)| s);
            }
        });
    surfaces
}

/// The pilot of one pixel, writing each light's values (`per_light` each) and estimate into
/// `values` and `estimates`: returns the surface camera sample 0 hit.
fn pilot_pixel<T>(
    scene: &Scene,
    pixel: UVec2,
    samples: u32,
    (values, estimates): (&mut [T], &mut [Rgb]),
    per_light: usize,
    visit: &(impl Fn(usize, &Phase, &mut [T]) + Sync),
) -> Option<Surface> {
    let (point, surface) = first_surface(scene, pixel)?;
    let mut sampler = pilot_sampler(scene, pixel);
    PhaseBuffers::with_thread_local(|buffers| {
        for (light, emitter) in scene.emitters.iter().enumerate() {
            if emitter.is_delta() {
                continue;
            }
            let mut sampling =
                LightSampling::new(scene, &point, light, pixel, &mut sampler, buffers);
            let split = SampleSplit::new(0.5, samples);
            estimates[light] =
                sampling.phase(split, PhaseRole::PILOT, &PerSample(Balance), &mut ());
            if let Some((phase, _)) = sampling.last_phase() {
                visit(light, &phase, &mut values[light * per_light..][..per_light]);
            }
        }
    });
    Some(surface)
}

/// The measured cost of one sample of each technique for one light, in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleCosts {
    pub bsdf: f64,
    pub light: f64,
}

impl SampleCosts {
    /// Equal costs: the cost-aware objective is the variance alone.
    pub const EQUAL: SampleCosts = SampleCosts {
        bsdf: 1.0,
        light: 1.0,
    };

    /// Light `light`'s costs: c_B / c_L = `ratio` where given, else as `measured` (per light,
    /// [`measure_costs`]), else equal (not measured, or no shading point saw the light).
    pub fn of_light(ratio: Option<f64>, measured: &[Option<SampleCosts>], light: usize) -> Self {
        match ratio {
            Some(ratio) => SampleCosts {
                bsdf: ratio,
                light: 1.0,
            },
            None => measured
                .get(light)
                .copied()
                .flatten()
                .unwrap_or(SampleCosts::EQUAL),
        }
    }
}

/// Shading points per side of the grid `cost_alpha` measures its costs on.
pub const COST_GRID: u32 = 48;
/// Samples per timed batch of `cost_alpha`'s measure.
pub const COST_BATCH: u32 = 8;

/// Times BSDF and light sampling of every non-delta light on the scene itself, on one thread:
/// at the shading points of a grid of up to `grid` × `grid` pixels spread over the window
/// (camera sample 0's), batches of `batch` samples of each technique, in alternating order,
/// twice (the first round warms the caches and is discarded). A batch is what the render pays
/// per sample: drawing the direction, tracing its ray, evaluating the other technique's density.
/// The slowest 1 % of batches of each technique are dropped (preemption by other programs).
/// Returns the mean cost per sample of each technique per light (None for delta lights and
/// lights no shading point measured).
pub fn measure_costs(scene: &Scene, grid: u32, batch: u32) -> Vec<Option<SampleCosts>> {
    let lights = scene.emitters.len();
    let window = scene.window;
    let (nx, ny) = (
        grid.min(window.width).max(1),
        grid.min(window.height).max(1),
    );
    let mut points = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let pixel = UVec2::new(
                window.x + (2 * i + 1) * window.width / (2 * nx),
                window.y + (2 * j + 1) * window.height / (2 * ny),
            );
            let ray = CameraSample::new(scene, pixel, 0).ray;
            if let Some(hit) = scene.intersect(&ray) {
                points.push((pixel, hit, ray.direction));
            }
        }
    }
    let mut times: Vec<[Vec<Duration>; 2]> = vec![[Vec::new(), Vec::new()]; lights];
    let mut records = Vec::with_capacity(batch as usize);
    for round in 0..2 {
        for (k, (pixel, hit, direction)) in points.iter().enumerate() {
            let point = ShadingPoint::new(scene, hit, -*direction);
            let mut sampler = pilot_sampler(scene, *pixel);
            for (light, emitter) in scene.emitters.iter().enumerate() {
                if emitter.is_delta() {
                    continue;
                }
                for t in 0..2 {
                    let technique = (t + k) % 2;
                    records.clear();
                    let start = Instant::now();
                    if technique == 0 {
                        draw_bsdf_samples(
                            scene,
                            &point,
                            light,
                            batch,
                            &mut sampler,
                            &mut records,
                            Densities::Lit,
                            None,
                        );
                    } else {
                        draw_light_samples(
                            scene,
                            &point,
                            light,
                            batch,
                            &mut sampler,
                            &mut records,
                            Densities::Lit,
                        );
                    }
                    let elapsed = start.elapsed();
                    if round == 1 {
                        times[light][technique].push(elapsed);
                    }
                }
            }
        }
    }
    let mean = |batches: &mut Vec<Duration>| -> Option<f64> {
        if batches.is_empty() {
            return None;
        }
        batches.sort_unstable();
        let kept = &batches[..batches.len() - batches.len() / 100];
        let total: f64 = kept.iter().map(Duration::as_secs_f64).sum();
        Some(total / (kept.len() as f64 * batch as f64))
    };
    times
        .iter_mut()
        .map(|[b, l]| {
            Some(SampleCosts {
                bsdf: mean(b)?,
                light: mean(l)?,
            })
        })
        .collect()
}

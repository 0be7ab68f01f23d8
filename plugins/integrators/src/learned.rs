//! α learned from the render's own passes (`statistics: "passes"` of `alpha`, `exact_alpha`
//! and `pooled_alpha`): no pilot; every sample of a pass is drawn at the α its pixel and light
//! were given before the pass, and adds what it says about every other α to the pixel's sums
//! (docs/integrators.md, "Learned α").
//!
//! A light's N samples at a shading point, drawn at split β, estimate the objective at any α
//! ([`PilotSamples`] reads records at any split): each camera sample adds the objective at
//! [`NODES`] evenly spaced α of the clamp interval (the mixture's second moment m̂(α) or the
//! stratified variance), or the paper's Î₁, Î₂ ([`PilotSamples::second_order`]), to its pixel's
//! integrator sums, which core keeps across passes. Before pass k ([`LearnedAlpha::begin_pass`])
//! the sums of passes < k, alone or pooled over the similar pixels of a window (the edge-stopping
//! filter of `pooled_alpha`, its radius a fraction of the image so that it does not depend on the
//! resolution), give each pixel and light its α, clamped; pass k draws all its samples at it.
//! The first pass has no statistics: α = ½, the balance split. So α of pass k is a function of
//! passes < k only, each pass is unbiased for its α, and the passes combine by the passes' rule.
//! The last pass adds no statistics (nothing reads them).
//!
//! Memory: 8 · (NODES + 1) bytes per pixel and light of statistics (8 · 3 for Î₁, Î₂), 4 for α,
//! and a pixel's surface when pooling.

use crate::allocation::Allocation;
use crate::moments::PilotSamples;
use crate::phase::{LightEstimate, PhaseRole, SampleSplit};
use crate::pilot::{self, Surface};
use crate::pooled_alpha::{AlphaMap, NODES, Pooled, alpha_of};
use crate::sampling::LightSampling;
use crate::weighting::Weighting;
use lumis_core::passes::PassContext;
use lumis_core::scene::Scene;
use rayon::prelude::*;

/// The image size, in pixels along its larger side, at which a pooling radius in pixels is
/// itself: radii scale with the image from there.
pub const REFERENCE_SIZE: f64 = 256.0;

/// The allocation: N samples at the α its pixel and light learned from the passes before.
pub struct LearnedAlpha {
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub pooled: Pooled,
    pub clamp: [f64; 2],
    /// The pooling window's radius in pixels of a [`REFERENCE_SIZE`] image (0: each pixel
    /// alone).
    pub radius: u32,
    alphas: AlphaMap,
    /// What camera sample 0 of each pixel hit (row order), found once when pooling.
    surfaces: Vec<Option<Surface>>,
    /// The pixels' statistics in row order, sized once.
    values: Vec<f64>,
    learning: bool,
}

impl LearnedAlpha {
    pub fn new(samples: u32, pooled: Pooled, clamp: [f64; 2], radius: u32) -> Self {
        LearnedAlpha {
            samples,
            pooled,
            clamp,
            radius,
            alphas: AlphaMap::default(),
            surfaces: Vec::new(),
            values: Vec::new(),
            learning: false,
        }
    }

    /// α of each pixel of the window (row order) and light, from the statistics of the passes
    /// so far (`values`, row order).
    fn alphas(&self, scene: &Scene) -> Vec<f32> {
        let window = scene.window;
        let lights = scene.emitters.len();
        let per_light = self.pooled.per_light();
        let (width, height) = (window.width as i64, window.height as i64);
        let r = (self.radius as f64 * width.max(height) as f64 / REFERENCE_SIZE).round() as i64;
        let (pooled, clamp, values, surfaces) =
            (self.pooled, self.clamp, &self.values, &self.surfaces);
        let mut alphas = vec![f32::NAN; (window.width * window.height) as usize * lights];
        alphas
            .par_chunks_mut((window.width as usize * lights).max(1))
            .enumerate()
            .for_each(|(y, row)| {
                let mut sum = vec![0.0f64; per_light];
                let mut normalised = vec![0.0f32; per_light];
                for x in 0..width {
                    let p = (y as i64 * width + x) as usize;
                    let surface = surfaces.get(p).copied().flatten();
                    for light in 0..lights {
                        if scene.emitters[light].is_delta() {
                            continue;
                        }
                        sum.fill(0.0);
                        for qy in (y as i64 - r).max(0)..(y as i64 + r + 1).min(height) {
                            for qx in (x - r).max(0)..(x + r + 1).min(width) {
                                let q = (qy * width + qx) as usize;
                                let similar = q == p
                                    || surface.is_some_and(|s| {
                                        surfaces[q].is_some_and(|t| s.similar(&t))
                                    });
                                if !similar {
                                    continue;
                                }
                                let v = &values[(q * lights + light) * per_light..][..per_light];
                                for (s, v) in sum.iter_mut().zip(v) {
                                    *s += v;
                                }
                            }
                        }
                        // Means over the observations (the objective's scale does not move
                        // its minimum), so that f32 holds them; the count stays last.
                        let count = sum[per_light - 1];
                        let scale = if count > 0.0 { 1.0 / count } else { 0.0 };
                        for (n, s) in normalised.iter_mut().zip(&sum[..per_light - 1]) {
                            *n = (s * scale) as f32;
                        }
                        normalised[per_light - 1] = count as f32;
                        let alpha = alpha_of(pooled, &normalised, clamp)
                            .unwrap_or(0.5)
                            .clamp(clamp[0], clamp[1]);
                        row[x as usize * lights + light] = alpha as f32;
                    }
                }
            });
        alphas
    }
}

impl Allocation for LearnedAlpha {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let alpha = self
            .alphas
            .get(sampling.pixel(), sampling.light())
            .unwrap_or(0.5)
            .clamp(self.clamp[0], self.clamp[1]);
        let split = SampleSplit::new(alpha, self.samples);
        let value = sampling.phase(split, PhaseRole::ESTIMATE, weighting, &mut ());
        LightEstimate { value, alpha }
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        scene.emitters.len() * self.pooled.per_light()
    }

    fn begin_pass(&mut self, scene: &Scene, pass: &PassContext<'_>, offset: usize) {
        let sums = pass.sums;
        // The last pass (planned to end the render) adds statistics nothing would read.
        self.learning = sums.samples.first().is_none_or(|&done| {
            let plan = pass.budget.pixel(0);
            plan.planned > u64::from(plan.end.saturating_sub(done))
        });
        if pass.index == 0 {
            self.alphas = AlphaMap::default();
            return;
        }
        if self.radius > 0 && self.surfaces.is_empty() {
            self.surfaces = pilot::surfaces(scene);
        }
        let stride = self.pixel_sums(scene);
        self.values.resize(sums.samples.len() * stride, 0.0);
        for p in 0..sums.samples.len() {
            let row = sums.row_index(p);
            let from = &sums.sums[p * sums.stride + offset..][..stride];
            self.values[row * stride..][..stride].copy_from_slice(from);
        }
        let alphas = self.alphas(scene);
        self.alphas = AlphaMap::new(scene.window, scene.emitters.len(), alphas);
    }

    #[inline]
    fn learning(&self) -> bool {
        self.learning
    }

    fn observe(&self, sampling: &LightSampling, sums: &mut [f64]) {
        let Some((phase, _)) = sampling.last_phase() else {
            return;
        };
        let per_light = self.pooled.per_light();
        let out = &mut sums[sampling.light() * per_light..][..per_light];
        let pilot = PilotSamples::new(&phase);
        match self.pooled {
            Pooled::Nodes(objective) => {
                if !pilot.informative() {
                    return;
                }
                pilot.add_objective_at_nodes(objective, self.clamp, &mut out[..NODES]);
                out[NODES] += 1.0;
            }
            Pooled::SecondOrder => {
                let (i1, i2) = pilot.second_order();
                if i2 > 0.0 && i1.is_finite() && i2.is_finite() {
                    out[0] += i1;
                    out[1] += i2;
                    out[2] += 1.0;
                }
            }
        }
    }
}

//! α learned from the render's own passes (`statistics: "passes"` of `alpha`, `exact_alpha`,
//! `pooled_alpha` and `cost_alpha`): no pilot; every sample of a pass is drawn at the α its pixel and light
//! were given before the pass, and adds what it says about every other α to the pixel's sums
//! (docs/integrators.md, "Learned α").
//!
//! A light's N samples at a shading point, drawn at split β, estimate the objective at any α
//! ([`PilotSamples`] reads records at any split): each camera sample adds the objective at
//! [`NODES`] evenly spaced α of the clamp interval (the mixture's second moment m̂(α), the
//! stratified variance, or for the cost-aware α the variance itself, unclamped, later weighed
//! by each light's sample costs), or the paper's Î₁, Î₂ ([`PilotSamples::second_order`]), to its pixel's
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
use crate::moments::{Objective, PilotSamples};
use crate::phase::{LightEstimate, PhaseRole, SampleSplit};
use crate::pilot::{self, SampleCosts, Surface};
use crate::sampling::LightSampling;
use crate::second_order::second_order_alpha;
use crate::weighting::Weighting;
use glam::UVec2;
use lumis_core::output::Window;
use lumis_core::passes::PassContext;
use lumis_core::scene::Scene;
use rayon::prelude::*;

/// The image size, in pixels along its larger side, at which a pooling radius in pixels is
/// itself: radii scale with the image from there.
pub const REFERENCE_SIZE: f64 = 256.0;

/// Evenly spaced α in the clamp interval at which each pixel's objective is kept.
pub const NODES: usize = 17;

/// What each pixel keeps of its pilot, per light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pooled {
    /// An objective of [`crate::moments`] at [`NODES`] α, then 1 if the pilot is informative.
    Nodes(Objective),
    /// Î₁, Î₂ (sums), then 1 if Î₂ > 0.
    SecondOrder,
    /// The variance V̂ (mixture, or stratified) at [`NODES`] α, unclamped, then 1 if the pilot
    /// is informative: α minimises V̂(α) (α c_B + (1 − α) c_L), with the light's sample costs
    /// (`cost_alpha`).
    Cost { stratified: bool },
}

impl Pooled {
    pub fn per_light(self) -> usize {
        match self {
            Pooled::Nodes(_) | Pooled::Cost { .. } => NODES + 1,
            Pooled::SecondOrder => 3,
        }
    }
}

/// α per pixel of the window and light.
#[derive(Clone, Debug, Default)]
pub struct AlphaMap {
    window: Option<Window>,
    lights: usize,
    alphas: Vec<f32>,
}

impl AlphaMap {
    /// α of each pixel of `window` (row order) and light, NaN where there is none.
    pub fn new(window: Window, lights: usize, alphas: Vec<f32>) -> Self {
        AlphaMap {
            window: Some(window),
            lights,
            alphas,
        }
    }

    /// α at `pixel` (film coordinates) for `light`, if the pilot covered it.
    pub fn get(&self, pixel: UVec2, light: usize) -> Option<f64> {
        let w = self.window?;
        let (x, y) = (pixel.x.checked_sub(w.x)?, pixel.y.checked_sub(w.y)?);
        if x >= w.width || y >= w.height {
            return None;
        }
        let a = *self
            .alphas
            .get((y * w.width + x) as usize * self.lights + light)?;
        a.is_finite().then_some(a as f64)
    }

    /// The α a sample at `sampling`'s pixel and light is drawn with: the map's, or the even
    /// split where it has none, in `clamp`.
    pub fn at(&self, sampling: &LightSampling, clamp: [f64; 2]) -> f64 {
        self.get(sampling.pixel(), sampling.light())
            .unwrap_or(0.5)
            .clamp(clamp[0], clamp[1])
    }
}

/// The α of `values` (one light's pooled values) in `clamp`, or None if uninformative;
/// `costs` are the light's sample costs (read by [`Pooled::Cost`] only).
pub fn alpha_of(
    pooled: Pooled,
    values: &[f32],
    clamp: [f64; 2],
    costs: SampleCosts,
) -> Option<f64> {
    match pooled {
        Pooled::SecondOrder => {
            (values[2] > 0.0).then_some(())?;
            second_order_alpha(values[0] as f64, values[1] as f64)
        }
        Pooled::Nodes(_) => {
            (values[NODES] > 0.0).then_some(())?;
            let v: [f64; NODES] = std::array::from_fn(|k| values[k] as f64);
            node_minimum(&v, clamp)
        }
        Pooled::Cost { .. } => {
            (values[NODES] > 0.0).then_some(())?;
            // The pooled variance is a mean of unbiased but noisy terms: where it is nowhere
            // positive the pilot says nothing about efficiency.
            values[..NODES].iter().any(|&v| v > 0.0).then_some(())?;
            let step = (clamp[1] - clamp[0]) / (NODES - 1) as f64;
            let v: [f64; NODES] = std::array::from_fn(|k| {
                let alpha = clamp[0] + step * k as f64;
                (values[k] as f64).max(0.0) * (alpha * costs.bsdf + (1.0 - alpha) * costs.light)
            });
            node_minimum(&v, clamp)
        }
    }
}

/// The α in `clamp` at which `v`, an objective at [`NODES`] evenly spaced α of `clamp`, is least:
/// the best node, moved to the vertex of the parabola through it and its neighbours.
fn node_minimum(v: &[f64; NODES], clamp: [f64; 2]) -> Option<f64> {
    let best = (0..NODES).min_by(|&a, &b| v[a].total_cmp(&v[b]))?;
    let step = (clamp[1] - clamp[0]) / (NODES - 1) as f64;
    let mut alpha = clamp[0] + step * best as f64;
    if best > 0 && best < NODES - 1 {
        let (l, c, r) = (v[best - 1], v[best], v[best + 1]);
        let curvature = l - 2.0 * c + r;
        if curvature > 0.0 && curvature.is_finite() {
            alpha += step * (0.5 * (l - r) / curvature).clamp(-1.0, 1.0);
        }
    }
    Some(alpha)
}

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
    /// c_B / c_L given for every light ([`Pooled::Cost`]), or None to measure them.
    cost_ratio: Option<f64>,
    /// Each light's sample costs ([`Pooled::Cost`]; equal where unmeasured).
    costs: Vec<Option<SampleCosts>>,
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
            cost_ratio: None,
            costs: Vec::new(),
            surfaces: Vec::new(),
            values: Vec::new(),
            learning: false,
        }
    }

    /// With [`Pooled::Cost`]: the costs' ratio c_B / c_L for every light, or None to measure
    /// each light's on the scene in `preprocess` (as `cost_alpha` does).
    pub fn with_cost_ratio(self, ratio: Option<f64>) -> Self {
        LearnedAlpha {
            cost_ratio: ratio,
            ..self
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
        let costs: Vec<SampleCosts> = (0..lights)
            .map(|light| SampleCosts::of_light(self.cost_ratio, &self.costs, light))
            .collect();
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
                        let alpha = alpha_of(pooled, &normalised, clamp, costs[light])
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
        let alpha = self.alphas.at(sampling, self.clamp);
        let split = SampleSplit::new(alpha, self.samples);
        let value = sampling.phase(split, PhaseRole::ESTIMATE, weighting, &mut ());
        LightEstimate { value, alpha }
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        scene.emitters.len() * self.pooled.per_light()
    }

    fn preprocess(&mut self, scene: &Scene) {
        if matches!(self.pooled, Pooled::Cost { .. }) && self.cost_ratio.is_none() {
            self.costs = pilot::measure_costs(scene, pilot::COST_GRID, pilot::COST_BATCH);
        }
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
                let (nodes, count) = out.split_at_mut(NODES);
                let nodes: &mut [f64; NODES] = nodes.try_into().expect("NODES sums");
                if pilot.add_objective_at_nodes(objective, self.clamp, nodes) {
                    count[0] += 1.0;
                }
            }
            Pooled::Cost { stratified } => {
                let (nodes, count) = out.split_at_mut(NODES);
                let nodes: &mut [f64; NODES] = nodes.try_into().expect("NODES sums");
                if pilot.add_variance_at_nodes(stratified, self.clamp, nodes) {
                    count[0] += 1.0;
                }
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

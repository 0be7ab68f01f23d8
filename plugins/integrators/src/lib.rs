//! Built-in integrator plugins: the MIS family, direct lighting at the first surface a camera
//! ray hits, with BSDF and light sampling combined. Every method is one file, named after the
//! plugin, that registers itself:
//!
//! - `bsdf`: BSDF sampling only.
//! - `light`: light sampling only (BSDF sampling for Dirac lobes).
//! - `balance`: half the samples each, the balance heuristic.
//! - `power`: half each, the power heuristic (β = 2).
//! - `max`: half each, the maximum heuristic.
//! - `cutoff`: half each, Veach's cutoff heuristic.
//! - `alpha`: the second-order adaptive α of Lu, Pacanowski and Granier 2013 (or a fixed α).
//! - `exact_alpha`: the α that exactly minimises a pilot's estimate of the variance.
//! - `cost_alpha`: the α that minimises a pilot's variance times the samples' measured cost.
//! - `pooled_alpha`: α from pilot statistics pooled over similar neighbouring pixels.
//! - `variance_aware`: variance-aware weights (Grittmann et al. 2019) from a pilot pass.
//! - `optimal_mis`: the optimal weights of Kondapaneni et al. 2019.
//! - `path`: path tracing with the family's per-light estimator at every vertex.
//!
//! A method is a [`allocation::Method`] run by [`mis::MisIntegrator`]: most are an
//! [`allocation::Allocation`] (how a light's N samples are split between the techniques, in
//! phases) with a [`weighting::Weighting`] (how a phase's samples are weighed), paired by
//! [`allocation::Weighted`]; one that makes its own weights implements `Method` itself. The
//! modules the plugins share, each importing only modules listed before it (the workspace's
//! `tests/module_layers.rs` checks that no module imports itself through others and that none
//! of these imports a plugin):
//!
//! - [`shading_point`], `batch`: a surface point seen by the camera, and each thread's space
//!   for the batch calls;
//! - [`estimator`]: draws one light's samples at a shading point as [`estimator::SampleRecord`]s;
//! - [`phase`]: a phase's [`phase::SampleSplit`], [`phase::PhaseRole`] and records, the
//!   [`phase::Observer`]s that see it, and a light's [`phase::LightEstimate`];
//! - [`weighting`]: the [`weighting::Weighting`] trait, per-sample heuristics (the balance
//!   heuristic among them) and the checks of a heuristic's tests;
//! - [`aovs`]: the AOV layers and their per-pixel sums, gathered by an observer;
//! - [`sampling`]: [`sampling::LightSampling`], which draws, weighs and shows the phases, in
//!   each thread's buffers;
//! - [`allocation`], [`fixed_alpha`]: the allocation traits and the one-phase allocation;
//! - [`mis`]: the integrator and the family's parameters;
//! - [`moments`], [`second_order`], [`pilot`], [`alpha_family`]: what the α methods share;
//! - [`one_point`]: one shading point's variance as a function of α, exactly (for tests);
//! - [`vertex_cache`]: the world-space cache of α at `path`'s vertices past the first.
//!
//! A new method is one file (its trait impls and its registration) and one `pub mod` line
//! (docs/writing-a-plugin.md).

pub mod allocation;
pub mod alpha_family;
pub mod aovs;
mod batch;
pub mod estimator;
pub mod fixed_alpha;
pub mod learned;
pub mod mis;
pub mod moments;
pub mod one_point;
pub mod phase;
pub mod pilot;
pub mod sampling;
pub mod second_order;
pub mod shading_point;
pub mod vertex_cache;
pub mod weighting;

pub mod alpha;
pub mod balance;
pub mod bsdf;
pub mod cost_alpha;
pub mod cutoff;
pub mod exact_alpha;
pub mod light;
pub mod max;
pub mod optimal_mis;
pub mod path;
pub mod pooled_alpha;
pub mod power;
pub mod variance_aware;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

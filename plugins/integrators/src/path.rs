//! `path`: unidirectional path tracing with the MIS family at every vertex. At each surface a
//! path meets that scatters light, every light (or one, `lights`) is estimated by the same
//! per-light estimator the direct integrators use: N samples split between BSDF and light
//! sampling by an allocation, combined by a weighting; BSDF samples that reach the light count
//! its emission, weighted against light sampling. The path goes on along the first BSDF sample
//! drawn at the vertex (a sample of the estimate, so the ray that found the emission is the ray
//! the path follows), or along a BSDF sample of its own where no estimate drew one; emission is
//! added only where the camera ray meets it directly. docs/integrators.md has the formulas and
//! the argument that the estimate is unbiased. A packet of camera samples is shaded as a wave,
//! vertex depth by vertex depth, each light's estimates drawn together for the live paths
//! ([`Integrator::shade_together`]), bit for bit what shading each path alone gives.
//!
//! Parameters:
//! - `max_depth` (integer, default -1, in [-1, 2147483647]): the longest path, in segments,
//!   Mitsuba's convention: -1 unbounded, 0 black, 1 emitters seen directly only, 2 direct
//!   lighting, d light that met at most d − 1 surfaces. Paths end at vertex 1024 whatever it
//!   says ([`MAX_VERTICES`]).
//! - `rr_depth` (integer, default 5, in [1, 2147483647]): the vertex from which Russian
//!   roulette may end a path (Mitsuba's rule: it goes on with probability
//!   min(max(throughput) · η², 0.95), η the product of the refractions' relative indices).
//! - `hide_emitters` (bool, default false): emitters the camera sees directly are hidden, as
//!   Mitsuba does: its rays pass through area emitters, and the environment behind is black.
//! - `lights` (choice, default "all"): "all" estimates every light at every vertex, as the
//!   direct integrators do; "one" one light per vertex, chosen as Mitsuba does, with
//!   probability in proportion to its emitter's `sampling_weight` (a parameter of every
//!   emitter, default 1: uniformly), its estimate divided by the probability of choosing it.
//! - `samples` (integer, default 2, in [1, 1048576]): N, samples per light at the first vertex.
//! - `deep_samples` (integer, default 2, in [1, 1048576]): N per light at the vertices past the
//!   first, split n_B = ⌊α N + ½⌋ with α = `fixed` for the fixed allocation, ½ for the others.
//! - `weighting` (choice, default "power"): how each phase's samples are weighed, at every
//!   vertex: "balance", "power" (Mitsuba's), "max", "cutoff", "optimal_mis" (the optimal
//!   weights by Kondapaneni et al.'s progressive estimator, unbiased, at vertices of N ≥ 4
//!   samples per light, balance at the others; with `allocation` "fixed" only).
//! - `threshold` (float, default 0.1, in [0, 1]): the cutoff heuristic's, with "cutoff".
//! - `allocation` (choice, default "fixed"): how the first vertex's N samples are split, as
//!   the direct plugin of that name: "fixed" (n_B = ⌊α N + ½⌋ with α = `fixed`, at every
//!   vertex), "alpha", "exact_alpha", "cost_alpha", "pooled_alpha", "variance_aware" (which
//!   weighs the first vertex's samples itself); their parameters below.
//! - `fixed` (float, default 0.5, in [0, 1]): α of the fixed allocation.
//! - The allocations' parameters, as their plugins document them, each only with an allocation
//!   that reads it: `mode` (choice, default "integrated"); `alpha_samples` (integer, default 0);
//!   `clamp` (interval, default (0.025, 0.975)); `variance` (choice, default "mixture");
//!   `cost_ratio` (float, default 0); `pilot_samples` (integer, default 0);
//!   `radius` (integer, default 2); `objective` (choice, default "exact");
//!   `block` (integer, default 16).
//! - `deep_allocation` (choice, default "split"): the vertices past the first that reflect only
//!   and are not a Dirac lobe alone: "split" estimates each light as above (N =
//!   `deep_samples`, `weighting`); the others draw one continuation from the paper's one-sample
//!   mixture q_α = α p_B + (1 − α) p_L of BSDF sampling and sampling one light J chosen among
//!   the non-delta lights in proportion to their `sampling_weight`s (uniformly by default; any
//!   choice is unbiased, as J is drawn before the direction), the path going on along whichever
//!   technique drew it
//!   with weight f / q_α (the one-sample balance heuristic), the emission it meets counted at the
//!   vertex (delta lights keep their own sample each, by `lights`: with "one", one delta light
//!   chosen among them by their weights). α is `fixed` for "mixture";
//!   read from a world-space cache ([`crate::vertex_cache`]) filled by the render's earlier
//!   passes for "learned" (the α of least estimated second moment) and "guiding_fraction"
//!   (practical path guiding's learned BSDF-sampling fraction, Müller et al.); ½ in the first
//!   pass, and in a render of one pass.
//! - `cache_resolution` (integer, default 32, in [1, 4096]): cells of the cache along the
//!   scene's longest side (with "learned" and "guiding_fraction").
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples" (of the first
//!   vertex, as the direct integrators write them) and "depth_samples" (the samples drawn at
//!   each vertex depth, channels d1 … d7 and d8plus, summed over the pixel's camera samples).
//!
//! Why one file of over 600 lines: one plugin, one file: the path loop and its wave over a
//! packet, its per-vertex estimates (the split and the one-sample mixture), light choice,
//! roulette and the depth AOV, with its tests; the mixture's cache is [`crate::vertex_cache`].

use crate::allocation::{Method, Weighted};
use crate::alpha_family::{
    ALPHA_SAMPLES_SPEC, CLAMP_SPEC, MODE_SPEC, VARIANCE_SPEC, pilot_samples_spec,
};
use crate::aovs::{self, AovRequest, LightTally};
use crate::estimator::{
    ContinuationSlot, draw_continuation, emitted, estimate_delta_light, light_density_of,
};
use crate::fixed_alpha::FixedAlpha;
use crate::max::Maximum;
use crate::mis::{SAMPLES_SPEC, read_samples};
use crate::optimal_mis::Progressive;
use crate::phase::LightEstimate;
use crate::power::Power;
use crate::sampling::{LightSampling, PhaseBuffers};
use crate::shading_point::ShadingPoint;
use crate::vertex_cache::{ALPHA_MAX, ALPHA_MIN, Learning, MixtureSample, VertexCache};
use crate::weighting::{Balance, PerSample, Weighting};
use crate::{
    alpha, balance, cost_alpha, cutoff, exact_alpha, max, optimal_mis, pooled_alpha, power,
    variance_aware,
};
use arrayvec::ArrayVec;
use lumis_core::emitter::ReferencePoint;
use lumis_core::geometry::{Intersection, Ray};
use lumis_core::integrator::WAVE_SIZE;
use lumis_core::integrator::{CameraSample, Integrator, PacketSums, shade_one_by_one};
use lumis_core::math::{Rgb, luminance};
use lumis_core::output::Aov;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::passes::PassContext;
use lumis_core::registry::IntegratorPlugin;
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "path";
pub const MAX_DEPTH: &str = "max_depth";
pub const RR_DEPTH: &str = "rr_depth";
pub const HIDE_EMITTERS: &str = "hide_emitters";
pub const LIGHTS: &str = "lights";
pub const ALL: &str = "all";
pub const ONE: &str = "one";
pub const DEEP_SAMPLES: &str = "deep_samples";
pub const WEIGHTING: &str = "weighting";
pub const ALLOCATION: &str = "allocation";
pub const FIXED: &str = "fixed";
pub const DEEP_ALLOCATION: &str = "deep_allocation";
pub const SPLIT: &str = "split";
pub const MIXTURE: &str = "mixture";
pub const LEARNED: &str = "learned";
pub const GUIDING_FRACTION: &str = "guiding_fraction";
pub const CACHE_RESOLUTION: &str = "cache_resolution";
/// The AOV layer of samples per vertex depth.
pub const DEPTH_SAMPLES: &str = "depth_samples";

/// Paths end at this vertex whatever `max_depth` says: a bound on the work of one camera
/// sample (a closed box of mirrors, Russian roulette off), so that a render stays cancellable.
/// What it leaves out is the light of paths longer than 1024 segments, at most ρ^1024 of the
/// rest for surfaces of albedo ρ (below 10⁻⁴⁶ for ρ = 0.9).
pub const MAX_VERTICES: u32 = 1024;
/// The probability with which Russian roulette lets a path go on is at most this (Mitsuba's).
const RR_MAX_PROBABILITY: f32 = 0.95;
/// Channels of the `depth_samples` layer: depths 1 to 7, then every depth from 8 on.
const DEPTH_CHANNELS: usize = 8;
/// Most emitters hidden along one camera ray ([`HIDE_EMITTERS`]): past them, black.
const MAX_HIDDEN: u32 = 64;
/// Mixture vertices of one camera sample whose statistics reach the cache: the first ones.
const MAX_RECORDED: usize = 16;

/// The layers `aovs` may ask for: the direct integrators' and [`DEPTH_SAMPLES`].
const AOV_NAMES: &[&str] = &[
    aovs::ALPHA,
    aovs::SAMPLING_VARIANCE,
    aovs::SAMPLE_COUNTS,
    DEPTH_SAMPLES,
];
const WEIGHTINGS: &[&str] = &[
    balance::NAME,
    power::NAME,
    max::NAME,
    cutoff::NAME,
    optimal_mis::NAME,
];
const ALLOCATIONS: &[&str] = &[
    FIXED,
    alpha::NAME,
    exact_alpha::NAME,
    cost_alpha::NAME,
    pooled_alpha::NAME,
    variance_aware::NAME,
];

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: MAX_DEPTH,
        kind: ParamKind::Int {
            default: Some(-1),
            min: -1,
            max: i32::MAX as i64,
        },
        unit: "segments",
        description: "longest path (Mitsuba's convention): -1 unbounded, 1 emitters seen directly, 2 direct lighting",
    },
    ParamSpec {
        name: RR_DEPTH,
        kind: ParamKind::Int {
            default: Some(5),
            min: 1,
            max: i32::MAX as i64,
        },
        unit: "",
        description: "vertex from which Russian roulette may end a path",
    },
    ParamSpec {
        name: HIDE_EMITTERS,
        kind: ParamKind::Bool {
            default: Some(false),
        },
        unit: "",
        description: "hide the emitters the camera sees directly (area emitters are seen through, the environment is black)",
    },
    ParamSpec {
        name: LIGHTS,
        kind: ParamKind::Choice {
            options: &[ALL, ONE],
            default: ALL,
        },
        unit: "",
        description: "all: every light at every vertex (as the direct integrators); one: one light per vertex, chosen in proportion to the emitters' sampling_weight (as Mitsuba)",
    },
    ParamSpec {
        description: "N: samples per light at the first vertex",
        kind: ParamKind::Int {
            default: Some(2),
            min: 1,
            max: 1 << 20,
        },
        ..SAMPLES_SPEC
    },
    ParamSpec {
        name: DEEP_SAMPLES,
        kind: ParamKind::Int {
            default: Some(2),
            min: 1,
            max: 1 << 20,
        },
        unit: "",
        description: "N: samples per light at the vertices past the first",
    },
    ParamSpec {
        name: WEIGHTING,
        kind: ParamKind::Choice {
            options: WEIGHTINGS,
            default: power::NAME,
        },
        unit: "",
        description: "how a phase's samples are weighed, at every vertex",
    },
    ParamSpec {
        name: cutoff::THRESHOLD,
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "the cutoff heuristic's threshold (weighting cutoff)",
    },
    ParamSpec {
        name: ALLOCATION,
        kind: ParamKind::Choice {
            options: ALLOCATIONS,
            default: FIXED,
        },
        unit: "",
        description: "how the first vertex's samples are split, as the direct plugin of that name (fixed: α = `fixed` at every vertex)",
    },
    ParamSpec {
        name: FIXED,
        kind: ParamKind::Float {
            default: Some(0.5),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "α of the fixed allocation",
    },
    MODE_SPEC,
    ALPHA_SAMPLES_SPEC,
    CLAMP_SPEC,
    VARIANCE_SPEC,
    ParamSpec {
        name: cost_alpha::COST_RATIO,
        kind: ParamKind::Float {
            default: Some(0.0),
            min: 0.0,
            max: 1000.0,
        },
        unit: "",
        description: "cost_alpha's c_B / c_L (0: measured)",
    },
    pilot_samples_spec(
        "M, the pilot's samples per light per pixel (0: N/8 for pooled_alpha, N/4 for variance_aware)",
    ),
    ParamSpec {
        name: pooled_alpha::RADIUS,
        kind: ParamKind::Int {
            default: Some(2),
            min: 0,
            max: 64,
        },
        unit: "pixels",
        description: "pooled_alpha's pooling radius",
    },
    ParamSpec {
        name: pooled_alpha::OBJECTIVE,
        kind: ParamKind::Choice {
            options: &[
                pooled_alpha::EXACT,
                pooled_alpha::STRATIFIED,
                pooled_alpha::SECOND_ORDER,
            ],
            default: pooled_alpha::EXACT,
        },
        unit: "",
        description: "pooled_alpha's objective",
    },
    ParamSpec {
        name: variance_aware::BLOCK,
        kind: ParamKind::Int {
            default: Some(16),
            min: 1,
            max: 4096,
        },
        unit: "pixels",
        description: "variance_aware's blocks",
    },
    ParamSpec {
        name: DEEP_ALLOCATION,
        kind: ParamKind::Choice {
            options: &[SPLIT, MIXTURE, LEARNED, GUIDING_FRACTION],
            default: SPLIT,
        },
        unit: "",
        description: "past the first vertex: split (each light, N = deep_samples) or one continuation from the mixture α p_B + (1 − α) p_L, α = fixed (mixture), learned from earlier passes in a world-space cache (learned: least second moment; guiding_fraction: Müller et al.'s BSDF-sampling fraction)",
    },
    ParamSpec {
        name: CACHE_RESOLUTION,
        kind: ParamKind::Int {
            default: Some(32),
            min: 1,
            max: 4096,
        },
        unit: "cells",
        description: "cells of the learned α's cache along the scene's longest side",
    },
    ParamSpec {
        name: crate::mis::AOVS,
        kind: ParamKind::List { options: AOV_NAMES },
        unit: "",
        description: "extra output layers: alpha, sampling_variance, samples (of the first vertex), depth_samples (samples per vertex depth)",
    },
];

/// How many lights each vertex estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Lights {
    All,
    /// One, chosen uniformly.
    One,
}

/// The layers asked for.
#[derive(Clone, Copy, Debug, Default)]
struct PathAovs {
    /// The first vertex's, as the direct integrators write them.
    first: AovRequest,
    depth_samples: bool,
}

impl PathAovs {
    /// Sums per pixel before the first vertex's: the depth channels.
    fn depth_sums(&self) -> usize {
        if self.depth_samples {
            DEPTH_CHANNELS
        } else {
            0
        }
    }

    /// Whether vertex `depth`'s lights are tallied.
    fn tallied(&self, depth: u32) -> bool {
        self.depth_samples || (depth == 1 && self.first.any())
    }
}

/// How vertices past the first are estimated ([`DEEP_ALLOCATION`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Deep {
    Split,
    /// The one-sample mixture at this α.
    Mixture(f64),
    /// The one-sample mixture, α from the cache.
    Learned(Learning),
}

/// The lights a mixture vertex treats apart, found in `preprocess`, each list with the running
/// sums of its lights' `sampling_weight`s where they are not all equal (empty: uniformly).
#[derive(Default)]
struct LightLists {
    /// Non-delta lights: J is chosen among them.
    mixed: Vec<usize>,
    mixed_cdf: Vec<f32>,
    delta: Vec<usize>,
    delta_cdf: Vec<f32>,
}

/// The running sums of `weights`, or nothing where they are all equal (a uniform choice, whose
/// arithmetic is the same without `sampling_weight`s as before them).
pub fn weights_cdf(weights: impl Iterator<Item = f32> + Clone) -> Vec<f32> {
    let mut all = weights.clone();
    let first = all.next();
    if all.all(|w| Some(w) == first) {
        return Vec::new();
    }
    weights
        .scan(0.0f32, |sum, w| {
            *sum += w;
            Some(*sum)
        })
        .collect()
}

/// The path tracer: the first vertex's method, the deeper vertices', and the path's rules.
pub struct Path {
    first: Box<dyn Method>,
    deeper: Box<dyn Method>,
    deep: Deep,
    cache_resolution: u32,
    /// With a learned α: its cache, made in `preprocess`.
    cache: Option<VertexCache>,
    light_lists: LightLists,
    /// The lights' `sampling_weight`s, cumulated, where they are not all equal (empty:
    /// `lights: one` chooses uniformly).
    light_cdf: Vec<f32>,
    /// Vertices at which lights are estimated are those below it (Mitsuba's `max_depth`;
    /// `u32::MAX` unbounded).
    max_depth: u32,
    rr_depth: u32,
    hide_emitters: bool,
    lights: Lights,
    aovs: PathAovs,
}

/// A per-sample weighting by its name in [`WEIGHTINGS`] (`optimal_mis` is a method of its own:
/// [`fixed_method`]).
fn weighting_named(name: &str, threshold: f32) -> Box<dyn Weighting> {
    match name {
        power::NAME => Box::new(PerSample(Power)),
        max::NAME => Box::new(PerSample(Maximum)),
        cutoff::NAME => Box::new(PerSample(cutoff::Cutoff { threshold })),
        _ => Box::new(PerSample(Balance)),
    }
}

/// Fewest samples per light at a vertex for `optimal_mis`'s estimate: a first phase of M = N/2
/// ≥ 2 draws both techniques, so that its Â can be regular.
const OPTIMAL_MIN_SAMPLES: u32 = 4;

/// The fixed split of N = `samples` at `alpha`, weighed by weighting `name`. `optimal_mis` is
/// Kondapaneni et al.'s progressive estimator, unbiased, rather than their direct one: a
/// vertex's N does not grow with the camera samples, so the direct estimator's O(1/N) bias
/// would stay in the image (at N = 2 its fit interpolates the two samples, and where both
/// reach a small light it returns the light's value over the whole hemisphere). Below
/// [`OPTIMAL_MIN_SAMPLES`] its first phase would be one sample, Â singular: balance.
fn fixed_method(alpha: f64, samples: u32, name: &str, threshold: f32) -> Box<dyn Method> {
    if name == optimal_mis::NAME && samples >= OPTIMAL_MIN_SAMPLES {
        return Box::new(Progressive {
            alpha,
            samples,
            first: samples / 2,
        });
    }
    Box::new(Weighted(
        FixedAlpha { alpha, samples },
        weighting_named(name, threshold),
    ))
}

/// The first vertex's method: allocation `name` ([`ALLOCATIONS`]) with its parameters, for N =
/// `samples`, weighed by `weighting`.
fn first_method(
    params: &mut Params,
    name: &str,
    samples: u32,
    (weighting_name, threshold): (&str, f32),
) -> Result<Box<dyn Method>, PluginError> {
    if name == FIXED {
        let alpha = params.float(FIXED)? as f64;
        return Ok(fixed_method(alpha, samples, weighting_name, threshold));
    }
    if weighting_name == optimal_mis::NAME {
        return Err(PluginError::Invalid(format!(
            "{}: `{WEIGHTING}` {:?} makes its own split of each vertex's samples (its \
             progressive estimator); it takes `{ALLOCATION}` {FIXED:?} only, not {name:?}",
            params.plugin(),
            optimal_mis::NAME
        )));
    }
    let weighting = weighting_named(weighting_name, threshold);
    Ok(match name {
        alpha::NAME => Box::new(Weighted(
            alpha::read_allocation(params, samples)?,
            weighting,
        )),
        exact_alpha::NAME => Box::new(Weighted(
            exact_alpha::read_allocation(params, samples)?,
            weighting,
        )),
        cost_alpha::NAME => Box::new(Weighted(
            cost_alpha::read_allocation(params, samples)?,
            weighting,
        )),
        pooled_alpha::NAME => Box::new(Weighted(
            pooled_alpha::read_allocation(params, samples)?,
            weighting,
        )),
        _ => Box::new(variance_aware::read_method(params, samples)?),
    })
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let max_depth = match params.int(MAX_DEPTH)? {
        -1 => u32::MAX,
        d => d as u32,
    };
    let rr_depth = params.int(RR_DEPTH)? as u32;
    let hide_emitters = params.bool(HIDE_EMITTERS)?;
    let lights = if params.choice(LIGHTS)? == ONE {
        Lights::One
    } else {
        Lights::All
    };
    let samples = read_samples(params)?;
    let deep_samples = params.int(DEEP_SAMPLES)? as u32;
    let weighting = params.choice(WEIGHTING)?;
    let threshold = if weighting == cutoff::NAME {
        params.float(cutoff::THRESHOLD)?
    } else {
        0.0
    };
    let allocation = params.choice(ALLOCATION)?;
    let first = first_method(params, allocation, samples, (weighting, threshold))?;
    // The fixed allocation's α holds at every vertex; an adaptive one's statistics describe the
    // first vertex only (issue 47 learns α at the others), which get the balanced split.
    let deep_alpha = if allocation == FIXED {
        params.float(FIXED)? as f64
    } else {
        0.5
    };
    let deeper = fixed_method(deep_alpha, deep_samples, weighting, threshold);
    let deep = match params.choice(DEEP_ALLOCATION)? {
        MIXTURE => Deep::Mixture(
            params
                .float(FIXED)?
                .clamp(ALPHA_MIN as f32, ALPHA_MAX as f32) as f64,
        ),
        LEARNED => Deep::Learned(Learning::SecondMoment),
        GUIDING_FRACTION => Deep::Learned(Learning::GuidingFraction),
        _ => Deep::Split,
    };
    let cache_resolution = if matches!(deep, Deep::Learned(_)) {
        params.int(CACHE_RESOLUTION)? as u32
    } else {
        0
    };
    let names = params.list(crate::mis::AOVS)?;
    let aovs = PathAovs {
        first: AovRequest::from_names(&names),
        depth_samples: names.contains(&DEPTH_SAMPLES),
    };
    Ok(Box::new(Path {
        first,
        deeper,
        deep,
        cache_resolution,
        cache: None,
        light_lists: LightLists::default(),
        light_cdf: Vec::new(),
        max_depth,
        rr_depth,
        hide_emitters,
        lights,
        aovs,
    }))
}

/// What a path has gathered and carries: the radiance so far, the throughput of its vertices'
/// samples, and the product of their relative indices of refraction.
#[derive(Clone, Copy)]
struct PathState {
    radiance: Rgb,
    throughput: Rgb,
    eta: f32,
}

impl PathState {
    /// Adds `value`, the radiance a vertex's estimate found, weighted by the throughput; a
    /// value that is not a finite number (an overflow in a BSDF or a light) is dropped.
    #[inline(always)]
    fn add(&mut self, value: Rgb) {
        let weighted = self.throughput * value;
        if weighted.is_finite() {
            self.radiance += weighted;
        }
    }
}

impl Path {
    /// What a camera ray that meets no surface (past the emitters it hides) brings back: the
    /// environment, or black where emitters are hidden.
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Rgb {
        if self.hide_emitters {
            Rgb::ZERO
        } else {
            scene.environment_radiance(ray.direction)
        }
    }

    /// A path whose camera ray `ray` first meets `hit`: the emission seen there (none where
    /// emitters are hidden), throughput one.
    fn started(&self, scene: &Scene, hit: &Intersection, ray: &Ray) -> PathState {
        PathState {
            radiance: if self.hide_emitters {
                Rgb::ZERO
            } else {
                emitted(scene, hit, ray.direction)
            },
            throughput: Rgb::ONE,
            eta: 1.0,
        }
    }

    /// The camera ray's first surface, past the emitters it hides ([`HIDE_EMITTERS`]), and
    /// whether any was hidden.
    fn first_surface(
        &self,
        scene: &Scene,
        mut ray: Ray,
        mut hit: Option<Intersection>,
    ) -> (Ray, Option<Intersection>, bool) {
        if !self.hide_emitters {
            return (ray, hit, false);
        }
        let mut hidden = 0;
        while let Some(h) = hit.filter(|h| scene.emitter_of(h).is_some()) {
            hidden += 1;
            if hidden > MAX_HIDDEN {
                return (ray, None, true);
            }
            ray = h.spawn_ray(ray.direction);
            hit = scene
                .geometry
                .first_hit_leaving(&ray, &h)
                .map(|first| scene.geometry.surface(&ray, &first));
        }
        (ray, hit, hidden > 0)
    }

    /// The lights' estimates at one vertex (`depth`, `primary` as [`LightSampling::at_vertex`]
    /// says), each added to `path`; the continuation is taken from their BSDF samples while
    /// `slot` wants it.
    #[allow(clippy::too_many_arguments)]
    fn estimate_vertex(
        &self,
        scene: &Scene,
        sp: &ShadingPoint,
        (depth, primary): (u32, bool),
        sample: &mut CameraSample,
        buffers: &mut PhaseBuffers,
        slot: &mut ContinuationSlot,
        sums: &mut [f64],
        path: &mut PathState,
    ) {
        let lights = scene.emitters.len();
        match self.lights {
            Lights::All => {
                for light in 0..lights {
                    let value = self.estimate_light(
                        scene,
                        sp,
                        light,
                        (depth, primary),
                        sample,
                        buffers,
                        slot,
                        sums,
                    );
                    path.add(value);
                }
            }
            Lights::One if lights > 0 => {
                let u = sample.sampler.next_1d();
                let (light, inverse_probability) = choose_light(&self.light_cdf, u, lights);
                let value = self.estimate_light(
                    scene,
                    sp,
                    light,
                    (depth, primary),
                    sample,
                    buffers,
                    slot,
                    sums,
                );
                path.add(value * inverse_probability);
            }
            Lights::One => {}
        }
    }

    /// One light's estimate at a vertex, its statistics added to the pixel's sums when a layer
    /// asks for them.
    #[allow(clippy::too_many_arguments)]
    fn estimate_light(
        &self,
        scene: &Scene,
        sp: &ShadingPoint,
        light: usize,
        (depth, primary): (u32, bool),
        sample: &mut CameraSample,
        buffers: &mut PhaseBuffers,
        slot: &mut ContinuationSlot,
        sums: &mut [f64],
    ) -> Rgb {
        if scene.emitters[light].is_delta() {
            return estimate_delta_light(scene, sp, light, &mut sample.sampler);
        }
        let method = if depth == 1 {
            &self.first
        } else {
            &self.deeper
        };
        let tallied = self.aovs.tallied(depth);
        let mut tally = LightTally::default();
        let mut sampling =
            LightSampling::new(scene, sp, light, sample.pixel, &mut sample.sampler, buffers)
                .with_camera_sample(sample.index)
                .at_vertex(depth, primary)
                .with_continuation(slot);
        if tallied {
            sampling = sampling.with_tally(&mut tally);
        }
        let estimate = method.estimate(&mut sampling);
        if tallied {
            let (depth_sums, first_sums) = sums.split_at_mut(self.aovs.depth_sums());
            if depth == 1 && self.aovs.first.any() {
                self.aovs.first.add(first_sums, light, &estimate, &tally);
            }
            if let Some(count) = depth_sums.get_mut(depth_channel(depth)) {
                *count += tally.samples() as f64;
            }
        }
        estimate.value
    }
}

/// One camera sample's path in a wave ([`Integrator::shade_together`]): what it
/// gathered, the surface it reached and the ray that reached it.
#[derive(Clone, Copy)]
struct WavePath {
    state: PathState,
    hit: Intersection,
    ray: Ray,
    /// Whether its first vertex is the first surface the camera ray met (no emitter hidden).
    primary: bool,
}

/// A wave's paths, made once per wave and written in place at each vertex depth (made anew at
/// each depth with `array::from_fn`, its arrays were copied whole: 8 % more instructions on
/// cornell-bounce). Path k is camera sample k's; at the current depth, member i is the i-th
/// live path, sample `owners[i]`, at shading point `points[i]`, its continuation in
/// `slots[i]`. The lists are pushed in place (arrays of the wave's size made whole were zeroed
/// whole, or built apart and copied whole: 2.4 % and 1.7 % of cornell-bounce's instructions).
struct Wave<'a> {
    /// Path k, pushed in order as the wave starts.
    paths: ArrayVec<Option<WavePath>, WAVE_SIZE>,
    /// Whether path k reached the current depth.
    live: [bool; WAVE_SIZE],
    /// The members at the current depth, pushed anew at each.
    owners: ArrayVec<usize, WAVE_SIZE>,
    points: ArrayVec<ShadingPoint<'a>, WAVE_SIZE>,
    primary: ArrayVec<bool, WAVE_SIZE>,
    slots: ArrayVec<ContinuationSlot, WAVE_SIZE>,
}

impl Default for Wave<'_> {
    fn default() -> Self {
        Wave {
            paths: ArrayVec::new(),
            live: [false; WAVE_SIZE],
            owners: ArrayVec::new(),
            points: ArrayVec::new(),
            primary: ArrayVec::new(),
            slots: ArrayVec::new(),
        }
    }
}

/// The wave's members' camera samples, member i's at index i.
type Members<'s> = ArrayVec<&'s mut CameraSample, WAVE_SIZE>;

impl Path {
    /// Vertex `depth` of the wave's live paths, as `shade` runs it for each: the lights'
    /// estimates, drawn together for all the paths, then each path's continuation, roulette
    /// and next surface. A path that ends there is no longer live.
    fn wave_vertex<'a>(
        &self,
        scene: &'a Scene,
        depth: u32,
        samples: &mut [CameraSample],
        wave: &mut Wave<'a>,
        buffers: &mut [PhaseBuffers; WAVE_SIZE],
    ) {
        // The next vertex is worth reaching if it will sample lights.
        let goes_on = depth + 1 < self.max_depth && depth + 1 < MAX_VERTICES;
        let mut members = Members::new();
        wave.owners.clear();
        wave.points.clear();
        wave.primary.clear();
        wave.slots.clear();
        let live = samples.iter_mut().zip(&wave.live).enumerate();
        for (k, sample) in live.filter_map(|(k, (sample, &live))| live.then_some((k, sample))) {
            let Some(path) = &wave.paths[k] else { continue };
            wave.owners.push(k);
            wave.points
                .push(ShadingPoint::new(scene, &path.hit, -path.ray.direction));
            wave.primary.push(depth == 1 && path.primary);
            wave.slots.push(if goes_on {
                ContinuationSlot::Wanted
            } else {
                ContinuationSlot::NotWanted
            });
            members.push(sample);
        }
        let count = members.len();
        let lights = scene.emitters.len();
        match self.lights {
            Lights::All => {
                for light in 0..lights {
                    // Times one: the same bits as `shade`'s estimate added as is.
                    let each = |_| Some(1.0);
                    self.light_together(scene, light, depth, &mut members, wave, buffers, each);
                }
            }
            Lights::One if lights > 0 => {
                // Each path's light, drawn first at the vertex as `shade` draws it; the paths
                // that chose one light are estimated together.
                let mut choices = [(0, 0.0); WAVE_SIZE];
                for (choice, sample) in choices.iter_mut().zip(members.iter_mut()) {
                    *choice = choose_light(&self.light_cdf, sample.sampler.next_1d(), lights);
                }
                let mut chosen = choices.map(|(light, _)| light);
                chosen[..count].sort_unstable();
                let mut previous = None;
                for &light in &chosen[..count] {
                    if previous == Some(light) {
                        continue;
                    }
                    previous = Some(light);
                    let those = |i: usize| {
                        let (chosen, inverse_probability) = choices[i];
                        (chosen == light).then_some(inverse_probability)
                    };
                    self.light_together(scene, light, depth, &mut members, wave, buffers, those);
                }
            }
            Lights::One => {}
        }
        let Wave {
            paths,
            live,
            owners,
            points,
            slots,
            ..
        } = wave;
        let each = owners.iter().zip(&mut members).zip(&*points).zip(&*slots);
        for (((&k, sample), sp), slot) in each {
            live[k] = false;
            let Some(path) = paths[k].as_mut() else {
                continue;
            };
            let continuation = match *slot {
                ContinuationSlot::NotWanted => continue,
                ContinuationSlot::Drawn(continuation) => continuation,
                // No estimate drew a BSDF sample: one of the path's own.
                ContinuationSlot::Wanted => draw_continuation(scene, sp, &mut sample.sampler),
            };
            let Some(continuation) = continuation else {
                continue;
            };
            path.state.throughput *= continuation.sample.weight;
            path.state.eta *= continuation.sample.eta;
            if !self.roulette(depth, &mut path.state, sample) {
                continue;
            }
            let Some(next) = continuation.hit else {
                continue;
            };
            path.hit = next;
            path.ray = continuation.ray;
            live[k] = true;
        }
    }

    /// Light `light`'s estimates at vertex `depth` of the wave's members that `weight_of(i)`
    /// takes (`Some`), drawn together for a non-delta light, each added to its path times the
    /// weight it gives (1 / probability for a light chosen at random, else 1).
    #[allow(clippy::too_many_arguments)]
    fn light_together(
        &self,
        scene: &Scene,
        light: usize,
        depth: u32,
        members: &mut Members<'_>,
        wave: &mut Wave<'_>,
        buffers: &mut [PhaseBuffers; WAVE_SIZE],
        weight_of: impl Fn(usize) -> Option<f32>,
    ) {
        let Wave {
            paths,
            owners,
            points,
            primary,
            slots,
            ..
        } = wave;
        let add = |path: &mut Option<WavePath>, value: Rgb, weight: f32| {
            if let Some(path) = path {
                path.state.add(value * weight);
            }
        };
        if scene.emitters[light].is_delta() {
            for (i, (sample, sp)) in members.iter_mut().zip(points.iter()).enumerate() {
                let Some(weight) = weight_of(i) else {
                    continue;
                };
                let value = estimate_delta_light(scene, sp, light, &mut sample.sampler);
                add(&mut paths[owners[i]], value, weight);
            }
            return;
        }
        let method = if depth == 1 {
            &self.first
        } else {
            &self.deeper
        };
        // The members estimated, in order: sampling j is member `estimated[j]`.
        let mut estimated = [0; WAVE_SIZE];
        // Pushed in place: an array of the wave's size, made whole, was zeroed whole.
        let mut samplings = ArrayVec::<Option<LightSampling>, WAVE_SIZE>::new();
        let taken = members.iter_mut().zip(points.iter()).zip(slots.iter_mut());
        let each = taken.zip(primary.iter()).enumerate();
        for ((i, (((sample, sp), slot), &primary)), buffers) in each.zip(buffers.iter_mut()) {
            if weight_of(i).is_none() {
                continue;
            }
            let sampler = &mut sample.sampler;
            let sampling = LightSampling::new(scene, sp, light, sample.pixel, sampler, buffers)
                .with_camera_sample(sample.index)
                .at_vertex(depth, primary)
                .with_continuation(slot);
            estimated[samplings.len()] = i;
            samplings.push(Some(sampling));
        }
        let n = samplings.len();
        let mut estimates = [LightEstimate::default(); WAVE_SIZE];
        method.estimate_together(&mut samplings, &mut estimates[..n]);
        for (&i, estimate) in estimated.iter().zip(&estimates).take(n) {
            if let Some(weight) = weight_of(i) {
                add(&mut paths[owners[i]], estimate.value, weight);
            }
        }
    }
}

/// Where a mixture vertex sends its path: the weight its throughput takes (a reflection: no
/// relative index), and the ray with the closest surface it meets (`None`: it leaves).
struct Step {
    weight: Rgb,
    ray: Ray,
    hit: Option<Intersection>,
}

/// A mixture vertex's sample, waiting for the radiance its path brings back.
#[derive(Clone, Copy, Default)]
struct Pending {
    sample: MixtureSample,
    /// The path's radiance before the sample's continuation, and its throughput there.
    radiance: Rgb,
    throughput: Rgb,
}

/// The mixture samples of one camera sample's path, the first [`MAX_RECORDED`].
#[derive(Default)]
struct Recording {
    pending: [Pending; MAX_RECORDED],
    count: usize,
}

impl Recording {
    #[inline(always)]
    fn push(&mut self, vertex: Pending) {
        if let Some(slot) = self.pending.get_mut(self.count) {
            *slot = vertex;
            self.count += 1;
        }
    }
}

impl Path {
    /// Whether vertex `depth` at `sp` draws from the one-sample mixture: past the first
    /// vertex, with a mixture asked for, a surface that only reflects and not only through a
    /// Dirac lobe (light sampling could reach it), and a non-delta light to sample.
    fn mixes_at(&self, depth: u32, sp: &ShadingPoint) -> bool {
        depth > 1
            && self.deep != Deep::Split
            && !sp.flags.transmission()
            && !sp.is_pure_delta()
            && !self.light_lists.mixed.is_empty()
    }

    /// A mixture vertex: delta lights sampled as `lights` says, then one direction from
    /// q_α = α p_B + (1 − α) p_J for a light J chosen among the non-delta ones by their
    /// `sampling_weight`s, traced
    /// to its closest surface; `None` where the sample is black (the path ends). The sample's
    /// densities are left in `pending` for the cache.
    fn mixture_vertex(
        &self,
        scene: &Scene,
        sp: &ShadingPoint,
        sample: &mut CameraSample,
        path: &mut PathState,
        pending: &mut Pending,
    ) -> Option<Step> {
        let delta = &self.light_lists.delta;
        match self.lights {
            Lights::All => {
                for &light in delta {
                    path.add(estimate_delta_light(scene, sp, light, &mut sample.sampler));
                }
            }
            Lights::One if !delta.is_empty() => {
                let u = sample.sampler.next_1d();
                let (index, inverse_probability) =
                    choose_light(&self.light_lists.delta_cdf, u, delta.len());
                let value = estimate_delta_light(scene, sp, delta[index], &mut sample.sampler);
                path.add(value * inverse_probability);
            }
            Lights::One => {}
        }
        let mixed = &self.light_lists.mixed;
        let u = sample.sampler.next_1d();
        // Not divided by J's probability: given J, f / q_α is unbiased on its own.
        let light = mixed[choose_light(&self.light_lists.mixed_cdf, u, mixed.len()).0];
        let alpha = match (self.deep, &self.cache) {
            (Deep::Mixture(alpha), _) => alpha,
            (_, Some(cache)) => {
                pending.sample.slot = cache.slot(sp.hit.position, sp.normal);
                cache.alpha(pending.sample.slot)
            }
            _ => 0.5,
        };
        pending.sample.alpha = alpha;
        pending.radiance = path.radiance;
        pending.throughput = path.throughput;
        let direction = sample_mixture(scene, sp, light, alpha, &mut sample.sampler)?;
        // A Dirac lobe's sample has no density to compare: it is not recorded.
        pending.sample.p_bsdf = if direction.delta {
            0.0
        } else {
            direction.p_bsdf as f64
        };
        pending.sample.p_light = direction.p_light as f64;
        let (weight, ray) = (direction.weight, direction.ray);
        let hit = scene
            .geometry
            .first_hit_leaving(&ray, &sp.hit)
            .map(|first| scene.geometry.surface(&ray, &first));
        Some(Step { weight, ray, hit })
    }

    /// Gives the cache what the path's mixture vertices saw: each one's estimate g/q, the
    /// radiance found past it divided by the throughput it was reached with.
    fn record(&self, pending: &mut [Pending], radiance: Rgb) {
        let Some(cache) = &self.cache else { return };
        for p in pending.iter_mut().filter(|p| p.sample.p_bsdf > 0.0) {
            let found = radiance - p.radiance;
            let per = |found: f32, throughput: f32| {
                if throughput > 0.0 {
                    found / throughput
                } else {
                    0.0
                }
            };
            let estimate = Rgb::new(
                per(found.x, p.throughput.x),
                per(found.y, p.throughput.y),
                per(found.z, p.throughput.z),
            );
            p.sample.y = luminance(estimate) as f64;
            cache.record(&p.sample);
        }
    }
}

impl Path {
    /// Whether the path goes on past vertex `depth` with its new throughput: not if that is
    /// not a positive finite number, nor if Russian roulette ends it (from `rr_depth` on; the
    /// throughput of a path that goes on is divided by its probability of going on).
    #[inline(always)]
    fn roulette(&self, depth: u32, path: &mut PathState, sample: &mut CameraSample) -> bool {
        let largest = path.throughput.max_element();
        if !(largest > 0.0 && largest.is_finite()) {
            return false;
        }
        if depth >= self.rr_depth {
            let go_on = (largest * path.eta * path.eta).min(RR_MAX_PROBABILITY);
            if sample.sampler.next_1d() >= go_on {
                return false;
            }
            path.throughput /= go_on;
        }
        true
    }
}

/// One direction drawn from the one-sample mixture at a shading point ([`sample_mixture`]).
pub struct MixtureDirection {
    /// The ray leaving the point along it.
    pub ray: Ray,
    /// f |cos θ| / q_α (for a Dirac lobe of the BSDF, its sample's weight over α).
    pub weight: Rgb,
    /// Its densities under BSDF sampling and under light J's sampling, in solid angle.
    pub p_bsdf: f32,
    pub p_light: f32,
    /// Drawn from a Dirac lobe of the BSDF (only BSDF sampling draws it).
    pub delta: bool,
}

/// Draws one direction at `sp`, a point whose BSDF only reflects, from the one-sample mixture
/// q_α = α p_B + (1 − α) p_J of BSDF sampling and non-delta light `light`'s sampling; `None`
/// where the drawn direction carries nothing (no direction drawn, or one the surface does not
/// scatter into). Its density over the directions it returns is [`mixture_density`].
pub fn sample_mixture(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    alpha: f64,
    sampler: &mut Sampler,
) -> Option<MixtureDirection> {
    let mixture =
        |p_bsdf: f32, p_light: f32| (alpha * p_bsdf as f64 + (1.0 - alpha) * p_light as f64) as f32;
    if (sampler.next_1d() as f64) < alpha {
        let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
        let s = sp.bsdf.sample(&sp.ctx, sp.wo, u_lobe, u)?;
        let wi = sp.frame.to_world(s.wi);
        if !sp.leaves_toward::<false>(wi, s.wi) {
            return None;
        }
        let ray = sp.origin.ray(&sp.hit, wi);
        if s.delta {
            // Only BSDF sampling draws a Dirac lobe: chosen with probability α.
            return Some(MixtureDirection {
                ray,
                weight: s.weight / alpha as f32,
                p_bsdf: s.pdf,
                p_light: 0.0,
                delta: true,
            });
        }
        let p_light = light_density_of(scene, sp, light, &ray);
        Some(MixtureDirection {
            ray,
            weight: s.weight * (s.pdf / mixture(s.pdf, p_light)),
            p_bsdf: s.pdf,
            p_light,
            delta: false,
        })
    } else {
        let reference = ReferencePoint {
            position: sp.hit.position,
        };
        let ls = scene.emitters[light].sample_direction(&reference, sampler.next_2d())?;
        let wi = sp.frame.to_local(ls.wi);
        if !sp.scatters_from_sample::<false>(&ls, wi.z) {
            return None;
        }
        let (f, p_bsdf) = sp.bsdf.eval_pdf(&sp.ctx, sp.wo, wi);
        if f == Rgb::ZERO {
            return None;
        }
        Some(MixtureDirection {
            ray: sp.origin.ray(&sp.hit, ls.wi),
            weight: f / mixture(p_bsdf, ls.pdf),
            p_bsdf,
            p_light: ls.pdf,
            delta: false,
        })
    }
}

/// q_α toward world direction `wi` at `sp` for light `light`: the density of
/// [`sample_mixture`]'s non-Dirac directions (for its χ² test).
pub fn mixture_density(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    alpha: f64,
    wi: glam::Vec3,
) -> f64 {
    let p_bsdf = sp.bsdf.pdf(&sp.ctx, sp.wo, sp.frame.to_local(wi)) as f64;
    let p_light = light_density_of(scene, sp, light, &sp.origin.ray(&sp.hit, wi)) as f64;
    alpha * p_bsdf + (1.0 - alpha) * p_light
}

/// The light `lights: one` chooses with `u` among `lights` lights, and 1 / its probability:
/// uniformly where `cdf` is empty, else in proportion to the lights' `sampling_weight`s
/// (Mitsuba's), `cdf` their running sums.
#[inline(always)]
pub fn choose_light(cdf: &[f32], u: f32, lights: usize) -> (usize, f32) {
    let Some(&total) = cdf.last() else {
        return (
            ((u * lights as f32) as usize).min(lights - 1),
            lights as f32,
        );
    };
    let target = u * total;
    // The first light whose interval holds the target: never one of weight 0, even where
    // rounding puts the target at the total.
    let light = cdf
        .partition_point(|&c| c <= target)
        .min(cdf.partition_point(|&c| c < total));
    let weight = cdf[light] - light.checked_sub(1).map_or(0.0, |l| cdf[l]);
    (light, total / weight)
}

/// The `depth_samples` channel of vertex `depth`.
fn depth_channel(depth: u32) -> usize {
    (depth as usize).min(DEPTH_CHANNELS) - 1
}

impl Integrator for Path {
    fn aovs(&self, scene: &Scene) -> Vec<Aov> {
        let mut layers = Vec::new();
        if self.aovs.depth_samples {
            let mut channels: Vec<String> = (1..DEPTH_CHANNELS).map(|d| format!("d{d}")).collect();
            channels.push(format!("d{DEPTH_CHANNELS}plus"));
            layers.push(Aov {
                name: DEPTH_SAMPLES.into(),
                channels,
                preview: false,
            });
        }
        layers.extend(self.aovs.first.declare(scene));
        layers
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        self.aovs.depth_sums() + self.aovs.first.pixel_sums(scene)
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.first.preprocess(scene);
        self.deeper.preprocess(scene);
        let weights = &scene.emitter_weights;
        self.light_cdf = weights_cdf(weights.iter().copied());
        if self.deep != Deep::Split {
            let (delta, mixed): (Vec<usize>, Vec<usize>) =
                (0..scene.emitters.len()).partition(|&e| scene.emitters[e].is_delta());
            self.light_lists = LightLists {
                mixed_cdf: weights_cdf(mixed.iter().map(|&e| weights[e])),
                mixed,
                delta_cdf: weights_cdf(delta.iter().map(|&e| weights[e])),
                delta,
            };
        }
        if let Deep::Learned(learning) = self.deep {
            self.cache = Some(VertexCache::new(
                scene,
                self.cache_resolution,
                learning,
                0.5,
            ));
        }
    }

    fn begin_pass(&mut self, _scene: &Scene, pass: &PassContext<'_>) {
        // Pass k reads what passes < k added.
        if let Some(cache) = &mut self.cache
            && pass.index > 0
        {
            cache.freeze();
        }
    }

    fn learned_state(&self) -> Vec<u8> {
        self.cache.as_ref().map_or_else(Vec::new, VertexCache::save)
    }

    fn restore_learned_state(&mut self, state: &[u8]) -> Result<(), String> {
        match &mut self.cache {
            _ if state.is_empty() => Ok(()),
            Some(cache) => cache.restore(state),
            None => Err(format!(
                "this `{NAME}` learns no α across passes (`{DEEP_ALLOCATION}` is neither \"{LEARNED}\" nor \"{GUIDING_FRACTION}\"), but the state holds a cache of α"
            )),
        }
    }

    fn merge_learned_states(&self, a: &[u8], b: &[u8]) -> Result<Vec<u8>, String> {
        match (a.is_empty(), b.is_empty()) {
            (true, true) => Ok(Vec::new()),
            (false, false) => crate::vertex_cache::merge(a, b),
            _ => Err("one shard holds a cache of α and the other none".into()),
        }
    }

    fn shade(&self, scene: &Scene, sample: &mut CameraSample, sums: &mut [f64]) -> Rgb {
        if self.max_depth == 0 {
            return Rgb::ZERO;
        }
        let mut traced_now = None;
        let hit = sample.hit(scene, &mut traced_now).copied();
        let (mut ray, hit, hidden) = self.first_surface(scene, sample.ray, hit);
        let Some(mut hit) = hit else {
            return self.escaped(scene, &ray);
        };
        let mut path = self.started(scene, &hit, &ray);
        // Only with a cache: without, nothing is written (a `None` is its tag alone).
        let mut recording = self.cache.as_ref().map(|_| Recording::default());
        PhaseBuffers::with_thread_local(|buffers| {
            for depth in 1..MAX_VERTICES {
                // Mitsuba's vertex d − 1 samples lights when d < max_depth.
                if depth >= self.max_depth {
                    break;
                }
                let sp = ShadingPoint::new(scene, &hit, -ray.direction);
                // The next vertex is worth reaching if it will sample lights.
                let goes_on = depth + 1 < self.max_depth && depth + 1 < MAX_VERTICES;
                if self.mixes_at(depth, &sp) {
                    if self.aovs.depth_samples {
                        sums[depth_channel(depth)] += 1.0;
                    }
                    let mut vertex = Pending::default();
                    let step = self.mixture_vertex(scene, &sp, sample, &mut path, &mut vertex);
                    let Some(step) = step else { break };
                    path.throughput *= step.weight;
                    if let Some(recording) = &mut recording {
                        recording.push(vertex);
                    }
                    // What the direction meets is the vertex's light estimate.
                    let Some(next) = step.hit else {
                        path.add(scene.environment_radiance(step.ray.direction));
                        break;
                    };
                    path.add(emitted(scene, &next, step.ray.direction));
                    if !goes_on || !self.roulette(depth, &mut path, sample) {
                        break;
                    }
                    hit = next;
                    ray = step.ray;
                    continue;
                }
                let mut slot = if goes_on {
                    ContinuationSlot::Wanted
                } else {
                    ContinuationSlot::NotWanted
                };
                let vertex = (depth, depth == 1 && !hidden);
                self.estimate_vertex(
                    scene, &sp, vertex, sample, buffers, &mut slot, sums, &mut path,
                );
                let continuation = match slot {
                    ContinuationSlot::NotWanted => break,
                    ContinuationSlot::Drawn(continuation) => continuation,
                    ContinuationSlot::Wanted => {
                        // No estimate drew a BSDF sample: one of the path's own.
                        if self.aovs.depth_samples {
                            sums[depth_channel(depth)] += 1.0;
                        }
                        draw_continuation(scene, &sp, &mut sample.sampler)
                    }
                };
                let Some(continuation) = continuation else {
                    break;
                };
                path.throughput *= continuation.sample.weight;
                path.eta *= continuation.sample.eta;
                if !self.roulette(depth, &mut path, sample) {
                    break;
                }
                let Some(next) = continuation.hit else {
                    break;
                };
                hit = next;
                ray = continuation.ray;
            }
        });
        if let Some(recording) = &mut recording {
            self.record(&mut recording.pending[..recording.count], path.radiance);
        }
        path.radiance
    }

    /// Asks for waves of [`WAVE_SIZE`] camera samples: at deep vertices the live paths'
    /// points are scattered over the scene's BSDFs, and only many paths fill a BSDF's lanes
    /// (the path race's box in 0.906 [0.870, 0.944] of the time it took in packets of 16,
    /// docs/performance.md).
    fn wave_size(&self) -> usize {
        WAVE_SIZE
    }

    /// The wave's paths advanced together, vertex depth by vertex depth
    /// ([`wave_vertex`](Path::wave_vertex)): at each depth every light's estimates at all the
    /// live paths' shading points are drawn together ([`Method::estimate_together`], each path
    /// taking its continuation from its first BSDF sample there, as `shade` does), then each
    /// path goes on or ends. Each path draws from its own stream in the order `shade` draws, so
    /// each sample gets what `shade` gives, bit for bit. One by one, through `shade`: with AOVs
    /// (their sums), with a deeper mixture (its vertices, the cache's records, are drawn per
    /// path), with an allocation that learns, at `max_depth` 0, and for a wave of one, which
    /// has nothing to share.
    fn shade_together(
        &self,
        scene: &Scene,
        samples: &mut [CameraSample],
        sums: &mut PacketSums<'_>,
        radiance: &mut [Rgb],
    ) {
        if self.aovs.first.any()
            || self.aovs.depth_samples
            || self.deep != Deep::Split
            || self.first.learning()
            || self.deeper.learning()
            || self.max_depth == 0
            || samples.len() == 1
            || samples.len() > WAVE_SIZE
        {
            return shade_one_by_one(self, scene, samples, sums, radiance);
        }
        assert_eq!(samples.len(), radiance.len(), "one estimate per sample");
        let mut wave = Wave::default();
        let started = samples.iter().zip(radiance.iter_mut());
        for (k, (sample, radiance)) in started.enumerate() {
            let mut traced_now = None;
            let hit = sample.hit(scene, &mut traced_now).copied();
            let (ray, hit, hidden) = self.first_surface(scene, sample.ray, hit);
            let Some(hit) = hit else {
                *radiance = self.escaped(scene, &ray);
                wave.paths.push(None);
                continue;
            };
            wave.paths.push(Some(WavePath {
                state: self.started(scene, &hit, &ray),
                hit,
                ray,
                primary: !hidden,
            }));
            wave.live[k] = true;
        }
        PhaseBuffers::with_thread_local_wave(|buffers| {
            // Mitsuba's vertex d − 1 samples lights when d < max_depth.
            for depth in 1..MAX_VERTICES.min(self.max_depth) {
                if !wave.live.contains(&true) {
                    break;
                }
                self.wave_vertex(scene, depth, samples, &mut wave, buffers);
            }
        });
        for (path, radiance) in wave.paths.iter().zip(radiance) {
            if let Some(path) = path {
                *radiance = path.state.radiance;
            }
        }
    }

    fn resolve(&self, scene: &Scene, sums: &[f64], _samples: u32, aovs: &mut [f32]) {
        let depth = self.aovs.depth_sums();
        for (value, sum) in aovs.iter_mut().zip(&sums[..depth]) {
            *value = *sum as f32;
        }
        self.aovs
            .first
            .resolve(scene, &sums[depth..], &mut aovs[depth..]);
    }
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "path tracing with the MIS family's per-light estimator (any weighting, any first-vertex allocation) at every vertex",
        params: PARAMS,
        create,
    }
}

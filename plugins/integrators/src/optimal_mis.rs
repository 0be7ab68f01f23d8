//! `optimal_mis`: direct lighting with the optimal MIS weights of Kondapaneni, Vévoda, Grittmann,
//! Skřivan, Slusallek and Křivánek (SIGGRAPH 2019). For one shading point and light, with
//! counts n_B, n_L and p_mix = n_B p_B + n_L p_L, the weights that minimise the variance of the
//! multi-sample estimator are
//!
//!   w_t(x) = a_t p_t / f + (n_t p_t / p_mix) · (1 − (a_B p_B + a_L p_L) / f),
//!
//! where a = (a_B, a_L) solves the 2×2 system A a = b, A_ik = ∫ p_i p_k / p_mix, b_i = ∫ f p_i /
//! p_mix; the estimate is then a_B + a_L + Σ_samples (f − a_B p_B − a_L p_L) / p_mix, the
//! balance heuristic applied to f minus the control variate a_B p_B + a_L p_L. A and b are
//! estimated from the samples themselves, Â_ik = Σ p_i p_k / p_mix², b̂_i = Σ f p_i / p_mix², over
//! every sample, black ones included: these phases are drawn with both densities of every
//! record. A technique's failed draws (no direction) and Dirac samples count as points only
//! their technique reaches (p_t / p_mix = 1/n_t). RGB is handled per channel: one Â, three b̂.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "direct"): "direct" — N samples at α = ½, and the estimate is
//!   â_B + â_L with â = Â⁻¹ b̂ from those same samples (their direct estimator: consistent, its
//!   bias O(1/N)); "progressive" — M samples at α = ½ give the balance estimate L̂₁ and â; the
//!   other N − M, at α = ½, are weighed by the optimal weights with â (clipped to [0, 1] and
//!   renormalised, so that they stay a partition of unity and the image non-negative), giving
//!   L̂₂; the estimate is (M·L̂₁ + (N − M)·L̂₂)/N, unbiased (â depends only on the first phase).
//! - `alpha_samples` (integer, default 0 = N/2, in [0, 1048576]): M in "progressive" mode.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! Guards: Â is singular or ill-conditioned when its determinant is below 10⁻⁶ Â_BB Â_LL (the
//! two techniques' densities nearly proportional over the samples, or one never non-zero), and
//! then the phase falls back to the balance heuristic, as it does for a channel whose direct
//! estimate is negative or not finite (both vanish as N grows, so the direct estimator stays
//! consistent). Delta lights take one light sample each.

use crate::allocation::{Method, Weighted};
use crate::alpha_family::{self, at_most_samples};
use crate::estimator::SampleRecord;
use crate::fixed_alpha::FixedAlpha;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::phase::{LightEstimate, Phase, PhaseRole, SampleSplit};
use crate::sampling::LightSampling;
use crate::weighting::{Balance, PerSample, Weighting};
use glam::DVec3;
use lumis_core::integrator::Integrator;
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "optimal_mis";
/// Parameter: [`DIRECT`] or [`PROGRESSIVE`].
pub const MODE: &str = "mode";
pub const DIRECT: &str = "direct";
pub const PROGRESSIVE: &str = "progressive";
/// Parameter: M, the first phase's samples in progressive mode.
pub const ALPHA_SAMPLES: &str = alpha_family::ALPHA_SAMPLES;
/// Â is treated as singular below this determinant relative to Â_BB Â_LL.
const CONDITION: f64 = 1e-6;

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: MODE,
        kind: ParamKind::Choice {
            options: &[DIRECT, PROGRESSIVE],
            default: DIRECT,
        },
        unit: "",
        description: "direct: the weights' coefficients from the samples they weigh (consistent); progressive: from a first phase, applied to the second (unbiased)",
    },
    ParamSpec {
        name: ALPHA_SAMPLES,
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description: "M, the first phase's samples in progressive mode (0: N/2)",
    },
    AOVS_SPEC,
];

/// What a record contributes to the system: u_t = p_t / p_mix for each technique and g = f /
/// p_mix (per channel). `bsdf` says which technique drew it.
#[inline]
fn record_terms(r: &SampleRecord, bsdf: bool, (n_b, n_l): (f64, f64)) -> ([f64; 2], DVec3) {
    let f = r.f.as_dvec3();
    if r.delta {
        // A Dirac sample: a point only BSDF sampling reaches; f is already f / p_B.
        return ([1.0 / n_b, 0.0], f / n_b);
    }
    let (p_b, p_l) = (r.p_bsdf as f64, r.p_light as f64);
    let own = if bsdf { p_b } else { p_l };
    if own <= 0.0 {
        // A failed draw: a point only this technique reaches, where f = 0.
        return if bsdf {
            ([1.0 / n_b, 0.0], DVec3::ZERO)
        } else {
            ([0.0, 1.0 / n_l], DVec3::ZERO)
        };
    }
    let p_mix = n_b * p_b + n_l * p_l;
    ([p_b / p_mix, p_l / p_mix], f / p_mix)
}

/// The optimal-MIS system Â a = b̂ of one phase (Â symmetric: BB, BL, LL).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OptimalSystem {
    pub a_bb: f64,
    pub a_bl: f64,
    pub a_ll: f64,
    /// b̂_B, b̂_L per channel.
    pub b: [DVec3; 2],
}

/// The coefficients (a_B, a_L) per channel.
pub type Coefficients = [DVec3; 2];

impl OptimalSystem {
    /// Â and b̂ from every record of `phase` (drawn with both densities).
    pub fn from_phase(phase: &Phase) -> Self {
        let counts = (phase.split.n_bsdf as f64, phase.split.n_light as f64);
        let mut s = OptimalSystem::default();
        for (i, r) in phase.records.iter().enumerate() {
            let (u, g) = record_terms(r, i < phase.split.n_bsdf as usize, counts);
            s.a_bb += u[0] * u[0];
            s.a_bl += u[0] * u[1];
            s.a_ll += u[1] * u[1];
            s.b[0] += g * u[0];
            s.b[1] += g * u[1];
        }
        s
    }

    /// a = Â⁻¹ b̂ per channel, or `None` if Â is singular or ill-conditioned (determinant
    /// below 10⁻⁶ Â_BB Â_LL) or the result is not finite.
    pub fn solve(&self) -> Option<Coefficients> {
        let det = self.a_bb * self.a_ll - self.a_bl * self.a_bl;
        // Also rejects a NaN determinant.
        let well_conditioned = det > CONDITION * self.a_bb * self.a_ll;
        if !well_conditioned || !det.is_finite() {
            return None;
        }
        let a_b = (self.a_ll * self.b[0] - self.a_bl * self.b[1]) / det;
        let a_l = (self.a_bb * self.b[1] - self.a_bl * self.b[0]) / det;
        (a_b.is_finite() && a_l.is_finite()).then_some([a_b, a_l])
    }
}

/// Kondapaneni et al.'s direct estimator: the coefficients from the phase's own samples, the
/// estimate â_B + â_L per channel; per record, its term of the control-variate form,
/// g − â·u + (â_B + â_L)/n, which add up to it. The balance heuristic where Â is ill-conditioned or a
/// channel's estimate is negative or not finite.
pub struct DirectOptimal;

impl Weighting for DirectOptimal {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        let balance = PerSample(Balance).weigh(phase, contributions);
        let Some([a_b, a_l]) = OptimalSystem::from_phase(phase).solve() else {
            return balance;
        };
        let estimate = a_b + a_l;
        // Channels whose direct estimate is usable.
        let usable = |c: usize| estimate[c].is_finite() && estimate[c] >= 0.0;
        if !(0..3).any(usable) {
            return balance;
        }
        let counts = (phase.split.n_bsdf as f64, phase.split.n_light as f64);
        let share = estimate / phase.records.len() as f64;
        for (i, (r, c)) in phase
            .records
            .iter()
            .zip(contributions.iter_mut())
            .enumerate()
        {
            let (u, g) = record_terms(r, i < phase.split.n_bsdf as usize, counts);
            let term = g - a_b * u[0] - a_l * u[1] + share;
            for k in (0..3).filter(|&k| usable(k)) {
                c[k] = term[k] as f32;
            }
        }
        let mut value = balance;
        for k in (0..3).filter(|&k| usable(k)) {
            value[k] = estimate[k] as f32;
        }
        value
    }

    fn needs_both_densities(&self) -> bool {
        true
    }
}

/// A weighting drawn with both densities of every record that weighs like `W`: the first
/// phase of the progressive mode, which is weighed by the balance heuristic but sets up Â.
pub struct WithBothDensities<W>(pub W);

impl<W: Weighting> Weighting for WithBothDensities<W> {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        self.0.weigh(phase, contributions)
    }

    fn needs_both_densities(&self) -> bool {
        true
    }
}

/// The optimal weights for given coefficients, where f > 0 (channel by channel), clipped to
/// [0, 1] and renormalised to sum to one: unbiased for any coefficients (a partition of unity
/// wherever f ≠ 0) and never negative. Dirac samples weigh 1. (The optimal estimator's terms
/// for black samples, −(a·p)/p_mix, are not part of a weighting: with them the estimate can be
/// negative.)
pub struct ClippedOptimal(pub Coefficients);

impl Weighting for ClippedOptimal {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        let [a_b, a_l] = self.0;
        let (n_b, n_l) = (phase.split.n_bsdf as f64, phase.split.n_light as f64);
        let mut value = Rgb::ZERO;
        for (i, (r, c)) in phase
            .records
            .iter()
            .zip(contributions.iter_mut())
            .enumerate()
        {
            if r.is_black() {
                continue;
            }
            let bsdf = i < phase.split.n_bsdf as usize;
            let own_count = if bsdf { n_b } else { n_l };
            if r.delta {
                *c = r.f / own_count as f32;
                value += *c;
                continue;
            }
            let (p_b, p_l) = (r.p_bsdf as f64, r.p_light as f64);
            let p_mix = n_b * p_b + n_l * p_l;
            let (balance_b, balance_l) = (n_b * p_b / p_mix, n_l * p_l / p_mix);
            let f = r.f.as_dvec3();
            let mut out = DVec3::ZERO;
            for k in 0..3 {
                if f[k] <= 0.0 {
                    continue;
                }
                let rest = 1.0 - (a_b[k] * p_b + a_l[k] * p_l) / f[k];
                let w_b = (a_b[k] * p_b / f[k] + balance_b * rest).clamp(0.0, 1.0);
                let w_l = (a_l[k] * p_l / f[k] + balance_l * rest).clamp(0.0, 1.0);
                let (w_b, w_l) = if w_b + w_l > 0.0 {
                    (w_b / (w_b + w_l), w_l / (w_b + w_l))
                } else {
                    (balance_b, balance_l)
                };
                let (w, p) = if bsdf { (w_b, p_b) } else { (w_l, p_l) };
                let term = w * f[k] / (own_count * p);
                out[k] = if term.is_finite() { term } else { 0.0 };
            }
            *c = out.as_vec3();
            value += *c;
        }
        value
    }
}

/// The progressive mode: M samples at α (balance, setting up Â), then N − M at α weighed by
/// [`ClippedOptimal`] with the first phase's coefficients (balance if Â was ill-conditioned):
/// its own weights, so a [`Method`], given no weighting. α is ½ in this plugin (`path` gives
/// its `fixed`).
pub struct Progressive {
    /// α, the fraction of each phase's samples drawn by BSDF sampling.
    pub alpha: f64,
    /// N, samples per light per camera sample.
    pub samples: u32,
    /// M, the first phase's samples.
    pub first: u32,
}

impl Method for Progressive {
    fn estimate(&self, sampling: &mut LightSampling) -> LightEstimate {
        let n = self.samples;
        let m = self.first.min(n);
        let rest = n - m;
        let first_role = PhaseRole {
            counted: true,
            measured: rest < 2,
        };
        let first = sampling.phase(
            SampleSplit::new(self.alpha, m),
            first_role,
            &WithBothDensities(PerSample(Balance)),
            &mut (),
        );
        let alpha = SampleSplit::new(self.alpha, n).alpha();
        if rest == 0 {
            return LightEstimate {
                value: first,
                alpha,
            };
        }
        let coefficients = sampling
            .last_phase()
            .and_then(|(phase, _)| OptimalSystem::from_phase(&phase).solve());
        let second_role = PhaseRole {
            counted: true,
            measured: rest >= 2,
        };
        let split = SampleSplit::new(self.alpha, rest);
        let second = match coefficients {
            Some(a) => sampling.phase(split, second_role, &ClippedOptimal(a), &mut ()),
            None => sampling.phase(split, second_role, &PerSample(Balance), &mut ()),
        };
        LightEstimate {
            value: (first * m as f32 + second * rest as f32) / n as f32,
            alpha,
        }
    }
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let given = params.int(ALPHA_SAMPLES)? as u32;
    if params.choice(MODE)? == DIRECT {
        let allocation = FixedAlpha {
            alpha: 0.5,
            samples,
        };
        return MisIntegrator::boxed(params, Weighted(allocation, DirectOptimal));
    }
    let first = if given == 0 { samples / 2 } else { given };
    let first = at_most_samples(params, ALPHA_SAMPLES, first, samples, "")?;
    MisIntegrator::boxed(
        params,
        Progressive {
            alpha: 0.5,
            samples,
            first,
        },
    )
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the optimal MIS weights of Kondapaneni et al. 2019 (direct or progressive estimate of their coefficients)",
        params: PARAMS,
        create,
    }
}

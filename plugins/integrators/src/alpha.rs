//! `alpha`: direct lighting with the second-order adaptive α of Lu, Pacanowski and Granier
//! (Pacific Graphics 2013): per shading point and light, the fraction α of the N samples drawn
//! from the BSDF (the rest from the light) minimises a second-order Taylor approximation of the
//! variance of the mixture estimator, estimated from samples taken at α = ½:
//! α̂ = clamp(½ + ¼ · Î₁/Î₂), Î₁ = mean of f²Δp/p̄³, Î₂ = mean of f²Δp²/p̄⁴, with p̄ = (p_B + p_L)/2
//! and Δp = (p_B − p_L)/2 (α̂ = ½ when Î₂ is zero or not finite). Delta lights take one light
//! sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "integrated"): "integrated" — M samples at α = ½ give L̂₁ and α̂,
//!   the other N − M at α̂ give L̂₂, and the estimate is (M·L̂₁ + (N − M)·L̂₂)/N (paper, Table 2);
//!   "preprocessed" — M pilot samples at α = ½ give α̂ only, then N fresh samples at α̂ (paper,
//!   Table 1); "fixed" — α = `fixed` everywhere (½ reproduces `balance` bit for bit).
//! - `alpha_samples` (integer, default 0 = N/2 integrated, 4096 preprocessed): M.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): bounds of α̂.
//! - `fixed` (float, default 0.5, in [0, 1]): α in "fixed" mode.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! Counts: n_B = ⌊α·n + ½⌋ (at least one sample per technique when 0 < α < 1), n_L = n − n_B; the
//! balance weights use these realised counts, so each phase is unbiased for any α̂ chosen from
//! samples it does not reuse.

use crate::allocation::{Allocation, FixedAlpha, LightEstimate, LightSampling, SampleSplit};
use crate::balance::Balance;
use crate::estimator::SampleRecord;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC};
use crate::phase::{Observer, Phase, PhaseRole};
use crate::weighting::{PerSample, Weighting};
use lumis_core::geometry::PACKET_SIZE;
use lumis_core::integrator::Integrator;
use lumis_core::math::lanes::{LaneKernel, Lanes, MAX_WIDTH, Mask, V3, with_widest_lanes};
use lumis_core::math::{Rgb, luminance, luminance_lanes};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

/// The plugin's name in scene files.
pub const NAME: &str = "alpha";
/// Parameter: how α is obtained, one of [`INTEGRATED`], [`PREPROCESSED`], [`FIXED`].
pub const MODE: &str = "mode";
pub const INTEGRATED: &str = "integrated";
pub const PREPROCESSED: &str = "preprocessed";
pub const FIXED: &str = "fixed";
/// Parameter: M, the samples at α = ½ that estimate α̂.
pub const ALPHA_SAMPLES: &str = "alpha_samples";
/// Parameter: the interval α̂ is clamped to.
pub const CLAMP: &str = "clamp";
/// Parameter: α in [`FIXED`] mode (its name is the mode's).
pub const FIXED_ALPHA: &str = FIXED;

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    ParamSpec {
        name: MODE,
        kind: ParamKind::Choice {
            options: &[INTEGRATED, PREPROCESSED, FIXED],
            default: INTEGRATED,
        },
        unit: "",
        description: "how α is obtained: integrated (paper Table 2), preprocessed (Table 1) or fixed",
    },
    ParamSpec {
        name: ALPHA_SAMPLES,
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description: "M, samples at α = ½ that estimate α (0: N/2 integrated, 4096 preprocessed)",
    },
    ParamSpec {
        name: CLAMP,
        kind: ParamKind::Interval {
            default: [0.025, 0.975],
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "interval α̂ is clamped to",
    },
    ParamSpec {
        name: FIXED_ALPHA,
        kind: ParamKind::Float {
            default: Some(0.5),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "α in fixed mode",
    },
    AOVS_SPEC,
];

/// The paper's sums over samples drawn at α = ½ (a stratified sample of p̄): M·Î₁ = Σ f²Δp/p̄³
/// and M·Î₂ = Σ f²Δp²/p̄⁴, with f the luminance of the integrand, summed in f64. Samples with
/// f = 0 or p̄ not a positive finite number add nothing. A Dirac BSDF sample (p_B → ∞) adds the
/// limit of both terms, 4 (f/p_B)², which gives the supplemental's α = 3/4 for mirrors.
///
/// As an [`Observer`], it computes the terms of a phase in lanes, in `f32`, written as
/// q² r and q² r² with q = f/p̄ (the sample's estimate at α = ½) and r = Δp/p̄ in [−1, 1]; they
/// are summed in lanes over blocks of [`BLOCK`] records, whose sums join the f64 totals. A
/// block whose lane sums overflow, are not numbers, or are too small for `f32` to hold their
/// digits (Î₂'s below [`SMALLEST_LANE_SUM`]) is summed again record by record in f64
/// ([`add`](Self::add)), so the f64 range is kept.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SecondOrderMoments {
    pub i1: f64,
    pub i2: f64,
}

impl SecondOrderMoments {
    /// Adds one sample of scalar integrand `f` and densities `p_bsdf`, `p_light`.
    pub fn add(&mut self, f: f32, p_bsdf: f32, p_light: f32) {
        let (f, p_b, p_l) = (f as f64, p_bsdf as f64, p_light as f64);
        let p_bar = 0.5 * (p_b + p_l);
        // p̄ positive and finite in two comparisons (NaN fails both).
        if f == 0.0 || !(p_bar > 0.0 && p_bar < f64::INFINITY) {
            return;
        }
        let delta_p = 0.5 * (p_b - p_l);
        let f2 = f * f;
        self.i1 += f2 * delta_p / (p_bar * p_bar * p_bar);
        self.i2 += f2 * delta_p * delta_p / (p_bar * p_bar * p_bar * p_bar);
    }

    /// Adds one Dirac BSDF sample whose f / p_B is `weight` (luminance).
    pub fn add_dirac(&mut self, weight: f32) {
        let w = weight as f64;
        self.i1 += 4.0 * w * w;
        self.i2 += 4.0 * w * w;
    }

    /// α̂ = ½ + ¼ · Î₁/Î₂ clamped to `clamp`, or ½ when Î₂ is zero or not finite (no sample saw
    /// the light, or p_B = p_L everywhere).
    pub fn alpha(&self, clamp: [f64; 2]) -> f64 {
        second_order_alpha(self.i1, self.i2)
            .unwrap_or(0.5)
            .clamp(clamp[0], clamp[1])
    }

    /// Adds one record's terms in f64 (the lanes compute the same terms in `f32`).
    pub fn add_record(&mut self, record: &SampleRecord) {
        if record.is_black() {
            return;
        }
        if record.delta {
            self.add_dirac(luminance(record.f));
        } else {
            self.add(luminance(record.f), record.p_bsdf, record.p_light);
        }
    }
}

impl Observer for SecondOrderMoments {
    fn observe(&mut self, phase: &Phase, _contributions: &[Rgb]) {
        for block in phase.records.chunks(BLOCK) {
            match with_widest_lanes(BlockTerms { records: block }) {
                Some((i1, i2)) => {
                    self.i1 += i1;
                    self.i2 += i2;
                }
                None => block.iter().for_each(|r| self.add_record(r)),
            }
        }
    }
}

/// Records whose terms are summed in `f32` lanes before their sums join the f64 totals: each of
/// the eight slots then sums at most eight terms in `f32`.
pub const BLOCK: usize = 64;

/// The smallest sum of a block's Î₂ terms kept from the lanes: from about 10⁻³⁸ `f32` loses
/// digits, so a block of samples this dim (or with p_B = p_L everywhere, where Î₂ is 0) is
/// summed again in f64.
pub const SMALLEST_LANE_SUM: f64 = 1e-30;

/// The sums of the second-order terms of at most [`BLOCK`] records, in lanes, or `None` where
/// `f32` cannot hold them.
struct BlockTerms<'a> {
    records: &'a [SampleRecord],
}

impl LaneKernel for BlockTerms<'_> {
    type Output = Option<(f64, f64)>;

    #[inline(always)]
    fn run<L: Lanes, const W: usize>(self) -> Self::Output {
        // Record k is summed in slot k mod MAX_WIDTH whatever the width, and the slots in
        // order, so that four and eight lanes give the same bits.
        let mut sums = [(L::splat(0.0), L::splat(0.0)); MAX_WIDTH];
        let slots = MAX_WIDTH / W;
        let mut lit = L::Mask::from_fn(|_| false);
        let groups = self.records.chunks_exact(W);
        let rest = groups.remainder();
        let full = groups.len();
        for (g, group) in groups.enumerate() {
            let group: &[SampleRecord; W] = group.try_into().expect("a group of W records");
            lit = lit | add_group_terms(&mut sums[g % slots], group);
        }
        if !rest.is_empty() {
            // Default records are black: they add zero.
            let mut padded = [SampleRecord::default(); W];
            padded[..rest.len()].copy_from_slice(rest);
            lit = lit | add_group_terms(&mut sums[full % slots], &padded);
        }
        let (mut i1, mut i2) = (0.0f64, 0.0f64);
        for (t1, t2) in &sums[..slots] {
            for i in 0..W {
                i1 += t1.lane(i) as f64;
                i2 += t2.lane(i) as f64;
            }
        }
        let held = i1.is_finite() && i2.is_finite() && (i2 >= SMALLEST_LANE_SUM || !lit.any());
        held.then_some((i1, i2))
    }
}

/// Adds the terms q² r and q² r² of W records to `sums` (zero where a record adds nothing), and
/// returns which lanes add something. (A function, not a closure: a closure left out of line
/// would not have the kernel's AVX2.)
#[inline(always)]
fn add_group_terms<L: Lanes, const W: usize>(
    sums: &mut (L, L),
    group: &[SampleRecord; W],
) -> L::Mask {
    let (zero, half, one) = (L::splat(0.0), L::splat(0.5), L::splat(1.0));
    let f = luminance_lanes(V3::<L>::from_fn(|i| group[i].f));
    let delta = L::Mask::from_fn(|i| group[i].delta);
    // Halves first: p_B + p_L may overflow where p̄ does not.
    let (p_bsdf, p_light) = (
        half * L::from_fn(|i| group[i].p_bsdf),
        half * L::from_fn(|i| group[i].p_light),
    );
    let (p_bar, delta_p) = (p_bsdf + p_light, p_bsdf - p_light);
    let p_bar_usable = p_bar.gt(zero) & p_bar.lt(L::splat(f32::INFINITY));
    // A Dirac sample needs no p̄.
    let adds = !f.eq(zero) & (delta | p_bar_usable);
    let inv_p_bar = one / p_bar;
    // A Dirac sample's limit: q = 2 f/p_B (its record's f is f/p_B), r = 1.
    let q = L::select(delta, L::splat(2.0) * f, f * inv_p_bar);
    let r = L::select(delta, one, delta_p * inv_p_bar);
    // Selected last: r is not a number where p̄ is 0.
    let t1 = q * q * r;
    let (t1, t2) = (L::select(adds, t1, zero), L::select(adds, t1 * r, zero));
    *sums = (sums.0 + t1, sums.1 + t2);
    adds
}

/// The unclamped second-order α from the sums of [`SecondOrderMoments`]: ½ + ¼ · I₁ / I₂, or
/// `None` when I₂ is zero or not finite.
pub fn second_order_alpha(i1: f64, i2: f64) -> Option<f64> {
    let ratio = i1 / i2;
    (i2 > 0.0 && i2.is_finite() && ratio.is_finite()).then_some(0.5 + 0.25 * ratio)
}

/// Where α̂ comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Per shading point and light: M samples at α = ½ give L̂₁ and α̂, the other N − M samples
    /// at α̂ give L̂₂; the estimate is (M·L̂₁ + (N − M)·L̂₂) / N (paper, Table 2). Unbiased: α̂
    /// depends only on the first phase, and each phase is an unbiased estimate for its counts.
    Integrated { alpha_samples: u32 },
    /// Per shading point and light: M pilot samples at α = ½ give α̂ only; N fresh samples at
    /// α̂ give the estimate (paper, Table 1).
    Preprocessed { alpha_samples: u32 },
}

/// The paper's allocation: α̂ from a phase at α = ½.
pub struct SecondOrderAlpha {
    pub mode: Mode,
    pub clamp: [f64; 2],
}

impl Mode {
    /// Runs the two phases of the mode: samples at α = ½ seen by `observer`, then samples at
    /// the α that `choose` takes from them (clamped by the caller's rule).
    pub fn estimate<W: Weighting + ?Sized, O: Observer>(
        self,
        sampling: &mut LightSampling,
        weighting: &W,
        observer: &mut O,
        choose: impl FnOnce(&LightSampling, &O) -> f64,
    ) -> LightEstimate {
        let n = sampling.samples();
        let (split, role) = self.first_phase(n);
        let first = sampling.phase(split, role, weighting, observer);
        let alpha = choose(sampling, observer);
        let second = self.second_phase(n).map(|(count, role)| {
            sampling.phase(SampleSplit::new(alpha, count), role, weighting, &mut ())
        });
        LightEstimate {
            value: self.combine(n, first, second),
            alpha,
        }
    }

    /// [`estimate`](Self::estimate) for the samplings of one light at several shading points
    /// (the camera samples of a pixel), each with a new observer, its estimate in
    /// `estimates[k]`: a packet ([`PACKET_SIZE`] points) at a time, each phase of its points
    /// drawn together where the phases are small ([`LightSampling::phases`]), so that α's two
    /// phases of N/2 samples fill the batch kernels' lanes as one phase of N does. Every
    /// sampling gets what `estimate` would give it, bit for bit.
    pub fn estimate_together<W: Weighting + ?Sized, O: Observer + Default>(
        self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        choose: impl Fn(&LightSampling, &O) -> f64,
        estimates: &mut [LightEstimate],
    ) {
        let packets = samplings
            .chunks_mut(PACKET_SIZE)
            .zip(estimates.chunks_mut(PACKET_SIZE));
        for (samplings, estimates) in packets {
            let mut observers: [O; PACKET_SIZE] = std::array::from_fn(|_| O::default());
            self.estimate_packet(samplings, weighting, &mut observers, &choose, estimates);
        }
    }

    /// [`estimate_together`](Self::estimate_together) for one packet, `observers[k]` seeing
    /// `samplings[k]`'s first phase. The samplings share N (the integrator's), on which the
    /// phases' splits and roles depend.
    fn estimate_packet<W: Weighting + ?Sized, O: Observer>(
        self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        observers: &mut [O; PACKET_SIZE],
        choose: &impl Fn(&LightSampling, &O) -> f64,
        estimates: &mut [LightEstimate],
    ) {
        let len = samplings.len();
        let mut lit = samplings.iter().flatten();
        let Some(n) = lit.next().map(LightSampling::samples) else {
            return;
        };
        assert!(
            lit.all(|s| s.samples() == n),
            "the samplings of a packet share N"
        );
        let (first_split, first_role) = self.first_phase(n);
        let mut first = [Rgb::ZERO; PACKET_SIZE];
        LightSampling::phases(
            samplings,
            &[first_split; PACKET_SIZE],
            first_role,
            weighting,
            observers,
            &mut first[..len],
        );
        let mut alphas = [0.5; PACKET_SIZE];
        for ((alpha, sampling), observer) in alphas.iter_mut().zip(&*samplings).zip(&*observers) {
            if let Some(sampling) = sampling {
                *alpha = choose(sampling, observer);
            }
        }
        let second_phase = self.second_phase(n);
        let mut second = [Rgb::ZERO; PACKET_SIZE];
        if let Some((count, role)) = second_phase {
            LightSampling::phases(
                samplings,
                &alphas.map(|alpha| SampleSplit::new(alpha, count)),
                role,
                weighting,
                &mut [(); PACKET_SIZE],
                &mut second[..len],
            );
        }
        for (k, estimate) in estimates.iter_mut().enumerate() {
            if samplings[k].is_some() {
                *estimate = LightEstimate {
                    value: self.combine(n, first[k], second_phase.map(|_| second[k])),
                    alpha: alphas[k],
                };
            }
        }
    }

    /// The split and role of the phase at α = ½ for N = `n`.
    fn first_phase(self, n: u32) -> (SampleSplit, PhaseRole) {
        match self {
            Mode::Integrated { alpha_samples } => {
                let rest = n - alpha_samples.min(n);
                // V[L_1] is measured on the samples at α̂, unless fewer than two are left.
                let role = PhaseRole {
                    counted: true,
                    measured: rest < 2,
                };
                (SampleSplit::new(0.5, alpha_samples.min(n)), role)
            }
            Mode::Preprocessed { alpha_samples } => {
                (SampleSplit::new(0.5, alpha_samples), PhaseRole::PILOT)
            }
        }
    }

    /// The samples and role of the phase at α̂ for N = `n`, if there is one (its split is
    /// `SampleSplit::new(α̂, samples)`).
    fn second_phase(self, n: u32) -> Option<(u32, PhaseRole)> {
        match self {
            Mode::Integrated { alpha_samples } => {
                let rest = n - alpha_samples.min(n);
                let role = PhaseRole {
                    counted: true,
                    measured: rest >= 2,
                };
                (rest > 0).then_some((rest, role))
            }
            Mode::Preprocessed { .. } => Some((n, PhaseRole::ESTIMATE)),
        }
    }

    /// The estimate from the phases' estimates `first` and `second` (if there was one).
    fn combine(self, n: u32, first: Rgb, second: Option<Rgb>) -> Rgb {
        match (self, second) {
            (Mode::Integrated { alpha_samples }, Some(second)) => {
                let m = alpha_samples.min(n);
                (first * m as f32 + second * (n - m) as f32) / n as f32
            }
            (Mode::Integrated { .. }, None) => first,
            (Mode::Preprocessed { .. }, second) => second.unwrap_or(first),
        }
    }
}

impl Allocation for SecondOrderAlpha {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let mut moments = SecondOrderMoments::default();
        self.mode
            .estimate(sampling, weighting, &mut moments, |_, moments| {
                moments.alpha(self.clamp)
            })
    }

    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        self.mode.estimate_together(
            samplings,
            weighting,
            |_, moments: &SecondOrderMoments| moments.alpha(self.clamp),
            estimates,
        );
    }
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let balance = PerSample(Balance);
    let mode = match params.choice(MODE)? {
        FIXED => {
            let alpha = params.float(FIXED_ALPHA)? as f64;
            return MisIntegrator::boxed(params, FixedAlpha { alpha }, balance);
        }
        INTEGRATED => {
            let n = params.int(SAMPLES_SPEC.name)? as u32;
            let given = params.int(ALPHA_SAMPLES)? as u32;
            let alpha_samples = if given == 0 { n / 2 } else { given };
            if alpha_samples > n {
                return Err(PluginError::Invalid(format!(
                    "{}: `{ALPHA_SAMPLES}` ({alpha_samples}) cannot exceed `{}` ({n}) in integrated mode",
                    params.plugin(),
                    SAMPLES_SPEC.name
                )));
            }
            Mode::Integrated { alpha_samples }
        }
        _ => {
            let given = params.int(ALPHA_SAMPLES)? as u32;
            Mode::Preprocessed {
                alpha_samples: if given == 0 { 4096 } else { given },
            }
        }
    };
    let [lo, hi] = params.interval(CLAMP)?;
    let clamp = [lo as f64, hi as f64];
    MisIntegrator::boxed(params, SecondOrderAlpha { mode, clamp }, balance)
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with the second-order adaptive α between BSDF and light sampling (Lu et al. 2013)",
        params: PARAMS,
        create,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allocation::SampleSplit;

    /// The moments of a synthetic integrand on [0, 1]: the concentrated density is a box of
    /// height k (width 1/k), the other is 1, and f follows the concentrated one. Half the
    /// samples come from each density (a stratified sample of p̄), as at α = ½.
    fn synthetic_moments(k: f32, concentrated_is_bsdf: bool) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        let n = 20_000;
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            for x in [u / k, u] {
                let p = if x < 1.0 / k { k } else { 0.0 };
                if concentrated_is_bsdf {
                    moments.add(p, p, 1.0);
                } else {
                    moments.add(p, 1.0, p);
                }
            }
        }
        moments
    }

    #[test]
    fn a_near_mirror_lobe_under_a_broad_light_gives_three_quarters() {
        // f concentrated where p_B is: the supplemental's §1.4 limit.
        let alpha = synthetic_moments(1e4, true).alpha([0.0, 1.0]);
        assert!((alpha - 0.75).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn a_tiny_light_over_a_broad_lobe_gives_one_quarter() {
        let alpha = synthetic_moments(1e4, false).alpha([0.0, 1.0]);
        assert!((alpha - 0.25).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn mirrors_give_three_quarters() {
        let mut moments = SecondOrderMoments::default();
        moments.add_dirac(0.8);
        assert_eq!(moments.alpha([0.0, 1.0]), 0.75);
    }

    /// Records of every kind: black, Dirac, lit with densities from 10⁻³ to 10³ (some BSDF
    /// samples the light cannot produce), integrands from 10⁻³ to 10³.
    fn varied_records(n: usize, seed: u64) -> Vec<SampleRecord> {
        let mut s = lumis_core::sampler::Sampler::new(seed, 1, 2);
        let spread = |s: &mut lumis_core::sampler::Sampler| 10f32.powf(6.0 * s.next_1d() - 3.0);
        (0..n)
            .map(|i| {
                let f = Rgb::new(spread(&mut s), spread(&mut s), spread(&mut s));
                match (i + 3) % 7 {
                    0 => SampleRecord::default(),
                    // Chosen among two lobes.
                    1 => SampleRecord {
                        f,
                        p_bsdf: 0.5,
                        p_light: 0.0,
                        delta: true,
                    },
                    2 => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: 0.0,
                        delta: false,
                    },
                    _ => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: spread(&mut s),
                        delta: false,
                    },
                }
            })
            .collect()
    }

    fn observed(records: &[SampleRecord]) -> SecondOrderMoments {
        let split = SampleSplit {
            n_bsdf: records.len() as u32,
            n_light: 0,
        };
        let mut moments = SecondOrderMoments::default();
        moments.observe(&Phase::of(split, records), &[]);
        moments
    }

    fn in_f64(records: &[SampleRecord]) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        records.iter().for_each(|r| moments.add_record(r));
        moments
    }

    #[test]
    fn the_lanes_sum_what_f64_sums_within_f32_rounding() {
        // Against the f64 sums of the same f32 inputs, a term q²r = f²Δp/p̄³ carries the
        // roundings of p̄ (three times, as p̄⁻³), 1/p̄ (three), q (two), Δp, r, q² and q²r: 12;
        // q²r² five more (Δp, p̄, 1/p̄ and r again, and the product): 17. A slot sums at most
        // BLOCK / 8 terms from zero: 7 roundings. So |error| ≤ ((1 + γ(n))(1 + γ(7)) − 1) ·
        // Σ|term|, n = 12 and 17 (pbrt-v4's γ(n) = nε/(1 − nε), ε = 2⁻²⁴).
        let gamma =
            |n: f64| n * f64::from(f32::EPSILON) / 2.0 / (1.0 - n * f64::from(f32::EPSILON) / 2.0);
        let sums = gamma((BLOCK / MAX_WIDTH - 1) as f64);
        let bound = |n: f64| (1.0 + gamma(n)) * (1.0 + sums) - 1.0;
        let (bound_i1, bound_i2) = (bound(12.0), bound(17.0));
        for n in [1, 7, 8, 9, 31, 64, 65, 150] {
            let records = varied_records(n, n as u64);
            let (lanes, exact) = (observed(&records), in_f64(&records));
            let mut absolute = SecondOrderMoments::default();
            for r in &records {
                let mut one = SecondOrderMoments::default();
                one.add_record(r);
                absolute.i1 += one.i1.abs();
                absolute.i2 += one.i2.abs();
            }
            assert!(exact.i2 > 0.0, "{n} records: some are lit");
            assert!(
                (lanes.i1 - exact.i1).abs() <= bound_i1 * absolute.i1,
                "{n}: I₁ {lanes:?} vs {exact:?}"
            );
            assert!(
                (lanes.i2 - exact.i2).abs() <= bound_i2 * absolute.i2,
                "{n}: I₂ {lanes:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn four_and_eight_lanes_give_the_same_bits() {
        let records = varied_records(150, 9);
        lumis_core::math::lanes::limit_width(4);
        let four = observed(&records);
        lumis_core::math::lanes::limit_width(MAX_WIDTH);
        let widest = observed(&records);
        assert_eq!(four.i1.to_bits(), widest.i1.to_bits());
        assert_eq!(four.i2.to_bits(), widest.i2.to_bits());
    }

    #[test]
    fn terms_beyond_the_range_of_f32_are_summed_in_f64() {
        let lit = |f: f32, p_bsdf: f32, p_light: f32| SampleRecord {
            f: Rgb::splat(f),
            p_bsdf,
            p_light,
            delta: false,
        };
        // q = f / p̄ ≈ 10³⁰: q² overflows f32. Then f = 10⁻²⁵: q² r² underflows it.
        for scale in [1e30, 1e-25] {
            let records: Vec<_> = (0..20)
                .map(|i| lit(scale * (1.0 + i as f32), 1.0 + (i % 3) as f32, 2.0))
                .collect();
            let (lanes, exact) = (observed(&records), in_f64(&records));
            assert_eq!(lanes, exact, "f scaled by {scale}");
            assert!(exact.i1.is_finite() && exact.i2 > 0.0, "{exact:?}");
            // α does not depend on the integrand's scale.
            let unscaled: Vec<_> = records
                .iter()
                .map(|r| lit(r.f.x / scale, r.p_bsdf, r.p_light))
                .collect();
            let alpha = observed(&unscaled).alpha([0.0, 1.0]);
            assert!(
                (lanes.alpha([0.0, 1.0]) - alpha).abs() < 1e-6,
                "f scaled by {scale}"
            );
        }
    }

    #[test]
    fn undefined_estimates_give_one_half_within_the_clamp() {
        assert_eq!(second_order_alpha(0.0, 0.0), None);
        assert_eq!(second_order_alpha(1.0, f64::INFINITY), None);
        // p_B = p_L everywhere: Δp = 0, I₂ = 0, so α is undefined (the integrator uses ½).
        let mut moments = SecondOrderMoments::default();
        for i in 0..100 {
            moments.add(1.0 + i as f32, 2.0, 2.0);
        }
        assert_eq!(second_order_alpha(moments.i1, moments.i2), None);
        assert_eq!(moments.alpha([0.025, 0.975]), 0.5);
        assert_eq!(moments.alpha([0.6, 0.9]), 0.6);
    }
}

//! The shared parts of the methods that steer the split (or the weights) with samples drawn
//! at α = ½ before the rest: `alpha`, `exact_alpha`, `cost_alpha`, `pooled_alpha`,
//! `variance_aware` and `optimal_mis` (progressive). Their parameters' names and declarations,
//! the readers of those parameters, with the one check that a count taken out of N does not
//! exceed it ([`at_most_samples`]); the paper's two uses of such samples at a shading point
//! ([`Mode`], run by [`TwoPhases`]); and the allocation that chooses α from them by a rule
//! ([`PilotAlpha`], [`AlphaRule`]). A pilot pass over the whole image, whose estimate camera
//! sample 0 reuses, is [`crate::pilot`].

use crate::allocation::Allocation;
use crate::mis::SAMPLES;
use crate::moments::PilotSamples;
use crate::phase::{EstimatesOnly, LightEstimate, Observer, PhaseRole, SampleSplit};
use crate::sampling::LightSampling;
use crate::weighting::Weighting;
use lumis_core::geometry::PACKET_SIZE;
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::scene::Scene;

/// Parameter: how the samples at α = ½ are used, [`INTEGRATED`] or [`PREPROCESSED`] (`alpha`
/// adds `fixed`).
pub const MODE: &str = "mode";
pub const INTEGRATED: &str = "integrated";
pub const PREPROCESSED: &str = "preprocessed";
/// Parameter: M, the samples at α = ½ per shading point and light.
pub const ALPHA_SAMPLES: &str = "alpha_samples";
/// Parameter: the interval α is chosen in.
pub const CLAMP: &str = "clamp";
/// Parameter: which variance is minimised, [`MIXTURE`] or [`STRATIFIED`].
pub const VARIANCE: &str = "variance";
pub const MIXTURE: &str = "mixture";
pub const STRATIFIED: &str = "stratified";
/// Parameter: M, the samples per light per pixel of a pilot pass over the image.
pub const PILOT_SAMPLES: &str = "pilot_samples";

/// Parameter: where α's statistics come from, [`PILOT`] (samples at α = ½ per `mode`, or a
/// pilot pass) or [`PASSES`] (the render's earlier passes, [`crate::learned`]).
pub const STATISTICS: &str = "statistics";
pub const PILOT: &str = "pilot";
pub const PASSES: &str = "passes";

/// `statistics`, read by [`read_learns`].
pub const STATISTICS_SPEC: ParamSpec = ParamSpec {
    name: STATISTICS,
    kind: ParamKind::Choice {
        options: &[PILOT, PASSES],
        default: PILOT,
    },
    unit: "",
    description: "pilot: α from samples at α = ½ drawn for it; passes: from the render's earlier passes (a render in passes; the first pass, and a one-pass render, at α = ½)",
};

/// Reads `statistics`: whether α is learned from the render's earlier passes.
pub fn read_learns(params: &mut Params) -> Result<bool, PluginError> {
    Ok(params.choice(STATISTICS)? == PASSES)
}

/// `mode` of `exact_alpha` and `cost_alpha`.
pub const MODE_SPEC: ParamSpec = ParamSpec {
    name: MODE,
    kind: ParamKind::Choice {
        options: &[INTEGRATED, PREPROCESSED],
        default: INTEGRATED,
    },
    unit: "",
    description: "integrated: the pilot's samples are part of the estimate (paper Table 2); preprocessed: a separate pilot (Table 1)",
};

/// `alpha_samples`, read by [`read_mode`].
pub const ALPHA_SAMPLES_SPEC: ParamSpec = ParamSpec {
    name: ALPHA_SAMPLES,
    kind: ParamKind::Int {
        default: Some(0),
        min: 0,
        max: 1 << 20,
    },
    unit: "",
    description: "M, samples at α = ½ that choose α (0: N/2 integrated, 4096 preprocessed)",
};

/// `clamp`, read by [`read_clamp`].
pub const CLAMP_SPEC: ParamSpec = ParamSpec {
    name: CLAMP,
    kind: ParamKind::Interval {
        default: [0.025, 0.975],
        min: 0.0,
        max: 1.0,
    },
    unit: "",
    description: "interval α is chosen in",
};

/// `variance`, read by [`read_stratified`].
pub const VARIANCE_SPEC: ParamSpec = ParamSpec {
    name: VARIANCE,
    kind: ParamKind::Choice {
        options: &[MIXTURE, STRATIFIED],
        default: MIXTURE,
    },
    unit: "",
    description: "variance minimised: of the mixture estimator (as the paper) or of the stratified estimator the integrators use",
};

/// `pilot_samples`, read by [`read_pilot_samples`], described by `description` (its default
/// differs from method to method).
pub const fn pilot_samples_spec(description: &'static str) -> ParamSpec {
    ParamSpec {
        name: PILOT_SAMPLES,
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description,
    }
}

/// `m`, a count of samples that parameter `name` sets and that the estimate takes out of its
/// N = `samples`, or the error that `name` cannot exceed N (`why`: the rest of the message).
pub fn at_most_samples(
    params: &Params,
    name: &str,
    m: u32,
    samples: u32,
    why: &str,
) -> Result<u32, PluginError> {
    if m > samples {
        return Err(PluginError::Invalid(format!(
            "{}: `{name}` ({m}) cannot exceed `{SAMPLES}` ({samples}){why}",
            params.plugin()
        )));
    }
    Ok(m)
}

/// Reads `mode` and `alpha_samples` for N = `samples` ([`mode_named`]).
pub fn read_mode(params: &mut Params, samples: u32) -> Result<Mode, PluginError> {
    let mode = params.choice(MODE)?;
    mode_named(params, mode, samples)
}

/// Mode `mode` ([`INTEGRATED`], or else [`PREPROCESSED`]) for N = `samples`, reading M from
/// `alpha_samples`: 0 gives N/2 integrated, 4096 preprocessed; at most N integrated.
pub fn mode_named(params: &mut Params, mode: &str, samples: u32) -> Result<Mode, PluginError> {
    let given = params.int(ALPHA_SAMPLES)? as u32;
    if mode == INTEGRATED {
        let alpha_samples = if given == 0 { samples / 2 } else { given };
        let why = " in integrated mode";
        let alpha_samples = at_most_samples(params, ALPHA_SAMPLES, alpha_samples, samples, why)?;
        Ok(Mode::Integrated { alpha_samples })
    } else {
        Ok(Mode::Preprocessed {
            alpha_samples: if given == 0 { 4096 } else { given },
        })
    }
}

/// Reads `clamp`.
pub fn read_clamp(params: &mut Params) -> Result<[f64; 2], PluginError> {
    let [lo, hi] = params.interval(CLAMP)?;
    Ok([lo as f64, hi as f64])
}

/// Reads `variance`: whether the stratified estimator's variance is minimised.
pub fn read_stratified(params: &mut Params) -> Result<bool, PluginError> {
    Ok(params.choice(VARIANCE)? == STRATIFIED)
}

/// Reads `pilot_samples` for N = `samples`: 0 gives N / `fraction` (at least 2, at most N);
/// at most N, as camera sample 0 reuses the pilot's samples ([`crate::pilot`]).
pub fn read_pilot_samples(
    params: &mut Params,
    fraction: u32,
    samples: u32,
) -> Result<u32, PluginError> {
    let given = params.int(PILOT_SAMPLES)? as u32;
    let m = if given == 0 {
        (samples / fraction).max(2).min(samples)
    } else {
        given
    };
    let why = ": camera sample 0's estimate is made of the pilot's M samples and N − M fresh ones";
    at_most_samples(params, PILOT_SAMPLES, m, samples, why)
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

/// N samples of one light at a shading point in the two phases of `mode`: M at α = ½, seen by
/// an observer, then, at the α chosen from them, the other N − M (integrated) or N fresh ones
/// (preprocessed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TwoPhases {
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub mode: Mode,
}

impl TwoPhases {
    /// Runs the two phases at `sampling`'s point: samples at α = ½ seen by `observer`, then
    /// samples at the α that `choose` takes from them (clamped by the caller's rule).
    pub fn estimate<W: Weighting + ?Sized, O: Observer>(
        self,
        sampling: &mut LightSampling,
        weighting: &W,
        observer: &mut O,
        choose: impl FnOnce(&LightSampling, &O) -> f64,
    ) -> LightEstimate {
        let (split, role) = self.first_phase();
        let first = sampling.phase(split, role, weighting, observer);
        let alpha = choose(sampling, observer);
        let second = self.second_phase().map(|(count, role)| {
            sampling.phase(SampleSplit::new(alpha, count), role, weighting, &mut ())
        });
        LightEstimate {
            value: self.combine(first, second),
            alpha,
        }
    }

    /// [`estimate`](Self::estimate) for the samplings of one light at several shading points
    /// (a packet of camera samples), each with a new observer, its estimate in
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
    /// `samplings[k]`'s first phase.
    fn estimate_packet<W: Weighting + ?Sized, O: Observer>(
        self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        observers: &mut [O; PACKET_SIZE],
        choose: &impl Fn(&LightSampling, &O) -> f64,
        estimates: &mut [LightEstimate],
    ) {
        if samplings.iter().all(Option::is_none) {
            return;
        }
        let len = samplings.len();
        let (first_split, first_role) = self.first_phase();
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
        let second_phase = self.second_phase();
        let mut second = [Rgb::ZERO; PACKET_SIZE];
        if let Some((count, role)) = second_phase {
            LightSampling::phases(
                samplings,
                &alphas.map(|alpha| SampleSplit::new(alpha, count)),
                role,
                weighting,
                &mut [EstimatesOnly; PACKET_SIZE],
                &mut second[..len],
            );
        }
        for (k, estimate) in estimates.iter_mut().enumerate() {
            if samplings[k].is_some() {
                *estimate = LightEstimate {
                    value: self.combine(first[k], second_phase.map(|_| second[k])),
                    alpha: alphas[k],
                };
            }
        }
    }

    /// The split and role of the phase at α = ½.
    fn first_phase(self) -> (SampleSplit, PhaseRole) {
        let n = self.samples;
        match self.mode {
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

    /// The samples and role of the phase at α̂, if there is one (its split is
    /// `SampleSplit::new(α̂, samples)`).
    fn second_phase(self) -> Option<(u32, PhaseRole)> {
        let n = self.samples;
        match self.mode {
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
    fn combine(self, first: Rgb, second: Option<Rgb>) -> Rgb {
        let n = self.samples;
        match (self.mode, second) {
            (Mode::Integrated { alpha_samples }, Some(second)) => {
                let m = alpha_samples.min(n);
                (first * m as f32 + second * (n - m) as f32) / n as f32
            }
            (Mode::Integrated { .. }, None) => first,
            (Mode::Preprocessed { .. }, second) => second.unwrap_or(first),
        }
    }
}

/// How α is chosen from a pilot's records (drawn at α = ½).
pub trait AlphaRule: Send + Sync {
    /// α in `clamp` for light `light`, or `None` if the pilot says nothing about it.
    fn alpha(&self, pilot: &PilotSamples, light: usize, clamp: [f64; 2]) -> Option<f64>;

    /// Work once per scene before rendering (e.g. measuring the costs of the techniques).
    fn preprocess(&mut self, _scene: &Scene) {}
}

/// The paper's two uses of samples at α = ½ ([`TwoPhases`]), with α chosen from their records
/// by `rule`.
pub struct PilotAlpha<R> {
    pub phases: TwoPhases,
    pub clamp: [f64; 2],
    pub rule: R,
}

impl<R: AlphaRule> PilotAlpha<R> {
    /// α from the last phase `sampling` drew (the pilot), ½ clamped if it says nothing.
    fn alpha_of_last_phase(&self, sampling: &LightSampling) -> f64 {
        let light = sampling.light();
        sampling
            .last_phase()
            .and_then(|(phase, _)| {
                self.rule
                    .alpha(&PilotSamples::new(&phase), light, self.clamp)
            })
            .unwrap_or(0.5)
            .clamp(self.clamp[0], self.clamp[1])
    }
}

impl<R: AlphaRule> Allocation for PilotAlpha<R> {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        self.phases
            .estimate(sampling, weighting, &mut (), |sampling, _| {
                self.alpha_of_last_phase(sampling)
            })
    }

    fn estimate_together<W: Weighting + ?Sized>(
        &self,
        samplings: &mut [Option<LightSampling>],
        weighting: &W,
        estimates: &mut [LightEstimate],
    ) {
        self.phases.estimate_together(
            samplings,
            weighting,
            |sampling, _: &()| self.alpha_of_last_phase(sampling),
            estimates,
        );
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.rule.preprocess(scene);
    }
}

//! A phase: the samples of one light at one shading point drawn with one split of the two
//! techniques, as a batch the weighting ([`crate::weighting`]) combines into an estimate and
//! observers ([`Observer`]) then see. An allocation ([`crate::allocation`]) may draw several
//! phases per light (a pilot, then the rest) and combines them into a [`LightEstimate`].

use crate::estimator::SampleRecord;
use glam::UVec2;
use lumis_core::math::Rgb;

/// How many samples of each technique one phase draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSplit {
    pub n_bsdf: u32,
    pub n_light: u32,
}

impl SampleSplit {
    /// `n` samples with a fraction `alpha` from the BSDF: n_B = ⌊α·n + ½⌋, n_L = n − n_B. When
    /// 0 < α < 1 and n ≥ 2 each technique keeps at least one sample, so that neither technique's
    /// support is ever dropped (a mirror needs BSDF samples, a point-like light light samples).
    /// Weights use these realised counts, so the estimate is unbiased for any α chosen
    /// independently of the samples it weighs; and the counts are deterministic (no random
    /// rounding), so images stay bit-identical across thread counts.
    pub fn new(alpha: f64, n: u32) -> Self {
        // The cast truncates: ⌊·⌋ at or above 0, and below 0 (or NaN) it gives 0, as the cast
        // of the floor would. `f64::floor` is a libm call on baseline x86-64.
        let mut n_bsdf = ((alpha * n as f64 + 0.5) as u32).min(n);
        if alpha > 0.0 && alpha < 1.0 && n >= 2 {
            n_bsdf = n_bsdf.clamp(1, n - 1);
        }
        SampleSplit {
            n_bsdf,
            n_light: n - n_bsdf,
        }
    }

    pub fn total(&self) -> u32 {
        self.n_bsdf + self.n_light
    }

    /// The fraction of the split's samples drawn from the BSDF (the `alpha` AOV of a method
    /// that keeps one split).
    pub fn alpha(&self) -> f64 {
        self.n_bsdf as f64 / self.total() as f64
    }

    /// Whether a phase of this split fills batch kernels of `lanes` lanes by itself (as many
    /// samples of a technique), so that drawing it alone costs less than interleaving it with
    /// other points' phases. On the Veach scene with eight lanes, together ran at 0.905 [0.850,
    /// 0.964] of point by point's speed for `balance` at N = 64 and at 0.946 [0.939, 0.952] at
    /// N = 16, and 1.050 [1.044, 1.056] times as fast at N = 8 (docs/performance.md).
    pub fn fills(&self, lanes: u32) -> bool {
        self.n_bsdf >= lanes || self.n_light >= lanes
    }
}

/// One light's estimate at one shading point, from all its phases.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightEstimate {
    /// The estimate of the radiance reflected from this light, L̂_j.
    pub value: Rgb,
    /// The fraction of samples the method meant for BSDF sampling (the `alpha` AOV).
    pub alpha: f64,
}

/// What a phase's samples are for, which decides what the integrator's AOVs make of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhaseRole {
    /// The phase's samples are part of the estimate (counted by the `samples` AOV).
    pub counted: bool,
    /// The phase's samples measure the sampling variance V[L_{1,α}] (the `sampling_variance`
    /// AOV): those drawn at the split the method settled on.
    pub measured: bool,
}

impl PhaseRole {
    /// The whole estimate, or its final part: counted and measured.
    pub const ESTIMATE: PhaseRole = PhaseRole {
        counted: true,
        measured: true,
    };
    /// A pilot whose samples are not part of the estimate (they only steer it).
    pub const PILOT: PhaseRole = PhaseRole {
        counted: false,
        measured: false,
    };
}

/// The samples of one phase: `split.n_bsdf` BSDF records, then `split.n_light` light records.
#[derive(Clone, Copy, Debug)]
pub struct Phase<'a> {
    /// The pixel being rendered (for methods that keep state per pixel or block of pixels).
    pub pixel: UVec2,
    /// Index of the light in `scene.emitters`.
    pub light: usize,
    /// The realised counts n_B and n_L of this phase.
    pub split: SampleSplit,
    /// What the phase's samples are for.
    pub role: PhaseRole,
    pub records: &'a [SampleRecord],
}

impl<'a> Phase<'a> {
    /// The BSDF samples' records.
    pub fn bsdf_records(&self) -> &'a [SampleRecord] {
        &self.records[..self.split.n_bsdf as usize]
    }

    /// The light samples' records.
    pub fn light_records(&self) -> &'a [SampleRecord] {
        &self.records[self.split.n_bsdf as usize..]
    }
}

/// Sees every phase it is given, after the weighting, and accumulates what a method needs
/// (moments for α, statistics for AOVs). One call per phase: an observer loops over the batch.
pub trait Observer {
    /// `contributions[i]` is record i's weighted contribution to the phase's estimate (their
    /// sum is the estimate; zero for black records).
    fn observe(&mut self, phase: &Phase, contributions: &[Rgb]);

    /// Whether the records of the phases it is given are read, by `observe` or afterwards by
    /// the caller ([`LightSampling::last_phase`]). Where none of a packet's phases' are, and
    /// the weighting weighs each record alone, the phases are summed as their records are
    /// drawn ([`LightSampling::phases_together`]), none kept, and `observe` is not called.
    ///
    /// [`LightSampling::last_phase`]: crate::sampling::LightSampling::last_phase
    /// [`LightSampling::phases_together`]: crate::sampling::LightSampling::phases_together
    fn reads_records(&self) -> bool {
        true
    }
}

/// No observer (the caller may still read the last phase's records).
impl Observer for () {
    #[inline]
    fn observe(&mut self, _phase: &Phase, _contributions: &[Rgb]) {}
}

/// No observer, and a caller that reads only the phases' estimates, not their records.
#[derive(Clone, Copy, Debug, Default)]
pub struct EstimatesOnly;

impl Observer for EstimatesOnly {
    #[inline]
    fn observe(&mut self, _phase: &Phase, _contributions: &[Rgb]) {}

    #[inline]
    fn reads_records(&self) -> bool {
        false
    }
}

//! A phase: the samples of one light at one shading point drawn with one split of the two
//! techniques, as a batch the weighting ([`crate::weighting`]) combines into an estimate and
//! observers ([`Observer`]) then see. An allocation ([`crate::allocation`]) may draw several
//! phases per light (a pilot, then the rest).

use crate::allocation::SampleSplit;
use crate::estimator::SampleRecord;
use glam::UVec2;
use lumis_core::math::Rgb;

/// The samples of one phase: `split.n_bsdf` BSDF records, then `split.n_light` light records.
#[derive(Clone, Copy, Debug)]
pub struct Phase<'a> {
    /// The pixel being rendered (for methods that keep state per pixel or block of pixels).
    pub pixel: UVec2,
    /// Index of the light in `scene.emitters`.
    pub light: usize,
    /// The realised counts n_B and n_L of this phase.
    pub split: SampleSplit,
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

#[cfg(test)]
impl<'a> Phase<'a> {
    /// A phase at pixel (0, 0) of light 0, for the unit tests of weightings and observers.
    pub(crate) fn of(split: SampleSplit, records: &'a [SampleRecord]) -> Self {
        Phase {
            pixel: UVec2::ZERO,
            light: 0,
            split,
            records,
        }
    }
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

/// Sees every phase it is given, after the weighting, and accumulates what a method needs
/// (moments for α, statistics for AOVs). One call per phase: an observer loops over the batch.
pub trait Observer {
    /// `contributions[i]` is record i's weighted contribution to the phase's estimate (their
    /// sum is the estimate; zero for black records).
    fn observe(&mut self, phase: &Phase, contributions: &[Rgb]);
}

/// No observer.
impl Observer for () {
    #[inline]
    fn observe(&mut self, _phase: &Phase, _contributions: &[Rgb]) {}
}

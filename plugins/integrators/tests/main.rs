//! The integrators' tests, in one test binary (`cargo test -p lumis-integrators`; `-- alpha::`
//! runs one module's tests). They link the library as it is built for the renderer, instead of
//! compiling it a second time with its own tests (docs/testing.md). Cargo's discovery of
//! `tests/*.rs` is off (`autotests = false`): a new file is declared here, which the workspace's
//! `every_test_file_is_a_module` checks.

use lumis_core::math::Rgb;
use lumis_integrators::estimator::SampleRecord;
use lumis_integrators::phase::{Phase, PhaseRole, SampleSplit};

mod alpha;
mod phases;
mod plugins;
mod weighting;

/// A non-delta record of grey integrand `f`.
pub fn grey(f: f32, p_bsdf: f32, p_light: f32) -> SampleRecord {
    SampleRecord {
        f: Rgb::splat(f),
        p_bsdf,
        p_light,
        delta: false,
    }
}

/// A phase of the estimate at pixel (0, 0) of light 0, for the tests of weightings and
/// observers.
pub fn phase_of(split: SampleSplit, records: &[SampleRecord]) -> Phase<'_> {
    Phase {
        pixel: glam::UVec2::ZERO,
        light: 0,
        split,
        role: PhaseRole::ESTIMATE,
        records,
    }
}

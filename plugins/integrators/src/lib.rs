//! Built-in integrator plugins, one per file: the MIS family (`bsdf`, `light`, `balance`,
//! `power`, `max`, `cutoff`, `alpha`). Each is an [`allocation::Allocation`] (how a light's N
//! samples are split between BSDF and light sampling, in phases) combined with a
//! [`weighting::Weighting`] (how a phase's samples are weighed) in a [`mis::MisIntegrator`];
//! the samples themselves come from the shared [`estimator`], and [`phase::Observer`]s see them.
//! A new method is one file (its trait impl and its registration) and one `pub mod` line.

pub mod allocation;
pub mod aovs;
pub mod estimator;
pub mod mis;
pub mod phase;
pub mod weighting;

pub mod alpha;
pub mod balance;
pub mod bsdf;
pub mod cutoff;
pub mod light;
pub mod max;
pub mod power;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

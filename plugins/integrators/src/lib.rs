//! Built-in integrator plugins, one per file: the MIS family (`bsdf`, `light`, `balance`,
//! `power`, `max`, `alpha`), which share one per-light direct-lighting estimator
//! ([`estimator`]) and differ only in how they split and weight its samples ([`mis`]).

pub mod alpha;
pub mod balance;
pub mod bsdf;
pub mod estimator;
pub mod light;
pub mod max;
pub mod mis;
pub mod power;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

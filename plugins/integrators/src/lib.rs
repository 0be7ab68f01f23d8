//! Built-in integrator plugins. They share one per-light direct-lighting estimator
//! ([`estimator`]); each plugin file only chooses how samples are split and weighted.

pub mod balance;
pub mod estimator;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

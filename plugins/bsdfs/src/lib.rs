//! Built-in BSDF plugins, one per file, each registered under its scene-file name.

pub mod diffuse;
pub mod glossy;
pub mod measured;
pub mod mirror;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

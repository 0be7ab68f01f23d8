//! Built-in emitter plugins, one per file, each registered under its scene-file name.

pub mod area;
pub mod directional;
pub mod envmap;
pub mod point;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

//! Built-in texture plugins, one per file, each registered under its scene-file name. A scene
//! writes a texture inline where a parameter accepts one (`ParamKind::RgbOrTexture`,
//! `ParamKind::FloatOrTexture`): `reflectance: (type: "checkerboard", color0: 0.2, color1: 0.8)`.

pub mod checkerboard;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

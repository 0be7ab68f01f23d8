//! Built-in BSDF plugins, one per file, each registered under its scene-file name; and the
//! formulas several of them share: `microfacet` (GGX and Beckmann) and `fresnel` (dielectric and
//! conductor reflectance, named indices of refraction).

pub mod dielectric;
pub mod diffuse;
pub mod fresnel;
pub mod glossy;
pub mod ior;
pub mod measured;
pub mod microfacet;
pub mod mirror;
pub mod roughdielectric;
pub mod thindielectric;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

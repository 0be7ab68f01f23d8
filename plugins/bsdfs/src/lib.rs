//! Built-in BSDF plugins, one per file, each registered under its scene-file name; and the
//! formulas several of them share: `microfacet` (GGX and Beckmann) and `fresnel` (dielectric and
//! conductor reflectance, named indices of refraction).

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod fresnel;
pub mod glossy;
pub mod ior;
pub mod measured;
pub mod microfacet;
pub mod mirror;
pub mod plastic;
pub mod roughconductor;
pub mod roughdielectric;
pub mod roughplastic;
pub mod thindielectric;
pub mod twosided;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

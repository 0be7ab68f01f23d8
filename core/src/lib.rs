//! lumis-core: the renderer's interfaces and machinery. It contains no plugin: BSDFs, emitters
//! and integrators live in the plugin crates and register themselves with [`registry`].

pub mod bsdf;
pub mod budgets;
pub mod camera;
pub mod chi2;
pub mod dylib;
pub mod emitter;
pub mod error;
pub mod error_estimate;
pub mod film;
pub mod film_sums;
pub mod filter;
pub mod geometry;
pub mod huge_pages;
pub mod image_io;
pub mod integrator;
pub mod limits;
pub mod math;
pub mod output;
pub mod params;
pub mod passes;
pub mod progressive;
pub mod registry;
pub mod render;
pub mod render_files;
pub mod sampler;
pub mod scene;
pub mod testing;
pub mod texture;

pub use inventory;

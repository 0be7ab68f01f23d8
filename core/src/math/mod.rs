//! Small numerical building blocks shared by every plugin.

mod cache;
pub mod distribution;
mod float;
pub mod frame;
pub mod lanes;
pub mod rgb;
pub mod warp;

pub use cache::prefetch;
pub use distribution::{Distribution1D, Distribution2D};
pub use float::{gamma, next_float_down, next_float_up};
pub use frame::Frame;
pub use rgb::{Rgb, luminance, luminance_lanes};

//! lumis: a physically based renderer for multiple importance sampling research.
//!
//! This facade re-exports the core ([`lumis_core`]) and links every built-in plugin crate, so
//! that their `inventory` registrations are kept by the linker. Programs and tests that render
//! should go through this crate (or call [`link_plugins`]).

pub use lumis_bsdfs as bsdfs;
pub use lumis_core::*;
pub use lumis_emitters as emitters;
pub use lumis_integrators as integrators;

/// Makes sure every built-in plugin crate is linked into the final program: a crate none of
/// whose symbols is used may be dropped by the linker together with its registrations.
pub fn link_plugins() {
    lumis_bsdfs::link();
    lumis_emitters::link();
    lumis_integrators::link();
}

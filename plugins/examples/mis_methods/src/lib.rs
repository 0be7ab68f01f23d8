//! Two MIS methods written outside lumis, one file each, as docs/writing-a-plugin.md walks
//! through them: a weighting heuristic ([`power_beta`]) and an allocation strategy
//! ([`lit_fraction`]). Each file is what a built-in method's file in
//! `plugins/integrators/src/` would be, with `lumis_integrators::` for `crate::` in its paths:
//! its doc comment, its trait impl, its parameters and its registration. A program that links
//! this crate finds both in the registry, by name; the test below renders a bundled scene with
//! each and checks that it converges to `balance`'s image.

pub mod lit_fraction;
pub mod power_beta;

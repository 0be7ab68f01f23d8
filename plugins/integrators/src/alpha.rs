//! `alpha`: direct lighting with the second-order adaptive α of Lu, Pacanowski and Granier
//! (Pacific Graphics 2013): per shading point and light, the fraction α of the N samples drawn
//! from the BSDF (the rest from the light) minimises a second-order Taylor approximation of the
//! variance of the mixture estimator, estimated from samples taken at α = ½:
//! α̂ = clamp(½ + ¼ · Î₁/Î₂), Î₁ = mean of f²Δp/p̄³, Î₂ = mean of f²Δp²/p̄⁴, with p̄ = (p_B + p_L)/2
//! and Δp = (p_B − p_L)/2 (α̂ = ½ when Î₂ is zero or not finite). Delta lights take one light
//! sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `mode` (choice, default "integrated"): "integrated" — M samples at α = ½ give L̂₁ and α̂,
//!   the other N − M at α̂ give L̂₂, and the estimate is (M·L̂₁ + (N − M)·L̂₂)/N (paper, Table 2);
//!   "preprocessed" — M pilot samples at α = ½ give α̂ only, then N fresh samples at α̂ (paper,
//!   Table 1); "fixed" — α = `fixed` everywhere (½ reproduces `balance` bit for bit).
//! - `alpha_samples` (integer, default 0 = N/2 integrated, 4096 preprocessed): M.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): bounds of α̂.
//! - `fixed` (float, default 0.5, in [0, 1]): α in "fixed" mode.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! Counts: n_B = ⌊α·n + ½⌋ (at least one sample per technique when 0 < α < 1), n_L = n − n_B; the
//! balance weights use these realised counts, so each phase is unbiased for any α̂ chosen from
//! samples it does not reuse.

use crate::estimator::Heuristic;
use crate::mis::{self, Strategy};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;

static PARAMS: &[ParamSpec] = &[
    mis::SAMPLES,
    ParamSpec {
        name: "mode",
        kind: ParamKind::Choice {
            options: &["integrated", "preprocessed", "fixed"],
            default: "integrated",
        },
        unit: "",
        description: "how α is obtained: integrated (paper Table 2), preprocessed (Table 1) or fixed",
    },
    ParamSpec {
        name: "alpha_samples",
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description: "M, samples at α = ½ that estimate α (0: N/2 integrated, 4096 preprocessed)",
    },
    ParamSpec {
        name: "clamp",
        kind: ParamKind::Interval {
            default: [0.025, 0.975],
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "interval α̂ is clamped to",
    },
    ParamSpec {
        name: "fixed",
        kind: ParamKind::Float {
            default: Some(0.5),
            min: 0.0,
            max: 1.0,
        },
        unit: "",
        description: "α in fixed mode",
    },
    mis::AOVS,
];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let strategy = match params.choice("mode")? {
        "fixed" => Strategy::Fixed {
            alpha: params.float("fixed")? as f64,
            heuristic: Heuristic::Balance,
        },
        mode => {
            let n = params.int("samples")? as u32;
            let given = params.int("alpha_samples")? as u32;
            let [lo, hi] = params.interval("clamp")?;
            let clamp = [lo as f64, hi as f64];
            if mode == "integrated" {
                let alpha_samples = if given == 0 { n / 2 } else { given };
                if alpha_samples > n {
                    return Err(PluginError::Invalid(format!(
                        "{}: `alpha_samples` ({alpha_samples}) cannot exceed `samples` ({n}) in integrated mode",
                        params.plugin()
                    )));
                }
                Strategy::Integrated {
                    alpha_samples,
                    clamp,
                }
            } else {
                Strategy::Preprocessed {
                    alpha_samples: if given == 0 { 4096 } else { given },
                    clamp,
                }
            }
        }
    };
    Ok(Box::new(mis::create(params, strategy)?))
}

inventory::submit! {
    IntegratorPlugin {
        name: "alpha",
        description: "direct lighting with the second-order adaptive α between BSDF and light sampling (Lu et al. 2013)",
        params: PARAMS,
        create,
    }
}

//! `<integrator>`: `direct` becomes lumis' `power` (the same power-heuristic estimator).

use super::Converter;
use super::properties::Value;
use lumis_core::scene::description::PluginSpec;
use lumis_integrators::{mis, power as power_plugin};
use roxmltree::Node;

/// lumis' `power` integrator with `samples` per light.
pub(super) fn power(samples: i64) -> PluginSpec {
    PluginSpec::new(power_plugin::NAME).int(mis::SAMPLES, samples)
}

impl Converter {
    pub(super) fn integrator(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        self.objects_not_converted(&p.objects, "the integrator", false);
        if p.kind != "direct" {
            self.problem(
                p.line,
                format!(
                    "integrator `{}` is not converted: lumis renders direct lighting (`direct`)",
                    p.kind
                ),
            );
            return Ok(());
        }
        let mut count = |name: &str| match p.take(name) {
            Some((Value::Int(n), _)) if n > 0 => Some(n),
            Some((_, l)) => {
                self.report
                    .problem(l, format!("`{name}` must be a positive integer"));
                None
            }
            None => None,
        };
        let shading = count("shading_samples").unwrap_or(1);
        let emitter = count("emitter_samples").unwrap_or(shading);
        let bsdf = count("bsdf_samples").unwrap_or(shading);
        if let Some((Value::Bool(true), l)) = p.take("hide_emitters") {
            self.problem(l, "`hide_emitters` is not converted");
        }
        // Saturates: `power` refuses more samples than it takes, with its limit.
        let samples = emitter.saturating_add(bsdf);
        self.note(
            p.line,
            format!(
                "`direct` ({emitter} emitter + {bsdf} BSDF samples, one light chosen per emitter \
                 sample) becomes lumis `power` with samples {samples}: the same power-heuristic \
                 estimator of the same image, taking its samples from every light"
            ),
        );
        self.integrator = Some(power(samples));
        self.finish(p, "the integrator");
        Ok(())
    }
}

//! `<integrator>`: `direct` becomes lumis' `power` (the power heuristic), or `light` / `bsdf`
//! when it takes samples of one technique only, with Mitsuba's weight of delta lights (see
//! `Converter::direct`); `path`,
//! and `moment` around a `path`, become lumis' `path` with Mitsuba's estimator at every vertex
//! (one light per vertex, one light and one BSDF sample, the power heuristic).

use super::Converter;
use super::properties::{Properties, Value};
use lumis_core::scene::description::PluginSpec;
use lumis_integrators::{
    bsdf as bsdf_plugin, light as light_plugin, mis, path, power as power_plugin,
};
use roxmltree::Node;

/// lumis' `power` integrator with `samples` per light.
pub(super) fn power(samples: i64) -> PluginSpec {
    PluginSpec::new(power_plugin::NAME).int(mis::SAMPLES, samples)
}

/// lumis' `path` as Mitsuba's `path` samples: at every vertex one light chosen uniformly, one
/// light sample and one BSDF sample weighed by the power heuristic; `max_depth`, `rr_depth`
/// and `hide_emitters` as given (Mitsuba's defaults otherwise, which are lumis').
pub(super) fn mitsuba_path() -> PluginSpec {
    PluginSpec::new(path::NAME)
        .string(path::LIGHTS, path::ONE)
        .int(mis::SAMPLES, 2)
        .int(path::DEEP_SAMPLES, 2)
        .string(path::WEIGHTING, power_plugin::NAME)
}

impl Converter {
    pub(super) fn integrator(&mut self, node: &Node) -> Result<(), String> {
        let mut p = self.properties(node)?;
        if p.kind == "moment" {
            let nested: Vec<Node> = p
                .objects
                .iter()
                .copied()
                .filter(|o| o.tag_name().name() == "integrator")
                .collect();
            if let [inner] = nested.as_slice() {
                self.note(
                    p.line,
                    "`moment` becomes the integrator it wraps: lumis writes no second-moment \
                     layer (its studies measure variance across runs)",
                );
                self.finish(p, "the moment integrator");
                return self.integrator(inner);
            }
            self.problem(
                p.line,
                "a `moment` integrator with other than one nested integrator is not converted",
            );
            return Ok(());
        }
        self.objects_not_converted(&p.objects, "the integrator", false);
        match p.kind.as_str() {
            "direct" => self.direct(&mut p),
            "path" => self.path_integrator(&mut p),
            other => self.problem(
                p.line,
                format!("integrator `{other}` is not converted: lumis renders `direct` and `path`"),
            ),
        }
        self.finish(p, "the integrator");
        Ok(())
    }

    /// Mitsuba's `direct` (src/integrators/direct.cpp): `emitter_samples` samples of one light
    /// each and `bsdf_samples` BSDF samples, power heuristic. One technique alone becomes lumis'
    /// `light` or `bsdf`, both become `power`. A delta light's emitter sample is weighted 1 there,
    /// not 1/`emitter_samples`, so Mitsuba's image has each delta light `emitter_samples` times
    /// (none with 0): recorded in `delta_light_factor` and applied to the emitters at the end.
    fn direct(&mut self, p: &mut Properties) {
        let mut count = |name: &str| match p.take(name) {
            Some((Value::Int(n), l)) if n >= 0 => Some((n, l)),
            Some((_, l)) => {
                self.report
                    .problem(l, format!("`{name}` must be a non-negative integer"));
                None
            }
            None => None,
        };
        let shading = count("shading_samples");
        let emitter = count("emitter_samples");
        let bsdf = count("bsdf_samples");
        if let (Some((_, l)), true) = (shading, emitter.is_some() || bsdf.is_some()) {
            // Mitsuba throws on this.
            self.problem(
                l,
                "`shading_samples` with `emitter_samples` or `bsdf_samples`: Mitsuba refuses                  both at once",
            );
            return;
        }
        let shading = shading.map_or(1, |(n, _)| n);
        let emitter = emitter.map_or(shading, |(n, _)| n);
        let bsdf = bsdf.map_or(shading, |(n, _)| n);
        if let Some((Value::Bool(true), l)) = p.take("hide_emitters") {
            self.problem(l, "`hide_emitters` is not converted");
        }
        // `samples` saturates: the plugins refuse more than they take, with their limit.
        let (spec, what) = match (emitter, bsdf) {
            (0, 0) => {
                self.problem(
                    p.line,
                    "`direct` with no emitter and no BSDF sample: Mitsuba refuses it",
                );
                return;
            }
            (n, 0) => (
                PluginSpec::new(light_plugin::NAME).int(mis::SAMPLES, n),
                format!(
                    "lumis `light` with samples {n}: light sampling only; at a purely specular \
                     surface (a smooth conductor or dielectric) lumis samples the BSDF where \
                     Mitsuba's image has nothing but emitters seen directly"
                ),
            ),
            (0, n) => (
                PluginSpec::new(bsdf_plugin::NAME).int(mis::SAMPLES, n),
                format!("lumis `bsdf` with samples {n}: BSDF sampling only"),
            ),
            (e, b) => {
                let n = e.saturating_add(b);
                (
                    power(n),
                    format!(
                        "lumis `power` with samples {n}: the same power heuristic, its samples \
                         split evenly between the techniques (the same mean)"
                    ),
                )
            }
        };
        self.note(
            p.line,
            format!(
                "`direct` ({emitter} emitter + {bsdf} BSDF samples, one light chosen per emitter \
                 sample) becomes {what}"
            ),
        );
        if emitter != 1 {
            self.delta_light_factor = Some((emitter, p.line));
        }
        self.integrator = Some(spec);
    }

    fn path_integrator(&mut self, p: &mut Properties) {
        let mut spec = mitsuba_path();
        let mut depth = |name: &str, min: i64| match p.take(name) {
            Some((Value::Int(n), _)) if n >= min => Some(n),
            Some((_, l)) => {
                self.report
                    .problem(l, format!("`{name}` must be an integer of at least {min}"));
                None
            }
            None => None,
        };
        // Mitsuba reads both as unsigned: -1 is its "unbounded" (2³² − 1), as lumis' -1.
        let max_depth = depth("max_depth", -1);
        // 0 and 1 are the same rule in Mitsuba (its depth is at least 1 when it is tested).
        let rr_depth = depth("rr_depth", 0).map(|d| d.max(1));
        if let Some(d) = max_depth {
            spec = spec.int(path::MAX_DEPTH, d.min(i32::MAX as i64));
        }
        if let Some(d) = rr_depth {
            spec = spec.int(path::RR_DEPTH, d.min(i32::MAX as i64));
        }
        match p.take("hide_emitters") {
            Some((Value::Bool(hide), _)) => {
                spec.params
                    .insert(path::HIDE_EMITTERS.into(), ron::Value::Bool(hide));
            }
            Some((_, l)) => self.problem(l, "`hide_emitters` must be a boolean"),
            None => {}
        }
        self.note(
            p.line,
            "`path` becomes lumis `path` with lights \"one\", samples 2 and deep_samples 2, \
             weighting \"power\": Mitsuba's estimator at every vertex (one light chosen uniformly, \
             one light and one BSDF sample, the power heuristic), except that a BSDF sample counts \
             the light it was drawn for only (the same mean)",
        );
        self.integrator = Some(spec);
    }
}

//! Built-in integrator plugins: the MIS family, direct lighting at the first surface a camera
//! ray hits, with BSDF and light sampling combined. Every method is one file, named after the
//! plugin, that registers itself:
//!
//! - `bsdf`: BSDF sampling only.
//! - `light`: light sampling only (BSDF sampling for Dirac lobes).
//! - `balance`: half the samples each, the balance heuristic.
//! - `power`: half each, the power heuristic (β = 2).
//! - `max`: half each, the maximum heuristic.
//! - `cutoff`: half each, Veach's cutoff heuristic.
//! - `alpha`: the second-order adaptive α of Lu, Pacanowski and Granier 2013 (or a fixed α).
//! - `exact_alpha`: the α that exactly minimises a pilot's estimate of the variance.
//! - `cost_alpha`: the α that minimises a pilot's variance times the samples' measured cost.
//! - `pooled_alpha`: α from pilot statistics pooled over similar neighbouring pixels.
//! - `variance_aware`: variance-aware weights (Grittmann et al. 2019) from a pilot pass.
//! - `optimal_mis`: the optimal weights of Kondapaneni et al. 2019.
//! - `path`: path tracing with the family's per-light estimator at every vertex.
//!
//! A method is a [`allocation::Method`] run by [`mis::MisIntegrator`]: most are an
//! [`allocation::Allocation`] (how a light's N samples are split between the techniques, in
//! phases) with a [`weighting::Weighting`] (how a phase's samples are weighed), paired by
//! [`allocation::Weighted`]; one that makes its own weights implements `Method` itself. The
//! modules the plugins share, each importing only modules listed before it (tests below check
//! that no module imports itself through others and that none of these imports a plugin):
//!
//! - [`shading_point`], `batch`: a surface point seen by the camera, and each thread's space
//!   for the batch calls;
//! - [`estimator`]: draws one light's samples at a shading point as [`estimator::SampleRecord`]s;
//! - [`phase`]: a phase's [`phase::SampleSplit`], [`phase::PhaseRole`] and records, the
//!   [`phase::Observer`]s that see it, and a light's [`phase::LightEstimate`];
//! - [`weighting`]: the [`weighting::Weighting`] trait, per-sample heuristics (the balance
//!   heuristic among them) and the checks of a heuristic's tests;
//! - [`aovs`]: the AOV layers and their per-pixel sums, gathered by an observer;
//! - [`sampling`]: [`sampling::LightSampling`], which draws, weighs and shows the phases, in
//!   each thread's buffers;
//! - [`allocation`], [`fixed_alpha`]: the allocation traits and the one-phase allocation;
//! - [`mis`]: the integrator and the family's parameters;
//! - [`moments`], [`second_order`], [`pilot`], [`alpha_family`]: what the α methods share;
//! - [`one_point`]: one shading point's variance as a function of α, exactly (for tests).
//!
//! A new method is one file (its trait impls and its registration) and one `pub mod` line
//! (docs/writing-a-plugin.md).

pub mod allocation;
pub mod alpha_family;
pub mod aovs;
mod batch;
pub mod estimator;
pub mod fixed_alpha;
pub mod mis;
pub mod moments;
pub mod one_point;
pub mod phase;
pub mod pilot;
pub mod sampling;
pub mod second_order;
pub mod shading_point;
pub mod weighting;

pub mod alpha;
pub mod balance;
pub mod bsdf;
pub mod cost_alpha;
pub mod cutoff;
pub mod exact_alpha;
pub mod light;
pub mod max;
pub mod optimal_mis;
pub mod path;
pub mod pooled_alpha;
pub mod power;
pub mod variance_aware;

/// Referenced by the `lumis` facade so the linker keeps this crate and its registrations.
#[inline(never)]
pub fn link() {}

#[cfg(test)]
mod tests {
    use lumis_core::registry::{IntegratorPlugin, PluginInfo, builtin};
    use std::collections::{BTreeMap, BTreeSet};
    use std::path::Path;

    /// The methods this file's doc lists, in its list of `- `name`: ...` lines.
    fn listed_methods() -> Vec<String> {
        include_str!("lib.rs")
            .lines()
            .filter_map(|l| l.strip_prefix("//! - `"))
            .filter_map(|l| l.split_once("`:"))
            .map(|(name, _)| name.to_string())
            .collect()
    }

    /// The doc lists every registered method, and nothing else.
    #[test]
    fn the_crate_doc_lists_every_registered_method() {
        let mut listed = listed_methods();
        listed.sort();
        let registered: Vec<String> = builtin::<IntegratorPlugin>()
            .iter()
            .map(|p| p.name().to_string())
            .collect();
        assert_eq!(listed, registered, "the list in lib.rs's doc");
    }

    /// The crate modules each source file refers to (`crate::module` paths and `use crate::{…}`
    /// groups in code, comments left out), tests included.
    fn module_imports(source: &str) -> BTreeSet<String> {
        let code: String = source
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        let ident = |s: &str| -> String {
            s.chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect()
        };
        let mut modules = BTreeSet::new();
        for (at, _) in code.match_indices("crate::") {
            let rest = &code[at + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let group = &group[..group.find('}').unwrap_or(group.len())];
                modules.extend(group.split(',').map(|item| ident(item.trim())));
            } else {
                modules.insert(ident(rest));
            }
        }
        modules.remove("");
        modules
    }

    /// Each module of the crate with the modules it imports, and whether it is a plugin (its
    /// file submits a registration).
    fn module_graph() -> BTreeMap<String, (BTreeSet<String>, bool)> {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut graph = BTreeMap::new();
        for entry in std::fs::read_dir(&src).expect("src/") {
            let path = entry.expect("a directory entry").path();
            if path.extension().is_some_and(|e| e == "rs") {
                let module = path.file_stem().and_then(|m| m.to_str()).expect("UTF-8");
                let text = std::fs::read_to_string(&path).expect("a source file");
                let mut imports = module_imports(&text);
                imports.remove(module);
                let plugin = text.contains(concat!("inventory::", "submit!"));
                graph.insert(module.to_string(), (imports, plugin));
            }
        }
        assert!(graph.len() >= 20, "found only {:?}", graph.keys());
        graph
    }

    /// The modules that are not plugins import none: plugins build on them, never the reverse.
    #[test]
    fn shared_modules_import_no_plugin() {
        let graph = module_graph();
        for (module, (imports, plugin)) in &graph {
            for import in imports {
                let imports_plugin = graph.get(import).is_some_and(|(_, p)| *p);
                assert!(
                    *plugin || !imports_plugin,
                    "{module}.rs, shared by the plugins, imports the plugin {import}"
                );
            }
        }
        assert!(graph.values().filter(|(_, plugin)| *plugin).count() >= 12);
    }

    /// No two modules of the crate import each other, directly or through others: the
    /// modules form layers (a depth-first search of the graph of `crate::` imports).
    #[test]
    fn no_module_imports_itself_through_others() {
        let graph: BTreeMap<String, BTreeSet<String>> = module_graph()
            .into_iter()
            .map(|(module, (imports, _))| (module, imports))
            .collect();
        // 0: not visited, 1: on the current path, 2: done.
        fn visit(
            module: &str,
            graph: &BTreeMap<String, BTreeSet<String>>,
            state: &mut BTreeMap<String, u8>,
            path: &mut Vec<String>,
        ) {
            path.push(module.to_string());
            match state.get(module).copied().unwrap_or(0) {
                1 => panic!("import circle: {}", path.join(" → ")),
                2 => {}
                _ => {
                    state.insert(module.to_string(), 1);
                    for next in graph.get(module).into_iter().flatten() {
                        visit(next, graph, state, path);
                    }
                    state.insert(module.to_string(), 2);
                }
            }
            path.pop();
        }
        let mut state = BTreeMap::new();
        for module in graph.keys() {
            visit(module, &graph, &mut state, &mut Vec::new());
        }
    }

    /// The import scan finds single paths, groups and nested paths, not comments.
    #[test]
    fn the_import_scan_reads_paths_and_groups() {
        let source =
            "use crate::a::B;\nuse crate::{b, c::D};\n// crate::e\nfn f() { crate::g::h(); }";
        let found: Vec<String> = module_imports(source).into_iter().collect();
        assert_eq!(found, ["a", "b", "c", "g"]);
    }
}

//! What the crate shows beside its methods: its doc's list of methods, a description's N, and
//! `path`'s choice of a light.

/// The tests of `lumis_integrators::mis` (`plugins/integrators/src/mis.rs`).
mod mis {

    use lumis_core::params::Params;

    use lumis_core::registry::IntegratorPlugin;

    use lumis_core::registry::find;
    use lumis_core::scene::description::PluginSpec;
    use lumis_integrators::mis::*;

    /// N set in a description reaches the plugin's `create` as its `samples`.
    #[test]
    fn set_samples_gives_a_plugin_its_n() {
        // By its name: the plugins import this module, not the reverse.
        let plugin = find::<IntegratorPlugin>("balance").expect("balance");
        assert!(takes_samples(plugin));
        let mut spec = PluginSpec {
            kind: "balance".into(),
            params: Default::default(),
        };
        set_samples(&mut spec, 7);
        let mut params = Params::new("balance", plugin.params, spec.params).expect("params");
        assert_eq!(read_samples(&mut params).expect("samples"), 7);
    }
}

/// The tests of `lumis_integrators::path` (`plugins/integrators/src/path.rs`).
mod path {

    use lumis_integrators::path::{choose_light, weights_cdf};

    /// A mixture vertex chooses J among the non-delta lights, and `lights: one` its delta light
    /// among the delta ones, in proportion to their own `sampling_weight`s: each list's running
    /// sums are those of its lights' weights, and equal weights (the default) keep the uniform
    /// choice's arithmetic.
    #[test]
    fn each_light_list_chooses_by_its_own_weights() {
        // Lights 0 and 2 are delta, 1, 3 and 4 are not.
        let weights = [8.0f32, 1.0, 8.0, 4.0, 0.5];
        let mixed = [1usize, 3, 4];
        let cdf = weights_cdf(mixed.iter().map(|&e| weights[e]));
        assert_eq!(cdf, [1.0, 5.0, 5.5]);
        let n = 11_000;
        let mut counts = [0usize; 5];
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            counts[mixed[choose_light(&cdf, u, mixed.len()).0]] += 1;
        }
        for (count, expected) in counts.iter().zip([0, 2000, 0, 8000, 1000]) {
            assert!(count.abs_diff(expected) <= 1, "{counts:?}");
        }
        let delta = [0usize, 2];
        assert!(weights_cdf(delta.iter().map(|&e| weights[e])).is_empty());
        assert!(weights_cdf([3.0f32].into_iter()).is_empty());
        assert!(weights_cdf(std::iter::empty::<f32>()).is_empty());
    }

    /// With `sampling_weight`s, each light is chosen with probability w_j / Σ w (over a
    /// stratified grid of u, exactly up to one stratum), never one of weight 0, and its estimate
    /// is scaled by Σ w / w_j; without, uniformly (the old rule).
    #[test]
    fn lights_are_chosen_in_proportion_to_their_sampling_weight() {
        let weights = [1.0f32, 0.0, 4.0, 0.5, 0.0];
        let cdf: Vec<f32> = weights
            .iter()
            .scan(0.0, |s, &w| {
                *s += w;
                Some(*s)
            })
            .collect();
        let total = cdf[cdf.len() - 1];
        let n = 100_000;
        let mut counts = [0usize; 5];
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            let (light, inverse) = choose_light(&cdf, u, weights.len());
            assert!(weights[light] > 0.0, "u {u}: light {light} of weight 0");
            assert!((inverse - total / weights[light]).abs() <= 1e-5 * inverse);
            counts[light] += 1;
        }
        for (count, w) in counts.iter().zip(weights) {
            let expected = w / total * n as f32;
            assert!((*count as f32 - expected).abs() <= 2.0, "{counts:?}");
        }
        assert_eq!(choose_light(&cdf, 1.0 - f32::EPSILON / 2.0, 5).0, 3);
        assert_eq!(choose_light(&[], 0.99, 4), (3, 4.0));
    }
}

/// The tests of the crate doc (`plugins/integrators/src/lib.rs`).
mod crate_doc {
    use lumis_core::registry::{IntegratorPlugin, PluginInfo, builtin};

    /// The methods this file's doc lists, in its list of `- `name`: ...` lines.
    fn listed_methods() -> Vec<String> {
        include_str!("../src/lib.rs")
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
}

//! The example methods' own properties: `power_beta`'s weights and `lit_fraction`'s α.

/// The tests of `lumis_mis_methods::power_beta` (`plugins/examples/mis_methods/src/power_beta.rs`).
mod power_beta {

    use lumis_integrators::weighting::Heuristic;
    use lumis_integrators::weighting::{
        Balance, assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };
    use lumis_mis_methods::power_beta::*;

    #[test]
    fn weights_are_a_partition_of_unity() {
        for beta in [0.5, 1.0, 2.0, 3.0, 16.0] {
            assert_partition_of_unity(&PowerBeta { beta });
            assert_small_phases_weigh_as_the_lanes_do(&PowerBeta { beta });
        }
    }

    #[test]
    fn beta_one_is_the_balance_heuristic() {
        for (mine, other) in [(1.0, 3.0), (0.25, 0.5), (7.0, 1e-3)] {
            let (a, b) = (
                PowerBeta { beta: 1.0 }.weight(mine, other),
                Balance.weight(mine, other),
            );
            assert!((a - b).abs() <= 1e-6, "{mine} {other}: {a} vs {b}");
        }
    }
}

/// The tests of `lumis_mis_methods::lit_fraction` (`plugins/examples/mis_methods/src/lit_fraction.rs`).
mod lit_fraction {

    use lumis_mis_methods::lit_fraction::*;

    #[test]
    fn alpha_follows_the_lit_counts_within_the_clamp() {
        assert_eq!(LitCounts::default().alpha(), 0.5);
        assert_eq!(LitCounts { bsdf: 3, light: 1 }.alpha(), 4.0 / 6.0);
        assert_eq!(LitCounts { bsdf: 0, light: 40 }.alpha(), 0.1);
        assert_eq!(LitCounts { bsdf: 40, light: 0 }.alpha(), 0.9);
    }
}

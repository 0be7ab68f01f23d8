//! The weightings: the per-sample heuristics (balance, power, maximum, cutoff, the default
//! `weight4`), the variance-aware and the optimal weights.

/// The tests of `lumis_integrators::balance` (`plugins/integrators/src/balance.rs`).
mod balance {

    use lumis_integrators::weighting::{Balance, PerSample};

    use lumis_core::math::Rgb;
    use lumis_core::sampler::Sampler;
    use lumis_integrators::estimator::SampleRecord;
    use lumis_integrators::phase::SampleSplit;
    use lumis_integrators::weighting::{
        Weighting, assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };

    #[test]
    fn weights_are_a_partition_of_unity() {
        assert_partition_of_unity(&Balance);
    }

    #[test]
    fn small_phases_weigh_as_the_lanes_do() {
        assert_small_phases_weigh_as_the_lanes_do(&Balance);
    }

    /// Random records of both techniques, some black, one Dirac (a BSDF sample).
    fn records(split: SampleSplit) -> Vec<SampleRecord> {
        let mut s = Sampler::new(3, 4, 5);
        let mut v: Vec<SampleRecord> = (0..split.total())
            .map(|i| SampleRecord {
                f: if i % 5 == 0 {
                    Rgb::ZERO
                } else {
                    Rgb::new(s.next_1d(), s.next_1d(), s.next_1d())
                },
                p_bsdf: 0.1 + 3.0 * s.next_1d(),
                // Some BSDF samples in directions the light cannot produce.
                p_light: if i < split.n_bsdf && i % 7 == 0 {
                    0.0
                } else {
                    0.1 + 3.0 * s.next_1d()
                },
                delta: false,
            })
            .collect();
        v[1].delta = true;
        v[1].p_light = 0.0;
        v
    }

    /// The balance heuristic is the mixture (defensive) estimator Σ f / (n_B p_B + n_L p_L)
    /// over all samples (a Dirac sample contributing f / n_B), computed here independently.
    #[test]
    fn balance_is_the_mixture_estimator() {
        for split in [
            SampleSplit::new(0.5, 16),
            SampleSplit::new(0.2, 11),
            SampleSplit::new(0.9, 13),
        ] {
            let records = records(split);
            let phase = crate::phase_of(split, &records);
            let mut contributions = vec![Rgb::ZERO; records.len()];
            let value = PerSample(Balance).weigh(&phase, &mut contributions);
            let (n_b, n_l) = (split.n_bsdf as f64, split.n_light as f64);
            let mut expected = glam::DVec3::ZERO;
            for r in &records {
                if r.delta {
                    expected += r.f.as_dvec3() / n_b;
                } else if !r.is_black() {
                    let mix = n_b * r.p_bsdf as f64 + n_l * r.p_light as f64;
                    expected += r.f.as_dvec3() / mix;
                }
            }
            let sum: Rgb = contributions.iter().copied().sum();
            assert!(
                (value.as_dvec3() - expected).abs().max_element() < 1e-5 * expected.max_element(),
                "{split:?}: {value} vs {expected}"
            );
            assert_eq!(sum, value, "contributions add up to the estimate");
        }
    }
}

/// The tests of `lumis_integrators::power` (`plugins/integrators/src/power.rs`).
mod power {

    use lumis_integrators::power::*;
    use lumis_integrators::weighting::{
        assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };

    #[test]
    fn weights_are_a_partition_of_unity() {
        assert_partition_of_unity(&Power);
    }

    #[test]
    fn small_phases_weigh_as_the_lanes_do() {
        assert_small_phases_weigh_as_the_lanes_do(&Power);
    }
}

/// The tests of `lumis_integrators::max` (`plugins/integrators/src/max.rs`).
mod max {

    use lumis_integrators::max::*;
    use lumis_integrators::weighting::{
        assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };

    #[test]
    fn weights_are_a_partition_of_unity() {
        assert_partition_of_unity(&Maximum);
    }

    #[test]
    fn small_phases_weigh_as_the_lanes_do() {
        assert_small_phases_weigh_as_the_lanes_do(&Maximum);
    }
}

/// The tests of `lumis_integrators::cutoff` (`plugins/integrators/src/cutoff.rs`).
mod cutoff {

    use lumis_integrators::weighting::Heuristic;

    use lumis_integrators::cutoff::*;
    use lumis_integrators::max::Maximum;
    use lumis_integrators::weighting::{
        Balance, assert_partition_of_unity, assert_small_phases_weigh_as_the_lanes_do,
    };

    #[test]
    fn weights_are_a_partition_of_unity() {
        for threshold in [0.0, 0.01, 0.1, 0.5, 0.999, 1.0] {
            assert_partition_of_unity(&Cutoff { threshold });
        }
    }

    #[test]
    fn small_phases_weigh_as_the_lanes_do() {
        assert_small_phases_weigh_as_the_lanes_do(&Cutoff { threshold: 0.1 });
    }

    #[test]
    fn small_weights_are_cut_and_the_rest_balanced() {
        let h = Cutoff { threshold: 0.1 };
        assert_eq!(h.weight(1.0, 20.0), 0.0);
        assert_eq!(h.weight(20.0, 1.0), 1.0);
        assert_eq!(h.weight(1.0, 3.0), Balance.weight(1.0, 3.0));
        // Just above the cutoff the balance weight, just below none.
        assert!(h.weight(1.0, 9.99) > 0.09);
        assert_eq!(h.weight(1.0, 10.01), 0.0);
    }

    #[test]
    fn thresholds_zero_and_one_are_balance_and_maximum() {
        let values = [0.0f32, 1e-30, 0.3, 0.7, 1.0, 2.0, 9.0, 1e30];
        for a in values {
            for b in values.iter().copied().filter(|&b| b != a) {
                let balance = Cutoff { threshold: 0.0 }.weight(a, b);
                assert_eq!(balance.to_bits(), Balance.weight(a, b).to_bits(), "{a} {b}");
                let max = Cutoff { threshold: 1.0 }.weight(a, b);
                assert_eq!(max, Maximum.weight(a, b), "{a} {b}");
            }
        }
    }
}

/// The tests of `lumis_integrators::weighting` (`plugins/integrators/src/weighting.rs`).
mod heuristic {

    use glam::Vec4;

    use lumis_integrators::weighting::*;

    /// A heuristic that only gives `weight` (as a third-party one may) gets `weight4` lane by
    /// lane; every built-in heuristic overrides it, so only this test reaches the default.
    #[test]
    fn the_default_weight4_applies_weight_to_each_lane() {
        struct Square;
        impl Heuristic for Square {
            fn weight(&self, mine: f32, other: f32) -> f32 {
                mine * mine / (mine * mine + other * other)
            }
        }
        let (mine, other) = (
            Vec4::new(1.0, 2.0, 0.5, 7.0),
            Vec4::new(3.0, 1.0, 0.25, 0.0),
        );
        let lanes = Square.weight4(mine, other).to_array();
        for (i, lane) in lanes.into_iter().enumerate() {
            assert_eq!(lane, Square.weight(mine[i], other[i]), "lane {i}");
        }
    }
}

/// The tests of `lumis_integrators::variance_aware` (`plugins/integrators/src/variance_aware.rs`).
mod variance_aware {

    use lumis_integrators::phase::SampleSplit;

    use lumis_integrators::weighting::{Balance, PerSample, Weighting};

    use lumis_core::math::Rgb;

    use lumis_integrators::estimator::SampleRecord;
    use lumis_integrators::variance_aware::*;

    #[test]
    fn factors_follow_the_moment_form_and_its_guards() {
        assert_eq!(moment_factor(2.0, 4.0), 2.0);
        assert_eq!(moment_factor(0.0, 4.0), 1.0);
        assert_eq!(moment_factor(3.0, 0.0), 1.0);
    }

    /// With factors (c_B, c_L) a sample's weight is c_t n_t p_t / Σ c_k n_k p_k: the BSDF and
    /// light samples at one direction still sum to one, and factors (1, 1) are the balance
    /// heuristic bit for bit.
    #[test]
    fn scaled_weights_are_a_partition_of_unity() {
        let r = SampleRecord {
            f: Rgb::ONE,
            p_bsdf: 0.7,
            p_light: 2.5,
            delta: false,
        };
        let records = [r, r, r, r, r];
        let split = SampleSplit {
            n_bsdf: 2,
            n_light: 3,
        };
        let phase = crate::phase_of(split, &records);
        for factors in [[1.0, 1.0], [4.0, 1.0], [1.0, 30.0]] {
            let mut c = [Rgb::ZERO; 5];
            ScaledBalance(factors).weigh(&phase, &mut c);
            // Weight = contribution · n p / f.
            let w_b = c[0].x * 2.0 * 0.7;
            let w_l = c[2].x * 3.0 * 2.5;
            assert!((w_b + w_l - 1.0).abs() < 1e-6, "{factors:?}");
            let expected = factors[0] * 1.4 / (factors[0] * 1.4 + factors[1] * 7.5);
            assert!((w_b - expected).abs() < 1e-6);
        }
        let mut a = [Rgb::ZERO; 5];
        let mut b = [Rgb::ZERO; 5];
        ScaledBalance([1.0, 1.0]).weigh(&phase, &mut a);
        PerSample(Balance).weigh(&phase, &mut b);
        assert_eq!(a, b);
    }
}

/// The tests of `lumis_integrators::optimal_mis` (`plugins/integrators/src/optimal_mis.rs`).
mod optimal_mis {

    use lumis_integrators::estimator::SampleRecord;

    use lumis_integrators::phase::SampleSplit;

    use glam::DVec3;
    use lumis_integrators::weighting::{Balance, PerSample, Weighting};

    use lumis_core::math::Rgb;

    use lumis_integrators::optimal_mis::*;

    /// If f is exactly a combination of the densities, f = c_B p_B + c_L p_L, the direct
    /// estimate is exact (c_B + c_L) whatever the samples: the control variate removes all
    /// variance.
    #[test]
    fn a_combination_of_the_densities_is_integrated_exactly() {
        let (c_b, c_l) = (0.3f32, 0.7f32);
        let mut records = Vec::new();
        // Densities on [0, 1]: p_B = 2x, p_L = 1; samples anywhere (black ones too).
        for (i, x) in [0.1f32, 0.5, 0.9, 0.3, 0.05, 0.7, 0.2, 0.95]
            .iter()
            .enumerate()
        {
            let (p_b, p_l) = (2.0 * x, 1.0);
            let f = c_b * p_b + c_l * p_l;
            records.push(crate::grey(if i % 3 == 2 { 0.0 } else { f }, p_b, p_l));
        }
        // Black samples break f = c·p: rebuild f exactly instead.
        for r in &mut records {
            r.f = Rgb::splat(c_b * r.p_bsdf + c_l * r.p_light);
        }
        let split = SampleSplit {
            n_bsdf: 4,
            n_light: 4,
        };
        let phase = crate::phase_of(split, &records);
        let mut contributions = vec![Rgb::ZERO; records.len()];
        let value = DirectOptimal.weigh(&phase, &mut contributions);
        assert!((value.x - (c_b + c_l)).abs() < 1e-5, "{value}");
        let sum: Rgb = contributions.iter().copied().sum();
        assert!((sum - value).abs().max_element() < 1e-5, "{sum} vs {value}");
    }

    #[test]
    fn proportional_densities_fall_back_to_balance() {
        let records: Vec<SampleRecord> = (0..6)
            .map(|i| crate::grey(1.0 + i as f32, 1.0 + i as f32, 2.0 + 2.0 * i as f32))
            .collect();
        let split = SampleSplit {
            n_bsdf: 3,
            n_light: 3,
        };
        let phase = crate::phase_of(split, &records);
        assert_eq!(OptimalSystem::from_phase(&phase).solve(), None);
        let mut a = vec![Rgb::ZERO; 6];
        let mut b = vec![Rgb::ZERO; 6];
        assert_eq!(
            DirectOptimal.weigh(&phase, &mut a),
            PerSample(Balance).weigh(&phase, &mut b)
        );
        assert_eq!(a, b);
    }

    /// The clipped weights of a sample with f > 0 form a partition of unity: the BSDF sample's
    /// and the light sample's weights at the same direction add up to one.
    #[test]
    fn clipped_weights_are_a_partition_of_unity() {
        let coefficients = [DVec3::new(0.5, -2.0, 40.0), DVec3::new(1.5, 3.0, -1.0)];
        for (f, p_b, p_l) in [(1.0, 0.3, 2.0), (0.01, 5.0, 0.2), (3.0, 1.0, 1.0)] {
            let records = [crate::grey(f, p_b, p_l), crate::grey(f, p_b, p_l)];
            let split = SampleSplit {
                n_bsdf: 1,
                n_light: 1,
            };
            let phase = crate::phase_of(split, &records);
            let mut c = [Rgb::ZERO; 2];
            ClippedOptimal(coefficients).weigh(&phase, &mut c);
            // Contribution = w f / p (n = 1): the weights are c p / f.
            let w = |c: Rgb, p: f32| c * p / f;
            let total = w(c[0], p_b) + w(c[1], p_l);
            assert!((total - Rgb::ONE).abs().max_element() < 1e-5, "{total}");
            assert!(c.iter().all(|c| c.min_element() >= 0.0));
        }
    }
}

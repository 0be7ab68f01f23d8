//! What the α methods share: the pilot's moments and objectives, the second-order α and its
//! sums, the pooled and learned α, one shading point's exact variance, and the vertex cache.

/// The tests of `lumis_integrators::moments` (`plugins/integrators/src/moments.rs`).
mod moments {
    use lumis_integrators::estimator::SampleRecord;

    use lumis_core::math::Rgb;
    use lumis_integrators::moments::*;

    /// A pilot at α = ½ whose samples follow a synthetic integrand on [0, 1]: f = 1 on [0, w],
    /// p_B uniform, p_L a box of height 1/w on [0, w] (concentrated light), half the samples
    /// from each. Exact second moment: ∫ f²/q_α = w² / (α w + 1 − α) (on [0, w], q_α = α + (1 −
    /// α)/w), minimised at α = 0.
    fn box_pilot(w: f32, n: usize) -> Vec<SampleRecord> {
        let mut records = Vec::new();
        for i in 0..n {
            let x = (i as f32 + 0.5) / n as f32;
            let inside = x < w;
            records.push(crate::grey(
                if inside { 1.0 } else { 0.0 },
                1.0,
                if inside { 1.0 / w } else { 0.0 },
            ));
        }
        for i in 0..n {
            let x = w * (i as f32 + 0.5) / n as f32;
            records.push(crate::grey(if x < w { 1.0 } else { 0.0 }, 1.0, 1.0 / w));
        }
        records
    }

    #[test]
    fn the_second_moment_matches_its_integral() {
        let records = box_pilot(0.1, 1000);
        let pilot = PilotSamples::from_records(&records, 1000, 1000);
        for alpha in [0.0, 0.2, 0.5, 0.9, 1.0] {
            let exact = 0.01 / (alpha * 0.1 + 1.0 - alpha);
            let m = pilot.sums(alpha).second_moment;
            assert!(
                (m - exact).abs() < 1e-3 * exact,
                "α {alpha}: {m} vs {exact}"
            );
        }
        // The means of the techniques add up to the integral, 0.1.
        let s = pilot.sums(0.3);
        let mean = 0.3 * s.mean_bsdf + 0.7 * s.mean_light;
        assert!((mean - 0.1).abs() < 1e-4 && (pilot.mean() - 0.1).abs() < 1e-4);
    }

    /// The objective at the nodes, added in one pass over the records, is the objective at
    /// each node; a pilot drawn at β = ¼ gives the second-order sums of one at ½.
    #[test]
    fn nodes_and_second_order_sums_match_their_definitions() {
        let records = box_pilot(0.1, 200);
        let pilot = PilotSamples::from_records(&records, 200, 200);
        let clamp = [0.025, 0.975];
        for objective in [Objective::Mixture, Objective::Stratified] {
            let mut nodes = [1.0; 17];
            assert!(pilot.add_objective_at_nodes(objective, clamp, &mut nodes));
            for (k, v) in nodes.iter().enumerate() {
                let expected = 1.0 + pilot.objective(objective, 0.025 + 0.95 * k as f64 / 16.0);
                assert!(
                    (v - expected).abs() <= 1e-12 * expected,
                    "{objective:?} node {k}"
                );
            }
        }
        // Î₁, Î₂ of the box at ½ (records drawn at ½) and from records drawn at ¼: the BSDF
        // stratum of the first, a quarter as many, with the light stratum whole.
        let quarter: Vec<SampleRecord> = records[..200]
            .iter()
            .step_by(3)
            .chain(&records[200..])
            .copied()
            .collect();
        let n_bsdf = records[..200].iter().step_by(3).count() as u32;
        let at_quarter = PilotSamples::from_records(&quarter, n_bsdf, 200);
        let (half, other) = (pilot.second_order(), at_quarter.second_order());
        for (a, b) in [(half.0, other.0), (half.1, other.1)] {
            assert!((a - b).abs() < 0.02 * a.abs(), "{half:?} vs {other:?}");
        }
    }

    /// The variance at the nodes (what a learned cost-aware α sums) is the mixture's
    /// ∫ f²/q_α − μ² of the box, w² / (α w + 1 − α) − w², or the stratified estimator's, and is
    /// not clamped: a pilot whose variance estimate is below 0 adds it as it is.
    #[test]
    fn variances_at_nodes_match_their_definitions_unclamped() {
        let records = box_pilot(0.1, 400);
        let pilot = PilotSamples::from_records(&records, 400, 400);
        let clamp = [0.025, 0.975];
        let mut mixture = [0.0; 17];
        let mut stratified = [0.0; 17];
        assert!(pilot.add_variance_at_nodes(false, clamp, &mut mixture));
        assert!(pilot.add_variance_at_nodes(true, clamp, &mut stratified));
        for k in 0..17 {
            let alpha = 0.025 + 0.95 * k as f64 / 16.0;
            let exact = 0.01 / (alpha * 0.1 + 1.0 - alpha) - 0.01;
            assert!(
                (mixture[k] - exact).abs() < 2e-5,
                "α {alpha}: {} vs {exact}",
                mixture[k]
            );
            let unit = Objective::Cost {
                stratified: true,
                bsdf: 1.0,
                light: 1.0,
            };
            let expected = pilot.objective(unit, alpha);
            assert!((stratified[k].max(0.0) - expected).abs() <= 1e-12 * expected.max(1e-300));
        }
        // Four equal terms, all where p_B = 2 p_L: μ̂² (unbiased, from both strata) is y², and
        // m̂(α) = y² · 1.5 / (1 + α) falls below it for α > ½.
        let records = [crate::grey(1.0, 2.0, 1.0); 4];
        let small = PilotSamples::from_records(&records, 2, 2);
        let mut nodes = [0.0; 17];
        assert!(small.add_variance_at_nodes(false, clamp, &mut nodes));
        assert!(nodes.iter().any(|&v| v < 0.0), "{nodes:?}");
    }

    #[test]
    fn the_exact_minimum_is_the_clamp_for_a_concentrated_light() {
        let records = box_pilot(0.01, 500);
        let pilot = PilotSamples::from_records(&records, 500, 500);
        assert_eq!(pilot.exact_minimum([0.025, 0.975]), Some(0.025));
    }

    /// An interior minimum: f = x + 0.2 on [0, 1], p_B = 2x, p_L = 1. m(α) = ∫ (x + 0.2)² /
    /// (2αx + 1 − α), whose minimum is found by dense search on the exact integral (Simpson).
    #[test]
    fn the_exact_minimum_of_an_interior_optimum_matches_quadrature() {
        let n = 4000;
        let mut records = Vec::new();
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            let x = u.sqrt(); // p_B = 2x
            records.push(crate::grey(x + 0.2, 2.0 * x, 1.0));
        }
        for i in 0..n {
            let x = (i as f32 + 0.5) / n as f32;
            records.push(crate::grey(x + 0.2, 2.0 * x, 1.0));
        }
        let pilot = PilotSamples::from_records(&records, n as u32, n as u32);
        let exact_m = |alpha: f64| {
            let k = 2000;
            (0..=k)
                .map(|j| {
                    let x = j as f64 / k as f64;
                    let w = if j == 0 || j == k {
                        1.0
                    } else if j % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    w * (x + 0.2) * (x + 0.2) / (2.0 * alpha * x + 1.0 - alpha)
                })
                .sum::<f64>()
                / (3.0 * k as f64)
        };
        let best = minimise_on_grid([0.0, 0.99], exact_m);
        let found = pilot.exact_minimum([0.0, 0.99]).unwrap();
        assert!(found > 0.05 && found < 0.95, "{found}");
        assert!((found - best).abs() < 0.01, "{found} vs {best}");
        // The grid search on the pilot's m̂ agrees with Newton's.
        let grid = minimise_on_grid([0.0, 0.99], |a| pilot.sums(a).second_moment);
        assert!((grid - found).abs() < 1e-3, "{grid} vs {found}");
    }

    #[test]
    fn uninformative_pilots_give_no_alpha() {
        let same = [crate::grey(1.0, 2.0, 2.0), crate::grey(0.5, 1.0, 1.0)];
        let pilot = PilotSamples::from_records(&same, 1, 1);
        assert_eq!(pilot.exact_minimum([0.0, 1.0]), None);
        let mut nodes = [1.0; 5];
        assert!(!pilot.add_objective_at_nodes(Objective::Mixture, [0.0, 1.0], &mut nodes));
        assert_eq!(nodes, [1.0; 5]);
        let black = [crate::grey(0.0, 2.0, 0.0), SampleRecord::default()];
        let pilot = PilotSamples::from_records(&black, 1, 1);
        assert_eq!(pilot.minimise(Objective::Stratified, [0.0, 1.0]), None);
    }

    #[test]
    fn dirac_samples_push_alpha_to_the_bsdf() {
        let mut records = vec![
            SampleRecord {
                f: Rgb::splat(0.8),
                p_bsdf: 1.0,
                p_light: 0.0,
                delta: true,
            };
            4
        ];
        records.extend([SampleRecord::default(); 4]);
        let pilot = PilotSamples::from_records(&records, 4, 4);
        assert_eq!(pilot.exact_minimum([0.025, 0.975]), Some(0.975));
        // m(α) = (1/M) Σ (f/β)² / (α/β): 4 samples of f = 0.8 out of M = 8, β = ½.
        let m = pilot.sums(0.5).second_moment;
        assert!((m - 0.5 * (1.6 * 1.6) / 1.0).abs() < 1e-6, "{m}");
    }

    /// Where the techniques see different parts of f (the light sampling finds a bright spot
    /// the BSDF misses, the BSDF a dim broad part the light samples rarely reach), the
    /// stratified estimator's variance is lowest nearer ½ than the mixture's.
    #[test]
    fn the_stratified_objective_keeps_both_techniques_where_they_see_different_parts() {
        let mut records = Vec::new();
        // BSDF samples: a broad dim region, density 1, where the light's density is small.
        for _ in 0..50 {
            records.push(crate::grey(1.0, 1.0, 0.01));
        }
        // Light samples: a bright spot, light density 100, BSDF density 0.01.
        for _ in 0..50 {
            records.push(crate::grey(100.0, 0.01, 100.0));
        }
        let pilot = PilotSamples::from_records(&records, 50, 50);
        let mixture = pilot.minimise(Objective::Mixture, [0.025, 0.975]).unwrap();
        let stratified = pilot
            .minimise(Objective::Stratified, [0.025, 0.975])
            .unwrap();
        let v = |a: f64| pilot.objective(Objective::Stratified, a);
        assert!(v(stratified) <= v(mixture) + 1e-12);
        assert!(v(stratified) <= v(0.5) + 1e-12);
        // Cost: with light samples ten times cheaper, α moves toward the light.
        let cheap_light = Objective::Cost {
            stratified: true,
            bsdf: 10.0,
            light: 1.0,
        };
        let cost = pilot.minimise(cheap_light, [0.025, 0.975]).unwrap();
        assert!(cost <= stratified + 1e-3, "{cost} vs {stratified}");
    }
}

/// The tests of `lumis_integrators::second_order` (`plugins/integrators/src/second_order.rs`).
mod second_order {
    use lumis_core::math::Rgb;
    use lumis_core::math::lanes::DEFAULT_WIDTH;
    use lumis_integrators::estimator::SampleRecord;
    use lumis_integrators::phase::Observer;
    use lumis_integrators::phase::SampleSplit;
    use lumis_integrators::second_order::*;

    /// The moments of a synthetic integrand on [0, 1]: the concentrated density is a box of
    /// height k (width 1/k), the other is 1, and f follows the concentrated one. Half the
    /// samples come from each density (a stratified sample of p̄), as at α = ½.
    fn synthetic_moments(k: f32, concentrated_is_bsdf: bool) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        let n = 20_000;
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            for x in [u / k, u] {
                let p = if x < 1.0 / k { k } else { 0.0 };
                if concentrated_is_bsdf {
                    moments.add(p, p, 1.0);
                } else {
                    moments.add(p, 1.0, p);
                }
            }
        }
        moments
    }

    #[test]
    fn a_near_mirror_lobe_under_a_broad_light_gives_three_quarters() {
        // f concentrated where p_B is: the supplemental's §1.4 limit.
        let alpha = synthetic_moments(1e4, true).alpha([0.0, 1.0]);
        assert!((alpha - 0.75).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn a_tiny_light_over_a_broad_lobe_gives_one_quarter() {
        let alpha = synthetic_moments(1e4, false).alpha([0.0, 1.0]);
        assert!((alpha - 0.25).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn mirrors_give_three_quarters() {
        let mut moments = SecondOrderMoments::default();
        moments.add_dirac(0.8);
        assert_eq!(moments.alpha([0.0, 1.0]), 0.75);
    }

    /// Records of every kind: black, Dirac, lit with densities from 10⁻³ to 10³ (some BSDF
    /// samples the light cannot produce), integrands from 10⁻³ to 10³.
    fn varied_records(n: usize, seed: u64) -> Vec<SampleRecord> {
        let mut s = lumis_core::sampler::Sampler::new(seed, 1, 2);
        let spread = |s: &mut lumis_core::sampler::Sampler| 10f32.powf(6.0 * s.next_1d() - 3.0);
        (0..n)
            .map(|i| {
                let f = Rgb::new(spread(&mut s), spread(&mut s), spread(&mut s));
                match (i + 3) % 7 {
                    0 => SampleRecord::default(),
                    // Chosen among two lobes.
                    1 => SampleRecord {
                        f,
                        p_bsdf: 0.5,
                        p_light: 0.0,
                        delta: true,
                    },
                    2 => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: 0.0,
                        delta: false,
                    },
                    _ => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: spread(&mut s),
                        delta: false,
                    },
                }
            })
            .collect()
    }

    fn observed(records: &[SampleRecord]) -> SecondOrderMoments {
        let split = SampleSplit {
            n_bsdf: records.len() as u32,
            n_light: 0,
        };
        let mut moments = SecondOrderMoments::default();
        moments.observe(&crate::phase_of(split, records), &[]);
        moments
    }

    fn in_f64(records: &[SampleRecord]) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        records.iter().for_each(|r| moments.add_record(r));
        moments
    }

    #[test]
    fn the_lanes_sum_what_f64_sums_within_f32_rounding() {
        // Against the f64 sums of the same f32 inputs, a term q²r = f²Δp/p̄³ carries the
        // roundings of p̄ (three times, as p̄⁻³), 1/p̄ (three), q (two), Δp, r, q² and q²r: 12;
        // q²r² five more (Δp, p̄, 1/p̄ and r again, and the product): 17. A slot sums at most
        // BLOCK / 8 terms from zero: 7 roundings. So |error| ≤ ((1 + γ(n))(1 + γ(7)) − 1) ·
        // Σ|term|, n = 12 and 17 (pbrt-v4's γ(n) = nε/(1 − nε), ε = 2⁻²⁴).
        let gamma =
            |n: f64| n * f64::from(f32::EPSILON) / 2.0 / (1.0 - n * f64::from(f32::EPSILON) / 2.0);
        let sums = gamma((BLOCK / SLOTS - 1) as f64);
        let bound = |n: f64| (1.0 + gamma(n)) * (1.0 + sums) - 1.0;
        let (bound_i1, bound_i2) = (bound(12.0), bound(17.0));
        for n in [1, 7, 8, 9, 31, 64, 65, 150] {
            let records = varied_records(n, n as u64);
            let (lanes, exact) = (observed(&records), in_f64(&records));
            let mut absolute = SecondOrderMoments::default();
            for r in &records {
                let mut one = SecondOrderMoments::default();
                one.add_record(r);
                absolute.i1 += one.i1.abs();
                absolute.i2 += one.i2.abs();
            }
            assert!(exact.i2 > 0.0, "{n} records: some are lit");
            assert!(
                (lanes.i1 - exact.i1).abs() <= bound_i1 * absolute.i1,
                "{n}: I₁ {lanes:?} vs {exact:?}"
            );
            assert!(
                (lanes.i2 - exact.i2).abs() <= bound_i2 * absolute.i2,
                "{n}: I₂ {lanes:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn every_width_gives_the_same_bits() {
        let records = varied_records(150, 9);
        lumis_core::math::lanes::limit_width(4);
        let four = observed(&records);
        for width in [8, 16] {
            lumis_core::math::lanes::limit_width(width);
            let wider = observed(&records);
            assert_eq!(four.i1.to_bits(), wider.i1.to_bits(), "{width} lanes");
            assert_eq!(four.i2.to_bits(), wider.i2.to_bits(), "{width} lanes");
        }
        lumis_core::math::lanes::limit_width(DEFAULT_WIDTH);
    }

    #[test]
    fn terms_beyond_the_range_of_f32_are_summed_in_f64() {
        let lit = |f: f32, p_bsdf: f32, p_light: f32| SampleRecord {
            f: Rgb::splat(f),
            p_bsdf,
            p_light,
            delta: false,
        };
        // q = f / p̄ ≈ 10³⁰: q² overflows f32. Then f = 10⁻²⁵: q² r² underflows it.
        for scale in [1e30, 1e-25] {
            let records: Vec<_> = (0..20)
                .map(|i| lit(scale * (1.0 + i as f32), 1.0 + (i % 3) as f32, 2.0))
                .collect();
            let (lanes, exact) = (observed(&records), in_f64(&records));
            assert_eq!(lanes, exact, "f scaled by {scale}");
            assert!(exact.i1.is_finite() && exact.i2 > 0.0, "{exact:?}");
            // α does not depend on the integrand's scale.
            let unscaled: Vec<_> = records
                .iter()
                .map(|r| lit(r.f.x / scale, r.p_bsdf, r.p_light))
                .collect();
            let alpha = observed(&unscaled).alpha([0.0, 1.0]);
            assert!(
                (lanes.alpha([0.0, 1.0]) - alpha).abs() < 1e-6,
                "f scaled by {scale}"
            );
        }
    }

    #[test]
    fn undefined_estimates_give_one_half_within_the_clamp() {
        assert_eq!(second_order_alpha(0.0, 0.0), None);
        assert_eq!(second_order_alpha(1.0, f64::INFINITY), None);
        // p_B = p_L everywhere: Δp = 0, I₂ = 0, so α is undefined (the integrator uses ½).
        let mut moments = SecondOrderMoments::default();
        for i in 0..100 {
            moments.add(1.0 + i as f32, 2.0, 2.0);
        }
        assert_eq!(second_order_alpha(moments.i1, moments.i2), None);
        assert_eq!(moments.alpha([0.025, 0.975]), 0.5);
        assert_eq!(moments.alpha([0.6, 0.9]), 0.6);
    }
}

/// The tests of `lumis_integrators::pooled_alpha` (`plugins/integrators/src/pooled_alpha.rs`).
mod pooled_alpha {

    use lumis_integrators::learned::{NODES, Pooled, alpha_of};

    use lumis_integrators::moments::Objective;

    use lumis_integrators::pilot::SampleCosts;

    #[test]
    fn the_node_minimum_is_refined_by_a_parabola() {
        // (α − 0.3)² sampled at the 17 nodes of [0, 1]: the vertex is found exactly.
        let mut values: Vec<f32> = (0..NODES)
            .map(|k| (k as f32 / 16.0 - 0.3).powi(2))
            .collect();
        values.push(1.0);
        let alpha = alpha_of(
            Pooled::Nodes(Objective::Mixture),
            &values,
            [0.0, 1.0],
            SampleCosts::EQUAL,
        )
        .unwrap();
        assert!((alpha - 0.3).abs() < 1e-6, "{alpha}");
        // A minimum at a bound stays there.
        let mut values: Vec<f32> = (0..NODES).map(|k| k as f32).collect();
        values.push(1.0);
        let alpha = alpha_of(
            Pooled::Nodes(Objective::Mixture),
            &values,
            [0.025, 0.975],
            SampleCosts::EQUAL,
        );
        assert_eq!(alpha, Some(0.025));
        // Uninformative: no α.
        values[NODES] = 0.0;
        assert_eq!(
            alpha_of(
                Pooled::Nodes(Objective::Mixture),
                &values,
                [0.0, 1.0],
                SampleCosts::EQUAL
            ),
            None
        );
    }
}

/// The tests of `lumis_integrators::learned` (`plugins/integrators/src/learned.rs`).
mod learned {

    use lumis_integrators::pilot::SampleCosts;

    use lumis_integrators::learned::*;

    /// A variance (α − ½)² + 0.1 at the nodes of [0, 1], observed once.
    fn parabola() -> Vec<f32> {
        let mut values: Vec<f32> = (0..NODES)
            .map(|k| {
                let alpha = k as f64 / (NODES - 1) as f64;
                ((alpha - 0.5).powi(2) + 0.1) as f32
            })
            .collect();
        values.push(1.0);
        values
    }

    /// The cost-aware α minimises V̂(α) (α c_B + (1 − α) c_L): at equal costs the variance's
    /// minimum; with BSDF samples 3× as costly, the minimum of ((α − ½)² + 0.1)(1 + 2α), below
    /// ½ (the root of its derivative); a variance nowhere positive, or no observation, gives
    /// no α.
    #[test]
    fn the_cost_aware_alpha_weighs_the_variance_by_the_cost() {
        let cost = Pooled::Cost { stratified: false };
        let clamp = [0.0, 1.0];
        let equal = alpha_of(cost, &parabola(), clamp, SampleCosts::EQUAL).unwrap();
        assert!((equal - 0.5).abs() < 1e-6, "{equal}");
        let dear_bsdf = SampleCosts {
            bsdf: 3.0,
            light: 1.0,
        };
        let alpha = alpha_of(cost, &parabola(), clamp, dear_bsdf).unwrap();
        // d/dα [((α − ½)² + 0.1)(1 + 2α)] = 0: 6α² − 2α − 0.3 = 0 (expanded), α = (2 + √(4 +
        // 7.2)) / 12.
        let exact = (2.0 + 11.2f64.sqrt()) / 12.0;
        assert!(
            alpha < 0.5 && (alpha - exact).abs() < 0.01,
            "{alpha} vs {exact}"
        );
        let mut flat = vec![-0.01f32; NODES];
        flat.push(1.0);
        assert_eq!(alpha_of(cost, &flat, clamp, dear_bsdf), None);
        let mut unseen = parabola();
        unseen[NODES] = 0.0;
        assert_eq!(alpha_of(cost, &unseen, clamp, dear_bsdf), None);
    }
}

/// The tests of `lumis_integrators::one_point` (`plugins/integrators/src/one_point.rs`).
mod one_point {

    use glam::{Vec2, Vec3};
    use lumis_core::bsdf::{Bsdf, BsdfContext};
    use lumis_core::math::Rgb;

    use lumis_core::bsdf::{BsdfFlags, BsdfSample};
    use lumis_core::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
    use lumis_integrators::one_point::*;

    /// A Lambertian lobe of albedo 1, enough to check the quadrature against closed forms.
    struct Lambert;

    impl Bsdf for Lambert {
        fn eval(&self, _ctx: &BsdfContext, _wo: Vec3, wi: Vec3) -> Rgb {
            Rgb::splat(wi.z.max(0.0) / std::f32::consts::PI)
        }
        fn pdf(&self, _ctx: &BsdfContext, _wo: Vec3, wi: Vec3) -> f32 {
            cosine_hemisphere_pdf(wi.z)
        }
        fn sample(&self, ctx: &BsdfContext, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
            let wi = square_to_cosine_hemisphere(u);
            lumis_core::bsdf::sample_from_pdf(self, ctx, wo, wi)
        }
        fn flags(&self) -> BsdfFlags {
            BsdfFlags::DIFFUSE_REFLECTION
        }
    }

    /// A light straight above a Lambertian lobe: μ = L_e sin²θ_max (the irradiance of a cap,
    /// over π), and at α = 1 the second moment is L_e² ∫ cos/π = L_e μ.
    #[test]
    fn the_quadrature_matches_closed_forms() {
        let radius = 0.4f64;
        let point = OnePoint::new(&Lambert, Vec3::Z, Vec3::Z, radius, 2.0);
        let mu = 2.0 * radius.sin().powi(2);
        assert!((point.mean() - mu).abs() < 1e-6 * mu, "{}", point.mean());
        let m1 = point.second_moment(1.0);
        assert!((m1 - 2.0 * mu).abs() < 1e-5 * mu, "{m1}");
        // At α = 1 the estimator f / p_B = L_e is constant where the cone is: variance L_e μ − μ².
        assert!((point.variance(1.0) - (2.0 * mu - mu * mu)).abs() < 1e-5);
        // Stratified and mixture variances agree at the ends (one technique only).
        assert!((point.stratified_variance(0.0) - point.variance(0.0)).abs() < 1e-9);
    }

    #[test]
    fn pilots_see_the_light_with_both_techniques() {
        let point = OnePoint::new(&Lambert, Vec3::Z, Vec3::new(0.3, 0.0, 1.0), 0.3, 1.0);
        let records = point.pilot(4000, 4000, 7);
        let lit_bsdf = records[..4000].iter().filter(|r| !r.is_black()).count();
        let lit_light = records[4000..].iter().filter(|r| !r.is_black()).count();
        assert_eq!(lit_light, 4000);
        // The fraction of cosine-weighted directions in the cone is ∫_cone cos/π = μ / L_e.
        let expected = point.mean() * 4000.0;
        let sigma = (expected * (1.0 - point.mean())).sqrt();
        assert!((lit_bsdf as f64 - expected).abs() < 4.0 * sigma);
    }
}

/// The tests of `lumis_integrators::vertex_cache` (`plugins/integrators/src/vertex_cache.rs`).
mod vertex_cache {

    use lumis_integrators::vertex_cache::*;

    /// Fixed-point sums are exact: any order of the same terms gives the same bits, negative
    /// terms and carries included.
    #[test]
    fn fixed_sums_do_not_depend_on_order() {
        let terms: Vec<f64> = (0..2000)
            .map(|i| ((i * 7919 % 1000) as f64 - 480.0) * 1.37e-3 * (1 + i % 5) as f64)
            .collect();
        let forward = FixedSum::default();
        terms.iter().for_each(|&t| forward.add(t));
        let backward = FixedSum::default();
        terms.iter().rev().for_each(|&t| backward.add(t));
        assert_eq!(forward.value().to_bits(), backward.value().to_bits());
        let exact: f64 = terms.iter().sum();
        assert!(
            (forward.value() - exact).abs() < 1e-6,
            "{} {exact}",
            forward.value()
        );
        let huge = FixedSum::default();
        for _ in 0..5000 {
            huge.add(4.0e6);
        }
        assert_eq!(huge.value(), 2.0e10);
    }
}

//! The study's plan: its configuration, the cells it runs, the collection of their results and
//! their store.

/// The tests of `lumis::study::config` (`src/study/config.rs`).
mod config {

    use lumis_integrators::alpha;

    use lumis::study::config::*;
    use std::path::PathBuf;

    #[test]
    fn choices_parse_their_parameters_and_refuse_what_the_study_sets() {
        let c = Choice::parse("alpha:mode=preprocessed:alpha_samples=256").expect("parses");
        assert_eq!(c.spec.kind, "alpha");
        assert_eq!(c.string_param(alpha::MODE), Some("preprocessed"));
        assert_eq!(c.int_param(alpha::ALPHA_SAMPLES), Some(256));
        assert!(!c.is_integrated_alpha());
        assert!(
            Choice::parse("alpha")
                .expect("parses")
                .is_integrated_alpha()
        );
        assert!(Choice::parse("alpha:samples=4").is_err());
        assert!(Choice::parse(":x=1").is_err());
        assert_eq!(
            split_list("balance, alpha:clamp=(0.1,0.9),max"),
            ["balance", "alpha:clamp=(0.1,0.9)", "max"]
        );
    }

    /// The baseline is `balance` in a direct study and `path` with the balance weighting in a
    /// study of `path` rows, wherever it is in the list; the headline falls back to the first
    /// other `path` row; a mixed list is refused.
    #[test]
    fn the_baseline_is_the_balance_row_of_its_family_and_mixed_lists_are_refused() {
        let mut config =
            StudyConfig::new(vec![], PathBuf::from("out")).expect("the defaults parse");
        let with = |config: &mut StudyConfig, list: &str| {
            config.integrators = parse_integrators(list).expect("list");
        };
        assert_eq!(config.baseline().expect("balance"), 2);
        with(
            &mut config,
            "path:weighting=power,path:weighting=balance:max_depth=3",
        );
        assert!(config.is_path_study());
        assert_eq!(config.baseline().expect("path balance"), 1);
        assert_eq!(config.headline_index(), Some(0));
        with(
            &mut config,
            "path:weighting=balance,path:weighting=power,path:allocation=alpha:samples=8",
        );
        assert_eq!(config.headline_index(), Some(2));
        with(&mut config, "path,path:weighting=max");
        assert!(config.baseline().is_err());
        with(&mut config, "balance,path:weighting=balance");
        let error = config.baseline().expect_err("mixed").to_string();
        assert!(error.contains("mixes `path` rows"), "{error}");
        with(&mut config, "balance,light");
        assert!(!config.is_path_study());
        assert_eq!(config.headline_index(), None);
    }

    #[test]
    fn budgets_increase_and_rounds_double_to_the_cap() {
        assert_eq!(parse_budgets("4, 8,16").expect("parses"), [4, 8, 16]);
        assert!(parse_budgets("8,4").is_err());
        assert!(parse_budgets("0,4").is_err());
        let mut config =
            StudyConfig::new(vec![], PathBuf::from("out")).expect("the defaults parse");
        assert_eq!(config.target_budget(), 32);
        config.runs = 4;
        config.max_runs = 20;
        assert_eq!(config.rounds(), [4, 8, 16]);
        config.max_runs = 4;
        assert_eq!(config.rounds(), [4]);
    }
}

/// The tests of `lumis::study::plan` (`src/study/plan.rs`).
mod plan {
    use lumis::study::config::StudyConfig;

    use lumis_integrators::balance;

    use lumis::study::config::{Sweeps, parse_budgets, parse_integrators};
    use lumis::study::plan::*;
    use std::path::PathBuf;

    fn config() -> StudyConfig {
        lumis::link_plugins();
        let mut config =
            StudyConfig::new(vec![PathBuf::from("a.ron")], PathBuf::from("out")).expect("defaults");
        config.integrators = parse_integrators("balance,alpha,light").expect("list");
        config.budgets = parse_budgets("8,16,32,256").expect("ladder");
        config
    }

    #[test]
    fn curves_cover_every_integrator_at_every_budget_and_cells_are_run_major() {
        let config = config();
        let plan = plan_scene(&config, 0, PathBuf::from("s/03.ron")).expect("plans");
        assert_eq!(plan.name, "03");
        assert_eq!(plan.configurations.len(), 12);
        assert_eq!(plan.curves.len(), 3);
        assert_eq!(plan.target, 1, "the middle of 8, 16, 32, 256 is 16");
        assert_eq!((plan.balance, plan.headline), (0, Some(1)));
        assert_eq!(plan.paper.len(), 3, "the integrators at N = 256");
        let cells = plan.cells(1..=2, true);
        assert_eq!(cells.len(), 24);
        assert!(cells[..12].iter().all(|c| c.seed == 1));
        assert_eq!(
            cells[12].role,
            Role::Run {
                configuration: 0,
                run: 2
            }
        );
        assert_eq!(plan.reference_cells().len(), REFERENCE_SHARDS as usize);
        assert_eq!(
            plan.reference.as_ref().map(|r| r.total_samples()),
            Some(4096)
        );
        // The same configuration and plan twice: the same cells.
        let again = plan_scene(&config, 0, PathBuf::from("s/03.ron")).expect("plans");
        assert_eq!(again.cells(1..=2, true), cells);
    }

    #[test]
    fn sweeps_and_paper_pilots_reuse_identical_configurations_and_keep_k0() {
        let mut config = config();
        config.sweeps = Sweeps::parse("all").expect("sweeps");
        config.paper_pilots = true;
        let plan = plan_scene(&config, 0, PathBuf::from("03.ron")).expect("plans");
        // Sweep budget 16: balance at 16 is the curve's; the convergence sweep's balance at
        // N = 4, 8, 16, 32 reuses the curve's at 8, 16 and 32.
        let balance_at = |n: u32| {
            plan.configurations
                .iter()
                .filter(|c| c.choice.spec.kind == balance::NAME && c.samples == n)
                .count()
        };
        assert_eq!((balance_at(4), balance_at(8), balance_at(16)), (1, 1, 1));
        assert_eq!(plan.sweeps.len(), 8 + 4 + 4);
        let growing = plan.configurations.iter().filter(|c| c.grows).count();
        assert_eq!(growing, 12, "only the curves grow");
        assert_eq!(plan.cells(5..=5, false).len(), 12);
        assert_eq!(plan.paper.len(), 4, "and the preprocessed α with M = 4096");
    }
}

/// The tests of `lumis::study::collect` (`src/study/collect.rs`).
mod collect {
    use lumis::study::cell::CellResult;
    use lumis::study::config::StudyConfig;

    use lumis::study::plan::{Role, ScenePlan};

    use lumis::study::summary::Context;

    use lumis_core::math::Rgb;

    use lumis::study::collect::*;
    use lumis::study::config::{parse_budgets, parse_integrators};
    use lumis::study::plan::plan_scene;
    use lumis::study::reference::Reference;

    /// A synthetic cell result: each pixel the reference plus noise that depends on the cell
    /// (a hash of its configuration, run and pixel), σ growing with the configuration's index.
    fn synthetic(cell: &lumis::study::plan::Cell, reference: &[f64], w: u32, h: u32) -> CellResult {
        let Role::Run { configuration, run } = cell.role else {
            unreachable!("runs only")
        };
        let noise = |p: usize| {
            let mut z = (configuration as u64) << 40 ^ u64::from(run) << 20 ^ p as u64;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let sigma = 0.1 * (1.0 + configuration as f64 / 4.0);
        CellResult {
            cell: *cell,
            width: w,
            height: h,
            color: reference
                .iter()
                .enumerate()
                .map(|(p, r)| [(r * (1.0 + sigma * noise(p))) as f32; 3])
                .collect(),
            channels: Vec::new(),
            cpu_time: 0.01 * (1.0 + configuration as f64) * (1.0 + 0.1 * noise(run as usize)),
            wall_time: 0.01,
        }
    }

    const W: u32 = 24;
    const H: u32 = 16;

    /// A one-scene study of `integrators` at N = 4, 8, 16 with K₀ = 3 and a cap of 6, its plan,
    /// the reference's luminance, and the synthetic results of every planned round.
    fn synthetic_study(integrators: &str) -> (StudyConfig, ScenePlan, Vec<f64>, Vec<CellResult>) {
        lumis::link_plugins();
        let mut config = StudyConfig::new(vec!["s/03.ron".into()], "out".into()).expect("defaults");
        config.integrators = parse_integrators(integrators).expect("list");
        config.budgets = parse_budgets("4,8,16").expect("ladder");
        config.runs = 3;
        config.max_runs = 6;
        let plan = plan_scene(&config, 0, "s/03.ron".into()).expect("plan");
        let luminance: Vec<f64> = (0..(W * H) as usize)
            .map(|p| 0.1 + (p % 7) as f64 * 0.3)
            .collect();
        let results = plan
            .cells(1..=3, true)
            .into_iter()
            .chain(plan.cells(4..=6, false))
            .map(|c| synthetic(&c, &luminance, W, H))
            .collect();
        (config, plan, luminance, results)
    }

    /// The analysis of `results` against the noiseless reference `luminance`.
    fn analyse(
        config: &StudyConfig,
        plan: &ScenePlan,
        luminance: &[f64],
        results: &mut dyn Iterator<Item = CellResult>,
    ) -> SceneAnalysis {
        let reference = Reference {
            pixels: luminance.iter().map(|&y| Rgb::splat(y as f32)).collect(),
            luminance: luminance.to_vec(),
            variance: vec![0.0; luminance.len()],
            samples: None,
            cpu_time: None,
            path: "synthetic".into(),
            cached: false,
        };
        let context = Context::new(reference, 0.01, 8, 1.0, W, H);
        let mut collector = Collector::new(plan.clone(), context, config);
        for r in results {
            collector.add(&r).expect("a run of this plan");
        }
        collector.analyse(false).expect("complete runs")
    }

    /// Collect is a pure function of the results: the same cells added in the plan's order or
    /// reversed, or after a round trip through their serialised form, give bit-identical
    /// analyses (what issue 16's `--collect` over cells run anywhere relies on).
    #[test]
    fn collect_is_independent_of_the_order_and_the_transport_of_results() {
        let (config, plan, luminance, results) = synthetic_study("balance,alpha,light");
        let analyse_at = |precision: f64, results: &mut dyn Iterator<Item = CellResult>| {
            let mut config = config.clone();
            config.precision = precision;
            analyse(&config, &plan, &luminance, results)
        };
        let analyse =
            |results: &mut dyn Iterator<Item = CellResult>| analyse_at(config.precision, results);
        let forward = analyse(&mut results.iter().cloned());
        let reversed = analyse(&mut results.iter().rev().cloned());
        let transported = analyse(&mut results.iter().map(|r| {
            let text = ron::to_string(r).expect("serialises");
            ron::from_str::<CellResult>(&text).expect("deserialises")
        }));
        for other in [&reversed, &transported] {
            assert_eq!(other.runs, forward.runs);
            for (a, b) in forward
                .rows
                .iter()
                .flatten()
                .zip(other.rows.iter().flatten())
            {
                assert_eq!(a.relative_variance, b.relative_variance, "{}", a.label);
                assert_eq!(a.ratios.relative_variance, b.ratios.relative_variance);
                assert_eq!(a.relative_mse, b.relative_mse);
                assert_eq!(a.cpu_time, b.cpu_time);
            }
            for (a, b) in forward.trade.iter().zip(&other.trade) {
                assert_eq!(
                    a.speedup.map(|r| r.estimate),
                    b.speedup.map(|r| r.estimate),
                    "{}",
                    a.label
                );
            }
        }
        // The K rule chose a round of the plan, and every curve has every budget.
        assert!(forward.runs == 3 || forward.runs == 6);
        assert_eq!(forward.rows.len(), 3);
        assert!(forward.rows.iter().all(|r| r.len() == 3));

        // A planned study holds every round up to the cap; collect applies the K rule to them
        // and reports the K a local run reports, which stops at the first round precise enough
        // (here K₀ = 3, with a loose precision) or runs to the cap (a precision never met).
        for (precision, local_k) in [(0.9, 3), (1e-9, 6)] {
            let local: Vec<_> = if local_k == 3 {
                results[..plan.cells(1..=3, true).len()].to_vec()
            } else {
                results.clone()
            };
            let local = analyse_at(precision, &mut local.into_iter());
            let planned = analyse_at(precision, &mut results.iter().cloned());
            assert_eq!(
                (local.runs, planned.runs),
                (local_k, local_k),
                "precision {precision}"
            );
            for (a, b) in local
                .rows
                .iter()
                .flatten()
                .zip(planned.rows.iter().flatten())
            {
                assert_eq!(a.relative_variance, b.relative_variance, "{}", a.label);
            }
        }
    }

    /// Where a reading lies is a function of the curve's measured times alone: synthetic times,
    /// in budget order and not (a larger budget measured faster, as timing noise at small
    /// budgets can make it).
    #[test]
    fn readings_are_within_between_the_least_and_the_greatest_measured_time() {
        let logs = |times: [f64; 4]| times.map(f64::ln);
        for times in [logs([1.0, 2.0, 4.0, 8.0]), logs([2.0, 1.0, 4.0, 8.0])] {
            let at = |t: f64| Extent::of(&times, t.ln());
            for t in [1.0, 1.5, 2.0, 3.0, 8.0] {
                assert_eq!(at(t), Extent::Within, "{t} in {times:?}");
            }
            assert_eq!(at(0.6), Extent::Extrapolated);
            assert_eq!(at(15.0), Extent::Extrapolated);
            assert_eq!(at(0.4), Extent::Beyond { above: false });
            assert_eq!(at(17.0), Extent::Beyond { above: true });
        }
    }

    /// Balance read against itself at its own target is a measured point of its curve: a
    /// speed-up of exactly 1, within the curve, even when the target budget's time is the
    /// least of the curve (synthetic times; with measured ones, noise at small budgets can
    /// order them so).
    #[test]
    fn balance_at_its_own_target_is_within_its_curve_whatever_the_times() {
        let (config, plan, luminance, mut results) = synthetic_study("balance,alpha,light");
        let balance = &plan.curves[plan.balance];
        assert_eq!(plan.target, 1, "the middle of 4, 8, 16");
        for result in &mut results {
            let Role::Run { configuration, run } = result.cell.role else {
                continue;
            };
            if let Some(j) = balance.iter().position(|&c| c == configuration) {
                result.cpu_time = [0.02, 0.015, 0.04][j] * (1.0 + 0.01 * f64::from(run));
            }
        }
        let analysis = analyse(&config, &plan, &luminance, &mut results.into_iter());
        let t = analysis
            .trade
            .iter()
            .find(|t| t.label == "balance")
            .expect("balance's trade");
        let speedup = t.speedup.expect("balance reaches its own target");
        assert_eq!(speedup.estimate.value, 1.0);
        for (what, reading) in [
            ("speedup", t.speedup),
            ("time to target", t.time_to_target),
            ("equal-time ratio", t.equal_time_ratio),
        ] {
            assert_eq!(reading.map(|r| r.extent), Some(Extent::Within), "{what}");
        }
    }

    /// The speed-up over the headline α reads α's curve against the integrator's at balance's
    /// target: α over itself is 1, balance over α is the inverse of α's speed-up over balance
    /// (the same two curves, replicate by replicate); a study without an integrated α has none
    /// (and must not read a third curve that is not there).
    #[test]
    fn speedups_over_the_headline_agree_with_those_over_balance_and_need_an_alpha() {
        let (config, plan, luminance, results) = synthetic_study("balance,alpha,light");
        let analysis = analyse(&config, &plan, &luminance, &mut results.into_iter());
        let of = |label: &str| {
            let t = analysis
                .trade
                .iter()
                .find(|t| t.label == label)
                .expect(label);
            (
                t.speedup.map(|r| r.estimate),
                t.speedup_over_headline.map(|r| r.estimate),
            )
        };
        let (Some(alpha_over_balance), Some(alpha_over_alpha)) = of("alpha") else {
            panic!("α reaches the target: {:?}", of("alpha"))
        };
        assert!(
            (alpha_over_alpha.value - 1.0).abs() < 1e-12,
            "{alpha_over_alpha:?}"
        );
        let (_, Some(balance_over_alpha)) = of("balance") else {
            panic!("balance reaches its own target")
        };
        assert!(
            (balance_over_alpha.value * alpha_over_balance.value - 1.0).abs() < 1e-9,
            "{balance_over_alpha:?} · {alpha_over_balance:?}"
        );
        // Log-symmetric intervals of reciprocal values from the same replicates: reciprocal ends.
        assert!((balance_over_alpha.lo * alpha_over_balance.hi - 1.0).abs() < 1e-9);

        let (config, plan, luminance, results) = synthetic_study("balance,light");
        let analysis = analyse(&config, &plan, &luminance, &mut results.into_iter());
        assert_eq!(analysis.trade.len(), 2);
        assert!(
            analysis
                .trade
                .iter()
                .all(|t| t.speedup_over_headline.is_none())
        );
        assert!(analysis.trade.iter().all(|t| t.speedup.is_some()));
    }
}

/// The tests of `lumis::study::store` (`src/study/store.rs`).
mod store {
    use lumis::study::cell::{CellResult, Channel};
    use lumis::study::plan::{Cell, Role};

    use lumis::study::store::*;

    fn result() -> CellResult {
        CellResult {
            cell: Cell {
                scene: 1,
                role: Role::Run {
                    configuration: 5,
                    run: 3,
                },
                seed: 42,
            },
            width: 3,
            height: 2,
            color: (0..6).map(|i| [i as f32, 0.5, -1.0e-30]).collect(),
            channels: vec![Channel {
                name: "alpha.combined".into(),
                values: vec![0.25, 0.5, 0.75, 1.0, f32::MIN_POSITIVE, 0.0],
            }],
            cpu_time: 1.25,
            wall_time: 0.75,
        }
    }

    #[test]
    fn a_cell_reads_back_bit_for_bit_and_damage_is_named() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let path = cell_path(dir.path(), 7);
        let written = result();
        write_cell(&path, &written).expect("writes");
        let read = read_cell(&path, &written.cell).expect("reads");
        assert_eq!(read.color, written.color);
        assert_eq!(read.channels[0].values, written.channels[0].values);
        assert_eq!((read.cpu_time, read.wall_time), (1.25, 0.75));

        let mut other = written.cell;
        other.seed = 43;
        let e = read_cell(&path, &other)
            .expect_err("another cell")
            .to_string();
        assert!(
            e.contains("000007.cell") && e.contains("another plan"),
            "{e}"
        );

        let bytes = std::fs::read(&path).expect("read");
        std::fs::write(&path, &bytes[..bytes.len() - 5]).expect("truncate");
        let e = read_cell(&path, &written.cell)
            .expect_err("truncated")
            .to_string();
        assert!(
            e.contains("000007.cell") && e.contains("runs past the end"),
            "{e}"
        );
        std::fs::write(&path, b"LUMISSHD\x01\0\0\0").expect("write");
        let e = read_cell(&path, &written.cell)
            .expect_err("another kind")
            .to_string();
        assert!(e.contains("not a lumis study cell file"), "{e}");
        let mut newer = bytes.clone();
        newer[8] = 9;
        std::fs::write(&path, &newer).expect("write");
        let e = read_cell(&path, &written.cell)
            .expect_err("a newer format")
            .to_string();
        assert!(e.contains("format 9"), "{e}");
    }

    #[test]
    fn indices_print_as_ranges() {
        assert_eq!(ranges(&[0, 1, 2, 3, 7, 9, 10]), "0-3, 7, 9-10");
        assert_eq!(ranges(&[]), "");
    }
}

//! The study's analysis: statistics, the error summary and its intervals' coverage, colour
//! metrics, panels, the report's tally, plots' ticks and the paper's tables.

/// The tests of `lumis::study::stats` (`src/study/stats.rs`).
mod stats {

    use lumis::study::stats::*;

    fn design(runs: usize, blocks: usize) -> Design {
        Design { runs, blocks }
    }

    #[test]
    fn a_mean_over_runs_gets_the_textbook_variance() {
        // One block, one value per run: the jackknife of a mean is s²/K exactly.
        let values = [1.0, 4.0, 2.0, 7.0];
        let d = design(4, 1);
        let per_run: Vec<[f64; 1]> = values.iter().map(|&v| [v]).collect();
        let refs: Vec<&[f64]> = per_run.iter().map(|r| r.as_slice()).collect();
        let jack = Jack::run_block_mean(d, &refs, 1.0);
        let mean = 3.5;
        let s2 = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 3.0;
        let e = jack.interval();
        assert!((e.value - mean).abs() < 1e-12);
        assert!((e.se * e.se - s2 / 4.0).abs() < 1e-12, "{e:?}");
        // One stratum: K − 1 degrees of freedom.
        assert!((e.df - 3.0).abs() < 1e-9, "{e:?}");
        let t3 = 3.182_446_305_284_263;
        assert!((e.hi - e.value - t3 * e.se).abs() < 1e-6, "{e:?}");
        // The time stratum of the same values gives the same interval.
        let timed = Jack::run_mean(d, Stratum::Time, &values).interval();
        assert!((timed.se - e.se).abs() < 1e-12);
    }

    #[test]
    fn independent_strata_add_their_variances_and_degrees_of_freedom() {
        // Two identical blocks: twice the variance of one, twice the degrees of freedom.
        let d = design(4, 2);
        let runs = [[1.0, 1.0], [4.0, 4.0], [2.0, 2.0], [7.0, 7.0]];
        let refs: Vec<&[f64]> = runs.iter().map(|r| r.as_slice()).collect();
        let e = Jack::run_block_mean(d, &refs, 1.0).interval();
        let s2 = 7.0; // of (1, 4, 2, 7)
        assert!((e.se * e.se - 2.0 * s2 / 4.0).abs() < 1e-12, "{e:?}");
        assert!((e.df - 6.0).abs() < 1e-9, "{e:?}");
    }

    #[test]
    fn ratios_pair_their_replicates_and_log_intervals_are_positive() {
        let d = design(3, 1);
        let a = Jack::run_mean(d, Stratum::Global, &[2.0, 4.0, 6.0]);
        // b = a / 2 exactly: the ratio is 2 in every replicate, so it has no variance.
        let b = a.map(|v| v / 2.0);
        let r = a.ratio(&b).log_interval();
        assert_eq!((r.value, r.lo, r.hi), (2.0, 2.0, 2.0));
        let c = Jack::run_mean(d, Stratum::Global, &[3.0, 1.0, 2.0]);
        let e = a.ratio(&c).log_interval();
        assert!(e.lo > 0.0 && e.lo < e.value && e.value < e.hi, "{e:?}");
    }

    #[test]
    fn student_quantiles() {
        assert!((student_quantile(f64::INFINITY) - 1.959_964).abs() < 1e-6);
        assert!((student_quantile(3.0) - 3.182_446).abs() < 1e-5);
        assert!((student_quantile(30.0) - 2.042_272).abs() < 1e-5);
    }

    #[test]
    fn medians() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn curves_are_reached_between_points_or_along_their_slope() {
        // y = −x: reaches y = −1.5 at x = 1.5, between the points.
        let line = [(0.0, 0.0), (1.0, -1.0), (2.0, -2.0)];
        assert_eq!(reach(&line, -1.5), Some(Reach::Within(1.5)));
        assert_eq!(reach(&line, -3.0), Some(Reach::AfterLast(3.0)));
        assert_eq!(reach(&line, 0.5), Some(Reach::BeforeFirst(-0.5)));
        assert_eq!(reach(&[(0.0, 1.0), (1.0, 1.0)], 0.0), None);
        assert_eq!(reach(&line[..1], -0.5), None);
    }

    /// A level met at a point is reached at that point's x exactly, and between two points
    /// within their x, whatever the rounding: what lets a curve read at its own measured point
    /// be `Within` its measured times.
    #[test]
    fn a_level_met_at_a_point_is_reached_at_its_x() {
        // Logs of times and errors whose interpolation, x0 + (y1 − y0)(x1 − x0)/(y1 − y0),
        // rounds above x1, the greatest time.
        let (x0, x1) = (0.1_f64.ln(), 0.2_f64.ln());
        let (y0, y1) = (0.3_f64.ln(), 0.2_f64.ln());
        assert!(
            x0 + (y1 - y0) * (x1 - x0) / (y1 - y0) > x1,
            "a case that rounds up"
        );
        let points = [(x0, y0), (x1, y1)];
        assert_eq!(reach(&points, y1), Some(Reach::Within(x1)));
        assert_eq!(reach(&points, y0), Some(Reach::Within(x0)));
        // Times out of budget order (a larger budget measured faster): between the two.
        for level in [0.3, 0.25, 0.2000001, 0.2].map(f64::ln) {
            let Some(Reach::Within(x)) = reach(&[(x1, y0), (x0, y1)], level) else {
                panic!("{level} is reached between the points")
            };
            assert!(x0 <= x && x <= x1, "{x} not in [{x0}, {x1}]");
        }
    }
}

/// The tests of `lumis::study::summary` (`src/study/summary.rs`).
mod summary {
    use lumis::study::cell::CellResult;

    use lumis::study::reference::Reference;

    use lumis_core::math::Rgb;

    use lumis::study::summary::*;

    #[test]
    fn blocks_tile_the_image_row_by_row() {
        let blocks = Blocks::new(5, 3, 2);
        assert_eq!(blocks.count, 6);
        assert_eq!(blocks.of(0), 0);
        assert_eq!(blocks.of(4), 2);
        assert_eq!(blocks.of(2 * 5), 3);
        assert_eq!(blocks.of(2 * 5 + 4), 5);
        let sums = blocks.sums((0..15).map(|_| 1.0));
        assert_eq!(sums, [4.0, 4.0, 2.0, 2.0, 2.0, 1.0]);
    }

    /// A normal deviate stream (SplitMix64 and Box–Muller): the coverage test's synthetic
    /// renders, with no dependency on the renderer's samplers.
    struct Normal(u64);

    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }

        fn sample(&mut self) -> f64 {
            let (u, v) = (self.uniform().max(f64::MIN_POSITIVE), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    fn seed() -> u64 {
        std::env::var("LUMIS_TEST_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0)
    }

    /// One synthetic run: each pixel its reference value plus normal noise of the given σ.
    fn synthetic_run(
        run: u32,
        reference: &[f64],
        sigma: &[f64],
        normal: &mut Normal,
        width: u32,
        height: u32,
    ) -> CellResult {
        let color = reference
            .iter()
            .zip(sigma)
            .map(|(&r, &s)| [(r + s * normal.sample()) as f32; 3])
            .collect();
        CellResult {
            cell: lumis::study::plan::Cell {
                scene: 0,
                role: lumis::study::plan::Role::Run {
                    configuration: 0,
                    run,
                },
                seed: u64::from(run),
            },
            width,
            height,
            color,
            channels: Vec::new(),
            cpu_time: 1.0 + 0.1 * normal.sample().abs(),
            wall_time: 1.0,
        }
    }

    /// Over `trials` synthetic studies of two configurations with known per-pixel variances,
    /// the fraction of the nominal 95 % intervals that cover the truth, for the ratio of
    /// relative variances (integrated over pixels: the headline ratio) and for A's relative
    /// MSE. `highlight` multiplies σ of every 97th pixel of A (a few pixels dominating the sum).
    fn coverage(trials: usize, runs: u32, highlight: f64, seed: u64) -> (f64, f64) {
        let (width, height, block) = (48u32, 32u32, 8u32);
        let pixels = (width * height) as usize;
        let luminance: Vec<f64> = (0..pixels)
            .map(|p| 0.05 + 2.0 * ((p * 7919) % 101) as f64 / 101.0)
            .collect();
        let reference = Reference {
            pixels: luminance.iter().map(|&y| Rgb::splat(y as f32)).collect(),
            luminance: luminance.clone(),
            variance: vec![0.0; pixels],
            samples: None,
            cpu_time: None,
            path: std::path::PathBuf::from("synthetic"),
            cached: false,
        };
        let context = Context::new(reference, 0.01, block, 1.0, width, height);
        let reference = context.reference.luminance.clone();
        let sigma_a: Vec<f64> = (0..pixels)
            .map(|p| {
                let boost = if p % 97 == 0 { highlight } else { 1.0 };
                0.2 * reference[p] * boost
            })
            .collect();
        let sigma_b: Vec<f64> = reference.iter().map(|r| 0.25 * r).collect();
        let relative = |sigma: &[f64]| -> f64 {
            sigma
                .iter()
                .zip(&context.weights)
                .map(|(s, w)| s * s * w)
                .sum::<f64>()
                / pixels as f64
        };
        let true_ratio = relative(&sigma_a) / relative(&sigma_b);
        let true_mse = relative(&sigma_a);
        let mut normal = Normal(seed);
        let (mut ratio_hits, mut mse_hits) = (0, 0);
        for _ in 0..trials {
            let summaries = |sigma: &[f64], normal: &mut Normal| -> Vec<RunSummary> {
                (1..=runs)
                    .map(|k| {
                        let cell = synthetic_run(k, &reference, sigma, normal, width, height);
                        RunSummary::new(&cell, k, &context, false)
                    })
                    .collect()
            };
            let a = summaries(&sigma_a, &mut normal);
            let b = summaries(&sigma_b, &mut normal);
            let a = ConfigurationStats::new(&a.iter().collect::<Vec<_>>(), &context);
            let b = ConfigurationStats::new(&b.iter().collect::<Vec<_>>(), &context);
            let ratio = a
                .relative_variance
                .ratio(&b.relative_variance)
                .log_interval();
            ratio_hits += usize::from(ratio.contains(true_ratio));
            mse_hits += usize::from(a.relative_mse.interval().contains(true_mse));
        }
        let n = trials as f64;
        (ratio_hits as f64 / n, mse_hits as f64 / n)
    }

    /// The Wilson score interval of a binomial proportion, at the normal quantile `z`.
    fn wilson(fraction: f64, trials: usize, z: f64) -> (f64, f64) {
        let n = trials as f64;
        let centre = (fraction + z * z / (2.0 * n)) / (1.0 + z * z / n);
        let half = z / (1.0 + z * z / n)
            * (fraction * (1.0 - fraction) / n + z * z / (4.0 * n * n)).sqrt();
        (centre - half, centre + half)
    }

    /// The intervals' coverage on synthetic data with known variance, over 400 trials of K = 4
    /// runs of 48×32 pixels in 8×8 blocks, with evenly spread noise and with noise where 1 % of
    /// the pixels hold most of the variance. Statistics linear in the runs (rel. MSE): the 99 %
    /// Wilson band of the fraction of nominal 95 % intervals that contain the truth contains
    /// 0.95 (±2.8 % at 400 trials). Variances across runs: the jackknife is conservative (for
    /// normal noise its variance is (K − 1)/(K − 2) times too large, docs/study.md), so the
    /// band must reach 0.95 (never too narrow) and contain no value above the coverage that
    /// excess predicts, 2Φ(1.96 √1.5) − 1 = 0.984 at K = 4 (not wider than the theory says).
    #[test]
    fn nominal_95_percent_intervals_cover_the_truth_as_the_theory_says() {
        const TRIALS: usize = 400;
        const Z99: f64 = 2.575_829_3;
        const PREDICTED_VARIANCE_COVERAGE: f64 = 0.984;
        for (highlight, what) in [(1.0, "even noise"), (12.0, "highlights")] {
            let (ratio, mse) = coverage(TRIALS, 4, highlight, seed());
            let (lo, hi) = wilson(mse, TRIALS, Z99);
            assert!(
                lo <= 0.95 && 0.95 <= hi,
                "{what}, rel. MSE: coverage {mse} over {TRIALS} trials, 99 % band [{lo:.3}, {hi:.3}]"
            );
            let (lo, hi) = wilson(ratio, TRIALS, Z99);
            assert!(
                hi >= 0.95 && lo <= PREDICTED_VARIANCE_COVERAGE,
                "{what}, relative variance ratio: coverage {ratio} over {TRIALS} trials, 99 % band [{lo:.3}, {hi:.3}]"
            );
        }
    }

    #[test]
    fn the_top_share_counts_the_largest_thousandth() {
        let mut values = vec![1.0; 999];
        values.push(999.0);
        assert!((top_share(values) - 0.5).abs() < 1e-12);
    }
}

/// The tests of `lumis::study::metrics` (`src/study/metrics.rs`).
mod metrics {
    use lumis::study::metrics::*;
    use lumis_core::math::Rgb;

    #[test]
    fn lab_of_white_black_and_grey() {
        let white = display_to_lab([1.0; 3]);
        assert!((white[0] - 100.0).abs() < 0.01, "{white:?}");
        assert!(white[1].abs() < 0.01 && white[2].abs() < 0.01, "{white:?}");
        assert_eq!(display_to_lab([0.0; 3]), [0.0; 3]);
        // 18 % grey is L* ≈ 49.5 (CIE definition: L* = 116 · 0.18^(1/3) − 16).
        let grey = display_to_lab([0.18f32.powf(1.0 / 2.2); 3]);
        assert!((grey[0] - 49.5).abs() < 0.05, "{grey:?}");
    }

    #[test]
    fn lab_difference_is_zero_for_equal_images_and_clamps_highlights() {
        let a = vec![Rgb::new(0.2, 0.5, 0.9), Rgb::new(5.0, 5.0, 5.0)];
        assert!(lab_difference(&a, &a, 1.0).iter().all(|&d| d == 0.0));
        // Both pixels clip to white after the tone map.
        let b = vec![Rgb::new(0.2, 0.5, 0.9), Rgb::new(50.0, 50.0, 50.0)];
        assert!(lab_difference(&a, &b, 1.0).iter().all(|&d| d == 0.0));
        // Pure red against black: ΔE*ab = |Lab(red)|.
        let red = display_to_lab([1.0, 0.0, 0.0]);
        let d = lab_difference(&[Rgb::X], &[Rgb::ZERO], 1.0)[0];
        let norm = red.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            (d - norm).abs() < 1e-9 && (red[0] - 53.24).abs() < 0.05,
            "{red:?}"
        );
    }
}

/// The tests of `lumis::study::panel` (`src/study/panel.rs`).
mod panel {

    use lumis::study::panel::*;

    #[test]
    fn worst_window_finds_the_error() {
        let (w, h) = (64, 48);
        let mut error = vec![0.0; (w * h) as usize];
        for y in 24..40 {
            for x in 40..56 {
                error[(y * w + x) as usize] = 1.0;
            }
        }
        assert_eq!(worst_window(&error, w, h, 16, 16), (40, 24));
        assert_eq!(heat(0.0), [0, 0, 0]);
        assert_eq!(heat(DELTA_E_WHITE), [255, 255, 255]);
        assert_eq!(alpha_display(0.0), [255, 0, 0]);
        assert_eq!(alpha_display(1.0), [0, 255, 0]);
    }
}

/// The tests of `lumis::study::report` (`src/study/report.rs`).
mod report {
    use lumis::study::collect::{Extent, Reading};

    use lumis::study::stats::Estimate;

    use lumis::study::report::*;

    fn speedup(value: f64, lo: f64, hi: f64, extent: Extent) -> Reading {
        Reading {
            estimate: Estimate {
                value,
                lo,
                hi,
                se: f64::NAN,
                df: f64::NAN,
            },
            extent,
        }
    }

    /// Speed-ups known only as bounds count on their side and rank there in the median (leaving
    /// them out once gave a median of 1.82 for an integrator slower on 5 of 7 scenes).
    #[test]
    fn the_tally_ranks_bounds_on_their_side() {
        let slower_beyond = speedup(0.1, 0.05, 0.2, Extent::Beyond { above: true });
        let faster_beyond = speedup(9.0, 5.0, 20.0, Extent::Beyond { above: false });
        let faster = speedup(1.8, 1.6, 2.0, Extent::Within);
        let not_significant = speedup(1.05, 0.9, 1.2, Extent::Extrapolated);
        let slower = speedup(0.8, 0.7, 0.9, Extent::Within);

        let [median, counts] =
            tally(&[slower_beyond, slower_beyond, slower_beyond, faster, faster]);
        assert_eq!(
            (median.as_str(), counts.as_str()),
            (SLOWER_THAN_BOUND, "2 / 0 / 3")
        );
        let [median, counts] = tally(&[faster_beyond, faster, not_significant, slower, slower]);
        assert_eq!((median.as_str(), counts.as_str()), ("1.05", "2 / 1 / 2"));
        let [median, _] = tally(&[faster_beyond, faster_beyond, faster]);
        assert_eq!(median, FASTER_THAN_BOUND);
        // An even count: the geometric mean of the middle two.
        let [median, _] = tally(&[slower, faster]);
        assert_eq!(median, short((0.8f64 * 1.8).sqrt()));
        assert_eq!(tally(&[])[0], "–");
    }
}

/// The tests of `lumis::study::plots` (`src/study/plots.rs`).
mod plots {

    use lumis::study::plots::*;

    #[test]
    fn log_ticks_are_round_and_never_zero() {
        // Three decades: 1, 2, 5 would make ten ticks, so powers of ten only.
        assert_eq!(log_ticks(0.001, 1.0), [0.001, 0.01, 0.1, 1.0]);
        assert_eq!(log_ticks(0.15, 3.0), [0.2, 0.5, 1.0, 2.0]);
        let ticks = log_ticks(0.0013, 0.9);
        assert!(ticks.iter().all(|&t| t > 0.0), "{ticks:?}");
        for t in &ticks {
            let label = tick_label(*t);
            assert_ne!(label, "0", "{ticks:?}");
            let mantissa = t / 10f64.powf(t.log10().floor());
            assert!(
                [1.0, 2.0, 5.0].iter().any(|m| (mantissa - m).abs() < 1e-9),
                "{t} is not 1, 2 or 5 × 10^k"
            );
        }
        assert_eq!(
            Scale::Log2.ticks(3.0, 300.0),
            [4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0]
        );
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(16.0), "16");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(0.001), "10⁻³");
        assert_eq!(tick_label(0.002), "2×10⁻³");
        assert_eq!(tick_label(1e5), "10⁵");
    }
}

/// The tests of `lumis::study::paper` (`src/study/paper.rs`).
mod paper {
    use lumis::study::config::Choice;

    use lumis::study::paper::*;
    use std::path::Path;

    #[test]
    fn scenes_are_found_by_file_name_and_efficiency_matches_table_2() {
        let s1 = scene(Path::new("scenes/paper/01.ron")).expect("scene 1");
        assert!(scene(Path::new("scenes/paper/12.ron")).is_none());
        assert!(scene(Path::new("scenes/veach.ron")).is_none());
        assert!(scene(Path::new("1.ron")).is_none());
        // Table 2 prints efficiencies 0.0047 (balance) and 0.0060 (integrated α) for scene 1.
        let balance = efficiency(s1, "balance", None).expect("balance");
        let alpha = efficiency(s1, "alpha", Some("integrated")).expect("alpha");
        assert!((balance - 0.0047).abs() < 5e-5, "{balance}");
        assert!((alpha - 0.0060).abs() < 5e-5, "{alpha}");
        assert!(s1.time.get("alpha", Some("preprocessed")).is_none());
        assert_eq!(s1.sampling_variance.ratio("balance", None), Some(1.0));
    }

    #[test]
    fn only_the_papers_configurations_get_its_columns() {
        let at = |text: &str, n| method(&Choice::parse(text).expect("parses"), n);
        assert_eq!(at("balance", 256), Some(("balance", None)));
        assert_eq!(at("balance", 64), None);
        assert_eq!(at("alpha", 256), Some(("alpha", Some("integrated"))));
        assert_eq!(
            at("alpha:alpha_samples=128", 256),
            Some(("alpha", Some("integrated")))
        );
        assert_eq!(at("alpha:alpha_samples=64", 256), None);
        assert_eq!(at("alpha:clamp=(0.1,0.9)", 256), None);
        assert_eq!(
            at("alpha:mode=preprocessed:alpha_samples=4096", 256),
            Some(("alpha", Some("preprocessed")))
        );
        assert_eq!(at("alpha:mode=preprocessed:alpha_samples=256", 256), None);
        assert_eq!(at("cutoff", 256), None);
    }
}

//! A phase's split of the samples, and what the AOVs gather from the phases.

/// The tests of `lumis_integrators::phase` (`plugins/integrators/src/phase.rs`).
mod phase {

    use lumis_integrators::phase::*;

    #[test]
    fn sample_splits_round_and_keep_both_techniques() {
        let split = |n_bsdf, n_light| SampleSplit { n_bsdf, n_light };
        assert_eq!(SampleSplit::new(0.5, 256), split(128, 128));
        assert_eq!(SampleSplit::new(0.025, 16), split(1, 15));
        assert_eq!(SampleSplit::new(0.975, 16), split(15, 1));
        assert_eq!(SampleSplit::new(1.0, 16), split(16, 0));
        assert_eq!(SampleSplit::new(0.0, 16), split(0, 16));
        assert_eq!(SampleSplit::new(0.3, 1).total(), 1);
        assert_eq!(SampleSplit::new(0.5, 0), split(0, 0));
        assert_eq!(SampleSplit::new(0.3, 10).alpha(), 0.3);
    }
}

/// The tests of `lumis_integrators::aovs` (`plugins/integrators/src/aovs.rs`).
mod aovs {
    use lumis_integrators::phase::{LightEstimate, Observer, Phase};

    use lumis_core::math::Rgb;

    use lumis_integrators::aovs::*;
    use lumis_integrators::estimator::SampleRecord;
    use lumis_integrators::phase::{PhaseRole, SampleSplit};

    /// Shows the tally a phase of `n_bsdf + n_light` samples whose one-sample estimates Y are
    /// `values` (grey contributions Y / n).
    fn observe(tally: &mut LightTally, n_bsdf: u32, values: &[f32], role: PhaseRole) {
        let split = SampleSplit {
            n_bsdf,
            n_light: values.len() as u32 - n_bsdf,
        };
        let records = vec![SampleRecord::default(); values.len()];
        let phase = Phase {
            role,
            ..crate::phase_of(split, &records)
        };
        let n = values.len() as f32;
        let contributions: Vec<Rgb> = values.iter().map(|&y| Rgb::splat(y / n)).collect();
        tally.observe(&phase, &contributions);
    }

    fn unbiased_variance(values: &[f64]) -> f64 {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)
    }

    #[test]
    fn the_estimate_channel_weighs_every_counted_phase_and_the_y_channel_only_the_measured() {
        let request = AovRequest::from_names(&[SAMPLING_VARIANCE]);
        let pilot = [1.0f32, 3.0, 2.0, 6.0];
        let second = [4.0f32, 4.5, 3.5, 5.0, 4.0, 3.0];
        let ignored = [100.0f32, -50.0];
        let mut tally = LightTally::default();
        // A pilot that steers only (neither counted nor measured), then an integrated-α-like
        // pair: the first phase counted, the second counted and measured.
        observe(&mut tally, 1, &ignored, PhaseRole::PILOT);
        let first_role = PhaseRole {
            counted: true,
            measured: false,
        };
        observe(&mut tally, 2, &pilot, first_role);
        observe(&mut tally, 5, &second, PhaseRole::ESTIMATE);

        // One light, one shading point: the sums of one pixel.
        let mut sums = vec![0.0; PER_LIGHT + COUNTS];
        let estimate = LightEstimate {
            value: Rgb::ZERO,
            alpha: 0.5,
        };
        request.add(&mut sums, 0, &estimate, &tally);
        let as_f64 = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<_>>();
        let (v1, v2) = (
            unbiased_variance(&as_f64(&pilot)),
            unbiased_variance(&as_f64(&second)),
        );
        let paper_basis = (4.0 * v1 + 6.0 * v2) / 10.0;
        // The pilot that only steers is not counted either.
        let (lights, counts) = pixel_sums(&sums);
        assert_eq!((counts.bsdf, counts.light), (7.0, 3.0));
        // The typed sums are the f64 sums themselves, in order.
        assert_eq!((sums[PER_LIGHT], sums[PER_LIGHT + 1]), (7.0, 3.0));
        assert_eq!(sums[..2], [0.5, 1.0], "Σ α and the shading points first");

        let (measured, all) = (
            lights[0].measured_variance().expect("six measured samples"),
            lights[0].estimate_variance().expect("ten counted samples"),
        );
        assert!((measured - v2).abs() < 1e-9 * v2, "{measured} {v2}");
        assert!(
            (all - paper_basis).abs() < 1e-9 * paper_basis,
            "{all} {paper_basis}"
        );
    }
}

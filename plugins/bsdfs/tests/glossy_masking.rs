//! `glossy`'s `masking` parameter: the separable Smith term (Mitsuba 3's) is sampled
//! consistently (chi-square of `sample` against `pdf`, weight = eval / pdf) and differs from the
//! height-correlated term by exactly the factor the formulas give.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext};

/// The context of a BSDF tested on its own: seen from the front, at uv (0, 0).
const FRONT: BsdfContext = BsdfContext::FRONT;
use lumis_core::chi2::{Chi2Test, FAMILY_FALSE_ALARM, sidak, test_bsdf, test_seed};
use lumis_core::params::Params;
use lumis_core::registry::{self, BsdfPlugin};
use lumis_core::sampler::Sampler;
use std::sync::Arc;

fn bsdf(params: &str) -> Arc<dyn Bsdf> {
    lumis_bsdfs::link();
    let plugin = registry::find::<BsdfPlugin>("glossy").unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new("glossy", plugin.params, values).unwrap();
    let b = (plugin.create)(&mut p).unwrap();
    p.finish().unwrap();
    b
}

/// ωo at the given cos θ, azimuth 30° (no axis is special), unit length to the last bit.
fn incident(cos: f32) -> Vec3 {
    let sin = (1.0 - cos * cos).sqrt();
    let phi = 30f32.to_radians();
    Vec3::new(sin * phi.cos(), sin * phi.sin(), cos).normalize()
}

const INCIDENT: [f32; 3] = [1.0, std::f32::consts::FRAC_1_SQRT_2, 0.2];
const ROUGHNESS: [f32; 4] = [0.02, 0.1, 0.5, 1.0];

/// (name, parameters, α) of the separable cases: specular only, and over a diffuse base.
fn separable_cases() -> Vec<(String, String, f32)> {
    let mut cases = Vec::new();
    for a in ROUGHNESS {
        cases.push((
            format!("separable a={a}"),
            format!("\"roughness\": {a}, \"specular\": 0.9, \"masking\": \"separable\""),
            a,
        ));
        cases.push((
            format!("separable a={a} +base"),
            format!("\"roughness\": {a}, \"diffuse\": 0.5, \"masking\": \"separable\""),
            a,
        ));
    }
    cases
}

#[test]
fn separable_masking_sampling_passes_chi_square() {
    let mut cases = Vec::new();
    for cos in INCIDENT {
        let wo = incident(cos);
        for (name, params, alpha) in separable_cases() {
            let mut test = Chi2Test {
                seed: test_seed(),
                ..Chi2Test::default()
            };
            if alpha < 0.3 {
                // Resolve the sharp lobe with bins over a cap about the mirror direction.
                test.axis = Vec3::new(-wo.x, -wo.y, wo.z);
                test.cos_cap = (12.0 * alpha as f64).min(std::f64::consts::PI).cos();
            }
            cases.push((format!("{name} cos={cos}"), bsdf(&params), wo, test));
        }
    }
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
    for (name, b, wo, test) in &cases {
        test_bsdf(b.as_ref(), &FRONT, *wo, test).assert_passes(alpha, name);
    }
}

#[test]
fn separable_masking_weight_equals_eval_over_pdf() {
    for (name, params, _) in separable_cases() {
        let b = bsdf(&params);
        for cos in INCIDENT {
            let wo = incident(cos);
            let mut s = Sampler::new(test_seed(), 2, 3);
            let mut accepted = 0;
            for _ in 0..20_000 {
                let (ul, u) = (s.next_1d(), s.next_2d());
                let Some(smp) = b.sample(&FRONT, wo, ul, u) else {
                    continue;
                };
                accepted += 1;
                let pdf = b.pdf(&FRONT, wo, smp.wi);
                let expected = b.eval(&FRONT, wo, smp.wi) / pdf;
                assert!(((pdf - smp.pdf) / pdf).abs() < 1e-4, "{name}: pdf");
                let err = (smp.weight - expected).abs().max_element();
                assert!(
                    err <= 1e-4 * expected.max_element().max(1e-6),
                    "{name} cos={cos}: weight {:?} vs eval/pdf {expected:?}",
                    smp.weight
                );
            }
            // A guard that the check above was exercised, not a rate: at α = 1 about half the
            // reflected directions fall below the horizon (9889–9928 of 20000 accepted at normal
            // incidence over seeds 1–4, so the former bound of 10000 failed them).
            assert!(
                accepted >= 5_000,
                "{name} cos={cos}: only {accepted} samples"
            );
        }
    }
}

/// Smith's Λ for GGX in f64, from the formula (not from the plugin).
fn lambda(alpha: f64, w: Vec3) -> f64 {
    let (x, y, z) = (w.x as f64, w.y as f64, w.z as f64);
    let tan2 = (x * x + y * y) / (z * z);
    ((1.0 + alpha * alpha * tan2).sqrt() - 1.0) / 2.0
}

/// With no diffuse base, eval is F D G₂ / (4 cos θo): the ratio of the two forms is
/// (1 + Λo + Λi) / ((1 + Λo)(1 + Λi)), 1 at normal incidence and falling toward grazing angles.
#[test]
fn separable_differs_from_height_correlated_by_the_formula_factor() {
    let mut s = Sampler::new(test_seed(), 5, 5);
    for alpha in [0.05f32, 0.3, 0.8] {
        let hc = bsdf(&format!("\"roughness\": {alpha}, \"specular\": 1"));
        let sep = bsdf(&format!(
            "\"roughness\": {alpha}, \"specular\": 1, \"masking\": \"separable\""
        ));
        let mut smallest = 1.0f64;
        for _ in 0..5000 {
            let wo = uniform_hemisphere(s.next_2d());
            let wi = uniform_hemisphere(s.next_2d());
            let (a, b) = (
                hc.eval(&FRONT, wo, wi).x as f64,
                sep.eval(&FRONT, wo, wi).x as f64,
            );
            if a < 1e-6 {
                continue;
            }
            let (lo, li) = (lambda(alpha as f64, wo), lambda(alpha as f64, wi));
            let factor = (1.0 + lo + li) / ((1.0 + lo) * (1.0 + li));
            assert!(
                (b / a - factor).abs() <= 1e-4 * factor,
                "α={alpha} wo={wo} wi={wi}: ratio {} vs {factor}",
                b / a
            );
            smallest = smallest.min(factor);
        }
        // The directions drawn reach angles where the difference is substantial.
        assert!(smallest < 0.9, "α={alpha}: smallest factor {smallest}");
        // At normal incidence and reflection the two agree to rounding.
        let (a, b) = (
            hc.eval(&FRONT, Vec3::Z, Vec3::Z),
            sep.eval(&FRONT, Vec3::Z, Vec3::Z),
        );
        assert!((a - b).abs().max_element() <= 1e-6 * a.max_element());
    }
}

/// The separable term never exceeds the height-correlated one, so with the same random numbers
/// (the sampling does not depend on the masking) every weight is at most the other's, and the
/// lossless-Fresnel albedo stays at most 1.
#[test]
fn separable_masking_loses_energy_never_gains_it() {
    for alpha in [0.1f32, 0.5, 1.0] {
        let hc = bsdf(&format!("\"roughness\": {alpha}, \"specular\": 1"));
        let sep = bsdf(&format!(
            "\"roughness\": {alpha}, \"specular\": 1, \"masking\": \"separable\""
        ));
        for cos in [1.0, 0.5, 0.1] {
            let wo = incident(cos);
            let mut s = Sampler::new(test_seed(), 7, 7);
            let n = 50_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let (ul, u) = (s.next_1d(), s.next_2d());
                let w_sep = sep.sample(&FRONT, wo, ul, u).map_or(0.0, |x| x.weight.x);
                let w_hc = hc.sample(&FRONT, wo, ul, u).map_or(0.0, |x| x.weight.x);
                assert!(w_sep <= w_hc * (1.0 + 1e-5), "α={alpha} cos={cos}");
                sum += w_sep as f64;
                sum2 += (w_sep as f64).powi(2);
            }
            let mean = sum / n as f64;
            let se = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            assert!(mean <= 1.0 + 4.0 * se, "α={alpha} cos={cos}: {mean} ± {se}");
        }
    }
}

fn uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x.max(1e-3);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

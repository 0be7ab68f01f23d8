//! The shared microfacet module (`lumis_bsdfs::microfacet`), GGX and Beckmann, tested on its
//! own: D and Λ against closed forms written here from Walter et al. 2007 (in f64, Beckmann's
//! Λ with statrs' erf), the integrals every microfacet model satisfies (∫ D cos θh dωh = 1 and
//! ∫ G1(ωo) max(0, ωo·h) D(h) dωh = cos θo, Heitz 2014 eq. 14) by the quadrature of
//! `evaluation.rs`, the sampling of visible normals by chi-square against its density, the
//! Beckmann slope inversion against its CDF, erf and erfinv against statrs, and lanes against
//! one lane bit for bit.

use crate::evaluation::{Quadrature, composite, lobe_coordinates, visible_normals};
use glam::{DVec3, Vec3, Vec4};
use lumis_bsdfs::microfacet::{
    Beckmann, Distribution, Ggx, Masking, Microfacet, erf, erfinv, reflect,
};
use lumis_core::chi2::{Chi2Test, FAMILY_FALSE_ALARM, run_side_by_side, sidak, test_sampler};
use lumis_core::math::lanes::{Lanes, V3};
use statrs::function::erf as reference;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

const EPS: f64 = f32::EPSILON as f64;

/// Roughness values of the closed-form and integral checks.
const ALPHAS: [f32; 7] = [1e-3, 1e-2, 0.05, 0.2, 0.5, 1.0, 2.0];

/// cos θ of the chosen directions, down to grazing.
const COS: [f64; 8] = [1.0, 0.9, 0.7, 0.4, 0.2, 0.05, 0.01, 1e-3];

/// The unit vector at cos θ, azimuth 30°.
fn direction(cos: f64) -> DVec3 {
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 30f64.to_radians();
    DVec3::new(sin * phi.cos(), sin * phi.sin(), cos)
}

/// One lane's value of a microfacet function.
fn one<D: Distribution>(alpha: f32) -> Microfacet<D, f32> {
    Microfacet::new(alpha)
}

fn v3(w: DVec3) -> V3<f32> {
    V3::splat(w.as_vec3())
}

/// tan²θ of a direction.
fn tan2(w: DVec3) -> f64 {
    (w.x * w.x + w.y * w.y) / (w.z * w.z)
}

/// Walter et al. 2007, eq. 33: GGX's D.
fn ggx_d(alpha: f64, h: DVec3) -> f64 {
    let cos2 = h.z * h.z;
    let a2 = alpha * alpha;
    a2 / (PI * cos2 * cos2 * (a2 + tan2(h)).powi(2))
}

/// Walter et al. 2007, from eq. 34: GGX's Λ = (√(1 + α² tan²θ) − 1) / 2.
fn ggx_lambda(alpha: f64, w: DVec3) -> f64 {
    ((1.0 + alpha * alpha * tan2(w)).sqrt() - 1.0) / 2.0
}

/// Walter et al. 2007, eq. 25: Beckmann's D = exp(−tan²θ/α²) / (π α² cos⁴θ).
fn beckmann_d(alpha: f64, h: DVec3) -> f64 {
    let cos2 = h.z * h.z;
    (-tan2(h) / (alpha * alpha)).exp() / (PI * alpha * alpha * cos2 * cos2)
}

/// Beckmann's Λ with a = 1/(α tan θ): (erf(a) − 1)/2 + exp(−a²)/(2a√π), written with erfc.
fn beckmann_lambda(alpha: f64, w: DVec3) -> f64 {
    let a = 1.0 / (alpha * tan2(w).sqrt());
    ((-a * a).exp() / (a * PI.sqrt()) - reference::erfc(a)) / 2.0
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

/// D and Λ of both distributions agree with the closed forms at chosen normals and directions,
/// to the f32 rounding of their operations (and, for Beckmann's Λ, the erfc fit's 1.2·10⁻⁷ of
/// the two terms that cancel in it).
#[test]
fn d_and_lambda_match_the_closed_forms() {
    let mut compared = 0;
    for alpha in ALPHAS {
        let a = alpha as f64;
        for cos in COS {
            let w = direction(cos);
            // Exactly the f32 vector the module is given.
            let w = w.as_vec3().as_dvec3();
            let (ggx, beckmann) = (one::<Ggx>(alpha), one::<Beckmann>(alpha));
            // D: the f32 formula's operations, and exp's argument's rounding (Beckmann).
            let expected = ggx_d(a, w);
            if expected > 1e-30 && expected < 1e30 {
                let got = ggx.d(v3(w)) as f64;
                assert!(
                    relative(got, expected) <= 32.0 * EPS,
                    "GGX α={alpha} cos={cos}: D {got} vs {expected}"
                );
                compared += 1;
            }
            let expected = beckmann_d(a, w);
            if expected > 1e-30 && expected < 1e30 {
                let got = beckmann.d(v3(w)) as f64;
                let exponent = tan2(w) / (a * a);
                assert!(
                    relative(got, expected) <= (32.0 + 4.0 * exponent) * EPS,
                    "Beckmann α={alpha} cos={cos}: D {got} vs {expected}"
                );
                compared += 1;
            }
            if cos == 1.0 {
                assert_eq!(ggx.lambda(v3(w)), 0.0);
                assert_eq!(beckmann.lambda(v3(w)), 0.0);
                continue;
            }
            let expected = ggx_lambda(a, w);
            let got = ggx.lambda(v3(w)) as f64;
            assert!(
                (got - expected).abs() <= 16.0 * EPS * (expected + 1.0),
                "GGX α={alpha} cos={cos}: Λ {got} vs {expected}"
            );
            let expected = beckmann_lambda(a, w);
            let got = beckmann.lambda(v3(w)) as f64;
            let big = 1.0 / (alpha as f64 * tan2(w).sqrt());
            let terms = (-big * big).exp() / (big * PI.sqrt()) + reference::erfc(big);
            // f32 underflows below its smallest normal number (G1 is then exactly 1).
            let tolerance = terms * (1.2e-7 + 16.0 * EPS * (1.0 + big * big))
                + 16.0 * EPS * expected
                + f32::MIN_POSITIVE as f64;
            assert!(
                (got - expected).abs() <= tolerance,
                "Beckmann α={alpha} cos={cos}: Λ {got} vs {expected} (tolerance {tolerance:.1e})"
            );
            compared += 2;
        }
    }
    assert!(compared > 150, "only {compared} comparisons");
    // At grazing incidence Λ is infinite and G1 zero; below the surface D is zero.
    let grazing = V3::splat(Vec3::X);
    assert_eq!(one::<Ggx>(0.3).lambda(grazing), f32::INFINITY);
    assert_eq!(one::<Beckmann>(0.3).lambda(grazing), f32::INFINITY);
    assert_eq!(one::<Beckmann>(0.3).g1(grazing), 0.0);
    let below = V3::splat(Vec3::new(0.3, 0.0, -0.9).normalize());
    assert_eq!(one::<Ggx>(0.3).d(below), 0.0);
    assert_eq!(one::<Beckmann>(0.3).d(below), 0.0);
}

/// The two masking forms from Λ: 1/(1 + Λo + Λi) and 1/((1 + Λo)(1 + Λi)).
#[test]
fn masking_forms_are_their_formulas() {
    for (lo, li) in [
        (0.0f32, 0.0f32),
        (0.5, 0.25),
        (3.0, 0.0),
        (f32::INFINITY, 1.0),
    ] {
        let (l, i) = (lo as f64, li as f64);
        let hc = Masking::HeightCorrelated.g2(lo, li) as f64;
        let sep = Masking::Separable.g2(lo, li) as f64;
        assert!(
            (hc - 1.0 / (1.0 + l + i)).abs() <= 4.0 * EPS,
            "{lo} {li}: {hc}"
        );
        assert!(
            (sep - 1.0 / ((1.0 + l) * (1.0 + i))).abs() <= 4.0 * EPS,
            "{lo} {li}: {sep}"
        );
        assert!(sep <= hc);
    }
}

/// erf and erfinv within their accuracy of statrs' (erf as 1 − erfc: about 2·10⁻⁷ absolute).
#[test]
fn erf_and_erfinv_match_the_reference() {
    for k in -400..=400 {
        let x = k as f64 / 80.0;
        let got = erf(x as f32) as f64;
        let expected = reference::erf((x as f32) as f64);
        assert!(
            (got - expected).abs() <= 4e-7,
            "erf({x}) = {got}, reference {expected}"
        );
    }
    for k in -999..=999 {
        let y = k as f64 / 1000.0;
        let y32 = y as f32;
        let got = erfinv(y32) as f64;
        let expected = reference::erf_inv(y32 as f64);
        assert!(
            (got - expected).abs() <= 4e-7 * expected.abs().max(1e-3) + 1e-9,
            "erfinv({y}) = {got}, reference {expected}"
        );
    }
    // Far in the tails: 1 − 2⁻²⁴ and its negative.
    let tail = 1.0 - f32::EPSILON / 2.0;
    let expected = reference::erf_inv(tail as f64);
    assert!(relative(erfinv(tail) as f64, expected) < 1e-5);
    assert_eq!(erfinv(1.0), f32::INFINITY);
    assert_eq!(erfinv(-1.0), f32::NEG_INFINITY);
    assert_eq!(erf(f32::INFINITY), 1.0);
    assert_eq!(erf(0.0), 0.0);
}

/// ∫ D(h) cos θh dωh = 1 for both distributions at every roughness, by quadrature in the
/// coordinates that spread a lobe of width α over [0, π/2) (`lobe_coordinates`).
#[test]
fn both_distributions_are_normalised() {
    fn check<D: Distribution>(alpha: f32) {
        let m = one::<D>(alpha);
        let a = alpha as f64;
        let area = |panels: usize| {
            let mut sum = 0.0;
            let phi_rule = composite(0.0, TAU, 4);
            for (psi, w_psi) in composite(0.0, FRAC_PI_2, panels) {
                for &(phi, w_phi) in &phi_rule {
                    let (h, jacobian) = lobe_coordinates(a, psi, phi);
                    sum += w_psi * w_phi * jacobian * m.d(v3(h)) as f64 * h.z;
                }
            }
            sum
        };
        let q = Quadrature::refined(area, 16);
        assert!(
            (q.value - 1.0).abs() <= 4.0 * q.error + 128.0 * EPS,
            "{} α={alpha}: ∫ D cos θh dωh = {} ± {:.1e}",
            D::NAME,
            q.value,
            q.error
        );
    }
    for alpha in ALPHAS {
        check::<Ggx>(alpha);
        check::<Beckmann>(alpha);
    }
}

/// ∫ G1(ωo) max(0, ωo·h) D(h) dωh = cos θo: Λ belongs to D (Heitz 2014, eq. 14), for both
/// distributions, every roughness and incidence down to grazing.
#[test]
fn visible_normals_of_both_distributions_are_normalised() {
    fn check<D: Distribution>(alpha: f32, cos: f64) {
        let m = one::<D>(alpha);
        let wo = direction(cos).as_vec3().as_dvec3();
        let g1 = m.g1(v3(wo)) as f64;
        let integral = |panels: usize| {
            let mut sum = 0.0;
            visible_normals(alpha as f64, wo, panels, |h, dh| {
                sum += g1 * wo.dot(h).max(0.0) * m.d(v3(h)) as f64 * dh;
            });
            sum
        };
        let q = Quadrature::refined(integral, 16);
        assert!(
            (q.value - wo.z).abs() <= 4.0 * q.error + 256.0 * EPS * wo.z,
            "{} α={alpha} cos={cos}: ∫ G1 (ωo·h)⁺ D = {} ± {:.1e}, expected {}",
            D::NAME,
            q.value,
            q.error,
            wo.z
        );
    }
    for alpha in ALPHAS {
        for cos in [1.0, 0.7, 0.2, 0.05, 1e-2] {
            check::<Ggx>(alpha, cos);
            check::<Beckmann>(alpha, cos);
        }
    }
}

/// The visible normals drawn by each distribution follow `visible_normal_pdf` (chi-square, one
/// family over both distributions, three roughnesses and three incidences).
#[test]
fn visible_normal_sampling_matches_its_density() {
    #[derive(Clone, Copy)]
    enum Which {
        Ggx,
        Beckmann,
    }
    fn run<D: Distribution>(
        alpha: f32,
        wo: Vec3,
        test: &Chi2Test,
    ) -> lumis_core::chi2::Chi2Outcome {
        let m = one::<D>(alpha);
        let wo3 = V3::splat(wo);
        test.run(
            |s| {
                let u = s.next_2d();
                let h = m.sample_visible_normal(wo3, (u.x, u.y)).lane(0);
                (h.is_finite() && wo.dot(h) > 0.0).then_some(h)
            },
            |h| m.visible_normal_pdf(wo3, V3::splat(h)) as f64,
        )
    }
    let mut cases = Vec::new();
    for which in [Which::Ggx, Which::Beckmann] {
        for alpha in [0.05f32, 0.3, 1.0] {
            for cos in [1.0, 0.5, 0.05] {
                let mut test = Chi2Test {
                    samples: 300_000,
                    ..Chi2Test::default()
                };
                if alpha < 0.3 {
                    test.cos_cap = (12.0 * alpha as f64).cos();
                }
                cases.push((which, alpha, direction(cos).as_vec3().normalize(), test));
            }
        }
    }
    let level = sidak(FAMILY_FALSE_ALARM, cases.len());
    let outcomes = run_side_by_side(&cases, |(which, alpha, wo, test)| match which {
        Which::Ggx => run::<Ggx>(*alpha, *wo, test),
        Which::Beckmann => run::<Beckmann>(*alpha, *wo, test),
    });
    for ((which, alpha, wo, _), outcome) in cases.iter().zip(outcomes) {
        let name = match which {
            Which::Ggx => "ggx",
            Which::Beckmann => "beckmann",
        };
        outcome.assert_passes(
            level,
            &format!("{name} visible normals α={alpha} cos={}", wo.z),
        );
    }
}

/// The Beckmann slope inversion lands where the visible slope's CDF is the random number: the
/// sampled normal's slope x̃ (at α = 1, ωo at azimuth 0, u₁ = ½ so that ỹ = 0) has
/// F(x̃) = u₀ with F(x) ∝ cot θ (√π/2)(1 + erf x) + exp(−x²)/2, to f32 rounding, from normal
/// to grazing incidence; and ỹ's CDF (1 + erf ỹ)/2 is u₁.
#[test]
fn beckmann_slope_inversion_lands_on_its_cdf() {
    let m = one::<Beckmann>(1.0);
    let cdf = |cot: f64, x: f64| {
        let unnormalised = |x: f64| {
            if cot.is_infinite() {
                (1.0 + reference::erf(x)) / 2.0
            } else {
                cot * PI.sqrt() / 2.0 * (1.0 + reference::erf(x)) + (-x * x).exp() / 2.0
            }
        };
        unnormalised(x) / unnormalised(cot)
    };
    let mut worst = 0.0f64;
    for cos in [1.0, 0.99, 0.8, 0.5, 0.2, 0.05, 1e-2, 1e-3] {
        let sin = (1.0f64 - cos * cos).sqrt();
        let wo = Vec3::new(sin as f32, 0.0, cos as f32);
        let cot = (wo.z as f64) / (wo.x as f64);
        for k in 0..=200 {
            let u0 = ((k as f32) / 200.0).clamp(1e-6, 1.0 - 1e-6);
            let h = m.sample_visible_normal(V3::splat(wo), (u0, 0.5)).lane(0);
            assert!(h.is_finite() && h.z > 0.0, "cos={cos} u0={u0}: {h}");
            let slope = -(h.x as f64) / (h.z as f64);
            let error = (cdf(cot, slope) - u0 as f64).abs();
            worst = worst.max(error);
            assert!(
                error <= 2e-5,
                "cos={cos} u0={u0}: F(x̃ = {slope}) − u₀ = {error:.2e}"
            );
        }
        for k in 1..200 {
            let u1 = k as f32 / 200.0;
            let h = m.sample_visible_normal(V3::splat(wo), (0.5, u1)).lane(0);
            let slope = -(h.y as f64) / (h.z as f64);
            let error = ((1.0 + reference::erf(slope)) / 2.0 - u1 as f64).abs();
            assert!(
                error <= 2e-6,
                "cos={cos} u1={u1}: Φ(ỹ = {slope}) − u₁ = {error:.2e}"
            );
        }
    }
    eprintln!("largest |F(x̃) − u₀|: {worst:.2e}");
}

/// Sampling gives finite unit normals above the surface for the extreme random numbers and
/// incidences, and reflected directions on the viewer's side of the normal.
#[test]
fn extreme_numbers_give_finite_normals() {
    fn check<D: Distribution>() {
        for alpha in [1e-4f32, 0.1, 1.0, 3.0] {
            let m = one::<D>(alpha);
            for cos in [1.0f32, 0.5, 1e-3, 1e-7] {
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos).normalize();
                for u0 in [0.0f32, 1e-7, 0.5, 1.0 - f32::EPSILON / 2.0] {
                    for u1 in [0.0f32, 0.5, 1.0 - f32::EPSILON / 2.0] {
                        let h = m.sample_visible_normal(V3::splat(wo), (u0, u1)).lane(0);
                        assert!(
                            h.is_finite() && h.z >= 0.0 && (h.length() - 1.0).abs() < 1e-5,
                            "{} α={alpha} cos={cos} u=({u0}, {u1}): {h}",
                            D::NAME
                        );
                        let wi = reflect::<f32>(V3::splat(wo), V3::splat(h)).lane(0);
                        assert!(wi.is_finite());
                        let pdf = m.visible_normal_pdf(V3::splat(wo), V3::splat(h));
                        assert!(pdf.is_finite() && pdf >= 0.0);
                    }
                }
            }
        }
    }
    check::<Ggx>();
    check::<Beckmann>();
}

/// Four lanes give what one lane gives, bit for bit (Beckmann's exp and log are taken lane by
/// lane, so they must not differ either).
#[test]
fn four_lanes_give_what_one_gives_bit_for_bit() {
    fn check<D: Distribution>() {
        let mut s = test_sampler(91);
        for _ in 0..2_000 {
            let alphas: [f32; 4] = std::array::from_fn(|_| 1e-3 + 1.5 * s.next_1d());
            let dirs: [Vec3; 4] = std::array::from_fn(|_| {
                let u = s.next_2d();
                lumis_core::math::warp::square_to_cosine_hemisphere(u)
            });
            let normals: [Vec3; 4] = std::array::from_fn(|_| {
                let u = s.next_2d();
                lumis_core::math::warp::square_to_cosine_hemisphere(u)
            });
            let us: [(f32, f32); 4] = std::array::from_fn(|_| {
                let u = s.next_2d();
                (u.x, u.y)
            });
            let four = Microfacet::<D, Vec4>::new(Vec4::from_array(alphas));
            let wo4 = V3::<Vec4>::from_fn(|i| dirs[i]);
            let h4 = V3::<Vec4>::from_fn(|i| normals[i]);
            let u4 = (Vec4::from_fn(|i| us[i].0), Vec4::from_fn(|i| us[i].1));
            let (d4, l4, p4) = (
                four.d(h4),
                four.lambda(wo4),
                four.visible_normal_pdf(wo4, h4),
            );
            let s4 = four.sample_visible_normal(wo4, u4);
            for i in 0..4 {
                let m = one::<D>(alphas[i]);
                let (wo, h) = (V3::splat(dirs[i]), V3::splat(normals[i]));
                assert_eq!(d4.lane(i).to_bits(), m.d(h).to_bits());
                assert_eq!(l4.lane(i).to_bits(), m.lambda(wo).to_bits());
                assert_eq!(p4.lane(i).to_bits(), m.visible_normal_pdf(wo, h).to_bits());
                let single = m.sample_visible_normal(wo, us[i]).lane(0);
                assert_eq!(
                    s4.lane(i).to_array().map(f32::to_bits),
                    single.to_array().map(f32::to_bits),
                    "{} lane {i}",
                    D::NAME
                );
            }
        }
    }
    check::<Ggx>();
    check::<Beckmann>();
}

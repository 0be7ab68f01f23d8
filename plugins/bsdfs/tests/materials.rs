//! Independent checks of the conductors, plastics and `twosided` (their statistical tests are in
//! `bsdfs.rs`'s plan): the Fresnel terms against closed forms written here (Snell and the
//! Fresnel equations in f64, with complex arithmetic for conductors), the rough BSDFs' `eval`
//! against F D G1 G1 / (4 cos θo) from those forms and the microfacet ones of `microfacet.rs`'s
//! tests, the rough coating's tables against their smooth limit and an independent quadrature,
//! the named conductors, and the sides of `twosided`.

use crate::bsdfs::nested;
use glam::{DVec3, Vec2, Vec3};
use lumis_bsdfs::fresnel;
use lumis_bsdfs::microfacet::{Beckmann, Ggx};
use lumis_bsdfs::roughplastic::CoatingTables;
use lumis_core::bsdf::{Bsdf, BsdfContext, Side};
use lumis_core::math::lanes::V3;
use lumis_core::params::Params;
use lumis_core::registry::{self, BsdfPlugin};
use std::f64::consts::PI;
use std::sync::Arc;

const EPS: f64 = f32::EPSILON as f64;
const FRONT: BsdfContext = BsdfContext::FRONT;

fn bsdf(kind: &str, params: &str) -> Result<Arc<dyn Bsdf>, String> {
    lumis_bsdfs::link();
    let plugin = registry::find::<BsdfPlugin>(kind).unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new(format!("bsdf `t` ({kind})"), plugin.params, values).unwrap();
    let b = (plugin.create)(&mut p).map_err(|e| e.to_string())?;
    p.finish().map_err(|e| e.to_string())?;
    Ok(b)
}

/// A complex number, for the conductor's Fresnel equations.
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn norm2(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
    /// The principal square root.
    fn sqrt(self) -> C {
        let r = self.norm2().sqrt();
        let re = ((r + self.0) / 2.0).max(0.0).sqrt();
        let im = ((r - self.0) / 2.0).max(0.0).sqrt().copysign(self.1);
        C(re, im)
    }
}

/// The Fresnel equations for a complex index n = η + i k relative to the outside, light from
/// outside at cos θi: r_s = (cos θi − n cos θt)/(cos θi + n cos θt), r_p = (n cos θi − cos
/// θt)/(n cos θi + cos θt), n cos θt = √(n² − sin²θi); R = (|r_s|² + |r_p|²)/2.
fn fresnel_reference(cos: f64, eta: f64, k: f64) -> f64 {
    let n = C(eta, k);
    let sin2 = 1.0 - cos * cos;
    let n_cos_t = n.mul(n).sub(C(sin2, 0.0)).sqrt();
    let cos_t = n_cos_t.div(n);
    let c = C(cos, 0.0);
    let rs = c.sub(n_cos_t).div(c.add(n_cos_t));
    let rp = n.mul(c).sub(cos_t).div(n.mul(c).add(cos_t));
    (rs.norm2() + rp.norm2()) / 2.0
}

const COSINES: [f64; 8] = [1.0, 0.95, 0.8, 0.5, 0.3, 0.1, 0.02, 1e-3];

/// The dielectric reflectance from both sides (total internal reflection included) and the
/// refracted cosine, against the Fresnel equations with real n.
#[test]
fn dielectric_fresnel_matches_the_fresnel_equations() {
    for eta in [1.0f32, 1.000_277, 1.33, 1.49, 2.419, 1.0 / 1.5] {
        for cos in COSINES {
            for side in [1.0f64, -1.0] {
                let cos_i = (cos * side) as f32;
                let (f, cos_t, eta_it, eta_ti) = fresnel::dielectric(cos_i, eta);
                // From inside, light sees the index 1/η.
                let n = if side > 0.0 {
                    eta as f64
                } else {
                    1.0 / eta as f64
                };
                let sin_t2 = (1.0 - cos * cos) / (n * n);
                let expected = if sin_t2 >= 1.0 {
                    1.0
                } else {
                    fresnel_reference(cos, n, 0.0)
                };
                assert!(
                    (f as f64 - expected).abs() <= 1e-5 + 64.0 * EPS * expected,
                    "η={eta} cos={cos_i}: F {f} vs {expected}"
                );
                let expected_t = if sin_t2 >= 1.0 {
                    0.0
                } else {
                    -(1.0 - sin_t2).sqrt() * side
                };
                assert!(
                    (cos_t as f64 - expected_t).abs() <= 1e-5,
                    "η={eta} cos={cos_i}: cos θt {cos_t} vs {expected_t}"
                );
                assert!(((eta_it * eta_ti) as f64 - 1.0).abs() <= 4.0 * EPS);
                assert!((eta_it as f64 - n).abs() <= 4.0 * EPS * n);
            }
        }
    }
    // Matched indices reflect nothing.
    assert_eq!(fresnel::dielectric(0.3f32, 1.0).0, 0.0);
}

/// The conductor reflectance against the complex Fresnel equations, and at normal incidence
/// against ((η − 1)² + k²) / ((η + 1)² + k²), for the named metals and chosen indices.
#[test]
fn conductor_fresnel_matches_the_complex_fresnel_equations() {
    let mut pairs: Vec<(f32, f32)> = vec![(0.0, 1.0), (1.5, 0.0), (0.2, 3.9), (4.0, 4.0)];
    for name in ["Cu", "Au", "Ag", "Al", "Cr"] {
        let (eta, k) = fresnel::named_conductor(name).unwrap();
        pairs.extend((0..3).map(|c| (eta[c], k[c])));
    }
    for (eta, k) in pairs {
        for cos in COSINES {
            let f = fresnel::conductor::<f32>(
                cos as f32,
                V3::splat(Vec3::splat(eta)),
                V3::splat(Vec3::splat(k)),
            )
            .lane(0)
            .x as f64;
            let expected = fresnel_reference(cos, eta as f64, k as f64);
            assert!(
                (f - expected).abs() <= 2e-5,
                "η={eta} k={k} cos={cos}: F {f} vs {expected}"
            );
        }
        let (e, kk) = (eta as f64, k as f64);
        let normal = ((e - 1.0).powi(2) + kk * kk) / ((e + 1.0).powi(2) + kk * kk);
        let f =
            fresnel::conductor::<f32>(1.0, V3::splat(Vec3::splat(eta)), V3::splat(Vec3::splat(k)))
                .lane(0)
                .x as f64;
        assert!(
            (f - normal).abs() <= 1e-5,
            "η={eta} k={k}: F(1) {f} vs {normal}"
        );
    }
    // η = k = 0 (some channels of Mitsuba's table): 1, the limit, not 0/0.
    let f = fresnel::conductor::<f32>(1.0, V3::splat(Vec3::ZERO), V3::splat(Vec3::ZERO)).lane(0);
    assert_eq!(f, Vec3::ONE);
}

/// The named conductors: a smooth one reflects F(cos θo) of its table's (η, k) per channel;
/// `material` with `eta` is refused, an unknown name lists the known ones, and Mitsuba 3's
/// default `none` is a perfect mirror.
#[test]
fn named_conductors_reflect_their_fresnel_and_bad_names_are_refused() {
    let gold = bsdf("conductor", "\"material\": \"Au\"").unwrap();
    let (eta, k) = fresnel::named_conductor("Au").unwrap();
    for cos in [1.0f64, 0.6, 0.1] {
        let wo = Vec3::new((1.0 - cos * cos).sqrt() as f32, 0.0, cos as f32);
        let s = gold
            .sample(&FRONT, wo, 0.5, Vec2::splat(0.5))
            .expect("a sample");
        assert!(s.delta && s.wi == Vec3::new(-wo.x, -wo.y, wo.z));
        for c in 0..3 {
            let expected = fresnel_reference(wo.z as f64, eta[c] as f64, k[c] as f64);
            assert!((s.weight[c] as f64 - expected).abs() <= 2e-5, "channel {c}");
        }
    }
    let mirror = bsdf("conductor", "").unwrap();
    let s = mirror.sample(&FRONT, Vec3::Z, 0.5, Vec2::ZERO).unwrap();
    assert_eq!(s.weight, Vec3::ONE);
    let e = bsdf("conductor", "\"material\": \"Au\", \"eta\": 1")
        .err()
        .unwrap();
    assert!(e.contains("not both") && e.contains("bsdf `t`"), "{e}");
    let e = bsdf("roughconductor", "\"material\": \"Gold\"")
        .err()
        .unwrap();
    assert!(
        e.contains("unknown conductor `Gold`") && e.contains("Au"),
        "{e}"
    );
    for bad in [
        "\"k\": -1",
        "\"eta\": (1, NaN, 1)",
        "\"alpha\": 1e9",
        "\"alpha\": -0.1",
    ] {
        let e = bsdf("roughconductor", bad)
            .err()
            .unwrap_or_else(|| panic!("{bad} accepted"));
        assert!(e.contains("roughconductor"), "{bad}: {e}");
    }
    for bad in ["\"int_ior\": 0", "\"int_ior\": -1.5", "\"ext_ior\": NaN"] {
        assert!(bsdf("plastic", bad).is_err(), "{bad} accepted");
    }
    let e = bsdf("roughplastic", "\"int_ior\": 1.2, \"ext_ior\": 1.2")
        .err()
        .unwrap();
    assert!(e.contains("must differ"), "{e}");
    // α = 0 is used as 10⁻⁴ (Mitsuba's clamp): finite values, the same as α = 10⁻⁴.
    let zero = bsdf("roughconductor", "\"alpha\": 0").unwrap();
    let tiny = bsdf("roughconductor", "\"alpha\": 0.0001").unwrap();
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let wi = Vec3::new(-0.6, 1e-4, 0.8).normalize();
    assert_eq!(zero.eval_pdf(&FRONT, wo, wi), tiny.eval_pdf(&FRONT, wo, wi));
}

/// f64 D and Λ of the two distributions (Walter et al. 2007), as in `microfacet.rs`.
fn d_lambda(beckmann: bool, alpha: f64, w: DVec3) -> (f64, f64) {
    let cos2 = w.z * w.z;
    let tan2 = (w.x * w.x + w.y * w.y) / cos2;
    let a2 = alpha * alpha;
    if beckmann {
        let d = (-tan2 / a2).exp() / (PI * a2 * cos2 * cos2);
        let a = 1.0 / (alpha * tan2.sqrt());
        let lambda = ((-a * a).exp() / (a * PI.sqrt()) - statrs::function::erf::erfc(a)) / 2.0;
        (d, if tan2 == 0.0 { 0.0 } else { lambda })
    } else {
        let d = a2 / (PI * cos2 * cos2 * (a2 + tan2).powi(2));
        (d, ((1.0 + a2 * tan2).sqrt() - 1.0) / 2.0)
    }
}

/// (ωo, ωi) pairs above the surface, in the plane of incidence and across it.
fn pairs() -> Vec<(Vec3, Vec3)> {
    let mut pairs = Vec::new();
    for &co in &[1.0f32, 0.7, 0.3, 0.05] {
        for &ci in &[0.9f32, 0.5, 0.2] {
            for phi in [0.0f32, 2.0, 3.1] {
                let wo = Vec3::new((1.0 - co * co).sqrt(), 0.0, co).normalize();
                let si = (1.0 - ci * ci).sqrt();
                let wi = Vec3::new(si * phi.cos(), si * phi.sin(), ci).normalize();
                pairs.push((wo, wi));
            }
        }
    }
    pairs
}

/// `roughconductor`'s eval is F(ωo·h) D(h) G1(ωo) G1(ωi) / (4 cos θo) and its pdf
/// G1(ωo) D(h) / (4 cos θo), from the closed forms, for both distributions.
#[test]
fn roughconductor_is_its_closed_form() {
    let (eta, k) = fresnel::named_conductor("Cu").unwrap();
    for (distribution, beckmann) in [("beckmann", true), ("ggx", false)] {
        for alpha in [0.05f64, 0.3, 1.0] {
            let b = bsdf(
                "roughconductor",
                &format!(
                    "\"distribution\": \"{distribution}\", \"alpha\": {alpha}, \"material\": \"Cu\""
                ),
            )
            .unwrap();
            for (wo, wi) in pairs() {
                let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
                let h = (o + i).normalize();
                let (d, _) = d_lambda(beckmann, alpha, h);
                let (_, lo) = d_lambda(beckmann, alpha, o);
                let (_, li) = d_lambda(beckmann, alpha, i);
                let g = 1.0 / ((1.0 + lo) * (1.0 + li));
                let (value, pdf) = b.eval_pdf(&FRONT, wo, wi);
                let expected_pdf = d / (1.0 + lo) / (4.0 * o.z);
                let tolerance = |x: f64| 1e-4 * x + 1e-30;
                assert!(
                    (pdf as f64 - expected_pdf).abs() <= tolerance(expected_pdf),
                    "{distribution} α={alpha} {wo} {wi}: pdf {pdf} vs {expected_pdf}"
                );
                for c in 0..3 {
                    let f = fresnel_reference(o.dot(h), eta[c] as f64, k[c] as f64);
                    let expected = f * d * g / (4.0 * o.z);
                    assert!(
                        (value[c] as f64 - expected).abs() <= tolerance(expected),
                        "{distribution} α={alpha} {wo} {wi} channel {c}: {} vs {expected}",
                        value[c]
                    );
                }
            }
        }
    }
}

/// `plastic`'s diffuse lobe is R / (1 − F_dr) (1/η²)(1 − F(cos θo))(1 − F(cos θi)) cos θi / π
/// and its density the lobe's probability times cos θi / π; the delta lobe is chosen with
/// F w / (F w + (1 − F)(1 − w)) and weighs F specular / probability.
#[test]
fn plastic_is_its_closed_form() {
    let eta = 1.49 / 1.000_277;
    let b = bsdf("plastic", "\"diffuse_reflectance\": (0.8, 0.4, 0.2)").unwrap();
    let fdr = fresnel::diffuse_reflectance(1.0 / eta as f32) as f64;
    let w = 1.0 / (1.0 + (0.8 + 0.4 + 0.2) / 3.0);
    for (wo, wi) in pairs() {
        let (fo, fi) = (
            fresnel_reference(wo.z as f64, eta, 0.0),
            fresnel_reference(wi.z as f64, eta, 0.0),
        );
        let (value, pdf) = b.eval_pdf(&FRONT, wo, wi);
        let probability = fo * w / (fo * w + (1.0 - fo) * (1.0 - w));
        let cosine = wi.z as f64 / PI;
        let expected_pdf = (1.0 - probability) * cosine;
        assert!((pdf as f64 - expected_pdf).abs() <= 1e-5 * expected_pdf);
        for (c, r) in [0.8, 0.4, 0.2].into_iter().enumerate() {
            let expected = r / (1.0 - fdr) / (eta * eta) * (1.0 - fo) * (1.0 - fi) * cosine;
            assert!(
                (value[c] as f64 - expected).abs() <= 1e-5 * expected,
                "{wo} {wi}: {} vs {expected}",
                value[c]
            );
        }
        // u_lobe just below the delta lobe's probability draws it.
        let u_lobe = (probability * 0.999) as f32;
        let s = b.sample(&FRONT, wo, u_lobe, Vec2::splat(0.3)).unwrap();
        assert!(s.delta && (s.pdf as f64 - probability).abs() <= 1e-5 * probability);
        assert!((s.weight.x as f64 - fo / probability).abs() <= 1e-4 * fo / probability);
    }
}

/// The rough coating's tables: near-smooth (α = 10⁻³), T(μ) is the smooth interface's
/// 1 − F(μ) and F_dr the exact 2 ∫ F(μ, 1/η) μ dμ (to the tables' quadrature, 64 cosines); at
/// α = 0.3, T(μ) agrees with an independent quadrature over microfacet normals in spherical
/// coordinates of ∫ D_ωi(m) G1(ωt, m) (1 − F(ωi·m)) dm.
#[test]
fn coating_tables_match_the_smooth_limit_and_a_quadrature() {
    let eta = 1.5f32;
    let smooth = CoatingTables::new::<Ggx>(1e-3, eta);
    for (i, &t) in smooth.transmittance.iter().enumerate().skip(2) {
        let mu = i as f64 / 63.0;
        let expected = 1.0 - fresnel_reference(mu, eta as f64, 0.0);
        assert!(
            (t as f64 - expected).abs() <= 2e-3,
            "μ={mu}: T {t} vs {expected}"
        );
    }
    // Mitsuba's F_dr is the mean over the 64 cosines of 2 μ R(μ) (not the integral, from which
    // that sum differs by 0.8 % at η = 1.5, R jumping to 1 at the critical angle).
    let reflectance = |mu: f64| {
        let sin_t2 = (1.0 - mu * mu) * (eta as f64) * (eta as f64);
        if sin_t2 >= 1.0 {
            1.0
        } else {
            fresnel_reference(mu, 1.0 / eta as f64, 0.0)
        }
    };
    let sum: f64 = (0..64)
        .map(|i| {
            let mu = (i as f64 / 63.0).max(1e-6);
            2.0 * mu * reflectance(mu) / 64.0
        })
        .sum();
    assert!(
        (smooth.internal_reflectance as f64 - sum).abs() <= 2e-3,
        "F_dr {} vs {sum}",
        smooth.internal_reflectance
    );
    // α = 0.3, Beckmann: the same integral in (θm, φm) over the normals visible from ωi.
    let alpha = 0.3f64;
    let rough = CoatingTables::new::<Beckmann>(alpha as f32, eta);
    for i in [8usize, 24, 40, 63] {
        let mu = i as f64 / 63.0;
        let wi = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let (nt, np) = (400, 200);
        let mut sum = 0.0;
        for a in 0..nt {
            let theta = (a as f64 + 0.5) / nt as f64 * (PI / 2.0);
            for b in 0..np {
                let phi = (b as f64 + 0.5) / np as f64 * 2.0 * PI;
                let m = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let cos = wi.dot(m);
                if cos <= 0.0 {
                    continue;
                }
                let (d, _) = d_lambda(true, alpha, m);
                let (_, li) = d_lambda(true, alpha, wi);
                // Refraction about m (η from outside).
                let n = eta as f64;
                let sin_t2 = (1.0 - cos * cos) / (n * n);
                if sin_t2 >= 1.0 {
                    continue;
                }
                let cos_t = (1.0 - sin_t2).sqrt();
                let wt = m * (cos / n - cos_t) - wi / n;
                if wt.z >= 0.0 || wt.dot(m) * wt.z <= 0.0 {
                    continue;
                }
                let (_, lt) = d_lambda(true, alpha, wt);
                let vndf = cos * d / (1.0 + li) / mu;
                let f = fresnel_reference(cos, n, 0.0);
                let area = theta.sin() * (PI / 2.0 / nt as f64) * (2.0 * PI / np as f64);
                sum += vndf * (1.0 - f) / (1.0 + lt) * area;
            }
        }
        let t = rough.transmittance[i] as f64;
        assert!((t - sum).abs() <= 2e-3, "μ={mu}: T {t} vs quadrature {sum}");
    }
}

/// `twosided` shades the front with `front` and the back with `back`, in single and batch
/// calls (a batch mixing both sides included); without `back`, `front` from both sides.
#[test]
fn twosided_chooses_by_side() {
    let one = nested("(type: \"twosided\", front: (type: \"diffuse\", reflectance: 0.25))");
    let behind = BsdfContext::new(Vec2::ZERO, Side::Back);
    let (wo, wi) = (Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.6, 0.0, 0.8));
    assert_eq!(one.eval(&behind, wo, wi), one.eval(&FRONT, wo, wi));
    assert!((one.eval(&behind, wo, wi).x as f64 - 0.25 * 0.8 / PI).abs() < 1e-6);

    let two = nested(
        "(type: \"twosided\", front: (type: \"diffuse\", reflectance: 0.25), back: (type: \"diffuse\", reflectance: 0.75))",
    );
    let back = BsdfContext::new(Vec2::ZERO, Side::Back);
    let (wo, wi) = (Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.6, 0.0, 0.8));
    let f = two.eval(&FRONT, wo, wi).x as f64;
    let b = two.eval(&back, wo, wi).x as f64;
    assert!((f - 0.25 * 0.8 / PI).abs() < 1e-6 && (b - 0.75 * 0.8 / PI).abs() < 1e-6);
    let ctx = [FRONT, back, back, FRONT];
    let mut out = [(Vec3::NAN, f32::NAN); 4];
    two.eval_pdf_batch(&ctx, &[wo], &[wi; 4], &mut out);
    for (c, (value, _)) in ctx.iter().zip(out) {
        assert_eq!(value, two.eval(c, wo, wi));
    }
    let mut samples = [None; 4];
    two.sample_batch(&ctx, &[wo], &[(0.5, Vec2::splat(0.4)); 4], &mut samples);
    for (c, s) in ctx.iter().zip(samples) {
        assert_eq!(s, two.sample(c, wo, 0.5, Vec2::splat(0.4)));
    }
}

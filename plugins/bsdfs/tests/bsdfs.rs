//! Statistical and numerical tests of every registered built-in BSDF: chi-square of `sample`
//! against `pdf`, sample weight = eval / pdf, white furnace (albedo ≤ 1, and 1 where lossless),
//! reciprocity, and finite values for hostile input. The BSDFs come from the registry; each has
//! an entry in [`plan`] with the configurations to test, and a BSDF registered without one fails
//! `every_registered_bsdf_has_a_test_plan`.
//!
//! Why one file of over 600 lines: one plan of configurations for every registered BSDF, checked by
//! every statistical test from the same table.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, Side};
use lumis_core::chi2::{
    Chi2Test, FAMILY_FALSE_ALARM, run_side_by_side, sidak, test_bsdf, test_seed, z_limit,
};
use lumis_core::math::lanes::{DEFAULT_WIDTH, limit_width, widest_width};
use lumis_core::params::Params;
use lumis_core::registry::{self, BsdfPlugin};
use lumis_core::sampler::Sampler;
use std::sync::Arc;

/// The analytic BRDF the test MERL file is generated from.
const MERL_SOURCE: &str = "\"roughness\": 0.25, \"specular\": (0.9, 0.6, 0.3), \"diffuse\": 0.3";

/// The MERL table generated from the glossy BRDF `MERL_SOURCE`, and the `measured` plugin reading
/// it: the file is written once per test process into a temporary directory that is removed as
/// soon as both have read it (both hold the table in memory), so no run leaves it behind.
fn merl() -> &'static (lumis_bsdfs::measured::MerlTable, Arc<dyn Bsdf>) {
    static MERL: std::sync::OnceLock<(lumis_bsdfs::measured::MerlTable, Arc<dyn Bsdf>)> =
        std::sync::OnceLock::new();
    MERL.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("glossy.binary");
        let source = bsdf("glossy", MERL_SOURCE);
        lumis_bsdfs::measured::write_merl(&path, |wi, wo| source.eval(&FRONT, wo, wi) / wi.z)
            .unwrap();
        let table = lumis_bsdfs::measured::MerlTable::read(&path).unwrap();
        let plugin = bsdf(
            "measured",
            &format!("\"file\": {:?}", path.to_str().unwrap()),
        );
        (table, plugin)
    })
}

fn measured() -> Arc<dyn Bsdf> {
    merl().1.clone()
}

fn bsdf(kind: &str, params: &str) -> Arc<dyn Bsdf> {
    lumis_bsdfs::link();
    let plugin = registry::find::<BsdfPlugin>(kind).unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new(kind, plugin.params, values).unwrap();
    let b = (plugin.create)(&mut p).unwrap();
    p.finish().unwrap();
    b
}

/// The context of a BSDF tested on its own: seen from the front, at uv (0, 0).
const FRONT: BsdfContext = BsdfContext::FRONT;

/// The `i`th of a few contexts: either side, at texture coordinates inside and outside [0, 1]².
fn context(i: usize) -> BsdfContext {
    let side = if i.is_multiple_of(2) {
        Side::Front
    } else {
        Side::Back
    };
    let uv = [Vec2::ZERO, Vec2::new(0.3, 0.7), Vec2::new(-2.5, 11.25)][i % 3];
    BsdfContext::new(uv, side)
}

/// ωo at the given cos θ (azimuth 30°, so no axis is special).
fn incident(cos: f32) -> Vec3 {
    // Unit length to the last bit matters: with α = 1e-4 a 1e-5 error in |ωo| shifts the lobe.
    let sin = (1.0 - cos * cos).sqrt();
    let phi = 30f32.to_radians();
    Vec3::new(sin * phi.cos(), sin * phi.sin(), cos).normalize()
}

const INCIDENT: [f32; 3] = [1.0, std::f32::consts::FRAC_1_SQRT_2, 1e-3];
const ROUGHNESS: [f32; 6] = [1e-4, 1e-3, 1e-2, 0.1, 0.5, 1.0];

/// How one configuration is chi-square tested at incidence cos θo.
struct Chi2Setup {
    wo: Vec3,
    test: Chi2Test,
    /// Histogram half vectors instead of directions (see [`half_vector_chi2`]).
    half_vector: bool,
}

/// One configuration of a BSDF and how its sampling is chi-square tested: `None` at incidences
/// where no histogram resolves the lobe (covered by the other tests instead).
struct Case {
    label: String,
    bsdf: Arc<dyn Bsdf>,
    chi2: Box<dyn Fn(f32) -> Option<Chi2Setup>>,
}

/// A furnace configuration: its albedo is at most 1 at every incidence of [`INCIDENT`], and when
/// `lossless` is given, 1 within its tolerance at its incidences.
struct Furnace {
    label: String,
    bsdf: Arc<dyn Bsdf>,
    lossless: Option<(f64, &'static [f32])>,
}

/// What is tested of one BSDF plugin: configurations for the chi-square, weight, reciprocity and
/// hostile-input tests, and configurations at the energy limit for the furnace.
struct Plan {
    cases: Vec<Case>,
    furnaces: Vec<Furnace>,
}

/// The standard chi-square test of `sample` against `pdf` at ωo of incidence cos.
fn standard_chi2(cos: f32) -> Option<Chi2Setup> {
    Some(Chi2Setup {
        wo: incident(cos),
        test: Chi2Test::default(),
        half_vector: false,
    })
}

/// The chi-square setup of a GGX-like lobe of roughness `alpha` at incidence cos.
fn glossy_chi2(alpha: f32, cos: f32) -> Option<Chi2Setup> {
    // At grazing incidence the reflected lobe is ~2α·cos θo wide across the plane of
    // incidence: for α = 1e-2 and below at cos θo = 1e-3 that is under 2e-5 rad, within a few
    // hundred f32 roundings of a unit vector, so neither the sampled directions nor any
    // histogram of them resolve it. Those cases are covered by the weight, furnace and
    // finiteness tests instead.
    if alpha * cos < 5e-5 {
        return None;
    }
    let wo = incident(cos);
    let mut test = Chi2Test::default();
    if alpha < 0.3 {
        // Resolve the sharp lobe: bins over a cap about the mirror direction, or at grazing
        // incidence about the normal in half-vector space.
        test.axis = if cos >= 0.5 {
            Vec3::new(-wo.x, -wo.y, wo.z)
        } else {
            Vec3::Z
        };
        test.cos_cap = (12.0 * alpha as f64).min(std::f64::consts::PI).cos();
    }
    Some(Chi2Setup {
        wo,
        test,
        half_vector: cos < 0.5,
    })
}

fn case(
    label: String,
    bsdf: Arc<dyn Bsdf>,
    chi2: impl Fn(f32) -> Option<Chi2Setup> + 'static,
) -> Case {
    Case {
        label,
        bsdf,
        chi2: Box::new(chi2),
    }
}

fn furnace(kind: &str, params: &str, lossless: Option<(f64, &'static [f32])>) -> Furnace {
    Furnace {
        label: format!("{kind} {params}"),
        bsdf: bsdf(kind, params),
        lossless,
    }
}

/// The test plan of the built-in BSDF `name`, or `None` if it has none yet.
fn plan(name: &str) -> Option<Plan> {
    let lossless_everywhere: Option<(f64, &'static [f32])> = Some((1e-6, &[1.0, 0.5, 0.1]));
    Some(match name {
        "diffuse" => Plan {
            cases: vec![case(
                "diffuse".into(),
                bsdf("diffuse", "\"reflectance\": (0.9, 0.5, 0.1)"),
                standard_chi2,
            )],
            furnaces: vec![furnace(
                "diffuse",
                "\"reflectance\": 1",
                lossless_everywhere,
            )],
        },
        "mirror" => Plan {
            // A Dirac lobe has no density to histogram against: `chi2` is never applicable;
            // the weight test checks that its samples are flagged delta with zero eval.
            cases: vec![case(
                "mirror".into(),
                bsdf("mirror", "\"reflectance\": (0.9, 0.5, 0.1)"),
                |_| None,
            )],
            furnaces: vec![furnace("mirror", "\"reflectance\": 1", lossless_everywhere)],
        },
        "measured" => Plan {
            cases: vec![case("measured".into(), measured(), |cos| {
                // The measured density is piecewise constant over (cos θi, φi − φo) cells: with
                // ωo at azimuth 0 and 64 × 128 bins per hemisphere the bins align with the
                // cells, so Simpson's rule integrates each bin exactly.
                Some(Chi2Setup {
                    wo: Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos).normalize(),
                    test: Chi2Test {
                        theta_bins: 128,
                        phi_bins: 128,
                        samples: 2_000_000,
                        ..Chi2Test::default()
                    },
                    half_vector: false,
                })
            })],
            // Tabulated from a glossy BRDF that conserves energy.
            furnaces: vec![Furnace {
                label: "measured".into(),
                bsdf: measured(),
                lossless: None,
            }],
        },
        "glossy" => {
            let mut cases = Vec::new();
            let mut furnaces = Vec::new();
            for a in ROUGHNESS {
                for (label, params) in [
                    (
                        format!("glossy a={a}"),
                        format!("\"roughness\": {a}, \"specular\": 0.9"),
                    ),
                    (
                        format!("glossy a={a} +base"),
                        format!("\"roughness\": {a}, \"diffuse\": 0.5"),
                    ),
                ] {
                    cases.push(case(label, bsdf("glossy", &params), move |cos| {
                        glossy_chi2(a, cos)
                    }));
                }
                for params in [
                    format!("\"roughness\": {a}, \"specular\": 1"),
                    format!("\"roughness\": {a}, \"specular\": 0.04, \"diffuse\": 1"),
                ] {
                    furnaces.push(furnace("glossy", &params, None));
                }
            }
            // Smooth and fully reflective glossy is lossless up to its (tiny) masking loss.
            furnaces.push(furnace(
                "glossy",
                "\"roughness\": 0.0001, \"specular\": 1",
                Some((1e-4, &[1.0])),
            ));
            Plan { cases, furnaces }
        }
        "conductor" => Plan {
            // A Dirac lobe: no density to histogram; the weight test checks its samples.
            cases: vec![case(
                "conductor Au".into(),
                bsdf("conductor", "\"material\": \"Au\""),
                |_| None,
            )],
            // Mitsuba's `none`: Fresnel 1, a perfect mirror.
            furnaces: vec![furnace("conductor", "", lossless_everywhere)],
        },
        "roughconductor" => {
            let mut cases = Vec::new();
            for (distribution, a, material) in [
                ("beckmann", 0.05f32, "Au"),
                ("beckmann", 0.5, "Al"),
                ("ggx", 0.2, "Cu"),
            ] {
                let params = format!(
                    "\"distribution\": \"{distribution}\", \"alpha\": {a}, \"material\": \"{material}\""
                );
                cases.push(case(
                    format!("roughconductor {distribution} a={a} {material}"),
                    bsdf("roughconductor", &params),
                    move |cos| glossy_chi2(a, cos),
                ));
            }
            let mut furnaces = Vec::new();
            for distribution in ["beckmann", "ggx"] {
                for a in [0.1, 1.0] {
                    furnaces.push(furnace(
                        "roughconductor",
                        &format!("\"distribution\": \"{distribution}\", \"alpha\": {a}"),
                        None,
                    ));
                }
                // Nearly smooth with Fresnel 1: lossless up to the (tiny) masking loss.
                furnaces.push(furnace(
                    "roughconductor",
                    &format!("\"distribution\": \"{distribution}\", \"alpha\": 0.0001"),
                    Some((1e-4, &[1.0])),
                ));
            }
            Plan { cases, furnaces }
        }
        "plastic" => Plan {
            cases: vec![case(
                "plastic".into(),
                bsdf("plastic", "\"diffuse_reflectance\": (0.9, 0.5, 0.1)"),
                standard_chi2,
            )],
            // A white base under the coating reflects everything but what the diffuse Fresnel
            // fit gets wrong: Mitsuba's d'Eon–Irving fit of F_dr is 0.08 % high at η = 1.49,
            // which makes the albedo at most 0.12 % above 1 (computed from the exact
            // reflectance; at normal incidence).
            furnaces: vec![
                furnace(
                    "plastic",
                    "\"diffuse_reflectance\": 1",
                    Some((2e-3, &[1.0, 0.5, 0.1])),
                ),
                furnace(
                    "plastic",
                    "\"diffuse_reflectance\": 1, \"nonlinear\": true",
                    Some((2e-3, &[1.0, 0.5, 0.1])),
                ),
            ],
        },
        "roughplastic" => {
            let mut cases = Vec::new();
            for (distribution, a) in [("beckmann", 0.1f32), ("ggx", 0.4)] {
                cases.push(case(
                    format!("roughplastic {distribution} a={a}"),
                    bsdf(
                        "roughplastic",
                        &format!(
                            "\"distribution\": \"{distribution}\", \"alpha\": {a}, \"diffuse_reflectance\": (0.9, 0.5, 0.1)"
                        ),
                    ),
                    move |cos| glossy_chi2(a, cos),
                ));
            }
            let furnaces = [("beckmann", 0.1), ("ggx", 0.5)]
                .iter()
                .map(|(distribution, a)| {
                    furnace(
                        "roughplastic",
                        &format!(
                            "\"distribution\": \"{distribution}\", \"alpha\": {a}, \"diffuse_reflectance\": 1"
                        ),
                        None,
                    )
                })
                .collect();
            Plan { cases, furnaces }
        }
        "twosided" => Plan {
            // Seen from the front here (the side tests are in `materials.rs`).
            cases: vec![case(
                "twosided".into(),
                nested(
                    "(type: \"twosided\", front: (type: \"diffuse\", reflectance: (0.9, 0.5, 0.1)), back: (type: \"roughconductor\"))",
                ),
                standard_chi2,
            )],
            furnaces: vec![Furnace {
                label: "twosided".into(),
                bsdf: nested(
                    "(type: \"twosided\", front: (type: \"diffuse\", reflectance: 1), back: (type: \"conductor\"))",
                ),
                lossless: lossless_everywhere,
            }],
        },
        // Dirac lobes: no density to histogram; a refraction's weight carries 1/η² (entering
        // glass from the front: the albedo is below 1). Energy, Snell's law and the sides are
        // tested in `dielectrics.rs`.
        "dielectric" => Plan {
            cases: vec![case(
                "dielectric".into(),
                bsdf("dielectric", "\"specular_reflectance\": (0.9, 0.5, 0.1)"),
                |_| None,
            )],
            furnaces: vec![furnace("dielectric", "\"int_ior\": \"water\"", None)],
        },
        "thindielectric" => Plan {
            cases: vec![case(
                "thindielectric".into(),
                bsdf(
                    "thindielectric",
                    "\"specular_transmittance\": (0.9, 0.5, 0.1)",
                ),
                |_| None,
            )],
            furnaces: vec![furnace("thindielectric", "", lossless_everywhere)],
        },
        "roughdielectric" => {
            let mut cases = Vec::new();
            let mut furnaces = Vec::new();
            for distribution in ["ggx", "beckmann"] {
                for a in [0.3f32, 0.8] {
                    let params = format!(
                        "\"distribution\": {distribution:?}, \"alpha\": {a}, \"int_ior\": 1.33"
                    );
                    cases.push(case(
                        format!("roughdielectric {distribution} a={a}"),
                        bsdf("roughdielectric", &params),
                        standard_chi2,
                    ));
                    furnaces.push(furnace("roughdielectric", &params, None));
                }
            }
            Plan { cases, furnaces }
        }
        _ => return None,
    })
}

/// A BSDF that refers to others (nested BSDFs, textures), built from its RON description as a
/// scene builds it.
pub(crate) fn nested(description: &str) -> Arc<dyn Bsdf> {
    lumis_bsdfs::link();
    let spec: lumis_core::scene::description::PluginSpec =
        ron::from_str(description).expect("a plugin description");
    let references =
        lumis_core::scene::references::SceneReferences::standalone(std::path::Path::new("."));
    references.build_bsdf("bsdf", &spec).expect("builds").0
}

/// The plans of every registered built-in BSDF, by name.
fn plans() -> Vec<(&'static str, Plan)> {
    lumis_bsdfs::link();
    registry::builtin::<BsdfPlugin>()
        .iter()
        .map(|p| {
            let plan = plan(p.name).unwrap_or_else(|| {
                panic!(
                    "BSDF `{}` is registered but has no test plan: add its configurations to `plan` in {}",
                    p.name,
                    file!()
                )
            });
            (p.name, plan)
        })
        .collect()
}

/// Every case of every registered BSDF.
fn all_bsdfs() -> Vec<(String, Arc<dyn Bsdf>)> {
    plans()
        .into_iter()
        .flat_map(|(_, plan)| plan.cases)
        .map(|c| (c.label, c.bsdf))
        .collect()
}

#[test]
fn every_registered_bsdf_has_a_test_plan() {
    let plans = plans();
    assert!(plans.len() >= 4, "only {} BSDFs registered", plans.len());
    for (name, plan) in &plans {
        assert!(!plan.cases.is_empty(), "{name}: no configurations");
        assert!(
            !plan.furnaces.is_empty(),
            "{name}: no furnace configuration"
        );
    }
}

#[test]
fn chi_square_sampling_matches_pdf() {
    let mut runs = Vec::new();
    for (_, plan) in plans() {
        for case in plan.cases {
            for cos in INCIDENT {
                if let Some(setup) = (case.chi2)(cos) {
                    runs.push((
                        format!("{} cos={cos}", case.label),
                        case.bsdf.clone(),
                        setup,
                    ));
                }
            }
        }
    }
    let alpha = sidak(FAMILY_FALSE_ALARM, runs.len());
    let outcomes = run_side_by_side(&runs, |(_, b, setup)| {
        if setup.half_vector {
            half_vector_chi2(b.as_ref(), setup.wo, &setup.test)
        } else {
            test_bsdf(b.as_ref(), &FRONT, setup.wo, &setup.test)
        }
    });
    for ((name, _, _), outcome) in runs.iter().zip(outcomes) {
        outcome.assert_passes(alpha, name);
    }
}

/// The chi-square test in half-vector coordinates h = normalize(ωo + ωi), a bijection for a
/// fixed ωo with density p_h(h) = p(ωi) · 4 |ωo · h|. At grazing incidence a reflected lobe is
/// squeezed to a width of ~α·cos θo in one direction, which no histogram of f32 directions
/// resolves; in h it keeps its width α.
fn half_vector_chi2(b: &dyn Bsdf, wo: Vec3, test: &Chi2Test) -> lumis_core::chi2::Chi2Outcome {
    test.run(
        |s| {
            let u_lobe = s.next_1d();
            let h = (wo + b.sample(&FRONT, wo, u_lobe, s.next_2d())?.wi).normalize();
            // Within ~1e-7 of the horizon the f32 round trip ωi → h → ωi can cross it; such
            // samples count as failed, as the density below does.
            (reflect(wo, h).z > 0.0).then_some(h)
        },
        |h| {
            let wi = reflect(wo, h);
            if wi.z <= 0.0 || wo.dot(h) <= 0.0 {
                return 0.0;
            }
            (b.pdf(&FRONT, wo, wi) * 4.0 * wo.dot(h)) as f64
        },
    )
}

fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    (2.0 * wo.dot(h) * h - wo).normalize()
}

#[test]
fn sample_weight_equals_eval_over_pdf() {
    for (name, b) in all_bsdfs() {
        for cos in INCIDENT {
            let wo = incident(cos);
            let mut s = Sampler::new(test_seed(), 2, 3);
            for _ in 0..20_000 {
                let (ul, u) = (s.next_1d(), s.next_2d());
                let Some(smp) = b.sample(&FRONT, wo, ul, u) else {
                    continue;
                };
                assert!(smp.weight.is_finite() && smp.pdf > 0.0, "{name}: {smp:?}");
                if smp.delta {
                    // A BSDF of Dirac lobes only evaluates to zero everywhere (one with
                    // another lobe too, a plastic, evaluates that lobe there).
                    if !b.flags().is_pure_delta() {
                        continue;
                    }
                    assert_eq!(
                        b.eval(&FRONT, wo, smp.wi),
                        glam::Vec3::ZERO,
                        "{name}: delta lobes have no eval"
                    );
                    continue;
                }
                let pdf = b.pdf(&FRONT, wo, smp.wi);
                let expected = b.eval(&FRONT, wo, smp.wi) / pdf;
                assert!(
                    ((pdf - smp.pdf) / pdf).abs() < 1e-4,
                    "{name}: pdf {pdf} vs {}",
                    smp.pdf
                );
                let err = (smp.weight - expected).abs().max_element();
                assert!(
                    err <= 1e-4 * expected.max_element().max(1e-6),
                    "{name} cos={cos}: weight {:?} vs eval/pdf {expected:?}",
                    smp.weight
                );
            }
        }
    }
}

/// `eval_pdf` gives `eval` and `pdf` bit for bit (a BSDF that shares their work must not
/// change either): at sampled directions, uniform ones over the whole sphere (below the
/// horizon too), and from below the horizon.
#[test]
fn eval_pdf_is_eval_and_pdf_bit_for_bit() {
    let bits = |(f, p): (Vec3, f32)| (f.to_array().map(f32::to_bits), p.to_bits());
    for (name, b) in all_bsdfs() {
        for wo in INCIDENT.map(incident).into_iter().chain([-incident(0.5)]) {
            let mut s = Sampler::new(test_seed(), 4, 5);
            let mut compared = 0;
            for i in 0..4_000 {
                let (ul, u) = (s.next_1d(), s.next_2d());
                let wi = if i % 2 == 0 {
                    let Some(smp) = b.sample(&FRONT, wo, ul, u) else {
                        continue;
                    };
                    smp.wi
                } else {
                    let z = 1.0 - 2.0 * u.x;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = std::f32::consts::TAU * u.y;
                    Vec3::new(r * phi.cos(), r * phi.sin(), z)
                };
                assert_eq!(
                    bits(b.eval_pdf(&FRONT, wo, wi)),
                    bits((b.eval(&FRONT, wo, wi), b.pdf(&FRONT, wo, wi))),
                    "{name}: wo {wo} wi {wi}"
                );
                compared += 1;
            }
            assert!(compared >= 2_000, "{name}: only {compared} directions");
        }
    }
}

/// The batch entry points give what the single calls give, bit for bit: `sample_batch` what
/// `sample` gives for each `(u_lobe, u)`, `eval_pdf_batch` what `eval_pdf` gives for each
/// direction. At every kernel width (four lanes, eight where the processor has AVX2, sixteen
/// where it has AVX-512), for batches of every length a group of four, eight or sixteen can end
/// with (1 to 15 left over, and longer ones), of one ωo (one shading point) or of several (one per camera sample), for ωo at the
/// test incidences and hostile ones (below the horizon, grazing, exactly normal, a hair above
/// the horizon, off the normal by 1e-20); the numbers from a seeded stream with the corners 0,
/// 1/2 and 0.9999999 in some lanes, the directions sampled, uniform over the sphere and special
/// (the poles, the horizon, just below it, the mirror direction). Each output starts as a NaN
/// sentinel, so an element the batch leaves unwritten fails.
#[test]
fn batches_give_what_single_calls_give_bit_for_bit() {
    const LENGTHS: [usize; 12] = [1, 2, 3, 4, 5, 7, 8, 9, 15, 17, 33, 64];
    const ROUNDS: usize = 40;
    const CORNERS: [f32; 3] = [0.0, 0.5, 0.999_999_9];
    let hostile = [
        -incident(0.5),
        Vec3::Z,
        Vec3::new(1.0, 0.0, 1e-7).normalize(),
        Vec3::new(1e-20, 0.0, 1.0).normalize(),
        Vec3::new(0.6, 0.8, -1e-7),
        -Vec3::Z,
    ];
    let special = |wo: Vec3| {
        [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.0, -1.0, 0.0),
            incident(1e-3),
            Vec3::new(1.0, 0.0, 1e-7).normalize(),
            Vec3::new(0.6, 0.8, -1e-7),
            Vec3::new(1e-20, 0.0, 1.0),
            Vec3::new(0.3, -0.4, -0.866),
            wo,
            -wo,
            Vec3::new(-wo.x, -wo.y, wo.z),
        ]
    };
    let sample_bits = |s: Option<lumis_core::bsdf::BsdfSample>| {
        s.map(|s| {
            (
                s.wi.to_array().map(f32::to_bits),
                s.pdf.to_bits(),
                s.weight.to_array().map(f32::to_bits),
                s.delta,
                s.transmission(),
                s.eta.to_bits(),
            )
        })
    };
    let eval_pdf_bits = |(f, p): (Vec3, f32)| (f.to_array().map(f32::to_bits), p.to_bits());
    let sentinel =
        lumis_core::bsdf::BsdfSample::delta(Vec3::NAN, f32::NAN, Vec3::NAN).with_eta(f32::NAN);
    // The incidences, then the hostile ones not among them (incident(1) is +Z).
    let mut incidences: Vec<Vec3> = INCIDENT.map(incident).to_vec();
    for wo in hostile {
        if !incidences.contains(&wo) {
            incidences.push(wo);
        }
    }
    let (mut some_overall, mut none_overall, mut none_above) = (0usize, 0usize, 0usize);
    // Batches in which some lanes give a sample and others none, with wo above the horizon:
    // where a lane's mask matters.
    let mut mixed = 0usize;
    // Every kernel width, four, eight (with AVX2) and sixteen (with AVX-512): the same results
    // either way.
    for width in [4, 8, 16] {
        limit_width(width);
        if widest_width() != width {
            // The processor has no lanes this wide: its widest were tested already.
            continue;
        }
        for (name, b) in all_bsdfs() {
            let (mut some_above, mut positive_above) = (0usize, 0usize);
            for &wo in &incidences {
                let mut s = Sampler::new(test_seed(), 14, 15);
                let (mut some, mut positive) = (0usize, 0usize);
                for round in 0..ROUNDS {
                    for len in LENGTHS {
                        // (u_lobe, u): from the stream, with corners in some lanes (one number,
                        // two, or all three).
                        let u: Vec<(f32, Vec2)> = (0..len)
                            .map(|k| {
                                let (mut ul, mut u) = (s.next_1d(), s.next_2d());
                                let corner = CORNERS[(s.next_1d() * 3.0) as usize];
                                match (k * 7 + round * 3) % 8 {
                                    0 => ul = corner,
                                    1 => u.x = corner,
                                    2 => u.y = corner,
                                    3 => (ul, u) = (corner, Vec2::splat(corner)),
                                    4 => u = Vec2::new(corner, CORNERS[(k + round) % 3]),
                                    _ => {}
                                }
                                (ul, u)
                            })
                            .collect();
                        // One shading point in even rounds (its ωo given once in rounds divisible by
                        // four, for every element in the others); in odd ones, the elements of
                        // several (the camera samples of a pixel), each its own ωo.
                        let wos: Vec<Vec3> = (0..len)
                            .map(|k| match round % 2 {
                                0 => wo,
                                _ => incidences[(k + round) % incidences.len()],
                            })
                            .collect();
                        // Contexts likewise: the point's one (from the front or the back, at some
                        // uv) given once or for every element, or each point's own.
                        let point = context(round);
                        let ctxs: Vec<BsdfContext> = (0..len)
                            .map(|k| match round % 2 {
                                0 => point,
                                _ => context(k + round),
                            })
                            .collect();
                        let mut out = vec![Some(sentinel); len];
                        let (ctx_argument, wo_argument) = match round % 4 {
                            0 => (std::slice::from_ref(&point), std::slice::from_ref(&wo)),
                            _ => (&ctxs[..], &wos[..]),
                        };
                        b.sample_batch(ctx_argument, wo_argument, &u, &mut out);
                        let drawn = out.iter().filter(|s| s.is_some()).count();
                        // (Of the BSDFs with their own batch code.)
                        if name == "diffuse" || name.starts_with("glossy") {
                            mixed += (drawn > 0 && drawn < len) as usize;
                        }
                        for (k, (&(ul, uk), batch)) in u.iter().zip(&out).enumerate() {
                            let wo = wos[k];
                            let single = b.sample(&ctxs[k], wo, ul, uk);
                            assert_eq!(
                                sample_bits(*batch),
                                sample_bits(single),
                                "{name} ({width} lanes): sample_batch of {len}, element {k}: wo {wo:?}, u_lobe {ul:?}, \
                             u {uk:?}: batch {batch:?}, single {single:?}"
                            );
                            some += single.is_some() as usize;
                            none_overall += single.is_none() as usize;
                            none_above += (single.is_none() && wo.z > 0.0) as usize;
                        }
                        // Directions: sampled (a uniform one where sampling fails), uniform over
                        // the sphere, and special.
                        let wi: Vec<Vec3> = (0..len)
                            .map(|k| {
                                let (ul, u) = (s.next_1d(), s.next_2d());
                                let uniform = || {
                                    let z = 1.0 - 2.0 * u.x;
                                    let r = (1.0 - z * z).max(0.0).sqrt();
                                    let phi = std::f32::consts::TAU * u.y;
                                    Vec3::new(r * phi.cos(), r * phi.sin(), z)
                                };
                                match (k + round) % 3 {
                                    0 => b
                                        .sample(&FRONT, wo, ul, u)
                                        .map_or_else(uniform, |smp| smp.wi),
                                    1 => uniform(),
                                    _ => {
                                        let special = special(wo);
                                        special[((ul * special.len() as f32) as usize)
                                            .min(special.len() - 1)]
                                    }
                                }
                            })
                            .collect();
                        let mut out = vec![(Vec3::NAN, f32::NAN); len];
                        b.eval_pdf_batch(ctx_argument, wo_argument, &wi, &mut out);
                        for (k, (&wik, &batch)) in wi.iter().zip(&out).enumerate() {
                            let wo = wos[k];
                            let single = b.eval_pdf(&ctxs[k], wo, wik);
                            assert_eq!(
                                eval_pdf_bits(batch),
                                eval_pdf_bits(single),
                                "{name} ({width} lanes): eval_pdf_batch of {len}, element {k}: wo {wo:?}, wi \
                             {wik:?}: batch {batch:?}, single {single:?}"
                            );
                            positive += (single.1 > 0.0) as usize;
                        }
                    }
                }
                some_overall += some;
                if wo.z > 0.0 {
                    some_above += some;
                    positive_above += positive;
                }
                if INCIDENT.map(incident).contains(&wo) {
                    assert!(
                        some >= 1_000,
                        "{name} ({width} lanes): only {some} samples compared at wo {wo:?}"
                    );
                }
            }
            // A delta lobe has no density: its directions are compared all the same.
            assert!(
                some_above >= 8_000 && (b.flags().delta() || positive_above >= 5_000),
                "{name} ({width} lanes): only {some_above} samples and {positive_above} directions of positive \
             density compared with wo above the horizon"
            );
        }
    }
    limit_width(DEFAULT_WIDTH);
    assert!(
        mixed >= 100,
        "only {mixed} batches mixed samples and failed ones"
    );
    assert!(
        some_overall > 0 && none_overall > 0 && none_above >= 100,
        "{some_overall} samples and {none_overall} failed samples ({none_above} with wo above \
         the horizon): both must be compared"
    );
}

/// Directional albedo by sampling: mean weight and its standard error.
fn albedo(b: &dyn Bsdf, wo: Vec3, n: usize) -> (f64, f64) {
    let mut s = Sampler::new(test_seed(), 8, 7);
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let (ul, u) = (s.next_1d(), s.next_2d());
        let w = b
            .sample(&FRONT, wo, ul, u)
            .map_or(0.0, |smp| smp.weight.max_element() as f64);
        sum += w;
        sum2 += w * w;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// One-sided z-tests (albedo ≤ 1 + z σ; |albedo − 1| ≤ z σ + the lossless case's tolerance), one
/// family at the suite's false-alarm rate (Šidák over its checks).
#[test]
fn white_furnace_albedo_is_at_most_one_and_one_when_lossless() {
    // (label, cos θo, albedo, standard error, Some(tolerance) when it must be 1).
    let mut checks = Vec::new();
    for (_, plan) in plans() {
        for f in plan.furnaces {
            for cos in INCIDENT {
                let (albedo, se) = albedo(f.bsdf.as_ref(), incident(cos), 100_000);
                checks.push((f.label.clone(), cos, albedo, se, None));
            }
            if let Some((tolerance, incidences)) = f.lossless {
                for &cos in incidences {
                    let (albedo, se) = albedo(f.bsdf.as_ref(), incident(cos), 100_000);
                    checks.push((f.label.clone(), cos, albedo, se, Some(tolerance)));
                }
            }
        }
    }
    // Each check is one-sided (the lossless ones two-sided, counted twice).
    let sides = checks.iter().map(|c| 1 + c.4.is_some() as usize).sum();
    let z = z_limit(2.0 * sidak(FAMILY_FALSE_ALARM, sides));
    for (label, cos, albedo, se, lossless) in checks {
        match lossless {
            None => assert!(
                albedo <= 1.0 + z * se,
                "{label} cos={cos}: albedo {albedo} ± {se} (limit {z:.2} σ, seed {})",
                test_seed()
            ),
            Some(tolerance) => assert!(
                (albedo - 1.0).abs() <= z * se + tolerance,
                "{label} cos={cos}: lossless albedo {albedo} ± {se} (limit {z:.2} σ, seed {})",
                test_seed()
            ),
        }
    }
}

#[test]
fn eval_is_reciprocal() {
    let mut s = Sampler::new(test_seed(), 5, 6);
    for (name, b) in all_bsdfs() {
        for _ in 0..5_000 {
            let a = lumis_core::math::warp::square_to_cosine_hemisphere(s.next_2d());
            let c = lumis_core::math::warp::square_to_cosine_hemisphere(s.next_2d());
            if a.z < 1e-3 || c.z < 1e-3 {
                continue;
            }
            // eval includes cos θi: compare f = eval / cos θi both ways.
            let f_ac = b.eval(&FRONT, a, c) / c.z;
            let f_ca = b.eval(&FRONT, c, a) / a.z;
            let err = (f_ac - f_ca).abs().max_element();
            assert!(
                err <= 1e-4 * f_ac.max_element().max(1e-3),
                "{name}: {f_ac:?} vs {f_ca:?}"
            );
        }
    }
}

#[test]
fn hostile_directions_give_finite_values() {
    let special = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(1.0, 0.0, 1e-7).normalize(),
        Vec3::new(0.6, 0.8, -1e-7),
        Vec3::new(1e-20, 0.0, 1.0),
        incident(1e-3),
        Vec3::new(0.3, -0.4, -0.866),
    ];
    let corners = [
        Vec2::ZERO,
        Vec2::new(0.0, 0.999_999_9),
        Vec2::splat(0.999_999_9),
        Vec2::new(0.5, 0.0),
    ];
    for (name, b) in all_bsdfs() {
        for wo in special {
            for wi in special {
                let (f, p) = (b.eval(&FRONT, wo, wi), b.pdf(&FRONT, wo, wi));
                assert!(
                    f.is_finite() && f.min_element() >= 0.0,
                    "{name}: eval({wo}, {wi}) = {f}"
                );
                assert!(p.is_finite() && p >= 0.0, "{name}: pdf({wo}, {wi}) = {p}");
                // A transmitting BSDF scatters below the horizon, never from below it.
                if wo.z <= 0.0 || (wi.z <= 0.0 && !b.flags().transmission()) {
                    assert_eq!(f, Vec3::ZERO, "{name}: light below the horizon");
                }
            }
            for u in corners {
                for ul in [0.0, 0.5, 0.999_999_9] {
                    if let Some(smp) = b.sample(&FRONT, wo, ul, u) {
                        assert!(
                            smp.wi.is_finite() && smp.weight.is_finite() && smp.pdf.is_finite(),
                            "{name}: {smp:?}"
                        );
                        assert!(
                            smp.wi.z > 0.0 || (smp.wi.z < 0.0 && b.flags().transmission()),
                            "{name}: sampled below the horizon"
                        );
                    }
                }
            }
        }
    }
}

/// The measured BRDF read from a file generated from an analytic one reproduces it: exactly at
/// the table's grid points, and within the table's interpolation error between them.
#[test]
fn measured_reproduces_the_analytic_brdf_it_was_generated_from() {
    let source = bsdf("glossy", MERL_SOURCE);
    let table = &merl().0;
    let f = |wo: Vec3, wi: Vec3| source.eval(&FRONT, wo, wi) / wi.z;
    let mut s = Sampler::new(test_seed(), 12, 13);
    let mut errors = Vec::new();
    for _ in 0..20_000 {
        let wo = lumis_core::math::warp::square_to_cosine_hemisphere(s.next_2d());
        let wi = lumis_core::math::warp::square_to_cosine_hemisphere(s.next_2d());
        if wo.z < 0.05 || wi.z < 0.05 {
            continue;
        }
        let (a, m) = (f(wo, wi), table.lookup(wi, wo));
        errors.push(((m - a).abs() / a.max(Vec3::splat(1e-3))).max_element());
    }
    errors.sort_by(f32::total_cmp);
    let median = errors[errors.len() / 2];
    let p95 = errors[errors.len() * 95 / 100];
    // Linear interpolation on the 90x90x180 grid of a smooth lobe (alpha = 0.25).
    assert!(
        median < 0.01 && p95 < 0.05,
        "relative error: median {median}, 95th percentile {p95}"
    );
}

#[test]
fn measured_refuses_missing_and_corrupt_files_by_name() {
    lumis_bsdfs::link();
    let plugin = registry::find::<BsdfPlugin>("measured").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("corrupt.binary");
    std::fs::write(&corrupt, [0u8; 100]).unwrap();
    for (file, reason) in [
        ("missing.binary", "cannot read measured BRDF"),
        ("corrupt.binary", "not a MERL file"),
    ] {
        let values = ron::from_str(&format!("{{\"file\": {file:?}}}")).unwrap();
        let mut p = Params::new("bsdf `m` (measured)", plugin.params, values)
            .unwrap()
            .with_base_dir(dir.path());
        let e = (plugin.create)(&mut p).err().expect("refused").to_string();
        assert!(
            e.contains(file) && e.contains(reason) && e.contains("bsdf `m`"),
            "{e}"
        );
    }
}

/// Sampling of an isotropic lobe commutes with rotations about the normal: the same random
/// numbers at ωo turned by ψ give the direction turned by ψ. The chi-square tests cannot see a
/// sign error in the azimuth where ωo has none (the measured BSDF is tested at azimuth 0 so
/// that its cells align with the bins). Lobes sampled relative to ωo only: the glossy
/// specular lobe (u_lobe = 0 with no diffuse base), the mirror, and the measured BSDF's tables
/// (u_lobe above its defensive cosine fraction).
#[test]
fn lobe_sampling_turns_with_the_incident_direction() {
    let lobes = [
        (
            "glossy",
            bsdf("glossy", "\"roughness\": 0.3, \"diffuse\": 0"),
            0.0,
        ),
        ("mirror", bsdf("mirror", ""), 0.0),
        ("measured", measured(), 0.5),
    ];
    let turn = |w: Vec3, psi: f32| {
        let (s, c) = psi.sin_cos();
        Vec3::new(c * w.x - s * w.y, s * w.x + c * w.y, w.z)
    };
    let mut sampler = Sampler::new(3, 0, 0);
    for (name, b, u_lobe) in lobes {
        let mut compared = 0;
        for _ in 0..200 {
            let (cos, psi) = (0.2 + 0.7 * sampler.next_1d(), 6.0 * sampler.next_1d());
            let wo = incident(cos);
            let u = sampler.next_2d();
            let (Some(a), Some(b)) = (
                b.sample(&FRONT, wo, u_lobe, u),
                b.sample(&FRONT, turn(wo, psi), u_lobe, u),
            ) else {
                continue;
            };
            let expected = turn(a.wi, psi);
            // f32 rounding of the two paths: at most 5e-7 over these samples.
            assert!(
                (b.wi - expected).length() < 1e-5,
                "{name}: ωo {wo}, ψ {psi}: {} against {expected}",
                b.wi
            );
            compared += 1;
        }
        assert!(compared > 100, "{name}: only {compared} samples");
    }
}

//! Independent checks of BSDF evaluation, through the plugins' public interface: GGX's D, G1
//! and G2 against closed forms and the integrals every microfacet model satisfies; reciprocity;
//! directional albedo by deterministic quadrature of `eval` against closed forms and against
//! the mean sample weight (a two-sided white furnace through `sample`).
//!
//! With specular reflectance 1 (Fresnel is then exactly 1) and no diffuse base, the `glossy`
//! plugin's microfacet distribution D, its Smith masking G1 and its masking-shadowing G2 can be
//! read back from `eval` (which includes cos θi) and `pdf` (the visible-normal density):
//!
//! - at ωo = z, pdf(z, ω) = D(h)/4 and eval(z, ω) = D(h) G2(z, ω)/4 = D(h) G1(ω)/4, so
//!   G1(ω) = eval(z, ω) / pdf(z, ω);
//! - pdf(h, h) = G1(h) D(h) / (4 cos θh) (retro-reflection, half vector h), so
//!   D(h) = 4 cos θh pdf(h, h) / G1(h);
//! - eval(ωo, ωi) = D(h) G2(ωo, ωi) / (4 cos θo), so G2 = 4 cos θo eval / D(h).
//!
//! These are checked against closed forms written here from the papers (Walter et al. 2007, eqs.
//! 33–34, for D and G1; Heitz 2014, eq. 99, for the height-correlated G2, in the form of
//! Filament's visibility term) at chosen angles down to grazing ones, and against the integrals
//! every microfacet model satisfies, by deterministic quadrature: ∫ D(h) cos θh dωh = 1, and
//! ∫ G1(ωo) max(0, ωo·h) D(h) dωh = cos θo (Heitz 2014, eq. 14). A wrong D, a Smith Λ that does
//! not belong to D, or G1(ωo)·G1(ωi) in place of the height-correlated G2 fails them.
//!
//! Every quadrature states its error: the difference between the rule and the rule with twice
//! the panels; tolerances are a multiple of it plus the plugins' f32 rounding.
//!
//! Why one file of over 600 lines: the closed forms and quadratures the BSDF checks share.

use glam::{DVec3, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext};

/// The context of a BSDF tested on its own: seen from the front, at uv (0, 0).
const FRONT: BsdfContext = BsdfContext::FRONT;
use lumis_core::chi2::{FAMILY_FALSE_ALARM, sidak, test_sampler, test_seed, z_limit};
use lumis_core::params::Params;
use lumis_core::registry::{self, BsdfPlugin};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::sync::Arc;

/// The BSDF plugin `kind` built from `params` (the inside of a RON map), as a scene would.
fn bsdf(kind: &str, params: &str) -> Arc<dyn Bsdf> {
    lumis_bsdfs::link();
    let plugin = registry::find::<BsdfPlugin>(kind).unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new(kind, plugin.params, values).unwrap();
    let b = (plugin.create)(&mut p).unwrap();
    p.finish().unwrap();
    b
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on the Legendre polynomial).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut rule = vec![(0.0, 0.0); n];
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut derivative = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_{n−1}(x) by the three-term recurrence.
            let (mut previous, mut p) = (1.0, x);
            for k in 2..=n {
                let next = ((2 * k - 1) as f64 * x * p - (k - 1) as f64 * previous) / k as f64;
                previous = p;
                p = next;
            }
            if n == 1 {
                previous = 1.0;
            }
            derivative = n as f64 * (x * p - previous) / (x * x - 1.0);
            let step = p / derivative;
            x -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        let weight = 2.0 / ((1.0 - x * x) * derivative * derivative);
        rule[i] = (-x, weight);
        rule[n - 1 - i] = (x, weight);
    }
    rule
}

/// A composite rule on [a, b]: `panels` equal panels of 8-point Gauss–Legendre.
pub(crate) fn composite(a: f64, b: f64, panels: usize) -> Vec<(f64, f64)> {
    let base = gauss_legendre(8);
    let width = (b - a) / panels as f64;
    (0..panels)
        .flat_map(|k| {
            let start = a + k as f64 * width;
            base.iter()
                .map(move |&(x, w)| (start + 0.5 * width * (x + 1.0), 0.5 * width * w))
        })
        .collect()
}

/// An integral by quadrature and an estimate of its error.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Quadrature {
    pub(crate) value: f64,
    pub(crate) error: f64,
}

impl Quadrature {
    /// `rule(panels)` evaluated at `panels` and at twice as many: the finer value, with the
    /// difference as its error (an overestimate for the piecewise-smooth integrands here, whose
    /// error falls at least fourfold when the panels are halved).
    pub(crate) fn refined(rule: impl Fn(usize) -> f64, panels: usize) -> Self {
        let coarse = rule(panels);
        let fine = rule(2 * panels);
        Quadrature {
            value: fine,
            error: (fine - coarse).abs(),
        }
    }
}

/// f32 rounding: the plugin evaluates in f32.
const EPS: f64 = f32::EPSILON as f64;

/// The roughness values tested, from a near-mirror to the roughest.
const ROUGHNESS: [f32; 6] = [1e-4, 1e-3, 1e-2, 0.1, 0.5, 1.0];

/// cos θo tested, down to grazing.
const COS_O: [f64; 5] = [1.0, 0.7, 0.2, 1e-2, 1e-3];

/// GGX closed forms in f64, written from the papers rather than from the plugin.
struct Reference {
    alpha: f64,
}

impl Reference {
    /// Walter et al. 2007, eq. 33: D(h) = α² / (π cos⁴θ (α² + tan²θ)²).
    fn d(&self, h: DVec3) -> f64 {
        let h = h.normalize();
        if h.z <= 0.0 {
            return 0.0;
        }
        let cos2 = h.z * h.z;
        let tan2 = (h.x * h.x + h.y * h.y) / cos2;
        let a2 = self.alpha * self.alpha;
        a2 / (PI * cos2 * cos2 * (a2 + tan2).powi(2))
    }

    /// Walter et al. 2007, eq. 34: G1(ω) = 2 / (1 + √(1 + α² tan²θ)).
    fn g1(&self, w: DVec3) -> f64 {
        let w = w.normalize();
        let tan2 = (w.x * w.x + w.y * w.y) / (w.z * w.z);
        2.0 / (1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }

    /// Heitz 2014, eq. 99, G2 = 1 / (1 + Λ(ωo) + Λ(ωi)), written as 4 μo μi V with Filament's
    /// V = 0.5 / (μo √(μi²(1 − α²) + α²) + μi √(μo²(1 − α²) + α²)).
    fn g2(&self, wo: DVec3, wi: DVec3) -> f64 {
        let (mo, mi) = (wo.normalize().z, wi.normalize().z);
        let a2 = self.alpha * self.alpha;
        let lo = mo * (mi * mi * (1.0 - a2) + a2).sqrt();
        let li = mi * (mo * mo * (1.0 - a2) + a2).sqrt();
        2.0 * mo * mi / (lo + li)
    }

    /// f(ωo, ωi) cos θi with Fresnel 1: D G2 / (4 cos θo). The half vector is that of the
    /// vectors as given: f32 directions are unit only to within ε, and where ωi is nearly −ωo
    /// (a grazing mirror pair) normalising them first would move h by ε / |ωo + ωi|.
    fn eval(&self, wo: DVec3, wi: DVec3) -> f64 {
        let h = (wo + wi).normalize();
        self.d(h) * self.g2(wo, wi) / (4.0 * wo.normalize().z)
    }

    /// The density of reflecting ωo about a visible normal: G1(ωo) D(h) / (4 cos θo).
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let h = (wo + wi).normalize();
        self.g1(wo) * self.d(h) / (4.0 * wo.normalize().z)
    }
}

/// D, G1 and G2 read back from a `glossy` plugin's `eval` and `pdf` (module comment).
struct Readback {
    bsdf: Arc<dyn Bsdf>,
}

impl Readback {
    fn new(alpha: f32) -> Self {
        Readback {
            bsdf: bsdf(
                "glossy",
                &format!("\"roughness\": {alpha}, \"specular\": 1"),
            ),
        }
    }

    /// With `masking` given explicitly (`height_correlated` or `separable`).
    fn with_masking(alpha: f32, masking: &str) -> Self {
        Readback {
            bsdf: bsdf(
                "glossy",
                &format!("\"roughness\": {alpha}, \"specular\": 1, \"masking\": \"{masking}\""),
            ),
        }
    }

    fn g1(&self, w: Vec3) -> f64 {
        self.bsdf.eval(&FRONT, Vec3::Z, w).x as f64 / self.bsdf.pdf(&FRONT, Vec3::Z, w) as f64
    }

    fn d(&self, h: Vec3) -> f64 {
        4.0 * h.z as f64 * self.bsdf.pdf(&FRONT, h, h) as f64 / self.g1(h)
    }

    fn g2(&self, wo: Vec3, wi: Vec3) -> f64 {
        4.0 * wo.z as f64 * self.bsdf.eval(&FRONT, wo, wi).x as f64 / self.d((wo + wi).normalize())
    }
}

/// The unit vector at cos θ and azimuth φ.
fn direction(cos: f64, phi: f64) -> DVec3 {
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    DVec3::new(sin * phi.cos(), sin * phi.sin(), cos)
}

fn reflect(wo: DVec3, h: DVec3) -> DVec3 {
    2.0 * wo.dot(h) * h - wo
}

/// Pairs (ωo, ωi) in f32 for roughness α: ωo at each cos θo of [`COS_O`], ωi reflected about
/// normals at tan θh = 0, α/2 and 2α (in and across the plane of incidence), and grazing ωi.
fn chosen_pairs(alpha: f64) -> Vec<(Vec3, Vec3)> {
    let mut pairs = Vec::new();
    for cos_o in COS_O {
        let phi_o = 30f64.to_radians();
        let wo = direction(cos_o, phi_o);
        for (tan_h, phi_h) in [(0.0, 0.0), (0.5, 0.0), (2.0, 0.0), (0.5, 1.2), (2.0, 2.5)] {
            let h = direction(1.0 / (1.0 + (tan_h * alpha).powi(2)).sqrt(), phi_o + phi_h);
            let wi = reflect(wo, h);
            if wi.z > 1e-4 {
                pairs.push((wo.as_vec3(), wi.as_vec3()));
            }
        }
        for cos_i in [0.3, 1e-2, 1e-3] {
            let wi = direction(cos_i, phi_o + PI + 0.35);
            pairs.push((wo.as_vec3(), wi.as_vec3()));
        }
    }
    pairs
}

/// The relative error the plugin's f32 evaluation may have: a few roundings of each of the
/// dozen operations from its inputs, none of which cancels catastrophically (the inputs are
/// exact; sums of two floats are correctly rounded).
const POINTWISE: f64 = 32.0 * EPS;

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn eval_and_pdf_match_the_closed_forms_at_chosen_angles() {
    let mut worst = 0.0f64;
    for alpha32 in ROUGHNESS {
        let reference = Reference {
            alpha: alpha32 as f64,
        };
        let b = Readback::new(alpha32).bsdf;
        for (wo, wi) in chosen_pairs(alpha32 as f64) {
            let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
            let eval = b.eval(&FRONT, wo, wi);
            assert!(
                eval.x == eval.y && eval.y == eval.z,
                "grey for specular 1: {eval}"
            );
            for (what, plugin, closed) in [
                ("eval", eval.x as f64, reference.eval(o, i)),
                ("pdf", b.pdf(&FRONT, wo, wi) as f64, reference.pdf(o, i)),
            ] {
                let e = relative(plugin, closed);
                worst = worst.max(e);
                assert!(
                    e <= POINTWISE,
                    "α = {alpha32}, ωo = {wo}, ωi = {wi}: {what} {plugin:e}, closed form {closed:e} \
                     (relative error {e:.1e})"
                );
            }
        }
    }
    eprintln!("largest relative error: {worst:.1e} (bound {POINTWISE:.1e})");
}

/// (cos θo, cos θi) pairs for the masking checks, down to grazing angles.
const MASKING_PAIRS: [(f64, f64); 7] = [
    (0.9, 0.8),
    (0.5, 0.5),
    (0.2, 0.6),
    (0.05, 0.3),
    (1e-2, 1e-2),
    (1e-3, 0.5),
    (1e-3, 1e-3),
];

/// G2 read back from `eval` is the height-correlated 1 / (1 + Λo + Λi), both against its
/// closed form and against the plugin's own G1 (Λ = 1/G1 − 1), at angles where the
/// uncorrelated G1(ωo) G1(ωi) differs from it by far more than the tolerance; by default and
/// when `masking: "height_correlated"` is asked for.
#[test]
fn masking_is_height_correlated_at_chosen_angles_down_to_grazing() {
    for explicit in [false, true] {
        height_correlated_at_chosen_angles(explicit);
    }
}

fn height_correlated_at_chosen_angles(explicit: bool) {
    let mut discriminating = 0;
    for alpha32 in [0.05f32, 0.2, 0.5, 1.0] {
        let reference = Reference {
            alpha: alpha32 as f64,
        };
        let plugin = if explicit {
            Readback::with_masking(alpha32, "height_correlated")
        } else {
            Readback::new(alpha32)
        };
        for (cos_o, cos_i) in MASKING_PAIRS {
            let wo = direction(cos_o, 0.4).as_vec3();
            let wi = direction(cos_i, 0.4 + PI - 0.3).as_vec3();
            let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
            let g2 = plugin.g2(wo, wi);
            let closed = reference.g2(o, i);
            let (g1o, g1i) = (plugin.g1(wo), plugin.g1(wi));
            let correlated = 1.0 / (1.0 / g1o + 1.0 / g1i - 1.0);
            // Reading back takes a few plugin calls: their errors add.
            let tolerance = 4.0 * POINTWISE;
            for (what, expected) in [("closed form", closed), ("from G1", correlated)] {
                assert!(
                    relative(g2, expected) <= tolerance,
                    "α = {alpha32}, cos θo = {cos_o}, cos θi = {cos_i}: G2 {g2}, {what} {expected}"
                );
            }
            assert!(
                relative(g1o, reference.g1(o)) <= tolerance
                    && relative(g1i, reference.g1(i)) <= tolerance,
                "α = {alpha32}: G1 {g1o}, {g1i}, closed forms {}, {}",
                reference.g1(o),
                reference.g1(i)
            );
            if relative(g1o * g1i, closed) > 10.0 * tolerance {
                discriminating += 1;
            }
        }
    }
    // The test has power against the uncorrelated product at most of its angles.
    assert!(discriminating >= 20, "{discriminating} of 28");
}

/// With `masking: "separable"`, G2 read back from `eval` is G1(ωo) G1(ωi), both with G1 in closed
/// form (Walter 2007) and with the plugin's own G1, at angles where the height-correlated term
/// differs from it by far more than the tolerance (so that a plugin ignoring the option fails);
/// and `pdf`, the visible-normal density, does not depend on the option.
#[test]
fn masking_is_the_product_of_g1_when_separable_is_asked_for() {
    let mut discriminating = 0;
    for alpha32 in [0.05f32, 0.2, 0.5, 1.0] {
        let reference = Reference {
            alpha: alpha32 as f64,
        };
        let plugin = Readback::with_masking(alpha32, "separable");
        let correlated = Readback::new(alpha32);
        for (cos_o, cos_i) in MASKING_PAIRS {
            let wo = direction(cos_o, 0.4).as_vec3();
            let wi = direction(cos_i, 0.4 + PI - 0.3).as_vec3();
            let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
            let g2 = plugin.g2(wo, wi);
            let product = reference.g1(o) * reference.g1(i);
            let tolerance = 4.0 * POINTWISE;
            for (what, expected) in [
                ("closed form", product),
                ("from G1", plugin.g1(wo) * plugin.g1(wi)),
            ] {
                assert!(
                    relative(g2, expected) <= tolerance,
                    "separable, α = {alpha32}, cos θo = {cos_o}, cos θi = {cos_i}: G2 {g2}, \
                     {what} {expected}"
                );
            }
            let (p, q) = (
                plugin.bsdf.pdf(&FRONT, wo, wi) as f64,
                correlated.bsdf.pdf(&FRONT, wo, wi) as f64,
            );
            assert!(
                relative(p, q) <= POINTWISE,
                "separable, α = {alpha32}: pdf {p} differs from the height-correlated one's {q}"
            );
            if relative(product, reference.g2(o, i)) > 10.0 * tolerance {
                discriminating += 1;
            }
        }
    }
    assert!(discriminating >= 20, "{discriminating} of 28");
}

/// The direction at (ψ, φ) with tan θh = α tan ψ, a substitution that spreads a GGX lobe of any
/// width over ψ in [0, π/2); and the Jacobian dω / (dψ dφ).
pub(crate) fn lobe_coordinates(alpha: f64, psi: f64, phi: f64) -> (DVec3, f64) {
    let (s, c) = psi.sin_cos();
    let r2 = c * c + alpha * alpha * s * s;
    let r = r2.sqrt();
    let (cos_t, sin_t) = (c / r, alpha * s / r);
    // dθ/dψ = α sec²ψ / (1 + α² tan²ψ) = α / (cos²ψ + α² sin²ψ).
    let jacobian = sin_t * alpha / r2;
    (
        DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t),
        jacobian,
    )
}

/// ∫ D(h) cos θh dωh over the hemisphere with D read back from the plugin.
fn projected_area(plugin: &Readback, alpha: f64, panels: usize) -> f64 {
    let phi_rule = composite(0.0, TAU, 4);
    let mut sum = 0.0;
    for (psi, w_psi) in composite(0.0, FRAC_PI_2, panels) {
        for &(phi, w_phi) in &phi_rule {
            let (h, jacobian) = lobe_coordinates(alpha, psi, phi);
            sum += w_psi * w_phi * jacobian * plugin.d(h.as_vec3()) * h.z;
        }
    }
    sum
}

/// The tolerance of an integral by quadrature: four times its estimated error, plus the f32
/// rounding of the integrand read back from the plugin, relative to the integral's size.
fn tolerance(q: Quadrature, scale: f64) -> f64 {
    4.0 * q.error + 4.0 * POINTWISE * scale
}

#[test]
fn microfacet_distribution_is_normalised() {
    for alpha32 in ROUGHNESS {
        let alpha = alpha32 as f64;
        let plugin = Readback::new(alpha32);
        let q = Quadrature::refined(|panels| projected_area(&plugin, alpha, panels), 16);
        eprintln!(
            "α = {alpha32}: ∫ D cos θh dωh = {:.9} (quadrature error {:.1e})",
            q.value, q.error
        );
        assert!(
            (q.value - 1.0).abs() <= tolerance(q, 1.0),
            "α = {alpha32}: ∫ D cos θh dωh = {} ± {:.1e}",
            q.value,
            q.error
        );
    }
}

/// Calls `visit(h, dωh)` for the nodes of a quadrature over the normals h visible from ωo
/// (ωo·h > 0), in the coordinates of [`lobe_coordinates`]. The kink where ωo·h = 0 is kept off
/// the nodes: φ runs over the visible arc only, and ψ is split where that arc starts to shrink
/// (θh = π/2 − θo).
pub(crate) fn visible_normals(
    alpha: f64,
    wo: DVec3,
    panels: usize,
    mut visit: impl FnMut(DVec3, f64),
) {
    let (sin_o, cos_o) = ((1.0 - wo.z * wo.z).max(0.0).sqrt(), wo.z);
    let phi_o = wo.y.atan2(wo.x);
    let psi_split = cos_o.atan2(alpha * sin_o);
    for (from, to) in [(0.0, psi_split), (psi_split, FRAC_PI_2)] {
        if to <= from {
            continue;
        }
        for (psi, w_psi) in composite(from, to, panels) {
            let (h, _) = lobe_coordinates(alpha, psi, 0.0);
            let (cos_h, sin_h) = (h.z, h.x);
            // Visible where cos(φ − φo) ≥ −cot θo cot θh.
            let half_width = if sin_o * sin_h > 0.0 {
                (-(cos_o * cos_h) / (sin_o * sin_h)).max(-1.0).acos()
            } else {
                PI
            };
            for (phi, w_phi) in composite(phi_o - half_width, phi_o + half_width, 4) {
                let (h, jacobian) = lobe_coordinates(alpha, psi, phi);
                visit(h, w_psi * w_phi * jacobian);
            }
        }
    }
}

/// ∫ G1(ωo) max(0, ωo·h) D(h) dωh with G1 and D read back from the plugin.
fn visible_projected_area(plugin: &Readback, alpha: f64, wo: DVec3, panels: usize) -> f64 {
    let g1 = plugin.g1(wo.as_vec3());
    let mut sum = 0.0;
    visible_normals(alpha, wo, panels, |h, dh| {
        sum += dh * g1 * wo.dot(h).max(0.0) * plugin.d(h.as_vec3());
    });
    sum
}

#[test]
fn visible_normals_are_normalised() {
    for alpha32 in ROUGHNESS {
        let alpha = alpha32 as f64;
        let plugin = Readback::new(alpha32);
        for cos_o in COS_O {
            let wo = direction(cos_o, 0.7).as_vec3().as_dvec3();
            let q = Quadrature::refined(
                |panels| visible_projected_area(&plugin, alpha, wo, panels),
                16,
            );
            eprintln!(
                "α = {alpha32}, cos θo = {cos_o}: ∫ G1 (ωo·h)⁺ D dωh / cos θo = {:.9} (quadrature error {:.1e})",
                q.value / wo.z,
                q.error / wo.z
            );
            assert!(
                (q.value - wo.z).abs() <= tolerance(q, wo.z),
                "α = {alpha32}, cos θo = {cos_o}: ∫ G1 (ωo·h)⁺ D dωh = {} ± {:.1e}, expected {}",
                q.value,
                q.error,
                wo.z
            );
        }
    }
}

/// f(ωo, ωi) = f(ωi, ωo), with Fresnel below 1 and the diffuse base, at angles down to grazing.
#[test]
fn eval_is_reciprocal_down_to_grazing_angles() {
    for alpha in [1e-3f32, 0.1, 0.6] {
        let b = bsdf(
            "glossy",
            &format!("\"roughness\": {alpha}, \"specular\": (0.9, 0.5, 0.04), \"diffuse\": 0.4"),
        );
        for (wo, wi) in chosen_pairs(alpha as f64) {
            let forward = b.eval(&FRONT, wo, wi) / wi.z;
            let backward = b.eval(&FRONT, wi, wo) / wo.z;
            // Fresnel reads cos θd as ωo·h one way and ωi·h the other: for f32 vectors of norm
            // 1 ± ε they differ by about ε / |ωo + ωi|, which grazing mirror pairs amplify.
            let tolerance = 2.0 * POINTWISE * (1.0 + 2.0 / (wo + wi).length() as f64);
            for c in 0..3 {
                assert!(
                    relative(forward[c] as f64, backward[c] as f64) <= tolerance,
                    "α = {alpha}, ωo = {wo}, ωi = {wi}: f = {forward} one way, {backward} the other"
                );
            }
        }
    }
}

#[test]
fn gauss_legendre_integrates_polynomials_exactly() {
    // An n-point rule is exact up to degree 2n − 1.
    for n in [1, 2, 5, 8] {
        for degree in 0..2 * n {
            let sum: f64 = gauss_legendre(n)
                .iter()
                .map(|&(x, w)| w * x.powi(degree as i32))
                .sum();
            let exact = if degree % 2 == 0 {
                2.0 / (degree + 1) as f64
            } else {
                0.0
            };
            assert!((sum - exact).abs() < 1e-13, "n = {n}, x^{degree}: {sum}");
        }
    }
    let sum: f64 = composite(0.0, PI, 3)
        .iter()
        .map(|&(x, w)| w * x.sin())
        .sum();
    assert!((sum - 2.0).abs() < 1e-12, "{sum}");
}

// Directional albedo ρ(ωo) = ∫ eval(ωo, ωi) dωi, by deterministic quadrature of `eval`.

/// ∫ g(ωi) dωi over the upper hemisphere, in (cos θi, φi) where dω = d cos θ dφ: for integrands
/// that are smooth there (the diffuse terms, and the measured table's moderate lobe).
fn hemisphere(g: &impl Fn(Vec3) -> DVec3, panels: usize) -> DVec3 {
    let phi_rule = composite(0.0, TAU, 2 * panels);
    let mut sum = DVec3::ZERO;
    for (mu, w_mu) in composite(0.0, 1.0, panels) {
        for &(phi, w_phi) in &phi_rule {
            sum += w_mu * w_phi * g(direction(mu, phi).as_vec3());
        }
    }
    sum
}

/// ∫ g(ωi) dωi for a lobe of GGX width α about the mirror direction of ωo, over the half vectors
/// h of [`visible_normals`], ωi = reflect(ωo, h), dωi = 4 (ωo·h) dωh.
fn lobe(g: &impl Fn(Vec3) -> DVec3, alpha: f64, wo: Vec3, panels: usize) -> DVec3 {
    let o = wo.as_dvec3();
    let mut sum = DVec3::ZERO;
    visible_normals(alpha, o, panels, |h, dh| {
        let wi = reflect(o, h);
        if wi.z > 0.0 {
            sum += dh * 4.0 * o.dot(h) * g(wi.as_vec3());
        }
    });
    sum
}

/// An RGB integral by quadrature with its error per channel, as [`Quadrature::refined`].
#[derive(Clone, Copy, Debug)]
struct Rgb64 {
    value: DVec3,
    error: DVec3,
}

fn refined_rgb(rule: impl Fn(usize) -> DVec3, panels: usize) -> Rgb64 {
    let coarse = rule(panels);
    let fine = rule(2 * panels);
    Rgb64 {
        value: fine,
        error: (fine - coarse).abs(),
    }
}

fn eval64(b: &dyn Bsdf, wo: Vec3, wi: Vec3) -> DVec3 {
    b.eval(&FRONT, wo, wi).as_dvec3()
}

/// Schlick's Fresnel, written from the definition: F0 + (1 − F0)(1 − cos θd)⁵.
fn schlick(f0: DVec3, cos: f64) -> DVec3 {
    f0 + (DVec3::ONE - f0) * (1.0 - cos).clamp(0.0, 1.0).powi(5)
}

/// The albedo of `glossy` by quadrature of its `eval`: the specular lobe in half-vector
/// coordinates, the diffuse base (the difference with the same BSDF without it) over the
/// hemisphere.
fn glossy_albedo(alpha: f32, specular: &str, diffuse: &str, wo: Vec3) -> Rgb64 {
    let params = format!("\"roughness\": {alpha}, \"specular\": {specular}");
    let bare = bsdf("glossy", &params);
    let based = bsdf("glossy", &format!("{params}, \"diffuse\": {diffuse}"));
    let spec = refined_rgb(
        |n| lobe(&|wi| eval64(bare.as_ref(), wo, wi), alpha as f64, wo, n),
        16,
    );
    let base = refined_rgb(
        |n| {
            hemisphere(
                &|wi| eval64(based.as_ref(), wo, wi) - eval64(bare.as_ref(), wo, wi),
                n,
            )
        },
        4,
    );
    Rgb64 {
        value: spec.value + base.value,
        error: spec.error + base.error,
    }
}

#[test]
fn diffuse_albedo_is_its_reflectance() {
    let b = bsdf("diffuse", "\"reflectance\": (0.9, 0.5, 0.1)");
    for cos_o in COS_O {
        let wo = direction(cos_o, 0.3).as_vec3();
        let q = refined_rgb(|n| hemisphere(&|wi| eval64(b.as_ref(), wo, wi), n), 4);
        let expected = DVec3::new(0.9, 0.5, 0.1).as_vec3().as_dvec3();
        let tolerance = 4.0 * q.error + POINTWISE * expected;
        assert!(
            (q.value - expected).abs().cmple(tolerance).all(),
            "cos θo = {cos_o}: ρ = {} ± {}, expected {expected}",
            q.value,
            q.error
        );
    }
}

/// The diffuse base (Ashikhmin–Shirley's, weighted by 1 − max F0) reflects
/// d (1 − max F0)(1 − (1 − cos θo / 2)⁵): its 28/(23π) normalisation makes the integral over
/// ωi of (1 − (1 − cos θi / 2)⁵) cos θi exactly 23π/28.
#[test]
fn glossy_base_albedo_is_its_closed_form() {
    let d = DVec3::new(0.9, 0.5, 0.1);
    let f0 = 0.3f32;
    for cos_o in COS_O {
        let wo = direction(cos_o, 0.3).as_vec3();
        let mu = wo.z as f64;
        let params = format!("\"roughness\": 0.3, \"specular\": {f0}");
        let bare = bsdf("glossy", &params);
        let based = bsdf("glossy", &format!("{params}, \"diffuse\": (0.9, 0.5, 0.1)"));
        let q = refined_rgb(
            |n| {
                hemisphere(
                    &|wi| eval64(based.as_ref(), wo, wi) - eval64(bare.as_ref(), wo, wi),
                    n,
                )
            },
            4,
        );
        let expected = d * (1.0 - f0 as f64) * (1.0 - (1.0 - mu / 2.0).powi(5));
        // The specular parts cancel node by node up to their f32 rounding (albedo ≤ 1).
        let tolerance = 4.0 * q.error + DVec3::splat(2.0 * POINTWISE);
        assert!(
            (q.value - expected).abs().cmple(tolerance).all(),
            "cos θo = {cos_o}: base albedo {} ± {}, closed form {expected}",
            q.value,
            q.error
        );
    }
}

/// The specular lobe's albedo by quadrature of the plugin's `eval` and of the closed forms
/// (with Schlick's Fresnel), over every roughness and incidence down to grazing: they agree to
/// the plugin's f32 rounding, and a smooth lossless lobe reflects everything.
#[test]
fn glossy_specular_albedo_matches_the_closed_forms() {
    let f0_rgb = DVec3::new(0.9, 0.5, 0.04).as_vec3().as_dvec3();
    for alpha32 in ROUGHNESS {
        let reference = Reference {
            alpha: alpha32 as f64,
        };
        for (specular, f0) in [("1", DVec3::ONE), ("(0.9, 0.5, 0.04)", f0_rgb)] {
            let b = bsdf(
                "glossy",
                &format!("\"roughness\": {alpha32}, \"specular\": {specular}"),
            );
            for cos_o in COS_O {
                let wo = direction(cos_o, 0.3).as_vec3();
                let o = wo.as_dvec3();
                let plugin = lobe(&|wi| eval64(b.as_ref(), wo, wi), alpha32 as f64, wo, 32);
                let closed = lobe(
                    &|wi| {
                        let i = wi.as_dvec3();
                        reference.eval(o, i) * schlick(f0, o.dot((o + i).normalize()))
                    },
                    alpha32 as f64,
                    wo,
                    32,
                );
                assert!(
                    (plugin - closed)
                        .abs()
                        .cmple(2.0 * POINTWISE * closed)
                        .all(),
                    "α = {alpha32}, F0 = {specular}, cos θo = {cos_o}: ρ = {plugin}, closed forms {closed}"
                );
                if specular == "1" && cos_o == 1.0 {
                    eprintln!(
                        "α = {alpha32}: albedo at normal incidence, F0 = 1: {:.6}",
                        closed.x
                    );
                }
            }
        }
    }
    // α = 1 makes D = 1/π, and at normal incidence G2 = G1(ωi) = 2 cos θi / (1 + cos θi): the
    // albedo is ∫₀¹ μ / (1 + μ) dμ = 1 − ln 2.
    let b = bsdf("glossy", "\"roughness\": 1, \"specular\": 1");
    let rho = refined_rgb(
        |n| lobe(&|wi| eval64(b.as_ref(), Vec3::Z, wi), 1.0, Vec3::Z, n),
        16,
    );
    let expected = 1.0 - 2f64.ln();
    assert!(
        (rho.value.x - expected).abs() <= 4.0 * rho.error.x + POINTWISE * expected,
        "α = 1: albedo at normal incidence {} ± {}, expected 1 − ln 2",
        rho.value.x,
        rho.error.x
    );
    // A near-mirror (α = 1e-4) reflects all at normal incidence: G2 = 1 − O(α²).
    let b = bsdf("glossy", "\"roughness\": 0.0001, \"specular\": 1");
    let rho = refined_rgb(
        |n| lobe(&|wi| eval64(b.as_ref(), Vec3::Z, wi), 1e-4, Vec3::Z, n),
        16,
    );
    assert!(
        (rho.value.x - 1.0).abs() <= 4.0 * rho.error.x + 1e-6,
        "smooth lossless albedo {} ± {}",
        rho.value.x,
        rho.error.x
    );
}

/// Mean and standard error of the sample weights (per channel) for `samples` samples.
fn sampled_albedo(b: &dyn Bsdf, wo: Vec3, samples: usize, stream: u64) -> (DVec3, DVec3) {
    let mut s = test_sampler(stream);
    let (mut sum, mut sum2) = (DVec3::ZERO, DVec3::ZERO);
    for _ in 0..samples {
        let u_lobe = s.next_1d();
        let w = b
            .sample(&FRONT, wo, u_lobe, s.next_2d())
            .map_or(DVec3::ZERO, |smp| smp.weight.as_dvec3());
        sum += w;
        sum2 += w * w;
    }
    let n = samples as f64;
    let mean = sum / n;
    let variance = (sum2 / n - mean * mean).max(DVec3::ZERO);
    (mean, (variance / n).map(f64::sqrt))
}

/// The two-sided white furnace: the mean sample weight of `sample` equals the albedo integrated
/// from `eval` by quadrature, within a z-test corrected for the family (Šidák) whose σ combines
/// the Monte Carlo error and the quadrature's. Catches samplers whose density disagrees with
/// `pdf` where it matters, or weights not eval/pdf — in either direction, unlike the one-sided
/// "albedo ≤ 1".
#[test]
fn sampled_albedo_matches_quadrature() {
    let mut cases: Vec<(String, Arc<dyn Bsdf>, Vec3, Rgb64)> = Vec::new();
    for cos_o in [1.0, 0.5, 0.1, 1e-2] {
        let wo = direction(cos_o, 0.3).as_vec3();
        let diffuse = bsdf("diffuse", "\"reflectance\": (0.9, 0.5, 0.1)");
        let exact = DVec3::new(0.9, 0.5, 0.1).as_vec3().as_dvec3();
        cases.push((
            format!("diffuse cos θo = {cos_o}"),
            diffuse,
            wo,
            Rgb64 {
                value: exact,
                error: DVec3::ZERO,
            },
        ));
        for alpha in [1e-3f32, 0.1, 0.5, 1.0] {
            for (specular, diffuse) in [("1", "0"), ("(0.9, 0.5, 0.04)", "(0.2, 0.5, 0.8)")] {
                let b = bsdf(
                    "glossy",
                    &format!(
                        "\"roughness\": {alpha}, \"specular\": {specular}, \"diffuse\": {diffuse}"
                    ),
                );
                cases.push((
                    format!(
                        "glossy α = {alpha}, F0 = {specular}, base {diffuse}, cos θo = {cos_o}"
                    ),
                    b,
                    wo,
                    glossy_albedo(alpha, specular, diffuse, wo),
                ));
            }
        }
    }
    let z = z_limit(sidak(FAMILY_FALSE_ALARM, 3 * cases.len()));
    for (k, (name, b, wo, q)) in cases.iter().enumerate() {
        let (mean, se) = sampled_albedo(b.as_ref(), *wo, 200_000, k as u64);
        for c in 0..3 {
            let sigma = (se[c] * se[c] + q.error[c] * q.error[c]).sqrt();
            assert!(
                (mean[c] - q.value[c]).abs() <= z * sigma + POINTWISE * q.value[c],
                "{name}, channel {c}: sampled {} ± {}, quadrature {} ± {} (|z| > {z:.2}, seed {})",
                mean[c],
                se[c],
                q.value[c],
                q.error[c],
                test_seed()
            );
        }
    }
}

/// The analytic BRDF the measured plugin's test table is generated from.
const MERL_SOURCE: &str = "\"roughness\": 0.25, \"specular\": (0.9, 0.6, 0.3), \"diffuse\": 0.3";

/// The `measured` plugin read from a MERL file tabulating `source`, written into a temporary
/// directory that is removed before returning (the plugin holds the table in memory).
fn measured_from(source: &dyn Bsdf) -> Arc<dyn Bsdf> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("source.binary");
    lumis_bsdfs::measured::write_merl(&path, |wi, wo| source.eval(&FRONT, wo, wi) / wi.z).unwrap();
    bsdf(
        "measured",
        &format!("\"file\": {:?}", path.to_str().unwrap()),
    )
}

/// The measured BRDF's albedo, by quadrature of its `eval`, is that of the analytic BRDF its table
/// was generated from, to the table's interpolation error; and its mean sample weight matches
/// the quadrature (the two-sided furnace of [`sampled_albedo_matches_quadrature`]).
#[test]
fn measured_albedo_matches_its_source_and_its_samples() {
    let source = bsdf("glossy", MERL_SOURCE);
    let measured = measured_from(source.as_ref());
    let cases = [1.0, 0.7, 0.3, 0.1];
    let z = z_limit(sidak(FAMILY_FALSE_ALARM, 3 * cases.len()));
    for (k, cos_o) in cases.into_iter().enumerate() {
        let wo = direction(cos_o, 0.0).as_vec3();
        let of = |b: &Arc<dyn Bsdf>| {
            refined_rgb(|n| hemisphere(&|wi| eval64(b.as_ref(), wo, wi), n), 32)
        };
        let (table, analytic) = (of(&measured), of(&source));
        eprintln!(
            "cos θo = {cos_o}: measured albedo {:.5} ± {:.1e}, source {:.5} ± {:.1e}",
            table.value,
            table.error.max_element(),
            analytic.value,
            analytic.error.max_element()
        );
        // Trilinear interpolation of a 90 × 90 × 180 table of a lobe of α = 0.25 moves the
        // albedo by 0.05 % (normal incidence) to 0.3 % (cos θo = 0.1); 1 % still catches a
        // channel's scale (15 %) or a misplaced lobe.
        let interpolation = 0.01 * analytic.value;
        assert!(
            (table.value - analytic.value)
                .abs()
                .cmple(interpolation + 4.0 * (table.error + analytic.error))
                .all(),
            "cos θo = {cos_o}: measured albedo {} ± {}, source {} ± {}",
            table.value,
            table.error,
            analytic.value,
            analytic.error
        );
        let (mean, se) = sampled_albedo(measured.as_ref(), wo, 200_000, 100 + k as u64);
        for c in 0..3 {
            let sigma = (se[c] * se[c] + table.error[c] * table.error[c]).sqrt();
            assert!(
                (mean[c] - table.value[c]).abs() <= z * sigma + POINTWISE * table.value[c],
                "cos θo = {cos_o}, channel {c}: sampled {} ± {}, quadrature {} ± {} (seed {})",
                mean[c],
                se[c],
                table.value[c],
                table.error[c],
                test_seed()
            );
        }
    }
}

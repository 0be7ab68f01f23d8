//! `roughplastic`: a rough dielectric coating over a diffuse base (Mitsuba 3's
//! `roughplastic`): microfacet reflection at the coating (GGX or Beckmann), and the light the
//! rough interface transmits reflected by the base, scattered inside and transmitted back out.
//!
//! Parameters:
//! - `distribution` (choice, default `beckmann`, or `ggx`): the coating's microfacet
//!   distribution (Mitsuba's default is Beckmann).
//! - `alpha` (float, default 0.1, in [0, 10]): its roughness α, one value (the transmittance
//!   table depends on it, as in Mitsuba, where it cannot be a texture either); below 10⁻⁴ used
//!   as 10⁻⁴.
//! - `int_ior` (float, default 1.49, in [0.01, 10]): the index of refraction of the coating.
//! - `ext_ior` (float, default 1.000277, in [0.01, 10]): the index outside; it must differ from
//!   `int_ior`.
//! - `diffuse_reflectance` (rgb or texture, default (0.5, 0.5, 0.5), in [0, 1]): as `plastic`'s.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): as `plastic`'s.
//! - `nonlinear` (bool, default false): as `plastic`'s.
//!
//! With η = int_ior / ext_ior: f(ωo, ωi) cos θi = specular_reflectance · F(ωo·h) D(h) G1(ωo)
//! G1(ωi) / (4 cos θo) + R / (1 − F_dr) · (1/η²) T(cos θo) T(cos θi) cos θi / π, where T(μ) is
//! the fraction of light arriving at cos θ = μ that the rough interface transmits and F_dr the
//! fraction of diffuse light inside that it reflects back (nonlinear: R / (1 − R F_dr)). Both
//! are computed when the BSDF is built, as Mitsuba computes them: T at 64 cosines evenly spaced
//! in [0, 1] (interpolated linearly between them), each the mean over visible normals m of
//! G1(ωt, m)(1 − F(ωo·m)) with ωt refracted about m, by a 32 × 32 Gauss–Legendre rule in the
//! sampling's random numbers (128 × 128 for η < 1); F_dr = 2 ∫ R(μ) μ dμ as the mean over the
//! same 64 cosines of 2 μ R(μ), R(μ) the reflectance at 1/η by the same rule (128 × 128 for
//! 1/η < 1). Sampling: the specular lobe by visible normals with probability
//! (1 − T(cos θo)) w / ((1 − T(cos θo)) w + T(cos θo)(1 − w)) (w as `plastic`'s), else the
//! cosine-weighted hemisphere; `pdf` is exactly that mixture. Reflection only; Mitsuba's is
//! one-sided, which a scene asks for with `one_sided: true` (the importer writes it).

use crate::fresnel;
use crate::microfacet::{Beckmann, Distribution, Ggx, MIN_ALPHA, Masking, Microfacet, reflect};
use crate::plastic::{
    DIFFUSE_REFLECTANCE, DIFFUSE_REFLECTANCE_SPEC, EXT_IOR_SPEC, INT_IOR_SPEC, NONLINEAR,
    NONLINEAR_SPEC, Reflectances, SPECULAR_REFLECTANCE, SPECULAR_REFLECTANCE_SPEC,
    internal_scattering, read_eta, specular_weight,
};
use crate::roughconductor::{DISTRIBUTION, DISTRIBUTION_SPEC, GGX};
use glam::Vec3;
use lumis_core::bsdf::{Bsdf, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSampleLanes};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, Mask, V3};
use lumis_core::math::warp::{cosine_hemisphere_pdf_lanes, square_to_cosine_hemisphere_lanes};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::marker::PhantomData;
use std::sync::Arc;

/// The number of cosines at which the transmittance T(μ) is tabulated (Mitsuba's).
pub const TABLE_SIZE: usize = 64;

/// A rough plastic of distribution `D`.
pub struct RoughPlastic<D> {
    alpha: f32,
    eta: f32,
    inv_eta2: f32,
    tables: CoatingTables,
    specular_weight: f32,
    nonlinear: bool,
    diffuse: Textured<Rgb>,
    specular: Textured<Rgb>,
    distribution: PhantomData<D>,
}

/// What the rough coating's interface does to light, computed once per BSDF.
#[derive(Clone, Debug)]
pub struct CoatingTables {
    /// T(μ) at μ = max(10⁻⁶, i / 63).
    pub transmittance: [f32; TABLE_SIZE],
    /// F_dr: the fraction of diffuse light inside the coating that its interface reflects.
    pub internal_reflectance: f32,
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on the Legendre polynomial).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut rule = vec![(0.0, 0.0); n];
    for i in 0..n.div_ceil(2) {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut derivative = 1.0;
        for _ in 0..100 {
            let (mut previous, mut p) = (1.0, x);
            for k in 2..=n {
                let next = ((2 * k - 1) as f64 * x * p - (k - 1) as f64 * previous) / k as f64;
                previous = p;
                p = next;
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

/// G1(ω) with Mitsuba's side test: zero where ω sees the back of the microfacet m.
#[inline(always)]
fn g1_facing<D: Distribution>(m: &Microfacet<D, f32>, w: Vec3, normal: Vec3) -> f32 {
    if w.dot(normal) * w.z <= 0.0 {
        0.0
    } else {
        m.g1(V3::splat(w))
    }
}

/// Σ over a tensor-product Gauss–Legendre rule (n × n, on the unit square) of `f(u)` times the
/// weights, i.e. the mean of `f` over the square.
fn square_mean(rule: &[(f64, f64)], mut f: impl FnMut(f32, f32) -> f32) -> f64 {
    let mut sum = 0.0;
    for &(y, wy) in rule {
        for &(x, wx) in rule {
            let u = ((0.5 * x + 0.5) as f32, (0.5 * y + 0.5) as f32);
            sum += f(u.0, u.1) as f64 * wx * wy * 0.25;
        }
    }
    sum
}

impl CoatingTables {
    /// The tables of an interface of distribution `D`, roughness `alpha` and relative index
    /// `eta` (see the module's documentation).
    pub fn new<D: Distribution>(alpha: f32, eta: f32) -> Self {
        let m = Microfacet::<D, f32>::constant(alpha);
        let cosines: Vec<f32> = (0..TABLE_SIZE)
            .map(|i| (i as f32 / (TABLE_SIZE - 1) as f32).max(1e-6))
            .collect();
        let direction = |mu: f32| Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let transmission_rule = gauss_legendre(if eta > 1.0 { 32 } else { 128 });
        let mut transmittance = [0.0; TABLE_SIZE];
        for (t, &mu) in transmittance.iter_mut().zip(&cosines) {
            let wi = direction(mu);
            *t = square_mean(&transmission_rule, |u0, u1| {
                let normal = m.sample_visible_normal(V3::splat(wi), (u0, u1)).lane(0);
                let cos = wi.dot(normal);
                let (f, cos_t, _, eta_ti) = fresnel::dielectric(cos, eta);
                let wt = normal * (cos * eta_ti + cos_t) - wi * eta_ti;
                if wt.z * wi.z >= 0.0 {
                    return 0.0;
                }
                g1_facing(&m, wt, normal) * (1.0 - f)
            }) as f32;
        }
        let inside = 1.0 / eta;
        let reflection_rule = gauss_legendre(if inside > 1.0 { 32 } else { 128 });
        let mut sum = 0.0;
        for &mu in &cosines {
            let wi = direction(mu);
            let reflectance = square_mean(&reflection_rule, |u0, u1| {
                let normal = m.sample_visible_normal(V3::splat(wi), (u0, u1)).lane(0);
                let wr = reflect::<f32>(V3::splat(wi), V3::splat(normal)).lane(0);
                if wr.z <= 0.0 {
                    return 0.0;
                }
                let f = fresnel::dielectric(wi.dot(normal), inside).0;
                g1_facing(&m, wr, normal) * f
            });
            sum += reflectance * mu as f64;
        }
        CoatingTables {
            transmittance,
            internal_reflectance: (2.0 * sum / TABLE_SIZE as f64) as f32,
        }
    }

    /// T(μ), linear between the table's cosines.
    #[inline(always)]
    pub fn transmittance<L: Lanes>(&self, mu: L) -> L {
        L::from_fn(
            #[inline(always)]
            |i| {
                let x = mu.lane(i).clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
                let index = (x as usize).min(TABLE_SIZE - 2);
                let (a, b) = (self.transmittance[index], self.transmittance[index + 1]);
                let t = x - index as f32;
                a + (b - a) * t
            },
        )
    }
}

impl<D: Distribution> RoughPlastic<D> {
    /// The probability of the specular lobe, given T(cos θo).
    #[inline(always)]
    fn specular_probability<L: Lanes>(&self, t_o: L) -> L {
        let one = L::splat(1.0);
        let w = L::splat(self.specular_weight);
        let specular = (one - t_o) * w;
        let diffuse = t_o * (one - w);
        specular / (specular + diffuse)
    }
}

impl<D: Distribution> BsdfLanes for RoughPlastic<D> {
    type Params<L: Lanes> = Reflectances<L>;

    fn bsdf_flags(&self) -> BsdfFlags {
        let varying = self.diffuse.varies() || self.specular.varies();
        BsdfFlags::GLOSSY_REFLECTION
            | BsdfFlags::DIFFUSE_REFLECTION
            | if varying {
                BsdfFlags::SPATIALLY_VARYING
            } else {
                BsdfFlags::NONE
            }
    }

    #[inline(always)]
    fn params_lanes<L: Lanes>(&self, ctx: &BsdfContextLanes<L>) -> Reflectances<L> {
        Reflectances {
            diffuse: self.diffuse.at(ctx.uv),
            specular: self.specular.at(ctx.uv),
        }
    }

    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        p: &Reflectances<L>,
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let below = wo.z.le(zero) | wi.z.le(zero);
        let m = Microfacet::<D, L>::constant(self.alpha);
        let h = (wo + wi).normalize_or_zero();
        let cos_h = wo.dot(h);
        let (d, lambda_o) = (m.d(h), m.lambda(wo));
        let g2 = Masking::Separable.g2(lambda_o, m.lambda(wi));
        let f = fresnel::dielectric(cos_h, L::splat(self.eta)).0;
        let specular = p.specular * (f * d * g2 / (L::splat(4.0) * wo.z));
        let specular = V3::select(specular.is_finite() & cos_h.gt(zero), specular, V3::zero());
        let (t_o, t_i) = (
            self.tables.transmittance(wo.z),
            self.tables.transmittance(wi.z),
        );
        let cosine = cosine_hemisphere_pdf_lanes(wi.z);
        let base = internal_scattering(p.diffuse, self.tables.internal_reflectance, self.nonlinear);
        let diffuse = base * (cosine * L::splat(self.inv_eta2) * t_o * t_i);
        let probability = self.specular_probability(t_o);
        let specular_pdf = L::select(
            cos_h.gt(zero),
            Microfacet::<D, L>::reflection_pdf(wo, d, lambda_o),
            zero,
        );
        let pdf = probability * specular_pdf + (one - probability) * cosine;
        (
            V3::select(below, V3::zero(), specular + diffuse),
            L::select(below, zero, pdf),
        )
    }

    /// The specular lobe by visible normals or the base by the cosine, then the value and
    /// density from `eval_pdf` (as [`lumis_core::bsdf::sample_from_pdf`]).
    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        p: &Reflectances<L>,
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        u_lobe: L,
        u: (L, L),
    ) -> BsdfSampleLanes<L> {
        let m = Microfacet::<D, L>::constant(self.alpha);
        let probability = self.specular_probability(self.tables.transmittance(wo.z));
        let specular = u_lobe.lt(probability);
        let wi = if specular.all() {
            reflect(wo, m.sample_visible_normal(wo, u))
        } else if !specular.any() {
            square_to_cosine_hemisphere_lanes(u.0, u.1)
        } else {
            V3::select(
                specular,
                reflect(wo, m.sample_visible_normal(wo, u)),
                square_to_cosine_hemisphere_lanes(u.0, u.1),
            )
        };
        let above = !wo.z.le(L::splat(0.0));
        BsdfSampleLanes::from_pdf(above, wi, self.eval_pdf_lanes(p, ctx, wo, wi))
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "roughplastic";
pub const ALPHA: &str = "alpha";
pub use crate::plastic::{EXT_IOR, INT_IOR};

static PARAMS: &[ParamSpec] = &[
    DISTRIBUTION_SPEC,
    ParamSpec {
        name: ALPHA,
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 0.0,
            max: 10.0,
        },
        unit: "",
        description: "roughness α of the coating (below 1e-4 used as 1e-4)",
    },
    INT_IOR_SPEC,
    EXT_IOR_SPEC,
    DIFFUSE_REFLECTANCE_SPEC,
    SPECULAR_REFLECTANCE_SPEC,
    NONLINEAR_SPEC,
];

fn build<D: Distribution>(
    alpha: f32,
    eta: f32,
    diffuse: Textured<Rgb>,
    specular: Textured<Rgb>,
    nonlinear: bool,
) -> Arc<dyn Bsdf> {
    Arc::new(RoughPlastic::<D> {
        alpha,
        eta,
        inv_eta2: 1.0 / (eta * eta),
        tables: CoatingTables::new::<D>(alpha, eta),
        specular_weight: specular_weight(&diffuse, &specular),
        nonlinear,
        diffuse,
        specular,
        distribution: PhantomData,
    })
}

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let distribution = params.choice(DISTRIBUTION)?;
    let alpha = params.float(ALPHA)?.max(MIN_ALPHA);
    let eta = read_eta(params)?;
    if eta == 1.0 {
        return Err(PluginError::Invalid(format!(
            "{}: `{INT_IOR}` and `{EXT_IOR}` must differ (a coating of the same index reflects \
             nothing; use `diffuse`)",
            params.plugin()
        )));
    }
    let diffuse = params.rgb_or_texture(DIFFUSE_REFLECTANCE)?;
    let specular = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    let nonlinear = params.bool(NONLINEAR)?;
    Ok(if distribution == GGX {
        build::<Ggx>(alpha, eta, diffuse, specular, nonlinear)
    } else {
        build::<Beckmann>(alpha, eta, diffuse, specular, nonlinear)
    })
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "rough plastic: a rough dielectric coating (Beckmann or GGX) over a diffuse base, Mitsuba's model",
        params: PARAMS,
        create,
    }
}

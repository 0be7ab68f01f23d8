//! `roughdielectric`: a rough interface between two dielectrics (frosted glass), Mitsuba 3's
//! `roughdielectric`: the microfacet model of Walter et al. 2007, reflection and refraction
//! through microfacets of a GGX or Beckmann distribution (`microfacet.rs`), normals sampled
//! among those visible from ωo.
//!
//! Parameters:
//! - `int_ior` (float or name, default 1.5046, bk7): index of refraction inside, on the side
//!   the surface's normal points away from; a number in [1e-6, 1e6] or one of Mitsuba's
//!   material names (`fresnel.rs`).
//! - `ext_ior` (float or name, default 1.000277, air): index of refraction outside.
//! - `distribution` (choice, default "beckmann"): "beckmann" or "ggx".
//! - `alpha` (float, default 0.1, in [0, 4]): roughness α, the distribution's width (clamped
//!   to at least 1e-4, as Mitsuba does).
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   reflected light (1 for physical realism).
//! - `specular_transmittance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   transmitted light (1 for physical realism).
//!
//! With η the relative index seen from ωo (int_ior / ext_ior from outside, the context's side
//! `Front`; its reciprocal from inside), the generalised half vector m = ±normalize(ωo + η' ωi)
//! (η' = 1 for a reflection, η for a refraction; m turned to the viewer's side), F = F(ωo·m, η)
//! the Fresnel reflectance, D the distribution and G = G1(ωo) G1(ωi) Smith's separable
//! masking (Mitsuba's):
//! - reflection: f cos θi = F D G / (4 cos θo);
//! - refraction: f cos θi = (1 − F) D G |ωo·m| |ωi·m| / (cos θo (ωo·m + η ωi·m)²), the η² of
//!   Walter's BTDF cancelled by the 1/η² of radiance crossing the interface (core's `bsdf`).
//!
//! `sample` draws m from the normals visible from ωo (density G1(ωo) (ωo·m) D(m) / cos θo),
//! reflects with probability F and refracts otherwise, so that
//! pdf = D_ωo(m) · F / (4 ωi·m) for a reflection and D_ωo(m) · (1 − F) η² |ωi·m| / (ωo·m + η
//! ωi·m)² for a refraction, and the weight is G1(ωi) (times 1/η² refracted). Microfacets whose
//! side disagrees with ωo's or ωi's contribute nothing, as in Mitsuba.

use crate::dielectric::{
    SPECULAR_REFLECTANCE, SPECULAR_REFLECTANCE_SPEC, SPECULAR_TRANSMITTANCE,
    SPECULAR_TRANSMITTANCE_SPEC,
};
use crate::ior::{self, EXT_IOR_SPEC, INT_IOR_SPEC, eta_seen_from};
use crate::microfacet::{Beckmann, Distribution, Ggx, MIN_ALPHA, Microfacet, reflect};
use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::V3;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::sync::Arc;

/// A rough dielectric interface of relative index `eta` (inside over outside), microfacet
/// distribution `D`.
pub struct RoughDielectric<D> {
    eta: f32,
    distribution: Microfacet<D, f32>,
    reflectance: Textured<Rgb>,
    transmittance: Textured<Rgb>,
}

/// What `eval` and `pdf` share for one pair of directions: the half vector and the factors of
/// the lobe the pair belongs to.
struct Pair {
    /// Unit, on the viewer's side (m.z > 0).
    m: Vec3,
    /// A reflection (ωi on ωo's side), else a refraction.
    reflected: bool,
    /// The relative index seen from ωo.
    eta: f32,
    /// F(ωo·m).
    fresnel: f32,
}

impl<D: Distribution> RoughDielectric<D> {
    pub fn new(
        eta: f32,
        alpha: f32,
        reflectance: Textured<Rgb>,
        transmittance: Textured<Rgb>,
    ) -> Self {
        RoughDielectric {
            eta,
            distribution: Microfacet::constant(alpha.max(MIN_ALPHA)),
            reflectance,
            transmittance,
        }
    }

    /// The pair's half vector and lobe, or `None` where it has no value: ωo below the horizon,
    /// ωi on the horizon, no half vector (ωi = −ωo across an index-matched interface), or a
    /// microfacet facing away from ωo or ωi.
    fn pair(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Option<Pair> {
        if wo.z <= 0.0 || !wo.is_finite() || wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let reflected = wi.z > 0.0;
        let eta = eta_seen_from(ctx.side, self.eta);
        let m = if reflected { wo + wi } else { wo + wi * eta };
        let m = m.normalize_or_zero();
        let m = if m.z < 0.0 { -m } else { m };
        if m.z == 0.0 || wo.dot(m) <= 0.0 || wi.dot(m) * wi.z <= 0.0 {
            return None;
        }
        let (fresnel, _) = ior::fresnel(wo.dot(m), eta);
        Some(Pair {
            m,
            reflected,
            eta,
            fresnel,
        })
    }

    /// f cos θi and the density of `pair`.
    fn value_and_density(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3, pair: &Pair) -> (Rgb, f32) {
        let d = &self.distribution;
        let (m, lm) = (pair.m, V3::<f32>::splat(pair.m));
        let (lo, li) = (V3::<f32>::splat(wo), V3::<f32>::splat(wi));
        let density_m = d.visible_normal_pdf(lo, lm);
        let g = d.g1(lo) * d.g1(li);
        let dm = d.d(lm);
        let (value, pdf) = if pair.reflected {
            let value = pair.fresnel * dm * g / (4.0 * wo.z);
            let pdf = density_m * pair.fresnel / (4.0 * wi.dot(m));
            (self.reflectance.value_at(ctx.uv) * value, pdf)
        } else {
            let (o_m, i_m) = (wo.dot(m), wi.dot(m));
            let denominator = o_m + pair.eta * i_m;
            let denominator2 = denominator * denominator;
            let t = 1.0 - pair.fresnel;
            let value = t * dm * g * (o_m * i_m).abs() / (wo.z * denominator2);
            let pdf = density_m * t * pair.eta * pair.eta * i_m.abs() / denominator2;
            (self.transmittance.value_at(ctx.uv) * value, pdf)
        };
        if value.is_finite() && pdf.is_finite() {
            (value, pdf)
        } else {
            (Rgb::ZERO, 0.0)
        }
    }
}

impl<D: Distribution> Bsdf for RoughDielectric<D> {
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(ctx, wo, wi).0
    }

    fn pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(ctx, wo, wi).1
    }

    fn eval_pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        match self.pair(ctx, wo, wi) {
            Some(pair) => self.value_and_density(ctx, wo, wi, &pair),
            None => (Rgb::ZERO, 0.0),
        }
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 || !wo.is_finite() {
            return None;
        }
        let d = &self.distribution;
        let lo = V3::<f32>::splat(wo);
        let m = d.sample_visible_normal(lo, (u.x, u.y)).lane(0);
        let eta = eta_seen_from(ctx.side, self.eta);
        let cos_o_m = wo.dot(m);
        if cos_o_m <= 0.0 || !m.is_finite() {
            return None;
        }
        let (fresnel, cos_t) = ior::fresnel(cos_o_m, eta);
        let reflected = u_lobe < fresnel;
        let wi = if reflected {
            reflect(lo, V3::splat(m)).lane(0)
        } else {
            // Snell's law about m: the tangential part scaled by 1/η, cos θt along −m.
            m * (cos_o_m / eta + cos_t) - wo / eta
        };
        // The sampled direction must leave on the side its lobe scatters to.
        if wi.z == 0.0 || (wi.z > 0.0) != reflected || !wi.is_finite() {
            return None;
        }
        let (value, pdf) = self.eval_pdf(ctx, wo, wi);
        let sample = BsdfSample::new(wi, pdf, value / pdf);
        let valid = pdf > 0.0 && sample.weight.is_finite();
        valid.then(|| {
            if reflected {
                sample
            } else {
                sample.with_eta(eta)
            }
        })
    }

    fn flags(&self) -> BsdfFlags {
        let varying = if self.reflectance.varies() || self.transmittance.varies() {
            BsdfFlags::SPATIALLY_VARYING
        } else {
            BsdfFlags::NONE
        };
        BsdfFlags::GLOSSY_REFLECTION | BsdfFlags::GLOSSY_TRANSMISSION | varying
    }
}

/// The plugin's name in scene files, and its parameters' names and choices.
pub const NAME: &str = "roughdielectric";
pub const DISTRIBUTION: &str = "distribution";
pub const BECKMANN: &str = Beckmann::NAME;
pub const GGX: &str = Ggx::NAME;
pub const ALPHA: &str = "alpha";

static PARAMS: &[ParamSpec] = &[
    INT_IOR_SPEC,
    EXT_IOR_SPEC,
    ParamSpec {
        name: DISTRIBUTION,
        kind: ParamKind::Choice {
            options: &[BECKMANN, GGX],
            default: BECKMANN,
        },
        unit: "",
        description: "microfacet distribution: beckmann or ggx",
    },
    ParamSpec {
        name: ALPHA,
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 0.0,
            max: 4.0,
        },
        unit: "",
        description: "roughness α, the width of the microfacet distribution (at least 1e-4 is used)",
    },
    SPECULAR_REFLECTANCE_SPEC,
    SPECULAR_TRANSMITTANCE_SPEC,
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let eta = ior::read_eta(params)?;
    let alpha = params.float(ALPHA)?;
    let reflectance = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    let transmittance = params.rgb_or_texture(SPECULAR_TRANSMITTANCE)?;
    Ok(if params.choice(DISTRIBUTION)? == GGX {
        Arc::new(RoughDielectric::<Ggx>::new(
            eta,
            alpha,
            reflectance,
            transmittance,
        ))
    } else {
        Arc::new(RoughDielectric::<Beckmann>::new(
            eta,
            alpha,
            reflectance,
            transmittance,
        ))
    })
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "rough dielectric interface (frosted glass): microfacet reflection and refraction, GGX or Beckmann (Walter et al. 2007)",
        params: PARAMS,
        create,
    }
}

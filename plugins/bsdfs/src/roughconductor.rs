//! `roughconductor`: a rough metal, microfacet reflection (GGX or Beckmann) with the Fresnel
//! reflectance of a complex index of refraction η + i k (Mitsuba 3's `roughconductor`).
//!
//! Parameters:
//! - `distribution` (choice, default `beckmann`, or `ggx`): the microfacet distribution
//!   (Mitsuba's default is Beckmann).
//! - `alpha` (float or texture, default 0.1, in [0, 10]): the roughness α (the slopes' RMS for
//!   Beckmann times √2, the GGX width); values below 10⁻⁴ are used as 10⁻⁴, as Mitsuba does.
//! - `material` (string, default "none"): as `conductor`'s.
//! - `eta` (rgb or texture, default (0, 0, 0)): as `conductor`'s.
//! - `k` (rgb or texture, default (1, 1, 1)): as `conductor`'s.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): as `conductor`'s.
//!
//! f(ωo, ωi) cos θi = F(ωo·h) D(h) G1(ωo) G1(ωi) / (4 cos θo), with Mitsuba's separable
//! masking-shadowing, zero where either direction is below the surface or h faces away from
//! them. Sampling: ωi reflected about a normal visible from ωo (`microfacet`), density
//! G1(ωo) D(h) / (4 cos θo). Reflection only; Mitsuba's is one-sided, which a scene asks for
//! with `one_sided: true` (the importer writes it). Isotropic: Mitsuba's `alpha_u`/`alpha_v`
//! are not read.

use crate::conductor::{
    ComplexIor, ETA_SPEC, K_SPEC, MATERIAL_SPEC, SPECULAR_REFLECTANCE, SPECULAR_REFLECTANCE_SPEC,
    read_ior,
};
use crate::fresnel;
use crate::microfacet::{Beckmann, Distribution, Ggx, MIN_ALPHA, Masking, Microfacet, reflect};
use lumis_core::bsdf::{Bsdf, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSampleLanes};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, V3};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{FloatSource, RgbSource, Textured};
use std::marker::PhantomData;
use std::sync::Arc;

/// A rough conductor of distribution `D`.
pub struct RoughConductor<D> {
    alpha: Textured<f32>,
    ior: ComplexIor,
    specular: Textured<Rgb>,
    distribution: PhantomData<D>,
}

/// The parameters at each lane's point.
#[derive(Clone, Copy)]
pub struct Resolved<L> {
    alpha: L,
    eta: V3<L>,
    k: V3<L>,
    specular: V3<L>,
}

impl<D: Distribution> RoughConductor<D> {
    pub fn new(alpha: Textured<f32>, ior: ComplexIor, specular: Textured<Rgb>) -> Self {
        RoughConductor {
            alpha,
            ior,
            specular,
            distribution: PhantomData,
        }
    }
}

impl<D: Distribution> BsdfLanes for RoughConductor<D> {
    type Params<L: Lanes> = Resolved<L>;

    fn bsdf_flags(&self) -> BsdfFlags {
        let varying = self.alpha.varies() || self.ior.varies() || self.specular.varies();
        BsdfFlags::GLOSSY_REFLECTION
            | if varying {
                BsdfFlags::SPATIALLY_VARYING
            } else {
                BsdfFlags::NONE
            }
    }

    #[inline(always)]
    fn params_lanes<L: Lanes>(&self, ctx: &BsdfContextLanes<L>) -> Resolved<L> {
        Resolved {
            alpha: self.alpha.at(ctx.uv).max(L::splat(MIN_ALPHA)),
            eta: self.ior.eta.at(ctx.uv),
            k: self.ior.k.at(ctx.uv),
            specular: self.specular.at(ctx.uv),
        }
    }

    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        p: &Resolved<L>,
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let zero = L::splat(0.0);
        let m = Microfacet::<D, L>::new(p.alpha);
        let h = (wo + wi).normalize_or_zero();
        let cos_h = wo.dot(h);
        // Both directions above the surface, and h facing them (Mitsuba's G1 side test).
        let invalid = wo.z.le(zero) | wi.z.le(zero) | cos_h.le(zero);
        let (d, lambda_o) = (m.d(h), m.lambda(wo));
        let g2 = Masking::Separable.g2(lambda_o, m.lambda(wi));
        let scale = d * g2 / (L::splat(4.0) * wo.z);
        let f = fresnel::conductor(cos_h, p.eta, p.k);
        let value = f.mul_elementwise(p.specular) * scale;
        let value = V3::select(value.is_finite() & !invalid, value, V3::zero());
        let pdf = Microfacet::<D, L>::reflection_pdf(wo, d, lambda_o);
        (value, L::select(invalid, zero, pdf))
    }

    /// Reflection about a visible normal; value and density from `eval_pdf` (as
    /// [`lumis_core::bsdf::sample_from_pdf`]).
    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        p: &Resolved<L>,
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        _u_lobe: L,
        u: (L, L),
    ) -> BsdfSampleLanes<L> {
        let m = Microfacet::<D, L>::new(p.alpha);
        let wi = reflect(wo, m.sample_visible_normal(wo, u));
        let above = !wo.z.le(L::splat(0.0));
        BsdfSampleLanes::from_pdf(above, wi, self.eval_pdf_lanes(p, ctx, wo, wi))
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "roughconductor";
pub const DISTRIBUTION: &str = "distribution";
pub const ALPHA: &str = "alpha";
pub use crate::conductor::{ETA, K, MATERIAL, NONE};
/// Values of `distribution`.
pub const BECKMANN: &str = Beckmann::NAME;
pub const GGX: &str = Ggx::NAME;

/// The parameters rough BSDFs share (`roughplastic` declares `distribution` too).
pub(crate) const DISTRIBUTION_SPEC: ParamSpec = ParamSpec {
    name: DISTRIBUTION,
    kind: ParamKind::Choice {
        options: &[BECKMANN, GGX],
        default: BECKMANN,
    },
    unit: "",
    description: "microfacet distribution: beckmann (Mitsuba's default) or ggx",
};

static PARAMS: &[ParamSpec] = &[
    DISTRIBUTION_SPEC,
    ParamSpec {
        name: ALPHA,
        kind: ParamKind::FloatOrTexture {
            default: Some(0.1),
            min: 0.0,
            max: 10.0,
        },
        unit: "",
        description: "roughness α (below 1e-4 used as 1e-4); or a texture",
    },
    MATERIAL_SPEC,
    ETA_SPEC,
    K_SPEC,
    SPECULAR_REFLECTANCE_SPEC,
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let distribution = params.choice(DISTRIBUTION)?;
    let alpha = params.float_or_texture(ALPHA)?;
    let ior = read_ior(params)?;
    let specular = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    Ok(if distribution == GGX {
        Arc::new(RoughConductor::<Ggx>::new(alpha, ior, specular))
    } else {
        Arc::new(RoughConductor::<Beckmann>::new(alpha, ior, specular))
    })
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "rough conductor: Beckmann or GGX microfacets with the Fresnel reflectance of a complex index of refraction",
        params: PARAMS,
        create,
    }
}

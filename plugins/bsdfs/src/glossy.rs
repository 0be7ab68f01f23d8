//! `glossy`: GGX (Trowbridge–Reitz) microfacet reflection with Smith masking-shadowing and
//! Schlick's Fresnel, over an optional diffuse base.
//!
//! Parameters:
//! - `roughness` (float, default 0.1, in [0.0001, 1]): the GGX α (≈ the squared perceptual
//!   roughness).
//! - `specular` (rgb, default (0.04, 0.04, 0.04), in [0, 1]): F0, the reflectance at normal
//!   incidence.
//! - `diffuse` (rgb, default (0, 0, 0), in [0, 1]): albedo of the diffuse base layer.
//! - `masking` (choice, default `height_correlated`, or `separable`): the Smith masking-shadowing
//!   term G₂(ωo, ωi). `height_correlated` is 1 / (1 + Λ(ωo) + Λ(ωi)) (Heitz 2014, the more
//!   accurate, and pbrt-v3's and pbrt-v4's); `separable` is G₁(ωo) G₁(ωi) =
//!   1 / ((1 + Λ(ωo))(1 + Λ(ωi))), as Mitsuba 3's `roughconductor` uses. They agree at normal
//!   incidence; the separable term is smaller by the factor (1 + Λ(ωo) + Λ(ωi)) /
//!   ((1 + Λ(ωo))(1 + Λ(ωi))) toward grazing angles.
//!
//! The base is Ashikhmin and Shirley's (2000) energy-conserving diffuse term, reciprocal and
//! weighted by (1 − F0) so that specular plus diffuse never reflect more than arrives.
//! Sampling: the specular lobe by its distribution of visible normals (Heitz 2018), the base
//! with the cosine-weighted hemisphere, chosen in proportion to their estimated albedos for
//! the given ωo; `pdf` is exactly that mixture's density.

pub use crate::microfacet::Masking;
use crate::microfacet::{Ggx, Microfacet, reflect};
use lumis_core::bsdf::{Bsdf, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSampleLanes};
use lumis_core::math::lanes::{Lanes, Mask, V3};
use lumis_core::math::warp::{cosine_hemisphere_pdf_lanes, square_to_cosine_hemisphere_lanes};
use lumis_core::math::{Rgb, luminance, luminance_lanes};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::f32::consts::PI;
use std::sync::Arc;

pub struct Glossy {
    alpha: f32,
    f0: Rgb,
    diffuse: Rgb,
    masking: Masking,
}

/// A pair of directions (ωo, ωi) with what their value and density share.
#[derive(Clone, Copy)]
struct Pair<L> {
    wo: V3<L>,
    wi: V3<L>,
    h: V3<L>,
    /// D(h).
    d: L,
    /// Λ(ωo).
    lambda_o: L,
}

impl<L: Lanes> Pair<L> {
    /// Whether ωo or ωi is below the surface (the BSDF is zero there).
    #[inline(always)]
    fn below(&self) -> L::Mask {
        let zero = L::splat(0.0);
        self.wo.z.le(zero) | self.wi.z.le(zero)
    }
}

/// Schlick's approximation of the Fresnel reflectance, per channel.
#[inline(always)]
fn schlick<L: Lanes>(f0: Rgb, cos: L) -> V3<L> {
    let m = (L::splat(1.0) - cos).clamp(L::splat(0.0), L::splat(1.0));
    let m5 = (m * m) * (m * m) * m;
    V3::splat(f0) + V3::splat(Rgb::ONE - f0) * m5
}

/// x⁵, as products.
#[inline(always)]
fn pow5<L: Lanes>(x: L) -> L {
    let x2 = x * x;
    x2 * x2 * x
}

/// The lobes' formulas over [`Lanes`]: the scalar methods run them on one sample, the batch
/// methods on four or eight, with the same operations.
impl Glossy {
    pub fn new(alpha: f32, f0: Rgb, diffuse: Rgb, masking: Masking) -> Self {
        Glossy {
            alpha,
            f0,
            diffuse,
            masking,
        }
    }

    /// The GGX distribution of this roughness.
    #[inline(always)]
    fn microfacet<L: Lanes>(&self) -> Microfacet<Ggx, L> {
        Microfacet::constant(self.alpha)
    }

    /// Probability of sampling the specular lobe for this ωo.
    #[inline(always)]
    fn specular_probability<L: Lanes>(&self, wo: V3<L>) -> L {
        if self.diffuse == Rgb::ZERO {
            return L::splat(1.0);
        }
        let spec = luminance_lanes(schlick(self.f0, wo.z));
        let base = L::splat(luminance(self.diffuse) * (1.0 - self.f0.max_element()));
        (spec / (spec + base)).clamp(L::splat(0.1), L::splat(0.9))
    }

    /// The specular lobe's F D G2 / (4 cos θo cos θi) · cos θi at half vector h, given D(h) and
    /// Λ(ωo); zero where it is not finite.
    #[inline(always)]
    fn specular_value<L: Lanes>(&self, wo: V3<L>, wi: V3<L>, h: V3<L>, d: L, lambda_o: L) -> V3<L> {
        let g2 = self.masking.g2(lambda_o, self.microfacet().lambda(wi));
        let spec = schlick(self.f0, wo.dot(h)) * (d * g2 / (L::splat(4.0) * wo.z));
        V3::select(spec.is_finite(), spec, V3::zero())
    }

    /// The diffuse base's value · cos θi (zero without a base, at no cost).
    #[inline(always)]
    fn diffuse_value<L: Lanes>(&self, wo: V3<L>, wi: V3<L>) -> V3<L> {
        if self.diffuse == Rgb::ZERO {
            return V3::zero();
        }
        let one = L::splat(1.0);
        let fo = one - pow5(one - L::splat(0.5) * wo.z);
        let fi = one - pow5(one - L::splat(0.5) * wi.z);
        let albedo = self.diffuse * (1.0 - self.f0.max_element());
        V3::splat(albedo) * (L::splat(28.0 / (23.0 * PI)) * fo * fi) * wi.z
    }

    /// What the value and the density of a pair of directions share: the half vector h, D(h)
    /// and Λ(ωo).
    #[inline(always)]
    fn pair<L: Lanes>(&self, wo: V3<L>, wi: V3<L>) -> Pair<L> {
        let h = (wo + wi).normalize_or_zero();
        let microfacet = self.microfacet();
        Pair {
            wo,
            wi,
            h,
            d: microfacet.d(h),
            lambda_o: microfacet.lambda(wo),
        }
    }

    /// The mixture's value; zero where ωo or ωi is below the surface.
    #[inline(always)]
    fn value<L: Lanes>(&self, pair: &Pair<L>) -> V3<L> {
        let Pair {
            wo,
            wi,
            h,
            d,
            lambda_o,
        } = *pair;
        // D(h) is 0 where h is below the surface, and so is the specular lobe.
        let value = self.diffuse_value(wo, wi) + self.specular_value(wo, wi, h, d, lambda_o);
        V3::select(pair.below(), V3::zero(), value)
    }

    /// The mixture's density; zero where ωo or ωi is below the surface.
    #[inline(always)]
    fn density<L: Lanes>(&self, pair: &Pair<L>) -> L {
        let zero = L::splat(0.0);
        let specular_pdf = Microfacet::<Ggx, L>::reflection_pdf(pair.wo, pair.d, pair.lambda_o);
        let p = self.specular_probability(pair.wo);
        let pdf = p * specular_pdf + (L::splat(1.0) - p) * cosine_hemisphere_pdf_lanes(pair.wi.z);
        L::select(pair.below(), zero, pdf)
    }
}

impl BsdfLanes for Glossy {
    /// Every parameter is a constant.
    type Params<L: Lanes> = ();

    const READS_CONTEXT: bool = false;

    fn bsdf_flags(&self) -> BsdfFlags {
        if self.diffuse == Rgb::ZERO {
            BsdfFlags::GLOSSY_REFLECTION
        } else {
            BsdfFlags::GLOSSY_REFLECTION | BsdfFlags::DIFFUSE_REFLECTION
        }
    }

    #[inline(always)]
    fn params_lanes<L: Lanes>(&self, _ctx: &BsdfContextLanes<L>) {}

    /// `eval` and `pdf` of the mixture.
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        _params: &(),
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let pair = self.pair(wo, wi);
        (self.value(&pair), self.density(&pair))
    }

    /// `sample` in each lane: the specular lobe by visible normals or the diffuse base, then
    /// its value and density from `eval_pdf` (as [`lumis_core::bsdf::sample_from_pdf`]).
    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        params: &(),
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        u_lobe: L,
        u: (L, L),
    ) -> BsdfSampleLanes<L> {
        let specular = u_lobe.lt(self.specular_probability(wo));
        let wi = if specular.all() {
            reflect(wo, self.microfacet().sample_visible_normal(wo, u))
        } else if !specular.any() {
            square_to_cosine_hemisphere_lanes(u.0, u.1)
        } else {
            V3::select(
                specular,
                reflect(wo, self.microfacet().sample_visible_normal(wo, u)),
                square_to_cosine_hemisphere_lanes(u.0, u.1),
            )
        };
        let above = !wo.z.le(L::splat(0.0));
        BsdfSampleLanes::from_pdf(above, wi, self.eval_pdf_lanes(params, ctx, wo, wi))
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "glossy";
pub const ROUGHNESS: &str = "roughness";
pub const SPECULAR: &str = "specular";
pub const DIFFUSE: &str = "diffuse";
pub const MASKING: &str = "masking";
/// Values of its choices.
pub const HEIGHT_CORRELATED: &str = "height_correlated";
pub const SEPARABLE: &str = "separable";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: ROUGHNESS,
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 1e-4,
            max: 1.0,
        },
        unit: "",
        description: "GGX α: width of the microfacet distribution",
    },
    ParamSpec {
        name: SPECULAR,
        kind: ParamKind::Rgb {
            default: Some([0.04, 0.04, 0.04]),
            max: 1.0,
        },
        unit: "",
        description: "F0, Fresnel reflectance at normal incidence (Schlick), per channel in [0, 1]",
    },
    ParamSpec {
        name: DIFFUSE,
        kind: ParamKind::Rgb {
            default: Some([0.0, 0.0, 0.0]),
            max: 1.0,
        },
        unit: "",
        description: "albedo of the diffuse base layer, per channel in [0, 1]",
    },
    ParamSpec {
        name: MASKING,
        kind: ParamKind::Choice {
            options: &[HEIGHT_CORRELATED, SEPARABLE],
            default: HEIGHT_CORRELATED,
        },
        unit: "",
        description: "Smith masking-shadowing G2: height-correlated (as pbrt), or separable G1·G1 (as Mitsuba 3)",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let alpha = params.float(ROUGHNESS)?;
    let f0 = params.rgb(SPECULAR)?;
    let diffuse = params.rgb(DIFFUSE)?;
    let masking = match params.choice(MASKING)? {
        SEPARABLE => Masking::Separable,
        _ => Masking::HeightCorrelated,
    };
    Ok(Arc::new(Glossy::new(alpha, f0, diffuse, masking)))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "GGX microfacet reflection (visible-normal sampling) over an optional diffuse base",
        params: PARAMS,
        create,
    }
}

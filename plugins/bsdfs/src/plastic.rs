//! `plastic`: a smooth dielectric coating over a diffuse base (Mitsuba 3's `plastic`): a Dirac
//! lobe of Fresnel reflection at the coating, and the light it transmits reflected by the base,
//! scattered inside the coating and transmitted back out.
//!
//! Parameters:
//! - `int_ior` (float, default 1.49, in [0.01, 10]): the coating's index of refraction
//!   (Mitsuba's default, polypropylene; the importer turns Mitsuba's names into numbers).
//! - `ext_ior` (float, default 1.000277, in [0.01, 10]): the index outside (air).
//! - `diffuse_reflectance` (rgb or texture, default (0.5, 0.5, 0.5), in [0, 1]): the base's
//!   albedo.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): a factor on the
//!   coating's reflection (not physical; Mitsuba's).
//! - `nonlinear` (bool, default false): account for the base's colour changing with each
//!   internal bounce (Mitsuba's `nonlinear`): R / (1 − R F_dr) instead of R / (1 − F_dr).
//!
//! With η = int_ior / ext_ior, F(cos) the dielectric Fresnel reflectance and F_dr the diffuse
//! Fresnel reflectance of the inside (`fresnel::diffuse_reflectance(1/η)`):
//! f(ωo, ωi) cos θi = R / (1 − F_dr) · (1/η²) (1 − F(cos θo)) (1 − F(cos θi)) cos θi / π, and
//! the delta lobe reflects F(cos θo) · specular_reflectance. Sampling chooses the delta lobe
//! with probability F(cos θo) w / (F(cos θo) w + (1 − F(cos θo))(1 − w)), w the specular
//! weight s̄ / (s̄ + d̄) of the reflectances' means (a texture's mean over the unit square of
//! texture coordinates, from a 64 × 64 grid of lookups), else the cosine-weighted hemisphere;
//! `pdf` is the diffuse lobe's share of that. Reflection only; Mitsuba's is one-sided, which a
//! scene asks for with `one_sided: true` (the importer writes it).

use crate::fresnel;
use glam::Vec2;
use lumis_core::bsdf::{Bsdf, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSampleLanes};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, Mask, V3};
use lumis_core::math::warp::{cosine_hemisphere_pdf_lanes, square_to_cosine_hemisphere_lanes};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::sync::Arc;

/// A smooth plastic.
pub struct Plastic {
    /// η = int_ior / ext_ior.
    eta: f32,
    /// 1 / η².
    inv_eta2: f32,
    /// The diffuse Fresnel reflectance of the inside of the coating.
    fdr_int: f32,
    /// w: the weight of the delta lobe in sampling.
    specular_weight: f32,
    nonlinear: bool,
    diffuse: Textured<Rgb>,
    specular: Textured<Rgb>,
}

/// The reflectances at each lane's point.
#[derive(Clone, Copy)]
pub struct Reflectances<L> {
    pub diffuse: V3<L>,
    pub specular: V3<L>,
}

/// The mean of a colour parameter, as Mitsuba's `mean()`: a constant's channels' mean, a
/// texture's single value (`eval_1`) averaged over a 64 × 64 grid of the unit square.
pub(crate) fn mean(value: &Textured<Rgb>) -> f32 {
    match value {
        Textured::Constant(c) => (c.x + c.y + c.z) / 3.0,
        Textured::Texture(texture) => {
            const N: usize = 64;
            let points: Vec<Vec2> = (0..N * N)
                .map(|i| {
                    Vec2::new(
                        ((i % N) as f32 + 0.5) / N as f32,
                        ((i / N) as f32 + 0.5) / N as f32,
                    )
                })
                .collect();
            let mut values = vec![0.0; points.len()];
            texture.eval_1_batch(&points, &mut values);
            (values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64) as f32
        }
    }
}

/// The weight w = s̄ / (s̄ + d̄) of the specular lobe in sampling (½ if both are black).
pub(crate) fn specular_weight(diffuse: &Textured<Rgb>, specular: &Textured<Rgb>) -> f32 {
    let (d, s) = (mean(diffuse), mean(specular));
    if d + s > 0.0 { s / (d + s) } else { 0.5 }
}

/// R / (1 − F_dr), or R / (1 − R F_dr) when nonlinear: the base's albedo with the coating's
/// internal reflections summed.
#[inline(always)]
pub(crate) fn internal_scattering<L: Lanes>(diffuse: V3<L>, fdr: f32, nonlinear: bool) -> V3<L> {
    let one = L::splat(1.0);
    if nonlinear {
        let f = L::splat(fdr);
        V3::new(
            diffuse.x / (one - diffuse.x * f),
            diffuse.y / (one - diffuse.y * f),
            diffuse.z / (one - diffuse.z * f),
        )
    } else {
        diffuse * (one / L::splat(1.0 - fdr))
    }
}

impl Plastic {
    /// The probability of the delta lobe at cos θo, given F(cos θo).
    #[inline(always)]
    fn specular_probability<L: Lanes>(&self, f_o: L) -> L {
        let one = L::splat(1.0);
        let w = L::splat(self.specular_weight);
        let specular = f_o * w;
        let diffuse = (one - f_o) * (one - w);
        specular / (specular + diffuse)
    }
}

impl BsdfLanes for Plastic {
    type Params<L: Lanes> = Reflectances<L>;

    fn bsdf_flags(&self) -> BsdfFlags {
        let varying = self.diffuse.varies() || self.specular.varies();
        BsdfFlags::DELTA_REFLECTION
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

    /// The diffuse lobe's value and its share of the density (the delta lobe has neither).
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        p: &Reflectances<L>,
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let eta = L::splat(self.eta);
        let below = wo.z.le(zero) | wi.z.le(zero);
        let f_o = fresnel::dielectric(wo.z, eta).0;
        let f_i = fresnel::dielectric(wi.z, eta).0;
        let cosine = cosine_hemisphere_pdf_lanes(wi.z);
        let base = internal_scattering(p.diffuse, self.fdr_int, self.nonlinear);
        let value = base * (cosine * L::splat(self.inv_eta2) * (one - f_o) * (one - f_i));
        let pdf = cosine * (one - self.specular_probability(f_o));
        (
            V3::select(below, V3::zero(), value),
            L::select(below, zero, pdf),
        )
    }

    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        p: &Reflectances<L>,
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        u_lobe: L,
        u: (L, L),
    ) -> BsdfSampleLanes<L> {
        let zero = L::splat(0.0);
        let above = !wo.z.le(zero);
        let f_o = fresnel::dielectric(wo.z, L::splat(self.eta)).0;
        let probability = self.specular_probability(f_o);
        let specular = u_lobe.lt(probability) & above;
        let mirror = V3::new(-wo.x, -wo.y, wo.z);
        let diffuse = if specular.all() {
            None
        } else {
            let wi = square_to_cosine_hemisphere_lanes(u.0, u.1);
            Some(BsdfSampleLanes::from_pdf(
                above & !specular,
                wi,
                self.eval_pdf_lanes(p, ctx, wo, wi),
            ))
        };
        let delta_weight = p.specular * (f_o / probability);
        let delta_valid = specular & probability.gt(zero) & delta_weight.is_finite();
        let Some(d) = diffuse else {
            return BsdfSampleLanes::new(delta_valid, mirror, probability, delta_weight)
                .with_delta(specular);
        };
        BsdfSampleLanes::new(
            delta_valid | (!specular & d.valid),
            V3::select(specular, mirror, d.wi),
            L::select(specular, probability, d.pdf),
            V3::select(specular, delta_weight, d.weight),
        )
        .with_delta(specular)
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "plastic";
pub const INT_IOR: &str = "int_ior";
pub const EXT_IOR: &str = "ext_ior";
pub const DIFFUSE_REFLECTANCE: &str = "diffuse_reflectance";
pub const SPECULAR_REFLECTANCE: &str = "specular_reflectance";
pub const NONLINEAR: &str = "nonlinear";

/// The parameters both plastics declare.
pub(crate) const INT_IOR_SPEC: ParamSpec = ParamSpec {
    name: INT_IOR,
    kind: ParamKind::Float {
        default: Some(1.49),
        min: 0.01,
        max: 10.0,
    },
    unit: "",
    description: "index of refraction of the coating (polypropylene by default)",
};
pub(crate) const EXT_IOR_SPEC: ParamSpec = ParamSpec {
    name: EXT_IOR,
    kind: ParamKind::Float {
        default: Some(1.000_277),
        min: 0.01,
        max: 10.0,
    },
    unit: "",
    description: "index of refraction outside (air by default)",
};
pub(crate) const DIFFUSE_REFLECTANCE_SPEC: ParamSpec = ParamSpec {
    name: DIFFUSE_REFLECTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([0.5, 0.5, 0.5]),
        max: 1.0,
    },
    unit: "",
    description: "albedo of the diffuse base, per channel in [0, 1]; or a texture",
};
pub(crate) const SPECULAR_REFLECTANCE_SPEC: ParamSpec = ParamSpec {
    name: SPECULAR_REFLECTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([1.0, 1.0, 1.0]),
        max: 1.0,
    },
    unit: "",
    description: "factor on the coating's reflection, per channel in [0, 1]; or a texture",
};
pub(crate) const NONLINEAR_SPEC: ParamSpec = ParamSpec {
    name: NONLINEAR,
    kind: ParamKind::Bool {
        default: Some(false),
    },
    unit: "",
    description: "the base's colour changes with each internal reflection: R / (1 - R F_dr)",
};

static PARAMS: &[ParamSpec] = &[
    INT_IOR_SPEC,
    EXT_IOR_SPEC,
    DIFFUSE_REFLECTANCE_SPEC,
    SPECULAR_REFLECTANCE_SPEC,
    NONLINEAR_SPEC,
];

/// η = int_ior / ext_ior.
pub(crate) fn read_eta(params: &mut Params) -> Result<f32, PluginError> {
    Ok(params.float(INT_IOR)? / params.float(EXT_IOR)?)
}

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let eta = read_eta(params)?;
    let diffuse = params.rgb_or_texture(DIFFUSE_REFLECTANCE)?;
    let specular = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    let nonlinear = params.bool(NONLINEAR)?;
    Ok(Arc::new(Plastic {
        eta,
        inv_eta2: 1.0 / (eta * eta),
        fdr_int: fresnel::diffuse_reflectance(1.0 / eta),
        specular_weight: specular_weight(&diffuse, &specular),
        nonlinear,
        diffuse,
        specular,
    }))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "smooth plastic: a dielectric coating (delta reflection) over a diffuse base, Mitsuba's model",
        params: PARAMS,
        create,
    }
}

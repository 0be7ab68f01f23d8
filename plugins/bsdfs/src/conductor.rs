//! `conductor`: a smooth metal, a Dirac lobe of reflection weighted by the Fresnel reflectance of
//! a complex index of refraction η + i k (Mitsuba 3's `conductor`).
//!
//! Parameters:
//! - `material` (string, default "none"): a named conductor of Mitsuba's table (`"Cu"`, `"Au"`,
//!   `"Ag"`, `"Al"`, … as its RGB variants use them: `fresnel::NAMED_CONDUCTORS`), or "none",
//!   a perfect mirror (η = 0, k = 1, Fresnel 1), Mitsuba 3's default. Not with `eta` or `k`.
//! - `eta` (rgb or texture, default (0, 0, 0), each channel ≥ 0): the real part η of the index
//!   of refraction, relative to the outside.
//! - `k` (rgb or texture, default (1, 1, 1), each channel ≥ 0): its imaginary part, the
//!   absorption coefficient.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): a factor on the
//!   reflection, per channel (not physical; Mitsuba's).
//!
//! `eval` and `pdf` are zero for every given direction (a delta has no density); `sample`
//! returns the mirror direction flagged `delta`, with probability 1 and weight
//! `specular_reflectance` · F(cos θo). Where the Fresnel formula has no value (η = k = 0 at
//! normal incidence) it is 1, its limit. Reflection only; Mitsuba's conductor is one-sided,
//! which a scene asks for with `one_sided: true` (the importer writes it).

use crate::fresnel;
use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::V3;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::sync::Arc;

/// A smooth conductor.
pub struct Conductor {
    ior: ComplexIor,
    specular: Textured<Rgb>,
}

/// The complex index of refraction η + i k of a conductor, per channel, each part a constant
/// or a texture.
#[derive(Clone, Debug)]
pub struct ComplexIor {
    pub eta: Textured<Rgb>,
    pub k: Textured<Rgb>,
}

impl ComplexIor {
    /// Whether a part varies over the surface.
    pub fn varies(&self) -> bool {
        self.eta.varies() || self.k.varies()
    }
}

impl Bsdf for Conductor {
    fn eval(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, _u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (eta, k) = (self.ior.eta.value_at(ctx.uv), self.ior.k.value_at(ctx.uv));
        let f = fresnel::conductor::<f32>(wo.z, V3::splat(eta), V3::splat(k)).lane(0);
        let weight = self.specular.value_at(ctx.uv) * f;
        Some(BsdfSample::delta(
            Vec3::new(-wo.x, -wo.y, wo.z),
            1.0,
            weight,
        ))
    }

    fn flags(&self) -> BsdfFlags {
        let varying = if self.ior.varies() || self.specular.varies() {
            BsdfFlags::SPATIALLY_VARYING
        } else {
            BsdfFlags::NONE
        };
        BsdfFlags::DELTA_REFLECTION | varying
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "conductor";
pub const MATERIAL: &str = "material";
pub const ETA: &str = "eta";
pub const K: &str = "k";
pub const SPECULAR_REFLECTANCE: &str = "specular_reflectance";
/// The `material` of a perfect mirror.
pub const NONE: &str = "none";

/// The parameters conductors share (`roughconductor` declares them too).
pub(crate) const MATERIAL_SPEC: ParamSpec = ParamSpec {
    name: MATERIAL,
    kind: ParamKind::Str {
        default: Some(NONE),
    },
    unit: "",
    description: "a named conductor of Mitsuba's table (Cu, Au, Ag, Al, ...), or none (a perfect mirror)",
};
pub(crate) const ETA_SPEC: ParamSpec = ParamSpec {
    name: ETA,
    kind: ParamKind::RgbOrTexture {
        default: Some([0.0, 0.0, 0.0]),
        max: f32::INFINITY,
    },
    unit: "",
    description: "real part of the complex index of refraction; not with `material`",
};
pub(crate) const K_SPEC: ParamSpec = ParamSpec {
    name: K,
    kind: ParamKind::RgbOrTexture {
        default: Some([1.0, 1.0, 1.0]),
        max: f32::INFINITY,
    },
    unit: "",
    description: "imaginary part (absorption) of the complex index of refraction; not with `material`",
};
pub(crate) const SPECULAR_REFLECTANCE_SPEC: ParamSpec = ParamSpec {
    name: SPECULAR_REFLECTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([1.0, 1.0, 1.0]),
        max: 1.0,
    },
    unit: "",
    description: "factor on the reflection, per channel in [0, 1]; or a texture",
};

static PARAMS: &[ParamSpec] = &[MATERIAL_SPEC, ETA_SPEC, K_SPEC, SPECULAR_REFLECTANCE_SPEC];

/// The complex index of refraction the parameters give: a named material, or `eta` and `k`
/// (defaults: a perfect mirror). Both at once are refused, as Mitsuba refuses them.
pub(crate) fn read_ior(params: &mut Params) -> Result<ComplexIor, PluginError> {
    let material = params.string(MATERIAL)?;
    if material != NONE {
        if params.is_given(ETA) || params.is_given(K) {
            return Err(PluginError::Invalid(format!(
                "{}: give either `{MATERIAL}` or `{ETA}` and `{K}`, not both",
                params.plugin()
            )));
        }
        let (eta, k) = fresnel::named_conductor(&material)
            .map_err(|e| PluginError::Invalid(format!("{}: {e}", params.plugin())))?;
        return Ok(ComplexIor {
            eta: Textured::Constant(Rgb::from(eta)),
            k: Textured::Constant(Rgb::from(k)),
        });
    }
    Ok(ComplexIor {
        eta: params.rgb_or_texture(ETA)?,
        k: params.rgb_or_texture(K)?,
    })
}

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let ior = read_ior(params)?;
    let specular = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    Ok(Arc::new(Conductor { ior, specular }))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "smooth conductor: a delta lobe with the Fresnel reflectance of a complex index of refraction",
        params: PARAMS,
        create,
    }
}

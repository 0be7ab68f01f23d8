//! The indices of refraction of the dielectric BSDFs (`dielectric`, `thindielectric`,
//! `roughdielectric`): their parameters `int_ior` and `ext_ior`, each a number or one of
//! Mitsuba 3's material names ([`fresnel::NAMED_IORS`]: "bk7", "water", "diamond", …), and the
//! relative index η = int_ior / ext_ior the BSDFs use.

use crate::fresnel::{self, NAMED_IORS};
use lumis_core::bsdf::Side;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};

/// Parameter names, as Mitsuba's.
pub const INT_IOR: &str = "int_ior";
pub const EXT_IOR: &str = "ext_ior";

/// The range of an index of refraction: positive, within six orders of magnitude of 1.
pub const MIN: f32 = 1e-6;
pub const MAX: f32 = 1e6;

/// `int_ior`: the index of refraction inside (bk7 by default, Mitsuba's).
pub const INT_IOR_SPEC: ParamSpec = ParamSpec {
    name: INT_IOR,
    kind: ParamKind::Float {
        default: Some(1.5046),
        min: MIN,
        max: MAX,
    },
    unit: "",
    description: "index of refraction inside (the side the normal points away from): a number, or a material name such as \"bk7\", \"water\", \"diamond\" (Mitsuba's list)",
};

/// `ext_ior`: the index of refraction outside (air by default, Mitsuba's).
pub const EXT_IOR_SPEC: ParamSpec = ParamSpec {
    name: EXT_IOR,
    kind: ParamKind::Float {
        default: Some(1.000277),
        min: MIN,
        max: MAX,
    },
    unit: "",
    description: "index of refraction outside (the side the normal points to): a number or a material name, as int_ior",
};

/// η = `int_ior` / `ext_ior`, each a number or a name of [`NAMED_IORS`].
pub fn read_eta(params: &mut Params) -> Result<f32, PluginError> {
    let int_ior = params.float_or_name(INT_IOR, NAMED_IORS)?;
    let ext_ior = params.float_or_name(EXT_IOR, NAMED_IORS)?;
    Ok(int_ior / ext_ior)
}

/// The relative index across an interface of index `eta` (inside over outside) for a viewer on
/// `side`: η = η_far / η_near, `eta` seen from outside (`Front`), its reciprocal from inside.
#[inline]
pub fn eta_seen_from(side: Side, eta: f32) -> f32 {
    match side {
        Side::Front => eta,
        Side::Back => 1.0 / eta,
    }
}

/// The Fresnel reflectance of the smooth interface of relative index `eta` (the far side's
/// index over the viewer's) seen at cos θ = `cos_o` > 0, and the cosine of the refracted
/// direction, negative (0 under total internal reflection, where the reflectance is 1).
#[inline]
pub fn fresnel(cos_o: f32, eta: f32) -> (f32, f32) {
    let (f, cos_t, _, _) = fresnel::dielectric::<f32>(cos_o, eta);
    (f, cos_t)
}
